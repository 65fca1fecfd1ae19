//! The part's own supports in the search: which supports an [`Evaluator`]
//! counts, and the winner as printed.
//!
//! The optimiser scores the spheres alone (unless `--count-supports` asks
//! for every candidate's straight supports in its loop). Its winner is then
//! checked as `export` would print it ([`enforce_supports`]): the supports
//! of `export`'s default structure, routed to clear the views of the
//! search's own scenarios, are counted as occluders, and a sphere they hide
//! more than `max_hidden` of counts as not seen. The availability floor
//! then applies to the part as printed: the paper's biprism's own printed
//! availability (or the share asked for).
//!
//! A winner that misses it is repaired in rounds, as the identifiability
//! floor is: a Nelder–Mead run of [`SUPPORT_ROUND_ITERATIONS`] from it
//! prices, on the scenarios held so far (those its printed part lost or
//! nearly lost), the routed supports following the spheres as they move
//! ([`Supports::following`]), with a soft ramp on the hidden fraction so
//! that the optimiser sees a slope. Each round's layout is routed again and
//! checked on every scenario; the first that meets both availability
//! floors (spheres alone and as printed), every constraint and the
//! identifiability floor is kept. After [`SUPPORT_ROUNDS`] rounds without
//! one, or at a round's layout whose part cannot be built, the winner
//! stands and the books say so.

use super::summary::{HeldOutCheck, PrintedFigures, SupportsBooks};
use super::{
    optimise, AvailabilityFloor, Candidate, Evaluator, IdentifyScope, OptimiseOutcome, SearchError,
    SearchSettings,
};
use crate::family::Family;
use crate::layout::Layout;
use crate::mesh::{supports_for_range, GeometryError, MarkerOptions};
use crate::scenario::{sphere_images, visibility};
use crate::visibility::{support_fractions, EyeCone, MaxHidden, Supports, WorkingRange};
use nalgebra::Vector3;
use rayon::prelude::*;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Instant;

/// Most repair rounds for the printed availability floor.
pub const SUPPORT_ROUNDS: usize = 4;
/// Nelder–Mead iterations of one such round.
pub const SUPPORT_ROUND_ITERATIONS: u64 = 300;
/// How much repair [`enforce_supports`] may spend.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct RepairBudget {
    /// Most rounds (0: check only).
    pub rounds: usize,
    /// Nelder–Mead iterations of a round.
    pub iterations: u64,
}

impl RepairBudget {
    /// The search's: [`SUPPORT_ROUNDS`] rounds of
    /// [`SUPPORT_ROUND_ITERATIONS`].
    pub const SEARCH: RepairBudget = RepairBudget {
        rounds: SUPPORT_ROUNDS,
        iterations: SUPPORT_ROUND_ITERATIONS,
    };
    /// The check alone, no repair.
    pub const CHECK_ONLY: RepairBudget = RepairBudget {
        rounds: 0,
        iterations: 0,
    };
}

/// A scenario whose printed part hides more than this share of
/// `max_hidden` of some sphere is held by the repair (it is near the limit).
const NEAR_SHARE: f64 = 0.5;

/// Which supports an [`Evaluator`] counts as occluders.
#[derive(Debug, Clone)]
pub(super) enum SupportRule {
    /// None: the spheres alone hide each other.
    None,
    /// The supports of the one layout this evaluator scores
    /// ([`Evaluator::with_supports`]).
    Fixed(Arc<Supports>, MaxHidden),
    /// Every candidate's own straight supports
    /// ([`crate::mesh::straight_supports`] with these options,
    /// [`Evaluator::with_candidate_supports`]), screened once per
    /// candidate against the cone of the grid's eyes.
    Candidate(Arc<MarkerOptions>, MaxHidden, Option<EyeCone>),
    /// A printed part's supports following the candidate's spheres, on the
    /// scenarios a repair round holds ([`Following`]).
    Following(Arc<Following>),
}

