//! What a camera sees of a sphere: the exact silhouette conic, its ellipse
//! centre (what a blob detector measures) and the centroid of the filled
//! silhouette, and the [`Observation`] that the Monte-Carlo engine, the
//! error models and `solve` take as a feature's image point.
//!
//! # The silhouette
//!
//! A sphere of radius `r` with centre `C` in the camera frame is seen along
//! the cone of rays tangent to it. A ray through the undistorted normalised
//! image point `m = (x, y, 1)` touches the sphere when the angle θ between
//! `m` and `C` has `sin θ = r / |C|`, i.e. `(m·C)² = |m|² (|C|² − r²)`. So
//! the silhouette on the plane `z = 1` is the conic
//!
//! ```text
//!   mᵀ Q m = 0,   Q = C Cᵀ − (|C|² − r²) I        (normalised plane)
//!   Q_px = K⁻ᵀ Q K⁻¹                              (pixels, no distortion)
//! ```
//!
//! with `mᵀ Q m > 0` inside. It is a bounded ellipse exactly when the whole
//! sphere lies in front of the camera, `C_z > r`; otherwise the cone reaches
//! the plane `z = 0` and its section is a parabola or hyperbola (a
//! [`SphereImageError`]). Solving `∇(mᵀQm) = 0` for the centre gives, in
//! closed form,
//!
//! ```text
//!   m₀ = (C_x, C_y) · C_z / (C_z² − r²)  =  π(C) · C_z² / (C_z² − r²),
//! ```
//!
//! the projected centre `π(C)` pushed radially outward from the principal
//! point by the factor `1 / (1 − r²/C_z²)`. The displacement is
//! `|π(C)| r² / (C_z² − r²)`: it grows with `(r/C_z)²` and with the distance
//! from the principal point. The semi-axes are
//! `r √k / (C_z² − r²)` along `π(C)` and `r / √(C_z² − r²)` across it, with
//! `k = |C|² − r²`. The ellipse centre is an affine covariant, so in pixels
//! it is `K m₀`.
//!
//! # The filled silhouette's centroid
//!
//! A filled ellipse is centrally symmetric, so its centroid is its centre:
//! without distortion a centroiding detector and an ellipse fit measure the
//! same point. With lens distortion the silhouette in the raw image is the
//! distorted ellipse, no longer a conic; [`filled_centroid_px`] integrates
//! its centroid numerically (Green's theorem on a fine polygon).
//!
//! # Distortion: what [`Observation::EllipseCentre`] means
//!
//! The observation is the undistorted ellipse centre `m₀` mapped to pixels
//! through the camera's distortion, `K · distort(m₀)`: what a detector gives
//! when it fits the ellipse after undistorting the blob's edge (OpenCV's
//! usual pipeline), and what `solve` undistorts back to `m₀` exactly. Without
//! distortion it is also the centroid of the filled disc.

use crate::camera::Camera;
use crate::pose::Pose;
use nalgebra::{Matrix2x3, Matrix3, Vector2, Vector3};
use std::fmt;
use std::str::FromStr;

/// Why a sphere has no elliptical silhouette.
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub enum SphereImageError {
    /// The radius is not a positive finite number of millimetres.
    BadRadius(f64),
    /// The camera centre is inside the sphere or on its surface.
    CameraInsideSphere {
        /// Distance from the camera centre to the sphere centre, mm.
        distance_mm: f64,
        /// Sphere radius, mm.
        radius_mm: f64,
    },
    /// Part of the sphere is at or behind the plane z = 0 of the camera.
    NotInFront {
        /// Depth of the sphere centre, mm.
        depth_mm: f64,
        /// Sphere radius, mm.
        radius_mm: f64,
    },
}

