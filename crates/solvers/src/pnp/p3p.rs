//! P3P: every pose that maps three object points onto three image points,
//! by Lambda Twist (Persson & Nordberg, "Lambda Twist: An Accurate Fast
//! Robust Perspective Three Point (P3P) Solver", ECCV 2018).
//!
//! **Problem.** Given object points `x_1, x_2, x_3` (mm) and unit bearings
//! `y_i ∝ (m_i, 1)` of their normalised image points, find the depths
//! `λ_i > 0` with `‖λ_i y_i − λ_j y_j‖² = a_ij = ‖x_i − x_j‖²` (paper eq. 4),
//! then the rigid transform that carries the `x_i` onto the `λ_i y_i`.
//!
//! **Method.** Each distance equation is a quadric `Λᵀ M_ij Λ = a_ij` in
//! `Λ = (λ_1, λ_2, λ_3)`, with `M_ij` holding 1 on the `i`, `j` diagonal
//! and `−b_ij = −y_i·y_j` off it (paper eq. 5). The homogeneous forms
//! `D_1 = a_23 M_12 − a_12 M_23` and `D_2 = a_23 M_13 − a_13 M_23` both
//! vanish at a solution (eq. 7), and so does `D_0 = D_1 + γ D_2` for every
//! `γ`. The `γ` that makes `D_0` singular is a root of the cubic
//! `det(D_1 + γ D_2) = 0` (eq. 9); a singular indefinite `D_0` factors into
//! two planes through the origin (eqs. 12–15), found here from its
//! eigenvalues with the zero one known (§3.3). On each plane, two of the
//! distance equations give a homogeneous quadratic in the plane's
//! coordinates, hence up to two depth triples (eqs. 16–18): four poses at
//! most. Each triple is polished by Gauss–Newton on the three distance
//! equations (§3.5), and the pose follows from the two triangle edges and
//! their cross product, `R = Y X⁻¹` (eq. 20), projected onto SO(3).
//!
//! **Preconditions.** The object points must span a triangle and the
//! bearings must not be coplanar (image points not collinear): both make
//! the pose undetermined. [`solve`] refuses them with a [`PnpError`];
//! [`solve_bearings`], the hot-path form, returns no candidate instead.
//! Every returned pose is finite, puts the three points in front of the
//! camera and reproduces the three distances.
//!
//! Nothing is allocated: candidates are returned in a [`P3pCandidates`]
//! array vector.
//!
//! ```
//! use layout_opt_solvers::pnp::p3p;
//! use layout_opt_solvers::pose::{rotation_error_deg, Pose};
//! use nalgebra::{Rotation3, Vector2, Vector3};
//!
//! let object = [
//!     Vector3::new(0.0, 0.0, 0.0),
//!     Vector3::new(50.0, 0.0, 10.0),
//!     Vector3::new(0.0, 40.0, -20.0),
//! ];
//! let truth = Pose::new(Rotation3::from_euler_angles(0.3, -0.2, 0.1), Vector3::new(10.0, 5.0, 400.0));
//! let image: Vec<Vector2<f64>> = object.iter().map(|p| truth.project_normalised(p)).collect();
//! let poses = p3p::solve(&object, &image.try_into().unwrap())?;
//! assert!(poses.iter().any(|pose| rotation_error_deg(&truth.rotation, &pose.rotation) < 1e-8));
//! # Ok::<(), layout_opt_solvers::pnp::PnpError>(())
//! ```

// `!(x > 0.0)` is deliberate throughout: it is true for NaN as well, so
// a non-finite intermediate rejects a root rather than passing it.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

use super::polynomial::Polynomial;
use super::{check_finite, PnpError};
use crate::pose::{nearest_rotation, Pose};
use nalgebra::{Matrix2, Matrix3, Vector2, Vector3};
use smallvec::SmallVec;

/// Up to four poses, stored inline.
pub type P3pCandidates = SmallVec<[Pose; 4]>;

/// Human name of the method.
pub const NAME: &str = "P3P (Lambda Twist)";

