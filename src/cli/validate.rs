//! `layout-opt validate`: a layout's sensitivity report.

use super::common::{
    command_line, naming_file, parse_probability, parse_solvers, CameraArgs, GridArgs,
};
use super::noise_model::NoiseModelArg;
use super::validate_images::{image_flag, ImageArgs};
use super::volume::{volume_flag, VolumeArgs, VolumeDefaults};
use super::{progress, GlobalOptions};
use anyhow::Context;
use clap::Args;
use layout_opt::config::ConfigError;
use layout_opt::layout::Layout;
use layout_opt::mesh::MarkerOptions;
use layout_opt::montecarlo::{MonteCarloConfig, DEFAULT_GROSS_THRESHOLD_DEG};
use layout_opt::scenario::ScenarioGrid;
use layout_opt::sphere_image::Observation;
use layout_opt::validate::config::default_tilt_step_deg;
use layout_opt::validate::image_report;
use layout_opt::validate::markdown::{budget_text, console};
use layout_opt::validate::workflow::{WorkflowConfig, WorkflowError};
use layout_opt::validate::{
    self, IdentifiabilityCheck, ValidateConfig, DEFAULT_TILT_STEP_DEG, POLYNOMIAL_TILT_STEP_DEG,
};
use layout_opt::volume::WorkingVolume;
use std::path::PathBuf;

/// Monte-Carlo trials per scenario unless `--trials` says otherwise.
pub(super) const DEFAULT_TRIALS: usize = 200;

/// Flags of `validate`.
#[derive(Debug, Args)]
pub struct ValidateArgs {
    /// Layout file (JSON). Default: the paper's biprism (L = 50 mm, 10 mm spheres).
    pub(super) layout: Option<PathBuf>,
    #[command(flatten)]
    pub(super) grid: GridArgs,
    #[command(flatten)]
    pub(super) volume: VolumeArgs,
    #[command(flatten)]
    pub(super) camera: CameraArgs,
    /// Solvers: `all` or a comma list of stable names (see `solve --list`).
    #[arg(long, default_value = "all")]
    pub(super) solvers: String,
    /// Monte-Carlo trials per scenario.
    #[arg(long, default_value_t = DEFAULT_TRIALS)]
    pub(super) trials: usize,
    /// Noise model: isotropic, per-point, size[:REF_PX] or calibrated:FILE (σ from images, docs/formats.md), each optionally +outliers:RATE[:PX].
    #[arg(long, default_value = "isotropic")]
    pub(super) noise_model: NoiseModelArg,
    /// Rotation error counted as a gross failure, degrees.
    #[arg(long, default_value_t = DEFAULT_GROSS_THRESHOLD_DEG)]
    pub(super) gross_threshold: f64,
    /// Image point of a sphere: `ellipse-centre` (its silhouette's centre,
    /// what a blob detector measures) or `centre` (its projected centre).
    /// Noise is added on top.
    #[arg(long, default_value = "ellipse-centre")]
    pub(super) observation: Observation,
    /// Monte-Carlo trials of the unlabelled solver per visible scenario: the
    /// blobs shuffled, how often it labels them wrongly (0: the prediction
    /// from the noise-free margin alone).
    #[arg(long, default_value_t = validate::DEFAULT_IDENTIFY_TRIALS)]
    pub(super) identify_trials: usize,
    /// Least predicted probability of a correct labelling for a scenario to
    /// count as identifiable (0.999 or 99.9%).
    #[arg(long, default_value = "0.999", value_name = "PROBABILITY")]
    pub(super) identify_criterion: String,
    /// Output directory. Default: reports/<layout name>/.
    #[arg(long, value_name = "DIR")]
    pub(super) out: Option<PathBuf>,
    /// Sphere-centre fabrication error σ_fab, mm per coordinate: the error
    /// budget (report.md, summary.json) counts a part printed to it, first
    /// order and by a Monte-Carlo run with a new part per trial solved with
    /// the nominal layout, under --noise-model. 0 (the default): a
    /// characterised layout's own covariance, or no part error.
    #[arg(long, value_name = "MM", default_value_t = 0.0)]
    pub(super) fabrication_sigma: f64,
    /// 1σ of the camera's intrinsics for the error budget, px:
    /// fx=…,fy=…,cx=…,cy=… (a name left out is 0).
    #[arg(long, value_name = "fx=PX,fy=PX,cx=PX,cy=PX")]
    pub(super) camera_sigma: Option<layout_opt::error_model::budget::IntrinsicSigma>,
    /// The largest fraction (0–1) of a sphere's silhouette that the part's
    /// own supports may hide while the sphere still counts as seen.
    #[arg(long, value_name = "FRACTION", default_value_t = layout_opt::visibility::DEFAULT_MAX_HIDDEN)]
    pub(super) max_hidden: f64,
    /// Leave the part's supports out: only the spheres hide each other (the
    /// behaviour before the supports were modelled).
    #[arg(long)]
    pub(super) no_supports: bool,
    #[command(flatten)]
    pub(super) images: ImageArgs,
}

/// The set file (`*.set.json`) the layout argument names, if it names one:
/// `validate_set` validates it.
pub fn set_path(args: &ValidateArgs) -> Option<&std::path::Path> {
    args.layout
        .as_deref()
        .filter(|p| p.to_string_lossy().ends_with(".set.json"))
}

