//! The seed paper's error-transfer model (§3.3, eqs. 26–30) and Qu & Hou's
//! planar model (§2.2, eqs. 11–13).
//!
//! # Per segment (eqs. 28–29)
//! The garbled eq. 27 is read as in docs/paper-notes.md, "Eqs. 26–29: error
//! transfer along one segment".
//! For a segment from the reference point P0 (object origin, image
//! `(u0, v0)`, depth tz) to a feature P_i, with 3D length d, projected length m
//! on the normalised image plane, `m_o = √(u0² + v0²)`, angle β to the optical
//! axis and `d_z = P_iz^c − tz`:
//! * `δd/δm = tz² m / (d sin²β)`, `δd/δm_o = d_z² m_o / (d sin²β)`;
//! * `δβ/δm = tz² m / (d² sinβ √cosβ)`, `δβ/δm_o = d_z² m_o / (d² sinβ √cosβ)`.
//!
//! # From segments to a pose-error prediction (our aggregation)
//! The paper gives sensitivities per segment; a layout's pose error needs
//! them combined. We treat every segment through the reference point as a
//! measurement of its camera-frame direction u:
//! * its angle β to the optical axis, with standard deviation
//!   `σ_β = √((δβ/δm · σ_m)² + (δβ/δm_o · σ_mo)²)`, which constrains the
//!   rotation component along `e_γ ∝ z × u`;
//! * its image azimuth γ, with `σ_γ = σ_⊥ / m` (the perpendicular image noise
//!   over the projected length: Qu & Hou's eq. 11 scaling `∝ d/l`), which
//!   moves u by `sinβ · δγ` and constrains the rotation component along
//!   `e_β`, the unit vector in the plane of u and z perpendicular to u.
//!
//! Each constraint adds `a aᵀ / σ²` to a 3×3 information matrix on the
//! rotation vector ω; the predicted covariance is its inverse and the RMS
//! rotation error `√trace`. Segment lengths d give the scale, hence depth:
//! the relative scale error is `(Σ_i (d_i / σ_d,i)²)^(−1/2)`, `δtz = tz · s`,
//! and `δtx² = (tz σ_mo)² + (u0 δtz)²` (likewise y), since `tx = u0 tz`.
//!
//! Image noise of σ px at each endpoint gives `σ_mo = σ_0 / f`,
//! `σ_m = √(σ_0² + σ_i²) / f` (both endpoints, along the segment) and
//! `σ_⊥ = √(σ_0² + σ_i²) / f` (across it), f being the mean focal length.
//! Where `sinβ` or `cosβ` vanishes the paper's ratios are infinite and the
//! segment contributes no information on β.

use crate::camera::Camera;
use crate::pose::Pose;
use nalgebra::{Matrix3, Vector2, Vector3};

/// Below this, sinβ or cosβ counts as zero (the eq. 29 ratios are infinite).
pub const ANGLE_EPSILON: f64 = 1e-9;

/// The eqs. 28–29 sensitivities of one segment through the reference point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SegmentSensitivity {
    /// 3D length d, mm.
    pub length_mm: f64,
    /// Projected length m on the normalised image plane.
    pub projected_length: f64,
    /// `m_o`: distance of the reference image from the principal point.
    pub m_o: f64,
    /// β: angle between the segment and the optical axis, radians, in [0, π/2].
    pub beta: f64,
    /// `d_z = P_iz^c − tz`, mm.
    pub depth_offset_mm: f64,
    /// tz: depth of the reference point, mm.
    pub depth_mm: f64,
    /// δd/δm (eq. 28), mm per normalised unit.
    pub length_per_m: f64,
    /// δd/δm_o (eq. 28), mm per normalised unit.
    pub length_per_m_o: f64,
    /// δβ/δm (eq. 29), radians per normalised unit.
    pub beta_per_m: f64,
    /// δβ/δm_o (eq. 29), radians per normalised unit.
    pub beta_per_m_o: f64,
}

impl SegmentSensitivity {
    /// Evaluates eqs. 26–29 for the segment from `reference` to `point`
    /// (object coordinates, mm) under `pose`.
    pub fn new(pose: &Pose, reference: &Vector3<f64>, point: &Vector3<f64>) -> Self {
        let c0 = pose.transform(reference);
        let ci = pose.transform(point);
        let depth_mm = c0.z;
        let image0 = Vector2::new(c0.x / c0.z, c0.y / c0.z);
        let imagei = Vector2::new(ci.x / ci.z, ci.y / ci.z);
        let m_o = image0.norm();
        let m = (imagei - image0).norm();
        let segment = ci - c0;
        let length_mm = segment.norm();
        let cos_beta = (segment.z.abs() / length_mm).min(1.0);
        let beta = cos_beta.acos();
        let sin_beta = beta.sin();
        let d_z = ci.z - depth_mm;
        let tz2 = depth_mm * depth_mm;
        let (length_per_m, length_per_m_o) = if sin_beta > ANGLE_EPSILON {
            let denominator = length_mm * sin_beta * sin_beta;
            (tz2 * m / denominator, d_z * d_z * m_o / denominator)
        } else {
            (f64::INFINITY, f64::INFINITY)
        };
        let (beta_per_m, beta_per_m_o) = if sin_beta > ANGLE_EPSILON && cos_beta > ANGLE_EPSILON {
            let denominator = length_mm * length_mm * sin_beta * cos_beta.sqrt();
            (tz2 * m / denominator, d_z * d_z * m_o / denominator)
        } else {
            (f64::INFINITY, f64::INFINITY)
        };
        Self {
            length_mm,
            projected_length: m,
            m_o,
            beta,
            depth_offset_mm: d_z,
            depth_mm,
            length_per_m,
            length_per_m_o,
            beta_per_m,
            beta_per_m_o,
        }
    }

