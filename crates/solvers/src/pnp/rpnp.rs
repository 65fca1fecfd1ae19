//! RPnP: Li, Xu & Xie, "A Robust O(n) Solution to the Perspective-n-Point
//! Problem", IEEE TPAMI 34(7), 2012.
//!
//! 1. **Rotation axis.** The pair of points whose lines of sight make
//!    the widest angle (the longest projected segment) fixes the axis
//!    `P_i1 → P_i2`. The object points are re-expressed in a frame whose
//!    x-axis is that edge, with origin at its midpoint.
//! 2. **Cost polynomial.** Each other point `P_i` forms a P3P triplet
//!    with the edge. With unit rays `u`, `C_i1 = s u_i1`,
//!    `C_i2 = s (cos θ12 + τ) u_i2` and `C_i = s μ u_i`, the three distance
//!    constraints eliminate `s` and `μ` and leave a quartic `f_i(τ) = 0`.
//!    The cost `F(τ) = Σ_i f_i(τ)²` is minimised: its derivative
//!    `F′/2 = Σ f_i f_i′` has degree 7. Every real root with `F″ > 0` is a
//!    candidate.
//! 3. **Rotation about the axis and translation.** For each τ the
//!    camera-frame direction of the axis is `(cos θ12 + τ) u_i2 − u_i1`; the
//!    rotation about it, `(cos α, sin α)`, and the translation enter the
//!    projection equations linearly, so they come from the eigenvector of
//!    the smallest eigenvalue of the 6×6 normal matrix (the homogeneous
//!    least-squares solution, scaled so its last entry is 1).
//! 4. **Refinement.** The distances `‖R X_j + t‖` from step 3 put
//!    every point back on its own line of sight, and 3D alignment (absolute
//!    orientation) of the object points with those camera points gives the
//!    final pose, which is a rigid transform even when `cos² α + sin² α ≠ 1`.
//!
//! Every local minimum of `F` gives a candidate; all are returned.
//!
//! Checked against the authors' MATLAB code (`RPnP.m`) step by step: the
//! triplet quartic is theirs times 4 (a unit test compares the
//! coefficients), so every triplet has their weight in `F`; the 6×6
//! homogeneous system (rows `u Z − X`, `v Z − Y` in the unknowns
//! `[c, s, tₓ, t_y, t_z, 1]`), the unnormalised `(c, s)` used for the depths,
//! and the final line-of-sight placement and 3D alignment (`calcampose`) are
//! theirs. Deviations: the axis is the widest pair over *all* pairs rather
//! than over `n` random pairs (deterministic; O(n²) but with a negligible
//! constant for the sizes used here); the final alignment is rigid, where
//! theirs fits a similarity and keeps its scale in the translation only
//! (`t = ȳ − c R x̄`, which depends on the object frame's origin; the
//! rotation is the same); the real roots come from [`super::polynomial`]
//! (exact real-root isolation, to a few ulps) rather than companion-matrix
//! roots whose imaginary part is below 1e-3 of the largest real part; all
//! minima are returned and the caller keeps the one with the lowest summed
//! squared reprojection error (theirs: mean reprojection distance).
//!
//! **Accuracy.** On noisy data RPnP is near the first-order limit for the
//! biprism but 1.27× above it on random n = 6…100 sets, more for larger n
//! (tests/it/noisy.rs). That is the method's, not this implementation's: the
//! axis in the camera frame is fixed by the two image points of the widest
//! pair (and τ), so their noise does not average out as n grows, and the
//! final alignment corrects only part of it. With those two image points
//! noise-free the same code is at the limit (tests/it/noisy.rs measures both).
//!
//! Equation numbers are not cited: this follows the authors' reference code,
//! read for understanding, and the paper's description of the method.
//!
//! Requirements: n ≥ 4 points (validated by the caller). Nothing is
//! allocated: the polynomial and the 6×6 system are fixed size, and only
//! the smallest eigenpair of the 6×6 normal matrix is computed
//! ([`crate::linalg::smallest_eigenpairs`]).

use super::polynomial::{multiply_into, Polynomial};
use super::{Candidates, Method, PnpError};
use crate::linalg::smallest_eigenpairs;
use crate::pose::{absolute_orientation, Pose};
use nalgebra::{Matrix3, SMatrix, Vector2, Vector3};

