//! Experiment 7: the paper's real-image protocol (§4.2 2), Tables I–XV),
//! simulated, since its images are not available.
//!
//! Protocol: the paper's biprism (L = 50 mm, 10 mm spheres) at depths
//! 200…1000 mm in steps of 200, X offsets 0, 50 and 100 mm, tilted about X
//! from −90° to 90° in steps of 2°, 30 noise draws per pose by default.
//!
//! **The noise level is calibrated**, not taken as σ = √0.2 px: at √0.2 px
//! our errors were about 10× below the paper's tables, whose real images of
//! 10 mm spheres carry more centre noise than the simulations' "variance
//! 0.2". σ is scaled until [`CALIBRATION_SOLVER`] reproduces its mean RE in
//! the paper's Table III ([`CALIBRATION_TABLE_RE_DEG`]); that solver is
//! then left out of every verdict, and the others are judged at that σ.
//! Like the paper's tables, each cell averages the errors over the poses at
//! one (depth, offset); we average over the poses in which no sphere's image
//! overlaps a nearer sphere's (an occluded centre cannot be measured).
//!
//! **The image border is ignored**, as in the paper's simulations. With the
//! stated camera (1280×720, cy = 508) no pose at 200 mm keeps every sphere
//! inside the frame, yet the paper photographed the marker there; its
//! principal point suggests a taller sensor. The tables count the poses that
//! would leave a 1280×720 frame.
//!
//! Differences from the paper: errors are absolute per simulated image, not
//! relative between consecutive images (eq. 33 applied to `R_{i−1}ᵀ R_i`);
//! noise is simulated Gaussian, not the three lighting conditions.

use super::claims::{self, describe, num, Claim};
use super::engine::{find, group, stream};
use super::engine::{run_scenarios, run_scenarios_with, scenario_cells, Context};
use super::panel::{Cell, FirstOrderLine, Metric, Panel};
use super::{paper_sigma_px, Experiment, ExperimentResult, PAPER_SOLVERS};
use crate::layout::Layout;
use crate::pnp::Solver;
use crate::report::{significant, Table};
use crate::scenario::{Range, Scenario, ScenarioGrid};
use crate::statistics::median;
use std::fmt::Write as _;

/// Depths, mm.
pub const DEPTHS_MM: [f64; 5] = [200.0, 400.0, 600.0, 800.0, 1000.0];
/// X offsets, mm.
pub const OFFSETS_MM: [f64; 3] = [0.0, 50.0, 100.0];
/// Tilt about X: range and step, degrees.
pub const TILT_RANGE_DEG: (f64, f64, f64) = (-90.0, 90.0, 2.0);
/// The solver whose error in one of the paper's tables sets σ. DLS is a
/// closed-form solver with no start and no iterations to stop, so its error
/// is set by the noise alone; in the paper's tables it sits in the middle
/// of the accurate group, and of the claims here only one names it (in a
/// group of four).
pub const CALIBRATION_SOLVER: Solver = Solver::Dls;
/// The table that sets σ: Table III, the marker at 600 mm under the
/// atmospheric spotlight (the first lighting condition). It is the middle
/// depth and has all three offsets (Table I has only the axis).
pub const CALIBRATION_DEPTH_MM: f64 = 600.0;
/// [`CALIBRATION_SOLVER`]'s RE (°) in Table III at offsets 0, 50 and
/// 100 mm; the calibration matches their mean.
pub const CALIBRATION_TABLE_RE_DEG: [f64; 3] = [2.98, 2.93, 2.90];
/// Passes of the calibration: σ is rescaled by target / measured after each
/// (the error is nearly linear in σ; the second pass takes up the rest).
pub const CALIBRATION_PASSES: usize = 2;

/// The calibrated noise level and what it took.
#[derive(Debug, Clone, Copy)]
struct Calibration {
    /// σ the protocol runs at, px.
    sigma_px: f64,
    /// The calibrating solver's mean RE at Table III's poses at σ = √0.2 px.
    uncalibrated_re_deg: f64,
}

/// The paper's Table III target: the mean of [`CALIBRATION_TABLE_RE_DEG`].
fn calibration_target_deg() -> f64 {
    CALIBRATION_TABLE_RE_DEG.iter().sum::<f64>() / CALIBRATION_TABLE_RE_DEG.len() as f64
}