/// A triangle whose doubled area is below this fraction of its squared
/// longest edge counts as collinear (its roll about the line is
/// undetermined).
pub const COLLINEAR_TOLERANCE: f64 = 1e-9;
/// Bearings whose triple product is below this count as coplanar (the
/// image points as collinear, or two of them as coincident).
pub const COPLANAR_BEARINGS_TOLERANCE: f64 = 1e-12;
/// Relative size below which a discriminant or an eigenvalue is rounding
/// noise: a double root or a rank-one form blurred by rounding still counts.
const ROUNDING_TOLERANCE: f64 = 1e-12;
/// Newton steps on the depths (§3.5); the paper uses 5, and each step
/// squares the relative error of an already close root. More are allowed
/// for far-field roots that start further off; converged roots stop early.
pub const DEPTH_REFINEMENT_STEPS: usize = 15;
/// `γ` needs no polishing once the eigenvalue it zeroes is below this
/// fraction of the smaller non-zero one.
const SETTLED_ZERO: f64 = 1e-12;
/// Newton steps polishing `γ` (see [`plane_pair`]).
const GAMMA_POLISH_STEPS: usize = 4;
/// Two depth triples this close (relative) are the same root.
const DUPLICATE_DEPTH_TOLERANCE: f64 = 1e-7;
/// `Y X⁻¹` (eq. 20) must be a rotation to this accuracy (`‖MᵀM − I‖`):
/// depths that do not make the camera-frame triangle congruent to the
/// object triangle are not a pose.
pub const ORTHOGONALITY_TOLERANCE: f64 = 1e-6;
/// A candidate is kept only if it reproduces every squared distance to
/// this relative accuracy: the roots of a near-degenerate configuration can
/// be meaningless, and this is what they must reach to count as poses.
pub const DISTANCE_TOLERANCE: f64 = 1e-9;

/// Every pose for three object points and their three normalised image
/// points, after checking the input.
///
/// Errors: a non-finite coordinate, coincident object points, collinear
/// object points, coincident or collinear image points.
pub fn solve(
    object: &[Vector3<f64>; 3],
    image: &[Vector2<f64>; 3],
) -> Result<P3pCandidates, PnpError> {
    check_finite(object, image)?;
    for (first, second) in [(0, 1), (0, 2), (1, 2)] {
        if object[first] == object[second] {
            return Err(PnpError::DuplicatePoints { first, second });
        }
    }
    if !spans_triangle(object) {
        return Err(PnpError::Collinear);
    }
    if image[0] == image[1] && image[1] == image[2] {
        return Err(PnpError::CoincidentImagePoints);
    }
    let bearings = image.map(|m| Vector3::new(m.x, m.y, 1.0).normalize());
    if !bearings_span_space(&bearings) {
        return Err(PnpError::CollinearImagePoints);
    }
    let mut poses = P3pCandidates::new();
    solve_bearings(object, &bearings, &mut poses);
    Ok(poses)
}

/// Whether three object points span a triangle (not collinear within
/// [`COLLINEAR_TOLERANCE`]).
pub fn spans_triangle(object: &[Vector3<f64>; 3]) -> bool {
    let e1 = object[1] - object[0];
    let e2 = object[2] - object[0];
    let longest_sq = e1
        .norm_squared()
        .max(e2.norm_squared())
        .max((object[2] - object[1]).norm_squared());
    e1.cross(&e2).norm() > COLLINEAR_TOLERANCE * longest_sq
}

/// Whether three unit bearings span space (the image points are neither
/// collinear nor coincident, within [`COPLANAR_BEARINGS_TOLERANCE`]).
pub fn bearings_span_space(bearings: &[Vector3<f64>; 3]) -> bool {
    bearings[0].cross(&bearings[1]).dot(&bearings[2]).abs() > COPLANAR_BEARINGS_TOLERANCE
}

