//! The seed paper's solver family: paraperspective pose (Horaud et al.,
//! "Object pose: the link between weak perspective, paraperspective, and full
//! perspective", IJCV 22(2), 1997; paper §3.2, eqs. 17–21) and the paper's
//! method, paraperspective → β (eqs. 14–16) → weighted Gauss–Newton
//! (eqs. 30–31) → absolute orientation (§3.5).
//!
//! # Reference point
//! Paraperspective is written about a reference point P0 at the object origin
//! whose image `(u0, v0)` is measured (eq. 17). The paper's biprism has its
//! centre O0 as a feature for this. For any layout we use the feature nearest
//! the centroid ([`reference_index`]) and shift the object coordinates so that
//! it is the origin; the pose is shifted back at the end. Reports name the
//! point (`reference_index`).
//!
//! # Choices the paper leaves open (docs/paper-notes.md, "Eq. 19" to "`parallel` and the `parallel-gn` ablation")
//! * Eq. 19 is used as corrected: `tz = ½(√(1+u0²)/‖I‖ + √(1+v0²)/‖J‖)`.
//! * The near-rotation `[i j k]ᵀ` of eq. 21 is projected onto SO(3) by SVD.
//! * Control points of the paper's method (§4.1): the reference point plus one
//!   point at distance `s` along each object axis, `s` being the largest
//!   distance of a feature from the reference. For the paper's biprism this is
//!   exactly `[L,0,0], [0,L,0], [0,0,L], [0,0,0]`.
//! * Weights (eq. 30): `w = d² / (tz² · m_o · m)` with d the pair's 3D length
//!   and m its projected length on the normalised image plane under the
//!   initial pose. For the three pairs through the reference point, m_o is the
//!   distance of the reference image from the principal point,
//!   `√(u0² + v0²)`; for the three other pairs, it is that of the pair's
//!   midpoint image. m_o is floored at [`M_O_FLOOR_FRACTION`] times the mean
//!   projected pair length, because m_o → 0 on the optical axis would make the
//!   three pairs through the origin swamp the others. Weights are computed
//!   once, from the paraperspective pose.
//! * The unweighted variant (`parallel-gn`) runs the same pipeline with unit
//!   weights, so the effect of eq. 30 can be measured.
//! * `parallel` iterates the paraperspective equations with Horaud's
//!   perspective correction `(x_i − u0)(1 + ε_i) = I·P_i`, `ε_i = k·P_i / tz`,
//!   until the corrections stop changing; its first iteration is eqs. 17–21.
//!   It returns the iterate with the lowest reprojection error and stops on
//!   divergence ([`solve_iterative`]).
//!
//! # Where the single start holds
//! The paper's method starts Gauss–Newton once, from the paraperspective
//! pose, and we keep it that way: `parallel-weighted` is the method as
//! published. Two generic safeguards of the shared β machinery apply to it
//! as to every EPnP-family solver: backtracking Gauss–Newton
//! ([`gauss_newton::refine_betas`]) and the depth-reversed mirror candidate
//! ([`EpnpSystem::push_candidates`]). What remains are local minima reached
//! from a paraperspective start that is far off: under strong perspective
//! (depth/size near 1) and for thin, nearly planar objects the first-order
//! paraperspective pose can be tens of degrees from the truth, and
//! Gauss–Newton on the six control-point distances then settles in the
//! minimum nearest that start (the sweep's noise-free misses of
//! `parallel-weighted` are up to 150° off). `reports/solvers/` measures where (the conformance sweep,
//! `cargo run --release --features examples --example conformance`).

use super::epnp::{EpnpSystem, PAIRS};
use super::{gauss_newton, reprojection_error_sq_in_front, Candidates, Method, PnpError};
use crate::pose::{nearest_rotation, Pose};
use nalgebra::{Matrix3, Rotation3, Vector2, Vector3, Vector4};
use smallvec::smallvec;

/// m_o is floored at this fraction of the mean projected control-pair length.
pub const M_O_FLOOR_FRACTION: f64 = 0.5;
/// Horaud's iteration stops when no perspective correction ε_i moves by more
/// than this.
pub const ITERATION_TOLERANCE: f64 = 1e-14;
/// Upper bound on Horaud's iterations.
pub const MAX_ITERATIONS: usize = 500;
/// Horaud's iteration stops as not converging when this many iterations in
/// a row have not lowered the best reprojection error. A converging
/// iteration lowers it at every step once near its fixed point (its
/// corrections may grow for a while before that, so their size is no
/// test); an oscillation or a drift to a spurious fixed point does not.
pub const STALL_ITERATIONS: usize = 50;

const SOLVER: &str = "Paraperspective";

