//! Why a search failed: the one error of the search's analysis, report and
//! workflow.

use super::checkpoint::CheckpointError;
use super::optimise::OptimiseError;
use crate::config::ConfigError;
use crate::family::FamilyError;
use crate::files::LockError;
use crate::layout::LayoutError;
use crate::mesh::ExportError;
use crate::montecarlo::MonteCarloError;
use crate::report::ReportError;
use crate::validate::ValidateError;
use std::path::PathBuf;

/// Why a search failed.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SearchError {
    /// A setting is out of range (named by its field).
    #[error("invalid search configuration: {0}")]
    Config(#[from] ConfigError),
    /// The family cannot be built.
    #[error(transparent)]
    Family(#[from] FamilyError),
    /// Checkpoints could not be prepared or removed.
    #[error(transparent)]
    Checkpoint(#[from] CheckpointError),
    /// The optimisation failed.
    #[error(transparent)]
    Optimise(#[from] OptimiseError),
    /// A directory could not be created.
    #[error("creating {}: {source}", path.display())]
    CreateDir {
        /// The directory.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// The caller asked to stop a run that keeps nothing part-way (a set
    /// search).
    #[error(transparent)]
    Interrupted(#[from] crate::kernel::Interrupted),
    /// The best-so-far layout could not be written during the search.
    #[error("could not write the best-so-far layout: {0}")]
    BestSoFar(String),
    /// The winning layout could not be written.
    #[error(transparent)]
    Layout(#[from] LayoutError),
    /// The winner's or the paper's biprism's part could not be built to
    /// count its supports.
    #[error("the printed part's supports could not be routed: {0}")]
    Supports(String),
    /// No layout can meet the constraints (found before the search).
    #[error("the constraints cannot all be met: {0}")]
    Unsatisfiable(String),
    /// An output cannot be written (found before any work).
    #[error("cannot write {}: {source}; nothing was run", path.display())]
    Unwritable {
        /// The output file or directory.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// Another run holds an output.
    #[error(transparent)]
    Lock(#[from] LockError),
    /// The best layout found breaks a constraint.
    #[error("the constraints cannot all be met (best layout, kept in {}): {}", layout.display(), violations.join("; "))]
    Infeasible {
        /// Where the best layout was written.
        layout: PathBuf,
        /// Each broken constraint, in words.
        violations: Vec<String>,
    },
    /// The Monte-Carlo comparison failed.
    #[error(transparent)]
    MonteCarlo(#[from] MonteCarloError),
    /// The winner's validation failed.
    #[error(transparent)]
    Sensitivity(#[from] ValidateError),
    /// A report file could not be written.
    #[error(transparent)]
    Report(#[from] ReportError),
    /// The mesh export failed.
    #[error("exporting the winner to {}: {source}", dir.display())]
    Export {
        /// The export directory.
        dir: PathBuf,
        /// Why.
        source: ExportError,
    },
}
