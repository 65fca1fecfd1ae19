use super::*;
use crate::track::GreyFrame;
use std::io::Cursor;
use std::sync::atomic::{AtomicBool, Ordering};

/// A `width`×`height` Y4M stream of `frames` mono frames, frame k's pixel
/// (x, y) = (x + 3y + 7k) mod 256, written with the `y4m` crate.
fn mono_y4m(width: usize, height: usize, frames: usize) -> Vec<u8> {
    let mut out = Vec::new();
    let mut encoder = y4m::encode(width, height, y4m::Ratio::new(30, 1))
        .with_colorspace(y4m::Colorspace::Cmono)
        .write_header(&mut out)
        .unwrap();
    for k in 0..frames {
        let luma: Vec<u8> = (0..width * height)
            .map(|i| ((i % width + 3 * (i / width) + 7 * k) % 256) as u8)
            .collect();
        encoder
            .write_frame(&y4m::Frame::new([&luma, &[], &[]], None))
            .unwrap();
    }
    out
}

fn frames_of(source: &mut dyn FrameSource) -> (Vec<StreamFrame>, Option<StreamError>) {
    let mut frames = Vec::new();
    loop {
        match source.next_frame() {
            Ok(Some(frame)) => frames.push(frame),
            Ok(None) => return (frames, None),
            Err(error) => return (frames, Some(error)),
        }
    }
}

#[test]
fn raw_formats_parse_and_bad_ones_say_what_to_give() {
    assert_eq!(
        "1280x720".parse::<RawFormat>(),
        Ok(RawFormat {
            width: 1280,
            height: 720,
            bit_depth: 8
        })
    );
    let deep: RawFormat = "640X480:16".parse().unwrap();
    assert_eq!((deep.width, deep.height, deep.bit_depth), (640, 480, 16));
    assert_eq!(deep.frame_bytes(), 640 * 480 * 2);
    for bad in ["", "1280", "0x720", "1280x", "axb", "1280x720:12", "-1x5"] {
        let error = bad.parse::<RawFormat>().unwrap_err();
        assert!(
            error.contains("bits") || error.contains("WIDTHxHEIGHT"),
            "{bad}: {error}"
        );
    }
}

#[test]
fn raw_frames_come_whole_and_a_cut_frame_ends_the_stream() {
    let format: RawFormat = "4x3:16".parse().unwrap();
    let mut bytes = Vec::new();
    for k in 0..2u16 {
        for i in 0..12u16 {
            bytes.extend_from_slice(&(1000 * k + i).to_le_bytes());
        }
    }
    let mut whole = RawSource::new(Cursor::new(bytes.clone()), format, Some(10.0));
    let (frames, end) = frames_of(&mut whole);
    assert!(end.is_none(), "{end:?}");
    assert_eq!(frames.len(), 2);
    let second = frames[1].frame.as_ref().unwrap();
    assert_eq!(second.bit_depth(), 16);
    assert_eq!(second.at(1, 2), 1000 + 9);
    assert_eq!((frames[1].index, frames[1].name.as_str()), (1, "stdin:1"));
    assert_eq!(frames[1].timestamp_s, Some(0.1));
    assert_eq!(frames[1].clock, Clock::FrameRate);

    bytes.extend_from_slice(&[1, 2, 3]);
    let mut cut = RawSource::new(Cursor::new(bytes), format, None);
    let (frames, end) = frames_of(&mut cut);
    assert_eq!(frames.len(), 2);
    assert_eq!(frames[0].clock, Clock::Arrival);
    match end {
        Some(StreamError::Truncated {
            index: 2,
            got: 3,
            expected: 24,
        }) => {}
        other => panic!("{other:?}"),
    }
}

