//! Real roots of small real polynomials, for the solvers that reduce pose to
//! a univariate polynomial (RPnP's degree-7 cost derivative).
//!
//! Method: recursive isolation by derivatives. The real roots of `p′` cut the
//! real line into intervals on which `p` is monotone, so each interval holds
//! at most one root of `p`, found by a safeguarded Newton–bisection iteration
//! that never leaves its bracket. Starting from the linear derivative
//! `p^(d−1)` and working up to `p` gives every real root, with no complex
//! arithmetic and no eigenvalue problem. The outer intervals are closed by
//! Cauchy's bound `1 + max |a_k / a_d|`, which contains every root.
//!
//! A root of even multiplicity (where `p` touches zero without crossing) is
//! reported only if `p` vanishes exactly at the critical point; a tangency
//! blurred by rounding is not a crossing and is not reported.
//!
//! Everything lives on the stack: coefficients in `[f64; MAX_DEGREE + 1]`,
//! roots in a [`Roots`] small vector.

use smallvec::SmallVec;

/// Highest degree handled.
pub const MAX_DEGREE: usize = 8;
/// Leading coefficients smaller than this fraction of the largest
/// coefficient are dropped (their roots lie beyond ~1e14 times the others).
pub const NEGLIGIBLE_LEADING: f64 = 1e-14;
/// Bisection stops when the bracket is narrower than this fraction of its
/// larger end point (a few ulps).
pub const BRACKET_TOLERANCE: f64 = 4.0 * f64::EPSILON;
/// Upper bound on Newton–bisection steps per root (bisection alone halves a
/// bracket of any finite width to the tolerance well within this).
pub const MAX_ROOT_ITERATIONS: usize = 200;

/// Real roots, ascending.
pub type Roots = SmallVec<[f64; MAX_DEGREE]>;

/// A polynomial `Σ c_k x^k` of degree at most [`MAX_DEGREE`], coefficients in
/// ascending powers.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Polynomial {
    coefficients: [f64; MAX_DEGREE + 1],
    degree: usize,
}

impl Polynomial {
    /// Builds `Σ coefficients[k] x^k`, ascending powers. Returns `None` for
    /// more than `MAX_DEGREE + 1` coefficients or a non-finite coefficient.
    /// Negligible leading coefficients (see [`NEGLIGIBLE_LEADING`]) are
    /// dropped.
    pub fn new(coefficients: &[f64]) -> Option<Self> {
        if coefficients.len() > MAX_DEGREE + 1 || !coefficients.iter().all(|c| c.is_finite()) {
            return None;
        }
        let mut stored = [0.0; MAX_DEGREE + 1];
        stored[..coefficients.len()].copy_from_slice(coefficients);
        let largest = coefficients.iter().fold(0.0f64, |m, c| m.max(c.abs()));
        let mut degree = coefficients.len().saturating_sub(1);
        while degree > 0 && stored[degree].abs() <= NEGLIGIBLE_LEADING * largest {
            stored[degree] = 0.0;
            degree -= 1;
        }
        Some(Self {
            coefficients: stored,
            degree,
        })
    }

    /// The degree after dropping negligible leading coefficients.
    pub fn degree(&self) -> usize {
        self.degree
    }

    /// Coefficients in ascending powers, up to the degree.
    pub fn coefficients(&self) -> &[f64] {
        &self.coefficients[..=self.degree]
    }

    /// Value at `x` (Horner).
    #[inline]
    pub fn eval(&self, x: f64) -> f64 {
        self.coefficients[..=self.degree]
            .iter()
            .rev()
            .fold(0.0, |acc, &c| acc * x + c)
    }

    /// Value and first derivative at `x` (Horner).
    #[inline]
    pub fn eval_with_derivative(&self, x: f64) -> (f64, f64) {
        let mut value = 0.0;
        let mut slope = 0.0;
        for &c in self.coefficients[..=self.degree].iter().rev() {
            slope = slope * x + value;
            value = value * x + c;
        }
        (value, slope)
    }

    /// The derivative.
    pub fn derivative(&self) -> Polynomial {
        let mut coefficients = [0.0; MAX_DEGREE + 1];
        for k in 1..=self.degree {
            coefficients[k - 1] = self.coefficients[k] * k as f64;
        }
        Polynomial {
            coefficients,
            degree: self.degree.saturating_sub(1),
        }
    }

    /// Cauchy's bound: every root `x` has `|x| < 1 + max_k |c_k / c_d|`.
    fn root_bound(&self) -> f64 {
        let leading = self.coefficients[self.degree].abs();
        1.0 + self.coefficients[..self.degree]
            .iter()
            .fold(0.0f64, |m, c| m.max(c.abs() / leading))
    }

