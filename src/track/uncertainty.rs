//! The pose fields that `track` and `solve` write beside R and t: OpenCV's
//! `rvec`/`tvec`, each point's reprojection residual, the noise σ (given,
//! estimated from the residuals, or each centre's own from its blob), the
//! first-order 6×6 covariance of `(rvec, tvec)` and its 1σ figures, and
//! how far the labels can be trusted.
//!
//! **Covariance.** [`crate::error_model::first_order`] gives the covariance
//! of the pose perturbation `(ω, δt)` with `R ← exp([ω]×) R`. OpenCV's rvec
//! is the rotation vector θ of R itself; to first order
//! `exp([ω]×) exp([θ]×) = exp([θ + J_l⁻¹(θ) ω]×)`, with the inverse left
//! Jacobian of SO(3)
//! `J_l⁻¹(θ) = I − ½[θ]× + (1/|θ|² − (1 + cos|θ|)/(2|θ| sin|θ|)) [θ]×²`
//! (Barfoot, *State Estimation for Robotics*, 2017, eq. (7.185)). The
//! covariance written is `J Σ Jᵀ` with `J = diag(J_l⁻¹(θ), I)`. The
//! 1σ figures are basis-free: `sigma_rot_deg = √trace Σ_ωω` (RMS geodesic
//! rotation error) and `sigma_trans_mm = √trace Σ_tt`.
//!
//! **σ from residuals** (`solve`). With `n` points and 6 pose parameters
//! the fit leaves `2n − 6` degrees of freedom: `σ̂² = Σ‖rᵢ‖² / (2n − 6)`.
//!
//! **σ from the blobs** (`track`, unless `--sigma-px` gives one). Each
//! centre has its own σ, and the frame one σ that every centre shares:
//!
//! * *Noise.* The ellipse centre's σ per axis from its own edges,
//!   `nᵢ = fit residual · √(2 / kept points)`
//!   ([`crate::track::detect::Blob::centre_noise_px`]); the windowed
//!   centroid's from the pixel noise it sums
//!   ([`crate::track::detect::Blob::window_noise_px`]). Where the pose's
//!   residuals exceed that noise (`s² = Σ ‖rᵢ‖² / nᵢ² / (2n − 6) > 1`),
//!   every `nᵢ` grows by `s`: the frame says its centres are worse than
//!   their pixels claim.
//! * *Mismatch.* On a flat bright disc the two centres agree but for
//!   their noise (after `--refine`, but for what the part's render sets
//!   between them). Shading, a lamp beside the camera, or a body behind
//!   the limb pulls them apart, and pulls the centres themselves. The
//!   part of their distance that their noise does not explain,
//!   `eᵢ = √max(0, dᵢ² − 2 (n_ellipse² + n_window²))`, is the evidence.
//!   [`MismatchShares`] turn it into an independent σ `own · eᵢ` and a
//!   shared σ `c` with `c² = mean (shared · eᵢ)²`: a lamp pulls every
//!   centre the same way, which moves the pose as a whole and which no
//!   residual shows. The windowed centroid carries the pull itself
//!   (`own = shared = 0.5`); the ellipse fit's half-level edge feels a
//!   small part of it (`shared = 0.15`).
//! * *Covariance.* The pose is an unweighted fit, so its covariance is
//!   the sandwich [`crate::error_model::first_order::pose_covariance_sandwich`]
//!   of `σᵢ² = s² nᵢ² + (own · eᵢ)²` and `c`.
//!
//! The shares were measured on `render`'s noisy frames in its three
//! presets (docs/commands.md, "An honest covariance"): the mean
//! normalised squared pose error came within 0.7–1.2 of its ideal 6 in
//! each, for both centre methods, with and without `--refine`; σ from the
//! residuals alone gave 11–75.
//!
//! **Label trust.** `identify` ranks labellings by RMS; `ambiguity` is the
//! runner-up's RMS over the best's. The identifiability model
//! ([`crate::identifiability`]) says a wrong labelling whose residual norm
//! is `‖r‖` wins with probability `Φ(−‖r‖ / 2σ)`. From the two fits,
//! `‖r‖² ≈ n (rms₂² − rms₁²) = n rms₁² (a² − 1)` and
//! `σ² ≈ n rms₁² / (2n − 6)`, so the predicted probability that the labels
//! are wrong is `Φ(−√((a² − 1)(2n − 6)) / 2)`: ½ for twins (a = 1), and
//! below the identifiability bar of 1e-3 once `a ≥ √(1 + 38.2/(2n − 6))`
//! (2.40 for 7 blobs, 4.48 for 4).

