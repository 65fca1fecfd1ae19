//! Renders a [`ValidateSummary`] into a report directory: `report.md`,
//! `summary.json`, `scenarios.csv`, `occlusions.csv`, one CSV and SVG per
//! curve, `predicted_vs_measured.svg` and `marker_views.svg`. It computes
//! nothing new: every number comes from the summary.

use super::markdown::markdown;
use super::summary::{occluded_pairs, visible, Curve, IdentifiabilityCurve, ValidateSummary};
use crate::error_model::budget::{BudgetOverview, DepthRow};
use crate::report::{plots, write_text, ReportError, Table};
use crate::validate::VisibilityClass;
use std::path::Path;

/// Writes the report of `validation` into `dir` (created if missing), each
/// file atomically.
pub fn write(dir: &Path, validation: &ValidateSummary) -> Result<(), ReportError> {
    let layout = &validation.layout;
    std::fs::create_dir_all(dir).map_err(|e| ReportError::write(dir, e))?;
    let summary = &validation.overview;
    let json = serde_json::to_string_pretty(summary)
        .map_err(|e| ReportError::write(&dir.join("summary.json"), e))?;
    write_text(&dir.join("summary.json"), &(json + "\n"))?;
    let scenarios_csv = scenario_table(validation)
        .csv()
        .map_err(|e| ReportError::write(&dir.join("scenarios.csv"), e))?;
    write_text(&dir.join("scenarios.csv"), &scenarios_csv)?;
    let occlusions_csv = occlusion_table(validation)
        .csv()
        .map_err(|e| ReportError::write(&dir.join("occlusions.csv"), e))?;
    write_text(&dir.join("occlusions.csv"), &occlusions_csv)?;
    for curve in &summary.curves {
        write_curve(dir, curve)?;
    }
    if let Some(budget) = &summary.error_budget {
        write_budget_plot(dir, budget)?;
    }
    for curve in &summary.identifiability.curves {
        write_identifiability_curve(dir, curve, summary.identifiability.trials_per_scenario)?;
    }
    let scatter: Vec<(String, Vec<(f64, f64)>)> = summary
        .solvers
        .iter()
        .enumerate()
        .map(|(index, row)| {
            let points = validation
                .outcomes
                .iter()
                .filter(|o| visible(o))
                .filter_map(|o| {
                    Some((
                        o.first_order?.rms_rotation_deg,
                        o.solvers.get(index)?.rotation_deg.rms,
                    ))
                })
                .collect();
            (row.pooled.solver.name().to_string(), points)
        })
        .collect();
    plots::predicted_vs_measured(
        &dir.join("predicted_vs_measured.svg"),
        "Per-scenario RMS rotation error: first-order prediction vs Monte-Carlo",
        &scatter,
    )?;
    let named: Vec<(String, nalgebra::Vector3<f64>)> = layout
        .points
        .iter()
        .map(|p| (p.name.clone(), p.position))
        .collect();
    plots::orthographic_views(
        &dir.join("marker_views.svg"),
        &format!(
            "{}: three views, spheres to scale ({} mm)",
            layout.name, layout.sphere_diameter_mm
        ),
        &named,
        layout.sphere_diameter_mm,
    )?;
    write_pairs(dir, summary)?;
    let mut report = markdown(summary);
    if let Some(images) = &validation.images {
        write_images(dir, images)?;
        report.push_str(&super::image_report::markdown(images));
    }
    write_text(&dir.join("report.md"), &report)?;
    Ok(())
}

/// `images.csv` and `images.json` of the image check.
fn write_images(dir: &Path, images: &super::image_check::ImageSummary) -> Result<(), ReportError> {
    let csv_path = dir.join("images.csv");
    let csv = super::image_report::scenario_table(images)
        .csv()
        .map_err(|e| ReportError::write(&csv_path, e))?;
    write_text(&csv_path, &csv)?;
    let samples = dir.join(super::image_report::SAMPLE_DIR);
    for (name, png) in super::image_report::sample_pngs(images) {
        std::fs::create_dir_all(&samples).map_err(|e| ReportError::write(&samples, e))?;
        let path = samples.join(name);
        crate::files::write_atomic(&path, &png).map_err(|e| ReportError::write(&path, e))?;
    }
    let json_path = dir.join("images.json");
    let json =
        serde_json::to_string_pretty(images).map_err(|e| ReportError::write(&json_path, e))?;
    write_text(&json_path, &(json + "\n"))
}

