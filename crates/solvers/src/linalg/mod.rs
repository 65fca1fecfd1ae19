//! Small dense linear algebra for the hot path, fixed-size and
//! allocation-free: the few smallest eigenpairs of a small symmetric matrix
//! ([`smallest_eigenpairs`], in `eigenpairs.rs`), the 3×3 symmetric
//! eigenproblem, one-sided Jacobi orthogonalisation and a square-root-free
//! Cholesky solve ([`solve_positive_definite`]) (the three in `small.rs`),
//! and the eigenvalues of a small non-symmetric matrix ([`nonsymmetric`]).

mod eigenpairs;
pub mod nonsymmetric;
mod small;

pub use eigenpairs::{smallest_eigenpairs, EigenError, SmallestEigenpairs};

use nalgebra::Vector3;

/// Two unit vectors that make a right-handed orthonormal frame with the
/// unit `axis`: `e1 = axis × h / |axis × h|` with `h` the x axis (the y
/// axis when `axis` is within about 25° of x), and `e2 = axis × e1`. The
/// same axis always gives the same pair, so sight lines spread around it
/// are reproducible.
///
/// ```
/// use layout_opt_solvers::linalg::perpendicular_pair;
/// use nalgebra::Vector3;
/// let axis = Vector3::new(1.0, 2.0, 2.0) / 3.0;
/// let (e1, e2) = perpendicular_pair(&axis);
/// assert!(e1.dot(&axis).abs() < 1e-15 && e2.dot(&axis).abs() < 1e-15);
/// assert!((e1.norm() - 1.0).abs() < 1e-15 && e1.dot(&e2).abs() < 1e-15);
/// assert!((axis.cross(&e1) - e2).norm() < 1e-15);
/// ```
pub fn perpendicular_pair(axis: &Vector3<f64>) -> (Vector3<f64>, Vector3<f64>) {
    let helper = if axis.x.abs() < 0.9 {
        Vector3::x()
    } else {
        Vector3::y()
    };
    let e1 = axis.cross(&helper).normalize();
    let e2 = axis.cross(&e1);
    (e1, e2)
}
pub use small::{
    orthogonalise_columns_3x3, solve_positive_definite, symmetric_eigen_3x3, JACOBI_TOLERANCE,
    ONE_SIDED_JACOBI_TOLERANCE,
};
