//! The search report: `reports/<name>/report.md`, `summary.json`,
//! `designs.csv` and a three-view SVG per design. The winner is compared with
//! its start, the paper's biprism in the same envelope and the hand designs,
//! on the same scenarios and noise draws, on the search seed and on an
//! independent validation seed.

use super::compare::DesignRow;
use super::optimise::{SearchOutcome, SearchSettings};
use super::ObjectiveSettings;
use crate::camera::Camera;
use crate::family::Constraints;
use crate::report::{percent_lower, plots, significant, write_text, ReportError, Table};
use crate::scenario::ScenarioGrid;
use serde::Serialize;
use std::fmt::Write as _;
use std::path::Path;

/// Provenance of a search.
#[derive(Debug, Clone, Serialize)]
pub struct SearchHeader {
    /// The command line.
    pub command: String,
    /// layout-opt version.
    pub version: String,
    /// The family, with its options.
    pub family: String,
    /// The constraints.
    pub constraints: Constraints,
    /// The objective.
    pub objective: ObjectiveSettings,
    /// The optimiser.
    pub search: SearchSettings,
    /// The scenario grid.
    pub grid: ScenarioGrid,
    /// The camera.
    pub camera: Camera,
    /// Solver of the Monte-Carlo comparison.
    pub comparison_solver: String,
    /// Trials per scenario of the comparison.
    pub comparison_trials: usize,
    /// Seeds of the comparison: the search's, then the validation seed.
    pub comparison_seeds: Vec<u64>,
}

/// The claims the acceptance criteria ask about, computed from the rows.
#[derive(Debug, Clone, Serialize)]
pub struct Verdicts {
    /// Per comparison seed: 1 − winner RMS rotation / paper biprism RMS
    /// rotation, %, over the scenarios visible to both.
    pub rotation_reduction_vs_paper_percent: Vec<f64>,
    /// Per seed: winner RMS translation ≤ paper biprism's, on the scenarios
    /// visible to both.
    pub translation_no_worse: Vec<bool>,
    /// Winner availability − paper biprism availability, percentage points.
    pub availability_difference_pp: f64,
    /// Winner occluded scenarios ≤ paper biprism's.
    pub occlusion_no_more_frequent: bool,
    /// Winner's objective (accuracy + availability, without constraint
    /// penalties) below every hand design's.
    pub beats_hand_designs_on_objective: bool,
    /// Per seed: winner's Monte-Carlo RMS rotation below every hand design's,
    /// each pair on the scenarios visible to both.
    pub beats_hand_designs_on_monte_carlo: Vec<bool>,
    /// Winner's objective below that of every *admissible* hand design: each
    /// hand design as drawn when it meets the constraints, otherwise its
    /// nearest admissible version (the search's own repair). A design the
    /// user's constraints rule out (spheres that cannot be identified) is
    /// not an alternative the user has.
    pub beats_admissible_hand_designs_on_objective: bool,
    /// The admissible hand designs' names.
    pub admissible_hand_designs: Vec<String>,
    /// Whether the winner meets every constraint.
    pub winner_feasible: bool,
}

/// Everything in the report.
#[derive(Debug, Clone, Serialize)]
pub struct SearchSummary {
    /// Provenance.
    pub header: SearchHeader,
    /// The optimiser's result.
    pub outcome: SearchOutcome,
    /// One row per design: winner, start, paper biprism, hand designs.
    pub designs: Vec<DesignRow>,
    /// The acceptance claims.
    pub verdicts: Verdicts,
}

