//! `validate --images`: every visible scenario of a validation rendered
//! once and read back by `track` under seeded sensor noise
//! ([`super::images::check_pose`]), pooled into an [`ImageSummary`] beside
//! the point-noise figures.
//!
//! **Setup.** The part is the one whose supports validate's visibility
//! model counts: `export`'s part with validate's structure options, its
//! supports routed for validate's own scenarios
//! ([`crate::mesh::marker_for_range`]), rendered with the render
//! command's defaults ([`RenderConfig::new`]) through the validation's
//! camera; noise streams are seeded by the validation's seed, and the
//! frame index of a scenario is its grid index, so results do not depend
//! on the thread count. A pose the renderer refuses (behind the camera,
//! outside the image) is counted by reason.
//!
//! **Pooling.** A *sphere view* is one sphere of one scenario with at
//! least two labelled centres. Its bias is its mean centre error (a 2-D
//! vector, px) and its σ the per-axis RMS of the errors about that mean
//! (n − 1 degrees of freedom per axis). A bin pools the σ of its sphere
//! views as `sqrt(Σ spread / (2 Σ (n − 1)))` and gives the RMS length of
//! their biases. The centre tables keep to whole spheres (hidden by less
//! than [`WHOLE_SPHERE_HIDDEN`]); a partly hidden sphere whose bias exceeds
//! [`BIAS_SIGMAS`] times its own σ is listed as biased.
//!
//! **Pose.** The first-order prediction scales linearly with σ, so the
//! prediction at the measured σ is the prediction at the assumed σ (the
//! scenario's σ, exact for the isotropic noise model) times the ratio of
//! the scenario's measured σ (the whole spheres' σ pooled as above) to it.
//! RMS figures over scenarios are the root of the mean of the
//! per-scenario squares, over visible scenarios with an image pose and a
//! first-order prediction.

use super::config::Checked;
use super::images::{
    check_pose, sigma_samples, sphere_views, PoseImages, SphereView, WHOLE_SPHERE_HIDDEN,
};
use crate::config::ConfigError;
use crate::mesh::marker_for_range;
use crate::montecarlo::ScenarioOutcome;
use crate::noise::calibrated::{fit, CalibratedSigma, FitQuality, SigmaSample};
use crate::observer::{watch, Observer};
use crate::render::{RenderConfig, RenderError, Scene};
use crate::scenario::Scenario;
use crate::track::TrackConfig;
use crate::visibility::WorkingRange;
use serde::Serialize;
use std::collections::BTreeMap;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

/// Default noisy frames per scenario.
pub const DEFAULT_IMAGE_TRIALS: usize = 20;

/// A partly hidden sphere's bias beyond this many of its σ is listed.
pub const BIAS_SIGMAS: f64 = 3.0;

/// Width of the disc-radius bins of the centre table, px.
pub const RADIUS_BIN_PX: f64 = 4.0;

/// Width of the depth bins of the centre table, mm.
pub const DEPTH_BIN_MM: f64 = 200.0;

/// Most biased sphere views the summary lists (the count covers all).
pub const MAX_BIASED_LISTED: usize = 20;

/// Fewest distinct whole-sphere radii a noise law is fitted to.
pub const MIN_LAW_RADII: usize = 3;

/// Progress phase of the image check: one step per visible scenario.
pub const PHASE: &str = "images";

/// The image check's settings.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ImageCheck {
    /// Noisy frames read back per scenario.
    pub trials: usize,
}

impl Default for ImageCheck {
    fn default() -> Self {
        ImageCheck {
            trials: DEFAULT_IMAGE_TRIALS,
        }
    }
}

impl ImageCheck {
    /// Refuses a bad value, naming its field (`image_trials`).
    ///
    /// ```
    /// use layout_opt::validate::image_check::ImageCheck;
    /// assert!(ImageCheck::default().check().is_ok());
    /// assert_eq!(ImageCheck { trials: 0 }.check().unwrap_err().field, "image_trials");
    /// ```
    pub fn check(&self) -> Result<(), ConfigError> {
        if self.trials == 0 {
            return Err(ConfigError::new("image_trials", "must be at least 1"));
        }
        Ok(())
    }
}

