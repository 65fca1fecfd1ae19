//! What counting each candidate's own supports costs the search: one
//! evaluation of the objective ([`Evaluator::evaluate`]) with the spheres
//! alone, and with every candidate's supports as occluders
//! ([`Evaluator::with_candidate_supports`], default options, 1% hidden
//! allowed), for the committed search winner and the paper's biprism, on
//! the default search grid (depth 200..1000:200 mm, offset-x 0..100:25 mm,
//! tilt −60..60:10°: 325 scenarios).
//!
//! `cargo bench --bench supports`
//!
//! Each evaluation runs on a pool of one thread and is timed in the
//! process's CPU time ([`cpu_time::CpuTime`]); the ratio of the medians is
//! the cost of counting supports on one core.

mod cpu_time;

use cpu_time::CpuTime;
use criterion::{criterion_group, criterion_main, Criterion};
use layout_opt::layout::Layout;
use layout_opt::mesh::MarkerOptions;
use layout_opt::scenario::{Range, ScenarioGrid};
use layout_opt::search::{Evaluator, SearchConfig};
use layout_opt::visibility::MaxHidden;
use std::hint::black_box;

fn bench(c: &mut Criterion<CpuTime>) {
    let range = |text: &str| text.parse::<Range>().expect("a valid range");
    let grid = ScenarioGrid::new(
        range("200..1000:200"),
        range("0..100:25"),
        range("0"),
        range("-60..60:10"),
        range("0"),
        range("0"),
        range("0.5"),
    )
    .expect("a valid grid");
    let config = SearchConfig::new("supports", &std::env::temp_dir());
    let paper = Layout::paper_biprism();
    let plain = Evaluator::new(
        config.camera,
        grid.scenarios(),
        config.objective.clone(),
        config.constraints,
        &paper.positions(),
    );
    let counted = plain.with_candidate_supports(
        MarkerOptions::default(),
        MaxHidden::default(),
        &paper.positions(),
    );
    // The benches are a package of their own in benches/: the layouts are
    // one folder up.
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../layouts/biprism-search.json");
    let winner = Layout::load(&path).expect("the search winner loads");
    let one_core = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("a pool of one thread");
    for (name, layout) in [("winner", &winner), ("paper biprism", &paper)] {
        let (points, sigmas) = (layout.positions(), layout.point_sigmas());
        for (rule, evaluator) in [("spheres alone", &plain), ("supports counted", &counted)] {
            c.bench_function(&format!("evaluate {name}, {rule}"), |b| {
                b.iter(|| one_core.install(|| evaluator.evaluate(black_box(&points), &sigmas)))
            });
        }
    }
}

criterion_group! {
    name = benches;
    config = Criterion::default().with_measurement(CpuTime).sample_size(30);
    targets = bench
}
criterion_main!(benches);
