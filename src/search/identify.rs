//! The identifiability floor enforced on the search's winner by repair
//! rounds (constraint generation); see [`enforce_identifiability`].

use super::error::SearchError;
use super::optimise::{self, Candidate, SearchSettings};
use super::summary::IdentifyBooks;
use super::{Evaluator, IdentifiabilityFloor, IdentifyScope};
use crate::family::Family;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

/// Rounds of the identifiability repair at most.
pub const IDENTIFY_ROUNDS: usize = 4;
/// Nelder–Mead iterations of one round of the identifiability repair.
pub const IDENTIFY_ROUND_ITERATIONS: u64 = 400;
/// Every this many visible scenarios, one joins the scenarios the repair
/// checks from its first round on (besides those found failing), so that a
/// round cannot trade one failing scenario for unseen others.
pub const IDENTIFY_THINNING: usize = 16;
/// Failing scenarios one round adds to the checked set at most (spread
/// evenly over those failing), so that a winner failing everywhere (a
/// symmetric one) does not make every evaluation check the whole grid.
pub const IDENTIFY_MAX_NEW: usize = 24;

/// At most `count` of `items`, spread evenly (all of them when they are
/// fewer).
fn spread_evenly(items: &[usize], count: usize) -> Vec<usize> {
    if items.len() <= count {
        return items.to_vec();
    }
    (0..count).map(|k| items[k * items.len() / count]).collect()
}

pub(crate) use super::optimise::Quiet;

/// Enforces the identifiability floor on the search's winner by repair
/// rounds (constraint generation): the winner is checked on every visible
/// scenario; while it fails the floor, a Nelder–Mead run from it minimises
/// the objective plus the identifiability penalty
/// ([`super::IDENTIFIABILITY_PENALTY`]) over the scenarios found failing so
/// far and a thinned grid ([`IDENTIFY_THINNING`]), and its winner is checked
/// on every visible scenario again. The multistart itself never runs the
/// unlabelled solver (it costs 0.1–1 ms per scenario, 50–500 times the
/// first-order objective). A winner still failing after
/// [`IDENTIFY_ROUNDS`] rounds is returned as is, not admissible.
pub(crate) fn enforce_identifiability(
    family: &Family,
    evaluator: &Evaluator,
    floor: IdentifiabilityFloor,
    settings: &SearchSettings,
    outcome: optimise::OptimiseOutcome,
    stop: &AtomicBool,
) -> Result<(optimise::OptimiseOutcome, IdentifyBooks), SearchError> {
    let point_sigma = family.layout("", &family.initial()).point_sigmas();
    let full = evaluator.with_identifiability(Some(floor), IdentifyScope::All);
    let check = |params: &[f64]| full.evaluate(&family.points(params), &point_sigma);
    let mut books = IdentifyBooks {
        floor,
        method: format!(
            "repair rounds: the multistart scores accuracy alone; its winner is checked on every visible scenario and, while it fails, a Nelder–Mead run of {IDENTIFY_ROUND_ITERATIONS} iterations from it adds a penalty of {} per decade of predicted wrong-label probability above the criterion over the scenarios found failing so far (at most {IDENTIFY_MAX_NEW} more per round, spread over the failing ones) and every {IDENTIFY_THINNING}th scenario, at most {IDENTIFY_ROUNDS} rounds",
            super::IDENTIFIABILITY_PENALTY
        ),
        rounds: 0,
        checked_per_round: Vec::new(),
        evaluations: 0,
        before: None,
        after: None,
        accuracy_before: outcome.best.evaluation.accuracy,
        seconds: 0.0,
    };
    let mut outcome = outcome;
    let mut checked = check(&outcome.best.params);
    books.before = checked.identifiability.clone();
    let thinned: Vec<usize> = (0..evaluator.scenarios().len())
        .step_by(IDENTIFY_THINNING)
        .collect();
    let mut active: Vec<usize> = thinned;
    while !checked.meets_identifiability_floor() && books.rounds < IDENTIFY_ROUNDS {
        if stop.load(Ordering::Relaxed) {
            break;
        }
        if let Some(figures) = &checked.identifiability {
            active.extend(spread_evenly(&figures.failing, IDENTIFY_MAX_NEW));
        }
        active.sort_unstable();
        active.dedup();
        books.rounds += 1;
        books.checked_per_round.push(active.len());
        let scoped = evaluator.with_identifiability(
            Some(floor),
            IdentifyScope::Scenarios(Arc::new(active.clone())),
        );
        let repaired = optimise::repair_round(
            family,
            &scoped,
            settings,
            IDENTIFY_ROUND_ITERATIONS,
            &outcome.best.params,
            stop,
        )?;
        books.evaluations += repaired.evaluations_this_run;
        if repaired.interrupted {
            outcome.interrupted = true;
            break;
        }
        let candidate = check(&repaired.best.params);
        // Keep the repaired layout only if it is no worse on the floor.
        let failing =
            |e: &super::Evaluation| e.identifiability.as_ref().map_or(0, |f| f.failing.len());
        if failing(&candidate) <= failing(&checked) && candidate.violations.feasible() {
            outcome.best = Candidate {
                params: repaired.best.params,
                evaluation: candidate.clone(),
                start: repaired.best.start,
            };
            checked = candidate;
        } else {
            active.extend(spread_evenly(
                candidate
                    .identifiability
                    .as_ref()
                    .map_or(&[][..], |f| &f.failing[..]),
                IDENTIFY_MAX_NEW,
            ));
        }
    }
    // The winner's evaluation carries its full-grid identifiability.
    outcome.best.evaluation = checked.clone();
    books.after = checked.identifiability;
    outcome.evaluations += books.evaluations;
    Ok((outcome, books))
}
