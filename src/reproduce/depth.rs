//! Experiment 4 (§4.3 "influence of the distance between the camera and
//! feature point coordinate system", Figs. 11–14; §5.2): accuracy against the
//! depth/size ratio, near and far, for n = 10 random points and for the
//! paper's biprism.
//!
//! Protocol: the paper varies the depth D "0~500 mm, step 100" (near) and
//! "0~10000 mm, step 500" (far); D = 0 is degenerate (points on the camera
//! centre), so we start at the first step. σ = √0.2 px, 100 trials.
//! * n = 10: points uniform in a cube of side S = 500 mm whose near face is at
//!   depth D, centred on the optical axis; random object attitude. The ratio
//!   is D/S (the paper: "the distance from the camera focus to the smallest
//!   edge of the feature point selection range to the size of the range"),
//!   0.2…1 near and 1…20 far.
//! * biprism (L = 50 mm): origin on the optical axis at depth D, uniformly
//!   random attitude. The ratio is D/L, 2…10 near and 10…200 far (the paper's
//!   "reaching 200").
//!
//! Near and far panels of one marker share their trials' draws.

use super::claims::{self, describe, num, Claim, PARALLEL_AMBIGUITY};
use super::engine::{find, group, stream};
use super::engine::{
    from_camera_points, random_rotation, run_random, unit_noise, Context, Instance,
};
use super::panel::{two_worst, Cell, Metric, Panel};
use super::stats::{knee_fit, spearman};
use super::{paper_sigma_px, Experiment, ExperimentResult, PAPER_SOLVERS};
use crate::layout::PAPER_ARM_MM;
use crate::pnp::Solver;
use crate::pose::Pose;
use crate::statistics::median;
use crate::synthetic::biprism_points;
use nalgebra::Vector3;
use rand::Rng;

/// Side of the n = 10 point cube, mm.
pub const CUBE_SIDE_MM: f64 = 500.0;
/// Points of the random panels.
pub const RANDOM_COUNT: usize = 10;
/// Near depths: 100…500 mm in steps of 100.
pub const NEAR_DEPTHS_MM: (f64, f64, f64) = (100.0, 500.0, 100.0);
/// Far depths: 500…10000 mm in steps of 500.
pub const FAR_DEPTHS_MM: (f64, f64, f64) = (500.0, 10000.0, 500.0);
/// "Close range" of the weighting claims: depth/size ratio below this (§4.3 (4), §5.2).
pub const CLOSE_RATIO: f64 = 4.0;
/// The knee the paper reports for DLT, EPnP and EPnP+GN on the biprism.
pub const CLAIMED_KNEE_RATIO: f64 = 40.0;
/// "Below the others": at least this fraction of the ratios.
pub const DOMINANCE_FRACTION: f64 = 0.9;

/// One figure: file stem, figure, title, depths, random points (else the
/// biprism), marker size.
type PanelSpec<'a> = (&'a str, &'a str, &'a str, &'a [f64], bool, f64);

fn depths((start, end, step): (f64, f64, f64)) -> Vec<f64> {
    (0..)
        .map(|k| start + step * k as f64)
        .take_while(|d| *d <= end + 1e-9)
        .collect()
}

