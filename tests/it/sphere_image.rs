//! The exact sphere-image model against independent ground truth: the
//! silhouette sampled by rays tangent to the sphere, fitted with a general
//! conic by least squares.

use layout_opt::camera::Camera;
use layout_opt::sphere_image::{SphereImageError, SphereSilhouette};
use layout_opt::synthetic::stream_rng;
use nalgebra::{DMatrix, Matrix2, Vector2, Vector3};
use rand::Rng;

/// Seed of this file's streams.
const SEED: u64 = 17;
/// Tangent rays sampled per silhouette.
const SAMPLES: usize = 200;

/// Points where rays from the camera centre touch the sphere: the circle
/// `{X : (X − C)·X = 0, |X − C| = r}`, projected by the pinhole camera.
fn tangent_silhouette(camera: &Camera, centre: &Vector3<f64>, radius: f64) -> Vec<Vector2<f64>> {
    let distance = centre.norm();
    let d = centre / distance;
    let helper = if d.x.abs() < 0.9 {
        Vector3::x()
    } else {
        Vector3::y()
    };
    let e1 = d.cross(&helper).normalize();
    let e2 = d.cross(&e1);
    let along = -radius / distance;
    let across = (1.0 - along * along).sqrt();
    (0..SAMPLES)
        .map(|k| {
            let phi = std::f64::consts::TAU * (k as f64 + 0.37) / SAMPLES as f64;
            let x = centre + radius * (d * along + (e1 * phi.cos() + e2 * phi.sin()) * across);
            assert!(((x - centre).dot(&x)).abs() < 1e-9 * distance * distance);
            camera.project(&x).unwrap()
        })
        .collect()
}

/// A general conic fitted to `points` by linear least squares (smallest
/// singular vector, Hartley-normalised coordinates); returns its centre.
fn fitted_conic_centre(points: &[Vector2<f64>]) -> Vector2<f64> {
    let mean = points.iter().sum::<Vector2<f64>>() / points.len() as f64;
    let scale = points.iter().map(|p| (p - mean).norm()).sum::<f64>() / points.len() as f64;
    let design = DMatrix::from_fn(points.len(), 6, |row, column| {
        let p = (points[row] - mean) / scale;
        [p.x * p.x, p.x * p.y, p.y * p.y, p.x, p.y, 1.0][column]
    });
    let svd = design.svd(false, true);
    let v_t = svd.v_t.unwrap();
    let smallest = (0..6)
        .min_by(|&a, &b| svd.singular_values[a].total_cmp(&svd.singular_values[b]))
        .unwrap();
    let c = v_t.row(smallest);
    let (a, b, cc, d, e) = (c[0], c[1], c[2], c[3], c[4]);
    let centre =
        Matrix2::new(2.0 * a, b, b, 2.0 * cc).try_inverse().unwrap() * Vector2::new(-d, -e);
    mean + centre * scale
}

#[test]
fn ellipse_centre_matches_a_fitted_tangent_silhouette() {
    let camera = Camera::paper();
    let mut rng = stream_rng(SEED, 1, 0);
    let mut worst_centre = 0.0f64;
    let mut worst_on_conic = 0.0f64;
    for _ in 0..200 {
        let radius = rng.random_range(1.0..20.0);
        let depth = rng.random_range(150.0..1000.0);
        let pixel = Vector2::new(
            rng.random_range(0.0..camera.width() as f64),
            rng.random_range(0.0..camera.height() as f64),
        );
        let m = camera.pixel_to_normalised(&pixel).unwrap();
        let centre = Vector3::new(m.x * depth, m.y * depth, depth);
        let model = SphereSilhouette::new(&camera, &centre, radius).unwrap();
        let samples = tangent_silhouette(&camera, &centre, radius);
        let fitted = fitted_conic_centre(&samples);
        worst_centre = worst_centre.max((fitted - model.ellipse_centre_px).norm());
        // Every sample lies on the model's conic: first-order geometric
        // distance |pᵀQp| / |∇(pᵀQp)|.
        for p in &samples {
            let h = Vector3::new(p.x, p.y, 1.0);
            let value = h.dot(&(model.conic_px * h));
            let gradient = (2.0 * model.conic_px * h).fixed_rows::<2>(0).norm();
            worst_on_conic = worst_on_conic.max(value.abs() / gradient);
        }
    }
    assert!(
        worst_centre < 1e-6,
        "fitted vs model centre: {worst_centre:e} px"
    );
    assert!(
        worst_on_conic < 1e-6,
        "samples off the conic: {worst_on_conic:e} px"
    );
}

