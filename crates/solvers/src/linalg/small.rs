//! Direct methods for small fixed-size problems: the symmetric 3×3
//! eigenproblem by cyclic Jacobi, one-sided Jacobi orthogonalisation of 3×3
//! columns, and a square-root-free Cholesky solve. No heap allocation.

use nalgebra::{SMatrix, SVector};

/// A 3×3 off-diagonal entry is negligible, and the cyclic Jacobi method of
/// [`symmetric_eigen_3x3`] skips it, when it is at most this fraction of the
/// sum of the two diagonal magnitudes it couples (Rutishauser's test; the
/// rotation would change neither diagonal entry in double precision).
pub const JACOBI_TOLERANCE: f64 = f64::EPSILON / 4.0;
/// Cap on the cyclic Jacobi sweeps of [`symmetric_eigen_3x3`]; convergence is
/// quadratic and 3×3 matrices need four or five.
const JACOBI_MAX_SWEEPS: usize = 32;

/// Eigenvalues and orthonormal eigenvectors (as columns) of a symmetric 3×3
/// matrix, eigenvalues in descending order, without heap allocation.
///
/// Cyclic Jacobi (Golub & Van Loan, *Matrix Computations*, 4th ed., §8.5,
/// Algorithm 8.5.3, with the rotation of Rutishauser's `jacobi`): each
/// rotation zeroes one off-diagonal entry; sweeps repeat until every
/// off-diagonal entry is negligible next to its diagonal pair
/// ([`JACOBI_TOLERANCE`]). The eigenvalues have the accuracy of
/// `nalgebra::SymmetricEigen` (a small multiple of `ε‖A‖`, better for the
/// small eigenvalues of a scaled positive definite matrix), and repeated
/// eigenvalues get an orthonormal basis of their eigenspace. It replaces
/// `SymmetricEigen` on the point-spread path, where the general
/// tridiagonal-QR code cost about 1 µs per call.
///
/// Requirements: `a` symmetric and finite (only the upper triangle is read).
///
/// # Example
/// ```
/// use layout_opt_solvers::linalg::symmetric_eigen_3x3;
/// use nalgebra::Matrix3;
/// let a = Matrix3::new(2.0, 1.0, 0.0, 1.0, 2.0, 0.0, 0.0, 0.0, 5.0);
/// let (values, vectors) = symmetric_eigen_3x3(&a);
/// assert!((values[0] - 5.0).abs() < 1e-15 && (values[2] - 1.0).abs() < 1e-15);
/// let residual = a * vectors.column(2) - vectors.column(2) * values[2];
/// assert!(residual.norm() < 1e-15);
/// ```
#[allow(clippy::needless_range_loop)]
pub fn symmetric_eigen_3x3(
    a: &nalgebra::Matrix3<f64>,
) -> (nalgebra::Vector3<f64>, nalgebra::Matrix3<f64>) {
    let mut m = [[0.0f64; 3]; 3];
    for (i, row) in m.iter_mut().enumerate() {
        for (j, entry) in row.iter_mut().enumerate() {
            *entry = if i <= j { a[(i, j)] } else { a[(j, i)] };
        }
    }
    // Columns of the accumulated rotations, v[k] = k-th eigenvector.
    let mut v = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    for _ in 0..JACOBI_MAX_SWEEPS {
        let mut rotated = false;
        for (p, q, r) in [(0usize, 1usize, 2usize), (0, 2, 1), (1, 2, 0)] {
            let apq = m[p][q];
            if apq.abs() <= JACOBI_TOLERANCE * (m[p][p].abs() + m[q][q].abs()) {
                continue;
            }
            rotated = true;
            // t = tan θ, the smaller root of t² + 2 t θ' − 1 = 0 (G&VL 8.5.2).
            let theta = (m[q][q] - m[p][p]) / (2.0 * apq);
            let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
            let c = 1.0 / (t * t + 1.0).sqrt();
            let s = t * c;
            m[p][p] -= t * apq;
            m[q][q] += t * apq;
            m[p][q] = 0.0;
            m[q][p] = 0.0;
            let (arp, arq) = (m[r][p], m[r][q]);
            m[r][p] = c * arp - s * arq;
            m[p][r] = m[r][p];
            m[r][q] = s * arp + c * arq;
            m[q][r] = m[r][q];
            for row in 0..3 {
                let (vp, vq) = (v[p][row], v[q][row]);
                v[p][row] = c * vp - s * vq;
                v[q][row] = s * vp + c * vq;
            }
        }
        if !rotated {
            break;
        }
    }
    let mut order = [0usize, 1, 2];
    order.sort_by(|&x, &y| m[y][y].total_cmp(&m[x][x]));
    let values = nalgebra::Vector3::from_fn(|k, _| m[order[k]][order[k]]);
    let vectors = nalgebra::Matrix3::from_fn(|row, k| v[order[k]][row]);
    (values, vectors)
}

