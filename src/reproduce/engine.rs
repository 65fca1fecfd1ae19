//! Running the trials.
//!
//! * **Random geometries** (experiments 1, 2 and 4): every trial draws its
//!   own points, attitude and noise, as the paper's simulation protocol does
//!   (§4.2). Trial `k` of panel stream `s` draws from `stream_rng(seed, s, k)`
//!   afresh at *every* setting of the panel, so the settings of one trial
//!   share their geometry and unit noise (common random numbers): the curve
//!   along the x axis moves only because x moves.
//! * **Fixed scenarios** (experiments 5, 6 and 7): one marker pose per
//!   setting and noise-only trials, run by [`crate::montecarlo::run`].
//!
//! Trials run in parallel with rayon and are collected in trial order; every
//! reduction is sequential, so the output is bit-identical at any thread
//! count.

use super::config::Experiment;
use super::panel::{Cell, FirstOrderLine};
use super::stats::Stat;
use crate::camera::Camera;
use crate::error_model::first_order::pose_covariance;
use crate::montecarlo::{self, MonteCarloConfig, MonteCarloError, ScenarioOutcome, Target};
use crate::noise::NoiseModel;
use crate::pnp::Solver;
use crate::pose::{paper_rotation_error_deg, rotation_error_deg, translation_error_percent, Pose};
use crate::scenario::Scenario;
use crate::synthetic::{standard_normal, stream_rng, uniform_rotation};
use nalgebra::{Vector2, Vector3};
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

/// A geodesic rotation error above this is a gross failure (degrees).
/// It is the crate's one threshold, shared with `validate`, `search` and the
/// solver conformance sweep, so a gross failure means the same in every
/// report.
pub const GROSS_ERROR_DEG: f64 = crate::montecarlo::DEFAULT_GROSS_THRESHOLD_DEG;

/// Shared settings of one run.
pub(crate) struct Context<'a> {
    /// The camera (the paper's, without distortion).
    pub camera: Camera,
    /// Seed of every stream.
    pub seed: u64,
    /// Solvers, in report order.
    pub solvers: Vec<Solver>,
    /// Progress of the running experiment.
    pub progress: Progress<'a>,
    /// Set when the caller wants the run to stop: trials still to run are
    /// skipped (and the run's results thrown away).
    pub stop: &'a AtomicBool,
}

impl Context<'_> {
    /// Whether the caller asked the run to stop.
    pub fn stopped(&self) -> bool {
        self.stop.load(Ordering::Relaxed)
    }
}

/// Progress of the running experiment, reported through a callback with
/// (experiment name, problems done, problems in total).
pub(crate) struct Progress<'a> {
    name: std::sync::Mutex<(&'static str, usize)>,
    done: AtomicUsize,
    callback: &'a (dyn Fn(&str, usize, usize) + Sync),
}

impl<'a> Progress<'a> {
    pub fn new(callback: &'a (dyn Fn(&str, usize, usize) + Sync)) -> Self {
        Self {
            name: std::sync::Mutex::new(("", 0)),
            done: AtomicUsize::new(0),
            callback,
        }
    }

    /// Starts an experiment of `total` problems.
    pub fn start(&self, name: &'static str, total: usize) {
        *self.name.lock().expect("progress lock") = (name, total);
        self.done.store(0, Ordering::Relaxed);
        (self.callback)(name, 0, total);
    }

    /// Marks `count` more problems done.
    pub fn advance(&self, count: usize) {
        let done = self.done.fetch_add(count, Ordering::Relaxed) + count;
        let (name, total) = *self.name.lock().expect("progress lock");
        (self.callback)(name, done, total);
    }
}

/// One noisy problem with known answer.
#[derive(Debug, Clone)]
pub(crate) struct Instance {
    /// Object points, mm.
    pub object: Vec<Vector3<f64>>,
    /// The true pose (object → camera).
    pub truth: Pose,
    /// Pixel noise σ.
    pub sigma_px: f64,
    /// Standard normal pairs, one per object point (scaled by σ).
    pub unit_noise: Vec<Vector2<f64>>,
}

/// `count` standard normal pairs.
pub(crate) fn unit_noise(rng: &mut ChaCha8Rng, count: usize) -> Vec<Vector2<f64>> {
    (0..count)
        .map(|_| Vector2::new(standard_normal(rng), standard_normal(rng)))
        .collect()
}

/// `count` points uniform in the camera-frame box `[-half, half]² × [near, far]`.
pub(crate) fn camera_box_points(
    rng: &mut ChaCha8Rng,
    count: usize,
    half_width_mm: f64,
    near_mm: f64,
    far_mm: f64,
) -> Vec<Vector3<f64>> {
    (0..count)
        .map(|_| {
            let x = (rng.random::<f64>() * 2.0 - 1.0) * half_width_mm;
            let y = (rng.random::<f64>() * 2.0 - 1.0) * half_width_mm;
            let z = near_mm + rng.random::<f64>() * (far_mm - near_mm);
            Vector3::new(x, y, z)
        })
        .collect()
}

