//! Experiment 5 (§4.3 "effect of the distance from the origin of the feature
//! point coordinate system to the optical axis", Figs. S1, S2): the paper's
//! biprism moved along Y away from the optical axis, at depths of 200 and
//! 100 mm.
//!
//! Protocol: origin at `(0, y, D)` with y = 1…476 mm in steps of 25 and
//! D = 200 mm (Fig. S1) or 100 mm (Fig. S2); the marker axes parallel to the
//! camera's (the paper fixes X and Z and gives no attitude; the base attitude
//! of our scenario convention); σ = √0.2 px; 100 noise trials per position.
//! The x axis is the paper's: y over the marker size L = 50 mm, so the last
//! position is the ratio 9.52 that the paper quotes.

use super::claims::{self, describe, num, Claim, PARALLEL_AMBIGUITY};
use super::engine::{find, group, stream};
use super::engine::{run_scenarios, scenario_cells, Context};
use super::panel::{two_worst, Metric, Panel};
use super::{paper_sigma_px, Experiment, ExperimentResult, PAPER_SOLVERS};
use crate::layout::{Layout, PAPER_ARM_MM};
use crate::scenario::Scenario;

/// Depths of Figs. S1 and S2, mm.
pub const DEPTHS_MM: [f64; 2] = [200.0, 100.0];
/// First Y offset, mm.
pub const OFFSET_START_MM: f64 = 1.0;
/// Y offset step, mm.
pub const OFFSET_STEP_MM: f64 = 25.0;
/// Number of Y offsets (1…476 mm).
pub const OFFSET_COUNT: usize = 20;
/// The paper's improvement of paraperspective by the weighting at ratio 9.52
/// (Fig. S2): rotation 2.2° → 0.62°.
pub const CLAIMED_ROTATION_FACTOR: f64 = 3.5;
/// … and translation 0.67% → 0.47%.
pub const CLAIMED_TRANSLATION_FACTOR: f64 = 1.42;

pub(crate) fn run(
    context: &Context,
    trials: usize,
) -> Result<ExperimentResult, super::ReproduceError> {
    let layout = Layout::paper_biprism();
    let object = layout.positions();
    let offsets: Vec<f64> = (0..OFFSET_COUNT)
        .map(|k| OFFSET_START_MM + OFFSET_STEP_MM * k as f64)
        .collect();
    context.progress.start(
        Experiment::OffAxis.name(),
        trials * offsets.len() * DEPTHS_MM.len(),
    );
    let mut panels = Vec::new();
    for (panel_index, (&depth_mm, (id, figure))) in DEPTHS_MM
        .iter()
        .zip([
            ("figS1_offaxis_200", "Fig. S1"),
            ("figS2_offaxis_100", "Fig. S2"),
        ])
        .enumerate()
    {
        let base = stream(Experiment::OffAxis, panel_index as u64) as usize;
        let scenarios: Vec<Scenario> = offsets
            .iter()
            .enumerate()
            .map(|(k, &offset_y_mm)| Scenario {
                index: base + k,
                depth_mm,
                offset_x_mm: 0.0,
                offset_y_mm,
                tilt_deg: 0.0,
                pan_deg: 0.0,
                roll_deg: 0.0,
                sigma_px: paper_sigma_px(),
            })
            .collect();
        let outcomes = run_scenarios(
            context,
            &object,
            layout.sphere_diameter_mm,
            &scenarios,
            trials,
        )?;
        let (cells, first_order) = outcomes
            .iter()
            .map(|o| scenario_cells(o, context, trials))
            .unzip();
        panels.push(Panel {
            id: id.into(),
            figure: figure.into(),
            title: format!(
                "Accuracy vs distance from the optical axis, biprism at depth {depth_mm} mm"
            ),
            x_label: "distance from the optical axis / L (L = 50 mm)".into(),
            x: offsets.iter().map(|y| y / PAPER_ARM_MM).collect(),
            solvers: context.solvers.clone(),
            cells,
            first_order,
            model_rotation: None,
        });
    }
    let claims = claims(context, &panels);
    Ok(ExperimentResult {
        experiment: Experiment::OffAxis,
        trials,
        setup: vec![
            format!("The paper's biprism (L = {PAPER_ARM_MM} mm), origin at (0, y, D) with y = {OFFSET_START_MM}…{} mm in steps of {OFFSET_STEP_MM}, D = 200 mm (Fig. S1) and 100 mm (Fig. S2); marker axes parallel to the camera's.", OFFSET_START_MM + OFFSET_STEP_MM * (OFFSET_COUNT - 1) as f64),
            format!("σ = √0.2 px; {trials} noise trials per position (the paper: 100). x axis: y / L, as the paper's (9.52 at y = 476 mm)."),
            "As in the paper's simulations, the image border and occlusion are ignored (most positions at D = 100 mm fall outside a 1280×720 image).".into(),
        ],
        panels,
        extra_markdown: String::new(),
        claims,
        extra_csv: Vec::new(),
        timing: None,
    })
}

