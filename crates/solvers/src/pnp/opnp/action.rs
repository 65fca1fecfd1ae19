//! Real solutions of four *odd* cubic equations in four unknowns by an
//! elimination template and multiplication (action) matrices.
//!
//! **Problem.** `f_j(q) = C_j(q) + L_j(q) = 0`, `j = 1…4`, `q = (a, b, c, d)`,
//! where `C_j` is a cubic form and `L_j` a linear form: every monomial has odd
//! degree, so the solutions come in pairs `±q`, plus the trivial `q = 0`.
//! When the cubic parts share no projective zero (no solutions at infinity),
//! Bézout's bound is attained: 81 solutions, that is `q = 0` and 40 pairs.
//! OPnP's optimality conditions have this form (Zheng et al., ICCV 2013; their
//! generated solver reports the same 81 = 1 + 2·40).
//!
//! **Chart (numerical device, same solutions).** OPnP on a marker with an
//! isotropic point scatter (the biprism) has cubic parts close to
//! `c·(q·q)·q_j`, which vanish on the whole isotropic cone: 36 of the 40
//! pairs then sit near infinity and a monomial basis up to degree 8 cannot
//! represent them in double precision. [`solve`] therefore first rewrites the
//! system in the weighted-projective chart `pᵀAp + s = 1` ([`to_chart`]); the
//! result is again an odd cubic system with the same solution pairs, mapped
//! back exactly by `q = p/√(1 − pᵀAp)` ([`from_chart`]).
//!
//! **Quotient algebra.** Let `I = ⟨f_1…f_4⟩`. Because the `f_j` are odd,
//! `ℂ[q]/I` splits into an even part (dimension 41: the 40 pairs and `q = 0`)
//! and an odd part (dimension 40: odd functions vanish at `q = 0`). The
//! cubic parts form a regular sequence, so the graded Hilbert function of the
//! quotient is that of four generic cubics, `(1 + t + t²)⁴ = 1, 4, 10, 16, 19,
//! 16, 10, 4, 1` in degrees 0…8, and the `f_j` are an H-basis: the part of
//! `I` of degree ≤ D is spanned by the multiples `m·f_j`, `deg m ≤ D − 3`.
//! Ask, Kuang & Åström (ICPR 2012, "Exploiting p-fold symmetries for faster
//! polynomial equation solving"), whose method the OPnP authors' solver uses,
//! work in one parity class of the quotient; so do we.
//!
//! **Template.** Even polynomials up to degree 8 are reduced modulo `I`
//! degree by degree. A multiple `m·f_j` with `deg m = k − 3` has a degree-`k`
//! part `m·C_j` and a degree-`(k−2)` part `m·L_j`, so the Macaulay matrix is
//! block bidiagonal by degree. The equations are first interreduced so that
//! each has its own leading cubic monomial `LMᵢ` (`interreduce`); the rows
//! `m·f_j` with `LMᵢ | m` for some `i < j` are Koszul redundancies (the F5
//! criterion, Faugère 2002) and are left out: 48 to 60 of the 224 rows of
//! degree 8 and 6 of the 80 of degree 6, which made the solver about a
//! quarter faster at the same accuracy. Each block (top degree k = 8, 6, 4;
//! 165, 84 and 35 top columns) is brought to echelon form by
//! Gaussian elimination with complete pivoting over its top columns — the
//! adaptive basis choice of Byröd, Josephson & Åström ("Fast and stable
//! polynomial equation solving and its application to computer vision",
//! IJCV 2009). Its expected rank is the number of top monomials minus the
//! Hilbert function (164, 74, 16); the unpivoted columns are this problem's
//! standard monomials, 1 + 10 + 19 in degrees 8, 6, 4, plus every monomial of
//! degree 2 and the constant: 41, a basis of the even quotient.
//!
//! **Odd basis from the socle.** The 40 odd basis monomials are chosen per
//! problem too, without eliminating any odd block: the graded quotient of
//! the cubic parts is Gorenstein with a one-dimensional socle in degree 8,
//! whose functional `φ` falls out of the degree-8 echelon form by back
//! substitution; degree-k monomials form a basis of that degree exactly when
//! their pairing matrix `[φ(u·m)]` with the degree-`(8−k)` monomials has full
//! rank, and column pivoting picks well-conditioned ones (4 + 16 + 16 in
//! degrees 7, 5, 3, plus `a, b, c, d`). History, measured on the same test
//! problems: a basis fixed once for all problems (grevlex standard monomials
//! of a random system) lost the true solution in 2 of 1500 noise-free OPnP
//! problems (a far-field biprism, an n = 5 set); choosing it by complete
//! pivoting on the odd Macaulay blocks lost none but cost 0.4 ms; the socle
//! choice loses none either and costs a few microseconds.
//!
//! **Action matrix without degree 9.** Multiplying the odd quotient by an
//! even polynomial (the classical action matrix on a parity class) would need
//! reductions in degree 9 — a 336-row block. Instead we use the four maps
//! `M_x : odd quotient → even quotient`, `b ↦ NF(x·b)`, for `x ∈ {a, b, c, d}`,
//! which need degree 8 only. With `B` the odd basis and `v_k = (b(q_k))_{b∈B}`,
//! every solution pair satisfies `ev_{q_k} · M_x = x(q_k) · v_kᵀ`. The row of
//! `M_x` for the constant monomial is zero (`x·b` vanishes at `q = 0`);
//! dropping it leaves 40×40 matrices with `M_x = W⁻¹ diag(x(q_k)) V` (V, W
//! evaluation matrices). For two linear forms `ℓ₁, ℓ₂`, `A = M_{ℓ₂}⁻¹ M_{ℓ₁}
//! = V⁻¹ diag(ℓ₁(q_k)/ℓ₂(q_k)) V`: the eigenvectors of `Aᵀ` are the `v_k`,
//! found by inverse iteration for each real eigenvalue (the eigenvalues come
//! from a balanced Hessenberg QR without Schur vectors,
//! [`crate::linalg::nonsymmetric`]; typically 4 of the 40 are
//! real, so this costs about a third of a full real Schur form with its
//! vectors, which the solver used before). `ℓ₂` is chosen per
//! problem among a few fixed forms: the first whose `M_{ℓ₂}` is well
//! conditioned ([`DENOMINATOR_GOOD_RCOND`]), else the best conditioned.
//!
//! **Extraction.** `B` holds `a, b, c, d`, so `v_k` gives the direction `u` of
//! `q_k`; the 16 cubic monomials of `B` give `‖q_k‖²` by least squares
//! (`v(m) = s·‖q‖³ m(u)`, `v(x) = s·‖q‖ u`). A negative `‖q‖²` means the pair
//! is `±i·w` with `w` real: not a real solution. Over 1000 noisy OPnP
//! problems (σ = 0.5 px; biprism, random n = 6…100, n = 4–5, planar) the
//! estimate of the solution that polishes to the minimum nearest the truth
//! had relative error median 3e-14, 99th percentile 5e-11, worst 2e-8;
//! callers polish it (OPnP by Newton's method on its cost, [`newton_polish`]
//! for a bare system).

use super::monomials::{self, Exponent, CUBIC, CUBIC_COUNT, LINEAR};
use crate::linalg::nonsymmetric as eigenvalues;
use nalgebra::{DMatrix, SMatrix, SVector};
use std::sync::LazyLock;

/// Coefficients of one odd cubic equation: the 20 cubic monomials of
/// [`monomials::CUBIC`] (grevlex order), then `a, b, c, d`.
pub type OddCubic = [f64; EQUATION_TERMS];
/// Number of coefficients of an odd cubic equation in four unknowns.
pub const EQUATION_TERMS: usize = CUBIC_COUNT + 4;
/// Number of solution pairs `±q ≠ 0` of a generic system (Bézout: 81 = 1 + 2·40).
pub const SOLUTION_PAIRS: usize = 40;