/// Two columns count as orthogonal in [`orthogonalise_columns_3x3`] when
/// `|a_p·a_q| ≤ ONE_SIDED_JACOBI_TOLERANCE · ‖a_p‖‖a_q‖`. The rounding error
/// of a computed 3-vector dot product is up to about 3ε of that product, so
/// a tighter test would keep rotating on noise (LAPACK `dgesvj` uses √m·ε).
pub const ONE_SIDED_JACOBI_TOLERANCE: f64 = 8.0 * f64::EPSILON;
/// Cap on the one-sided Jacobi sweeps of [`orthogonalise_columns_3x3`].
const ONE_SIDED_JACOBI_MAX_SWEEPS: usize = 32;

/// One-sided Jacobi (Hestenes 1958; Golub & Van Loan, *Matrix
/// Computations*, 4th ed., §8.6.3; Demmel & Veselić 1992): plane rotations
/// `V` applied from the right until the columns of `A V` are mutually
/// orthogonal. Returns `(A V, V)`: the columns of `A V` are `σ_k u_k` and
/// those of `V` the right singular vectors `v_k`, in no particular order, so
/// `A = (A V) Vᵀ` is a singular value decomposition with `U Σ = A V`.
///
/// A pair of columns counts as orthogonal when `|a_p·a_q| ≤`
/// [`ONE_SIDED_JACOBI_TOLERANCE`]` · ‖a_p‖‖a_q‖`. The singular values then have high
/// relative accuracy and the vectors of well-separated singular values are
/// accurate to about `ε / relative gap`, better than forming `AᵀA`. It
/// allocates nothing. A column whose norm falls to
/// `ONE_SIDED_JACOBI_TOLERANCE · ‖A‖_F` or below (rank deficiency) is left
/// alone: its direction is rounding noise, and rotating it against the
/// others would never pass the orthogonality test.
///
/// Requirements: `a` finite and of moderate scale (products of squared
/// column norms must neither overflow nor underflow; callers scale to unit
/// max-norm).
pub fn orthogonalise_columns_3x3(
    a: &nalgebra::Matrix3<f64>,
) -> (nalgebra::Matrix3<f64>, nalgebra::Matrix3<f64>) {
    let mut columns: [[f64; 3]; 3] = std::array::from_fn(|k| [a[(0, k)], a[(1, k)], a[(2, k)]]);
    let mut v = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    let dot = |x: &[f64; 3], y: &[f64; 3]| x[0] * y[0] + x[1] * y[1] + x[2] * y[2];
    let mut norms_sq: [f64; 3] = std::array::from_fn(|k| dot(&columns[k], &columns[k]));
    // A column at rounding level of ‖A‖ has no direction to speak of: it
    // is left alone (else a rank-deficient A would rotate it for ever).
    let frobenius_sq = norms_sq[0] + norms_sq[1] + norms_sq[2];
    let negligible_sq = ONE_SIDED_JACOBI_TOLERANCE * ONE_SIDED_JACOBI_TOLERANCE * frobenius_sq;
    for _ in 0..ONE_SIDED_JACOBI_MAX_SWEEPS {
        let mut rotated = false;
        for (p, q) in [(0usize, 1usize), (0, 2), (1, 2)] {
            let gamma = dot(&columns[p], &columns[q]);
            let (alpha, beta) = (norms_sq[p], norms_sq[q]);
            // Written so that NaN counts as orthogonal (no rotation).
            let coupled = gamma.abs() > ONE_SIDED_JACOBI_TOLERANCE * (alpha * beta).sqrt();
            if !coupled || alpha <= negligible_sq || beta <= negligible_sq {
                continue;
            }
            rotated = true;
            // The rotation that diagonalises [[α, γ], [γ, β]] (G&VL 8.5.2).
            let zeta = (beta - alpha) / (2.0 * gamma);
            let t = zeta.signum() / (zeta.abs() + (zeta * zeta + 1.0).sqrt());
            let c = 1.0 / (t * t + 1.0).sqrt();
            let s = t * c;
            for row in 0..3 {
                let (ap, aq) = (columns[p][row], columns[q][row]);
                columns[p][row] = c * ap - s * aq;
                columns[q][row] = s * ap + c * aq;
                let (vp, vq) = (v[p][row], v[q][row]);
                v[p][row] = c * vp - s * vq;
                v[q][row] = s * vp + c * vq;
            }
            // Recomputed rather than updated (α − tγ, β + tγ), so that the
            // norms never drift from the columns.
            norms_sq[p] = dot(&columns[p], &columns[p]);
            norms_sq[q] = dot(&columns[q], &columns[q]);
        }
        if !rotated {
            break;
        }
    }
    (
        nalgebra::Matrix3::from_fn(|row, k| columns[k][row]),
        nalgebra::Matrix3::from_fn(|row, k| v[k][row]),
    )
}

