//! `characterise`: the printed part measured from images of it.
//!
//! A printed part is not its layout: a printer holds its sphere centres to
//! about ±0.1–0.2 mm, and tracking with the nominal layout turns that
//! error into pose error far above the image noise's. Commercial optical
//! trackers close the loop by measuring each tool after it is made from
//! the tracker's own images; this module does the same.
//!
//! Every frame's labelled projected sphere centres (from `track`'s reading
//! of the frame, `track`'s JSON lines, or a `solve` batch) enter one
//! bundle adjustment of the sphere centres and the frame poses
//! ([`bundle`]), started from the nominal layout and the poses tracked
//! with it, with a robust loss. Frames that do not fit one rigid part
//! (another marker, wrong labels, a sphere partly hidden and missed) are
//! dropped, worst first, while their residuals are improbable under the
//! rest's noise, and named. The result is reported in the gauge that best
//! overlays the nominal ([`gauge`]), at the nominal's scale or at the
//! scale of measured distances, with each sphere's covariance from the
//! adjustment's information and the centres' noise estimated from its
//! residuals. Where a sphere's 1σ exceeds the bar, nothing is reported:
//! the error names the views that would bring it down ([`plan`]).
//!
//! No files, no printing: [`workflow`] reads and writes.

pub mod bundle;
pub mod gauge;
pub mod plan;
pub mod report;
pub mod workflow;

use crate::camera::Camera;
use crate::config::ConfigError;
use crate::layout::Layout;
use crate::pose::Pose;
pub use bundle::MIN_FRAMES;
use bundle::{adjust, robust_sigma, shape_information, BundleError, BundleOptions, Observation};
use gauge::{distance_scale, shape_covariance, Distance, Similarity};
use nalgebra::{DMatrix, Matrix3, Vector2, Vector3};
use serde::Serialize;

/// Probability below which a frame's residuals, under the noise of the
/// rest, mark it as not of this part (it is then dropped).
pub const DEFAULT_DROP_PROBABILITY: f64 = 1e-6;

/// Default bar on a sphere's largest 1σ, mm.
pub const DEFAULT_MAX_SIGMA_MM: f64 = 0.02;

/// Default σ of a caliper distance, mm.
pub const DEFAULT_DISTANCE_SIGMA_MM: f64 = 0.01;

/// Fewest labelled centres a frame must have to be used.
pub const MIN_CENTRES_PER_FRAME: usize = 4;

/// A frame is dropped only when its residual RMS is also this many times
/// the median frame's: a reading's own systematic errors (the part behind
/// a limb, shading) vary between views and are not a reason to drop one,
/// while another marker or a wrong label leaves residuals of pixels.
pub const DROP_RMS_FACTOR: f64 = 3.0;

/// Nor is a frame dropped whose residual RMS per axis is below this, px:
/// no reading tells frames apart at a thousandth of a pixel (exact
/// centres converted from ellipse centres differ by less).
pub const DROP_FLOOR_PX: f64 = 1e-3;

/// Largest share of the frames that may be dropped before the run refuses:
/// beyond it the nominal layout, the camera or the labels are wrong.
pub const MAX_DROPPED_SHARE: f64 = 0.34;

/// Largest change of scale a single measured distance may make, relative
/// to the nominal's (a print shrinks by tenths of a percent; beyond this
/// the pair's names or the value are wrong).
pub const MAX_SCALE_CHANGE: f64 = 0.02;

/// How far (in its σ) a measured distance may disagree with the others and
/// the images before the run refuses.
pub const MAX_DISTANCE_DISAGREEMENT_SIGMA: f64 = 5.0;

/// A measured distance between two named sphere centres.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct NamedDistance {
    /// First point's name.
    pub first: String,
    /// Second point's name.
    pub second: String,
    /// Measured distance, mm.
    pub mm: f64,
    /// Its 1σ, mm.
    pub sigma_mm: f64,
}

impl std::str::FromStr for NamedDistance {
    type Err = String;

    /// `P1:P4=100.03` or `P1:P4=100.03±0.005` (also `+-`).
    fn from_str(text: &str) -> Result<Self, Self::Err> {
        let usage = || {
            format!("'{text}' is not a distance; write FIRST:SECOND=MM or FIRST:SECOND=MM±SIGMA, e.g. P1:P4=100.03")
        };
        let (pair, value) = text.split_once('=').ok_or_else(usage)?;
        let (first, second) = pair.split_once(':').ok_or_else(usage)?;
        let (mm, sigma) = match value.split_once('±').or_else(|| value.split_once("+-")) {
            Some((mm, sigma)) => (mm, Some(sigma)),
            None => (value, None),
        };
        let mm: f64 = mm.trim().parse().map_err(|_| usage())?;
        let sigma_mm = match sigma {
            Some(s) => s.trim().parse().map_err(|_| usage())?,
            None => DEFAULT_DISTANCE_SIGMA_MM,
        };
        if !(mm.is_finite() && mm > 0.0) {
            return Err(format!(
                "distance {pair} must be a positive length in mm, got {mm}"
            ));
        }
        if !(sigma_mm.is_finite() && sigma_mm > 0.0) {
            return Err(format!(
                "the σ of distance {pair} must be positive, got {sigma_mm}"
            ));
        }
        Ok(NamedDistance {
            first: first.trim().to_string(),
            second: second.trim().to_string(),
            mm,
            sigma_mm,
        })
    }
}

