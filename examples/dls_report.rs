//! DLS report: candidate counts and single-thread solve times.
//!
//! `cargo run --release --features examples --example dls_report [PROBLEMS]`
//!
//! Problems are drawn like the integration tests' (random attitude, depth /
//! size 2–200 log-uniform, off axis up to 40%, σ = 0.5 px on the paper's
//! camera), seeded. Each problem is solved [`REPEATS`] times on the calling
//! thread, each solve timed on its own; the table gives the median over
//! problems of the fastest of those (robust to other processes taking the
//! core) and of their mean.

use layout_opt::camera::Camera;
use layout_opt::pnp::dls::ChartPolicy;
use layout_opt::pnp::{best_candidate, dls, Solver};
use layout_opt::pose::{rotation_error_deg, Pose};
use layout_opt::synthetic::{
    biprism_points, project_with_noise, random_points, random_pose, stream_rng, Problem,
};
use rand::Rng;
use std::time::Instant;

const SEED: u64 = 42;
const SIGMA_PX: f64 = 0.5;
const REPEATS: usize = 20;

fn problem(count: usize, case: u64) -> Problem {
    let camera = Camera::paper();
    let mut attempt = 0;
    loop {
        let mut rng = stream_rng(SEED, count as u64, case * 64 + attempt);
        attempt += 1;
        let object = if count == 7 {
            biprism_points(50.0)
        } else {
            random_points(&mut rng, count, 100.0)
        };
        let ratio = 2.0 * 100f64.powf(rng.random::<f64>());
        let truth = random_pose(&mut rng, ratio * 100.0, 0.4);
        if object.iter().any(|p| truth.transform(p).z < 50.0) {
            continue;
        }
        if let Some(p) = project_with_noise(&mut rng, &camera, object, truth, SIGMA_PX) {
            return p;
        }
    }
}

/// (fastest, mean) of [`REPEATS`] separately timed solves, in seconds.
fn time(solver: Solver, p: &Problem) -> (f64, f64) {
    let mut fastest = f64::INFINITY;
    let mut total = 0.0;
    for _ in 0..REPEATS {
        let start = Instant::now();
        std::hint::black_box(solver.solve(&p.object, &p.normalised).ok());
        let seconds = start.elapsed().as_secs_f64();
        fastest = fastest.min(seconds);
        total += seconds;
    }
    (fastest, total / REPEATS as f64)
}

/// Medians of the fastest and of the mean times, as text in microseconds.
fn time_summary(times: &[(f64, f64)]) -> String {
    if times.is_empty() {
        return "-".to_string();
    }
    let mut fastest: Vec<f64> = times.iter().map(|t| t.0).collect();
    let mut mean: Vec<f64> = times.iter().map(|t| t.1).collect();
    format!(
        "{:.0} / {:.0} us",
        1e6 * median(&mut fastest),
        1e6 * median(&mut mean)
    )
}

/// A four-chart candidate counts as found when one on-demand candidate is
/// this close (the charts weight the noisy cost differently, module docs).
const MATCH_DEG: f64 = 1.0;
/// The on-demand best candidate counts as worse when its rotation error
/// exceeds the four-chart best's by more than this.
const WORSE_DEG: f64 = 0.01;

/// (some four-chart candidate missed, best candidate worse, rotation errors
/// (°) of the two best candidates) for one problem.
fn compare_with_all_charts(p: &Problem, candidates: &[Pose]) -> (bool, bool, Option<(f64, f64)>) {
    let Ok((all, _)) = dls::solve_with_statistics_in(&p.object, &p.normalised, ChartPolicy::All)
    else {
        return (false, false, None);
    };
    let missed = all.iter().any(|a| {
        candidates
            .iter()
            .all(|c| rotation_error_deg(&a.rotation, &c.rotation) > MATCH_DEG)
    });
    let error = |set: &[Pose]| {
        best_candidate("DLS", set, &p.object, &p.normalised).map_or(f64::INFINITY, |b| {
            rotation_error_deg(&p.truth.rotation, &b.rotation)
        })
    };
    let (on_demand, all) = (error(candidates), error(&all));
    (missed, on_demand > all + WORSE_DEG, Some((on_demand, all)))
}

