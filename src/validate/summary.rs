//! What a validation found: every number of its report, serialisable.
//!
//! [`ValidateSummary`] is the analysis's output and the report's only
//! input: the pooled [`Overview`] (exactly what `summary.json` holds, and
//! nothing that depends on the machine, so the same seed gives the same file
//! at any thread count), every scenario's outcome, and the error budget
//! when the part or the camera adds to the noise.

use crate::camera::Camera;
use crate::error_model::budget::{Budget, BudgetOverview};
use crate::identifiability::{self, ScenarioIdentifiability};
use crate::layout::Layout;
use crate::montecarlo::{Pooled, PoseErrorVector, ScenarioOutcome};
use crate::scenario::{Scenario, Visibility};
use crate::volume::WorkingVolume;
use serde::Serialize;

/// A finished validation: the pooled overview and every scenario's
/// outcome.
#[derive(Debug, Clone, Serialize)]
pub struct ValidateSummary {
    /// The layout validated (the report names its points and draws it).
    pub layout: Layout,
    /// Pooled results: what `summary.json` holds.
    pub overview: Overview,
    /// Per-scenario results, in grid order.
    pub outcomes: Vec<ScenarioOutcome>,
    /// Per-scenario identifiability, in grid order (None for scenarios that
    /// are not visible).
    pub identifiability: Vec<Option<ScenarioIdentifiability>>,
    /// The error budget, every scenario (None when only image noise is
    /// counted).
    pub budget: Option<Budget>,
    /// The image-level check (None unless asked for).
    pub images: Option<super::image_check::ImageSummary>,
}

impl ValidateSummary {
    /// Solves attempted by the Monte-Carlo run (successful ones plus solver
    /// errors).
    pub fn solves(&self) -> usize {
        self.outcomes
            .iter()
            .flat_map(|o| o.solvers.iter())
            .map(|r| r.rotation_deg.count + r.solver_errors)
            .sum()
    }
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
    /// The working volume (in `summary.json` as `grid` for a grid, as
    /// before the volume existed, or as `sampled_volume`).
    #[serde(skip)]
    pub volume: WorkingVolume,
    /// The grid, when the volume is one.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub grid: Option<crate::scenario::ScenarioGrid>,
    /// The sampled volume, when the volume is one.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sampled_volume: Option<crate::volume::SampledVolume>,
    /// The volume in words and numbers.
    pub volume_text: String,
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
    /// Every sphere in front, inside the image and clear of the others,
    /// but the part's own supports hide more than the allowed fraction of
    /// some sphere.
    HiddenBySupport,
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
        } else if !visibility.hidden_by_support.is_empty() {
            Self::HiddenBySupport
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
            Self::HiddenBySupport => "hidden-by-support",
        }
    }
}

/// Scenario counts by visibility: `visible + occluded + outside_image +
/// behind_camera + hidden_by_support = scenarios`, each scenario counted once by the precedence
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
    /// Scenarios that break no other rule, in which the part's supports
    /// hide more than the allowed fraction of some sphere (0 when the
    /// supports are not counted).
    pub hidden_by_support: usize,
    /// Whether the supports were counted, and the largest hidden fraction
    /// that still counted as seen.
    pub max_hidden: Option<f64>,
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
    /// Per value: visible, occluded, outside the image, behind the camera,
    /// hidden by a support.
    pub counts: Vec<[usize; 5]>,
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

/// Every pooled number of the report (`summary.json`).
#[derive(Debug, Clone, Serialize)]
pub struct Overview {
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
    /// The first solver's error over every pair of varying axes
    /// ([`super::pairs`]).
    pub pairs: PairwiseErrors,
    /// The visible viewpoints with the first solver's largest errors.
    pub worst: Vec<WorstViewpoint>,
    /// The error budget of the chain (image noise, the part, the camera),
    /// first order and Monte-Carlo, pooled and per depth; absent when
    /// only image noise is counted.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error_budget: Option<BudgetOverview>,
}

/// One axis of the pairwise matrix.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PairAxis {
    /// The axis's name.
    pub axis: String,
    /// Its unit.
    pub unit: String,
    /// Its values (grid values or bin centres).
    pub values: Vec<f64>,
}

/// The pooled error over one pair of axes.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PairPanel {
    /// Index of the horizontal axis in [`PairwiseErrors::axes`].
    pub x: usize,
    /// Index of the vertical axis.
    pub y: usize,
    /// RMS rotation error of the first solver, degrees, per cell
    /// (`[y bin][x bin]`); None where no visible viewpoint falls.
    pub rms_rotation_deg: Vec<Vec<Option<f64>>>,
    /// Visible viewpoints per cell.
    pub visible: Vec<Vec<usize>>,
    /// Viewpoints per cell.
    pub viewpoints: Vec<Vec<usize>>,
}

/// Error against every pair of varying axes.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PairwiseErrors {
    /// The solver whose Monte-Carlo error the cells hold (the first one).
    pub solver: String,
    /// The varying axes, in grid order.
    pub axes: Vec<PairAxis>,
    /// Every pair `x < y` of them.
    pub panels: Vec<PairPanel>,
    /// Smallest and largest cell value, degrees (one colour scale for all).
    pub range_deg: Option<(f64, f64)>,
}

/// A viewpoint among the worst.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct WorstViewpoint {
    /// The viewpoint.
    pub scenario: Scenario,
    /// It in words.
    pub description: String,
    /// The first solver's RMS rotation error there, degrees.
    pub rms_rotation_deg: f64,
    /// The first-order (Cramér–Rao) RMS rotation there, degrees.
    pub first_order_rotation_deg: Option<f64>,
}

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
    pub(super) fn of(errors: &[PoseErrorVector]) -> Self {
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

/// Whether every sphere of the scenario is visible (pooled in the
/// statistics).
pub(super) fn visible(outcome: &ScenarioOutcome) -> bool {
    outcome.visibility.is_visible()
}

/// A scenario in words, for the lists of the report.
pub(super) fn describe_scenario(s: &Scenario) -> String {
    format!(
        "depth {} mm, offset ({}, {}) mm, tilt {}°, pan {}°, roll {}°, σ {} px",
        hundredths(s.depth_mm),
        hundredths(s.offset_x_mm),
        hundredths(s.offset_y_mm),
        hundredths(s.tilt_deg),
        hundredths(s.pan_deg),
        hundredths(s.roll_deg),
        hundredths(s.sigma_px)
    )
}

/// A value to two decimals at most (a grid's values print as given; a
/// sampled one does not print 15 digits).
fn hundredths(value: f64) -> f64 {
    let rounded = (value * 100.0).round() / 100.0;
    if rounded == 0.0 {
        0.0
    } else {
        rounded
    }
}

/// Which sphere hides which in a scenario, in words.
pub(super) fn occluded_pairs(layout: &Layout, outcome: &ScenarioOutcome) -> String {
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

/// The unit of a named grid axis.
pub(super) fn axis_unit(axis: &str) -> &'static str {
    match axis {
        "depth" | "offset-x" | "offset-y" => "mm",
        "noise" => "px",
        _ => "deg",
    }
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
}
