//! Blob grouping: a frame's unordered blobs split into the markers of a
//! set by the best joint fit (the set module's docs, "Blob grouping").

use crate::pnp::ml;
use crate::pnp::p3p;
use crate::pnp::unlabelled::{UnlabelledOptions, MIN_POINTS, SCREENING_FACTOR, SETTLED_FRACTION};
use crate::pose::Pose;
use nalgebra::{Vector2, Vector3};
use rayon::prelude::*;
use serde::Serialize;

/// One marker found among a frame's blobs.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Placement {
    /// The marker (index in the set).
    pub marker: usize,
    /// The blobs it explains (indices into the frame's blob list),
    /// ascending.
    pub blobs: Vec<usize>,
    /// For each of `blobs`, the marker's point it is.
    pub labels: Vec<usize>,
    /// The pose fitted on the matched blobs.
    #[serde(skip)]
    pub pose: Pose,
    /// Reprojection RMS over the matched blobs, normalised units.
    pub rms: f64,
}

/// Every placement of `object` (marker `marker`) among `image`'s blobs
/// within the gate (module docs), each labelling once with its lowest RMS.
pub fn placements(
    marker: usize,
    object: &[Vector3<f64>],
    image: &[Vector2<f64>],
    options: &UnlabelledOptions,
) -> Vec<Placement> {
    let n = object.len();
    let b = image.len();
    let mut found: Vec<Placement> = Vec::new();
    if n < MIN_POINTS || b < MIN_POINTS.max(n.saturating_sub(options.max_missing)) {
        return found;
    }
    let gate_sq = options.gate * options.gate;
    let screening_sq = (SCREENING_FACTOR * options.gate).powi(2);
    let bearing = |m: &Vector2<f64>| Vector3::new(m.x, m.y, 1.0).normalize();
    let mut poses = p3p::P3pCandidates::new();
    let mut taken = vec![usize::MAX; n];
    let mut settled = false;
    'triples: for i in 0..b {
        for j in i + 1..b {
            for k in j + 1..b {
                let triple = [i, j, k];
                let bearings = triple.map(|t| bearing(&image[t]));
                if !p3p::bearings_span_space(&bearings) {
                    continue;
                }
                for pa in 0..n {
                    for pb in 0..n {
                        for pc in 0..n {
                            if pb == pa || pc == pa || pc == pb {
                                continue;
                            }
                            p3p::solve_bearings(
                                &[object[pa], object[pb], object[pc]],
                                &bearings,
                                &mut poses,
                            );
                            for pose in &poses {
                                if let Some(p) = place(
                                    marker,
                                    object,
                                    image,
                                    pose,
                                    [(i, pa), (j, pb), (k, pc)],
                                    options.max_missing,
                                    screening_sq,
                                    gate_sq,
                                    &mut taken,
                                ) {
                                    settled |= p.blobs.len() == n
                                        && p.rms <= SETTLED_FRACTION * options.gate;
                                    offer(&mut found, p);
                                }
                            }
                        }
                    }
                }
                if settled {
                    break 'triples;
                }
            }
        }
    }
    found
}

/// One hypothesis: the marker's points take their nearest free blobs;
/// refitted and gated.
#[allow(clippy::too_many_arguments)]
fn place(
    marker: usize,
    object: &[Vector3<f64>],
    image: &[Vector2<f64>],
    pose: &Pose,
    triple: [(usize, usize); 3],
    max_missing: usize,
    screening_sq: f64,
    gate_sq: f64,
    taken: &mut [usize],
) -> Option<Placement> {
    taken.fill(usize::MAX);
    for &(blob, point) in &triple {
        taken[point] = blob;
    }
    let mut missing = 0;
    for (k, p) in object.iter().enumerate() {
        if taken[k] != usize::MAX {
            continue;
        }
        let c = pose.transform(p);
        let nearest = (c.z > 0.0)
            .then(|| Vector2::new(c.x / c.z, c.y / c.z))
            .and_then(|projection| {
                image
                    .iter()
                    .enumerate()
                    .filter(|(blob, _)| !taken.contains(blob))
                    .map(|(blob, m)| (blob, (m - projection).norm_squared()))
                    .min_by(|x, y| x.1.total_cmp(&y.1))
            });
        match nearest {
            Some((blob, d)) if d <= screening_sq => taken[k] = blob,
            _ => {
                missing += 1;
                if missing > max_missing {
                    return None;
                }
            }
        }
    }
    let mut pairs: Vec<(usize, usize)> = taken
        .iter()
        .enumerate()
        .filter(|(_, &blob)| blob != usize::MAX)
        .map(|(point, &blob)| (blob, point))
        .collect();
    pairs.sort_unstable();
    fitted(marker, object, image, pose, &pairs, gate_sq)
}

/// The placement of marker `marker` on the (blob, point) `pairs`,
/// ascending by blob: the pose refitted from `pose` and every pair within
/// the gate, or None.
fn fitted(
    marker: usize,
    object: &[Vector3<f64>],
    image: &[Vector2<f64>],
    pose: &Pose,
    pairs: &[(usize, usize)],
    gate_sq: f64,
) -> Option<Placement> {
    let matched: Vec<Vector3<f64>> = pairs.iter().map(|&(_, point)| object[point]).collect();
    let blobs: Vec<Vector2<f64>> = pairs.iter().map(|&(blob, _)| image[blob]).collect();
    let refined = ml::refine(pose, &matched, &blobs);
    let mut sum_sq = 0.0;
    for (p, m) in matched.iter().zip(&blobs) {
        let c = refined.transform(p);
        if !(c.z > 0.0) {
            return None;
        }
        let error_sq = (Vector2::new(c.x / c.z, c.y / c.z) - m).norm_squared();
        if !(error_sq <= gate_sq) {
            return None;
        }
        sum_sq += error_sq;
    }
    Some(Placement {
        marker,
        blobs: pairs.iter().map(|&(blob, _)| blob).collect(),
        labels: pairs.iter().map(|&(_, point)| point).collect(),
        pose: refined,
        rms: (sum_sq / pairs.len() as f64).sqrt(),
    })
}

