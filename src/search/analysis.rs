//! The search as a pure analysis: a checked [`SearchConfig`] in, a
//! serialisable [`SearchSummary`] out, with no file and no printing.
//! [`run`] optimises the family over the scenario grid, enforces the
//! identifiability floor, compares the winner with its start and the hand
//! designs on the same scenarios and draws, checks it on a held-out grid,
//! sweeps the Pareto front when asked, and validates the winner. Progress
//! and log lines go to an [`Observer`], which may stop the run in any phase.
//!
//! The workflow ([`super::workflow`]) runs the same analysis with its
//! [`Hooks`]: checkpoints for the optimisation and a listener that keeps
//! the best layout so far on disk. The analysis never touches a file itself.
//!
//! ```no_run
//! use layout_opt::observer::Silent;
//! use layout_opt::search::analysis::{self, Analysed};
//! use layout_opt::search::SearchConfig;
//!
//! let mut config = SearchConfig::new("my-marker", &std::env::temp_dir());
//! config.search.starts = 2;
//! config.search.iterations = 100;
//! if let Analysed::Finished(finished) = analysis::run(&config, &mut Silent)? {
//!     println!("objective {:.4}", finished.summary.outcome.best.evaluation.objective);
//! }
//! # Ok::<(), layout_opt::search::SearchError>(())
//! ```

use super::checkpoint::Checkpoints;
use super::compare::{compare, hand_designs, CompareProgress, Comparison, DesignRow};
use super::config::{held_out_grid, SearchConfig};
use super::error::SearchError;
use super::feasibility::unsatisfiable;
use super::front::{self, FrontFiles};
use super::identify::{enforce_identifiability, Quiet, IDENTIFY_ROUNDS};
use super::optimise::{self, Candidate, OptimiseOutcome, SearchObserver, SearchSettings};
use super::summary::{
    verdicts, ChainRow, HeldOutCheck, IdentifyBooks, SearchHeader, SearchSummary, SupportsBooks,
};
use super::supports::{enforce_supports, PrintedParts, RepairBudget, SUPPORT_ROUNDS};
use super::{Evaluator, IdentifyScope};
use crate::family::{Family, FamilyError, FamilyKind};
use crate::layout::Layout;
use crate::montecarlo::{MonteCarloConfig, MonteCarloError, DEFAULT_GROSS_THRESHOLD_DEG};
use crate::observer::{watch, Observer};
use crate::validate::{self, ValidateConfig, ValidateError};
use crate::volume::WorkingVolume;
use nalgebra::Vector3;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Instant;

/// Progress phase of the optimisation: iterations of every start.
pub const PHASE_SEARCH: &str = "search";
/// Progress phase of the comparison with the hand designs: Monte-Carlo
/// scenarios of every design on both seeds.
pub const PHASE_COMPARE: &str = "comparison";
/// Progress phase of the winner's sensitivity report: its scenarios.
pub const PHASE_VALIDATE: &str = "validation";
/// Progress phase of the Pareto front's sweep: its levels.
pub const PHASE_FRONT: &str = "front";
/// Progress phase of the identifiability repair (one step per round).
pub const PHASE_IDENTIFY: &str = "identifiability";
/// Progress phase of the winner's check as printed, and its repair (one
/// step for the check, one per round).
pub const PHASE_SUPPORTS: &str = "supports";

/// The family and its free parameters, in words.
pub fn family_description(family: &Family) -> String {
    match family.kind() {
        FamilyKind::Biprism {
            centre,
            tilts,
            free_hub,
        } => format!(
            "biprism: 6 arm lengths{}{}{}",
            if *tilts { " + 2 tilts per arm" } else { "" },
            if *free_hub {
                " + hub position"
            } else {
                ", hub at the envelope centre"
            },
            if *centre {
                " + centre point"
            } else {
                ", no centre point"
            }
        ),
        FamilyKind::Tetrahedron { centre } => format!(
            "tetrahedron: 4 free vertices{}",
            if *centre { " + centre point" } else { "" }
        ),
        FamilyKind::Custom {
            start: Some(layout),
            ..
        } => format!(
            "custom: {} points from {}, {} fixed",
            layout.points.len(),
            layout.name,
            layout.points.iter().filter(|p| p.fixed).count()
        ),
        FamilyKind::Custom { count, .. } => format!("custom: {count} free points"),
    }
}

