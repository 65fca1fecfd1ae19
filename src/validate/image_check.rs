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
//! **Pose.** The first-order prediction at the assumed σ is the
//! Monte-Carlo run's (the noise model's σ per sphere, every sphere in
//! front). The prediction at the measured σ is the first-order covariance
//! of the pose the tracker solved: the spheres its pose used in at least
//! half of the scenario's posed frames, each at its own measured σ (its
//! view's, above), whatever the noise model; beside it, the same with the
//! first-order pose bias that those spheres' mean centre errors cause
//! (`(Jᵀ W J)⁻¹ Jᵀ W b`) added in quadrature. The assumed σ shown is the
//! RMS over the spheres of the noise model's σ at their disc radii.
//! RMS figures over scenarios are the root of the mean of the
//! per-scenario squares, over visible scenarios with an image pose and a
//! first-order prediction.

use super::config::Checked;
use super::images::{
    check_pose, independent_views, sample_frame, sigma_samples, sphere_views, PoseImages, Reader,
    SphereView, WHOLE_SPHERE_HIDDEN,
};
use crate::camera::Camera;
use crate::config::ConfigError;
use crate::mesh::marker_for_range;
use crate::montecarlo::ScenarioOutcome;
use crate::noise::calibrated::{fit, CalibratedSigma, CentreErrorMeasure, FitQuality, SigmaSample};
use crate::observer::{watch, Observer};
use crate::pose::{rotation_error_deg, translation_error_mm};
use crate::render::config::MAX_SUPERSAMPLING;
use crate::render::{Appearance, Blur, Lighting, Noise, RenderConfig, RenderError, Scene};
use crate::scenario::Scenario;
use crate::track::refine::{Refiner, DEFAULT_SUPERSAMPLING, MAX_ROUNDS};
use crate::track::{CentreMethod, FrameAnalysis, GreyFrame, Threshold, TrackConfig};
use crate::visibility::WorkingRange;
use nalgebra::Vector3;
use serde::Serialize;
use std::collections::BTreeMap;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

/// Default noisy frames per scenario.
pub const DEFAULT_IMAGE_TRIALS: usize = 20;
/// Largest lens blur σ the image check takes, px: beyond it a 4 px disc
/// (a 10 mm sphere at 1.6 m) is smeared past recognition.
pub const MAX_BLUR_SIGMA_PX: f64 = 5.0;

/// A partly hidden sphere's bias beyond this many of its σ is listed.
pub const BIAS_SIGMAS: f64 = 3.0;

/// Width of the disc-radius bins of the centre table, px.
pub const RADIUS_BIN_PX: f64 = 4.0;

/// Width of the depth bins of the centre table, mm.
pub const DEPTH_BIN_MM: f64 = 200.0;

/// Most biased sphere views the summary lists (the count covers all).
pub const MAX_BIASED_LISTED: usize = 20;

/// Width of the disc-radius bins whose RMS centre error about the truth the
/// law is fitted to, px. Each view's bias is its own, so single views
/// scatter about the law by half their value; the law has to give the RMS
/// at a radius (what the first-order model turns into a pose's RMS), and
/// a fit to relative residuals of single views would fall below it.
pub const LAW_BIN_PX: f64 = 1.0;

/// Fewest distinct radii (or radius bins) a noise law is fitted to.
pub const MIN_LAW_RADII: usize = 3;

/// Progress phase of the image check: one step per visible scenario.
pub const PHASE: &str = "images";

/// The camera and lighting the image check renders with: the settings of
/// `render` that a noise calibration stands for.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum ImagePreset {
    /// The paper's camera (validate's camera, by default the paper's
    /// 1280×720, f 1301 px) with `render`'s defaults: retroreflective
    /// spheres under a ring light, 4×4 supersampling, σ 0.5 px blur,
    /// 8 bit, full well 10,000 e⁻, read noise 10 e⁻.
    #[default]
    Paper,
    /// A typical machine-vision camera ([`machine_vision_camera`]: a
    /// 1440×1080 global-shutter sensor of 3.45 µm pixels behind a 6 mm
    /// lens, f 1739 px) with a ring light and retroreflective spheres:
    /// full well 10,500 e⁻, read noise 2.2 e⁻, 8 bit, σ 0.5 px blur.
    MachineVision,
    /// A diffuse white print under room light: validate's camera, `render`'s
    /// `diffuse` lighting preset (a lamp 30° off the axis and 15% ambient
    /// light, white spheres, grey supports), the default sensor and blur,
    /// and the tracker at a fixed threshold ([`DIFFUSE_THRESHOLD`]).
    Diffuse,
}

/// The diffuse preset's fixed tracker threshold, fraction of full scale:
/// above `render`'s diffuse supports facing the light (0.5), below its lit
/// spheres (0.85).
pub const DIFFUSE_THRESHOLD: f64 = 0.55;

