//! SQPnP: Terzakis & Lourakis, "A Consistently Fast and Globally Optimal
//! Solution to the Perspective-n-Point Problem", ECCV 2020.
//!
//! **Cost.** With `r = vec(R)` row-major, `R X_i = A_i r`
//! where `A_i = I₃ ⊗ X_iᵀ`. The error of point i is
//! `‖[I₂ | −m_i] (A_i r + t)‖²`, i.e. `(A_i r + t)ᵀ Q_i (A_i r + t)` with
//! `Q_i = [1 0 −x; 0 1 −y; −x −y x²+y²]` (the projection error scaled by
//! depth). The translation minimising the sum is linear in r,
//! `t = P r` with `P = −(Σ Q_i)⁻¹ Σ Q_i A_i`, and eliminating it
//! leaves the quadratic program
//! `min rᵀ Ω r` subject to `R ∈ SO(3)`, with
//! `Ω = Σ A_iᵀ Q_i A_i + (Σ Q_i A_i)ᵀ P`, a 9×9 positive
//! semidefinite matrix.
//!
//! **Starts.** Each eigenvector `e` of Ω whose eigenvalue
//! is below [`RANK_TOLERANCE`] (at least the smallest one) gives a start:
//! if `√3 e` is already orthogonal (to [`ORTHOGONALITY_SQUARED_ERROR_THRESHOLD`])
//! it is the solution up to the sign of its determinant; otherwise SQP runs
//! from the nearest rotations to both `√3 e` and `−√3 e`. Further
//! eigenvectors, in increasing order of eigenvalue, are tried (both signs)
//! while the best error found exceeds three times their eigenvalue: the
//! regions they seed may hold a lower minimum.
//!
//! **SQP.** At `r` the six orthonormality constraints
//! `h(r) = 0` are linearised; the step satisfies them to first order and
//! minimises the cost over what they leave free (three directions). Iterate
//! until `‖δ‖²` falls below [`SQP_SQUARED_TOLERANCE`] or
//! [`SQP_MAX_ITERATIONS`] steps. The step is the paper's; only the basis it
//! is computed in differs: with `mat(δ) = W R⁻ᵀ` the linearised constraints
//! fix the symmetric part of W, `−½ (R Rᵀ − I)`, and leave its skew part
//! free, so no Gram–Schmidt is needed.
//!
//! Every distinct minimum that passes the cheirality test (centroid in
//! front, or a majority of points in front, as in the reference code) is
//! returned, not only the global one.
//!
//! **Coplanar points** need no special case: Ω then has a larger null space
//! and every null vector seeds a start. The method needs ≥ 3 points; like
//! every solver here it is given ≥ 4.
//!
//! Deviations from OpenCV's `sqpnp.cpp` (which follows the authors' code):
//! - a start that is already a rotation is polished by SQP rather than taken
//!   as is (see [`OrthogonalStart`]; [`solve_with`] can do either);
//! - the object points are centred and scaled to unit RMS radius before Ω is
//!   built, so the absolute tolerances below (the reference values, tuned for
//!   unit-scale data) mean the same in any unit;
//! - every SQP result is projected onto SO(3) (the reference skips that when
//!   its determinant is within 1.01), because a [`Pose`] holds an exact
//!   rotation;
//! - all local minima are returned, not only those within 1e-6 of the
//!   lowest error;
//! - the SQP step is computed in the basis `W R⁻ᵀ` (the same step, without
//!   Gram–Schmidt);
//! - the image-point variance guard is [`IMAGE_VARIANCE_TOLERANCE`], far
//!   below OpenCV's 1e-5, which would reject objects more than ~100 sizes
//!   away;
//! - only the eigenpairs of Ω that a solve reads are computed (the five
//!   smallest up front, the rest on demand; `OmegaEigen`) where the
//!   reference decomposes Ω fully (SVD, or rank-revealing QR in its 2024
//!   version);
//! - the square-root-free `L D Lᵀ` solve of the 3×3 reduced system is the
//!   2022 reference's; its LU fallback is not needed because the reduced
//!   Hessian is positive definite whenever the step is defined (otherwise
//!   SQP stops, as before).
//!
//! **Speed** (n = 7, σ = 0.5 px, far field 20–200 sizes away, where a
//! solve runs ~6 SQP starts of ~7 steps): the step works on the sparse
//! null-space basis ([`SqpnpSystem::run_sqp`]), every projection onto SO(3)
//! uses FOAM whatever the sign of the determinant
//! ([`crate::pose::nearest_rotation`]), and Ω's eigenpairs come from
//! [`smallest_eigenpairs`]; together 13.6 → 8.2 µs median
//! (`cargo run --release --features examples --example baseline_timing`).
//!
//! Equation numbers are not cited: this follows the reference code, read
//! for understanding, and the paper's description of it.

