//! Monte-Carlo and first-order throughput on the paper's biprism over the
//! default validate grid (the paper's protocol: 5 depths × 3 offsets × 91
//! tilts). Run: `cargo bench --bench montecarlo`.
//!
//! * `mc/parallel-weighted`: 1365 scenarios × 200 trials (validate's
//!   default grid and trial count) of the paper's solver through the engine
//!   (rayon over scenarios), including each scenario's first-order,
//!   transfer-model and visibility work: solves per second = 273,000 /
//!   median time.
//! * `first_order/1365_scenarios`: the first-order covariance of every
//!   scenario, single thread: scenarios per millisecond = 1365 / median (ms).

use criterion::{black_box, criterion_group, criterion_main, Criterion};
use layout_opt::camera::Camera;
use layout_opt::error_model::first_order::pose_covariance_isotropic;
use layout_opt::montecarlo::{run, MonteCarloConfig, Target, DEFAULT_GROSS_THRESHOLD_DEG};
use layout_opt::noise::NoiseModel;
use layout_opt::pnp::Solver;
use layout_opt::scenario::ScenarioGrid;
use layout_opt::synthetic::biprism_points;
use std::time::Duration;

fn bench(c: &mut Criterion) {
    let camera = Camera::paper();
    let object = biprism_points(50.0);
    let scenarios = ScenarioGrid::paper_protocol(2.0).scenarios();
    let sigmas = [None; 7];
    let target = Target {
        camera: &camera,
        object: &object,
        sphere_diameter_mm: 10.0,
        point_sigma_px: &sigmas,
    };
    let config = MonteCarloConfig {
        trials: 200,
        seed: 1,
        solvers: vec![Solver::ParallelWeighted],
        noise: NoiseModel::default(),
        gross_threshold_deg: DEFAULT_GROSS_THRESHOLD_DEG,
        observation: layout_opt::sphere_image::Observation::Centre,
    };
    let mut group = c.benchmark_group("mc");
    group
        .sample_size(10)
        .measurement_time(Duration::from_secs(10));
    group.bench_function("parallel-weighted", |b| {
        b.iter(|| black_box(run(&target, &scenarios, &config, &|_| {}).unwrap()))
    });
    group.finish();
    let poses: Vec<_> = scenarios.iter().map(|s| s.pose()).collect();
    c.bench_function("first_order/1365_scenarios", |b| {
        b.iter(|| {
            poses
                .iter()
                .map(|pose| {
                    pose_covariance_isotropic(&camera, pose, &object, 0.5)
                        .map(|c| c.rms_rotation_deg())
                        .unwrap_or(0.0)
                })
                .sum::<f64>()
        })
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
