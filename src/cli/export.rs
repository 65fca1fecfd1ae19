//! `layout-opt export`: a printable, watertight marker mesh (STL, OBJ,
//! glTF, GLB) and its fabrication sheet.

use super::common::naming_file;
use super::{progress, GlobalOptions};
use anyhow::Context;
use clap::Args;
use layout_opt::layout::{Layout, ObjImport};
use layout_opt::mesh::geometry::{
    Bed, Structure, DEFAULT_MIN_FEATURE_MM, DEFAULT_STRUT_DIAMETER_MM, DEFAULT_VIEW_CONE_DEG,
};
use layout_opt::mesh::pipeline::{self, ExportConfig};
use layout_opt::mesh::{Axis, ExportError, ExportOptions, Format, MarkerOptions, MountHoles};
use layout_opt::scenario::{Range, ScenarioGrid};
use layout_opt::visibility::{MaxHidden, WorkingRange};
use std::path::{Path, PathBuf};

/// Lost views printed on the summary line.
const LOST_VIEWS_SHOWN: usize = 8;

/// Flags of `export`.
#[derive(Debug, Args)]
pub struct ExportArgs {
    /// Layout file: JSON (see README), or OBJ (a point set, or one object
    /// per sphere). Without it, the paper's biprism.
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
    /// and the views they still lose are reported.
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

fn megabytes(bytes: u64) -> String {
    if bytes >= 1 << 20 {
        format!("{:.1} MB", bytes as f64 / (1u64 << 20) as f64)
    } else {
        format!("{:.1} kB", bytes as f64 / 1024.0)
    }
}

/// The view cone's half-angle: `--view-cone`, else the largest angle
/// between the main view and the view at a tilt t and pan p of the ranges
/// given (`acos(cos t · cos p)`, the camera turned about X then Y), else
/// [`DEFAULT_VIEW_CONE_DEG`].
fn view_cone_deg(view_cone: Option<f64>, tilt: Option<&Range>, pan: Option<&Range>) -> f64 {
    if let Some(cone) = view_cone {
        return cone;
    }
    if tilt.is_none() && pan.is_none() {
        return DEFAULT_VIEW_CONE_DEG;
    }
    let zero = Range::single(0.0);
    let (tilt, pan) = (tilt.unwrap_or(&zero), pan.unwrap_or(&zero));
    let mut cone: f64 = 0.0;
    for t in &tilt.values {
        for p in &pan.values {
            let cosine = (t.to_radians().cos() * p.to_radians().cos()).clamp(-1.0, 1.0);
            cone = cone.max(cosine.acos().to_degrees());
        }
    }
    // acos(cos 25°) is 25.000000000000004°: whole nanodegrees read better.
    (cone * 1e9).round() / 1e9
}

/// The working range of `--depth` and the other grid flags, if given.
fn working_range(args: &ExportArgs) -> anyhow::Result<Option<WorkingRange>> {
    let (tilt, pan) = (args.tilt.clone(), args.pan.clone());
    let args = &args.range;
    let Some(depth) = args.depth.as_deref() else {
        anyhow::ensure!(
            args.offset_x.is_none() && args.offset_y.is_none(),
            "--offset-x and --offset-y set the working range: give --depth too"
        );
        return Ok(None);
    };
    let zero = Range::single(0.0);
    let range = |r: &Option<Box<Range>>| r.as_deref().unwrap_or(&zero).clone();
    let grid = ScenarioGrid::new(
        depth.clone(),
        range(&args.offset_x),
        range(&args.offset_y),
        range(&tilt),
        range(&pan),
        Range::single(0.0),
        Range::single(0.5),
    )?;
    Ok(Some(WorkingRange {
        camera: layout_opt::camera::Camera::paper(),
        scenarios: grid.scenarios(),
        max_hidden: args.max_hidden,
    }))
}

pub fn run(args: ExportArgs, global: &GlobalOptions) -> anyhow::Result<()> {
    let (layout, source) = load_layout(&args)?;
    let view_cone = view_cone_deg(args.view_cone, args.tilt.as_deref(), args.pan.as_deref());
    anyhow::ensure!(
        args.view_cone.is_some() || view_cone < 80.0,
        "--tilt and --pan reach {view_cone:.1}° from the main view; the view cone must stay below 80°: narrow the ranges or give --view-cone"
    );
    let working_range = working_range(&args)?;
    let options = ExportOptions {
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
    };
    let config = ExportConfig {
        layout,
        options,
        out_dir: args.out.clone(),
    };
    progress::catch_ctrl_c();
    let mut bars = progress::Bars::new(global.quiet);
    let result = pipeline::run(&config, &mut bars);
    bars.finish();
    if let Err(ExportError::Interrupted) = result {
        eprintln!("interrupted: none of the export's files were written");
        std::process::exit(super::search::EXIT_INTERRUPTED);
    }
    let report = result.with_context(|| format!("cannot export {source}"))?;

    let m = &report.mesh;
    let t = &m.topology;
    println!(
        "{}: {} triangles, {} vertices, volume {:.1} mm³, grid {} mm, meshed in {:.2} s",
        report.name, t.faces, t.vertices, t.signed_volume_mm3, m.resolution_mm, m.seconds
    );
    println!(
        "watertight: all {} edges shared by exactly 2 faces in opposite directions; {} body; Euler characteristic {} (2 - 2 x {} holes); no degenerate or inverted faces; max surface error {:.3} mm",
        t.edges, t.components, t.euler_characteristic, m.holes, m.max_surface_error_mm
    );
    for file in &report.files {
        let timing = match file.format {
            Some(format) => format!(", {format} in {:.2} s", file.seconds),
            None => String::new(),
        };
        println!(
            "wrote {} ({}{timing})",
            display(&file.path),
            megabytes(file.bytes)
        );
    }
    let strut_covered = |fraction: f64, sphere: &str| {
        (fraction > 0.0).then(|| format!("{sphere} {:.1} %", 100.0 * fraction))
    };
    let main: Vec<String> = report
        .main_view_coverage
        .iter()
        .filter_map(|c| strut_covered(c.covered_by_struts, &c.sphere))
        .collect();
    let cone: Vec<String> = report
        .main_view_coverage
        .iter()
        .filter_map(|c| strut_covered(c.cone_covered_by_struts, &c.sphere))
        .collect();
    let verdict = |covered: &[String]| {
        if covered.is_empty() {
            "no strut covers a sphere".to_string()
        } else {
            format!("struts cover {}", covered.join(", "))
        }
    };
    println!(
        "main view ({}): {}; view cone ±{}°: {}{}; identification margin {:.3} mm",
        report.view,
        verdict(&main),
        report.view_cone_deg,
        verdict(&cone),
        if report.occlusion_allowed && !cone.is_empty() {
            " (allowed by --allow-occlusion)"
        } else {
            ""
        },
        report.identification_margin_mm
    );
    if let Some(scenarios) = report.working_range_scenarios {
        let mut lost: Vec<usize> = report.lost_views.iter().map(|l| l.scenario.index).collect();
        lost.dedup();
        println!(
            "working range ({scenarios} scenarios): {}",
            if lost.is_empty() {
                "the supports hide no sphere in any view the spheres leave visible".to_string()
            } else {
                let views: Vec<String> = report
                    .lost_views
                    .iter()
                    .take(LOST_VIEWS_SHOWN)
                    .map(|l| {
                        let s = &l.scenario;
                        format!(
                            "{} {:.0} % at depth {} x {} y {} tilt {} pan {}",
                            layout_name_of(&report, l.sphere),
                            100.0 * l.hidden_fraction,
                            s.depth_mm,
                            s.offset_x_mm,
                            s.offset_y_mm,
                            s.tilt_deg,
                            s.pan_deg
                        )
                    })
                    .collect();
                format!(
                    "{} views lost, no route of the supports clears them: {}{} (all in the export JSON)",
                    lost.len(),
                    views.join("; "),
                    if report.lost_views.len() > LOST_VIEWS_SHOWN { "; …" } else { "" }
                )
            }
        );
    }
    match &report.tolerances.centre {
        Some(c) => println!(
            "sphere-centre tolerance ±{:.3} mm per coordinate, from the datum on the plate (keeps the fabrication share of the RMS rotation error at most {:.0} % of the image noise's over {} scenarios; see the sheet)",
            c.tolerance_mm,
            100.0 * c.share,
            c.scenarios
        ),
        None => println!("sphere-centre tolerance: none from the error model (no default scenario sees every sphere)"),
    }
    let o = &report.overhang;
    let [x, y, z] = report.print_size_mm;
    println!(
        "print ({}): {x:.1} × {y:.1} × {z:.1} mm on a {} × {} × {} mm bed, lowest point at z = 0; overhangs steeper than {}° from vertical: {:.1} mm² (plus {:.1} mm² of sphere undersides); support estimate {:.0} mm³ ({:.1} % of the part); {:.0} mm² on the bed",
        report.structure,
        report.bed_mm[0],
        report.bed_mm[1],
        report.bed_mm[2],
        o.limit_deg,
        o.area_mm2,
        o.sphere_area_mm2,
        o.support_estimate_mm3,
        100.0 * o.support_estimate_mm3 / t.signed_volume_mm3,
        o.bed_contact_mm2,
    );
    Ok(())
}

/// The name of sphere `index` in the report's datum table.
fn layout_name_of(report: &layout_opt::mesh::ExportReport, index: usize) -> String {
    report
        .datum
        .iter()
        .filter(|d| d.kind == "sphere")
        .nth(index)
        .map_or_else(|| format!("sphere {index}"), |d| d.name.clone())
}

fn display(path: &Path) -> String {
    path.display().to_string()
}
