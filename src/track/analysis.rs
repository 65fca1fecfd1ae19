//! One frame in, one labelled pose with its uncertainty out: detection
//! ([`super::detect`]), identification (the unlabelled solver,
//! [`crate::pnp::unlabelled`]), the pose (`ml` on the exact sphere-image
//! model, or the chosen solver on the projected sphere centres) and its
//! first-order covariance ([`super::uncertainty`]). No files, no printing.
//!
//! **Which blobs.** Blobs flagged as partly hidden are left out of the
//! identification and the pose (a blob whose notch the detector cut away,
//! measured from the rest of its outline, is not flagged and is used;
//! [`super::detect`]); after the pose each is given the label of
//! the nearest unclaimed model ellipse within its semi-major axis, so the
//! output says which sphere it was. With more usable blobs than spheres
//! (clutter, at most `max_extra_blobs`), every subset of as many blobs as
//! spheres is identified and the one whose labelling fits best wins; when
//! no subset yields a consistent labelling, subsets with one blob fewer
//! (one sphere missing) are tried.
//!
//! **Identification input.** The unlabelled solver fits projected points,
//! so it is given each blob's projected sphere centre (`m₀ / (1 + b²)`,
//! [`super::conic`]): exact for whole spheres, with no ellipse-centre bias.

use super::config::{CentreMethod, TrackConfig};
use super::detect::{detect, Blob, DetectError, Detection, Rejected};
use super::frame::{FrameError, GreyFrame};
use super::uncertainty::{
    model_pixel, pose_figures, wrong_label_probability, CentreEvidence, FiguresError,
    MismatchShares, SigmaChoice,
};
use crate::pnp::unlabelled::{identify, Identification, LabellingError, UnlabelledOptions};
use crate::pnp::{ml_sphere, Solver};
use crate::pose::Pose;
use nalgebra::{Vector2, Vector3};
use serde::Serialize;

