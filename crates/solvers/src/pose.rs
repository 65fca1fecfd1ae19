//! Poses and pose-error metrics.
//!
//! A [`Pose`] maps object (marker) coordinates to camera coordinates,
//! `X_cam = R · X_obj + t` (paper eq. 3, OpenCV). Rotation errors are in
//! degrees at this boundary; code inside works in radians.
//!
//! ```
//! use layout_opt_solvers::pose::{nearest_rotation, rotation_error_deg, Pose};
//! use nalgebra::{Matrix3, Rotation3, Vector3};
//!
//! let truth = Pose::new(
//!     Rotation3::from_euler_angles(0.1, 0.2, 0.3),
//!     Vector3::new(0.0, 0.0, 500.0),
//! );
//! let p = Vector3::new(10.0, 0.0, 0.0);
//! assert!((truth.transform(&p) - (truth.rotation * p + truth.translation)).norm() < 1e-12);
//! // The rotation nearest to a perturbed rotation matrix is close to it.
//! let noisy = truth.rotation.matrix() + Matrix3::from_element(1e-4);
//! let projected = nearest_rotation(&noisy);
//! assert!(rotation_error_deg(&truth.rotation, &projected) < 0.02);
//! ```

use crate::linalg::orthogonalise_columns_3x3;
use nalgebra::{Matrix2x3, Matrix3, Rotation3, SMatrix, Vector2, Vector3, SVD};

/// A rigid transform from the object (marker) frame to the camera frame:
/// `X_cam = rotation · X_obj + translation`, translation in millimetres.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Pose {
    /// Rotation from object to camera axes.
    pub rotation: Rotation3<f64>,
    /// Position of the object origin in the camera frame, mm.
    pub translation: Vector3<f64>,
}

impl Pose {
    /// Builds a pose from a rotation and a translation.
    pub fn new(rotation: Rotation3<f64>, translation: Vector3<f64>) -> Self {
        Self {
            rotation,
            translation,
        }
    }

    /// Maps an object point into the camera frame.
    #[inline]
    pub fn transform(&self, object_point: &Vector3<f64>) -> Vector3<f64> {
        self.rotation * object_point + self.translation
    }

    /// The camera centre in the object frame: `−Rᵀ t`.
    #[inline]
    pub fn camera_centre(&self) -> Vector3<f64> {
        -(self.rotation.inverse() * self.translation)
    }

    /// Projects an object point onto the normalised image plane `z = 1`.
    #[inline]
    pub fn project_normalised(&self, object_point: &Vector3<f64>) -> Vector2<f64> {
        let camera_point = self.transform(object_point);
        Vector2::new(
            camera_point.x / camera_point.z,
            camera_point.y / camera_point.z,
        )
    }

    /// Whether every entry of the pose is finite.
    pub fn is_finite(&self) -> bool {
        self.rotation.matrix().iter().all(|v| v.is_finite())
            && self.translation.iter().all(|v| v.is_finite())
    }

    /// Whether every object point lies strictly in front of the camera.
    pub fn all_in_front(&self, object_points: &[Vector3<f64>]) -> bool {
        object_points.iter().all(|p| self.transform(p).z > 0.0)
    }

    /// The pose with the object frame moved by `shift`: if `self` maps
    /// points expressed relative to `shift`, the result maps the original
    /// coordinates (`X_cam = R (X − shift) + t`).
    pub fn with_object_origin_shifted(&self, shift: &Vector3<f64>) -> Self {
        Self {
            rotation: self.rotation,
            translation: self.translation - self.rotation * shift,
        }
    }
}

