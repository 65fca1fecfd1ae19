//! `layout-opt search` end to end: the report and layout it writes, the same
//! winner at any thread count, and clear errors for bad arguments. A small
//! grid and budget keep CI fast; the default run's figures are in README.

use assert_cmd::Command;
use predicates::prelude::*;
use std::path::Path;

fn layout_opt() -> Command {
    Command::cargo_bin("layout-opt").unwrap()
}

const SMALL: [&str; 12] = [
    "--depth",
    "300,800",
    "--offset-x",
    "0,60",
    "--tilt",
    "-40..40:20",
    "--starts",
    "2",
    "--compare-trials",
    "20",
    "--quiet",
    "--seed",
];

fn run_search(dir: &Path, threads: &str, extra: &[&str]) -> assert_cmd::assert::Assert {
    layout_opt()
        .arg("search")
        .args(SMALL)
        .arg("3")
        .args(["--threads", threads, "--name", "t"])
        .arg("--out")
        .arg(dir.join("t.json"))
        .arg("--report")
        .arg(dir.join("report"))
        .arg("--checkpoint-dir")
        .arg(dir.join("checkpoints"))
        .args(extra)
        .args(if extra.contains(&"--iterations") {
            &[][..]
        } else {
            &["--iterations", "150"][..]
        })
        // The winner's identifiability Monte-Carlo at the fewest trials,
        // unless the test asserts on it.
        .args(if extra.contains(&"--identify-trials") {
            &[][..]
        } else {
            &["--identify-trials", "2"][..]
        })
        .assert()
}

#[test]
fn search_writes_a_valid_layout_and_a_report() {
    let dir = tempfile::tempdir().unwrap();
    // Without an identifiability constraint (neither the monocular floor nor
    // the stereo distance rule, which is off by default) the paper's
    // biprism, the family's natural start, is admissible, so the search must
    // not lose it.
    run_search(dir.path(), "2", &["--min-identifiability", "none"])
        .success()
        .stdout(predicate::str::contains("paper-biprism"));
    let layout = layout_opt::layout::Layout::load(&dir.path().join("t.json")).unwrap();
    layout.validate().unwrap();
    let provenance = layout.provenance.unwrap();
    assert_eq!(provenance["seed"], 3);
    assert_eq!(provenance["status"], "finished");
    assert!(provenance["command"].as_str().unwrap().contains("search"));
    let report = std::fs::read_to_string(dir.path().join("report/report.md")).unwrap();
    for needle in [
        "## Designs on the same scenarios and draws",
        "seven-cube-corners",
        "tetrahedron-with-centre",
        "## Verdicts",
        "## Under every chain",
        "winner-validation/report.md",
    ] {
        assert!(report.contains(needle), "report.md lacks {needle:?}");
    }
    assert!(dir
        .path()
        .join("report/winner-validation/summary.json")
        .exists());
    let summary: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(dir.path().join("report/summary.json")).unwrap(),
    )
    .unwrap();
    let designs = summary["designs"].as_array().unwrap();
    assert_eq!(designs[0]["name"], "t");
    assert_eq!(designs[2]["name"], "paper-biprism");
    // The search never loses its (admissible) natural start.
    let winner = designs[0]["evaluation"]["cost"].as_f64().unwrap();
    let start = designs[1]["evaluation"]["objective"].as_f64().unwrap();
    assert!(
        winner <= start + 1e-12,
        "winner {winner} worse than its start {start}"
    );
    assert!(summary["verdicts"]["winner_feasible"].as_bool().unwrap());
    // The winner and the paper's biprism under every chain: the printed
    // part adds error to both; the ideal chain scores the search's own
    // objective, so the winner's accuracy there is its design row's.
    let chains = summary["chains"].as_array().unwrap();
    let kinds: Vec<&str> = chains
        .iter()
        .map(|c| c["chain"]["kind"].as_str().unwrap())
        .collect();
    assert_eq!(kinds, ["ideal", "printed", "characterised"]);
    let rotation = |k: usize, who: &str| chains[k][who].as_f64().unwrap();
    for who in ["winner_rotation_deg", "paper_rotation_deg"] {
        assert!(rotation(1, who) > rotation(2, who), "{chains:?}");
    }
    let ideal_accuracy = chains[0]["winner_accuracy"].as_f64().unwrap();
    let design_accuracy = designs[0]["evaluation"]["accuracy"].as_f64().unwrap();
    assert!(
        (ideal_accuracy - design_accuracy).abs() < 1e-9,
        "{ideal_accuracy} vs {design_accuracy}"
    );
    // The report leads with the answer, from the summary's figures: the
    // winner, its availability against the paper's biprism's, the command
    // and the layout file, all before the provenance table.
    let lead = report
        .split("| | |")
        .next()
        .unwrap()
        .split_once('\n')
        .unwrap()
        .1;
    let availability =
        |k: usize| 100.0 * designs[k]["evaluation"]["availability"].as_f64().unwrap();
    let layout_file = dir.path().join("t.json").display().to_string();
    for needle in [
        "**Answer.** The search's winner is `t` (7 spheres",
        "Against the paper's biprism (`paper-biprism`)",
        "first-order error ",
        &format!(
            "{:.1}% of the scenarios against {:.1}%",
            availability(0),
            availability(2)
        ),
        "- **command**: `layout-opt search",
        &format!("- **layout file**: `{layout_file}`"),
    ] {
        assert!(
            lead.contains(needle),
            "the report's lead lacks {needle:?}:\n{lead}"
        );
    }
}

