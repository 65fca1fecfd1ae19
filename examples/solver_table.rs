//! Accuracy and speed of every solver on seeded near-field biprism problems:
//! the paper's 7-point biprism (L = 50 mm), depth 200–1000 mm (depth/size
//! 2–10), random attitude, up to 20% off axis, σ = 0.5 px on the paper's
//! camera. Prints median and mean rotation error, RMS translation error (%),
//! gross failures (> 10°), RMS rotation / Cramér–Rao limit (per problem) and
//! median single-thread µs per solve.
//!
//! Run: `cargo run --release --features examples --example solver_table -- [problems] [seed]`

use layout_opt::camera::Camera;
use layout_opt::error_model::first_order::pose_covariance_isotropic;
use layout_opt::pnp::Solver;
use layout_opt::pose::{rotation_error_deg, translation_error_percent};
use layout_opt::synthetic::{biprism_points, project_with_noise, random_pose, stream_rng, Problem};
use rand::Rng;
use std::time::Instant;

fn main() {
    let mut args = std::env::args().skip(1);
    let count: usize = args
        .next()
        .map_or(1000, |a| a.parse().expect("problem count"));
    let seed: u64 = args.next().map_or(2026, |a| a.parse().expect("seed"));
    let camera = Camera::paper();
    let sigma_px = 0.5;
    let problems: Vec<(Problem, f64)> = (0..count as u64)
        .map(|case| {
            let mut rng = stream_rng(seed, 42, case);
            let depth = rng.random_range(200.0..1000.0);
            let truth = random_pose(&mut rng, depth, 0.2);
            let p = project_with_noise(&mut rng, &camera, biprism_points(50.0), truth, sigma_px)
                .expect("in front");
            let limit = pose_covariance_isotropic(&camera, &p.truth, &p.object, sigma_px)
                .unwrap()
                .rms_rotation_deg();
            (p, limit)
        })
        .collect();
    println!("{count} near-field biprism problems, σ = {sigma_px} px, seed {seed}");
    println!(
        "| solver | median rot (°) | mean rot (°) | RMS trans (%) | gross > 10° | errors | RMS rot / CRLB | median µs |\n|---|---|---|---|---|---|---|---|"
    );
    for &solver in Solver::ALL {
        let mut rotation = Vec::new();
        let mut translation_sq = 0.0;
        let mut ratio_sq = 0.0;
        let (mut gross, mut errors) = (0, 0);
        let mut micros = Vec::new();
        for (p, limit) in &problems {
            // Time the best of three solves of the same problem (single thread).
            let mut best = f64::INFINITY;
            let mut result = None;
            for _ in 0..3 {
                let start = Instant::now();
                let r = solver.solve_best(&p.object, &p.normalised);
                best = best.min(start.elapsed().as_secs_f64() * 1e6);
                result = Some(r);
            }
            micros.push(best);
            match result.unwrap() {
                Ok(pose) => {
                    let r = rotation_error_deg(&p.truth.rotation, &pose.rotation);
                    if r > 10.0 {
                        gross += 1;
                    } else {
                        ratio_sq += (r / limit).powi(2);
                    }
                    rotation.push(r);
                    translation_sq +=
                        translation_error_percent(&p.truth.translation, &pose.translation).powi(2);
                }
                Err(_) => errors += 1,
            }
        }
        let n = rotation.len().max(1) as f64;
        let mean = rotation.iter().sum::<f64>() / n;
        rotation.sort_by(f64::total_cmp);
        micros.sort_by(f64::total_cmp);
        let median = rotation
            .get(rotation.len() / 2)
            .copied()
            .unwrap_or(f64::NAN);
        let kept = (rotation.len() - gross).max(1) as f64;
        println!(
            "| `{}` | {:.4} | {:.4} | {:.4} | {} | {} | {:.3} | {:.2} |",
            solver.name(),
            median,
            mean,
            (translation_sq / n).sqrt(),
            gross,
            errors,
            (ratio_sq / kept).sqrt(),
            micros[micros.len() / 2]
        );
    }
}