/// Why a frame has no pose.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum TrackError {
    /// The file is not a usable frame.
    #[error(transparent)]
    Frame(#[from] FrameError),
    /// The detector gave up.
    #[error(transparent)]
    Detect(#[from] DetectError),
    /// No blob passed the detector.
    #[error("no blobs found ({} components rejected: {} too small, {} too large, {} too faint, {} not sphere-shaped)", .0.small + .0.large + .0.contrast + .0.shape, .0.small, .0.large, .0.contrast, .0.shape)]
    NoBlobs(Rejected),
    /// Too few whole blobs to identify the marker.
    #[error("too few blobs: {usable} whole blob(s) ({hidden} more flagged as partly hidden) for {spheres} spheres; at least {needed} are needed")]
    TooFewBlobs {
        /// Whole blobs.
        usable: usize,
        /// Blobs flagged as partly hidden.
        hidden: usize,
        /// Spheres of the layout.
        spheres: usize,
        /// Blobs needed.
        needed: usize,
    },
    /// More blobs than spheres plus the clutter allowed.
    #[error("too many blobs: {found} whole blobs for {spheres} spheres, more than the {max_extra} extra allowed (--max-extra-blobs)")]
    TooManyBlobs {
        /// Whole blobs.
        found: usize,
        /// Spheres of the layout.
        spheres: usize,
        /// Extra blobs allowed.
        max_extra: usize,
    },
    /// No labelling fits the blobs.
    #[error("identification failed: {0}")]
    Identification(LabellingError),
    /// The labels cannot be trusted.
    #[error("ambiguous identification: another labelling fits almost as well (ambiguity {ambiguity:.3}); the labels are wrong with probability {probability:.2e}, above {max:.0e}")]
    Ambiguous {
        /// Runner-up RMS over best RMS.
        ambiguity: f64,
        /// Predicted probability that the labels are wrong.
        probability: f64,
        /// The largest accepted.
        max: f64,
    },
    /// The final fit failed.
    #[error("labels found, but the final fit failed: {0}")]
    Pose(String),
    /// The covariance could not be computed.
    #[error(transparent)]
    Figures(#[from] FiguresError),
    /// The render-and-compare refinement ([`super::refine`]) failed.
    #[error("refinement failed: {0}")]
    Refine(String),
}

/// A tracked frame (docs/formats.md, "`track` output").
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TrackedFrame {
    /// For each blob (in `blobs` order), its sphere index, or `null`.
    pub labels: Vec<Option<usize>>,
    /// Runner-up RMS over best RMS of the identification; `null` when no
    /// other labelling is consistent.
    pub ambiguity: Option<f64>,
    /// Predicted probability that the labels are wrong.
    pub wrong_label_probability: f64,
    /// Rotation, object → camera, row-major.
    #[serde(rename = "R")]
    pub rotation: [[f64; 3]; 3],
    /// Translation, mm.
    pub t: [f64; 3],
    /// rvec, tvec, residuals (per sphere), σ and covariance.
    #[serde(flatten)]
    pub figures: FramedFigures,
    /// Spheres of the layout that no whole blob was matched to.
    pub missing: Vec<usize>,
    /// RMS of the residuals, px.
    pub reprojection_rms_px: f64,
    /// What the render-and-compare refinement did ([`super::refine`]);
    /// `None` (and absent from the JSON) without it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub refinement: Option<Refinement>,
}

/// What the render-and-compare refinement ([`super::refine`]) did to a
/// frame (docs/formats.md, "`track` output").
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Refinement {
    /// Rounds run.
    pub rounds: u32,
    /// The levels the last round drew the part with.
    pub levels: RenderLevels,
    /// For each sphere of the layout, the bias taken off its centre in the
    /// last round, raw px; `null` where none was (not in the pose, or not
    /// whole in the render).
    pub bias_px: Vec<Option<[f64; 2]>>,
    /// For each sphere of the layout, how far the last round's render
    /// departs from the frame around its blob ([`super::likeness::Likeness`]);
    /// a sphere's bias is taken off only where the render matches.
    /// `null` where no whole labelled blob was compared.
    pub likeness: Vec<Option<super::likeness::Likeness>>,
    /// Rotation between the first pose and the refined one, degrees.
    pub rotation_change_deg: f64,
    /// Distance between their translations, mm.
    pub translation_change_mm: f64,
}

/// The levels a refinement's last round drew the part with
/// ([`super::refine`], "Levels"): fitted to the frame or as given;
/// radiances as fractions of full scale.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct RenderLevels {
    /// The spheres' radiance (where a shaded sphere faces the camera).
    pub sphere: f64,
    /// The supports' (plate, pillars, cones) radiance.
    pub support: f64,
    /// The background's radiance.
    pub background: f64,
    /// The spheres' shading law: the look's name (`retroreflective`,
    /// `lambertian` or `diffuse`).
    pub shading: &'static str,
    /// Whether the levels were fitted to the frame.
    pub fitted: bool,
}

/// [`super::uncertainty::PoseFigures`] with residuals per sphere.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FramedFigures {
    /// OpenCV's rotation vector, rad.
    pub rvec: [f64; 3],
    /// OpenCV's tvec, mm.
    pub tvec: [f64; 3],
    /// For each sphere of the layout, measured minus model centre, px;
    /// `null` for a sphere not in the pose.
    pub residuals_px: Vec<Option<[f64; 2]>>,
    /// σ of the covariance, px (from the blobs: the RMS of each centre's
    /// own σ and the shared one together).
    pub sigma_px: f64,
    /// Where σ came from.
    pub sigma_source: super::uncertainty::SigmaSource,
    /// From the blobs ([`super::uncertainty`]): for each sphere of the
    /// layout, its centre's own σ, px; `null` for a sphere not in the pose.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub centre_sigma_px: Option<Vec<Option<f64>>>,
    /// From the blobs: the σ every centre shares, px.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sigma_shared_px: Option<f64>,
    /// From the blobs: how much the pose's residuals grew the centres'
    /// noise (1: not at all).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub residual_inflation: Option<f64>,
    /// Covariance of (rvec rad, tvec mm), 6×6.
    pub covariance: [[f64; 6]; 6],
    /// 1σ rotation, degrees.
    pub sigma_rot_deg: f64,
    /// 1σ translation, mm.
    pub sigma_trans_mm: f64,
}

/// One frame's outcome with what the detector saw.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameAnalysis {
    /// The pose, or why there is none.
    pub outcome: Result<TrackedFrame, TrackError>,
    /// The detection (None when the frame could not be read or the
    /// detector gave up).
    pub detection: Option<Detection>,
    /// The pose itself (for overlays), when there is one.
    pub pose: Option<Pose>,
}

