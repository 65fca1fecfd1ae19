//! Fabrication error of the sphere centres: how a printed part whose
//! spheres are off their nominal centres biases the pose when the solver
//! uses the nominal layout (docs/formats.md, "`export`", "Tolerances").
//!
//! A printed part has centres `Xᵢ + eᵢ`, each `eᵢ` fixed for that part and,
//! over parts, i.i.d. `N(0, σ_fab² I₃)` per sphere. The camera sees the
//! printed centres; the solver fits the nominal `Xᵢ`. To first order the
//! image moves by `bᵢ = (∂pixel/∂X)ᵢ eᵢ` with `∂pixel/∂X = (∂pixel/∂t) R`
//! (the last three columns of [`pixel_jacobian`], times the rotation), and
//! the pose by the Gauss–Newton step on that image bias, the same map as
//! [`super::first_order::pose_covariance_and_bias`]:
//!
//! `δ = Σᵢ Aᵢ Bᵢ eᵢ`, `Aᵢ = (JᵀWJ)⁻¹ Jᵢᵀ Wᵢ`, `Bᵢ = (∂pixel/∂X)ᵢ`,
//!
//! so the pose error of the fabrication has covariance `σ_fab² G` with
//! `G = Σᵢ (AᵢBᵢ)(AᵢBᵢ)ᵀ` ([`FabricationSensitivity`]), independent of the
//! image noise and added to its covariance `(JᵀWJ)⁻¹`. Both scale the same
//! way with the weights, so `G` depends on the relative σ of the points
//! only.
//!
//! The pose error includes the rigid part of `eᵢ` (a part printed shifted
//! as a whole is read as a shifted pose), which is what a pose measured
//! against the nominal marker frame sees.
//!
//! [`tolerance`] turns this into a centre tolerance over a scenario grid;
//! [`super::budget`] puts it beside the image noise and the camera, and
//! checks it with a new perturbed part per trial.

use super::first_order::{pixel_jacobian, pose_covariance, FirstOrderError, PoseCovariance};
use crate::camera::Camera;
use crate::pose::Pose;
use crate::scenario::{sphere_images, visibility, Scenario, ScenarioGrid};
use nalgebra::{SMatrix, Vector3};
use serde::Serialize;

/// The fabrication share the sheet's tolerance is set for: the RMS
/// rotation error a part with that tolerance adds is at most this fraction
/// of the image-noise RMS rotation error, in every visible scenario of the
/// grid (added in quadrature, it raises the total by under 0.5 %).
pub const TOLERANCE_SHARE: f64 = 0.1;

/// Why a fabrication figure could not be computed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum FabricationError {
    /// The share is not in (0, 1].
    #[error("the fabrication share must be in (0, 1], got {0}")]
    BadShare(f64),
    /// No scenario of the grid sees every sphere with noise σ > 0.
    #[error("no scenario of the grid sees every sphere with image noise above 0 px, so no tolerance follows from it")]
    NoVisibleScenario,
    /// The first-order model failed.
    #[error(transparent)]
    FirstOrder(#[from] FirstOrderError),
}

/// `G` of the module documentation: the pose covariance per mm² of σ_fab.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FabricationSensitivity {
    /// 6×6 covariance of `(ω [rad], δt [mm])` for σ_fab = 1 mm.
    pub per_mm2: SMatrix<f64, 6, 6>,
}

impl FabricationSensitivity {
    /// RMS geodesic rotation error per mm of σ_fab, degrees.
    pub fn rotation_deg_per_mm(&self) -> f64 {
        let g = &self.per_mm2;
        (g[(0, 0)] + g[(1, 1)] + g[(2, 2)])
            .max(0.0)
            .sqrt()
            .to_degrees()
    }

    /// RMS translation error per mm of σ_fab, mm.
    pub fn translation_mm_per_mm(&self) -> f64 {
        let g = &self.per_mm2;
        (g[(3, 3)] + g[(4, 4)] + g[(5, 5)]).max(0.0).sqrt()
    }

