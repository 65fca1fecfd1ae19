//! What a search found, as the report shows it: its provenance
//! ([`SearchHeader`]), one row per design compared, the verdicts the
//! acceptance criteria ask about, the held-out check and the books of the
//! identifiability repair. Built by the analysis, rendered by the report;
//! every type serialises to `summary.json`.

use super::compare::DesignRow;
use super::front::FrontReport;
use super::optimise::{OptimiseOutcome, SearchSettings};
use super::{Evaluation, IdentifiabilityFigures, IdentifiabilityFloor, ObjectiveSettings};
use crate::camera::Camera;
use crate::family::Constraints;
use crate::scenario::ScenarioGrid;
use crate::volume::WorkingVolume;
use nalgebra::Vector3;
use serde::Serialize;

/// Provenance of a search.
#[derive(Debug, Clone, Serialize)]
pub struct SearchHeader {
    /// The command line.
    pub command: String,
    /// Where the winning layout was written (as the command named it).
    pub layout_path: std::path::PathBuf,
    /// layout-opt version.
    pub version: String,
    /// The family, with its options.
    pub family: String,
    /// The constraints.
    pub constraints: Constraints,
    /// The objective.
    pub objective: ObjectiveSettings,
    /// The optimiser.
    pub search: SearchSettings,
    /// The working volume (in `summary.json` as `grid` for a grid, as
    /// before the volume existed, or as `sampled_volume`).
    #[serde(skip)]
    pub volume: WorkingVolume,
    /// The grid, when the volume is one.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub grid: Option<ScenarioGrid>,
    /// The sampled volume, when the volume is one.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sampled_volume: Option<crate::volume::SampledVolume>,
    /// The volume in words and numbers.
    pub volume_text: String,
    /// The camera.
    pub camera: Camera,
    /// Solver of the Monte-Carlo comparison.
    pub comparison_solver: String,
    /// Trials per scenario of the comparison.
    pub comparison_trials: usize,
    /// Seeds of the comparison: the search's, then the validation seed.
    pub comparison_seeds: Vec<u64>,
}

/// The claims the acceptance criteria ask about, computed from the rows.
#[derive(Debug, Clone, Serialize)]
pub struct Verdicts {
    /// Per comparison seed: 1 − winner RMS rotation / paper biprism RMS
    /// rotation, %, over the scenarios visible to both.
    pub rotation_reduction_vs_paper_percent: Vec<f64>,
    /// Per seed: winner RMS translation ≤ paper biprism's, on the scenarios
    /// visible to both.
    pub translation_no_worse: Vec<bool>,
    /// Winner availability − paper biprism availability, percentage points.
    pub availability_difference_pp: f64,
    /// Winner occluded scenarios ≤ paper biprism's.
    pub occlusion_no_more_frequent: bool,
    /// Winner's objective (accuracy + availability, without constraint
    /// penalties) below every hand design's.
    pub beats_hand_designs_on_objective: bool,
    /// Per seed: winner's Monte-Carlo RMS rotation below every hand design's,
    /// each pair on the scenarios visible to both.
    pub beats_hand_designs_on_monte_carlo: Vec<bool>,
    /// Winner's objective below that of every *admissible* hand design: each
    /// hand design as drawn when it meets the constraints, otherwise its
    /// nearest admissible version (the search's own repair). A design the
    /// user's constraints rule out (spheres that cannot be identified: by
    /// the stereo distance rule or, over every visible scenario, the
    /// identifiability floor) is not an alternative the user has.
    pub beats_admissible_hand_designs_on_objective: bool,
    /// The admissible hand designs' names.
    pub admissible_hand_designs: Vec<String>,
    /// Whether the winner meets every constraint.
    pub winner_feasible: bool,
    /// The availability floor in force (None: no floor).
    pub availability_floor: Option<f64>,
    /// Whether the winner reaches it.
    pub winner_meets_availability_floor: bool,
    /// Whether the winner meets the identifiability floor on every visible
    /// scenario (None: no floor).
    pub winner_meets_identifiability_floor: Option<bool>,
    /// The name of the paper's biprism's row, the design every comparison
    /// is against.
    pub paper_design: String,
    /// The hand design the winner is closest to (same sphere count), when
    /// one has as many spheres.
    pub closest_hand_design: Option<ClosestDesign>,
}

/// How far the winner's spheres are from a hand design's.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ClosestDesign {
    /// The hand design's name.
    pub name: String,
    /// The largest distance from a winner sphere to the hand design's
    /// sphere it is paired with, after the rigid motion that best
    /// (least squares) maps the winner onto the hand design, under the
    /// pairing that makes this distance smallest, mm.
    pub largest_shift_mm: f64,
}

