//! The camera: the pinhole model with Brown–Conrady distortion from the
//! solver crate ([`layout_opt_solvers::camera`], re-exported here whole), and
//! reading camera files, which the solver crate leaves to the tool.
//!
//! A camera file is our JSON format or an OpenCV calibration YAML file
//! (docs/formats.md, "Camera file", contract): [`load`] chooses by content,
//! [`from_json`] and [`from_opencv_yaml`] parse text. A solve batch gives its
//! camera as a [`CameraSpec`].
//!
//! ```
//! use layout_opt::camera::{self, Camera};
//!
//! let camera = camera::from_json(r#"{"fx": 1000, "fy": 1001, "cx": 320, "cy": 240}"#)?;
//! assert_eq!(camera.fx(), 1000.0);
//! // Width and height default to the paper's camera, 1280×720.
//! assert_eq!((camera.width(), camera.height()), (1280, 720));
//! assert_eq!(camera, Camera::new(1000.0, 1001.0, 320.0, 240.0, 1280, 720, [0.0; 5])?);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

pub use layout_opt_solvers::camera::{
    distortion_from_slice, Camera, CameraError, MAX_FOCAL_PX, MIN_FOCAL_PX,
    UNDISTORT_MAX_ITERATIONS, UNDISTORT_TOLERANCE,
};

use serde::Deserialize;
use std::path::Path;

/// Why a camera file could not be read: the file, its syntax, or the camera
/// it describes.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum CameraFileError {
    /// A camera file could not be read.
    #[error("cannot read camera file {path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// The cause.
        source: std::io::Error,
    },
    /// A camera file could not be parsed.
    #[error("cannot parse camera file {path}: {message}")]
    Parse {
        /// The file.
        path: String,
        /// What the parser said.
        message: String,
    },
    /// The file parsed, but its camera is not one (a focal length no lens
    /// has, a non-finite parameter, a distortion vector of the wrong length).
    #[error(transparent)]
    Camera(#[from] CameraError),
}

/// The JSON form of a camera (docs/formats.md, "Camera file", contract).
/// `width`, `height` and `distortion` are optional so that a solve batch may
/// give intrinsics only.
#[derive(Debug, Clone, Deserialize)]
pub struct CameraSpec {
    /// Horizontal focal length, px.
    pub fx: f64,
    /// Vertical focal length, px.
    pub fy: f64,
    /// Principal point column, px.
    pub cx: f64,
    /// Principal point row, px.
    pub cy: f64,
    /// Image width, px (default: the paper's 1280).
    #[serde(default)]
    pub width: Option<u32>,
    /// Image height, px (default: the paper's 720).
    #[serde(default)]
    pub height: Option<u32>,
    /// `[k1, k2, p1, p2, k3]`; 4 coefficients mean k3 = 0.
    #[serde(default)]
    pub distortion: Option<Vec<f64>>,
}

impl CameraSpec {
    /// Validates the specification into a [`Camera`].
    pub fn into_camera(self) -> Result<Camera, CameraError> {
        let distortion = distortion_from_slice(self.distortion.as_deref().unwrap_or(&[]))?;
        let paper = Camera::paper();
        Camera::new(
            self.fx,
            self.fy,
            self.cx,
            self.cy,
            self.width.unwrap_or(paper.width()),
            self.height.unwrap_or(paper.height()),
            distortion,
        )
    }
}

/// Loads a camera from our JSON format or an OpenCV calibration YAML
/// file (`camera_matrix`, `distortion_coefficients`, `image_width`,
/// `image_height`). The format is chosen by content: a file whose first
/// non-blank character is `{` is JSON, anything else is parsed as YAML,
/// so OpenCV's XML form is not read (convert it to YAML first).
pub fn load(path: &Path) -> Result<Camera, CameraFileError> {
    let text = std::fs::read_to_string(path).map_err(|source| CameraFileError::Io {
        path: path.display().to_string(),
        source,
    })?;
    let display = path.display().to_string();
    if text.trim_start().starts_with('{') {
        from_json(&text).map_err(|e| relabel(e, &display))
    } else {
        from_opencv_yaml(&text).map_err(|e| relabel(e, &display))
    }
}

/// Parses our JSON camera format.
pub fn from_json(text: &str) -> Result<Camera, CameraFileError> {
    let spec: CameraSpec = serde_json::from_str(text).map_err(|e| CameraFileError::Parse {
        path: "<json>".into(),
        message: e.to_string(),
    })?;
    Ok(spec.into_camera()?)
}