/// Computes the verdicts: rows are winner, start, then the hand designs with
/// the paper's biprism first (`hand`), then the admissible versions of those
/// that break a constraint (`admissible`).
pub fn verdicts(
    rows: &[DesignRow],
    paper_index: usize,
    hand: std::ops::Range<usize>,
    admissible: std::ops::Range<usize>,
) -> Verdicts {
    let winner = &rows[0];
    let admissible_rows: Vec<&DesignRow> = rows[hand.clone()]
        .iter()
        .chain(&rows[admissible])
        .filter(|r| r.evaluation.violations.feasible())
        .collect();
    let paper = &rows[paper_index];
    let seeds = winner.monte_carlo.len();
    Verdicts {
        rotation_reduction_vs_paper_percent: (0..seeds)
            .map(|k| {
                let mc = &paper.monte_carlo[k];
                100.0 * (1.0 - mc.winner_common.rms_rotation_deg / mc.common.rms_rotation_deg)
            })
            .collect(),
        translation_no_worse: (0..seeds)
            .map(|k| {
                let mc = &paper.monte_carlo[k];
                mc.winner_common.rms_translation_mm <= mc.common.rms_translation_mm
            })
            .collect(),
        availability_difference_pp: 100.0
            * (winner.evaluation.availability - paper.evaluation.availability),
        occlusion_no_more_frequent: winner.evaluation.occluded <= paper.evaluation.occluded,
        beats_hand_designs_on_objective: rows[hand.clone()]
            .iter()
            .all(|r| winner.evaluation.objective < r.evaluation.objective),
        beats_hand_designs_on_monte_carlo: (0..seeds)
            .map(|k| {
                rows[hand.clone()].iter().all(|r| {
                    let mc = &r.monte_carlo[k];
                    mc.winner_common.rms_rotation_deg < mc.common.rms_rotation_deg
                })
            })
            .collect(),
        beats_admissible_hand_designs_on_objective: admissible_rows
            .iter()
            .all(|r| winner.evaluation.objective < r.evaluation.objective),
        admissible_hand_designs: admissible_rows.iter().map(|r| r.name.clone()).collect(),
        winner_feasible: winner.evaluation.violations.feasible(),
    }
}

fn yes(flag: bool) -> &'static str {
    if flag {
        "yes"
    } else {
        "**no**"
    }
}

/// Writes the report into `dir`.
pub fn write(dir: &Path, summary: &SearchSummary) -> Result<(), ReportError> {
    std::fs::create_dir_all(dir).map_err(|e| ReportError::write(dir, e))?;
    let json = serde_json::to_string_pretty(summary)
        .map_err(|e| ReportError::write(&dir.join("summary.json"), e))?;
    write_text(&dir.join("summary.json"), &(json + "\n"))?;
    let table = designs_table(summary);
    write_text(
        &dir.join("designs.csv"),
        &table
            .csv()
            .map_err(|e| ReportError::write(&dir.join("designs.csv"), e))?,
    )?;
    for row in &summary.designs {
        let named: Vec<(String, nalgebra::Vector3<f64>)> = row
            .layout
            .points
            .iter()
            .map(|p| (p.name.clone(), p.position))
            .collect();
        plots::orthographic_views(
            &dir.join(format!("views-{}.svg", row.name)),
            &format!(
                "{}: three views, spheres to scale ({} mm)",
                row.name, row.layout.sphere_diameter_mm
            ),
            &named,
            row.layout.sphere_diameter_mm,
        )?;
    }
    write_text(&dir.join("report.md"), &markdown(summary, &table))
}

