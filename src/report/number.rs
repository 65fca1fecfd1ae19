//! Numbers as reports and summaries print them.

/// Below 10^this a number is written in e-notation.
const SMALLEST_PLAIN_MAGNITUDE: i32 = -3;

/// Formats a number with `digits` significant digits (in e-notation below
/// 0.001), or "—" when absent or
/// not finite.
pub fn significant(value: Option<f64>, digits: usize) -> String {
    match value {
        Some(v) if v.is_finite() => {
            if v == 0.0 {
                return "0".into();
            }
            let magnitude = v.abs().log10().floor() as i32;
            if magnitude < SMALLEST_PLAIN_MAGNITUDE {
                // 6.39e-5 reads better than 0.0000639.
                let decimals = digits.saturating_sub(1);
                return format!("{v:.decimals$e}");
            }
            let decimals = (digits as i32 - 1 - magnitude).max(0) as usize;
            format!("{v:.decimals$}")
        }
        _ => "—".into(),
    }
}

#[cfg(test)]
mod tests {
    use super::significant;

    #[test]
    fn small_numbers_use_e_notation_and_the_rest_do_not() {
        assert_eq!(significant(Some(0.0000639), 3), "6.39e-5");
        assert_eq!(significant(Some(0.00224), 3), "0.00224");
        assert_eq!(significant(Some(38200.0), 3), "38200");
        assert_eq!(significant(Some(0.0), 3), "0");
        assert_eq!(significant(Some(f64::NAN), 3), "—");
    }
}