    /// Every real root, ascending. A polynomial that is identically zero, or
    /// a non-zero constant, has none.
    pub fn real_roots(&self) -> Roots {
        if self.degree == 0 {
            return Roots::new();
        }
        // The chain p, p′, p″, … down to the linear derivative.
        let mut chain = [*self; MAX_DEGREE];
        for level in 1..self.degree {
            chain[level] = chain[level - 1].derivative();
        }
        let bound = self.root_bound();
        // Roots of the linear member, then each member's roots from the
        // critical points given by the roots of the one below it.
        let mut roots = Roots::new();
        for level in (0..self.degree).rev() {
            let p = &chain[level];
            let critical = std::mem::take(&mut roots);
            let mut ends = Roots::new();
            ends.push(-bound);
            ends.extend(critical.into_iter().filter(|x| x.abs() < bound));
            ends.push(bound);
            for pair in ends.windows(2) {
                if let Some(root) = root_in_monotone_bracket(p, pair[0], pair[1]) {
                    if roots.last().is_none_or(|&last| root > last) {
                        roots.push(root);
                    }
                }
            }
        }
        roots
    }
}

/// The root of `p` in `[a, b]`, where `p` is monotone, if `p` changes sign
/// (or vanishes) there. Safeguarded Newton: a Newton step is taken when it
/// stays inside the current bracket, otherwise the bracket is bisected.
fn root_in_monotone_bracket(p: &Polynomial, a: f64, b: f64) -> Option<f64> {
    let (mut low, mut high) = (a, b);
    let (f_low, f_high) = (p.eval(low), p.eval(high));
    if f_low == 0.0 {
        return Some(low);
    }
    if f_high == 0.0 {
        return Some(high);
    }
    if (f_low > 0.0) == (f_high > 0.0) {
        return None;
    }
    let increasing = f_high > 0.0;
    let mut x = 0.5 * (low + high);
    for _ in 0..MAX_ROOT_ITERATIONS {
        let (value, slope) = p.eval_with_derivative(x);
        if value == 0.0 {
            return Some(x);
        }
        // Shrink the bracket to the side that keeps the sign change.
        if (value > 0.0) == increasing {
            high = x;
        } else {
            low = x;
        }
        if high - low <= BRACKET_TOLERANCE * low.abs().max(high.abs()).max(f64::MIN_POSITIVE) {
            break;
        }
        let newton = x - value / slope;
        x = if slope != 0.0 && newton > low && newton < high {
            if (newton - x).abs() <= BRACKET_TOLERANCE * x.abs() {
                return Some(newton);
            }
            newton
        } else {
            0.5 * (low + high)
        };
    }
    Some(x.clamp(low, high))
}

