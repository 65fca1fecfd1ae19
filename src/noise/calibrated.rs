//! A centre-noise law measured from images: `σ(r) = a / r^b + c` px, with
//! `r` the blob's disc radius in px.
//!
//! **Form.** A blob's centre averages the noise of its edge, whose length
//! grows with `r`, so σ falls as a power of `r` (`b` = ½ for edge noise
//! that averages over the perimeter, 1 or more when the edge's contrast
//! grows too). The constant `c` is what no size removes: quantisation,
//! the detector's own bias spread, a lens that is never perfectly
//! modelled. Today's `size` law is the special case `b` = ½, `c` = 0.
//!
//! **Fit.** [`fit`] takes the measured σ at several radii and minimises the
//! squared *relative* residual, `Σ wᵢ ((σ(rᵢ) − sᵢ) / sᵢ)²`, so that the
//! small σ of large blobs weigh as much as the large σ of small ones. For a
//! fixed `b` the law is linear in `a` and `c`, solved exactly with both
//! kept non-negative; `b` is found by a grid over [`EXPONENT_RANGE`] and a
//! golden-section refinement around the grid's best, deterministic for
//! the same data.
//!
//! **File.** JSON ([`CalibrationFile`], documented in `docs/formats.md`):
//! the three coefficients, the radius range they were fitted over, the
//! fit's quality and how the data were made.

use serde::{Deserialize, Serialize};
use std::path::Path;

/// The exponents `b` the fit considers.
pub const EXPONENT_RANGE: (f64, f64) = (0.0, 3.0);
/// Grid steps over [`EXPONENT_RANGE`] before the golden-section search.
const EXPONENT_GRID: usize = 60;
/// Golden-section iterations (the bracket shrinks by 0.618 each).
const GOLDEN_ITERATIONS: usize = 60;

/// `σ(r) = a / r^b + c` px.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CalibratedSigma {
    /// Scale of the size-dependent part, px · px^b.
    pub a: f64,
    /// Exponent of the radius.
    pub b: f64,
    /// The floor no blob size removes, px.
    pub c: f64,
}

impl CalibratedSigma {
    /// Checks that the coefficients are finite, `a` and `c` non-negative,
    /// not both zero, and `b` within [`EXPONENT_RANGE`].
    pub fn new(a: f64, b: f64, c: f64) -> Result<Self, CalibrationError> {
        let check = |name: &'static str, value: f64, ok: bool, requirement: &'static str| {
            if value.is_finite() && ok {
                Ok(())
            } else {
                Err(CalibrationError::Coefficient {
                    name,
                    value,
                    requirement,
                })
            }
        };
        check("a", a, a >= 0.0, "a non-negative number")?;
        check(
            "b",
            b,
            (EXPONENT_RANGE.0..=EXPONENT_RANGE.1).contains(&b),
            "from 0 to 3",
        )?;
        check("c", c, c >= 0.0, "a non-negative number")?;
        if a + c <= 0.0 {
            return Err(CalibrationError::Coefficient {
                name: "a + c",
                value: a + c,
                requirement: "positive: a law of zero noise",
            });
        }
        Ok(Self { a, b, c })
    }

    /// σ at disc radius `radius_px` (a radius below 0.5 px is taken as
    /// 0.5 px: no detector resolves a smaller blob).
    pub fn sigma(&self, radius_px: f64) -> f64 {
        self.a / radius_px.max(0.5).powf(self.b) + self.c
    }
}

/// A calibration as written to and read from a file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CalibrationFile {
    /// The law, in words: always `"sigma_px = a / radius_px^b + c"`.
    pub law: String,
    /// Scale of the size-dependent part.
    pub a: f64,
    /// Exponent of the radius.
    pub b: f64,
    /// Floor, px.
    pub c: f64,
    /// The smallest and largest disc radius the data covered, px; outside
    /// it the law is an extrapolation.
    pub radius_px: [f64; 2],
    /// How well the law fits the data.
    pub fit: FitQuality,
    /// What the law measures of a centre: its error about the truth (noise
    /// and bias together) or its noise alone. Files that do not say are
    /// noise alone (the first files written).
    #[serde(default)]
    pub centre_error: CentreErrorMeasure,
    /// How the data were made: the command, preset, seed, trials.
    #[serde(default)]
    pub source: String,
}

