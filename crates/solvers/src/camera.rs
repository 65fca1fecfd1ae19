//! Pinhole camera with Brown–Conrady distortion, as OpenCV defines it.
//!
//! Conventions (layout-opt's docs/formats.md, "Conventions" and "Camera
//! file", contract): OpenCV's camera frame (x right, y down, z forward along
//! the optical axis); intrinsics in pixels; distortion coefficients
//! `[k1, k2, p1, p2, k3]`.
//!
//! Solvers never see pixels: [`Camera::pixel_to_normalised`] removes the
//! intrinsics and the distortion (iteratively, as OpenCV's `undistortPoints`),
//! and the solvers work on the undistorted normalised image plane `z = 1`.
//!
//! ```
//! use layout_opt_solvers::camera::Camera;
//! use nalgebra::{Vector2, Vector3};
//!
//! let camera = Camera::paper();
//! // A point on the optical axis images at the principal point.
//! let pixel = camera.project(&Vector3::new(0.0, 0.0, 500.0)).unwrap();
//! assert!((pixel - Vector2::new(camera.cx(), camera.cy())).norm() < 1e-9);
//! // Pixels go back to the normalised image plane z = 1.
//! let off_axis = camera.project(&Vector3::new(50.0, -20.0, 500.0)).unwrap();
//! let normalised = camera.pixel_to_normalised(&off_axis).unwrap();
//! assert!((normalised - Vector2::new(0.1, -0.04)).norm() < 1e-12);
//! // A point behind the camera has no image.
//! assert!(camera.project(&Vector3::new(0.0, 0.0, -1.0)).is_none());
//! ```

use nalgebra::{Matrix2, Vector2, Vector3};

/// Iterations of the fixed-point undistortion before we give up.
pub const UNDISTORT_MAX_ITERATIONS: usize = 50;
/// Convergence threshold of the undistortion, in normalised units
/// (about 1e-9 px at f = 1300 px).
pub const UNDISTORT_TOLERANCE: f64 = 1e-12;

/// Errors raised while building a camera or undistorting a pixel. (Reading
/// a camera file, and its errors, are layout-opt's `camera` module.)
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum CameraError {
    /// A focal length was not a number of pixels any camera has.
    BadFocalLength {
        /// Horizontal focal length, px.
        fx: f64,
        /// Vertical focal length, px.
        fy: f64,
    },
    /// A principal point coordinate or a distortion coefficient was NaN or infinite.
    NotFinite {
        /// Which parameter.
        name: &'static str,
        /// Its value.
        value: f64,
    },
    /// The image size was zero.
    BadImageSize {
        /// Width, px.
        width: u32,
        /// Height, px.
        height: u32,
    },
    /// The distortion vector has a length OpenCV does not use here.
    BadDistortionLength(usize),
    /// Undistortion did not converge (the distortion model folds over here).
    UndistortDiverged {
        /// Pixel column.
        u: f64,
        /// Pixel row.
        v: f64,
    },
}

impl std::fmt::Display for CameraError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            CameraError::BadFocalLength { fx, fy } => write!(
                f,
                "camera focal lengths must lie between {MIN_FOCAL_PX} and {MAX_FOCAL_PX:e} px, got fx = {fx}, fy = {fy}"
            ),
            CameraError::NotFinite { name, value } => {
                write!(f, "camera parameter {name} is not finite ({value})")
            }
            CameraError::BadImageSize { width, height } => write!(
                f,
                "camera image size must be positive, got {width}x{height}"
            ),
            CameraError::BadDistortionLength(length) => write!(
                f,
                "distortion must have 0, 4 or 5 coefficients [k1,k2,p1,p2,k3], got {length}"
            ),
            CameraError::UndistortDiverged { u, v } => write!(
                f,
                "undistortion did not converge at pixel ({u:.3}, {v:.3})"
            ),
        }
    }
}

impl std::error::Error for CameraError {}

/// A calibrated camera: intrinsics, image size and Brown–Conrady distortion.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
pub struct Camera {
    fx: f64,
    fy: f64,
    cx: f64,
    cy: f64,
    width: u32,
    height: u32,
    distortion: [f64; 5],
}

