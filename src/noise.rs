//! Pixel-noise models for Monte-Carlo trials.
//!
//! Every model draws exactly [`DRAWS_PER_POINT`] numbers per feature per
//! trial, in feature order, whatever its parameters, so that two layouts, two
//! solvers or two noise settings see the same underlying random numbers
//! (common random numbers).
//!
//! * `isotropic`: Gaussian σ px on both axes of every feature.
//! * `per-point`: each feature's own σ from the layout file (`sigma_px`), the
//!   scenario's σ for features without one.
//! * `size`: σ scaled with the sphere's projected size. A blob centroid's
//!   error falls with the length of its edge, over which the edge noise
//!   averages: `σ_i = σ · √(r_ref / r_i)` with r_i the image disc radius and
//!   `r_ref` the radius at which the scenario's σ applies (default
//!   [`DEFAULT_REFERENCE_RADIUS_PX`]).
//! * `calibrated:FILE`: σ measured from images as a function of the disc
//!   radius, `σ_i = a / r_i^b + c` ([`calibrated`]); the scenario's σ is
//!   not used.
//! * outliers (on top of any of the above): with probability `rate` a feature
//!   gets a gross error of [`DEFAULT_OUTLIER_PX`] px (default) in a uniformly
//!   random direction.

pub mod calibrated;

pub use calibrated::{CalibratedSigma, CalibrationError, CalibrationFile};
use rand::Rng;
use rand_distr::StandardNormal;
use serde::Serialize;
use std::str::FromStr;

/// Random numbers drawn per feature per trial, by every model.
pub const DRAWS_PER_POINT: usize = 4;
/// Disc radius (px) at which the `size` model's σ equals the scenario's σ.
pub const DEFAULT_REFERENCE_RADIUS_PX: f64 = 10.0;
/// Magnitude of an outlier, px.
pub const DEFAULT_OUTLIER_PX: f64 = 20.0;

/// How σ varies between features.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "kebab-case")]
pub enum NoiseKind {
    /// The same σ for every feature.
    Isotropic,
    /// Each feature's `sigma_px` from the layout, else the scenario's σ.
    PerPoint,
    /// σ scaled by `√(reference_radius_px / r_i)`.
    Size {
        /// Disc radius at which σ applies unscaled, px.
        reference_radius_px: f64,
    },
    /// σ = a / r^b + c from an image calibration; the scenario's σ unused.
    Calibrated(CalibratedSigma),
}

/// A noise model: how σ varies, plus an optional outlier process.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct NoiseModel {
    /// How σ varies between features.
    pub kind: NoiseKind,
    /// Probability that a feature is an outlier in a trial.
    pub outlier_rate: f64,
    /// Size of an outlier's error, px.
    pub outlier_px: f64,
}

/// A noise model that cannot be used.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum NoiseError {
    /// The model text is not one we know.
    #[error("unknown noise model '{0}'; use isotropic, per-point, size[:REF_RADIUS_PX] or calibrated:FILE, optionally +outliers:RATE[:PX]")]
    Unknown(String),
    /// A parameter is out of range.
    #[error("noise model parameter {name} = {value} is out of range ({requirement})")]
    Parameter {
        /// Which parameter.
        name: &'static str,
        /// Its value.
        value: f64,
        /// The allowed range.
        requirement: &'static str,
    },
    /// A `calibrated:FILE` whose file cannot be used.
    #[error(transparent)]
    Calibration(#[from] CalibrationError),
}

impl Default for NoiseModel {
    fn default() -> Self {
        Self {
            kind: NoiseKind::Isotropic,
            outlier_rate: 0.0,
            outlier_px: DEFAULT_OUTLIER_PX,
        }
    }
}

impl NoiseModel {
    /// Per-feature σ for a scenario of noise `sigma_px`, given the layout's
    /// per-point σ and the features' image disc radii.
    pub fn point_sigma(&self, sigma_px: f64, layout_sigma: Option<f64>, radius_px: f64) -> f64 {
        match self.kind {
            NoiseKind::Isotropic => sigma_px,
            NoiseKind::PerPoint => layout_sigma.unwrap_or(sigma_px),
            NoiseKind::Size {
                reference_radius_px,
            } => sigma_px * (reference_radius_px / radius_px).sqrt(),
            NoiseKind::Calibrated(law) => law.sigma(radius_px),
        }
    }

