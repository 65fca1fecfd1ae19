//! The one error every command's configuration check returns.
//!
//! Each command (search, validate, export, reproduce, render, track) checks
//! its configuration once, in the library, before any work starts. A bad
//! value is reported as a [`ConfigError`] that names the configuration field
//! (`sphere_diameter_mm`, `trials`, …) and says what is wrong with it; the
//! command line maps field names to its flag names ([`ConfigError::field`]),
//! so the wording is the same wherever the config came from.

use thiserror::Error;

/// A configuration value that cannot be used, named by its field.
#[derive(Debug, Clone, PartialEq, Error)]
#[error("{field}: {reason}")]
#[non_exhaustive]
pub struct ConfigError {
    /// The configuration field, as spelled in the config struct.
    pub field: &'static str,
    /// What is wrong with its value, as a sentence fragment without the
    /// field's name ("must be positive, got -1").
    pub reason: String,
}

impl ConfigError {
    /// An error for `field` with the given `reason`.
    pub fn new(field: &'static str, reason: impl Into<String>) -> Self {
        ConfigError {
            field,
            reason: reason.into(),
        }
    }

    /// Checks that `value` is finite and positive.
    ///
    /// ```
    /// use layout_opt::config::ConfigError;
    /// assert!(ConfigError::positive("gap_mm", 1.0).is_ok());
    /// let error = ConfigError::positive("gap_mm", -1.0).unwrap_err();
    /// assert_eq!(error.to_string(), "gap_mm: must be a positive finite number, got -1");
    /// ```
    pub fn positive(field: &'static str, value: f64) -> Result<(), ConfigError> {
        if value.is_finite() && value > 0.0 {
            Ok(())
        } else {
            Err(ConfigError::new(
                field,
                format!("must be a positive finite number, got {value}"),
            ))
        }
    }

    /// Checks that `value` is finite and not negative.
    pub fn non_negative(field: &'static str, value: f64) -> Result<(), ConfigError> {
        if value.is_finite() && value >= 0.0 {
            Ok(())
        } else {
            Err(ConfigError::new(
                field,
                format!("must be a finite number ≥ 0, got {value}"),
            ))
        }
    }

    /// Checks that `value` lies in `[low, high]` (and is finite).
    pub fn within(field: &'static str, value: f64, low: f64, high: f64) -> Result<(), ConfigError> {
        if value.is_finite() && (low..=high).contains(&value) {
            Ok(())
        } else {
            Err(ConfigError::new(
                field,
                format!("must lie in {low}..{high}, got {value}"),
            ))
        }
    }
}

/// A YAML parser's error as one line: its first line (where and what),
/// without the source excerpt drawn below it and without a leading
/// `error: `.
///
/// ```
/// use layout_opt::config::one_line;
/// let text = "error: line 2 column 6: bad ':'\n --> <input>:2:6\n  |";
/// assert_eq!(one_line(text), "line 2 column 6: bad ':'");
/// ```
pub fn one_line(error: &str) -> String {
    let first = error.lines().next().unwrap_or_default().trim();
    first.strip_prefix("error: ").unwrap_or(first).to_string()
}

/// A share in [0, 1] written as a fraction (`0.999`) or a percentage
/// (`99.9%`); `None` for anything else.
pub fn parse_share(text: &str) -> Option<f64> {
    let text = text.trim();
    let (number, scale) = match text.strip_suffix('%') {
        Some(percent) => (percent, 0.01),
        None => (text, 1.0),
    };
    let share = number.trim().parse::<f64>().ok()? * scale;
    (0.0..=1.0).contains(&share).then_some(share)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn messages_name_the_field_and_the_value() {
        assert_eq!(
            ConfigError::non_negative("trials", f64::NAN)
                .unwrap_err()
                .to_string(),
            "trials: must be a finite number ≥ 0, got NaN"
        );
        assert_eq!(
            ConfigError::within("max_hidden", 1.5, 0.0, 1.0)
                .unwrap_err()
                .to_string(),
            "max_hidden: must lie in 0..1, got 1.5"
        );
        assert!(ConfigError::within("max_hidden", 1.0, 0.0, 1.0).is_ok());
    }
}
