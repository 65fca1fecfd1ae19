//! Unlabelled identification benchmark: median time of one
//! `pnp::unlabelled::identify` call (shuffled blobs, σ = 0.5 px, paper
//! camera, depth 200–1000 mm) for random noncoplanar sets with n = 4, 7,
//! 12, 16, and the P3P hypotheses each tried. The % of correct labellings
//! is printed before the timings.
//!
//! Run: `cargo bench --bench unlabelled` (target: ≤ 1 ms for n = 7 on one
//! core).

use criterion::{black_box, criterion_group, criterion_main, BenchmarkId, Criterion};
use layout_opt::camera::Camera;
use layout_opt::pnp::unlabelled::{identify, UnlabelledOptions};
use layout_opt::pnp::Solver;
use layout_opt::pose::reprojection_rms_normalised;
use layout_opt::synthetic::{project_with_noise, random_points, random_pose, stream_rng};
use nalgebra::Vector2;
use rand::seq::SliceRandom;
use std::time::Duration;

const PROBLEMS: usize = 32;
const SIGMA_PX: f64 = 0.5;

/// Shuffled noisy blobs with their true labels.
struct Shuffled {
    object: Vec<nalgebra::Vector3<f64>>,
    image: Vec<Vector2<f64>>,
    labels: Vec<usize>,
}

fn problems(n: usize) -> Vec<Shuffled> {
    let camera = Camera::paper();
    let mut out = Vec::with_capacity(PROBLEMS);
    let mut case = 0;
    while out.len() < PROBLEMS {
        let mut rng = stream_rng(23, n as u64, case);
        case += 1;
        let object = random_points(&mut rng, n, 100.0);
        let depth = 200.0 + 800.0 * (case % 5) as f64 / 4.0;
        let truth = random_pose(&mut rng, depth, 0.2);
        if object.iter().any(|p| truth.transform(p).z < 50.0) {
            continue;
        }
        let Some(problem) = project_with_noise(&mut rng, &camera, object, truth, SIGMA_PX) else {
            continue;
        };
        let mut labels: Vec<usize> = (0..n).collect();
        labels.shuffle(&mut rng);
        let image = labels.iter().map(|&k| problem.normalised[k]).collect();
        out.push(Shuffled {
            object: problem.object,
            image,
            labels,
        });
    }
    out
}

fn bench(c: &mut Criterion) {
    let options = UnlabelledOptions::default();
    let mut group = c.benchmark_group("unlabelled");
    group
        .measurement_time(Duration::from_secs(3))
        .warm_up_time(Duration::from_secs(1))
        .sample_size(20);
    for n in [4, 7, 12, 16] {
        let set = problems(n);
        let (mut correct, mut outfit, mut failed, mut hypotheses) = (0, 0, 0, 0);
        for p in &set {
            let Ok(found) = identify(&p.object, &p.image, &options) else {
                failed += 1;
                continue;
            };
            {
                hypotheses += found.hypotheses;
                if found.best.labels == p.labels {
                    correct += 1;
                } else {
                    // A wrong labelling that fits better than the true one
                    // (refined alike) is the noise's doing, not a miss.
                    let truth: Vec<_> = p.labels.iter().map(|&k| p.object[k]).collect();
                    if let Ok(pose) = Solver::Ml.solve_best(&truth, &p.image) {
                        if found.best.rms <= reprojection_rms_normalised(&pose, &truth, &p.image) {
                            outfit += 1;
                        }
                    }
                }
            }
        }
        println!(
            "unlabelled n = {n}: {:.1}% correct labels ({outfit} wrong ones fit better than the truth, {failed} errors), {:.0} P3P hypotheses per problem",
            100.0 * correct as f64 / set.len() as f64,
            hypotheses as f64 / set.len() as f64
        );
        group.bench_with_input(BenchmarkId::new("identify", n), &set, |b, set| {
            let mut index = 0;
            b.iter(|| {
                let p = &set[index % set.len()];
                index += 1;
                black_box(identify(
                    black_box(&p.object),
                    black_box(&p.image),
                    &options,
                ))
                .ok()
            })
        });
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