/// Keeps each (blobs, labels) once, with its lowest RMS.
fn offer(found: &mut Vec<Placement>, placement: Placement) {
    match found
        .iter_mut()
        .find(|p| p.blobs == placement.blobs && p.labels == placement.labels)
    {
        Some(seen) if placement.rms < seen.rms => *seen = placement,
        Some(_) => {}
        None => found.push(placement),
    }
}

/// Groups a frame's blobs into markers of the set by the best joint fit
/// (module docs): at most one placement per marker, no blob in two.
/// Sorted by marker.
pub fn group_blobs(
    objects: &[Vec<Vector3<f64>>],
    image: &[Vector2<f64>],
    options: &UnlabelledOptions,
) -> Vec<Placement> {
    grouping(objects, image, options).placements
}

/// A frame's blobs grouped into markers ([`grouping`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Grouping {
    /// The markers placed, sorted by marker.
    pub placements: Vec<Placement>,
    /// Blob groups that two markers fit about as well: (the better
    /// fitting marker, its rival, the better one's blobs); neither is
    /// placed on them.
    pub ambiguous: Vec<(usize, usize, Vec<usize>)>,
}

/// A rival marker that fits most of a placement's blobs within this
/// factor of its reprojection RMS makes their identity ambiguous.
pub const CROSS_AMBIGUITY_RATIO: f64 = 3.0;

/// [`group_blobs`], and the blob groups whose marker is ambiguous: before
/// a placement is accepted, a placement of another marker not yet placed
/// that explains as many blobs, at least half of them (and three) the
/// same, at an RMS within [`CROSS_AMBIGUITY_RATIO`] of its own makes the
/// group ambiguous, and
/// neither marker is placed on it (its blobs are set aside). A right
/// marker fits its own blobs to their noise, far better than any other
/// marker of a set whose markers one camera can tell apart; blobs biased
/// by something in front of them may fit two markers alike.
pub fn grouping(
    objects: &[Vec<Vector3<f64>>],
    image: &[Vector2<f64>],
    options: &UnlabelledOptions,
) -> Grouping {
    let mut candidates: Vec<Placement> = objects
        .par_iter()
        .enumerate()
        .map(|(j, object)| placements(j, object, image, options))
        .collect::<Vec<_>>()
        .into_iter()
        .flatten()
        .collect();
    let rank = |a: &Placement, b: &Placement| {
        b.blobs
            .len()
            .cmp(&a.blobs.len())
            .then(a.rms.total_cmp(&b.rms))
            .then(a.marker.cmp(&b.marker))
            .then(a.labels.cmp(&b.labels))
    };
    candidates.sort_by(rank);
    let gate_sq = options.gate * options.gate;
    let mut chosen: Vec<Placement> = Vec::new();
    let mut ambiguous = Vec::new();
    let mut used = vec![false; image.len()];
    let mut next = 0;
    while next < candidates.len() {
        let candidate = candidates[next].clone();
        next += 1;
        if chosen.iter().any(|c| c.marker == candidate.marker) {
            continue;
        }
        if candidate.blobs.iter().any(|&b| used[b]) {
            // A point of this marker took a blob an accepted marker
            // explains (a sphere hidden behind the other marker's sphere
            // projects into its blob): the placement without those blobs,
            // refitted, joins the ranking where it belongs.
            let object = &objects[candidate.marker];
            let pairs: Vec<(usize, usize)> = candidate
                .blobs
                .iter()
                .zip(&candidate.labels)
                .filter(|&(&blob, _)| !used[blob])
                .map(|(&blob, &point)| (blob, point))
                .collect();
            let enough = MIN_POINTS.max(object.len().saturating_sub(options.max_missing));
            if pairs.len() >= enough {
                let reduced = fitted(
                    candidate.marker,
                    object,
                    image,
                    &candidate.pose,
                    &pairs,
                    gate_sq,
                );
                if let Some(reduced) = reduced {
                    let at =
                        next + candidates[next..].partition_point(|c| rank(c, &reduced).is_le());
                    candidates.insert(at, reduced);
                }
            }
            continue;
        }
        let shared_enough = |rival: &Placement| {
            let shared = rival
                .blobs
                .iter()
                .filter(|b| candidate.blobs.binary_search(b).is_ok())
                .count();
            shared >= MIN_POINTS.max(candidate.blobs.len().div_ceil(2))
        };
        let rival = candidates[next..].iter().find(|rival| {
            rival.marker != candidate.marker
                && rival.blobs.len() == candidate.blobs.len()
                && !chosen.iter().any(|c| c.marker == rival.marker)
                && rival.blobs.iter().all(|&b| !used[b])
                && rival.rms <= CROSS_AMBIGUITY_RATIO * candidate.rms
                && shared_enough(rival)
        });
        for &b in &candidate.blobs {
            used[b] = true;
        }
        match rival {
            Some(rival) => ambiguous.push((candidate.marker, rival.marker, candidate.blobs)),
            None => chosen.push(candidate),
        }
    }
    chosen.sort_by_key(|p| p.marker);
    Grouping {
        placements: chosen,
        ambiguous,
    }
}