/// Most spheres a layout may have for [`largest_shift_mm`] to pair them
/// (it tries every pairing: 8! = 40 320).
const MAX_PAIRED_SPHERES: usize = 8;

/// The smallest, over pairings of `a`'s points with `b`'s, of the largest
/// distance between paired points once `a` is moved rigidly onto `b`
/// (least squares), mm: how far `a` is from being `b` seen another way.
/// None when the counts differ, are below 3 or exceed
/// [`MAX_PAIRED_SPHERES`].
fn largest_shift_mm(a: &[Vector3<f64>], b: &[Vector3<f64>]) -> Option<f64> {
    fn pairings(a: &[Vector3<f64>], b: &[Vector3<f64>], order: &mut Vec<usize>, best: &mut f64) {
        if order.len() == b.len() {
            let paired = || order.iter().map(|&k| b[k]);
            let motion = crate::pose::absolute_orientation(a.iter().copied(), paired());
            let worst = a
                .iter()
                .zip(paired())
                .map(|(p, q)| (motion.rotation * p + motion.translation - q).norm())
                .fold(0.0, f64::max);
            *best = best.min(worst);
            return;
        }
        for k in 0..b.len() {
            if !order.contains(&k) {
                order.push(k);
                pairings(a, b, order, best);
                order.pop();
            }
        }
    }
    if a.len() != b.len() || a.len() < 3 || a.len() > MAX_PAIRED_SPHERES {
        return None;
    }
    let mut best = f64::INFINITY;
    pairings(a, b, &mut Vec::with_capacity(b.len()), &mut best);
    Some(best)
}

/// First-order figures of the winner and the paper's biprism on a held-out
/// grid: scenarios the search never saw.
#[derive(Debug, Clone, Serialize)]
pub struct HeldOutCheck {
    /// The held-out volume, in words.
    pub grid: String,
    /// Its scenarios.
    pub scenarios: usize,
    /// Winner's first-order RMS rotation, degrees (every in-front scenario).
    pub winner_rotation_rms_deg: Option<f64>,
    /// Paper biprism's first-order RMS rotation, degrees.
    pub paper_rotation_rms_deg: Option<f64>,
    /// 1 − winner / paper, %.
    pub rotation_reduction_percent: Option<f64>,
    /// Winner's first-order RMS translation, mm.
    pub winner_translation_rms_mm: Option<f64>,
    /// Paper biprism's first-order RMS translation, mm.
    pub paper_translation_rms_mm: Option<f64>,
    /// Winner's availability.
    pub winner_availability: f64,
    /// Paper biprism's availability.
    pub paper_availability: f64,
    /// Winner's occluded scenarios.
    pub winner_occluded: usize,
    /// Paper biprism's occluded scenarios.
    pub paper_occluded: usize,
}

impl HeldOutCheck {
    /// The check from first-order evaluations of the winner and the paper's
    /// biprism on `grid`.
    pub fn new(volume: &WorkingVolume, winner: &Evaluation, paper: &Evaluation) -> Self {
        let rotation = |e: &Evaluation| e.terms.first().and_then(|t| t.rotation_deg);
        let translation = |e: &Evaluation| e.terms.first().and_then(|t| t.translation_mm);
        Self {
            grid: volume_text(volume),
            scenarios: volume.len(),
            winner_rotation_rms_deg: rotation(winner),
            paper_rotation_rms_deg: rotation(paper),
            rotation_reduction_percent: rotation(winner)
                .zip(rotation(paper))
                .map(|(w, p)| 100.0 * (1.0 - w / p)),
            winner_translation_rms_mm: translation(winner),
            paper_translation_rms_mm: translation(paper),
            winner_availability: winner.availability,
            paper_availability: paper.availability,
            winner_occluded: winner.occluded,
            paper_occluded: paper.occluded,
        }
    }
}

/// Everything in the report.
#[derive(Debug, Clone, Serialize)]
pub struct SearchSummary {
    /// Provenance.
    pub header: SearchHeader,
    /// The optimiser's result.
    pub outcome: OptimiseOutcome,
    /// One row per design: winner, start, paper biprism, hand designs.
    pub designs: Vec<DesignRow>,
    /// The acceptance claims.
    pub verdicts: Verdicts,
    /// The winner and the paper's biprism on a held-out grid.
    pub held_out: HeldOutCheck,
    /// The same with the supports `export` builds for each counted as
    /// occluders (`None`: a part could not be built).
    pub held_out_with_supports: Option<HeldOutCheck>,
    /// The winner and the paper's biprism as printed on the search's own
    /// scenarios, and how the winner was repaired to the floor as printed
    /// (`None`: not checked).
    pub supports: Option<SupportsBooks>,
    /// The Pareto front, when asked for.
    pub front: Option<FrontReport>,
    /// How the identifiability floor was enforced (None: no floor).
    pub identifiability: Option<IdentifyBooks>,
    /// The winner and the paper's biprism under every chain
    /// ([`super::Chain`]), on the search's own scenarios.
    pub chains: Vec<ChainRow>,
}

