//! All eigenvalues (real and complex) of a small real non-symmetric matrix:
//! Parlett–Reinsch balancing, Householder reduction to Hessenberg form, then
//! the implicit double-shift QR iteration of Francis (1961–62), eigenvalues
//! only.
//!
//! References: Parlett & Reinsch, "Balancing a matrix for calculation of
//! eigenvalues and eigenvectors", Numer. Math. 13, 1969; Golub & Van Loan,
//! *Matrix Computations*, 4th ed., §7.4 (Householder reduction to Hessenberg
//! form) and §7.5 (Algorithm 7.5.1, the Francis QR step, and §7.5.7,
//! deflation). Only the active window `H[l..=n, l..=n]` is updated, since
//! neither Schur vectors nor the off-window part of the Schur form are needed.
//!
//! Why not nalgebra's `complex_eigenvalues`: it does not balance (the action
//! matrices of the three-cubics solver (DLS) and of OPnP have entries over many orders of magnitude), and its
//! iteration has no bound.

use nalgebra::SMatrix;

/// Iterations allowed per deflated eigenvalue (or pair) before giving up,
/// as in EISPACK's `hqr`.
pub const MAX_ITERATIONS_PER_EIGENVALUE: usize = 30;
/// Iterations after which an ad hoc "exceptional" shift breaks a cycle.
pub const EXCEPTIONAL_SHIFT_EVERY: usize = 10;
/// Balancing scales by powers of this radix, so it introduces no rounding.
const BALANCING_RADIX: f64 = 2.0;
/// Balancing stops when a sweep reduces no row + column norm below this
/// fraction of its previous value (Parlett & Reinsch use 0.95).
const BALANCING_IMPROVEMENT: f64 = 0.95;
/// Upper bound on balancing sweeps (it converges in a few).
const MAX_BALANCING_SWEEPS: usize = 50;

/// An eigenvalue `re + i·im`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Eigenvalue {
    /// Real part.
    pub re: f64,
    /// Imaginary part (zero for a real eigenvalue found as such).
    pub im: f64,
}

/// Why the eigenvalues could not be computed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum EigenvalueError {
    /// An entry of the matrix was NaN or infinite.
    NonFinite,
    /// The QR iteration did not deflate within the iteration limit.
    NoConvergence,
}

impl std::fmt::Display for EigenvalueError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            EigenvalueError::NonFinite => f.write_str("the matrix has a non-finite entry"),
            EigenvalueError::NoConvergence => write!(
                f,
                "the QR iteration did not converge in {MAX_ITERATIONS_PER_EIGENVALUE} iterations"
            ),
        }
    }
}

impl std::error::Error for EigenvalueError {}

/// A square matrix stored as its columns: `columns[j][i]` is entry `(i, j)`,
/// so column operations run over contiguous memory.
type Columns<const N: usize> = [[f64; N]; N];

/// All `N` eigenvalues of `matrix`, in no particular order.
pub fn eigenvalues<const N: usize>(
    matrix: &SMatrix<f64, N, N>,
) -> Result<[Eigenvalue; N], EigenvalueError> {
    if !matrix.iter().all(|v| v.is_finite()) {
        return Err(EigenvalueError::NonFinite);
    }
    let mut columns: Columns<N> = [[0.0; N]; N];
    for (column, source) in columns.iter_mut().zip(matrix.as_slice().chunks_exact(N)) {
        column.copy_from_slice(source);
    }
    balance(&mut columns);
    reduce_to_hessenberg(&mut columns);
    hessenberg_eigenvalues(&mut columns)
}

/// Parlett–Reinsch balancing in the 1-norm: a diagonal similarity by powers
/// of two that makes each row and column (off the diagonal) of similar size.
fn balance<const N: usize>(a: &mut Columns<N>) {
    for _ in 0..MAX_BALANCING_SWEEPS {
        let mut converged = true;
        for i in 0..N {
            let column: f64 = a[i].iter().map(|v| v.abs()).sum::<f64>() - a[i][i].abs();
            let row: f64 = a.iter().map(|c| c[i].abs()).sum::<f64>() - a[i][i].abs();
            if !(column > 0.0 && row > 0.0) {
                continue;
            }
            let (mut scaled_column, mut scaled_row, mut factor) = (column, row, 1.0);
            while scaled_column < scaled_row / BALANCING_RADIX {
                scaled_column *= BALANCING_RADIX;
                scaled_row /= BALANCING_RADIX;
                factor *= BALANCING_RADIX;
            }
            while scaled_column >= scaled_row * BALANCING_RADIX {
                scaled_column /= BALANCING_RADIX;
                scaled_row *= BALANCING_RADIX;
                factor /= BALANCING_RADIX;
            }
            if scaled_column + scaled_row < BALANCING_IMPROVEMENT * (column + row) {
                converged = false;
                // Column i times f, row i divided by f (the diagonal is unchanged).
                for v in a[i].iter_mut() {
                    *v *= factor;
                }
                for c in a.iter_mut() {
                    c[i] /= factor;
                }
            }
        }
        if converged {
            break;
        }
    }
}

