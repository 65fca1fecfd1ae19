//! Time to render one 1280×720 frame of the 7-sphere search winner
//! (`layouts/biprism-search.json`, pillars) at 4×4 supersampling on one
//! core, head on at 200, 600 and 1000 mm and tilted 40° at 600 mm, and
//! the time to add sensor noise to a rendered frame.
//!
//! `cargo bench --bench render`
//!
//! Each frame renders on a pool of one thread and is timed in the process's
//! CPU time ([`cpu_time::CpuTime`]), so the figures are the cost on one
//! core whatever else the machine is doing.

mod cpu_time;

use cpu_time::CpuTime;
use criterion::{criterion_group, criterion_main, Criterion};
use layout_opt::camera::Camera;
use layout_opt::layout::Layout;
use layout_opt::mesh::{Marker, MarkerOptions};
use layout_opt::pose::Pose;
use layout_opt::render::{expose, render_radiance, RenderConfig, Scene};
use nalgebra::{Rotation3, Vector3};
use std::hint::black_box;

fn pose(depth_mm: f64, tilt_deg: f64) -> Pose {
    Pose::new(
        Rotation3::from_axis_angle(&Vector3::x_axis(), tilt_deg.to_radians()),
        Vector3::new(0.0, 0.0, depth_mm),
    )
}

fn bench(c: &mut Criterion<CpuTime>) {
    // The benches are a package of their own in benches/: the layouts are
    // one folder up.
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../layouts/biprism-search.json");
    let layout = Layout::load(&path).expect("the search winner loads");
    let scene = Scene::from_marker(
        Marker::design(&layout, &MarkerOptions::default()).expect("the part builds"),
    );
    let config = RenderConfig::new(Camera::paper());
    let one_core = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("a pool of one thread");
    let mut group = c.benchmark_group("render");
    group.sample_size(20);
    for (name, depth_mm, tilt_deg) in [
        ("frame_200mm", 200.0, 0.0),
        ("frame_600mm", 600.0, 0.0),
        ("frame_1000mm", 1000.0, 0.0),
        ("frame_600mm_tilt40", 600.0, 40.0),
    ] {
        let pose = pose(depth_mm, tilt_deg);
        group.bench_function(name, |b| {
            b.iter(|| {
                one_core.install(|| render_radiance(&scene, black_box(&pose), &config).unwrap())
            })
        });
    }
    let radiance = render_radiance(&scene, &pose(600.0, 0.0), &config).unwrap();
    for bits in [8u8, 16] {
        let mut sensor = config.sensor;
        sensor.bit_depth = bits;
        group.bench_function(format!("noise_{bits}bit"), |b| {
            b.iter(|| one_core.install(|| expose(black_box(&radiance), &sensor, 7, 0, 0)))
        });
    }
    group.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default().with_measurement(CpuTime);
    targets = bench
}
criterion_main!(benches);
