//! Tests of the parent module.

use super::*;
use crate::layout::Layout;
use crate::scenario::Range;
use approx::assert_relative_eq;
use nalgebra::Rotation3;

/// Every sight line of sphere `k`'s silhouette followed to the sphere
/// against every part, with no culling, no cut-off plane and no
/// skipped lines: the model's rule as written, for a scenario in which
/// the spheres are all in front (other spheres are not asked).
fn traced_in_full(
    eye: &Vector3<f64>,
    centres: &[Vector3<f64>],
    radius: f64,
    supports: &Supports,
    k: usize,
) -> usize {
    let centre = centres[k];
    silhouette_directions(eye, &centre, radius)
        .filter(|direction| {
            let t_sphere = occluders::ray_ball(eye, direction, &centre, radius)
                .unwrap_or_else(|| (centre - eye).dot(direction));
            supports.occluders().iter().any(|part| {
                let grow = if part.is_fillet_of(&centre) {
                    occluders::FILLET_MARGIN_MM
                } else {
                    0.0
                };
                part.ray_hit_grown(eye, direction, f64::INFINITY, grow)
                    .is_some_and(|t| {
                        let hit = eye + direction * t;
                        t < t_sphere - SURFACE_TOLERANCE_MM
                            && centres
                                .iter()
                                .all(|c| (hit - c).norm() > radius + SURFACE_TOLERANCE_MM)
                    })
            })
        })
        .count()
}

/// The paper's biprism with the search's supports, and the same with
/// a fillet at its first sphere and a plate box added, so that every
/// kind of part is culled.
fn test_parts() -> (Vec<Vector3<f64>>, f64, [Supports; 2]) {
    let layout = Layout::paper_biprism();
    let centres = layout.positions();
    let straight = crate::mesh::straight_supports(
        &centres,
        layout.sphere_diameter_mm,
        &crate::mesh::MarkerOptions::default(),
    );
    let mut parts = straight.occluders().to_vec();
    let (cone, strut) = (&parts[0], &parts[1]);
    let (
        Occluder::RoundCone {
            a,
            radius_a,
            b,
            radius_b,
        },
        Occluder::Capsule { a: s, b: e, radius },
    ) = (cone, strut)
    else {
        panic!("a cone and a strut first: {parts:?}");
    };
    let fillet = Occluder::Fillet {
        hulls: vec![(*a, *radius_a, *b, *radius_b)],
        pieces: vec![(*s, s + (e - s).normalize() * 8.0, *radius)],
        blend_mm: 1.5,
    };
    parts.push(fillet);
    parts.push(Occluder::Box {
        centre: Vector3::new(0.0, 0.0, 60.0),
        half_extents: Vector3::new(40.0, 40.0, 2.0),
    });
    let radius = 0.5 * layout.sphere_diameter_mm;
    (centres, radius, [straight, Supports::new(parts)])
}

/// The pose of a camera at `eye` looking at `target`.
fn looking_at(eye: &Vector3<f64>, target: &Vector3<f64>) -> Pose {
    let direction = (target - eye).normalize();
    let up = if direction.y.abs() < 0.9 {
        Vector3::y()
    } else {
        Vector3::x()
    };
    let rotation = Rotation3::face_towards(&direction, &up).inverse();
    Pose::new(rotation, -(rotation * eye))
}