use crate::camera::Camera;
use crate::error_model::first_order::{
    pose_covariance_isotropic, pose_covariance_sandwich, FirstOrderError,
};
use crate::identifiability::normal_upper_tail;
use crate::pose::Pose;
use crate::sphere_image::ellipse_centre_normalised;
use nalgebra::{Matrix3, SMatrix, Vector2, Vector3};
use serde::{Deserialize, Serialize};

/// Smallest σ estimated from residuals, px: noise-free synthetic frames fit
/// to rounding, and a zero σ has no covariance.
pub const MIN_SIGMA_PX: f64 = 1e-6;

/// Where σ came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum SigmaSource {
    /// Given by the caller.
    Given,
    /// Estimated from the fit's residuals.
    Residuals,
    /// Each centre's own, from its blob (module docs).
    Blobs,
}

/// What one blob says about its centre's error (module docs, "σ from the
/// blobs").
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CentreEvidence {
    /// The σ per axis of the centre read, from the blob's own noise, px.
    pub noise_px: f64,
    /// How far the blob's ellipse centre and windowed centroid lie apart, px.
    pub disagreement_px: f64,
    /// The σ per axis that the two centres' own noise gives their
    /// difference, px.
    pub disagreement_noise_px: f64,
}

impl CentreEvidence {
    /// The disagreement beyond what the two centres' noise explains:
    /// `√max(0, d² − 2 σ_d²)` (the difference has σ_d on each axis).
    pub fn excess_disagreement_px(&self) -> f64 {
        let expected = 2.0 * self.disagreement_noise_px.powi(2);
        (self.disagreement_px.powi(2) - expected).max(0.0).sqrt()
    }
}

/// The shares of a blob's [`CentreEvidence::disagreement_px`] that count as
/// its own σ and as the σ shared by the frame's centres.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MismatchShares {
    /// Share counted as the centre's own σ.
    pub own: f64,
    /// Share counted as σ shared by every centre.
    pub shared: f64,
}

impl MismatchShares {
    /// For the ellipse fit's centre, whose half-level edge feels a small
    /// part of what pulls the two centres apart (module docs).
    pub const ELLIPSE: MismatchShares = MismatchShares {
        own: 0.0,
        shared: 0.15,
    };
    /// For an intensity centroid (windowed or not), which carries the pull
    /// itself.
    pub const CENTROID: MismatchShares = MismatchShares {
        own: 0.5,
        shared: 0.5,
    };
}

/// How the covariance's σ is chosen.
#[derive(Debug, Clone, Copy)]
pub enum SigmaChoice<'a> {
    /// The caller's σ for every point, px.
    Given(f64),
    /// Estimated from the fit's residuals.
    Residuals,
    /// Each centre's own from its blob, one per point, and the shares of
    /// the centre method read (module docs).
    Blobs(&'a [CentreEvidence], MismatchShares),
}

/// The σ of [`SigmaSource::Blobs`] (module docs).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CentreSigmas {
    /// Each point's own σ, px: its noise, grown by `inflation`, and its
    /// own share of the mismatch.
    pub own_px: Vec<f64>,
    /// σ shared by every point, px.
    pub shared_px: f64,
    /// How much the residuals grew the noise: `max(1, s)`.
    pub inflation: f64,
}

