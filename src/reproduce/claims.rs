//! Claims and the numeric rules that decide them.
//!
//! Every verdict is computed from the run's data by one of the rules below;
//! none is written by hand. The words the paper uses map to rules:
//!
//! | the paper says | rule |
//! |---|---|
//! | A is better than / reduces the error of B | `mean_B / mean_A ≥` [`IMPROVEMENT_RATIO`] and the two-sample z ≥ [`SIGNIFICANCE_Z`] |
//! | A is slightly better than B | `mean_B / mean_A > 1` and z ≥ [`SIGNIFICANCE_Z`] |
//! | A is comparable / consistent / equivalent to B | `1/`[`COMPARABLE_RATIO`] `≤ mean_A / mean_B ≤` [`COMPARABLE_RATIO`] |
//! | A is at most slightly worse than B | `mean_A / mean_B ≤` [`COMPARABLE_RATIO`] |
//! | A is (one of) the best | `mean_A ≤` [`BEST_TOLERANCE`] `×` the best mean of the paper's solvers |
//! | error increases / decreases with x | Spearman ρ of the mean curve `≥` [`TREND_RHO`] (or `≤ −`) |
//! | error is not affected by x | largest / smallest binned mean `≤` [`FLAT_RATIO`] |
//! | the error curve is a straight line | R² of a line fit `≥` [`LINEAR_R2`] |
//! | erratic | failure rate (solver error or geodesic error > [`super::engine::GROSS_ERROR_DEG`]°) `≥` [`ERRATIC_RATE`] and `≥` [`ERRATIC_FACTOR`] × the rate at large n |
//! | an improvement by a factor F | measured factor `≥ 1 + (F − 1)/2` (at least half the claimed gain) |
//! | about F times | measured factor within `[F/`[`ABOUT_FACTOR`]`, F·`[`ABOUT_FACTOR`]`]` |
//!
//! Means are the paper's statistic ("average error"). The z score is
//! unpaired, hence conservative under our common random numbers.

use super::stats::{compare, Comparison, Stat};
use serde::Serialize;

/// "A reduces the error of B": B's mean is at least this multiple of A's.
pub const IMPROVEMENT_RATIO: f64 = 1.10;
/// A difference of means counts only with a two-sample z at least this.
pub const SIGNIFICANCE_Z: f64 = 2.0;
/// "Comparable": the ratio of means lies within `[1/x, x]`.
pub const COMPARABLE_RATIO: f64 = 1.25;
/// "The best": within this factor of the best mean.
pub const BEST_TOLERANCE: f64 = 1.10;
/// "Increases with x": Spearman rank correlation at least this.
pub const TREND_RHO: f64 = 0.8;
/// "Not affected by x": largest over smallest binned mean at most this.
pub const FLAT_RATIO: f64 = 2.0;
/// "A straight line": R² of a least-squares line at least this.
pub const LINEAR_R2: f64 = 0.98;
/// "Erratic": a failure rate at least this…
pub const ERRATIC_RATE: f64 = 0.05;
/// …and at least this multiple of the rate at large n.
pub const ERRATIC_FACTOR: f64 = 3.0;
/// "About F times": within this factor of F either way.
pub const ABOUT_FACTOR: f64 = 2.0;
/// "Increases significantly with depth": the far/near ratio of means at least this.
pub const DEPTH_GROWTH: f64 = 1.5;
/// "Stabilises from n = 12": the gain left between n = 12 and n = 20 is at
/// most this fraction of the whole gain from the smallest n to n = 20.
pub const STABILISE_FRACTION: f64 = 1.0 / 3.0;
/// "A knee near x₀": the best two-segment split lies within `[x₀/k, x₀·k]`
/// for this k…
pub const KNEE_FACTOR: f64 = 2.0;
/// …and halves the residual of a single line at least.
pub const KNEE_RESIDUAL_FRACTION: f64 = 0.5;
/// "Lowest near β₀": the minimum of the smoothed curve within this many
/// degrees of β₀.
pub const MINIMUM_TOLERANCE_DEG: f64 = 10.0;

/// "Indistinguishable": two errors whose ratio is within this fraction of
/// 1, or whose difference is not significant (z below [`SIGNIFICANCE_Z`]).
pub const TIE_FRACTION: f64 = 0.05;
/// A level the paper states as a range holds within the range widened by
/// this fraction at either end.
pub const LEVEL_TOLERANCE: f64 = 0.10;