    /// The fabrication covariance `σ_fab² G` added to `noise`.
    pub fn add_to(&self, noise: &PoseCovariance, sigma_fab_mm: f64) -> PoseCovariance {
        PoseCovariance {
            covariance: noise.covariance + self.per_mm2 * (sigma_fab_mm * sigma_fab_mm),
            translation_norm_mm: noise.translation_norm_mm,
        }
    }
}

/// `∂pixel/∂X` of object point `p`: the image motion per mm of the point's
/// own displacement (marker frame).
pub fn object_point_jacobian(camera: &Camera, pose: &Pose, p: &Vector3<f64>) -> SMatrix<f64, 2, 3> {
    let pose_jacobian = pixel_jacobian(camera, pose, p);
    pose_jacobian.fixed_view::<2, 3>(0, 3) * pose.rotation.matrix()
}

/// The fabrication sensitivity `G` at `pose` for per-point pixel noise
/// `sigma_px` (the weights; with every σ zero, equal weights).
pub fn sensitivity(
    camera: &Camera,
    pose: &Pose,
    object: &[Vector3<f64>],
    sigma_px: &[f64],
) -> Result<FabricationSensitivity, FirstOrderError> {
    if sigma_px.len() != object.len() {
        return Err(FirstOrderError::MismatchedLengths {
            points: object.len(),
            sigmas: sigma_px.len(),
        });
    }
    let noise_free = sigma_px.iter().all(|&s| s == 0.0);
    let weight = |sigma: f64| -> Result<f64, FirstOrderError> {
        if noise_free {
            Ok(1.0)
        } else if sigma > 0.0 && sigma.is_finite() {
            Ok(1.0 / (sigma * sigma))
        } else {
            Err(FirstOrderError::BadSigma(sigma))
        }
    };
    let mut information = SMatrix::<f64, 6, 6>::zeros();
    for (index, (p, &sigma)) in object.iter().zip(sigma_px).enumerate() {
        if pose.transform(p).z <= 0.0 {
            return Err(FirstOrderError::BehindCamera(index));
        }
        let jacobian = pixel_jacobian(camera, pose, p);
        information += jacobian.transpose() * jacobian * weight(sigma)?;
    }
    let cholesky = information.cholesky().ok_or(FirstOrderError::Singular)?;
    let mut per_mm2 = SMatrix::<f64, 6, 6>::zeros();
    for (p, &sigma) in object.iter().zip(sigma_px) {
        let jacobian = pixel_jacobian(camera, pose, p);
        let image_per_mm = jacobian.fixed_view::<2, 3>(0, 3) * pose.rotation.matrix();
        // Aᵢ Bᵢ = (JᵀWJ)⁻¹ Jᵢᵀ Wᵢ Bᵢ, one 6×3 block per point.
        let block = cholesky.solve(&(jacobian.transpose() * image_per_mm * weight(sigma)?));
        per_mm2 += block * block.transpose();
    }
    Ok(FabricationSensitivity { per_mm2 })
}

/// The centre tolerance of a layout over a scenario grid.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FabricationTolerance {
    /// The share it is set for ([`TOLERANCE_SHARE`]).
    pub share: f64,
    /// The largest σ_fab (per axis, per sphere) at which the fabrication
    /// RMS rotation error is at most `share` × the noise RMS rotation error
    /// in every visible scenario, mm.
    pub max_sigma_mm: f64,
    /// The centre tolerance ±T per axis: a part whose every centre
    /// coordinate is within ±T of nominal has a per-axis RMS deviation of at
    /// most T whatever the distribution, so T = `max_sigma_mm`.
    pub tolerance_mm: f64,
    /// The scenario that sets it.
    pub worst_scenario: Scenario,
    /// The noise RMS rotation error there, degrees.
    pub noise_rotation_deg: f64,
    /// The fabrication RMS rotation error there per mm of σ_fab, degrees.
    pub rotation_deg_per_mm: f64,
    /// Visible scenarios with noise σ > 0 it was taken over.
    pub scenarios: usize,
    /// Scenarios of the grid.
    pub grid_scenarios: usize,
}

