//! `layout-opt validate`: a layout's sensitivity report.

use super::common::{
    command_line, duration_text, naming_file, parse_solvers, CameraArgs, GridArgs, SLOW_RUN_SECONDS,
};
use super::{progress, GlobalOptions};
use anyhow::Context;
use clap::Args;
use layout_opt::error_model::fabrication::{self, FabricationError};
use layout_opt::layout::Layout;
use layout_opt::montecarlo::{MonteCarloConfig, MonteCarloError, DEFAULT_GROSS_THRESHOLD_DEG};
use layout_opt::noise::NoiseModel;
use layout_opt::pnp::Solver;
use layout_opt::report::Table;
use layout_opt::scenario::ScenarioGrid;
use layout_opt::sensitivity::pipeline::{self, SensitivityConfig, SensitivityOutcome};
use layout_opt::sensitivity::{self, SensitivityError};
use layout_opt::sphere_image::Observation;
use std::path::PathBuf;

/// Tilt step of the default grid, degrees (the paper's protocol).
pub const DEFAULT_TILT_STEP_DEG: f64 = 2.0;
/// Tilt step of the default grid when the solvers include a polynomial
/// solver (`dls`, `opnp`: 0.1–1 ms per solve, 15–150× the others), so that
/// `--solvers all` on the default grid at 200 trials fits in a minute on two
/// cores. `--tilt -90..90:2` restores the full protocol.
pub const POLYNOMIAL_TILT_STEP_DEG: f64 = 10.0;

/// Flags of `validate`.
#[derive(Debug, Args)]
pub struct ValidateArgs {
    /// Layout file (JSON). Default: the paper's biprism (L = 50 mm, 10 mm spheres).
    layout: Option<PathBuf>,
    #[command(flatten)]
    grid: GridArgs,
    #[command(flatten)]
    camera: CameraArgs,
    /// Solvers: `all` or a comma list of stable names (see `solve --list`).
    #[arg(long, default_value = "all")]
    solvers: String,
    /// Monte-Carlo trials per scenario.
    #[arg(long, default_value_t = 200)]
    trials: usize,
    /// Noise model: isotropic, per-point, size[:REF_PX], each optionally +outliers:RATE[:PX].
    #[arg(long, default_value = "isotropic")]
    noise_model: NoiseModel,
    /// Rotation error counted as a gross failure, degrees.
    #[arg(long, default_value_t = DEFAULT_GROSS_THRESHOLD_DEG)]
    gross_threshold: f64,
    /// Image point of a sphere: `ellipse-centre` (its silhouette's centre,
    /// what a blob detector measures) or `centre` (its projected centre).
    /// Noise is added on top.
    #[arg(long, default_value = "ellipse-centre")]
    observation: Observation,
    /// Monte-Carlo trials of the unlabelled solver per visible scenario: the
    /// blobs shuffled, how often it labels them wrongly (0: the prediction
    /// from the noise-free margin alone).
    #[arg(long, default_value_t = layout_opt::sensitivity::DEFAULT_IDENTIFY_TRIALS)]
    identify_trials: usize,
    /// Least predicted probability of a correct labelling for a scenario to
    /// count as identifiable (0.999 or 99.9%).
    #[arg(long, default_value = "0.999", value_name = "PROBABILITY")]
    identify_criterion: String,
    /// Output directory. Default: reports/<layout name>/.
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// Sphere-centre fabrication error σ_fab, mm per coordinate: after the
    /// report, a Monte-Carlo run prints a new perturbed part per trial and
    /// solves it with the nominal layout, beside the first-order model
    /// with the fabrication term. 0 (the default) runs nothing more.
    #[arg(long, value_name = "MM", default_value_t = 0.0)]
    fabrication_sigma: f64,
}

/// A probability strictly between 0 and 1, as `0.999` or `99.9%`.
fn parse_probability(text: &str) -> anyhow::Result<f64> {
    let text = text.trim();
    let value = match text.strip_suffix('%') {
        Some(number) => number.trim().parse::<f64>().map(|v| v / 100.0),
        None => text.parse::<f64>(),
    }
    .map_err(|_| anyhow::anyhow!("'{text}' is not a probability (0.999 or 99.9%)"))?;
    anyhow::ensure!(
        value > 0.0 && value < 1.0,
        "'{text}' must be a probability strictly between 0 and 1"
    );
    Ok(value)
}