/// The ambiguity of the paper's "Parallel": the single paraperspective step
/// of eqs. 17–21 (`parallel-init`) or Horaud's iteration (`parallel`).
pub const PARALLEL_AMBIGUITY: &str = "\"Parallel\" as Horaud's iteration (`parallel`) rather than the single paraperspective step of eqs. 17–21 (`parallel-init`), the method's initial value";

/// A claim's verdict.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Verdict {
    /// Our data meet the criterion.
    Holds,
    /// The claim orders two methods, and ours are tied: their ratio is
    /// within [`TIE_FRACTION`] of 1, or the difference is not significant
    /// over the trials run.
    Indistinguishable,
    /// Our data do not meet the criterion; [`Claim::reason`] says why.
    DoesNotHold,
    /// A cost ratio between the paper's MATLAB implementations: our ratio
    /// is shown, not judged.
    ImplementationDependent,
    /// The criterion could not be computed (a solver or data is missing).
    NotEvaluated,
}

impl Verdict {
    /// Every verdict, in report order.
    pub const ALL: [Verdict; 5] = [
        Verdict::Holds,
        Verdict::Indistinguishable,
        Verdict::DoesNotHold,
        Verdict::ImplementationDependent,
        Verdict::NotEvaluated,
    ];

    /// The verdict in words.
    pub fn label(self) -> &'static str {
        match self {
            Verdict::Holds => "holds",
            Verdict::Indistinguishable => "indistinguishable",
            Verdict::DoesNotHold => "does not hold",
            Verdict::ImplementationDependent => "implementation-dependent",
            Verdict::NotEvaluated => "not evaluated",
        }
    }

    /// From a boolean.
    pub fn from_bool(holds: bool) -> Verdict {
        if holds {
            Verdict::Holds
        } else {
            Verdict::DoesNotHold
        }
    }
}

/// Why a claim does not hold.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "kebab-case")]
pub enum Reason {
    /// A faithful simulation contradicts it; `figure` is where the paper
    /// shows what we do not see.
    Contradiction {
        /// The paper's figure or table.
        figure: String,
    },
    /// The verdict depends on an ambiguity in the paper, named here.
    Ambiguity {
        /// The ambiguity.
        ambiguity: String,
    },
}

impl Reason {
    /// The kind, for counts.
    pub fn kind(&self) -> &'static str {
        match self {
            Reason::Contradiction { .. } => "contradiction",
            Reason::Ambiguity { .. } => "ambiguity",
        }
    }

    /// One line on why.
    pub fn text(&self) -> String {
        match self {
            Reason::Contradiction { figure } => {
                format!("a faithful simulation contradicts it ({figure})")
            }
            Reason::Ambiguity { ambiguity } => {
                format!("depends on an ambiguity in the paper: {ambiguity}")
            }
        }
    }
}

/// One claim of the paper, checked.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Claim {
    /// Stable identifier, e.g. `points.stabilise`.
    pub id: String,
    /// Where the paper makes it.
    pub source: String,
    /// The claim, stated plainly.
    pub statement: String,
    /// The numeric rule that decides it.
    pub criterion: String,
    /// The verdict.
    pub verdict: Verdict,
    /// The numbers behind the verdict (or why it was not evaluated).
    pub evidence: String,
    /// Solvers the claim names that this build does not have.
    pub not_available: Vec<String>,
    /// Why it does not hold (set exactly when the verdict is
    /// [`Verdict::DoesNotHold`]).
    pub reason: Option<Reason>,
    /// The ambiguity a failure depends on, if any ([`Claim::ambiguity`]).
    #[serde(skip)]
    depends_on: Option<String>,
}

impl Claim {
    /// A claim with its statement and rule; give it a verdict with
    /// [`Claim::judge`] or [`Claim::skip`].
    pub fn new(id: &str, source: &str, statement: &str, criterion: &str) -> Claim {
        Claim {
            id: id.to_string(),
            source: source.to_string(),
            statement: statement.to_string(),
            criterion: criterion.to_string(),
            verdict: Verdict::NotEvaluated,
            evidence: String::new(),
            not_available: Vec::new(),
            reason: None,
            depends_on: None,
        }
    }

    /// Records a computed verdict.
    pub fn judge(self, holds: bool, evidence: String) -> Claim {
        self.decide(Verdict::from_bool(holds), evidence)
    }

