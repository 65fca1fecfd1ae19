//! `search --set N`: N markers designed for one working range and one
//! envelope, each meeting the single-marker floors, no two confusable.
//!
//! **Method** (sequential design with the earlier markers as fixed
//! rivals): marker 1 is the single-marker search's winner (the
//! optimiser's multistart, then the identifiability repair rounds), with
//! the configuration's seed: what one marker reaches alone. Marker k is
//! searched the same way from the seed of its try; its winner is kept
//! when it is admissible (constraints, availability and identifiability
//! floors) and the cross matrix between it and every marker kept before
//! meets the cross floor in both directions (over every
//! [`SetSearchSettings::cross_thinning`]th scenario of the working
//! volume, and at the dips between the scenarios where a pair comes near
//! the floor, [`crate::set::dips`], unless
//! [`SetSearchSettings::between_samples`] is off). An admissible winner
//! that fails only the cross floor is first repaired ([`repair`]: the confusions found are held fixed and
//! priced while Nelder–Mead moves the marker away from them, for a few
//! rounds; each round's layout has its own dips searched and checked).
//! A single-marker search lands in the same basin from most
//! seeds, so new tries alone rarely get clear of the earlier markers.
//! Otherwise the next try runs from another seed; after
//! [`SetSearchSettings::tries`] tries the set is refused with the reason.
//! The set's objective is the worst (or the mean) of its markers'
//! accuracies; each marker's accuracy beside marker 1's is the price of
//! being told apart. The final cross matrix covers every scenario: each
//! pair as the try that kept its later marker checked it (the tries check
//! only the pairs of their own marker), or computed again when the tries'
//! check was thinned.

pub mod repair;
pub mod validation;

use super::analysis::{held_out_check, Analysis};
use super::identify::{enforce_identifiability, Quiet};
use super::optimise;
use super::supports::{enforce_supports, RepairBudget};
use super::SearchError;
use super::{HeldOutCheck, IdentifiabilityFigures, SearchConfig, SupportsBooks};
use crate::identifiability::IdentifiabilitySettings;
use crate::layout::Layout;
use crate::montecarlo::Target;
use crate::report::number::share_percent;
use crate::scenario::Scenario;
use crate::set::dips::{find_dips, Sample};
use crate::set::{all_pairs, cross_pairs, CrossMatrix, MAX_MARKERS, MIN_MARKERS};
use nalgebra::Vector3;
use repair::{repair_cross, CrossRule};
use serde::Serialize;
use std::fmt;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::Instant;

/// Default tries per marker.
pub const DEFAULT_SET_TRIES: usize = 4;
/// Default thinning of the scenarios the tries' cross check uses: 1, every
/// scenario, since checking every 4th let a 4-marker set through whose
/// full matrix failed 1 to 7 of 166 viewpoints in five pairs (the cross
/// check costs seconds beside a search's minutes).
pub const DEFAULT_CROSS_THINNING: usize = 1;
/// Seed step between tries (a prime, so tries of different markers do
/// not share seeds).
pub const TRY_SEED_STEP: u64 = 7919;

/// How the set's markers are scored together.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum SetObjective {
    /// The worst marker's accuracy.
    Worst,
    /// The mean of the markers' accuracies.
    Mean,
}

impl std::str::FromStr for SetObjective {
    type Err = String;
    fn from_str(text: &str) -> Result<Self, Self::Err> {
        match text.trim() {
            "worst" => Ok(SetObjective::Worst),
            "mean" => Ok(SetObjective::Mean),
            other => Err(format!(
                "unknown set objective '{other}'; use worst or mean"
            )),
        }
    }
}

