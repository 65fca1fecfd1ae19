//! Identifiability: how often one image of a layout, its blobs unlabelled,
//! is given the wrong labels by the unlabelled solver
//! ([`crate::pnp::unlabelled::identify`]), predicted from the noise-free
//! ambiguity margin and measured by Monte-Carlo.
//!
//! # Prediction (docs/formats.md, "Identifiability")
//! On a scenario's noise-free observations the correct labelling fits
//! exactly; the best *wrong* labelling that is geometrically consistent
//! leaves a residual vector `r` (2n pixel coordinates, its pose fitted by
//! least squares), `‖r‖` the **margin**. With pixel noise `e`
//! (covariance `Σ`), fitting both labellings to first order leaves the
//! residuals `(I − P₁) e` and `r + (I − P₂) e`, where `P₁`, `P₂` are the
//! orthogonal projectors onto the two fits' 6-column reprojection
//! Jacobians (`(I − P₂) r = r` since `r` is a least-squares residual). The
//! wrong labelling wins when its cost is lower:
//!
//! `D = ‖r‖² + 2 rᵀe + eᵀ(P₁ − P₂)e < 0`.
//!
//! `D` has mean `‖r‖² + tr((P₁ − P₂)Σ)` (the trace is 0 for i.i.d. noise:
//! both projectors have rank 6) and variance `4 rᵀΣr + 2 tr(((P₁ − P₂)Σ)²)`
//! (the linear and quadratic parts of a Gaussian are uncorrelated). Taking
//! `D` as Gaussian:
//!
//! `P(wrong) ≈ Φ(−E[D] / √Var[D])`,
//!
//! which for i.i.d. σ and a margin large beside σ is the textbook
//! `Φ(−‖r‖ / 2σ)`; the quadratic term matters where the margin is a few σ
//! and the two fits' Jacobians differ. Only the best wrong labelling is
//! counted (the next ones add at most their own, smaller, probabilities). A
//! symmetric view, where a wrong labelling fits exactly (`r = 0`, equal
//! projectors), gives `P(wrong) = ½`: the solver cannot tell the twins
//! apart. A view where no wrong labelling fits within the search gate
//! ([`IdentifiabilitySettings::gate_px`]) has a margin above the gate, and
//! its probability is bounded by that of the gate.
//!
//! # Monte-Carlo
//! Trial `k` of scenario `s` adds the Monte-Carlo engine's own noise draw
//! (`stream_rng(seed, s, k)`, the same draws as `validate`'s solvers),
//! shuffles the blobs with a second seeded stream, runs `identify` and
//! counts a trial as wrong when any label differs from the truth or no
//! labelling is found. A wrong labelling that fits the blobs worse than the
//! true one (refitted) is also counted as *missed*: the solver's search lost
//! the truth, which no margin predicts; the rest, wrong labellings that fit
//! better, are what the prediction models. Results do not depend on the
//! thread count.

use crate::camera::Camera;
use crate::error_model::first_order::pixel_jacobian;
use crate::montecarlo::{point_sigmas, Target};
use crate::noise::NoiseModel;
use crate::pnp::ml;
use crate::pnp::unlabelled::{identify, Labelling, LabellingError, UnlabelledOptions};
use crate::pose::Pose;
use crate::scenario::{sphere_images, visibility, Scenario};
use crate::sphere_image::Observation;
use crate::synthetic::stream_rng;
use nalgebra::{DMatrix, DVector, Vector2, Vector3};
use rand::seq::SliceRandom;
use rayon::prelude::*;
use serde::Serialize;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

/// Default share of correct labellings a scenario must reach to count as
/// identifiable (a predicted wrong-label probability of at most 1e-3).
pub const DEFAULT_MIN_CORRECT: f64 = 0.999;
/// Per-point gate of the Monte-Carlo trials, in σ of the noisiest point: a
/// correct labelling's point leaves it with probability `exp(−g²/2)`
/// (1.5e-8 for 6σ), so the gate does not reject the truth.
pub const TRIAL_GATE_SIGMAS: f64 = 6.0;
/// Smallest per-point gate of the trials, px (for σ near zero).
pub const MIN_TRIAL_GATE_PX: f64 = 0.5;
/// Gate of the noise-free margin search, in σ: a wrong labelling whose
/// residual norm exceeds `2 · 7.03 σ` wins with probability below 1e-12, so
/// 15σ finds every labelling that matters.
pub const PREDICTION_GATE_SIGMAS: f64 = 15.0;
/// Margins below this are symmetric twins, px: a wrong labelling fits the
/// noise-free image to within the ellipse-centre displacement's asymmetry
/// (thousandths of a pixel for the paper's biprism).
pub const TWIN_MARGIN_PX: f64 = 0.01;
/// Random stream (offset) of the trials' blob shuffles, apart from the
/// noise streams.
pub const SHUFFLE_STREAM: u64 = 0x1D_0000_0000;