/// The feature used as paraperspective reference point P0: the one nearest
/// the centroid of the object points (ties go to the lowest index).
pub fn reference_index(object: &[Vector3<f64>]) -> usize {
    let centroid = object.iter().sum::<Vector3<f64>>() / object.len() as f64;
    let mut best = 0;
    let mut best_distance = f64::INFINITY;
    for (index, p) in object.iter().enumerate() {
        let distance = (p - centroid).norm_squared();
        if distance < best_distance {
            best = index;
            best_distance = distance;
        }
    }
    best
}

/// A paraperspective problem: object points relative to the reference point.
struct Paraperspective<'a> {
    object: &'a [Vector3<f64>],
    image: &'a [Vector2<f64>],
    reference: usize,
    shift: Vector3<f64>,
    /// `(Σ P_i P_iᵀ)⁻¹` over the shifted points (eq. 17's normal equations).
    inverse_scatter: Matrix3<f64>,
}

/// The result of one paraperspective solve (eqs. 17–21), in the shifted frame.
#[derive(Debug, Clone, Copy)]
struct ParaperspectivePose {
    pose: Pose,
    /// Third row of R, used by Horaud's correction.
    k: Vector3<f64>,
}

impl<'a> Paraperspective<'a> {
    fn new(object: &'a [Vector3<f64>], image: &'a [Vector2<f64>]) -> Result<Self, PnpError> {
        let reference = reference_index(object);
        let shift = object[reference];
        let mut scatter = Matrix3::zeros();
        for p in object {
            let q = p - shift;
            scatter += q * q.transpose();
        }
        let inverse_scatter = scatter.try_inverse().ok_or(PnpError::Degenerate {
            solver: SOLVER,
            reason: "points around the reference point do not span three directions",
        })?;
        Ok(Self {
            object,
            image,
            reference,
            shift,
            inverse_scatter,
        })
    }

    fn shifted(&self, index: usize) -> Vector3<f64> {
        self.object[index] - self.shift
    }

    /// Eqs. 17–21 with optional Horaud corrections `(1 + ε_i)`.
    fn solve(&self, correction: impl Fn(usize) -> f64) -> Result<ParaperspectivePose, PnpError> {
        let reference_image = self.image[self.reference];
        let (u0, v0) = (reference_image.x, reference_image.y);
        // Eq. 17 by linear least squares over the points other than P0
        // (P0 itself contributes nothing: its shifted coordinates are zero).
        let mut rhs_i = Vector3::zeros();
        let mut rhs_j = Vector3::zeros();
        for (index, m) in self.image.iter().enumerate() {
            let q = self.shifted(index);
            let scale = correction(index);
            rhs_i += q * ((m.x - u0) * scale);
            rhs_j += q * ((m.y - v0) * scale);
        }
        let big_i = self.inverse_scatter * rhs_i;
        let big_j = self.inverse_scatter * rhs_j;
        let (norm_i, norm_j) = (big_i.norm(), big_j.norm());
        if !(norm_i > 0.0 && norm_j > 0.0 && norm_i.is_finite() && norm_j.is_finite()) {
            return Err(PnpError::Degenerate {
                solver: SOLVER,
                reason: "the image has no extent around the reference point",
            });
        }
        // Eq. 19, as corrected in docs/paper-notes.md, "Eq. 19: depth from ‖I‖ and ‖J‖".
        let tz = 0.5 * ((1.0 + u0 * u0).sqrt() / norm_i + (1.0 + v0 * v0).sqrt() / norm_j);
        // Eq. 21: (Id − tz v0 [I]× + tz u0 [J]×) k = tz² (I × J).
        let system = Matrix3::identity() - big_i.cross_matrix() * (tz * v0)
            + big_j.cross_matrix() * (tz * u0);
        let k = system
            .lu()
            .solve(&(big_i.cross(&big_j) * (tz * tz)))
            .ok_or(PnpError::Degenerate {
                solver: SOLVER,
                reason: "eq. 21 is singular",
            })?;
        // Eq. 18 inverted: i = tz I + u0 k, j = tz J + v0 k.
        let i = big_i * tz + k * u0;
        let j = big_j * tz + k * v0;
        let near_rotation = Matrix3::from_rows(&[i.transpose(), j.transpose(), k.transpose()]);
        if !near_rotation.iter().all(|v| v.is_finite()) {
            return Err(PnpError::Degenerate {
                solver: SOLVER,
                reason: "paraperspective rotation is not finite",
            });
        }
        let rotation: Rotation3<f64> = nearest_rotation(&near_rotation);
        let translation = Vector3::new(u0 * tz, v0 * tz, tz);
        let k = rotation.matrix().row(2).transpose();
        Ok(ParaperspectivePose {
            pose: Pose::new(rotation, translation),
            k,
        })
    }

    /// Sum of squared reprojection errors of a pose in the shifted frame;
    /// infinite if a point is not in front of the camera.
    fn reprojection_error_sq(&self, pose: &Pose) -> f64 {
        reprojection_error_sq_in_front(&self.unshift(pose), self.object, self.image)
            .unwrap_or(f64::INFINITY)
    }

