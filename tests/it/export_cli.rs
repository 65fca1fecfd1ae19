//! The `layout-opt export` command line: defaults, outputs and the errors a
//! user sees on stderr.

use assert_cmd::Command;
use predicates::prelude::*;
use std::path::Path;

fn layout_opt() -> Command {
    Command::cargo_bin("layout-opt").unwrap()
}

fn shipped(name: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("layouts")
        .join(name)
        .display()
        .to_string()
}

#[test]
fn no_arguments_exports_the_paper_biprism_into_build() {
    let dir = tempfile::tempdir().unwrap();
    layout_opt()
        .current_dir(dir.path())
        .arg("export")
        .assert()
        .success()
        .stdout(predicate::str::contains("biprism-paper:"))
        .stdout(predicate::str::contains("triangles"))
        .stdout(predicate::str::contains("volume"))
        .stdout(predicate::str::contains("watertight: all"))
        .stdout(predicate::str::contains("Euler characteristic 2"))
        .stdout(predicate::str::contains("wrote build/biprism-paper.stl"));
    for file in [
        "biprism-paper.stl",
        "biprism-paper.obj",
        "biprism-paper.gltf",
        "biprism-paper.bin",
        "biprism-paper.glb",
        "biprism-paper-fabrication.md",
        "biprism-paper-fabrication.csv",
        "biprism-paper-views.svg",
        "biprism-paper-export.json",
    ] {
        assert!(dir.path().join("build").join(file).exists(), "{file}");
    }
}

#[test]
fn chosen_formats_holes_and_mount() {
    let dir = tempfile::tempdir().unwrap();
    layout_opt()
        .args([
            "export",
            &shipped("tetrahedron.json"),
            "--format",
            "stl,glb",
        ])
        .args(["--mount", "-y", "--mount-holes", "M3", "--out"])
        .arg(dir.path())
        .assert()
        .success()
        .stdout(predicate::str::contains(
            "Euler characteristic -2 (2 - 2 x 2 holes)",
        ));
    assert!(dir.path().join("tetrahedron.stl").exists());
    assert!(dir.path().join("tetrahedron.glb").exists());
    assert!(!dir.path().join("tetrahedron.obj").exists());
    assert!(!dir.path().join("tetrahedron.gltf").exists());
}

#[test]
fn a_strut_too_thin_to_print_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    layout_opt()
        .args(["export", "--strut-diameter", "0.6", "--out"])
        .arg(dir.path())
        .assert()
        .failure()
        .stderr(predicate::str::contains(
            "strut diameter 0.6 mm is too thin to print: below the minimum feature size 1 mm (--min-feature)",
        ));
    assert!(!dir.path().join("biprism-paper.stl").exists());
}

#[test]
fn overlapping_spheres_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("overlap.json");
    std::fs::write(
        &path,
        r#"{"name": "overlap", "units": "mm", "sphere_diameter_mm": 10, "points": [
            {"name": "A", "position": [0, 0, 0]}, {"name": "B", "position": [8, 0, 0]},
            {"name": "C", "position": [0, 40, 0]}, {"name": "D", "position": [0, 0, 40]}]}"#,
    )
    .unwrap();
    layout_opt()
        .args(["export"])
        .arg(&path)
        .arg("--out")
        .arg(dir.path())
        .assert()
        .failure()
        .stderr(predicate::str::contains("Error: cannot export"))
        .stderr(predicate::str::contains(
            "spheres A and B overlap: centres 8.000 mm apart, less than the sphere diameter 10 mm",
        ));
}

#[test]
fn spheres_closer_than_the_minimum_feature_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("close.json");
    std::fs::write(
        &path,
        r#"{"points": [
            {"name": "A", "position": [0, 0, 0]}, {"name": "B", "position": [10.5, 0, 0]},
            {"name": "C", "position": [0, 40, 0]}, {"name": "D", "position": [0, 0, 40]}]}"#,
    )
    .unwrap();
    layout_opt()
        .arg("export")
        .arg(&path)
        .arg("--out")
        .arg(dir.path())
        .assert()
        .failure()
        .stderr(predicate::str::contains(
            "spheres A and B are 0.500 mm apart",
        ));
}

#[test]
fn an_unknown_format_is_refused() {
    layout_opt()
        .args(["export", "--format", "stl,ply"])
        .assert()
        .failure()
        .stderr(predicate::str::contains(
            "unknown format \"ply\": expected stl, 3mf, obj, gltf or glb",
        ));
}

#[test]
fn bad_geometry_options_are_refused() {
    layout_opt()
        .args(["export", "--mount", "-z"])
        .assert()
        .failure()
        .stderr(predicate::str::contains(
            "the mount axis -z points at the camera (the view is along +z)",
        ));
    layout_opt()
        .args(["export", "--resolution", "2"])
        .assert()
        .failure()
        .stderr(predicate::str::contains(
            "--resolution 2 mm is too coarse for the finest feature (1 mm); use at most 0.5 mm",
        ));
    layout_opt()
        .args(["export", "--mount-holes", "M7"])
        .assert()
        .failure()
        .stderr(predicate::str::contains("unknown mount holes \"M7\""));
    layout_opt()
        .args(["export", "--view", "up"])
        .assert()
        .failure()
        .stderr(predicate::str::contains("unknown axis \"up\""));
}

#[test]
fn a_missing_layout_file_is_reported() {
    layout_opt()
        .args(["export", "no-such-layout.json"])
        .assert()
        .failure()
        .stderr(predicate::str::contains(
            "cannot read layout file no-such-layout.json",
        ));
}

#[test]
fn an_obj_point_set_is_imported() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("four.obj");
    std::fs::write(&path, "v 0 0 0\nv 40 0 0\nv 0 40 0\nv 0 0 40\n").unwrap();
    layout_opt()
        .arg("export")
        .arg(&path)
        .args(["--format", "stl", "--sphere-diameter", "8", "--out"])
        .arg(dir.path())
        .assert()
        .success()
        .stdout(predicate::str::contains("four:"));
    let sheet = std::fs::read_to_string(dir.path().join("four-fabrication.md")).unwrap();
    assert!(
        sheet.contains("| V2 | 40.000 | 0.000 | 0.000 | 8.000 |"),
        "{sheet}"
    );
}

#[test]
fn the_view_cone_follows_the_tilts_given() {
    let dir = tempfile::tempdir().unwrap();
    let export = |extra: &[&str]| {
        let mut command = layout_opt();
        command
            .args([
                "export",
                &shipped("tetrahedron.json"),
                "--format",
                "stl",
                "--out",
            ])
            .arg(dir.path())
            .args(extra);
        command.assert()
    };
    export(&["--tilt", "-25..25:5"])
        .success()
        .stdout(predicate::str::contains("view cone ±25°"));
    export(&[])
        .success()
        .stdout(predicate::str::contains("view cone ±20°"));
    export(&["--tilt", "-90..90:10"])
        .failure()
        .stderr(predicate::str::contains(
            "--tilt and --pan reach 90.0° from the main view; the view cone must stay below 80°",
        ));
    export(&["--tilt", "10", "--view-cone", "5"])
        .failure()
        .stderr(predicate::str::contains("cannot be used with"));
}