use super::{Candidates, Method, PnpError};
use crate::linalg::{smallest_eigenpairs, solve_positive_definite, SmallestEigenpairs};
use crate::pose::nearest_rotation;
use crate::pose::Pose;
use nalgebra::{Matrix3, Rotation3, SMatrix, SVector, SymmetricEigen, Vector2, Vector3};
use smallvec::SmallVec;

/// The method's name in messages.
const NAME: &str = "SQPnP";
/// Eigenvalues of Ω below this count as zero (reference value: 1e-7).
pub const RANK_TOLERANCE: f64 = 1e-7;
/// SQP stops when the squared step norm falls below this (reference value: 1e-10).
pub const SQP_SQUARED_TOLERANCE: f64 = 1e-10;
/// Upper bound on SQP steps per start (reference value: 15).
pub const SQP_MAX_ITERATIONS: usize = 15;
/// A start `√3 e` with squared orthogonality error below this is taken as a
/// rotation (OpenCV: 1e-8; see [`OrthogonalStart`]).
pub const ORTHOGONALITY_SQUARED_ERROR_THRESHOLD: f64 = 1e-8;
/// Two solutions whose `r` differ by less than this (squared) are one
/// (OpenCV: 1e-10).
pub const EQUAL_VECTORS_SQUARED_DIFF: f64 = 1e-10;
/// More than six null vectors means the data fix nothing (OpenCV asserts it).
pub const MAX_NULL_VECTORS: usize = 6;
/// Variance of the normalised image points below which `Σ Q_i` is singular
/// (all image points coincide).
pub const IMAGE_VARIANCE_TOLERANCE: f64 = 1e-14;

type Vector9 = SVector<f64, 9>;
type Matrix9 = SMatrix<f64, 9, 9>;

/// `r = vec(R)`, row-major.
#[inline]
fn vec_row_major(m: &Matrix3<f64>) -> Vector9 {
    Vector9::from_fn(|k, _| m[(k / 3, k % 3)])
}

/// The matrix of a row-major `r`.
#[inline]
fn mat_row_major(r: &Vector9) -> Matrix3<f64> {
    Matrix3::from_fn(|i, j| r[3 * i + j])
}

/// `Σ (r_aᵀ r_a − 1)² + 2 Σ_{a<b} (r_aᵀ r_b)²` over the rows r_a: the squared
/// Frobenius norm of `R Rᵀ − I`.
fn orthogonality_squared_error(r: &Vector9) -> f64 {
    let m = mat_row_major(r);
    (m * m.transpose() - Matrix3::identity()).norm_squared()
}

/// The data of one problem: Ω, the translation map P and the normalisation.
#[derive(Debug, Clone)]
pub struct SqpnpSystem {
    omega: Matrix9,
    translation_map: SMatrix<f64, 3, 9>,
    centroid: Vector3<f64>,
    scale: f64,
}