/// Geodesic rotation error `acos((trace(R_trueᵀ R) − 1)/2)`, in degrees.
///
/// Computed as `atan2(sin θ, cos θ)` of the relative rotation, with sin θ from
/// its skew-symmetric part: the plain `acos` form cannot resolve angles below
/// about 1e-6° in double precision (and returns NaN when rounding pushes the
/// cosine past 1).
pub fn rotation_error_deg(truth: &Rotation3<f64>, estimate: &Rotation3<f64>) -> f64 {
    let relative = truth.matrix().transpose() * estimate.matrix();
    let cosine = (relative.trace() - 1.0) / 2.0;
    let sine = 0.5
        * Vector3::new(
            relative[(2, 1)] - relative[(1, 2)],
            relative[(0, 2)] - relative[(2, 0)],
            relative[(1, 0)] - relative[(0, 1)],
        )
        .norm();
    sine.atan2(cosine).to_degrees()
}

/// The paper's E_rot (eq. 33): the largest angle between corresponding
/// columns of the true and estimated rotation matrices, in degrees.
pub fn paper_rotation_error_deg(truth: &Rotation3<f64>, estimate: &Rotation3<f64>) -> f64 {
    (0..3)
        .map(|k| {
            let a = truth.matrix().column(k);
            let b = estimate.matrix().column(k);
            // atan2 of |a×b| and a·b is exact near 0, where acos loses digits.
            let cross = a.cross(&b).norm();
            cross.atan2(a.dot(&b))
        })
        .fold(0.0, f64::max)
        .to_degrees()
}

/// Relative translation error `100·|t − t_true| / |t_true|`, in percent.
pub fn translation_error_percent(truth: &Vector3<f64>, estimate: &Vector3<f64>) -> f64 {
    100.0 * (estimate - truth).norm() / truth.norm()
}

/// Absolute translation error `|t − t_true|`, in millimetres.
pub fn translation_error_mm(truth: &Vector3<f64>, estimate: &Vector3<f64>) -> f64 {
    (estimate - truth).norm()
}

/// Root-mean-square reprojection error on the normalised image plane.
/// Multiply by a focal length for pixels when there is no distortion;
/// for the exact pixel figure use
/// [`crate::camera::Camera`] with [`reprojection_rms_px`].
pub fn reprojection_rms_normalised(
    pose: &Pose,
    object_points: &[Vector3<f64>],
    normalised_points: &[Vector2<f64>],
) -> f64 {
    let sum: f64 = object_points
        .iter()
        .zip(normalised_points)
        .map(|(p, m)| (pose.project_normalised(p) - m).norm_squared())
        .sum();
    (sum / object_points.len().max(1) as f64).sqrt()
}

/// Root-mean-square reprojection error in pixels, with the camera's
/// distortion, against raw pixel measurements.
pub fn reprojection_rms_px(
    camera: &crate::camera::Camera,
    pose: &Pose,
    object_points: &[Vector3<f64>],
    pixels: &[Vector2<f64>],
) -> f64 {
    let sum: f64 = object_points
        .iter()
        .zip(pixels)
        .map(|(p, pixel)| {
            let projected = camera.normalised_to_pixel(&pose.project_normalised(p));
            (projected - pixel).norm_squared()
        })
        .sum();
    (sum / object_points.len().max(1) as f64).sqrt()
}

