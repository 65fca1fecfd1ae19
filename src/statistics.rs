//! Order statistics of samples, shared by the Monte-Carlo summaries, the
//! validation analysis and the reproduction's verdicts.
//!
//! Every function is pure and deterministic: NaN sorts by
//! [`f64::total_cmp`], so the same values give the same bits in any order.

/// Median of sorted, non-empty values: the middle value, or the mean of the
/// two middle values for an even count.
pub fn median_of_sorted(sorted: &[f64]) -> f64 {
    let n = sorted.len();
    if n % 2 == 1 {
        sorted[n / 2]
    } else {
        0.5 * (sorted[n / 2 - 1] + sorted[n / 2])
    }
}

/// Median of `values` (sorted in place); `None` when empty.
pub fn median(values: &mut [f64]) -> Option<f64> {
    values.sort_by(f64::total_cmp);
    (!values.is_empty()).then(|| median_of_sorted(values))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn median_of_odd_even_and_empty() {
        assert_eq!(median(&mut [3.0, 1.0, 2.0, 10.0]), Some(2.5));
        assert_eq!(median(&mut [5.0, -1.0, 2.0]), Some(2.0));
        assert_eq!(median(&mut []), None);
        assert_eq!(median_of_sorted(&[1.0, 2.0]), 1.5);
    }
}
