//! Layout search: the objective that scores a marker over a scenario grid,
//! and the argmin optimisers that minimise it ([`optimise`]).
//!
//! # The command's shape
//! * [`config`]: every input and output path of one search
//!   ([`SearchConfig`]), checked once ([`SearchConfig::check`]) with a
//!   [`crate::config::ConfigError`] that names the bad field;
//! * [`analysis`]: the pure search, config in, [`SearchSummary`] out, no
//!   file and no printing, progress through an observer; its phases
//!   (optimisation, identifiability repair, comparison, held-out check,
//!   front, validation) are small methods over one run context;
//! * [`report`]: renders the summary (Markdown, CSV, SVG, JSON and the
//!   terminal's lines), one writer for one search's report directory;
//! * [`workflow`]: locks, checkpoints, the best-so-far file, atomic writes,
//!   `run.json` and the mesh export, as a list of phases over one run
//!   context ([`workflow::PHASES`]); [`estimate`] tells a slow search's time
//!   beforehand.
//!
//! # Objective
//! Per scenario, a term gives an RMS rotation error (degrees) and an RMS
//! translation error (mm):
//! * `crlb`: the first-order (Cramér–Rao) pose covariance;
//! * `transfer`: the paper's transfer model (scenarios where it diverges are
//!   left out of that term and counted);
//! * `mc:<solver>`: the Monte-Carlo error of a real solver, with the run's
//!   common random numbers (trial k of scenario s draws the same noise for
//!   every candidate layout).
//!
//! Scenario values are aggregated by `mean` (root mean square), `p95` or
//! `max` over every scenario in which all spheres are in front of the
//! camera, giving R (deg) and T (mm). Visibility is priced separately: were
//! accuracy pooled over a layout's own visible scenarios, a layout would be
//! punished for becoming measurable in hard scenarios (far, head-on) that
//! another layout hides from. A term scores `(R/R₀ + w_t · T/T₀) / (1 + w_t)`,
//! with R₀, T₀ the same aggregates of the reference layout (the paper's
//! biprism scaled to the envelope), so 1.0 means "as accurate as the paper's
//! biprism". A blend sums weighted terms.
//!
//! *Availability* is the fraction of scenarios with every sphere in front,
//! inside the image and unoccluded. By default it is a **constraint**: a
//! floor ([`AvailabilityFloor`], by default the reference layout's own
//! availability on the same grid), and the objective is accuracy alone. The
//! floor is enforced by an exact penalty: a layout below it pays
//! [`AVAILABILITY_PENALTY`] per unit of missing availability, counted both
//! exactly and softly (see below) so that the optimiser sees a slope back to
//! the feasible side, and ranks behind every layout that meets it; a layout
//! that meets it pays nothing, so the floor does not bias the winner. The
//! weighted blend stays available: the objective adds
//! `w_a · (1 − availability)`, so a layout cannot win by leaving the image
//! or hiding spheres more often. The blend counts each scenario's visibility softly, ramping
//! from 0 to 1 as its smallest visibility margin
//! ([`crate::scenario::visibility_margin_px`]) goes from −[`SOFT_MARGIN_PX`]
//! to +[`SOFT_MARGIN_PX`], so that optimisers see a slope rather than a
//! staircase of 0/1 steps; reports count visibility exactly. The *cost* the optimisers minimise adds
//! [`CONSTRAINT_PENALTY`] per mm of constraint violation.
//!
//! # Books
//! Every term keeps count of the scenarios it scored and of those it could
//! not ([`TermValue`]): behind the camera, unusable noise (a sphere with no
//! positive σ), or the model failing (a singular covariance, a diverging
//! transfer model, a Monte-Carlo scenario where every trial failed). A blend
//! scores every term on the *same* scenarios, those every term could
//! evaluate ([`Evaluation::scored`]), so no two terms are averaged over
//! different subsets; the reference aggregates are taken the same way.
//!
//! ```
//! use layout_opt::layout::Layout;
//! use layout_opt::search::{Evaluator, SearchConfig};
//!
//! // The default search's settings; nothing is written until a run.
//! let config = SearchConfig::new("doc", &std::env::temp_dir());
//! let paper = Layout::paper_biprism();
//! let evaluator = Evaluator::new(
//!     config.camera,
//!     config.volume.scenarios(&config.camera),
//!     config.objective.clone(),
//!     config.constraints,
//!     &paper.positions(),
//! );
//! // Accuracy is relative to the reference layout: 1 for itself, more
//! // (worse) for the same shape at half the size.
//! let itself = evaluator.evaluate(&paper.positions(), &paper.point_sigmas());
//! assert!((itself.accuracy - 1.0).abs() < 1e-9);
//! let half: Vec<_> = paper.positions().iter().map(|p| p * 0.5).collect();
//! assert!(evaluator.evaluate(&half, &paper.point_sigmas()).accuracy > 1.5);
//! ```

pub mod analysis;
mod chain;
pub(crate) mod checkpoint;
pub(crate) mod compare;
pub mod config;
mod error;
pub mod estimate;
pub(crate) mod feasibility;
pub(crate) mod front;
pub(crate) mod identify;
pub(crate) mod optimise;
pub mod report;
pub mod set;
pub mod summary;
mod supports;
pub mod workflow;

