//! The correspondence-batch contract of `layout-opt solve`
//! (docs/formats.md, "`solve` batch").
//!
//! Input:
//! ```json
//! { "camera": {"fx":..,"fy":..,"cx":..,"cy":..,"distortion":[k1,k2,p1,p2,k3]},
//!   "problems": [ {"id": "shot-001", "object_points": [[x,y,z],...], "image_points": [[u,v],...]} ] }
//! ```
//! Pixel coordinates are raw (still distorted when distortion is given);
//! unknown fields are ignored. A malformed file is a [`BatchError`]; a bad
//! problem becomes an `error` entry and the rest of the batch still runs.
//!
//! Output: `{"solver": NAME, "results": [{"id", "rotation", "translation",
//! "reprojection_rms_px", "seconds", "start"?} | {"id", "error"}]}`, where
//! `seconds` times the solver call alone and `start` names the solver whose
//! pose a refining method (`ml`) started from.
//!
//! Unlabelled: [`Batch::solve_unlabelled`] (`solve --unlabelled`) reads
//! each problem's image points as an unordered set of blobs (up to one
//! fewer than the object points), labels them with
//! [`crate::pnp::unlabelled::identify`] and fits the final pose with the
//! chosen solver on the found labels; results add `labels`, `ambiguity`
//! and `runner_up_rms_px` (the last two `null` when no other labelling is
//! consistent).
//!
//! Spheres: with a sphere diameter (`solve --sphere-diameter D`, or
//! `"sphere_diameter"` on a problem, which takes precedence) the image points
//! are the centres of the spheres' silhouette ellipses, and `ml` fits the
//! exact sphere-image model ([`crate::pnp::ml_sphere`]); the reprojection
//! RMS is then measured against the model's ellipse centres. The other
//! solvers fit projected centres only, so a problem with a diameter and
//! another solver gets an `error` entry rather than a silently biased pose.

use crate::camera::{Camera, CameraSpec};
use crate::pnp::unlabelled::{identify, UnlabelledOptions};
use crate::pnp::{ml_sphere, Solver};
use crate::pose::{reprojection_rms_px, Pose};
use crate::sphere_image::ellipse_centre_normalised;
use nalgebra::{Vector2, Vector3};
use serde::{Deserialize, Serialize};
use std::time::Instant;

/// A batch file that cannot be used at all.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum BatchError {
    /// The file is not valid JSON or lacks the required structure.
    #[error("malformed problem file: {0}")]
    Malformed(String),
    /// The camera is unusable.
    #[error("malformed camera: {0}")]
    Camera(#[from] crate::camera::CameraError),
}

#[derive(Debug, Deserialize)]
struct RawBatch {
    camera: serde_json::Value,
    problems: Vec<serde_json::Value>,
}

/// One problem as read from the file.
#[derive(Debug, Clone, Deserialize, Serialize)]
pub struct ProblemInput {
    /// Caller's identifier (defaults to `#<index>` when absent).
    #[serde(default)]
    pub id: Option<String>,
    /// Object points, mm.
    pub object_points: Vec<[f64; 3]>,
    /// Raw pixel coordinates.
    pub image_points: Vec<[f64; 2]>,
    /// Sphere diameter, mm: the image points are ellipse centres.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sphere_diameter: Option<f64>,
}

/// A parsed batch: a camera and problems, each of which may already have
/// failed to parse.
#[derive(Debug)]
pub struct Batch {
    /// The camera of every problem.
    pub camera: Camera,
    /// The problems, in file order, with their ids.
    pub problems: Vec<(String, Result<ProblemInput, String>)>,
}

/// One entry of the output.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum ProblemResult {
    /// A solved problem.
    Solved {
        /// Caller's identifier.
        id: String,
        /// Rotation matrix, row-major, object → camera.
        rotation: [[f64; 3]; 3],
        /// Translation, mm.
        translation: [f64; 3],
        /// RMS reprojection error against the raw pixels, distortion included.
        reprojection_rms_px: f64,
        /// Wall time of the solver call alone, seconds.
        seconds: f64,
        /// The solver whose pose this one refines, if any (`ml`: `sqpnp`).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        start: Option<String>,
        /// Unlabelled solves only: for each image point, the index of its
        /// object point.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        labels: Option<Vec<usize>>,
        /// Unlabelled solves only: the refined reprojection RMS of the best
        /// other consistent labelling over that of the chosen one; `null`
        /// when no other labelling is consistent.
        #[serde(
            default,
            skip_serializing_if = "Option::is_none",
            deserialize_with = "present"
        )]
        ambiguity: Option<Option<f64>>,
        /// Unlabelled solves only: the runner-up labelling's reprojection
        /// RMS, px; `null` when no other labelling is consistent.
        #[serde(
            default,
            skip_serializing_if = "Option::is_none",
            deserialize_with = "present"
        )]
        runner_up_rms_px: Option<Option<f64>>,
    },
    /// A problem that could not be solved, and why.
    Failed {
        /// Caller's identifier.
        id: String,
        /// What was wrong.
        error: String,
    },
}