/// Why the image check could not run.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ImageCheckError {
    /// A setting is unusable.
    #[error(transparent)]
    Config(#[from] ConfigError),
    /// The part cannot be built.
    #[error("the part cannot be built for the image check: {0}")]
    Part(#[from] crate::mesh::GeometryError),
    /// The renderer failed for a reason other than the pose.
    #[error("the image check cannot render: {0}")]
    Render(RenderError),
    /// An observer asked to stop.
    #[error("the image check was interrupted")]
    Interrupted,
}

/// Centre errors of the whole spheres in one bin.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CentreBin {
    /// The bin's lower edge (px or mm).
    pub from: f64,
    /// Its upper edge.
    pub to: f64,
    /// Sphere views in it.
    pub sphere_views: usize,
    /// Centres in it.
    pub centres: usize,
    /// RMS length of the sphere views' mean errors, px.
    pub bias_px: f64,
    /// Pooled per-axis σ about each view's mean, px.
    pub sigma_px: f64,
}

/// A partly hidden sphere whose centre the hidden part pulled.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct BiasedCentre {
    /// The scenario.
    pub scenario: Scenario,
    /// The sphere's name.
    pub sphere: String,
    /// Fraction of its silhouette hidden.
    pub hidden: f64,
    /// Disc radius, px.
    pub radius_px: f64,
    /// Length of its mean centre error, px.
    pub bias_px: f64,
    /// Its per-axis σ, px.
    pub sigma_px: f64,
}

/// Image-level pose errors beside the first-order prediction.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PoseComparison {
    /// Scenarios pooled.
    pub scenarios: usize,
    /// RMS of the assumed σ, px.
    pub assumed_sigma_px: f64,
    /// Measured σ of the whole spheres' centres, pooled over those
    /// scenarios, px.
    pub measured_sigma_px: f64,
    /// Rotation RMS from the images, degrees.
    pub image_rotation_rms_deg: f64,
    /// First-order rotation RMS at the assumed σ, degrees.
    pub predicted_rotation_rms_deg: f64,
    /// First-order rotation RMS at each scenario's measured σ, degrees.
    pub predicted_at_measured_rotation_rms_deg: f64,
    /// Translation RMS from the images, mm.
    pub image_translation_rms_mm: f64,
    /// First-order translation RMS at the assumed σ, mm.
    pub predicted_translation_rms_mm: f64,
    /// First-order translation RMS at each scenario's measured σ, mm.
    pub predicted_at_measured_translation_rms_mm: f64,
}

/// One scenario's image figures (a row of `images.csv`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ScenarioImages {
    /// The scenario's grid index (the frame index of its noise).
    pub scenario: usize,
    /// Depth, mm.
    pub depth_mm: f64,
    /// Tilt, degrees.
    pub tilt_deg: f64,
    /// Why the renderer refused the pose (None: rendered).
    pub refused: Option<String>,
    /// Frames read.
    pub frames: usize,
    /// Frames that gave a pose.
    pub posed: usize,
    /// Frames with a wrong label.
    pub mislabelled: usize,
    /// Frames in which a whole sphere got no blob.
    pub missing_a_whole_sphere: usize,
    /// Whole spheres measured.
    pub whole_spheres: usize,
    /// Smallest whole sphere's disc radius, px (NaN when none).
    pub min_radius_px: f64,
    /// Whole spheres' pooled centre σ, px (NaN when none).
    pub sigma_px: f64,
    /// Largest bias length of any sphere view, px (NaN when none).
    pub max_bias_px: f64,
    /// Rotation RMS of the posed frames, degrees (NaN when none).
    pub rotation_rms_deg: f64,
    /// Translation RMS of the posed frames, mm (NaN when none).
    pub translation_rms_mm: f64,
    /// First-order rotation RMS at the scenario's σ, degrees (NaN when
    /// none).
    pub predicted_rotation_rms_deg: f64,
}

/// The fitted noise law, or why none could be fitted.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub enum NoiseLaw {
    /// The law and how well it fits.
    Fitted {
        /// σ = a / r^b + c.
        law: CalibratedSigma,
        /// Its fit quality, with today's `size` law's.
        quality: FitQuality,
        /// Smallest and largest radius measured, px.
        radius_px: [f64; 2],
    },
    /// Too few whole-sphere radii, or a failed fit.
    Unfitted(String),
}

