//! Argument parsing and dispatch. Each subcommand lives in its own file and
//! turns its flags into library configurations before any work starts.

mod common;
mod export;
mod progress;
mod reproduce;
mod search;
mod solve;
mod validate;

use clap::{Args, Parser, Subcommand};

/// Design 3D fiducial markers for close-range camera pose estimation.
#[derive(Debug, Parser)]
#[command(name = "layout-opt", version, about, long_about = None)]
struct Cli {
    #[command(flatten)]
    global: GlobalOptions,
    #[command(subcommand)]
    command: Command,
}

/// Options every subcommand takes.
#[derive(Debug, Clone, Args)]
pub struct GlobalOptions {
    /// Seed of every random stream.
    #[arg(long, global = true, default_value_t = 7)]
    pub seed: u64,
    /// Worker threads (default: all cores). Results do not depend on it.
    #[arg(long, global = true)]
    pub threads: Option<usize>,
    /// No progress bar.
    #[arg(long, short, global = true)]
    pub quiet: bool,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// PnP on a batch of correspondences (JSON), with any solver.
    Solve(solve::SolveArgs),
    /// Sensitivity report of a layout: Monte-Carlo error of every solver
    /// against the first-order and transfer-model predictions.
    Validate(Box<validate::ValidateArgs>),
    /// Optimise a layout family over a scenario grid with argmin.
    Search(Box<search::SearchArgs>),
    /// The seed paper's simulation experiments, regenerated on our solvers
    /// and checked claim by claim.
    Reproduce(reproduce::ReproduceArgs),
    /// Printable watertight marker mesh (STL, OBJ, glTF, GLB) and a
    /// fabrication sheet.
    Export(export::ExportArgs),
}

/// Parses the command line and runs the chosen subcommand.
pub fn run() -> anyhow::Result<()> {
    let cli = Cli::parse();
    if let Some(threads) = cli.global.threads {
        anyhow::ensure!(threads > 0, "--threads must be at least 1");
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build_global()
            .map_err(|e| anyhow::anyhow!("cannot start {threads} threads: {e}"))?;
    }
    match cli.command {
        Command::Solve(args) => solve::run(args, &cli.global),
        Command::Validate(args) => validate::run(*args, &cli.global),
        Command::Search(args) => search::run(*args, &cli.global),
        Command::Reproduce(args) => reproduce::run(args, &cli.global),
        Command::Export(args) => export::run(args, &cli.global),
    }
}