    /// The paper's angular factor `1 / (sinβ √cosβ)`; its minimum is at
    /// β = arctan √2 ≈ 54.7° (§4.3).
    pub fn angular_factor(beta: f64) -> f64 {
        1.0 / (beta.sin() * beta.cos().sqrt())
    }
}

/// A transfer-model prediction for one pose.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct TransferPrediction {
    /// Predicted RMS rotation error, degrees (None when the segments do not
    /// constrain all three rotation axes).
    pub rms_rotation_deg: Option<f64>,
    /// Predicted RMS translation error, mm (None when no segment fixes scale).
    pub rms_translation_mm: Option<f64>,
}

/// Predicts the pose error of `object` seen under `pose` with per-point pixel
/// noise `sigma_px`, from the segments joining `reference` to every other
/// point (module docs give the aggregation).
pub fn predict(
    camera: &Camera,
    pose: &Pose,
    object: &[Vector3<f64>],
    reference: usize,
    sigma_px: &[f64],
) -> TransferPrediction {
    let focal = 0.5 * (camera.fx() + camera.fy());
    let sigma_reference = sigma_px[reference] / focal;
    let optical_axis = Vector3::z();
    let mut rotation_information = Matrix3::zeros();
    let mut scale_information = 0.0;
    for (index, point) in object.iter().enumerate() {
        if index == reference {
            continue;
        }
        let segment = SegmentSensitivity::new(pose, &object[reference], point);
        let sigma_endpoints =
            (sigma_px[reference].powi(2) + sigma_px[index].powi(2)).sqrt() / focal;
        let direction = (pose.rotation * (point - object[reference])).normalize();
        // β: rotation about e_γ ∝ z × u changes the angle to the axis.
        let across = optical_axis - direction * direction.dot(&optical_axis);
        let sigma_beta =
            (segment.beta_per_m * sigma_endpoints).hypot(segment.beta_per_m_o * sigma_reference);
        if across.norm() > ANGLE_EPSILON && sigma_beta.is_finite() && sigma_beta > 0.0 {
            let e_beta = across.normalize();
            let axis = direction.cross(&e_beta);
            rotation_information += axis * axis.transpose() / (sigma_beta * sigma_beta);
        }
        // γ: the image azimuth; rotation about e_β moves u by sinβ·δγ.
        if segment.projected_length > 0.0 && across.norm() > ANGLE_EPSILON {
            let sigma_gamma = sigma_endpoints / segment.projected_length;
            let e_beta = across.normalize();
            let sigma_direction = segment.beta.sin() * sigma_gamma;
            rotation_information +=
                e_beta * e_beta.transpose() / (sigma_direction * sigma_direction);
        }
        let sigma_length = (segment.length_per_m * sigma_endpoints)
            .hypot(segment.length_per_m_o * sigma_reference);
        if sigma_length.is_finite() && sigma_length > 0.0 {
            scale_information += (segment.length_mm / sigma_length).powi(2);
        }
    }
    let rms_rotation_deg = rotation_information
        .try_inverse()
        .map(|covariance| covariance.trace().max(0.0).sqrt().to_degrees())
        .filter(|v| v.is_finite());
    let rms_translation_mm = (scale_information > 0.0).then(|| {
        let c0 = pose.transform(&object[reference]);
        let depth = c0.z;
        let relative_scale = scale_information.sqrt().recip();
        let depth_error = depth * relative_scale;
        let (u0, v0) = (c0.x / c0.z, c0.y / c0.z);
        let lateral = |u: f64| (depth * sigma_reference).powi(2) + (u * depth_error).powi(2);
        (lateral(u0) + lateral(v0) + depth_error * depth_error).sqrt()
    });
    TransferPrediction {
        rms_rotation_deg,
        rms_translation_mm,
    }
}

