//! `track` on streams: YUV4MPEG2 and raw grey frames on standard input,
//! and a directory followed as it fills. Each frame's line is written as
//! the frame is done; a cut stream ends with exit 1 keeping every whole
//! frame's line; Ctrl-C stops a silent stream with exit 130.

use super::frames;
use assert_cmd::Command;
use layout_opt::camera::Camera;
use layout_opt::track::GreyFrame;
use predicates::prelude::*;
use std::io::{BufRead, BufReader, Write};
use std::path::Path;
use std::process::Stdio;
use std::time::{Duration, Instant};

fn winner_path() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("layouts/biprism-search.json")
}

/// Three rendered frames of the winner, 450–550 mm, within ±20°.
fn three_frames() -> Vec<GreyFrame> {
    let camera = Camera::paper();
    super::clean_poses(0x57EA, 3, 500.0, 20.0, |_| true)
        .iter()
        .enumerate()
        .map(|(k, pose)| {
            super::winner()
                .render(&frames::noisy(camera, 4), pose)
                .expose(9, k as u64)
        })
        .collect()
}

/// The frames as an 8-bit mono YUV4MPEG2 stream at 25 Hz.
fn y4m_of(frames: &[GreyFrame]) -> Vec<u8> {
    let (width, height) = (frames[0].width() as usize, frames[0].height() as usize);
    let mut out = Vec::new();
    let mut encoder = y4m::encode(width, height, y4m::Ratio::new(25, 1))
        .with_colorspace(y4m::Colorspace::Cmono)
        .write_header(&mut out)
        .unwrap();
    for frame in frames {
        let luma: Vec<u8> = frame.pixels().iter().map(|&v| v as u8).collect();
        encoder
            .write_frame(&y4m::Frame::new([&luma, &[], &[]], None))
            .unwrap();
    }
    out
}

/// The frames as raw 8-bit grey, one after another.
fn raw_of(frames: &[GreyFrame]) -> Vec<u8> {
    frames
        .iter()
        .flat_map(|f| f.pixels().iter().map(|&v| v as u8))
        .collect()
}

fn lines_of(text: &[u8]) -> Vec<serde_json::Value> {
    String::from_utf8(text.to_vec())
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect()
}

/// A Y4M stream on standard input gives, frame by frame, the labels, pose
/// and covariance that the same frames give as PNG files, each line with
/// its index, its time at the stream's rate and its latency.
#[test]
fn a_y4m_stream_gives_the_poses_of_the_same_frames_as_png_files() {
    let frames = three_frames();
    let dir = tempfile::tempdir().unwrap();
    for (k, frame) in frames.iter().enumerate() {
        std::fs::write(dir.path().join(format!("{k}.png")), frame.to_png()).unwrap();
    }
    let files = Command::cargo_bin("layout-opt")
        .unwrap()
        .args(["track", "--quiet"])
        .arg(winner_path())
        .arg(dir.path())
        .assert()
        .success();
    let streamed = Command::cargo_bin("layout-opt")
        .unwrap()
        .args(["track", "--quiet"])
        .arg(winner_path())
        .arg("-")
        .write_stdin(y4m_of(&frames))
        .assert()
        .success()
        .stderr(
            predicate::str::contains("3 pose(s) from 3 frames")
                .and(predicate::str::contains("latency per frame")),
        );
    let files = lines_of(&files.get_output().stdout);
    let streamed = lines_of(&streamed.get_output().stdout);
    assert_eq!((files.len(), streamed.len()), (3, 3));
    for (k, (file, line)) in files.iter().zip(&streamed).enumerate() {
        for field in [
            "labels",
            "rvec",
            "tvec",
            "covariance",
            "residuals_px",
            "blobs",
        ] {
            assert!(!file[field].is_null(), "{field}: {file}");
            assert_eq!(file[field], line[field], "frame {k}, {field}");
        }
        assert_eq!(line["index"], k as u64);
        assert_eq!(line["frame"], format!("stdin:{k}"));
        assert_eq!(line["clock"], "frame_rate");
        assert!((line["timestamp_s"].as_f64().unwrap() - k as f64 / 25.0).abs() < 1e-12);
        let latency = &line["latency_ms"];
        for stage in ["decode", "detect", "solve", "analyse", "total"] {
            assert!(
                latency[stage].as_f64().unwrap() >= 0.0,
                "{stage}: {latency}"
            );
        }
        assert!(file.get("latency_ms").is_none());
    }
}

/// A raw stream cut part-way through its third frame: exit 1, a message
/// naming the cut, and the two whole frames' lines in --output.
#[test]
fn a_raw_stream_cut_mid_frame_exits_1_with_every_whole_frame_written() {
    let frames = three_frames();
    let mut bytes = raw_of(&frames);
    bytes.truncate(bytes.len() - 1000);
    let dir = tempfile::tempdir().unwrap();
    let output = dir.path().join("poses.jsonl");
    Command::cargo_bin("layout-opt")
        .unwrap()
        .args(["track", "--raw", "1280x720", "--fps", "60", "--output"])
        .arg(&output)
        .arg(winner_path())
        .arg("-")
        .write_stdin(bytes)
        .assert()
        .code(1)
        .stderr(
            predicate::str::contains("part-way through frame 2")
                .and(predicate::str::contains("the lines of 2 frames are in")),
        );
    let lines = lines_of(&std::fs::read(&output).unwrap());
    assert_eq!(lines.len(), 2);
    assert!(lines.iter().all(|l| l["rvec"].is_array()));
    assert!((lines[1]["timestamp_s"].as_f64().unwrap() - 1.0 / 60.0).abs() < 1e-12);
}