/// Tilts per (depth, offset).
fn tilt_count() -> usize {
    let (start, end, step) = TILT_RANGE_DEG;
    ((end - start) / step).round() as usize + 1
}

/// The mean over the offsets of `solver`'s (column `j` of the outcomes)
/// mean RE at `depth_mm`, each offset pooled over its unoccluded poses.
fn mean_re_over_offsets(
    outcomes: &[crate::montecarlo::ScenarioOutcome],
    depth_mm: f64,
    solver: Solver,
    j: usize,
    trials: usize,
) -> Option<f64> {
    let means: Vec<f64> = OFFSETS_MM
        .iter()
        .filter_map(|&offset_mm| {
            let cells: Vec<Cell> = outcomes
                .iter()
                .filter(|o| {
                    o.scenario.depth_mm == depth_mm
                        && o.scenario.offset_x_mm == offset_mm
                        && measurable(o)
                })
                .filter_map(|o| o.solvers.get(j).map(|r| Cell::from_outcome(r, trials)))
                .collect();
            Cell::pool(solver, cells.iter()).rotation_deg.mean()
        })
        .collect();
    (!means.is_empty()).then(|| means.iter().sum::<f64>() / means.len() as f64)
}

/// The protocol's poses at `depths` and noise level `sigma_px`, numbered
/// from `base`.
fn protocol_scenarios(depths: &[f64], sigma_px: f64, base: usize) -> Vec<Scenario> {
    let (start, end, step) = TILT_RANGE_DEG;
    let grid = ScenarioGrid::new(
        Range::list(depths),
        Range::list(&OFFSETS_MM),
        Range::single(0.0),
        Range::stepped(start, end, step).expect("a positive step"),
        Range::single(0.0),
        Range::single(0.0),
        Range::single(sigma_px),
    )
    .expect("the protocol grid is valid");
    grid.scenarios()
        .into_iter()
        .map(|s| Scenario {
            index: base + s.index,
            ..s
        })
        .collect()
}

/// Scales σ until [`CALIBRATION_SOLVER`] at Table III's poses reproduces the
/// paper's mean RE there. Every pass draws the same unit noise (one
/// stream), so the passes differ only in σ.
fn calibrate(
    context: &Context,
    object: &[nalgebra::Vector3<f64>],
    sphere_diameter_mm: f64,
    trials: usize,
) -> Result<Calibration, super::ReproduceError> {
    let base = stream(Experiment::Protocol, 1) as usize;
    let target = calibration_target_deg();
    let mut sigma_px = paper_sigma_px();
    let mut uncalibrated_re_deg = f64::NAN;
    for pass in 0..CALIBRATION_PASSES {
        let scenarios = protocol_scenarios(&[CALIBRATION_DEPTH_MM], sigma_px, base);
        let outcomes = run_scenarios_with(
            context,
            &[CALIBRATION_SOLVER],
            object,
            sphere_diameter_mm,
            &scenarios,
            trials,
        )?;
        let measured = mean_re_over_offsets(
            &outcomes,
            CALIBRATION_DEPTH_MM,
            CALIBRATION_SOLVER,
            0,
            trials,
        )
        .filter(|m| *m > 0.0);
        let Some(measured) = measured else {
            // Nothing measurable at 600 mm: keep the paper's σ.
            return Ok(Calibration {
                sigma_px: paper_sigma_px(),
                uncalibrated_re_deg,
            });
        };
        if pass == 0 {
            uncalibrated_re_deg = measured;
        }
        sigma_px *= target / measured;
    }
    Ok(Calibration {
        sigma_px,
        uncalibrated_re_deg,
    })
}

/// The paper's bound on the accurate methods' variation with the offset.
pub const OFFSET_VARIATION_ROTATION_DEG: f64 = 0.7;
/// See [`OFFSET_VARIATION_ROTATION_DEG`].
pub const OFFSET_VARIATION_TRANSLATION_PERCENT: f64 = 1.0;

/// One (depth, offset) cell of the tables.
struct Block {
    depth_mm: f64,
    offset_mm: f64,
    /// Poses pooled (no sphere occluded).
    visible: usize,
    /// Poses with every sphere inside the 1280×720 frame as well.
    in_frame: usize,
    poses: usize,
    cells: Vec<Cell>,
    first_order: Option<FirstOrderLine>,
}