/// Reads PNG bytes and tracks the frame.
pub fn analyse_png(config: &TrackConfig, bytes: &[u8]) -> FrameAnalysis {
    match GreyFrame::from_png_of_size(bytes, config.camera.width(), config.camera.height()) {
        Ok(frame) => analyse(config, &frame),
        Err(error) => FrameAnalysis {
            outcome: Err(error.into()),
            detection: None,
            pose: None,
        },
    }
}

/// The most blobs the detector accepts in a frame of `spheres` spheres
/// with `extra` clutter blobs allowed, before it gives up on the frame.
pub(super) fn max_blobs(spheres: usize, extra: usize) -> usize {
    (spheres + extra) * 4 + 16
}

/// The blobs of `frame` by `config`'s detector, for `config`'s marker.
pub(super) fn detect_blobs(
    config: &TrackConfig,
    frame: &GreyFrame,
) -> Result<Detection, DetectError> {
    detect(
        frame,
        &config.camera,
        &config.detector,
        config.radius_mm(),
        max_blobs(config.object.len(), config.max_extra_blobs),
    )
}

/// Tracks one frame (module docs). `config` must have been validated.
pub fn analyse(config: &TrackConfig, frame: &GreyFrame) -> FrameAnalysis {
    analyse_timed(config, frame).0
}

/// How long the two steps of [`analyse`] took on one frame.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct StageTimes {
    /// Threshold, components, blob figures and centres.
    pub detect: std::time::Duration,
    /// Identification, the pose and its covariance.
    pub solve: std::time::Duration,
}

/// [`analyse`], with the time each step took (a stream's latency).
pub fn analyse_timed(config: &TrackConfig, frame: &GreyFrame) -> (FrameAnalysis, StageTimes) {
    let start = std::time::Instant::now();
    let detected = detect_blobs(config, frame);
    let mut times = StageTimes {
        detect: start.elapsed(),
        ..StageTimes::default()
    };
    let mut detection = match detected {
        Ok(detection) => detection,
        Err(error) => {
            let analysis = FrameAnalysis {
                outcome: Err(error.into()),
                detection: None,
                pose: None,
            };
            return (analysis, times);
        }
    };
    let located = locate(config, &mut detection.blobs, &detection.rejected);
    times.solve = start.elapsed() - times.detect;
    let analysis = match located {
        Ok((tracked, pose)) => FrameAnalysis {
            outcome: Ok(tracked),
            detection: Some(detection),
            pose: Some(pose),
        },
        Err(error) => FrameAnalysis {
            outcome: Err(error),
            detection: Some(detection),
            pose: None,
        },
    };
    (analysis, times)
}

/// The measured centre of a blob, normalised, by the configured method,
/// less its bias where the refinement measured one.
pub(super) fn measured_normalised(blob: &Blob, method: CentreMethod) -> Vector2<f64> {
    let raw = match method {
        CentreMethod::Ellipse => blob.ellipse_centre_normalised,
        CentreMethod::Centroid => blob.centroid_normalised,
        CentreMethod::Window => blob.window_centroid_normalised,
    };
    raw - blob.bias.map_or(Vector2::zeros(), |b| b.normalised)
}

/// The projected sphere centre of a blob on the undistorted normalised
/// plane: its centre by `method`, less the refinement's bias where there
/// is one, over `1 + b²` ([`Blob::centre_shrink`]); what identification
/// and the centre solvers fit.
pub fn projected_centre_normalised(blob: &Blob, method: CentreMethod) -> Vector2<f64> {
    measured_normalised(blob, method) / blob.centre_shrink
}

/// The silhouette's ellipse centre of a shaded blob, normalised, for its
/// sphere centred at `centre` (camera frame, mm) of radius `radius_mm`:
/// what `ml`'s sphere model fits ([`ml_sphere`]). Under light from the
/// camera a shaded sphere's radiance is symmetric about its centre ray
/// ([`Blob::shaded`]), so its outline, a contour of the shading inside the
/// limb, is a circular cone about that ray like the silhouette but
/// narrower: its ellipse gives the projected centre `c` exactly
/// ([`projected_centre_normalised`]) but an ellipse centre nearer `c`
/// than the silhouette's (by 0.01–0.05 px at 300–550 mm, 150 px off the
/// axis). The silhouette's is `c (1 + b²)`, with `b² = r² / (|C|² − r²)`
/// its minor semi-axis on the normalised plane at the depth the pose
/// gives.
fn silhouette_centre(blob: &Blob, centre: &Vector3<f64>, radius_mm: f64) -> Vector2<f64> {
    let b2 = radius_mm.powi(2) / (centre.norm_squared() - radius_mm.powi(2)).max(f64::EPSILON);
    projected_centre_normalised(blob, CentreMethod::Ellipse) * (1.0 + b2)
}

