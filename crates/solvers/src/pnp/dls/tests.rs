//! Unit tests of DLS: the cost algebra, the charts, and exact recovery in
//! the cases the integration tests do not single out (half-turns, planar
//! scenes, three points).

use super::*;
use crate::pnp::{best_candidate, Solver};
use crate::pose::rotation_error_deg;
use crate::synthetic::{random_points, random_pose, stream_rng, uniform_rotation};
use nalgebra::{Unit, UnitQuaternion};
use rand::Rng;

const SEED: u64 = 2011;
const ROTATION_TOLERANCE_DEG: f64 = 1e-6;
const TRANSLATION_TOLERANCE: f64 = 1e-8;

fn project(pose: &Pose, object: &[Vector3<f64>]) -> Vec<Vector2<f64>> {
    object.iter().map(|p| pose.project_normalised(p)).collect()
}

/// Relative translation and rotation errors of the best candidate.
fn best_errors(truth: &Pose, object: &[Vector3<f64>]) -> (f64, f64) {
    let image = project(truth, object);
    let pose = Solver::Dls.solve_best(object, &image).unwrap();
    (
        rotation_error_deg(&truth.rotation, &pose.rotation),
        (pose.translation - truth.translation).norm() / truth.translation.norm(),
    )
}

/// A pose with the given rotation, the object centred 500 mm ahead.
fn pose_with(rotation: Rotation3<f64>, rng: &mut impl Rng) -> Pose {
    let offset = Vector3::new(rng.random::<f64>() - 0.5, rng.random::<f64>() - 0.5, 0.0) * 200.0;
    Pose::new(rotation, Vector3::new(0.0, 0.0, 500.0) + offset)
}

/// Depth of the object in [`problem_data`]'s problems.
const PROBLEM_DEPTH_MM: f64 = 600.0;

fn problem_data(case: u64) -> (Vec<Vector3<f64>>, Vec<Vector2<f64>>) {
    let mut rng = stream_rng(SEED, 1, case);
    let object = random_points(&mut rng, 8, 100.0);
    let truth = random_pose(&mut rng, PROBLEM_DEPTH_MM, 0.3);
    let image: Vec<_> = object
        .iter()
        .map(|p| truth.project_normalised(p) + Vector2::new(1e-3, -2e-3) * rng.random::<f64>())
        .collect();
    (object, image)
}

#[test]
fn quartic_is_the_cost_of_the_cayley_numerator() {
    let (object, image) = problem_data(0);
    let matrices = CostMatrices::new(&object, &image).unwrap();
    let mut rng = stream_rng(SEED, 2, 0);
    for chart in &CHARTS {
        let quartic = matrices.quartic(chart);
        let flip = Matrix3::from_diagonal(&Vector3::from(*chart));
        for _ in 0..5 {
            let s = Vector3::from_fn(|_, _| rng.random::<f64>() * 3.0 - 1.5);
            let numerator = cayley_numerator(&s) * flip;
            let direct = matrices.cost_of(&numerator);
            let expanded: f64 = quartic
                .iter()
                .enumerate()
                .map(|(i, c)| {
                    let m = monomials::MONOMIALS[i];
                    c * s.x.powi(m[0] as i32) * s.y.powi(m[1] as i32) * s.z.powi(m[2] as i32)
                })
                .sum();
            assert!((direct - expanded).abs() <= 1e-12 * direct.abs().max(1.0));
        }
    }
}

#[test]
fn gradient_matches_central_differences_of_the_quartic() {
    let (object, image) = problem_data(1);
    let matrices = CostMatrices::new(&object, &image).unwrap();
    let quartic = matrices.quartic(&CHARTS[2]);
    let cubics = gradient(&quartic);
    let value = |s: &Vector3<f64>| {
        matrices.cost_of(&(cayley_numerator(s) * Matrix3::from_diagonal(&Vector3::from(CHARTS[2]))))
    };
    let s = Vector3::new(0.4, -0.3, 0.9);
    let analytic = three_cubics::evaluate(&cubics, &s);
    let h = 1e-6;
    for k in 0..3 {
        let mut step = Vector3::zeros();
        step[k] = h;
        let numeric = (value(&(s + step)) - value(&(s - step))) / (2.0 * h);
        assert!((numeric - analytic[k]).abs() <= 1e-6 * analytic.norm().max(1.0));
    }
}