impl SetSearchSettings {
    /// Settings for `markers` markers, each checked before any work; the
    /// first bad value is named by its field.
    pub fn new(
        markers: usize,
        objective: SetObjective,
        min_cross: Option<f64>,
        tries: usize,
    ) -> Result<Self, crate::config::ConfigError> {
        use crate::config::ConfigError;
        if !(MIN_MARKERS..=MAX_MARKERS).contains(&markers) {
            return Err(ConfigError::new(
                "markers",
                format!("must be {MIN_MARKERS} to {MAX_MARKERS} markers, got {markers}"),
            ));
        }
        let min_cross = min_cross.filter(|p| *p > 0.0 && *p < 1.0).ok_or_else(|| {
            ConfigError::new(
                "min_cross",
                "must be a probability between 0 and 1 (exclusive)",
            )
        })?;
        if tries == 0 {
            return Err(ConfigError::new("tries", "must be at least 1"));
        }
        Ok(SetSearchSettings {
            markers,
            objective,
            min_cross,
            tries,
            cross_thinning: DEFAULT_CROSS_THINNING,
            between_samples: true,
        })
    }
}

/// The set's own settings.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SetSearchSettings {
    /// Markers in the set (2 to 8).
    pub markers: usize,
    /// How the markers' accuracies are scored together.
    pub objective: SetObjective,
    /// Per-viewpoint floor of cross-identifiability: a viewpoint counts
    /// when the predicted confusion probability is at most 1 − this, and a
    /// pair meets the floor when this share of its viewpoints counts.
    pub min_cross: f64,
    /// Searches per marker at most.
    pub tries: usize,
    /// Every this many scenarios join the tries' cross check.
    pub cross_thinning: usize,
    /// Whether the dips between the volume's viewpoints join every cross
    /// check ([`crate::set::dips`]; `search --samples-only` turns it off).
    pub between_samples: bool,
}

/// One marker of a designed set.
#[derive(Debug, Clone, Serialize)]
pub struct SetMarker {
    /// The layout (named `<name>-k`).
    pub layout: Layout,
    /// Its accuracy (1 = the paper's biprism in the envelope; lower is
    /// better).
    pub accuracy: f64,
    /// The optimiser seed of the try that was kept.
    pub seed: u64,
    /// Tries it took.
    pub tries: usize,
    /// Rounds of the cross repair its kept try took ([`repair`]).
    pub cross_repair_rounds: usize,
    /// Its identifiability over the working volume.
    pub identifiability: Option<IdentifiabilityFigures>,
    /// It and the paper's biprism as printed, and its repair to the floor
    /// as printed (None: not checked), as in a single search.
    pub printed: Option<SupportsBooks>,
    /// It and the paper's biprism to first order on the held-out grid, as
    /// a single search's winner is checked.
    pub held_out: HeldOutCheck,
}

/// A designed set.
#[derive(Debug, Clone, Serialize)]
pub struct SetSearchOutcome {
    /// The set's settings.
    pub settings: SetSearchSettings,
    /// The markers, in set order.
    pub markers: Vec<SetMarker>,
    /// What one marker reaches alone: marker 1's accuracy (the
    /// single-marker search's winner).
    pub alone_accuracy: f64,
    /// The set's objective: the worst or mean accuracy.
    pub objective: f64,
    /// The cross matrix over every scenario of the working volume.
    pub matrix: CrossMatrix,
    /// Scenarios in the working volume.
    pub scenarios: usize,
    /// Viewpoints between them (the dips near the floor) that the kept
    /// markers' cross checks added.
    pub dips: usize,
    /// Seconds of the whole design.
    pub seconds: f64,
}

/// Refuses a set size outside 2…8, before any work.
pub fn check_set_size(markers: usize) -> Result<(), SearchError> {
    if !(MIN_MARKERS..=MAX_MARKERS).contains(&markers) {
        return Err(SearchError::Config(crate::config::ConfigError::new(
            "set",
            format!("must be {MIN_MARKERS} to {MAX_MARKERS} markers, got {markers}"),
        )));
    }
    Ok(())
}

/// How a try of a set's marker ended.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum TryVerdict {
    /// The try's winner is the marker.
    Kept,
    /// Its winner misses a floor of its own: a constraint, availability or
    /// identifiability.
    NotAdmissible,
    /// Its winner as printed misses the availability floor.
    NotAsPrinted,
    /// Its winner, repaired, is cross-identifiable with the earlier markers
    /// in this share of the checked viewpoints only (the worst pair's, at
    /// the best the repair's rounds reached).
    Confusable {
        /// The worst pair's share of viewpoints that meet the floor.
        share: f64,
        /// The floor.
        floor: f64,
    },
}

