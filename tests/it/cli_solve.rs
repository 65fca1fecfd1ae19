//! `layout-opt solve` end to end: the batch contract, errors on stderr, and
//! exit statuses.

use assert_cmd::Command;
use predicates::prelude::*;

fn layout_opt() -> Command {
    Command::cargo_bin("layout-opt").unwrap()
}

#[test]
fn list_prints_every_stable_name() {
    let assert = layout_opt().args(["solve", "--list"]).assert().success();
    let out = String::from_utf8(assert.get_output().stdout.clone()).unwrap();
    for &solver in layout_opt::pnp::Solver::ALL {
        assert!(out.contains(solver.name()), "missing {solver}");
    }
}

#[test]
fn default_run_solves_the_demo_batch_with_every_solver() {
    for &solver in layout_opt::pnp::Solver::ALL {
        let assert = layout_opt()
            .args(["solve", "--quiet", "--solver", solver.name()])
            .assert()
            .success()
            .stderr(predicate::str::contains("solved 5 of 5 problems"));
        let output: serde_json::Value =
            serde_json::from_slice(&assert.get_output().stdout).unwrap();
        assert_eq!(output["solver"], solver.name());
        for result in output["results"].as_array().unwrap() {
            assert!(result["error"].is_null(), "{solver}: {result}");
            let rms = result["reprojection_rms_px"].as_f64().unwrap();
            // A sanity bound only (DLT on 7 points at 1 m is ~2.6 px at σ 0.5):
            // accuracy is judged in tests/it/noisy.rs.
            assert!(rms.is_finite() && rms < 10.0, "{solver}: rms {rms}");
            assert!(result["seconds"].as_f64().unwrap() > 0.0);
            let rotation = result["rotation"].as_array().unwrap();
            assert_eq!(rotation.len(), 3);
        }
    }
}

#[test]
fn example_file_writes_output_with_error_entries() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("poses.json");
    layout_opt()
        .args([
            "solve",
            "--problems",
            "examples/shots.json",
            "--solver",
            "epnp",
            "--output",
        ])
        .arg(&out)
        .assert()
        .success()
        .stdout(predicate::str::contains("solved 3 of 4 problems"));
    let output: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
    let results = output["results"].as_array().unwrap();
    assert_eq!(results[3]["id"], "shot-bad");
    assert_eq!(results[3]["error"], "EPnP needs at least 4 points, got 3");
}

#[test]
fn malformed_file_is_a_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("bad.json");
    std::fs::write(&bad, "{ \"camera\": ").unwrap();
    layout_opt()
        .args(["solve", "--problems"])
        .arg(&bad)
        .assert()
        .failure()
        .stderr(
            predicate::str::starts_with("Error: in ")
                .and(predicate::str::contains("malformed problem file")),
        );
    std::fs::write(
        &bad,
        r#"{"camera": {"fx": -5, "fy": 1, "cx": 0, "cy": 0}, "problems": []}"#,
    )
    .unwrap();
    layout_opt()
        .args(["solve", "--problems"])
        .arg(&bad)
        .assert()
        .failure()
        .stderr(predicate::str::contains(
            "focal lengths must lie between 1 and 1e8 px",
        ));
    layout_opt()
        .args(["solve", "--problems", "/nonexistent/shots.json"])
        .assert()
        .failure()
        .stderr(predicate::str::contains("cannot read problem file"));
    layout_opt()
        .args(["solve", "--solver", "nope"])
        .assert()
        .failure()
        .stderr(predicate::str::contains("unknown solver 'nope'"));
}
