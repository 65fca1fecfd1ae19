//! Renders a [`ValidateSummary`] as text: `report.md` ([`markdown`]) and the
//! lines the command line prints when a run ends ([`console`],
//! [`budget_text`]). Computes nothing new.

use super::summary::{
    axis_unit, AxisErrors, AxisVisibility, IdentifiabilitySummary, Overview, Systematic,
    ValidateSummary,
};
use crate::error_model::budget::{BudgetOverview, SourceFigures};
use crate::report::{significant, Table};
use crate::volume::WorkingVolume;
use std::fmt::Write as _;
use std::path::Path;

/// What a run prints when it ends: the visibility counts, one row per
/// solver, the models' predictions, the systematic part, identifiability
/// (the error budget is [`budget_text`]). `out` is the report
/// directory the lines point to.
pub fn console(validation: &ValidateSummary, out: &Path) -> String {
    let summary = &validation.overview;
    let h = &summary.header;
    let v = &summary.visibility;
    let mut text = String::new();
    let _ = writeln!(
        text,
        "{}: {} scenarios × {} trials, seed {}: {} visible, {} occluded, {} outside the image, {} behind the camera{} (each scenario counted once, in the order behind, outside, occluded{})",
        h.layout, v.scenarios, h.trials_per_scenario, h.seed, v.visible, v.occluded, v.outside_image, v.behind_camera,
        support_count(v), if v.max_hidden.is_some() { ", hidden by a support" } else { "" }
    );
    if v.visible == 0 {
        let _ = writeln!(text, "no scenario is visible, so no error is measurable; see {} for why each scenario is hidden", out.join("scenarios.csv").display());
    }
    let mut table = Table::new([
        "solver",
        "RMS rot (°)",
        "/ 1st order",
        "RMS trans (mm)",
        "gross",
    ]);
    for row in &summary.solvers {
        let p = &row.pooled;
        table.row([
            p.solver.name().to_string(),
            format!("{:.4}", p.rms_rotation_deg),
            p.first_order
                .rotation_ratio
                .map_or("—".into(), |r| format!("{r:.3}")),
            format!("{:.3}", p.rms_translation_mm),
            p.gross_failures.to_string(),
        ]);
    }
    if !summary.solvers.is_empty() {
        text.push_str(&table.console());
    }
    if let Some(first) = summary.solvers.first() {
        let (f, t) = (&first.pooled.first_order, &first.pooled.transfer);
        let show = |v: Option<f64>, unit: &str| {
            v.filter(|v| v.is_finite())
                .map_or("not measurable".into(), |v| format!("{v:.4}{unit}"))
        };
        let _ = writeln!(
            text,
            "first-order limit: {} / {} over {} scenarios; transfer model: {} over {} scenarios{}",
            show(f.predicted_rms_rotation_deg, "°"),
            show(f.predicted_rms_translation_mm, " mm"),
            f.scenarios,
            show(t.predicted_rms_rotation_deg, "°"),
            t.scenarios,
            if h.volume.sigma_values_px().contains(&0.0) {
                " (the models predict nothing at σ = 0)"
            } else {
                ""
            }
        );
    }
    let s = &summary.systematic;
    if s.scenarios == 0 {
        let _ = writeln!(
            text,
            "observation {}: nothing to measure, no scenario is visible",
            h.observation
        );
    } else {
        let _ = writeln!(
        text,
        "observation {}: image bias up to {:.3} px (median {:.3} px); systematic rotation (first-order bias, RMS) {:.2e}° beside random {:.2e}°, translation {:.2e} mm beside {:.2e} mm",
        h.observation,
        s.max_displacement_px,
        s.median_displacement_px,
        s.first_order_bias.rms_rotation_deg,
        s.first_order_random.rms_rotation_deg,
        s.first_order_bias.rms_translation_mm,
        s.first_order_random.rms_translation_mm
    );
    }
    let id = &summary.identifiability;
    let _ = writeln!(
        text,
        "identifiability (criterion {:.1}% correct labels): {} of {} visible scenarios, smallest margin {}; predicted wrong-label rate {} (mean), Monte-Carlo {} ({} of {} trials)",
        100.0 * id.min_correct,
        id.identifiable,
        id.scenarios,
        id.smallest_margin_px
            .map_or("above the gate".to_string(), |m| format!("{m:.3} px")),
        id.mean_predicted_wrong
            .map_or("—".to_string(), |p| format!("{p:.2e}")),
        id.monte_carlo_wrong
            .map_or("—".to_string(), |p| format!("{p:.2e}")),
        id.trials.wrong,
        id.trials.trials
    );
    text
}