/// The five coefficients `[k1, k2, p1, p2, k3]` from a distortion vector
/// of 0, 4 or 5 coefficients, as OpenCV writes them (4 mean k3 = 0, none
/// mean no distortion).
///
/// ```
/// use layout_opt_solvers::camera::distortion_from_slice;
/// assert_eq!(distortion_from_slice(&[0.1, 0.0, 0.0, 0.0]).unwrap(), [0.1, 0.0, 0.0, 0.0, 0.0]);
/// let err = distortion_from_slice(&[1.0, 2.0]).unwrap_err();
/// assert_eq!(err.to_string(), "distortion must have 0, 4 or 5 coefficients [k1,k2,p1,p2,k3], got 2");
/// ```
pub fn distortion_from_slice(coefficients: &[f64]) -> Result<[f64; 5], CameraError> {
    let mut distortion = [0.0; 5];
    match coefficients.len() {
        0 | 4 | 5 => distortion[..coefficients.len()].copy_from_slice(coefficients),
        n => return Err(CameraError::BadDistortionLength(n)),
    }
    Ok(distortion)
}

/// Smallest focal length accepted, px: below one pixel per unit of
/// normalised coordinate no lens forms an image worth solving (and a
/// subnormal value would overflow the normalisation).
pub const MIN_FOCAL_PX: f64 = 1.0;
/// Largest focal length accepted, px: a 10⁸ px focal length is a field of
/// view of about 10⁻⁵ degrees on a 1280 px sensor, beyond any camera.
pub const MAX_FOCAL_PX: f64 = 1e8;

const PAPER_WIDTH: u32 = 1280;
const PAPER_HEIGHT: u32 = 720;

impl Camera {
    /// Builds a camera, checking that every parameter is usable.
    ///
    /// ```
    /// use layout_opt_solvers::camera::Camera;
    /// let camera = Camera::new(1000.0, 1000.0, 640.0, 360.0, 1280, 720, [0.0; 5]).unwrap();
    /// assert_eq!(camera.fx(), 1000.0);
    /// assert!(Camera::new(0.0, 1000.0, 640.0, 360.0, 1280, 720, [0.0; 5]).is_err());
    /// // A subnormal focal length, or one no lens has, is refused too.
    /// assert!(Camera::new(1e-320, 1000.0, 640.0, 360.0, 1280, 720, [0.0; 5]).is_err());
    /// assert!(Camera::new(1000.0, 1e12, 640.0, 360.0, 1280, 720, [0.0; 5]).is_err());
    /// ```
    pub fn new(
        fx: f64,
        fy: f64,
        cx: f64,
        cy: f64,
        width: u32,
        height: u32,
        distortion: [f64; 5],
    ) -> Result<Self, CameraError> {
        let usable = |f: f64| (MIN_FOCAL_PX..=MAX_FOCAL_PX).contains(&f);
        if !(usable(fx) && usable(fy)) {
            return Err(CameraError::BadFocalLength { fx, fy });
        }
        for (name, value) in [("cx", cx), ("cy", cy)] {
            if !value.is_finite() {
                return Err(CameraError::NotFinite { name, value });
            }
        }
        const NAMES: [&str; 5] = ["k1", "k2", "p1", "p2", "k3"];
        for (name, value) in NAMES.iter().zip(distortion) {
            if !value.is_finite() {
                return Err(CameraError::NotFinite { name, value });
            }
        }
        if width == 0 || height == 0 {
            return Err(CameraError::BadImageSize { width, height });
        }
        Ok(Self {
            fx,
            fy,
            cx,
            cy,
            width,
            height,
            distortion,
        })
    }

    /// The paper's camera (§4.2): fx 1301.473508, fy 1300.926193, cx 653,
    /// cy 508, 1280×720, with no distortion, as its simulations use.
    pub fn paper() -> Self {
        Self {
            fx: 1301.473508,
            fy: 1300.926193,
            cx: 653.0,
            cy: 508.0,
            width: PAPER_WIDTH,
            height: PAPER_HEIGHT,
            distortion: [0.0; 5],
        }
    }

    /// The paper's camera with its real-image distortion
    /// `[-0.087355, 0.204686, 0, 0, 0]`.
    pub fn paper_with_distortion() -> Self {
        Self {
            distortion: [-0.087355, 0.204686, 0.0, 0.0, 0.0],
            ..Self::paper()
        }
    }