/// Householder reduction to upper Hessenberg form by a similarity
/// (Golub & Van Loan Algorithm 7.4.2), without accumulating the reflectors.
fn reduce_to_hessenberg<const N: usize>(a: &mut Columns<N>) {
    for k in 0..N.saturating_sub(2) {
        let below = &a[k][k + 1..];
        let norm = below.iter().map(|v| v * v).sum::<f64>().sqrt();
        if norm == 0.0 {
            continue;
        }
        let alpha = -norm.copysign(below[0]);
        let mut v = [0.0; N];
        v[k + 1..].copy_from_slice(below);
        v[k + 1] -= alpha;
        let v_norm_sq: f64 = v[k + 1..].iter().map(|e| e * e).sum();
        if v_norm_sq == 0.0 {
            continue;
        }
        let tau = 2.0 / v_norm_sq;
        let v = &v[k + 1..];
        // Left, (I − τvvᵀ)A on rows k+1..: column k becomes (…, α, 0, …).
        for column in a[k + 1..].iter_mut() {
            let rows = &mut column[k + 1..];
            let dot = tau * rows.iter().zip(v).map(|(c, e)| c * e).sum::<f64>();
            for (c, e) in rows.iter_mut().zip(v) {
                *c -= dot * e;
            }
        }
        a[k][k + 1] = alpha;
        a[k][k + 2..].fill(0.0);
        // Right, A(I − τvvᵀ) on columns k+1..: w = A v, then A −= τ w vᵀ.
        let mut w = [0.0; N];
        for (column, &e) in a[k + 1..].iter().zip(v) {
            for (wi, c) in w.iter_mut().zip(column) {
                *wi += c * e;
            }
        }
        for (column, &e) in a[k + 1..].iter_mut().zip(v) {
            let factor = tau * e;
            for (c, wi) in column.iter_mut().zip(&w) {
                *c -= factor * wi;
            }
        }
    }
}

/// Eigenvalues of `[[a, b], [c, d]]`.
fn eigenvalues_2x2(a: f64, b: f64, c: f64, d: f64) -> [Eigenvalue; 2] {
    let mean = 0.5 * (a + d);
    let half_difference = 0.5 * (a - d);
    let discriminant = half_difference * half_difference + b * c;
    if discriminant >= 0.0 {
        // The root of larger magnitude first, then the other from the
        // determinant, so neither suffers cancellation.
        let root = discriminant.sqrt();
        let larger = mean + root.copysign(mean);
        let determinant = a * d - b * c;
        let smaller = if larger != 0.0 {
            determinant / larger
        } else {
            mean - root
        };
        [
            Eigenvalue {
                re: larger,
                im: 0.0,
            },
            Eigenvalue {
                re: smaller,
                im: 0.0,
            },
        ]
    } else {
        let im = (-discriminant).sqrt();
        [
            Eigenvalue { re: mean, im },
            Eigenvalue { re: mean, im: -im },
        ]
    }
}

/// The Householder reflector `I − τ v vᵀ` that maps `x` onto a multiple of
/// `e1`, as `(v, τ)`. `None` if `x = 0`.
fn reflector<const K: usize>(x: [f64; K]) -> Option<([f64; K], f64)> {
    let norm = x.iter().map(|v| v * v).sum::<f64>().sqrt();
    if norm == 0.0 {
        return None;
    }
    let alpha = -norm.copysign(x[0]);
    let mut v = x;
    v[0] -= alpha;
    let v_norm_sq: f64 = v.iter().map(|e| e * e).sum();
    if v_norm_sq == 0.0 {
        return None;
    }
    Some((v, 2.0 / v_norm_sq))
}