/// The machine-vision preset's camera: 1440×1080, 3.45 µm pixels, 6 mm
/// lens (f = 6 / 0.00345 = 1739.1 px), principal point at the centre, no
/// distortion.
pub fn machine_vision_camera() -> Camera {
    Camera::new(1739.1, 1739.1, 720.0, 540.0, 1440, 1080, [0.0; 5])
        .expect("the preset's camera is valid")
}

impl ImagePreset {
    /// Every preset, in CLI order.
    pub const ALL: [ImagePreset; 3] = [
        ImagePreset::Paper,
        ImagePreset::MachineVision,
        ImagePreset::Diffuse,
    ];

    /// Its CLI name.
    pub fn name(self) -> &'static str {
        match self {
            ImagePreset::Paper => "paper",
            ImagePreset::MachineVision => "machine-vision",
            ImagePreset::Diffuse => "diffuse",
        }
    }

    /// The camera the preset brings (None: validate's own).
    pub fn camera(self) -> Option<Camera> {
        match self {
            ImagePreset::MachineVision => Some(machine_vision_camera()),
            ImagePreset::Paper | ImagePreset::Diffuse => None,
        }
    }

    /// The render settings for `camera`, noise seeded by `seed`.
    pub fn render(self, camera: Camera, seed: u64) -> RenderConfig {
        let mut render = RenderConfig::new(camera);
        render.seed = seed;
        match self {
            ImagePreset::Paper => {}
            ImagePreset::MachineVision => {
                render.sensor.noise = Some(Noise {
                    full_well_electrons: 10_500.0,
                    read_noise_electrons: 2.2,
                });
            }
            ImagePreset::Diffuse => {
                render.appearance = Appearance::preset(Lighting::Diffuse);
            }
        }
        render
    }

    /// The tracker's threshold for the preset: Otsu's for bright discs on
    /// a dark part; for the diffuse print, whose grey supports Otsu's level
    /// joins to the spheres, a fixed level above the lit supports.
    pub fn threshold(self) -> Threshold {
        match self {
            ImagePreset::Paper | ImagePreset::MachineVision => Threshold::Otsu,
            ImagePreset::Diffuse => Threshold::Fixed(DIFFUSE_THRESHOLD),
        }
    }

    /// The preset in words, for the report.
    pub fn describe(self) -> String {
        let what = match self {
            ImagePreset::Paper => "retroreflective spheres under a ring light, render's default sensor and blur",
            ImagePreset::MachineVision => "1440×1080 machine-vision camera (f 1739 px), ring light and retroreflective spheres, full well 10,500 e⁻, read noise 2.2 e⁻",
            ImagePreset::Diffuse => "diffuse white print under room light (render's diffuse lighting), render's default sensor and blur, tracker threshold fixed at 0.55",
        };
        format!("preset {}: {what}", self.name())
    }
}

impl std::str::FromStr for ImagePreset {
    type Err = ConfigError;
    fn from_str(text: &str) -> Result<Self, ConfigError> {
        ImagePreset::ALL
            .into_iter()
            .find(|p| p.name().eq_ignore_ascii_case(text.trim()))
            .ok_or_else(|| {
                ConfigError::new(
                    "image_preset",
                    format!("unknown preset \"{text}\"; use paper, machine-vision or diffuse"),
                )
            })
    }
}

/// How `--image-refine` refines each frame: `track --refine
/// --refine-rounds ROUNDS --supersampling SUPERSAMPLING`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct ImageRefine {
    /// Rounds of render-and-compare.
    pub rounds: u32,
    /// The render's sub-samples per pixel side.
    pub supersampling: u32,
}

impl ImageRefine {
    /// Refuses rounds outside 1..[`MAX_ROUNDS`] and a supersampling outside
    /// 1..[`MAX_SUPERSAMPLING`], naming `image_refine`.
    pub fn check(&self) -> Result<(), ConfigError> {
        if !(1..=MAX_ROUNDS).contains(&self.rounds) {
            return Err(ConfigError::new(
                "image_refine",
                format!("rounds must lie in 1..{MAX_ROUNDS}, got {}", self.rounds),
            ));
        }
        if !(1..=MAX_SUPERSAMPLING).contains(&self.supersampling) {
            return Err(ConfigError::new(
                "image_refine",
                format!(
                    "supersampling must lie in 1..{MAX_SUPERSAMPLING}, got {}",
                    self.supersampling
                ),
            ));
        }
        Ok(())
    }
}

impl std::str::FromStr for ImageRefine {
    type Err = ConfigError;

