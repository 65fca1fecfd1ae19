//! The Pareto front of accuracy against availability, by an ε-constraint
//! sweep: the search is run again with the availability floor raised step by
//! step, each level warm-started from the previous level's winner, and the
//! non-dominated layouts among all the levels' winners (and the main
//! search's winner) form the front.
//!
//! * Level 0 has no floor: the most accurate layout regardless of
//!   availability. Its availability `a₀` is where the sweep begins.
//! * Levels 1…L put the floor at `a₀ + k (1 − a₀) / L`. A level whose winner
//!   cannot reach its floor ends the sweep: the levels above it are
//!   infeasible for this optimiser too.
//! * Then the weighted blend, without a floor, at each weight of
//!   [`BLEND_WEIGHTS`]: its winners are supported points of the front that
//!   the ε-levels, whose penalty can push a warm start past the best layout
//!   at a floor, may miss.
//! * Every level runs the family's natural and spread starts plus
//!   [`WARM_STARTS`] warm starts (the front members so far that score best
//!   under the level's objective), without the final polish, each repaired
//!   to meet the constraints; only layouts that meet the constraints enter
//!   the front.
//! * Accuracy is the search objective's accuracy (1 = the reference layout);
//!   the front also lists the first-order RMS rotation and translation on
//!   the search grid.

use super::optimise::{self, Candidate, OptimiseError, Quiet, SearchSettings};
use super::{Evaluation, Evaluator};
use crate::family::Family;
use crate::layout::Layout;
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;

/// How the front is swept.
#[derive(Debug, Clone, Serialize)]
pub struct FrontSettings {
    /// Availability levels above the unconstrained one (L).
    pub levels: usize,
    /// Iterations of each start at each level.
    pub iterations: u64,
}

impl Default for FrontSettings {
    fn default() -> Self {
        Self {
            levels: 8,
            iterations: 2000,
        }
    }
}

/// Warm starts of each level: the front members that score best under the
/// level's objective.
pub const WARM_STARTS: usize = 2;
/// Availability weights of the blend levels after the ε-constraint levels.
pub const BLEND_WEIGHTS: [f64; 4] = [0.5, 1.0, 2.0, 4.0];

/// A layout on (or offered to) the front.
#[derive(Debug, Clone)]
pub struct FrontPoint {
    /// Its parameters and evaluation.
    pub candidate: Candidate,
    /// The floor of the level that found it (None: no floor).
    pub floor: Option<f64>,
}

/// `a` is at least as good as `b` on accuracy and availability.
pub fn at_least_as_good(
    a_accuracy: f64,
    a_availability: f64,
    b_accuracy: f64,
    b_availability: f64,
) -> bool {
    a_accuracy <= b_accuracy && a_availability >= b_availability
}

/// The non-dominated points of `points` (lower accuracy, higher
/// availability), sorted by availability; of two equal points the first is
/// kept.
pub fn non_dominated(points: Vec<FrontPoint>) -> Vec<FrontPoint> {
    let key = |p: &FrontPoint| {
        (
            p.candidate.evaluation.accuracy,
            p.candidate.evaluation.availability,
        )
    };
    let mut front: Vec<FrontPoint> = Vec::new();
    for (i, p) in points.iter().enumerate() {
        let (acc, avail) = key(p);
        let dominated = points.iter().enumerate().any(|(j, q)| {
            let (q_acc, q_avail) = key(q);
            let better_somewhere = q_acc < acc || q_avail > avail;
            let equal = q_acc == acc && q_avail == avail;
            (at_least_as_good(q_acc, q_avail, acc, avail) && better_somewhere) || (equal && j < i)
        });
        if !dominated {
            front.push(p.clone());
        }
    }
    front.sort_by(|a, b| {
        a.candidate
            .evaluation
            .availability
            .total_cmp(&b.candidate.evaluation.availability)
    });
    front
}

