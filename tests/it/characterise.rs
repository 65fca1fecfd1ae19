//! `layout-opt characterise` end to end, on frames `render` draws of a part
//! whose sphere centres are the nominal layout's displaced by known
//! errors: the centres come back, their covariance is honest, a shrink is
//! measured with a distance, frames that are not of the part are dropped
//! and named, and refusals write nothing.

use assert_cmd::Command;
use layout_opt::characterise::gauge::Similarity;
use layout_opt::layout::Layout;
use nalgebra::{Matrix3, Vector3};
use predicates::prelude::*;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

fn layout_opt() -> Command {
    Command::cargo_bin("layout-opt").unwrap()
}

fn nominal_path() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("layouts/biprism-search.json")
}

fn nominal() -> Layout {
    Layout::load(&nominal_path()).unwrap()
}

/// The shrink along x of the printed part.
const SHRINK_X: f64 = 0.005;

/// The nominal with every coordinate displaced by 0.1–0.3 mm (seeded signs
/// and sizes), then shrunk by [`SHRINK_X`] along x.
fn printed() -> Layout {
    let mut layout = nominal();
    let mut rng = ChaCha8Rng::seed_from_u64(48);
    for point in &mut layout.points {
        for k in 0..3 {
            let sign = if rng.random::<bool>() { 1.0 } else { -1.0 };
            point.position[k] += sign * rng.random_range(0.1..0.3);
        }
        point.position.x *= 1.0 - SHRINK_X;
    }
    layout.name = "printed".into();
    layout
}

/// The views: two depths, tilt and pan over ±40° (50 frames).
const VIEWS: [&str; 6] = [
    "--depth",
    "450,550",
    "--tilt",
    "-40..40:20",
    "--pan",
    "-40..40:20",
];

/// Renders the printed part into `dir` with `flags` besides [`VIEWS`].
fn render(dir: &Path, flags: &[&str]) {
    let part = dir.join("printed.json");
    std::fs::create_dir_all(dir).unwrap();
    std::fs::write(&part, printed().to_json()).unwrap();
    layout_opt()
        .arg("render")
        .arg(&part)
        .arg("--out")
        .arg(dir.join("frames"))
        .args(VIEWS)
        .args(["--bit-depth", "16", "-q"])
        .args(flags)
        .assert()
        .success();
}

/// Noise-free frames of the printed part, rendered once.
fn noise_free() -> &'static Path {
    static DIR: OnceLock<tempfile::TempDir> = OnceLock::new();
    DIR.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        render(dir.path(), &["--no-noise"]);
        dir
    })
    .path()
}

/// `characterise` of the nominal from `inputs` into `out` with `flags`.
fn characterise(inputs: &[&Path], out: &Path, flags: &[&str]) -> assert_cmd::assert::Assert {
    layout_opt()
        .arg("characterise")
        .arg(nominal_path())
        .args(inputs)
        .arg("--out")
        .arg(out)
        .arg("-q")
        .args(flags)
        .assert()
}

/// The printed centres in the gauge a characterisation reports: overlaid
/// on the nominal by a similarity (`rigid`: by a rigid motion, the scale
/// measured).
fn truth_in_gauge(rigid: bool) -> Vec<Vector3<f64>> {
    let (truth, nominal) = (printed().positions(), nominal().positions());
    let overlay = if rigid {
        Similarity::rigid_onto(&truth, &nominal)
    } else {
        Similarity::onto(&truth, &nominal)
    };
    overlay.apply_all(&truth)
}

/// Each sphere's error, mm, and its normalised squared error against the
/// 3×3 covariance the characterised layout's provenance carries.
fn errors(measured: &Path, rigid: bool) -> Vec<(f64, f64)> {
    let layout = Layout::load(measured).unwrap();
    let provenance = layout.provenance.clone().unwrap();
    let covariances = &provenance["characterised"]["covariance_mm2"];
    layout
        .points
        .iter()
        .zip(truth_in_gauge(rigid))
        .map(|(point, truth)| {
            let e = point.position - truth;
            let c: Vec<Vec<f64>> =
                serde_json::from_value(covariances[&point.name].clone()).unwrap();
            let c = Matrix3::from_fn(|r, k| c[r][k]);
            let nse = (e.transpose() * c.try_inverse().unwrap() * e)[0];
            (e.norm(), nse)
        })
        .collect()
}

