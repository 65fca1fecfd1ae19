//! Sensitivity analysis of a layout (the `validate` command). Monte-Carlo runs of real solvers
//! over a scenario grid, beside the first-order (Cramér–Rao) and transfer-model
//! predictions, with visibility counted per scenario.
//!
//! Statistics pool the *visible* scenarios (every sphere in front, inside the
//! image and unoccluded): those are the images a detector would deliver.
//! Scenarios that break a visibility rule are counted and named in the report
//! and kept, with their errors, in `scenarios.csv`.
//!
//! `summary.json` holds every number of `report.md` and nothing that depends
//! on the machine (timings go to `run.json`), so the same seed gives the same
//! file at any thread count.

use crate::camera::Camera;
use crate::identifiability::{self, IdentifiabilitySettings, ScenarioIdentifiability};
use crate::layout::{Layout, LayoutError};
use crate::montecarlo::{
    self, median, MonteCarloConfig, MonteCarloError, Pooled, PoseErrorVector, ScenarioOutcome,
    Target,
};
use crate::pnp::parallel::reference_index;
use crate::report::{plots, significant, write_text, ReportError, Table};
use crate::scenario::{Scenario, ScenarioGrid, Visibility};
use serde::Serialize;
use std::fmt::Write as _;
use std::path::Path;

/// Why a validation could not run.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SensitivityError {
    /// The layout is unusable.
    #[error("invalid layout: {0}")]
    Layout(#[from] LayoutError),
    /// The Monte-Carlo configuration is unusable.
    #[error(transparent)]
    MonteCarlo(#[from] MonteCarloError),
    /// The report could not be written.
    #[error(transparent)]
    Report(#[from] ReportError),
    /// A setting is out of range.
    #[error("invalid validation settings: {0}")]
    Config(String),
}

/// Where every number came from.
#[derive(Debug, Clone, Serialize)]
pub struct Header {
    /// The command line that produced the report.
    pub command: String,
    /// layout-opt version.
    pub version: String,
    /// Seed of every noise stream.
    pub seed: u64,
    /// Trials per scenario.
    pub trials_per_scenario: usize,
    /// Solvers run on every trial.
    pub solvers: Vec<String>,
    /// The noise model.
    pub noise_model: String,
    /// Rotation error counted as a gross failure, degrees.
    pub gross_threshold_deg: f64,
    /// The camera.
    pub camera: Camera,
    /// The layout's name.
    pub layout: String,
    /// Sphere diameter, mm.
    pub sphere_diameter_mm: f64,
    /// What a sphere's image point is (`centre` or `ellipse-centre`).
    pub observation: String,
    /// The feature used as paraperspective reference (and as the transfer
    /// model's segment origin).
    pub reference_point: String,
    /// The scenario grid.
    pub grid: ScenarioGrid,
}

/// Why a scenario is not pooled, or that it is: one class per scenario, so
/// the counts add up to the grid. A scenario that breaks several rules is
/// counted under the first of behind the camera, outside the image,
/// occluded (the most severe: a sphere behind the camera has no image at
/// all, one outside the image is lost, an occluded one is seen but cannot
/// be measured cleanly).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum VisibilityClass {
    /// Every sphere in front, inside the image and unoccluded.
    Visible,
    /// Every sphere in front and inside the image, some disc overlapping a
    /// nearer one.
    Occluded,
    /// Every sphere in front, some leaving the image.
    OutsideImage,
    /// Some sphere behind the camera (no trials run).
    BehindCamera,
}

impl VisibilityClass {
    /// The class of a scenario, by the precedence above.
    pub fn of(visibility: &Visibility) -> Self {
        if !visibility.behind.is_empty() {
            Self::BehindCamera
        } else if !visibility.outside.is_empty() {
            Self::OutsideImage
        } else if !visibility.occluded.is_empty() {
            Self::Occluded
        } else {
            Self::Visible
        }
    }

    /// The class in words, as in the CSV files.
    pub fn name(self) -> &'static str {
        match self {
            Self::Visible => "visible",
            Self::Occluded => "occluded",
            Self::OutsideImage => "outside-image",
            Self::BehindCamera => "behind-camera",
        }
    }
}

/// Scenario counts by visibility: `visible + occluded + outside_image +
/// behind_camera = scenarios`, each scenario counted once by the precedence
/// of [`VisibilityClass`].
#[derive(Debug, Clone, Serialize)]
pub struct VisibilityCounts {
    /// Scenarios in the grid.
    pub scenarios: usize,
    /// Scenarios with every sphere visible (pooled in the statistics).
    pub visible: usize,
    /// Scenarios with every sphere in front and inside the image, in which
    /// some sphere's disc overlaps a nearer one.
    pub occluded: usize,
    /// Scenarios with every sphere in front, in which some sphere leaves the
    /// image (whether or not another is occluded).
    pub outside_image: usize,
    /// Scenarios in which some sphere is behind the camera (no trials run).
    pub behind_camera: usize,
    /// Fraction of scenarios that are visible.
    pub availability: f64,
    /// Scenarios with an occluded sphere, whatever their class (a superset
    /// of `occluded`); every one is listed in `occlusions.csv`.
    pub with_occlusion: usize,
    /// The first dozen scenarios of class occluded (lost to occlusion
    /// alone), described: which sphere hides which.
    pub occlusion_examples: Vec<String>,
    /// The counts at each value of every axis with more than one value.
    pub by_axis: Vec<AxisVisibility>,
}

/// Visibility counts at each value of one grid axis.
#[derive(Debug, Clone, Serialize)]
pub struct AxisVisibility {
    /// Axis name (depth, offset-x, ...).
    pub axis: String,
    /// Axis unit.
    pub unit: String,
    /// The axis values.
    pub values: Vec<f64>,
    /// Per value: visible, occluded, outside the image, behind the camera.
    pub counts: Vec<[usize; 4]>,
}

/// One solver pooled over the visible scenarios, with model agreement.
#[derive(Debug, Clone, Serialize)]
pub struct SolverRow {
    /// Pooled statistics and model agreement.
    #[serde(flatten)]
    pub pooled: Pooled,
    /// Median over scenarios of (scenario RMS rotation / its first-order prediction).
    pub median_scenario_ratio_to_first_order: Option<f64>,
    /// Median over scenarios of (scenario RMS rotation / its transfer-model prediction).
    pub median_scenario_ratio_to_transfer: Option<f64>,
}

/// Error against one grid axis, pooled over the visible scenarios at each value.
#[derive(Debug, Clone, Serialize)]
pub struct Curve {
    /// Axis name (depth, offset-x, ...).
    pub axis: String,
    /// Axis unit.
    pub unit: String,
    /// The axis values.
    pub values: Vec<f64>,
    /// Fraction of scenarios visible at each value.
    pub availability: Vec<f64>,
    /// First-order RMS rotation prediction at each value, degrees.
    pub first_order_rotation_deg: Vec<Option<f64>>,
    /// Transfer-model RMS rotation prediction at each value, degrees.
    pub transfer_rotation_deg: Vec<Option<f64>>,
    /// Per solver: measured RMS rotation and translation at each value.
    pub solvers: Vec<CurveSolver>,
}

/// One solver's line on a curve.
#[derive(Debug, Clone, Serialize)]
pub struct CurveSolver {
    /// Stable solver name.
    pub solver: String,
    /// RMS rotation error, degrees (None where no scenario is visible).
    pub rms_rotation_deg: Vec<Option<f64>>,
    /// RMS translation error, mm.
    pub rms_translation_mm: Vec<Option<f64>>,
}

/// Every number of the report.
#[derive(Debug, Clone, Serialize)]
pub struct Summary {
    /// Provenance.
    pub header: Header,
    /// Visibility counts.
    pub visibility: VisibilityCounts,
    /// Per-solver statistics over the visible scenarios.
    pub solvers: Vec<SolverRow>,
    /// Curves along every axis with more than one value.
    pub curves: Vec<Curve>,
    /// The systematic part of the error beside the random part, per axis.
    pub systematic: Systematic,
    /// How often the unlabelled solver would label the visible scenarios
    /// wrongly, predicted and measured.
    pub identifiability: IdentifiabilitySummary,
}

/// How identifiability is checked in a validation.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct IdentifiabilityCheck {
    /// A scenario is identifiable when its predicted share of correct
    /// labellings reaches this.
    pub min_correct: f64,
    /// Monte-Carlo trials of the unlabelled solver per visible scenario (0:
    /// the prediction alone).
    pub trials: usize,
}

impl Default for IdentifiabilityCheck {
    fn default() -> Self {
        IdentifiabilityCheck {
            min_correct: identifiability::DEFAULT_MIN_CORRECT,
            trials: DEFAULT_IDENTIFY_TRIALS,
        }
    }
}

/// Default Monte-Carlo trials of the unlabelled solver per visible scenario.
pub const DEFAULT_IDENTIFY_TRIALS: usize = 200;

