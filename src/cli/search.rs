//! `layout-opt search`: flags into a [`SearchConfig`], progress bars and
//! Ctrl-C into an [`Observer`], and the summary printed. The pipeline itself
//! is [`layout_opt::search::pipeline::run`].

use super::common::{
    command_line, duration_text, naming_file, CameraArgs, GridArgs, SLOW_RUN_SECONDS,
};
use super::{progress, GlobalOptions};
use anyhow::Context;
use clap::{Args, ValueEnum};
use layout_opt::family::{Constraints, Envelope, FamilyKind};
use layout_opt::layout::Layout;
use layout_opt::mesh::Format;
use layout_opt::noise::NoiseModel;
use layout_opt::pnp::Solver;
use layout_opt::report::{percent_lower, Table};
use layout_opt::scenario::ScenarioGrid;
use layout_opt::search::pipeline::{self, FrontOutput, MeshExport, SearchConfig};
use layout_opt::search::{
    hand_designs, Aggregate, AvailabilityFloor, Evaluator, FrontSettings, IdentifiabilityFloor,
    Objective, ObjectiveSettings, Optimiser, SearchSettings, Term, FINAL_POLISH_STARTS,
};
use layout_opt::sphere_image::Observation;
use std::path::PathBuf;
use std::time::Instant;

/// The polish budget when --polish is not given: two thirds of
/// --iterations (2000 with the default 3000), so the polish shrinks with a
/// quick search instead of dominating it.
fn default_polish(iterations: u64) -> u64 {
    (u128::from(iterations) * 2 / 3) as u64
}

/// Layout families.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
enum FamilyName {
    Biprism,
    Tetrahedron,
    Custom,
}