/// The method's name in messages.
const NAME: &str = "RPnP";
/// Smallest accepted `|last entry|` of the eigenvector of step 3, relative to
/// the vector's norm: below it the homogeneous solution has no finite scale.
pub const HOMOGENEOUS_SCALE_TOLERANCE: f64 = 1e-12;

/// The widest pair of lines of sight must make at least this squared sine
/// (an angle of 1e-8 rad); below it all image points coincide and no pose
/// follows. Objects 200 sizes away still subtend ~5e-3 rad.
pub const MIN_SPREAD_SIN_SQ: f64 = 1e-16;

/// Unit line of sight of a normalised image point.
#[inline]
fn ray(m: &Vector2<f64>) -> Vector3<f64> {
    Vector3::new(m.x, m.y, 1.0).normalize()
}

/// A right-handed orthonormal frame whose first column is the unit vector
/// `axis`; the second is built from whichever of the y and z coordinate axes
/// is further from `axis`, as in the authors' code.
fn frame_with_first_axis(axis: &Vector3<f64>) -> Matrix3<f64> {
    let (y, z) = if axis.y.abs() < axis.z.abs() {
        let z = axis.cross(&Vector3::y()).normalize();
        (z.cross(axis).normalize(), z)
    } else {
        let y = Vector3::z().cross(axis).normalize();
        (y, axis.cross(&y).normalize())
    };
    Matrix3::from_columns(&[*axis, y, z])
}

/// The pair `(i1, i2)` of image points that RPnP takes as its rotation axis
/// (step 1): the two whose lines of sight make the widest angle. Exposed so
/// that tests can study the method's sensitivity to these two points.
pub fn axis_pair(image: &[Vector2<f64>]) -> (usize, usize) {
    widest_pair(|i| ray(&image[i]), image.len())
}

/// The pair `(i1, i2)` whose lines of sight make the widest angle.
fn widest_pair(rays: impl Fn(usize) -> Vector3<f64>, count: usize) -> (usize, usize) {
    let mut best = (0, 1, f64::INFINITY);
    for i in 0..count {
        let a = rays(i);
        for j in i + 1..count {
            let cosine = a.dot(&rays(j));
            if cosine < best.2 {
                best = (i, j, cosine);
            }
        }
    }
    (best.0, best.1)
}

/// The quartic `f_i(τ)` (ascending coefficients) of the triplet
/// `(P_i1, P_i2, P_i)` (step 2).
///
/// With `k = cos θ12 + τ`, `w = sin² θ12 + τ²` (so that `s² = D1² / w`),
/// `A = (D2/D1)²`, `B = (D3/D1)²`, the distance constraints are
/// `μ² − 2 μ cos θ1i + 1 = A w` and `μ² − 2 μ k cos θ2i + k² = B w`.
/// Their difference gives `μ = N / (2L)` with `N = k² − 1 + (A − B) w` and
/// `L = k cos θ2i − cos θ1i`; substituting back gives
/// `f = N² − 4 cos θ1i · N L + 4 (1 − A w) L²`.
fn triplet_quartic(cos12: f64, sin12_sq: f64, cos1i: f64, cos2i: f64, a: f64, b: f64) -> [f64; 5] {
    // N = (A − B − 1) sin²θ12 + 2 cos θ12 τ + (1 + A − B) τ²  (using cos² − 1 = −sin²).
    let n = [(a - b - 1.0) * sin12_sq, 2.0 * cos12, 1.0 + a - b];
    let l = [cos12 * cos2i - cos1i, cos2i];
    let one_minus_aw = [1.0 - a * sin12_sq, 0.0, -a];
    let mut n_sq = [0.0; 5];
    multiply_into(&n, &n, &mut n_sq);
    let mut n_l = [0.0; 4];
    multiply_into(&n, &l, &mut n_l);
    let mut l_sq = [0.0; 3];
    multiply_into(&l, &l, &mut l_sq);
    let mut last = [0.0; 5];
    multiply_into(&one_minus_aw, &l_sq, &mut last);
    let mut quartic = n_sq;
    for k in 0..4 {
        quartic[k] -= 4.0 * cos1i * n_l[k];
    }
    for k in 0..5 {
        quartic[k] += 4.0 * last[k];
    }
    quartic
}

