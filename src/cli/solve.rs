//! `layout-opt solve`: PnP on a batch of correspondences.

use super::{progress, GlobalOptions};
use anyhow::Context;
use clap::Args;
use layout_opt::batch::{
    demo_batch_json, Batch, ProblemResult, SetBatch, SetProblemResult, UnlabelledConfig,
    DEFAULT_GATE_PX,
};
use layout_opt::kernel::{OutputPlan, Outputs};
use layout_opt::pnp::Solver;
use layout_opt::set::MarkerSet;
use layout_opt::track::uncertainty::solve_figures;
use std::path::PathBuf;

/// Flags of `solve`.
#[derive(Debug, Args)]
pub struct SolveArgs {
    /// Correspondence batch (JSON, see README). Without it, a built-in demo
    /// batch (the paper's biprism at 200..1000 mm, σ 0.5 px, from --seed).
    #[arg(long, value_name = "FILE")]
    problems: Option<PathBuf>,
    /// Solver, by stable name (see --list). Default: parallel-weighted; with
    /// --unlabelled, ml (the final pose is this solver on the found labels).
    #[arg(long)]
    solver: Option<Solver>,
    /// Write the results here instead of stdout.
    #[arg(long, value_name = "FILE")]
    output: Option<PathBuf>,
    /// List the solvers and exit.
    #[arg(long)]
    list: bool,
    /// Sphere diameter, mm: the image points are the centres of the spheres'
    /// silhouette ellipses (what a blob detector measures), and `ml` fits the
    /// exact sphere-image model. A problem's own "sphere_diameter" wins.
    /// Only `ml` accepts it; other solvers give each such problem an error.
    #[arg(long, value_name = "MM")]
    sphere_diameter: Option<f64>,
    /// Each problem's image_points are an unordered set of blobs (at most one
    /// fewer than the object points): find which blob is which object point
    /// from the geometry alone (P3P hypotheses, verified by reprojection).
    /// Adds "labels", "ambiguity" and "runner_up_rms_px" to each result.
    #[arg(long)]
    unlabelled: bool,
    /// With --unlabelled: a labelling is consistent when every blob lies
    /// within this many px of its reprojection. The default, 2.5 px, is 5σ
    /// at σ = 0.5 px; raise it for noisier blobs.
    #[arg(long, value_name = "PX", requires = "unlabelled", default_value_t = DEFAULT_GATE_PX)]
    gate_px: f64,
    /// With --unlabelled: the blobs of each problem come from the markers
    /// of this set file (layouts/<name>.set.json); a problem's object_points
    /// are ignored. Blobs are grouped into markers by the best joint fit,
    /// and each result lists the markers found, each with its number, name,
    /// blobs, labels and pose, and the blobs no marker explains.
    #[arg(long, value_name = "SET.json", requires = "unlabelled")]
    set: Option<PathBuf>,
}

/// Noise of the built-in demo batch, px.
const DEMO_SIGMA_PX: f64 = 0.5;

