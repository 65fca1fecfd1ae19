//! Experiment 2 (§4.3 "impact of noise on algorithmic accuracy", Figs. 8, 9a,
//! 9b): accuracy against pixel noise σ = 0.5…10 px, for n = 10 random points
//! and for the paper's biprism with L = 25 and 100 mm.
//!
//! Protocol (§4.2): the 10 points are uniform in the camera-frame box
//! `[−500, 500]² × [500, 1500]` mm with a random object attitude; the biprism's
//! origin is uniform in the same box with a uniformly random attitude. 500
//! trials. Within a trial every σ uses the same geometry and unit noise, and
//! the two biprism sizes share their poses and noise (common random numbers).

use super::claims::{self, describe, num, Claim};
use super::engine::{
    camera_box_points, from_camera_points, random_rotation, run_random, unit_noise, Context,
    Instance,
};
use super::engine::{find, group, stream};
use super::panel::{Metric, Panel};
use super::stats::{line_fit, spearman};
use super::{Experiment, ExperimentResult, PAPER_SOLVERS};
use crate::pnp::Solver;
use crate::pose::Pose;
use crate::report::Table;
use crate::synthetic::biprism_points;
use nalgebra::Vector3;
use rand::Rng;
use std::fmt::Write as _;

/// Smallest σ, px.
pub const SIGMA_MIN_PX: f64 = 0.5;
/// Largest σ, px.
pub const SIGMA_MAX_PX: f64 = 10.0;
/// σ step, px.
pub const SIGMA_STEP_PX: f64 = 0.5;
/// Random points of the first panel.
pub const RANDOM_COUNT: usize = 10;
/// The biprism sizes L of Figs. 9a and 9b, mm.
pub const BIPRISM_ARMS_MM: [f64; 2] = [25.0, 100.0];
/// Box of the points and of the biprism origin (§4.2), mm.
const BOX: (f64, f64, f64) = (500.0, 500.0, 1500.0);

/// The closed-form methods of the paper's comparison (OPnP is compared with these).
const CLOSED_FORM: [&str; 8] = [
    "dlt",
    "epnp",
    "epnp-gn",
    "dls",
    "rpnp",
    "opnp",
    "parallel",
    "parallel-weighted",
];

pub(crate) fn run(context: &Context, trials: usize) -> ExperimentResult {
    let sigmas: Vec<f64> = (0..)
        .map(|k| SIGMA_MIN_PX + SIGMA_STEP_PX * k as f64)
        .take_while(|s| *s <= SIGMA_MAX_PX + 1e-9)
        .collect();
    context
        .progress
        .start(Experiment::Noise.name(), 3 * trials * sigmas.len());
    let random = |rng: &mut rand_chacha::ChaCha8Rng, setting: usize| {
        let points = camera_box_points(rng, RANDOM_COUNT, BOX.0, BOX.1, BOX.2);
        let rotation = random_rotation(rng);
        let noise = unit_noise(rng, RANDOM_COUNT);
        let (object, truth) = from_camera_points(&points, rotation);
        Instance {
            object,
            truth,
            sigma_px: sigmas[setting],
            unit_noise: noise,
        }
    };
    let biprism = |arm_mm: f64| {
        let sigmas = &sigmas;
        move |rng: &mut rand_chacha::ChaCha8Rng, setting: usize| {
            let origin = Vector3::new(
                (rng.random::<f64>() * 2.0 - 1.0) * BOX.0,
                (rng.random::<f64>() * 2.0 - 1.0) * BOX.0,
                BOX.1 + rng.random::<f64>() * (BOX.2 - BOX.1),
            );
            let rotation = random_rotation(rng);
            let object = biprism_points(arm_mm);
            let noise = unit_noise(rng, object.len());
            Instance {
                object,
                truth: Pose::new(rotation, origin),
                sigma_px: sigmas[setting],
                unit_noise: noise,
            }
        }
    };
    let mut panels = Vec::new();
    let (cells, first_order) = run_random(
        context,
        stream(Experiment::Noise, 0),
        trials,
        sigmas.len(),
        &random,
    );
    panels.push(Panel {
        id: "fig8_noise_n10".into(),
        figure: "Fig. 8".into(),
        title: "Accuracy vs noise, n = 10 random points".into(),
        x_label: "σ (px)".into(),
        x: sigmas.clone(),
        solvers: context.solvers.clone(),
        cells,
        first_order,
        model_rotation: None,
    });
    for (arm_mm, id, figure) in [
        (BIPRISM_ARMS_MM[0], "fig9a_noise_biprism25", "Fig. 9a"),
        (BIPRISM_ARMS_MM[1], "fig9b_noise_biprism100", "Fig. 9b"),
    ] {
        let generate = biprism(arm_mm);
        let (cells, first_order) = run_random(
            context,
            stream(Experiment::Noise, 1),
            trials,
            sigmas.len(),
            &generate,
        );
        panels.push(Panel {
            id: id.into(),
            figure: figure.into(),
            title: format!("Accuracy vs noise, biprism L = {arm_mm} mm"),
            x_label: "σ (px)".into(),
            x: sigmas.clone(),
            solvers: context.solvers.clone(),
            cells,
            first_order,
            model_rotation: None,
        });
    }
    let claims = claims(context, &panels);
    ExperimentResult {
        experiment: Experiment::Noise,
        trials,
        setup: vec![
            format!("σ = {SIGMA_MIN_PX}…{SIGMA_MAX_PX} px in steps of {SIGMA_STEP_PX} (the paper: \"0~10 pixels, step 0.5\"); {trials} trials per σ (the paper: 500)."),
            format!("Fig. 8: n = {RANDOM_COUNT} points uniform in the camera-frame box [−500, 500]² × [500, 1500] mm, random object attitude."),
            "Figs. 9a/9b: the paper's biprism (six vertices at ±L on the axes plus the centre O0) with L = 25 and 100 mm (the paper's \"edge length\" read as L), its origin uniform in the same box, random attitude; both sizes see the same poses and noise.".into(),
            "Every σ of a trial uses the same geometry and unit noise, scaled by σ.".into(),
        ],
        extra_markdown: paper_figures_table(context, &panels),
        panels,
        claims,
        extra_csv: Vec::new(),
        timing: None,
    }
}