pub fn run(args: ValidateArgs, global: &GlobalOptions) -> anyhow::Result<()> {
    let layout = match &args.layout {
        Some(path) => naming_file(Layout::load(path), "layout", path)?,
        None => Layout::paper_biprism(),
    };
    layout
        .validate()
        .with_context(|| format!("layout {}", layout.name))?;
    let camera = args.camera.camera()?;
    let solvers = parse_solvers(&args.solvers)?;
    let polynomial = solvers
        .iter()
        .any(|s| matches!(s, Solver::Dls | Solver::Opnp));
    let tilt_step = if polynomial {
        POLYNOMIAL_TILT_STEP_DEG
    } else {
        DEFAULT_TILT_STEP_DEG
    };
    let coarsened = polynomial && args.grid.tilt.is_none();
    let grid = args.grid.grid(&ScenarioGrid::paper_protocol(tilt_step))?;
    anyhow::ensure!(args.trials > 0, "--trials must be at least 1");
    let tilt_note = coarsened.then(|| {
        format!(
            "default tilt step {POLYNOMIAL_TILT_STEP_DEG}° instead of the paper's {DEFAULT_TILT_STEP_DEG}° because the solvers include dls or opnp; pass --tilt -90..90:{DEFAULT_TILT_STEP_DEG} for the full protocol"
        )
    });
    anyhow::ensure!(
        args.gross_threshold > 0.0 && args.gross_threshold.is_finite(),
        "--gross-threshold must be a positive, finite number of degrees, got {}",
        args.gross_threshold
    );
    anyhow::ensure!(
        args.fabrication_sigma >= 0.0 && args.fabrication_sigma.is_finite(),
        "{}",
        FabricationError::BadSigma(args.fabrication_sigma)
    );
    let identify_criterion =
        parse_probability(&args.identify_criterion).context("--identify-criterion")?;
    let config = SensitivityConfig {
        out_dir: args
            .out
            .clone()
            .unwrap_or_else(|| PathBuf::from("reports").join(&layout.name)),
        layout,
        camera,
        grid,
        monte_carlo: MonteCarloConfig {
            trials: args.trials,
            seed: global.seed,
            solvers,
            noise: args.noise_model,
            gross_threshold_deg: args.gross_threshold,
            observation: args.observation,
        },
        identifiability: layout_opt::sensitivity::IdentifiabilityCheck {
            min_correct: identify_criterion,
            trials: args.identify_trials,
        },
        command: command_line(),
        grid_note: tilt_note.clone(),
    };
    if let Some(note) = &tilt_note {
        println!("note: {note}");
    }
    progress::catch_ctrl_c();
    if !global.quiet {
        // Every run is estimated (the calibration takes a fraction of a
        // second); only the slow ones say so.
        let estimate = sensitivity::estimate_seconds(
            &config.layout,
            &config.camera,
            &config.grid,
            &config.monte_carlo,
        )?;
        if estimate.seconds >= SLOW_RUN_SECONDS {
            eprintln!(
            "estimate: about {} on {} threads (a timed calibration run of {} scenarios × {} trials took {:.2} s; scaled to {} scenarios × {} trials)",
            duration_text(estimate.seconds),
            rayon::current_num_threads(),
            estimate.calibration_scenarios,
            estimate.calibration_trials,
            estimate.calibration_seconds,
            config.grid.len(),
            config.monte_carlo.trials
        );
        }
    }
    let mut bars = progress::Bars::new(global.quiet);
    let result = pipeline::run(&config, &mut bars);
    bars.finish();
    if let Err(SensitivityError::MonteCarlo(MonteCarloError::Interrupted)) = result {
        eprintln!("interrupted: no report written");
        std::process::exit(progress::EXIT_INTERRUPTED);
    }
    let SensitivityOutcome {
        validation,
        solves,
        seconds,
    } = result?;
    let (layout, out) = (&config.layout, &config.out_dir);
    let (camera, grid) = (&config.camera, &config.grid);
    let config = &config.monte_carlo;
    let threads = rayon::current_num_threads();

    let summary = &validation.summary;
    let v = &summary.visibility;
    println!(
        "{}: {} scenarios × {} trials, seed {}: {} visible, {} occluded, {} outside the image, {} behind the camera (each scenario counted once, in the order behind, outside, occluded)",
        layout.name, v.scenarios, config.trials, config.seed, v.visible, v.occluded, v.outside_image, v.behind_camera
    );
    if v.visible == 0 {
        println!("no scenario is visible, so no error is measurable; see {} for why each scenario is hidden", out.join("scenarios.csv").display());
    }
    let mut table = Table::new([
        "solver",
        "RMS rot (°)",
        "/ 1st order",
        "RMS trans (mm)",
        "gross",
    ]);
    for row in &summary.solvers {
        let p = &row.pooled;
        table.row([
            p.solver.name().to_string(),
            format!("{:.4}", p.rms_rotation_deg),
            row.pooled
                .first_order
                .rotation_ratio
                .map_or("—".into(), |r| format!("{r:.3}")),
            format!("{:.3}", p.rms_translation_mm),
            p.gross_failures.to_string(),
        ]);
    }
    if !summary.solvers.is_empty() {
        print!("{}", table.console());
    }
    if let Some(first) = summary.solvers.first() {
        let (f, t) = (&first.pooled.first_order, &first.pooled.transfer);
        let show = |v: Option<f64>, unit: &str| {
            v.filter(|v| v.is_finite())
                .map_or("not measurable".into(), |v| format!("{v:.4}{unit}"))
        };
        println!(
            "first-order limit: {} / {} over {} scenarios; transfer model: {} over {} scenarios{}",
            show(f.predicted_rms_rotation_deg, "°"),
            show(f.predicted_rms_translation_mm, " mm"),
            f.scenarios,
            show(t.predicted_rms_rotation_deg, "°"),
            t.scenarios,
            if summary.header.grid.sigma_px.values.contains(&0.0) {
                " (the models predict nothing at σ = 0)"
            } else {
                ""
            }
        );
    }
    let s = &summary.systematic;
    println!(
        "observation {}: image bias up to {:.3} px (median {:.3} px); systematic rotation (first-order bias, RMS) {:.2e}° beside random {:.2e}°, translation {:.2e} mm beside {:.2e} mm",
        config.observation,
        s.max_displacement_px,
        s.median_displacement_px,
        s.first_order_bias.rms_rotation_deg,
        s.first_order_random.rms_rotation_deg,
        s.first_order_bias.rms_translation_mm,
        s.first_order_random.rms_translation_mm
    );
    let id = &summary.identifiability;
    println!(
        "identifiability (criterion {:.1}% correct labels): {} of {} visible scenarios, smallest margin {}; predicted wrong-label rate {} (mean), Monte-Carlo {} ({} of {} trials)",
        100.0 * id.min_correct,
        id.identifiable,
        id.scenarios,
        id.smallest_margin_px
            .map_or("above the gate".to_string(), |m| format!("{m:.3} px")),
        id.mean_predicted_wrong
            .map_or("—".to_string(), |p| format!("{p:.2e}")),
        id.monte_carlo_wrong
            .map_or("—".to_string(), |p| format!("{p:.2e}")),
        id.trials.wrong,
        id.trials.trials
    );
    println!(
        "{solves} solves in {seconds:.1} s on {threads} threads ({:.0} solves/s); report in {}",
        solves as f64 / seconds.max(1e-9),
        out.display()
    );
    if args.fabrication_sigma > 0.0 {
        fabrication_check(&args, layout, camera, grid, config, &bars)?;
    }
    Ok(())
}

