//! The cross repair: a marker that no earlier marker may be confused with,
//! reached from a try that came close.
//!
//! A try's winner that meets every single-marker floor but fails the
//! cross floor in a few viewpoints is repaired, as the identifiability
//! repair does for one marker (constraint generation): each confusion
//! the cross check found in a viewpoint that fails the floor or comes
//! near it ([`crate::set::CrossPair::near`]; a scenario, which marker's
//! blobs, the other marker's labelling and pose) is held fixed as a
//! [`Confusion`], and a Nelder–Mead run from the winner minimises the
//! objective plus [`CROSS_PENALTY`] per decade of each held confusion's
//! predicted probability above [`CROSS_MARGIN`] of the floor's criterion,
//! plus [`CROSS_TRUST_PER_MM2`] per mm² of squared distance from the
//! layout the round starts from (the winner, then the last round's
//! admissible layout). Pricing a held confusion refits one labelling's pose
//! ([`crate::set::labelled_confusion`], tens of microseconds), where
//! finding it searched every labelling with every blob left out in turn
//! (the unlabelled solver, milliseconds). The repaired layout is then
//! checked again (`repair_cross`), alone (every single-marker floor over
//! the whole grid) and against the earlier markers (the cross matrix);
//! confusions it brings up are held in the next round, for at most
//! [`CROSS_ROUNDS`] rounds. A round whose layout misses a single-marker
//! floor changes nothing for the next, which would repeat it exactly (one
//! Nelder–Mead run, seeded, from the same layout under the same held
//! confusions), so the repair ends there, unless the miss was the
//! marker's own identifiability and the rounds did not guard it yet.

use super::super::optimise::{self, Candidate, OptimiseOutcome, SearchSettings};
use super::super::{
    Evaluator, IdentifiabilityFloor, IdentifyScope, SearchError, IDENTIFY_THINNING,
};
use crate::camera::Camera;
use crate::family::Family;
use crate::identifiability::IdentifiabilitySettings;
use crate::montecarlo::Target;
use crate::pose::Pose;
use crate::scenario::Scenario;
use crate::set::{cross_scenario, labelled_confusion, seen_view, CrossMatrix, SeenView};
use nalgebra::Vector3;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

/// Rounds of the cross repair at most. A round (its Nelder–Mead and
/// checks, 2 to 20 s) costs less than a new try (a 17 s search, its own
/// check, and its own repair from the start): with at most 6 rounds the
/// fifth marker of `search --set 8` was refused after four tries; with
/// 12, `search --set 5` kept the same marker on its first try, in 8
/// rounds, the set in 334.4 s (2 cores, 2026-11-28). Sets whose repairs
/// clear within 6 rounds are unchanged.
pub const CROSS_ROUNDS: usize = 12;
/// Nelder–Mead iterations of one round of the cross repair.
pub const CROSS_ROUND_ITERATIONS: u64 = 400;
/// Cost per decade by which a held confusion's predicted probability
/// exceeds [`CROSS_MARGIN`] times the cross floor's criterion.
pub const CROSS_PENALTY: f64 = 1.0;
/// The repair prices a held confusion from this share of the floor's
/// criterion on, so that it settles with a margin rather than on the
/// edge of the floor, where the full check's other labellings tip it
/// over.
pub const CROSS_MARGIN: f64 = 0.1;
/// Cost per mm² of the summed squared distance of the repaired points from
/// the layout the round started from. The held confusions are only those
/// found so far: unchecked, the simplex's first steps (a tenth of each
/// range) land where the marker is confused with the earlier ones in many
/// other viewpoints (68 instead of 1, in a 4-marker set). Held close, a
/// move that clears one viewpoint changes the others' margins little.
///
/// The trust is centred on the last round's layout, not on the winner:
/// centred on the winner, each round went back towards it as far as the
/// held confusions let it, moved the marker again, and brought up new
/// confusions (and new dips between the viewpoints) each time; a 4-marker
/// set needed 4 tries for its last marker (6 rounds each) and took
/// 494.9 s. Centred on the last round, each round moves only as far as
/// the confusions it adds require, every marker was kept on its first try
/// in 3 to 5 rounds, and the set took 191.7 s, its worst marker's
/// accuracy 0.5956 against 0.5884 (`search --set 4`, 2 cores,
/// 2026-11-28).
pub const CROSS_TRUST_PER_MM2: f64 = 0.01;

