//! `reproduce`: the seed paper's simulation experiments (Hu, Li & Tan, §4.3
//! and the supplementary figures) regenerated on our solvers, with every claim
//! the paper makes about them checked by an explicit numeric rule
//! ([`claims`]).
//!
//! | experiment | paper | what varies |
//! |---|---|---|
//! | `points` | Fig. 7, §2.1, §5.1 | n = 4…20 random points |
//! | `noise` | Figs. 8, 9 | σ = 0.5…10 px; n = 10 random points, biprism with L = 25 and 100 mm |
//! | `timing` | Fig. 10 | n = 4…104, single-thread median time per solve |
//! | `depth` | Figs. 11–14, §5.2 | depth/size ratio, n = 10 random points and the biprism, near and far |
//! | `off-axis` | Figs. S1, S2 | distance of the biprism from the optical axis at depths 200 and 100 mm |
//! | `tilt` | Fig. S3 | biprism rotated about Y, −90°…90° |
//! | `protocol` | Tables I–XV | the real-image protocol, simulated |
//!
//! Every solver in [`Solver::ALL`] runs in every experiment, so solvers added
//! later appear without changes here. Claims that name a solver this build
//! lacks are reported as *not evaluated*.
//!
//! **Reading of the paper** (documented choices, see docs/paper-notes.md,
//! "Simulation experiments (§4.3)"):
//! * "noise with a variance of 0.2" is σ = √0.2 ≈ 0.447 px ([`paper_sigma_px`]);
//!   the noise sweep's "0~10 pixels, step 0.5" is σ = 0.5…10 px;
//! * the "6-point biprism" is the paper's Fig. 6 marker: six vertices at ±L
//!   on the axes plus the centre O0 (7 features); its size is L;
//! * errors are the paper's E_rot (eq. 33) and E_t (%), averaged over trials
//!   as the paper does; geodesic errors and medians are in the CSV files;
//! * simulations 1–6 ignore the image border and occlusion, as the paper's
//!   simulations do; the simulated real-image protocol (7) ignores the border
//!   too but pools only the poses in which no sphere hides another, as a
//!   detector needs;
//! * the camera is the paper's (§4.2), without distortion.
//!
//! `summary.json` and every CSV except `timing*.csv` are bit-identical for the
//! same seed at any thread count; timings (`timing.csv`, `timing_claims.csv`,
//! `timing.json`) and wall times (`run.json`) are machine-dependent.

pub(crate) mod claims;
mod depth;
mod engine;
mod noise;
mod off_axis;
pub(crate) mod panel;
mod points;
mod protocol;
pub(crate) mod stats;
mod tilt;
mod timing;
pub mod workflow;

pub use claims::{Claim, Verdict};
pub use engine::GROSS_ERROR_DEG;
pub use timing::{TimingResult, TimingRow};

use crate::camera::Camera;
use crate::montecarlo::MonteCarloError;
use crate::pnp::Solver;
use crate::report::{write_text, ReportError, Table};

use engine::{Context, Progress};
use panel::{Metric, Panel};
use serde::Serialize;
use std::fmt::Write as _;
use std::path::Path;
use std::str::FromStr;
use std::sync::atomic::AtomicBool;
use std::time::Instant;

/// Noise draws per pose of the simulated protocol by default (1365 poses:
/// each table cell pools about 2,000 solves per solver, and the whole run
/// stays well within 15 minutes on two cores with every solver, OPnP taking
/// about 2 ms per solve).
pub const PROTOCOL_DEFAULT_TRIALS: usize = 30;

/// The paper's noise level "variance 0.2", in px².
pub const PAPER_VARIANCE_PX2: f64 = 0.2;

/// σ for the paper's "variance 0.2": √0.2 px.
pub fn paper_sigma_px() -> f64 {
    PAPER_VARIANCE_PX2.sqrt()
}

/// The solvers the paper's tables compare (Tables I–XV), by our stable names,
/// in the paper's column order. Claims about "the paper's solvers" use the
/// members of this list that this build has.
pub const PAPER_SOLVERS: [&str; 9] = [
    "dlt",
    "epnp",
    "epnp-gn",
    "dls",
    "lhm",
    "rpnp",
    "opnp",
    "parallel",
    "parallel-weighted",
];

