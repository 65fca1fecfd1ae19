//! `layout-opt search`: optimise a layout family over a scenario grid.

use super::common::{command_line, CameraArgs, GridArgs};
use super::{progress, GlobalOptions};
use anyhow::Context;
use clap::{Args, ValueEnum};
use indicatif::ProgressBar;
use layout_opt::family::{Constraints, Envelope, Family, FamilyKind};
use layout_opt::layout::Layout;
use layout_opt::mesh::{ExportOptions, Format};
use layout_opt::noise::NoiseModel;
use layout_opt::pnp::Solver;
use layout_opt::scenario::{Range, ScenarioGrid};
use layout_opt::search::checkpoint::{Checkpoints, ResumeStatus};
use layout_opt::search::compare::{compare, hand_designs};
use layout_opt::search::optimise::{self, Candidate, Optimiser, SearchObserver, SearchSettings};
use layout_opt::search::report::{self as search_report, verdicts, SearchHeader, SearchSummary};
use layout_opt::search::{Aggregate, Evaluator, Objective, ObjectiveSettings};
use layout_opt::validate;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Instant;

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
    /// Smallest difference between two pairwise centre distances, mm, so that
    /// spheres can be identified without labels (0 disables).
    #[arg(long, default_value_t = 1.0)]
    min_distance_diff: f64,
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
    /// Cost of losing every scenario to visibility (occlusion, leaving the image).
    #[arg(long, default_value_t = 1.0)]
    availability_weight: f64,
    /// Monte-Carlo trials per scenario for mc: objectives.
    #[arg(long, default_value_t = 20)]
    trials: usize,
    /// Noise model: isotropic, per-point, size[:REF_PX], optionally +outliers:RATE[:PX].
    #[arg(long, default_value = "isotropic")]
    noise_model: NoiseModel,
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
    /// Nelder–Mead polish iterations after particle swarm or annealing.
    #[arg(long, default_value_t = 2000)]
    polish: u64,
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
    /// Report directory. Default: reports/<name>/.
    #[arg(long, value_name = "DIR")]
    report: Option<PathBuf>,
    /// Continue an interrupted search from its checkpoints. Refused, naming
    /// the settings that changed, when the only checkpoints are those of a
    /// different configuration.
    #[arg(long)]
    resume: bool,
    /// Where checkpoints are kept (one directory per name and configuration
    /// hash; removed when the search finishes).
    #[arg(long, value_name = "DIR", default_value = ".layout-opt/checkpoints")]
    checkpoint_dir: PathBuf,
    /// Also export the winner as printable meshes in these formats
    /// (stl, obj, gltf, glb; comma-separated), with `export`'s defaults.
    #[arg(long, value_delimiter = ',', value_name = "FORMATS")]
    export: Vec<Format>,
    /// Directory of the exported meshes. Default: build/<name>/.
    #[arg(long, value_name = "DIR")]
    export_dir: Option<PathBuf>,
}

/// The default search grid: depths from --depth (required in spirit; 200..1000
/// if omitted), X offsets 0…100 mm, tilt −60°…60° in 10° steps, σ 0.5 px.
fn default_grid() -> ScenarioGrid {
    ScenarioGrid::new(
        "200..1000".parse().expect("valid"),
        "0..100".parse().expect("valid"),
        Range::single(0.0),
        "-60..60:10".parse().expect("valid"),
        Range::single(0.0),
        Range::single(0.0),
        Range::single(0.5),
    )
    .expect("the default grid is valid")
}

/// Draws progress and writes the best-so-far layout atomically.
struct Reporter {
    bar: ProgressBar,
    family: Family,
    name: String,
    path: PathBuf,
    provenance: serde_json::Value,
    write_error: Mutex<Option<String>>,
    total_iterations: u64,
    iterations: Mutex<Vec<u64>>,
}

impl SearchObserver for Reporter {
    fn improved(&self, candidate: &Candidate) {
        let mut layout = self.family.layout(&self.name, &candidate.params);
        let mut provenance = self.provenance.clone();
        provenance["status"] = "best so far (search running or interrupted)".into();
        provenance["score"] = candidate.evaluation.cost.into();
        layout.provenance = Some(provenance);
        if let Err(e) = layout.save_atomic(&self.path) {
            *self
                .write_error
                .lock()
                .expect("no panics while holding the lock") = Some(e.to_string());
        }
        self.bar
            .set_message(format!("best {:.4}", candidate.evaluation.cost));
    }