pub use analysis::{
    PHASE_COMPARE, PHASE_FRONT, PHASE_IDENTIFY, PHASE_SEARCH, PHASE_SUPPORTS, PHASE_VALIDATE,
    STATUS_FINISHED,
};
pub use chain::{Chain, DEFAULT_PRINTED_SIGMA_MM};
pub use checkpoint::CheckpointError;
pub use compare::{hand_designs, DesignRow, MonteCarloFigures, PooledFigures};
pub use config::{FrontOutput, MeshExport, SearchConfig, WINNER_IDENTIFY_TRIALS};
pub use error::SearchError;
pub use front::{FrontEntry, FrontReport, FrontSettings, HandEntry};
pub use identify::{
    IDENTIFY_MAX_NEW, IDENTIFY_ROUNDS, IDENTIFY_ROUND_ITERATIONS, IDENTIFY_THINNING,
};
pub use optimise::{
    Candidate, OptimiseError, OptimiseOutcome, Optimiser, SearchSettings, FINAL_POLISH_STARTS,
};
pub use summary::{
    ClosestDesign, HeldOutCheck, IdentifyBooks, PrintedFigures, SearchHeader, SearchSummary,
    SupportsBooks, Verdicts,
};
pub use supports::{held_out_with_supports, SUPPORT_ROUNDS, SUPPORT_ROUND_ITERATIONS};
use supports::{Following, SupportRule};

use crate::camera::Camera;
use crate::error_model::budget;
use crate::error_model::first_order::{pose_covariance, pose_covariance_and_bias};
use crate::error_model::transfer;
use crate::family::{Constraints, Violations};
use crate::montecarlo::{
    self, point_sigmas, MonteCarloConfig, Target, DEFAULT_GROSS_THRESHOLD_DEG,
};
use crate::noise::NoiseModel;
use crate::pnp::{parallel::reference_index, Solver};
use crate::scenario::{sphere_images, visibility, visibility_margin_px, Scenario};
use crate::sphere_image::{ellipse_centre_bias_px_into, Observation};
use crate::visibility::{
    spheres_hidden_by_supports, support_fractions, EyeCone, MaxHidden, Supports,
};
use nalgebra::Vector3;
use rayon::prelude::*;
use serde::Serialize;
use std::str::FromStr;

/// Half-width of the soft visibility ramp, px.
pub const SOFT_MARGIN_PX: f64 = 5.0;
/// Cost added per mm of total constraint violation.
pub const CONSTRAINT_PENALTY: f64 = 10.0;
/// The penalty measures violations of the gap and identifiability
/// constraints tightened by this fraction (plus [`PENALTY_MARGIN_MM`]), so
/// that optimisers, which settle on the edge of what they are penalised for,
/// settle inside the true constraints.
pub const PENALTY_MARGIN_FRACTION: f64 = 0.02;
/// Absolute part of the tightening, mm.
pub const PENALTY_MARGIN_MM: f64 = 0.01;
/// Cost of a term when no scenario has every sphere in front of the camera.
pub const UNMEASURABLE_COST: f64 = 1e3;
/// Cost per unit of availability below the floor (so one scenario of a
/// 325-scenario grid costs 0.31, a third of the reference layout's accuracy).
pub const AVAILABILITY_PENALTY: f64 = 100.0;
/// Cost per decade by which a checked scenario's predicted wrong-label
/// probability exceeds the identifiability criterion, summed over the
/// failing scenarios once more fail than the floor allows.
pub const IDENTIFIABILITY_PENALTY: f64 = 1.0;

/// The identifiability floor: the least share of visible scenarios in which
/// the unlabelled solver is predicted to label the blobs correctly with
/// probability at least `min_correct` ([`crate::identifiability`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct IdentifiabilityFloor {
    /// Least share of the visible scenarios that must be identifiable.
    pub min_share: f64,
    /// Least predicted share of correct labellings of an identifiable
    /// scenario.
    pub min_correct: f64,
}

impl IdentifiabilityFloor {
    /// The default floor: 99.9% of the visible scenarios, each labelled
    /// correctly with probability 99.9% or more.
    pub const DEFAULT: IdentifiabilityFloor = IdentifiabilityFloor {
        min_share: 0.999,
        min_correct: crate::identifiability::DEFAULT_MIN_CORRECT,
    };

    /// How many of `visible` scenarios may fail the criterion.
    pub fn allowed_failures(&self, visible: usize) -> usize {
        ((1.0 - self.min_share) * visible as f64 + 1e-9).floor() as usize
    }
}

/// Which scenarios an evaluation checks for identifiability (each check
/// runs the unlabelled solver, 0.1–1 ms, so the search checks a chosen
/// few: the identifiability repair).
#[derive(Debug, Clone, Default, PartialEq)]
pub enum IdentifyScope {
    /// None.
    #[default]
    Off,
    /// These positions in the evaluator's scenario list (the visible ones
    /// among them).
    Scenarios(std::sync::Arc<Vec<usize>>),
    /// Every visible scenario.
    All,
}

/// Identifiability of an evaluated layout over the scenarios checked.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct IdentifiabilityFigures {
    /// Whether every visible scenario was checked (else a chosen subset).
    pub all_checked: bool,
    /// Visible scenarios checked.
    pub checked: usize,
    /// Of them, those predicted identifiable.
    pub identifiable: usize,
    /// Failures the floor allows over the layout's visible scenarios.
    pub allowed_failures: usize,
    /// Smallest margin over the checked scenarios, px (None: none within
    /// the search gate).
    pub smallest_margin_px: Option<f64>,
    /// Positions (in the evaluator's scenario list) of the checked
    /// scenarios that are not identifiable.
    pub failing: Vec<usize>,
    /// Of them, those where a wrong labelling fits the noise-free view
    /// (margin below [`crate::identifiability::TWIN_MARGIN_PX`]): symmetric
    /// twins.
    pub twins: usize,
    /// The floor's penalty (0 when it is met).
    pub penalty: f64,
}

impl IdentifiabilityFigures {
    /// Whether the checked scenarios meet the floor.
    pub fn meets_floor(&self) -> bool {
        self.failing.len() <= self.allowed_failures
    }
}

/// The least availability a layout must reach.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum AvailabilityFloor {
    /// No floor: availability is priced by the availability weight alone.
    None,
    /// The reference layout's availability on the same grid (for the
    /// biprism family, the paper's biprism).
    Reference,
    /// A share of the grid's scenarios, in [0, 1].
    Share(f64),
}

