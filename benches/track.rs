//! `track`'s per-frame cost: detection, identification and pose of a
//! 1280×720 frame of the 7-sphere search winner (test rasteriser, 8-bit,
//! blurred and noisy), on one core. Target: ≤ 5 ms.

#[path = "../tests/it/track/raster.rs"]
#[allow(dead_code)]
mod raster;

use criterion::{criterion_group, criterion_main, Criterion};
use layout_opt::camera::Camera;
use layout_opt::layout::Layout;
use layout_opt::pose::Pose;
use layout_opt::track::{analyse, GreyFrame, TrackConfig};
use nalgebra::{Rotation3, Vector3};

fn bench(c: &mut Criterion) {
    let layout = Layout::load(std::path::Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/layouts/biprism-search.json"
    )))
    .unwrap();
    let camera = Camera::paper();
    let object = layout.positions();
    let pose = Pose::new(
        Rotation3::from_euler_angles(0.35, -0.25, 0.4),
        Vector3::new(-5.0, -60.0, 500.0),
    );
    let mut scene = raster::Scene::clean(&camera, &object, layout.sphere_radius_mm(), pose);
    scene.bit_depth = 8;
    scene.blur_px = 0.7;
    scene.noise = 0.02;
    scene.supersampling = 4;
    let (frame, _) = raster::render(&scene);
    let png = frame.to_png();
    let config = TrackConfig::new(&layout, camera);
    assert!(analyse(&config, &frame).outcome.is_ok());
    // One frame's analysis runs on the calling thread alone.
    c.bench_function("track: detect + identify + pose, 1280x720, 7 blobs", |b| {
        b.iter(|| analyse(&config, std::hint::black_box(&frame)))
    });
    c.bench_function("track: PNG decode, 1280x720 8-bit", |b| {
        b.iter(|| GreyFrame::from_png(std::hint::black_box(&png)).unwrap())
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
