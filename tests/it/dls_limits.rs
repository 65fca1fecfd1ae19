//! DLS against the first-order (Cramér–Rao) limit: the search layout at
//! tilt ±30° with noise, and far-field problems. They were unit tests of
//! `pnp::dls` until the solvers became the crate layout-opt-solvers; they
//! need the tool's error model and conformance generator, so they live here.

use layout_opt::camera::Camera;
use layout_opt::conformance::{far_field_cell, generate_with, rotation_limit_deg};
use layout_opt::error_model::first_order::pose_covariance_isotropic;
use layout_opt::pnp::Solver;
use layout_opt::pose::{rotation_error_deg, Pose};
use layout_opt::synthetic::{project_with_noise, stream_rng};
use nalgebra::{Rotation3, Vector3};

/// The DLS unit tests' seed.
const SEED: u64 = 2011;

/// A seven-point layout produced by `layout-opt search --objective mc:dls`
/// (a biprism with tilted arms and a hub point), mm; the same as the DLS
/// unit tests' (crates/solvers/src/pnp/dls/tests.rs).
fn search_layout() -> Vec<Vector3<f64>> {
    vec![
        Vector3::new(3.387268871538042, 0.07371804148363986, 0.3199500357012208),
        Vector3::new(4.276245293854925, -14.13812735584971, 43.69184846600312),
        Vector3::new(49.908496672256994, 4.291045054052243, 1.2822528651555234),
        Vector3::new(9.248040517173276, 3.4687529863686217, -48.045626789875804),
        Vector3::new(-26.007209122568764, -6.8215137976356965, 1.7254490897843517),
        Vector3::new(0.9204193282850817, 49.92727405487977, 4.79390124111792),
        Vector3::new(8.881325193592685, -47.357176529794266, -1.3490110977112781),
    ]
}

/// The validation protocol's poses at tilt ±30° about x: depths 200…1000 mm,
/// x offsets 0, 50 and 100 mm (as in the DLS unit tests).
fn tilt_30_poses() -> Vec<Pose> {
    let mut poses = Vec::new();
    for tilt_deg in [-30.0f64, 30.0] {
        for depth_mm in [200.0, 400.0, 600.0, 800.0, 1000.0] {
            for offset_mm in [0.0, 50.0, 100.0] {
                poses.push(Pose::new(
                    Rotation3::from_axis_angle(&Vector3::x_axis(), tilt_deg.to_radians()),
                    Vector3::new(offset_mm, 0.0, depth_mm),
                ));
            }
        }
    }
    poses
}

/// Noisy trials of the tilt ±30° poses (`search_layout_at_tilt_30_is_recovered`
/// in the DLS unit tests solves them noise-free).
const NOISY_TRIALS: usize = 200;
/// Pixel noise of the noisy trials (the validation protocol's).
const NOISY_SIGMA_PX: f64 = 0.5;
/// Rotation errors above this count as gross failures (the validation
/// report's threshold).
const GROSS_ROTATION_DEG: f64 = 10.0;
/// Largest RMS rotation error allowed, as a multiple of the first-order
/// (Cramér–Rao) limit: measured 0.972 after the fix, plus a margin (before
/// it: 334, with 87 gross failures near 177°).
const NOISY_RMS_OVER_LIMIT: f64 = 1.02;

#[test]
fn search_layout_at_tilt_30_meets_the_first_order_limit_with_noise() {
    let object = search_layout();
    let camera = Camera::paper();
    let poses = tilt_30_poses();
    let (mut error_sq, mut limit_sq, mut gross) = (0.0, 0.0, 0);
    for trial in 0..NOISY_TRIALS {
        let truth = poses[trial % poses.len()];
        let mut rng = stream_rng(SEED, 10, trial as u64);
        let problem =
            project_with_noise(&mut rng, &camera, object.clone(), truth, NOISY_SIGMA_PX).unwrap();
        let pose = Solver::Dls
            .solve_best(&problem.object, &problem.normalised)
            .unwrap();
        let error = rotation_error_deg(&truth.rotation, &pose.rotation);
        if error > GROSS_ROTATION_DEG {
            gross += 1;
        }
        error_sq += error * error;
        let limit = pose_covariance_isotropic(&camera, &truth, &object, NOISY_SIGMA_PX)
            .unwrap()
            .rms_rotation_deg();
        limit_sq += limit * limit;
    }
    let ratio = (error_sq / limit_sq).sqrt();
    assert_eq!(gross, 0, "{gross} gross failures");
    assert!(ratio < NOISY_RMS_OVER_LIMIT, "ratio {ratio}");
}

/// Far-field problems of [`far_field_meets_the_limit_without_gross_failures`].
const FAR_FIELD_PROBLEMS: u64 = 3000;

/// Far field (depth/size 20–30, n = 6–12, σ = 0.5 px): no gross failure for
/// DLS, SQPnP, OPnP or ML, and DLS's RMS rotation error within 1.1× the
/// first-order limit. Before the half-turns behind the camera were left out
/// of the first chart's choice, DLS could choose a chart whose singular set
/// held the pose and miss it: on 3000 other problems of this kind, one
/// gross failure 150° off and an RMS of 1.66× the limit.
#[test]
fn far_field_meets_the_limit_without_gross_failures() {
    let solvers = [Solver::Dls, Solver::Sqpnp, Solver::Opnp, Solver::Ml];
    let mut gross = [0usize; 4];
    let (mut error_sq, mut limit_sq) = (0.0, 0.0);
    for case in 0..FAR_FIELD_PROBLEMS {
        let mut rng = stream_rng(SEED, 12, case);
        let cell = far_field_cell(&mut rng, 20.0..30.0, NOISY_SIGMA_PX);
        let problem = generate_with(&mut rng, &cell).unwrap().problem;
        for (k, solver) in solvers.iter().enumerate() {
            let error = solver
                .solve_best(&problem.object, &problem.normalised)
                .map(|pose| rotation_error_deg(&problem.truth.rotation, &pose.rotation))
                .unwrap_or(180.0);
            if error > GROSS_ROTATION_DEG {
                gross[k] += 1;
            }
            if k == 0 {
                error_sq += error * error;
            }
        }
        let limit = rotation_limit_deg(&cell.camera(), &problem, NOISY_SIGMA_PX).unwrap();
        limit_sq += limit * limit;
    }
    let ratio = (error_sq / limit_sq).sqrt();
    assert_eq!(gross, [0; 4], "gross failures of dls, sqpnp, opnp, ml");
    assert!(ratio <= 1.1, "DLS RMS/limit {ratio}");
}
