//! The working volume from the command line: today's grid flags reproduce
//! today's numbers exactly, a volume file and the same flags give the same
//! report, the pairwise page and the worst viewpoints are written, and bad
//! volumes are refused before any work. Every run is a handful of
//! viewpoints at two or three trials.

use assert_cmd::Command;
use predicates::prelude::*;
use std::path::Path;

fn layout_opt() -> Command {
    Command::cargo_bin("layout-opt").unwrap()
}

/// The cheapest validation: one solver, 3 trials, no identifiability
/// trials.
const CHEAP: [&str; 8] = [
    "--quiet",
    "--solvers",
    "parallel-weighted",
    "--trials",
    "3",
    "--identify-trials",
    "0",
    "--no-supports",
];

fn validate(dir: &Path, args: &[&str]) {
    layout_opt()
        .arg("validate")
        .args(CHEAP)
        .args(args)
        .arg("--out")
        .arg(dir)
        .assert()
        .success();
}

fn summary_without_command(dir: &Path) -> serde_json::Value {
    let mut summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("summary.json")).unwrap()).unwrap();
    summary["header"]["command"] = serde_json::Value::Null;
    summary
}

/// `scenarios.csv` of this grid, as written by the release before the
/// working volume existed (commit afb6c3c), byte for byte: the grid form
/// changes no number. With the supports counted, as then.
#[test]
fn range_flags_alone_and_samples_grid_reproduce_the_grid_before_the_volume() {
    let pinned = include_str!("fixtures/validate_grid_scenarios.csv");
    let grid = [
        "--depth",
        "300,600",
        "--offset-x",
        "0,40",
        "--tilt",
        "-30,30",
        "--pan",
        "0,15",
        "--seed",
        "5",
    ];
    for extra in [&[][..], &["--samples", "grid"][..]] {
        let dir = tempfile::tempdir().unwrap();
        layout_opt()
            .args([
                "validate",
                "--quiet",
                "--solvers",
                "parallel-weighted",
                "--trials",
                "3",
                "--identify-trials",
                "0",
            ])
            .args(grid)
            .args(extra)
            .arg("--out")
            .arg(dir.path())
            .assert()
            .success();
        let written = std::fs::read_to_string(dir.path().join("scenarios.csv")).unwrap();
        assert!(written == pinned, "{extra:?}: scenarios.csv changed");
    }
}

const FLAGS: [&str; 16] = [
    "--samples",
    "24",
    "--depth",
    "300..800",
    "--offset-x",
    "0..60",
    "--offset-y",
    "-30..30",
    "--view-cone",
    "50",
    "--roll",
    "-20..20",
    "--noise",
    "0.5",
    "--seed",
    "4",
];

const YAML: &str = "\
depth_mm: [300, 800]
placement:
  offsets: {x_mm: [0, 60], y_mm: [-30, 30]}
orientation:
  view_cone: {half_angle_deg: 50, roll_deg: [-20, 20]}
sigma_px: 0.5
samples: 24
";

const JSON: &str = r#"{
  "depth_mm": [300, 800],
  "placement": {"offsets": {"x_mm": [0, 60], "y_mm": [-30, 30]}},
  "orientation": {"view_cone": {"half_angle_deg": 50, "roll_deg": [-20, 20]}},
  "sigma_px": [0.5, 0.5],
  "samples": 8
}"#;