/// `--fabrication-sigma`: a Monte-Carlo run with a new perturbed part per
/// trial, solved with the nominal layout, beside the first-order model.
fn fabrication_check(
    args: &ValidateArgs,
    layout: &Layout,
    camera: &layout_opt::camera::Camera,
    grid: &ScenarioGrid,
    config: &MonteCarloConfig,
    bars: &progress::Bars,
) -> anyhow::Result<()> {
    use layout_opt::observer::Observer;
    let solver = config.solvers[0];
    let result = fabrication::monte_carlo(
        camera,
        &grid.scenarios(),
        &layout.positions(),
        layout.sphere_diameter_mm,
        args.fabrication_sigma,
        config.trials,
        config.seed,
        solver,
        &|| bars.interrupted(),
    );
    if let Err(FabricationError::Interrupted) = result {
        eprintln!("interrupted during the fabrication check");
        std::process::exit(progress::EXIT_INTERRUPTED);
    }
    let run = result?;
    let show = |v: Option<f64>| v.map_or("not measurable".into(), |v| format!("{v:.4}°"));
    let ratio = run
        .measured_rotation_deg()
        .zip(run.predicted_rotation_deg())
        .map_or("—".into(), |(m, p)| format!("{:.3}", m / p));
    println!(
        "fabrication σ {} mm ({}, a new part per trial, projected centres, isotropic noise; {} scenarios × {} trials): first-order RMS rotation {} from the noise, {} from the fabrication, {} both; Monte-Carlo {} (ratio {ratio})",
        args.fabrication_sigma,
        run.solver,
        run.outcomes.len(),
        run.trials,
        show(run.noise_rotation_deg()),
        show(run.fabrication_rotation_deg()),
        show(run.predicted_rotation_deg()),
        show(run.measured_rotation_deg()),
    );
    Ok(())
}