/// `error_pairs.svg` (the pairwise heatmap matrix, when two or more axes
/// vary) and `worst_viewpoints.csv`.
fn write_pairs(dir: &Path, summary: &super::summary::Overview) -> Result<(), ReportError> {
    use crate::report::heatmap::{heatmap_matrix, HeatmapAxis, HeatmapMatrix, HeatmapPanel};
    let pairs = &summary.pairs;
    if !pairs.panels.is_empty() {
        let matrix = HeatmapMatrix {
            title: format!(
                "{}: RMS rotation error over every pair of the volume's axes",
                summary.header.layout
            ),
            quantity: format!("{} Monte-Carlo RMS rotation (°)", pairs.solver),
            axes: pairs
                .axes
                .iter()
                .map(|a| HeatmapAxis {
                    label: format!("{} ({})", a.axis, a.unit),
                    values: a.values.clone(),
                })
                .collect(),
            panels: pairs
                .panels
                .iter()
                .map(|p| HeatmapPanel {
                    x: p.x,
                    y: p.y,
                    cells: p.rms_rotation_deg.clone(),
                })
                .collect(),
        };
        heatmap_matrix(&dir.join("error_pairs.svg"), &matrix)?;
    }
    let mut table = Table::new([
        "rank",
        "depth_mm",
        "offset_x_mm",
        "offset_y_mm",
        "tilt_deg",
        "pan_deg",
        "roll_deg",
        "sigma_px",
        "rms_rot_deg",
        "first_order_rms_rot_deg",
    ]);
    for (rank, w) in summary.worst.iter().enumerate() {
        let s = &w.scenario;
        table.row([
            (rank + 1).to_string(),
            s.depth_mm.to_string(),
            s.offset_x_mm.to_string(),
            s.offset_y_mm.to_string(),
            s.tilt_deg.to_string(),
            s.pan_deg.to_string(),
            s.roll_deg.to_string(),
            s.sigma_px.to_string(),
            format!("{:.6e}", w.rms_rotation_deg),
            w.first_order_rotation_deg
                .map_or(String::new(), |v| format!("{v:.6e}")),
        ]);
    }
    let path = dir.join("worst_viewpoints.csv");
    let csv = table.csv().map_err(|e| ReportError::write(&path, e))?;
    write_text(&path, &csv)
}

/// `error_budget.svg`: each source's first-order RMS rotation per depth,
/// the first-order total and the Monte-Carlo total, on a log scale (a
/// source that adds nothing is left out).
fn write_budget_plot(dir: &Path, budget: &BudgetOverview) -> Result<(), ReportError> {
    let line = |name: &str, dashed: bool, pick: &dyn Fn(&DepthRow) -> f64| plots::Series {
        name: name.into(),
        points: budget
            .by_depth
            .iter()
            .map(|row| (row.depth_mm, pick(row)))
            .collect(),
        dashed,
    };
    plots::line_plot(
        &dir.join("error_budget.svg"),
        "Error budget: RMS rotation per source",
        "depth (mm)",
        "RMS rotation (deg)",
        &[
            line("image noise", false, &|r| r.first_order.noise_deg),
            line("the part", false, &|r| r.first_order.part_deg),
            line("the camera", false, &|r| r.first_order.camera_deg),
            line("total, first order", true, &|r| r.first_order.total_deg),
            line("total, Monte-Carlo", false, &|r| r.monte_carlo.total_deg),
        ],
    )
}