impl TryVerdict {
    /// Why the try was refused; None when it was kept.
    pub fn reason(&self) -> Option<String> {
        match self {
            TryVerdict::Kept => None,
            TryVerdict::NotAdmissible => Some(
                "it misses a floor of its own (constraints, availability or identifiability)"
                    .to_string(),
            ),
            TryVerdict::NotAsPrinted => {
                Some("as printed it misses the availability floor".to_string())
            }
            TryVerdict::Confusable { share, floor } => Some(format!(
                "cross-identifiable with the earlier markers in {}% of the checked viewpoints, the floor {}%",
                share_percent(*share),
                share_percent(*floor)
            )),
        }
    }
}

impl fmt::Display for TryVerdict {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.reason() {
            None => f.write_str("kept"),
            Some(reason) => write!(f, "refused: {reason}"),
        }
    }
}

/// A set search keeps nothing part-way: once asked to stop, it ends.
fn stopped(stop: &AtomicBool) -> Result<(), SearchError> {
    if stop.load(std::sync::atomic::Ordering::SeqCst) {
        let kept = "interrupted; no set written (a set search keeps nothing part-way)";
        return Err(crate::kernel::Interrupted::keeping(kept).into());
    }
    Ok(())
}

/// Designs the set (module docs). `on_try(marker, try, verdict)` hears
/// each try's end.
pub fn design_set(
    config: &SearchConfig,
    set: &SetSearchSettings,
    stop: &AtomicBool,
    on_try: &dyn Fn(usize, usize, TryVerdict),
) -> Result<SetSearchOutcome, SearchError> {
    check_set_size(set.markers)?;
    if !(set.min_cross > 0.0 && set.min_cross < 1.0) {
        return Err(SearchError::Config(crate::config::ConfigError::new(
            "min_cross_identifiability",
            format!("must be a share in (0, 1), got {}", set.min_cross),
        )));
    }
    if set.tries == 0 || set.cross_thinning == 0 {
        return Err(SearchError::Config(crate::config::ConfigError::new(
            "set_tries",
            "and the cross thinning must be at least 1".to_string(),
        )));
    }
    let started = Instant::now();
    let analysis = Analysis::new(config)?;
    let family = analysis.family();
    let evaluator = analysis.evaluator();
    let scenarios: Vec<Scenario> = evaluator.scenarios().to_vec();
    let thinned: Vec<Scenario> = scenarios
        .iter()
        .step_by(set.cross_thinning)
        .copied()
        .collect();
    let cross_settings = IdentifiabilitySettings {
        min_correct: set.min_cross,
        trials: 0,
        seed: config.objective.seed,
        observation: config.objective.observation,
        noise: config.objective.noise,
    };
    let diameter = config.constraints.sphere_diameter_mm;
    let paper = super::hand_designs(&config.constraints.envelope, diameter).swap_remove(0);
    // Each try's winner checked (and repaired) as printed, as a single
    // search's is; `budget` CHECK_ONLY once a cross repair has moved it.
    let printed = |outcome: optimise::OptimiseOutcome,
                   settings: &optimise::SearchSettings,
                   budget: RepairBudget|
     -> Result<(optimise::OptimiseOutcome, Option<SupportsBooks>), SearchError> {
        match config.supports {
            Some(max_hidden) => {
                let (outcome, books, _) = enforce_supports(
                    family, &evaluator, &paper, max_hidden, settings, budget, outcome, stop,
                )?;
                Ok((outcome, Some(books)))
            }
            None => Ok((outcome, None)),
        }
    };
    // The volume's samples with their unit-cube points: where the dips
    // between them are searched from (`crate::set::dips`).
    let samples: Vec<Sample> = scenarios
        .iter()
        .copied()
        .zip(config.volume.unit_points())
        .collect();
    let between = set.between_samples.then_some(&samples[..]);
    let mut markers: Vec<SetMarker> = Vec::with_capacity(set.markers);
    // The pairs of each kept marker with the markers before it, as its
    // try checked them.
    let mut checked_pairs = Vec::new();
    let mut dips = 0;
    for k in 0..set.markers {
        let mut best_share: Option<f64> = None;
        let mut last = TryVerdict::Kept;
        let mut kept = None;
        for attempt in 0..set.tries {
            let seed = config
                .search
                .seed
                .wrapping_add((k * set.tries + attempt) as u64 * TRY_SEED_STEP);
            let settings = optimise::SearchSettings {
                seed,
                ..config.search.clone()
            };
            let outcome =
                optimise::run(family, &evaluator, &settings, stop, Arc::new(Quiet), None)?;
            stopped(stop)?;
            let outcome = match config.min_identifiability {
                Some(floor) => {
                    enforce_identifiability(family, &evaluator, floor, &settings, outcome, stop)?.0
                }
                None => outcome,
            };
            let (mut outcome, mut books) = printed(outcome, &settings, RepairBudget::SEARCH)?;
            let met_as_printed =
                |books: &Option<SupportsBooks>| books.as_ref().is_none_or(|b| b.met);
            let mut verdict = if !outcome.best.evaluation.admissible() {
                TryVerdict::NotAdmissible
            } else if !met_as_printed(&books) {
                TryVerdict::NotAsPrinted
            } else {
                TryVerdict::Kept
            };
            let mut rounds = 0;
            if verdict == TryVerdict::Kept && !markers.is_empty() {
                let rivals: Vec<Vec<Vector3<f64>>> =
                    markers.iter().map(|m| m.layout.positions()).collect();
                let pairs: Vec<(usize, usize)> = (0..k).flat_map(|j| [(k, j), (j, k)]).collect();
                let with = |points: &[Vector3<f64>]| {
                    let mut objects = rivals.clone();
                    objects.push(points.to_vec());
                    objects
                };
                let check = |points: &[Vector3<f64>], scenarios: &[Scenario]| {
                    let objects = with(points);
                    matrix_of(config, &objects, scenarios, &cross_settings, &pairs)
                };
                let full = |points: &[Vector3<f64>], scenarios: &mut Vec<Scenario>| {
                    let objects = with(points);
                    let on = (scenarios, between);
                    full_matrix(config, &objects, on, &cross_settings, &pairs)
                };
                let mut checked = thinned.clone();
                let mut matrix = full(&family.points(&outcome.best.params), &mut checked);
                let mut share = matrix.worst_share();
                if !matrix.meets_floor() {
                    let rule = CrossRule {
                        camera: config.camera,
                        sphere_diameter_mm: diameter,
                        settings: cross_settings,
                        rivals: rivals.clone(),
                        confusions: Vec::new(),
                        anchor: family.points(&outcome.best.params),
                    };
                    let repair = repair_cross(
                        family,
                        &evaluator,
                        config.min_identifiability,
                        &settings,
                        rule,
                        (outcome, matrix),
                        (&check, &full, checked),
                        stop,
                    )?;
                    // A matrix that meets the floor is the best one seen.
                    (outcome, matrix, rounds, share) = (
                        repair.outcome,
                        repair.matrix,
                        repair.rounds,
                        repair.best_share,
                    );
                    checked = repair.scenarios;
                    // The repair moved it: checked as printed again.
                    (outcome, books) = printed(outcome, &settings, RepairBudget::CHECK_ONLY)?;
                }
                best_share = Some(best_share.map_or(share, |b: f64| b.max(share)));
                verdict = if !matrix.meets_floor() {
                    TryVerdict::Confusable {
                        share,
                        floor: set.min_cross,
                    }
                } else if !met_as_printed(&books) {
                    TryVerdict::NotAsPrinted
                } else {
                    checked_pairs.extend(matrix.pairs);
                    dips += checked.len() - thinned.len();
                    TryVerdict::Kept
                };
            }
            stopped(stop)?;
            on_try(k + 1, attempt + 1, verdict);
            last = verdict;
            if verdict == TryVerdict::Kept {
                let name = format!("{}-{}", config.name, k + 1);
                let mut layout = family.layout(&name, &outcome.best.params);
                let mut provenance = analysis.provenance();
                provenance["set"] = serde_json::json!({
                    "marker": k + 1,
                    "of": set.markers,
                    "seed": seed,
                    "cross_repair_rounds": rounds,
                });
                layout.provenance = Some(provenance);
                let evaluation = &outcome.best.evaluation;
                let held_out = held_out_check(config, &evaluator, &layout, &paper);
                kept = Some(SetMarker {
                    held_out,
                    layout,
                    accuracy: evaluation.accuracy,
                    seed,
                    tries: attempt + 1,
                    cross_repair_rounds: rounds,
                    identifiability: evaluation.identifiability.clone(),
                    printed: books,
                });
                break;
            }
        }
        match kept {
            Some(marker) => markers.push(marker),
            None => {
                return Err(SearchError::Unsatisfiable(format!(
                    "marker {} of {}: {} met the floors{}; a larger --envelope, more spheres (--points with --family custom), a lower --min-cross-identifiability or more --set-tries would make it feasible, or a smaller --set ({} found)",
                    k + 1,
                    set.markers,
                    match set.tries {
                        1 => "its one search never".to_string(),
                        n => format!("none of {n} searches"),
                    },
                    match best_share {
                        Some(share) => format!(
                            " (the best was {})",
                            TryVerdict::Confusable {
                                share,
                                floor: set.min_cross
                            }
                            .reason()
                            .unwrap_or_default()
                        ),
                        None => format!(
                            " (none reached the cross check; the last: {})",
                            last.reason().unwrap_or_default()
                        ),
                    },
                    match markers.len() {
                        1 => "1 marker was".to_string(),
                        n => format!("{n} markers were"),
                    }
                )));
            }
        }
    }
    let objects: Vec<Vec<Vector3<f64>>> = markers.iter().map(|m| m.layout.positions()).collect();
    // Each pair was checked over every scenario when its later marker was
    // kept; a thinned check is done again over every one.
    let mut matrix = if set.cross_thinning == 1 {
        checked_pairs.sort_by_key(|p| (p.marker, p.rival));
        CrossMatrix {
            markers: Vec::new(),
            min_cross: set.min_cross,
            pairs: checked_pairs,
        }
    } else {
        let mut checked = scenarios.clone();
        let pairs = all_pairs(objects.len());
        let matrix = full_matrix(
            config,
            &objects,
            (&mut checked, between),
            &cross_settings,
            &pairs,
        );
        dips = checked.len() - scenarios.len();
        matrix
    };
    matrix.markers = markers.iter().map(|m| m.layout.name.clone()).collect();
    let accuracies: Vec<f64> = markers.iter().map(|m| m.accuracy).collect();
    let objective = match set.objective {
        SetObjective::Worst => accuracies.iter().copied().fold(f64::MIN, f64::max),
        SetObjective::Mean => accuracies.iter().sum::<f64>() / accuracies.len() as f64,
    };
    Ok(SetSearchOutcome {
        settings: set.clone(),
        alone_accuracy: markers[0].accuracy,
        objective,
        markers,
        matrix,
        scenarios: scenarios.len(),
        dips,
        seconds: started.elapsed().as_secs_f64(),
    })
}