/// Reads a field that may be `null`: present means `Some`, so `null`
/// stays distinct from an absent field.
fn present<'de, D: serde::Deserializer<'de>>(d: D) -> Result<Option<Option<f64>>, D::Error> {
    Option::<f64>::deserialize(d).map(Some)
}

/// How `solve --unlabelled` identifies the blobs (module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct UnlabelledConfig {
    /// Per-blob reprojection gate, px (converted to normalised units with
    /// the smaller focal length).
    pub gate_px: f64,
    /// How many object points may have no blob.
    pub max_missing: usize,
}

/// Default gate of `solve --unlabelled`, px: 5σ at the σ = 0.5 px that
/// blob detectors reach on our spheres, so a correct blob falls outside it
/// with probability e^(−12.5) ≈ 4e-6, while a wrong labelling usually
/// misses by far more (tens of px on the near-field views).
pub const DEFAULT_GATE_PX: f64 = 2.5;

impl Default for UnlabelledConfig {
    fn default() -> Self {
        Self {
            gate_px: DEFAULT_GATE_PX,
            max_missing: 1,
        }
    }
}

/// The whole output document.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BatchOutput {
    /// Stable name of the solver used.
    pub solver: String,
    /// One entry per input problem, in input order.
    pub results: Vec<ProblemResult>,
}

/// A batch document's camera and, per problem, its id (its `id`, else
/// `#index`) and the problem parsed as `P`, or why it could not be: a
/// malformed problem stops only itself.
#[allow(clippy::type_complexity)]
fn parse_document<P: serde::de::DeserializeOwned>(
    text: &str,
) -> Result<(Camera, Vec<(String, Result<P, String>)>), BatchError> {
    let raw: RawBatch =
        serde_json::from_str(text).map_err(|e| BatchError::Malformed(e.to_string()))?;
    let spec: CameraSpec = serde_json::from_value(raw.camera)
        .map_err(|e| BatchError::Malformed(format!("camera: {e}")))?;
    let camera = spec.into_camera()?;
    let problems = raw
        .problems
        .into_iter()
        .enumerate()
        .map(|(index, value)| {
            let id = value
                .get("id")
                .and_then(|id| id.as_str().map(str::to_owned))
                .unwrap_or_else(|| format!("#{index}"));
            let parsed =
                serde_json::from_value::<P>(value).map_err(|e| format!("malformed problem: {e}"));
            (id, parsed)
        })
        .collect();
    Ok((camera, problems))
}

impl Batch {
    /// Parses a batch document.
    pub fn from_json(text: &str) -> Result<Batch, BatchError> {
        let (camera, problems) = parse_document(text)?;
        Ok(Batch { camera, problems })
    }

    /// Solves every problem with `solver`, in order.
    pub fn solve(&self, solver: Solver, on_progress: impl FnMut(usize)) -> BatchOutput {
        self.solve_with_spheres(solver, None, on_progress)
    }

    /// [`Batch::solve`] with a default sphere diameter (mm) for the problems
    /// that do not give their own `sphere_diameter`: their image points are
    /// ellipse centres (module docs).
    pub fn solve_with_spheres(
        &self,
        solver: Solver,
        sphere_diameter_mm: Option<f64>,
        on_progress: impl FnMut(usize),
    ) -> BatchOutput {
        self.solve_problems(solver, sphere_diameter_mm, None, on_progress)
    }

    /// Unlabelled solves: each problem's image points are an unordered set
    /// of blobs (up to `config.max_missing` fewer than the object points).
    /// The labelling comes from [`crate::pnp::unlabelled::identify`]; the
    /// final pose is `solver` on the found correspondences (with a sphere
    /// diameter, `ml`'s sphere-image fit). Each result adds `labels`,
    /// `ambiguity` and `runner_up_rms_px`.
    pub fn solve_unlabelled(
        &self,
        solver: Solver,
        sphere_diameter_mm: Option<f64>,
        config: UnlabelledConfig,
        on_progress: impl FnMut(usize),
    ) -> BatchOutput {
        self.solve_problems(solver, sphere_diameter_mm, Some(config), on_progress)
    }

