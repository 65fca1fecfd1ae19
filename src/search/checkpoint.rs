//! Checkpoints of a running search, so that `search --resume` continues an
//! interrupted run instead of starting again.
//!
//! * A run's checkpoints live in `<root>/<name>-<hash>/`, where `hash` is a
//!   stable 64-bit FNV-1a hash of the run's *search configuration*: every
//!   setting that changes which layouts are evaluated (family, envelope,
//!   constraints, camera, scenario grid, objective, optimiser, budget, seed,
//!   program version), but not the thread count or output paths. The
//!   configuration itself is stored beside the checkpoints as `config.json`.
//! * `--resume` continues only from the directory of the *same* hash. When
//!   only checkpoints of another configuration of the same name exist, it
//!   fails and lists the settings that differ: a stale checkpoint never
//!   resumes silently. Without `--resume` a run starts afresh and replaces
//!   its own checkpoints.
//! * Each start's optimiser phase (main, polish) is an argmin executor with a
//!   [`StartCheckpoint`]: every [`CHECKPOINT_EVERY`] iterations, but no more
//!   often than every [`CHECKPOINT_INTERVAL`], and once more when the phase
//!   ends, the solver and its state (simplex, swarm or annealing state with
//!   its random generator), the start's best parameters, its perturbation
//!   generator and its evaluation count are written with the crate's atomic
//!   write ([`crate::files::write_atomic`]) as CBOR, which keeps every f64
//!   exactly, infinities included. Because every stream is seeded and
//!   restored, a resumed run reaches the same winner as an uninterrupted
//!   one, and counts the same evaluations.
//! * A finished search removes its checkpoints; an interrupted one keeps
//!   them.

use argmin::core::checkpointing::{Checkpoint, CheckpointingFrequency};
use rand_chacha::ChaCha8Rng;
use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

/// Iterations between checkpoints of an optimiser phase.
pub const CHECKPOINT_EVERY: u64 = 20;
/// Least time between two checkpoints of one phase: each is flushed to disk
/// (about 10 ms on a busy disk), and a stop loses at most this much work.
pub const CHECKPOINT_INTERVAL: std::time::Duration = std::time::Duration::from_secs(1);
/// Version of the checkpoint file format.
const FORMAT_VERSION: u32 = 2;

/// Why checkpoints could not be prepared or read.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum CheckpointError {
    /// `--resume` found only checkpoints of another configuration.
    #[error(
        "not resuming: the checkpoint in {dir} was written by a different search configuration \
         (hash {found}, this run {expected}); differing settings: {differences}. \
         Rerun without --resume to start afresh, or with the original settings to resume it"
    )]
    Stale {
        /// The stale checkpoint directory.
        dir: PathBuf,
        /// This run's hash.
        expected: String,
        /// The checkpoint's hash.
        found: String,
        /// The settings that differ, comma-separated.
        differences: String,
    },
    /// A checkpoint file could not be read or written.
    #[error("checkpoint {path}: {message}")]
    Io {
        /// The file or directory.
        path: PathBuf,
        /// What went wrong.
        message: String,
    },
}

fn io_error(path: &Path, error: impl std::fmt::Display) -> CheckpointError {
    CheckpointError::Io {
        path: path.to_path_buf(),
        message: error.to_string(),
    }
}

/// Stable FNV-1a 64-bit hash of a configuration's canonical JSON text
/// (`serde_json` writes object keys in sorted order), as 16 hex digits.
pub fn config_hash(config: &serde_json::Value) -> String {
    const OFFSET: u64 = 0xcbf2_9ce4_8422_2325;
    const PRIME: u64 = 0x0000_0100_0000_01b3;
    let text = config.to_string();
    let hash = text
        .bytes()
        .fold(OFFSET, |h, b| (h ^ u64::from(b)).wrapping_mul(PRIME));
    format!("{hash:016x}")
}

/// What [`Checkpoints::prepare`] found.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ResumeStatus {
    /// A fresh run (no `--resume`).
    Fresh,
    /// `--resume` found checkpoints of this configuration and continues them.
    Resuming,
    /// `--resume` found nothing to resume; the run starts afresh.
    NothingToResume,
}

/// The checkpoint directory of one search configuration.
#[derive(Debug, Clone)]
pub struct Checkpoints {
    dir: PathBuf,
    hash: String,
}

