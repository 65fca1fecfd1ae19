//! Constraints no layout can meet, found before any search: every pairwise
//! centre distance lies between one sphere diameter plus the gap and the
//! envelope's diagonal, and distinct distances need the stereo rule's
//! difference between them ([`unsatisfiable`]).

use super::optimise;
use crate::family::{Constraints, Envelope, Family, FamilyKind};

/// without searching: every pairwise centre distance lies between one
/// sphere diameter plus the gap and the envelope's diagonal, and distinct
/// distances need the identifiability difference between them.
pub fn unsatisfiable(family: &Family, constraints: &Constraints) -> Option<String> {
    let points = family.point_count();
    if points < 2 {
        return None;
    }
    let [x, y, z] = constraints.envelope.size_mm;
    let diagonal = (x * x + y * y + z * z).sqrt();
    let closest = constraints.sphere_diameter_mm + constraints.min_gap_mm;
    if closest > diagonal {
        return Some(format!(
            "{points} spheres {closest} mm apart (diameter plus smallest gap) do not fit an envelope whose diagonal is {diagonal:.1} mm"
        ));
    }
    let distances = points * (points - 1) / 2;
    match constraints.distinct_distance_capacity() {
        Some(capacity) if distances > capacity => Some(format!(
            "{points} points have {distances} pairwise distances, but the envelope holds at most {capacity} distances {} mm apart between {closest} mm (sphere diameter plus gap) and its diagonal, {diagonal:.1} mm; use fewer points, a larger envelope or a smaller --min-distance-diff",
            constraints.min_distance_diff_mm,
        )),
        Some(_) if matches!(family.kind(), FamilyKind::Custom { .. }) => {
            unidentifiable(family, constraints)
        }
        _ => None,
    }
}

/// Random stream of the up-front identifiability check.
const FEASIBILITY_STREAM: u64 = 0xF0EA51;
/// Envelope scales the refusal of [`unidentifiable`] tries, in order.
const FEASIBLE_ENVELOPE_SCALES: [f64; 4] = [1.25, 1.5, 2.0, 3.0];
/// Fractions of the distance difference the refusal of [`unidentifiable`]
/// tries, in order.
const FEASIBLE_DIFF_FRACTIONS: [f64; 3] = [0.75, 0.5, 0.25];

/// The smallest difference between two pairwise distances that the
/// distance-spreading repair reaches for `family`'s start in `constraints`
/// (tightened as the search's penalty tightens them), trying
/// [`optimise::SPREAD_TRIES`] seeded jitters, and whether it met them.
fn spread_check(family: &Family, constraints: &Constraints) -> (bool, f64) {
    let target = constraints.tightened(super::PENALTY_MARGIN_FRACTION, super::PENALTY_MARGIN_MM);
    let fixed = family.fixed_points();
    let mut closest = 0.0f64;
    for attempt in 0..optimise::SPREAD_TRIES {
        let mut points = family.points(&family.initial());
        let mut rng = crate::synthetic::stream_rng(0, FEASIBILITY_STREAM, attempt);
        if target.spread_distances(&mut points, &fixed, &mut rng) {
            return (
                true,
                constraints.violations(&points).smallest_distance_diff_mm,
            );
        }
        closest = closest.max(constraints.violations(&points).smallest_distance_diff_mm);
    }
    (false, closest)
}

/// The up-front identifiability check of a custom family: the number of
/// distances may fit the envelope's range ([`Constraints::distinct_distance_capacity`]),
/// but they must also fit the geometry, which allows far fewer (with the
/// default constraints, 13 points rather than the 18 the range allows).
/// If the distance-spreading repair finds no identifiable layout from the
/// family's start, the search (whose starts repair the same way) would not
/// either: the refusal says how close it came and which point count,
/// envelope or difference it does reach. It is a failed search, not a
/// proof that no layout exists, and says so.
fn unidentifiable(family: &Family, constraints: &Constraints) -> Option<String> {
    let (met, closest) = spread_check(family, constraints);
    if met {
        return None;
    }
    let points = family.point_count();
    let diff = constraints.min_distance_diff_mm;
    let rebuilt = |kind: FamilyKind, envelope: Envelope| {
        Family::new(kind, envelope, constraints.sphere_diameter_mm).ok()
    };
    let mut options = Vec::new();
    if let FamilyKind::Custom { start: None, .. } = family.kind() {
        if let Some(count) = (4..points).rev().find(|&count| {
            rebuilt(
                FamilyKind::Custom { count, start: None },
                constraints.envelope,
            )
            .is_some_and(|f| spread_check(&f, constraints).0)
        }) {
            options.push(format!("--points {count}"));
        }
    }
    let size = constraints.envelope.size_mm;
    if let Some(envelope) = FEASIBLE_ENVELOPE_SCALES.iter().find_map(|scale| {
        let envelope = Envelope::new(size.map(|s| s * scale)).ok()?;
        let family = rebuilt(family.kind().clone(), envelope)?;
        let wider = Constraints {
            envelope,
            ..*constraints
        };
        spread_check(&family, &wider).0.then_some(envelope)
    }) {
        let [x, y, z] = envelope.size_mm;
        options.push(if x == y && y == z {
            format!("--envelope {x}")
        } else {
            format!("--envelope {x},{y},{z}")
        });
    }
    if let Some(smaller) = FEASIBLE_DIFF_FRACTIONS.iter().find_map(|fraction| {
        let smaller = Constraints {
            min_distance_diff_mm: diff * fraction,
            ..*constraints
        };
        spread_check(family, &smaller)
            .0
            .then_some(smaller.min_distance_diff_mm)
    }) {
        options.push(format!("--min-distance-diff {smaller}"));
    }
    let options = if options.is_empty() {
        "it finds none with fewer points, a larger envelope or a smaller difference either"
            .to_string()
    } else {
        format!("it does find one with {}", options.join(", or "))
    };
    Some(format!(
        "no layout of {points} points found whose {} pairwise distances differ by {diff} mm or more: the distance-spreading repair that every start of the search uses got them {closest:.2} mm apart at best ({} seeded tries; a failed search, not a proof that none exists); {options}",
        points * (points - 1) / 2,
        optimise::SPREAD_TRIES,
    ))
}
