//! EPnP: Lepetit, Moreno-Noguer & Fua, "EPnP: An Accurate O(n) Solution to
//! the PnP Problem", IJCV 81(2), 2009. Paper eqs. 4–10 restate it.
//!
//! Every object point is written in barycentric coordinates `α_ij` of four
//! noncoplanar control points (eq. 4); the projection equations (eq. 7) make
//! a 2n×12 system `M x = 0` (eq. 8) in the camera-frame control points, whose
//! solution lies in the span of the eigenvectors of `MᵀM` for the smallest
//! eigenvalues (eq. 9). The coefficients β are fixed by requiring the control
//! points to keep their mutual distances, for null-space dimensions N = 1…4
//! (Lepetit §3.3); [`super::epnp_gn`] refines them by Gauss–Newton (eq. 10,
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

use super::{Candidates, Method, PnpError};
use crate::linalg::{smallest_eigenpairs, solve_positive_definite, EigenError};
use crate::pose::{nearest_rotation, Pose};
use crate::spread::Spread;
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
    /// The fourth-smallest eigenvalue of `MᵀM` over the mean of its eight
    /// largest ([`EpnpSystem::null_space_flatness`]).
    null_space_flatness: f64,
    /// Its smallest eigenvalue: the least residual `xᵀMᵀMx / ‖x‖²` any
    /// control points reach.
    smallest_eigenvalue: f64,
}

/// The distinct entries of `MᵀM`: block (j, k) of control points j and k is
/// `[[p, 0, −u], [0, p, −v], [−u, −v, r]]` with p, u, v, r the entries
/// `UPPER[j][k]` of these four arrays, in this order.
type NormalMoments = [[f64; 10]; 4];

/// Index of the unordered control-point pair (j, k) in [`NormalMoments`].
const UPPER: [[usize; 4]; 4] = [[0, 1, 2, 3], [1, 4, 5, 6], [2, 5, 7, 8], [3, 6, 8, 9]];

/// What one pass over the points gives [`EpnpSystem::new`].
struct PointSums {
    /// `MᵀM` of eq. 8.
    normal_matrix: SMatrix<f64, 12, 12>,
    /// Its distinct entries ([`NormalMoments`]).
    moments: NormalMoments,
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

/// The distinct entries of `MᵀM`, for unrefined EPnP's test of whether the
/// linearised closed forms fit the image ([`EpnpSystem::residual_ratio`]).
/// Kept apart from [`EpnpSystem`] so that the solvers that never ask
/// (EPnP+GN, IEPnP, the paper's family) do not carry it.
#[derive(Debug, Clone)]
pub struct FitTest {
    moments: NormalMoments,
}

impl EpnpSystem {
    /// Builds the system for `object`/`image` with the given control points.
    pub fn new(
        control_world: [Vector3<f64>; 4],
        object: &[Vector3<f64>],
        image: &[Vector2<f64>],
    ) -> Result<Self, PnpError> {
        Self::with_fit_test(control_world, object, image).map(|(system, _)| system)
    }

    /// [`EpnpSystem::new`], and the entries of `MᵀM` that
    /// [`EpnpSystem::relinearises`] reads.
    pub fn with_fit_test(
        control_world: [Vector3<f64>; 4],
        object: &[Vector3<f64>],
        image: &[Vector2<f64>],
    ) -> Result<(Self, FitTest), PnpError> {
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
            null_space_flatness: 0.0,
            smallest_eigenvalue: 0.0,
        };
        // Eq. 9: the null space is spanned by the eigenvectors of MᵀM for its
        // four smallest eigenvalues, smallest first.
        let eigenpairs = smallest_eigenpairs::<12, 4>(&sums.normal_matrix).map_err(|error| {
            PnpError::Degenerate {
                solver: "EPnP",
                reason: match error {
                    EigenError::NonFinite { .. } => "MᵀM has a non-finite entry",
                    _ => "the eigen-decomposition of MᵀM did not converge",
                },
            }
        })?;
        system.null_space = eigenpairs.vectors;
        // The trace is the sum of all twelve eigenvalues, so the mean of the
        // eight largest costs nothing more.
        let largest_eight_mean =
            (sums.normal_matrix.trace() - eigenpairs.values.iter().sum::<f64>()) / 8.0;
        system.null_space_flatness = eigenpairs.values[3] / largest_eight_mean;
        system.smallest_eigenvalue = eigenpairs.values[0];

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
        Ok((
            system,
            FitTest {
                moments: sums.moments,
            },
        ))
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

