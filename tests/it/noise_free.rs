//! Noise-free recovery: every solver recovers the generating pose to
//! rotation error < 1e-6° and relative translation error < 1e-8 on at least
//! 1000 seeded problems: the biprism and random n = 6…100 sets (near field,
//! far field, off axis, any rotation), and n = 4–5 where the method allows it;
//! methods that accept coplanar points (SQPnP) also on planar and
//! quasi-planar sets (rotation within 1e-5° there, see
//! [`allowed_misses_per_1000`]).

use crate::common::{errors, problem, Family};
use layout_opt::pnp::Solver;

const ROTATION_TOLERANCE_DEG: f64 = 1e-6;
const TRANSLATION_TOLERANCE: f64 = 1e-8;
/// Rotation tolerance on quasi-planar sets (see [`allowed_misses_per_1000`]).
const QUASI_PLANAR_ROTATION_TOLERANCE_DEG: f64 = 1e-5;
const SEED: u64 = 20261121;

/// Cases per family; the biprism and random families together give ≥ 1000.
const CASES: u64 = 500;

/// Misses allowed per 1000 cases. Zero for every method except LHM, whose
/// orthogonal iteration converges to *a* minimum of the object-space error,
/// not always the global one (Lu et al. §4.3 prove global convergence to a
/// critical point only). Seen: 0 misses on the biprism and on random
/// n = 6…100 sets, and 1 in 500 n = 4–5 sets (Minimal case 94, n = 4, near
/// field: LHM stops at a true local minimum 108° away whose reprojection
/// error is 0.079; SQPnP finds the same minimum among its candidates).
/// IEPnP needed 20 before its Gauss–Newton backtracked and tried the mirror
/// candidate; it now misses none.
///
/// The count is printed either way.
///
/// Quasi-planar sets get a rotation tolerance of [`QUASI_PLANAR_ROTATION_TOLERANCE_DEG`]:
/// the rotation out of their near-plane is weakly determined, and SQPnP
/// stops when its step `‖δ‖²` falls below 1e-10 (the reference code's
/// value), which bounds the remaining rotation error by about 1e-5 rad, not
/// 1e-6°. Where to stop is then sensitive to rounding: with SQPnP's former
/// private 3×3 LDLᵀ the worst of these 500 sets was 5.3e-9°; with the
/// shared [`layout_opt::linalg::solve_positive_definite`], which rounds two
/// products differently, case 479 stops at 2.7e-6° (both measured with
/// `cargo test --release --test it noise_free::sqpnp -- --nocapture`). The
/// translation tolerance stays.
fn allowed_misses_per_1000(solver: Solver) -> usize {
    match solver {
        Solver::Lhm => 2,
        _ => 0,
    }
}

fn check(solver: Solver, family: Family, cases: u64) {
    let mut failures = Vec::new();
    let mut worst = (0.0f64, 0.0f64);
    let rotation_tolerance = match family {
        Family::QuasiPlanar => QUASI_PLANAR_ROTATION_TOLERANCE_DEG,
        _ => ROTATION_TOLERANCE_DEG,
    };
    for case in 0..cases {
        let p = problem(SEED, family, case, 0.0);
        match solver.solve_best(&p.object, &p.normalised) {
            Ok(pose) => {
                let (rotation, translation) = errors(&p, &pose);
                worst = (worst.0.max(rotation), worst.1.max(translation));
                if !(rotation < rotation_tolerance && translation < TRANSLATION_TOLERANCE) {
                    failures.push((case, rotation, translation));
                }
            }
            Err(e) => {
                eprintln!("{solver} case {case}: {e}");
                failures.push((case, f64::NAN, f64::NAN));
            }
        }
    }
    eprintln!(
        "{solver} on {family:?}: {} misses in {cases}; worst {worst:?}",
        failures.len()
    );
    assert!(
        failures.len() * 1000 <= allowed_misses_per_1000(solver) * cases as usize,
        "{solver} on {family:?}: {} of {cases} cases missed (rotation deg, relative translation): first {:?}; worst {:?}",
        failures.len(),
        &failures[..failures.len().min(5)],
        worst
    );
}

macro_rules! noise_free_tests {
    ($($name:ident: $solver:expr, minimal = $minimal:expr;)*) => {$(
        #[test]
        fn $name() {
            check($solver, Family::Biprism, CASES);
            check($solver, Family::Random, CASES);
            if $minimal {
                check($solver, Family::Minimal, CASES);
            }
        }
    )*};
}

// EPnP+GN is not run on n = 4–5: its closed-form β start is poor there and
// GN settles in wrong minima (the paper's §2.1 claim that "EPnP+GN performs
// erratically when n = 4 or 5"; seen here: 142 of 500 cases missed). EPnP
// without GN is not exact at n = 4 (its N = 4 case is an approximation).
/// OPnP accepts coplanar points (`needs_noncoplanar` is false): exact
/// recovery on random planar sets, n = 4…100, too.
#[test]
fn opnp_planar() {
    check(Solver::Opnp, Family::Planar, CASES);
}

noise_free_tests! {
    dlt: Solver::Dlt, minimal = false;
    epnp: Solver::Epnp, minimal = false;
    epnp_gn: Solver::EpnpGn, minimal = false;
    iepnp: Solver::Iepnp, minimal = true;
    parallel: Solver::Parallel, minimal = true;
    parallel_gn: Solver::ParallelGn, minimal = true;
    parallel_weighted: Solver::ParallelWeighted, minimal = true;
    dls: Solver::Dls, minimal = true;
    lhm: Solver::Lhm, minimal = true;
    rpnp: Solver::Rpnp, minimal = true;
    sqpnp: Solver::Sqpnp, minimal = true;
    opnp: Solver::Opnp, minimal = true;
    ml: Solver::Ml, minimal = true;
}

/// SQPnP accepts coplanar points: exact recovery on planar sets and on
/// slabs 1e-4…1e-1 as thick as they are wide.
#[test]
fn sqpnp_planar_and_quasi_planar() {
    check(Solver::Sqpnp, Family::Planar, CASES);
    check(Solver::Sqpnp, Family::QuasiPlanar, CASES);
}
