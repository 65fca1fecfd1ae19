//! IEPnP (paper §2.1, after Chen [26]): EPnP whose initial β come from a
//! weak-perspective (scaled orthographic) pose instead of EPnP's closed
//! forms, followed by the same Gauss–Newton (eq. 10).
//!
//! We do not have Chen's text; this follows the paper's description. The
//! weak-perspective pose is taken about the centroid of the object points
//! (so no feature needs to sit at the origin): `x_i − x̄ = I·(P_i − P̄)`,
//! `y_i − ȳ = J·(P_i − P̄)` by least squares, `tz = 2 / (‖I‖ + ‖J‖)`,
//! `i = I/‖I‖`, `j = J/‖J‖`, `k = i × j`, projected onto SO(3). The control
//! points are Lepetit's (centroid and principal axes), as in `epnp`.

use super::epnp::{principal_control_points, EpnpSystem};
use super::{gauss_newton, Candidates, Method, PnpError};
use crate::pose::{nearest_rotation, Pose};
use nalgebra::{Matrix3, Vector2, Vector3};

/// The weak-perspective pose about the centroid of the object points.
pub fn weak_perspective_pose(
    object: &[Vector3<f64>],
    image: &[Vector2<f64>],
) -> Result<Pose, PnpError> {
    let count = object.len() as f64;
    let object_centroid = object.iter().sum::<Vector3<f64>>() / count;
    let image_centroid = image.iter().sum::<Vector2<f64>>() / count;
    let mut scatter = Matrix3::zeros();
    let mut rhs_i = Vector3::zeros();
    let mut rhs_j = Vector3::zeros();
    for (p, m) in object.iter().zip(image) {
        let q = p - object_centroid;
        let d = m - image_centroid;
        scatter += q * q.transpose();
        rhs_i += q * d.x;
        rhs_j += q * d.y;
    }
    let degenerate = |reason| PnpError::Degenerate {
        solver: "IEPnP",
        reason,
    };
    let inverse = scatter
        .try_inverse()
        .ok_or_else(|| degenerate("object points do not span three directions"))?;
    let (big_i, big_j) = (inverse * rhs_i, inverse * rhs_j);
    let (norm_i, norm_j) = (big_i.norm(), big_j.norm());
    if !(norm_i > 0.0 && norm_j > 0.0 && norm_i.is_finite() && norm_j.is_finite()) {
        return Err(degenerate("the image points have no extent"));
    }
    let tz = 2.0 / (norm_i + norm_j);
    let i = big_i / norm_i;
    let j = big_j / norm_j;
    let k = i.cross(&j);
    let rotation = nearest_rotation(&Matrix3::from_rows(&[
        i.transpose(),
        j.transpose(),
        k.transpose(),
    ]));
    // The centroid sits at depth tz on the ray of the image centroid.
    let translation =
        Vector3::new(image_centroid.x, image_centroid.y, 1.0) * tz - rotation * object_centroid;
    Ok(Pose::new(rotation, translation))
}

/// `iepnp`: weak-perspective initial betas + the EPnP Gauss–Newton (paper §2.1, Chen [26]).
pub const IEPNP: Method = Method {
    name: "iepnp",
    display_name: "IEPnP",
    description: "weak-perspective initial betas + the same Gauss-Newton (paper §2.1, Chen [26])",
    min_points: 4,
    accepts_coplanar: false,
    exact: true,
    start: None,
    solve,
};

/// IEPnP: weak-perspective β0, then Gauss–Newton. One candidate, and its
/// depth-reversed mirror when the reconstruction is a mirror image.
pub fn solve(object: &[Vector3<f64>], image: &[Vector2<f64>]) -> Result<Candidates, PnpError> {
    let initial = weak_perspective_pose(object, image)?;
    let control_world = principal_control_points(object);
    let system = EpnpSystem::new(control_world, object, image)?;
    let control_camera: [Vector3<f64>; 4] =
        std::array::from_fn(|j| initial.transform(&control_world[j]));
    let start = system.betas_from_control_camera(&control_camera);
    let mut candidates = Candidates::new();
    system.push_candidates(
        &start,
        |betas| gauss_newton::refine_betas(&system, betas, &gauss_newton::UNIT_WEIGHTS),
        &mut candidates,
    );
    Ok(candidates)
}
