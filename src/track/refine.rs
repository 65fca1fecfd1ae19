//! Render-and-compare: the printed part's own bias on each blob centre,
//! measured on a render of the part at the tracked pose and taken off
//! (`track --refine`).
//!
//! **Why.** The detector places each edge point against the background
//! right outside the limb ([`super::detect`]). Where the part itself lies
//! behind the limb, that background is not flat: the base plate's grey,
//! the shaded cone under the sphere ringing the limb, the plate's edge
//! within a pixel of it. The edge points on such an arc move by a tenth of
//! a pixel or more, and a small disc's centre by a few hundredths: at
//! 1000 mm (13 px discs) the search winner's noise-free pose is off by up
//! to 0.019° (docs/commands.md, `track`). No model of one edge point's
//! profile sees a step inside the first pixel outside the limb; the pose
//! does, since it says where the plate and the cones lie.
//!
//! **Each round** ([`Refiner::refine`]):
//! 1. renders the part (as `export` builds it) at the current pose without
//!    noise, with the optics given and the appearance given or, by
//!    default in `track`, with the frame's own levels ("Levels");
//! 2. reads the render with the frame's own detector and centre method;
//! 3. takes as each sphere's bias the centre read there minus the exact
//!    ellipse centre at that pose ([`crate::sphere_image`]), from the
//!    render's blob nearest that centre, flagged as partly hidden or not:
//!    a flag is a threshold on a blob's figures, and a blob the frame uses
//!    may be flagged in the noise-free render (its own cone cutting a
//!    quarter of the outline at a steep tilt), where a windowed centroid
//!    left uncorrected errs by 0.3 px;
//! 4. takes each labelled unflagged blob's bias off its measured centre
//!    and locates the marker again: identification, pose and covariance.
//!
//! **Levels** ([`Refiner::with_fitted_levels`]). A render drawn with
//! levels other than the frame's (brighter supports, dimmer spheres, matte
//! spheres drawn as discs) puts its own bias on every centre. So before
//! each round's render, the levels are fitted to the frame: the render is
//! linear in the sphere's, the supports' and the background's radiance,
//! so the part is drawn three times at the pose, each of the three alone
//! at 1, and the three radiances that make the sum closest to the frame
//! over the blobs' regions (least squares, none below zero) draw the
//! render. Where most of the frame's blobs are shaded
//! ([`super::detect::Blob::shaded`]), the retroreflective look's spheres
//! are drawn as Lambertian ones. The record's `refinement.levels` gives
//! what was drawn. It costs two more renders a round.
//!
//! **The likeness check.** After the rounds, the last round's render is
//! compared with the frame around each corrected blob ([`Likeness`]: the
//! render fitted to the frame by a gain, an offset and a subpixel shift,
//! which takes up the pose's own small error, the residual against the
//! frame's own pixel noise). Where the render is unlike the frame, the look given is
//! not the camera's (another shading, other support or background levels)
//! and the bias measured on it is the wrong one: that sphere keeps its
//! measured centre and the marker is located again. The record's
//! `likeness` says, per sphere, what was found.
//!
//! A sphere with no blob in the render within its semi-major axis (it
//! merges with a neighbour there) keeps its measured centre.
//! The correction is only as good as the render's likeness to the camera:
//! the appearance, the blur and the part's supports must be the ones the
//! camera sees. Its render needs no noise, and its supersampling should
//! not be coarser than the camera's own sampling (a render's sampling
//! error moves a small disc's centre by about a hundredth of a pixel at
//! 4×4); docs/commands.md gives what a mismatch costs.

use super::analysis::{
    detect_blobs, locate, measured_normalised, FrameAnalysis, Refinement, RenderLevels, TrackError,
};
use super::config::TrackConfig;
use super::detect::{Blob, CentreBias, WINDOW_PAD_PX};
use super::frame::GreyFrame;
use super::likeness::Likeness;
use crate::config::ConfigError;
use crate::pose::{rotation_error_deg, Pose};
use crate::render::{
    expose, render_channels_within, render_radiance_within, Lighting, Radiance, RenderConfig,
    Scene, Sensor,
};
use crate::sphere_image::ellipse_centre_normalised;
use nalgebra::{Matrix3, Vector2, Vector3};

