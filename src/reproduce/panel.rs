//! Curves: one panel is one figure of the paper (one x axis, one line per
//! solver), with the statistics of every solver at every x.

use super::stats::Stat;
use crate::montecarlo::{FirstOrderPrediction, SolverOutcome};
use crate::pnp::Solver;
use crate::report::significant;
use serde::Serialize;

/// Which error a curve shows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Metric {
    /// The paper's E_rot (eq. 33), degrees.
    Rotation,
    /// The paper's E_t, percent of |t|.
    Translation,
}

impl Metric {
    /// Axis label.
    pub fn label(self) -> &'static str {
        match self {
            Metric::Rotation => "mean E_rot, eq. 33 (deg)",
            Metric::Translation => "mean E_t (%)",
        }
    }

    /// Short name for files.
    pub fn file_suffix(self) -> &'static str {
        match self {
            Metric::Rotation => "rotation",
            Metric::Translation => "translation",
        }
    }

    /// Unit.
    pub fn unit(self) -> &'static str {
        match self {
            Metric::Rotation => "°",
            Metric::Translation => "%",
        }
    }
}

/// One solver at one setting.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Cell {
    /// The solver.
    pub solver: Solver,
    /// False when the setting has fewer points than the solver accepts (the
    /// solver is not run there).
    pub applicable: bool,
    /// Trials run.
    pub attempts: usize,
    /// Trials in which the solver returned an error (no pose).
    pub solver_errors: usize,
    /// The first error message, if any.
    pub first_error: Option<String>,
    /// The paper's E_rot (eq. 33), degrees.
    pub rotation_deg: Stat,
    /// Geodesic rotation error, degrees.
    pub geodesic_deg: Stat,
    /// The paper's E_t, percent.
    pub translation_percent: Stat,
    /// Trials with a geodesic rotation error above the gross threshold.
    pub gross_failures: usize,
}

impl Cell {
    /// A cell for a solver that is not run at this setting.
    pub fn not_applicable(solver: Solver) -> Cell {
        Cell {
            solver,
            applicable: false,
            attempts: 0,
            solver_errors: 0,
            first_error: None,
            rotation_deg: Stat::default(),
            geodesic_deg: Stat::default(),
            translation_percent: Stat::default(),
            gross_failures: 0,
        }
    }

    /// From one scenario of the Monte-Carlo engine.
    pub fn from_outcome(outcome: &SolverOutcome, trials: usize) -> Cell {
        Cell {
            solver: outcome.solver,
            applicable: true,
            attempts: trials,
            solver_errors: outcome.solver_errors,
            first_error: outcome.first_error.clone(),
            rotation_deg: Stat::from_summary(&outcome.paper_rotation_deg),
            geodesic_deg: Stat::from_summary(&outcome.rotation_deg),
            translation_percent: Stat::from_summary(&outcome.translation_percent),
            gross_failures: outcome.gross_failures,
        }
    }

    /// Pools cells of the same solver.
    pub fn pool<'a>(solver: Solver, cells: impl IntoIterator<Item = &'a Cell> + Clone) -> Cell {
        let applicable: Vec<&Cell> = cells.into_iter().filter(|c| c.applicable).collect();
        Cell {
            solver,
            applicable: !applicable.is_empty(),
            attempts: applicable.iter().map(|c| c.attempts).sum(),
            solver_errors: applicable.iter().map(|c| c.solver_errors).sum(),
            first_error: applicable.iter().find_map(|c| c.first_error.clone()),
            rotation_deg: Stat::pool(applicable.iter().map(|c| &c.rotation_deg)),
            geodesic_deg: Stat::pool(applicable.iter().map(|c| &c.geodesic_deg)),
            translation_percent: Stat::pool(applicable.iter().map(|c| &c.translation_percent)),
            gross_failures: applicable.iter().map(|c| c.gross_failures).sum(),
        }
    }

    /// The statistics of `metric`.
    pub fn stat(&self, metric: Metric) -> &Stat {
        match metric {
            Metric::Rotation => &self.rotation_deg,
            Metric::Translation => &self.translation_percent,
        }
    }

    /// Fraction of trials that failed: a solver error or a gross rotation error.
    pub fn failure_rate(&self) -> Option<f64> {
        (self.attempts > 0)
            .then(|| (self.solver_errors + self.gross_failures) as f64 / self.attempts as f64)
    }
}