/// A pivot below this fraction of the largest pivot of its block means the
/// block has lost rank: the system is degenerate for this template.
pub const RANK_TOLERANCE: f64 = 1e-11;
/// After the expected number of pivots, what is left of a block must be below
/// this fraction of the smallest pivot taken; otherwise the rank is not the
/// one the Hilbert function predicts.
pub const RANK_GAP: f64 = 1e-5;
/// Smallest acceptable reciprocal condition estimate (smallest over largest
/// LU pivot) of the denominator matrix `M_{ℓ₂}`.
pub const DENOMINATOR_RCOND: f64 = 1e-13;
/// A denominator candidate whose reciprocal condition estimate reaches this
/// is taken at once, without factorising the remaining candidates: its
/// inverse loses at most six of the sixteen digits, and Newton's method
/// polishes the solutions afterwards. (Factorising all eight candidates
/// cost about 6% of a solve; the first one is usually taken.)
pub const DENOMINATOR_GOOD_RCOND: f64 = 1e-6;
/// A complex eigenvalue pair whose imaginary part is below this fraction of
/// its modulus is taken as a (numerically split) real eigenvalue.
pub const NEAR_REAL: f64 = 1e-8;

/// Why the polynomial solver could not return solutions.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum SolverError {
    /// A block of the elimination template does not have the rank the Hilbert
    /// function of a system without solutions at infinity predicts.
    RankDeficient {
        /// Top degree of the block.
        degree: usize,
        /// Numerical rank found (number of acceptable pivots).
        found: usize,
        /// Rank predicted by the Hilbert function.
        expected: usize,
    },
    /// A coefficient of the equations is NaN or infinite.
    NonFinite,
    /// Every candidate denominator multiplication matrix is singular.
    SingularDenominator,
    /// The QR iteration for the eigenvalues of the action matrix did not
    /// converge.
    SchurFailed,
}

impl std::fmt::Display for SolverError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            SolverError::RankDeficient {
                degree,
                found,
                expected,
            } => write!(
                f,
                "elimination template block of degree {degree} has rank {found}, expected {expected}"
            ),
            SolverError::NonFinite => f.write_str("a coefficient of the equations is not finite"),
            SolverError::SingularDenominator => f.write_str("no multiplication matrix is invertible"),
            SolverError::SchurFailed => {
                f.write_str("the eigenvalues of the action matrix did not converge")
            }
        }
    }
}

impl std::error::Error for SolverError {}

impl SolverError {
    /// A fixed description, for error types that carry a `&'static str`.
    pub fn reason(&self) -> &'static str {
        match self {
            SolverError::RankDeficient { .. } => {
                "Gröbner elimination template is rank deficient (solutions at infinity or a degenerate configuration)"
            }
            SolverError::SingularDenominator => {
                "Gröbner solver: no multiplication matrix is invertible"
            }
            SolverError::NonFinite => "Gröbner solver: a coefficient is not finite",
            SolverError::SchurFailed => {
                "Gröbner solver: the eigenvalues of the action matrix did not converge"
            }
        }
    }
}

/// One row pattern of a template block: equation `equation` multiplied by a
/// monomial; `top[t]` is the block column of `multiplier · CUBIC[t]`,
/// `tail[t]` the tail column of `multiplier · LINEAR[t]`.
#[derive(Debug, Clone)]
struct RowPattern {
    multiplier: Exponent,
    equation: usize,
    top: [u16; CUBIC_COUNT],
    tail: [u16; 4],
}

/// One degree block of the even Macaulay matrix.
#[derive(Debug, Clone)]
struct Block {
    /// Top degree k of the block's rows.
    degree: usize,
    /// Offset of the degree-k monomials in the global even column space.
    top_offset: usize,
    /// Number of degree-k monomials.
    top_len: usize,
    /// Number of degree-(k−2) monomials (they follow the top ones).
    tail_len: usize,
    /// Rank predicted by the Hilbert function.
    rank: usize,
    rows: Vec<RowPattern>,
    /// How the elimination treats the tail.
    tail: TailHandling,
}

impl Block {
    fn width(&self) -> usize {
        self.top_len + self.tail_len
    }
}

/// Fixed structure of the solver, built once ([`TEMPLATE`]).
#[derive(Debug, Clone)]
pub struct Template {
    /// Even monomials of degree 8, 6, 4, 2, 0, concatenated: the global even
    /// column space (295 columns).
    even_columns: Vec<Exponent>,
    /// Offsets of degrees 8, 6, 4, 2, 0 in `even_columns`.
    degree_offsets: [usize; 5],
    /// Even blocks, top degree 8, 6, 4.
    blocks: [Block; 3],
    /// Odd monomials of degree 7, 5, 3, 1, concatenated (200).
    odd_columns: Vec<Exponent>,
    /// Offsets of degrees 7, 5, 3, 1 in `odd_columns`.
    odd_offsets: [usize; 4],
    /// `product_column[i][x]`: global even column of `x · odd_columns[i]`.
    product_column: Vec<[usize; 4]>,
    /// `cubic_quintic[c · 56 + m]`: global even column (degree 8) of the
    /// product of the `c`-th cubic and the `m`-th quintic odd column.
    cubic_quintic: Vec<usize>,
}

/// The solver structure, built on first use.
pub static TEMPLATE: LazyLock<Template> = LazyLock::new(Template::build);

/// Hilbert function of the quotient by four cubics in four unknowns,
/// `(1 + t + t²)⁴`, degrees 0…8.
const HILBERT: [usize; 9] = [1, 4, 10, 16, 19, 16, 10, 4, 1];

/// Concatenates the monomials of the given degrees; returns them with the
/// offset of each degree.
fn concatenated<const N: usize>(degrees: [usize; N]) -> (Vec<Exponent>, [usize; N]) {
    let mut columns = Vec::new();
    let mut offsets = [0usize; N];
    for (slot, &degree) in degrees.iter().enumerate() {
        offsets[slot] = columns.len();
        columns.extend(monomials::of_degree(degree));
    }
    (columns, offsets)
}

/// The block of top degree `degree`, whose top monomials start at
/// `top_offset` of its column space.
fn block(degree: usize, top_offset: usize) -> Block {
    let top = monomials::of_degree(degree);
    let tail = monomials::of_degree(degree - 2);
    let rows = block_rows(degree, &top, &tail);
    Block {
        degree,
        top_offset,
        top_len: top.len(),
        tail_len: tail.len(),
        rank: top.len() - HILBERT[degree],
        rows,
        // Only degree 8 has few reduced monomials (x times the four degree-7
        // basis monomials) against a wide tail; degrees 6 and 4 reduce 40
        // to 64 monomials each, where carrying the tail is cheaper.
        tail: if degree == 8 {
            TailHandling::Deferred
        } else {
            TailHandling::Carried
        },
    }
}

impl Template {
    /// Builds the template structure: even and odd blocks, product table.
    fn build() -> Template {
        let (even_columns, degree_offsets) = concatenated([8, 6, 4, 2, 0]);
        let blocks = [(8, 0), (6, 1), (4, 2)].map(|(d, slot)| block(d, degree_offsets[slot]));
        let (odd_columns, odd_offsets) = concatenated([7, 5, 3, 1]);
        let product_column = odd_columns
            .iter()
            .map(|m| {
                LINEAR.map(|x| {
                    monomials::position(&even_columns, &monomials::product(&x, m)).unwrap()
                })
            })
            .collect();
        let quintics = &odd_columns[odd_offsets[1]..odd_offsets[2]];
        let cubics = &odd_columns[odd_offsets[2]..odd_offsets[3]];
        let cubic_quintic = cubics
            .iter()
            .flat_map(|c| {
                quintics
                    .iter()
                    .map(|m| monomials::position(&even_columns, &monomials::product(c, m)).unwrap())
            })
            .collect();
        Template {
            even_columns,
            degree_offsets,
            blocks,
            odd_columns,
            odd_offsets,
            product_column,
            cubic_quintic,
        }
    }

