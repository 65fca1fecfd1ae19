//! `layout-opt track LAYOUT -` and `track LAYOUT DIR --follow`: frames
//! from standard input or from a directory that fills, each frame's JSON
//! line written and flushed as the frame is done
//! ([`layout_opt::track::stream`]).

use anyhow::Context;
use clap::Args;
use layout_opt::kernel::{Interrupted, OutputPlan, StopRequest};
use layout_opt::track::stream::{
    run_stream, FollowSource, FrameSource, RawFormat, RawSource, StreamEnd, StreamRun,
    StreamTracker, Y4mSource,
};
use std::io::{BufReader, BufWriter, Write};
use std::path::{Path, PathBuf};
use std::time::Duration;

/// The flags of a stream.
#[derive(Debug, Args)]
pub struct StreamArgs {
    /// With `-` as the frames: standard input holds raw grey frames of
    /// this size, 8-bit or (`:16`) 16-bit little-endian, one after another
    /// (`ffmpeg … -f rawvideo -pix_fmt gray -`). Without it, standard
    /// input is read as YUV4MPEG2 (`ffmpeg … -f yuv4mpegpipe -pix_fmt gray
    /// -`), whose luma plane is the frame.
    #[arg(long, value_name = "WIDTHxHEIGHT[:16]")]
    raw: Option<RawFormat>,
    /// With --raw: the frames' rate, for their timestamps (without it, a
    /// raw frame's time is when it arrived).
    #[arg(long, value_name = "HZ", requires = "raw")]
    fps: Option<f64>,
    /// The frames are one directory to follow: its PNG files are tracked
    /// in name order as each is written (those there already first), until
    /// Ctrl-C or --idle.
    #[arg(long)]
    follow: bool,
    /// With --follow: stop, with success, after this many seconds without
    /// a new frame.
    #[arg(long, value_name = "SECONDS", requires = "follow")]
    idle: Option<f64>,
}

/// Where a stream's frames come from, before it is opened.
#[derive(Debug)]
pub enum StreamInput {
    /// Standard input.
    Stdin,
    /// A directory followed.
    Follow(PathBuf),
}

impl StreamArgs {
    /// The stream `frames` name with these flags, or None when they are
    /// frame files to track as a batch.
    pub fn input(&self, frames: &[PathBuf]) -> anyhow::Result<Option<StreamInput>> {
        let stdin = frames.iter().any(|f| f.as_os_str() == "-");
        anyhow::ensure!(
            !stdin || frames.len() == 1,
            "`-` (frames on standard input) must be the only frame argument"
        );
        anyhow::ensure!(
            stdin || self.raw.is_none(),
            "--raw describes frames on standard input: give `-` as the frames"
        );
        if let Some(fps) = self.fps {
            anyhow::ensure!(
                fps.is_finite() && fps > 0.0,
                "--fps must be a positive rate, got {fps}"
            );
        }
        if let Some(idle) = self.idle {
            anyhow::ensure!(
                idle.is_finite() && idle > 0.0,
                "--idle must be a positive number of seconds, got {idle}"
            );
        }
        if self.follow {
            anyhow::ensure!(!stdin, "--follow takes a directory, not `-`");
            let [dir] = frames else {
                anyhow::bail!(
                    "--follow takes one directory as the frames, got {} arguments",
                    frames.len()
                );
            };
            anyhow::ensure!(
                dir.is_dir(),
                "--follow: {} is not a directory",
                dir.display()
            );
            return Ok(Some(StreamInput::Follow(dir.clone())));
        }
        Ok(stdin.then_some(StreamInput::Stdin))
    }

    /// Opens the stream (for standard input in Y4M, reads its header).
    fn open(
        &self,
        input: &StreamInput,
        camera_size: (u32, u32),
    ) -> anyhow::Result<Box<dyn FrameSource>> {
        Ok(match input {
            StreamInput::Stdin => {
                let stdin = BufReader::with_capacity(1 << 20, std::io::stdin());
                match self.raw {
                    Some(format) => Box::new(RawSource::new(stdin, format, self.fps)),
                    None => Box::new(Y4mSource::new(stdin).context("standard input")?),
                }
            }
            StreamInput::Follow(dir) => Box::new(FollowSource::new(
                dir,
                camera_size.0,
                camera_size.1,
                self.idle.map(Duration::from_secs_f64),
            )?),
        })
    }
}

/// What the stream reads besides its frames, and where its lines go.
pub struct StreamJob<'a> {
    /// Files the run reads (the layout, the set), each with its argument.
    pub sources: Vec<(&'static str, &'a Path)>,
    /// `--output`, or None for standard output.
    pub output: Option<&'a Path>,
    /// What tracks each frame.
    pub tracker: &'a dyn StreamTracker,
    /// The camera's width and height.
    pub camera_size: (u32, u32),
    /// The run in words, for the summary ("7 spheres of …").
    pub describe: String,
}

/// Tracks the stream, then says on standard error what it did and what
/// each stage's latency was.
pub fn run(args: &StreamArgs, input: &StreamInput, job: StreamJob<'_>) -> anyhow::Result<()> {
    let mut plan = OutputPlan::new();
    for (what, path) in &job.sources {
        plan.input(*what, path);
    }
    if let StreamInput::Follow(dir) = input {
        plan.input("IMAGES", dir);
    }
    if let Some(path) = job.output {
        plan.stream("--output", path);
    }
    let outputs = plan.open()?;
    let source = args.open(input, job.camera_size)?;
    let mut out: Box<dyn Write> = match job.output {
        Some(path) => Box::new(BufWriter::new(outputs.open_stream(path)?)),
        None => Box::new(std::io::stdout().lock()),
    };
    // From here on the first Ctrl-C asks the run to stop after its frame.
    StopRequest::watch();
    let run = run_stream(
        source,
        job.camera_size,
        job.tracker,
        &mut out,
        &StopRequest::requested,
    )?;
    drop(out);
    eprintln!("{}", summary(&run, &job.describe));
    let kept = match job.output {
        Some(path) => format!(
            "the lines of {} frames are in {}",
            run.frames,
            path.display()
        ),
        None => format!("the lines of {} frames are written", run.frames),
    };
    match run.end {
        StreamEnd::Finished => Ok(()),
        StreamEnd::Stopped => Err(Interrupted::keeping(format!("interrupted; {kept}")).into()),
        StreamEnd::Failed(error) => Err(anyhow::anyhow!("{error}; {kept}")),
    }
}

/// "tracked … of … frames …" and each stage's latency.
fn summary(run: &StreamRun, describe: &str) -> String {
    let mut text = format!(
        "stream: {} pose(s) from {} frames with {describe}",
        run.posed, run.frames
    );
    let stages = run.latency_summary();
    if !stages.is_empty() {
        text.push_str("\nlatency per frame, ms (median / 95th percentile / largest):");
        for (stage, s) in stages {
            text.push_str(&format!(
                "\n  {stage:<8} {:>8.3} {:>8.3} {:>8.3}",
                s.median, s.p95, s.max
            ));
        }
    }
    text
}
