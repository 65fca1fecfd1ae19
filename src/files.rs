//! How the crate writes files: every layout, report, plot, mesh and
//! checkpoint goes through [`write_atomic`], so that a reader (or a run that
//! is killed half-way) never sees a partial file; and [`OutputLock`] keeps
//! two runs from writing the same outputs at once.
//!
//! * [`write_atomic`] writes to a temporary file with a unique name in the
//!   target's own directory (`.<name>.<pid>.<n>.tmp`, created exclusively),
//!   flushes it to disk, renames it over the target and flushes the
//!   directory, so that the rename itself survives a crash.
//! * A run killed between the write and the rename leaves its temporary
//!   behind; [`remove_stale_temporaries`] removes those of a target once the
//!   caller holds the target's [`OutputLock`] (no one else may be writing it).
//! * [`OutputLock`] holds an exclusive advisory lock (`flock` on Unix) on
//!   `<path>.lock`; the operating system releases it when the process ends,
//!   however it ends, so a crashed run never leaves a lock that blocks the
//!   next one.

use std::ffi::OsString;
use std::fs::{File, OpenOptions};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// Suffix of the temporary files [`write_atomic`] creates.
pub const TEMPORARY_SUFFIX: &str = ".tmp";
/// Suffix of the lock files [`OutputLock`] holds.
pub const LOCK_SUFFIX: &str = ".lock";

/// Distinguishes the temporaries of one process's threads.
static NEXT_TEMPORARY: AtomicU64 = AtomicU64::new(0);
/// The lock files this process holds ([`OutputLock`]).
static HELD: std::sync::Mutex<Vec<PathBuf>> = std::sync::Mutex::new(Vec::new());

/// The directory `path` lives in (`.` for a bare file name).
pub fn directory_of(path: &Path) -> PathBuf {
    match path.parent() {
        Some(dir) if !dir.as_os_str().is_empty() => dir.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

fn file_name_of(path: &Path) -> std::io::Result<OsString> {
    path.file_name().map(|n| n.to_os_string()).ok_or_else(|| {
        std::io::Error::new(
            std::io::ErrorKind::InvalidInput,
            format!("{} does not name a file", path.display()),
        )
    })
}

/// The prefix every temporary of `file_name` starts with.
fn temporary_prefix(file_name: &OsString) -> String {
    format!(".{}.", file_name.to_string_lossy())
}

/// Writes `bytes` to `path` atomically: a temporary file with a unique name
/// in the same directory, fsync, rename over `path`, fsync of the directory.
/// The directory must exist. On failure the temporary is removed and `path`
/// is left as it was.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    let temporary = write_temporary(path, bytes)?;
    let result = std::fs::rename(&temporary, path).map(|()| sync_directory(&directory_of(path)));
    if result.is_err() {
        let _ = std::fs::remove_file(&temporary);
    }
    result
}

/// Writes `bytes` to a new temporary file beside `path` (named as
/// [`write_atomic`] names its temporaries, so that
/// [`remove_stale_temporaries`] finds it), flushed to disk, and returns its
/// path; `path` itself is not touched. The caller renames the temporary
/// over `path` or removes it. On failure nothing is left.
pub fn write_temporary(path: &Path, bytes: &[u8]) -> std::io::Result<PathBuf> {
    let dir = directory_of(path);
    let prefix = temporary_prefix(&file_name_of(path)?);
    let (temporary, mut file) = loop {
        let candidate = dir.join(format!(
            "{prefix}{}.{}{TEMPORARY_SUFFIX}",
            std::process::id(),
            NEXT_TEMPORARY.fetch_add(1, Ordering::Relaxed)
        ));
        match OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&candidate)
        {
            Ok(file) => break (candidate, file),
            // Left by a process of the same id long gone: try the next name.
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => continue,
            Err(e) => return Err(e),
        }
    };
    let result = file.write_all(bytes).and_then(|()| file.sync_all());
    drop(file);
    match result {
        Ok(()) => Ok(temporary),
        Err(e) => {
            let _ = std::fs::remove_file(&temporary);
            Err(e)
        }
    }
}

/// Writes `text` atomically, creating its directory first.
pub fn write_text_atomic(path: &Path, text: &str) -> std::io::Result<()> {
    std::fs::create_dir_all(directory_of(path))?;
    write_atomic(path, text.as_bytes())
}

/// Makes a rename in `dir` durable where directories can be synced (not on
/// every platform: an error is ignored).
pub fn sync_directory(dir: &Path) {
    if let Ok(handle) = File::open(dir) {
        let _ = handle.sync_all();
    }
}

