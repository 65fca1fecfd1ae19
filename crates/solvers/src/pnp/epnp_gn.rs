//! EPnP+GN: EPnP's closed-form β refined by Gauss–Newton on the six
//! control-point distances (Lepetit, Moreno-Noguer & Fua 2009 §3.4; paper
//! eq. 10), as the reference implementation does.
//!
//! The EPnP system and its closed forms are [`super::epnp`]'s, the
//! refinement [`super::gauss_newton`]'s; this file joins them, so that
//! neither of those needs the other.
//!
//! Requirements: n ≥ 4 noncoplanar points (validated by the caller).

use super::epnp::{principal_control_points, EpnpSystem, RELINEARISED_START_MAX_POINTS};
use super::{gauss_newton, Candidates, Method, PnpError};
use nalgebra::{Vector2, Vector3, Vector4};

/// `epnp-gn`: EPnP + Gauss–Newton on the betas (paper eq. 10).
pub const EPNP_GN: Method = Method {
    name: "epnp-gn",
    display_name: "EPnP+GN",
    description: "EPnP + Gauss-Newton on the betas, paper eq. 10 (Lepetit et al. 2009)",
    min_points: 4,
    accepts_coplanar: false,
    exact: true,
    start: None,
    solve,
};

/// EPnP+GN: the four linearised closed forms refined by Gauss–Newton, as in
/// the reference implementation, and the relinearised one too where N = 4
/// for every pose ([`RELINEARISED_START_MAX_POINTS`]). Adds the
/// depth-reversed mirror of any candidate whose reconstruction is a mirror
/// image of the object ([`EpnpSystem::push_candidates`]).
pub fn solve(object: &[Vector3<f64>], image: &[Vector2<f64>]) -> Result<Candidates, PnpError> {
    let (system, _) = EpnpSystem::with_fit_test(principal_control_points(object), object, image)?;
    let mut candidates = Candidates::new();
    let refine = |start: &Vector4<f64>| {
        gauss_newton::refine_betas(&system, start, &gauss_newton::UNIT_WEIGHTS)
    };
    for betas in &system.closed_form_betas() {
        system.push_candidates(betas, refine, &mut candidates);
    }
    // With four points M is 8×12, so its null space is 4-dimensional
    // whatever the pose: only N = 4 is right, and the linearised N = 4
    // start is far off often enough to matter (sweep, noise-free n = 4:
    // 30 of 600 missed without this start, none with it).
    if object.len() <= RELINEARISED_START_MAX_POINTS {
        system.push_candidates(&system.relinearised_betas(), refine, &mut candidates);
    }
    Ok(candidates)
}