    fn progress(&self, start: usize, iteration: u64, _evaluations: usize, _best_cost: f64) {
        let mut iterations = self
            .iterations
            .lock()
            .expect("no panics while holding the lock");
        if let Some(slot) = iterations.get_mut(start) {
            *slot = (*slot).max(iteration);
        }
        self.bar
            .set_position(iterations.iter().sum::<u64>().min(self.total_iterations));
    }
}

fn family_description(family: &Family) -> String {
    match family.kind() {
        FamilyKind::Biprism {
            centre,
            tilts,
            free_hub,
        } => format!(
            "biprism: 6 arm lengths{}{}{}",
            if *tilts { " + 2 tilts per arm" } else { "" },
            if *free_hub {
                " + hub position"
            } else {
                ", hub at the envelope centre"
            },
            if *centre {
                " + centre point"
            } else {
                ", no centre point"
            }
        ),
        FamilyKind::Tetrahedron { centre } => format!(
            "tetrahedron: 4 free vertices{}",
            if *centre { " + centre point" } else { "" }
        ),
        FamilyKind::Custom {
            start: Some(layout),
            ..
        } => format!(
            "custom: {} points from {}, {} fixed",
            layout.points.len(),
            layout.name,
            layout.points.iter().filter(|p| p.fixed).count()
        ),
        FamilyKind::Custom { count, .. } => format!("custom: {count} free points"),
    }
}