/// The figures the paper quotes beside ours (informational: the paper does
/// not say which solver or statistic its extremes refer to).
fn paper_figures_table(context: &Context, panels: &[Panel]) -> String {
    let (accurate, _) = group(
        context,
        &["opnp", "rpnp", "parallel", "parallel-weighted", "lhm"],
    );
    let paper = [
        ("Fig. 8", "0.77° / 0.7%", "15.7° / 12%"),
        ("Fig. 9a", "24° / 17.7%", "112° / 85.6%"),
        ("Fig. 9b", "5.35° / 3.76%", "84.6° / 55.2%"),
    ];
    let mut table = Table::new([
        "figure",
        "paper, smallest (E_rot / E_t)",
        "ours at σ = 0.5 px (range over the accurate solvers)",
        "paper, largest",
        "ours at σ = 10 px",
    ]);
    for (panel, (figure, small, large)) in panels.iter().zip(paper) {
        let range = |i: usize| {
            let values = |metric: Metric| -> Vec<f64> {
                accurate
                    .iter()
                    .filter_map(|&s| panel.cell(i, s)?.stat(metric).mean())
                    .collect()
            };
            let span = |v: Vec<f64>, unit: &str| {
                let lo = v.iter().copied().fold(f64::INFINITY, f64::min);
                let hi = v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
                if v.is_empty() {
                    "—".to_string()
                } else {
                    format!("{}–{}{unit}", num(lo), num(hi))
                }
            };
            format!(
                "{} / {}",
                span(values(Metric::Rotation), "°"),
                span(values(Metric::Translation), "%")
            )
        };
        table.row([
            figure.to_string(),
            small.to_string(),
            range(0),
            large.to_string(),
            range(panel.x.len() - 1),
        ]);
    }
    let names: Vec<&str> = accurate.iter().map(|s| s.name()).collect();
    let mut out = String::new();
    let _ = writeln!(
        out,
        "### The paper's quoted extremes beside ours\n\nThe paper quotes extreme errors for \"the more accurate algorithms\" (OPnP, RPnP, parallel, parallel weight, LHM) without saying which statistic or σ they refer to, so these are shown for context, not judged. Ours: mean E_rot / mean E_t over {}.\n",
        names.join(", ")
    );
    out.push_str(&table.markdown());
    out
}