/// How identifiability is predicted and measured.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct IdentifiabilitySettings {
    /// A scenario is identifiable when its predicted share of correct
    /// labellings reaches this (default 0.999).
    pub min_correct: f64,
    /// Monte-Carlo trials per visible scenario (0: prediction only).
    pub trials: usize,
    /// Seed of the noise and shuffle streams.
    pub seed: u64,
    /// What a sphere's image point is.
    pub observation: Observation,
    /// The noise model (outliers included in the trials; the prediction
    /// uses the Gaussian part).
    pub noise: NoiseModel,
}

impl IdentifiabilitySettings {
    /// Largest predicted wrong-label probability of an identifiable scenario.
    pub fn max_wrong(&self) -> f64 {
        1.0 - self.min_correct
    }
}

/// The standard normal upper tail `Q(x) = 1 − Φ(x) = erfc(x/√2)/2`,
/// accurate to a relative 1.2e-7 over the whole line (the Chebyshev fit of
/// `erfc` in Press et al., *Numerical Recipes*, §6.2).
pub fn normal_upper_tail(x: f64) -> f64 {
    let z = x.abs() / std::f64::consts::SQRT_2;
    let t = 1.0 / (1.0 + 0.5 * z);
    let poly = -z * z - 1.265_512_23
        + t * (1.000_023_68
            + t * (0.374_091_96
                + t * (0.096_784_18
                    + t * (-0.186_288_06
                        + t * (0.278_868_07
                            + t * (-1.135_203_98
                                + t * (1.488_515_87 + t * (-0.822_152_23 + t * 0.170_872_77))))))));
    let erfc = t * poly.exp();
    if x >= 0.0 {
        0.5 * erfc
    } else {
        1.0 - 0.5 * erfc
    }
}

/// The `x` with `Q(x) = p`, for `p` in (0, 1) (bisection on
/// [`normal_upper_tail`], to 1e-12).
pub fn normal_upper_quantile(p: f64) -> f64 {
    let (mut lo, mut hi) = (-40.0, 40.0);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if normal_upper_tail(mid) > p {
            lo = mid;
        } else {
            hi = mid;
        }
        if hi - lo < 1e-12 {
            break;
        }
    }
    0.5 * (lo + hi)
}

/// The margin (px) at which i.i.d. noise σ gives a wrong-label probability
/// of `max_wrong` to first order: `2σ · Q⁻¹(max_wrong)` (3.09 px at σ =
/// 0.5 px and 1e-3).
pub fn required_margin_px(sigma_px: f64, max_wrong: f64) -> f64 {
    2.0 * sigma_px * normal_upper_quantile(max_wrong)
}

/// The best wrong labelling of a noise-free view and what it predicts.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Prediction {
    /// `‖r‖`, the residual norm of the best wrong consistent labelling over
    /// every blob, px (`√n ×` its RMS); None when no wrong labelling fits
    /// within the gate, so the margin exceeds `gate_px`.
    pub margin_px: Option<f64>,
    /// The gate of the search, px: the margin is at least this when
    /// `margin_px` is None.
    pub gate_px: f64,
    /// Predicted probability that `identify` picks a wrong labelling (for
    /// a margin above the gate, the probability at the gate: an upper
    /// bound).
    pub wrong_probability: f64,
    /// The wrong labelling (for each blob, its object point), if any.
    pub runner_up: Option<Vec<usize>>,
}

/// Why a prediction could not be made.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum IdentifiabilityError {
    /// The unlabelled solver refused the view.
    #[error("the unlabelled solver failed on the noise-free view: {0}")]
    Solver(#[from] LabellingError),
    /// A noise σ is not positive.
    #[error("identifiability needs a positive noise σ at every point, got {0} px")]
    Noise(f64),
    /// Noise-free observations could not be made (a sphere not in front).
    #[error("the view has a sphere that is not in front of the camera")]
    NotInFront,
}

