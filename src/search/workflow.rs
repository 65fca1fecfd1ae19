//! The search as a run that never loses or clobbers a result. [`run`] takes
//! a [`SearchConfig`] that names every input and every output path, and
//! reports progress through an [`Observer`]; it never prints. It checks and
//! locks its outputs before any work, keeps the best layout so far in
//! [`partial_path`], keeps checkpoints so that `resume` continues an
//! interrupted optimisation, can be stopped in every phase, and replaces the
//! layout and report only when every phase of the analysis has finished.
//!
//! The run is a short list of phases over one [`RunContext`]
//! ([`PHASES`]): lock the outputs, prepare the checkpoints, run the
//! analysis ([`super::analysis`]), write the outputs (the layout, the
//! report by [`super::report::write`], `run.json`), export the meshes, clean
//! up. A phase may end the run early (an interrupted analysis keeps its
//! best layout in the partial file).
//!
//! ```no_run
//! use layout_opt::observer::Silent;
//! use layout_opt::search::{workflow, SearchConfig};
//!
//! let dir = std::env::temp_dir().join("layout-opt-doc");
//! let mut config = SearchConfig::new("my-marker", &dir);
//! config.search.starts = 2;
//! config.search.iterations = 100;
//! let outcome = workflow::run(&config, &mut Silent)?;
//! println!("objective {:.4}", outcome.objective);
//! # Ok::<(), layout_opt::search::SearchError>(())
//! ```

use super::analysis::{Analysed, Analysis, Finished, Hooks, Stopped};
use super::checkpoint::{Checkpoints, ResumeStatus};
use super::config::{checkpoint_dir_beside, partial_path, SearchConfig};
use super::error::SearchError;
use super::front::FrontReport;
use super::optimise::{Candidate, SearchObserver};
use super::report;
use super::summary::SearchSummary;
use crate::family::Family;
use crate::files::{self, OutputLock};
use crate::layout::{Layout, LayoutError};
use crate::mesh::ExportOptions;
use crate::observer::Observer;
use crate::report::{write_text, ReportError};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::Instant;

/// Progress phase of the optional mesh export (one step).
pub const PHASE_EXPORT: &str = "export";
/// Provenance status of the partial file while the search runs.
pub const STATUS_RUNNING: &str = "best so far (search running or interrupted)";
/// Least time between two writes of the partial file during a search.
pub const PARTIAL_EVERY: std::time::Duration = std::time::Duration::from_secs(1);

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

impl SearchOutcome {
    /// What an interrupted run tells its user: where it stopped, where the
    /// best layout is and how to continue.
    pub fn interrupted_text(&self, layout_path: &Path) -> String {
        format!(
            "interrupted in the {} phase after {:.1} s; the best layout seen is in {}; {} and the report were left as they were; continue with --resume (checkpoints in {})",
            self.interrupted_phase.as_deref().unwrap_or("search"),
            self.total_seconds,
            self.partial.display(),
            layout_path.display(),
            self.checkpoints.display()
        )
    }

    /// What a finished run tells its user: the winner, the report's
    /// summary ([`report::console`]), the exported files and where the
    /// report is. `None` when the run was interrupted.
    pub fn finished_text(&self, config: &SearchConfig) -> Option<String> {
        let summary = self.summary.as_ref()?;
        let mut text = format!(
            "{}: {} ({} evaluations in {:.1} s); wrote {}\n",
            config.name,
            self.family,
            self.evaluations,
            self.search_seconds,
            config.layout_path.display()
        );
        text.push_str(&report::console(summary));
        for file in &self.exported {
            text.push_str(&format!("exported {}\n", file.display()));
        }
        text.push_str(&format!(
            "report in {} ({:.1} s in all)\n",
            config.report_dir.display(),
            self.total_seconds
        ));
        Some(text)
    }
}

/// Keeps the best layout so far in the partial file (at most every
/// [`PARTIAL_EVERY`], so that fast improvements do not queue on the disk).
struct BestSoFar {
    family: Family,
    name: String,
    path: PathBuf,
    provenance: serde_json::Value,
    write_error: Mutex<Option<String>>,
    last_write: Mutex<Option<Instant>>,
}

impl BestSoFar {
    /// Writes `params` to the partial file with `status`.
    fn write(&self, params: &[f64], cost: f64, status: &str) -> Result<(), LayoutError> {
        let mut layout = self.family.layout(&self.name, params);
        let mut provenance = self.provenance.clone();
        provenance["status"] = status.into();
        provenance["score"] = cost.into();
        layout.provenance = Some(provenance);
        layout.save_atomic(&self.path)
    }

    /// A write that failed while the search ran, as an error.
    fn failed(&self) -> Result<(), SearchError> {
        match self
            .write_error
            .lock()
            .expect("no panics while holding the lock")
            .take()
        {
            Some(error) => Err(SearchError::BestSoFar(error)),
            None => Ok(()),
        }
    }
}

impl SearchObserver for BestSoFar {
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

