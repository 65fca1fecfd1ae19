//! `track` on a stream: frames from standard input (YUV4MPEG2 or raw grey)
//! or from a directory that keeps filling ([`source`]), tracked one at a
//! time as they come, each frame's JSON line written and flushed as soon
//! as the frame is done.
//!
//! A stream's line is the frame's `track` record (docs/formats.md,
//! "`track` output") with the frame's `index`, `timestamp_s` and `clock`
//! before it and its `latency_ms` after. A frame whose bytes are not an
//! image gets an error record and the stream goes on; a stream that cannot
//! go on ends the run with a [`StreamError`], every line before it
//! written. A reader thread waits for the frames, so that a stop request
//! is answered within one frame's analysis even while the stream is
//! silent.

pub mod source;

use super::analysis::{analyse_timed, FrameAnalysis, TrackError};
use super::config::TrackConfig;
use super::refine::Refiner;
use super::report;
use super::set::{analyse_set, set_records, SetFrameAnalysis, SetTrackConfig};
use serde::Serialize;
pub use source::{
    Clock, FollowSource, FrameSource, RawFormat, RawSource, StreamError, StreamFrame, Y4mSource,
};
use std::io::Write;
use std::sync::mpsc::{sync_channel, RecvTimeoutError};
use std::time::{Duration, Instant};

/// How often the run asks whether to stop while it waits for a frame.
const STOP_POLL: Duration = Duration::from_millis(20);

/// Frames read ahead of the one being tracked.
const READ_AHEAD: usize = 2;

/// Where one frame's time went, in milliseconds.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct Latency {
    /// From the frame's bytes to the grey frame ([`StreamFrame::decode`]).
    pub decode: f64,
    /// Threshold, components, blob figures and centres (one marker).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub detect: Option<f64>,
    /// Identification, pose and covariance (one marker).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub solve: Option<f64>,
    /// Render-and-compare rounds (`--refine`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub refine: Option<f64>,
    /// Everything after the decode (with a set, every marker's search).
    pub analyse: f64,
    /// Decode and analysis.
    pub total: f64,
}

fn ms(duration: Duration) -> f64 {
    duration.as_secs_f64() * 1e3
}

/// One line of a stream: the frame's place and time, its record, and its
/// latency.
#[derive(Serialize)]
struct StreamLine<'a, R: Serialize> {
    index: u64,
    timestamp_s: Option<f64>,
    clock: source::Clock,
    #[serde(flatten)]
    record: R,
    latency_ms: &'a Latency,
}

fn write_line(
    out: &mut dyn Write,
    frame: &StreamFrame,
    record: impl Serialize,
    latency: &Latency,
) -> std::io::Result<()> {
    let line = StreamLine {
        index: frame.index,
        timestamp_s: frame.timestamp_s,
        clock: frame.clock,
        record,
        latency_ms: latency,
    };
    serde_json::to_writer(&mut *out, &line)?;
    out.write_all(b"\n")
}

/// What tracks a stream's frames and writes their lines.
pub trait StreamTracker {
    /// Tracks `frame`, whose decode `latency` already holds, completes
    /// `latency` and writes the frame's line(s) to `out`; returns how many
    /// markers it posed.
    fn track(
        &self,
        frame: &StreamFrame,
        latency: &mut Latency,
        out: &mut dyn Write,
    ) -> std::io::Result<usize>;
}

/// One marker ([`TrackConfig`]), refined when a refiner is given.
#[derive(Debug, Clone, Copy)]
pub struct MarkerTracker<'a> {
    /// The validated configuration.
    pub config: &'a TrackConfig,
    /// The render-and-compare refiner (`--refine`), checked against
    /// `config`.
    pub refiner: Option<&'a Refiner>,
}

impl StreamTracker for MarkerTracker<'_> {
    fn track(
        &self,
        frame: &StreamFrame,
        latency: &mut Latency,
        out: &mut dyn Write,
    ) -> std::io::Result<usize> {
        let start = Instant::now();
        let analysis = match &frame.frame {
            Ok(grey) => {
                let (analysis, times) = analyse_timed(self.config, grey);
                latency.detect = Some(ms(times.detect));
                latency.solve = Some(ms(times.solve));
                match self.refiner {
                    Some(refiner) => {
                        let refining = Instant::now();
                        let refined = refiner.refine(self.config, grey, analysis);
                        latency.refine = Some(ms(refining.elapsed()));
                        refined
                    }
                    None => analysis,
                }
            }
            Err(error) => FrameAnalysis {
                outcome: Err(TrackError::Frame(error.clone())),
                detection: None,
                pose: None,
            },
        };
        latency.analyse = ms(start.elapsed());
        latency.total = latency.decode + latency.analyse;
        write_line(out, frame, report::record(&frame.name, &analysis), latency)?;
        Ok(usize::from(analysis.outcome.is_ok()))
    }
}

/// Every marker of a set ([`SetTrackConfig`], validated): one line per
/// marker found, or one for a frame without any.
#[derive(Debug, Clone, Copy)]
pub struct SetTracker<'a> {
    /// The validated configuration.
    pub config: &'a SetTrackConfig,
}

