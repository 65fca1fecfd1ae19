//! The export run: the analysis ([`super::analysis::analyse`]), then every
//! requested format, the fabrication sheet and `<name>-export.json`
//! written as one staged file set ([`export`]), with its progress reported
//! to an [`Observer`] ([`run`]); the files written are in the returned
//! report.
use super::analysis::{analyse, Analysis, ExportReport, WrittenFile};
use super::{gltf, obj, sheet, stl, threemf};
use super::{ExportError, ExportOptions, Format, MeshWriter};
use crate::kernel::stop::abandon_on_stop;
use crate::kernel::{OutputPlan, Outputs, Scratch};
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
    /// The files the layout was read from, each with the argument that
    /// named it: no output may be one of them.
    pub sources: Vec<(String, PathBuf)>,
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
    let outputs = Target {
        dir: &config.out_dir,
        sources: &config.sources,
    }
    .open()?;
    let (layout, options) = (config.layout.clone(), config.options.clone());
    let analysis = abandon_on_stop(observer, move || analyse(&layout, &options))
        .map_err(|_| ExportError::Interrupted)??;
    let observer_ref = &*observer;
    let report = write_analysis(analysis, &config.options, &config.out_dir, outputs, &|| {
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
    let outputs = Target {
        dir: out_dir,
        sources: &[],
    }
    .open()?;
    let analysis = analyse(layout, options)?;
    if interrupted() {
        return Err(ExportError::Interrupted);
    }
    write_analysis(analysis, options, out_dir, outputs, interrupted)
}

/// Where an export's files go, and what they must not overwrite.
#[derive(Debug, Clone, Copy)]
pub struct Target<'a> {
    /// The output directory (created if missing).
    pub dir: &'a Path,
    /// The files the run read, each with the argument that named it.
    pub sources: &'a [(String, PathBuf)],
}

impl Target<'_> {
    /// The export's output set, checked and locked before any work
    /// ([`crate::kernel::outputs`]): an output directory that is a file,
    /// or that another run holds, is refused here.
    pub fn open(&self) -> Result<Outputs, ExportError> {
        let mut plan = OutputPlan::new();
        for (what, path) in self.sources {
            plan.input(what.as_str(), path);
        }
        plan.dir("--out", self.dir);
        Ok(plan.open()?)
    }
}

/// Writes an analysed part's files into `out_dir`, through `outputs` (its
/// [`Target`] opened), as one output set on the run kernel: each writer's
/// files made in a scratch directory and staged beside their targets, and
/// all moved into place together at the end, so that a failure or a stop
/// part-way leaves none of them (and the files of an earlier export as
/// they were). A file named like one of the target's sources is refused.
/// `interrupted` is asked between the files.
pub fn write_analysis(
    analysis: Analysis,
    options: &ExportOptions,
    out_dir: &Path,
    outputs: Outputs,
    interrupted: &dyn Fn() -> bool,
) -> Result<ExportReport, ExportError> {
    let Analysis { solid, mut report } = analysis;
    let scratch = Scratch::new(out_dir)?;
    let mut staged = Staged::default();
    // A writer's file, moved out of the scratch directory; where it lands.
    let mut stage = |written: &Path| -> Result<PathBuf, ExportError> {
        let path = out_dir.join(written.file_name().unwrap_or_default());
        outputs.stage_written(written, &path)?;
        staged.one_more()?;
        Ok(path)
    };
    let mut formats = options.formats.clone();
    formats.sort();
    formats.dedup();
    for format in formats {
        let start = Instant::now();
        let written = writer(format).write(&solid, scratch.path())?;
        let seconds = start.elapsed().as_secs_f64();
        for path in written {
            let bytes = file_size(&path);
            report.files.push(WrittenFile {
                format: Some(format),
                bytes,
                path: stage(&path)?,
                seconds,
            });
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
        scratch.path(),
    )?;
    let seconds = start.elapsed().as_secs_f64();
    for path in sheet_files {
        let bytes = file_size(&path);
        report.files.push(WrittenFile {
            format: None,
            bytes,
            path: stage(&path)?,
            seconds,
        });
    }
    if interrupted() {
        return Err(ExportError::Interrupted);
    }
    let json_path = out_dir.join(format!("{}-export.json", solid.name()));
    report.files.push(WrittenFile {
        format: None,
        path: json_path.clone(),
        bytes: 0,
        seconds: 0.0,
    });
    let json = serde_json::to_string_pretty(&report).expect("the report serialises") + "\n";
    outputs.stage(&json_path, json.as_bytes())?;
    staged.one_more()?;
    drop(scratch);
    outputs.commit()?;
    if let Some(last) = report.files.last_mut() {
        last.bytes = json.len() as u64;
    }
    Ok(report)
}

/// Counts the files an export stages, for the test-only failure point.
#[derive(Debug, Default)]
struct Staged {
    #[cfg(test)]
    count: usize,
}

#[cfg(test)]
thread_local! {
    /// Test-only failure point: fail once this many files are staged.
    static FAIL_AFTER_FILES: std::cell::Cell<Option<usize>> = const { std::cell::Cell::new(None) };
}

impl Staged {
    /// One more file is staged.
    fn one_more(&mut self) -> Result<(), ExportError> {
        #[cfg(test)]
        {
            self.count += 1;
            if FAIL_AFTER_FILES.with(|f| f.get()) == Some(self.count) {
                return Err(ExportError::Io {
                    path: PathBuf::from("staged"),
                    source: std::io::Error::other("injected failure"),
                });
            }
        }
        Ok(())
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
            sources: Vec::new(),
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
            matches!(
                &error,
                ExportError::Output(crate::kernel::OutputError::Write { path, .. })
                    if path.ends_with("small.stl")
            ),
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
