//! EPnP: Lepetit, Moreno-Noguer & Fua, "EPnP: An Accurate O(n) Solution to
//! the PnP Problem", IJCV 81(2), 2009. Paper eqs. 4–10 restate it.
//!
//! Every object point is written in barycentric coordinates `α_ij` of four
//! noncoplanar control points (eq. 4); the projection equations (eq. 7) make
//! a 2n×12 system `M x = 0` (eq. 8) in the camera-frame control points, whose
//! solution lies in the span of the eigenvectors of `MᵀM` for the smallest
//! eigenvalues (eq. 9). The coefficients β are fixed by requiring the control
//! points to keep their mutual distances, for null-space dimensions N = 1…4
//! (Lepetit §3.3), optionally refined by Gauss–Newton (eq. 10, see
//! [`super::gauss_newton`]). Absolute orientation then gives R, t.
//!
//! [`EpnpSystem`] is the reusable part: `parallel-weighted`, `iepnp` and
//! `epnp-gn` all build one and differ only in where their β come from and how
//! GN weights the six control-point distances.
//!
//! Requirements: n ≥ 4 noncoplanar points (validated by the caller). Nothing
//! is allocated: `MᵀM` is accumulated directly as a 12×12 fixed-size matrix,
//! and only its four smallest eigenpairs are computed
//! ([`crate::linalg::smallest_eigenpairs`]).

use super::{foam, gauss_newton, Candidates, PnpError, Spread};
use crate::linalg::{smallest_eigenpairs, solve_positive_definite, EigenError};
use crate::pose::Pose;
use nalgebra::{Matrix3, SMatrix, SVector, Vector2, Vector3, Vector4};

/// The six control-point pairs `i < j`, in the order of the rows of L and ρ.
pub const PAIRS: [(usize, usize); 6] = [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)];

/// A 12-vector: the four camera-frame control points stacked (eq. 8's x).
pub type Stacked = SVector<f64, 12>;

/// The EPnP linear system of one problem: control points, barycentric map,
/// null space of `MᵀM`, and the distance constraints L β̄ = ρ.
#[derive(Debug, Clone)]
pub struct EpnpSystem {
    control_world: [Vector3<f64>; 4],
    /// Inverse of `[c1−c0, c2−c0, c3−c0]`: maps `p − c0` to `(α1, α2, α3)`.
    to_barycentric: Matrix3<f64>,
    /// Eigenvectors of MᵀM, smallest eigenvalue first (v1…v4 of eq. 15).
    null_space: [Stacked; 4],
    /// The 6×10 matrix L of Lepetit eq. 13: row k holds the products that
    /// multiply `[β11, β12, β22, β13, β23, β33, β14, β24, β34, β44]`.
    distance_products: SMatrix<f64, 6, 10>,
    /// ρ: squared world distances between the control points of each pair.
    control_distances_sq: SVector<f64, 6>,
    /// Mean barycentric coordinates `ᾱ` of the object points.
    alpha_mean: Vector4<f64>,
    /// `G = Σ_i (α_i − ᾱ)(P_i − P̄)ᵀ`: with it the cross-covariance of the
    /// absolute orientation step is `C G` for any camera-frame control
    /// points C, so recovering a pose costs O(1) instead of O(n).
    alpha_object_covariance: SMatrix<f64, 4, 3>,
    /// Centroid `P̄` of the object points.
    object_centroid: Vector3<f64>,
}

/// What one pass over the points gives [`EpnpSystem::new`].
struct PointSums {
    /// `MᵀM` of eq. 8.
    normal_matrix: SMatrix<f64, 12, 12>,
    alpha_mean: Vector4<f64>,
    alpha_object_covariance: SMatrix<f64, 4, 3>,
    object_centroid: Vector3<f64>,
}

/// Lepetit's control points: the centroid, plus one point along each
/// principal axis at the RMS extent of the points along that axis.
pub fn principal_control_points(object: &[Vector3<f64>]) -> [Vector3<f64>; 4] {
    let spread = Spread::of(object);
    let mut control = [spread.centroid; 4];
    for k in 0..3 {
        control[k + 1] += spread.axes.column(k) * spread.extents[k];
    }
    control
}

