//! Orthogonal iteration (LHM): Lu, Hager & Mjolsness, "Fast and Globally
//! Convergent Pose Estimation from Video Images", IEEE TPAMI 22(6), 2000.
//!
//! **Object-space error.** The line of sight of image point
//! `v_i = (x_i, y_i, 1)` projects onto itself with `V_i = v_i v_iᵀ / (v_iᵀ v_i)`;
//! a pose is exact when every camera point lies on its line of sight, so the
//! method minimises
//! `E(R, t) = Σ_i ‖(I − V_i)(R p_i + t)‖²`.
//!
//! **Optimal translation.** For fixed R the minimiser is
//! `t(R) = (1/n) (I − (1/n) Σ_j V_j)⁻¹ Σ_j (V_j − I) R p_j`; with the object
//! points centred (`Σ p_j = 0`) this is `G Σ_j V_j R p_j`, where the
//! translation factor `G = (I − (1/n) Σ V_j)⁻¹ / n` is computed once per solve.
//!
//! **Iteration.** Given `R_k`, project the camera points onto the lines of
//! sight, `q_i = V_i (R_k p_i + t(R_k))`, and solve the absolute-orientation
//! problem `p_i → q_i` in closed form for `R_{k+1}`: the rotation nearest to
//! `Σ_i (q_i − q̄)(p_i − p̄)ᵀ` (the paper uses its SVD; we use FOAM,
//! [`crate::pose::nearest_rotation`], which gives the same rotation faster). The error never
//! increases, and the iteration converges to a critical point from any
//! start (the paper's global-convergence result).
//!
//! **Start** (as the authors' `objpose.m` does without an initial
//! guess): the weak-perspective pose, i.e. the same absolute-orientation step
//! with every point placed at depth 1 on its line of sight, `q_i = v_i`.
//!
//! **Stopping.** The loop ends when the object-space error falls below
//! [`ERROR_FLOOR`] times the object scatter `Σ ‖p_i‖²` (an exact fit), when
//! an iteration lowers it by less than [`RELATIVE_DECREASE_TOLERANCE`] of its
//! value (converged on noisy data), or after [`MAX_ITERATIONS`]. The copy
//! of the authors' `objpose.m` we read stops at a relative decrease of 1e-5
//! or an absolute error of 1e-8 (units of the data), after at most 20
//! iterations; that stops short of the exact pose, which is why ours are
//! tighter and scale-free.
//!
//! `V_i` is held as the unit direction `u_i = v_i / ‖v_i‖` (`V_i = u_i u_iᵀ`,
//! `V_i x = u_i (u_i · x)`), the centred points and directions sit in
//! inline storage for up to [`INLINE_POINTS`] points (one allocation per
//! solve beyond), and the iteration itself allocates nothing. `t(R)` is
//! linear in R, so `G Σ V_i ⊗ p_iᵀ` is also precomputed as a 3×9 map.
//!
//! One candidate is returned. Equation numbers are not cited: this follows
//! the authors' reference code (`objpose.m`), read for understanding, and
//! the paper's description of the method.

use super::{Candidates, Method, PnpError};
use crate::pose::nearest_rotation;
use crate::pose::Pose;
use nalgebra::{Matrix3, Rotation3, SMatrix, Vector2, Vector3};
use smallvec::{smallvec, SmallVec};

/// The method's name in messages.
const NAME: &str = "LHM";
/// Points held inline (on the stack); more cost one allocation per solve.
pub const INLINE_POINTS: usize = 32;
/// Upper bound on orthogonal iterations.
pub const MAX_ITERATIONS: usize = 1000;
/// Stop when the object-space error is below this fraction of the object
/// scatter `Σ ‖p_i − p̄‖²`: the pose then fits to rounding level.
pub const ERROR_FLOOR: f64 = 1e-26;
/// Stop when an iteration lowers the object-space error by less than this
/// fraction of its value.
pub const RELATIVE_DECREASE_TOLERANCE: f64 = 1e-10;

/// `det(I − (1/n) Σ V_j)` below this means the lines of sight (nearly)
/// coincide: the determinant is about the squared angular spread of the
/// image points, ~1e-5 even at 200 object sizes away.
pub const LINES_OF_SIGHT_TOLERANCE: f64 = 1e-14;

