//! `layout-opt characterise`: the printed part measured from frames of it
//! (or from `track`'s JSON lines), or with `--plan`, the views to record.

use super::common::{command_line, naming_file};
use super::reading::{configure, refiner, ReadingArgs};
use super::{progress, GlobalOptions};
use anyhow::Context;
use clap::Args;
use layout_opt::characterise::plan::{capture_plan, DEFAULT_PLAN_SIGMA_PX};
use layout_opt::characterise::report::plan_text;
use layout_opt::characterise::workflow::{
    is_records, run as run_characterise, CharacteriseOutputs, CharacteriseWorkflowError, Source,
};
use layout_opt::characterise::{CharacteriseConfig, NamedDistance, DEFAULT_MAX_SIGMA_MM};
use layout_opt::kernel::Interrupted;
use layout_opt::layout::Layout;
use layout_opt::scenario::Range;
use layout_opt::track::workflow::WorkflowError;
use std::path::PathBuf;

/// Flags of `characterise`.
#[derive(Debug, Args)]
pub struct CharacteriseArgs {
    /// The nominal layout file (JSON): the design the part was printed from.
    #[arg(value_name = "LAYOUT")]
    layout: PathBuf,
    /// Frames of the printed part: 8- or 16-bit greyscale PNG files or
    /// directories of them, read as `track` reads them (its flags below);
    /// or `track`'s JSON-lines files (.jsonl, .ndjson, .json), or `solve`
    /// batch files (.json with "problems"; object points the nominal's).
    #[arg(value_name = "FRAMES", required_unless_present = "plan")]
    frames: Vec<PathBuf>,
    /// The characterised layout to write (JSON, the layout format); its
    /// report goes beside it as STEM-report.md and STEM-report.json.
    #[arg(long, value_name = "MEASURED.json", required_unless_present = "plan")]
    out: Option<PathBuf>,
    /// A measured distance between two sphere centres that sets the scale
    /// (a caliper's): FIRST:SECOND=MM, or FIRST:SECOND=MM±SIGMA (σ 0.01 mm
    /// unless given). Repeat for more; without it the scale is the
    /// nominal's, since one camera cannot see a uniform shrink.
    #[arg(long, value_name = "P1:P4=MM")]
    distance: Vec<NamedDistance>,
    /// Refuse (writing nothing, and naming the views to add) when any
    /// sphere's largest 1σ exceeds this, mm.
    #[arg(long, value_name = "MM", default_value_t = DEFAULT_MAX_SIGMA_MM)]
    max_sigma: f64,
    /// Print the views to capture for this layout and the σ each sphere
    /// would reach, instead of characterising.
    #[arg(long, conflicts_with_all = ["frames", "out", "distance"])]
    plan: bool,
    /// --plan's working range, mm: the views are planned at the nearest
    /// depth in it where every view keeps the part inside the image.
    #[arg(
        long,
        value_name = "RANGE",
        default_value = "200..1000",
        requires = "plan"
    )]
    depth: Range,
    #[command(flatten)]
    reading: ReadingArgs,
}

pub fn run(args: CharacteriseArgs, global: &GlobalOptions) -> anyhow::Result<()> {
    let nominal = naming_file(Layout::load(&args.layout), "layout", &args.layout)?;
    if args.plan {
        return plan(&args, &nominal);
    }
    let out = args
        .out
        .clone()
        .expect("clap requires --out without --plan");
    let camera = args.reading.camera.camera()?;
    let mut config = CharacteriseConfig::new(nominal.clone(), camera);
    config.distances = args.distance.clone();
    config.max_sigma_mm = args.max_sigma;
    if let Err(error) = config.validate() {
        let flag = match error.field {
            "distances" => "--distance",
            "max_sigma_mm" => "--max-sigma",
            "nominal" => "LAYOUT",
            other => other,
        };
        anyhow::bail!("{flag}: {}", error.reason);
    }
    let records = args.frames.iter().filter(|p| is_records(p)).count();
    anyhow::ensure!(
        records == 0 || records == args.frames.len(),
        "{}",
        CharacteriseWorkflowError::Mixed
    );
    let mut sources = vec![("LAYOUT".to_string(), args.layout.clone())];
    if let Some(camera) = &args.reading.camera.camera {
        sources.push(("--camera".into(), camera.clone()));
    }
    let outputs = CharacteriseOutputs {
        sources,
        layout: out.clone(),
    };
    let command = command_line();
    let mut bars = progress::Bars::new(global.quiet);
    let result = if records > 0 {
        run_characterise(
            &config,
            Source::Records {
                inputs: &args.frames,
            },
            &outputs,
            &command,
            &mut bars,
        )
    } else {
        let track = configure(&args.reading, &nominal)?;
        let refiner = refiner(&args.reading, &nominal, &track)?;
        run_characterise(
            &config,
            Source::Frames {
                track: &track,
                refiner: refiner.as_ref(),
                inputs: &args.frames,
            },
            &outputs,
            &command,
            &mut bars,
        )
    };
    bars.finish();
    let run = match result {
        Ok(run) => run,
        Err(CharacteriseWorkflowError::Track(WorkflowError::Interrupted)) => {
            return Err(Interrupted::nothing_written().into())
        }
        Err(error) => return Err(error).context("characterise: nothing written"),
    };
    let c = &run.characterisation;
    for dropped in &c.dropped {
        eprintln!("{}: not used: {}", dropped.frame, dropped.reason);
    }
    let (worst, sigma) = c.worst_sigma();
    let largest_correction = c
        .correction_mm
        .iter()
        .map(|d| (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt())
        .fold(0.0, f64::max);
    eprintln!(
        "characterised {} from {} of {} frames ({} centres, residual RMS {:.4} px, centre σ {:.4} px; scale from {}): largest correction {:.4} mm, largest 1σ {:.4} mm ({}); wrote {}, {} and {}",
        c.nominal,
        c.frames.len(),
        run.frames_given,
        c.centres,
        c.residual_rms_px,
        c.sigma_px,
        if c.scale.source == "distances" { "the distances" } else { "the nominal" },
        largest_correction,
        sigma,
        c.names[worst],
        out.display(),
        run.report.0.display(),
        run.report.1.display()
    );
    Ok(())
}

/// `--plan`: the views to capture and the σ they would give.
fn plan(args: &CharacteriseArgs, nominal: &Layout) -> anyhow::Result<()> {
    let camera = args.reading.camera.camera()?;
    let (near, far) = args
        .depth
        .values
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &d| {
            (lo.min(d), hi.max(d))
        });
    let sigma_px = args.reading.sigma_px.unwrap_or(DEFAULT_PLAN_SIGMA_PX);
    let plan =
        capture_plan(nominal, &camera, near, far, sigma_px).context("characterise --plan")?;
    print!("{}", plan_text(&plan));
    Ok(())
}
