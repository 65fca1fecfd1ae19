//! Where a stream's frames come from: YUV4MPEG2 or raw grey frames on a
//! reader (standard input, a pipe from a camera's tool or from `ffmpeg`),
//! or a directory that the acquisition software keeps filling.
//!
//! A source hands out one [`StreamFrame`] at a time, blocking until the
//! next one is whole. A frame whose bytes do not make an image (a PNG that
//! is not one) comes as a frame with an error, and the stream goes on; a
//! stream that cannot go on (cut part-way through a frame, a Y4M frame
//! header that is not one) ends with a [`StreamError`].

use crate::track::frame::{FrameError, GreyFrame};
use serde::Serialize;
use std::collections::{BTreeMap, BTreeSet, VecDeque};
use std::io::Read;
use std::path::{Path, PathBuf};
use std::str::FromStr;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant, SystemTime};

/// What a frame's `timestamp_s` counts.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Clock {
    /// The stream's frame rate: index ÷ rate, from the start of the
    /// stream (Y4M's `F` field, or `--fps` with raw frames).
    FrameRate,
    /// When the frame's last byte arrived, from the start of the stream.
    Arrival,
    /// The file's modification time, in seconds since the Unix epoch.
    FileModified,
}

/// One frame of a stream.
#[derive(Debug)]
pub struct StreamFrame {
    /// Its place in the stream, from 0.
    pub index: u64,
    /// Its name in the records: `stdin:INDEX`, or the file's path.
    pub name: String,
    /// Its time, in seconds, by [`StreamFrame::clock`] (None: a file
    /// whose modification time cannot be read).
    pub timestamp_s: Option<f64>,
    /// What [`StreamFrame::timestamp_s`] counts.
    pub clock: Clock,
    /// The frame, or why its bytes are not one.
    pub frame: Result<GreyFrame, FrameError>,
    /// From the frame's bytes, once whole, to the grey frame (reading the
    /// file and decoding it, for a followed directory).
    pub decode: Duration,
}

/// Why a stream cannot go on.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum StreamError {
    /// The stream does not start as a YUV4MPEG2 stream.
    #[error("{0}")]
    NotY4m(String),
    /// The frames are not the camera's size.
    #[error("the stream's frames are {width}×{height} pixels; the camera's are {camera_width}×{camera_height}")]
    Size {
        /// The stream's frame width.
        width: u32,
        /// The stream's frame height.
        height: u32,
        /// The camera's width.
        camera_width: u32,
        /// The camera's height.
        camera_height: u32,
    },
    /// The stream ended part-way through a frame.
    #[error(
        "the stream ended part-way through frame {index}: {got} of its {expected} bytes arrived"
    )]
    Truncated {
        /// The frame cut.
        index: u64,
        /// Bytes of it that arrived.
        got: u64,
        /// Bytes a whole frame has.
        expected: u64,
    },
    /// A Y4M frame header is not one: where the next frame starts is not
    /// known, so the stream cannot go on.
    #[error("frame {index}: the stream has no FRAME header where one must be (the stream is malformed from here on)")]
    Malformed {
        /// The frame whose header is bad.
        index: u64,
    },
    /// Reading failed.
    #[error("cannot read the stream: {0}")]
    Read(#[source] std::io::Error),
    /// The followed directory cannot be read.
    #[error("cannot follow {}: {reason}", path.display())]
    Follow {
        /// The directory.
        path: PathBuf,
        /// Why.
        reason: String,
    },
    /// A line could not be written.
    #[error("cannot write the frame's line: {0}")]
    Write(#[source] std::io::Error),
}

/// A source of frames.
pub trait FrameSource: Send {
    /// The next frame, waiting for it; `None` at the stream's clean end.
    fn next_frame(&mut self) -> Result<Option<StreamFrame>, StreamError>;

    /// The size every frame has, where the stream says it before its first
    /// frame (checked against the camera before any frame is read).
    fn frame_size(&self) -> Option<(u32, u32)>;
}

/// Raw grey frames: `--raw WIDTHxHEIGHT[:BITS]`, rows top to bottom,
/// 8-bit samples or 16-bit little-endian ones (`gray16le`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RawFormat {
    /// Pixels per row.
    pub width: u32,
    /// Rows.
    pub height: u32,
    /// 8 or 16.
    pub bit_depth: u8,
}

impl RawFormat {
    /// Bytes per frame.
    pub fn frame_bytes(&self) -> u64 {
        u64::from(self.width) * u64::from(self.height) * u64::from(self.bit_depth / 8)
    }
}

impl FromStr for RawFormat {
    type Err = String;