/// Parses an OpenCV calibration YAML file (`%YAML:1.0`, `!!opencv-matrix`).
pub fn from_opencv_yaml(text: &str) -> Result<Camera, CameraFileError> {
    let parse_error = |message: String| CameraFileError::Parse {
        path: "<yaml>".into(),
        message,
    };
    // OpenCV writes a `%YAML:1.0` directive that YAML 1.2 parsers reject;
    // it carries no information, so drop it.
    let body: String = text
        .lines()
        .filter(|line| !line.trim_start().starts_with("%YAML"))
        .collect::<Vec<_>>()
        .join("\n");
    let calibration: OpenCvCalibration = serde_saphyr::from_str(&body)
        .map_err(|e| parse_error(crate::config::one_line(&e.to_string())))?;
    let k = &calibration.camera_matrix;
    if k.rows != 3 || k.cols != 3 || k.data.len() != 9 {
        return Err(parse_error(format!(
            "camera_matrix must be 3x3 with 9 values, got {}x{} with {}",
            k.rows,
            k.cols,
            k.data.len()
        )));
    }
    let distortion = match &calibration.distortion_coefficients {
        Some(d) if d.data.len() > 5 => {
            // OpenCV's rational/thin-prism terms are beyond our model; they
            // are accepted only when zero.
            if d.data[5..].iter().any(|&c| c != 0.0) {
                return Err(parse_error(format!(
                    "distortion has {} coefficients with non-zero terms beyond k3; only [k1,k2,p1,p2,k3] is supported",
                    d.data.len()
                )));
            }
            distortion_from_slice(&d.data[..5])?
        }
        Some(d) => distortion_from_slice(&d.data)?,
        None => [0.0; 5],
    };
    let paper = Camera::paper();
    Ok(Camera::new(
        k.data[0],
        k.data[4],
        k.data[2],
        k.data[5],
        calibration.image_width.unwrap_or(paper.width()),
        calibration.image_height.unwrap_or(paper.height()),
        distortion,
    )?)
}

fn relabel(error: CameraFileError, path: &str) -> CameraFileError {
    match error {
        CameraFileError::Parse { message, .. } => CameraFileError::Parse {
            path: path.to_string(),
            message,
        },
        other => other,
    }
}

#[derive(Debug, Deserialize)]
struct OpenCvMatrix {
    rows: usize,
    cols: usize,
    data: Vec<f64>,
}

#[derive(Debug, Deserialize)]
struct OpenCvCalibration {
    camera_matrix: OpenCvMatrix,
    #[serde(default)]
    distortion_coefficients: Option<OpenCvMatrix>,
    #[serde(default)]
    image_width: Option<u32>,
    #[serde(default)]
    image_height: Option<u32>,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn loads_json_with_optional_fields() {
        let camera = from_json(r#"{"fx":1000,"fy":1001,"cx":320,"cy":240}"#).unwrap();
        assert_eq!(camera.width(), 1280);
        assert!(!camera.has_distortion());
        let camera = from_json(
            r#"{"fx":1000,"fy":1001,"cx":320,"cy":240,"width":640,"height":480,"distortion":[0.1,0,0,0]}"#,
        )
        .unwrap();
        assert_eq!(camera.distortion(), [0.1, 0.0, 0.0, 0.0, 0.0]);
        let err = from_json(r#"{"fx":0,"fy":1,"cx":0,"cy":0}"#).unwrap_err();
        assert!(err.to_string().contains("must lie between 1 and"), "{err}");
        let err = from_json(r#"{"fx":1,"fy":1,"cx":0,"cy":0,"distortion":[1,2]}"#).unwrap_err();
        assert!(err.to_string().contains("got 2"), "{err}");
        assert!(from_json("{ not json").is_err());
    }

    #[test]
    fn loads_opencv_yaml() {
        let text = r#"%YAML:1.0
---
image_width: 1280
image_height: 720
camera_matrix: !!opencv-matrix
   rows: 3
   cols: 3
   dt: d
   data: [ 1301.473508, 0., 653., 0., 1300.926193, 508., 0., 0., 1. ]
distortion_coefficients: !!opencv-matrix
   rows: 1
   cols: 5
   dt: d
   data: [ -0.087355, 0.204686, 0., 0., 0. ]
"#;
        let camera = from_opencv_yaml(text).unwrap();
        assert_eq!(camera, Camera::paper_with_distortion());
        let bad = text.replace("rows: 3\n   cols: 3", "rows: 2\n   cols: 3");
        let err = from_opencv_yaml(&bad).unwrap_err();
        assert!(err.to_string().contains("3x3"), "{err}");
    }
}