impl CentreSigmas {
    /// The σ of `evidence` for a fit that left `residuals` (px), one per
    /// point; a noise below [`MIN_SIGMA_PX`] counts as that.
    pub fn of(
        evidence: &[CentreEvidence],
        shares: MismatchShares,
        residuals: &[Vector2<f64>],
    ) -> Self {
        let noise: Vec<f64> = evidence
            .iter()
            .map(|e| e.noise_px.max(MIN_SIGMA_PX))
            .collect();
        let dof = 2 * evidence.len() as i64 - 6;
        let inflation = if dof > 0 {
            let chi2: f64 = residuals
                .iter()
                .zip(&noise)
                .map(|(r, n)| r.norm_squared() / (n * n))
                .sum();
            (chi2 / dof as f64).sqrt().max(1.0)
        } else {
            1.0
        };
        let own_px = noise
            .iter()
            .zip(evidence)
            .map(|(n, e)| (inflation * n).hypot(shares.own * e.excess_disagreement_px()))
            .collect();
        let shared_px = if evidence.is_empty() {
            0.0
        } else {
            (evidence
                .iter()
                .map(|e| (shares.shared * e.excess_disagreement_px()).powi(2))
                .sum::<f64>()
                / evidence.len() as f64)
                .sqrt()
        };
        CentreSigmas {
            own_px,
            shared_px,
            inflation,
        }
    }
}

/// The pose fields shared by `track` and `solve` (docs/formats.md).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PoseFigures {
    /// OpenCV's rotation vector of R (axis × angle), rad.
    pub rvec: [f64; 3],
    /// OpenCV's tvec (= t), mm.
    pub tvec: [f64; 3],
    /// Each point's residual, measured minus model, raw px.
    pub residuals_px: Vec<[f64; 2]>,
    /// The σ of the covariance, px (from the blobs: the RMS of each
    /// point's own σ and the shared one together).
    pub sigma_px: f64,
    /// Where σ came from.
    pub sigma_source: SigmaSource,
    /// From the blobs: each point's σ and the shared one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub centre_sigmas: Option<CentreSigmas>,
    /// First-order covariance of `(rvec [rad], tvec [mm])`, row-major 6×6.
    pub covariance: [[f64; 6]; 6],
    /// 1σ rotation error (RMS geodesic angle), degrees.
    pub sigma_rot_deg: f64,
    /// 1σ translation error (RMS), mm.
    pub sigma_trans_mm: f64,
}

/// Why the figures could not be computed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum FiguresError {
    /// Too few points to estimate σ, and none was given.
    #[error("{points} points leave no degrees of freedom to estimate σ from; give σ")]
    NoDegreesOfFreedom {
        /// Points fitted.
        points: usize,
    },
    /// The point counts differ.
    #[error("{object} object points but {image} image points")]
    Mismatched {
        /// Object points.
        object: usize,
        /// Image points.
        image: usize,
    },
    /// The first-order covariance failed.
    #[error("covariance: {0}")]
    Covariance(#[from] FirstOrderError),
}

/// The inverse left Jacobian of SO(3) at the rotation vector θ (module docs).
pub fn inverse_left_jacobian(theta: &Vector3<f64>) -> Matrix3<f64> {
    let angle = theta.norm();
    let skew = theta.cross_matrix();
    let coefficient = if angle < 1e-5 {
        1.0 / 12.0 + angle * angle / 720.0
    } else {
        1.0 / (angle * angle) - (1.0 + angle.cos()) / (2.0 * angle * angle.sin())
    };
    Matrix3::identity() - 0.5 * skew + coefficient * skew * skew
}

/// The model image point of object point `p` at `pose`, raw px: the sphere's
/// ellipse centre when `radius_mm` is given, else its projection; `None`
/// when it is not in front of the camera.
pub fn model_pixel(
    camera: &Camera,
    pose: &Pose,
    p: &Vector3<f64>,
    radius_mm: Option<f64>,
) -> Option<Vector2<f64>> {
    let c = pose.transform(p);
    match radius_mm {
        Some(r) => ellipse_centre_normalised(&c, r)
            .ok()
            .map(|m| camera.normalised_to_pixel(&m)),
        None => camera.project(&c),
    }
}

