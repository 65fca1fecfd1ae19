//! Tests of the three-cubics solver on systems with known roots.

use super::*;
use crate::synthetic::stream_rng;
use nalgebra::{DMatrix, Matrix3, Vector3};
use rand::Rng;

/// `c0 + c·x` as a cubic.
fn linear(c0: f64, c: &Vector3<f64>) -> Cubic {
    let mut p = [0.0; CUBIC_TERMS];
    p[index(0, 0, 0)] = c0;
    p[index(1, 0, 0)] = c.x;
    p[index(0, 1, 0)] = c.y;
    p[index(0, 0, 1)] = c.z;
    p
}

/// Product of two polynomials whose degrees add to at most 3.
fn multiply(p: &Cubic, q: &Cubic) -> Cubic {
    let mut out = [0.0; CUBIC_TERMS];
    for (i, &a) in p.iter().enumerate() {
        for (j, &b) in q.iter().enumerate() {
            if a == 0.0 || b == 0.0 {
                continue;
            }
            let (m, n) = (MONOMIALS[i], MONOMIALS[j]);
            let e = [m[0] + n[0], m[1] + n[1], m[2] + n[2]];
            assert!(e.iter().sum::<u8>() <= 3, "degree overflow");
            out[index(e[0] as usize, e[1] as usize, e[2] as usize)] += a * b;
        }
    }
    out
}

/// A dense system with known roots: `f = L h(A x + d)` where `h_k(u)` is a
/// product of factors in `u_k` alone, so the roots are `A⁻¹(u* − d)` for
/// every combination of the factors' roots `u*`.
struct Known {
    system: [Cubic; 3],
    roots: Vec<Vector3<f64>>,
}

/// `real[k]` are the real roots of `h_k`; if it has only one, `h_k` also gets
/// the factor `u_k² + 1` (two complex roots).
fn known_system(seed: u64, real: [&[f64]; 3]) -> Known {
    let mut rng = stream_rng(seed, 7, 0);
    let a = Matrix3::from_fn(|i, j| if i == j { 1.5 } else { 0.0 } + rng.random::<f64>() - 0.5);
    let d = Vector3::from_fn(|_, _| rng.random::<f64>() - 0.5);
    let mix = Matrix3::from_fn(|i, j| if i == j { 1.0 } else { 0.0 } + rng.random::<f64>() - 0.5);
    let mut h = [[0.0; CUBIC_TERMS]; 3];
    for k in 0..3 {
        let row = a.row(k).transpose();
        let u = linear(d[k], &row);
        let mut product = linear(1.0, &Vector3::zeros());
        for &root in real[k] {
            product = multiply(&product, &linear(d[k] - root, &row));
        }
        if real[k].len() == 1 {
            let mut square_plus_one = multiply(&u, &u);
            square_plus_one[0] += 1.0;
            product = multiply(&product, &square_plus_one);
        }
        h[k] = product;
    }
    let mut system = [[0.0; CUBIC_TERMS]; 3];
    for k in 0..3 {
        for j in 0..3 {
            for (s, c) in system[k].iter_mut().zip(&h[j]) {
                *s += mix[(k, j)] * c;
            }
        }
    }
    let inverse = a.try_inverse().unwrap();
    let mut roots = Vec::new();
    for &r0 in real[0] {
        for &r1 in real[1] {
            for &r2 in real[2] {
                roots.push(inverse * (Vector3::new(r0, r1, r2) - d));
            }
        }
    }
    Known { system, roots }
}

fn assert_same_roots(found: &[Vector3<f64>], expected: &[Vector3<f64>], tolerance: f64) {
    assert_eq!(found.len(), expected.len(), "found {found:?}");
    for e in expected {
        let nearest = found
            .iter()
            .map(|f| (f - e).norm())
            .fold(f64::INFINITY, f64::min);
        assert!(
            nearest < tolerance * (1.0 + e.norm()),
            "root {e} missed by {nearest}"
        );
    }
}