/// What a characterisation needs besides the frames.
#[derive(Debug, Clone, PartialEq)]
pub struct CharacteriseConfig {
    /// The nominal layout: the start, the names and, by default, the scale.
    pub nominal: Layout,
    /// The camera (its focal length turns residuals into px; the views to
    /// add are planned with it).
    pub camera: Camera,
    /// Measured distances that give the scale (none: the nominal's).
    pub distances: Vec<NamedDistance>,
    /// The bar on every sphere's largest 1σ, mm.
    pub max_sigma_mm: f64,
    /// A frame whose residuals are less probable than this is dropped.
    pub drop_probability: f64,
    /// The adjustment's tolerances.
    pub bundle: BundleOptions,
}

impl CharacteriseConfig {
    /// The defaults for `nominal` seen by `camera`.
    pub fn new(nominal: Layout, camera: Camera) -> CharacteriseConfig {
        CharacteriseConfig {
            nominal,
            camera,
            distances: Vec::new(),
            max_sigma_mm: DEFAULT_MAX_SIGMA_MM,
            drop_probability: DEFAULT_DROP_PROBABILITY,
            bundle: BundleOptions::default(),
        }
    }

    /// Checks the configuration; the error names the field.
    pub fn validate(&self) -> Result<(), ConfigError> {
        self.nominal
            .validate()
            .map_err(|e| ConfigError::new("nominal", e.to_string()))?;
        if !(self.max_sigma_mm.is_finite() && self.max_sigma_mm > 0.0) {
            return Err(ConfigError::new(
                "max_sigma_mm",
                "must be a positive length in mm",
            ));
        }
        if !(self.drop_probability > 0.0 && self.drop_probability < 0.5) {
            return Err(ConfigError::new("drop_probability", "must lie in (0, 0.5)"));
        }
        self.resolve_distances()?;
        Ok(())
    }

    /// The distances with their points' indices.
    fn resolve_distances(&self) -> Result<Vec<Distance>, ConfigError> {
        let index = |name: &str| {
            self.nominal
                .points
                .iter()
                .position(|p| p.name == name)
                .ok_or_else(|| {
                    let names: Vec<&str> = self
                        .nominal
                        .points
                        .iter()
                        .map(|p| p.name.as_str())
                        .collect();
                    ConfigError::new(
                        "distances",
                        format!(
                            "no sphere '{name}' in layout {} (its spheres: {})",
                            self.nominal.name,
                            names.join(", ")
                        ),
                    )
                })
        };
        self.distances
            .iter()
            .map(|d| {
                let (first, second) = (index(&d.first)?, index(&d.second)?);
                if first == second {
                    return Err(ConfigError::new(
                        "distances",
                        format!("{}:{} names one sphere twice", d.first, d.second),
                    ));
                }
                Ok(Distance {
                    first,
                    second,
                    mm: d.mm,
                    sigma_mm: d.sigma_mm,
                })
            })
            .collect()
    }
}

/// One frame's labelled centres and the pose to start from.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameCentres {
    /// The frame's name (its file, or its record).
    pub name: String,
    /// The pose tracked with the nominal layout.
    pub pose: Pose,
    /// `(sphere, projected centre on the undistorted normalised plane)`.
    pub centres: Vec<(usize, Vector2<f64>)>,
}

/// A frame the characterisation did not use, and why.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SkippedFrame {
    /// The frame.
    pub frame: String,
    /// Why.
    pub reason: String,
}

/// How a used frame fits the characterised part.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FrameFit {
    /// The frame.
    pub frame: String,
    /// Its labelled centres.
    pub centres: usize,
    /// RMS residual of its centres, px.
    pub rms_px: f64,
    /// Its pose in the characterised part's frame: rotation vector (rad).
    pub rvec: [f64; 3],
    /// Translation, mm.
    pub tvec: [f64; 3],
}

/// Where the reported scale came from.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ScaleSource {
    /// `"nominal"` or `"distances"`.
    pub source: &'static str,
    /// The scale relative to the nominal's (1 for `"nominal"`).
    pub factor: f64,
    /// Each distance: as measured, and in the characterised part.
    pub distances: Vec<DistanceFit>,
}

/// A measured distance against the characterised part.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DistanceFit {
    /// The distance as given.
    pub measured: NamedDistance,
    /// In the characterised part, mm.
    pub characterised_mm: f64,
    /// In the nominal layout, mm.
    pub nominal_mm: f64,
}