/// Identifiability over the visible scenarios (module
/// [`crate::identifiability`]).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct IdentifiabilitySummary {
    /// The prediction model, in words.
    pub model: String,
    /// The least predicted share of correct labellings of an identifiable
    /// scenario.
    pub min_correct: f64,
    /// Monte-Carlo trials per visible scenario.
    pub trials_per_scenario: usize,
    /// Seed of the trials' noise (the validation's) and shuffle streams.
    pub seed: u64,
    /// Gate of the noise-free search for wrong labellings, in σ.
    pub prediction_gate_sigmas: f64,
    /// Per-point gate of the trials' unlabelled solver, in σ.
    pub trial_gate_sigmas: f64,
    /// Visible scenarios.
    pub scenarios: usize,
    /// Visible scenarios with a prediction.
    pub predicted: usize,
    /// Visible scenarios predicted identifiable.
    pub identifiable: usize,
    /// `identifiable / scenarios` (None without visible scenarios).
    pub identifiable_share: Option<f64>,
    /// Smallest margin of any visible scenario, px (None: every margin is
    /// above its gate).
    pub smallest_margin_px: Option<f64>,
    /// Mean predicted wrong-label probability over the visible scenarios.
    pub mean_predicted_wrong: Option<f64>,
    /// Monte-Carlo wrong-label rate over every trial of the visible
    /// scenarios.
    pub monte_carlo_wrong: Option<f64>,
    /// The part of it in which the wrong labelling fits better than the
    /// true one (what the prediction models; the rest are the solver's
    /// search missing the truth, and trials without a labelling).
    pub monte_carlo_ambiguous: Option<f64>,
    /// Trials run, wrong and failed (no labelling found), over the visible
    /// scenarios.
    pub trials: identifiability::TrialCounts,
    /// The visible scenarios that are not identifiable (first dozen),
    /// described with their margin and probabilities.
    pub worst: Vec<String>,
    /// Per axis with more than one value.
    pub curves: Vec<IdentifiabilityCurve>,
}

/// Identifiability against one grid axis, over the visible scenarios at
/// each value.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct IdentifiabilityCurve {
    /// Axis name.
    pub axis: String,
    /// Axis unit.
    pub unit: String,
    /// The axis values.
    pub values: Vec<f64>,
    /// Visible scenarios at each value.
    pub visible: Vec<usize>,
    /// Share of them predicted identifiable.
    pub identifiable_share: Vec<Option<f64>>,
    /// Smallest margin, px (None: none found within the gate, or nothing
    /// visible).
    pub smallest_margin_px: Vec<Option<f64>>,
    /// Mean predicted wrong-label probability.
    pub predicted_wrong: Vec<Option<f64>>,
    /// Monte-Carlo wrong-label rate.
    pub monte_carlo_wrong: Vec<Option<f64>>,
}

/// RMS over scenarios of a signed per-axis error, with the RMS and largest
/// of its norm.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct AxisErrors {
    /// Scenarios pooled.
    pub scenarios: usize,
    /// RMS rotation about camera x, y, z, degrees.
    pub rms_rotation_per_axis_deg: [f64; 3],
    /// RMS geodesic rotation, degrees.
    pub rms_rotation_deg: f64,
    /// Largest geodesic rotation, degrees.
    pub max_rotation_deg: f64,
    /// RMS translation along camera x, y, z, mm (None for the random part,
    /// whose first-order model reports the total only).
    pub rms_translation_per_axis_mm: Option<[f64; 3]>,
    /// RMS translation, mm.
    pub rms_translation_mm: f64,
    /// Largest translation, mm.
    pub max_translation_mm: f64,
}

impl AxisErrors {
    fn of(errors: &[PoseErrorVector]) -> Self {
        if errors.is_empty() {
            return AxisErrors::default();
        }
        let n = errors.len() as f64;
        let rms = |f: &dyn Fn(&PoseErrorVector) -> f64| {
            (errors.iter().map(|e| f(e).powi(2)).sum::<f64>() / n).sqrt()
        };
        let max = |f: &dyn Fn(&PoseErrorVector) -> f64| errors.iter().map(f).fold(0.0, f64::max);
        AxisErrors {
            scenarios: errors.len(),
            rms_rotation_per_axis_deg: std::array::from_fn(|k| rms(&|e| e.rotation_deg[k])),
            rms_rotation_deg: rms(&|e| e.rotation_norm_deg()),
            max_rotation_deg: max(&|e| e.rotation_norm_deg()),
            rms_translation_per_axis_mm: Some(std::array::from_fn(|k| {
                rms(&|e| e.translation_mm[k])
            })),
            rms_translation_mm: rms(&|e| e.translation_norm_mm()),
            max_translation_mm: max(&|e| e.translation_norm_mm()),
        }
    }
}

/// The bias with zero noise beside the random part, over the visible
/// scenarios.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct Systematic {
    /// Scenarios with an image bias computed.
    pub scenarios: usize,
    /// Largest image displacement (observation − projected centre) of any
    /// sphere in any scenario, px.
    pub max_displacement_px: f64,
    /// Median over scenarios of the largest displacement in each, px.
    pub median_displacement_px: f64,
    /// The first-order random part: RMS over scenarios of the per-axis
    /// Cramér–Rao standard deviations.
    pub first_order_random: AxisErrors,
    /// The first-order bias, `(JᵀWJ)⁻¹JᵀW b`, over the same scenarios.
    pub first_order_bias: AxisErrors,
    /// Per solver (in the order of the run): the pose error on the
    /// noise-free observations.
    pub solvers: Vec<(String, AxisErrors)>,
}

/// A finished validation: the summary and every scenario's outcome.
#[derive(Debug, Clone)]
pub struct Analysis {
    /// Pooled results.
    pub summary: Summary,
    /// Per-scenario results, in grid order.
    pub outcomes: Vec<ScenarioOutcome>,
    /// Per-scenario identifiability, in grid order (None for scenarios that
    /// are not visible).
    pub identifiability: Vec<Option<ScenarioIdentifiability>>,
}

/// Runs the Monte-Carlo validation of `layout`.
pub fn run(
    layout: &Layout,
    camera: &Camera,
    grid: &ScenarioGrid,
    config: &MonteCarloConfig,
    check: &IdentifiabilityCheck,
    command: &str,
    on_scenario_done: &(dyn Fn(usize) + Sync),
) -> Result<Analysis, SensitivityError> {
    let never = std::sync::atomic::AtomicBool::new(false);
    run_until(
        layout,
        camera,
        grid,
        config,
        check,
        command,
        on_scenario_done,
        &never,
    )
}

/// [`run`], ended early with [`MonteCarloError::Interrupted`] once `stop` is
/// set ([`montecarlo::run_until`]). `on_scenario_done` counts the
/// Monte-Carlo scenarios, then the identifiability scenarios after them
/// (twice the grid in all).
#[allow(clippy::too_many_arguments)]
pub fn run_until(
    layout: &Layout,
    camera: &Camera,
    grid: &ScenarioGrid,
    config: &MonteCarloConfig,
    check: &IdentifiabilityCheck,
    command: &str,
    on_scenario_done: &(dyn Fn(usize) + Sync),
    stop: &std::sync::atomic::AtomicBool,
) -> Result<Analysis, SensitivityError> {
    layout.validate()?;
    let object = layout.positions();
    let sigmas = layout.point_sigmas();
    let target = Target {
        camera,
        object: &object,
        sphere_diameter_mm: layout.sphere_diameter_mm,
        point_sigma_px: &sigmas,
    };
    let scenarios = grid.scenarios();
    let outcomes = montecarlo::run_until(&target, &scenarios, config, on_scenario_done, stop)?;
    let settings = IdentifiabilitySettings {
        min_correct: check.min_correct,
        trials: check.trials,
        seed: config.seed,
        observation: config.observation,
        noise: config.noise,
    };
    let visible_at: Vec<bool> = outcomes.iter().map(visible).collect();
    let identified = identifiability::run_until(
        &target,
        &scenarios,
        &settings,
        &|s| visible_at.get(s.index).copied().unwrap_or(false),
        &|done| on_scenario_done(scenarios.len() + done),
        stop,
    )
    .ok_or(MonteCarloError::Interrupted)?;
    let header = Header {
        command: command.to_string(),
        version: env!("CARGO_PKG_VERSION").to_string(),
        seed: config.seed,
        trials_per_scenario: config.trials,
        solvers: config
            .solvers
            .iter()
            .map(|s| s.name().to_string())
            .collect(),
        noise_model: config.noise.describe(),
        gross_threshold_deg: config.gross_threshold_deg,
        camera: *camera,
        layout: layout.name.clone(),
        sphere_diameter_mm: layout.sphere_diameter_mm,
        observation: config.observation.name().to_string(),
        reference_point: layout.points[reference_index(&object)].name.clone(),
        grid: grid.clone(),
    };
    let summary = Summary {
        header,
        visibility: visibility_counts(layout, grid, &outcomes),
        solvers: solver_rows(&outcomes, config.solvers.len()),
        curves: curves(grid, &outcomes, config),
        systematic: systematic(&outcomes, config),
        identifiability: identifiability_summary(grid, &outcomes, &identified, &settings),
    };
    Ok(Analysis {
        summary,
        outcomes,
        identifiability: identified,
    })
}