pub(crate) fn run(context: &Context, trials: usize) -> ExperimentResult {
    let near = depths(NEAR_DEPTHS_MM);
    let far = depths(FAR_DEPTHS_MM);
    context.progress.start(
        Experiment::Depth.name(),
        2 * trials * (near.len() + far.len()),
    );
    let sigma_px = paper_sigma_px();
    let random = |depths: &[f64]| {
        let depths = depths.to_vec();
        move |rng: &mut rand_chacha::ChaCha8Rng, setting: usize| {
            let depth = depths[setting];
            let points: Vec<Vector3<f64>> = (0..RANDOM_COUNT)
                .map(|_| {
                    let u = Vector3::from_fn(|_, _| rng.random::<f64>());
                    Vector3::new(
                        (u.x - 0.5) * CUBE_SIDE_MM,
                        (u.y - 0.5) * CUBE_SIDE_MM,
                        depth + u.z * CUBE_SIDE_MM,
                    )
                })
                .collect();
            let rotation = random_rotation(rng);
            let noise = unit_noise(rng, RANDOM_COUNT);
            let (object, truth) = from_camera_points(&points, rotation);
            Instance {
                object,
                truth,
                sigma_px,
                unit_noise: noise,
            }
        }
    };
    let biprism = |depths: &[f64]| {
        let depths = depths.to_vec();
        move |rng: &mut rand_chacha::ChaCha8Rng, setting: usize| {
            let rotation = random_rotation(rng);
            let object = biprism_points(PAPER_ARM_MM);
            let noise = unit_noise(rng, object.len());
            Instance {
                object,
                truth: Pose::new(rotation, Vector3::new(0.0, 0.0, depths[setting])),
                sigma_px,
                unit_noise: noise,
            }
        }
    };
    let specs: [PanelSpec; 4] = [
        (
            "fig11_depth_n10_far",
            "Fig. 11",
            "n = 10 random points, far (D = 500…10000 mm)",
            &far,
            true,
            CUBE_SIDE_MM,
        ),
        (
            "fig12_depth_n10_near",
            "Fig. 12",
            "n = 10 random points, near (D = 100…500 mm)",
            &near,
            true,
            CUBE_SIDE_MM,
        ),
        (
            "fig13_depth_biprism_far",
            "Fig. 13",
            "biprism L = 50 mm, far (D = 500…10000 mm)",
            &far,
            false,
            PAPER_ARM_MM,
        ),
        (
            "fig14_depth_biprism_near",
            "Fig. 14",
            "biprism L = 50 mm, near (D = 100…500 mm)",
            &near,
            false,
            PAPER_ARM_MM,
        ),
    ];
    let mut panels = Vec::new();
    for (id, figure, title, depths, is_random, size_mm) in specs {
        let (cells, first_order) = if is_random {
            run_random(
                context,
                stream(Experiment::Depth, 0),
                trials,
                depths.len(),
                &random(depths),
            )
        } else {
            run_random(
                context,
                stream(Experiment::Depth, 1),
                trials,
                depths.len(),
                &biprism(depths),
            )
        };
        panels.push(Panel {
            id: id.into(),
            figure: figure.into(),
            title: format!("Accuracy vs depth/size ratio, {title}"),
            x_label: if is_random {
                "depth/size ratio D/S (S = 500 mm)".into()
            } else {
                "depth/size ratio D/L (L = 50 mm)".into()
            },
            x: depths.iter().map(|d| d / size_mm).collect(),
            solvers: context.solvers.clone(),
            cells,
            first_order,
            model_rotation: None,
        });
    }
    let claims = claims(context, &panels);
    ExperimentResult {
        experiment: Experiment::Depth,
        trials,
        setup: vec![
            format!("σ = √0.2 px; {trials} trials per depth (the paper: 100)."),
            format!("n = 10: points uniform in a {CUBE_SIDE_MM} mm cube centred on the optical axis with its near face at depth D; ratio D/S: 0.2…1 near (D = 100…500 mm, step 100), 1…20 far (D = 500…10000 mm, step 500). Random object attitude."),
            format!("Biprism (L = {PAPER_ARM_MM} mm): origin on the optical axis at depth D, uniformly random attitude; ratio D/L: 2…10 near, 10…200 far."),
            "The paper starts both ranges at D = 0, which puts points on the camera centre; we start at the first step.".into(),
        ],
        panels,
        extra_markdown: String::new(),
        claims,
        extra_csv: Vec::new(),
        timing: None,
    }
}

/// `solver` pooled over every panel's x values below `limit`.
fn pooled_below(panels: &[Panel], solver: Solver, limit: f64) -> Option<Cell> {
    let cells: Vec<Cell> = panels
        .iter()
        .filter_map(|p| p.pooled(solver, |x| x < limit))
        .collect();
    let pooled = Cell::pool(solver, cells.iter());
    pooled.applicable.then_some(pooled)
}