impl fmt::Display for SphereImageError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SphereImageError::BadRadius(radius_mm) => write!(
                f,
                "sphere radius must be positive and finite, got {radius_mm} mm"
            ),
            SphereImageError::CameraInsideSphere {
                distance_mm,
                radius_mm,
            } => write!(
                f,
                "the camera centre is inside or on the sphere (centre {distance_mm} mm away, radius {radius_mm} mm): it has no silhouette"
            ),
            SphereImageError::NotInFront {
                depth_mm,
                radius_mm,
            } => write!(
                f,
                "the sphere (centre depth {depth_mm} mm, radius {radius_mm} mm) is not wholly in front of the camera: its silhouette is not an ellipse"
            ),
        }
    }
}

impl std::error::Error for SphereImageError {}

fn check(centre_camera_mm: &Vector3<f64>, radius_mm: f64) -> Result<(), SphereImageError> {
    if !(radius_mm > 0.0 && radius_mm.is_finite()) {
        return Err(SphereImageError::BadRadius(radius_mm));
    }
    let distance_mm = centre_camera_mm.norm();
    if distance_mm.is_nan() || distance_mm <= radius_mm {
        return Err(SphereImageError::CameraInsideSphere {
            distance_mm,
            radius_mm,
        });
    }
    if centre_camera_mm.z <= radius_mm || !distance_mm.is_finite() {
        return Err(SphereImageError::NotInFront {
            depth_mm: centre_camera_mm.z,
            radius_mm,
        });
    }
    Ok(())
}

/// The silhouette conic on the undistorted normalised plane,
/// `Q = C Cᵀ − (|C|² − r²) I`, positive inside (module docs).
pub fn normalised_conic(
    centre_camera_mm: &Vector3<f64>,
    radius_mm: f64,
) -> Result<Matrix3<f64>, SphereImageError> {
    check(centre_camera_mm, radius_mm)?;
    let k = centre_camera_mm.norm_squared() - radius_mm * radius_mm;
    Ok(centre_camera_mm * centre_camera_mm.transpose() - Matrix3::identity() * k)
}

/// The silhouette conic in pixels, `Q_px = K⁻ᵀ Q K⁻¹`, positive inside; the
/// camera's distortion is ignored (the distorted silhouette is no conic).
pub fn pixel_conic(
    camera: &Camera,
    centre_camera_mm: &Vector3<f64>,
    radius_mm: f64,
) -> Result<Matrix3<f64>, SphereImageError> {
    let q = normalised_conic(centre_camera_mm, radius_mm)?;
    let k_inverse = Matrix3::new(
        1.0 / camera.fx(),
        0.0,
        -camera.cx() / camera.fx(),
        0.0,
        1.0 / camera.fy(),
        -camera.cy() / camera.fy(),
        0.0,
        0.0,
        1.0,
    );
    Ok(k_inverse.transpose() * q * k_inverse)
}

/// The silhouette ellipse's centre on the undistorted normalised plane,
/// `(C_x, C_y) · C_z / (C_z² − r²)`.
pub fn ellipse_centre_normalised(
    centre_camera_mm: &Vector3<f64>,
    radius_mm: f64,
) -> Result<Vector2<f64>, SphereImageError> {
    check(centre_camera_mm, radius_mm)?;
    let scale = centre_camera_mm.z / (centre_camera_mm.z.powi(2) - radius_mm * radius_mm);
    Ok(Vector2::new(centre_camera_mm.x, centre_camera_mm.y) * scale)
}

/// `∂m₀/∂C` of [`ellipse_centre_normalised`] (2×3). With `r = 0` it is the
/// pinhole projection's Jacobian.
pub fn ellipse_centre_jacobian(centre_camera_mm: &Vector3<f64>, radius_mm: f64) -> Matrix2x3<f64> {
    let (x, y, z) = (centre_camera_mm.x, centre_camera_mm.y, centre_camera_mm.z);
    let r2 = radius_mm * radius_mm;
    let denominator = z * z - r2;
    let scale = z / denominator;
    let scale_z = -(z * z + r2) / (denominator * denominator);
    Matrix2x3::new(scale, 0.0, x * scale_z, 0.0, scale, y * scale_z)
}