/// The characterised part (docs/formats.md, "`characterise` report").
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Characterisation {
    /// The nominal layout's name.
    pub nominal: String,
    /// Point names, in layout order.
    pub names: Vec<String>,
    /// Nominal centres, mm.
    pub nominal_mm: Vec<[f64; 3]>,
    /// Characterised centres, mm, in the gauge that overlays the nominal.
    pub measured_mm: Vec<[f64; 3]>,
    /// Characterised minus nominal, mm.
    pub correction_mm: Vec<[f64; 3]>,
    /// Each centre's 3×3 covariance, mm².
    pub covariance_mm2: Vec<[[f64; 3]; 3]>,
    /// Each centre's 1σ along its covariance's principal axes, largest
    /// first, mm.
    pub sigma_axes_mm: Vec<[f64; 3]>,
    /// Each centre's largest 1σ's direction (unit, in the layout frame).
    pub weakest_direction: Vec<[f64; 3]>,
    /// Frames used, with their fit.
    pub frames: Vec<FrameFit>,
    /// Frames dropped or skipped, with why.
    pub dropped: Vec<SkippedFrame>,
    /// Centres used.
    pub centres: usize,
    /// RMS residual over the used centres, px.
    pub residual_rms_px: f64,
    /// The centres' σ estimated from the residuals (per axis), px.
    pub sigma_px: f64,
    /// The scale and where it came from.
    pub scale: ScaleSource,
    /// Levenberg–Marquardt iterations, over every refit.
    pub iterations: usize,
    /// The bar every sphere's largest 1σ met, mm.
    pub max_sigma_mm: f64,
}

impl Characterisation {
    /// The largest 1σ of any sphere, mm, and the sphere's index.
    pub fn worst_sigma(&self) -> (usize, f64) {
        self.sigma_axes_mm
            .iter()
            .enumerate()
            .map(|(i, s)| (i, s[0]))
            .fold((0, 0.0), |best, x| if x.1 > best.1 { x } else { best })
    }

    /// The characterised layout: the nominal's names and diameter at the
    /// characterised centres, its provenance saying so.
    pub fn layout(&self, nominal: &Layout, command: &str) -> Layout {
        let mut layout = nominal.clone();
        for (point, x) in layout.points.iter_mut().zip(&self.measured_mm) {
            point.position = Vector3::from(*x);
        }
        layout.name = format!("{}-characterised", nominal.name);
        layout.family = None;
        // A JSON object of one value per point, keyed by the point's name.
        let per_point =
            |values: Vec<serde_json::Value>| -> serde_json::Map<String, serde_json::Value> {
                self.names.iter().cloned().zip(values).collect()
            };
        let largest_sigma = per_point(
            self.sigma_axes_mm
                .iter()
                .map(|s| serde_json::json!(s[0]))
                .collect(),
        );
        let covariances = per_point(
            self.covariance_mm2
                .iter()
                .map(|c| serde_json::json!(c))
                .collect(),
        );
        layout.provenance = Some(serde_json::json!({
            "command": command,
            "version": env!("CARGO_PKG_VERSION"),
            "characterised": {
                "nominal": self.nominal,
                "nominal_provenance": nominal.provenance,
                "nominal_family": nominal.family,
                "frames": self.frames.len(),
                "dropped": self.dropped.iter().map(|d| &d.frame).collect::<Vec<_>>(),
                "centres": self.centres,
                "residual_rms_px": self.residual_rms_px,
                "sigma_px": self.sigma_px,
                "scale": self.scale,
                "sigma_mm": largest_sigma,
                "covariance_mm2": covariances,
            }
        }));
        layout
    }
}

/// Why a characterisation could not be made.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum CharacteriseError {
    /// The configuration is invalid.
    #[error(transparent)]
    Config(#[from] ConfigError),
    /// Too few frames to use.
    #[error("{usable} usable frame(s) of {given}; a characterisation needs at least {needed} (frames skipped: {skipped})")]
    TooFewFrames {
        /// Frames usable.
        usable: usize,
        /// Frames given.
        given: usize,
        /// Frames needed.
        needed: usize,
        /// The skipped frames and why, as text.
        skipped: String,
    },
    /// Too many frames do not fit one part.
    #[error("{dropped} of {frames} frames do not fit one rigid part ({names}); the nominal layout, the camera or the labels are probably wrong")]
    TooManyDropped {
        /// Frames dropped.
        dropped: usize,
        /// Frames used at first.
        frames: usize,
        /// Their names.
        names: String,
    },
    /// The adjustment failed.
    #[error("bundle adjustment failed: {0}")]
    Bundle(#[from] BundleError),
    /// A direction of the shape no frame observes.
    #[error(
        "the frames leave part of the shape unobserved ({0}); add views tilted about two axes"
    )]
    Unobserved(String),
    /// Measured distances contradict the images or the nominal.
    #[error("{0}")]
    Distance(String),
    /// A sphere's 1σ is above the bar.
    #[error("sphere {sphere}'s 1σ is {sigma_mm:.4} mm along ({}), above --max-sigma {max_sigma_mm} mm: the frames observe it poorly. Capture also: {}", .direction.map(|v| format!("{v:.2}")).join(", "), .add_views.join("; "))]
    TooUncertain {
        /// The worst sphere's name.
        sphere: String,
        /// Its largest 1σ, mm.
        sigma_mm: f64,
        /// The bar, mm.
        max_sigma_mm: f64,
        /// Its weakest direction.
        direction: [f64; 3],
        /// The views to add, described.
        add_views: Vec<String>,
    },
}