/// First-order figures of `winner` and the paper's biprism (`paper`) on
/// the held-out grid of `config`'s volume (midpoints of a grid's values;
/// a sampled volume scrambled with another seed).
pub(crate) fn held_out_check(
    config: &SearchConfig,
    evaluator: &Evaluator,
    winner: &Layout,
    paper: &Layout,
) -> HeldOutCheck {
    let volume = config.volume.held_out(held_out_grid);
    let first_order = evaluator
        .without_supports(&paper.positions())
        .on_scenarios(volume.scenarios(&config.camera), &paper.positions())
        .first_order(&paper.positions());
    HeldOutCheck::new(
        &volume,
        &first_order.evaluate(&winner.positions(), &winner.point_sigmas()),
        &first_order.evaluate(&paper.positions(), &paper.point_sigmas()),
    )
}

/// What the workflow lends the analysis: a listener of the optimisation
/// (it keeps the best layout so far on disk), the checkpoints the
/// optimisation resumes from and writes, and a check run once the
/// optimisation has ended (a failed write of the listener's).
pub struct Hooks<'a> {
    /// Hears every improvement and iteration of the optimisation.
    pub listener: Arc<dyn SearchObserver + Send>,
    /// Checkpoints of the optimisation (None: none kept).
    pub checkpoints: Option<&'a Checkpoints>,
    /// Runs once the optimisation has ended, before anything else.
    pub after_search: &'a dyn Fn() -> Result<(), SearchError>,
}

impl Hooks<'_> {
    /// No listener, no checkpoints, nothing after the search: the pure
    /// analysis.
    pub fn none() -> Hooks<'static> {
        Hooks {
            listener: Arc::new(Quiet),
            checkpoints: None,
            after_search: &|| Ok(()),
        }
    }
}

/// How an analysis ended.
#[derive(Debug)]
#[allow(clippy::large_enum_variant)]
pub enum Analysed {
    /// Every phase finished.
    Finished(Box<Finished>),
    /// The observer stopped the run; the best layout found so far is kept.
    Interrupted(Stopped),
    /// The best layout found breaks a constraint: never a finished result.
    Infeasible {
        /// The best layout found.
        best: Stopped,
        /// Each broken constraint, in words.
        violations: Vec<String>,
    },
}

/// A finished analysis: what the report renders.
#[derive(Debug)]
pub struct Finished {
    /// The winning layout, with its provenance.
    pub winner: Layout,
    /// The comparison, verdicts and books.
    pub summary: SearchSummary,
    /// The winner's sensitivity analysis on the validation seed.
    pub validation: validate::ValidateSummary,
    /// The Pareto front and its members' layouts, when asked for.
    pub front: Option<FrontFiles>,
    /// Seconds spent optimising.
    pub search_seconds: f64,
}

/// Where an unfinished analysis ended.
#[derive(Debug, Clone)]
pub struct Stopped {
    /// The phase it ended in ([`PHASE_SEARCH`], [`PHASE_COMPARE`], …).
    pub phase: &'static str,
    /// The best layout's status, in words, for its provenance.
    pub status: &'static str,
    /// The best layout's family parameters.
    pub params: Vec<f64>,
    /// Its objective-plus-penalty cost.
    pub cost: f64,
    /// Objective evaluations of the whole search.
    pub evaluations: usize,
    /// Seconds spent optimising.
    pub search_seconds: f64,
}

/// A search ready to run: its configuration checked, its family built and
/// the constraints found satisfiable as far as that is known without
/// searching.
#[derive(Debug)]
pub struct Analysis<'c> {
    config: &'c SearchConfig,
    family: Family,
    description: String,
}

/// Runs the whole analysis of `config` with no hooks (no file is read or
/// written).
pub fn run(config: &SearchConfig, observer: &mut impl Observer) -> Result<Analysed, SearchError> {
    Analysis::new(config)?.run(observer, Hooks::none())
}

/// Why a phase ended the run early: stopped, or failed.
enum Halt {
    Stopped(Analysed),
    Failed(SearchError),
}

impl<E: Into<SearchError>> From<E> for Halt {
    fn from(error: E) -> Self {
        Halt::Failed(error.into())
    }
}

/// The run context of an analysis: what every phase reads, and the stop
/// flag they share.
struct Run<'a, 'c> {
    analysis: &'a Analysis<'c>,
    evaluator: Evaluator,
    hand: Vec<Layout>,
    stop: AtomicBool,
    search_seconds: f64,
}