/// The rotation nearest to `m` in the Frobenius norm: the `R` in SO(3)
/// maximising `tr(Rᵀ m)`, for `m = U Σ Vᵀ` the SVD projection
/// `R = U diag(1, 1, det(U Vᵀ)) Vᵀ`. This is the crate's one projection onto
/// SO(3); every solver uses it.
///
/// The fast path is Markley's FOAM ("Attitude Determination Using Vector
/// Observations: A Fast Optimal Matrix Algorithm", J. Astronaut. Sci. 41(2),
/// 1993), as Lourakis & Terzakis use it for absolute orientation and in
/// SQPnP's reference code. No SVD is needed: with singular values
/// `s₁ ≥ s₂ ≥ s₃`, the optimum `λ = s₁ + s₂ + sign(det m)·s₃` is the largest
/// root of `(λ² − ‖m‖²)² − 8 λ det m − 4 ‖adj m‖² = 0` (Markley eq. 23,
/// Frobenius norms), found by Newton from `λ₀ = √3 ‖m‖ ≥ λ`, where the
/// quartic is convex. Then, with `κ = (λ² − ‖m‖²)/2` and `ζ = κλ − det m`,
/// `R = ((κ + ‖m‖²) m + λ adj(m)ᵀ − m mᵀ m) / ζ` (eqs. 14, 18, 19).
///
/// The formula holds for either sign of `det m`. Its divisor is
/// `ζ = (s₁ + s₂)(s₁ + s₃)(s₂ + s₃)` when `det m ≥ 0` and
/// `(s₁ + s₂)(s₁ − s₃)(s₂ − s₃)` when `det m < 0`, small only where the
/// nearest rotation is itself ill-determined (`m` nearly of rank one, or
/// `s₂ ≈ s₃` with a negative determinant). There, and when the result is
/// not orthogonal to [`FOAM_ORTHOGONALITY_SQUARED_TOLERANCE`] (λ is then a
/// nearly double root, found inaccurately), the SVD decides: a one-sided
/// Jacobi sweep ([`crate::linalg::orthogonalise_columns_3x3`]), and for
/// matrices of rank below two `nalgebra::SVD`.
pub fn nearest_rotation(m: &Matrix3<f64>) -> Rotation3<f64> {
    match foam(m) {
        Some(rotation) => Rotation3::from_matrix_unchecked(rotation),
        None => nearest_rotation_jacobi(m),
    }
}

/// [`nearest_rotation`] leaves `m` to the SVD when
/// `ζ < MIN_ZETA_FRACTION (‖m‖²/3)^{3/2}` (a division by nearly zero).
/// FOAM's rounding grows like `ε / ζ`; the orthogonality test catches what
/// this lets through.
pub const MIN_ZETA_FRACTION: f64 = 1e-6;
/// A FOAM result whose `‖R Rᵀ − I‖²` exceeds this is discarded for the SVD
/// (it would mean λ, and with it the rotation, is inaccurate).
pub const FOAM_ORTHOGONALITY_SQUARED_TOLERANCE: f64 = 1e-24;
/// Upper bound on FOAM's Newton steps for λ (it converges in a handful).
pub const FOAM_MAX_NEWTON_STEPS: usize = 30;
/// FOAM's Newton stops when a step changes λ by less than this fraction of λ.
pub const FOAM_NEWTON_TOLERANCE: f64 = 1e-15;
/// Below this ratio of its second to its largest singular value a matrix
/// counts as rank one for [`nearest_rotation`]: the rotation is then not
/// unique, and the general SVD picks one.
pub const NEAREST_ROTATION_RANK_TOLERANCE: f64 = 1e-10;

/// FOAM's rotation for `m`, or `None` where it is ill-conditioned (see
/// [`nearest_rotation`]).
fn foam(m: &Matrix3<f64>) -> Option<Matrix3<f64>> {
    let det = m.determinant();
    let norm_sq = m.norm_squared();
    if !norm_sq.is_finite() || det.is_nan() || norm_sq == 0.0 {
        return None;
    }
    // adj(m)ᵀ = cofactor matrix; ‖adj m‖² is the same either way.
    let cofactor = Matrix3::from_columns(&[
        m.column(1).cross(&m.column(2)),
        m.column(2).cross(&m.column(0)),
        m.column(0).cross(&m.column(1)),
    ]);
    let adj_norm_sq = cofactor.norm_squared();
    let mut lambda = (3.0 * norm_sq).sqrt();
    for _ in 0..FOAM_MAX_NEWTON_STEPS {
        let shifted = lambda * lambda - norm_sq;
        let value = shifted * shifted - 8.0 * lambda * det - 4.0 * adj_norm_sq;
        let slope = 4.0 * lambda * shifted - 8.0 * det;
        if slope.is_nan() || slope <= 0.0 {
            break;
        }
        let step = value / slope;
        lambda -= step;
        if step.abs() <= FOAM_NEWTON_TOLERANCE * lambda.abs() {
            break;
        }
    }
    let kappa = 0.5 * (lambda * lambda - norm_sq);
    let zeta = kappa * lambda - det;
    // (‖m‖²/3)^{3/2}, without libm's pow.
    let unit = norm_sq / 3.0;
    // NaN is refused too.
    if zeta.is_nan() || zeta < MIN_ZETA_FRACTION * unit * unit.sqrt() {
        return None;
    }
    let r = ((kappa + norm_sq) * m + lambda * cofactor - m * m.transpose() * m) / zeta;
    let orthogonality = (r * r.transpose() - Matrix3::identity()).norm_squared();
    (orthogonality <= FOAM_ORTHOGONALITY_SQUARED_TOLERANCE).then_some(r)
}

