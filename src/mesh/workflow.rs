//! `export` as one call with an [`Observer`](crate::observer::Observer),
//! like the other commands' workflows: the part is designed, meshed,
//! checked and written ([`export`]), with its progress reported to the
//! observer; the files written are in the returned report.
use super::{ExportError, ExportOptions, ExportReport};
use crate::layout::Layout;
use crate::observer::Observer;
use std::path::PathBuf;

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
/// [`ExportError::Interrupted`]: before the work starts, or between the
/// design and each file, and then none of the export's files are left.
pub fn run(
    config: &ExportConfig,
    observer: &mut impl Observer,
) -> Result<ExportReport, ExportError> {
    if observer.interrupted() {
        return Err(ExportError::Interrupted);
    }
    observer.progress(PHASE_EXPORT, 0, 1);
    let observer_ref = &*observer;
    let report = super::export_observed(&config.layout, &config.options, &config.out_dir, &|| {
        observer_ref.interrupted()
    })?;
    observer.progress(PHASE_EXPORT, 1, 1);
    Ok(report)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::Format;

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
}
