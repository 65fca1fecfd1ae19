//! First-order pose covariance `Σ = (Jᵀ W J)⁻¹` (docs/paper-notes.md, "Error
//! models beside the paper's").
//!
//! J is the 2n×6 Jacobian of the pixel reprojections with respect to the pose
//! perturbation `(ω, δt)` (`R ← exp([ω]×) R`, `t ← t + δt`; ω in radians about
//! the camera axes, δt in mm) at the true pose, with the camera's distortion
//! included. W is block-diagonal with each point's inverse pixel covariance,
//! here `σ_i⁻² I₂` for per-point isotropic noise. For an unbiased estimator
//! under Gaussian pixel noise this is the Cramér–Rao lower bound; the ML
//! estimator reaches it as noise → 0.
//!
//! The RMS geodesic rotation error is `√trace(Σ_ωω)`: for small errors the
//! geodesic angle is ‖ω‖, and `E‖ω‖² = trace Σ_ωω`.

use crate::camera::Camera;
use crate::pose::{normalised_projection_jacobian, Pose};
use nalgebra::{Matrix2, SMatrix, Vector2, Vector3};

/// Why a first-order covariance could not be computed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum FirstOrderError {
    /// A point is not in front of the camera.
    #[error("object point {0} is not in front of the camera")]
    BehindCamera(usize),
    /// The number of noise levels differs from the number of points.
    #[error("{points} points but {sigmas} noise levels")]
    MismatchedLengths {
        /// Number of points.
        points: usize,
        /// Number of σ values.
        sigmas: usize,
    },
    /// A noise level is not positive and finite.
    #[error("noise level {0} px is not positive and finite")]
    BadSigma(f64),
    /// The Fisher information is singular: the pose is not observable.
    #[error("the pose is not observable from these points (singular information matrix)")]
    Singular,
}

/// A first-order pose covariance.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoseCovariance {
    /// 6×6 covariance of `(ω [rad], δt [mm])`.
    pub covariance: SMatrix<f64, 6, 6>,
    /// |t| of the pose it was computed at, mm (for the relative figure).
    pub translation_norm_mm: f64,
}

impl PoseCovariance {
    /// RMS geodesic rotation error, degrees: `√trace(Σ_ωω)`.
    pub fn rms_rotation_deg(&self) -> f64 {
        let trace = self.covariance[(0, 0)] + self.covariance[(1, 1)] + self.covariance[(2, 2)];
        trace.max(0.0).sqrt().to_degrees()
    }

    /// RMS rotation error about each camera axis (x, y, z), degrees. About x
    /// is pitch, about y yaw (pan), about z (the optical axis) roll.
    pub fn rms_rotation_per_axis_deg(&self) -> Vector3<f64> {
        Vector3::from_fn(|k, _| self.covariance[(k, k)].max(0.0).sqrt().to_degrees())
    }

    /// RMS translation error, mm: `√trace(Σ_tt)`.
    pub fn rms_translation_mm(&self) -> f64 {
        let trace = self.covariance[(3, 3)] + self.covariance[(4, 4)] + self.covariance[(5, 5)];
        trace.max(0.0).sqrt()
    }

    /// RMS translation error as a percentage of |t|.
    pub fn rms_translation_percent(&self) -> f64 {
        100.0 * self.rms_translation_mm() / self.translation_norm_mm
    }
}

/// Jacobian of the pixel projection of object point `p` with respect to the
/// pose perturbation, distortion included: `K · D_distort · ∂π/∂(ω, δt)`.
pub fn pixel_jacobian(camera: &Camera, pose: &Pose, p: &Vector3<f64>) -> SMatrix<f64, 2, 6> {
    let camera_point = pose.transform(p);
    let normalised_jacobian = normalised_projection_jacobian(pose, p);
    let focal = Matrix2::new(camera.fx(), 0.0, 0.0, camera.fy());
    if camera.has_distortion() {
        let m = Vector2::new(
            camera_point.x / camera_point.z,
            camera_point.y / camera_point.z,
        );
        focal * camera.distort_jacobian(&m) * normalised_jacobian
    } else {
        focal * normalised_jacobian
    }
}