impl std::fmt::Display for AvailabilityFloor {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            AvailabilityFloor::None => f.write_str("none"),
            AvailabilityFloor::Reference => f.write_str("reference"),
            AvailabilityFloor::Share(share) => write!(f, "{share}"),
        }
    }
}

impl FromStr for AvailabilityFloor {
    type Err = ObjectiveError;
    fn from_str(text: &str) -> Result<Self, Self::Err> {
        match text.trim() {
            "none" => Ok(AvailabilityFloor::None),
            "reference" => Ok(AvailabilityFloor::Reference),
            other => crate::config::parse_share(other)
                .map(AvailabilityFloor::Share)
                .ok_or_else(|| ObjectiveError::BadFloor(other.to_string())),
        }
    }
}

/// Why an objective could not be parsed or set up.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum ObjectiveError {
    /// The objective text is not one we know.
    #[error("unknown objective '{0}'; use crlb, transfer, mc:<solver>, or a blend like crlb:0.7+mc:parallel-weighted:0.3")]
    Unknown(String),
    /// A weight is not positive.
    #[error("objective weights must be positive and finite, got {0}")]
    BadWeight(f64),
    /// An availability floor is neither a share in [0, 1] nor a keyword.
    #[error("the availability floor must be a share in [0, 1] (0.6 or 60%), 'reference' or 'none', got '{0}'")]
    BadFloor(String),
}

/// One term of the objective.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Term {
    /// First-order (Cramér–Rao) covariance.
    Crlb,
    /// The paper's transfer model.
    Transfer,
    /// Monte-Carlo error of a solver.
    MonteCarlo(Solver),
}

impl std::fmt::Display for Term {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Term::Crlb => f.write_str("crlb"),
            Term::Transfer => f.write_str("transfer"),
            Term::MonteCarlo(solver) => write!(f, "mc:{solver}"),
        }
    }
}

/// A weighted blend of terms (a single term has weight 1).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Objective {
    /// Terms and their weights.
    pub terms: Vec<(Term, f64)>,
}

impl std::fmt::Display for Objective {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let parts: Vec<String> = self
            .terms
            .iter()
            .map(|(term, weight)| {
                if self.terms.len() == 1 {
                    term.to_string()
                } else {
                    format!("{term}:{weight}")
                }
            })
            .collect();
        f.write_str(&parts.join("+"))
    }
}

impl FromStr for Objective {
    type Err = ObjectiveError;
    fn from_str(text: &str) -> Result<Self, Self::Err> {
        let unknown = || ObjectiveError::Unknown(text.to_string());
        let mut terms = Vec::new();
        for part in text.split('+') {
            let pieces: Vec<&str> = part.trim().split(':').collect();
            let (term, rest) = match pieces.as_slice() {
                ["crlb", rest @ ..] => (Term::Crlb, rest),
                ["transfer", rest @ ..] => (Term::Transfer, rest),
                ["mc", solver, rest @ ..] => (
                    Term::MonteCarlo(solver.parse().map_err(|_| unknown())?),
                    rest,
                ),
                ["mc"] => (Term::MonteCarlo(Solver::ParallelWeighted), &[][..]),
                _ => return Err(unknown()),
            };
            let weight = match rest {
                [] => 1.0,
                [weight] => weight.parse::<f64>().map_err(|_| unknown())?,
                _ => return Err(unknown()),
            };
            if !(weight > 0.0 && weight.is_finite()) {
                return Err(ObjectiveError::BadWeight(weight));
            }
            terms.push((term, weight));
        }
        Ok(Objective { terms })
    }
}

/// How per-scenario errors are combined.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Aggregate {
    /// Root mean square over the scored scenarios.
    Mean,
    /// 95th percentile (nearest rank).
    P95,
    /// Worst scenario.
    Max,
}

impl FromStr for Aggregate {
    type Err = String;
    fn from_str(text: &str) -> Result<Self, Self::Err> {
        match text {
            "mean" => Ok(Aggregate::Mean),
            "p95" => Ok(Aggregate::P95),
            "max" => Ok(Aggregate::Max),
            other => Err(format!("unknown aggregate '{other}'; use mean, p95 or max")),
        }
    }
}

impl Aggregate {
    /// Aggregates `values` (reordered in place); None when empty.
    pub fn apply(self, values: &mut [f64]) -> Option<f64> {
        if values.is_empty() {
            return None;
        }
        Some(match self {
            Aggregate::Mean => {
                (values.iter().map(|v| v * v).sum::<f64>() / values.len() as f64).sqrt()
            }
            Aggregate::Max => values.iter().copied().fold(f64::NEG_INFINITY, f64::max),
            Aggregate::P95 => {
                values.sort_by(f64::total_cmp);
                montecarlo::nearest_rank_of_sorted(values, 0.95)
            }
        })
    }
}

/// Everything the objective needs besides the layout.
#[derive(Debug, Clone, Serialize)]
pub struct ObjectiveSettings {
    /// The terms.
    pub objective: Objective,
    /// How scenarios are combined.
    pub aggregate: Aggregate,
    /// w_t: weight of translation against rotation.
    pub translation_weight: f64,
    /// w_a: cost of losing every scenario to visibility.
    pub availability_weight: f64,
    /// The least availability a layout must reach.
    pub min_availability: AvailabilityFloor,
    /// Monte-Carlo trials per scenario (for `mc:` terms).
    pub trials: usize,
    /// Seed of the common random numbers.
    pub seed: u64,
    /// Pixel noise model.
    pub noise: NoiseModel,
    /// What a sphere's image point is; with ellipse centres the `crlb` term
    /// carries the first-order pose bias, `√(rms² + bias²)`. Only the ideal
    /// chain reads it: the others read projected centres.
    pub observation: Observation,
    /// The chain scored (the part's error beside the image noise).
    pub chain: Chain,
}