/// One confusion found by a cross check, held fixed: in `scenario`, the
/// blobs of the candidate (`candidate_seen`) or of earlier marker `rival`
/// (one left out: `missing`) are explained by the other's points `labels`
/// at about `pose`.
#[derive(Debug, Clone)]
pub struct Confusion {
    /// The scenario.
    pub scenario: Scenario,
    /// The earlier marker involved (its index among the rivals).
    pub rival: usize,
    /// Whether the candidate's blobs are the ones seen (else the rival's).
    pub candidate_seen: bool,
    /// The blob left out.
    pub missing: Option<usize>,
    /// For each blob kept, the other marker's point it was given.
    pub labels: Vec<usize>,
    /// The other marker's pose in that fit.
    pub pose: Pose,
    /// The rival's view when its blobs are the ones seen (it does not
    /// change while the candidate moves).
    pub rival_view: Option<SeenView>,
}

/// The held confusions of a repair, priced for each candidate.
#[derive(Debug, Clone)]
pub struct CrossRule {
    /// The camera.
    pub camera: Camera,
    /// The spheres' diameter, mm.
    pub sphere_diameter_mm: f64,
    /// The cross check's settings (the floor's criterion, noise,
    /// observation).
    pub settings: IdentifiabilitySettings,
    /// The earlier markers' points.
    pub rivals: Vec<Vec<Vector3<f64>>>,
    /// The confusions held.
    pub confusions: Vec<Confusion>,
    /// The points the trust term is centred on: the winner the repair
    /// started from, then each round's admissible layout.
    pub anchor: Vec<Vector3<f64>>,
}

impl CrossRule {
    /// The penalty of the candidate `points`: [`CROSS_PENALTY`] per decade
    /// of each held confusion's probability above the criterion, plus
    /// [`CROSS_TRUST_PER_MM2`] per mm² of squared distance from the anchor.
    pub fn penalty(&self, points: &[Vector3<f64>]) -> f64 {
        let moved: f64 = points
            .iter()
            .zip(&self.anchor)
            .map(|(p, a)| (p - a).norm_squared())
            .sum();
        CROSS_TRUST_PER_MM2 * moved + self.confusion_penalty(points)
    }

    /// [`CROSS_PENALTY`] per decade of each held confusion's probability
    /// above the criterion. The candidate's view is made once per
    /// scenario; a rival's was made when the confusion was held.
    pub fn confusion_penalty(&self, points: &[Vector3<f64>]) -> f64 {
        let max_wrong = CROSS_MARGIN * self.settings.max_wrong();
        let none = vec![None; points.len()];
        let target = Target {
            camera: &self.camera,
            object: points,
            sphere_diameter_mm: self.sphere_diameter_mm,
            point_sigma_px: &none,
        };
        let mut views: Vec<(usize, Option<SeenView>)> = Vec::new();
        let mut penalty = 0.0;
        for c in &self.confusions {
            let rival = &self.rivals[c.rival][..];
            let probability = if !c.candidate_seen {
                c.rival_view.as_ref().and_then(|view| {
                    labelled_confusion(
                        &self.camera,
                        &c.scenario,
                        (rival, view),
                        points,
                        (c.missing, &c.labels, &c.pose),
                    )
                })
            } else {
                let at = match views.iter().position(|(s, _)| *s == c.scenario.index) {
                    Some(at) => at,
                    None => {
                        let view = seen_view(&target, &c.scenario, &self.settings);
                        views.push((c.scenario.index, view));
                        views.len() - 1
                    }
                };
                views[at].1.as_ref().and_then(|view| {
                    labelled_confusion(
                        &self.camera,
                        &c.scenario,
                        (points, view),
                        rival,
                        (c.missing, &c.labels, &c.pose),
                    )
                })
            };
            if let Some(p) = probability.filter(|p| *p > max_wrong) {
                penalty += CROSS_PENALTY * (p / max_wrong).log10();
            }
        }
        penalty
    }