/// The per-frame statistic's critical value: the upper `p` quantile of χ²
/// with `dof` degrees of freedom (Wilson–Hilferty).
fn chi_squared_quantile(dof: f64, p: f64) -> f64 {
    let z = crate::identifiability::normal_upper_quantile(p);
    let h = 2.0 / (9.0 * dof);
    dof * (1.0 - h + z * h.sqrt()).powi(3)
}

/// Frames' centres → observations, in frame order; frames with too few
/// centres or a sphere twice are skipped.
fn observations(
    frames: &[FrameCentres],
    spheres: usize,
) -> (Vec<usize>, Vec<Observation>, Vec<SkippedFrame>) {
    let mut used = Vec::new();
    let mut out = Vec::new();
    let mut skipped = Vec::new();
    for (index, frame) in frames.iter().enumerate() {
        let mut seen = vec![false; spheres];
        let mut twice = None;
        for &(sphere, _) in &frame.centres {
            if sphere >= spheres {
                twice = Some(format!("label {sphere} is not a sphere of the layout"));
                break;
            }
            if std::mem::replace(&mut seen[sphere], true) {
                twice = Some(format!("sphere {sphere} is labelled twice"));
                break;
            }
        }
        if let Some(reason) = twice {
            skipped.push(SkippedFrame {
                frame: frame.name.clone(),
                reason: format!("labels disagree with one part: {reason}"),
            });
            continue;
        }
        if frame.centres.len() < MIN_CENTRES_PER_FRAME {
            skipped.push(SkippedFrame {
                frame: frame.name.clone(),
                reason: format!(
                    "{} labelled centre(s); at least {MIN_CENTRES_PER_FRAME} are needed",
                    frame.centres.len()
                ),
            });
            continue;
        }
        let k = used.len();
        used.push(index);
        out.extend(
            frame
                .centres
                .iter()
                .map(|&(sphere, normalised)| Observation {
                    frame: k,
                    sphere,
                    normalised,
                }),
        );
    }
    (used, out, skipped)
}

/// Characterises the part from its frames (module docs). `config` must
/// have been validated.
pub fn characterise(
    config: &CharacteriseConfig,
    frames: &[FrameCentres],
) -> Result<Characterisation, CharacteriseError> {
    config.validate()?;
    let nominal: Vec<Vector3<f64>> = config.nominal.points.iter().map(|p| p.position).collect();
    let spheres = nominal.len();
    let focal_px = 0.5 * (config.camera.fx() + config.camera.fy());
    let (mut used, mut observations, mut dropped) = observations(frames, spheres);
    let skipped_text = |dropped: &[SkippedFrame]| {
        dropped
            .iter()
            .map(|d| format!("{}: {}", d.frame, d.reason))
            .collect::<Vec<_>>()
            .join("; ")
    };
    if used.len() < MIN_FRAMES {
        return Err(CharacteriseError::TooFewFrames {
            usable: used.len(),
            given: frames.len(),
            needed: MIN_FRAMES,
            skipped: skipped_text(&dropped),
        });
    }
    let first_count = used.len();
    let mut shape = nominal.clone();
    let mut poses: Vec<Pose> = used.iter().map(|&f| frames[f].pose).collect();
    let mut iterations = 0;
    let bundle = loop {
        let bundle = adjust(&shape, &poses, &observations, &config.bundle)?;
        iterations += bundle.iterations;
        // Each frame's squared residuals over the robust σ of all centres.
        let sigma = robust_sigma(&bundle.residuals).max(f64::MIN_POSITIVE);
        let mut statistic = vec![(0.0, 0usize); used.len()];
        for (o, r) in observations.iter().zip(&bundle.residuals) {
            statistic[o.frame].0 += r.norm_squared() / (sigma * sigma);
            statistic[o.frame].1 += 1;
        }
        let frame_rms: Vec<f64> = statistic
            .iter()
            .map(|&(t, n)| (t / n.max(1) as f64).sqrt())
            .collect();
        let median_rms = crate::statistics::median(&mut frame_rms.clone()).unwrap_or(0.0);
        let worst = statistic
            .iter()
            .enumerate()
            .filter(|&(k, _)| {
                frame_rms[k] > DROP_RMS_FACTOR * median_rms
                    && frame_rms[k] * sigma * focal_px / std::f64::consts::SQRT_2 > DROP_FLOOR_PX
            })
            .map(|(k, &(t, n))| {
                let dof = (2 * n).saturating_sub(6).max(1) as f64;
                (k, t / chi_squared_quantile(dof, config.drop_probability))
            })
            .max_by(|a, b| a.1.total_cmp(&b.1));
        match worst {
            Some((k, excess)) if excess > 1.0 => {
                let rms = (statistic[k].0 / statistic[k].1 as f64 / 2.0).sqrt() * sigma * focal_px;
                dropped.push(SkippedFrame {
                    frame: frames[used[k]].name.clone(),
                    reason: format!(
                        "does not fit the part the other frames show: residual RMS {rms:.3} px per axis against {:.3} px; another marker, wrong labels or a sphere partly hidden",
                        sigma * focal_px
                    ),
                });
                used.remove(k);
                poses = bundle.poses.clone();
                poses.remove(k);
                shape = bundle.shape.clone();
                observations.retain(|o| o.frame != k);
                for o in &mut observations {
                    if o.frame > k {
                        o.frame -= 1;
                    }
                }
                let lost = first_count - used.len();
                if lost as f64 > MAX_DROPPED_SHARE * first_count as f64 || used.len() < MIN_FRAMES {
                    let names: Vec<String> = dropped.iter().map(|d| d.frame.clone()).collect();
                    return Err(CharacteriseError::TooManyDropped {
                        dropped: lost,
                        frames: first_count,
                        names: names.join(", "),
                    });
                }
            }
            _ => break bundle,
        }
    };
    let fit = Fit {
        used,
        observations,
        bundle,
        dropped,
        iterations,
    };
    finish(config, frames, &nominal, fit)
}