fn systematic(outcomes: &[ScenarioOutcome], config: &MonteCarloConfig) -> Systematic {
    let visible_outcomes: Vec<&ScenarioOutcome> = outcomes.iter().filter(|o| visible(o)).collect();
    let biased: Vec<&ScenarioOutcome> = visible_outcomes
        .iter()
        .copied()
        .filter(|o| o.bias.is_some())
        .collect();
    let mut displacements: Vec<f64> = biased
        .iter()
        .filter_map(|o| o.bias.map(|b| b.max_displacement_px))
        .collect();
    let max_displacement_px = displacements.iter().copied().fold(0.0, f64::max);
    let median_displacement_px = median(&mut displacements).unwrap_or(0.0);
    let bias: Vec<PoseErrorVector> = biased
        .iter()
        .filter_map(|o| o.bias.map(|b| b.pose))
        .collect();
    let random: Vec<[f64; 4]> = visible_outcomes
        .iter()
        .filter_map(|o| {
            let f = o.first_order?;
            let [x, y, z] = f.rms_rotation_per_axis_deg;
            Some([x, y, z, f.rms_translation_mm])
        })
        .collect();
    let first_order_random = if random.is_empty() {
        AxisErrors::default()
    } else {
        let n = random.len() as f64;
        let rms = |k: usize| (random.iter().map(|r| r[k] * r[k]).sum::<f64>() / n).sqrt();
        let norm = |r: &[f64; 4]| (r[0] * r[0] + r[1] * r[1] + r[2] * r[2]).sqrt();
        AxisErrors {
            scenarios: random.len(),
            rms_rotation_per_axis_deg: [rms(0), rms(1), rms(2)],
            rms_rotation_deg: (random.iter().map(|r| norm(r).powi(2)).sum::<f64>() / n).sqrt(),
            max_rotation_deg: random.iter().map(norm).fold(0.0, f64::max),
            rms_translation_per_axis_mm: None,
            rms_translation_mm: rms(3),
            max_translation_mm: random.iter().map(|r| r[3]).fold(0.0, f64::max),
        }
    };
    let solvers = config
        .solvers
        .iter()
        .enumerate()
        .map(|(index, solver)| {
            let errors: Vec<PoseErrorVector> = visible_outcomes
                .iter()
                .filter_map(|o| o.solvers.get(index)?.systematic)
                .collect();
            (solver.name().to_string(), AxisErrors::of(&errors))
        })
        .collect();
    Systematic {
        scenarios: biased.len(),
        max_displacement_px,
        median_displacement_px,
        first_order_random,
        first_order_bias: AxisErrors::of(&bias),
        solvers,
    }
}

/// The identifiability summary of the visible scenarios.
fn identifiability_summary(
    grid: &ScenarioGrid,
    outcomes: &[ScenarioOutcome],
    identified: &[Option<ScenarioIdentifiability>],
    settings: &IdentifiabilitySettings,
) -> IdentifiabilitySummary {
    let pairs: Vec<(&ScenarioOutcome, &ScenarioIdentifiability)> = outcomes
        .iter()
        .zip(identified)
        .filter(|(o, _)| visible(o))
        .filter_map(|(o, i)| Some((o, i.as_ref()?)))
        .collect();
    let stats = |group: &[&(&ScenarioOutcome, &ScenarioIdentifiability)]| {
        let predictions: Vec<&identifiability::Prediction> = group
            .iter()
            .filter_map(|(_, i)| i.prediction.as_ref())
            .collect();
        let identifiable = group
            .iter()
            .filter(|(_, i)| i.identifiable(settings))
            .count();
        let smallest = predictions
            .iter()
            .filter_map(|p| p.margin_px)
            .fold(None, |m: Option<f64>, v| Some(m.map_or(v, |m| m.min(v))));
        let mean_predicted = (!predictions.is_empty()).then(|| {
            predictions.iter().map(|p| p.wrong_probability).sum::<f64>() / predictions.len() as f64
        });
        let mut trials = identifiability::TrialCounts::default();
        for (_, i) in group {
            trials.trials += i.trials.trials;
            trials.wrong += i.trials.wrong;
            trials.failed += i.trials.failed;
            trials.missed += i.trials.missed;
        }
        (
            predictions.len(),
            identifiable,
            smallest,
            mean_predicted,
            trials,
        )
    };
    let all: Vec<&(&ScenarioOutcome, &ScenarioIdentifiability)> = pairs.iter().collect();
    let (predicted, identifiable, smallest_margin_px, mean_predicted_wrong, trials) = stats(&all);
    let worst = pairs
        .iter()
        .filter(|(_, i)| !i.identifiable(settings))
        .take(12)
        .map(|(o, i)| {
            let what = match &i.prediction {
                Some(p) => format!(
                    "margin {} px, predicted wrong {}, Monte-Carlo wrong {}",
                    p.margin_px.map_or("—".into(), |m| significant(Some(m), 3)),
                    significant(Some(p.wrong_probability), 3),
                    i.trials
                        .wrong_rate()
                        .map_or("—".into(), |r| significant(Some(r), 3))
                ),
                None => format!("no prediction: {}", i.error.as_deref().unwrap_or("")),
            };
            format!("{}: {what}", describe_scenario(&o.scenario))
        })
        .collect();
    let curves = grid
        .named_ranges()
        .iter()
        .filter(|(_, range)| range.values.len() > 1)
        .map(|(axis, range)| {
            let groups: Vec<Vec<&(&ScenarioOutcome, &ScenarioIdentifiability)>> = range
                .values
                .iter()
                .map(|&value| {
                    pairs
                        .iter()
                        .filter(|(o, _)| axis_value(&o.scenario, axis) == value)
                        .collect()
                })
                .collect();
            let per_value: Vec<_> = groups.iter().map(|g| (g.len(), stats(g))).collect();
            IdentifiabilityCurve {
                axis: axis.to_string(),
                unit: axis_unit(axis).to_string(),
                values: range.values.clone(),
                visible: per_value.iter().map(|(n, _)| *n).collect(),
                identifiable_share: per_value
                    .iter()
                    .map(|(n, s)| (*n > 0).then(|| s.1 as f64 / *n as f64))
                    .collect(),
                smallest_margin_px: per_value.iter().map(|(_, s)| s.2).collect(),
                predicted_wrong: per_value.iter().map(|(_, s)| s.3).collect(),
                monte_carlo_wrong: per_value.iter().map(|(_, s)| s.4.wrong_rate()).collect(),
            }
        })
        .collect();
    IdentifiabilitySummary {
        model: "P(wrong) = Φ(−E[D]/√Var[D]) for the best wrong consistent labelling of the noise-free view (D = ‖r‖² + 2rᵀe + eᵀ(P₁ − P₂)e, first order)".into(),
        min_correct: settings.min_correct,
        trials_per_scenario: settings.trials,
        seed: settings.seed,
        prediction_gate_sigmas: identifiability::PREDICTION_GATE_SIGMAS,
        trial_gate_sigmas: identifiability::TRIAL_GATE_SIGMAS,
        scenarios: pairs.len(),
        predicted,
        identifiable,
        identifiable_share: (!pairs.is_empty()).then(|| identifiable as f64 / pairs.len() as f64),
        smallest_margin_px,
        mean_predicted_wrong,
        monte_carlo_wrong: trials.wrong_rate(),
        monte_carlo_ambiguous: trials.ambiguous_rate(),
        trials,
        worst,
        curves,
    }
}

/// Scenarios of the timed calibration run behind [`estimate_seconds`].
pub const CALIBRATION_SCENARIOS: usize = 8;
/// Trials per scenario of that run.
pub const CALIBRATION_TRIALS: usize = 4;
/// Shortest calibration run that is trusted, seconds; a shorter one is
/// repeated on more scenarios.
pub const CALIBRATION_MIN_SECONDS: f64 = 0.05;

/// A run-time estimate and where it came from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RunEstimate {
    /// Estimated wall-clock seconds of the full run.
    pub seconds: f64,
    /// Scenarios of the calibration run.
    pub calibration_scenarios: usize,
    /// Trials per scenario of the calibration run.
    pub calibration_trials: usize,
    /// Wall-clock seconds of the calibration run.
    pub calibration_seconds: f64,
}

