//! A reproduction as one call: the experiments, the report and `run.json`,
//! into the directory the configuration names, with progress through an
//! [`Observer`](crate::observer::Observer) (one phase per experiment).
use super::report::write as write_report;
use super::{run_until, Config, ReproduceError, Reproduction};
use crate::kernel::{OutputPlan, Scratch};
use crate::observer::{relay, Observer};
use crate::report::{write_text, ReportError};
use std::path::PathBuf;
use std::sync::atomic::AtomicBool;
use std::sync::Mutex;
use std::time::Instant;

/// Every input and the output directory of a reproduction.
#[derive(Debug, Clone)]
pub struct ReproduceConfig {
    /// Experiments, seed and trials.
    pub experiments: Config,
    /// The command that asked for the run, for the report header.
    pub command: String,
    /// The report directory.
    pub out_dir: PathBuf,
}

/// What a reproduction produced.
#[derive(Debug, Clone)]
pub struct ReproduceOutcome {
    /// Every experiment's panels and claims.
    pub reproduction: Reproduction,
    /// Wall-clock seconds of the experiments.
    pub seconds: f64,
}

/// Runs the experiments and writes the report, with `run.json` (timing
/// per experiment, threads), into [`ReproduceConfig::out_dir`].
///
/// An observer that asks to stop ([`Observer::interrupted`], polled
/// every 20 ms) ends the run within one problem with
/// [`ReproduceError::Interrupted`], and nothing is written. The report is
/// one output set on the run kernel ([`crate::kernel::outputs`]):
/// `out_dir` is checked and locked before the experiments, the files are
/// written into a scratch directory inside it, staged beside their
/// targets and moved into place together, so that `out_dir` never holds a
/// half-written file and a failed write leaves the previous report as it
/// was.
pub fn run(
    config: &ReproduceConfig,
    observer: &mut impl Observer,
) -> Result<ReproduceOutcome, ReproduceError> {
    let mut plan = OutputPlan::new();
    plan.dir("--out", &config.out_dir);
    let outputs = plan.open()?;
    let latest = Mutex::new(None::<(String, u64, u64)>);
    let stop = AtomicBool::new(false);
    let started = Instant::now();
    let reproduction = relay(
        observer,
        |o| {
            let latest = latest.lock().expect("progress lock").clone();
            if let Some((phase, done, total)) = latest {
                o.progress(&phase, done, total);
            }
        },
        Some(&stop),
        || {
            run_until(
                &config.experiments,
                &config.command,
                &|name, done, total| {
                    *latest.lock().expect("progress lock") =
                        Some((name.to_string(), done as u64, total as u64));
                },
                &stop,
            )
        },
    )?;
    let seconds = started.elapsed().as_secs_f64();
    let scratch = Scratch::new(&config.out_dir)?;
    let dir = scratch.path();
    write_report(dir, &reproduction)?;
    let run = serde_json::json!({
        "wall_seconds": seconds,
        "threads": rayon::current_num_threads(),
        "experiments": reproduction
            .wall_seconds
            .iter()
            .map(|(e, s)| serde_json::json!({"experiment": e.name(), "wall_seconds": s}))
            .collect::<Vec<_>>(),
    });
    let path = dir.join("run.json");
    let text = serde_json::to_string_pretty(&run).map_err(|e| ReportError::write(&path, e))?;
    write_text(&path, &(text + "\n"))?;
    let written = std::fs::read_dir(dir).map_err(|e| ReportError::write(dir, e))?;
    for entry in written {
        let entry = entry.map_err(|e| ReportError::write(dir, e))?;
        outputs.stage_written(&entry.path(), &config.out_dir.join(entry.file_name()))?;
    }
    drop(scratch);
    outputs.commit()?;
    Ok(ReproduceOutcome {
        reproduction,
        seconds,
    })
}