/// Per-solve data: centred object points, lines of sight, and the linear map
/// `vec(R) ↦ t(R)` (row-major `vec`).
struct OrthogonalIteration {
    centred: SmallVec<[Vector3<f64>; INLINE_POINTS]>,
    sight: SmallVec<[Vector3<f64>; INLINE_POINTS]>,
    translation_map: SMatrix<f64, 3, 9>,
}

impl OrthogonalIteration {
    fn new(
        centred: SmallVec<[Vector3<f64>; INLINE_POINTS]>,
        image: &[Vector2<f64>],
    ) -> Result<Self, PnpError> {
        let count = centred.len() as f64;
        let sight: SmallVec<[Vector3<f64>; INLINE_POINTS]> = image
            .iter()
            .map(|m| Vector3::new(m.x, m.y, 1.0).normalize())
            .collect();
        // Eq. 20: G = (I − (1/n) Σ V_j)⁻¹ / n.
        let mut mean_projection = Matrix3::zeros();
        for u in &sight {
            mean_projection += u * u.transpose();
        }
        mean_projection /= count;
        let spread = Matrix3::identity() - mean_projection;
        let coincident = PnpError::Degenerate {
            solver: NAME,
            reason: "all lines of sight coincide, so the translation is undetermined",
        };
        let determinant = spread.determinant();
        if determinant.is_nan() || determinant <= LINES_OF_SIGHT_TOLERANCE {
            return Err(coincident);
        }
        let factor = spread.try_inverse().ok_or(coincident)? / count;
        // Σ_j V_j R p_j = Σ_j u_j (u_jᵀ R p_j) = [Σ_j u_j (u_j ⊗ p_j)ᵀ] vec(R).
        let mut sum = SMatrix::<f64, 3, 9>::zeros();
        for (u, p) in sight.iter().zip(&centred) {
            for row in 0..3 {
                for col in 0..3 {
                    let weight = u[row] * p[col];
                    for k in 0..3 {
                        sum[(k, 3 * row + col)] += u[k] * weight;
                    }
                }
            }
        }
        Ok(Self {
            centred,
            sight,
            translation_map: factor * sum,
        })
    }

    /// The optimal translation for `rotation`.
    #[inline]
    fn translation(&self, rotation: &Matrix3<f64>) -> Vector3<f64> {
        let row_major = SMatrix::<f64, 9, 1>::from_fn(|k, _| rotation[(k / 3, k % 3)]);
        self.translation_map * row_major
    }

    /// One pass over the points for pose `(rotation, translation)`: the
    /// object-space error and the cross-covariance
    /// `Σ q_i p_iᵀ` of the projected camera points.
    #[inline]
    fn error_and_covariance(
        &self,
        rotation: &Matrix3<f64>,
        translation: &Vector3<f64>,
    ) -> (f64, Matrix3<f64>) {
        let mut error = 0.0;
        let mut covariance = Matrix3::zeros();
        for (p, u) in self.centred.iter().zip(&self.sight) {
            let camera = rotation * p + translation;
            let on_line = u * u.dot(&camera);
            error += (camera - on_line).norm_squared();
            covariance += on_line * p.transpose();
        }
        (error, covariance)
    }
}

/// `lhm`: orthogonal iteration on the object-space error (Lu, Hager & Mjolsness 2000), from a weak-perspective start.
pub const LHM: Method = Method {
    name: "lhm",
    display_name: "LHM",
    description: "orthogonal iteration on the object-space error from a weak-perspective start (Lu, Hager & Mjolsness 2000)",
    min_points: 4,
    accepts_coplanar: false,
    exact: true,
    start: None,
    solve,
};