#[test]
fn y4m_frames_read_back_as_written_at_the_stream_rate() {
    let bytes = mono_y4m(5, 4, 3);
    let mut source = Y4mSource::new(Cursor::new(bytes)).unwrap();
    assert_eq!(source.frame_size(), Some((5, 4)));
    let (frames, end) = frames_of(&mut source);
    assert!(end.is_none(), "{end:?}");
    assert_eq!(frames.len(), 3);
    for (k, frame) in frames.iter().enumerate() {
        let grey = frame.frame.as_ref().unwrap();
        assert_eq!(grey.bit_depth(), 8);
        assert_eq!(u64::from(grey.at(2, 3)), ((2 + 9 + 7 * k) % 256) as u64);
        assert_eq!(frame.timestamp_s, Some(k as f64 / 30.0));
    }
}

#[test]
fn deep_and_colour_y4m_give_their_luma_on_sixteen_bits() {
    let (width, height) = (4, 2);
    let mut out = Vec::new();
    let mut encoder = y4m::encode(width, height, y4m::Ratio::new(25, 1))
        .with_colorspace(y4m::Colorspace::C420p12)
        .write_header(&mut out)
        .unwrap();
    let luma: Vec<u16> = (0..8).map(|i| 4095 - i).collect();
    let chroma = [2048u16; 2];
    encoder
        .write_frame(&y4m::Frame::from_u16([&luma, &chroma, &chroma], None))
        .unwrap();
    let mut source = Y4mSource::new(Cursor::new(out)).unwrap();
    let (frames, end) = frames_of(&mut source);
    assert!(end.is_none(), "{end:?}");
    let grey = frames[0].frame.as_ref().unwrap();
    assert_eq!(grey.bit_depth(), 16);
    assert_eq!(grey.at(0, 0), 4095 << 4);
    assert_eq!(grey.at(3, 1), (4095 - 7) << 4);
}

#[test]
fn a_cut_or_malformed_y4m_stream_ends_with_its_reason() {
    let bytes = mono_y4m(5, 4, 2);
    let frame_bytes = 6 + 20;
    // Cut in the second frame's pixels, and in its FRAME line.
    for keep in [bytes.len() - 7, bytes.len() - frame_bytes + 3] {
        let mut source = Y4mSource::new(Cursor::new(bytes[..keep].to_vec())).unwrap();
        let (frames, end) = frames_of(&mut source);
        assert_eq!(frames.len(), 1);
        match end {
            Some(StreamError::Truncated {
                index: 1,
                got,
                expected,
            }) => {
                assert_eq!(expected, frame_bytes as u64);
                assert_eq!(got, (keep - (bytes.len() - frame_bytes)) as u64);
            }
            other => panic!("{other:?}"),
        }
    }
    let mut bad = bytes.clone();
    let second = bytes.len() - frame_bytes;
    bad[second..second + 5].copy_from_slice(b"FRAMX");
    let mut source = Y4mSource::new(Cursor::new(bad)).unwrap();
    let (frames, end) = frames_of(&mut source);
    assert_eq!(frames.len(), 1);
    assert!(
        matches!(end, Some(StreamError::Malformed { index: 1 })),
        "{end:?}"
    );
    for (not_y4m, needle) in [
        (&b""[..], "ended before"),
        (b"\x89PNG\r\n\x1a\nxxxxxxxx\n", "--raw"),
        (b"YUV4MPEG2 W4 H2 Cmono16\n", "pixel format"),
        (b"YUV4MPEG2 W100000 H100000 Cmono\n", "MiB each"),
    ] {
        let error = Y4mSource::new(Cursor::new(not_y4m.to_vec()))
            .err()
            .expect("refused");
        assert!(error.to_string().contains(needle), "{error}");
    }
}

/// Counts the frames and answers each with a line of its index.
struct Lines;

impl StreamTracker for Lines {
    fn track(
        &self,
        frame: &StreamFrame,
        latency: &mut Latency,
        out: &mut dyn Write,
    ) -> std::io::Result<usize> {
        latency.total = latency.decode;
        writeln!(out, "{}", frame.index)?;
        Ok(usize::from(frame.frame.is_ok()))
    }
}