/// [`nearest_rotation`] by a one-sided Jacobi SVD: allocation-free, and
/// several times faster than `nalgebra::SVD` (which forms `mᵀm` and runs the
/// general symmetric eigen-solver). Only the two largest singular pairs are
/// used: with `ũ3 = u1 × u2` and `ṽ3 = v1 × v2`,
/// `R = u1 v1ᵀ + u2 v2ᵀ + ũ3 ṽ3ᵀ`, which is the SVD projection whatever the
/// signs of `det U` and `det V` (`u1 × u2 = det(U) u3`). A matrix of rank
/// below two (or with a non-finite entry) goes to `nalgebra::SVD`.
fn nearest_rotation_jacobi(m: &Matrix3<f64>) -> Rotation3<f64> {
    // R does not depend on the scale of m; unit max-norm keeps the squared
    // norms of the Jacobi sweep away from overflow and underflow.
    let max_abs = m.amax();
    if !(max_abs > 0.0 && max_abs.is_finite()) {
        return nearest_rotation_svd(m);
    }
    let (scaled_left, right) = orthogonalise_columns_3x3(&(m / max_abs));
    let norms: [f64; 3] = std::array::from_fn(|k| scaled_left.column(k).norm());
    // The two largest singular values, by index.
    let mut order = [0usize, 1, 2];
    order.sort_by(|&a, &b| norms[b].total_cmp(&norms[a]));
    let (first, second) = (order[0], order[1]);
    // Written so that NaN counts as rank-deficient.
    let rank_two = norms[second] > NEAREST_ROTATION_RANK_TOLERANCE * norms[first];
    if !rank_two || !norms[first].is_finite() {
        return nearest_rotation_svd(m);
    }
    let u1 = scaled_left.column(first) / norms[first];
    let u2 = scaled_left.column(second) / norms[second];
    // Jacobi leaves the columns orthogonal to working accuracy; one
    // Gram–Schmidt step makes u1, u2 orthonormal to rounding.
    let u2 = (u2 - u1 * u1.dot(&u2)).normalize();
    let (v1, v2) = (right.column(first), right.column(second));
    let rotation =
        u1 * v1.transpose() + u2 * v2.transpose() + u1.cross(&u2) * v1.cross(&v2).transpose();
    Rotation3::from_matrix_unchecked(rotation)
}

/// [`nearest_rotation`] by `nalgebra::SVD`, for matrices of rank below two.
fn nearest_rotation_svd(m: &Matrix3<f64>) -> Rotation3<f64> {
    let svd = SVD::new(*m, true, true);
    let (u, v_t) = (svd.u.unwrap(), svd.v_t.unwrap());
    let mut correction = Matrix3::identity();
    if (u * v_t).determinant() < 0.0 {
        correction[(2, 2)] = -1.0;
    }
    Rotation3::from_matrix_unchecked(u * correction * v_t)
}

