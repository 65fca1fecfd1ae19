//! `validate --fabrication-sigma`: a Monte-Carlo run with a new perturbed
//! part per trial beside the first-order model; σ = 0 changes nothing.

use assert_cmd::Command;
use std::path::Path;

fn layout_opt() -> Command {
    Command::cargo_bin("layout-opt").unwrap()
}

/// A small validate run into `dir` with extra flags; its stdout.
fn validate(dir: &Path, extra: &[&str]) -> String {
    let output = layout_opt()
        .args([
            "validate",
            "--quiet",
            "--trials",
            "300",
            "--depth",
            "300,600",
            "--tilt",
            "-40,-30,-20,20,30,40",
            "--solvers",
            "ml",
            // Identifiability is not what these runs compare.
            "--identify-trials",
            "0",
            "--out",
        ])
        .arg(dir)
        .args(extra)
        .assert()
        .success()
        .get_output()
        .stdout
        .clone();
    String::from_utf8(output).unwrap()
}

/// summary.json without the command line, and scenarios.csv.
fn report(dir: &Path) -> (String, Vec<u8>) {
    let text = std::fs::read_to_string(dir.join("summary.json")).unwrap();
    let mut summary: serde_json::Value = serde_json::from_str(&text).unwrap();
    summary["header"]["command"].take();
    (
        serde_json::to_string(&summary).unwrap(),
        std::fs::read(dir.join("scenarios.csv")).unwrap(),
    )
}

#[test]
fn zero_sigma_changes_nothing_and_a_part_per_trial_matches_the_first_order_model() {
    let plain = tempfile::tempdir().unwrap();
    let zero = tempfile::tempdir().unwrap();
    let some = tempfile::tempdir().unwrap();
    let plain_out = validate(plain.path(), &[]);
    let zero_out = validate(zero.path(), &["--fabrication-sigma", "0"]);
    let some_out = validate(some.path(), &["--fabrication-sigma", "0.2"]);
    assert!(
        report(plain.path()) == report(zero.path()),
        "σ = 0 changed the report"
    );
    assert!(!plain_out.contains("fabrication") && !zero_out.contains("fabrication"));
    assert!(
        report(plain.path()) == report(some.path()),
        "the noise part changed"
    );
    let line = some_out
        .lines()
        .find(|l| l.starts_with("fabrication σ 0.2 mm"))
        .unwrap_or_else(|| panic!("{some_out}"));
    let ratio: f64 = line
        .rsplit_once("(ratio ")
        .and_then(|(_, r)| r.trim_end_matches(')').parse().ok())
        .unwrap_or_else(|| panic!("{line}"));
    assert!((0.85..1.15).contains(&ratio), "{line}");
}

#[test]
fn a_bad_fabrication_sigma_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    for bad in ["-0.1", "NaN", "inf"] {
        layout_opt()
            .args([
                "validate",
                "--quiet",
                "--trials",
                "1",
                "--fabrication-sigma",
                bad,
                "--out",
            ])
            .arg(dir.path())
            .assert()
            .failure()
            .stderr(predicates::str::contains(
                "--fabrication-sigma must be a finite number of millimetres ≥ 0",
            ));
    }
}