/// Flags of `search`.
#[derive(Debug, Args)]
pub struct SearchArgs {
    /// Layout family.
    #[arg(long, value_enum, default_value = "biprism")]
    family: FamilyName,
    /// Leave out the centre point (biprism: O0; tetrahedron: the centroid point).
    #[arg(long)]
    no_centre: bool,
    /// Keep biprism arms on their axes (only their lengths vary).
    #[arg(long)]
    no_tilts: bool,
    /// Pin the biprism's hub at the envelope's centre (by default it may move
    /// anywhere in the envelope).
    #[arg(long, alias = "centered-hub")]
    centred_hub: bool,
    /// Number of free points (custom family).
    #[arg(long, default_value_t = 7)]
    points: usize,
    /// Start layout for the custom family; its points marked "fixed" stay put.
    #[arg(long, value_name = "FILE")]
    init: Option<PathBuf>,
    /// Envelope bounding the sphere centres: one size (a cube) or X,Y,Z, mm.
    #[arg(long, default_value = "100")]
    envelope: Envelope,
    /// Sphere diameter, mm.
    #[arg(long, default_value_t = 10.0)]
    sphere_diameter: f64,
    /// Smallest gap between sphere surfaces, mm.
    #[arg(long, default_value_t = 2.0)]
    min_gap: f64,
    /// Smallest difference between two pairwise centre distances, mm: the
    /// identification rule of stereo trackers, which measure 3D points
    /// (0, the default, disables it; a single camera is served by
    /// --min-identifiability).
    #[arg(long, default_value_t = 0.0)]
    min_distance_diff: f64,
    /// Least share of the visible scenarios in which one image identifies
    /// the spheres: the unlabelled solver is predicted to label the blobs
    /// correctly with probability ≥ 99.9% (--identify-criterion). A share
    /// (0.999 or 99.9%) or `none` (for stereo trackers, which identify by
    /// --min-distance-diff).
    #[arg(long, default_value = "99.9%", value_name = "SHARE")]
    min_identifiability: IdentifiabilityShare,
    /// Least predicted probability of a correct labelling for a scenario to
    /// count as identifiable.
    #[arg(long, default_value = "99.9%", value_name = "PROBABILITY")]
    identify_criterion: IdentifiabilityShare,
    /// Monte-Carlo trials of the unlabelled solver per visible scenario in
    /// the winner's validation (0: the prediction alone).
    #[arg(long, default_value_t = pipeline::DEFAULT_IDENTIFY_TRIALS)]
    identify_trials: usize,
    #[command(flatten)]
    grid: GridArgs,
    #[command(flatten)]
    camera: CameraArgs,
    /// Objective: crlb, transfer, mc:<solver>, or a blend like crlb:0.7+mc:parallel-weighted:0.3.
    #[arg(long, default_value = "crlb")]
    objective: Objective,
    /// How scenarios are combined: mean (RMS), p95 or max.
    #[arg(long, default_value = "mean")]
    aggregate: Aggregate,
    /// Weight of translation against rotation error in the objective.
    #[arg(long, default_value_t = 0.5)]
    translation_weight: f64,
    /// Weighted blend: cost of losing every scenario to visibility (occlusion,
    /// leaving the image), added to the accuracy. 0 (the default) scores
    /// accuracy alone, subject to --min-availability.
    #[arg(long, default_value_t = 0.0)]
    availability_weight: f64,
    /// Least share of the grid's scenarios in which every sphere is visible
    /// and unoccluded: a share (0.6 or 60%), `reference` (the family's
    /// reference design on the same grid: for biprism, the paper's biprism),
    /// or `none` (availability priced by --availability-weight alone).
    #[arg(long, default_value = "reference", value_name = "SHARE")]
    min_availability: AvailabilityFloor,
    /// Monte-Carlo trials per scenario for mc: objectives.
    #[arg(long, default_value_t = 20)]
    trials: usize,
    /// Noise model: isotropic, per-point, size[:REF_PX], optionally +outliers:RATE[:PX].
    #[arg(long, default_value = "isotropic")]
    noise_model: NoiseModel,
    /// Image point of a sphere: `ellipse-centre` (its silhouette's centre,
    /// what a blob detector measures; the crlb term then carries the pose
    /// bias) or `centre` (its projected centre). Noise is added on top.
    #[arg(long, default_value = "ellipse-centre")]
    observation: Observation,
    /// Optimiser: nelder-mead, pso or annealing (the last two are followed by
    /// a Nelder–Mead polish).
    #[arg(long, default_value = "nelder-mead")]
    optimiser: Optimiser,
    /// Independent starts, run in parallel.
    #[arg(long, default_value_t = 8)]
    starts: usize,
    /// Starts beyond the first two (the family's natural start and its
    /// spread start): 0 draws them uniformly within bounds; a fraction f in
    /// (0, 1] draws them around the spread start, each parameter within ± f
    /// of its range (basin hopping around the best structured start; random
    /// starts in a 20-odd-dimensional box rarely reach the good basins).
    #[arg(long, default_value_t = 0.02, value_name = "FRACTION")]
    start_jitter: f64,
    /// Iterations per start.
    #[arg(long, default_value_t = 3000)]
    iterations: u64,
    /// Particles (particle swarm).
    #[arg(long, default_value_t = 32)]
    particles: usize,
    /// Nelder–Mead polish iterations: after particle swarm or annealing; after
    /// Nelder–Mead, the final polish runs this many from the winner and from
    /// three seeded copies jittered around it (0 disables). Default: two
    /// thirds of --iterations (2000 with its default), so that a short
    /// --iterations makes a short search.
    #[arg(long)]
    polish: Option<u64>,
    /// Solver of the Monte-Carlo comparison in the report.
    #[arg(long, default_value = "parallel-weighted")]
    compare_solver: Solver,
    /// Trials per scenario of the Monte-Carlo comparison.
    #[arg(long, default_value_t = 200)]
    compare_trials: usize,
    /// Solvers of the winner's full sensitivity report (`all` or a list; the
    /// polynomial solvers DLS and OPnP take 0.3–2 ms per solve).
    #[arg(
        long,
        default_value = "parallel-weighted,parallel-gn,epnp-gn,sqpnp,lhm,ml"
    )]
    validate_solvers: String,
    /// Name of the result. Default: <family>-search.
    #[arg(long)]
    name: Option<String>,
    /// Where to write the winning layout. Default: layouts/<name>.json.
    #[arg(long, value_name = "FILE")]
    out: Option<PathBuf>,
    /// Report directory. Default: reports/<name>/; with --out FILE, beside
    /// it: <FILE's directory>/<FILE's stem>-report/.
    #[arg(long, value_name = "DIR")]
    report: Option<PathBuf>,
    /// Continue an interrupted search from its checkpoints. Refused, naming
    /// the settings that changed, when the only checkpoints are those of a
    /// different configuration.
    #[arg(long)]
    resume: bool,
    /// Where checkpoints are kept (one directory per name and configuration
    /// hash; removed when the search finishes). Default: hidden beside the
    /// layout, <FILE's directory>/.<FILE's stem>.checkpoints/, so that it
    /// follows --out.
    #[arg(long, value_name = "DIR")]
    checkpoint_dir: Option<PathBuf>,
    /// Also export the winner as printable meshes in these formats
    /// (stl, 3mf, obj, gltf, glb; comma-separated), with `export`'s defaults.
    #[arg(long, value_delimiter = ',', value_name = "FORMATS")]
    export: Vec<Format>,
    /// Directory of the exported meshes. Default: build/<name>/.
    #[arg(long, value_name = "DIR")]
    export_dir: Option<PathBuf>,
    /// Also compute the Pareto front of accuracy against availability (an
    /// ε-constraint sweep): front.json, front.csv and front.svg in the report
    /// directory, a layout per member in <dir of the layout>/<name>-front/.
    #[arg(long)]
    front: bool,
    /// Availability levels of the front's sweep above the unconstrained one.
    #[arg(long, default_value_t = 8, value_name = "N", requires = "front")]
    front_levels: usize,
}

