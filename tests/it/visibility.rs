//! The visibility model's supports against the part that `export` writes:
//! the analytic hidden fraction agrees with a ray cast of the exported
//! mesh (OBJ read back with `tobj`); a support that cannot clear the
//! working range loses exactly the views it hides a sphere in; the
//! fractions do not depend on the thread count.

use crate::export_common::read_obj;
use layout_opt::camera::Camera;
use layout_opt::layout::Layout;
use layout_opt::mesh::workflow::export;
use layout_opt::mesh::{
    straight_supports, supports_for_range, ExportOptions, Format, Marker, MarkerOptions,
};
use layout_opt::scenario::{sphere_images, visibility, Range, Scenario, ScenarioGrid};
use layout_opt::search::{Evaluator, SearchConfig};
use layout_opt::visibility::{
    hidden_fractions, silhouette_directions, spheres_hidden_by_supports, support_fractions,
    EyeCone, MaxHidden, Supports, WorkingRange,
};
use nalgebra::Vector3;
use rayon::prelude::*;

/// Möller–Trumbore: the distance along the ray to the triangle.
fn ray_triangle(
    origin: &Vector3<f64>,
    direction: &Vector3<f64>,
    t: &[Vector3<f64>; 3],
) -> Option<f64> {
    let e1 = t[1] - t[0];
    let e2 = t[2] - t[0];
    let p = direction.cross(&e2);
    let det = e1.dot(&p);
    if det.abs() < 1e-14 {
        return None;
    }
    let s = origin - t[0];
    let u = s.dot(&p) / det;
    let q = s.cross(&e1);
    let v = direction.dot(&q) / det;
    if u < 0.0 || v < 0.0 || u + v > 1.0 {
        return None;
    }
    Some(e2.dot(&q) / det).filter(|d| *d > 0.0)
}

/// The fraction of sphere `k`'s silhouette lines whose first triangle lies
/// well before the sphere and on no sphere: hidden by a support.
fn mesh_support_fraction(
    triangles: &[[Vector3<f64>; 3]],
    scenario: &Scenario,
    centres: &[Vector3<f64>],
    radius: f64,
    k: usize,
) -> f64 {
    let pose = scenario.pose();
    let eye = -(pose.rotation.matrix().transpose() * pose.translation);
    let directions: Vec<_> = silhouette_directions(&eye, &centres[k], radius).collect();
    let tolerance = layout_opt::visibility::SURFACE_TOLERANCE_MM;
    // Only triangles inside the cone from the eye round the sphere can
    // meet one of its sight lines: each triangle's bounding ball, seen
    // from the eye, against the cone's half-angle.
    let axis = (centres[k] - eye).normalize();
    let cone = (radius / (centres[k] - eye).norm()).asin();
    let triangles: Vec<&[Vector3<f64>; 3]> = triangles
        .iter()
        .filter(|t| {
            let middle = (t[0] + t[1] + t[2]) / 3.0;
            let reach = t.iter().map(|v| (v - middle).norm()).fold(0.0, f64::max);
            let to = middle - eye;
            let distance = to.norm();
            distance <= reach
                || (to.dot(&axis) / distance).clamp(-1.0, 1.0).acos()
                    <= cone + (reach / distance).asin() + 1e-6
        })
        .collect();
    let hidden = directions
        .iter()
        .filter(|d| {
            let oc = eye - centres[k];
            let b = oc.dot(d);
            let t_sphere = -b
                - (b * b - oc.norm_squared() + radius * radius)
                    .max(0.0)
                    .sqrt();
            let nearest = triangles
                .iter()
                .filter_map(|t| ray_triangle(&eye, d, t))
                .fold(f64::INFINITY, f64::min);
            let hit = eye + *d * nearest;
            nearest < t_sphere - tolerance
                && centres
                    .iter()
                    .all(|c| (hit - c).norm() > radius + tolerance)
        })
        .count();
    hidden as f64 / directions.len() as f64
}

