//! Solver conformance sweep: every PnP solver on seeded problems across the
//! PnP problem space, plus six named regimes.
//!
//! ```text
//! cargo run --release --features examples --example conformance                 # full sweep + regimes
//! cargo run --release --features examples --example conformance -- --quick      # 20 problems per cell (300 by default)
//! cargo run --release --features examples --example conformance -- --regimes    # the six regimes only
//!   [--seed N] [--problems N] [--regime-problems N] [--threads N] [--out DIR]
//! ```
//!
//! Reports go to `--out` (default `reports/solvers`): `conformance.md`,
//! `conformance.csv` (one row per solver × cell), `regimes.md`,
//! `regimes.csv`, `run.json` and `heatmap-<solver>.svg`; `--regimes` writes
//! only `regimes.md`, `regimes.csv` and `run-regimes.json`.
//!
//! # Problems
//! Drawn by [`layout_opt::conformance`] (its docs give the recipe): n points
//! uniform in a box of thickness t (z side over x/y side), centred, scaled to
//! a 100 mm diameter, the centroid's pixel uniform in the 1280×720 image or
//! a fraction of the way from the principal point to a random corner, the
//! centroid at depth `depth/size × diameter`, a rotation uniform on SO(3)
//! redrawn until every point is at depth ≥ 5% of the centroid's (points may
//! leave the image: below depth/size ≈ 3 the object cannot fit in it), the
//! default camera (`Camera::default()`: fx 1301.47, fy 1300.93, cx 653,
//! cy 508) with or without the paper's distortion [-0.087355, 0.204686, 0,
//! 0, 0], Gaussian pixel noise σ on the distorted pixels, then
//! `Camera::pixel_to_normalised` as the product does. Problem `k` of a cell
//! comes from ChaCha8(seed, hash of the cell's geometry, k): the same at any
//! thread count, and shared by cells that differ only in σ or distortion.
//!
//! # Design (cells)
//! Base cell: depth/size 5, n = 10, cube (t = 1), centroid uniform in the
//! image, no distortion, σ = 0.5 px. Then
//! 1. one axis at a time from the base: depth/size 0.5–200 (1 ≈ the classic
//!    EPnP cube at depth ≈ its size), n 4–200, thickness 0 (planar), 0.001,
//!    0.01 (quasi-planar), 0.03, 0.1, 0.3, 1 (cube), off-axis (centroid on
//!    the axis, ¼, ½, ¾ of the way to a corner, at the corner), distortion
//!    on, σ 0–5 px;
//! 2. the same one-axis sweeps noise-free (σ = 0);
//! 3. a depth/size × thickness grid at n = 6, σ = 1 px (where solvers break);
//! 4. hard corners combining extremes (near + wide + distorted, far +
//!    minimal, planar + corner, n = 200 at σ = 5, ...).
//!
//! Cells equal to an earlier one are dropped.
//!
//! # Metrics (per solver × cell)
//! * gross %: rotation error > 10° (geodesic angle
//!   acos((tr(R_trueᵀR) − 1)/2)), over the problems the solver ran on;
//! * errors %: the solver returned an `Err` (a panic counts as an error and
//!   is also counted on its own);
//! * RMS/CRLB: `sqrt(mean((e_i / ℓ_i)²))` over the successful non-gross
//!   problems, e_i the rotation error and ℓ_i the problem's first-order RMS
//!   rotation limit √trace Σ_ωω, Σ = (JᵀWJ)⁻¹ from
//!   `error_model::first_order` with the cell's camera (focal lengths and
//!   distortion) and σ; shown when at least 10 problems count; the CSV adds
//!   its standard error (delta method over the squared ratios);
//! * the largest rotation error of a successful solve in σ = 0 cells, and
//!   how many exceed 1e-3°.
//!
//! A solver is "not applicable" in a cell (and not run) when n is below its
//! `min_points()` or the cell is planar (t = 0) and `needs_noncoplanar()`.
//!
//! # Regimes (300 problems each unless stated, σ = 0.5 px, no distortion)
//! 1. far field: the crate's biprism builder, arm 25 mm (50 mm across), depth
//!    1–3 m, uniform rotation, origin's pixel uniform with every point inside
//!    the image;
//! 2. classic EPnP: 6 or 10 (alternately) points uniform in the camera-frame
//!    box [−500, 500]² × [500, 1500] mm (Lepetit et al.'s [−2,2]²×[4,8]
//!    protocol scaled to a 1 m cube at depth/size ≈ 1), random rotation, the
//!    object frame at the points' centroid;
//! 3. noise-free: n uniform in 6–20, depth/size uniform in 1.6–2.9, cube,
//!    σ = 0: largest rotation error and count above 1e-3°;
//! 4. quasi-planar: 8 points in a 100 × 100 × 1 mm box, depth 300–1000 mm;
//! 5. the 7-point layout of the DLS failure report on `validate`'s default
//!    grid with tilt step 30° (depth 200–1000 × offset-x 0, 50, 100 × tilt
//!    −90..90: 105 scenarios), ⌈300/105⌉ = 3 noise draws each (315 problems).
//! 6. far field, random sets: the cell recipe above with n uniform in 6–12,
//!    depth/size uniform in 20–50 (100 mm at 2–5 m), cube, centroid uniform
//!    in the image (`conformance::far_field_cell`; the DLS far-field unit test
//!    draws its cells the same way at depth/size 20–30): where DLS once had
//!    gross failures while `sqpnp`, `opnp` and `ml` had none.

use clap::Parser;
use layout_opt::camera::Camera;
use layout_opt::conformance::{self, generate, Cell, OffAxis};
use layout_opt::montecarlo::DEFAULT_GROSS_THRESHOLD_DEG;
use layout_opt::pnp::{PnpError, Solver};
use layout_opt::pose::{rotation_error_deg, Pose};
use layout_opt::report::{significant, write_text, Table};
use layout_opt::scenario::ScenarioGrid;
use layout_opt::spread::Spread;
use layout_opt::synthetic::{
    biprism_points, project_with_noise, stream_rng, uniform_rotation, Problem,
};
use nalgebra::Vector3;
use plotters::prelude::*;
use rand::Rng;
use rayon::prelude::*;
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};
use std::time::Instant;

const DEFAULT_SEED: u64 = 20_260_301;
const PROBLEMS_PER_CELL: usize = 300;
const QUICK_PROBLEMS_PER_CELL: usize = 20;
const REGIME_PROBLEMS: usize = 300;
const REGIME_SIGMA_PX: f64 = 0.5;
const GROSS_DEG: f64 = DEFAULT_GROSS_THRESHOLD_DEG;
/// Noise-free rotation error counted as a miss, degrees.
const MISS_DEG: f64 = 1e-3;
/// What the per-cell RMS/CRLB can and cannot show, with the measurements
/// behind it (the tests named reproduce them).
const YARDSTICKS: &str = "\
## Reading RMS/CRLB against the targets