/// The supports a repair round prices: one layout's routed supports,
/// carried along as the candidate's spheres move away from it, counted on
/// the held scenarios only (the others count as the spheres alone leave
/// them).
#[derive(Debug)]
pub(super) struct Following {
    /// The routed supports of `anchor`.
    supports: Supports,
    /// The sphere centres they were routed for.
    anchor: Vec<Vector3<f64>>,
    /// Per scenario of the evaluator, whether it is held.
    held: Vec<bool>,
    max_hidden: MaxHidden,
}

impl Following {
    /// `supports` at the candidate's spheres `points`: every point of a
    /// part within a sphere diameter of an anchor sphere moves with it.
    fn at(&self, points: &[Vector3<f64>], radius_mm: f64) -> Supports {
        self.supports
            .following(&self.anchor, points, 2.0 * radius_mm)
    }

    /// Per scenario of `evaluator`, for a held one that the spheres at
    /// `points` alone leave visible, [`Following::judge`] of the part
    /// carried to them; `None` for the others. Scenarios run in parallel (a
    /// round runs one Nelder–Mead start); the result does not depend on
    /// the thread count.
    pub(super) fn judge_all(
        &self,
        evaluator: &Evaluator,
        points: &[Vector3<f64>],
    ) -> Vec<Option<(Vec<usize>, f64)>> {
        let moved = self.at(points, 0.5 * evaluator.constraints.sphere_diameter_mm);
        support_fractions_where(evaluator, points, &moved, |s| self.held[s])
            .into_iter()
            .map(|fractions| fractions.map(|f| self.judge(&f)))
            .collect()
    }

    /// The spheres hidden beyond the limit, given each sphere's hidden
    /// fraction, and the scenario's soft visibility: 1 with nothing hidden,
    /// ½ at the limit, 0 at twice the limit (a slope for the optimiser
    /// where the count jumps).
    fn judge(&self, fractions: &[f64]) -> (Vec<usize>, f64) {
        let limit = self.max_hidden.fraction();
        let hidden = (0..fractions.len())
            .filter(|&k| fractions[k] > limit)
            .collect();
        let worst = fractions.iter().copied().fold(0.0, f64::max);
        let width = limit.max(1e-3);
        (
            hidden,
            (0.5 + (limit - worst) / (2.0 * width)).clamp(0.0, 1.0),
        )
    }
}

/// Per scenario of `evaluator` that `include` names and the spheres at
/// `points` alone leave visible, the fraction of each sphere that
/// `supports` hide; `None` for the others. Scenarios run in parallel; the
/// result does not depend on the thread count.
fn support_fractions_where(
    evaluator: &Evaluator,
    points: &[Vector3<f64>],
    supports: &Supports,
    include: impl Fn(usize) -> bool + Sync,
) -> Vec<Option<Vec<f64>>> {
    let diameter = evaluator.constraints.sphere_diameter_mm;
    evaluator
        .scenarios
        .par_iter()
        .enumerate()
        .map(|(s, scenario)| {
            if !include(s) {
                return None;
            }
            let pose = scenario.pose();
            let images = sphere_images(&evaluator.camera, &pose, points, diameter);
            visibility(&images, &evaluator.camera)
                .is_visible()
                .then(|| {
                    support_fractions(&evaluator.camera, &pose, points, 0.5 * diameter, supports)
                })
        })
        .collect()
}

/// A layout as printed: its routed supports, its worst hidden fraction per
/// scenario the spheres alone leave visible, and its figures.
struct Printed {
    supports: Supports,
    worst: Vec<Option<f64>>,
    figures: PrintedFigures,
}