#[test]
fn the_winner_does_not_depend_on_the_thread_count() {
    let one = tempfile::tempdir().unwrap();
    let two = tempfile::tempdir().unwrap();
    run_search(one.path(), "1", &[]).success();
    run_search(two.path(), "2", &[]).success();
    let points = |dir: &Path| {
        let layout = layout_opt::layout::Layout::load(&dir.join("t.json")).unwrap();
        layout.points.iter().map(|p| p.position).collect::<Vec<_>>()
    };
    assert_eq!(points(one.path()), points(two.path()));
}

#[test]
fn every_family_and_optimiser_runs() {
    for extra in [
        &[
            "--family",
            "tetrahedron",
            "--optimiser",
            "pso",
            "--particles",
            "8",
            "--iterations",
            "20",
            "--polish",
            "100",
            // A regular tetrahedron is symmetric: its identifiability
            // repair (3.5 s, tested on its own) is not what this checks.
            "--min-identifiability",
            "none",
        ][..],
        &[
            "--family",
            "custom",
            "--points",
            "6",
            "--optimiser",
            "annealing",
            "--iterations",
            "100",
            "--polish",
            "100",
        ][..],
        &[
            "--family",
            "biprism",
            "--no-tilts",
            "--no-centre",
            "--iterations",
            "1000",
        ][..],
        &["--objective", "transfer", "--aggregate", "max"][..],
        &[
            "--objective",
            "crlb:0.5+mc:parallel-weighted:0.5",
            "--trials",
            "3",
            "--iterations",
            "20",
        ][..],
    ] {
        let dir = tempfile::tempdir().unwrap();
        run_search(dir.path(), "2", extra).success();
        layout_opt::layout::Layout::load(&dir.path().join("t.json"))
            .unwrap()
            .validate()
            .unwrap();
    }
}

#[test]
fn custom_search_keeps_fixed_points() {
    let dir = tempfile::tempdir().unwrap();
    let init = dir.path().join("init.json");
    std::fs::write(
        &init,
        r#"{"name": "seed", "points": [
            {"name": "A", "position": [0, 0, 0], "fixed": true},
            {"name": "B", "position": [40, 0, 0]},
            {"name": "C", "position": [0, 40, 0]},
            {"name": "D", "position": [0, 0, 40]},
            {"name": "E", "position": [-30, -30, 20], "fixed": true}]}"#,
    )
    .unwrap();
    run_search(
        dir.path(),
        "2",
        &[
            "--family",
            "custom",
            "--init",
            init.to_str().unwrap(),
            "--min-distance-diff",
            "0",
        ],
    )
    .success();
    let layout = layout_opt::layout::Layout::load(&dir.path().join("t.json")).unwrap();
    assert_eq!(layout.points[0].position, nalgebra::Vector3::zeros());
    assert_eq!(
        layout.points[4].position,
        nalgebra::Vector3::new(-30.0, -30.0, 20.0)
    );
    assert!(layout.points[0].fixed && layout.points[4].fixed);
}

