//! One run's outputs, as a set: declared with the run's inputs before any
//! work, checked, locked, staged and committed together.
//!
//! * [`OutputPlan`] names every input the run reads and every output it
//!   may write (a file, a directory the run writes files into, or a file
//!   expected inside such a directory), each with the flag or argument that
//!   gave it, for the error messages.
//! * [`OutputPlan::open`] refuses, before any work, an output that is one
//!   of the inputs or another output (compared as the files they resolve
//!   to, so `a/../b.json` is `b.json`), an output file that is a directory
//!   and an output directory that is a file; then it takes the lock of
//!   every output ([`OutputLock`]), so that a second run on the same
//!   outputs is refused at once, and removes the temporaries a killed run
//!   left for them.
//! * [`Outputs::stage`] writes a file's bytes to a temporary beside it;
//!   [`Outputs::commit`] renames every staged file into place, and when a
//!   rename fails part-way, puts back what the earlier renames replaced.
//!   Outputs dropped before the commit remove what they staged: a run that
//!   fails or is interrupted leaves every output as it was.

use crate::files::{
    directory_of, remove_stale_temporaries, sync_directory, write_temporary, LockError, OutputLock,
};
use std::path::{Component, Path, PathBuf};
use std::sync::Mutex;

/// Why a run's outputs cannot be opened, staged or committed.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum OutputError {
    /// An output resolves to an input or to another output.
    #[error("{what} {} is also {other}; give it another path (nothing was written)", path.display())]
    Clash {
        /// The flag or argument of the output.
        what: String,
        /// The path as given.
        path: PathBuf,
        /// The input or output it collides with, in words.
        other: String,
    },
    /// An output file names a directory.
    #[error("{what} {} is a directory; give the path of a file", path.display())]
    IsADirectory {
        /// The flag or argument.
        what: String,
        /// The path.
        path: PathBuf,
    },
    /// An output directory, or the directory of an output file, is a file.
    #[error("{what} {}: {} is a file, not a directory", path.display(), file.display())]
    NotADirectory {
        /// The flag or argument.
        what: String,
        /// The output's path.
        path: PathBuf,
        /// The file that stands where a directory must be.
        file: PathBuf,
    },
    /// Another run holds an output.
    #[error(transparent)]
    Lock(#[from] LockError),
    /// A file could not be written or moved into place.
    #[error("cannot write {}: {source}", path.display())]
    Write {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// A file was staged that the plan did not declare (a bug of the
    /// calling workflow, refused rather than written).
    #[error("{} is not one of this run's declared outputs", path.display())]
    Undeclared {
        /// The file.
        path: PathBuf,
    },
}

/// What an output is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    /// A file, locked on its own.
    File,
    /// A directory the run writes files into, locked as a whole.
    Dir,
    /// A file inside a declared directory: checked against the inputs and
    /// the other outputs, covered by its directory's lock.
    InDir,
    /// A file the run writes as it goes (a stream's lines), not staged:
    /// checked and locked like a file, opened by [`Outputs::open_stream`].
    Stream,
}

#[derive(Debug, Clone)]
struct Entry {
    what: String,
    path: PathBuf,
    kind: Kind,
}

/// The inputs and outputs of a run, before it starts.
#[derive(Debug, Clone, Default)]
pub struct OutputPlan {
    inputs: Vec<(String, PathBuf)>,
    outputs: Vec<Entry>,
}

impl OutputPlan {
    /// An empty plan.
    pub fn new() -> Self {
        Self::default()
    }

    /// The run reads `path` (`what`: its flag or argument).
    pub fn input(&mut self, what: impl Into<String>, path: impl AsRef<Path>) -> &mut Self {
        self.inputs.push((what.into(), path.as_ref().to_path_buf()));
        self
    }

    /// The run reads every path of `paths`, each given by `what`.
    pub fn inputs<P: AsRef<Path>>(
        &mut self,
        what: &str,
        paths: impl IntoIterator<Item = P>,
    ) -> &mut Self {
        for path in paths {
            self.input(what, path);
        }
        self
    }

    /// The run may write the file `path`.
    pub fn file(&mut self, what: impl Into<String>, path: impl AsRef<Path>) -> &mut Self {
        self.output(what, path, Kind::File)
    }