/// `rpnp`: RPnP (Li, Xu & Xie 2012): all local minima of the degree-7 cost derivative about the widest edge.
pub const RPNP: Method = Method {
    name: "rpnp",
    display_name: "RPnP",
    description: "RPnP: every local minimum of the degree-7 cost about the widest edge, then 3D alignment (Li, Xu & Xie 2012)",
    min_points: 4,
    accepts_coplanar: false,
    exact: true,
    start: None,
    solve,
};

/// RPnP: one candidate per local minimum of the cost `F(τ)`.
pub fn solve(object: &[Vector3<f64>], image: &[Vector2<f64>]) -> Result<Candidates, PnpError> {
    let count = object.len();
    if count < 4 {
        return Err(PnpError::TooFewPoints {
            solver: NAME,
            needed: 4,
            got: count,
        });
    }
    let degenerate = |reason| PnpError::Degenerate {
        solver: NAME,
        reason,
    };

    // Step 1: the rotation axis and the object frame built on it.
    let (i1, i2) = widest_pair(|i| ray(&image[i]), count);
    let (ray1, ray2) = (ray(&image[i1]), ray(&image[i2]));
    let sin12_sq = ray1.cross(&ray2).norm_squared();
    if sin12_sq.is_nan() || sin12_sq <= MIN_SPREAD_SIN_SQ {
        return Err(degenerate(
            "the image points have no spread (all lines of sight coincide)",
        ));
    }
    let edge = object[i2] - object[i1];
    let edge_length = edge.norm();
    let midpoint = 0.5 * (object[i1] + object[i2]);
    let object_frame = frame_with_first_axis(&(edge / edge_length));
    let local = |p: &Vector3<f64>| object_frame.transpose() * (p - midpoint);

    // Step 2: F′/2 = Σ f_i f_i′, degree 7.
    let cos12 = ray1.dot(&ray2);
    let mut derivative_half = [0.0; 8];
    for (i, p) in object.iter().enumerate() {
        if i == i1 || i == i2 {
            continue;
        }
        let ray_i = ray(&image[i]);
        let a = ((p - object[i1]).norm() / edge_length).powi(2);
        let b = ((p - object[i2]).norm() / edge_length).powi(2);
        let f = triplet_quartic(cos12, sin12_sq, ray1.dot(&ray_i), ray2.dot(&ray_i), a, b);
        let f_prime = [f[1], 2.0 * f[2], 3.0 * f[3], 4.0 * f[4]];
        let mut product = [0.0; 8];
        multiply_into(&f, &f_prime, &mut product);
        for (sum, term) in derivative_half.iter_mut().zip(product) {
            *sum += term;
        }
    }
    let cost_derivative = Polynomial::new(&derivative_half)
        .ok_or_else(|| degenerate("the cost polynomial is not finite"))?;
    let cost_curvature = cost_derivative.derivative();

    let mut candidates = Candidates::new();
    for tau in cost_derivative.real_roots() {
        if cost_curvature.eval(tau) <= 0.0 {
            continue; // a maximum or an inflection of F, not a minimum
        }
        if let Some(pose) = pose_for_root(tau, cos12, &ray1, &ray2, &local, object, image) {
            candidates.push(pose);
        }
    }
    if candidates.is_empty() {
        return Err(degenerate(
            "no minimum of the cost polynomial gives a finite pose",
        ));
    }
    Ok(candidates)
}

