//! DLS: Hesch & Roumeliotis, "A Direct Least-Squares (DLS) Method for PnP",
//! ICCV 2011, with the chart rotations of the authors' later "DLS+++"
//! (`robust_dls_pnp.m`) that avoid the Cayley singularity.
//!
//! **Cost.** With unit bearings `b_i = [m_i; 1]/‖[m_i; 1]‖`, each
//! correspondence says `α_i b_i = R p_i + t` for an unknown depth `α_i`.
//! DLS minimises the object-space least-squares error
//! `J = Σ_i ‖(I − b_i b_iᵀ)(R p_i + t)‖²` (the squared distance of each
//! transformed point from its ray; minimising over `α_i` leaves the
//! projection onto the ray's orthogonal complement `P_i = I − b_i b_iᵀ`).
//! `J` is quadratic in `t`, whose minimiser is linear in `r = vec(R)`
//! (column-major): `t = T r`, `T = −(Σ P_i)⁻¹ Σ (p_iᵀ ⊗ P_i)` (the paper's
//! closed-form translation; `(Σ P_i)⁻¹` is its `H` of eq. 25). Substituting
//! gives `J = rᵀ M r` with the 9 × 9 positive semi-definite
//! `M = Σ (p_i p_iᵀ) ⊗ P_i − Vᵀ (Σ P_i)⁻¹ V`, `V = Σ p_iᵀ ⊗ P_i`.
//!
//! **Cayley.** `R = C̄(s)/(1 + sᵀs)` with
//! `C̄(s) = (1 − sᵀs) I + 2[s]× + 2 s sᵀ` (Cayley–Gibbs–Rodrigues; `s` is
//! `tan(θ/2)` times the unit axis). The depths and translation are free, so
//! the factor `1 + sᵀs` can be absorbed into them; the paper minimises
//! `J'(s) = vec(C̄(s))ᵀ M vec(C̄(s)) = (1 + sᵀs)² J`, a quartic in `s`
//! (its eq. 17; equation numbers as the authors' and TheiaSfM's code cite
//! them). The optimality conditions `∇J'(s) = 0` (eq. 18) are three
//! cubics with 27 complex solutions, all found by the Macaulay-matrix /
//! action-matrix solver of [`super::three_cubics`]. Each real critical point
//! that is a local minimum (positive definite Hessian, as in the authors'
//! code) gives a rotation, then `t = T r`.
//!
//! **Charts (the Cayley singularity).** `s` is infinite for half-turns, and
//! near them the polynomial system has a root near infinity and is
//! ill-conditioned. As in the authors' DLS+++, the problem is solved again
//! with the object frame rotated by fixed rotations `F_j`, and the results
//! are rotated back (`R = R' F_j`). With unit quaternions, the Cayley chart
//! of `F_j` covers rotations whose quaternion `q` has a large component
//! `|⟨q, q_j⟩|`. Three charts can never suffice (some unit `q` is orthogonal
//! to any three quaternions: DLS+++'s 90° turns about x, y and z all see the
//! 120° rotations about the cube diagonals as half-turns). Four orthonormal
//! quaternions always leave one component `≥ 1/2`, so this module uses the
//! identity and the half-turns about x, y and z: every rotation is at most
//! 120° (`|s| ≤ tan 60° ≈ 1.73`) in at least one chart. A chart's minima
//! are used only within 150° of its centre (`|s| ≤ tan 75°`,
//! [`CHART_TRUST_CAYLEY_NORM`]), so every rotation is covered with margin.
//! A chart whose template is singular is skipped; only if every chart fails
//! is an error returned.
//!
//! **Charts on demand.** Solving all four charts every time costs four
//! polynomial solves; usually one suffices. [`solve_with_statistics`] (the
//! default, [`ChartPolicy::OnDemand`]) therefore:
//! 1. starts in the chart farthest from its singularity. Chart `c`'s
//!    quartic `J'_c` has a root at infinity exactly when one of its
//!    half-turns (the unit quaternions with component `c` zero, where its
//!    Cayley vector is infinite) is a zero-cost pose, and is ill-conditioned
//!    when one is nearly as cheap as the minimum. Only half-turns whose
//!    optimal translation leaves the object's centroid in front of the
//!    camera count ([`CostMatrices::quaternion_centroid_depth`]): `J`
//!    measures distances to lines, not rays, and in the far field the pose
//!    turned half a turn about the line of sight and moved behind the camera
//!    (`t → −t`) costs about as little as the true pose. Its quaternion is
//!    orthogonal to the true one, so it is a half-turn of the chart centred
//!    on the true pose; counting it made that chart look singular and
//!    picked one whose singular set held the true pose instead, where the
//!    minimum was lost (3 gross failures in 300 far-field problems). With `J(R(q)) = z(q)ᵀ K z(q)`
//!    over the ten quadratic monomials of the quaternion, the cost of
//!    chart `c`'s half-turns is a ternary quartic form; its least value
//!    ([`CostMatrices::equator_cost`]) is found by sampling 64 fixed
//!    directions and running Newton's method on the sphere from every
//!    sample that is a local minimum among its neighbours. The chart whose
//!    half-turns cost the most is solved first ([`CostMatrices::first_chart`],
//!    which refines only the charts that can still win: about 4 µs);
//! 2. solves again, in the chart nearest to it (`covering_chart`: the
//!    largest quaternion component), every critical point found beyond a
//!    solved chart's trusted region, every real eigenvalue whose root could
//!    not be polished there, and every in-front minimum more than 120° from
//!    the centre (`|s| > tan 60°`, [`CHART_COVER_CAYLEY_NORM`]), because the
//!    Cayley map stretches the cost there and the root is less accurate (a
//!    three-point case of the unit tests came out 2·10⁻⁶° off at 123°, and
//!    exact at 84° in the next chart); the nearest chart always has it
//!    within 120°;
//! 3. solves every chart when a template is singular (a root at infinity,
//!    direction unknown) or when no chart solved so far gave a trusted
//!    minimum in front of the camera: the pose then sits where those charts
//!    are singular, or where their weighting `1/cos⁴(θ/2)` of the cost has
//!    bent its minimum away (noise can remove a minimum near a chart's
//!    half-turns that way).
//!
//! **Why the least cost, not the least sample.** Sampling alone (as this
//! module first did) overestimates the least cost by orders of magnitude
//! when the cost valley around a well-determined pose is narrower than the
//! samples' spacing (16°; every direction is within 14° of one). A seven-point layout from our own search
//! showed it: at a tilt of 30° about x, the pose (quaternion
//! `(cos 15°, sin 15°, 0, 0)`) is a zero-cost half-turn of the y and z
//! charts, yet the y chart's least sample cost 0.16, more than any other
//! chart's, so it was solved first. There the true minimum is a double root
//! at infinity, which rounding turns into a complex pair of modulus ≈ 5·10⁶
//! (not a real root beyond the trusted region, not a rejected real
//! eigenvalue, not a singular template), while a spurious local minimum
//! 177° away put every point in front of the camera: nothing asked for
//! another chart, and DLS returned the flip (noise-free; with σ = 0.5 px
//! the layout's validation run had 74 gross failures). Over 2000 test
//! problems (half of them tilts about x, the validation protocol's poses)
//! the least sample picked a chart whose half-turns cost at least 10% less
//! than another's 596 times, the refined least cost never (against a dense
//! 20 000-direction search refined by Newton's method).
//!
//! Measured with `cargo run --release --features examples --example dls_report 200` (σ = 0.5 px,
//! depth/size 2–200, n = 4…104): 1.5–1.9 charts on average (median 1–2, max
//! 4); the median rotation error of the best candidate matches the
//! four-chart solve's to within ±4% on every n, and no problem fails that
//! the four-chart solve passes. [`ChartPolicy::All`] keeps the four-chart
//! solve as the reference.
//!
//! **Refinement and merging.** The charts' costs `J' = J / cos⁴(θ/2)`
//! (θ the rotation angle within the chart) weight the object-space error
//! `J` differently, so with noise each chart's minimum of `J'` is a
//! different estimate, and in the far field, where the cost valley is flat,
//! the weighting moves it by several times the noise (at depth/size 200,
//! n = 200 it put 294 of 300 problems more than 10° off). Each minimum of
//! `J'` is therefore refined by Newton's method to the nearby minimum of
//! `J` itself ([`refine_object_space_minimum`]), the same cost in every
//! chart. Copies closer than [`DUPLICATE_ROTATION_RAD`] are merged
//! (keeping the one with the smallest `|s|`); the rest are returned as
//! candidates, and [`super::best_candidate`] picks the one with the lowest
//! reprojection error.
//!
//! **Conditioning.** The object points are centred and scaled to unit RMS
//! radius first (`J'`'s roots do not depend on this; the pose is mapped
//! back exactly).
//!
//! **Requirements.** n ≥ 3 points, not collinear (P3P's minimum: with three
//! points the up-to-four exact P3P poses are among the candidates, next to
//! any local minima of positive cost, which rank below them). Coplanar
//! points are fine: nothing in the derivation needs a 3D spread (tested on
//! planar and quasi-planar sets).
//!
//! **Deviations from the paper.** (1) Four charts instead of DLS+++'s three,
//! solved on demand, the first chosen by the least cost of its half-turns
//! (see above). (2) The action matrix is for multiplication by one variable
//! after a fixed generic change of variables, and the template is
//! eliminated block by block, rather than the paper's Schur complement with
//! a random linear form (same basis, same template rows, fewer flops, no
//! randomness). (3) Each root is polished by Newton's method on `∇J' = 0`,
//! the same equations, before it is used. (4) Every trusted minimum of every
//! chart, refined to a minimum of `J` (5), is returned and the caller
//! ranks them by reprojection error;
//! OpenCV's port instead keeps the lowest `J'` over its charts, although
//! the charts' `J'` weight `J` differently and are not comparable.
//! (5) Each minimum of `J'` is refined to the nearby minimum of `J`, which
//! the paper's `J'` only approximates away from the chart's centre.

