//! OPnP: Zheng, Kuang, Sugimoto, Åström & Okutomi, "Revisiting the PnP
//! Problem: A Fast, General and Optimal Solution", ICCV 2013.
//!
//! The steps below follow the paper and the authors' public MATLAB code
//! (`OPnP.m`, `PnP_Polish.m`, and a solver generated with the automatic
//! generator of Kukelova, Bujnak & Pajdla, ECCV 2008), read for
//! understanding; the derivations here are ours, and steps are named by
//! content rather than by the paper's equation numbers.
//!
//! **Parameterisation.** The rotation is written with a
//! *non-unit* quaternion `q = (a, b, c, d)`: `R = R̄(q)/‖q‖²`, where `R̄(q)`
//! is the usual quaternion matrix with entries quadratic in `q` (e.g.
//! `R̄₁₁ = a² + b² − c² − d²`, `R̄₁₂ = 2(bc − ad)`). The free scale of `q` is
//! the depth gauge: `‖q‖² = L / z̄`, with `z̄ = r₃·X̄ + t₃` the depth of the
//! object-point centroid `X̄` and `L` a fixed length (below). With centred,
//! scaled points `X̂ᵢ = (Xᵢ − X̄)/L` and the centroid's camera position `c`,
//! the projection `uᵢ (r₃Xᵢ + t₃) = r₁Xᵢ + t₁` divided by `z̄` (so that
//! `r₃(Xᵢ − X̄)/z̄ = r̄₃·X̂ᵢ`) becomes
//!
//! `uᵢ (r̄₃·X̂ᵢ + 1) − r̄₁·X̂ᵢ − t̃₁ = 0`,  `vᵢ (r̄₃·X̂ᵢ + 1) − r̄₂·X̂ᵢ − t̃₂ = 0`,
//!
//! with `r̄ⱼ` the rows of `R̄(q)` and `(t̃₁, t̃₂) = (c₁, c₂)/z̄` the
//! normalised image of the centroid. Both are linear in `z = [1, m(q)]`,
//! `m(q) = (a², ab, ac, ad, b², bc, bd, c², cd, d²)`, and in `t̃`. Each
//! residual is the reprojection error weighted by `zᵢ/z̄` (point depth over
//! centroid depth): this is the paper's algebraic cost.
//!
//! **Translation eliminated in closed form.** `t̃` enters with coefficient
//! −1 in every residual, so its least-squares value is the mean over the
//! points; substituting it back leaves `f(q) = zᵀ Q z` with an 11×11 positive
//! semidefinite `Q` (we accumulate the centred scatter directly, which avoids
//! the cancellation of `NᵀN − n·ḡḡᵀ`).
//!
//! **First-order optimality conditions.** `q` is unconstrained, so the
//! minimisers are among the stationary points `∇f(q) = 0`: four cubic
//! equations in `(a, b, c, d)` whose monomials all have odd degree (3 and 1).
//! They have 81 solutions: `q = 0` and 40 pairs `±q`. [`action`] solves them
//! with an elimination template and an action matrix of size 40 (the paper's
//! generated solver, exploiting the same symmetry, is built by the automatic
//! generator of Kukelova et al.; ours is built programmatically at first use
//! and documented there).
//!
//! **Recovery and polishing.** For each real pair, `q` is polished by Newton's
//! method on `∇f = 0` (the paper's implementation takes one damped Newton
//! step; we iterate to convergence, which makes noise-free recovery exact to
//! rounding), kept only if the Hessian of `f` is positive semidefinite (a
//! local minimum — the paper's implementation drops the others too), and
//! turned into `R = R̄(q)/‖q‖²`, `z̄ = L/‖q‖²`, `c = z̄·(t̃₁, t̃₂, 1)`,
//! `t = c − R X̄`. Every such pose is returned; [`super::best_candidate`]
//! picks the lowest reprojection error among those in front of the camera.
//! (The authors' code, for n > 6, keeps only the candidates of least
//! algebraic cost; we return every minimum and let the project's common
//! selection rule decide.)
//!
//! **Candidate counts** (`cargo run --release --features examples --example opnp_report`, 1000
//! seeded problems, biprism and random n = 6…100, depth/size 2–200,
//! σ = 0.5 px): the action matrix had median 4 real eigenvalues (max 8),
//! giving median 2 real pairs `±q` (max 4), of which OPnP returned median 1
//! local minimum (max 2), all with every point in front.
//!
//! **Scale `L`.** The gauge fixes `‖q‖² = L/z̄`; we take `L` = RMS object
//! radius / RMS image radius, the weak-perspective depth estimate, so the
//! sought solution has `‖q‖ ≈ 1`, which keeps the monomials of the
//! elimination template (up to degree 8) well scaled. `L` does not change
//! the cost being minimised, only the numerical scale of `q`.
//!
//! **Cost.** One solve takes about 0.93–1.15 ms on one core of the project's
//! machine, independent of n (the same example; EPnP takes 6–30 µs there,
//! so OPnP is 37–176× slower, not the ≈5× the paper reports for its MATLAB
//! implementations; it was 1.35–1.6 ms before the degree-8 tail was
//! deferred and the Schur vectors dropped, see [`action`]). About two
//! thirds of it is the Gaussian elimination of the degree-8 template block
//! (≈170 × 165 with complete pivoting, a few million multiply-adds), an
//! eighth the eigenvalues of the 40 × 40 action matrix. The template
//! blocks (about 0.4 MB) are allocated per solve; the cost, gradient,
//! Hessian and pose use fixed-size types.
//!
//! **Requirements.** n ≥ 4 points, not collinear; planar and nonplanar sets
//! are both handled (the quaternion keeps `R` a rotation, so no third column
//! needs to be inferred). The image points must not all coincide.