/// One term's raw aggregates.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct TermValue {
    /// The term.
    pub term: Term,
    /// Aggregated RMS rotation error, degrees.
    pub rotation_deg: Option<f64>,
    /// Aggregated RMS translation error, mm.
    pub translation_mm: Option<f64>,
    /// Scenarios the term could evaluate (among those with every sphere in
    /// front and usable noise).
    pub evaluated: usize,
    /// Scenarios where the term's model failed (singular covariance,
    /// diverging transfer model, every Monte-Carlo trial failed).
    pub failed: usize,
}

/// A scored layout.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Evaluation {
    /// The cost minimised by the search: objective + constraint penalty.
    pub cost: f64,
    /// The objective: accuracy + availability term.
    pub objective: f64,
    /// The accuracy part (1.0 = the reference layout).
    pub accuracy: f64,
    /// Raw aggregates per term.
    pub terms: Vec<TermValue>,
    /// Fraction of scenarios with every sphere visible.
    pub availability: f64,
    /// The soft availability the objective uses (see the module docs).
    pub soft_availability: f64,
    /// Scenarios with every sphere visible.
    pub visible: usize,
    /// Scenarios with every sphere in front of the camera (scored for accuracy).
    pub in_front: usize,
    /// Scenarios with an occluded sphere.
    pub occluded: usize,
    /// Scenarios with a sphere outside the image.
    pub outside: usize,
    /// Scenarios with a sphere behind the camera.
    pub behind: usize,
    /// Scenarios the accuracy is aggregated over: in front, usable noise,
    /// and evaluated by every term.
    pub scored: usize,
    /// In-front scenarios left out because a sphere had no positive σ.
    pub unusable_noise: usize,
    /// The availability floor in force (None: no floor).
    pub availability_floor: Option<f64>,
    /// The floor's penalty (0 when the floor is met).
    pub floor_penalty: f64,
    /// Constraint violations.
    pub violations: Violations,
    /// Identifiability over the scenarios the evaluator checks (None when
    /// it checks none).
    pub identifiability: Option<IdentifiabilityFigures>,
    /// The cross repair's penalty on confusions with earlier markers of a
    /// set (0 outside a repair; [`set::repair`]).
    #[serde(skip_serializing_if = "is_zero")]
    pub cross_penalty: f64,
}

fn is_zero(value: &f64) -> bool {
    *value == 0.0
}

impl Evaluation {
    /// The layout reaches the availability floor (or there is none).
    pub fn meets_availability_floor(&self) -> bool {
        self.availability_floor
            .is_none_or(|floor| self.availability + 1e-12 >= floor)
    }

    /// The checked scenarios meet the identifiability floor (or none was
    /// checked).
    pub fn meets_identifiability_floor(&self) -> bool {
        self.identifiability
            .as_ref()
            .is_none_or(IdentifiabilityFigures::meets_floor)
    }

    /// Meets every constraint, the availability floor and, over the
    /// scenarios checked, the identifiability floor.
    pub fn admissible(&self) -> bool {
        self.violations.feasible()
            && self.meets_availability_floor()
            && self.meets_identifiability_floor()
    }
}

/// Scores layouts on a fixed scenario grid.
#[derive(Debug, Clone)]
pub struct Evaluator {
    camera: Camera,
    scenarios: Vec<Scenario>,
    settings: ObjectiveSettings,
    constraints: Constraints,
    /// The constraints the penalty measures (tightened).
    penalised: Constraints,
    /// (R₀, T₀) per term, from the reference layout.
    reference: Vec<(f64, f64)>,
    /// The reference layout's availability.
    reference_availability: f64,
    /// The availability floor in force.
    floor: Option<f64>,
    /// The identifiability floor in force.
    identify_floor: Option<IdentifiabilityFloor>,
    /// The scenarios checked for identifiability.
    identify_scope: IdentifyScope,
    /// Which supports hide spheres ([`SupportRule`]).
    supports: SupportRule,
    /// The confusions with earlier markers a set's cross repair holds.
    cross: Option<std::sync::Arc<set::repair::CrossRule>>,
}

/// Per-scenario raw values of one layout: visibility flags and, per term,
/// (rotation, translation) for the in-front scenarios it can score.
struct ScenarioValues {
    visible: usize,
    soft_visible: f64,
    in_front: usize,
    occluded: usize,
    outside: usize,
    behind: usize,
    unusable_noise: usize,
    /// Per term, per scenario: (rotation, translation) when the term could
    /// evaluate it; `None` for scenarios not in front or with unusable noise.
    per_term: Vec<Vec<Option<(f64, f64)>>>,
    /// Per term: scenarios in front with usable noise where the model failed.
    failed: Vec<usize>,
    /// Scenarios in front with usable noise.
    usable: Vec<bool>,
    /// Per checked visible scenario: (position, predicted wrong-label
    /// probability, margin px).
    identified: Vec<(usize, f64, Option<f64>)>,
}

/// One term's (rotations, translations) over the scored scenarios.
type TermSamples = (Vec<f64>, Vec<f64>);

impl ScenarioValues {
    /// Per term, the (rotations, translations) of the scenarios that every
    /// term evaluated: the common subset, so no two terms are averaged over
    /// different scenarios.
    fn common(&self) -> (usize, Vec<TermSamples>) {
        let common: Vec<bool> = (0..self.usable.len())
            .map(|s| self.usable[s] && self.per_term.iter().all(|t| t[s].is_some()))
            .collect();
        let count = common.iter().filter(|c| **c).count();
        let per_term = self
            .per_term
            .iter()
            .map(|values| {
                values
                    .iter()
                    .zip(&common)
                    .filter_map(|(v, c)| v.filter(|_| *c))
                    .unzip()
            })
            .collect();
        (count, per_term)
    }
}

