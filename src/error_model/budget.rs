//! The error budget of the chain a user runs: the pose covariance each
//! source leaves, to first order, and a Monte-Carlo check of each source
//! alone and of all together.
//!
//! The sources, each independent of the others:
//!
//! * **Image noise**: each sphere's projected centre is read with
//!   isotropic noise of the noise model's σ for its image radius
//!   ([`NoiseModel::point_sigma`]). The reading's bias is zero: `track`
//!   turns every ellipse into the sphere's projected centre, which is what
//!   the budget's images are.
//! * **The part**: the printed centres are `Xᵢ + eᵢ`, `eᵢ ~ N(0, Cᵢ)`, one
//!   part per trial, while the solver fits the nominal `Xᵢ`; `Cᵢ = σ_fab² I`
//!   for a part printed to `--fabrication-sigma`, or a characterised
//!   layout's own per-sphere covariance ([`PartError`]). To first order the
//!   pose moves by `Σᵢ Aᵢ Bᵢ eᵢ`, `Aᵢ = (JᵀWJ)⁻¹ Jᵢᵀ Wᵢ`, `Bᵢ = ∂pixel/∂Xᵢ`
//!   (as [`super::fabrication`]), so its covariance is
//!   `Σᵢ (AᵢBᵢ) Cᵢ (AᵢBᵢ)ᵀ`.
//! * **The camera**: the true intrinsics are the nominal's plus
//!   `δθ ~ N(0, diag(σ_fx², σ_fy², σ_cx², σ_cy²))`, one camera per trial,
//!   while the solver reads pixels with the nominal's. A point's pixel
//!   moves by `Kᵢ δθ`, `Kᵢ = [[x_d, 0, 1, 0], [0, y_d, 0, 1]]` (its distorted
//!   normalised coordinates), so the pose by `M δθ`, `M = Σᵢ Aᵢ Kᵢ`, with
//!   covariance `M Σ_θ Mᵀ`.
//!
//! The total is the sum of the three covariances. The Monte-Carlo check
//! draws, per trial, the noise, the part and the camera that each run asks
//! for and solves with the nominal layout and camera; trial `k` of scenario
//! `s` and source run `r` draws from
//! `stream_rng(seed + BUDGET_SEED_OFFSET + r, s, k)`, so the result does
//! not depend on the thread count.

use super::fabrication::object_point_jacobian;
use super::first_order::{pixel_jacobian, pose_information, FirstOrderError};
use crate::camera::Camera;
use crate::noise::NoiseModel;
use crate::pnp::Solver;
use crate::pose::{rotation_error_deg, Pose};
use crate::scenario::{sphere_images, visibility, Scenario};
use crate::synthetic::stream_rng;
use nalgebra::{Matrix3, SMatrix, Vector2, Vector3, Vector4};
use rand::Rng;
use rand_distr::StandardNormal;
use rayon::prelude::*;
use serde::Serialize;

/// Added to the run's seed for the budget's Monte-Carlo streams (one more
/// per source run), so that they differ from the main Monte-Carlo's.
pub const BUDGET_SEED_OFFSET: u64 = 0xb0d6_0000;

/// How far the printed part's centres are from the layout the solver fits.
#[derive(Debug, Clone, PartialEq)]
pub enum PartError {
    /// The layout is the part (no error).
    Exact,
    /// Every coordinate of every centre off by σ, mm (`--fabrication-sigma`).
    Printed(f64),
    /// Each centre's own 3×3 covariance, mm² (a characterised layout's).
    Characterised(Vec<Matrix3<f64>>),
}

impl PartError {
    /// Sphere `i`'s covariance, mm².
    fn covariance(&self, i: usize) -> Matrix3<f64> {
        match self {
            PartError::Exact => Matrix3::zeros(),
            PartError::Printed(sigma) => Matrix3::identity() * (sigma * sigma),
            PartError::Characterised(blocks) => blocks[i],
        }
    }

    /// Whether the part adds any error.
    pub fn is_exact(&self) -> bool {
        match self {
            PartError::Exact => true,
            PartError::Printed(sigma) => *sigma == 0.0,
            PartError::Characterised(blocks) => blocks.iter().all(|b| b.norm() == 0.0),
        }
    }