/// A converged adjustment over the frames kept.
struct Fit {
    /// The frames kept (indices into the frames given).
    used: Vec<usize>,
    /// Their centres (frame indices into `used`).
    observations: Vec<Observation>,
    /// The adjustment.
    bundle: bundle::Bundle,
    /// Frames skipped or dropped, with why.
    dropped: Vec<SkippedFrame>,
    /// Levenberg–Marquardt iterations over every refit.
    iterations: usize,
}

/// The gauge, the covariance, the checks and the summary of a converged
/// adjustment.
fn finish(
    config: &CharacteriseConfig,
    frames: &[FrameCentres],
    nominal: &[Vector3<f64>],
    fit: Fit,
) -> Result<Characterisation, CharacteriseError> {
    let Fit {
        used,
        observations,
        bundle,
        dropped,
        iterations,
    } = fit;
    let (used, observations) = (&used[..], &observations[..]);
    let focal_px = 0.5 * (config.camera.fx() + config.camera.fy());
    let spheres = nominal.len();
    let distances = config.resolve_distances()?;
    let Gauged {
        shape,
        poses,
        factor,
    } = in_gauge(&bundle, nominal, &distances)?;
    let information = shape_information(&shape, &poses, observations, &bundle.weights)?;
    check_observed(&information, &config.nominal)?;
    // σ² of a centre per axis, normalised units, from the weighted residuals.
    let dof = (2 * observations.len()).saturating_sub(3 * spheres + 6 * poses.len() - 7);
    let weighted: f64 = bundle
        .residuals
        .iter()
        .zip(&bundle.weights)
        .map(|(r, w)| w * r.norm_squared())
        .sum();
    let sigma_squared = weighted / dof.max(1) as f64;
    let covariance =
        shape_covariance(&information, &shape, sigma_squared, &distances).ok_or_else(|| {
            CharacteriseError::Unobserved("the information matrix is singular".into())
        })?;
    check_distances(&shape, &covariance, &distances, &config.nominal)?;
    let blocks: Vec<Matrix3<f64>> = (0..spheres)
        .map(|i| covariance.fixed_view::<3, 3>(3 * i, 3 * i).into_owned())
        .collect();
    let (sigma_axes_mm, weakest_direction): (Vec<[f64; 3]>, Vec<[f64; 3]>) =
        blocks.iter().map(principal_sigma).unzip();
    let frame_fits = frame_fits(
        frames,
        used,
        observations,
        &bundle.residuals,
        &poses,
        focal_px,
    );
    let rms = (bundle
        .residuals
        .iter()
        .map(|r| r.norm_squared())
        .sum::<f64>()
        / observations.len() as f64)
        .sqrt()
        * focal_px;
    let characterisation = Characterisation {
        nominal: config.nominal.name.clone(),
        names: config
            .nominal
            .points
            .iter()
            .map(|p| p.name.clone())
            .collect(),
        nominal_mm: nominal.iter().map(|x| [x.x, x.y, x.z]).collect(),
        measured_mm: shape.iter().map(|x| [x.x, x.y, x.z]).collect(),
        correction_mm: shape
            .iter()
            .zip(nominal)
            .map(|(x, n)| [x.x - n.x, x.y - n.y, x.z - n.z])
            .collect(),
        covariance_mm2: blocks
            .iter()
            .map(|b| std::array::from_fn(|r| std::array::from_fn(|c| b[(r, c)])))
            .collect(),
        sigma_axes_mm,
        weakest_direction,
        frames: frame_fits,
        dropped,
        centres: observations.len(),
        residual_rms_px: rms,
        sigma_px: sigma_squared.sqrt() * focal_px,
        scale: ScaleSource {
            source: if distances.is_empty() {
                "nominal"
            } else {
                "distances"
            },
            factor,
            distances: config
                .distances
                .iter()
                .zip(&distances)
                .map(|(named, d)| DistanceFit {
                    measured: named.clone(),
                    characterised_mm: d.in_shape(&shape),
                    nominal_mm: d.in_shape(nominal),
                })
                .collect(),
        },
        iterations,
        max_sigma_mm: config.max_sigma_mm,
    };
    let (worst, sigma_mm) = characterisation.worst_sigma();
    if sigma_mm > config.max_sigma_mm {
        let observed = plan::Observed {
            shape: &shape,
            poses: &poses,
            observations,
            weights: &bundle.weights,
            sigma_squared,
            distances: &distances,
        };
        let add_views = plan::views_to_add(
            &config.nominal,
            &config.camera,
            config.max_sigma_mm,
            &observed,
        );
        return Err(CharacteriseError::TooUncertain {
            sphere: characterisation.names[worst].clone(),
            sigma_mm,
            max_sigma_mm: config.max_sigma_mm,
            direction: characterisation.weakest_direction[worst],
            add_views,
        });
    }
    Ok(characterisation)
}