/// --follow tracks the frames written into the directory after it started,
/// in name order, a bad file as an error record, and stops after --idle.
#[test]
fn follow_picks_up_files_written_after_it_started() {
    let frames = three_frames();
    let dir = tempfile::tempdir().unwrap();
    let watched = dir.path().join("incoming");
    std::fs::create_dir(&watched).unwrap();
    std::fs::write(watched.join("0.png"), frames[0].to_png()).unwrap();
    let bin = assert_cmd::cargo::cargo_bin("layout-opt");
    let mut child = std::process::Command::new(bin)
        .args(["track", "--follow", "--idle", "2"])
        .arg(winner_path())
        .arg(&watched)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut stdout = BufReader::new(child.stdout.take().unwrap());
    let mut first = String::new();
    stdout.read_line(&mut first).unwrap();
    assert!(first.contains("0.png"), "{first}");
    // Written only now that the first line is out: the acquisition goes on.
    std::fs::write(watched.join("1.png"), frames[1].to_png()).unwrap();
    std::fs::write(watched.join("2-bad.png"), b"not a png").unwrap();
    let status = child.wait().unwrap();
    assert!(status.success());
    let mut rest = Vec::new();
    std::io::Read::read_to_end(&mut stdout, &mut rest).unwrap();
    let lines = lines_of(&rest);
    assert_eq!(lines.len(), 2, "{lines:?}");
    assert!(lines[0]["frame"].as_str().unwrap().ends_with("1.png"));
    assert!(lines[0]["rvec"].is_array());
    assert_eq!(lines[0]["clock"], "file_modified");
    assert!(lines[1]["frame"].as_str().unwrap().ends_with("2-bad.png"));
    assert!(lines[1]["error"].is_string(), "{}", lines[1]);
}

/// Ctrl-C while the stream is silent stops the run with status 130, the
/// frame that came before it written.
#[test]
fn ctrl_c_stops_a_silent_stream_with_130() {
    let frames = three_frames();
    let bin = assert_cmd::cargo::cargo_bin("layout-opt");
    let mut child = std::process::Command::new(bin)
        .args(["track", "--raw", "1280x720"])
        .arg(winner_path())
        .arg("-")
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut stdin = child.stdin.take().unwrap();
    stdin.write_all(&raw_of(&frames[..1])).unwrap();
    stdin.flush().unwrap();
    let mut stdout = BufReader::new(child.stdout.take().unwrap());
    let mut first = String::new();
    stdout.read_line(&mut first).unwrap();
    assert!(first.contains("stdin:0"), "{first}");
    let asked = Instant::now();
    let killed = std::process::Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(killed.success());
    let status = child.wait().unwrap();
    assert!(asked.elapsed() < Duration::from_secs(5));
    assert_eq!(status.code(), Some(130));
    let mut stderr = String::new();
    std::io::Read::read_to_string(&mut child.stderr.take().unwrap(), &mut stderr).unwrap();
    assert!(stderr.contains("interrupted"), "{stderr}");
    drop(stdin);
}

/// Stream flags that do not fit the frames, and a stream of another size
/// than the camera, are refused with one line naming the problem.
#[test]
fn stream_flags_that_do_not_fit_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let frame = dir.path().join("frame.png");
    std::fs::write(&frame, super::good_frame_png()).unwrap();
    let frame = frame.to_str().unwrap();
    let dir_arg = dir.path().to_str().unwrap();
    let cases: [(&[&str], &str); 7] = [
        (
            &[frame, "--raw", "1280x720"],
            "--raw describes frames on standard input",
        ),
        (&["-", frame], "must be the only frame argument"),
        (&["-", "--raw", "1280x720:12"], "8 or 16"),
        (
            &["-", "--raw", "1280x720", "--fps", "0"],
            "--fps must be a positive",
        ),
        (&[dir_arg, dir_arg, "--follow"], "one directory"),
        (&[frame, "--follow"], "is not a directory"),
        (&["-", "--csv", "x.csv"], "JSON lines only"),
    ];
    for (args, needle) in cases {
        Command::cargo_bin("layout-opt")
            .unwrap()
            .arg("track")
            .arg(winner_path())
            .args(args)
            .write_stdin(Vec::new())
            .assert()
            .failure()
            .stderr(predicate::str::contains(needle));
    }
    let small = GreyFrame::new(64, 48, 8, vec![0; 64 * 48]).unwrap();
    Command::cargo_bin("layout-opt")
        .unwrap()
        .arg("track")
        .arg(winner_path())
        .arg("-")
        .write_stdin(y4m_of(&[small]))
        .assert()
        .code(1)
        .stderr(predicate::str::contains(
            "64×48 pixels; the camera's are 1280×720",
        ));
    Command::cargo_bin("layout-opt")
        .unwrap()
        .arg("track")
        .arg(winner_path())
        .arg("-")
        .write_stdin(b"\x89PNG not a stream".to_vec())
        .assert()
        .code(1)
        .stderr(predicate::str::contains("YUV4MPEG2"));
}
