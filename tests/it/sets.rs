//! Marker sets (issue #29): the set file and its refusals,
//! cross-identifiability between markers (two copies, mirror images, a set
//! of distinct markers), identification against a set and blob grouping.

use layout_opt::camera::Camera;
use layout_opt::identifiability::{required_margin_px, IdentifiabilitySettings};
use layout_opt::layout::{Layout, LayoutPoint};
use layout_opt::montecarlo::Target;
use layout_opt::noise::NoiseModel;
use layout_opt::pnp::ml;
use layout_opt::pnp::unlabelled::UnlabelledOptions;
use layout_opt::pose::Pose;
use layout_opt::scenario::{Scenario, ScenarioGrid};
use layout_opt::set::{
    cross_matrix, cross_scenario, group_blobs, identify_in_set, set_file_json, set_trials,
    write_set, MarkerSet, SetError,
};
use layout_opt::sphere_image::Observation;
use nalgebra::{Rotation3, Vector2, Vector3};

const DIAMETER_MM: f64 = 8.0;

/// Four asymmetric 7-point markers of about 100 mm, spheres at least 20 mm
/// apart, each a different shape.
fn four_markers() -> Vec<Vec<Vector3<f64>>> {
    vec![
        vec![
            Vector3::new(0.0, 0.0, 0.0),
            Vector3::new(48.0, 6.0, 0.0),
            Vector3::new(-12.0, 40.0, 9.0),
            Vector3::new(18.0, -31.0, 36.0),
            Vector3::new(-38.0, -14.0, -22.0),
            Vector3::new(29.0, 33.0, -27.0),
            Vector3::new(-30.0, 22.0, 30.0),
        ],
        vec![
            Vector3::new(0.0, 0.0, 0.0),
            Vector3::new(-45.0, 0.0, 10.0),
            Vector3::new(5.0, -47.0, -5.0),
            Vector3::new(35.0, 30.0, 20.0),
            Vector3::new(-20.0, 35.0, -35.0),
            Vector3::new(40.0, -20.0, -30.0),
            Vector3::new(10.0, 10.0, 45.0),
        ],
        vec![
            Vector3::new(0.0, 0.0, 0.0),
            Vector3::new(30.0, 0.0, 0.0),
            Vector3::new(-25.0, 28.0, 0.0),
            Vector3::new(0.0, -45.0, 20.0),
            Vector3::new(45.0, 40.0, 25.0),
            Vector3::new(-40.0, -30.0, 35.0),
            Vector3::new(15.0, 20.0, -40.0),
        ],
        vec![
            Vector3::new(0.0, 0.0, 0.0),
            Vector3::new(25.0, -40.0, 0.0),
            Vector3::new(-50.0, 10.0, 5.0),
            Vector3::new(20.0, 45.0, -10.0),
            Vector3::new(-10.0, -25.0, -40.0),
            Vector3::new(45.0, 5.0, 40.0),
            Vector3::new(-25.0, 35.0, 35.0),
        ],
    ]
}

fn layout(name: &str, points: &[Vector3<f64>]) -> Layout {
    Layout {
        name: name.to_string(),
        points: points
            .iter()
            .enumerate()
            .map(|(k, p)| LayoutPoint::new(format!("S{k}"), *p))
            .collect(),
        sphere_diameter_mm: DIAMETER_MM,
        family: None,
        provenance: None,
    }
}

fn settings(trials: usize) -> IdentifiabilitySettings {
    IdentifiabilitySettings {
        min_correct: 0.999,
        trials,
        seed: 29,
        observation: Observation::Centre,
        noise: NoiseModel::default(),
    }
}

fn grid(depths: &str, tilts: &str, pans: &str) -> Vec<Scenario> {
    ScenarioGrid::new(
        depths.parse().unwrap(),
        "0".parse().unwrap(),
        "0".parse().unwrap(),
        tilts.parse().unwrap(),
        pans.parse().unwrap(),
        "0".parse().unwrap(),
        "0.5".parse().unwrap(),
    )
    .unwrap()
    .scenarios()
}

fn targets<'a>(
    camera: &'a Camera,
    objects: &'a [Vec<Vector3<f64>>],
    sigmas: &'a [Option<f64>],
) -> Vec<Target<'a>> {
    objects
        .iter()
        .map(|object| Target {
            camera,
            object,
            sphere_diameter_mm: DIAMETER_MM,
            point_sigma_px: &sigmas[..object.len()],
        })
        .collect()
}