#[test]
fn bad_arguments_are_clear_errors() {
    for (args, message) in [
        (&["--depth", "500..100:0"][..], "the step must be positive"),
        (
            &["--tilt", "-200..200:10"][..],
            "tilt must be within −180…180°",
        ),
        (&["--depth", "0"][..], "depth must be positive"),
        (&["--envelope", "5"][..], "smaller than one sphere"),
        (
            &["--family", "custom", "--points", "3"][..],
            "at least 4 points, got 3",
        ),
        (&["--objective", "fast"][..], "unknown objective"),
        (&["--envelope", "1,2"][..], "cannot parse envelope"),
        (&["--iterations", "0"][..], "iterations must be at least 1"),
        (
            &["--start-jitter", "2"][..],
            "start jitter must be a fraction",
        ),
    ] {
        // In a directory of its own: a refused run must leave nothing in
        // its working directory (no checkpoint directory).
        let cwd = tempfile::tempdir().unwrap();
        layout_opt()
            .current_dir(cwd.path())
            .arg("search")
            .args(args)
            .args(["--quiet", "--out", "/nonexistent-dir-for-test/x.json"])
            .assert()
            .failure()
            .stderr(predicate::str::contains(message));
        assert_eq!(
            std::fs::read_dir(cwd.path()).unwrap().count(),
            0,
            "{args:?}"
        );
    }
    // Constraints that cannot all be met: a biprism of seven 30 mm spheres
    // with 20 mm gaps does not fit a 60 mm box (its arms would have to
    // reach 50 mm from the centre along the box's diagonals).
    let dir = tempfile::tempdir().unwrap();
    layout_opt()
        .arg("search")
        .args([
            "--quiet",
            "--envelope",
            "60",
            "--sphere-diameter",
            "30",
            "--min-gap",
            "20",
            "--iterations",
            "50",
            "--starts",
            "1",
            "--depth",
            "500",
            "--tilt",
            "0",
        ])
        .arg("--out")
        .arg(dir.path().join("x.json"))
        .arg("--report")
        .arg(dir.path().join("r"))
        .assert()
        .failure()
        .stderr(
            // Which constraint the best layout still breaks depends on the
            // optimiser's path; the message must name one with its figure.
            predicate::str::contains("cannot all be met").and(
                predicate::str::contains("smallest gap").or(predicate::str::contains(
                    "outside the [60.0, 60.0, 60.0] mm envelope by",
                )),
            ),
        );
}

#[test]
fn resume_refuses_a_stale_checkpoint_and_export_writes_the_winner() {
    let dir = tempfile::tempdir().unwrap();
    // Nothing to resume: says so and runs; a finished run leaves no checkpoints.
    let export_dir = dir.path().join("meshes");
    run_search(
        dir.path(),
        "2",
        &[
            "--resume",
            "--export",
            "stl,obj",
            "--export-dir",
            export_dir.to_str().unwrap(),
        ],
    )
    .success()
    .stderr(predicate::str::contains("starting afresh"))
    .stdout(predicate::str::contains("exported"));
    let checkpoints = dir.path().join("checkpoints");
    assert_eq!(std::fs::read_dir(&checkpoints).unwrap().count(), 0);
    let (models, _) = tobj::load_obj(export_dir.join("t.obj"), &tobj::GPU_LOAD_OPTIONS).unwrap();
    assert!(!models.is_empty() && !models[0].mesh.indices.is_empty());
    assert!(std::fs::metadata(export_dir.join("t.stl")).unwrap().len() > 84);

    // A checkpoint of another configuration under the same name is refused,
    // naming what differs, and left alone.
    let stale = checkpoints.join("t-0123456789abcdef");
    std::fs::create_dir_all(&stale).unwrap();
    std::fs::write(
        stale.join("config.json"),
        r#"{"search": {"seed": 99}, "version": "0.0.0"}"#,
    )
    .unwrap();
    run_search(dir.path(), "2", &["--resume"])
        .failure()
        .stderr(predicate::str::contains("different search configuration"))
        .stderr(predicate::str::contains("search"))
        .stderr(predicate::str::contains("Rerun without --resume"));
    assert!(stale.join("config.json").exists());
}

#[test]
fn out_elsewhere_puts_the_report_beside_the_layout() {
    // The working directory stands in for a checkout: a search whose --out
    // points elsewhere must write nothing under its reports/ or layouts/.
    let checkout = tempfile::tempdir().unwrap();
    let elsewhere = tempfile::tempdir().unwrap();
    let out = elsewhere.path().join("marker.json");
    layout_opt()
        .current_dir(checkout.path())
        .arg("search")
        .args(SMALL)
        .arg("3")
        .args(["--iterations", "100"])
        .arg("--out")
        .arg(&out)
        .assert()
        .success()
        .stdout(predicate::str::contains("marker-report"));
    assert!(out.exists());
    assert!(elsewhere.path().join("marker-report/report.md").exists());
    assert!(elsewhere
        .path()
        .join("marker-report/winner-validation/summary.json")
        .exists());
    assert!(!checkout.path().join("reports").exists());
    assert!(!checkout.path().join("layouts").exists());
}

