//! Error models: how image noise becomes pose error.
//!
//! * [`first_order`]: the first-order pose covariance `Σ = (Jᵀ W J)⁻¹`, the
//!   Cramér–Rao limit for an unbiased estimator under Gaussian pixel noise.

pub mod first_order;
