//! `solve --sphere-diameter` and `--observation` end to end.

use assert_cmd::Command;
use layout_opt::camera::Camera;
use layout_opt::pose::{rotation_error_deg, Pose};
use layout_opt::sphere_image::ellipse_centre_normalised;
use nalgebra::{Matrix3, Rotation3, Vector3};
use predicates::prelude::*;

fn layout_opt() -> Command {
    Command::cargo_bin("layout-opt").unwrap()
}

/// A batch of noise-free ellipse centres of 10 mm spheres on the paper's
/// biprism, seen off-axis at 200…400 mm by the distorted paper camera.
fn ellipse_centre_batch() -> (String, Vec<Pose>) {
    let camera = Camera::paper_with_distortion();
    let object = layout_opt::synthetic::biprism_points(50.0);
    let truths: Vec<Pose> = (0..4)
        .map(|i| {
            Pose::new(
                Rotation3::from_euler_angles(0.5 - 0.3 * i as f64, -0.2, 0.15),
                Vector3::new(70.0, -40.0, 200.0 + 70.0 * i as f64),
            )
        })
        .collect();
    let problems: Vec<serde_json::Value> = truths
        .iter()
        .map(|truth| {
            let pixels: Vec<[f64; 2]> = object
                .iter()
                .map(|p| {
                    let m = ellipse_centre_normalised(&truth.transform(p), 5.0).unwrap();
                    let px = camera.normalised_to_pixel(&m);
                    [px.x, px.y]
                })
                .collect();
            serde_json::json!({
                "object_points": object.iter().map(|p| [p.x, p.y, p.z]).collect::<Vec<_>>(),
                "image_points": pixels,
            })
        })
        .collect();
    let text = serde_json::json!({
        "camera": {"fx": camera.fx(), "fy": camera.fy(), "cx": camera.cx(), "cy": camera.cy(),
                   "distortion": camera.distortion()},
        "problems": problems,
    })
    .to_string();
    (text, truths)
}

fn rotation_errors(output: &serde_json::Value, truths: &[Pose]) -> Vec<f64> {
    output["results"]
        .as_array()
        .unwrap()
        .iter()
        .zip(truths)
        .map(|(result, truth)| {
            let r = &result["rotation"];
            let m = Matrix3::from_fn(|i, j| r[i][j].as_f64().unwrap());
            rotation_error_deg(&truth.rotation, &Rotation3::from_matrix_unchecked(m))
        })
        .collect()
}

#[test]
fn solve_with_sphere_diameter_is_exact_on_ellipse_centres() {
    let dir = tempfile::tempdir().unwrap();
    let (text, truths) = ellipse_centre_batch();
    let problems = dir.path().join("shots.json");
    std::fs::write(&problems, text).unwrap();
    let solve = |extra: &[&str], out: &str| {
        let path = dir.path().join(out);
        layout_opt()
            .args(["solve", "--quiet", "--solver", "ml", "--problems"])
            .arg(&problems)
            .args(extra)
            .arg("--output")
            .arg(&path)
            .assert()
            .success();
        let output: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
        rotation_errors(&output, &truths)
    };
    let exact = solve(&["--sphere-diameter", "10"], "sphere.json");
    assert!(exact.iter().all(|e| *e < 1e-6), "{exact:?}");
    let naive = solve(&[], "point.json");
    assert!(naive.iter().all(|e| *e > 1e-3), "{naive:?}");
}

#[test]
fn sphere_and_observation_flags_reject_bad_values() {
    layout_opt()
        .args([
            "solve",
            "--quiet",
            "--solver",
            "sqpnp",
            "--sphere-diameter",
            "10",
        ])
        .assert()
        .failure()
        .stderr(predicate::str::contains(
            "--sphere-diameter needs --solver ml",
        ));
    layout_opt()
        .args(["solve", "--quiet", "--solver", "ml", "--sphere-diameter=-2"])
        .assert()
        .failure()
        .stderr(predicate::str::contains("positive number of mm"));
    layout_opt()
        .args(["validate", "--quiet", "--observation", "blob"])
        .assert()
        .failure()
        .stderr(predicate::str::contains(
            "expected `centre` or `ellipse-centre`",
        ));
}