#[test]
fn cost_matrix_is_the_object_space_error_at_the_optimal_translation() {
    let (object, image) = problem_data(2);
    let matrices = CostMatrices::new(&object, &image).unwrap();
    let rotation = *uniform_rotation(&mut stream_rng(SEED, 3, 0)).matrix();
    let normalised: Vec<Vector3<f64>> = object
        .iter()
        .map(|p| (p - matrices.centroid) / matrices.scale)
        .collect();
    let r = SVector::<f64, 9>::from_column_slice(rotation.as_slice());
    let t = matrices.translation * r;
    let error = |t: &Vector3<f64>| -> f64 {
        normalised
            .iter()
            .zip(&image)
            .map(|(p, m)| {
                let b = Vector3::new(m.x, m.y, 1.0).normalize();
                let x = rotation * p + t;
                (x - b * b.dot(&x)).norm_squared()
            })
            .sum()
    };
    let at_optimum = error(&t);
    assert!((at_optimum - matrices.cost_of(&rotation)).abs() <= 1e-12 * at_optimum.max(1.0));
    // t is the minimiser: any step raises the error.
    for k in 0..3 {
        let mut step = Vector3::zeros();
        step[k] = 1e-4;
        assert!(error(&(t + step)) > at_optimum && error(&(t - step)) > at_optimum);
    }
}

#[test]
fn cayley_rotation_is_a_rotation_by_twice_the_arctangent() {
    let axis = Unit::new_normalize(Vector3::new(1.0, -2.0, 0.5));
    let angle: f64 = 2.3;
    let s = axis.into_inner() * (angle / 2.0).tan();
    let expected = Rotation3::from_axis_angle(&axis, angle);
    assert!((cayley_rotation(&s) - expected.matrix()).norm() < 1e-14);
}

#[test]
fn four_charts_cover_every_rotation_within_120_degrees() {
    // In chart j the rotation solved for is R F_j, whose angle is what |s| measures.
    let mut rng = stream_rng(SEED, 4, 0);
    let mut worst: f64 = 0.0;
    for _ in 0..20000 {
        let rotation = uniform_rotation(&mut rng);
        let best = CHARTS
            .iter()
            .map(|chart| {
                let flip = Rotation3::from_matrix_unchecked(Matrix3::from_diagonal(
                    &Vector3::from(*chart),
                ));
                (rotation * flip).angle()
            })
            .fold(f64::INFINITY, f64::min);
        worst = worst.max(best);
    }
    assert!(
        worst.to_degrees() <= 120.0 + 1e-9,
        "worst {}",
        worst.to_degrees()
    );
    // DLS+++'s three 90° charts leave a hole: the 120° turns about the cube
    // diagonals are half-turns in all three (R' = R Q_kᵀ).
    let quarter_turns = [Vector3::x_axis(), Vector3::y_axis(), Vector3::z_axis()]
        .map(|axis| Rotation3::from_axis_angle(&axis, std::f64::consts::FRAC_PI_2));
    let diagonal =
        UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(0.5, -0.5, -0.5, -0.5));
    for quarter_turn in &quarter_turns {
        let in_chart = diagonal.to_rotation_matrix() * quarter_turn.inverse();
        assert!((rotation_error_deg(&Rotation3::identity(), &in_chart) - 180.0).abs() < 1e-9);
    }
    // With the four charts, the worst case is 120°, attained by the same rotations.
    let diagonal =
        UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(0.5, -0.5, -0.5, -0.5));
    let rotation = diagonal.to_rotation_matrix();
    for chart in &CHARTS {
        let flip = Rotation3::from_matrix_unchecked(Matrix3::from_diagonal(&Vector3::from(*chart)));
        assert!(((rotation * flip).angle().to_degrees() - 120.0).abs() < 1e-9);
    }
}