/// The cross matrix of `pairs` (seen, offered) of `objects` (one sphere
/// diameter, no per-point σ) over `scenarios`.
fn matrix_of(
    config: &SearchConfig,
    objects: &[Vec<Vector3<f64>>],
    scenarios: &[Scenario],
    settings: &IdentifiabilitySettings,
    pairs: &[(usize, usize)],
) -> CrossMatrix {
    let none = vec![None; objects.iter().map(Vec::len).max().unwrap_or(0)];
    let targets: Vec<Target> = objects
        .iter()
        .map(|object| target(config, object, &none))
        .collect();
    let names: Vec<String> = (1..=objects.len())
        .map(|k| format!("{}-{k}", config.name))
        .collect();
    cross_pairs(&targets, &names, scenarios, settings, pairs)
}

/// `object` seen by `config`'s camera, spheres of its diameter, no
/// per-point σ (`none` holds a None for each point at least).
fn target<'a>(
    config: &'a SearchConfig,
    object: &'a [Vector3<f64>],
    none: &'a [Option<f64>],
) -> Target<'a> {
    Target {
        camera: &config.camera,
        object,
        sphere_diameter_mm: config.constraints.sphere_diameter_mm,
        point_sigma_px: &none[..object.len()],
    }
}

/// [`matrix_of`] over `scenarios`, then, given the volume's `samples`
/// (with their unit-cube points), over the dips between them
/// ([`crate::set::dips::find_dips`], followed from the samples and from
/// the labellings this check found) whose predicted confusion exceeds
/// [`crate::set::NEAR_SHARE`] of the criterion; those join `scenarios`,
/// numbered after them.
fn full_matrix(
    config: &SearchConfig,
    objects: &[Vec<Vector3<f64>>],
    (scenarios, samples): (&mut Vec<Scenario>, Option<&[Sample]>),
    settings: &IdentifiabilitySettings,
    pairs: &[(usize, usize)],
) -> CrossMatrix {
    let mut matrix = matrix_of(config, objects, scenarios, settings, pairs);
    let Some(samples) = samples else {
        return matrix;
    };
    let near = crate::set::NEAR_SHARE * settings.max_wrong();
    let none = vec![None; objects.iter().map(Vec::len).max().unwrap_or(0)];
    let mut dips: Vec<Scenario> = Vec::new();
    for &(i, j) in pairs {
        let found = matrix.pair(i, j).map_or(&[][..], |p| &p.found[..]);
        let pair_dips = find_dips(
            &target(config, &objects[i], &none),
            &objects[j],
            &config.volume,
            samples,
            found,
            settings,
            0,
        );
        dips.extend(
            pair_dips
                .into_iter()
                .filter(|d| d.confusion_probability > near)
                .map(|d| d.scenario),
        );
    }
    let next = scenarios.iter().map(|s| s.index + 1).max().unwrap_or(0);
    for (k, scenario) in dips.iter_mut().enumerate() {
        scenario.index = next + k;
    }
    matrix.absorb(matrix_of(config, objects, &dips, settings, pairs));
    scenarios.extend(dips);
    matrix
}