/// The ε-constraint sweep. `base` is the main search's settings (its seed
/// and optimiser are kept; starts become the natural and spread starts plus
/// warm starts, without jitter); `offered` are layouts already found (the
/// main search's winner) that join the warm starts and the front.
/// `levels_done` counts finished levels (of `front.levels + 1 +`
/// [`BLEND_WEIGHTS`]`.len()`). A stop ends
/// the sweep at once; the levels finished so far still give a front.
/// Returns the front and the evaluations spent.
pub fn sweep(
    family: &Family,
    evaluator: &Evaluator,
    base: &SearchSettings,
    front: &FrontSettings,
    offered: &[Candidate],
    stop: &AtomicBool,
    levels_done: &AtomicU64,
) -> Result<(Vec<FrontPoint>, usize), OptimiseError> {
    let settings = SearchSettings {
        starts: 2.min(base.starts.max(1)),
        start_jitter: 0.0,
        iterations: front.iterations,
        polish_iterations: 0,
        ..base.clone()
    };
    let mut pool: Vec<FrontPoint> = offered
        .iter()
        .filter(|c| c.evaluation.violations.feasible())
        .map(|c| FrontPoint {
            candidate: c.clone(),
            floor: c.evaluation.availability_floor,
        })
        .collect();
    let evaluations = std::cell::Cell::new(0);
    let run_level = |floor: Option<f64>, weight: f64, pool: &[FrontPoint]| {
        let level = evaluator.with_floor(floor).with_availability_weight(weight);
        // Warm starts: the front members that score best under this level's
        // objective (its floor as an exact penalty, its weight).
        let score = |p: &FrontPoint| {
            let e = &p.candidate.evaluation;
            e.accuracy
                + weight * (1.0 - e.availability)
                + floor.map_or(0.0, |f| {
                    super::AVAILABILITY_PENALTY * (f - e.availability).max(0.0)
                })
        };
        let mut members = non_dominated(pool.to_vec());
        members.sort_by(|a, b| score(a).total_cmp(&score(b)));
        let warm: Vec<Vec<f64>> = members
            .into_iter()
            .take(WARM_STARTS)
            .map(|p| p.candidate.params)
            .collect();
        optimise::run_with_starts(
            family,
            &level,
            &settings,
            &warm,
            stop,
            Arc::new(Quiet),
            None,
        )
        .map(|outcome| {
            evaluations.set(evaluations.get() + outcome.evaluations);
            outcome.best
        })
    };
    let first = match run_level(None, 0.0, &pool) {
        Err(OptimiseError::InterruptedEmpty) => {
            return Ok((non_dominated(pool), evaluations.get()))
        }
        other => other?,
    };
    let lowest = first.evaluation.availability;
    if first.evaluation.violations.feasible() {
        pool.push(FrontPoint {
            candidate: first,
            floor: None,
        });
    }
    levels_done.store(1, Ordering::Relaxed);
    for k in 1..=front.levels {
        if stop.load(Ordering::Relaxed) {
            break;
        }
        let floor = lowest + k as f64 * (1.0 - lowest) / front.levels as f64;
        let best = match run_level(Some(floor), 0.0, &pool) {
            Err(OptimiseError::InterruptedEmpty) => break,
            other => other?,
        };
        let reached = best.evaluation.admissible();
        if best.evaluation.violations.feasible() {
            pool.push(FrontPoint {
                candidate: best,
                floor: Some(floor),
            });
        }
        levels_done.store(k as u64 + 1, Ordering::Relaxed);
        if !reached {
            break;
        }
    }
    for (k, weight) in BLEND_WEIGHTS.iter().enumerate() {
        if stop.load(Ordering::Relaxed) {
            break;
        }
        let best = match run_level(None, *weight, &pool) {
            Err(OptimiseError::InterruptedEmpty) => break,
            other => other?,
        };
        if best.evaluation.violations.feasible() {
            pool.push(FrontPoint {
                candidate: best,
                floor: None,
            });
        }
        levels_done.store((front.levels + 2 + k) as u64, Ordering::Relaxed);
    }
    Ok((non_dominated(pool), evaluations.get()))
}

/// One member of the front, as `front.json` lists it.
#[derive(Debug, Clone, Serialize)]
pub struct FrontEntry {
    /// The member's name.
    pub name: String,
    /// Its layout file.
    pub layout: PathBuf,
    /// The availability floor of the level that found it (None: no floor;
    /// the unconstrained or a blend level).
    pub floor: Option<f64>,
    /// Accuracy (1 = the reference layout), the objective's.
    pub accuracy: f64,
    /// Share of the grid's scenarios with every sphere visible.
    pub availability: f64,
    /// Scenarios with an occluded sphere.
    pub occluded: usize,
    /// First-order RMS rotation error on the search grid, degrees.
    pub rotation_rms_deg: Option<f64>,
    /// First-order RMS translation error on the search grid, mm.
    pub translation_rms_mm: Option<f64>,
    /// Monte-Carlo figures; the sweep computes none (null).
    pub monte_carlo: Option<serde_json::Value>,
}

