//! The conformance sweep's problem generator (`layout_opt::conformance`):
//! seeded reproducibility, every point in front of the camera, the requested
//! n / thickness / depth ratio honoured, and noise-free problems solved
//! exactly (rotation error < 1e-6°) by SQPnP and ML on a handful of cells.

use layout_opt::conformance::{
    diameter, generate, Cell, OffAxis, MIN_DEPTH_FRACTION, OBJECT_DIAMETER_MM,
};
use layout_opt::pnp::Solver;
use layout_opt::pose::rotation_error_deg;

const SEED: u64 = 20_260_301;
const CASES: u64 = 25;

fn cell(depth_ratio: f64, points: usize, thickness: f64, off_axis: OffAxis) -> Cell {
    Cell {
        depth_ratio,
        points,
        thickness,
        off_axis,
        distortion: false,
        sigma_px: 0.5,
    }
}

/// Cells spanning the sweep's axes and its extremes.
fn cells() -> Vec<Cell> {
    let mut cells = Vec::new();
    for depth_ratio in [0.5, 1.0, 5.0, 200.0] {
        for (points, thickness) in [(4, 1.0), (6, 0.0), (10, 0.01), (200, 0.3)] {
            for off_axis in [OffAxis::Uniform, OffAxis::TowardCorner(1.0)] {
                for distortion in [false, true] {
                    cells.push(Cell {
                        distortion,
                        ..cell(depth_ratio, points, thickness, off_axis)
                    });
                }
            }
        }
    }
    cells
}

#[test]
fn the_same_seed_gives_the_same_problem_and_another_case_another() {
    let c = cell(2.0, 8, 0.1, OffAxis::Uniform);
    let a = generate(&c, SEED, 3).problem;
    let b = generate(&c, SEED, 3).problem;
    assert_eq!(a.object, b.object);
    assert_eq!(a.pixels, b.pixels);
    assert_eq!(a.normalised, b.normalised);
    assert_eq!(a.truth, b.truth);
    assert_ne!(generate(&c, SEED, 4).problem.object, a.object);
    assert_ne!(generate(&c, SEED + 1, 3).problem.object, a.object);
}

#[test]
fn cells_differing_in_noise_or_distortion_share_their_geometry() {
    let c = cell(5.0, 10, 1.0, OffAxis::Uniform);
    let quiet = generate(&Cell { sigma_px: 0.0, ..c }, SEED, 7).problem;
    let noisy = generate(&Cell { sigma_px: 2.0, ..c }, SEED, 7).problem;
    assert_eq!(quiet.object, noisy.object);
    assert_eq!(quiet.truth, noisy.truth);
    assert_ne!(quiet.pixels, noisy.pixels);
}

#[test]
fn every_point_is_in_front_and_the_cell_is_honoured() {
    for c in cells() {
        for case in 0..CASES {
            let generated = generate(&c, SEED, case);
            let p = &generated.problem;
            assert_eq!(p.object.len(), c.points, "{c:?}");
            assert_eq!(p.normalised.len(), c.points);
            assert_eq!(p.pixels.len(), c.points);
            // Centred, diameter as promised, depth/size as requested.
            let centroid = p.object.iter().sum::<nalgebra::Vector3<f64>>() / c.points as f64;
            assert!(centroid.norm() < 1e-9 * OBJECT_DIAMETER_MM, "{c:?}");
            let size = diameter(&p.object);
            assert!((size - OBJECT_DIAMETER_MM).abs() < 1e-9 * OBJECT_DIAMETER_MM);
            let ratio = p.truth.translation.z / size;
            assert!(
                (ratio - c.depth_ratio).abs() < 1e-9 * c.depth_ratio,
                "{c:?}: depth/size {ratio}"
            );
            // In front, with the promised margin.
            for x in &p.object {
                let depth = p.truth.transform(x).z;
                assert!(
                    depth >= MIN_DEPTH_FRACTION * p.truth.translation.z,
                    "{c:?} case {case}: a point at depth {depth}"
                );
            }
            // Thickness: the object-frame z extent is at most t · side
            // (exactly 0 for planar cells), x and y extents at most the side.
            let extent = |k: usize| {
                let (lo, hi) = p.object.iter().fold((f64::MAX, f64::MIN), |(lo, hi), x| {
                    (lo.min(x[k]), hi.max(x[k]))
                });
                hi - lo
            };
            let side = generated.side_mm;
            assert!(extent(0) <= side * (1.0 + 1e-12) && extent(1) <= side * (1.0 + 1e-12));
            if c.thickness == 0.0 {
                assert!(p.object.iter().all(|x| x.z == 0.0), "{c:?}");
            } else {
                assert!(extent(2) <= c.thickness * side * (1.0 + 1e-12), "{c:?}");
                if c.points >= 200 {
                    assert!(extent(2) >= 0.9 * c.thickness * side, "{c:?}");
                }
            }
            // The solver input is what the camera sees of the pixels.
            let camera = c.camera();
            for (pixel, m) in p.pixels.iter().zip(&p.normalised) {
                let back = camera.pixel_to_normalised(pixel).unwrap();
                assert!((back - m).norm() < 1e-12);
            }
        }
    }
}

