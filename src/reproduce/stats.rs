//! Statistics behind the verdicts: per-cell error statistics, pooling,
//! two-sample comparisons, rank and linear trends, and a two-segment fit.
//!
//! Every function here is pure and deterministic: the same inputs in the same
//! order give the same bits.

use crate::montecarlo::Summary;
use serde::Serialize;

/// Statistics of one error over the trials that returned a pose.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct Stat {
    /// Number of values.
    pub count: usize,
    /// Mean (the paper's "average error").
    pub mean: f64,
    /// Root mean square (with the mean, gives the standard deviation).
    pub rms: f64,
    /// Median, when the values were at hand (not after pooling).
    pub median: Option<f64>,
    /// Largest value.
    pub max: f64,
    /// Mean of the fourth powers, when the values were at hand (NaN after
    /// the Monte-Carlo engine's summaries): the spread of the squares, for
    /// [`Stat::rms_interval`].
    pub mean_fourth: f64,
}

/// z of a two-sided 95% interval.
const Z_95: f64 = 1.959_964;

impl Stat {
    /// From a Monte-Carlo summary.
    pub fn from_summary(summary: &Summary) -> Stat {
        Stat {
            count: summary.count,
            mean: summary.mean,
            rms: summary.rms,
            median: (summary.count > 0).then_some(summary.median),
            max: summary.max,
            mean_fourth: f64::NAN,
        }
    }

    /// From raw values (sorted in place).
    pub fn of(values: &mut [f64]) -> Stat {
        let mean_fourth = if values.is_empty() {
            f64::NAN
        } else {
            values.iter().map(|v| v.powi(4)).sum::<f64>() / values.len() as f64
        };
        Stat {
            mean_fourth,
            ..Stat::from_summary(&Summary::of(values))
        }
    }

    /// A 95% interval of the RMS: the delta method on the mean square,
    /// whose standard error is `√((m₄ − m₂²)/n)`; `None` without the fourth
    /// moment or with fewer than two values.
    pub fn rms_interval(&self) -> Option<(f64, f64)> {
        if self.count < 2 || !self.mean_fourth.is_finite() {
            return None;
        }
        let mean_square = self.rms * self.rms;
        let variance = (self.mean_fourth - mean_square * mean_square).max(0.0);
        let half = Z_95 * (variance / self.count as f64).sqrt();
        Some((
            (mean_square - half).max(0.0).sqrt(),
            (mean_square + half).sqrt(),
        ))
    }

    /// Trial-weighted pool of several statistics of the same error (the
    /// median is lost).
    pub fn pool<'a>(stats: impl IntoIterator<Item = &'a Stat>) -> Stat {
        let (mut count, mut sum, mut sum_sq, mut max) = (0usize, 0.0, 0.0, 0.0f64);
        let mut sum_fourth = 0.0;
        for s in stats {
            if s.count == 0 {
                continue;
            }
            let n = s.count as f64;
            count += s.count;
            sum += n * s.mean;
            sum_sq += n * s.rms * s.rms;
            sum_fourth += n * s.mean_fourth;
            max = max.max(s.max);
        }
        if count == 0 {
            return Stat::default();
        }
        let n = count as f64;
        Stat {
            count,
            mean: sum / n,
            rms: (sum_sq / n).sqrt(),
            median: None,
            max,
            mean_fourth: sum_fourth / n,
        }
    }

    /// The mean, or `None` without values.
    pub fn mean(&self) -> Option<f64> {
        (self.count > 0).then_some(self.mean)
    }

    /// Standard error of the mean, `s/√n` with the sample standard deviation.
    pub fn standard_error(&self) -> f64 {
        if self.count < 2 {
            return f64::INFINITY;
        }
        let n = self.count as f64;
        let variance = (self.rms * self.rms - self.mean * self.mean).max(0.0) * n / (n - 1.0);
        (variance / n).sqrt()
    }
}

/// Two means compared: `ratio = a / b` and the two-sample z score of
/// `a − b` (unpaired, so conservative under common random numbers, which
/// correlate the two samples positively).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Comparison {
    /// Mean of a over mean of b.
    pub ratio: f64,
    /// `(mean_a − mean_b) / √(se_a² + se_b²)`.
    pub z: f64,
}