/// A hand design against the front.
#[derive(Debug, Clone, Serialize)]
pub struct HandEntry {
    /// The design's name.
    pub name: String,
    /// Whether it meets the constraints.
    pub admissible: bool,
    /// Accuracy (1 = the reference layout).
    pub accuracy: f64,
    /// Availability.
    pub availability: f64,
    /// First-order RMS rotation error on the search grid, degrees.
    pub rotation_rms_deg: Option<f64>,
    /// First-order RMS translation error on the search grid, mm.
    pub translation_rms_mm: Option<f64>,
    /// The first front member at least as good on accuracy and availability.
    pub dominated_by: Option<String>,
    /// The first front member at least as good on first-order RMS rotation
    /// and availability.
    pub dominated_on_rotation_by: Option<String>,
}

/// `front.json`.
#[derive(Debug, Clone, Serialize)]
pub struct FrontReport {
    /// How the front was computed.
    pub method: String,
    /// The sweep's settings.
    pub settings: FrontSettings,
    /// Objective evaluations of the sweep.
    pub evaluations: usize,
    /// Seconds of the sweep.
    pub seconds: f64,
    /// The members, by availability.
    pub members: Vec<FrontEntry>,
    /// The hand designs, as drawn and made admissible.
    pub hand_designs: Vec<HandEntry>,
    /// Every hand design has a front member at least as good on accuracy and
    /// availability.
    pub dominates_every_hand_design: bool,
}

/// The method, in words, for the reports.
pub const METHOD: &str = "ε-constraint sweep: the search rerun with the availability floor raised in equal steps from the availability of the most accurate layout (no floor) towards 1, then with the weighted blend at availability weights 0.5, 1, 2 and 4, each level warm-started from the two front members so far that score best under its objective plus the family's natural and spread starts; the floor is an exact penalty (100 per unit of missing availability, counted exactly and softly) and ranks layouts below it behind every layout above it; only layouts meeting the constraints enter, and the non-dominated ones form the front";

/// The first-order RMS rotation and translation of an evaluation (its
/// first term's), as the front and its plot show them.
pub(super) fn first_order(evaluation: &Evaluation) -> (Option<f64>, Option<f64>) {
    evaluation
        .terms
        .first()
        .map_or((None, None), |t| (t.rotation_deg, t.translation_mm))
}

/// The front's report with its members' layouts, built by [`build`]
/// without touching a file and written by the search report, so that a run can write
/// them together with the rest of its report once every phase has finished.
#[derive(Debug, Clone)]
pub struct FrontFiles {
    /// What `front.json` holds (each member's `layout` is the path its
    /// layout file gets).
    pub report: FrontReport,
    /// The members' layouts, in the report's order.
    pub layouts: Vec<Layout>,
}

/// What [`build`] needs: where the members' layouts go, how to name and
/// score them, and the sweep's books.
pub struct FrontInputs<'a> {
    /// Directory of the members' layout files (`<name>-front-<k>.json`).
    pub layout_dir: &'a Path,
    /// Name of the search; members are `<name>-front-<k>`.
    pub name: &'a str,
    /// The family the members' parameters belong to.
    pub family: &'a Family,
    /// The front's points, by availability.
    pub points: &'a [FrontPoint],
    /// Scores layouts by the first-order model on the search grid.
    pub first_order_evaluator: &'a Evaluator,
    /// The hand designs' names, layouts and evaluations by the search
    /// objective.
    pub hand: &'a [(String, Layout, Evaluation)],
    /// Provenance every member's layout carries.
    pub provenance: &'a serde_json::Value,
    /// Objective evaluations of the sweep.
    pub evaluations: usize,
    /// Seconds of the sweep.
    pub seconds: f64,
    /// The sweep's settings.
    pub settings: &'a FrontSettings,
}