    fn solve_problems(
        &self,
        solver: Solver,
        sphere_diameter_mm: Option<f64>,
        unlabelled: Option<UnlabelledConfig>,
        mut on_progress: impl FnMut(usize),
    ) -> BatchOutput {
        let results = self
            .problems
            .iter()
            .enumerate()
            .map(|(index, (id, problem))| {
                let result = match problem {
                    Ok(problem) => solve_one(
                        &self.camera,
                        solver,
                        id,
                        problem,
                        problem.sphere_diameter.or(sphere_diameter_mm),
                        unlabelled,
                    ),
                    Err(error) => ProblemResult::Failed {
                        id: id.clone(),
                        error: error.clone(),
                    },
                };
                on_progress(index + 1);
                result
            })
            .collect();
        BatchOutput {
            solver: solver.name().to_string(),
            results,
        }
    }
}

fn solve_one(
    camera: &Camera,
    solver: Solver,
    id: &str,
    problem: &ProblemInput,
    sphere_diameter_mm: Option<f64>,
    unlabelled: Option<UnlabelledConfig>,
) -> ProblemResult {
    let failed = |error: String| ProblemResult::Failed {
        id: id.to_string(),
        error,
    };
    let object: Vec<Vector3<f64>> = problem
        .object_points
        .iter()
        .map(|p| Vector3::new(p[0], p[1], p[2]))
        .collect();
    let pixels: Vec<Vector2<f64>> = problem
        .image_points
        .iter()
        .map(|p| Vector2::new(p[0], p[1]))
        .collect();
    let mut normalised = Vec::with_capacity(pixels.len());
    for (index, pixel) in pixels.iter().enumerate() {
        if !pixel.iter().all(|v| v.is_finite()) {
            return failed(format!("image point {index} has a non-finite coordinate"));
        }
        match camera.pixel_to_normalised(pixel) {
            Ok(m) => normalised.push(m),
            Err(e) => return failed(format!("image point {index}: {e}")),
        }
    }
    if let Some(config) = unlabelled {
        let points = ProblemPoints {
            id,
            object: &object,
            pixels: &pixels,
            normalised: &normalised,
        };
        return solve_one_unlabelled(camera, solver, points, sphere_diameter_mm, config);
    }
    if let Some(diameter_mm) = sphere_diameter_mm {
        if let Err(error) = check_sphere_diameter(diameter_mm, solver) {
            return failed(error);
        }
        let radius_mm = 0.5 * diameter_mm;
        let start = Instant::now();
        let outcome = ml_sphere::solve(&object, &normalised, radius_mm);
        let seconds = start.elapsed().as_secs_f64();
        return match outcome {
            Ok(pose) => {
                let mut result = solved(id, camera, solver, &pose, &object, &pixels, seconds);
                if let ProblemResult::Solved {
                    reprojection_rms_px,
                    ..
                } = &mut result
                {
                    *reprojection_rms_px =
                        ellipse_centre_rms_px(camera, &pose, &object, &pixels, radius_mm);
                }
                result
            }
            Err(e) => failed(e.to_string()),
        };
    }
    let start = Instant::now();
    let outcome = solver.solve_best(&object, &normalised);
    let seconds = start.elapsed().as_secs_f64();
    match outcome {
        Ok(pose) => solved(id, camera, solver, &pose, &object, &pixels, seconds),
        Err(e) => failed(e.to_string()),
    }
}

/// A problem's sphere diameter must be a positive number of mm, and only
/// `ml` fits the sphere-image model.
fn check_sphere_diameter(diameter_mm: f64, solver: Solver) -> Result<(), String> {
    if !(diameter_mm > 0.0 && diameter_mm.is_finite()) {
        return Err(format!(
            "sphere_diameter must be a positive number of mm, got {diameter_mm}"
        ));
    }
    if solver != Solver::Ml {
        return Err(format!(
            "a sphere diameter needs the ml solver, which fits the sphere-image model; {} fits projected centres and would be biased",
            solver.name()
        ));
    }
    Ok(())
}

/// One problem's points, read and checked: its id, the object points, the
/// observed pixels and their undistorted normalised coordinates.
#[derive(Debug, Clone, Copy)]
struct ProblemPoints<'a> {
    id: &'a str,
    object: &'a [Vector3<f64>],
    pixels: &'a [Vector2<f64>],
    normalised: &'a [Vector2<f64>],
}