/// Applies the reflector `(v, τ)` at rows/columns `k..k+K` of the active
/// window `[low, high]`: from the left to columns `max(low, k−1)..=high`,
/// from the right to rows `low..=min(k+K, high)`.
fn apply_reflector<const N: usize, const K: usize>(
    h: &mut Columns<N>,
    (v, tau): ([f64; K], f64),
    k: usize,
    low: usize,
    high: usize,
) {
    for column in h[k.saturating_sub(1).max(low)..=high].iter_mut() {
        let rows = &mut column[k..k + K];
        let dot = tau * rows.iter().zip(&v).map(|(c, e)| c * e).sum::<f64>();
        for (c, e) in rows.iter_mut().zip(&v) {
            *c -= dot * e;
        }
    }
    let last = (k + K).min(high);
    let columns = &mut h[k..k + K];
    let mut dots = [0.0; N];
    for (column, e) in columns.iter().zip(&v) {
        for (d, c) in dots[low..=last].iter_mut().zip(&column[low..=last]) {
            *d += c * e;
        }
    }
    for (column, e) in columns.iter_mut().zip(&v) {
        let factor = tau * e;
        for (c, d) in column[low..=last].iter_mut().zip(&dots[low..=last]) {
            *c -= factor * d;
        }
    }
}