/// Predicts the wrong-label probability of the noise-free view `observed`
/// (normalised image points, in object order) of `object` at pose `truth`,
/// with per-point noise `sigmas_px` (module docs). `gate_px` bounds the
/// search for wrong labellings.
pub fn predict(
    camera: &Camera,
    truth: &Pose,
    object: &[Vector3<f64>],
    observed: &[Vector2<f64>],
    sigmas_px: &[f64],
    gate_px: f64,
) -> Result<Prediction, IdentifiabilityError> {
    if let Some(&bad) = sigmas_px.iter().find(|s| !(**s > 0.0 && s.is_finite())) {
        return Err(IdentifiabilityError::Noise(bad));
    }
    let focal = camera.fx().min(camera.fy());
    let options = UnlabelledOptions {
        gate: gate_px / focal,
        max_missing: 0,
    };
    let identification = identify(object, observed, &options)?;
    let truth_labels: Vec<usize> = (0..object.len()).collect();
    let wrong: Option<&Labelling> = if identification.best.labels != truth_labels {
        Some(&identification.best)
    } else {
        identification.runner_up.as_ref()
    };
    let Some(wrong) = wrong else {
        let sigma = sigmas_px.iter().copied().fold(0.0, f64::max);
        return Ok(Prediction {
            margin_px: None,
            gate_px,
            wrong_probability: normal_upper_tail(gate_px / (2.0 * sigma)),
            runner_up: None,
        });
    };
    let assigned: Vec<Vector3<f64>> = wrong.labels.iter().map(|&l| object[l]).collect();
    let pose = ml::refine(&wrong.pose, &assigned, observed);
    let (margin_px, wrong_probability) =
        wrong_probability(camera, truth, &pose, object, &assigned, observed, sigmas_px);
    Ok(Prediction {
        margin_px: Some(margin_px),
        gate_px,
        wrong_probability,
        runner_up: Some(wrong.labels.clone()),
    })
}

/// The margin (px) and predicted wrong-label probability of one wrong
/// labelling: `assigned[j]` is the object point it gives blob `j`, fitted
/// at `pose`; the truth gives blob `j` `object[j]` at `truth`. The wrong
/// points may come from another marker ([`crate::set`]'s cross margin).
pub fn wrong_probability(
    camera: &Camera,
    truth: &Pose,
    pose: &Pose,
    object: &[Vector3<f64>],
    assigned: &[Vector3<f64>],
    observed: &[Vector2<f64>],
    sigmas_px: &[f64],
) -> (f64, f64) {
    let n = object.len();
    let rows = 2 * n;
    let (fx, fy) = (camera.fx(), camera.fy());
    let mut residual = DVector::zeros(rows);
    for (j, (p, m)) in assigned.iter().zip(observed).enumerate() {
        let d = pose.project_normalised(p) - m;
        residual[2 * j] = fx * d.x;
        residual[2 * j + 1] = fy * d.y;
    }
    let basis = |pose: &Pose, points: &[Vector3<f64>]| -> DMatrix<f64> {
        let mut jacobian = DMatrix::zeros(rows, 6);
        for (j, p) in points.iter().enumerate() {
            let block = pixel_jacobian(camera, pose, p);
            jacobian.view_mut((2 * j, 0), (2, 6)).copy_from(&block);
        }
        jacobian.qr().q()
    };
    let q_true = basis(truth, object);
    let q_wrong = basis(pose, assigned);
    // The residual orthogonal to the wrong fit (it is, to the fit's
    // tolerance; projecting makes the first-order model exact).
    let residual = &residual - &q_wrong * (q_wrong.transpose() * &residual);
    let margin_px = residual.norm();
    let difference = &q_true * q_true.transpose() - &q_wrong * q_wrong.transpose();
    let variance: Vec<f64> = (0..rows).map(|i| sigmas_px[i / 2].powi(2)).collect();
    let mean_shift: f64 = (0..rows).map(|i| difference[(i, i)] * variance[i]).sum();
    let mut quadratic = 0.0;
    for i in 0..rows {
        for k in 0..rows {
            quadratic += difference[(i, k)].powi(2) * variance[i] * variance[k];
        }
    }
    let linear: f64 = (0..rows).map(|i| residual[i].powi(2) * variance[i]).sum();
    let mean = margin_px * margin_px + mean_shift;
    let spread = (4.0 * linear + 2.0 * quadratic).sqrt();
    let probability = if spread > 0.0 {
        normal_upper_tail(mean / spread)
    } else if mean > 0.0 {
        0.0
    } else {
        // A wrong labelling that fits exactly and sees the noise exactly as
        // the truth does: a coin toss between twins.
        0.5
    };
    (margin_px, probability)
}