impl<'c> Analysis<'c> {
    /// Checks `config` ([`SearchConfig::check`], the optimiser's settings),
    /// builds the family and refuses constraints that no layout can meet.
    pub fn new(config: &'c SearchConfig) -> Result<Self, SearchError> {
        config.check()?;
        config.search.check()?;
        let constraints = config.constraints;
        let family = Family::new(
            config.family.clone(),
            constraints.envelope,
            constraints.sphere_diameter_mm,
        )?;
        if let Some(reason) = unsatisfiable(&family, &constraints) {
            return Err(SearchError::Unsatisfiable(reason));
        }
        let description = family_description(&family);
        Ok(Self {
            config,
            family,
            description,
        })
    }

    /// The configuration.
    pub fn config(&self) -> &SearchConfig {
        self.config
    }

    /// The family searched.
    pub fn family(&self) -> &Family {
        &self.family
    }

    /// The family and its free parameters, in words.
    pub fn description(&self) -> &str {
        &self.description
    }

    /// The provenance every layout of the run carries: the command, seed,
    /// objective, version and the search's grid (`range`: every axis's
    /// values, by name), which `export` routes the supports for when no
    /// range is given.
    pub fn provenance(&self) -> serde_json::Value {
        let config = self.config;
        let range: serde_json::Map<String, serde_json::Value> = config
            .volume
            .axis_ranges(&config.camera)
            .iter()
            .map(|(name, range)| (name.to_string(), serde_json::json!(range.values)))
            .collect();
        serde_json::json!({
            "range": range,
            "volume": config.volume.describe(),
            "command": config.command,
            "seed": config.search.seed,
            "objective": config.objective.objective.to_string(),
            "aggregate": format!("{:?}", config.objective.aggregate).to_lowercase(),
            "version": env!("CARGO_PKG_VERSION"),
        })
    }

    /// Everything that decides which layouts the optimisation evaluates:
    /// the key of its checkpoints.
    pub fn checkpoint_key(&self) -> serde_json::Value {
        let config = self.config;
        let mut key = serde_json::json!({
            "version": env!("CARGO_PKG_VERSION"),
            "family": self.description,
            "start_layout": match self.family.kind() {
                FamilyKind::Custom { start: Some(layout), .. } => serde_json::to_value(layout)
                    .expect("a layout serialises"),
                _ => serde_json::Value::Null,
            },
            "sphere_diameter_mm": config.constraints.sphere_diameter_mm,
            "constraints": config.constraints,
            "camera": config.camera,
            "objective": config.objective,
            "search": config.search,
        });
        // A grid keeps the key it always had, so that its checkpoints
        // resume; a sampled volume is keyed by all of it, seed included.
        match &config.volume {
            WorkingVolume::Grid(grid) => key["grid"] = serde_json::json!(grid),
            WorkingVolume::Sampled(volume) => key["volume"] = serde_json::json!(volume),
        }
        // Only when asked for, so that earlier checkpoints keep their key.
        if let Some(max_hidden) = config.count_supports {
            key["count_supports"] = serde_json::json!(max_hidden.fraction());
        }
        key
    }

    /// The objective's evaluator, its reference the paper's biprism scaled
    /// to the envelope (building it scores that reference once).
    pub fn evaluator(&self) -> Evaluator {
        let config = self.config;
        let constraints = config.constraints;
        let paper =
            hand_designs(&constraints.envelope, constraints.sphere_diameter_mm).swap_remove(0);
        let evaluator = Evaluator::new(
            config.camera,
            config.volume.scenarios(&config.camera),
            config.objective.clone(),
            constraints,
            &paper.positions(),
        );
        match config.count_supports {
            Some(max_hidden) => evaluator.with_candidate_supports(
                crate::mesh::MarkerOptions::default(),
                max_hidden,
                &paper.positions(),
            ),
            None => evaluator,
        }
    }

    /// Runs the phases in order: optimisation, identifiability, comparison,
    /// held-out check, front, validation.
    pub fn run(
        &self,
        observer: &mut impl Observer,
        hooks: Hooks<'_>,
    ) -> Result<Analysed, SearchError> {
        let constraints = self.config.constraints;
        let mut run = Run {
            analysis: self,
            evaluator: self.evaluator(),
            hand: hand_designs(&constraints.envelope, constraints.sphere_diameter_mm),
            stop: AtomicBool::new(false),
            search_seconds: 0.0,
        };
        match run.phases(observer, &hooks) {
            Ok(finished) => Ok(Analysed::Finished(Box::new(finished))),
            Err(Halt::Stopped(analysed)) => Ok(analysed),
            Err(Halt::Failed(error)) => Err(error),
        }
    }
}

