//! The export run: the analysis ([`super::analysis::analyse`]), then every
//! requested format, the fabrication sheet and `<name>-export.json`
//! written as one staged file set ([`export`]), with its progress reported
//! to an [`Observer`] ([`run`]); the files written are in the returned
//! report.
use super::analysis::{analyse, Analysis, ExportReport, WrittenFile};
use super::{gltf, obj, sheet, stl, threemf, write_file};
use super::{ExportError, ExportOptions, Format, MeshWriter};
use crate::kernel::stop::abandon_on_stop;
use crate::layout::Layout;
use crate::observer::Observer;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Progress phase of an export (one step: the part).
pub const PHASE_EXPORT: &str = "export";

/// Everything an export needs.
#[derive(Debug, Clone)]
pub struct ExportConfig {
    /// The layout to build.
    pub layout: Layout,
    /// Formats and the part's design.
    pub options: ExportOptions,
    /// Directory every file goes into.
    pub out_dir: PathBuf,
}

/// Builds and writes the part. An observer that asks to stop gets
/// [`ExportError::Interrupted`]: within 20 ms while the part is built and
/// checked (the build is abandoned: it writes nothing), or between the
/// files, and then none of the export's files are left.
pub fn run(
    config: &ExportConfig,
    observer: &mut impl Observer,
) -> Result<ExportReport, ExportError> {
    observer.progress(PHASE_EXPORT, 0, 1);
    let (layout, options) = (config.layout.clone(), config.options.clone());
    let analysis = abandon_on_stop(observer, move || analyse(&layout, &options))
        .map_err(|_| ExportError::Interrupted)??;
    let observer_ref = &*observer;
    let report = write_analysis(analysis, &config.options, &config.out_dir, &|| {
        observer_ref.interrupted()
    })?;
    observer.progress(PHASE_EXPORT, 1, 1);
    Ok(report)
}

/// The writer of `format`.
pub fn writer(format: Format) -> &'static dyn MeshWriter {
    match format {
        Format::Stl => &stl::StlWriter,
        Format::Obj => &obj::ObjWriter,
        Format::Gltf => &gltf::GltfWriter { binary: false },
        Format::Glb => &gltf::GltfWriter { binary: true },
        Format::ThreeMf => &threemf::ThreeMfWriter,
    }
}

/// Builds the marker for `layout` and writes every requested format, the
/// fabrication sheet (`<name>-fabrication.md`, `.csv`, `<name>-views.svg`)
/// and this report as `<name>-export.json` into `out_dir` (created if
/// missing), as a set: every file is first written into a staging
/// directory inside `out_dir` and then renamed into place, so that a
/// failure part-way leaves none of the new files (see [`FileSet`]).
pub fn export(
    layout: &Layout,
    options: &ExportOptions,
    out_dir: &Path,
) -> Result<ExportReport, ExportError> {
    export_observed(layout, options, out_dir, &|| false)
}

/// [`export`], asking `interrupted` between the steps: once it says yes,
/// the export stops with [`ExportError::Interrupted`] and leaves none of
/// its files.
fn export_observed(
    layout: &Layout,
    options: &ExportOptions,
    out_dir: &Path,
    interrupted: &dyn Fn() -> bool,
) -> Result<ExportReport, ExportError> {
    let analysis = analyse(layout, options)?;
    if interrupted() {
        return Err(ExportError::Interrupted);
    }
    write_analysis(analysis, options, out_dir, interrupted)
}