    /// Number of rows and columns of each even block (top degree 8, 6, 4).
    pub fn block_sizes(&self) -> [(usize, usize); 3] {
        self.blocks.clone().map(|b| (b.rows.len(), b.width()))
    }
}

/// Rows of the degree-`degree` block: every equation times every monomial
/// of degree `degree − 3`.
fn block_rows(degree: usize, top: &[Exponent], tail: &[Exponent]) -> Vec<RowPattern> {
    let mut rows = Vec::new();
    for multiplier in monomials::of_degree(degree - 3) {
        for equation in 0..4 {
            let top_columns = std::array::from_fn(|t| {
                let m = monomials::product(&multiplier, &CUBIC[t]);
                monomials::position(top, &m).unwrap() as u16
            });
            let tail_columns = std::array::from_fn(|t| {
                let m = monomials::product(&multiplier, &LINEAR[t]);
                monomials::position(tail, &m).unwrap() as u16
            });
            rows.push(RowPattern {
                multiplier,
                equation,
                top: top_columns,
                tail: tail_columns,
            });
        }
    }
    rows
}

/// A pivot of the cubic coefficient matrix below this fraction of the
/// first means the four cubic parts are linearly dependent.
pub const CUBIC_RANK_TOLERANCE: f64 = 1e-12;

/// Replaces the equations by an invertible combination of them (the same
/// ideal) whose cubic parts are in reduced echelon form: Gauss–Jordan with
/// complete pivoting on the 4×20 cubic coefficients. Equation `i` then has
/// coefficient 1 on its *leading* cubic monomial `LMᵢ` and 0 on the others'.
fn interreduce(equations: &[OddCubic; 4]) -> Result<([OddCubic; 4], [Exponent; 4]), SolverError> {
    let mut e = *equations;
    let mut leading = [[0u8; 4]; 4];
    let mut used = [false; CUBIC_COUNT];
    let mut first = 0.0;
    for k in 0..4 {
        let mut best = (k, 0usize, 0.0f64);
        for (r, row) in e.iter().enumerate().skip(k) {
            for (c, v) in row[..CUBIC_COUNT].iter().enumerate() {
                if !used[c] && v.abs() > best.2 {
                    best = (r, c, v.abs());
                }
            }
        }
        let (r, c, magnitude) = best;
        if k == 0 {
            first = magnitude;
        }
        if magnitude.is_nan() || magnitude <= CUBIC_RANK_TOLERANCE * first {
            return Err(SolverError::RankDeficient {
                degree: 3,
                found: k,
                expected: 4,
            });
        }
        e.swap(k, r);
        used[c] = true;
        leading[k] = CUBIC[c];
        let pivot = e[k][c];
        e[k].iter_mut().for_each(|v| *v /= pivot);
        let pivot_row = e[k];
        for (other, row) in e.iter_mut().enumerate() {
            if other != k && row[c] != 0.0 {
                let factor = row[c];
                for (a, b) in row.iter_mut().zip(&pivot_row) {
                    *a -= factor * b;
                }
                row[c] = 0.0;
            }
        }
    }
    Ok((e, leading))
}

/// Whether row `m·f_j` is a Koszul redundancy after [`interreduce`]: `m`
/// divisible by `LMᵢ` for some `i < j` (the relation `f_j·f_i·m′ = f_i·f_j·m′`
/// expresses it through the other rows, the F5 criterion of Faugère). The
/// rank check of [`eliminate`] still guards the block.
fn is_koszul_redundant(row: &RowPattern, leading: &[Exponent; 4]) -> bool {
    leading[..row.equation]
        .iter()
        .any(|lm| (0..4).all(|k| row.multiplier[k] >= lm[k]))
}

/// Fills a block's matrix (row-major, top then tail columns) from the
/// interreduced equations, leaving out the Koszul-redundant rows; returns
/// it with its width.
fn fill(block: &Block, equations: &[OddCubic; 4], leading: &[Exponent; 4]) -> (Vec<f64>, usize) {
    let width = block.width();
    let mut matrix = Vec::with_capacity(block.rows.len() * width);
    for row in block
        .rows
        .iter()
        .filter(|r| !is_koszul_redundant(r, leading))
    {
        let coefficients = &equations[row.equation];
        let start = matrix.len();
        matrix.resize(start + width, 0.0);
        let out = &mut matrix[start..];
        for (t, &column) in row.top.iter().enumerate() {
            out[usize::from(column)] = coefficients[t];
        }
        for (t, &column) in row.tail.iter().enumerate() {
            out[block.top_len + usize::from(column)] = coefficients[CUBIC_COUNT + t];
        }
    }
    (matrix, width)
}

/// Relative size below which a candidate column of a pairing matrix counts
/// as dependent when choosing the odd basis (`odd_basis_from_socle`).
pub const PAIRING_RANK_TOLERANCE: f64 = 1e-10;

/// This problem's basis of the odd quotient from the socle of the graded
/// quotient, without eliminating the odd blocks.
///
/// The cubic parts span a complete intersection, so their graded quotient
/// `A` is Gorenstein with one-dimensional socle `A₈`, and multiplication
/// `A_k × A_{8−k} → A₈` is a perfect pairing. The linear functional `φ` on
/// degree-8 forms that vanishes on the top parts of the degree-8 rows
/// (normalised to 1 on the standard monomial `s₈`) is read off the echelon
/// form by back substitution. Degree-k monomials `m` then form a basis of
/// `A_k` exactly when the pairing matrix `[φ(u·m)]`, `u` over the monomials of
/// degree `8 − k`, has full rank on them; we pick them greedily by column
/// pivoting (largest residual first): 4 of degree 7 (paired with `a…d`), 16
/// of degree 5 and 16 of degree 3 (paired with each other). A basis of every
/// graded piece is a basis of the (affine) odd quotient.
fn odd_basis_from_socle(
    template: &Template,
    matrix: &[f64],
    echelon: &Echelon,
) -> Result<Vec<usize>, SolverError> {
    let phi = socle_functional(&template.blocks[0], matrix, echelon);
    let offsets = template.odd_offsets;
    let (septics, quintics, cubics) = (
        offsets[0]..offsets[1],
        offsets[1]..offsets[2],
        offsets[2]..offsets[3],
    );
    let mut basis = Vec::with_capacity(SOLUTION_PAIRS);
    // Degree 7: rows a…d, columns the degree-7 monomials.
    let pairing: Vec<f64> = (0..4)
        .flat_map(|x| {
            septics
                .clone()
                .map(move |m| template.product_column[m][x])
                .map(|c| phi[c])
        })
        .collect();
    let chosen = select_columns(&pairing, 4, septics.len(), HILBERT[7], 7)?;
    basis.extend(chosen.into_iter().map(|k| septics.start + k));
    // Degree 5 against degree 3, and its transpose.
    let (n3, n5) = (cubics.len(), quintics.len());
    let pairing: Vec<f64> = template.cubic_quintic.iter().map(|&c| phi[c]).collect();
    let chosen = select_columns(&pairing, n3, n5, HILBERT[5], 5)?;
    basis.extend(chosen.into_iter().map(|k| quintics.start + k));
    let transposed: Vec<f64> = (0..n5)
        .flat_map(|m| (0..n3).map(move |c| (c, m)))
        .map(|(c, m)| pairing[c * n5 + m])
        .collect();
    let chosen = select_columns(&transposed, n5, n3, HILBERT[3], 3)?;
    basis.extend(chosen.into_iter().map(|k| cubics.start + k));
    basis.extend(offsets[3]..offsets[3] + 4);
    Ok(basis)
}