fn grid(depth: &str, tilt: &str, pan: &str) -> Vec<Scenario> {
    ScenarioGrid::new(
        depth.parse().unwrap(),
        Range::single(0.0),
        Range::single(0.0),
        tilt.parse().unwrap(),
        pan.parse().unwrap(),
        Range::single(0.0),
        Range::single(0.5),
    )
    .unwrap()
    .scenarios()
}

#[test]
fn analytic_support_fraction_agrees_with_a_ray_cast_of_the_exported_mesh() {
    let layout = Layout::paper_biprism();
    let dir = tempfile::tempdir().unwrap();
    let options = ExportOptions {
        formats: vec![Format::Obj],
        allow_occlusion: true,
        ..Default::default()
    };
    let report = export(&layout, &options, dir.path()).unwrap();
    let mesh = read_obj(&dir.path().join(format!("{}.obj", report.name)));
    let triangles: Vec<[Vector3<f64>; 3]> = mesh
        .triangles
        .iter()
        .map(|t| t.map(|i| mesh.positions[i]))
        .collect();
    let marker = Marker::design(&layout, &MarkerOptions::default()).unwrap();
    let supports = Supports::new(marker.occluders());
    let camera = Camera::paper();
    let centres = layout.positions();
    let radius = 0.5 * layout.sphere_diameter_mm;
    // Views from above and below, where the pillars of the front spheres
    // pass in front of the spheres behind them.
    let mut compared = 0;
    let mut partly_hidden = 0;
    for scenario in grid("400", "-60..60:15", "-20,0,20") {
        let pose = scenario.pose();
        let fractions = hidden_fractions(&camera, &pose, &centres, radius, &supports);
        for (k, f) in fractions.iter().enumerate() {
            let Some(f) = f else { continue };
            if f.sphere > 0.0 || f.outside > 0.0 {
                continue;
            }
            // Every sphere a pillar hides, and every tenth of the others.
            if f.support == 0.0 && (scenario.index + k) % 10 != 0 {
                continue;
            }
            let measured = mesh_support_fraction(&triangles, &scenario, &centres, radius, k);
            assert!(
                (measured - f.support).abs() <= 0.01,
                "{} at tilt {} pan {}: analytic {:.4}, mesh {:.4}",
                layout.points[k].name,
                scenario.tilt_deg,
                scenario.pan_deg,
                f.support,
                measured
            );
            compared += 1;
            partly_hidden += usize::from(f.support > 0.02 && f.support < 0.98);
        }
    }
    assert!(partly_hidden >= 3, "{partly_hidden} partly hidden spheres");
    assert!(compared >= 20, "{compared} compared");
}

#[test]
fn a_support_that_cannot_clear_the_range_loses_exactly_those_views() {
    let layout = Layout::paper_biprism();
    let range = WorkingRange {
        camera: Camera::paper(),
        scenarios: grid("300", "-80..80:10", "-60..60:30"),
        max_hidden: MaxHidden::default(),
    };
    let centres = layout.positions();
    let options = MarkerOptions {
        working_views: range.clear_views(&centres, layout.sphere_diameter_mm),
        ..Default::default()
    };
    let marker = Marker::design(&layout, &options).unwrap();
    let supports = Supports::new(marker.occluders());
    let lost = range.lost_views(&centres, layout.sphere_diameter_mm, &supports);
    assert!(!lost.is_empty(), "this range is too wide to clear");
    let visible: Vec<usize> = range
        .scenarios
        .iter()
        .filter(|s| {
            let images = layout_opt::scenario::sphere_images(
                &range.camera,
                &s.pose(),
                &centres,
                layout.sphere_diameter_mm,
            );
            layout_opt::scenario::visibility(&images, &range.camera).is_visible()
        })
        .map(|s| s.index)
        .collect();
    for scenario in &range.scenarios {
        let fractions = hidden_fractions(
            &range.camera,
            &scenario.pose(),
            &centres,
            0.5 * layout.sphere_diameter_mm,
            &supports,
        );
        for (k, f) in fractions.iter().enumerate() {
            let hidden = f.is_some_and(|f| f.support > 0.01) && visible.contains(&scenario.index);
            let reported = lost
                .iter()
                .any(|l| l.scenario.index == scenario.index && l.sphere == k);
            assert_eq!(hidden, reported, "scenario {} sphere {k}", scenario.index);
        }
    }
    // Not every view is lost.
    let lost_scenarios: std::collections::BTreeSet<usize> =
        lost.iter().map(|l| l.scenario.index).collect();
    assert!(
        lost_scenarios.len() < visible.len(),
        "{} of {}",
        lost_scenarios.len(),
        visible.len()
    );
}

