//! Comparing designs on the same scenarios and noise draws: the search
//! winner against its start, the paper's biprism in the same envelope and
//! simple hand designs, by the search objective and by Monte-Carlo runs of a
//! real solver on two seeds (the search's, and an independent one).

use super::{Evaluation, Evaluator};
use crate::camera::Camera;
use crate::family::{Envelope, SPREAD_DIRECTIONS};
use crate::layout::{Layout, LayoutPoint};
use crate::montecarlo::{
    self, MonteCarloConfig, MonteCarloError, ScenarioOutcome, Target, DEFAULT_GROSS_THRESHOLD_DEG,
};
use crate::noise::NoiseModel;
use crate::pnp::Solver;
use nalgebra::Vector3;
use serde::Serialize;
use std::sync::atomic::AtomicBool;

/// Monte-Carlo figures of one design on one seed.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct MonteCarloFigures {
    /// The seed of the noise draws.
    pub seed: u64,
    /// Pooled over every scenario with all spheres in front (the same
    /// scenarios for every design unless one reaches behind the camera).
    pub all: PooledFigures,
    /// Pooled over the design's own visible scenarios.
    pub visible: PooledFigures,
    /// Pooled over the scenarios visible to both this design and the winner.
    pub common: PooledFigures,
    /// The winner pooled over the same common scenarios.
    pub winner_common: PooledFigures,
}

/// Pooled Monte-Carlo errors over a set of scenarios.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PooledFigures {
    /// Scenarios pooled.
    pub scenarios: usize,
    /// RMS rotation error, degrees.
    pub rms_rotation_deg: f64,
    /// RMS translation error, mm.
    pub rms_translation_mm: f64,
    /// RMS translation error, %.
    pub rms_translation_percent: f64,
    /// Worst RMS rotation error over the depths, degrees.
    pub worst_depth_rms_rotation_deg: f64,
    /// Gross failures.
    pub gross_failures: usize,
}

impl PooledFigures {
    fn of<'a>(outcomes: impl Iterator<Item = &'a ScenarioOutcome> + Clone) -> PooledFigures {
        let mut depths: Vec<f64> = outcomes.clone().map(|o| o.scenario.depth_mm).collect();
        depths.sort_by(f64::total_cmp);
        depths.dedup();
        let worst = depths
            .iter()
            .filter_map(|&d| {
                montecarlo::pool(outcomes.clone().filter(|o| o.scenario.depth_mm == d), 0)
            })
            .map(|p| p.rms_rotation_deg)
            .fold(0.0, f64::max);
        match montecarlo::pool(outcomes, 0) {
            Some(p) => PooledFigures {
                scenarios: p.scenarios,
                rms_rotation_deg: p.rms_rotation_deg,
                rms_translation_mm: p.rms_translation_mm,
                rms_translation_percent: p.rms_translation_percent,
                worst_depth_rms_rotation_deg: worst,
                gross_failures: p.gross_failures,
            },
            None => PooledFigures {
                scenarios: 0,
                rms_rotation_deg: f64::NAN,
                rms_translation_mm: f64::NAN,
                rms_translation_percent: f64::NAN,
                worst_depth_rms_rotation_deg: f64::NAN,
                gross_failures: 0,
            },
        }
    }
}

/// One design's row of the comparison.
#[derive(Debug, Clone, Serialize)]
pub struct DesignRow {
    /// Design name.
    pub name: String,
    /// Its layout.
    #[serde(skip)]
    pub layout: Layout,
    /// The search objective's evaluation.
    pub evaluation: Evaluation,
    /// Monte-Carlo on the search seed and on the validation seed.
    pub monte_carlo: Vec<MonteCarloFigures>,
    /// Where one image cannot identify its spheres, in words (None when
    /// identifiability is not checked).
    pub not_identifiable: Option<String>,
}

