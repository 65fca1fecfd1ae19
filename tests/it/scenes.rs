//! Frames of several markers: `render SET.json --poses SCENES.json` draws
//! two markers of a set in one frame, one part hiding a sphere of the
//! other; the truth names what hides what; `track --set` leaves the hidden
//! sphere out and poses both markers.

use crate::sets::two_marker_set;
use layout_opt::layout::Layout;
use layout_opt::mesh::{routed_as_recorded, Marker, MarkerOptions};
use layout_opt::pose::Pose;
use layout_opt::render::{part_truth, Placed, RenderConfig, Scene};
use nalgebra::{Rotation3, Vector3};
use std::path::{Path, PathBuf};

fn scene_of(layout: &Layout) -> Scene {
    let options = routed_as_recorded(layout, MarkerOptions::default()).unwrap();
    Scene::from_marker(Marker::design(layout, &options).unwrap())
}

fn names(layout: &Layout) -> Vec<String> {
    layout.points.iter().map(|p| p.name.clone()).collect()
}

/// How marker 2's sphere stands to marker 1's in a scene.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Meeting {
    /// 150 mm behind it on the same sight line: wholly hidden.
    Behind,
    /// Beside it, 5 mm deeper, their discs overlapping by a pixel: one
    /// blob.
    Touching,
}

/// A scene where sphere `front` of marker 1 and sphere `back` of marker 2
/// meet as `meeting` says, and nothing else of either marker is hidden or
/// leaves the image, every other pair of spheres apart by more than their
/// radii plus 4 px: (pose 1, pose 2, front, back).
fn scene_where(
    meeting: Meeting,
    layouts: &[Layout],
    scenes: &[Scene],
) -> (Pose, Pose, usize, usize) {
    let camera = RenderConfig::new(layout_opt::camera::Camera::paper()).camera;
    let first = Pose::new(
        Rotation3::from_euler_angles(0.15, -0.1, 0.3),
        Vector3::new(-40.0, -5.0, 550.0),
    );
    let rotation = Rotation3::from_euler_angles(-0.1, 0.05, -0.2);
    let radius_px = |centre: &Vector3<f64>, radius: f64| camera.fx() * radius / centre.z;
    for front in 0..layouts[0].points.len() {
        for back in 0..layouts[1].points.len() {
            let (centre, radius) = scenes[0].spheres()[front];
            let sight = first.transform(&centre);
            let there = match meeting {
                Meeting::Behind => sight * ((sight.norm() + 150.0) / sight.norm()),
                Meeting::Touching => {
                    let deeper = sight * ((sight.z + 5.0) / sight.z);
                    let r_back = scenes[1].spheres()[back].1;
                    let apart_px = radius_px(&sight, radius) + radius_px(&deeper, r_back) - 1.0;
                    deeper + Vector3::new(apart_px * deeper.z / camera.fx(), 0.0, 0.0)
                }
            };
            let second = Pose::new(rotation, there - rotation * scenes[1].spheres()[back].0);
            let parts = [
                Placed {
                    scene: &scenes[0],
                    pose: &first,
                },
                Placed {
                    scene: &scenes[1],
                    pose: &second,
                },
            ];
            let truths: Vec<_> = (0..2)
                .map(|k| part_truth(&parts, k, &names(&layouts[k]), &camera).unwrap())
                .collect();
            let mut discs = Vec::new();
            let mut clean = true;
            for (k, truth) in truths.iter().enumerate() {
                for (j, sphere) in truth.spheres.iter().enumerate() {
                    let special = (k, j) == (1, back) || (k, j) == (0, front);
                    match meeting {
                        Meeting::Behind if (k, j) == (1, back) => {
                            clean &= sphere.hidden.by_other_marker >= 0.99
                                && sphere.hidden_by_markers.len() == 1
                                && sphere.hidden_by_markers[0].marker == 1;
                        }
                        Meeting::Touching if special => {
                            clean &= sphere.hidden.by_support == 0.0
                                && sphere.hidden.by_sphere == 0.0
                                && sphere.hidden.outside_image == 0.0;
                        }
                        _ => {
                            clean &= sphere.hidden.total() == 0.0;
                            discs.push((sphere.ellipse_centre_px, sphere.semi_axes_px[0]));
                        }
                    }
                }
            }
            let apart = discs.iter().enumerate().all(|(a, (ca, ra))| {
                discs[a + 1..].iter().all(|(cb, rb)| {
                    let d = ((ca[0] - cb[0]).powi(2) + (ca[1] - cb[1]).powi(2)).sqrt();
                    d > ra + rb + 4.0
                })
            });
            if clean && apart {
                return (first, second, front, back);
            }
        }
    }
    panic!("no pair of spheres gives a scene where they meet as {meeting:?}");
}

