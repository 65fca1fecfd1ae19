//! Maximum-likelihood pose: Levenberg–Marquardt on the reprojection error
//! (Levenberg 1944, Marquardt 1963), started from the best closed-form pose.
//!
//! Cost: `Σ_i ‖π(R P_i + t) − m_i‖²` on the normalised image plane; under
//! isotropic Gaussian noise on that plane (pixels with fx = fy and no
//! distortion) this is the maximum-likelihood estimate, and at small noise
//! its error reaches the first-order (Cramér–Rao) limit.
//!
//! Start: the best SQPnP candidate ([`sqpnp::solve`], the lowest
//! reprojection error among its local minima), always: [`START`] names it,
//! and reports and `solve`'s output carry the name. SQPnP reaches the
//! global minimum of its object-space cost over the whole problem space
//! (near and far field, depth/size down to 0.5, planar and quasi-planar
//! sets), so LM starts in the basin of the maximum-likelihood pose. The
//! paper's parallel-weighted pose, the earlier start, is faster by a few
//! tenths of a microsecond but lands in another basin on 1–5% of
//! strong-perspective problems (depth/size ≈ 1) and on quasi-planar sets.
//! As SQPnP does, ML accepts coplanar points.
//! Parameterisation: `R ← exp([ω]×) R`, `t ← t + δt` (see
//! [`crate::pose::normalised_projection_jacobian`]). Damping is Marquardt's
//! diagonal scaling. The 6×6 normal equations are accumulated per point in
//! fixed-size types; nothing is allocated.

use super::{best_candidate, sqpnp, Candidates, Method, PnpError, Solver};
use crate::pose::{perturb, Pose};
use nalgebra::{Matrix2x3, SMatrix, Vector2, Vector3};
use smallvec::smallvec;

/// Upper bound on LM iterations.
pub const MAX_ITERATIONS: usize = 100;
/// Initial damping factor λ.
pub const INITIAL_DAMPING: f64 = 1e-3;
/// Stop when an accepted step lowers the cost by less than this fraction.
/// Near the minimum a step lowers the cost by about the squared Mahalanobis
/// distance still to go, times the noise variance; 1e-10 of a cost of n
/// noise variances leaves ~1e-5 standard deviations, far below anything the
/// statistics can see (and the noise-free case, where the cost falls by
/// orders of magnitude per step, ends on [`STEP_TOLERANCE`] instead).
pub const COST_TOLERANCE: f64 = 1e-10;
/// Stop when a step rotates by less than this (radians) and moves the
/// translation by less than this fraction of its length: without noise LM
/// converges quadratically, so the error left is of the order of its square.
pub const STEP_TOLERANCE: f64 = 1e-12;
/// Damping increases tried per iteration before giving up.
const MAX_DAMPING_TRIES: usize = 12;
/// Smallest diagonal entry Marquardt's scaling multiplies.
const DIAGONAL_FLOOR: f64 = 1e-30;
/// Smallest damping factor.
const MIN_DAMPING: f64 = 1e-12;

fn cost(pose: &Pose, object: &[Vector3<f64>], image: &[Vector2<f64>]) -> f64 {
    let mut sum = 0.0;
    for (p, m) in object.iter().zip(image) {
        let c = pose.transform(p);
        if c.z <= 0.0 {
            return f64::INFINITY;
        }
        let inverse_z = 1.0 / c.z;
        sum += (Vector2::new(c.x * inverse_z, c.y * inverse_z) - m).norm_squared();
    }
    sum
}

/// `JᵀJ` (lower triangle) and `Jᵀr` of the reprojection residuals at
/// `pose`, point by point; the Jacobian is
/// [`crate::pose::normalised_projection_jacobian`], written out so that the
/// camera point is computed once.
fn normal_equations(
    pose: &Pose,
    object: &[Vector3<f64>],
    image: &[Vector2<f64>],
) -> (SMatrix<f64, 6, 6>, SMatrix<f64, 6, 1>) {
    let mut normal = SMatrix::<f64, 6, 6>::zeros();
    let mut gradient = SMatrix::<f64, 6, 1>::zeros();
    for (p, m) in object.iter().zip(image) {
        let rotated = pose.rotation * p;
        let c = rotated + pose.translation;
        let inverse_z = 1.0 / c.z;
        let (u, v) = (c.x * inverse_z, c.y * inverse_z);
        let residual = Vector2::new(u - m.x, v - m.y);
        // ∂π/∂X, then ∂X/∂ω = −[R P]× and ∂X/∂t = I.
        let projection = Matrix2x3::new(
            inverse_z,
            0.0,
            -u * inverse_z,
            0.0,
            inverse_z,
            -v * inverse_z,
        );
        let rotation_part = projection * -rotated.cross_matrix();
        let rows: [SMatrix<f64, 6, 1>; 2] = std::array::from_fn(|r| {
            SMatrix::<f64, 6, 1>::new(
                rotation_part[(r, 0)],
                rotation_part[(r, 1)],
                rotation_part[(r, 2)],
                projection[(r, 0)],
                projection[(r, 1)],
                projection[(r, 2)],
            )
        });
        for (row, r) in rows.iter().zip(residual.iter()) {
            normal.syger(1.0, row, row, 1.0);
            gradient += row * *r;
        }
    }
    (normal, gradient)
}