/// One unlabelled problem: identify, then the final fit on the labels.
fn solve_one_unlabelled(
    camera: &Camera,
    solver: Solver,
    points: ProblemPoints<'_>,
    sphere_diameter_mm: Option<f64>,
    config: UnlabelledConfig,
) -> ProblemResult {
    let ProblemPoints {
        id,
        object,
        pixels,
        normalised,
    } = points;
    let failed = |error: String| ProblemResult::Failed {
        id: id.to_string(),
        error,
    };
    if !(config.gate_px > 0.0 && config.gate_px.is_finite()) {
        return failed(format!(
            "the gate must be a positive number of px, got {}",
            config.gate_px
        ));
    }
    if let Some(diameter_mm) = sphere_diameter_mm {
        if let Err(error) = check_sphere_diameter(diameter_mm, solver) {
            return failed(error);
        }
    }
    let options = UnlabelledOptions::with_gate_px(
        config.gate_px,
        camera.fx().min(camera.fy()),
        config.max_missing,
    );
    let start = Instant::now();
    let found = match identify(object, normalised, &options) {
        Ok(found) => found,
        Err(e) => return failed(e.to_string()),
    };
    let matched: Vec<Vector3<f64>> = found.best.labels.iter().map(|&k| object[k]).collect();
    let radius_mm = sphere_diameter_mm.map(|d| 0.5 * d);
    let outcome = match radius_mm {
        Some(radius_mm) => {
            ml_sphere::solve(&matched, normalised, radius_mm).map_err(|e| e.to_string())
        }
        None => solver
            .solve_best(&matched, normalised)
            .map_err(|e| e.to_string()),
    };
    let seconds = start.elapsed().as_secs_f64();
    let pose = match outcome {
        Ok(pose) => pose,
        Err(e) => return failed(format!("labels found, but the final fit failed: {e}")),
    };
    let mut result = solved(id, camera, solver, &pose, &matched, pixels, seconds);
    let runner_up_rms_px = found.runner_up.as_ref().map(|runner_up| {
        let matched: Vec<Vector3<f64>> = runner_up.labels.iter().map(|&k| object[k]).collect();
        reprojection_rms_px(camera, &runner_up.pose, &matched, pixels)
    });
    if let ProblemResult::Solved {
        reprojection_rms_px,
        labels,
        ambiguity,
        runner_up_rms_px: runner_up_field,
        ..
    } = &mut result
    {
        if let Some(radius_mm) = radius_mm {
            *reprojection_rms_px =
                ellipse_centre_rms_px(camera, &pose, &matched, pixels, radius_mm);
        }
        *labels = Some(found.best.labels.clone());
        *ambiguity = Some(found.ambiguity());
        *runner_up_field = Some(runner_up_rms_px);
    }
    result
}

/// RMS distance, px, between `pixels` and the ellipse centres of spheres of
/// radius `radius_mm` at `pose` (distortion included); infinite when a
/// sphere is not wholly in front of the camera.
fn ellipse_centre_rms_px(
    camera: &Camera,
    pose: &Pose,
    object: &[Vector3<f64>],
    pixels: &[Vector2<f64>],
    radius_mm: f64,
) -> f64 {
    let mut sum = 0.0;
    for (p, pixel) in object.iter().zip(pixels) {
        match ellipse_centre_normalised(&pose.transform(p), radius_mm) {
            Ok(m) => sum += (camera.normalised_to_pixel(&m) - pixel).norm_squared(),
            Err(_) => return f64::INFINITY,
        }
    }
    (sum / object.len().max(1) as f64).sqrt()
}

fn solved(
    id: &str,
    camera: &Camera,
    solver: Solver,
    pose: &Pose,
    object: &[Vector3<f64>],
    pixels: &[Vector2<f64>],
    seconds: f64,
) -> ProblemResult {
    let r = pose.rotation.matrix();
    ProblemResult::Solved {
        id: id.to_string(),
        rotation: std::array::from_fn(|row| std::array::from_fn(|col| r[(row, col)])),
        translation: [pose.translation.x, pose.translation.y, pose.translation.z],
        reprojection_rms_px: reprojection_rms_px(camera, pose, object, pixels),
        seconds,
        start: solver.start().map(|start| start.name().to_string()),
        labels: None,
        ambiguity: None,
        runner_up_rms_px: None,
    }
}

/// One frame of `solve --unlabelled --set`: blobs only (a problem's
/// `object_points`, if any, are ignored: the set gives the markers).
#[derive(Debug, Clone, Deserialize)]
struct SetProblemInput {
    image_points: Vec<[f64; 2]>,
    #[serde(default)]
    sphere_diameter: Option<f64>,
}

/// A batch of frames for a marker set (docs/formats.md, "`solve` batch").
#[derive(Debug)]
pub struct SetBatch {
    /// The camera of every frame.
    pub camera: Camera,
    /// The frames, in file order, with their ids; a frame that did not
    /// parse carries its error.
    frames: Vec<(String, Result<SetProblemInput, String>)>,
}

