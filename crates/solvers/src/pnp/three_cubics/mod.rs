//! Every real solution of three cubic equations in three unknowns,
//! `f₁(x) = f₂(x) = f₃(x) = 0`, by a Macaulay elimination template and the
//! eigenvalues of the action (multiplication) matrix it yields.
//!
//! **Problem.** Three dense cubics in `x ∈ ℝ³` with no common root at
//! infinity have Bézout's `3·3·3 = 27` complex roots. DLS's optimality
//! conditions (the gradient of a quartic) are such a system; so is any
//! gradient of a generic quartic.
//!
//! **Method** (after Macaulay 1902 and the action-matrix method of Auzinger &
//! Stetter 1988, as Hesch & Roumeliotis use it for DLS, ICCV 2011 §III-C):
//! 1. Change variables `x = Q y` by a fixed rotation `Q` ([`generic_rotation`])
//!    with no special relation to the axes, so that inputs with symmetries
//!    tied to the coordinate axes do not make the template degenerate.
//!    Each cubic is scaled to unit largest coefficient.
//! 2. The 27 *box* monomials `y1^a y2^b y3^c` (`a, b, c ≤ 2`) are a basis of
//!    the quotient ring whenever the template below is invertible. Every
//!    other monomial of degree ≤ 7 owns one template row (see
//!    [`monomials`]): 93 polynomials `y^μ f_k` of the ideal, written
//!    `C m_N + D m_B = 0` with `m_N` the 93 non-box and `m_B` the box
//!    monomials. `C` is block triangular by degree (blocks of 3, 9, 18, 27
//!    and 36), so `C⁻¹` is applied block by block with a partial-pivoting LU
//!    per diagonal block (≈ 50 k flops instead of ≈ 540 k for the dense
//!    93 × 93 LU of the paper's Schur complement).
//! 3. Multiplication by `y1` maps box monomials with `a < 2` to box
//!    monomials; the other nine, `y1·y1²y2^b y3^c = y1³ y2^b y3^c`, are
//!    template monomials whose rows of `−C⁻¹D` express them in the box. Only
//!    those nine rows are needed, so `Cᵀ Z = E` is solved for nine right-hand
//!    sides and the rows are `−Zᵀ D`. This gives the 27 × 27 action matrix
//!    `A` with `A m_B(y) = y1 m_B(y)` at every root.
//! 4. The eigenvalues of `A` ([`crate::linalg::nonsymmetric::eigenvalues`]) are the `y1` of the 27 roots.
//!    `A` is a block companion matrix, so for a real eigenvalue `λ` the
//!    eigenvector's first nine entries `w = (y2^b y3^c)` span the null space
//!    of the 9 × 9 matrix `λ³ I − λ² A₂ − λ A₁ − A₀`; `y2` and `y3` are read
//!    off as least-squares ratios of consecutive powers in `w`.
//! 5. Each real root is polished by Newton's method on the original system
//!    and kept only if its relative residual is below
//!    [`ROOT_RESIDUAL_TOLERANCE`]; duplicates are merged.
//!
//! Nothing is allocated: every matrix is fixed-size on the stack.

pub mod monomials;

use monomials::{
    box_index, index, Slot, BLOCK_SIZES, BLOCK_STARTS, BOX_COUNT, CUBIC_TERMS, MONOMIALS,
    ROW_COLUMNS, ROW_EQUATION, SLOTS, TEMPLATE_COUNT,
};
use nalgebra::{Matrix3, Rotation3, SMatrix, Vector3};
use smallvec::SmallVec;

/// A cubic in three unknowns: its 20 coefficients in the graded monomial
/// order of [`monomials::index`] (constant, x1, x2, x3, x1², x1x2, …, x3³).
pub type Cubic = [f64; CUBIC_TERMS];

/// The real roots of a system; at most 27, so they never leave the stack.
pub type Roots = SmallVec<[Vector3<f64>; BOX_COUNT]>;

/// Number of action-matrix rows that need the template: the box monomials
/// with `a = 2`, whose product with `y1` leaves the box.
pub const TEMPLATE_TARGETS: usize = 9;