use super::three_cubics::{self, monomials, Cubic, CubicSystemError};
use super::{Candidates, Method, PnpError};
use crate::pose::{rotation_error_deg, Pose};
use nalgebra::{
    Matrix3, Rotation3, SMatrix, SVector, SymmetricEigen, UnitQuaternion, Vector2, Vector3,
};
use smallvec::SmallVec;

/// Human name used in errors.
const NAME: &str = "DLS";

/// Fewest correspondences: three, as for P3P.
pub const MIN_POINTS: usize = 3;

/// Diagonals of the chart rotations `F_j`: the identity and the half-turns
/// about x, y and z.
pub const CHARTS: [[f64; 3]; 4] = [
    [1.0, 1.0, 1.0],
    [1.0, -1.0, -1.0],
    [-1.0, 1.0, -1.0],
    [-1.0, -1.0, 1.0],
];

/// A critical point counts as a local minimum if the smallest eigenvalue of
/// the Hessian of `J'` is above `−HESSIAN_TOLERANCE` times the largest
/// (rounding can leave a well-defined but flat minimum slightly negative).
pub const HESSIAN_TOLERANCE: f64 = 1e-9;

/// `Σ_i (I − b_i b_iᵀ)` counts as singular (every image point on one ray)
/// when its smallest eigenvalue is below this fraction of its largest.
pub const RAY_SPREAD_TOLERANCE: f64 = 1e-12;

/// Minima from different charts whose rotations differ by less than this
/// angle (radians) are one minimum found twice. Noise-free copies agree to
/// about 10⁻¹⁰ rad; noisy ones differ by far more (module documentation).
pub const DUPLICATE_ROTATION_RAD: f64 = 1e-6;