    /// Holds the confusions of `matrix` that involve the candidate (the
    /// last marker of the matrix; the earlier ones are the rivals, in
    /// order) in the viewpoints that fail the floor or come near it
    /// ([`crate::set::CrossPair::near`]), found again in `scenarios`
    /// (those the matrix was computed over) to learn each one's labelling:
    /// a repair that held only the failing ones would move the marker into
    /// the near ones. Returns how many were added.
    pub fn hold(
        &mut self,
        candidate: &[Vector3<f64>],
        matrix: &CrossMatrix,
        scenarios: &[Scenario],
    ) -> usize {
        let last = self.rivals.len();
        let none = vec![
            None;
            candidate
                .len()
                .max(self.rivals.iter().map(Vec::len).max().unwrap_or(0))
        ];
        let mut added = 0;
        for pair in &matrix.pairs {
            let (candidate_seen, rival) = match (pair.marker == last, pair.rival == last) {
                (true, false) => (true, pair.rival),
                (false, true) => (false, pair.marker),
                _ => continue,
            };
            let (seen, model) = if candidate_seen {
                (candidate, &self.rivals[rival][..])
            } else {
                (&self.rivals[rival][..], candidate)
            };
            let target = Target {
                camera: &self.camera,
                object: seen,
                sphere_diameter_mm: self.sphere_diameter_mm,
                point_sigma_px: &none[..seen.len()],
            };
            for index in &pair.near {
                let Some(scenario) = scenarios.iter().find(|s| s.index == *index) else {
                    continue;
                };
                let Some(found) = cross_scenario(&target, model, scenario, &self.settings) else {
                    continue;
                };
                let (Some(labels), Some(pose)) = (found.labels, found.pose) else {
                    continue;
                };
                let held = self.confusions.iter().any(|c| {
                    c.scenario.index == scenario.index
                        && c.rival == rival
                        && c.candidate_seen == candidate_seen
                        && c.missing == found.missing
                        && c.labels == labels
                });
                if !held {
                    let rival_view = if candidate_seen {
                        None
                    } else {
                        seen_view(&target, scenario, &self.settings)
                    };
                    self.confusions.push(Confusion {
                        rival_view,
                        scenario: *scenario,
                        rival,
                        candidate_seen,
                        missing: found.missing,
                        labels,
                        pose,
                    });
                    added += 1;
                }
            }
        }
        added
    }
}

/// What a cross repair did.
#[derive(Debug, Clone)]
pub struct CrossRepair {
    /// The repaired outcome, or the given one when no round cleared the
    /// floor.
    pub outcome: OptimiseOutcome,
    /// Its cross matrix against the earlier markers (the given one when no
    /// round cleared the floor).
    pub matrix: CrossMatrix,
    /// The worst pair's share of viewpoints meeting the floor at its best:
    /// the given matrix's, or a round's full check's when higher (what a
    /// repair that did not clear the floor came to).
    pub best_share: f64,
    /// Rounds run.
    pub rounds: usize,
    /// Confusions held in the end.
    pub held: usize,
    /// The viewpoints checked in the end: those given, and the dips
    /// between them found for the rounds' layouts.
    pub scenarios: Vec<Scenario>,
}

/// A cross check of candidate points over some scenarios.
pub type CrossCheck<'a> = &'a dyn Fn(&[Vector3<f64>], &[Scenario]) -> CrossMatrix;
/// The full cross check of candidate points: over the scenarios given,
/// then over the dips between the volume's viewpoints that it finds
/// (`crate::set::dips`), which join the scenarios.
pub type CrossFullCheck<'a> = &'a dyn Fn(&[Vector3<f64>], &mut Vec<Scenario>) -> CrossMatrix;