#[test]
fn finds_all_27_real_roots_of_a_system_with_known_roots() {
    let known = known_system(
        1,
        [&[-1.3, 0.2, 1.1], &[-0.7, 0.4, 1.9], &[-2.0, -0.1, 0.8]],
    );
    let result = real_roots(&known.system).unwrap();
    assert_eq!(result.real_eigenvalues, 27);
    assert_same_roots(&result.roots, &known.roots, 1e-10);
    for root in &result.roots {
        assert!(relative_residual(&known.system, root) < 1e-12);
    }
}

#[test]
fn action_matrix_eigenvalues_and_eigenvectors_reproduce_the_roots() {
    let known = known_system(2, [&[-1.0, 0.3, 1.4], &[-0.6, 0.5, 1.2], &[-1.5, 0.1, 0.9]]);
    let action = action_matrix(&known.system).unwrap();
    let q = generic_rotation();
    let mut eigenvalues: Vec<f64> = crate::linalg::nonsymmetric::eigenvalues(&action)
        .unwrap()
        .iter()
        .map(|e| {
            assert!(e.im.abs() < 1e-8);
            e.re
        })
        .collect();
    let mut expected: Vec<f64> = known.roots.iter().map(|x| (q.transpose() * x).x).collect();
    eigenvalues.sort_by(f64::total_cmp);
    expected.sort_by(f64::total_cmp);
    for (found, wanted) in eigenvalues.iter().zip(&expected) {
        assert!((found - wanted).abs() < 1e-9, "{found} vs {wanted}");
    }
    // A m_B(y) = y1 m_B(y): the box monomials at each root are an eigenvector.
    for x in &known.roots {
        let y = q.transpose() * x;
        let v = nalgebra::SVector::<f64, 27>::from_fn(|i, _| {
            let m = monomials::BOX[i];
            y.x.powi(m[0] as i32) * y.y.powi(m[1] as i32) * y.z.powi(m[2] as i32)
        });
        let residual = (action * v - v * y.x).norm() / v.norm();
        assert!(residual < 1e-9, "eigenvector residual {residual}");
    }
}

#[test]
fn keeps_only_the_real_roots() {
    // h1 and h3 have one real root and a complex pair each: 1·3·1 = 3 real
    // roots out of 27.
    let known = known_system(3, [&[0.4], &[-0.9, 0.1, 1.3], &[-0.5]]);
    let result = real_roots(&known.system).unwrap();
    assert_same_roots(&result.roots, &known.roots, 1e-10);
}

/// The dense Macaulay computation the paper describes (93 × 93 LU of the
/// whole template, allocating), as a reference for the block elimination.
fn dense_action_matrix(system_in_y: &[Cubic; 3]) -> DMatrix<f64> {
    let mut c = DMatrix::<f64>::zeros(TEMPLATE_COUNT, TEMPLATE_COUNT);
    let mut d = DMatrix::<f64>::zeros(TEMPLATE_COUNT, BOX_COUNT);
    for t in 0..TEMPLATE_COUNT {
        let f = &system_in_y[ROW_EQUATION[t] as usize];
        for (coefficient, &column) in f.iter().zip(&ROW_COLUMNS[t]) {
            match SLOTS[column as usize] {
                Slot::Template(beta) => c[(t, beta)] += coefficient,
                Slot::Box(gamma) => d[(t, gamma)] += coefficient,
            }
        }
    }
    let reduced = c.lu().solve(&d).unwrap();
    let mut action = DMatrix::<f64>::zeros(BOX_COUNT, BOX_COUNT);
    for i in 0..BOX_COUNT {
        let m = monomials::BOX[i];
        let (a, b, cc) = (m[0] as usize, m[1] as usize, m[2] as usize);
        if a < 2 {
            action[(i, box_index(a + 1, b, cc))] = 1.0;
        } else {
            let Slot::Template(t) = SLOTS[index(3, b, cc)] else {
                unreachable!()
            };
            for gamma in 0..BOX_COUNT {
                action[(i, gamma)] = -reduced[(t, gamma)];
            }
        }
    }
    action
}