/// Computes [`PoseFigures`] for `pose` fitted to `pixels` (raw px) of the
/// matched `object` points, with σ as `sigma` chooses.
pub fn pose_figures(
    camera: &Camera,
    pose: &Pose,
    object: &[Vector3<f64>],
    pixels: &[Vector2<f64>],
    radius_mm: Option<f64>,
    sigma: SigmaChoice<'_>,
) -> Result<PoseFigures, FiguresError> {
    let evidence_count = match sigma {
        SigmaChoice::Blobs(evidence, _) => evidence.len(),
        _ => pixels.len(),
    };
    if object.len() != pixels.len() || evidence_count != pixels.len() {
        return Err(FiguresError::Mismatched {
            object: object.len(),
            image: pixels.len().min(evidence_count),
        });
    }
    let mut residuals_px = Vec::with_capacity(object.len());
    let mut sum = 0.0;
    for (index, (p, measured)) in object.iter().zip(pixels).enumerate() {
        let model = model_pixel(camera, pose, p, radius_mm).ok_or(FiguresError::Covariance(
            FirstOrderError::BehindCamera(index),
        ))?;
        let r = measured - model;
        sum += r.norm_squared();
        residuals_px.push([r.x, r.y]);
    }
    let (sigma_px, source, centre_sigmas, first_order) = match sigma {
        SigmaChoice::Given(sigma) => (
            sigma,
            SigmaSource::Given,
            None,
            pose_covariance_isotropic(camera, pose, object, sigma)?,
        ),
        SigmaChoice::Residuals => {
            let dof = 2 * object.len() as i64 - 6;
            if dof <= 0 {
                return Err(FiguresError::NoDegreesOfFreedom {
                    points: object.len(),
                });
            }
            let sigma = (sum / dof as f64).sqrt().max(MIN_SIGMA_PX);
            (
                sigma,
                SigmaSource::Residuals,
                None,
                pose_covariance_isotropic(camera, pose, object, sigma)?,
            )
        }
        SigmaChoice::Blobs(evidence, shares) => {
            let residuals: Vec<Vector2<f64>> =
                residuals_px.iter().map(|r| Vector2::from(*r)).collect();
            let sigmas = CentreSigmas::of(evidence, shares, &residuals);
            let covariance =
                pose_covariance_sandwich(camera, pose, object, &sigmas.own_px, sigmas.shared_px)?;
            let mean_own = sigmas.own_px.iter().map(|s| s * s).sum::<f64>()
                / sigmas.own_px.len().max(1) as f64;
            (
                (mean_own + sigmas.shared_px.powi(2)).sqrt(),
                SigmaSource::Blobs,
                Some(sigmas),
                covariance,
            )
        }
    };
    let sigma_rot_deg = first_order.rms_rotation_deg();
    let sigma_trans_mm = first_order.rms_translation_mm();
    let theta = pose.rotation.scaled_axis();
    let mut jacobian = SMatrix::<f64, 6, 6>::identity();
    jacobian
        .fixed_view_mut::<3, 3>(0, 0)
        .copy_from(&inverse_left_jacobian(&theta));
    let covariance = jacobian * first_order.covariance * jacobian.transpose();
    Ok(PoseFigures {
        rvec: [theta.x, theta.y, theta.z],
        tvec: [pose.translation.x, pose.translation.y, pose.translation.z],
        residuals_px,
        sigma_px,
        sigma_source: source,
        centre_sigmas,
        covariance: std::array::from_fn(|i| std::array::from_fn(|j| covariance[(i, j)])),
        sigma_rot_deg,
        sigma_trans_mm,
    })
}

