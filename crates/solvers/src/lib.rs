//! layout-opt-solvers: fourteen Perspective-n-Point solvers behind one
//! interface, rigid poses and their error measures, the OpenCV pinhole
//! camera with Brown–Conrady distortion, and where a sphere's image centre
//! lies. The solver part of layout-opt, a crate of its own so that a
//! program that only solves poses compiles nalgebra and smallvec and
//! little else.
//!
//! Conventions: millimetres and pixels; OpenCV's camera frame; a
//! [`pose::Pose`] maps object coordinates to camera coordinates,
//! `X_cam = R · X_obj + t`. The solvers work on undistorted normalised image
//! points ([`camera::Camera::pixel_to_normalised`]).
//!
//! ```
//! use layout_opt_solvers::camera::Camera;
//! use layout_opt_solvers::pnp::Solver;
//! use layout_opt_solvers::pose::{rotation_error_deg, Pose};
//! use nalgebra::{Rotation3, Vector3};
//!
//! let camera = Camera::paper();
//! let object = [
//!     Vector3::new(0.0, 0.0, 0.0),
//!     Vector3::new(50.0, 0.0, 0.0),
//!     Vector3::new(0.0, 50.0, 0.0),
//!     Vector3::new(0.0, 0.0, 50.0),
//!     Vector3::new(-50.0, 0.0, 0.0),
//!     Vector3::new(0.0, -50.0, 0.0),
//! ];
//! let truth = Pose::new(Rotation3::from_euler_angles(0.2, -0.1, 0.3), Vector3::new(10.0, -5.0, 600.0));
//! let image: Vec<_> = object
//!     .iter()
//!     .map(|p| {
//!         let pixel = camera.project(&truth.transform(p)).unwrap();
//!         camera.pixel_to_normalised(&pixel).unwrap()
//!     })
//!     .collect();
//! let pose = Solver::ParallelWeighted.solve_best(&object, &image)?;
//! assert!(rotation_error_deg(&truth.rotation, &pose.rotation) < 1e-6);
//! # Ok::<(), layout_opt_solvers::pnp::PnpError>(())
//! ```
//!
//! Features: `serde` (Serialize and Deserialize for poses, solvers and the
//! camera) and `synthetic` (the `synthetic` module: seeded random streams,
//! poses and noisy views). Neither is on by default.
#![warn(missing_docs)]

pub mod camera;
pub mod linalg;
pub mod pnp;
pub mod pose;
pub mod sphere_image;
pub mod spread;
#[cfg(feature = "synthetic")]
pub mod synthetic;
