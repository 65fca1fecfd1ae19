//! The search report: renders what the analysis found and writes one
//! search's report directory in one call ([`write`]): `report.md`,
//! `summary.json`, `designs.csv`, a three-view SVG per design, the winner's
//! sensitivity report in `winner-validation/` and, when a front was swept,
//! `front.json`, `front.csv`, `front.svg` with the members' layouts. The
//! winner is compared with its start, the paper's biprism in the same
//! envelope and the hand designs, on the same scenarios and noise draws, on
//! the search seed and on an independent validation seed. It computes
//! nothing new; [`console`] renders the same summary for a terminal.

use super::analysis::Finished;
use super::error::SearchError;
use super::front::{self, FrontFiles, FrontReport};
use super::summary::{volume_text, SearchSummary};
use super::{AvailabilityFloor, IdentifiabilityFigures, AVAILABILITY_PENALTY};
use crate::report::{percent_lower, plots, significant, write_text, ReportError, Table};
use crate::validate;
use std::fmt::Write as _;
use std::path::Path;

/// Writes the report of a finished search into `dir`: the search's own
/// files, the winner's validation in `dir/winner-validation/` and the front
/// (its members' layouts at their entries' paths).
pub fn write(dir: &Path, finished: &Finished) -> Result<(), SearchError> {
    write_summary(dir, &finished.summary)?;
    validate::report::write(&dir.join("winner-validation"), &finished.validation)?;
    if let Some(files) = &finished.front {
        write_front(dir, files, &finished.summary)?;
    }
    Ok(())
}

fn yes(flag: bool) -> &'static str {
    if flag {
        "yes"
    } else {
        "**no**"
    }
}