/// Everything the image check found.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ImageSummary {
    /// The settings.
    pub check: ImageCheck,
    /// The seed of the noise streams.
    pub seed: u64,
    /// The render preset, in words.
    pub preset: String,
    /// Visible scenarios tried.
    pub scenarios: usize,
    /// Poses the renderer refused, by reason.
    pub refused: BTreeMap<String, usize>,
    /// Frames read.
    pub frames: usize,
    /// Frames that gave a pose.
    pub posed_frames: usize,
    /// Frames lost (no pose), by the tracker's reason.
    pub lost: BTreeMap<String, usize>,
    /// Frames with a wrong label.
    pub mislabelled_frames: usize,
    /// Frames in which a whole sphere got no blob.
    pub frames_missing_a_whole_sphere: usize,
    /// Whole spheres' centres against disc radius.
    pub by_radius: Vec<CentreBin>,
    /// Whole spheres' centres against depth.
    pub by_depth: Vec<CentreBin>,
    /// Pose errors against the prediction.
    pub pose: Option<PoseComparison>,
    /// Partly hidden spheres biased beyond [`BIAS_SIGMAS`] σ: how many.
    pub biased_count: usize,
    /// The largest of them (at most [`MAX_BIASED_LISTED`]).
    pub biased: Vec<BiasedCentre>,
    /// The noise law fitted to the whole spheres.
    pub noise_law: NoiseLaw,
    /// Per scenario, in grid order (`images.csv`; not in `summary.json`).
    #[serde(skip)]
    pub per_scenario: Vec<ScenarioImages>,
}

/// Pooled σ of sphere views (module docs), NaN when none.
fn pooled_sigma<'a>(views: impl Iterator<Item = &'a SphereView>) -> f64 {
    let (spread, dof) = views.fold((0.0, 0.0), |(s, d), v| {
        (s + v.spread, d + 2.0 * (v.centres as f64 - 1.0))
    });
    if dof > 0.0 {
        (spread / dof).sqrt()
    } else {
        f64::NAN
    }
}

fn rms(values: impl Iterator<Item = f64>) -> f64 {
    let (sum, n) = values.fold((0.0, 0usize), |(s, n), v| (s + v * v, n + 1));
    if n == 0 {
        f64::NAN
    } else {
        (sum / n as f64).sqrt()
    }
}

/// [`run_until`] with progress as [`PHASE`] through `observer`, which may
/// ask to stop.
pub fn run(
    config: Checked,
    check: &ImageCheck,
    outcomes: &[ScenarioOutcome],
    observer: &mut impl Observer,
) -> Result<ImageSummary, ImageCheckError> {
    let done = AtomicU64::new(0);
    let stop = AtomicBool::new(false);
    let total = outcomes
        .iter()
        .filter(|o| o.visibility.is_visible())
        .count() as u64;
    watch(
        observer,
        PHASE,
        total,
        || done.load(Ordering::Relaxed),
        Some(&stop),
        || {
            run_until(
                config,
                check,
                outcomes,
                &|finished| done.store(finished as u64, Ordering::Relaxed),
                &stop,
            )
        },
    )
}

/// What one visible scenario gave.
struct Rendered {
    outcome_index: usize,
    images: Result<PoseImages, String>,
}