    /// How the report names it.
    pub fn describe(&self) -> String {
        match self {
            PartError::Exact => "none (the part is the layout)".into(),
            PartError::Printed(sigma) => format!("printed, σ {sigma} mm per coordinate"),
            PartError::Characterised(blocks) => {
                let largest = blocks
                    .iter()
                    .map(|b| b.symmetric_eigen().eigenvalues.max().max(0.0).sqrt())
                    .fold(0.0, f64::max);
                format!("characterised, each centre's own covariance (largest 1σ {largest:.4} mm)")
            }
        }
    }
}

/// 1σ of the camera's intrinsics, px (`--camera-sigma`, or an OpenCV
/// calibration's standard deviations).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct IntrinsicSigma {
    /// σ of fx, px.
    pub fx: f64,
    /// σ of fy, px.
    pub fy: f64,
    /// σ of cx, px.
    pub cx: f64,
    /// σ of cy, px.
    pub cy: f64,
}

impl IntrinsicSigma {
    fn as_vector(&self) -> Vector4<f64> {
        Vector4::new(self.fx, self.fy, self.cx, self.cy)
    }

    /// Whether every σ is zero.
    pub fn is_zero(&self) -> bool {
        self.as_vector().iter().all(|&s| s == 0.0)
    }
}

impl std::str::FromStr for IntrinsicSigma {
    type Err = String;

    /// `fx=0.5,fy=0.5,cx=0.3,cy=0.3`; a name left out is 0.
    fn from_str(text: &str) -> Result<Self, Self::Err> {
        let mut sigma = IntrinsicSigma::default();
        for item in text.split(',').map(str::trim).filter(|s| !s.is_empty()) {
            let (name, value) = item
                .split_once('=')
                .ok_or_else(|| format!("'{item}' is not NAME=PX (fx, fy, cx or cy)"))?;
            let value: f64 = value
                .trim()
                .parse()
                .map_err(|_| format!("'{value}' is not a number of pixels"))?;
            if !(value.is_finite() && value >= 0.0) {
                return Err(format!("the σ of {name} must be ≥ 0 px, got {value}"));
            }
            let slot = match name.trim() {
                "fx" => &mut sigma.fx,
                "fy" => &mut sigma.fy,
                "cx" => &mut sigma.cx,
                "cy" => &mut sigma.cy,
                other => return Err(format!("unknown intrinsic '{other}'; use fx, fy, cx, cy")),
            };
            *slot = value;
        }
        Ok(sigma)
    }
}

/// RMS rotation error of each source, and of all together, degrees.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct SourceFigures {
    /// Image noise alone.
    pub noise_deg: f64,
    /// The part alone.
    pub part_deg: f64,
    /// The camera alone.
    pub camera_deg: f64,
    /// All together.
    pub total_deg: f64,
}

/// One scenario of the budget.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct BudgetOutcome {
    /// The scenario.
    pub scenario: Scenario,
    /// First-order RMS rotation errors.
    pub first_order: SourceFigures,
    /// First-order RMS translation error of all together, mm.
    pub total_translation_mm: f64,
    /// Monte-Carlo RMS rotation errors, each source alone and all.
    pub monte_carlo: SourceFigures,
    /// Trials whose solve failed, over the four runs.
    pub failed_trials: usize,
}

/// One depth of the budget: RMS over its scenarios.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DepthRow {
    /// The depth, mm.
    pub depth_mm: f64,
    /// Scenarios at that depth.
    pub scenarios: usize,
    /// First order.
    pub first_order: SourceFigures,
    /// Monte-Carlo.
    pub monte_carlo: SourceFigures,
}

/// A budget over scenarios.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Budget {
    /// The noise model, described.
    pub noise: String,
    /// The part's error, described.
    pub part: String,
    /// The camera's intrinsic σ.
    pub camera_sigma: IntrinsicSigma,
    /// The solver of the Monte-Carlo check.
    pub solver: String,
    /// Trials per scenario and source run.
    pub trials: usize,
    /// Every visible scenario, in grid order.
    pub outcomes: Vec<BudgetOutcome>,
}