/// The magnitude: 10 mm spheres at 200 mm depth near the edge of
/// the paper's image are displaced by a few tenths of a pixel, four times
/// as much for 20 mm spheres.
#[test]
fn displacement_magnitude_at_the_image_edge() {
    let camera = Camera::paper();
    let depth = 200.0;
    let margin_px = 20.0;
    let edges = [
        Vector2::new(margin_px, camera.cy()),
        Vector2::new(camera.width() as f64 - margin_px, camera.cy()),
        Vector2::new(camera.cx(), margin_px),
        Vector2::new(camera.cx(), camera.height() as f64 - margin_px),
    ];
    for pixel in edges {
        let m = camera.pixel_to_normalised(&pixel).unwrap();
        let centre = Vector3::new(m.x * depth, m.y * depth, depth);
        let ten = SphereSilhouette::new(&camera, &centre, 5.0).unwrap();
        let twenty = SphereSilhouette::new(&camera, &centre, 10.0).unwrap();
        let off_axis_px = (pixel - Vector2::new(camera.cx(), camera.cy())).norm();
        // Closed form: |u − c| r² / (z² − r²).
        let expected = off_axis_px * 25.0 / (depth * depth - 25.0);
        assert!((ten.displacement_px() - expected).abs() < 1e-9);
        assert!(
            (0.1..0.45).contains(&ten.displacement_px()),
            "{pixel}: {} px",
            ten.displacement_px()
        );
        let ratio = twenty.displacement_px() / ten.displacement_px();
        assert!((ratio - 4.0).abs() < 0.02, "ratio {ratio}");
        // Outward: farther from the principal point than the centre's image.
        let principal = Vector2::new(camera.cx(), camera.cy());
        assert!((ten.ellipse_centre_px - principal).norm() > (ten.centre_px - principal).norm());
    }
    // On the optical axis there is no displacement.
    let on_axis = SphereSilhouette::new(&camera, &Vector3::new(0.0, 0.0, depth), 5.0).unwrap();
    assert!(on_axis.displacement_px() < 1e-12);
}

#[test]
fn spheres_without_an_elliptical_silhouette_are_typed_errors() {
    let camera = Camera::paper();
    assert!(matches!(
        SphereSilhouette::new(&camera, &Vector3::new(0.0, 0.0, 4.0), 5.0),
        Err(SphereImageError::CameraInsideSphere { .. })
    ));
    assert!(matches!(
        SphereSilhouette::new(&camera, &Vector3::new(100.0, 0.0, 3.0), 5.0),
        Err(SphereImageError::NotInFront { .. })
    ));
}