/// Renders the one frame of the set's markers at `first` and `second`
/// into `dir`/frames.
fn render_scene(dir: &Path, set_path: &Path, first: &Pose, second: &Pose) -> PathBuf {
    let scenes_path = dir.join("scenes.json");
    let file = serde_json::json!([[pose_json(1, first), pose_json(2, second)]]);
    std::fs::write(&scenes_path, file.to_string()).unwrap();
    let out = dir.join("frames");
    assert_cmd::Command::cargo_bin("layout-opt")
        .unwrap()
        .args(["render", "--quiet", "--seed", "5"])
        .arg(set_path)
        .arg("--poses")
        .arg(&scenes_path)
        .arg("--out")
        .arg(&out)
        .assert()
        .success();
    out
}

/// `track --set` on one frame: its JSON lines.
fn track_set(set_path: &Path, frame: &Path) -> Vec<serde_json::Value> {
    let output = assert_cmd::Command::cargo_bin("layout-opt")
        .unwrap()
        .args(["track", "--quiet", "--set"])
        .arg(set_path)
        .arg(frame)
        .assert()
        .success()
        .get_output()
        .stdout
        .clone();
    String::from_utf8(output)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect()
}

fn labels_of(record: &serde_json::Value) -> Vec<u64> {
    record["labels"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|l| l.as_u64())
        .collect()
}

fn pose_json(marker: usize, pose: &Pose) -> serde_json::Value {
    let r = pose.rotation.matrix();
    serde_json::json!({
        "marker": marker,
        "R": (0..3).map(|i| (0..3).map(|j| r[(i, j)]).collect::<Vec<f64>>()).collect::<Vec<_>>(),
        "t": [pose.translation.x, pose.translation.y, pose.translation.z],
    })
}

fn translation_of(record: &serde_json::Value) -> Vector3<f64> {
    let t: Vec<f64> = serde_json::from_value(record["t"].clone()).unwrap();
    Vector3::new(t[0], t[1], t[2])
}

#[test]
fn a_scene_of_two_markers_names_the_hidden_sphere_and_track_set_poses_both() {
    let dir = tempfile::tempdir().unwrap();
    let (set_path, layouts) = two_marker_set(dir.path());
    let scenes: Vec<Scene> = layouts.iter().map(scene_of).collect();
    let (first, second, _, hidden) = scene_where(Meeting::Behind, &layouts, &scenes);
    let out = render_scene(dir.path(), &set_path, &first, &second);
    // The record: both markers, their poses, and the hidden sphere named
    // with the marker that hides it.
    let record: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("pair-000.json")).unwrap()).unwrap();
    let markers = record["markers"].as_array().unwrap();
    assert_eq!(markers.len(), 2);
    assert_eq!(markers[1]["marker"], 2);
    assert_eq!(markers[1]["layout"], layouts[1].name.as_str());
    assert!((translation_of(&markers[1]) - second.translation).norm() < 1e-9);
    let sphere = &markers[1]["spheres"][hidden];
    assert_eq!(sphere["hidden_by_markers"][0]["marker"], 1, "{sphere}");
    assert!(sphere["hidden"]["by_other_marker"].as_f64().unwrap() >= 0.99);
    assert!(markers[0]["spheres"]
        .as_array()
        .unwrap()
        .iter()
        .all(|s| s.get("hidden_by_markers").is_none()));
    // track --set: both markers, the hidden sphere among neither's labels.
    let records = track_set(&set_path, &out.join("pair-000.png"));
    let found: Vec<u64> = records
        .iter()
        .filter_map(|r| r["marker"].as_u64())
        .collect();
    assert_eq!(found, [1, 2], "{records:?}");
    for (record, truth) in records.iter().zip([&first, &second]) {
        assert!(
            (translation_of(record) - truth.translation).norm() < 2.0,
            "{record}"
        );
        assert!(record["covariance"].is_array());
    }
    let labels = labels_of(&records[1]);
    assert_eq!(labels.len(), layouts[1].points.len() - 1, "{}", records[1]);
    assert!(!labels.contains(&(hidden as u64)), "{}", records[1]);
    let first_labels = records[0]["labels"].as_array().unwrap();
    assert_eq!(
        first_labels.iter().filter(|l| l.is_u64()).count(),
        layouts[0].points.len()
    );
}