* **Sampling noise.** At 300 problems a cell's RMS/CRLB has a standard error of about 0.025 for a solver at the limit (`rms_over_crlb_se` in the CSV gives each one): a cell at 1.02–1.06 is within one or two standard errors of 1. The seven cells where `ml` read above 1.02 while `sqpnp` was within 1.1 (C014, C021, C023–C025, C029, C075, 1.021–1.058 at ±0.025–0.030) are at 0.988–1.018 (±0.011–0.014) over 1500 problems of the same cells, and a multi-start ML (Levenberg–Marquardt from every candidate of every solver and from the true pose) found no lower reprojection error on any of those 10,500 problems: `ml` reaches the global minimum, and the first-order limit, there (`cargo test --release --test it noisy::ml_is_within`).
* **`epnp-gn` near the camera.** EPnP+GN does not minimise the reprojection error: eq. 8's algebraic residual of a point is its image error times its depth, and Gauss–Newton then fits the four β of the noisy null space to the six control-point distances. Near the camera, where depths across the object differ severalfold, that estimator is well above the limit: RMS/CRLB 3.16 (C002), 3.61 (C070), 2.39 (C071), 2.40 (C072), 1.63 (C074), 1.69 (C075), 4.64 (C093). Started from the true pose's β, the same Gauss–Newton converges to the same estimates (the same RMS/CRLB to three digits in all seven cells), so this is the method's excess, not a failed search; a faithful EPnP+GN cannot be held to 1.5 there, while `ml` is at 0.97–1.20 in the same cells (`cargo test --release --test it noisy::epnp_gn_near_field`).
* **Beyond first order.** Where the median limit is above a few degrees (depth/size ≥ 50 at σ ≥ 0.5 px) every solver, `ml` included, reads well below 1: the non-gross errors are truncated at 10°, and the first-order limit no longer describes the estimator.

";

/// Fewest successful non-gross problems for an RMS/CRLB figure.
const MIN_KEPT_FOR_RATIO: usize = 10;
/// Cells whose median first-order RMS rotation limit is at most this (or
/// σ = 0) are "well posed": a gross error there is the solver's fault.
const WELL_POSED_CRLB_DEG: f64 = 1.0;
/// Random streams of the regimes (cells use hashes of their geometry).
const REGIME_STREAM: u64 = 0x5245_4749_4d45_0000;

/// The 7-point layout of the DLS failure report (mm).
const DLS_FAILURE_LAYOUT: [[f64; 3]; 7] = [
    [3.387268871538042, 0.07371804148363986, 0.3199500357012208],
    [4.276245293854925, -14.13812735584971, 43.69184846600312],
    [49.908496672256994, 4.291045054052243, 1.2822528651555234],
    [9.248040517173276, 3.4687529863686217, -48.045626789875804],
    [-26.007209122568764, -6.8215137976356965, 1.7254490897843517],
    [0.9204193282850817, 49.92727405487977, 4.79390124111792],
    [8.881325193592685, -47.357176529794266, -1.3490110977112781],
];

#[derive(Debug, Parser)]
#[command(about = "PnP solver conformance sweep")]
struct Args {
    /// Seed of every random stream.
    #[arg(long, default_value_t = DEFAULT_SEED)]
    seed: u64,
    /// A much smaller sweep (20 problems per cell).
    #[arg(long)]
    quick: bool,
    /// Run only the six named regimes.
    #[arg(long)]
    regimes: bool,
    /// Problems per sweep cell (default 300, or 20 with --quick).
    #[arg(long)]
    problems: Option<usize>,
    /// Problems per regime.
    #[arg(long, default_value_t = REGIME_PROBLEMS)]
    regime_problems: usize,
    /// Rayon threads (default: all cores). Results do not depend on it.
    #[arg(long)]
    threads: Option<usize>,
    /// Report directory.
    #[arg(long, default_value = "reports/solvers")]
    out: PathBuf,
}

/// What one solver did on one problem.
#[derive(Debug, Clone, Copy)]
enum Outcome {
    NotApplicable(&'static str),
    Solved(f64),
    Failed(&'static str),
    Panicked,
}

/// A problem ready to solve.
struct Case {
    problem: Problem,
    limit_deg: Option<f64>,
    planar: bool,
}

struct CaseResult {
    limit_deg: Option<f64>,
    outcomes: Vec<Outcome>,
}

fn error_kind(error: &PnpError) -> &'static str {
    match error {
        PnpError::TooFewPoints { .. } => "TooFewPoints",
        PnpError::MismatchedLengths { .. } => "MismatchedLengths",
        PnpError::NonFinite { .. } => "NonFinite",
        PnpError::DuplicatePoints { .. } => "DuplicatePoints",
        PnpError::Collinear => "Collinear",
        PnpError::Coplanar { .. } => "Coplanar",
        PnpError::BehindCamera { .. } => "BehindCamera",
        PnpError::PolynomialSolver { .. } => "PolynomialSolver",
        PnpError::Degenerate { .. } => "Degenerate",
        _ => "Other",
    }
}

fn not_applicable(solver: Solver, points: usize, planar: bool) -> Option<&'static str> {
    if points < solver.min_points() {
        Some("n below min_points")
    } else if planar && solver.needs_noncoplanar() {
        Some("coplanar")
    } else {
        None
    }
}

fn solve_case(case: &Case) -> CaseResult {
    let p = &case.problem;
    let outcomes = Solver::ALL
        .iter()
        .map(|&solver| {
            if let Some(reason) = not_applicable(solver, p.object.len(), case.planar) {
                return Outcome::NotApplicable(reason);
            }
            match catch_unwind(AssertUnwindSafe(|| {
                solver.solve_best(&p.object, &p.normalised)
            })) {
                Ok(Ok(pose)) => {
                    let error = rotation_error_deg(&p.truth.rotation, &pose.rotation);
                    // A non-finite pose that slipped through counts as gross.
                    Outcome::Solved(if error.is_finite() { error } else { 180.0 })
                }
                Ok(Err(error)) => Outcome::Failed(error_kind(&error)),
                Err(_) => Outcome::Panicked,
            }
        })
        .collect();
    CaseResult {
        limit_deg: case.limit_deg,
        outcomes,
    }
}

/// One solver's statistics over a set of problems.
#[derive(Debug, Clone, Default)]
struct Stats {
    not_applicable: Option<&'static str>,
    problems: usize,
    errors: usize,
    panics: usize,
    gross: usize,
    kept: usize,
    sum_sq_deg: f64,
    sum_sq_ratio: f64,
    /// Σ (e_i/ℓ_i)⁴, for the standard error of RMS/CRLB.
    sum_fourth_ratio: f64,
    ratio_count: usize,
    max_deg: Option<f64>,
    misses: usize,
    error_kinds: BTreeMap<&'static str, usize>,
}