    fn from_str(text: &str) -> Result<Self, String> {
        let usage = || {
            format!("{text:?}: give WIDTHxHEIGHT or WIDTHxHEIGHT:BITS, as 1280x720 or 1280x720:16")
        };
        let (size, bits) = match text.split_once(':') {
            Some((size, bits)) => (size, Some(bits)),
            None => (text, None),
        };
        let (width, height) = size.split_once(['x', 'X']).ok_or_else(usage)?;
        let parse = |v: &str| v.trim().parse::<u32>().ok().filter(|&v| v > 0);
        let (width, height) = parse(width).zip(parse(height)).ok_or_else(usage)?;
        let bit_depth = match bits.map(str::trim) {
            None | Some("8") => 8,
            Some("16") => 16,
            Some(other) => return Err(format!("{text:?}: {other} bits; raw frames have 8 or 16")),
        };
        Ok(RawFormat {
            width,
            height,
            bit_depth,
        })
    }
}

/// Counts the bytes its reader has given, for telling a clean end of a
/// stream from one cut part-way through a frame.
struct Counted<R> {
    inner: R,
    count: Arc<AtomicU64>,
}

impl<R: Read> Read for Counted<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.inner.read(buf)?;
        self.count.fetch_add(n as u64, Ordering::Relaxed);
        Ok(n)
    }
}

/// Raw grey frames from a reader.
pub struct RawSource<R> {
    reader: R,
    format: RawFormat,
    fps: Option<f64>,
    buffer: Vec<u8>,
    index: u64,
    start: Instant,
}

impl<R: Read + Send> RawSource<R> {
    /// Frames of `format` from `reader`; `fps` gives their times (else the
    /// time each arrives).
    pub fn new(reader: R, format: RawFormat, fps: Option<f64>) -> Self {
        RawSource {
            reader,
            format,
            fps,
            buffer: vec![0; format.frame_bytes() as usize],
            index: 0,
            start: Instant::now(),
        }
    }
}

impl<R: Read + Send> FrameSource for RawSource<R> {
    fn next_frame(&mut self) -> Result<Option<StreamFrame>, StreamError> {
        let mut filled = 0;
        while filled < self.buffer.len() {
            match self.reader.read(&mut self.buffer[filled..]) {
                Ok(0) => break,
                Ok(n) => filled += n,
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                Err(e) => return Err(StreamError::Read(e)),
            }
        }
        if filled == 0 {
            return Ok(None);
        }
        if filled < self.buffer.len() {
            return Err(StreamError::Truncated {
                index: self.index,
                got: filled as u64,
                expected: self.buffer.len() as u64,
            });
        }
        let arrived = self.start.elapsed();
        let decoding = Instant::now();
        let pixels: Vec<u16> = if self.format.bit_depth == 8 {
            self.buffer.iter().map(|&v| u16::from(v)).collect()
        } else {
            self.buffer
                .chunks_exact(2)
                .map(|b| u16::from_le_bytes([b[0], b[1]]))
                .collect()
        };
        let frame = GreyFrame::new(
            self.format.width,
            self.format.height,
            self.format.bit_depth,
            pixels,
        );
        let (timestamp_s, clock) = match self.fps {
            Some(fps) => (Some(self.index as f64 / fps), Clock::FrameRate),
            None => (Some(arrived.as_secs_f64()), Clock::Arrival),
        };
        let frame = StreamFrame {
            index: self.index,
            name: format!("stdin:{}", self.index),
            timestamp_s,
            clock,
            frame,
            decode: decoding.elapsed(),
        };
        self.index += 1;
        Ok(Some(frame))
    }

    fn frame_size(&self) -> Option<(u32, u32)> {
        Some((self.format.width, self.format.height))
    }
}

/// YUV4MPEG2 frames from a reader: the luma plane of any of the pixel
/// formats the `y4m` crate reads (`mono`, `mono12`, and 4:2:0, 4:2:2 and
/// 4:4:4 at 8, 10 or 12 bits). Samples deeper than 8 bits are scaled to
/// 16 bits.
pub struct Y4mSource<R: Read> {
    decoder: y4m::Decoder<Counted<R>>,
    count: Arc<AtomicU64>,
    /// Bytes read when the last whole frame ended.
    frame_end: u64,
    frame_bytes: u64,
    width: u32,
    height: u32,
    bit_depth: usize,
    /// Frames a second, where the header gives a rate.
    fps: Option<f64>,
    index: u64,
}