/// For each of the `chosen` blobs, fitted to the `matched` object points,
/// its silhouette's ellipse centre at `pose` where it is shaded
/// ([`silhouette_centre`]); `None` where it is not.
fn silhouettes(
    config: &TrackConfig,
    blobs: &[Blob],
    chosen: &[usize],
    matched: &[Vector3<f64>],
    pose: &Pose,
) -> Vec<Option<Vector2<f64>>> {
    chosen
        .iter()
        .zip(matched)
        .map(|(&i, p)| {
            blobs[i]
                .shaded
                .then(|| silhouette_centre(&blobs[i], &pose.transform(p), config.radius_mm()))
        })
        .collect()
}

/// Whether the pose fits a shaded blob's silhouette centre in place of
/// its measured centre: `ml` on ellipse centres ([`silhouette_centre`]).
fn fits_silhouettes(config: &TrackConfig) -> bool {
    config.solver == Solver::Ml && config.centre == CentreMethod::Ellipse
}

/// The pose figures of the `chosen` blobs fitted to the `matched` object
/// points at `pose`: residuals of the centres the pose fitted, and the
/// covariance at `--sigma-px` or at each centre's own σ from its blob
/// ([`super::uncertainty`]; a shaded blob's disagreement is taken against
/// its silhouette's centre, whatever the centre method).
fn frame_figures(
    config: &TrackConfig,
    blobs: &[Blob],
    chosen: &[usize],
    matched: &[Vector3<f64>],
    pose: &Pose,
) -> Result<super::uncertainty::PoseFigures, TrackError> {
    let radius_mm = config.radius_mm();
    let silhouettes_px: Vec<Option<Vector2<f64>>> =
        silhouettes(config, blobs, chosen, matched, pose)
            .into_iter()
            .map(|s| s.map(|c| config.camera.normalised_to_pixel(&c)))
            .collect();
    let pixels: Vec<Vector2<f64>> = chosen
        .iter()
        .zip(&silhouettes_px)
        .map(|(&i, s)| match s {
            Some(silhouette) if fits_silhouettes(config) => *silhouette,
            _ => measured_px(&blobs[i], config.centre),
        })
        .collect();
    let evidence: Vec<CentreEvidence> = chosen
        .iter()
        .zip(&silhouettes_px)
        .map(|(&i, s)| {
            let blob = &blobs[i];
            CentreEvidence {
                noise_px: match config.centre {
                    CentreMethod::Ellipse => blob.centre_noise_px,
                    CentreMethod::Centroid | CentreMethod::Window => blob.window_noise_px,
                },
                // Refined, the render's own gap stands against the frame's,
                // both about the contour's ellipse centre.
                disagreement_px: match s {
                    Some(silhouette) if blob.bias.is_none() => blob.disagreement_with(silhouette),
                    _ => blob.disagreement_px(),
                },
                disagreement_noise_px: blob.centre_noise_px.hypot(blob.window_noise_px),
            }
        })
        .collect();
    let sigma = match config.sigma_px {
        Some(sigma) => SigmaChoice::Given(sigma),
        None => SigmaChoice::Blobs(
            &evidence,
            match config.centre {
                CentreMethod::Ellipse => MismatchShares::ELLIPSE,
                CentreMethod::Centroid | CentreMethod::Window => MismatchShares::CENTROID,
            },
        ),
    };
    Ok(pose_figures(
        &config.camera,
        pose,
        matched,
        &pixels,
        Some(radius_mm),
        sigma,
    )?)
}

