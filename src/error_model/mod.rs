//! Error models: how image noise becomes pose error.
//!
//! * [`first_order`]: the first-order pose covariance `Σ = (Jᵀ W J)⁻¹`, the
//!   Cramér–Rao limit for an unbiased estimator under Gaussian pixel noise.
//! * [`transfer`]: the seed paper's error-transfer model (eqs. 26–30) and Qu &
//!   Hou's planar model (eqs. 11–13).
//!
//! ```
//! use layout_opt::camera::Camera;
//! use layout_opt::error_model::first_order::pose_covariance_isotropic;
//! use layout_opt::layout::Layout;
//! use layout_opt::pose::Pose;
//! use nalgebra::{Rotation3, Vector3};
//!
//! let camera = Camera::paper();
//! let points = Layout::paper_biprism().positions();
//! let at = |depth| Pose::new(Rotation3::identity(), Vector3::new(0.0, 0.0, depth));
//! let near = pose_covariance_isotropic(&camera, &at(300.0), &points, 0.5).unwrap();
//! let far = pose_covariance_isotropic(&camera, &at(900.0), &points, 0.5).unwrap();
//! // Pose error grows with depth, and rotation error is a small angle.
//! assert!(far.rms_rotation_deg() > 2.0 * near.rms_rotation_deg());
//! assert!(far.rms_translation_mm() > near.rms_translation_mm());
//! assert!(near.rms_rotation_deg() > 0.0 && near.rms_rotation_deg() < 1.0);
//! ```

pub mod budget;
pub mod fabrication;
pub mod first_order;
pub mod transfer;