/// A chart's minima are used only where `|s| ≤ tan 75° = 2 + √3`, i.e.
/// within 150° of the chart's centre. Beyond it the chart's weighting
/// `1/cos⁴(θ/2)` of the cost exceeds 200 and the polynomial system nears
/// its singularity, and another chart (≤ 120°) covers the rotation.
pub const CHART_TRUST_CAYLEY_NORM: f64 = 3.732_050_807_568_877;

/// Number of directions on which [`CostMatrices::equator_cost`] samples a
/// chart's singular set (a 2-sphere of half-turns, up to sign) to seed its
/// Newton descents.
pub const EQUATOR_DIRECTIONS: usize = 64;

/// Fibonacci-lattice directions on the upper unit hemisphere: nearly even
/// coverage, fixed (no randomness).
static EQUATOR_SAMPLES: std::sync::LazyLock<[[f64; 3]; EQUATOR_DIRECTIONS]> =
    std::sync::LazyLock::new(|| {
        let golden_angle = std::f64::consts::PI * (3.0 - 5f64.sqrt());
        std::array::from_fn(|i| {
            let z = (i as f64 + 0.5) / EQUATOR_DIRECTIONS as f64;
            let r = (1.0 - z * z).sqrt();
            let phi = golden_angle * i as f64;
            [r * phi.cos(), r * phi.sin(), z]
        })
    });

/// Each sample of [`CostMatrices::equator_minimum`] is compared with this
/// many nearest samples (up to sign; the Fibonacci lattice is nearly
/// hexagonal); a sample no costlier than all of them seeds a Newton descent.
pub const EQUATOR_NEIGHBOURS: usize = 6;

/// Most Newton steps of one descent on a chart's singular set (from within
/// a sample spacing of the minimum it converges in 3–6).
pub const EQUATOR_NEWTON_ITERATIONS: usize = 8;

/// A Newton step on the singular set is capped at this angle (radians,
/// 29°, about twice the farthest any direction is from a sample), so that
/// a descent stays near its basin.
pub const EQUATOR_MAX_STEP_RAD: f64 = 0.5;

/// A descent on the singular set has converged when its step is shorter
/// than this (radians).
pub const EQUATOR_STEP_TOLERANCE_RAD: f64 = 1e-6;

/// Halvings of a Newton step that does not lower the cost before the
/// descent stops.
pub const EQUATOR_BACKTRACKS: usize = 12;

/// The Riemannian Hessian of a descent is raised to at least this fraction
/// of its largest eigenvalue, so every step goes downhill (a Newton step
/// towards a saddle otherwise).
pub const EQUATOR_HESSIAN_FLOOR: f64 = 1e-3;

/// For each of [`EQUATOR_SAMPLES`], its [`EQUATOR_NEIGHBOURS`] nearest
/// others, with `u` and `−u` the same direction (the singular set is a
/// projective plane: `q` and `−q` are one rotation).
static EQUATOR_NEIGHBOUR_TABLE: std::sync::LazyLock<
    [[usize; EQUATOR_NEIGHBOURS]; EQUATOR_DIRECTIONS],
> = std::sync::LazyLock::new(|| {
    let samples = &*EQUATOR_SAMPLES;
    std::array::from_fn(|i| {
        let closeness = |j: usize| {
            let (a, b) = (samples[i], samples[j]);
            (a[0] * b[0] + a[1] * b[1] + a[2] * b[2]).abs()
        };
        let mut nearest = [usize::MAX; EQUATOR_NEIGHBOURS];
        for slot in 0..EQUATOR_NEIGHBOURS {
            nearest[slot] = (0..EQUATOR_DIRECTIONS)
                .filter(|&j| j != i && !nearest[..slot].contains(&j))
                .max_by(|&a, &b| closeness(a).total_cmp(&closeness(b)))
                .unwrap_or(i);
        }
        nearest
    })
});

/// `(u0², u0u1, u0u2, u1², u1u2, u2²)`.
fn ternary_quadratics(u: &Vector3<f64>) -> SVector<f64, 6> {
    SVector::<f64, 6>::new(
        u.x * u.x,
        u.x * u.y,
        u.x * u.z,
        u.y * u.y,
        u.y * u.z,
        u.z * u.z,
    )
}

/// The cost on one chart's singular set: `f(u) = z(u)ᵀ K z(u)` with
/// `z` = [`ternary_quadratics`], a quartic form in `u ∈ ℝ³`, `|u| = 1`,
/// counted only where the object's centroid is in front of the camera.
struct EquatorForm {
    /// `K` restricted to the six monomials without the chart's component.
    gram: SMatrix<f64, 6, 6>,
    /// `d` restricted to the same monomials: the centroid's depth at the
    /// optimal translation is `dᵀ z(u)`.
    depth: SVector<f64, 6>,
}

impl EquatorForm {
    /// The form of chart `chart` (an index into [`CHARTS`]) from the
    /// quaternion Gram matrix `K` and the centroid-depth form `d`
    /// ([`CostMatrices::quaternion_centroid_depth`]).
    fn new(gram: &SMatrix<f64, 10, 10>, depth: &SVector<f64, 10>, chart: usize) -> Self {
        // The six monomials without q_chart, and K restricted to them. In
        // QUATERNION_MONOMIALS' order they are, for the free components
        // u = (q_i, q_j, q_k) (i < j < k), (u0², u0u1, u0u2, u1², u1u2, u2²):
        // the order of `ternary_quadratics`.
        let mut kept = [0usize; 6];
        for (slot, m) in (0..10)
            .filter(|&m| QUATERNION_MONOMIALS[m].0 != chart && QUATERNION_MONOMIALS[m].1 != chart)
            .enumerate()
        {
            kept[slot] = m;
        }
        Self {
            gram: SMatrix::<f64, 6, 6>::from_fn(|i, j| gram[(kept[i], kept[j])]),
            depth: SVector::<f64, 6>::from_fn(|i, _| depth[kept[i]]),
        }
    }