/// Removes the temporaries [`write_atomic`] left behind for `path` (by a
/// run that was killed between its write and its rename) and says how many
/// it removed. Call it only while holding `path`'s [`OutputLock`]: a
/// temporary of a run still writing would otherwise vanish under it.
pub fn remove_stale_temporaries(path: &Path) -> std::io::Result<usize> {
    let dir = directory_of(path);
    let prefix = temporary_prefix(&file_name_of(path)?);
    let entries = match std::fs::read_dir(&dir) {
        Ok(entries) => entries,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(0),
        Err(e) => return Err(e),
    };
    let mut removed = 0;
    for entry in entries {
        let entry = entry?;
        let name = entry.file_name();
        let name = name.to_string_lossy();
        if name.starts_with(&prefix) && name.ends_with(TEMPORARY_SUFFIX) {
            let rest = &name[prefix.len()..name.len() - TEMPORARY_SUFFIX.len()];
            // Only `<pid>.<n>`: never a temporary of a longer file name.
            let ours = rest
                .split_once('.')
                .is_some_and(|(pid, n)| is_number(pid) && is_number(n));
            if ours {
                std::fs::remove_file(entry.path())?;
                removed += 1;
            }
        }
    }
    Ok(removed)
}

/// Removes every temporary [`write_atomic`] left in `dir` (a directory the
/// caller owns, such as a locked checkpoint directory).
pub fn remove_stale_temporaries_in(dir: &Path) -> std::io::Result<usize> {
    let entries = match std::fs::read_dir(dir) {
        Ok(entries) => entries,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(0),
        Err(e) => return Err(e),
    };
    let mut removed = 0;
    for entry in entries {
        let entry = entry?;
        let name = entry.file_name();
        let name = name.to_string_lossy();
        if name.starts_with('.') && name.ends_with(TEMPORARY_SUFFIX) && entry.path().is_file() {
            std::fs::remove_file(entry.path())?;
            removed += 1;
        }
    }
    Ok(removed)
}

fn is_number(text: &str) -> bool {
    !text.is_empty() && text.bytes().all(|b| b.is_ascii_digit())
}

/// Why an [`OutputLock`] could not be taken.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum LockError {
    /// Another process holds it.
    #[error(
        "{} is in use by another run (it holds {}); wait for that run to finish, or choose other output paths",
        path.display(),
        lock.display()
    )]
    Busy {
        /// The output path.
        path: PathBuf,
        /// Its lock file.
        lock: PathBuf,
    },
    /// The lock file could not be created (the directory is not writable).
    #[error("cannot write beside {}: {source}", path.display())]
    Io {
        /// The output path.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
}

/// An exclusive lock on an output path, held as `<path>.lock` until dropped;
/// the lock file is removed then.
#[derive(Debug)]
pub struct OutputLock {
    path: PathBuf,
    file: Option<File>,
}

impl OutputLock {
    /// Takes the lock of `path` (a file or a directory, which need not
    /// exist; its parent directory is created), or fails at once when
    /// another process holds it.
    pub fn acquire(path: &Path) -> Result<OutputLock, LockError> {
        let lock = lock_path(path);
        let io = |source| LockError::Io {
            path: path.to_path_buf(),
            source,
        };
        std::fs::create_dir_all(directory_of(&lock)).map_err(io)?;
        loop {
            let file = OpenOptions::new()
                .read(true)
                .write(true)
                .create(true)
                .truncate(false)
                .open(&lock)
                .map_err(io)?;
            match file.try_lock() {
                Ok(()) => {}
                Err(std::fs::TryLockError::WouldBlock) => {
                    return Err(LockError::Busy {
                        path: path.to_path_buf(),
                        lock,
                    })
                }
                Err(std::fs::TryLockError::Error(e)) => return Err(io(e)),
            }
            // The holder before us may have removed the file between our
            // open and our lock: then we hold a lock on a file no one else
            // can find, and must lock the one that is there now.
            if same_file(&file, &lock) {
                let mut file = file;
                let _ = file.set_len(0);
                let _ = writeln!(file, "{}", std::process::id());
                HELD.lock()
                    .unwrap_or_else(|e| e.into_inner())
                    .push(lock.clone());
                return Ok(OutputLock {
                    path: lock,
                    file: Some(file),
                });
            }
        }
    }

    /// The lock file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Whether this process holds the lock of `path` already (a run inside
    /// a run: a search exporting its winner into the directory it locked).
    pub fn held_here(path: &Path) -> bool {
        let lock = lock_path(path);
        HELD.lock()
            .unwrap_or_else(|e| e.into_inner())
            .contains(&lock)
    }
}