impl Run<'_, '_> {
    fn config(&self) -> &SearchConfig {
        self.analysis.config
    }

    fn phases(
        &mut self,
        observer: &mut impl Observer,
        hooks: &Hooks<'_>,
    ) -> Result<Finished, Halt> {
        let outcome = self.optimise(observer, hooks)?;
        let (outcome, identify_books) = self.identify(observer, outcome)?;
        let (outcome, printed) = self.supports(observer, outcome)?;
        let winner = self.winner(observer, &outcome)?;
        let (rows, seeds, ranges) = self.compare(observer, &outcome, &winner)?;
        let held_out = self.held_out(&winner);
        let chains = self.chains(&winner);
        let held_out_with_supports = printed
            .as_ref()
            .map(|(_, parts)| self.held_out_with_supports(&winner, parts));
        let front = self.front(observer, &outcome, &rows[ranges.paper..])?;
        let config = self.config();
        let summary = SearchSummary {
            header: SearchHeader {
                command: config.command.clone(),
                layout_path: config.layout_path.clone(),
                version: env!("CARGO_PKG_VERSION").to_string(),
                family: self.analysis.description.clone(),
                constraints: config.constraints,
                objective: config.objective.clone(),
                search: config.search.clone(),
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
                camera: config.camera,
                comparison_solver: config.compare_solver.name().to_string(),
                comparison_trials: config.compare_trials,
                comparison_seeds: seeds.to_vec(),
            },
            verdicts: verdicts(&rows, ranges.paper, ranges.hand, ranges.admissible),
            outcome,
            designs: rows,
            held_out,
            held_out_with_supports,
            supports: printed.map(|(books, _)| books),
            front: front.as_ref().map(|f| f.report.clone()),
            identifiability: identify_books,
            chains,
        };
        let validation = self.validate(observer, &winner, &summary)?;
        Ok(Finished {
            winner,
            summary,
            validation,
            front,
            search_seconds: self.search_seconds,
        })
    }

    /// Ends the run in `phase` with the best layout of `outcome`.
    fn stopped(
        &self,
        outcome: &OptimiseOutcome,
        phase: &'static str,
        status: &'static str,
    ) -> Stopped {
        Stopped {
            phase,
            status,
            params: outcome.best.params.clone(),
            cost: outcome.best.evaluation.cost,
            evaluations: outcome.evaluations,
            search_seconds: self.search_seconds,
        }
    }

    /// The multistart optimisation ([`PHASE_SEARCH`]).
    fn optimise(
        &mut self,
        observer: &mut impl Observer,
        hooks: &Hooks<'_>,
    ) -> Result<OptimiseOutcome, Halt> {
        let settings = &self.config().search;
        let tracker = Arc::new(IterationCount::new(settings, hooks.listener.clone()));
        let checkpoints = hooks.checkpoints;
        let started = Instant::now();
        let outcome = watch(
            observer,
            PHASE_SEARCH,
            settings.starts as u64 * tracker.budget,
            || tracker.done(),
            Some(&self.stop),
            || {
                optimise::run(
                    &self.analysis.family,
                    &self.evaluator,
                    settings,
                    &self.stop,
                    tracker.clone(),
                    checkpoints,
                )
            },
        )?;
        self.search_seconds = started.elapsed().as_secs_f64();
        (hooks.after_search)()?;
        Ok(outcome)
    }

    /// The identifiability floor's repair rounds ([`PHASE_IDENTIFY`]), when
    /// there is a floor; an interrupted search skips them.
    fn identify(
        &self,
        observer: &mut impl Observer,
        outcome: OptimiseOutcome,
    ) -> Result<(OptimiseOutcome, Option<IdentifyBooks>), Halt> {
        let started = Instant::now();
        let (outcome, books) = match self.config().min_identifiability {
            Some(floor) if !outcome.interrupted => {
                // One step per round; a winner that needs fewer rounds ends
                // the bar at its total.
                let rounds_done = AtomicU64::new(0);
                let (outcome, mut books) = watch(
                    observer,
                    PHASE_IDENTIFY,
                    IDENTIFY_ROUNDS as u64,
                    || rounds_done.load(Ordering::Relaxed),
                    Some(&self.stop),
                    || {
                        let repaired = enforce_identifiability(
                            &self.analysis.family,
                            &self.evaluator,
                            floor,
                            &self.config().search,
                            outcome,
                            &self.stop,
                        );
                        rounds_done.store(IDENTIFY_ROUNDS as u64, Ordering::Relaxed);
                        repaired
                    },
                )?;
                books.seconds = started.elapsed().as_secs_f64();
                (outcome, Some(books))
            }
            _ => (outcome, None),
        };
        if outcome.interrupted {
            let stopped = self.stopped(&outcome, PHASE_SEARCH, "interrupted: best layout seen");
            return Err(Halt::Stopped(Analysed::Interrupted(stopped)));
        }
        let violations = &outcome.best.evaluation.violations;
        if !violations.feasible() {
            return Err(Halt::Stopped(Analysed::Infeasible {
                best: self.stopped(&outcome, PHASE_SEARCH, "infeasible: breaks the constraints"),
                violations: violations.describe(&self.config().constraints),
            }));
        }
        Ok((outcome, books))
    }