/// The winner and the paper's biprism under one chain: the `crlb` term's
/// aggregated RMS rotation of each, on the search's scenarios and noise.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ChainRow {
    /// The chain.
    pub chain: super::Chain,
    /// The winner's aggregated RMS rotation, degrees.
    pub winner_rotation_deg: Option<f64>,
    /// The paper's biprism's, degrees.
    pub paper_rotation_deg: Option<f64>,
    /// The winner's accuracy: its objective's accuracy part relative to
    /// the paper's biprism (1 = as good) under the chain, rotation and
    /// translation weighed as the search weighs them.
    pub winner_accuracy: f64,
}

/// Computes the verdicts: rows are winner, start, then the hand designs with
/// the paper's biprism first (`hand`), then the admissible versions of those
/// that break a constraint (`admissible`).
pub fn verdicts(
    rows: &[DesignRow],
    paper_index: usize,
    hand: std::ops::Range<usize>,
    admissible: std::ops::Range<usize>,
) -> Verdicts {
    let winner = &rows[0];
    let admissible_rows: Vec<&DesignRow> = rows[hand.clone()]
        .iter()
        .chain(&rows[admissible])
        .filter(|r| {
            r.evaluation.violations.feasible() && r.evaluation.meets_identifiability_floor()
        })
        .collect();
    let paper = &rows[paper_index];
    let seeds = winner.monte_carlo.len();
    Verdicts {
        rotation_reduction_vs_paper_percent: (0..seeds)
            .map(|k| {
                let mc = &paper.monte_carlo[k];
                100.0 * (1.0 - mc.winner_common.rms_rotation_deg / mc.common.rms_rotation_deg)
            })
            .collect(),
        translation_no_worse: (0..seeds)
            .map(|k| {
                let mc = &paper.monte_carlo[k];
                mc.winner_common.rms_translation_mm <= mc.common.rms_translation_mm
            })
            .collect(),
        availability_difference_pp: 100.0
            * (winner.evaluation.availability - paper.evaluation.availability),
        occlusion_no_more_frequent: winner.evaluation.occluded <= paper.evaluation.occluded,
        beats_hand_designs_on_objective: rows[hand.clone()]
            .iter()
            .all(|r| winner.evaluation.objective < r.evaluation.objective),
        beats_hand_designs_on_monte_carlo: (0..seeds)
            .map(|k| {
                rows[hand.clone()].iter().all(|r| {
                    let mc = &r.monte_carlo[k];
                    mc.winner_common.rms_rotation_deg < mc.common.rms_rotation_deg
                })
            })
            .collect(),
        beats_admissible_hand_designs_on_objective: admissible_rows
            .iter()
            .all(|r| winner.evaluation.objective < r.evaluation.objective),
        admissible_hand_designs: admissible_rows.iter().map(|r| r.name.clone()).collect(),
        winner_feasible: winner.evaluation.violations.feasible(),
        availability_floor: winner.evaluation.availability_floor,
        winner_meets_availability_floor: winner.evaluation.meets_availability_floor(),
        winner_meets_identifiability_floor: winner
            .evaluation
            .identifiability
            .as_ref()
            .map(|f| f.meets_floor()),
        paper_design: paper.name.clone(),
        closest_hand_design: rows[hand]
            .iter()
            .filter_map(|r| {
                let shift = largest_shift_mm(&winner.layout.positions(), &r.layout.positions())?;
                Some(ClosestDesign {
                    name: r.name.clone(),
                    largest_shift_mm: shift,
                })
            })
            .min_by(|x, y| x.largest_shift_mm.total_cmp(&y.largest_shift_mm)),
    }
}

/// How the identifiability floor was enforced on the winner.
#[derive(Debug, Clone, Serialize)]
pub struct IdentifyBooks {
    /// The floor.
    pub floor: IdentifiabilityFloor,
    /// How it is enforced, in words.
    pub method: String,
    /// Repair rounds run (0: the search's winner met the floor as found).
    pub rounds: usize,
    /// Scenarios checked in each round (failing ones and the thinned grid).
    pub checked_per_round: Vec<usize>,
    /// Objective evaluations of the repair rounds.
    pub evaluations: usize,
    /// The search's winner over every visible scenario, before any repair.
    pub before: Option<IdentifiabilityFigures>,
    /// The final winner over every visible scenario.
    pub after: Option<IdentifiabilityFigures>,
    /// The search winner's accuracy before the repair.
    pub accuracy_before: f64,
    /// Wall-clock seconds of the checks and repair.
    pub seconds: f64,
}

