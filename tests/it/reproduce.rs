//! `layout-opt reproduce` end to end: the structure of the report, statistical
//! sanity of the curves, bit-identical CSVs for the same seed at different
//! thread counts, and clear errors for bad flags.

use assert_cmd::Command;
use predicates::prelude::*;
use std::collections::BTreeMap;
use std::path::Path;

fn layout_opt() -> Command {
    Command::cargo_bin("layout-opt").unwrap()
}

/// The experiment CSVs and the figures each must produce.
const EXPERIMENT_FILES: [(&str, &[&str]); 7] = [
    ("points.csv", &["fig7_points"]),
    (
        "noise.csv",
        &[
            "fig8_noise_n10",
            "fig9a_noise_biprism25",
            "fig9b_noise_biprism100",
        ],
    ),
    ("timing.csv", &[]),
    (
        "depth.csv",
        &[
            "fig11_depth_n10_far",
            "fig12_depth_n10_near",
            "fig13_depth_biprism_far",
            "fig14_depth_biprism_near",
        ],
    ),
    ("off_axis.csv", &["figS1_offaxis_200", "figS2_offaxis_100"]),
    ("tilt.csv", &["figS3_tilt"]),
    (
        "protocol.csv",
        &[
            "tables_protocol_offset0",
            "tables_protocol_offset50",
            "tables_protocol_offset100",
        ],
    ),
];

/// Runs `reproduce --quick` with `checkout` as the working directory and no
/// `--out`, and returns where it wrote: its default `reports/paper-quick/`,
/// never the reference run's `reports/paper/`.
///
/// It runs every experiment with the §4.2 camera (`--camera`), whose
/// errors stay in the linear regime the statistics checks assume; the
/// paper's own cameras (f = 80 and 500 px) are checked by the unit tests
/// of `Experiment::paper_camera`.
fn run_quick(checkout: &Path, threads: &str) -> std::path::PathBuf {
    let camera = checkout.join("camera-4.2.json");
    std::fs::write(
        &camera,
        r#"{"fx": 1301.473508, "fy": 1300.926193, "cx": 653, "cy": 508, "width": 1280, "height": 720}"#,
    )
    .unwrap();
    layout_opt()
        .current_dir(checkout)
        .args([
            "reproduce",
            "--quick",
            "--quiet",
            "--seed",
            "11",
            "--threads",
            threads,
            "--camera",
            camera.to_str().unwrap(),
        ])
        .assert()
        .success()
        .stdout(predicate::str::contains(
            "report in reports/paper-quick/report.md",
        ))
        .stdout(predicate::str::contains("protocol"));
    assert!(!checkout.join("reports/paper").exists());
    // The camera reached every experiment.
    let summary: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(checkout.join("reports/paper-quick/summary.json")).unwrap(),
    )
    .unwrap();
    assert_eq!(summary["header"]["camera_override"]["fx"], 1301.473508);
    for trials in summary["header"]["trials"].as_array().unwrap() {
        assert_eq!(trials["camera"]["fx"], 1301.473508, "{trials}");
    }
    checkout.join("reports/paper-quick")
}

/// Rows of a CSV as maps from column name to cell.
fn rows(path: &Path) -> Vec<BTreeMap<String, String>> {
    let mut reader = csv::Reader::from_path(path).unwrap();
    let header: Vec<String> = reader.headers().unwrap().iter().map(String::from).collect();
    reader
        .records()
        .map(|r| {
            let r = r.unwrap();
            header
                .iter()
                .cloned()
                .zip(r.iter().map(String::from))
                .collect()
        })
        .collect()
}

/// Mean E_rot of `solver` along panel `panel` of a long-format CSV, as (x, mean).
fn curve(rows: &[BTreeMap<String, String>], panel: &str, solver: &str) -> Vec<(f64, f64)> {
    rows.iter()
        .filter(|r| r["panel"] == panel && r["solver"] == solver && !r["mean_erot_deg"].is_empty())
        .map(|r| (r["x"].parse().unwrap(), r["mean_erot_deg"].parse().unwrap()))
        .collect()
}