impl Budget {
    /// The RMS over the scenarios of a figure.
    fn pooled(
        outcomes: &[&BudgetOutcome],
        figure: impl Fn(&BudgetOutcome) -> SourceFigures,
    ) -> SourceFigures {
        let n = outcomes.len().max(1) as f64;
        let rms = |pick: &dyn Fn(&SourceFigures) -> f64| {
            (outcomes
                .iter()
                .map(|o| pick(&figure(o)).powi(2))
                .sum::<f64>()
                / n)
                .sqrt()
        };
        SourceFigures {
            noise_deg: rms(&|f| f.noise_deg),
            part_deg: rms(&|f| f.part_deg),
            camera_deg: rms(&|f| f.camera_deg),
            total_deg: rms(&|f| f.total_deg),
        }
    }

    /// Every scenario pooled: first order, Monte-Carlo.
    pub fn overall(&self) -> (SourceFigures, SourceFigures) {
        let all: Vec<&BudgetOutcome> = self.outcomes.iter().collect();
        (
            Self::pooled(&all, |o| o.first_order),
            Self::pooled(&all, |o| o.monte_carlo),
        )
    }

    /// What `summary.json` holds: the sources, the pooled figures and the
    /// rows per depth.
    pub fn overview(&self) -> BudgetOverview {
        let (first_order, monte_carlo) = self.overall();
        BudgetOverview {
            noise: self.noise.clone(),
            part: self.part.clone(),
            camera_sigma: self.camera_sigma,
            solver: self.solver.clone(),
            trials: self.trials,
            scenarios: self.outcomes.len(),
            first_order,
            monte_carlo,
            by_depth: self.by_depth(),
        }
    }

    /// One row per depth, nearest first.
    pub fn by_depth(&self) -> Vec<DepthRow> {
        let mut depths: Vec<f64> = self.outcomes.iter().map(|o| o.scenario.depth_mm).collect();
        depths.sort_by(f64::total_cmp);
        depths.dedup();
        depths
            .into_iter()
            .map(|depth_mm| {
                let at: Vec<&BudgetOutcome> = self
                    .outcomes
                    .iter()
                    .filter(|o| o.scenario.depth_mm == depth_mm)
                    .collect();
                DepthRow {
                    depth_mm,
                    scenarios: at.len(),
                    first_order: Self::pooled(&at, |o| o.first_order),
                    monte_carlo: Self::pooled(&at, |o| o.monte_carlo),
                }
            })
            .collect()
    }
}

/// The budget pooled, as `summary.json` holds it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct BudgetOverview {
    /// The noise model, described.
    pub noise: String,
    /// The part's error, described.
    pub part: String,
    /// The camera's intrinsic σ, px.
    pub camera_sigma: IntrinsicSigma,
    /// The Monte-Carlo check's solver.
    pub solver: String,
    /// Trials per scenario and source run.
    pub trials: usize,
    /// Visible scenarios.
    pub scenarios: usize,
    /// First order over every scenario (RMS).
    pub first_order: SourceFigures,
    /// Monte-Carlo over every scenario (RMS).
    pub monte_carlo: SourceFigures,
    /// One row per depth.
    pub by_depth: Vec<DepthRow>,
}

/// Why a budget could not be made.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum BudgetError {
    /// A Monte-Carlo check needs trials.
    #[error("an error budget's Monte-Carlo check needs at least one trial")]
    NoTrials,
    /// The part's covariances do not match the layout.
    #[error("the part has {blocks} centre covariances for {spheres} spheres")]
    MismatchedPart {
        /// Covariances given.
        blocks: usize,
        /// Spheres.
        spheres: usize,
    },
    /// The caller asked to stop.
    #[error("the error budget's Monte-Carlo check was interrupted")]
    Interrupted,
}

/// What a budget is computed for.
#[derive(Debug, Clone, Copy)]
pub struct BudgetInputs<'a> {
    /// The camera (nominal).
    pub camera: &'a Camera,
    /// The layout the solver fits, mm.
    pub object: &'a [Vector3<f64>],
    /// Each point's own σ from the layout, for the per-point noise model.
    pub layout_sigmas: &'a [Option<f64>],
    /// Sphere diameter, mm.
    pub sphere_diameter_mm: f64,
    /// The image-noise model.
    pub noise: &'a NoiseModel,
    /// The part's error.
    pub part: &'a PartError,
    /// The camera's intrinsic σ.
    pub camera_sigma: IntrinsicSigma,
    /// Trials per scenario and source run.
    pub trials: usize,
    /// The run's seed.
    pub seed: u64,
    /// The Monte-Carlo check's solver.
    pub solver: Solver,
}