/// [`measured_normalised`] in raw px.
pub(super) fn measured_px(blob: &Blob, method: CentreMethod) -> Vector2<f64> {
    let p = match method {
        CentreMethod::Ellipse => blob.ellipse_centre_px,
        CentreMethod::Centroid => blob.centroid_px,
        CentreMethod::Window => blob.window_centroid_px,
    };
    Vector2::from(p) - blob.bias.map_or(Vector2::zeros(), |b| Vector2::from(b.px))
}

/// Every `size`-subset of `0..n`, in lexicographic order.
fn subsets(n: usize, size: usize) -> Vec<Vec<usize>> {
    let mut out = Vec::new();
    let mut current: Vec<usize> = (0..size).collect();
    if size > n {
        return out;
    }
    loop {
        out.push(current.clone());
        let Some(i) = (0..size).rev().find(|&i| current[i] < n - size + i) else {
            return out;
        };
        current[i] += 1;
        for j in i + 1..size {
            current[j] = current[j - 1] + 1;
        }
    }
}

pub(super) fn locate(
    config: &TrackConfig,
    blobs: &mut [Blob],
    rejected: &Rejected,
) -> Result<(TrackedFrame, Pose), TrackError> {
    let spheres = config.object.len();
    if blobs.is_empty() {
        return Err(TrackError::NoBlobs(*rejected));
    }
    let usable: Vec<usize> = (0..blobs.len()).filter(|&i| !blobs[i].hidden()).collect();
    let hidden = blobs.len() - usable.len();
    let needed = spheres - 1;
    if usable.len() < needed {
        return Err(TrackError::TooFewBlobs {
            usable: usable.len(),
            hidden,
            spheres,
            needed,
        });
    }
    if usable.len() > spheres + config.max_extra_blobs {
        return Err(TrackError::TooManyBlobs {
            found: usable.len(),
            spheres,
            max_extra: config.max_extra_blobs,
        });
    }
    let projected: Vec<Vector2<f64>> = usable
        .iter()
        .map(|&i| projected_centre_normalised(&blobs[i], config.centre))
        .collect();
    let focal = config.camera.fx().min(config.camera.fy());
    let options = UnlabelledOptions::with_gate_px(config.gate_px, focal, 1);
    // The chosen blobs (indices into `usable`) and their identification.
    let mut best: Option<(Vec<usize>, Identification)> = None;
    let mut last_error = None;
    let first_size = usable.len().min(spheres);
    for size in [first_size, first_size - 1] {
        if size < needed {
            break;
        }
        for subset in subsets(usable.len(), size) {
            let image: Vec<Vector2<f64>> = subset.iter().map(|&k| projected[k]).collect();
            match identify(&config.object, &image, &options) {
                Ok(found) => {
                    if best
                        .as_ref()
                        .is_none_or(|(_, b)| found.best.rms < b.best.rms)
                    {
                        best = Some((subset, found));
                    }
                }
                Err(error) => last_error = Some(error),
            }
        }
        if best.is_some() {
            break;
        }
    }
    let Some((subset, found)) = best else {
        return Err(TrackError::Identification(last_error.unwrap_or(
            LabellingError::NoConsistentLabelling { hypotheses: 0 },
        )));
    };
    let chosen: Vec<usize> = subset.iter().map(|&k| usable[k]).collect();
    let ambiguity = found.ambiguity();
    let probability = wrong_label_probability(ambiguity, chosen.len());
    if probability > config.max_wrong_labels {
        return Err(TrackError::Ambiguous {
            ambiguity: ambiguity.unwrap_or(f64::INFINITY),
            probability,
            max: config.max_wrong_labels,
        });
    }
    let matched: Vec<Vector3<f64>> = found
        .best
        .labels
        .iter()
        .map(|&k| config.object[k])
        .collect();
    let radius_mm = config.radius_mm();
    let pose = match config.solver {
        Solver::Ml => {
            let measured: Vec<Vector2<f64>> = chosen
                .iter()
                .map(|&i| measured_normalised(&blobs[i], config.centre))
                .collect();
            let start = found.best.pose;
            if !start.all_in_front(&matched) {
                return Err(TrackError::Pose(
                    ml_sphere::SphereFitError::NotInFront { radius_mm }.to_string(),
                ));
            }
            let pose = ml_sphere::refine(&start, &matched, &measured, radius_mm);
            let silhouettes = silhouettes(config, blobs, &chosen, &matched, &pose);
            if fits_silhouettes(config) && silhouettes.iter().any(Option::is_some) {
                let centres: Vec<Vector2<f64>> = measured
                    .iter()
                    .zip(&silhouettes)
                    .map(|(m, s)| s.unwrap_or(*m))
                    .collect();
                ml_sphere::refine(&pose, &matched, &centres, radius_mm)
            } else {
                pose
            }
        }
        solver => {
            let image: Vec<Vector2<f64>> = subset.iter().map(|&k| projected[k]).collect();
            solver
                .solve_best(&matched, &image)
                .map_err(|e| TrackError::Pose(e.to_string()))?
        }
    };
    let figures = frame_figures(config, blobs, &chosen, &matched, &pose)?;
    for (&blob, &label) in chosen.iter().zip(&found.best.labels) {
        blobs[blob].label = Some(label);
    }
    // Hidden blobs: the nearest unclaimed model ellipse within the blob's
    // semi-major axis.
    let mut claimed: Vec<bool> = vec![false; spheres];
    for &label in &found.best.labels {
        claimed[label] = true;
    }
    let models: Vec<Option<Vector2<f64>>> = config
        .object
        .iter()
        .map(|p| model_pixel(&config.camera, &pose, p, Some(radius_mm)))
        .collect();
    for blob in blobs.iter_mut().filter(|b| b.hidden()) {
        let at = Vector2::new(blob.ellipse_centre_px[0], blob.ellipse_centre_px[1]);
        let nearest = models
            .iter()
            .enumerate()
            .filter(|(k, m)| !claimed[*k] && m.is_some())
            .map(|(k, m)| (k, (m.expect("filtered") - at).norm()))
            .min_by(|a, b| a.1.total_cmp(&b.1));
        if let Some((k, distance)) = nearest {
            if distance <= blob.semi_axes_px[0].max(config.gate_px) {
                blob.label = Some(k);
                claimed[k] = true;
            }
        }
    }
    let mut residuals_px = vec![None; spheres];
    for (&label, r) in found.best.labels.iter().zip(&figures.residuals_px) {
        residuals_px[label] = Some(*r);
    }
    let centre_sigma_px = figures.centre_sigmas.as_ref().map(|sigmas| {
        let mut per_sphere = vec![None; spheres];
        for (&label, s) in found.best.labels.iter().zip(&sigmas.own_px) {
            per_sphere[label] = Some(*s);
        }
        per_sphere
    });
    let mut used = vec![false; spheres];
    for &label in &found.best.labels {
        used[label] = true;
    }
    let rms = (figures
        .residuals_px
        .iter()
        .map(|r| r[0] * r[0] + r[1] * r[1])
        .sum::<f64>()
        / figures.residuals_px.len() as f64)
        .sqrt();
    let r = pose.rotation.matrix();
    let tracked = TrackedFrame {
        labels: blobs.iter().map(|b| b.label).collect(),
        ambiguity,
        wrong_label_probability: probability,
        rotation: std::array::from_fn(|i| std::array::from_fn(|j| r[(i, j)])),
        t: [pose.translation.x, pose.translation.y, pose.translation.z],
        figures: FramedFigures {
            rvec: figures.rvec,
            tvec: figures.tvec,
            residuals_px,
            sigma_px: figures.sigma_px,
            sigma_source: figures.sigma_source,
            centre_sigma_px,
            sigma_shared_px: figures.centre_sigmas.as_ref().map(|s| s.shared_px),
            residual_inflation: figures.centre_sigmas.as_ref().map(|s| s.inflation),
            covariance: figures.covariance,
            sigma_rot_deg: figures.sigma_rot_deg,
            sigma_trans_mm: figures.sigma_trans_mm,
        },
        missing: (0..spheres).filter(|&k| !used[k]).collect(),
        reprojection_rms_px: rms,
        refinement: None,
    };
    Ok((tracked, pose))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn subsets_are_every_combination_once() {
        assert_eq!(subsets(4, 2).len(), 6);
        assert_eq!(subsets(9, 7).len(), 36);
        assert_eq!(subsets(3, 3), vec![vec![0, 1, 2]]);
        assert!(subsets(2, 3).is_empty());
        assert_eq!(subsets(3, 2), vec![vec![0, 1], vec![0, 2], vec![1, 2]]);
    }
}
