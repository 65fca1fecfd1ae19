//! `layout-opt render`: grey PNG images of the part `export` builds, as the
//! camera sees it, each with its ground truth (docs/formats.md, "Render
//! frame record").
//!
//! - [`config`]: how the part looks, the optics and the sensor, validated
//!   once ([`RenderConfig`]);
//! - [`scene`]: the part's primitives and the rays that meet them;
//! - [`analysis`]: poses and the part in, noise-free radiance images out;
//! - [`sensor`]: shot and read noise, quantisation, seeded;
//! - [`truth`]: exact sphere images and hidden fractions per frame;
//! - [`workflow`]: the run: checks, staging, PNG and JSON files renamed
//!   into place as a set, progress and interruption;
//! - [`scenes`]: the same run for frames of several markers, each at its
//!   own pose, hiding one another.

pub mod analysis;
pub mod config;
pub mod scene;
pub mod scenes;
pub mod sensor;
pub mod truth;
pub mod workflow;

pub use analysis::{
    render_channels_within, render_radiance, render_radiance_within, render_scene, scene_blur_px,
    Placed, Radiance,
};
pub use config::{Appearance, Blur, Lighting, Noise, Optics, RenderConfig, Sensor};
pub use scene::Scene;
pub use sensor::{expose, Digital};
pub use truth::{frame_truth, part_truth, FrameTruth, Hidden, HiddenBy, SphereTruth};

use crate::pose::Pose;
use nalgebra::{Matrix3, Rotation3, Vector3};
use std::path::PathBuf;

/// A rotation in a poses file may be this far from orthonormal
/// (largest entry of `RᵀR − I`).
pub const ROTATION_TOLERANCE: f64 = 1e-6;