    /// The winner as a layout with its provenance.
    fn winner(
        &self,
        observer: &mut impl Observer,
        outcome: &OptimiseOutcome,
    ) -> Result<Layout, Halt> {
        let cost = outcome.best.evaluation.cost;
        observer.log(&format!(
            "search finished: objective {cost:.6} after {} evaluations in {:.1} s",
            outcome.evaluations, self.search_seconds
        ));
        let mut winner = self
            .analysis
            .family
            .layout(&self.config().name, &outcome.best.params);
        let mut provenance = self.analysis.provenance();
        provenance["score"] = cost.into();
        provenance["status"] = STATUS_FINISHED.into();
        provenance["evaluations"] = outcome.evaluations.into();
        // Checked on every visible scenario: export reads it to tell a
        // design identified from one image from one that needs distances.
        if let Some(f) = outcome
            .best
            .evaluation
            .identifiability
            .as_ref()
            .filter(|f| f.all_checked)
        {
            provenance["identifiability"] = serde_json::json!({
                "identifiable": f.identifiable,
                "visible": f.checked,
            });
        }
        winner.provenance = Some(provenance);
        Ok(winner)
    }

    /// The designs compared with the winner: its start, the hand designs
    /// and, for those that break a constraint (the paper's biprism and the
    /// cube corners repeat pairwise distances), their nearest admissible
    /// versions by the search's own repair, so that the winner meets them
    /// like for like.
    fn designs(&self, winner: &Layout) -> Result<(Vec<(String, Layout)>, DesignRanges), Halt> {
        let name = &self.config().name;
        let constraints = self.config().constraints;
        let family = &self.analysis.family;
        let start = family.layout(&format!("{name}-start"), &family.initial());
        let mut designs = vec![(name.clone(), winner.clone()), ("start".to_string(), start)];
        let paper = designs.len();
        designs.extend(self.hand.iter().map(|l| (l.name.clone(), l.clone())));
        let hand = paper..designs.len();
        for layout in &self.hand {
            if constraints.violations(&layout.positions()).feasible() {
                continue;
            }
            let free = Family::new(
                FamilyKind::Custom {
                    count: layout.points.len(),
                    start: Some(layout.clone()),
                },
                constraints.envelope,
                constraints.sphere_diameter_mm,
            )
            .map_err(|e: FamilyError| Halt::Failed(e.into()))?;
            let params = optimise::repair(&free, &self.evaluator, &free.initial())?;
            let mut admissible = free.layout(&format!("{}-admissible", layout.name), &params);
            admissible.provenance = Some(serde_json::json!({
                "source": format!("{} moved to the nearest layout that meets the constraints (the search's repair)", layout.name),
            }));
            designs.push((admissible.name.clone(), admissible));
        }
        let admissible = hand.end..designs.len();
        Ok((
            designs,
            DesignRanges {
                paper,
                hand,
                admissible,
            },
        ))
    }