fn write_curve(dir: &Path, curve: &Curve) -> Result<(), ReportError> {
    let mut table = Table::new(
        [
            format!("{} ({})", curve.axis, curve.unit),
            "availability".into(),
            "first-order RMS rot (deg)".into(),
            "transfer RMS rot (deg)".into(),
        ]
        .into_iter()
        .chain(curve.solvers.iter().flat_map(|s| {
            [
                format!("{} RMS rot (deg)", s.solver),
                format!("{} RMS trans (mm)", s.solver),
            ]
        })),
    );
    for (k, value) in curve.values.iter().enumerate() {
        let cell = |v: Option<f64>| v.map_or(String::new(), |v| format!("{v:.6e}"));
        table.row(
            [
                value.to_string(),
                format!("{:.4}", curve.availability[k]),
                cell(curve.first_order_rotation_deg[k]),
                cell(curve.transfer_rotation_deg[k]),
            ]
            .into_iter()
            .chain(
                curve
                    .solvers
                    .iter()
                    .flat_map(|s| [cell(s.rms_rotation_deg[k]), cell(s.rms_translation_mm[k])]),
            ),
        );
    }
    let path = dir.join(format!("error_vs_{}.csv", curve.axis));
    write_text(
        &path,
        &table.csv().map_err(|e| ReportError::write(&path, e))?,
    )?;
    let xy = |values: &[Option<f64>]| -> Vec<(f64, f64)> {
        curve
            .values
            .iter()
            .zip(values)
            .filter_map(|(&x, y)| y.map(|y| (x, y)))
            .collect()
    };
    let mut series: Vec<plots::Series> = curve
        .solvers
        .iter()
        .map(|s| plots::Series {
            name: s.solver.clone(),
            points: xy(&s.rms_rotation_deg),
            dashed: false,
        })
        .collect();
    series.push(plots::Series {
        name: "first-order limit".into(),
        points: xy(&curve.first_order_rotation_deg),
        dashed: true,
    });
    series.push(plots::Series {
        name: "transfer model".into(),
        points: xy(&curve.transfer_rotation_deg),
        dashed: true,
    });
    let availability = plots::Availability {
        points: curve
            .values
            .iter()
            .copied()
            .zip(curve.availability.iter().copied())
            .collect(),
        axis: curve.axis.clone(),
        unit: curve.unit.clone(),
        label: "share of scenarios with every sphere visible".into(),
        empty: "nothing visible".into(),
    };
    let path = dir.join(format!("error_vs_{}.svg", curve.axis));
    let title = format!("RMS rotation error vs {} (visible scenarios)", curve.axis);
    let x_label = format!("{} ({})", curve.axis, curve.unit);
    if series.len() <= plots::MAX_SERIES_PER_PANEL {
        plots::line_plot_with_availability(
            &path,
            &title,
            &x_label,
            "RMS rotation error (deg)",
            &series,
            Some(&availability),
        )?;
    } else {
        // Too many solvers for one panel: one per solver group, each with
        // the model lines, on one y scale.
        let (models, solvers): (Vec<_>, Vec<_>) = series.into_iter().partition(|s| s.dashed);
        let panels: Vec<plots::LinePanel> = plots::SOLVER_GROUPS
            .iter()
            .enumerate()
            .map(|(g, heading)| plots::LinePanel {
                heading: heading.to_string(),
                series: solvers
                    .iter()
                    .filter(|s| plots::solver_group(&s.name) == g)
                    .chain(&models)
                    .map(|s| plots::BandedSeries {
                        series: s.clone(),
                        band: Vec::new(),
                    })
                    .collect(),
            })
            .filter(|p| p.series.iter().any(|s| !s.series.dashed))
            .collect();
        plots::panel_plot(
            &path,
            &title,
            &[],
            &x_label,
            "RMS rotation error (deg)",
            &panels,
            Some(&availability),
        )?;
    }
    Ok(())
}

/// Predicted probabilities below this are drawn at it (they run to 1e-20
/// and would give the axis twenty decades that say only "never").
const PREDICTED_FLOOR: f64 = 1e-6;

