//! Gauss–Newton over EPnP's β (Lepetit et al. 2009 §3.4; paper eq. 10), with
//! optional per-pair weights (paper eq. 31).
//!
//! The residual of control-point pair `(a, b)` is
//! `‖C_a^c − C_b^c‖² − ‖C_a^w − C_b^w‖² = L_k β̄ − ρ_k`, where β̄ holds the ten
//! products of β. Gauss–Newton minimises `Σ_k w_k r_k²` over the four β;
//! with unit weights this is eq. 10, with the weights of eq. 30 it is eq. 31.

use super::epnp::{EpnpSystem, PRODUCT_COLUMN};
use crate::linalg::solve_positive_definite;
use nalgebra::{Matrix4, SVector, Vector4, Vector6};

/// Unit weights: plain EPnP Gauss–Newton (eq. 10).
pub const UNIT_WEIGHTS: [f64; 6] = [1.0; 6];
/// Upper bound on Gauss–Newton iterations. The reference implementation
/// runs 5 full steps; converged problems stop on [`STEP_TOLERANCE`] after
/// 2–4, so the bound only matters for starts far from the solution, where
/// backtracked steps need more iterations.
pub const MAX_ITERATIONS: usize = 20;
/// Step halvings tried when a full step raises the cost, before the
/// iteration stops. 2⁻³⁰ of a step is below anything that can still lower
/// a cost evaluated in double precision.
pub const MAX_HALVINGS: usize = 30;
/// Stop after an accepted step that changed β by at most this fraction of
/// ‖β‖. Below it the cost comparison itself is rounding noise: the
/// residuals `ρ_k − L_k β̄` cancel terms of size ‖c_a − c_b‖², and on
/// 1000 near-field biprism problems (seed 2026) the next step was rejected
/// as "cost increased" after last accepted steps of 1e-8…1e-12 relative,
/// one wasted iteration in two. Without noise GN converges quadratically,
/// leaving an error of the order of the step squared; with noise, linearly
/// at a rate of about 1e-2, leaving ~1e-10 relative, seven orders of
/// magnitude below the noise-driven error.
pub const STEP_TOLERANCE: f64 = 1e-8;

/// The ten products `[β1², β1β2, β2², β1β3, β2β3, β3², β1β4, β2β4, β3β4, β4²]`
/// in the column order of L.
#[inline]
fn products(b: &Vector4<f64>) -> SVector<f64, 10> {
    SVector::<f64, 10>::from_column_slice(&[
        b[0] * b[0],
        b[0] * b[1],
        b[1] * b[1],
        b[0] * b[2],
        b[1] * b[2],
        b[2] * b[2],
        b[0] * b[3],
        b[1] * b[3],
        b[2] * b[3],
        b[3] * b[3],
    ])
}

/// The six residuals `ρ_k − L_k β̄`.
#[inline]
fn residuals(system: &EpnpSystem, betas: &Vector4<f64>) -> Vector6<f64> {
    system.control_distances_sq() - system.distance_products() * products(betas)
}

/// `Σ_k w_k r_k²`.
#[inline]
fn weighted_sum_sq(residuals: &Vector6<f64>, weights: &[f64; 6]) -> f64 {
    residuals.iter().zip(weights).map(|(r, w)| w * r * r).sum()
}

/// Weighted residual cost `Σ_k w_k (L_k β̄ − ρ_k)²`.
pub fn cost(system: &EpnpSystem, betas: &Vector4<f64>, weights: &[f64; 6]) -> f64 {
    weighted_sum_sq(&residuals(system, betas), weights)
}

/// The quadratic forms of the six distance constraints: `L_k β̄ = βᵀ Q_k β`
/// with `Q_k` symmetric (its off-diagonal entries are half the mixed
/// coefficients of L). Then `∂(L_k β̄)/∂β = 2 Q_k β` (the Jacobian of the
/// reference implementation) and `L_k β̄ = ½ βᵀ (2 Q_k β)`, so one 4×4
/// product per pair gives both the Jacobian row and the residual.
fn quadratic_forms(system: &EpnpSystem) -> [[[f64; 4]; 4]; 6] {
    let l = system.distance_products();
    std::array::from_fn(|k| {
        std::array::from_fn(|i| {
            std::array::from_fn(|j| {
                let coefficient = l[(k, PRODUCT_COLUMN[i][j])];
                if i == j {
                    coefficient
                } else {
                    0.5 * coefficient
                }
            })
        })
    })
}