    fn progress(&self, _: usize, _: u64, _: usize, _: f64) {}
}

/// Whether the run goes on to the next phase.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Flow {
    Continue,
    Stop,
}

/// What the phases of one run share.
pub struct RunContext<'c> {
    config: &'c SearchConfig,
    analysis: Analysis<'c>,
    partial: PathBuf,
    best_so_far: Arc<BestSoFar>,
    locks: Vec<OutputLock>,
    checkpoints: Option<(Checkpoints, ResumeStatus)>,
    started: Instant,
    finished: Option<Box<Finished>>,
    stopped: Option<Stopped>,
    exported: Vec<PathBuf>,
}

/// One phase of a run.
type Phase<O> = for<'a, 'b, 'c> fn(&'a mut RunContext<'b>, &'c mut O) -> Result<Flow, SearchError>;

/// The phases of a run, in order.
pub const PHASES: [&str; 6] = [
    "lock outputs",
    "prepare checkpoints",
    "analyse",
    "write outputs",
    "export",
    "clean up",
];

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
pub fn run<O: Observer>(
    config: &SearchConfig,
    observer: &mut O,
) -> Result<SearchOutcome, SearchError> {
    let analysis = Analysis::new(config)?;
    let best_so_far = Arc::new(BestSoFar {
        family: analysis.family().clone(),
        name: config.name.clone(),
        path: partial_path(&config.layout_path),
        provenance: analysis.provenance(),
        write_error: Mutex::new(None),
        last_write: Mutex::new(None),
    });
    let mut context = RunContext {
        config,
        analysis,
        partial: partial_path(&config.layout_path),
        best_so_far,
        locks: Vec::new(),
        checkpoints: None,
        started: Instant::now(),
        finished: None,
        stopped: None,
        exported: Vec::new(),
    };
    let phases: [Phase<O>; PHASES.len()] = [
        lock_outputs,
        prepare_checkpoints,
        analyse,
        write_outputs,
        export,
        clean_up,
    ];
    for phase in phases {
        if phase(&mut context, observer)? == Flow::Stop {
            break;
        }
    }
    context.outcome()
}

impl RunContext<'_> {
    fn checkpoints(&self) -> &Checkpoints {
        &self
            .checkpoints
            .as_ref()
            .expect("checkpoints are prepared before the analysis")
            .0
    }

    /// The run's outcome, once its phases have ended: finished, or stopped
    /// with the best layout in the partial file.
    fn outcome(self) -> Result<SearchOutcome, SearchError> {
        let total_seconds = self.started.elapsed().as_secs_f64();
        let checkpoints = self.checkpoints().dir().to_path_buf();
        let family = self.analysis.description().to_string();
        let outcome = match (self.finished, self.stopped) {
            (Some(finished), _) => {
                let Finished {
                    winner,
                    summary,
                    front,
                    search_seconds,
                    ..
                } = *finished;
                SearchOutcome {
                    winner,
                    objective: summary.outcome.best.evaluation.cost,
                    family,
                    evaluations: summary.outcome.evaluations,
                    interrupted: false,
                    interrupted_phase: None,
                    partial: self.partial,
                    checkpoints,
                    front: front.map(|f| f.report),
                    summary: Some(summary),
                    exported: self.exported,
                    search_seconds,
                    total_seconds,
                }
            }
            (None, Some(stopped)) => SearchOutcome {
                winner: Layout::load(&self.partial)?,
                objective: stopped.cost,
                family,
                evaluations: stopped.evaluations,
                interrupted: true,
                interrupted_phase: Some(stopped.phase.to_string()),
                partial: self.partial,
                checkpoints,
                summary: None,
                exported: Vec::new(),
                front: None,
                search_seconds: stopped.search_seconds,
                total_seconds,
            },
            (None, None) => unreachable!("the analysis phase ends finished or stopped"),
        };
        Ok(outcome)
    }
}

/// Checks that every output can be written, locks the outputs (a second
/// run on them fails at once) and removes what a killed run left of their
/// temporaries.
fn lock_outputs<O: Observer>(
    context: &mut RunContext<'_>,
    observer: &mut O,
) -> Result<Flow, SearchError> {
    let config = context.config;
    check_outputs(config)?;
    context
        .locks
        .push(OutputLock::acquire(&config.layout_path)?);
    if config.report_dir != config.layout_path {
        context.locks.push(OutputLock::acquire(&config.report_dir)?);
    }
    if let Some(export) = &config.export {
        context.locks.push(OutputLock::acquire(&export.dir)?);
    }
    let stale = remove_stale_temporaries(config, &context.partial);
    if stale > 0 {
        observer.log(&format!(
            "removed {stale} temporary file(s) a killed run left behind"
        ));
    }
    Ok(Flow::Continue)
}

