//! The `characterise` run: the frames' labelled centres read (grey frames
//! through `track`'s reading, `track`'s JSON lines, or `solve` batches),
//! the part
//! characterised, and the characterised layout with its report written
//! together, or nothing (a refusal writes nothing).

use super::report;
use super::{characterise, Characterisation, CharacteriseConfig, CharacteriseError, FrameCentres};
use crate::camera::Camera;
use crate::config::ConfigError;
use crate::kernel::{OutputError, OutputPlan};
use crate::layout::Layout;
use crate::observer::Observer;
use crate::pose::Pose;
use crate::track::analysis::projected_centre_normalised;
use crate::track::refine::Refiner;
use crate::track::workflow::{expand_inputs, run as run_track, TrackOutputs, WorkflowError};
use crate::track::TrackConfig;
use nalgebra::{Matrix3, Rotation3, Vector2, Vector3};
use std::path::{Path, PathBuf};

/// Where the frames' centres come from.
#[derive(Debug)]
pub enum Source<'a> {
    /// Grey PNG frames (files or directories), read as `track` reads them.
    Frames {
        /// `track`'s configuration (the nominal layout's).
        track: &'a TrackConfig,
        /// `--refine`'s render-and-compare, if asked.
        refiner: Option<&'a Refiner>,
        /// The frames.
        inputs: &'a [PathBuf],
    },
    /// `track`'s JSON-lines files, or `solve` batch files (a JSON object
    /// with `problems`: each problem a frame, its object points the
    /// nominal's, which label its image points).
    Records {
        /// The files.
        inputs: &'a [PathBuf],
    },
}

/// Where the outputs go, and the files besides the frames that the run
/// reads.
#[derive(Debug, Clone, PartialEq)]
pub struct CharacteriseOutputs {
    /// Files read besides the frames, each with the argument naming it.
    pub sources: Vec<(String, PathBuf)>,
    /// The characterised layout (JSON); the report goes beside it.
    pub layout: PathBuf,
}

impl CharacteriseOutputs {
    /// The report's Markdown and JSON beside the layout:
    /// `STEM-report.md`, `STEM-report.json`.
    pub fn report_paths(&self) -> (PathBuf, PathBuf) {
        let stem = self
            .layout
            .file_stem()
            .map_or("characterised".into(), |s| s.to_string_lossy().into_owned());
        let dir = self.layout.parent().unwrap_or(Path::new(""));
        (
            dir.join(format!("{stem}-report.md")),
            dir.join(format!("{stem}-report.json")),
        )
    }
}