    /// Records a verdict, with its reason when it is "does not hold": the
    /// ambiguity the claim depends on ([`Claim::ambiguity`]), else a
    /// contradiction with the figure the claim cites.
    pub fn decide(mut self, verdict: Verdict, evidence: String) -> Claim {
        self.verdict = verdict;
        self.evidence = evidence;
        self.reason = (verdict == Verdict::DoesNotHold).then(|| match &self.depends_on {
            Some(ambiguity) => Reason::Ambiguity {
                ambiguity: ambiguity.clone(),
            },
            None => Reason::Contradiction {
                figure: self.source.clone(),
            },
        });
        self
    }

    /// Records the verdict of an ordering claim decided by comparison `c`:
    /// "holds" when `holds`, else "indistinguishable" when `c` is a tie
    /// ([`is_tie`]), else "does not hold".
    pub fn judge_order(self, holds: bool, c: &Comparison, evidence: String) -> Claim {
        let verdict = if holds {
            Verdict::Holds
        } else if is_tie(c) {
            Verdict::Indistinguishable
        } else {
            Verdict::DoesNotHold
        };
        self.decide(verdict, evidence)
    }

    /// Records a cost ratio between implementations: shown, not judged.
    pub fn implementation_dependent(self, evidence: String) -> Claim {
        self.decide(Verdict::ImplementationDependent, evidence)
    }

    /// Declares that a failure of this claim depends on an ambiguity in the
    /// paper (before or after the verdict).
    pub fn ambiguity(mut self, ambiguity: &str) -> Claim {
        self.depends_on = Some(ambiguity.to_string());
        let (verdict, evidence) = (self.verdict, std::mem::take(&mut self.evidence));
        self.decide(verdict, evidence)
    }

    /// Records that the claim could not be evaluated, and why.
    pub fn skip(mut self, reason: impl Into<String>) -> Claim {
        self.verdict = Verdict::NotEvaluated;
        self.evidence = reason.into();
        self
    }

    /// Notes solvers the claim names that are not available.
    pub fn missing(mut self, names: Vec<String>) -> Claim {
        self.not_available = names;
        self
    }

    /// Marks the claim as not evaluated because `names` are missing.
    pub fn solvers_missing(self, names: Vec<String>) -> Claim {
        let reason = format!("not evaluated: solver not available ({})", names.join(", "));
        self.missing(names).skip(reason)
    }
}

/// Whether `better` improves on `worse` by the improvement rule.
pub fn improves(better: &Stat, worse: &Stat) -> Option<(bool, Comparison)> {
    let c = compare(worse, better)?;
    Some((c.ratio >= IMPROVEMENT_RATIO && c.z >= SIGNIFICANCE_Z, c))
}

/// Whether `better` is better than `worse` by any significant margin.
pub fn slightly_better(better: &Stat, worse: &Stat) -> Option<(bool, Comparison)> {
    let c = compare(worse, better)?;
    Some((c.ratio > 1.0 && c.z >= SIGNIFICANCE_Z, c))
}

/// The verdict of a claim made of several conditions, some of them
/// orderings: "does not hold" if any condition fails outright, else
/// "indistinguishable" if an ordering failed only as a tie, else "holds".
#[derive(Debug, Clone, Copy, Default)]
pub struct Tally {
    failed: bool,
    tied: bool,
}

impl Tally {
    /// A condition that is not an ordering.
    pub fn check(&mut self, ok: bool) {
        self.failed |= !ok;
    }

    /// An ordering decided by comparison `c`.
    pub fn order(&mut self, ok: bool, c: &Comparison) {
        if !ok {
            if is_tie(c) {
                self.tied = true;
            } else {
                self.failed = true;
            }
        }
    }

    /// The verdict so far.
    pub fn verdict(&self) -> Verdict {
        if self.failed {
            Verdict::DoesNotHold
        } else if self.tied {
            Verdict::Indistinguishable
        } else {
            Verdict::Holds
        }
    }
}

/// Whether comparison `c` is a tie: a ratio within [`TIE_FRACTION`] of 1,
/// or a difference that is not significant.
pub fn is_tie(c: &Comparison) -> bool {
    (c.ratio - 1.0).abs() <= TIE_FRACTION || c.z.abs() < SIGNIFICANCE_Z
}

/// Whether `value` lies in the paper's stated range `(low, high)` widened
/// by [`LEVEL_TOLERANCE`] at each end.
pub fn within_level(value: f64, (low, high): (f64, f64)) -> bool {
    value >= low * (1.0 - LEVEL_TOLERANCE) && value <= high * (1.0 + LEVEL_TOLERANCE)
}

