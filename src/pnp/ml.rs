//! Maximum-likelihood pose: Levenberg–Marquardt on the reprojection error
//! (Levenberg 1944, Marquardt 1963), started from the best closed-form pose.
//!
//! Cost: `Σ_i ‖π(R P_i + t) − m_i‖²` on the normalised image plane; under
//! isotropic Gaussian noise on that plane (pixels with fx = fy and no
//! distortion) this is the maximum-likelihood estimate, and at small noise
//! its error reaches the first-order (Cramér–Rao) limit.
//!
//! Start: the candidate with the lowest reprojection error among EPnP+GN's
//! four candidates and the paper's parallel-weighted pose. Parameterisation:
//! `R ← exp([ω]×) R`, `t ← t + δt` (see
//! [`crate::pose::normalised_projection_jacobian`]). Damping is Marquardt's
//! diagonal scaling.

use super::{best_candidate, epnp, parallel, Candidates, PnpError};
use crate::pose::{normalised_projection_jacobian, perturb, Pose};
use nalgebra::{SMatrix, Vector2, Vector3};
use smallvec::smallvec;

/// Upper bound on LM iterations.
pub const MAX_ITERATIONS: usize = 100;
/// Initial damping factor λ.
pub const INITIAL_DAMPING: f64 = 1e-3;
/// Stop when the relative cost decrease of an accepted step falls below this.
pub const COST_TOLERANCE: f64 = 1e-14;
/// Stop when a step is shorter than this (radians and mm, combined).
pub const STEP_TOLERANCE: f64 = 1e-13;

fn cost(pose: &Pose, object: &[Vector3<f64>], image: &[Vector2<f64>]) -> f64 {
    object
        .iter()
        .zip(image)
        .map(|(p, m)| {
            let c = pose.transform(p);
            if c.z <= 0.0 {
                return f64::INFINITY;
            }
            (Vector2::new(c.x / c.z, c.y / c.z) - m).norm_squared()
        })
        .sum()
}

/// Levenberg–Marquardt refinement of `start` on the reprojection error.
/// Never returns a pose with a higher cost than `start`.
pub fn refine(start: &Pose, object: &[Vector3<f64>], image: &[Vector2<f64>]) -> Pose {
    let mut pose = *start;
    let mut current = cost(&pose, object, image);
    if !current.is_finite() {
        return pose;
    }
    let mut damping = INITIAL_DAMPING;
    for _ in 0..MAX_ITERATIONS {
        let mut normal = SMatrix::<f64, 6, 6>::zeros();
        let mut gradient = SMatrix::<f64, 6, 1>::zeros();
        for (p, m) in object.iter().zip(image) {
            let c = pose.transform(p);
            let residual = Vector2::new(c.x / c.z, c.y / c.z) - m;
            let jacobian = normalised_projection_jacobian(&pose, p);
            normal += jacobian.transpose() * jacobian;
            gradient += jacobian.transpose() * residual;
        }
        let mut improved = false;
        // Raise the damping until a step lowers the cost (or give up).
        for _ in 0..12 {
            let mut damped = normal;
            for d in 0..6 {
                damped[(d, d)] += damping * normal[(d, d)].max(1e-30);
            }
            let Some(step) = damped.cholesky().map(|c| -c.solve(&gradient)) else {
                damping *= 10.0;
                continue;
            };
            let candidate = perturb(&pose, &step);
            let candidate_cost = cost(&candidate, object, image);
            if candidate_cost <= current {
                let decrease = current - candidate_cost;
                pose = candidate;
                let previous = current;
                current = candidate_cost;
                damping = (damping / 10.0).max(1e-12);
                improved = true;
                if decrease <= COST_TOLERANCE * previous || step.norm() <= STEP_TOLERANCE {
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

/// ML: the best closed-form start, refined by LM. One candidate.
pub fn solve(object: &[Vector3<f64>], image: &[Vector2<f64>]) -> Result<Candidates, PnpError> {
    let mut starts: Candidates = epnp::solve(object, image, true)?;
    // The paper's method may fail where EPnP does not (e.g. a degenerate
    // paraperspective); then the EPnP candidates are the start set.
    if let Ok(paper) = parallel::solve_with_gauss_newton(object, image, true) {
        starts.extend(paper);
    }
    let start = best_candidate("ML", &starts, object, image)?;
    Ok(smallvec![refine(&start, object, image)])
}