#[test]
fn the_own_cone_lies_within_the_tolerance_of_its_sphere_below_its_level() {
    // The search's cone (10 mm sphere, 40° half-angle onto a 1.2 mm
    // strut), a short one, a blunt one and one that widens.
    let cones = [
        (5.0, 5.9, 0.6),
        (5.0, 4.5, 2.0),
        (3.0, 2.0, 2.5),
        (2.0, 6.0, 3.0),
    ];
    for (radius, length, radius_b) in cones {
        let level = own_cone_level(radius, length, radius_b);
        let sine = (radius - radius_b) / length;
        assert!(level >= (radius * sine).min(length - radius_b));
        let cone = Occluder::RoundCone {
            a: Vector3::zeros(),
            radius_a: radius,
            b: Vector3::new(0.0, 0.0, length),
            radius_b,
        };
        let mut within = 0;
        for i in 0..200_000 {
            let f = i as f64;
            let p = Vector3::new(
                (f * 0.618_033_988_75).fract() * 2.0 - 1.0,
                (f * 0.414_213_562_37).fract() * 2.0 - 1.0,
                (f * 0.732_050_807_57).fract(),
            )
            .component_mul(&Vector3::new(
                radius.max(radius_b) + 0.5,
                radius.max(radius_b) + 0.5,
                length + radius_b + radius,
            )) - Vector3::new(0.0, 0.0, radius);
            if p.z > level || cone.distance(&p) > 0.0 {
                continue;
            }
            within += 1;
            assert!(
                p.norm() - radius <= SURFACE_TOLERANCE_MM,
                "{radius} {length} {radius_b}: {p:?} at level {level}"
            );
        }
        assert!(within > 1000, "{within}");
    }
    // The search's cone: the level lies past the circle where the flank
    // leaves the ball, and just past it the flank is beyond the
    // tolerance.
    let level = own_cone_level(5.0, 5.9, 0.6);
    let sine = 4.4 / 5.9;
    assert!(level > 5.0 * sine + 0.5, "{level}");
    let past = level + 0.05;
    let flank_radius = (5.0 - (past - 5.0 * sine) / (1.0 - sine * sine).sqrt() * sine)
        / (1.0 - sine * sine).sqrt();
    let on_flank = Vector3::new(flank_radius - 1e-9, 0.0, past);
    assert!(on_flank.norm() - 5.0 > SURFACE_TOLERANCE_MM - 0.05);
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig {
        cases: 96,
        // Nothing written next to the sources on a failure.
        failure_persistence: None,
        ..proptest::prelude::ProptestConfig::default()
    })]

    /// The culled model counts exactly the lines a full trace hides,
    /// from eyes all round the part (the tolerance: none).
    #[test]
    fn support_fractions_equal_a_full_trace_from_any_eye(
        azimuth in 0.0..std::f64::consts::TAU,
        height in -1.0f64..1.0,
        distance in 120.0f64..1500.0,
        aim in proptest::array::uniform3(-15.0f64..15.0),
    ) {
        let (centres, radius, supports) = test_parts();
        let across = (1.0 - height * height).sqrt();
        let eye = Vector3::new(across * azimuth.cos(), across * azimuth.sin(), height)
            * distance;
        let pose = looking_at(&eye, &Vector3::from(aim));
        proptest::prop_assume!(centres.iter().all(|c| pose.transform(c).z > radius));
        let camera = Camera::paper();
        for supports in &supports {
            let fast = support_fractions(&camera, &pose, &centres, radius, supports);
            for (k, f) in fast.iter().enumerate() {
                let full = traced_in_full(&eye, &centres, radius, supports, k);
                proptest::prop_assert_eq!(*f, full as f64 / SILHOUETTE_RAYS as f64, "sphere {}", k);
            }
        }
    }
}

#[test]
fn the_screened_decision_equals_a_full_trace_over_a_grid() {
    let (centres, radius, supports) = test_parts();
    let range = |text: &str| text.parse::<Range>().expect("a valid range");
    let scenarios = ScenarioGrid::new(
        range("200..1000:400"),
        range("0..100:50"),
        range("0"),
        range("-60..60:10"),
        range("-40..40:20"),
        range("0"),
        range("0.5"),
    )
    .expect("a valid grid")
    .scenarios();
    let eyes = EyeCone::of(&scenarios).expect("eyes");
    let camera = Camera::paper();
    let (mut compared, mut hidden) = (0, 0);
    for supports in &supports {
        let screen = eyes.screen(&centres, radius, supports);
        for scenario in &scenarios {
            let pose = scenario.pose();
            if !centres.iter().all(|c| pose.transform(c).z > radius) {
                continue;
            }
            let eye = pose.camera_centre();
            let full: Vec<usize> = (0..centres.len())
                .map(|k| traced_in_full(&eye, &centres, radius, supports, k))
                .collect();
            for max_hidden in [0.0, 0.01, 0.05] {
                let max_hidden = MaxHidden::new(max_hidden).expect("a fraction");
                let decided: Vec<usize> = spheres_hidden_by_supports(
                    &camera, &pose, &centres, radius, supports, &screen, max_hidden,
                )
                .collect();
                let expected: Vec<usize> = (0..centres.len())
                    .filter(|&k| full[k] as f64 / SILHOUETTE_RAYS as f64 > max_hidden.fraction())
                    .collect();
                assert_eq!(decided, expected, "{scenario:?} {max_hidden:?}");
            }
            compared += 1;
            hidden += full.iter().filter(|&&n| n > 4).count();
        }
    }
    assert!(compared > 100 && hidden > 10, "{compared} {hidden}");
}

fn head_on(depth_mm: f64) -> Pose {
    Pose::new(Rotation3::identity(), Vector3::new(0.0, 0.0, depth_mm))
}