    /// Back to the caller's object frame.
    fn unshift(&self, pose: &Pose) -> Pose {
        pose.with_object_origin_shifted(&self.shift)
    }
}

/// The single paraperspective step of eqs. 17–21 about the reference
/// point ([`reference_index`]), without Horaud's correction, in the caller's
/// object frame: the pose `parallel-weighted` starts from, and the
/// `parallel-init` solver.
pub fn single_step(object: &[Vector3<f64>], image: &[Vector2<f64>]) -> Result<Pose, PnpError> {
    let problem = Paraperspective::new(object, image)?;
    Ok(problem.unshift(&problem.solve(|_| 1.0)?.pose))
}

/// `parallel`: the paraperspective pose of eqs. 17–21, iterated with
/// Horaud's perspective correction until it converges to the full
/// perspective pose. Returns one candidate: the iterate with the lowest
/// reprojection error.
///
/// Horaud et al. (§5) show the iteration converges when the object's depth
/// extent is small against its distance (the corrections ε_i stay well
/// below 1). Under strong perspective (depth/size near 1, or a thin object
/// seen edge-on) it can instead wander, or settle on a fixed point far from
/// the pose, with tens to thousands of pixels of reprojection error. So the
/// iteration keeps the best iterate by reprojection error, and stops when
/// [`STALL_ITERATIONS`] iterations in a row have not improved on it or when
/// an iterate is degenerate, returning that best iterate.
pub fn solve_iterative(
    object: &[Vector3<f64>],
    image: &[Vector2<f64>],
) -> Result<Candidates, PnpError> {
    let problem = Paraperspective::new(object, image)?;
    let mut current = problem.solve(|_| 1.0)?;
    let mut best = (problem.reprojection_error_sq(&current.pose), current.pose);
    let mut since_best = 0;
    for _ in 0..MAX_ITERATIONS {
        let previous = current;
        let tz = previous.pose.translation.z;
        current = match problem.solve(|index| 1.0 + previous.k.dot(&problem.shifted(index)) / tz) {
            Ok(next) => next,
            Err(_) => break,
        };
        let error_sq = problem.reprojection_error_sq(&current.pose);
        if error_sq < best.0 {
            best = (error_sq, current.pose);
            since_best = 0;
        } else {
            since_best += 1;
        }
        let change = (0..object.len())
            .map(|index| {
                (current.k / current.pose.translation.z - previous.k / tz)
                    .dot(&problem.shifted(index))
                    .abs()
            })
            .fold(0.0, f64::max);
        if change.is_nan() || change <= ITERATION_TOLERANCE || since_best >= STALL_ITERATIONS {
            break;
        }
    }
    Ok(smallvec![problem.unshift(&best.1)])
}

/// Control points of the paper's method: the reference point (origin of the
/// shifted frame) and one point at distance `s` along each object axis.
fn paper_control_points(problem: &Paraperspective) -> [Vector3<f64>; 4] {
    let s = (0..problem.object.len())
        .map(|index| problem.shifted(index).norm())
        .fold(0.0, f64::max);
    [
        Vector3::zeros(),
        Vector3::new(s, 0.0, 0.0),
        Vector3::new(0.0, s, 0.0),
        Vector3::new(0.0, 0.0, s),
    ]
}

/// The paper's eq. 30 weight `w = d² / (tz² · m_o · m)` of a segment of
/// length d (mm) at depth tz (mm), with reference image distance `m_o` and
/// projected length m (normalised units). Only relative weights matter;
/// [`eq30_weights`] floors `m_o` and `m` (see the module documentation).
#[inline]
pub fn eq30_weight(length_mm: f64, depth_mm: f64, m_o: f64, m: f64) -> f64 {
    length_mm * length_mm / (depth_mm * depth_mm * m_o * m)
}

/// The weights of eq. 30 for the six control-point pairs, from the initial
/// pose (see the module documentation for the choices made).
pub fn eq30_weights(control_world: &[Vector3<f64>; 4], pose: &Pose) -> [f64; 6] {
    let tz = pose.translation.z;
    let control_camera: [Vector3<f64>; 4] =
        std::array::from_fn(|j| pose.transform(&control_world[j]));
    let project = |p: &Vector3<f64>| Vector2::new(p.x / p.z, p.y / p.z);
    let projected_lengths: [f64; 6] = std::array::from_fn(|k| {
        let (a, b) = PAIRS[k];
        (project(&control_camera[a]) - project(&control_camera[b])).norm()
    });
    let mean_length = projected_lengths.iter().sum::<f64>() / 6.0;
    let floor = (M_O_FLOOR_FRACTION * mean_length).max(f64::MIN_POSITIVE);
    std::array::from_fn(|k| {
        let (a, b) = PAIRS[k];
        let length_mm = (control_world[a] - control_world[b]).norm();
        // Pairs through control point 0 (the reference) use the reference's
        // image; the others the image of their midpoint.
        let anchor = if a == 0 {
            control_camera[0]
        } else {
            (control_camera[a] + control_camera[b]) * 0.5
        };
        let m_o = project(&anchor).norm().max(floor);
        let m = projected_lengths[k].max(f64::MIN_POSITIVE);
        eq30_weight(length_mm, tz, m_o, m)
    })
}