#[test]
fn hidden_fractions_do_not_depend_on_the_thread_count() {
    let layout = Layout::paper_biprism();
    let marker = Marker::design(&layout, &MarkerOptions::default()).unwrap();
    let supports = Supports::new(marker.occluders());
    let camera = Camera::paper();
    let centres = layout.positions();
    let scenarios = grid("400..1000:300", "-60..60:20", "-20,20");
    let run = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| {
                scenarios
                    .par_iter()
                    .map(|s| hidden_fractions(&camera, &s.pose(), &centres, 5.0, &supports))
                    .collect::<Vec<_>>()
            })
    };
    let one = run(1);
    assert_eq!(one, run(3));
    assert!(one
        .iter()
        .flatten()
        .any(|f| f.is_some_and(|f| f.support > 0.0)));
}

/// `validate` with the supports counted, on a range too wide for the
/// paper biprism's supports to clear (as above): exactly the scenarios in
/// which they hide a sphere move from visible to hidden by a support,
/// nothing else changes class, and `--no-supports` (`structure: None`)
/// gives the spheres-alone counts.
#[test]
fn validate_counts_the_scenarios_the_supports_hide() {
    use layout_opt::montecarlo::{MonteCarloConfig, DEFAULT_GROSS_THRESHOLD_DEG};
    use layout_opt::pnp::Solver;
    use layout_opt::validate::{IdentifiabilityCheck, ValidateConfig};
    let layout = Layout::paper_biprism();
    let grid = ScenarioGrid::new(
        "300".parse().unwrap(),
        Range::single(0.0),
        Range::single(0.0),
        "-80..80:10".parse().unwrap(),
        "-60..60:30".parse().unwrap(),
        Range::single(0.0),
        Range::single(0.5),
    )
    .unwrap();
    let range = WorkingRange {
        camera: Camera::paper(),
        scenarios: grid.scenarios(),
        max_hidden: MaxHidden::default(),
    };
    let supports =
        layout_opt::mesh::supports_for_range(&layout, &MarkerOptions::default(), &range).unwrap();
    let lost: std::collections::BTreeSet<usize> = range
        .lost_views(&layout.positions(), layout.sphere_diameter_mm, &supports)
        .iter()
        .map(|l| l.scenario.index)
        .collect();
    assert!(!lost.is_empty());
    let run = |structure: Option<MarkerOptions>| {
        let config = ValidateConfig {
            layout: layout.clone(),
            camera: Camera::paper(),
            volume: layout_opt::volume::WorkingVolume::Grid(grid.clone()),
            monte_carlo: MonteCarloConfig {
                trials: 2,
                seed: 3,
                solvers: vec![Solver::Ml],
                noise: Default::default(),
                gross_threshold_deg: DEFAULT_GROSS_THRESHOLD_DEG,
                observation: Default::default(),
            },
            identifiability: IdentifiabilityCheck {
                trials: 0,
                ..Default::default()
            },
            fabrication_sigma_mm: 0.0,
            camera_sigma: Default::default(),
            structure,
            max_hidden: 0.01,
            command: String::new(),
        };
        layout_opt::validate::analysis::analyse(&config, &mut layout_opt::observer::Silent).unwrap()
    };
    let with = run(Some(MarkerOptions::default()));
    let without = run(None);
    let (v, w) = (&with.overview.visibility, &without.overview.visibility);
    assert_eq!(w.hidden_by_support, 0);
    assert_eq!(v.hidden_by_support, lost.len(), "{v:?}");
    for outcome in &with.outcomes {
        assert_eq!(
            !outcome.visibility.hidden_by_support.is_empty(),
            lost.contains(&outcome.scenario.index)
        );
    }
    assert_eq!(v.visible + v.hidden_by_support, w.visible);
    assert_eq!(
        (v.occluded, v.outside_image, v.behind_camera),
        (w.occluded, w.outside_image, w.behind_camera)
    );
    // A scenario hidden by a support is left out of identifiability as an
    // occluded one is.
    for (outcome, identified) in with.outcomes.iter().zip(&with.identifiability) {
        if !outcome.visibility.hidden_by_support.is_empty() {
            assert!(identified.is_none(), "{:?}", outcome.scenario);
        }
    }
}