impl<R: Read + Send> Y4mSource<R> {
    /// Reads the stream's header.
    pub fn new(reader: R) -> Result<Self, StreamError> {
        let count = Arc::new(AtomicU64::new(0));
        let counted = Counted {
            inner: reader,
            count: Arc::clone(&count),
        };
        let limits = y4m::Limits {
            bytes: MAX_Y4M_FRAME_BYTES,
        };
        let decoder =
            y4m::Decoder::new_with_limits(counted, limits).map_err(|e| header_error(&e))?;
        let colour = decoder.get_colorspace();
        let (w, h) = (decoder.get_width() as u64, decoder.get_height() as u64);
        let bytes = colour.get_bytes_per_sample() as u64;
        let chroma = match colour {
            y4m::Colorspace::Cmono | y4m::Colorspace::Cmono12 => 0,
            y4m::Colorspace::C422 | y4m::Colorspace::C422p10 | y4m::Colorspace::C422p12 => {
                2 * w.div_ceil(2) * h
            }
            y4m::Colorspace::C444 | y4m::Colorspace::C444p10 | y4m::Colorspace::C444p12 => {
                2 * w * h
            }
            _ => 2 * w.div_ceil(2) * h.div_ceil(2),
        };
        let frame_end = count.load(Ordering::Relaxed);
        let rate = decoder.get_framerate();
        Ok(Y4mSource {
            width: decoder.get_width() as u32,
            height: decoder.get_height() as u32,
            bit_depth: decoder.get_bit_depth(),
            fps: Some(rate.num as f64 / rate.den as f64).filter(|f| f.is_finite() && *f > 0.0),
            decoder,
            count,
            frame_end,
            // "FRAME\n" and the planes.
            frame_bytes: 6 + (w * h + chroma) * bytes,
            index: 0,
        })
    }
}

/// The largest Y4M frame (all planes) the reader allocates for: 8K 4:4:4
/// at 12 bits is 199 MB, so a header that claims more is refused before
/// its buffer is made.
pub const MAX_Y4M_FRAME_BYTES: usize = 256 << 20;

/// The words for a stream whose header the `y4m` crate refused.
fn header_error(error: &y4m::Error) -> StreamError {
    let raw_hint = "for raw grey frames give --raw WIDTHxHEIGHT[:16]";
    match error {
        y4m::Error::EOF => StreamError::NotY4m(format!(
            "the stream ended before its YUV4MPEG2 header; {raw_hint}"
        )),
        y4m::Error::IoError(e) => StreamError::Read(std::io::Error::new(e.kind(), e.to_string())),
        y4m::Error::UnknownColorspace => StreamError::NotY4m(format!(
            "the YUV4MPEG2 stream's pixel format (its C field) is not one the reader takes: mono, mono12, or 4:2:0, 4:2:2 or 4:4:4 at 8, 10 or 12 bits (16-bit grey: {raw_hint} with -f rawvideo -pix_fmt gray16le)"
        )),
        y4m::Error::OutOfMemory => StreamError::NotY4m(format!(
            "the YUV4MPEG2 stream's frames are over {} MiB each, more than any camera's frame here",
            MAX_Y4M_FRAME_BYTES >> 20
        )),
        other => StreamError::NotY4m(format!(
            "the stream does not start with a YUV4MPEG2 header ({other}); {raw_hint}"
        )),
    }
}

impl<R: Read + Send> FrameSource for Y4mSource<R> {
    fn next_frame(&mut self) -> Result<Option<StreamFrame>, StreamError> {
        let index = self.index;
        let result = self.decoder.read_frame();
        let read = self.count.load(Ordering::Relaxed);
        let decoding = Instant::now();
        let frame = match result {
            Ok(frame) => frame,
            // The crate reports a cut frame as the end of the file: the
            // bytes it took since the last whole frame tell them apart.
            Err(y4m::Error::EOF) if read == self.frame_end => return Ok(None),
            Err(y4m::Error::EOF) => {
                return Err(StreamError::Truncated {
                    index,
                    got: read - self.frame_end,
                    expected: self.frame_bytes,
                })
            }
            Err(y4m::Error::IoError(e)) => return Err(StreamError::Read(e)),
            Err(_) => return Err(StreamError::Malformed { index }),
        };
        let depth = self.bit_depth;
        let luma = frame.get_y_plane();
        let (pixels, bit_depth): (Vec<u16>, u8) = if depth <= 8 {
            (luma.iter().map(|&v| u16::from(v)).collect(), 8)
        } else {
            let shift = 16 - depth as u32;
            let samples = luma
                .chunks_exact(2)
                .map(|b| u16::from_le_bytes([b[0], b[1]]) << shift)
                .collect();
            (samples, 16)
        };
        let frame = GreyFrame::new(self.width, self.height, bit_depth, pixels);
        self.frame_end = read;
        self.index += 1;
        Ok(Some(StreamFrame {
            index,
            name: format!("stdin:{index}"),
            timestamp_s: self.fps.map(|fps| index as f64 / fps),
            clock: Clock::FrameRate,
            frame,
            decode: decoding.elapsed(),
        }))
    }