fn designs_table(summary: &SearchSummary) -> Table {
    let seeds = &summary.header.comparison_seeds;
    let solver = &summary.header.comparison_solver;
    let mut header: Vec<String> = vec![
        "design".into(),
        "points".into(),
        "objective".into(),
        "accuracy (1 = paper biprism)".into(),
        "availability %".into(),
        "occluded scenarios".into(),
        "constraints".into(),
    ];
    for seed in seeds {
        header.push(format!("seed {seed}: {solver} RMS rot (°), all scenarios"));
        header.push(format!("seed {seed}: RMS trans (mm), all scenarios"));
        header.push(format!("seed {seed}: worst-depth RMS rot (°)"));
        header.push(format!("seed {seed}: RMS rot (°), own visible"));
        header.push(format!("seed {seed}: RMS rot (°) / winner's, both visible"));
    }
    let mut table = Table::new(header);
    for row in &summary.designs {
        let e = &row.evaluation;
        let problems = e.violations.describe(&summary.header.constraints);
        let mut cells = vec![
            row.name.clone(),
            row.layout.points.len().to_string(),
            significant(Some(e.objective), 4),
            significant(Some(e.accuracy), 4),
            format!("{:.1}", 100.0 * e.availability),
            e.occluded.to_string(),
            if problems.is_empty() {
                "met".into()
            } else {
                problems.join("; ")
            },
        ];
        for mc in &row.monte_carlo {
            cells.push(significant(Some(mc.all.rms_rotation_deg), 4));
            cells.push(significant(Some(mc.all.rms_translation_mm), 4));
            cells.push(significant(Some(mc.all.worst_depth_rms_rotation_deg), 4));
            cells.push(significant(Some(mc.visible.rms_rotation_deg), 4));
            cells.push(format!(
                "{} / {} ({} scenarios)",
                significant(Some(mc.common.rms_rotation_deg), 4),
                significant(Some(mc.winner_common.rms_rotation_deg), 4),
                mc.common.scenarios
            ));
        }
        table.row(cells);
    }
    table
}