/// The adjusted shape and poses in the reported gauge, and the scale
/// relative to the nominal's.
struct Gauged {
    shape: Vec<Vector3<f64>>,
    poses: Vec<Pose>,
    factor: f64,
}

/// The adjusted shape and poses in the reported gauge: overlaid on the
/// nominal by a similarity, then, with distances, scaled to fit them and
/// overlaid again by a rigid motion; with the scale relative to the
/// nominal's.
fn in_gauge(
    bundle: &bundle::Bundle,
    nominal: &[Vector3<f64>],
    distances: &[Distance],
) -> Result<Gauged, CharacteriseError> {
    let overlay = Similarity::onto(&bundle.shape, nominal);
    let shape = overlay.apply_all(&bundle.shape);
    let poses: Vec<Pose> = bundle.poses.iter().map(|p| overlay.carry_pose(p)).collect();
    if distances.is_empty() {
        return Ok(Gauged {
            shape,
            poses,
            factor: 1.0,
        });
    }
    let factor = distance_scale(&shape, distances);
    if (factor - 1.0).abs() > MAX_SCALE_CHANGE {
        return Err(CharacteriseError::Distance(format!(
            "the distances make the part {:+.2}% the nominal's size, beyond the ±{}% a print shrinks or grows; check the spheres' names and the values",
            100.0 * (factor - 1.0),
            100.0 * MAX_SCALE_CHANGE
        )));
    }
    let scaling = Similarity {
        scale: factor,
        rotation: nalgebra::Rotation3::identity(),
        translation: Vector3::zeros(),
    };
    let scaled = scaling.apply_all(&shape);
    let rigid = Similarity::rigid_onto(&scaled, nominal);
    let poses = poses
        .iter()
        .map(|p| rigid.carry_pose(&scaling.carry_pose(p)))
        .collect();
    Ok(Gauged {
        shape: rigid.apply_all(&scaled),
        poses,
        factor,
    })
}

/// The principal 1σ of a 3×3 covariance, largest first, and the largest's
/// direction.
fn principal_sigma(block: &Matrix3<f64>) -> ([f64; 3], [f64; 3]) {
    let eigen = block.symmetric_eigen();
    let mut order = [0, 1, 2];
    order.sort_by(|&a, &b| eigen.eigenvalues[b].total_cmp(&eigen.eigenvalues[a]));
    let sigma = order.map(|k| eigen.eigenvalues[k].max(0.0).sqrt());
    let mut direction = eigen.eigenvectors.column(order[0]).into_owned();
    // A sign that reads the same on every run: largest component positive.
    let largest = direction.iamax();
    if direction[largest] < 0.0 {
        direction = -direction;
    }
    (sigma, [direction.x, direction.y, direction.z])
}

/// Refuses when the reduced information has more null directions than the
/// seven of the gauge.
fn check_observed(information: &DMatrix<f64>, nominal: &Layout) -> Result<(), CharacteriseError> {
    let eigen = information.clone().symmetric_eigen();
    let mut values: Vec<(f64, usize)> = eigen
        .eigenvalues
        .iter()
        .enumerate()
        .map(|(k, &v)| (v, k))
        .collect();
    values.sort_by(|a, b| a.0.total_cmp(&b.0));
    let largest = values.last().map_or(0.0, |v| v.0);
    let (eighth, column) = values.get(7).copied().unwrap_or((largest, 0));
    if eighth.is_nan() || eighth <= UNOBSERVED_RATIO * largest {
        let vector = eigen.eigenvectors.column(column);
        let (sphere, _) = (0..nominal.points.len())
            .map(|i| (i, vector.fixed_rows::<3>(3 * i).norm()))
            .fold((0, 0.0), |best, x| if x.1 > best.1 { x } else { best });
        let direction = vector.fixed_rows::<3>(3 * sphere).normalize();
        return Err(CharacteriseError::Unobserved(format!(
            "sphere {} moves along ({:.2}, {:.2}, {:.2}) unseen by any frame",
            nominal.points[sphere].name, direction.x, direction.y, direction.z
        )));
    }
    Ok(())
}

/// Smallest eigenvalue beyond the gauge's, relative to the largest, that
/// counts as observed.
const UNOBSERVED_RATIO: f64 = 1e-12;

