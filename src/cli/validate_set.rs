//! `validate SET.json`: the set's markers and cross matrix (the work is
//! [`layout_opt::search::set::validation`]), on the run kernel: the report
//! directory checked and locked before any work, and Ctrl-C answered
//! within a poll while the set is analysed.

use super::common::command_line;
use super::{progress, GlobalOptions};
use anyhow::Context;
use layout_opt::camera::Camera;
use layout_opt::identifiability::IdentifiabilitySettings;
use layout_opt::kernel::stop::abandon_on_stop;
use layout_opt::kernel::{Interrupted, OutputPlan};
use layout_opt::search::set::validation::validate_set;
use layout_opt::set::MarkerSet;
use layout_opt::volume::WorkingVolume;
use std::path::{Path, PathBuf};

/// `validate SET.json`: each marker's identifiability and the set's cross
/// matrix over `volume`, with seeded trials against the whole set;
/// `set-report.md` and `set.json` in `out` (default `reports/<set>/`).
/// `ignored` names the flags of a single layout's validation that were
/// given: a set's validation uses none of them, so they are refused.
pub fn run(
    path: &Path,
    camera: &Camera,
    volume: &WorkingVolume,
    settings: &IdentifiabilitySettings,
    out: Option<PathBuf>,
    ignored: &[&str],
    global: &GlobalOptions,
) -> anyhow::Result<()> {
    if let Some(flag) = ignored.first() {
        anyhow::bail!(
            "{flag} applies to a single layout's validation; a set's (SET.json) predicts and tries identification only: leave out {}",
            ignored.join(", ")
        );
    }
    let set = MarkerSet::load(path)?;
    set.check_distinct()?;
    let out_dir = out.unwrap_or_else(|| PathBuf::from("reports").join(&set.name));
    let set_dir = layout_opt::files::directory_of(path);
    let mut plan = OutputPlan::new();
    plan.input("SET", path)
        .inputs("SET", set.members.iter().map(|m| set_dir.join(&m.file)))
        .dir("--out", &out_dir);
    let _outputs = plan.open()?;
    let mut bars = progress::Bars::new(global.quiet);
    let (camera, volume, settings) = (*camera, volume.clone(), *settings);
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