impl Checkpoints {
    /// Prepares the checkpoints of the search `name` with `config` under
    /// `root`: for `resume`, finds this configuration's directory (or fails
    /// on a stale one); otherwise clears it and writes `config.json`.
    pub fn prepare(
        root: &Path,
        name: &str,
        config: &serde_json::Value,
        resume: bool,
    ) -> Result<(Checkpoints, ResumeStatus), CheckpointError> {
        let hash = config_hash(config);
        let dir = root.join(format!("{name}-{hash}"));
        let checkpoints = Checkpoints {
            dir: dir.clone(),
            hash: hash.clone(),
        };
        if resume {
            if dir.join("config.json").is_file() {
                return Ok((checkpoints, ResumeStatus::Resuming));
            }
            if let Some((stale, found, differences)) = find_stale(root, name, config)? {
                return Err(CheckpointError::Stale {
                    dir: stale,
                    expected: hash,
                    found,
                    differences,
                });
            }
        }
        if dir.exists() {
            std::fs::remove_dir_all(&dir).map_err(|e| io_error(&dir, e))?;
        }
        std::fs::create_dir_all(&dir).map_err(|e| io_error(&dir, e))?;
        let text = serde_json::to_string_pretty(config).map_err(|e| io_error(&dir, e))? + "\n";
        write_atomic(&dir.join("config.json"), text.as_bytes())?;
        let status = if resume {
            ResumeStatus::NothingToResume
        } else {
            ResumeStatus::Fresh
        };
        Ok((checkpoints, status))
    }

    /// The directory.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// The configuration hash.
    pub fn hash(&self) -> &str {
        &self.hash
    }

    /// The checkpoint file of `start`'s `phase` ("main" or "polish").
    pub fn file(&self, start: usize, phase: &str) -> PathBuf {
        self.dir.join(format!("start-{start}-{phase}.cbor"))
    }

    /// Removes the checkpoints (after a finished search).
    pub fn remove(&self) -> Result<(), CheckpointError> {
        match std::fs::remove_dir_all(&self.dir) {
            Ok(()) => Ok(()),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(()),
            Err(e) => Err(io_error(&self.dir, e)),
        }
    }
}

/// A checkpoint directory of the same name but another configuration, with
/// its hash and the top-level settings that differ.
fn find_stale(
    root: &Path,
    name: &str,
    config: &serde_json::Value,
) -> Result<Option<(PathBuf, String, String)>, CheckpointError> {
    let Ok(entries) = std::fs::read_dir(root) else {
        return Ok(None);
    };
    let prefix = format!("{name}-");
    let mut candidates: Vec<PathBuf> = entries
        .filter_map(Result::ok)
        .map(|e| e.path())
        .filter(|p| {
            p.file_name()
                .and_then(|n| n.to_str())
                .and_then(|n| n.strip_prefix(&prefix))
                .is_some_and(|hash| hash.len() == 16 && hash.chars().all(|c| c.is_ascii_hexdigit()))
                && p.join("config.json").is_file()
        })
        .collect();
    candidates.sort();
    let Some(dir) = candidates.into_iter().next() else {
        return Ok(None);
    };
    let path = dir.join("config.json");
    let text = std::fs::read_to_string(&path).map_err(|e| io_error(&path, e))?;
    let old: serde_json::Value = serde_json::from_str(&text).map_err(|e| io_error(&path, e))?;
    let found = config_hash(&old);
    let mut differences = Vec::new();
    if let (Some(new), Some(old)) = (config.as_object(), old.as_object()) {
        for key in new
            .keys()
            .chain(old.keys().filter(|k| !new.contains_key(*k)))
        {
            if new.get(key) != old.get(key) {
                differences.push(key.clone());
            }
        }
    }
    differences.dedup();
    Ok(Some((dir, found, differences.join(", "))))
}

/// Writes `bytes` to `path` with the crate's one atomic write
/// ([`crate::files::write_atomic`]).
fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), CheckpointError> {
    crate::files::write_atomic(path, bytes).map_err(|e| io_error(path, e))
}

/// Start-level state that lives outside argmin's solver and state: the
/// start's best parameters and its annealing perturbation generator.
#[derive(Debug)]
pub struct StartState {
    /// Parameters of the start's best candidate so far.
    pub best_params: Option<Vec<f64>>,
    /// The generator of annealing's perturbations.
    pub anneal_rng: ChaCha8Rng,
    /// Objective evaluations of the start so far, those of earlier runs
    /// restored from its checkpoints included.
    pub evaluations: u64,
}

#[derive(Serialize)]
struct FileOut<'a, S, I> {
    version: u32,
    solver: &'a S,
    state: &'a I,
    best_params: &'a Option<Vec<f64>>,
    anneal_rng: &'a ChaCha8Rng,
    evaluations: u64,
}

/// The executor's part of a checkpoint file (the start-level fields are
/// read by [`StartCheckpoint::restore_start_state`]).
#[derive(Deserialize)]
struct FileIn<S, I> {
    version: u32,
    solver: S,
    state: I,
}

/// The argmin checkpoint of one start's optimiser phase.
pub struct StartCheckpoint {
    path: PathBuf,
    start_state: Arc<Mutex<StartState>>,
    last_save: Mutex<Option<std::time::Instant>>,
}

