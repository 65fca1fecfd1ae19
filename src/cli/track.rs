//! `layout-opt track`: grey camera frames of a printed marker → labelled
//! poses with their uncertainty, one JSON line per frame.

use super::common::naming_file;
use super::reading::{configure, refiner, ReadingArgs};
use super::{progress, GlobalOptions};
use anyhow::Context;
use clap::Args;
use layout_opt::kernel::Interrupted;
use layout_opt::layout::Layout;
use layout_opt::track::workflow::{run as run_track, TrackOutputs, WorkflowError};
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