    /// `f` on [`EQUATOR_SAMPLES`], `+∞` where the centroid is behind the
    /// camera.
    fn sampled(&self) -> [f64; EQUATOR_DIRECTIONS] {
        let samples = &*EQUATOR_SAMPLES;
        std::array::from_fn(|i| self.value(&Vector3::from(samples[i])))
    }

    /// The least of `f` (and where): Newton descents from every sample no
    /// costlier than its neighbours (`values` = [`Self::sampled`]).
    fn minimum(&self, values: &[f64; EQUATOR_DIRECTIONS]) -> (f64, Vector3<f64>) {
        let samples = &*EQUATOR_SAMPLES;
        let mut best = (f64::INFINITY, Vector3::z());
        for (i, neighbours) in EQUATOR_NEIGHBOUR_TABLE.iter().enumerate() {
            if values[i] < best.0 {
                best = (values[i], Vector3::from(samples[i]));
            }
            if values[i].is_finite() && neighbours.iter().all(|&j| values[j] >= values[i]) {
                let refined = self.descend(Vector3::from(samples[i]), values[i]);
                if refined.0 < best.0 {
                    best = refined;
                }
            }
        }
        best
    }

    /// `f(u)`, or `+∞` where the optimal translation puts the object's
    /// centroid at or behind the camera (depth `dᵀ z(u) ≤ 0`).
    fn value(&self, u: &Vector3<f64>) -> f64 {
        let z = ternary_quadratics(u);
        if self.depth.dot(&z) > 0.0 {
            z.dot(&(self.gram * z))
        } else {
            f64::INFINITY
        }
    }

    /// Gradient and Hessian of `f` in ℝ³.
    fn derivatives(&self, u: &Vector3<f64>) -> (Vector3<f64>, Matrix3<f64>) {
        let w = self.gram * ternary_quadratics(u);
        // ∂z/∂u, one row per monomial.
        #[rustfmt::skip]
        let dz = SMatrix::<f64, 6, 3>::new(
            2.0 * u.x, 0.0, 0.0,
            u.y, u.x, 0.0,
            u.z, 0.0, u.x,
            0.0, 2.0 * u.y, 0.0,
            0.0, u.z, u.y,
            0.0, 0.0, 2.0 * u.z,
        );
        // Σ_m w_m ∂²z_m/∂u².
        #[rustfmt::skip]
        let curvature = Matrix3::new(
            2.0 * w[0], w[1], w[2],
            w[1], 2.0 * w[3], w[4],
            w[2], w[4], 2.0 * w[5],
        );
        let gradient = 2.0 * dz.tr_mul(&w);
        let hessian = 2.0 * dz.tr_mul(&(self.gram * dz)) + 2.0 * curvature;
        (gradient, hessian)
    }

    /// Riemannian Newton's method for `f` on the unit sphere from `u`
    /// (with cost `value`), each step capped, made to descend and
    /// backtracked: the local minimum `(f, u)` of `u`'s basin.
    fn descend(&self, mut u: Vector3<f64>, mut value: f64) -> (f64, Vector3<f64>) {
        for _ in 0..EQUATOR_NEWTON_ITERATIONS {
            let (gradient, hessian) = self.derivatives(&u);
            // An orthonormal basis of the tangent plane at u.
            let helper = if u.x.abs() < 0.6 {
                Vector3::x()
            } else {
                Vector3::y()
            };
            let e1 = u.cross(&helper).normalize();
            let basis = nalgebra::Matrix3x2::from_columns(&[e1, u.cross(&e1)]);
            // On the sphere: projected gradient, and Hessian Bᵀ(∇²f − (uᵀ∇f) I)B.
            let tangent_gradient = basis.tr_mul(&gradient);
            let mut tangent_hessian =
                basis.tr_mul(&(hessian * basis)) - nalgebra::Matrix2::identity() * u.dot(&gradient);
            // Its eigenvalues, in closed form.
            let half_trace = 0.5 * tangent_hessian.trace();
            let radius = (half_trace * half_trace - tangent_hessian.determinant())
                .max(0.0)
                .sqrt();
            let (smallest, largest) = (half_trace - radius, half_trace + radius);
            let floor = EQUATOR_HESSIAN_FLOOR * smallest.abs().max(largest.abs());
            if smallest < floor {
                tangent_hessian += nalgebra::Matrix2::identity() * (floor - smallest);
            }
            let Some(mut step) = tangent_hessian
                .try_inverse()
                .map(|inverse| -(inverse * tangent_gradient))
                .filter(|step| step.iter().all(|v| v.is_finite()))
            else {
                break;
            };
            if step.norm() > EQUATOR_MAX_STEP_RAD {
                step *= EQUATOR_MAX_STEP_RAD / step.norm();
            }
            let converged = step.norm() < EQUATOR_STEP_TOLERANCE_RAD;
            let mut accepted = false;
            // A converged step is taken if it helps, never halved.
            let tries = if converged { 1 } else { EQUATOR_BACKTRACKS };
            for _ in 0..tries {
                let next = (u + basis * step).normalize();
                let next_value = self.value(&next);
                if next_value < value {
                    (u, value) = (next, next_value);
                    accepted = true;
                    break;
                }
                step *= 0.5;
            }
            if converged || !accepted {
                break;
            }
        }
        (value, u)
    }
}

/// The factors `(a, b)` of each quaternion monomial `q_a q_b` of
/// [`CostMatrices::quaternion_gram`], with `q = (w, x, y, z)`.
const QUATERNION_MONOMIALS: [(usize, usize); 10] = [
    (0, 0),
    (0, 1),
    (0, 2),
    (0, 3),
    (1, 1),
    (1, 2),
    (1, 3),
    (2, 2),
    (2, 3),
    (3, 3),
];

/// `tan 60°`: every rotation is within 120° of the centre of one of the
/// four charts, where `|s| ≤ tan 60°`. A minimum found beyond this in one
/// chart is solved for again in the chart nearest to it, where the Cayley
/// map stretches less (module documentation).
pub const CHART_COVER_CAYLEY_NORM: f64 = 1.732_050_807_568_877_2;