pub mod action;
pub mod monomials;

use super::{Candidates, Method, PnpError};
use crate::pose::Pose;
use monomials::{Exponent, CUBIC, CUBIC_COUNT, QUADRATIC};
use nalgebra::{
    Matrix4, Quaternion, SMatrix, SVector, SymmetricEigen, UnitQuaternion, Vector2, Vector3,
    Vector4,
};

/// Human name used in errors.
pub const NAME: &str = "OPnP";
/// Fewest correspondences OPnP accepts.
pub const MIN_POINTS: usize = 4;
/// The image points are taken as coincident when their RMS spread is below
/// this (normalised image units, i.e. radians near the axis).
pub const IMAGE_SPREAD_TOLERANCE: f64 = 1e-12;
/// Newton iterations at most when polishing a stationary point.
pub const MAX_NEWTON_ITERATIONS: usize = 25;
/// Newton stops when a step is shorter than this fraction of `‖q‖`.
pub const NEWTON_STEP_TOLERANCE: f64 = 1e-15;
/// A polished point is a local minimum when the smallest Hessian eigenvalue
/// is at least `−MINIMUM_TOLERANCE` times the largest.
pub const MINIMUM_TOLERANCE: f64 = 1e-8;
/// Two polished solutions closer than this fraction of `‖q‖` (up to sign)
/// are the same stationary point.
pub const DUPLICATE_TOLERANCE: f64 = 1e-9;

/// 11-vector `z = [1, m(q)]`.
type Lifted = SVector<f64, 11>;

/// `∂m_l/∂q_p = factor · q_r`, one entry per nonzero derivative.
#[derive(Debug, Clone, Copy)]
struct Derivative {
    monomial: usize,
    variable: usize,
    factor: f64,
    times: usize,
}

/// Nonzero first derivatives of the ten quadratic monomials.
fn derivatives() -> Vec<Derivative> {
    let mut out = Vec::new();
    for (l, m) in QUADRATIC.iter().enumerate() {
        for p in 0..4 {
            if m[p] == 0 {
                continue;
            }
            let mut rest = *m;
            rest[p] -= 1;
            let r = rest.iter().position(|&e| e == 1).unwrap();
            out.push(Derivative {
                monomial: l,
                variable: p,
                factor: f64::from(m[p]),
                times: r,
            });
        }
    }
    out
}

/// `R̄(q)` as a linear map of `m(q)`: `ROTATION_COEFFICIENTS[j][k][l]` is the
/// coefficient of `m_l` in entry `(j, k)`.
const ROTATION_COEFFICIENTS: [[[f64; 10]; 3]; 3] = {
    // m = a², ab, ac, ad, b², bc, bd, c², cd, d²
    [
        [
            [1., 0., 0., 0., 1., 0., 0., -1., 0., -1.],
            [0., 0., 0., -2., 0., 2., 0., 0., 0., 0.],
            [0., 0., 2., 0., 0., 0., 2., 0., 0., 0.],
        ],
        [
            [0., 0., 0., 2., 0., 2., 0., 0., 0., 0.],
            [1., 0., 0., 0., -1., 0., 0., 1., 0., -1.],
            [0., -2., 0., 0., 0., 0., 0., 0., 2., 0.],
        ],
        [
            [0., 0., -2., 0., 0., 0., 2., 0., 0., 0.],
            [0., 2., 0., 0., 0., 0., 0., 0., 2., 0.],
            [1., 0., 0., 0., -1., 0., 0., -1., 0., 1.],
        ],
    ]
};

