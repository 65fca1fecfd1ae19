//! `layout-opt search`: flags into a [`SearchConfig`], checked by the
//! library ([`SearchConfig::check`], its fields named by their flags here),
//! progress bars and Ctrl-C into an [`Observer`](layout_opt::observer::Observer),
//! and the outcome printed. The search itself is [`workflow::run`].

mod flags;
mod set;

use super::common::{command_line, duration_text, naming_file, parse_solvers, SLOW_RUN_SECONDS};
use super::volume::{volume_flag, VolumeDefaults};
use super::{progress, GlobalOptions};
use anyhow::Context;
use clap::ValueEnum;
use flags::FamilyName;
pub use flags::SearchArgs;
use layout_opt::config::ConfigError;
use layout_opt::family::{Constraints, FamilyKind};
use layout_opt::layout::Layout;
use layout_opt::search::config::{
    checkpoint_dir_beside, default_grid, default_polish_iterations, default_volume,
    report_dir_beside,
};
use layout_opt::search::{
    estimate, workflow, FrontOutput, FrontSettings, IdentifiabilityFloor, MeshExport,
    ObjectiveSettings, SearchConfig, SearchSettings,
};
use std::path::{Path, PathBuf};

/// The flags as a search configuration; the default paths are relative to
/// the working directory.
fn config(args: SearchArgs, global: &GlobalOptions) -> anyhow::Result<SearchConfig> {
    let camera = args.camera.camera()?;
    let volume = args.volume.volume(
        &args.grid,
        VolumeDefaults {
            grid: default_grid(),
            volume: default_volume(global.seed),
        },
        global.seed,
    )?;
    let min_identifiability = match (args.min_identifiability.0, args.identify_criterion.0) {
        (None, _) => None,
        (Some(_), None) => anyhow::bail!(
            "--identify-criterion must be a probability, not none (turn the floor off with --min-identifiability none)"
        ),
        (Some(min_share), Some(min_correct)) => Some(IdentifiabilityFloor {
            min_share,
            min_correct,
        }),
    };
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
        FamilyName::Custom => FamilyKind::Custom {
            count: args.points,
            start: match &args.init {
                Some(path) => {
                    let layout = naming_file(Layout::load(path), "start layout", path)?;
                    layout
                        .validate()
                        .with_context(|| format!("start layout {}", path.display()))?;
                    Some(layout)
                }
                None => None,
            },
        },
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
        (None, Some(out)) => report_dir_beside(out),
        (None, None) => PathBuf::from("reports").join(&name),
    };
    let export = (!args.export.is_empty()).then(|| MeshExport {
        formats: args.export.clone(),
        dir: args
            .export_dir
            .clone()
            .unwrap_or_else(|| PathBuf::from("build").join(&name)),
    });
    let front = args.front.then(|| FrontOutput {
        settings: FrontSettings {
            levels: args.front_levels,
            ..FrontSettings::default()
        },
        layout_dir: layout_path
            .parent()
            .unwrap_or(Path::new(""))
            .join(format!("{name}-front")),
    });
    Ok(SearchConfig {
        family,
        constraints: Constraints {
            envelope: args.envelope,
            sphere_diameter_mm: args.sphere_diameter,
            min_gap_mm: args.min_gap,
            min_distance_diff_mm: args.min_distance_diff,
        },
        camera,
        volume,
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
            chain: args.chain,
        },
        search: SearchSettings {
            optimiser: args.optimiser,
            starts: args.starts,
            iterations: args.iterations,
            particles: args.particles,
            polish_iterations: args
                .polish
                .unwrap_or(default_polish_iterations(args.iterations)),
            seed: global.seed,
            start_jitter: args.start_jitter,
        },
        compare_solver: args.compare_solver,
        compare_trials: args.compare_trials,
        validate_solvers: parse_solvers(&args.validate_solvers)?,
        resume: args.resume,
        command: command_line(),
        report_dir,
        checkpoint_dir: args
            .checkpoint_dir
            .unwrap_or_else(|| checkpoint_dir_beside(&layout_path)),
        layout_path,
        export,
        front,
        name,
        min_identifiability,
        identify_trials: args.identify_trials,
        count_supports: args.count_supports,
        supports: (!args.no_supports).then_some(args.max_hidden),
    })
}

/// A configuration error in the command line's words: the field's flag,
/// then what is wrong with its value.
fn flag_error(error: ConfigError) -> anyhow::Error {
    if let Some(flag) = volume_flag(&error) {
        return anyhow::anyhow!("{flag} {}", error.reason);
    }
    let flag = match error.field {
        "sigma_px" => "--noise".to_string(),
        "sphere_diameter_mm" => "--sphere-diameter".to_string(),
        "min_gap_mm" => "--min-gap".to_string(),
        "min_distance_diff_mm" => "--min-distance-diff".to_string(),
        field => format!("--{}", field.replace('_', "-")),
    };
    anyhow::anyhow!("{flag} {}", error.reason)
}

pub fn run(args: SearchArgs, global: &GlobalOptions) -> anyhow::Result<()> {
    let set = args.set.settings()?;
    let config = config(args, global)?;
    config.check().map_err(flag_error)?;
    if let Some(set) = set {
        return set::run(&config, &set, global);
    }
    if !global.quiet {
        if let Some(estimate) =
            estimate::estimate(&config).filter(|e| e.seconds >= SLOW_RUN_SECONDS)
        {
            eprintln!(
                "estimate: the optimisation takes about {} ({}); the comparison and the winner's validation follow",
                duration_text(estimate.seconds),
                estimate.basis()
            );
        }
    }
    let mut bars = progress::Bars::new(global.quiet);
    let result = workflow::run(&config, &mut bars);
    bars.finish();
    let outcome = result?;
    match outcome.finished_text(&config) {
        Some(text) => print!("{text}"),
        None => {
            let kept = outcome.interrupted_text(&config.layout_path);
            return Err(layout_opt::kernel::Interrupted::keeping(kept).into());
        }
    }
    Ok(())
}