/// Estimates the wall-clock time of [`run`] from a short timed run of the
/// same solvers on [`CALIBRATION_SCENARIOS`] scenarios spread evenly over
/// the grid (so visible and hidden ones in their proportions) at
/// [`CALIBRATION_TRIALS`] trials (four times the scenarios, again, while
/// the run takes less than [`CALIBRATION_MIN_SECONDS`]), scaled linearly to
/// the whole grid and trial count. The calibration uses its own noise streams' results only
/// for timing; the run's results do not depend on it.
pub fn estimate_seconds(
    layout: &Layout,
    camera: &Camera,
    grid: &ScenarioGrid,
    config: &MonteCarloConfig,
) -> Result<RunEstimate, SensitivityError> {
    layout.validate()?;
    let object = layout.positions();
    let sigmas = layout.point_sigmas();
    let target = Target {
        camera,
        object: &object,
        sphere_diameter_mm: layout.sphere_diameter_mm,
        point_sigma_px: &sigmas,
    };
    let scenarios = grid.scenarios();
    let trials = config.trials.min(CALIBRATION_TRIALS);
    let calibration = MonteCarloConfig {
        trials,
        ..config.clone()
    };
    // Start the worker threads before timing anything.
    rayon::broadcast(|_| ());
    let mut wanted = CALIBRATION_SCENARIOS;
    let (sample_len, calibration_seconds) = loop {
        let stride = scenarios.len().div_ceil(wanted).max(1);
        let sample: Vec<Scenario> = scenarios.iter().step_by(stride).copied().collect();
        let started = std::time::Instant::now();
        montecarlo::run(&target, &sample, &calibration, &|_| {})?;
        let seconds = started.elapsed().as_secs_f64();
        // A run too short to time well (fixed costs dominate) is repeated
        // on four times the scenarios, up to the whole grid.
        if seconds >= CALIBRATION_MIN_SECONDS || sample.len() >= scenarios.len() {
            break (sample.len(), seconds);
        }
        wanted *= 4;
    };
    let scale =
        (scenarios.len() as f64 / sample_len as f64) * (config.trials as f64 / trials as f64);
    Ok(RunEstimate {
        seconds: calibration_seconds * scale,
        calibration_scenarios: sample_len,
        calibration_trials: trials,
        calibration_seconds,
    })
}

fn visible(outcome: &ScenarioOutcome) -> bool {
    outcome.visibility.is_visible()
}

fn describe_scenario(s: &Scenario) -> String {
    format!(
        "depth {} mm, offset ({}, {}) mm, tilt {}°, pan {}°, roll {}°, σ {} px",
        s.depth_mm, s.offset_x_mm, s.offset_y_mm, s.tilt_deg, s.pan_deg, s.roll_deg, s.sigma_px
    )
}

fn class_index(class: VisibilityClass) -> usize {
    match class {
        VisibilityClass::Visible => 0,
        VisibilityClass::Occluded => 1,
        VisibilityClass::OutsideImage => 2,
        VisibilityClass::BehindCamera => 3,
    }
}

fn count_classes<'a>(outcomes: impl Iterator<Item = &'a ScenarioOutcome>) -> [usize; 4] {
    let mut counts = [0; 4];
    for o in outcomes {
        counts[class_index(VisibilityClass::of(&o.visibility))] += 1;
    }
    counts
}

fn occluded_pairs(layout: &Layout, outcome: &ScenarioOutcome) -> String {
    outcome
        .visibility
        .occluded
        .iter()
        .map(|&(hidden, by)| {
            format!(
                "{} behind {}",
                layout.points[hidden].name, layout.points[by].name
            )
        })
        .collect::<Vec<_>>()
        .join(", ")
}

fn visibility_counts(
    layout: &Layout,
    grid: &ScenarioGrid,
    outcomes: &[ScenarioOutcome],
) -> VisibilityCounts {
    let with_occlusion: Vec<&ScenarioOutcome> = outcomes
        .iter()
        .filter(|o| !o.visibility.occluded.is_empty())
        .collect();
    let occlusion_examples = with_occlusion
        .iter()
        .filter(|o| VisibilityClass::of(&o.visibility) == VisibilityClass::Occluded)
        .take(12)
        .map(|o| {
            format!(
                "{}: {}",
                describe_scenario(&o.scenario),
                occluded_pairs(layout, o)
            )
        })
        .collect();
    let by_axis = grid
        .named_ranges()
        .iter()
        .filter(|(_, range)| range.values.len() > 1)
        .map(|(axis, range)| AxisVisibility {
            axis: axis.to_string(),
            unit: axis_unit(axis).to_string(),
            values: range.values.clone(),
            counts: range
                .values
                .iter()
                .map(|&value| {
                    count_classes(
                        outcomes
                            .iter()
                            .filter(|o| axis_value(&o.scenario, axis) == value),
                    )
                })
                .collect(),
        })
        .collect();
    let [visible, occluded, outside_image, behind_camera] = count_classes(outcomes.iter());
    VisibilityCounts {
        scenarios: outcomes.len(),
        visible,
        occluded,
        outside_image,
        behind_camera,
        availability: visible as f64 / outcomes.len().max(1) as f64,
        with_occlusion: with_occlusion.len(),
        occlusion_examples,
        by_axis,
    }
}

/// Every scenario with an occluded sphere, whatever its class: where it is
/// and which sphere hides which.
fn occlusion_table(layout: &Layout, validation: &Analysis) -> Table {
    let mut table = Table::new([
        "scenario",
        "depth_mm",
        "offset_x_mm",
        "offset_y_mm",
        "tilt_deg",
        "pan_deg",
        "roll_deg",
        "sigma_px",
        "class",
        "occluded",
    ]);
    for o in validation
        .outcomes
        .iter()
        .filter(|o| !o.visibility.occluded.is_empty())
    {
        let s = &o.scenario;
        table.row([
            s.index.to_string(),
            s.depth_mm.to_string(),
            s.offset_x_mm.to_string(),
            s.offset_y_mm.to_string(),
            s.tilt_deg.to_string(),
            s.pan_deg.to_string(),
            s.roll_deg.to_string(),
            s.sigma_px.to_string(),
            VisibilityClass::of(&o.visibility).name().to_string(),
            occluded_pairs(layout, o),
        ]);
    }
    table
}

fn solver_rows(outcomes: &[ScenarioOutcome], solver_count: usize) -> Vec<SolverRow> {
    (0..solver_count)
        .filter_map(|index| {
            let pooled = montecarlo::pool(outcomes.iter().filter(|o| visible(o)), index)?;
            let scenario_ratios = |model: &dyn Fn(&ScenarioOutcome) -> Option<f64>| {
                let mut ratios: Vec<f64> = outcomes
                    .iter()
                    .filter(|o| visible(o))
                    .filter_map(|o| {
                        let predicted = model(o).filter(|p| p.is_finite() && *p > 0.0)?;
                        let measured = o.solvers.get(index)?.rotation_deg;
                        (measured.count > 0).then(|| measured.rms / predicted)
                    })
                    .collect();
                median(&mut ratios)
            };
            Some(SolverRow {
                median_scenario_ratio_to_first_order: scenario_ratios(&|o| {
                    o.first_order.map(|f| f.rms_rotation_deg)
                }),
                median_scenario_ratio_to_transfer: scenario_ratios(&|o| {
                    o.transfer.and_then(|t| t.rms_rotation_deg)
                }),
                pooled,
            })
        })
        .collect()
}

fn axis_value(s: &Scenario, axis: &str) -> f64 {
    match axis {
        "depth" => s.depth_mm,
        "offset-x" => s.offset_x_mm,
        "offset-y" => s.offset_y_mm,
        "tilt" => s.tilt_deg,
        "pan" => s.pan_deg,
        "roll" => s.roll_deg,
        _ => s.sigma_px,
    }
}

fn axis_unit(axis: &str) -> &'static str {
    match axis {
        "depth" | "offset-x" | "offset-y" => "mm",
        "noise" => "px",
        _ => "deg",
    }
}

fn curves(
    grid: &ScenarioGrid,
    outcomes: &[ScenarioOutcome],
    config: &MonteCarloConfig,
) -> Vec<Curve> {
    grid.named_ranges()
        .iter()
        .filter(|(_, range)| range.values.len() > 1)
        .map(|(axis, range)| {
            let groups: Vec<Vec<&ScenarioOutcome>> = range
                .values
                .iter()
                .map(|&value| {
                    outcomes
                        .iter()
                        .filter(|o| axis_value(&o.scenario, axis) == value)
                        .collect()
                })
                .collect();
            let pooled: Vec<Vec<Option<Pooled>>> = groups
                .iter()
                .map(|group| {
                    (0..config.solvers.len())
                        .map(|index| {
                            montecarlo::pool(group.iter().copied().filter(|o| visible(o)), index)
                        })
                        .collect()
                })
                .collect();
            let model = |f: &dyn Fn(&ScenarioOutcome) -> Option<f64>| -> Vec<Option<f64>> {
                groups
                    .iter()
                    .map(|group| {
                        let values: Vec<f64> = group
                            .iter()
                            .filter(|o| visible(o))
                            .filter_map(|o| f(o))
                            .collect();
                        (!values.is_empty()).then(|| {
                            (values.iter().map(|v| v * v).sum::<f64>() / values.len() as f64).sqrt()
                        })
                    })
                    .collect()
            };
            Curve {
                axis: axis.to_string(),
                unit: axis_unit(axis).to_string(),
                values: range.values.clone(),
                availability: groups
                    .iter()
                    .map(|g| g.iter().filter(|o| visible(o)).count() as f64 / g.len().max(1) as f64)
                    .collect(),
                first_order_rotation_deg: model(&|o| o.first_order.map(|f| f.rms_rotation_deg)),
                transfer_rotation_deg: model(&|o| o.transfer.and_then(|t| t.rms_rotation_deg)),
                solvers: config
                    .solvers
                    .iter()
                    .enumerate()
                    .map(|(index, solver)| CurveSolver {
                        solver: solver.name().to_string(),
                        rms_rotation_deg: pooled
                            .iter()
                            .map(|p| p[index].as_ref().map(|p| p.rms_rotation_deg))
                            .collect(),
                        rms_translation_mm: pooled
                            .iter()
                            .map(|p| p[index].as_ref().map(|p| p.rms_translation_mm))
                            .collect(),
                    })
                    .collect(),
            }
        })
        .collect()
}