/// Absolute orientation (Umeyama/Kabsch, without scale): the pose that best
/// maps `object` points onto `camera` points in the least-squares sense.
/// This is the last step of EPnP and of the paper's method (it cites LHM
/// [29], whose closed form is the same SVD solution).
///
/// Needs at least three non-collinear points; callers validate that.
pub fn absolute_orientation(
    object: impl Iterator<Item = Vector3<f64>> + Clone,
    camera: impl Iterator<Item = Vector3<f64>> + Clone,
) -> Pose {
    let mut count = 0.0;
    let mut object_mean = Vector3::zeros();
    let mut camera_mean = Vector3::zeros();
    for (o, c) in object.clone().zip(camera.clone()) {
        object_mean += o;
        camera_mean += c;
        count += 1.0;
    }
    object_mean /= count;
    camera_mean /= count;
    let mut cross_covariance = Matrix3::zeros();
    for (o, c) in object.zip(camera) {
        cross_covariance += (c - camera_mean) * (o - object_mean).transpose();
    }
    let rotation = nearest_rotation(&cross_covariance);
    let translation = camera_mean - rotation * object_mean;
    Pose::new(rotation, translation)
}

/// Jacobian of the normalised projection `π(X) = (X_x/X_z, X_y/X_z)` of the
/// camera-frame point `X = R P + t` with respect to the pose perturbation
/// `(ω, δt)`, where the perturbed pose is `R ← exp([ω]×) R`, `t ← t + δt`
/// (ω in radians, about the camera axes; see [`perturb`]):
/// `∂X/∂ω = −[R P]×` and `∂X/∂t = I`.
#[inline]
pub fn normalised_projection_jacobian(
    pose: &Pose,
    object_point: &Vector3<f64>,
) -> SMatrix<f64, 2, 6> {
    let rotated = pose.rotation * object_point;
    let camera_point = rotated + pose.translation;
    let (x, y, z) = (camera_point.x, camera_point.y, camera_point.z);
    let inverse_z = 1.0 / z;
    let projection = Matrix2x3::new(
        inverse_z,
        0.0,
        -x * inverse_z * inverse_z,
        0.0,
        inverse_z,
        -y * inverse_z * inverse_z,
    );
    let mut jacobian = SMatrix::<f64, 2, 6>::zeros();
    jacobian
        .fixed_view_mut::<2, 3>(0, 0)
        .copy_from(&(projection * -rotated.cross_matrix()));
    jacobian.fixed_view_mut::<2, 3>(0, 3).copy_from(&projection);
    jacobian
}