impl Evaluator {
    /// An evaluator normalised by `reference` (the paper's biprism scaled to
    /// the envelope, usually). If the reference cannot be measured by a term,
    /// that term is left unnormalised (R₀ = 1°, T₀ = 1 mm).
    pub fn new(
        camera: Camera,
        scenarios: Vec<Scenario>,
        settings: ObjectiveSettings,
        constraints: Constraints,
        reference: &[Vector3<f64>],
    ) -> Self {
        // The envelope is not tightened: its excess is continuous and the
        // best layouts sit on it, so shrinking it would cost real accuracy.
        let penalised = constraints.tightened(PENALTY_MARGIN_FRACTION, PENALTY_MARGIN_MM);
        let mut evaluator = Self {
            camera,
            scenarios,
            reference: vec![(1.0, 1.0); settings.objective.terms.len()],
            reference_availability: 0.0,
            floor: None,
            identify_floor: None,
            identify_scope: IdentifyScope::Off,
            supports: SupportRule::None,
            cross: None,
            settings,
            constraints,
            penalised,
        };
        let raw = evaluator.values(reference, &vec![None; reference.len()]);
        evaluator.reference_availability =
            raw.visible as f64 / evaluator.scenarios.len().max(1) as f64;
        evaluator.floor = match evaluator.settings.min_availability {
            AvailabilityFloor::None => None,
            AvailabilityFloor::Reference => Some(evaluator.reference_availability),
            AvailabilityFloor::Share(share) => Some(share),
        };
        evaluator.reference = raw
            .common()
            .1
            .into_iter()
            .map(|(mut rotation, mut translation)| {
                let a = evaluator.settings.aggregate;
                (
                    a.apply(&mut rotation).filter(|v| *v > 0.0).unwrap_or(1.0),
                    a.apply(&mut translation)
                        .filter(|v| *v > 0.0)
                        .unwrap_or(1.0),
                )
            })
            .collect();
        evaluator
    }

    /// The scenario grid.
    pub fn scenarios(&self) -> &[Scenario] {
        &self.scenarios
    }

    /// The settings.
    pub fn settings(&self) -> &ObjectiveSettings {
        &self.settings
    }

    /// The constraints.
    pub fn constraints(&self) -> &Constraints {
        &self.constraints
    }

    /// The reference aggregates (R₀ deg, T₀ mm) per term.
    pub fn reference(&self) -> &[(f64, f64)] {
        &self.reference
    }

    /// The reference layout's availability on the grid.
    pub fn reference_availability(&self) -> f64 {
        self.reference_availability
    }

    /// The availability floor in force (None: no floor).
    pub fn availability_floor(&self) -> Option<f64> {
        self.floor
    }

    /// The same evaluator with another availability floor (the reference
    /// aggregates are kept; an ε-constraint sweep changes only the floor).
    pub fn with_floor(&self, floor: Option<f64>) -> Self {
        let mut evaluator = self.clone();
        evaluator.floor = floor;
        evaluator.settings.min_availability = match floor {
            Some(share) => AvailabilityFloor::Share(share),
            None => AvailabilityFloor::None,
        };
        evaluator
    }

    /// The first-order (`crlb`) evaluator with this one's grid, aggregate,
    /// weights and floor, normalised by `reference`: the figures the front
    /// and the held-out check report whatever the objective.
    pub fn first_order(&self, reference: &[Vector3<f64>]) -> Self {
        let mut settings = self.settings.clone();
        settings.objective = Objective {
            terms: vec![(Term::Crlb, 1.0)],
        };
        let mut evaluator = Evaluator::new(
            self.camera,
            self.scenarios.clone(),
            settings,
            self.constraints,
            reference,
        );
        evaluator.floor = self.floor;
        if let SupportRule::Candidate(..) = &self.supports {
            evaluator.supports = self.supports.clone();
            evaluator.reference_availability = self.reference_availability;
        }
        evaluator
    }

    /// The same evaluator with an identifiability floor checked on `scope`
    /// (the reference aggregates and the availability floor are kept).
    pub fn with_identifiability(
        &self,
        floor: Option<IdentifiabilityFloor>,
        scope: IdentifyScope,
    ) -> Self {
        let mut evaluator = self.clone();
        evaluator.identify_floor = floor;
        evaluator.identify_scope = if floor.is_some() {
            scope
        } else {
            IdentifyScope::Off
        };
        evaluator
    }

    /// The same evaluator with the supports of one layout counted
    /// ([`crate::visibility`]): a scenario in which they hide more than
    /// `max_hidden` of a sphere counts as not visible, for availability and
    /// identifiability alike. Only meaningful for scoring the layout the
    /// supports were designed for (e.g. a winner against its printed part).
    pub fn with_supports(&self, supports: Supports, max_hidden: MaxHidden) -> Self {
        let mut evaluator = self.clone();
        evaluator.supports = SupportRule::Fixed(std::sync::Arc::new(supports), max_hidden);
        evaluator
    }

    /// The same evaluator counting every candidate's own supports: those
    /// that `export`'s pillars would try first for it
    /// ([`crate::mesh::straight_supports`] with `options`), so that the
    /// optimiser sees what a layout's supports cost and may move its
    /// spheres out of their way. The reference layout's availability (and
    /// the availability floor taken from it) is recounted with its own
    /// supports; the accuracy references do not change (accuracy is pooled
    /// over the scenarios in front, whatever hides what).
    pub fn with_candidate_supports(
        &self,
        options: crate::mesh::MarkerOptions,
        max_hidden: MaxHidden,
        reference: &[Vector3<f64>],
    ) -> Self {
        let mut evaluator = self.clone();
        evaluator.supports = SupportRule::Candidate(
            std::sync::Arc::new(options),
            max_hidden,
            EyeCone::of(&evaluator.scenarios),
        );
        let visible = evaluator
            .values(reference, &vec![None; reference.len()])
            .visible;
        evaluator.reference_availability = visible as f64 / evaluator.scenarios.len().max(1) as f64;
        if evaluator.settings.min_availability == AvailabilityFloor::Reference {
            evaluator.floor = Some(evaluator.reference_availability);
        }
        evaluator
    }