/// One marker found in a frame.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SetMarkerResult {
    /// The marker's number in the set (1 is the set file's first).
    pub marker: usize,
    /// The marker's layout name.
    pub name: String,
    /// The blobs it explains (indices into the frame's image points).
    pub blobs: Vec<usize>,
    /// For each of `blobs`, the index of the marker's point it is.
    pub labels: Vec<usize>,
    /// Rotation matrix, row-major, marker → camera.
    pub rotation: [[f64; 3]; 3],
    /// Translation, mm.
    pub translation: [f64; 3],
    /// RMS reprojection error over its blobs, px.
    pub reprojection_rms_px: f64,
}

/// One entry of a set batch's output.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum SetProblemResult {
    /// The markers found in a frame.
    Solved {
        /// Caller's identifier.
        id: String,
        /// Every marker found, by marker number.
        markers: Vec<SetMarkerResult>,
        /// Blobs no marker explains.
        unexplained: Vec<usize>,
        /// Wall time of the grouping and the final fits, seconds.
        seconds: f64,
    },
    /// A frame that could not be solved, and why.
    Failed {
        /// Caller's identifier.
        id: String,
        /// What was wrong.
        error: String,
    },
}

/// The output document of a set batch.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SetBatchOutput {
    /// Stable name of the solver of the final fits.
    pub solver: String,
    /// The set's name.
    pub set: String,
    /// One entry per frame, in input order.
    pub results: Vec<SetProblemResult>,
}

impl SetBatch {
    /// Parses a batch whose problems are frames of blobs.
    pub fn from_json(text: &str) -> Result<SetBatch, BatchError> {
        let (camera, frames) = parse_document(text)?;
        Ok(SetBatch { camera, frames })
    }

    /// The number of frames.
    pub fn len(&self) -> usize {
        self.frames.len()
    }

    /// Whether there are no frames.
    pub fn is_empty(&self) -> bool {
        self.frames.is_empty()
    }

    /// Finds the set's markers in every frame: the blobs are grouped by
    /// the best joint fit ([`crate::set::group_blobs`]), then each marker's
    /// pose is `solver` on its blobs (with a sphere diameter, `ml`'s
    /// sphere-image fit).
    pub fn solve(
        &self,
        set: &crate::set::MarkerSet,
        solver: Solver,
        sphere_diameter_mm: Option<f64>,
        config: UnlabelledConfig,
        mut on_progress: impl FnMut(usize),
    ) -> SetBatchOutput {
        let objects = set.objects();
        let names = set.names();
        let results = self
            .frames
            .iter()
            .enumerate()
            .map(|(index, (id, frame))| {
                let result = match frame {
                    Ok(frame) => solve_frame(
                        &self.camera,
                        solver,
                        id,
                        frame,
                        (&objects, &names),
                        frame.sphere_diameter.or(sphere_diameter_mm),
                        config,
                    ),
                    Err(error) => SetProblemResult::Failed {
                        id: id.clone(),
                        error: error.clone(),
                    },
                };
                on_progress(index + 1);
                result
            })
            .collect();
        SetBatchOutput {
            solver: solver.name().to_string(),
            set: set.name.clone(),
            results,
        }
    }
}