/// A share given as `0.999`, `99.9%` or `none`.
#[derive(Debug, Clone, Copy, PartialEq)]
struct IdentifiabilityShare(Option<f64>);

impl std::str::FromStr for IdentifiabilityShare {
    type Err = String;
    fn from_str(text: &str) -> Result<Self, Self::Err> {
        let text = text.trim();
        if text == "none" {
            return Ok(Self(None));
        }
        let (number, scale) = match text.strip_suffix('%') {
            Some(number) => (number, 0.01),
            None => (text, 1.0),
        };
        let share = number
            .trim()
            .parse::<f64>()
            .map(|v| v * scale)
            .map_err(|_| format!("'{text}' is not a share (0.999, 99.9% or none)"))?;
        if !(0.0..=1.0).contains(&share) {
            return Err(format!("'{text}' is not a share between 0 and 1 (0%…100%)"));
        }
        Ok(Self(Some(share)))
    }
}

/// The flags as a pipeline configuration; the default paths are relative to
/// the working directory.
fn config(args: SearchArgs, global: &GlobalOptions) -> anyhow::Result<SearchConfig> {
    let camera = args.camera.camera()?;
    let grid = args.grid.grid(&pipeline::default_grid())?;
    let min_identifiability = match (args.min_identifiability.0, args.identify_criterion.0) {
        (None, _) => None,
        (Some(_), None) => anyhow::bail!(
            "--identify-criterion must be a probability, not none (turn the floor off with --min-identifiability none)"
        ),
        (Some(min_share), Some(min_correct)) => {
            anyhow::ensure!(
                min_correct > 0.0 && min_correct < 1.0,
                "--identify-criterion must be a probability strictly between 0 and 1, got {min_correct}"
            );
            Some(IdentifiabilityFloor {
                min_share,
                min_correct,
            })
        }
    };
    check_degenerate(&args, &grid)?;
    if args.init.is_some() && args.family != FamilyName::Custom {
        anyhow::bail!("--init applies to --family custom");
    }
    if args.centred_hub && args.family != FamilyName::Biprism {
        anyhow::bail!("--centred-hub applies to --family biprism");
    }
    let family = match args.family {
        FamilyName::Biprism => FamilyKind::Biprism {
            centre: !args.no_centre,
            tilts: !args.no_tilts,
            free_hub: !args.centred_hub,
        },
        FamilyName::Tetrahedron => FamilyKind::Tetrahedron {
            centre: !args.no_centre,
        },
        FamilyName::Custom => {
            let start = match &args.init {
                Some(path) => {
                    let layout = naming_file(Layout::load(path), "start layout", path)?;
                    layout
                        .validate()
                        .with_context(|| format!("start layout {}", path.display()))?;
                    Some(layout)
                }
                None => None,
            };
            FamilyKind::Custom {
                count: args.points,
                start,
            }
        }
    };
    let name = args.name.clone().unwrap_or_else(|| {
        let family = args.family.to_possible_value().expect("no skipped values");
        format!("{}-search", family.get_name())
    });
    let layout_path = args
        .out
        .clone()
        .unwrap_or_else(|| PathBuf::from("layouts").join(format!("{name}.json")));
    let report_dir = match (&args.report, &args.out) {
        (Some(dir), _) => dir.clone(),
        (None, Some(out)) => pipeline::report_dir_beside(out),
        (None, None) => PathBuf::from("reports").join(&name),
    };
    let export = (!args.export.is_empty()).then(|| MeshExport {
        formats: args.export.clone(),
        dir: args
            .export_dir
            .clone()
            .unwrap_or_else(|| PathBuf::from("build").join(&name)),
    });
    if args.front_levels == 0 {
        anyhow::bail!("--front-levels must be at least 1");
    }
    let front = args.front.then(|| FrontOutput {
        settings: FrontSettings {
            levels: args.front_levels,
            ..FrontSettings::default()
        },
        layout_dir: layout_path
            .parent()
            .unwrap_or(std::path::Path::new(""))
            .join(format!("{name}-front")),
    });
    Ok(SearchConfig {
        layout_path: layout_path.clone(),
        family,
        constraints: Constraints {
            envelope: args.envelope,
            sphere_diameter_mm: args.sphere_diameter,
            min_gap_mm: args.min_gap,
            min_distance_diff_mm: args.min_distance_diff,
        },
        camera,
        grid,
        objective: ObjectiveSettings {
            objective: args.objective,
            aggregate: args.aggregate,
            translation_weight: args.translation_weight,
            availability_weight: args.availability_weight,
            min_availability: args.min_availability,
            trials: args.trials,
            seed: global.seed,
            noise: args.noise_model,
            observation: args.observation,
        },
        search: SearchSettings {
            optimiser: args.optimiser,
            starts: args.starts,
            iterations: args.iterations,
            particles: args.particles,
            polish_iterations: args.polish.unwrap_or(default_polish(args.iterations)),
            seed: global.seed,
            start_jitter: args.start_jitter,
        },
        compare_solver: args.compare_solver,
        compare_trials: args.compare_trials,
        validate_solvers: super::common::parse_solvers(&args.validate_solvers)?,
        resume: args.resume,
        command: command_line(),
        report_dir,
        checkpoint_dir: args
            .checkpoint_dir
            .unwrap_or_else(|| pipeline::checkpoint_dir_beside(&layout_path)),
        export,
        front,
        name,
        min_identifiability,
        identify_trials: args.identify_trials,
    })
}

