//! `search --set N`: the set designed ([`layout_opt::search::set`]), its
//! layouts, set file and report written.

use super::super::common::IdentifiabilityShare;
use super::super::GlobalOptions;
use anyhow::Context;
use clap::Args;
use layout_opt::layout::Layout;
use layout_opt::search::set::{design_set, set_report, SetSearchSettings};
use layout_opt::search::{SearchConfig, SearchError};
use layout_opt::set::write_set;
use std::path::Path;

/// The flags of `search --set N`.
#[derive(Debug, Args)]
pub(crate) struct SetArgs {
    /// Design a set of N markers (2–8) that one camera tells apart, over
    /// this working range and envelope: <name>-1.json … <name>-N.json and
    /// <name>.set.json beside the layout, set-report.md and set.json in the
    /// report directory. Markers are searched in turn, each kept when no
    /// earlier marker is confusable with it (docs/commands.md).
    #[arg(long, value_name = "N")]
    pub(super) set: Option<usize>,
    /// With --set: score the set by its worst marker's accuracy or the mean.
    #[arg(
        long,
        default_value = "worst",
        value_name = "worst|mean",
        requires = "set"
    )]
    pub(super) set_objective: layout_opt::search::set::SetObjective,
    /// With --set: least predicted probability, per viewpoint, that another
    /// marker is not taken for the one seen; every pair must meet it in a
    /// 99.9% share of the viewpoints where the marker is visible.
    #[arg(
        long,
        default_value = "99.9%",
        value_name = "PROBABILITY",
        requires = "set"
    )]
    pub(super) min_cross_identifiability: IdentifiabilityShare,
    /// With --set: searches per marker before the set is refused.
    #[arg(long, default_value_t = layout_opt::search::set::DEFAULT_SET_TRIES, value_name = "N", requires = "set")]
    pub(super) set_tries: usize,
    /// With --set: check the cross floor on the volume's viewpoints only,
    /// not also at the dips between them (docs/formats.md, "Between the
    /// viewpoints"): faster (4 markers: 125.0 s against 233.8 s on 2
    /// cores), but a confusion a degree or two wide between the viewpoints
    /// passes unseen.
    #[arg(long, requires = "set")]
    pub(super) samples_only: bool,
}

impl SetArgs {
    /// The set's settings (None without `--set`), each bad value refused
    /// with its flag named.
    pub(super) fn settings(&self) -> anyhow::Result<Option<SetSearchSettings>> {
        self.set
            .map(|markers| {
                SetSearchSettings::new(
                    markers,
                    self.set_objective,
                    self.min_cross_identifiability.0,
                    self.set_tries,
                )
                .map(|settings| SetSearchSettings {
                    between_samples: !self.samples_only,
                    ..settings
                })
                .map_err(|e| {
                    let flag = match e.field {
                        "markers" => "--set",
                        "min_cross" => "--min-cross-identifiability",
                        _ => "--set-tries",
                    };
                    anyhow::anyhow!("{flag} {}", e.reason)
                })
            })
            .transpose()
    }
}

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
    // The set's files and report checked and locked before any work: a
    // second set search into them is refused at once.
    let mut plan = layout_opt::kernel::OutputPlan::new();
    plan.file(
        "--out",
        layout_dir.join(format!("{}.set.json", config.name)),
    );
    for k in 1..=set.markers {
        plan.file(
            "--out",
            layout_dir.join(format!("{}-{k}.json", config.name)),
        );
    }
    plan.dir("--report", &config.report_dir);
    let _outputs = plan.open()?;
    let quiet = global.quiet;
    layout_opt::kernel::StopRequest::watch();
    let stop = layout_opt::kernel::StopRequest::flag();
    let outcome = design_set(config, set, stop, &|marker, attempt, verdict| {
        if !quiet {
            eprintln!(
                "marker {marker} of {}: try {attempt} {verdict}",
                set.markers
            );
        }
    })
    .map_err(|e| match e {
        SearchError::Interrupted(stopped) => anyhow::Error::new(stopped),
        e => anyhow::anyhow!("--set {}: {e}", set.markers),
    })?;
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
    let lower: Vec<f64> = outcome
        .markers
        .iter()
        .filter_map(|m| m.held_out.rotation_reduction_percent)
        .collect();
    let rotation = match (
        lower.iter().copied().reduce(f64::min),
        lower.iter().copied().reduce(f64::max),
    ) {
        (Some(low), Some(high)) => format!(
            "; rotation {low:.1}–{high:.1}% below the paper's biprism (first order, held-out grid)"
        ),
        _ => String::new(),
    };
    println!(
        "{}: {} markers in {:.1} s; objective {:.4} (alone {:.4}){rotation}; smallest cross margin {worst_margin}; cross floor met: {}; wrote {} and report {}",
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
