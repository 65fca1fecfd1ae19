//! Bad input never panics: arbitrary (including NaN, infinite, duplicate,
//! collinear, coplanar, mismatched and behind-the-camera) inputs give either a
//! finite pose or a typed error, for every solver.

use layout_opt::pnp::{PnpError, Solver};
use nalgebra::{Vector2, Vector3};
use proptest::prelude::*;

fn coordinate() -> impl Strategy<Value = f64> {
    prop_oneof![
        8 => -200.0..200.0f64,
        1 => Just(f64::NAN),
        1 => Just(f64::INFINITY),
        1 => Just(0.0),
        1 => Just(1e300),
    ]
}

fn points3(max: usize) -> impl Strategy<Value = Vec<Vector3<f64>>> {
    prop::collection::vec((coordinate(), coordinate(), coordinate()), 0..max).prop_map(|v| {
        v.into_iter()
            .map(|(x, y, z)| Vector3::new(x, y, z))
            .collect()
    })
}

fn points2(max: usize) -> impl Strategy<Value = Vec<Vector2<f64>>> {
    prop::collection::vec((coordinate(), coordinate()), 0..max).prop_map(|v| {
        v.into_iter()
            .map(|(x, y)| Vector2::new(x / 100.0, y / 100.0))
            .collect()
    })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, .. ProptestConfig::default() })]

    #[test]
    fn arbitrary_inputs_never_panic(object in points3(12), image in points2(12)) {
        for &solver in Solver::ALL {
            if let Ok(pose) = solver.solve_best(&object, &image) {
                prop_assert!(pose.is_finite(), "{solver} returned a non-finite pose");
            }
        }
    }

    #[test]
    fn matched_arbitrary_inputs_never_panic(
        pairs in prop::collection::vec(((-100.0..100.0f64, -100.0..100.0f64, -100.0..100.0f64), (-1.0..1.0f64, -1.0..1.0f64)), 0..12)
    ) {
        let object: Vec<_> = pairs.iter().map(|((x, y, z), _)| Vector3::new(*x, *y, *z)).collect();
        let image: Vec<_> = pairs.iter().map(|(_, (u, v))| Vector2::new(*u, *v)).collect();
        for &solver in Solver::ALL {
            if let Ok(pose) = solver.solve_best(&object, &image) {
                prop_assert!(pose.is_finite(), "{solver} returned a non-finite pose");
                prop_assert!(pose.all_in_front(&object), "{solver} put points behind the camera");
            }
        }
    }
}

fn biprism() -> Vec<Vector3<f64>> {
    layout_opt::synthetic::biprism_points(50.0)
}

#[test]
fn typed_errors_for_each_kind_of_bad_input() {
    let object = biprism();
    let image: Vec<Vector2<f64>> = object
        .iter()
        .map(|p| Vector2::new(p.x / (p.z + 500.0), p.y / (p.z + 500.0)))
        .collect();
    for &solver in Solver::ALL {
        // Too few points.
        let few = solver.min_points() - 1;
        assert!(matches!(
            solver.solve_best(&object[..few], &image[..few]),
            Err(PnpError::TooFewPoints { .. })
        ));
        // Mismatched lengths.
        assert!(matches!(
            solver.solve_best(&object, &image[..6]),
            Err(PnpError::MismatchedLengths {
                object: 7,
                image: 6
            })
        ));
        // NaN.
        let mut nan = image.clone();
        nan[3].y = f64::NAN;
        assert_eq!(
            solver.solve_best(&object, &nan),
            Err(PnpError::NonFinite {
                kind: "image",
                index: 3
            })
        );
        // Duplicates.
        let mut duplicate = object.clone();
        duplicate[6] = duplicate[2];
        assert!(matches!(
            solver.solve_best(&duplicate, &image),
            Err(PnpError::DuplicatePoints {
                first: 2,
                second: 6
            })
        ));
        // Collinear.
        let line: Vec<_> = (0..7)
            .map(|i| Vector3::new(i as f64, 0.0, 2.0 * i as f64))
            .collect();
        assert_eq!(solver.solve_best(&line, &image), Err(PnpError::Collinear));
        // Points behind the camera: the image of the biprism seen from the
        // other side of the camera centre (x → −x through the pinhole).
        let behind: Vec<Vector2<f64>> = object
            .iter()
            .map(|p| {
                let c = p - Vector3::new(0.0, 0.0, 500.0);
                Vector2::new(c.x / c.z, c.y / c.z)
            })
            .map(|m| -m)
            .collect();
        match solver.solve_best(&object, &behind) {
            Err(PnpError::BehindCamera { .. }) | Err(PnpError::Degenerate { .. }) => {}
            Ok(pose) => assert!(pose.all_in_front(&object), "{solver}"),
            Err(other) => panic!("{solver}: unexpected {other}"),
        }
    }
    // Coplanar points, for the methods that need a 3D spread.
    let plane: Vec<_> = (0..7)
        .map(|i| {
            Vector3::new(
                (i % 3) as f64 * 10.0,
                (i / 3) as f64 * 10.0 + (i * i) as f64,
                0.0,
            )
        })
        .collect();
    for &solver in Solver::ALL.iter().filter(|s| s.needs_noncoplanar()) {
        assert!(matches!(
            solver.solve_best(&plane, &image),
            Err(PnpError::Coplanar { .. })
        ));
    }
}