impl SqpnpSystem {
    /// Builds Ω and P from the points, after centring the
    /// object points and scaling them to unit RMS radius.
    pub fn new(object: &[Vector3<f64>], image: &[Vector2<f64>]) -> Result<Self, PnpError> {
        let count = object.len() as f64;
        let (centroid, scale) = super::centroid_and_rms_radius(object);
        let mut sum_q = Matrix3::zeros();
        let mut sum_qa = SMatrix::<f64, 3, 9>::zeros();
        let mut omega = Matrix9::zeros();
        for (p, m) in object.iter().zip(image) {
            let x = (p - centroid) / scale;
            let q = Matrix3::new(
                1.0,
                0.0,
                -m.x,
                0.0,
                1.0,
                -m.y,
                -m.x,
                -m.y,
                m.x * m.x + m.y * m.y,
            );
            let outer = x * x.transpose();
            sum_q += q;
            // Q_i A_i: block (a, b) is q_ab xᵀ; A_iᵀ Q_i A_i = Q_i ⊗ x xᵀ.
            for a in 0..3 {
                for b in 0..3 {
                    let q_ab = q[(a, b)];
                    if q_ab == 0.0 {
                        continue;
                    }
                    for k in 0..3 {
                        sum_qa[(a, 3 * b + k)] += q_ab * x[k];
                    }
                    let mut block = omega.fixed_view_mut::<3, 3>(3 * a, 3 * b);
                    block += outer * q_ab;
                }
            }
        }
        let image_variance = sum_q.determinant() / count.powi(3);
        if image_variance.is_nan() || image_variance <= IMAGE_VARIANCE_TOLERANCE {
            return Err(PnpError::Degenerate {
                solver: NAME,
                reason: "the image points have no spread",
            });
        }
        let inverse = sum_q.try_inverse().ok_or(PnpError::Degenerate {
            solver: NAME,
            reason: "the image points have no spread",
        })?;
        let translation_map = -(inverse * sum_qa);
        omega += sum_qa.transpose() * translation_map;
        let omega = 0.5 * (omega + omega.transpose());
        Ok(Self {
            omega,
            translation_map,
            centroid,
            scale,
        })
    }

    /// The 9×9 matrix Ω (in the normalised object frame).
    pub fn omega(&self) -> &Matrix9 {
        &self.omega
    }

    /// The cost `rᵀ Ω r` of a row-major rotation vector.
    #[inline]
    pub fn cost(&self, r: &Vector9) -> f64 {
        r.dot(&(self.omega * r))
    }

    /// The pose for a rotation, with its optimal translation `t = P r`,
    /// mapped back from the normalised object frame.
    pub fn pose(&self, rotation: &Rotation3<f64>) -> Pose {
        let normalised = self.translation_map * vec_row_major(rotation.matrix());
        Pose::new(
            *rotation,
            normalised * self.scale - rotation * self.centroid,
        )
    }

    /// Sequential quadratic programming from the rotation `start`.
    /// Returns the final rotation (projected onto SO(3)).
    pub fn run_sqp(&self, start: &Rotation3<f64>) -> Rotation3<f64> {
        let mut r = vec_row_major(start.matrix());
        for _ in 0..SQP_MAX_ITERATIONS {
            let Some(step) = self.sqp_step(&r) else {
                break;
            };
            r += step;
            if step.norm_squared() < SQP_SQUARED_TOLERANCE {
                break;
            }
        }
        let mut m = mat_row_major(&r);
        if m.determinant() < 0.0 {
            m = -m;
        }
        nearest_rotation(&m)
    }

