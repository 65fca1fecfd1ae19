//! `validate`'s error budget: `--fabrication-sigma` and `--camera-sigma`
//! add the part and the camera to the image noise, first order beside a
//! Monte-Carlo run with a new part and camera per trial, in report.md,
//! summary.json and the terminal, under `--noise-model`; σ = 0 changes
//! nothing.

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

/// summary.json without the command line and the error budget, the
/// budget, and scenarios.csv.
fn report(dir: &Path) -> (String, serde_json::Value, Vec<u8>) {
    let text = std::fs::read_to_string(dir.join("summary.json")).unwrap();
    let mut summary: serde_json::Value = serde_json::from_str(&text).unwrap();
    summary["header"]["command"].take();
    let budget = summary
        .as_object_mut()
        .unwrap()
        .remove("error_budget")
        .unwrap_or(serde_json::Value::Null);
    (
        serde_json::to_string(&summary).unwrap(),
        budget,
        std::fs::read(dir.join("scenarios.csv")).unwrap(),
    )
}

/// The budget's total, Monte-Carlo over first order.
fn total_ratio(budget: &serde_json::Value) -> f64 {
    budget["monte_carlo"]["total_deg"].as_f64().unwrap()
        / budget["first_order"]["total_deg"].as_f64().unwrap()
}

#[test]
fn zero_sigma_changes_nothing_and_the_budget_matches_its_monte_carlo() {
    let plain = tempfile::tempdir().unwrap();
    let zero = tempfile::tempdir().unwrap();
    let some = tempfile::tempdir().unwrap();
    let plain_out = validate(plain.path(), &[]);
    let zero_out = validate(zero.path(), &["--fabrication-sigma", "0"]);
    let some_out = validate(
        some.path(),
        &[
            "--fabrication-sigma",
            "0.2",
            "--camera-sigma",
            "fx=2,cx=0.5",
        ],
    );
    let (plain_report, plain_budget, plain_csv) = report(plain.path());
    assert!(
        (
            plain_report.clone(),
            plain_budget.clone(),
            plain_csv.clone()
        ) == report(zero.path()),
        "σ = 0 changed the report"
    );
    assert!(plain_budget.is_null());
    assert!(!plain_out.contains("error budget") && !zero_out.contains("error budget"));
    let (some_report, budget, some_csv) = report(some.path());
    assert!(
        plain_report == some_report && plain_csv == some_csv,
        "the noise part changed"
    );
    assert!(some_out.contains("error budget"), "{some_out}");
    let markdown = std::fs::read_to_string(some.path().join("report.md")).unwrap();
    assert!(markdown.contains("## Error budget"), "{markdown}");
    let first = &budget["first_order"];
    for source in ["noise_deg", "part_deg", "camera_deg"] {
        assert!(first[source].as_f64().unwrap() > 0.0, "{source}: {budget}");
    }
    assert_eq!(budget["by_depth"].as_array().unwrap().len(), 2, "{budget}");
    let ratio = total_ratio(&budget);
    assert!((0.9..1.1).contains(&ratio), "{budget}");
}

/// The budget's noise is the run's `--noise-model`: a law that grows on
/// small discs gives another noise term than the isotropic default.
#[test]
fn the_budget_honours_the_noise_model() {
    let isotropic = tempfile::tempdir().unwrap();
    let sized = tempfile::tempdir().unwrap();
    validate(isotropic.path(), &["--fabrication-sigma", "0.05"]);
    validate(
        sized.path(),
        &["--fabrication-sigma", "0.05", "--noise-model", "size:30"],
    );
    let (_, a, _) = report(isotropic.path());
    let (_, b, _) = report(sized.path());
    assert!(b["noise"].as_str().unwrap().contains("30 px"), "{b}");
    let (na, nb) = (
        a["first_order"]["noise_deg"].as_f64().unwrap(),
        b["first_order"]["noise_deg"].as_f64().unwrap(),
    );
    assert!(nb > 1.2 * na, "{na} against {nb}");
    assert!((0.9..1.1).contains(&total_ratio(&b)), "{b}");
}

#[test]
fn a_bad_camera_sigma_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    layout_opt()
        .args(["validate", "--quiet", "--camera-sigma", "k1=0.1", "--out"])
        .arg(dir.path())
        .assert()
        .failure()
        .stderr(predicates::str::contains("--camera-sigma"))
        .stderr(predicates::str::contains("unknown intrinsic 'k1'"));
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