fn mean_charts(stats: &[dls::Statistics]) -> f64 {
    stats.iter().map(|s| s.charts_solved as f64).sum::<f64>() / stats.len().max(1) as f64
}

fn median(values: &mut [f64]) -> f64 {
    values.sort_by(f64::total_cmp);
    values[values.len() / 2]
}

fn main() {
    let problems: u64 = std::env::args()
        .nth(1)
        .map(|a| a.parse().expect("PROBLEMS is a count"))
        .unwrap_or(1000);
    println!("DLS on {problems} problems per n, sigma = {SIGMA_PX} px, one thread");
    println!(
        "{:>4} | {:>11} | {:>22} | {:>14} | {:>14} | {:>14} | {:>10} | {:>16} | {:>14} | {:>14}",
        "n",
        "charts",
        "real crit. pts",
        "local minima",
        "trusted",
        "in front",
        "returned",
        "DLS time",
        "EPnP+GN time",
        "vs all charts"
    );
    for count in [4usize, 5, 6, 7, 10, 20, 50, 104] {
        let mut stats = Vec::new();
        let mut dls_times = Vec::new();
        let mut epnp_times = Vec::new();
        let mut failures = 0;
        let (mut missed, mut worse) = (0, 0);
        let (mut errors_on_demand, mut errors_all) = (Vec::new(), Vec::new());
        for case in 0..problems {
            let p = problem(count, case);
            match dls::solve_with_statistics(&p.object, &p.normalised) {
                Ok((candidates, s)) => {
                    stats.push(s);
                    let (m, w, e) = compare_with_all_charts(&p, &candidates);
                    missed += usize::from(m);
                    worse += usize::from(w);
                    if let Some((on_demand, all)) = e {
                        errors_on_demand.push(on_demand);
                        errors_all.push(all);
                    }
                }
                Err(_) => failures += 1,
            }
            dls_times.push(time(Solver::Dls, &p));
            if count >= 6 {
                epnp_times.push(time(Solver::EpnpGn, &p));
            }
        }
        let summary = |f: &dyn Fn(&dls::Statistics) -> usize| {
            let mut v: Vec<f64> = stats.iter().map(|s| f(s) as f64).collect();
            let max = v.iter().copied().fold(0.0, f64::max);
            format!("{:>5.0} / {:<4.0}", median(&mut v), max)
        };
        println!(
            "{:>4} | {:>11} | {:>22} | {:>14} | {:>14} | {:>14} | {:>10} | {:>16} | {:>14} | {:>14}{}",
            if count == 7 {
                "7bp".to_string()
            } else {
                count.to_string()
            },
            format!("{} ({:.2})", summary(&|s| s.charts_solved).trim(), mean_charts(&stats)),
            summary(&|s| s.real_critical_points),
            summary(&|s| s.local_minima),
            summary(&|s| s.trusted),
            summary(&|s| s.in_front),
            summary(&|s| s.returned),
            time_summary(&dls_times),
            time_summary(&epnp_times),
            format!(
                "{missed} / {worse} / {:.4}° vs {:.4}°",
                median(&mut errors_on_demand),
                median(&mut errors_all)
            ),
            if failures > 0 {
                format!("  ({failures} errors)")
            } else {
                String::new()
            }
        );
    }
    println!("(counts: median / max; charts: median / max (mean); times: median fastest / median mean of {REPEATS}; 7bp = the paper's biprism)");
    println!(
        "(vs all charts: problems where a candidate of the four-chart solve has no candidate within {MATCH_DEG}° / where the best candidate is more than {WORSE_DEG}° further from the truth than the four-chart solve's best)"
    );
}