    /// `ROUNDS` or `ROUNDS:SUPERSAMPLING`; the supersampling defaults to
    /// `track --refine`'s.
    ///
    /// ```
    /// use layout_opt::validate::image_check::ImageRefine;
    /// let r: ImageRefine = "2:16".parse().unwrap();
    /// assert_eq!((r.rounds, r.supersampling), (2, 16));
    /// assert_eq!("3".parse::<ImageRefine>().unwrap().rounds, 3);
    /// assert!("0".parse::<ImageRefine>().is_err() && "2:x".parse::<ImageRefine>().is_err());
    /// ```
    fn from_str(text: &str) -> Result<Self, ConfigError> {
        let bad = || {
            ConfigError::new(
                "image_refine",
                format!("expected ROUNDS or ROUNDS:SUPERSAMPLING, got \"{text}\""),
            )
        };
        let (rounds, supersampling) = match text.split_once(':') {
            Some((rounds, supersampling)) => (rounds, Some(supersampling)),
            None => (text, None),
        };
        let refine = ImageRefine {
            rounds: rounds.trim().parse().map_err(|_| bad())?,
            supersampling: match supersampling {
                Some(s) => s.trim().parse().map_err(|_| bad())?,
                None => DEFAULT_SUPERSAMPLING,
            },
        };
        refine.check()?;
        Ok(refine)
    }
}

/// The image check's settings.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ImageCheck {
    /// Noisy frames read back per scenario.
    pub trials: usize,
    /// The camera and lighting rendered.
    pub preset: ImagePreset,
    /// Render the spheres alone, without the part's supports and plate:
    /// the case where the images must agree with the point model, since
    /// nothing can cut into a sphere's outline.
    pub spheres_only: bool,
    /// The lens's Gaussian blur σ, px (0: none, the supersampled box filter
    /// alone); `None` keeps the preset's.
    pub blur_sigma_px: Option<f64>,
    /// The centre the tracker solves from (`track --centre`).
    pub centre: CentreMethod,
    /// Refine each frame by render-and-compare (`track --refine`), the part
    /// drawn as the frames are; `None`: not refined.
    pub refine: Option<ImageRefine>,
}

impl Default for ImageCheck {
    fn default() -> Self {
        ImageCheck {
            trials: DEFAULT_IMAGE_TRIALS,
            preset: ImagePreset::Paper,
            spheres_only: false,
            blur_sigma_px: None,
            centre: CentreMethod::default(),
            refine: None,
        }
    }
}

impl ImageCheck {
    /// What is rendered, in words, for the report: the preset, and the
    /// part and blur where they depart from it.
    pub fn describe(&self) -> String {
        let mut text = self.preset.describe();
        let n = MAX_SUPERSAMPLING;
        text.push_str(&format!("; frames sub-sampled {n} × {n} per edge pixel"));
        if self.spheres_only {
            text.push_str("; the spheres alone, without supports or plate");
        }
        match self.blur_sigma_px {
            Some(sigma) if sigma > 0.0 => text.push_str(&format!("; lens blur σ {sigma} px")),
            Some(_) => text.push_str("; no lens blur"),
            None => {}
        }
        text.push_str(&format!("; read by track --centre {}", self.centre.name()));
        if let Some(refine) = self.refine {
            text.push_str(&format!(
                " --refine --refine-rounds {} --supersampling {}",
                refine.rounds, refine.supersampling
            ));
        }
        text
    }

