//! The search report: `reports/<name>/report.md`, `summary.json`,
//! `designs.csv` and a three-view SVG per design. The winner is compared with
//! its start, the paper's biprism in the same envelope and the hand designs,
//! on the same scenarios and noise draws, on the search seed and on an
//! independent validation seed.

use super::compare::DesignRow;
use super::front::{self, FrontReport};
use super::optimise::{SearchOutcome, SearchSettings};
use super::{AvailabilityFloor, Evaluation, ObjectiveSettings, AVAILABILITY_PENALTY};
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
    /// user's constraints rule out (spheres that cannot be identified: by
    /// the stereo distance rule or, over every visible scenario, the
    /// identifiability floor) is not an alternative the user has.
    pub beats_admissible_hand_designs_on_objective: bool,
    /// The admissible hand designs' names.
    pub admissible_hand_designs: Vec<String>,
    /// Whether the winner meets every constraint.
    pub winner_feasible: bool,
    /// The availability floor in force (None: no floor).
    pub availability_floor: Option<f64>,
    /// Whether the winner reaches it.
    pub winner_meets_availability_floor: bool,
    /// Whether the winner meets the identifiability floor on every visible
    /// scenario (None: no floor).
    pub winner_meets_identifiability_floor: Option<bool>,
}

/// First-order figures of the winner and the paper's biprism on a held-out
/// grid: scenarios the search never saw.
#[derive(Debug, Clone, Serialize)]
pub struct HeldOutCheck {
    /// The held-out grid, in words.
    pub grid: String,
    /// Its scenarios.
    pub scenarios: usize,
    /// Winner's first-order RMS rotation, degrees (every in-front scenario).
    pub winner_rotation_rms_deg: Option<f64>,
    /// Paper biprism's first-order RMS rotation, degrees.
    pub paper_rotation_rms_deg: Option<f64>,
    /// 1 − winner / paper, %.
    pub rotation_reduction_percent: Option<f64>,
    /// Winner's first-order RMS translation, mm.
    pub winner_translation_rms_mm: Option<f64>,
    /// Paper biprism's first-order RMS translation, mm.
    pub paper_translation_rms_mm: Option<f64>,
    /// Winner's availability.
    pub winner_availability: f64,
    /// Paper biprism's availability.
    pub paper_availability: f64,
    /// Winner's occluded scenarios.
    pub winner_occluded: usize,
    /// Paper biprism's occluded scenarios.
    pub paper_occluded: usize,
}