/// Writes an analysed part's files into `out_dir` as one staged file set,
/// as [`export`] does; `interrupted` is asked between the files.
pub fn write_analysis(
    analysis: Analysis,
    options: &ExportOptions,
    out_dir: &Path,
    interrupted: &dyn Fn() -> bool,
) -> Result<ExportReport, ExportError> {
    let Analysis { solid, mut report } = analysis;
    std::fs::create_dir_all(out_dir).map_err(|source| ExportError::Io {
        path: out_dir.to_path_buf(),
        source,
    })?;
    let mut set = FileSet::stage(out_dir, &solid.name())?;
    let staging = set.staging.clone();
    let mut formats = options.formats.clone();
    formats.sort();
    formats.dedup();
    for format in formats {
        let start = Instant::now();
        let written = writer(format).write(&solid, &staging)?;
        let seconds = start.elapsed().as_secs_f64();
        for path in written {
            report.files.push(WrittenFile {
                format: Some(format),
                bytes: file_size(&path),
                path,
                seconds,
            });
            set.wrote()?;
        }
        if interrupted() {
            return Err(ExportError::Interrupted);
        }
    }
    let start = Instant::now();
    let sheet_files = sheet::write(
        &solid,
        &report.main_view_coverage,
        &report.tolerances,
        report.one_image_identifiability,
        &staging,
    )?;
    let seconds = start.elapsed().as_secs_f64();
    for path in sheet_files {
        report.files.push(WrittenFile {
            format: None,
            bytes: file_size(&path),
            path,
            seconds,
        });
        set.wrote()?;
    }
    if interrupted() {
        return Err(ExportError::Interrupted);
    }
    // The report names the files where they will be.
    for file in &mut report.files {
        if let Some(name) = file.path.file_name() {
            file.path = out_dir.join(name);
        }
    }
    let json_name = format!("{}-export.json", solid.name());
    report.files.push(WrittenFile {
        format: None,
        path: out_dir.join(&json_name),
        bytes: 0,
        seconds: 0.0,
    });
    let json = serde_json::to_string_pretty(&report).expect("the report serialises") + "\n";
    write_file(&staging.join(&json_name), json.as_bytes())?;
    set.wrote()?;
    set.commit()?;
    if let Some(last) = report.files.last_mut() {
        last.bytes = json.len() as u64;
    }
    Ok(report)
}

/// An export's files as a set: written into a staging directory inside the
/// output directory (`.<name>.export.<pid>.<n>.tmp`), then renamed into
/// place one by one by [`FileSet::commit`]. Dropped before the commit
/// finished (an error, an interruption), it removes the staging directory
/// and any file it had already moved into place, so that an export leaves
/// all of its files or none of them. Files of an earlier export that a
/// renamed file replaced are not restored.
struct FileSet {
    out_dir: PathBuf,
    staging: PathBuf,
    moved: Vec<PathBuf>,
    committed: bool,
    /// Files staged so far (for the test-only failure point).
    #[cfg(test)]
    written: usize,
}

#[cfg(test)]
thread_local! {
    /// Test-only failure point: fail once this many files are staged.
    static FAIL_AFTER_FILES: std::cell::Cell<Option<usize>> = const { std::cell::Cell::new(None) };
}

impl FileSet {
    fn stage(out_dir: &Path, name: &str) -> Result<FileSet, ExportError> {
        static NEXT: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
        let n = NEXT.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let staging = out_dir.join(format!(".{name}.export.{}.{n}.tmp", std::process::id()));
        std::fs::create_dir(&staging).map_err(|source| ExportError::Io {
            path: staging.clone(),
            source,
        })?;
        Ok(FileSet {
            out_dir: out_dir.to_path_buf(),
            staging,
            moved: Vec::new(),
            committed: false,
            #[cfg(test)]
            written: 0,
        })
    }

    /// One more file is staged.
    fn wrote(&mut self) -> Result<(), ExportError> {
        #[cfg(test)]
        {
            self.written += 1;
            if FAIL_AFTER_FILES.with(|f| f.get()) == Some(self.written) {
                return Err(ExportError::Io {
                    path: self.staging.clone(),
                    source: std::io::Error::other("injected failure"),
                });
            }
        }
        Ok(())
    }

    /// Moves every staged file into the output directory.
    fn commit(mut self) -> Result<(), ExportError> {
        let io = |path: &Path| {
            let path = path.to_path_buf();
            move |source| ExportError::Io { path, source }
        };
        let mut staged: Vec<PathBuf> = std::fs::read_dir(&self.staging)
            .map_err(io(&self.staging))?
            .map(|entry| entry.map(|e| e.path()))
            .collect::<Result<_, _>>()
            .map_err(io(&self.staging))?;
        staged.sort();
        for from in staged {
            let Some(name) = from.file_name() else {
                continue;
            };
            let to = self.out_dir.join(name);
            std::fs::rename(&from, &to).map_err(io(&to))?;
            self.moved.push(to);
        }
        self.committed = true;
        let _ = std::fs::remove_dir(&self.staging);
        Ok(())
    }
}

impl Drop for FileSet {
    fn drop(&mut self) {
        if !self.committed {
            for path in &self.moved {
                let _ = std::fs::remove_file(path);
            }
            let _ = std::fs::remove_dir_all(&self.staging);
        }
    }
}

