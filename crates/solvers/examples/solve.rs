//! Solves one pose: a camera, seven marker points and a known pose; the
//! points are projected to pixels with a little noise, turned back into
//! normalised image points, and solved with the paper's parallel-perspective
//! solver (`parallel-weighted`) and with ML; each pose is printed with its
//! error against the truth.
//!
//! `cargo run --release -p layout-opt-solvers --example solve`

use layout_opt_solvers::camera::Camera;
use layout_opt_solvers::pnp::{PnpError, Solver};
use layout_opt_solvers::pose::{rotation_error_deg, Pose};
use nalgebra::{Rotation3, Vector2, Vector3};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    // The paper's camera (fx 1301.47, fy 1300.93, cx 653, cy 508, 1280×720)
    // with its real-image distortion.
    let camera = Camera::new(
        1301.473508,
        1300.926193,
        653.0,
        508.0,
        1280,
        720,
        [-0.087355, 0.204686, 0.0, 0.0, 0.0],
    )?;
    // The paper's biprism: a centre and six points 50 mm out along ±x, ±y, ±z.
    let object = [
        Vector3::new(0.0, 0.0, 0.0),
        Vector3::new(0.0, 0.0, 50.0),
        Vector3::new(50.0, 0.0, 0.0),
        Vector3::new(0.0, 0.0, -50.0),
        Vector3::new(-50.0, 0.0, 0.0),
        Vector3::new(0.0, 50.0, 0.0),
        Vector3::new(0.0, -50.0, 0.0),
    ];
    // The marker 600 mm ahead, a little off axis, tilted.
    let truth = Pose::new(
        Rotation3::from_euler_angles(0.35, -0.2, 0.1),
        Vector3::new(40.0, -25.0, 600.0),
    );

    // Project to pixels; add a fixed sub-pixel error to each point (about
    // what a blob detector leaves); undistort to the normalised image
    // points the solvers take.
    let wobble = [
        (0.21, -0.13),
        (-0.30, 0.05),
        (0.08, 0.27),
        (-0.12, -0.22),
        (0.25, 0.10),
        (-0.05, -0.31),
        (0.17, 0.19),
    ];
    let mut image = Vec::with_capacity(object.len());
    for (point, (du, dv)) in object.iter().zip(wobble) {
        let pixel = camera
            .project(&truth.transform(point))
            .ok_or("a point is behind the camera")?;
        let measured = pixel + Vector2::new(du, dv);
        image.push(camera.pixel_to_normalised(&measured)?);
    }

    let (roll, pitch, yaw) = truth.rotation.euler_angles();
    println!(
        "truth: rotation (roll, pitch, yaw) ({roll:.5}, {pitch:.5}, {yaw:.5}) rad, translation {:.3?} mm",
        truth.translation.as_slice()
    );
    for solver in [Solver::ParallelWeighted, Solver::Ml] {
        let pose = solver.solve_best(&object, &image)?;
        let rotation_error = rotation_error_deg(&truth.rotation, &pose.rotation);
        let translation_error = (pose.translation - truth.translation).norm();
        let (roll, pitch, yaw) = pose.rotation.euler_angles();
        println!(
            "{} ({}): rotation ({roll:.5}, {pitch:.5}, {yaw:.5}) rad, translation {:.3?} mm; \
             error {rotation_error:.4}° and {translation_error:.3} mm",
            solver.display_name(),
            solver.name(),
            pose.translation.as_slice()
        );
    }

    // Bad input is an error that says why, never a panic.
    match Solver::ParallelWeighted.solve_best(&object[..3], &image[..3]) {
        Err(error @ PnpError::TooFewPoints { .. }) => println!("three points: {error}"),
        other => println!("three points: unexpected {other:?}"),
    }
    Ok(())
}