/// Exit status of a run stopped by Ctrl-C (128 + SIGINT, as shells report).
pub const EXIT_INTERRUPTED: i32 = 130;

/// Refuses settings under which the objective cannot rank layouts, naming
/// the flag and why, before any work starts.
fn check_degenerate(args: &SearchArgs, grid: &ScenarioGrid) -> anyhow::Result<()> {
    if let Some(&sigma) = grid.sigma_px.values.iter().find(|&&s| s <= 0.0) {
        anyhow::bail!(
            "--noise {sigma}: search needs σ > 0 px; without noise every layout's error is zero, so the objective cannot tell layouts apart (and its ratio to the paper's biprism is 0/0)"
        );
    }
    for (flag, weight) in [
        ("--translation-weight", args.translation_weight),
        ("--availability-weight", args.availability_weight),
    ] {
        anyhow::ensure!(
            weight.is_finite(),
            "{flag} must be finite, got {weight}: an infinite or undefined weight makes every layout's objective infinite or undefined, so none can be ranked"
        );
        anyhow::ensure!(
            weight >= 0.0,
            "{flag} must be non-negative, got {weight}: a negative weight would reward the error it should price"
        );
    }
    let d = args.sphere_diameter;
    anyhow::ensure!(
        d.is_finite() && d > 0.0,
        "--sphere-diameter must be a positive, finite number of mm, got {d}"
    );
    for (flag, value) in [
        ("--min-gap", args.min_gap),
        ("--min-distance-diff", args.min_distance_diff),
    ] {
        anyhow::ensure!(
            value.is_finite() && value >= 0.0,
            "{flag} must be a finite, non-negative number, got {value}"
        );
    }
    anyhow::ensure!(args.trials > 0, "--trials must be at least 1");
    anyhow::ensure!(
        args.compare_trials > 0,
        "--compare-trials must be at least 1"
    );
    Ok(())
}

