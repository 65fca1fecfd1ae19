//! The rotation nearest to a 3×3 matrix, by Markley's FOAM ("Attitude
//! Determination Using Vector Observations: A Fast Optimal Matrix
//! Algorithm", J. Astronaut. Sci. 41(2), 1993), as Lourakis & Terzakis use
//! it for absolute orientation ("Efficient Absolute Orientation Revisited",
//! IROS 2018) and in SQPnP's reference code.
//!
//! For `M = U diag(s) Vᵀ` the rotation maximising `tr(Rᵀ M)` attains
//! `λ = s1 + s2 + sign(det M)·s3`, the largest root of
//! `(λ² − ‖M‖²)² − 8 λ det M − 4 ‖adj M‖² = 0` (Markley eq. 23, Frobenius
//! norms). Newton's method from `λ0 = √3 ‖M‖ ≥ λ` converges to it
//! monotonically (the quartic is convex there). Then, with
//! `κ = (λ² − ‖M‖²)/2` and `ζ = κλ − det M`,
//! `R = ((κ + ‖M‖²) M + λ adj(M)ᵀ − M Mᵀ M) / ζ` (Markley eqs. 14, 18, 19).
//!
//! No SVD is needed, which makes it several times faster than
//! [`crate::pose::nearest_rotation`]. FOAM is used only where it is well
//! conditioned: `det M > 0`, where `ζ ≥ 8 s1 s2 s3` is bounded away from 0.
//! When `M` is nearly singular the largest root becomes (nearly) double, and
//! when `det M < 0` with `s2 ≈ s3` the division by ζ cancels badly; there the
//! SVD projection is used instead. The result is the same rotation either
//! way (the hot loops of LHM and SQPnP project matrices close to a rotation,
//! so they take the fast path).

use crate::pose;
use nalgebra::{Matrix3, Rotation3};

/// `det M` below this fraction of `(‖M‖/√3)³` (nearly singular, or
/// negative) goes to the SVD (OpenCV's sqpnp.cpp uses `|det| < 1e-4` on
/// unit-scale matrices).
pub const SINGULAR_DETERMINANT_FRACTION: f64 = 1e-4;
/// Upper bound on Newton steps for λ (it converges in a handful).
pub const MAX_NEWTON_STEPS: usize = 30;
/// Newton stops when a step changes λ by less than this fraction of λ.
pub const NEWTON_TOLERANCE: f64 = 1e-15;

/// The rotation `R` minimising `‖R − m‖_F` (equivalently maximising
/// `tr(Rᵀ m)`), determinant +1.
pub fn nearest_rotation(m: &Matrix3<f64>) -> Rotation3<f64> {
    let norm_sq = m.norm_squared();
    let det = m.determinant();
    // (‖m‖²/3)^{3/2}, without libm's pow (a measurable share of EPnP).
    let mean_sq = norm_sq / 3.0;
    let unit_cube = mean_sq * mean_sq.sqrt();
    if !norm_sq.is_finite() || det.is_nan() || det < SINGULAR_DETERMINANT_FRACTION * unit_cube {
        return pose::nearest_rotation(m);
    }
    // adj(M)ᵀ = cofactor matrix; ‖adj M‖² is the same either way.
    let cofactor = Matrix3::from_columns(&[
        m.column(1).cross(&m.column(2)),
        m.column(2).cross(&m.column(0)),
        m.column(0).cross(&m.column(1)),
    ]);
    let adj_norm_sq = cofactor.norm_squared();
    let mut lambda = (3.0 * norm_sq).sqrt();
    for _ in 0..MAX_NEWTON_STEPS {
        let shifted = lambda * lambda - norm_sq;
        let value = shifted * shifted - 8.0 * lambda * det - 4.0 * adj_norm_sq;
        let slope = 4.0 * lambda * shifted - 8.0 * det;
        if slope.is_nan() || slope <= 0.0 {
            break;
        }
        let step = value / slope;
        lambda -= step;
        if step.abs() <= NEWTON_TOLERANCE * lambda.abs() {
            break;
        }
    }
    let kappa = 0.5 * (lambda * lambda - norm_sq);
    let zeta = kappa * lambda - det;
    let rotation = ((kappa + norm_sq) * m + lambda * cofactor - m * m.transpose() * m) / zeta;
    if !rotation.iter().all(|v| v.is_finite()) {
        return pose::nearest_rotation(m);
    }
    Rotation3::from_matrix_unchecked(rotation)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synthetic::{stream_rng, uniform_rotation};
    use rand::Rng;

    #[test]
    fn agrees_with_the_svd_projection() {
        for case in 0..2000 {
            let mut rng = stream_rng(17, 90, case);
            // Random matrices of any conditioning and sign of determinant,
            // at any scale.
            let scale = 10f64.powf(rng.random_range(-3.0..3.0));
            let m = Matrix3::from_fn(|_, _| rng.random_range(-1.0..1.0)) * scale;
            let svd = pose::nearest_rotation(&m);
            let foam = nearest_rotation(&m);
            let difference = (svd.matrix() - foam.matrix()).norm();
            assert!(difference < 1e-9, "case {case}: {difference}\n{m}");
            let r = foam.matrix();
            let ortho = (r.transpose() * r - Matrix3::identity()).norm();
            assert!(
                ortho < 1e-12,
                "case {case}: {ortho:e} {:?}",
                m.svd(false, false).singular_values
            );
            assert!((r.determinant() - 1.0).abs() < 1e-12);
        }
    }

    #[test]
    fn is_exact_near_a_rotation_and_falls_back_when_singular() {
        let mut rng = stream_rng(17, 91, 0);
        let truth = uniform_rotation(&mut rng);
        let m = truth.matrix() * Matrix3::from_diagonal(&nalgebra::Vector3::new(3.0, 2.0, 0.5));
        // m = R S with S symmetric positive: its polar factor is R exactly.
        let foam = nearest_rotation(&m);
        assert!((foam.matrix() - truth.matrix()).norm() < 1e-14);
        let rank_two =
            truth.matrix() * Matrix3::from_diagonal(&nalgebra::Vector3::new(3.0, 2.0, 0.0));
        let foam = nearest_rotation(&rank_two);
        assert!((foam.matrix() - pose::nearest_rotation(&rank_two).matrix()).norm() < 1e-12);
    }
}