/// The error budget as a table: one row per depth and one for all, each
/// source's first-order RMS rotation with its share of the total variance,
/// and the Monte-Carlo total beside the first-order one.
fn budget_table(b: &BudgetOverview) -> Table {
    let mut table = Table::new([
        "depth (mm)",
        "noise (°)",
        "part (°)",
        "camera (°)",
        "total (°)",
        "Monte-Carlo (°)",
        "MC / 1st order",
    ]);
    let cell = |deg: f64, total: f64| {
        let share = if total > 0.0 {
            100.0 * (deg / total).powi(2)
        } else {
            0.0
        };
        format!("{} ({share:.0}%)", significant(Some(deg), 3))
    };
    let mut row = |label: String, f: &SourceFigures, m: &SourceFigures| {
        table.row([
            label,
            cell(f.noise_deg, f.total_deg),
            cell(f.part_deg, f.total_deg),
            cell(f.camera_deg, f.total_deg),
            significant(Some(f.total_deg), 3),
            significant(Some(m.total_deg), 3),
            format!("{:.3}", m.total_deg / f.total_deg),
        ]);
    };
    for depth in &b.by_depth {
        row(
            format!("{}", depth.depth_mm),
            &depth.first_order,
            &depth.monte_carlo,
        );
    }
    row("all".into(), &b.first_order, &b.monte_carlo);
    table
}

/// The sources of a budget, in one sentence.
fn budget_sources(b: &BudgetOverview) -> String {
    let c = &b.camera_sigma;
    format!(
        "image noise {}; the part {}; the camera σ fx {} fy {} cx {} cy {} px; Monte-Carlo: {}, {} trials per scenario and source, {} visible scenarios",
        b.noise, b.part, c.fx, c.fy, c.cx, c.cy, b.solver, b.trials, b.scenarios
    )
}

/// The error budget's section of `report.md`.
fn budget_markdown(b: &BudgetOverview) -> String {
    let mut out = String::new();
    let _ = writeln!(
        out,
        "## Error budget
"
    );
    let _ = writeln!(
        out,
        "The RMS rotation error each source leaves, to first order, and its share of the total variance; the total beside a Monte-Carlo run of all sources together (each trial a new part, camera and noise, solved with the nominal layout and camera). Sources: {}. The reading's bias is zero: `track` turns each ellipse into the sphere's projected centre. Per source alone, the Monte-Carlo figures are in `summary.json` (`error_budget`).\n",
        budget_sources(b)
    );
    out.push_str(&budget_table(b).markdown());
    let _ = writeln!(out, "\n![error budget](error_budget.svg)\n");
    out
}

/// The error budget as terminal text: its sources and its table.
pub fn budget_text(b: &BudgetOverview) -> String {
    format!(
        "error budget, RMS rotation and share of the variance ({}):\n{}",
        budget_sources(b),
        budget_table(b).console()
    )
}

fn range_text(values: &[f64]) -> String {
    match values {
        [single] => single.to_string(),
        [first, .., last] if values.len() > 4 => {
            format!("{first} … {last} ({} values)", values.len())
        }
        _ => values
            .iter()
            .map(|v| v.to_string())
            .collect::<Vec<_>>()
            .join(", "),
    }
}

/// ", 3 hidden by a support" when the supports were counted, else nothing.
fn support_count(v: &super::summary::VisibilityCounts) -> String {
    match v.max_hidden {
        Some(_) => format!(", {} hidden by a support", v.hidden_by_support),
        None => String::new(),
    }
}

/// One axis's visibility counts as a table, consecutive values with the
/// same counts merged into one row ("−90 … −60"). The column of scenarios
/// hidden by a support appears when some value has one.
fn axis_visibility_table(axis: &AxisVisibility) -> Table {
    let supports = axis.counts.iter().any(|c| c[4] > 0);
    let columns = if supports { 5 } else { 4 };
    let mut table = Table::new(
        [
            format!("{} ({})", axis.axis, axis.unit),
            "visible".to_string(),
            "occluded".to_string(),
            "outside image".to_string(),
            "behind camera".to_string(),
        ]
        .into_iter()
        .chain(supports.then(|| "hidden by a support".to_string())),
    );
    let mut start = 0;
    while start < axis.values.len() {
        let mut end = start;
        while end + 1 < axis.values.len() && axis.counts[end + 1] == axis.counts[start] {
            end += 1;
        }
        let values = if end == start {
            axis.values[start].to_string()
        } else {
            format!("{} … {}", axis.values[start], axis.values[end])
        };
        let counts = &axis.counts[start][..columns];
        table.row(std::iter::once(values).chain(counts.iter().map(|c| c.to_string())));
        start = end + 1;
    }
    table
}