impl Stats {
    fn add(&mut self, outcome: Outcome, limit_deg: Option<f64>) {
        match outcome {
            Outcome::NotApplicable(reason) => {
                self.not_applicable = Some(reason);
                return;
            }
            Outcome::Failed(kind) => {
                self.errors += 1;
                *self.error_kinds.entry(kind).or_default() += 1;
            }
            Outcome::Panicked => {
                self.errors += 1;
                self.panics += 1;
                *self.error_kinds.entry("panic").or_default() += 1;
            }
            Outcome::Solved(error) => {
                self.max_deg = Some(self.max_deg.map_or(error, |m| m.max(error)));
                if error > MISS_DEG {
                    self.misses += 1;
                }
                if error > GROSS_DEG {
                    self.gross += 1;
                } else {
                    self.kept += 1;
                    self.sum_sq_deg += error * error;
                    if let Some(limit) = limit_deg {
                        let sq = (error / limit).powi(2);
                        self.sum_sq_ratio += sq;
                        self.sum_fourth_ratio += sq * sq;
                        self.ratio_count += 1;
                    }
                }
            }
        }
        self.problems += 1;
    }

    fn applicable(&self) -> bool {
        self.not_applicable.is_none() && self.problems > 0
    }
    fn gross_pct(&self) -> Option<f64> {
        self.applicable()
            .then(|| 100.0 * self.gross as f64 / self.problems as f64)
    }
    fn errors_pct(&self) -> Option<f64> {
        self.applicable()
            .then(|| 100.0 * self.errors as f64 / self.problems as f64)
    }
    fn rms_deg(&self) -> Option<f64> {
        (self.kept > 0).then(|| (self.sum_sq_deg / self.kept as f64).sqrt())
    }
    fn ratio(&self) -> Option<f64> {
        (self.ratio_count >= MIN_KEPT_FOR_RATIO)
            .then(|| (self.sum_sq_ratio / self.ratio_count as f64).sqrt())
    }
    /// Standard error of [`Stats::ratio`] from the spread of the squared
    /// ratios q_i = (e_i/ℓ_i)² (delta method: SE(√q̄) = SE(q̄)/(2√q̄)).
    fn ratio_se(&self) -> Option<f64> {
        let ratio = self.ratio()?;
        let count = self.ratio_count as f64;
        let mean = self.sum_sq_ratio / count;
        let variance = (self.sum_fourth_ratio / count - mean * mean) * count / (count - 1.0);
        (ratio > 0.0).then(|| (variance.max(0.0) / count).sqrt() / (2.0 * ratio))
    }
    fn kinds(&self) -> String {
        self.error_kinds
            .iter()
            .map(|(k, v)| format!("{k}:{v}"))
            .collect::<Vec<_>>()
            .join(";")
    }
}

fn aggregate<'a>(results: impl Iterator<Item = &'a CaseResult>) -> (Vec<Stats>, Option<f64>) {
    let mut stats = vec![Stats::default(); Solver::ALL.len()];
    let mut limits = Vec::new();
    for result in results {
        limits.extend(result.limit_deg);
        for (s, &outcome) in stats.iter_mut().zip(&result.outcomes) {
            s.add(outcome, result.limit_deg);
        }
    }
    (stats, median(&mut limits))
}

fn median(values: &mut [f64]) -> Option<f64> {
    values.sort_by(f64::total_cmp);
    values.get(values.len() / 2).copied()
}

// ---------------------------------------------------------------- design

struct CellDef {
    group: String,
    cell: Cell,
}

fn label(cell: &Cell) -> String {
    format!(
        "d/s {} · n {} · t {} · {} · {}σ {}",
        cell.depth_ratio,
        cell.points,
        cell.thickness,
        cell.off_axis,
        if cell.distortion { "dist · " } else { "" },
        cell.sigma_px
    )
}

const DEPTHS: [f64; 10] = [0.5, 1.0, 2.0, 3.0, 5.0, 10.0, 20.0, 50.0, 100.0, 200.0];
const COUNTS: [usize; 11] = [4, 5, 6, 7, 8, 10, 15, 20, 50, 100, 200];
const THICKNESSES: [f64; 7] = [0.0, 0.001, 0.01, 0.03, 0.1, 0.3, 1.0];
const OFF_AXIS: [OffAxis; 6] = [
    OffAxis::TowardCorner(0.0),
    OffAxis::TowardCorner(0.25),
    OffAxis::TowardCorner(0.5),
    OffAxis::TowardCorner(0.75),
    OffAxis::TowardCorner(1.0),
    OffAxis::Uniform,
];
const SIGMAS: [f64; 6] = [0.0, 0.1, 0.5, 1.0, 2.0, 5.0];

fn design() -> Vec<CellDef> {
    let base = Cell {
        depth_ratio: 5.0,
        points: 10,
        thickness: 1.0,
        off_axis: OffAxis::Uniform,
        distortion: false,
        sigma_px: 0.5,
    };
    let mut cells: Vec<CellDef> = Vec::new();
    let mut push = |group: &str, cell: Cell| {
        if !cells.iter().any(|c| c.cell == cell) {
            cells.push(CellDef {
                group: group.to_string(),
                cell,
            });
        }
    };
    push("base", base);
    for sigma_px in [0.5, 0.0] {
        let b = Cell { sigma_px, ..base };
        let suffix = if sigma_px == 0.0 { ", σ = 0" } else { "" };
        for depth_ratio in DEPTHS {
            push(&format!("depth/size{suffix}"), Cell { depth_ratio, ..b });
        }
        for points in COUNTS {
            push(&format!("n{suffix}"), Cell { points, ..b });
        }
        for thickness in THICKNESSES {
            push(&format!("thickness{suffix}"), Cell { thickness, ..b });
        }
        for off_axis in OFF_AXIS {
            push(&format!("off-axis{suffix}"), Cell { off_axis, ..b });
        }
        for distortion in [false, true] {
            push(&format!("distortion{suffix}"), Cell { distortion, ..b });
        }
    }
    for sigma_px in SIGMAS {
        push("σ", Cell { sigma_px, ..base });
    }
    for depth_ratio in [0.5, 1.0, 2.0, 5.0, 20.0, 50.0] {
        for thickness in [0.0, 0.01, 0.1, 1.0] {
            push(
                "depth/size × thickness (n = 6, σ = 1)",
                Cell {
                    depth_ratio,
                    thickness,
                    points: 6,
                    sigma_px: 1.0,
                    ..base
                },
            );
        }
    }
    let corner = |depth_ratio, points, thickness, off_axis, distortion, sigma_px| Cell {
        depth_ratio,
        points,
        thickness,
        off_axis,
        distortion,
        sigma_px,
    };
    let at_corner = OffAxis::TowardCorner(1.0);
    let uniform = OffAxis::Uniform;
    for cell in [
        // near, wide, distorted, at the corner
        corner(0.5, 6, 1.0, at_corner, true, 1.0),
        // minimal and near, noise-free
        corner(1.0, 4, 1.0, uniform, false, 0.0),
        // minimal and far
        corner(100.0, 4, 1.0, uniform, false, 0.1),
        // far, quasi-planar, at the corner
        corner(50.0, 20, 0.01, at_corner, false, 0.5),
        // planar minimal at the corner, distorted
        corner(2.0, 4, 0.0, at_corner, true, 0.5),
        // planar, many points, near, noisy, distorted
        corner(0.5, 200, 0.0, at_corner, true, 5.0),
        // far, many points, distorted, at the corner
        corner(200.0, 200, 1.0, at_corner, true, 1.0),
        // quasi-planar minimal, noise-free
        corner(3.0, 5, 0.01, uniform, false, 0.0),
        // thin, far, corner, distorted, noise-free
        corner(50.0, 8, 0.001, at_corner, true, 0.0),
        // n = 5 near the corner at σ = 5
        corner(1.0, 5, 0.3, at_corner, true, 5.0),
        // planar and far, noise-free
        corner(200.0, 10, 0.0, uniform, false, 0.0),
        // near, noise-free, at the corner, distorted
        corner(0.5, 10, 1.0, at_corner, true, 0.0),
    ] {
        push("hard corners", cell);
    }
    cells
}