/// Where a design cannot be identified: the visible scenarios that fail the
/// criterion, as the values of each axis at which they occur.
pub fn where_not_identifiable(
    figures: &super::IdentifiabilityFigures,
    scenarios: &[crate::scenario::Scenario],
) -> String {
    if figures.failing.is_empty() {
        return format!("identifiable in all {} visible scenarios", figures.checked);
    }
    let twins = if figures.twins > 0 {
        format!(
            "; {} of them symmetric (a wrong labelling fits the noise-free image to within {} px)",
            figures.twins,
            crate::identifiability::TWIN_MARGIN_PX
        )
    } else {
        String::new()
    };
    if figures.failing.len() == figures.checked {
        return format!(
            "not identifiable in any of its {} visible scenarios{twins}",
            figures.checked
        );
    }
    let failing: Vec<&crate::scenario::Scenario> = figures
        .failing
        .iter()
        .filter_map(|&k| scenarios.get(k))
        .collect();
    type Axis = (
        &'static str,
        &'static str,
        fn(&crate::scenario::Scenario) -> f64,
    );
    let axes: [Axis; 7] = [
        ("depth", "mm", |s| s.depth_mm),
        ("offset x", "mm", |s| s.offset_x_mm),
        ("offset y", "mm", |s| s.offset_y_mm),
        ("tilt", "°", |s| s.tilt_deg),
        ("pan", "°", |s| s.pan_deg),
        ("roll", "°", |s| s.roll_deg),
        ("σ", "px", |s| s.sigma_px),
    ];
    let mut parts = Vec::new();
    for (name, unit, value) in axes {
        let all: Vec<f64> = scenarios.iter().map(value).collect();
        let mut distinct: Vec<f64> = failing.iter().map(|s| value(s)).collect();
        distinct.sort_by(f64::total_cmp);
        distinct.dedup();
        let mut every: Vec<f64> = all;
        every.sort_by(f64::total_cmp);
        every.dedup();
        if every.len() > 1 && distinct.len() < every.len() {
            let values: Vec<String> = distinct.iter().map(|v| v.to_string()).collect();
            parts.push(format!("{name} {} {unit}", values.join(", ")));
        }
    }
    format!(
        "not identifiable in {} of {} visible scenarios{}{twins}",
        figures.failing.len(),
        figures.checked,
        if parts.is_empty() {
            String::new()
        } else {
            format!(", at {}", parts.join("; "))
        }
    )
}

/// The hand designs every search report includes, in `envelope` with spheres
/// of `sphere_diameter_mm`: the paper's biprism scaled to the envelope, seven
/// corners of the envelope box, and a regular tetrahedron (inscribed in the
/// box) with its centre.
pub fn hand_designs(envelope: &Envelope, sphere_diameter_mm: f64) -> Vec<Layout> {
    let h = envelope.half();
    let make = |name: &str, points: Vec<(String, Vector3<f64>)>| Layout {
        name: name.to_string(),
        points: points
            .into_iter()
            .map(|(n, p)| LayoutPoint::new(n, p))
            .collect(),
        sphere_diameter_mm,
        family: None,
        provenance: Some(
            serde_json::json!({"source": "hand design included in every search report"}),
        ),
    };
    let biprism = crate::synthetic::biprism(1.0)
        .into_iter()
        .map(|(n, p)| (n, p.component_mul(&h)))
        .collect();
    // Box directions scaled to the envelope, named prefix1, prefix2, …
    let scaled = |prefix: &str, directions: &[[f64; 3]]| -> Vec<(String, Vector3<f64>)> {
        directions
            .iter()
            .enumerate()
            .map(|(i, c)| {
                (
                    format!("{prefix}{}", i + 1),
                    Vector3::new(c[0], c[1], c[2]).component_mul(&h),
                )
            })
            .collect()
    };
    let corners = scaled(
        "C",
        &[
            [1.0, 1.0, 1.0],
            [1.0, 1.0, -1.0],
            [1.0, -1.0, 1.0],
            [1.0, -1.0, -1.0],
            [-1.0, 1.0, 1.0],
            [-1.0, 1.0, -1.0],
            [-1.0, -1.0, 1.0],
        ],
    );
    let mut tetrahedron = scaled("V", &SPREAD_DIRECTIONS[..4]);
    tetrahedron.push(("C".into(), Vector3::zeros()));
    vec![
        make("paper-biprism", biprism),
        make("seven-cube-corners", corners),
        make("tetrahedron-with-centre", tetrahedron),
    ]
}

/// What a comparison reports while it runs, and how it is stopped.
pub struct CompareProgress<'a> {
    /// Called (from worker threads) after each scenario of each design and
    /// seed.
    pub on_scenario_done: &'a (dyn Fn() + Sync),
    /// Ends the comparison early ([`MonteCarloError::Interrupted`]).
    pub stop: &'a AtomicBool,
}

