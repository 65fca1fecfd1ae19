//! Normalised direct linear transform with orthonormalisation (Hartley &
//! Zisserman, *Multiple View Geometry*, 2nd ed., §7.1 and §4.4; paper refs
//! [32, 33]).
//!
//! With calibrated, normalised image points the 3×4 projection matrix is
//! `P = λ [R | t]`. Object points are centred and scaled to RMS distance √3,
//! image points to RMS distance √2 (Hartley's normalisation); the 12 entries
//! of the normalised P are the eigenvector of `AᵀA` for its smallest
//! eigenvalue (A is the 2n×12 DLT design matrix, accumulated directly as
//! 12×12; [`crate::linalg::smallest_eigenpairs`] computes only that
//! pair). After denormalisation the sign is fixed so that `det(P₁:₃) > 0`,
//! λ is the mean singular value of `P₁:₃` (one-sided Jacobi,
//! [`crate::linalg::orthogonalise_columns_3x3`]), R its nearest rotation
//! and `t = p₄ / λ`.
//!
//! Requirements: n ≥ 6 noncoplanar points (11 degrees of freedom; a planar
//! set makes the system rank-deficient).

use super::{Candidates, Method, PnpError};
use crate::linalg::{orthogonalise_columns_3x3, smallest_eigenpairs, EigenError};
use crate::pose::{nearest_rotation, Pose};
use nalgebra::{Matrix3, Matrix3x4, Matrix4, SMatrix, SVector, Vector2, Vector3};
use smallvec::smallvec;

/// DLT needs six correspondences for its eleven unknowns.
pub const MIN_POINTS: usize = 6;

/// `dlt`: normalised DLT with orthonormalisation (Hartley & Zisserman).
pub const DLT: Method = Method {
    name: "dlt",
    display_name: "DLT",
    description: "normalised DLT with orthonormalisation (Hartley & Zisserman; paper refs [32,33])",
    min_points: MIN_POINTS,
    accepts_coplanar: false,
    exact: true,
    start: None,
    solve,
};

/// Solves the DLT. One candidate.
pub fn solve(object: &[Vector3<f64>], image: &[Vector2<f64>]) -> Result<Candidates, PnpError> {
    let count = object.len() as f64;
    let object_centroid = object.iter().sum::<Vector3<f64>>() / count;
    let image_centroid = image.iter().sum::<Vector2<f64>>() / count;
    let object_rms = (object
        .iter()
        .map(|p| (p - object_centroid).norm_squared())
        .sum::<f64>()
        / count)
        .sqrt();
    let image_rms = (image
        .iter()
        .map(|m| (m - image_centroid).norm_squared())
        .sum::<f64>()
        / count)
        .sqrt();
    if image_rms.is_nan() || image_rms <= 0.0 {
        return Err(PnpError::Degenerate {
            solver: "DLT",
            reason: "the image points have no extent",
        });
    }
    let object_scale = 3f64.sqrt() / object_rms;
    let image_scale = 2f64.sqrt() / image_rms;

    let mut ata = SMatrix::<f64, 12, 12>::zeros();
    for (p, m) in object.iter().zip(image) {
        let q = (p - object_centroid) * object_scale;
        let n = (m - image_centroid) * image_scale;
        let h = [q.x, q.y, q.z, 1.0];
        let mut row_u = SVector::<f64, 12>::zeros();
        let mut row_v = SVector::<f64, 12>::zeros();
        for c in 0..4 {
            row_u[c] = h[c];
            row_u[8 + c] = -n.x * h[c];
            row_v[4 + c] = h[c];
            row_v[8 + c] = -n.y * h[c];
        }
        ata.syger(1.0, &row_u, &row_u, 1.0);
        ata.syger(1.0, &row_v, &row_v, 1.0);
    }
    ata.fill_upper_triangle_with_lower_triangle();
    // Only the eigenvector of the smallest eigenvalue is needed.
    let p = smallest_eigenpairs::<12, 1>(&ata)
        .map_err(|error| PnpError::Degenerate {
            solver: "DLT",
            reason: match error {
                EigenError::NonFinite { .. } => "AᵀA has a non-finite entry",
                _ => "the eigen-decomposition of AᵀA did not converge",
            },
        })?
        .vectors[0];
    let normalised = Matrix3x4::from_fn(|r, c| p[4 * r + c]);

    // Denormalise: P = T_image⁻¹ P̃ T_object.
    let mut object_transform = Matrix4::identity() * object_scale;
    object_transform[(3, 3)] = 1.0;
    object_transform
        .fixed_view_mut::<3, 1>(0, 3)
        .copy_from(&(-object_centroid * object_scale));
    let image_inverse = Matrix3::new(
        1.0 / image_scale,
        0.0,
        image_centroid.x,
        0.0,
        1.0 / image_scale,
        image_centroid.y,
        0.0,
        0.0,
        1.0,
    );
    let mut projection: Matrix3x4<f64> = image_inverse * normalised * object_transform;
    let mut left: Matrix3<f64> = projection.fixed_view::<3, 3>(0, 0).into_owned();
    if left.determinant() < 0.0 {
        projection = -projection;
        left = -left;
    }
    // Singular values: the column norms of `left · V` (scaled to unit
    // max-norm for the Jacobi sweep, and back).
    let max_abs = left.amax();
    let scale = if max_abs > 0.0 && max_abs.is_finite() {
        let (scaled_left, _) = orthogonalise_columns_3x3(&(left / max_abs));
        let sum: f64 = scaled_left.column_iter().map(|c| c.norm()).sum();
        sum / 3.0 * max_abs
    } else {
        f64::NAN
    };
    if !(scale > 0.0 && scale.is_finite()) {
        return Err(PnpError::Degenerate {
            solver: "DLT",
            reason: "the projection matrix has no rotation part",
        });
    }
    let rotation = nearest_rotation(&left);
    let translation = projection.column(3) / scale;
    Ok(smallvec![Pose::new(rotation, translation)])
}