/// A problem from camera-frame points: the object frame has a uniformly
/// random attitude `rotation` and its origin at the points' centroid, so
/// `object_i = Rᵀ (c_i − centroid)` and the true pose is `(R, centroid)`.
pub(crate) fn from_camera_points(
    camera_points: &[Vector3<f64>],
    rotation: nalgebra::Rotation3<f64>,
) -> (Vec<Vector3<f64>>, Pose) {
    let centroid = camera_points.iter().sum::<Vector3<f64>>() / camera_points.len() as f64;
    let object = camera_points
        .iter()
        .map(|c| rotation.inverse() * (c - centroid))
        .collect();
    (object, Pose::new(rotation, centroid))
}

/// A uniformly random attitude.
pub(crate) fn random_rotation(rng: &mut ChaCha8Rng) -> nalgebra::Rotation3<f64> {
    uniform_rotation(rng)
}

enum Outcome {
    NotApplicable,
    Failed(String),
    Pose {
        rotation_deg: f64,
        geodesic_deg: f64,
        translation_percent: f64,
    },
}

struct SettingTrial {
    outcomes: Vec<Outcome>,
    first_order: Option<FirstOrderLine>,
}

fn solve_instance(context: &Context, instance: &Instance) -> SettingTrial {
    if context.stopped() {
        // Skipped, not solved: the stopped run's results are discarded.
        return SettingTrial {
            outcomes: context
                .solvers
                .iter()
                .map(|_| Outcome::Failed("the run was stopped".into()))
                .collect(),
            first_order: None,
        };
    }
    let camera = &context.camera;
    let n = instance.object.len();
    let mut normalised = Vec::with_capacity(n);
    let mut imageable = true;
    for (p, unit) in instance.object.iter().zip(&instance.unit_noise) {
        let Some(pixel) = camera.project(&instance.truth.transform(p)) else {
            imageable = false;
            break;
        };
        match camera.pixel_to_normalised(&(pixel + unit * instance.sigma_px)) {
            Ok(m) => normalised.push(m),
            Err(_) => {
                imageable = false;
                break;
            }
        }
    }
    if !imageable {
        let outcomes = context
            .solvers
            .iter()
            .map(|_| Outcome::Failed("a point is not in front of the camera".into()))
            .collect();
        return SettingTrial {
            outcomes,
            first_order: None,
        };
    }
    let outcomes = context
        .solvers
        .iter()
        .map(|solver| {
            if n < solver.min_points() {
                return Outcome::NotApplicable;
            }
            match solver.solve_best(&instance.object, &normalised) {
                Ok(pose) => Outcome::Pose {
                    rotation_deg: paper_rotation_error_deg(
                        &instance.truth.rotation,
                        &pose.rotation,
                    ),
                    geodesic_deg: rotation_error_deg(&instance.truth.rotation, &pose.rotation),
                    translation_percent: translation_error_percent(
                        &instance.truth.translation,
                        &pose.translation,
                    ),
                },
                Err(error) => Outcome::Failed(error.to_string()),
            }
        })
        .collect();
    let first_order = (instance.sigma_px > 0.0)
        .then(|| {
            pose_covariance(
                camera,
                &instance.truth,
                &instance.object,
                &vec![instance.sigma_px; n],
            )
            .ok()
        })
        .flatten()
        .map(|c| FirstOrderLine {
            rms_rotation_deg: c.rms_rotation_deg(),
            rms_translation_percent: c.rms_translation_percent(),
        });
    SettingTrial {
        outcomes,
        first_order,
    }
}