    /// The Monte-Carlo comparison ([`PHASE_COMPARE`]) on the same scenarios
    /// and draws, on the search seed and an independent validation seed.
    fn compare(
        &self,
        observer: &mut impl Observer,
        outcome: &OptimiseOutcome,
        winner: &Layout,
    ) -> Result<(Vec<DesignRow>, [u64; 2], DesignRanges), Halt> {
        let config = self.config();
        let (designs, ranges) = self.designs(winner)?;
        let seeds = [config.search.seed, validation_seed(config)];
        let compared = AtomicU64::new(0);
        let total = (designs.len() * seeds.len() * self.evaluator.scenarios().len()) as u64;
        // Every design's identifiability over every visible scenario.
        let evaluator = self
            .evaluator
            .with_identifiability(config.min_identifiability, IdentifyScope::All);
        let rows = watch(
            observer,
            PHASE_COMPARE,
            total,
            || compared.load(Ordering::Relaxed),
            Some(&self.stop),
            || {
                compare(
                    &Comparison {
                        camera: &config.camera,
                        evaluator: &evaluator,
                        designs: &designs,
                        solver: config.compare_solver,
                        trials: config.compare_trials,
                        seeds: &seeds,
                        noise: config.objective.noise,
                    },
                    &CompareProgress {
                        on_scenario_done: &|| {
                            compared.fetch_add(1, Ordering::Relaxed);
                        },
                        stop: &self.stop,
                    },
                )
            },
        );
        let rows = match rows {
            Err(MonteCarloError::Interrupted) => {
                return Err(Halt::Stopped(Analysed::Interrupted(self.stopped(
                    outcome,
                    PHASE_COMPARE,
                    "interrupted in the comparison: the search's winner, report not written",
                ))))
            }
            rows => rows?,
        };
        observer.log(&format!(
            "comparison finished: {} designs on {} seeds",
            designs.len(),
            seeds.len()
        ));
        Ok((rows, seeds, ranges))
    }

    /// First-order figures of the winner and the paper's biprism on a
    /// held-out grid ([`held_out_check`]).
    /// The winner and the paper's biprism under every chain
    /// ([`super::Chain`]: ideal, printed to 0.1 mm, characterised from the
    /// capture plan at 0.02 px), scored by the `crlb` term on the search's
    /// scenarios, noise and weights, the objective's other settings kept.
    fn chains(&self, winner: &Layout) -> Vec<ChainRow> {
        let config = self.config();
        let paper = self.hand[0].positions();
        let chains = [
            super::Chain::Ideal,
            super::Chain::Printed {
                sigma_mm: super::DEFAULT_PRINTED_SIGMA_MM,
            },
            super::Chain::Characterised {
                sigma_px: crate::characterise::plan::DEFAULT_PLAN_SIGMA_PX,
            },
        ];
        chains
            .into_iter()
            .map(|chain| {
                let evaluator = Evaluator::new(
                    config.camera,
                    config.volume.scenarios(&config.camera),
                    super::ObjectiveSettings {
                        objective: "crlb".parse().expect("crlb is an objective"),
                        chain,
                        ..config.objective.clone()
                    },
                    config.constraints,
                    &paper,
                );
                let rotation = |points: &[Vector3<f64>], sigmas: &[Option<f64>]| {
                    let evaluation = evaluator.evaluate(points, sigmas);
                    (
                        evaluation.terms.first().and_then(|t| t.rotation_deg),
                        evaluation.accuracy,
                    )
                };
                let (winner_rotation_deg, winner_accuracy) =
                    rotation(&winner.positions(), &winner.point_sigmas());
                let (paper_rotation_deg, _) = rotation(&paper, &self.hand[0].point_sigmas());
                ChainRow {
                    chain,
                    winner_rotation_deg,
                    paper_rotation_deg,
                    winner_accuracy,
                }
            })
            .collect()
    }

    fn held_out(&self, winner: &Layout) -> HeldOutCheck {
        held_out_check(self.config(), &self.evaluator, winner, &self.hand[0])
    }

    /// [`Self::held_out`] with the supports `export` would print for the
    /// winner and the paper's biprism (`parts`) counted as occluders.
    fn held_out_with_supports(&self, winner: &Layout, parts: &PrintedParts) -> HeldOutCheck {
        let volume = self.config().volume.held_out(held_out_grid);
        super::held_out_with_supports(
            &self.evaluator,
            &volume,
            winner,
            &self.hand[0],
            parts,
            self.config().supports.unwrap_or_default(),
        )
    }

