//! The whole search as one call: checkpoints, optimisation, comparison with
//! the hand designs, validation of the winner, the report and an optional
//! mesh export. [`run`] takes a [`SearchConfig`] that names every input and
//! every output path, and reports progress through an [`Observer`]; it never
//! prints. A run never loses or clobbers a result: it checks and locks its
//! outputs before any work, keeps the best layout so far in
//! [`partial_path`], can be stopped in every phase, and replaces the layout
//! and report only when every phase has finished.
//!
//! ```no_run
//! use layout_opt::observer::Silent;
//! use layout_opt::search::pipeline::{self, SearchConfig};
//!
//! let dir = std::env::temp_dir().join("layout-opt-doc");
//! let mut config = SearchConfig::new("my-marker", &dir);
//! config.search.starts = 2;
//! config.search.iterations = 100;
//! let outcome = pipeline::run(&config, &mut Silent)?;
//! println!("objective {:.4}", outcome.objective);
//! # Ok::<(), pipeline::SearchError>(())
//! ```

use super::checkpoint::{CheckpointError, Checkpoints, ResumeStatus};
use super::compare::{compare, hand_designs, CompareProgress};
use super::front::{self, FrontReport, FrontSettings};
use super::optimise::{self, Candidate, Optimiser, SearchObserver, SearchSettings};
use super::report::{self as search_report, verdicts, HeldOutCheck, SearchHeader, SearchSummary};
use super::{
    Aggregate, AvailabilityFloor, Evaluator, IdentifiabilityFloor, IdentifyScope, ObjectiveSettings,
};
use crate::camera::Camera;
use crate::family::{Constraints, Envelope, Family, FamilyError, FamilyKind};
use crate::files::{self, LockError};
use crate::layout::{Layout, LayoutError};
use crate::mesh::{ExportError, ExportOptions, Format};
use crate::montecarlo::{MonteCarloConfig, MonteCarloError, DEFAULT_GROSS_THRESHOLD_DEG};
use crate::noise::NoiseModel;
use crate::observer::{watch, Observer};
use crate::pnp::Solver;
use crate::report::{write_text, ReportError};
use crate::scenario::{Range, ScenarioGrid};
use crate::validate::{self, ValidateConfig, ValidateError};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Instant;

/// Progress phase of the optimisation: iterations of every start.
pub const PHASE_SEARCH: &str = "search";
/// Progress phase of the comparison with the hand designs: Monte-Carlo
/// scenarios of every design on both seeds.
pub const PHASE_COMPARE: &str = "comparison";
/// Progress phase of the winner's sensitivity report: its scenarios.
pub const PHASE_VALIDATE: &str = "validation";
/// Progress phase of the optional mesh export (one step).
pub const PHASE_EXPORT: &str = "export";
/// Progress phase of the Pareto front's sweep: its levels.
pub const PHASE_FRONT: &str = "front";
/// Progress phase of the identifiability repair (one step per round).
pub const PHASE_IDENTIFY: &str = "identifiability";
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
/// Default Monte-Carlo trials of the unlabelled solver per visible scenario
/// in the winner's validation.
pub const DEFAULT_IDENTIFY_TRIALS: usize = 50;

/// The default scenario grid: depths 200…1000 mm (5 values), X offsets
/// 0…100 mm, tilt −60°…60° in 10° steps, σ 0.5 px.
pub fn default_grid() -> ScenarioGrid {
    ScenarioGrid::new(
        "200..1000".parse().expect("valid"),
        "0..100".parse().expect("valid"),
        Range::single(0.0),
        "-60..60:10".parse().expect("valid"),
        Range::single(0.0),
        Range::single(0.0),
        Range::single(0.5),
    )
    .expect("the default grid is valid")
}

/// A held-out grid beside `grid`: every range of two or more values is
/// replaced by the midpoints of its neighbouring values, so no scenario is
/// shared with `grid` (`200..1000` in 5 → 300, 500, 700, 900).
pub fn held_out_grid(grid: &ScenarioGrid) -> ScenarioGrid {
    let shift = |range: &Range| {
        if range.values.len() < 2 {
            range.clone()
        } else {
            let mids: Vec<f64> = range
                .values
                .windows(2)
                .map(|w| 0.5 * (w[0] + w[1]))
                .collect();
            Range::list(&mids)
        }
    };
    ScenarioGrid::new(
        shift(&grid.depth_mm),
        shift(&grid.offset_x_mm),
        shift(&grid.offset_y_mm),
        shift(&grid.tilt_deg),
        shift(&grid.pan_deg),
        shift(&grid.roll_deg),
        grid.sigma_px.clone(),
    )
    .expect("midpoints of a valid grid form a valid grid")
}

/// The Pareto front of a search (`search --front`).
#[derive(Debug, Clone)]
pub struct FrontOutput {
    /// How the front is swept.
    pub settings: FrontSettings,
    /// Directory of the members' layout files (beside the winner's:
    /// `<dir of the layout>/<name>-front/`).
    pub layout_dir: PathBuf,
}

/// The winner's meshes, written with `export`'s defaults.
#[derive(Debug, Clone)]
pub struct MeshExport {
    /// Formats to write (at least one).
    pub formats: Vec<Format>,
    /// Directory of the meshes and fabrication sheet.
    pub dir: PathBuf,
}

/// Every input and every output path of a search.
#[derive(Debug, Clone)]
pub struct SearchConfig {
    /// Name of the result (the winning layout's name).
    pub name: String,
    /// The layout family and its options.
    pub family: FamilyKind,
    /// Envelope, sphere diameter, gaps and identifiability.
    pub constraints: Constraints,
    /// The simulated camera.
    pub camera: Camera,
    /// The scenarios the objective is computed over.
    pub grid: ScenarioGrid,
    /// The objective (its seed is the seed of its common random numbers).
    pub objective: ObjectiveSettings,
    /// Optimiser and budget. `search.seed` is also the run's seed: the
    /// comparison uses it and `seed + 1`, the winner's validation `seed + 1`.
    pub search: SearchSettings,
    /// Solver of the Monte-Carlo comparison with the hand designs.
    pub compare_solver: Solver,
    /// Trials per scenario of the comparison and of the winner's validation.
    pub compare_trials: usize,
    /// Solvers of the winner's sensitivity report (at least one).
    pub validate_solvers: Vec<Solver>,
    /// Continue from this configuration's checkpoints, if any.
    pub resume: bool,
    /// The command that asked for the run, recorded in the layout's
    /// provenance and the report headers.
    pub command: String,
    /// Where the winning layout is written when the run finishes (the best
    /// so far goes to [`partial_path`] of it while the run lasts).
    pub layout_path: PathBuf,
    /// The report directory (with `winner-validation/` inside).
    pub report_dir: PathBuf,
    /// Where checkpoints are kept (one subdirectory per name and
    /// configuration hash; removed when the search finishes). The command
    /// line's default is [`checkpoint_dir_beside`] the layout, so that runs
    /// with different outputs never share checkpoints.
    pub checkpoint_dir: PathBuf,
    /// Meshes of the winner, if wanted.
    pub export: Option<MeshExport>,
    /// The Pareto front of accuracy against availability, if wanted.
    pub front: Option<FrontOutput>,
    /// The identifiability floor (None: no floor; monocular trackers need
    /// one, stereo trackers use `constraints.min_distance_diff_mm`).
    pub min_identifiability: Option<IdentifiabilityFloor>,
    /// Monte-Carlo trials of the unlabelled solver per visible scenario in
    /// the winner's validation (0: the prediction alone).
    pub identify_trials: usize,
}