/// The same volume by flags, by a YAML file and by a JSON file (whose
/// sample count `--samples` overrides) gives the same summary and the same
/// scenarios, and the report names the volume and writes the pairwise
/// page and the worst viewpoints.
#[test]
fn a_volume_file_and_the_same_flags_give_identical_reports() {
    let dir = tempfile::tempdir().unwrap();
    let by_flags = dir.path().join("flags");
    validate(&by_flags, &FLAGS);
    let yaml = dir.path().join("volume.yaml");
    std::fs::write(&yaml, YAML).unwrap();
    let json = dir.path().join("volume.json");
    std::fs::write(&json, JSON).unwrap();
    let by_yaml = dir.path().join("yaml");
    validate(
        &by_yaml,
        &["--volume", yaml.to_str().unwrap(), "--seed", "4"],
    );
    let by_json = dir.path().join("json");
    validate(
        &by_json,
        &[
            "--volume",
            json.to_str().unwrap(),
            "--samples",
            "24",
            "--seed",
            "4",
        ],
    );
    let expected = summary_without_command(&by_flags);
    assert_eq!(expected["visibility"]["scenarios"], 24);
    for other in [&by_yaml, &by_json] {
        assert_eq!(summary_without_command(other), expected, "{other:?}");
        assert_eq!(
            std::fs::read_to_string(other.join("scenarios.csv")).unwrap(),
            std::fs::read_to_string(by_flags.join("scenarios.csv")).unwrap()
        );
    }
    let report = std::fs::read_to_string(by_flags.join("report.md")).unwrap();
    assert!(
        report.contains("24 scrambled Sobol viewpoints (seed 4): depth 300…800 mm, x offset 0…60 mm, y offset -30…30 mm, face within 50° of the line of sight, roll -20…20° about it, σ 0.5 px"),
        "{report}"
    );
    // Six axes vary (depth, both offsets, and the three angles the cone
    // and roll turn into): 15 panels, and up to ten worst viewpoints.
    assert_eq!(expected["pairs"]["panels"].as_array().unwrap().len(), 15);
    let svg = std::fs::read_to_string(by_flags.join("error_pairs.svg")).unwrap();
    assert_eq!(svg.matches(r#"fill="none" stroke="black""#).count(), 15);
    let worst = expected["worst"].as_array().unwrap();
    assert!(!worst.is_empty() && worst.len() <= 10);
    let rms: Vec<f64> = worst
        .iter()
        .map(|w| w["rms_rotation_deg"].as_f64().unwrap())
        .collect();
    assert!(rms.windows(2).all(|w| w[0] >= w[1]), "{rms:?}");
    assert!(by_flags.join("worst_viewpoints.csv").exists());
}

/// Each bad volume is refused, naming its flag, before any report exists.
#[test]
fn bad_volumes_are_refused_before_any_work() {
    let cases: [(&[&str], &str); 6] = [
        (
            &["--view-cone", "95"],
            "--view-cone must be a half-angle from 0° to at most 90°, got 95°",
        ),
        (
            &["--samples", "16", "--depth", "1000..200"],
            "--depth is an inverted range 1000..200",
        ),
        (&["--samples", "0"], "--samples is 0"),
        (
            &["--samples", "8", "--offset-x", "5000"],
            "no viewpoint of it has every sphere of",
        ),
        (&["--placement-cone", "90"], "--placement-cone must be"),
        (
            &["--samples", "grid", "--view-cone", "30"],
            "--samples grid",
        ),
    ];
    for (args, message) in cases {
        for command in ["validate", "search"] {
            let dir = tempfile::tempdir().unwrap();
            let out = dir.path().join("out");
            let mut cmd = layout_opt();
            cmd.args([command, "--quiet"]).args(args);
            if command == "validate" {
                cmd.arg("--out").arg(&out);
            } else {
                cmd.arg("--out").arg(out.join("x.json"));
            }
            cmd.assert()
                .failure()
                .stderr(predicate::str::contains(message));
            assert!(!out.exists(), "{command} {args:?} wrote {out:?}");
        }
    }
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("v.json");
    std::fs::write(&file, r#"{"depth_mm": [300, 800]}"#).unwrap();
    layout_opt()
        .args(["validate", "--quiet", "--volume"])
        .arg(&file)
        .assert()
        .failure()
        .stderr(
            predicate::str::contains("malformed volume file")
                .and(predicate::str::contains("missing field `placement`")),
        );
}