pub(crate) fn run(
    context: &Context,
    trials: usize,
) -> Result<ExperimentResult, super::ReproduceError> {
    let layout = Layout::paper_biprism();
    let object = layout.positions();
    let (start, end, step) = TILT_RANGE_DEG;
    let calibration_poses = OFFSETS_MM.len() * tilt_count();
    let poses = DEPTHS_MM.len() * calibration_poses;
    context.progress.start(
        Experiment::Protocol.name(),
        trials * (poses + CALIBRATION_PASSES * calibration_poses),
    );
    let calibration = calibrate(context, &object, layout.sphere_diameter_mm, trials)?;
    let scenarios = protocol_scenarios(
        &DEPTHS_MM,
        calibration.sigma_px,
        stream(Experiment::Protocol, 0) as usize,
    );
    let outcomes = run_scenarios(
        context,
        &object,
        layout.sphere_diameter_mm,
        &scenarios,
        trials,
    )?;

    let mut blocks = Vec::new();
    for &depth_mm in &DEPTHS_MM {
        for &offset_mm in &OFFSETS_MM {
            let here: Vec<_> = outcomes
                .iter()
                .filter(|o| o.scenario.depth_mm == depth_mm && o.scenario.offset_x_mm == offset_mm)
                .collect();
            let in_frame = here.iter().filter(|o| o.visibility.is_visible()).count();
            let visible: Vec<_> = here
                .iter()
                .filter(|o| measurable(o))
                .map(|o| scenario_cells(o, context, trials))
                .collect();
            let cells = context
                .solvers
                .iter()
                .enumerate()
                .map(|(j, &solver)| Cell::pool(solver, visible.iter().map(|(cells, _)| &cells[j])))
                .collect();
            let limits: Vec<FirstOrderLine> = visible.iter().filter_map(|(_, f)| *f).collect();
            let first_order = (!limits.is_empty()).then(|| {
                let n = limits.len() as f64;
                let rms = |f: &dyn Fn(&FirstOrderLine) -> f64| {
                    (limits.iter().map(|l| f(l).powi(2)).sum::<f64>() / n).sqrt()
                };
                FirstOrderLine {
                    rms_rotation_deg: rms(&|l| l.rms_rotation_deg),
                    rms_translation_percent: rms(&|l| l.rms_translation_percent),
                }
            });
            blocks.push(Block {
                depth_mm,
                offset_mm,
                visible: visible.len(),
                in_frame,
                poses: here.len(),
                cells,
                first_order,
            });
        }
    }

    let panels: Vec<Panel> = OFFSETS_MM
        .iter()
        .map(|&offset_mm| {
            let row: Vec<&Block> = blocks.iter().filter(|b| b.offset_mm == offset_mm).collect();
            Panel {
                id: format!("tables_protocol_offset{offset_mm}"),
                figure: "Tables I–XV".into(),
                title: format!(
                    "Simulated protocol, X offset {offset_mm} mm, mean over unoccluded tilts"
                ),
                x_label: "depth (mm)".into(),
                x: row.iter().map(|b| b.depth_mm).collect(),
                solvers: context.solvers.clone(),
                cells: row.iter().map(|b| b.cells.clone()).collect(),
                first_order: row.iter().map(|b| b.first_order).collect(),
                model_rotation: None,
            }
        })
        .collect();

    let claims = claims(context, &blocks);
    Ok(ExperimentResult {
        experiment: Experiment::Protocol,
        trials,
        setup: vec![
            format!("The paper's biprism (L = 50 mm, {} mm spheres) at depths 200…1000 mm in steps of 200, X offsets 0, 50 and 100 mm, marker axes parallel to the camera's, tilted about X from {start}° to {end}° in steps of {step}° ({} poses).", layout.sphere_diameter_mm, scenarios.len()),
            format!(
                "σ = {} px, calibrated: at the paper's σ = √0.2 px, `{}` averaged {}° RE at Table III's poses (600 mm, the three offsets) against the paper's {}° (the mean of its Table III row, {}); σ was scaled until they matched ({CALIBRATION_PASSES} passes), and `{}` reaches {}° in the run below. `{}` is therefore left out of every verdict; the other solvers are judged at this σ. {trials} noise draws per pose (the paper: one image per pose).",
                num(calibration.sigma_px),
                CALIBRATION_SOLVER.name(),
                num(calibration.uncalibrated_re_deg),
                num(calibration_target_deg()),
                CALIBRATION_TABLE_RE_DEG.map(|v| format!("{v:.2}°")).join(", "),
                CALIBRATION_SOLVER.name(),
                num(
                    context
                        .solvers
                        .iter()
                        .position(|&s| s == CALIBRATION_SOLVER)
                        .and_then(|j| mean_re_over_offsets(&outcomes, CALIBRATION_DEPTH_MM, CALIBRATION_SOLVER, j, trials))
                        .unwrap_or(f64::NAN)
                ),
                CALIBRATION_SOLVER.name(),
            ),
            "Each table cell is the mean over the poses at that (depth, offset) in which no sphere's image disc overlaps a nearer sphere's (an occluded centre cannot be measured). The image border is ignored, as in the paper's simulations: with the stated 1280×720 frame and cy = 508, no pose at 200 mm keeps every sphere inside the frame, yet the paper photographed the marker there (its principal point suggests a taller sensor). So unlike the paper's Table I, the 200 mm table has all three offsets; the column \"in 1280×720\" counts the poses that stay inside that frame.".into(),
            "Errors are absolute per simulated image; the paper's are relative between consecutive real images (eq. 33 on R_{i−1}ᵀR_i), which for independent errors are about √2 larger. The three lighting conditions (Tables I–V, VI–X, XI–XV) cannot be simulated; one table per depth stands for all three.".into(),
        ],
        extra_markdown: tables_markdown(context, &blocks),
        panels,
        claims,
        extra_csv: vec![("protocol_scenarios.csv".into(), scenario_csv(context, &outcomes, trials))],
        timing: None,
    })
}

