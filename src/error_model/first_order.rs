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

/// [`pixel_jacobian`] of point `index` at `p`, once its σ is a positive
/// number and the point is in front of the camera.
fn checked_jacobian(
    camera: &Camera,
    pose: &Pose,
    index: usize,
    p: &Vector3<f64>,
    sigma: f64,
) -> Result<SMatrix<f64, 2, 6>, FirstOrderError> {
    if !(sigma > 0.0 && sigma.is_finite()) {
        return Err(FirstOrderError::BadSigma(sigma));
    }
    if pose.transform(p).z <= 0.0 {
        return Err(FirstOrderError::BehindCamera(index));
    }
    Ok(pixel_jacobian(camera, pose, p))
}

/// The pose information `Σ Jᵢᵀ Jᵢ / σᵢ²` for per-point isotropic pixel
/// noise `sigma_px[i]`, every σ positive and every point in front.
pub fn pose_information(
    camera: &Camera,
    pose: &Pose,
    object: &[Vector3<f64>],
    sigma_px: &[f64],
) -> Result<SMatrix<f64, 6, 6>, FirstOrderError> {
    if sigma_px.len() != object.len() {
        return Err(FirstOrderError::MismatchedLengths {
            points: object.len(),
            sigmas: sigma_px.len(),
        });
    }
    let mut information = SMatrix::<f64, 6, 6>::zeros();
    for (index, (p, &sigma)) in object.iter().zip(sigma_px).enumerate() {
        let jacobian = checked_jacobian(camera, pose, index, p, sigma)?;
        information += jacobian.transpose() * jacobian / (sigma * sigma);
    }
    Ok(information)
}

/// The first-order pose covariance for per-point isotropic pixel noise
/// `sigma_px[i]`.
pub fn pose_covariance(
    camera: &Camera,
    pose: &Pose,
    object: &[Vector3<f64>],
    sigma_px: &[f64],
) -> Result<PoseCovariance, FirstOrderError> {
    let information = pose_information(camera, pose, object, sigma_px)?;
    let covariance = information
        .cholesky()
        .ok_or(FirstOrderError::Singular)?
        .inverse();
    Ok(PoseCovariance {
        covariance,
        translation_norm_mm: pose.translation.norm(),
    })
}

/// The first-order covariance of an unweighted least-squares pose fit
/// whose image points carry independent isotropic noise `sigma_px[i]` and,
/// on top, one error shared by every point, isotropic with σ `common_px`:
/// with `A = Σ Jᵢᵀ Jᵢ`, the sandwich
/// `A⁻¹ (Σ σᵢ² Jᵢᵀ Jᵢ + c² (Σ Jᵢ)ᵀ (Σ Jᵢ)) A⁻¹`. A shared error (a shading
/// that pulls every centre towards one lamp) moves the pose as a whole, and
/// the residuals cannot show it; per-point σ alone would leave it out.
pub fn pose_covariance_sandwich(
    camera: &Camera,
    pose: &Pose,
    object: &[Vector3<f64>],
    sigma_px: &[f64],
    common_px: f64,
) -> Result<PoseCovariance, FirstOrderError> {
    if sigma_px.len() != object.len() {
        return Err(FirstOrderError::MismatchedLengths {
            points: object.len(),
            sigmas: sigma_px.len(),
        });
    }
    if !(common_px >= 0.0 && common_px.is_finite()) {
        return Err(FirstOrderError::BadSigma(common_px));
    }
    let (mut design, mut spread) = (SMatrix::<f64, 6, 6>::zeros(), SMatrix::<f64, 6, 6>::zeros());
    let mut shared = SMatrix::<f64, 2, 6>::zeros();
    for (index, (p, &sigma)) in object.iter().zip(sigma_px).enumerate() {
        let jacobian = checked_jacobian(camera, pose, index, p, sigma)?;
        let normal = jacobian.transpose() * jacobian;
        design += normal;
        spread += normal * (sigma * sigma);
        shared += jacobian;
    }
    spread += shared.transpose() * shared * (common_px * common_px);
    let inverse = design
        .cholesky()
        .ok_or(FirstOrderError::Singular)?
        .inverse();
    let covariance = inverse * spread * inverse;
    Ok(PoseCovariance {
        covariance: 0.5 * (covariance + covariance.transpose()),
        translation_norm_mm: pose.translation.norm(),
    })
}