    /// The same camera without distortion.
    pub fn without_distortion(&self) -> Self {
        Self {
            distortion: [0.0; 5],
            ..*self
        }
    }

    /// Horizontal focal length, px.
    pub fn fx(&self) -> f64 {
        self.fx
    }
    /// Vertical focal length, px.
    pub fn fy(&self) -> f64 {
        self.fy
    }
    /// Principal point column, px.
    pub fn cx(&self) -> f64 {
        self.cx
    }
    /// Principal point row, px.
    pub fn cy(&self) -> f64 {
        self.cy
    }
    /// Image width, px.
    pub fn width(&self) -> u32 {
        self.width
    }
    /// Image height, px.
    pub fn height(&self) -> u32 {
        self.height
    }
    /// Distortion coefficients `[k1, k2, p1, p2, k3]`.
    pub fn distortion(&self) -> [f64; 5] {
        self.distortion
    }
    /// Whether any distortion coefficient is non-zero.
    pub fn has_distortion(&self) -> bool {
        self.distortion.iter().any(|&c| c != 0.0)
    }

    /// Applies Brown–Conrady distortion to an undistorted normalised point
    /// (OpenCV's model).
    pub fn distort(&self, normalised: &Vector2<f64>) -> Vector2<f64> {
        let [k1, k2, p1, p2, k3] = self.distortion;
        let (x, y) = (normalised.x, normalised.y);
        let r2 = x * x + y * y;
        let radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
        Vector2::new(
            x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x),
            y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y,
        )
    }

    /// Jacobian of [`Camera::distort`] with respect to the undistorted
    /// normalised point.
    pub fn distort_jacobian(&self, normalised: &Vector2<f64>) -> Matrix2<f64> {
        let [k1, k2, p1, p2, k3] = self.distortion;
        let (x, y) = (normalised.x, normalised.y);
        let r2 = x * x + y * y;
        let radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
        // d(radial)/d(r2)
        let radial_r2 = k1 + r2 * (2.0 * k2 + 3.0 * r2 * k3);
        let dxx = radial + x * radial_r2 * 2.0 * x + 2.0 * p1 * y + p2 * 6.0 * x;
        let dxy = x * radial_r2 * 2.0 * y + 2.0 * p1 * x + p2 * 2.0 * y;
        let dyx = y * radial_r2 * 2.0 * x + p1 * 2.0 * x + 2.0 * p2 * y;
        let dyy = radial + y * radial_r2 * 2.0 * y + p1 * 6.0 * y + 2.0 * p2 * x;
        Matrix2::new(dxx, dxy, dyx, dyy)
    }

    /// Maps an undistorted normalised point to pixels (distortion applied).
    pub fn normalised_to_pixel(&self, normalised: &Vector2<f64>) -> Vector2<f64> {
        let distorted = if self.has_distortion() {
            self.distort(normalised)
        } else {
            *normalised
        };
        Vector2::new(
            self.fx * distorted.x + self.cx,
            self.fy * distorted.y + self.cy,
        )
    }

    /// Projects a camera-frame point to pixels. Returns `None` when the point
    /// is not in front of the camera (z ≤ 0).
    pub fn project(&self, point_camera_mm: &Vector3<f64>) -> Option<Vector2<f64>> {
        if point_camera_mm.z <= 0.0 {
            return None;
        }
        let normalised = Vector2::new(
            point_camera_mm.x / point_camera_mm.z,
            point_camera_mm.y / point_camera_mm.z,
        );
        Some(self.normalised_to_pixel(&normalised))
    }

    /// Removes intrinsics and distortion from a raw pixel: the undistorted
    /// normalised coordinates the solvers work on.
    ///
    /// The inversion is OpenCV's fixed-point iteration, followed by Newton
    /// steps on the exact model so that the result is accurate to
    /// [`UNDISTORT_TOLERANCE`].
    pub fn pixel_to_normalised(&self, pixel: &Vector2<f64>) -> Result<Vector2<f64>, CameraError> {
        let distorted = Vector2::new((pixel.x - self.cx) / self.fx, (pixel.y - self.cy) / self.fy);
        if !self.has_distortion() {
            return Ok(distorted);
        }
        let mut estimate = distorted;
        for _ in 0..UNDISTORT_MAX_ITERATIONS {
            let residual = self.distort(&estimate) - distorted;
            if residual.norm() < UNDISTORT_TOLERANCE {
                return Ok(estimate);
            }
            let step = match self.distort_jacobian(&estimate).try_inverse() {
                Some(inverse) => inverse * residual,
                None => break,
            };
            estimate -= step;
            if !estimate.iter().all(|v| v.is_finite()) {
                break;
            }
        }
        let residual = self.distort(&estimate) - distorted;
        if residual.norm() < 1e3 * UNDISTORT_TOLERANCE {
            Ok(estimate)
        } else {
            Err(CameraError::UndistortDiverged {
                u: pixel.x,
                v: pixel.y,
            })
        }
    }

    /// Whether a pixel lies inside the image with a margin (px).
    pub fn contains(&self, pixel: &Vector2<f64>, margin_px: f64) -> bool {
        pixel.x >= margin_px
            && pixel.y >= margin_px
            && pixel.x <= self.width as f64 - margin_px
            && pixel.y <= self.height as f64 - margin_px
    }
}