/// Writes `report.md`, `summary.json`, `scenarios.csv`, one CSV and SVG per
/// curve, `predicted_vs_measured.svg` and `marker_views.svg` into `dir`.
pub fn write_report(
    dir: &Path,
    layout: &Layout,
    validation: &Analysis,
) -> Result<(), SensitivityError> {
    std::fs::create_dir_all(dir).map_err(|e| ReportError::write(dir, e))?;
    let summary = &validation.summary;
    let json = serde_json::to_string_pretty(summary)
        .map_err(|e| ReportError::write(&dir.join("summary.json"), e))?;
    write_text(&dir.join("summary.json"), &(json + "\n"))?;
    let scenarios_csv = scenario_table(layout, validation)
        .csv()
        .map_err(|e| ReportError::write(&dir.join("scenarios.csv"), e))?;
    write_text(&dir.join("scenarios.csv"), &scenarios_csv)?;
    let occlusions_csv = occlusion_table(layout, validation)
        .csv()
        .map_err(|e| ReportError::write(&dir.join("occlusions.csv"), e))?;
    write_text(&dir.join("occlusions.csv"), &occlusions_csv)?;
    for curve in &summary.curves {
        write_curve(dir, curve)?;
    }
    for curve in &summary.identifiability.curves {
        write_identifiability_curve(dir, curve)?;
    }
    let scatter: Vec<(String, Vec<(f64, f64)>)> = summary
        .solvers
        .iter()
        .enumerate()
        .map(|(index, row)| {
            let points = validation
                .outcomes
                .iter()
                .filter(|o| visible(o))
                .filter_map(|o| {
                    Some((
                        o.first_order?.rms_rotation_deg,
                        o.solvers.get(index)?.rotation_deg.rms,
                    ))
                })
                .collect();
            (row.pooled.solver.name().to_string(), points)
        })
        .collect();
    plots::predicted_vs_measured(
        &dir.join("predicted_vs_measured.svg"),
        "Per-scenario RMS rotation error: first-order prediction vs Monte-Carlo",
        &scatter,
    )?;
    let named: Vec<(String, nalgebra::Vector3<f64>)> = layout
        .points
        .iter()
        .map(|p| (p.name.clone(), p.position))
        .collect();
    plots::orthographic_views(
        &dir.join("marker_views.svg"),
        &format!(
            "{}: three views, spheres to scale ({} mm)",
            layout.name, layout.sphere_diameter_mm
        ),
        &named,
        layout.sphere_diameter_mm,
    )?;
    write_text(&dir.join("report.md"), &markdown(summary))?;
    Ok(())
}

fn write_curve(dir: &Path, curve: &Curve) -> Result<(), SensitivityError> {
    let mut table = Table::new(
        [
            format!("{} ({})", curve.axis, curve.unit),
            "availability".into(),
            "first-order RMS rot (deg)".into(),
            "transfer RMS rot (deg)".into(),
        ]
        .into_iter()
        .chain(curve.solvers.iter().flat_map(|s| {
            [
                format!("{} RMS rot (deg)", s.solver),
                format!("{} RMS trans (mm)", s.solver),
            ]
        })),
    );
    for (k, value) in curve.values.iter().enumerate() {
        let cell = |v: Option<f64>| v.map_or(String::new(), |v| format!("{v:.6e}"));
        table.row(
            [
                value.to_string(),
                format!("{:.4}", curve.availability[k]),
                cell(curve.first_order_rotation_deg[k]),
                cell(curve.transfer_rotation_deg[k]),
            ]
            .into_iter()
            .chain(
                curve
                    .solvers
                    .iter()
                    .flat_map(|s| [cell(s.rms_rotation_deg[k]), cell(s.rms_translation_mm[k])]),
            ),
        );
    }
    let path = dir.join(format!("error_vs_{}.csv", curve.axis));
    write_text(
        &path,
        &table.csv().map_err(|e| ReportError::write(&path, e))?,
    )?;
    let xy = |values: &[Option<f64>]| -> Vec<(f64, f64)> {
        curve
            .values
            .iter()
            .zip(values)
            .filter_map(|(&x, y)| y.map(|y| (x, y)))
            .collect()
    };
    let mut series: Vec<plots::Series> = curve
        .solvers
        .iter()
        .map(|s| plots::Series {
            name: s.solver.clone(),
            points: xy(&s.rms_rotation_deg),
            dashed: false,
        })
        .collect();
    series.push(plots::Series {
        name: "first-order limit".into(),
        points: xy(&curve.first_order_rotation_deg),
        dashed: true,
    });
    series.push(plots::Series {
        name: "transfer model".into(),
        points: xy(&curve.transfer_rotation_deg),
        dashed: true,
    });
    let availability = plots::Availability {
        points: curve
            .values
            .iter()
            .copied()
            .zip(curve.availability.iter().copied())
            .collect(),
        axis: curve.axis.clone(),
        unit: curve.unit.clone(),
    };
    plots::line_plot_with_availability(
        &dir.join(format!("error_vs_{}.svg", curve.axis)),
        &format!("RMS rotation error vs {} (visible scenarios)", curve.axis),
        &format!("{} ({})", curve.axis, curve.unit),
        "RMS rotation error (deg)",
        &series,
        Some(&availability),
    )?;
    Ok(())
}

fn write_identifiability_curve(
    dir: &Path,
    curve: &IdentifiabilityCurve,
) -> Result<(), SensitivityError> {
    let mut table = Table::new([
        format!("{} ({})", curve.axis, curve.unit),
        "visible".into(),
        "identifiable share".into(),
        "smallest margin (px)".into(),
        "predicted wrong-label probability".into(),
        "Monte-Carlo wrong-label rate".into(),
    ]);
    let cell = |v: Option<f64>| v.map_or(String::new(), |v| format!("{v:.6e}"));
    for (k, value) in curve.values.iter().enumerate() {
        table.row([
            value.to_string(),
            curve.visible[k].to_string(),
            cell(curve.identifiable_share[k]),
            cell(curve.smallest_margin_px[k]),
            cell(curve.predicted_wrong[k]),
            cell(curve.monte_carlo_wrong[k]),
        ]);
    }
    let path = dir.join(format!("identifiability_vs_{}.csv", curve.axis));
    write_text(
        &path,
        &table.csv().map_err(|e| ReportError::write(&path, e))?,
    )?;
    let xy = |values: &[Option<f64>]| -> Vec<(f64, f64)> {
        curve
            .values
            .iter()
            .zip(values)
            .filter_map(|(&x, y)| y.map(|y| (x, y)))
            .collect()
    };
    let series = [
        plots::Series {
            name: "Monte-Carlo wrong-label rate".into(),
            points: xy(&curve.monte_carlo_wrong),
            dashed: false,
        },
        plots::Series {
            name: "predicted wrong-label probability".into(),
            points: xy(&curve.predicted_wrong),
            dashed: true,
        },
    ];
    let visible_total: usize = curve.visible.iter().sum();
    let availability = plots::Availability {
        points: curve
            .values
            .iter()
            .copied()
            .zip(curve.identifiable_share.iter().map(|s| s.unwrap_or(0.0)))
            .collect(),
        axis: curve.axis.clone(),
        unit: curve.unit.clone(),
    };
    plots::line_plot_with_availability(
        &dir.join(format!("identifiability_vs_{}.svg", curve.axis)),
        &format!(
            "Wrong-label rate vs {} ({} visible scenarios; panel: share identifiable)",
            curve.axis, visible_total
        ),
        &format!("{} ({})", curve.axis, curve.unit),
        "wrong-label probability",
        &series,
        Some(&availability),
    )?;
    Ok(())
}