    /// The run may write files into the directory `path` (created if
    /// missing when the plan is opened).
    pub fn dir(&mut self, what: impl Into<String>, path: impl AsRef<Path>) -> &mut Self {
        self.output(what, path, Kind::Dir)
    }

    /// The run will write `path` inside a directory declared with
    /// [`OutputPlan::dir`]: checked like a file before the run, locked with
    /// its directory.
    pub fn file_in_dir(&mut self, what: impl Into<String>, path: impl AsRef<Path>) -> &mut Self {
        self.output(what, path, Kind::InDir)
    }

    /// The run writes the file `path` as it goes, every line kept when it
    /// stops ([`Outputs::open_stream`]): checked and locked like a file,
    /// never staged.
    pub fn stream(&mut self, what: impl Into<String>, path: impl AsRef<Path>) -> &mut Self {
        self.output(what, path, Kind::Stream)
    }

    fn output(&mut self, what: impl Into<String>, path: impl AsRef<Path>, kind: Kind) -> &mut Self {
        self.outputs.push(Entry {
            what: what.into(),
            path: path.as_ref().to_path_buf(),
            kind,
        });
        self
    }

    /// Checks the plan and takes its locks (module docs). Nothing is
    /// written but the lock files and the output directories.
    pub fn open(self) -> Result<Outputs, OutputError> {
        for entry in &self.outputs {
            check_kind(entry)?;
        }
        let inputs: Vec<(String, PathBuf)> = self
            .inputs
            .iter()
            .map(|(what, path)| (what.clone(), resolved(path)))
            .collect();
        let outputs: Vec<PathBuf> = self.outputs.iter().map(|e| resolved(&e.path)).collect();
        for (k, entry) in self.outputs.iter().enumerate() {
            if let Some((what, _)) = inputs.iter().find(|(_, p)| *p == outputs[k]) {
                return Err(clash(entry, format!("the input {what}")));
            }
            if let Some(j) = (0..k).find(|&j| outputs[j] == outputs[k]) {
                let other = format!("the output of {}", self.outputs[j].what);
                return Err(clash(entry, other));
            }
        }
        // Built up as it goes, so that a refusal part-way (a lock another
        // run holds) drops what was taken and made so far.
        let entries = self.outputs.clone();
        let mut opened = Outputs {
            plan: self,
            resolved_inputs: inputs,
            staged: Mutex::new(Vec::new()),
            made_dirs: Vec::new(),
            committed: false,
            locks: Vec::new(),
        };
        for entry in &entries {
            if entry.kind == Kind::Dir {
                let missing: Vec<PathBuf> = entry
                    .path
                    .ancestors()
                    .take_while(|d| !d.as_os_str().is_empty() && !d.exists())
                    .map(Path::to_path_buf)
                    .collect();
                std::fs::create_dir_all(&entry.path).map_err(write_error(&entry.path))?;
                opened.made_dirs.extend(missing);
            }
            // A lock this process holds already (a run inside a run, such
            // as a search exporting its winner) covers the output.
            if entry.kind != Kind::InDir && !OutputLock::held_here(&entry.path) {
                opened.locks.push(OutputLock::acquire(&entry.path)?);
                if entry.kind == Kind::Dir {
                    // Ours now: what a killed run left in it goes.
                    remove_stale_in(&entry.path).map_err(write_error(&entry.path))?;
                }
            }
            if entry.kind != Kind::Dir {
                remove_stale_temporaries(&entry.path).map_err(write_error(&entry.path))?;
            }
        }
        Ok(opened)
    }
}

/// Removes from `dir`, whose lock the caller has just taken, what killed
/// runs left there: hidden temporaries (`.<name>.<pid>.<n>.tmp`) and
/// hidden scratch or staging directories (`.<…>.<pid>.<n>.tmp`, as
/// [`Scratch`] and earlier versions' render and export staging named
/// them). Nothing else is touched.
fn remove_stale_in(dir: &Path) -> std::io::Result<()> {
    crate::files::remove_stale_temporaries_in(dir)?;
    for entry in std::fs::read_dir(dir)? {
        let entry = entry?;
        let name = entry.file_name();
        let name = name.to_string_lossy();
        let Some(stem) = name
            .strip_prefix('.')
            .and_then(|rest| rest.strip_suffix(".tmp"))
        else {
            continue;
        };
        let mut parts = stem.rsplit('.');
        let numbered = parts
            .next()
            .zip(parts.next())
            .is_some_and(|(n, pid)| is_number(n) && is_number(pid));
        if numbered && entry.file_type()?.is_dir() {
            std::fs::remove_dir_all(entry.path())?;
        }
    }
    Ok(())
}

