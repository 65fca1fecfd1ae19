//! The default search, end to end: `layout-opt search --depth 200..1000`
//! exactly as the README runs it (8 starts of Nelder–Mead on the first-order
//! objective, the Monte-Carlo comparison of the winner with the hand designs
//! on two seeds, and the winner's sensitivity report), on every core. The
//! outputs go to a temporary directory instead of `layouts/` and `reports/`.
//!
//! Run with `cargo build --release && cargo bench --bench search` (the
//! bench runs the binary that build leaves beside it); criterion reports the
//! median wall time of the whole command over ten runs (about 11 s each).
//! The second benchmark adds `--front` (the ε-constraint sweep of the Pareto
//! front); `cargo bench --bench search -- front` runs it alone.

use criterion::{criterion_group, criterion_main, Criterion, SamplingMode};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

/// The `layout-opt` binary of this build. The benches are a package of their
/// own, so Cargo does not build it for them: `cargo build --release` puts it
/// in `target/release/`, and `cargo bench` this bench in
/// `target/release/deps/`.
fn binary() -> PathBuf {
    let bench = std::env::current_exe().expect("the bench knows its own path");
    let path = bench
        .parent()
        .and_then(Path::parent)
        .expect("the bench lies in target/<profile>/deps/")
        .join(format!("layout-opt{}", std::env::consts::EXE_SUFFIX));
    assert!(
        path.is_file(),
        "{} is missing: run `cargo build --release` first",
        path.display()
    );
    path
}

fn search_command(dir: &Path, extra: &[&str]) -> impl Fn() {
    let binary = binary();
    let dir = dir.to_path_buf();
    let extra: Vec<String> = extra.iter().map(|s| s.to_string()).collect();
    move || {
        let status = Command::new(&binary)
            .args(["search", "--depth", "200..1000", "--quiet"])
            .args(&extra)
            .arg("--out")
            .arg(dir.join("biprism-search.json"))
            .arg("--report")
            .arg(dir.join("report"))
            .arg("--checkpoint-dir")
            .arg(dir.join("checkpoints"))
            .status()
            .expect("layout-opt runs");
        assert!(status.success(), "the search failed");
    }
}

fn bench_default_search(c: &mut Criterion) {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let run = search_command(dir.path(), &[]);
    let mut group = c.benchmark_group("search");
    // One run per sample: ten runs in all.
    group.sampling_mode(SamplingMode::Flat);
    group.sample_size(10);
    group.warm_up_time(Duration::from_secs(1));
    group.measurement_time(Duration::from_secs(100));
    group.bench_function("default (search --depth 200..1000)", |b| b.iter(&run));
    group.finish();
}

fn bench_front(c: &mut Criterion) {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let run = search_command(dir.path(), &["--front"]);
    let mut group = c.benchmark_group("search");
    group.sampling_mode(SamplingMode::Flat);
    group.sample_size(10);
    group.warm_up_time(Duration::from_secs(1));
    group.measurement_time(Duration::from_secs(600));
    group.bench_function("front (search --depth 200..1000 --front)", |b| b.iter(&run));
    group.finish();
}

criterion_group!(benches, bench_default_search, bench_front);
criterion_main!(benches);
