//! A validation as one call: the analysis, the report and `run.json`, into
//! the directory the configuration names, under a lock on it, with a time
//! estimate before a slow run and progress through an [`Observer`].
//!
//! [`run`] checks the configuration once, takes the output lock, logs an
//! estimate of a slow run, runs the analysis's Monte-Carlo runs, then its
//! phases in order over one [`Run`] context: [`error_budget`],
//! [`write_report`], [`write_noise_model`], [`write_run_json`]. A stop
//! during the Monte-Carlo runs or the budget leaves no report; the budget
//! comes before the report, which carries it.

use super::analysis;
use super::analysis::ValidateError;
use super::config::{Checked, ValidateConfig};
use super::image_check::{self, ImageCheck, NoiseLaw};
use super::report;
use super::summary::ValidateSummary;
use crate::config::ConfigError;
use crate::montecarlo::{self, MonteCarloConfig, Target};
use crate::noise::calibrated::{CalibrationFile, CentreErrorMeasure, LAW};
use crate::observer::Observer;
use crate::report::{duration_text, write_text, ReportError, SLOW_RUN_SECONDS};
use crate::scenario::Scenario;
use std::path::PathBuf;
use std::time::Instant;

/// Why a validation run could not finish.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum WorkflowError {
    /// The analysis failed, was interrupted, or its config is unusable.
    #[error(transparent)]
    Validate(#[from] ValidateError),
    /// An output is an input or another output, or another run holds it.
    #[error(transparent)]
    Output(#[from] crate::kernel::OutputError),
    /// The report could not be written.
    #[error(transparent)]
    Report(#[from] ReportError),
    /// The caller asked to stop after the last interruptible phase, before
    /// anything was written.
    #[error(transparent)]
    Interrupted(#[from] crate::kernel::Interrupted),
    /// The noise law could not be fitted or written.
    #[error("cannot write the noise model {path}: {reason}")]
    NoiseModel {
        /// The file asked for.
        path: PathBuf,
        /// Why.
        reason: String,
    },
}

impl WorkflowError {
    /// What the run was doing when Ctrl-C stopped it, for an interrupted
    /// run; `None` for any other error.
    pub fn interrupted(&self) -> Option<&'static str> {
        use crate::error_model::budget::BudgetError;
        use crate::montecarlo::MonteCarloError;
        use crate::validate::image_check::ImageCheckError;
        match self {
            WorkflowError::Validate(ValidateError::MonteCarlo(MonteCarloError::Interrupted)) => {
                Some("interrupted: no report written")
            }
            WorkflowError::Validate(ValidateError::Budget(BudgetError::Interrupted)) => {
                Some("interrupted during the error budget: no report written")
            }
            WorkflowError::Interrupted(_) => Some("interrupted: no report written"),
            WorkflowError::Validate(ValidateError::Images(ImageCheckError::Interrupted)) => {
                Some("interrupted during the image check: no report written")
            }
            _ => None,
        }
    }
}

/// Every input of a validation run: the analysis's configuration and where
/// and how the run writes.
#[derive(Debug, Clone)]
pub struct WorkflowConfig {
    /// What to validate.
    pub validate: ValidateConfig,
    /// The report directory.
    pub out_dir: PathBuf,
    /// A remark on how the grid was chosen, recorded in `run.json`.
    pub grid_note: Option<String>,
    /// Whether to time a short calibration run first and, when the run
    /// looks slow ([`SLOW_RUN_SECONDS`] or more), log the estimate.
    pub estimate: bool,
    /// The image-level check after the Monte-Carlo runs (None: none).
    pub images: Option<ImageCheck>,
    /// Where to write the noise law fitted by the image check (a
    /// [`CalibrationFile`]); needs [`Self::images`].
    pub noise_model_out: Option<PathBuf>,
    /// The files the run read (the layout, the camera, the volume, the
    /// noise law), each with the argument that named it: no output may be
    /// one of them.
    pub sources: Vec<(String, PathBuf)>,
}

impl WorkflowConfig {
    /// Checks what the workflow adds to the analysis's config: the image
    /// check's fields, and `write_noise_model` only with `images`.
    pub fn check(&self) -> Result<(), ConfigError> {
        if let Some(images) = &self.images {
            images.check()?;
        }
        if self.noise_model_out.is_some() && self.images.is_none() {
            return Err(ConfigError::new(
                "write_noise_model",
                "needs the image check (images): the law is fitted to its centres",
            ));
        }
        Ok(())
    }

    /// The run's outputs checked against its sources and each other, and
    /// locked, before any work ([`crate::kernel::outputs`]). The report's
    /// files are written atomically, one by one, once the run is done.
    fn open_outputs(&self) -> Result<crate::kernel::Outputs, crate::kernel::OutputError> {
        let mut plan = crate::kernel::OutputPlan::new();
        for (what, path) in &self.sources {
            plan.input(what.as_str(), path);
        }
        plan.dir("--out", &self.out_dir);
        if let Some(path) = &self.noise_model_out {
            plan.file("--write-noise-model", path);
        }
        plan.open()
    }

    /// `validate` into `out_dir`, no grid note, no estimate.
    pub fn new(validate: ValidateConfig, out_dir: impl Into<PathBuf>) -> Self {
        WorkflowConfig {
            validate,
            out_dir: out_dir.into(),
            grid_note: None,
            estimate: false,
            images: None,
            noise_model_out: None,
            sources: Vec::new(),
        }
    }
}

/// What a validation run produced.
#[derive(Debug, Clone)]
pub struct ValidateOutcome {
    /// The summary the report was written from.
    pub summary: ValidateSummary,
    /// Solves attempted by the Monte-Carlo run (successful ones plus solver
    /// errors).
    pub solves: usize,
    /// Wall-clock seconds of the Monte-Carlo runs.
    pub seconds: f64,
    /// Wall-clock seconds of the image check (None when it did not run).
    pub image_seconds: Option<f64>,
    /// Worker threads.
    pub threads: usize,
    /// The estimate logged before the run (None when not asked for).
    pub estimate: Option<RunEstimate>,
}

impl ValidateOutcome {
    /// The run in one line: solves, time, threads and where the report is.
    pub fn timing_line(&self, out_dir: &std::path::Path) -> String {
        let images = self
            .image_seconds
            .map_or(String::new(), |s| format!(", image check {s:.1} s"));
        format!(
            "{} solves in {:.1} s on {} threads ({:.0} solves/s){images}; report in {}",
            self.solves,
            self.seconds,
            self.threads,
            self.solves as f64 / self.seconds.max(1e-9),
            out_dir.display()
        )
    }
}

/// The context every phase after the analysis works on.
pub struct Run<'a, O: Observer> {
    config: &'a WorkflowConfig,
    validate: Checked<'a>,
    observer: &'a mut O,
    summary: ValidateSummary,
    seconds: f64,
    image_seconds: Option<f64>,
}

/// One step of a run, after the analysis.
type Phase<O> = fn(&mut Run<'_, O>) -> Result<(), WorkflowError>;

/// Validates [`WorkflowConfig::validate`] and writes its report, with
/// `run.json` (timing, threads, solves, the grid note), into
/// [`WorkflowConfig::out_dir`], holding its lock throughout: the
/// config is checked, the estimate logged, the Monte-Carlo runs done, then
/// the phases [`error_budget`], [`write_report`], [`write_noise_model`] and
/// [`write_run_json`] run over the finished [`Run`]. An observer that asks
/// to stop ends the Monte-Carlo runs within a trial
/// (`MonteCarlo(Interrupted)`), the image check or the error budget
/// (`Budget(Interrupted)`); a stop asked for after the last of them
/// ends the run before the first file ([`WorkflowError::Interrupted`]). An
/// interrupted run writes no report.
pub fn run(
    config: &WorkflowConfig,
    observer: &mut impl Observer,
) -> Result<ValidateOutcome, WorkflowError> {
    let validate = config.validate.check().map_err(ValidateError::from)?;
    config.check().map_err(ValidateError::from)?;
    let _outputs = config.open_outputs()?;
    let estimate = match config.estimate {
        true => Some(estimate(validate, observer)?),
        false => None,
    };
    let started = Instant::now();
    let mut summary = analysis::monte_carlo(validate, observer)?;
    let seconds = started.elapsed().as_secs_f64();
    let mut image_seconds = None;
    if let Some(check) = &config.images {
        let started = Instant::now();
        summary.images = Some(
            image_check::run(validate, check, &summary.outcomes, observer)
                .map_err(ValidateError::from)?,
        );
        image_seconds = Some(started.elapsed().as_secs_f64());
    }
    let mut run = Run {
        config,
        validate,
        observer,
        summary,
        seconds,
        image_seconds,
    };
    let phases: [Phase<_>; 5] = [
        error_budget,
        stop_if_asked,
        write_report,
        write_noise_model,
        write_run_json,
    ];
    for phase in phases {
        phase(&mut run)?;
    }
    Ok(ValidateOutcome {
        solves: run.summary.solves(),
        seconds: run.seconds,
        image_seconds: run.image_seconds,
        threads: rayon::current_num_threads(),
        estimate,
        summary: run.summary,
    })
}

/// Times a calibration run and logs the estimate when the run looks slow.
fn estimate(validate: Checked, observer: &mut impl Observer) -> Result<RunEstimate, ValidateError> {
    let estimate = estimate_seconds(validate)?;
    if estimate.seconds >= SLOW_RUN_SECONDS {
        observer.log(&format!(
            "estimate: about {} on {} threads (a timed calibration run of {} scenarios × {} trials took {:.2} s; scaled to {} scenarios × {} trials)",
            duration_text(estimate.seconds),
            rayon::current_num_threads(),
            estimate.calibration_scenarios,
            estimate.calibration_trials,
            estimate.calibration_seconds,
            validate.volume.len(),
            validate.monte_carlo.trials
        ));
    }
    Ok(estimate)
}

/// Ends the run when the observer asked to stop once the last
/// interruptible phase had passed its last poll.
fn stop_if_asked<O: Observer>(run: &mut Run<'_, O>) -> Result<(), WorkflowError> {
    match run.observer.interrupted() {
        true => Err(crate::kernel::Interrupted::nothing_written().into()),
        false => Ok(()),
    }
}

/// The report, from the summary.
fn write_report<O: Observer>(run: &mut Run<'_, O>) -> Result<(), WorkflowError> {
    Ok(report::write(&run.config.out_dir, &run.summary)?)
}

/// The noise law the image check fitted, as a [`CalibrationFile`] written
/// atomically to [`WorkflowConfig::noise_model_out`], when asked for.
fn write_noise_model<O: Observer>(run: &mut Run<'_, O>) -> Result<(), WorkflowError> {
    let Some(path) = &run.config.noise_model_out else {
        return Ok(());
    };
    let refuse = |reason: String| WorkflowError::NoiseModel {
        path: path.clone(),
        reason,
    };
    let Some(images) = &run.summary.images else {
        return Err(refuse("the image check did not run".to_string()));
    };
    let (law, quality, radius_px) = match &images.noise_law {
        NoiseLaw::Fitted {
            law,
            quality,
            radius_px,
        } => (law, quality, radius_px),
        NoiseLaw::Unfitted(reason) => return Err(refuse(reason.clone())),
    };
    let file = CalibrationFile {
        law: LAW.to_string(),
        a: law.a,
        b: law.b,
        c: law.c,
        radius_px: *radius_px,
        fit: *quality,
        centre_error: CentreErrorMeasure::AboutTruth,
        source: format!(
            "{} (seed {}, {} noisy frames per scenario, {})",
            run.validate.command, images.seed, images.check.trials, images.preset
        ),
    };
    crate::files::write_text_atomic(path, &file.to_json()).map_err(|e| refuse(e.to_string()))
}

/// `run.json`: what depends on the machine (timing, threads), kept out of
/// `summary.json`.
fn write_run_json<O: Observer>(run: &mut Run<'_, O>) -> Result<(), WorkflowError> {
    let solves = run.summary.solves();
    let path = run.config.out_dir.join("run.json");
    let json = serde_json::json!({
        "tilt_step_note": run.config.grid_note,
        "wall_seconds": run.seconds,
        "image_seconds": run.image_seconds,
        "threads": rayon::current_num_threads(),
        "solves": solves,
        "solves_per_second": solves as f64 / run.seconds,
    });
    let text = serde_json::to_string_pretty(&json).map_err(|e| ReportError::write(&path, e))?;
    write_text(&path, &(text + "\n"))?;
    Ok(())
}

/// The error budget, when the part or the camera adds to the noise.
fn error_budget<O: Observer>(run: &mut Run<'_, O>) -> Result<(), WorkflowError> {
    let budget = analysis::error_budget(run.validate, run.observer)?;
    analysis::add_budget(&mut run.summary, budget);
    Ok(())
}

/// Scenarios of the timed calibration run behind [`estimate_seconds`].
pub const CALIBRATION_SCENARIOS: usize = 8;
/// Trials per scenario of that run.
pub const CALIBRATION_TRIALS: usize = 4;
/// Shortest calibration run that is trusted, seconds; a shorter one is
/// repeated on more scenarios.
pub const CALIBRATION_MIN_SECONDS: f64 = 0.05;

/// A run-time estimate and where it came from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RunEstimate {
    /// Estimated wall-clock seconds of the full run.
    pub seconds: f64,
    /// Scenarios of the calibration run.
    pub calibration_scenarios: usize,
    /// Trials per scenario of the calibration run.
    pub calibration_trials: usize,
    /// Wall-clock seconds of the calibration run.
    pub calibration_seconds: f64,
}

/// Estimates the wall-clock time of [`analysis::monte_carlo`] from a short timed run of the
/// same solvers on [`CALIBRATION_SCENARIOS`] scenarios spread evenly over
/// the grid (so visible and hidden ones in their proportions) at
/// [`CALIBRATION_TRIALS`] trials (four times the scenarios, again, while
/// the run takes less than [`CALIBRATION_MIN_SECONDS`]), scaled linearly to
/// the whole grid and trial count. The calibration uses its own noise streams' results only
/// for timing; the run's results do not depend on it.
pub fn estimate_seconds(validate: Checked) -> Result<RunEstimate, ValidateError> {
    let (layout, config) = (&validate.layout, &validate.monte_carlo);
    let object = layout.positions();
    let sigmas = layout.point_sigmas();
    let target = Target {
        camera: &validate.camera,
        object: &object,
        sphere_diameter_mm: layout.sphere_diameter_mm,
        point_sigma_px: &sigmas,
    };
    let scenarios = validate.volume.scenarios(&validate.camera);
    let trials = config.trials.min(CALIBRATION_TRIALS);
    let calibration = MonteCarloConfig {
        trials,
        ..config.clone()
    };
    // Start the worker threads before timing anything.
    rayon::broadcast(|_| ());
    let mut wanted = CALIBRATION_SCENARIOS;
    let (sample_len, calibration_seconds) = loop {
        let stride = scenarios.len().div_ceil(wanted).max(1);
        let sample: Vec<Scenario> = scenarios.iter().step_by(stride).copied().collect();
        let started = std::time::Instant::now();
        montecarlo::run(&target, &sample, &calibration, &|_| {})?;
        let seconds = started.elapsed().as_secs_f64();
        // A run too short to time well (fixed costs dominate) is repeated
        // on four times the scenarios, up to the whole grid.
        if seconds >= CALIBRATION_MIN_SECONDS || sample.len() >= scenarios.len() {
            break (sample.len(), seconds);
        }
        wanted *= 4;
    };
    let scale =
        (scenarios.len() as f64 / sample_len as f64) * (config.trials as f64 / trials as f64);
    Ok(RunEstimate {
        seconds: calibration_seconds * scale,
        calibration_scenarios: sample_len,
        calibration_trials: trials,
        calibration_seconds,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::Camera;
    use crate::layout::Layout;
    use crate::observer::Silent;
    use crate::pnp::Solver;
    use crate::scenario::{Range, ScenarioGrid};
    use crate::validate::IdentifiabilityCheck;

    fn config(
        out_dir: PathBuf,
        grid: ScenarioGrid,
        trials: usize,
        solvers: Vec<Solver>,
    ) -> WorkflowConfig {
        let mut validate = ValidateConfig::new(Layout::paper_biprism(), solvers);
        validate.camera = Camera::paper();
        validate.volume = crate::volume::WorkingVolume::Grid(grid);
        validate.monte_carlo.trials = trials;
        validate.monte_carlo.seed = 1;
        validate.identifiability = IdentifiabilityCheck::default();
        validate.command = "test".into();
        WorkflowConfig::new(validate, out_dir)
    }

    #[test]
    fn writes_the_report_and_run_json_where_the_config_says() {
        let dir = tempfile::tempdir().unwrap();
        let grid = ScenarioGrid::new(
            "300,600".parse().unwrap(),
            Range::single(0.0),
            Range::single(0.0),
            "-20,20".parse().unwrap(),
            Range::single(0.0),
            Range::single(0.0),
            Range::single(0.5),
        )
        .unwrap();
        let mut config = config(
            dir.path().join("report"),
            grid,
            5,
            vec![Solver::ParallelWeighted],
        );
        config.estimate = true;
        let outcome = run(&config, &mut Silent).unwrap();
        assert_eq!(outcome.solves, 4 * 5);
        assert!(outcome.estimate.is_some_and(|e| e.seconds >= 0.0));
        assert!(outcome.summary.budget.is_none());
        assert!(outcome.image_seconds.is_none() && outcome.summary.images.is_none());
        assert!(config.out_dir.join("report.md").exists());
        assert!(config.out_dir.join("run.json").exists());
        assert!(!crate::files::lock_path(&config.out_dir).exists());
        config.validate.monte_carlo.gross_threshold_deg = 0.0;
        assert!(matches!(
            run(&config, &mut Silent),
            Err(WorkflowError::Validate(ValidateError::Config(e))) if e.field == "gross_threshold_deg"
        ));
    }

    /// Asks to stop from the start.
    struct Stopped;
    impl Observer for Stopped {
        fn interrupted(&self) -> bool {
            true
        }
    }

    #[test]
    fn a_stop_ends_the_run_without_a_report() {
        let dir = tempfile::tempdir().unwrap();
        // Enough work that the stop, polled every 20 ms, comes first.
        let config = config(
            dir.path().join("report"),
            ScenarioGrid::paper_protocol(2.0),
            200,
            vec![Solver::ParallelWeighted, Solver::Ml],
        );
        // A run that ignored the stop would finish with Ok.
        let result = run(&config, &mut Stopped);
        assert!(
            matches!(
                result,
                Err(WorkflowError::Validate(ValidateError::MonteCarlo(
                    crate::montecarlo::MonteCarloError::Interrupted
                )))
            ),
            "{result:?}"
        );
        assert!(!config.out_dir.exists());
    }

    /// Asks to stop only once the Monte-Carlo phase has reported its last
    /// step: after the last poll of every interruptible phase.
    #[derive(Default)]
    struct LateStop {
        finished: bool,
    }
    impl Observer for LateStop {
        fn progress(&mut self, phase: &str, done: u64, total: u64) {
            self.finished |= phase == crate::validate::analysis::PHASE && done == total;
        }
        fn interrupted(&self) -> bool {
            self.finished
        }
    }

    #[test]
    fn a_stop_after_the_last_poll_still_writes_no_report() {
        let dir = tempfile::tempdir().unwrap();
        let grid = ScenarioGrid::new(
            "300,600".parse().unwrap(),
            Range::single(0.0),
            Range::single(0.0),
            Range::single(0.0),
            Range::single(0.0),
            Range::single(0.0),
            Range::single(0.5),
        )
        .unwrap();
        let config = config(dir.path().join("report"), grid, 3, vec![Solver::Ml]);
        let mut observer = LateStop::default();
        let result = run(&config, &mut observer);
        assert!(observer.finished, "the Monte-Carlo phase never finished");
        let error = result.unwrap_err();
        assert_eq!(error.interrupted(), Some("interrupted: no report written"));
        assert!(!config.out_dir.join("report.md").exists());
        assert!(!config.out_dir.join("run.json").exists());
    }
}
