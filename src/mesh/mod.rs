//! Printable marker meshes (WIP).

pub mod extract;
pub mod geometry;
pub mod repair;
pub mod sdf;
pub mod trimesh;