/// One of the paper's simulation experiments.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Experiment {
    /// Accuracy against the number of points (Fig. 7).
    Points,
    /// Accuracy against pixel noise (Figs. 8, 9).
    Noise,
    /// Running time against the number of points (Fig. 10).
    Timing,
    /// Accuracy against the depth/size ratio (Figs. 11–14).
    Depth,
    /// Accuracy against the distance from the optical axis (Figs. S1, S2).
    OffAxis,
    /// Accuracy against the tilt about Y (Fig. S3).
    Tilt,
    /// The real-image protocol of Tables I–XV, simulated.
    Protocol,
}

impl Experiment {
    /// Every experiment, in the paper's order.
    pub const ALL: [Experiment; 7] = [
        Experiment::Points,
        Experiment::Noise,
        Experiment::Timing,
        Experiment::Depth,
        Experiment::OffAxis,
        Experiment::Tilt,
        Experiment::Protocol,
    ];

    /// The CLI name.
    pub fn name(self) -> &'static str {
        match self {
            Experiment::Points => "points",
            Experiment::Noise => "noise",
            Experiment::Timing => "timing",
            Experiment::Depth => "depth",
            Experiment::OffAxis => "off-axis",
            Experiment::Tilt => "tilt",
            Experiment::Protocol => "protocol",
        }
    }

    /// Section title.
    pub fn title(self) -> &'static str {
        match self {
            Experiment::Points => "Number of points (Fig. 7)",
            Experiment::Noise => "Noise (Figs. 8, 9a, 9b)",
            Experiment::Timing => "Running time (Fig. 10)",
            Experiment::Depth => "Depth/size ratio (Figs. 11–14)",
            Experiment::OffAxis => "Distance from the optical axis (Figs. S1, S2)",
            Experiment::Tilt => "Tilt about Y (Fig. S3)",
            Experiment::Protocol => "The real-image protocol, simulated (Tables I–XV)",
        }
    }

    /// Position in the paper's order, 1-based (also the stream family).
    pub fn number(self) -> u64 {
        match self {
            Experiment::Points => 1,
            Experiment::Noise => 2,
            Experiment::Timing => 3,
            Experiment::Depth => 4,
            Experiment::OffAxis => 5,
            Experiment::Tilt => 6,
            Experiment::Protocol => 7,
        }
    }

    /// The paper's trial count (repetitions for timing); `None` for the
    /// protocol, whose real images have one shot per pose.
    pub fn paper_trials(self) -> Option<usize> {
        match self {
            Experiment::Points => Some(200),
            Experiment::Noise => Some(500),
            Experiment::Timing => Some(500),
            Experiment::Depth => Some(100),
            Experiment::OffAxis => Some(100),
            Experiment::Tilt => Some(100),
            Experiment::Protocol => None,
        }
    }

    /// Default trials: the paper's count; for the protocol,
    /// [`PROTOCOL_DEFAULT_TRIALS`] noise draws per pose.
    pub fn default_trials(self) -> usize {
        self.paper_trials().unwrap_or(PROTOCOL_DEFAULT_TRIALS)
    }

    /// Trials under `--quick` (same grids, fewer trials): a smoke run that
    /// stays within a minute on two shared cores with every solver.
    pub fn quick_trials(self) -> usize {
        match self {
            Experiment::Points => 10,
            Experiment::Noise => 10,
            Experiment::Timing => 10,
            Experiment::Depth => 10,
            Experiment::OffAxis => 10,
            Experiment::Tilt => 3,
            Experiment::Protocol => 1,
        }
    }

    /// Wall-clock seconds of the experiment at its default trials in the
    /// reference run (`layout-opt reproduce --quiet`, seed 7, every solver,
    /// 2 threads on a shared 2-core machine): the cost model behind
    /// [`Config::estimate_seconds`].
    pub fn reference_seconds(self) -> f64 {
        match self {
            Experiment::Points => 2.1,
            Experiment::Noise => 16.3,
            Experiment::Timing => 15.2,
            Experiment::Depth => 2.8,
            Experiment::OffAxis => 2.1,
            Experiment::Tilt => 9.0,
            Experiment::Protocol => 20.4,
        }
    }

    /// Whether its outputs are bit-reproducible (timing is not).
    pub fn deterministic(self) -> bool {
        self != Experiment::Timing
    }
}

