//! Maximum-likelihood pose from the ellipse centres of sphere images:
//! Levenberg–Marquardt on the reprojection error of the exact sphere-image
//! model ([`crate::sphere_image`]) instead of the point projection.
//!
//! A blob detector measures the centre of a sphere's silhouette ellipse,
//! which lies outward of the projected sphere centre by the factor
//! `C_z² / (C_z² − r²)` (on the normalised plane). Fitting projected centres
//! to such points biases the pose; this solver fits the ellipse centres
//! themselves:
//!
//! ```text
//!   min over (R, t)  Σ_i ‖g(R P_i + t) − m_i‖²,   g(C) = (C_x, C_y) · C_z / (C_z² − r²)
//! ```
//!
//! on the undistorted normalised plane (`m_i` the undistorted ellipse
//! centres). With `r → 0` it is [`super::ml`]'s cost. On noise-free ellipse
//! centres the minimum is the true pose, with zero residual.
//!
//! Start: the best SQPnP candidate on the ellipse centres (as [`super::ml`];
//! the displacement is a fraction of a pixel, well inside the basin).
//! The Levenberg–Marquardt loop, its damping, tolerances and the
//! parameterisation `R ← exp([ω]×) R`, `t ← t + δt` are [`super::ml`]'s;
//! nothing is allocated per iteration.

use super::ml::levenberg_marquardt;
use super::{best_candidate, sqpnp, PnpError};
use crate::pose::Pose;
use crate::sphere_image::ellipse_centre_jacobian;
use nalgebra::{SMatrix, Vector2, Vector3};

/// Why the sphere-model fit failed.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum SphereFitError {
    /// The start (or the input) was rejected by the PnP layer.
    Pnp(PnpError),
    /// The radius is not a positive finite number of millimetres.
    BadRadius(f64),
    /// No start puts every sphere wholly in front of the camera (depth > radius).
    NotInFront {
        /// Sphere radius, mm.
        radius_mm: f64,
    },
}

impl std::fmt::Display for SphereFitError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            // Transparent: the PnP error's own message.
            SphereFitError::Pnp(error) => std::fmt::Display::fmt(error, f),
            SphereFitError::BadRadius(radius_mm) => write!(
                f,
                "sphere radius must be positive and finite, got {radius_mm} mm"
            ),
            SphereFitError::NotInFront { radius_mm } => write!(
                f,
                "ML (sphere model): no start puts every {radius_mm} mm sphere wholly in front of the camera"
            ),
        }
    }
}

impl std::error::Error for SphereFitError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            // Transparent: the PnP error stands in for this one, so its
            // source is this one's.
            SphereFitError::Pnp(error) => std::error::Error::source(error),
            _ => None,
        }
    }
}

impl From<PnpError> for SphereFitError {
    fn from(error: PnpError) -> Self {
        SphereFitError::Pnp(error)
    }
}

/// `Σ ‖g(C_i) − m_i‖²`, infinite when a sphere is not wholly in front.
fn cost(pose: &Pose, object: &[Vector3<f64>], image: &[Vector2<f64>], radius_mm: f64) -> f64 {
    let r2 = radius_mm * radius_mm;
    let mut sum = 0.0;
    for (p, m) in object.iter().zip(image) {
        let c = pose.transform(p);
        if c.z <= radius_mm || c.z.is_nan() {
            return f64::INFINITY;
        }
        let scale = c.z / (c.z * c.z - r2);
        sum += (Vector2::new(c.x * scale, c.y * scale) - m).norm_squared();
    }
    sum
}

/// `JᵀJ` (lower triangle) and `Jᵀr` of the ellipse-centre residuals.
fn normal_equations(
    pose: &Pose,
    object: &[Vector3<f64>],
    image: &[Vector2<f64>],
    radius_mm: f64,
) -> (SMatrix<f64, 6, 6>, SMatrix<f64, 6, 1>) {
    let r2 = radius_mm * radius_mm;
    let mut normal = SMatrix::<f64, 6, 6>::zeros();
    let mut gradient = SMatrix::<f64, 6, 1>::zeros();
    for (p, m) in object.iter().zip(image) {
        let rotated = pose.rotation * p;
        let c = rotated + pose.translation;
        let scale = c.z / (c.z * c.z - r2);
        let residual = Vector2::new(c.x * scale - m.x, c.y * scale - m.y);
        // ∂g/∂C, then ∂C/∂ω = −[R P]× and ∂C/∂t = I.
        let model = ellipse_centre_jacobian(&c, radius_mm);
        let rotation_part = model * -rotated.cross_matrix();
        let rows: [SMatrix<f64, 6, 1>; 2] = std::array::from_fn(|r| {
            SMatrix::<f64, 6, 1>::new(
                rotation_part[(r, 0)],
                rotation_part[(r, 1)],
                rotation_part[(r, 2)],
                model[(r, 0)],
                model[(r, 1)],
                model[(r, 2)],
            )
        });
        for (row, r) in rows.iter().zip(residual.iter()) {
            normal.syger(1.0, row, row, 1.0);
            gradient += row * *r;
        }
    }
    (normal, gradient)
}

