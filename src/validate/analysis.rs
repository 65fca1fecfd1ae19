//! The validation itself: a checked [`ValidateConfig`] in, a
//! [`ValidateSummary`] out. No files and no printing; progress and
//! interruption go through an [`Observer`].
//!
//! Three Monte-Carlo runs over the grid: the solvers on noisy images
//! ([`crate::montecarlo`]), the unlabelled solver on shuffled blobs of the
//! visible scenarios ([`crate::identifiability`]), and, when σ_fab > 0, a new
//! perturbed part per trial ([`crate::error_model::fabrication`]). Statistics
//! pool the *visible* scenarios (every sphere in front, inside the image and
//! unoccluded): those are the images a detector would deliver. Scenarios
//! that break a visibility rule are counted and kept, with their errors, in
//! the summary's outcomes.

use super::config::{Checked, ValidateConfig};
use super::summary::{
    axis_unit, describe_scenario, occluded_pairs, visible, AxisErrors, AxisVisibility, Curve,
    CurveSolver, Header, IdentifiabilityCurve, IdentifiabilitySummary, Overview, SolverRow,
    Systematic, ValidateSummary, VisibilityClass, VisibilityCounts,
};
use crate::config::ConfigError;
use crate::error_model::budget::{self, Budget, BudgetError, BudgetInputs};
use crate::identifiability::{self, IdentifiabilitySettings, ScenarioIdentifiability};
use crate::layout::Layout;
use crate::montecarlo::{
    self, median, MonteCarloConfig, MonteCarloError, Pooled, PoseErrorVector, ScenarioOutcome,
    Target,
};
use crate::observer::{relay, watch, Observer};
use crate::pnp::parallel::reference_index;
use crate::report::significant;
use crate::visibility::{support_fractions, MaxHidden, Supports, WorkingRange};
use crate::volume::{VolumeAxis, WorkingVolume};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

