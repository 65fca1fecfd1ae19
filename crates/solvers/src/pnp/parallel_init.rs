//! `parallel-init`: the single paraperspective step of the seed paper
//! (Hu, Li & Tan, §3.2, eqs. 17–21; Horaud et al., IJCV 22(2), 1997), with
//! no correction and no refinement.
//!
//! This is the pose the paper's method starts Gauss–Newton from, and what
//! the paper means by "Parallel" where it speaks of the proposed method's
//! *initial value* (its close-range depth claims, the off-axis improvement
//! and the cost of weighting). `parallel` iterates the same equations with
//! Horaud's perspective correction to convergence; the two readings of the
//! paper's word are kept apart (docs/paper-notes.md, "`parallel` and the
//! `parallel-gn` ablation").
//!
//! Under a true paraperspective projection about the reference point the
//! step is exact; under full perspective it carries the first-order bias of
//! the affine model, which grows as the object's extent approaches its
//! depth. The reference point and every choice of eqs. 17–21 are
//! `parallel`'s ([`super::parallel`]).

use super::parallel::single_step;
use super::{Candidates, Method, PnpError};
use nalgebra::{Vector2, Vector3};
use smallvec::smallvec;

/// `parallel-init`: eqs. 17–21 once, the paper's initial value.
pub const PARALLEL_INIT: Method = Method {
    name: "parallel-init",
    display_name: "Paraperspective (single step)",
    description:
        "paraperspective pose, eqs. 17-21, one step: the initial value of the paper's method",
    min_points: 4,
    accepts_coplanar: false,
    exact: false,
    start: None,
    solve,
};

/// One candidate: the single-step paraperspective pose.
pub fn solve(object: &[Vector3<f64>], image: &[Vector2<f64>]) -> Result<Candidates, PnpError> {
    Ok(smallvec![single_step(object, image)?])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pose::{rotation_error_deg, translation_error_percent, Pose};
    use nalgebra::{Rotation3, Vector3};

    /// The paper's biprism (L = 50 mm) with its centre: the reference point
    /// is the centre, at the object origin.
    fn biprism() -> Vec<Vector3<f64>> {
        let l = 50.0;
        vec![
            Vector3::zeros(),
            Vector3::new(l, 0.0, 0.0),
            Vector3::new(-l, 0.0, 0.0),
            Vector3::new(0.0, l, 0.0),
            Vector3::new(0.0, -l, 0.0),
            Vector3::new(0.0, 0.0, l),
            Vector3::new(0.0, 0.0, -l),
        ]
    }

    fn pose(depth: f64) -> Pose {
        Pose::new(
            Rotation3::from_euler_angles(0.3, -0.5, 0.8),
            Vector3::new(0.2 * depth, -0.1 * depth, depth),
        )
    }

    /// Eq. 18 forwards: x_i = u0 + (i − u0 k)·P_i / tz, y_i likewise.
    fn paraperspective_image(object: &[Vector3<f64>], pose: &Pose) -> Vec<Vector2<f64>> {
        let t = pose.translation;
        let (u0, v0) = (t.x / t.z, t.y / t.z);
        let r = pose.rotation.matrix();
        let (i, j, k) = (
            r.row(0).transpose(),
            r.row(1).transpose(),
            r.row(2).transpose(),
        );
        object
            .iter()
            .map(|p| {
                Vector2::new(
                    u0 + (i - k * u0).dot(p) / t.z,
                    v0 + (j - k * v0).dot(p) / t.z,
                )
            })
            .collect()
    }

    fn perspective_image(object: &[Vector3<f64>], pose: &Pose) -> Vec<Vector2<f64>> {
        object
            .iter()
            .map(|p| {
                let c = pose.transform(p);
                Vector2::new(c.x / c.z, c.y / c.z)
            })
            .collect()
    }

    fn errors(image: &[Vector2<f64>], truth: &Pose) -> (f64, f64) {
        let found = solve(&biprism(), image).unwrap()[0];
        (
            rotation_error_deg(&truth.rotation, &found.rotation),
            translation_error_percent(&truth.translation, &found.translation),
        )
    }

    #[test]
    fn exact_under_a_true_paraperspective_projection() {
        for depth in [120.0, 400.0, 3000.0] {
            let truth = pose(depth);
            let (rotation, translation) =
                errors(&paraperspective_image(&biprism(), &truth), &truth);
            assert!(rotation < 1e-9, "depth {depth}: {rotation}°");
            assert!(translation < 1e-9, "depth {depth}: {translation}%");
        }
    }

    #[test]
    fn biased_under_full_perspective_as_the_affine_model_predicts() {
        // Depth/size 3: the first-order model is visibly off; depth/size 60:
        // the bias has shrunk with the ratio.
        let near = pose(150.0);
        let far = pose(3000.0);
        let (near_rotation, near_translation) =
            errors(&perspective_image(&biprism(), &near), &near);
        let (far_rotation, _) = errors(&perspective_image(&biprism(), &far), &far);
        assert!(near_rotation > 0.5, "near: {near_rotation}°");
        assert!(near_translation > 0.1, "near: {near_translation}%");
        assert!(
            far_rotation < near_rotation / 10.0,
            "{far_rotation}° vs {near_rotation}°"
        );
        // The full-perspective solvers recover the same noise-free pose.
        let refined = crate::pnp::Solver::ParallelWeighted
            .solve_best(&biprism(), &perspective_image(&biprism(), &near))
            .unwrap();
        assert!(rotation_error_deg(&near.rotation, &refined.rotation) < 1e-6);
    }
}
