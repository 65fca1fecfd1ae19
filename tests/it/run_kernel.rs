//! The run kernel's promises, command by command, on the defects that
//! trying bad input found: an output that is an input or another output is
//! refused before any work and nothing is clobbered; an output that cannot
//! be written leaves the others as they were; a second run on the same
//! output is refused; a blur the renderer cannot draw is refused by name; a
//! mistyped input is an error; and Ctrl-C ends a run with status 130 within
//! a second, leaving none of its files.

use assert_cmd::Command;
use layout_opt::files::OutputLock;
use std::path::{Path, PathBuf};

fn layout_opt() -> Command {
    Command::cargo_bin("layout-opt").unwrap()
}

fn repository(path: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(path)
}

/// `render`'s two frames of the winner (500 and 600 mm, head on) into
/// `dir`; their PNG paths.
fn two_frames(dir: &Path) -> Vec<PathBuf> {
    layout_opt()
        .arg("render")
        .arg(repository("layouts/biprism-search.json"))
        .args(["--depth", "500,600", "--tilt", "0", "--quiet", "--out"])
        .arg(dir)
        .assert()
        .success();
    let mut frames: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "png"))
        .collect();
    frames.sort();
    assert_eq!(frames.len(), 2);
    frames
}

/// A set of two shipped layouts (the winner and the tetrahedron), its
/// files written into `dir`; the set file's path.
fn pair_set(dir: &Path) -> PathBuf {
    let load = |name: &str| layout_opt::layout::Layout::load(&repository(name)).unwrap();
    let pair = [
        load("layouts/biprism-search.json"),
        load("layouts/tetrahedron.json"),
    ];
    layout_opt::set::write_set(dir, "pair", &pair).unwrap()
}

/// The run fails with one line on stderr that holds every needle.
fn fails_saying(command: &mut Command, needles: &[&str]) {
    let output = command.output().unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(1), "{stderr}");
    assert_eq!(stderr.trim_end().lines().count(), 1, "{stderr}");
    for needle in needles {
        assert!(stderr.contains(needle), "{needle:?} not in {stderr}");
    }
}

/// Names in `dir`, sorted.
fn names(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

#[test]
fn an_output_that_is_an_input_or_another_output_is_refused_and_nothing_is_clobbered() {
    let dir = tempfile::tempdir().unwrap();
    let frames_dir = dir.path().join("frames");
    let frames = two_frames(&frames_dir);
    let before = names(&frames_dir);
    let png = std::fs::read(&frames[1]).unwrap();
    let layout = dir.path().join("L.json");
    std::fs::copy(repository("layouts/biprism-search.json"), &layout).unwrap();
    let layout_text = std::fs::read_to_string(&layout).unwrap();
    let track = || {
        let mut command = layout_opt();
        command
            .arg("track")
            .arg(&layout)
            .arg(&frames_dir)
            .arg("--quiet");
        command
    };
    // A frame of the input directory as --output, as --csv, as an overlay.
    fails_saying(
        track().arg("--output").arg(&frames[1]),
        &["--output", "is also the input IMAGES"],
    );
    fails_saying(
        track().arg("--csv").arg(&frames[1]),
        &["--csv", "is also the input IMAGES"],
    );
    // The layout as --output, spelt another way.
    fails_saying(
        track()
            .arg("--output")
            .arg(dir.path().join("frames/../L.json")),
        &["--output", "the input LAYOUT"],
    );
    // The same file as --output and --csv.
    let out = dir.path().join("o.jsonl");
    fails_saying(
        track().arg("--output").arg(&out).arg("--csv").arg(&out),
        &["--csv", "the output of --output"],
    );
    // track --set: the set file as --output.
    let set = pair_set(dir.path());
    let set_text = std::fs::read_to_string(&set).unwrap();
    fails_saying(
        layout_opt()
            .arg("track")
            .arg("--set")
            .arg(&set)
            .arg(&frames_dir)
            .arg("--output")
            .arg(&set),
        &["--output", "the input --set"],
    );
    assert_eq!(std::fs::read_to_string(&set).unwrap(), set_text);
    // solve: the problem file as --output.
    let problems = dir.path().join("B.json");
    let batch = layout_opt::batch::demo_batch_json(1, 0.5);
    std::fs::write(&problems, &batch).unwrap();
    fails_saying(
        layout_opt()
            .arg("solve")
            .arg("--problems")
            .arg(&problems)
            .arg("--output")
            .arg(&problems),
        &["--output", "the input --problems"],
    );
    assert_eq!(std::fs::read_to_string(&problems).unwrap(), batch);
    // Nothing was touched or added.
    assert_eq!(std::fs::read(&frames[1]).unwrap(), png);
    assert_eq!(names(&frames_dir), before);
    assert_eq!(std::fs::read_to_string(&layout).unwrap(), layout_text);
    assert!(!out.exists());
}

#[test]
fn an_output_that_cannot_be_written_leaves_the_others_as_they_were() {
    let dir = tempfile::tempdir().unwrap();
    let frames_dir = dir.path().join("frames");
    two_frames(&frames_dir);
    let out = dir.path().join("out.jsonl");
    std::fs::write(&out, "an earlier run's lines\n").unwrap();
    // A file stands where the CSV's directory must be.
    let blocker = dir.path().join("blocker");
    std::fs::write(&blocker, "x").unwrap();
    fails_saying(
        layout_opt()
            .arg("track")
            .arg(repository("layouts/biprism-search.json"))
            .arg(&frames_dir)
            .arg("--output")
            .arg(&out)
            .arg("--csv")
            .arg(blocker.join("t.csv")),
        &["--csv", "is a file, not a directory"],
    );
    assert_eq!(
        std::fs::read_to_string(&out).unwrap(),
        "an earlier run's lines\n"
    );
    assert_eq!(names(dir.path()), ["blocker", "frames", "out.jsonl"]);
}

#[test]
fn a_second_run_on_an_output_in_use_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let frames_dir = dir.path().join("frames");
    two_frames(&frames_dir);
    let out = dir.path().join("out.jsonl");
    // Another run holds the output.
    let held = OutputLock::acquire(&out).unwrap();
    fails_saying(
        layout_opt()
            .arg("track")
            .arg(repository("layouts/biprism-search.json"))
            .arg(&frames_dir)
            .arg("--output")
            .arg(&out),
        &["in use by another run", "out.jsonl.lock"],
    );
    assert!(!out.exists());
    drop(held);
    layout_opt()
        .arg("track")
        .arg(repository("layouts/biprism-search.json"))
        .arg(&frames_dir)
        .arg("--quiet")
        .arg("--output")
        .arg(&out)
        .assert()
        .success();
    assert_eq!(std::fs::read_to_string(&out).unwrap().lines().count(), 2);
}

