//! A reproduction as one call: the experiments, the report and `run.json`,
//! into the directory the configuration names, with progress through an
//! [`Observer`](crate::observer::Observer) (one phase per experiment).
use super::report::write as write_report;
use super::{run_until, Config, ReproduceError, Reproduction};
use crate::observer::{relay, Observer};
use crate::report::{write_text, ReportError};
use std::path::{Path, PathBuf};
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
/// written as a set: every file first into a staging directory beside
/// `out_dir` (`.<name>.writing-<pid>`), then moved into `out_dir` one
/// rename each, so `out_dir` never holds a half-written file, and a
/// failed write leaves the previous report as it was.
pub fn run(
    config: &ReproduceConfig,
    observer: &mut impl Observer,
) -> Result<ReproduceOutcome, ReproduceError> {
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
    write_as_set(&config.out_dir, |dir| {
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
        Ok(())
    })?;
    Ok(ReproduceOutcome {
        reproduction,
        seconds,
    })
}

/// Runs `write` on a fresh staging directory beside `out_dir`, then
/// moves what it wrote into `out_dir` (one rename per file, replacing
/// files of the same name; other files in `out_dir` stay). The staging
/// directory is removed either way.
fn write_as_set(
    out_dir: &Path,
    write: impl FnOnce(&Path) -> Result<(), ReproduceError>,
) -> Result<(), ReproduceError> {
    let parent = match out_dir.parent() {
        Some(parent) if !parent.as_os_str().is_empty() => parent.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let name = out_dir
        .file_name()
        .map_or_else(|| "report".into(), |n| n.to_string_lossy().into_owned());
    std::fs::create_dir_all(&parent).map_err(|e| ReportError::write(&parent, e))?;
    let staging = parent.join(format!(".{name}.writing-{}", std::process::id()));
    // A killed run of this process id cannot still be writing.
    let _ = std::fs::remove_dir_all(&staging);
    let result = write(&staging).and_then(|()| {
        std::fs::create_dir_all(out_dir).map_err(|e| ReportError::write(out_dir, e))?;
        move_into(&staging, out_dir)
    });
    let _ = std::fs::remove_dir_all(&staging);
    result
}

/// Moves every file under `from` to the same place under `to`.
fn move_into(from: &Path, to: &Path) -> Result<(), ReproduceError> {
    let entries = std::fs::read_dir(from).map_err(|e| ReportError::write(from, e))?;
    for entry in entries {
        let entry = entry.map_err(|e| ReportError::write(from, e))?;
        let target = to.join(entry.file_name());
        if entry.path().is_dir() {
            std::fs::create_dir_all(&target).map_err(|e| ReportError::write(&target, e))?;
            move_into(&entry.path(), &target)?;
        } else {
            std::fs::rename(entry.path(), &target).map_err(|e| ReportError::write(&target, e))?;
        }
    }
    Ok(())
}
