//! `search --set N`: the set designed ([`layout_opt::search::set`]), its
//! layouts, set file and report written.

use super::super::{progress, GlobalOptions};
use anyhow::Context;
use layout_opt::layout::Layout;
use layout_opt::search::set::{design_set, set_report, SetSearchSettings};
use layout_opt::search::SearchConfig;
use layout_opt::set::write_set;
use std::path::Path;

/// `search --set N`: the set designed, its files and report written.
pub(super) fn run(
    config: &SearchConfig,
    set: &SetSearchSettings,
    global: &GlobalOptions,
) -> anyhow::Result<()> {
    let layout_dir = config
        .layout_path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."))
        .to_path_buf();
    for dir in [&layout_dir, &config.report_dir] {
        layout_opt::files::check_writable_dir(dir)
            .with_context(|| format!("cannot write into {}; nothing was run", dir.display()))?;
    }
    progress::catch_ctrl_c();
    let stop = std::sync::atomic::AtomicBool::new(false);
    let quiet = global.quiet;
    let outcome = design_set(config, set, &stop, &|marker, attempt, verdict| {
        if !quiet {
            eprintln!(
                "marker {marker} of {}: try {attempt} {verdict}",
                set.markers
            );
        }
    })
    .map_err(|e| anyhow::anyhow!("--set {}: {e}", set.markers))?;
    let layouts: Vec<Layout> = outcome.markers.iter().map(|m| m.layout.clone()).collect();
    let set_path = write_set(&layout_dir, &config.name, &layouts)?;
    let report_path = layout_opt::search::set::validation::write_reports(
        &config.report_dir,
        &set_report(&outcome, &config.command),
        &serde_json::to_value(&outcome)?,
    )
    .with_context(|| {
        format!(
            "cannot write the set's report into {}",
            config.report_dir.display()
        )
    })?;
    let worst_margin = outcome
        .matrix
        .smallest_margin_px()
        .map_or("above the gate everywhere".to_string(), |m| {
            format!("{m:.2} px")
        });
    println!(
        "{}: {} markers in {:.1} s; objective {:.4} (alone {:.4}); smallest cross margin {worst_margin}; cross floor met: {}; wrote {} and report {}",
        config.name,
        outcome.markers.len(),
        outcome.seconds,
        outcome.objective,
        outcome.alone_accuracy,
        if outcome.matrix.meets_floor() { "yes" } else { "no" },
        set_path.display(),
        report_path.display()
    );
    Ok(())
}