/// The first-order bias term predicts the systematic error of a point-model
/// fit on noise-free ellipse centres (ML, which has no bias of its own), per
/// axis, in every scenario of a small near-field grid; with centre
/// observations both vanish.
#[test]
fn first_order_bias_predicts_the_systematic_error_of_ml() {
    use layout_opt::montecarlo::{self, MonteCarloConfig, Target, DEFAULT_GROSS_THRESHOLD_DEG};
    use layout_opt::noise::NoiseModel;
    use layout_opt::pnp::Solver;
    use layout_opt::scenario::{Range, ScenarioGrid};
    use layout_opt::sphere_image::Observation;
    let camera = Camera::paper();
    let object = layout_opt::synthetic::biprism_points(50.0);
    let grid = ScenarioGrid::new(
        Range::list(&[200.0, 400.0]),
        Range::list(&[0.0, 100.0]),
        Range::single(0.0),
        Range::list(&[-50.0, -20.0, 10.0, 40.0]),
        Range::single(15.0),
        Range::single(0.0),
        Range::single(0.5),
    )
    .unwrap();
    let sigmas = [None; 7];
    let target = Target {
        camera: &camera,
        object: &object,
        sphere_diameter_mm: 10.0,
        point_sigma_px: &sigmas,
    };
    let run = |observation| {
        let config = MonteCarloConfig {
            trials: 1,
            seed: SEED,
            solvers: vec![Solver::Ml],
            noise: NoiseModel::default(),
            gross_threshold_deg: DEFAULT_GROSS_THRESHOLD_DEG,
            observation,
        };
        montecarlo::run(&target, &grid.scenarios(), &config, &|_| {}).unwrap()
    };
    let mut compared = 0;
    for outcome in run(Observation::EllipseCentre) {
        let (Some(bias), Some(measured)) = (outcome.bias, outcome.solvers[0].systematic) else {
            continue;
        };
        assert!(bias.max_displacement_px > 0.0);
        let predicted = bias.pose;
        let scale = predicted.rotation_norm_deg();
        assert!(scale > 1e-5, "{scale}");
        for k in 0..3 {
            // fx and fy differ by 4e-4: ML fits the normalised plane, the
            // first-order model weights pixels.
            assert!(
                (predicted.rotation_deg[k] - measured.rotation_deg[k]).abs() < 0.01 * scale,
                "{:?}: predicted {:?}, measured {:?}",
                outcome.scenario,
                predicted.rotation_deg,
                measured.rotation_deg
            );
        }
        let translation = predicted.translation_norm_mm();
        assert!(
            (predicted.translation_norm_mm() - measured.translation_norm_mm()).abs()
                < 0.01 * translation
        );
        compared += 1;
    }
    assert!(compared >= 12, "{compared} scenarios compared");
    for outcome in run(Observation::Centre) {
        if let (Some(bias), Some(measured)) = (outcome.bias, outcome.solvers[0].systematic) {
            assert_eq!(bias.max_displacement_px, 0.0);
            // ML's own stopping rule leaves up to ~1e-6° on exact data.
            assert!(
                measured.rotation_norm_deg() < 1e-5,
                "{}",
                measured.rotation_norm_deg()
            );
        }
    }
}

/// The sphere-model ML is exact on noise-free ellipse centres in every
/// in-front scenario of the default validate grid (the paper's protocol),
/// where the point-model ML is biased; prints the figures.
#[test]
fn sphere_model_ml_is_exact_over_the_default_grid() {
    use layout_opt::pnp::{ml, ml_sphere};
    use layout_opt::pose::rotation_error_deg;
    use layout_opt::scenario::ScenarioGrid;
    use layout_opt::sphere_image::ellipse_centre_normalised;
    let object = layout_opt::synthetic::biprism_points(50.0);
    let radius = 5.0;
    let mut worst_sphere: f64 = 0.0;
    let mut worst_sphere_mm: f64 = 0.0;
    let mut naive = Vec::new();
    for scenario in ScenarioGrid::paper_protocol(2.0).scenarios() {
        if scenario.sigma_px != 0.5 {
            continue;
        }
        let truth = scenario.pose();
        let Ok(image) = object
            .iter()
            .map(|p| ellipse_centre_normalised(&truth.transform(p), radius))
            .collect::<Result<Vec<_>, _>>()
        else {
            continue;
        };
        let pose = ml_sphere::solve(&object, &image, radius).unwrap();
        worst_sphere = worst_sphere.max(rotation_error_deg(&truth.rotation, &pose.rotation));
        worst_sphere_mm = worst_sphere_mm.max((pose.translation - truth.translation).norm());
        let point = ml::solve(&object, &image).unwrap()[0];
        naive.push(rotation_error_deg(&truth.rotation, &point.rotation));
    }
    naive.sort_by(f64::total_cmp);
    let median = naive[naive.len() / 2];
    let max = naive[naive.len() - 1];
    eprintln!(
        "{} poses: sphere-model ML worst {worst_sphere:.2e}° / {worst_sphere_mm:.2e} mm; point-model ML on ellipse centres median {median:.2e}°, max {max:.2e}°",
        naive.len()
    );
    assert!(worst_sphere < 1e-6, "{worst_sphere}°");
    assert!(worst_sphere_mm < 1e-6, "{worst_sphere_mm} mm");
    assert!(median > 1e-4, "point model median bias {median}°");
}