fn is_number(text: &str) -> bool {
    !text.is_empty() && text.bytes().all(|b| b.is_ascii_digit())
}

fn clash(entry: &Entry, other: String) -> OutputError {
    OutputError::Clash {
        what: entry.what.clone(),
        path: entry.path.clone(),
        other,
    }
}

fn write_error(path: &Path) -> impl FnOnce(std::io::Error) -> OutputError + '_ {
    move |source| OutputError::Write {
        path: path.to_path_buf(),
        source,
    }
}

/// An output file must not be a directory, and no file may stand where an
/// output's directory must be.
fn check_kind(entry: &Entry) -> Result<(), OutputError> {
    let path = &entry.path;
    if entry.kind != Kind::Dir && path.is_dir() {
        return Err(OutputError::IsADirectory {
            what: entry.what.clone(),
            path: path.clone(),
        });
    }
    let first_dir = match entry.kind {
        Kind::Dir => path.clone(),
        Kind::File | Kind::InDir | Kind::Stream => directory_of(path),
    };
    let mut dir = Some(first_dir.as_path());
    while let Some(d) = dir.filter(|d| !d.as_os_str().is_empty()) {
        if d.exists() {
            if !d.is_dir() {
                return Err(OutputError::NotADirectory {
                    what: entry.what.clone(),
                    path: path.clone(),
                    file: d.to_path_buf(),
                });
            }
            break;
        }
        dir = d.parent();
    }
    Ok(())
}

/// The file `path` names: its nearest existing ancestor resolved (links
/// followed), the rest appended with `.` and `..` taken lexically.
fn resolved(path: &Path) -> PathBuf {
    let absolute = if path.is_absolute() {
        path.to_path_buf()
    } else {
        std::env::current_dir().unwrap_or_default().join(path)
    };
    let mut normal = PathBuf::new();
    for component in absolute.components() {
        match component {
            Component::CurDir => {}
            Component::ParentDir => {
                normal.pop();
            }
            other => normal.push(other),
        }
    }
    let mut base = normal.as_path();
    let mut rest = Vec::new();
    loop {
        if let Ok(real) = base.canonicalize() {
            let mut out = real;
            for part in rest.iter().rev() {
                out.push(part);
            }
            return out;
        }
        match (base.parent(), base.file_name()) {
            (Some(parent), Some(name)) => {
                rest.push(name.to_os_string());
                base = parent;
            }
            _ => return normal,
        }
    }
}

/// A file staged: its temporary, the path it was staged for, and that
/// path resolved (compared when the same file is staged again).
#[derive(Debug)]
struct Staged {
    temporary: PathBuf,
    path: PathBuf,
    resolved: PathBuf,
}

/// A run's opened outputs: its locks, and the files staged so far.
#[derive(Debug)]
pub struct Outputs {
    plan: OutputPlan,
    /// Each input with the argument that named it, resolved.
    resolved_inputs: Vec<(String, PathBuf)>,
    /// Every file staged.
    staged: Mutex<Vec<Staged>>,
    /// Directories the plan created, deepest first: removed again (when
    /// still empty) if the run ends without its commit.
    made_dirs: Vec<PathBuf>,
    committed: bool,
    locks: Vec<OutputLock>,
}

impl Outputs {
    /// Writes `bytes` for `path` to a temporary beside it; `path` must be a
    /// declared output file or lie directly in a declared directory, and
    /// must not be an input. Nothing replaces `path` before
    /// [`Outputs::commit`]. Threads may stage at once; staging a file again
    /// replaces what was staged for it.
    pub fn stage(&self, path: &Path, bytes: &[u8]) -> Result<(), OutputError> {
        let target = self.stageable(path)?;
        let temporary = write_temporary(path, bytes).map_err(write_error(path))?;
        self.record(temporary, path, &target);
        Ok(())
    }