impl StartCheckpoint {
    /// A checkpoint at `path` that also saves `start_state`. Its first save
    /// is always written; later ones at most every [`CHECKPOINT_INTERVAL`].
    pub fn new(path: PathBuf, start_state: Arc<Mutex<StartState>>) -> Self {
        Self {
            path,
            start_state,
            last_save: Mutex::new(None),
        }
    }

    /// Restores the start-level state from the file, if there is one, and
    /// says whether there was.
    pub fn restore_start_state(&self) -> Result<bool, CheckpointError> {
        #[derive(Deserialize)]
        struct Extras {
            version: u32,
            best_params: Option<Vec<f64>>,
            anneal_rng: ChaCha8Rng,
            evaluations: u64,
        }
        let Some(bytes) = self.read()? else {
            return Ok(false);
        };
        let extras: Extras =
            ciborium::from_reader(bytes.as_slice()).map_err(|e| io_error(&self.path, e))?;
        self.check_version(extras.version)?;
        let mut state = self
            .start_state
            .lock()
            .expect("no panics while holding the lock");
        state.best_params = extras.best_params;
        state.anneal_rng = extras.anneal_rng;
        state.evaluations = extras.evaluations;
        Ok(true)
    }

    fn read(&self) -> Result<Option<Vec<u8>>, CheckpointError> {
        match std::fs::read(&self.path) {
            Ok(bytes) => Ok(Some(bytes)),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
            Err(e) => Err(io_error(&self.path, e)),
        }
    }

    fn check_version(&self, version: u32) -> Result<(), CheckpointError> {
        if version == FORMAT_VERSION {
            Ok(())
        } else {
            Err(io_error(
                &self.path,
                format!("format version {version}, expected {FORMAT_VERSION}"),
            ))
        }
    }
}

impl<S, I> Checkpoint<S, I> for StartCheckpoint
where
    S: Serialize + DeserializeOwned,
    I: Serialize + DeserializeOwned,
{
    fn save(&self, solver: &S, state: &I) -> Result<(), argmin::core::Error> {
        {
            let mut last_save = self
                .last_save
                .lock()
                .expect("no panics while holding the lock");
            if last_save.is_some_and(|t| t.elapsed() < CHECKPOINT_INTERVAL) {
                return Ok(());
            }
            *last_save = Some(std::time::Instant::now());
        }
        let start_state = self
            .start_state
            .lock()
            .expect("no panics while holding the lock");
        let mut bytes = Vec::new();
        ciborium::into_writer(
            &FileOut {
                version: FORMAT_VERSION,
                solver,
                state,
                best_params: &start_state.best_params,
                anneal_rng: &start_state.anneal_rng,
                evaluations: start_state.evaluations,
            },
            &mut bytes,
        )?;
        write_atomic(&self.path, &bytes)?;
        Ok(())
    }

    fn load(&self) -> Result<Option<(S, I)>, argmin::core::Error> {
        let Some(bytes) = self.read()? else {
            return Ok(None);
        };
        let file: FileIn<S, I> = ciborium::from_reader(bytes.as_slice())?;
        self.check_version(file.version)?;
        Ok(Some((file.solver, file.state)))
    }

    fn frequency(&self) -> CheckpointingFrequency {
        CheckpointingFrequency::Every(CHECKPOINT_EVERY)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_hash_is_stable_and_sensitive() {
        let a = serde_json::json!({"seed": 7, "family": "biprism"});
        let b = serde_json::json!({"family": "biprism", "seed": 7});
        let c = serde_json::json!({"seed": 8, "family": "biprism"});
        assert_eq!(config_hash(&a), config_hash(&b));
        assert_ne!(config_hash(&a), config_hash(&c));
        // Pinned: the hash must not change between builds or platforms.
        assert_eq!(config_hash(&serde_json::json!({})), "08f44b07b5901a25");
    }

    #[test]
    fn resume_refuses_a_stale_configuration_and_names_what_changed() {
        let root = std::env::temp_dir().join(format!("lo-ckpt-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&root);
        let old = serde_json::json!({"seed": 7, "iterations": 100, "family": "biprism"});
        let (first, status) = Checkpoints::prepare(&root, "run", &old, false).unwrap();
        assert_eq!(status, ResumeStatus::Fresh);
        let (again, status) = Checkpoints::prepare(&root, "run", &old, true).unwrap();
        assert_eq!(status, ResumeStatus::Resuming);
        assert_eq!(again.dir(), first.dir());
        let new = serde_json::json!({"seed": 8, "iterations": 100, "family": "biprism"});
        let error = Checkpoints::prepare(&root, "run", &new, true).unwrap_err();
        let message = error.to_string();
        assert!(message.contains("differing settings: seed"), "{message}");
        assert!(message.contains(first.hash()), "{message}");
        let (_, status) = Checkpoints::prepare(&root, "other", &new, true).unwrap();
        assert_eq!(status, ResumeStatus::NothingToResume);
        first.remove().unwrap();
        assert!(!first.dir().exists());
        let _ = std::fs::remove_dir_all(&root);
    }
}