/// The socle functional `φ` on the degree-8 monomials (indexed by the
/// block's original top columns): zero on the top part of every degree-8
/// row, 1 on the standard monomial `s₈`. In the permuted order of the
/// echelon, `s₈` sits at position 0 and pivot `s` at `top − 1 − s`, whose row
/// has entries only at positions up to its own: back substitution.
fn socle_functional(block: &Block, matrix: &[f64], echelon: &Echelon) -> Vec<f64> {
    let (top, width) = (block.top_len, block.width());
    let mut phi_permuted = vec![0.0; top];
    phi_permuted[0] = 1.0;
    for (step, &row) in echelon.pivot_rows.iter().enumerate().rev() {
        let position = top - 1 - step;
        let u = &matrix[row * width..row * width + position + 1];
        let dot: f64 = u[..position]
            .iter()
            .zip(&phi_permuted[..position])
            .map(|(a, b)| a * b)
            .sum();
        phi_permuted[position] = -dot / u[position];
    }
    let mut phi = vec![0.0; top];
    for (position, &column) in echelon.permutation.iter().enumerate() {
        phi[column] = phi_permuted[position];
    }
    phi
}

/// Greedy column pivoting (modified Gram–Schmidt, largest residual first)
/// on the row-major `rows × cols` matrix: the indices of `count` columns.
/// Fails with `RankDeficient` for `degree` when fewer are independent.
fn select_columns(
    matrix: &[f64],
    rows: usize,
    cols: usize,
    count: usize,
    degree: usize,
) -> Result<Vec<usize>, SolverError> {
    // Column-major copy: column c is columns[c * rows..(c + 1) * rows].
    let mut columns = vec![0.0; rows * cols];
    for r in 0..rows {
        for c in 0..cols {
            columns[c * rows + r] = matrix[r * cols + c];
        }
    }
    let mut norms: Vec<f64> = columns
        .chunks_exact(rows)
        .map(|v| v.iter().map(|x| x * x).sum())
        .collect();
    let mut taken = vec![false; cols];
    let mut chosen = Vec::with_capacity(count);
    let mut pivot = vec![0.0; rows];
    let mut first = 0.0;
    for step in 0..count {
        let best = (0..cols)
            .filter(|&c| !taken[c])
            .max_by(|&a, &b| norms[a].total_cmp(&norms[b]))
            .unwrap_or(0);
        let norm = norms[best].sqrt();
        if step == 0 {
            first = norm;
        }
        if norm.is_nan() || norm <= PAIRING_RANK_TOLERANCE * first {
            return Err(SolverError::RankDeficient {
                degree,
                found: step,
                expected: count,
            });
        }
        chosen.push(best);
        taken[best] = true;
        for (p, x) in pivot
            .iter_mut()
            .zip(&columns[best * rows..(best + 1) * rows])
        {
            *p = x / norm;
        }
        for c in 0..cols {
            if taken[c] {
                continue;
            }
            let column = &mut columns[c * rows..(c + 1) * rows];
            let projection: f64 = column.iter().zip(&pivot).map(|(a, b)| a * b).sum();
            let mut norm_sq = 0.0;
            for (a, b) in column.iter_mut().zip(&pivot) {
                *a -= projection * b;
                norm_sq += *a * *a;
            }
            norms[c] = norm_sq;
        }
    }
    Ok(chosen)
}

/// Echelon form of one block after [`eliminate`]. Columns of the top part
/// were permuted as pivots were taken: pivot `s` sits at position
/// `top_len − 1 − s`, and `permutation[k]` is the original top column now at
/// position `k`. Every row shares the permutation.
struct Echelon {
    /// Storage row of pivot `s`, in elimination order.
    pivot_rows: Vec<usize>,
    /// Original top column at each (permuted) position.
    permutation: Vec<usize>,
    /// Original top columns left without a pivot: this degree's standard
    /// monomials.
    standard: Vec<usize>,
    /// Whether the tail was left as filled ([`TailHandling::Deferred`]), with
    /// the elimination multipliers stored in place of the zeros.
    deferred_tail: bool,
}

/// How [`eliminate`] treats a block's tail (its degree `k − 2` columns).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum TailHandling {
    /// Every row update is applied to the tail too; a normal form then
    /// subtracts the pivot rows' reduced tails.
    Carried,
    /// The tail keeps the filled coefficients and each row stores its
    /// multiplier where the pivot column was eliminated (an LU
    /// factorisation, `R = L·U` for the pivot rows `R`). A normal form
    /// `g − Σ g_s U_s` then needs `Σ g_s tail(U_s) = Σ h_s tail(R_s)` with
    /// `Lᵀh = g`: one more triangular solve per reduced monomial, but no
    /// tail updates in the elimination. For degree 8 (84 tail columns, about
    /// 170 rows, 164 pivots, 16 reduced monomials) this saves about 1 M of
    /// the block's 3 M multiply-adds.
    Deferred,
}

/// Gaussian elimination with complete pivoting over the first `block.top_len`
/// columns of the row-major `matrix` (rows × `width`; the remaining columns,
/// the block's tail if present, are carried along or deferred as
/// `block.tail` says), stopping after `block.rank` pivots.
///
/// Each pivot column is swapped to the end of the still-active top columns,
/// so the row updates touch only the active columns and the tail. Rows keep
/// their storage position; a row whose entry in the pivot column is exactly
/// zero is skipped (the template is sparse at first), and each row's largest
/// active entry is tracked so the next pivot is found in O(rows).
fn eliminate(matrix: &mut [f64], width: usize, block: &Block) -> Result<Echelon, SolverError> {
    let rows = matrix.len() / width;
    let top = block.top_len;
    let mut permutation: Vec<usize> = (0..top).collect();
    let mut row_used = vec![false; rows];
    let mut pivot_rows = Vec::with_capacity(block.rank);
    let mut pivot_values = vec![0.0; width];
    // Largest |entry| over the active top columns, per row.
    let mut maxima: Vec<f64> = (0..rows)
        .map(|r| max_abs(&matrix[r * width..r * width + top]))
        .collect();
    let mut active = top;
    let mut first_pivot = 0.0;
    let mut smallest_pivot = f64::INFINITY;
    let deferred = block.tail == TailHandling::Deferred;
    for step in 0..block.rank {
        let pivot_row = (0..rows)
            .filter(|&r| !row_used[r])
            .max_by(|&a, &b| maxima[a].total_cmp(&maxima[b]))
            .unwrap_or(0);
        let magnitude = maxima[pivot_row];
        if step == 0 {
            first_pivot = magnitude;
        }
        if row_used[pivot_row] || magnitude.is_nan() || magnitude <= RANK_TOLERANCE * first_pivot {
            return Err(SolverError::RankDeficient {
                degree: block.degree,
                found: step,
                expected: block.rank,
            });
        }
        smallest_pivot = smallest_pivot.min(magnitude);
        row_used[pivot_row] = true;
        pivot_rows.push(pivot_row);
        let pivot_position = matrix[pivot_row * width..pivot_row * width + active]
            .iter()
            .position(|v| v.abs() == magnitude)
            .unwrap_or(active - 1);
        // Move the pivot column to the end of the active columns.
        let last = active - 1;
        if pivot_position != last {
            for r in 0..rows {
                matrix.swap(r * width + pivot_position, r * width + last);
            }
            permutation.swap(pivot_position, last);
        }
        active = last;
        pivot_values.copy_from_slice(&matrix[pivot_row * width..(pivot_row + 1) * width]);
        let inverse_pivot = 1.0 / pivot_values[last];
        for r in 0..rows {
            if row_used[r] {
                continue;
            }
            let row = &mut matrix[r * width..(r + 1) * width];
            let factor = row[last] * inverse_pivot;
            row[last] = if deferred { factor } else { 0.0 };
            if factor == 0.0 {
                continue;
            }
            maxima[r] =
                subtract_scaled_max_abs(&mut row[..active], &pivot_values[..active], factor);
            if !deferred {
                for (a, b) in row[top..].iter_mut().zip(&pivot_values[top..]) {
                    *a -= factor * b;
                }
            }
        }
    }
    let remaining = (0..rows)
        .filter(|&r| !row_used[r])
        .map(|r| maxima[r])
        .fold(0.0, f64::max);
    if remaining > RANK_GAP * smallest_pivot {
        return Err(SolverError::RankDeficient {
            degree: block.degree,
            found: block.rank + 1,
            expected: block.rank,
        });
    }
    let standard = permutation[..active].to_vec();
    Ok(Echelon {
        pivot_rows,
        permutation,
        standard,
        deferred_tail: deferred,
    })
}