/// The first-order pose covariance for per-point isotropic pixel noise
/// `sigma_px[i]`.
pub fn pose_covariance(
    camera: &Camera,
    pose: &Pose,
    object: &[Vector3<f64>],
    sigma_px: &[f64],
) -> Result<PoseCovariance, FirstOrderError> {
    if sigma_px.len() != object.len() {
        return Err(FirstOrderError::MismatchedLengths {
            points: object.len(),
            sigmas: sigma_px.len(),
        });
    }
    let mut information = SMatrix::<f64, 6, 6>::zeros();
    for (index, (p, &sigma)) in object.iter().zip(sigma_px).enumerate() {
        if !(sigma > 0.0 && sigma.is_finite()) {
            return Err(FirstOrderError::BadSigma(sigma));
        }
        if pose.transform(p).z <= 0.0 {
            return Err(FirstOrderError::BehindCamera(index));
        }
        let jacobian = pixel_jacobian(camera, pose, p);
        information += jacobian.transpose() * jacobian / (sigma * sigma);
    }
    let covariance = information
        .cholesky()
        .ok_or(FirstOrderError::Singular)?
        .inverse();
    Ok(PoseCovariance {
        covariance,
        translation_norm_mm: pose.translation.norm(),
    })
}

/// [`pose_covariance`] with the same σ for every point.
pub fn pose_covariance_isotropic(
    camera: &Camera,
    pose: &Pose,
    object: &[Vector3<f64>],
    sigma_px: f64,
) -> Result<PoseCovariance, FirstOrderError> {
    if !(sigma_px > 0.0 && sigma_px.is_finite()) {
        return Err(FirstOrderError::BadSigma(sigma_px));
    }
    let mut information = SMatrix::<f64, 6, 6>::zeros();
    for (index, p) in object.iter().enumerate() {
        if pose.transform(p).z <= 0.0 {
            return Err(FirstOrderError::BehindCamera(index));
        }
        let jacobian = pixel_jacobian(camera, pose, p);
        information += jacobian.transpose() * jacobian;
    }
    let covariance = information
        .cholesky()
        .ok_or(FirstOrderError::Singular)?
        .inverse()
        * (sigma_px * sigma_px);
    Ok(PoseCovariance {
        covariance,
        translation_norm_mm: pose.translation.norm(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pose::perturb;
    use approx::assert_relative_eq;
    use nalgebra::Rotation3;

    #[test]
    fn pixel_jacobian_matches_central_differences_with_distortion() {
        let camera = Camera::paper_with_distortion();
        let pose = Pose::new(
            Rotation3::from_euler_angles(0.4, 0.2, -0.3),
            Vector3::new(60.0, -40.0, 350.0),
        );
        let p = Vector3::new(30.0, 20.0, -10.0);
        let analytic = pixel_jacobian(&camera, &pose, &p);
        let h = 1e-6;
        for column in 0..6 {
            let mut delta = SMatrix::<f64, 6, 1>::zeros();
            delta[column] = h;
            let pixel = |pose: &Pose| camera.project(&pose.transform(&p)).unwrap();
            let numeric =
                (pixel(&perturb(&pose, &delta)) - pixel(&perturb(&pose, &(-delta)))) / (2.0 * h);
            assert_relative_eq!(
                analytic.column(column).into_owned(),
                numeric,
                epsilon = 1e-5,
                max_relative = 1e-6
            );
        }
    }

    #[test]
    fn isotropic_and_per_point_agree_and_scale_with_sigma() {
        let camera = Camera::paper();
        let pose = Pose::new(
            Rotation3::from_euler_angles(0.3, 0.1, 0.2),
            Vector3::new(0.0, 0.0, 500.0),
        );
        let object = crate::synthetic::biprism_points(50.0);
        let a = pose_covariance_isotropic(&camera, &pose, &object, 0.5).unwrap();
        let b = pose_covariance(&camera, &pose, &object, &[0.5; 7]).unwrap();
        assert_relative_eq!(
            a.rms_rotation_deg(),
            b.rms_rotation_deg(),
            max_relative = 1e-10
        );
        let c = pose_covariance_isotropic(&camera, &pose, &object, 1.0).unwrap();
        assert_relative_eq!(
            c.rms_rotation_deg(),
            2.0 * a.rms_rotation_deg(),
            max_relative = 1e-10
        );
        assert!(matches!(
            pose_covariance(&camera, &pose, &object, &[0.5; 3]),
            Err(FirstOrderError::MismatchedLengths { .. })
        ));
        assert_eq!(
            pose_covariance_isotropic(&camera, &pose, &object, 0.0).unwrap_err(),
            FirstOrderError::BadSigma(0.0)
        );
    }
}