// ---------------------------------------------------------------- regimes

struct Regime {
    key: &'static str,
    name: &'static str,
    sigma_px: f64,
    cases: Vec<Case>,
}

fn case_from(problem: Problem, camera: &Camera, sigma_px: f64) -> Case {
    let limit_deg = conformance::rotation_limit_deg(camera, &problem, sigma_px);
    let planar = Spread::of(&problem.object).extents[2] == 0.0;
    Case {
        problem,
        limit_deg,
        planar,
    }
}

fn regimes(seed: u64, count: usize) -> Vec<Regime> {
    let camera = Camera::default();
    let sigma = REGIME_SIGMA_PX;
    let rng_for = |regime: u64, case: usize| stream_rng(seed, REGIME_STREAM + regime, case as u64);

    // 1. Far field: 50 mm biprism at 1–3 m, every point inside the image.
    let far: Vec<Case> = (0..count)
        .into_par_iter()
        .map(|k| {
            let mut rng = rng_for(1, k);
            loop {
                let depth = rng.random_range(1000.0..3000.0);
                let Some(problem) = conformance::place_and_observe(
                    &mut rng,
                    &camera,
                    biprism_points(25.0),
                    depth,
                    OffAxis::Uniform,
                    sigma,
                ) else {
                    continue;
                };
                if problem.pixels.iter().all(|px| camera.contains(px, 0.0)) {
                    return case_from(problem, &camera, sigma);
                }
            }
        })
        .collect();

    // 2. Classic EPnP: points uniform in a camera-frame 1 m box at depth
    // 0.5–1.5 m, object frame at their centroid with a random attitude.
    let epnp: Vec<Case> = (0..count)
        .into_par_iter()
        .map(|k| {
            let mut rng = rng_for(2, k);
            let n = if k % 2 == 0 { 6 } else { 10 };
            let camera_points: Vec<Vector3<f64>> = (0..n)
                .map(|_| {
                    Vector3::new(
                        rng.random_range(-500.0..500.0),
                        rng.random_range(-500.0..500.0),
                        rng.random_range(500.0..1500.0),
                    )
                })
                .collect();
            let centroid = camera_points.iter().sum::<Vector3<f64>>() / n as f64;
            let rotation = uniform_rotation(&mut rng);
            let object = camera_points
                .iter()
                .map(|c| rotation.inverse() * (c - centroid))
                .collect();
            let truth = Pose::new(rotation, centroid);
            let problem = project_with_noise(&mut rng, &camera, object, truth, sigma)
                .expect("every point is in front");
            case_from(problem, &camera, sigma)
        })
        .collect();

    // 3. Noise-free, n 6–20, depth/size 1.6–2.9.
    let noise_free: Vec<Case> = (0..count)
        .into_par_iter()
        .map(|k| {
            let mut rng = rng_for(3, k);
            let cell = Cell {
                depth_ratio: rng.random_range(1.6..2.9),
                points: rng.random_range(6..=20),
                thickness: 1.0,
                off_axis: OffAxis::Uniform,
                distortion: false,
                sigma_px: 0.0,
            };
            let generated = conformance::generate_with(&mut rng, &cell).expect("a problem");
            case_from(generated.problem, &camera, 0.0)
        })
        .collect();

    // 4. Quasi-planar: 8 points in a 100 × 100 × 1 mm box at 300–1000 mm.
    let quasi_planar: Vec<Case> = (0..count)
        .into_par_iter()
        .map(|k| {
            let mut rng = rng_for(4, k);
            loop {
                let mut object: Vec<Vector3<f64>> = (0..8)
                    .map(|_| {
                        Vector3::new(
                            rng.random_range(-50.0..50.0),
                            rng.random_range(-50.0..50.0),
                            rng.random_range(-0.5..0.5),
                        )
                    })
                    .collect();
                let centroid = object.iter().sum::<Vector3<f64>>() / 8.0;
                object.iter_mut().for_each(|p| *p -= centroid);
                let depth = rng.random_range(300.0..1000.0);
                if let Some(problem) = conformance::place_and_observe(
                    &mut rng,
                    &camera,
                    object,
                    depth,
                    OffAxis::Uniform,
                    sigma,
                ) {
                    return case_from(problem, &camera, sigma);
                }
            }
        })
        .collect();

    // 5. The DLS-failure 7-point layout on validate's default grid, tilt step 30°.
    let grid = ScenarioGrid::paper_protocol(30.0).scenarios();
    let draws = count.div_ceil(grid.len()).max(1);
    let layout: Vec<Vector3<f64>> = DLS_FAILURE_LAYOUT
        .iter()
        .map(|p| Vector3::from(*p))
        .collect();
    let seven: Vec<Case> = (0..grid.len() * draws)
        .into_par_iter()
        .map(|k| {
            let mut rng = rng_for(5, k);
            let scenario = &grid[k % grid.len()];
            let problem = project_with_noise(
                &mut rng,
                &camera,
                layout.clone(),
                scenario.pose(),
                scenario.sigma_px,
            )
            .expect("the grid keeps the layout in front");
            case_from(problem, &camera, scenario.sigma_px)
        })
        .collect();

    // 6. Far field, random sets: n 6–12, 100 mm at 2–5 m (depth/size 20–50).
    let far_random: Vec<Case> = (0..count)
        .into_par_iter()
        .map(|k| {
            let mut rng = rng_for(6, k);
            let cell =
                conformance::far_field_cell(&mut rng, conformance::FAR_FIELD_DEPTH_RATIO, sigma);
            let generated = conformance::generate_with(&mut rng, &cell).expect("a problem");
            case_from(generated.problem, &camera, sigma)
        })
        .collect();

    vec![
        Regime {
            key: "far-field",
            name: "1 far field: 50 mm biprism at 1–3 m",
            sigma_px: sigma,
            cases: far,
        },
        Regime {
            key: "epnp-classic",
            name: "2 classic EPnP: 6/10 points in a 1 m cube at 0.5–1.5 m",
            sigma_px: sigma,
            cases: epnp,
        },
        Regime {
            key: "noise-free",
            name: "3 noise-free: n 6–20, depth/size 1.6–2.9",
            sigma_px: 0.0,
            cases: noise_free,
        },
        Regime {
            key: "quasi-planar",
            name: "4 quasi-planar: 8 points, 100 × 100 × 1 mm",
            sigma_px: sigma,
            cases: quasi_planar,
        },
        Regime {
            key: "dls-failure-7pt",
            name: "5 7-point layout, validate grid (tilt step 30°)",
            sigma_px: sigma,
            cases: seven,
        },
        Regime {
            key: "far-field-random",
            name: "6 far field: n 6–12, 100 mm at 2–5 m",
            sigma_px: sigma,
            cases: far_random,
        },
    ]
}