/// The hot-path form of [`solve`]: unit `bearings`, no input checks;
/// appends the poses to `out` (cleared first). Degenerate input (collinear
/// object points, coplanar bearings) gives no pose, never a non-finite one.
pub fn solve_bearings(
    object: &[Vector3<f64>; 3],
    bearings: &[Vector3<f64>; 3],
    out: &mut P3pCandidates,
) {
    out.clear();
    let [y1, y2, y3] = bearings;
    let b12 = y1.dot(y2);
    let b13 = y1.dot(y3);
    let b23 = y2.dot(y3);
    let a12 = (object[0] - object[1]).norm_squared();
    let a13 = (object[0] - object[2]).norm_squared();
    let a23 = (object[1] - object[2]).norm_squared();
    if !(a12 > 0.0 && a13 > 0.0 && a23 > 0.0) {
        return;
    }
    // The quadrics of eq. 5.
    let m12 = Matrix3::new(1.0, -b12, 0.0, -b12, 1.0, 0.0, 0.0, 0.0, 0.0);
    let m13 = Matrix3::new(1.0, 0.0, -b13, 0.0, 0.0, 0.0, -b13, 0.0, 1.0);
    let m23 = Matrix3::new(0.0, 0.0, 0.0, 0.0, 1.0, -b23, 0.0, -b23, 1.0);
    let d1 = m12 * a23 - m23 * a12;
    let d2 = m13 * a23 - m23 * a13;
    // Of the (up to three) degenerate members of the pencil, the one whose
    // line pair is real and best separated.
    let Some(planes) = degenerate_combinations(&d1, &d2)
        .iter()
        .filter_map(|&gamma| plane_pair(&d1, &d2, gamma))
        .max_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(planes, _)| planes)
    else {
        return;
    };
    // Inverse of the object triangle frame (eq. 20), shared by every root.
    let x_edge1 = object[0] - object[1];
    let x_edge2 = object[0] - object[2];
    let x_frame = Matrix3::from_columns(&[x_edge1, x_edge2, x_edge1.cross(&x_edge2)]);
    let Some(x_inverse) = x_frame.try_inverse() else {
        return;
    };
    let distances = [a12, a13, a23];
    let cosines = [b12, b13, b23];
    let mut depths: SmallVec<[Vector3<f64>; 4]> = SmallVec::new();
    for normal in planes {
        // An orthonormal basis (u, v) of the plane normal·Λ = 0.
        let Some(normal) = normal.try_normalize(f64::MIN_POSITIVE) else {
            continue;
        };
        let helper = if normal.x.abs() < 0.6 {
            Vector3::x()
        } else {
            Vector3::y()
        };
        let u = normal.cross(&helper).normalize();
        let v = normal.cross(&u);
        let basis = nalgebra::Matrix3x2::from_columns(&[u, v]);
        let q12: Matrix2<f64> = basis.transpose() * m12 * basis;
        let q13: Matrix2<f64> = basis.transpose() * m13 * basis;
        let q23: Matrix2<f64> = basis.transpose() * m23 * basis;
        // Λ on the plane with two of the distance equations holding: a
        // homogeneous quadratic. Each pair is solved, since one can be
        // nearly a double root (ill-conditioned) where another is not;
        // duplicates are dropped below.
        let pairs = [
            q12 * a23 - q23 * a12,
            q13 * a23 - q23 * a13,
            q12 * a13 - q13 * a12,
        ];
        let directions = pairs
            .iter()
            .flat_map(|h| homogeneous_quadratic_roots(h[(0, 0)], h[(0, 1)], h[(1, 1)]));
        for direction in directions {
            let lambda_direction = basis * direction;
            let scale_sq = lambda_direction.dot(&(m23 * lambda_direction));
            if !(scale_sq > 0.0) {
                continue;
            }
            let mut lambda = lambda_direction * (a23 / scale_sq).sqrt();
            if lambda.iter().all(|l| *l < 0.0) {
                lambda = -lambda;
            }
            if !lambda.iter().all(|l| *l > 0.0) {
                continue;
            }
            refine_depths(&mut lambda, &cosines, &distances);
            if !lambda.iter().all(|l| *l > 0.0 && l.is_finite())
                || !reproduces_distances(&lambda, &cosines, &distances)
            {
                continue;
            }
            let camera = [y1 * lambda.x, y2 * lambda.y, y3 * lambda.z];
            let y_edge1 = camera[0] - camera[1];
            let y_edge2 = camera[0] - camera[2];
            let y_frame = Matrix3::from_columns(&[y_edge1, y_edge2, y_edge1.cross(&y_edge2)]);
            let raw_rotation = y_frame * x_inverse;
            if !((raw_rotation.transpose() * raw_rotation - Matrix3::identity()).norm()
                <= ORTHOGONALITY_TOLERANCE)
            {
                continue;
            }
            let rotation = nearest_rotation(&raw_rotation);
            let object_centroid = (object[0] + object[1] + object[2]) / 3.0;
            let camera_centroid = (camera[0] + camera[1] + camera[2]) / 3.0;
            let pose = Pose::new(rotation, camera_centroid - rotation * object_centroid);
            let duplicate = depths.iter().any(|d: &Vector3<f64>| {
                (d - lambda).amax() <= DUPLICATE_DEPTH_TOLERANCE * lambda.amax()
            });
            if pose.is_finite()
                && object.iter().all(|p| pose.transform(p).z > 0.0)
                && !duplicate
                && out.len() < out.inline_size()
            {
                depths.push(lambda);
                out.push(pose);
            }
        }
    }
}

