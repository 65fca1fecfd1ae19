//! Shared helpers for the integration tests: seeded problem families.

use layout_opt::camera::Camera;
use layout_opt::pose::{rotation_error_deg, Pose};
use layout_opt::spread::Spread;
use layout_opt::synthetic::{
    self, biprism_points, random_points, random_pose, stream_rng, uniform_rotation, Problem,
};
use nalgebra::Vector3;
use rand::Rng;

/// Smallest principal extent, relative to the largest, of a set in general position.
pub const MIN_THICKNESS: f64 = 0.25;

/// The kinds of configuration the acceptance criteria name.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Family {
    /// The paper's 7-point biprism, L = 50 mm.
    Biprism,
    /// Random noncoplanar points, n = 6…100.
    Random,
    /// Random noncoplanar points, n = 4 or 5.
    Minimal,
    /// Random coplanar points, n = 4…20, in a randomly oriented plane
    /// through the cube (for the methods that accept coplanar points).
    Planar,
    /// Random points, n = 4…20, in a slab whose thickness is 1e-4…1e-1 of
    /// its width (log-uniform): nearly coplanar but not quite.
    QuasiPlanar,
}

/// Problem `case` of a family: depth/size ratio log-uniform in [2, 200]
/// (near field 2–20 for half the cases), random attitude, off-axis up to 40%
/// of the depth, and pixel noise `sigma_px` on the paper's camera.
pub fn problem(seed: u64, family: Family, case: u64, sigma_px: f64) -> Problem {
    let stream = match family {
        Family::Biprism => 1,
        Family::Random => 2,
        Family::Minimal => 3,
        Family::Planar => 4,
        Family::QuasiPlanar => 5,
    };
    let camera = Camera::paper();
    let mut attempt = 0;
    loop {
        let mut rng = stream_rng(seed, stream, case * 64 + attempt);
        attempt += 1;
        let (object, size_mm): (Vec<Vector3<f64>>, f64) = match family {
            Family::Biprism => (biprism_points(50.0), 100.0),
            Family::Random => {
                let n = rng.random_range(6..=100);
                (random_points(&mut rng, n, 100.0), 100.0)
            }
            Family::Minimal => {
                let n = rng.random_range(4..=5);
                (random_points(&mut rng, n, 100.0), 100.0)
            }
            Family::Planar | Family::QuasiPlanar => {
                let n = rng.random_range(4..=20);
                let thickness = if family == Family::Planar {
                    0.0
                } else {
                    10f64.powf(rng.random_range(-4.0..-1.0))
                };
                let plane = uniform_rotation(&mut rng);
                let points = random_points(&mut rng, n, 100.0)
                    .into_iter()
                    .map(|p| plane * Vector3::new(p.x, p.y, p.z * thickness))
                    .collect();
                (points, 100.0)
            }
        };
        // General position: a well-spread set, not a sliver. Random 4–5 point
        // draws are often nearly coplanar, where every method is ill-posed.
        // The (quasi-)planar families need only a well-spread plane.
        let spread = Spread::of(&object);
        let thin_axis = match family {
            Family::Planar | Family::QuasiPlanar => 1,
            _ => 2,
        };
        if spread.extents[thin_axis] < MIN_THICKNESS * spread.extents[0] {
            continue;
        }
        let ratio = if case.is_multiple_of(2) {
            2.0 * 10f64.powf(rng.random::<f64>()) // near field: 2–20
        } else {
            20.0 * 10f64.powf(rng.random::<f64>()) // far field: 20–200
        };
        let truth: Pose = random_pose(&mut rng, ratio * size_mm, 0.4);
        // Keep every point well in front (depth ≥ 0.5 size) so the problem is a
        // perspective one at all, and reject numerically degenerate draws.
        if object.iter().any(|p| truth.transform(p).z < 0.5 * size_mm) {
            continue;
        }
        if let Some(problem) =
            synthetic::project_with_noise(&mut rng, &camera, object, truth, sigma_px)
        {
            return problem;
        }
    }
}

/// Rotation error (deg) and relative translation error of an estimate.
pub fn errors(problem: &Problem, estimate: &Pose) -> (f64, f64) {
    let rotation = rotation_error_deg(&problem.truth.rotation, &estimate.rotation);
    let translation = (estimate.translation - problem.truth.translation).norm()
        / problem.truth.translation.norm();
    (rotation, translation)
}