fn scenario_table(layout: &Layout, validation: &Analysis) -> Table {
    let mut table = Table::new([
        "scenario",
        "depth_mm",
        "offset_x_mm",
        "offset_y_mm",
        "tilt_deg",
        "pan_deg",
        "roll_deg",
        "sigma_px",
        "visible",
        "class",
        "visibility_issues",
        "first_order_rms_rot_deg",
        "first_order_rms_trans_mm",
        "transfer_rms_rot_deg",
        "qu_hou_rms_rot_deg",
        "bias_max_displacement_px",
        "first_order_bias_rot_deg",
        "first_order_bias_rot_x_deg",
        "first_order_bias_rot_y_deg",
        "first_order_bias_rot_z_deg",
        "first_order_bias_trans_mm",
        "first_order_bias_trans_x_mm",
        "first_order_bias_trans_y_mm",
        "first_order_bias_trans_z_mm",
        "identify_margin_px",
        "identify_predicted_wrong",
        "identify_trials",
        "identify_mc_wrong_rate",
        "identify_mc_missed",
        "solver",
        "trials",
        "rms_rot_deg",
        "mean_rot_deg",
        "median_rot_deg",
        "p95_rot_deg",
        "rms_erot_deg",
        "rms_trans_mm",
        "rms_trans_percent",
        "gross_failures",
        "solver_errors",
    ]);
    let name = |i: usize| layout.points[i].name.clone();
    for (o, identified) in validation.outcomes.iter().zip(
        validation
            .identifiability
            .iter()
            .chain(std::iter::repeat(&None)),
    ) {
        let s = &o.scenario;
        let v = &o.visibility;
        let mut issues: Vec<String> = Vec::new();
        issues.extend(
            v.behind
                .iter()
                .map(|&i| format!("{} behind camera", name(i))),
        );
        issues.extend(
            v.outside
                .iter()
                .map(|&i| format!("{} outside image", name(i))),
        );
        issues.extend(
            v.occluded
                .iter()
                .map(|&(h, b)| format!("{} behind {}", name(h), name(b))),
        );
        let opt = |v: Option<f64>| v.map_or(String::new(), |v| format!("{v:.6e}"));
        let common = [
            s.index.to_string(),
            s.depth_mm.to_string(),
            s.offset_x_mm.to_string(),
            s.offset_y_mm.to_string(),
            s.tilt_deg.to_string(),
            s.pan_deg.to_string(),
            s.roll_deg.to_string(),
            s.sigma_px.to_string(),
            v.is_visible().to_string(),
            VisibilityClass::of(v).name().to_string(),
            issues.join("; "),
            opt(o.first_order.map(|f| f.rms_rotation_deg)),
            opt(o.first_order.map(|f| f.rms_translation_mm)),
            opt(o.transfer.and_then(|t| t.rms_rotation_deg)),
            opt(o.qu_hou_rotation_deg),
            opt(o.bias.map(|b| b.max_displacement_px)),
            opt(o.bias.map(|b| b.pose.rotation_norm_deg())),
            opt(o.bias.map(|b| b.pose.rotation_deg[0])),
            opt(o.bias.map(|b| b.pose.rotation_deg[1])),
            opt(o.bias.map(|b| b.pose.rotation_deg[2])),
            opt(o.bias.map(|b| b.pose.translation_norm_mm())),
            opt(o.bias.map(|b| b.pose.translation_mm[0])),
            opt(o.bias.map(|b| b.pose.translation_mm[1])),
            opt(o.bias.map(|b| b.pose.translation_mm[2])),
            // A margin above the search gate is written as `>GATE`.
            identified
                .as_ref()
                .and_then(|i| i.prediction.as_ref())
                .map_or(String::new(), |p| match p.margin_px {
                    Some(m) => format!("{m:.6e}"),
                    None => format!(">{:.6e}", p.gate_px),
                }),
            opt(identified
                .as_ref()
                .and_then(|i| i.prediction.as_ref())
                .map(|p| p.wrong_probability)),
            identified
                .as_ref()
                .map_or(String::new(), |i| i.trials.trials.to_string()),
            opt(identified.as_ref().and_then(|i| i.trials.wrong_rate())),
            identified
                .as_ref()
                .filter(|i| i.trials.trials > 0)
                .map_or(String::new(), |i| i.trials.missed.to_string()),
        ];
        if o.solvers.is_empty() {
            table.row(
                common
                    .iter()
                    .cloned()
                    .chain(std::iter::repeat_n(String::new(), 11)),
            );
        }
        for r in &o.solvers {
            table.row(common.iter().cloned().chain([
                r.solver.name().to_string(),
                r.rotation_deg.count.to_string(),
                format!("{:.6e}", r.rotation_deg.rms),
                format!("{:.6e}", r.rotation_deg.mean),
                format!("{:.6e}", r.rotation_deg.median),
                format!("{:.6e}", r.rotation_deg.p95),
                format!("{:.6e}", r.paper_rotation_deg.rms),
                format!("{:.6e}", r.translation_mm.rms),
                format!("{:.6e}", r.translation_percent.rms),
                r.gross_failures.to_string(),
                r.solver_errors.to_string(),
            ]));
        }
    }
    table
}

fn range_text(values: &[f64]) -> String {
    match values {
        [single] => single.to_string(),
        [first, .., last] if values.len() > 4 => {
            format!("{first} … {last} ({} values)", values.len())
        }
        _ => values
            .iter()
            .map(|v| v.to_string())
            .collect::<Vec<_>>()
            .join(", "),
    }
}

/// One axis's visibility counts as a table, consecutive values with the
/// same counts merged into one row ("−90 … −60").
fn axis_visibility_table(axis: &AxisVisibility) -> Table {
    let mut table = Table::new([
        format!("{} ({})", axis.axis, axis.unit),
        "visible".to_string(),
        "occluded".to_string(),
        "outside image".to_string(),
        "behind camera".to_string(),
    ]);
    let mut start = 0;
    while start < axis.values.len() {
        let mut end = start;
        while end + 1 < axis.values.len() && axis.counts[end + 1] == axis.counts[start] {
            end += 1;
        }
        let values = if end == start {
            axis.values[start].to_string()
        } else {
            format!("{} … {}", axis.values[start], axis.values[end])
        };
        let counts = axis.counts[start];
        table.row(std::iter::once(values).chain(counts.iter().map(|c| c.to_string())));
        start = end + 1;
    }
    table
}