#[test]
fn the_centroid_lands_on_its_pixel_target() {
    for distortion in [false, true] {
        let axis = Cell {
            distortion,
            ..cell(3.0, 6, 1.0, OffAxis::TowardCorner(0.0))
        };
        let camera = axis.camera();
        for case in 0..CASES {
            let p = generate(&axis, SEED, case).problem;
            let pixel = camera.project(&p.truth.translation).unwrap();
            assert!((pixel.x - camera.cx()).abs() < 1e-6 && (pixel.y - camera.cy()).abs() < 1e-6);
        }
        let uniform = Cell {
            off_axis: OffAxis::Uniform,
            ..axis
        };
        for case in 0..CASES {
            let p = generate(&uniform, SEED, case).problem;
            let pixel = camera.project(&p.truth.translation).unwrap();
            assert!(camera.contains(&pixel, -1e-6), "{pixel:?}");
        }
    }
}

/// Noise-free cells across the sweep's axes: the pose is determined exactly.
fn noise_free_cells() -> Vec<Cell> {
    let noise_free = |depth_ratio, points, thickness, off_axis, distortion| Cell {
        depth_ratio,
        points,
        thickness,
        off_axis,
        distortion,
        sigma_px: 0.0,
    };
    let corner = OffAxis::TowardCorner(1.0);
    vec![
        noise_free(5.0, 10, 1.0, OffAxis::Uniform, false),
        noise_free(1.0, 6, 1.0, corner, true),
        noise_free(0.5, 20, 0.3, OffAxis::Uniform, true),
        noise_free(20.0, 8, 0.1, OffAxis::TowardCorner(0.5), false),
        noise_free(3.0, 50, 0.01, OffAxis::Uniform, true),
        noise_free(2.0, 6, 0.0, corner, false),
    ]
}

/// Every noise-free problem of [`noise_free_cells`] that `solver` accepts
/// must come back with rotation error < 1e-6°.
fn assert_solves_noise_free_exactly(solver: Solver) {
    let mut misses = Vec::new();
    for c in noise_free_cells() {
        if c.thickness == 0.0 && solver.needs_noncoplanar() {
            continue;
        }
        for case in 0..CASES {
            let p = generate(&c, SEED, case).problem;
            match solver.solve_best(&p.object, &p.normalised) {
                Ok(pose) => {
                    let error = rotation_error_deg(&p.truth.rotation, &pose.rotation);
                    if error >= 1e-6 {
                        misses.push(format!("{c:?} case {case}: {error:.3e}°"));
                    }
                }
                Err(e) => misses.push(format!("{c:?} case {case}: {e}")),
            }
        }
    }
    assert!(
        misses.is_empty(),
        "{solver}: {} noise-free problems not solved to < 1e-6°:\n{}",
        misses.len(),
        misses.join("\n")
    );
}

#[test]
fn noise_free_problems_are_solved_exactly_by_sqpnp() {
    assert_solves_noise_free_exactly(Solver::Sqpnp);
}

/// Fails on the solvers of 2026-03 (before the solver fixes): ML returns
/// `BehindCamera` on 4 of the 25 depth/size 0.5 problems (its start, the
/// paper's parallel-weighted pose, is poor that close). Not loosened: the
/// conformance sweep's report carries the same finding.
#[test]
fn noise_free_problems_are_solved_exactly_by_ml() {
    assert_solves_noise_free_exactly(Solver::Ml);
}
