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
pub use small::{
    orthogonalise_columns_3x3, solve_positive_definite, symmetric_eigen_3x3, JACOBI_TOLERANCE,
    ONE_SIDED_JACOBI_TOLERANCE,
};