fn claims(context: &Context, panels: &[Panel]) -> Vec<Claim> {
    let (paper, missing) = group(context, &PAPER_SOLVERS);
    let rot = Metric::Rotation;
    let pooled_mean = |panel: &Panel, s: Solver| {
        panel
            .pooled(s, |_| true)
            .and_then(|c| c.rotation_deg.mean())
    };
    let mut out = Vec::new();

    // (1) Errors increase with noise.
    let claim = Claim::new(
        "noise.errors-increase",
        "§4.3 noise (1), Figs. 8–9",
        "The errors of every method increase with noise.",
        &format!(
            "Spearman ρ(σ, mean E_rot) ≥ {} for every paper solver available, in all three figures",
            claims::TREND_RHO
        ),
    );
    let mut holds = true;
    let mut lowest: Option<(f64, String)> = None;
    for panel in panels {
        for &s in &paper {
            let (x, y) = panel.means(s, rot);
            let rho = spearman(&x, &y).unwrap_or(f64::NAN);
            holds &= rho >= claims::TREND_RHO;
            if lowest.as_ref().is_none_or(|l| rho.is_nan() || rho < l.0) {
                lowest = Some((rho, format!("{} in {}", s.name(), panel.figure)));
            }
        }
    }
    out.push(
        claim
            .judge(
                holds,
                lowest.map_or("no data".into(), |(rho, at)| {
                    format!("lowest ρ = {rho:.3} ({at})")
                }),
            )
            .missing(missing.clone()),
    );

    // (1) OPnP, RPnP and LHM are the most noise-resistant at either size.
    let claim = Claim::new(
        "noise.opnp-rpnp-lhm-best",
        "§4.3 noise (1), Figs. 8–9",
        "OPnP, RPnP and LHM resist noise best, with the best accuracy at either marker size.",
        &format!(
            "in every figure, each one's mean E_rot pooled over σ ≤ {} × the best paper solver's",
            claims::BEST_TOLERANCE
        ),
    );
    let (named, named_missing) = group(context, &["opnp", "rpnp", "lhm"]);
    if named.is_empty() {
        out.push(claim.solvers_missing(named_missing));
    } else {
        let mut holds = true;
        let mut parts = Vec::new();
        for panel in panels {
            let best = paper
                .iter()
                .filter_map(|&s| pooled_mean(panel, s))
                .fold(f64::INFINITY, f64::min);
            for &s in &named {
                let ratio = pooled_mean(panel, s).unwrap_or(f64::NAN) / best;
                holds &= ratio <= claims::BEST_TOLERANCE;
                parts.push(format!(
                    "{} {}: {}× best",
                    panel.figure,
                    s.name(),
                    num(ratio)
                ));
            }
        }
        out.push(claim.judge(holds, parts.join(", ")).missing(named_missing));
    }

    // (2) A larger marker is more accurate.
    let claim = Claim::new(
        "noise.larger-marker-more-accurate",
        "§4.3 noise (2), Figs. 9a–9b",
        "The larger the distance between the marker points, the more accurate every method.",
        "improvement rule on mean E_rot pooled over σ: L = 100 mm against L = 25 mm, for every paper solver available",
    );
    let (small, large) = (&panels[1], &panels[2]);
    let mut tally = claims::Tally::default();
    let mut parts = Vec::new();
    for &s in &paper {
        let pair = small.pooled(s, |_| true).zip(large.pooled(s, |_| true));
        match pair.and_then(|(a, b)| claims::improves(&b.rotation_deg, &a.rotation_deg)) {
            Some((ok, c)) => {
                tally.order(ok, &c);
                parts.push(format!("{} {}×", s.name(), num(c.ratio)));
            }
            None => tally.check(false),
        }
    }
    out.push(
        claim
            .decide(
                tally.verdict(),
                format!("E_rot(L = 25) / E_rot(L = 100): {}", parts.join(", ")),
            )
            .missing(missing.clone()),
    );

    // (2) Straight error curves for n = 10 and L = 100; curved for L = 25.
    let (accurate, accurate_missing) = group(
        context,
        &["opnp", "rpnp", "parallel", "parallel-weighted", "lhm"],
    );
    let r2 = |panel: &Panel, s: Solver| {
        let (x, y) = panel.means(s, rot);
        line_fit(&x, &y).map_or(f64::NAN, |f| f.r_squared)
    };
    let claim = Claim::new(
        "noise.straight-lines",
        "§4.3 noise (2), Figs. 8, 9b",
        "For n = 10 and for L = 100 mm the error curves of the accurate methods (OPnP, RPnP, parallel, parallel weight, LHM) are straight lines.",
        &format!("R² of a line fit to mean E_rot against σ ≥ {} for each, in Figs. 8 and 9b", claims::LINEAR_R2),
    );
    let mut holds = true;
    let mut parts = Vec::new();
    for panel in [&panels[0], &panels[2]] {
        for &s in &accurate {
            let value = r2(panel, s);
            holds &= value >= claims::LINEAR_R2;
            parts.push(format!("{} {} R² {:.4}", panel.figure, s.name(), value));
        }
    }
    out.push(
        claim
            .judge(holds, parts.join(", "))
            .missing(accurate_missing.clone()),
    );
    let claim = Claim::new(
        "noise.curved-small-marker",
        "§4.3 noise (2), Fig. 9a",
        "With L = 25 mm the error curves bend (are not straight lines).",
        &format!(
            "R² of a line fit to mean E_rot against σ < {} for each accurate method in Fig. 9a",
            claims::LINEAR_R2
        ),
    );
    let values: Vec<(Solver, f64)> = accurate.iter().map(|&s| (s, r2(&panels[1], s))).collect();
    let holds = values.iter().all(|(_, v)| *v < claims::LINEAR_R2);
    out.push(
        claim
            .judge(
                holds,
                values
                    .iter()
                    .map(|(s, v)| format!("{} R² {v:.4}", s.name()))
                    .collect::<Vec<_>>()
                    .join(", "),
            )
            .missing(accurate_missing),
    );

    // (3) OPnP is the most accurate closed-form method and beats LHM.
    let claim = Claim::new(
        "noise.opnp-most-accurate",
        "§4.3 noise (3), Figs. 8–9",
        "OPnP is the most accurate closed-form method, better even than the iterative LHM.",
        "in every figure, OPnP's mean E_rot pooled over σ ≤ every other closed-form paper solver's, and OPnP slightly better than LHM (rule above)",
    );
    match (find(context, "opnp"), find(context, "lhm")) {
        (Some(opnp), Some(lhm)) => {
            let (closed, _) = group(context, &CLOSED_FORM);
            let mut tally = claims::Tally::default();
            let mut parts = Vec::new();
            for panel in panels {
                let own = pooled_mean(panel, opnp).unwrap_or(f64::NAN);
                let best_other = closed
                    .iter()
                    .filter(|&&s| s != opnp)
                    .filter_map(|&s| pooled_mean(panel, s).map(|m| (s, m)))
                    .min_by(|a, b| a.1.total_cmp(&b.1));
                if let Some((s, m)) = best_other {
                    tally.check(own <= m);
                    parts.push(format!(
                        "{}: OPnP {}° vs best other closed-form {} {}°",
                        panel.figure,
                        num(own),
                        s.name(),
                        num(m)
                    ));
                }
                let pair = panel
                    .pooled(opnp, |_| true)
                    .zip(panel.pooled(lhm, |_| true));
                match pair
                    .and_then(|(a, b)| claims::slightly_better(&a.rotation_deg, &b.rotation_deg))
                {
                    Some((ok, c)) => {
                        tally.order(ok, &c);
                        parts.push(format!("LHM/OPnP {}", describe(&c)));
                    }
                    None => tally.check(false),
                }
            }
            out.push(claim.decide(tally.verdict(), parts.join("; ")));
        }
        (opnp, lhm) => {
            let mut names = Vec::new();
            if opnp.is_none() {
                names.push("opnp".to_string());
            }
            if lhm.is_none() {
                names.push("lhm".to_string());
            }
            out.push(claim.solvers_missing(names));
        }
    }

    // (3) The proposed method equals OPnP in noise robustness.
    let claim = Claim::new(
        "noise.comparable-to-opnp",
        "§4.3 noise (3), Abstract, §5.2",
        "The proposed method is equivalent to OPnP in robustness against noise.",
        &format!(
            "in every figure, parallel-weighted / OPnP mean E_rot pooled over σ within [1/{0}, {0}]",
            claims::COMPARABLE_RATIO
        ),
    );
    match (find(context, "parallel-weighted"), find(context, "opnp")) {
        (Some(pw), Some(opnp)) => {
            let mut holds = true;
            let mut parts = Vec::new();
            for panel in panels {
                let (ok, ratio) = claims::comparable(
                    pooled_mean(panel, pw).unwrap_or(f64::NAN),
                    pooled_mean(panel, opnp).unwrap_or(f64::NAN),
                );
                holds &= ok;
                parts.push(format!("{} {}×", panel.figure, num(ratio)));
            }
            out.push(claim.judge(
                holds,
                format!("parallel-weighted / OPnP: {}", parts.join(", ")),
            ));
        }
        _ => out.push(claim.solvers_missing(vec!["opnp".into()])),
    }
    out
}