// ---------------------------------------------------------------- output

fn pct(value: Option<f64>) -> String {
    significant(value, 2)
}

fn deg(value: Option<f64>) -> String {
    match value {
        Some(v) if v > 0.0 && v < 1e-3 => format!("{v:.1e}"),
        v => significant(v, 3),
    }
}

struct CellResult {
    id: String,
    def: CellDef,
    median_limit_deg: Option<f64>,
    stats: Vec<Stats>,
}

struct Header {
    command: String,
    seed: u64,
    version: &'static str,
}

impl Header {
    fn line(&self, problems: &str) -> String {
        format!(
            "Produced by `{}` (layout-opt {}), seed {}, {}.",
            self.command, self.version, self.seed, problems
        )
    }
}

fn regimes_table(regimes: &[(Regime, Vec<Stats>)]) -> Table {
    let mut header = vec!["solver".to_string()];
    for (regime, _) in regimes {
        if regime.sigma_px == 0.0 {
            header.push(format!("{} — max rot (°)", regime.name));
            header.push("misses > 1e-3°".into());
            header.push("errors".into());
        } else {
            header.push(format!("{} — gross / errors", regime.name));
            header.push("RMS/CRLB".into());
        }
    }
    let mut table = Table::new(header);
    for (index, solver) in Solver::ALL.iter().enumerate() {
        let mut row = vec![format!("`{}`", solver.name())];
        for (regime, stats) in regimes {
            let s = &stats[index];
            if !s.applicable() {
                row.push("n/a".into());
                row.push("n/a".into());
                if regime.sigma_px == 0.0 {
                    row.push("n/a".into());
                }
            } else if regime.sigma_px == 0.0 {
                row.push(deg(s.max_deg));
                row.push(s.misses.to_string());
                row.push(s.errors.to_string());
            } else {
                row.push(format!("{} / {}", s.gross, s.errors));
                row.push(significant(s.ratio(), 3));
            }
        }
        table.row(row);
    }
    table
}

fn regimes_csv(header: &Header, regimes: &[(Regime, Vec<Stats>)]) -> anyhow::Result<String> {
    let mut w = csv::Writer::from_writer(Vec::new());
    w.write_record([
        "regime",
        "regime_name",
        "solver",
        "sigma_px",
        "applicable",
        "problems",
        "gross",
        "errors",
        "panics",
        "error_kinds",
        "rms_rot_deg",
        "rms_over_crlb",
        "ratio_problems",
        "max_rot_deg",
        "misses_over_1e-3_deg",
        "seed",
        "command",
    ])?;
    for (regime, stats) in regimes {
        for (solver, s) in Solver::ALL.iter().zip(stats) {
            w.write_record([
                regime.key.to_string(),
                regime.name.to_string(),
                solver.name().to_string(),
                regime.sigma_px.to_string(),
                s.applicable().to_string(),
                s.problems.to_string(),
                s.gross.to_string(),
                s.errors.to_string(),
                s.panics.to_string(),
                s.kinds(),
                opt(s.rms_deg()),
                opt(s.ratio()),
                s.ratio_count.to_string(),
                opt(s.max_deg),
                s.misses.to_string(),
                header.seed.to_string(),
                header.command.clone(),
            ])?;
        }
    }
    Ok(String::from_utf8(w.into_inner()?)?)
}

fn opt(value: Option<f64>) -> String {
    value.map_or(String::new(), |v| format!("{v:.7e}"))
}

fn regimes_markdown(header: &Header, regimes: &[(Regime, Vec<Stats>)]) -> String {
    let counts: Vec<String> = regimes
        .iter()
        .map(|(r, _)| format!("{} {}", r.key, r.cases.len()))
        .collect();
    let mut md = String::new();
    let _ = writeln!(md, "## Regimes\n");
    let _ = writeln!(
        md,
        "{} Problems per regime: {}. σ = {REGIME_SIGMA_PX} px except regime 3 (σ = 0); default camera, no distortion. \"gross / errors\" are counts (rotation error > {GROSS_DEG}°, `Err` returned); RMS/CRLB over the successful non-gross problems. Regime 5 runs the 105 scenarios of `validate`'s default grid at tilt step 30°, several noise draws each; some of its scenarios put points outside the image (the solvers do not care).\n",
        header.line("problem counts as listed"),
        counts.join(", ")
    );
    md.push_str(&regimes_table(regimes).markdown());
    md
}

fn cells_csv(header: &Header, cells: &[CellResult]) -> anyhow::Result<String> {
    let mut w = csv::Writer::from_writer(Vec::new());
    w.write_record([
        "cell",
        "group",
        "depth_ratio",
        "points",
        "thickness",
        "off_axis",
        "distortion",
        "sigma_px",
        "median_crlb_rot_deg",
        "solver",
        "applicable",
        "not_applicable_reason",
        "problems",
        "errors",
        "errors_pct",
        "panics",
        "error_kinds",
        "gross",
        "gross_pct",
        "kept",
        "rms_rot_deg",
        "rms_over_crlb",
        "rms_over_crlb_se",
        "ratio_problems",
        "max_rot_deg",
        "misses_over_1e-3_deg",
        "seed",
        "command",
    ])?;
    for c in cells {
        let cell = &c.def.cell;
        for (solver, s) in Solver::ALL.iter().zip(&c.stats) {
            w.write_record([
                c.id.clone(),
                c.def.group.clone(),
                cell.depth_ratio.to_string(),
                cell.points.to_string(),
                cell.thickness.to_string(),
                cell.off_axis.to_string(),
                cell.distortion.to_string(),
                cell.sigma_px.to_string(),
                opt(c.median_limit_deg),
                solver.name().to_string(),
                s.applicable().to_string(),
                s.not_applicable.unwrap_or("").to_string(),
                s.problems.to_string(),
                s.errors.to_string(),
                opt(s.errors_pct()),
                s.panics.to_string(),
                s.kinds(),
                s.gross.to_string(),
                opt(s.gross_pct()),
                s.kept.to_string(),
                opt(s.rms_deg()),
                opt(s.ratio()),
                opt(s.ratio_se()),
                s.ratio_count.to_string(),
                opt(s.max_deg),
                s.misses.to_string(),
                header.seed.to_string(),
                header.command.clone(),
            ])?;
        }
    }
    Ok(String::from_utf8(w.into_inner()?)?)
}