/// The first-order pose covariances of one view, one per source, of
/// `(ω [rad], δt [mm])` (module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SourceCovariances {
    /// Image noise.
    pub noise: SMatrix<f64, 6, 6>,
    /// The part.
    pub part: SMatrix<f64, 6, 6>,
    /// The camera.
    pub camera: SMatrix<f64, 6, 6>,
}

impl SourceCovariances {
    /// All three together.
    pub fn total(&self) -> SMatrix<f64, 6, 6> {
        self.noise + self.part + self.camera
    }
}

/// RMS geodesic rotation of a pose covariance, degrees.
pub fn rms_rotation_deg(covariance: &SMatrix<f64, 6, 6>) -> f64 {
    (covariance[(0, 0)] + covariance[(1, 1)] + covariance[(2, 2)])
        .max(0.0)
        .sqrt()
        .to_degrees()
}

/// RMS translation of a pose covariance, mm.
pub fn rms_translation_mm(covariance: &SMatrix<f64, 6, 6>) -> f64 {
    (covariance[(3, 3)] + covariance[(4, 4)] + covariance[(5, 5)])
        .max(0.0)
        .sqrt()
}

/// `Kᵢ`: a pixel's motion per unit of (fx, fy, cx, cy).
fn intrinsic_jacobian(camera: &Camera, pose: &Pose, p: &Vector3<f64>) -> SMatrix<f64, 2, 4> {
    let distorted = camera.distort(&pose.project_normalised(p));
    SMatrix::<f64, 2, 4>::new(distorted.x, 0.0, 1.0, 0.0, 0.0, distorted.y, 0.0, 1.0)
}

/// Each source's first-order pose covariance at `pose`: per-point pixel σ
/// `sigmas`, each centre's covariance `part` (mm²), the intrinsics'
/// `camera_sigma`.
pub fn source_covariances(
    camera: &Camera,
    pose: &Pose,
    object: &[Vector3<f64>],
    sigmas: &[f64],
    part: &[Matrix3<f64>],
    camera_sigma: IntrinsicSigma,
) -> Result<SourceCovariances, FirstOrderError> {
    if part.len() != object.len() {
        return Err(FirstOrderError::MismatchedLengths {
            points: object.len(),
            sigmas: part.len(),
        });
    }
    let information = pose_information(camera, pose, object, sigmas)?;
    let cholesky = information.cholesky().ok_or(FirstOrderError::Singular)?;
    let noise = cholesky.inverse();
    let mut part_covariance = SMatrix::<f64, 6, 6>::zeros();
    let mut camera_map = SMatrix::<f64, 6, 4>::zeros();
    for ((p, &sigma), centre) in object.iter().zip(sigmas).zip(part) {
        let j = pixel_jacobian(camera, pose, p);
        // Aᵢ = (JᵀWJ)⁻¹ Jᵢᵀ Wᵢ.
        let a = cholesky.solve(&(j.transpose() / (sigma * sigma)));
        let ab = a * object_point_jacobian(camera, pose, p);
        part_covariance += ab * centre * ab.transpose();
        camera_map += a * intrinsic_jacobian(camera, pose, p);
    }
    let sigma = camera_sigma.as_vector();
    let theta = SMatrix::<f64, 4, 4>::from_diagonal(&sigma.component_mul(&sigma));
    Ok(SourceCovariances {
        noise,
        part: part_covariance,
        camera: camera_map * theta * camera_map.transpose(),
    })
}

/// Which sources a Monte-Carlo run draws.
#[derive(Debug, Clone, Copy)]
struct Draw {
    noise: bool,
    part: bool,
    camera: bool,
}

/// The four runs: each source alone, then all.
const RUNS: [Draw; 4] = [
    Draw {
        noise: true,
        part: false,
        camera: false,
    },
    Draw {
        noise: false,
        part: true,
        camera: false,
    },
    Draw {
        noise: false,
        part: false,
        camera: true,
    },
    Draw {
        noise: true,
        part: true,
        camera: true,
    },
];

