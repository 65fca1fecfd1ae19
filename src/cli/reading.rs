//! How `track` and `characterise` read frames: the flags of the camera,
//! the detector, the centres, the identification and the render-and-compare
//! refinement, turned into a checked [`TrackConfig`] and a [`Refiner`].

use super::common::{CameraArgs, StructureArgs};
use super::look::{flag, LookArgs};
use anyhow::Context;
use clap::Args;
use layout_opt::layout::Layout;
use layout_opt::mesh::{routed_as_recorded, Marker};
use layout_opt::pnp::Solver;
use layout_opt::render::{RenderConfig, Scene};
use layout_opt::track::config::{
    DEFAULT_MAX_AREA_PX, DEFAULT_MIN_AREA_PX, DEFAULT_MIN_CONTRAST, MAX_EXTRA_BLOBS,
};
use layout_opt::track::refine::{self, Refiner};
use layout_opt::track::{CentreMethod, Threshold, TrackConfig};

/// How frames are read: the camera, the detector, the centres, the
/// identification and the render-and-compare refinement (`track` and
/// `characterise` read frames alike).
#[derive(Debug, Args)]
pub struct ReadingArgs {
    #[command(flatten)]
    pub(super) camera: CameraArgs,
    /// Sphere diameter, mm. Default: the layout's.
    #[arg(long, value_name = "MM")]
    pub(super) sphere_diameter: Option<f64>,
    /// Threshold: auto (Otsu's level; where it leaves a blob partly hidden
    /// or misshapen, also the upper of Otsu's three-class levels, which
    /// parts white spheres from a lit grey body, keeping the reading with
    /// more whole blobs; each record names the one applied), otsu, otsu3,
    /// local (uneven light), local:RADIUS_PX:OFFSET, or a fixed level in
    /// 0..1 of full scale.
    #[arg(long, default_value = "auto")]
    pub(super) threshold: Threshold,
    /// Which blob centre feeds the pose: ellipse (fit to the subpixel edge),
    /// centroid (intensity-weighted, above a quarter of the step) or window
    /// (background-subtracted, over the fitted ellipse grown by 1.5 px: the
    /// least noisy, but pulled by the part behind the limb; use it with
    /// --refine).
    #[arg(long, default_value = "ellipse")]
    pub(super) centre: CentreMethod,
    /// Solver of the final pose; ml fits the exact sphere-image model, the
    /// others fit the projected sphere centres.
    #[arg(long, default_value = "ml")]
    pub(super) solver: Solver,
    /// Pixel σ of the blob centres for the covariance, one for all.
    /// Default: each centre's own from its blob (its pixels' noise, grown
    /// where the pose's residuals exceed it, and the mismatch between its
    /// two centres).
    #[arg(long, value_name = "PX")]
    pub(super) sigma_px: Option<f64>,
    /// Identification gate, px.
    #[arg(long, value_name = "PX", default_value_t = layout_opt::batch::DEFAULT_GATE_PX)]
    pub(super) gate_px: f64,
    /// Blobs tolerated beyond the spheres (clutter, reflections).
    #[arg(long, default_value_t = 2, value_name = "N")]
    pub(super) max_extra_blobs: usize,
    /// Smallest blob, px.
    #[arg(long, default_value_t = DEFAULT_MIN_AREA_PX, value_name = "PX")]
    pub(super) min_area: usize,
    /// Largest blob, px.
    #[arg(long, default_value_t = DEFAULT_MAX_AREA_PX, value_name = "PX")]
    pub(super) max_area: usize,
    /// Least blob contrast, fraction of full scale.
    #[arg(long, default_value_t = DEFAULT_MIN_CONTRAST, value_name = "FRACTION")]
    pub(super) min_contrast: f64,
    /// Refuse a frame whose labels are wrong with a larger predicted
    /// probability (the identifiability model's bar is 1e-3).
    #[arg(long, value_name = "P")]
    pub(super) max_wrong_labels: Option<f64>,
    /// Render-and-compare: render the part at each frame's pose, read the
    /// render with the same detector, take each sphere's bias (the part
    /// behind its limb) off its centre and solve again. The part and its
    /// look come from the flags below, as for `render`; they must be what
    /// the camera sees. With --set, each marker found is refined with its
    /// own part alone.
    #[arg(long)]
    pub(super) refine: bool,
    /// Rounds of --refine.
    #[arg(long, value_name = "N", default_value_t = 1, requires = "refine")]
    pub(super) refine_rounds: u32,
    #[command(flatten)]
    #[command(next_help_heading = "The part and its look, for --refine")]
    pub(super) structure: StructureArgs,
    #[command(flatten)]
    pub(super) look: LookArgs,
}