#[test]
fn recovers_half_turns_and_the_chart_boundaries_exactly() {
    let mut rng = stream_rng(SEED, 5, 0);
    let mut rotations: Vec<Rotation3<f64>> = Vec::new();
    // Exact half-turns about the axes, about random axes, and within 1e-9…1e-3 rad of them.
    for axis in [Vector3::x_axis(), Vector3::y_axis(), Vector3::z_axis()] {
        rotations.push(Rotation3::from_axis_angle(&axis, std::f64::consts::PI));
    }
    for k in 0..30 {
        let axis = Unit::new_normalize(Vector3::from_fn(|_, _| rng.random::<f64>() - 0.5));
        let offset = if k % 3 == 0 {
            0.0
        } else {
            10f64.powf(-9.0 + 6.0 * rng.random::<f64>())
        };
        rotations.push(Rotation3::from_axis_angle(
            &axis,
            std::f64::consts::PI - offset,
        ));
    }
    // The worst case for the four charts: 120° about the cube diagonals.
    for signs in [
        [1.0, 1.0, 1.0],
        [1.0, -1.0, 1.0],
        [-1.0, 1.0, 1.0],
        [1.0, 1.0, -1.0],
    ] {
        let axis = Unit::new_normalize(Vector3::from(signs));
        rotations.push(Rotation3::from_axis_angle(
            &axis,
            2.0 * std::f64::consts::FRAC_PI_3,
        ));
    }
    for (case, rotation) in rotations.iter().enumerate() {
        let object = random_points(&mut rng, 6 + case % 10, 100.0);
        let truth = pose_with(*rotation, &mut rng);
        let (rotation_error, translation_error) = best_errors(&truth, &object);
        assert!(
            rotation_error < ROTATION_TOLERANCE_DEG && translation_error < TRANSLATION_TOLERANCE,
            "case {case} (angle {}°): errors {rotation_error}° and {translation_error}",
            rotation.angle().to_degrees()
        );
    }
}

#[test]
fn recovers_planar_scenes_exactly() {
    let mut misses = 0;
    for case in 0..200 {
        let mut rng = stream_rng(SEED, 6, case);
        let count = rng.random_range(4..=30);
        // Points on a random plane through a random point.
        let tilt = uniform_rotation(&mut rng);
        let object: Vec<Vector3<f64>> = (0..count)
            .map(|_| {
                let (u, v) = (rng.random::<f64>() - 0.5, rng.random::<f64>() - 0.5);
                tilt * Vector3::new(u * 100.0, v * 100.0, 0.0) + Vector3::new(10.0, -5.0, 3.0)
            })
            .collect();
        let depth_mm = 300.0 + 1000.0 * rng.random::<f64>();
        let truth = random_pose(&mut rng, depth_mm, 0.3);
        if object.iter().any(|p| truth.transform(p).z < 50.0) {
            continue;
        }
        let (rotation_error, translation_error) = best_errors(&truth, &object);
        if !(rotation_error < ROTATION_TOLERANCE_DEG && translation_error < TRANSLATION_TOLERANCE) {
            misses += 1;
            eprintln!("planar case {case}: {rotation_error}° {translation_error}");
        }
    }
    assert_eq!(misses, 0);
}

#[test]
fn recovers_quasi_planar_sets_and_far_off_origins_exactly() {
    for case in 0..200 {
        let mut rng = stream_rng(SEED, 9, case);
        let count = rng.random_range(4..=40);
        // Thickness 10⁻¹…10⁻⁴ of the extent, in a random orientation.
        let thickness = 10f64.powf(-1.0 - 3.0 * rng.random::<f64>());
        let tilt = uniform_rotation(&mut rng);
        let mut object: Vec<Vector3<f64>> = (0..count)
            .map(|_| {
                let u = Vector3::new(
                    rng.random::<f64>(),
                    rng.random::<f64>(),
                    rng.random::<f64>(),
                );
                tilt * (u - Vector3::repeat(0.5)).component_mul(&Vector3::new(
                    100.0,
                    100.0,
                    100.0 * thickness,
                ))
            })
            .collect();
        let depth_mm = 200.0 * 10f64.powf(2.0 * rng.random::<f64>());
        let mut truth = random_pose(&mut rng, depth_mm, 0.4);
        if case % 2 == 1 {
            // Object coordinates far from their origin: the centring must be exact.
            let offset = Vector3::new(1e4, -3e4, 2e4);
            for p in &mut object {
                *p += offset;
            }
            truth.translation -= truth.rotation * offset;
        }
        if object.iter().any(|p| truth.transform(p).z < 50.0) {
            continue;
        }
        let (rotation_error, translation_error) = best_errors(&truth, &object);
        assert!(
            rotation_error < ROTATION_TOLERANCE_DEG && translation_error < TRANSLATION_TOLERANCE,
            "case {case} (thickness {thickness:e}): {rotation_error}° {translation_error}"
        );
    }
}