    /// Draws one feature's pixel error: [`DRAWS_PER_POINT`] numbers from
    /// `rng`, always.
    #[inline]
    pub fn draw(&self, rng: &mut impl Rng, sigma_px: f64) -> [f64; 2] {
        let gx: f64 = rng.sample(StandardNormal);
        let gy: f64 = rng.sample(StandardNormal);
        let outlier_draw: f64 = rng.random();
        let angle: f64 = rng.random::<f64>() * std::f64::consts::TAU;
        let (mut dx, mut dy) = (gx * sigma_px, gy * sigma_px);
        if outlier_draw < self.outlier_rate {
            dx += self.outlier_px * angle.cos();
            dy += self.outlier_px * angle.sin();
        }
        [dx, dy]
    }

    /// This model with the outlier process of `+outliers:…` text, if any.
    fn with_outliers(
        mut self,
        outliers: Option<&str>,
        unknown: impl Fn() -> NoiseError,
    ) -> Result<Self, NoiseError> {
        let number = |s: &str| s.parse::<f64>().map_err(|_| unknown());
        if let Some(outliers) = outliers {
            let mut parts = outliers.split(':');
            if parts.next() != Some("outliers") {
                return Err(unknown());
            }
            self.outlier_rate = number(parts.next().ok_or_else(&unknown)?)?;
            if let Some(px) = parts.next() {
                self.outlier_px = number(px)?;
            }
            if parts.next().is_some() {
                return Err(unknown());
            }
            if !(0.0..=1.0).contains(&self.outlier_rate) {
                return Err(NoiseError::Parameter {
                    name: "outlier rate",
                    value: self.outlier_rate,
                    requirement: "0 to 1",
                });
            }
            if !(self.outlier_px >= 0.0 && self.outlier_px.is_finite()) {
                return Err(NoiseError::Parameter {
                    name: "outlier size",
                    value: self.outlier_px,
                    requirement: "non-negative px",
                });
            }
        }
        Ok(self)
    }

    /// A short description for report headers.
    pub fn describe(&self) -> String {
        let kind = match self.kind {
            NoiseKind::Isotropic => "isotropic Gaussian".to_string(),
            NoiseKind::PerPoint => "per-point σ from the layout (scenario σ elsewhere)".to_string(),
            NoiseKind::Size {
                reference_radius_px,
            } => format!("σ·√({reference_radius_px} px / disc radius)"),
            NoiseKind::Calibrated(law) => format!(
                "calibrated from images: σ = {:.3} / r^{:.2} + {:.3} px (r the disc radius; the scenario's σ unused)",
                law.a, law.b, law.c
            ),
        };
        if self.outlier_rate > 0.0 {
            format!(
                "{kind}, outliers: {:.1}% of features off by {} px",
                100.0 * self.outlier_rate,
                self.outlier_px
            )
        } else {
            kind
        }
    }
}