/// Spheres of two markers whose discs overlap make one blob: it is flagged
/// (partly hidden), left out of both markers, and named among the
/// blobs no marker explains; both markers are posed from the rest.
#[test]
fn touching_blobs_of_two_markers_are_flagged_and_both_markers_posed() {
    let dir = tempfile::tempdir().unwrap();
    let (set_path, layouts) = two_marker_set(dir.path());
    let scenes: Vec<Scene> = layouts.iter().map(scene_of).collect();
    let (first, second, front, back) = scene_where(Meeting::Touching, &layouts, &scenes);
    let out = render_scene(dir.path(), &set_path, &first, &second);
    let truth: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("pair-000.json")).unwrap()).unwrap();
    let centre = |marker: usize, sphere: usize| -> Vec<f64> {
        serde_json::from_value(
            truth["markers"][marker]["spheres"][sphere]["ellipse_centre_px"].clone(),
        )
        .unwrap()
    };
    let (front_px, back_px) = (centre(0, front), centre(1, back));
    let records = track_set(&set_path, &out.join("pair-000.png"));
    let found: Vec<u64> = records
        .iter()
        .filter_map(|r| r["marker"].as_u64())
        .collect();
    assert_eq!(found, [1, 2], "{records:?}");
    for (record, (truth, left_out)) in records.iter().zip([(&first, front), (&second, back)]) {
        assert!(
            (translation_of(record) - truth.translation).norm() < 2.0,
            "{record}"
        );
        let labels = labels_of(record);
        assert!(!labels.contains(&(left_out as u64)), "{record}");
        // The merged blob: flagged among the blobs no marker explains, or
        // rejected as no sphere's disc, said where, over both discs.
        let flagged = record["unclaimed_blobs"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|b| !b["hidden_because"].as_array().unwrap().is_empty())
            .count();
        let misshapen = record["misshapen"].as_array().unwrap();
        assert_eq!(flagged + misshapen.len(), 1, "{record}");
        for component in misshapen {
            let b: Vec<f64> = serde_json::from_value(component["box_px"].clone()).unwrap();
            for centre in [&front_px, &back_px] {
                assert!(
                    (b[0]..=b[2]).contains(&centre[0]) && (b[1]..=b[3]).contains(&centre[1]),
                    "{component} misses {centre:?}"
                );
            }
        }
    }
}

/// The scenario flags move one marker of a set and `--fixed` holds
/// another still: each frame's record gives both poses and the scenario.
#[test]
fn scenario_flags_move_one_marker_past_a_fixed_one() {
    let dir = tempfile::tempdir().unwrap();
    let (set_path, _) = two_marker_set(dir.path());
    let out = dir.path().join("grid");
    assert_cmd::Command::cargo_bin("layout-opt")
        .unwrap()
        .args([
            "render",
            "--quiet",
            "--depth",
            "450..650:200",
            "--tilt",
            "20",
        ])
        .args([
            "--offset-x=-80",
            "--moving",
            "2",
            "--fixed",
            "1:90,-40,700:10,-15,30",
        ])
        .arg(&set_path)
        .arg("--out")
        .arg(&out)
        .assert()
        .success();
    for (frame, depth) in [(0, 450.0), (1, 650.0)] {
        let record: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(out.join(format!("pair-{frame:03}.json"))).unwrap(),
        )
        .unwrap();
        let markers = record["markers"].as_array().unwrap();
        assert_eq!(markers[0]["marker"], 2);
        assert_eq!(translation_of(&markers[0]), Vector3::new(-80.0, 0.0, depth));
        assert_eq!(markers[1]["marker"], 1);
        assert_eq!(
            translation_of(&markers[1]),
            Vector3::new(90.0, -40.0, 700.0)
        );
        assert_eq!(record["scenario"]["depth_mm"].as_f64(), Some(depth));
    }
}