/// `vec(C̄(s))` as a 9 × 10 matrix times the monomials of degree ≤ 2 in `s`
/// (graded order: 1, s1, s2, s3, s1², s1s2, s1s3, s2², s2s3, s3²);
/// `vec` is column-major.
fn cayley_numerator_coefficients() -> SMatrix<f64, 9, 10> {
    let mut g = SMatrix::<f64, 9, 10>::zeros();
    let (one, s1, s2, s3, s11, s12, s13, s22, s23, s33) = (0, 1, 2, 3, 4, 5, 6, 7, 8, 9);
    // Diagonal: 1 − sᵀs + 2 s_k².
    for (entry, k) in [(0, s11), (4, s22), (8, s33)] {
        g[(entry, one)] = 1.0;
        for square in [s11, s22, s33] {
            g[(entry, square)] = if square == k { 1.0 } else { -1.0 };
        }
    }
    // Off-diagonal (row, column) → vec index 3·column + row: 2 s_r s_c ± 2 s_k.
    let off = [
        (1, s12, s3, 2.0),  // C̄21 = 2 s1 s2 + 2 s3
        (3, s12, s3, -2.0), // C̄12 = 2 s1 s2 − 2 s3
        (2, s13, s2, -2.0), // C̄31 = 2 s1 s3 − 2 s2
        (6, s13, s2, 2.0),  // C̄13 = 2 s1 s3 + 2 s2
        (5, s23, s1, 2.0),  // C̄32 = 2 s2 s3 + 2 s1
        (7, s23, s1, -2.0), // C̄23 = 2 s2 s3 − 2 s1
    ];
    for (entry, product, linear, sign) in off {
        g[(entry, product)] = 2.0;
        g[(entry, linear)] = sign;
    }
    g
}

/// The unnormalised Cayley rotation `C̄(s)`.
pub fn cayley_numerator(s: &Vector3<f64>) -> Matrix3<f64> {
    (1.0 - s.norm_squared()) * Matrix3::identity()
        + 2.0 * s.cross_matrix()
        + 2.0 * s * s.transpose()
}

/// The rotation with Cayley vector `s`, `C̄(s)/(1 + sᵀs)`.
pub fn cayley_rotation(s: &Vector3<f64>) -> Matrix3<f64> {
    cayley_numerator(s) / (1.0 + s.norm_squared())
}

/// The least-squares data of one problem in its normalised object frame.
#[derive(Debug, Clone)]
pub struct CostMatrices {
    /// `M`: `J = vec(R)ᵀ M vec(R)`.
    pub cost: SMatrix<f64, 9, 9>,
    /// `T`: the optimal translation is `T vec(R)`.
    pub translation: SMatrix<f64, 3, 9>,
    /// Centroid of the object points (mm).
    pub centroid: Vector3<f64>,
    /// RMS distance of the object points from their centroid (mm).
    pub scale: f64,
}

impl CostMatrices {
    /// Builds `M` and `T` from the correspondences (O(n)).
    pub fn new(object: &[Vector3<f64>], image: &[Vector2<f64>]) -> Result<Self, PnpError> {
        let (centroid, scale) = super::centroid_and_rms_radius(object);
        let mut ray_sum = Matrix3::zeros();
        let mut v = SMatrix::<f64, 3, 9>::zeros();
        let mut quadratic = SMatrix::<f64, 9, 9>::zeros();
        for (p, m) in object.iter().zip(image) {
            let p = (p - centroid) / scale;
            let b = Vector3::new(m.x, m.y, 1.0).normalize();
            let projector = Matrix3::identity() - b * b.transpose();
            ray_sum += projector;
            for a in 0..3 {
                let block = projector * p[a];
                let mut v_block = v.fixed_view_mut::<3, 3>(0, 3 * a);
                v_block += block;
                for c in a..3 {
                    let mut q_block = quadratic.fixed_view_mut::<3, 3>(3 * a, 3 * c);
                    q_block += block * p[c];
                }
            }
        }
        for a in 0..3 {
            for c in 0..a {
                let upper = quadratic.fixed_view::<3, 3>(3 * c, 3 * a).into_owned();
                quadratic
                    .fixed_view_mut::<3, 3>(3 * a, 3 * c)
                    .copy_from(&upper.transpose());
            }
        }
        // Σ P_i is singular exactly when every bearing is the same ray.
        let spread = SymmetricEigen::new(ray_sum).eigenvalues;
        let ray_sum_inverse = ray_sum
            .try_inverse()
            .filter(|_| spread.min() > RAY_SPREAD_TOLERANCE * spread.max())
            .ok_or(PnpError::Degenerate {
                solver: NAME,
                reason: "all image points lie on one ray",
            })?;
        let translation = -ray_sum_inverse * v;
        let mut cost = quadratic + v.transpose() * translation;
        cost = 0.5 * (cost + cost.transpose());
        Ok(Self {
            cost,
            translation,
            centroid,
            scale,
        })
    }

    /// `J'(s)` in the chart with diagonal `chart` as its 35 quartic
    /// coefficients (graded order of [`monomials::index`]).
    pub fn quartic(&self, chart: &[f64; 3]) -> [f64; 35] {
        // R = R' F: column c of R is chart[c] times column c of R'.
        let cost =
            SMatrix::<f64, 9, 9>::from_fn(|i, j| chart[i / 3] * chart[j / 3] * self.cost[(i, j)]);
        let g = cayley_numerator_coefficients();
        let k = g.transpose() * cost * g;
        let mut quartic = [0.0; 35];
        for a in 0..10 {
            for b in 0..10 {
                let (ma, mb) = (monomials::MONOMIALS[a], monomials::MONOMIALS[b]);
                let sum = monomials::index(
                    (ma[0] + mb[0]) as usize,
                    (ma[1] + mb[1]) as usize,
                    (ma[2] + mb[2]) as usize,
                );
                quartic[sum] += k[(a, b)];
            }
        }
        quartic
    }

