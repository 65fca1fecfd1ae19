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
    let Some(foam) = Foam::of(m, norm_sq, det) else {
        return pose::nearest_rotation(m);
    };
    Rotation3::from_matrix_unchecked(foam.rotation)
}

/// FOAM's closed form for `m`: the candidate rotation with its divisor ζ,
/// before any conditioning test; `None` when the result is not finite.
struct Foam {
    rotation: Matrix3<f64>,
    zeta: f64,
}

impl Foam {
    /// Largest root λ of the quartic by Newton from above (the quartic is
    /// convex and increasing beyond it), then the rotation formula.
    fn of(m: &Matrix3<f64>, norm_sq: f64, det: f64) -> Option<Foam> {
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
        rotation
            .iter()
            .all(|v| v.is_finite())
            .then_some(Foam { rotation, zeta })
    }
}

/// The rotation nearest to `m` by FOAM for either sign of `det m`,
/// guarded by its own conditioning rather than by the sign and size of
/// `det m`.
///
/// SQPnP starts SQP from the nearest rotations to `±√3 e`: one of the two
/// always has a negative determinant, and in the far field the eigenvectors
/// beyond the first are often nearly rank-one matrices. The shared
/// [`nearest_rotation`] sends both cases to an SVD, which made the
/// projections a sixth of the solve. FOAM's formula holds for either sign:
/// its divisor is `ζ = κλ − det m`, which equals `(s₁ + s₂)(s₁ + s₃)(s₂ + s₃)`
/// for `det m ≥ 0` and `(s₁ + s₂)(s₁ − s₃)(s₂ − s₃)` for `det m < 0`
/// (singular values `s₁ ≥ s₂ ≥ s₃`), small only where the nearest rotation
/// itself is ill-determined (`m` nearly of rank one, or `s₂ ≈ s₃` with a
/// negative determinant). The SVD projection ([`pose::nearest_rotation`])
/// decides when ζ is below [`MIN_ZETA_FRACTION`] of `(‖m‖²/3)^{3/2}` or when
/// the FOAM result is not orthogonal to
/// [`FOAM_ORTHOGONALITY_SQUARED_TOLERANCE`] (λ inaccurate: it is a nearly
/// double root when `m` is nearly of rank one).
pub fn nearest_rotation_any_det(m: &Matrix3<f64>) -> Rotation3<f64> {
    let det = m.determinant();
    let norm_sq = m.norm_squared();
    if !norm_sq.is_finite() || det.is_nan() || norm_sq == 0.0 {
        return pose::nearest_rotation(m);
    }
    let unit = norm_sq / 3.0;
    let Some(foam) = Foam::of(m, norm_sq, det)
        .filter(|foam| foam.zeta >= MIN_ZETA_FRACTION * unit * unit.sqrt())
    else {
        return pose::nearest_rotation(m);
    };
    // λ is a nearly double root when m is nearly rank one, and Newton then
    // leaves it inaccurate; the result shows it by not being orthogonal.
    let r = foam.rotation;
    let orthogonality = (r * r.transpose() - Matrix3::identity()).norm_squared();
    if orthogonality.is_nan() || orthogonality > FOAM_ORTHOGONALITY_SQUARED_TOLERANCE {
        return pose::nearest_rotation(m);
    }
    Rotation3::from_matrix_unchecked(r)
}

/// [`nearest_rotation_any_det`] leaves `m` to the SVD when
/// `ζ < MIN_ZETA_FRACTION (‖m‖²/3)^{3/2}` (a division by nearly zero).
/// FOAM's rounding grows like `ε / ζ`; the orthogonality test catches what
/// this lets through.
pub const MIN_ZETA_FRACTION: f64 = 1e-6;
/// A FOAM result whose `‖R Rᵀ − I‖²` exceeds this is discarded for the SVD
/// (it would mean λ, and with it the rotation, is inaccurate).
pub const FOAM_ORTHOGONALITY_SQUARED_TOLERANCE: f64 = 1e-24;

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

    #[test]
    fn foam_projection_agrees_with_the_svd_for_either_sign() {
        use rand::Rng;
        let mut worst = 0.0f64;
        for case in 0..4000 {
            let mut rng = stream_rng(11, 81, case);
            let scale = 10f64.powf(rng.random_range(-3.0..3.0));
            let mut m = Matrix3::from_fn(|_, _| rng.random_range(-1.0..1.0)) * scale;
            if case % 2 == 1 {
                // Nearly singular, either sign: s₃ shrunk by up to 1e-12.
                let svd = m.svd(true, true);
                let mut s = svd.singular_values;
                s[2] *= 10f64.powf(rng.random_range(-12.0..0.0));
                m = svd.u.unwrap() * Matrix3::from_diagonal(&s) * svd.v_t.unwrap();
            }
            let svd = pose::nearest_rotation(&m);
            let ours = nearest_rotation_any_det(&m);
            let difference = (svd.matrix() - ours.matrix()).norm();
            worst = worst.max(difference);
            let r = ours.matrix();
            let ortho = (r.transpose() * r - Matrix3::identity()).norm();
            assert!(
                difference < 1e-9 && ortho < 1e-12,
                "case {case}: {difference:e}, {ortho:e}\n{m}"
            );
            assert!((r.determinant() - 1.0).abs() < 1e-12);
        }
        eprintln!("worst difference from the SVD projection: {worst:e}");
    }
}
