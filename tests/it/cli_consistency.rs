//! The command line's consistency: every error said once and naming its
//! file or flag, ranges read one way in every form, negative values after a
//! flag, degenerate values refused with the reason, visibility counts that
//! add up, and default output directories that never overwrite the
//! committed reference reports with a smaller run.

use assert_cmd::Command;
use predicates::prelude::*;
use std::path::Path;

fn layout_opt() -> Command {
    Command::cargo_bin("layout-opt").unwrap()
}

fn stderr_of(assert: assert_cmd::assert::Assert) -> String {
    String::from_utf8(assert.get_output().stderr.clone()).unwrap()
}

/// A small, fast validate run into `out` with extra flags.
fn small_validate(out: &Path, extra: &[&str]) -> assert_cmd::assert::Assert {
    layout_opt()
        .args([
            "validate",
            "--quiet",
            "--solvers",
            "parallel",
            "--trials",
            "2",
            "--offset-x",
            "0",
            "--tilt",
            "0",
            "--identify-trials",
            "0",
        ])
        .args(extra)
        .arg("--out")
        .arg(out)
        .assert()
}

fn summary(dir: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(dir.join("summary.json")).unwrap()).unwrap()
}

#[test]
fn a_missing_file_is_named_and_its_cause_said_once() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("no-such-layout.json");
    let shown = missing.display().to_string();
    for command in ["validate", "export"] {
        let stderr = stderr_of(layout_opt().arg(command).arg(&missing).assert().failure());
        assert!(stderr.contains(&shown), "{command}: {stderr}");
        assert_eq!(
            stderr.matches("No such file or directory").count(),
            1,
            "{command}: {stderr}"
        );
        assert_eq!(stderr.lines().count(), 1, "{command}: {stderr}");
    }
    let camera = dir.path().join("no-such-camera.json");
    let stderr = stderr_of(
        layout_opt()
            .args(["validate", "--camera"])
            .arg(&camera)
            .assert()
            .failure(),
    );
    assert!(stderr.contains(&camera.display().to_string()), "{stderr}");
    assert_eq!(
        stderr.matches("No such file or directory").count(),
        1,
        "{stderr}"
    );
}

#[test]
fn a_malformed_export_input_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("bad-layout.json");
    std::fs::write(&bad, "{\"units\": \"mm\"}").unwrap();
    let stderr = stderr_of(
        layout_opt()
            .arg("export")
            .arg(&bad)
            .arg("--out")
            .arg(dir.path().join("out"))
            .assert()
            .failure(),
    );
    assert!(stderr.contains(&bad.display().to_string()), "{stderr}");
    assert!(stderr.contains("malformed layout"), "{stderr}");
}

#[test]
fn descending_ranges_mean_the_same_in_both_forms() {
    let stepped = tempfile::tempdir().unwrap();
    let five = tempfile::tempdir().unwrap();
    small_validate(stepped.path(), &["--depth", "1000..200:200"]).success();
    small_validate(five.path(), &["--depth", "1000..200"]).success();
    let depths = |dir: &Path| summary(dir)["header"]["grid"]["depth_mm"]["values"].clone();
    assert_eq!(
        depths(stepped.path()),
        serde_json::json!([1000.0, 800.0, 600.0, 400.0, 200.0])
    );
    assert_eq!(depths(stepped.path()), depths(five.path()));
}

#[test]
fn angles_outside_their_domain_are_refused() {
    for (flag, range) in [
        ("--tilt", "-200..200:10"),
        ("--pan", "190"),
        ("--roll", "-181"),
    ] {
        layout_opt()
            .args(["validate", "--quiet", flag, range])
            .assert()
            .failure()
            .stderr(predicate::str::contains("must be within −180…180°"));
    }
}

#[test]
fn negative_values_follow_their_flag() {
    // A negative number after a flag is its value, checked for its domain,
    // never "unexpected argument '-1'".
    for args in [
        &["validate", "--gross-threshold", "-1"][..],
        &["search", "--translation-weight", "-1"][..],
        &["export", "--strut-diameter", "-2"][..],
    ] {
        let stderr = stderr_of(layout_opt().args(args).assert().failure());
        assert!(
            !stderr.contains("unexpected argument"),
            "{args:?}: {stderr}"
        );
        assert!(
            stderr.contains(args[1]) || stderr.contains("strut"),
            "{args:?}: {stderr}"
        );
    }
    let dir = tempfile::tempdir().unwrap();
    small_validate(dir.path(), &["--offset-y", "-20", "--depth", "500"]).success();
    assert_eq!(
        summary(dir.path())["header"]["grid"]["offset_y_mm"]["values"],
        serde_json::json!([-20.0])
    );
}