/// Wrong labellings counted over seeded noisy trials of one view.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct TrialCounts {
    /// Trials run.
    pub trials: usize,
    /// Trials whose labels differed from the truth.
    pub wrong: usize,
    /// Trials in which no labelling was found (counted as wrong too).
    pub failed: usize,
    /// Wrong trials whose chosen labelling fits the blobs *worse* than the
    /// true labelling does (its pose refitted from the truth): the solver's
    /// search missed the truth, which no margin explains (counted in
    /// `wrong` too).
    pub missed: usize,
}

impl TrialCounts {
    /// The share of wrong (or failed) trials.
    pub fn wrong_rate(&self) -> Option<f64> {
        (self.trials > 0).then(|| self.wrong as f64 / self.trials as f64)
    }

    /// The share of trials in which a wrong labelling won because it fits
    /// better than the truth: what the prediction models.
    pub fn ambiguous_rate(&self) -> Option<f64> {
        (self.trials > 0)
            .then(|| (self.wrong - self.failed - self.missed) as f64 / self.trials as f64)
    }
}

/// Identifiability of one scenario.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ScenarioIdentifiability {
    /// Grid index of the scenario.
    pub scenario: usize,
    /// The noise-free prediction (None where it could not be made, with
    /// `error` saying why).
    pub prediction: Option<Prediction>,
    /// Why no prediction was made.
    pub error: Option<String>,
    /// The Monte-Carlo counts (zero trials when none were asked for).
    pub trials: TrialCounts,
}

impl ScenarioIdentifiability {
    /// Whether the prediction says the scenario is identifiable.
    pub fn identifiable(&self, settings: &IdentifiabilitySettings) -> bool {
        self.prediction
            .as_ref()
            .is_some_and(|p| p.wrong_probability <= settings.max_wrong())
    }
}

/// Noise-free observations (px, normalised) and per-point σ (px).
pub(crate) type CleanView = (Vec<Vector2<f64>>, Vec<Vector2<f64>>, Vec<f64>);

/// The trials' noise-free observations of `target` in `scenario`, px and
/// normalised, with the per-point σ; None when a sphere is not in front.
pub(crate) fn clean_view(
    target: &Target,
    scenario: &Scenario,
    observation: Observation,
    noise: &NoiseModel,
) -> Option<CleanView> {
    let truth = scenario.pose();
    let images = sphere_images(
        target.camera,
        &truth,
        target.object,
        target.sphere_diameter_mm,
    );
    if !visibility(&images, target.camera).all_in_front() {
        return None;
    }
    let radius_mm = 0.5 * target.sphere_diameter_mm;
    let mut pixels = Vec::with_capacity(target.object.len());
    let mut normalised = Vec::with_capacity(target.object.len());
    for p in target.object {
        let m = observation
            .normalised(&truth.transform(p), radius_mm)
            .ok()?;
        let pixel = target.camera.normalised_to_pixel(&m);
        pixels.push(pixel);
        // Round trip through the camera, as the trials do.
        normalised.push(target.camera.pixel_to_normalised(&pixel).ok()?);
    }
    let sigmas = point_sigmas(noise, scenario.sigma_px, &images, target.point_sigma_px);
    Some((pixels, normalised, sigmas))
}