/// `report.md`: every pooled number, with the plots beside them.
pub(super) fn markdown(summary: &Overview) -> String {
    let h = &summary.header;
    let v = &summary.visibility;
    let mut out = String::new();
    let _ = writeln!(out, "# Sensitivity report: {}\n", h.layout);
    let _ = writeln!(out, "| | |\n|---|---|");
    let _ = writeln!(out, "| command | `{}` |", h.command);
    let _ = writeln!(out, "| layout-opt | {} |", h.version);
    let _ = writeln!(out, "| seed | {} |", h.seed);
    let _ = writeln!(out, "| trials per scenario | {} |", h.trials_per_scenario);
    let _ = writeln!(out, "| solvers | {} |", h.solvers.join(", "));
    let _ = writeln!(out, "| noise model | {} |", h.noise_model);
    let _ = writeln!(
        out,
        "| camera | fx {} fy {} cx {} cy {}, {}×{} px, distortion {:?} |",
        h.camera.fx(),
        h.camera.fy(),
        h.camera.cx(),
        h.camera.cy(),
        h.camera.width(),
        h.camera.height(),
        h.camera.distortion()
    );
    let _ = writeln!(out, "| spheres | {} mm |", h.sphere_diameter_mm);
    let _ = writeln!(
        out,
        "| observation | {} (noise added on top) |",
        h.observation
    );
    let _ = writeln!(
        out,
        "| reference feature (paraperspective P0, transfer-model segment origin) | {} |",
        h.reference_point
    );
    let _ = writeln!(
        out,
        "| gross failure | rotation error > {}° |\n",
        h.gross_threshold_deg
    );

    let _ = writeln!(out, "## Scenarios\n");
    let _ = writeln!(
        out,
        "Working volume: {}. Availability below is a share of these viewpoints.\n",
        h.volume_text
    );
    if let WorkingVolume::Grid(grid) = &h.volume {
        let mut table = Table::new(["axis", "values"]);
        for (name, range) in grid.named_ranges() {
            table.row([
                format!("{name} ({})", axis_unit(name)),
                range_text(&range.values),
            ]);
        }
        out.push_str(&table.markdown());
    }
    let _ = writeln!(
        out,
        "\n{} scenarios: **{} visible** (availability {:.1}%), {} occluded, {} with a sphere outside the image (margin 5 px), {} with a sphere behind the camera (no trials), {} with a sphere hidden by the part's supports; {} + {} + {} + {} + {} = {}.",
        v.scenarios, v.visible, 100.0 * v.availability, v.occluded, v.outside_image, v.behind_camera, v.hidden_by_support,
        v.visible, v.occluded, v.outside_image, v.behind_camera, v.hidden_by_support, v.scenarios
    );
    let _ = writeln!(out, "{}", match v.max_hidden {
        Some(max) => format!("The part's supports (those `export` builds with its default structure, routed for this grid) count as occluders: a sphere of which they hide more than {:.1}% of the silhouette counts as not seen, as one behind another sphere does (`--no-supports`: the spheres alone).", 100.0 * max),
        None => "The part's supports are not counted (`--no-supports`): only the spheres hide each other.".to_string(),
    });
    let _ = writeln!(out, "Each scenario is counted once, under the first rule it breaks in the order behind the camera, outside the image, occluded, hidden by a support. A sphere is occluded when its image disc overlaps the disc of a nearer sphere; {} scenarios have an occluded sphere, {} of them also breaking an earlier rule. Statistics below pool the visible scenarios; `scenarios.csv` has every scenario, visible or not, with its class, and `occlusions.csv` every scenario with an occluded sphere and which sphere hides which.\n", v.with_occlusion, v.with_occlusion - v.occluded);
    for axis in &v.by_axis {
        let _ = writeln!(out, "Visibility by {} ({}): scenarios at each value; a row \"A … B\" stands for consecutive values with the same counts.\n", axis.axis, axis.unit);
        out.push_str(&axis_visibility_table(axis).markdown());
        out.push('\n');
    }
    if !v.occlusion_examples.is_empty() {
        let _ = writeln!(
            out,
            "Occluded scenarios (first {} of {}; `occlusions.csv` lists all {} scenarios with an occluded sphere):\n",
            v.occlusion_examples.len(),
            v.occluded,
            v.with_occlusion
        );
        for example in &v.occlusion_examples {
            let _ = writeln!(out, "- {example}");
        }
        out.push('\n');
    }

    let _ = writeln!(out, "## Accuracy per solver (visible scenarios)\n");
    let _ = writeln!(out, "Monte-Carlo, {} trials per scenario, seed {}. RMS pools every trial; \"worst\" is the worst scenario's RMS. Translation errors are |t − t_true|.\n", h.trials_per_scenario, h.seed);
    let mut table = Table::new([
        "solver",
        "trials",
        "RMS rot (°)",
        "mean rot (°)",
        "worst scenario RMS rot (°)",
        "RMS E_rot eq. 33 (°)",
        "RMS trans (mm)",
        "RMS trans (%)",
        "gross",
        "errors",
    ]);
    for row in &summary.solvers {
        let p = &row.pooled;
        table.row([
            format!("`{}`", p.solver.name()),
            p.trials.to_string(),
            significant(Some(p.rms_rotation_deg), 3),
            significant(Some(p.mean_rotation_deg), 3),
            significant(Some(p.worst_rms_rotation_deg), 3),
            significant(Some(p.rms_paper_rotation_deg), 3),
            significant(Some(p.rms_translation_mm), 3),
            significant(Some(p.rms_translation_percent), 3),
            p.gross_failures.to_string(),
            p.solver_errors.to_string(),
        ]);
    }
    out.push_str(&table.markdown());

    let _ = writeln!(out, "\n## Predicted against measured\n");
    if let Some(first) = summary.solvers.first() {
        let (f, t) = (&first.pooled.first_order, &first.pooled.transfer);
        let _ = writeln!(
            out,
            "The first-order (Cramér–Rao) model, `(JᵀWJ)⁻¹` at the true pose, predicts an RMS rotation error of **{}°** and RMS translation error of **{} mm** over the {} visible scenarios. The paper's transfer model (eqs. 26–29, aggregated as documented in `error_model::transfer`) predicts **{}°** and **{} mm** over the {} of them where it is finite (it diverges where every segment through the reference point is parallel or perpendicular to the optical axis).\n",
            significant(f.predicted_rms_rotation_deg, 3), significant(f.predicted_rms_translation_mm, 3), f.scenarios,
            significant(t.predicted_rms_rotation_deg, 3), significant(t.predicted_rms_translation_mm, 3), t.scenarios
        );
    }
    let _ = writeln!(out, "Ratios are measured / predicted over the scenarios each model covers; 1.00 means the model is exact, above 1 the solver does worse than the model predicts.\n");
    let mut agreement = Table::new([
        "solver",
        "rot / first-order",
        "median scenario rot / first-order",
        "trans / first-order",
        "rot / transfer",
        "median scenario rot / transfer",
        "trans / transfer",
    ]);
    for row in &summary.solvers {
        let (f, t) = (&row.pooled.first_order, &row.pooled.transfer);
        agreement.row([
            format!("`{}`", row.pooled.solver.name()),
            significant(f.rotation_ratio, 3),
            significant(row.median_scenario_ratio_to_first_order, 3),
            significant(f.translation_ratio, 3),
            significant(t.rotation_ratio, 3),
            significant(row.median_scenario_ratio_to_transfer, 3),
            significant(t.translation_ratio, 3),
        ]);
    }
    out.push_str(&agreement.markdown());
    let _ = writeln!(
        out,
        "\n![predicted vs measured](predicted_vs_measured.svg)\n"
    );

    out.push_str(&systematic_markdown(&summary.systematic, &h.observation));
    if let Some(budget) = &summary.error_budget {
        out.push_str(&budget_markdown(budget));
    }
    out.push_str(&identifiability_markdown(&summary.identifiability));

    if !summary.curves.is_empty() {
        let _ = writeln!(out, "## Error along each axis\n");
        let _ = writeln!(out, "Each point pools the visible scenarios at that value. Solvers are the lines with markers (some of them dashed or dotted, to tell them apart in grey); the model predictions are the black and grey lines without markers. CSV beside each plot.\n");
        for curve in &summary.curves {
            let _ = writeln!(
                out,
                "### {}\n\n![error vs {}](error_vs_{}.svg)\n\n[error_vs_{}.csv](error_vs_{}.csv)\n",
                curve.axis, curve.axis, curve.axis, curve.axis, curve.axis
            );
        }
    }
    out.push_str(&pairs_markdown(summary));
    let _ = writeln!(out, "## Marker\n\n![three views](marker_views.svg)\n");
    out
}