/// `parallel`: paraperspective pose (paper eqs. 17–21), iterated to full perspective as Horaud et al. 1997 do; no GN.
pub const PARALLEL: Method = Method {
    name: "parallel",
    display_name: "Paraperspective",
    description:
        "paraperspective pose, eqs. 17-21, iterated to full perspective (Horaud et al. 1997)",
    min_points: 4,
    accepts_coplanar: false,
    exact: true,
    start: None,
    solve: solve_iterative,
};

/// `parallel-gn`: ablation: paraperspective betas + *unweighted* GN (eq. 10), to measure what the weights of eq. 30 contribute.
pub const PARALLEL_GN: Method = Method {
    name: "parallel-gn",
    display_name: "Paraperspective+GN (unweighted)",
    description: "ablation: paraperspective betas + unweighted Gauss-Newton (eq. 10)",
    min_points: 4,
    accepts_coplanar: false,
    exact: true,
    start: None,
    solve: solve_unweighted,
};

/// `parallel-weighted`: the paper's method: paraperspective → betas (eqs. 14–16) → weighted GN (eqs. 30–31) → absolute orientation.
pub const PARALLEL_WEIGHTED: Method = Method {
    name: "parallel-weighted",
    display_name: "Parallel-weighted",
    description: "the paper's method: paraperspective -> betas (eqs. 14-16) -> weighted GN (eqs. 30-31) -> absolute orientation",
    min_points: 4,
    accepts_coplanar: false,
    exact: true,
    start: None,
    solve: solve_weighted,
};

/// `parallel-weighted`, the paper's method: single-step paraperspective
/// (eqs. 17–21) → control points (eq. 14) → β0 (eq. 16) → Gauss–Newton
/// weighted by eq. 30 (eq. 31) → pose. Returns one candidate, and its
/// depth-reversed mirror when the reconstruction is a mirror image of the
/// object ([`EpnpSystem::push_candidates`]).
pub fn solve_weighted(
    object: &[Vector3<f64>],
    image: &[Vector2<f64>],
) -> Result<Candidates, PnpError> {
    solve_with_gauss_newton(object, image, eq30_weights)
}

/// The `parallel-gn` ablation: as [`solve_weighted`], with unit weights
/// (eq. 10) in place of eq. 30's.
pub fn solve_unweighted(
    object: &[Vector3<f64>],
    image: &[Vector2<f64>],
) -> Result<Candidates, PnpError> {
    solve_with_gauss_newton(object, image, |_, _| gauss_newton::UNIT_WEIGHTS)
}

/// Paraperspective → β0 → Gauss–Newton with the pair weights that
/// `weights` gives for the control points (in the frame shifted to the
/// reference point) and the initial pose.
fn solve_with_gauss_newton(
    object: &[Vector3<f64>],
    image: &[Vector2<f64>],
    weights: impl Fn(&[Vector3<f64>; 4], &Pose) -> [f64; 6],
) -> Result<Candidates, PnpError> {
    let problem = Paraperspective::new(object, image)?;
    // The initial pose and the control points are in the frame shifted to
    // the reference point; weights and β0 are computed there.
    let initial = problem.solve(|_| 1.0)?.pose;
    let control_shifted = paper_control_points(&problem);
    // Eq. 14: control points in the camera frame under the initial pose.
    let control_camera: [Vector3<f64>; 4] =
        std::array::from_fn(|j| initial.transform(&control_shifted[j]));
    let weights = weights(&control_shifted, &initial);
    // The EPnP system takes the same control points in the caller's frame:
    // barycentric coordinates do not change under the shift, and the pose
    // it returns needs no shifting back.
    let control_world = control_shifted.map(|c| c + problem.shift);
    let system = EpnpSystem::new(control_world, object, image)?;
    // Eq. 16.
    let start: Vector4<f64> = system.betas_from_control_camera(&control_camera);
    let mut candidates = Candidates::new();
    system.push_candidates(
        &start,
        |betas| gauss_newton::refine_betas(&system, betas, &weights),
        &mut candidates,
    );
    Ok(candidates)
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn eq30_weight_formula() {
        assert_relative_eq!(
            eq30_weight(50.0, 500.0, 0.1, 0.05),
            2500.0 / (250000.0 * 0.005)
        );
    }
}