    fn frame_size(&self) -> Option<(u32, u32)> {
        Some((self.width, self.height))
    }
}

/// How often a followed directory is listed.
pub const FOLLOW_POLL: Duration = Duration::from_millis(50);

/// PNG frames written into a directory while the run goes, taken in name
/// order as each is whole: a file counts as written once its size and
/// modification time are the same on two listings in a row. Files there
/// when the run starts are frames too. Only `.png` names count, so an
/// acquisition program that writes under another name and renames is
/// never read half-written.
pub struct FollowSource {
    dir: PathBuf,
    width: u32,
    height: u32,
    /// Stop after this long without a new frame (None: follow until
    /// stopped).
    idle: Option<Duration>,
    /// Files taken, or queued to be.
    taken: BTreeSet<PathBuf>,
    /// Files seen once, with their size and time then.
    settling: BTreeMap<PathBuf, (u64, Option<SystemTime>)>,
    queue: VecDeque<PathBuf>,
    index: u64,
    last_frame: Instant,
}

impl FollowSource {
    /// Follows `dir`, whose frames must be `width`×`height`.
    pub fn new(
        dir: &Path,
        width: u32,
        height: u32,
        idle: Option<Duration>,
    ) -> Result<Self, StreamError> {
        if !dir.is_dir() {
            return Err(StreamError::Follow {
                path: dir.to_path_buf(),
                reason: "not a directory (--follow takes one directory)".into(),
            });
        }
        Ok(FollowSource {
            dir: dir.to_path_buf(),
            width,
            height,
            idle,
            taken: BTreeSet::new(),
            settling: BTreeMap::new(),
            queue: VecDeque::new(),
            index: 0,
            last_frame: Instant::now(),
        })
    }

    /// Lists the directory once: files unchanged since the last listing
    /// join the queue, in name order.
    fn list(&mut self) -> Result<(), StreamError> {
        let entries = std::fs::read_dir(&self.dir).map_err(|e| StreamError::Follow {
            path: self.dir.clone(),
            reason: e.to_string(),
        })?;
        let mut now: BTreeMap<PathBuf, (u64, Option<SystemTime>)> = BTreeMap::new();
        for entry in entries.flatten() {
            let path = entry.path();
            let png = path
                .extension()
                .is_some_and(|e| e.eq_ignore_ascii_case("png"));
            if !png || self.taken.contains(&path) {
                continue;
            }
            let Ok(meta) = std::fs::metadata(&path) else {
                continue;
            };
            if meta.is_file() {
                now.insert(path, (meta.len(), meta.modified().ok()));
            }
        }
        for (path, state) in &now {
            if state.0 > 0 && self.settling.get(path) == Some(state) {
                self.taken.insert(path.clone());
                self.queue.push_back(path.clone());
            }
        }
        now.retain(|path, _| !self.taken.contains(path));
        self.settling = now;
        Ok(())
    }
}

impl FrameSource for FollowSource {
    fn next_frame(&mut self) -> Result<Option<StreamFrame>, StreamError> {
        loop {
            if let Some(path) = self.queue.pop_front() {
                self.last_frame = Instant::now();
                let index = self.index;
                self.index += 1;
                let decoding = Instant::now();
                let modified = std::fs::metadata(&path).and_then(|m| m.modified());
                let frame = std::fs::read(&path)
                    .map_err(|e| FrameError::Decode(format!("cannot read the file: {e}")))
                    .and_then(|bytes| GreyFrame::from_png_of_size(&bytes, self.width, self.height));
                let timestamp_s = modified
                    .ok()
                    .and_then(|t| t.duration_since(SystemTime::UNIX_EPOCH).ok())
                    .map(|d| d.as_secs_f64());
                return Ok(Some(StreamFrame {
                    index,
                    name: path.display().to_string(),
                    timestamp_s,
                    clock: Clock::FileModified,
                    frame,
                    decode: decoding.elapsed(),
                }));
            }
            if self
                .idle
                .is_some_and(|idle| self.last_frame.elapsed() >= idle)
            {
                return Ok(None);
            }
            self.list()?;
            if self.queue.is_empty() {
                std::thread::sleep(FOLLOW_POLL);
            }
        }
    }

    fn frame_size(&self) -> Option<(u32, u32)> {
        None
    }
}
