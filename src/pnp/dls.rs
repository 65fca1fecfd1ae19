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
//! **Merging.** In noise-free data every chart finds the same zero-cost
//! minimum, and copies closer than [`DUPLICATE_ROTATION_RAD`] are merged
//! (keeping the one with the smallest `|s|`). With noise the charts' costs
//! `J' = J / cos⁴(θ/2)` (θ the rotation angle within the chart) weight the
//! same object-space error `J` differently, so each chart's minimum is a
//! slightly different estimate: measured differences run from 10⁻³ rad in
//! the near field to 0.1 rad at depth/size ≈ 100 with σ = 0.5 px. Those are
//! all returned as candidates, and [`super::best_candidate`] picks the one
//! with the lowest reprojection error.
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
//! **Deviations from the paper.** (1) Four charts instead of DLS+++'s three
//! (see above). (2) The action matrix is for multiplication by one variable
//! after a fixed generic change of variables, and the template is
//! eliminated block by block, rather than the paper's Schur complement with
//! a random linear form (same basis, same template rows, fewer flops, no
//! randomness). (3) Each root is polished by Newton's method on `∇J' = 0`,
//! the same equations, before it is used. (4) Every trusted minimum of every
//! chart is returned and the caller ranks them by reprojection error;
//! OpenCV's port instead keeps the lowest `J'` over its charts, although
//! the charts' `J'` weight `J` differently and are not comparable.

use super::three_cubics::{self, monomials, Cubic, CubicSystemError};
use super::{Candidates, PnpError};
use crate::pose::{rotation_error_deg, Pose};
use nalgebra::{Matrix3, Rotation3, SMatrix, SVector, SymmetricEigen, Vector2, Vector3};
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

/// DLS with its statistics (see the module documentation).
pub fn solve_with_statistics(
    object: &[Vector3<f64>],
    image: &[Vector2<f64>],
) -> Result<(Candidates, Statistics), PnpError> {
    let matrices = CostMatrices::new(object, image)?;
    let mut statistics = Statistics::default();
    let mut found: SmallVec<[Found; 8]> = SmallVec::new();
    let mut first_error = None;
    for chart in &CHARTS {
        let system = gradient(&matrices.quartic(chart));
        let roots = match three_cubics::real_roots(&system) {
            Ok(roots) => roots,
            Err(error) => {
                first_error.get_or_insert(error);
                continue;
            }
        };
        statistics.charts_solved += 1;
        statistics.real_critical_points += roots.roots.len();
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
            if s.norm() > CHART_TRUST_CAYLEY_NORM {
                continue;
            }
            statistics.trusted += 1;
            let chart_rotation = cayley_rotation(s);
            let rotation = chart_rotation * Matrix3::from_diagonal(&Vector3::from(*chart));
            let pose = matrices.pose(&rotation);
            if !pose.is_finite() || !pose.all_in_front(object) {
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

/// DLS: every local minimum of the DLS cost that puts all points in front
/// of the camera, lowest cost first.
pub fn solve(object: &[Vector3<f64>], image: &[Vector2<f64>]) -> Result<Candidates, PnpError> {
    solve_with_statistics(object, image).map(|(candidates, _)| candidates)
}

#[cfg(test)]
mod tests;