fn markdown(summary: &SearchSummary, table: &Table) -> String {
    let h = &summary.header;
    let o = &summary.outcome;
    let v = &summary.verdicts;
    let mut out = String::new();
    let _ = writeln!(out, "# Search report: {}\n", summary.designs[0].layout.name);
    let _ = writeln!(out, "| | |\n|---|---|");
    let _ = writeln!(out, "| command | `{}` |", h.command);
    let _ = writeln!(out, "| layout-opt | {} |", h.version);
    let _ = writeln!(out, "| family | {} |", h.family);
    let _ = writeln!(
        out,
        "| constraints | envelope {:?} mm (bounds sphere centres), spheres {} mm, gap ≥ {} mm, pairwise distances differ by ≥ {} mm |",
        h.constraints.envelope.size_mm, h.constraints.sphere_diameter_mm, h.constraints.min_gap_mm, h.constraints.min_distance_diff_mm
    );
    let _ = writeln!(
        out,
        "| objective | `{}`, aggregate {:?}, translation weight {}, availability weight {}, noise {}, seed {} |",
        h.objective.objective, h.objective.aggregate, h.objective.translation_weight, h.objective.availability_weight,
        h.objective.noise.describe(), h.objective.seed
    );
    let further_starts = if h.search.start_jitter > 0.0 {
        format!(
            "within ± {} of each parameter's range around the spread start",
            h.search.start_jitter
        )
    } else {
        "uniform within bounds".to_string()
    };
    let _ = writeln!(
        out,
        "| optimiser | {:?}, {} starts × {} iterations ({} particles), Nelder–Mead polish {} iterations, seed {}; start 0 the family's natural start, start 1 its spread start, the rest {} |",
        h.search.optimiser, h.search.starts, h.search.iterations, h.search.particles, h.search.polish_iterations, h.search.seed, further_starts
    );
    let _ = writeln!(
        out,
        "| scenarios | {} ({}) |",
        h.grid.len(),
        grid_text(&h.grid)
    );
    let _ = writeln!(
        out,
        "| comparison | Monte-Carlo with `{}`, {} trials per scenario, seeds {:?} (the search's, then an independent validation seed) |\n",
        h.comparison_solver, h.comparison_trials, h.comparison_seeds
    );
    let _ = writeln!(
        out,
        "The search evaluated {} layouts{}. The winner came from start {} with objective {} (accuracy {} of the paper's biprism; availability {:.1}%).\n",
        o.evaluations,
        if o.interrupted { " and was **interrupted**; the winner is the best layout seen" } else { "" },
        o.best.start,
        significant(Some(o.best.evaluation.objective), 4),
        significant(Some(o.best.evaluation.accuracy), 4),
        100.0 * o.best.evaluation.availability
    );
    let _ = writeln!(out, "## Designs on the same scenarios and draws\n");
    let _ = writeln!(out, "The objective is accuracy (1 = the paper's biprism; scored on every scenario with all spheres in front) plus the availability term, without constraint penalties; lower is better. Monte-Carlo columns pool every scenario (\"all\"), the design's own visible scenarios, and the scenarios visible to both the design and the winner, where the two are compared like for like.\n");
    out.push_str(&table.markdown());
    let _ = writeln!(out, "\n## Verdicts\n");
    let mut verdicts = Table::new(["claim", "result"]);
    for (k, seed) in h.comparison_seeds.iter().enumerate() {
        verdicts.row([
            format!("RMS rotation error at least 40% below the paper's biprism, on the scenarios both see (seed {seed})"),
            format!("{}: {}", percent_lower(v.rotation_reduction_vs_paper_percent[k]), yes(v.rotation_reduction_vs_paper_percent[k] >= 40.0)),
        ]);
        verdicts.row([
            format!("translation error no worse than the paper's biprism (seed {seed})"),
            yes(v.translation_no_worse[k]).to_string(),
        ]);
        verdicts.row([
            format!("beats every hand design in Monte-Carlo RMS rotation (seed {seed})"),
            yes(v.beats_hand_designs_on_monte_carlo[k]).to_string(),
        ]);
    }
    verdicts.row([
        "beats every hand design on the objective, as drawn (admissible or not)".to_string(),
        yes(v.beats_hand_designs_on_objective).to_string(),
    ]);
    verdicts.row([
        format!(
            "beats every admissible hand design on the objective ({})",
            v.admissible_hand_designs.join(", ")
        ),
        yes(v.beats_admissible_hand_designs_on_objective).to_string(),
    ]);
    verdicts.row([
        "availability no more than 2 points below the paper's biprism".to_string(),
        format!(
            "{:+.1} points: {}",
            v.availability_difference_pp,
            yes(v.availability_difference_pp >= -2.0)
        ),
    ]);
    verdicts.row([
        "occlusions no more frequent than the paper's biprism".to_string(),
        yes(v.occlusion_no_more_frequent).to_string(),
    ]);
    verdicts.row([
        "winner meets every constraint".to_string(),
        yes(v.winner_feasible).to_string(),
    ]);
    out.push_str(&verdicts.markdown());
    let _ = writeln!(out, "\n## Winner\n");
    let mut points = Table::new(["point", "x (mm)", "y (mm)", "z (mm)"]);
    for p in &summary.designs[0].layout.points {
        points.row([
            p.name.clone(),
            format!("{:.3}", p.position.x),
            format!("{:.3}", p.position.y),
            format!("{:.3}", p.position.z),
        ]);
    }
    out.push_str(&points.markdown());
    let _ = writeln!(out, "\nA full sensitivity report of the winner on the validation seed is in [winner-validation/report.md](winner-validation/report.md).\n");
    for row in &summary.designs {
        let _ = writeln!(out, "![{}](views-{}.svg)\n", row.name, row.name);
    }
    out
}

fn grid_text(grid: &ScenarioGrid) -> String {
    grid.named_ranges()
        .iter()
        .filter(|(_, r)| r.values.len() > 1 || r.values[0] != 0.0)
        .map(|(name, r)| {
            let values = &r.values;
            if values.len() > 3 {
                format!(
                    "{name} {}…{} ({} values)",
                    values[0],
                    values[values.len() - 1],
                    values.len()
                )
            } else {
                format!(
                    "{name} {}",
                    values
                        .iter()
                        .map(|v| v.to_string())
                        .collect::<Vec<_>>()
                        .join(",")
                )
            }
        })
        .collect::<Vec<_>>()
        .join("; ")
}