fn claims(context: &Context, panels: &[Panel]) -> Vec<Claim> {
    let (paper, missing) = group(context, &PAPER_SOLVERS);
    let rot = Metric::Rotation;
    let far = [&panels[0], &panels[2]];
    let pooled_mean = |panel: &Panel, s: Solver| {
        panel
            .pooled(s, |_| true)
            .and_then(|c| c.rotation_deg.mean())
    };
    let mut out = Vec::new();

    // (1) Errors increase with the ratio.
    let claim = Claim::new(
        "depth.errors-increase",
        "§4.3 depth (1), Figs. 11, 13",
        "As the depth/size ratio increases, the errors of every method increase.",
        &format!(
            "Spearman ρ(ratio, mean E_rot) ≥ {} for every paper solver available, on both far ranges",
            claims::TREND_RHO
        ),
    );
    let mut holds = true;
    let mut parts = Vec::new();
    for panel in far {
        let mut lowest = (f64::INFINITY, String::new());
        for &s in &paper {
            let (x, y) = panel.means(s, rot);
            let rho = spearman(&x, &y).unwrap_or(f64::NAN);
            holds &= rho >= claims::TREND_RHO;
            if rho.is_nan() || rho < lowest.0 {
                lowest = (rho, s.name().to_string());
            }
        }
        parts.push(format!(
            "{}: lowest ρ = {:.3} ({})",
            panel.figure, lowest.0, lowest.1
        ));
    }
    out.push(
        claim
            .judge(holds, parts.join("; "))
            .missing(missing.clone()),
    );

    // (1) DLT and EPnP are the most affected.
    let claim = Claim::new(
        "depth.dlt-epnp-most-affected",
        "§4.3 depth (1), Figs. 11, 13",
        "DLT and EPnP are the methods most affected by the depth/size ratio.",
        "on both far ranges, DLT and EPnP have the two largest mean E_rot (pooled over the ratios) among the paper solvers available",
    );
    match (find(context, "dlt"), find(context, "epnp")) {
        (Some(dlt), Some(epnp)) => {
            let (holds, evidence) = two_worst(far, &paper, dlt, epnp);
            out.push(claim.judge(holds, evidence).missing(missing.clone()));
        }
        _ => out.push(claim.solvers_missing(vec!["dlt".into(), "epnp".into()])),
    }

    let pw = find(context, "parallel-weighted");

    // (2) n = 10: consistent with DLS, RPnP and LHM.
    let claim = Claim::new(
        "depth.n10-consistent-with-dls-rpnp-lhm",
        "§4.3 depth (2), Fig. 11",
        "With 10 random points the proposed method is consistent with DLS, RPnP and LHM (the paper's minimum errors: 0.5°, 0.4%).",
        &format!(
            "parallel-weighted / the median of those methods' mean E_rot, pooled over the far range, within [1/{0}, {0}]",
            claims::COMPARABLE_RATIO
        ),
    );
    let (refs, refs_missing) = group(context, &["dls", "rpnp", "lhm"]);
    match pw {
        Some(pw) if !refs.is_empty() => {
            let panel = &panels[0];
            let mut reference: Vec<f64> =
                refs.iter().filter_map(|&s| pooled_mean(panel, s)).collect();
            let (holds, ratio) = claims::comparable(
                pooled_mean(panel, pw).unwrap_or(f64::NAN),
                median(&mut reference).unwrap_or(f64::NAN),
            );
            let min_of = |metric: Metric| {
                panel
                    .curve(pw, metric)
                    .iter()
                    .map(|(_, s)| s.mean)
                    .fold(f64::INFINITY, f64::min)
            };
            out.push(
                claim
                    .judge(
                        holds,
                        format!(
                            "ratio {}; the proposed method's smallest means: {}° and {}%",
                            num(ratio),
                            num(min_of(rot)),
                            num(min_of(Metric::Translation))
                        ),
                    )
                    .missing(refs_missing),
            );
        }
        _ => out.push(claim.solvers_missing(refs_missing)),
    }

    // (3) Biprism: the accurate group is immune, DLT/EPnP/EPnP+GN are not.
    let claim = Claim::new(
        "depth.biprism-immune-group",
        "§4.3 depth (3), Fig. 13",
        "On the biprism (ratio up to 200), the proposed method, parallel, LHM, RPnP and OPnP resist the depth/size ratio better than DLT, EPnP and EPnP+GN.",
        &format!(
            "on the far range, each of the first group has a lower mean E_rot than each of DLT, EPnP and EPnP+GN at ≥ {:.0}% of the ratios",
            100.0 * DOMINANCE_FRACTION
        ),
    );
    let (immune, immune_missing) = group(
        context,
        &["parallel-weighted", "parallel", "lhm", "rpnp", "opnp"],
    );
    let (fragile, fragile_missing) = group(context, &["dlt", "epnp", "epnp-gn"]);
    if immune.is_empty() || fragile.is_empty() {
        let mut names = immune_missing;
        names.extend(fragile_missing);
        out.push(claim.solvers_missing(names));
    } else {
        let panel = &panels[2];
        let mut worst = (1.0f64, String::new());
        for &a in &immune {
            for &b in &fragile {
                let (mut wins, mut total) = (0usize, 0usize);
                for i in 0..panel.x.len() {
                    let (Some(ea), Some(eb)) = (
                        panel.cell(i, a).and_then(|c| c.rotation_deg.mean()),
                        panel.cell(i, b).and_then(|c| c.rotation_deg.mean()),
                    ) else {
                        continue;
                    };
                    total += 1;
                    wins += usize::from(ea < eb);
                }
                let fraction = wins as f64 / total.max(1) as f64;
                if fraction < worst.0 || worst.1.is_empty() {
                    worst = (fraction, format!("{} below {}", a.name(), b.name()));
                }
            }
        }
        let mut names = immune_missing;
        names.extend(fragile_missing);
        out.push(
            claim
                .judge(
                    worst.0 >= DOMINANCE_FRACTION,
                    format!(
                        "weakest pair: {} at {:.0}% of the ratios",
                        worst.1,
                        100.0 * worst.0
                    ),
                )
                .missing(names),
        );
    }

    // (3) Two straight lines with a knee near ratio 40.
    let claim = Claim::new(
        "depth.biprism-knee-40",
        "§4.3 depth (3), Fig. 13",
        "On the biprism, the error curves of DLT, EPnP and EPnP+GN are two straight lines with the knee near a depth/size ratio of 40.",
        &format!(
            "best two-segment fit of mean E_rot against the ratio (far range) has its knee within [{}, {}] and ≤ {} of a single line's residual, for each",
            CLAIMED_KNEE_RATIO / claims::KNEE_FACTOR,
            CLAIMED_KNEE_RATIO * claims::KNEE_FACTOR,
            claims::KNEE_RESIDUAL_FRACTION
        ),
    );
    let (fragile, fragile_missing) = group(context, &["dlt", "epnp", "epnp-gn"]);
    if fragile.is_empty() {
        out.push(claim.solvers_missing(fragile_missing));
    } else {
        let mut holds = true;
        let mut parts = Vec::new();
        for &s in &fragile {
            let (x, y) = panels[2].means(s, rot);
            match knee_fit(&x, &y) {
                Some(fit) => {
                    let fraction = fit.two_segment_sum_sq / fit.one_line_sum_sq;
                    holds &= fit.knee >= CLAIMED_KNEE_RATIO / claims::KNEE_FACTOR
                        && fit.knee <= CLAIMED_KNEE_RATIO * claims::KNEE_FACTOR
                        && fraction <= claims::KNEE_RESIDUAL_FRACTION;
                    parts.push(format!(
                        "{} knee at {} (residual {:.2} of one line)",
                        s.name(),
                        num(fit.knee),
                        fraction
                    ));
                }
                None => holds = false,
            }
        }
        out.push(
            claim
                .judge(holds, parts.join(", "))
                .missing(fragile_missing),
        );
    }

    // (4) and §5.2: the weighting removes paraperspective's close-range error.
    for (id, source, other_name, statement) in [
        (
            "depth.weighting-fixes-parallel-close",
            "§4.3 depth (4), Figs. 12, 14",
            "parallel-init",
            "Below a depth/size ratio of 4 paraperspective alone (the single step, the method's initial value) has large errors, and the proposed weighted optimisation removes them.",
        ),
        (
            "depth.weighting-fixes-parallel-close-iterated",
            "§4.3 depth (4), Figs. 12, 14",
            "parallel",
            "The same claim, reading \"Parallel\" as Horaud's iteration to convergence.",
        ),
        (
            "depth.weights-beat-unweighted-close",
            "§5.2",
            "parallel-gn",
            "Below a depth/size ratio of 4 the error-aware weighting consistently outperforms the same method without weights (ablation: parallel-gn).",
        ),
    ] {
        let claim = Claim::new(
            id,
            source,
            statement,
            &format!("improvement rule on mean E_rot, parallel-weighted against {other_name}, at every setting with ratio < {CLOSE_RATIO} (all four figures)"),
        );
        match (pw, find(context, other_name)) {
            (Some(pw), Some(other)) => {
                let mut tally = claims::Tally::default();
                let mut parts = Vec::new();
                for panel in panels {
                    for (i, &x) in panel.x.iter().enumerate() {
                        if x >= CLOSE_RATIO {
                            continue;
                        }
                        let pair = panel.cell(i, pw).zip(panel.cell(i, other));
                        match pair.and_then(|(a, b)| claims::improves(&a.rotation_deg, &b.rotation_deg)) {
                            Some((ok, c)) => {
                                tally.order(ok, &c);
                                parts.push(format!("{} ratio {}: {}", panel.figure, x, describe(&c)));
                            }
                            None => tally.check(false),
                        }
                    }
                }
                let claim = claim.decide(
                    tally.verdict(),
                    format!("{other_name} / parallel-weighted: {}", parts.join("; ")),
                );
                out.push(if other_name == "parallel" {
                    claim.ambiguity(PARALLEL_AMBIGUITY)
                } else {
                    claim
                });
            }
            _ => out.push(claim.solvers_missing(vec![other_name.into()])),
        }
    }

    // §2.1: IEPnP is unstable close to the camera.
    let claim = Claim::new(
        "depth.iepnp-unstable-close",
        "§2.1",
        "IEPnP (weak-perspective start) is not stable when the marker is close to the camera; the paraperspective start is.",
        &format!("improvement rule on mean E_rot pooled over every setting with ratio < {CLOSE_RATIO}: parallel-weighted against IEPnP"),
    );
    match (pw, find(context, "iepnp")) {
        (Some(pw), Some(iepnp)) => {
            let pair =
                pooled_below(panels, pw, CLOSE_RATIO).zip(pooled_below(panels, iepnp, CLOSE_RATIO));
            match pair {
                Some((a, b)) => match claims::improves(&a.rotation_deg, &b.rotation_deg) {
                    Some((holds, c)) => out.push(claim.judge_order(
                        holds,
                        &c,
                        format!(
                            "ratio < 4: IEPnP {}° (failure rate {:.1}%) vs parallel-weighted {}° ({:.1}%): {}",
                            num(b.rotation_deg.mean),
                            100.0 * b.failure_rate().unwrap_or(f64::NAN),
                            num(a.rotation_deg.mean),
                            100.0 * a.failure_rate().unwrap_or(f64::NAN),
                            describe(&c)
                        ),
                    )),
                    None => out.push(claim.skip("not evaluated: no poses below ratio 4")),
                },
                None => out.push(claim.skip("not evaluated: no settings below ratio 4")),
            }
        }
        _ => out.push(claim.solvers_missing(vec!["iepnp".into()])),
    }
    out
}
