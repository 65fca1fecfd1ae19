//! `layout-opt export SET.json`: every marker of a set, numbered, with the
//! set's sheet ([`layout_opt::mesh::set_workflow`]).

use super::{progress, GlobalOptions};
use anyhow::Context;
use layout_opt::mesh::set_workflow::export_set;
use layout_opt::mesh::summary::summary;
use layout_opt::mesh::{ExportError, ExportOptions};
use layout_opt::set::{MarkerSet, SET_FORMAT};
use std::path::Path;

/// Whether `path` is a set file: JSON whose `format` is the set format.
pub fn is_set_file(path: &Path) -> bool {
    let is_json = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("json"));
    is_json
        && std::fs::read_to_string(path)
            .ok()
            .and_then(|text| serde_json::from_str::<serde_json::Value>(&text).ok())
            .is_some_and(|v| v.get("format").and_then(|f| f.as_str()) == Some(SET_FORMAT))
}

/// Reads the set and every layout it lists; a missing or bad layout is an
/// error naming its file, before any part is built.
pub fn load(path: &Path) -> anyhow::Result<MarkerSet> {
    let set = MarkerSet::load(path)?;
    set.check_distinct()?;
    Ok(set)
}

/// Builds and writes every part of `set`, and prints each part's summary.
pub fn run(
    set: &MarkerSet,
    options: &ExportOptions,
    out: &Path,
    global: &GlobalOptions,
) -> anyhow::Result<()> {
    let mut bars = progress::Bars::new(global.quiet);
    let result = export_set(set, options, out, &mut bars);
    bars.finish();
    if let Err(ExportError::Interrupted) = result {
        let kept = "interrupted: none of the set's files were written";
        return Err(layout_opt::kernel::Interrupted::keeping(kept).into());
    }
    let report = result.with_context(|| format!("cannot export the set {}", set.path.display()))?;
    for part in &report.parts {
        println!(
            "part {} ({}, number engraved), in {}:",
            part.number,
            part.file,
            part.directory.display()
        );
        print!("{}", summary(&part.report));
    }
    println!("wrote {}", report.sheet.display());
    Ok(())
}