fn check_structure(dir: &Path) {
    for (csv, figures) in EXPERIMENT_FILES {
        assert!(dir.join(csv).is_file(), "{csv} missing");
        for figure in figures {
            for suffix in ["rotation", "translation"] {
                let svg = std::fs::read_to_string(dir.join(format!("{figure}_{suffix}.svg")))
                    .unwrap_or_else(|e| panic!("{figure}_{suffix}.svg: {e}"));
                assert!(
                    svg.starts_with("<svg") && svg.contains("polyline"),
                    "{figure}"
                );
            }
        }
    }
    for file in [
        "report.md",
        "summary.json",
        "claims.csv",
        "protocol_scenarios.csv",
        "timing_claims.csv",
        "timing.json",
        "run.json",
        "fig10_timing.svg",
    ] {
        assert!(dir.join(file).is_file(), "{file} missing");
    }

    let report = std::fs::read_to_string(dir.join("report.md")).unwrap();
    for needle in [
        "| command | `layout-opt reproduce --quick",
        "| seed | 11 |",
        "| layout-opt | ",
        "| trials per setting | points 10 (paper 200)",
        "σ = √0.2 = 0.4472 px",
        "## Claims at a glance",
        "## 1. Number of points (Fig. 7)",
        "## 2. Noise",
        "## 3. Running time (Fig. 10)",
        "## 4. Depth/size ratio",
        "## 5. Distance from the optical axis",
        "## 6. Tilt about Y (Fig. S3)",
        "## 7. The real-image protocol, simulated (Tables I–XV)",
        "**Table I: the marker 200 mm from the camera**",
        "| 0 | RE (°) |",
    ] {
        assert!(report.contains(needle), "report.md lacks {needle:?}");
    }

    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["header"]["seed"], 11);
    assert_eq!(summary["header"]["quick"], true);
    let experiments = summary["experiments"].as_array().unwrap();
    // Timing is machine-dependent and stays out of summary.json.
    let names: Vec<&str> = experiments
        .iter()
        .map(|e| e["experiment"].as_str().unwrap())
        .collect();
    assert_eq!(
        names,
        ["points", "noise", "depth", "off-axis", "tilt", "protocol"]
    );
    let mut verdicts = BTreeMap::new();
    for experiment in experiments {
        let claims = experiment["claims"].as_array().unwrap();
        assert!(claims.len() >= 4, "{}", experiment["experiment"]);
        for claim in claims {
            let verdict = claim["verdict"].as_str().unwrap();
            *verdicts.entry(verdict.to_string()).or_insert(0) += 1;
            assert!(
                [
                    "holds",
                    "indistinguishable",
                    "does-not-hold",
                    "implementation-dependent",
                    "not-evaluated"
                ]
                .contains(&verdict),
                "{claim}"
            );
            // Every "does not hold" says why, and nothing else carries a reason.
            assert_eq!(
                claim["reason"].is_object(),
                verdict == "does-not-hold",
                "{claim}"
            );
            let evidence = claim["evidence"].as_str().unwrap();
            assert!(!evidence.is_empty() && !claim["criterion"].as_str().unwrap().is_empty());
            if verdict == "not-evaluated" {
                assert!(evidence.starts_with("not evaluated"), "{evidence}");
            }
            // Every claim appears in the report with its verdict.
            assert!(report.contains(&format!("`{}`", claim["id"].as_str().unwrap())));
        }
    }
    assert!(
        verdicts.get("holds").copied().unwrap_or(0) > 0,
        "{verdicts:?}"
    );
    // claims.csv lists every claim report.md lists, timing's included.
    let listed = rows(&dir.join("claims.csv"));
    let timing_claims = rows(&dir.join("timing_claims.csv"));
    assert_eq!(
        listed.len(),
        verdicts.values().sum::<usize>() + timing_claims.len()
    );
    for row in &listed {
        assert!(report.contains(&format!("`{}`", row["id"])), "{row:?}");
        assert_eq!(
            row["reason"].is_empty(),
            row["verdict"] != "does not hold",
            "{row:?}"
        );
    }

    // Timing: every n from 4 to 104 in steps of 4, for every solver.
    let timing = rows(&dir.join("timing.csv"));
    let solvers: Vec<String> = summary["header"]["solvers"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s.as_str().unwrap().to_string())
        .collect();
    assert_eq!(timing.len(), 26 * solvers.len());
    for row in &timing {
        if row["repetitions"] != "0" {
            assert!(row["median_us"].parse::<f64>().unwrap() > 0.0, "{row:?}");
        }
    }
}