/// Repairs `outcome`'s winner against the earlier markers that `rule`
/// holds (module docs). `matrix` is its cross matrix over `scenarios`,
/// `check` computes one for other points (`full_check` with the dips it
/// finds), and `floor` is the
/// identifiability floor the winner must keep. Each round runs
/// Nelder–Mead from the last admissible round's layout (the first from the
/// winner), its trust centred there too, checks its layout on the
/// viewpoints of the held confusions, and only when those pass on every
/// scenario; whatever either check finds failing or near is held from
/// then on. The first layout that meets every single-marker floor over
/// the whole grid and the cross floor on every scenario is the repair's
/// result. That full check adds the round's layout's own dips between the
/// viewpoints (none when the set checks its viewpoints only), which stay
/// checked in later rounds.
#[allow(clippy::too_many_arguments)]
pub(crate) fn repair_cross(
    family: &Family,
    evaluator: &Evaluator,
    floor: Option<IdentifiabilityFloor>,
    settings: &SearchSettings,
    mut rule: CrossRule,
    (outcome, matrix): (OptimiseOutcome, CrossMatrix),
    (check, full_check, mut scenarios): (CrossCheck, CrossFullCheck, Vec<Scenario>),
    stop: &AtomicBool,
) -> Result<CrossRepair, SearchError> {
    let point_sigma = family.layout("", &family.initial()).point_sigmas();
    let full = evaluator.with_identifiability(floor, IdentifyScope::All);
    let thinned: Vec<usize> = (0..evaluator.scenarios().len())
        .step_by(IDENTIFY_THINNING)
        .collect();
    let scoped = evaluator.with_identifiability(floor, IdentifyScope::Scenarios(Arc::new(thinned)));
    // The rounds check the marker's own identifiability only once a
    // round's layout has failed it: the unlabelled solver on a thinned
    // grid costs several times the rest of an evaluation, and the
    // winner's margins against itself are rarely what a move away from
    // the other markers loses.
    let mut guard_identity = false;
    rule.hold(&family.points(&outcome.best.params), &matrix, &scenarios);
    let mut from = outcome.best.params.clone();
    let mut repair = CrossRepair {
        best_share: matrix.worst_share(),
        outcome,
        matrix,
        rounds: 0,
        held: 0,
        scenarios: Vec::new(),
    };
    while repair.rounds < CROSS_ROUNDS && !stop.load(Ordering::Relaxed) {
        repair.rounds += 1;
        let repaired = optimise::repair_round(
            family,
            &if guard_identity { &scoped } else { evaluator }.with_cross(rule.clone()),
            settings,
            CROSS_ROUND_ITERATIONS,
            &from,
            stop,
        )?;
        repair.outcome.evaluations += repaired.evaluations_this_run;
        if repaired.interrupted {
            repair.outcome.interrupted = true;
            break;
        }
        let points = family.points(&repaired.best.params);
        let evaluation = full.evaluate(&points, &point_sigma);
        if !evaluation.admissible() {
            // The next round starts from the same layout under the same
            // held confusions and seed: unless it now guards the marker's
            // identifiability, it would repeat this one exactly.
            if guard_identity || evaluation.meets_identifiability_floor() {
                break;
            }
            guard_identity = true;
            continue;
        }
        let watched: Vec<Scenario> = scenarios
            .iter()
            .filter(|s| rule.confusions.iter().any(|c| c.scenario.index == s.index))
            .copied()
            .collect();
        let quick = check(&points, &watched);
        rule.hold(&points, &quick, &watched);
        from = repaired.best.params.clone();
        rule.anchor = points.clone();
        if !quick.meets_floor() {
            continue;
        }
        // The moved marker's own dips join the viewpoints checked.
        let matrix = full_check(&points, &mut scenarios);
        repair.best_share = repair.best_share.max(matrix.worst_share());
        rule.hold(&points, &matrix, &scenarios);
        if matrix.meets_floor() {
            repair.outcome.best = Candidate {
                params: repaired.best.params,
                evaluation,
                start: repaired.best.start,
            };
            repair.matrix = matrix;
            break;
        }
    }
    repair.held = rule.confusions.len();
    repair.scenarios = scenarios;
    Ok(repair)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::noise::NoiseModel;
    use crate::scenario::ScenarioGrid;
    use crate::set::cross_matrix;
    use crate::sphere_image::Observation;

    const DIAMETER_MM: f64 = 8.0;

    fn marker() -> Vec<Vector3<f64>> {
        vec![
            Vector3::new(0.0, 0.0, 0.0),
            Vector3::new(48.0, 6.0, 0.0),
            Vector3::new(-12.0, 40.0, 9.0),
            Vector3::new(18.0, -31.0, 36.0),
            Vector3::new(-38.0, -14.0, -22.0),
            Vector3::new(29.0, 33.0, -27.0),
        ]
    }

    fn rule(rival: Vec<Vector3<f64>>, anchor: Vec<Vector3<f64>>) -> CrossRule {
        CrossRule {
            camera: Camera::paper(),
            sphere_diameter_mm: DIAMETER_MM,
            settings: IdentifiabilitySettings {
                min_correct: 0.999,
                trials: 0,
                seed: 29,
                observation: Observation::Centre,
                noise: NoiseModel::default(),
            },
            rivals: vec![rival],
            confusions: Vec::new(),
            anchor,
        }
    }

    /// A near copy of a marker is confused with it; the confusions held
    /// from the cross check are priced, less the farther the copy moves
    /// away, and the trust term adds its squared distance.
    #[test]
    fn held_confusions_are_priced_less_as_the_marker_moves_away() {
        let rival = marker();
        let mut copy = rival.clone();
        copy[1].x += 0.5;
        let scenarios = ScenarioGrid::new(
            "500,800".parse().unwrap(),
            "0".parse().unwrap(),
            "0".parse().unwrap(),
            "-30,0,30".parse().unwrap(),
            "0".parse().unwrap(),
            "0".parse().unwrap(),
            "0.5".parse().unwrap(),
        )
        .unwrap()
        .scenarios();
        let mut rule = rule(rival.clone(), copy.clone());
        let sigmas = vec![None; 6];
        let matrix = |points: &[Vector3<f64>]| {
            let objects = [rival.clone(), points.to_vec()];
            let targets: Vec<Target> = objects
                .iter()
                .map(|object| Target {
                    camera: &rule.camera,
                    object,
                    sphere_diameter_mm: DIAMETER_MM,
                    point_sigma_px: &sigmas,
                })
                .collect();
            cross_matrix(
                &targets,
                &["a".to_string(), "b".to_string()],
                &scenarios,
                &rule.settings,
            )
        };
        let found = matrix(&copy);
        assert!(!found.meets_floor());
        let added = rule.hold(&copy, &found, &scenarios);
        assert!(added >= 2, "{added} confusions held");
        assert_eq!(rule.hold(&copy, &found, &scenarios), 0, "held twice");
        let near = rule.confusion_penalty(&copy);
        assert!(near > 1.0, "{near}");
        // The worst case leaves out the blob that differs, so another
        // point moves.
        let mut away = copy.clone();
        away[3].x += 6.0;
        let far = rule.confusion_penalty(&away);
        assert!(far < 0.5 * near, "{far} against {near}");
        assert!((rule.penalty(&away) - far - CROSS_TRUST_PER_MM2 * 36.0).abs() < 1e-9);
        assert!((rule.penalty(&copy) - near).abs() < 1e-12);
    }
}