#[test]
fn a_set_file_round_trips_and_bad_sets_are_refused_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let markers = four_markers();
    let layouts: Vec<Layout> = markers[..2]
        .iter()
        .enumerate()
        .map(|(k, m)| layout(&format!("m{k}"), m))
        .collect();
    let path = write_set(dir.path(), "pair", &layouts).unwrap();
    assert_eq!(path, dir.path().join("pair.set.json"));
    let set = MarkerSet::load(&path).unwrap();
    assert_eq!(set.name, "pair");
    assert_eq!(set.names(), ["pair-1", "pair-2"]);
    assert_eq!(set.objects()[1], markers[1]);
    set.check_distinct().unwrap();

    // A missing layout: the error names it.
    let missing = dir.path().join("missing.set.json");
    std::fs::write(
        &missing,
        set_file_json("x", &["pair-1.json".into(), "nowhere.json".into()]),
    )
    .unwrap();
    let error = MarkerSet::load(&missing).unwrap_err();
    assert!(matches!(error, SetError::Layout { .. }), "{error}");
    assert!(error.to_string().contains("nowhere.json"), "{error}");

    // One marker: too few.
    let single = dir.path().join("single.set.json");
    std::fs::write(&single, set_file_json("x", &["pair-1.json".into()])).unwrap();
    let error = MarkerSet::load(&single).unwrap_err().to_string();
    assert!(
        error.contains("lists 1 markers") && error.contains("single.set.json"),
        "{error}"
    );

    // Another format.
    let wrong = dir.path().join("wrong.set.json");
    std::fs::write(
        &wrong,
        r#"{"format": "layout-opt-layout", "version": 1, "name": "x", "markers": ["a.json", "b.json"]}"#,
    )
    .unwrap();
    let error = MarkerSet::load(&wrong).unwrap_err().to_string();
    assert!(
        error.contains("layout-opt-set") && error.contains("wrong.set.json"),
        "{error}"
    );

    // Different sphere diameters.
    let mut big = layout("big", &markers[2]);
    big.sphere_diameter_mm = 12.0;
    big.save_atomic(&dir.path().join("big.json")).unwrap();
    let mixed = dir.path().join("mixed.set.json");
    std::fs::write(
        &mixed,
        set_file_json("x", &["pair-1.json".into(), "big.json".into()]),
    )
    .unwrap();
    let error = MarkerSet::load(&mixed).unwrap_err().to_string();
    assert!(
        error.contains("big.json") && error.contains("12"),
        "{error}"
    );
}

/// Two copies of one marker (the second moved and relabelled): the set is
/// refused by `check_distinct`, and the cross matrix, computed anyway,
/// finds every visible view confusable (0% cross-identifiable, margin 0).
#[test]
fn two_copies_of_one_marker_are_refused_and_zero_percent_cross_identifiable() {
    let dir = tempfile::tempdir().unwrap();
    let original = four_markers().remove(0);
    let motion = Pose::new(
        Rotation3::from_euler_angles(0.3, 0.2, -0.5),
        Vector3::new(4.0, -3.0, 2.0),
    );
    let mut copy: Vec<Vector3<f64>> = original.iter().map(|p| motion.transform(p)).collect();
    copy.rotate_left(2);
    let path = write_set(
        dir.path(),
        "twins",
        &[layout("a", &original), layout("b", &copy)],
    )
    .unwrap();
    let set = MarkerSet::load(&path).unwrap();
    let error = set.check_distinct().unwrap_err().to_string();
    assert!(
        error.contains("twins-1.json")
            && error.contains("twins-2.json")
            && error.contains("same marker"),
        "{error}"
    );

    let camera = Camera::paper();
    let objects = set.objects();
    let sigmas = vec![None; 7];
    let targets = targets(&camera, &objects, &sigmas);
    let scenarios = grid("300,600", "-20,20", "0");
    let matrix = cross_matrix(&targets, &set.names(), &scenarios, &settings(0));
    for pair in &matrix.pairs {
        assert!(pair.visible > 0);
        assert_eq!(pair.cross_identifiable, 0, "{pair:?}");
        assert!(pair.smallest_margin_px.unwrap() < 1e-3, "{pair:?}");
        assert!(pair.worst_confusion > 0.3, "{pair:?}");
    }
    assert_eq!(matrix.worst_share(), 0.0);
    assert!(!matrix.meets_floor());
}

/// A marker and its mirror image (z ↦ −z). Under orthographic projection
/// the mirror explains every view exactly (the Necker reversal); under
/// perspective it departs by the relief over the depth. Independently of
/// the set's search, the mirror is fitted at the Necker pose with the true
/// correspondences: wherever that fit lies within the gate, the cross
/// prediction finds a fit at least as good, and wherever its residual is
/// below the margin the floor needs, the view is counted confusable. Far
/// views are confusable, near ones are not.
#[test]
fn a_mirror_image_is_caught_wherever_it_fits_within_the_gate() {
    let camera = Camera::paper();
    let original = four_markers().remove(1);
    let mirror: Vec<Vector3<f64>> = original
        .iter()
        .map(|p| Vector3::new(p.x, p.y, -p.z))
        .collect();
    let objects = vec![original.clone(), mirror.clone()];
    let sigmas = vec![None; 7];
    let targets = targets(&camera, &objects, &sigmas);
    let settings = settings(0);
    let scenarios = grid("250,1000,2500", "-15,15", "0,20");
    let required = required_margin_px(0.5, settings.max_wrong());
    let focal = camera.fx().min(camera.fy());
    let (mut fits, mut confusable, mut clear) = (0, 0, 0);
    for scenario in &scenarios {
        let Some(prediction) = cross_scenario(&targets[0], &mirror, scenario, &settings) else {
            continue;
        };
        // The Necker pose: rows r1·M, r2·M, their cross product.
        let truth = scenario.pose();
        let r = truth.rotation.matrix();
        let m = nalgebra::Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, -1.0));
        let (r1, r2) = (r.row(0) * m, r.row(1) * m);
        let r3 = r1.cross(&r2);
        let necker = Pose::new(
            Rotation3::from_matrix_unchecked(nalgebra::Matrix3::from_rows(&[r1, r2, r3])),
            truth.translation,
        );
        let image: Vec<Vector2<f64>> = original
            .iter()
            .map(|p| truth.project_normalised(p))
            .collect();
        let fitted = ml::refine(&necker, &mirror, &image);
        let residuals: Vec<f64> = mirror
            .iter()
            .zip(&image)
            .map(|(p, m)| focal * (fitted.project_normalised(p) - m).norm())
            .collect();
        let worst = residuals.iter().copied().fold(0.0, f64::max);
        let norm = residuals.iter().map(|r| r * r).sum::<f64>().sqrt();
        if worst <= prediction.gate_px {
            fits += 1;
            let margin = prediction
                .margin_px
                .unwrap_or_else(|| panic!("scenario {}: the mirror fits within the gate (norm {norm} px) but no margin was found", scenario.index));
            assert!(
                margin <= norm + 1e-6,
                "scenario {}: margin {margin} > {norm}",
                scenario.index
            );
        }
        if norm < required {
            confusable += 1;
            assert!(
                prediction.confusion_probability > settings.max_wrong(),
                "scenario {}: a mirror within {norm} px is not counted confusable: {prediction:?}",
                scenario.index
            );
        }
        if prediction.margin_px.is_none_or(|m| m > 2.0 * required) {
            clear += 1;
        }
    }
    assert!(confusable > 0, "no far view is confusable");
    assert!(clear > 0, "no near view tells the mirror apart");
    assert!(fits >= confusable);
}