/// What a calibrated σ measures of a detected centre, per axis.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CentreErrorMeasure {
    /// The RMS about the exact centre: the scatter under sensor noise and
    /// the view's own bias (what the tracker's errors are, over a working
    /// range whose views each bias their centres differently).
    AboutTruth,
    /// The RMS about the view's mean centre: sensor noise alone.
    #[default]
    Scatter,
}

impl CentreErrorMeasure {
    /// In words, for reports.
    pub fn describe(self) -> &'static str {
        match self {
            Self::AboutTruth => "error about the exact centre (noise and bias)",
            Self::Scatter => "scatter about the mean centre (noise alone)",
        }
    }
}

/// The law written in every file.
pub const LAW: &str = "sigma_px = a / radius_px^b + c";

impl CalibrationFile {
    /// The checked law.
    pub fn sigma(&self) -> Result<CalibratedSigma, CalibrationError> {
        if self.law != LAW {
            return Err(CalibrationError::Law(self.law.clone()));
        }
        CalibratedSigma::new(self.a, self.b, self.c)
    }

    /// Reads and checks a calibration file.
    pub fn load(path: &Path) -> Result<Self, CalibrationError> {
        let text = std::fs::read_to_string(path).map_err(|error| CalibrationError::Read {
            path: path.display().to_string(),
            reason: error.to_string(),
        })?;
        let file: CalibrationFile =
            serde_json::from_str(&text).map_err(|error| CalibrationError::Parse {
                path: path.display().to_string(),
                line: error.line(),
                reason: error.to_string(),
            })?;
        file.sigma()?;
        Ok(file)
    }

    /// The file as pretty JSON.
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("a calibration serialises") + "\n"
    }
}

/// How well a law fits the data it was fitted to.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FitQuality {
    /// Radii (data points) fitted.
    pub points: usize,
    /// Weighted RMS of the relative residuals, `(σ(r) − s) / s`.
    pub rms_relative_residual: f64,
    /// The largest relative residual in magnitude.
    pub worst_relative_residual: f64,
    /// The same RMS for the best law of today's `size` form (`b` = ½,
    /// `c` = 0), for comparison.
    pub size_law_rms_relative_residual: f64,
}

/// One measurement: σ of the centre at one disc radius, and its weight
/// (for example the number of centres behind it).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SigmaSample {
    /// Disc radius, px.
    pub radius_px: f64,
    /// Measured σ of the centre, px.
    pub sigma_px: f64,
    /// Weight, > 0.
    pub weight: f64,
}

/// A calibration that cannot be read, checked or fitted.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum CalibrationError {
    /// The file cannot be read.
    #[error("cannot read noise calibration {path}: {reason}")]
    Read {
        /// The file.
        path: String,
        /// Why.
        reason: String,
    },
    /// The file is not a calibration.
    #[error("noise calibration {path}, line {line}: {reason}")]
    Parse {
        /// The file.
        path: String,
        /// The line the parser stopped at.
        line: usize,
        /// What it found (names the field).
        reason: String,
    },
    /// The law is not ours.
    #[error("noise calibration law '{0}' is not '{LAW}'")]
    Law(String),
    /// A coefficient is out of range.
    #[error("noise calibration field {name} = {value} must be {requirement}")]
    Coefficient {
        /// Which coefficient.
        name: &'static str,
        /// Its value.
        value: f64,
        /// What it must be.
        requirement: &'static str,
    },
    /// Too little or bad data to fit.
    #[error("cannot fit a noise law: {0}")]
    Data(String),
}