/// The centre tolerance of `object` (spheres of `sphere_diameter_mm`) seen
/// by `camera` over `grid`: over every scenario in which every sphere is
/// visible and σ > 0, the smallest `share · rms_noise / rms_fab(1 mm)`.
pub fn tolerance(
    camera: &Camera,
    grid: &ScenarioGrid,
    object: &[Vector3<f64>],
    sphere_diameter_mm: f64,
    share: f64,
) -> Result<FabricationTolerance, FabricationError> {
    if !(share > 0.0 && share <= 1.0) {
        return Err(FabricationError::BadShare(share));
    }
    let scenarios = grid.scenarios();
    let mut best: Option<(f64, Scenario, f64, f64)> = None;
    let mut used = 0;
    for scenario in &scenarios {
        if scenario.sigma_px.is_nan() || scenario.sigma_px <= 0.0 {
            continue;
        }
        let pose = scenario.pose();
        let images = sphere_images(camera, &pose, object, sphere_diameter_mm);
        if !visibility(&images, camera).is_visible() {
            continue;
        }
        let sigmas = vec![scenario.sigma_px; object.len()];
        let (Ok(noise), Ok(fabrication)) = (
            pose_covariance(camera, &pose, object, &sigmas),
            sensitivity(camera, &pose, object, &sigmas),
        ) else {
            continue;
        };
        used += 1;
        let noise_deg = noise.rms_rotation_deg();
        let per_mm = fabrication.rotation_deg_per_mm();
        let allowed = share * noise_deg / per_mm;
        if best.is_none_or(|(b, ..)| allowed < b) {
            best = Some((allowed, *scenario, noise_deg, per_mm));
        }
    }
    let (max_sigma_mm, worst_scenario, noise_rotation_deg, rotation_deg_per_mm) =
        best.ok_or(FabricationError::NoVisibleScenario)?;
    Ok(FabricationTolerance {
        share,
        max_sigma_mm,
        tolerance_mm: max_sigma_mm,
        worst_scenario,
        noise_rotation_deg,
        rotation_deg_per_mm,
        scenarios: used,
        grid_scenarios: scenarios.len(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::layout::Layout;
    use crate::synthetic::stream_rng;
    use approx::assert_relative_eq;
    use nalgebra::Rotation3;
    use nalgebra::Vector2;
    use rand::Rng;
    use rand_distr::StandardNormal;

    fn pose() -> Pose {
        Pose::new(
            Rotation3::from_euler_angles(0.4, -0.2, 0.1),
            Vector3::new(30.0, -20.0, 450.0),
        )
    }

    /// `∂pixel/∂X` against central differences of the projection.
    #[test]
    fn object_point_jacobian_matches_central_differences() {
        let camera = Camera::paper_with_distortion();
        let pose = pose();
        let p = Vector3::new(20.0, -35.0, 15.0);
        let analytic = object_point_jacobian(&camera, &pose, &p);
        let h = 1e-5;
        for k in 0..3 {
            let mut d = Vector3::zeros();
            d[k] = h;
            let pixel = |q: Vector3<f64>| camera.project(&pose.transform(&q)).unwrap();
            let numeric = (pixel(p + d) - pixel(p - d)) / (2.0 * h);
            assert_relative_eq!(
                analytic.column(k).into_owned(),
                numeric,
                epsilon = 1e-6,
                max_relative = 1e-6
            );
        }
    }

    /// G is the covariance of the Gauss–Newton step on the image bias of
    /// centre errors: for one fixed error pattern, the step equals Σ AᵢBᵢeᵢ
    /// as recovered by refining with ML on the biased image.
    #[test]
    fn sensitivity_predicts_the_refined_pose_of_a_slightly_misprinted_part() {
        let camera = Camera::new(1300.0, 1300.0, 653.0, 508.0, 1280, 720, [0.0; 5]).unwrap();
        let pose = pose();
        let object = Layout::paper_biprism().positions();
        let sigmas = vec![0.5; object.len()];
        let g = sensitivity(&camera, &pose, &object, &sigmas).unwrap();
        // Draw many tiny error patterns: the sample covariance of the
        // refined poses' rotation approaches trace(G_ωω)·σ².
        let sigma_fab = 1e-3;
        let mut sum = 0.0;
        let draws = 300;
        for k in 0..draws {
            let mut rng = stream_rng(5, 0, k);
            let image: Vec<Vector2<f64>> = object
                .iter()
                .map(|p| {
                    let e = Vector3::from_fn(|_, _| rng.sample::<f64, _>(StandardNormal));
                    let pixel = camera
                        .project(&pose.transform(&(p + e * sigma_fab)))
                        .unwrap();
                    camera.pixel_to_normalised(&pixel).unwrap()
                })
                .collect();
            let refined = crate::pnp::ml::refine(&pose, &object, &image);
            sum += (refined.rotation * pose.rotation.inverse())
                .scaled_axis()
                .norm_squared();
        }
        let measured_deg = (sum / draws as f64).sqrt().to_degrees();
        let predicted_deg = g.rotation_deg_per_mm() * sigma_fab;
        assert_relative_eq!(measured_deg, predicted_deg, max_relative = 0.1);
    }

    #[test]
    fn zero_sigma_adds_nothing_and_bad_inputs_are_errors() {
        let camera = Camera::paper();
        let pose = pose();
        let object = Layout::paper_biprism().positions();
        let sigmas = vec![0.5; object.len()];
        let noise = pose_covariance(&camera, &pose, &object, &sigmas).unwrap();
        let g = sensitivity(&camera, &pose, &object, &sigmas).unwrap();
        assert_eq!(g.add_to(&noise, 0.0), noise);
        assert!(g.rotation_deg_per_mm() > 0.0);
        assert!(matches!(
            sensitivity(&camera, &pose, &object, &[0.5]),
            Err(FirstOrderError::MismatchedLengths { .. })
        ));
        let grid = ScenarioGrid::paper_protocol(30.0);
        assert_eq!(
            tolerance(&camera, &grid, &object, 10.0, 0.0).unwrap_err(),
            FabricationError::BadShare(0.0)
        );
    }

    /// The tolerance meets its share exactly in the worst scenario and
    /// within it everywhere else.
    #[test]
    fn tolerance_holds_the_share_in_every_visible_scenario() {
        let camera = Camera::paper();
        let object = Layout::paper_biprism().positions();
        let grid = ScenarioGrid::paper_protocol(10.0);
        let t = tolerance(&camera, &grid, &object, 10.0, TOLERANCE_SHARE).unwrap();
        assert!(t.scenarios > 0 && t.scenarios <= t.grid_scenarios);
        assert_relative_eq!(
            t.rotation_deg_per_mm * t.max_sigma_mm,
            TOLERANCE_SHARE * t.noise_rotation_deg,
            max_relative = 1e-12
        );
        for scenario in grid.scenarios() {
            let pose = scenario.pose();
            let images = sphere_images(&camera, &pose, &object, 10.0);
            if !visibility(&images, &camera).is_visible() {
                continue;
            }
            let sigmas = vec![scenario.sigma_px; object.len()];
            let noise = pose_covariance(&camera, &pose, &object, &sigmas).unwrap();
            let g = sensitivity(&camera, &pose, &object, &sigmas).unwrap();
            assert!(
                g.rotation_deg_per_mm() * t.max_sigma_mm
                    <= TOLERANCE_SHARE * noise.rms_rotation_deg() * (1.0 + 1e-9)
            );
        }
    }
}