/// A diagonal template block whose LU pivot falls below this fraction of its
/// largest entry counts as singular: the system has (or nearly has) a root
/// at infinity in these variables.
pub const TEMPLATE_PIVOT_TOLERANCE: f64 = 1e-13;
/// An eigenvalue counts as real if its imaginary part is below this
/// fraction of `1 + |λ|`. Loose on purpose: Newton's method and the
/// residual test decide whether a real root is really there.
pub const REAL_EIGENVALUE_TOLERANCE: f64 = 1e-5;
/// Newton iterations allowed when polishing a root.
pub const NEWTON_MAX_ITERATIONS: usize = 8;
/// A root is accepted when `max_k |f_k(x)| / Σ_j |c_kj x^j|` (the residual
/// relative to the size of the terms that cancel) is below this.
pub const ROOT_RESIDUAL_TOLERANCE: f64 = 1e-9;
/// Two roots closer than this (relative to `1 + ‖x‖`) are the same root.
pub const DUPLICATE_ROOT_TOLERANCE: f64 = 1e-7;

/// Why the system could not be solved.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum CubicSystemError {
    /// A coefficient was NaN or infinite.
    NonFinite,
    /// A diagonal block of the Macaulay template is singular.
    SingularTemplate {
        /// Degree (3…7) of the singular block.
        degree: usize,
    },
    /// The eigenvalues of the action matrix could not be computed.
    Eigenvalues(crate::linalg::nonsymmetric::EigenvalueError),
}

impl std::fmt::Display for CubicSystemError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            CubicSystemError::NonFinite => f.write_str("a polynomial coefficient is not finite"),
            CubicSystemError::SingularTemplate { degree } => write!(
                f,
                "the Macaulay elimination template is singular (degree-{degree} block)"
            ),
            CubicSystemError::Eigenvalues(source) => {
                write!(f, "eigenvalues of the action matrix: {source}")
            }
        }
    }
}

impl std::error::Error for CubicSystemError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            CubicSystemError::Eigenvalues(source) => Some(source),
            _ => None,
        }
    }
}

impl From<crate::linalg::nonsymmetric::EigenvalueError> for CubicSystemError {
    fn from(source: crate::linalg::nonsymmetric::EigenvalueError) -> Self {
        CubicSystemError::Eigenvalues(source)
    }
}

/// The fixed change of variables `x = Q y`: a rotation by 1.2 rad about the
/// axis `(3, −5, 7)/√83`, chosen to be unrelated to the coordinate axes.
pub fn generic_rotation() -> Matrix3<f64> {
    let axis = Vector3::new(3.0, -5.0, 7.0).normalize();
    *Rotation3::from_scaled_axis(axis * 1.2).matrix()
}

/// `f_k(Q y)` for each cubic: the system in the solver's variables `y`.
fn change_variables(system: &[Cubic; 3], q: &Matrix3<f64>) -> [Cubic; 3] {
    // expansions[m] = coefficients (in y) of x^m with x = Q y, built up one
    // linear factor x_k = Σ_j Q_kj y_j at a time.
    let mut expansions = [[0.0; CUBIC_TERMS]; CUBIC_TERMS];
    expansions[0][0] = 1.0;
    for (m, &monomial) in MONOMIALS.iter().enumerate().take(CUBIC_TERMS).skip(1) {
        let mut exponents = monomial;
        let k = exponents.iter().position(|&e| e > 0).unwrap_or(0);
        exponents[k] -= 1;
        let lower = index(
            exponents[0] as usize,
            exponents[1] as usize,
            exponents[2] as usize,
        );
        let (done, rest) = expansions.split_at_mut(m);
        let target = &mut rest[0];
        for (term, &value) in done[lower].iter().enumerate() {
            if value == 0.0 {
                continue;
            }
            let e = MONOMIALS[term];
            for j in 0..3 {
                let mut raised = [e[0] as usize, e[1] as usize, e[2] as usize];
                raised[j] += 1;
                target[index(raised[0], raised[1], raised[2])] += value * q[(k, j)];
            }
        }
    }
    let mut out = [[0.0; CUBIC_TERMS]; 3];
    for (f, g) in system.iter().zip(out.iter_mut()) {
        for (c, expansion) in f.iter().zip(&expansions) {
            for (gj, ej) in g.iter_mut().zip(expansion) {
                *gj += c * ej;
            }
        }
    }
    out
}