#[test]
fn three_points_give_the_p3p_poses_including_the_truth() {
    let mut found = 0;
    let cases = 100;
    for case in 0..cases {
        let mut rng = stream_rng(SEED, 7, case);
        let object = random_points(&mut rng, 3, 100.0);
        let depth_mm = 400.0 + 400.0 * rng.random::<f64>();
        let truth = random_pose(&mut rng, depth_mm, 0.3);
        if object.iter().any(|p| truth.transform(p).z < 50.0) {
            found += 1;
            continue;
        }
        let image = project(&truth, &object);
        let candidates = Solver::Dls.solve(&object, &image).unwrap();
        // The exact P3P poses are zero-cost minima; DLS may also return
        // local minima of its cost with J > 0, which are not P3P poses.
        let exact = candidates
            .iter()
            .filter(|pose| crate::pose::reprojection_rms_normalised(pose, &object, &image) < 1e-9)
            .count();
        assert!((1..=4).contains(&exact), "case {case}: {exact} exact poses");
        if candidates.iter().any(|pose| {
            rotation_error_deg(&truth.rotation, &pose.rotation) < ROTATION_TOLERANCE_DEG
                && (pose.translation - truth.translation).norm() / truth.translation.norm()
                    < TRANSLATION_TOLERANCE
        }) {
            found += 1;
        }
    }
    assert_eq!(found, cases);
}

#[test]
fn error_messages_name_the_method_and_the_input() {
    let object = vec![Vector3::new(0.0, 0.0, 0.0), Vector3::new(1.0, 0.0, 0.0)];
    let image = vec![Vector2::new(0.0, 0.0); 2];
    let err = Solver::Dls.solve(&object, &image).unwrap_err();
    assert_eq!(err.to_string(), "DLS needs at least 3 points, got 2");
    // Every point on one ray: the translation is not determined.
    let object = vec![
        Vector3::new(0.0, 0.0, 0.0),
        Vector3::new(10.0, 0.0, 0.0),
        Vector3::new(0.0, 10.0, 0.0),
        Vector3::new(0.0, 0.0, 10.0),
    ];
    let image = vec![Vector2::new(0.1, 0.2); 4];
    let err = Solver::Dls.solve(&object, &image).unwrap_err();
    assert_eq!(
        err.to_string(),
        "all image points coincide; no PnP method can recover a pose from one image point"
    );
    let err = PnpError::PolynomialSolver {
        solver: "DLS",
        source: CubicSystemError::SingularTemplate { degree: 7 },
    };
    assert_eq!(
        err.to_string(),
        "DLS: the polynomial solver failed: the Macaulay elimination template is singular (degree-7 block)"
    );
    // DLS accepts coplanar points.
    assert!(!Solver::Dls.needs_noncoplanar());
    assert_eq!(Solver::Dls.min_points(), 3);
    assert_eq!(Solver::from_name("dls"), Some(Solver::Dls));
}

#[test]
fn candidates_are_distinct_minima_in_front_with_the_lowest_cost_first() {
    for case in 0..50 {
        let mut rng = stream_rng(SEED, 8, case);
        let count = rng.random_range(4..=12);
        let object = random_points(&mut rng, count, 100.0);
        let truth = random_pose(&mut rng, 300.0, 0.3);
        let image: Vec<_> = object
            .iter()
            .map(|p| {
                let noise = Vector2::new(rng.random::<f64>() - 0.5, rng.random::<f64>() - 0.5);
                truth.project_normalised(p) + noise * 2e-3
            })
            .collect();
        let Ok((candidates, statistics)) = solve_with_statistics(&object, &image) else {
            continue;
        };
        assert!((1..=CHARTS.len()).contains(&statistics.charts_solved));
        assert_eq!(statistics.returned, candidates.len());
        assert!(statistics.local_minima <= statistics.real_critical_points);
        assert!(statistics.in_front <= statistics.trusted);
        assert!(statistics.trusted <= statistics.local_minima);
        for (i, a) in candidates.iter().enumerate() {
            assert!(a.all_in_front(&object));
            for b in &candidates[i + 1..] {
                assert!(
                    rotation_error_deg(&a.rotation, &b.rotation).to_radians()
                        >= DUPLICATE_ROTATION_RAD
                );
            }
        }
        let matrices = CostMatrices::new(&object, &image).unwrap();
        let costs: Vec<f64> = candidates
            .iter()
            .map(|pose| matrices.cost_of(pose.rotation.matrix()))
            .collect();
        assert!(costs.windows(2).all(|w| w[0] <= w[1]));
        assert!(best_candidate("DLS", &candidates, &object, &image).is_ok());
    }
}