/// Noise-free renders read with `--refine` (which takes the part's pull
/// off each centre): the printed centres come back within
/// [`RECOVERED_RMS_MM`] in the gauge of the nominal's scale; the layout
/// says it was characterised and `track` reads it and says so.
#[test]
fn noise_free_frames_give_the_printed_centres_back() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("measured.json");
    characterise(&[&noise_free().join("frames")], &out, &["--refine"])
        .success()
        .stderr(predicate::str::contains(
            "characterised biprism-search from",
        ));
    assert_recovered(&errors(&out, false));
    let layout = Layout::load(&out).unwrap();
    let characterised = &layout.provenance.as_ref().unwrap()["characterised"];
    assert!(
        characterised["frames"].as_u64().unwrap() >= 30,
        "{characterised}"
    );
    assert_eq!(characterised["scale"]["source"], "nominal");
    assert!(dir.path().join("measured-report.md").is_file());
    let report: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(dir.path().join("measured-report.json")).unwrap(),
    )
    .unwrap();
    assert_eq!(report["names"].as_array().unwrap().len(), 7);
    // track reads the characterised layout and names it.
    let frame = noise_free().join("frames/printed-012.png");
    layout_opt()
        .arg("track")
        .arg(&out)
        .arg(frame)
        .assert()
        .success()
        .stderr(predicate::str::contains("characterised from"));
}

/// How close the centres come back from noise-free frames, RMS, mm. The
/// floor is the reading's own residual bias with `--refine`, about
/// 0.007 px on frames of the nominal part itself (its render samples
/// edges 8 × 8, the frames 4 × 4), which repeats between neighbouring
/// views: 0.0014–0.0025 mm RMS over the parts tried, its worst sphere up
/// to 0.004 mm.
const RECOVERED_RMS_MM: f64 = 0.003;

/// The printed centres came back: within [`RECOVERED_RMS_MM`] RMS, and
/// no sphere beyond 0.005 mm.
fn assert_recovered(errors: &[(f64, f64)]) {
    let rms = (errors.iter().map(|(e, _)| e * e).sum::<f64>() / errors.len() as f64).sqrt();
    assert!(
        rms < RECOVERED_RMS_MM,
        "RMS {rms} mm from the printed centres: {errors:?}"
    );
    for (k, (error, _)) in errors.iter().enumerate() {
        assert!(
            *error < 0.005,
            "sphere {k}: {error} mm from the printed centre"
        );
    }
}

/// A 0.5% shrink along x is invisible at the nominal's scale, and
/// measured with a distance between two spheres far apart in x: the
/// centres then come back as well after a rigid overlay alone.
#[test]
fn a_shrink_is_measured_with_a_distance() {
    let truth = printed();
    let (first, second) = (1, 4);
    let apart = (truth.points[first].position - truth.points[second].position).norm();
    let nominal = nominal();
    let distance = format!(
        "{}:{}={apart:.5}±0.0005",
        nominal.points[first].name, nominal.points[second].name
    );
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("measured.json");
    characterise(
        &[&noise_free().join("frames")],
        &out,
        &["--refine", "--distance", &distance],
    )
    .success();
    assert_recovered(&errors(&out, true));
    let layout = Layout::load(&out).unwrap();
    let scale = &layout.provenance.as_ref().unwrap()["characterised"]["scale"];
    assert_eq!(scale["source"], "distances");
    // The part's size relative to the nominal: the similarity that
    // overlays the printed part on the nominal shrinks it by this much.
    let truth_scale = 1.0 / Similarity::onto(&truth.positions(), &nominal.positions()).scale;
    let factor = scale["factor"].as_f64().unwrap();
    assert!(truth_scale < 1.0 - SHRINK_X / 4.0, "{truth_scale}");
    // Within the reading's floor: 5e-5 is 0.007 mm over the pair.
    assert!(
        (factor - truth_scale).abs() < 5e-5,
        "{factor} against {truth_scale}: {scale}"
    );
}