/// Each cubic divided by its largest coefficient (all-zero cubics unchanged).
fn normalised(system: &[Cubic; 3]) -> [Cubic; 3] {
    let mut out = *system;
    for f in &mut out {
        let largest = f.iter().fold(0.0f64, |m, c| m.max(c.abs()));
        if largest > 0.0 {
            for c in f.iter_mut() {
                *c /= largest;
            }
        }
    }
    out
}

/// Template index of each target monomial `y1³ y2^b y3^c`, by `3b + c`.
const TARGET_TEMPLATE: [usize; TEMPLATE_TARGETS] = {
    let mut table = [0usize; TEMPLATE_TARGETS];
    let mut r = 0;
    while r < TEMPLATE_TARGETS {
        table[r] = match SLOTS[index(3, r / 3, r % 3)] {
            Slot::Template(t) => t,
            Slot::Box(_) => panic!("y1³ y2^b y3^c is never a box monomial"),
        };
        r += 1;
    }
    table
};

/// In-place LU with partial pivoting of `matrix`, then `matrix⁻¹ · rhs`.
/// Returns `false` if a pivot is below [`TEMPLATE_PIVOT_TOLERANCE`] times the
/// largest entry.
fn lu_solve<const N: usize, const R: usize>(
    matrix: &mut [[f64; N]; N],
    rhs: &mut [[f64; R]; N],
) -> bool {
    let largest = matrix.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
    let threshold = TEMPLATE_PIVOT_TOLERANCE * largest;
    if threshold.is_nan() || threshold <= 0.0 {
        return false;
    }
    for k in 0..N {
        let pivot_row = (k..N)
            .max_by(|&a, &b| matrix[a][k].abs().total_cmp(&matrix[b][k].abs()))
            .unwrap_or(k);
        let usable = matrix[pivot_row][k].abs() > threshold;
        if !usable {
            return false;
        }
        matrix.swap(k, pivot_row);
        rhs.swap(k, pivot_row);
        let inverse_pivot = 1.0 / matrix[k][k];
        let (upper, lower) = matrix.split_at_mut(k + 1);
        let (rhs_upper, rhs_lower) = rhs.split_at_mut(k + 1);
        let pivot = &upper[k];
        let pivot_rhs = &rhs_upper[k];
        for (row, row_rhs) in lower.iter_mut().zip(rhs_lower.iter_mut()) {
            let factor = row[k] * inverse_pivot;
            if factor == 0.0 {
                continue;
            }
            for j in k + 1..N {
                row[j] -= factor * pivot[j];
            }
            for j in 0..R {
                row_rhs[j] -= factor * pivot_rhs[j];
            }
        }
    }
    for k in (0..N).rev() {
        let mut value = rhs[k];
        for j in k + 1..N {
            let factor = matrix[k][j];
            for r in 0..R {
                value[r] -= factor * rhs[j][r];
            }
        }
        let inverse_pivot = 1.0 / matrix[k][k];
        for v in &mut value {
            *v *= inverse_pivot;
        }
        rhs[k] = value;
    }
    true
}

/// Workspace of the transposed block solve `Cᵀ Z = E`.
struct Elimination {
    /// Right-hand sides, one row per template index, one column per target;
    /// lower blocks accumulate the contributions of solved higher blocks.
    rhs: [[f64; TEMPLATE_TARGETS]; TEMPLATE_COUNT],
    /// `Zᵀ D`, accumulated as blocks are solved: row `r` is minus the
    /// action-matrix row of box monomial `y1² y2^b y3^c`, `r = 3b + c`.
    box_part: [[f64; BOX_COUNT]; TEMPLATE_TARGETS],
}

