//! `validate`: the sensitivity report of a layout. Monte-Carlo runs of real
//! solvers over a scenario grid, beside the first-order (Cramér–Rao) and
//! transfer-model predictions, with visibility counted per scenario, the
//! identifiability of the blobs and, on request, the fabrication error.
//!
//! The command has the shape every command shares, one file per part:
//!
//! - [`config`]: [`ValidateConfig`], every input, checked once
//!   ([`ValidateConfig::check`]) with a [`ConfigError`] that names the field;
//! - [`analysis`]: a checked config in, a serialisable [`ValidateSummary`]
//!   ([`summary`]) out; no files, no printing, progress through an
//!   [`Observer`](crate::observer::Observer);
//! - [`report`] (files) and [`markdown`] (text): render a summary, computing
//!   nothing new;
//! - [`workflow`]: the output lock, the time estimate, the phases, the
//!   atomic writes and `run.json`.
//!
//! ```no_run
//! use layout_opt::layout::Layout;
//! use layout_opt::observer::Silent;
//! use layout_opt::pnp::Solver;
//! use layout_opt::validate::workflow::WorkflowConfig;
//! use layout_opt::validate::{self, ValidateConfig};
//!
//! let config = ValidateConfig::new(Layout::paper_biprism(), vec![Solver::Ml]);
//! // The numbers alone, no files:
//! let summary = validate::analyse(&config, &mut Silent)?;
//! println!("{} visible scenarios", summary.overview.visibility.visible);
//! // The report and run.json in a directory:
//! validate::workflow::run(&WorkflowConfig::new(config, "reports/biprism"), &mut Silent)?;
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

pub mod analysis;
pub mod config;
pub mod image_check;
pub mod image_report;
pub mod images;
pub mod markdown;
pub mod pairs;
pub mod report;
pub mod summary;
pub mod workflow;

pub use analysis::{analyse, ValidateError, PHASE};
pub use config::{
    IdentifiabilityCheck, ValidateConfig, DEFAULT_IDENTIFY_TRIALS, DEFAULT_TILT_STEP_DEG,
    POLYNOMIAL_TILT_STEP_DEG,
};
pub use summary::{
    AxisErrors, AxisVisibility, Curve, CurveSolver, Header, IdentifiabilityCurve,
    IdentifiabilitySummary, Overview, SolverRow, Systematic, ValidateSummary, VisibilityClass,
    VisibilityCounts,
};