/// The pairwise heatmap page and the worst viewpoints.
fn pairs_markdown(summary: &Overview) -> String {
    let mut out = String::new();
    let pairs = &summary.pairs;
    if !pairs.panels.is_empty() {
        let _ = writeln!(out, "## Error over pairs of axes\n");
        let _ = writeln!(
            out,
            "{} panels, one per pair of the {} axes that vary; each cell pools `{}`'s trials over the visible viewpoints in it, on one colour scale{} (viridis; grey: no visible viewpoint).\n\n![error over pairs of axes](error_pairs.svg)\n",
            pairs.panels.len(),
            pairs.axes.len(),
            pairs.solver,
            pairs
                .range_deg
                .map_or(String::new(), |(lo, hi)| format!(" from {lo:.3}° to {hi:.3}°"))
        );
    }
    if !summary.worst.is_empty() {
        let _ = writeln!(
            out,
            "## The {} worst viewpoints ({})\n",
            summary.worst.len(),
            pairs.solver
        );
        let mut table = Table::new(["rank", "viewpoint", "RMS rotation (°)", "first order (°)"]);
        for (rank, w) in summary.worst.iter().enumerate() {
            table.row([
                (rank + 1).to_string(),
                w.description.clone(),
                format!("{:.4}", w.rms_rotation_deg),
                w.first_order_rotation_deg
                    .map_or("—".into(), |v| format!("{v:.4}")),
            ]);
        }
        out.push_str(&table.markdown());
        let _ = writeln!(out, "\n[worst_viewpoints.csv](worst_viewpoints.csv)\n");
    }
    out
}