fn check_statistics(dir: &Path) {
    // Error grows with noise: ML's mean E_rot at σ = 10 px is at least 10×
    // that at σ = 0.5 px in every noise figure, and grows almost monotonically.
    let noise = rows(&dir.join("noise.csv"));
    for panel in [
        "fig8_noise_n10",
        "fig9a_noise_biprism25",
        "fig9b_noise_biprism100",
    ] {
        let c = curve(&noise, panel, "ml");
        assert_eq!(c.len(), 20, "{panel}");
        assert_eq!((c[0].0, c[19].0), (0.5, 10.0));
        assert!(c[19].1 > 10.0 * c[0].1, "{panel}: {c:?}");
        let rises = c.windows(2).filter(|w| w[1].1 > w[0].1).count();
        assert!(rises >= 17, "{panel}: {rises} of 19 steps rise");
    }
    // A larger marker is more accurate for ML.
    let (small, large) = (
        curve(&noise, "fig9a_noise_biprism25", "ml"),
        curve(&noise, "fig9b_noise_biprism100", "ml"),
    );
    let sum = |c: &[(f64, f64)]| c.iter().map(|p| p.1).sum::<f64>();
    assert!(sum(&small) > 2.0 * sum(&large));

    // More points, smaller error; DLT is not run below its minimum of 6.
    let points = rows(&dir.join("points.csv"));
    let ml = curve(&points, "fig7_points", "ml");
    assert_eq!(ml.len(), 17);
    assert!(ml[16].1 < ml[2].1, "ml n = 20 vs n = 6: {ml:?}");
    let dlt: Vec<&BTreeMap<String, String>> = points
        .iter()
        .filter(|r| r["solver"] == "dlt" && (r["x"] == "4" || r["x"] == "5"))
        .collect();
    assert!(dlt.iter().all(|r| r["applicable"] == "false"), "{dlt:?}");

    // Deeper is worse: on the biprism's far range ML's error grows with depth,
    // and stays within a factor of 2 of the first-order limit (E_rot against
    // the RMS geodesic limit).
    let depth = rows(&dir.join("depth.csv"));
    let far: Vec<&BTreeMap<String, String>> = depth
        .iter()
        .filter(|r| r["panel"] == "fig13_depth_biprism_far" && r["solver"] == "ml")
        .collect();
    let first: f64 = far[0]["mean_erot_deg"].parse().unwrap();
    let last: f64 = far[far.len() - 1]["mean_erot_deg"].parse().unwrap();
    assert!(last > 5.0 * first, "{first} → {last}");
    for row in &far {
        let measured: f64 = row["rms_geodesic_deg"].parse().unwrap();
        let limit: f64 = row["first_order_rms_rot_deg"].parse().unwrap();
        assert!(
            measured > 0.5 * limit && measured < 2.0 * limit,
            "ratio {} at {}",
            measured / limit,
            row["x"]
        );
    }
}

/// Files whose content must not depend on the thread count: every CSV but
/// the timing ones.
fn deterministic_csvs(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "csv"))
        .filter(|p| {
            !p.file_name()
                .unwrap()
                .to_str()
                .unwrap()
                .starts_with("timing")
        })
        .map(|p| {
            let name = p.file_name().unwrap().to_str().unwrap().to_string();
            let mut content = std::fs::read(&p).unwrap();
            if name == "claims.csv" {
                // Its timing rows are machine-dependent.
                let rows = rows(&p);
                content = rows
                    .iter()
                    .filter(|r| r["experiment"] != "timing")
                    .map(|r| format!("{r:?}\n"))
                    .collect::<String>()
                    .into_bytes();
            }
            (name, content)
        })
        .collect()
}

fn summary_without_command(dir: &Path) -> serde_json::Value {
    let mut summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("summary.json")).unwrap()).unwrap();
    summary["header"].as_object_mut().unwrap().remove("command");
    summary
}

#[test]
fn quick_run_has_every_part_is_sane_and_reproducible() {
    let first_checkout = tempfile::tempdir().unwrap();
    let first = run_quick(first_checkout.path(), "2");
    check_structure(&first);
    check_statistics(&first);

    let second_checkout = tempfile::tempdir().unwrap();
    let second = run_quick(second_checkout.path(), "1");
    let (a, b) = (deterministic_csvs(&first), deterministic_csvs(&second));
    assert_eq!(a.keys().collect::<Vec<_>>(), b.keys().collect::<Vec<_>>());
    assert!(a.len() >= 8, "{:?}", a.keys());
    for (name, content) in &a {
        assert!(
            content == &b[name],
            "{name} differs between 2 threads and 1"
        );
    }
    assert_eq!(
        summary_without_command(&first),
        summary_without_command(&second)
    );
}

#[test]
fn one_experiment_writes_only_its_own_files() {
    let dir = tempfile::tempdir().unwrap();
    layout_opt()
        .args([
            "reproduce",
            "--quiet",
            "--experiment",
            "off-axis",
            "--trials",
            "5",
            "--out",
        ])
        .arg(dir.path())
        .assert()
        .success();
    assert!(dir.path().join("off_axis.csv").is_file());
    assert!(!dir.path().join("noise.csv").exists());
    assert!(!dir.path().join("timing.csv").exists());
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("summary.json")).unwrap())
            .unwrap();
    assert_eq!(summary["experiments"].as_array().unwrap().len(), 1);
    assert_eq!(summary["header"]["trials"][0]["trials"], 5);
    assert_eq!(summary["header"]["trials"][0]["paper_trials"], 100);
}

#[test]
fn bad_flags_get_clear_errors() {
    layout_opt()
        .args(["reproduce", "--experiment", "bogus"])
        .assert()
        .failure()
        .stderr(predicate::str::contains("unknown experiment 'bogus'"))
        .stderr(predicate::str::contains("off-axis"));
    layout_opt()
        .args(["reproduce", "--trials", "0"])
        .assert()
        .failure()
        .stderr(predicate::str::contains("--trials must be at least 1"));
}