impl Drop for OutputLock {
    fn drop(&mut self) {
        // Remove before unlocking, so that whoever locks next locks a file
        // that is still there (see `acquire`).
        let _ = std::fs::remove_file(&self.path);
        let mut held = HELD.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(k) = held.iter().position(|p| *p == self.path) {
            held.swap_remove(k);
        }
        drop(self.file.take());
    }
}

/// `<path>.lock`.
pub fn lock_path(path: &Path) -> PathBuf {
    let mut name = path.as_os_str().to_owned();
    name.push(LOCK_SUFFIX);
    PathBuf::from(name)
}

#[cfg(unix)]
fn same_file(file: &File, path: &Path) -> bool {
    use std::os::unix::fs::MetadataExt;
    match (file.metadata(), std::fs::metadata(path)) {
        (Ok(a), Ok(b)) => a.dev() == b.dev() && a.ino() == b.ino(),
        _ => false,
    }
}

#[cfg(not(unix))]
fn same_file(_file: &File, path: &Path) -> bool {
    path.exists()
}

/// Checks that files can be created in `dir` (creating it if needed) by
/// writing and removing a probe file.
pub fn check_writable_dir(dir: &Path) -> std::io::Result<()> {
    std::fs::create_dir_all(dir)?;
    let probe = dir.join(format!(
        ".layout-opt-probe.{}.{}{TEMPORARY_SUFFIX}",
        std::process::id(),
        NEXT_TEMPORARY.fetch_add(1, Ordering::Relaxed)
    ));
    OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(&probe)?;
    std::fs::remove_file(&probe)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_atomic_write_replaces_the_file_and_leaves_no_temporary() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.json");
        write_atomic(&path, b"one").unwrap();
        write_atomic(&path, b"two").unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"two");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    #[test]
    fn concurrent_writers_of_one_file_never_collide() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("shared.json");
        std::thread::scope(|scope| {
            for k in 0..8u8 {
                let path = &path;
                scope.spawn(move || {
                    for _ in 0..50 {
                        write_atomic(path, &[k; 64]).unwrap();
                    }
                });
            }
        });
        let bytes = std::fs::read(&path).unwrap();
        assert_eq!(bytes.len(), 64);
        assert!(bytes.iter().all(|&b| b == bytes[0]));
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    #[test]
    fn a_failed_write_leaves_the_target_alone() {
        let dir = tempfile::tempdir().unwrap();
        let missing = dir.path().join("no-such-dir/a.json");
        assert!(write_atomic(&missing, b"x").is_err());
        assert!(write_atomic(dir.path(), b"x").is_err());
    }

    #[test]
    fn stale_temporaries_are_removed_and_only_those() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.json");
        for name in [".a.json.123.0.tmp", ".a.json.7.12.tmp"] {
            std::fs::write(dir.path().join(name), "stale").unwrap();
        }
        // Another file's temporary and an unrelated hidden file stay.
        for name in [".a.json.partial.json.5.0.tmp", ".a.json.notes"] {
            std::fs::write(dir.path().join(name), "keep").unwrap();
        }
        assert_eq!(remove_stale_temporaries(&path).unwrap(), 2);
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 2);
        assert_eq!(remove_stale_temporaries_in(dir.path()).unwrap(), 1);
    }

    #[test]
    fn a_lock_is_exclusive_and_released_on_drop() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("sub/out.json");
        let first = OutputLock::acquire(&out).unwrap();
        assert!(first.path().exists());
        // flock locks belong to the open file, so a second open in the same
        // process is refused like another process would be.
        let error = OutputLock::acquire(&out).unwrap_err();
        assert!(matches!(error, LockError::Busy { .. }));
        assert!(
            error.to_string().contains("in use by another run"),
            "{error}"
        );
        drop(first);
        assert!(!lock_path(&out).exists());
        let again = OutputLock::acquire(&out).unwrap();
        drop(again);
    }

    #[test]
    fn writability_is_checked_with_a_probe() {
        let dir = tempfile::tempdir().unwrap();
        check_writable_dir(&dir.path().join("new/deeper")).unwrap();
        assert_eq!(
            std::fs::read_dir(dir.path().join("new/deeper"))
                .unwrap()
                .count(),
            0
        );
        let file = dir.path().join("file");
        std::fs::write(&file, "x").unwrap();
        assert!(check_writable_dir(&file.join("below")).is_err());
    }
}

/// Errors while writing a report.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ReportError {
    /// A file could not be written.
    #[error("cannot write {path}: {message}")]
    Write {
        /// The file.
        path: String,
        /// What went wrong.
        message: String,
    },
}

impl ReportError {
    /// Wraps any displayable error for `path`.
    pub fn write(path: &Path, error: impl std::fmt::Display) -> Self {
        ReportError::Write {
            path: path.display().to_string(),
            message: error.to_string(),
        }
    }
}