/// Jacobian rows `2 Q_k β` and residuals `ρ_k − L_k β̄` at β.
#[inline]
fn linearise(
    forms: &[[[f64; 4]; 4]; 6],
    rho: &Vector6<f64>,
    betas: &Vector4<f64>,
) -> ([Vector4<f64>; 6], Vector6<f64>) {
    let mut residuals = Vector6::zeros();
    let jacobian = std::array::from_fn(|k| {
        let q = &forms[k];
        let row = Vector4::from_fn(|i, _| {
            2.0 * (q[i][0] * betas[0]
                + q[i][1] * betas[1]
                + q[i][2] * betas[2]
                + q[i][3] * betas[3])
        });
        residuals[k] = rho[k] - 0.5 * row.dot(betas);
        row
    });
    (jacobian, residuals)
}

/// Refines β by Gauss–Newton on the weighted distance residuals, with a
/// backtracking line search: a step that raises the cost is halved until it
/// lowers it (at most [`MAX_HALVINGS`] times), and only a direction that no
/// halving makes a descent ends the iteration. So the result is never worse
/// than the start, and a start whose first full step overshoots (the
/// quartic cost often rises on it, e.g. 1.0·10⁷ → 7.4·10⁷, before falling
/// to rounding) still converges. The full step is tried first, so a problem
/// that plain Gauss–Newton solves takes exactly the same steps. The
/// iteration also stops after a step shorter than [`STEP_TOLERANCE`] (after
/// it is taken). Fixed-size 6×4 Jacobian and 4×4 normal equations, nothing
/// allocated; the linearisation of an accepted candidate is reused for the
/// next step.
pub fn refine_betas(system: &EpnpSystem, start: &Vector4<f64>, weights: &[f64; 6]) -> Vector4<f64> {
    let forms = quadratic_forms(system);
    let rho = system.control_distances_sq();
    let mut betas = *start;
    let (mut jacobian, mut current_residuals) = linearise(&forms, rho, &betas);
    let mut current_cost = weighted_sum_sq(&current_residuals, weights);
    for _ in 0..MAX_ITERATIONS {
        let mut normal = Matrix4::zeros();
        let mut gradient = Vector4::zeros();
        for k in 0..6 {
            let row = &jacobian[k];
            let weighted = row * weights[k];
            // Lower triangle only: the factorisation reads nothing else.
            for c in 0..4 {
                for r in c..4 {
                    normal[(r, c)] += weighted[r] * row[c];
                }
            }
            gradient += weighted * current_residuals[k];
        }
        let mut step = match solve_positive_definite(&normal, &gradient) {
            Some(step) => step,
            None => {
                normal.fill_upper_triangle_with_lower_triangle();
                match normal.lu().solve(&gradient) {
                    Some(step) => step,
                    None => break,
                }
            }
        };
        if !step.iter().all(|v| v.is_finite()) {
            break;
        }
        let mut accepted = None;
        for _ in 0..=MAX_HALVINGS {
            let candidate = betas + step;
            let (candidate_jacobian, candidate_residuals) = linearise(&forms, rho, &candidate);
            let candidate_cost = weighted_sum_sq(&candidate_residuals, weights);
            if candidate_cost <= current_cost {
                accepted = Some((
                    candidate,
                    candidate_jacobian,
                    candidate_residuals,
                    candidate_cost,
                ));
                break;
            }
            step *= 0.5;
        }
        let Some((candidate, candidate_jacobian, candidate_residuals, candidate_cost)) = accepted
        else {
            break;
        };
        betas = candidate;
        jacobian = candidate_jacobian;
        current_residuals = candidate_residuals;
        current_cost = candidate_cost;
        if step.norm_squared() <= STEP_TOLERANCE * STEP_TOLERANCE * betas.norm_squared() {
            break;
        }
    }
    betas
}