/// Why a render cannot run or stopped.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum RenderError {
    /// A configuration value is bad.
    #[error(transparent)]
    Config(#[from] crate::config::ConfigError),
    /// The part cannot be built.
    #[error("cannot build the part: {0}")]
    Geometry(#[from] crate::mesh::GeometryError),
    /// A sphere is not wholly in front of the camera.
    #[error("frame {frame}: sphere {sphere} is not wholly in front of the camera (pose behind the camera?): {source}")]
    BehindCamera {
        /// The frame.
        frame: usize,
        /// The sphere's name.
        sphere: String,
        /// Why its silhouette is no ellipse.
        source: crate::sphere_image::SphereImageError,
    },
    /// Part of the part reaches the camera's plane.
    #[error("frame {frame}: the part reaches {depth_mm:.1} mm from the camera's plane (pose behind the camera?)")]
    PartBehindCamera {
        /// The frame.
        frame: usize,
        /// Depth of the part's nearest bounding-box corner, mm.
        depth_mm: f64,
    },
    /// No sphere shows in the image.
    #[error("frame {frame}: the part is outside the image (no sphere's silhouette reaches it); the marker origin is at ({x:.1}, {y:.1}, {z:.1}) mm")]
    OutsideImage {
        /// The frame.
        frame: usize,
        /// Marker origin, camera frame, mm.
        x: f64,
        /// See `x`.
        y: f64,
        /// See `x`.
        z: f64,
    },
    /// A pixel could not be undistorted to a ray.
    #[error("camera: {0}")]
    Camera(crate::camera::CameraError),
    /// A poses file is malformed.
    #[error("poses: {0}")]
    Poses(String),
    /// No poses to render.
    #[error("no poses to render")]
    NoPoses,
    /// Reading or writing a file failed.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file or directory.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// A PNG could not be encoded.
    #[error("{}: cannot encode the PNG: {source}", path.display())]
    Png {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: image::ImageError,
    },
    /// The caller asked to stop; nothing was written.
    #[error("interrupted; no image was written")]
    Interrupted,
    /// The outputs were refused (one is an input, or taken by another
    /// run) or could not be written.
    #[error(transparent)]
    Output(#[from] crate::kernel::OutputError),
    /// The lens's defocus blurs a frame beyond what a render draws.
    #[error("frame {frame}: the defocus blurs the marker {sigma_px:.3e} px (σ) at {depth_mm:.1} mm, more than the {max} px a render draws; bring --focus nearer the marker or --aperture down")]
    TooBlurred {
        /// The frame.
        frame: usize,
        /// Its blur, px.
        sigma_px: f64,
        /// The marker origin's depth, mm.
        depth_mm: f64,
        /// [`config::MAX_BLUR_SIGMA_PX`].
        max: f64,
    },
}

impl RenderError {
    /// The same error, naming frame `frame` where it names one.
    pub(crate) fn in_frame(self, frame: usize) -> Self {
        match self {
            RenderError::BehindCamera { sphere, source, .. } => RenderError::BehindCamera {
                frame,
                sphere,
                source,
            },
            RenderError::TooBlurred {
                frame: _,
                sigma_px,
                depth_mm,
                max,
            } => RenderError::TooBlurred {
                frame,
                sigma_px,
                depth_mm,
                max,
            },
            other => other,
        }
    }
}

/// One pose of a poses file.
#[derive(Debug, Clone, serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct PoseRecord {
    #[serde(rename = "R")]
    rotation: [[f64; 3]; 3],
    #[serde(rename = "t")]
    translation: [f64; 3],
}

/// The poses of a `--poses` file: a JSON array of `{"R": [[…], […], […]],
/// "t": […]}`, R by rows (marker → camera), t in mm (docs/formats.md,
/// "Render poses file"). A rotation must be orthonormal to within
/// [`ROTATION_TOLERANCE`] with determinant +1.
///
/// ```
/// let poses = layout_opt::render::poses_from_json(
///     r#"[{"R": [[1,0,0],[0,1,0],[0,0,1]], "t": [0, 0, 500]}]"#,
/// ).unwrap();
/// assert_eq!(poses[0].translation.z, 500.0);
/// ```
pub fn poses_from_json(text: &str) -> Result<Vec<Pose>, RenderError> {
    let records: Vec<PoseRecord> =
        serde_json::from_str(text).map_err(|e| RenderError::Poses(e.to_string()))?;
    if records.is_empty() {
        return Err(RenderError::NoPoses);
    }
    records
        .iter()
        .enumerate()
        .map(|(k, record)| {
            checked_pose(&record.rotation, &record.translation)
                .map_err(|why| RenderError::Poses(format!("pose {k}: {why}")))
        })
        .collect()
}

/// The pose of `R` (rows, marker → camera) and `t` (mm), or why they make
/// none: not finite, or R not a rotation to within
/// [`ROTATION_TOLERANCE`].
fn checked_pose(rotation: &[[f64; 3]; 3], translation: &[f64; 3]) -> Result<Pose, String> {
    let r = Matrix3::from_fn(|i, j| rotation[i][j]);
    let t = Vector3::from(*translation);
    if !(r.iter().all(|v| v.is_finite()) && t.iter().all(|v| v.is_finite())) {
        return Err("R and t must be finite".into());
    }
    let off = (r.transpose() * r - Matrix3::identity()).abs().max();
    if off > ROTATION_TOLERANCE || r.determinant() <= 0.0 {
        return Err(format!(
            "R is not a rotation (RᵀR differs from I by {off:.2e}, det {:.3})",
            r.determinant()
        ));
    }
    Ok(Pose::new(Rotation3::from_matrix_unchecked(r), t))
}

/// One marker's pose in a frame of a scenes file.
#[derive(Debug, Clone, serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct MarkerPoseRecord {
    marker: usize,
    #[serde(rename = "R")]
    rotation: [[f64; 3]; 3],
    #[serde(rename = "t")]
    translation: [f64; 3],
}