#[test]
fn a_missing_input_is_an_error_not_a_corrupt_frame() {
    fails_saying(
        layout_opt()
            .arg("track")
            .arg(repository("layouts/biprism-search.json"))
            .arg("/nonexistent/frames/"),
        &["/nonexistent/frames/", "no such file or directory"],
    );
}

#[test]
fn a_blur_the_renderer_cannot_draw_is_refused_before_any_work() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("frames");
    let render = || {
        let mut command = layout_opt();
        command
            .args([
                "render", "--depth", "500", "--tilt", "0", "--quiet", "--out",
            ])
            .arg(&out);
        command
    };
    fails_saying(
        render().args(["--blur", "1e9"]),
        &["--blur", "must lie in 0..20"],
    );
    fails_saying(
        render().args(["--aperture", "1e6", "--focus", "300"]),
        &["frame 0", "defocus", "--aperture"],
    );
    fails_saying(
        layout_opt()
            .arg("track")
            .arg(repository("layouts/biprism-search.json"))
            .arg(dir.path())
            .args(["--refine", "--blur", "1e9"]),
        &["--blur", "must lie in 0..20"],
    );
    assert_eq!(names(dir.path()), Vec::<String>::new());
}

#[test]
fn a_killed_runs_temporaries_are_removed_by_the_next_render() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("frames");
    std::fs::create_dir(&out).unwrap();
    let stale = out.join(".biprism-paper-000.png.4242.0.tmp");
    std::fs::write(&stale, "left by a killed run").unwrap();
    layout_opt()
        .args([
            "render", "--depth", "500", "--tilt", "0", "--quiet", "--out",
        ])
        .arg(&out)
        .assert()
        .success();
    assert!(!stale.exists());
    assert_eq!(
        names(&out),
        ["biprism-paper-000.json", "biprism-paper-000.png"]
    );
}

