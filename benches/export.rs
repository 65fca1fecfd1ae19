//! Export speed on the paper's biprism (7 spheres) at the default
//! resolution: design + meshing + checks, each writer on a built solid, and
//! the whole `export` (all four formats and the fabrication sheet).
//!
//! Run with `cargo bench --bench export`; criterion reports the median.

use criterion::{criterion_group, criterion_main, Criterion};
use layout_opt::layout::Layout;
use layout_opt::mesh::workflow::{export, writer};
use layout_opt::mesh::{build, ExportOptions, Format};
use std::time::Duration;

fn bench_export(c: &mut Criterion) {
    let layout = Layout::paper_biprism();
    let options = ExportOptions::default();
    let dir = tempfile::tempdir().expect("a temporary directory");

    let mut group = c.benchmark_group("export");
    group.sample_size(10);
    group.measurement_time(Duration::from_secs(20));
    group.bench_function("build (design + mesh + checks)", |b| {
        b.iter(|| build(&layout, &options).expect("the biprism builds"))
    });
    let solid = build(&layout, &options).expect("the biprism builds");
    for &format in Format::ALL {
        group.bench_function(format!("write {format}"), |b| {
            b.iter(|| writer(format).write(&solid, dir.path()).expect("writes"))
        });
    }
    group.bench_function("export all formats + sheet", |b| {
        b.iter(|| export(&layout, &options, dir.path()).expect("exports"))
    });
    group.finish();
}

criterion_group!(benches, bench_export);
criterion_main!(benches);