/// A set of four distinct markers: the noise-free blobs of every marker in
/// every visible view, shuffled, name the right marker with the right
/// labels; a few seeded noisy trials at σ = 0.5 px never name another
/// marker where the prediction says the pair is cross-identifiable.
#[test]
fn noise_free_views_of_a_four_marker_set_name_the_right_marker_and_labels() {
    let camera = Camera::paper();
    let objects = four_markers();
    let sigmas = vec![None; 7];
    let targets = targets(&camera, &objects, &sigmas);
    let scenarios = grid("300,500", "-30,30", "-30,30");
    let focal = camera.fx().min(camera.fy());
    let options = UnlabelledOptions::with_gate_px(2.5, focal, 1);
    let mut views = 0;
    for (i, object) in objects.iter().enumerate() {
        for scenario in &scenarios {
            let truth = scenario.pose();
            let order: Vec<usize> = (0..object.len())
                .map(|k| (3 * k + i) % object.len())
                .collect();
            let image: Vec<Vector2<f64>> = order
                .iter()
                .map(|&k| truth.project_normalised(&object[k]))
                .collect();
            let found = identify_in_set(&objects, &image, &options).unwrap();
            assert_eq!(found.marker, i, "marker {i} scenario {}", scenario.index);
            assert_eq!(
                found.best.labels, order,
                "marker {i} scenario {}",
                scenario.index
            );
            views += 1;
        }
    }
    assert_eq!(views, 4 * scenarios.len());

    let small = grid("400", "20", "0");
    let settings = settings(3);
    let matrix = cross_matrix(
        &targets,
        &["a".into(), "b".into(), "c".into(), "d".into()],
        &small,
        &settings,
    );
    assert_eq!(matrix.pairs.len(), 12);
    assert!(matrix.meets_floor(), "{matrix:?}");
    let (counts, named) = set_trials(&targets, &small, &settings);
    for (i, c) in counts.iter().enumerate() {
        assert_eq!(c.trials, 3 * small.len(), "{c:?}");
        assert_eq!(c.wrong_marker, 0, "marker {i}: {c:?}");
        assert_eq!(named[i][i], c.trials - c.failed);
    }
}

/// Two markers in one frame: the blobs, mixed and shuffled, are grouped
/// into both markers with the right labels.
#[test]
fn blobs_of_two_markers_in_one_frame_are_grouped_by_the_joint_fit() {
    let objects = four_markers();
    let objects = vec![objects[0].clone(), objects[2].clone()];
    let poses = [
        Pose::new(
            Rotation3::from_euler_angles(0.3, -0.2, 0.1),
            Vector3::new(-90.0, 10.0, 500.0),
        ),
        Pose::new(
            Rotation3::from_euler_angles(-0.2, 0.4, 1.0),
            Vector3::new(80.0, -20.0, 550.0),
        ),
    ];
    let mut blobs: Vec<(usize, usize, Vector2<f64>)> = Vec::new();
    for (marker, (object, pose)) in objects.iter().zip(&poses).enumerate() {
        for (k, p) in object.iter().enumerate() {
            blobs.push((marker, k, pose.project_normalised(p)));
        }
    }
    // A fixed shuffle that interleaves the two markers.
    let order: Vec<usize> = (0..blobs.len())
        .map(|k| (5 * k + 3) % blobs.len())
        .collect();
    let image: Vec<Vector2<f64>> = order.iter().map(|&k| blobs[k].2).collect();
    let options = UnlabelledOptions::with_gate_px(2.5, Camera::paper().fx(), 1);
    let groups = group_blobs(&objects, &image, &options);
    assert_eq!(groups.len(), 2, "{groups:?}");
    for (marker, group) in groups.iter().enumerate() {
        assert_eq!(group.marker, marker);
        assert_eq!(group.blobs.len(), 7);
        for (&blob, &label) in group.blobs.iter().zip(&group.labels) {
            let (truth_marker, truth_label, _) = blobs[order[blob]];
            assert_eq!((truth_marker, truth_label), (marker, label));
        }
    }
}