impl EpnpSystem {
    /// Builds the system for `object`/`image` with the given control points.
    pub fn new(
        control_world: [Vector3<f64>; 4],
        object: &[Vector3<f64>],
        image: &[Vector2<f64>],
    ) -> Result<Self, PnpError> {
        let to_barycentric = barycentric_map(&control_world)?;
        let sums = accumulate_point_sums(&control_world[0], &to_barycentric, object, image);
        let mut system = Self {
            control_world,
            to_barycentric,
            null_space: [Stacked::zeros(); 4],
            distance_products: SMatrix::zeros(),
            control_distances_sq: SVector::zeros(),
            alpha_mean: sums.alpha_mean,
            alpha_object_covariance: sums.alpha_object_covariance,
            object_centroid: sums.object_centroid,
        };
        // Eq. 9: the null space is spanned by the eigenvectors of MᵀM for its
        // four smallest eigenvalues, smallest first.
        system.null_space = smallest_eigenpairs::<12, 4>(&sums.normal_matrix)
            .map_err(|error| PnpError::Degenerate {
                solver: "EPnP",
                reason: match error {
                    EigenError::NonFinite { .. } => "MᵀM has a non-finite entry",
                    _ => "the eigen-decomposition of MᵀM did not converge",
                },
            })?
            .vectors;

        // Lepetit eq. 13: ‖Σ_k β_k (v_k[a] − v_k[b])‖² = ‖c_a − c_b‖².
        for (row, &(a, b)) in PAIRS.iter().enumerate() {
            let dv: [Vector3<f64>; 4] = std::array::from_fn(|k| {
                system.null_space[k].fixed_rows::<3>(3 * a).into_owned()
                    - system.null_space[k].fixed_rows::<3>(3 * b).into_owned()
            });
            let products = [
                dv[0].dot(&dv[0]),
                2.0 * dv[0].dot(&dv[1]),
                dv[1].dot(&dv[1]),
                2.0 * dv[0].dot(&dv[2]),
                2.0 * dv[1].dot(&dv[2]),
                dv[2].dot(&dv[2]),
                2.0 * dv[0].dot(&dv[3]),
                2.0 * dv[1].dot(&dv[3]),
                2.0 * dv[2].dot(&dv[3]),
                dv[3].dot(&dv[3]),
            ];
            for (col, value) in products.into_iter().enumerate() {
                system.distance_products[(row, col)] = value;
            }
            system.control_distances_sq[row] = (control_world[a] - control_world[b]).norm_squared();
        }
        Ok(system)
    }

    /// `MᵀM` of eq. 8 for `object`/`image` under the given control points,
    /// the matrix whose smallest eigenvectors span the solution (eq. 9).
    /// Exposed for tests and benchmarks of the eigen-solver.
    pub fn normal_matrix(
        control_world: [Vector3<f64>; 4],
        object: &[Vector3<f64>],
        image: &[Vector2<f64>],
    ) -> Result<SMatrix<f64, 12, 12>, PnpError> {
        let to_barycentric = barycentric_map(&control_world)?;
        Ok(accumulate_point_sums(&control_world[0], &to_barycentric, object, image).normal_matrix)
    }

    /// Barycentric coordinates `α` of `p` with respect to the control points (eq. 4).
    #[inline]
    pub fn alphas(&self, p: &Vector3<f64>) -> [f64; 4] {
        barycentric(&self.control_world[0], &self.to_barycentric, p)
    }

    /// The world-frame control points.
    pub fn control_world(&self) -> &[Vector3<f64>; 4] {
        &self.control_world
    }

    /// The 6×10 distance-product matrix L.
    pub fn distance_products(&self) -> &SMatrix<f64, 6, 10> {
        &self.distance_products
    }

    /// ρ, the squared world distances of the six control-point pairs.
    pub fn control_distances_sq(&self) -> &SVector<f64, 6> {
        &self.control_distances_sq
    }

    /// Camera-frame control points `x = V β` (eqs. 9 and 15).
    pub fn control_camera(&self, betas: &Vector4<f64>) -> [Vector3<f64>; 4] {
        let stacked: Stacked = self.null_space[0] * betas[0]
            + self.null_space[1] * betas[1]
            + self.null_space[2] * betas[2]
            + self.null_space[3] * betas[3];
        std::array::from_fn(|j| stacked.fixed_rows::<3>(3 * j).into_owned())
    }