/// The per-setting comparison of two methods: the median over settings of
/// `median_a / median_b` at each setting (settings where either has no
/// median are left out), so that a few gross failures at one setting do
/// not decide it. `None` without a usable setting.
pub fn per_setting_ratio(settings: &[(Stat, Stat)]) -> Option<f64> {
    let mut ratios: Vec<f64> = settings
        .iter()
        .filter_map(|(a, b)| {
            let (a, b) = (a.median?, b.median?);
            (b > 0.0).then_some(a / b)
        })
        .collect();
    crate::statistics::median(&mut ratios)
}

/// Whether two means are comparable; returns (holds, ratio a/b).
pub fn comparable(a: f64, b: f64) -> (bool, f64) {
    let ratio = a / b;
    (
        (1.0 / COMPARABLE_RATIO..=COMPARABLE_RATIO).contains(&ratio),
        ratio,
    )
}

/// Whether a measured improvement factor reproduces a claimed one.
pub fn reproduces_factor(claimed: f64, measured: f64) -> bool {
    measured >= 1.0 + 0.5 * (claimed - 1.0)
}

/// Whether a measured factor is "about" the claimed one.
pub fn about_factor(claimed: f64, measured: f64) -> bool {
    measured >= claimed / ABOUT_FACTOR && measured <= claimed * ABOUT_FACTOR
}

/// A comparison for evidence text: `ratio ×, z`.
pub fn describe(c: &Comparison) -> String {
    format!("{:.3}× (z = {:.1})", c.ratio, c.z)
}

/// Formats a number for evidence text (3 significant digits).
pub fn num(value: f64) -> String {
    crate::report::significant(Some(value), 3)
}