impl Printed {
    /// Routes `layout`'s supports for `range` and counts them on the
    /// scenarios of `plain` (an evaluator of the spheres alone).
    fn of(
        plain: &Evaluator,
        range: &WorkingRange,
        layout: &Layout,
        max_hidden: MaxHidden,
    ) -> Result<Printed, GeometryError> {
        let supports = supports_for_range(layout, &MarkerOptions::default(), range)?;
        let points = layout.positions();
        let worst: Vec<Option<f64>> = support_fractions_where(plain, &points, &supports, |_| true)
            .into_iter()
            .map(|fractions| fractions.map(|f| f.into_iter().fold(0.0, f64::max)))
            .collect();
        let visible = worst.iter().flatten().count();
        let lost = worst
            .iter()
            .flatten()
            .filter(|&&w| w > max_hidden.fraction())
            .count();
        let n = plain.scenarios.len().max(1) as f64;
        let accuracy = plain.evaluate(&points, &layout.point_sigmas()).accuracy;
        Ok(Printed {
            supports,
            worst,
            figures: PrintedFigures {
                availability: (visible - lost) as f64 / n,
                availability_without: visible as f64 / n,
                lost_to_supports: lost,
                accuracy,
            },
        })
    }

    /// Per scenario, whether it is visible as printed.
    fn seen(&self, max_hidden: MaxHidden) -> Vec<bool> {
        self.worst
            .iter()
            .map(|w| w.is_some_and(|w| w <= max_hidden.fraction()))
            .collect()
    }

    /// The scenarios lost or nearly lost to the supports.
    fn near(&self, max_hidden: MaxHidden) -> impl Iterator<Item = usize> + '_ {
        let limit = NEAR_SHARE * max_hidden.fraction();
        self.worst
            .iter()
            .enumerate()
            .filter(move |(_, w)| w.is_some_and(|w| w > limit))
            .map(|(s, _)| s)
    }
}