/// Renders and reads back every visible scenario of `outcomes` (module
/// docs), in parallel, calling `on_done` with the count finished; a set
/// `stop` ends it with [`ImageCheckError::Interrupted`].
pub fn run_until(
    config: Checked,
    check: &ImageCheck,
    outcomes: &[ScenarioOutcome],
    on_done: &(dyn Fn(usize) + Sync),
    stop: &AtomicBool,
) -> Result<ImageSummary, ImageCheckError> {
    use rayon::prelude::*;
    check.check()?;
    let layout = &config.layout;
    let names: Vec<String> = layout.points.iter().map(|p| p.name.clone()).collect();
    // The part whose supports validate's visibility model counts: routed
    // for validate's own scenarios, with its structure options (export's
    // defaults under --no-supports, which the model then ignores).
    let range = WorkingRange {
        camera: config.camera,
        scenarios: outcomes.iter().map(|o| o.scenario).collect(),
        max_hidden: config.max_hidden()?,
    };
    let options = config.structure.clone().unwrap_or_default();
    let scene = Scene::from_marker(marker_for_range(layout, &options, &range)?);
    let mut render = RenderConfig::new(config.camera);
    render.seed = config.monte_carlo.seed;
    let track = TrackConfig::new(layout, config.camera);
    track.validate().map_err(|e| {
        ConfigError::new(
            "images",
            format!("the tracker cannot read {}: {e}", layout.name),
        )
    })?;
    let chosen: Vec<usize> = (0..outcomes.len())
        .filter(|&i| outcomes[i].visibility.is_visible())
        .collect();
    let done = AtomicU64::new(0);
    let rendered: Vec<Rendered> = chosen
        .par_iter()
        .map(|&outcome_index| {
            if stop.load(Ordering::Relaxed) {
                return Err(ImageCheckError::Interrupted);
            }
            let scenario = &outcomes[outcome_index].scenario;
            let images = match check_pose(
                &scene,
                &names,
                &render,
                &track,
                &scenario.pose(),
                scenario.index as u64,
                check.trials,
            ) {
                Ok(images) => Ok(images),
                Err(error) => Err(refusal(error)?),
            };
            on_done(done.fetch_add(1, Ordering::Relaxed) as usize + 1);
            Ok(Rendered {
                outcome_index,
                images,
            })
        })
        .collect::<Result<_, _>>()?;
    Ok(summarise(config, check, outcomes, &names, &rendered))
}

/// A pose the renderer refuses, as a reason; any other render error as
/// an error.
fn refusal(error: RenderError) -> Result<String, ImageCheckError> {
    match error {
        RenderError::BehindCamera { .. } | RenderError::PartBehindCamera { .. } => {
            Ok("behind the camera".to_string())
        }
        RenderError::OutsideImage { .. } => Ok("outside the image".to_string()),
        other => Err(ImageCheckError::Render(other)),
    }
}

