//! Report writers: SVG plots, markdown tables and CSV files.
//! Reports go to `reports/<name>/` as `report.md` + `summary.json` + CSV +
//! SVG (docs/formats.md, "Report files"); the commands that build them own
//! their content, this module only draws and formats.

pub mod plots;

use std::fmt::Write as _;
use std::path::Path;

/// Errors while writing a report.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ReportError {
    /// A file could not be written.
    #[error("cannot write {path}: {message}")]
    Write {
        /// The file.
        path: String,
        /// What went wrong.
        message: String,
    },
}

impl ReportError {
    /// Wraps any displayable error for `path`.
    pub fn write(path: &Path, error: impl std::fmt::Display) -> Self {
        ReportError::Write {
            path: path.display().to_string(),
            message: error.to_string(),
        }
    }
}

/// A markdown table under construction.
#[derive(Debug, Clone, Default)]
pub struct Table {
    header: Vec<String>,
    rows: Vec<Vec<String>>,
}

impl Table {
    /// A table with these column headings.
    pub fn new<S: Into<String>>(header: impl IntoIterator<Item = S>) -> Self {
        Self {
            header: header.into_iter().map(Into::into).collect(),
            rows: Vec::new(),
        }
    }

    /// Appends a row.
    pub fn row<S: Into<String>>(&mut self, cells: impl IntoIterator<Item = S>) {
        self.rows.push(cells.into_iter().map(Into::into).collect());
    }

    /// The table as GitHub-flavoured markdown.
    pub fn markdown(&self) -> String {
        let mut out = String::new();
        let _ = writeln!(out, "| {} |", self.header.join(" | "));
        let _ = writeln!(out, "|{}", "---|".repeat(self.header.len()));
        for row in &self.rows {
            let _ = writeln!(out, "| {} |", row.join(" | "));
        }
        out
    }

    /// The table as CSV (same cells).
    pub fn csv(&self) -> Result<String, csv::Error> {
        let mut writer = csv::Writer::from_writer(Vec::new());
        writer.write_record(&self.header)?;
        for row in &self.rows {
            writer.write_record(row)?;
        }
        let bytes = writer.into_inner().map_err(|e| e.into_error())?;
        Ok(String::from_utf8(bytes).expect("CSV of UTF-8 cells is UTF-8"))
    }
}

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

/// Writes a text file atomically ([`crate::files::write_atomic`]),
/// creating its directory.
pub fn write_text(path: &Path, text: &str) -> Result<(), ReportError> {
    crate::files::write_text_atomic(path, text).map_err(|e| ReportError::write(path, e))
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
    fn significant_digits() {
        assert_eq!(significant(Some(0.012345), 3), "0.0123");
        assert_eq!(significant(Some(123.456), 3), "123");
        assert_eq!(significant(None, 3), "—");
        assert_eq!(significant(Some(f64::NAN), 3), "—");
    }
}