/// LHM: orthogonal iteration from the weak-perspective start. One candidate.
pub fn solve(object: &[Vector3<f64>], image: &[Vector2<f64>]) -> Result<Candidates, PnpError> {
    if object.len() < 4 {
        return Err(PnpError::TooFewPoints {
            solver: NAME,
            needed: 4,
            got: object.len(),
        });
    }
    let centroid = object.iter().sum::<Vector3<f64>>() / object.len() as f64;
    let centred: SmallVec<[Vector3<f64>; INLINE_POINTS]> =
        object.iter().map(|p| p - centroid).collect();
    let scatter: f64 = centred.iter().map(|p| p.norm_squared()).sum();
    let iteration = OrthogonalIteration::new(centred, image)?;

    // Weak-perspective start: absolute orientation onto the image points
    // at depth 1, q_i = v_i (the centred p makes q̄ drop out).
    let mut start = Matrix3::zeros();
    for (p, m) in iteration.centred.iter().zip(image) {
        start += Vector3::new(m.x, m.y, 1.0) * p.transpose();
    }
    let mut rotation: Matrix3<f64> = nearest_rotation(&start).into_inner();
    let mut translation = iteration.translation(&rotation);
    let (mut error, mut covariance) = iteration.error_and_covariance(&rotation, &translation);

    for _ in 0..MAX_ITERATIONS {
        if error.is_nan() || error <= ERROR_FLOOR * scatter {
            break;
        }
        // Absolute orientation p_i → q_i, then t(R).
        let next_rotation = nearest_rotation(&covariance).into_inner();
        let next_translation = iteration.translation(&next_rotation);
        let (next_error, next_covariance) =
            iteration.error_and_covariance(&next_rotation, &next_translation);
        if next_error.is_nan() || next_error >= error {
            break; // rounding: the error no longer decreases
        }
        let decrease = error - next_error;
        (rotation, translation, error, covariance) =
            (next_rotation, next_translation, next_error, next_covariance);
        if decrease <= RELATIVE_DECREASE_TOLERANCE * (error + decrease) {
            break;
        }
    }

    let pose = Pose::new(Rotation3::from_matrix_unchecked(rotation), translation)
        .with_object_origin_shifted(&centroid);
    if !pose.is_finite() {
        return Err(PnpError::Degenerate {
            solver: NAME,
            reason: "the iteration produced a non-finite pose",
        });
    }
    Ok(smallvec![pose])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pose::rotation_error_deg;
    use crate::synthetic::{biprism_points, random_pose, stream_rng};

    #[test]
    fn translation_map_is_the_optimal_translation() {
        // For fixed R, t(R) zeroes the gradient of E: Σ (I − V_i)(R p_i + t) = 0.
        let mut rng = stream_rng(3, 70, 0);
        let object = biprism_points(50.0);
        let truth = random_pose(&mut rng, 300.0, 0.3);
        let image: Vec<_> = object.iter().map(|p| truth.project_normalised(p)).collect();
        let centroid = object.iter().sum::<Vector3<f64>>() / 7.0;
        let centred = object.iter().map(|p| p - centroid).collect();
        let iteration = OrthogonalIteration::new(centred, &image).unwrap();
        let rotation = Rotation3::from_euler_angles(0.3, 0.2, -0.5).into_inner();
        let t = iteration.translation(&rotation);
        let mut gradient = Vector3::zeros();
        for (p, u) in iteration.centred.iter().zip(&iteration.sight) {
            let camera = rotation * p + t;
            gradient += camera - u * u.dot(&camera);
        }
        assert!(gradient.norm() < 1e-9 * t.norm(), "{gradient}");
    }

    #[test]
    fn converges_to_the_exact_pose() {
        let object = biprism_points(50.0);
        for case in 0..20 {
            let mut rng = stream_rng(3, 71, case);
            let truth = random_pose(&mut rng, 250.0 + 100.0 * case as f64, 0.3);
            let image: Vec<_> = object.iter().map(|p| truth.project_normalised(p)).collect();
            let pose = solve(&object, &image).unwrap()[0];
            let error = rotation_error_deg(&truth.rotation, &pose.rotation);
            assert!(error < 1e-7, "case {case}: {error}°");
        }
    }

    #[test]
    fn rejects_too_few_points_and_coincident_lines_of_sight() {
        let object = [Vector3::zeros(), Vector3::x(), Vector3::y()];
        let err = solve(&object, &[Vector2::zeros(); 3]).unwrap_err();
        assert_eq!(err.to_string(), "LHM needs at least 4 points, got 3");
        let object = [Vector3::zeros(), Vector3::x(), Vector3::y(), Vector3::z()];
        let err = solve(&object, &[Vector2::new(0.1, 0.2); 4]).unwrap_err();
        assert_eq!(
            err.to_string(),
            "LHM failed: all lines of sight coincide, so the translation is undetermined"
        );
    }
}