/// `solve --unlabelled --set`: frames of one marker, of two markers mixed,
/// and with one blob missing name each marker, its blobs and labels and
/// its pose; a set file naming a missing layout is refused before any
/// work, naming the layout.
#[cfg(feature = "cli")]
#[test]
fn solve_set_names_the_marker_and_labels_of_each_blob_group() {
    use assert_cmd::Command;
    let dir = tempfile::tempdir().unwrap();
    let markers = four_markers();
    let layouts: Vec<Layout> = markers[..3]
        .iter()
        .enumerate()
        .map(|(k, m)| layout(&format!("m{k}"), m))
        .collect();
    let set = write_set(dir.path(), "trio", &layouts).unwrap();
    let camera = Camera::paper();
    let poses = [
        Pose::new(
            Rotation3::from_euler_angles(0.2, 0.3, -0.4),
            Vector3::new(-70.0, 15.0, 450.0),
        ),
        Pose::new(
            Rotation3::from_euler_angles(-0.3, -0.1, 0.7),
            Vector3::new(75.0, -10.0, 520.0),
        ),
    ];
    let project = |marker: usize, pose: &Pose, k: usize| {
        let p = camera
            .project(&pose.transform(&markers[marker][k]))
            .unwrap();
        [p.x, p.y]
    };
    // Frame a: marker 3 alone, reversed. Frame b: markers 2 and 1
    // interleaved. Frame c: marker 1 with point 4 missing.
    let frame_a: Vec<[f64; 2]> = (0..7).rev().map(|k| project(2, &poses[0], k)).collect();
    let mut frame_b = Vec::new();
    for k in 0..7 {
        frame_b.push(project(1, &poses[0], k));
        frame_b.push(project(0, &poses[1], 6 - k));
    }
    let frame_c: Vec<[f64; 2]> = [0, 1, 2, 3, 5, 6]
        .iter()
        .map(|&k| project(0, &poses[1], k))
        .collect();
    let batch = serde_json::json!({
        "camera": {"fx": camera.fx(), "fy": camera.fy(), "cx": camera.cx(), "cy": camera.cy()},
        "problems": [
            {"id": "a", "image_points": frame_a},
            {"id": "b", "image_points": frame_b},
            {"id": "c", "image_points": frame_c},
        ],
    });
    let input = dir.path().join("frames.json");
    let output = dir.path().join("found.json");
    std::fs::write(&input, batch.to_string()).unwrap();
    Command::cargo_bin("layout-opt")
        .unwrap()
        .args(["solve", "--quiet", "--unlabelled", "--set"])
        .arg(&set)
        .arg("--problems")
        .arg(&input)
        .arg("--output")
        .arg(&output)
        .assert()
        .success();
    let result: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&output).unwrap()).unwrap();
    assert_eq!(result["set"], "trio");
    let results = result["results"].as_array().unwrap();
    let found = |frame: usize| -> Vec<(usize, Vec<usize>, Vec<usize>)> {
        results[frame]["markers"]
            .as_array()
            .unwrap_or_else(|| panic!("frame {frame}: {}", results[frame]))
            .iter()
            .map(|m| {
                assert!(m["reprojection_rms_px"].as_f64().unwrap() < 1e-6, "{m}");
                (
                    m["marker"].as_u64().unwrap() as usize,
                    serde_json::from_value(m["blobs"].clone()).unwrap(),
                    serde_json::from_value(m["labels"].clone()).unwrap(),
                )
            })
            .collect()
    };
    assert_eq!(
        found(0),
        vec![(3, (0..7).collect(), (0..7).rev().collect())]
    );
    assert_eq!(
        found(1),
        vec![
            (
                1,
                (0..7).map(|k| 2 * k + 1).collect(),
                (0..7).rev().collect()
            ),
            (2, (0..7).map(|k| 2 * k).collect(), (0..7).collect()),
        ]
    );
    assert_eq!(
        found(2),
        vec![(1, (0..6).collect(), vec![0, 1, 2, 3, 5, 6])]
    );
    assert_eq!(results[1]["unexplained"], serde_json::json!([]));
    let translation: Vec<f64> =
        serde_json::from_value(results[1]["markers"][0]["translation"].clone()).unwrap();
    assert!((translation[2] - 520.0).abs() < 1e-6, "{translation:?}");

    // A set naming a missing layout: refused before any work.
    let broken = dir.path().join("broken.set.json");
    std::fs::write(
        &broken,
        set_file_json("x", &["trio-1.json".into(), "gone.json".into()]),
    )
    .unwrap();
    let assert = Command::cargo_bin("layout-opt")
        .unwrap()
        .args(["solve", "--quiet", "--unlabelled", "--set"])
        .arg(&broken)
        .arg("--problems")
        .arg(&input)
        .assert()
        .failure();
    let stderr = String::from_utf8_lossy(&assert.get_output().stderr).to_string();
    assert!(
        stderr.contains("gone.json") && stderr.contains("--set"),
        "{stderr}"
    );
}