/// Every sphere in front of the camera and none occluded by a nearer one
/// (the image border is ignored, see the module documentation).
fn measurable(outcome: &crate::montecarlo::ScenarioOutcome) -> bool {
    outcome.visibility.behind.is_empty() && outcome.visibility.occluded.is_empty()
}

fn tables_markdown(context: &Context, blocks: &[Block]) -> String {
    let mut out = String::from("### Tables I–XV, simulated: RE (°) and TE (%) per solver\n\nLaid out as the paper's tables: one table per depth, a pair of rows (RE = mean E_rot, TE = mean E_t) per X offset, one column per solver. \"pooled\" counts the unoccluded tilts averaged, out of 91; \"in 1280×720\" how many of all 91 keep every sphere inside that frame.\n");
    for (k, &depth_mm) in DEPTHS_MM.iter().enumerate() {
        let _ = writeln!(
            out,
            "\n**Table {}: the marker {} mm from the camera**\n",
            ["I", "II", "III", "IV", "V"][k],
            depth_mm
        );
        let mut table = Table::new(
            ["offset (mm)", "Err"]
                .into_iter()
                .map(String::from)
                .chain(context.solvers.iter().map(|s| format!("`{}`", s.name())))
                .chain([
                    "first-order (RMS)".into(),
                    "pooled".into(),
                    "in 1280×720".into(),
                ]),
        );
        for block in blocks.iter().filter(|b| b.depth_mm == depth_mm) {
            for (metric, label) in [
                (Metric::Rotation, "RE (°)"),
                (Metric::Translation, "TE (%)"),
            ] {
                let limit = block.first_order.map(|f| match metric {
                    Metric::Rotation => f.rms_rotation_deg,
                    Metric::Translation => f.rms_translation_percent,
                });
                table.row(
                    [
                        if metric == Metric::Rotation {
                            block.offset_mm.to_string()
                        } else {
                            String::new()
                        },
                        label.to_string(),
                    ]
                    .into_iter()
                    .chain(
                        block
                            .cells
                            .iter()
                            .map(|c| significant(c.stat(metric).mean(), 3)),
                    )
                    .chain([
                        significant(limit, 3),
                        format!("{}/{}", block.visible, block.poses),
                        format!("{}/{}", block.in_frame, block.poses),
                    ]),
                );
            }
        }
        out.push_str(&table.markdown());
    }
    out.push_str("\n`protocol_scenarios.csv` has every pose, visible or not.\n");
    out
}