/// The silhouette's semi-axes on the normalised plane: `(along, across)`
/// the direction of the projected centre from the principal point.
pub fn semi_axes_normalised(
    centre_camera_mm: &Vector3<f64>,
    radius_mm: f64,
) -> Result<(f64, f64), SphereImageError> {
    check(centre_camera_mm, radius_mm)?;
    let r2 = radius_mm * radius_mm;
    let denominator = centre_camera_mm.z.powi(2) - r2;
    let k = centre_camera_mm.norm_squared() - r2;
    Ok((
        radius_mm * k.sqrt() / denominator,
        radius_mm / denominator.sqrt(),
    ))
}

/// Vertices of the polygon that approximates the centroid integral in
/// [`filled_centroid_px`] by default.
pub const CENTROID_POLYGON_VERTICES: usize = 720;

/// Centroid of the filled silhouette in raw pixels, distortion included: the
/// undistorted ellipse is sampled at `vertices` points equally spaced in its
/// affine parameter, each is distorted, and the polygon's area centroid is
/// taken (Green's theorem). Without distortion the polygon is an affine
/// image of a regular one and the result is the ellipse centre exactly; with
/// distortion it converges as `1/vertices²`.
pub fn filled_centroid_px(
    camera: &Camera,
    centre_camera_mm: &Vector3<f64>,
    radius_mm: f64,
    vertices: usize,
) -> Result<Vector2<f64>, SphereImageError> {
    let centre = ellipse_centre_normalised(centre_camera_mm, radius_mm)?;
    let (along, across) = semi_axes_normalised(centre_camera_mm, radius_mm)?;
    let direction = Vector2::new(centre_camera_mm.x, centre_camera_mm.y);
    let u = if direction.norm() > 0.0 {
        direction.normalize()
    } else {
        Vector2::x()
    };
    let v = Vector2::new(-u.y, u.x);
    let vertices = vertices.max(3);
    let point = |index: usize| {
        let angle = std::f64::consts::TAU * index as f64 / vertices as f64;
        let m = centre + u * (along * angle.cos()) + v * (across * angle.sin());
        camera.normalised_to_pixel(&m)
    };
    // Shift to the first vertex for conditioning.
    let origin = point(0);
    let (mut area2, mut cx, mut cy) = (0.0, 0.0, 0.0);
    let mut previous = point(0) - origin;
    for index in 1..=vertices {
        let current = point(index % vertices) - origin;
        let cross = previous.x * current.y - current.x * previous.y;
        area2 += cross;
        cx += (previous.x + current.x) * cross;
        cy += (previous.y + current.y) * cross;
        previous = current;
    }
    Ok(origin + Vector2::new(cx, cy) / (3.0 * area2))
}

/// Everything about one sphere's image.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SphereSilhouette {
    /// The silhouette conic in pixels (distortion ignored), positive inside.
    pub conic_px: Matrix3<f64>,
    /// The ellipse centre on the undistorted normalised plane.
    pub ellipse_centre_normalised: Vector2<f64>,
    /// The ellipse centre in raw pixels (`K · distort(m₀)`).
    pub ellipse_centre_px: Vector2<f64>,
    /// The projection of the sphere's centre in raw pixels.
    pub centre_px: Vector2<f64>,
}

impl SphereSilhouette {
    /// The image of the sphere of radius `radius_mm` centred at
    /// `centre_camera_mm`.
    pub fn new(
        camera: &Camera,
        centre_camera_mm: &Vector3<f64>,
        radius_mm: f64,
    ) -> Result<Self, SphereImageError> {
        let conic_px = pixel_conic(camera, centre_camera_mm, radius_mm)?;
        let ellipse_centre_normalised = ellipse_centre_normalised(centre_camera_mm, radius_mm)?;
        let centre_normalised = Vector2::new(
            centre_camera_mm.x / centre_camera_mm.z,
            centre_camera_mm.y / centre_camera_mm.z,
        );
        Ok(Self {
            conic_px,
            ellipse_centre_normalised,
            ellipse_centre_px: camera.normalised_to_pixel(&ellipse_centre_normalised),
            centre_px: camera.normalised_to_pixel(&centre_normalised),
        })
    }