    /// The β that best reproduce given camera-frame control points,
    /// `β0 = (VᵀV)⁻¹ Vᵀ x` (eq. 16). V has orthonormal columns, so this is Vᵀx.
    pub fn betas_from_control_camera(&self, control_camera: &[Vector3<f64>; 4]) -> Vector4<f64> {
        let mut stacked = Stacked::zeros();
        for (j, c) in control_camera.iter().enumerate() {
            stacked.fixed_rows_mut::<3>(3 * j).copy_from(c);
        }
        Vector4::from_fn(|k, _| self.null_space[k].dot(&stacked))
    }

    /// Lepetit's closed-form β for null-space dimensions N = 1, 2, 3 and the
    /// linearised approximation for N = 4, in that order.
    pub fn closed_form_betas(&self) -> [Vector4<f64>; 4] {
        [
            self.betas_dimension_1(),
            self.betas_dimension_2(),
            self.betas_dimension_3(),
            self.betas_dimension_4(),
        ]
    }

    /// N = 1: `β = Σ ‖v[a]−v[b]‖·‖c_a−c_b‖ / Σ ‖v[a]−v[b]‖²` (Lepetit eq. 12).
    fn betas_dimension_1(&self) -> Vector4<f64> {
        let (mut numerator, mut denominator) = (0.0, 0.0);
        for row in 0..6 {
            let dv_sq = self.distance_products[(row, 0)];
            numerator += dv_sq.sqrt() * self.control_distances_sq[row].sqrt();
            denominator += dv_sq;
        }
        Vector4::new(numerator / denominator, 0.0, 0.0, 0.0)
    }

    /// N = 2: solve for `[β11, β12, β22]` by least squares over the six
    /// distances (Lepetit §3.3, "linearization").
    fn betas_dimension_2(&self) -> Vector4<f64> {
        let l = self.distance_products.fixed_columns::<3>(0).into_owned();
        let b = solve_least_squares(&l, &self.control_distances_sq);
        let (mut b1, b2) = signed_roots(b[0], b[2]);
        if b[1] < 0.0 {
            b1 = -b1;
        }
        Vector4::new(b1, b2, 0.0, 0.0)
    }

    /// N = 3: solve for `[β11, β12, β22, β13, β23]` (Lepetit §3.3; the
    /// sixth product β33 is dropped as in the reference implementation).
    fn betas_dimension_3(&self) -> Vector4<f64> {
        let l = self.distance_products.fixed_columns::<5>(0).into_owned();
        let b = solve_least_squares(&l, &self.control_distances_sq);
        let (mut b1, b2) = signed_roots(b[0], b[2]);
        if b[1] < 0.0 {
            b1 = -b1;
        }
        let b3 = if b1 != 0.0 { b[3] / b1 } else { 0.0 };
        Vector4::new(b1, b2, b3, 0.0)
    }

    /// N = 4: solve for `[β11, β12, β13, β14]` by least squares, the
    /// approximation the reference implementation uses in place of full
    /// relinearisation; GN then corrects it.
    fn betas_dimension_4(&self) -> Vector4<f64> {
        let l = SMatrix::<f64, 6, 4>::from_columns(&[
            self.distance_products.column(0).into_owned(),
            self.distance_products.column(1).into_owned(),
            self.distance_products.column(3).into_owned(),
            self.distance_products.column(6).into_owned(),
        ]);
        let b = solve_least_squares(&l, &self.control_distances_sq);
        if b[0] < 0.0 {
            let root = (-b[0]).sqrt();
            Vector4::new(root, -b[1] / root, -b[2] / root, -b[3] / root)
        } else if b[0] > 0.0 {
            let root = b[0].sqrt();
            Vector4::new(root, b[1] / root, b[2] / root, b[3] / root)
        } else {
            Vector4::zeros()
        }
    }