fn file_size(path: &Path) -> u64 {
    std::fs::metadata(path).map(|m| m.len()).unwrap_or(0)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::layout::LayoutPoint;
    use std::cell::Cell;

    /// Records progress; stops at once when asked to.
    #[derive(Default)]
    struct Record {
        stop: bool,
        progress: Vec<(String, u64, u64)>,
    }

    impl Observer for Record {
        fn progress(&mut self, phase: &str, done: u64, total: u64) {
            self.progress.push((phase.to_string(), done, total));
        }
        fn interrupted(&self) -> bool {
            self.stop
        }
    }

    #[test]
    fn reports_progress_and_every_file_and_honours_an_early_stop() {
        let dir = tempfile::tempdir().unwrap();
        let config = ExportConfig {
            layout: Layout::paper_biprism(),
            options: ExportOptions {
                formats: vec![Format::Stl],
                ..Default::default()
            },
            out_dir: dir.path().to_path_buf(),
        };
        let mut observer = Record::default();
        let report = run(&config, &mut observer).unwrap();
        assert!(!report.files.is_empty());
        assert!(report.files.iter().all(|f| f.path.exists()));
        assert_eq!(
            observer.progress,
            [
                (PHASE_EXPORT.to_string(), 0, 1),
                (PHASE_EXPORT.to_string(), 1, 1)
            ]
        );
        let mut stopping = Record {
            stop: true,
            ..Default::default()
        };
        let other = tempfile::tempdir().unwrap();
        let config = ExportConfig {
            out_dir: other.path().join("never"),
            ..config
        };
        assert!(matches!(
            run(&config, &mut stopping),
            Err(ExportError::Interrupted)
        ));
        assert!(!config.out_dir.exists());
    }

    /// A small part that meshes in a fraction of a second.
    pub(crate) fn small() -> Layout {
        let points = [
            [0.0, 0.0, 0.0],
            [30.0, 0.0, -10.0],
            [0.0, 26.0, -5.0],
            [-12.0, -14.0, 15.0],
        ];
        Layout {
            name: "small".into(),
            points: points
                .iter()
                .enumerate()
                .map(|(i, p)| LayoutPoint::new(format!("S{i}"), (*p).into()))
                .collect(),
            sphere_diameter_mm: 6.0,
            family: None,
            provenance: None,
        }
    }

    fn options() -> ExportOptions {
        ExportOptions {
            formats: vec![Format::Stl, Format::Obj],
            allow_occlusion: true,
            ..Default::default()
        }
    }

    /// Every entry of `dir`, sorted.
    fn entries(dir: &Path) -> Vec<String> {
        let mut names: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        names
    }

    #[test]
    fn a_failure_part_way_leaves_none_of_the_files() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("keep.txt"), "not ours").unwrap();
        let report = export(&small(), &options(), dir.path()).unwrap();
        // stl, obj, the sheet's three files, the report.
        assert_eq!(report.files.len(), 6);
        assert!(report.files.iter().all(|f| f.path.exists()), "{report:?}");
        assert_eq!(entries(dir.path()).len(), 7);
        for fail_after in [1, 4, 6] {
            let other = tempfile::tempdir().unwrap();
            std::fs::write(other.path().join("keep.txt"), "not ours").unwrap();
            FAIL_AFTER_FILES.with(|f| f.set(Some(fail_after)));
            let result = export(&small(), &options(), other.path());
            FAIL_AFTER_FILES.with(|f| f.set(None));
            let error = result.unwrap_err();
            assert!(error.to_string().contains("injected failure"), "{error}");
            assert_eq!(
                entries(other.path()),
                ["keep.txt"],
                "failing after {fail_after}"
            );
        }
    }

    #[test]
    fn a_rename_that_fails_takes_back_the_files_already_moved() {
        let dir = tempfile::tempdir().unwrap();
        // The last file moved into place (names sorted) cannot replace a
        // directory that holds a file.
        std::fs::create_dir(dir.path().join("small.stl")).unwrap();
        std::fs::write(dir.path().join("small.stl").join("x"), "x").unwrap();
        let error = export(&small(), &options(), dir.path()).unwrap_err();
        assert!(
            matches!(&error, ExportError::Io { path, .. } if path.ends_with("small.stl")),
            "{error}"
        );
        assert_eq!(entries(dir.path()), ["small.stl"]);
    }

    #[test]
    fn an_interruption_part_way_leaves_none_of_the_files() {
        for polls in [1, 2, 3] {
            let dir = tempfile::tempdir().unwrap();
            let asked = Cell::new(0);
            let interrupted = || {
                asked.set(asked.get() + 1);
                asked.get() >= polls
            };
            let result = export_observed(&small(), &options(), dir.path(), &interrupted);
            assert!(matches!(result, Err(ExportError::Interrupted)));
            assert!(entries(dir.path()).is_empty(), "after {polls} polls");
        }
    }
}