/// Applies the perturbation `(ω, δt)` of [`normalised_projection_jacobian`].
pub fn perturb(pose: &Pose, delta: &SMatrix<f64, 6, 1>) -> Pose {
    let omega = Vector3::new(delta[0], delta[1], delta[2]);
    Pose::new(
        Rotation3::new(omega) * pose.rotation,
        pose.translation + Vector3::new(delta[3], delta[4], delta[5]),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn rotation_error_is_the_relative_angle() {
        let a = Rotation3::from_euler_angles(0.1, -0.4, 2.0);
        let delta = Rotation3::from_axis_angle(&Vector3::y_axis(), 3f64.to_radians());
        assert_relative_eq!(rotation_error_deg(&a, &(a * delta)), 3.0, epsilon = 1e-12);
        assert_relative_eq!(rotation_error_deg(&a, &a), 0.0, epsilon = 1e-12);
        // Tiny and near-π angles are resolved (acos would return 0 or NaN).
        let tiny = Rotation3::from_axis_angle(&Vector3::x_axis(), 1e-10);
        assert_relative_eq!(
            rotation_error_deg(&a, &(a * tiny)),
            1e-10f64.to_degrees(),
            max_relative = 1e-4
        );
        let half_turn = Rotation3::from_axis_angle(&Vector3::z_axis(), std::f64::consts::PI - 1e-9);
        assert_relative_eq!(
            rotation_error_deg(&a, &(a * half_turn)),
            180.0,
            epsilon = 1e-6
        );
        // E_rot (eq. 33) for a rotation about one axis: two columns move by the angle.
        assert_relative_eq!(
            paper_rotation_error_deg(&Rotation3::identity(), &delta),
            3.0,
            epsilon = 1e-12
        );
    }

    #[test]
    fn translation_errors() {
        let t = Vector3::new(0.0, 0.0, 500.0);
        let e = Vector3::new(3.0, 4.0, 500.0);
        assert_relative_eq!(translation_error_mm(&t, &e), 5.0);
        assert_relative_eq!(translation_error_percent(&t, &e), 1.0);
    }

    #[test]
    fn absolute_orientation_recovers_a_rigid_motion() {
        let pose = Pose::new(
            Rotation3::from_euler_angles(0.3, -1.1, 2.5),
            Vector3::new(10.0, -20.0, 700.0),
        );
        let object: Vec<Vector3<f64>> = vec![
            Vector3::new(0.0, 0.0, 0.0),
            Vector3::new(50.0, 0.0, 0.0),
            Vector3::new(0.0, 50.0, 0.0),
            Vector3::new(0.0, 0.0, 50.0),
            Vector3::new(-50.0, 10.0, 3.0),
        ];
        let camera: Vec<Vector3<f64>> = object.iter().map(|p| pose.transform(p)).collect();
        let estimate = absolute_orientation(object.iter().copied(), camera.iter().copied());
        assert!(rotation_error_deg(&pose.rotation, &estimate.rotation) < 1e-10);
        assert_relative_eq!(estimate.translation, pose.translation, epsilon = 1e-9);
    }

    /// The Jacobi path agrees with the `nalgebra::SVD` projection on random
    /// matrices of any conditioning, scale and sign of determinant, and on
    /// rank-two matrices; rank one goes to the SVD itself.
    #[test]
    fn nearest_rotation_matches_the_svd_projection() {
        use crate::synthetic::{standard_normal, stream_rng};
        for case in 0..3000u64 {
            let mut rng = stream_rng(31, 1, case);
            let scale = [1.0, 1e-120, 1e-6, 1e6, 1e120][case as usize % 5];
            let mut m = Matrix3::from_fn(|_, _| standard_normal(&mut rng)) * scale;
            if case % 3 == 1 {
                // Rank two.
                let svd = m.svd(true, true);
                let mut singular = svd.singular_values;
                singular[2] = 0.0;
                m = svd.u.unwrap() * Matrix3::from_diagonal(&singular) * svd.v_t.unwrap();
            }
            let fast = nearest_rotation_jacobi(&m);
            let reference = nearest_rotation_svd(&m);
            let r = fast.matrix();
            assert!((r - reference.matrix()).norm() < 1e-9, "case {case}: {m}");
            assert!((r.transpose() * r - Matrix3::identity()).amax() < 1e-14);
            assert_relative_eq!(r.determinant(), 1.0, epsilon = 1e-14);
        }
        // A zero row (LHM's weak-perspective start with centred points).
        let mut zero_row = Matrix3::new(3.0, -1.0, 0.5, 0.2, 2.0, -0.7, 0.0, 0.0, 0.0);
        zero_row[(2, 2)] = 0.0;
        assert!(
            (nearest_rotation(&zero_row).matrix() - nearest_rotation_svd(&zero_row).matrix())
                .norm()
                < 1e-12
        );
        let rank_one = Vector3::new(1.0, 2.0, 3.0) * Vector3::new(-1.0, 0.5, 2.0).transpose();
        let r = nearest_rotation(&rank_one);
        assert_relative_eq!(r.matrix().determinant(), 1.0, epsilon = 1e-12);
        // Exactly a rotation times a positive diagonal: the polar factor.
        let truth = Rotation3::from_euler_angles(0.3, -1.1, 2.5);
        let m = truth.matrix() * Matrix3::from_diagonal(&Vector3::new(3.0, 2.0, 1e-3));
        assert!((nearest_rotation(&m).matrix() - truth.matrix()).norm() < 1e-14);
    }

    /// FOAM and the Jacobi fallback each agree with `nalgebra::SVD` on
    /// random matrices of any scale and sign of determinant, including
    /// nearly singular ones (s₃ shrunk by up to 1e-12), and FOAM takes the
    /// well-conditioned ones.
    #[test]
    fn both_paths_agree_with_the_svd_projection() {
        use crate::synthetic::stream_rng;
        use rand::Rng;
        let mut foam_taken = 0;
        for case in 0..4000u64 {
            let mut rng = stream_rng(11, 81, case);
            let scale = 10f64.powf(rng.random_range(-3.0..3.0));
            let mut m = Matrix3::from_fn(|_, _| rng.random_range(-1.0..1.0)) * scale;
            if case % 2 == 1 {
                let svd = m.svd(true, true);
                let mut s = svd.singular_values;
                s[2] *= 10f64.powf(rng.random_range(-12.0..0.0));
                m = svd.u.unwrap() * Matrix3::from_diagonal(&s) * svd.v_t.unwrap();
            }
            let reference = nearest_rotation_svd(&m);
            let foam_result = foam(&m);
            foam_taken += usize::from(foam_result.is_some());
            for r in [
                foam_result.unwrap_or_else(|| *reference.matrix()),
                *nearest_rotation_jacobi(&m).matrix(),
                *nearest_rotation(&m).matrix(),
            ] {
                let difference = (r - reference.matrix()).norm();
                let ortho = (r.transpose() * r - Matrix3::identity()).norm();
                assert!(
                    difference < 1e-9 && ortho < 1e-12,
                    "case {case}: {difference:e}, {ortho:e}\n{m}"
                );
                assert!((r.determinant() - 1.0).abs() < 1e-12);
            }
        }
        assert!(foam_taken > 3000, "FOAM took only {foam_taken} of 4000");
    }

    #[test]
    fn nearest_rotation_has_positive_determinant() {
        let reflection = Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, -1.0));
        let r = nearest_rotation(&reflection);
        assert_relative_eq!(r.matrix().determinant(), 1.0, epsilon = 1e-12);
    }

    #[test]
    fn projection_jacobian_matches_central_differences() {
        let pose = Pose::new(
            Rotation3::from_euler_angles(0.3, -0.7, 1.1),
            Vector3::new(30.0, -20.0, 400.0),
        );
        let point = Vector3::new(40.0, -25.0, 10.0);
        let analytic = normalised_projection_jacobian(&pose, &point);
        let h = 1e-6;
        for column in 0..6 {
            let mut delta = SMatrix::<f64, 6, 1>::zeros();
            delta[column] = h;
            let plus = perturb(&pose, &delta).project_normalised(&point);
            let minus = perturb(&pose, &(-delta)).project_normalised(&point);
            let numeric = (plus - minus) / (2.0 * h);
            assert_relative_eq!(
                analytic.column(column).into_owned(),
                numeric,
                epsilon = 1e-8,
                max_relative = 1e-6
            );
        }
    }

    #[test]
    fn shifting_the_object_origin_keeps_camera_points() {
        let pose = Pose::new(
            Rotation3::from_euler_angles(0.3, -0.1, 0.5),
            Vector3::new(1.0, 2.0, 300.0),
        );
        let shift = Vector3::new(5.0, -7.0, 11.0);
        let shifted = pose.with_object_origin_shifted(&shift);
        let p = Vector3::new(20.0, 30.0, -40.0);
        assert_relative_eq!(
            shifted.transform(&p),
            pose.transform(&(p - shift)),
            epsilon = 1e-10
        );
    }
}
