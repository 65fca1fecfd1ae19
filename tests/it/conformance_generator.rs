//! The conformance sweep's problem generator (`layout_opt::conformance`):
//! seeded reproducibility, every point in front of the camera, the requested
//! n / thickness / depth ratio honoured; and noise-free problems across the
//! sweep's axes solved exactly (rotation error < 1e-6°) by every solver,
//! with the exceptions listed, and bounded, in
//! [`noise_free_exception`].

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

/// Noise-free cells across the sweep's axes (depth/size 0.5…200, n 4…200,
/// planar to cube, off-axis to the image corner, distortion on and off):
/// the pose is determined exactly.
fn noise_free_cells() -> Vec<Cell> {
    let mut cells = Vec::new();
    for depth_ratio in [0.5, 1.0, 5.0, 200.0] {
        for (points, thickness) in [(4, 1.0), (6, 0.0), (10, 0.01), (200, 0.3)] {
            for (off_axis, distortion) in [
                (OffAxis::Uniform, false),
                (OffAxis::TowardCorner(1.0), true),
            ] {
                cells.push(Cell {
                    sigma_px: 0.0,
                    distortion,
                    ..cell(depth_ratio, points, thickness, off_axis)
                });
            }
        }
    }
    cells
}

/// Where a solver may miss a noise-free pose, and the reason; `None` where
/// it must recover it exactly. Every exception is a method that starts a
/// local iteration once, from an approximation that its own paper limits:
/// - DLT on thin sets: the 11-parameter projection matrix needs a
///   noncoplanar object (Hartley & Zisserman §7.1), and a 1%-thin set
///   leaves its system nearly singular in double precision;
/// - unrefined EPnP with four points: Lepetit et al.'s closed forms assume
///   the null-space dimension N, and at n = 4 the 8×12 system has N = 4 for
///   every pose, where the relinearised system is itself ill-conditioned;
///   EPnP+GN recovers every one of these;
/// - IEPnP and the paraperspective family: one start from an affine camera
///   (weak perspective, paper §2.1; paraperspective, Horaud et al. 1997 §5,
///   valid while the object's depth extent is small against its distance),
///   so close up (depth/size ≤ 5) and for thin sets seen obliquely the
///   iteration settles in the minimum nearest a start far off (the
///   sweep's noise-free misses reach 150–180°);
/// - LHM: orthogonal iteration converges globally to *a* critical point of
///   the object-space error, not always the global minimum (Lu, Hager &
///   Mjolsness 2000 §4.3).
fn noise_free_exception(solver: Solver, cell: &Cell) -> Option<&'static str> {
    let close_or_thin = cell.depth_ratio <= 5.0 || cell.thickness <= 0.01;
    match solver {
        Solver::Dlt if cell.thickness <= 0.01 => Some("DLT needs a noncoplanar object"),
        Solver::Epnp if cell.points == 4 => Some("EPnP's closed forms at N = 4"),
        Solver::Iepnp | Solver::Parallel | Solver::ParallelGn | Solver::ParallelWeighted
            if close_or_thin =>
        {
            Some("one start from an affine camera model")
        }
        Solver::Lhm => Some("orthogonal iteration converges to a critical point"),
        _ => None,
    }
}

/// Every exact solver ([`Solver::is_exact`]), on every noise-free problem of [`noise_free_cells`] that it
/// accepts and that is not a listed exception, recovers the rotation to
/// < 1e-6°. The exceptions are counted and printed, and may not exceed the
/// miss rate measured when they were set (plus a small margin), so a
/// regression there fails too.
#[test]
fn noise_free_problems_are_solved_exactly_by_every_solver() {
    let mut misses = Vec::new();
    for &solver in Solver::ALL.iter().filter(|s| s.is_exact()) {
        let (mut excepted_misses, mut excepted_runs) = (0usize, 0usize);
        for c in noise_free_cells() {
            if (c.thickness == 0.0 && solver.needs_noncoplanar()) || c.points < solver.min_points()
            {
                continue;
            }
            let exception = noise_free_exception(solver, &c);
            for case in 0..CASES {
                let p = generate(&c, SEED, case).problem;
                let outcome = solver
                    .solve_best(&p.object, &p.normalised)
                    .map(|pose| rotation_error_deg(&p.truth.rotation, &pose.rotation));
                let missed = !matches!(outcome, Ok(error) if error < 1e-6);
                if exception.is_some() {
                    excepted_runs += 1;
                    excepted_misses += usize::from(missed);
                } else if missed {
                    misses.push(format!("{solver} {c:?} case {case}: {outcome:?}"));
                }
            }
        }
        if excepted_runs > 0 {
            let rate = excepted_misses as f64 / excepted_runs as f64;
            eprintln!("{solver}: {excepted_misses} misses in {excepted_runs} excepted problems");
            assert!(
                rate <= max_excepted_miss_rate(solver),
                "{solver}: {excepted_misses} of {excepted_runs} excepted noise-free problems missed"
            );
        }
    }
    assert!(
        misses.is_empty(),
        "{} noise-free problems not solved to < 1e-6°:\n{}",
        misses.len(),
        misses.join("\n")
    );
}

/// The miss rate measured in each solver's excepted cells, plus a margin.
fn max_excepted_miss_rate(solver: Solver) -> f64 {
    match solver {
        Solver::Dlt => MEASURED_DLT,
        Solver::Epnp => MEASURED_EPNP,
        Solver::Iepnp => MEASURED_IEPNP,
        Solver::Parallel => MEASURED_PARALLEL,
        Solver::ParallelGn | Solver::ParallelWeighted => MEASURED_PARALLEL_GN,
        Solver::Lhm => MEASURED_LHM,
        _ => 0.0,
    }
}

// Measured (2026-11-23, after the backtracking and mirror fixes) on the
// excepted problems of `noise_free_cells`, 25 cases each, and the cap set
// just above: DLT 0 of 200 (the sweep's one DLT miss, 1.1e-3° at depth/size
// 50 and 0.1% thickness, is not among these draws), EPnP 104 of 200,
// IEPnP 49 of 500, paraperspective 196 of 500, parallel-gn 23 and
// parallel-weighted 20 of 500, LHM 103 of 600.
const MEASURED_DLT: f64 = 0.01;
const MEASURED_EPNP: f64 = 0.55;
const MEASURED_IEPNP: f64 = 0.11;
const MEASURED_PARALLEL: f64 = 0.42;
const MEASURED_PARALLEL_GN: f64 = 0.05;
const MEASURED_LHM: f64 = 0.19;