/// The first-order (Cramér–Rao) limit at one setting: RMS over the trials'
/// geometries of the per-geometry prediction.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct FirstOrderLine {
    /// RMS geodesic rotation error, degrees.
    pub rms_rotation_deg: f64,
    /// RMS translation error, percent of |t|.
    pub rms_translation_percent: f64,
}

impl From<FirstOrderPrediction> for FirstOrderLine {
    fn from(p: FirstOrderPrediction) -> Self {
        FirstOrderLine {
            rms_rotation_deg: p.rms_rotation_deg,
            rms_translation_percent: p.rms_translation_percent,
        }
    }
}

/// One figure: a line per solver over one x axis. Serialises as its curves
/// ([`PanelSummary`]).
#[derive(Debug, Clone)]
pub struct Panel {
    /// File stem, e.g. `fig7_points`.
    pub id: String,
    /// The paper's figure, e.g. "Fig. 7".
    pub figure: String,
    /// Plot title.
    pub title: String,
    /// X axis label (with unit).
    pub x_label: String,
    /// The x values.
    pub x: Vec<f64>,
    /// Solvers, in report order.
    pub solvers: Vec<Solver>,
    /// `cells[i][j]`: solver j at x[i].
    pub cells: Vec<Vec<Cell>>,
    /// First-order limit at each x, when defined.
    pub first_order: Vec<Option<FirstOrderLine>>,
    /// An extra model curve for the rotation plot (name, points), e.g. the
    /// paper's `1/(sinβ √cosβ)` scaled to the data.
    pub model_rotation: Option<(String, Vec<(f64, f64)>)>,
}

/// One solver's line on a figure, as written to `summary.json`.
#[derive(Debug, Clone, Serialize)]
pub struct SolverCurve {
    /// Stable solver name.
    pub solver: String,
    /// Mean E_rot per x (None where the solver is not run or returned no pose).
    pub mean_erot_deg: Vec<Option<f64>>,
    /// Median E_rot per x.
    pub median_erot_deg: Vec<Option<f64>>,
    /// Mean E_t per x.
    pub mean_et_percent: Vec<Option<f64>>,
    /// Trials that returned a pose, per x.
    pub poses: Vec<usize>,
    /// Solver errors plus gross failures, per x.
    pub failures: Vec<usize>,
}

/// A figure's curves, as written to `summary.json`.
#[derive(Debug, Clone, Serialize)]
pub struct PanelSummary<'a> {
    /// File stem.
    pub id: &'a str,
    /// The paper's figure.
    pub figure: &'a str,
    /// Title.
    pub title: &'a str,
    /// X axis label.
    pub x_label: &'a str,
    /// The x values.
    pub x: &'a [f64],
    /// First-order RMS rotation limit per x, degrees.
    pub first_order_rms_rotation_deg: Vec<Option<f64>>,
    /// First-order RMS translation limit per x, percent.
    pub first_order_rms_translation_percent: Vec<Option<f64>>,
    /// One curve per solver.
    pub solvers: Vec<SolverCurve>,
}

impl Serialize for Panel {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        self.summary().serialize(serializer)
    }
}