/// `search --set 2` on a small grid: two layouts and the set file beside
/// the layout path, the report with each marker's accuracy alone and in
/// the set and the cross matrix; the set file loads and its markers are
/// distinct and cross-identifiable. `--set 9` is refused before any work,
/// with nothing written.
#[cfg(feature = "cli")]
#[test]
fn search_set_writes_the_markers_the_set_file_and_the_cross_matrix() {
    use assert_cmd::Command;
    let dir = tempfile::tempdir().unwrap();
    let layout_path = dir.path().join("layouts").join("duo.json");
    let report = dir.path().join("report");
    let search = |markers: &str| {
        let mut command = Command::cargo_bin("layout-opt").unwrap();
        command
            .args(["--quiet", "search", "--set", markers, "--starts", "1"])
            .args(["--iterations", "40", "--depth", "400", "--tilt=-30,30"])
            .args(["--name", "duo", "--out"])
            .arg(&layout_path)
            .arg("--report")
            .arg(&report);
        command
    };
    let assert = search("9").assert().failure();
    let stderr = String::from_utf8_lossy(&assert.get_output().stderr).to_string();
    assert!(
        stderr.contains("--set must be 2 to 8 markers, got 9"),
        "{stderr}"
    );
    assert!(!dir.path().join("layouts").exists() && !report.exists());

    search("2").assert().success();
    let set = MarkerSet::load(&dir.path().join("layouts").join("duo.set.json")).unwrap();
    assert_eq!(set.names(), ["duo-1", "duo-2"]);
    set.check_distinct().unwrap();
    let text = std::fs::read_to_string(report.join("set-report.md")).unwrap();
    assert!(
        text.contains("| 1 (duo-1) |") && text.contains("| 2 (duo-2) |"),
        "{text}"
    );
    assert!(text.contains("Smallest cross margin, px"), "{text}");
    assert!(text.contains("viewpoints between them"), "{text}");
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(report.join("set.json")).unwrap()).unwrap();
    assert!(summary["dips"].as_u64().is_some(), "{summary}");
    let pairs = summary["matrix"]["pairs"].as_array().unwrap();
    assert_eq!(pairs.len(), 2);
    for pair in pairs {
        assert!(pair["visible"].as_u64().unwrap() > 0, "{pair}");
        assert_eq!(pair["failing"], serde_json::json!([]), "{pair}");
    }
    // The objective is the worst marker's accuracy.
    let worst = summary["markers"]
        .as_array()
        .unwrap()
        .iter()
        .map(|m| m["accuracy"].as_f64().unwrap())
        .fold(f64::MIN, f64::max);
    assert_eq!(summary["objective"].as_f64().unwrap(), worst);
    // Each marker against the paper's biprism on the held-out grid, in
    // the file and in the report's column.
    for marker in summary["markers"].as_array().unwrap() {
        let held = &marker["held_out"];
        let (winner, paper) = (
            held["winner_rotation_rms_deg"].as_f64().unwrap(),
            held["paper_rotation_rms_deg"].as_f64().unwrap(),
        );
        assert!(winner > 0.0 && paper > 0.0, "{held}");
        let lower = held["rotation_reduction_percent"].as_f64().unwrap();
        assert!(
            (lower - 100.0 * (1.0 - winner / paper)).abs() < 1e-9,
            "{held}"
        );
        assert!(text.contains(&format!("{lower:.1}% lower")), "{text}");
    }
}

