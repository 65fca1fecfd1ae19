//! `layout-opt track`: grey camera frames of a printed marker → labelled
//! poses with their uncertainty, one JSON line per frame.

use super::common::naming_file;
use super::reading::{configure, refiner, ReadingArgs};
use super::track_stream::{self, StreamArgs, StreamJob};
use super::{progress, GlobalOptions};
use anyhow::Context;
use clap::Args;
use layout_opt::kernel::Interrupted;
use layout_opt::layout::Layout;
use layout_opt::track::stream::MarkerTracker;
use layout_opt::track::workflow::{run as run_track, TrackOutputs, WorkflowError};
use layout_opt::track::TrackConfig;
use std::path::PathBuf;

/// Flags of `track`.
#[derive(Debug, Args)]
pub struct TrackArgs {
    /// The marker's layout file (JSON); with --set, the first frame.
    #[arg(required_unless_present = "set", value_name = "LAYOUT")]
    layout: Option<PathBuf>,
    /// Frames: 8- or 16-bit greyscale PNG files, or directories of them;
    /// `-` for a stream on standard input (Y4M, or --raw), or one
    /// directory with --follow. A stream's lines are written as each frame
    /// is done, with its index, timestamp and latency.
    #[arg(required_unless_present = "set", value_name = "IMAGES")]
    images: Vec<PathBuf>,
    /// A set file (layout-opt-set): find every marker of the set in each
    /// frame and name it by its number and layout; all arguments are
    /// frames. JSON lines only (no --csv, --overlay).
    #[arg(long, value_name = "SET.json", conflicts_with_all = ["csv", "overlay"])]
    set: Option<PathBuf>,
    #[command(flatten)]
    reading: ReadingArgs,
    #[command(flatten)]
    stream: StreamArgs,
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
            &args.stream,
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
    if let Some(input) = args.stream.input(&args.images)? {
        anyhow::ensure!(
            args.csv.is_none() && args.overlay.is_none(),
            "a stream gives JSON lines only: --csv and --overlay take frame files"
        );
        let tracker = MarkerTracker {
            config: &config,
            refiner: refiner.as_ref(),
        };
        let job = StreamJob {
            sources: vec![("LAYOUT", &layout_path)],
            output: args.output.as_deref(),
            tracker: &tracker,
            camera_size: (config.camera.width(), config.camera.height()),
            describe: describe(&layout, &config, &args.reading, refiner.is_some()),
        };
        return track_stream::run(&args.stream, &input, job);
    }
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
    let (compared, unlike) = run.unlike_spheres();
    if unlike > 0 {
        eprintln!("warning: --refine: the render was unlike the frame around {unlike} of {compared} spheres, which kept their measured centres (refinement.likeness in the records); give the look the camera sees (--preset, the radiances, --blur) and the part's structure flags");
    }
    let summary = format!(
        "tracked {} of {} frames with {}",
        run.tracked(),
        run.frames.len(),
        describe(&layout, &config, &args.reading, refiner.is_some())
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

/// The marker and the reading, for the run's summary line: "NAME (7
/// spheres of 10 mm, ellipse centres, ml solver)".
fn describe(layout: &Layout, config: &TrackConfig, reading: &ReadingArgs, refined: bool) -> String {
    let name = match layout.characterised() {
        Some(how) => format!("{} ({how})", layout.name),
        None => layout.name.clone(),
    };
    let refined = if refined {
        format!(", refined by {} render round(s)", reading.refine_rounds)
    } else {
        String::new()
    };
    format!(
        "{name} ({} spheres of {} mm, {} centres, {} solver{refined})",
        config.object.len(),
        config.sphere_diameter_mm,
        config.centre.name(),
        config.solver
    )
}