    /// The same evaluator pricing a printed part's supports as they follow
    /// the candidate's spheres ([`supports::Following`]), under the
    /// availability floor `floor` of the part as printed (a supports
    /// repair round).
    fn with_following(&self, rule: Following, floor: Option<f64>) -> Self {
        let mut evaluator = self.clone();
        evaluator.supports = SupportRule::Following(std::sync::Arc::new(rule));
        evaluator.floor = floor;
        evaluator
    }

    /// The same evaluator pricing the confusions that `rule` holds (a
    /// set's cross repair, [`set::repair`]).
    pub fn with_cross(&self, rule: set::repair::CrossRule) -> Self {
        let mut evaluator = self.clone();
        evaluator.cross = Some(std::sync::Arc::new(rule));
        evaluator
    }

    /// Whether candidates' own supports are counted
    /// ([`Evaluator::with_candidate_supports`]).
    pub fn counts_candidate_supports(&self) -> bool {
        matches!(self.supports, SupportRule::Candidate(..))
    }

    /// The identifiability floor in force.
    pub fn identifiability_floor(&self) -> Option<IdentifiabilityFloor> {
        self.identify_floor
    }

    /// The same evaluator with another availability weight (the weighted
    /// blend; the reference aggregates and the floor are kept).
    pub fn with_availability_weight(&self, weight: f64) -> Self {
        let mut evaluator = self.clone();
        evaluator.settings.availability_weight = weight;
        evaluator
    }

    /// The same evaluator on another scenario grid (a held-out grid), with
    /// the same reference layout's aggregates recomputed there.
    /// Candidates' own supports stay counted when they were.
    pub fn on_scenarios(&self, scenarios: Vec<Scenario>, reference: &[Vector3<f64>]) -> Self {
        let evaluator = Evaluator::new(
            self.camera,
            scenarios,
            self.settings.clone(),
            self.constraints,
            reference,
        );
        match &self.supports {
            SupportRule::Candidate(options, max_hidden, _) => {
                evaluator.with_candidate_supports((**options).clone(), *max_hidden, reference)
            }
            _ => evaluator,
        }
    }

    /// The same evaluator with no supports counted: the spheres alone.
    pub fn without_supports(&self, reference: &[Vector3<f64>]) -> Self {
        let mut evaluator = self.clone();
        evaluator.supports = SupportRule::None;
        if matches!(self.supports, SupportRule::Candidate(..)) {
            let visible = evaluator
                .values(reference, &vec![None; reference.len()])
                .visible;
            evaluator.reference_availability =
                visible as f64 / evaluator.scenarios.len().max(1) as f64;
            if evaluator.settings.min_availability == AvailabilityFloor::Reference {
                evaluator.floor = Some(evaluator.reference_availability);
            }
        }
        evaluator
    }

