//! The reproduction's analysis: a checked [`Config`] in, a [`Reproduction`]
//! (every experiment's panels and claims, serialisable) out. No files, no
//! printing.

use super::config::{paper_sigma_px, Config, Experiment, PAPER_SOLVERS};
use super::engine::group;
use super::engine::{Context, Progress, GROSS_ERROR_DEG};
use super::summary::{Header, Reproduction, TrialCount};
use super::ReproduceError;
use super::{depth, noise, off_axis, points, protocol, tilt, timing};
use crate::camera::Camera;
use crate::pnp::Solver;
use std::sync::atomic::AtomicBool;
use std::time::Instant;

/// Runs the experiments of `config`. `on_progress(experiment, done, total)`
/// is called from worker threads as problems finish.
pub fn run(
    config: &Config,
    command: &str,
    on_progress: &(dyn Fn(&str, usize, usize) + Sync),
) -> Result<Reproduction, ReproduceError> {
    run_until(config, command, on_progress, &AtomicBool::new(false))
}

/// [`run`], ended early with [`ReproduceError::Interrupted`] once `stop` is
/// set: trials not yet begun are skipped (the Monte-Carlo experiments read
/// it before each trial, the random-geometry ones before each problem,
/// timing before each repetition), so the run ends within one problem.
pub fn run_until(
    config: &Config,
    command: &str,
    on_progress: &(dyn Fn(&str, usize, usize) + Sync),
    stop: &AtomicBool,
) -> Result<Reproduction, ReproduceError> {
    config.check()?;
    let mut context = Context {
        camera: Camera::paper(),
        seed: config.seed,
        solvers: Solver::ALL.to_vec(),
        progress: Progress::new(on_progress),
        stop,
    };
    let (_, missing) = group(&context, &PAPER_SOLVERS);
    let header = Header {
        command: command.to_string(),
        version: env!("CARGO_PKG_VERSION").to_string(),
        seed: config.seed,
        quick: config.quick,
        trials: config
            .experiments
            .iter()
            .map(|&experiment| TrialCount {
                experiment,
                trials: config.trials_for(experiment),
                paper_trials: experiment.paper_trials(),
                camera: config.camera_for(experiment),
            })
            .collect(),
        solvers: context
            .solvers
            .iter()
            .map(|s| s.name().to_string())
            .collect(),
        paper_solvers_not_available: missing,
        camera_override: config.camera,
        paper_sigma_px: paper_sigma_px(),
        gross_error_deg: GROSS_ERROR_DEG,
    };
    let mut experiments = Vec::new();
    let mut wall_seconds = Vec::new();
    let interrupted = |context: &Context| context.stopped().then_some(ReproduceError::Interrupted);
    for &experiment in &config.experiments {
        if let Some(error) = interrupted(&context) {
            return Err(error);
        }
        context.camera = config.camera_for(experiment);
        let trials = config.trials_for(experiment);
        let started = Instant::now();
        let result = match experiment {
            Experiment::Points => Ok(points::run(&context, trials)),
            Experiment::Noise => Ok(noise::run(&context, trials)),
            Experiment::Timing => Ok(timing::run(&context, trials)),
            Experiment::Depth => Ok(depth::run(&context, trials)),
            Experiment::OffAxis => off_axis::run(&context, trials),
            Experiment::Tilt => tilt::run(&context, trials),
            Experiment::Protocol => protocol::run(&context, trials),
        };
        // A stopped experiment's results are incomplete: never returned.
        if let Some(error) = interrupted(&context) {
            return Err(error);
        }
        let result = result?;
        wall_seconds.push((experiment, started.elapsed().as_secs_f64()));
        experiments.push(result);
    }
    Ok(Reproduction {
        header,
        experiments,
        wall_seconds,
    })
}