/// With two or more distances, each against the scale the rest and the
/// images give.
fn check_distances(
    shape: &[Vector3<f64>],
    covariance: &DMatrix<f64>,
    distances: &[Distance],
    nominal: &Layout,
) -> Result<(), CharacteriseError> {
    if distances.len() < 2 {
        return Ok(());
    }
    for d in distances {
        let length = d.in_shape(shape);
        let unit = (shape[d.first] - shape[d.second]) / length;
        // Variance of the shape's distance along the pair.
        let mut variance = 0.0;
        for (a, sa) in [(d.first, 1.0), (d.second, -1.0)] {
            for (b, sb) in [(d.first, 1.0), (d.second, -1.0)] {
                let block = covariance.fixed_view::<3, 3>(3 * a, 3 * b);
                variance += sa * sb * (unit.transpose() * block * unit)[0];
            }
        }
        let disagreement = (d.mm - length) / (d.sigma_mm.powi(2) + variance).sqrt();
        if disagreement.abs() > MAX_DISTANCE_DISAGREEMENT_SIGMA {
            return Err(CharacteriseError::Distance(format!(
                "distance {}:{} = {} mm disagrees with the others and the images, which make it {length:.4} mm ({disagreement:+.1}σ); check it",
                nominal.points[d.first].name, nominal.points[d.second].name, d.mm
            )));
        }
    }
    Ok(())
}