/// Row `j` of `R̄(q)` applied to `x`, as coefficients of `m(q)`.
fn rotation_row(j: usize, x: &Vector3<f64>) -> SVector<f64, 10> {
    SVector::from_fn(|l, _| (0..3).map(|k| ROTATION_COEFFICIENTS[j][k][l] * x[k]).sum())
}

/// `m(q)`.
fn quadratic_monomials(q: &Vector4<f64>) -> SVector<f64, 10> {
    let q = [q[0], q[1], q[2], q[3]];
    SVector::from_fn(|l, _| monomials::evaluate(&QUADRATIC[l], &q))
}

/// The algebraic cost `f(q) = zᵀ Q z` of one problem, with what is needed to
/// turn a minimiser back into a pose.
#[derive(Debug, Clone)]
pub struct AlgebraicCost {
    q_matrix: SMatrix<f64, 11, 11>,
    /// Rows giving `t̃₁ = ḡ_xᵀ z` and `t̃₂ = ḡ_yᵀ z`.
    centroid_image: [Lifted; 2],
    centroid: Vector3<f64>,
    length_scale: f64,
    derivatives: Vec<Derivative>,
}

impl AlgebraicCost {
    /// Builds `Q` for `object`/`image` (validated).
    pub fn new(object: &[Vector3<f64>], image: &[Vector2<f64>]) -> Result<Self, PnpError> {
        let count = object.len() as f64;
        let (centroid, object_radius) = super::centroid_and_rms_radius(object);
        let image_centroid = image.iter().sum::<Vector2<f64>>() / count;
        let image_radius = (image
            .iter()
            .map(|m| (m - image_centroid).norm_squared())
            .sum::<f64>()
            / count)
            .sqrt();
        if image_radius.is_nan() || image_radius <= IMAGE_SPREAD_TOLERANCE {
            return Err(PnpError::Degenerate {
                solver: NAME,
                reason: "the image points coincide",
            });
        }
        let length_scale = object_radius / image_radius;

        // Residual rows g: x-row [u, u·P₃(X̂) − P₁(X̂)], y-row likewise.
        let rows = |p: &Vector3<f64>, m: &Vector2<f64>| -> [Lifted; 2] {
            let x = (p - centroid) / length_scale;
            let third = rotation_row(2, &x);
            let mut out = [Lifted::zeros(); 2];
            for (axis, row) in out.iter_mut().enumerate() {
                let image_coordinate = m[axis];
                row[0] = image_coordinate;
                let own = rotation_row(axis, &x);
                for l in 0..10 {
                    row[l + 1] = image_coordinate * third[l] - own[l];
                }
            }
            out
        };
        let mut mean = [Lifted::zeros(); 2];
        for (p, m) in object.iter().zip(image) {
            let r = rows(p, m);
            mean[0] += r[0];
            mean[1] += r[1];
        }
        mean[0] /= count;
        mean[1] /= count;
        let mut q_matrix = SMatrix::<f64, 11, 11>::zeros();
        for (p, m) in object.iter().zip(image) {
            let r = rows(p, m);
            for axis in 0..2 {
                let centred = r[axis] - mean[axis];
                q_matrix.syger(1.0, &centred, &centred, 1.0);
            }
        }
        q_matrix.fill_upper_triangle_with_lower_triangle();
        Ok(Self {
            q_matrix,
            centroid_image: mean,
            centroid,
            length_scale,
            derivatives: derivatives(),
        })
    }

    fn lifted(q: &Vector4<f64>) -> Lifted {
        let m = quadratic_monomials(q);
        Lifted::from_fn(|k, _| if k == 0 { 1.0 } else { m[k - 1] })
    }

    /// `f(q)`.
    pub fn value(&self, q: &Vector4<f64>) -> f64 {
        let z = Self::lifted(q);
        (z.transpose() * self.q_matrix * z)[0]
    }

    /// `∇f(q)`.
    pub fn gradient(&self, q: &Vector4<f64>) -> Vector4<f64> {
        let w = self.q_matrix * Self::lifted(q);
        let mut g = Vector4::zeros();
        for d in &self.derivatives {
            g[d.variable] += 2.0 * w[d.monomial + 1] * d.factor * q[d.times];
        }
        g
    }