impl Panel {
    /// The curves of this figure.
    pub fn summary(&self) -> PanelSummary<'_> {
        let column = |j: usize, f: &dyn Fn(&Cell) -> Option<f64>| -> Vec<Option<f64>> {
            self.cells.iter().map(|row| f(&row[j])).collect()
        };
        PanelSummary {
            id: &self.id,
            figure: &self.figure,
            title: &self.title,
            x_label: &self.x_label,
            x: &self.x,
            first_order_rms_rotation_deg: self
                .first_order
                .iter()
                .map(|f| f.map(|f| f.rms_rotation_deg))
                .collect(),
            first_order_rms_translation_percent: self
                .first_order
                .iter()
                .map(|f| f.map(|f| f.rms_translation_percent))
                .collect(),
            solvers: self
                .solvers
                .iter()
                .enumerate()
                .map(|(j, solver)| SolverCurve {
                    solver: solver.name().to_string(),
                    mean_erot_deg: column(j, &|c| c.rotation_deg.mean()),
                    median_erot_deg: column(j, &|c| c.rotation_deg.median),
                    mean_et_percent: column(j, &|c| c.translation_percent.mean()),
                    poses: self
                        .cells
                        .iter()
                        .map(|row| row[j].rotation_deg.count)
                        .collect(),
                    failures: self
                        .cells
                        .iter()
                        .map(|row| row[j].solver_errors + row[j].gross_failures)
                        .collect(),
                })
                .collect(),
        }
    }

    /// The column of `solver`, if it ran.
    pub fn index(&self, solver: Solver) -> Option<usize> {
        self.solvers.iter().position(|&s| s == solver)
    }

    /// The curve of `solver` for `metric`: (x, statistic) where the solver
    /// applies and returned poses.
    pub fn curve(&self, solver: Solver, metric: Metric) -> Vec<(f64, Stat)> {
        let Some(j) = self.index(solver) else {
            return Vec::new();
        };
        self.x
            .iter()
            .zip(&self.cells)
            .filter(|(_, row)| row[j].applicable && row[j].stat(metric).count > 0)
            .map(|(&x, row)| (x, *row[j].stat(metric)))
            .collect()
    }

    /// Means of `curve`, split into xs and ys.
    pub fn means(&self, solver: Solver, metric: Metric) -> (Vec<f64>, Vec<f64>) {
        self.curve(solver, metric)
            .into_iter()
            .map(|(x, s)| (x, s.mean))
            .unzip()
    }

    /// The cell of `solver` at x index `i`.
    pub fn cell(&self, i: usize, solver: Solver) -> Option<&Cell> {
        self.index(solver).map(|j| &self.cells[i][j])
    }

    /// `solver` pooled over the x values that pass `keep`.
    pub fn pooled(&self, solver: Solver, keep: impl Fn(f64) -> bool) -> Option<Cell> {
        let j = self.index(solver)?;
        let cells: Vec<&Cell> = self
            .x
            .iter()
            .zip(&self.cells)
            .filter(|(&x, _)| keep(x))
            .map(|(_, row)| &row[j])
            .collect();
        let pooled = Cell::pool(solver, cells.iter().copied());
        pooled.applicable.then_some(pooled)
    }
}

/// Whether `first` and `second` have the two largest mean E_rot (pooled over
/// each panel's points) among `solvers` in every panel, with the per-panel
/// ranking (worst first, four shown) as evidence.
pub fn two_worst<'a>(
    panels: impl IntoIterator<Item = &'a Panel>,
    solvers: &[Solver],
    first: Solver,
    second: Solver,
) -> (bool, String) {
    let mut holds = true;
    let mut parts = Vec::new();
    for panel in panels {
        let mut ranked: Vec<(Solver, f64)> = solvers
            .iter()
            .filter_map(|&s| {
                panel
                    .pooled(s, |_| true)
                    .and_then(|c| c.rotation_deg.mean())
                    .map(|m| (s, m))
            })
            .collect();
        ranked.sort_by(|a, b| b.1.total_cmp(&a.1));
        let top: Vec<Solver> = ranked.iter().take(2).map(|r| r.0).collect();
        holds &= top.contains(&first) && top.contains(&second);
        parts.push(format!(
            "{}: {}",
            panel.figure,
            ranked
                .iter()
                .take(4)
                .map(|(s, m)| format!("{} {}°", s.name(), significant(Some(*m), 3)))
                .collect::<Vec<_>>()
                .join(" > ")
        ));
    }
    (holds, parts.join("; "))
}