    /// Recovers the pose from β: camera-frame control points (eq. 9), then
    /// absolute orientation between the object points and their camera-frame
    /// reconstructions `Σ_j α_ij c_j` (eq. 5). The overall sign of β is
    /// chosen so that the points lie in front of the camera (mean depth
    /// positive).
    ///
    /// Because the reconstructions are linear in the control points, their
    /// centroid is `C ᾱ` and their cross-covariance with the object points
    /// is `C G` (C = [c_0 … c_3], G from [`EpnpSystem::new`]): the same
    /// absolute orientation as over the n points, in O(1).
    pub fn pose_from_betas(&self, betas: &Vector4<f64>) -> Pose {
        let control = self.control_camera(betas);
        let mut camera_centroid = control[0] * self.alpha_mean[0]
            + control[1] * self.alpha_mean[1]
            + control[2] * self.alpha_mean[2]
            + control[3] * self.alpha_mean[3];
        let mut cross_covariance = Matrix3::zeros();
        for (j, c) in control.iter().enumerate() {
            cross_covariance += c * self.alpha_object_covariance.row(j);
        }
        if camera_centroid.z < 0.0 {
            camera_centroid = -camera_centroid;
            cross_covariance = -cross_covariance;
        }
        // FOAM (no SVD) where the cross-covariance is well conditioned, the
        // SVD projection otherwise: the same rotation either way.
        let rotation = foam::nearest_rotation(&cross_covariance);
        let translation = camera_centroid - rotation * self.object_centroid;
        Pose::new(rotation, translation)
    }
}

/// Barycentric coordinates `α` of `p` (eq. 4), given the first control
/// point and the map from `p − c0` to `(α1, α2, α3)`.
#[inline]
fn barycentric(
    control0: &Vector3<f64>,
    to_barycentric: &Matrix3<f64>,
    p: &Vector3<f64>,
) -> [f64; 4] {
    let a = to_barycentric * (p - control0);
    [1.0 - a.x - a.y - a.z, a.x, a.y, a.z]
}

/// One pass over the points: `MᵀM` (eq. 8) without forming M, and the
/// barycentric moments that [`EpnpSystem::pose_from_betas`] needs.
///
/// Eq. 7 in normalised coordinates (fx = fy = 1, principal point 0) gives
/// point i the rows `Σ_j α_ij (x_j − u_i z_j) = 0` and
/// `Σ_j α_ij (y_j − v_i z_j) = 0`, so the 3×3 block (j, k) of `MᵀM` is
/// `Σ_i α_ij α_ik [[1, 0, −u_i], [0, 1, −v_i], [−u_i, −v_i, u_i² + v_i²]]`:
/// four symmetric 4×4 moment matrices (40 products per point) hold it all.
#[allow(clippy::needless_range_loop)]
fn accumulate_point_sums(
    control0: &Vector3<f64>,
    to_barycentric: &Matrix3<f64>,
    object: &[Vector3<f64>],
    image: &[Vector2<f64>],
) -> PointSums {
    // Upper triangles of Σ αα ᵀ, Σ u αα ᵀ, Σ v αα ᵀ, Σ (u²+v²) αα ᵀ, entry
    // (j, k ≥ j) at index UPPER[j][k].
    const UPPER: [[usize; 4]; 4] = [[0, 1, 2, 3], [1, 4, 5, 6], [2, 5, 7, 8], [3, 6, 8, 9]];
    let mut moments = [[0.0f64; 10]; 4];
    let mut alpha_sum = Vector4::zeros();
    let mut alpha_offset_sum = SMatrix::<f64, 4, 3>::zeros();
    let mut offset_sum = Vector3::zeros();
    for (p, m) in object.iter().zip(image) {
        // Offsets from c0 (the centroid, or the paper's reference point)
        // keep the one-pass moments below free of cancellation.
        let offset = p - control0;
        let a = to_barycentric * offset;
        let alphas = Vector4::new(1.0 - a.x - a.y - a.z, a.x, a.y, a.z);
        let weights = [1.0, m.x, m.y, m.x * m.x + m.y * m.y];
        let mut index = 0;
        for j in 0..4 {
            for k in j..4 {
                let product = alphas[j] * alphas[k];
                for (moment, weight) in moments.iter_mut().zip(weights) {
                    moment[index] += weight * product;
                }
                index += 1;
            }
        }
        alpha_sum += alphas;
        alpha_offset_sum += alphas * offset.transpose();
        offset_sum += offset;
    }
    let [plain, by_u, by_v, by_radius] = moments;
    let mut normal_matrix = SMatrix::<f64, 12, 12>::zeros();
    for j in 0..4 {
        for k in 0..4 {
            let i = UPPER[j][k];
            let (r, c) = (3 * j, 3 * k);
            normal_matrix[(r, c)] = plain[i];
            normal_matrix[(r + 1, c + 1)] = plain[i];
            normal_matrix[(r, c + 2)] = -by_u[i];
            normal_matrix[(r + 2, c)] = -by_u[i];
            normal_matrix[(r + 1, c + 2)] = -by_v[i];
            normal_matrix[(r + 2, c + 1)] = -by_v[i];
            normal_matrix[(r + 2, c + 2)] = by_radius[i];
        }
    }
    let count = object.len() as f64;
    let alpha_mean = alpha_sum / count;
    let offset_mean = offset_sum / count;
    PointSums {
        normal_matrix,
        alpha_mean,
        // Σ (α_i − ᾱ)(q_i − q̄)ᵀ = Σ α_i q_iᵀ − n ᾱ q̄ᵀ, with q = P − c0.
        alpha_object_covariance: alpha_offset_sum - alpha_mean * offset_sum.transpose(),
        object_centroid: control0 + offset_mean,
    }
}