/// The worst value of `metric` over the cells, with the cell's id.
fn worst(
    cells: &[CellResult],
    index: usize,
    metric: impl Fn(&CellResult, &Stats) -> Option<f64>,
) -> Option<(f64, String)> {
    let mut best: Option<(f64, String)> = None;
    for c in cells {
        if let Some(v) = metric(c, &c.stats[index]) {
            if best.as_ref().is_none_or(|(b, _)| v > *b) {
                best = Some((v, c.id.clone()));
            }
        }
    }
    best
}

fn with_cell(value: Option<(f64, String)>, format: impl Fn(Option<f64>) -> String) -> String {
    match value {
        Some((v, id)) => format!("{} ({id})", format(Some(v))),
        None => "—".into(),
    }
}

fn well_posed(cell: &CellResult) -> bool {
    cell.def.cell.sigma_px == 0.0
        || cell
            .median_limit_deg
            .is_some_and(|limit| limit <= WELL_POSED_CRLB_DEG)
}

fn summary_table(cells: &[CellResult]) -> Table {
    let mut table = Table::new([
        "solver",
        "cells run / n/a",
        "gross overall %",
        "worst gross % (cell)",
        "worst gross %, well-posed cells (cell)",
        "errors overall %",
        "worst errors % (cell)",
        "worst RMS/CRLB (cell)",
        "largest noise-free rot ° (cell)",
        "noise-free misses > 1e-3°",
    ]);
    for (index, solver) in Solver::ALL.iter().enumerate() {
        let run: Vec<&Stats> = cells
            .iter()
            .map(|c| &c.stats[index])
            .filter(|s| s.applicable())
            .collect();
        let problems: usize = run.iter().map(|s| s.problems).sum();
        let gross: usize = run.iter().map(|s| s.gross).sum();
        let errors: usize = run.iter().map(|s| s.errors).sum();
        let overall = |k: usize| (problems > 0).then(|| 100.0 * k as f64 / problems as f64);
        let noise_free = |c: &CellResult, s: &Stats| {
            (c.def.cell.sigma_px == 0.0 && s.applicable())
                .then_some(s.max_deg)
                .flatten()
        };
        let misses: usize = cells
            .iter()
            .filter(|c| c.def.cell.sigma_px == 0.0)
            .map(|c| c.stats[index].misses)
            .sum();
        let noise_free_problems: usize = cells
            .iter()
            .filter(|c| c.def.cell.sigma_px == 0.0)
            .map(|c| c.stats[index].problems)
            .sum();
        table.row([
            format!("`{}`", solver.name()),
            format!("{} / {}", run.len(), cells.len() - run.len()),
            pct(overall(gross)),
            with_cell(worst(cells, index, |_, s| s.gross_pct()), pct),
            with_cell(
                worst(cells, index, |c, s| {
                    well_posed(c).then(|| s.gross_pct()).flatten()
                }),
                pct,
            ),
            pct(overall(errors)),
            with_cell(worst(cells, index, |_, s| s.errors_pct()), pct),
            with_cell(worst(cells, index, |_, s| s.ratio()), |v| significant(v, 3)),
            with_cell(worst(cells, index, noise_free), deg),
            format!("{misses} / {noise_free_problems}"),
        ]);
    }
    table
}

fn per_cell_table(
    cells: &[CellResult],
    filter: impl Fn(&CellResult) -> bool,
    value: impl Fn(&Stats) -> String,
) -> Table {
    let mut header = vec!["cell".to_string(), "group".into(), "parameters".into()];
    header.extend(Solver::ALL.iter().map(|s| format!("`{}`", s.name())));
    let mut table = Table::new(header);
    for c in cells.iter().filter(|c| filter(c)) {
        let mut row = vec![c.id.clone(), c.def.group.clone(), label(&c.def.cell)];
        row.extend(c.stats.iter().map(|s| {
            if let Some(reason) = s.not_applicable {
                format!("n/a ({reason})")
            } else {
                value(s)
            }
        }));
        table.row(row);
    }
    table
}

/// Which cells a per-cell table lists.
type CellFilter = Box<dyn Fn(&CellResult) -> bool>;
/// What a per-cell table shows of a solver's statistics.
type CellValue = Box<dyn Fn(&Stats) -> String>;

fn conformance_markdown(
    header: &Header,
    per_cell: usize,
    cells: &[CellResult],
    regimes_md: &str,
) -> String {
    let mut md = String::new();
    let _ = writeln!(md, "# Solver conformance sweep\n");
    let _ = writeln!(
        md,
        "{}\n",
        header.line(&format!(
            "{per_cell} problems per cell × {} cells = {} problems, each solved by every applicable solver",
            cells.len(),
            per_cell * cells.len()
        ))
    );
    md.push_str(
        "Problems: n points uniform in a box whose z side is t × its x/y side (t = 0 planar, 1 cube), centred and scaled to a 100 mm diameter; centroid at depth `depth/size × diameter` on the ray of a pixel uniform in the 1280×720 image (`uniform`) or a fraction of the way from the principal point to a random image corner (`axis` = 0, `corner` = 1); rotation uniform on SO(3), redrawn until every point is at depth ≥ 5% of the centroid's (points may leave the image); the default camera (fx 1301.47, fy 1300.93, cx 653, cy 508), with the paper's distortion [-0.087355, 0.204686, 0, 0, 0] where the cell says `dist`; Gaussian noise σ on the distorted pixels, then the camera's undistortion to the solvers' normalised points. Cells differing only in σ or distortion share their draws.\n\n",
    );
    let _ = writeln!(
        md,
        "Metrics: **gross** = rotation error > {GROSS_DEG}° (geodesic angle acos((tr(R_trueᵀR) − 1)/2)), % of the problems the solver ran on; **errors** = the solver returned `Err` (a panic counts as an error; the CSV names the error kinds); **RMS/CRLB** = √mean((e_i/ℓ_i)²) over the successful *non-gross* problems, ℓ_i = √trace Σ_ωω of the first-order covariance Σ = (JᵀWJ)⁻¹ (`error_model::first_order`, the cell's camera and σ), shown when ≥ {MIN_KEPT_FOR_RATIO} problems count (1 = the Cramér–Rao limit; the CSV gives its standard error, `rms_over_crlb_se`, about 0.025 at 300 problems: see the yardsticks below); **well-posed** cells have a median first-order RMS rotation limit ≤ {WELL_POSED_CRLB_DEG}° (or σ = 0): elsewhere gross errors are partly the noise's doing, not the solver's; **noise-free** = largest rotation error of a successful solve in σ = 0 cells, misses = solves above {MISS_DEG}°. **n/a**: n below the solver's `min_points()`, or a planar cell (t = 0) for a solver that `needs_noncoplanar()`; not run, not counted as errors.\n"
    );
    let _ = writeln!(md, "## Summary per solver (whole sweep)\n");
    md.push_str(&summary_table(cells).markdown());
    md.push('\n');
    md.push_str(YARDSTICKS);
    md.push_str(regimes_md);
    md.push('\n');
    let _ = writeln!(md, "## Cells\n");
    let mut table = Table::new([
        "cell",
        "group",
        "depth/size",
        "n",
        "thickness",
        "off-axis",
        "distortion",
        "σ (px)",
        "median CRLB rot (°)",
    ]);
    for c in cells {
        let cell = &c.def.cell;
        table.row([
            c.id.clone(),
            c.def.group.clone(),
            cell.depth_ratio.to_string(),
            cell.points.to_string(),
            cell.thickness.to_string(),
            cell.off_axis.to_string(),
            if cell.distortion { "on" } else { "off" }.to_string(),
            cell.sigma_px.to_string(),
            deg(c.median_limit_deg),
        ]);
    }
    md.push_str(&table.markdown());
    let sections: [(&str, CellFilter, CellValue); 4] = [
        (
            "Gross % per cell",
            Box::new(|_| true),
            Box::new(|s| pct(s.gross_pct())),
        ),
        (
            "Errors % per cell",
            Box::new(|_| true),
            Box::new(|s| pct(s.errors_pct())),
        ),
        (
            "RMS/CRLB per cell (σ > 0)",
            Box::new(|c| c.def.cell.sigma_px > 0.0),
            Box::new(|s| significant(s.ratio(), 3)),
        ),
        (
            "Largest noise-free rotation error per cell (°, σ = 0)",
            Box::new(|c| c.def.cell.sigma_px == 0.0),
            Box::new(|s| deg(s.max_deg)),
        ),
    ];
    for (title, filter, value) in sections {
        let _ = writeln!(md, "\n## {title}\n");
        md.push_str(&per_cell_table(cells, filter, value).markdown());
    }
    md
}