impl Default for Camera {
    fn default() -> Self {
        Self::paper()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn paper_camera_defaults() {
        let camera = Camera::default();
        assert_eq!(camera.fx(), 1301.473508);
        assert_eq!(camera.fy(), 1300.926193);
        assert_eq!((camera.cx(), camera.cy()), (653.0, 508.0));
        assert_eq!((camera.width(), camera.height()), (1280, 720));
        assert!(!camera.has_distortion());
        assert!(Camera::paper_with_distortion().has_distortion());
    }

    #[test]
    fn rejects_bad_parameters_with_clear_messages() {
        let err = Camera::new(-1.0, 1.0, 0.0, 0.0, 10, 10, [0.0; 5]).unwrap_err();
        assert!(err.to_string().contains("fx = -1"), "{err}");
        let err = Camera::new(1.0, 1.0, f64::NAN, 0.0, 10, 10, [0.0; 5]).unwrap_err();
        assert!(err.to_string().contains("cx"), "{err}");
        let err = Camera::new(1.0, 1.0, 0.0, 0.0, 0, 10, [0.0; 5]).unwrap_err();
        assert!(err.to_string().contains("0x10"), "{err}");
        let err = Camera::new(
            1.0,
            1.0,
            0.0,
            0.0,
            1,
            1,
            [0.0, f64::INFINITY, 0.0, 0.0, 0.0],
        )
        .unwrap_err();
        assert!(err.to_string().contains("k2"), "{err}");
    }

    #[test]
    fn undistort_inverts_distort() {
        let camera = Camera::new(
            1300.0,
            1301.0,
            653.0,
            508.0,
            1280,
            720,
            [-0.087355, 0.204686, 0.001, -0.0007, 0.01],
        )
        .unwrap();
        for &(x, y) in &[(0.0, 0.0), (0.3, -0.2), (-0.45, 0.27), (0.49, 0.4)] {
            let normalised = Vector2::new(x, y);
            let pixel = camera.normalised_to_pixel(&normalised);
            let back = camera.pixel_to_normalised(&pixel).unwrap();
            assert_relative_eq!(back, normalised, epsilon = 1e-11);
        }
    }

    #[test]
    fn distortion_jacobian_matches_central_differences() {
        let camera = Camera::new(1.0, 1.0, 0.0, 0.0, 1, 1, [-0.3, 0.2, 0.01, -0.02, 0.05]).unwrap();
        let point = Vector2::new(0.31, -0.22);
        let analytic = camera.distort_jacobian(&point);
        let h = 1e-6;
        for column in 0..2 {
            let mut delta = Vector2::zeros();
            delta[column] = h;
            let numeric =
                (camera.distort(&(point + delta)) - camera.distort(&(point - delta))) / (2.0 * h);
            assert_relative_eq!(
                analytic.column(column).into_owned(),
                numeric,
                epsilon = 1e-8
            );
        }
    }

    #[test]
    fn project_rejects_points_behind() {
        let camera = Camera::paper();
        assert!(camera.project(&Vector3::new(0.0, 0.0, -1.0)).is_none());
        let pixel = camera.project(&Vector3::new(0.0, 0.0, 500.0)).unwrap();
        assert_relative_eq!(pixel, Vector2::new(653.0, 508.0));
    }
}
