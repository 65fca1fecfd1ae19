//! Experiment 1 (§4.3 "the influence of the number of feature points", Fig. 7;
//! §2.1 on EPnP+GN at n = 4–5; §5.1): accuracy against n = 4…20.
//!
//! Protocol (§4.2): points uniform in the camera-frame box
//! `[−500, 500]² × [500, 1500]` mm, a uniformly random object attitude with
//! the origin at the points' centroid, σ = √0.2 px, 200 trials. Trial k draws
//! 20 points and uses the first n, so the sets are nested across n.

use super::claims::{self, describe, num, Claim};
use super::engine::{
    camera_box_points, from_camera_points, random_rotation, run_random, unit_noise, Context,
    Instance,
};
use super::engine::{find, group, stream};
use super::panel::{Metric, Panel};
use super::stats::{spearman, Stat};
use super::{paper_sigma_px, Experiment, ExperimentResult, PAPER_SOLVERS};
use crate::pnp::Solver;

/// Smallest n.
pub const MIN_COUNT: usize = 4;
/// Largest n.
pub const MAX_COUNT: usize = 20;
/// The point box: half width in x and y, mm.
pub const BOX_HALF_WIDTH_MM: f64 = 500.0;
/// The point box: nearest depth, mm.
pub const BOX_NEAR_MM: f64 = 500.0;
/// The point box: farthest depth, mm.
pub const BOX_FAR_MM: f64 = 1500.0;
/// "Stable from n ≥ 12" (§4.3 (1)).
pub const STABLE_FROM: usize = 12;
/// The paper's bounds once stable: E_rot within 0.7°, E_t within 1.4%.
pub const STABLE_ROTATION_DEG: f64 = 0.7;
/// See [`STABLE_ROTATION_DEG`].
pub const STABLE_TRANSLATION_PERCENT: f64 = 1.4;
/// "Few points" for the erratic claim (§2.1: n = 4 or 5).
pub const FEW_POINTS: [usize; 2] = [4, 5];
/// "Many points" reference for the erratic claim.
pub const MANY_POINTS_FROM: usize = 8;

pub(crate) fn run(context: &Context, trials: usize) -> ExperimentResult {
    let counts: Vec<usize> = (MIN_COUNT..=MAX_COUNT).collect();
    context
        .progress
        .start(Experiment::Points.name(), trials * counts.len());
    let sigma_px = paper_sigma_px();
    let generate = |rng: &mut rand_chacha::ChaCha8Rng, setting: usize| {
        let n = counts[setting];
        let points = camera_box_points(rng, MAX_COUNT, BOX_HALF_WIDTH_MM, BOX_NEAR_MM, BOX_FAR_MM);
        let rotation = random_rotation(rng);
        let noise = unit_noise(rng, MAX_COUNT);
        let (object, truth) = from_camera_points(&points[..n], rotation);
        Instance {
            object,
            truth,
            sigma_px,
            unit_noise: noise[..n].to_vec(),
        }
    };
    let (cells, first_order) = run_random(
        context,
        stream(Experiment::Points, 0),
        trials,
        counts.len(),
        &generate,
    );
    let panel = Panel {
        id: "fig7_points".into(),
        figure: "Fig. 7".into(),
        title: "Accuracy vs number of points, σ = √0.2 px".into(),
        x_label: "number of points n".into(),
        x: counts.iter().map(|&n| n as f64).collect(),
        solvers: context.solvers.clone(),
        cells,
        first_order,
        model_rotation: None,
    };
    let claims = claims(context, &panel);
    ExperimentResult {
        experiment: Experiment::Points,
        trials,
        setup: vec![
            format!("n = {MIN_COUNT}…{MAX_COUNT}; {trials} trials per n (the paper: 200)."),
            format!("Points uniform in the camera-frame box [−{BOX_HALF_WIDTH_MM}, {BOX_HALF_WIDTH_MM}]² × [{BOX_NEAR_MM}, {BOX_FAR_MM}] mm (§4.2); uniformly random object attitude with its origin at the centroid. Trial k draws {MAX_COUNT} points and uses the first n (nested sets)."),
            "σ = √0.2 px. Solvers that need more points than n (DLT: 6) are not run there (\"n/a\").".into(),
            "The camera is in the header's camera row: by default the paper's \"80\", read as a focal length of 80 px.".into(),
        ],
        panels: vec![panel],
        extra_markdown: String::new(),
        claims,
        extra_csv: Vec::new(),
        timing: None,
    }
}

