//! `characterise`'s own cost beyond reading the frames: the bundle
//! adjustment, frame checks, gauge, covariance and summary for 40 frames
//! of the 7-sphere search winner, seen from tilts and pans over ±40° at
//! 450–550 mm with 0.02 px of centre noise, started from the nominal
//! layout while the part is displaced by 0.1–0.3 mm per coordinate.
//! Target: ≤ 2 s on 2 cores. Timed in the process's CPU time
//! ([`cpu_time::CpuTime`]).

mod cpu_time;

use cpu_time::CpuTime;
use criterion::{criterion_group, criterion_main, Criterion};
use layout_opt::camera::Camera;
use layout_opt::characterise::{characterise, CharacteriseConfig, FrameCentres};
use layout_opt::layout::Layout;
use layout_opt::pose::Pose;
use nalgebra::{Rotation3, Vector2, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;

fn bench(c: &mut Criterion<CpuTime>) {
    let nominal = Layout::load(
        &std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../layouts/biprism-search.json"),
    )
    .unwrap();
    let camera = Camera::paper();
    let mut rng = ChaCha8Rng::seed_from_u64(40);
    let printed: Vec<Vector3<f64>> = nominal
        .positions()
        .iter()
        .map(|x| {
            x + Vector3::from_fn(|_, _| {
                rng.random_range(0.1..0.3) * if rng.random::<bool>() { 1.0 } else { -1.0 }
            })
        })
        .collect();
    let sigma = 0.02 / camera.fx();
    let frames: Vec<FrameCentres> = (0..40)
        .map(|k| {
            let (tilt, pan) = (
                (k % 5) as f64 * 20.0 - 40.0,
                ((k / 5) % 5) as f64 * 20.0 - 40.0,
            );
            let depth = if k < 25 { 450.0 } else { 550.0 };
            let rotation = Rotation3::from_euler_angles(tilt.to_radians(), pan.to_radians(), 0.0);
            let truth = Pose::new(rotation, Vector3::new(0.0, 0.0, depth));
            let centres = printed
                .iter()
                .enumerate()
                .map(|(i, x)| {
                    let noise =
                        Vector2::new(rng.sample(StandardNormal), rng.sample(StandardNormal));
                    (i, truth.project_normalised(x) + noise * sigma)
                })
                .collect();
            FrameCentres {
                name: format!("frame-{k:02}"),
                pose: truth,
                centres,
            }
        })
        .collect();
    let config = CharacteriseConfig::new(nominal, camera);
    characterise(&config, &frames).unwrap();
    c.bench_function(
        "characterise: 40 frames x 7 spheres (adjust, gauge, covariance)",
        |b| b.iter(|| characterise(&config, std::hint::black_box(&frames)).unwrap()),
    );
}

criterion_group! {
    name = benches;
    config = Criterion::default().with_measurement(CpuTime);
    targets = bench
}
criterion_main!(benches);