/// Writes `summary.json`, `designs.csv`, the views and `report.md` into `dir`.
fn write_summary(dir: &Path, summary: &SearchSummary) -> Result<(), ReportError> {
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
        "accuracy (1 = the paper's biprism)".into(),
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

/// The designs table as narrow tables: the designs, Monte-Carlo per seed,
/// and the objective's bookkeeping folded away; and a word on designs that
/// are the same layout under two names.
fn designs_markdown(summary: &SearchSummary, table: &Table) -> String {
    const DESIGN: [usize; 8] = [0, 1, 2, 3, 4, 8, 9, 10];
    const BOOKS: [usize; 4] = [0, 5, 6, 7];
    const PER_SEED: usize = 5;
    let mut out = table.columns(&DESIGN).markdown();
    for (k, seed) in summary.header.comparison_seeds.iter().enumerate() {
        let first = 11 + PER_SEED * k;
        let columns: Vec<usize> = std::iter::once(0).chain(first..first + PER_SEED).collect();
        let _ = writeln!(out, "\nMonte-Carlo, seed {seed}:\n");
        out.push_str(&table.columns(&columns).markdown());
    }
    let _ = writeln!(
        out,
        "\n<details><summary>How each objective was counted</summary>\n\n{}\n</details>\n",
        table.columns(&BOOKS).markdown()
    );
    let designs = &summary.designs;
    for (i, a) in designs.iter().enumerate() {
        for b in &designs[i + 1..] {
            if a.layout.points == b.layout.points {
                let why = if a.name == "start" || b.name == "start" {
                    ": the search started from that hand design"
                } else {
                    ""
                };
                let _ = writeln!(
                    out,
                    "`{}` and `{}` are the same layout under two names{why}, so their rows agree.\n",
                    a.name, b.name
                );
            }
        }
    }
    out
}

/// The section on the winner as printed ([`super::SupportsBooks`]).
fn supports_markdown(summary: &SearchSummary) -> String {
    let mut out = String::new();
    let Some(books) = &summary.supports else {
        return out;
    };
    let _ = writeln!(out, "\n## The winner as printed\n");
    let identifiable = books
        .identifiable_as_printed
        .map_or(String::new(), |(visible, identifiable)| {
            format!(
                " The winner is identifiable from one image in {identifiable} of its {visible} scenarios visible as printed."
            )
        });
    let _ = writeln!(
        out,
        "How: {}. Floor as printed: {}. {}.{identifiable}\n",
        books.method(),
        books.floor.map_or("none".to_string(), |f| format!(
            "{:.1}% of the scenarios",
            100.0 * f
        )),
        supports_outcome(books)
    );
    let mut table = Table::new([
        "design",
        "availability as printed %",
        "spheres alone %",
        "scenarios lost to supports",
        "accuracy (1 = the paper's biprism)",
    ]);
    let mut row = |name: &str, f: &super::PrintedFigures| {
        table.row([
            name.to_string(),
            format!("{:.1}", 100.0 * f.availability),
            format!("{:.1}", 100.0 * f.availability_without),
            f.lost_to_supports.to_string(),
            significant(Some(f.accuracy), 4),
        ]);
    };
    if books.rounds > 0 {
        row("winner as found", &books.found);
    }
    row("winner", &books.winner);
    row("paper-biprism", &books.paper);
    out.push_str(&table.markdown());
    out
}

/// What the check as printed found and did, in one sentence.
fn supports_outcome(books: &super::SupportsBooks) -> String {
    let state = if books.met { "met" } else { "NOT met" };
    if books.rounds == 0 {
        return format!(
            "The winner as found: {state}, no repair needed ({:.1} s)",
            books.seconds
        );
    }
    format!(
        "The winner as found missed it; {} repair round{} (scenarios held per round: {}; {} evaluations, {:.1} s): {state}{}",
        books.rounds,
        if books.rounds == 1 { "" } else { "s" },
        books
            .held_per_round
            .iter()
            .map(|n| n.to_string())
            .collect::<Vec<_>>()
            .join(", "),
        books.evaluations,
        books.seconds,
        if books.met {
            format!(
                ", accuracy {} → {}",
                significant(Some(books.found.accuracy), 4),
                significant(Some(books.winner.accuracy), 4)
            )
        } else {
            "; the winner is the layout as found".to_string()
        }
    )
}

/// The check as printed's line of [`console`].
fn console_supports(out: &mut String, summary: &SearchSummary) {
    let Some(books) = &summary.supports else {
        return;
    };
    let _ = writeln!(
        out,
        "as printed (routed supports counted, a sphere hidden over {}% not seen): availability {:.1}% vs the paper's biprism's {:.1}% (spheres alone {:.1}% vs {:.1}%); floor {}: {}. {}",
        100.0 * books.max_hidden,
        100.0 * books.winner.availability,
        100.0 * books.paper.availability,
        100.0 * books.winner.availability_without,
        100.0 * books.paper.availability_without,
        books
            .floor
            .map_or("none".to_string(), |f| format!("{:.1}%", 100.0 * f)),
        met(books.met),
        supports_outcome(books)
    );
}

fn identifiability_markdown(summary: &SearchSummary) -> String {
    let mut out = String::new();
    let Some(books) = &summary.identifiability else {
        return out;
    };
    let _ = writeln!(out, "\n## Identifiability from one image\n");
    let figures = |f: &Option<IdentifiabilityFigures>| {
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
        "The search's winner as found: {} (accuracy {}). {} ({} evaluations, scenarios checked per round: {}, {:.1} s); the winner: {} (accuracy {}).\n",
        figures(&books.before),
        significant(Some(books.accuracy_before), 4),
        match books.rounds {
            0 => "No repair round was needed".to_string(),
            1 => "1 repair round".to_string(),
            n => format!("{n} repair rounds"),
        },
        books.evaluations,
        if books.checked_per_round.is_empty() {
            "none".to_string()
        } else {
            books
                .checked_per_round
                .iter()
                .map(|c| c.to_string())
                .collect::<Vec<_>>()
                .join(", ")
        },
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

/// The report's first lines: what won, by how much against the paper's
/// biprism (accuracy, availability, identifiability), under which command,
/// and where its layout is.
fn answer_markdown(summary: &SearchSummary) -> String {
    let mut out = String::new();
    let h = &summary.header;
    let v = &summary.verdicts;
    let winner = &summary.designs[0];
    let w = &winner.evaluation;
    let closest = v.closest_hand_design.as_ref().map_or(String::new(), |c| {
        format!(
            ": the hand design `{1}` with no sphere more than {0} mm from its place (after the rigid motion that best maps one onto the other; `{1}` is the closest hand design)",
            significant(Some(c.largest_shift_mm), 3),
            c.name
        )
    });
    let _ = writeln!(
        out,
        "**Answer.** The {} is `{}` ({} spheres of {} mm){closest}.",
        if summary.outcome.interrupted {
            "best layout of an **interrupted** search"
        } else {
            "search's winner"
        },
        winner.name,
        winner.layout.points.len(),
        winner.layout.sphere_diameter_mm
    );
    let Some(paper) = summary.designs.iter().find(|d| d.name == v.paper_design) else {
        return out + "\n";
    };
    let p = &paper.evaluation;
    let _ = writeln!(
        out,
        "Against the paper's biprism (`{}`) on the same {} scenarios:\n",
        paper.name,
        h.volume.len()
    );
    let reductions: Vec<String> = h
        .comparison_seeds
        .iter()
        .zip(&v.rotation_reduction_vs_paper_percent)
        .map(|(seed, r)| format!("{} (seed {seed})", percent_lower(*r)))
        .collect();
    let common = paper
        .monte_carlo
        .first()
        .map_or(0, |mc| mc.common.scenarios);
    let _ = writeln!(
        out,
        "- **accuracy**: first-order error {} × the paper's biprism's; Monte-Carlo RMS rotation with `{}` {} on the {common} scenarios both see{}",
        significant(Some(w.accuracy / p.accuracy), 3),
        h.comparison_solver,
        reductions.join(", "),
        match summary.held_out.rotation_reduction_percent {
            Some(r) => format!("; {} on a held-out grid", percent_lower(r)),
            None => String::new(),
        }
    );
    let _ = writeln!(
        out,
        "- **availability** (every sphere visible): {:.1}% of the scenarios against {:.1}% ({:+.1} points)",
        100.0 * w.availability,
        100.0 * p.availability,
        v.availability_difference_pp
    );
    if let (Some(wi), Some(pi)) = (&w.identifiability, &p.identifiability) {
        let _ = writeln!(
            out,
            "- **identifiable from one image**: {} of {} visible scenarios against {} of {}",
            wi.identifiable, wi.checked, pi.identifiable, pi.checked
        );
    }
    let _ = writeln!(out, "- **command**: `{}`", h.command);
    let _ = writeln!(out, "- **layout file**: `{}`\n", h.layout_path.display());
    out
}

fn markdown(summary: &SearchSummary, table: &Table) -> String {
    let h = &summary.header;
    let o = &summary.outcome;
    let v = &summary.verdicts;
    let mut out = String::new();
    let _ = writeln!(out, "# Search report: {}\n", summary.designs[0].layout.name);
    out.push_str(&answer_markdown(summary));
    let _ = writeln!(out, "| | |\n|---|---|");
    let _ = writeln!(out, "| command | `{}` |", h.command);
    let _ = writeln!(out, "| layout-opt | {} |", h.version);
    let _ = writeln!(out, "| family | {} |", h.family);
    let _ =
        writeln!(
        out,
        "| constraints | envelope {} mm (bounds sphere centres), spheres {} mm, gap ≥ {} mm, {} |",
        h.constraints.envelope.size_mm.map(|v| v.to_string()).join(" × "),
        h.constraints.sphere_diameter_mm,
        h.constraints.min_gap_mm,
        if h.constraints.min_distance_diff_mm > 0.0 {
            format!("pairwise distances differ by ≥ {} mm", h.constraints.min_distance_diff_mm)
        } else {
            "pairwise distances unconstrained".to_string()
        }
    );
    let _ = writeln!(
        out,
        "| objective | `{}`, aggregate {:?}, translation weight {}, availability weight {}, noise {}, seed {}; chain: {} |",
        h.objective.objective, h.objective.aggregate, h.objective.translation_weight, h.objective.availability_weight,
        h.objective.noise.describe(), h.objective.seed, h.objective.chain.describe()
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
        h.volume.len(),
        volume_text(&h.volume)
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
        "How the winner's objective was counted: {} scenarios, {} with every sphere in front ({} behind the camera), {} left out for unusable noise, {} scored by every term; {}. Accuracy is aggregated over the scenarios every term scored, never over different subsets per term.\n",
        h.volume.len(),
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
    out.push_str(&designs_markdown(summary, table));
    out.push_str(&identifiability_markdown(summary));
    out.push_str(&supports_markdown(summary));
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
        if v.admissible_hand_designs.is_empty() {
            "beats every admissible hand design on the objective (none is admissible)".to_string()
        } else {
            format!(
                "beats every admissible hand design on the objective ({})",
                v.admissible_hand_designs.join(", ")
            )
        },
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
    if let Some(books) = &summary.supports {
        verdicts.row([
            "winner reaches the availability floor as printed (its routed supports counted)"
                .to_string(),
            format!(
                "{:.1}% against {}: {}",
                100.0 * books.winner.availability,
                books
                    .floor
                    .map_or("no floor".to_string(), |f| format!("{:.1}%", 100.0 * f)),
                yes(books.met)
            ),
        ]);
    }
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
    verdicts.row([
        "occlusions no more frequent than the paper's biprism".to_string(),
        yes(v.occlusion_no_more_frequent).to_string(),
    ]);
    verdicts.row([
        "winner meets every constraint".to_string(),
        yes(v.winner_feasible).to_string(),
    ]);
    out.push_str(&verdicts.markdown());
    out.push_str(&chains_markdown(&summary.chains));
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
        out.push_str(&front_table(f).markdown());
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

/// Writes what [`front::build`] built: each member's layout file (at its entry's
/// `layout` path, atomically), then `front.json`, `front.csv` and
/// `front.svg` in `report_dir`.
fn write_front(
    report_dir: &Path,
    files: &FrontFiles,
    summary: &SearchSummary,
) -> Result<(), ReportError> {
    let report = &files.report;
    for (entry, layout) in report.members.iter().zip(&files.layouts) {
        if let Some(dir) = entry.layout.parent() {
            std::fs::create_dir_all(dir).map_err(|e| ReportError::write(dir, e))?;
        }
        layout
            .save_atomic(&entry.layout)
            .map_err(|e| ReportError::write(&entry.layout, e))?;
    }
    std::fs::create_dir_all(report_dir).map_err(|e| ReportError::write(report_dir, e))?;
    let json_path = report_dir.join("front.json");
    let json =
        serde_json::to_string_pretty(&report).map_err(|e| ReportError::write(&json_path, e))?;
    write_text(&json_path, &(json + "\n"))?;
    let csv_path = report_dir.join("front.csv");
    let table = front_table(report);
    write_text(
        &csv_path,
        &table.csv().map_err(|e| ReportError::write(&csv_path, e))?,
    )?;
    let mut series = vec![plots::Series {
        name: "Pareto front (search)".into(),
        points: report
            .members
            .iter()
            .filter_map(|m| m.rotation_rms_deg.map(|r| (100.0 * m.availability, r)))
            .collect(),
        dashed: false,
    }];
    for h in &report.hand_designs {
        if let Some(r) = h.rotation_rms_deg {
            series.push(plots::Series {
                name: h.name.clone(),
                points: vec![(100.0 * h.availability, r)],
                dashed: false,
            });
        }
    }
    let winner = &summary.designs[0];
    let winner_point = front::first_order(&winner.evaluation)
        .0
        .map(|r| (100.0 * winner.evaluation.availability, r));
    plots::front_plot(
        &report_dir.join("front.svg"),
        &plots::FrontPlot {
            title: "Accuracy against availability: the front, the hand designs and the winner",
            x_label: "availability (% of the grid's scenarios)",
            y_label: "first-order RMS rotation (°), search grid",
            series: &series,
            winner: winner_point.map(|p| (winner.name.as_str(), p)),
        },
    )?;
    Ok(())
}

/// The front and the hand designs as one table (`front.csv`, and the
/// report's markdown).
fn front_table(report: &FrontReport) -> Table {
    let mut table = Table::new([
        "design",
        "availability floor",
        "availability %",
        "accuracy (1 = reference)",
        "first-order RMS rot (°)",
        "first-order RMS trans (mm)",
        "dominated by",
        "layout",
    ]);
    for m in &report.members {
        table.row([
            m.name.clone(),
            m.floor
                .map_or("none".into(), |f| format!("{:.1}%", 100.0 * f)),
            format!("{:.1}", 100.0 * m.availability),
            significant(Some(m.accuracy), 4),
            significant(m.rotation_rms_deg, 4),
            significant(m.translation_rms_mm, 4),
            "front member".into(),
            m.layout.display().to_string(),
        ]);
    }
    for h in &report.hand_designs {
        table.row([
            h.name.clone(),
            String::new(),
            format!("{:.1}", 100.0 * h.availability),
            significant(Some(h.accuracy), 4),
            significant(h.rotation_rms_deg, 4),
            significant(h.translation_rms_mm, 4),
            h.dominated_by.clone().unwrap_or_else(|| "**none**".into()),
            String::new(),
        ]);
    }
    table
}

/// The summary for a terminal: the designs' table, the winner against the
/// paper's biprism, the held-out check, the floors, the identifiability
/// books, the verdict on the hand designs and the front, one line each.
pub fn console(summary: &SearchSummary) -> String {
    let mut out = String::new();
    let v = &summary.verdicts;
    let mut table = Table::new([
        "design",
        "objective",
        "avail %",
        "RMS rot (°)",
        "RMS trans (mm)",
        "both visible: vs winner",
    ]);
    for row in &summary.designs {
        let mc = &row.monte_carlo[1];
        table.row([
            row.name.clone(),
            measurable(row.evaluation.objective, 4),
            format!("{:.1}", 100.0 * row.evaluation.availability),
            measurable(mc.all.rms_rotation_deg, 4),
            measurable(mc.all.rms_translation_mm, 3),
            format!(
                "{} / {}",
                measurable(mc.common.rms_rotation_deg, 4),
                measurable(mc.winner_common.rms_rotation_deg, 4)
            ),
        ]);
    }
    out.push_str(&table.console());
    if summary
        .designs
        .first()
        .is_some_and(|winner| winner.evaluation.availability == 0.0)
    {
        let _ = writeln!(out, "no scenario of the grid shows every sphere of the winner, so its Monte-Carlo errors on visible scenarios are not measurable; check --sphere-diameter, --envelope and the grid");
    }
    let header = &summary.header;
    let seeds = &header.comparison_seeds;
    let _ = writeln!(
        out,
        "winner vs the paper's biprism ({} Monte-Carlo, {} trials, seeds {} and {}, scenarios both see): RMS rotation {} / {}; availability {:+.1} points",
        header.comparison_solver,
        header.comparison_trials,
        seeds[0],
        seeds[1],
        percent_lower(v.rotation_reduction_vs_paper_percent[0]),
        percent_lower(v.rotation_reduction_vs_paper_percent[1]),
        v.availability_difference_pp
    );
    let held = &summary.held_out;
    let _ = writeln!(
        out,
        "held-out grid ({} scenarios), first order: RMS rotation {:.4}° vs the paper's biprism's {:.4}° ({:.1}% lower); availability {:.1}% vs {:.1}%; occluded {} vs {}",
        held.scenarios,
        held.winner_rotation_rms_deg.unwrap_or(f64::NAN),
        held.paper_rotation_rms_deg.unwrap_or(f64::NAN),
        held.rotation_reduction_percent.unwrap_or(f64::NAN),
        100.0 * held.winner_availability,
        100.0 * held.paper_availability,
        held.winner_occluded,
        held.paper_occluded
    );
    if let Some(supported) = &summary.held_out_with_supports {
        let _ = writeln!(
            out,
            "held-out grid with the printed supports counted: availability {:.1}% vs the paper's biprism's {:.1}%; RMS rotation {:.4}° vs {:.4}°",
            100.0 * supported.winner_availability,
            100.0 * supported.paper_availability,
            supported.winner_rotation_rms_deg.unwrap_or(f64::NAN),
            supported.paper_rotation_rms_deg.unwrap_or(f64::NAN),
        );
    }
    let best = &summary.outcome.best.evaluation;
    let _ = writeln!(
        out,
        "objective {:.4} (accuracy {:.4}); availability floor {}: {}",
        best.objective,
        best.accuracy,
        v.availability_floor
            .map_or("none".to_string(), |f| format!("{:.1}%", 100.0 * f)),
        met(v.winner_meets_availability_floor)
    );
    console_identifiability(&mut out, summary);
    console_supports(&mut out, summary);
    let yes_no = |b: bool| if b { "yes" } else { "no" };
    if v.admissible_hand_designs.is_empty() {
        let _ = writeln!(
            out,
            "winner's objective below every hand design's: {} as drawn (no hand design meets the constraints)",
            yes_no(v.beats_hand_designs_on_objective),
        );
    } else {
        let _ = writeln!(
            out,
            "winner's objective below every hand design's: {} as drawn, {} among the admissible ones ({})",
            yes_no(v.beats_hand_designs_on_objective),
            yes_no(v.beats_admissible_hand_designs_on_objective),
            v.admissible_hand_designs.join(", ")
        );
    }
    if let Some(front) = &summary.front {
        let _ = writeln!(
            out,
            "Pareto front ({} members, {} evaluations in {:.1} s; every hand design dominated: {}):",
            front.members.len(),
            front.evaluations,
            front.seconds,
            yes_no(front.dominates_every_hand_design)
        );
        out.push_str(&console_front(front).console());
    }
    out
}

fn met(flag: bool) -> &'static str {
    if flag {
        "met"
    } else {
        "NOT met"
    }
}

/// The identifiability floor's lines of [`console`].
fn console_identifiability(out: &mut String, summary: &SearchSummary) {
    let Some(books) = &summary.identifiability else {
        return;
    };
    let figures = |f: &Option<IdentifiabilityFigures>| {
        f.as_ref().map_or("—".to_string(), |f| {
            format!(
                "{} of {} visible scenarios, smallest margin {} px",
                f.identifiable,
                f.checked,
                f.smallest_margin_px
                    .map_or("above the gate".into(), |m| format!("{m:.2}"))
            )
        })
    };
    let floor = format!(
        "identifiability floor {:.1}% (each scenario ≥ {:.1}% correct labels): {}",
        100.0 * books.floor.min_share,
        100.0 * books.floor.min_correct,
        met(summary
            .outcome
            .best
            .evaluation
            .meets_identifiability_floor())
    );
    if books.rounds == 0 {
        let _ = writeln!(
            out,
            "{floor}; the search's winner: {} (checked in {:.1} s, no repair needed)",
            figures(&books.after),
            books.seconds
        );
    } else {
        let _ = writeln!(
            out,
            "{floor}; the search's winner: {}; after {} repair round(s) ({} evaluations, {:.1} s): {}",
            figures(&books.before),
            books.rounds,
            books.evaluations,
            books.seconds,
            figures(&books.after)
        );
    }
    for row in &summary.designs {
        if let Some(text) = &row.not_identifiable {
            let _ = writeln!(out, "  {}: {text}", row.name);
        }
    }
}

/// The front and the hand designs for a terminal.
fn console_front(front: &FrontReport) -> Table {
    let mut table = Table::new([
        "design",
        "avail %",
        "accuracy",
        "RMS rot (°)",
        "RMS trans (mm)",
        "dominated by",
    ]);
    let fmt = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.4}"));
    for m in &front.members {
        table.row([
            m.name.clone(),
            format!("{:.1}", 100.0 * m.availability),
            format!("{:.4}", m.accuracy),
            fmt(m.rotation_rms_deg),
            fmt(m.translation_rms_mm),
            String::new(),
        ]);
    }
    for h in &front.hand_designs {
        table.row([
            h.name.clone(),
            format!("{:.1}", 100.0 * h.availability),
            format!("{:.4}", h.accuracy),
            fmt(h.rotation_rms_deg),
            fmt(h.translation_rms_mm),
            h.dominated_by.clone().unwrap_or_else(|| "none".into()),
        ]);
    }
    table
}

/// A number with `decimals` decimals, or "not measurable" when it is not
/// finite (nothing visible to measure it on).
fn measurable(value: f64, decimals: usize) -> String {
    if value.is_finite() {
        format!("{value:.decimals$}")
    } else {
        "not measurable".into()
    }
}

/// The robustness table: the winner and the paper's biprism under every
/// chain.
fn chains_markdown(rows: &[super::summary::ChainRow]) -> String {
    if rows.is_empty() {
        return String::new();
    }
    let mut out = String::new();
    let _ = writeln!(out, "\n## Under every chain\n");
    let _ = writeln!(out, "The `crlb` term (aggregated RMS rotation) of the winner and the paper's biprism on the search's own scenarios and noise, under each chain a user may run (`--chain`): the part is the layout (ideal, read as `--observation` says); printed to 0.1 mm per centre coordinate; printed and characterised from `characterise --plan`'s views at 0.02 px. Printed and characterised chains read projected centres, as `track` does. The accuracy weighs translation as the search does.\n");
    let mut table = Table::new([
        "chain",
        "winner RMS rot (°)",
        "paper's biprism RMS rot (°)",
        "winner / biprism",
        "winner's accuracy",
    ]);
    for row in rows {
        let ratio = row
            .winner_rotation_deg
            .zip(row.paper_rotation_deg)
            .map(|(w, p)| w / p);
        table.row([
            row.chain.describe(),
            significant(row.winner_rotation_deg, 4),
            significant(row.paper_rotation_deg, 4),
            significant(ratio, 3),
            format!("{:.3}", row.winner_accuracy),
        ]);
    }
    out.push_str(&table.markdown());
    out
}