/// Solves `A x = b` for a small symmetric positive definite `A` by the
/// square-root-free Cholesky factorisation `A = L D Lᵀ` (Golub & Van Loan,
/// *Matrix Computations*, 4th ed., Algorithm 4.1.2), reading only the lower
/// triangle. Returns `None` when a pivot of D is not positive (A not
/// numerically positive definite) or not finite. Written out over fixed
/// arrays so that it unrolls, and without square roots so that each column
/// puts one division, not a square root and a division, on the dependency
/// chain: `nalgebra::Cholesky` walks runtime-sized views and cost several
/// times more at these sizes (4×4 Gauss–Newton and the β least squares of
/// EPnP).
#[allow(clippy::needless_range_loop)]
pub fn solve_positive_definite<const C: usize>(
    a: &SMatrix<f64, C, C>,
    b: &SVector<f64, C>,
) -> Option<SVector<f64, C>> {
    // Unit lower L below the diagonal (lower[i][j], j < i); `scaled[i][j]`
    // holds L_ij d_j; `inverse_pivot[j]` is 1/d_j.
    let mut lower = [[0.0f64; C]; C];
    let mut scaled = [[0.0f64; C]; C];
    let mut inverse_pivot = [0.0f64; C];
    for j in 0..C {
        let mut pivot = a[(j, j)];
        for k in 0..j {
            pivot -= scaled[j][k] * lower[j][k];
        }
        if !(pivot > 0.0 && pivot.is_finite()) {
            return None;
        }
        let inverse = 1.0 / pivot;
        inverse_pivot[j] = inverse;
        for i in j + 1..C {
            let mut value = a[(i, j)];
            for k in 0..j {
                value -= scaled[i][k] * lower[j][k];
            }
            scaled[i][j] = value;
            lower[i][j] = value * inverse;
        }
    }
    // L y = b, then D Lᵀ x = y.
    let mut y = [0.0f64; C];
    for i in 0..C {
        let mut value = b[i];
        for k in 0..i {
            value -= lower[i][k] * y[k];
        }
        y[i] = value;
    }
    let mut x = SVector::<f64, C>::zeros();
    for i in (0..C).rev() {
        let mut value = y[i] * inverse_pivot[i];
        for k in i + 1..C {
            value -= lower[k][i] * x[k];
        }
        x[i] = value;
    }
    Some(x)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synthetic::{standard_normal, stream_rng};
    use nalgebra::{SymmetricEigen, Vector3};

    const SEED: u64 = 20261121;
    /// `symmetric_eigen_3x3` against `SymmetricEigen` on random symmetric
    /// matrices, on exactly repeated eigenvalues (where any orthonormal basis
    /// of the eigenspace is right), on rank-deficient scatter matrices
    /// (collinear and coplanar point sets) and on the zero matrix.
    #[test]
    fn jacobi_3x3_matches_symmetric_eigen() {
        use nalgebra::Matrix3;
        let check = |a: &Matrix3<f64>| {
            let (values, vectors) = symmetric_eigen_3x3(a);
            let norm = a.norm().max(f64::MIN_POSITIVE);
            let mut reference = SymmetricEigen::new(*a).eigenvalues;
            reference.as_mut_slice().sort_by(|x, y| y.total_cmp(x));
            for k in 0..3 {
                assert!(
                    (values[k] - reference[k]).abs() <= 1e-14 * norm,
                    "{a}: {values} vs {reference}"
                );
                let v = vectors.column(k);
                assert!((a * v - v * values[k]).norm() <= 1e-14 * norm);
            }
            assert!(values[0] >= values[1] && values[1] >= values[2]);
            assert!((vectors.transpose() * vectors - Matrix3::identity()).amax() < 1e-14);
        };
        for case in 0..2000u64 {
            let mut rng = stream_rng(SEED, 7, case);
            let scale = [1.0, 1e-150, 1e-8, 1e8, 1e150][case as usize % 5];
            let b = Matrix3::from_fn(|_, _| standard_normal(&mut rng));
            let a = match case % 4 {
                0 => (b + b.transpose()) * scale,
                // Positive semi-definite with a repeated eigenvalue.
                1 => {
                    let q = nearest_orthogonal(&b);
                    q * Matrix3::from_diagonal(&Vector3::new(2.0, 2.0, 0.5)) * q.transpose() * scale
                }
                // Scatter of collinear points: rank one.
                2 => {
                    let d = b.column(0) * scale.sqrt();
                    d * d.transpose() * (1.0 + case as f64)
                }
                // Scatter of coplanar points: rank two.
                _ => {
                    let (u, w) = (b.column(0), b.column(1));
                    (u * u.transpose() + w * w.transpose()) * scale
                }
            };
            check(&((a + a.transpose()) * 0.5));
        }
        check(&Matrix3::zeros());
        check(&Matrix3::identity());
    }

    fn nearest_orthogonal(b: &nalgebra::Matrix3<f64>) -> nalgebra::Matrix3<f64> {
        let svd = b.svd(true, true);
        svd.u.unwrap() * svd.v_t.unwrap()
    }

    /// The fixed-size Cholesky solve agrees with nalgebra's and refuses
    /// matrices that are not positive definite.
    #[test]
    fn positive_definite_solve_matches_nalgebra() {
        for case in 0..500u64 {
            let mut rng = stream_rng(SEED, 8, case);
            let b = SMatrix::<f64, 5, 5>::from_fn(|_, _| standard_normal(&mut rng));
            let a = b * b.transpose() + SMatrix::<f64, 5, 5>::identity() * 1e-3;
            let rhs = SVector::<f64, 5>::from_fn(|_, _| standard_normal(&mut rng));
            let x = solve_positive_definite(&a, &rhs).unwrap();
            let reference = a.cholesky().unwrap().solve(&rhs);
            assert!((x - reference).norm() <= 1e-9 * reference.norm());
            assert!((a * x - rhs).norm() <= 1e-10 * a.norm() * x.norm());
        }
        let indefinite = nalgebra::Matrix2::new(1.0, 2.0, 2.0, 1.0);
        assert!(solve_positive_definite(&indefinite, &nalgebra::Vector2::new(1.0, 0.0)).is_none());
        let singular = nalgebra::Matrix2::new(1.0, 1.0, 1.0, 1.0);
        assert!(solve_positive_definite(&singular, &nalgebra::Vector2::new(1.0, 0.0)).is_none());
        let not_finite = nalgebra::Matrix3::from_element(f64::NAN);
        assert!(solve_positive_definite(&not_finite, &nalgebra::Vector3::zeros()).is_none());
    }
}
