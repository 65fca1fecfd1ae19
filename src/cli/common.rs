//! Flags shared by the commands that run scenarios: the camera, the
//! scenario grid and the solvers.

use clap::Args;
use layout_opt::camera::Camera;
use layout_opt::pnp::Solver;
use layout_opt::scenario::{Range, ScenarioGrid};
use std::path::{Path, PathBuf};

/// Names the file in an error about it, unless the message already does:
/// "reading layout x.json: malformed layout: …", but not "reading layout
/// x.json: cannot read layout file x.json: …".
pub fn naming_file<T, E>(result: Result<T, E>, what: &str, path: &Path) -> anyhow::Result<T>
where
    E: std::error::Error + Send + Sync + 'static,
{
    result.map_err(|error| {
        let shown = path.display().to_string();
        if error.to_string().contains(&shown) {
            anyhow::Error::new(error)
        } else {
            anyhow::Error::new(error).context(format!("{what} {shown}"))
        }
    })
}

/// The camera.
#[derive(Debug, Clone, Args)]
pub struct CameraArgs {
    /// Camera file: our JSON or an OpenCV calibration YAML. Default: the
    /// paper's camera (fx 1301.47, fy 1300.93, cx 653, cy 508, 1280×720).
    #[arg(long, value_name = "FILE")]
    pub camera: Option<PathBuf>,
    /// Use the default camera's real-image distortion [-0.087355, 0.204686, 0, 0, 0]
    /// (simulations ignore distortion otherwise).
    #[arg(long)]
    pub with_distortion: bool,
}

impl CameraArgs {
    /// The camera these flags name.
    pub fn camera(&self) -> anyhow::Result<Camera> {
        match (&self.camera, self.with_distortion) {
            (Some(path), false) => naming_file(Camera::load(path), "camera", path),
            (Some(_), true) => anyhow::bail!("--with-distortion applies to the default camera; a camera file carries its own distortion"),
            (None, false) => Ok(Camera::paper()),
            (None, true) => Ok(Camera::paper_with_distortion()),
        }
    }
}

/// The scenario grid. Ranges are `A..B` (5 values), `A..B:STEP`, a single
/// value, or a comma list.
#[derive(Debug, Clone, Args)]
pub struct GridArgs {
    /// Depths of the marker origin, mm.
    #[arg(long, value_name = "RANGE", allow_hyphen_values = true)]
    pub depth: Option<Range>,
    /// X offsets of the marker origin, mm.
    #[arg(long, value_name = "RANGE", allow_hyphen_values = true)]
    pub offset_x: Option<Range>,
    /// Y offsets of the marker origin, mm.
    #[arg(long, value_name = "RANGE", allow_hyphen_values = true)]
    pub offset_y: Option<Range>,
    /// Tilts about X, degrees.
    #[arg(long, value_name = "RANGE", allow_hyphen_values = true)]
    pub tilt: Option<Range>,
    /// Pans about Y, degrees.
    #[arg(long, value_name = "RANGE", allow_hyphen_values = true)]
    pub pan: Option<Range>,
    /// Rolls about Z, degrees.
    #[arg(long, value_name = "RANGE", allow_hyphen_values = true)]
    pub roll: Option<Range>,
    /// Pixel noise σ, px.
    #[arg(long, value_name = "RANGE", allow_hyphen_values = true)]
    pub noise: Option<Range>,
}

impl GridArgs {
    /// The grid, each missing range taken from `defaults`.
    pub fn grid(&self, defaults: &ScenarioGrid) -> anyhow::Result<ScenarioGrid> {
        let pick = |given: &Option<Range>, default: &Range| {
            given.clone().unwrap_or_else(|| default.clone())
        };
        Ok(ScenarioGrid::new(
            pick(&self.depth, &defaults.depth_mm),
            pick(&self.offset_x, &defaults.offset_x_mm),
            pick(&self.offset_y, &defaults.offset_y_mm),
            pick(&self.tilt, &defaults.tilt_deg),
            pick(&self.pan, &defaults.pan_deg),
            pick(&self.roll, &defaults.roll_deg),
            pick(&self.noise, &defaults.sigma_px),
        )?)
    }
}

/// The command line as typed, for report headers.
pub fn command_line() -> String {
    let mut words: Vec<String> = std::env::args().collect();
    if let Some(first) = words.first_mut() {
        *first = "layout-opt".into();
    }
    words
        .iter()
        .map(|w| {
            if w.contains(' ') {
                format!("'{w}'")
            } else {
                w.clone()
            }
        })
        .collect::<Vec<_>>()
        .join(" ")
}

pub use layout_opt::report::{duration_text, SLOW_RUN_SECONDS};

/// Parses `all` or a comma list of solver names.
pub fn parse_solvers(text: &str) -> anyhow::Result<Vec<Solver>> {
    if text.trim() == "all" {
        return Ok(Solver::ALL.to_vec());
    }
    let mut solvers = Vec::new();
    for name in text.split(',').map(str::trim).filter(|s| !s.is_empty()) {
        let solver: Solver = name.parse().map_err(|e: String| anyhow::anyhow!(e))?;
        if !solvers.contains(&solver) {
            solvers.push(solver);
        }
    }
    anyhow::ensure!(!solvers.is_empty(), "--solvers names no solver");
    Ok(solvers)
}