    /// `K` with `J(R(q)) = z(q)ᵀ K z(q)` for a unit quaternion
    /// `q = (w, x, y, z)` and `z(q) = (w², wx, wy, wz, x², xy, xz, y², yz,
    /// z²)`: the quartic of the identity chart read with `q = (1, s)`.
    pub fn quaternion_gram(&self) -> SMatrix<f64, 10, 10> {
        let g = cayley_numerator_coefficients();
        g.transpose() * self.cost * g
    }

    /// `d` with `dᵀ z(q)` the depth (camera z) of the object's centroid at
    /// the optimal translation `t = T vec(R(q))`, for a unit quaternion `q`
    /// and `z(q)` as in [`CostMatrices::quaternion_gram`]. The centroid is
    /// the normalised frame's origin, so its camera position is `t`.
    pub fn quaternion_centroid_depth(&self) -> SVector<f64, 10> {
        let g = cayley_numerator_coefficients();
        (self.translation.row(2) * g).transpose()
    }

    /// The least cost `J` over the singular set of chart `chart` (an index
    /// into [`CHARTS`]): the rotations a half-turn away from its centre, the
    /// unit quaternions with component `chart` zero, where its Cayley vector
    /// is infinite. See [`CostMatrices::equator_minimum`].
    pub fn equator_cost(&self, gram: &SMatrix<f64, 10, 10>, chart: usize) -> f64 {
        self.equator_minimum(gram, chart).0
    }

    /// The least cost `J` over chart `chart`'s half-turns and the unit
    /// quaternion `(w, x, y, z)` (component `chart` zero) attaining it.
    ///
    /// On those quaternions `J` is a ternary quartic form `f(u)` of the
    /// three free components `u` (unit). It is sampled on
    /// [`EQUATOR_DIRECTIONS`] fixed directions, and every sample that is no
    /// costlier than its [`EQUATOR_NEIGHBOURS`] nearest neighbours seeds
    /// Newton's method on the sphere, which converges to the local minimum
    /// of `f` in that basin. The samples alone are not enough: near a
    /// well-determined pose `J` rises steeply (the cost valley can be
    /// narrower than the samples' spacing of 16°), so the least sample
    /// can exceed the least cost by orders of magnitude and misrank the
    /// charts (module documentation, "Why the least cost, not the least
    /// sample").
    pub fn equator_minimum(&self, gram: &SMatrix<f64, 10, 10>, chart: usize) -> (f64, [f64; 4]) {
        let form = EquatorForm::new(gram, &self.quaternion_centroid_depth(), chart);
        let (value, u) = form.minimum(&form.sampled());
        let free: [usize; 3] = match chart {
            0 => [1, 2, 3],
            1 => [0, 2, 3],
            2 => [0, 1, 3],
            _ => [0, 1, 2],
        };
        let mut q = [0.0; 4];
        for (slot, component) in free.iter().zip(u.iter()) {
            q[*slot] = *component;
        }
        (value, q)
    }

    /// The chart whose half-turns cost the most ([`CostMatrices::equator_cost`]
    /// largest; the lowest index on a tie), the one [`ChartPolicy::OnDemand`]
    /// solves first. The same as comparing the four equator costs, with less
    /// work: a chart's least sample bounds its least cost from above, so a
    /// chart whose least sample is below the largest least cost found so far
    /// cannot win and is not refined.
    pub fn first_chart(&self, gram: &SMatrix<f64, 10, 10>) -> usize {
        let depth = self.quaternion_centroid_depth();
        let forms: [EquatorForm; 4] = std::array::from_fn(|c| EquatorForm::new(gram, &depth, c));
        let sampled: [[f64; EQUATOR_DIRECTIONS]; 4] = std::array::from_fn(|c| forms[c].sampled());
        let upper: [f64; 4] =
            std::array::from_fn(|c| sampled[c].iter().copied().fold(f64::INFINITY, f64::min));
        let mut order = [0, 1, 2, 3];
        order.sort_by(|&a, &b| upper[b].total_cmp(&upper[a]).then(a.cmp(&b)));
        let mut best = (f64::NEG_INFINITY, 0);
        for c in order {
            if upper[c] < best.0 || (upper[c] == best.0 && c > best.1) {
                continue;
            }
            let (least, _) = forms[c].minimum(&sampled[c]);
            if least > best.0 || (least == best.0 && c < best.1) {
                best = (least, c);
            }
        }
        best.1
    }

    /// `J(R) = vec(R)ᵀ M vec(R)` for a rotation in the normalised frame.
    pub fn cost_of(&self, rotation: &Matrix3<f64>) -> f64 {
        let r = SVector::<f64, 9>::from_column_slice(rotation.as_slice());
        (r.transpose() * self.cost * r)[0]
    }

    /// The pose in original coordinates for a rotation found in the
    /// normalised frame: `t̃ = T vec(R)`, then `t = scale·t̃ − R·centroid`.
    pub fn pose(&self, rotation: &Matrix3<f64>) -> Pose {
        let r = SVector::<f64, 9>::from_column_slice(rotation.as_slice());
        let normalised_translation = self.translation * r;
        let rotation = Rotation3::from_matrix_unchecked(*rotation);
        Pose::new(
            rotation,
            self.scale * normalised_translation - rotation * self.centroid,
        )
    }
}

/// The gradient of a quartic: three cubics, `∂J'/∂s_k`.
pub fn gradient(quartic: &[f64; 35]) -> [Cubic; 3] {
    let mut cubics = [[0.0; monomials::CUBIC_TERMS]; 3];
    for (term, &value) in quartic.iter().enumerate() {
        let m = monomials::MONOMIALS[term];
        for (k, cubic) in cubics.iter_mut().enumerate() {
            if m[k] == 0 {
                continue;
            }
            let mut lower = [m[0] as usize, m[1] as usize, m[2] as usize];
            lower[k] -= 1;
            cubic[monomials::index(lower[0], lower[1], lower[2])] += m[k] as f64 * value;
        }
    }
    cubics
}

