//! `validate SET.json`: the set's markers and cross matrix (the work is
//! [`layout_opt::search::set::validation`]), on the run kernel: the report
//! directory checked and locked before any work, and Ctrl-C answered
//! within a poll while the set is analysed.

use super::common::command_line;
use super::common::parse_probability;
use super::validate::{protocol_volume, ValidateArgs, DEFAULT_TRIALS};
use super::{progress, GlobalOptions};
use anyhow::Context;
use layout_opt::camera::Camera;
use layout_opt::identifiability::IdentifiabilitySettings;
use layout_opt::kernel::stop::abandon_on_stop;
use layout_opt::kernel::{Interrupted, OutputPlan};
use layout_opt::montecarlo::DEFAULT_GROSS_THRESHOLD_DEG;
use layout_opt::search::set::validation::validate_set;
use layout_opt::set::MarkerSet;
use layout_opt::validate::DEFAULT_TILT_STEP_DEG;
use std::path::{Path, PathBuf};

/// `validate SET.json`: each marker's identifiability and the set's cross
/// matrix over the protocol volume, with seeded trials against the whole
/// set; `set-report.md` and `set.json` in `--out` (default
/// `reports/<set>/`). The flags of a single layout's validation that were
/// given are refused: a set's validation uses none of them.
pub fn run(path: &Path, args: &ValidateArgs, global: &GlobalOptions) -> anyhow::Result<()> {
    let ignored = single_layout_flags(args);
    if let Some(flag) = ignored.first() {
        anyhow::bail!(
            "{flag} applies to a single layout's validation; a set's (SET.json) predicts and tries identification only: leave out {}",
            ignored.join(", ")
        );
    }
    let settings = IdentifiabilitySettings {
        min_correct: parse_probability(&args.identify_criterion).context("--identify-criterion")?,
        trials: args.identify_trials,
        seed: global.seed,
        observation: args.observation,
        noise: args.noise_model.model,
    };
    let volume = protocol_volume(args, DEFAULT_TILT_STEP_DEG, global.seed)?;
    let camera: Camera = args.camera.camera()?;
    let set = MarkerSet::load(path)?;
    set.check_distinct()?;
    let out_dir = args
        .out
        .clone()
        .unwrap_or_else(|| PathBuf::from("reports").join(&set.name));
    let set_dir = layout_opt::files::directory_of(path);
    let mut plan = OutputPlan::new();
    plan.input("SET", path)
        .inputs("SET", set.members.iter().map(|m| set_dir.join(&m.file)))
        .dir("--out", &out_dir);
    let _outputs = plan.open()?;
    let mut bars = progress::Bars::new(global.quiet);
    let analysed = set.clone();
    let result = abandon_on_stop(&mut bars, move || {
        validate_set(&analysed, &camera, &volume, &settings)
    });
    bars.finish();
    let validation = result.map_err(|_: Interrupted| {
        Interrupted::keeping(format!(
            "interrupted: no set report written ({} untouched)",
            out_dir.display()
        ))
    })?;
    let report_path = validation
        .write(&out_dir, &command_line())
        .with_context(|| format!("cannot write the set's report into {}", out_dir.display()))?;
    println!(
        "{}; report in {}",
        validation.summary(),
        report_path.display()
    );
    Ok(())
}

/// The flags of a single layout's validation that were given (that differ
/// from their defaults): a set's validation has no use for them.
fn single_layout_flags(args: &ValidateArgs) -> Vec<&'static str> {
    [
        ("--solvers", args.solvers != "all"),
        ("--trials", args.trials != DEFAULT_TRIALS),
        (
            "--gross-threshold",
            args.gross_threshold != DEFAULT_GROSS_THRESHOLD_DEG,
        ),
        ("--fabrication-sigma", args.fabrication_sigma != 0.0),
        ("--camera-sigma", args.camera_sigma.is_some()),
        (
            "--max-hidden",
            args.max_hidden != layout_opt::visibility::DEFAULT_MAX_HIDDEN,
        ),
        ("--no-supports", args.no_supports),
        ("--images", args.images.check().is_some()),
    ]
    .into_iter()
    .filter_map(|(flag, given)| given.then_some(flag))
    .collect()
}