/// Checks the winner of `outcome` as printed, against the paper's biprism
/// `paper` as printed, on the scenarios of `evaluator` (the search's), and
/// repairs it while it misses the printed availability floor (module
/// docs), within `budget`. A repaired layout must still meet the
/// constraints and the floors of `evaluator`, identifiability over every
/// visible scenario included. The winner of the returned outcome is the
/// repaired layout when a round succeeded.
#[allow(clippy::too_many_arguments)]
pub(super) fn enforce_supports(
    family: &Family,
    evaluator: &Evaluator,
    paper: &Layout,
    max_hidden: MaxHidden,
    settings: &SearchSettings,
    budget: RepairBudget,
    outcome: OptimiseOutcome,
    stop: &AtomicBool,
) -> Result<(OptimiseOutcome, SupportsBooks, PrintedParts), SearchError> {
    let started = Instant::now();
    let plain = evaluator.without_supports(&paper.positions());
    let range = WorkingRange {
        camera: plain.camera,
        scenarios: plain.scenarios.clone(),
        max_hidden,
    };
    let layout_of = |params: &[f64]| family.layout("", params);
    let winner = layout_of(&outcome.best.params);
    let (found, paper_printed) = rayon::join(
        || Printed::of(&plain, &range, &winner, max_hidden),
        || Printed::of(&plain, &range, paper, max_hidden),
    );
    let (found, paper_printed) = (
        found.map_err(|e| SearchError::Supports(e.to_string()))?,
        paper_printed.map_err(|e| SearchError::Supports(e.to_string()))?,
    );
    let floor = match plain.settings.min_availability {
        AvailabilityFloor::None => None,
        AvailabilityFloor::Reference => Some(paper_printed.figures.availability),
        AvailabilityFloor::Share(share) => Some(share),
    };
    let meets = |p: &Printed| floor.is_none_or(|f| p.figures.availability + 1e-12 >= f);
    let mut books = SupportsBooks {
        max_hidden: max_hidden.fraction(),
        scenarios: plain.scenarios.len(),
        floor,
        found: found.figures.clone(),
        winner: found.figures.clone(),
        paper: paper_printed.figures.clone(),
        met: meets(&found),
        identifiable_as_printed: None,
        rounds: 0,
        max_rounds: budget.rounds,
        round_iterations: budget.iterations,
        held_per_round: Vec::new(),
        evaluations: 0,
        seconds: 0.0,
    };
    let mut outcome = outcome;
    // What a repaired layout must still meet: the search's own evaluator
    // (constraints, the availability floor of the spheres alone) with the
    // identifiability floor checked on every visible scenario.
    let full =
        evaluator.with_identifiability(evaluator.identifiability_floor(), IdentifyScope::All);
    let point_sigma = winner.point_sigmas();
    let found_seen = found.seen(max_hidden);
    let found_supports = found.supports.clone();
    let mut winner_supports = None;
    let mut current = found;
    let mut from = outcome.best.params.clone();
    let mut held = vec![false; plain.scenarios.len()];
    while !books.met && books.rounds < budget.rounds && !stop.load(Ordering::Relaxed) {
        for s in current.near(max_hidden) {
            held[s] = true;
        }
        books.rounds += 1;
        books
            .held_per_round
            .push(held.iter().filter(|&&h| h).count());
        let rule = Following {
            supports: current.supports,
            anchor: family.points(&from),
            held: held.clone(),
            max_hidden,
        };
        let round = plain.with_following(rule, floor);
        let repaired =
            optimise::repair_round(family, &round, settings, budget.iterations, &from, stop)?;
        books.evaluations += repaired.evaluations_this_run;
        if repaired.interrupted {
            outcome.interrupted = true;
            break;
        }
        let params = repaired.best.params;
        // A round's layout whose part cannot be built ends the repair; the
        // winner found stands, its own part counted.
        let Ok(candidate) = Printed::of(&plain, &range, &layout_of(&params), max_hidden) else {
            break;
        };
        let checked = full.evaluate(&family.points(&params), &point_sigma);
        if meets(&candidate) && checked.admissible() {
            books.met = true;
            books.winner = candidate.figures.clone();
            winner_supports = Some((candidate.supports.clone(), candidate.seen(max_hidden)));
            outcome.best = Candidate {
                params: params.clone(),
                evaluation: checked,
                start: repaired.best.start,
            };
        }
        current = candidate;
        from = params;
    }
    outcome.evaluations += books.evaluations;
    books.seconds = started.elapsed().as_secs_f64();
    let (winner_part, seen) = winner_supports.unwrap_or((found_supports, found_seen));
    books.identifiable_as_printed = outcome
        .best
        .evaluation
        .identifiability
        .as_ref()
        .filter(|f| f.all_checked)
        .map(|f| {
            let visible = seen.iter().filter(|&&v| v).count();
            let failing = f.failing.iter().filter(|&&s| seen[s]).count();
            (visible, visible - failing)
        });
    let parts = PrintedParts {
        winner: winner_part,
        paper: paper_printed.supports,
    };
    Ok((outcome, books, parts))
}

/// The routed supports of the winner and the paper's biprism, as
/// [`enforce_supports`] counted them.
pub struct PrintedParts {
    /// The winner's (after any repair).
    pub winner: Supports,
    /// The paper's biprism's.
    pub paper: Supports,
}