/// Starts `layout-opt ARGS`, waits until `ready` says the run is under
/// way, sends SIGINT (what Ctrl-C sends) and waits for the exit; the exit
/// code, stderr, and the time from the signal to the exit.
#[cfg(unix)]
fn interrupted(args: &[&str], ready: impl Fn() -> bool) -> (Option<i32>, String, f64) {
    use std::time::{Duration, Instant};
    let mut child = std::process::Command::new(assert_cmd::cargo::cargo_bin("layout-opt"))
        .args(args)
        .stderr(std::process::Stdio::piped())
        .stdout(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let started = Instant::now();
    while !ready() && started.elapsed() < Duration::from_secs(60) {
        std::thread::sleep(Duration::from_millis(20));
    }
    assert!(child.try_wait().unwrap().is_none(), "the run ended early");
    let signalled = Instant::now();
    let kill = std::process::Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(kill.success());
    let status = loop {
        if let Some(status) = child.try_wait().unwrap() {
            break status;
        }
        assert!(
            signalled.elapsed() < Duration::from_secs(20),
            "no exit 20 s after Ctrl-C"
        );
        std::thread::sleep(Duration::from_millis(10));
    };
    let waited = signalled.elapsed().as_secs_f64();
    let mut stderr = String::new();
    std::io::Read::read_to_string(&mut child.stderr.take().unwrap(), &mut stderr).unwrap();
    (status.code(), stderr, waited)
}

/// Ctrl-C while `render` writes its frames: exit 130 within a second of
/// the signal, one line saying nothing was written, and no file of the run
/// left.
#[cfg(unix)]
#[test]
fn ctrl_c_ends_a_render_within_a_second_with_status_130_and_no_files() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("frames");
    let out_text = out.to_string_lossy().into_owned();
    let staged = || {
        std::fs::read_dir(&out)
            .map(|entries| entries.count() > 0)
            .unwrap_or(false)
    };
    let (code, stderr, waited) = interrupted(
        &[
            "render",
            "--depth",
            "300..900:100",
            "--tilt=-30..30:10",
            "--quiet",
            "--threads",
            "1",
            "--out",
            &out_text,
        ],
        staged,
    );
    assert_eq!(code, Some(130), "{stderr}");
    assert!(waited < 1.0, "took {waited} s");
    assert!(stderr.contains("none of the render's files"), "{stderr}");
    assert_eq!(names(dir.path()), Vec::<String>::new());
}

/// Ctrl-C while `export` builds the part (seconds without a file written):
/// exit 130 within a second, and no file.
#[cfg(unix)]
#[test]
fn ctrl_c_ends_an_export_while_it_builds_the_part() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("part");
    let out_text = out.to_string_lossy().into_owned();
    let layout = repository("layouts/biprism-search.json");
    let layout_text = layout.to_string_lossy().into_owned();
    let started = std::time::Instant::now();
    let (code, stderr, waited) = interrupted(
        &["export", &layout_text, "--quiet", "--out", &out_text],
        || started.elapsed().as_secs_f64() > 0.7,
    );
    assert_eq!(code, Some(130), "{stderr}");
    assert!(waited < 1.0, "took {waited} s");
    assert!(stderr.contains("none of the export's files"), "{stderr}");
    assert_eq!(names(dir.path()), Vec::<String>::new());
}

#[test]
fn a_sets_validation_refuses_the_flags_it_has_no_use_for() {
    let dir = tempfile::tempdir().unwrap();
    let set = pair_set(dir.path());
    let before = names(dir.path());
    for flags in [
        &["--trials", "5"][..],
        &["--solvers", "ml"],
        &["--fabrication-sigma", "0.1"],
        &["--max-hidden", "0.05"],
        &["--images"],
    ] {
        fails_saying(
            layout_opt()
                .arg("validate")
                .arg(&set)
                .args(flags)
                .arg("--out")
                .arg(dir.path().join("report")),
            &[flags[0], "a set's"],
        );
    }
    assert_eq!(names(dir.path()), before);
}

#[test]
fn a_malformed_yaml_file_and_an_impossible_depth_are_one_line_each() {
    let dir = tempfile::tempdir().unwrap();
    let camera = dir.path().join("camera.yaml");
    std::fs::write(&camera, "fx: [1, 2\n  bad: : :\n").unwrap();
    fails_saying(
        layout_opt().arg("validate").arg("--camera").arg(&camera),
        &["camera.yaml", "line 2 column 6"],
    );
    fails_saying(
        layout_opt().args(["validate", "--depth", "1e308"]),
        &["depth must be at most 100000 mm", "got 1e308"],
    );
    fails_saying(
        layout_opt().args(["validate", "--samples", "8", "--depth", "200..1e9"]),
        &["--depth must be at most 100000 mm"],
    );
}

/// `export` with its layout inside `--out`, named as the export's own
/// report would be: refused, the layout kept, no file of the export left;
/// an `--out` that is a file: refused before the part is built.
#[test]
fn an_export_never_writes_over_its_layout_or_into_a_file() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("part");
    std::fs::create_dir(&out).unwrap();
    let layout = out.join("biprism-search-export.json");
    std::fs::copy(repository("layouts/biprism-search.json"), &layout).unwrap();
    let text = std::fs::read_to_string(&layout).unwrap();
    fails_saying(
        layout_opt()
            .arg("export")
            .arg(&layout)
            .args(["--format", "stl", "--quiet", "--out"])
            .arg(&out),
        &["biprism-search-export.json", "is also the input LAYOUT"],
    );
    assert_eq!(std::fs::read_to_string(&layout).unwrap(), text);
    assert_eq!(names(&out), ["biprism-search-export.json"]);
    let started = std::time::Instant::now();
    fails_saying(
        layout_opt()
            .arg("export")
            .arg(repository("layouts/biprism-search.json"))
            .arg("--out")
            .arg(&layout),
        &["--out", "is a file, not a directory"],
    );
    assert!(
        started.elapsed().as_secs_f64() < 2.0,
        "refused only after the build"
    );
}