/// The most rounds of refinement.
pub const MAX_ROUNDS: u32 = 5;
/// Pixels traced around a blob beyond its ellipse, the detector's window
/// padding and the blur's reach.
pub const REGION_MARGIN_PX: f64 = 4.0;
/// Render supersampling `track --refine` uses unless told (sub-samples per
/// pixel side): finer than `render`'s default 4, whose own sampling error
/// would otherwise show in the correction.
pub const DEFAULT_SUPERSAMPLING: u32 = 8;

/// Renders the part and measures the bias of each centre (module docs).
#[derive(Debug, Clone)]
pub struct Refiner {
    scene: Scene,
    render: RenderConfig,
    rounds: u32,
    fit_levels: bool,
}

impl Refiner {
    /// A refiner drawing `scene` with `render`'s camera, appearance and
    /// optics (its sensor is replaced by a noise-free 16-bit one), for
    /// `rounds` rounds. The camera must be the tracker's.
    pub fn new(scene: Scene, mut render: RenderConfig, rounds: u32) -> Result<Self, ConfigError> {
        render.sensor = Sensor {
            bit_depth: 16,
            noise: None,
        };
        render.realisations = 1;
        render.validate()?;
        if !(1..=MAX_ROUNDS).contains(&rounds) {
            return Err(ConfigError::new(
                "refine_rounds",
                format!("must lie in 1..{MAX_ROUNDS}, got {rounds}"),
            ));
        }
        Ok(Refiner {
            scene,
            render,
            rounds,
            fit_levels: false,
        })
    }

    /// The refiner drawing the part with the levels of each frame, fitted
    /// before each round's render (module docs, "Levels"), instead of the
    /// appearance's.
    pub fn with_fitted_levels(mut self, fit: bool) -> Self {
        self.fit_levels = fit;
        self
    }

    /// Checks that the part is rendered through `config`'s camera (the
    /// frames').
    pub fn check(&self, config: &TrackConfig) -> Result<(), ConfigError> {
        if self.render.camera == config.camera {
            Ok(())
        } else {
            Err(ConfigError::new(
                "refine",
                "the refinement renders through another camera than the frames'",
            ))
        }
    }

    /// The part rendered at `pose` (noise-free, 16 bit), traced only
    /// around the frame's `blobs` (their ellipse's box, grown by the
    /// detector's window padding, the blur's reach and
    /// [`REGION_MARGIN_PX`]): a blob's centre depends on no pixel beyond.
    /// With fitted levels ([`Refiner::with_fitted_levels`]), drawn with the
    /// levels of `frame` there; and the levels it was drawn with.
    pub fn render_around(
        &self,
        config: &TrackConfig,
        pose: &Pose,
        blobs: &[Blob],
        frame: &GreyFrame,
    ) -> Result<(GreyFrame, RenderLevels), String> {
        let camera = &config.camera;
        let blur = self
            .render
            .optics
            .blur
            .sigma_px(camera.fx(), pose.translation.z);
        let grow = WINDOW_PAD_PX as f64 + (3.0 * blur).ceil() + REGION_MARGIN_PX;
        let (width, height) = (camera.width() as f64, camera.height() as f64);
        let regions: Vec<(usize, usize, usize, usize)> = blobs
            .iter()
            .map(|b| {
                let reach = b.semi_axes_px[0] + grow;
                let [u, v] = b.ellipse_centre_px;
                let at = |value: f64, size: f64| value.clamp(0.0, size) as usize;
                (
                    at(u - reach, width),
                    at(v - reach, height),
                    at(u + reach + 1.0, width),
                    at(v + reach + 1.0, height),
                )
            })
            .collect();
        let fitted = if self.fit_levels {
            self.fitted(pose, blobs, &regions, frame)?
        } else {
            None
        };
        let (radiance, levels) = match fitted {
            Some(fitted) => fitted,
            None => {
                let appearance = &self.render.appearance;
                (
                    render_radiance_within(&self.scene, pose, &self.render, Some(&regions))
                        .map_err(|e| e.to_string())?,
                    RenderLevels {
                        sphere: appearance.sphere_radiance * appearance.exposure,
                        support: appearance.support_radiance * appearance.exposure,
                        background: appearance.background_radiance * appearance.exposure,
                        shading: appearance.lighting.name(),
                        fitted: false,
                    },
                )
            }
        };
        let digital = expose(&radiance, &self.render.sensor, 0, 0, 0);
        let render = GreyFrame::new(
            digital.width as u32,
            digital.height as u32,
            digital.bit_depth,
            digital.values,
        )
        .map_err(|e| e.to_string())?;
        Ok((render, levels))
    }

