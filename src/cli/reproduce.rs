//! `layout-opt reproduce`: the seed paper's simulation experiments,
//! regenerated and checked claim by claim.

use super::common::command_line;
use super::{progress, GlobalOptions};
use clap::Args;
use layout_opt::reproduce::pipeline::{self, ReproduceConfig, ReproduceOutcome};
use layout_opt::reproduce::{self, claims::Verdict, Config};
use std::path::PathBuf;

/// Flags of `reproduce`.
#[derive(Debug, Args)]
pub struct ReproduceArgs {
    /// Experiments: `all`, or a comma list of points, noise, timing, depth,
    /// off-axis, tilt, protocol.
    #[arg(long, default_value = "all")]
    experiment: String,
    /// Output directory.
    #[arg(long, value_name = "DIR", default_value = "reports/paper")]
    out: PathBuf,
    /// Trials per setting for every experiment (repetitions for timing).
    /// Default: the paper's counts (protocol: 30 noise draws per pose).
    #[arg(long)]
    trials: Option<usize>,
    /// Few trials on the same grids (a smoke run of well under a minute).
    #[arg(long)]
    quick: bool,
}

pub fn run(args: ReproduceArgs, global: &GlobalOptions) -> anyhow::Result<()> {
    let experiments = reproduce::parse_experiments(&args.experiment)?;
    anyhow::ensure!(args.trials != Some(0), "--trials must be at least 1");
    let config = Config {
        experiments,
        seed: global.seed,
        trials: args.trials,
        quick: args.quick,
    };
    let config = ReproduceConfig {
        experiments: config,
        command: command_line(),
        out_dir: args.out.clone(),
    };
    let mut bars = progress::Bars::new(global.quiet);
    let result = pipeline::run(&config, &mut bars);
    bars.finish();
    let ReproduceOutcome {
        reproduction,
        seconds,
    } = result?;
    let config = &config.experiments;
    println!(
        "reproduce: seed {}{}, {} threads",
        config.seed,
        if config.quick { ", --quick" } else { "" },
        rayon::current_num_threads()
    );
    println!(
        "{:<10} {:>8} {:>6} {:>14} {:>14} {:>10}",
        "experiment", "trials", "holds", "does not hold", "not evaluated", "wall (s)"
    );
    for (result, (_, wall)) in reproduction
        .experiments
        .iter()
        .zip(&reproduction.wall_seconds)
    {
        let count = |v: Verdict| result.claims.iter().filter(|c| c.verdict == v).count();
        println!(
            "{:<10} {:>8} {:>6} {:>14} {:>14} {:>10.1}",
            result.experiment.name(),
            result.trials,
            count(Verdict::Holds),
            count(Verdict::DoesNotHold),
            count(Verdict::NotEvaluated),
            wall
        );
    }
    println!(
        "{seconds:.1} s in all; report in {}",
        args.out.join("report.md").display()
    );
    Ok(())
}