impl Elimination {
    /// Solves the diagonal block `block` (degree `block + 3`, size `N`) of
    /// `Cᵀ Z = E` and pushes its rows' other terms into the lower blocks and
    /// the box part.
    fn solve_block<const N: usize>(
        &mut self,
        system: &[Cubic; 3],
        block: usize,
    ) -> Result<(), CubicSystemError> {
        debug_assert_eq!(BLOCK_SIZES[block], N);
        let start = BLOCK_STARTS[block];
        // transposed[β][ρ] = C[ρ, β] for β, ρ in this block.
        let mut transposed = [[0.0; N]; N];
        for (rho, t) in (start..start + N).enumerate() {
            let f = &system[ROW_EQUATION[t] as usize];
            for (coefficient, &column) in f.iter().zip(&ROW_COLUMNS[t]) {
                if let Slot::Template(beta) = SLOTS[column as usize] {
                    if beta >= start {
                        transposed[beta - start][rho] += coefficient;
                    }
                }
            }
        }
        let mut solution = [[0.0; TEMPLATE_TARGETS]; N];
        solution.copy_from_slice(&self.rhs[start..start + N]);
        if !lu_solve(&mut transposed, &mut solution) {
            return Err(CubicSystemError::SingularTemplate { degree: block + 3 });
        }
        for (z, t) in solution.iter().zip(start..start + N) {
            let f = &system[ROW_EQUATION[t] as usize];
            for (&coefficient, &column) in f.iter().zip(&ROW_COLUMNS[t]) {
                if coefficient == 0.0 {
                    continue;
                }
                match SLOTS[column as usize] {
                    Slot::Template(beta) if beta < start => {
                        for (target, zr) in self.rhs[beta].iter_mut().zip(z) {
                            *target -= coefficient * zr;
                        }
                    }
                    Slot::Box(gamma) => {
                        for (row, zr) in self.box_part.iter_mut().zip(z) {
                            row[gamma] += coefficient * zr;
                        }
                    }
                    Slot::Template(_) => {}
                }
            }
        }
        Ok(())
    }
}

/// The 27 × 27 action matrix of multiplication by `y1` on the box basis,
/// for a system already in the solver's variables and scaled.
fn action_matrix_in_solver_variables(
    system: &[Cubic; 3],
) -> Result<SMatrix<f64, BOX_COUNT, BOX_COUNT>, CubicSystemError> {
    let mut elimination = Elimination {
        rhs: [[0.0; TEMPLATE_TARGETS]; TEMPLATE_COUNT],
        box_part: [[0.0; BOX_COUNT]; TEMPLATE_TARGETS],
    };
    for (r, &t) in TARGET_TEMPLATE.iter().enumerate() {
        elimination.rhs[t][r] = 1.0;
    }
    // Highest degree first: Cᵀ is block upper triangular in ascending degree.
    elimination.solve_block::<36>(system, 4)?;
    elimination.solve_block::<27>(system, 3)?;
    elimination.solve_block::<18>(system, 2)?;
    elimination.solve_block::<9>(system, 1)?;
    elimination.solve_block::<3>(system, 0)?;

    let mut action = SMatrix::<f64, BOX_COUNT, BOX_COUNT>::zeros();
    for a in 0..2 {
        for b in 0..3 {
            for c in 0..3 {
                action[(box_index(a, b, c), box_index(a + 1, b, c))] = 1.0;
            }
        }
    }
    for (r, row) in elimination.box_part.iter().enumerate() {
        for (gamma, value) in row.iter().enumerate() {
            action[(box_index(2, r / 3, r % 3), gamma)] = -value;
        }
    }
    Ok(action)
}

/// The action matrix of multiplication by `y1 = (Qᵀ x)₁` on the box basis
/// in the solver's variables `y = Qᵀ x` (`Q` = [`generic_rotation`]): its
/// eigenvalues are the `y1` of the 27 roots, each with eigenvector the box
/// monomials evaluated at that root.
pub fn action_matrix(
    system: &[Cubic; 3],
) -> Result<SMatrix<f64, BOX_COUNT, BOX_COUNT>, CubicSystemError> {
    if !system.iter().flatten().all(|c| c.is_finite()) {
        return Err(CubicSystemError::NonFinite);
    }
    let in_y = normalised(&change_variables(system, &generic_rotation()));
    action_matrix_in_solver_variables(&in_y)
}