/// Fibonacci-lattice directions on the upper hemisphere, `count` of them.
fn hemisphere_directions(count: usize) -> impl Iterator<Item = Vector3<f64>> {
    let golden_angle = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    (0..count).map(move |i| {
        let z = (i as f64 + 0.5) / count as f64;
        let r = (1.0 - z * z).sqrt();
        let phi = golden_angle * i as f64;
        Vector3::new(r * phi.cos(), r * phi.sin(), z)
    })
}

/// The rotation of a (not necessarily unit) quaternion `(w, x, y, z)`.
fn quaternion_rotation(q: [f64; 4]) -> Rotation3<f64> {
    UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(q[0], q[1], q[2], q[3]))
        .to_rotation_matrix()
}

/// Whether the optimal translation for `rotation` puts the object's
/// centroid in front of the camera (from the pose, not the depth form).
fn centroid_in_front(matrices: &CostMatrices, rotation: &Matrix3<f64>) -> bool {
    matrices.pose(rotation).transform(&matrices.centroid).z > 0.0
}

#[test]
fn centroid_depth_form_is_the_depth_at_the_optimal_translation() {
    let (object, image) = problem_data(6);
    let matrices = CostMatrices::new(&object, &image).unwrap();
    let depth = matrices.quaternion_centroid_depth();
    let mut rng = stream_rng(SEED, 11, 0);
    for _ in 0..20 {
        let q = UnitQuaternion::from_rotation_matrix(&uniform_rotation(&mut rng));
        let (w, x, y, z) = (q.w, q.i, q.j, q.k);
        let monomials = SVector::<f64, 10>::from_column_slice(&[
            w * w,
            w * x,
            w * y,
            w * z,
            x * x,
            x * y,
            x * z,
            y * y,
            y * z,
            z * z,
        ]);
        let rotation = q.to_rotation_matrix();
        let direct = matrices
            .pose(rotation.matrix())
            .transform(&matrices.centroid)
            .z
            / matrices.scale;
        assert!((depth.dot(&monomials) - direct).abs() <= 1e-10 * direct.abs().max(1.0));
    }
}

/// How far above the dense search's least cost [`CostMatrices::equator_cost`]
/// may stop when the least in-front half-turn cost lies on the boundary
/// (centroid depth 0): the backtracking descent stops short of it (1.094×
/// in case 5, chart 2). Such half-turns are far costlier than the pose and
/// never decide the first chart.
const BOUNDARY_COST_SLACK: f64 = 1.1;

#[test]
fn equator_cost_is_the_least_cost_of_the_charts_half_turns() {
    // Dense sampling (a 1.5° lattice) of the half-turns that leave the
    // centroid in front bounds the least cost from above; the minimiser
    // found is such a half-turn of the chart and costs what it says.
    for case in [3, 4, 5] {
        let (object, image) = problem_data(case);
        let matrices = CostMatrices::new(&object, &image).unwrap();
        let gram = matrices.quaternion_gram();
        let mut costs = [0.0; 4];
        for (chart, centre) in CHARTS.iter().enumerate() {
            let free: Vec<usize> = (0..4).filter(|&k| k != chart).collect();
            let dense = hemisphere_directions(10_000)
                .map(|u| {
                    let mut q = [0.0; 4];
                    for (slot, value) in free.iter().zip(u.iter()) {
                        q[*slot] = *value;
                    }
                    let rotation = quaternion_rotation(q);
                    if centroid_in_front(&matrices, rotation.matrix()) {
                        matrices.cost_of(rotation.matrix())
                    } else {
                        f64::INFINITY
                    }
                })
                .fold(f64::INFINITY, f64::min);
            let (least, q) = matrices.equator_minimum(&gram, chart);
            assert_eq!(q[chart], 0.0);
            let rotation = quaternion_rotation(q);
            // A half-turn of this chart: its Cayley vector is infinite.
            let relative = rotation.matrix() * Matrix3::from_diagonal(&Vector3::from(*centre));
            assert!((relative.trace() + 1.0).abs() < 1e-12);
            assert!(centroid_in_front(&matrices, rotation.matrix()));
            let direct = matrices.cost_of(rotation.matrix());
            assert!(
                (least - direct).abs() <= 1e-12 * direct.abs().max(1e-300),
                "case {case}, chart {chart}: {least} vs {direct}"
            );
            // An interior minimum is met exactly; one on the boundary, where
            // the centroid reaches the camera plane, is approached by the
            // backtracking descent to within a few per cent.
            let depth_mm = matrices
                .pose(rotation.matrix())
                .transform(&matrices.centroid)
                .z;
            let on_boundary = depth_mm < 1e-3 * PROBLEM_DEPTH_MM;
            let slack = if on_boundary {
                BOUNDARY_COST_SLACK
            } else {
                1.0
            };
            assert!(
                least <= dense * slack,
                "case {case}, chart {chart}: {least} vs {dense}"
            );
            costs[chart] = matrices.equator_cost(&gram, chart);
            assert_eq!(costs[chart], least);
        }
        let largest = (0..4).max_by(|&a, &b| costs[a].total_cmp(&costs[b]).then(b.cmp(&a)));
        assert_eq!(Some(matrices.first_chart(&gram)), largest);
    }
}