/// One frame of a set batch.
fn solve_frame(
    camera: &Camera,
    solver: Solver,
    id: &str,
    frame: &SetProblemInput,
    (objects, names): (&[Vec<Vector3<f64>>], &[String]),
    sphere_diameter_mm: Option<f64>,
    config: UnlabelledConfig,
) -> SetProblemResult {
    let failed = |error: String| SetProblemResult::Failed {
        id: id.to_string(),
        error,
    };
    if !(config.gate_px > 0.0 && config.gate_px.is_finite()) {
        return failed(format!(
            "the gate must be a positive number of px, got {}",
            config.gate_px
        ));
    }
    if let Some(diameter_mm) = sphere_diameter_mm {
        if let Err(error) = check_sphere_diameter(diameter_mm, solver) {
            return failed(error);
        }
    }
    let pixels: Vec<Vector2<f64>> = frame
        .image_points
        .iter()
        .map(|p| Vector2::new(p[0], p[1]))
        .collect();
    let mut normalised = Vec::with_capacity(pixels.len());
    for (index, pixel) in pixels.iter().enumerate() {
        if !pixel.iter().all(|v| v.is_finite()) {
            return failed(format!("image point {index} has a non-finite coordinate"));
        }
        match camera.pixel_to_normalised(pixel) {
            Ok(m) => normalised.push(m),
            Err(e) => return failed(format!("image point {index}: {e}")),
        }
    }
    let options = UnlabelledOptions::with_gate_px(
        config.gate_px,
        camera.fx().min(camera.fy()),
        config.max_missing,
    );
    let start = Instant::now();
    let groups = crate::set::group_blobs(objects, &normalised, &options);
    if groups.is_empty() {
        return failed(format!(
            "no marker of the set fits {} of the {} blobs within the {} px gate",
            if config.max_missing > 0 {
                "all but one"
            } else {
                "all"
            },
            pixels.len(),
            config.gate_px
        ));
    }
    let mut markers = Vec::with_capacity(groups.len());
    let mut claimed = vec![false; pixels.len()];
    for group in &groups {
        let matched: Vec<Vector3<f64>> = group
            .labels
            .iter()
            .map(|&k| objects[group.marker][k])
            .collect();
        let blobs: Vec<Vector2<f64>> = group.blobs.iter().map(|&b| normalised[b]).collect();
        let blob_pixels: Vec<Vector2<f64>> = group.blobs.iter().map(|&b| pixels[b]).collect();
        let (pose, rms) = match sphere_diameter_mm {
            Some(diameter_mm) => match ml_sphere::solve(&matched, &blobs, 0.5 * diameter_mm) {
                Ok(pose) => {
                    let rms = ellipse_centre_rms_px(
                        camera,
                        &pose,
                        &matched,
                        &blob_pixels,
                        0.5 * diameter_mm,
                    );
                    (pose, rms)
                }
                Err(e) => {
                    return failed(format!(
                        "marker {}: the final fit failed: {e}",
                        group.marker + 1
                    ))
                }
            },
            None => match solver.solve_best(&matched, &blobs) {
                Ok(pose) => {
                    let rms = reprojection_rms_px(camera, &pose, &matched, &blob_pixels);
                    (pose, rms)
                }
                Err(e) => {
                    return failed(format!(
                        "marker {}: the final fit failed: {e}",
                        group.marker + 1
                    ))
                }
            },
        };
        for &b in &group.blobs {
            claimed[b] = true;
        }
        let r = pose.rotation.matrix();
        markers.push(SetMarkerResult {
            marker: group.marker + 1,
            name: names[group.marker].clone(),
            blobs: group.blobs.clone(),
            labels: group.labels.clone(),
            rotation: std::array::from_fn(|row| std::array::from_fn(|col| r[(row, col)])),
            translation: [pose.translation.x, pose.translation.y, pose.translation.z],
            reprojection_rms_px: rms,
        });
    }
    SetProblemResult::Solved {
        id: id.to_string(),
        markers,
        unexplained: (0..pixels.len()).filter(|&b| !claimed[b]).collect(),
        seconds: start.elapsed().as_secs_f64(),
    }
}