/// Nelder–Mead's evaluations per start, `SIMPLEX_EVALUATIONS_PER_START +
/// SIMPLEX_EVALUATIONS_PER_ITERATION × iterations`: a line through two
/// measured biprism searches (`search --depth 200..1000`): 8 starts × 3000
/// iterations made 38,423 evaluations, 2 starts × 150 iterations 985. The
/// fixed part is the restarted rounds' initial simplices and the start's
/// repair. The final polish's runs follow the same line: with four runs of
/// 2000 iterations it predicts 51,500 evaluations for the default search
/// (52,818 measured) and 14,120 for 2 starts × 150 iterations (14,019).
const SIMPLEX_EVALUATIONS_PER_START: f64 = 265.0;
/// See [`SIMPLEX_EVALUATIONS_PER_START`].
const SIMPLEX_EVALUATIONS_PER_ITERATION: f64 = 1.51;
/// Objective evaluations timed for the estimate; the fastest counts (the
/// others may be slowed by the machine's other work).
const TIMED_EVALUATIONS: usize = 3;

/// For objectives with a Monte-Carlo term (the slow ones), prints an
/// estimate of the optimisation's time before a run of
/// [`SLOW_RUN_SECONDS`] or more: the fastest of [`TIMED_EVALUATIONS`]
/// evaluations of the paper's biprism, times the evaluations the optimiser
/// will make (a cost model, [`SIMPLEX_EVALUATIONS_PER_START`]), over the
/// threads that run the starts in parallel.
fn print_estimate(config: &SearchConfig) {
    let settings = &config.objective;
    if !settings
        .objective
        .terms
        .iter()
        .any(|(term, _)| matches!(term, Term::MonteCarlo(_)))
    {
        return;
    }
    let constraints = config.constraints;
    let paper = hand_designs(&constraints.envelope, constraints.sphere_diameter_mm).swap_remove(0);
    let (positions, sigmas) = (paper.positions(), paper.point_sigmas());
    // Building the evaluator scores its reference layout once: that is the
    // first timed evaluation.
    let started = Instant::now();
    let evaluator = Evaluator::new(
        config.camera,
        config.grid.scenarios(),
        settings.clone(),
        constraints,
        &positions,
    );
    let mut per_evaluation = started.elapsed().as_secs_f64();
    for _ in 1..TIMED_EVALUATIONS {
        let started = Instant::now();
        let _ = evaluator.evaluate(&positions, &sigmas);
        per_evaluation = per_evaluation.min(started.elapsed().as_secs_f64());
    }
    let search = &config.search;
    let simplex = |iterations: u64| {
        SIMPLEX_EVALUATIONS_PER_START + SIMPLEX_EVALUATIONS_PER_ITERATION * iterations as f64
    };
    let per_start = match search.optimiser {
        Optimiser::NelderMead => simplex(search.iterations),
        Optimiser::ParticleSwarm => {
            search.iterations as f64 * search.particles as f64 + simplex(search.polish_iterations)
        }
        Optimiser::Annealing => search.iterations as f64 + simplex(search.polish_iterations),
    };
    // After Nelder–Mead, the final polish: FINAL_POLISH_STARTS more runs of
    // the polish budget, in parallel.
    let polish_runs = match search.optimiser {
        Optimiser::NelderMead if search.polish_iterations > 0 => FINAL_POLISH_STARTS,
        _ => 0,
    };
    let polish = polish_runs as f64 * simplex(search.polish_iterations);
    let evaluations = per_start * search.starts as f64 + polish;
    // A Monte-Carlo evaluation runs its scenarios on every thread, so the
    // timed one already used the whole machine, as the starts do together:
    // the time is evaluations × that time, not divided by the threads
    // again (checked: 14,019 evaluations of 2 starts × 150 iterations took
    // 182.8 s; two estimates before such runs said 184 s and 212 s).
    let seconds = per_evaluation * evaluations;
    if seconds < SLOW_RUN_SECONDS {
        return;
    }
    eprintln!(
        "estimate: the optimisation takes about {} ({:.3} s per evaluation of {} on the paper's biprism over {} scenarios, the fastest of {TIMED_EVALUATIONS} timed now; × about {:.0} evaluations for {} starts and the final polish (cost model from two measured searches); each evaluation runs on all {} threads); the comparison and the winner's validation follow",
        duration_text(seconds),
        per_evaluation,
        settings.objective,
        config.grid.len(),
        evaluations,
        search.starts,
        rayon::current_num_threads(),
    );
}

