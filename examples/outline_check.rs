//! The share of each sphere's outline that the printed part's supports
//! hide, three ways, on the search winner over the paper's protocol grid:
//! the visibility model's area fraction, its outline fraction
//! (`visibility::outline`), and the render's ground truth (rays around the
//! silhouette cast on the rendered scene). Prints, per tilt, the visible
//! scenarios, how many sphere views each measure puts at ≥ 1% and ≥ 10%,
//! and the outline model's agreement with the truth.
//!
//! `cargo run --release --features examples --example outline_check [LAYOUT] [INSET_PX]`

use layout_opt::camera::Camera;
use layout_opt::layout::Layout;
use layout_opt::mesh::{marker_for_range, MarkerOptions};
use layout_opt::render::{frame_truth, Scene};
use layout_opt::scenario::{sphere_images, visibility, ScenarioGrid};
use layout_opt::visibility::outline::{outline_hidden_by_supports, OUTLINE_INSET_PX};
use layout_opt::visibility::{support_fractions, MaxHidden, Supports, WorkingRange};
use rayon::prelude::*;
use std::collections::BTreeMap;

fn main() {
    let path = std::env::args()
        .nth(1)
        .unwrap_or_else(|| "layouts/biprism-search.json".to_string());
    let inset_px: f64 = std::env::args()
        .nth(2)
        .map_or(OUTLINE_INSET_PX, |a| a.parse().expect("an inset in px"));
    let layout = Layout::load(std::path::Path::new(&path)).expect("a layout file");
    let camera = Camera::paper();
    let scenarios = ScenarioGrid::paper_protocol(10.0).scenarios();
    let range = WorkingRange {
        camera,
        scenarios: scenarios.clone(),
        max_hidden: MaxHidden::default(),
    };
    let marker = marker_for_range(&layout, &MarkerOptions::default(), &range).expect("a part");
    let supports = Supports::new(marker.occluders());
    let scene = Scene::from_marker(marker);
    let names: Vec<String> = layout.points.iter().map(|p| p.name.clone()).collect();
    let centres = layout.positions();
    let radius = layout.sphere_radius_mm();
    // Per visible scenario and sphere: its tilt, and the three measures.
    let rows: Vec<(i64, [f64; 3])> = scenarios
        .par_iter()
        .filter(|s| {
            visibility(
                &sphere_images(&camera, &s.pose(), &centres, layout.sphere_diameter_mm),
                &camera,
            )
            .is_visible()
        })
        .flat_map_iter(|s| {
            let pose = s.pose();
            let area = support_fractions(&camera, &pose, &centres, radius, &supports);
            let outline =
                outline_hidden_by_supports(&camera, &pose, &centres, radius, &supports, inset_px);
            let truth = frame_truth(&scene, &names, &pose, &camera).expect("a truth");
            let tilt = s.tilt_deg.round() as i64;
            (0..centres.len())
                .map(|k| {
                    (
                        tilt,
                        [
                            area[k],
                            outline[k].unwrap_or(0.0),
                            truth.spheres[k].hidden.by_support,
                        ],
                    )
                })
                .collect::<Vec<_>>()
        })
        .collect();
    let mut by_tilt: BTreeMap<i64, Vec<[f64; 3]>> = BTreeMap::new();
    for (tilt, values) in rows {
        by_tilt.entry(tilt).or_default().push(values);
    }
    println!("{path}: paper's protocol grid, visible scenarios, sphere views hidden by supports (area model | outline model {inset_px} px inside the limb | render truth, outline)");
    println!("tilt  views  ≥1%: area outline truth  ≥10%: area outline truth  outline−truth: mean |d|  max |d|");
    for (tilt, views) in &by_tilt {
        let count = |m: usize, at: f64| views.iter().filter(|v| v[m] >= at).count();
        let d: Vec<f64> = views.iter().map(|v| (v[1] - v[2]).abs()).collect();
        println!(
            "{tilt:>4} {:>6}  {:>9} {:>7} {:>5}  {:>10} {:>7} {:>5}  {:>22.4} {:>8.3}",
            views.len(),
            count(0, 0.01),
            count(1, 0.01),
            count(2, 0.01),
            count(0, 0.10),
            count(1, 0.10),
            count(2, 0.10),
            d.iter().sum::<f64>() / d.len() as f64,
            d.iter().fold(0.0f64, |a, &b| a.max(b)),
        );
    }
}
