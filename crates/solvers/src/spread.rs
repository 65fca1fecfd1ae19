//! The principal spread of a point set, and the tolerances below which a
//! point set counts as degenerate (duplicate, collinear or coplanar points).
//! Layout validation and PnP input validation share them, so a layout that
//! passes one passes the other.

use crate::linalg::symmetric_eigen_3x3;
use nalgebra::{Matrix3, Vector3};

/// Relative size of the smallest principal extent of the object points,
/// below which they count as coplanar (and of the second, as collinear).
pub const PLANARITY_TOLERANCE: f64 = 1e-6;
/// Two object points closer than this fraction of the point spread are
/// duplicates.
pub const DUPLICATE_TOLERANCE: f64 = 1e-9;

/// Principal spread of a point set: centroid and the singular values
/// (square roots of the scatter eigenvalues, largest first) with their axes
/// as columns.
#[derive(Debug, Clone, Copy)]
pub struct Spread {
    /// Centroid of the points.
    pub centroid: Vector3<f64>,
    /// RMS extents along the principal axes, largest first.
    pub extents: Vector3<f64>,
    /// Principal axes as columns, in the order of `extents`.
    pub axes: Matrix3<f64>,
}

impl Spread {
    /// Computes the principal spread of `points` (non-empty).
    pub fn of(points: &[Vector3<f64>]) -> Spread {
        let count = points.len() as f64;
        let centroid = points.iter().sum::<Vector3<f64>>() / count;
        let mut scatter = Matrix3::zeros();
        for p in points {
            let d = p - centroid;
            scatter += d * d.transpose();
        }
        // Largest first, so the extents come out ordered.
        let (variances, axes) = symmetric_eigen_3x3(&(scatter / count));
        let extents = variances.map(|v| v.max(0.0).sqrt());
        Spread {
            centroid,
            extents,
            axes,
        }
    }
}