/// Levenberg–Marquardt refinement of `start` on the reprojection error.
/// Never returns a pose with a higher cost than `start`.
pub fn refine(start: &Pose, object: &[Vector3<f64>], image: &[Vector2<f64>]) -> Pose {
    levenberg_marquardt(
        start,
        |pose| normal_equations(pose, object, image),
        |pose| cost(pose, object, image),
    )
}

/// The Levenberg–Marquardt loop shared by [`refine`] and the sphere-model
/// fit ([`super::ml_sphere`]): Gauss–Newton normal equations `(JᵀJ, Jᵀr)`
/// over the pose's six local parameters ([`perturb`]), damped on the
/// diagonal (Marquardt's scaling) until a step lowers `cost`. Never returns
/// a pose with a higher cost than `start`.
pub(crate) fn levenberg_marquardt(
    start: &Pose,
    normal_equations: impl Fn(&Pose) -> (SMatrix<f64, 6, 6>, SMatrix<f64, 6, 1>),
    cost: impl Fn(&Pose) -> f64,
) -> Pose {
    let mut pose = *start;
    let mut current = cost(&pose);
    if !current.is_finite() {
        return pose;
    }
    let mut damping = INITIAL_DAMPING;
    for _ in 0..MAX_ITERATIONS {
        let (normal, gradient) = normal_equations(&pose);
        let mut improved = false;
        // Raise the damping until a step lowers the cost (or give up).
        for _ in 0..MAX_DAMPING_TRIES {
            let mut damped = normal;
            for d in 0..6 {
                damped[(d, d)] += damping * normal[(d, d)].max(DIAGONAL_FLOOR);
            }
            // Cholesky reads the lower triangle only.
            let Some(step) = damped.cholesky().map(|c| -c.solve(&gradient)) else {
                damping *= 10.0;
                continue;
            };
            let candidate = perturb(&pose, &step);
            let candidate_cost = cost(&candidate);
            if candidate_cost <= current {
                let decrease = current - candidate_cost;
                pose = candidate;
                let previous = current;
                current = candidate_cost;
                damping = (damping / 10.0).max(MIN_DAMPING);
                improved = true;
                let rotation_step = step.fixed_rows::<3>(0).norm();
                let translation_step = step.fixed_rows::<3>(3).norm();
                if decrease <= COST_TOLERANCE * previous
                    || (rotation_step <= STEP_TOLERANCE
                        && translation_step <= STEP_TOLERANCE * pose.translation.norm())
                {
                    return pose;
                }
                break;
            }
            damping *= 10.0;
        }
        if !improved {
            break;
        }
    }
    pose
}

/// The solver whose best candidate starts LM.
pub const START: Solver = Solver::Sqpnp;

/// `ml`: levenberg–Marquardt on reprojection error from the best SQPnP candidate: the maximum-likelihood estimate under isotropic Gaussian noise.
pub const ML: Method = Method {
    name: "ml",
    display_name: "ML (Levenberg-Marquardt)",
    description: "Levenberg-Marquardt on reprojection error from the best SQPnP candidate (maximum likelihood); coplanar points allowed",
    min_points: 4,
    accepts_coplanar: true,
    exact: true,
    start: Some(START),
    solve,
};

/// ML: the best SQPnP candidate, refined by LM. One candidate.
pub fn solve(object: &[Vector3<f64>], image: &[Vector2<f64>]) -> Result<Candidates, PnpError> {
    let starts = sqpnp::solve(object, image)?;
    let start = best_candidate("ML", &starts, object, image)?;
    Ok(smallvec![refine(&start, object, image)])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pose::normalised_projection_jacobian;
    use nalgebra::Rotation3;

    /// The fused normal equations equal `Σ JᵀJ` and `Σ Jᵀr` built from
    /// [`normalised_projection_jacobian`] (itself checked against central
    /// differences in `pose`).
    #[test]
    fn normal_equations_match_the_projection_jacobian() {
        let pose = Pose::new(
            Rotation3::from_euler_angles(0.3, -0.7, 1.1),
            Vector3::new(30.0, -20.0, 400.0),
        );
        let object = [
            Vector3::new(40.0, -25.0, 10.0),
            Vector3::new(-30.0, 5.0, 20.0),
            Vector3::new(0.0, 35.0, -15.0),
            Vector3::new(10.0, 10.0, 40.0),
        ];
        let image: Vec<Vector2<f64>> = object
            .iter()
            .enumerate()
            .map(|(i, p)| pose.project_normalised(p) + Vector2::new(1e-3 * i as f64, -2e-3))
            .collect();
        let (mut normal, gradient) = normal_equations(&pose, &object, &image);
        normal.fill_upper_triangle_with_lower_triangle();
        let mut expected_normal = SMatrix::<f64, 6, 6>::zeros();
        let mut expected_gradient = SMatrix::<f64, 6, 1>::zeros();
        for (p, m) in object.iter().zip(&image) {
            let jacobian = normalised_projection_jacobian(&pose, p);
            let residual = pose.project_normalised(p) - m;
            expected_normal += jacobian.transpose() * jacobian;
            expected_gradient += jacobian.transpose() * residual;
        }
        assert!((normal - expected_normal).norm() <= 1e-14 * expected_normal.norm());
        assert!((gradient - expected_gradient).norm() <= 1e-14 * expected_gradient.norm());
    }
}
