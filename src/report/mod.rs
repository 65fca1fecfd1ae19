//! Report writers: SVG plots, markdown tables and CSV files.
//! Reports go to `reports/<name>/` as `report.md` + `summary.json` + CSV +
//! SVG (docs/formats.md, "Report files"); the commands that build them own
//! their content, this module only draws and formats.

pub mod heatmap;
pub mod plots;

use std::path::Path;

pub mod number;
mod table;

pub use table::Table;

pub use crate::files::ReportError;

pub use number::significant;

/// A reduction in percent (positive when the new value is lower) in words:
/// "40.2% lower" or "7.7% higher", never "−7.7% lower"; "not measurable"
/// when the reduction is not a finite number (for example when the
/// reference error is zero or nothing was measured).
pub fn percent_lower(reduction_percent: f64) -> String {
    if !reduction_percent.is_finite() {
        "not measurable".into()
    } else if reduction_percent < 0.0 && format!("{:.1}", -reduction_percent) != "0.0" {
        format!("{:.1}% higher", -reduction_percent)
    } else {
        format!("{:.1}% lower", reduction_percent.abs())
    }
}

/// Writes a text file atomically ([`crate::files::write_atomic`]),
/// creating its directory.
pub fn write_text(path: &Path, text: &str) -> Result<(), ReportError> {
    crate::files::write_text_atomic(path, text).map_err(|e| ReportError::write(path, e))
}

/// Runs estimated to take at least this long, seconds, print their
/// estimate before they start.
pub const SLOW_RUN_SECONDS: f64 = 10.0;

/// A duration for an estimate, rounded to what an estimate can promise:
/// "5 s", "40 s", "3 min", "1.5 h".
pub fn duration_text(seconds: f64) -> String {
    if !seconds.is_finite() {
        "an unknown time".into()
    } else if seconds < 1.0 {
        "1 s".into()
    } else if seconds < 90.0 {
        format!("{:.0} s", seconds)
    } else if seconds < 5400.0 {
        format!("{:.0} min", seconds / 60.0)
    } else {
        format!("{:.1} h", seconds / 3600.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tables_render() {
        let mut table = Table::new(["solver", "RMS (°)"]);
        table.row(["ml", "0.12"]);
        assert_eq!(
            table.markdown(),
            "| solver | RMS (°) |\n|---|---|\n| ml | 0.12 |\n"
        );
        assert_eq!(table.csv().unwrap(), "solver,RMS (°)\nml,0.12\n");
    }

    #[test]
    fn console_columns_align_on_long_names() {
        let mut table = Table::new(["design", "RMS (°)"]);
        table.row(["winner", "0.12"]);
        table.row(["a-design-with-a-very-long-name", "10.5"]);
        let text = table.console();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines.len(), 3);
        // Every line ends its last column at the same character.
        let ends: Vec<usize> = lines.iter().map(|l| l.chars().count()).collect();
        assert!(ends.iter().all(|&e| e == ends[0]), "{text}");
        assert!(lines[1].starts_with("winner "), "{text}");
        assert!(lines[2].ends_with("  10.5"), "{text}");
    }

    #[test]
    fn percentages_say_lower_or_higher() {
        assert_eq!(percent_lower(40.24), "40.2% lower");
        assert_eq!(percent_lower(-7.7), "7.7% higher");
        assert_eq!(percent_lower(0.0), "0.0% lower");
        assert_eq!(percent_lower(f64::NAN), "not measurable");
        assert_eq!(percent_lower(f64::INFINITY), "not measurable");
    }

    #[test]
    fn significant_digits() {
        assert_eq!(significant(Some(0.012345), 3), "0.0123");
        assert_eq!(significant(Some(123.456), 3), "123");
        assert_eq!(significant(None, 3), "—");
        assert_eq!(significant(Some(f64::NAN), 3), "—");
    }
}
