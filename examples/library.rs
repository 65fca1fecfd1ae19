//! layout-opt as a library: one PnP solve, the first-order pose covariance of
//! a layout, a validation's numbers on a few scenarios, and a small search
//! through the same workflow as
//! `layout-opt search`, written into a fresh temporary directory.
//!
//! Run: `cargo run --release --features examples --example library`

use layout_opt::camera::Camera;
use layout_opt::error_model::first_order::pose_covariance_isotropic;
use layout_opt::layout::Layout;
use layout_opt::observer::Observer;
use layout_opt::pnp::Solver;
use layout_opt::pose::{rotation_error_deg, translation_error_percent, Pose};
use layout_opt::search::{workflow, SearchConfig};
use layout_opt::synthetic::{project_with_noise, stream_rng};
use layout_opt::validate::{self, ValidateConfig};
use nalgebra::{Rotation3, Vector3};

/// Prints each phase once and every log line; never interrupts.
#[derive(Default)]
struct Phases {
    current: String,
}

impl Observer for Phases {
    fn progress(&mut self, phase: &str, _done: u64, total: u64) {
        if phase != self.current {
            println!("  {phase} ({total} steps)");
            self.current = phase.to_string();
        }
    }

    fn log(&mut self, line: &str) {
        println!("  {line}");
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let camera = Camera::paper();
    let layout = Layout::paper_biprism();
    let truth = Pose::new(
        Rotation3::from_euler_angles(0.3, -0.2, 0.1),
        Vector3::new(20.0, -10.0, 500.0),
    );
    let sigma_px = 0.5;

    // 1. One PnP problem: the paper's biprism at 500 mm, σ = 0.5 px.
    let mut rng = stream_rng(7, 0, 0);
    let problem = project_with_noise(&mut rng, &camera, layout.positions(), truth, sigma_px)
        .ok_or("a point is behind the camera")?;
    let estimate = Solver::Ml.solve_best(&problem.object, &problem.normalised)?;
    println!(
        "ML solve: rotation error {:.4}°, translation error {:.3}%",
        rotation_error_deg(&truth.rotation, &estimate.rotation),
        translation_error_percent(&truth.translation, &estimate.translation)
    );

    // 2. The first-order (Cramér–Rao) covariance of the same layout and pose.
    let covariance = pose_covariance_isotropic(&camera, &truth, &layout.positions(), sigma_px)?;
    println!(
        "first order: RMS rotation {:.4}°, RMS translation {:.3} mm",
        covariance.rms_rotation_deg(),
        covariance.rms_translation_mm()
    );

    // 3. The validation's numbers (no files) of the same layout on six
    //    scenarios: every solver's Monte-Carlo error beside the limit.
    let mut check = ValidateConfig::new(layout.clone(), vec![Solver::Ml, Solver::Epnp]);
    check.volume =
        layout_opt::volume::WorkingVolume::Grid(layout_opt::scenario::ScenarioGrid::new(
            "400,700".parse()?,
            layout_opt::scenario::Range::single(0.0),
            layout_opt::scenario::Range::single(0.0),
            "-30,0,30".parse()?,
            layout_opt::scenario::Range::single(0.0),
            layout_opt::scenario::Range::single(0.0),
            layout_opt::scenario::Range::single(sigma_px),
        )?);
    check.monte_carlo.trials = 50;
    check.identifiability.trials = 0;
    let validation = validate::analyse(&check, &mut layout_opt::observer::Silent)?;
    for row in &validation.overview.solvers {
        println!(
            "validate {}: RMS rotation {:.4}° over {} visible scenarios ({:.3}× the first-order limit)",
            row.pooled.solver.name(),
            row.pooled.rms_rotation_deg,
            validation.overview.visibility.visible,
            row.pooled.first_order.rotation_ratio.unwrap_or(f64::NAN)
        );
    }

    // 4. A two-start search on a small grid, everything under a fresh
    //    temporary directory.
    let dir = std::env::temp_dir().join(format!("layout-opt-library-{}", std::process::id()));
    let mut config = SearchConfig::new("example", &dir);
    config.volume =
        layout_opt::volume::WorkingVolume::Grid(layout_opt::scenario::ScenarioGrid::new(
            "300,800".parse()?,
            "0,60".parse()?,
            layout_opt::scenario::Range::single(0.0),
            "-40..40:20".parse()?,
            layout_opt::scenario::Range::single(0.0),
            layout_opt::scenario::Range::single(0.0),
            layout_opt::scenario::Range::single(sigma_px),
        )?);
    config.search.starts = 2;
    config.search.iterations = 150;
    config.compare_trials = 20;
    config.validate_solvers = vec![Solver::ParallelWeighted, Solver::Ml];
    config.command = "cargo run --release --features examples --example library".into();
    println!("search into {}:", dir.display());
    let outcome = workflow::run(&config, &mut Phases::default())?;
    let summary = outcome.summary.as_ref().ok_or("interrupted")?;
    println!(
        "winner {}: objective {:.4} ({} evaluations, {:.1} s); RMS rotation vs the paper's biprism: {:+.1}%",
        outcome.winner.name,
        outcome.objective,
        outcome.evaluations,
        outcome.total_seconds,
        -summary.verdicts.rotation_reduction_vs_paper_percent[0]
    );
    println!(
        "layout {}, report {}",
        config.layout_path.display(),
        config.report_dir.join("report.md").display()
    );
    Ok(())
}