/// Inverse of `[c1−c0, c2−c0, c3−c0]`, the map from `p − c0` to `(α1, α2, α3)`.
fn barycentric_map(control_world: &[Vector3<f64>; 4]) -> Result<Matrix3<f64>, PnpError> {
    let basis = Matrix3::from_columns(&[
        control_world[1] - control_world[0],
        control_world[2] - control_world[0],
        control_world[3] - control_world[0],
    ]);
    basis.try_inverse().ok_or(PnpError::Degenerate {
        solver: "EPnP",
        reason: "control points are coplanar",
    })
}

/// Both roots with the sign convention of the reference implementation:
/// `(√|b11|, √|b22|)` when b11 and b22 agree in sign with the solution, else 0.
fn signed_roots(b11: f64, b22: f64) -> (f64, f64) {
    if b11 < 0.0 {
        ((-b11).sqrt(), if b22 < 0.0 { (-b22).sqrt() } else { 0.0 })
    } else {
        (b11.sqrt(), if b22 > 0.0 { b22.sqrt() } else { 0.0 })
    }
}

/// Least squares `min ‖A x − b‖` for a small fixed-size tall matrix, by the
/// normal equations. If A has lost rank numerically, a ridge of
/// [`RIDGE_FRACTION`] of the mean diagonal makes the solve well posed.
fn solve_least_squares<const C: usize>(
    a: &SMatrix<f64, 6, C>,
    b: &SVector<f64, 6>,
) -> SVector<f64, C> {
    let mut ata = a.tr_mul(a);
    let atb = a.tr_mul(b);
    if let Some(solution) = solve_positive_definite(&ata, &atb) {
        return solution;
    }
    let ridge = RIDGE_FRACTION * ata.trace() / C as f64;
    for d in 0..C {
        ata[(d, d)] += ridge;
    }
    solve_positive_definite(&ata, &atb).unwrap_or_else(SVector::zeros)
}

/// Ridge added to a rank-deficient normal matrix, relative to its mean diagonal.
pub const RIDGE_FRACTION: f64 = 1e-12;

/// EPnP (`refine = false`) or EPnP+GN (`refine = true`): one candidate per
/// null-space dimension N = 1…4.
pub fn solve(
    object: &[Vector3<f64>],
    image: &[Vector2<f64>],
    refine: bool,
) -> Result<Candidates, PnpError> {
    let system = EpnpSystem::new(principal_control_points(object), object, image)?;
    Ok(system
        .closed_form_betas()
        .iter()
        .map(|betas| {
            let betas = if refine {
                gauss_newton::refine_betas(&system, betas, &gauss_newton::UNIT_WEIGHTS)
            } else {
                *betas
            };
            system.pose_from_betas(&betas)
        })
        .collect())
}