/// A volume in words: a grid's varying axes (as reports have always
/// named them), or a sampled volume's description.
pub(crate) fn volume_text(volume: &WorkingVolume) -> String {
    match volume {
        WorkingVolume::Grid(grid) => grid_text(grid),
        WorkingVolume::Sampled(_) => volume.describe(),
    }
}

fn grid_text(grid: &ScenarioGrid) -> String {
    grid.named_ranges()
        .iter()
        .filter(|(_, r)| r.values.len() > 1 || r.values[0] != 0.0)
        .map(|(name, r)| {
            let values = &r.values;
            if values.len() > 3 {
                format!(
                    "{name} {}…{} ({} values)",
                    values[0],
                    values[values.len() - 1],
                    values.len()
                )
            } else {
                format!(
                    "{name} {}",
                    values
                        .iter()
                        .map(|v| v.to_string())
                        .collect::<Vec<_>>()
                        .join(",")
                )
            }
        })
        .collect::<Vec<_>>()
        .join("; ")
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Rotation3;

    #[test]
    fn largest_shift_pairs_points_in_any_order_and_pose() {
        let a = [
            Vector3::new(0.0, 0.0, 0.0),
            Vector3::new(10.0, 0.0, 0.0),
            Vector3::new(0.0, 10.0, 0.0),
        ];
        // b is a, reordered, with one point moved by 2 mm and one by 1 mm.
        let b = [
            Vector3::new(0.0, 12.0, 0.0),
            Vector3::new(0.0, 0.0, 0.0),
            Vector3::new(10.0, 0.0, 1.0),
        ];
        let shift = largest_shift_mm(&a, &b).unwrap();
        assert!(shift > 0.5 && shift < 2.0, "{shift}");
        // The same points, reordered, turned and moved: no shift.
        let turn = Rotation3::from_euler_angles(0.3, -1.2, 2.0);
        let moved: Vec<Vector3<f64>> = [2, 0, 1]
            .iter()
            .map(|&k| turn * a[k] + Vector3::new(5.0, -7.0, 1.0))
            .collect();
        assert!(largest_shift_mm(&a, &moved).unwrap() < 1e-9);
        assert_eq!(largest_shift_mm(&a, &b[..2]), None);
    }
}

/// One layout on the search's scenarios, as printed and as the spheres
/// alone.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PrintedFigures {
    /// Share of the scenarios with every sphere visible, the routed
    /// supports counted.
    pub availability: f64,
    /// The same, the spheres alone.
    pub availability_without: f64,
    /// Scenarios the spheres alone leave visible in which a support hides
    /// more than `max_hidden` of a sphere.
    pub lost_to_supports: usize,
    /// Accuracy (1 = the paper's biprism; supports do not change it).
    pub accuracy: f64,
}

/// How the winner was checked, and repaired, as printed.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SupportsBooks {
    /// A sphere hidden more than this fraction counts as not seen.
    pub max_hidden: f64,
    /// The search's scenarios.
    pub scenarios: usize,
    /// The availability floor as printed (None: no floor).
    pub floor: Option<f64>,
    /// The optimiser's winner, before any repair.
    pub found: PrintedFigures,
    /// The winner after the repair (the same as `found` when none ran).
    pub winner: PrintedFigures,
    /// The paper's biprism.
    pub paper: PrintedFigures,
    /// Whether the winner meets the floor as printed.
    pub met: bool,
    /// The winner's scenarios visible as printed, and of them those
    /// predicted identifiable from one image (None: identifiability was not
    /// checked on every visible scenario).
    pub identifiable_as_printed: Option<(usize, usize)>,
    /// Repair rounds run.
    pub rounds: usize,
    /// Most repair rounds.
    pub max_rounds: usize,
    /// Nelder–Mead iterations of a round.
    pub round_iterations: u64,
    /// Scenarios held per round.
    pub held_per_round: Vec<usize>,
    /// Evaluations of the repair rounds.
    pub evaluations: usize,
    /// Time of the check and the repair, s.
    pub seconds: f64,
}

impl SupportsBooks {
    /// How the check and the repair work, in words (report and summary).
    pub fn method(&self) -> String {
        format!(
            "the supports of export's default structure, routed to clear the search's own scenarios, counted as occluders (a sphere hidden more than {}% counts as not seen); the availability floor applies to the part as printed, the paper's biprism's own printed availability; a winner below it is repaired by Nelder–Mead rounds of {} iterations that price its routed supports following the spheres on the scenarios lost or nearly lost so far, each round's layout routed again and checked on every scenario, at most {} rounds",
            100.0 * self.max_hidden,
            self.round_iterations,
            self.max_rounds
        )
    }
}
