//! Argument parsing and dispatch. Each subcommand lives in its own file and
//! turns its flags into library configurations before any work starts.

mod characterise;
mod common;
mod export;
mod export_set;
mod look;
mod noise_model;
mod progress;
mod reading;
mod render;
mod render_scenes;
mod reproduce;
mod search;
mod solve;
mod track;
mod track_set;
mod track_stream;
mod validate;
mod validate_images;
mod validate_set;
mod volume;

use clap::{Args, CommandFactory, FromArgMatches, Parser, Subcommand};

/// Most worker threads `--threads` accepts, per core: more only queue
/// behind each other, and a huge count exhausts the machine while starting.
pub const MAX_THREADS_PER_CORE: usize = 4;

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
    /// Worker threads (default: all cores; at most 4× the cores). Results do
    /// not depend on it.
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
    /// Printable watertight marker mesh (STL, 3MF, OBJ, glTF, GLB) and a
    /// fabrication sheet.
    Export(export::ExportArgs),
    /// Grey PNG images of the part export builds, as the camera sees it,
    /// with the ground truth of every frame.
    Render(Box<render::RenderArgs>),
    /// Grey camera frames of a printed marker → labelled poses with their
    /// uncertainty (JSON lines).
    Track(Box<track::TrackArgs>),
    /// The printed part measured from frames of it: every sphere centre
    /// and its 1σ by bundle adjustment, written as a layout to track with
    /// (or, with --plan, the views to capture).
    Characterise(Box<characterise::CharacteriseArgs>),
}

/// Parses the command line and runs the chosen subcommand.
pub fn run() -> anyhow::Result<()> {
    let cli = parse();
    if let Some(threads) = cli.global.threads {
        anyhow::ensure!(threads > 0, "--threads must be at least 1");
        let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
        anyhow::ensure!(
            threads <= MAX_THREADS_PER_CORE * cores,
            "--threads {threads} is more than {MAX_THREADS_PER_CORE}× the {cores} cores of this machine ({} threads at most); results do not depend on the thread count, so use fewer",
            MAX_THREADS_PER_CORE * cores
        );
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build_global()
            .map_err(|e| anyhow::anyhow!("cannot start {threads} threads: {e}"))?;
    }
    match cli.command {
        Command::Solve(args) => solve::run(args, &cli.global),
        Command::Validate(args) => match validate::set_path(&args) {
            Some(set) => validate_set::run(set, &args, &cli.global),
            None => validate::run(*args, &cli.global),
        },
        Command::Search(args) => search::run(*args, &cli.global),
        Command::Reproduce(args) => reproduce::run(args, &cli.global),
        Command::Export(args) => export::run(args, &cli.global),
        Command::Render(args) => render::run(*args, &cli.global),
        Command::Track(args) => track::run(*args, &cli.global),
        Command::Characterise(args) => characterise::run(*args, &cli.global),
    }
}

/// The command line, parsed. Every subcommand reads a word like `-1` or
/// `-0.5` after a flag as a negative number rather than as an unknown flag
/// (grid ranges such as `-90..90` also take hyphen values).
fn parse() -> Cli {
    let mut command = Cli::command();
    let names: Vec<String> = command
        .get_subcommands()
        .map(|c| c.get_name().to_string())
        .collect();
    for name in names {
        command = command.mut_subcommand(name, |c| c.allow_negative_numbers(true));
    }
    let matches = command.get_matches();
    Cli::from_arg_matches(&matches).unwrap_or_else(|e| e.exit())
}