/// Predicts (and, with trials, measures) the identifiability of `target`
/// in one scenario. A scenario with a sphere behind the camera gets an
/// error and no trials.
pub fn scenario(
    target: &Target,
    scenario: &Scenario,
    settings: &IdentifiabilitySettings,
    stop: &AtomicBool,
) -> ScenarioIdentifiability {
    let mut result = ScenarioIdentifiability {
        scenario: scenario.index,
        prediction: None,
        error: None,
        trials: TrialCounts::default(),
    };
    let Some((pixels, normalised, sigmas)) =
        clean_view(target, scenario, settings.observation, &settings.noise)
    else {
        result.error = Some(IdentifiabilityError::NotInFront.to_string());
        return result;
    };
    let sigma = sigmas.iter().copied().fold(0.0, f64::max);
    match predict(
        target.camera,
        &scenario.pose(),
        target.object,
        &normalised,
        &sigmas,
        PREDICTION_GATE_SIGMAS * sigma,
    ) {
        Ok(prediction) => result.prediction = Some(prediction),
        Err(error) => result.error = Some(error.to_string()),
    }
    if settings.trials == 0 || sigma <= 0.0 || sigma.is_nan() {
        return result;
    }
    let camera = target.camera;
    let focal = camera.fx().min(camera.fy());
    let options = UnlabelledOptions {
        gate: (TRIAL_GATE_SIGMAS * sigma).max(MIN_TRIAL_GATE_PX) / focal,
        max_missing: 0,
    };
    let n = pixels.len();
    let mut order: Vec<usize> = (0..n).collect();
    let mut noisy = vec![Vector2::zeros(); n];
    let mut shuffled = vec![Vector2::zeros(); n];
    let mut assigned = vec![Vector3::zeros(); n];
    let truth = scenario.pose();
    for trial in 0..settings.trials {
        if stop.load(Ordering::Relaxed) {
            break;
        }
        let mut rng = stream_rng(settings.seed, scenario.index as u64, trial as u64);
        let mut usable = true;
        for ((pixel, sigma), slot) in pixels.iter().zip(&sigmas).zip(noisy.iter_mut()) {
            let [dx, dy] = settings.noise.draw(&mut rng, *sigma);
            match camera.pixel_to_normalised(&Vector2::new(pixel.x + dx, pixel.y + dy)) {
                Ok(m) => *slot = m,
                Err(_) => usable = false,
            }
        }
        result.trials.trials += 1;
        if !usable {
            result.trials.wrong += 1;
            result.trials.failed += 1;
            continue;
        }
        let mut shuffle = stream_rng(
            settings.seed,
            SHUFFLE_STREAM + scenario.index as u64,
            trial as u64,
        );
        order.shuffle(&mut shuffle);
        for (slot, &k) in shuffled.iter_mut().zip(&order) {
            *slot = noisy[k];
        }
        match identify(target.object, &shuffled, &options) {
            Ok(found) => {
                if found.best.labels.iter().zip(&order).any(|(l, k)| l != k) {
                    result.trials.wrong += 1;
                    for (slot, &k) in assigned.iter_mut().zip(&order) {
                        *slot = target.object[k];
                    }
                    let refit = ml::refine(&truth, &assigned, &shuffled);
                    let true_rms = (assigned
                        .iter()
                        .zip(&shuffled)
                        .map(|(p, m)| (refit.project_normalised(p) - m).norm_squared())
                        .sum::<f64>()
                        / n as f64)
                        .sqrt();
                    if found.best.rms > true_rms * (1.0 + 1e-9) {
                        result.trials.missed += 1;
                    }
                }
            }
            Err(_) => {
                result.trials.wrong += 1;
                result.trials.failed += 1;
            }
        }
    }
    result
}

/// [`scenario`] over every scenario, in parallel, in grid order;
/// `on_scenario_done` hears the count finished so far. None when `stop`
/// ended the run.
pub fn run_until(
    target: &Target,
    scenarios: &[Scenario],
    settings: &IdentifiabilitySettings,
    only: &(dyn Fn(&Scenario) -> bool + Sync),
    on_scenario_done: &(dyn Fn(usize) + Sync),
    stop: &AtomicBool,
) -> Option<Vec<Option<ScenarioIdentifiability>>> {
    let done = AtomicUsize::new(0);
    scenarios
        .par_iter()
        .map(|s| {
            if stop.load(Ordering::Relaxed) {
                return None;
            }
            let result = only(s).then(|| scenario(target, s, settings, stop));
            if stop.load(Ordering::Relaxed) {
                return None;
            }
            on_scenario_done(done.fetch_add(1, Ordering::Relaxed) + 1);
            Some(result)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_normal_tail_matches_known_values() {
        for (x, q) in [
            (0.0, 0.5),
            (1.0, 0.158_655_253_931_457_05),
            (3.090_232_306_167_813_5, 1e-3),
            (-2.0, 0.977_249_868_051_820_8),
            (6.0, 9.865_876_450_376_946e-10),
        ] {
            let got = normal_upper_tail(x);
            assert!((got / q - 1.0).abs() < 2e-7, "Q({x}) = {got}, not {q}");
        }
        assert!((normal_upper_quantile(1e-3) - 3.090_232_306).abs() < 1e-6);
        assert!((required_margin_px(0.5, 1e-3) - 3.090_232_306).abs() < 1e-6);
    }
}