    /// How far the ellipse centre lies from the projected centre, px.
    pub fn displacement_px(&self) -> f64 {
        (self.ellipse_centre_px - self.centre_px).norm()
    }
}

/// What a feature's image point is.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "kebab-case"))]
pub enum Observation {
    /// The projection of the sphere's centre (an ideal point feature).
    Centre,
    /// The centre of the sphere's silhouette ellipse: what a blob detector
    /// measures (module docs).
    #[default]
    EllipseCentre,
}

impl Observation {
    /// Every observation model.
    pub const ALL: &'static [Observation] = &[Observation::Centre, Observation::EllipseCentre];

    /// Stable CLI name.
    pub fn name(self) -> &'static str {
        match self {
            Observation::Centre => "centre",
            Observation::EllipseCentre => "ellipse-centre",
        }
    }

    /// The observed point on the undistorted normalised plane of a sphere of
    /// radius `radius_mm` centred at `centre_camera_mm`.
    pub fn normalised(
        self,
        centre_camera_mm: &Vector3<f64>,
        radius_mm: f64,
    ) -> Result<Vector2<f64>, SphereImageError> {
        match self {
            Observation::Centre => {
                if !(centre_camera_mm.z > 0.0 && centre_camera_mm.norm().is_finite()) {
                    return Err(SphereImageError::NotInFront {
                        depth_mm: centre_camera_mm.z,
                        radius_mm,
                    });
                }
                Ok(Vector2::new(
                    centre_camera_mm.x / centre_camera_mm.z,
                    centre_camera_mm.y / centre_camera_mm.z,
                ))
            }
            Observation::EllipseCentre => ellipse_centre_normalised(centre_camera_mm, radius_mm),
        }
    }

    /// The observed raw pixels of every sphere of a marker at `pose`, written
    /// into `out` (cleared first).
    pub fn pixels_into(
        self,
        camera: &Camera,
        pose: &Pose,
        object: &[Vector3<f64>],
        radius_mm: f64,
        out: &mut Vec<Vector2<f64>>,
    ) -> Result<(), SphereImageError> {
        out.clear();
        for p in object {
            let m = self.normalised(&pose.transform(p), radius_mm)?;
            out.push(camera.normalised_to_pixel(&m));
        }
        Ok(())
    }
}

/// The image bias of ellipse-centre observations, raw pixels: each sphere's
/// ellipse centre minus its projected centre, written into `out` (cleared
/// first).
pub fn ellipse_centre_bias_px_into(
    camera: &Camera,
    pose: &Pose,
    object: &[Vector3<f64>],
    radius_mm: f64,
    out: &mut Vec<Vector2<f64>>,
) -> Result<(), SphereImageError> {
    out.clear();
    for p in object {
        let c = pose.transform(p);
        let ellipse = camera.normalised_to_pixel(&ellipse_centre_normalised(&c, radius_mm)?);
        let centre = camera.normalised_to_pixel(&Vector2::new(c.x / c.z, c.y / c.z));
        out.push(ellipse - centre);
    }
    Ok(())
}

impl fmt::Display for Observation {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Observation {
    type Err = String;