/// The frames of a scenes file for a set of `markers` markers: a JSON
/// array of frames, each an array of `{"marker": N, "R": [[…], […], […]],
/// "t": […]}`, N the marker's number in the set (from 1), each marker at
/// most once a frame (docs/formats.md, "Render scenes file"). Each frame
/// is its markers' `(index from 0, pose)`, in the file's order.
///
/// ```
/// let frames = layout_opt::render::scenes_from_json(
///     r#"[[{"marker": 2, "R": [[1,0,0],[0,1,0],[0,0,1]], "t": [0, 0, 500]}]]"#,
///     2,
/// ).unwrap();
/// assert_eq!(frames[0][0].0, 1);
/// ```
pub fn scenes_from_json(
    text: &str,
    markers: usize,
) -> Result<Vec<Vec<(usize, Pose)>>, RenderError> {
    let frames: Vec<Vec<MarkerPoseRecord>> =
        serde_json::from_str(text).map_err(|e| RenderError::Poses(e.to_string()))?;
    if frames.is_empty() {
        return Err(RenderError::NoPoses);
    }
    frames
        .iter()
        .enumerate()
        .map(|(k, frame)| {
            let bad = |why: String| RenderError::Poses(format!("frame {k}: {why}"));
            if frame.is_empty() {
                return Err(bad("no markers".into()));
            }
            let mut placed: Vec<(usize, Pose)> = Vec::with_capacity(frame.len());
            for record in frame {
                let n = record.marker;
                if n == 0 || n > markers {
                    return Err(bad(format!(
                        "marker {n}: the set's markers are numbered 1 to {markers}"
                    )));
                }
                if placed.iter().any(|(index, _)| *index == n - 1) {
                    return Err(bad(format!("marker {n} is placed twice")));
                }
                let pose = checked_pose(&record.rotation, &record.translation)
                    .map_err(|why| bad(format!("marker {n}: {why}")))?;
                placed.push((n - 1, pose));
            }
            Ok(placed)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_scenes_file_names_each_marker_of_the_set_once() {
        let i = r#""R": [[1,0,0],[0,1,0],[0,0,1]]"#;
        let two = format!(
            r#"[[{{"marker": 1, {i}, "t": [0,0,500]}}, {{"marker": 2, {i}, "t": [50,0,600]}}]]"#
        );
        let frames = scenes_from_json(&two, 2).unwrap();
        assert_eq!(frames[0].len(), 2);
        assert_eq!(frames[0][1].0, 1);
        assert_eq!(frames[0][1].1.translation.x, 50.0);
        for (text, needle) in [
            (
                format!(r#"[[{{"marker": 3, {i}, "t": [0,0,500]}}]]"#),
                "numbered 1 to 2",
            ),
            (
                format!(r#"[[{{"marker": 0, {i}, "t": [0,0,500]}}]]"#),
                "numbered 1 to 2",
            ),
            (
                format!(
                    r#"[[{{"marker": 1, {i}, "t": [0,0,500]}}, {{"marker": 1, {i}, "t": [0,0,600]}}]]"#
                ),
                "placed twice",
            ),
            (
                r#"[[{"marker": 1, "R": [[1,0,0],[0,1,0],[0,0,-1]], "t": [0,0,500]}]]"#.to_string(),
                "not a rotation",
            ),
            ("[[]]".to_string(), "frame 0: no markers"),
            (
                format!(r#"[[{{"marker": 1, {i}, "t": [0,0,500], "x": 1}}]]"#),
                "unknown field",
            ),
        ] {
            let error = scenes_from_json(&text, 2).unwrap_err().to_string();
            assert!(error.contains(needle), "{text}: {error}");
        }
        assert!(matches!(
            scenes_from_json("[]", 2),
            Err(RenderError::NoPoses)
        ));
    }

    #[test]
    fn a_poses_file_must_hold_rotations() {
        let bad = r#"[{"R": [[2,0,0],[0,1,0],[0,0,1]], "t": [0, 0, 500]}]"#;
        let error = poses_from_json(bad).unwrap_err().to_string();
        assert!(error.contains("pose 0: R is not a rotation"), "{error}");
        assert!(matches!(poses_from_json("[]"), Err(RenderError::NoPoses)));
        assert!(poses_from_json(r#"[{"R": 1}]"#).is_err());
    }
}