pub fn run(args: SolveArgs, global: &GlobalOptions) -> anyhow::Result<()> {
    if args.list {
        for &solver in Solver::ALL {
            println!("{:<18} {}", solver.name(), solver.description());
        }
        return Ok(());
    }
    // The output is checked against the inputs and locked before any work.
    let mut plan = OutputPlan::new();
    plan.inputs("--problems", &args.problems)
        .inputs("--set", &args.set);
    if let Some(path) = &args.output {
        plan.file("--output", path);
    }
    let files = plan.open()?;
    let (text, source) = match &args.problems {
        Some(path) => (
            std::fs::read_to_string(path)
                .with_context(|| format!("cannot read problem file {}", path.display()))?,
            path.display().to_string(),
        ),
        None => (
            demo_batch_json(global.seed, DEMO_SIGMA_PX),
            format!(
                "built-in demo batch (paper biprism, σ {DEMO_SIGMA_PX} px, seed {})",
                global.seed
            ),
        ),
    };
    let solver = args.solver.unwrap_or(if args.unlabelled {
        Solver::Ml
    } else {
        Solver::ParallelWeighted
    });
    anyhow::ensure!(
        args.gate_px > 0.0 && args.gate_px.is_finite(),
        "--gate-px must be a positive number of px, got {}",
        args.gate_px
    );
    if let Some(diameter) = args.sphere_diameter {
        anyhow::ensure!(
            diameter > 0.0 && diameter.is_finite(),
            "--sphere-diameter must be a positive number of mm, got {diameter}"
        );
        anyhow::ensure!(
            solver == Solver::Ml,
            "--sphere-diameter needs --solver ml (the solver that fits the sphere-image model); {} fits projected centres",
            solver
        );
    }
    if let Some(set) = &args.set {
        return run_set(&args, files, set, &text, &source, solver, global);
    }
    let batch = Batch::from_json(&text).with_context(|| format!("in {source}"))?;
    let bar = progress::bar(batch.problems.len() as u64, "solving", global.quiet);
    let on_progress = |done: usize| bar.set_position(done as u64);
    let output = if args.unlabelled {
        let config = UnlabelledConfig {
            gate_px: args.gate_px,
            ..UnlabelledConfig::default()
        };
        batch.solve_unlabelled(solver, args.sphere_diameter, config, on_progress)
    } else {
        batch.solve_with_spheres(solver, args.sphere_diameter, on_progress)
    };
    bar.finish_and_clear();
    // rvec/tvec, residuals, σ, covariance and label trust beside each pose.
    let figures = solve_figures(&batch, &output, args.sphere_diameter);
    let mut document = serde_json::to_value(&output)?;
    if let Some(results) = document.get_mut("results").and_then(|r| r.as_array_mut()) {
        for ((result, figures), (id, _)) in results.iter_mut().zip(&figures).zip(&batch.problems) {
            let Some(entry) = result.as_object_mut() else {
                continue;
            };
            match figures {
                Some(Ok(figures)) => {
                    if let Some(warning) = &figures.warning {
                        eprintln!("warning: {id}: {warning}");
                    }
                    if let serde_json::Value::Object(fields) = serde_json::to_value(figures)? {
                        entry.extend(fields);
                    }
                }
                Some(Err(error)) => {
                    entry.insert("figures_error".into(), error.clone().into());
                }
                None => {}
            }
        }
    }
    let json = serde_json::to_string_pretty(&document)?;

    let mut seconds: Vec<f64> = output
        .results
        .iter()
        .filter_map(|r| match r {
            ProblemResult::Solved { seconds, .. } => Some(*seconds),
            ProblemResult::Failed { .. } => None,
        })
        .collect();
    seconds.sort_by(f64::total_cmp);
    let failed = output.results.len() - seconds.len();
    let median = seconds
        .get(seconds.len() / 2)
        .map(|s| format!("; median {:.2} µs per solve", s * 1e6))
        .unwrap_or_default();
    let summary = format!(
        "{}{}: solved {} of {} problems from {source}{median}{}",
        solver,
        if args.unlabelled { " (unlabelled)" } else { "" },
        seconds.len(),
        output.results.len(),
        if failed > 0 {
            format!("; {failed} with errors (see their \"error\" entries)")
        } else {
            String::new()
        }
    );
    emit(&args, files, json, &summary)
}

/// Writes the output document where `--output` says, or to stdout.
fn emit(args: &SolveArgs, files: Outputs, json: String, summary: &str) -> anyhow::Result<()> {
    match &args.output {
        Some(path) => {
            files.stage(path, (json + "\n").as_bytes())?;
            files.commit()?;
            println!("{summary}; wrote {}", path.display());
        }
        None => {
            println!("{json}");
            eprintln!("{summary}");
        }
    }
    Ok(())
}

/// `solve --unlabelled --set SET.json`: the set's markers in every frame.
fn run_set(
    args: &SolveArgs,
    files: Outputs,
    set_path: &std::path::Path,
    text: &str,
    source: &str,
    solver: Solver,
    global: &GlobalOptions,
) -> anyhow::Result<()> {
    let set = MarkerSet::load(set_path).context("--set")?;
    set.check_distinct().context("--set")?;
    let batch = SetBatch::from_json(text).with_context(|| format!("in {source}"))?;
    let bar = progress::bar(batch.len() as u64, "solving", global.quiet);
    let config = UnlabelledConfig {
        gate_px: args.gate_px,
        ..UnlabelledConfig::default()
    };
    let output = batch.solve(&set, solver, args.sphere_diameter, config, |done| {
        bar.set_position(done as u64)
    });
    bar.finish_and_clear();
    let json = serde_json::to_string_pretty(&output)?;
    let (mut frames, mut found, mut failed) = (0, 0, 0);
    for result in &output.results {
        match result {
            SetProblemResult::Solved { markers, .. } => {
                frames += 1;
                found += markers.len();
            }
            SetProblemResult::Failed { .. } => failed += 1,
        }
    }
    let summary = format!(
        "{solver} (unlabelled, set {} of {} markers): {found} markers found in {frames} of {} frames from {source}{}",
        set.name,
        set.members.len(),
        output.results.len(),
        if failed > 0 {
            format!("; {failed} with errors (see their \"error\" entries)")
        } else {
            String::new()
        }
    );
    emit(args, files, json, &summary)
}