/// A seven-point layout produced by `layout-opt search --objective mc:dls`
/// (a biprism with tilted arms and a hub point), mm.
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
/// x offsets 0, 50 and 100 mm.
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

#[test]
fn equator_cost_finds_a_zero_cost_half_turn_between_the_samples() {
    // A tilt about x has quaternion (cos 15°, sin 15°, 0, 0): noise-free, it
    // is a zero-cost half-turn of the charts about y and z. The 64 samples
    // miss its narrow cost valley (the least sample costs 0.16, more than
    // the other charts' 0.12), so chart-y was solved first, where the true
    // pose is at infinity.
    let object = search_layout();
    let truth = Pose::new(
        Rotation3::from_axis_angle(&Vector3::x_axis(), 30f64.to_radians()),
        Vector3::new(0.0, 0.0, 600.0),
    );
    let image = project(&truth, &object);
    let matrices = CostMatrices::new(&object, &image).unwrap();
    let gram = matrices.quaternion_gram();
    let truth_cost = matrices.cost_of(truth.rotation.matrix());
    for chart in [2, 3] {
        let (least, q) = matrices.equator_minimum(&gram, chart);
        assert!(
            least <= truth_cost + 1e-12,
            "chart {chart}: {least} vs {truth_cost}"
        );
        let found = quaternion_rotation(q);
        assert!(rotation_error_deg(&truth.rotation, &found) < 1e-8);
    }
    assert!(matrices.first_chart(&gram) < 2);
}

/// Noise-free, every pose of the validation protocol at tilt ±30° (before
/// the fix, 177° off at several of them; now at most 3·10⁻¹²° and a relative
/// translation error of 10⁻¹³).
#[test]
fn search_layout_at_tilt_30_is_recovered() {
    let object = search_layout();
    for (case, truth) in tilt_30_poses().iter().enumerate() {
        let (rotation_error, translation_error) = best_errors(truth, &object);
        assert!(
            rotation_error < ROTATION_TOLERANCE_DEG && translation_error < TRANSLATION_TOLERANCE,
            "case {case}: errors {rotation_error}° and {translation_error}"
        );
    }
}

#[test]
fn on_demand_charts_find_the_four_chart_solve_s_best_pose() {
    // Noise-free, every attitude: the on-demand solve's best candidate is the
    // truth, as the four-chart solve's is, with fewer charts on average.
    let mut charts = 0;
    let cases = 200;
    for case in 0..cases {
        let mut rng = stream_rng(SEED, 9, case);
        let count = rng.random_range(4..=12);
        let object = random_points(&mut rng, count, 100.0);
        let truth = pose_with(uniform_rotation(&mut rng), &mut rng);
        let image = project(&truth, &object);
        let (candidates, statistics) =
            solve_with_statistics_in(&object, &image, ChartPolicy::OnDemand).unwrap();
        charts += statistics.charts_solved;
        let best = best_candidate("DLS", &candidates, &object, &image).unwrap();
        assert!(
            rotation_error_deg(&truth.rotation, &best.rotation) < ROTATION_TOLERANCE_DEG,
            "case {case}"
        );
        let (all, _) = solve_with_statistics_in(&object, &image, ChartPolicy::All).unwrap();
        let best_all = best_candidate("DLS", &all, &object, &image).unwrap();
        assert!(rotation_error_deg(&best_all.rotation, &best.rotation) < ROTATION_TOLERANCE_DEG);
    }
    assert!(
        charts < 2 * cases as usize,
        "{charts} charts for {cases} problems"
    );
}