fn claims(context: &Context, panels: &[Panel]) -> Vec<Claim> {
    let (paper, missing) = group(context, &PAPER_SOLVERS);
    let rot = Metric::Rotation;
    let mut out = Vec::new();

    // (1) DLT and EPnP are the most affected.
    let claim = Claim::new(
        "off-axis.dlt-epnp-most-affected",
        "§4.3 off-axis (1), Figs. S1, S2",
        "DLT and EPnP are the most affected by the distance from the optical axis, with large errors.",
        "in both figures, DLT and EPnP have the two largest mean E_rot (pooled over the offsets) among the paper solvers available",
    );
    match (find(context, "dlt"), find(context, "epnp")) {
        (Some(dlt), Some(epnp)) => {
            let (holds, evidence) = two_worst(panels, &paper, dlt, epnp);
            out.push(claim.judge(holds, evidence).missing(missing.clone()));
        }
        _ => out.push(claim.solvers_missing(vec!["dlt".into(), "epnp".into()])),
    }

    // (2) The others resist eccentricity.
    let claim = Claim::new(
        "off-axis.others-resist",
        "§4.3 off-axis (2), Figs. S1, S2",
        "The proposed method, OPnP, RPnP, LHM, DLS and EPnP+GN resist the change of eccentricity (the paper: E_rot from 0.2° to an upper bound lost in its text, which reads \"0.°\"; E_t 0.5–0.8%).",
        &format!("in both figures, each one's largest / smallest mean E_rot over the offsets ≤ {}", claims::FLAT_RATIO),
    );
    let (resist, resist_missing) = group(
        context,
        &["parallel-weighted", "opnp", "rpnp", "lhm", "dls", "epnp-gn"],
    );
    if resist.is_empty() {
        out.push(claim.solvers_missing(resist_missing));
    } else {
        let mut holds = true;
        let mut parts = Vec::new();
        let (mut rot_range, mut trans_range) = ((f64::INFINITY, 0.0f64), (f64::INFINITY, 0.0f64));
        for panel in panels {
            for &s in &resist {
                let (_, y) = panel.means(s, rot);
                let (lo, hi) = y.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), &v| {
                    (lo.min(v), hi.max(v))
                });
                let spread = hi / lo;
                holds &= spread <= claims::FLAT_RATIO;
                rot_range = (rot_range.0.min(lo), rot_range.1.max(hi));
                let (_, t) = panel.means(s, Metric::Translation);
                for v in t {
                    trans_range = (trans_range.0.min(v), trans_range.1.max(v));
                }
                parts.push(format!("{} {} ×{}", panel.figure, s.name(), num(spread)));
            }
        }
        out.push(
            claim
                .judge(
                    holds,
                    format!(
                        "largest/smallest: {}; ours: E_rot {}–{}°, E_t {}–{}%",
                        parts.join(", "),
                        num(rot_range.0),
                        num(rot_range.1),
                        num(trans_range.0),
                        num(trans_range.1)
                    ),
                )
                .missing(resist_missing),
        );
    }

    // (3) The weighting improves paraperspective far off the axis, near the camera.
    let near = &panels[1];
    let last = near.x.len() - 1;
    let pw = find(context, "parallel-weighted");
    for (id, other_name, statement) in [
        (
            "off-axis.weighting-improves-parallel-3.5x",
            "parallel-init",
            "At an off-axis/size ratio of 9.52 (depth 100 mm) the weighting cuts paraperspective's rotation error (the single step, the method's initial value) from 2.2° to 0.62° (3.5×) and its translation error from 0.67% to 0.47% (1.42×).",
        ),
        (
            "off-axis.weighting-improves-parallel-3.5x-iterated",
            "parallel",
            "The same claim, reading \"Parallel\" as Horaud's iteration to convergence.",
        ),
    ] {
        let claim = Claim::new(
            id,
            "§4.3 off-axis (3), Fig. S2",
            statement,
            &format!(
                "at ratio {} in Fig. S2: {other_name} / parallel-weighted mean E_rot ≥ {} and mean E_t ≥ {} (at least half of each claimed gain), with z ≥ {}",
                near.x[last],
                1.0 + 0.5 * (CLAIMED_ROTATION_FACTOR - 1.0),
                1.0 + 0.5 * (CLAIMED_TRANSLATION_FACTOR - 1.0),
                claims::SIGNIFICANCE_Z
            ),
        );
        match (pw, find(context, other_name)) {
            (Some(pw), Some(parallel)) => {
                let cells = near.cell(last, pw).zip(near.cell(last, parallel));
                let compared = cells.and_then(|(a, b)| {
                    let rotation = super::stats::compare(&b.rotation_deg, &a.rotation_deg)?;
                    let translation =
                        super::stats::compare(&b.translation_percent, &a.translation_percent)?;
                    Some((a, b, rotation, translation))
                });
                match compared {
                    Some((a, b, r, t)) => {
                        let holds = claims::reproduces_factor(CLAIMED_ROTATION_FACTOR, r.ratio)
                            && claims::reproduces_factor(CLAIMED_TRANSLATION_FACTOR, t.ratio)
                            && r.z >= claims::SIGNIFICANCE_Z;
                        let claim = claim.judge(
                            holds,
                            format!(
                                "E_rot {}° → {}° ({}), E_t {}% → {}% ({})",
                                num(b.rotation_deg.mean),
                                num(a.rotation_deg.mean),
                                describe(&r),
                                num(b.translation_percent.mean),
                                num(a.translation_percent.mean),
                                describe(&t)
                            ),
                        );
                        out.push(if other_name == "parallel" {
                            claim.ambiguity(PARALLEL_AMBIGUITY)
                        } else {
                            claim
                        });
                    }
                    None => out.push(claim.skip("not evaluated: no poses at ratio 9.52")),
                }
            }
            _ => out.push(claim.solvers_missing(vec![other_name.into()])),
        }
    }
    let claim = Claim::new(
        "off-axis.weights-beat-unweighted",
        "§4.3 off-axis (3), Fig. S2",
        "At ratio 9.52 near the camera, the weights themselves improve on the unweighted pipeline (ablation: parallel-gn).",
        "improvement rule on mean E_rot at ratio 9.52 in Fig. S2, parallel-weighted against parallel-gn",
    );
    match (pw, find(context, "parallel-gn")) {
        (Some(pw), Some(gn)) => {
            let pair = near.cell(last, pw).zip(near.cell(last, gn));
            match pair.and_then(|(a, b)| {
                claims::improves(&a.rotation_deg, &b.rotation_deg).map(|r| (a, b, r))
            }) {
                Some((a, b, (holds, c))) => out.push(claim.judge_order(
                    holds,
                    &c,
                    format!(
                        "parallel-gn {}° vs parallel-weighted {}°: {}",
                        num(b.rotation_deg.mean),
                        num(a.rotation_deg.mean),
                        describe(&c)
                    ),
                )),
                None => out.push(claim.skip("not evaluated: no poses at ratio 9.52")),
            }
        }
        _ => out.push(claim.solvers_missing(vec!["parallel-gn".into()])),
    }
    out
}