/// The legend of the set report's table of markers, up to the held-out
/// grid it names.
const MARKERS_LEGEND: &str = concat!(
    "Accuracy: the objective's accuracy term (1 = the paper's biprism scaled to the envelope; lower is better). ",
    "Alone: what one marker reaches (marker 1, the single-marker search's winner). ",
    "Rotation: first-order RMS rotation error of the marker and of the paper's biprism on the held-out grid",
);

/// The head of the set report's table of markers.
const MARKERS_HEAD: &str = concat!(
    "| marker | accuracy in the set | alone | price | rotation against the paper's biprism | identifiable ",
    "| available as printed (spheres alone; the paper's biprism as printed) | tries | cross repair rounds | seed |\n",
    "|---|---|---|---|---|---|---|---|---|---|\n",
);

/// The set's report: each marker's accuracy alone and in the set, and the
/// N×N matrix of the smallest cross margin (px) and the predicted
/// confusion rate (Markdown).
pub fn set_report(outcome: &SetSearchOutcome, command: &str) -> String {
    let sig = |v: f64, digits: usize| crate::report::number::significant(Some(v), digits);
    let n = outcome.markers.len();
    let mut text = format!(
        "# Marker set: {} markers\n\n`{command}`\n\nDesigned in {:.1} s over {} scenarios{}. Objective ({}): {}. Cross floor: a viewpoint counts when the predicted confusion probability is at most {}; every pair meets the floor: {}.\n\n",
        n,
        outcome.seconds,
        outcome.scenarios,
        if outcome.settings.between_samples {
            format!(
                " and {} viewpoints between them where a pair came near the floor (the dips' floors, docs/formats.md \"Between the viewpoints\"; the matrices count them)",
                outcome.dips
            )
        } else {
            " (their viewpoints only: --samples-only)".to_string()
        },
        match outcome.settings.objective {
            SetObjective::Worst => "the worst marker's accuracy",
            SetObjective::Mean => "the mean accuracy",
        },
        sig(outcome.objective, 4),
        sig(1.0 - outcome.settings.min_cross, 2),
        if outcome.matrix.meets_floor() { "yes" } else { "no" },
    );
    let held_out = outcome.markers.first().map_or(String::new(), |m| {
        format!("{} scenarios: {}", m.held_out.scenarios, m.held_out.grid)
    });
    text.push_str(&format!(
        "## Markers\n\n{MARKERS_LEGEND} ({held_out}).\n\n{MARKERS_HEAD}"
    ));
    for (k, m) in outcome.markers.iter().enumerate() {
        let identifiable = m.identifiability.as_ref().map_or("—".to_string(), |f| {
            format!("{} of {}", f.identifiable, f.checked)
        });
        let printed = m.printed.as_ref().map_or("not checked".to_string(), |b| {
            format!(
                "{:.1}% ({:.1}%; {:.1}%){}",
                100.0 * b.winner.availability,
                100.0 * b.winner.availability_without,
                100.0 * b.paper.availability,
                if b.rounds > 0 {
                    format!(", {} repair rounds", b.rounds)
                } else {
                    String::new()
                }
            )
        });
        let held = &m.held_out;
        let rotation = match (
            held.winner_rotation_rms_deg,
            held.paper_rotation_rms_deg,
            held.rotation_reduction_percent,
        ) {
            (Some(marker), Some(paper), Some(lower)) => format!(
                "{} ° vs {} °, {lower:.1}% lower",
                sig(marker, 4),
                sig(paper, 4)
            ),
            _ => "not measurable".to_string(),
        };
        text.push_str(&format!(
            "| {} ({}) | {} | {} | {:+.1}% | {rotation} | {} | {printed} | {} | {} | {} |\n",
            k + 1,
            m.layout.name,
            sig(m.accuracy, 4),
            sig(outcome.alone_accuracy, 4),
            100.0 * (m.accuracy / outcome.alone_accuracy - 1.0),
            identifiable,
            m.tries,
            m.cross_repair_rounds,
            m.seed
        ));
    }
    text.push_str(&matrix_markdown(&outcome.matrix));
    text
}

