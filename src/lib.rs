//! layout-opt: design noncoplanar 3D fiducial markers for close-range camera
//! pose estimation, scored by how badly image noise spoils the pose.
//!
//! The science is Hu, Li & Tan, "Research on a Camera Position Measurement
//! Method based on a Parallel Perspective Error Transfer Model" (the seed
//! paper): an error-transfer model and a PnP solver (paraperspective
//! initialisation + error-weighted Gauss–Newton over EPnP's β).
//!
//! Conventions: millimetres and pixels; OpenCV's camera frame; a
//! [`pose::Pose`] maps object coordinates to camera coordinates,
//! `X_cam = R · X_obj + t`.
#![warn(missing_docs)]

pub mod batch;
pub mod camera;
pub mod characterise;
pub mod config;
pub mod conformance;
pub mod ellipse;
pub mod error_model;
pub mod family;
pub mod files;
pub mod identifiability;
pub mod kernel;
pub mod layout;
pub mod mesh;
pub mod montecarlo;
pub mod noise;
pub mod observer;
pub mod render;
pub mod report;
pub mod reproduce;
pub mod scenario;
pub mod search;
pub mod set;
pub mod statistics;
pub mod track;
pub mod validate;
pub mod visibility;
pub mod volume;

// The solver crate's modules, under the paths they had when they lived
// here (`layout_opt::pnp::Solver`, `layout_opt::pose::Pose`, …); the camera
// model comes through `camera`, which adds reading camera files.
pub use layout_opt_solvers::{linalg, pnp, pose, sphere_image, spread, synthetic};
