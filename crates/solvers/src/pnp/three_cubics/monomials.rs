//! Monomials in three unknowns `x = (x1, x2, x3)` up to degree 7, and the
//! compile-time tables of the Macaulay elimination template built on them.
//!
//! **Order.** Monomials `x1^a x2^b x3^c` are numbered in graded order: by
//! degree `d = a + b + c`, then by falling `a`, then by falling `b`. The index
//! has the closed form `d(d+1)(d+2)/6 + e(e+1)/2 + c` with `e = b + c`, so the
//! 20 monomials of degree ≤ 3 (the terms of a cubic) come first and the 120
//! of degree ≤ 7 fill [`MONOMIALS`].
//!
//! **Template.** Macaulay's construction for three cubics (and the linear
//! form Macaulay adds for the u-resultant) uses degree 7, the sum of the
//! degrees minus the count plus one, `3·(3−1) + (1−1) + 1 = 7`:
//! - the 27 *box* monomials, `a, b, c ≤ 2`, are not divisible by any `x_k³`;
//!   they are the quotient-ring basis ([`BOX`]);
//! - each of the other 93 monomials `x^α` of degree ≤ 7 is divisible by some
//!   `x_k³`; with `k` the first such index it owns the template row
//!   `x^(α − 3e_k) · f_k`, whose highest-degree "diagonal" term is `x^α`
//!   itself. Rows and columns are grouped by degree 3…7 (3, 9, 18, 27 and 36
//!   of them), and a row of degree `d` only touches columns of degree
//!   `d − 3 … d`, so the 93 × 93 template block is block triangular.

/// Highest degree in the template.
pub const MAX_DEGREE: usize = 7;
/// Number of monomials of degree ≤ 7 in three unknowns, C(10, 3).
pub const MONOMIAL_COUNT: usize = 120;
/// Number of monomials of degree ≤ 3: the terms of a cubic.
pub const CUBIC_TERMS: usize = 20;
/// Number of box monomials `x1^a x2^b x3^c`, `a, b, c ≤ 2`: the Bézout number 3³.
pub const BOX_COUNT: usize = 27;
/// Number of template rows and non-box columns, `120 − 27`.
pub const TEMPLATE_COUNT: usize = MONOMIAL_COUNT - BOX_COUNT;
/// Template rows (and non-box columns) per degree 3…7.
pub const BLOCK_SIZES: [usize; 5] = [3, 9, 18, 27, 36];
/// First template index of each degree block 3…7.
pub const BLOCK_STARTS: [usize; 5] = [0, 3, 12, 30, 57];

/// Index of `x1^a x2^b x3^c` in the graded order.
pub const fn index(a: usize, b: usize, c: usize) -> usize {
    let d = a + b + c;
    let e = b + c;
    d * (d + 1) * (d + 2) / 6 + e * (e + 1) / 2 + c
}

/// Index of a box monomial `x1^a x2^b x3^c` (`a, b, c ≤ 2`) among the 27:
/// `9a + 3b + c`, so `a` selects a 9 × 9 block of the action matrix.
pub const fn box_index(a: usize, b: usize, c: usize) -> usize {
    9 * a + 3 * b + c
}

/// Exponents of every monomial of degree ≤ 7, by [`index`].
pub const MONOMIALS: [[u8; 3]; MONOMIAL_COUNT] = {
    let mut table = [[0u8; 3]; MONOMIAL_COUNT];
    let mut d = 0;
    while d <= MAX_DEGREE {
        let mut a = d as isize;
        while a >= 0 {
            let mut b = d as isize - a;
            while b >= 0 {
                let c = d as isize - a - b;
                table[index(a as usize, b as usize, c as usize)] = [a as u8, b as u8, c as u8];
                b -= 1;
            }
            a -= 1;
        }
        d += 1;
    }
    table
};

/// Exponents of the box monomials, by [`box_index`].
pub const BOX: [[u8; 3]; BOX_COUNT] = {
    let mut table = [[0u8; 3]; BOX_COUNT];
    let mut i = 0;
    while i < BOX_COUNT {
        table[i] = [(i / 9) as u8, ((i / 3) % 3) as u8, (i % 3) as u8];
        i += 1;
    }
    table
};

/// Where a monomial sits in the template: a box column or a template column.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Slot {
    /// Box monomial, by [`box_index`].
    Box(usize),
    /// Non-box monomial, by template index (its row and its column).
    Template(usize),
}

const fn is_box(m: [u8; 3]) -> bool {
    m[0] <= 2 && m[1] <= 2 && m[2] <= 2
}

/// Template index → monomial index, degree blocks in order.
pub const TEMPLATE_MONOMIALS: [u8; TEMPLATE_COUNT] = {
    let mut table = [0u8; TEMPLATE_COUNT];
    let mut next = 0;
    let mut i = 0;
    while i < MONOMIAL_COUNT {
        // Graded order already groups by degree, and no monomial of degree < 3 is outside the box.
        if !is_box(MONOMIALS[i]) {
            table[next] = i as u8;
            next += 1;
        }
        i += 1;
    }
    table
};

