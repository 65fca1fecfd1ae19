//! `layout-opt export`: a printable, watertight marker mesh (STL, OBJ,
//! glTF, GLB) and its fabrication sheet.

use super::common::naming_file;
use super::{progress, GlobalOptions};
use anyhow::Context;
use clap::Args;
use layout_opt::layout::{Layout, ObjImport};
use layout_opt::mesh::geometry::{
    Bed, Structure, DEFAULT_MIN_FEATURE_MM, DEFAULT_STRUT_DIAMETER_MM,
};
use layout_opt::mesh::summary::summary;
use layout_opt::mesh::view_cone::view_cone_deg;
use layout_opt::mesh::workflow::{self, ExportConfig};
use layout_opt::mesh::{Axis, ExportError, ExportOptions, Format, MarkerOptions, MountHoles};
use layout_opt::scenario::Range;
use layout_opt::visibility::{MaxHidden, RangeAxes, WorkingRange};
use std::path::PathBuf;

/// Flags of `export`.
#[derive(Debug, Args)]
pub struct ExportArgs {
    /// Layout file: JSON (see README), or OBJ (a point set, or one object
    /// per sphere), or a set file (layout-opt-set): every marker, numbered.
    /// Without it, the paper's biprism.
    #[arg(value_name = "LAYOUT")]
    layout: Option<PathBuf>,
    /// Formats to write, comma-separated: stl (mm, Z up), 3mf (mm, Z up,
    /// for slicers), obj (mm, marker frame), gltf (.gltf + .bin, m, Y up),
    /// glb (m, Y up).
    #[arg(long, value_delimiter = ',', default_value = "stl,3mf,obj,gltf,glb")]
    format: Vec<Format>,
    /// Output directory (created if missing).
    #[arg(long, value_name = "DIR", default_value = "build")]
    out: PathBuf,
    /// Strut diameter, mm.
    #[arg(long, value_name = "MM", default_value_t = DEFAULT_STRUT_DIAMETER_MM)]
    strut_diameter: f64,
    /// Smallest printable feature (struts, gaps, clearances), mm.
    #[arg(long, value_name = "MM", default_value_t = DEFAULT_MIN_FEATURE_MM)]
    min_feature: f64,
    /// Meshing grid spacing, mm (default 0.5, finer if a feature needs it).
    #[arg(long, value_name = "MM")]
    resolution: Option<f64>,
    /// Main viewing direction: the camera looks along it (+z: the base
    /// attitude of docs/formats.md, "Conventions"). Struts are routed so as
    /// not to cover spheres seen from there.
    #[arg(
        long,
        value_name = "AXIS",
        default_value = "+z",
        allow_hyphen_values = true
    )]
    view: Axis,
    /// Mount axis: the stub and base plate go this way; it points down on
    /// the print bed.
    #[arg(
        long,
        value_name = "AXIS",
        default_value = "-y",
        allow_hyphen_values = true
    )]
    mount: Axis,
    /// Clearance holes through the base plate, e.g. M3 (two) or M3x4 (four).
    #[arg(long, value_name = "SCREW")]
    mount_holes: Option<MountHoles>,
    /// Sphere diameter, mm: for OBJ point sets, or to override the layout's.
    #[arg(long, value_name = "MM")]
    sphere_diameter: Option<f64>,
    /// How the spheres are held: pillars (prints without support material:
    /// a base plate behind the spheres on the bed, a support rising to each
    /// sphere) or routed (the earlier strut tree with a stub and a small
    /// plate along --mount; needs support material).
    #[arg(long, value_name = "KIND", default_value = "pillars")]
    structure: Structure,
    /// Half-angle of the cone of viewing directions around --view, degrees:
    /// supports are chosen so as not to cover spheres from it, and a strut
    /// that does is an error unless --allow-occlusion.
    /// Default: from --tilt and --pan when given, else 20°.
    #[arg(long, value_name = "DEG", conflicts_with_all = ["tilt", "pan"])]
    view_cone: Option<f64>,
    /// Tilts about X the marker will be seen at, degrees (a range as in
    /// validate, e.g. -30..30:10 or -20,35): the view cone becomes the
    /// largest angle between the main view and a view of the range.
    #[arg(long, value_name = "RANGE", allow_hyphen_values = true, value_parser = boxed_range)]
    tilt: Option<Box<Range>>,
    /// Pans about Y the marker will be seen at, degrees (with --tilt or
    /// alone).
    #[arg(long, value_name = "RANGE", allow_hyphen_values = true, value_parser = boxed_range)]
    pan: Option<Box<Range>>,
    /// Write the files even when a strut covers a sphere from the view cone.
    #[arg(long)]
    allow_occlusion: bool,
    #[command(flatten)]
    range: Box<WorkingRangeArgs>,
    /// The printer's build volume X,Y,Z, mm; a part that does not fit is an
    /// error.
    #[arg(long, value_name = "X,Y,Z", default_value = "250,210,210")]
    bed: Bed,
}