    /// Refuses a bad value, naming its field (`image_trials`). A preset
    /// that brings its own camera needs validate's camera to be it.
    ///
    /// ```
    /// use layout_opt::validate::image_check::ImageCheck;
    /// assert!(ImageCheck::default().check().is_ok());
    /// let zero = ImageCheck { trials: 0, ..ImageCheck::default() };
    /// assert_eq!(zero.check().unwrap_err().field, "image_trials");
    /// ```
    pub fn check(&self) -> Result<(), ConfigError> {
        if self.trials == 0 {
            return Err(ConfigError::new("image_trials", "must be at least 1"));
        }
        if let Some(refine) = self.refine {
            refine.check()?;
        }
        if let Some(sigma) = self.blur_sigma_px {
            if !(sigma.is_finite() && (0.0..=MAX_BLUR_SIGMA_PX).contains(&sigma)) {
                return Err(ConfigError::new(
                    "image_blur",
                    format!("must be a blur σ from 0 to {MAX_BLUR_SIGMA_PX} px, got {sigma}"),
                ));
            }
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
    /// The sphere views' mean disc radius, px.
    pub mean_radius_px: f64,
    /// Pooled per-axis σ of the same frames' whole spheres by
    /// [`super::images::independent_centroid`] (noise alone, no tracker),
    /// px; NaN when none.
    pub independent_sigma_px: f64,
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
    /// The same with the pose bias that the spheres' measured mean centre
    /// errors cause added in quadrature, degrees.
    pub predicted_with_bias_rotation_rms_deg: f64,
    /// Its translation counterpart, mm.
    pub predicted_with_bias_translation_rms_mm: f64,
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
    /// Too few radii, or a failed fit.
    Unfitted(String),
}

/// One frame shown in the report: which scenario and realisation, why it
/// was chosen, what the tracker made of it, and the frame itself.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SampleFrame {
    /// Why it was chosen: `nearest`, `farthest` or `worst` (also its
    /// file's stem under `images/`).
    pub role: String,
    /// The scenario.
    pub scenario: Scenario,
    /// The noise realisation.
    pub trial: usize,
    /// What the tracker made of it, in words.
    pub outcome: String,
    /// The noisy frame as tracked.
    #[serde(skip)]
    pub frame: GreyFrame,
    /// The tracker's analysis of it.
    #[serde(skip)]
    pub analysis: FrameAnalysis,
    /// The camera, the layout's sphere centres (mm) and radius (mm), for
    /// the overlay's model outlines.
    #[serde(skip)]
    pub geometry: (Camera, Vec<Vector3<f64>>, f64),
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
    /// The noise law fitted to the centre errors about the exact centres
    /// (noise and bias) of every labelled sphere view, in radius bins of
    /// [`LAW_BIN_PX`]: the law `--write-noise-model` writes.
    pub noise_law: NoiseLaw,
    /// The law of the whole spheres' scatter alone (sensor noise).
    pub scatter_law: NoiseLaw,
    /// Per scenario, in grid order (`images.csv`; not in `summary.json`).
    #[serde(skip)]
    pub per_scenario: Vec<ScenarioImages>,
    /// The frames the report shows: the nearest scenario, the farthest and
    /// the worst ([`Setup::samples`]).
    pub samples: Vec<SampleFrame>,
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

/// Scenarios timed first for [`run`]'s estimate, spread evenly over the
/// visible ones (their results count like any other's).
pub const ESTIMATE_SCENARIOS: usize = 4;

/// [`run_until`] with progress as [`PHASE`] through `observer`, which may
/// ask to stop, and a time estimate: [`ESTIMATE_SCENARIOS`] scenarios
/// spread over the grid are checked first and timed, and the whole
/// check's time, scaled from theirs, is logged before the rest run.
pub fn run(
    config: Checked,
    check: &ImageCheck,
    outcomes: &[ScenarioOutcome],
    observer: &mut impl Observer,
) -> Result<ImageSummary, ImageCheckError> {
    check.check()?;
    let setup = Setup::new(config, check, outcomes)?;
    let chosen = visible(outcomes);
    let total = chosen.len() as u64;
    let stride = chosen.len().div_ceil(ESTIMATE_SCENARIOS).max(1);
    let first: Vec<usize> = chosen.iter().step_by(stride).copied().collect();
    let rest: Vec<usize> = chosen
        .iter()
        .enumerate()
        .filter(|(k, _)| k % stride != 0)
        .map(|(_, &i)| i)
        .collect();
    let done = AtomicU64::new(0);
    let stop = AtomicBool::new(false);
    let on_done = |_: usize| {
        done.fetch_add(1, Ordering::Relaxed);
    };
    // Start the worker threads before timing anything.
    rayon::broadcast(|_| ());
    let started = std::time::Instant::now();
    let mut rendered = watch(
        observer,
        PHASE,
        total,
        || done.load(Ordering::Relaxed),
        Some(&stop),
        || setup.check_all(check, outcomes, &first, &on_done, &stop),
    )?;
    let seconds = started.elapsed().as_secs_f64();
    if !rest.is_empty() {
        observer.log(&format!(
            "image check: about {} for {} visible scenarios × {} frames on {} threads (the first {} scenarios took {:.1} s)",
            minutes(seconds * chosen.len() as f64 / first.len() as f64),
            chosen.len(),
            check.trials,
            rayon::current_num_threads(),
            first.len(),
            seconds
        ));
        rendered.extend(watch(
            observer,
            PHASE,
            total,
            || done.load(Ordering::Relaxed),
            Some(&stop),
            || setup.check_all(check, outcomes, &rest, &on_done, &stop),
        )?);
    }
    rendered.sort_by_key(|r| r.outcome_index);
    setup.summarise(config, check, outcomes, &rendered)
}

/// An estimate's duration: whole seconds below two minutes, else minutes
/// to one decimal.
fn minutes(seconds: f64) -> String {
    if seconds < 120.0 {
        format!("{seconds:.0} s")
    } else {
        format!("{:.1} min", seconds / 60.0)
    }
}

/// What one visible scenario gave.
struct Rendered {
    outcome_index: usize,
    images: Result<PoseImages, String>,
}

/// The indices of the visible scenarios of `outcomes`.
fn visible(outcomes: &[ScenarioOutcome]) -> Vec<usize> {
    (0..outcomes.len())
        .filter(|&i| outcomes[i].visibility.is_visible())
        .collect()
}

/// What every scenario's check shares: the part, the renderer's and the
/// tracker's settings.
struct Setup {
    names: Vec<String>,
    scene: Scene,
    render: RenderConfig,
    track: TrackConfig,
    refiner: Option<Refiner>,
}

impl Setup {
    /// The part and settings of the module docs.
    fn new(
        config: Checked,
        check: &ImageCheck,
        outcomes: &[ScenarioOutcome],
    ) -> Result<Self, ImageCheckError> {
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
        let scene = if check.spheres_only {
            let radius = 0.5 * layout.sphere_diameter_mm;
            let spheres: Vec<_> = layout.positions().iter().map(|&c| (c, radius)).collect();
            Scene::spheres_only(&spheres)
        } else {
            let options = config.structure.clone().unwrap_or_default();
            Scene::from_marker(marker_for_range(layout, &options, &range)?)
        };
        if let Some(camera) = check.preset.camera() {
            if camera != config.camera {
                return Err(ConfigError::new(
                    "image_preset",
                    format!(
                        "{} renders through its own camera; validate must use it too",
                        check.preset.name()
                    ),
                )
                .into());
            }
        }
        let mut render = check.preset.render(config.camera, config.monte_carlo.seed);
        // The frames are a measurement: at render's default 4 × 4
        // sub-samples an edge pixel's coverage comes in steps of 1/16,
        // which biases a sharp 8 px disc's fitted centre by about 0.009 px,
        // twice the sensor noise's scatter; at 16 × 16 that falls to
        // 0.003 px.
        render.optics.supersampling = MAX_SUPERSAMPLING;
        if let Some(sigma_px) = check.blur_sigma_px {
            render.optics.blur = if sigma_px > 0.0 {
                Blur::Gaussian { sigma_px }
            } else {
                Blur::None
            };
        }
        let mut track = TrackConfig::new(layout, config.camera);
        track.detector.threshold = check.preset.threshold();
        track.centre = check.centre;
        track.validate().map_err(|e| {
            ConfigError::new(
                "images",
                format!("the tracker cannot read {}: {e}", layout.name),
            )
        })?;
        let refiner = match check.refine {
            Some(refine) => {
                let mut model = render.clone();
                model.optics.supersampling = refine.supersampling;
                Some(Refiner::new(scene.clone(), model, refine.rounds)?)
            }
            None => None,
        };
        Ok(Setup {
            names,
            scene,
            render,
            track,
            refiner,
        })
    }

    /// How every frame is read.
    fn reader(&self) -> Reader<'_> {
        Reader {
            track: &self.track,
            refiner: self.refiner.as_ref(),
        }
    }

    /// Checks the scenarios `chosen` (indices into `outcomes`) in
    /// parallel, calling `on_done` once per scenario finished; a set `stop`
    /// ends it with [`ImageCheckError::Interrupted`].
    fn check_all(
        &self,
        check: &ImageCheck,
        outcomes: &[ScenarioOutcome],
        chosen: &[usize],
        on_done: &(dyn Fn(usize) + Sync),
        stop: &AtomicBool,
    ) -> Result<Vec<Rendered>, ImageCheckError> {
        use rayon::prelude::*;
        chosen
            .par_iter()
            .map(|&outcome_index| {
                if stop.load(Ordering::Relaxed) {
                    return Err(ImageCheckError::Interrupted);
                }
                let scenario = &outcomes[outcome_index].scenario;
                let images = match check_pose(
                    &self.scene,
                    &self.names,
                    &self.render,
                    self.reader(),
                    &scenario.pose(),
                    scenario.index as u64,
                    check.trials,
                ) {
                    Ok(images) => Ok(images),
                    Err(error) => Err(refusal(error)?),
                };
                on_done(outcome_index);
                Ok(Rendered {
                    outcome_index,
                    images,
                })
            })
            .collect()
    }

    /// The summary of `rendered` with its sample frames.
    fn summarise(
        &self,
        config: Checked,
        check: &ImageCheck,
        outcomes: &[ScenarioOutcome],
        rendered: &[Rendered],
    ) -> Result<ImageSummary, ImageCheckError> {
        let mut summary = summarise(config, check, outcomes, &self.names, rendered);
        summary.samples = self.samples(config, outcomes, rendered)?;
        Ok(summary)
    }

    /// The report's sample frames, rendered again from their seeds: realisation
    /// 0 of the nearest rendered scenario and of the farthest (by depth,
    /// the first in grid order on a tie), and the worst frame
    /// ([`super::images::FrameRank`]) of the scenario whose worst frame is
    /// worst (the one with the most failed frames, then the largest
    /// rotation RMS, on a tie).
    fn samples(
        &self,
        config: Checked,
        outcomes: &[ScenarioOutcome],
        rendered: &[Rendered],
    ) -> Result<Vec<SampleFrame>, ImageCheckError> {
        let posed: Vec<(&Scenario, &PoseImages)> = rendered
            .iter()
            .filter_map(|r| {
                r.images
                    .as_ref()
                    .ok()
                    .map(|images| (&outcomes[r.outcome_index].scenario, images))
            })
            .collect();
        let by_depth = |far: bool| {
            posed.iter().copied().reduce(|best, next| {
                let better = if far {
                    next.0.depth_mm > best.0.depth_mm
                } else {
                    next.0.depth_mm < best.0.depth_mm
                };
                if better {
                    next
                } else {
                    best
                }
            })
        };
        let failures = |images: &PoseImages| {
            images.lost.values().sum::<usize>()
                + images.mislabelled_frames
                + images.frames_missing_a_whole_sphere
        };
        let worst = posed.iter().copied().reduce(|best, next| {
            let key = |(_, images): (&Scenario, &PoseImages)| {
                (
                    images.worst_rank.failure,
                    failures(images),
                    rms(images.rotation_error_deg.iter().copied()),
                )
            };
            let (a, b) = (key(next), key(best));
            let worse = (a.0, a.1)
                .cmp(&(b.0, b.1))
                .then(a.2.total_cmp(&b.2))
                .is_gt();
            if worse {
                next
            } else {
                best
            }
        });
        let chosen = [
            ("nearest", by_depth(false).map(|(s, _)| (s, 0))),
            ("farthest", by_depth(true).map(|(s, _)| (s, 0))),
            ("worst", worst.map(|(s, images)| (s, images.worst_trial))),
        ];
        let geometry = (
            config.camera,
            self.track.object.clone(),
            self.track.radius_mm(),
        );
        let mut samples = Vec::new();
        for (role, choice) in chosen {
            let Some((scenario, trial)) = choice else {
                continue;
            };
            let pose = scenario.pose();
            let (frame, analysis) = sample_frame(
                &self.scene,
                &self.render,
                self.reader(),
                &pose,
                scenario.index as u64,
                trial,
            )
            .map_err(ImageCheckError::Render)?;
            let outcome = match (&analysis.outcome, &analysis.pose) {
                (Ok(_), Some(estimate)) => format!(
                    "posed, rotation error {}°, translation error {} mm",
                    crate::report::number::significant(
                        Some(rotation_error_deg(&pose.rotation, &estimate.rotation)),
                        2
                    ),
                    crate::report::number::significant(
                        Some(translation_error_mm(
                            &pose.translation,
                            &estimate.translation
                        )),
                        2
                    )
                ),
                (Err(error), _) => format!("no pose: {error}"),
                (Ok(_), None) => "no pose".to_string(),
            };
            samples.push(SampleFrame {
                role: role.to_string(),
                scenario: *scenario,
                trial,
                outcome,
                frame,
                analysis,
                geometry: geometry.clone(),
            });
        }
        Ok(samples)
    }
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
    check.check()?;
    let setup = Setup::new(config, check, outcomes)?;
    let done = AtomicU64::new(0);
    let count = |_: usize| on_done(done.fetch_add(1, Ordering::Relaxed) as usize + 1);
    let rendered = setup.check_all(check, outcomes, &visible(outcomes), &count, stop)?;
    setup.summarise(config, check, outcomes, &rendered)
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
        preset: check.describe(),
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
        scatter_law: NoiseLaw::Unfitted(String::new()),
        per_scenario: Vec::new(),
        samples: Vec::new(),
    };
    // (radius, depth, view) of every whole sphere view, by the tracker and
    // by the independent centroid.
    let mut whole: Vec<(f64, f64, SphereView)> = Vec::new();
    let mut independent: Vec<(f64, f64, SphereView)> = Vec::new();
    let mut samples: Vec<SigmaSample> = Vec::new();
    let mut scatter_samples: Vec<SigmaSample> = Vec::new();
    let mut pose_rows: Vec<PoseRow> = Vec::new();
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
        if let (Some(predicted), Some(at_measured)) = (
            predicted,
            prediction_at_measured(&config, &scenario.pose(), images, &views),
        ) {
            if row.posed > 0 && scenario_sigma.is_finite() {
                let assumed = rms(images.radius_px.iter().enumerate().map(|(i, &r)| {
                    config.monte_carlo.noise.point_sigma(
                        scenario.sigma_px,
                        config.layout.points[i].sigma_px,
                        r,
                    )
                }));
                pose_rows.push(PoseRow {
                    image_rotation_deg: row.rotation_rms_deg,
                    predicted_rotation_deg: predicted.rms_rotation_deg,
                    at_measured_rotation_deg: at_measured.0,
                    with_bias_rotation_deg: at_measured.0.hypot(at_measured.2),
                    with_bias_translation_mm: at_measured.1.hypot(at_measured.3),
                    image_translation_mm: row.translation_rms_mm,
                    predicted_translation_mm: predicted.rms_translation_mm,
                    at_measured_translation_mm: at_measured.1,
                    assumed_sigma_px: assumed,
                });
            }
        }
        let poses = std::slice::from_ref(images);
        samples.extend(sigma_samples(poses, CentreErrorMeasure::AboutTruth));
        scatter_samples.extend(sigma_samples(poses, CentreErrorMeasure::Scatter));
        summary.per_scenario.push(row);
        whole.extend(
            views
                .into_iter()
                .filter(|v| v.hidden < WHOLE_SPHERE_HIDDEN)
                .map(|v| (v.radius_px, scenario.depth_mm, v)),
        );
        independent.extend(
            independent_views(images)
                .into_iter()
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
    let views = [whole.as_slice(), independent.as_slice()];
    summary.by_radius = bins(views, RADIUS_BIN_PX, |(radius, _, _)| *radius);
    summary.by_depth = bins(views, DEPTH_BIN_MM, |(_, depth, _)| *depth);
    summary.pose = pose_comparison(&pose_rows, &whole);
    summary.noise_law = noise_law(&rms_by_radius(&samples, LAW_BIN_PX));
    summary.scatter_law = noise_law(&scatter_samples);
    summary
}

/// Sphere views binned by `key` in bins `width` wide, lowest first: the
/// tracker's (`views[0]`), each bin with the independent centroid's
/// (`views[1]`) σ in it.
fn bins(
    views: [&[(f64, f64, SphereView)]; 2],
    width: f64,
    key: impl Fn(&(f64, f64, SphereView)) -> f64,
) -> Vec<CentreBin> {
    let mut by_bin: BTreeMap<i64, [Vec<&SphereView>; 2]> = BTreeMap::new();
    for (which, list) in views.iter().enumerate() {
        for item in list.iter() {
            by_bin
                .entry((key(item) / width).floor() as i64)
                .or_default()[which]
                .push(&item.2);
        }
    }
    by_bin
        .into_iter()
        .filter(|(_, [tracked, _])| !tracked.is_empty())
        .map(|(bin, [tracked, independent])| CentreBin {
            from: bin as f64 * width,
            to: (bin + 1) as f64 * width,
            sphere_views: tracked.len(),
            centres: tracked.iter().map(|v| v.centres).sum(),
            bias_px: rms(tracked.iter().map(|v| v.bias_px())),
            sigma_px: pooled_sigma(tracked.iter().copied()),
            mean_radius_px: tracked.iter().map(|v| v.radius_px).sum::<f64>() / tracked.len() as f64,
            independent_sigma_px: pooled_sigma(independent.iter().copied()),
        })
        .collect()
}

/// One scenario's pose figures: from the images, first order at the
/// assumed σ and at the measured σ.
struct PoseRow {
    image_rotation_deg: f64,
    predicted_rotation_deg: f64,
    at_measured_rotation_deg: f64,
    image_translation_mm: f64,
    predicted_translation_mm: f64,
    at_measured_translation_mm: f64,
    with_bias_rotation_deg: f64,
    with_bias_translation_mm: f64,
    /// RMS over the spheres of the noise model's σ, px.
    assumed_sigma_px: f64,
}

/// The first-order (rotation RMS °, translation RMS mm, rotation bias °,
/// translation bias mm) of the pose the tracker solved (module docs): the
/// spheres in at least half its posed frames, each at its own measured σ,
/// the bias from their measured mean centre errors; None when a sphere
/// among them has no σ, or the pose is singular.
fn prediction_at_measured(
    config: &Checked,
    pose: &crate::pose::Pose,
    images: &PoseImages,
    views: &[SphereView],
) -> Option<(f64, f64, f64, f64)> {
    let posed = images.rotation_error_deg.len();
    let positions = config.layout.positions();
    let (mut object, mut sigmas, mut biases) = (Vec::new(), Vec::new(), Vec::new());
    for (sphere, &count) in images.in_pose.iter().enumerate() {
        if posed == 0 || 2 * count < posed {
            continue;
        }
        let view = views.iter().find(|v| v.sphere == sphere)?;
        let sigma = view.sigma_px();
        if !(sigma > 0.0 && sigma.is_finite()) {
            return None;
        }
        object.push(positions[sphere]);
        sigmas.push(sigma);
        biases.push(nalgebra::Vector2::from(view.mean));
    }
    let (covariance, bias) = crate::error_model::first_order::pose_covariance_and_bias(
        &config.camera,
        pose,
        &object,
        &sigmas,
        &biases,
    )
    .ok()?;
    let covariance = covariance?;
    Some((
        covariance.rms_rotation_deg(),
        covariance.rms_translation_mm(),
        bias.rotation_deg(),
        bias.translation_norm_mm(),
    ))
}

/// The pooled pose comparison (module docs), None without scenarios.
fn pose_comparison(rows: &[PoseRow], whole: &[(f64, f64, SphereView)]) -> Option<PoseComparison> {
    if rows.is_empty() {
        return None;
    }
    let pooled = |f: &dyn Fn(&PoseRow) -> f64| rms(rows.iter().map(f));
    Some(PoseComparison {
        scenarios: rows.len(),
        assumed_sigma_px: pooled(&|r| r.assumed_sigma_px),
        measured_sigma_px: pooled_sigma(whole.iter().map(|(_, _, v)| v)),
        image_rotation_rms_deg: pooled(&|r| r.image_rotation_deg),
        predicted_rotation_rms_deg: pooled(&|r| r.predicted_rotation_deg),
        predicted_at_measured_rotation_rms_deg: pooled(&|r| r.at_measured_rotation_deg),
        image_translation_rms_mm: pooled(&|r| r.image_translation_mm),
        predicted_translation_rms_mm: pooled(&|r| r.predicted_translation_mm),
        predicted_at_measured_translation_rms_mm: pooled(&|r| r.at_measured_translation_mm),
        predicted_with_bias_rotation_rms_deg: pooled(&|r| r.with_bias_rotation_deg),
        predicted_with_bias_translation_rms_mm: pooled(&|r| r.with_bias_translation_mm),
    })
}

/// `samples` pooled in disc-radius bins `width` wide: per bin, the
/// weighted RMS of their σ at their weighted mean radius, weighted by the
/// bin's total weight; smallest radius first.
fn rms_by_radius(samples: &[SigmaSample], width: f64) -> Vec<SigmaSample> {
    let mut bins: BTreeMap<i64, [f64; 3]> = BTreeMap::new();
    for s in samples {
        let bin = bins
            .entry((s.radius_px / width).floor() as i64)
            .or_default();
        bin[0] += s.weight;
        bin[1] += s.weight * s.radius_px;
        bin[2] += s.weight * s.sigma_px * s.sigma_px;
    }
    bins.into_values()
        .map(|[weight, radius, square]| SigmaSample {
            radius_px: radius / weight,
            sigma_px: (square / weight).sqrt(),
            weight,
        })
        .collect()
}

/// The law fitted to `samples`, refused below [`MIN_LAW_RADII`] distinct
/// radii.
fn noise_law(samples: &[SigmaSample]) -> NoiseLaw {
    let mut radii: Vec<f64> = samples.iter().map(|s| s.radius_px).collect();
    radii.sort_by(f64::total_cmp);
    radii.dedup_by(|a, b| (*a - *b).abs() <= 1e-9 * b.abs());
    if radii.len() < MIN_LAW_RADII {
        return NoiseLaw::Unfitted(format!(
            "{} distinct sphere radii measured, at least {MIN_LAW_RADII} needed",
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
            independent: vec![],
            rotation_error_deg: vec![],
            translation_error_mm: vec![],
            mislabelled_frames: 0,
            frames_missing_a_whole_sphere: 0,
            lost: BTreeMap::new(),
            in_pose: vec![0; sphere + 1],
            worst_trial: 0,
            worst_rank: super::super::images::FrameRank {
                failure: 0,
                rotation_error_deg: 0.0,
            },
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
    fn radius_bins_pool_the_rms_at_the_mean_radius() {
        let sample = |radius_px, sigma_px, weight| SigmaSample {
            radius_px,
            sigma_px,
            weight,
        };
        let pooled = rms_by_radius(
            &[
                sample(6.2, 0.03, 1.0),
                sample(9.5, 0.02, 2.0),
                sample(6.8, 0.01, 3.0),
            ],
            1.0,
        );
        assert_eq!(pooled.len(), 2);
        assert!((pooled[0].radius_px - 6.65).abs() < 1e-12);
        assert!((pooled[0].sigma_px - (0.0012f64 / 4.0).sqrt()).abs() < 1e-12);
        assert_eq!(pooled[0].weight, 4.0);
        assert_eq!(pooled[1], sample(9.5, 0.02, 2.0));
    }

    #[test]
    fn presets_parse_by_name_and_set_what_they_say() {
        for preset in ImagePreset::ALL {
            assert_eq!(preset.name().parse::<ImagePreset>().unwrap(), preset);
        }
        assert_eq!(
            "glossy".parse::<ImagePreset>().unwrap_err().field,
            "image_preset"
        );
        let camera = Camera::paper();
        assert_eq!(
            ImagePreset::Paper.render(camera, 3),
            RenderConfig {
                seed: 3,
                ..RenderConfig::new(camera)
            }
        );
        let vision = ImagePreset::MachineVision.camera().unwrap();
        assert_eq!((vision.width(), vision.height()), (1440, 1080));
        let render = ImagePreset::MachineVision.render(vision, 3);
        assert_eq!(render.sensor.noise.unwrap().read_noise_electrons, 2.2);
        assert!(render.validate().is_ok());
        let diffuse = ImagePreset::Diffuse.render(camera, 3);
        assert_eq!(diffuse.appearance.lighting, Lighting::Diffuse);
        assert_eq!(
            ImagePreset::Diffuse.threshold(),
            Threshold::Fixed(DIFFUSE_THRESHOLD)
        );
        assert!(ImagePreset::Diffuse.camera().is_none());
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
            ImageCheck {
                trials: 0,
                ..ImageCheck::default()
            }
            .check()
            .unwrap_err()
            .field,
            "image_trials"
        );
        assert_eq!(ImageCheck::default().trials, DEFAULT_IMAGE_TRIALS);
    }
}