/// `validate LAYOUT` (a set file goes to `validate_set` instead).
pub fn run(args: ValidateArgs, global: &GlobalOptions) -> anyhow::Result<()> {
    let layout = match &args.layout {
        Some(path) => naming_file(Layout::load(path), "layout", path)?,
        None => Layout::paper_biprism(),
    };
    let camera = match args.images.preset_camera() {
        Some(camera) => {
            anyhow::ensure!(
                args.camera.camera.is_none() && !args.camera.with_distortion,
                "--image-preset machine-vision brings its own camera; leave out --camera and --with-distortion"
            );
            camera
        }
        None => args.camera.camera()?,
    };
    let solvers = parse_solvers(&args.solvers)?;
    let tilt_step = default_tilt_step_deg(&solvers);
    let volume = protocol_volume(&args, tilt_step, global.seed)?;
    let grid_note = (tilt_step != DEFAULT_TILT_STEP_DEG
        && args.grid.tilt.is_none()
        && matches!(volume, WorkingVolume::Grid(_)))
    .then(|| {
        format!(
            "default tilt step {POLYNOMIAL_TILT_STEP_DEG}° instead of the paper's {DEFAULT_TILT_STEP_DEG}° because the solvers include dls or opnp; pass --tilt -90..90:{DEFAULT_TILT_STEP_DEG} for the full protocol"
        )
    });
    let min_correct =
        parse_probability(&args.identify_criterion).context("--identify-criterion")?;
    let config = WorkflowConfig {
        out_dir: args
            .out
            .clone()
            .unwrap_or_else(|| PathBuf::from("reports").join(&layout.name)),
        validate: ValidateConfig {
            layout,
            camera,
            volume,
            monte_carlo: MonteCarloConfig {
                trials: args.trials,
                seed: global.seed,
                solvers,
                noise: args.noise_model.model,
                gross_threshold_deg: args.gross_threshold,
                observation: args.observation,
            },
            identifiability: IdentifiabilityCheck {
                min_correct,
                trials: args.identify_trials,
            },
            fabrication_sigma_mm: args.fabrication_sigma,
            camera_sigma: args.camera_sigma.unwrap_or_default(),
            structure: (!args.no_supports).then(MarkerOptions::default),
            max_hidden: args.max_hidden,
            command: command_line(),
        },
        grid_note,
        // Every run is estimated (the calibration takes a fraction of a
        // second); only the slow ones say so.
        estimate: !global.quiet,
        images: args.images.check(),
        noise_model_out: args.images.noise_model_out(),
        sources: [
            ("LAYOUT", args.layout.clone()),
            ("--camera", args.camera.camera.clone()),
            ("--volume", args.volume.volume.clone()),
            ("--noise-model", args.noise_model.file.clone()),
        ]
        .into_iter()
        .filter_map(|(what, path)| Some((what.to_string(), path?)))
        .collect(),
    };
    let layout_name = &config.validate.layout.name;
    config
        .validate
        .check()
        .map_err(|e| flag_error(e, layout_name))?;
    config.check().map_err(|e| flag_error(e, layout_name))?;
    if let Some(note) = &config.grid_note {
        println!("note: {note}");
    }
    if let Some(how) = config.validate.layout.characterised() {
        println!("layout {layout_name}: {how}");
    }
    let mut bars = progress::Bars::new(global.quiet);
    let result = validate::workflow::run(&config, &mut bars);
    bars.finish();
    if let Some(message) = result.as_ref().err().and_then(WorkflowError::interrupted) {
        return Err(layout_opt::kernel::Interrupted::keeping(message).into());
    }
    let outcome = result?;
    print!("{}", console(&outcome.summary, &config.out_dir));
    if let Some(images) = &outcome.summary.images {
        print!("{}", image_report::console(images));
    }
    if let Some(path) = &config.noise_model_out {
        println!("noise model written to {}", path.display());
    }
    println!("{}", outcome.timing_line(&config.out_dir));
    if let Some(budget) = &outcome.summary.overview.error_budget {
        print!("{}", budget_text(budget));
    }
    Ok(())
}

/// A configuration error in the words of the command line: the field's
/// flag, or the layout's name.
fn flag_error(error: ConfigError, layout: &str) -> anyhow::Error {
    if let Some(flag) = image_flag(error.field) {
        return anyhow::anyhow!("{flag} {}", error.reason);
    }
    if let Some(flag) = volume_flag(&error) {
        return anyhow::anyhow!("{flag} {}", error.reason);
    }
    let flag = match error.field {
        "layout" => return anyhow::anyhow!("layout {layout}: {}", error.reason),
        "solvers" => "--solvers",
        "trials" => "--trials",
        "gross_threshold_deg" => "--gross-threshold",
        "min_correct" => "--identify-criterion",
        "fabrication_sigma_mm" => "--fabrication-sigma",
        "max_hidden" => "--max-hidden",
        other => other,
    };
    anyhow::anyhow!("{flag} {}", error.reason)
}

/// The volume the flags give, by default the paper's protocol grid with
/// tilts `tilt_step_deg` apart.
pub(super) fn protocol_volume(
    args: &ValidateArgs,
    tilt_step_deg: f64,
    seed: u64,
) -> anyhow::Result<WorkingVolume> {
    let paper = ScenarioGrid::paper_protocol(tilt_step_deg);
    args.volume.volume(
        &args.grid,
        VolumeDefaults {
            grid: paper.clone(),
            volume: WorkingVolume::Grid(paper),
        },
        seed,
    )
}
