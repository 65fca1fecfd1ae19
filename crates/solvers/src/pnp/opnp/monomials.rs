//! Monomials in the four quaternion unknowns `(a, b, c, d)`.
//!
//! A monomial `a^i b^j c^k d^l` is stored as its exponent `[i, j, k, l]`.
//! Within one total degree, monomials are listed in graded reverse
//! lexicographic (grevlex) order, largest first, with `a > b > c > d`:
//! `x^α > x^β` when the last nonzero entry of `α − β` is negative. The
//! elimination template of [`super::action`] orders its columns this way, and
//! the equations' coefficient layout ([`CUBIC`], [`LINEAR`]) uses it too.

/// Exponent of a monomial in `(a, b, c, d)`.
pub type Exponent = [u8; 4];

/// Total degree of a monomial.
pub fn degree(exponent: &Exponent) -> usize {
    exponent.iter().map(|&e| usize::from(e)).sum()
}

/// Product of two monomials.
pub fn product(x: &Exponent, y: &Exponent) -> Exponent {
    [x[0] + y[0], x[1] + y[1], x[2] + y[2], x[3] + y[3]]
}

/// Grevlex comparison: `Greater` when `x` comes first (is the larger monomial).
pub fn grevlex(x: &Exponent, y: &Exponent) -> std::cmp::Ordering {
    use std::cmp::Ordering;
    match degree(x).cmp(&degree(y)) {
        Ordering::Equal => {}
        other => return other,
    }
    for k in (0..4).rev() {
        match x[k].cmp(&y[k]) {
            Ordering::Equal => continue,
            // A smaller power of the last differing variable is the larger monomial.
            Ordering::Less => return Ordering::Greater,
            Ordering::Greater => return Ordering::Less,
        }
    }
    Ordering::Equal
}

/// Every monomial of total degree `degree`, grevlex order, largest first.
/// There are `(degree + 3 choose 3)` of them.
pub fn of_degree(degree: usize) -> Vec<Exponent> {
    let mut monomials = Vec::new();
    for i in 0..=degree {
        for j in 0..=degree - i {
            for k in 0..=degree - i - j {
                let l = degree - i - j - k;
                monomials.push([i as u8, j as u8, k as u8, l as u8]);
            }
        }
    }
    monomials.sort_by(|x, y| grevlex(y, x));
    monomials
}

/// Position of `exponent` in `list`, if present.
pub fn position(list: &[Exponent], exponent: &Exponent) -> Option<usize> {
    list.iter().position(|m| m == exponent)
}

/// Value of a monomial at `q`.
pub fn evaluate(exponent: &Exponent, q: &[f64; 4]) -> f64 {
    (0..4).map(|k| q[k].powi(i32::from(exponent[k]))).product()
}

/// The ten quadratic monomials `a², ab, ac, ad, b², bc, bd, c², cd, d²`, in
/// the order the OPnP cost uses (lexicographic, not grevlex).
pub const QUADRATIC: [Exponent; 10] = [
    [2, 0, 0, 0],
    [1, 1, 0, 0],
    [1, 0, 1, 0],
    [1, 0, 0, 1],
    [0, 2, 0, 0],
    [0, 1, 1, 0],
    [0, 1, 0, 1],
    [0, 0, 2, 0],
    [0, 0, 1, 1],
    [0, 0, 0, 2],
];

/// The four linear monomials `a, b, c, d`.
pub const LINEAR: [Exponent; 4] = [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]];

/// Number of cubic monomials in four unknowns.
pub const CUBIC_COUNT: usize = 20;

/// The twenty cubic monomials, grevlex order, largest first. An odd cubic
/// equation is stored as 24 coefficients: these twenty, then [`LINEAR`].
pub static CUBIC: std::sync::LazyLock<Vec<Exponent>> = std::sync::LazyLock::new(|| of_degree(3));

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_and_order() {
        for (degree, count) in [
            (0, 1),
            (1, 4),
            (2, 10),
            (3, 20),
            (5, 56),
            (8, 165),
            (9, 220),
        ] {
            assert_eq!(of_degree(degree).len(), count);
        }
        let quadratic = of_degree(2);
        // Grevlex with a > b > c > d: a² > ab > b² > ac > bc > c² > ad > bd > cd > d².
        assert_eq!(
            quadratic,
            vec![
                [2, 0, 0, 0],
                [1, 1, 0, 0],
                [0, 2, 0, 0],
                [1, 0, 1, 0],
                [0, 1, 1, 0],
                [0, 0, 2, 0],
                [1, 0, 0, 1],
                [0, 1, 0, 1],
                [0, 0, 1, 1],
                [0, 0, 0, 2],
            ]
        );
        assert_eq!(CUBIC.len(), CUBIC_COUNT);
        assert_eq!(
            evaluate(&[1, 2, 0, 1], &[2.0, 3.0, 5.0, 7.0]),
            2.0 * 9.0 * 7.0
        );
    }
}
