//! `track`'s run: frames from files or directories, analysed in parallel
//! (results in input order, independent of the thread count), progress and
//! interruption through an [`Observer`], outputs written atomically.

use super::analysis::{analyse, FrameAnalysis, TrackError};
use super::config::TrackConfig;
use super::frame::GreyFrame;
use super::refine::Refiner;
use super::report;
use super::set::{analyse_set, set_json_lines, SetFrameAnalysis, SetTrackConfig};
use crate::config::ConfigError;
use crate::kernel::{OutputError, OutputPlan, Outputs};
use crate::observer::{watch, Observer};
use rayon::prelude::*;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

/// Name of the analysis phase, for progress.
pub const PHASE_TRACK: &str = "tracking";

/// Where the outputs go, and the files besides the frames that the run
/// reads (none of which an output may be).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TrackOutputs {
    /// Files the run reads besides the frames, each with the argument that
    /// named it (the layout, the set).
    pub sources: Vec<(String, PathBuf)>,
    /// JSON lines file (None: the caller takes the text).
    pub json_lines: Option<PathBuf>,
    /// CSV table.
    pub csv: Option<PathBuf>,
    /// Directory of overlay PNGs (created if missing).
    pub overlay_dir: Option<PathBuf>,
}

/// Why a run could not be made or finished.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum WorkflowError {
    /// The configuration is invalid.
    #[error(transparent)]
    Config(#[from] ConfigError),
    /// An input path is neither a file nor a readable directory.
    #[error("cannot read {path}: {reason}")]
    Input {
        /// The path.
        path: PathBuf,
        /// What went wrong.
        reason: String,
    },
    /// No frames to track.
    #[error("no frames: the inputs hold no .png files")]
    NoFrames,
    /// The outputs were refused (one is an input, or taken by another
    /// run) or could not be written.
    #[error(transparent)]
    Output(#[from] OutputError),
    /// The caller asked to stop; nothing was written.
    #[error("interrupted; no output written")]
    Interrupted,
}

/// The frames of `inputs`: files as given, directories' `.png` entries
/// (not recursive) sorted by name. A path that does not exist is an error;
/// an entry that cannot be read (a broken link) is kept, and gets its
/// frame's error record.
pub fn expand_inputs(inputs: &[PathBuf]) -> Result<Vec<PathBuf>, WorkflowError> {
    let mut frames = Vec::new();
    for path in inputs {
        if std::fs::symlink_metadata(path).is_err() {
            return Err(WorkflowError::Input {
                path: path.clone(),
                reason: "no such file or directory".into(),
            });
        }
        if path.is_dir() {
            let entries = std::fs::read_dir(path).map_err(|e| WorkflowError::Input {
                path: path.clone(),
                reason: e.to_string(),
            })?;
            let mut found: Vec<PathBuf> = entries
                .filter_map(|entry| entry.ok().map(|e| e.path()))
                .filter(|p| {
                    !p.is_dir() && p.extension().is_some_and(|e| e.eq_ignore_ascii_case("png"))
                })
                .collect();
            found.sort();
            frames.extend(found);
        } else {
            frames.push(path.clone());
        }
    }
    if frames.is_empty() {
        return Err(WorkflowError::NoFrames);
    }
    Ok(frames)
}

/// What a run produced.
#[derive(Debug)]
pub struct TrackRun {
    /// Each frame's name and analysis, in input order.
    pub frames: Vec<(String, FrameAnalysis)>,
    /// The JSON-lines text (also written when asked).
    pub json_lines: String,
}

impl TrackRun {
    /// Frames with a pose.
    pub fn tracked(&self) -> usize {
        self.frames
            .iter()
            .filter(|(_, a)| a.outcome.is_ok())
            .count()
    }

    /// Over the refined frames, the spheres whose render the likeness
    /// check compared with the frame, and those of them it found unlike
    /// (their corrections withdrawn; [`super::likeness::Likeness`]).
    pub fn unlike_spheres(&self) -> (usize, usize) {
        self.frames
            .iter()
            .filter_map(|(_, a)| a.outcome.as_ref().ok()?.refinement.as_ref())
            .flat_map(|r| r.likeness.iter().flatten())
            .fold((0, 0), |(compared, unlike), l| {
                (compared + 1, unlike + usize::from(!l.matches()))
            })
    }
}

/// Tracks every frame of `inputs`, each refined by `refiner` when given
/// ([`super::refine`]; its camera must be `config`'s), and writes the
/// outputs.
pub fn run(
    config: &TrackConfig,
    refiner: Option<&Refiner>,
    inputs: &[PathBuf],
    outputs: &TrackOutputs,
    observer: &mut impl Observer,
) -> Result<TrackRun, WorkflowError> {
    config.validate()?;
    if let Some(refiner) = refiner {
        refiner.check(config)?;
    }
    let paths = expand_inputs(inputs)?;
    let files = open_outputs(&paths, outputs)?;
    let frames = each_frame(observer, &paths, |path| {
        track_file(
            config,
            refiner,
            path,
            outputs.overlay_dir.as_deref(),
            &files,
        )
    })?
    .into_iter()
    .collect::<Result<Vec<(String, FrameAnalysis)>, _>>()?;
    let json_lines = report::json_lines(&frames);
    if let Some(path) = &outputs.json_lines {
        files.stage(path, json_lines.as_bytes())?;
    }
    if let Some(path) = &outputs.csv {
        files.stage(path, report::csv(&frames).as_bytes())?;
    }
    files.commit()?;
    Ok(TrackRun { frames, json_lines })
}

/// The run's outputs, checked against its frames and sources and locked
/// before any frame is read ([`crate::kernel::outputs`]).
fn open_outputs(frames: &[PathBuf], outputs: &TrackOutputs) -> Result<Outputs, WorkflowError> {
    let mut plan = OutputPlan::new();
    plan.inputs("IMAGES", frames);
    for (what, path) in &outputs.sources {
        plan.input(what.as_str(), path);
    }
    if let Some(path) = &outputs.json_lines {
        plan.file("--output", path);
    }
    if let Some(path) = &outputs.csv {
        plan.file("--csv", path);
    }
    if let Some(dir) = &outputs.overlay_dir {
        plan.dir("--overlay", dir);
        for frame in frames {
            plan.file_in_dir("--overlay", overlay_path(dir, frame));
        }
    }
    Ok(plan.open()?)
}

/// Where the overlay of `frame` goes.
fn overlay_path(dir: &Path, frame: &Path) -> PathBuf {
    let stem = frame
        .file_stem()
        .map_or("frame".into(), |s| s.to_string_lossy().into_owned());
    dir.join(format!("{stem}.overlay.png"))
}

/// What a `track --set` run produced.
#[derive(Debug)]
pub struct SetTrackRun {
    /// Each frame's name and analysis, in input order.
    pub frames: Vec<(String, SetFrameAnalysis)>,
    /// The JSON-lines text (also written when asked): one line per marker
    /// found, or one per frame without any.
    pub json_lines: String,
}

/// Tracks every frame of `inputs` against the markers of a set
/// ([`super::set`]) and writes the JSON lines when asked (the CSV table
/// and overlays are not made for sets: the outputs' other fields must be
/// empty).
pub fn run_set(
    config: &SetTrackConfig,
    inputs: &[PathBuf],
    outputs: &TrackOutputs,
    observer: &mut impl Observer,
) -> Result<SetTrackRun, WorkflowError> {
    config.validate()?;
    if outputs.csv.is_some() || outputs.overlay_dir.is_some() {
        return Err(WorkflowError::Config(ConfigError::new(
            "outputs",
            "a set's frames give JSON lines only (no CSV table or overlays)",
        )));
    }
    let paths = expand_inputs(inputs)?;
    let files = open_outputs(&paths, outputs)?;
    let frames = each_frame(observer, &paths, |path| {
        let name = path.display().to_string();
        let analysis = match std::fs::read(path)
            .map_err(|e| format!("cannot read the file: {e}"))
            .and_then(|bytes| {
                let camera = &config.markers[0].1.camera;
                GreyFrame::from_png_of_size(&bytes, camera.width(), camera.height())
                    .map_err(|e| e.to_string())
            }) {
            Ok(frame) => analyse_set(config, &frame),
            Err(error) => SetFrameAnalysis::unread(error),
        };
        (name, analysis)
    })?;
    let json_lines = set_json_lines(&frames);
    if let Some(path) = &outputs.json_lines {
        files.stage(path, json_lines.as_bytes())?;
    }
    files.commit()?;
    Ok(SetTrackRun { frames, json_lines })
}

/// `track` applied to every path in parallel, in input order, with
/// progress as [`PHASE_TRACK`] through `observer`, which may ask to stop.
fn each_frame<T: Send>(
    observer: &mut impl Observer,
    paths: &[PathBuf],
    track: impl Fn(&Path) -> T + Sync,
) -> Result<Vec<T>, WorkflowError> {
    let done = AtomicU64::new(0);
    let stop = AtomicBool::new(false);
    let frames: Option<Vec<T>> = watch(
        observer,
        PHASE_TRACK,
        paths.len() as u64,
        || done.load(Ordering::Relaxed),
        Some(&stop),
        || {
            paths
                .par_iter()
                .map(|path| {
                    if stop.load(Ordering::Relaxed) {
                        return None;
                    }
                    let result = track(path);
                    done.fetch_add(1, Ordering::Relaxed);
                    Some(result)
                })
                .collect()
        },
    );
    match frames {
        Some(frames) if !stop.load(Ordering::SeqCst) => Ok(frames),
        _ => Err(WorkflowError::Interrupted),
    }
}

/// One file: read, analyse and (when asked) write its overlay.
fn track_file(
    config: &TrackConfig,
    refiner: Option<&Refiner>,
    path: &Path,
    overlay_dir: Option<&Path>,
    files: &Outputs,
) -> Result<(String, FrameAnalysis), WorkflowError> {
    let name = path.display().to_string();
    let bytes = match std::fs::read(path) {
        Ok(bytes) => bytes,
        Err(e) => {
            let analysis = FrameAnalysis {
                outcome: Err(TrackError::Frame(super::frame::FrameError::Decode(
                    format!("cannot read the file: {e}"),
                ))),
                detection: None,
                pose: None,
            };
            return Ok((name, analysis));
        }
    };
    let frame =
        match GreyFrame::from_png_of_size(&bytes, config.camera.width(), config.camera.height()) {
            Ok(frame) => frame,
            Err(error) => {
                let analysis = FrameAnalysis {
                    outcome: Err(error.into()),
                    detection: None,
                    pose: None,
                };
                return Ok((name, analysis));
            }
        };
    let mut analysis = analyse(config, &frame);
    if let Some(refiner) = refiner {
        analysis = refiner.refine(config, &frame, analysis);
    }
    if let Some(dir) = overlay_dir {
        let png = report::overlay_png(
            &frame,
            &analysis,
            &config.camera,
            &config.object,
            config.radius_mm(),
            analysis.pose.as_ref(),
        );
        files.stage(&overlay_path(dir, path), &png)?;
    }
    Ok((name, analysis))
}