// ---------------------------------------------------------------- heatmaps

fn blend(a: RGBColor, b: RGBColor, t: f64) -> RGBColor {
    let mix = |x: u8, y: u8| (f64::from(x) + (f64::from(y) - f64::from(x)) * t).round() as u8;
    RGBColor(mix(a.0, b.0), mix(a.1, b.1), mix(a.2, b.2))
}

/// A sequential scale safe under colour-vision deficiency (ColorBrewer's
/// YlOrBr): pale yellow at or below `good`, orange half way (log scale),
/// dark brown at or above `bad`. Lightness alone orders it, so it reads in
/// grey too; there is no red against green.
fn heat(value: f64, good: f64, bad: f64) -> RGBColor {
    const GOOD: RGBColor = RGBColor(255, 255, 212);
    const MIDDLE: RGBColor = RGBColor(254, 153, 41);
    const BAD: RGBColor = RGBColor(153, 52, 4);
    if value <= 0.0 {
        return GOOD;
    }
    let t = ((value.ln() - good.ln()) / (bad.ln() - good.ln())).clamp(0.0, 1.0);
    if t < 0.5 {
        blend(GOOD, MIDDLE, 2.0 * t)
    } else {
        blend(MIDDLE, BAD, 2.0 * t - 1.0)
    }
}

/// Every empty cell, whatever the reason, is drawn in this grey; its text
/// says why ("n/a" or "—").
const EMPTY: RGBColor = RGBColor(225, 225, 225);

fn heatmap(
    path: &Path,
    solver: Solver,
    header: &Header,
    per_cell: usize,
    cells: &[CellResult],
    index: usize,
) -> anyhow::Result<()> {
    const ROW: i32 = 16;
    const LABEL: i32 = 430;
    const COLUMN: i32 = 100;
    const TOP: i32 = 96;
    let columns = ["gross %", "errors %", "RMS/CRLB", "noise-free °"];
    let width = LABEL + COLUMN * columns.len() as i32 + 20;
    // One row per cell and one heading row per group of the design.
    let mut rows = Vec::new();
    for c in cells {
        if rows.last().map(|(group, _)| group) != Some(&Some(c.def.group.as_str())) {
            rows.push((Some(c.def.group.as_str()), None));
        }
        rows.push((Some(c.def.group.as_str()), Some(c)));
    }
    let height = TOP + ROW * rows.len() as i32 + 100;
    let root = SVGBackend::new(path, (width as u32, height as u32)).into_drawing_area();
    let draw = || -> Result<(), Box<dyn std::error::Error>> {
        root.fill(&WHITE)?;
        let font = |size: u32| ("sans-serif", size).into_font().color(&BLACK);
        root.draw(&Text::new(
            format!("{} — conformance sweep", solver.display_name()),
            (10, 8),
            font(18),
        ))?;
        root.draw(&Text::new(
            format!(
                "seed {}, {per_cell} problems per cell, {} cells; layout-opt {}",
                header.seed,
                cells.len(),
                header.version
            ),
            (10, 32),
            font(12),
        ))?;
        root.draw(&Text::new(
            format!("command: {}", header.command),
            (10, 50),
            font(12),
        ))?;
        for (k, title) in columns.iter().enumerate() {
            root.draw(&Text::new(
                title.to_string(),
                (LABEL + COLUMN * k as i32 + 6, TOP - 22),
                font(15),
            ))?;
        }
        for (row, (group, c)) in rows.iter().enumerate() {
            let y = TOP + ROW * row as i32;
            let Some(c) = c else {
                root.draw(&Rectangle::new(
                    [(0, y + ROW - 3), (width, y + ROW - 2)],
                    BLACK.filled(),
                ))?;
                root.draw(&Text::new(
                    group.unwrap_or_default().to_string(),
                    (6, y),
                    ("sans-serif", 13)
                        .into_font()
                        .style(FontStyle::Bold)
                        .color(&BLACK),
                ))?;
                continue;
            };
            root.draw(&Text::new(
                format!("{} {}", c.id, label(&c.def.cell)),
                (6, y + 1),
                font(13),
            ))?;
            let s = &c.stats[index];
            let noise_free = c.def.cell.sigma_px == 0.0;
            let values: [(Option<f64>, String, f64, f64); 4] = [
                (s.gross_pct(), pct(s.gross_pct()), 0.3, 30.0),
                (s.errors_pct(), pct(s.errors_pct()), 0.3, 30.0),
                (
                    (!noise_free).then(|| s.ratio()).flatten(),
                    if noise_free {
                        String::new()
                    } else {
                        significant(s.ratio(), 3)
                    },
                    1.1,
                    10.0,
                ),
                (
                    noise_free.then_some(s.max_deg).flatten(),
                    if noise_free {
                        deg(s.max_deg)
                    } else {
                        String::new()
                    },
                    1e-6,
                    1.0,
                ),
            ];
            for (k, (value, text, good, bad)) in values.into_iter().enumerate() {
                let x = LABEL + COLUMN * k as i32;
                let (fill, text) = if s.not_applicable.is_some() {
                    (EMPTY, "n/a".to_string())
                } else {
                    match value {
                        Some(v) => (heat(v, good, bad), text),
                        None => (EMPTY, "—".to_string()),
                    }
                };
                root.draw(&Rectangle::new(
                    [(x, y), (x + COLUMN - 2, y + ROW - 2)],
                    fill.filled(),
                ))?;
                root.draw(&Text::new(text, (x + 6, y + 1), font(13)))?;
            }
        }
        let bottom = TOP + ROW * rows.len() as i32 + 10;
        let notes = [
            "Rows are grouped (bold) by what the group varies. Row labels: d/s = centroid depth / object diameter;".to_string(),
            "n = number of points; t = thickness, the box's z side over its x/y side (0 planar, 1 cube); then where the".to_string(),
            "centroid projects (axis, a fraction of the way to a corner, corner, uniform); dist = the paper's lens distortion;".to_string(),
            "σ = pixel noise (px). Colour, log scale, pale = good, dark = bad: gross and errors % pale ≤ 0.3, orange ≈ 3,".to_string(),
            "dark ≥ 30; RMS/CRLB pale ≤ 1.1, dark ≥ 10; noise-free ° pale ≤ 1e-6, dark ≥ 1. Grey = empty: n/a, the solver".to_string(),
            "does not take the cell; —, not measured there (RMS/CRLB needs noise; the noise-free column needs none).".to_string(),
            format!("gross = rotation error > {GROSS_DEG}°, the threshold of every report (validate, search, reproduce);"),
            format!("RMS/CRLB over the successful non-gross problems, shown when at least {MIN_KEPT_FOR_RATIO} count."),
        ];
        for (k, note) in notes.iter().enumerate() {
            root.draw(&Text::new(
                note.clone(),
                (6, bottom + 16 * k as i32),
                font(11),
            ))?;
        }
        root.present()?;
        Ok(())
    };
    draw().map_err(|e| anyhow::anyhow!("cannot draw {}: {e}", path.display()))
}