/// The error budget over `scenarios` (module docs): every scenario that
/// sees every sphere clearly.
pub fn budget(
    inputs: &BudgetInputs,
    scenarios: &[Scenario],
    stop: &(dyn Fn() -> bool + Sync),
) -> Result<Budget, BudgetError> {
    if inputs.trials == 0 {
        return Err(BudgetError::NoTrials);
    }
    if let PartError::Characterised(blocks) = inputs.part {
        if blocks.len() != inputs.object.len() {
            return Err(BudgetError::MismatchedPart {
                blocks: blocks.len(),
                spheres: inputs.object.len(),
            });
        }
    }
    let outcomes: Vec<Option<BudgetOutcome>> = scenarios
        .par_iter()
        .map(|scenario| budget_scenario(inputs, scenario, stop))
        .collect::<Result<_, _>>()?;
    Ok(Budget {
        noise: inputs.noise.describe(),
        part: inputs.part.describe(),
        camera_sigma: inputs.camera_sigma,
        solver: inputs.solver.name().to_string(),
        trials: inputs.trials,
        outcomes: outcomes.into_iter().flatten().collect(),
    })
}

/// Cholesky-like factor of a (possibly singular) covariance, by its
/// eigen decomposition with negative rounding clamped.
fn square_root(covariance: &Matrix3<f64>) -> Matrix3<f64> {
    let eigen = covariance.symmetric_eigen();
    let roots = eigen.eigenvalues.map(|v| v.max(0.0).sqrt());
    eigen.eigenvectors * Matrix3::from_diagonal(&roots)
}

fn budget_scenario(
    inputs: &BudgetInputs,
    scenario: &Scenario,
    stop: &(dyn Fn() -> bool + Sync),
) -> Result<Option<BudgetOutcome>, BudgetError> {
    let truth = scenario.pose();
    let images = sphere_images(
        inputs.camera,
        &truth,
        inputs.object,
        inputs.sphere_diameter_mm,
    );
    if !visibility(&images, inputs.camera).is_visible() {
        return Ok(None);
    }
    let sigmas: Vec<f64> = images
        .iter()
        .zip(inputs.layout_sigmas)
        .map(|(image, own)| {
            let radius = image.map_or(f64::NAN, |i| i.radius_px);
            inputs.noise.point_sigma(scenario.sigma_px, *own, radius)
        })
        .collect();
    let part: Vec<Matrix3<f64>> = (0..inputs.object.len())
        .map(|i| inputs.part.covariance(i))
        .collect();
    let Ok(linear) = source_covariances(
        inputs.camera,
        &truth,
        inputs.object,
        &sigmas,
        &part,
        inputs.camera_sigma,
    ) else {
        return Ok(None);
    };
    let roots: Vec<Matrix3<f64>> = part.iter().map(square_root).collect();
    let total = linear.total();
    let mut measured = [0.0; 4];
    let mut failed = 0;
    for (run, draw) in RUNS.iter().enumerate() {
        let mut squared = 0.0;
        let mut solved = 0usize;
        for trial in 0..inputs.trials {
            if stop() {
                return Err(BudgetError::Interrupted);
            }
            let mut rng = stream_rng(
                inputs.seed.wrapping_add(BUDGET_SEED_OFFSET + run as u64),
                scenario.index as u64,
                trial as u64,
            );
            match trial_error(inputs, &truth, &sigmas, &roots, *draw, &mut rng) {
                Some(error) => {
                    squared += error * error;
                    solved += 1;
                }
                None => failed += 1,
            }
        }
        measured[run] = if solved > 0 {
            (squared / solved as f64).sqrt()
        } else {
            f64::NAN
        };
    }
    Ok(Some(BudgetOutcome {
        scenario: *scenario,
        first_order: SourceFigures {
            noise_deg: rms_rotation_deg(&linear.noise),
            part_deg: rms_rotation_deg(&linear.part),
            camera_deg: rms_rotation_deg(&linear.camera),
            total_deg: rms_rotation_deg(&total),
        },
        total_translation_mm: rms_translation_mm(&total),
        monte_carlo: SourceFigures {
            noise_deg: measured[0],
            part_deg: measured[1],
            camera_deg: measured[2],
            total_deg: measured[3],
        },
        failed_trials: failed,
    }))
}