/// Each used frame's fit.
fn frame_fits(
    frames: &[FrameCentres],
    used: &[usize],
    observations: &[Observation],
    residuals: &[Vector2<f64>],
    poses: &[Pose],
    focal_px: f64,
) -> Vec<FrameFit> {
    let mut sums = vec![(0.0, 0usize); used.len()];
    for (o, r) in observations.iter().zip(residuals) {
        sums[o.frame].0 += r.norm_squared();
        sums[o.frame].1 += 1;
    }
    used.iter()
        .zip(&sums)
        .zip(poses)
        .map(|((&f, &(sum, n)), pose)| {
            let rvec = pose.rotation.scaled_axis();
            FrameFit {
                frame: frames[f].name.clone(),
                centres: n,
                rms_px: (sum / n.max(1) as f64).sqrt() * focal_px,
                rvec: [rvec.x, rvec.y, rvec.z],
                tvec: [pose.translation.x, pose.translation.y, pose.translation.z],
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Rotation3;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;
    use rand_distr::StandardNormal;

    fn nominal() -> Layout {
        Layout::paper_biprism()
    }

    /// The nominal displaced by up to ±0.2 mm per coordinate.
    fn printed(rng: &mut ChaCha8Rng) -> Vec<Vector3<f64>> {
        nominal()
            .positions()
            .iter()
            .map(|x| x + Vector3::from_fn(|_, _| rng.random_range(-0.2..0.2)))
            .collect()
    }

    /// Frames turned about two axes at 450 mm, centres with `sigma_px` of
    /// Gaussian noise; the poses to start from are the true ones.
    fn frames(
        part: &[Vector3<f64>],
        tilts: &[(f64, f64)],
        sigma_px: f64,
        rng: &mut ChaCha8Rng,
    ) -> Vec<FrameCentres> {
        let sigma = sigma_px / Camera::paper().fx();
        tilts
            .iter()
            .enumerate()
            .map(|(k, &(tilt, pan))| {
                let rotation =
                    Rotation3::from_euler_angles(tilt.to_radians(), pan.to_radians(), 0.3);
                let pose = Pose::new(rotation, Vector3::new(0.0, 0.0, 450.0));
                let centres = part
                    .iter()
                    .enumerate()
                    .map(|(i, x)| {
                        let noise =
                            Vector2::new(rng.sample(StandardNormal), rng.sample(StandardNormal));
                        (i, pose.project_normalised(x) + noise * sigma)
                    })
                    .collect();
                FrameCentres {
                    name: format!("f{k}"),
                    pose,
                    centres,
                }
            })
            .collect()
    }

    fn grid() -> Vec<(f64, f64)> {
        [-30.0, -15.0, 0.0, 15.0, 30.0]
            .iter()
            .flat_map(|&t| [-30.0, 0.0, 30.0].map(|p| (t, p)))
            .collect()
    }

    #[test]
    fn distances_parse_and_refuse_with_the_reason() {
        let d: NamedDistance = "P1:P4=100.03".parse().unwrap();
        assert_eq!(
            (d.first.as_str(), d.second.as_str(), d.mm),
            ("P1", "P4", 100.03)
        );
        assert_eq!(d.sigma_mm, DEFAULT_DISTANCE_SIGMA_MM);
        let d: NamedDistance = "P1:P4=100.03±0.002".parse().unwrap();
        assert_eq!(d.sigma_mm, 0.002);
        let d: NamedDistance = "P1:P4=100+-0.5".parse().unwrap();
        assert_eq!((d.mm, d.sigma_mm), (100.0, 0.5));
        assert!("P1P4=3"
            .parse::<NamedDistance>()
            .unwrap_err()
            .contains("is not a distance"));
        assert_eq!(
            "P1:P4=-3".parse::<NamedDistance>().unwrap_err(),
            "distance P1:P4 must be a positive length in mm, got -3"
        );
        assert_eq!(
            "P1:P4=3±0".parse::<NamedDistance>().unwrap_err(),
            "the σ of distance P1:P4 must be positive, got 0"
        );
    }

    #[test]
    fn a_bad_config_names_its_field() {
        let mut config = CharacteriseConfig::new(nominal(), Camera::paper());
        config.distances = vec!["P1:P9=10".parse().unwrap()];
        let error = config.validate().unwrap_err();
        assert_eq!(error.field, "distances");
        assert!(
            error.reason.starts_with("no sphere 'P9' in layout"),
            "{}",
            error.reason
        );
        config.distances = vec!["P1:P1=10".parse().unwrap()];
        assert_eq!(
            config.validate().unwrap_err().reason,
            "P1:P1 names one sphere twice"
        );
        config.distances.clear();
        config.max_sigma_mm = 0.0;
        assert_eq!(config.validate().unwrap_err().field, "max_sigma_mm");
    }

    /// Noise-free centres give the printed part back exactly, in the gauge
    /// that overlays the nominal.
    #[test]
    fn noise_free_centres_give_the_part_back() {
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let part = printed(&mut rng);
        let frames = frames(&part, &grid(), 0.0, &mut rng);
        let config = CharacteriseConfig::new(nominal(), Camera::paper());
        let c = characterise(&config, &frames).unwrap();
        let truth = Similarity::onto(&part, &nominal().positions()).apply_all(&part);
        for (m, t) in c.measured_mm.iter().zip(&truth) {
            assert!((Vector3::from(*m) - t).norm() < 1e-7, "{m:?} vs {t}");
        }
        assert_eq!(c.frames.len(), 15);
        assert!(c.dropped.is_empty());
    }

    /// Under Gaussian noise the reported covariance is honest: the mean
    /// normalised squared error over spheres and seeds is near its 3
    /// degrees of freedom (the bounds hold its sampling spread over 140
    /// spheres, about ±0.4, with room).
    #[test]
    fn the_covariance_is_honest_under_gaussian_noise() {
        let mut total = 0.0;
        let mut count = 0;
        for seed in 0..20 {
            let mut rng = ChaCha8Rng::seed_from_u64(100 + seed);
            let part = printed(&mut rng);
            let frames = frames(&part, &grid(), 0.05, &mut rng);
            let config = CharacteriseConfig::new(nominal(), Camera::paper());
            let c = characterise(&config, &frames).unwrap();
            let truth = Similarity::onto(&part, &nominal().positions()).apply_all(&part);
            for ((m, t), cov) in c.measured_mm.iter().zip(&truth).zip(&c.covariance_mm2) {
                let e = Vector3::from(*m) - t;
                let cov = Matrix3::from_fn(|r, k| cov[r][k]);
                total += (e.transpose() * cov.try_inverse().unwrap() * e)[0];
                count += 1;
            }
        }
        let mean = total / count as f64;
        assert!((2.2..3.9).contains(&mean), "mean NSE {mean} over {count}");
    }

    /// A frame with two labels swapped is dropped and named; a frame with a
    /// label twice is skipped; too few frames, or frames from one
    /// direction, are refused.
    #[test]
    fn bad_frames_are_named_and_bad_sets_refused() {
        let mut rng = ChaCha8Rng::seed_from_u64(2);
        let part = printed(&mut rng);
        let mut frames = frames(&part, &grid(), 0.05, &mut rng);
        let swapped = &mut frames[4].centres;
        let (a, b) = (swapped[1].1, swapped[2].1);
        swapped[1].1 = b;
        swapped[2].1 = a;
        frames[7].centres[3].0 = 0;
        let config = CharacteriseConfig::new(nominal(), Camera::paper());
        let c = characterise(&config, &frames).unwrap();
        let dropped: Vec<&str> = c.dropped.iter().map(|d| d.frame.as_str()).collect();
        assert_eq!(dropped, ["f7", "f4"], "{:?}", c.dropped);
        assert!(
            c.dropped[0].reason.contains("labelled twice"),
            "{:?}",
            c.dropped
        );
        assert!(
            c.dropped[1].reason.contains("does not fit"),
            "{:?}",
            c.dropped
        );
        let error = characterise(&config, &frames[..5]).unwrap_err();
        assert!(
            matches!(error, CharacteriseError::TooFewFrames { usable: 5, .. }),
            "{error}"
        );
        let one_way = vec![(20.0, 10.0); 8];
        let same = self::frames(&part, &one_way, 0.05, &mut rng);
        let error = characterise(&config, &same).unwrap_err();
        assert!(
            matches!(
                error,
                CharacteriseError::TooUncertain { .. } | CharacteriseError::Unobserved(_)
            ),
            "{error}"
        );
        if let CharacteriseError::TooUncertain { add_views, .. } = &error {
            assert!(!add_views.is_empty());
        }
    }
}