/// Fits `σ(r) = a / r^b + c` to `samples` (module docs). Needs at least
/// three samples at two or more distinct radii, every radius, σ and weight
/// finite and positive.
pub fn fit(samples: &[SigmaSample]) -> Result<(CalibratedSigma, FitQuality), CalibrationError> {
    if samples.len() < 3 {
        return Err(CalibrationError::Data(format!(
            "{} radii measured, at least 3 needed",
            samples.len()
        )));
    }
    let positive = |x: f64| x.is_finite() && x > 0.0;
    if let Some(bad) = samples
        .iter()
        .find(|s| !(positive(s.radius_px) && positive(s.sigma_px) && positive(s.weight)))
    {
        return Err(CalibrationError::Data(format!(
            "radius {} px, σ {} px, weight {}: each must be finite and positive",
            bad.radius_px, bad.sigma_px, bad.weight
        )));
    }
    let (low, high) = samples
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), s| {
            (l.min(s.radius_px), h.max(s.radius_px))
        });
    if high <= low * (1.0 + 1e-9) {
        return Err(CalibrationError::Data(format!(
            "every radius is {low} px: a law of radius needs two or more"
        )));
    }
    let cost = |b: f64| best_scale_and_floor(samples, b).2;
    let step = (EXPONENT_RANGE.1 - EXPONENT_RANGE.0) / EXPONENT_GRID as f64;
    let best = (0..=EXPONENT_GRID)
        .map(|i| EXPONENT_RANGE.0 + step * i as f64)
        .min_by(|x, y| cost(*x).total_cmp(&cost(*y)))
        .expect("the grid is not empty");
    let b = golden_minimum(
        cost,
        (best - step).max(EXPONENT_RANGE.0),
        (best + step).min(EXPONENT_RANGE.1),
    );
    let b = if cost(b) <= cost(best) { b } else { best };
    let (a, c, _) = best_scale_and_floor(samples, b);
    let law = CalibratedSigma::new(a, b, c)?;
    let size_law = {
        let (a, _) = best_scale(samples, 0.5);
        CalibratedSigma { a, b: 0.5, c: 0.0 }
    };
    let quality = FitQuality {
        points: samples.len(),
        rms_relative_residual: rms_relative(samples, &law),
        worst_relative_residual: samples
            .iter()
            .map(|s| (law.sigma(s.radius_px) - s.sigma_px) / s.sigma_px)
            .fold(
                0.0,
                |worst: f64, r| if r.abs() > worst.abs() { r } else { worst },
            ),
        size_law_rms_relative_residual: rms_relative(samples, &size_law),
    };
    Ok((law, quality))
}

/// Weighted RMS of the relative residuals of `law` over `samples`.
fn rms_relative(samples: &[SigmaSample], law: &CalibratedSigma) -> f64 {
    let (sum, weight) = samples.iter().fold((0.0, 0.0), |(sum, weight), s| {
        let r = (law.sigma(s.radius_px) - s.sigma_px) / s.sigma_px;
        (sum + s.weight * r * r, weight + s.weight)
    });
    (sum / weight).sqrt()
}

/// For a fixed exponent: the non-negative `(a, c)` of least weighted
/// relative squared residual, and that residual sum.
fn best_scale_and_floor(samples: &[SigmaSample], b: f64) -> (f64, f64, f64) {
    // Relative residual (a xᵢ + c − sᵢ)/sᵢ with xᵢ = rᵢ^−b: a weighted
    // linear least-squares problem in (a, c) with rows (xᵢ/sᵢ, 1/sᵢ) and
    // target 1.
    let (mut sxx, mut sxy, mut syy, mut sx, mut sy) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for s in samples {
        let x = s.radius_px.max(0.5).powf(-b) / s.sigma_px;
        let y = 1.0 / s.sigma_px;
        sxx += s.weight * x * x;
        sxy += s.weight * x * y;
        syy += s.weight * y * y;
        sx += s.weight * x;
        sy += s.weight * y;
    }
    let residual = |a: f64, c: f64| {
        samples
            .iter()
            .map(|s| {
                let r = (a * s.radius_px.max(0.5).powf(-b) + c - s.sigma_px) / s.sigma_px;
                s.weight * r * r
            })
            .sum::<f64>()
    };
    let determinant = sxx * syy - sxy * sxy;
    if determinant > 1e-12 * sxx * syy {
        let a = (sx * syy - sy * sxy) / determinant;
        let c = (sy * sxx - sx * sxy) / determinant;
        if a >= 0.0 && c >= 0.0 {
            return (a, c, residual(a, c));
        }
    }
    // The unconstrained minimum has a negative part (or the columns are
    // parallel, b = 0): the constrained one lies on an edge, a = 0 or c = 0.
    let (a, a_only) = best_scale(samples, b);
    let c = sy / syy;
    let c_only = residual(0.0, c);
    if a_only <= c_only {
        (a, 0.0, a_only)
    } else {
        (0.0, c, c_only)
    }
}