/// `validate SET.json`: a set of two distinct markers gets the report with
/// each marker and the cross matrix; a set of two copies of one marker is
/// refused before any work, naming both files.
#[cfg(feature = "cli")]
#[test]
fn validate_set_reports_each_marker_and_refuses_two_copies() {
    use assert_cmd::Command;
    let dir = tempfile::tempdir().unwrap();
    let markers = four_markers();
    let set = write_set(
        dir.path(),
        "pair",
        &[layout("a", &markers[0]), layout("b", &markers[3])],
    )
    .unwrap();
    let out = dir.path().join("report");
    Command::cargo_bin("layout-opt")
        .unwrap()
        .args(["--quiet", "validate"])
        .arg(&set)
        .args(["--identify-trials", "2", "--depth", "400", "--tilt=-20,20"])
        .arg("--out")
        .arg(&out)
        .assert()
        .success();
    let report = std::fs::read_to_string(out.join("set-report.md")).unwrap();
    assert!(report.contains("| 1 (pair-1) | pair-1.json |"), "{report}");
    assert!(report.contains("| 2 (pair-2) | pair-2.json |"), "{report}");
    assert!(report.contains("Smallest cross margin, px"), "{report}");
    assert!(report.contains("## Between the viewpoints"), "{report}");
    assert!(
        report.contains("## A blob left out near the floor"),
        "{report}"
    );
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("set.json")).unwrap()).unwrap();
    // Both ordered pairs searched between the grid's viewpoints; trials
    // run at every failing dip only.
    let between = summary["between"].as_array().unwrap();
    assert_eq!(between.len(), 2);
    for pair in between {
        let (near, failing) = (
            pair["near"].as_u64().unwrap(),
            pair["failing"].as_u64().unwrap(),
        );
        assert!(failing <= near, "{pair}");
        assert_eq!(pair["trials"].as_u64().unwrap(), 2 * failing, "{pair}");
    }
    for pair in summary["near"].as_array().unwrap() {
        let missing = pair["missing"].as_u64().unwrap();
        assert!(missing <= pair["near"].as_u64().unwrap(), "{pair}");
        assert_eq!(pair["trials"].as_u64().unwrap(), 2 * missing, "{pair}");
    }
    let trials = summary["trials"].as_array().unwrap();
    assert_eq!(trials.len(), 2);
    for counts in trials {
        assert!(counts["trials"].as_u64().unwrap() > 0, "{counts}");
        assert_eq!(counts["wrong_marker"], 0, "{counts}");
    }

    let copy = dir.path().join("copy.json");
    std::fs::copy(dir.path().join("pair-1.json"), &copy).unwrap();
    let twins = dir.path().join("twins.set.json");
    std::fs::write(
        &twins,
        set_file_json("twins", &["pair-1.json".into(), "copy.json".into()]),
    )
    .unwrap();
    let twin_out = dir.path().join("twin-report");
    let assert = Command::cargo_bin("layout-opt")
        .unwrap()
        .args(["--quiet", "validate"])
        .arg(&twins)
        .arg("--out")
        .arg(&twin_out)
        .assert()
        .failure();
    let stderr = String::from_utf8_lossy(&assert.get_output().stderr).to_string();
    assert!(
        stderr.contains("pair-1.json")
            && stderr.contains("copy.json")
            && stderr.contains("same marker"),
        "{stderr}"
    );
    assert!(!twin_out.exists());
}

/// `validate SET.json` tries the viewpoints near the floor again with the
/// worst case's blob left out: for a copy of a marker with one point
/// moved by 12 mm and two by 0.4 mm, leaving that point's blob out leaves
/// a fraction of a pixel between the two, and the trials name the other
/// marker about as often as predicted.
#[test]
fn near_viewpoints_are_tried_with_the_worst_cases_blob_left_out() {
    use layout_opt::search::set::validation::validate_set;
    use layout_opt::volume::WorkingVolume;
    let dir = tempfile::tempdir().unwrap();
    let marker = four_markers()[1].clone();
    let mut copy = marker.clone();
    copy[3].z += 12.0;
    copy[1].x += 0.4;
    copy[5].y -= 0.4;
    let path = write_set(
        dir.path(),
        "near",
        &[layout("a", &marker), layout("b", &copy)],
    )
    .unwrap();
    let set = MarkerSet::load(&path).unwrap();
    let grid = ScenarioGrid::new(
        "600,900".parse().unwrap(),
        "0".parse().unwrap(),
        "0".parse().unwrap(),
        "-30,0,30".parse().unwrap(),
        "-10,10".parse().unwrap(),
        "0".parse().unwrap(),
        "0.5".parse().unwrap(),
    )
    .unwrap();
    let trials = 30;
    let validation = validate_set(
        &set,
        &Camera::paper(),
        &WorkingVolume::Grid(grid),
        &settings(trials),
    );
    assert_eq!(validation.near.len(), 2);
    let (mut wrong, mut expected, mut tried) = (0, 0.0, 0);
    for pair in &validation.near {
        assert!(pair.missing > 0 && pair.missing <= pair.near, "{pair:?}");
        assert_eq!(pair.trials, trials * pair.missing, "{pair:?}");
        wrong += pair.wrong_marker;
        expected += pair.expected_wrong;
        tried += pair.trials;
    }
    // Binomial per viewpoint: the count within 4 standard deviations of
    // the prediction (at most p = 0.5, so sd ≤ √(n/4)).
    let sd = (tried as f64 / 4.0).sqrt();
    assert!(expected > 2.0 * sd, "expected {expected} of {tried}");
    assert!(
        (wrong as f64 - expected).abs() <= 4.0 * sd,
        "{wrong} named the other marker, {expected:.1} expected, of {tried}"
    );
    let report = validation.markdown("test");
    assert!(
        report.contains("## A blob left out near the floor"),
        "{report}"
    );
    assert_eq!(validation.json()["near"].as_array().unwrap().len(), 2);
}

/// A set file of markers 1 and 2 of [`four_markers`] in `dir`.
pub(crate) fn two_marker_set(dir: &std::path::Path) -> (std::path::PathBuf, Vec<Layout>) {
    let markers = four_markers();
    let layouts = vec![layout("pair-a", &markers[0]), layout("pair-b", &markers[1])];
    // The set file names its layouts <set>-k.
    let path = write_set(dir, "pair", &layouts).unwrap();
    let layouts = MarkerSet::load(&path)
        .unwrap()
        .members
        .into_iter()
        .map(|m| m.layout)
        .collect();
    (path, layouts)
}

