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

/// A share (0…1) as a percentage with one decimal, or with as many more
/// (up to four) as keep a share short of 1 from reading "100.0" (99.99%
/// is not 100%) and one above 0 from reading "0.0".
pub fn share_percent(share: f64) -> String {
    let percent = 100.0 * share;
    (1..=4)
        .map(|decimals| format!("{percent:.decimals$}"))
        .find(|text| {
            let read: f64 = text.parse().unwrap_or(percent);
            !((share < 1.0 && read >= 100.0) || (share > 0.0 && read <= 0.0))
        })
        .unwrap_or_else(|| format!("{percent:.4}"))
}

#[cfg(test)]
mod tests {
    use super::{share_percent, significant};

    #[test]
    fn shares_near_the_ends_keep_the_decimals_that_tell_them_apart() {
        assert_eq!(share_percent(0.96), "96.0");
        assert_eq!(share_percent(0.999), "99.9");
        assert_eq!(share_percent(0.9999), "99.99");
        assert_eq!(share_percent(1.0), "100.0");
        assert_eq!(share_percent(0.00002), "0.002");
        assert_eq!(share_percent(0.0), "0.0");
    }

    #[test]
    fn small_numbers_use_e_notation_and_the_rest_do_not() {
        assert_eq!(significant(Some(0.0000639), 3), "6.39e-5");
        assert_eq!(significant(Some(0.00224), 3), "0.00224");
        assert_eq!(significant(Some(38200.0), 3), "38200");
        assert_eq!(significant(Some(0.0), 3), "0");
        assert_eq!(significant(Some(f64::NAN), 3), "—");
    }
}