/// Steps 3 and 4 for one root τ: the rotation about the axis and the
/// translation by homogeneous least squares, then 3D alignment. `None` when
/// the homogeneous solution has no finite scale.
fn pose_for_root(
    tau: f64,
    cos12: f64,
    ray1: &Vector3<f64>,
    ray2: &Vector3<f64>,
    local: &impl Fn(&Vector3<f64>) -> Vector3<f64>,
    object: &[Vector3<f64>],
    image: &[Vector2<f64>],
) -> Option<Pose> {
    let axis = ray2 * (cos12 + tau) - ray1;
    let camera_frame = frame_with_first_axis(&axis.try_normalize(0.0)?);
    let (x_axis, y_axis, z_axis) = (
        camera_frame.column(0).into_owned(),
        camera_frame.column(1).into_owned(),
        camera_frame.column(2).into_owned(),
    );
    // Camera point of local point X: X_x x + cos α (X_y y + X_z z)
    // + sin α (X_y z − X_z y) + t, linear in [cos α, sin α, t, 1].
    let parts = |p: &Vector3<f64>| {
        let q = local(p);
        (
            y_axis * q.y + z_axis * q.z,
            z_axis * q.y - y_axis * q.z,
            x_axis * q.x,
        )
    };
    let mut normal = SMatrix::<f64, 6, 6>::zeros();
    for (p, m) in object.iter().zip(image) {
        let (cosine_part, sine_part, fixed) = parts(p);
        let row_x = SMatrix::<f64, 6, 1>::from([
            cosine_part.x - m.x * cosine_part.z,
            sine_part.x - m.x * sine_part.z,
            1.0,
            0.0,
            -m.x,
            fixed.x - m.x * fixed.z,
        ]);
        let row_y = SMatrix::<f64, 6, 1>::from([
            cosine_part.y - m.y * cosine_part.z,
            sine_part.y - m.y * sine_part.z,
            0.0,
            1.0,
            -m.y,
            fixed.y - m.y * fixed.z,
        ]);
        normal.syger(1.0, &row_x, &row_x, 1.0);
        normal.syger(1.0, &row_y, &row_y, 1.0);
    }
    // Only the eigenvector of the smallest eigenvalue is needed; the
    // shared solver reads the lower triangle and skips the other five.
    let vector = smallest_eigenpairs::<6, 1>(&normal).ok()?.vectors[0];
    if vector[5].is_nan() || vector[5].abs() <= HOMOGENEOUS_SCALE_TOLERANCE * vector.norm() {
        return None;
    }
    let solution = vector / vector[5];
    let (cosine, sine) = (solution[0], solution[1]);
    let translation = Vector3::new(solution[2], solution[3], solution[4]);
    // Step 4: each point at its estimated distance on its own line of sight.
    let camera_points = object.iter().zip(image).map(|(p, m)| {
        let (cosine_part, sine_part, fixed) = parts(p);
        let distance = (fixed + cosine_part * cosine + sine_part * sine + translation).norm();
        ray(m) * distance
    });
    let pose = absolute_orientation(object.iter().copied(), camera_points);
    pose.is_finite().then_some(pose)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pose::rotation_error_deg;
    use crate::synthetic::{random_points, random_pose, stream_rng};

    fn project(pose: &Pose, object: &[Vector3<f64>]) -> Vec<Vector2<f64>> {
        object.iter().map(|p| pose.project_normalised(p)).collect()
    }

    #[test]
    fn quartic_vanishes_at_the_true_configuration() {
        // Three camera points; τ from the true depth ratio of the first two.
        let c1: Vector3<f64> = Vector3::new(10.0, -5.0, 300.0);
        let c2: Vector3<f64> = Vector3::new(-40.0, 20.0, 350.0);
        let ci: Vector3<f64> = Vector3::new(30.0, 45.0, 280.0);
        let (u1, u2, ui) = (c1.normalize(), c2.normalize(), ci.normalize());
        let cos12 = u1.dot(&u2);
        let tau = c2.norm() / c1.norm() - cos12;
        let d1 = (c1 - c2).norm();
        let a = ((ci - c1).norm() / d1).powi(2);
        let b = ((ci - c2).norm() / d1).powi(2);
        let f = triplet_quartic(
            cos12,
            u1.cross(&u2).norm_squared(),
            u1.dot(&ui),
            u2.dot(&ui),
            a,
            b,
        );
        let p = Polynomial::new(&f).unwrap();
        let scale = f.iter().fold(0.0f64, |m, c| m.max(c.abs()));
        assert!(p.eval(tau).abs() < 1e-12 * scale, "{}", p.eval(tau));
        assert!(p.real_roots().iter().any(|r| (r - tau).abs() < 1e-9));
    }

    /// The triplet quartic is the authors' (`RPnP.m`, written there with
    /// auxiliary quantities A1…A7 in descending powers) times 4, so every
    /// triplet carries the same weight in `F = Σ f_i²` as in their code.
    #[test]
    fn quartic_is_four_times_the_authors_form() {
        use rand::Rng;
        let mut rng = stream_rng(5, 61, 0);
        for _ in 0..100 {
            let mut unit = || {
                Vector3::new(
                    rng.random_range(-0.5..0.5),
                    rng.random_range(-0.5..0.5),
                    1.0,
                )
                .normalize()
            };
            let (u1, u2, ui) = (unit(), unit(), unit());
            let (a, b) = (rng.random_range(0.1..3.0), rng.random_range(0.1..3.0));
            let (c12, c1i, c2i) = (u1.dot(&u2), u1.dot(&ui), u2.dot(&ui));
            let (s12_sq, s1i_sq) = (1.0 - c12 * c12, 1.0 - c1i * c1i);
            let a2 = a * s12_sq - s1i_sq;
            let a3 = c1i * c2i - c12;
            let a4 = c12 * c2i - c1i;
            let a6 = (b - 1.0 - a) / 2.0;
            let a7 = 1.0 - c12 * c12 - c1i * c1i + c12 * c1i * c2i + a6 * s12_sq;
            let authors = [
                a7 * a7 - a2 * a4 * a4,
                2.0 * (a3 * a7 - a2 * a4 * c2i),
                a3 * a3 + 2.0 * a6 * a7 - a * a4 * a4 - a2 * c2i * c2i,
                2.0 * (a3 * a6 - a * a4 * c2i),
                a6 * a6 - a * c2i * c2i,
            ];
            let ours = triplet_quartic(c12, u1.cross(&u2).norm_squared(), c1i, c2i, a, b);
            let scale = ours.iter().fold(0.0f64, |m, c| m.max(c.abs()));
            for k in 0..5 {
                assert!(
                    (ours[k] - 4.0 * authors[k]).abs() < 1e-12 * scale,
                    "power {k}: {} vs 4 × {}",
                    ours[k],
                    authors[k]
                );
            }
        }
    }

    #[test]
    fn frame_is_a_rotation_with_the_given_first_axis() {
        for axis in [
            Vector3::new(1.0, 2.0, 3.0),
            Vector3::new(0.0, 1.0, 0.0),
            Vector3::new(0.0, 0.0, -1.0),
        ] {
            let axis = axis.normalize();
            let frame = frame_with_first_axis(&axis);
            assert!((frame.transpose() * frame - Matrix3::identity()).norm() < 1e-14);
            assert!((frame.determinant() - 1.0).abs() < 1e-14);
            assert!((frame.column(0) - axis).norm() < 1e-15);
        }
    }

    #[test]
    fn recovers_a_pose_exactly_and_returns_it_among_the_candidates() {
        for case in 0..50 {
            let mut rng = stream_rng(5, 60, case);
            let object = random_points(&mut rng, 4 + (case as usize % 6), 100.0);
            let truth = random_pose(&mut rng, 400.0, 0.3);
            if object.iter().any(|p| truth.transform(p).z < 50.0) {
                continue;
            }
            let candidates = solve(&object, &project(&truth, &object)).unwrap();
            let best = candidates
                .iter()
                .map(|c| rotation_error_deg(&truth.rotation, &c.rotation))
                .fold(f64::INFINITY, f64::min);
            assert!(best < 1e-7, "case {case}: {best}°");
        }
    }

    #[test]
    fn a_point_image_is_a_typed_error() {
        let object = [Vector3::zeros(), Vector3::x(), Vector3::y(), Vector3::z()];
        let err = solve(&object, &[Vector2::new(0.1, 0.2); 4]).unwrap_err();
        assert_eq!(
            err.to_string(),
            "RPnP failed: the image points have no spread (all lines of sight coincide)"
        );
    }

    #[test]
    fn rejects_too_few_points() {
        let object = [Vector3::zeros(), Vector3::x(), Vector3::y()];
        let image = [Vector2::zeros(); 3];
        let err = solve(&object, &image).unwrap_err();
        assert_eq!(err.to_string(), "RPnP needs at least 4 points, got 3");
    }
}
