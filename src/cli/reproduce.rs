//! `layout-opt reproduce`: the seed paper's simulation experiments,
//! regenerated and checked claim by claim.

use super::common::{command_line, duration_text, naming_file, SLOW_RUN_SECONDS};
use super::{progress, GlobalOptions};
use clap::Args;
use layout_opt::camera;
use layout_opt::report::Table;
use layout_opt::reproduce::workflow::{self, ReproduceConfig, ReproduceOutcome};
use layout_opt::reproduce::{self, Config, Experiment, Verdict, REFERENCE_THREADS};
use std::path::PathBuf;

/// Flags of `reproduce`.
#[derive(Debug, Args)]
pub struct ReproduceArgs {
    /// Experiments: `all`, or a comma list of points, noise, timing, depth,
    /// off-axis, tilt, protocol.
    #[arg(long, default_value = "all")]
    experiment: String,
    /// Output directory. Default: reports/paper for the full run; a run with
    /// --quick, --trials or a subset of experiments gets its own directory
    /// (reports/paper-quick, reports/paper-trials-N, reports/paper-timing),
    /// so the reference report is never overwritten by a smaller run.
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// Trials per setting for every experiment (repetitions for timing).
    /// Default: the paper's counts (protocol: 30 noise draws per pose).
    #[arg(long)]
    trials: Option<usize>,
    /// Few trials on the same grids (a smoke run of well under a minute).
    #[arg(long)]
    quick: bool,
    /// Camera file (JSON, docs/formats.md) for every experiment. Default:
    /// the paper's per experiment (f = 80 px for points, noise, off-axis;
    /// f = 500 px for depth, tilt; the §4.2 camera for protocol).
    #[arg(long, value_name = "FILE")]
    camera: Option<PathBuf>,
}

pub fn run(args: ReproduceArgs, global: &GlobalOptions) -> anyhow::Result<()> {
    let experiments = reproduce::parse_experiments(&args.experiment)?;
    anyhow::ensure!(args.trials != Some(0), "--trials must be at least 1");
    let config = Config {
        experiments,
        seed: global.seed,
        trials: args.trials,
        quick: args.quick,
        camera: args
            .camera
            .as_deref()
            .map(|path| naming_file(camera::load(path), "camera", path))
            .transpose()?,
    };
    let out_dir = args.out.clone().unwrap_or_else(|| config.default_out_dir());
    let threads = rayon::current_num_threads();
    if !global.quiet && config.estimate_seconds(threads) >= SLOW_RUN_SECONDS {
        eprintln!(
            "estimate: about {} on {threads} threads (cost model: each experiment's time in a reference run of every experiment at default trials, {} s on {REFERENCE_THREADS} threads of a shared 2-core machine, scaled by trials and threads); report in {}",
            duration_text(config.estimate_seconds(threads)),
            Experiment::ALL.iter().map(|e| e.reference_seconds()).sum::<f64>().round(),
            out_dir.display()
        );
    }
    let config = ReproduceConfig {
        experiments: config,
        command: command_line(),
        out_dir,
    };
    let mut bars = progress::Bars::new(global.quiet);
    let result = workflow::run(&config, &mut bars);
    bars.finish();
    if let Err(reproduce::ReproduceError::Interrupted) = result {
        let kept = format!(
            "interrupted: no report written ({} untouched)",
            config.out_dir.display()
        );
        return Err(layout_opt::kernel::Interrupted::keeping(kept).into());
    }
    let ReproduceOutcome {
        reproduction,
        seconds,
    } = result?;
    let out_dir = &config.out_dir;
    let config = &config.experiments;
    println!(
        "reproduce: seed {}{}, {} threads",
        config.seed,
        if config.quick { ", --quick" } else { "" },
        rayon::current_num_threads()
    );
    let mut table = Table::new([
        "experiment",
        "trials",
        "holds",
        "indistinguishable",
        "does not hold",
        "implementation-dependent",
        "not evaluated",
        "wall (s)",
    ]);
    for (result, (_, wall)) in reproduction
        .experiments
        .iter()
        .zip(&reproduction.wall_seconds)
    {
        let count = |v: Verdict| result.claims.iter().filter(|c| c.verdict == v).count();
        table.row([
            result.experiment.name().to_string(),
            result.trials.to_string(),
            count(Verdict::Holds).to_string(),
            count(Verdict::Indistinguishable).to_string(),
            count(Verdict::DoesNotHold).to_string(),
            count(Verdict::ImplementationDependent).to_string(),
            count(Verdict::NotEvaluated).to_string(),
            format!("{wall:.1}"),
        ]);
    }
    print!("{}", table.console());
    println!(
        "{seconds:.1} s in all; report in {}",
        out_dir.join("report.md").display()
    );
    Ok(())
}