pub fn run(args: SearchArgs, global: &GlobalOptions) -> anyhow::Result<()> {
    anyhow::ensure!(
        args.sphere_diameter > 0.0 && args.sphere_diameter.is_finite(),
        "--sphere-diameter must be positive"
    );
    anyhow::ensure!(
        args.min_gap >= 0.0 && args.min_distance_diff >= 0.0,
        "--min-gap and --min-distance-diff must be non-negative"
    );
    anyhow::ensure!(
        args.translation_weight >= 0.0 && args.availability_weight >= 0.0,
        "objective weights must be non-negative"
    );
    anyhow::ensure!(
        args.trials > 0 && args.compare_trials > 0,
        "--trials and --compare-trials must be at least 1"
    );
    let camera = args.camera.camera()?;
    let grid = args.grid.grid(&default_grid())?;
    let kind = match args.family {
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
                    let layout = Layout::load(path)
                        .with_context(|| format!("loading start layout {}", path.display()))?;
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
    if args.init.is_some() && args.family != FamilyName::Custom {
        anyhow::bail!("--init applies to --family custom");
    }
    if args.centred_hub && args.family != FamilyName::Biprism {
        anyhow::bail!("--centred-hub applies to --family biprism");
    }
    let family = Family::new(kind, args.envelope, args.sphere_diameter)?;
    let constraints = Constraints {
        envelope: args.envelope,
        sphere_diameter_mm: args.sphere_diameter,
        min_gap_mm: args.min_gap,
        min_distance_diff_mm: args.min_distance_diff,
    };
    let settings = ObjectiveSettings {
        objective: args.objective.clone(),
        aggregate: args.aggregate,
        translation_weight: args.translation_weight,
        availability_weight: args.availability_weight,
        trials: args.trials,
        seed: global.seed,
        noise: args.noise_model,
    };
    let search_settings = SearchSettings {
        optimiser: args.optimiser,
        starts: args.starts,
        iterations: args.iterations,
        particles: args.particles,
        polish_iterations: args.polish,
        seed: global.seed,
        start_jitter: args.start_jitter,
    };
    let name = args
        .name
        .clone()
        .unwrap_or_else(|| format!("{}-search", family.name()));
    let layout_path = args
        .out
        .clone()
        .unwrap_or_else(|| PathBuf::from("layouts").join(format!("{name}.json")));
    let report_dir = args
        .report
        .clone()
        .unwrap_or_else(|| PathBuf::from("reports").join(&name));
    if let Some(parent) = layout_path.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent)
            .with_context(|| format!("creating {}", parent.display()))?;
    }

    let hand = hand_designs(&args.envelope, args.sphere_diameter);
    let paper = &hand[0];
    let evaluator = Evaluator::new(
        camera,
        grid.scenarios(),
        settings.clone(),
        constraints,
        &paper.positions(),
    );
    let command = command_line();
    // Everything that decides which layouts the search evaluates: the key of
    // its checkpoints.
    let search_config = serde_json::json!({
        "version": env!("CARGO_PKG_VERSION"),
        "family": family_description(&family),
        "start_layout": match family.kind() {
            FamilyKind::Custom { start: Some(layout), .. } => serde_json::to_value(layout)?,
            _ => serde_json::Value::Null,
        },
        "sphere_diameter_mm": args.sphere_diameter,
        "constraints": constraints,
        "camera": camera,
        "grid": grid,
        "objective": settings,
        "search": search_settings,
    });
    let (checkpoints, resume_status) =
        Checkpoints::prepare(&args.checkpoint_dir, &name, &search_config, args.resume)?;
    match resume_status {
        ResumeStatus::Resuming => eprintln!(
            "resuming from the checkpoints in {}",
            checkpoints.dir().display()
        ),
        ResumeStatus::NothingToResume => eprintln!(
            "no checkpoint of this configuration (hash {}); starting afresh",
            checkpoints.hash()
        ),
        ResumeStatus::Fresh => {}
    }
    let provenance = serde_json::json!({
        "command": command,
        "seed": global.seed,
        "objective": settings.objective.to_string(),
        "aggregate": format!("{:?}", settings.aggregate).to_lowercase(),
        "version": env!("CARGO_PKG_VERSION"),
    });

    static STOP: AtomicBool = AtomicBool::new(false);
    // A second handler cannot be installed in the same process; that only
    // matters to tests that call run twice, and they never press Ctrl-C.
    let _ = ctrlc::set_handler(|| STOP.store(true, Ordering::SeqCst));

    let total_iterations = args.starts as u64
        * (args.iterations
            + if args.optimiser == Optimiser::NelderMead {
                0
            } else {
                args.polish
            });
    let bar = progress::bar(total_iterations, "searching", global.quiet);
    let reporter = Arc::new(Reporter {
        bar: bar.clone(),
        family: family.clone(),
        name: name.clone(),
        path: layout_path.clone(),
        provenance: provenance.clone(),
        write_error: Mutex::new(None),
        total_iterations,
        iterations: Mutex::new(vec![0; args.starts]),
    });
    let started = Instant::now();
    let outcome = optimise::run(
        &family,
        &evaluator,
        &search_settings,
        &STOP,
        reporter.clone(),
        Some(&checkpoints),
    )?;
    let search_seconds = started.elapsed().as_secs_f64();
    bar.finish_and_clear();
    if let Some(error) = reporter
        .write_error
        .lock()
        .expect("no panics while holding the lock")
        .take()
    {
        anyhow::bail!("could not write the best-so-far layout: {error}");
    }

    let mut winner = family.layout(&name, &outcome.best.params);
    let mut final_provenance = provenance.clone();
    final_provenance["score"] = outcome.best.evaluation.cost.into();
    final_provenance["status"] = if outcome.interrupted {
        "interrupted: best layout seen".into()
    } else {
        "finished".into()
    };
    final_provenance["evaluations"] = outcome.evaluations.into();
    winner.provenance = Some(final_provenance);
    winner.save_atomic(&layout_path)?;
    if outcome.interrupted {
        println!(
            "interrupted after {search_seconds:.1} s; the best layout seen is in {}; continue with --resume (checkpoints in {})",
            layout_path.display(),
            checkpoints.dir().display()
        );
        return Ok(());
    }
    checkpoints.remove()?;
    let violations = outcome.best.evaluation.violations;
    if !violations.feasible() {
        anyhow::bail!(
            "the constraints cannot all be met (best layout, kept in {}): {}",
            layout_path.display(),
            violations.describe(&constraints).join("; ")
        );
    }

    // Compare on the same scenarios and draws, on the search seed and an
    // independent validation seed.
    let validation_seed = global.seed.wrapping_add(1);
    let start_layout = family.layout(&format!("{name}-start"), &family.initial());
    let mut designs = vec![
        (name.clone(), winner.clone()),
        ("start".to_string(), start_layout),
    ];
    let paper_index = designs.len();
    designs.extend(hand.iter().map(|l| (l.name.clone(), l.clone())));
    let hand_range = paper_index..designs.len();
    // Hand designs that break a constraint (the paper's biprism and the cube
    // corners repeat pairwise distances) also appear made admissible, by the
    // search's own repair, so the winner meets them like for like.
    for layout in &hand {
        if constraints.violations(&layout.positions()).feasible() {
            continue;
        }
        let free = Family::new(
            FamilyKind::Custom {
                count: layout.points.len(),
                start: Some(layout.clone()),
            },
            args.envelope,
            args.sphere_diameter,
        )?;
        let params = optimise::repair(&free, &evaluator, &free.initial())?;
        let mut admissible = free.layout(&format!("{}-admissible", layout.name), &params);
        admissible.provenance = Some(serde_json::json!({
            "source": format!("{} moved to the nearest layout that meets the constraints (the search's repair)", layout.name),
        }));
        designs.push((admissible.name.clone(), admissible));
    }
    let admissible_range = hand_range.end..designs.len();
    let seeds = [global.seed, validation_seed];
    let rows = compare(
        &camera,
        &evaluator,
        &designs,
        args.compare_solver,
        args.compare_trials,
        &seeds,
        args.noise_model,
    )?;
    let summary = SearchSummary {
        header: SearchHeader {
            command: command.clone(),
            version: env!("CARGO_PKG_VERSION").to_string(),
            family: family_description(&family),
            constraints,
            objective: settings,
            search: search_settings,
            grid: grid.clone(),
            camera,
            comparison_solver: args.compare_solver.name().to_string(),
            comparison_trials: args.compare_trials,
            comparison_seeds: seeds.to_vec(),
        },
        verdicts: verdicts(&rows, paper_index, hand_range, admissible_range),
        outcome,
        designs: rows,
    };
    search_report::write(&report_dir, &summary)?;
    let validate_solvers = super::validate::parse_solvers(&args.validate_solvers)?;
    write_winner_validation(
        &report_dir.join("winner-validation"),
        &winner,
        &camera,
        &grid,
        validate_solvers,
        validation_seed,
        args.compare_trials,
        args.noise_model,
        &command,
    )?;
    let total_seconds = started.elapsed().as_secs_f64();
    std::fs::write(
        report_dir.join("run.json"),
        serde_json::to_string_pretty(&serde_json::json!({
            "search_seconds": search_seconds,
            "total_seconds": total_seconds,
            "evaluations": summary.outcome.evaluations,
            "threads": rayon::current_num_threads(),
        }))? + "\n",
    )?;

    let exported = if args.export.is_empty() {
        None
    } else {
        let dir = args
            .export_dir
            .clone()
            .unwrap_or_else(|| PathBuf::from("build").join(&name));
        let options = ExportOptions {
            formats: args.export.clone(),
            marker: Default::default(),
            resolution_mm: None,
        };
        let report = layout_opt::mesh::export(&winner, &options, &dir)
            .with_context(|| format!("exporting the winner to {}", dir.display()))?;
        Some(report.files)
    };
    let v = &summary.verdicts;
    println!(
        "{name}: {} ({} evaluations in {search_seconds:.1} s); wrote {}",
        family_description(&family),
        summary.outcome.evaluations,
        layout_path.display()
    );
    println!(
        "{:<26} {:>10} {:>8} {:>14} {:>16} {:>22}",
        "design",
        "objective",
        "avail %",
        "RMS rot (°)",
        "RMS trans (mm)",
        "both visible: vs winner"
    );
    for row in &summary.designs {
        let mc = &row.monte_carlo[1];
        println!(
            "{:<26} {:>10.4} {:>8.1} {:>14.4} {:>16.3} {:>12.4} / {:.4}",
            row.name,
            row.evaluation.objective,
            100.0 * row.evaluation.availability,
            mc.all.rms_rotation_deg,
            mc.all.rms_translation_mm,
            mc.common.rms_rotation_deg,
            mc.winner_common.rms_rotation_deg
        );
    }
    println!(
        "winner vs paper biprism ({} Monte-Carlo, {} trials, seeds {} and {}, scenarios both see): RMS rotation {:.1}% / {:.1}% lower; availability {:+.1} points",
        args.compare_solver,
        args.compare_trials,
        seeds[0],
        seeds[1],
        v.rotation_reduction_vs_paper_percent[0],
        v.rotation_reduction_vs_paper_percent[1],
        v.availability_difference_pp
    );
    println!(
        "winner's objective below every hand design's: {} as drawn, {} among the admissible ones ({})",
        if v.beats_hand_designs_on_objective { "yes" } else { "no" },
        if v.beats_admissible_hand_designs_on_objective { "yes" } else { "no" },
        v.admissible_hand_designs.join(", ")
    );
    for file in exported.iter().flatten() {
        println!("exported {}", file.path.display());
    }
    println!(
        "report in {} ({total_seconds:.1} s in all)",
        report_dir.display()
    );
    Ok(())
}

#[allow(clippy::too_many_arguments)]
fn write_winner_validation(
    dir: &Path,
    winner: &Layout,
    camera: &layout_opt::camera::Camera,
    grid: &ScenarioGrid,
    solvers: Vec<Solver>,
    seed: u64,
    trials: usize,
    noise: NoiseModel,
    command: &str,
) -> anyhow::Result<()> {
    let config = layout_opt::montecarlo::MonteCarloConfig {
        trials,
        seed,
        solvers,
        noise,
        gross_threshold_deg: layout_opt::montecarlo::DEFAULT_GROSS_THRESHOLD_DEG,
    };
    let validation = validate::run(winner, camera, grid, &config, command, &|_| {})?;
    validate::write_report(dir, winner, &validation)?;
    Ok(())
}