fn markdown(summary: &Summary) -> String {
    let h = &summary.header;
    let v = &summary.visibility;
    let mut out = String::new();
    let _ = writeln!(out, "# Sensitivity report: {}\n", h.layout);
    let _ = writeln!(out, "| | |\n|---|---|");
    let _ = writeln!(out, "| command | `{}` |", h.command);
    let _ = writeln!(out, "| layout-opt | {} |", h.version);
    let _ = writeln!(out, "| seed | {} |", h.seed);
    let _ = writeln!(out, "| trials per scenario | {} |", h.trials_per_scenario);
    let _ = writeln!(out, "| solvers | {} |", h.solvers.join(", "));
    let _ = writeln!(out, "| noise model | {} |", h.noise_model);
    let _ = writeln!(
        out,
        "| camera | fx {} fy {} cx {} cy {}, {}×{} px, distortion {:?} |",
        h.camera.fx(),
        h.camera.fy(),
        h.camera.cx(),
        h.camera.cy(),
        h.camera.width(),
        h.camera.height(),
        h.camera.distortion()
    );
    let _ = writeln!(out, "| spheres | {} mm |", h.sphere_diameter_mm);
    let _ = writeln!(
        out,
        "| observation | {} (noise added on top) |",
        h.observation
    );
    let _ = writeln!(
        out,
        "| reference feature (paraperspective P0, transfer-model segment origin) | {} |",
        h.reference_point
    );
    let _ = writeln!(
        out,
        "| gross failure | rotation error > {}° |\n",
        h.gross_threshold_deg
    );

    let _ = writeln!(out, "## Scenarios\n");
    let mut grid = Table::new(["axis", "values"]);
    for (name, range) in h.grid.named_ranges() {
        grid.row([
            format!("{name} ({})", axis_unit(name)),
            range_text(&range.values),
        ]);
    }
    out.push_str(&grid.markdown());
    let _ = writeln!(
        out,
        "\n{} scenarios: **{} visible** (availability {:.1}%), {} occluded, {} with a sphere outside the image (margin 5 px), {} with a sphere behind the camera (no trials); {} + {} + {} + {} = {}.",
        v.scenarios, v.visible, 100.0 * v.availability, v.occluded, v.outside_image, v.behind_camera,
        v.visible, v.occluded, v.outside_image, v.behind_camera, v.scenarios
    );
    let _ = writeln!(out, "Each scenario is counted once, under the first rule it breaks in the order behind the camera, outside the image, occluded. A sphere is occluded when its image disc overlaps the disc of a nearer sphere; {} scenarios have an occluded sphere, {} of them also breaking an earlier rule. Statistics below pool the visible scenarios; `scenarios.csv` has every scenario, visible or not, with its class, and `occlusions.csv` every scenario with an occluded sphere and which sphere hides which.\n", v.with_occlusion, v.with_occlusion - v.occluded);
    for axis in &v.by_axis {
        let _ = writeln!(out, "Visibility by {} ({}): scenarios at each value; a row \"A … B\" stands for consecutive values with the same counts.\n", axis.axis, axis.unit);
        out.push_str(&axis_visibility_table(axis).markdown());
        out.push('\n');
    }
    if !v.occlusion_examples.is_empty() {
        let _ = writeln!(
            out,
            "Occluded scenarios (first {} of {}; `occlusions.csv` lists all {} scenarios with an occluded sphere):\n",
            v.occlusion_examples.len(),
            v.occluded,
            v.with_occlusion
        );
        for example in &v.occlusion_examples {
            let _ = writeln!(out, "- {example}");
        }
        out.push('\n');
    }

    let _ = writeln!(out, "## Accuracy per solver (visible scenarios)\n");
    let _ = writeln!(out, "Monte-Carlo, {} trials per scenario, seed {}. RMS pools every trial; \"worst\" is the worst scenario's RMS. Translation errors are |t − t_true|.\n", h.trials_per_scenario, h.seed);
    let mut table = Table::new([
        "solver",
        "trials",
        "RMS rot (°)",
        "mean rot (°)",
        "worst scenario RMS rot (°)",
        "RMS E_rot eq. 33 (°)",
        "RMS trans (mm)",
        "RMS trans (%)",
        "gross",
        "errors",
    ]);
    for row in &summary.solvers {
        let p = &row.pooled;
        table.row([
            format!("`{}`", p.solver.name()),
            p.trials.to_string(),
            significant(Some(p.rms_rotation_deg), 3),
            significant(Some(p.mean_rotation_deg), 3),
            significant(Some(p.worst_rms_rotation_deg), 3),
            significant(Some(p.rms_paper_rotation_deg), 3),
            significant(Some(p.rms_translation_mm), 3),
            significant(Some(p.rms_translation_percent), 3),
            p.gross_failures.to_string(),
            p.solver_errors.to_string(),
        ]);
    }
    out.push_str(&table.markdown());

    let _ = writeln!(out, "\n## Predicted against measured\n");
    if let Some(first) = summary.solvers.first() {
        let (f, t) = (&first.pooled.first_order, &first.pooled.transfer);
        let _ = writeln!(
            out,
            "The first-order (Cramér–Rao) model, `(JᵀWJ)⁻¹` at the true pose, predicts an RMS rotation error of **{}°** and RMS translation error of **{} mm** over the {} visible scenarios. The paper's transfer model (eqs. 26–29, aggregated as documented in `error_model::transfer`) predicts **{}°** and **{} mm** over the {} of them where it is finite (it diverges where every segment through the reference point is parallel or perpendicular to the optical axis).\n",
            significant(f.predicted_rms_rotation_deg, 3), significant(f.predicted_rms_translation_mm, 3), f.scenarios,
            significant(t.predicted_rms_rotation_deg, 3), significant(t.predicted_rms_translation_mm, 3), t.scenarios
        );
    }
    let _ = writeln!(out, "Ratios are measured / predicted over the scenarios each model covers; 1.00 means the model is exact, above 1 the solver does worse than the model predicts.\n");
    let mut agreement = Table::new([
        "solver",
        "rot / first-order",
        "median scenario rot / first-order",
        "trans / first-order",
        "rot / transfer",
        "median scenario rot / transfer",
        "trans / transfer",
    ]);
    for row in &summary.solvers {
        let (f, t) = (&row.pooled.first_order, &row.pooled.transfer);
        agreement.row([
            format!("`{}`", row.pooled.solver.name()),
            significant(f.rotation_ratio, 3),
            significant(row.median_scenario_ratio_to_first_order, 3),
            significant(f.translation_ratio, 3),
            significant(t.rotation_ratio, 3),
            significant(row.median_scenario_ratio_to_transfer, 3),
            significant(t.translation_ratio, 3),
        ]);
    }
    out.push_str(&agreement.markdown());
    let _ = writeln!(
        out,
        "\n![predicted vs measured](predicted_vs_measured.svg)\n"
    );

    out.push_str(&systematic_markdown(&summary.systematic, &h.observation));
    out.push_str(&identifiability_markdown(&summary.identifiability));

    if !summary.curves.is_empty() {
        let _ = writeln!(out, "## Error along each axis\n");
        let _ = writeln!(out, "Each point pools the visible scenarios at that value; dashed lines are the model predictions. CSV beside each plot.\n");
        for curve in &summary.curves {
            let _ = writeln!(
                out,
                "### {}\n\n![error vs {}](error_vs_{}.svg)\n\n[error_vs_{}.csv](error_vs_{}.csv)\n",
                curve.axis, curve.axis, curve.axis, curve.axis, curve.axis
            );
        }
    }
    let _ = writeln!(out, "## Marker\n\n![three views](marker_views.svg)\n");
    out
}

fn identifiability_markdown(s: &IdentifiabilitySummary) -> String {
    let mut out = String::new();
    let _ = writeln!(out, "## Identifiability (visible scenarios)\n");
    let _ = writeln!(
        out,
        "Whether one image tells which blob is which sphere: the unlabelled solver on the blobs, shuffled. Predicted from the noise-free ambiguity margin (the residual norm ‖r‖ of the best wrong labelling that is geometrically consistent): {}. A scenario is identifiable when its predicted wrong-label probability is at most {}. Monte-Carlo: {} trials per visible scenario (the validation's noise draws, seed {}, blobs shuffled), per-point gate {}σ; the wrong labellings are counted, a trial without any labelling counts as wrong. A wrong labelling that fits the blobs worse than the true labelling (refitted) means the solver's search lost the truth, which no margin predicts; the last column is the rest, the wrong labellings that fit better, which is what the prediction models.\n",
        s.model,
        significant(Some(1.0 - s.min_correct), 3),
        s.trials_per_scenario,
        s.seed,
        s.trial_gate_sigmas
    );
    let mut table = Table::new([
        "visible scenarios",
        "identifiable",
        "share",
        "smallest margin (px)",
        "mean predicted wrong",
        "Monte-Carlo wrong (trials)",
        "of which a better fit than the truth",
    ]);
    table.row([
        s.scenarios.to_string(),
        s.identifiable.to_string(),
        s.identifiable_share
            .map_or("—".into(), |v| format!("{:.1}%", 100.0 * v)),
        s.smallest_margin_px.map_or(
            format!("> {}σ everywhere", s.prediction_gate_sigmas),
            |m| significant(Some(m), 3),
        ),
        significant(s.mean_predicted_wrong, 3),
        format!(
            "{} ({} of {}, {} without a labelling, {} fitting worse than the truth)",
            significant(s.monte_carlo_wrong, 3),
            s.trials.wrong,
            s.trials.trials,
            s.trials.failed,
            s.trials.missed
        ),
        significant(s.monte_carlo_ambiguous, 3),
    ]);
    out.push_str(&table.markdown());
    if !s.worst.is_empty() {
        let _ = writeln!(
            out,
            "\nScenarios that are not identifiable ({} of {}, first {}):\n",
            s.scenarios - s.identifiable,
            s.scenarios,
            s.worst.len()
        );
        for line in &s.worst {
            let _ = writeln!(out, "- {line}");
        }
    }
    for curve in &s.curves {
        let _ = writeln!(
            out,
            "\n### Identifiability vs {}\n\n![identifiability vs {}](identifiability_vs_{}.svg)\n\n[identifiability_vs_{}.csv](identifiability_vs_{}.csv)",
            curve.axis, curve.axis, curve.axis, curve.axis, curve.axis
        );
    }
    out.push('\n');
    out
}

