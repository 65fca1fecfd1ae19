//! `layout-opt track`: from grey camera frames of a printed marker to
//! labelled poses with their uncertainty.
//!
//! * [`config`]: the validated [`TrackConfig`];
//! * [`frame`]: 8/16-bit grey PNG frames and their errors;
//! * [`detect`] and [`conic`]: blobs, subpixel centres (intensity centroid,
//!   direct least-squares ellipse fit, the sphere's projected centre) and
//!   the partly-hidden flag;
//! * [`analysis`]: one frame in, labels + pose + covariance out (no files);
//! * [`refine`]: render-and-compare, the part's own bias on each centre
//!   measured on a render at the tracked pose and taken off, where
//!   [`likeness`] finds the render like the frame;
//! * [`uncertainty`]: rvec/tvec, residuals, σ, covariance and label trust,
//!   shared with `solve`;
//! * [`report`]: JSON lines, CSV, overlay PNGs;
//! * [`stream`]: frames from standard input or a directory that fills,
//!   each line written as its frame is done;
//! * [`workflow`]: files and directories, parallel frames, progress,
//!   atomic writes.
//!
//! The JSON-lines output is a contract (docs/formats.md, "`track` output").

pub mod analysis;
pub mod config;
pub mod conic;
pub mod detect;
pub mod frame;
pub mod likeness;
pub mod refine;
pub mod report;
pub mod set;
pub mod stream;
pub mod uncertainty;
pub mod workflow;

pub use analysis::{analyse, analyse_png, FrameAnalysis, TrackError, TrackedFrame};
pub use config::{CentreMethod, DetectorConfig, Threshold, TrackConfig};
pub use frame::{FrameError, GreyFrame};