    /// How close `MᵀM` is to a 4-dimensional null space: its fourth-smallest
    /// eigenvalue over the mean of its eight largest (scale-free; NaN or
    /// negative only for a degenerate system). Lepetit et al. §3.3: the
    /// effective dimension N of the null space grows with the distance to
    /// the camera and reaches 4 under weak perspective, where the solution
    /// needs all four null vectors. Below [`NULL_SPACE_FLAT_BELOW`] it is 4.
    pub fn null_space_flatness(&self) -> f64 {
        self.null_space_flatness
    }

    /// Whether the null space is effectively 4-dimensional, so that the
    /// relinearised N = 4 β ([`EpnpSystem::relinearised_betas`]) is worth
    /// computing whatever the linearised closed forms give:
    /// [`EpnpSystem::null_space_flatness`] below [`NULL_SPACE_FLAT_BELOW`]
    /// (or not a number), or n ≤ [`ALWAYS_RELINEARISE_MAX_POINTS`], where M
    /// has at most ten rows and noise decides the dimension.
    pub fn needs_relinearisation(&self, points: usize) -> bool {
        points <= ALWAYS_RELINEARISE_MAX_POINTS
            || self.null_space_flatness < NULL_SPACE_FLAT_BELOW
            || self.null_space_flatness.is_nan()
    }

    /// Whether unrefined EPnP adds the relinearised N = 4 candidate to
    /// `linearised`, the candidates of the four linearised closed forms:
    /// where the null space is effectively 4-dimensional
    /// ([`EpnpSystem::needs_relinearisation`]), or where none of them fits
    /// the image ([`EpnpSystem::residual_ratio`] above
    /// [`LINEARISED_FIT_RATIO`] for every one, or not a number).
    pub fn relinearises(&self, fit: &FitTest, points: usize, linearised: &[Pose]) -> bool {
        if self.needs_relinearisation(points) {
            return true;
        }
        let least_ratio = linearised
            .iter()
            .map(|pose| self.residual_ratio(fit, pose))
            .fold(f64::INFINITY, f64::min);
        // `f64::min` skips NaN ratios, so none fitting leaves infinity.
        least_ratio > LINEARISED_FIT_RATIO || least_ratio.is_nan()
    }

    /// How badly `pose` fits eq. 8: the residual `xᵀMᵀMx / ‖x‖²` of the
    /// camera-frame control points x it places, over the least residual any
    /// control points reach (the smallest eigenvalue of `MᵀM`). A pose
    /// that fits the image leaves a residual of the noise's size, a few
    /// times that least one; a closed form that failed leaves far more.
    /// Read from the ten distinct 3×3 blocks of `MᵀM` ([`NormalMoments`]).
    pub fn residual_ratio(&self, fit: &FitTest, pose: &Pose) -> f64 {
        let x = self.control_world.map(|c| pose.transform(&c));
        let [plain, by_u, by_v, by_radius] = &fit.moments;
        let mut residual = 0.0;
        for j in 0..4 {
            for k in j..4 {
                let i = UPPER[j][k];
                let (a, b) = (&x[j], &x[k]);
                let block = plain[i] * (a.x * b.x + a.y * b.y)
                    - by_u[i] * (a.x * b.z + a.z * b.x)
                    - by_v[i] * (a.y * b.z + a.z * b.y)
                    + by_radius[i] * a.z * b.z;
                // Off-diagonal blocks appear twice in the quadratic form.
                residual += if j == k { block } else { 2.0 * block };
            }
        }
        let norm_sq: f64 = x.iter().map(|c| c.norm_squared()).sum();
        residual / (norm_sq * self.smallest_eigenvalue)
    }