fn write_identifiability_curve(
    dir: &Path,
    curve: &IdentifiabilityCurve,
    trials_per_scenario: usize,
) -> Result<(), ReportError> {
    let mut table = Table::new([
        format!("{} ({})", curve.axis, curve.unit),
        "visible".into(),
        "identifiable share".into(),
        "smallest margin (px)".into(),
        "predicted wrong-label probability".into(),
        "Monte-Carlo wrong-label rate".into(),
    ]);
    let cell = |v: Option<f64>| v.map_or(String::new(), |v| format!("{v:.6e}"));
    for (k, value) in curve.values.iter().enumerate() {
        table.row([
            value.to_string(),
            curve.visible[k].to_string(),
            cell(curve.identifiable_share[k]),
            cell(curve.smallest_margin_px[k]),
            cell(curve.predicted_wrong[k]),
            cell(curve.monte_carlo_wrong[k]),
        ]);
    }
    let path = dir.join(format!("identifiability_vs_{}.csv", curve.axis));
    write_text(
        &path,
        &table.csv().map_err(|e| ReportError::write(&path, e))?,
    )?;
    let xy = |values: &[Option<f64>]| -> Vec<(f64, f64)> {
        curve
            .values
            .iter()
            .zip(values)
            .filter_map(|(&x, y)| y.map(|y| (x, y)))
            .collect()
    };
    // A rate of zero has no place on a log axis: it is drawn at its 95%
    // upper bound, 3 / trials, as its own series.
    type Points = Vec<(f64, f64)>;
    let (zero, measured): (Points, Points) = curve
        .values
        .iter()
        .zip(&curve.monte_carlo_wrong)
        .zip(&curve.visible)
        .filter_map(|((&x, rate), &visible)| rate.map(|r| (x, r, visible)))
        .map(|(x, r, visible)| {
            if r > 0.0 {
                (x, r)
            } else {
                (x, -3.0 / (visible * trials_per_scenario).max(1) as f64)
            }
        })
        .partition(|&(_, r)| r < 0.0);
    let series = [
        plots::Series {
            name: "Monte-Carlo wrong-label rate".into(),
            points: measured,
            dashed: false,
        },
        plots::Series {
            name: "Monte-Carlo: none wrong (at its 95% bound, 3 / trials)".into(),
            points: zero.into_iter().map(|(x, r)| (x, -r)).collect(),
            dashed: false,
        },
        plots::Series {
            name: format!("predicted wrong-label probability (floor {PREDICTED_FLOOR:e})"),
            points: xy(&curve.predicted_wrong)
                .into_iter()
                .map(|(x, p)| (x, p.max(PREDICTED_FLOOR)))
                .collect(),
            dashed: true,
        },
    ];
    let visible_total: usize = curve.visible.iter().sum();
    let availability = plots::Availability {
        points: curve
            .values
            .iter()
            .copied()
            .zip(curve.identifiable_share.iter().map(|s| s.unwrap_or(0.0)))
            .collect(),
        axis: curve.axis.clone(),
        unit: curve.unit.clone(),
        label: "share of the visible scenarios predicted identifiable".into(),
        empty: "nothing identifiable".into(),
    };
    plots::line_plot_with_availability(
        &dir.join(format!("identifiability_vs_{}.svg", curve.axis)),
        &format!(
            "Wrong-label rate vs {} ({} visible scenarios; panel: share identifiable)",
            curve.axis, visible_total
        ),
        &format!("{} ({})", curve.axis, curve.unit),
        "wrong-label probability",
        &series,
        Some(&availability),
    )?;
    Ok(())
}

/// Every scenario with an occluded sphere, whatever its class: where it is
/// and which sphere hides which.
fn occlusion_table(validation: &ValidateSummary) -> Table {
    let mut table = Table::new([
        "scenario",
        "depth_mm",
        "offset_x_mm",
        "offset_y_mm",
        "tilt_deg",
        "pan_deg",
        "roll_deg",
        "sigma_px",
        "class",
        "occluded",
    ]);
    for o in validation
        .outcomes
        .iter()
        .filter(|o| !o.visibility.occluded.is_empty())
    {
        let s = &o.scenario;
        table.row([
            s.index.to_string(),
            s.depth_mm.to_string(),
            s.offset_x_mm.to_string(),
            s.offset_y_mm.to_string(),
            s.tilt_deg.to_string(),
            s.pan_deg.to_string(),
            s.roll_deg.to_string(),
            s.sigma_px.to_string(),
            VisibilityClass::of(&o.visibility).name().to_string(),
            occluded_pairs(&validation.layout, o),
        ]);
    }
    table
}