/// Levenberg–Marquardt refinement of `start` on the ellipse-centre
/// reprojection error. Never returns a pose with a higher cost than `start`.
pub fn refine(
    start: &Pose,
    object: &[Vector3<f64>],
    image: &[Vector2<f64>],
    radius_mm: f64,
) -> Pose {
    levenberg_marquardt(
        start,
        |pose| normal_equations(pose, object, image, radius_mm),
        |pose| cost(pose, object, image, radius_mm),
    )
}

/// ML with the sphere model: the best SQPnP candidate on the ellipse centres
/// `image` (undistorted normalised), refined by LM on the exact model for
/// spheres of radius `radius_mm`.
pub fn solve(
    object: &[Vector3<f64>],
    image: &[Vector2<f64>],
    radius_mm: f64,
) -> Result<Pose, SphereFitError> {
    if !(radius_mm > 0.0 && radius_mm.is_finite()) {
        return Err(SphereFitError::BadRadius(radius_mm));
    }
    let starts = sqpnp::solve(object, image)?;
    let start = best_candidate("ML (sphere model)", &starts, object, image)?;
    if !cost(&start, object, image, radius_mm).is_finite() {
        return Err(SphereFitError::NotInFront { radius_mm });
    }
    Ok(refine(&start, object, image, radius_mm))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pose::{perturb, rotation_error_deg};
    use crate::sphere_image::ellipse_centre_normalised;
    use nalgebra::Rotation3;

    /// The fused normal equations equal `Σ JᵀJ`, `Σ Jᵀr` with J from central
    /// differences of the model.
    #[test]
    fn normal_equations_match_central_differences() {
        let pose = Pose::new(
            Rotation3::from_euler_angles(0.3, -0.7, 1.1),
            Vector3::new(30.0, -20.0, 250.0),
        );
        let object = [
            Vector3::new(40.0, -25.0, 10.0),
            Vector3::new(-30.0, 5.0, 20.0),
            Vector3::new(0.0, 35.0, -15.0),
            Vector3::new(10.0, 10.0, 40.0),
        ];
        let radius = 8.0;
        let image: Vec<Vector2<f64>> = object
            .iter()
            .map(|p| pose.project_normalised(p) + Vector2::new(2e-3, -1e-3))
            .collect();
        let (mut normal, gradient) = normal_equations(&pose, &object, &image, radius);
        normal.fill_upper_triangle_with_lower_triangle();
        let model = |pose: &Pose, p: &Vector3<f64>| {
            ellipse_centre_normalised(&pose.transform(p), radius).unwrap()
        };
        let mut expected_normal = SMatrix::<f64, 6, 6>::zeros();
        let mut expected_gradient = SMatrix::<f64, 6, 1>::zeros();
        let h = 1e-6;
        for (p, m) in object.iter().zip(&image) {
            let jacobian = SMatrix::<f64, 2, 6>::from_fn(|row, column| {
                let mut delta = SMatrix::<f64, 6, 1>::zeros();
                delta[column] = h;
                (model(&perturb(&pose, &delta), p) - model(&perturb(&pose, &-delta), p))[row]
                    / (2.0 * h)
            });
            expected_normal += jacobian.transpose() * jacobian;
            expected_gradient += jacobian.transpose() * (model(&pose, p) - m);
        }
        assert!((normal - expected_normal).norm() <= 1e-6 * expected_normal.norm());
        assert!((gradient - expected_gradient).norm() <= 1e-6 * expected_gradient.norm());
    }

    #[test]
    fn exact_on_noise_free_ellipse_centres_and_rejects_bad_radii() {
        let object = crate::synthetic::biprism_points(50.0);
        let truth = Pose::new(
            Rotation3::from_euler_angles(0.5, 0.2, -0.3),
            Vector3::new(80.0, 40.0, 220.0),
        );
        let radius = 10.0;
        let image: Vec<Vector2<f64>> = object
            .iter()
            .map(|p| ellipse_centre_normalised(&truth.transform(p), radius).unwrap())
            .collect();
        let pose = solve(&object, &image, radius).unwrap();
        assert!(rotation_error_deg(&truth.rotation, &pose.rotation) < 1e-6);
        assert!((pose.translation - truth.translation).norm() < 1e-6);
        // The point model on the same data is measurably off.
        let naive = crate::pnp::ml::solve(&object, &image).unwrap()[0];
        assert!(rotation_error_deg(&truth.rotation, &naive.rotation) > 1e-3);
        assert_eq!(
            solve(&object, &image, 0.0).unwrap_err(),
            SphereFitError::BadRadius(0.0)
        );
    }
}