impl FromStr for NoiseModel {
    type Err = NoiseError;
    /// `isotropic`, `per-point`, `size`, `size:REF_PX` or
    /// `calibrated:FILE` (which reads the file), each optionally followed
    /// by `+outliers:RATE` or `+outliers:RATE:PX`.
    fn from_str(text: &str) -> Result<Self, Self::Err> {
        let unknown = || NoiseError::Unknown(text.to_string());
        let number = |s: &str| s.parse::<f64>().map_err(|_| unknown());
        let (base, outliers) = match text.split_once('+') {
            Some((base, outliers)) => (base, Some(outliers)),
            None => (text, None),
        };
        let mut model = NoiseModel::default();
        if let Some(path) = base.strip_prefix("calibrated:") {
            let file = CalibrationFile::load(std::path::Path::new(path))?;
            model.kind = NoiseKind::Calibrated(file.sigma()?);
            return model.with_outliers(outliers, unknown);
        }
        let mut parts = base.split(':');
        model.kind = match (parts.next(), parts.next(), parts.next()) {
            (Some("isotropic"), None, None) => NoiseKind::Isotropic,
            (Some("per-point"), None, None) => NoiseKind::PerPoint,
            (Some("size"), radius, None) => {
                let reference_radius_px = radius
                    .map(number)
                    .transpose()?
                    .unwrap_or(DEFAULT_REFERENCE_RADIUS_PX);
                if !(reference_radius_px > 0.0 && reference_radius_px.is_finite()) {
                    return Err(NoiseError::Parameter {
                        name: "reference radius",
                        value: reference_radius_px,
                        requirement: "positive px",
                    });
                }
                NoiseKind::Size {
                    reference_radius_px,
                }
            }
            _ => return Err(unknown()),
        };
        model.with_outliers(outliers, unknown)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synthetic::stream_rng;

    #[test]
    fn parses_models() {
        assert_eq!(
            "isotropic".parse::<NoiseModel>().unwrap(),
            NoiseModel::default()
        );
        assert_eq!(
            "per-point".parse::<NoiseModel>().unwrap().kind,
            NoiseKind::PerPoint
        );
        assert_eq!(
            "size:8".parse::<NoiseModel>().unwrap().kind,
            NoiseKind::Size {
                reference_radius_px: 8.0
            }
        );
        let m: NoiseModel = "size+outliers:0.05:15".parse().unwrap();
        assert_eq!(m.outlier_rate, 0.05);
        assert_eq!(m.outlier_px, 15.0);
        assert!("gaussian".parse::<NoiseModel>().is_err());
        let err = "isotropic+outliers:2".parse::<NoiseModel>().unwrap_err();
        assert!(err.to_string().contains("0 to 1"), "{err}");
    }

    #[test]
    fn draws_are_common_random_numbers() {
        let clean = NoiseModel::default();
        let noisy: NoiseModel = "isotropic+outliers:1".parse().unwrap();
        let mut a = stream_rng(3, 4, 5);
        let mut b = stream_rng(3, 4, 5);
        for _ in 0..10 {
            let x = clean.draw(&mut a, 0.5);
            let y = noisy.draw(&mut b, 0.5);
            // Same Gaussian part, plus a 20 px outlier.
            let dx = y[0] - x[0];
            let dy = y[1] - x[1];
            assert!(((dx * dx + dy * dy).sqrt() - 20.0).abs() < 1e-9);
        }
    }

    #[test]
    fn a_calibrated_model_reads_its_file_and_scales_with_radius() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("noise.json");
        let file = CalibrationFile {
            law: calibrated::LAW.to_string(),
            a: 2.0,
            b: 1.0,
            c: 0.05,
            radius_px: [3.0, 40.0],
            fit: calibrated::FitQuality {
                points: 8,
                rms_relative_residual: 0.02,
                worst_relative_residual: 0.04,
                size_law_rms_relative_residual: 0.3,
            },
            centre_error: calibrated::CentreErrorMeasure::AboutTruth,
            source: String::new(),
        };
        std::fs::write(&path, file.to_json()).unwrap();
        let model: NoiseModel = format!("calibrated:{}+outliers:0.01", path.display())
            .parse()
            .unwrap();
        assert!((model.point_sigma(0.5, Some(9.0), 20.0) - 0.15).abs() < 1e-12);
        assert_eq!(model.outlier_rate, 0.01);
        assert!(
            model.describe().contains("calibrated"),
            "{}",
            model.describe()
        );
        let missing = format!("calibrated:{}", dir.path().join("none.json").display());
        let error = missing.parse::<NoiseModel>().unwrap_err().to_string();
        assert!(error.contains("cannot read noise calibration"), "{error}");
    }

    #[test]
    fn size_law() {
        let m: NoiseModel = "size:10".parse().unwrap();
        assert!((m.point_sigma(0.5, None, 40.0) - 0.25).abs() < 1e-12);
        let p: NoiseModel = "per-point".parse().unwrap();
        assert_eq!(p.point_sigma(0.5, Some(0.2), 1.0), 0.2);
        assert_eq!(p.point_sigma(0.5, None, 1.0), 0.5);
    }
}