/// For a fixed exponent and no floor: the best `a ≥ 0` and its residual sum.
fn best_scale(samples: &[SigmaSample], b: f64) -> (f64, f64) {
    let (mut sxx, mut sx) = (0.0, 0.0);
    for s in samples {
        let x = s.radius_px.max(0.5).powf(-b) / s.sigma_px;
        sxx += s.weight * x * x;
        sx += s.weight * x;
    }
    let a = (sx / sxx).max(0.0);
    let residual = samples
        .iter()
        .map(|s| {
            let r = (a * s.radius_px.max(0.5).powf(-b) - s.sigma_px) / s.sigma_px;
            s.weight * r * r
        })
        .sum();
    (a, residual)
}

/// The minimum of a unimodal `f` on `[low, high]` by golden-section search.
fn golden_minimum(f: impl Fn(f64) -> f64, mut low: f64, mut high: f64) -> f64 {
    let ratio = (5f64.sqrt() - 1.0) / 2.0;
    let mut x1 = high - ratio * (high - low);
    let mut x2 = low + ratio * (high - low);
    let (mut f1, mut f2) = (f(x1), f(x2));
    for _ in 0..GOLDEN_ITERATIONS {
        if f1 <= f2 {
            high = x2;
            (x2, f2) = (x1, f1);
            x1 = high - ratio * (high - low);
            f1 = f(x1);
        } else {
            low = x1;
            (x1, f1) = (x2, f2);
            x2 = low + ratio * (high - low);
            f2 = f(x2);
        }
    }
    0.5 * (low + high)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn samples(law: &CalibratedSigma, radii: &[f64]) -> Vec<SigmaSample> {
        radii
            .iter()
            .map(|&r| SigmaSample {
                radius_px: r,
                sigma_px: law.sigma(r),
                weight: 1.0,
            })
            .collect()
    }

    const RADII: [f64; 8] = [3.0, 5.0, 7.0, 10.0, 14.0, 20.0, 30.0, 45.0];

    #[test]
    fn noise_free_data_give_back_their_law() {
        for (a, b, c) in [(0.9, 1.0, 0.02), (0.3, 0.5, 0.0), (2.0, 1.7, 0.05)] {
            let truth = CalibratedSigma::new(a, b, c).unwrap();
            let (law, quality) = fit(&samples(&truth, &RADII)).unwrap();
            assert!((law.b - b).abs() < 1e-4, "{law:?} against {truth:?}");
            assert!((law.a - a).abs() < 1e-3 * a, "{law:?} against {truth:?}");
            assert!((law.c - c).abs() < 1e-5, "{law:?} against {truth:?}");
            assert!(quality.rms_relative_residual < 1e-5, "{quality:?}");
        }
    }

    #[test]
    fn the_size_law_is_recognised_and_a_floor_is_not_mistaken_for_it() {
        let size = CalibratedSigma::new(0.5 * 10f64.sqrt(), 0.5, 0.0).unwrap();
        let (_, quality) = fit(&samples(&size, &RADII)).unwrap();
        assert!(quality.size_law_rms_relative_residual < 1e-6, "{quality:?}");
        let floored = CalibratedSigma::new(1.0, 1.0, 0.05).unwrap();
        let (_, quality) = fit(&samples(&floored, &RADII)).unwrap();
        assert!(quality.rms_relative_residual < 1e-5, "{quality:?}");
        assert!(quality.size_law_rms_relative_residual > 0.1, "{quality:?}");
    }

    #[test]
    fn bad_data_are_refused() {
        let law = CalibratedSigma::new(1.0, 1.0, 0.0).unwrap();
        assert!(fit(&samples(&law, &[3.0, 5.0])).is_err());
        assert!(fit(&samples(&law, &[5.0, 5.0, 5.0])).is_err());
        let mut bad = samples(&law, &RADII);
        bad[2].sigma_px = f64::NAN;
        let error = fit(&bad).unwrap_err().to_string();
        assert!(error.contains("finite and positive"), "{error}");
        assert!(CalibratedSigma::new(-1.0, 1.0, 0.0).is_err());
        assert!(CalibratedSigma::new(1.0, 4.0, 0.0).is_err());
        assert!(CalibratedSigma::new(0.0, 1.0, 0.0).is_err());
    }

    #[test]
    fn a_file_round_trips_and_a_malformed_one_names_its_line_and_field() {
        let dir = tempfile::tempdir().unwrap();
        let law = CalibratedSigma::new(0.8, 1.1, 0.03).unwrap();
        let (law, fit) = fit(&samples(&law, &RADII)).unwrap();
        let file = CalibrationFile {
            law: LAW.to_string(),
            a: law.a,
            b: law.b,
            c: law.c,
            radius_px: [3.0, 45.0],
            fit,
            centre_error: CentreErrorMeasure::AboutTruth,
            source: "a test".to_string(),
        };
        let path = dir.path().join("noise.json");
        std::fs::write(&path, file.to_json()).unwrap();
        assert_eq!(CalibrationFile::load(&path).unwrap(), file);

        // The first files did not say what they measure: noise alone.
        let older = file
            .to_json()
            .replace("  \"centre_error\": \"about_truth\",\n", "");
        std::fs::write(&path, older).unwrap();
        let read = CalibrationFile::load(&path).unwrap();
        assert_eq!(read.centre_error, CentreErrorMeasure::Scatter);
        let odd = file.to_json().replace("about_truth", "about_lunch");
        std::fs::write(&path, odd).unwrap();
        let error = CalibrationFile::load(&path).unwrap_err().to_string();
        assert!(error.contains("about_lunch"), "{error}");

        let text = file.to_json().replace("\"b\":", "\"bee\":");
        std::fs::write(&path, text).unwrap();
        let error = CalibrationFile::load(&path).unwrap_err().to_string();
        assert!(error.contains("line 4") && error.contains("bee"), "{error}");

        let text = file.to_json().replace(&format!("{}", file.c), "-0.5");
        std::fs::write(&path, text).unwrap();
        let error = CalibrationFile::load(&path).unwrap_err().to_string();
        assert!(error.contains("field c = -0.5"), "{error}");

        let error = CalibrationFile::load(&dir.path().join("missing.json"))
            .unwrap_err()
            .to_string();
        assert!(error.contains("cannot read"), "{error}");
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]
        /// Whatever the data, the fitted law is valid and no worse than
        /// the best size law on the same data.
        #[test]
        fn the_fit_is_valid_and_never_worse_than_the_size_law(
            sigmas in proptest::collection::vec(0.01f64..3.0, 4..10)
        ) {
            let data: Vec<SigmaSample> = sigmas
                .iter()
                .enumerate()
                .map(|(i, &s)| SigmaSample { radius_px: 2.0 + 3.0 * i as f64, sigma_px: s, weight: 1.0 })
                .collect();
            let (law, quality) = fit(&data).unwrap();
            prop_assert!(CalibratedSigma::new(law.a, law.b, law.c).is_ok());
            prop_assert!(quality.rms_relative_residual <= quality.size_law_rms_relative_residual + 1e-9);
        }
    }
}