/// Every real root `γ` of `det(D_1 + γ D_2)` (eq. 9),
/// each polished by Newton steps, plus `None` (`D_2` itself) when the cubic has lost
/// its leading term (`det D_2 = 0`, a root at infinity). The paper takes one
/// root; with only two real solutions some roots give a pair of complex
/// planes, so every root is offered and [`plane_pair`] scores them.
fn degenerate_combinations(d1: &Matrix3<f64>, d2: &Matrix3<f64>) -> SmallVec<[Option<f64>; 3]> {
    let mut out = SmallVec::new();
    // det(A + γB) = det A + γ tr(adj(A) B) + γ² tr(A adj(B)) + γ³ det B.
    let adjugate = |m: &Matrix3<f64>| -> Matrix3<f64> {
        let c0 = m.column(0);
        let c1 = m.column(1);
        let c2 = m.column(2);
        // Rows of the adjugate are the cross products of column pairs.
        Matrix3::from_rows(&[
            c1.cross(&c2).transpose(),
            c2.cross(&c0).transpose(),
            c0.cross(&c1).transpose(),
        ])
    };
    let c0 = d1.determinant();
    let c1 = (adjugate(d1) * d2).trace();
    let c2 = (d1 * adjugate(d2)).trace();
    let c3 = d2.determinant();
    let Some(cubic) = Polynomial::new(&[c0, c1, c2, c3]) else {
        return out;
    };
    if cubic.degree() < 3 {
        out.push(None);
    }
    for mut gamma in cubic.real_roots() {
        for _ in 0..2 {
            let (value, slope) = cubic.eval_with_derivative(gamma);
            if slope != 0.0 {
                let next = gamma - value / slope;
                if next.is_finite() && cubic.eval(next).abs() < value.abs() {
                    gamma = next;
                }
            }
        }
        if out.len() < 3 {
            out.push(Some(gamma));
        }
    }
    out
}