/// Most Newton steps of [`refine_object_space_minimum`] (from a minimum of
/// `J'` it converges in 2–4).
pub const REFINE_ITERATIONS: usize = 10;

/// [`refine_object_space_minimum`] stops when its step in `s` is shorter
/// than this.
pub const REFINE_STEP_TOLERANCE: f64 = 1e-12;

/// Halvings of a refinement step that does not lower `J` before the
/// refinement stops.
pub const REFINE_BACKTRACKS: usize = 20;

/// The Hessian of `J` in [`refine_object_space_minimum`] has its
/// eigenvalues raised to at least this fraction of the largest, so every
/// step descends.
pub const REFINE_HESSIAN_FLOOR: f64 = 1e-6;

/// From a local minimum `s` of chart `chart`'s `J'`, the nearby local
/// minimum of the object-space cost itself, `J(s) = J'(s)/(1 + sᵀs)²`
/// (the same cost in every chart), by Newton's method in the chart's
/// Cayley coordinates with backtracking. `system` is `∇J'`
/// ([`gradient`] of the chart's quartic). Stops where the Hessian of `J`
/// is not positive definite or no step lowers `J`.
fn refine_object_space_minimum(
    matrices: &CostMatrices,
    chart: &[f64; 3],
    system: &[Cubic; 3],
    mut s: Vector3<f64>,
) -> Vector3<f64> {
    let flip = Matrix3::from_diagonal(&Vector3::from(*chart));
    // J, or +∞ where the optimal translation puts the centroid at or
    // behind the camera: in the far field the mirror pose behind the camera
    // (module documentation) can cost less, and a descent must not cross
    // over to it.
    let cost = |s: &Vector3<f64>| {
        let rotation = cayley_rotation(s) * flip;
        let r = SVector::<f64, 9>::from_column_slice(rotation.as_slice());
        if (matrices.translation.row(2) * r)[0] > 0.0 {
            matrices.cost_of(&rotation)
        } else {
            f64::INFINITY
        }
    };
    let mut value = cost(&s);
    for _ in 0..REFINE_ITERATIONS {
        let weight = 1.0 + s.norm_squared();
        let numerator = value * weight * weight;
        let numerator_gradient = three_cubics::evaluate(system, &s);
        let numerator_hessian = three_cubics::jacobian(system, &s);
        let numerator_hessian = 0.5 * (numerator_hessian + numerator_hessian.transpose());
        let (w2, w3, w4) = (weight.powi(2), weight.powi(3), weight.powi(4));
        let gradient = numerator_gradient / w2 - s * (4.0 * numerator / w3);
        let cross = numerator_gradient * s.transpose();
        let hessian = numerator_hessian / w2
            - (cross + cross.transpose()) * (4.0 / w3)
            - Matrix3::identity() * (4.0 * numerator / w3)
            + s * s.transpose() * (24.0 * numerator / w4);
        // Raised to a positive definite floor, so every step descends.
        let eigen = SymmetricEigen::new(hessian);
        let floor = REFINE_HESSIAN_FLOOR * eigen.eigenvalues.amax();
        let raised = eigen.eigenvalues.map(|e| 1.0 / e.max(floor));
        let Some(mut step) = Some(
            -(eigen.eigenvectors
                * Matrix3::from_diagonal(&raised)
                * eigen.eigenvectors.transpose()
                * gradient),
        )
        .filter(|step| step.iter().all(|v| v.is_finite())) else {
            break;
        };
        let converged = step.norm() < REFINE_STEP_TOLERANCE * (1.0 + s.norm());
        let mut accepted = false;
        for _ in 0..REFINE_BACKTRACKS {
            let next = s + step;
            let next_value = cost(&next);
            if next_value <= value {
                (s, value) = (next, next_value);
                accepted = true;
                break;
            }
            step *= 0.5;
        }
        if converged || !accepted {
            break;
        }
    }
    s
}

/// What one DLS run found, for reports and tests.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Statistics {
    /// Charts whose polynomial system was solved (at most 4).
    pub charts_solved: usize,
    /// Real critical points of `J'`, summed over the charts.
    pub real_critical_points: usize,
    /// Of those, local minima.
    pub local_minima: usize,
    /// Of those, minima within their chart's trusted region.
    pub trusted: usize,
    /// Of those, minima that put every point in front of the camera.
    pub in_front: usize,
    /// Candidates returned after merging the charts.
    pub returned: usize,
}

/// A local minimum found in one chart.
struct Found {
    pose: Pose,
    /// `|s|` in its chart: smaller is better conditioned.
    cayley_norm: f64,
    /// `J(R)`, comparable across charts.
    cost: f64,
}

/// Which charts [`solve_with_statistics_in`] solves.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ChartPolicy {
    /// The identity chart, then only the charts needed to confirm, in a
    /// chart where it is well conditioned, every critical point found
    /// beyond a solved chart's trusted region (module documentation). The
    /// default.
    OnDemand,
    /// All four charts, every time (the reference the on-demand policy is
    /// tested against).
    All,
}

/// The chart (index into [`CHARTS`]) in which the rotation with Cayley
/// vector `s` in chart `chart` is closest to the centre: the largest
/// component of its unit quaternion. For `|s| > tan 75°` in one chart that
/// component is at least `|s|/√(3(1 + |s|²)) > 0.55`, so the rotation is
/// within 113° of the new chart's centre, well inside its trusted region.
fn covering_chart(chart: &[f64; 3], s: &Vector3<f64>) -> usize {
    let rotation = cayley_rotation(s) * Matrix3::from_diagonal(&Vector3::from(*chart));
    let q = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(rotation));
    let components = [q.w, q.i, q.j, q.k].map(f64::abs);
    // CHARTS is ordered identity, half-turns about x, y, z: the quaternions
    // (1, 0, 0, 0), (0, 1, 0, 0), (0, 0, 1, 0), (0, 0, 0, 1).
    (0..4)
        .max_by(|&a, &b| components[a].total_cmp(&components[b]))
        .unwrap_or(0)
}