#[cfg(test)]
mod repair_tests {
    use super::*;
    use crate::search::optimise::tests::setup;
    use crate::search::optimise::Optimiser;
    use crate::search::optimise::Quiet;
    use crate::sphere_image::Observation;

    /// The cross repair of a near copy of an earlier marker (a free shape
    /// of 6 points, each parameter 1% of its range away) under the
    /// identifiability floor `floor`: the repair, the share of the copy's
    /// matrix before it, how far it moved the copy (mm), and whether its
    /// matrix is the check of the repaired layout.
    fn repair_near_copy(floor: Option<IdentifiabilityFloor>) -> (CrossRepair, f64, f64, bool) {
        // A free shape: a copy scaled (a biprism of another size) looks
        // the same from farther away, and no repair separates them.
        let (_, evaluator) = setup();
        let family = Family::new(
            crate::family::FamilyKind::Custom {
                count: 6,
                start: None,
            },
            evaluator.constraints().envelope,
            10.0,
        )
        .unwrap();
        // The earlier marker, and the candidate a near copy of it: each
        // parameter 1% of its range away.
        let rival = family.points(&family.initial());
        let (lower, upper) = family.bounds();
        let params: Vec<f64> = family
            .initial()
            .iter()
            .enumerate()
            .map(|(k, p)| p + [-0.01, 0.01][k % 2] * (upper[k] - lower[k]))
            .collect();
        let candidate = family.points(&params);
        let scenarios = evaluator.scenarios().to_vec();
        let settings = IdentifiabilitySettings {
            min_correct: 0.999,
            trials: 0,
            seed: 3,
            observation: Observation::Centre,
            noise: crate::noise::NoiseModel::default(),
        };
        let camera = Camera::paper();
        let sigmas = vec![None; rival.len()];
        let check = |points: &[Vector3<f64>], scenarios: &[Scenario]| {
            let objects = [rival.clone(), points.to_vec()];
            let targets: Vec<Target> = objects
                .iter()
                .map(|object| Target {
                    camera: &camera,
                    object,
                    sphere_diameter_mm: 10.0,
                    point_sigma_px: &sigmas,
                })
                .collect();
            crate::set::cross_pairs(
                &targets,
                &["a".to_string(), "b".to_string()],
                scenarios,
                &settings,
                &[(1, 0), (0, 1)],
            )
        };
        let matrix = check(&candidate, &scenarios);
        assert!(!matrix.meets_floor(), "a near copy is confusable");
        let matrix_share = matrix.worst_share();
        let search = SearchSettings {
            optimiser: Optimiser::NelderMead,
            starts: 1,
            start_jitter: 0.0,
            iterations: 10,
            particles: 0,
            polish_iterations: 0,
            seed: 5,
        };
        let outcome = optimise::run(
            &family,
            &evaluator,
            &SearchSettings {
                iterations: 1,
                ..search.clone()
            },
            &AtomicBool::new(false),
            Arc::new(Quiet),
            None,
        )
        .unwrap();
        let outcome = OptimiseOutcome {
            best: Candidate {
                params: params.clone(),
                evaluation: evaluator.evaluate(&candidate, &sigmas),
                start: 0,
            },
            ..outcome
        };
        let rule = CrossRule {
            camera,
            sphere_diameter_mm: 10.0,
            settings,
            rivals: vec![rival.clone()],
            confusions: Vec::new(),
            anchor: candidate.clone(),
        };
        let repair = repair_cross(
            &family,
            &evaluator,
            floor,
            &search,
            rule,
            (outcome, matrix),
            (
                &check,
                &|points: &[Vector3<f64>], scenarios: &mut Vec<Scenario>| check(points, scenarios),
                scenarios.clone(),
            ),
            &AtomicBool::new(false),
        )
        .unwrap();
        let repaired = family.points(&repair.outcome.best.params);
        let rechecked = check(&repaired, &scenarios) == repair.matrix;
        let moved = repaired
            .iter()
            .zip(&candidate)
            .map(|(p, a)| (p - a).norm())
            .fold(0.0, f64::max);
        (repair, matrix_share, moved, rechecked)
    }