/// Over seeds of sensor noise (a small full well, so that the noise and
/// not the reading's residual bias dominates; `track`'s default reading),
/// the centres' errors agree
/// with their reported covariance: the mean normalised squared error
/// over spheres and seeds is within the target of twice its three
/// degrees of freedom, and not below a third of them (a covariance far
/// too large would hide nothing, but tell the user nothing either).
#[test]
fn noisy_frames_give_an_honest_covariance() {
    let mut nse = Vec::new();
    for seed in ["1", "2", "3"] {
        let dir = tempfile::tempdir().unwrap();
        render(dir.path(), &["--seed", seed, "--full-well", "1500"]);
        let out = dir.path().join("measured.json");
        characterise(&[&dir.path().join("frames")], &out, &[]).success();
        nse.extend(errors(&out, false).into_iter().map(|(_, n)| n));
    }
    let mean = nse.iter().sum::<f64>() / nse.len() as f64;
    assert!(
        (1.0..=6.0).contains(&mean),
        "mean NSE {mean} over {} spheres: {nse:?}",
        nse.len()
    );
}

/// A frame of another marker among the frames is skipped and named; a
/// frame whose labels are swapped (in `track`'s JSON lines) does not fit
/// the part the others show, and is dropped and named; the rest still
/// give the centres.
#[test]
fn frames_not_of_the_part_are_dropped_and_named() {
    let dir = tempfile::tempdir().unwrap();
    let frames = dir.path().join("frames");
    std::fs::create_dir_all(&frames).unwrap();
    for entry in std::fs::read_dir(noise_free().join("frames")).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "png") {
            std::fs::copy(&path, frames.join(path.file_name().unwrap())).unwrap();
        }
    }
    let paper = Path::new(env!("CARGO_MANIFEST_DIR")).join("layouts/biprism-paper.json");
    let other = dir.path().join("other");
    layout_opt()
        .arg("render")
        .arg(&paper)
        .arg("--out")
        .arg(&other)
        .args(["--depth", "500", "--tilt", "20", "--pan", "10", "-q"])
        .assert()
        .success();
    std::fs::copy(
        other.join("biprism-paper-000.png"),
        frames.join("zz-other.png"),
    )
    .unwrap();
    let out = dir.path().join("measured.json");
    characterise(&[&frames], &out, &[])
        .success()
        .stderr(predicate::str::contains(
            "zz-other.png: not used: not tracked",
        ));
    // Swapped labels in one record.
    let records = dir.path().join("tracked.jsonl");
    layout_opt()
        .arg("track")
        .arg(nominal_path())
        .arg(noise_free().join("frames"))
        .arg("--output")
        .arg(&records)
        .arg("-q")
        .assert()
        .success();
    let mut lines: Vec<serde_json::Value> = std::fs::read_to_string(&records)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    let record = lines.iter_mut().find(|r| r.get("error").is_none()).unwrap();
    let swapped = record["frame"].as_str().unwrap().to_string();
    let blobs = record["blobs"].as_array_mut().unwrap();
    let labelled: Vec<usize> = (0..blobs.len())
        .filter(|&k| !blobs[k]["label"].is_null())
        .collect();
    let (a, b) = (labelled[0], labelled[1]);
    let label_a = blobs[a]["label"].clone();
    blobs[a]["label"] = blobs[b]["label"].clone();
    blobs[b]["label"] = label_a;
    let text: String = lines.iter().map(|l| l.to_string() + "\n").collect();
    std::fs::write(&records, text).unwrap();
    let out = dir.path().join("from-records.json");
    characterise(&[&records], &out, &[])
        .success()
        .stderr(predicate::str::contains(format!(
            "{swapped}: not used: does not fit the part"
        )));
    let layout = Layout::load(&out).unwrap();
    let dropped = &layout.provenance.as_ref().unwrap()["characterised"]["dropped"];
    assert!(
        dropped
            .as_array()
            .unwrap()
            .iter()
            .any(|d| d == swapped.as_str()),
        "{dropped}"
    );
}