/// Compares the means of `a` and `b`; `None` when either has no values or
/// b's mean is zero.
pub fn compare(a: &Stat, b: &Stat) -> Option<Comparison> {
    let (mean_a, mean_b) = (a.mean()?, b.mean()?);
    if mean_b <= 0.0 {
        return None;
    }
    let spread = (a.standard_error().powi(2) + b.standard_error().powi(2)).sqrt();
    let difference = mean_a - mean_b;
    let z = if spread > 0.0 && spread.is_finite() {
        difference / spread
    } else if spread == 0.0 && difference != 0.0 {
        difference.signum() * f64::INFINITY
    } else {
        0.0
    };
    Some(Comparison {
        ratio: mean_a / mean_b,
        z,
    })
}

fn ranks(values: &[f64]) -> Vec<f64> {
    let mut order: Vec<usize> = (0..values.len()).collect();
    order.sort_by(|&a, &b| values[a].total_cmp(&values[b]));
    let mut ranks = vec![0.0; values.len()];
    let mut start = 0;
    while start < order.len() {
        let mut end = start;
        while end + 1 < order.len() && values[order[end + 1]] == values[order[start]] {
            end += 1;
        }
        let rank = 0.5 * (start + end) as f64;
        for &index in &order[start..=end] {
            ranks[index] = rank;
        }
        start = end + 1;
    }
    ranks
}

/// Pearson correlation of `x` and `y` (`None` for fewer than 3 points or a
/// constant sequence).
pub fn pearson(x: &[f64], y: &[f64]) -> Option<f64> {
    if x.len() != y.len() || x.len() < 3 {
        return None;
    }
    let n = x.len() as f64;
    let (mx, my) = (x.iter().sum::<f64>() / n, y.iter().sum::<f64>() / n);
    let (mut sxy, mut sxx, mut syy) = (0.0, 0.0, 0.0);
    for (a, b) in x.iter().zip(y) {
        sxy += (a - mx) * (b - my);
        sxx += (a - mx) * (a - mx);
        syy += (b - my) * (b - my);
    }
    (sxx > 0.0 && syy > 0.0).then(|| sxy / (sxx * syy).sqrt())
}

/// Spearman rank correlation of `x` and `y` (ties get mean ranks).
pub fn spearman(x: &[f64], y: &[f64]) -> Option<f64> {
    pearson(&ranks(x), &ranks(y))
}

/// Least-squares line `y = slope·x + intercept` with its R².
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct LineFit {
    /// Slope.
    pub slope: f64,
    /// Intercept.
    pub intercept: f64,
    /// Coefficient of determination.
    pub r_squared: f64,
    /// Sum of squared residuals.
    pub residual_sum_sq: f64,
}

/// Fits a line to `(x, y)` (`None` for fewer than 2 points or constant x).
pub fn line_fit(x: &[f64], y: &[f64]) -> Option<LineFit> {
    if x.len() != y.len() || x.len() < 2 {
        return None;
    }
    let n = x.len() as f64;
    let (mx, my) = (x.iter().sum::<f64>() / n, y.iter().sum::<f64>() / n);
    let (mut sxy, mut sxx, mut syy) = (0.0, 0.0, 0.0);
    for (a, b) in x.iter().zip(y) {
        sxy += (a - mx) * (b - my);
        sxx += (a - mx) * (a - mx);
        syy += (b - my) * (b - my);
    }
    if sxx <= 0.0 {
        return None;
    }
    let slope = sxy / sxx;
    let intercept = my - slope * mx;
    let residual_sum_sq: f64 = x
        .iter()
        .zip(y)
        .map(|(a, b)| (b - slope * a - intercept).powi(2))
        .sum();
    let r_squared = if syy > 0.0 {
        1.0 - residual_sum_sq / syy
    } else {
        1.0
    };
    Some(LineFit {
        slope,
        intercept,
        r_squared,
        residual_sum_sq,
    })
}

/// The best fit of two independent line segments split at one sample.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct KneeFit {
    /// Where the two fitted lines meet (clamped to the gap between the
    /// segments): the knee.
    pub knee: f64,
    /// Residual sum of squares of the two-segment fit.
    pub two_segment_sum_sq: f64,
    /// Residual sum of squares of a single line.
    pub one_line_sum_sq: f64,
}

