//! The default search, end to end: `layout-opt search --depth 200..1000`
//! exactly as the README runs it (8 starts of Nelder–Mead on the first-order
//! objective, the Monte-Carlo comparison of the winner with the hand designs
//! on two seeds, and the winner's sensitivity report), on every core. The
//! outputs go to a temporary directory instead of `layouts/` and `reports/`.
//!
//! Run with `cargo bench --bench search`; criterion reports the median wall
//! time of the whole command over ten runs (about 11 s each).

use criterion::{criterion_group, criterion_main, Criterion, SamplingMode};
use std::process::Command;
use std::time::Duration;

fn bench_default_search(c: &mut Criterion) {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let run = || {
        let status = Command::new(env!("CARGO_BIN_EXE_layout-opt"))
            .args(["search", "--depth", "200..1000", "--quiet"])
            .arg("--out")
            .arg(dir.path().join("biprism-search.json"))
            .arg("--report")
            .arg(dir.path().join("report"))
            .arg("--checkpoint-dir")
            .arg(dir.path().join("checkpoints"))
            .status()
            .expect("layout-opt runs");
        assert!(status.success(), "the default search failed");
    };
    let mut group = c.benchmark_group("search");
    // One run per sample: ten runs in all.
    group.sampling_mode(SamplingMode::Flat);
    group.sample_size(10);
    group.warm_up_time(Duration::from_secs(1));
    group.measurement_time(Duration::from_secs(100));
    group.bench_function("default (search --depth 200..1000)", |b| b.iter(run));
    group.finish();
}

criterion_group!(benches, bench_default_search);
criterion_main!(benches);
