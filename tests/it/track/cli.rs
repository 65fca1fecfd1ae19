//! `layout-opt track` end to end: JSON lines on stdout, `--csv`,
//! `--overlay`, an error record for a bad frame while the others go on,
//! errors on stderr, and exit statuses.

use assert_cmd::Command;
use layout_opt::track::likeness::{LIKENESS_NOISE_FLOOR, MAX_MISMATCH};
use predicates::prelude::*;

fn layout_opt() -> Command {
    Command::cargo_bin("layout-opt").unwrap()
}

fn winner_path() -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("layouts/biprism-search.json")
}

/// `track` on the winner and `frame` with `flags` fails, naming `needle`
/// on stderr.
fn refused(frame: &std::path::Path, flags: &[&str], needle: &str) {
    layout_opt()
        .arg("track")
        .arg(winner_path())
        .arg(frame)
        .args(flags)
        .assert()
        .failure()
        .stderr(predicate::str::contains(needle));
}

/// A directory of two frames, a rendered one and an empty file: two JSON
/// lines in file order, the good frame tracked with all seven labels, the
/// bad one an error record naming its file; the CSV has a header and a row
/// per frame, the overlay directory a PNG for the tracked frame; stderr
/// names the bad frame, and the run succeeds.
#[test]
fn a_directory_of_frames_gives_json_lines_csv_and_overlays() {
    let dir = tempfile::tempdir().unwrap();
    let frames = dir.path().join("frames");
    std::fs::create_dir(&frames).unwrap();
    std::fs::write(frames.join("a-good.png"), super::good_frame_png()).unwrap();
    std::fs::write(frames.join("b-empty.png"), []).unwrap();
    let csv = dir.path().join("out.csv");
    let overlay = dir.path().join("overlay");
    let assert = layout_opt()
        .arg("track")
        .arg(winner_path())
        .arg(&frames)
        .arg("--csv")
        .arg(&csv)
        .arg("--overlay")
        .arg(&overlay)
        .arg("--quiet")
        .assert()
        .success()
        .stderr(
            predicate::str::contains("b-empty.png")
                .and(predicate::str::contains("tracked 1 of 2 frames")),
        );
    let stdout = String::from_utf8(assert.get_output().stdout.clone()).unwrap();
    let lines: Vec<serde_json::Value> = stdout
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(lines.len(), 2, "{stdout}");
    let good = &lines[0];
    assert!(good["frame"].as_str().unwrap().ends_with("a-good.png"));
    let labels: Vec<u64> = good["labels"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|l| l.as_u64())
        .collect();
    let mut sorted = labels.clone();
    sorted.sort_unstable();
    assert_eq!(sorted, (0..7).collect::<Vec<u64>>(), "{good}");
    for field in ["rvec", "tvec", "R", "t", "covariance", "residuals_px"] {
        assert!(good[field].is_array(), "{field} missing: {good}");
    }
    assert!(good["sigma_rot_deg"].as_f64().unwrap() > 0.0);
    let bad = &lines[1];
    assert!(bad["frame"].as_str().unwrap().ends_with("b-empty.png"));
    assert!(
        bad["error"].as_str().unwrap().contains("empty (0 bytes)"),
        "{bad}"
    );
    let table = std::fs::read_to_string(&csv).unwrap();
    assert_eq!(table.lines().count(), 3, "{table}");
    assert!(overlay.join("a-good.overlay.png").is_file());
    assert!(!overlay.join("b-empty.overlay.png").exists());
}

/// Bad flags, a missing layout and a missing frame path stop the run
/// before any frame, with one line on stderr naming the flag or the file,
/// and a failing exit status.
#[test]
fn bad_flags_and_inputs_fail_with_a_named_error() {
    let dir = tempfile::tempdir().unwrap();
    let frame = dir.path().join("frame.png");
    std::fs::write(&frame, super::good_frame_png()).unwrap();
    let cases: [(&[&str], &str); 4] = [
        (&["--sphere-diameter", "-1"], "--sphere-diameter"),
        (&["--threshold", "bright"], "--threshold"),
        (&["--max-extra-blobs", "99"], "--max-extra-blobs"),
        (&["--min-contrast", "2"], "--min-contrast"),
    ];
    for (flags, needle) in cases {
        refused(&frame, flags, needle);
    }
    layout_opt()
        .arg("track")
        .arg(dir.path().join("no-layout.json"))
        .arg(&frame)
        .assert()
        .failure()
        .stderr(predicate::str::contains("no-layout.json"));
    layout_opt()
        .arg("track")
        .arg(winner_path())
        .arg(dir.path().join("empty-dir-does-not-exist"))
        .arg("--quiet")
        .assert()
        .failure()
        .stderr(predicate::str::contains(
            "empty-dir-does-not-exist: no such file or directory",
        ));
}