/// Refusals name their cause and write nothing: a distance naming no
/// sphere, too few frames, frames from one direction, a record that is
/// not a track record.
#[test]
fn refusals_write_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("measured.json");
    let frames = noise_free().join("frames");
    characterise(&[&frames], &out, &["--distance", "P1:P9=100"])
        .failure()
        .stderr(predicate::str::contains("--distance: no sphere 'P9'"));
    characterise(&[&frames], &out, &["--distance", "P1:P4"])
        .failure()
        .stderr(predicate::str::contains("is not a distance"));
    let three: Vec<PathBuf> = (0..3)
        .map(|k| frames.join(format!("printed-{k:03}.png")))
        .collect();
    let three: Vec<&Path> = three.iter().map(PathBuf::as_path).collect();
    characterise(&three, &out, &[])
        .failure()
        .stderr(predicate::str::contains(
            "a characterisation needs at least 6",
        ));
    // From one direction only, at six depths: refused with views to add.
    let line = dir.path().join("line");
    std::fs::write(dir.path().join("printed.json"), printed().to_json()).unwrap();
    layout_opt()
        .arg("render")
        .arg(dir.path().join("printed.json"))
        .arg("--out")
        .arg(&line)
        .args([
            "--depth",
            "400..650:50",
            "--tilt",
            "-20",
            "--pan",
            "0",
            "-q",
        ])
        .assert()
        .success();
    characterise(&[&line], &out, &[])
        .failure()
        .stderr(predicate::str::contains("Capture also: tilt"));
    let bad = dir.path().join("bad.jsonl");
    std::fs::write(&bad, "{\"frame\": \"x.png\", \"R\": 1}\n").unwrap();
    characterise(&[&bad], &out, &[])
        .failure()
        .stderr(predicate::str::contains("bad.jsonl, line 1"));
    assert!(!out.exists());
    assert!(!dir.path().join("measured-report.md").exists());
}

/// `--plan` lists the views to capture and the σ each sphere would reach,
/// below the default bar for the winner.
#[test]
fn the_plan_lists_views_and_sigmas() {
    let output = layout_opt()
        .arg("characterise")
        .arg(nominal_path())
        .arg("--plan")
        .output()
        .unwrap();
    assert!(output.status.success());
    let text = String::from_utf8(output.stdout).unwrap();
    let views = text
        .lines()
        .filter(|l| l.contains(" spheres clear)"))
        .count();
    assert!(views >= 25, "{text}");
    let sigmas: Vec<f64> = text
        .lines()
        .filter_map(|l| {
            l.trim()
                .strip_suffix(" mm")?
                .rsplit(": ")
                .next()?
                .parse()
                .ok()
        })
        .collect();
    assert_eq!(sigmas.len(), 7, "{text}");
    assert!(sigmas.iter().all(|&s| s > 0.0 && s < 0.02), "{sigmas:?}");
}

/// A `solve` batch of the render's exact centres (object points the
/// nominal's, which label them): ellipse centres with `sphere_diameter` in
/// half the problems, projected centres in the others. With no reading in
/// between, the printed centres come back to rounding.
#[test]
fn a_solve_batch_of_exact_centres_gives_the_part_back_exactly() {
    let nominal = nominal();
    let mut problems = Vec::new();
    for k in 0..50 {
        let record: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(noise_free().join(format!("frames/printed-{k:03}.json")))
                .unwrap(),
        )
        .unwrap();
        let ellipses = k % 2 == 0;
        let key = if ellipses {
            "ellipse_centre_px"
        } else {
            "projected_centre_px"
        };
        let spheres = record["spheres"].as_array().unwrap();
        let mut problem = serde_json::json!({
            "id": format!("view-{k}"),
            "object_points": nominal.points.iter().map(|p| [p.position.x, p.position.y, p.position.z]).collect::<Vec<_>>(),
            "image_points": spheres.iter().map(|s| s[key].clone()).collect::<Vec<_>>(),
        });
        if ellipses {
            problem["sphere_diameter"] = serde_json::json!(nominal.sphere_diameter_mm);
        }
        problems.push(problem);
    }
    let camera = std::fs::read_to_string(noise_free().join("frames/printed-000.json")).unwrap();
    let camera: serde_json::Value = serde_json::from_str(&camera).unwrap();
    let batch = serde_json::json!({"camera": camera["camera"], "problems": problems});
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("batch.json");
    std::fs::write(&path, batch.to_string()).unwrap();
    let out = dir.path().join("measured.json");
    characterise(&[&path], &out, &[]).success();
    for (k, (error, _)) in errors(&out, false).into_iter().enumerate() {
        assert!(error < 1e-5, "sphere {k}: {error} mm");
    }
    let layout = Layout::load(&out).unwrap();
    assert_eq!(layout.provenance.unwrap()["characterised"]["frames"], 50);
}