#[test]
fn max_hidden_rejects_values_outside_zero_to_one() {
    for bad in ["-0.1", "1.01", "nan", "x"] {
        let error = bad.parse::<MaxHidden>().unwrap_err();
        assert_eq!(error.field, "max_hidden");
        assert!(error.reason.contains("from 0 to 1"), "{error}");
    }
    assert_eq!(MaxHidden::default().fraction(), DEFAULT_MAX_HIDDEN);
    assert_eq!("1".parse::<MaxHidden>().unwrap().fraction(), 1.0);
}

#[test]
fn a_capsule_across_half_the_disc_hides_half() {
    let camera = Camera::default();
    // A wide slab of capsule covering y < 0 in front of the sphere.
    let supports = Supports::new(vec![Occluder::Box {
        centre: Vector3::new(0.0, -50.0, -20.0),
        half_extents: Vector3::new(50.0, 50.0, 1.0),
    }]);
    let fractions = hidden_fractions(
        &camera,
        &head_on(500.0),
        &[Vector3::zeros()],
        5.0,
        &supports,
    );
    let f = fractions[0].expect("in front");
    assert_relative_eq!(f.support, 0.5, epsilon = 0.02);
    assert_eq!(f.sphere, 0.0);
    assert_eq!(f.outside, 0.0);
    // Behind the sphere it hides nothing.
    let behind = Supports::new(vec![Occluder::Box {
        centre: Vector3::new(0.0, -50.0, 20.0),
        half_extents: Vector3::new(50.0, 50.0, 1.0),
    }]);
    let f = hidden_fractions(&camera, &head_on(500.0), &[Vector3::zeros()], 5.0, &behind)[0]
        .expect("in front");
    assert_eq!(f.support, 0.0);
}

#[test]
fn a_sphere_in_front_hides_by_sphere_and_the_border_by_outside() {
    let camera = Camera::default();
    let centres = [Vector3::zeros(), Vector3::new(0.0, 0.0, -30.0)];
    let f = hidden_fractions(&camera, &head_on(500.0), &centres, 5.0, &Supports::none());
    assert_relative_eq!(f[0].unwrap().sphere, 1.0);
    assert_eq!(f[1].unwrap().sphere, 0.0);
    // Centre on the image's left border: half outside.
    let x = -camera.cx() * 500.0 / camera.fx();
    let pose = Pose::new(Rotation3::identity(), Vector3::new(x, 0.0, 500.0));
    let f = hidden_fractions(&camera, &pose, &[Vector3::zeros()], 5.0, &Supports::none());
    assert_relative_eq!(f[0].unwrap().outside, 0.5, epsilon = 0.03);
}

#[test]
fn supports_follow_their_spheres_and_leave_the_rest() {
    let (centres, radius, [_, supports]) = test_parts();
    assert_eq!(
        supports.following(&centres, &centres, 2.0 * radius),
        supports
    );
    // Sphere 0 moves 1.5 mm: its own cone and fillet go with it, exactly
    // onto its new centre; the plate, far from every sphere, stays.
    let mut moved = centres.clone();
    moved[0] += Vector3::new(1.5, -0.5, 0.25);
    let follows = supports.following(&centres, &moved, 2.0 * radius);
    let parts = follows.occluders();
    let Occluder::RoundCone { a, .. } = &parts[0] else {
        panic!("the first part is sphere 0's cone: {parts:?}");
    };
    assert_eq!(*a, moved[0]);
    assert!(parts.iter().any(|p| p.is_fillet_of(&moved[0])));
    assert!(!parts.iter().any(|p| p.is_fillet_of(&centres[0])));
    assert_eq!(parts.last(), supports.occluders().last());
    // Every sphere moved alike, and the reach wide enough to carry every
    // part: the supports translate, and from a translated eye each
    // sphere hides as before.
    let shift = Vector3::new(3.0, 2.0, -1.0);
    let shifted: Vec<_> = centres.iter().map(|c| c + shift).collect();
    let carried = supports.following(&centres, &shifted, 1e6);
    let camera = Camera::paper();
    let mut hidden_somewhere = false;
    for eye in [
        Vector3::new(0.0, 120.0, -500.0),
        Vector3::new(80.0, -60.0, -400.0),
    ] {
        let pose = looking_at(&eye, &Vector3::zeros());
        let moved_pose = looking_at(&(eye + shift), &shift);
        let before = support_fractions(&camera, &pose, &centres, radius, &supports);
        let after = support_fractions(&camera, &moved_pose, &shifted, radius, &carried);
        hidden_somewhere |= before.iter().any(|&f| f > 0.05);
        for (b, a) in before.iter().zip(&after) {
            assert!(
                (b - a).abs() <= 1.0 / SILHOUETTE_RAYS as f64,
                "{before:?} {after:?}"
            );
        }
    }
    assert!(
        hidden_somewhere,
        "some eye must see a support hide a sphere"
    );
}