    /// Stages `written`, a file a writer made (in a [`Scratch`] directory
    /// on the same file system), as `path`: as [`Outputs::stage`], moving
    /// the file rather than copying its bytes.
    pub fn stage_written(&self, written: &Path, path: &Path) -> Result<(), OutputError> {
        let target = self.stageable(path)?;
        // A fresh temporary name beside the target, then the file over it.
        let temporary = write_temporary(path, b"").map_err(write_error(path))?;
        if let Err(source) = std::fs::rename(written, &temporary) {
            let _ = std::fs::remove_file(&temporary);
            return Err(OutputError::Write {
                path: path.to_path_buf(),
                source,
            });
        }
        self.record(temporary, path, &target);
        Ok(())
    }

    /// The file `path` names, once it is known to be a declared output and
    /// not an input.
    fn stageable(&self, path: &Path) -> Result<PathBuf, OutputError> {
        let entry = self
            .plan
            .outputs
            .iter()
            .find(|e| match e.kind {
                Kind::File | Kind::InDir => e.path == path,
                Kind::Dir => directory_of(path) == e.path,
                Kind::Stream => false,
            })
            .ok_or_else(|| OutputError::Undeclared {
                path: path.to_path_buf(),
            })?;
        let target = resolved(path);
        if let Some((what, _)) = self.resolved_inputs.iter().find(|(_, p)| *p == target) {
            let entry = Entry {
                path: path.to_path_buf(),
                ..entry.clone()
            };
            return Err(clash(&entry, format!("the input {what}")));
        }
        Ok(target)
    }

    /// Records `temporary` as what `path` becomes at the commit, in place
    /// of anything staged for it before.
    fn record(&self, temporary: PathBuf, path: &Path, target: &Path) {
        let mut staged = self.staged.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(k) = staged.iter().position(|s| s.resolved == target) {
            let _ = std::fs::remove_file(staged.remove(k).temporary);
        }
        staged.push(Staged {
            temporary,
            path: path.to_path_buf(),
            resolved: target.to_path_buf(),
        });
    }

    /// Creates (or empties) `path`, declared with [`OutputPlan::stream`],
    /// for the run to write as it goes. What is written stays when the run
    /// fails or stops: a stream's file is not staged.
    pub fn open_stream(&self, path: &Path) -> Result<std::fs::File, OutputError> {
        let declared = self
            .plan
            .outputs
            .iter()
            .any(|e| e.kind == Kind::Stream && e.path == path);
        if !declared {
            return Err(OutputError::Undeclared {
                path: path.to_path_buf(),
            });
        }
        std::fs::File::create(path).map_err(write_error(path))
    }

    /// Moves every staged file into place, in the order of their paths.
    /// When a move fails, the files already moved are taken back (each
    /// replaced file restored) and the error names the file that failed.
    pub fn commit(mut self) -> Result<(), OutputError> {
        let mut staged = std::mem::take(self.staged.get_mut().unwrap_or_else(|e| e.into_inner()));
        staged.sort_by(|a, b| a.path.cmp(&b.path));
        let mut done: Vec<(PathBuf, Option<PathBuf>)> = Vec::new();
        let mut failure = None;
        for (k, file) in staged.iter().enumerate() {
            match move_into_place(&file.temporary, &file.path) {
                Ok(backup) => done.push((file.path.clone(), backup)),
                Err(source) => {
                    failure = Some((k, file.path.clone(), source));
                    break;
                }
            }
        }
        match failure {
            None => {
                self.committed = true;
                for (target, backup) in &done {
                    if let Some(backup) = backup {
                        let _ = std::fs::remove_file(backup);
                    }
                    sync_directory(&directory_of(target));
                }
                Ok(())
            }
            Some((k, path, source)) => {
                for (target, backup) in done.iter().rev() {
                    match backup {
                        Some(backup) => {
                            let _ = std::fs::rename(backup, target);
                        }
                        None => {
                            let _ = std::fs::remove_file(target);
                        }
                    }
                }
                for file in &staged[k..] {
                    let _ = std::fs::remove_file(&file.temporary);
                }
                Err(OutputError::Write { path, source })
            }
        }
    }
}

