//! `track`'s per-frame cost: detection, identification and pose of a
//! 1280×720 frame of the 7-sphere search winner on its supports, drawn by
//! `render` (retroreflective preset, σ 0.5 px blur, 8-bit with the default
//! sensor noise), on one core. Target: ≤ 5 ms, and ≤ 5 ms for a frame of a
//! raw stream, its read and decode included. Beside it, what one round
//! of `track --refine` adds (no target: it renders the part). Timed in the process's CPU
//! time ([`cpu_time::CpuTime`]), so the figures hold on a shared machine.

mod cpu_time;

#[path = "../tests/it/track/frames.rs"]
#[allow(dead_code)]
mod frames;

use cpu_time::CpuTime;
use criterion::{criterion_group, criterion_main, Criterion};
use layout_opt::camera::Camera;
use layout_opt::scenario::Scenario;
use layout_opt::track::refine::{Refiner, DEFAULT_SUPERSAMPLING};
use layout_opt::track::stream::{FrameSource, RawSource};
use layout_opt::track::{analyse, GreyFrame, TrackConfig};

fn bench(c: &mut Criterion<CpuTime>) {
    // The benches are their own package (benches/Cargo.toml): the
    // repository's layouts are one folder up from its manifest.
    let part = frames::Part::load(
        &std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../layouts/biprism-search.json"),
    );
    let camera = Camera::paper();
    // The first view at 500 mm, within ±20° of head on, with no sphere
    // hidden.
    let pose = (-4..=4)
        .flat_map(|t| (-4..=4).map(move |p| (5.0 * t as f64, 5.0 * p as f64)))
        .map(|(tilt_deg, pan_deg)| {
            Scenario {
                index: 0,
                depth_mm: 500.0,
                offset_x_mm: (0.5 * camera.width() as f64 - camera.cx()) / camera.fx() * 500.0,
                offset_y_mm: (0.5 * camera.height() as f64 - camera.cy()) / camera.fy() * 500.0,
                tilt_deg,
                pan_deg,
                roll_deg: 20.0,
                sigma_px: 0.5,
            }
            .pose()
        })
        .find(|pose| {
            frames::clean_view(
                &part.truth_over(&camera, pose, layout_opt::render::truth::SILHOUETTE_RAYS),
                &camera,
            )
        })
        .expect("a clean view");
    let frame = part.render(&frames::noisy(camera, 4), &pose).expose(1, 0);
    let png = frame.to_png();
    let config = TrackConfig::new(&part.layout, camera);
    let analysis = analyse(&config, &frame);
    let tracked = analysis.outcome.as_ref().unwrap();
    assert_eq!(tracked.labels.iter().flatten().count(), 7);
    // One frame's analysis runs on the calling thread alone.
    c.bench_function("track: detect + identify + pose, 1280x720, 7 blobs", |b| {
        b.iter(|| analyse(&config, std::hint::black_box(&frame)))
    });
    // `track --refine`'s extra cost: one round, its render at the default
    // 8×8 supersampling, on the same frame.
    let refiner = Refiner::new(
        part.scene.clone(),
        frames::noise_free(camera, DEFAULT_SUPERSAMPLING),
        1,
    )
    .unwrap();
    c.bench_function(
        "track --refine: one round (render 8x8, detect, pose)",
        |b| b.iter(|| refiner.refine(&config, &frame, std::hint::black_box(analysis.clone()))),
    );
    // `track --refine`'s default: the frame's levels fitted first, over
    // three renders (the sphere, the supports and the background alone).
    let fitted = refiner.clone().with_fitted_levels(true);
    c.bench_function(
        "track --refine: one round with the levels fitted (one three-channel render 8x8, detect, pose)",
        |b| b.iter(|| fitted.refine(&config, &frame, std::hint::black_box(analysis.clone()))),
    );
    c.bench_function("track: PNG decode, 1280x720 8-bit", |b| {
        b.iter(|| GreyFrame::from_png(std::hint::black_box(&png)).unwrap())
    });
    // `track LAYOUT - --raw 1280x720`: a frame read from a stream of raw
    // 8-bit frames, made a grey frame and tracked. Target: ≤ 5 ms.
    let raw: Vec<u8> = frame.pixels().iter().map(|&v| v as u8).collect();
    let mut source = RawSource::new(
        Endless { bytes: &raw, at: 0 },
        "1280x720".parse().unwrap(),
        None,
    );
    c.bench_function(
        "track: raw stream frame, read + decode + detect + pose, 1280x720 8-bit",
        |b| {
            b.iter(|| {
                let next = source.next_frame().unwrap().unwrap();
                analyse(&config, &next.frame.unwrap())
            })
        },
    );
}

/// A stream that repeats one frame's bytes without end.
struct Endless<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl std::io::Read for Endless<'_> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = buf.len().min(self.bytes.len() - self.at);
        buf[..n].copy_from_slice(&self.bytes[self.at..self.at + n]);
        self.at = (self.at + n) % self.bytes.len();
        Ok(n)
    }
}

criterion_group! {
    name = benches;
    config = Criterion::default().with_measurement(CpuTime);
    targets = bench
}
criterion_main!(benches);