/// A null vector of a 9 × 9 matrix by Gaussian elimination with complete
/// pivoting: the free variable is the column left after eight pivots.
fn null_vector(mut m: [[f64; 9]; 9]) -> [f64; 9] {
    let mut columns: [usize; 9] = std::array::from_fn(|i| i);
    for k in 0..8 {
        let mut best = (k, k, 0.0);
        for (i, row) in m.iter().enumerate().skip(k) {
            for (jj, &column) in columns.iter().enumerate().skip(k) {
                let value = row[column].abs();
                if value > best.2 {
                    best = (i, jj, value);
                }
            }
        }
        m.swap(k, best.0);
        columns.swap(k, best.1);
        let pivot_column = columns[k];
        let pivot = m[k][pivot_column];
        if pivot == 0.0 {
            continue;
        }
        let (upper, lower) = m.split_at_mut(k + 1);
        for row in lower.iter_mut() {
            let factor = row[pivot_column] / pivot;
            for &column in &columns[k..] {
                row[column] -= factor * upper[k][column];
            }
        }
    }
    let mut x = [0.0; 9];
    x[columns[8]] = 1.0;
    for k in (0..8).rev() {
        let pivot = m[k][columns[k]];
        if pivot == 0.0 {
            continue;
        }
        let sum: f64 = columns[k + 1..].iter().map(|&c| m[k][c] * x[c]).sum();
        x[columns[k]] = -sum / pivot;
    }
    x
}

/// `(y2, y3)` from `w = (y2^b y3^c)` indexed `3b + c`: least-squares ratios
/// of consecutive powers.
fn ratios(w: &[f64; 9]) -> (f64, f64) {
    let (mut y2_num, mut y2_den, mut y3_num, mut y3_den) = (0.0, 0.0, 0.0, 0.0);
    for b in 0..3 {
        for c in 0..3 {
            let here = w[3 * b + c];
            if b < 2 {
                y2_num += w[3 * (b + 1) + c] * here;
                y2_den += here * here;
            }
            if c < 2 {
                y3_num += w[3 * b + c + 1] * here;
                y3_den += here * here;
            }
        }
    }
    (y2_num / y2_den, y3_num / y3_den)
}

/// Values of the system at `x`.
pub fn evaluate(system: &[Cubic; 3], x: &Vector3<f64>) -> Vector3<f64> {
    let values = monomials::cubic_monomials(&[x.x, x.y, x.z]);
    Vector3::from_fn(|k, _| system[k].iter().zip(&values).map(|(c, v)| c * v).sum())
}

/// Jacobian `∂f_k/∂x_j` of the system at `x`.
pub fn jacobian(system: &[Cubic; 3], x: &Vector3<f64>) -> Matrix3<f64> {
    let values = monomials::cubic_monomials(&[x.x, x.y, x.z]);
    let mut out = Matrix3::zeros();
    for (term, m) in MONOMIALS.iter().enumerate().take(CUBIC_TERMS) {
        for j in 0..3 {
            if m[j] == 0 {
                continue;
            }
            let mut lower = [m[0] as usize, m[1] as usize, m[2] as usize];
            lower[j] -= 1;
            let derivative = m[j] as f64 * values[index(lower[0], lower[1], lower[2])];
            for k in 0..3 {
                out[(k, j)] += system[k][term] * derivative;
            }
        }
    }
    out
}

/// `max_k |f_k(x)| / Σ_j |c_kj x^j|`: the residual relative to the size of
/// the terms that cancel in it (a backward error).
pub fn relative_residual(system: &[Cubic; 3], x: &Vector3<f64>) -> f64 {
    let values = monomials::cubic_monomials(&[x.x, x.y, x.z]);
    system
        .iter()
        .map(|f| {
            let (sum, size) = f
                .iter()
                .zip(&values)
                .fold((0.0, 0.0), |(s, a), (c, v)| (s + c * v, a + (c * v).abs()));
            if size > 0.0 {
                sum.abs() / size
            } else {
                0.0
            }
        })
        .fold(0.0, f64::max)
}