/// Renames `temporary` over `target`, first moving an existing `target`
/// aside (to a temporary name of its own); returns where it went.
fn move_into_place(temporary: &Path, target: &Path) -> std::io::Result<Option<PathBuf>> {
    let backup = if target.exists() {
        let backup = write_temporary(target, b"")?;
        if let Err(e) = std::fs::rename(target, &backup) {
            let _ = std::fs::remove_file(&backup);
            return Err(e);
        }
        Some(backup)
    } else {
        None
    };
    match std::fs::rename(temporary, target) {
        Ok(()) => Ok(backup),
        Err(e) => {
            if let Some(backup) = &backup {
                let _ = std::fs::rename(backup, target);
            }
            Err(e)
        }
    }
}

impl Drop for Outputs {
    fn drop(&mut self) {
        let staged = self.staged.get_mut().unwrap_or_else(|e| e.into_inner());
        for file in staged.iter() {
            let _ = std::fs::remove_file(&file.temporary);
        }
        if !self.committed {
            // The locks first: a directory's lock file lies beside it.
            self.locks.clear();
            for dir in &self.made_dirs {
                let _ = std::fs::remove_dir(dir);
            }
        }
    }
}

/// A private directory inside an output directory, for writers that make
/// their files themselves ([`Outputs::stage_written`] moves them out);
/// removed with whatever is left in it when dropped.
#[derive(Debug)]
pub struct Scratch {
    dir: PathBuf,
}

impl Scratch {
    /// A new scratch directory in `dir` (`.scratch.<pid>.<n>.tmp`).
    pub fn new(dir: &Path) -> Result<Scratch, OutputError> {
        static NEXT: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
        let n = NEXT.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let scratch = dir.join(format!(".scratch.{}.{n}.tmp", std::process::id()));
        std::fs::create_dir_all(&scratch).map_err(write_error(&scratch))?;
        Ok(Scratch { dir: scratch })
    }

    /// The directory.
    pub fn path(&self) -> &Path {
        &self.dir
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn names(dir: &Path) -> Vec<String> {
        let mut names: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        names
    }

    #[test]
    fn an_output_that_is_an_input_is_refused_however_it_is_spelt() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::create_dir(dir.path().join("frames")).unwrap();
        let frame = dir.path().join("frames/a.png");
        std::fs::write(&frame, "png").unwrap();
        let mut plan = OutputPlan::new();
        plan.input("IMAGES", &frame)
            .file("--output", dir.path().join("frames/../frames/./a.png"));
        let error = plan.open().unwrap_err();
        assert!(matches!(error, OutputError::Clash { .. }), "{error}");
        assert!(error.to_string().contains("--output"), "{error}");
        assert!(error.to_string().contains("IMAGES"), "{error}");
        assert_eq!(std::fs::read_to_string(&frame).unwrap(), "png");
        assert_eq!(names(&dir.path().join("frames")), ["a.png"]);
    }