/// Locks this configuration's checkpoints (another run with the same
/// checkpoint directory, name and configuration would clobber them) and
/// prepares them: fresh, or resumed when asked and found.
fn prepare_checkpoints<O: Observer>(
    context: &mut RunContext<'_>,
    observer: &mut O,
) -> Result<Flow, SearchError> {
    let config = context.config;
    let key = context.analysis.checkpoint_key();
    let dir = config.checkpoint_dir.join(format!(
        "{}-{}",
        config.name,
        super::checkpoint::config_hash(&key)
    ));
    context.locks.push(OutputLock::acquire(&dir)?);
    let (checkpoints, status) =
        Checkpoints::prepare(&config.checkpoint_dir, &config.name, &key, config.resume)?;
    match status {
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
    context.checkpoints = Some((checkpoints, status));
    Ok(Flow::Continue)
}

/// Runs the analysis with the checkpoints and the best-so-far file. An
/// interrupted analysis leaves its best layout in the partial file and ends
/// the run; an infeasible winner is never a finished result.
fn analyse<O: Observer>(
    context: &mut RunContext<'_>,
    observer: &mut O,
) -> Result<Flow, SearchError> {
    context.started = Instant::now();
    let best_so_far = context.best_so_far.clone();
    let after_search = || best_so_far.failed();
    let hooks = Hooks {
        listener: context.best_so_far.clone(),
        checkpoints: Some(context.checkpoints()),
        after_search: &after_search,
    };
    let keep = |best: &Stopped| {
        best_so_far
            .write(&best.params, best.cost, best.status)
            .map_err(|e| SearchError::BestSoFar(e.to_string()))
    };
    match context.analysis.run(observer, hooks)? {
        Analysed::Finished(finished) => {
            context.finished = Some(finished);
            Ok(Flow::Continue)
        }
        Analysed::Interrupted(stopped) => {
            keep(&stopped)?;
            context.stopped = Some(stopped);
            Ok(Flow::Stop)
        }
        Analysed::Infeasible { best, violations } => {
            keep(&best)?;
            context.checkpoints().remove()?;
            Err(SearchError::Infeasible {
                layout: context.partial.clone(),
                violations,
            })
        }
    }
}

/// Every phase of the analysis finished: only now are the finished outputs
/// replaced (the layout, the report, `run.json`).
fn write_outputs<O: Observer>(
    context: &mut RunContext<'_>,
    _observer: &mut O,
) -> Result<Flow, SearchError> {
    let config = context.config;
    let finished = context
        .finished
        .as_ref()
        .expect("the analysis finished before its outputs are written");
    finished.winner.save_atomic(&config.layout_path)?;
    report::write(&config.report_dir, finished)?;
    let run_path = config.report_dir.join("run.json");
    let outcome = &finished.summary.outcome;
    let run_json = serde_json::to_string_pretty(&serde_json::json!({
        "search_seconds": finished.search_seconds,
        "total_seconds": context.started.elapsed().as_secs_f64(),
        "evaluations": outcome.evaluations,
        "evaluations_this_run": outcome.evaluations_this_run,
        "resumed": context.checkpoints.as_ref().is_some_and(|c| c.1 == ResumeStatus::Resuming),
        "threads": rayon::current_num_threads(),
    }))
    .map_err(|e| ReportError::write(&run_path, e))?;
    write_text(&run_path, &(run_json + "\n"))?;
    Ok(Flow::Continue)
}

/// The winner's meshes, with `export`'s defaults, when asked for.
fn export<O: Observer>(
    context: &mut RunContext<'_>,
    observer: &mut O,
) -> Result<Flow, SearchError> {
    let Some(export) = &context.config.export else {
        return Ok(Flow::Continue);
    };
    let finished = context
        .finished
        .as_ref()
        .expect("the analysis finished before the export");
    observer.progress(PHASE_EXPORT, 0, 1);
    let options = ExportOptions {
        formats: export.formats.clone(),
        ..Default::default()
    };
    let report = crate::mesh::workflow::export(&finished.winner, &options, &export.dir).map_err(
        |source| SearchError::Export {
            dir: export.dir.clone(),
            source,
        },
    )?;
    observer.progress(PHASE_EXPORT, 1, 1);
    context.exported = report.files.into_iter().map(|f| f.path).collect();
    Ok(Flow::Continue)
}

/// Removes the checkpoints and the superseded partial file, releases the
/// locks, and leaves no empty default checkpoint directory.
fn clean_up<O: Observer>(
    context: &mut RunContext<'_>,
    observer: &mut O,
) -> Result<Flow, SearchError> {
    let config = context.config;
    context.checkpoints().remove()?;
    match std::fs::remove_file(&context.partial) {
        Ok(()) => {}
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
        Err(e) => observer.log(&format!(
            "could not remove the superseded {}: {e}",
            context.partial.display()
        )),
    }
    context.locks.clear();
    if config.checkpoint_dir == checkpoint_dir_beside(&config.layout_path) {
        // The default root is this output's own: leave no empty directory
        // (one still in use by another configuration is not empty).
        let _ = std::fs::remove_dir(&config.checkpoint_dir);
    }
    Ok(Flow::Continue)
}

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

#[cfg(test)]
mod tests;