/// Lanes of the hand-vectorised reductions below.
const LANES: usize = 4;

/// `max(m, |v|)` by one comparison, which compiles to a single `maxpd`
/// where `f64::max` (NaN-aware) costs four more instructions in the
/// elimination's inner loop. A NaN is not propagated here; the blocks'
/// entries are finite whenever the equations are, which [`solve`] checks.
#[inline(always)]
fn max_magnitude(m: f64, v: f64) -> f64 {
    let a = v.abs();
    if a > m {
        a
    } else {
        m
    }
}

/// `max |x|` over a slice, in [`LANES`] independent lanes so that it
/// vectorises without reassociating floating-point operations.
fn max_abs(x: &[f64]) -> f64 {
    let mut lanes = [0.0f64; LANES];
    let chunks = x.chunks_exact(LANES);
    let rest = chunks.remainder();
    for chunk in chunks {
        for k in 0..LANES {
            lanes[k] = max_magnitude(lanes[k], chunk[k]);
        }
    }
    rest.iter()
        .fold(lanes.into_iter().fold(0.0, max_magnitude), |m, &v| {
            max_magnitude(m, v)
        })
}

/// `a −= factor · b`, returning `max |a|` afterwards (fused, lane-wise).
fn subtract_scaled_max_abs(a: &mut [f64], b: &[f64], factor: f64) -> f64 {
    let mut lanes = [0.0f64; LANES];
    let mut a_chunks = a.chunks_exact_mut(LANES);
    let mut b_chunks = b.chunks_exact(LANES);
    for (x, y) in (&mut a_chunks).zip(&mut b_chunks) {
        for k in 0..LANES {
            x[k] -= factor * y[k];
            lanes[k] = max_magnitude(lanes[k], x[k]);
        }
    }
    let mut m = lanes.into_iter().fold(0.0, max_magnitude);
    for (x, y) in a_chunks
        .into_remainder()
        .iter_mut()
        .zip(b_chunks.remainder())
    {
        *x -= factor * y;
        m = max_magnitude(m, *x);
    }
    m
}

/// One real solution pair `±q` of the system (one representative).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RealSolution {
    /// The solution `q = (a, b, c, d)`; `−q` is a solution too.
    pub q: [f64; 4],
}

/// Output of [`solve`]: the real solution pairs, and how many real
/// eigenvalues the action matrix had (including pairs `±i·w`).
#[derive(Debug, Clone, Default)]
pub struct Solutions {
    /// One representative of every real pair `±q`, `q ≠ 0`.
    pub real: Vec<RealSolution>,
    /// Number of real eigenvalues of the action matrix.
    pub real_eigenvalues: usize,
}

/// Fixed candidate linear forms for the denominator `ℓ₂` (the coordinate
/// axes and four mixed forms); the numerator `ℓ₁` is [`NUMERATOR_FORM`].
const DENOMINATOR_FORMS: [[f64; 4]; 8] = [
    [1.0, 0.0, 0.0, 0.0],
    [0.0, 1.0, 0.0, 0.0],
    [0.0, 0.0, 1.0, 0.0],
    [0.0, 0.0, 0.0, 1.0],
    [0.5, 0.5, 0.5, 0.5],
    [0.5, -0.5, 0.5, -0.5],
    [0.5, 0.5, -0.5, -0.5],
    [0.5, -0.5, -0.5, 0.5],
];
/// The numerator form `ℓ₁`: fixed, generic, and not proportional to any
/// denominator candidate, so that `ℓ₁/ℓ₂` separates the solutions.
const NUMERATOR_FORM: [f64; 4] = [0.6172, -0.2893, 0.4351, 0.5887];

/// Diagonal of the chart matrix `A` (see [`to_chart`]): positive, so every
/// real solution lands inside the ellipsoid `pᵀAp < 1`, and unequal, so the
/// isotropic cone `q·q = 0` — where nearly isotropic systems (OPnP on a
/// symmetric marker) park their escaping solutions — is not the chart's
/// hyperplane at infinity.
pub const CHART_DIAGONAL: [f64; 4] = [0.55, 0.85, 1.2, 1.6];

/// Rewrites the system in the weighted-projective chart `s = 1 − pᵀAp`.
///
/// With the extra unknown `s` of weight 2, `F_j(q, s) = C_j(q) + s·L_j(q)` is
/// weighted homogeneous of degree 3, and `(q, s) ~ (λq, λ²s)`; the original
/// system is the chart `s = 1`, where solutions near infinity (`s → 0`)
/// have huge `‖q‖` and ruin any monomial basis up to degree 8. In the chart
/// `pᵀAp + s = 1` the system is again odd cubic,
/// `g_j(p) = C_j(p) − (pᵀAp)·L_j(p) + L_j(p)`, with the same solution pairs:
/// a solution `p` with `σ = 1 − pᵀAp > 0` is `q = p/√σ` of the original
/// (`f_j(q) = σ^{-3/2} g_j(p)`), and `σ < 0` means the original pair is
/// `±i·w`, not real.
pub fn to_chart(equations: &[OddCubic; 4]) -> [OddCubic; 4] {
    let cubic_index = |e: &Exponent| monomials::position(&CUBIC, e).unwrap();
    equations.map(|mut e| {
        for k in 0..4 {
            for r in 0..4 {
                let mut m = [0u8; 4];
                m[k] += 2;
                m[r] += 1;
                e[cubic_index(&m)] -= CHART_DIAGONAL[k] * e[CUBIC_COUNT + r];
            }
        }
        let norm = e.iter().map(|c| c * c).sum::<f64>().sqrt();
        if norm > 0.0 {
            e.iter_mut().for_each(|c| *c /= norm);
        }
        e
    })
}

/// Maps a real chart solution `p` back to `q = p/√(1 − pᵀAp)`; `None` when
/// `1 − pᵀAp ≤ 0` (the original pair is not real).
pub fn from_chart(p: &[f64; 4]) -> Option<[f64; 4]> {
    let sigma = 1.0 - (0..4).map(|k| CHART_DIAGONAL[k] * p[k] * p[k]).sum::<f64>();
    (sigma > 0.0).then(|| {
        let scale = sigma.sqrt().recip();
        p.map(|x| x * scale)
    })
}

/// Solves `f_1 = … = f_4 = 0` for its real solution pairs, through the
/// chart of [`to_chart`].
pub fn solve(equations: &[OddCubic; 4]) -> Result<Solutions, SolverError> {
    if !equations.iter().flatten().all(|c| c.is_finite()) {
        return Err(SolverError::NonFinite);
    }
    let mut solutions = solve_direct(&to_chart(equations))?;
    solutions.real = solutions
        .real
        .iter()
        .filter_map(|s| from_chart(&s.q).map(|q| RealSolution { q }))
        .collect();
    Ok(solutions)
}