/// A demonstration batch: the paper's biprism seen by the paper's camera (with
/// its real-image distortion) at a few poses along the working range, with
/// seeded Gaussian pixel noise of `sigma_px`. Used when `solve` runs without
/// `--problems`.
pub fn demo_batch_json(seed: u64, sigma_px: f64) -> String {
    use crate::synthetic::{biprism_points, project_with_noise, stream_rng};
    use nalgebra::Rotation3;
    let camera = Camera::paper_with_distortion();
    let object = biprism_points(50.0);
    let mut problems = Vec::new();
    for (index, depth_mm) in [200.0, 400.0, 600.0, 800.0, 1000.0].into_iter().enumerate() {
        let tilt = (-30.0 + 15.0 * index as f64).to_radians();
        let truth = Pose::new(
            Rotation3::from_euler_angles(tilt, 0.3, 0.1),
            Vector3::new(20.0, -10.0, depth_mm),
        );
        let mut rng = stream_rng(seed, 0xD3, index as u64);
        let problem = project_with_noise(&mut rng, &camera, object.clone(), truth, sigma_px)
            .expect("the demo poses put the biprism in front of the camera");
        problems.push(serde_json::json!({
            "id": format!("demo-{depth_mm:.0}mm"),
            "object_points": problem.object.iter().map(|p| [p.x, p.y, p.z]).collect::<Vec<_>>(),
            "image_points": problem.pixels.iter().map(|p| [p.x, p.y]).collect::<Vec<_>>(),
        }));
    }
    let document = serde_json::json!({
        "camera": {
            "fx": camera.fx(), "fy": camera.fy(), "cx": camera.cx(), "cy": camera.cy(),
            "width": camera.width(), "height": camera.height(),
            "distortion": camera.distortion(),
        },
        "problems": problems,
    });
    serde_json::to_string_pretty(&document).expect("JSON values serialise")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn demo_batch_solves_with_every_solver() {
        let batch = Batch::from_json(&demo_batch_json(1, 0.0)).unwrap();
        for &solver in Solver::ALL.iter().filter(|s| s.is_exact()) {
            let output = batch.solve(solver, |_| {});
            assert_eq!(output.results.len(), 5);
            for result in &output.results {
                match result {
                    ProblemResult::Solved {
                        reprojection_rms_px,
                        ..
                    } => assert!(*reprojection_rms_px < 1e-6, "{solver}: {result:?}"),
                    ProblemResult::Failed { error, .. } => panic!("{solver}: {error}"),
                }
            }
        }
    }

    #[test]
    fn bad_problems_get_error_entries_and_the_rest_runs() {
        let text = r#"{"camera": {"fx": 1000, "fy": 1000, "cx": 320, "cy": 240},
            "problems": [
              {"id": "few", "object_points": [[0,0,0],[1,0,0],[0,1,0]], "image_points": [[1,1],[2,2],[3,3]]},
              {"id": "mismatch", "object_points": [[0,0,0],[1,0,0],[0,1,0],[0,0,1]], "image_points": [[1,1]]},
              {"id": "shape", "object_points": [[0,0]], "image_points": []},
              {"object_points": [[0,0,0],[1,0,0],[0,1,0],[1,1,0],[2,0,0],[0,2,0]], "image_points": [[1,1],[2,1],[1,2],[2,2],[3,1],[1,3]], "extra": true}
            ]}"#;
        let batch = Batch::from_json(text).unwrap();
        let output = batch.solve(Solver::EpnpGn, |_| {});
        let errors: Vec<String> = output
            .results
            .iter()
            .map(|r| match r {
                ProblemResult::Failed { id, error } => format!("{id}: {error}"),
                other => panic!("expected errors, got {other:?}"),
            })
            .collect();
        assert_eq!(errors[0], "few: EPnP+GN needs at least 4 points, got 3");
        assert_eq!(
            errors[1],
            "mismatch: mismatched lengths: 4 object points but 1 image points"
        );
        assert!(
            errors[2].starts_with("shape: malformed problem"),
            "{}",
            errors[2]
        );
        assert_eq!(
            errors[3],
            "#3: object points are coplanar; EPnP+GN needs noncoplanar points"
        );
    }

    /// Noise-free ellipse centres of 10 mm spheres (the demo poses, paper
    /// camera with distortion): `ml` with the diameter is exact, without it
    /// measurably biased; other solvers refuse the diameter.
    #[test]
    fn sphere_diameter_fits_ellipse_centres_exactly() {
        use crate::pose::{rotation_error_deg, Pose};
        use nalgebra::Rotation3;
        let camera = Camera::paper_with_distortion();
        let object = crate::synthetic::biprism_points(50.0);
        let truths: Vec<Pose> = [200.0, 300.0, 500.0]
            .iter()
            .enumerate()
            .map(|(i, &depth)| {
                Pose::new(
                    Rotation3::from_euler_angles(0.4 - 0.3 * i as f64, 0.3, 0.1),
                    Vector3::new(90.0, -60.0, depth),
                )
            })
            .collect();
        let problems: Vec<serde_json::Value> = truths
            .iter()
            .enumerate()
            .map(|(i, truth)| {
                let pixels: Vec<[f64; 2]> = object
                    .iter()
                    .map(|p| {
                        let m = ellipse_centre_normalised(&truth.transform(p), 5.0).unwrap();
                        let px = camera.normalised_to_pixel(&m);
                        [px.x, px.y]
                    })
                    .collect();
                let mut problem = serde_json::json!({
                    "id": format!("p{i}"),
                    "object_points": object.iter().map(|p| [p.x, p.y, p.z]).collect::<Vec<_>>(),
                    "image_points": pixels,
                });
                if i == 2 {
                    problem["sphere_diameter"] = serde_json::json!(10.0);
                }
                problem
            })
            .collect();
        let text = serde_json::json!({
            "camera": {"fx": camera.fx(), "fy": camera.fy(), "cx": camera.cx(), "cy": camera.cy(),
                       "distortion": camera.distortion()},
            "problems": problems,
        })
        .to_string();
        let batch = Batch::from_json(&text).unwrap();
        let rotation_errors = |output: &BatchOutput| -> Vec<f64> {
            output
                .results
                .iter()
                .zip(&truths)
                .map(|(result, truth)| match result {
                    ProblemResult::Solved { rotation, .. } => {
                        let r = nalgebra::Matrix3::from_fn(|i, j| rotation[i][j]);
                        rotation_error_deg(&truth.rotation, &Rotation3::from_matrix_unchecked(r))
                    }
                    ProblemResult::Failed { error, .. } => panic!("{error}"),
                })
                .collect()
        };
        let exact = batch.solve_with_spheres(Solver::Ml, Some(10.0), |_| {});
        for (error, result) in rotation_errors(&exact).iter().zip(&exact.results) {
            assert!(*error < 1e-6, "{error}° {result:?}");
            if let ProblemResult::Solved {
                reprojection_rms_px,
                ..
            } = result
            {
                assert!(*reprojection_rms_px < 1e-6, "{reprojection_rms_px}");
            }
        }
        // Problems 0 and 1 have no diameter of their own: the point model is biased.
        let naive = batch.solve(Solver::Ml, |_| {});
        let naive_errors = rotation_errors(&BatchOutput {
            solver: naive.solver.clone(),
            results: naive.results[..2].to_vec(),
        });
        assert!(naive_errors.iter().all(|e| *e > 1e-3), "{naive_errors:?}");
        let refused = batch.solve_with_spheres(Solver::Sqpnp, Some(10.0), |_| {});
        assert!(
            matches!(&refused.results[0], ProblemResult::Failed { error, .. } if error.contains("needs the ml solver"))
        );
        let bad = batch.solve_with_spheres(Solver::Ml, Some(-1.0), |_| {});
        assert!(
            matches!(&bad.results[0], ProblemResult::Failed { error, .. } if error.contains("positive"))
        );
        // The problem's own diameter wins over the default.
        assert!(matches!(&bad.results[2], ProblemResult::Solved { .. }));
    }

    /// Unlabelled with spheres: shuffled noise-free ellipse centres of 10 mm
    /// spheres on an asymmetric marker (one blob missing in the second
    /// problem) are labelled, and the sphere-model fit is exact; a solver
    /// other than ml is refused.
    #[test]
    fn unlabelled_sphere_blobs_are_labelled_and_fitted_exactly() {
        use crate::pose::rotation_error_deg;
        use nalgebra::Rotation3;
        let camera = Camera::paper_with_distortion();
        let object = [
            Vector3::new(0.0, 0.0, 0.0),
            Vector3::new(60.0, 5.0, 0.0),
            Vector3::new(-10.0, 45.0, 10.0),
            Vector3::new(20.0, -30.0, 40.0),
            Vector3::new(-35.0, -15.0, -25.0),
            Vector3::new(30.0, 35.0, -30.0),
        ];
        let truth = Pose::new(
            Rotation3::from_euler_angles(0.4, 0.3, 0.1),
            Vector3::new(60.0, -40.0, 250.0),
        );
        let orders: [&[usize]; 2] = [&[4, 1, 5, 0, 3, 2], &[2, 5, 0, 4, 1]];
        let problems: Vec<serde_json::Value> = orders
            .iter()
            .map(|order| {
                let pixels: Vec<[f64; 2]> = order
                    .iter()
                    .map(|&k| {
                        let m =
                            ellipse_centre_normalised(&truth.transform(&object[k]), 5.0).unwrap();
                        let px = camera.normalised_to_pixel(&m);
                        [px.x, px.y]
                    })
                    .collect();
                serde_json::json!({
                    "object_points": object.iter().map(|p| [p.x, p.y, p.z]).collect::<Vec<_>>(),
                    "image_points": pixels,
                })
            })
            .collect();
        let text = serde_json::json!({
            "camera": {"fx": camera.fx(), "fy": camera.fy(), "cx": camera.cx(), "cy": camera.cy(),
                       "distortion": camera.distortion()},
            "problems": problems,
        })
        .to_string();
        let batch = Batch::from_json(&text).unwrap();
        let output =
            batch.solve_unlabelled(Solver::Ml, Some(10.0), UnlabelledConfig::default(), |_| {});
        for (result, order) in output.results.iter().zip(orders) {
            match result {
                ProblemResult::Solved {
                    rotation,
                    labels,
                    reprojection_rms_px,
                    ..
                } => {
                    assert_eq!(labels.as_deref(), Some(order));
                    assert!(*reprojection_rms_px < 1e-6, "{reprojection_rms_px}");
                    let r = nalgebra::Matrix3::from_fn(|i, j| rotation[i][j]);
                    let error =
                        rotation_error_deg(&truth.rotation, &Rotation3::from_matrix_unchecked(r));
                    assert!(error < 1e-6, "{error}°");
                }
                ProblemResult::Failed { error, .. } => panic!("{error}"),
            }
        }
        let refused = batch.solve_unlabelled(
            Solver::Sqpnp,
            Some(10.0),
            UnlabelledConfig::default(),
            |_| {},
        );
        assert!(
            matches!(&refused.results[0], ProblemResult::Failed { error, .. } if error.contains("needs the ml solver"))
        );
    }

    #[test]
    fn malformed_files_are_errors() {
        assert!(Batch::from_json("not json").is_err());
        assert!(Batch::from_json(r#"{"problems": []}"#).is_err());
        let err =
            Batch::from_json(r#"{"camera": {"fx": 0, "fy": 1, "cx": 0, "cy": 0}, "problems": []}"#)
                .unwrap_err();
        assert!(err.to_string().contains("malformed camera"), "{err}");
    }
}