pub fn run(args: SearchArgs, global: &GlobalOptions) -> anyhow::Result<()> {
    let config = config(args, global)?;
    if !global.quiet {
        print_estimate(&config);
    }
    progress::catch_ctrl_c();
    let mut bars = progress::Bars::new(global.quiet);
    let result = pipeline::run(&config, &mut bars);
    bars.finish();
    let outcome = result?;
    let layout_path = config.layout_path.display();
    let search_seconds = outcome.search_seconds;
    let Some(summary) = &outcome.summary else {
        eprintln!(
            "interrupted in the {} phase after {:.1} s; the best layout seen is in {}; {layout_path} and the report were left as they were; continue with --resume (checkpoints in {})",
            outcome.interrupted_phase.as_deref().unwrap_or("search"),
            outcome.total_seconds,
            outcome.partial.display(),
            outcome.checkpoints.display()
        );
        std::process::exit(EXIT_INTERRUPTED);
    };
    let v = &summary.verdicts;
    println!(
        "{}: {} ({} evaluations in {search_seconds:.1} s); wrote {layout_path}",
        config.name, outcome.family, outcome.evaluations,
    );
    let mut table = Table::new([
        "design",
        "objective",
        "avail %",
        "RMS rot (°)",
        "RMS trans (mm)",
        "both visible: vs winner",
    ]);
    for row in &summary.designs {
        let mc = &row.monte_carlo[1];
        table.row([
            row.name.clone(),
            measurable(row.evaluation.objective, 4),
            format!("{:.1}", 100.0 * row.evaluation.availability),
            measurable(mc.all.rms_rotation_deg, 4),
            measurable(mc.all.rms_translation_mm, 3),
            format!(
                "{} / {}",
                measurable(mc.common.rms_rotation_deg, 4),
                measurable(mc.winner_common.rms_rotation_deg, 4)
            ),
        ]);
    }
    print!("{}", table.console());
    if summary
        .designs
        .first()
        .is_some_and(|winner| winner.evaluation.availability == 0.0)
    {
        println!(
            "no scenario of the grid shows every sphere of the winner, so its Monte-Carlo errors on visible scenarios are not measurable; check --sphere-diameter, --envelope and the grid"
        );
    }
    let seeds = &summary.header.comparison_seeds;
    println!(
        "winner vs paper biprism ({} Monte-Carlo, {} trials, seeds {} and {}, scenarios both see): RMS rotation {} / {}; availability {:+.1} points",
        config.compare_solver,
        config.compare_trials,
        seeds[0],
        seeds[1],
        percent_lower(v.rotation_reduction_vs_paper_percent[0]),
        percent_lower(v.rotation_reduction_vs_paper_percent[1]),
        v.availability_difference_pp
    );
    let held = &summary.held_out;
    println!(
        "held-out grid ({} scenarios), first order: RMS rotation {:.4}° vs the paper biprism's {:.4}° ({:.1}% lower); availability {:.1}% vs {:.1}%; occluded {} vs {}",
        held.scenarios,
        held.winner_rotation_rms_deg.unwrap_or(f64::NAN),
        held.paper_rotation_rms_deg.unwrap_or(f64::NAN),
        held.rotation_reduction_percent.unwrap_or(f64::NAN),
        100.0 * held.winner_availability,
        100.0 * held.paper_availability,
        held.winner_occluded,
        held.paper_occluded
    );
    println!(
        "objective {:.4} (accuracy {:.4}); availability floor {}: {}",
        summary.outcome.best.evaluation.objective,
        summary.outcome.best.evaluation.accuracy,
        v.availability_floor
            .map_or("none".to_string(), |f| format!("{:.1}%", 100.0 * f)),
        if v.winner_meets_availability_floor {
            "met"
        } else {
            "NOT met"
        }
    );
    if let Some(books) = &summary.identifiability {
        let figures = |f: &Option<layout_opt::search::IdentifiabilityFigures>| {
            f.as_ref().map_or("—".to_string(), |f| {
                format!(
                    "{} of {} visible scenarios, smallest margin {} px",
                    f.identifiable,
                    f.checked,
                    f.smallest_margin_px
                        .map_or("above the gate".into(), |m| format!("{m:.2}"))
                )
            })
        };
        let met = if summary
            .outcome
            .best
            .evaluation
            .meets_identifiability_floor()
        {
            "met"
        } else {
            "NOT met"
        };
        let floor = format!(
            "identifiability floor {:.1}% (each scenario ≥ {:.1}% correct labels): {met}",
            100.0 * books.floor.min_share,
            100.0 * books.floor.min_correct,
        );
        if books.rounds == 0 {
            println!(
                "{floor}; the search's winner: {} (checked in {:.1} s, no repair needed)",
                figures(&books.after),
                books.seconds
            );
        } else {
            println!(
                "{floor}; the search's winner: {}; after {} repair round(s) ({} evaluations, {:.1} s): {}",
                figures(&books.before),
                books.rounds,
                books.evaluations,
                books.seconds,
                figures(&books.after)
            );
        }
        for row in &summary.designs {
            if let Some(text) = &row.not_identifiable {
                println!("  {}: {text}", row.name);
            }
        }
    }
    let yes_no = |b: bool| if b { "yes" } else { "no" };
    if v.admissible_hand_designs.is_empty() {
        println!(
            "winner's objective below every hand design's: {} as drawn (no hand design meets the constraints)",
            yes_no(v.beats_hand_designs_on_objective),
        );
    } else {
        println!(
            "winner's objective below every hand design's: {} as drawn, {} among the admissible ones ({})",
            yes_no(v.beats_hand_designs_on_objective),
            yes_no(v.beats_admissible_hand_designs_on_objective),
            v.admissible_hand_designs.join(", ")
        );
    }
    if let Some(front) = &outcome.front {
        println!(
            "Pareto front ({} members, {} evaluations in {:.1} s; every hand design dominated: {}):",
            front.members.len(),
            front.evaluations,
            front.seconds,
            yes_no(front.dominates_every_hand_design)
        );
        let mut table = Table::new([
            "design",
            "avail %",
            "accuracy",
            "RMS rot (°)",
            "RMS trans (mm)",
            "dominated by",
        ]);
        let fmt = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.4}"));
        for m in &front.members {
            table.row([
                m.name.clone(),
                format!("{:.1}", 100.0 * m.availability),
                format!("{:.4}", m.accuracy),
                fmt(m.rotation_rms_deg),
                fmt(m.translation_rms_mm),
                String::new(),
            ]);
        }
        for h in &front.hand_designs {
            table.row([
                h.name.clone(),
                format!("{:.1}", 100.0 * h.availability),
                format!("{:.4}", h.accuracy),
                fmt(h.rotation_rms_deg),
                fmt(h.translation_rms_mm),
                h.dominated_by.clone().unwrap_or_else(|| "none".into()),
            ]);
        }
        print!("{}", table.console());
    }
    for file in &outcome.exported {
        println!("exported {}", file.display());
    }
    println!(
        "report in {} ({:.1} s in all)",
        config.report_dir.display(),
        outcome.total_seconds
    );
    Ok(())
}

/// A number with `decimals` decimals, or "not measurable" when it is not
/// finite (nothing visible to measure it on).
fn measurable(value: f64, decimals: usize) -> String {
    if value.is_finite() {
        format!("{value:.decimals$}")
    } else {
        "not measurable".into()
    }
}