fn scenario_csv(
    context: &Context,
    outcomes: &[crate::montecarlo::ScenarioOutcome],
    trials: usize,
) -> String {
    let mut table = Table::new([
        "depth_mm",
        "offset_x_mm",
        "tilt_deg",
        "unoccluded",
        "in_frame",
        "solver",
        "poses",
        "solver_errors",
        "gross_failures",
        "mean_erot_deg",
        "median_erot_deg",
        "mean_et_percent",
        "first_order_rms_rot_deg",
    ]);
    let number = |v: Option<f64>| v.map_or(String::new(), |v| format!("{v:.6e}"));
    for o in outcomes {
        let (cells, limit) = scenario_cells(o, context, trials);
        for cell in cells {
            table.row([
                o.scenario.depth_mm.to_string(),
                o.scenario.offset_x_mm.to_string(),
                o.scenario.tilt_deg.to_string(),
                measurable(o).to_string(),
                o.visibility.is_visible().to_string(),
                cell.solver.name().to_string(),
                cell.rotation_deg.count.to_string(),
                cell.solver_errors.to_string(),
                cell.gross_failures.to_string(),
                number(cell.rotation_deg.mean()),
                number(cell.rotation_deg.median),
                number(cell.translation_percent.mean()),
                number(limit.map(|l| l.rms_rotation_deg)),
            ]);
        }
    }
    table.csv().expect("CSV of strings")
}

fn block(blocks: &[Block], depth_mm: f64, offset_mm: f64) -> Option<&Block> {
    blocks
        .iter()
        .find(|b| b.depth_mm == depth_mm && b.offset_mm == offset_mm && b.visible > 0)
}