/// Vertices of `mesh` deeper than `depth_mm` below the engraved face and
/// inside the text's box.
fn vertices_in_groove(
    mesh: &[nalgebra::Vector3<f64>],
    engraving: &serde_json::Value,
    depth_mm: f64,
) -> usize {
    let v = |key: &str| {
        let a: Vec<f64> = serde_json::from_value(engraving[key].clone()).unwrap();
        Vector3::new(a[0], a[1], a[2])
    };
    let (normal, right, up, origin) = (v("normal"), v("right"), v("up"), v("origin"));
    let level = engraving["face_level_mm"].as_f64().unwrap();
    let size: Vec<f64> = serde_json::from_value(engraving["size_mm"].clone()).unwrap();
    mesh.iter()
        .filter(|p| {
            let (x, y) = ((*p - origin).dot(&right), (*p - origin).dot(&up));
            // Between the face and the plate's back (4 mm behind it).
            (level - 2.0..level - depth_mm).contains(&p.dot(&normal))
                && (0.0..=size[0]).contains(&x)
                && (0.0..=size[1]).contains(&y)
        })
        .count()
}

/// `layout-opt export --quiet --format obj --out OUT SET`.
fn export_set(set_path: &std::path::Path, out: &std::path::Path) -> assert_cmd::assert::Assert {
    assert_cmd::Command::cargo_bin("layout-opt")
        .unwrap()
        .args(["export", "--quiet", "--format", "obj", "--out"])
        .arg(out)
        .arg(set_path)
        .assert()
}

/// `export SET.json`: one directory per part, each part's number engraved
/// into its plate (vertices below the plate's face inside the digit's box,
/// which the same layout exported without the number lacks, and a volume
/// lower by about the grooves' volume), every mesh a watertight solid,
/// and one sheet naming every part with its layout file.
#[test]
fn a_set_exports_numbered_watertight_parts_and_one_sheet() {
    use layout_opt::mesh::{build, ExportOptions};
    let dir = tempfile::tempdir().unwrap();
    let (set_path, layouts) = two_marker_set(dir.path());
    let out = dir.path().join("parts");
    export_set(&set_path, &out).success();
    let sheet = std::fs::read_to_string(out.join("pair-set.md")).unwrap();
    for (k, layout) in layouts.iter().enumerate() {
        let number = k + 1;
        let part = out.join(format!("{number}-{}", layout.name));
        let row = format!(
            "| {number} | {} | pair-{number}.json | {number}-{}/ |",
            layout.name, layout.name
        );
        assert!(sheet.contains(&row), "{row} missing:\n{sheet}");
        let report: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(part.join(format!("{}-export.json", layout.name))).unwrap(),
        )
        .unwrap();
        let engraving = &report["engraving"];
        assert_eq!(engraving["text"], number.to_string());
        let (models, _) = tobj::load_obj(
            part.join(format!("{}.obj", layout.name)),
            &tobj::LoadOptions::default(),
        )
        .unwrap();
        let mesh = &models[0].mesh;
        let numbered = layout_opt::mesh::TriangleMesh {
            positions: mesh
                .positions
                .chunks(3)
                .map(|p| Vector3::new(p[0] as f64, p[1] as f64, p[2] as f64))
                .collect(),
            triangles: mesh.indices.chunks(3).map(|t| [t[0], t[1], t[2]]).collect(),
        };
        let topology = numbered.topology();
        assert!(topology.is_watertight_solid(), "{topology:?}");
        assert_eq!(topology.components, 1);
        let depth = engraving["depth_mm"].as_f64().unwrap();
        assert!(vertices_in_groove(&numbered.positions, engraving, 0.5 * depth) > 20);
        assert!(sheet.contains(&format!(
            "{number}-{}/{}-fabrication.md",
            layout.name, layout.name
        )));
        if number > 1 {
            // One unnumbered twin is enough to show what the grooves remove
            // (each meshing at the engraving's grid takes seconds).
            continue;
        }
        // The same layout without the number, on the same grid.
        let resolution = report["mesh"]["resolution_mm"].as_f64().unwrap();
        let plain = build(
            layout,
            &ExportOptions {
                resolution_mm: Some(resolution),
                ..Default::default()
            },
        )
        .unwrap();
        assert_eq!(
            vertices_in_groove(&plain.mesh.positions, engraving, 0.1 * depth),
            0
        );
        let removed = plain.mesh.signed_volume() - numbered.signed_volume();
        let stroke = engraving["stroke_mm"].as_f64().unwrap();
        // Each digit's strokes: between 2 and 7 segments of 2 to 3 stroke
        // widths, each a half-round groove of the stroke's width.
        let section = 0.5 * std::f64::consts::PI * (0.5 * stroke).powi(2);
        let (least, most) = (2.0 * 2.0 * stroke * section, 7.0 * 4.0 * stroke * section);
        assert!(
            removed > 0.5 * least && removed < 2.0 * most,
            "part {number}: {removed} mm³ removed, expected {least}..{most}"
        );
    }
}

/// A set file naming a missing layout is refused naming that file, and no
/// part is written.
#[test]
fn exporting_a_set_with_a_missing_layout_names_it_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let (set_path, _) = two_marker_set(dir.path());
    std::fs::remove_file(dir.path().join("pair-2.json")).unwrap();
    let out = dir.path().join("parts");
    export_set(&set_path, &out)
        .failure()
        .stderr(predicates::str::contains("pair-2.json"));
    assert!(!out.exists());
}