/// Solves the system as given (no chart): [`solve`] without the change of
/// variables.
pub fn solve_direct(equations: &[OddCubic; 4]) -> Result<Solutions, SolverError> {
    let template = &*TEMPLATE;
    let even_len = template.even_columns.len();

    // 1. Eliminate each even degree block (complete pivoting over its top
    //    columns); the odd basis follows from the degree-8 echelon's socle.
    let (equations, leading) = interreduce(equations)?;
    let mut matrices = Vec::with_capacity(3);
    let mut echelons = Vec::with_capacity(3);
    for block in &template.blocks {
        let (mut matrix, width) = fill(block, &equations, &leading);
        let echelon = eliminate(&mut matrix, width, block)?;
        matrices.push(matrix);
        echelons.push(echelon);
    }
    let basis = odd_basis_from_socle(template, &matrices[0], &echelons[0])?;

    // 2. The even basis (constant dropped): standard monomials of degree 8,
    //    6, 4 (from the eliminations), then all ten of degree 2.
    let mut basis_of_column = vec![usize::MAX; even_len];
    let mut basis_len = 0;
    for (block, echelon) in template.blocks.iter().zip(&echelons) {
        for &c in &echelon.standard {
            basis_of_column[block.top_offset + c] = basis_len;
            basis_len += 1;
        }
    }
    for slot in &mut basis_of_column[template.degree_offsets[3]..template.degree_offsets[4]] {
        *slot = basis_len;
        basis_len += 1;
    }
    debug_assert_eq!(basis_len, SOLUTION_PAIRS);

    // 3. Normal forms of x·b for x ∈ {a, b, c, d} and b in the odd basis,
    //    reduced block by block; each distinct monomial once.
    let mut normal_forms: Vec<Option<Vec<f64>>> = vec![None; even_len];
    let mut work = vec![0.0; even_len];
    let mut scratch = Vec::new();
    let mut multiplication: [DMatrix<f64>; 4] =
        std::array::from_fn(|_| DMatrix::zeros(SOLUTION_PAIRS, SOLUTION_PAIRS));
    for (x, matrix) in multiplication.iter_mut().enumerate() {
        for (i, &odd_column) in basis.iter().enumerate() {
            let column = template.product_column[odd_column][x];
            if normal_forms[column].is_none() {
                work.iter_mut().for_each(|v| *v = 0.0);
                work[column] = 1.0;
                reduce(&mut work, template, &matrices, &echelons, &mut scratch);
                let coordinates = (0..even_len)
                    .filter(|&c| basis_of_column[c] != usize::MAX)
                    .map(|c| (basis_of_column[c], work[c]))
                    .fold(vec![0.0; SOLUTION_PAIRS], |mut acc, (k, v)| {
                        acc[k] = v;
                        acc
                    });
                normal_forms[column] = Some(coordinates);
            }
            let coordinates = normal_forms[column].as_ref().unwrap();
            for (k, &v) in coordinates.iter().enumerate() {
                matrix[(k, i)] = v;
            }
        }
    }

    // 4. Denominator ℓ₂: the best-conditioned candidate; A = M_ℓ₂⁻¹ M_ℓ₁.
    let combine = |form: &[f64; 4]| {
        let mut m = DMatrix::zeros(SOLUTION_PAIRS, SOLUTION_PAIRS);
        for (x, &w) in form.iter().enumerate() {
            if w != 0.0 {
                m += &multiplication[x] * w;
            }
        }
        m
    };
    let mut best: Option<(f64, nalgebra::LU<f64, nalgebra::Dyn, nalgebra::Dyn>)> = None;
    for form in &DENOMINATOR_FORMS {
        let lu = combine(form).lu();
        let diagonal = lu.u().diagonal().map(f64::abs);
        let rcond = diagonal.min() / diagonal.max();
        if rcond.is_finite() && best.as_ref().is_none_or(|(b, _)| rcond > *b) {
            best = Some((rcond, lu));
        }
        if rcond >= DENOMINATOR_GOOD_RCOND {
            break;
        }
    }
    let (rcond, lu) = best.ok_or(SolverError::SingularDenominator)?;
    if rcond.is_nan() || rcond <= DENOMINATOR_RCOND {
        return Err(SolverError::SingularDenominator);
    }
    let action = lu
        .solve(&combine(&NUMERATOR_FORM))
        .ok_or(SolverError::SingularDenominator)?;

    // 5. Eigenvalues of Aᵀ (balanced Hessenberg QR, eigenvalues only), then
    //    an eigenvector for each real one by inverse iteration: the
    //    odd-basis values at the solution pairs.
    let transposed = SMatrix::<f64, SOLUTION_PAIRS, SOLUTION_PAIRS>::from_fn(|i, j| action[(j, i)]);
    let eigenvalues =
        eigenvalues::eigenvalues(&transposed).map_err(|_| SolverError::SchurFailed)?;
    let mut solutions = Solutions::default();
    for eigenvalue in &eigenvalues {
        let modulus = eigenvalue.re.hypot(eigenvalue.im);
        // A numerically split real pair is kept once, as its real part.
        if eigenvalue.im < 0.0 || eigenvalue.im > NEAR_REAL * modulus {
            continue;
        }
        solutions.real_eigenvalues += 1;
        let Some(vector) = inverse_iteration(&transposed, eigenvalue.re) else {
            continue;
        };
        if let Some(q) = extract(template, &basis, &vector) {
            solutions.real.push(RealSolution { q });
        }
    }
    Ok(solutions)
}

/// Steps of inverse iteration per eigenvector: the shift is an eigenvalue
/// to rounding, so one step already gives the eigenvector to working
/// accuracy; the second removes what a nearby eigenvalue left.
pub const INVERSE_ITERATION_STEPS: usize = 2;

/// The eigenvector of `a` for its (computed) real eigenvalue `lambda` by
/// inverse iteration: LU with partial pivoting of `a − λI` once, in place,
/// exactly-zero pivots replaced by `ε‖a‖` (the shift is an eigenvalue, so
/// the matrix is singular to rounding: that is what makes one step enough).
fn inverse_iteration<const N: usize>(
    a: &SMatrix<f64, N, N>,
    lambda: f64,
) -> Option<SVector<f64, N>> {
    // Row-major copy of a − λI.
    let mut lu = [[0.0f64; N]; N];
    for (i, row) in lu.iter_mut().enumerate() {
        for (j, v) in row.iter_mut().enumerate() {
            *v = a[(i, j)];
        }
        row[i] -= lambda;
    }
    let scale = a.amax().max(f64::MIN_POSITIVE);
    let tiny = f64::EPSILON * scale;
    let mut permutation: [usize; N] = std::array::from_fn(|i| i);
    for k in 0..N {
        let pivot_row = (k..N)
            .max_by(|&x, &y| lu[x][k].abs().total_cmp(&lu[y][k].abs()))
            .unwrap_or(k);
        lu.swap(k, pivot_row);
        permutation.swap(k, pivot_row);
        if lu[k][k].abs() < tiny {
            lu[k][k] = if lu[k][k] < 0.0 { -tiny } else { tiny };
        }
        let inverse_pivot = 1.0 / lu[k][k];
        let (upper, lower) = lu.split_at_mut(k + 1);
        let pivot = &upper[k];
        for row in lower.iter_mut() {
            let factor = row[k] * inverse_pivot;
            row[k] = factor;
            if factor == 0.0 {
                continue;
            }
            for (x, p) in row[k + 1..].iter_mut().zip(&pivot[k + 1..]) {
                *x -= factor * p;
            }
        }
    }
    // Start from a fixed vector with no special relation to the basis.
    let mut x: [f64; N] = std::array::from_fn(|i| 1.0 + 0.1 * ((i * 7) % 11) as f64);
    for _ in 0..INVERSE_ITERATION_STEPS {
        let mut y: [f64; N] = std::array::from_fn(|i| x[permutation[i]]);
        for i in 0..N {
            let sum: f64 = (0..i).map(|j| lu[i][j] * y[j]).sum();
            y[i] -= sum;
        }
        for i in (0..N).rev() {
            let sum: f64 = (i + 1..N).map(|j| lu[i][j] * y[j]).sum();
            y[i] = (y[i] - sum) / lu[i][i];
        }
        let norm = y.iter().map(|v| v * v).sum::<f64>().sqrt();
        if !norm.is_finite() || norm == 0.0 {
            return None;
        }
        x = y.map(|v| v / norm);
    }
    Some(SVector::from(x))
}