    /// Hessian of `f` at `q`.
    pub fn hessian(&self, q: &Vector4<f64>) -> Matrix4<f64> {
        let w = self.q_matrix * Self::lifted(q);
        // J = ∂m/∂q (10×4).
        let mut jacobian = SMatrix::<f64, 10, 4>::zeros();
        for d in &self.derivatives {
            jacobian[(d.monomial, d.variable)] += d.factor * q[d.times];
        }
        let q_mm = self.q_matrix.fixed_view::<10, 10>(1, 1);
        let mut h = 2.0 * jacobian.transpose() * q_mm * jacobian;
        // Second derivatives of m_l are constant: ∂²(q_r q_s) = 1 at (r, s), (s, r); ∂²q_r² = 2.
        for d in &self.derivatives {
            h[(d.variable, d.times)] += 2.0 * w[d.monomial + 1] * d.factor;
        }
        h
    }

    /// The four optimality conditions `½ ∂f/∂q_p = 0` as odd cubic equations
    /// (the optimality conditions), each scaled to unit coefficient norm.
    pub fn equations(&self) -> [action::OddCubic; 4] {
        let mut equations = [[0.0; action::EQUATION_TERMS]; 4];
        let cubic_index = |e: &Exponent| monomials::position(&CUBIC, e).unwrap();
        for d in &self.derivatives {
            let equation = &mut equations[d.variable];
            // Linear part: factor · Q[l+1][0] · q_r.
            equation[CUBIC_COUNT + d.times] += d.factor * self.q_matrix[(d.monomial + 1, 0)];
            // Cubic part: factor · Q[l+1][k+1] · q_r · m_k.
            for (k, m) in QUADRATIC.iter().enumerate() {
                let mut product = *m;
                product[d.times] += 1;
                equation[cubic_index(&product)] +=
                    d.factor * self.q_matrix[(d.monomial + 1, k + 1)];
            }
        }
        for equation in &mut equations {
            let norm = equation.iter().map(|c| c * c).sum::<f64>().sqrt();
            if norm > 0.0 {
                equation.iter_mut().for_each(|c| *c /= norm);
            }
        }
        equations
    }

    /// Newton's method on `∇f = 0` from `q`; returns the polished point.
    pub fn polish(&self, q: &Vector4<f64>) -> Vector4<f64> {
        let mut current = *q;
        let mut gradient = self.gradient(&current);
        for _ in 0..MAX_NEWTON_ITERATIONS {
            let Some(step) = self.hessian(&current).lu().solve(&gradient) else {
                break;
            };
            let next = current - step;
            let next_gradient = self.gradient(&next);
            if next_gradient.norm().is_nan() || next_gradient.norm() >= gradient.norm() {
                break;
            }
            current = next;
            gradient = next_gradient;
            if step.norm() <= NEWTON_STEP_TOLERANCE * current.norm() {
                break;
            }
        }
        current
    }

    /// Whether `q` is a local minimum of `f` (Hessian positive semidefinite
    /// within [`MINIMUM_TOLERANCE`]).
    pub fn is_local_minimum(&self, q: &Vector4<f64>) -> bool {
        let eigenvalues = SymmetricEigen::new(self.hessian(q)).eigenvalues;
        let largest = eigenvalues.amax();
        eigenvalues.min() >= -MINIMUM_TOLERANCE * largest
    }

    /// The quaternion of `pose` in this cost's gauge, `‖q‖² = L/z̄` (the
    /// inverse of [`AlgebraicCost::pose`] up to the sign of `q`).
    pub fn gauge_quaternion(&self, pose: &Pose) -> Vector4<f64> {
        let unit = UnitQuaternion::from_rotation_matrix(&pose.rotation);
        let depth = pose.transform(&self.centroid).z;
        Vector4::new(unit.w, unit.i, unit.j, unit.k) * (self.length_scale / depth).sqrt()
    }

    /// The pose for a real `q ≠ 0`: `R = R̄(q)/‖q‖²`,
    /// `z̄ = L/‖q‖²`, centroid `c = z̄ (t̃₁, t̃₂, 1)`, `t = c − R X̄`.
    pub fn pose(&self, q: &Vector4<f64>) -> Pose {
        let z = Self::lifted(q);
        let norm_sq = q.norm_squared();
        let rotation = UnitQuaternion::from_quaternion(Quaternion::new(q[0], q[1], q[2], q[3]))
            .to_rotation_matrix();
        let depth = self.length_scale / norm_sq;
        let centroid_camera = Vector3::new(
            self.centroid_image[0].dot(&z) * depth,
            self.centroid_image[1].dot(&z) * depth,
            depth,
        );
        Pose::new(rotation, centroid_camera - rotation * self.centroid)
    }
}

