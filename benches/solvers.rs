//! Solver benchmark: the same columns for every solver (PoseLib's
//! benchmark): median single-thread time per solve (criterion), % of problems
//! with a valid pose, and % within tolerance of the ground truth, on the
//! paper's 7-point biprism and on random noncoplanar sets with n = 4…104.
//!
//! Run: `cargo bench --bench solvers` (add `-- biprism` for n = 7 only).
//! The accuracy columns are printed before the timings; criterion writes the
//! medians to `target/criterion/`.

use criterion::{black_box, criterion_group, criterion_main, BenchmarkId, Criterion};
use layout_opt::camera::Camera;
use layout_opt::pnp::Solver;
use layout_opt::pose::rotation_error_deg;
use layout_opt::synthetic::{
    biprism_points, project_with_noise, random_points, random_pose, stream_rng, Problem,
};
use std::time::Duration;

const PROBLEMS: usize = 64;
const SIGMA_PX: f64 = 0.5;
/// "Within tolerance": rotation error below this at σ = 0.5 px.
const TOLERANCE_DEG: f64 = 1.0;

fn problems(n: Option<usize>, seed: u64) -> Vec<Problem> {
    let camera = Camera::paper();
    let mut out = Vec::with_capacity(PROBLEMS);
    let mut case = 0;
    while out.len() < PROBLEMS {
        let mut rng = stream_rng(seed, n.unwrap_or(7) as u64, case);
        case += 1;
        let object = match n {
            None => biprism_points(50.0),
            Some(n) => random_points(&mut rng, n, 100.0),
        };
        // Near field: depth 200–1000 mm for a 100 mm marker.
        let depth = 200.0 + 800.0 * (case % 5) as f64 / 4.0;
        let truth = random_pose(&mut rng, depth, 0.2);
        if object.iter().any(|p| truth.transform(p).z < 50.0) {
            continue;
        }
        if let Some(p) = project_with_noise(&mut rng, &camera, object, truth, SIGMA_PX) {
            out.push(p);
        }
    }
    out
}

fn accuracy_row(solver: Solver, label: &str, set: &[Problem]) {
    let mut valid = 0;
    let mut within = 0;
    for p in set {
        if let Ok(pose) = solver.solve_best(&p.object, &p.normalised) {
            valid += 1;
            if rotation_error_deg(&p.truth.rotation, &pose.rotation) < TOLERANCE_DEG {
                within += 1;
            }
        }
    }
    let percent = |k: usize| 100.0 * k as f64 / set.len() as f64;
    println!(
        "{:<18} {:<8} valid {:>5.1}%  within {TOLERANCE_DEG}° {:>5.1}%",
        solver.name(),
        label,
        percent(valid),
        percent(within)
    );
}

fn bench(c: &mut Criterion) {
    let sets: Vec<(String, Vec<Problem>)> =
        std::iter::once(("biprism".to_string(), problems(None, 1)))
            .chain(
                [4usize, 8, 16, 32, 64, 104]
                    .into_iter()
                    .map(|n| (format!("n={n}"), problems(Some(n), 2))),
            )
            .collect();
    println!("accuracy at σ = {SIGMA_PX} px over {PROBLEMS} near-field problems per set");
    for &solver in Solver::ALL {
        for (label, set) in &sets {
            if set[0].object.len() >= solver.min_points() {
                accuracy_row(solver, label, set);
            }
        }
    }
    for (label, set) in &sets {
        let mut group = c.benchmark_group(label.as_str());
        group.warm_up_time(Duration::from_millis(500));
        group.measurement_time(Duration::from_secs(2));
        for &solver in Solver::ALL {
            if set[0].object.len() < solver.min_points() {
                continue;
            }
            group.bench_with_input(BenchmarkId::from_parameter(solver.name()), set, |b, set| {
                let mut index = 0;
                b.iter(|| {
                    let p = &set[index % set.len()];
                    index += 1;
                    black_box(
                        solver
                            .solve_best(black_box(&p.object), black_box(&p.normalised))
                            .ok(),
                    )
                })
            });
        }
        group.finish();
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