/// One trial: the sources `draw` asks for, drawn in a fixed order (the
/// part, the camera, the noise), solved with the nominal layout and
/// camera; the rotation error in degrees, or `None` when the solve failed.
fn trial_error(
    inputs: &BudgetInputs,
    truth: &Pose,
    sigmas: &[f64],
    roots: &[Matrix3<f64>],
    draw: Draw,
    rng: &mut impl Rng,
) -> Option<f64> {
    let mut normal = || -> f64 { rng.sample(StandardNormal) };
    let printed: Vec<Vector3<f64>> = inputs
        .object
        .iter()
        .zip(roots)
        .map(|(x, root)| {
            let z = Vector3::new(normal(), normal(), normal());
            if draw.part {
                x + root * z
            } else {
                *x
            }
        })
        .collect();
    let delta = Vector4::new(normal(), normal(), normal(), normal())
        .component_mul(&inputs.camera_sigma.as_vector());
    let seen_by = if draw.camera {
        let c = inputs.camera;
        Camera::new(
            c.fx() + delta[0],
            c.fy() + delta[1],
            c.cx() + delta[2],
            c.cy() + delta[3],
            c.width(),
            c.height(),
            c.distortion(),
        )
        .ok()?
    } else {
        *inputs.camera
    };
    let mut image = Vec::with_capacity(printed.len());
    for (p, &sigma) in printed.iter().zip(sigmas) {
        let pixel = seen_by.project(&truth.transform(p))?;
        let noise = inputs.noise.draw(rng, sigma);
        let noise = if draw.noise {
            Vector2::new(noise[0], noise[1])
        } else {
            Vector2::zeros()
        };
        image.push(inputs.camera.pixel_to_normalised(&(pixel + noise)).ok()?);
    }
    let pose = inputs.solver.solve_best(inputs.object, &image).ok()?;
    Some(rotation_error_deg(&truth.rotation, &pose.rotation))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::layout::Layout;

    /// The paper's biprism and camera under isotropic noise.
    struct Fixture {
        object: Vec<Vector3<f64>>,
        own_sigmas: Vec<Option<f64>>,
        camera: Camera,
        noise: NoiseModel,
    }

    impl Fixture {
        fn new() -> Fixture {
            let object = Layout::paper_biprism().positions();
            Fixture {
                own_sigmas: vec![None; object.len()],
                object,
                camera: Camera::paper(),
                noise: NoiseModel::default(),
            }
        }

        /// Inputs with `part`, `camera_sigma` and `trials`; seed 3, `ml`.
        fn inputs<'a>(
            &'a self,
            part: &'a PartError,
            camera_sigma: IntrinsicSigma,
            trials: usize,
        ) -> BudgetInputs<'a> {
            BudgetInputs {
                camera: &self.camera,
                object: &self.object,
                layout_sigmas: &self.own_sigmas,
                sphere_diameter_mm: 10.0,
                noise: &self.noise,
                part,
                camera_sigma,
                trials,
                seed: 3,
                solver: Solver::Ml,
            }
        }
    }

    /// A view at `depth_mm` tilted `tilt_deg`, panned `pan_deg`, 20 mm off
    /// axis, with σ `sigma_px`.
    fn scenario(
        index: usize,
        depth_mm: f64,
        tilt_deg: f64,
        pan_deg: f64,
        sigma_px: f64,
    ) -> Scenario {
        Scenario {
            index,
            depth_mm,
            offset_x_mm: 20.0,
            offset_y_mm: 0.0,
            tilt_deg,
            pan_deg,
            roll_deg: 0.0,
            sigma_px,
        }
    }

    #[test]
    fn intrinsic_sigmas_parse_and_refuse_with_the_reason() {
        let sigma: IntrinsicSigma = "fx=0.5, cy=0.25".parse().unwrap();
        assert_eq!(
            sigma,
            IntrinsicSigma {
                fx: 0.5,
                fy: 0.0,
                cx: 0.0,
                cy: 0.25
            }
        );
        assert_eq!(
            "k1=0.1".parse::<IntrinsicSigma>().unwrap_err(),
            "unknown intrinsic 'k1'; use fx, fy, cx, cy"
        );
        assert_eq!(
            "fx=-1".parse::<IntrinsicSigma>().unwrap_err(),
            "the σ of fx must be ≥ 0 px, got -1"
        );
        assert!("fx".parse::<IntrinsicSigma>().is_err());
    }

    /// `Kᵢ` against central differences of the projection in the
    /// intrinsics.
    #[test]
    fn the_intrinsic_jacobian_matches_central_differences() {
        let camera = Camera::paper_with_distortion();
        let pose = Pose::new(
            nalgebra::Rotation3::from_euler_angles(0.3, -0.2, 0.1),
            Vector3::new(20.0, -10.0, 400.0),
        );
        let p = Vector3::new(30.0, 20.0, -10.0);
        let analytic = intrinsic_jacobian(&camera, &pose, &p);
        let h = 1e-4;
        let shifted = |k: usize, s: f64| {
            let mut v = [camera.fx(), camera.fy(), camera.cx(), camera.cy()];
            v[k] += s;
            Camera::new(
                v[0],
                v[1],
                v[2],
                v[3],
                camera.width(),
                camera.height(),
                camera.distortion(),
            )
            .unwrap()
            .project(&pose.transform(&p))
            .unwrap()
        };
        for k in 0..4 {
            let numeric = (shifted(k, h) - shifted(k, -h)) / (2.0 * h);
            assert!(
                (analytic.column(k) - numeric).norm() < 1e-6,
                "{k}: {analytic} vs {numeric}"
            );
        }
    }

    /// Each source alone and all together: first order within 10% of the
    /// Monte-Carlo RMS on every depth of a small grid.
    #[test]
    fn the_first_order_budget_agrees_with_monte_carlo() {
        let fixture = Fixture::new();
        let part = PartError::Printed(0.05);
        let scenarios: Vec<Scenario> =
            [(300.0, -20.0), (300.0, 20.0), (600.0, -20.0), (600.0, 20.0)]
                .iter()
                .enumerate()
                .map(|(index, &(depth_mm, tilt_deg))| {
                    scenario(index, depth_mm, tilt_deg, 15.0, 0.3)
                })
                .collect();
        let camera_sigma = IntrinsicSigma {
            fx: 2.0,
            fy: 2.0,
            cx: 1.5,
            cy: 1.5,
        };
        let inputs = fixture.inputs(&part, camera_sigma, 1500);
        let on = |threads: usize| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| budget(&inputs, &scenarios, &|| false).unwrap())
        };
        let budget = on(2);
        assert_eq!(budget, on(1), "the thread count changed the budget");
        // Some of these views overlap two spheres' discs: those are left out.
        assert!(budget.outcomes.len() >= 2, "{budget:?}");
        for row in budget.by_depth() {
            let (f, m) = (row.first_order, row.monte_carlo);
            for (name, a, b) in [
                ("noise", f.noise_deg, m.noise_deg),
                ("part", f.part_deg, m.part_deg),
                ("camera", f.camera_deg, m.camera_deg),
                ("total", f.total_deg, m.total_deg),
            ] {
                assert!(
                    a > 0.0 && (a / b - 1.0).abs() < 0.1,
                    "{} mm, {name}: first order {a}, Monte-Carlo {b}",
                    row.depth_mm
                );
            }
            let sum = (f.noise_deg.powi(2) + f.part_deg.powi(2) + f.camera_deg.powi(2)).sqrt();
            assert!((sum - f.total_deg).abs() < 1e-9 * sum);
        }
    }

    #[test]
    fn bad_inputs_and_a_stop_are_errors() {
        let fixture = Fixture::new();
        let part = PartError::Characterised(vec![Matrix3::identity() * 1e-4; 2]);
        let inputs = fixture.inputs(&part, IntrinsicSigma::default(), 2);
        let scenario = scenario(0, 500.0, 20.0, 10.0, 0.2);
        assert_eq!(
            budget(&inputs, &[scenario], &|| false)
                .unwrap_err()
                .to_string(),
            "the part has 2 centre covariances for 7 spheres"
        );
        let exact = PartError::Printed(0.1);
        let stopped = BudgetInputs {
            part: &exact,
            ..inputs
        };
        assert_eq!(
            budget(&stopped, &[scenario], &|| true).unwrap_err(),
            BudgetError::Interrupted
        );
        let none = BudgetInputs {
            trials: 0,
            ..stopped
        };
        assert_eq!(
            budget(&none, &[scenario], &|| false).unwrap_err(),
            BudgetError::NoTrials
        );
        assert!(PartError::Printed(0.0).is_exact() && PartError::Exact.is_exact());
    }
}
