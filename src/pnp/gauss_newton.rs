//! Gauss–Newton over EPnP's β (Lepetit et al. 2009 §3.4; paper eq. 10), with
//! optional per-pair weights (paper eq. 31).
//!
//! The residual of control-point pair `(a, b)` is
//! `‖C_a^c − C_b^c‖² − ‖C_a^w − C_b^w‖² = L_k β̄ − ρ_k`, where β̄ holds the ten
//! products of β. Gauss–Newton minimises `Σ_k w_k r_k²` over the four β;
//! with unit weights this is eq. 10, with the weights of eq. 30 it is eq. 31.

use super::epnp::EpnpSystem;
use nalgebra::{Matrix4, SVector, Vector4, Vector6};

/// Unit weights: plain EPnP Gauss–Newton (eq. 10).
pub const UNIT_WEIGHTS: [f64; 6] = [1.0; 6];
/// Upper bound on Gauss–Newton iterations (the reference implementation runs 5).
pub const MAX_ITERATIONS: usize = 10;
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

/// Refines β by Gauss–Newton on the weighted distance residuals. A step that
/// does not lower the cost ends the iteration, so the result is never worse
/// than the start; so does a step shorter than [`STEP_TOLERANCE`] (after it
/// is taken). Fixed-size 6×4 Jacobian and 4×4 normal equations; the
/// residuals of an accepted candidate are reused for the next step.
pub fn refine_betas(system: &EpnpSystem, start: &Vector4<f64>, weights: &[f64; 6]) -> Vector4<f64> {
    let l = system.distance_products();
    let mut betas = *start;
    let mut current_residuals = residuals(system, &betas);
    let mut current_cost = weighted_sum_sq(&current_residuals, weights);
    for _ in 0..MAX_ITERATIONS {
        let b = &betas;
        let mut normal = Matrix4::zeros();
        let mut gradient = Vector4::zeros();
        for k in 0..6 {
            let row = l.row(k);
            // ∂(L_k β̄)/∂β, as in the reference implementation.
            let jacobian = Vector4::new(
                2.0 * row[0] * b[0] + row[1] * b[1] + row[3] * b[2] + row[6] * b[3],
                row[1] * b[0] + 2.0 * row[2] * b[1] + row[4] * b[2] + row[7] * b[3],
                row[3] * b[0] + row[4] * b[1] + 2.0 * row[5] * b[2] + row[8] * b[3],
                row[6] * b[0] + row[7] * b[1] + row[8] * b[2] + 2.0 * row[9] * b[3],
            );
            let weighted = jacobian * weights[k];
            normal.syger(1.0, &weighted, &jacobian, 1.0);
            gradient += weighted * current_residuals[k];
        }
        let step = match normal.cholesky() {
            Some(c) => c.solve(&gradient),
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
        let candidate = betas + step;
        let candidate_residuals = residuals(system, &candidate);
        let candidate_cost = weighted_sum_sq(&candidate_residuals, weights);
        if candidate_cost > current_cost {
            break;
        }
        betas = candidate;
        current_residuals = candidate_residuals;
        current_cost = candidate_cost;
        if step.norm_squared() <= STEP_TOLERANCE * STEP_TOLERANCE * betas.norm_squared() {
            break;
        }
    }
    betas
}