/// The two planes (normals) into which the singular symmetric form `Λᵀ D Λ`
/// factors, or `None` when it does not factor into real planes (its two
/// non-zero eigenvalues share a sign). With eigenvalues `σ_p > 0 > σ_n`
/// and the third zero, `σ_p p² + σ_n n² = 0` (`p`, `n` the coordinates
/// along their eigenvectors) splits into `p = ±s n`, `s = √(−σ_n/σ_p)`
/// (eqs. 12–15).
///
/// The `γ` of the cubic makes `D` singular only to the precision of a 3×3
/// determinant, about `ε ‖D‖³`; when `D` has one large eigenvalue (far
/// field) that leaves the "zero" eigenvalue comparable with the small
/// non-zero one and the planes a percent off. So `γ` is first polished by
/// Newton's method on the eigenvalue nearest zero, whose derivative in `γ`
/// is `eᵀ D_2 e` (Hellmann–Feynman), until that eigenvalue is at rounding
/// level. The score, the smaller over the larger magnitude of the two
/// non-zero eigenvalues, is near 0 when the pair is ill-determined.
fn plane_pair(
    d1: &Matrix3<f64>,
    d2: &Matrix3<f64>,
    gamma: Option<f64>,
) -> Option<([Vector3<f64>; 2], f64)> {
    let combination = |gamma: Option<f64>| match gamma {
        Some(gamma) => d1 + d2 * gamma,
        None => *d2,
    };
    let nearest_zero = |values: &Vector3<f64>| -> usize {
        (0..3)
            .min_by(|&a, &b| values[a].abs().total_cmp(&values[b].abs()))
            .unwrap_or(0)
    };
    let mut gamma = gamma;
    let mut eigen = combination(gamma).symmetric_eigen();
    if let Some(mut g) = gamma {
        for _ in 0..GAMMA_POLISH_STEPS {
            let k = nearest_zero(&eigen.eigenvalues);
            // Done when the "zero" is negligible beside the smaller non-zero
            // eigenvalue (the usual case: no extra decomposition).
            let smaller_nonzero = eigen.eigenvalues[(k + 1) % 3]
                .abs()
                .min(eigen.eigenvalues[(k + 2) % 3].abs());
            if eigen.eigenvalues[k].abs() <= SETTLED_ZERO * smaller_nonzero {
                break;
            }
            let e = eigen.eigenvectors.column(k).into_owned();
            let slope = e.dot(&(d2 * e));
            if slope == 0.0 || !slope.is_finite() {
                break;
            }
            let next = g - eigen.eigenvalues[k] / slope;
            if !next.is_finite() {
                break;
            }
            let next_eigen = (d1 + d2 * next).symmetric_eigen();
            let next_k = nearest_zero(&next_eigen.eigenvalues);
            if next_eigen.eigenvalues[next_k].abs() >= eigen.eigenvalues[k].abs() {
                break;
            }
            g = next;
            eigen = next_eigen;
        }
        gamma = Some(g);
    }
    let _ = gamma;
    let k = nearest_zero(&eigen.eigenvalues);
    let (i, j) = ((k + 1) % 3, (k + 2) % 3);
    let (si, sj) = (eigen.eigenvalues[i], eigen.eigenvalues[j]);
    let larger = si.abs().max(sj.abs());
    if !(larger > 0.0) {
        return None;
    }
    let ei = eigen.eigenvectors.column(i).into_owned();
    let ej = eigen.eigenvectors.column(j).into_owned();
    let smaller = si.abs().min(sj.abs());
    if smaller <= ROUNDING_TOLERANCE * larger {
        // Rank one: σ p² = 0, a double plane.
        let normal = if si.abs() >= sj.abs() { ei } else { ej };
        return Some(([normal, normal], 0.0));
    }
    if !(si * sj < 0.0) {
        return None;
    }
    let (positive, negative, e_positive, e_negative) = if si > 0.0 {
        (si, sj, ei, ej)
    } else {
        (sj, si, ej, ei)
    };
    let s = (-negative / positive).sqrt();
    Some((
        [e_positive - e_negative * s, e_positive + e_negative * s],
        smaller / larger,
    ))
}