fn identifiability_markdown(s: &IdentifiabilitySummary) -> String {
    let mut out = String::new();
    let _ = writeln!(out, "## Identifiability (visible scenarios)\n");
    let _ = writeln!(
        out,
        "Whether one image tells which blob is which sphere: the unlabelled solver on the blobs, shuffled. Predicted from the noise-free ambiguity margin (the residual norm ‖r‖ of the best wrong labelling that is geometrically consistent): {}. A scenario is identifiable when its predicted wrong-label probability is at most {}. Monte-Carlo: {} trials per visible scenario (the validation's noise draws, seed {}, blobs shuffled), per-point gate {}σ; the wrong labellings are counted, a trial without any labelling counts as wrong. A wrong labelling that fits the blobs worse than the true labelling (refitted) means the solver's search lost the truth, which no margin predicts; the last column is the rest, the wrong labellings that fit better, which is what the prediction models.\n",
        s.model,
        significant(Some(1.0 - s.min_correct), 3),
        s.trials_per_scenario,
        s.seed,
        s.trial_gate_sigmas
    );
    let mut table = Table::new([
        "visible scenarios",
        "identifiable",
        "share",
        "smallest margin (px)",
        "mean predicted wrong",
        "Monte-Carlo wrong (trials)",
        "of which a better fit than the truth",
    ]);
    table.row([
        s.scenarios.to_string(),
        s.identifiable.to_string(),
        s.identifiable_share
            .map_or("—".into(), |v| format!("{:.1}%", 100.0 * v)),
        match (s.smallest_margin_px, s.scenarios) {
            (_, 0) => "— (nothing visible)".to_string(),
            (Some(m), _) => significant(Some(m), 3),
            (None, _) => format!("> {}σ everywhere", s.prediction_gate_sigmas),
        },
        significant(s.mean_predicted_wrong, 3),
        format!(
            "{} ({} of {}, {} without a labelling, {} fitting worse than the truth)",
            significant(s.monte_carlo_wrong, 3),
            s.trials.wrong,
            s.trials.trials,
            s.trials.failed,
            s.trials.missed
        ),
        significant(s.monte_carlo_ambiguous, 3),
    ]);
    out.push_str(&table.markdown());
    if !s.worst.is_empty() {
        let _ = writeln!(
            out,
            "\nScenarios that are not identifiable ({} of {}, first {}):\n",
            s.scenarios - s.identifiable,
            s.scenarios,
            s.worst.len()
        );
        for line in &s.worst {
            let _ = writeln!(out, "- {line}");
        }
    }
    for curve in &s.curves {
        let _ = writeln!(
            out,
            "\n### Identifiability vs {}\n\n![identifiability vs {}](identifiability_vs_{}.svg)\n\n[identifiability_vs_{}.csv](identifiability_vs_{}.csv)",
            curve.axis, curve.axis, curve.axis, curve.axis, curve.axis
        );
    }
    out.push('\n');
    out
}