// ---------------------------------------------------------------- main

fn command_line() -> String {
    let words: Vec<String> = std::env::args()
        .skip(1)
        .map(|w| if w.contains(' ') { format!("'{w}'") } else { w })
        .collect();
    let mut command = "cargo run --release --features examples --example conformance".to_string();
    if !words.is_empty() {
        command.push_str(" -- ");
        command.push_str(&words.join(" "));
    }
    command
}

fn main() -> anyhow::Result<()> {
    let args = Args::parse();
    if let Some(threads) = args.threads {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build_global()?;
    }
    // Solver panics are caught and counted; keep their messages off the terminal.
    std::panic::set_hook(Box::new(|_| {}));
    let header = Header {
        command: command_line(),
        seed: args.seed,
        version: env!("CARGO_PKG_VERSION"),
    };
    let per_cell = args.problems.unwrap_or(if args.quick {
        QUICK_PROBLEMS_PER_CELL
    } else {
        PROBLEMS_PER_CELL
    });
    let started = Instant::now();

    let mut sweep_seconds = None;
    let mut cell_results = Vec::new();
    if !args.regimes {
        let cells = design();
        eprintln!(
            "sweep: {} cells × {per_cell} problems on {} threads",
            cells.len(),
            rayon::current_num_threads()
        );
        let tasks: Vec<(usize, u64)> = (0..cells.len())
            .flat_map(|c| (0..per_cell as u64).map(move |k| (c, k)))
            .collect();
        let results: Vec<CaseResult> = tasks
            .par_iter()
            .map(|&(c, k)| {
                let cell = &cells[c].cell;
                let generated = generate(cell, args.seed, k);
                let case = case_from(generated.problem, &cell.camera(), cell.sigma_px);
                solve_case(&Case {
                    planar: cell.thickness == 0.0,
                    ..case
                })
            })
            .collect();
        for (c, def) in cells.into_iter().enumerate() {
            let (stats, median_limit_deg) =
                aggregate(results[c * per_cell..(c + 1) * per_cell].iter());
            cell_results.push(CellResult {
                id: format!("C{:03}", c + 1),
                def,
                median_limit_deg,
                stats,
            });
        }
        sweep_seconds = Some(started.elapsed().as_secs_f64());
        eprintln!("sweep: {:.1} s", sweep_seconds.unwrap_or_default());
    }

    let regime_started = Instant::now();
    let regimes: Vec<(Regime, Vec<Stats>)> = regimes(args.seed, args.regime_problems)
        .into_iter()
        .map(|regime| {
            let results: Vec<CaseResult> = regime.cases.par_iter().map(solve_case).collect();
            let (stats, _) = aggregate(results.iter());
            (regime, stats)
        })
        .collect();
    let regime_seconds = regime_started.elapsed().as_secs_f64();
    eprintln!("regimes: {regime_seconds:.1} s");

    let out = &args.out;
    std::fs::create_dir_all(out)?;
    let regimes_md = regimes_markdown(&header, &regimes);
    write_text(
        &out.join("regimes.md"),
        &format!("# Solver regimes\n\n{regimes_md}"),
    )?;
    write_text(&out.join("regimes.csv"), &regimes_csv(&header, &regimes)?)?;
    if !args.regimes {
        let md = conformance_markdown(&header, per_cell, &cell_results, &regimes_md);
        write_text(&out.join("conformance.md"), &md)?;
        write_text(
            &out.join("conformance.csv"),
            &cells_csv(&header, &cell_results)?,
        )?;
        for (index, &solver) in Solver::ALL.iter().enumerate() {
            heatmap(
                &out.join(format!("heatmap-{}.svg", solver.name())),
                solver,
                &header,
                per_cell,
                &cell_results,
                index,
            )?;
        }
        println!("## Summary per solver (whole sweep)\n");
        println!(
            "{}\n",
            header.line(&format!(
                "{per_cell} problems per cell × {} cells",
                cell_results.len()
            ))
        );
        print!("{}", summary_table(&cell_results).markdown());
        println!();
    }
    println!("{regimes_md}");
    let run = serde_json::json!({
        "command": header.command,
        "version": header.version,
        "seed": header.seed,
        "mode": if args.regimes { "regimes" } else { "sweep+regimes" },
        "quick": args.quick,
        "problems_per_cell": (!args.regimes).then_some(per_cell),
        "cells": cell_results.len(),
        "sweep_problems": per_cell * cell_results.len(),
        "regime_problems": regimes
            .iter()
            .map(|(r, _)| (r.key.to_string(), serde_json::json!(r.cases.len())))
            .collect::<serde_json::Map<_, _>>(),
        "solvers": Solver::ALL.iter().map(|s| s.name()).collect::<Vec<_>>(),
        "gross_threshold_deg": GROSS_DEG,
        "noise_free_miss_deg": MISS_DEG,
        "min_problems_for_ratio": MIN_KEPT_FOR_RATIO,
        "camera": Camera::default(),
        "distorted_camera": Camera::paper_with_distortion(),
        "rayon_threads": rayon::current_num_threads(),
        "sweep_seconds": sweep_seconds,
        "regime_seconds": regime_seconds,
        "total_seconds": started.elapsed().as_secs_f64(),
    });
    // A regimes-only run leaves the full run's record alone.
    let record = if args.regimes {
        "run-regimes.json"
    } else {
        "run.json"
    };
    write_text(&out.join(record), &serde_json::to_string_pretty(&run)?)?;
    eprintln!("wrote {}", out.display());
    Ok(())
}