/// Builds the front's report: a layout per member, to be written to
/// `inputs.layout_dir`, and the report of `front.json`. Writes nothing (the
/// search report does).
pub fn build(inputs: &FrontInputs<'_>) -> FrontFiles {
    let FrontInputs {
        layout_dir,
        name,
        family,
        points,
        first_order_evaluator,
        hand,
        provenance,
        evaluations,
        seconds,
        settings,
    } = *inputs;
    let mut members = Vec::with_capacity(points.len());
    let mut layouts = Vec::with_capacity(points.len());
    for (k, point) in points.iter().enumerate() {
        let member = format!("{name}-front-{}", k + 1);
        let mut layout = family.layout(&member, &point.candidate.params);
        let mut record = provenance.clone();
        record["status"] = "finished: Pareto front member".into();
        record["availability_floor"] = point.floor.into();
        layout.provenance = Some(record);
        let path = layout_dir.join(format!("{member}.json"));
        let (rotation, translation) = first_order(
            &first_order_evaluator.evaluate(&layout.positions(), &layout.point_sigmas()),
        );
        let e = &point.candidate.evaluation;
        members.push(FrontEntry {
            name: member,
            layout: path,
            floor: point.floor,
            accuracy: e.accuracy,
            availability: e.availability,
            occluded: e.occluded,
            rotation_rms_deg: rotation,
            translation_rms_mm: translation,
            monte_carlo: None,
        });
        layouts.push(layout);
    }
    let hand_designs: Vec<HandEntry> = hand
        .iter()
        .map(|(design, layout, e)| {
            let (rotation, translation) = first_order(
                &first_order_evaluator.evaluate(&layout.positions(), &layout.point_sigmas()),
            );
            let dominated_by = members
                .iter()
                .find(|m| at_least_as_good(m.accuracy, m.availability, e.accuracy, e.availability))
                .map(|m| m.name.clone());
            let dominated_on_rotation_by = members
                .iter()
                .find(|m| match (m.rotation_rms_deg, rotation) {
                    (Some(mine), Some(theirs)) => {
                        at_least_as_good(mine, m.availability, theirs, e.availability)
                    }
                    _ => false,
                })
                .map(|m| m.name.clone());
            HandEntry {
                name: design.clone(),
                admissible: e.violations.feasible(),
                accuracy: e.accuracy,
                availability: e.availability,
                rotation_rms_deg: rotation,
                translation_rms_mm: translation,
                dominated_by,
                dominated_on_rotation_by,
            }
        })
        .collect();
    let report = FrontReport {
        method: METHOD.to_string(),
        settings: settings.clone(),
        evaluations,
        seconds,
        dominates_every_hand_design: hand_designs.iter().all(|h| h.dominated_by.is_some()),
        members,
        hand_designs,
    };
    FrontFiles { report, layouts }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::search::Evaluation;

    fn point(accuracy: f64, availability: f64) -> FrontPoint {
        let mut e = blank();
        e.accuracy = accuracy;
        e.availability = availability;
        FrontPoint {
            candidate: Candidate {
                params: vec![accuracy, availability],
                evaluation: e,
                start: 0,
            },
            floor: None,
        }
    }

    fn blank() -> Evaluation {
        Evaluation {
            cost: 0.0,
            objective: 0.0,
            accuracy: 0.0,
            terms: Vec::new(),
            availability: 0.0,
            soft_availability: 0.0,
            visible: 0,
            in_front: 0,
            occluded: 0,
            outside: 0,
            behind: 0,
            scored: 0,
            unusable_noise: 0,
            availability_floor: None,
            floor_penalty: 0.0,
            violations: Default::default(),
            identifiability: None,
            cross_penalty: 0.0,
        }
    }

    #[test]
    fn the_front_keeps_only_non_dominated_points_in_availability_order() {
        let front = non_dominated(vec![
            point(0.6, 0.5),
            point(0.7, 0.4), // dominated by (0.6, 0.5)
            point(0.8, 0.7),
            point(0.6, 0.5), // a duplicate
            point(0.5, 0.3),
        ]);
        let kept: Vec<(f64, f64)> = front
            .iter()
            .map(|p| {
                (
                    p.candidate.evaluation.accuracy,
                    p.candidate.evaluation.availability,
                )
            })
            .collect();
        assert_eq!(kept, vec![(0.5, 0.3), (0.6, 0.5), (0.8, 0.7)]);
    }
}