impl StreamTracker for SetTracker<'_> {
    fn track(
        &self,
        frame: &StreamFrame,
        latency: &mut Latency,
        out: &mut dyn Write,
    ) -> std::io::Result<usize> {
        let start = Instant::now();
        let analysis = match &frame.frame {
            Ok(grey) => analyse_set(self.config, grey),
            Err(error) => SetFrameAnalysis::unread(error.to_string()),
        };
        latency.analyse = ms(start.elapsed());
        latency.total = latency.decode + latency.analyse;
        for record in set_records(&frame.name, &analysis) {
            write_line(out, frame, record, latency)?;
        }
        Ok(analysis.markers.len())
    }
}

/// How a stream's run ended.
#[derive(Debug)]
pub enum StreamEnd {
    /// The stream ended cleanly (or a followed directory stayed idle for
    /// the time given).
    Finished,
    /// The caller asked to stop.
    Stopped,
    /// The stream could not go on; every line before it is written.
    Failed(StreamError),
}

/// What a stream's run did.
#[derive(Debug)]
pub struct StreamRun {
    /// Frames tracked (a line written for each).
    pub frames: u64,
    /// Markers posed over them.
    pub posed: u64,
    /// Each frame's latency, in stream order.
    pub latencies: Vec<Latency>,
    /// How it ended.
    pub end: StreamEnd,
}

/// Tracks the frames of `source` as they come, each frame's lines written
/// to `out` and flushed before the next frame; `stop` is asked between
/// frames and every 20 ms while waiting for one. Frames must be
/// `camera_size`: a source that says its size first is refused at once
/// when it differs, and a frame file of another size gets an error
/// record.
pub fn run_stream(
    source: Box<dyn FrameSource>,
    camera_size: (u32, u32),
    tracker: &dyn StreamTracker,
    out: &mut dyn Write,
    stop: &dyn Fn() -> bool,
) -> Result<StreamRun, StreamError> {
    if let Some((width, height)) = source.frame_size().filter(|&s| s != camera_size) {
        return Err(StreamError::Size {
            width,
            height,
            camera_width: camera_size.0,
            camera_height: camera_size.1,
        });
    }
    let (sender, receiver) = sync_channel(READ_AHEAD);
    // Detached: a stop while it waits on a silent stream leaves it blocked
    // in its read, which ends with the process.
    std::thread::spawn(move || {
        let mut source = source;
        loop {
            let next = source.next_frame();
            let more = matches!(next, Ok(Some(_)));
            if sender.send(next).is_err() || !more {
                break;
            }
        }
    });
    let mut run = StreamRun {
        frames: 0,
        posed: 0,
        latencies: Vec::new(),
        end: StreamEnd::Finished,
    };
    loop {
        if stop() {
            run.end = StreamEnd::Stopped;
            return Ok(run);
        }
        let frame = match receiver.recv_timeout(STOP_POLL) {
            Err(RecvTimeoutError::Timeout) => continue,
            Err(RecvTimeoutError::Disconnected) | Ok(Ok(None)) => return Ok(run),
            Ok(Err(error)) => {
                run.end = StreamEnd::Failed(error);
                return Ok(run);
            }
            Ok(Ok(Some(frame))) => frame,
        };
        let mut latency = Latency {
            decode: ms(frame.decode),
            ..Latency::default()
        };
        let written = tracker
            .track(&frame, &mut latency, out)
            .and_then(|posed| out.flush().map(|()| posed));
        match written {
            Ok(posed) => {
                run.frames += 1;
                run.posed += posed as u64;
                run.latencies.push(latency);
            }
            Err(error) => {
                run.end = StreamEnd::Failed(StreamError::Write(error));
                return Ok(run);
            }
        }
    }
}

/// One stage's figure in a frame's [`Latency`], where the frame has it.
type Stage = fn(&Latency) -> Option<f64>;

/// The median, 95th percentile and largest of one stage's latency.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct StageSummary {
    /// Median, ms.
    pub median: f64,
    /// 95th percentile (nearest rank), ms.
    pub p95: f64,
    /// Largest, ms.
    pub max: f64,
}

impl StageSummary {
    /// Over `values` (None when there are none).
    pub fn of(mut values: Vec<f64>) -> Option<StageSummary> {
        if values.is_empty() {
            return None;
        }
        values.sort_by(f64::total_cmp);
        let rank = ((0.95 * values.len() as f64).ceil() as usize).clamp(1, values.len());
        Some(StageSummary {
            median: crate::statistics::median_of_sorted(&values),
            p95: values[rank - 1],
            max: values[values.len() - 1],
        })
    }
}

impl StreamRun {
    /// Each stage's summary over the frames that have it, in the order
    /// decode, detect, solve, refine, analyse, total.
    pub fn latency_summary(&self) -> Vec<(&'static str, StageSummary)> {
        let stages: [(&str, Stage); 6] = [
            ("decode", |l| Some(l.decode)),
            ("detect", |l| l.detect),
            ("solve", |l| l.solve),
            ("refine", |l| l.refine),
            ("analyse", |l| Some(l.analyse)),
            ("total", |l| Some(l.total)),
        ];
        stages
            .iter()
            .filter_map(|(name, of)| {
                let values: Vec<f64> = self.latencies.iter().filter_map(of).collect();
                StageSummary::of(values).map(|s| (*name, s))
            })
            .collect()
    }
}

#[cfg(test)]
mod tests;