/// Reduces the even polynomial `g` (dense over the global even columns)
/// modulo `I`, block by block: afterwards it is nonzero only on standard
/// monomials and in degrees 2 and 0. `scratch` holds one block row.
fn reduce(
    g: &mut [f64],
    template: &Template,
    matrices: &[Vec<f64>],
    echelons: &[Echelon],
    scratch: &mut Vec<f64>,
) {
    for ((block, matrix), echelon) in template.blocks.iter().zip(matrices).zip(echelons) {
        let width = block.width();
        let top = block.top_len;
        let span = &mut g[block.top_offset..block.top_offset + width];
        if span[..top].iter().all(|&v| v == 0.0) {
            continue;
        }
        // Into the block's permuted column order.
        scratch.clear();
        scratch.extend(echelon.permutation.iter().map(|&c| span[c]));
        scratch.extend_from_slice(&span[top..]);
        if echelon.deferred_tail {
            reduce_deferred(scratch, top, width, matrix, echelon);
        } else {
            for (step, &row) in echelon.pivot_rows.iter().enumerate() {
                let position = top - 1 - step;
                let value = scratch[position];
                if value == 0.0 {
                    continue;
                }
                let pivot_row = &matrix[row * width..(row + 1) * width];
                let factor = value / pivot_row[position];
                for (a, b) in scratch[..position].iter_mut().zip(&pivot_row[..position]) {
                    *a -= factor * b;
                }
                for (a, b) in scratch[top..].iter_mut().zip(&pivot_row[top..]) {
                    *a -= factor * b;
                }
                scratch[position] = 0.0;
            }
        }
        for (k, &c) in echelon.permutation.iter().enumerate() {
            span[c] = scratch[k];
        }
        span[top..].copy_from_slice(&scratch[top..]);
    }
}

/// [`reduce`] through a block eliminated with [`TailHandling::Deferred`]:
/// `scratch` holds one polynomial in the block's permuted top order, then
/// its tail. (1) Forward sweep over the `U` rows (top parts only), leaving
/// `g_s` at pivot position `s`; (2) `Lᵀh = g` in place, backwards over the
/// positions, each row's multipliers lying right of its own position; (3)
/// the tail loses `Σ h_s · tail(R_s)`, the filled tails of the pivot rows.
/// Afterwards the top part is nonzero only on the standard columns.
fn reduce_deferred(
    scratch: &mut [f64],
    top: usize,
    width: usize,
    matrix: &[f64],
    echelon: &Echelon,
) {
    let rank = echelon.pivot_rows.len();
    for (step, &row) in echelon.pivot_rows.iter().enumerate() {
        let position = top - 1 - step;
        let value = scratch[position];
        if value == 0.0 {
            continue;
        }
        let pivot_row = &matrix[row * width..row * width + position + 1];
        let factor = value / pivot_row[position];
        for (a, b) in scratch[..position].iter_mut().zip(&pivot_row[..position]) {
            *a -= factor * b;
        }
        scratch[position] = factor;
    }
    let (top_part, tail) = scratch.split_at_mut(top);
    for step in (0..rank).rev() {
        let position = top - 1 - step;
        let h = top_part[position];
        if h == 0.0 {
            continue;
        }
        let row = &matrix[echelon.pivot_rows[step] * width..(echelon.pivot_rows[step] + 1) * width];
        for (a, b) in top_part[position + 1..]
            .iter_mut()
            .zip(&row[position + 1..top])
        {
            *a -= h * b;
        }
        for (a, b) in tail.iter_mut().zip(&row[top..]) {
            *a -= h * b;
        }
    }
    top_part[top - rank..].iter_mut().for_each(|v| *v = 0.0);
}

/// Reads `q` off an eigenvector `v ∝ (b(q))_{b∈B}`: the direction from the
/// linear monomials, `|q|²` by least squares over the cubic ones. `None` when
/// the pair is not real (`|q|² ≤ 0`) or the vector is unusable.
fn extract(
    template: &Template,
    basis: &[usize],
    v: &SVector<f64, SOLUTION_PAIRS>,
) -> Option<[f64; 4]> {
    // The linear monomials are the last four basis entries (see `odd_basis`).
    let linear: [f64; 4] = std::array::from_fn(|k| v[SOLUTION_PAIRS - 4 + k]);
    let linear_norm = linear.iter().map(|x| x * x).sum::<f64>().sqrt();
    if !linear_norm.is_finite() || linear_norm <= 0.0 {
        return None;
    }
    let direction = linear.map(|x| x / linear_norm);
    let (mut numerator, mut denominator) = (0.0, 0.0);
    for (i, &column) in basis.iter().enumerate() {
        let monomial = &template.odd_columns[column];
        if monomials::degree(monomial) != 3 {
            continue;
        }
        let m = monomials::evaluate(monomial, &direction);
        numerator += v[i] * m;
        denominator += m * m;
    }
    let norm_sq = numerator / (linear_norm * denominator);
    if !norm_sq.is_finite() || norm_sq <= 0.0 {
        return None;
    }
    let norm = norm_sq.sqrt();
    Some(direction.map(|x| x * norm))
}

/// Newton's method on the square system `f(q) = 0`, started at `q`: at most
/// `iterations` steps, stopping early when a step no longer shrinks the
/// residual. Polishes the eigenvector estimates to full precision.
pub fn newton_polish(equations: &[OddCubic; 4], q: &[f64; 4], iterations: usize) -> [f64; 4] {
    let residual_norm = |q: &[f64; 4]| {
        equations
            .iter()
            .map(|e| evaluate(e, q).powi(2))
            .sum::<f64>()
            .sqrt()
    };
    let mut current = *q;
    let mut current_norm = residual_norm(&current);
    for _ in 0..iterations {
        let mut jacobian = nalgebra::Matrix4::zeros();
        let mut value = nalgebra::Vector4::zeros();
        for (j, e) in equations.iter().enumerate() {
            value[j] = evaluate(e, &current);
            let gradient = gradient(e, &current);
            for k in 0..4 {
                jacobian[(j, k)] = gradient[k];
            }
        }
        let Some(step) = jacobian.lu().solve(&value) else {
            break;
        };
        let next = std::array::from_fn(|k| current[k] - step[k]);
        let next_norm = residual_norm(&next);
        if next_norm.is_nan() || next_norm >= current_norm {
            break;
        }
        current = next;
        current_norm = next_norm;
    }
    current
}

/// Gradient of an odd cubic equation at `q`.
pub fn gradient(equation: &OddCubic, q: &[f64; 4]) -> [f64; 4] {
    let mut out = [0.0; 4];
    for (m, c) in CUBIC.iter().zip(equation) {
        for k in 0..4 {
            if m[k] > 0 {
                let mut reduced = *m;
                reduced[k] -= 1;
                out[k] += c * f64::from(m[k]) * monomials::evaluate(&reduced, q);
            }
        }
    }
    for k in 0..4 {
        out[k] += equation[CUBIC_COUNT + k];
    }
    out
}