#[test]
fn block_elimination_matches_the_dense_template() {
    for case in 0..20 {
        let mut rng = stream_rng(5, 1, case);
        let system: [Cubic; 3] =
            std::array::from_fn(|_| std::array::from_fn(|_| rng.random::<f64>() * 2.0 - 1.0));
        let in_y = normalised(&change_variables(&system, &generic_rotation()));
        let ours = action_matrix_in_solver_variables(&in_y).unwrap();
        let reference = dense_action_matrix(&in_y);
        // Both are rounding-error approximations of the same matrix; random
        // systems can make the template ill-conditioned (entries up to 1e7
        // were seen), so the agreement is judged relative to the largest entry.
        let scale = reference.amax();
        for i in 0..BOX_COUNT {
            for j in 0..BOX_COUNT {
                assert!(
                    (ours[(i, j)] - reference[(i, j)]).abs() <= 1e-7 * scale,
                    "case {case} entry ({i},{j}): {} vs {}",
                    ours[(i, j)],
                    reference[(i, j)]
                );
            }
        }
    }
}

#[test]
fn random_systems_have_an_odd_number_of_real_roots_all_with_small_residuals() {
    // Complex roots of a real system come in conjugate pairs, so a generic
    // system has an odd number of real roots among its 27.
    let mut counts = [0usize; 28];
    for case in 0..200 {
        let mut rng = stream_rng(6, 1, case);
        let system: [Cubic; 3] =
            std::array::from_fn(|_| std::array::from_fn(|_| rng.random::<f64>() * 2.0 - 1.0));
        let result = real_roots(&system).unwrap();
        assert_eq!(result.roots.len() % 2, 1, "case {case}: {:?}", result.roots);
        counts[result.roots.len()] += 1;
        for x in &result.roots {
            assert!(relative_residual(&system, x) < 1e-11);
        }
    }
    // More than one real root is common for dense random cubics.
    assert!(counts[3..].iter().sum::<usize>() > 0);
}

#[test]
fn change_of_variables_is_composition() {
    let mut rng = stream_rng(8, 1, 0);
    let system: [Cubic; 3] =
        std::array::from_fn(|_| std::array::from_fn(|_| rng.random::<f64>() * 2.0 - 1.0));
    let q = generic_rotation();
    let in_y = change_variables(&system, &q);
    for _ in 0..10 {
        let y = Vector3::from_fn(|_, _| rng.random::<f64>() * 4.0 - 2.0);
        let direct = evaluate(&system, &(q * y));
        let composed = evaluate(&in_y, &y);
        assert!((direct - composed).norm() < 1e-12 * (1.0 + direct.norm()));
    }
}

#[test]
fn jacobian_matches_central_differences() {
    let mut rng = stream_rng(9, 1, 0);
    let system: [Cubic; 3] =
        std::array::from_fn(|_| std::array::from_fn(|_| rng.random::<f64>() * 2.0 - 1.0));
    let x = Vector3::new(0.3, -0.8, 1.1);
    let analytic = jacobian(&system, &x);
    let h = 1e-6;
    for j in 0..3 {
        let mut step = Vector3::zeros();
        step[j] = h;
        let numeric = (evaluate(&system, &(x + step)) - evaluate(&system, &(x - step))) / (2.0 * h);
        for k in 0..3 {
            assert!((numeric[k] - analytic[(k, j)]).abs() < 1e-8);
        }
    }
}

#[test]
fn errors_are_typed_and_say_what_failed() {
    let mut system: [Cubic; 3] = [[0.0; CUBIC_TERMS]; 3];
    system[0][index(3, 0, 0)] = 1.0;
    system[1][index(0, 3, 0)] = 1.0;
    // f3 = 0: every x with x1 = x2 = 0 is a root, so the template is singular.
    let err = real_roots(&system).unwrap_err();
    assert_eq!(err, CubicSystemError::SingularTemplate { degree: 7 });
    assert_eq!(
        err.to_string(),
        "the Macaulay elimination template is singular (degree-7 block)"
    );
    system[2][0] = f64::NAN;
    assert_eq!(
        real_roots(&system).unwrap_err(),
        CubicSystemError::NonFinite
    );
    assert_eq!(
        CubicSystemError::from(crate::linalg::nonsymmetric::EigenvalueError::NoConvergence)
            .to_string(),
        "eigenvalues of the action matrix: the QR iteration did not converge in 30 iterations"
    );
}