/// Runs `trials` random trials at each of `settings` settings of one panel
/// stream. `generate(rng, setting)` builds the problem of a setting from the
/// trial's fresh stream. Returns the cells `[setting][solver]` and the
/// first-order limit per setting (RMS over the trials).
pub(crate) fn run_random(
    context: &Context,
    stream: u64,
    trials: usize,
    settings: usize,
    generate: &(dyn Fn(&mut ChaCha8Rng, usize) -> Instance + Sync),
) -> (Vec<Vec<Cell>>, Vec<Option<FirstOrderLine>>) {
    let per_trial: Vec<Vec<SettingTrial>> = (0..trials)
        .into_par_iter()
        .filter_map(|trial| {
            // After a stop the trials not yet begun are dropped unbuilt
            // (the stopped run's results are discarded).
            if context.stopped() {
                return None;
            }
            let results = (0..settings)
                .map(|setting| {
                    let mut rng = stream_rng(context.seed, stream, trial as u64);
                    solve_instance(context, &generate(&mut rng, setting))
                })
                .collect();
            context.progress.advance(settings);
            Some(results)
        })
        .collect();
    let mut cells = Vec::with_capacity(settings);
    let mut limits = Vec::with_capacity(settings);
    for setting in 0..settings {
        let row = context
            .solvers
            .iter()
            .enumerate()
            .map(|(index, &solver)| {
                let mut rotation = Vec::with_capacity(trials);
                let mut geodesic = Vec::with_capacity(trials);
                let mut translation = Vec::with_capacity(trials);
                let (mut failures, mut gross, mut applicable) = (0, 0, false);
                let mut first_error = None;
                for trial in &per_trial {
                    match &trial[setting].outcomes[index] {
                        Outcome::NotApplicable => {}
                        Outcome::Failed(message) => {
                            applicable = true;
                            failures += 1;
                            if first_error.is_none() {
                                first_error = Some(message.clone());
                            }
                        }
                        Outcome::Pose {
                            rotation_deg,
                            geodesic_deg,
                            translation_percent,
                        } => {
                            applicable = true;
                            rotation.push(*rotation_deg);
                            geodesic.push(*geodesic_deg);
                            translation.push(*translation_percent);
                            if *geodesic_deg > GROSS_ERROR_DEG {
                                gross += 1;
                            }
                        }
                    }
                }
                if !applicable {
                    return Cell::not_applicable(solver);
                }
                Cell {
                    solver,
                    applicable: true,
                    attempts: trials,
                    solver_errors: failures,
                    first_error,
                    rotation_deg: Stat::of(&mut rotation),
                    geodesic_deg: Stat::of(&mut geodesic),
                    translation_percent: Stat::of(&mut translation),
                    gross_failures: gross,
                }
            })
            .collect();
        cells.push(row);
        let predictions: Vec<FirstOrderLine> = per_trial
            .iter()
            .filter_map(|trial| trial[setting].first_order)
            .collect();
        limits.push((!predictions.is_empty()).then(|| {
            let count = predictions.len() as f64;
            let rms = |f: &dyn Fn(&FirstOrderLine) -> f64| {
                (predictions.iter().map(|p| f(p).powi(2)).sum::<f64>() / count).sqrt()
            };
            FirstOrderLine {
                rms_rotation_deg: rms(&|p| p.rms_rotation_deg),
                rms_translation_percent: rms(&|p| p.rms_translation_percent),
            }
        }));
    }
    (cells, limits)
}

/// Runs fixed scenarios of a marker through the Monte-Carlo engine with
/// isotropic noise; the scenarios' `index` fields seed their streams.
pub(crate) fn run_scenarios(
    context: &Context,
    object: &[Vector3<f64>],
    sphere_diameter_mm: f64,
    scenarios: &[Scenario],
    trials: usize,
) -> Result<Vec<ScenarioOutcome>, MonteCarloError> {
    run_scenarios_with(
        context,
        &context.solvers,
        object,
        sphere_diameter_mm,
        scenarios,
        trials,
    )
}

/// [`run_scenarios`] with `solvers` instead of the run's (the protocol's
/// σ calibration runs one solver).
pub(crate) fn run_scenarios_with(
    context: &Context,
    solvers: &[Solver],
    object: &[Vector3<f64>],
    sphere_diameter_mm: f64,
    scenarios: &[Scenario],
    trials: usize,
) -> Result<Vec<ScenarioOutcome>, MonteCarloError> {
    let sigmas = vec![None; object.len()];
    let target = Target {
        camera: &context.camera,
        object,
        sphere_diameter_mm,
        point_sigma_px: &sigmas,
    };
    let config = MonteCarloConfig {
        trials,
        seed: context.seed,
        solvers: solvers.to_vec(),
        noise: NoiseModel::default(),
        gross_threshold_deg: GROSS_ERROR_DEG,
        // The paper simulates point features: its protocol observes the
        // projected sphere centres.
        observation: crate::sphere_image::Observation::Centre,
    };
    montecarlo::run_until(
        &target,
        scenarios,
        &config,
        &|_| context.progress.advance(trials),
        context.stop,
    )
}

/// The cells and first-order limit of one scenario outcome.
pub(crate) fn scenario_cells(
    outcome: &ScenarioOutcome,
    context: &Context,
    trials: usize,
) -> (Vec<Cell>, Option<FirstOrderLine>) {
    let cells = context
        .solvers
        .iter()
        .enumerate()
        .map(|(index, &solver)| match outcome.solvers.get(index) {
            Some(result) => Cell::from_outcome(result, trials),
            // A feature behind the camera: no trials ran.
            None => Cell::not_applicable(solver),
        })
        .collect();
    (cells, outcome.first_order.map(FirstOrderLine::from))
}

/// The paper's solvers this build has, and the names it lacks, from `names`.
pub(crate) fn group(context: &Context, names: &[&str]) -> (Vec<Solver>, Vec<String>) {
    let mut found = Vec::new();
    let mut missing = Vec::new();
    for name in names {
        match find(context, name) {
            Some(solver) => found.push(solver),
            None => missing.push(name.to_string()),
        }
    }
    (found, missing)
}

/// The solver called `name`, if this build has it and it runs.
pub(crate) fn find(context: &Context, name: &str) -> Option<Solver> {
    Solver::from_name(name).filter(|s| context.solvers.contains(s))
}

/// The stream of panel `panel` of experiment `experiment`:
/// `10⁶·experiment + 10⁴·panel` (scenarios add their index within the panel).
pub(crate) fn stream(experiment: Experiment, panel: u64) -> u64 {
    1_000_000 * experiment.number() + 10_000 * panel
}
