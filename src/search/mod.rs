//! Layout search: the objective that scores a marker over a scenario grid,
//! and the argmin optimisers that minimise it ([`optimise`]).
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
//! The *objective* adds `w_a · (1 − availability)`, availability being the
//! fraction of scenarios with every sphere in front, inside the image and
//! unoccluded, so a layout cannot win by leaving the image or hiding spheres
//! more often. The objective counts each scenario's visibility softly, ramping
//! from 0 to 1 as its smallest visibility margin
//! ([`crate::scenario::visibility_margin_px`]) goes from −[`SOFT_MARGIN_PX`]
//! to +[`SOFT_MARGIN_PX`], so that optimisers see a slope rather than a
//! staircase of 0/1 steps; reports count visibility exactly. The *cost* the optimisers minimise adds
//! [`CONSTRAINT_PENALTY`] per mm of constraint violation.

pub mod checkpoint;
pub mod compare;
pub mod optimise;
pub mod pipeline;
pub mod report;

use crate::camera::Camera;
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
use nalgebra::Vector3;
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
    /// Monte-Carlo trials per scenario (for `mc:` terms).
    pub trials: usize,
    /// Seed of the common random numbers.
    pub seed: u64,
    /// Pixel noise model.
    pub noise: NoiseModel,
    /// What a sphere's image point is; with ellipse centres the `crlb` term
    /// carries the first-order pose bias, `√(rms² + bias²)`.
    pub observation: Observation,
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
    /// Scenarios the term could score.
    pub scenarios: usize,
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
    /// Constraint violations.
    pub violations: Violations,
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
    per_term: Vec<(Vec<f64>, Vec<f64>)>,
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
        let tighten = |value: f64| {
            if value > 0.0 {
                value * (1.0 + PENALTY_MARGIN_FRACTION) + PENALTY_MARGIN_MM
            } else {
                0.0
            }
        };
        // The envelope is not tightened: its excess is continuous and the
        // best layouts sit on it, so shrinking it would cost real accuracy.
        let penalised = Constraints {
            envelope: constraints.envelope,
            sphere_diameter_mm: constraints.sphere_diameter_mm,
            min_gap_mm: constraints.min_gap_mm * (1.0 + PENALTY_MARGIN_FRACTION)
                + PENALTY_MARGIN_MM,
            min_distance_diff_mm: tighten(constraints.min_distance_diff_mm),
        };
        let mut evaluator = Self {
            camera,
            scenarios,
            reference: vec![(1.0, 1.0); settings.objective.terms.len()],
            settings,
            constraints,
            penalised,
        };
        let raw = evaluator.values(reference, &vec![None; reference.len()]);
        evaluator.reference = raw
            .per_term
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

    fn values(&self, points: &[Vector3<f64>], point_sigma: &[Option<f64>]) -> ScenarioValues {
        let terms = &self.settings.objective.terms;
        let mut values = ScenarioValues {
            visible: 0,
            soft_visible: 0.0,
            in_front: 0,
            occluded: 0,
            outside: 0,
            behind: 0,
            per_term: vec![(Vec::new(), Vec::new()); terms.len()],
        };
        let needs_models = terms
            .iter()
            .any(|(t, _)| matches!(t, Term::Crlb | Term::Transfer));
        let reference = reference_index(points);
        let mut in_front_flags = Vec::with_capacity(self.scenarios.len());
        let mut image_bias = Vec::with_capacity(points.len());
        for scenario in &self.scenarios {
            let pose = scenario.pose();
            let images = sphere_images(
                &self.camera,
                &pose,
                points,
                self.constraints.sphere_diameter_mm,
            );
            let v = visibility(&images, &self.camera);
            values.occluded += usize::from(!v.occluded.is_empty());
            values.outside += usize::from(!v.outside.is_empty());
            values.behind += usize::from(!v.behind.is_empty());
            values.visible += usize::from(v.is_visible());
            let margin = visibility_margin_px(&images, &self.camera);
            values.soft_visible += (0.5 + margin / (2.0 * SOFT_MARGIN_PX)).clamp(0.0, 1.0);
            let in_front = v.all_in_front();
            in_front_flags.push(in_front);
            if !in_front {
                continue;
            }
            values.in_front += 1;
            if !needs_models {
                continue;
            }
            let sigmas = point_sigmas(
                &self.settings.noise,
                scenario.sigma_px,
                &images,
                point_sigma,
            );
            if !sigmas.iter().all(|s| *s > 0.0) {
                continue;
            }
            for ((term, _), (rotation, translation)) in terms.iter().zip(values.per_term.iter_mut())
            {
                match term {
                    Term::Crlb => match self.settings.observation {
                        Observation::Centre => {
                            if let Ok(c) = pose_covariance(&self.camera, &pose, points, &sigmas) {
                                rotation.push(c.rms_rotation_deg());
                                translation.push(c.rms_translation_mm());
                            }
                        }
                        Observation::EllipseCentre => {
                            let radius_mm = 0.5 * self.constraints.sphere_diameter_mm;
                            if ellipse_centre_bias_px_into(
                                &self.camera,
                                &pose,
                                points,
                                radius_mm,
                                &mut image_bias,
                            )
                            .is_err()
                            {
                                continue;
                            }
                            if let Ok((Some(c), bias)) = pose_covariance_and_bias(
                                &self.camera,
                                &pose,
                                points,
                                &sigmas,
                                &image_bias,
                            ) {
                                rotation.push(c.rms_rotation_deg().hypot(bias.rotation_deg()));
                                translation
                                    .push(c.rms_translation_mm().hypot(bias.translation_norm_mm()));
                            }
                        }
                    },
                    Term::Transfer => {
                        let p = transfer::predict(&self.camera, &pose, points, reference, &sigmas);
                        if let (Some(r), Some(t)) = (p.rms_rotation_deg, p.rms_translation_mm) {
                            rotation.push(r);
                            translation.push(t);
                        }
                    }
                    Term::MonteCarlo(_) => {}
                }
            }
        }
        for ((term, _), (rotation, translation)) in terms.iter().zip(values.per_term.iter_mut()) {
            let Term::MonteCarlo(solver) = term else {
                continue;
            };
            let in_front: Vec<Scenario> = self
                .scenarios
                .iter()
                .zip(&in_front_flags)
                .filter(|(_, v)| **v)
                .map(|(s, _)| *s)
                .collect();
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
                observation: self.settings.observation,
            };
            if let Ok(outcomes) = montecarlo::run(&target, &in_front, &config, &|_| {}) {
                for outcome in outcomes {
                    if let Some(result) =
                        outcome.solvers.first().filter(|r| r.rotation_deg.count > 0)
                    {
                        rotation.push(result.rotation_deg.rms);
                        translation.push(result.translation_mm.rms);
                    }
                }
            }
        }
        values
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
        for (((term, weight), (mut rotation, mut translation)), (r0, t0)) in self
            .settings
            .objective
            .terms
            .iter()
            .zip(values.per_term)
            .zip(&self.reference)
        {
            let scenarios = rotation.len();
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
                scenarios,
            });
        }
        let scenarios = self.scenarios.len().max(1) as f64;
        let availability = values.visible as f64 / scenarios;
        let soft_availability = values.soft_visible / scenarios;
        let violations = self.constraints.violations(points);
        let objective = accuracy + self.settings.availability_weight * (1.0 - soft_availability);
        Evaluation {
            cost: objective + self.penalty(points),
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
            violations,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::family::Envelope;
    use crate::scenario::{Range, ScenarioGrid};

    fn evaluator(objective: &str) -> Evaluator {
        let grid = ScenarioGrid::new(
            Range::list(&[300.0, 700.0]),
            Range::list(&[0.0, 60.0]),
            Range::single(0.0),
            Range::list(&[-40.0, 0.0, 40.0]),
            Range::single(0.0),
            Range::single(0.0),
            Range::single(0.5),
        )
        .unwrap();
        Evaluator::new(
            Camera::paper(),
            grid.scenarios(),
            ObjectiveSettings {
                objective: objective.parse().unwrap(),
                aggregate: Aggregate::Mean,
                translation_weight: 0.5,
                availability_weight: 2.0,
                trials: 20,
                seed: 1,
                noise: NoiseModel::default(),
                observation: Observation::default(),
            },
            Constraints {
                envelope: Envelope::new([100.0; 3]).unwrap(),
                sphere_diameter_mm: 10.0,
                min_gap_mm: 2.0,
                min_distance_diff_mm: 0.0,
            },
            &crate::synthetic::biprism_points(50.0),
        )
    }

    #[test]
    fn the_reference_scores_one() {
        for objective in [
            "crlb",
            "transfer",
            "mc:ml",
            "crlb:0.5+mc:parallel-weighted:0.5",
        ] {
            let e = evaluator(objective);
            let score = e.evaluate(&crate::synthetic::biprism_points(50.0), &[None; 7]);
            let weights: f64 = e.settings().objective.terms.iter().map(|(_, w)| w).sum();
            assert!(
                (score.accuracy - weights).abs() < 1e-12,
                "{objective}: {}",
                score.accuracy
            );
        }
    }

    #[test]
    fn a_smaller_marker_scores_worse() {
        let e = evaluator("crlb");
        let small: Vec<_> = crate::synthetic::biprism_points(25.0);
        let score = e.evaluate(&small, &[None; 7]);
        assert!(score.accuracy > 1.5, "{}", score.accuracy);
    }

    #[test]
    fn objectives_parse() {
        assert_eq!(
            "crlb".parse::<Objective>().unwrap().terms,
            vec![(Term::Crlb, 1.0)]
        );
        assert_eq!(
            "mc:ml:0.3+transfer:0.7".parse::<Objective>().unwrap().terms,
            vec![(Term::MonteCarlo(Solver::Ml), 0.3), (Term::Transfer, 0.7)]
        );
        assert_eq!(
            "mc".parse::<Objective>().unwrap().terms,
            vec![(Term::MonteCarlo(Solver::ParallelWeighted), 1.0)]
        );
        assert!("mc:nope".parse::<Objective>().is_err());
        assert_eq!(
            "crlb:-1".parse::<Objective>().unwrap_err(),
            ObjectiveError::BadWeight(-1.0)
        );
        assert_eq!(
            "crlb:0.5+mc:ml:0.5"
                .parse::<Objective>()
                .unwrap()
                .to_string(),
            "crlb:0.5+mc:ml:0.5"
        );
    }

    #[test]
    fn aggregates() {
        assert_eq!(Aggregate::Max.apply(&mut [1.0, 3.0, 2.0]), Some(3.0));
        assert_eq!(
            Aggregate::Mean.apply(&mut [3.0, 4.0]),
            Some((12.5f64).sqrt())
        );
        assert_eq!(Aggregate::P95.apply(&mut [1.0, 2.0]), Some(2.0));
        assert_eq!(Aggregate::Mean.apply(&mut []), None);
    }
}