    /// The winner checked as printed and repaired to the printed
    /// availability floor ([`PHASE_SUPPORTS`], [`enforce_supports`]), when
    /// asked for. A part that cannot be built leaves the supports
    /// uncounted, and says so.
    fn supports(
        &self,
        observer: &mut impl Observer,
        outcome: OptimiseOutcome,
    ) -> Result<(OptimiseOutcome, Option<(SupportsBooks, PrintedParts)>), Halt> {
        let Some(max_hidden) = self.config().supports else {
            return Ok((outcome, None));
        };
        let fallback = outcome.clone();
        let done = AtomicU64::new(0);
        let result = watch(
            observer,
            PHASE_SUPPORTS,
            1 + SUPPORT_ROUNDS as u64,
            || done.load(Ordering::Relaxed),
            Some(&self.stop),
            || {
                let result = enforce_supports(
                    &self.analysis.family,
                    &self.evaluator,
                    &self.hand[0],
                    max_hidden,
                    &self.config().search,
                    RepairBudget::SEARCH,
                    outcome,
                    &self.stop,
                );
                done.store(1 + SUPPORT_ROUNDS as u64, Ordering::Relaxed);
                result
            },
        );
        let (outcome, books, parts) = match result {
            Ok(done) => done,
            Err(SearchError::Supports(reason)) => {
                observer.log(&format!(
                    "supports not counted: {reason}; the winner is scored as the spheres alone"
                ));
                return Ok((fallback, None));
            }
            Err(error) => return Err(Halt::Failed(error)),
        };
        if outcome.interrupted {
            let stopped = self.stopped(&outcome, PHASE_SUPPORTS, "interrupted: best layout seen");
            return Err(Halt::Stopped(Analysed::Interrupted(stopped)));
        }
        Ok((outcome, Some((books, parts))))
    }

    /// The Pareto front's sweep ([`PHASE_FRONT`]), when asked for; `hand`
    /// are the hand designs' rows.
    fn front(
        &self,
        observer: &mut impl Observer,
        outcome: &OptimiseOutcome,
        hand: &[DesignRow],
    ) -> Result<Option<FrontFiles>, Halt> {
        let Some(output) = &self.config().front else {
            return Ok(None);
        };
        let started = Instant::now();
        let levels_done = AtomicU64::new(0);
        let (points, evaluations) = watch(
            observer,
            PHASE_FRONT,
            (output.settings.levels + 1 + front::BLEND_WEIGHTS.len()) as u64,
            || levels_done.load(Ordering::Relaxed),
            Some(&self.stop),
            || {
                front::sweep(
                    &self.analysis.family,
                    &self.evaluator,
                    &self.config().search,
                    &output.settings,
                    std::slice::from_ref(&outcome.best),
                    &self.stop,
                    &levels_done,
                )
            },
        )?;
        if self.stop.load(Ordering::Relaxed) {
            return Err(Halt::Stopped(Analysed::Interrupted(self.stopped(
                outcome,
                PHASE_FRONT,
                "interrupted in the front's sweep: the search's winner, report not written",
            ))));
        }
        let hand_rows: Vec<_> = hand
            .iter()
            .map(|r| (r.name.clone(), r.layout.clone(), r.evaluation.clone()))
            .collect();
        let paper = &self.hand[0];
        Ok(Some(front::build(&front::FrontInputs {
            layout_dir: &output.layout_dir,
            name: &self.config().name,
            family: &self.analysis.family,
            points: &points,
            first_order_evaluator: &self.evaluator.first_order(&paper.positions()),
            hand: &hand_rows,
            provenance: &self.analysis.provenance(),
            evaluations,
            seconds: started.elapsed().as_secs_f64(),
            settings: &output.settings,
        })))
    }

    /// The winner's sensitivity analysis on the validation seed
    /// ([`PHASE_VALIDATE`]).
    fn validate(
        &self,
        observer: &mut impl Observer,
        winner: &Layout,
        summary: &SearchSummary,
    ) -> Result<validate::ValidateSummary, Halt> {
        let config = self.config();
        let monte_carlo = MonteCarloConfig {
            trials: config.compare_trials,
            seed: validation_seed(config),
            solvers: config.validate_solvers.clone(),
            noise: config.objective.noise,
            gross_threshold_deg: DEFAULT_GROSS_THRESHOLD_DEG,
            observation: config.objective.observation,
        };
        let validation_config = ValidateConfig {
            layout: winner.clone(),
            camera: config.camera,
            volume: config.volume.clone(),
            monte_carlo,
            identifiability: config.identifiability_check(),
            fabrication_sigma_mm: 0.0,
            camera_sigma: Default::default(),
            // The winner's validation keeps to the spheres alone, as the
            // search's own figures do; the report's held-out check with
            // supports says what the printed part loses.
            structure: None,
            max_hidden: crate::visibility::DEFAULT_MAX_HIDDEN,
            command: config.command.clone(),
        };
        let checked = validation_config
            .check()
            .map_err(|error| Halt::from(ValidateError::from(error)))?;
        let scenarios_done = AtomicU64::new(0);
        let validation = watch(
            observer,
            PHASE_VALIDATE,
            2 * config.volume.len() as u64,
            || scenarios_done.load(Ordering::Relaxed),
            Some(&self.stop),
            || {
                validate::analysis::monte_carlo_until(
                    checked,
                    validate::analysis::Hooks {
                        on_scenario_done: &|_| {
                            scenarios_done.fetch_add(1, Ordering::Relaxed);
                        },
                        stop: &self.stop,
                    },
                )
            },
        );
        match validation {
            Err(ValidateError::MonteCarlo(MonteCarloError::Interrupted)) => {
                Err(Halt::Stopped(Analysed::Interrupted(self.stopped(
                    &summary.outcome,
                    PHASE_VALIDATE,
                    "interrupted in the winner's validation: the search's winner, report not written",
                ))))
            }
            validation => Ok(validation?),
        }
    }
}