    /// One SQP step δ at r, or `None` if R is singular or the
    /// reduced Hessian `Nᵀ Ω N` is not positive definite.
    ///
    /// The step solves the linearised constraints `J δ = −h(r)` and, within
    /// that affine set, minimises `(r + δ)ᵀ Ω (r + δ)`. The paper (and the
    /// reference code) parameterise the set with an orthonormal basis H of
    /// J's row space and N of its null space, found by Gram–Schmidt. The
    /// minimiser does not depend on the basis, and a cheaper one exists:
    /// writing `mat(δ) = W R⁻ᵀ` makes `r_c · δ_a = W_ac`, so the six
    /// linearised constraints fix the symmetric part of W,
    /// `W_sym = −½ (R Rᵀ − I)`, and leave its skew part `[ω]×` free. Hence
    /// `δ = vec((−½ (R Rᵀ − I) + [ω]×) R⁻ᵀ)`, with the null-space basis
    /// `N = [vec([e_k]× R⁻ᵀ)]` and ω from `(Nᵀ Ω N) ω = −Nᵀ Ω (r + δ_p)`.
    ///
    /// With `s_a` the rows of `S = R⁻ᵀ`, the rows of `[e_k]× S` are
    /// `(0, −s₂, s₁)`, `(s₂, 0, −s₀)` and `(−s₁, s₀, 0)`: each null-space
    /// column has six non-zero entries, so `Ω N` costs six 9×3 by 3
    /// products (`Ω_{·b} s_c` for the six pairs `b ≠ c`) rather than a
    /// dense 9×9 by 9×3 one.
    fn sqp_step(&self, r: &Vector9) -> Option<Vector9> {
        let row = |a: usize| Vector3::new(r[3 * a], r[3 * a + 1], r[3 * a + 2]);
        let (r0, r1, r2) = (row(0), row(1), row(2));
        // S = R⁻ᵀ = cofactor(R) / det R, row by row.
        let cofactor = [r1.cross(&r2), r2.cross(&r0), r0.cross(&r1)];
        let determinant = r0.dot(&cofactor[0]);
        if determinant == 0.0 || !determinant.is_finite() {
            return None;
        }
        let inverse_determinant = determinant.recip();
        let s = cofactor.map(|c| c * inverse_determinant);
        // Particular part: rows of −½ (R Rᵀ − I) S.
        let gram = [
            [r0.dot(&r0) - 1.0, r0.dot(&r1), r0.dot(&r2)],
            [r0.dot(&r1), r1.dot(&r1) - 1.0, r1.dot(&r2)],
            [r0.dot(&r2), r1.dot(&r2), r2.dot(&r2) - 1.0],
        ];
        let mut particular = Vector9::zeros();
        for (a, g) in gram.iter().enumerate() {
            let p = (s[0] * g[0] + s[1] * g[1] + s[2] * g[2]) * -0.5;
            particular.fixed_rows_mut::<3>(3 * a).copy_from(&p);
        }
        // Null-space basis, column k = vec([e_k]× S).
        let mut null_space = SMatrix::<f64, 9, 3>::zeros();
        null_space.fixed_view_mut::<3, 1>(3, 0).copy_from(&-s[2]);
        null_space.fixed_view_mut::<3, 1>(6, 0).copy_from(&s[1]);
        null_space.fixed_view_mut::<3, 1>(0, 1).copy_from(&s[2]);
        null_space.fixed_view_mut::<3, 1>(6, 1).copy_from(&-s[0]);
        null_space.fixed_view_mut::<3, 1>(0, 2).copy_from(&-s[1]);
        null_space.fixed_view_mut::<3, 1>(3, 2).copy_from(&s[0]);
        // Ω N from the column blocks Ω_{·b} of Ω.
        let block = |b: usize| self.omega.fixed_view::<9, 3>(0, 3 * b);
        let mut omega_n = SMatrix::<f64, 9, 3>::zeros();
        omega_n.set_column(0, &(block(2) * s[1] - block(1) * s[2]));
        omega_n.set_column(1, &(block(0) * s[2] - block(2) * s[0]));
        omega_n.set_column(2, &(block(1) * s[0] - block(0) * s[1]));
        let reduced = null_space.transpose() * omega_n;
        let rhs = -(omega_n.transpose() * (r + particular));
        let omega_step = solve_positive_definite(&reduced, &rhs)?;
        Some(particular + null_space * omega_step)
    }
}

/// Eigenpairs of Ω computed only as far as they are used.
///
/// Ω is 9×9, but a solve reads few of its eigenpairs: the null vectors (or
/// the smallest one), and further ones only while the best cost exceeds
/// three times their eigenvalue. The [`EAGER_EIGENPAIRS`] smallest pairs come
/// from [`smallest_eigenpairs`] (tridiagonalisation, eigenvalues by QR,
/// vectors by inverse iteration: no rotation is accumulated into a 9×9
/// basis); the full decomposition is computed only if a solve asks for a
/// pair beyond them (it needs more than four null vectors, or a best cost
/// above three times the fifth eigenvalue).
struct OmegaEigen {
    omega: Matrix9,
    smallest: SmallestEigenpairs<9, EAGER_EIGENPAIRS>,
    /// All eigenvalues ascending and their eigenvectors as columns, once a
    /// pair beyond the eager ones has been asked for.
    full: Option<([f64; 9], Matrix9)>,
}