/// Evaluates an odd cubic equation at `q`.
pub fn evaluate(equation: &OddCubic, q: &[f64; 4]) -> f64 {
    let cubic: f64 = CUBIC
        .iter()
        .zip(equation)
        .map(|(m, c)| c * monomials::evaluate(m, q))
        .sum();
    cubic
        + (0..4)
            .map(|k| equation[CUBIC_COUNT + k] * q[k])
            .sum::<f64>()
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::DVector;
    use rand::{Rng, SeedableRng};

    /// Four odd cubic equations that vanish at the given points: a basis of
    /// the null space of the evaluation conditions, randomly combined.
    fn system_through(points: &[[f64; 4]], rng: &mut impl Rng) -> [OddCubic; 4] {
        let rows = points.len();
        let mut conditions = DMatrix::zeros(rows.max(1), EQUATION_TERMS);
        for (r, p) in points.iter().enumerate() {
            for (t, m) in CUBIC.iter().enumerate() {
                conditions[(r, t)] = monomials::evaluate(m, p);
            }
            for k in 0..4 {
                conditions[(r, CUBIC_COUNT + k)] = p[k];
            }
        }
        // Null space from the SVD of the (padded) square system.
        let mut square = DMatrix::zeros(EQUATION_TERMS, EQUATION_TERMS);
        square
            .view_mut((0, 0), (rows, EQUATION_TERMS))
            .copy_from(&conditions.rows(0, rows));
        let svd = square.svd(false, true);
        let v_t = svd.v_t.unwrap();
        let mut order: Vec<usize> = (0..EQUATION_TERMS).collect();
        order.sort_by(|&a, &b| svd.singular_values[a].total_cmp(&svd.singular_values[b]));
        let null: Vec<_> = order[..EQUATION_TERMS - rows]
            .iter()
            .map(|&k| v_t.row(k).transpose())
            .collect();
        std::array::from_fn(|_| {
            let mut e = DVector::zeros(EQUATION_TERMS);
            for v in &null {
                e += v * rng.random_range(-1.0..1.0);
            }
            std::array::from_fn(|t| e[t])
        })
    }

    fn distance_up_to_sign(x: &[f64; 4], y: &[f64; 4]) -> f64 {
        let minus: f64 = (0..4).map(|k| (x[k] - y[k]).powi(2)).sum::<f64>().sqrt();
        let plus: f64 = (0..4).map(|k| (x[k] + y[k]).powi(2)).sum::<f64>().sqrt();
        minus.min(plus)
    }

    #[test]
    fn template_has_the_predicted_shape() {
        let template = &*TEMPLATE;
        assert_eq!(template.even_columns.len(), 295);
        assert_eq!(template.block_sizes(), [(224, 249), (80, 119), (16, 45)]);
        assert_eq!(template.blocks.clone().map(|b| b.rank), [164, 74, 16]);
        assert_eq!(template.odd_columns.len(), 200);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(2);
        let equations: [OddCubic; 4] =
            std::array::from_fn(|_| std::array::from_fn(|_| rng.random_range(-1.0..1.0)));
        let block = &template.blocks[0];
        let (equations, leading) = interreduce(&equations).unwrap();
        let (mut matrix, width) = fill(block, &equations, &leading);
        // 224 rows less at least 48 Koszul redundancies (10 + 16 + 22 when
        // the leading monomials share the most), never below the rank.
        let rows = matrix.len() / width;
        assert!((164..=176).contains(&rows), "{rows} rows");
        let echelon = eliminate(&mut matrix, width, block).unwrap();
        assert_eq!(echelon.standard.len(), 1);
        let basis = odd_basis_from_socle(template, &matrix, &echelon).unwrap();
        assert_eq!(basis.len(), SOLUTION_PAIRS);
        let per_degree: Vec<usize> = [1, 3, 5, 7]
            .iter()
            .map(|&d| {
                basis
                    .iter()
                    .filter(|&&c| monomials::degree(&template.odd_columns[c]) == d)
                    .count()
            })
            .collect();
        assert_eq!(per_degree, vec![4, 16, 16, 4]);
    }

    #[test]
    fn socle_functional_annihilates_every_degree_8_row_even_the_dropped_ones() {
        let template = &*TEMPLATE;
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(4);
        let equations: [OddCubic; 4] =
            std::array::from_fn(|_| std::array::from_fn(|_| rng.random_range(-1.0..1.0)));
        let block = &template.blocks[0];
        let (equations, leading) = interreduce(&equations).unwrap();
        let (mut matrix, width) = fill(block, &equations, &leading);
        let echelon = eliminate(&mut matrix, width, block).unwrap();
        let phi = socle_functional(block, &matrix, &echelon);
        assert_eq!(phi[echelon.standard[0]], 1.0);
        let scale = phi.iter().map(|v| v.abs()).fold(0.0, f64::max);
        for row in &block.rows {
            let value: f64 = row
                .top
                .iter()
                .zip(&equations[row.equation])
                .map(|(&c, e)| phi[usize::from(c)] * e)
                .sum();
            assert!(value.abs() < 1e-12 * scale, "φ(row) = {value}");
        }
    }

    #[test]
    fn random_systems_real_solutions_satisfy_the_equations() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        for _ in 0..20 {
            let equations: [OddCubic; 4] =
                std::array::from_fn(|_| std::array::from_fn(|_| rng.random_range(-1.0..1.0)));
            let solutions = solve(&equations).expect("generic system");
            assert!(solutions.real_eigenvalues <= SOLUTION_PAIRS);
            assert!(solutions.real.len() <= solutions.real_eigenvalues);
            for s in &solutions.real {
                // Residuals relative to the size of the terms at q.
                let q = newton_polish(&equations, &s.q, 5);
                let scale: f64 = q.iter().map(|x| x.abs()).fold(0.0, f64::max);
                let scale = scale.powi(3) + scale;
                for e in &equations {
                    let residual = evaluate(e, &q) / scale;
                    assert!(residual.abs() < 1e-12, "residual {residual} at {q:?}");
                }
                let step: f64 = (0..4).map(|k| (q[k] - s.q[k]).powi(2)).sum::<f64>().sqrt();
                assert!(
                    step < 1e-3 * scale.cbrt().max(1.0),
                    "polish moved {step} from {:?}",
                    s.q
                );
            }
        }
    }

    #[test]
    fn recovers_prescribed_roots() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        for trial in 0..20 {
            let roots: Vec<[f64; 4]> = (0..6)
                .map(|_| std::array::from_fn(|_| rng.random_range(-1.5..1.5)))
                .collect();
            let equations = system_through(&roots, &mut rng);
            let solutions = solve(&equations).expect("generic system");
            let polished: Vec<[f64; 4]> = solutions
                .real
                .iter()
                .map(|s| newton_polish(&equations, &s.q, 5))
                .collect();
            for root in &roots {
                let nearest = polished
                    .iter()
                    .map(|q| distance_up_to_sign(q, root))
                    .fold(f64::INFINITY, f64::min);
                assert!(
                    nearest < 1e-12,
                    "trial {trial}: root {root:?} missed by {nearest}"
                );
            }
        }
    }

    #[test]
    fn chart_keeps_the_solutions() {
        // g_j(p) = σ^{3/2} f_j(q) for q = p/√σ, σ = 1 − pᵀAp (up to the row scaling).
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(8);
        let equations: [OddCubic; 4] =
            std::array::from_fn(|_| std::array::from_fn(|_| rng.random_range(-1.0..1.0)));
        let chart = to_chart(&equations);
        let p = [0.3, -0.2, 0.4, 0.1];
        let q = from_chart(&p).unwrap();
        let sigma: f64 = 1.0 - (0..4).map(|k| CHART_DIAGONAL[k] * p[k] * p[k]).sum::<f64>();
        for (f, g) in equations.iter().zip(&chart) {
            let ratio = evaluate(g, &p) / (sigma.powf(1.5) * evaluate(f, &q));
            // The ratio is the row's normalisation factor, the same at any point.
            let p2 = [-0.1, 0.5, 0.2, -0.3];
            let q2 = from_chart(&p2).unwrap();
            let sigma2: f64 = 1.0
                - (0..4)
                    .map(|k| CHART_DIAGONAL[k] * p2[k] * p2[k])
                    .sum::<f64>();
            let ratio2 = evaluate(g, &p2) / (sigma2.powf(1.5) * evaluate(f, &q2));
            assert!(
                (ratio - ratio2).abs() < 1e-12 * ratio.abs(),
                "{ratio} vs {ratio2}"
            );
        }
        // Outside the ellipsoid pᵀAp < 1 the original pair is not real.
        assert_eq!(from_chart(&[1.0, 1.0, 0.0, 0.0]), None);
    }

    #[test]
    fn degenerate_system_is_a_typed_error() {
        // All four equations equal: a positive-dimensional solution set.
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let e: OddCubic = std::array::from_fn(|_| rng.random_range(-1.0..1.0));
        let err = solve(&[e, e, e, e]).unwrap_err();
        assert!(matches!(err, SolverError::RankDeficient { .. }), "{err}");
    }
}