/// Qu & Hou's planar-target model (paper eqs. 11–13): standard deviations of
/// the azimuth γ, pitch θ and tilt φ per pixel of feature noise, for a planar
/// target of neighbouring-point spacing `size_mm` at depth `depth_mm`, with
/// `a/f = 1/f_px`. Angles in radians.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct QuHou {
    /// σ_γ/σ_p (eq. 11), radians per pixel.
    pub azimuth_per_px: f64,
    /// σ_θ/σ_p (eq. 12), radians per pixel.
    pub pitch_per_px: f64,
    /// σ_φ/σ_p (eq. 13), radians per pixel.
    pub tilt_per_px: f64,
}

impl QuHou {
    /// Evaluates eqs. 11–13.
    pub fn new(focal_px: f64, depth_mm: f64, size_mm: f64, pitch: f64, tilt: f64) -> Self {
        let base = 1.0 / (2.0 * focal_px);
        let ratio = depth_mm / size_mm;
        Self {
            azimuth_per_px: base * ratio,
            pitch_per_px: base * ratio * ratio * pitch.cos().abs(),
            tilt_per_px: base * ratio * ratio * tilt.cos().abs(),
        }
    }

    /// Combined RMS rotation error for σ px of feature noise, degrees.
    pub fn rms_rotation_deg(&self, sigma_px: f64) -> f64 {
        (sigma_px
            * (self.azimuth_per_px.powi(2) + self.pitch_per_px.powi(2) + self.tilt_per_px.powi(2))
                .sqrt())
        .to_degrees()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;
    use nalgebra::Rotation3;

    #[test]
    fn angular_factor_is_smallest_at_54_7_degrees() {
        let best = (1..900)
            .map(|tenth| (tenth as f64 / 10.0).to_radians())
            .min_by(|a, b| {
                SegmentSensitivity::angular_factor(*a)
                    .total_cmp(&SegmentSensitivity::angular_factor(*b))
            })
            .unwrap();
        assert_relative_eq!(
            best.to_degrees(),
            2f64.sqrt().atan().to_degrees(),
            epsilon = 0.1
        );
    }

    #[test]
    fn eq26_holds_for_the_segment() {
        // (d sinβ)² = tz² m² + m_o² d_z² + 2 (u_ix u0 + v_ix v0) tz d_z.
        let pose = Pose::new(
            Rotation3::from_euler_angles(0.4, -0.3, 0.2),
            Vector3::new(400.0, -250.0, 3000.0),
        );
        let reference = Vector3::zeros();
        let point = Vector3::new(10.0, 35.0, 20.0);
        let s = SegmentSensitivity::new(&pose, &reference, &point);
        let c0 = pose.transform(&reference);
        let ci = pose.transform(&point);
        let (u0, v0) = (c0.x / c0.z, c0.y / c0.z);
        let (uix, vix) = (ci.x / ci.z - u0, ci.y / ci.z - v0);
        let rhs = s.depth_mm.powi(2) * s.projected_length.powi(2)
            + s.m_o.powi(2) * s.depth_offset_mm.powi(2)
            + 2.0 * (uix * u0 + vix * v0) * s.depth_mm * s.depth_offset_mm;
        // Eq. 26 follows from the paraperspective relation (eq. 25), which is
        // first order in d/tz (here about 1/70): compare to that order.
        let lhs = (s.length_mm * s.beta.sin()).powi(2);
        assert_relative_eq!(lhs, rhs, max_relative = 0.05);
    }

    #[test]
    fn predictions_scale_with_noise_and_grow_with_depth() {
        let camera = Camera::paper();
        let object = crate::synthetic::biprism_points(50.0);
        let pose = |depth| {
            Pose::new(
                Rotation3::from_euler_angles(0.5, 0.3, 0.1),
                Vector3::new(20.0, 10.0, depth),
            )
        };
        let near = predict(&camera, &pose(300.0), &object, 0, &[0.5; 7]);
        let far = predict(&camera, &pose(900.0), &object, 0, &[0.5; 7]);
        let noisier = predict(&camera, &pose(300.0), &object, 0, &[1.0; 7]);
        let (near_r, far_r) = (
            near.rms_rotation_deg.unwrap(),
            far.rms_rotation_deg.unwrap(),
        );
        assert!(far_r > 2.0 * near_r, "{near_r} {far_r}");
        assert_relative_eq!(
            noisier.rms_rotation_deg.unwrap(),
            2.0 * near_r,
            max_relative = 1e-9
        );
        assert!(far.rms_translation_mm.unwrap() > near.rms_translation_mm.unwrap());
    }

    #[test]
    fn qu_hou_matches_equations() {
        let model = QuHou::new(1300.0, 500.0, 50.0, 0.0, 60f64.to_radians());
        assert_relative_eq!(model.azimuth_per_px, 10.0 / 2600.0);
        assert_relative_eq!(model.pitch_per_px, 100.0 / 2600.0);
        assert_relative_eq!(model.tilt_per_px, 50.0 / 2600.0, max_relative = 1e-12);
    }
}