fn systematic_markdown(s: &Systematic, observation: &str) -> String {
    let mut out = String::new();
    let _ = writeln!(
        out,
        "\n## Systematic and random error (visible scenarios)\n"
    );
    let _ = writeln!(
        out,
        "Observation `{observation}`: the image point of each sphere is displaced from its projected centre by up to **{} px** (median over scenarios of the largest displacement {} px, {} scenarios). The systematic part is the pose error with zero noise; unlike the random part it does not average out over frames. Rotation about camera x, y, z (pitch, yaw, roll); RMS over scenarios.\n",
        significant(Some(s.max_displacement_px), 3),
        significant(Some(s.median_displacement_px), 3),
        s.scenarios
    );
    let mut table = Table::new([
        "part",
        "rot x (°)",
        "rot y (°)",
        "rot z (°)",
        "rot (°)",
        "max rot (°)",
        "trans (mm)",
        "max trans (mm)",
    ]);
    let mut row = |name: String, e: &AxisErrors| {
        let [x, y, z] = e.rms_rotation_per_axis_deg;
        table.row([
            name,
            significant(Some(x), 3),
            significant(Some(y), 3),
            significant(Some(z), 3),
            significant(Some(e.rms_rotation_deg), 3),
            significant(Some(e.max_rotation_deg), 3),
            significant(Some(e.rms_translation_mm), 3),
            significant(Some(e.max_translation_mm), 3),
        ]);
    };
    row("random, first-order (1σ)".into(), &s.first_order_random);
    row("systematic, first-order bias".into(), &s.first_order_bias);
    for (solver, errors) in &s.solvers {
        row(format!("systematic, `{solver}` at zero noise"), errors);
    }
    out.push_str(&table.markdown());
    out.push('\n');
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_scenario_takes_the_first_rule_it_breaks() {
        let with = |behind: Vec<usize>, outside: Vec<usize>, occluded: Vec<(usize, usize)>| {
            VisibilityClass::of(&Visibility {
                behind,
                outside,
                occluded,
                hidden_by_support: Vec::new(),
            })
        };
        assert_eq!(with(vec![], vec![], vec![]), VisibilityClass::Visible);
        assert_eq!(
            with(vec![], vec![], vec![(1, 2)]),
            VisibilityClass::Occluded
        );
        assert_eq!(
            with(vec![], vec![3], vec![(1, 2)]),
            VisibilityClass::OutsideImage
        );
        assert_eq!(
            with(vec![0], vec![3], vec![(1, 2)]),
            VisibilityClass::BehindCamera
        );
        assert_eq!(with(vec![0], vec![], vec![]), VisibilityClass::BehindCamera);
    }

    #[test]
    fn axis_table_merges_runs_of_equal_counts() {
        let axis = AxisVisibility {
            axis: "tilt".into(),
            unit: "deg".into(),
            values: vec![-20.0, -10.0, 0.0, 10.0],
            counts: vec![[3, 0, 0, 0], [3, 0, 0, 0], [1, 2, 0, 0], [3, 0, 0, 0]],
        };
        assert_eq!(
            axis_visibility_table(&axis).markdown(),
            "| tilt (deg) | visible | occluded | outside image | behind camera |\n|---|---|---|---|---|\n\
| -20 … -10 | 3 | 0 | 0 | 0 |\n| 0 | 1 | 2 | 0 | 0 |\n| 10 | 3 | 0 | 0 | 0 |\n"
        );
    }
}

/// A validation as one call: the Monte-Carlo run, the report and `run.json`,
/// into the directory the configuration names, with progress through an
/// [`Observer`](crate::observer::Observer).
pub mod pipeline {
    use super::{run_until, write_report, Analysis, SensitivityError};
    use crate::camera::Camera;
    use crate::layout::Layout;
    use crate::montecarlo::MonteCarloConfig;
    use crate::observer::{watch, Observer};
    use crate::report::{write_text, ReportError};
    use crate::scenario::ScenarioGrid;
    use std::path::PathBuf;
    use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
    use std::time::Instant;

    /// Progress phase of the run: one step per scenario for the Monte-Carlo
    /// run, then one per scenario for identifiability.
    pub const PHASE: &str = "validating";

    /// Every input and the output directory of a validation.
    #[derive(Debug, Clone)]
    pub struct SensitivityConfig {
        /// The layout.
        pub layout: Layout,
        /// The simulated camera.
        pub camera: Camera,
        /// The scenarios.
        pub grid: ScenarioGrid,
        /// Trials, seed, solvers, noise and gross-failure threshold.
        pub monte_carlo: MonteCarloConfig,
        /// How identifiability is checked.
        pub identifiability: super::IdentifiabilityCheck,
        /// The command that asked for the run, for the report header.
        pub command: String,
        /// A remark on how the grid was chosen, recorded in `run.json`.
        pub grid_note: Option<String>,
        /// The report directory.
        pub out_dir: PathBuf,
    }

    /// What a validation produced.
    #[derive(Debug, Clone)]
    pub struct SensitivityOutcome {
        /// The summary and every scenario's outcome.
        pub validation: Analysis,
        /// Solves attempted (successful ones plus solver errors).
        pub solves: usize,
        /// Wall-clock seconds of the Monte-Carlo run.
        pub seconds: f64,
    }

    /// Validates [`SensitivityConfig::layout`] and writes its report, with
    /// `run.json` (timing, threads, solves, the grid note), into
    /// [`SensitivityConfig::out_dir`]. An observer that asks to stop ends the
    /// Monte-Carlo run within a trial; the result is then
    /// `SensitivityError::MonteCarlo(MonteCarloError::Interrupted)` and no
    /// report is written.
    pub fn run(
        config: &SensitivityConfig,
        observer: &mut impl Observer,
    ) -> Result<SensitivityOutcome, SensitivityError> {
        let threshold = config.monte_carlo.gross_threshold_deg;
        if !(threshold > 0.0 && threshold.is_finite()) {
            return Err(SensitivityError::Config(
                "the gross-failure threshold must be a positive number of degrees".into(),
            ));
        }
        let done = AtomicU64::new(0);
        let stop = AtomicBool::new(false);
        let started = Instant::now();
        let validation = watch(
            observer,
            PHASE,
            2 * config.grid.len() as u64,
            || done.load(Ordering::Relaxed),
            Some(&stop),
            || {
                run_until(
                    &config.layout,
                    &config.camera,
                    &config.grid,
                    &config.monte_carlo,
                    &config.identifiability,
                    &config.command,
                    &|finished| done.store(finished as u64, Ordering::Relaxed),
                    &stop,
                )
            },
        )?;
        let seconds = started.elapsed().as_secs_f64();
        write_report(&config.out_dir, &config.layout, &validation)?;
        let solves: usize = validation
            .outcomes
            .iter()
            .flat_map(|o| o.solvers.iter())
            .map(|r| r.rotation_deg.count + r.solver_errors)
            .sum();
        let run_path = config.out_dir.join("run.json");
        let run = serde_json::json!({
            "tilt_step_note": config.grid_note,
            "wall_seconds": seconds,
            "threads": rayon::current_num_threads(),
            "solves": solves,
            "solves_per_second": solves as f64 / seconds,
        });
        let text =
            serde_json::to_string_pretty(&run).map_err(|e| ReportError::write(&run_path, e))?;
        write_text(&run_path, &(text + "\n"))?;
        Ok(SensitivityOutcome {
            validation,
            solves,
            seconds,
        })
    }

    #[cfg(test)]
    mod tests {
        use super::*;
        use crate::observer::Silent;
        use crate::pnp::Solver;
        use crate::scenario::Range;

        #[test]
        fn writes_the_report_and_run_json_where_the_config_says() {
            let dir = tempfile::tempdir().unwrap();
            let mut config = SensitivityConfig {
                layout: Layout::paper_biprism(),
                camera: Camera::paper(),
                grid: ScenarioGrid::new(
                    "300,600".parse().unwrap(),
                    Range::single(0.0),
                    Range::single(0.0),
                    "-20,20".parse().unwrap(),
                    Range::single(0.0),
                    Range::single(0.0),
                    Range::single(0.5),
                )
                .unwrap(),
                monte_carlo: MonteCarloConfig {
                    trials: 5,
                    seed: 1,
                    solvers: vec![Solver::ParallelWeighted],
                    noise: Default::default(),
                    gross_threshold_deg: crate::montecarlo::DEFAULT_GROSS_THRESHOLD_DEG,
                    observation: Default::default(),
                },
                identifiability: super::super::IdentifiabilityCheck::default(),
                command: "test".into(),
                grid_note: None,
                out_dir: dir.path().join("report"),
            };
            let outcome = run(&config, &mut Silent).unwrap();
            assert_eq!(outcome.solves, 4 * 5);
            assert!(config.out_dir.join("report.md").exists());
            assert!(config.out_dir.join("run.json").exists());
            config.monte_carlo.gross_threshold_deg = 0.0;
            assert!(matches!(
                run(&config, &mut Silent),
                Err(SensitivityError::Config(_))
            ));
        }

        /// Asks to stop from the start.
        struct Stopped;
        impl Observer for Stopped {
            fn interrupted(&self) -> bool {
                true
            }
        }

        #[test]
        fn a_stop_ends_the_run_without_a_report() {
            let dir = tempfile::tempdir().unwrap();
            let config = SensitivityConfig {
                layout: Layout::paper_biprism(),
                camera: Camera::paper(),
                // Enough work that the stop, polled every 20 ms, comes first.
                grid: ScenarioGrid::paper_protocol(2.0),
                monte_carlo: MonteCarloConfig {
                    trials: 200,
                    seed: 1,
                    solvers: vec![Solver::ParallelWeighted, Solver::Ml],
                    noise: Default::default(),
                    gross_threshold_deg: crate::montecarlo::DEFAULT_GROSS_THRESHOLD_DEG,
                    observation: Default::default(),
                },
                identifiability: super::super::IdentifiabilityCheck::default(),
                command: "test".into(),
                grid_note: None,
                out_dir: dir.path().join("report"),
            };
            // A run that ignored the stop would finish with Ok.
            let result = run(&config, &mut Stopped);
            assert!(
                matches!(
                    result,
                    Err(SensitivityError::MonteCarlo(
                        crate::montecarlo::MonteCarloError::Interrupted
                    ))
                ),
                "{result:?}"
            );
            assert!(!config.out_dir.exists());
        }
    }
}