/// Predicted probability that the best labelling of `matched` blobs is
/// wrong, from its `ambiguity` (module docs); 0 when no other labelling is
/// consistent (the search gate bounds it, far below any bar we set).
pub fn wrong_label_probability(ambiguity: Option<f64>, matched: usize) -> f64 {
    let Some(a) = ambiguity else {
        return 0.0;
    };
    let dof = (2 * matched).saturating_sub(6) as f64;
    if dof == 0.0 || !a.is_finite() {
        return if a.is_finite() { 0.5 } else { 0.0 };
    }
    let margin_over_sigma = ((a * a - 1.0).max(0.0) * dof).sqrt();
    normal_upper_tail(0.5 * margin_over_sigma)
}

/// The pose fields of one `solve` result (docs/formats.md, "`solve`
/// batch"): for a solved problem, its [`PoseFigures`] (σ from the
/// residuals) and, for an unlabelled one, the predicted probability that
/// its labels are wrong.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SolveFigures {
    /// The pose fields.
    #[serde(flatten)]
    pub figures: PoseFigures,
    /// Unlabelled solves: predicted probability that the labels are wrong.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub wrong_label_probability: Option<f64>,
    /// Set when the labels cannot be trusted.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub warning: Option<String>,
}

/// [`SolveFigures`] for every result of a `solve` batch, in order; `None`
/// for failed problems, and an error message where the figures cannot be
/// computed. `sphere_diameter_mm` is the run's default diameter (a
/// problem's own wins, as in [`crate::batch`]).
pub fn solve_figures(
    batch: &crate::batch::Batch,
    output: &crate::batch::BatchOutput,
    sphere_diameter_mm: Option<f64>,
) -> Vec<Option<Result<SolveFigures, String>>> {
    use crate::batch::ProblemResult;
    batch
        .problems
        .iter()
        .zip(&output.results)
        .map(|((_, problem), result)| {
            let ProblemResult::Solved {
                rotation,
                translation,
                labels,
                ambiguity,
                ..
            } = result
            else {
                return None;
            };
            let problem = problem.as_ref().ok()?;
            let object: Vec<Vector3<f64>> = match labels {
                Some(labels) => labels
                    .iter()
                    .map(|&k| Vector3::from(problem.object_points[k]))
                    .collect(),
                None => problem.object_points.iter().map(|p| Vector3::from(*p)).collect(),
            };
            let pixels: Vec<Vector2<f64>> =
                problem.image_points.iter().map(|p| Vector2::from(*p)).collect();
            let matrix = Matrix3::from_fn(|i, j| rotation[i][j]);
            let pose = Pose::new(
                nalgebra::Rotation3::from_matrix_unchecked(matrix),
                Vector3::from(*translation),
            );
            let radius_mm = problem.sphere_diameter.or(sphere_diameter_mm).map(|d| 0.5 * d);
            let figures = match pose_figures(
                &batch.camera,
                &pose,
                &object,
                &pixels,
                radius_mm,
                SigmaChoice::Residuals,
            ) {
                Ok(figures) => figures,
                Err(error) => return Some(Err(error.to_string())),
            };
            let wrong = labels
                .as_ref()
                .map(|labels| wrong_label_probability(ambiguity.flatten(), labels.len()));
            let warning = wrong.filter(|&p| p > LABEL_TRUST_BAR).map(|p| {
                format!(
                    "labels cannot be trusted: ambiguity {:.3} predicts wrong labels with probability {p:.2e} (above {LABEL_TRUST_BAR:.0e})",
                    ambiguity.flatten().unwrap_or(f64::NAN)
                )
            });
            Some(Ok(SolveFigures {
                figures,
                wrong_label_probability: wrong,
                warning,
            }))
        })
        .collect()
}