/// Why a run could not be made or finished.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum CharacteriseWorkflowError {
    /// Reading the frames failed, or the run was interrupted.
    #[error(transparent)]
    Track(#[from] WorkflowError),
    /// A JSON-lines record cannot be used.
    #[error("{path}, line {line}: {reason}")]
    Record {
        /// The file.
        path: PathBuf,
        /// Its line (1-based).
        line: usize,
        /// What is wrong.
        reason: String,
    },
    /// The inputs mix frames and records.
    #[error("the inputs mix PNG frames and JSON-lines records; give one kind")]
    Mixed,
    /// The characterisation refused or failed; nothing was written.
    #[error(transparent)]
    Characterise(#[from] CharacteriseError),
    /// The outputs were refused or could not be written.
    #[error(transparent)]
    Output(#[from] OutputError),
}

/// What a run produced.
#[derive(Debug)]
pub struct CharacteriseRun {
    /// The characterisation.
    pub characterisation: Characterisation,
    /// Frames given.
    pub frames_given: usize,
    /// The report paths written.
    pub report: (PathBuf, PathBuf),
}

/// Whether a path holds JSON lines (by its extension).
pub fn is_records(path: &Path) -> bool {
    path.extension().is_some_and(|e| {
        ["jsonl", "ndjson", "json"]
            .iter()
            .any(|x| e.eq_ignore_ascii_case(x))
    })
}

/// Reads the centres, characterises and writes the outputs.
pub fn run(
    config: &CharacteriseConfig,
    source: Source<'_>,
    outputs: &CharacteriseOutputs,
    command: &str,
    observer: &mut impl Observer,
) -> Result<CharacteriseRun, CharacteriseWorkflowError> {
    config.validate().map_err(CharacteriseError::from)?;
    let inputs = match &source {
        Source::Frames { inputs, .. } => expand_inputs(inputs)?,
        Source::Records { inputs } => inputs.to_vec(),
    };
    let (md, json) = outputs.report_paths();
    let mut plan = OutputPlan::new();
    plan.inputs("FRAMES", &inputs);
    for (what, path) in &outputs.sources {
        plan.input(what.as_str(), path);
    }
    plan.file("--out", &outputs.layout);
    plan.file("--out (report)", &md);
    plan.file("--out (report JSON)", &json);
    let files = plan.open()?;
    let frames = match source {
        Source::Frames {
            track,
            refiner,
            inputs,
        } => {
            if track.camera != config.camera {
                return Err(CharacteriseError::Config(ConfigError::new(
                    "camera",
                    "the tracking camera differs from the characterisation's",
                ))
                .into());
            }
            let run = run_track(track, refiner, inputs, &TrackOutputs::default(), observer)?;
            run.frames
                .iter()
                .map(|(name, analysis)| frame_centres(name, analysis, track))
                .collect::<Vec<_>>()
        }
        Source::Records { inputs } => {
            let mut frames = Vec::new();
            for path in inputs {
                frames.extend(read_records(path, &config.camera, &config.nominal)?);
            }
            frames
        }
    };
    let frames_given = frames.len();
    let (usable, unusable): (Vec<_>, Vec<_>) = frames.into_iter().partition(|f| f.is_ok());
    let usable: Vec<FrameCentres> = usable
        .into_iter()
        .map(|f| f.expect("partitioned"))
        .collect();
    let mut characterisation = match characterise(config, &usable) {
        Err(CharacteriseError::TooFewFrames {
            usable: n,
            needed,
            skipped,
            ..
        }) => {
            let mut reasons: Vec<String> = unusable
                .iter()
                .map(|f| {
                    let skipped = f.as_ref().expect_err("partitioned");
                    format!("{}: {}", skipped.frame, skipped.reason)
                })
                .collect();
            if !skipped.is_empty() {
                reasons.push(skipped);
            }
            return Err(CharacteriseError::TooFewFrames {
                usable: n,
                given: frames_given,
                needed,
                skipped: reasons.join("; "),
            }
            .into());
        }
        result => result?,
    };
    for f in unusable {
        let skipped = f.expect_err("partitioned");
        characterisation.dropped.push(skipped);
    }
    let layout = characterisation.layout(&config.nominal, command);
    files.stage(&outputs.layout, layout.to_json().as_bytes())?;
    files.stage(
        &md,
        report::markdown(
            &characterisation,
            command,
            &outputs.layout.display().to_string(),
        )
        .as_bytes(),
    )?;
    files.stage(&json, report::json(&characterisation, command).as_bytes())?;
    files.commit()?;
    Ok(CharacteriseRun {
        characterisation,
        frames_given,
        report: (md, json),
    })
}

/// A tracked frame's labelled whole centres (those in its pose), or why it
/// has none.
fn frame_centres(
    name: &str,
    analysis: &crate::track::analysis::FrameAnalysis,
    config: &TrackConfig,
) -> Result<FrameCentres, super::SkippedFrame> {
    let skipped = |reason: String| super::SkippedFrame {
        frame: name.to_string(),
        reason,
    };
    let tracked = analysis
        .outcome
        .as_ref()
        .map_err(|e| skipped(format!("not tracked with the nominal layout: {e}")))?;
    let (Some(pose), Some(detection)) = (analysis.pose, analysis.detection.as_ref()) else {
        return Err(skipped("no pose".into()));
    };
    let centres = detection
        .blobs
        .iter()
        .filter(|b| !b.hidden())
        .filter_map(|b| {
            let label = b.label?;
            tracked.figures.residuals_px[label]?;
            Some((label, projected_centre_normalised(b, config.centre)))
        })
        .collect();
    Ok(FrameCentres {
        name: name.to_string(),
        pose,
        centres,
    })
}

/// One frame read from a file, or why it is skipped.
type ReadFrame = Result<FrameCentres, super::SkippedFrame>;

/// The frames of a `track` JSON-lines file ([`read_track_lines`]) or of a
/// `solve` batch ([`read_batch`]), by its content: a batch is one JSON
/// object with `problems`.
fn read_records(
    path: &Path,
    camera: &Camera,
    nominal: &Layout,
) -> Result<Vec<ReadFrame>, CharacteriseWorkflowError> {
    let text = std::fs::read_to_string(path).map_err(|e| CharacteriseWorkflowError::Record {
        path: path.to_path_buf(),
        line: 0,
        reason: format!("cannot read: {e}"),
    })?;
    let batch = serde_json::from_str::<serde_json::Value>(&text)
        .ok()
        .is_some_and(|v| v.get("problems").is_some());
    if batch {
        read_batch(path, &text, nominal)
    } else {
        read_track_lines(path, &text, camera)
    }
}

/// Largest distance, mm, between a batch's object point and the nominal
/// sphere centre it names.
pub const OBJECT_POINT_MATCH_MM: f64 = 1e-3;

/// The frames of a `solve` batch: each problem's image points, labelled by
/// the nominal sphere its object point is (within
/// [`OBJECT_POINT_MATCH_MM`]), undistorted with the batch's camera; a
/// problem with `sphere_diameter` has ellipse centres, each turned into
/// the projected centre (`m₀ (C_z² − r²) / C_z²`, the sphere's depth `C_z`
/// at the pose solved from them). The starting pose is
/// `ml`'s.
fn read_batch(
    path: &Path,
    text: &str,
    nominal: &Layout,
) -> Result<Vec<ReadFrame>, CharacteriseWorkflowError> {
    let batch =
        crate::batch::Batch::from_json(text).map_err(|e| CharacteriseWorkflowError::Record {
            path: path.to_path_buf(),
            line: 0,
            reason: e.to_string(),
        })?;
    let centres = nominal.positions();
    Ok(batch
        .problems
        .iter()
        .map(|(id, problem)| {
            let skipped = |reason: String| super::SkippedFrame {
                frame: format!("{}#{id}", path.display()),
                reason,
            };
            let problem = problem.as_ref().map_err(|e| skipped(e.clone()))?;
            let name = format!("{}#{id}", path.display());
            batch_frame(name, &batch.camera, problem, &centres).map_err(skipped)
        })
        .collect())
}

/// One problem as a frame named `name`: its pose and labelled projected
/// centres.
fn batch_frame(
    name: String,
    camera: &Camera,
    problem: &crate::batch::ProblemInput,
    nominal: &[Vector3<f64>],
) -> Result<FrameCentres, String> {
    if problem.object_points.len() != problem.image_points.len() {
        return Err(format!(
            "{} object points for {} image points",
            problem.object_points.len(),
            problem.image_points.len()
        ));
    }
    let mut labels = Vec::with_capacity(problem.object_points.len());
    for (k, p) in problem.object_points.iter().enumerate() {
        let p = Vector3::from(*p);
        let label = nominal
            .iter()
            .position(|x| (x - p).norm() <= OBJECT_POINT_MATCH_MM)
            .ok_or_else(|| {
                format!(
                    "object point {k} ({}, {}, {}) is no sphere centre of the nominal layout",
                    p.x, p.y, p.z
                )
            })?;
        labels.push(label);
    }
    let image = problem
        .image_points
        .iter()
        .map(|u| camera.pixel_to_normalised(&Vector2::from(*u)))
        .collect::<Result<Vec<_>, _>>()
        .map_err(|e| e.to_string())?;
    let object: Vec<Vector3<f64>> = labels.iter().map(|&i| nominal[i]).collect();
    let pose = crate::pnp::Solver::Ml
        .solve_best(&object, &image)
        .map_err(|e| format!("no starting pose: {e}"))?;
    let centres = labels
        .iter()
        .zip(&object)
        .zip(&image)
        .map(|((&label, x), m)| {
            let shrink = match problem.sphere_diameter {
                Some(d) => {
                    let r = 0.5 * d;
                    // m₀ = π(C) · C_z² / (C_z² − r²) (the track conic's).
                    let depth_squared = pose.transform(x).z.powi(2);
                    1.0 + r * r / (depth_squared - r * r)
                }
                None => 1.0,
            };
            (label, m / shrink)
        })
        .collect();
    Ok(FrameCentres {
        name,
        pose,
        centres,
    })
}

/// The frames of a `track` JSON-lines file: each tracked record's pose and
/// its whole labelled blobs' projected centres (`centre_px`, less a
/// `bias` where `--refine` measured one), undistorted. Error records are
/// frames skipped.
fn read_track_lines(
    path: &Path,
    text: &str,
    camera: &Camera,
) -> Result<Vec<ReadFrame>, CharacteriseWorkflowError> {
    let mut frames = Vec::new();
    for (k, line) in text.lines().enumerate() {
        if line.trim().is_empty() {
            continue;
        }
        let fail = |reason: String| CharacteriseWorkflowError::Record {
            path: path.to_path_buf(),
            line: k + 1,
            reason,
        };
        let record: serde_json::Value =
            serde_json::from_str(line).map_err(|e| fail(format!("not JSON: {e}")))?;
        let name = record["frame"]
            .as_str()
            .map_or_else(|| format!("{}:{}", path.display(), k + 1), str::to_string);
        if let Some(error) = record["error"].as_str() {
            frames.push(Err(super::SkippedFrame {
                frame: name,
                reason: format!("not tracked: {error}"),
            }));
            continue;
        }
        let pose = record_pose(&record).map_err(&fail)?;
        let residuals = record["residuals_px"].as_array();
        let mut centres = Vec::new();
        for blob in record["blobs"]
            .as_array()
            .ok_or_else(|| fail("no \"blobs\" array: not a track record".into()))?
        {
            let Some(label) = blob["label"].as_u64() else {
                continue;
            };
            let label = label as usize;
            let whole = blob["hidden_because"]
                .as_array()
                .is_none_or(|h| h.is_empty());
            let in_pose = residuals.is_none_or(|r| r.get(label).is_some_and(|v| !v.is_null()));
            if !(whole && in_pose) {
                continue;
            }
            let centre = pair(&blob["centre_px"])
                .ok_or_else(|| fail("a labelled blob without \"centre_px\" [u, v]".into()))?;
            let bias = pair(&blob["bias"]["px"]).unwrap_or_default();
            let normalised = camera
                .pixel_to_normalised(&(centre - bias))
                .map_err(|e| fail(format!("centre_px {centre}: {e}")))?;
            centres.push((label, normalised));
        }
        frames.push(Ok(FrameCentres {
            name,
            pose,
            centres,
        }));
    }
    Ok(frames)
}

/// `[u, v]` as a vector.
fn pair(value: &serde_json::Value) -> Option<Vector2<f64>> {
    let a = value.as_array()?;
    match a.as_slice() {
        [u, v] => {
            Some(Vector2::new(u.as_f64()?, v.as_f64()?)).filter(|p| p.iter().all(|x| x.is_finite()))
        }
        _ => None,
    }
}

/// A record's `R` and `t`.
fn record_pose(record: &serde_json::Value) -> Result<Pose, String> {
    let rows = record["R"]
        .as_array()
        .filter(|r| r.len() == 3)
        .ok_or("no \"R\" (3×3) in a tracked record")?;
    let mut r = Matrix3::zeros();
    for (i, row) in rows.iter().enumerate() {
        let row = row
            .as_array()
            .filter(|r| r.len() == 3)
            .ok_or("\"R\" must be 3×3")?;
        for (j, v) in row.iter().enumerate() {
            r[(i, j)] = v.as_f64().ok_or("\"R\" must hold numbers")?;
        }
    }
    let t = record["t"]
        .as_array()
        .filter(|t| t.len() == 3)
        .ok_or("no \"t\" [x, y, z] in a tracked record")?;
    let t: Vec<f64> = t
        .iter()
        .map(|v| v.as_f64().ok_or("\"t\" must hold numbers"))
        .collect::<Result<_, _>>()?;
    if !(r.iter().chain(&t).all(|v| v.is_finite()))
        || ((r.transpose() * r) - Matrix3::identity()).norm() > 1e-6
    {
        return Err("\"R\" is not a rotation, or R or t is not finite".into());
    }
    Ok(Pose::new(
        Rotation3::from_matrix_unchecked(r),
        Vector3::new(t[0], t[1], t[2]),
    ))
}