impl SearchConfig {
    /// The command line's defaults for a biprism search named `name` on
    /// [`default_grid`] with seed 7, writing `<dir>/<name>.json`, the report
    /// in `<dir>/<name>-report/` and checkpoints in `<dir>/.<name>.checkpoints/`.
    pub fn new(name: &str, dir: &Path) -> Self {
        let seed = 7;
        let layout_path = dir.join(format!("{name}.json"));
        SearchConfig {
            name: name.to_string(),
            family: FamilyKind::Biprism {
                centre: true,
                tilts: true,
                free_hub: true,
            },
            constraints: Constraints {
                envelope: Envelope::new([100.0; 3]).expect("a valid envelope"),
                sphere_diameter_mm: 10.0,
                min_gap_mm: 2.0,
                min_distance_diff_mm: 0.0,
            },
            camera: Camera::paper(),
            grid: default_grid(),
            objective: ObjectiveSettings {
                objective: "crlb".parse().expect("a valid objective"),
                aggregate: Aggregate::Mean,
                translation_weight: 0.5,
                availability_weight: 0.0,
                min_availability: AvailabilityFloor::Reference,
                trials: 20,
                seed,
                noise: NoiseModel::default(),
                observation: crate::sphere_image::Observation::default(),
            },
            search: SearchSettings {
                optimiser: Optimiser::NelderMead,
                starts: 8,
                start_jitter: 0.02,
                iterations: 3000,
                particles: 32,
                polish_iterations: 2000,
                seed,
            },
            compare_solver: Solver::ParallelWeighted,
            compare_trials: 200,
            validate_solvers: vec![
                Solver::ParallelWeighted,
                Solver::ParallelGn,
                Solver::EpnpGn,
                Solver::Sqpnp,
                Solver::Lhm,
                Solver::Ml,
            ],
            resume: false,
            command: "layout-opt (library)".to_string(),
            report_dir: report_dir_beside(&layout_path),
            checkpoint_dir: checkpoint_dir_beside(&layout_path),
            layout_path,
            export: None,
            front: None,
            min_identifiability: Some(IdentifiabilityFloor::DEFAULT),
            identify_trials: DEFAULT_IDENTIFY_TRIALS,
        }
    }

    /// How the winner's validation checks identifiability.
    pub fn identifiability_check(&self) -> validate::IdentifiabilityCheck {
        validate::IdentifiabilityCheck {
            min_correct: self
                .min_identifiability
                .map_or(crate::identifiability::DEFAULT_MIN_CORRECT, |f| {
                    f.min_correct
                }),
            trials: self.identify_trials,
        }
    }

    /// Checks what the optimiser and the family do not check themselves.
    fn check(&self) -> Result<(), SearchError> {
        let c = &self.constraints;
        let s = &self.objective;
        let problem = if !(c.sphere_diameter_mm > 0.0 && c.sphere_diameter_mm.is_finite()) {
            "the sphere diameter must be positive"
        } else if !(c.min_gap_mm >= 0.0 && c.min_distance_diff_mm >= 0.0) {
            "the smallest gap and distance difference must be non-negative"
        } else if !(s.translation_weight >= 0.0 && s.availability_weight >= 0.0) {
            "objective weights must be non-negative"
        } else if matches!(s.min_availability, AvailabilityFloor::Share(share) if !(0.0..=1.0).contains(&share))
        {
            "the availability floor must be a share in [0, 1]"
        } else if self.min_identifiability.is_some_and(|f| {
            !((0.0..=1.0).contains(&f.min_share) && f.min_correct > 0.0 && f.min_correct < 1.0)
        }) {
            "the identifiability floor must be a share in [0, 1] of scenarios each labelled correctly with a probability in (0, 1)"
        } else if s.trials == 0 || self.compare_trials == 0 {
            "Monte-Carlo trials and comparison trials must be at least 1"
        } else if self.validate_solvers.is_empty() {
            "the winner's validation needs at least one solver"
        } else if self.export.as_ref().is_some_and(|e| e.formats.is_empty()) {
            "a mesh export needs at least one format"
        } else {
            return Ok(());
        };
        Err(SearchError::Config(problem.to_string()))
    }
}

/// Where the report goes when only the layout file is chosen: beside it, as
/// `<dir>/<stem>-report/` (`out/marker.json` → `out/marker-report/`).
pub fn report_dir_beside(layout_path: &Path) -> PathBuf {
    let stem = layout_path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "layout".into());
    layout_path.with_file_name(format!("{stem}-report"))
}

/// Where the best layout so far goes while a search for `layout_path` runs,
/// and where an interrupted run leaves it: `<stem>.partial.json` beside it
/// (`out/marker.json` → `out/marker.partial.json`).
pub fn partial_path(layout_path: &Path) -> PathBuf {
    let stem = layout_path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "layout".into());
    layout_path.with_file_name(format!("{stem}.partial.json"))
}

/// The default checkpoint directory of a search writing `layout_path`:
/// hidden beside it, `<dir>/.<stem>.checkpoints/`, so that it follows
/// `--out` and two searches with different outputs never share it.
pub fn checkpoint_dir_beside(layout_path: &Path) -> PathBuf {
    let stem = layout_path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "layout".into());
    layout_path.with_file_name(format!(".{stem}.checkpoints"))
}

/// What a search produced.
#[derive(Debug, Clone)]
pub struct SearchOutcome {
    /// The winning layout as written to [`SearchConfig::layout_path`], or,
    /// when interrupted, the best seen as written to [`Self::partial`].
    pub winner: Layout,
    /// The winner's objective-plus-penalty cost.
    pub objective: f64,
    /// The family and its free parameters, in words.
    pub family: String,
    /// Objective evaluations of the whole search, those made before a
    /// resume included.
    pub evaluations: usize,
    /// Whether the observer stopped the run; then the best layout seen is
    /// in [`Self::partial`], the checkpoints are kept in
    /// [`Self::checkpoints`], and neither the layout file nor the report was
    /// written.
    pub interrupted: bool,
    /// The phase the stop ended ([`PHASE_SEARCH`], [`PHASE_COMPARE`] or
    /// [`PHASE_VALIDATE`]), when interrupted.
    pub interrupted_phase: Option<String>,
    /// The partial file ([`partial_path`]); removed when the run finishes.
    pub partial: PathBuf,
    /// This configuration's checkpoint directory (removed unless interrupted).
    pub checkpoints: PathBuf,
    /// The comparison and verdicts written to the report (`None` when
    /// interrupted).
    pub summary: Option<SearchSummary>,
    /// Files of the mesh export.
    pub exported: Vec<PathBuf>,
    /// The Pareto front, when asked for.
    pub front: Option<FrontReport>,
    /// Seconds spent optimising.
    pub search_seconds: f64,
    /// Seconds of the whole run.
    pub total_seconds: f64,
}