    /// The part's radiance at `pose` within `regions`, with the levels of
    /// `frame` there (module docs, "Levels"): the retroreflective look's
    /// spheres shaded as Lambertian ones where most of the frame's `blobs`
    /// are shaded, and
    /// the sphere's, the supports' and the background's radiances fitted
    /// to the frame's pixels by least squares over the renders of each
    /// alone (the render is linear in each), traced in one pass
    /// ([`render_channels_within`]). `None` where the fit is
    /// degenerate (no sphere radiance above zero, or too few pixels): the
    /// appearance given stands then.
    fn fitted(
        &self,
        pose: &Pose,
        blobs: &[Blob],
        regions: &[(usize, usize, usize, usize)],
        frame: &GreyFrame,
    ) -> Result<Option<(Radiance, RenderLevels)>, String> {
        let mut base = self.render.clone();
        let shaded = 2 * blobs.iter().filter(|b| b.shaded).count() > blobs.len();
        if shaded && base.appearance.lighting == Lighting::Retroreflective {
            base.appearance.lighting = Lighting::Lambertian;
            base.appearance.sphere_limb_falloff = 1.0;
            base.appearance.ambient = 0.0;
        }
        base.appearance.exposure = 1.0;
        let parts = render_channels_within(&self.scene, pose, &base, Some(regions))
            .map_err(|e| e.to_string())?;
        let width = parts[0].width;
        if (frame.width() as usize, frame.height() as usize) != (width, parts[0].height) {
            return Ok(None);
        }
        let full_scale = f64::from(frame.full_scale());
        let mut seen = vec![false; parts[0].values.len()];
        let (mut normal, mut right, mut count) = (Matrix3::zeros(), Vector3::zeros(), 0usize);
        for &(x0, y0, x1, y1) in regions {
            for y in y0..y1 {
                for x in x0..x1 {
                    let i = y * width + x;
                    if std::mem::replace(&mut seen[i], true) {
                        continue;
                    }
                    let row = Vector3::from_fn(|k, _| f64::from(parts[k].values[i]));
                    normal += row * row.transpose();
                    right += row * (f64::from(frame.pixels()[i]) / full_scale);
                    count += 1;
                }
            }
        }
        // A ridge a billionth of the mean diagonal: where a part does not
        // show in the regions (no support behind any limb), its level
        // comes out zero instead of leaving the fit undetermined.
        let ridge = 1e-9 * normal.trace() / 3.0;
        normal += Matrix3::identity() * ridge;
        let Some(levels) = (count >= 3 && ridge > 0.0)
            .then(|| normal.cholesky())
            .flatten()
        else {
            return Ok(None);
        };
        let levels = levels.solve(&right).map(|v| v.max(0.0));
        if !(levels.x > 0.0 && levels.iter().all(|v| v.is_finite())) {
            return Ok(None);
        }
        let values = (0..parts[0].values.len())
            .map(|i| {
                (0..3)
                    .map(|k| levels[k] * f64::from(parts[k].values[i]))
                    .sum::<f64>() as f32
            })
            .collect();
        Ok(Some((
            Radiance {
                width,
                height: parts[0].height,
                values,
            },
            RenderLevels {
                sphere: levels.x,
                support: levels.y,
                background: levels.z,
                shading: base.appearance.lighting.name(),
                fitted: true,
            },
        )))
    }

    /// For each sphere of `config`'s layout, the bias of `config`'s centre
    /// method at `pose`, read on `render` ([`Refiner::render_around`] at
    /// that pose); `None` where the render shows no blob of it.
    pub fn biases(
        &self,
        config: &TrackConfig,
        pose: &Pose,
        render: &GreyFrame,
    ) -> Result<Vec<Option<CentreBias>>, String> {
        let camera = &config.camera;
        let detection = detect_blobs(config, render).map_err(|e| format!("the render: {e}"))?;
        let radius = config.radius_mm();
        let biases = config
            .object
            .iter()
            .map(|p| {
                let exact = ellipse_centre_normalised(&pose.transform(p), radius).ok()?;
                let exact_px = camera.normalised_to_pixel(&exact);
                let blob = detection
                    .blobs
                    .iter()
                    .map(|b| (b, (Vector2::from(b.ellipse_centre_px) - exact_px).norm()))
                    .filter(|(b, distance)| *distance < b.semi_axes_px[0])
                    .min_by(|a, b| a.1.total_cmp(&b.1))?
                    .0;
                let measured = measured_normalised(blob, config.centre);
                let measured_px = camera.normalised_to_pixel(&measured);
                Some(CentreBias {
                    px: (measured_px - exact_px).into(),
                    normalised: measured - exact,
                    disagreement_px: (Vector2::from(blob.window_centroid_px)
                        - Vector2::from(blob.ellipse_centre_px))
                    .into(),
                })
            })
            .collect();
        Ok(biases)
    }