/// How many of Ω's smallest eigenpairs are computed up front (see
/// `OmegaEigen`); the fifth eigenvalue is the one the noncoplanar case's
/// stopping test usually reads last.
pub const EAGER_EIGENPAIRS: usize = 5;

impl OmegaEigen {
    fn new(omega: &Matrix9) -> Result<Self, PnpError> {
        let smallest = smallest_eigenpairs::<9, EAGER_EIGENPAIRS>(omega).map_err(|_| {
            PnpError::Degenerate {
                solver: NAME,
                reason: "eigen-decomposition of Omega failed",
            }
        })?;
        Ok(Self {
            omega: *omega,
            smallest,
            full: None,
        })
    }

    /// The full decomposition, ascending (computed on first use).
    fn full(&mut self) -> &([f64; 9], Matrix9) {
        let omega = self.omega;
        self.full.get_or_insert_with(|| {
            let eigen = SymmetricEigen::new(omega);
            let mut order: [usize; 9] = std::array::from_fn(|i| i);
            order.sort_by(|&a, &b| eigen.eigenvalues[a].total_cmp(&eigen.eigenvalues[b]));
            let values = order.map(|i| eigen.eigenvalues[i]);
            let vectors = Matrix9::from_fn(|row, k| eigen.eigenvectors[(row, order[k])]);
            (values, vectors)
        })
    }

    /// The k-th smallest eigenvalue (NaN if the full decomposition fails,
    /// which ends every comparison). Once the full decomposition exists,
    /// every pair comes from it, so that the vectors used stay orthonormal.
    fn value(&mut self, k: usize) -> f64 {
        if k >= EAGER_EIGENPAIRS || self.full.is_some() {
            return self.full().0[k];
        }
        self.smallest.values[k]
    }

    /// A unit eigenvector of the k-th smallest eigenvalue.
    fn vector(&mut self, k: usize) -> Vector9 {
        if k >= EAGER_EIGENPAIRS || self.full.is_some() {
            return self.full().1.column(k).into_owned();
        }
        self.smallest.vectors[k]
    }
}

/// One SQPnP result: rotation and its cost `rᵀ Ω r`.
#[derive(Debug, Clone, Copy)]
struct Minimum {
    rotation: Rotation3<f64>,
    cost: f64,
}

/// Keeps the distinct minima that pass the cheirality test, and the lowest
/// cost among them.
struct MinimumSet {
    minima: SmallVec<[Minimum; 8]>,
    lowest_cost: f64,
}

impl MinimumSet {
    fn offer(&mut self, minimum: Minimum, in_front: bool) {
        if !in_front || !minimum.cost.is_finite() {
            return;
        }
        self.lowest_cost = self.lowest_cost.min(minimum.cost);
        let r = vec_row_major(minimum.rotation.matrix());
        for kept in &mut self.minima {
            if (vec_row_major(kept.rotation.matrix()) - r).norm_squared()
                < EQUAL_VECTORS_SQUARED_DIFF
            {
                if minimum.cost < kept.cost {
                    *kept = minimum;
                }
                return;
            }
        }
        self.minima.push(minimum);
    }
}

/// What to do with a start `√3 e` that is already a rotation (orthogonality
/// error below [`ORTHOGONALITY_SQUARED_ERROR_THRESHOLD`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OrthogonalStart {
    /// Take it as the solution without SQP, as the paper and the
    /// reference code do. Its rotation is then off by up to
    /// `√threshold ≈ 1e-4` rad from the constrained minimum: on noise-free
    /// data far from the camera (Ω's null vector is accurate only to
    /// ~ε/(size/depth)⁴) and on data with rounding-level noise.
    TakeAsIs,
    /// Polish it with SQP, which converges in a step or two. The default:
    /// it is what makes the exact-recovery tests pass in the far field.
    Polish,
}

/// `sqpnp`: SQPnP (Terzakis & Lourakis 2020): sequential quadratic programming over the nine rotation entries from the null-space starts; handles coplanar points.
pub const SQPNP: Method = Method {
    name: "sqpnp",
    display_name: "SQPnP",
    description: "SQPnP: SQP over the rotation entries from the null-space starts, all local minima; coplanar points allowed (Terzakis & Lourakis 2020)",
    min_points: 4,
    accepts_coplanar: true,
    exact: true,
    start: None,
    solve,
};

