//! What a reproduction runs, checked once before any work starts: the
//! experiments, their trial counts, the seed, and the paper's constants
//! (its noise level and the solvers its tables compare).
//! [`Config::check`] refuses a bad value with a [`ConfigError`] that names
//! the field.

use super::ReproduceError;
use crate::camera::Camera;
use crate::config::ConfigError;
use serde::Serialize;
use std::fmt::Write as _;
use std::path::Path;
use std::str::FromStr;

/// Noise draws per pose of the simulated protocol by default (1365 poses:
/// each table cell pools about 2,000 solves per solver, and the whole run
/// stays well within 15 minutes on two cores with every solver, OPnP taking
/// about 2 ms per solve).
pub const PROTOCOL_DEFAULT_TRIALS: usize = 30;

/// The paper's focal length "80" of the points, noise and off-axis
/// simulations (§4.3), read as pixels.
pub const SHORT_FOCAL_PX: f64 = 80.0;

/// The paper's focal length "500" of the depth and tilt simulations
/// (§4.3, Fig. S3), read as pixels.
pub const LONG_FOCAL_PX: f64 = 500.0;

/// Width of the simulated cameras' frame, px (the paper's sensor).
pub const SIMULATED_WIDTH: u32 = 1280;

/// Height of the simulated cameras' frame, px (the paper's sensor).
pub const SIMULATED_HEIGHT: u32 = 720;

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
    /// 2 threads on the shared 2-core machine, load average 9–15 while
    /// other builds ran; a quiet machine takes about half): the cost model
    /// behind [`Config::estimate_seconds`]. Protocol includes its two σ
    /// calibration passes.
    pub fn reference_seconds(self) -> f64 {
        match self {
            Experiment::Points => 13.0,
            Experiment::Noise => 158.7,
            Experiment::Timing => 108.1,
            Experiment::Depth => 44.8,
            Experiment::OffAxis => 32.3,
            Experiment::Tilt => 123.1,
            Experiment::Protocol => 339.7,
        }
    }

    /// The camera the paper simulated this experiment with: f = 80 px for
    /// the points, noise and off-axis experiments (§4.3, Figs. 7–9, S1–S2;
    /// timing, whose time does not depend on the camera, shares it),
    /// f = 500 px for depth and tilt (Figs. 11–14, S3), and the §4.2 real
    /// camera for the simulated real-image protocol. The simulated cameras
    /// have square pixels, the paper's 1280×720 frame and the principal
    /// point at its centre (the paper gives neither): every point of the
    /// points, noise and tilt experiments projects inside that frame
    /// (|x/z| ≤ 1 at f = 80, |x/z| ≤ 0.11 at f = 500). No distortion.
    pub fn paper_camera(self) -> Camera {
        let focal = match self {
            Experiment::Points | Experiment::Noise | Experiment::OffAxis | Experiment::Timing => {
                SHORT_FOCAL_PX
            }
            Experiment::Depth | Experiment::Tilt => LONG_FOCAL_PX,
            Experiment::Protocol => return Camera::paper(),
        };
        Camera::new(
            focal,
            focal,
            f64::from(SIMULATED_WIDTH) / 2.0,
            f64::from(SIMULATED_HEIGHT) / 2.0,
            SIMULATED_WIDTH,
            SIMULATED_HEIGHT,
            [0.0; 5],
        )
        .expect("the paper's simulated cameras are valid")
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
    /// One camera for every experiment instead of each experiment's own
    /// ([`Experiment::paper_camera`]).
    pub camera: Option<Camera>,
}

impl Config {
    /// The camera `experiment` runs with: the override, else the paper's.
    pub fn camera_for(&self, experiment: Experiment) -> Camera {
        self.camera.unwrap_or_else(|| experiment.paper_camera())
    }

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

impl Config {
    /// Refuses zero trials and an empty experiment list.
    pub fn check(&self) -> Result<(), ConfigError> {
        if self.trials == Some(0) {
            return Err(ConfigError::new("trials", "must be at least 1"));
        }
        if self.experiments.is_empty() {
            return Err(ConfigError::new(
                "experiments",
                "name at least one experiment",
            ));
        }
        Ok(())
    }
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
            camera: None,
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
    fn every_experiment_has_its_documented_focal_length() {
        let focal = |e: Experiment| e.paper_camera().fx();
        for e in [Experiment::Points, Experiment::Noise, Experiment::OffAxis] {
            assert_eq!(focal(e), 80.0, "{e}");
        }
        for e in [Experiment::Depth, Experiment::Tilt] {
            assert_eq!(focal(e), 500.0, "{e}");
        }
        assert_eq!(Experiment::Protocol.paper_camera(), Camera::paper());
        for e in Experiment::ALL
            .into_iter()
            .filter(|&e| e != Experiment::Protocol)
        {
            let camera = e.paper_camera();
            assert_eq!(camera.fx(), camera.fy(), "{e}");
            assert_eq!((camera.cx(), camera.cy()), (640.0, 360.0), "{e}");
        }
        let mut overridden = config("points,tilt", None, true);
        overridden.camera = Some(Camera::paper());
        assert_eq!(overridden.camera_for(Experiment::Tilt), Camera::paper());
        assert_eq!(
            config("tilt", None, true).camera_for(Experiment::Tilt).fx(),
            500.0
        );
    }

    #[test]
    fn estimate_scales_with_trials_and_threads() {
        // The reference time itself, half of it on twice the threads, a
        // tenth of it at a tenth of the trials.
        let reference = Experiment::Noise.reference_seconds();
        let full = config("noise", None, false);
        assert!((full.estimate_seconds(2) - reference).abs() < 1e-9);
        assert!((full.estimate_seconds(4) - reference / 2.0).abs() < 1e-9);
        let fewer = config("noise", Some(50), false);
        assert!((fewer.estimate_seconds(2) - reference / 10.0).abs() < 1e-9);
        // Timing runs on one thread whatever the pool.
        let timing = config("timing", None, false);
        assert_eq!(timing.estimate_seconds(2), timing.estimate_seconds(8));
    }
}
