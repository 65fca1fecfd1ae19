//! Error models: how image noise becomes pose error.
//!
//! * [`first_order`]: the first-order pose covariance `Σ = (Jᵀ W J)⁻¹`, the
//!   Cramér–Rao limit for an unbiased estimator under Gaussian pixel noise.
//! * [`transfer`]: the seed paper's error-transfer model (eqs. 26–30) and Qu &
//!   Hou's planar model (eqs. 11–13).

pub mod first_order;
pub mod transfer;