/// `track --set`: each marker of a set rendered alone (the renderer draws
/// one part per frame), with its supports, is found and named by its
/// number and layout, with a pose near the truth and a covariance; with
/// `--refine` each one found is refined with its own part.
#[test]
fn track_set_names_the_marker_each_frame_shows() {
    use layout_opt::render::workflow::{run, FramePose, RenderJob};
    use layout_opt::render::RenderConfig;
    let dir = tempfile::tempdir().unwrap();
    let (set_path, layouts) = two_marker_set(dir.path());
    // Two views per marker: its supports may hide spheres in one.
    let truths = [
        Pose::new(
            Rotation3::from_euler_angles(0.15, -0.1, 0.3),
            Vector3::new(10.0, -5.0, 600.0),
        ),
        Pose::new(
            Rotation3::from_euler_angles(-0.1, 0.05, -0.2),
            Vector3::new(-5.0, 5.0, 650.0),
        ),
    ];
    let mut frames = Vec::new();
    for layout in &layouts {
        let mut config = RenderConfig::new(Camera::paper());
        config.realisations = 1;
        let job = RenderJob {
            sources: Vec::new(),
            layout: layout.clone(),
            marker: layout_opt::mesh::MarkerOptions::default(),
            poses: truths
                .iter()
                .map(|&pose| FramePose {
                    pose,
                    scenario: None,
                })
                .collect(),
            config,
            out_dir: dir.path().join(format!("frames-{}", layout.name)),
        };
        let report = run(&job, &mut layout_opt::observer::Silent).unwrap();
        frames.push(
            report
                .frames
                .iter()
                .map(|f| f.images[0].clone())
                .collect::<Vec<_>>(),
        );
    }
    // Unrefined, then refined (each marker found rendered alone).
    let mut batch = Vec::new();
    for refine in [false, true] {
        let output = assert_cmd::Command::cargo_bin("layout-opt")
            .unwrap()
            .args(["track", "--quiet", "--set"])
            .arg(&set_path)
            .args(frames.iter().flatten())
            .args(if refine {
                &["--refine", "--supersampling", "4"][..]
            } else {
                &[][..]
            })
            .assert()
            .success()
            .get_output()
            .stdout
            .clone();
        let stdout = String::from_utf8(output).unwrap();
        let records: Vec<serde_json::Value> = stdout
            .lines()
            .map(|l| serde_json::from_str(l).unwrap())
            .collect();
        for (k, (shown, layout)) in frames.iter().zip(&layouts).enumerate() {
            let mut found = 0;
            for (frame, truth) in shown.iter().zip(&truths) {
                let name = frame.display().to_string();
                let records: Vec<&serde_json::Value> = records
                    .iter()
                    .filter(|r| r["frame"] == name && !r["marker"].is_null())
                    .collect();
                // A frame of one marker never names another.
                assert!(records.len() <= 1, "{stdout}");
                let Some(record) = records.first() else {
                    continue;
                };
                found += 1;
                assert_eq!(record["marker"], k + 1, "{record}");
                assert_eq!(record["layout"], layout.name.as_str());
                let t: Vec<f64> = serde_json::from_value(record["t"].clone()).unwrap();
                assert!(
                    (Vector3::new(t[0], t[1], t[2]) - truth.translation).norm() < 10.0,
                    "{record}"
                );
                assert!(record["covariance"].is_array());
                assert_eq!(
                    record["refinement"]["rounds"].as_u64(),
                    refine.then_some(1),
                    "{record}"
                );
            }
            assert!(
                found >= 1,
                "marker {} found in none of its frames:\n{stdout}",
                k + 1
            );
        }
        if !refine {
            batch = records;
        }
    }
    // The same frames as a YUV4MPEG2 stream on standard input: the same
    // markers and poses, frame by frame, each line with its index.
    let mut y4m = Vec::new();
    let mut encoder = y4m::encode(1280, 720, y4m::Ratio::new(30, 1))
        .with_colorspace(y4m::Colorspace::Cmono)
        .write_header(&mut y4m)
        .unwrap();
    let names: Vec<String> = frames
        .iter()
        .flatten()
        .map(|f| f.display().to_string())
        .collect();
    for frame in frames.iter().flatten() {
        let grey = layout_opt::track::GreyFrame::from_png(&std::fs::read(frame).unwrap()).unwrap();
        let luma: Vec<u8> = grey.pixels().iter().map(|&v| v as u8).collect();
        encoder
            .write_frame(&y4m::Frame::new([&luma, &[], &[]], None))
            .unwrap();
    }
    let output = assert_cmd::Command::cargo_bin("layout-opt")
        .unwrap()
        .args(["track", "--quiet", "--set"])
        .arg(&set_path)
        .arg("-")
        .write_stdin(y4m)
        .assert()
        .success()
        .get_output()
        .stdout
        .clone();
    let streamed: Vec<serde_json::Value> = String::from_utf8(output)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(streamed.len(), batch.len());
    for (line, record) in streamed.iter().zip(&batch) {
        let index = line["index"].as_u64().unwrap() as usize;
        assert_eq!(record["frame"], names[index].as_str());
        assert_eq!(line["frame"], format!("stdin:{index}"));
        for field in ["marker", "layout", "t", "covariance"] {
            assert_eq!(line[field], record[field], "{field}: {line}");
        }
    }
}