#[test]
fn degenerate_values_are_refused_with_the_reason() {
    for (args, message) in [
        (&["search", "--noise", "0"][..], "search needs σ > 0 px"),
        (
            &["search", "--availability-weight", "inf"][..],
            "--availability-weight must be finite, got inf",
        ),
        (
            &["search", "--translation-weight", "NaN"][..],
            "--translation-weight must be finite",
        ),
        (
            &["--threads", "100000", "validate"][..],
            "cores of this machine",
        ),
        (
            &["validate", "--gross-threshold", "inf"][..],
            "--gross-threshold must be",
        ),
    ] {
        layout_opt()
            .args(args)
            .args(["--quiet"])
            .assert()
            .failure()
            .stderr(predicate::str::contains(message));
    }
}

#[test]
fn visibility_counts_are_a_partition_and_every_occlusion_is_listed() {
    let dir = tempfile::tempdir().unwrap();
    let assert = layout_opt()
        .args([
            "validate",
            "--quiet",
            "--solvers",
            "parallel,parallel-weighted",
            "--trials",
            "2",
            "--depth",
            "200..1000:400",
            "--tilt",
            "-90..90:15",
            "--identify-trials",
            "0",
            "--out",
        ])
        .arg(dir.path())
        .assert()
        .success();
    let v = &summary(dir.path())["visibility"];
    let count = |key: &str| v[key].as_u64().unwrap();
    // validate counts the part's supports by default: a scenario they hide
    // a sphere in is a class of its own.
    assert_eq!(
        count("visible")
            + count("occluded")
            + count("outside_image")
            + count("behind_camera")
            + count("hidden_by_support"),
        count("scenarios")
    );
    assert!(count("occluded") > 0 && count("outside_image") > 0, "{v}");
    assert!(count("with_occlusion") >= count("occluded"));
    let csv = std::fs::read_to_string(dir.path().join("occlusions.csv")).unwrap();
    assert_eq!(csv.lines().count() as u64, 1 + count("with_occlusion"));
    let report = std::fs::read_to_string(dir.path().join("report.md")).unwrap();
    assert!(report.contains("Visibility by tilt (deg)"), "{report}");
    assert!(report.contains("Visibility by depth (mm)"), "{report}");
    // The console table's rows end in the same column.
    let stdout = String::from_utf8(assert.get_output().stdout.clone()).unwrap();
    let rows: Vec<usize> = stdout
        .lines()
        .skip_while(|l| !l.starts_with("solver"))
        .take(3)
        .map(|l| l.chars().count())
        .collect();
    assert_eq!(rows.len(), 3, "{stdout}");
    assert!(rows.iter().all(|&r| r == rows[0]), "{stdout}");
}

#[test]
fn reproduce_subsets_never_write_into_reports_paper() {
    // `--quick` alone is checked by the reproduce module's quick run, which
    // also runs in a temporary working directory.
    let checkout = tempfile::tempdir().unwrap();
    layout_opt()
        .current_dir(checkout.path())
        .args([
            "reproduce",
            "--quiet",
            "--experiment",
            "off-axis",
            "--trials",
            "3",
        ])
        .assert()
        .success()
        .stdout(predicate::str::contains(
            "reports/paper-trials-3-off-axis/report.md",
        ));
    assert!(checkout
        .path()
        .join("reports/paper-trials-3-off-axis/report.md")
        .is_file());
    assert!(!checkout.path().join("reports/paper").exists());
}

#[test]
fn a_search_with_nothing_visible_says_not_measurable_never_nan() {
    // 60 mm spheres on a 100 mm envelope always hide one another.
    let dir = tempfile::tempdir().unwrap();
    let assert = layout_opt()
        .args([
            "search",
            "--quiet",
            "--sphere-diameter",
            "60",
            "--starts",
            "2",
            "--iterations",
            "150",
            "--depth",
            "400,800",
            "--tilt",
            "0,30",
            "--offset-x",
            "0",
            "--compare-trials",
            "5",
            "--validate-solvers",
            "parallel",
            "--checkpoint-dir",
        ])
        .arg(dir.path().join("checkpoints"))
        .arg("--out")
        .arg(dir.path().join("x.json"))
        .assert()
        .success();
    let stdout = String::from_utf8(assert.get_output().stdout.clone()).unwrap();
    assert!(!stdout.contains("NaN"), "{stdout}");
    assert!(stdout.contains("RMS rotation not measurable"), "{stdout}");
    assert!(
        stdout.contains("no scenario of the grid shows every sphere"),
        "{stdout}"
    );
    let report = std::fs::read_to_string(dir.path().join("x-report/report.md")).unwrap();
    assert!(!report.contains("NaN"));
    assert!(report.contains("not measurable"), "{report}");
}
