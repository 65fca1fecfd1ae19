//! `validate SET.json`: the set's markers and cross matrix (the work is
//! [`layout_opt::search::set::validation`]).

use super::common::command_line;
use anyhow::Context;
use layout_opt::camera::Camera;
use layout_opt::identifiability::IdentifiabilitySettings;
use layout_opt::search::set::validation::validate_set;
use layout_opt::set::MarkerSet;
use layout_opt::volume::WorkingVolume;
use std::path::{Path, PathBuf};

/// `validate SET.json`: each marker's identifiability and the set's cross
/// matrix over `volume`, with seeded trials against the whole set;
/// `set-report.md` and `set.json` in `out` (default `reports/<set>/`).
pub fn run(
    path: &Path,
    camera: &Camera,
    volume: &WorkingVolume,
    settings: &IdentifiabilitySettings,
    out: Option<PathBuf>,
) -> anyhow::Result<()> {
    let set = MarkerSet::load(path)?;
    set.check_distinct()?;
    let out_dir = out.unwrap_or_else(|| PathBuf::from("reports").join(&set.name));
    layout_opt::files::check_writable_dir(&out_dir)
        .with_context(|| format!("cannot write into {}; nothing was run", out_dir.display()))?;
    let validation = validate_set(&set, camera, volume, settings);
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