impl HeldOutCheck {
    /// The check from first-order evaluations of the winner and the paper's
    /// biprism on `grid`.
    pub fn new(grid: &ScenarioGrid, winner: &Evaluation, paper: &Evaluation) -> Self {
        let rotation = |e: &Evaluation| e.terms.first().and_then(|t| t.rotation_deg);
        let translation = |e: &Evaluation| e.terms.first().and_then(|t| t.translation_mm);
        Self {
            grid: grid_text(grid),
            scenarios: grid.len(),
            winner_rotation_rms_deg: rotation(winner),
            paper_rotation_rms_deg: rotation(paper),
            rotation_reduction_percent: rotation(winner)
                .zip(rotation(paper))
                .map(|(w, p)| 100.0 * (1.0 - w / p)),
            winner_translation_rms_mm: translation(winner),
            paper_translation_rms_mm: translation(paper),
            winner_availability: winner.availability,
            paper_availability: paper.availability,
            winner_occluded: winner.occluded,
            paper_occluded: paper.occluded,
        }
    }
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
    /// The winner and the paper's biprism on a held-out grid.
    pub held_out: HeldOutCheck,
    /// The same with the supports `export` builds for each counted as
    /// occluders (`None`: a part could not be built).
    pub held_out_with_supports: Option<HeldOutCheck>,
    /// The Pareto front, when asked for.
    pub front: Option<FrontReport>,
    /// How the identifiability floor was enforced (None: no floor).
    pub identifiability: Option<super::pipeline::IdentifyBooks>,
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
        .filter(|r| {
            r.evaluation.violations.feasible() && r.evaluation.meets_identifiability_floor()
        })
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
        availability_floor: winner.evaluation.availability_floor,
        winner_meets_availability_floor: winner.evaluation.meets_availability_floor(),
        winner_meets_identifiability_floor: winner
            .evaluation
            .identifiability
            .as_ref()
            .map(|f| f.meets_floor()),
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
        "scored scenarios (of in front)".into(),
        "per term: evaluated / failed".into(),
        "constraints".into(),
        "identifiable (visible)".into(),
        "smallest margin (px)".into(),
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
            format!("{} ({})", e.scored, e.in_front),
            e.terms
                .iter()
                .map(|t| format!("{}: {} / {}", t.term, t.evaluated, t.failed))
                .collect::<Vec<_>>()
                .join("; "),
            if problems.is_empty() {
                "met".into()
            } else {
                problems.join("; ")
            },
            e.identifiability.as_ref().map_or("—".into(), |f| {
                format!("{} of {}", f.identifiable, f.checked)
            }),
            e.identifiability
                .as_ref()
                .map_or("—".into(), |f| significant(f.smallest_margin_px, 3)),
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

fn identifiability_markdown(summary: &SearchSummary) -> String {
    let mut out = String::new();
    let Some(books) = &summary.identifiability else {
        return out;
    };
    let _ = writeln!(out, "\n## Identifiability from one image\n");
    let figures = |f: &Option<super::IdentifiabilityFigures>| {
        f.as_ref().map_or("—".to_string(), |f| {
            format!(
                "{} of {} visible scenarios identifiable, smallest margin {} px",
                f.identifiable,
                f.checked,
                significant(f.smallest_margin_px, 3)
            )
        })
    };
    let _ = writeln!(
        out,
        "The search's winner as found: {} (accuracy {}). {} repair round(s) ({} evaluations, scenarios checked per round {:?}, {:.1} s); the winner: {} (accuracy {}).\n",
        figures(&books.before),
        significant(Some(books.accuracy_before), 4),
        books.rounds,
        books.evaluations,
        books.checked_per_round,
        books.seconds,
        figures(&books.after),
        significant(Some(summary.designs[0].evaluation.accuracy), 4),
    );
    let _ = writeln!(out, "Where each design can be identified (predicted on the noise-free images of the search grid; the winner's validation report measures it by Monte-Carlo):\n");
    for row in &summary.designs {
        if let Some(text) = &row.not_identifiable {
            let _ = writeln!(out, "- **{}**: {text}", row.name);
        }
    }
    out
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
    let floor = match (h.objective.min_availability, v.availability_floor) {
        (AvailabilityFloor::None, _) | (_, None) => {
            "none (availability priced by the availability weight alone)".to_string()
        }
        (AvailabilityFloor::Reference, Some(f)) => format!(
            "{:.1}% of the scenarios: the paper's biprism's availability on this grid",
            100.0 * f
        ),
        (AvailabilityFloor::Share(_), Some(f)) => format!("{:.1}% of the scenarios", 100.0 * f),
    };
    let _ = writeln!(
        out,
        "| availability floor | {floor}; enforced by an exact penalty ({AVAILABILITY_PENALTY} per unit of missing availability, counted exactly and by the soft visibility ramp so the optimiser sees a slope; zero above the floor), and layouts below it rank behind every layout above it |"
    );
    let _ = writeln!(
        out,
        "| identifiability floor | {} |",
        match &summary.identifiability {
            Some(books) => format!(
                "{:.1}% of the visible scenarios, each labelled correctly by the unlabelled solver from one image with predicted probability ≥ {:.1}% (docs/formats.md, \"Identifiability\"); enforced by {}",
                100.0 * books.floor.min_share,
                100.0 * books.floor.min_correct,
                books.method
            ),
            None => "none (stereo identification by pairwise distances alone)".to_string(),
        }
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
    let b = &summary.designs[0].evaluation;
    let _ = writeln!(
        out,
        "Books of the winner's objective: {} scenarios, {} with every sphere in front ({} behind the camera), {} left out for unusable noise, {} scored by every term; {}. Accuracy is aggregated over the scenarios every term scored, never over different subsets per term.\n",
        h.grid.len(),
        b.in_front,
        b.behind,
        b.unusable_noise,
        b.scored,
        b.terms
            .iter()
            .map(|t| format!("`{}` evaluated {} and failed on {}", t.term, t.evaluated, t.failed))
            .collect::<Vec<_>>()
            .join(", ")
    );
    let _ = writeln!(out, "## Designs on the same scenarios and draws\n");
    let _ = writeln!(out, "The objective is accuracy (1 = the paper's biprism; scored on every scenario with all spheres in front) plus the availability term, without constraint penalties; lower is better. Monte-Carlo columns pool every scenario (\"all\"), the design's own visible scenarios, and the scenarios visible to both the design and the winner, where the two are compared like for like.\n");
    out.push_str(&table.markdown());
    out.push_str(&identifiability_markdown(summary));
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
        "winner reaches the availability floor".to_string(),
        yes(v.winner_meets_availability_floor).to_string(),
    ]);
    let held = &summary.held_out;
    verdicts.row([
        format!(
            "first-order RMS rotation at least 40% below the paper's biprism on a held-out grid ({} scenarios: {})",
            held.scenarios, held.grid
        ),
        match held.rotation_reduction_percent {
            Some(r) => format!(
                "{} ° vs {} °, {r:.1}% lower: {}",
                significant(held.winner_rotation_rms_deg, 4),
                significant(held.paper_rotation_rms_deg, 4),
                yes(r >= 40.0)
            ),
            None => "not measurable".to_string(),
        },
    ]);
    verdicts.row([
        "availability and occlusions on the held-out grid no worse than the paper's biprism"
            .to_string(),
        format!(
            "{:.1}% vs {:.1}%, {} vs {} occluded: {}",
            100.0 * held.winner_availability,
            100.0 * held.paper_availability,
            held.winner_occluded,
            held.paper_occluded,
            yes(held.winner_availability >= held.paper_availability
                && held.winner_occluded <= held.paper_occluded)
        ),
    ]);
    if let Some(supported) = &summary.held_out_with_supports {
        verdicts.row([
            "held-out grid with the printed supports counted (winner vs paper's biprism)"
                .to_string(),
            format!(
                "availability {:.1}% vs {:.1}% (without supports {:.1}% vs {:.1}%); RMS rotation {} ° vs {} °",
                100.0 * supported.winner_availability,
                100.0 * supported.paper_availability,
                100.0 * held.winner_availability,
                100.0 * held.paper_availability,
                significant(supported.winner_rotation_rms_deg, 4),
                significant(supported.paper_rotation_rms_deg, 4),
            ),
        ]);
    }
    verdicts.row([
        "occlusions no more frequent than the paper's biprism".to_string(),
        yes(v.occlusion_no_more_frequent).to_string(),
    ]);
    verdicts.row([
        "winner meets every constraint".to_string(),
        yes(v.winner_feasible).to_string(),
    ]);
    out.push_str(&verdicts.markdown());
    if let Some(f) = &summary.front {
        let _ = writeln!(out, "\n## Pareto front: accuracy against availability\n");
        let _ = writeln!(
            out,
            "{} ({} evaluations, {:.1} s). Every hand design has a front member at least as good on accuracy and availability: {}. Data in [front.json](front.json) and [front.csv](front.csv).\n",
            front::METHOD,
            f.evaluations,
            f.seconds,
            yes(f.dominates_every_hand_design)
        );
        out.push_str(&front::table(f).markdown());
        let _ = writeln!(out, "\n![front](front.svg)");
    }
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