    /// `analysis` refined (module docs); a frame without a pose is
    /// returned as it is, and one whose render or second location fails
    /// gets [`TrackError::Refine`].
    pub fn refine(
        &self,
        config: &TrackConfig,
        frame: &GreyFrame,
        analysis: FrameAnalysis,
    ) -> FrameAnalysis {
        let FrameAnalysis {
            outcome: Ok(_),
            detection: Some(mut detection),
            pose: Some(first),
        } = analysis
        else {
            return analysis;
        };
        let failed = |detection, reason: String| FrameAnalysis {
            outcome: Err(TrackError::Refine(reason)),
            detection: Some(detection),
            pose: None,
        };
        let mut pose = first;
        let mut tracked = None;
        let mut last = None;
        for _ in 0..self.rounds {
            let around = whole_labelled(&detection.blobs);
            let measured =
                self.render_around(config, &pose, &around, frame)
                    .and_then(|(render, levels)| {
                        Ok((self.biases(config, &pose, &render)?, render, levels))
                    });
            let (biases, render, levels) = match measured {
                Ok(measured) => measured,
                Err(reason) => return failed(detection, reason),
            };
            last = Some((around, render, levels));
            for blob in &mut detection.blobs {
                blob.bias = blob
                    .label
                    .filter(|_| !blob.hidden())
                    .and_then(|k| biases[k]);
                blob.label = None;
            }
            match locate(config, &mut detection.blobs, &detection.rejected) {
                Ok(located) => (tracked, pose) = (Some(located.0), located.1),
                Err(error) => {
                    return failed(detection, format!("after the correction: {error}"));
                }
            }
        }
        // The likeness check: the last round's render against the frame,
        // sphere by sphere. Where it is unlike the frame, the look given
        // is not the camera's and the bias measured on it is the wrong
        // one: that sphere keeps its measured centre, and the marker is
        // located again.
        let (around, render, levels) = last.expect("at least one round");
        let mut likeness = vec![None; config.object.len()];
        for blob in &around {
            if let Some(k) = blob.label {
                likeness[k] = Likeness::around(frame, &render, blob);
            }
        }
        let unlike = |blob: &Blob| {
            blob.bias.is_some()
                && blob
                    .label
                    .is_some_and(|k| !likeness[k].is_some_and(|l| l.matches()))
        };
        if detection.blobs.iter().any(unlike) {
            for blob in &mut detection.blobs {
                if unlike(blob) {
                    blob.bias = None;
                }
                blob.label = None;
            }
            match locate(config, &mut detection.blobs, &detection.rejected) {
                Ok(located) => (tracked, pose) = (Some(located.0), located.1),
                Err(error) => {
                    return failed(detection, format!("after the likeness check: {error}"));
                }
            }
        }
        let mut tracked = tracked.expect("at least one round");
        let mut bias_px = vec![None; config.object.len()];
        for blob in &detection.blobs {
            if let (Some(k), Some(bias)) = (blob.label, blob.bias) {
                bias_px[k] = Some(bias.px);
            }
        }
        tracked.refinement = Some(Refinement {
            rounds: self.rounds,
            levels,
            bias_px,
            likeness,
            rotation_change_deg: rotation_error_deg(&first.rotation, &pose.rotation),
            translation_change_mm: (first.translation - pose.translation).norm(),
        });
        FrameAnalysis {
            outcome: Ok(tracked),
            detection: Some(detection),
            pose: Some(pose),
        }
    }
}

/// The whole labelled blobs of a frame: those the refinement corrects.
fn whole_labelled(blobs: &[Blob]) -> Vec<Blob> {
    blobs
        .iter()
        .filter(|b| b.label.is_some() && !b.hidden())
        .cloned()
        .collect()
}