impl std::fmt::Display for Experiment {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Experiment {
    type Err = ReproduceError;
    fn from_str(name: &str) -> Result<Self, Self::Err> {
        Experiment::ALL
            .iter()
            .copied()
            .find(|e| e.name() == name.trim())
            .ok_or_else(|| ReproduceError::UnknownExperiment(name.trim().to_string()))
    }
}

/// Parses `all` or a comma list of experiment names (duplicates dropped,
/// the paper's order kept).
pub fn parse_experiments(text: &str) -> Result<Vec<Experiment>, ReproduceError> {
    if text.trim() == "all" {
        return Ok(Experiment::ALL.to_vec());
    }
    let mut chosen = Vec::new();
    for name in text.split(',').filter(|s| !s.trim().is_empty()) {
        let experiment: Experiment = name.parse()?;
        if !chosen.contains(&experiment) {
            chosen.push(experiment);
        }
    }
    if chosen.is_empty() {
        return Err(ReproduceError::UnknownExperiment(text.to_string()));
    }
    chosen.sort();
    Ok(chosen)
}

/// Why a reproduction could not run.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ReproduceError {
    /// An experiment name we do not know.
    #[error("unknown experiment '{0}'; known: all, points, noise, timing, depth, off-axis, tilt, protocol")]
    UnknownExperiment(String),
    /// Zero trials.
    #[error("the number of trials must be at least 1")]
    NoTrials,
    /// The Monte-Carlo engine refused the run.
    #[error(transparent)]
    MonteCarlo(#[from] MonteCarloError),
    /// A report file could not be written.
    #[error(transparent)]
    Report(#[from] ReportError),
    /// The caller asked the run to stop before it finished; nothing was
    /// written.
    #[error("the reproduction was stopped before it finished; no report written")]
    Interrupted,
}

/// What to run.
#[derive(Debug, Clone, PartialEq)]
pub struct Config {
    /// Experiments, in the paper's order.
    pub experiments: Vec<Experiment>,
    /// Seed of every stream.
    pub seed: u64,
    /// Trials for every experiment (repetitions for timing), overriding the defaults.
    pub trials: Option<usize>,
    /// Fewer trials on the same grids ([`Experiment::quick_trials`]).
    pub quick: bool,
}

impl Config {
    /// Trials of `experiment` under this configuration.
    pub fn trials_for(&self, experiment: Experiment) -> usize {
        self.trials.unwrap_or(if self.quick {
            experiment.quick_trials()
        } else {
            experiment.default_trials()
        })
    }
}

/// Threads of the reference run behind [`Experiment::reference_seconds`].
pub const REFERENCE_THREADS: usize = 2;

impl Config {
    /// Estimated wall-clock seconds on `threads` threads, from a cost model:
    /// each experiment's time in the reference run
    /// ([`Experiment::reference_seconds`]), scaled by its trials over the
    /// default ones and, except for timing (one thread by design), by
    /// [`REFERENCE_THREADS`] over `threads`. A machine faster or slower per
    /// core than the reference one scales the whole estimate.
    pub fn estimate_seconds(&self, threads: usize) -> f64 {
        self.experiments
            .iter()
            .map(|&experiment| {
                let trials =
                    self.trials_for(experiment) as f64 / experiment.default_trials() as f64;
                let threads = if experiment == Experiment::Timing {
                    1.0
                } else {
                    REFERENCE_THREADS as f64 / threads.max(1) as f64
                };
                experiment.reference_seconds() * trials * threads
            })
            .sum()
    }

    /// The default output directory: `reports/paper` for the reference run
    /// (every experiment at its default trials), and a directory of its own
    /// for any run of lower fidelity or narrower scope, so that a default
    /// never overwrites the committed reference report with a smaller run:
    /// `reports/paper-quick`, `reports/paper-trials-20`,
    /// `reports/paper-timing`, `reports/paper-quick-noise-depth`.
    pub fn default_out_dir(&self) -> std::path::PathBuf {
        let mut name = String::from("paper");
        if self.quick && self.trials.is_none() {
            name.push_str("-quick");
        }
        if let Some(trials) = self.trials {
            let _ = write!(name, "-trials-{trials}");
        }
        if self.experiments != Experiment::ALL {
            for experiment in &self.experiments {
                let _ = write!(name, "-{}", experiment.name());
            }
        }
        Path::new("reports").join(name)
    }
}

/// Trials of one experiment, for the header.
#[derive(Debug, Clone, Serialize)]
pub struct TrialCount {
    /// The experiment.
    pub experiment: Experiment,
    /// Trials run (repetitions for timing).
    pub trials: usize,
    /// The paper's count (`None`: one real image per pose).
    pub paper_trials: Option<usize>,
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
    /// The camera.
    pub camera: Camera,
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

/// A finished reproduction.
#[derive(Debug, Clone)]
pub struct Reproduction {
    /// Provenance.
    pub header: Header,
    /// Results, in the paper's order.
    pub experiments: Vec<ExperimentResult>,
    /// Wall time of each experiment, seconds (machine-dependent).
    pub wall_seconds: Vec<(Experiment, f64)>,
}

/// The paper's solvers this build has, and the names it lacks, from `names`.
pub(crate) fn group(context: &Context, names: &[&str]) -> (Vec<Solver>, Vec<String>) {
    let mut found = Vec::new();
    let mut missing = Vec::new();
    for name in names {
        match find(context, name) {
            Some(solver) => found.push(solver),
            None => missing.push(name.to_string()),
        }
    }
    (found, missing)
}

/// The solver called `name`, if this build has it and it runs.
pub(crate) fn find(context: &Context, name: &str) -> Option<Solver> {
    Solver::from_name(name).filter(|s| context.solvers.contains(s))
}

/// The stream of panel `panel` of experiment `experiment`:
/// `10⁶·experiment + 10⁴·panel` (scenarios add their index within the panel).
pub(crate) fn stream(experiment: Experiment, panel: u64) -> u64 {
    1_000_000 * experiment.number() + 10_000 * panel
}

/// Runs the experiments of `config`. `on_progress(experiment, done, total)`
/// is called from worker threads as problems finish.
pub fn run(
    config: &Config,
    command: &str,
    on_progress: &(dyn Fn(&str, usize, usize) + Sync),
) -> Result<Reproduction, ReproduceError> {
    run_until(config, command, on_progress, &AtomicBool::new(false))
}

/// [`run`], ended early with [`ReproduceError::Interrupted`] once `stop` is
/// set: trials not yet begun are skipped (the Monte-Carlo experiments read
/// it before each trial, the random-geometry ones before each problem,
/// timing before each repetition), so the run ends within one problem.
pub fn run_until(
    config: &Config,
    command: &str,
    on_progress: &(dyn Fn(&str, usize, usize) + Sync),
    stop: &AtomicBool,
) -> Result<Reproduction, ReproduceError> {
    if config.trials == Some(0) {
        return Err(ReproduceError::NoTrials);
    }
    let context = Context {
        camera: Camera::paper(),
        seed: config.seed,
        solvers: Solver::ALL.to_vec(),
        progress: Progress::new(on_progress),
        stop,
    };
    let (_, missing) = group(&context, &PAPER_SOLVERS);
    let header = Header {
        command: command.to_string(),
        version: env!("CARGO_PKG_VERSION").to_string(),
        seed: config.seed,
        quick: config.quick,
        trials: config
            .experiments
            .iter()
            .map(|&experiment| TrialCount {
                experiment,
                trials: config.trials_for(experiment),
                paper_trials: experiment.paper_trials(),
            })
            .collect(),
        solvers: context
            .solvers
            .iter()
            .map(|s| s.name().to_string())
            .collect(),
        paper_solvers_not_available: missing,
        camera: context.camera,
        paper_sigma_px: paper_sigma_px(),
        gross_error_deg: GROSS_ERROR_DEG,
    };
    let mut experiments = Vec::new();
    let mut wall_seconds = Vec::new();
    let interrupted = || context.stopped().then_some(ReproduceError::Interrupted);
    for &experiment in &config.experiments {
        if let Some(error) = interrupted() {
            return Err(error);
        }
        let trials = config.trials_for(experiment);
        let started = Instant::now();
        let result = match experiment {
            Experiment::Points => Ok(points::run(&context, trials)),
            Experiment::Noise => Ok(noise::run(&context, trials)),
            Experiment::Timing => Ok(timing::run(&context, trials)),
            Experiment::Depth => Ok(depth::run(&context, trials)),
            Experiment::OffAxis => off_axis::run(&context, trials),
            Experiment::Tilt => tilt::run(&context, trials),
            Experiment::Protocol => protocol::run(&context, trials),
        };
        // A stopped experiment's results are incomplete: never returned.
        if let Some(error) = interrupted() {
            return Err(error);
        }
        let result = result?;
        wall_seconds.push((experiment, started.elapsed().as_secs_f64()));
        experiments.push(result);
    }
    Ok(Reproduction {
        header,
        experiments,
        wall_seconds,
    })
}

/// The deterministic part of the results, as written to `summary.json`.
#[derive(Debug, Serialize)]
struct Summary<'a> {
    header: &'a Header,
    experiments: Vec<&'a ExperimentResult>,
}

/// Writes `report.md`, `summary.json`, `claims.csv`, one CSV per experiment,
/// two SVGs per figure, the extra CSVs, and for timing `timing.csv`,
/// `timing_claims.csv` and `timing.json`, into `dir`.
pub fn write_report(dir: &Path, reproduction: &Reproduction) -> Result<(), ReproduceError> {
    std::fs::create_dir_all(dir).map_err(|e| ReportError::write(dir, e))?;
    let deterministic: Vec<&ExperimentResult> = reproduction
        .experiments
        .iter()
        .filter(|e| e.experiment.deterministic())
        .collect();
    let summary = Summary {
        header: &reproduction.header,
        experiments: deterministic.clone(),
    };
    let path = dir.join("summary.json");
    let json = serde_json::to_string_pretty(&summary).map_err(|e| ReportError::write(&path, e))?;
    write_text(&path, &(json + "\n"))?;

    let claim_table = |results: &[&ExperimentResult]| {
        let mut table = Table::new([
            "id",
            "experiment",
            "source",
            "claim",
            "criterion",
            "verdict",
            "evidence",
            "not_available",
        ]);
        for result in results {
            for claim in &result.claims {
                table.row([
                    claim.id.clone(),
                    result.experiment.name().to_string(),
                    claim.source.clone(),
                    claim.statement.clone(),
                    claim.criterion.clone(),
                    claim.verdict.label().to_string(),
                    claim.evidence.clone(),
                    claim.not_available.join(" "),
                ]);
            }
        }
        table
    };
    let csv = |path: &Path, table: &Table| -> Result<(), ReproduceError> {
        let text = table.csv().map_err(|e| ReportError::write(path, e))?;
        write_text(path, &text)?;
        Ok(())
    };
    csv(&dir.join("claims.csv"), &claim_table(&deterministic))?;

    for result in &reproduction.experiments {
        if !result.panels.is_empty() {
            let mut table = Panel::csv_header();
            for panel in &result.panels {
                panel.csv_rows(result.experiment.name(), &mut table);
                panel.write_plots(dir)?;
            }
            csv(
                &dir.join(format!(
                    "{}.csv",
                    result.experiment.name().replace('-', "_")
                )),
                &table,
            )?;
        }
        for (name, content) in &result.extra_csv {
            write_text(&dir.join(name), content)?;
        }
        if let Some(timing) = &result.timing {
            timing.write(dir)?;
            csv(&dir.join("timing_claims.csv"), &claim_table(&[result]))?;
            let path = dir.join("timing.json");
            let json = serde_json::to_string_pretty(&serde_json::json!({
                "header": &reproduction.header,
                "timing": timing,
                "claims": &result.claims,
            }))
            .map_err(|e| ReportError::write(&path, e))?;
            write_text(&path, &(json + "\n"))?;
        }
    }
    write_text(&dir.join("report.md"), &markdown(reproduction))?;
    Ok(())
}

fn verdict_badge(verdict: Verdict) -> &'static str {
    match verdict {
        Verdict::Holds => "**holds**",
        Verdict::DoesNotHold => "**does not hold**",
        Verdict::NotEvaluated => "*not evaluated*",
    }
}

fn markdown(reproduction: &Reproduction) -> String {
    let h = &reproduction.header;
    let mut out = String::new();
    let _ = writeln!(
        out,
        "# The paper's simulation experiments, reproduced\n\nHu, Li & Tan, *Research on a Camera Position Measurement Method based on a Parallel Perspective Error Transfer Model*: every simulation experiment of §4.3 (and the simulated version of its real-image protocol) regenerated on this implementation, and each claim the paper makes about them checked by an explicit numeric rule.\n"
    );
    let _ = writeln!(out, "| | |\n|---|---|");
    let _ = writeln!(out, "| command | `{}` |", h.command);
    let _ = writeln!(out, "| layout-opt | {} |", h.version);
    let _ = writeln!(out, "| seed | {} |", h.seed);
    let _ = writeln!(
        out,
        "| mode | {} |",
        if h.quick {
            "`--quick` (few trials: verdicts are noisy)"
        } else {
            "default trial counts"
        }
    );
    let trials: Vec<String> = h
        .trials
        .iter()
        .map(|t| match t.paper_trials {
            Some(paper) => format!("{} {} (paper {paper})", t.experiment.name(), t.trials),
            None => format!(
                "{} {} (paper: one real image per pose)",
                t.experiment.name(),
                t.trials
            ),
        })
        .collect();
    let _ = writeln!(out, "| trials per setting | {} |", trials.join("; "));
    let _ = writeln!(out, "| solvers | {} |", h.solvers.join(", "));
    let _ = writeln!(
        out,
        "| the paper's solvers not in this build | {} |",
        if h.paper_solvers_not_available.is_empty() {
            "none".to_string()
        } else {
            h.paper_solvers_not_available.join(", ")
        }
    );
    let _ = writeln!(
        out,
        "| camera | the paper's (§4.2): fx {} fy {} cx {} cy {}, no distortion |",
        h.camera.fx(),
        h.camera.fy(),
        h.camera.cx(),
        h.camera.cy()
    );
    let _ = writeln!(
        out,
        "| noise | isotropic Gaussian; the paper's \"variance 0.2\" is taken as σ = √0.2 = {:.4} px; its noise sweep \"0~10 pixels, step 0.5\" as σ = 0.5…10 px |",
        h.paper_sigma_px
    );
    let _ = writeln!(out, "| errors | E_rot (eq. 33, the largest angle between corresponding columns of R and R_true, °) and E_t = 100·‖t − t_true‖/‖t_true‖ (%), averaged over trials as the paper does; the CSV files add medians and the geodesic angle |");
    let _ = writeln!(
        out,
        "| gross failure | geodesic rotation error > {}° |",
        h.gross_error_deg
    );
    let _ = writeln!(out, "| solver names | `parallel` is paraperspective alone (the paper's \"Parallel\", no GN); `parallel-weighted` is the paper's method (\"Parallel weight\"); `parallel-gn` is our ablation of it with unit weights, used to test what the weights of eq. 30 contribute; `iepnp`, `ml` (maximum likelihood, reaches the first-order limit) and any solver the paper does not compare are shown beside |\n");

    let _ = writeln!(out, "## Claims at a glance\n");
    let mut glance = Table::new(["#", "claim", "source", "verdict", "key figures"]);
    let mut counts = [0usize; 3];
    for result in &reproduction.experiments {
        for claim in &result.claims {
            counts[match claim.verdict {
                Verdict::Holds => 0,
                Verdict::DoesNotHold => 1,
                Verdict::NotEvaluated => 2,
            }] += 1;
            let cell = |text: &str| text.replace('|', "\\|");
            glance.row([
                format!("`{}`", claim.id),
                cell(&claim.statement),
                cell(&claim.source),
                verdict_badge(claim.verdict).to_string(),
                cell(&claim.evidence),
            ]);
        }
    }
    let _ = writeln!(
        out,
        "{} claims: {} hold, {} do not hold, {} not evaluated.\n",
        counts.iter().sum::<usize>(),
        counts[0],
        counts[1],
        counts[2]
    );
    out.push_str(&glance.markdown());
    let _ = writeln!(out, "\n## How verdicts are decided\n");
    out.push_str(&claims::criteria_markdown());

    for result in &reproduction.experiments {
        let _ = writeln!(
            out,
            "\n## {}. {}\n",
            result.experiment.number(),
            result.experiment.title()
        );
        for line in &result.setup {
            let _ = writeln!(out, "- {line}");
        }
        out.push('\n');
        for panel in &result.panels {
            let _ = writeln!(out, "### {} — {}\n", panel.figure, panel.title);
            let _ = writeln!(
                out,
                "![{0} rotation]({1}_rotation.svg)\n![{0} translation]({1}_translation.svg)\n",
                panel.figure, panel.id
            );
            let stride = panel.x.len().div_ceil(21);
            let _ = writeln!(out, "Mean E_rot (°):\n");
            out.push_str(&panel.markdown_table(Metric::Rotation, stride));
            let _ = writeln!(
                out,
                "\n<details><summary>Mean E_t (%)</summary>\n\n{}\n</details>\n",
                panel.markdown_table(Metric::Translation, stride)
            );
        }
        out.push_str(&result.extra_markdown);
        let _ = writeln!(out, "\n### Claims\n");
        for claim in &result.claims {
            let _ = writeln!(
                out,
                "- {} — {} ({})  \n  *Criterion:* {}  \n  *Result:* {}",
                verdict_badge(claim.verdict),
                claim.statement,
                claim.source,
                claim.criterion,
                claim.evidence
            );
        }
    }
    let _ = writeln!(out, "\n## Files\n");
    let _ = writeln!(out, "- `summary.json`: every deterministic number above (header, curves, claims); `claims.csv`: the claims of the deterministic experiments;");
    let _ = writeln!(out, "- `<experiment>.csv`: long format, one row per (panel, x, solver) with trials, poses, errors, gross failures, mean and median E_rot, mean and RMS geodesic error, mean and median E_t, and the first-order limit;");
    let _ = writeln!(out, "- `<figure>_rotation.svg`, `<figure>_translation.svg`: one plot per figure of the paper, log y axis;");
    let _ = writeln!(out, "- `timing.csv`, `timing_claims.csv`, `timing.json`, `run.json`: machine-dependent (timings, wall times); everything else is bit-identical for the same seed at any thread count.");
    let walls: Vec<String> = reproduction
        .wall_seconds
        .iter()
        .map(|(e, s)| format!("{} {s:.1} s", e.name()))
        .collect();
    let _ = writeln!(
        out,
        "\nTables show 3 significant digits; the CSV files hold 7. Wall time of this run on {} rayon threads: {} (also in `run.json`).",
        rayon::current_num_threads(),
        walls.join(", ")
    );
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn config(experiments: &str, trials: Option<usize>, quick: bool) -> Config {
        Config {
            experiments: parse_experiments(experiments).unwrap(),
            seed: 7,
            trials,
            quick,
        }
    }

    #[test]
    fn only_the_reference_run_defaults_to_reports_paper() {
        let dir = |c: Config| c.default_out_dir().display().to_string();
        assert_eq!(dir(config("all", None, false)), "reports/paper");
        assert_eq!(dir(config("all", None, true)), "reports/paper-quick");
        assert_eq!(
            dir(config("all", Some(20), false)),
            "reports/paper-trials-20"
        );
        assert_eq!(dir(config("timing", None, false)), "reports/paper-timing");
        assert_eq!(
            dir(config("depth,noise", None, true)),
            "reports/paper-quick-noise-depth"
        );
    }

    #[test]
    fn estimate_scales_with_trials_and_threads() {
        let full = config("noise", None, false);
        assert!((full.estimate_seconds(2) - 16.3).abs() < 1e-9);
        assert!((full.estimate_seconds(4) - 8.15).abs() < 1e-9);
        let fewer = config("noise", Some(50), false);
        assert!((fewer.estimate_seconds(2) - 1.63).abs() < 1e-9);
        // Timing runs on one thread whatever the pool.
        let timing = config("timing", None, false);
        assert_eq!(timing.estimate_seconds(2), timing.estimate_seconds(8));
    }
}