/// Why a validation's analysis could not run.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ValidateError {
    /// A configuration value is unusable.
    #[error("invalid validation settings: {0}")]
    Config(#[from] ConfigError),
    /// The Monte-Carlo run failed or was interrupted.
    #[error(transparent)]
    MonteCarlo(#[from] MonteCarloError),
    /// The error budget's Monte-Carlo check failed or was interrupted.
    #[error(transparent)]
    Budget(#[from] BudgetError),
    /// The image-level check failed or was interrupted.
    #[error(transparent)]
    Images(#[from] super::image_check::ImageCheckError),
    /// The part's supports cannot be built for the layout.
    #[error("the part's supports cannot be built: {0}")]
    Supports(#[from] crate::mesh::GeometryError),
}

/// Progress phase of the Monte-Carlo runs: one step per scenario for the
/// solvers, then one per scenario for identifiability.
pub const PHASE: &str = "validating";

/// How a caller that runs [`monte_carlo_until`] inside its own progress
/// display hears of it and stops it.
#[derive(Clone, Copy)]
pub struct Hooks<'a> {
    /// Called with the scenarios done so far: the Monte-Carlo scenarios,
    /// then the identifiability scenarios after them (twice the grid in
    /// all).
    pub on_scenario_done: &'a (dyn Fn(usize) + Sync),
    /// Once set, the run ends within a trial with
    /// [`MonteCarloError::Interrupted`].
    pub stop: &'a AtomicBool,
}

/// The whole validation of `config`: checks it, then runs
/// [`monte_carlo`] and [`error_budget`]. An observer that asks to stop ends
/// the run within a trial with `MonteCarlo(Interrupted)` or
/// `Budget(Interrupted)`.
pub fn analyse(
    config: &ValidateConfig,
    observer: &mut impl Observer,
) -> Result<ValidateSummary, ValidateError> {
    let config = config.check()?;
    let mut summary = monte_carlo(config, observer)?;
    add_budget(&mut summary, error_budget(config, observer)?);
    Ok(summary)
}

/// The solvers' and the unlabelled solver's Monte-Carlo runs, pooled, with
/// progress as [`PHASE`] (no error budget: `budget` is None).
pub fn monte_carlo(
    config: Checked,
    observer: &mut impl Observer,
) -> Result<ValidateSummary, ValidateError> {
    let done = AtomicU64::new(0);
    let stop = AtomicBool::new(false);
    watch(
        observer,
        PHASE,
        2 * config.volume.len() as u64,
        || done.load(Ordering::Relaxed),
        Some(&stop),
        || {
            monte_carlo_until(
                config,
                Hooks {
                    on_scenario_done: &|finished| done.store(finished as u64, Ordering::Relaxed),
                    stop: &stop,
                },
            )
        },
    )
}

/// [`monte_carlo`] for a caller with its own progress display (the
/// search's validation of its winner).
pub fn monte_carlo_until(config: Checked, hooks: Hooks) -> Result<ValidateSummary, ValidateError> {
    let layout = &config.layout;
    let monte_carlo = &config.monte_carlo;
    let object = layout.positions();
    let sigmas = layout.point_sigmas();
    let target = Target {
        camera: &config.camera,
        object: &object,
        sphere_diameter_mm: layout.sphere_diameter_mm,
        point_sigma_px: &sigmas,
    };
    let scenarios = config.volume.scenarios(&config.camera);
    let axes = config.volume.axes(&scenarios);
    let max_hidden = config.max_hidden()?;
    let supports = match &config.structure {
        Some(options) => {
            let range = WorkingRange {
                camera: config.camera,
                scenarios: scenarios.clone(),
                max_hidden,
            };
            Some(crate::mesh::supports_for_range(layout, options, &range)?)
        }
        None => None,
    };
    let mut outcomes = montecarlo::run_until(
        &target,
        &scenarios,
        monte_carlo,
        hooks.on_scenario_done,
        hooks.stop,
    )?;
    if let Some(supports) = &supports {
        count_supports(&mut outcomes, &config, supports, max_hidden);
    }
    let settings = IdentifiabilitySettings {
        min_correct: config.identifiability.min_correct,
        trials: config.identifiability.trials,
        seed: monte_carlo.seed,
        observation: monte_carlo.observation,
        noise: monte_carlo.noise,
    };
    let visible_at: Vec<bool> = outcomes.iter().map(visible).collect();
    let identified = identifiability::run_until(
        &target,
        &scenarios,
        &settings,
        &|s| visible_at.get(s.index).copied().unwrap_or(false),
        &|done| (hooks.on_scenario_done)(scenarios.len() + done),
        hooks.stop,
    )
    .ok_or(MonteCarloError::Interrupted)?;
    let overview = Overview {
        header: header(&config, &object),
        visibility: visibility_counts(
            supports.is_some().then_some(max_hidden.fraction()),
            layout,
            &axes,
            &outcomes,
        ),
        solvers: solver_rows(&outcomes, monte_carlo.solvers.len()),
        curves: curves(&axes, &outcomes, monte_carlo),
        systematic: systematic(&outcomes, monte_carlo),
        identifiability: identifiability_summary(&axes, &outcomes, &identified, &settings),
        pairs: super::pairs::pairwise(&axes, &outcomes, monte_carlo.solvers[0].name()),
        worst: super::pairs::worst(&outcomes),
        error_budget: None,
    };
    Ok(ValidateSummary {
        layout: layout.clone(),
        overview,
        outcomes,
        identifiability: identified,
        budget: None,
        images: None,
    })
}

/// Marks, in every scenario that is otherwise visible, the spheres that
/// `supports` hide beyond `max_hidden` ([`Visibility::hidden_by_support`]),
/// so that such a scenario counts as not seen, as one with a sphere behind
/// another does. In parallel; the result does not depend on the thread
/// count.
///
/// [`Visibility::hidden_by_support`]: crate::scenario::Visibility::hidden_by_support
fn count_supports(
    outcomes: &mut [ScenarioOutcome],
    config: &ValidateConfig,
    supports: &Supports,
    max_hidden: MaxHidden,
) {
    use rayon::prelude::*;
    let centres = config.layout.positions();
    let radius_mm = 0.5 * config.layout.sphere_diameter_mm;
    outcomes
        .par_iter_mut()
        .filter(|o| o.visibility.is_visible())
        .for_each(|o| {
            let fractions = support_fractions(
                &config.camera,
                &o.scenario.pose(),
                &centres,
                radius_mm,
                supports,
            );
            o.visibility.hidden_by_support = fractions
                .iter()
                .enumerate()
                .filter(|(_, f)| **f > max_hidden.fraction())
                .map(|(k, _)| k)
                .collect();
        });
}

/// The error budget (None when only image noise counts: no part error
/// and no camera σ): in every visible scenario, each source's first-order
/// pose covariance beside a Monte-Carlo run of each source alone and of
/// all together, with the first solver and the run's trials and noise
/// model ([`budget`]).
pub fn error_budget(
    config: Checked,
    observer: &mut impl Observer,
) -> Result<Option<Budget>, ValidateError> {
    let part = config.part_error();
    if part.is_exact() && config.camera_sigma.is_zero() {
        return Ok(None);
    }
    let object = config.layout.positions();
    let layout_sigmas = config.layout.point_sigmas();
    let inputs = BudgetInputs {
        camera: &config.camera,
        object: &object,
        layout_sigmas: &layout_sigmas,
        sphere_diameter_mm: config.layout.sphere_diameter_mm,
        noise: &config.monte_carlo.noise,
        part: &part,
        camera_sigma: config.camera_sigma,
        trials: config.monte_carlo.trials,
        seed: config.monte_carlo.seed,
        solver: config.monte_carlo.solvers[0],
    };
    let scenarios = config.volume.scenarios(&config.camera);
    let stop = AtomicBool::new(false);
    let run = relay(
        observer,
        |_| {},
        Some(&stop),
        || budget::budget(&inputs, &scenarios, &|| stop.load(Ordering::Relaxed)),
    );
    Ok(Some(run?))
}

/// Puts a budget into the summary and its overview.
pub fn add_budget(summary: &mut ValidateSummary, budget: Option<Budget>) {
    summary.overview.error_budget = budget.as_ref().map(Budget::overview);
    summary.budget = budget;
}

/// Where every number came from.
fn header(config: &ValidateConfig, object: &[nalgebra::Vector3<f64>]) -> Header {
    let (layout, monte_carlo) = (&config.layout, &config.monte_carlo);
    Header {
        command: config.command.clone(),
        version: env!("CARGO_PKG_VERSION").to_string(),
        seed: monte_carlo.seed,
        trials_per_scenario: monte_carlo.trials,
        solvers: monte_carlo
            .solvers
            .iter()
            .map(|s| s.name().to_string())
            .collect(),
        noise_model: monte_carlo.noise.describe(),
        gross_threshold_deg: monte_carlo.gross_threshold_deg,
        camera: config.camera,
        layout: layout.name.clone(),
        sphere_diameter_mm: layout.sphere_diameter_mm,
        observation: monte_carlo.observation.name().to_string(),
        reference_point: layout.points[reference_index(object)].name.clone(),
        volume: config.volume.clone(),
        grid: match &config.volume {
            WorkingVolume::Grid(grid) => Some(grid.clone()),
            WorkingVolume::Sampled(_) => None,
        },
        sampled_volume: match &config.volume {
            WorkingVolume::Sampled(volume) => Some(*volume),
            WorkingVolume::Grid(_) => None,
        },
        volume_text: config.volume.describe(),
    }
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
    axes: &[VolumeAxis],
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
    let curves = axes
        .iter()
        .map(|axis| {
            let groups: Vec<Vec<&(&ScenarioOutcome, &ScenarioIdentifiability)>> =
                (0..axis.values.len())
                    .map(|bin| {
                        pairs
                            .iter()
                            .filter(|(o, _)| axis.bin(&o.scenario) == Some(bin))
                            .collect()
                    })
                    .collect();
            let per_value: Vec<_> = groups.iter().map(|g| (g.len(), stats(g))).collect();
            IdentifiabilityCurve {
                axis: axis.name.to_string(),
                unit: axis_unit(axis.name).to_string(),
                values: axis.values.clone(),
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

fn class_index(class: VisibilityClass) -> usize {
    match class {
        VisibilityClass::Visible => 0,
        VisibilityClass::Occluded => 1,
        VisibilityClass::OutsideImage => 2,
        VisibilityClass::BehindCamera => 3,
        VisibilityClass::HiddenBySupport => 4,
    }
}

fn count_classes<'a>(outcomes: impl Iterator<Item = &'a ScenarioOutcome>) -> [usize; 5] {
    let mut counts = [0; 5];
    for o in outcomes {
        counts[class_index(VisibilityClass::of(&o.visibility))] += 1;
    }
    counts
}

fn visibility_counts(
    max_hidden: Option<f64>,
    layout: &Layout,
    axes: &[VolumeAxis],
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
    let by_axis = axes
        .iter()
        .map(|axis| AxisVisibility {
            axis: axis.name.to_string(),
            unit: axis_unit(axis.name).to_string(),
            values: axis.values.clone(),
            counts: (0..axis.values.len())
                .map(|bin| {
                    count_classes(
                        outcomes
                            .iter()
                            .filter(|o| axis.bin(&o.scenario) == Some(bin)),
                    )
                })
                .collect(),
        })
        .collect();
    let [visible, occluded, outside_image, behind_camera, hidden_by_support] =
        count_classes(outcomes.iter());
    VisibilityCounts {
        scenarios: outcomes.len(),
        visible,
        occluded,
        outside_image,
        behind_camera,
        hidden_by_support,
        max_hidden,
        availability: visible as f64 / outcomes.len().max(1) as f64,
        with_occlusion: with_occlusion.len(),
        occlusion_examples,
        by_axis,
    }
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

fn curves(
    axes: &[VolumeAxis],
    outcomes: &[ScenarioOutcome],
    config: &MonteCarloConfig,
) -> Vec<Curve> {
    axes.iter()
        .map(|axis| {
            let groups: Vec<Vec<&ScenarioOutcome>> = (0..axis.values.len())
                .map(|bin| {
                    outcomes
                        .iter()
                        .filter(|o| axis.bin(&o.scenario) == Some(bin))
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
                axis: axis.name.to_string(),
                unit: axis_unit(axis.name).to_string(),
                values: axis.values.clone(),
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::observer::Silent;
    use crate::pnp::Solver;
    use crate::scenario::Range;

    fn config() -> ValidateConfig {
        let mut config = ValidateConfig::new(Layout::paper_biprism(), vec![Solver::Ml]);
        config.volume = crate::volume::WorkingVolume::Grid(
            crate::scenario::ScenarioGrid::new(
                "300,600".parse().unwrap(),
                Range::single(0.0),
                Range::single(0.0),
                "-20,20".parse().unwrap(),
                Range::single(0.0),
                Range::single(0.0),
                Range::single(0.5),
            )
            .unwrap(),
        );
        config.monte_carlo.trials = 5;
        config.identifiability.trials = 2;
        config
    }

    #[test]
    fn the_error_budget_adds_to_the_summary_and_changes_nothing_else() {
        let plain = analyse(&config(), &mut Silent).unwrap();
        assert_eq!(plain.outcomes.len(), 4);
        assert_eq!(plain.identifiability.len(), 4);
        assert_eq!(plain.solves(), 4 * 5);
        assert!(plain.budget.is_none() && plain.overview.error_budget.is_none());
        let mut with = config();
        with.fabrication_sigma_mm = 0.1;
        let mut with = analyse(&with, &mut Silent).unwrap();
        let run = with.budget.as_ref().unwrap();
        assert_eq!((run.solver.as_str(), run.trials), ("ml", 5));
        let overview = with.overview.error_budget.take().unwrap();
        assert_eq!(
            overview.by_depth.iter().map(|r| r.scenarios).sum::<usize>(),
            run.outcomes.len()
        );
        assert_eq!(
            serde_json::to_string(&plain.overview).unwrap(),
            serde_json::to_string(&with.overview).unwrap()
        );
    }

    #[test]
    fn a_bad_config_is_refused_before_any_work() {
        let mut bad = config();
        bad.monte_carlo.solvers.clear();
        assert!(matches!(
            analyse(&bad, &mut Silent),
            Err(ValidateError::Config(e)) if e.field == "solvers"
        ));
    }
}