/// Positions of the designs compared: the paper's biprism (first of the
/// hand designs), the hand designs, their admissible versions.
struct DesignRanges {
    paper: usize,
    hand: std::ops::Range<usize>,
    admissible: std::ops::Range<usize>,
}

/// The comparison's second seed and the winner's validation seed.
fn validation_seed(config: &SearchConfig) -> u64 {
    config.search.seed.wrapping_add(1)
}

/// Provenance status of a finished run's layout.
pub const STATUS_FINISHED: &str = "finished";

/// Counts each start's iterations for the search's progress, and passes
/// every event on to the workflow's listener.
struct IterationCount {
    listener: Arc<dyn SearchObserver + Send>,
    /// Per start: iterations of its finished phases, the current phase's
    /// iteration, and whether the start ran to its end.
    iterations: std::sync::Mutex<Vec<StartProgress>>,
    /// Iterations one start may run (main phase plus polish).
    budget: u64,
}

/// One start's place in its budget.
#[derive(Debug, Clone, Copy, Default)]
struct StartProgress {
    earlier_phases: u64,
    current: u64,
    finished: bool,
}

impl IterationCount {
    fn new(settings: &SearchSettings, listener: Arc<dyn SearchObserver + Send>) -> Self {
        let budget = settings.iterations
            + if settings.optimiser == optimise::Optimiser::NelderMead {
                0
            } else {
                settings.polish_iterations
            };
        Self {
            listener,
            iterations: std::sync::Mutex::new(vec![StartProgress::default(); settings.starts]),
            budget,
        }
    }

    /// Iterations done, a finished start counting its whole budget (a
    /// Nelder–Mead start that converges ends early), so the bar reaches its
    /// total exactly when the search ends.
    fn done(&self) -> u64 {
        self.iterations
            .lock()
            .expect("no panics while holding the lock")
            .iter()
            .map(|p| {
                if p.finished {
                    self.budget
                } else {
                    (p.earlier_phases + p.current).min(self.budget)
                }
            })
            .sum()
    }
}

impl SearchObserver for IterationCount {
    fn improved(&self, candidate: &Candidate) {
        self.listener.improved(candidate);
    }

    fn progress(&self, start: usize, iteration: u64, evaluations: usize, best_cost: f64) {
        if let Some(slot) = self
            .iterations
            .lock()
            .expect("no panics while holding the lock")
            .get_mut(start)
        {
            // Each Nelder–Mead round and the polish count from 0 again.
            if iteration < slot.current {
                slot.earlier_phases += slot.current;
            }
            slot.current = iteration;
        }
        self.listener
            .progress(start, iteration, evaluations, best_cost);
    }

    fn finished(&self, start: usize) {
        if let Some(slot) = self
            .iterations
            .lock()
            .expect("no panics while holding the lock")
            .get_mut(start)
        {
            slot.finished = true;
        }
        self.listener.finished(start);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The checkpoint key holds the whole volume: another sample count or
    /// seed of the scrambling is another key; the grid form keeps the
    /// `grid` key it always had.
    #[test]
    fn the_checkpoint_key_includes_the_volume() {
        let dir = std::path::Path::new("unused");
        let base = SearchConfig::new("t", dir);
        let key = |config: &SearchConfig| Analysis::new(config).unwrap().checkpoint_key();
        let reference = key(&base);
        assert_eq!(
            reference["volume"]["samples"],
            crate::volume::DEFAULT_SAMPLES
        );
        assert!(reference.get("grid").is_none());
        let mut other = base.clone();
        other.volume = super::super::config::default_volume(8);
        assert_ne!(key(&other), reference);
        let mut grid = base.clone();
        grid.volume = WorkingVolume::Grid(super::super::config::default_grid());
        let grid_key = key(&grid);
        assert_eq!(
            grid_key["grid"],
            serde_json::json!(super::super::config::default_grid())
        );
        assert!(grid_key.get("volume").is_none());
    }
}