/// [`HeldOutCheck`] of `winner` and `paper` on `volume`, first order, with
/// their printed supports `parts` counted (as routed for the search's own
/// scenarios by [`enforce_supports`]): the figures as printed, on views
/// the routing never saw.
pub fn held_out_with_supports(
    evaluator: &Evaluator,
    volume: &crate::volume::WorkingVolume,
    winner: &Layout,
    paper: &Layout,
    parts: &PrintedParts,
    max_hidden: MaxHidden,
) -> HeldOutCheck {
    let first_order = evaluator
        .without_supports(&paper.positions())
        .on_scenarios(volume.scenarios(&evaluator.camera), &paper.positions())
        .first_order(&paper.positions());
    let evaluate = |layout: &Layout, supports: &Supports| {
        first_order
            .with_supports(supports.clone(), max_hidden)
            .evaluate(&layout.positions(), &layout.point_sigmas())
    };
    let (winner_values, paper_values) = rayon::join(
        || evaluate(winner, &parts.winner),
        || evaluate(paper, &parts.paper),
    );
    HeldOutCheck::new(volume, &winner_values, &paper_values)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::Camera;
    use crate::family::{Constraints, Envelope, FamilyKind};
    use crate::noise::NoiseModel;
    use crate::scenario::{Range, ScenarioGrid};
    use crate::search::{Aggregate, AvailabilityFloor, ObjectiveSettings, Optimiser};

    /// The biprism family (arms may tilt) on 40 views at 600 mm, tilted up
    /// to 50° and panned 20°, at these X offsets, its natural start (the
    /// paper's biprism) as the winner found, and an availability floor of
    /// `floor`.
    fn setup(
        floor: AvailabilityFloor,
        offsets_x: &[f64],
    ) -> (Family, Evaluator, Layout, OptimiseOutcome) {
        let envelope = Envelope::new([100.0; 3]).unwrap();
        let family = Family::new(
            FamilyKind::Biprism {
                centre: true,
                tilts: true,
                free_hub: false,
            },
            envelope,
            10.0,
        )
        .unwrap();
        let grid = ScenarioGrid::new(
            Range::single(600.0),
            Range::list(offsets_x),
            Range::list(&[-50.0, 0.0]),
            Range::list(&[-50.0, -25.0, 0.0, 25.0, 50.0]),
            Range::list(&[-20.0, 20.0]),
            Range::single(0.0),
            Range::single(0.5),
        )
        .unwrap();
        let paper = family.layout("paper-biprism", &family.initial());
        let evaluator = Evaluator::new(
            Camera::paper(),
            grid.scenarios(),
            ObjectiveSettings {
                objective: "crlb".parse().unwrap(),
                aggregate: Aggregate::Mean,
                translation_weight: 0.5,
                availability_weight: 0.0,
                min_availability: floor,
                trials: 10,
                seed: 1,
                noise: NoiseModel::default(),
                observation: crate::sphere_image::Observation::default(),
                chain: Default::default(),
            },
            Constraints {
                envelope,
                sphere_diameter_mm: 10.0,
                min_gap_mm: 2.0,
                min_distance_diff_mm: 0.0,
            },
            &paper.positions(),
        );
        let params = family.initial();
        let best = Candidate {
            evaluation: evaluator.evaluate(&family.points(&params), &paper.point_sigmas()),
            params,
            start: 0,
        };
        let outcome = OptimiseOutcome {
            best: best.clone(),
            starts: vec![best],
            evaluations: 0,
            evaluations_this_run: 0,
            interrupted: false,
        };
        (family, evaluator, paper, outcome)
    }

    fn settings() -> SearchSettings {
        SearchSettings {
            optimiser: Optimiser::NelderMead,
            starts: 1,
            start_jitter: 0.0,
            iterations: 100,
            particles: 8,
            polish_iterations: 0,
            seed: 3,
        }
    }

    /// [`enforce_supports`] on [`setup`], rounds of `iterations`.
    fn enforce(
        floor: AvailabilityFloor,
        offsets_x: &[f64],
        iterations: u64,
    ) -> (
        Family,
        Evaluator,
        OptimiseOutcome,
        SupportsBooks,
        PrintedParts,
    ) {
        let (family, evaluator, paper, outcome) = setup(floor, offsets_x);
        let (outcome, books, parts) = enforce_supports(
            &family,
            &evaluator,
            &paper,
            MaxHidden::default(),
            &settings(),
            RepairBudget {
                rounds: SUPPORT_ROUNDS,
                iterations,
            },
            outcome,
            &AtomicBool::new(false),
        )
        .unwrap();
        (family, evaluator, outcome, books, parts)
    }

    /// The availability of `params`' layout with its supports routed for
    /// the evaluator's scenarios, counted by the evaluator's own
    /// fixed-part path (not the check's).
    fn recount(family: &Family, evaluator: &Evaluator, params: &[f64]) -> (f64, Supports) {
        let layout = family.layout("", params);
        let range = WorkingRange {
            camera: evaluator.camera,
            scenarios: evaluator.scenarios.clone(),
            max_hidden: MaxHidden::default(),
        };
        let supports = supports_for_range(&layout, &MarkerOptions::default(), &range).unwrap();
        let availability = evaluator
            .with_supports(supports.clone(), MaxHidden::default())
            .evaluate(&layout.positions(), &layout.point_sigmas())
            .availability;
        (availability, supports)
    }

    #[test]
    fn a_winner_that_meets_the_printed_floor_is_kept_and_counted_as_the_evaluator_counts() {
        let (family, evaluator, outcome, books, parts) =
            enforce(AvailabilityFloor::Reference, &[0.0, 50.0], 60);
        // The start is the paper's biprism: its part loses views to its
        // supports here, and it sets the floor as printed.
        assert!(books.found.lost_to_supports > 0, "{books:?}");
        assert_eq!(books.floor, Some(books.paper.availability));
        assert!(books.met && books.rounds == 0 && books.evaluations == 0);
        assert_eq!(books.found, books.winner);
        assert_eq!(outcome.best.params, family.initial());
        let (availability, supports) = recount(&family, &evaluator, &outcome.best.params);
        assert_eq!(availability, books.winner.availability);
        assert_eq!(supports, parts.winner);
        assert_eq!(books.winner.availability_without, 1.0);
        assert_eq!(
            books.winner.availability,
            1.0 - books.winner.lost_to_supports as f64 / books.scenarios as f64
        );
    }

    #[test]
    fn a_winner_below_the_printed_floor_is_moved_until_its_routed_part_meets_it() {
        let (family, evaluator, outcome, books, parts) =
            enforce(AvailabilityFloor::Share(0.95), &[0.0, 50.0], 60);
        assert!(books.found.availability < 0.95, "{books:?}");
        assert!(books.met && books.rounds >= 1, "{books:?}");
        assert_ne!(outcome.best.params, family.initial());
        assert!(outcome.best.evaluation.admissible());
        // Routed again from scratch and counted by the fixed-part path.
        let (availability, supports) = recount(&family, &evaluator, &outcome.best.params);
        assert!(availability >= 0.95, "{availability}");
        assert_eq!(availability, books.winner.availability);
        assert_eq!(supports, parts.winner);
        assert_eq!(outcome.evaluations, books.evaluations);
    }

    #[test]
    fn a_winner_no_round_repairs_is_kept_as_found_and_the_books_say_so() {
        // Every view at 2 m to the side leaves the image: no layout is
        // visible in all of them.
        let (family, _, outcome, books, _) =
            enforce(AvailabilityFloor::Share(1.0), &[0.0, 2000.0], 10);
        assert!(!books.met);
        assert_eq!(books.rounds, SUPPORT_ROUNDS);
        assert_eq!(books.held_per_round.len(), SUPPORT_ROUNDS);
        assert!(books.held_per_round.windows(2).all(|w| w[0] <= w[1]));
        assert_eq!(books.held_per_round[0], books.found.lost_to_supports);
        assert_eq!(outcome.best.params, family.initial());
        assert_eq!(books.winner, books.found);
    }

    #[test]
    fn the_check_and_its_repair_do_not_depend_on_the_thread_count() {
        let run = |threads: usize| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| {
                    let (_, _, outcome, mut books, _) =
                        enforce(AvailabilityFloor::Share(0.95), &[0.0, 50.0], 30);
                    assert!(books.rounds >= 1, "the repair must run: {books:?}");
                    books.seconds = 0.0;
                    (outcome.best.params, books)
                })
        };
        assert_eq!(run(1), run(2));
    }
}