/// A `--max-hidden` outside 0–1 is refused by `validate`, `export` and
/// `search` before any work, naming the flag, and nothing is written.
#[test]
fn a_bad_max_hidden_is_refused_before_any_work() {
    for bad in ["1.5", "NaN", "-0.1"] {
        for command in ["validate", "export", "search"] {
            let dir = tempfile::tempdir().unwrap();
            let max_hidden = format!("--max-hidden={bad}");
            let args: Vec<&str> = match command {
                "validate" => vec!["validate", "--trials", "1", &max_hidden],
                "export" => vec!["export", "--depth", "600", &max_hidden],
                _ => vec!["search", "--iterations", "10", &max_hidden],
            };
            let out = match command {
                "search" => dir.path().join("w.json"),
                _ => dir.path().to_path_buf(),
            };
            let output = assert_cmd::Command::cargo_bin("layout-opt")
                .unwrap()
                .args(args)
                .arg("--out")
                .arg(out)
                .output()
                .unwrap();
            let stderr = String::from_utf8_lossy(&output.stderr);
            assert!(!output.status.success(), "{command} {bad}");
            assert!(
                stderr.contains("max-hidden") && stderr.contains("from 0 to 1"),
                "{command} --max-hidden {bad}: {stderr}"
            );
            assert_eq!(
                std::fs::read_dir(dir.path()).unwrap().count(),
                0,
                "{command} --max-hidden {bad} wrote something"
            );
        }
    }
}

/// `export` without range flags routes the supports for the search's grid
/// recorded in the layout's provenance, and without such a record builds
/// for the view cone as before.
#[test]
fn export_defaults_to_the_searched_range_in_the_provenance() {
    let dir = tempfile::tempdir().unwrap();
    let shipped =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("layouts/biprism-paper.json");
    let mut file: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(shipped).unwrap()).unwrap();
    file["name"] = "searched".into();
    file["provenance"] = serde_json::json!({"range": {
        "depth": [400.0, 700.0], "offset-x": [0.0, 50.0], "offset-y": [0.0],
        "tilt": [-20.0, 0.0, 20.0], "pan": [0.0], "roll": [0.0], "noise": [0.5]}});
    let searched = dir.path().join("searched.json");
    std::fs::write(&searched, file.to_string()).unwrap();
    let export = |layout: &std::path::Path, out: &str| {
        let out = dir.path().join(out);
        assert_cmd::Command::cargo_bin("layout-opt")
            .unwrap()
            .args(["--quiet", "export", "--format", "stl", "--out"])
            .arg(&out)
            .arg(layout)
            .assert()
            .success();
        let name = layout.file_stem().unwrap().to_string_lossy().to_string();
        let summary = std::fs::read_to_string(out.join(format!("{name}-export.json"))).unwrap();
        serde_json::from_str::<serde_json::Value>(&summary).unwrap()["working_range_scenarios"]
            .clone()
    };
    assert_eq!(export(&searched, "a"), serde_json::json!(12));
    file["provenance"] = serde_json::json!({"seed": 7});
    let plain = dir.path().join("plain.json");
    file["name"] = "plain".into();
    std::fs::write(&plain, file.to_string()).unwrap();
    let scenarios = export(&plain, "b");
    assert!(
        scenarios.is_null() || scenarios == serde_json::json!(0),
        "{scenarios}"
    );
}