/// What one OPnP solve found, for diagnostics and the candidate counts the
/// project reports.
#[derive(Debug, Clone, Default)]
pub struct Report {
    /// Real eigenvalues of the action matrix.
    pub real_eigenvalues: usize,
    /// Real solution pairs `±q` extracted (stationary points of `f`).
    pub real_solutions: usize,
    /// Distinct local minima after polishing: the candidates returned.
    pub minima: usize,
}

/// `opnp`: OPnP: every local minimum of the algebraic cost in a non-unit quaternion, by a Gröbner-basis solver (Zheng et al., ICCV 2013).
pub const OPNP: Method = Method {
    name: "opnp",
    display_name: NAME,
    description: "OPnP: all minima of the algebraic cost in a non-unit quaternion, Gröbner-basis solver (Zheng et al. 2013)",
    min_points: MIN_POINTS,
    accepts_coplanar: true,
    exact: true,
    start: None,
    solve,
};

/// OPnP: every local minimum of the algebraic cost, as a pose.
pub fn solve(object: &[Vector3<f64>], image: &[Vector2<f64>]) -> Result<Candidates, PnpError> {
    solve_with_report(object, image).map(|(candidates, _)| candidates)
}

/// [`solve`], also returning the solution counts.
pub fn solve_with_report(
    object: &[Vector3<f64>],
    image: &[Vector2<f64>],
) -> Result<(Candidates, Report), PnpError> {
    if object.len() < MIN_POINTS {
        return Err(PnpError::TooFewPoints {
            solver: NAME,
            needed: MIN_POINTS,
            got: object.len(),
        });
    }
    let cost = AlgebraicCost::new(object, image)?;
    let solutions = action::solve(&cost.equations()).map_err(|e| PnpError::Degenerate {
        solver: NAME,
        reason: e.reason(),
    })?;
    let mut report = Report {
        real_eigenvalues: solutions.real_eigenvalues,
        real_solutions: solutions.real.len(),
        minima: 0,
    };
    let mut minima: Vec<Vector4<f64>> = Vec::new();
    for solution in &solutions.real {
        let q = cost.polish(&Vector4::from(solution.q));
        if !q.iter().all(|v| v.is_finite()) || q.norm() == 0.0 {
            continue;
        }
        if !cost.is_local_minimum(&q) {
            continue;
        }
        let duplicate = minima
            .iter()
            .any(|m| (m - q).norm().min((m + q).norm()) <= DUPLICATE_TOLERANCE * q.norm());
        if !duplicate {
            minima.push(q);
        }
    }
    report.minima = minima.len();
    let candidates: Candidates = minima.iter().map(|q| cost.pose(q)).collect();
    Ok((candidates, report))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pose::rotation_error_deg;
    use approx::assert_relative_eq;
    use nalgebra::{Matrix3, Rotation3};

    fn problem() -> (Vec<Vector3<f64>>, Vec<Vector2<f64>>, Pose) {
        let pose = Pose::new(
            Rotation3::from_euler_angles(0.4, -0.9, 2.2),
            Vector3::new(20.0, -35.0, 400.0),
        );
        let object = crate::synthetic::biprism_points(50.0);
        let image = object.iter().map(|p| pose.project_normalised(p)).collect();
        (object, image, pose)
    }

    #[test]
    fn derivatives_match_central_differences() {
        let (object, mut image, _) = problem();
        image[2].x += 0.01;
        let cost = AlgebraicCost::new(&object, &image).unwrap();
        let q = Vector4::new(0.3, -0.8, 0.5, 0.9);
        let h = 1e-6;
        let gradient = cost.gradient(&q);
        let hessian = cost.hessian(&q);
        for k in 0..4 {
            let mut e = Vector4::zeros();
            e[k] = h;
            let numeric = (cost.value(&(q + e)) - cost.value(&(q - e))) / (2.0 * h);
            assert_relative_eq!(gradient[k], numeric, max_relative = 1e-6, epsilon = 1e-9);
            let numeric_column = (cost.gradient(&(q + e)) - cost.gradient(&(q - e))) / (2.0 * h);
            assert_relative_eq!(
                hessian.column(k).into_owned(),
                numeric_column,
                max_relative = 1e-6,
                epsilon = 1e-9
            );
        }
        // The odd cubic equations are the gradient, up to each row's scale.
        let equations = cost.equations();
        let qa = [q[0], q[1], q[2], q[3]];
        let values: Vec<f64> = equations.iter().map(|e| action::evaluate(e, &qa)).collect();
        for k in 0..4 {
            let ratio = values[k] / gradient[k];
            let unit = equations[k].iter().map(|c| c * c).sum::<f64>().sqrt();
            assert!(ratio > 0.0 && unit > 0.0);
        }
    }

    #[test]
    fn true_pose_is_a_zero_of_the_cost_and_a_solution() {
        let (object, image, pose) = problem();
        let cost = AlgebraicCost::new(&object, &image).unwrap();
        let q = cost.gauge_quaternion(&pose);
        // Zero up to rounding, relative to the cost's constant term Σ(uᵢ − ū)².
        let scale = cost.q_matrix[(0, 0)];
        assert!(cost.value(&q) < 1e-14 * scale, "cost {}", cost.value(&q));
        assert!(cost.gradient(&q).norm() < 1e-12 * scale);
        let recovered = cost.pose(&q);
        assert!(rotation_error_deg(&pose.rotation, &recovered.rotation) < 1e-10);
        assert_relative_eq!(
            recovered.translation,
            pose.translation,
            max_relative = 1e-12
        );
        let candidates = solve(&object, &image).unwrap();
        let best = super::super::best_candidate(NAME, &candidates, &object, &image).unwrap();
        assert!(rotation_error_deg(&pose.rotation, &best.rotation) < 1e-8);
        assert_relative_eq!(best.translation, pose.translation, max_relative = 1e-10);
    }

    #[test]
    fn error_messages() {
        let (object, image, _) = problem();
        let err = solve(&object[..3], &image[..3]).unwrap_err();
        assert_eq!(err.to_string(), "OPnP needs at least 4 points, got 3");
        let same = vec![Vector2::new(0.1, 0.2); object.len()];
        let err = solve(&object, &same).unwrap_err();
        assert_eq!(err.to_string(), "OPnP failed: the image points coincide");
    }

    #[test]
    fn coplanar_points_are_accepted_and_collinear_rejected() {
        use crate::pnp::Solver;
        let pose = Pose::new(
            Rotation3::from_euler_angles(0.7, 0.3, -1.2),
            Vector3::new(-15.0, 10.0, 300.0),
        );
        let plane: Vec<Vector3<f64>> = [
            (0.0, 0.0),
            (60.0, 5.0),
            (10.0, 50.0),
            (-40.0, 20.0),
            (25.0, -35.0),
        ]
        .iter()
        .map(|&(x, y)| Vector3::new(x, y, 0.0))
        .collect();
        let image: Vec<Vector2<f64>> = plane.iter().map(|p| pose.project_normalised(p)).collect();
        assert!(!Solver::Opnp.needs_noncoplanar());
        let best = Solver::Opnp.solve_best(&plane, &image).unwrap();
        assert!(rotation_error_deg(&pose.rotation, &best.rotation) < 1e-8);
        assert_relative_eq!(best.translation, pose.translation, max_relative = 1e-10);
        let line: Vec<Vector3<f64>> = (0..5)
            .map(|i| Vector3::new(i as f64, 2.0 * i as f64, 1.0))
            .collect();
        assert_eq!(
            Solver::Opnp.solve(&line, &image).unwrap_err(),
            PnpError::Collinear
        );
        let err = Solver::Opnp.solve(&plane[..3], &image[..3]).unwrap_err();
        assert_eq!(err.to_string(), "OPnP needs at least 4 points, got 3");
    }

    #[test]
    fn rotation_coefficients_match_the_unit_quaternion_matrix() {
        let q = Vector4::new(0.3, -0.5, 0.7, 0.2);
        let m = quadratic_monomials(&q);
        let rotation = UnitQuaternion::from_quaternion(Quaternion::new(q[0], q[1], q[2], q[3]))
            .to_rotation_matrix();
        let scaled: Matrix3<f64> = rotation.matrix() * q.norm_squared();
        for j in 0..3 {
            for k in 0..3 {
                let entry: f64 = (0..10).map(|l| ROTATION_COEFFICIENTS[j][k][l] * m[l]).sum();
                assert_relative_eq!(entry, scaled[(j, k)], epsilon = 1e-14);
            }
        }
    }
}