/// DLS with its statistics (see the module documentation), charts on
/// demand.
pub fn solve_with_statistics(
    object: &[Vector3<f64>],
    image: &[Vector2<f64>],
) -> Result<(Candidates, Statistics), PnpError> {
    solve_with_statistics_in(object, image, ChartPolicy::OnDemand)
}

/// DLS with its statistics, solving the charts `policy` asks for.
pub fn solve_with_statistics_in(
    object: &[Vector3<f64>],
    image: &[Vector2<f64>],
    policy: ChartPolicy,
) -> Result<(Candidates, Statistics), PnpError> {
    let matrices = CostMatrices::new(object, image)?;
    let mut statistics = Statistics::default();
    let mut found: SmallVec<[Found; 8]> = SmallVec::new();
    let mut first_error = None;
    let mut wanted = match policy {
        ChartPolicy::OnDemand => {
            // Start in the chart farthest from its singularity: the one
            // whose half-turns cost the most (module documentation).
            let first = matrices.first_chart(&matrices.quaternion_gram());
            let mut wanted = [false; 4];
            wanted[first] = true;
            wanted
        }
        ChartPolicy::All => [true; 4],
    };
    let mut attempted = [false; 4];
    loop {
        let Some(index) = (0..CHARTS.len()).find(|&c| wanted[c] && !attempted[c]) else {
            // No trusted minimum in front of the camera from the charts
            // solved: the pose sits where they are singular or where their
            // weighting 1/cos⁴(θ/2) has bent its minimum away. The others.
            if found.is_empty() && attempted.iter().any(|a| !a) {
                wanted = [true; 4];
                continue;
            }
            break;
        };
        attempted[index] = true;
        let chart = &CHARTS[index];
        let system = gradient(&matrices.quartic(chart));
        let roots = match three_cubics::real_roots(&system) {
            Ok(roots) => roots,
            Err(error) => {
                // A singular template means a root at (or numerically at)
                // infinity in this chart, direction unknown: every chart.
                first_error.get_or_insert(error);
                wanted = [true; 4];
                continue;
            }
        };
        statistics.charts_solved += 1;
        statistics.real_critical_points += roots.roots.len();
        // Any critical point beyond this chart's trusted region, or a real
        // eigenvalue whose root could not be polished there, is (re)solved
        // in the chart where it is closest to the centre.
        for s in roots.roots.iter().chain(&roots.rejected) {
            if s.norm() > CHART_TRUST_CAYLEY_NORM {
                wanted[covering_chart(chart, s)] = true;
            }
        }
        for s in &roots.roots {
            let hessian = three_cubics::jacobian(&system, s);
            let hessian = 0.5 * (hessian + hessian.transpose());
            let eigenvalues = SymmetricEigen::new(hessian).eigenvalues;
            let (smallest, largest) = (eigenvalues.min(), eigenvalues.amax());
            let is_minimum = smallest > -HESSIAN_TOLERANCE * largest;
            if !is_minimum {
                continue;
            }
            statistics.local_minima += 1;
            let s = &refine_object_space_minimum(&matrices, chart, &system, *s);
            let chart_rotation = cayley_rotation(s);
            let rotation = chart_rotation * Matrix3::from_diagonal(&Vector3::from(*chart));
            let pose = matrices.pose(&rotation);
            let in_front = pose.is_finite() && pose.all_in_front(object);
            if in_front && s.norm() > CHART_COVER_CAYLEY_NORM {
                // A candidate pose beyond 120° from this chart's centre:
                // solve again in the chart nearest to it (every rotation is
                // within 120° of one), where it is better conditioned.
                wanted[covering_chart(chart, s)] = true;
            }
            if s.norm() > CHART_TRUST_CAYLEY_NORM {
                continue;
            }
            statistics.trusted += 1;
            if !in_front {
                continue;
            }
            statistics.in_front += 1;
            found.push(Found {
                pose,
                cayley_norm: s.norm(),
                cost: matrices.cost_of(&rotation),
            });
        }
    }
    if statistics.charts_solved == 0 {
        return Err(PnpError::PolynomialSolver {
            solver: NAME,
            source: first_error.unwrap_or(CubicSystemError::NonFinite),
        });
    }
    // Merge copies of one minimum, keeping the best-conditioned one.
    found.sort_by(|a, b| a.cayley_norm.total_cmp(&b.cayley_norm));
    let mut kept: SmallVec<[Found; 8]> = SmallVec::new();
    for candidate in found {
        let duplicate = kept.iter().any(|k| {
            rotation_error_deg(&k.pose.rotation, &candidate.pose.rotation).to_radians()
                < DUPLICATE_ROTATION_RAD
        });
        if !duplicate {
            kept.push(candidate);
        }
    }
    kept.sort_by(|a, b| a.cost.total_cmp(&b.cost));
    statistics.returned = kept.len();
    if kept.is_empty() {
        return Err(PnpError::BehindCamera { solver: NAME });
    }
    Ok((kept.iter().map(|f| f.pose).collect(), statistics))
}

/// `dls`: direct least squares over the Cayley parameters, all critical points by a Macaulay/action-matrix solver (Hesch & Roumeliotis 2011).
pub const DLS: Method = Method {
    name: "dls",
    display_name: NAME,
    description: "direct least squares: all 27 critical points of the Cayley-parameterised cost by a Macaulay/action-matrix solver, in four charts (Hesch & Roumeliotis 2011)",
    min_points: MIN_POINTS,
    accepts_coplanar: true,
    exact: true,
    start: None,
    solve,
};

/// DLS: every local minimum of the DLS cost that puts all points in front
/// of the camera, lowest cost first.
pub fn solve(object: &[Vector3<f64>], image: &[Vector2<f64>]) -> Result<Candidates, PnpError> {
    solve_with_statistics(object, image).map(|(candidates, _)| candidates)
}

#[cfg(test)]
mod tests;