fn x_of(panel: &Panel, n: usize) -> Option<usize> {
    panel.x.iter().position(|&x| x == n as f64)
}

fn claims(context: &Context, panel: &Panel) -> Vec<Claim> {
    let (paper, missing) = group(context, &PAPER_SOLVERS);
    let rot = Metric::Rotation;
    let mut out = Vec::new();

    // (1) Accuracy improves with n.
    let claim = Claim::new(
        "points.improves-with-n",
        "§4.3 (1), Fig. 7",
        "As the number of points increases, the rotation accuracy of every method improves.",
        &format!(
            "Spearman ρ(n, mean E_rot) ≤ −{} for every paper solver available",
            claims::TREND_RHO
        ),
    );
    let rhos: Vec<(Solver, Option<f64>)> = paper
        .iter()
        .map(|&s| {
            let (x, y) = panel.means(s, rot);
            (s, spearman(&x, &y))
        })
        .collect();
    let holds = rhos
        .iter()
        .all(|(_, r)| r.is_some_and(|r| r <= -claims::TREND_RHO));
    let evidence = rhos
        .iter()
        .map(|(s, r)| {
            format!(
                "{} ρ = {}",
                s.name(),
                r.map_or("—".into(), |r| format!("{r:.2}"))
            )
        })
        .collect::<Vec<_>>()
        .join(", ");
    out.push(claim.judge(holds, evidence).missing(missing.clone()));

    // (1) Stable from n = 12.
    let claim = Claim::new(
        "points.stable-from-12",
        "§4.3 (1), §5.1, Fig. 7",
        "From n ≥ 12 every method's accuracy stabilises.",
        &format!(
            "for every paper solver available, (E(12) − E(20)) / (E(n_min) − E(20)) ≤ {:.3} on mean E_rot, n_min being the smallest n it accepts",
            claims::STABILISE_FRACTION
        ),
    );
    let (i12, i20) = (
        x_of(panel, STABLE_FROM).expect("n = 12 is on the grid"),
        x_of(panel, MAX_COUNT).expect("n = 20 is on the grid"),
    );
    let mut all = true;
    let mut parts = Vec::new();
    for &s in &paper {
        let curve = panel.curve(s, rot);
        let (Some(first), Some(e12), Some(e20)) = (
            curve.first().map(|c| c.1.mean),
            panel.cell(i12, s).and_then(|c| c.rotation_deg.mean()),
            panel.cell(i20, s).and_then(|c| c.rotation_deg.mean()),
        ) else {
            all = false;
            continue;
        };
        let fraction = (e12 - e20) / (first - e20);
        let ok = first > e20 && fraction <= claims::STABILISE_FRACTION;
        all &= ok;
        parts.push(format!("{} {:.2}", s.name(), fraction));
    }
    out.push(
        claim
            .judge(all, format!("gain left after n = 12: {}", parts.join(", ")))
            .missing(missing.clone()),
    );

    // (1) The bounds once stable.
    let claim = Claim::new(
        "points.bounds-from-12",
        "§4.3 (1), Fig. 7",
        "From n ≥ 12 the rotation error is within 0.7° and the position error within 1.4%.",
        &format!("for every paper solver available and every n ≥ 12: mean E_rot ≤ {STABLE_ROTATION_DEG}° and mean E_t ≤ {STABLE_TRANSLATION_PERCENT}%, each bound widened by {}%", 100.0 * claims::LEVEL_TOLERANCE),
    );
    let worst = |metric: Metric| {
        paper
            .iter()
            .flat_map(|&s| {
                panel
                    .curve(s, metric)
                    .into_iter()
                    .filter(|(x, _)| *x >= STABLE_FROM as f64)
                    .map(move |(_, st)| (s, st.mean))
            })
            .max_by(|a, b| a.1.total_cmp(&b.1))
    };
    match (worst(rot), worst(Metric::Translation)) {
        (Some((sr, r)), Some((st, t))) => out.push(
            claim
                .ambiguity("the noise level \"variance 0.2\", which sets the error level")
                .judge(
                    claims::within_level(r, (0.0, STABLE_ROTATION_DEG))
                        && claims::within_level(t, (0.0, STABLE_TRANSLATION_PERCENT)),
                    format!(
                        "worst at n ≥ 12: E_rot {}° ({}), E_t {}% ({})",
                        num(r),
                        sr.name(),
                        num(t),
                        st.name()
                    ),
                )
                .missing(missing.clone()),
        ),
        _ => out.push(claim.skip("not evaluated: no data at n ≥ 12")),
    }

    // (2) DLT and EPnP are poor, especially with few points.
    let claim = Claim::new(
        "points.dlt-epnp-poor",
        "§4.3 (2), Fig. 7",
        "DLT and EPnP have the largest errors, especially with few points.",
        "DLT and EPnP have the two largest mean E_rot among the paper solvers available, pooled over the n every one of them accepts; and each one's ratio to the median of the other paper solvers is larger at that smallest common n than at n = 20",
    );
    match (find(context, "dlt"), find(context, "epnp")) {
        (Some(dlt), Some(epnp)) => {
            let common_min = paper
                .iter()
                .map(|s| s.min_points())
                .max()
                .unwrap_or(MIN_COUNT);
            let pooled: Vec<(Solver, f64)> = paper
                .iter()
                .filter_map(|&s| {
                    let cell = panel.pooled(s, |x| x >= common_min as f64)?;
                    Some((s, cell.rotation_deg.mean()?))
                })
                .collect();
            let mut ranked = pooled.clone();
            ranked.sort_by(|a, b| b.1.total_cmp(&a.1));
            let top: Vec<Solver> = ranked.iter().take(2).map(|r| r.0).collect();
            let ratio_at = |s: Solver, i: usize| -> Option<f64> {
                let own = panel.cell(i, s)?.rotation_deg.mean()?;
                let mut others: Vec<f64> = paper
                    .iter()
                    .filter(|&&o| o != dlt && o != epnp)
                    .filter_map(|&o| panel.cell(i, o)?.rotation_deg.mean())
                    .collect();
                Some(own / crate::statistics::median(&mut others)?)
            };
            let i_min = x_of(panel, common_min).unwrap_or(0);
            let mut few_worse = true;
            let mut parts = Vec::new();
            for s in [dlt, epnp] {
                match (ratio_at(s, i_min), ratio_at(s, i20)) {
                    (Some(small), Some(large)) => {
                        few_worse &= small > large;
                        parts.push(format!(
                            "{}: {}× the others' median at n = {common_min}, {}× at n = 20",
                            s.name(),
                            num(small),
                            num(large)
                        ));
                    }
                    _ => few_worse = false,
                }
            }
            let holds = top.contains(&dlt) && top.contains(&epnp) && few_worse;
            let ranking = ranked
                .iter()
                .map(|(s, m)| format!("{} {}°", s.name(), num(*m)))
                .collect::<Vec<_>>()
                .join(" > ");
            out.push(
                claim
                    .judge(
                        holds,
                        format!(
                            "pooled over n ≥ {common_min}: {ranking}; {}",
                            parts.join("; ")
                        ),
                    )
                    .missing(missing.clone()),
            );
        }
        _ => out.push(claim.solvers_missing(vec!["dlt".into(), "epnp".into()])),
    }

    let pw = find(context, "parallel-weighted");
    let few_cell = |s: Solver| panel.pooled(s, |x| FEW_POINTS.contains(&(x as usize)));
    let all_cell = |s: Solver| panel.pooled(s, |_| true);

    // (3) More accurate than LHM, especially for n < 6.
    let claim = Claim::new(
        "points.beats-lhm-few-points",
        "§4.3 (3), Fig. 7",
        "The proposed method is more accurate than LHM, especially with few points (n < 6).",
        "improvement rule on mean E_rot, parallel-weighted against LHM, pooled over n = 4, 5",
    );
    match (pw, find(context, "lhm")) {
        (Some(pw), Some(lhm)) => {
            let pair = few_cell(pw).zip(few_cell(lhm));
            match pair.and_then(|(a, b)| {
                claims::improves(&a.rotation_deg, &b.rotation_deg).map(|r| (a, b, r))
            }) {
                Some((a, b, (holds, c))) => out.push(claim.judge_order(
                    holds,
                    &c,
                    format!(
                        "n = 4–5: LHM {}° vs parallel-weighted {}°: LHM/proposed = {}",
                        num(b.rotation_deg.mean),
                        num(a.rotation_deg.mean),
                        describe(&c)
                    ),
                )),
                None => out.push(claim.skip("not evaluated: no poses at n = 4–5")),
            }
        }
        _ => out.push(claim.solvers_missing(vec!["lhm".into()])),
    }

    // (3) Only slightly worse than RPnP and OPnP.
    let claim = Claim::new(
        "points.slightly-worse-than-rpnp-opnp",
        "§4.3 (3), Fig. 7",
        "The proposed method is only slightly worse than RPnP and OPnP.",
        &format!(
            "per setting: the median over n = 4…20 of parallel-weighted's median E_rot / X's ≤ {} for X = RPnP and OPnP (gross-failure rates shown apart)",
            claims::COMPARABLE_RATIO
        ),
    );
    let (refs, refs_missing) = group(context, &["rpnp", "opnp"]);
    match pw {
        Some(pw) if !refs.is_empty() => {
            let mut holds = true;
            let mut parts = Vec::new();
            let failures = |s: Solver| {
                all_cell(s)
                    .and_then(|c| c.failure_rate())
                    .map_or("—".to_string(), |r| format!("{:.1}%", 100.0 * r))
            };
            for &r in &refs {
                let settings: Vec<(Stat, Stat)> = (0..panel.x.len())
                    .filter_map(|i| {
                        let (a, b) = panel.cell(i, pw).zip(panel.cell(i, r))?;
                        Some((a.rotation_deg, b.rotation_deg))
                    })
                    .collect();
                let ratio = claims::per_setting_ratio(&settings).unwrap_or(f64::NAN);
                holds &= ratio <= claims::COMPARABLE_RATIO;
                parts.push(format!(
                    "parallel-weighted / {}: {} per setting{}",
                    r.name(),
                    num(ratio),
                    if ratio < 1.0 {
                        " (the proposed method is better)"
                    } else {
                        ""
                    }
                ));
            }
            parts.push(format!(
                "gross failures over n = 4…20: parallel-weighted {}, {}",
                failures(pw),
                refs.iter()
                    .map(|&r| format!("{} {}", r.name(), failures(r)))
                    .collect::<Vec<_>>()
                    .join(", ")
            ));
            out.push(claim.judge(holds, parts.join("; ")).missing(refs_missing));
        }
        _ => out.push(claim.solvers_missing(refs_missing)),
    }

    // (4) Weighted GN slightly better than paraperspective alone.
    for (id, other_name, statement) in [
        (
            "points.weighted-beats-parallel",
            "parallel",
            "The weighted method is slightly better than paraperspective without Gauss–Newton.",
        ),
        (
            "points.weights-beat-unweighted-gn",
            "parallel-gn",
            "The accuracy gain comes from the weighted Gauss–Newton (ablation: the same pipeline with unit weights).",
        ),
    ] {
        let claim = Claim::new(
            id,
            "§4.3 (4), Fig. 7",
            statement,
            &format!("\"slightly better\" rule on mean E_rot pooled over n = 4…20, parallel-weighted against {other_name}"),
        );
        match (pw, find(context, other_name)) {
            (Some(pw), Some(other)) => {
                let pair = all_cell(pw).zip(all_cell(other));
                match pair.and_then(|(a, b)| {
                    claims::slightly_better(&a.rotation_deg, &b.rotation_deg).map(|r| (a, b, r))
                }) {
                    Some((a, b, (holds, c))) => out.push(claim.judge_order(
                        holds,
                        &c,
                        format!(
                            "{other_name} {}° vs parallel-weighted {}°: ratio {}",
                            num(b.rotation_deg.mean),
                            num(a.rotation_deg.mean),
                            describe(&c)
                        ),
                    )),
                    None => out.push(claim.skip("not evaluated: no poses")),
                }
            }
            _ => out.push(claim.solvers_missing(vec![other_name.into()])),
        }
    }

    // §2.1: EPnP+GN is erratic at n = 4–5.
    let claim = Claim::new(
        "points.epnp-gn-erratic-few-points",
        "§2.1",
        "EPnP+GN performs erratically when n = 4 or 5.",
        &format!(
            "EPnP+GN's failure rate at n = 4–5 ≥ {} and ≥ {}× its rate at n ≥ {MANY_POINTS_FROM}",
            claims::ERRATIC_RATE,
            claims::ERRATIC_FACTOR
        ),
    );
    let rates = |s: Solver| {
        let few = few_cell(s)?.failure_rate()?;
        let many = panel
            .pooled(s, |x| x >= MANY_POINTS_FROM as f64)?
            .failure_rate()?;
        Some((few, many))
    };
    match find(context, "epnp-gn").and_then(|s| rates(s).map(|r| (s, r))) {
        Some((_, (few, many))) => {
            let holds = few >= claims::ERRATIC_RATE && few >= claims::ERRATIC_FACTOR * many;
            let others = context
                .solvers
                .iter()
                .filter_map(|&s| rates(s).map(|(f, _)| format!("{} {:.1}%", s.name(), 100.0 * f)))
                .collect::<Vec<_>>()
                .join(", ");
            out.push(claim.judge(
                holds,
                format!(
                    "EPnP+GN fails in {:.1}% of trials at n = 4–5 and {:.1}% at n ≥ {MANY_POINTS_FROM}; every solver at n = 4–5: {others}",
                    100.0 * few,
                    100.0 * many
                ),
            ));
        }
        None => out.push(claim.solvers_missing(vec!["epnp-gn".into()])),
    }

    // §2.1: the paraperspective start makes the method more stable than EPnP+GN.
    let claim = Claim::new(
        "points.more-stable-than-epnp-gn",
        "§2.1, §3.1",
        "Starting the betas from paraperspective makes the method more stable than EPnP+GN at few points.",
        "improvement rule on mean E_rot pooled over n = 4, 5: parallel-weighted against EPnP+GN",
    );
    match (pw, find(context, "epnp-gn")) {
        (Some(pw), Some(gn)) => {
            let pair: Option<(Stat, Stat)> = few_cell(pw)
                .zip(few_cell(gn))
                .map(|(a, b)| (a.rotation_deg, b.rotation_deg));
            match pair.and_then(|(a, b)| claims::improves(&a, &b).map(|r| (a, b, r))) {
                Some((a, b, (holds, c))) => out.push(claim.judge_order(
                    holds,
                    &c,
                    format!(
                        "n = 4–5: EPnP+GN {}° vs parallel-weighted {}°: {}",
                        num(b.mean),
                        num(a.mean),
                        describe(&c)
                    ),
                )),
                None => out.push(claim.skip("not evaluated: no poses at n = 4–5")),
            }
        }
        _ => out.push(claim.solvers_missing(vec!["epnp-gn".into()])),
    }
    out
}