#[test]
fn a_stream_of_another_size_is_refused_before_any_frame() {
    let source = Y4mSource::new(Cursor::new(mono_y4m(5, 4, 1))).unwrap();
    let mut out = Vec::new();
    let error = run_stream(Box::new(source), (6, 4), &Lines, &mut out, &|| false).unwrap_err();
    assert!(error.to_string().contains("5×4"), "{error}");
    assert!(out.is_empty());
}

#[test]
fn every_whole_frame_is_written_before_a_cut_ends_the_run() {
    let mut bytes = mono_y4m(5, 4, 3);
    bytes.truncate(bytes.len() - 1);
    let source = Y4mSource::new(Cursor::new(bytes)).unwrap();
    let mut out = Vec::new();
    let run = run_stream(Box::new(source), (5, 4), &Lines, &mut out, &|| false).unwrap();
    assert_eq!(String::from_utf8(out).unwrap(), "0\n1\n");
    assert_eq!((run.frames, run.posed), (2, 2));
    assert!(matches!(
        run.end,
        StreamEnd::Failed(StreamError::Truncated { index: 2, .. })
    ));
    let summary = run.latency_summary();
    let names: Vec<&str> = summary.iter().map(|(n, _)| *n).collect();
    assert_eq!(names, ["decode", "analyse", "total"]);
}

/// A reader that never gives a byte (a camera that stopped sending).
struct Silent;

impl std::io::Read for Silent {
    fn read(&mut self, _: &mut [u8]) -> std::io::Result<usize> {
        std::thread::sleep(Duration::from_secs(3600));
        Ok(0)
    }
}

#[test]
fn a_stop_is_answered_while_the_stream_is_silent() {
    let source = RawSource::new(Silent, "4x4".parse().unwrap(), None);
    let stop = AtomicBool::new(false);
    let started = Instant::now();
    let mut out = Vec::new();
    std::thread::scope(|scope| {
        scope.spawn(|| {
            std::thread::sleep(Duration::from_millis(100));
            stop.store(true, Ordering::SeqCst);
        });
        let run = run_stream(Box::new(source), (4, 4), &Lines, &mut out, &|| {
            stop.load(Ordering::SeqCst)
        })
        .unwrap();
        assert!(matches!(run.end, StreamEnd::Stopped), "{:?}", run.end);
        assert_eq!(run.frames, 0);
    });
    assert!(started.elapsed() < Duration::from_secs(2));
}

fn grey_png(width: u32, height: u32, level: u16) -> Vec<u8> {
    GreyFrame::new(width, height, 8, vec![level; (width * height) as usize])
        .unwrap()
        .to_png()
}

#[test]
fn a_followed_directory_gives_new_files_in_name_order_and_bad_ones_as_errors() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("b.png"), grey_png(4, 3, 20)).unwrap();
    std::fs::write(dir.path().join("a.png"), grey_png(4, 3, 10)).unwrap();
    std::fs::write(dir.path().join("notes.txt"), "not a frame").unwrap();
    let mut source = FollowSource::new(dir.path(), 4, 3, Some(Duration::from_millis(600))).unwrap();
    let first = source.next_frame().unwrap().unwrap();
    assert!(first.name.ends_with("a.png"), "{}", first.name);
    assert_eq!(first.clock, Clock::FileModified);
    assert!(first.timestamp_s.unwrap() > 1.7e9);
    // Written after the run started; "c" is not a frame of this camera.
    std::fs::write(dir.path().join("c.png"), grey_png(5, 3, 20)).unwrap();
    std::fs::write(dir.path().join("d.png"), grey_png(4, 3, 30)).unwrap();
    let (frames, end) = frames_of(&mut source);
    assert!(end.is_none(), "{end:?}");
    let names: Vec<&str> = frames
        .iter()
        .map(|f| f.name.rsplit('/').next().unwrap())
        .collect();
    assert_eq!(names, ["b.png", "c.png", "d.png"]);
    assert_eq!(frames[0].index, 1);
    assert!(frames[1].frame.is_err());
    assert_eq!(frames[2].frame.as_ref().unwrap().at(0, 0), 30);
    assert!(FollowSource::new(&dir.path().join("b.png"), 4, 3, None).is_err());
}