/// Unit directions `(α, β)` with `h11 α² + 2 h12 αβ + h22 β² = 0`: none,
/// or two (one for a double root).
fn homogeneous_quadratic_roots(h11: f64, h12: f64, h22: f64) -> SmallVec<[Vector2<f64>; 2]> {
    let mut roots = SmallVec::new();
    let discriminant = h12 * h12 - h11 * h22;
    // A double root blurred by rounding is still a root.
    if !(discriminant >= -ROUNDING_TOLERANCE * (h12 * h12 + (h11 * h22).abs())) {
        return roots;
    }
    let root = discriminant.max(0.0).sqrt();
    // Solve for the ratio over the coordinate with the larger coefficient,
    // in the cancellation-free form.
    let q = -(h12 + h12.signum() * root);
    if h11.abs() >= h22.abs() {
        // h11 r² + 2 h12 r + h22 = 0 in r = α/β.
        if h11 == 0.0 {
            return roots;
        }
        let r1 = q / h11;
        roots.push(Vector2::new(r1, 1.0).normalize());
        if q != 0.0 && root > 0.0 {
            roots.push(Vector2::new(h22 / q, 1.0).normalize());
        }
    } else {
        // h22 r² + 2 h12 r + h11 = 0 in r = β/α.
        let r1 = q / h22;
        roots.push(Vector2::new(1.0, r1).normalize());
        if q != 0.0 && root > 0.0 {
            roots.push(Vector2::new(1.0, h11 / q).normalize());
        }
    }
    roots
}

/// Residuals `λ_i² + λ_j² − 2 b_ij λ_i λ_j − a_ij` for (12, 13, 23).
fn distance_residuals(
    lambda: &Vector3<f64>,
    cosines: &[f64; 3],
    distances: &[f64; 3],
) -> Vector3<f64> {
    let (l1, l2, l3) = (lambda.x, lambda.y, lambda.z);
    Vector3::new(
        l1 * l1 + l2 * l2 - 2.0 * cosines[0] * l1 * l2 - distances[0],
        l1 * l1 + l3 * l3 - 2.0 * cosines[1] * l1 * l3 - distances[1],
        l2 * l2 + l3 * l3 - 2.0 * cosines[2] * l2 * l3 - distances[2],
    )
}

/// Newton's method on the three distance equations (§3.5). In the far
/// field the plane of a nearly rank-one `D_0` is poorly determined and a
/// root can start well off; [`reproduces_distances`] drops what the
/// iteration cannot bring home.
fn refine_depths(lambda: &mut Vector3<f64>, cosines: &[f64; 3], distances: &[f64; 3]) {
    let mut residual = distance_residuals(lambda, cosines, distances);
    let mut size = residual.norm_squared();
    let mut best = *lambda;
    for _ in 0..DEPTH_REFINEMENT_STEPS {
        if size == 0.0 {
            break;
        }
        let (l1, l2, l3) = (lambda.x, lambda.y, lambda.z);
        let jacobian = Matrix3::new(
            2.0 * (l1 - cosines[0] * l2),
            2.0 * (l2 - cosines[0] * l1),
            0.0,
            2.0 * (l1 - cosines[1] * l3),
            0.0,
            2.0 * (l3 - cosines[1] * l1),
            0.0,
            2.0 * (l2 - cosines[2] * l3),
            2.0 * (l3 - cosines[2] * l2),
        );
        let Some(inverse) = jacobian.try_inverse() else {
            break;
        };
        // Full Newton steps, as the paper's and PoseLib's refinements take:
        // the residual may rise on the way into the quadratic basin. The
        // best iterate is kept.
        let next = *lambda - inverse * residual;
        let next_residual = distance_residuals(&next, cosines, distances);
        let next_size = next_residual.norm_squared();
        if !next_size.is_finite() {
            break;
        }
        *lambda = next;
        residual = next_residual;
        if next_size < size {
            size = next_size;
            best = *lambda;
        }
    }
    *lambda = best;
}