    fn values(&self, points: &[Vector3<f64>], point_sigma: &[Option<f64>]) -> ScenarioValues {
        let terms = &self.settings.objective.terms;
        let n = self.scenarios.len();
        let mut values = ScenarioValues {
            visible: 0,
            soft_visible: 0.0,
            in_front: 0,
            occluded: 0,
            outside: 0,
            behind: 0,
            unusable_noise: 0,
            per_term: vec![vec![None; n]; terms.len()],
            failed: vec![0; terms.len()],
            usable: vec![false; n],
            identified: Vec::new(),
        };
        let needs_models = terms
            .iter()
            .any(|(t, _)| matches!(t, Term::Crlb | Term::Transfer));
        let reference = reference_index(points);
        let mut image_bias = Vec::with_capacity(points.len());
        let radius_mm = 0.5 * self.constraints.sphere_diameter_mm;
        // The chain's part: each centre's covariance (None: the ideal
        // chain; Some(None): the capture plan cannot characterise it, and
        // no scenario can be scored).
        let depths = self
            .scenarios
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), s| {
                (lo.min(s.depth_mm), hi.max(s.depth_mm))
            });
        let part = match needs_models {
            true => self.settings.chain.part_covariances(
                points,
                self.constraints.sphere_diameter_mm,
                &self.camera,
                depths,
            ),
            false => None,
        };
        let observation = match part {
            None => self.settings.observation,
            Some(_) => Observation::Centre,
        };
        let own;
        let screen;
        // A repair round's part, carried to these spheres and judged on
        // the held scenarios that the spheres alone leave visible (in
        // parallel: a round runs one Nelder–Mead start).
        let mut following = match &self.supports {
            SupportRule::Following(rule) => Some(rule.judge_all(self, points)),
            _ => None,
        };
        // The supports, and per sphere those that may hide it (all of
        // them for a fixed part; a candidate's, screened once).
        let supports = match &self.supports {
            SupportRule::None | SupportRule::Following(_) => None,
            SupportRule::Fixed(supports, max_hidden) => Some((&**supports, *max_hidden, None)),
            SupportRule::Candidate(options, max_hidden, eyes) => {
                own = crate::mesh::straight_supports(
                    points,
                    self.constraints.sphere_diameter_mm,
                    options,
                );
                screen = eyes.map(|eyes| eyes.screen(points, radius_mm, &own));
                screen
                    .as_ref()
                    .is_none_or(|screen| screen.iter().any(|parts| !parts.is_empty()))
                    .then_some((&own, *max_hidden, screen.as_deref()))
            }
        };
        // The visible scenarios whose identification this evaluation
        // checks, identified after the loop in parallel (a repair round
        // runs one Nelder–Mead start, so its evaluations are serial) and
        // kept in scenario order.
        let mut to_identify = Vec::new();
        for (s, scenario) in self.scenarios.iter().enumerate() {
            let pose = scenario.pose();
            let images = sphere_images(
                &self.camera,
                &pose,
                points,
                self.constraints.sphere_diameter_mm,
            );
            let mut v = visibility(&images, &self.camera);
            // The soft visibility the supports leave (a repair round's ramp).
            let mut support_soft = 1.0;
            if let Some(Some((hidden, soft))) = following.as_mut().map(|judged| judged[s].take()) {
                (v.hidden_by_support, support_soft) = (hidden, soft);
            }
            if let Some((supports, max_hidden, screen)) = supports {
                if v.is_visible() {
                    // Whether the scenario is visible is all that counts
                    // here: the first hidden sphere decides it.
                    v.hidden_by_support = match screen {
                        Some(screen) => spheres_hidden_by_supports(
                            &self.camera,
                            &pose,
                            points,
                            radius_mm,
                            supports,
                            screen,
                            max_hidden,
                        )
                        .take(1)
                        .collect(),
                        None => {
                            let fractions =
                                support_fractions(&self.camera, &pose, points, radius_mm, supports);
                            (0..points.len())
                                .filter(|&k| fractions[k] > max_hidden.fraction())
                                .collect()
                        }
                    };
                }
            }
            values.occluded += usize::from(!v.occluded.is_empty());
            values.outside += usize::from(!v.outside.is_empty());
            values.behind += usize::from(!v.behind.is_empty());
            values.visible += usize::from(v.is_visible());
            if v.is_visible() && self.checks_identifiability(s) {
                to_identify.push((s, pose, images.clone()));
            }
            let margin = if v.hidden_by_support.is_empty() || following.is_some() {
                visibility_margin_px(&images, &self.camera)
            } else {
                f64::NEG_INFINITY
            };
            values.soft_visible +=
                (0.5 + margin / (2.0 * SOFT_MARGIN_PX)).clamp(0.0, 1.0) * support_soft;
            if !v.all_in_front() {
                continue;
            }
            values.in_front += 1;
            let sigmas = point_sigmas(
                &self.settings.noise,
                scenario.sigma_px,
                &images,
                point_sigma,
            );
            if !sigmas.iter().all(|s| *s > 0.0) {
                values.unusable_noise += 1;
                continue;
            }
            values.usable[s] = true;
            if !needs_models {
                continue;
            }
            for (k, (term, _)) in terms.iter().enumerate() {
                let value = match term {
                    Term::Crlb => match observation {
                        Observation::Centre => match &part {
                            None => pose_covariance(&self.camera, &pose, points, &sigmas)
                                .ok()
                                .map(|c| (c.rms_rotation_deg(), c.rms_translation_mm())),
                            Some(None) => None,
                            Some(Some(blocks)) => budget::source_covariances(
                                &self.camera,
                                &pose,
                                points,
                                &sigmas,
                                blocks,
                                budget::IntrinsicSigma::default(),
                            )
                            .ok()
                            .map(|c| {
                                let total = c.total();
                                (
                                    budget::rms_rotation_deg(&total),
                                    budget::rms_translation_mm(&total),
                                )
                            }),
                        },
                        // The bias of ellipse-centre observations adds to
                        // the random part in quadrature (an RMS error).
                        Observation::EllipseCentre => {
                            let radius_mm = 0.5 * self.constraints.sphere_diameter_mm;
                            ellipse_centre_bias_px_into(
                                &self.camera,
                                &pose,
                                points,
                                radius_mm,
                                &mut image_bias,
                            )
                            .ok()
                            .and_then(|()| {
                                match pose_covariance_and_bias(
                                    &self.camera,
                                    &pose,
                                    points,
                                    &sigmas,
                                    &image_bias,
                                ) {
                                    Ok((Some(c), bias)) => Some((
                                        c.rms_rotation_deg().hypot(bias.rotation_deg()),
                                        c.rms_translation_mm().hypot(bias.translation_norm_mm()),
                                    )),
                                    _ => None,
                                }
                            })
                        }
                    },
                    Term::Transfer => {
                        let p = transfer::predict(&self.camera, &pose, points, reference, &sigmas);
                        p.rms_rotation_deg.zip(p.rms_translation_mm)
                    }
                    Term::MonteCarlo(_) => continue,
                };
                values.failed[k] += usize::from(value.is_none());
                values.per_term[k][s] = value;
            }
        }
        for (k, (term, _)) in terms.iter().enumerate() {
            let Term::MonteCarlo(solver) = term else {
                continue;
            };
            let usable: Vec<usize> = (0..n).filter(|&s| values.usable[s]).collect();
            let in_front: Vec<Scenario> = usable.iter().map(|&s| self.scenarios[s]).collect();
            let target = Target {
                camera: &self.camera,
                object: points,
                sphere_diameter_mm: self.constraints.sphere_diameter_mm,
                point_sigma_px: point_sigma,
            };
            let config = MonteCarloConfig {
                trials: self.settings.trials,
                seed: self.settings.seed,
                solvers: vec![*solver],
                noise: self.settings.noise,
                gross_threshold_deg: DEFAULT_GROSS_THRESHOLD_DEG,
                observation,
            };
            match montecarlo::run(&target, &in_front, &config, &|_| {}) {
                Ok(outcomes) => {
                    for (&s, outcome) in usable.iter().zip(outcomes) {
                        let value = outcome
                            .solvers
                            .first()
                            .filter(|r| r.rotation_deg.count > 0)
                            .map(|r| (r.rotation_deg.rms, r.translation_mm.rms));
                        values.failed[k] += usize::from(value.is_none());
                        values.per_term[k][s] = value;
                    }
                }
                Err(_) => values.failed[k] += usable.len(),
            }
        }
        values.identified = to_identify
            .par_iter()
            .map(|(s, pose, images)| {
                self.identify(*s, &self.scenarios[*s], pose, points, point_sigma, images)
            })
            .collect();
        values
    }

    fn checks_identifiability(&self, position: usize) -> bool {
        match &self.identify_scope {
            IdentifyScope::Off => false,
            IdentifyScope::All => true,
            IdentifyScope::Scenarios(positions) => positions.binary_search(&position).is_ok(),
        }
    }

    /// One visible scenario's predicted wrong-label probability and margin
    /// (probability 1 where no prediction can be made).
    fn identify(
        &self,
        position: usize,
        scenario: &Scenario,
        pose: &crate::pose::Pose,
        points: &[Vector3<f64>],
        point_sigma: &[Option<f64>],
        images: &[Option<crate::scenario::SphereImage>],
    ) -> (usize, f64, Option<f64>) {
        let radius_mm = 0.5 * self.constraints.sphere_diameter_mm;
        let observed: Option<Vec<nalgebra::Vector2<f64>>> = points
            .iter()
            .map(|p| {
                self.settings
                    .observation
                    .normalised(&pose.transform(p), radius_mm)
                    .ok()
            })
            .collect();
        let sigmas = point_sigmas(&self.settings.noise, scenario.sigma_px, images, point_sigma);
        let sigma = sigmas.iter().copied().fold(0.0, f64::max);
        let prediction = observed.and_then(|observed| {
            crate::identifiability::predict(
                &self.camera,
                pose,
                points,
                &observed,
                &sigmas,
                crate::identifiability::PREDICTION_GATE_SIGMAS * sigma,
            )
            .ok()
        });
        match prediction {
            Some(p) => (position, p.wrong_probability, p.margin_px),
            None => (position, 1.0, Some(0.0)),
        }
    }

    /// The identifiability figures of `values` (None when none is checked).
    fn identifiability_figures(&self, values: &ScenarioValues) -> Option<IdentifiabilityFigures> {
        let floor = self.identify_floor?;
        if self.identify_scope == IdentifyScope::Off {
            return None;
        }
        let max_wrong = 1.0 - floor.min_correct;
        let failing: Vec<&(usize, f64, Option<f64>)> = values
            .identified
            .iter()
            .filter(|(_, p, _)| *p > max_wrong)
            .collect();
        let allowed_failures = floor.allowed_failures(values.visible);
        let penalty = if failing.len() > allowed_failures {
            IDENTIFIABILITY_PENALTY
                * failing
                    .iter()
                    .map(|(_, p, _)| (p / max_wrong).log10())
                    .sum::<f64>()
        } else {
            0.0
        };
        Some(IdentifiabilityFigures {
            all_checked: self.identify_scope == IdentifyScope::All,
            checked: values.identified.len(),
            identifiable: values.identified.len() - failing.len(),
            allowed_failures,
            smallest_margin_px: values
                .identified
                .iter()
                .filter_map(|(_, _, m)| *m)
                .reduce(f64::min),
            failing: failing.iter().map(|(s, _, _)| *s).collect(),
            twins: failing
                .iter()
                .filter(|(_, _, m)| m.is_some_and(|m| m < crate::identifiability::TWIN_MARGIN_PX))
                .count(),
            penalty,
        })
    }

    /// The constraint penalty of `points` alone (tightened constraints,
    /// [`CONSTRAINT_PENALTY`] per mm): zero when they are met with margin.
    pub fn penalty(&self, points: &[Vector3<f64>]) -> f64 {
        CONSTRAINT_PENALTY * self.penalised.violations(points).total()
    }

    /// Scores a layout's points (with optional per-point σ from its file).
    pub fn evaluate(&self, points: &[Vector3<f64>], point_sigma: &[Option<f64>]) -> Evaluation {
        let values = self.values(points, point_sigma);
        let w_t = self.settings.translation_weight;
        let mut accuracy = 0.0;
        let mut terms = Vec::with_capacity(values.per_term.len());
        let (scored, common) = values.common();
        for ((((term, weight), (mut rotation, mut translation)), (r0, t0)), (evaluated, failed)) in
            self.settings
                .objective
                .terms
                .iter()
                .zip(common)
                .zip(&self.reference)
                .zip(
                    values
                        .per_term
                        .iter()
                        .map(|t| t.iter().flatten().count())
                        .zip(&values.failed),
                )
        {
            let r = self.settings.aggregate.apply(&mut rotation);
            let t = self.settings.aggregate.apply(&mut translation);
            accuracy += weight
                * match (r, t) {
                    (Some(r), Some(t)) => (r / r0 + w_t * t / t0) / (1.0 + w_t),
                    _ => UNMEASURABLE_COST,
                };
            terms.push(TermValue {
                term: *term,
                rotation_deg: r,
                translation_mm: t,
                evaluated,
                failed: *failed,
            });
        }
        let scenarios = self.scenarios.len().max(1) as f64;
        let availability = values.visible as f64 / scenarios;
        let soft_availability = values.soft_visible / scenarios;
        let violations = self.constraints.violations(points);
        let objective = accuracy + self.settings.availability_weight * (1.0 - soft_availability);
        let floor_penalty = self.floor_penalty(availability, soft_availability);
        let identifiability = self.identifiability_figures(&values);
        let identify_penalty = identifiability.as_ref().map_or(0.0, |f| f.penalty);
        let cross_penalty = self.cross.as_ref().map_or(0.0, |rule| rule.penalty(points));
        Evaluation {
            cost: objective
                + self.penalty(points)
                + floor_penalty
                + identify_penalty
                + cross_penalty,
            objective,
            accuracy,
            terms,
            availability,
            soft_availability,
            visible: values.visible,
            in_front: values.in_front,
            occluded: values.occluded,
            outside: values.outside,
            behind: values.behind,
            scored,
            unusable_noise: values.unusable_noise,
            availability_floor: self.floor,
            floor_penalty,
            violations,
            identifiability,
            cross_penalty,
        }
    }

    /// The floor's exact penalty: zero when `availability` reaches the floor,
    /// otherwise [`AVAILABILITY_PENALTY`] times the exact shortfall plus the
    /// soft one (the slope back to the feasible side).
    fn floor_penalty(&self, availability: f64, soft_availability: f64) -> f64 {
        match self.floor {
            Some(floor) if availability + 1e-12 < floor => {
                AVAILABILITY_PENALTY
                    * ((floor - availability) + (floor - soft_availability).max(0.0))
            }
            _ => 0.0,
        }
    }
}

#[cfg(test)]
mod tests;