fn claims(context: &Context, blocks: &[Block]) -> Vec<Claim> {
    // The calibrating solver matches the paper by construction: judged,
    // it would vote for whatever the calibration made it say.
    let (mut paper, missing) = group(context, &PAPER_SOLVERS);
    paper.retain(|&s| s != CALIBRATION_SOLVER);
    let index = |s: Solver| context.solvers.iter().position(|&o| o == s);
    let mean_at = |b: &Block, s: Solver, metric: Metric| {
        index(s).and_then(|j| b.cells[j].stat(metric).mean())
    };
    let pooled = |s: Solver| {
        let j = index(s)?;
        Cell::pool(
            s,
            blocks.iter().filter(|b| b.visible > 0).map(|b| &b.cells[j]),
        )
        .rotation_deg
        .mean()
    };
    let (near, far) = (
        block(blocks, DEPTHS_MM[0], 0.0),
        block(blocks, DEPTHS_MM[4], 0.0),
    );
    let growth = |s: Solver, metric: Metric| -> Option<f64> {
        Some(mean_at(far?, s, metric)? / mean_at(near?, s, metric)?)
    };
    let mut out = Vec::new();

    // (1) Errors grow significantly with depth.
    let claim = Claim::new(
        "protocol.errors-grow-with-depth",
        "§4.3 real images (1), Tables I–XV",
        "Both rotation and translation errors increase significantly with depth, from 200 to 1000 mm.",
        &format!("for every paper solver available, on the optical axis: mean RE and mean TE at 1000 mm ≥ {} × at 200 mm", claims::DEPTH_GROWTH),
    );
    let mut holds = !paper.is_empty();
    let mut parts = Vec::new();
    for &s in &paper {
        let (r, t) = (
            growth(s, Metric::Rotation).unwrap_or(f64::NAN),
            growth(s, Metric::Translation).unwrap_or(f64::NAN),
        );
        holds &= r >= claims::DEPTH_GROWTH && t >= claims::DEPTH_GROWTH;
        parts.push(format!("{} RE ×{}, TE ×{}", s.name(), num(r), num(t)));
    }
    out.push(
        claim
            .judge(holds, parts.join("; "))
            .missing(missing.clone()),
    );

    // (1) DLT and EPnP have the highest errors.
    let claim = Claim::new(
        "protocol.dlt-epnp-highest",
        "§4.3 real images (1), (4), Tables I–XV",
        "DLT and EPnP have the highest errors.",
        "DLT and EPnP have the two largest mean RE, pooled over every unoccluded pose, among the paper solvers available",
    );
    let mut ranked: Vec<(Solver, f64)> = paper
        .iter()
        .filter_map(|&s| pooled(s).map(|m| (s, m)))
        .collect();
    ranked.sort_by(|a, b| b.1.total_cmp(&a.1));
    let ranking = ranked
        .iter()
        .map(|(s, m)| format!("{} {}°", s.name(), num(*m)))
        .collect::<Vec<_>>()
        .join(" > ");
    match (find(context, "dlt"), find(context, "epnp")) {
        (Some(dlt), Some(epnp)) => {
            let top: Vec<Solver> = ranked.iter().take(2).map(|r| r.0).collect();
            out.push(
                claim
                    .judge(top.contains(&dlt) && top.contains(&epnp), ranking.clone())
                    .missing(missing.clone()),
            );
        }
        _ => out.push(claim.solvers_missing(vec!["dlt".into(), "epnp".into()])),
    }

    // (1), (4) Parallel and parallel-weighted adapt better to depth.
    let claim = Claim::new(
        "protocol.parallel-adapts-to-depth",
        "§4.3 real images (1), (2), (4), Tables I–XV",
        "Parallel and parallel-weighted are more adaptable to depth: their errors grow less from 200 to 1000 mm.",
        "each one's RE growth (1000 mm / 200 mm, on the axis) ≤ the median growth of the other paper solvers available",
    );
    let (named, named_missing) = group(context, &["parallel", "parallel-weighted"]);
    if named.is_empty() {
        out.push(claim.solvers_missing(named_missing));
    } else {
        let mut others: Vec<f64> = paper
            .iter()
            .filter(|s| !named.contains(s))
            .filter_map(|&s| growth(s, Metric::Rotation))
            .collect();
        let reference = median(&mut others).unwrap_or(f64::NAN);
        let mut holds = true;
        let mut parts = Vec::new();
        for &s in &named {
            let g = growth(s, Metric::Rotation).unwrap_or(f64::NAN);
            holds &= g <= reference;
            parts.push(format!("{} ×{}", s.name(), num(g)));
        }
        out.push(
            claim
                .judge(
                    holds,
                    format!(
                        "{}; the others' median ×{}",
                        parts.join(", "),
                        num(reference)
                    ),
                )
                .missing(named_missing),
        );
    }

    // (3) Consistent with OPnP, LHM, RPnP and DLS.
    let pw = find(context, "parallel-weighted");
    let claim = Claim::new(
        "protocol.consistent-with-opnp-lhm-rpnp-dls",
        "§4.3 real images (3), §5.4",
        "The proposed method's accuracy is consistent with OPnP, LHM, RPnP and DLS.",
        &format!(
            "parallel-weighted / the median of those methods' mean RE (without `{1}`, which calibrates σ), pooled over every unoccluded pose, within [1/{0}, {0}]",
            claims::COMPARABLE_RATIO,
            CALIBRATION_SOLVER.name()
        ),
    );
    let (mut refs, refs_missing) = group(context, &["opnp", "lhm", "rpnp", "dls"]);
    refs.retain(|&s| s != CALIBRATION_SOLVER);
    match pw {
        Some(pw) if !refs.is_empty() => {
            let mut reference: Vec<f64> = refs.iter().filter_map(|&s| pooled(s)).collect();
            let (holds, ratio) = claims::comparable(
                pooled(pw).unwrap_or(f64::NAN),
                median(&mut reference).unwrap_or(f64::NAN),
            );
            out.push(
                claim
                    .judge(holds, format!("ratio {}", num(ratio)))
                    .missing(refs_missing),
            );
        }
        _ => out.push(claim.solvers_missing(refs_missing)),
    }

    // (5) DLT and EPnP are sensitive to the offset; the others vary little.
    let claim = Claim::new(
        "protocol.offset-sensitivity",
        "§4.3 real images (5)",
        "DLT and EPnP are very sensitive to the optical-axis offset; the other methods vary within 0.7° (RE) and 1% (TE) with the offset.",
        &format!("at every depth with more than one offset: each other paper solver's range of mean RE over the offsets ≤ {OFFSET_VARIATION_ROTATION_DEG}° and of mean TE ≤ {OFFSET_VARIATION_TRANSLATION_PERCENT}%; and DLT's and EPnP's largest RE range exceeds every other's"),
    );
    match (find(context, "dlt"), find(context, "epnp")) {
        (Some(dlt), Some(epnp)) => {
            let range_of = |s: Solver, metric: Metric| -> f64 {
                DEPTHS_MM
                    .iter()
                    .filter_map(|&d| {
                        let values: Vec<f64> = OFFSETS_MM
                            .iter()
                            .filter_map(|&o| mean_at(block(blocks, d, o)?, s, metric))
                            .collect();
                        (values.len() > 1).then(|| {
                            values.iter().copied().fold(f64::NEG_INFINITY, f64::max)
                                - values.iter().copied().fold(f64::INFINITY, f64::min)
                        })
                    })
                    .fold(0.0, f64::max)
            };
            let others: Vec<Solver> = paper
                .iter()
                .copied()
                .filter(|&s| s != dlt && s != epnp)
                .collect();
            let other_rot = others
                .iter()
                .map(|&s| range_of(s, Metric::Rotation))
                .fold(0.0, f64::max);
            let other_trans = others
                .iter()
                .map(|&s| range_of(s, Metric::Translation))
                .fold(0.0, f64::max);
            let (dlt_range, epnp_range) = (
                range_of(dlt, Metric::Rotation),
                range_of(epnp, Metric::Rotation),
            );
            let holds = other_rot <= OFFSET_VARIATION_ROTATION_DEG
                && other_trans <= OFFSET_VARIATION_TRANSLATION_PERCENT
                && dlt_range > other_rot
                && epnp_range > other_rot;
            out.push(
                claim
                    .judge(
                        holds,
                        format!(
                            "largest RE range over offsets: DLT {}°, EPnP {}°, others ≤ {}°; others' TE range ≤ {}%",
                            num(dlt_range),
                            num(epnp_range),
                            num(other_rot),
                            num(other_trans)
                        ),
                    )
                    .missing(missing.clone()),
            );
        }
        _ => out.push(claim.solvers_missing(vec!["dlt".into(), "epnp".into()])),
    }

    // Conclusion: one of the best.
    let claim = Claim::new(
        "protocol.proposed-among-best",
        "§4.3 real images, conclusion",
        "The proposed method is one of the best and most stable algorithms.",
        &format!(
            "parallel-weighted's mean RE, pooled over every unoccluded pose, ≤ {} × the best paper solver's",
            claims::BEST_TOLERANCE
        ),
    );
    match (pw, ranked.last()) {
        (Some(pw), Some(&(best, best_mean))) => {
            let ratio = pooled(pw).unwrap_or(f64::NAN) / best_mean;
            out.push(
                claim
                    .judge(
                        ratio <= claims::BEST_TOLERANCE,
                        format!(
                            "{}× the best ({} {}°)",
                            num(ratio),
                            best.name(),
                            num(best_mean)
                        ),
                    )
                    .missing(missing.clone()),
            );
        }
        _ => out.push(claim.solvers_missing(vec!["parallel-weighted".into()])),
    }

    // Columns: error changes more the further from the axis.
    let claim = Claim::new(
        "protocol.error-grows-with-offset",
        "§4.3 real images, conclusion",
        "The further from the optical axis, the larger the pose error.",
        "improvement rule on mean RE pooled over the depths where every offset has unoccluded poses: offset 0 against offset 100 mm, for every paper solver available",
    )
    // The offset changes which tilts are pooled: more of them hide a
    // sphere on the axis than off it, so the pooled sets differ.
    .ambiguity("which tilts a table cell averages: the paper's are its 90 photographs, ours the unoccluded poses, and fewer tilts are unoccluded on the axis than 100 mm off it");
    let shared: Vec<f64> = DEPTHS_MM
        .iter()
        .copied()
        .filter(|&d| OFFSETS_MM.iter().all(|&o| block(blocks, d, o).is_some()))
        .collect();
    let mut tally = claims::Tally::default();
    tally.check(!paper.is_empty() && !shared.is_empty());
    let mut parts = Vec::new();
    for &s in &paper {
        let Some(j) = index(s) else { continue };
        let at = |offset: f64| {
            Cell::pool(
                s,
                shared
                    .iter()
                    .filter_map(|&d| block(blocks, d, offset))
                    .map(|b| &b.cells[j]),
            )
        };
        match claims::improves(&at(0.0).rotation_deg, &at(100.0).rotation_deg) {
            Some((ok, c)) => {
                tally.order(ok, &c);
                parts.push(format!("{} {}", s.name(), describe(&c)));
            }
            None => tally.check(false),
        }
    }
    out.push(
        claim
            .decide(
                tally.verdict(),
                format!("RE(100 mm) / RE(0): {}", parts.join(", ")),
            )
            .missing(missing),
    );

    // Lighting conditions need real images.
    out.push(
        Claim::new(
            "protocol.lighting",
            "§4.3 real images (2)–(4), §5.4",
            "Lighting (strong light, surgical shadowless lamp, underwater low light) changes the accuracy; parallel and parallel-weighted are the most robust to it.",
            "needs the paper's real images",
        )
        .skip("not evaluated: needs the paper's real images, which we do not have; Gaussian pixel noise cannot stand in for lighting"),
    );
    out
}
