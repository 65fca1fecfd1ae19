//! `layout-opt reproduce`: the seed paper's simulation experiments,
//! regenerated and checked claim by claim.

use super::common::command_line;
use super::{progress, GlobalOptions};
use anyhow::Context;
use clap::Args;
use layout_opt::reproduce::{self, claims::Verdict, Config};
use std::path::PathBuf;
use std::sync::Mutex;
use std::time::Instant;

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
    let bar = progress::bar(0, "reproducing", global.quiet);
    let current = Mutex::new(String::new());
    let started = Instant::now();
    let reproduction = reproduce::run(&config, &command_line(), &|name, done, total| {
        let mut current = current.lock().expect("progress lock");
        if *current != name {
            *current = name.to_string();
            bar.set_message(name.to_string());
            bar.set_length(total as u64);
        }
        bar.set_position(done as u64);
    })?;
    let seconds = started.elapsed().as_secs_f64();
    bar.finish_and_clear();
    reproduce::write_report(&args.out, &reproduction)
        .with_context(|| format!("writing the report to {}", args.out.display()))?;
    let run = serde_json::json!({
        "wall_seconds": seconds,
        "threads": rayon::current_num_threads(),
        "experiments": reproduction
            .wall_seconds
            .iter()
            .map(|(e, s)| serde_json::json!({"experiment": e.name(), "wall_seconds": s}))
            .collect::<Vec<_>>(),
    });
    let path = args.out.join("run.json");
    std::fs::write(&path, serde_json::to_string_pretty(&run)? + "\n")
        .with_context(|| format!("writing {}", path.display()))?;

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