    #[test]
    fn two_outputs_of_one_file_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let mut plan = OutputPlan::new();
        plan.file("--output", dir.path().join("x"))
            .file("--csv", dir.path().join("x"));
        let error = plan.open().unwrap_err();
        assert!(error.to_string().contains("--csv"), "{error}");
        assert!(error.to_string().contains("--output"), "{error}");
    }

    #[test]
    fn a_file_where_a_directory_must_be_and_a_directory_as_a_file_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("f");
        std::fs::write(&file, "x").unwrap();
        let mut plan = OutputPlan::new();
        plan.dir("--out", file.join("deeper"));
        assert!(matches!(
            plan.open().unwrap_err(),
            OutputError::NotADirectory { .. }
        ));
        let mut plan = OutputPlan::new();
        plan.file("--output", dir.path());
        assert!(matches!(
            plan.open().unwrap_err(),
            OutputError::IsADirectory { .. }
        ));
    }

    /// Open outputs hold their locks (another process is refused them:
    /// tests/it/run_kernel.rs); a run inside a run of the same process,
    /// such as a search exporting its winner into the directory it locked,
    /// is covered by the outer lock.
    #[test]
    fn open_outputs_hold_their_locks_until_dropped() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("out.json");
        let mut plan = OutputPlan::new();
        plan.file("--output", &out);
        let first = plan.clone().open().unwrap();
        assert!(OutputLock::held_here(&out));
        assert!(crate::files::lock_path(&out).exists());
        let inner = plan.clone().open().unwrap();
        drop(inner);
        assert!(
            OutputLock::held_here(&out),
            "the inner run took the lock away"
        );
        drop(first);
        assert!(!OutputLock::held_here(&out));
        assert!(!crate::files::lock_path(&out).exists());
        plan.open().unwrap();
    }

    /// A stream's file is checked and locked like a file, written as the
    /// run goes, and kept when the run ends without a commit; it cannot be
    /// staged, and only a declared stream can be opened.
    #[test]
    fn a_stream_is_written_as_it_goes_and_kept_without_a_commit() {
        let dir = tempfile::tempdir().unwrap();
        let layout = dir.path().join("layout.json");
        std::fs::write(&layout, "{}").unwrap();
        let mut plan = OutputPlan::new();
        plan.input("LAYOUT", &layout).stream("--output", &layout);
        assert!(matches!(
            plan.open().unwrap_err(),
            OutputError::Clash { .. }
        ));
        let lines = dir.path().join("lines.jsonl");
        std::fs::write(&lines, "an earlier run's\n").unwrap();
        let mut plan = OutputPlan::new();
        plan.input("LAYOUT", &layout).stream("--output", &lines);
        let outputs = plan.open().unwrap();
        assert!(OutputLock::held_here(&lines));
        let mut file = outputs.open_stream(&lines).unwrap();
        std::io::Write::write_all(&mut file, b"{\"index\":0}\n").unwrap();
        assert!(matches!(
            outputs.stage(&lines, b"x").unwrap_err(),
            OutputError::Undeclared { .. }
        ));
        assert!(matches!(
            outputs.open_stream(&layout).unwrap_err(),
            OutputError::Undeclared { .. }
        ));
        drop(outputs);
        assert_eq!(std::fs::read_to_string(&lines).unwrap(), "{\"index\":0}\n");
        assert!(!OutputLock::held_here(&lines));
    }

    #[test]
    fn staged_files_appear_only_at_the_commit_and_all_together() {
        let dir = tempfile::tempdir().unwrap();
        let (a, b) = (dir.path().join("a.json"), dir.path().join("sub/b.csv"));
        std::fs::write(&a, "old").unwrap();
        let mut plan = OutputPlan::new();
        plan.file("--output", &a)
            .dir("--dir", dir.path().join("sub"));
        let outputs = plan.open().unwrap();
        outputs.stage(&a, b"new").unwrap();
        outputs.stage(&b, b"table").unwrap();
        assert_eq!(std::fs::read_to_string(&a).unwrap(), "old");
        assert!(!b.exists());
        outputs.commit().unwrap();
        assert_eq!(std::fs::read_to_string(&a).unwrap(), "new");
        assert_eq!(std::fs::read_to_string(&b).unwrap(), "table");
        assert_eq!(names(dir.path()), ["a.json", "sub"]);
        assert_eq!(names(&dir.path().join("sub")), ["b.csv"]);
    }

    #[test]
    fn outputs_dropped_before_the_commit_leave_everything_as_it_was() {
        let dir = tempfile::tempdir().unwrap();
        let a = dir.path().join("a.json");
        std::fs::write(&a, "old").unwrap();
        let mut plan = OutputPlan::new();
        plan.file("--output", &a);
        let outputs = plan.open().unwrap();
        outputs.stage(&a, b"new").unwrap();
        drop(outputs);
        assert_eq!(std::fs::read_to_string(&a).unwrap(), "old");
        assert_eq!(names(dir.path()), ["a.json"]);
    }

    #[test]
    fn a_failed_move_puts_back_what_the_earlier_moves_replaced() {
        let dir = tempfile::tempdir().unwrap();
        let (a, b) = (dir.path().join("a.json"), dir.path().join("b.csv"));
        std::fs::write(&a, "old a").unwrap();
        let mut plan = OutputPlan::new();
        plan.file("--output", &a).file("--csv", &b);
        let outputs = plan.open().unwrap();
        outputs.stage(&a, b"new a").unwrap();
        outputs.stage(&b, b"new b").unwrap();
        // A directory now stands where b's file must go: its move fails.
        std::fs::create_dir(&b).unwrap();
        std::fs::write(b.join("keep"), "x").unwrap();
        let error = outputs.commit().unwrap_err();
        assert!(error.to_string().contains("b.csv"), "{error}");
        assert_eq!(std::fs::read_to_string(&a).unwrap(), "old a");
        assert_eq!(names(dir.path()), ["a.json", "b.csv"]);
    }

    #[test]
    fn an_undeclared_file_or_an_input_is_never_staged() {
        let dir = tempfile::tempdir().unwrap();
        let frames = dir.path().join("frames");
        std::fs::create_dir(&frames).unwrap();
        let frame = frames.join("a.png");
        std::fs::write(&frame, "png").unwrap();
        let mut plan = OutputPlan::new();
        plan.input("IMAGES", &frame).dir("--overlay", &frames);
        let outputs = plan.open().unwrap();
        assert!(matches!(
            outputs.stage(&frame, b"x").unwrap_err(),
            OutputError::Clash { .. }
        ));
        assert!(matches!(
            outputs
                .stage(&dir.path().join("elsewhere.png"), b"x")
                .unwrap_err(),
            OutputError::Undeclared { .. }
        ));
        outputs.stage(&frames.join("a.overlay.png"), b"o").unwrap();
        outputs.commit().unwrap();
        assert_eq!(std::fs::read_to_string(&frame).unwrap(), "png");
        assert_eq!(names(&frames), ["a.overlay.png", "a.png"]);
    }

    #[test]
    fn a_directory_the_plan_made_goes_again_with_an_uncommitted_run() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("new/frames");
        let mut plan = OutputPlan::new();
        plan.dir("--out", &out);
        let outputs = plan.clone().open().unwrap();
        outputs.stage(&out.join("a.png"), b"x").unwrap();
        drop(outputs);
        assert_eq!(names(dir.path()), Vec::<String>::new());
        let outputs = plan.open().unwrap();
        outputs.stage(&out.join("a.png"), b"x").unwrap();
        outputs.commit().unwrap();
        assert_eq!(names(&out), ["a.png"]);
    }

    #[test]
    fn a_file_a_writer_made_is_moved_in_at_the_commit() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("part");
        let mut plan = OutputPlan::new();
        plan.dir("--out", &out);
        let outputs = plan.open().unwrap();
        let scratch = Scratch::new(&out).unwrap();
        let written = scratch.path().join("a.stl");
        std::fs::write(&written, "solid").unwrap();
        outputs.stage_written(&written, &out.join("a.stl")).unwrap();
        assert!(!out.join("a.stl").exists());
        drop(scratch);
        outputs.commit().unwrap();
        assert_eq!(names(&out), ["a.stl"]);
        assert_eq!(std::fs::read_to_string(out.join("a.stl")).unwrap(), "solid");
    }

    #[test]
    fn a_killed_runs_scratch_and_staging_directories_go_when_its_directory_opens() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("part");
        for stale in [
            ".scratch.999.0.tmp",
            ".render.999.3.tmp",
            ".a.export.999.1.tmp",
        ] {
            std::fs::create_dir_all(out.join(stale).join("deeper")).unwrap();
        }
        std::fs::write(out.join(".a.stl.999.2.tmp"), "half").unwrap();
        // Not a run's: kept.
        std::fs::create_dir(out.join(".git")).unwrap();
        std::fs::create_dir(out.join(".notes.tmp")).unwrap();
        std::fs::write(out.join("a.stl"), "solid").unwrap();
        let mut plan = OutputPlan::new();
        plan.dir("--out", &out);
        drop(plan.open().unwrap());
        assert_eq!(names(&out), [".git", ".notes.tmp", "a.stl"]);
    }

    #[test]
    fn a_killed_runs_temporaries_are_removed_when_the_outputs_open() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("out.json");
        std::fs::write(dir.path().join(".out.json.999.0.tmp"), "stale").unwrap();
        let mut plan = OutputPlan::new();
        plan.file("--output", &out);
        let outputs = plan.open().unwrap();
        drop(outputs);
        assert_eq!(names(dir.path()), Vec::<String>::new());
    }
}