/// The first-order systematic pose error caused by a fixed image bias `b`
/// (for example the ellipse-centre displacement of spheres, see
/// [`crate::sphere_image`]) in an estimator that fits the point model:
/// `δ = (Jᵀ W J)⁻¹ Jᵀ W b`, the same Jacobian and weights as the covariance.
/// `δ = (ω, δt)` in the perturbation of [`crate::pose::perturb`]: the
/// estimate is `exp([ω]×) R`, `t + δt`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoseBias {
    /// Rotation bias about the camera axes x, y, z, radians.
    pub rotation_rad: Vector3<f64>,
    /// Translation bias along the camera axes, mm.
    pub translation_mm: Vector3<f64>,
}

impl PoseBias {
    /// Rotation bias per camera axis (x pitch, y yaw, z roll), signed degrees.
    pub fn rotation_per_axis_deg(&self) -> Vector3<f64> {
        self.rotation_rad.map(f64::to_degrees)
    }

    /// Geodesic rotation bias, degrees (to first order `|ω|`).
    pub fn rotation_deg(&self) -> f64 {
        self.rotation_rad.norm().to_degrees()
    }

    /// Translation bias, mm.
    pub fn translation_norm_mm(&self) -> f64 {
        self.translation_mm.norm()
    }
}

/// [`pose_covariance`] and the [`PoseBias`] of the image bias
/// `image_bias_px[i]` (raw pixels) in one pass over the points. With every
/// σ zero (a noise-free scenario) the bias is computed with equal weights
/// and the covariance is `None`.
pub fn pose_covariance_and_bias(
    camera: &Camera,
    pose: &Pose,
    object: &[Vector3<f64>],
    sigma_px: &[f64],
    image_bias_px: &[Vector2<f64>],
) -> Result<(Option<PoseCovariance>, PoseBias), FirstOrderError> {
    if sigma_px.len() != object.len() || image_bias_px.len() != object.len() {
        return Err(FirstOrderError::MismatchedLengths {
            points: object.len(),
            sigmas: sigma_px.len().min(image_bias_px.len()),
        });
    }
    let noise_free = sigma_px.iter().all(|&s| s == 0.0);
    let mut information = SMatrix::<f64, 6, 6>::zeros();
    let mut projected_bias = SMatrix::<f64, 6, 1>::zeros();
    for (index, ((p, &sigma), bias)) in object.iter().zip(sigma_px).zip(image_bias_px).enumerate() {
        // Divided (not multiplied by the reciprocal) so that the covariance
        // is bit-identical to `pose_covariance`'s.
        let variance = if noise_free {
            1.0
        } else if sigma > 0.0 && sigma.is_finite() {
            sigma * sigma
        } else {
            return Err(FirstOrderError::BadSigma(sigma));
        };
        if pose.transform(p).z <= 0.0 {
            return Err(FirstOrderError::BehindCamera(index));
        }
        let jacobian = pixel_jacobian(camera, pose, p);
        information += jacobian.transpose() * jacobian / variance;
        projected_bias += jacobian.transpose() * bias / variance;
    }
    let cholesky = information.cholesky().ok_or(FirstOrderError::Singular)?;
    let delta = cholesky.solve(&projected_bias);
    let bias = PoseBias {
        rotation_rad: delta.fixed_rows::<3>(0).into_owned(),
        translation_mm: delta.fixed_rows::<3>(3).into_owned(),
    };
    let covariance = (!noise_free).then(|| PoseCovariance {
        covariance: cholesky.inverse(),
        translation_norm_mm: pose.translation.norm(),
    });
    Ok((covariance, bias))
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

    /// The first-order bias is the Gauss–Newton step that the point model
    /// takes from the truth on biased pixels: checked against LM on
    /// pixels biased by a tiny fixed offset (where second-order terms are
    /// negligible), and zero without bias.
    /// A camera with fx = fy (so that ML's normalised-plane fit is the
    /// pixel fit), the paper's biprism and a tilted pose of it.
    fn square_pixel_view() -> (Camera, Pose, Vec<Vector3<f64>>) {
        let camera = Camera::new(1300.0, 1300.0, 653.0, 508.0, 1280, 720, [0.0; 5]).unwrap();
        let pose = Pose::new(
            Rotation3::from_euler_angles(0.3, -0.2, 0.1),
            Vector3::new(40.0, -20.0, 400.0),
        );
        (camera, pose, crate::synthetic::biprism_points(50.0))
    }

    #[test]
    fn bias_matches_the_refined_pose_on_slightly_biased_pixels() {
        let (camera, pose, object) = square_pixel_view();
        let bias: Vec<Vector2<f64>> = (0..object.len())
            .map(|i| Vector2::new(1e-3 * (i as f64 - 3.0), 5e-4 * (i % 3) as f64))
            .collect();
        let (covariance, predicted) =
            pose_covariance_and_bias(&camera, &pose, &object, &[0.5; 7], &bias).unwrap();
        let reference = pose_covariance(&camera, &pose, &object, &[0.5; 7]).unwrap();
        assert_relative_eq!(
            covariance.unwrap().covariance,
            reference.covariance,
            max_relative = 1e-10
        );
        let image: Vec<Vector2<f64>> = object
            .iter()
            .zip(&bias)
            .map(|(p, b)| {
                let pixel = camera.project(&pose.transform(p)).unwrap() + b;
                camera.pixel_to_normalised(&pixel).unwrap()
            })
            .collect();
        let refined = crate::pnp::ml::refine(&pose, &object, &image);
        let omega = (refined.rotation * pose.rotation.inverse()).scaled_axis();
        let dt = refined.translation - pose.translation;
        assert_relative_eq!(
            omega,
            predicted.rotation_rad,
            max_relative = 2e-3,
            epsilon = 1e-12
        );
        assert_relative_eq!(
            dt,
            predicted.translation_mm,
            max_relative = 2e-3,
            epsilon = 1e-9
        );
        let (none, zero) =
            pose_covariance_and_bias(&camera, &pose, &object, &[0.0; 7], &[Vector2::zeros(); 7])
                .unwrap();
        assert!(none.is_none());
        assert_eq!(zero.rotation_deg(), 0.0);
    }

    /// The sandwich is the spread of an unweighted fit (LM on the
    /// normalised plane, fx = fy) over pixels with unequal independent
    /// noise and a shift shared by every point: checked against 4000
    /// seeded trials, and equal to the per-point covariance without the
    /// shared term when every σ is the same.
    #[test]
    fn sandwich_is_the_spread_of_an_unweighted_fit() {
        use rand::SeedableRng;
        use rand_distr::{Distribution, StandardNormal};
        let (camera, pose, object) = square_pixel_view();
        let same = pose_covariance_sandwich(&camera, &pose, &object, &[0.3; 7], 0.0).unwrap();
        let reference = pose_covariance(&camera, &pose, &object, &[0.3; 7]).unwrap();
        assert_relative_eq!(same.covariance, reference.covariance, max_relative = 1e-9);
        let sigmas = [0.05, 0.1, 0.2, 0.05, 0.4, 0.1, 0.05];
        let common = 0.15;
        let predicted = pose_covariance_sandwich(&camera, &pose, &object, &sigmas, common)
            .unwrap()
            .covariance;
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let mut normal = || -> f64 { StandardNormal.sample(&mut rng) };
        let trials = 4000;
        let mut spread = SMatrix::<f64, 6, 6>::zeros();
        for _ in 0..trials {
            let shift = Vector2::new(normal(), normal()) * common;
            let image: Vec<Vector2<f64>> = object
                .iter()
                .zip(&sigmas)
                .map(|(p, s)| {
                    let noise = Vector2::new(normal(), normal()) * *s;
                    let pixel = camera.project(&pose.transform(p)).unwrap() + noise + shift;
                    camera.pixel_to_normalised(&pixel).unwrap()
                })
                .collect();
            let refined = crate::pnp::ml::refine(&pose, &object, &image);
            let mut e = SMatrix::<f64, 6, 1>::zeros();
            e.fixed_rows_mut::<3>(0)
                .copy_from(&(refined.rotation * pose.rotation.inverse()).scaled_axis());
            e.fixed_rows_mut::<3>(3)
                .copy_from(&(refined.translation - pose.translation));
            spread += e * e.transpose();
        }
        spread /= trials as f64;
        // Each diagonal term within 10% (its sampling σ is √(2/4000) ≈ 2.2%),
        // and the shared shift's share is far above that.
        for k in 0..6 {
            assert_relative_eq!(spread[(k, k)], predicted[(k, k)], max_relative = 0.1);
        }
        let independent = pose_covariance_sandwich(&camera, &pose, &object, &sigmas, 0.0)
            .unwrap()
            .covariance;
        assert!(predicted[(3, 3)] > 1.5 * independent[(3, 3)]);
        assert!(matches!(
            pose_covariance_sandwich(&camera, &pose, &object, &sigmas[..6], 0.0),
            Err(FirstOrderError::MismatchedLengths { .. })
        ));
        assert!(matches!(
            pose_covariance_sandwich(&camera, &pose, &object, &sigmas, f64::NAN),
            Err(FirstOrderError::BadSigma(_))
        ));
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
