//! Error against every pair of the volume's degrees of freedom, and the
//! worst viewpoints: part of the analysis, computed from the scenario
//! outcomes the Monte-Carlo run returned.
//!
//! Errors couple (tilt with offset, depth with roll), and a curve along one
//! axis averages the coupling away. For every pair of axes along which the
//! viewpoints vary, each cell of the pair's bins pools the first solver's
//! trials over the visible viewpoints that fall in it.

use super::summary::{
    axis_unit, describe_scenario, visible, PairAxis, PairPanel, PairwiseErrors, WorstViewpoint,
};
use crate::montecarlo::{self, ScenarioOutcome};
use crate::volume::VolumeAxis;

/// Viewpoints the worst-viewpoint list names ([`WorstViewpoint`]).
pub const WORST_VIEWPOINTS: usize = 10;

/// The pairwise errors of `outcomes` over `axes`, for the first solver.
pub fn pairwise(axes: &[VolumeAxis], outcomes: &[ScenarioOutcome], solver: &str) -> PairwiseErrors {
    let bins: Vec<Vec<Option<usize>>> = outcomes
        .iter()
        .map(|o| axes.iter().map(|a| a.bin(&o.scenario)).collect())
        .collect();
    let mut panels = Vec::new();
    for y in 0..axes.len() {
        for x in 0..y {
            let (columns, rows) = (axes[x].values.len(), axes[y].values.len());
            let mut members: Vec<Vec<Vec<&ScenarioOutcome>>> =
                vec![vec![Vec::new(); columns]; rows];
            for (outcome, at) in outcomes.iter().zip(&bins) {
                if let (Some(column), Some(row)) = (at[x], at[y]) {
                    members[row][column].push(outcome);
                }
            }
            let cell = |f: &dyn Fn(&[&ScenarioOutcome]) -> Option<f64>| -> Vec<Vec<Option<f64>>> {
                members
                    .iter()
                    .map(|row| row.iter().map(|c| f(c)).collect())
                    .collect()
            };
            panels.push(PairPanel {
                x,
                y,
                rms_rotation_deg: cell(&|c| {
                    montecarlo::pool(c.iter().copied().filter(|o| visible(o)), 0)
                        .map(|p| p.rms_rotation_deg)
                }),
                visible: members
                    .iter()
                    .map(|row| {
                        row.iter()
                            .map(|c| c.iter().filter(|o| visible(o)).count())
                            .collect()
                    })
                    .collect(),
                viewpoints: members
                    .iter()
                    .map(|row| row.iter().map(Vec::len).collect())
                    .collect(),
            });
        }
    }
    let range_deg = panels
        .iter()
        .flat_map(|p| p.rms_rotation_deg.iter().flatten().flatten())
        .fold(None, |range: Option<(f64, f64)>, &v| {
            Some(range.map_or((v, v), |(lo, hi)| (lo.min(v), hi.max(v))))
        });
    PairwiseErrors {
        solver: solver.to_string(),
        axes: axes
            .iter()
            .map(|a| PairAxis {
                axis: a.name.to_string(),
                unit: axis_unit(a.name).to_string(),
                values: a.values.clone(),
            })
            .collect(),
        panels,
        range_deg,
    }
}

/// The [`WORST_VIEWPOINTS`] visible viewpoints with the largest RMS
/// rotation error of the first solver, worst first (ties in volume order).
pub fn worst(outcomes: &[ScenarioOutcome]) -> Vec<WorstViewpoint> {
    let mut ranked: Vec<(&ScenarioOutcome, f64)> = outcomes
        .iter()
        .filter(|o| visible(o))
        .filter_map(|o| {
            let first = o.solvers.first()?;
            (first.rotation_deg.count > 0).then_some((o, first.rotation_deg.rms))
        })
        .collect();
    ranked.sort_by(|a, b| b.1.total_cmp(&a.1));
    ranked
        .into_iter()
        .take(WORST_VIEWPOINTS)
        .map(|(o, rms)| WorstViewpoint {
            scenario: o.scenario,
            description: describe_scenario(&o.scenario),
            rms_rotation_deg: rms,
            first_order_rotation_deg: o.first_order.map(|f| f.rms_rotation_deg),
        })
        .collect()
}
