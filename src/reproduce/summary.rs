//! What a reproduction found, serialisable: the header (where every number
//! came from) and each experiment's panels, claims and timings.

use super::claims::Claim;
use super::config::Experiment;
use super::panel::Panel;
use crate::camera::Camera;
use serde::Serialize;

/// Trials of one experiment, for the header.
#[derive(Debug, Clone, Serialize)]
pub struct TrialCount {
    /// The experiment.
    pub experiment: Experiment,
    /// Trials run (repetitions for timing).
    pub trials: usize,
    /// The paper's count (`None`: one real image per pose).
    pub paper_trials: Option<usize>,
    /// The camera it ran with.
    pub camera: Camera,
}

/// Where every number came from.
#[derive(Debug, Clone, Serialize)]
pub struct Header {
    /// The command line.
    pub command: String,
    /// layout-opt version.
    pub version: String,
    /// Seed.
    pub seed: u64,
    /// Whether `--quick` was given.
    pub quick: bool,
    /// Trials per experiment.
    pub trials: Vec<TrialCount>,
    /// Solvers run (stable names, in report order).
    pub solvers: Vec<String>,
    /// The paper's solvers this build does not have.
    pub paper_solvers_not_available: Vec<String>,
    /// The camera given for every experiment (`--camera`), if any; each
    /// experiment's camera is in [`TrialCount::camera`].
    pub camera_override: Option<Camera>,
    /// σ used for the paper's "variance 0.2", px.
    pub paper_sigma_px: f64,
    /// Gross-failure threshold on the geodesic rotation error, degrees.
    pub gross_error_deg: f64,
}

/// One experiment's results.
#[derive(Debug, Clone, Serialize)]
pub struct ExperimentResult {
    /// The experiment.
    pub experiment: Experiment,
    /// Trials per setting (repetitions for timing).
    pub trials: usize,
    /// Settings, as markdown bullet lines.
    pub setup: Vec<String>,
    /// Curves, one per figure.
    pub panels: Vec<Panel>,
    /// Extra markdown (tables laid out as the paper's).
    pub extra_markdown: String,
    /// The paper's claims, checked.
    pub claims: Vec<Claim>,
    /// Extra CSV files (name, content).
    #[serde(skip)]
    pub extra_csv: Vec<(String, String)>,
    /// Timing data (experiment 3 only).
    #[serde(skip)]
    pub timing: Option<TimingResult>,
}

/// A finished reproduction (the report writes its deterministic part to
/// `summary.json`; [`Reproduction::wall_seconds`] is machine-dependent).
#[derive(Debug, Clone, Serialize)]
pub struct Reproduction {
    /// Provenance.
    pub header: Header,
    /// Results, in the paper's order.
    pub experiments: Vec<ExperimentResult>,
    /// Wall time of each experiment, seconds (machine-dependent).
    pub wall_seconds: Vec<(Experiment, f64)>,
}

/// One solver at one n.
#[derive(Debug, Clone, Serialize)]
pub struct TimingRow {
    /// Number of points.
    pub n: usize,
    /// Stable solver name.
    pub solver: String,
    /// Timed solves.
    pub repetitions: usize,
    /// Solves that returned an error.
    pub errors: usize,
    /// Median time per call of `solve_best`, µs.
    pub median_us: Option<f64>,
    /// Mean time per call of `solve_best`, µs.
    pub mean_us: Option<f64>,
    /// Median time of the shared input checks alone, µs.
    pub median_validation_us: Option<f64>,
    /// Median over problems of (solve − checks): the method's own time, µs.
    pub median_method_us: Option<f64>,
}

/// The timing experiment's measurements.
#[derive(Debug, Clone, Serialize)]
pub struct TimingResult {
    /// Point counts.
    pub counts: Vec<usize>,
    /// One row per (n, solver).
    pub rows: Vec<TimingRow>,
    /// Threads in rayon's pool (the timing itself runs on one thread).
    pub rayon_threads: usize,
}