    /// Lepetit's closed-form β for null-space dimensions N = 1…4, all
    /// linearised as the reference implementation does (N = 4 over four of
    /// the ten products), in that order: the starts of EPnP+GN.
    /// [`EpnpSystem::relinearised_betas`] is the paper's N = 4.
    pub fn closed_form_betas(&self) -> [Vector4<f64>; 4] {
        [
            self.betas_dimension_1(),
            self.betas_dimension_2(),
            self.betas_dimension_3(),
            self.betas_dimension_4_linearised(),
        ]
    }

    /// N = 4 linearised: solve for `[β11, β12, β13, β14]` by least squares,
    /// the approximation of the reference implementation. Near the camera,
    /// where the null space is smaller than four, it is the more accurate of
    /// the two N = 4 starts (6 or 10 points in a 1 m cube at 0.5–1.5 m, 300
    /// problems at σ = 0.5 px: unrefined EPnP at 1.29× the first-order limit
    /// with it, 2.78× with relinearisation in its place); far from it,
    /// relinearisation is (unrefined EPnP returns both where the null space
    /// is effectively 4-dimensional, [`EpnpSystem::needs_relinearisation`]).
    fn betas_dimension_4_linearised(&self) -> Vector4<f64> {
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

    /// N = 4 by relinearisation (Lepetit §3.3, after Kipnis & Shamir): the
    /// six equations `L β̄ = ρ` leave the ten products β̄ in a 4-dimensional
    /// affine space `β̄ = u₀ + Σ λ_i u_i`. The products must come from one
    /// β (`β̄_ab β̄_cd = β̄_ac β̄_bd`: twenty independent relations), which
    /// is linear in the fifteen products `λ_i λ_j` (λ₀ = 1); least squares
    /// gives them, and `λ_i = λ₀ λ_i` gives β̄. Linearising over four of
    /// the ten products instead, as the reference implementation does,
    /// drops six terms: far from the camera, where N = 4 is the right
    /// dimension, that start is grossly wrong. Measured on the conformance
    /// sweep's far-field regime (a 50 mm biprism at 1–3 m, σ = 0.5 px, 300
    /// problems, no Gauss–Newton): 247 off by more than 10° with the four
    /// linearised closed forms, 33 with this one beside them (unrefined
    /// EPnP returns both, for the near field's sake, where
    /// [`EpnpSystem::needs_relinearisation`] says the null space is
    /// effectively 4-dimensional). On a similar draw of
    /// 300 problems, 257 fell to 15 with this one in place of the N = 4
    /// linearisation and to 34 with both. Gauss–Newton with backtracking
    /// and the mirror candidate needs no relinearised start (EPnP+GN: 0
    /// gross failures there from the four linearised ones), so EPnP+GN does
    /// not pay for it.
    pub fn relinearised_betas(&self) -> Vector4<f64> {
        let Some((particular, null_space)) =
            minimum_norm_and_null_space(&self.distance_products, &self.control_distances_sq)
        else {
            return Vector4::zeros();
        };
        // u₀ and the unit null vectors scaled alike, so that the columns of
        // the relinearised system are of one size.
        let scale = particular.norm();
        if !(scale > 0.0 && scale.is_finite()) {
            return Vector4::zeros();
        }
        let basis: [SVector<f64, 10>; 5] = [
            particular,
            null_space[0] * scale,
            null_space[1] * scale,
            null_space[2] * scale,
            null_space[3] * scale,
        ];
        // Each relation is one row over the products λ_i λ_j (i ≤ j, not
        // (0, 0), which is 1). For a product pair (p, q) the coefficient of
        // λ_i λ_j is `a_i b_j + a_j b_i` (`a_i b_i` on the diagonal), with
        // a, b the p-th and q-th entries of the basis. The system is kept
        // by columns, so that each entry of its normal equations (lower
        // triangle only) is one dot product of length 20.
        let entries: [[f64; 5]; 10] = std::array::from_fn(|p| std::array::from_fn(|i| basis[i][p]));
        let mut columns = [[0.0f64; 20]; 15];
        for (row, &(p, q, p2, q2)) in RANK_ONE_RELATIONS.iter().enumerate() {
            let (a, b, c, d) = (&entries[p], &entries[q], &entries[p2], &entries[q2]);
            let mut column = 0;
            for i in 0..5 {
                columns[column][row] = a[i] * b[i] - c[i] * d[i];
                column += 1;
                for j in i + 1..5 {
                    columns[column][row] = a[i] * b[j] + a[j] * b[i] - c[i] * d[j] - c[j] * d[i];
                    column += 1;
                }
            }
        }
        // Column 0 multiplies λ₀² = 1: it moves to the right-hand side.
        let dot = |x: &[f64; 20], y: &[f64; 20]| x.iter().zip(y).map(|(x, y)| x * y).sum::<f64>();
        let mut normal = SMatrix::<f64, 14, 14>::zeros();
        let mut moment = SVector::<f64, 14>::zeros();
        for r in 0..14 {
            moment[r] = -dot(&columns[r + 1], &columns[0]);
            for c in 0..=r {
                normal[(r, c)] = dot(&columns[r + 1], &columns[c + 1]);
            }
        }
        let products = solve_normal_equations(normal, &moment);
        // λ₀ λ_i for i = 1…4 are the first four unknowns.
        let mut combined = basis[0];
        for i in 0..4 {
            combined += basis[i + 1] * products[i];
        }
        betas_from_products(&combined)
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
        self.recover(betas).pose
    }

    /// [`EpnpSystem::pose_from_betas`], and whether the reconstruction is a
    /// mirror image of the object: its cross-covariance with the object
    /// points has a negative determinant, so the nearest rotation fits it
    /// badly. The distance constraints of eq. 13 cannot tell a shape from
    /// its mirror image, and far from the camera the depth-reversed mirror
    /// (a reflection in a plane facing the camera) projects almost as the
    /// shape does, so Gauss–Newton can converge to it.
    pub fn recover(&self, betas: &Vector4<f64>) -> Recovered {
        let (camera_centroid, cross_covariance) = self.reconstruction_moments(betas);
        // FOAM (no SVD) where the cross-covariance is well conditioned, the
        // SVD projection otherwise: the same rotation either way.
        let rotation = nearest_rotation(&cross_covariance);
        let translation = camera_centroid - rotation * self.object_centroid;
        Recovered {
            pose: Pose::new(rotation, translation),
            reflected: cross_covariance.determinant() < 0.0,
        }
    }

    /// The camera-frame control points of β with the sign of β chosen to
    /// put the reconstruction's centroid in front of the camera, and that
    /// centroid `C ᾱ`.
    fn control_in_front(&self, betas: &Vector4<f64>) -> ([Vector3<f64>; 4], Vector3<f64>) {
        let mut control = self.control_camera(betas);
        let centroid = control[0] * self.alpha_mean[0]
            + control[1] * self.alpha_mean[1]
            + control[2] * self.alpha_mean[2]
            + control[3] * self.alpha_mean[3];
        if centroid.z < 0.0 {
            for c in &mut control {
                *c = -*c;
            }
            return (control, -centroid);
        }
        (control, centroid)
    }

    /// The centroid of the camera-frame reconstruction and its
    /// cross-covariance `C G` with the object points, in front of the camera.
    fn reconstruction_moments(&self, betas: &Vector4<f64>) -> (Vector3<f64>, Matrix3<f64>) {
        let (control, centroid) = self.control_in_front(betas);
        let mut cross_covariance = Matrix3::zeros();
        for (j, c) in control.iter().enumerate() {
            cross_covariance += c * self.alpha_object_covariance.row(j);
        }
        (centroid, cross_covariance)
    }

    /// The β of the depth-reversed mirror of the reconstruction: its control
    /// points reflected in the plane `z = z̄` through the reconstruction's
    /// centroid, projected back onto the null space (eq. 16). Lepetit et
    /// al.'s reference code meets a negative determinant by reflecting in
    /// camera z; this is that reflection, offered as a further candidate.
    /// The reconstructions are affine in the control points, so reflecting
    /// the control points reflects every reconstructed point.
    pub fn mirrored_betas(&self, betas: &Vector4<f64>) -> Vector4<f64> {
        let (mut control, centroid) = self.control_in_front(betas);
        for c in &mut control {
            c.z = 2.0 * centroid.z - c.z;
        }
        self.betas_from_control_camera(&control)
    }

    /// Appends to `candidates` the pose for `refine(start)` and, when that
    /// reconstruction is a mirror image of the object
    /// ([`EpnpSystem::recover`]), the pose for `refine` applied to its
    /// depth-reversed mirror ([`EpnpSystem::mirrored_betas`]); the
    /// reprojection error then chooses between them. With `refine` the
    /// identity this is the unrefined EPnP candidate and its mirror. The
    /// mirror costs nothing when the reconstruction is proper, the common
    /// case.
    pub fn push_candidates(
        &self,
        start: &Vector4<f64>,
        refine: impl Fn(&Vector4<f64>) -> Vector4<f64>,
        candidates: &mut Candidates,
    ) {
        let betas = refine(start);
        let recovered = self.recover(&betas);
        candidates.push(recovered.pose);
        if recovered.reflected {
            candidates.push(self.pose_from_betas(&refine(&self.mirrored_betas(&betas))));
        }
    }
}

/// A pose recovered from β ([`EpnpSystem::recover`]).
#[derive(Debug, Clone, Copy)]
pub struct Recovered {
    /// The pose: the rotation nearest the reconstruction's cross-covariance.
    pub pose: Pose,
    /// Whether the reconstruction is a mirror image of the object.
    pub reflected: bool,
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
        moments,
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
fn solve_least_squares<const R: usize, const C: usize>(
    a: &SMatrix<f64, R, C>,
    b: &SVector<f64, R>,
) -> SVector<f64, C> {
    solve_normal_equations(a.tr_mul(a), &a.tr_mul(b))
}

/// Solves the normal equations `AᵀA x = Aᵀb` (lower triangle read), with a
/// ridge of [`RIDGE_FRACTION`] of the mean diagonal if `AᵀA` has lost rank
/// numerically; zeros if even that fails.
fn solve_normal_equations<const C: usize>(
    mut ata: SMatrix<f64, C, C>,
    atb: &SVector<f64, C>,
) -> SVector<f64, C> {
    if let Some(solution) = solve_positive_definite(&ata, atb) {
        return solution;
    }
    let ridge = RIDGE_FRACTION * ata.trace() / C as f64;
    for d in 0..C {
        ata[(d, d)] += ridge;
    }
    solve_positive_definite(&ata, atb).unwrap_or_else(SVector::zeros)
}

/// The twenty independent relations `β̄_p β̄_q = β̄_p' β̄_q'` that ten
/// products of one β satisfy, as column indices of L `(p, q, p', q')`:
/// every pair of products with the same four β factors, chained.
const RANK_ONE_RELATIONS: [(usize, usize, usize, usize); 20] = [
    (0, 2, 1, 1),
    (0, 4, 1, 3),
    (0, 7, 1, 6),
    (0, 5, 3, 3),
    (0, 8, 3, 6),
    (0, 9, 6, 6),
    (1, 4, 2, 3),
    (1, 7, 2, 6),
    (1, 5, 3, 4),
    (1, 8, 3, 7),
    (1, 8, 4, 6),
    (1, 9, 6, 7),
    (3, 8, 5, 6),
    (3, 9, 6, 8),
    (2, 5, 4, 4),
    (2, 8, 4, 7),
    (2, 9, 7, 7),
    (4, 8, 5, 7),
    (4, 9, 7, 8),
    (5, 9, 8, 8),
];

/// Column of L for the product `β_a β_b`.
pub const PRODUCT_COLUMN: [[usize; 4]; 4] =
    [[0, 1, 3, 6], [1, 2, 4, 7], [3, 4, 5, 8], [6, 7, 8, 9]];

/// β from its ten products β̄: the root of the largest square, and the other
/// entries divided by it. The overall sign is free (the pose recovery puts
/// the points in front); a negative largest square means the products came
/// out with the opposite sign, so they are negated first.
fn betas_from_products(products: &SVector<f64, 10>) -> Vector4<f64> {
    let square_of = |j: usize| products[PRODUCT_COLUMN[j][j]];
    let k = (1..4).fold(0, |k, j| {
        if square_of(j).abs() > square_of(k).abs() {
            j
        } else {
            k
        }
    });
    let square = products[PRODUCT_COLUMN[k][k]];
    let sign = if square < 0.0 { -1.0 } else { 1.0 };
    let root = (sign * square).sqrt();
    if !(root > 0.0 && root.is_finite()) {
        return Vector4::zeros();
    }
    Vector4::from_fn(|j, _| {
        if j == k {
            root
        } else {
            sign * products[PRODUCT_COLUMN[j][k]] / root
        }
    })
}

/// The minimum-norm solution of the underdetermined `L x = ρ` (6×10, full
/// row rank) and an orthonormal basis of the null space of L, from a
/// Householder QR of `Lᵀ = Q R` (Golub & Van Loan §5.2): `x = Q₁ R⁻ᵀ ρ`
/// and the null space is spanned by the last four columns of Q. `None` if
/// L has lost rank. Fixed arrays, nothing allocated.
#[allow(clippy::needless_range_loop)]
fn minimum_norm_and_null_space(
    l: &SMatrix<f64, 6, 10>,
    rho: &SVector<f64, 6>,
) -> Option<(SVector<f64, 10>, [SVector<f64, 10>; 4])> {
    // Columns of Lᵀ (the rows of L), reduced in place to R.
    let mut columns: [[f64; 10]; 6] = std::array::from_fn(|k| std::array::from_fn(|i| l[(k, i)]));
    let mut reflectors = [[0.0f64; 10]; 6];
    let mut factors = [0.0f64; 6];
    let scale = l.amax();
    if !(scale > 0.0 && scale.is_finite()) {
        return None;
    }
    for k in 0..6 {
        let norm = columns[k][k..].iter().map(|v| v * v).sum::<f64>().sqrt();
        // Written so that a NaN norm counts as rank lost.
        if norm.is_nan() || norm <= NULL_SPACE_RANK_TOLERANCE * scale {
            return None;
        }
        let alpha = if columns[k][k] > 0.0 { -norm } else { norm };
        let v = &mut reflectors[k];
        v[k..].copy_from_slice(&columns[k][k..]);
        v[k] -= alpha;
        let v_norm_sq: f64 = v[k..].iter().map(|x| x * x).sum();
        factors[k] = 2.0 / v_norm_sq;
        for j in k..6 {
            let projection = factors[k] * (k..10).map(|i| v[i] * columns[j][i]).sum::<f64>();
            for i in k..10 {
                columns[j][i] -= projection * v[i];
            }
        }
    }
    // Q y = H₀ H₁ … H₅ y.
    let apply_q = |mut y: [f64; 10]| -> SVector<f64, 10> {
        for k in (0..6).rev() {
            let v = &reflectors[k];
            let projection = factors[k] * (k..10).map(|i| v[i] * y[i]).sum::<f64>();
            for i in k..10 {
                y[i] -= projection * v[i];
            }
        }
        SVector::from(y)
    };
    // Rᵀ y = ρ, R upper triangular: R[i][j] is columns[j][i].
    let mut y = [0.0f64; 10];
    for i in 0..6 {
        let mut value = rho[i];
        for k in 0..i {
            value -= columns[i][k] * y[k];
        }
        y[i] = value / columns[i][i];
    }
    let null_space = std::array::from_fn(|m| {
        let mut unit = [0.0f64; 10];
        unit[6 + m] = 1.0;
        apply_q(unit)
    });
    Some((apply_q(y), null_space))
}

/// Below this fraction of L's largest entry a Householder column norm
/// counts as zero: L has lost rank and relinearisation is not posed.
pub const NULL_SPACE_RANK_TOLERANCE: f64 = 1e-12;

/// EPnP+GN also starts from the relinearised N = 4 β up to this many points:
/// with n points M has 2n rows, so n = 4 leaves a null space of dimension
/// 12 − 8 = 4 for every pose.
pub const RELINEARISED_START_MAX_POINTS: usize = 4;

/// Unrefined EPnP computes the relinearised N = 4 β only when
/// [`EpnpSystem::null_space_flatness`] is below this (or n ≤
/// [`RELINEARISED_START_MAX_POINTS`]): relinearisation costs about as much
/// as the rest of EPnP, and only where the null space is effectively
/// 4-dimensional does it rescue the linearised closed forms. Measured
/// (σ = 0.5 px): the far-field biprism (50 mm at 1–3 m, 1000 problems) lies
/// at 4.9·10⁻⁵–7.9·10⁻⁴, so the gate always opens there (122 gross failures
/// with and without it, 840 with no relinearisation); the 7-point biprism
/// of the criterion benchmark (100 mm at 0.2–1 m, 2000 problems) lies at
/// 2.2·10⁻³–9.8·10⁻², so the gate never opens there; over 48,347
/// problems of depth/size 0.5–200, n 4–20, thickness 0.01–1 at σ 0 and
/// 0.5 px, 12,442 gross failures with the gate against 12,414 with
/// relinearisation always and 16,526 with none, and the same noise-free
/// misses with and without it.
pub const NULL_SPACE_FLAT_BELOW: f64 = 2e-3;

/// Unrefined EPnP always computes the relinearised β up to this many
/// points: with five, M has ten rows, its null space is at least
/// 2-dimensional for every pose and the noise decides the rest. (With the
/// flatness test alone, five points at depth/size 5, σ = 0.5 px lost 9 more
/// problems of 300 to gross errors than with relinearisation always.)
pub const ALWAYS_RELINEARISE_MAX_POINTS: usize = 5;

/// Unrefined EPnP also computes the relinearised β when every linearised
/// candidate leaves more than this many times the least residual of eq. 8
/// ([`EpnpSystem::residual_ratio`]): the closed forms failed. Noise, not
/// the far field, is then what defeats them (depth/size 2–10 at σ = 1–5 px).
/// Measured once over 24,000 problems per σ (depth/size 0.5–200, n 4–20,
/// thickness 0.01–1, uniform in the image), gross failures with the
/// flatness test and five points alone against relinearisation always:
/// +2, +17, +52, +98 at σ = 0.5, 1, 2, 5 px; with this test too (there
/// on the best linearised candidate by reprojection error; the code takes
/// the least ratio over all of them, which fires no more often), 0, +1,
/// +4, +34 at a ratio of 20, 0, +2, +9, +45 at 50 (this value), 0, +5,
/// +17, +60 at 100. The lower the ratio, the more often the common case
/// pays: on the criterion benchmark's biprism it fires on 45 of 250
/// problems at 20, on 19 at 50
/// (`noisy::epnp_relinearises_in_the_far_field_only`). On the conformance
/// sweep (31,200 problems) unrefined EPnP has 3617 gross failures gated
/// against 3601 relinearising always, 15 of the 16 at σ = 5 px
/// (depth/size 5, 10 points), a cell that is not well-posed.
pub const LINEARISED_FIT_RATIO: f64 = 50.0;

/// Ridge added to a rank-deficient normal matrix, relative to its mean diagonal.
pub const RIDGE_FRACTION: f64 = 1e-12;

/// `epnp`: EPnP without refinement (Lepetit et al. 2009).
pub const EPNP: Method = Method {
    name: "epnp",
    display_name: "EPnP",
    description: "EPnP, no refinement, null-space cases N = 1..4 (Lepetit et al. 2009)",
    min_points: 4,
    accepts_coplanar: false,
    exact: true,
    start: None,
    solve,
};

/// EPnP: one candidate per closed form, the four linearised ones and,
/// where the null space is effectively 4-dimensional
/// ([`EpnpSystem::needs_relinearisation`]) or none of those four fits the
/// image ([`LINEARISED_FIT_RATIO`]), the relinearised N = 4; plus the
/// depth-reversed mirror of any candidate whose reconstruction is a mirror
/// image of the object ([`EpnpSystem::push_candidates`]). EPnP+GN, which
/// refines these, is [`super::epnp_gn`].
pub fn solve(object: &[Vector3<f64>], image: &[Vector2<f64>]) -> Result<Candidates, PnpError> {
    let (system, fit) = EpnpSystem::with_fit_test(principal_control_points(object), object, image)?;
    let mut candidates = Candidates::new();
    for betas in &system.closed_form_betas() {
        system.push_candidates(betas, |start| *start, &mut candidates);
    }
    if system.relinearises(&fit, object.len(), &candidates) {
        system.push_candidates(
            &system.relinearised_betas(),
            |start| *start,
            &mut candidates,
        );
    }
    Ok(candidates)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Rotation3;

    /// The block-wise residual of [`EpnpSystem::residual_ratio`] equals the
    /// quadratic form of the full `MᵀM`.
    #[test]
    fn residual_ratio_is_the_quadratic_form_of_the_normal_matrix() {
        let object = [
            Vector3::new(40.0, -25.0, 10.0),
            Vector3::new(-30.0, 5.0, 20.0),
            Vector3::new(0.0, 35.0, -15.0),
            Vector3::new(10.0, 10.0, 40.0),
            Vector3::new(-20.0, -30.0, -25.0),
            Vector3::new(25.0, 15.0, -5.0),
        ];
        let truth = Pose::new(
            Rotation3::from_euler_angles(0.3, -0.7, 1.1),
            Vector3::new(30.0, -20.0, 400.0),
        );
        let image: Vec<Vector2<f64>> = object
            .iter()
            .enumerate()
            .map(|(i, p)| truth.project_normalised(p) + Vector2::new(1e-3 * i as f64, -2e-3))
            .collect();
        let control = principal_control_points(&object);
        let (system, fit) = EpnpSystem::with_fit_test(control, &object, &image).unwrap();
        let normal = EpnpSystem::normal_matrix(control, &object, &image).unwrap();
        let smallest = smallest_eigenpairs::<12, 1>(&normal).unwrap().values[0];
        let pose = Pose::new(
            Rotation3::from_euler_angles(0.35, -0.6, 1.0),
            Vector3::new(25.0, -15.0, 420.0),
        );
        let x = Stacked::from_fn(|i, _| pose.transform(&control[i / 3])[i % 3]);
        let expected = (normal * x).dot(&x) / (x.norm_squared() * smallest);
        let ratio = system.residual_ratio(&fit, &pose);
        assert!(
            (ratio - expected).abs() <= 1e-9 * expected,
            "{ratio} against {expected}"
        );
    }
}