fn reproduces_distances(lambda: &Vector3<f64>, cosines: &[f64; 3], distances: &[f64; 3]) -> bool {
    let residual = distance_residuals(lambda, cosines, distances);
    (0..3).all(|k| residual[k].abs() <= DISTANCE_TOLERANCE * distances[k])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pose::rotation_error_deg;
    use crate::synthetic::{random_points, random_pose, stream_rng, uniform_rotation};
    use proptest::prelude::*;
    use rand::Rng;

    fn project(truth: &Pose, object: &[Vector3<f64>; 3]) -> [Vector2<f64>; 3] {
        object.map(|p| truth.project_normalised(&p))
    }

    /// The smallest rotation (degrees) and relative translation errors over
    /// the candidates.
    fn closest(poses: &P3pCandidates, truth: &Pose) -> (f64, f64) {
        poses
            .iter()
            .map(|pose| {
                (
                    rotation_error_deg(&truth.rotation, &pose.rotation),
                    (pose.translation - truth.translation).norm() / truth.translation.norm(),
                )
            })
            .fold((f64::INFINITY, f64::INFINITY), |(r, t), (pr, pt)| {
                if pr < r {
                    (pr, pt)
                } else {
                    (r, t)
                }
            })
    }

    fn triple(points: &[Vector3<f64>]) -> [Vector3<f64>; 3] {
        [points[0], points[1], points[2]]
    }

    /// Noise-free random triples, near and far field: the true pose is
    /// among the candidates to 1e-5° (the worst of 4000 draws is printed).
    #[test]
    fn recovers_the_true_pose_among_the_candidates() {
        let mut worst = 0.0f64;
        let mut solved = 0;
        for case in 0..4000u64 {
            let mut rng = stream_rng(17, 0x93, case);
            let object = triple(&random_points(&mut rng, 3, 100.0));
            if !spans_triangle(&object) {
                continue;
            }
            // Depth/size from 1.5 (strong perspective) to 100 (far field).
            let depth = 150.0 * (1.0 + 66.0 * rng.random::<f64>().powi(2));
            let truth = random_pose(&mut rng, depth, 0.3);
            if object.iter().any(|p| truth.transform(p).z < 20.0) {
                continue;
            }
            let image = project(&truth, &object);
            let poses = solve(&object, &image).unwrap();
            assert!(poses.len() <= 4);
            let (rotation_deg, translation) = closest(&poses, &truth);
            worst = worst.max(rotation_deg);
            assert!(
                rotation_deg < 1e-5 && translation < 1e-7,
                "case {case}: {rotation_deg}° {translation} over {} candidates",
                poses.len()
            );
            solved += 1;
        }
        assert!(solved > 3500, "{solved}");
        eprintln!("P3P worst rotation error over {solved} triples: {worst:e}°");
    }

    /// Near-degenerate draws: thin triangles (aspect 1e-3), tiny images
    /// (depth/size 100) and a camera near the triangle's plane still
    /// recover the pose, to a tolerance that grows with the conditioning.
    #[test]
    fn near_degenerate_triples() {
        for case in 0..600u64 {
            let mut rng = stream_rng(17, 0x94, case);
            let kind = case % 3;
            let base = random_points(&mut rng, 2, 100.0);
            let (object, depth) = match kind {
                0 => {
                    // Thin triangle: third point 1e-3 of the edge off the line.
                    let edge = base[1] - base[0];
                    let off = edge.cross(&Vector3::new(0.3, -0.5, 0.8)).normalize() * edge.norm();
                    ([base[0], base[1], base[0] + edge * 0.4 + off * 1e-3], 400.0)
                }
                1 => (triple(&random_points(&mut rng, 3, 100.0)), 1e4),
                _ => (triple(&random_points(&mut rng, 3, 100.0)), 300.0),
            };
            if !spans_triangle(&object) {
                continue;
            }
            let mut truth = random_pose(&mut rng, depth, 0.2);
            if kind == 2 {
                // Turn the triangle almost edge-on (normal 5° off perpendicular to the view).
                let normal = (object[1] - object[0])
                    .cross(&(object[2] - object[0]))
                    .normalize();
                let view = (truth.rotation.inverse() * Vector3::z()).normalize();
                let axis = normal.cross(&view);
                if let Some(axis) = axis.try_normalize(1e-9) {
                    let angle = normal.dot(&view).acos() - (90.0f64 - 5.0).to_radians();
                    let turn = nalgebra::Rotation3::from_axis_angle(
                        &nalgebra::Unit::new_normalize(axis),
                        angle,
                    );
                    truth.rotation *= turn;
                }
            }
            if object.iter().any(|p| truth.transform(p).z < 20.0) {
                continue;
            }
            let image = project(&truth, &object);
            let Ok(poses) = solve(&object, &image) else {
                continue;
            };
            let (rotation_deg, _) = closest(&poses, &truth);
            assert!(
                rotation_deg < 1e-4,
                "kind {kind} case {case}: {rotation_deg}° {:?} {truth:?} {object:?}",
                poses
                    .iter()
                    .map(|p| rotation_error_deg(&truth.rotation, &p.rotation))
                    .collect::<Vec<_>>()
            );
        }
    }

    #[test]
    fn degenerate_input_is_refused() {
        let object = [
            Vector3::new(0.0, 0.0, 0.0),
            Vector3::new(10.0, 0.0, 0.0),
            Vector3::new(0.0, 10.0, 5.0),
        ];
        let image = [
            Vector2::new(0.0, 0.0),
            Vector2::new(0.1, 0.0),
            Vector2::new(0.0, 0.1),
        ];
        let line = [object[0], object[1], object[1] * 2.0];
        assert_eq!(solve(&line, &image).unwrap_err(), PnpError::Collinear);
        let dup = [object[0], object[1], object[1]];
        assert_eq!(
            solve(&dup, &image).unwrap_err(),
            PnpError::DuplicatePoints {
                first: 1,
                second: 2
            }
        );
        let same = [image[0]; 3];
        assert_eq!(
            solve(&object, &same).unwrap_err(),
            PnpError::CoincidentImagePoints
        );
        let on_line = [image[0], image[1], image[1] * 3.0];
        assert_eq!(
            solve(&object, &on_line).unwrap_err(),
            PnpError::CollinearImagePoints
        );
        let mut nan = image;
        nan[2].y = f64::NAN;
        assert_eq!(
            solve(&object, &nan).unwrap_err(),
            PnpError::NonFinite {
                kind: "image",
                index: 2
            }
        );
        let mut inf = object;
        inf[0].x = f64::INFINITY;
        assert_eq!(
            solve(&inf, &image).unwrap_err(),
            PnpError::NonFinite {
                kind: "object",
                index: 0
            }
        );
        // The unchecked form gives no pose rather than garbage.
        let bearings = on_line.map(|m| Vector3::new(m.x, m.y, 1.0).normalize());
        let mut out = P3pCandidates::new();
        solve_bearings(&object, &bearings, &mut out);
        assert!(out.iter().all(|p| p.is_finite()));
        solve_bearings(
            &line,
            &image.map(|m| Vector3::new(m.x, m.y, 1.0).normalize()),
            &mut out,
        );
        assert!(out.is_empty());
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(256))]
        /// Invariants on arbitrary triples and views: at most four poses,
        /// each finite, a rotation, with the three points in front, and each
        /// maps the points onto their image rays.
        #[test]
        fn candidates_are_valid_poses(seed in 0u64..1_000_000, depth in 50.0f64..5000.0) {
            let mut rng = stream_rng(seed, 0x95, 0);
            let object = triple(&random_points(&mut rng, 3, 100.0));
            let truth = Pose::new(uniform_rotation(&mut rng), Vector3::new(
                rng.random_range(-0.3..0.3) * depth, rng.random_range(-0.3..0.3) * depth, depth));
            prop_assume!(object.iter().all(|p| truth.transform(p).z > 1.0));
            let image = project(&truth, &object);
            if let Ok(poses) = solve(&object, &image) {
                prop_assert!(poses.len() <= 4);
                for pose in &poses {
                    prop_assert!(pose.is_finite());
                    let r = pose.rotation.matrix();
                    prop_assert!((r.transpose() * r - Matrix3::identity()).norm() < 1e-9);
                    prop_assert!((r.determinant() - 1.0).abs() < 1e-9);
                    for (p, m) in object.iter().zip(&image) {
                        let c = pose.transform(p);
                        prop_assert!(c.z > 0.0);
                        let bearing = Vector3::new(m.x, m.y, 1.0).normalize();
                        // Angle between the ray and the transformed point.
                        prop_assert!(c.normalize().cross(&bearing).norm() < 1e-6, "{}", c.normalize().cross(&bearing).norm());
                    }
                }
            }
        }
    }
}