    fn from_str(text: &str) -> Result<Self, Self::Err> {
        Observation::ALL
            .iter()
            .copied()
            .find(|o| o.name() == text.trim())
            .ok_or_else(|| {
                format!("unknown observation {text:?}: expected `centre` or `ellipse-centre`")
            })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn typed_errors_for_spheres_without_an_ellipse() {
        let inside = ellipse_centre_normalised(&Vector3::new(1.0, 0.0, 3.0), 5.0).unwrap_err();
        assert!(matches!(
            inside,
            SphereImageError::CameraInsideSphere { .. }
        ));
        assert!(
            inside.to_string().contains("inside or on the sphere"),
            "{inside}"
        );
        let straddles = ellipse_centre_normalised(&Vector3::new(50.0, 0.0, 4.0), 5.0).unwrap_err();
        assert!(matches!(straddles, SphereImageError::NotInFront { .. }));
        assert!(
            straddles.to_string().contains("not an ellipse"),
            "{straddles}"
        );
        assert_eq!(
            normalised_conic(&Vector3::new(0.0, 0.0, 100.0), -1.0).unwrap_err(),
            SphereImageError::BadRadius(-1.0)
        );
        assert!(Observation::Centre
            .normalised(&Vector3::new(0.0, 0.0, -1.0), 5.0)
            .is_err());
        assert!(ellipse_centre_normalised(&Vector3::new(f64::NAN, 0.0, 100.0), 5.0).is_err());
    }

    #[test]
    fn centre_is_the_conic_centre_and_outward_of_the_projection() {
        let c = Vector3::new(60.0, -35.0, 210.0);
        let q = normalised_conic(&c, 5.0).unwrap();
        let m0 = ellipse_centre_normalised(&c, 5.0).unwrap();
        // The gradient of mᵀQm vanishes at the centre.
        let gradient = (q * Vector3::new(m0.x, m0.y, 1.0))
            .fixed_rows::<2>(0)
            .into_owned();
        assert!(gradient.norm() < 1e-9 * q.norm(), "{gradient}");
        let projected = Vector2::new(c.x / c.z, c.y / c.z);
        assert_relative_eq!(m0.normalize(), projected.normalize(), epsilon = 1e-15);
        assert!(m0.norm() > projected.norm());
    }

    #[test]
    fn jacobian_matches_central_differences() {
        let c = Vector3::new(40.0, 25.0, 180.0);
        let analytic = ellipse_centre_jacobian(&c, 6.0);
        let h = 1e-5;
        for column in 0..3 {
            let mut delta = Vector3::zeros();
            delta[column] = h;
            let numeric = (ellipse_centre_normalised(&(c + delta), 6.0).unwrap()
                - ellipse_centre_normalised(&(c - delta), 6.0).unwrap())
                / (2.0 * h);
            assert_relative_eq!(
                analytic.column(column).into_owned(),
                numeric,
                epsilon = 1e-12,
                max_relative = 1e-7
            );
        }
    }

    #[test]
    fn filled_centroid_is_the_ellipse_centre_without_distortion() {
        let camera = Camera::paper();
        let c = Vector3::new(-70.0, 30.0, 200.0);
        let silhouette = SphereSilhouette::new(&camera, &c, 10.0).unwrap();
        let centroid = filled_centroid_px(&camera, &c, 10.0, 64).unwrap();
        assert_relative_eq!(centroid, silhouette.ellipse_centre_px, epsilon = 1e-9);
        // With distortion the filled centroid differs from the distorted
        // centre, and the polygon has converged at the default size.
        let distorted = Camera::paper_with_distortion();
        let fine = filled_centroid_px(&distorted, &c, 10.0, 4 * CENTROID_POLYGON_VERTICES).unwrap();
        let default = filled_centroid_px(&distorted, &c, 10.0, CENTROID_POLYGON_VERTICES).unwrap();
        assert!(
            (fine - default).norm() < 1e-4,
            "{}",
            (fine - default).norm()
        );
    }

    #[test]
    fn observation_names_round_trip() {
        for &o in Observation::ALL {
            assert_eq!(o.name().parse::<Observation>().unwrap(), o);
        }
        assert_eq!(Observation::default(), Observation::EllipseCentre);
        let err = "blob".parse::<Observation>().unwrap_err();
        assert!(err.contains("ellipse-centre"), "{err}");
    }
}