fn figures(seed: u64, mine: &[ScenarioOutcome], winner: &[ScenarioOutcome]) -> MonteCarloFigures {
    let visible = |o: &&ScenarioOutcome| o.visibility.is_visible();
    let common: Vec<bool> = mine
        .iter()
        .zip(winner)
        .map(|(a, b)| a.visibility.is_visible() && b.visibility.is_visible())
        .collect();
    MonteCarloFigures {
        seed,
        all: PooledFigures::of(mine.iter().filter(|o| o.visibility.all_in_front())),
        visible: PooledFigures::of(mine.iter().filter(visible)),
        common: PooledFigures::of(
            mine.iter()
                .zip(&common)
                .filter(|(_, c)| **c)
                .map(|(o, _)| o),
        ),
        winner_common: PooledFigures::of(
            winner
                .iter()
                .zip(&common)
                .filter(|(_, c)| **c)
                .map(|(o, _)| o),
        ),
    }
}

/// What [`compare`] compares, and how.
#[derive(Debug, Clone, Copy)]
pub struct Comparison<'a> {
    /// The simulated camera.
    pub camera: &'a Camera,
    /// Scores each design by the search objective (its scenarios are the
    /// Monte-Carlo's).
    pub evaluator: &'a Evaluator,
    /// The designs by name; the first is the winner the others are paired
    /// with.
    pub designs: &'a [(String, Layout)],
    /// Solver of the Monte-Carlo runs.
    pub solver: Solver,
    /// Trials per scenario.
    pub trials: usize,
    /// One Monte-Carlo run per seed.
    pub seeds: &'a [u64],
    /// Pixel noise model.
    pub noise: NoiseModel,
}

/// Scores every design by the objective and by Monte-Carlo on each seed.
/// `designs[0]` is the winner the others are paired with. It runs
/// `designs.len() × seeds.len() × scenarios` Monte-Carlo scenarios, each
/// reported to `progress`, and stops early once `progress.stop` is set.
pub fn compare(
    comparison: &Comparison<'_>,
    progress: &CompareProgress<'_>,
) -> Result<Vec<DesignRow>, MonteCarloError> {
    let Comparison {
        camera,
        evaluator,
        designs,
        solver,
        trials,
        seeds,
        noise,
    } = *comparison;
    let outcomes: Vec<Vec<Vec<ScenarioOutcome>>> = designs
        .iter()
        .map(|(_, layout)| {
            seeds
                .iter()
                .map(|&seed| {
                    let object = layout.positions();
                    let sigmas = layout.point_sigmas();
                    let target = Target {
                        camera,
                        object: &object,
                        sphere_diameter_mm: layout.sphere_diameter_mm,
                        point_sigma_px: &sigmas,
                    };
                    let config = MonteCarloConfig {
                        trials,
                        seed,
                        solvers: vec![solver],
                        noise,
                        gross_threshold_deg: DEFAULT_GROSS_THRESHOLD_DEG,
                        observation: evaluator.settings().observation,
                    };
                    montecarlo::run_until(
                        &target,
                        evaluator.scenarios(),
                        &config,
                        &|_| (progress.on_scenario_done)(),
                        progress.stop,
                    )
                })
                .collect::<Result<Vec<_>, _>>()
        })
        .collect::<Result<_, _>>()?;
    Ok(designs
        .iter()
        .zip(&outcomes)
        .map(|((name, layout), mine)| {
            let sigmas = layout.point_sigmas();
            let evaluation = evaluator.evaluate(&layout.positions(), &sigmas);
            DesignRow {
                name: name.clone(),
                layout: layout.clone(),
                not_identifiable: evaluation
                    .identifiability
                    .as_ref()
                    .map(|f| where_not_identifiable(f, evaluator.scenarios())),
                evaluation,
                monte_carlo: seeds
                    .iter()
                    .enumerate()
                    .map(|(k, &seed)| figures(seed, &mine[k], &outcomes[0][k]))
                    .collect(),
            }
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hand_designs_are_valid_layouts() {
        let envelope = Envelope::new([100.0; 3]).unwrap();
        let designs = hand_designs(&envelope, 10.0);
        assert_eq!(designs.len(), 3);
        for layout in &designs {
            layout.validate().unwrap();
        }
        assert_eq!(
            designs[0].positions(),
            crate::synthetic::biprism_points(50.0)
        );
        assert_eq!(designs[1].points.len(), 7);
        assert_eq!(designs[2].points.len(), 5);
    }
}