/// The flag of a config field, for error messages.
fn flag_of(field: &str) -> &str {
    match field {
        "sphere_diameter_mm" => "--sphere-diameter",
        "threshold" => "--threshold",
        "min_area_px" => "--min-area",
        "max_area_px" => "--max-area",
        "min_contrast" => "--min-contrast",
        "sigma_px" => "--sigma-px",
        "gate_px" => "--gate-px",
        "max_extra_blobs" => "--max-extra-blobs",
        "max_wrong_labels" => "--max-wrong-labels",
        "object" => "LAYOUT",
        other => other,
    }
}

/// The tracking configuration of `layout` from the flags, checked.
pub(super) fn configure(args: &ReadingArgs, layout: &Layout) -> anyhow::Result<TrackConfig> {
    let camera = args.camera.camera()?;
    let mut config = TrackConfig::new(layout, camera);
    if let Some(diameter) = args.sphere_diameter {
        config.sphere_diameter_mm = diameter;
    }
    config.detector.threshold = args.threshold;
    config.detector.min_area_px = args.min_area;
    config.detector.max_area_px = args.max_area;
    config.detector.min_contrast = args.min_contrast;
    config.centre = args.centre;
    config.solver = args.solver;
    config.sigma_px = args.sigma_px;
    config.gate_px = args.gate_px;
    config.max_extra_blobs = args.max_extra_blobs;
    if let Some(p) = args.max_wrong_labels {
        config.max_wrong_labels = p;
    }
    if let Err(error) = config.validate() {
        anyhow::bail!("{}: {}", flag_of(error.field), error.reason);
    }
    anyhow::ensure!(
        config.max_extra_blobs <= MAX_EXTRA_BLOBS,
        "--max-extra-blobs must be at most {MAX_EXTRA_BLOBS}"
    );
    Ok(config)
}

/// The render-and-compare refiner the flags ask for, if any.
pub(super) fn refiner(
    args: &ReadingArgs,
    layout: &Layout,
    config: &TrackConfig,
) -> anyhow::Result<Option<Refiner>> {
    if !args.refine {
        anyhow::ensure!(
            !args.look.any_given(),
            "the look flags (--preset, --blur, …) describe the render of --refine; give --refine too"
        );
        return Ok(None);
    }
    // The part with the spheres the tracker assumes (--sphere-diameter).
    let part = Layout {
        sphere_diameter_mm: config.sphere_diameter_mm,
        ..layout.clone()
    };
    let options = routed_as_recorded(&part, args.structure.marker_options())?;
    let marker = Marker::design(&part, &options).context("cannot build the part for --refine")?;
    let mut render = RenderConfig::new(config.camera);
    render.appearance = args.look.appearance();
    render.optics = args.look.optics(refine::DEFAULT_SUPERSAMPLING);
    let refiner = Refiner::new(Scene::from_marker(marker), render, args.refine_rounds)
        .map_err(|e| anyhow::anyhow!("{}: {}", flag(e.field), e.reason))?
        .with_fitted_levels(!args.look.levels_given());
    Ok(Some(refiner))
}