fn systematic_markdown(s: &Systematic, observation: &str) -> String {
    let mut out = String::new();
    let _ = writeln!(
        out,
        "\n## Systematic and random error (visible scenarios)\n"
    );
    if s.scenarios == 0 {
        let _ = writeln!(out, "Nothing to measure: no scenario is visible.\n");
        return out;
    }
    let _ = writeln!(
        out,
        "Observation `{observation}`: the image point of each sphere is displaced from its projected centre by up to **{} px** (median over scenarios of the largest displacement {} px, {} scenarios). The systematic part is the pose error with zero noise; unlike the random part it does not average out over frames. Rotation about camera x, y, z (pitch, yaw, roll); RMS over scenarios.\n",
        significant(Some(s.max_displacement_px), 3),
        significant(Some(s.median_displacement_px), 3),
        s.scenarios
    );
    let mut table = Table::new([
        "part",
        "rot x (°)",
        "rot y (°)",
        "rot z (°)",
        "rot (°)",
        "max rot (°)",
        "trans (mm)",
        "max trans (mm)",
    ]);
    let mut row = |name: String, e: &AxisErrors| {
        let [x, y, z] = e.rms_rotation_per_axis_deg;
        table.row([
            name,
            significant(Some(x), 3),
            significant(Some(y), 3),
            significant(Some(z), 3),
            significant(Some(e.rms_rotation_deg), 3),
            significant(Some(e.max_rotation_deg), 3),
            significant(Some(e.rms_translation_mm), 3),
            significant(Some(e.max_translation_mm), 3),
        ]);
    };
    row("random, first-order (1σ)".into(), &s.first_order_random);
    row("systematic, first-order bias".into(), &s.first_order_bias);
    for (solver, errors) in &s.solvers {
        row(format!("systematic, `{solver}` at zero noise"), errors);
    }
    out.push_str(&table.markdown());
    out.push('\n');
    for (solver, errors) in &s.solvers {
        let failed = s.scenarios.saturating_sub(errors.scenarios);
        if failed == 0 {
            continue;
        }
        let _ = if errors.scenarios == 0 {
            writeln!(
                out,
                "`{solver}` returned no pose on any of the {} scenarios at zero noise, so its row has no figures (—).\n",
                s.scenarios
            )
        } else {
            writeln!(
                out,
                "`{solver}` returned no pose at zero noise on {failed} of the {} scenarios; its row pools the {} it solved.\n",
                s.scenarios, errors.scenarios
            )
        };
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_solver_without_a_pose_on_some_scenarios_says_so() {
        let solved = AxisErrors {
            scenarios: 4,
            ..AxisErrors::default()
        };
        let systematic = Systematic {
            scenarios: 4,
            solvers: vec![
                ("parallel-weighted".into(), solved),
                (
                    "epnp-gn".into(),
                    AxisErrors {
                        scenarios: 3,
                        ..solved
                    },
                ),
                ("parallel-gn".into(), AxisErrors::default()),
            ],
            ..Systematic::default()
        };
        let text = systematic_markdown(&systematic, "centre");
        assert!(!text.contains("`parallel-weighted` returned"), "{text}");
        assert!(
            text.contains("`epnp-gn` returned no pose at zero noise on 1 of the 4 scenarios; its row pools the 3 it solved."),
            "{text}"
        );
        assert!(
            text.contains("`parallel-gn` returned no pose on any of the 4 scenarios at zero noise, so its row has no figures (—)."),
            "{text}"
        );
    }

    #[test]
    fn axis_table_merges_runs_of_equal_counts() {
        let axis = AxisVisibility {
            axis: "tilt".into(),
            unit: "deg".into(),
            values: vec![-20.0, -10.0, 0.0, 10.0],
            counts: vec![
                [3, 0, 0, 0, 0],
                [3, 0, 0, 0, 0],
                [1, 2, 0, 0, 0],
                [3, 0, 0, 0, 0],
            ],
        };
        assert_eq!(
            axis_visibility_table(&axis).markdown(),
            "| tilt (deg) | visible | occluded | outside image | behind camera |\n|---|---|---|---|---|\n\
| -20 … -10 | 3 | 0 | 0 | 0 |\n| 0 | 1 | 2 | 0 | 0 |\n| 10 | 3 | 0 | 0 | 0 |\n"
        );
    }
}