/// Why a search failed.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SearchError {
    /// A setting is out of range.
    #[error("invalid search configuration: {0}")]
    Config(String),
    /// The family cannot be built.
    #[error(transparent)]
    Family(#[from] FamilyError),
    /// Checkpoints could not be prepared or removed.
    #[error(transparent)]
    Checkpoint(#[from] CheckpointError),
    /// The optimisation failed.
    #[error(transparent)]
    Optimise(#[from] optimise::SearchError),
    /// A directory could not be created.
    #[error("creating {}: {source}", path.display())]
    CreateDir {
        /// The directory.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// The best-so-far layout could not be written during the search.
    #[error("could not write the best-so-far layout: {0}")]
    BestSoFar(String),
    /// The winning layout could not be written.
    #[error(transparent)]
    Layout(#[from] LayoutError),
    /// No layout can meet the constraints (found before the search).
    #[error("the constraints cannot all be met: {0}")]
    Unsatisfiable(String),
    /// An output cannot be written (found before any work).
    #[error("cannot write {}: {source}; nothing was run", path.display())]
    Unwritable {
        /// The output file or directory.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// Another run holds an output.
    #[error(transparent)]
    Lock(#[from] LockError),
    /// The best layout found breaks a constraint.
    #[error("the constraints cannot all be met (best layout, kept in {}): {}", layout.display(), violations.join("; "))]
    Infeasible {
        /// Where the best layout was written.
        layout: PathBuf,
        /// Each broken constraint, in words.
        violations: Vec<String>,
    },
    /// The Monte-Carlo comparison failed.
    #[error(transparent)]
    MonteCarlo(#[from] MonteCarloError),
    /// The winner's validation failed.
    #[error(transparent)]
    Sensitivity(#[from] ValidateError),
    /// A report file could not be written.
    #[error(transparent)]
    Report(#[from] ReportError),
    /// The mesh export failed.
    #[error("exporting the winner to {}: {source}", dir.display())]
    Export {
        /// The export directory.
        dir: PathBuf,
        /// Why.
        source: ExportError,
    },
}

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

/// Writes the best-so-far layout to the partial file (at most every
/// [`PARTIAL_EVERY`], so that fast improvements do not queue on the disk),
/// and counts each start's iterations for the progress bar.
struct Tracker {
    family: Family,
    name: String,
    path: PathBuf,
    provenance: serde_json::Value,
    write_error: Mutex<Option<String>>,
    last_write: Mutex<Option<Instant>>,
    /// Per start: iterations of its finished phases, the current phase's
    /// iteration, and whether the start ran to its end.
    iterations: Mutex<Vec<StartProgress>>,
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

/// Least time between two writes of the partial file during a search.
pub const PARTIAL_EVERY: std::time::Duration = std::time::Duration::from_secs(1);

impl Tracker {
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

    /// Writes `params` to the partial file with `status`.
    fn write(&self, params: &[f64], cost: f64, status: &str) -> Result<(), LayoutError> {
        let mut layout = self.family.layout(&self.name, params);
        let mut provenance = self.provenance.clone();
        provenance["status"] = status.into();
        provenance["score"] = cost.into();
        layout.provenance = Some(provenance);
        layout.save_atomic(&self.path)
    }
}

impl SearchObserver for Tracker {
    fn improved(&self, candidate: &Candidate) {
        let mut last_write = self
            .last_write
            .lock()
            .expect("no panics while holding the lock");
        if last_write.is_some_and(|t| t.elapsed() < PARTIAL_EVERY) {
            return;
        }
        *last_write = Some(Instant::now());
        if let Err(e) = self.write(&candidate.params, candidate.evaluation.cost, STATUS_RUNNING) {
            *self
                .write_error
                .lock()
                .expect("no panics while holding the lock") = Some(e.to_string());
        }
    }

    fn progress(&self, start: usize, iteration: u64, _evaluations: usize, _best_cost: f64) {
        let mut iterations = self
            .iterations
            .lock()
            .expect("no panics while holding the lock");
        if let Some(slot) = iterations.get_mut(start) {
            // Each Nelder–Mead round and the polish count from 0 again.
            if iteration < slot.current {
                slot.earlier_phases += slot.current;
            }
            slot.current = iteration;
        }
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
    }
}

/// Provenance status of the partial file while the search runs.
pub const STATUS_RUNNING: &str = "best so far (search running or interrupted)";
/// Provenance status of a finished run's layout.
pub const STATUS_FINISHED: &str = "finished";

/// The directory a file lives in (`.` for a bare name).
fn parent_dir(path: &Path) -> PathBuf {
    match path.parent() {
        Some(dir) if !dir.as_os_str().is_empty() => dir.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

/// Checks before any work that every output can be written: the layout's
/// directory, the report directory (or where it will be created) and the
/// export directory.
fn check_outputs(config: &SearchConfig) -> Result<(), SearchError> {
    let unwritable = |path: &Path, source: std::io::Error| SearchError::Unwritable {
        path: path.to_path_buf(),
        source,
    };
    if config.layout_path.is_dir() {
        return Err(unwritable(
            &config.layout_path,
            std::io::Error::other("it is a directory"),
        ));
    }
    let dirs = std::iter::once(&config.report_dir).chain(config.export.as_ref().map(|e| &e.dir));
    let mut probes = vec![parent_dir(&config.layout_path)];
    for dir in dirs {
        if dir.exists() && !dir.is_dir() {
            return Err(unwritable(
                dir,
                std::io::Error::other("it is not a directory"),
            ));
        }
        probes.push(if dir.is_dir() {
            dir.clone()
        } else {
            parent_dir(dir)
        });
    }
    let validation = config.report_dir.join("winner-validation");
    if validation.is_dir() {
        probes.push(validation);
    }
    for dir in probes {
        files::check_writable_dir(&dir).map_err(|e| unwritable(&dir, e))?;
    }
    Ok(())
}

/// How the identifiability floor was enforced on the winner.
#[derive(Debug, Clone, serde::Serialize)]
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
    pub before: Option<super::IdentifiabilityFigures>,
    /// The final winner over every visible scenario.
    pub after: Option<super::IdentifiabilityFigures>,
    /// The search winner's accuracy before the repair.
    pub accuracy_before: f64,
    /// Wall-clock seconds of the checks and repair.
    pub seconds: f64,
}

/// At most `count` of `items`, spread evenly (all of them when they are
/// fewer).
fn spread_evenly(items: &[usize], count: usize) -> Vec<usize> {
    if items.len() <= count {
        return items.to_vec();
    }
    (0..count).map(|k| items[k * items.len() / count]).collect()
}

/// A search observer that hears nothing (the repair rounds report through
/// their own phase).
struct Quiet;

impl SearchObserver for Quiet {
    fn improved(&self, _: &Candidate) {}
    fn progress(&self, _: usize, _: u64, _: usize, _: f64) {}
}

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
fn enforce_identifiability(
    family: &Family,
    evaluator: &Evaluator,
    floor: IdentifiabilityFloor,
    settings: &SearchSettings,
    outcome: optimise::SearchOutcome,
    stop: &AtomicBool,
) -> Result<(optimise::SearchOutcome, IdentifyBooks), SearchError> {
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
        let round = SearchSettings {
            starts: 0,
            iterations: IDENTIFY_ROUND_ITERATIONS,
            polish_iterations: 0,
            ..settings.clone()
        };
        let repaired = optimise::run_with_starts(
            family,
            &scoped,
            &round,
            std::slice::from_ref(&outcome.best.params),
            stop,
            Arc::new(Quiet),
            None,
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

/// A reason the constraints cannot be met by any layout of `family`, found
/// without searching: every pairwise centre distance lies between one
/// sphere diameter plus the gap and the envelope's diagonal, and distinct
/// distances need the identifiability difference between them.
fn unsatisfiable(family: &Family, constraints: &Constraints) -> Option<String> {
    let points = family.point_count();
    if points < 2 {
        return None;
    }
    let [x, y, z] = constraints.envelope.size_mm;
    let diagonal = (x * x + y * y + z * z).sqrt();
    let closest = constraints.sphere_diameter_mm + constraints.min_gap_mm;
    if closest > diagonal {
        return Some(format!(
            "{points} spheres {closest} mm apart (diameter plus smallest gap) do not fit an envelope whose diagonal is {diagonal:.1} mm"
        ));
    }
    let distances = points * (points - 1) / 2;
    match constraints.distinct_distance_capacity() {
        Some(capacity) if distances > capacity => Some(format!(
            "{points} points have {distances} pairwise distances, but the envelope holds at most {capacity} distances {} mm apart between {closest} mm (sphere diameter plus gap) and its diagonal, {diagonal:.1} mm; use fewer points, a larger envelope or a smaller --min-distance-diff",
            constraints.min_distance_diff_mm,
        )),
        Some(_) if matches!(family.kind(), FamilyKind::Custom { .. }) => {
            unidentifiable(family, constraints)
        }
        _ => None,
    }
}

/// Random stream of the up-front identifiability check.
const FEASIBILITY_STREAM: u64 = 0xF0EA51;
/// Envelope scales the refusal of [`unidentifiable`] tries, in order.
const FEASIBLE_ENVELOPE_SCALES: [f64; 4] = [1.25, 1.5, 2.0, 3.0];
/// Fractions of the distance difference the refusal of [`unidentifiable`]
/// tries, in order.
const FEASIBLE_DIFF_FRACTIONS: [f64; 3] = [0.75, 0.5, 0.25];

/// The smallest difference between two pairwise distances that the
/// distance-spreading repair reaches for `family`'s start in `constraints`
/// (tightened as the search's penalty tightens them), trying
/// [`optimise::SPREAD_TRIES`] seeded jitters, and whether it met them.
fn spread_check(family: &Family, constraints: &Constraints) -> (bool, f64) {
    let target = constraints.tightened(super::PENALTY_MARGIN_FRACTION, super::PENALTY_MARGIN_MM);
    let fixed = family.fixed_points();
    let mut closest = 0.0f64;
    for attempt in 0..optimise::SPREAD_TRIES {
        let mut points = family.points(&family.initial());
        let mut rng = crate::synthetic::stream_rng(0, FEASIBILITY_STREAM, attempt);
        if target.spread_distances(&mut points, &fixed, &mut rng) {
            return (
                true,
                constraints.violations(&points).smallest_distance_diff_mm,
            );
        }
        closest = closest.max(constraints.violations(&points).smallest_distance_diff_mm);
    }
    (false, closest)
}

/// The up-front identifiability check of a custom family: the number of
/// distances may fit the envelope's range ([`Constraints::distinct_distance_capacity`]),
/// but they must also fit the geometry, which allows far fewer (with the
/// default constraints, 13 points rather than the 18 the range allows).
/// If the distance-spreading repair finds no identifiable layout from the
/// family's start, the search (whose starts repair the same way) would not
/// either: the refusal says how close it came and which point count,
/// envelope or difference it does reach. It is a failed search, not a
/// proof that no layout exists, and says so.
fn unidentifiable(family: &Family, constraints: &Constraints) -> Option<String> {
    let (met, closest) = spread_check(family, constraints);
    if met {
        return None;
    }
    let points = family.point_count();
    let diff = constraints.min_distance_diff_mm;
    let rebuilt = |kind: FamilyKind, envelope: Envelope| {
        Family::new(kind, envelope, constraints.sphere_diameter_mm).ok()
    };
    let mut options = Vec::new();
    if let FamilyKind::Custom { start: None, .. } = family.kind() {
        if let Some(count) = (4..points).rev().find(|&count| {
            rebuilt(
                FamilyKind::Custom { count, start: None },
                constraints.envelope,
            )
            .is_some_and(|f| spread_check(&f, constraints).0)
        }) {
            options.push(format!("--points {count}"));
        }
    }
    let size = constraints.envelope.size_mm;
    if let Some(envelope) = FEASIBLE_ENVELOPE_SCALES.iter().find_map(|scale| {
        let envelope = Envelope::new(size.map(|s| s * scale)).ok()?;
        let family = rebuilt(family.kind().clone(), envelope)?;
        let wider = Constraints {
            envelope,
            ..*constraints
        };
        spread_check(&family, &wider).0.then_some(envelope)
    }) {
        let [x, y, z] = envelope.size_mm;
        options.push(if x == y && y == z {
            format!("--envelope {x}")
        } else {
            format!("--envelope {x},{y},{z}")
        });
    }
    if let Some(smaller) = FEASIBLE_DIFF_FRACTIONS.iter().find_map(|fraction| {
        let smaller = Constraints {
            min_distance_diff_mm: diff * fraction,
            ..*constraints
        };
        spread_check(family, &smaller)
            .0
            .then_some(smaller.min_distance_diff_mm)
    }) {
        options.push(format!("--min-distance-diff {smaller}"));
    }
    let options = if options.is_empty() {
        "it finds none with fewer points, a larger envelope or a smaller difference either"
            .to_string()
    } else {
        format!("it does find one with {}", options.join(", or "))
    };
    Some(format!(
        "no layout of {points} points found whose {} pairwise distances differ by {diff} mm or more: the distance-spreading repair that every start of the search uses got them {closest:.2} mm apart at best ({} seeded tries; a failed search, not a proof that none exists); {options}",
        points * (points - 1) / 2,
        optimise::SPREAD_TRIES,
    ))
}

/// Removes what a killed run may have left of the outputs' temporaries and
/// says how many there were. The caller holds the outputs' locks.
fn remove_stale_temporaries(config: &SearchConfig, partial: &Path) -> usize {
    let mut removed = 0;
    for path in [&config.layout_path, &partial.to_path_buf()] {
        removed += files::remove_stale_temporaries(path).unwrap_or(0);
    }
    let mut dirs = vec![
        config.report_dir.clone(),
        config.report_dir.join("winner-validation"),
    ];
    dirs.extend(config.export.as_ref().map(|e| e.dir.clone()));
    dirs.extend(config.front.as_ref().map(|f| f.layout_dir.clone()));
    for dir in dirs {
        removed += files::remove_stale_temporaries_in(&dir).unwrap_or(0);
    }
    removed
}

/// Runs the whole search: optimises [`SearchConfig::family`] (resuming from
/// checkpoints when asked), compares the winner with its start and the hand
/// designs on the same scenarios and draws, validates it, and only then
/// writes it to [`SearchConfig::layout_path`] with the report in
/// [`SearchConfig::report_dir`] (and its meshes when asked).
///
/// Before any work it checks the settings, the constraints (where that is
/// possible without searching) and that every output can be written, and
/// locks the outputs ([`files::OutputLock`]): a second run on the same
/// outputs fails at once with [`SearchError::Lock`].
///
/// While the search runs, the best layout so far goes to
/// [`partial_path`]`(layout_path)`, never to `layout_path` itself.
/// `observer` hears each phase's progress and the checkpoint decision, and
/// may stop the run ([`Observer::interrupted`]) in any phase; an interrupted
/// run writes the best layout seen to the partial file, keeps its
/// checkpoints, leaves the layout and report of any earlier finished run
/// untouched, and returns at once with [`SearchOutcome::interrupted`] set.
pub fn run(
    config: &SearchConfig,
    observer: &mut impl Observer,
) -> Result<SearchOutcome, SearchError> {
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
    let name = &config.name;
    let seed = config.search.seed;
    let partial = partial_path(&config.layout_path);

    check_outputs(config)?;
    let mut locks = vec![files::OutputLock::acquire(&config.layout_path)?];
    if config.report_dir != config.layout_path {
        locks.push(files::OutputLock::acquire(&config.report_dir)?);
    }
    if let Some(export) = &config.export {
        locks.push(files::OutputLock::acquire(&export.dir)?);
    }
    let stale = remove_stale_temporaries(config, &partial);
    if stale > 0 {
        observer.log(&format!(
            "removed {stale} temporary file(s) a killed run left behind"
        ));
    }

    let hand = hand_designs(&constraints.envelope, constraints.sphere_diameter_mm);
    let paper = &hand[0];
    let evaluator = Evaluator::new(
        config.camera,
        config.grid.scenarios(),
        config.objective.clone(),
        constraints,
        &paper.positions(),
    );
    // Everything that decides which layouts the search evaluates: the key of
    // its checkpoints.
    let search_config = serde_json::json!({
        "version": env!("CARGO_PKG_VERSION"),
        "family": description,
        "start_layout": match family.kind() {
            FamilyKind::Custom { start: Some(layout), .. } => serde_json::to_value(layout)
                .expect("a layout serialises"),
            _ => serde_json::Value::Null,
        },
        "sphere_diameter_mm": constraints.sphere_diameter_mm,
        "constraints": constraints,
        "camera": config.camera,
        "grid": config.grid,
        "objective": config.objective,
        "search": config.search,
    });
    // Another run with the same checkpoints (an explicit shared checkpoint
    // directory, same name and configuration) would clobber them.
    let checkpoint_dir = config.checkpoint_dir.join(format!(
        "{name}-{}",
        super::checkpoint::config_hash(&search_config)
    ));
    locks.push(files::OutputLock::acquire(&checkpoint_dir)?);
    let (checkpoints, resume_status) =
        Checkpoints::prepare(&config.checkpoint_dir, name, &search_config, config.resume)?;
    match resume_status {
        ResumeStatus::Resuming => {
            let _ = files::remove_stale_temporaries_in(checkpoints.dir());
            observer.log(&format!(
                "resuming from the checkpoints in {}",
                checkpoints.dir().display()
            ))
        }
        ResumeStatus::NothingToResume => observer.log(&format!(
            "no checkpoint of this configuration (hash {}); starting afresh",
            checkpoints.hash()
        )),
        ResumeStatus::Fresh => {}
    }
    let provenance = serde_json::json!({
        "command": config.command,
        "seed": seed,
        "objective": config.objective.objective.to_string(),
        "aggregate": format!("{:?}", config.objective.aggregate).to_lowercase(),
        "version": env!("CARGO_PKG_VERSION"),
    });

    let settings = &config.search;
    let budget = settings.iterations
        + if settings.optimiser == Optimiser::NelderMead {
            0
        } else {
            settings.polish_iterations
        };
    let tracker = Arc::new(Tracker {
        family: family.clone(),
        name: name.clone(),
        path: partial.clone(),
        provenance: provenance.clone(),
        write_error: Mutex::new(None),
        last_write: Mutex::new(None),
        iterations: Mutex::new(vec![StartProgress::default(); settings.starts]),
        budget,
    });
    let stop = AtomicBool::new(false);
    let started = Instant::now();
    let outcome = watch(
        observer,
        PHASE_SEARCH,
        settings.starts as u64 * budget,
        || tracker.done(),
        Some(&stop),
        || {
            optimise::run(
                &family,
                &evaluator,
                settings,
                &stop,
                tracker.clone(),
                Some(&checkpoints),
            )
        },
    )?;
    let search_seconds = started.elapsed().as_secs_f64();
    if let Some(error) = tracker
        .write_error
        .lock()
        .expect("no panics while holding the lock")
        .take()
    {
        return Err(SearchError::BestSoFar(error));
    }
    let identify_started = Instant::now();
    let (outcome, identify_books) = match config.min_identifiability {
        Some(floor) if !outcome.interrupted => {
            // One step per round; a winner that needs fewer rounds ends the
            // bar at its total.
            let rounds_done = AtomicU64::new(0);
            let repaired = watch(
                observer,
                PHASE_IDENTIFY,
                IDENTIFY_ROUNDS as u64,
                || rounds_done.load(Ordering::Relaxed),
                Some(&stop),
                || {
                    let repaired = enforce_identifiability(
                        &family,
                        &evaluator,
                        floor,
                        &config.search,
                        outcome,
                        &stop,
                    );
                    rounds_done.store(IDENTIFY_ROUNDS as u64, Ordering::Relaxed);
                    repaired
                },
            )?;
            (repaired.0, Some(repaired.1))
        }
        _ => (outcome, None),
    };
    let identify_seconds = identify_started.elapsed().as_secs_f64();
    let identify_books = identify_books.map(|mut b| {
        b.seconds = identify_seconds;
        b
    });
    let best_cost = outcome.best.evaluation.cost;
    let best_params = outcome.best.params.clone();
    let mut result = SearchOutcome {
        winner: family.layout(name, &outcome.best.params),
        objective: best_cost,
        family: description.clone(),
        evaluations: outcome.evaluations,
        interrupted: false,
        interrupted_phase: None,
        partial: partial.clone(),
        checkpoints: checkpoints.dir().to_path_buf(),
        summary: None,
        exported: Vec::new(),
        front: None,
        search_seconds,
        total_seconds: search_seconds,
    };
    // Ends the run in `phase`: the best layout goes to the partial file, the
    // checkpoints stay, the finished outputs are not touched.
    let interrupted = |mut result: SearchOutcome, phase: &str, status: &str| {
        tracker
            .write(&best_params, best_cost, status)
            .map_err(|e| SearchError::BestSoFar(e.to_string()))?;
        result.interrupted = true;
        result.interrupted_phase = Some(phase.to_string());
        result.winner = Layout::load(&partial)?;
        result.total_seconds = started.elapsed().as_secs_f64();
        Ok(result)
    };
    if outcome.interrupted {
        return interrupted(result, PHASE_SEARCH, "interrupted: best layout seen");
    }
    let violations = &outcome.best.evaluation.violations;
    if !violations.feasible() {
        // An infeasible winner is never a finished result.
        tracker
            .write(
                &outcome.best.params,
                best_cost,
                "infeasible: breaks the constraints",
            )
            .map_err(|e| SearchError::BestSoFar(e.to_string()))?;
        checkpoints.remove()?;
        return Err(SearchError::Infeasible {
            layout: partial.clone(),
            violations: violations.describe(&constraints),
        });
    }

    observer.log(&format!(
        "search finished: objective {best_cost:.6} after {} evaluations in {search_seconds:.1} s",
        outcome.evaluations
    ));

    let mut winner = family.layout(name, &outcome.best.params);
    let provenance_for_front = provenance.clone();
    let mut final_provenance = provenance;
    final_provenance["score"] = best_cost.into();
    final_provenance["status"] = STATUS_FINISHED.into();
    final_provenance["evaluations"] = outcome.evaluations.into();
    winner.provenance = Some(final_provenance);

    // Compare on the same scenarios and draws, on the search seed and an
    // independent validation seed.
    let validation_seed = seed.wrapping_add(1);
    let start_layout = family.layout(&format!("{name}-start"), &family.initial());
    let mut designs = vec![
        (name.clone(), winner.clone()),
        ("start".to_string(), start_layout),
    ];
    let paper_index = designs.len();
    designs.extend(hand.iter().map(|l| (l.name.clone(), l.clone())));
    let hand_range = paper_index..designs.len();
    // Hand designs that break a constraint (the paper's biprism and the cube
    // corners repeat pairwise distances) also appear made admissible, by the
    // search's own repair, so the winner meets them like for like.
    for layout in &hand {
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
        )?;
        let params = optimise::repair(&free, &evaluator, &free.initial())?;
        let mut admissible = free.layout(&format!("{}-admissible", layout.name), &params);
        admissible.provenance = Some(serde_json::json!({
            "source": format!("{} moved to the nearest layout that meets the constraints (the search's repair)", layout.name),
        }));
        designs.push((admissible.name.clone(), admissible));
    }
    let admissible_range = hand_range.end..designs.len();
    let seeds = [seed, validation_seed];
    let compared = AtomicU64::new(0);
    let compare_total = (designs.len() * seeds.len() * evaluator.scenarios().len()) as u64;
    // Every design's identifiability over every visible scenario.
    let compare_evaluator =
        evaluator.with_identifiability(config.min_identifiability, IdentifyScope::All);
    let rows = watch(
        observer,
        PHASE_COMPARE,
        compare_total,
        || compared.load(Ordering::Relaxed),
        Some(&stop),
        || {
            compare(
                &config.camera,
                &compare_evaluator,
                &designs,
                config.compare_solver,
                config.compare_trials,
                &seeds,
                config.objective.noise,
                &CompareProgress {
                    on_scenario_done: &|| {
                        compared.fetch_add(1, Ordering::Relaxed);
                    },
                    stop: &stop,
                },
            )
        },
    );
    let rows = match rows {
        Err(MonteCarloError::Interrupted) => {
            return interrupted(
                result,
                PHASE_COMPARE,
                "interrupted in the comparison: the search's winner, report not written",
            )
        }
        rows => rows?,
    };
    observer.log(&format!(
        "comparison finished: {} designs on {} seeds",
        designs.len(),
        seeds.len()
    ));

    // First-order figures of the winner and the paper's biprism on a held-out
    // grid (midpoints of the search grid's values).
    let held_out = {
        let grid = held_out_grid(&config.grid);
        let first_order = evaluator
            .on_scenarios(grid.scenarios(), &paper.positions())
            .first_order(&paper.positions());
        HeldOutCheck::new(
            &grid,
            &first_order.evaluate(&winner.positions(), &winner.point_sigmas()),
            &first_order.evaluate(&paper.positions(), &paper.point_sigmas()),
        )
    };

    let front = match &config.front {
        None => None,
        Some(output) => {
            let front_started = Instant::now();
            let levels_done = AtomicU64::new(0);
            let (points, evaluations) = watch(
                observer,
                PHASE_FRONT,
                (output.settings.levels + 1 + front::BLEND_WEIGHTS.len()) as u64,
                || levels_done.load(Ordering::Relaxed),
                Some(&stop),
                || {
                    front::sweep(
                        &family,
                        &evaluator,
                        settings,
                        &output.settings,
                        std::slice::from_ref(&outcome.best),
                        &stop,
                        &levels_done,
                    )
                },
            )?;
            if stop.load(Ordering::Relaxed) {
                return interrupted(
                    result,
                    PHASE_FRONT,
                    "interrupted in the front's sweep: the search's winner, report not written",
                );
            }
            let hand_rows: Vec<_> = rows[paper_index..]
                .iter()
                .map(|r| (r.name.clone(), r.layout.clone(), r.evaluation.clone()))
                .collect();
            // Built now, written with the rest of the report once the
            // winner's validation has finished: an interrupted run leaves
            // no front without its report.
            let files = front::build(
                &output.layout_dir,
                name,
                &family,
                &points,
                &evaluator.first_order(&paper.positions()),
                &hand_rows,
                &provenance_for_front,
                (evaluations, front_started.elapsed().as_secs_f64()),
                &output.settings,
            );
            Some(files)
        }
    };
    let summary = SearchSummary {
        header: SearchHeader {
            command: config.command.clone(),
            version: env!("CARGO_PKG_VERSION").to_string(),
            family: description,
            constraints,
            objective: config.objective.clone(),
            search: config.search.clone(),
            grid: config.grid.clone(),
            camera: config.camera,
            comparison_solver: config.compare_solver.name().to_string(),
            comparison_trials: config.compare_trials,
            comparison_seeds: seeds.to_vec(),
        },
        verdicts: verdicts(&rows, paper_index, hand_range, admissible_range),
        outcome,
        designs: rows,
        held_out,
        front: front.as_ref().map(|f| f.report.clone()),
        identifiability: identify_books,
    };

    let validation_config = MonteCarloConfig {
        trials: config.compare_trials,
        seed: validation_seed,
        solvers: config.validate_solvers.clone(),
        noise: config.objective.noise,
        gross_threshold_deg: DEFAULT_GROSS_THRESHOLD_DEG,
        observation: config.objective.observation,
    };
    let validation_config = ValidateConfig {
        layout: winner.clone(),
        camera: config.camera,
        grid: config.grid.clone(),
        monte_carlo: validation_config,
        identifiability: config.identifiability_check(),
        fabrication_sigma_mm: 0.0,
        command: config.command.clone(),
    };
    let validation_config = validation_config.check().map_err(ValidateError::from)?;
    let scenarios_done = AtomicU64::new(0);
    let validation = watch(
        observer,
        PHASE_VALIDATE,
        2 * config.grid.scenarios().len() as u64,
        || scenarios_done.load(Ordering::Relaxed),
        Some(&stop),
        || {
            validate::analysis::monte_carlo_until(
                validation_config,
                validate::analysis::Hooks {
                    on_scenario_done: &|_| {
                        scenarios_done.fetch_add(1, Ordering::Relaxed);
                    },
                    stop: &stop,
                },
            )
        },
    );
    let validation =
        match validation {
            Err(ValidateError::MonteCarlo(MonteCarloError::Interrupted)) => return interrupted(
                result,
                PHASE_VALIDATE,
                "interrupted in the winner's validation: the search's winner, report not written",
            ),
            validation => validation?,
        };

    // Every phase finished: only now are the finished outputs replaced.
    winner.save_atomic(&config.layout_path)?;
    search_report::write(&config.report_dir, &summary)?;
    validate::report::write(&config.report_dir.join("winner-validation"), &validation)?;
    let total_seconds = started.elapsed().as_secs_f64();
    let run_path = config.report_dir.join("run.json");
    let run_json = serde_json::to_string_pretty(&serde_json::json!({
        "search_seconds": search_seconds,
        "total_seconds": total_seconds,
        "evaluations": summary.outcome.evaluations,
        "evaluations_this_run": summary.outcome.evaluations_this_run,
        "resumed": resume_status == ResumeStatus::Resuming,
        "threads": rayon::current_num_threads(),
    }))
    .map_err(|e| ReportError::write(&run_path, e))?;
    write_text(&run_path, &(run_json + "\n"))?;
    if let Some(files) = &front {
        front::write(&config.report_dir, files)?;
    }

    if let Some(export) = &config.export {
        observer.progress(PHASE_EXPORT, 0, 1);
        let options = ExportOptions {
            formats: export.formats.clone(),
            ..Default::default()
        };
        let report = crate::mesh::export(&winner, &options, &export.dir).map_err(|source| {
            SearchError::Export {
                dir: export.dir.clone(),
                source,
            }
        })?;
        observer.progress(PHASE_EXPORT, 1, 1);
        result.exported = report.files.into_iter().map(|f| f.path).collect();
    }
    checkpoints.remove()?;
    match std::fs::remove_file(&partial) {
        Ok(()) => {}
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
        Err(e) => observer.log(&format!(
            "could not remove the superseded {}: {e}",
            partial.display()
        )),
    }
    drop(locks);
    if config.checkpoint_dir == checkpoint_dir_beside(&config.layout_path) {
        // The default root is this output's own: leave no empty directory
        // (one still in use by another configuration is not empty).
        let _ = std::fs::remove_dir(&config.checkpoint_dir);
    }
    result.winner = winner;
    result.summary = Some(summary);
    result.front = front.map(|f| f.report);
    result.total_seconds = started.elapsed().as_secs_f64();
    Ok(result)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::observer::{Collect, Silent};

    fn small(dir: &Path) -> SearchConfig {
        let mut config = SearchConfig::new("t", dir);
        config.grid = ScenarioGrid::new(
            "300,800".parse().unwrap(),
            "0,60".parse().unwrap(),
            Range::single(0.0),
            "-40..40:20".parse().unwrap(),
            Range::single(0.0),
            Range::single(0.0),
            Range::single(0.5),
        )
        .unwrap();
        config.search.starts = 2;
        config.search.iterations = 100;
        config.compare_trials = 10;
        config.validate_solvers = vec![Solver::ParallelWeighted];
        config
    }

    #[test]
    fn a_search_writes_every_output_where_the_config_says() {
        let dir = tempfile::tempdir().unwrap();
        let mut config = small(dir.path());
        config.report_dir = dir.path().join("elsewhere/report");
        let mut observer = Collect::default();
        let outcome = run(&config, &mut observer).unwrap();
        assert!(!outcome.interrupted);
        assert_eq!(observer.lines.len(), 2, "{:?}", observer.lines);
        assert!(observer.lines[0].starts_with("search finished"));
        assert!(
            !outcome.partial.exists(),
            "a finished run leaves no partial file"
        );
        assert!(
            !config.checkpoint_dir.exists(),
            "nor its checkpoint directory"
        );
        let provenance = outcome.winner.provenance.as_ref().unwrap();
        assert_eq!(provenance["status"], STATUS_FINISHED);
        assert_eq!(Layout::load(&config.layout_path).unwrap(), outcome.winner);
        assert!(config.report_dir.join("report.md").exists());
        assert!(config
            .report_dir
            .join("winner-validation/report.md")
            .exists());
        assert!(!outcome.checkpoints.exists());
        assert!(!dir.path().join("t-report").exists());
        let summary = outcome.summary.unwrap();
        assert_eq!(summary.designs[0].name, "t");
    }

    /// Interrupts as soon as `phase` has made progress or, with
    /// `at_start`, as soon as it begins (a phase shorter than the
    /// observer's polling interval could otherwise end before a stop lands).
    struct StopIn {
        phase: &'static str,
        at_start: bool,
        progressed: bool,
        phases: Vec<String>,
    }

    impl StopIn {
        fn new(phase: &'static str) -> Self {
            Self {
                phase,
                at_start: false,
                progressed: false,
                phases: Vec::new(),
            }
        }

        fn at_start(phase: &'static str) -> Self {
            Self {
                at_start: true,
                ..Self::new(phase)
            }
        }
    }

    impl Observer for StopIn {
        fn progress(&mut self, phase: &str, done: u64, _total: u64) {
            assert!(
                !self.progressed || phase == self.phase,
                "no phase runs after a stop"
            );
            if self.phases.last().is_none_or(|p| p != phase) {
                self.phases.push(phase.to_string());
            }
            self.progressed |= phase == self.phase && (self.at_start || done > 0);
        }
        fn interrupted(&self) -> bool {
            self.progressed
        }
    }

    #[test]
    fn an_interrupted_search_keeps_its_best_layout_and_checkpoints() {
        let dir = tempfile::tempdir().unwrap();
        let mut config = small(dir.path());
        config.search.iterations = 100_000;
        let mut observer = StopIn::new(PHASE_SEARCH);
        let outcome = run(&config, &mut observer).unwrap();
        assert!(outcome.interrupted && outcome.summary.is_none());
        assert_eq!(outcome.interrupted_phase.as_deref(), Some(PHASE_SEARCH));
        assert!(outcome.checkpoints.exists());
        assert!(
            !config.layout_path.exists(),
            "only a finished run writes --out"
        );
        assert_eq!(Layout::load(&outcome.partial).unwrap(), outcome.winner);
        assert!(!config.report_dir.exists());
        assert!(!files::lock_path(&config.layout_path).exists());
    }

    #[test]
    fn every_phase_can_be_interrupted_and_the_finished_result_stays() {
        let dir = tempfile::tempdir().unwrap();
        let mut config = small(dir.path());
        // Long enough phases that a stop lands inside each.
        config.compare_trials = 400;
        config.validate_solvers = vec![Solver::ParallelWeighted, Solver::Ml];
        let finished = run(&config, &mut Silent).unwrap();
        let layout_bytes = std::fs::read(&config.layout_path).unwrap();
        let report_bytes = std::fs::read(config.report_dir.join("summary.json")).unwrap();
        for phase in [PHASE_COMPARE, PHASE_VALIDATE] {
            let mut observer = StopIn::at_start(phase);
            let outcome = run(&config, &mut observer).unwrap();
            assert!(outcome.interrupted, "{phase}");
            assert_eq!(outcome.interrupted_phase.as_deref(), Some(phase));
            assert_eq!(observer.phases.last().map(String::as_str), Some(phase));
            // The search had finished: the partial file holds its winner.
            let partial = Layout::load(&outcome.partial).unwrap();
            assert_eq!(partial.points, finished.winner.points);
            let status = partial.provenance.unwrap()["status"].clone();
            assert!(status.as_str().unwrap().contains(phase), "{status}");
            assert_eq!(std::fs::read(&config.layout_path).unwrap(), layout_bytes);
            assert_eq!(
                std::fs::read(config.report_dir.join("summary.json")).unwrap(),
                report_bytes
            );
            assert!(outcome.checkpoints.exists());
        }
        // A resumed run finishes, counts every evaluation and cleans up.
        let mut resumed_config = config.clone();
        resumed_config.resume = true;
        let resumed = run(&resumed_config, &mut Silent).unwrap();
        assert_eq!(resumed.evaluations, finished.evaluations);
        assert_eq!(resumed.winner.points, finished.winner.points);
        assert!(!resumed.partial.exists() && !resumed.checkpoints.exists());
    }

    #[test]
    fn a_front_is_written_with_its_report_and_not_before() {
        let dir = tempfile::tempdir().unwrap();
        let mut config = small(dir.path());
        config.validate_solvers = vec![Solver::ParallelWeighted, Solver::Ml];
        let layout_dir = dir.path().join("t-front");
        config.front = Some(FrontOutput {
            settings: FrontSettings {
                levels: 1,
                iterations: 40,
            },
            layout_dir: layout_dir.clone(),
        });
        // Stopped in the winner's validation, after the front's sweep: no
        // front file without its report.
        let mut observer = StopIn::at_start(PHASE_VALIDATE);
        let outcome = run(&config, &mut observer).unwrap();
        assert!(outcome.interrupted);
        assert!(observer.phases.iter().any(|p| p == PHASE_FRONT));
        assert!(!layout_dir.exists(), "front layouts before the report");
        assert!(!config.report_dir.exists());
        // A finished run writes both.
        let outcome = run(&config, &mut Silent).unwrap();
        let front = outcome.front.expect("a front");
        assert!(!front.members.is_empty());
        for member in &front.members {
            Layout::load(&member.layout).unwrap();
        }
        for file in ["front.json", "front.csv", "front.svg", "summary.json"] {
            assert!(config.report_dir.join(file).exists(), "{file}");
        }
    }

    #[test]
    fn custom_layouts_of_twelve_points_end_identifiable_and_sixteen_are_refused_up_front() {
        let dir = tempfile::tempdir().unwrap();
        let mut config = small(dir.path());
        // The stereo rule (pairwise distances 1 mm apart) in the default
        // 100 mm cube.
        config.constraints.min_distance_diff_mm = 1.0;
        config.family = FamilyKind::Custom {
            count: 12,
            start: None,
        };
        config.search.iterations = 60;
        config.search.polish_iterations = 40;
        let outcome = run(&config, &mut Silent).unwrap();
        let violations = config.constraints.violations(&outcome.winner.positions());
        assert!(violations.feasible(), "{violations:?}");
        assert!(violations.smallest_distance_diff_mm >= 1.0);
        let status = Layout::load(&config.layout_path)
            .unwrap()
            .provenance
            .unwrap()["status"]
            .clone();
        assert!(status.as_str().unwrap().starts_with("finished"), "{status}");

        // Sixteen: 120 distances fit the range (capacity 162) but not the
        // cube's geometry as far as the repair finds; refused before any
        // work, with what it does reach.
        let dir = tempfile::tempdir().unwrap();
        let mut config = small(dir.path());
        config.constraints.min_distance_diff_mm = 1.0;
        config.family = FamilyKind::Custom {
            count: 16,
            start: None,
        };
        let error = run(&config, &mut Silent).unwrap_err();
        let text = error.to_string();
        assert!(matches!(error, SearchError::Unsatisfiable(_)), "{text}");
        assert!(text.contains("no layout of 16 points"), "{text}");
        assert!(text.contains("--points 1"), "{text}");
        assert!(text.contains("not a proof"), "{text}");
        assert!(!config.checkpoint_dir.exists());
        assert!(!config.layout_path.exists());
    }

    /// Records each phase's last progress.
    #[derive(Default)]
    struct Record {
        last: Vec<(String, u64, u64)>,
    }

    impl Observer for Record {
        fn progress(&mut self, phase: &str, done: u64, total: u64) {
            assert!(done <= total, "{phase}: {done} of {total}");
            match self.last.last_mut() {
                Some(last) if last.0 == phase => {
                    assert!(
                        done >= last.1,
                        "{phase} went back from {} to {done}",
                        last.1
                    );
                    assert_eq!(total, last.2, "{phase} changed its total");
                    *last = (phase.to_string(), done, total);
                }
                _ => self.last.push((phase.to_string(), done, total)),
            }
        }
    }

    #[test]
    fn every_phase_has_a_bar_that_ends_at_its_total() {
        let dir = tempfile::tempdir().unwrap();
        let mut config = small(dir.path());
        config.search.starts = 3;
        config.search.iterations = 400;
        let mut observer = Record::default();
        run(&config, &mut observer).unwrap();
        let phases: Vec<&str> = observer.last.iter().map(|p| p.0.as_str()).collect();
        assert_eq!(
            phases,
            [PHASE_SEARCH, PHASE_IDENTIFY, PHASE_COMPARE, PHASE_VALIDATE]
        );
        // The search's total is its real budget: starts × iterations.
        assert_eq!(observer.last[0].2, 3 * 400);
        assert_eq!(observer.last[1].2, IDENTIFY_ROUNDS as u64);
        // The comparison: 5 designs (winner, start, 3 hand designs; none
        // made admissible, the stereo distance rule being off) × 2 seeds ×
        // 20 scenarios.
        assert_eq!(observer.last[2].2, 5 * 2 * 20);
        // The validation: its Monte-Carlo run, then identifiability.
        assert_eq!(observer.last[3].2, 2 * 20);
        for (phase, done, total) in &observer.last {
            assert_eq!(done, total, "{phase} ended short of its total");
        }
    }

    #[test]
    fn a_resumed_search_keeps_the_books() {
        let longer = |dir: &Path| {
            let mut config = small(dir);
            config.search.iterations = 2000;
            config
        };
        let dir = tempfile::tempdir().unwrap();
        let straight = run(&longer(dir.path()), &mut Silent).unwrap();
        let other = tempfile::tempdir().unwrap();
        let config = longer(other.path());
        let first = run(&config, &mut StopIn::new(PHASE_SEARCH)).unwrap();
        assert!(first.interrupted);
        // A temporary left by a killed writer is removed.
        let stale = config.layout_path.with_file_name(".t.json.999999.0.tmp");
        std::fs::write(&stale, "half a layout").unwrap();
        let mut resume = config.clone();
        resume.resume = true;
        let mut observer = Collect::default();
        let resumed = run(&resume, &mut observer).unwrap();
        assert!(!stale.exists());
        assert!(observer.lines.iter().any(|l| l.contains("resuming")));
        assert_eq!(resumed.evaluations, straight.evaluations);
        let run_json: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(config.report_dir.join("run.json")).unwrap(),
        )
        .unwrap();
        assert_eq!(run_json["evaluations"], straight.evaluations);
        assert_eq!(run_json["resumed"], true);
        assert!(run_json["evaluations_this_run"].as_u64().unwrap() < straight.evaluations as u64);
    }

    #[test]
    fn outputs_are_checked_and_locked_before_any_work() {
        let dir = tempfile::tempdir().unwrap();
        let mut config = small(dir.path());
        // Another run holds the layout.
        let lock = files::OutputLock::acquire(&config.layout_path).unwrap();
        let error = run(&config, &mut Silent).unwrap_err();
        assert!(matches!(error, SearchError::Lock(_)), "{error}");
        assert!(
            error.to_string().contains("in use by another run"),
            "{error}"
        );
        assert!(!config.checkpoint_dir.exists());
        drop(lock);
        // The layout's directory is a file.
        let file = dir.path().join("plain-file");
        std::fs::write(&file, "x").unwrap();
        config.layout_path = file.join("t.json");
        config.checkpoint_dir = checkpoint_dir_beside(&config.layout_path);
        let error = run(&config, &mut Silent).unwrap_err();
        assert!(matches!(error, SearchError::Unwritable { .. }), "{error}");
        // The report directory is a file.
        let mut config = small(dir.path());
        config.report_dir = file.clone();
        let error = run(&config, &mut Silent).unwrap_err();
        assert!(matches!(error, SearchError::Unwritable { .. }), "{error}");
        assert!(!config.checkpoint_dir.exists());
    }

    #[test]
    fn impossible_constraints_are_refused_before_the_search() {
        let dir = tempfile::tempdir().unwrap();
        let mut config = small(dir.path());
        config.constraints.min_distance_diff_mm = 1.0;
        config.family = FamilyKind::Custom {
            count: 30,
            start: None,
        };
        let error = run(&config, &mut Silent).unwrap_err();
        assert!(matches!(error, SearchError::Unsatisfiable(_)), "{error}");
        assert!(
            error.to_string().contains("435 pairwise distances"),
            "{error}"
        );
        assert!(!config.checkpoint_dir.exists());
        assert!(!config.layout_path.exists());
    }

    #[test]
    fn bad_settings_are_typed_errors() {
        let dir = tempfile::tempdir().unwrap();
        let mut config = small(dir.path());
        config.compare_trials = 0;
        assert!(matches!(
            run(&config, &mut Silent),
            Err(SearchError::Config(_))
        ));
        config.compare_trials = 10;
        config.search.iterations = 0;
        assert!(matches!(
            run(&config, &mut Silent),
            Err(SearchError::Optimise(_))
        ));
        // Nothing was created for a refused configuration.
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
    }

    #[test]
    fn too_many_points_for_distinct_distances_are_refused_before_the_search() {
        let dir = tempfile::tempdir().unwrap();
        let mut config = small(dir.path());
        config.constraints.min_distance_diff_mm = 1.0;
        config.family = FamilyKind::Custom {
            count: 19,
            start: None,
        };
        let error = run(&config, &mut Silent).unwrap_err();
        assert!(
            error.to_string().contains("171 pairwise distances")
                && error.to_string().contains("at most 162"),
            "{error}"
        );
        assert!(!config.layout_path.exists());
        assert!(!config.checkpoint_dir.exists());
    }

    #[test]
    fn the_report_goes_beside_the_layout() {
        assert_eq!(
            report_dir_beside(Path::new("out/marker.json")),
            Path::new("out/marker-report")
        );
    }
}
