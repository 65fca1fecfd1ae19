//! OPnP report: how many candidate solutions it returns on typical problems,
//! and how long one solve takes next to EPnP.
//!
//! ```text
//! cargo run --release --features examples --example opnp_report            # counts and timings
//! cargo run --release --features examples --example opnp_report -- counts  # counts only
//! ```
//!
//! Problems: the paper's biprism (n = 7) and random cube points (n = 6…100),
//! depth/size log-uniform in 2–200, random attitude, off-axis up to 40%,
//! σ = 0.5 px on the paper's camera; every draw seeded.
//!
//! Timing is wall clock, single thread: each problem is timed in `REPEATS`
//! batches (one OPnP solve, or 50 EPnP solves, per batch) and the fastest
//! batch counts, which discounts interruptions from other load on the
//! machine; the median over problems is reported.

use layout_opt::camera::Camera;
use layout_opt::pnp::{opnp, Solver};
use layout_opt::spread::Spread;
use layout_opt::synthetic::{
    biprism_points, project_with_noise, random_points, random_pose, stream_rng, Problem,
};
use rand::Rng;

const SEED: u64 = 2013;
const SIGMA_PX: f64 = 0.5;

/// Problem `case` with `count` points (`None`: the biprism).
fn problem(count: Option<usize>, case: u64) -> Problem {
    let camera = Camera::paper();
    let stream = count.map_or(1, |n| 100 + n as u64);
    let mut attempt = 0;
    loop {
        let mut rng = stream_rng(SEED, stream, case * 64 + attempt);
        attempt += 1;
        let object = match count {
            None => biprism_points(50.0),
            Some(n) => random_points(&mut rng, n, 100.0),
        };
        let spread = Spread::of(&object);
        if spread.extents[2] < 0.25 * spread.extents[0] {
            continue;
        }
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

fn median(values: &mut [f64]) -> f64 {
    values.sort_by(f64::total_cmp);
    values[values.len() / 2]
}

fn summary(name: &str, values: &[usize]) {
    let mut sorted = values.to_vec();
    sorted.sort_unstable();
    let mean = sorted.iter().sum::<usize>() as f64 / sorted.len() as f64;
    println!(
        "  {name:<34} median {:>3}  mean {mean:>5.2}  max {:>3}  min {:>3}",
        sorted[sorted.len() / 2],
        sorted[sorted.len() - 1],
        sorted[0]
    );
}

fn counts() {
    let mut eigen = Vec::new();
    let mut real = Vec::new();
    let mut minima = Vec::new();
    let mut in_front = Vec::new();
    let mut errors = 0;
    for case in 0..1000u64 {
        let count = if case % 2 == 0 {
            None
        } else {
            Some(6 + (case as usize / 2) % 95)
        };
        let p = problem(count, case);
        match opnp::solve_with_report(&p.object, &p.normalised) {
            Ok((candidates, report)) => {
                eigen.push(report.real_eigenvalues);
                real.push(report.real_solutions);
                minima.push(report.minima);
                in_front.push(
                    candidates
                        .iter()
                        .filter(|c| c.all_in_front(&p.object))
                        .count(),
                );
            }
            Err(e) => {
                errors += 1;
                eprintln!("case {case}: {e}");
            }
        }
    }
    println!(
        "OPnP solution counts, 1000 problems (500 biprism, 500 random n = 6…100), σ = {SIGMA_PX} px; {errors} errors:"
    );
    summary("real eigenvalues (of 40)", &eigen);
    summary("real solution pairs ±q", &real);
    summary("local minima = candidates returned", &minima);
    summary("candidates with all points in front", &in_front);
}

/// Timed batches per problem; the fastest counts.
const REPEATS: usize = 5;

/// Median over `problems` of the fastest per-solve time of `solver`, in
/// seconds, timing batches of `batch` solves.
fn time(solver: Solver, problems: &[Problem], batch: usize) -> f64 {
    let mut per_problem: Vec<f64> = problems
        .iter()
        .map(|p| {
            (0..REPEATS)
                .map(|_| {
                    let start = std::time::Instant::now();
                    for _ in 0..batch {
                        std::hint::black_box(solver.solve(&p.object, &p.normalised).ok());
                    }
                    start.elapsed().as_secs_f64() / batch as f64
                })
                .fold(f64::INFINITY, f64::min)
        })
        .collect();
    median(&mut per_problem)
}

fn timings() {
    println!(
        "Median over 100 problems of the fastest of {REPEATS} timings per solve (single thread):"
    );
    println!(
        "  {:<16} {:>12} {:>12} {:>10}",
        "points", "EPnP", "OPnP", "OPnP/EPnP"
    );
    let rows: Vec<(String, Option<usize>)> = std::iter::once(("biprism n=7".to_string(), None))
        .chain(
            [4usize, 5, 6, 8, 16, 32, 64, 104]
                .into_iter()
                .map(|n| (format!("random n={n}"), Some(n))),
        )
        .collect();
    for (label, count) in rows {
        let problems: Vec<Problem> = (0..100).map(|case| problem(count, case)).collect();
        // Warm up (builds OPnP's template once).
        let _ = Solver::Opnp.solve(&problems[0].object, &problems[0].normalised);
        let epnp = time(Solver::Epnp, &problems, 50);
        let opnp = time(Solver::Opnp, &problems, 1);
        println!(
            "  {label:<16} {:>9.2} µs {:>9.3} ms {:>9.0}×",
            epnp * 1e6,
            opnp * 1e3,
            opnp / epnp
        );
    }
}

fn main() {
    let which = std::env::args().nth(1).unwrap_or_default();
    if which.is_empty() || which == "counts" {
        counts();
    }
    if which.is_empty() || which == "timings" {
        timings();
    }
}