/// Splits `(x, y)` (x increasing) into two segments of at least three points
/// each, fitting a line to each, and returns the split with the smallest
/// total residual.
pub fn knee_fit(x: &[f64], y: &[f64]) -> Option<KneeFit> {
    let one = line_fit(x, y)?;
    let mut best: Option<KneeFit> = None;
    for split in 3..x.len().saturating_sub(2) {
        let (Some(left), Some(right)) = (
            line_fit(&x[..split], &y[..split]),
            line_fit(&x[split..], &y[split..]),
        ) else {
            continue;
        };
        let total = left.residual_sum_sq + right.residual_sum_sq;
        if best.is_none_or(|b| total < b.two_segment_sum_sq) {
            // Where the two lines meet, kept within the gap between the segments.
            let (lo, hi) = (x[split - 1], x[split]);
            let meet = (right.intercept - left.intercept) / (left.slope - right.slope);
            let knee = if meet.is_finite() {
                meet.clamp(lo, hi)
            } else {
                0.5 * (lo + hi)
            };
            best = Some(KneeFit {
                knee,
                two_segment_sum_sq: total,
                one_line_sum_sq: one.residual_sum_sq,
            });
        }
    }
    best
}

/// Mean of a slice (`None` when empty).
pub fn mean(values: &[f64]) -> Option<f64> {
    (!values.is_empty()).then(|| values.iter().sum::<f64>() / values.len() as f64)
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn pooling_is_trial_weighted() {
        let a = Stat::of(&mut [1.0, 2.0, 3.0]);
        let b = Stat::of(&mut [10.0]);
        let pooled = Stat::pool([&a, &b]);
        assert_eq!(pooled.count, 4);
        assert_relative_eq!(pooled.mean, 4.0);
        assert_relative_eq!(pooled.rms, ((1.0 + 4.0 + 9.0 + 100.0) / 4.0f64).sqrt());
        assert_eq!(pooled.max, 10.0);
        assert_eq!(pooled.median, None);
        assert_eq!(Stat::pool([]).count, 0);
    }

    #[test]
    fn standard_error_and_comparison() {
        let a = Stat::of(&mut [1.0, 3.0, 1.0, 3.0]);
        // Sample sd = √(4/3), se = √(1/3).
        assert_relative_eq!(a.standard_error(), (1.0f64 / 3.0).sqrt(), epsilon = 1e-12);
        let b = Stat::of(&mut [0.5, 1.5, 0.5, 1.5]);
        let c = compare(&a, &b).unwrap();
        assert_relative_eq!(c.ratio, 2.0);
        let spread = (a.standard_error().powi(2) + b.standard_error().powi(2)).sqrt();
        assert_relative_eq!(c.z, 1.0 / spread, epsilon = 1e-12);
        assert!(compare(&a, &Stat::default()).is_none());
    }

    #[test]
    fn correlations() {
        let x = [1.0, 2.0, 3.0, 4.0, 5.0];
        let y = [1.0, 4.0, 9.0, 16.0, 100.0];
        assert_relative_eq!(spearman(&x, &y).unwrap(), 1.0, epsilon = 1e-12);
        let down: Vec<f64> = y.iter().map(|v| -v).collect();
        assert_relative_eq!(spearman(&x, &down).unwrap(), -1.0, epsilon = 1e-12);
        assert!(pearson(&x, &y).unwrap() < 1.0);
        assert!(spearman(&x, &[1.0; 5]).is_none());
        // Ties share the mean rank.
        assert_eq!(ranks(&[3.0, 1.0, 3.0]), vec![1.5, 0.0, 1.5]);
    }

    #[test]
    fn line_and_knee_fits() {
        let x: Vec<f64> = (0..10).map(f64::from).collect();
        let y: Vec<f64> = x.iter().map(|v| 2.0 * v + 1.0).collect();
        let fit = line_fit(&x, &y).unwrap();
        assert_relative_eq!(fit.slope, 2.0, epsilon = 1e-12);
        assert_relative_eq!(fit.intercept, 1.0, epsilon = 1e-12);
        assert_relative_eq!(fit.r_squared, 1.0, epsilon = 1e-12);
        // A knee at x = 4: slope 5 then slope 0.5.
        let bent: Vec<f64> = x
            .iter()
            .map(|&v| {
                if v <= 4.0 {
                    5.0 * v
                } else {
                    20.0 + 0.5 * (v - 4.0)
                }
            })
            .collect();
        let knee = knee_fit(&x, &bent).unwrap();
        assert_eq!(knee.knee, 4.0);
        assert!(knee.two_segment_sum_sq < 1e-20 && knee.one_line_sum_sq > 1.0);
        assert_eq!(
            crate::statistics::median(&mut [3.0, 1.0, 2.0, 10.0]),
            Some(2.5)
        );
        assert_eq!(mean(&[]), None);
    }
}
