//! Numbers as reports and summaries print them.

/// Formats a number with `digits` significant digits, or "—" when absent or
/// not finite.
pub fn significant(value: Option<f64>, digits: usize) -> String {
    match value {
        Some(v) if v.is_finite() => {
            if v == 0.0 {
                return "0".into();
            }
            let magnitude = v.abs().log10().floor() as i32;
            let decimals = (digits as i32 - 1 - magnitude).max(0) as usize;
            format!("{v:.decimals$}")
        }
        _ => "—".into(),
    }
}
