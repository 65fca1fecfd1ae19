//! Eigen-solver benchmark: the four smallest eigenpairs of EPnP's 12×12
//! `MᵀM` (Lepetit et al. 2009, eq. 9) by `nalgebra::SymmetricEigen` (full
//! decomposition) and by [`layout_opt::linalg::smallest_eigenpairs`], on the
//! paper's biprism (L = 50 mm) at 500 mm and 5000 mm with σ = 0.5 px, and
//! the end-to-end `solve_best` of EPnP and the paper's method on the 500 mm
//! problem.
//!
//! Run: `cargo bench --bench eigen` (add `-- eigen/` for the eigen-solvers
//! only); criterion prints its estimates and writes them, medians included,
//! to `target/criterion/`.

use criterion::{black_box, criterion_group, criterion_main, Criterion};
use layout_opt::camera::Camera;
use layout_opt::linalg::smallest_eigenpairs;
use layout_opt::pnp::epnp::{principal_control_points, EpnpSystem};
use layout_opt::pnp::Solver;
use layout_opt::synthetic::{biprism_points, project_with_noise, random_pose, stream_rng, Problem};
use nalgebra::SymmetricEigen;
use std::time::Duration;

const SIGMA_PX: f64 = 0.5;

fn biprism_problem(depth_mm: f64) -> Problem {
    let mut rng = stream_rng(7, 1, depth_mm as u64);
    let truth = random_pose(&mut rng, depth_mm, 0.1);
    project_with_noise(
        &mut rng,
        &Camera::paper(),
        biprism_points(50.0),
        truth,
        SIGMA_PX,
    )
    .expect("the biprism is in front of the camera at this depth")
}

fn bench(c: &mut Criterion) {
    for depth_mm in [500.0, 5000.0] {
        let p = biprism_problem(depth_mm);
        let mtm = EpnpSystem::normal_matrix(
            principal_control_points(&p.object),
            &p.object,
            &p.normalised,
        )
        .expect("the biprism's control points are not coplanar");
        let mut group = c.benchmark_group(format!("eigen/biprism-{depth_mm}mm"));
        group.warm_up_time(Duration::from_millis(500));
        group.measurement_time(Duration::from_secs(3));
        group.bench_function("SymmetricEigen", |b| {
            b.iter(|| SymmetricEigen::new(black_box(mtm)))
        });
        group.bench_function("smallest_eigenpairs", |b| {
            b.iter(|| smallest_eigenpairs::<12, 4>(black_box(&mtm)))
        });
        group.finish();
    }

    let p = biprism_problem(500.0);
    let mut group = c.benchmark_group("solve_best/biprism-500mm");
    group.warm_up_time(Duration::from_millis(500));
    group.measurement_time(Duration::from_secs(3));
    for solver in [Solver::Epnp, Solver::ParallelWeighted] {
        group.bench_function(solver.name(), |b| {
            b.iter(|| solver.solve_best(black_box(&p.object), black_box(&p.normalised)))
        });
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