fn summarise(
    config: Checked,
    check: &ImageCheck,
    outcomes: &[ScenarioOutcome],
    names: &[String],
    rendered: &[Rendered],
) -> ImageSummary {
    let mut summary = ImageSummary {
        check: *check,
        seed: config.monte_carlo.seed,
        preset: "render defaults (retroreflective preset, default sensor and optics)".to_string(),
        scenarios: rendered.len(),
        refused: BTreeMap::new(),
        frames: 0,
        posed_frames: 0,
        lost: BTreeMap::new(),
        mislabelled_frames: 0,
        frames_missing_a_whole_sphere: 0,
        by_radius: Vec::new(),
        by_depth: Vec::new(),
        pose: None,
        biased_count: 0,
        biased: Vec::new(),
        noise_law: NoiseLaw::Unfitted(String::new()),
        per_scenario: Vec::new(),
    };
    // (radius, depth, view) of every whole sphere view.
    let mut whole: Vec<(f64, f64, SphereView)> = Vec::new();
    let mut samples: Vec<SigmaSample> = Vec::new();
    // (image rotation², predicted, ratio, image translation², predicted, assumed σ, measured σ)
    let mut pose_rows: Vec<[f64; 6]> = Vec::new();
    for item in rendered {
        let outcome = &outcomes[item.outcome_index];
        let scenario = &outcome.scenario;
        let predicted = outcome.first_order;
        let mut row = ScenarioImages {
            scenario: scenario.index,
            depth_mm: scenario.depth_mm,
            tilt_deg: scenario.tilt_deg,
            refused: None,
            frames: 0,
            posed: 0,
            mislabelled: 0,
            missing_a_whole_sphere: 0,
            whole_spheres: 0,
            min_radius_px: f64::NAN,
            sigma_px: f64::NAN,
            max_bias_px: f64::NAN,
            rotation_rms_deg: f64::NAN,
            translation_rms_mm: f64::NAN,
            predicted_rotation_rms_deg: predicted.map_or(f64::NAN, |p| p.rms_rotation_deg),
        };
        let images = match &item.images {
            Ok(images) => images,
            Err(reason) => {
                *summary.refused.entry(reason.clone()).or_default() += 1;
                row.refused = Some(reason.clone());
                summary.per_scenario.push(row);
                continue;
            }
        };
        summary.frames += images.trials;
        summary.posed_frames += images.rotation_error_deg.len();
        summary.mislabelled_frames += images.mislabelled_frames;
        summary.frames_missing_a_whole_sphere += images.frames_missing_a_whole_sphere;
        for (reason, count) in &images.lost {
            *summary.lost.entry(reason.clone()).or_default() += count;
        }
        let views = sphere_views(images);
        let whole_views: Vec<&SphereView> = views
            .iter()
            .filter(|v| v.hidden < WHOLE_SPHERE_HIDDEN)
            .collect();
        let scenario_sigma = pooled_sigma(whole_views.iter().copied());
        for view in &views {
            let sigma = view.sigma_px();
            if view.hidden >= WHOLE_SPHERE_HIDDEN && view.bias_px() > BIAS_SIGMAS * sigma {
                summary.biased.push(BiasedCentre {
                    scenario: *scenario,
                    sphere: names[view.sphere].clone(),
                    hidden: view.hidden,
                    radius_px: view.radius_px,
                    bias_px: view.bias_px(),
                    sigma_px: sigma,
                });
            }
        }
        row.frames = images.trials;
        row.posed = images.rotation_error_deg.len();
        row.mislabelled = images.mislabelled_frames;
        row.missing_a_whole_sphere = images.frames_missing_a_whole_sphere;
        row.whole_spheres = whole_views.len();
        row.min_radius_px = whole_views
            .iter()
            .map(|v| v.radius_px)
            .fold(f64::NAN, f64::min);
        row.sigma_px = scenario_sigma;
        row.max_bias_px = views
            .iter()
            .map(SphereView::bias_px)
            .fold(f64::NAN, f64::max);
        row.rotation_rms_deg = rms(images.rotation_error_deg.iter().copied());
        row.translation_rms_mm = rms(images.translation_error_mm.iter().copied());
        if let Some(predicted) = predicted {
            if row.posed > 0 && scenario_sigma.is_finite() && scenario.sigma_px > 0.0 {
                pose_rows.push([
                    row.rotation_rms_deg,
                    predicted.rms_rotation_deg,
                    row.translation_rms_mm,
                    predicted.rms_translation_mm,
                    scenario.sigma_px,
                    scenario_sigma,
                ]);
            }
        }
        samples.extend(sigma_samples(std::slice::from_ref(images)));
        summary.per_scenario.push(row);
        whole.extend(
            views
                .into_iter()
                .filter(|v| v.hidden < WHOLE_SPHERE_HIDDEN)
                .map(|v| (v.radius_px, scenario.depth_mm, v)),
        );
    }
    summary.biased_count = summary.biased.len();
    summary.biased.sort_by(|a, b| {
        b.bias_px
            .total_cmp(&a.bias_px)
            .then(a.scenario.index.cmp(&b.scenario.index))
    });
    summary.biased.truncate(MAX_BIASED_LISTED);
    summary.by_radius = bins(&whole, RADIUS_BIN_PX, |(radius, _, _)| *radius);
    summary.by_depth = bins(&whole, DEPTH_BIN_MM, |(_, depth, _)| *depth);
    summary.pose = pose_comparison(&pose_rows, &whole);
    summary.noise_law = noise_law(&samples);
    summary
}

/// Sphere views binned by `key` in bins `width` wide, lowest first.
fn bins(
    views: &[(f64, f64, SphereView)],
    width: f64,
    key: impl Fn(&(f64, f64, SphereView)) -> f64,
) -> Vec<CentreBin> {
    let mut by_bin: BTreeMap<i64, Vec<&SphereView>> = BTreeMap::new();
    for item in views {
        by_bin
            .entry((key(item) / width).floor() as i64)
            .or_default()
            .push(&item.2);
    }
    by_bin
        .into_iter()
        .map(|(bin, members)| CentreBin {
            from: bin as f64 * width,
            to: (bin + 1) as f64 * width,
            sphere_views: members.len(),
            centres: members.iter().map(|v| v.centres).sum(),
            bias_px: rms(members.iter().map(|v| v.bias_px())),
            sigma_px: pooled_sigma(members.iter().copied()),
        })
        .collect()
}

