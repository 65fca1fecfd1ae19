//! Single-thread timing of the baseline solvers on the paper's 7-point
//! biprism: `cargo run --release --features examples --example baseline_timing`.
//!
//! For each of 100 seeded problems per setting, the time of one solve is the
//! fastest of 15 batches of 40 solves (the minimum filters out time stolen by
//! other processes on a shared machine); the median over problems is printed.
//! `module` is the solver's own `solve`; `Solver::solve` adds input validation.

use layout_opt::camera::Camera;
use layout_opt::pnp::{lhm, rpnp, sqpnp, Candidates, PnpError, Solver};
use layout_opt::synthetic::{biprism_points, project_with_noise, random_pose, stream_rng, Problem};
use nalgebra::{Vector2, Vector3};
use rand::Rng;
use std::hint::black_box;
use std::time::Instant;

type Module = fn(&[Vector3<f64>], &[Vector2<f64>]) -> Result<Candidates, PnpError>;

fn problems(near: bool, sigma_px: f64) -> Vec<Problem> {
    let camera = Camera::paper();
    (0..100)
        .map(|case| {
            let mut rng = stream_rng(2026, 9, case);
            let ratio = if near { 2.0 } else { 20.0 } * 10f64.powf(rng.random::<f64>());
            let truth = random_pose(&mut rng, ratio * 100.0, 0.4);
            project_with_noise(&mut rng, &camera, biprism_points(50.0), truth, sigma_px)
                .expect("the biprism is in front")
        })
        .collect()
}

fn median_microseconds(problems: &[Problem], solve: impl Fn(&Problem)) -> f64 {
    let mut times: Vec<f64> = problems
        .iter()
        .map(|p| {
            (0..15)
                .map(|_| {
                    let start = Instant::now();
                    for _ in 0..40 {
                        solve(black_box(p));
                    }
                    start.elapsed().as_secs_f64() / 40.0
                })
                .fold(f64::INFINITY, f64::min)
        })
        .collect();
    times.sort_by(f64::total_cmp);
    times[times.len() / 2] * 1e6
}

fn main() {
    let modules: [(Solver, Module); 3] = [
        (Solver::Lhm, lhm::solve),
        (Solver::Rpnp, rpnp::solve),
        (Solver::Sqpnp, sqpnp::solve),
    ];
    println!("n = 7 biprism, median over 100 problems of the fastest of 15x40 solves (us)");
    println!(
        "{:<10} {:<26} {:>8} {:>14}",
        "solver", "setting", "module", "Solver::solve"
    );
    for (near, sigma_px) in [(true, 0.0), (true, 0.5), (false, 0.0), (false, 0.5)] {
        let set = problems(near, sigma_px);
        let setting = format!(
            "{} field, sigma {sigma_px} px",
            if near { "near (2-20)" } else { "far (20-200)" }
        );
        for (solver, module) in modules {
            let direct = median_microseconds(&set, |p| {
                black_box(module(&p.object, &p.normalised).ok());
            });
            let full = median_microseconds(&set, |p| {
                black_box(solver.solve(&p.object, &p.normalised).ok());
            });
            println!(
                "{:<10} {:<26} {:>8.2} {:>14.2}",
                solver.name(),
                setting,
                direct,
                full
            );
        }
        let full = median_microseconds(&set, |p| {
            black_box(Solver::EpnpGn.solve(&p.object, &p.normalised).ok());
        });
        println!("{:<10} {:<26} {:>8} {:>14.2}", "epnp-gn", setting, "", full);
    }
}