/// `--refine` renders the part at each frame's pose and takes each sphere's
/// bias off its centre: the JSON line says how many rounds, the bias per
/// sphere and how far the pose moved, and stderr says the frames were
/// refined. The render's flags without --refine and a bad round count or
/// supersampling are refused, naming the flag.
#[test]
fn refine_reports_its_bias_and_its_flags_are_checked() {
    let dir = tempfile::tempdir().unwrap();
    let frame = dir.path().join("frame.png");
    std::fs::write(&frame, super::good_frame_png()).unwrap();
    let assert = layout_opt()
        .arg("track")
        .arg(winner_path())
        .arg(&frame)
        .args(["--refine", "--supersampling", "4", "--quiet"])
        .assert()
        .success()
        .stderr(predicate::str::contains("refined by 1 render round"));
    let line: serde_json::Value = serde_json::from_slice(&assert.get_output().stdout).unwrap();
    let refinement = &line["refinement"];
    assert_eq!(refinement["rounds"], 1, "{line}");
    let biases = refinement["bias_px"].as_array().unwrap();
    assert_eq!(biases.len(), 7, "{line}");
    let likeness = refinement["likeness"].as_array().unwrap();
    assert_eq!(likeness.len(), 7, "{line}");
    // A bias is taken off only where the render is like the frame.
    let mut taken = 0;
    for (bias, like) in biases.iter().zip(likeness) {
        let residual = like["residual"].as_f64().unwrap();
        let noise = like["noise"].as_f64().unwrap();
        let matches = residual <= MAX_MISMATCH * noise.max(LIKENESS_NOISE_FLOOR);
        assert_eq!(!bias.is_null(), matches, "{line}");
        if matches {
            // A whole sphere at 500 mm: a few hundredths of a pixel.
            let [x, y] = [0, 1].map(|i| bias[i].as_f64().unwrap());
            assert!(x.hypot(y) < 0.2, "{line}");
            taken += 1;
        }
    }
    assert!(taken > 0, "{line}");
    let change = refinement["rotation_change_deg"].as_f64().unwrap();
    assert!(change > 0.0 && change < 0.05, "{line}");
    let cases: [(&[&str], &str); 3] = [
        (&["--blur", "0.7"], "give --refine too"),
        (&["--refine", "--refine-rounds", "0"], "--refine-rounds"),
        (&["--refine", "--supersampling", "40"], "--supersampling"),
    ];
    for (flags, needle) in cases {
        refused(&frame, flags, needle);
    }
}

/// `solve` gives each pose the tracker's figures (OpenCV's rvec/tvec, a
/// residual per point, σ and the 6×6 covariance), and where the unlabelled
/// solver's labels cannot be trusted (`examples/shots.json`: ambiguity 1.0,
/// a symmetric marker) it says so on stderr and in the JSON.
#[test]
fn solve_reports_rvec_covariance_and_untrusted_labels() {
    let assert = layout_opt()
        .args([
            "solve",
            "--quiet",
            "--problems",
            "examples/shots.json",
            "--unlabelled",
        ])
        .assert()
        .success()
        .stderr(predicate::str::contains(
            "warning: shot-001: labels cannot be trusted",
        ));
    let output: serde_json::Value = serde_json::from_slice(&assert.get_output().stdout).unwrap();
    let results = output["results"].as_array().unwrap();
    let solved: Vec<_> = results.iter().filter(|r| r["error"].is_null()).collect();
    assert_eq!(solved.len(), 3, "{output}");
    for result in solved {
        for field in ["rvec", "tvec"] {
            assert_eq!(result[field].as_array().unwrap().len(), 3, "{result}");
        }
        let covariance = result["covariance"].as_array().unwrap();
        assert!(covariance
            .iter()
            .all(|row| row.as_array().unwrap().len() == 6));
        assert_eq!(covariance.len(), 6);
        assert_eq!(result["residuals_px"].as_array().unwrap().len(), 7);
        assert!(result["sigma_rot_deg"].as_f64().unwrap() > 0.0);
        assert!(result["wrong_label_probability"].as_f64().unwrap() > 0.1);
        assert!(result["warning"]
            .as_str()
            .unwrap()
            .starts_with("labels cannot be trusted"));
    }
}

/// `render --preset lambertian` draws white matte spheres. `track --refine`
/// with levels given (the retroreflective look at `--sphere-radiance
/// 0.85`) finds its render unlike the frame around every sphere, keeps the
/// measured centres and says so on stderr. With the levels fitted (the
/// default: flat discs drawn shaded where the frame's blobs are, the
/// sphere's radiance near the render's 0.85), or with `--preset
/// lambertian`, the render is the frame's look: every centre corrected,
/// nothing said.
#[test]
fn refine_warns_when_its_render_is_unlike_the_frames() {
    let dir = tempfile::tempdir().unwrap();
    let frames = dir.path().join("frames");
    layout_opt()
        .arg("render")
        .arg(winner_path())
        .args([
            "--depth",
            "500",
            "--tilt",
            "10",
            "--preset",
            "lambertian",
            "--quiet",
            "--out",
        ])
        .arg(&frames)
        .assert()
        .success();
    let frame = frames.join("biprism-search-000.png");
    let track = |look: &[&str]| {
        let assert = layout_opt()
            .arg("track")
            .arg(winner_path())
            .arg(&frame)
            .args(["--refine", "--quiet"])
            .args(look)
            .assert()
            .success();
        let output = assert.get_output();
        let line: serde_json::Value = serde_json::from_slice(&output.stdout).unwrap();
        (line, String::from_utf8_lossy(&output.stderr).into_owned())
    };
    let (line, stderr) = track(&["--sphere-radiance", "0.85"]);
    assert!(
        stderr.contains("warning: --refine: the render was unlike the frame around 7 of 7 spheres"),
        "{stderr}"
    );
    let biases = line["refinement"]["bias_px"].as_array().unwrap();
    assert!(biases.iter().all(|b| b.is_null()), "{line}");
    assert_eq!(line["refinement"]["levels"]["fitted"], false, "{line}");
    for look in [&[][..], &["--preset", "lambertian"][..]] {
        let (line, stderr) = track(look);
        assert!(!stderr.contains("warning"), "{look:?}: {stderr}");
        let refinement = &line["refinement"];
        let biases = refinement["bias_px"].as_array().unwrap();
        assert!(biases.iter().all(|b| !b.is_null()), "{line}");
        assert_eq!(refinement["levels"]["fitted"], true, "{line}");
        assert_eq!(refinement["levels"]["shading"], "lambertian", "{line}");
        let sphere = refinement["levels"]["sphere"].as_f64().unwrap();
        assert!((0.75..0.95).contains(&sphere), "{line}");
    }
}