/// The pooled pose comparison (module docs), None without scenarios.
fn pose_comparison(rows: &[[f64; 6]], whole: &[(f64, f64, SphereView)]) -> Option<PoseComparison> {
    if rows.is_empty() {
        return None;
    }
    let pooled = |f: &dyn Fn(&[f64; 6]) -> f64| rms(rows.iter().map(f));
    Some(PoseComparison {
        scenarios: rows.len(),
        assumed_sigma_px: pooled(&|r| r[4]),
        measured_sigma_px: pooled_sigma(whole.iter().map(|(_, _, v)| v)),
        image_rotation_rms_deg: pooled(&|r| r[0]),
        predicted_rotation_rms_deg: pooled(&|r| r[1]),
        predicted_at_measured_rotation_rms_deg: pooled(&|r| r[1] * r[5] / r[4]),
        image_translation_rms_mm: pooled(&|r| r[2]),
        predicted_translation_rms_mm: pooled(&|r| r[3]),
        predicted_at_measured_translation_rms_mm: pooled(&|r| r[3] * r[5] / r[4]),
    })
}

/// The law fitted to `samples`, refused below [`MIN_LAW_RADII`] distinct
/// radii.
fn noise_law(samples: &[SigmaSample]) -> NoiseLaw {
    let mut radii: Vec<f64> = samples.iter().map(|s| s.radius_px).collect();
    radii.sort_by(f64::total_cmp);
    radii.dedup_by(|a, b| (*a - *b).abs() <= 1e-9 * b.abs());
    if radii.len() < MIN_LAW_RADII {
        return NoiseLaw::Unfitted(format!(
            "{} distinct whole-sphere radii measured, at least {MIN_LAW_RADII} needed",
            radii.len()
        ));
    }
    match fit(samples) {
        Ok((law, quality)) => NoiseLaw::Fitted {
            law,
            quality,
            radius_px: [radii[0], radii[radii.len() - 1]],
        },
        Err(error) => NoiseLaw::Unfitted(error.to_string()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn view(sphere: usize, errors: &[[f64; 2]]) -> SphereView {
        let images = PoseImages {
            frame: 0,
            trials: errors.len(),
            radius_px: vec![10.0; sphere + 1],
            hidden: vec![0.0; sphere + 1],
            centres: errors
                .iter()
                .map(|&error_px| super::super::images::CentreError { sphere, error_px })
                .collect(),
            rotation_error_deg: vec![],
            translation_error_mm: vec![],
            mislabelled_frames: 0,
            frames_missing_a_whole_sphere: 0,
            lost: BTreeMap::new(),
        };
        sphere_views(&images).pop().unwrap()
    }

    #[test]
    fn a_view_gives_its_mean_as_bias_and_its_per_axis_spread_as_sigma() {
        let v = view(1, &[[1.0, 2.0], [3.0, 2.0], [2.0, 1.0], [2.0, 3.0]]);
        assert_eq!(v.mean, [2.0, 2.0]);
        assert!((v.bias_px() - 8f64.sqrt()).abs() < 1e-12);
        // Spread 4 over 2 × 3 degrees of freedom.
        assert!((v.sigma_px() - (4.0f64 / 6.0).sqrt()).abs() < 1e-12);
        assert!((pooled_sigma([&v, &v].into_iter()) - v.sigma_px()).abs() < 1e-12);
    }

    #[test]
    fn a_law_needs_three_radii_and_zero_trials_are_refused() {
        let sample = |radius_px| SigmaSample {
            radius_px,
            sigma_px: 0.1 / radius_px + 0.01,
            weight: 1.0,
        };
        let two = [sample(5.0), sample(5.0), sample(10.0)];
        assert!(matches!(noise_law(&two), NoiseLaw::Unfitted(m) if m.starts_with("2 distinct")),);
        let three = [sample(5.0), sample(10.0), sample(20.0), sample(30.0)];
        assert!(matches!(noise_law(&three), NoiseLaw::Fitted { .. }));
        assert_eq!(
            ImageCheck { trials: 0 }.check().unwrap_err().field,
            "image_trials"
        );
        assert_eq!(ImageCheck::default().trials, DEFAULT_IMAGE_TRIALS);
    }
}
