//! `layout-opt track`: grey camera frames of a printed marker → labelled
//! poses with their uncertainty, one JSON line per frame.

use super::common::{naming_file, CameraArgs, StructureArgs};
use super::look::{flag, LookArgs};
use super::{progress, GlobalOptions};
use anyhow::Context;
use clap::Args;
use layout_opt::kernel::Interrupted;
use layout_opt::layout::Layout;
use layout_opt::mesh::{routed_as_recorded, Marker};
use layout_opt::pnp::Solver;
use layout_opt::render::{RenderConfig, Scene};
use layout_opt::track::config::{
    DEFAULT_MAX_AREA_PX, DEFAULT_MIN_AREA_PX, DEFAULT_MIN_CONTRAST, MAX_EXTRA_BLOBS,
};
use layout_opt::track::refine::{self, Refiner};
use layout_opt::track::workflow::{run as run_track, TrackOutputs, WorkflowError};
use layout_opt::track::{CentreMethod, Threshold, TrackConfig};
use std::path::PathBuf;

/// Flags of `track`.
#[derive(Debug, Args)]
pub struct TrackArgs {
    /// The marker's layout file (JSON); with --set, the first frame.
    #[arg(required_unless_present = "set", value_name = "LAYOUT")]
    layout: Option<PathBuf>,
    /// Frames: 8- or 16-bit greyscale PNG files, or directories of them.
    #[arg(required_unless_present = "set", value_name = "IMAGES")]
    images: Vec<PathBuf>,
    /// A set file (layout-opt-set): find every marker of the set in each
    /// frame and name it by its number and layout; all arguments are
    /// frames. JSON lines only (no --csv, --overlay).
    #[arg(long, value_name = "SET.json", conflicts_with_all = ["csv", "overlay"])]
    set: Option<PathBuf>,
    #[command(flatten)]
    reading: ReadingArgs,
    /// Write the JSON lines here instead of stdout.
    #[arg(long, value_name = "FILE")]
    output: Option<PathBuf>,
    /// Also write a CSV table (one row per frame).
    #[arg(long, value_name = "FILE")]
    csv: Option<PathBuf>,
    /// Write an annotated PNG per frame into this directory.
    #[arg(long, value_name = "DIR")]
    overlay: Option<PathBuf>,
}

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
    /// Pixel σ of the blob centres for the covariance. Default: estimated
    /// from each frame's residuals.
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

pub fn run(args: TrackArgs, global: &GlobalOptions) -> anyhow::Result<()> {
    if let Some(set) = &args.set {
        let frames: Vec<PathBuf> = args.layout.iter().chain(&args.images).cloned().collect();
        anyhow::ensure!(!frames.is_empty(), "--set needs frames (IMAGES)");
        return super::track_set::run(
            set,
            &frames,
            args.output.as_deref(),
            global,
            &|layout| configure(&args.reading, layout),
            &|layout, config| refiner(&args.reading, layout, config),
        );
    }
    let layout_path = args
        .layout
        .clone()
        .expect("clap requires LAYOUT without --set");
    let layout = naming_file(Layout::load(&layout_path), "layout", &layout_path)?;
    let config = configure(&args.reading, &layout)?;
    let refiner = refiner(&args.reading, &layout, &config)?;
    let outputs = TrackOutputs {
        sources: vec![("LAYOUT".into(), layout_path.clone())],
        json_lines: args.output.clone(),
        csv: args.csv.clone(),
        overlay_dir: args.overlay.clone(),
    };
    let mut bars = progress::Bars::new(global.quiet);
    let result = run_track(&config, refiner.as_ref(), &args.images, &outputs, &mut bars);
    bars.finish();
    let run = match result {
        Ok(run) => run,
        Err(WorkflowError::Interrupted) => return Err(Interrupted::nothing_written().into()),
        Err(error) => return Err(error).context("track"),
    };
    for (name, analysis) in &run.frames {
        if let Err(error) = &analysis.outcome {
            eprintln!("{name}: {error}");
        }
    }
    let refined = match &refiner {
        Some(_) => format!(
            ", refined by {} render round(s)",
            args.reading.refine_rounds
        ),
        None => String::new(),
    };
    let (compared, unlike) = run.unlike_spheres();
    if unlike > 0 {
        eprintln!("warning: --refine: the render was unlike the frame around {unlike} of {compared} spheres, which kept their measured centres (refinement.likeness in the records); give the look the camera sees (--preset, the radiances, --blur) and the part's structure flags");
    }
    let layout_name = match layout.characterised() {
        Some(how) => format!("{} ({how})", layout.name),
        None => layout.name.clone(),
    };
    let summary = format!(
        "tracked {} of {} frames with {} ({} spheres of {} mm, {} centres, {} solver{refined})",
        run.tracked(),
        run.frames.len(),
        layout_name,
        config.object.len(),
        config.sphere_diameter_mm,
        config.centre.name(),
        config.solver
    );
    match &args.output {
        Some(path) => eprintln!("{summary}; wrote {}", path.display()),
        None => {
            print!("{}", run.json_lines);
            eprintln!("{summary}");
        }
    }
    Ok(())
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
        .map_err(|e| anyhow::anyhow!("{}: {}", flag(e.field), e.reason))?;
    Ok(Some(refiner))
}