/// The working range's flags (boxed, so that `export`'s flags stay small).
#[derive(Debug, Args)]
struct WorkingRangeArgs {
    /// Depths of the working range, mm (as in validate): when given, the
    /// supports are routed to hide no sphere from the range's views
    /// (--depth × --offset-x × --offset-y × --tilt × --pan, paper camera),
    /// and the views they still lose are reported. Default: the search's
    /// grid recorded in the layout's provenance, if there is one.
    #[arg(long, value_name = "RANGE", allow_hyphen_values = true, value_parser = boxed_range)]
    depth: Option<Box<Range>>,
    /// X offsets of the working range, mm (with --depth; default 0).
    #[arg(long, value_name = "RANGE", allow_hyphen_values = true, value_parser = boxed_range)]
    offset_x: Option<Box<Range>>,
    /// Y offsets of the working range, mm (with --depth; default 0).
    #[arg(long, value_name = "RANGE", allow_hyphen_values = true, value_parser = boxed_range)]
    offset_y: Option<Box<Range>>,
    /// Largest fraction of a sphere's silhouette the supports may hide in
    /// a view of the working range before the view counts as lost (0 to 1).
    #[arg(long, value_name = "FRACTION", default_value = "0.01")]
    max_hidden: MaxHidden,
}

/// A range, boxed so that `export`'s flags stay small.
fn boxed_range(text: &str) -> Result<Box<Range>, String> {
    text.parse::<Range>()
        .map(Box::new)
        .map_err(|e| e.to_string())
}

fn load_layout(args: &ExportArgs) -> anyhow::Result<(Layout, String)> {
    let Some(path) = &args.layout else {
        let mut layout = Layout::paper_biprism();
        if let Some(d) = args.sphere_diameter {
            layout.sphere_diameter_mm = d;
        }
        return Ok((layout, "the paper's biprism (built in)".to_string()));
    };
    let is_obj = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("obj"));
    let mut layout = if is_obj {
        naming_file(
            Layout::from_obj(
                path,
                &ObjImport {
                    sphere_diameter_mm: args.sphere_diameter,
                    name: None,
                },
            ),
            "layout",
            path,
        )?
    } else {
        naming_file(Layout::load(path), "layout", path)?
    };
    if let Some(d) = args.sphere_diameter {
        layout.sphere_diameter_mm = d;
    }
    Ok((layout, path.display().to_string()))
}

/// The working range of `--depth` and the other grid flags, if given;
/// else the search's range recorded in the layout's provenance.
fn working_range(args: &ExportArgs, layout: &Layout) -> anyhow::Result<Option<WorkingRange>> {
    let given = RangeAxes {
        depth: args.range.depth.as_deref().cloned(),
        offset_x: args.range.offset_x.as_deref().cloned(),
        offset_y: args.range.offset_y.as_deref().cloned(),
        tilt: args.tilt.as_deref().cloned(),
        pan: args.pan.as_deref().cloned(),
    };
    let range = given.working_range(layout, args.range.max_hidden)?;
    anyhow::ensure!(
        range.is_some() || (given.offset_x.is_none() && given.offset_y.is_none()),
        "--offset-x and --offset-y set the working range: give --depth too"
    );
    Ok(range)
}

pub fn run(args: ExportArgs, global: &GlobalOptions) -> anyhow::Result<()> {
    if let Some(path) = args
        .layout
        .as_ref()
        .filter(|p| super::export_set::is_set_file(p))
    {
        anyhow::ensure!(
            args.sphere_diameter.is_none(),
            "--sphere-diameter does not apply to a set: its layouts give the diameter"
        );
        let set = super::export_set::load(path)?;
        let options = export_options(&args, &set.members[0].layout)?;
        return super::export_set::run(&set, &options, &args.out, global);
    }
    let (layout, source) = load_layout(&args)?;
    let options = export_options(&args, &layout)?;
    let config = ExportConfig {
        layout,
        options,
        out_dir: args.out.clone(),
        sources: args
            .layout
            .iter()
            .map(|path| ("LAYOUT".to_string(), path.clone()))
            .collect(),
    };
    let mut bars = progress::Bars::new(global.quiet);
    let result = workflow::run(&config, &mut bars);
    bars.finish();
    if let Err(ExportError::Interrupted) = result {
        let kept = "interrupted: none of the export's files were written";
        return Err(layout_opt::kernel::Interrupted::keeping(kept).into());
    }
    let report = result.with_context(|| format!("cannot export {source}"))?;

    print!("{}", summary(&report));
    Ok(())
}

/// The export's options from the flags (`layout` gives the working range
/// recorded in its provenance, when the flags give none).
fn export_options(args: &ExportArgs, layout: &Layout) -> anyhow::Result<ExportOptions> {
    let view_cone = view_cone_deg(args.view_cone, args.tilt.as_deref(), args.pan.as_deref());
    anyhow::ensure!(
        args.view_cone.is_some() || view_cone < 80.0,
        "--tilt and --pan reach {view_cone:.1}° from the main view; the view cone must stay below 80°: narrow the ranges or give --view-cone"
    );
    let working_range = working_range(args, layout)?;
    Ok(ExportOptions {
        formats: args.format.clone(),
        marker: MarkerOptions {
            strut_diameter_mm: args.strut_diameter,
            min_feature_mm: args.min_feature,
            view: args.view,
            mount: args.mount,
            mount_holes: args.mount_holes.clone(),
            structure: args.structure,
            view_cone_deg: view_cone,
            bed: args.bed,
            working_views: Vec::new(),
        },
        resolution_mm: args.resolution,
        allow_occlusion: args.allow_occlusion,
        working_range,
    })
}