/// The cross matrix as Markdown tables: the smallest cross margin (px),
/// the mean predicted confusion rate per viewpoint and the viewpoints
/// failing the floor, row the marker seen, column the rival.
pub fn matrix_markdown(matrix: &CrossMatrix) -> String {
    let sig = |v: f64, digits: usize| crate::report::number::significant(Some(v), digits);
    let n = matrix.markers.len();
    let mut text = String::new();
    for (title, cell) in [
        (
            "Smallest cross margin, px (row: the marker seen; column: the marker offered as the model; > gate: no fit within the gate)",
            0,
        ),
        (
            "Predicted confusion rate per viewpoint (mean over the row marker's visible viewpoints)",
            1,
        ),
        ("Viewpoints failing the cross floor", 2),
    ] {
        text.push_str(&format!("\n## {title}\n\n|  |"));
        for j in 0..n {
            text.push_str(&format!(" {} |", j + 1));
        }
        text.push_str("\n|---|");
        text.push_str(&"---|".repeat(n));
        text.push('\n');
        for i in 0..n {
            text.push_str(&format!("| {} |", i + 1));
            for j in 0..n {
                let value = match matrix.pair(i, j) {
                    None => "—".to_string(),
                    Some(p) => match cell {
                        0 => p
                            .smallest_margin_px
                            .map_or("> gate".to_string(), |m| sig(m, 3)),
                        1 => sig(p.mean_confusion, 2),
                        _ => format!("{} of {}", p.failing.len(), p.visible),
                    },
                };
                text.push_str(&format!(" {value} |"));
            }
            text.push('\n');
        }
    }
    text
}

#[cfg(test)]
mod tests {
    use super::TryVerdict;

    #[test]
    fn a_refused_try_names_the_floor_it_missed() {
        assert_eq!(TryVerdict::Kept.to_string(), "kept");
        assert!(TryVerdict::NotAdmissible
            .to_string()
            .contains("a floor of its own"));
        assert!(TryVerdict::NotAsPrinted.to_string().contains("as printed"));
        let confusable = TryVerdict::Confusable {
            share: 0.96,
            floor: 0.9999,
        }
        .to_string();
        assert!(
            confusable.contains("in 96.0% of the checked viewpoints, the floor 99.99%"),
            "{confusable}"
        );
    }
}