#[test]
fn front_writes_members_that_meet_the_constraints_and_rank_the_hand_designs() {
    let dir = tempfile::tempdir().unwrap();
    // The stereo rule, so that the symmetric hand designs have admissible
    // versions.
    run_search(
        dir.path(),
        "2",
        &["--front", "--front-levels", "2", "--min-distance-diff", "1"],
    )
    .success()
    .stdout(predicate::str::contains("Pareto front"));
    let front: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(dir.path().join("report/front.json")).unwrap(),
    )
    .unwrap();
    assert!(dir.path().join("report/front.csv").exists());
    assert!(dir.path().join("report/front.svg").exists());
    let members = front["members"].as_array().unwrap();
    assert!(!members.is_empty());
    let constraints = layout_opt::family::Constraints {
        envelope: layout_opt::family::Envelope::new([100.0; 3]).unwrap(),
        sphere_diameter_mm: 10.0,
        min_gap_mm: 2.0,
        min_distance_diff_mm: 1.0,
    };
    let mut last = f64::NEG_INFINITY;
    for member in members {
        let path = Path::new(member["layout"].as_str().unwrap());
        // Beside the winner's layout file, in <name>-front/.
        assert_eq!(path.parent().unwrap(), dir.path().join("t-front"));
        let layout = layout_opt::layout::Layout::load(path).unwrap();
        assert!(constraints.violations(&layout.positions()).feasible());
        let availability = member["availability"].as_f64().unwrap();
        assert!(
            availability >= last,
            "members are not in availability order"
        );
        last = availability;
        assert!(member["rotation_rms_deg"].as_f64().unwrap() > 0.0);
        assert!(member["translation_rms_mm"].as_f64().unwrap() > 0.0);
    }
    // Non-dominated: along increasing availability, accuracy only worsens.
    let accuracy: Vec<f64> = members
        .iter()
        .map(|m| m["accuracy"].as_f64().unwrap())
        .collect();
    assert!(accuracy.windows(2).all(|w| w[1] > w[0]), "{accuracy:?}");
    let hand = front["hand_designs"].as_array().unwrap();
    assert!(hand.iter().any(|h| h["name"] == "paper-biprism"));
    assert!(hand.iter().any(|h| h["name"] == "paper-biprism-admissible"));
    let report = std::fs::read_to_string(dir.path().join("report/report.md")).unwrap();
    assert!(report.contains("## Pareto front"));
    assert!(report.contains("availability floor"));
}

/// With the default identifiability floor the winner is identifiable in
/// every visible scenario of the grid (99.9% of 20 allows no failure),
/// while the symmetric paper biprism is identifiable in none; the report
/// says so for each design.
#[test]
fn the_winner_meets_the_identifiability_floor_and_the_report_says_where_designs_fail() {
    let dir = tempfile::tempdir().unwrap();
    run_search(dir.path(), "2", &["--identify-trials", "10"])
        .success()
        .stdout(predicate::str::contains("identifiability floor 99.9%"));
    let summary: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(dir.path().join("report/summary.json")).unwrap(),
    )
    .unwrap();
    assert_eq!(
        summary["verdicts"]["winner_meets_identifiability_floor"],
        true
    );
    let designs = summary["designs"].as_array().unwrap();
    let winner = &designs[0]["evaluation"]["identifiability"];
    assert_eq!(winner["all_checked"], true);
    assert_eq!(winner["failing"].as_array().unwrap().len(), 0);
    assert_eq!(winner["identifiable"], winner["checked"]);
    let paper = &designs[2];
    assert_eq!(paper["name"], "paper-biprism");
    assert_eq!(paper["evaluation"]["identifiability"]["identifiable"], 0);
    assert!(paper["not_identifiable"]
        .as_str()
        .unwrap()
        .contains("symmetric"));
    // Not identifiable, so not an admissible alternative.
    let admissible = summary["verdicts"]["admissible_hand_designs"]
        .as_array()
        .unwrap();
    assert!(!admissible.iter().any(|n| n == "paper-biprism"));
    let report = std::fs::read_to_string(dir.path().join("report/report.md")).unwrap();
    assert!(report.contains("## Identifiability from one image"));
    let validation: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(dir.path().join("report/winner-validation/summary.json")).unwrap(),
    )
    .unwrap();
    assert_eq!(validation["identifiability"]["trials_per_scenario"], 10);
}
