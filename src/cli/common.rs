//! Flags shared by the commands that run scenarios: the camera, the
//! scenario grid and the solvers.

use clap::Args;
use layout_opt::camera::{self, Camera};
use layout_opt::mesh::geometry::{
    Bed, Structure, DEFAULT_MIN_FEATURE_MM, DEFAULT_STRUT_DIAMETER_MM, DEFAULT_VIEW_CONE_DEG,
};
use layout_opt::mesh::{Axis, MarkerOptions, MountHoles};
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
            (Some(path), false) => naming_file(camera::load(path), "camera", path),
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

impl GridArgs {
    /// Whether any grid flag was given.
    pub fn any_given(&self) -> bool {
        [
            &self.depth,
            &self.offset_x,
            &self.offset_y,
            &self.tilt,
            &self.pan,
            &self.roll,
            &self.noise,
        ]
        .iter()
        .any(|r| r.is_some())
    }
}

/// How `export` builds the part, for commands that need the same part
/// (`render`).
#[derive(Debug, Clone, Args)]
pub struct StructureArgs {
    /// How the spheres are held: pillars (a base plate behind the spheres,
    /// a support rising to each) or routed (a strut tree with a stub).
    #[arg(long, value_name = "KIND", default_value = "pillars")]
    pub structure: Structure,
    /// Strut diameter, mm.
    #[arg(long, value_name = "MM", default_value_t = DEFAULT_STRUT_DIAMETER_MM)]
    pub strut_diameter: f64,
    /// Smallest printable feature (struts, gaps, clearances), mm.
    #[arg(long, value_name = "MM", default_value_t = DEFAULT_MIN_FEATURE_MM)]
    pub min_feature: f64,
    /// Main viewing direction the supports are routed for.
    #[arg(
        long,
        value_name = "AXIS",
        default_value = "+z",
        allow_hyphen_values = true
    )]
    pub view: Axis,
    /// Mount axis: the stub and base plate go this way.
    #[arg(
        long,
        value_name = "AXIS",
        default_value = "-y",
        allow_hyphen_values = true
    )]
    pub mount: Axis,
    /// Clearance holes through the base plate, e.g. M3 or M3x4.
    #[arg(long, value_name = "SCREW")]
    pub mount_holes: Option<MountHoles>,
    /// Half-angle of the cone of views the supports are routed for, degrees.
    #[arg(long, value_name = "DEG", default_value_t = DEFAULT_VIEW_CONE_DEG)]
    pub view_cone: f64,
    /// The printer's build volume X,Y,Z, mm.
    #[arg(long, value_name = "X,Y,Z", default_value = "250,210,210")]
    pub bed: Bed,
}

impl StructureArgs {
    /// The marker options these flags name.
    pub fn marker_options(&self) -> MarkerOptions {
        MarkerOptions {
            strut_diameter_mm: self.strut_diameter,
            min_feature_mm: self.min_feature,
            view: self.view,
            mount: self.mount,
            mount_holes: self.mount_holes.clone(),
            structure: self.structure,
            view_cone_deg: self.view_cone,
            bed: self.bed,
            working_views: Vec::new(),
        }
    }
}

/// A share given as `0.999`, `99.9%` or `none`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IdentifiabilityShare(pub Option<f64>);

impl std::str::FromStr for IdentifiabilityShare {
    type Err = String;
    fn from_str(text: &str) -> Result<Self, Self::Err> {
        let text = text.trim();
        if text == "none" {
            return Ok(Self(None));
        }
        layout_opt::config::parse_share(text)
            .map(|share| Self(Some(share)))
            .ok_or_else(|| {
                format!("'{text}' is not a share between 0 and 1 (0.999, 99.9% or none)")
            })
    }
}

/// A probability strictly between 0 and 1, as `0.999` or `99.9%`.
pub fn parse_probability(text: &str) -> anyhow::Result<f64> {
    layout_opt::config::parse_share(text)
        .filter(|&p| p > 0.0 && p < 1.0)
        .ok_or_else(|| {
            anyhow::anyhow!(
                "'{text}' is not a probability strictly between 0 and 1 (0.999 or 99.9%)"
            )
        })
}