#[test]
fn the_culled_support_fractions_equal_the_full_model_in_visible_scenarios() {
    let layout = Layout::paper_biprism();
    let camera = Camera::paper();
    let centres = layout.positions();
    let radius = 0.5 * layout.sphere_diameter_mm;
    let scenarios = grid("400,800", "-60..60:20", "-20,20");
    let range = WorkingRange {
        camera,
        scenarios: scenarios.clone(),
        max_hidden: MaxHidden::default(),
    };
    let options = MarkerOptions::default();
    let routed = supports_for_range(&layout, &options, &range).unwrap();
    let straight = straight_supports(&centres, layout.sphere_diameter_mm, &options);
    // The search's decision, from the supports screened once against the
    // grid's eyes and sight lines followed until it is known.
    let eyes = EyeCone::of(&scenarios).unwrap();
    let screens = [&routed, &straight].map(|s| eyes.screen(&centres, radius, s));
    let pairs = centres.len() * straight.occluders().len();
    let screened: usize = screens[1].iter().map(Vec::len).sum();
    assert!(screened < pairs, "{screened} of {pairs}");
    let (mut compared, mut hidden) = (0, 0);
    for scenario in &scenarios {
        let pose = scenario.pose();
        let images = sphere_images(&camera, &pose, &centres, layout.sphere_diameter_mm);
        if !visibility(&images, &camera).is_visible() {
            continue;
        }
        for (supports, screen) in [&routed, &straight].into_iter().zip(&screens) {
            let full = hidden_fractions(&camera, &pose, &centres, radius, supports);
            let fast = support_fractions(&camera, &pose, &centres, radius, supports);
            for (f, s) in full.iter().zip(&fast) {
                assert_eq!(f.expect("in front").support, *s, "{scenario:?}");
                compared += 1;
                hidden += usize::from(*s > 0.0);
            }
            for max_hidden in [0.0, 0.01, 0.1] {
                let max_hidden = MaxHidden::new(max_hidden).unwrap();
                let decided: Vec<usize> = spheres_hidden_by_supports(
                    &camera, &pose, &centres, radius, supports, screen, max_hidden,
                )
                .collect();
                let expected: Vec<usize> = (0..centres.len())
                    .filter(|&k| fast[k] > max_hidden.fraction())
                    .collect();
                assert_eq!(decided, expected, "{scenario:?}");
            }
        }
    }
    assert!(compared > 0 && hidden > 0, "{compared} {hidden}");
}

#[test]
fn the_search_can_price_each_candidate_with_its_own_supports() {
    let config = SearchConfig::new("t", &std::env::temp_dir());
    let paper = Layout::paper_biprism();
    let (points, sigmas) = (paper.positions(), paper.point_sigmas());
    let plain = Evaluator::new(
        config.camera,
        grid("400,800", "-60..60:20", "0"),
        config.objective.clone(),
        config.constraints,
        &points,
    );
    let counted =
        plain.with_candidate_supports(MarkerOptions::default(), MaxHidden::default(), &points);
    assert!(counted.counts_candidate_supports());
    let (a, b) = (
        plain.evaluate(&points, &sigmas),
        counted.evaluate(&points, &sigmas),
    );
    // The link from the front sphere onto the hub hides the hub when the
    // marker tilts; accuracy is pooled over the scenarios in front either way.
    assert!(
        b.availability < a.availability,
        "{} {}",
        b.availability,
        a.availability
    );
    assert_eq!(b.accuracy, a.accuracy);
    assert_eq!(counted.reference_availability(), b.availability);
    assert!(counted.reference_availability() < plain.reference_availability());
    // Counting nothing as lost gives back the spheres-alone figures.
    let lenient = plain.with_candidate_supports(
        MarkerOptions::default(),
        MaxHidden::new(1.0).unwrap(),
        &points,
    );
    assert_eq!(
        lenient.evaluate(&points, &sigmas).availability,
        a.availability
    );
    assert_eq!(
        counted.without_supports(&points).reference_availability(),
        plain.reference_availability()
    );
}