/// Largest predicted wrong-label probability `solve` accepts without a
/// warning: the identifiability model's bar,
/// `1 − `[`crate::identifiability::DEFAULT_MIN_CORRECT`].
pub const LABEL_TRUST_BAR: f64 = 1.0 - crate::identifiability::DEFAULT_MIN_CORRECT;

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;
    use nalgebra::Rotation3;

    #[test]
    fn inverse_left_jacobian_matches_central_differences() {
        // The series branch meets the closed form at its switch-over.
        let below = inverse_left_jacobian(&Vector3::new(0.99e-5, 0.0, 0.0));
        let above = inverse_left_jacobian(&Vector3::new(1.01e-5, 0.0, 0.0));
        assert_relative_eq!(below, above, epsilon = 2e-7);
        for theta in [
            Vector3::new(0.4, -1.1, 0.7),
            Vector3::new(0.02, -0.01, 0.005),
        ] {
            let rotation = Rotation3::new(theta);
            let analytic = inverse_left_jacobian(&theta);
            let h = 1e-6;
            for k in 0..3 {
                let mut omega = Vector3::zeros();
                omega[k] = h;
                let plus = (Rotation3::new(omega) * rotation).scaled_axis();
                let minus = (Rotation3::new(-omega) * rotation).scaled_axis();
                assert_relative_eq!(
                    analytic.column(k).into_owned(),
                    (plus - minus) / (2.0 * h),
                    epsilon = 1e-7
                );
            }
        }
    }

    /// The paper's biprism at a tilted pose through `camera`, and each
    /// sphere's exact ellipse centre (5 mm spheres) moved by `offset`.
    fn biprism_view(
        camera: &Camera,
        offset: Vector2<f64>,
    ) -> (Pose, Vec<Vector3<f64>>, Vec<Vector2<f64>>) {
        let object = crate::layout::biprism_points(50.0);
        let pose = Pose::new(
            Rotation3::from_euler_angles(0.3, -0.2, 0.5),
            Vector3::new(30.0, -20.0, 500.0),
        );
        let pixels = object
            .iter()
            .map(|p| model_pixel(camera, &pose, p, Some(5.0)).unwrap() + offset)
            .collect();
        (pose, object, pixels)
    }

    #[test]
    fn figures_of_an_exact_fit_and_given_sigma() {
        let camera = Camera::paper_with_distortion();
        let (pose, object, pixels) = biprism_view(&camera, Vector2::zeros());
        let figures = pose_figures(
            &camera,
            &pose,
            &object,
            &pixels,
            Some(5.0),
            SigmaChoice::Given(0.5),
        )
        .unwrap();
        assert_eq!(figures.sigma_source, SigmaSource::Given);
        assert!(figures
            .residuals_px
            .iter()
            .all(|r| r[0].abs() < 1e-9 && r[1].abs() < 1e-9));
        assert_relative_eq!(
            Rotation3::new(Vector3::from(figures.rvec)).matrix(),
            pose.rotation.matrix(),
            epsilon = 1e-12
        );
        let first = pose_covariance_isotropic(&camera, &pose, &object, 0.5).unwrap();
        assert_relative_eq!(figures.sigma_rot_deg, first.rms_rotation_deg());
        // The translation block is untouched; the matrix is symmetric.
        for i in 0..6 {
            for j in 0..6 {
                assert_relative_eq!(
                    figures.covariance[i][j],
                    figures.covariance[j][i],
                    max_relative = 1e-9
                );
                if i >= 3 && j >= 3 {
                    assert_relative_eq!(figures.covariance[i][j], first.covariance[(i, j)]);
                }
            }
        }
        let estimated = pose_figures(
            &camera,
            &pose,
            &object,
            &pixels,
            Some(5.0),
            SigmaChoice::Residuals,
        )
        .unwrap();
        assert_eq!(estimated.sigma_px, MIN_SIGMA_PX);
        assert!(matches!(
            pose_figures(
                &camera,
                &pose,
                &object[..3],
                &pixels[..3],
                None,
                SigmaChoice::Residuals
            ),
            Err(FiguresError::NoDegreesOfFreedom { points: 3 })
        ));
    }

    /// The blobs' σ: their noise where the residuals agree with it, grown
    /// by the residuals where they do not; the disagreement beyond the two
    /// centres' noise split by the shares; and the covariance the sandwich
    /// of those σ.
    #[test]
    fn blob_sigmas_follow_noise_residuals_and_disagreement() {
        let evidence = |noise_px: f64, disagreement_px: f64| CentreEvidence {
            noise_px,
            disagreement_px,
            disagreement_noise_px: 0.01,
        };
        let quiet = [evidence(0.02, 0.0); 7];
        let small = [Vector2::new(0.01, -0.01); 7];
        let sigmas = CentreSigmas::of(&quiet, MismatchShares::ELLIPSE, &small);
        assert_eq!(sigmas.inflation, 1.0);
        assert_eq!(sigmas.shared_px, 0.0);
        assert!(sigmas.own_px.iter().all(|&s| s == 0.02));
        // Residuals of 0.08 px per axis against 0.02 px of noise:
        // s² = 7 · 2 · 16 / 8 = 28.
        let large = [Vector2::new(0.08, 0.08); 7];
        let grown = CentreSigmas::of(&quiet, MismatchShares::ELLIPSE, &large);
        assert_relative_eq!(grown.inflation, 28f64.sqrt(), epsilon = 1e-12);
        assert_relative_eq!(grown.own_px[0], 0.02 * 28f64.sqrt(), epsilon = 1e-12);
        // A disagreement within its noise counts for nothing; one of 0.5 px
        // counts √(0.25 − 2·10⁻⁴).
        assert_eq!(evidence(0.02, 0.014).excess_disagreement_px(), 0.0);
        let excess = (0.25f64 - 2e-4).sqrt();
        assert_relative_eq!(evidence(0.02, 0.5).excess_disagreement_px(), excess);
        let pulled = [evidence(0.02, 0.5); 7];
        let centroid = CentreSigmas::of(&pulled, MismatchShares::CENTROID, &small);
        assert_relative_eq!(
            centroid.own_px[0],
            0.02f64.hypot(0.5 * excess),
            epsilon = 1e-12
        );
        assert_relative_eq!(centroid.shared_px, 0.5 * excess, epsilon = 1e-12);
        let ellipse = CentreSigmas::of(&pulled, MismatchShares::ELLIPSE, &small);
        assert_eq!(ellipse.own_px[0], 0.02);
        assert_relative_eq!(ellipse.shared_px, 0.15 * excess, epsilon = 1e-12);

        let camera = Camera::paper();
        let (pose, object, pixels) = biprism_view(&camera, small[0]);
        let figures = pose_figures(
            &camera,
            &pose,
            &object,
            &pixels,
            Some(5.0),
            SigmaChoice::Blobs(&pulled, MismatchShares::CENTROID),
        )
        .unwrap();
        assert_eq!(figures.sigma_source, SigmaSource::Blobs);
        let sigmas = figures.centre_sigmas.as_ref().unwrap();
        let sandwich =
            pose_covariance_sandwich(&camera, &pose, &object, &sigmas.own_px, sigmas.shared_px)
                .unwrap();
        assert_relative_eq!(
            figures.sigma_rot_deg,
            sandwich.rms_rotation_deg(),
            max_relative = 1e-9
        );
        assert_relative_eq!(
            figures.sigma_trans_mm,
            sandwich.rms_translation_mm(),
            max_relative = 1e-9
        );
        assert!(matches!(
            pose_figures(
                &camera,
                &pose,
                &object,
                &pixels,
                Some(5.0),
                SigmaChoice::Blobs(&pulled[..6], MismatchShares::CENTROID),
            ),
            Err(FiguresError::Mismatched { .. })
        ));
    }

    #[test]
    fn label_trust_follows_the_identifiability_model() {
        assert_eq!(wrong_label_probability(None, 7), 0.0);
        assert_relative_eq!(wrong_label_probability(Some(1.0), 7), 0.5, epsilon = 1e-6);
        // The 1e-3 bar sits at a = √(1 + 38.2/8) ≈ 2.40 for 7 blobs.
        assert!(wrong_label_probability(Some(2.3), 7) > 1e-3);
        assert!(wrong_label_probability(Some(2.5), 7) < 1e-3);
        assert!(wrong_label_probability(Some(4.3), 4) > 1e-3);
        assert!(wrong_label_probability(Some(4.6), 4) < 1e-3);
    }
}