/// Every scenario, visible or not, one row per solver.
fn scenario_table(validation: &ValidateSummary) -> Table {
    let mut table = Table::new([
        "scenario",
        "depth_mm",
        "offset_x_mm",
        "offset_y_mm",
        "tilt_deg",
        "pan_deg",
        "roll_deg",
        "sigma_px",
        "visible",
        "class",
        "visibility_issues",
        "first_order_rms_rot_deg",
        "first_order_rms_trans_mm",
        "transfer_rms_rot_deg",
        "qu_hou_rms_rot_deg",
        "bias_max_displacement_px",
        "first_order_bias_rot_deg",
        "first_order_bias_rot_x_deg",
        "first_order_bias_rot_y_deg",
        "first_order_bias_rot_z_deg",
        "first_order_bias_trans_mm",
        "first_order_bias_trans_x_mm",
        "first_order_bias_trans_y_mm",
        "first_order_bias_trans_z_mm",
        "identify_margin_px",
        "identify_predicted_wrong",
        "identify_trials",
        "identify_mc_wrong_rate",
        "identify_mc_missed",
        "solver",
        "trials",
        "rms_rot_deg",
        "mean_rot_deg",
        "median_rot_deg",
        "p95_rot_deg",
        "rms_erot_deg",
        "rms_trans_mm",
        "rms_trans_percent",
        "gross_failures",
        "solver_errors",
    ]);
    let name = |i: usize| validation.layout.points[i].name.clone();
    for (o, identified) in validation.outcomes.iter().zip(
        validation
            .identifiability
            .iter()
            .chain(std::iter::repeat(&None)),
    ) {
        let s = &o.scenario;
        let v = &o.visibility;
        let mut issues: Vec<String> = Vec::new();
        issues.extend(
            v.behind
                .iter()
                .map(|&i| format!("{} behind camera", name(i))),
        );
        issues.extend(
            v.outside
                .iter()
                .map(|&i| format!("{} outside image", name(i))),
        );
        issues.extend(
            v.occluded
                .iter()
                .map(|&(h, b)| format!("{} behind {}", name(h), name(b))),
        );
        let opt = |v: Option<f64>| v.map_or(String::new(), |v| format!("{v:.6e}"));
        let common = [
            s.index.to_string(),
            s.depth_mm.to_string(),
            s.offset_x_mm.to_string(),
            s.offset_y_mm.to_string(),
            s.tilt_deg.to_string(),
            s.pan_deg.to_string(),
            s.roll_deg.to_string(),
            s.sigma_px.to_string(),
            v.is_visible().to_string(),
            VisibilityClass::of(v).name().to_string(),
            issues.join("; "),
            opt(o.first_order.map(|f| f.rms_rotation_deg)),
            opt(o.first_order.map(|f| f.rms_translation_mm)),
            opt(o.transfer.and_then(|t| t.rms_rotation_deg)),
            opt(o.qu_hou_rotation_deg),
            opt(o.bias.map(|b| b.max_displacement_px)),
            opt(o.bias.map(|b| b.pose.rotation_norm_deg())),
            opt(o.bias.map(|b| b.pose.rotation_deg[0])),
            opt(o.bias.map(|b| b.pose.rotation_deg[1])),
            opt(o.bias.map(|b| b.pose.rotation_deg[2])),
            opt(o.bias.map(|b| b.pose.translation_norm_mm())),
            opt(o.bias.map(|b| b.pose.translation_mm[0])),
            opt(o.bias.map(|b| b.pose.translation_mm[1])),
            opt(o.bias.map(|b| b.pose.translation_mm[2])),
            // A margin above the search gate is written as `>GATE`.
            identified
                .as_ref()
                .and_then(|i| i.prediction.as_ref())
                .map_or(String::new(), |p| match p.margin_px {
                    Some(m) => format!("{m:.6e}"),
                    None => format!(">{:.6e}", p.gate_px),
                }),
            opt(identified
                .as_ref()
                .and_then(|i| i.prediction.as_ref())
                .map(|p| p.wrong_probability)),
            identified
                .as_ref()
                .map_or(String::new(), |i| i.trials.trials.to_string()),
            opt(identified.as_ref().and_then(|i| i.trials.wrong_rate())),
            identified
                .as_ref()
                .filter(|i| i.trials.trials > 0)
                .map_or(String::new(), |i| i.trials.missed.to_string()),
        ];
        if o.solvers.is_empty() {
            table.row(
                common
                    .iter()
                    .cloned()
                    .chain(std::iter::repeat_n(String::new(), 11)),
            );
        }
        for r in &o.solvers {
            table.row(common.iter().cloned().chain([
                r.solver.name().to_string(),
                r.rotation_deg.count.to_string(),
                format!("{:.6e}", r.rotation_deg.rms),
                format!("{:.6e}", r.rotation_deg.mean),
                format!("{:.6e}", r.rotation_deg.median),
                format!("{:.6e}", r.rotation_deg.p95),
                format!("{:.6e}", r.paper_rotation_deg.rms),
                format!("{:.6e}", r.translation_mm.rms),
                format!("{:.6e}", r.translation_percent.rms),
                r.gross_failures.to_string(),
                r.solver_errors.to_string(),
            ]));
        }
    }
    table
}