/// Newton's method on the system from `x`, for at most
/// [`NEWTON_MAX_ITERATIONS`] steps, stopping when a step no longer lowers
/// the residual norm.
pub fn polish(system: &[Cubic; 3], x: &Vector3<f64>) -> Vector3<f64> {
    let mut x = *x;
    let mut residual = evaluate(system, &x).norm();
    for _ in 0..NEWTON_MAX_ITERATIONS {
        if residual == 0.0 {
            break;
        }
        let Some(step) = jacobian(system, &x)
            .lu()
            .solve(&evaluate(system, &x))
            .filter(|s| s.iter().all(|v| v.is_finite()))
        else {
            break;
        };
        let next = x - step;
        let next_residual = evaluate(system, &next).norm();
        if next_residual.is_nan() || next_residual >= residual {
            break;
        }
        x = next;
        residual = next_residual;
        if step.norm() <= 4.0 * f64::EPSILON * (1.0 + x.norm()) {
            break;
        }
    }
    x
}

/// Every real root of the system, and the number of real eigenvalues they
/// came from.
#[derive(Debug, Clone)]
pub struct RealRoots {
    /// The distinct real roots that pass the residual test.
    pub roots: Roots,
    /// Eigenvalues of the action matrix counted as real.
    pub real_eigenvalues: usize,
    /// Estimates (before polishing) of the real eigenvalues whose root was
    /// rejected by the residual test: usually a numerically split complex
    /// pair, but possibly a real root too ill-conditioned to polish (a root
    /// near infinity). Callers that change variables to improve conditioning
    /// (DLS's charts) use them to decide where to look again.
    pub rejected: Roots,
}

/// Every real root of `f₁ = f₂ = f₃ = 0` (see the module documentation).
pub fn real_roots(system: &[Cubic; 3]) -> Result<RealRoots, CubicSystemError> {
    if !system.iter().flatten().all(|c| c.is_finite()) {
        return Err(CubicSystemError::NonFinite);
    }
    let scaled = normalised(system);
    let q = generic_rotation();
    let in_y = normalised(&change_variables(&scaled, &q));
    let action = action_matrix_in_solver_variables(&in_y)?;
    let eigenvalues = crate::linalg::nonsymmetric::eigenvalues(&action)?;

    let mut out = RealRoots {
        roots: Roots::new(),
        real_eigenvalues: 0,
        rejected: Roots::new(),
    };
    for eigenvalue in &eigenvalues {
        let lambda = eigenvalue.re;
        if eigenvalue.im.abs() > REAL_EIGENVALUE_TOLERANCE * (1.0 + lambda.abs()) {
            continue;
        }
        out.real_eigenvalues += 1;
        // λ³ w = (A₀ + λ A₁ + λ² A₂) w for w = (y2^b y3^c), A_a the 9 × 9
        // blocks of the rows y1²·(…) at columns y1^a·(…).
        let mut pencil = [[0.0; 9]; 9];
        for (r, row) in pencil.iter_mut().enumerate() {
            for (c, entry) in row.iter_mut().enumerate() {
                let blocks = [
                    action[(18 + r, c)],
                    action[(18 + r, 9 + c)],
                    action[(18 + r, 18 + c)],
                ];
                *entry = -(blocks[0] + lambda * (blocks[1] + lambda * blocks[2]));
                if r == c {
                    *entry += lambda * lambda * lambda;
                }
            }
        }
        let w = null_vector(pencil);
        let (y2, y3) = ratios(&w);
        let estimate = q * Vector3::new(lambda, y2, y3);
        let x = polish(&scaled, &estimate);
        if !x.iter().all(|v| v.is_finite())
            || relative_residual(&scaled, &x) > ROOT_RESIDUAL_TOLERANCE
        {
            if estimate.iter().all(|v| v.is_finite()) {
                out.rejected.push(estimate);
            }
            continue;
        }
        let tolerance = DUPLICATE_ROOT_TOLERANCE * (1.0 + x.norm());
        if out.roots.iter().all(|r| (r - x).norm() > tolerance) {
            out.roots.push(x);
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests;