    /// A near copy of the earlier marker is confused with it; the repair
    /// moves it until the cross floor holds in every viewpoint, and the
    /// repaired marker stays admissible.
    #[test]
    fn the_repair_clears_a_copy_of_an_earlier_marker() {
        let (repair, matrix_share, moved, rechecked) = repair_near_copy(None);
        assert!(repair.rounds >= 1 && repair.held > 0);
        assert!(repair.matrix.meets_floor(), "{:?}", repair.matrix);
        // A cleared repair's best share is its matrix's (design_set relies on it).
        assert_eq!(repair.best_share, repair.matrix.worst_share());
        assert!(repair.best_share > matrix_share, "{}", repair.best_share);
        assert!(repair.outcome.best.evaluation.admissible());
        assert!(rechecked);
        assert!(moved > 0.1, "moved {moved} mm");
    }

    /// Under an identifiability floor no layout meets (every viewpoint
    /// labelled right with probability 1 − 1e-15), the first round misses
    /// it, the second guards it and misses it too, and the repair ends
    /// there: a third round would repeat the second exactly.
    #[test]
    fn a_round_that_would_repeat_the_last_ends_the_repair() {
        let floor = IdentifiabilityFloor {
            min_share: 1.0,
            min_correct: 1.0 - 1e-15,
        };
        let (repair, matrix_share, _, _) = repair_near_copy(Some(floor));
        assert_eq!(repair.rounds, 2);
        assert!(!repair.matrix.meets_floor());
        assert_eq!(repair.best_share, matrix_share);
    }
}