/// Product of the polynomials `a` and `b` (ascending coefficients), written
/// into `out`, which must hold `a.len() + b.len() − 1` entries.
pub fn multiply_into(a: &[f64], b: &[f64], out: &mut [f64]) {
    out.iter_mut().for_each(|v| *v = 0.0);
    for (i, &x) in a.iter().enumerate() {
        for (j, &y) in b.iter().enumerate() {
            out[i + j] += x * y;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;
    use rand::Rng;

    /// Coefficients of `scale · Π (x − r)`, ascending.
    fn from_roots(roots: &[f64], scale: f64) -> Vec<f64> {
        let mut coefficients = vec![scale];
        for &r in roots {
            let mut next = vec![0.0; coefficients.len() + 1];
            multiply_into(&coefficients, &[-r, 1.0], &mut next);
            coefficients = next;
        }
        coefficients
    }

    #[test]
    fn finds_every_real_root_of_a_degree_7_product() {
        let truth = [-3.5, -1.0, -0.25, 0.1, 0.7, 2.0, 40.0];
        let p = Polynomial::new(&from_roots(&truth, -2.5)).unwrap();
        let roots = p.real_roots();
        assert_eq!(roots.len(), 7, "{roots:?}");
        for (found, expected) in roots.iter().zip(truth) {
            assert_relative_eq!(*found, expected, max_relative = 1e-12, epsilon = 1e-13);
        }
    }

    #[test]
    fn complex_pairs_are_not_roots() {
        // (x² + 1)(x² + 0.01)(x − 3)(x + 0.5)(x − 1e-3): three real roots.
        let mut a = vec![0.0; 5];
        multiply_into(&[1.0, 0.0, 1.0], &[0.01, 0.0, 1.0], &mut a);
        let mut coefficients = vec![0.0; 8];
        multiply_into(&a, &from_roots(&[3.0, -0.5, 1e-3], 1.0), &mut coefficients);
        let roots = Polynomial::new(&coefficients).unwrap().real_roots();
        assert_eq!(roots.len(), 3, "{roots:?}");
        assert_relative_eq!(roots[0], -0.5, epsilon = 1e-14);
        assert_relative_eq!(roots[1], 1e-3, max_relative = 1e-12);
        assert_relative_eq!(roots[2], 3.0, epsilon = 1e-14);
        assert!(Polynomial::new(&[1.0, 0.0, 1.0])
            .unwrap()
            .real_roots()
            .is_empty());
    }

    #[test]
    fn close_and_widely_scaled_roots() {
        let truth = [1.0, 1.0 + 1e-6, 1e-5, -1e4];
        let p = Polynomial::new(&from_roots(&truth, 1e-3)).unwrap();
        let roots = p.real_roots();
        assert_eq!(roots.len(), 4, "{roots:?}");
        assert_relative_eq!(roots[0], -1e4, max_relative = 1e-12);
        assert_relative_eq!(roots[1], 1e-5, max_relative = 1e-9);
        assert_relative_eq!(roots[2], 1.0, epsilon = 1e-9);
        assert_relative_eq!(roots[3], 1.0 + 1e-6, epsilon = 1e-9);
    }

    #[test]
    fn exact_double_root_and_low_degrees() {
        // (x − 2)² (x + 1): the double root is a critical point where p = 0.
        let roots = Polynomial::new(&from_roots(&[2.0, 2.0, -1.0], 1.0))
            .unwrap()
            .real_roots();
        assert_eq!(roots.as_slice(), &[-1.0, 2.0]);
        assert_eq!(
            Polynomial::new(&[3.0, -1.5])
                .unwrap()
                .real_roots()
                .as_slice(),
            &[2.0]
        );
        assert!(Polynomial::new(&[3.0]).unwrap().real_roots().is_empty());
        assert!(Polynomial::new(&[0.0, 0.0])
            .unwrap()
            .real_roots()
            .is_empty());
        // A negligible leading coefficient drops the degree.
        let p = Polynomial::new(&[-2.0, 1.0, 1e-300]).unwrap();
        assert_eq!(p.degree(), 1);
        assert_eq!(p.real_roots().as_slice(), &[2.0]);
        assert!(Polynomial::new(&[1.0; MAX_DEGREE + 2]).is_none());
        assert!(Polynomial::new(&[1.0, f64::NAN]).is_none());
    }

    #[test]
    fn derivative_and_evaluation_agree() {
        let p = Polynomial::new(&[1.0, -2.0, 0.5, 3.0]).unwrap();
        let (value, slope) = p.eval_with_derivative(1.5);
        assert_relative_eq!(value, p.eval(1.5));
        assert_relative_eq!(slope, p.derivative().eval(1.5));
        assert_relative_eq!(slope, -2.0 + 1.5 + 9.0 * 1.5 * 1.5 / 1.0);
    }

    /// Random degree-7 polynomials with k real roots and 7 − k complex ones:
    /// exactly the real ones come back, to a precision set by their spacing.
    #[test]
    fn random_products_recover_their_real_roots() {
        for case in 0..500 {
            let mut rng = crate::synthetic::stream_rng(99, 50, case);
            let pairs = rng.random_range(0..=3);
            let mut truth: Vec<f64> = (0..7 - 2 * pairs)
                .map(|_| rng.random_range(-5.0..5.0))
                .collect();
            let mut coefficients = from_roots(&truth, rng.random_range(0.1..10.0));
            for _ in 0..pairs {
                let (re, im) = (rng.random_range(-5.0..5.0), rng.random_range(0.1..3.0));
                let mut next = vec![0.0; coefficients.len() + 2];
                multiply_into(
                    &coefficients,
                    &[re * re + im * im, -2.0 * re, 1.0],
                    &mut next,
                );
                coefficients = next;
            }
            truth.sort_by(f64::total_cmp);
            let spacing = truth
                .windows(2)
                .map(|w| w[1] - w[0])
                .fold(f64::INFINITY, f64::min);
            if spacing < 1e-3 {
                continue;
            }
            let roots = Polynomial::new(&coefficients).unwrap().real_roots();
            assert_eq!(
                roots.len(),
                truth.len(),
                "case {case}: {roots:?} vs {truth:?}"
            );
            for (found, expected) in roots.iter().zip(&truth) {
                assert!(
                    (found - expected).abs() < 1e-8,
                    "case {case}: {found} vs {expected}"
                );
            }
        }
    }
}