/// The rules as a markdown list, for the report.
pub fn criteria_markdown() -> String {
    format!(
        "Each verdict is computed from this run's numbers by one of these rules (constants in `src/reproduce/claims.rs`); means over trials are the paper's \"average error\":\n\n\
| the paper says | rule |\n|---|---|\n\
| A is better than / reduces the error of B | mean_B / mean_A ≥ {IMPROVEMENT_RATIO} and two-sample z ≥ {SIGNIFICANCE_Z} |\n\
| A is slightly better than B | mean_B / mean_A > 1 and z ≥ {SIGNIFICANCE_Z} |\n\
| A is comparable / consistent / equivalent to B | 1/{COMPARABLE_RATIO} ≤ mean_A / mean_B ≤ {COMPARABLE_RATIO} |\n\
| A is at most slightly worse than B | mean_A / mean_B ≤ {COMPARABLE_RATIO} |\n\
| A is (one of) the best | mean_A ≤ {BEST_TOLERANCE} × the best mean among the paper's solvers |\n\
| error increases with x | Spearman ρ(x, mean) ≥ {TREND_RHO} |\n\
| error is not affected by x | largest / smallest binned mean ≤ {FLAT_RATIO} |\n\
| a straight error curve | R² of a line fit ≥ {LINEAR_R2} |\n\
| erratic | failure rate (solver error, or geodesic error > {gross}°) ≥ {ERRATIC_RATE} and ≥ {ERRATIC_FACTOR} × the rate at n ≥ 8 |\n\
| an improvement by a factor F | measured factor ≥ 1 + (F − 1)/2 |\n\
| about F times | measured factor within [F/{ABOUT_FACTOR}, {ABOUT_FACTOR}·F] |\n\
| increases significantly with depth | mean at the far end / mean at the near end ≥ {DEPTH_GROWTH} |\n\
| stable from n = 12 | gain left from n = 12 to 20 ≤ {stab:.3} of the gain from the smallest n to 20 |\n\
| a knee near x₀ | best two-segment split within [x₀/{KNEE_FACTOR}, {KNEE_FACTOR}·x₀] and ≤ {KNEE_RESIDUAL_FRACTION} of a single line's residual |\n\
| lowest near β₀ | minimum of the 11°-smoothed curve within ±{MINIMUM_TOLERANCE_DEG}° of β₀ on both sides |\n\n\
The z score is unpaired, so it is conservative: our solvers see the same noise draws (common random numbers), which correlates their errors positively. \"The paper's solvers\" are those its tables compare: DLT, EPnP, EPnP+GN, DLS, LHM, RPnP, OPnP, Parallel, Parallel weight. A claim that names solvers this build does not have is *not evaluated*; a claim over a group is evaluated on the members we have, and names the missing ones.\n",
        gross = super::engine::GROSS_ERROR_DEG,
        stab = STABILISE_FRACTION,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rules() {
        let small = Stat::of(&mut [1.0, 1.1, 0.9, 1.0, 1.05, 0.95]);
        let large = Stat::of(&mut [2.0, 2.2, 1.8, 2.0, 2.1, 1.9]);
        let (holds, c) = improves(&small, &large).unwrap();
        assert!(holds);
        assert!((c.ratio - 2.0).abs() < 1e-12);
        assert!(!improves(&large, &small).unwrap().0);
        assert!(slightly_better(&small, &large).unwrap().0);
        assert!(comparable(1.0, 1.2).0 && !comparable(1.0, 1.3).0);
        assert!(reproduces_factor(3.5, 2.25) && !reproduces_factor(3.5, 2.2));
        assert!(about_factor(5.0, 2.5) && about_factor(5.0, 10.0) && !about_factor(5.0, 2.4));
        let claim = Claim::new("x", "§1", "s", "c").solvers_missing(vec!["opnp".into()]);
        assert_eq!(claim.verdict, Verdict::NotEvaluated);
        assert_eq!(claim.evidence, "not evaluated: solver not available (opnp)");
        assert_eq!(Verdict::DoesNotHold.label(), "does not hold");
    }

    #[test]
    fn a_tie_is_indistinguishable_not_a_failure() {
        // OPnP against LHM at 1.001×: a saturated tie.
        let a = Stat::of(&mut [1.0, 1.2, 0.8, 1.0, 1.1, 0.9]);
        let b = Stat::of(&mut [1.001, 1.201, 0.801, 1.001, 1.101, 0.901]);
        let (holds, c) = slightly_better(&a, &b).unwrap();
        assert!(!holds);
        let claim =
            Claim::new("x", "Fig. 8", "a beats b", "rule").judge_order(holds, &c, "e".into());
        assert_eq!(claim.verdict, Verdict::Indistinguishable);
        assert_eq!(claim.reason, None);
        // A real reversal is a failure, with its figure.
        let worse = Stat::of(&mut [2.0, 2.2, 1.8, 2.0, 2.1, 1.9]);
        let (holds, c) = slightly_better(&worse, &a).unwrap();
        let claim =
            Claim::new("x", "Fig. 8", "worse beats a", "rule").judge_order(holds, &c, "e".into());
        assert_eq!(claim.verdict, Verdict::DoesNotHold);
        assert_eq!(
            claim.reason.as_ref().unwrap().text(),
            "a faithful simulation contradicts it (Fig. 8)"
        );
        // Declared ambiguities are named, before or after the verdict.
        let claim = Claim::new("x", "Fig. 8", "s", "r")
            .judge(false, "e".into())
            .ambiguity("which \"Parallel\"");
        assert_eq!(claim.reason.unwrap().kind(), "ambiguity");
        assert_eq!(claim.evidence, "e");
    }

    #[test]
    fn a_pooled_outlier_does_not_decide_a_per_setting_comparison() {
        // Four settings where a is 0.9–1.1× b, one where a failed grossly in
        // a few trials: the pooled means say 1.5×, the settings do not.
        let mut settings = Vec::new();
        let mut pooled_a = Vec::new();
        let mut pooled_b = Vec::new();
        for (k, factor) in [0.9, 1.0, 1.05, 1.1, 1.0].into_iter().enumerate() {
            let mut b: Vec<f64> = (1..=20).map(|i| i as f64 / 10.0).collect();
            let mut a: Vec<f64> = b.iter().map(|v| v * factor).collect();
            if k == 4 {
                a[0] = 60.0;
                a[1] = 90.0;
            }
            pooled_a.extend_from_slice(&a);
            pooled_b.extend_from_slice(&b);
            settings.push((Stat::of(&mut a), Stat::of(&mut b)));
        }
        let pooled = Stat::of(&mut pooled_a).mean / Stat::of(&mut pooled_b).mean;
        assert!(pooled > COMPARABLE_RATIO, "{pooled}");
        let per_setting = per_setting_ratio(&settings).unwrap();
        assert!((per_setting - 1.0).abs() < 0.06, "{per_setting}");
        assert!(comparable(per_setting, 1.0).0);
    }

    #[test]
    fn levels_allow_ten_percent_beyond_the_stated_range() {
        assert!(within_level(0.5, (0.5, 0.7)) && within_level(0.76, (0.5, 0.7)));
        assert!(within_level(0.46, (0.5, 0.7)));
        // Just outside the widened bounds.
        assert!(!within_level(0.771, (0.5, 0.7)));
        assert!(!within_level(0.449, (0.5, 0.7)));
    }
}