/// SQPnP: every distinct local minimum reached from the null-space starts,
/// lowest cost first. Orthogonal starts are polished
/// ([`OrthogonalStart::Polish`]).
pub fn solve(object: &[Vector3<f64>], image: &[Vector2<f64>]) -> Result<Candidates, PnpError> {
    solve_with(object, image, OrthogonalStart::Polish)
}

/// SQPnP with a choice of what to do with orthogonal starts;
/// [`OrthogonalStart::TakeAsIs`] reproduces the reference code (used to
/// cross-check against it).
pub fn solve_with(
    object: &[Vector3<f64>],
    image: &[Vector2<f64>],
    orthogonal_start: OrthogonalStart,
) -> Result<Candidates, PnpError> {
    if object.len() < 4 {
        return Err(PnpError::TooFewPoints {
            solver: NAME,
            needed: 4,
            got: object.len(),
        });
    }
    let system = SqpnpSystem::new(object, image)?;
    let mut eigen = OmegaEigen::new(&system.omega)?;
    let null_count = (0..9)
        .take_while(|&k| eigen.value(k) < RANK_TOLERANCE)
        .count();
    if null_count > MAX_NULL_VECTORS {
        return Err(PnpError::Degenerate {
            solver: NAME,
            reason: "Omega has more than six null vectors; the points do not fix the rotation",
        });
    }
    let in_front = |pose: &Pose| {
        let depth = |p: &Vector3<f64>| pose.transform(p).z;
        if depth(&system.centroid) > 0.0 {
            return true;
        }
        let ahead = object.iter().filter(|p| depth(p) > 0.0).count();
        2 * ahead >= object.len()
    };
    let mut found = MinimumSet {
        minima: SmallVec::new(),
        lowest_cost: f64::INFINITY,
    };
    let run_both_signs = |e: &Vector9, found: &mut MinimumSet| {
        for sign in [1.0, -1.0] {
            let start = nearest_rotation(&mat_row_major(&(e * sign)));
            let rotation = system.run_sqp(&start);
            let minimum = Minimum {
                rotation,
                cost: system.cost(&vec_row_major(rotation.matrix())),
            };
            found.offer(minimum, in_front(&system.pose(&rotation)));
        }
    };

    let start_count = null_count.max(1);
    for k in 0..start_count {
        let e = eigen.vector(k) * 3f64.sqrt();
        if orthogonality_squared_error(&e) < ORTHOGONALITY_SQUARED_ERROR_THRESHOLD {
            // Already a rotation up to the sign of its determinant.
            let m = mat_row_major(&e);
            let mut rotation = nearest_rotation(&(m * m.determinant().signum()));
            if orthogonal_start == OrthogonalStart::Polish {
                rotation = system.run_sqp(&rotation);
            }
            let minimum = Minimum {
                rotation,
                cost: system.cost(&vec_row_major(rotation.matrix())),
            };
            found.offer(minimum, in_front(&system.pose(&rotation)));
        } else {
            run_both_signs(&e, &mut found);
        }
    }
    // Further eigenvectors while the best cost exceeds three times their
    // eigenvalue; the largest one is never used (as in the reference).
    for k in start_count..8 {
        if found.lowest_cost <= 3.0 * eigen.value(k) {
            break;
        }
        let e = eigen.vector(k);
        run_both_signs(&e, &mut found);
    }

    if found.minima.is_empty() {
        return Err(PnpError::BehindCamera { solver: NAME });
    }
    found.minima.sort_by(|a, b| a.cost.total_cmp(&b.cost));
    Ok(found
        .minima
        .iter()
        .map(|minimum| system.pose(&minimum.rotation))
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pose::rotation_error_deg;
    use crate::synthetic::{random_points, random_pose, stream_rng};

    fn problem(case: u64, planar: bool) -> (Vec<Vector3<f64>>, Vec<Vector2<f64>>, Pose) {
        let mut rng = stream_rng(11, 80, case);
        let mut object = random_points(&mut rng, 8, 100.0);
        if planar {
            object.iter_mut().for_each(|p| p.z = 0.0);
        }
        let truth = random_pose(&mut rng, 500.0, 0.3);
        let image = object.iter().map(|p| truth.project_normalised(p)).collect();
        (object, image, truth)
    }

    #[test]
    fn omega_is_symmetric_psd_and_vanishes_at_the_true_rotation() {
        for case in 0..20 {
            let (object, image, truth) = problem(case, case % 2 == 0);
            let system = SqpnpSystem::new(&object, &image).unwrap();
            let omega = system.omega();
            assert!((omega - omega.transpose()).norm() < 1e-12 * omega.norm());
            let eigen = SymmetricEigen::new(*omega);
            assert!(eigen.eigenvalues.min() > -1e-10 * omega.norm());
            let r = vec_row_major(truth.rotation.matrix());
            assert!(
                system.cost(&r) < 1e-12 * omega.norm(),
                "{}",
                system.cost(&r)
            );
            // t = P r reproduces the true translation.
            let pose = system.pose(&truth.rotation);
            assert!(
                (pose.translation - truth.translation).norm() < 1e-9 * truth.translation.norm()
            );
        }
    }

    #[test]
    fn lazy_eigenpairs_are_eigenpairs_before_and_after_the_full_switch() {
        let (object, image, _) = problem(7, false);
        let system = SqpnpSystem::new(&object, &image).unwrap();
        let omega = *system.omega();
        let mut eigen = OmegaEigen::new(&omega).unwrap();
        let check = |value: f64, vector: Vector9| {
            assert!((omega * vector - vector * value).norm() < 1e-12 * omega.norm());
            assert!((vector.norm() - 1.0).abs() < 1e-12);
        };
        let eager: Vec<f64> = (0..EAGER_EIGENPAIRS).map(|k| eigen.value(k)).collect();
        for k in 0..EAGER_EIGENPAIRS {
            check(eigen.value(k), eigen.vector(k));
        }
        assert!(eigen.full.is_none());
        for k in 0..9 {
            check(eigen.value(k), eigen.vector(k));
        }
        assert!(eigen.full.is_some());
        for (k, value) in eager.iter().enumerate() {
            assert!((eigen.value(k) - value).abs() < 1e-12 * omega.norm());
        }
    }

    #[test]
    fn coplanar_points_give_a_four_dimensional_null_space() {
        let (object, image, _) = problem(3, true);
        let system = SqpnpSystem::new(&object, &image).unwrap();
        let eigen = SymmetricEigen::new(*system.omega());
        let null = eigen
            .eigenvalues
            .iter()
            .filter(|&&v| v < RANK_TOLERANCE)
            .count();
        assert_eq!(null, 4, "{:?}", eigen.eigenvalues);
    }

    #[test]
    fn sqp_converges_to_a_rotation_from_a_perturbed_start() {
        let (object, image, truth) = problem(5, false);
        let system = SqpnpSystem::new(&object, &image).unwrap();
        let start = Rotation3::from_scaled_axis(Vector3::new(0.2, -0.1, 0.15)) * truth.rotation;
        let rotation = system.run_sqp(&start);
        assert!(rotation_error_deg(&truth.rotation, &rotation) < 1e-7);
    }

    #[test]
    fn recovers_planar_and_general_poses() {
        for case in 0..40 {
            let (object, image, truth) = problem(100 + case, case % 2 == 0);
            let candidates = solve(&object, &image).unwrap();
            let best = candidates
                .iter()
                .map(|c| rotation_error_deg(&truth.rotation, &c.rotation))
                .fold(f64::INFINITY, f64::min);
            assert!(best < 1e-7, "case {case}: {best}°");
        }
    }

    #[test]
    fn rejects_too_few_points_and_a_point_image() {
        let object = [Vector3::zeros(), Vector3::x(), Vector3::y()];
        let err = solve(&object, &[Vector2::zeros(); 3]).unwrap_err();
        assert_eq!(err.to_string(), "SQPnP needs at least 4 points, got 3");
        let object = [Vector3::zeros(), Vector3::x(), Vector3::y(), Vector3::z()];
        let err = solve(&object, &[Vector2::new(0.1, 0.2); 4]).unwrap_err();
        assert_eq!(
            err.to_string(),
            "SQPnP failed: the image points have no spread"
        );
    }
}