/// Monomial index → its [`Slot`].
pub const SLOTS: [Slot; MONOMIAL_COUNT] = {
    let mut table = [Slot::Box(0); MONOMIAL_COUNT];
    let mut i = 0;
    while i < MONOMIAL_COUNT {
        let m = MONOMIALS[i];
        if is_box(m) {
            table[i] = Slot::Box(box_index(m[0] as usize, m[1] as usize, m[2] as usize));
        }
        i += 1;
    }
    let mut t = 0;
    while t < TEMPLATE_COUNT {
        table[TEMPLATE_MONOMIALS[t] as usize] = Slot::Template(t);
        t += 1;
    }
    table
};

/// For template row `t`: which cubic `k` it multiplies (the first `k` with
/// `α_k ≥ 3` for its monomial `x^α`).
pub const ROW_EQUATION: [u8; TEMPLATE_COUNT] = {
    let mut table = [0u8; TEMPLATE_COUNT];
    let mut t = 0;
    while t < TEMPLATE_COUNT {
        let m = MONOMIALS[TEMPLATE_MONOMIALS[t] as usize];
        table[t] = if m[0] >= 3 {
            0
        } else if m[1] >= 3 {
            1
        } else {
            2
        };
        t += 1;
    }
    table
};

/// For template row `t` and cubic term `j`: the monomial index of
/// `x^(α − 3e_k) · x^(term j)`, the column that coefficient `j` of `f_k` lands in.
pub const ROW_COLUMNS: [[u8; CUBIC_TERMS]; TEMPLATE_COUNT] = {
    let mut table = [[0u8; CUBIC_TERMS]; TEMPLATE_COUNT];
    let mut t = 0;
    while t < TEMPLATE_COUNT {
        let mut multiplier = MONOMIALS[TEMPLATE_MONOMIALS[t] as usize];
        multiplier[ROW_EQUATION[t] as usize] -= 3;
        let mut j = 0;
        while j < CUBIC_TERMS {
            let term = MONOMIALS[j];
            table[t][j] = index(
                (multiplier[0] + term[0]) as usize,
                (multiplier[1] + term[1]) as usize,
                (multiplier[2] + term[2]) as usize,
            ) as u8;
            j += 1;
        }
        t += 1;
    }
    table
};

/// Degree block (0 for degree 3 … 4 for degree 7) of template index `t`.
pub const fn block_of(t: usize) -> usize {
    let mut block = 4;
    while BLOCK_STARTS[block] > t {
        block -= 1;
    }
    block
}

/// Evaluates the 20 monomials of degree ≤ 3 at `x`.
#[inline]
pub fn cubic_monomials(x: &[f64; 3]) -> [f64; CUBIC_TERMS] {
    let mut values = [0.0; CUBIC_TERMS];
    for (value, m) in values.iter_mut().zip(&MONOMIALS) {
        *value = x[0].powi(m[0] as i32) * x[1].powi(m[1] as i32) * x[2].powi(m[2] as i32);
    }
    values
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn index_matches_the_table_and_is_graded() {
        for (i, m) in MONOMIALS.iter().enumerate() {
            assert_eq!(index(m[0] as usize, m[1] as usize, m[2] as usize), i);
            if i > 0 {
                let previous = MONOMIALS[i - 1];
                let degree = |m: [u8; 3]| m[0] + m[1] + m[2];
                assert!(degree(previous) <= degree(*m));
            }
        }
        assert_eq!(index(0, 0, 3), CUBIC_TERMS - 1);
        assert_eq!(index(0, 0, 7), MONOMIAL_COUNT - 1);
    }

    #[test]
    fn template_blocks_partition_the_non_box_monomials_by_degree() {
        for block in 0..5 {
            for t in BLOCK_STARTS[block]..BLOCK_STARTS[block] + BLOCK_SIZES[block] {
                let m = MONOMIALS[TEMPLATE_MONOMIALS[t] as usize];
                assert_eq!((m[0] + m[1] + m[2]) as usize, block + 3);
                assert_eq!(block_of(t), block);
                assert_eq!(SLOTS[TEMPLATE_MONOMIALS[t] as usize], Slot::Template(t));
            }
        }
        assert_eq!(BLOCK_SIZES.iter().sum::<usize>(), TEMPLATE_COUNT);
        let boxes = SLOTS.iter().filter(|s| matches!(s, Slot::Box(_))).count();
        assert_eq!(boxes, BOX_COUNT);
    }

    #[test]
    fn every_row_has_its_own_monomial_as_a_term_and_stays_within_three_degrees() {
        for t in 0..TEMPLATE_COUNT {
            let own = TEMPLATE_MONOMIALS[t];
            let k = ROW_EQUATION[t] as usize;
            // The x_k³ term of f_k lands on the row's own monomial.
            let cube = index(
                3 * (k == 0) as usize,
                3 * (k == 1) as usize,
                3 * (k == 2) as usize,
            );
            assert_eq!(ROW_COLUMNS[t][cube], own);
            let row_degree = block_of(t) + 3;
            for &column in &ROW_COLUMNS[t] {
                let m = MONOMIALS[column as usize];
                let degree = (m[0] + m[1] + m[2]) as usize;
                assert!(degree <= row_degree && degree + 3 >= row_degree);
            }
        }
    }
}