/// Francis double-shift QR on an upper Hessenberg matrix (destroyed).
fn hessenberg_eigenvalues<const N: usize>(
    h: &mut Columns<N>,
) -> Result<[Eigenvalue; N], EigenvalueError> {
    let mut out = [Eigenvalue { re: 0.0, im: 0.0 }; N];
    if N == 0 {
        return Ok(out);
    }
    // Entry (i, j) is h[j][i].
    let scale = h.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
    let mut high = N - 1;
    let mut iterations = 0usize;
    loop {
        // Deflate: find the start `low` of the unreduced block ending at `high`.
        let mut low = high;
        while low > 0 {
            let mut neighbourhood = h[low - 1][low - 1].abs() + h[low][low].abs();
            if neighbourhood == 0.0 {
                neighbourhood = scale;
            }
            if h[low - 1][low].abs() <= f64::EPSILON * neighbourhood {
                h[low - 1][low] = 0.0;
                break;
            }
            low -= 1;
        }
        if low == high {
            out[high] = Eigenvalue {
                re: h[high][high],
                im: 0.0,
            };
            iterations = 0;
            if high == 0 {
                return Ok(out);
            }
            high -= 1;
            continue;
        }
        if low + 1 == high {
            let pair = eigenvalues_2x2(h[low][low], h[high][low], h[low][high], h[high][high]);
            out[low] = pair[0];
            out[high] = pair[1];
            iterations = 0;
            if low == 0 {
                return Ok(out);
            }
            high = low - 1;
            continue;
        }
        if iterations == MAX_ITERATIONS_PER_EIGENVALUE {
            return Err(EigenvalueError::NoConvergence);
        }
        iterations += 1;

        // The two shifts enter only through their sum and product.
        let (a, b, c, d) = (
            h[high - 1][high - 1],
            h[high][high - 1],
            h[high - 1][high],
            h[high][high],
        );
        let (shift_sum, shift_product) = if iterations.is_multiple_of(EXCEPTIONAL_SHIFT_EVERY) {
            // Wilkinson's exceptional shift (as in EISPACK `hqr`).
            let s = h[high - 1][high].abs() + h[high - 2][high - 1].abs();
            (2.0 * d + 1.5 * s, d * d + 1.5 * s * d + s * s)
        } else {
            (a + d, a * d - b * c)
        };

        // First column of (H − σ1 I)(H − σ2 I) (Golub & Van Loan eq. 7.5.6).
        let (h00, h01, h10, h11, h21) = (
            h[low][low],
            h[low + 1][low],
            h[low][low + 1],
            h[low + 1][low + 1],
            h[low + 1][low + 2],
        );
        let mut x = h00 * h00 + h01 * h10 - shift_sum * h00 + shift_product;
        let mut y = h10 * (h00 + h11 - shift_sum);
        let mut z = h10 * h21;
        // Chase the bulge down the window.
        for k in low..high - 1 {
            if let Some(r) = reflector([x, y, z]) {
                apply_reflector(h, r, k, low, high);
            }
            if k > low {
                // Exact zeros where the reflector annihilated the bulge.
                h[k - 1][k + 1] = 0.0;
                h[k - 1][k + 2] = 0.0;
            }
            x = h[k][k + 1];
            y = h[k][k + 2];
            if k + 3 <= high {
                z = h[k][k + 3];
            }
        }
        if let Some(r) = reflector([x, y]) {
            apply_reflector(h, r, high - 1, low, high);
        }
        if high >= low + 2 {
            h[high - 2][high] = 0.0;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synthetic::stream_rng;
    use nalgebra::Complex;
    use rand::Rng;

    fn sorted(values: &mut [Complex<f64>]) {
        values.sort_by(|a, b| a.re.total_cmp(&b.re).then(a.im.total_cmp(&b.im)));
    }

    #[test]
    fn matches_nalgebra_on_random_matrices() {
        for case in 0..50 {
            let mut rng = stream_rng(11, 1, case);
            let m = SMatrix::<f64, 12, 12>::from_fn(|_, _| rng.random::<f64>() * 2.0 - 1.0);
            let ours = eigenvalues(&m).unwrap();
            let mut ours: Vec<Complex<f64>> =
                ours.iter().map(|e| Complex::new(e.re, e.im)).collect();
            let mut reference: Vec<Complex<f64>> =
                m.complex_eigenvalues().iter().copied().collect();
            sorted(&mut ours);
            sorted(&mut reference);
            for (a, b) in ours.iter().zip(&reference) {
                assert!((a - b).norm() < 1e-9, "case {case}: {a} vs {b}");
            }
        }
    }

    #[test]
    fn badly_scaled_companion_matrix_gives_the_polynomial_roots() {
        // (λ−1)(λ−2)(λ+3)(λ−0.5)(λ²+1), as a companion matrix C, then the
        // similar matrix D⁻¹ C D with D = diag(10^(3i)): same eigenvalues,
        // entries over 30 orders of magnitude, which balancing undoes.
        let real_roots = [1.0, 2.0, -3.0, 0.5];
        let mut poly = vec![1.0];
        let factors: Vec<Vec<f64>> = real_roots
            .iter()
            .map(|&r| vec![-r, 1.0])
            .chain([vec![1.0, 0.0, 1.0]])
            .collect();
        for factor in &factors {
            let mut next = vec![0.0; poly.len() + factor.len() - 1];
            for (i, p) in poly.iter().enumerate() {
                for (j, f) in factor.iter().enumerate() {
                    next[i + j] += p * f;
                }
            }
            poly = next;
        }
        let scale = |i: usize| 10f64.powi(3 * i as i32);
        let companion = SMatrix::<f64, 6, 6>::from_fn(|i, j| {
            let c = if j == 5 {
                -poly[i]
            } else if i == j + 1 {
                1.0
            } else {
                0.0
            };
            c * scale(j) / scale(i)
        });
        let mut found: Vec<Complex<f64>> = eigenvalues(&companion)
            .unwrap()
            .iter()
            .map(|e| Complex::new(e.re, e.im))
            .collect();
        let mut expected: Vec<Complex<f64>> = real_roots
            .iter()
            .map(|&r| Complex::new(r, 0.0))
            .chain([Complex::new(0.0, 1.0), Complex::new(0.0, -1.0)])
            .collect();
        sorted(&mut found);
        sorted(&mut expected);
        for (a, b) in found.iter().zip(&expected) {
            assert!((a - b).norm() < 1e-9, "{a} vs {b}");
        }
    }

    #[test]
    fn rejects_non_finite_entries() {
        let mut m = SMatrix::<f64, 4, 4>::identity();
        m[(1, 2)] = f64::INFINITY;
        assert_eq!(eigenvalues(&m), Err(EigenvalueError::NonFinite));
    }

    #[test]
    fn handles_triangular_and_diagonal_input() {
        let m = SMatrix::<f64, 5, 5>::from_fn(|i, j| {
            if j >= i {
                (i + 1) as f64 + j as f64 * 0.1
            } else {
                0.0
            }
        });
        let mut values: Vec<f64> = eigenvalues(&m).unwrap().iter().map(|e| e.re).collect();
        values.sort_by(f64::total_cmp);
        for (i, v) in values.iter().enumerate() {
            assert!((v - (i + 1) as f64 - i as f64 * 0.1).abs() < 1e-12);
        }
    }
}
