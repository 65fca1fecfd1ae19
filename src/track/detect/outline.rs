//! The outline fit of a blob ([`super`], step 3): a direct least-squares
//! ellipse refitted without the edge points that leave it and without the
//! notches that something in front of the limb cuts into it, and how far
//! what is left still dips inside the ellipse.

use super::{
    DIP_ARC_DEG, DIP_MIN_POINTS, DIP_SIGMAS, NOTCH_FLOOR_PX, NOTCH_MIN_KEPT, NOTCH_MIN_SIDE,
    NOTCH_ROUNDS, NOTCH_SIGMAS, NOTCH_WINDOW_DEG, REFIT_ROUNDS,
};
use crate::track::conic::{fit_ellipse, Ellipse, MIN_EDGE_POINTS};
use nalgebra::{Matrix2, SymmetricEigen, Vector2};
use std::f64::consts::TAU;

/// An ellipse fitted to a blob's edge points, with the points it left out.
#[derive(Debug, Clone, PartialEq)]
pub struct OutlineFit {
    /// The ellipse fitted to the kept points.
    pub ellipse: Ellipse,
    /// Per edge point: whether the final fit used it.
    pub kept: Vec<bool>,
    /// Per edge point: whether it was cut away as part of a notch
    /// ([`notch_arcs`]).
    pub notch: Vec<bool>,
}

/// The ellipse of a blob's edge `points` (undistorted px), robust to what
/// hides part of the outline: the direct least-squares fit, refitted
/// without the points farther from it than their `tolerances` (a straight
/// occluder's edge, a neighbour's), then without the arcs that lie inside
/// it along their length ([`notch_arcs`]: a support's notch, each point's
/// noise σ in `sigmas`), for up to [`NOTCH_ROUNDS`] rounds or until the cut
/// settles. The notch refit never keeps fewer than [`NOTCH_MIN_KEPT`] of
/// the points; where it would, the last ellipse stays and the notch is
/// reported whole. `None` when no ellipse fits the points at all.
pub fn fit_outline(
    points: &[Vector2<f64>],
    sigmas: &[f64],
    tolerances: &[f64],
) -> Option<OutlineFit> {
    if sigmas.len() != points.len() || tolerances.len() != points.len() {
        return None;
    }
    let mut ellipse = fit_ellipse(points)?;
    let mut inliers: Vec<bool> = vec![true; points.len()];
    for _ in 0..REFIT_ROUNDS {
        let next: Vec<bool> = points
            .iter()
            .zip(tolerances)
            .map(|(p, tolerance)| ellipse.distance(p).abs() <= *tolerance)
            .collect();
        if next == inliers {
            break;
        }
        let kept = masked(points, &next);
        if kept.len() < MIN_EDGE_POINTS.max(points.len() / 2) {
            break;
        }
        match fit_ellipse(&kept) {
            Some(refit) => {
                ellipse = refit;
                inliers = next;
            }
            None => break,
        }
    }
    // Notches: the arcs of the outline that lie inside the ellipse along
    // their length are cut away, and the ellipse refitted to the rest,
    // until the cut settles (module docs).
    let mut notch = vec![false; points.len()];
    let fewest = MIN_EDGE_POINTS.max((NOTCH_MIN_KEPT * points.len() as f64).ceil() as usize);
    for _ in 0..NOTCH_ROUNDS {
        let next_notch = notch_arcs(&ellipse, points, sigmas, tolerances);
        let next: Vec<bool> = points
            .iter()
            .zip(tolerances)
            .zip(&next_notch)
            .map(|((p, tolerance), cut)| !cut && ellipse.distance(p).abs() <= *tolerance)
            .collect();
        if next == inliers && next_notch == notch {
            break;
        }
        let kept = masked(points, &next);
        if kept.len() < fewest {
            // Too much to cut: the blob is flagged on the share alone.
            notch = next_notch;
            break;
        }
        match fit_ellipse(&kept) {
            Some(refit) => {
                ellipse = refit;
                inliers = next;
                notch = next_notch;
            }
            None => break,
        }
    }
    Some(OutlineFit {
        ellipse,
        kept: inliers,
        notch,
    })
}

/// The `points` whose `keep` is set.
fn masked(points: &[Vector2<f64>], keep: &[bool]) -> Vec<Vector2<f64>> {
    points
        .iter()
        .zip(keep)
        .filter(|(_, keep)| **keep)
        .map(|(p, _)| *p)
        .collect()
}

/// The edge points on a notch: every point whose window of
/// [`NOTCH_WINDOW_DEG`] of the ellipse's parametric angle, centred on it,
/// holds at least [`DIP_MIN_POINTS`] points whose mean distance lies inside
/// `ellipse` by more than [`NOTCH_SIGMAS`] standard errors of that mean
/// (each point's σ from `sigmas`) plus [`NOTCH_FLOOR_PX`]. A window holds
/// at least [`NOTCH_MIN_SIDE`] points either side of its centre, however
/// far they reach (a small disc has few edge points). Points outside the
/// ellipse by more than
/// their `tolerances` take no part (another blob's edge); points inside
/// by more do (the notch's deepest part).
///
/// On a whole disc the distances scatter about zero and no window passes;
/// where something in front of the disc hides its limb, the edge bends
/// inwards along an arc, which the ellipse fitted to the rest no longer
/// follows.
pub fn notch_arcs(
    ellipse: &Ellipse,
    points: &[Vector2<f64>],
    sigmas: &[f64],
    tolerances: &[f64],
) -> Vec<bool> {
    let mut notch = vec![false; points.len()];
    let root = shape_root(ellipse);
    // (angle, distance, σ, index), points outside beyond tolerance left out.
    let mut around: Vec<(f64, f64, f64, usize)> = points
        .iter()
        .zip(sigmas.iter().zip(tolerances))
        .enumerate()
        .filter_map(|(i, (p, (sigma, tolerance)))| {
            let distance = ellipse.distance(p);
            let u = root * (p - ellipse.centre);
            (distance <= *tolerance && distance.is_finite() && sigma.is_finite())
                .then(|| (u.y.atan2(u.x), distance, *sigma, i))
        })
        .collect();
    let n = around.len();
    if n < DIP_MIN_POINTS {
        return notch;
    }
    around.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.3.cmp(&b.3)));
    // The points three times round, for windows across ±180°.
    let sums = ArcSums::new(around.iter().map(|a| (a.0, a.1, a.2)), 3);
    let angle = |k: usize| sums.angle(k);
    let half = 0.5 * NOTCH_WINDOW_DEG.to_radians();
    let mut marked = vec![false; n];
    let (mut low, mut high) = (0, 0);
    for centre in n..2 * n {
        while (angle(centre) - angle(low) > half && centre - low > NOTCH_MIN_SIDE)
            || centre - low >= n / 2
        {
            low += 1;
        }
        high = high.max(centre);
        while high + 1 < 3 * n
            && (angle(high + 1) - angle(centre) <= half || high - centre < NOTCH_MIN_SIDE)
            && high + 1 - centre < n / 2
        {
            high += 1;
        }
        let Some((mean, mean_sigma, count)) = sums.mean(low, high) else {
            continue;
        };
        if -mean > NOTCH_SIGMAS * mean_sigma / count.sqrt() + NOTCH_FLOOR_PX {
            marked[centre - n] = true;
        }
    }
    for (k, point) in around.iter().enumerate() {
        notch[point.3] = marked[k];
    }
    notch
}

/// `M^{1/2}` of an ellipse's shape matrix: it maps the ellipse onto the
/// unit circle, whose polar angle is the ellipse's parametric angle.
fn shape_root(ellipse: &Ellipse) -> Matrix2<f64> {
    let eigen = SymmetricEigen::new(ellipse.shape);
    eigen.eigenvectors
        * Matrix2::from_diagonal(&eigen.eigenvalues.map(|v| v.max(0.0).sqrt()))
        * eigen.eigenvectors.transpose()
}

/// How far the edge dips inside `ellipse`, px: over every arc of at most
/// [`DIP_ARC_DEG`] of the ellipse's parametric angle (the angle of
/// `M^{1/2} (p − c)`, so that an arc is the same share of the outline
/// however elongated the ellipse) that holds at least [`DIP_MIN_POINTS`]
/// of the edge `points`, the mean distance of those points inside the
/// ellipse less [`DIP_SIGMAS`] standard errors of that mean (each point's
/// σ from `sigmas`); the largest such value, or 0.
///
/// Something in front of a disc cuts a notch or a chord into its edge:
/// there the edge points all lie inside the ellipse fitted to the rest
/// (the refit leaves out only those off by more than the outlier
/// tolerance, so a shallow notch still pulls its points inside), where
/// on a whole disc their distances scatter about zero.
pub fn edge_dip(ellipse: &Ellipse, points: &[Vector2<f64>], sigmas: &[f64]) -> f64 {
    let n = points.len();
    if n < DIP_MIN_POINTS {
        return 0.0;
    }
    let root = shape_root(ellipse);
    let mut around: Vec<(f64, f64, f64)> = points
        .iter()
        .zip(sigmas)
        .map(|(p, sigma)| {
            let u = root * (p - ellipse.centre);
            (u.y.atan2(u.x), ellipse.distance(p), *sigma)
        })
        .collect();
    around.sort_by(|a, b| a.0.total_cmp(&b.0));
    // The points twice round, for arcs across ±180°.
    let sums = ArcSums::new(around.iter().copied(), 2);
    let arc = DIP_ARC_DEG.to_radians();
    let mut deepest: f64 = 0.0;
    let mut end = 0;
    for start in 0..n {
        end = end.max(start);
        while end + 1 < start + n && sums.angle(end + 1) - sums.angle(start) <= arc {
            end += 1;
        }
        if let Some((mean, mean_sigma, count)) = sums.mean(start, end) {
            deepest = deepest.max(-mean - DIP_SIGMAS * mean_sigma / count.sqrt());
        }
    }
    deepest
}

/// Edge points sorted by their angle about an ellipse, laid `laps` times
/// round (angles growing by 2π each lap) with prefix sums of their
/// distances from the ellipse and of their σ, for the means over arcs
/// that cross ±180° ([`notch_arcs`], [`edge_dip`]).
struct ArcSums {
    angles: Vec<f64>,
    sum_distance: Vec<f64>,
    sum_sigma: Vec<f64>,
}

impl ArcSums {
    /// From `(angle, distance, σ)` of each point, sorted by angle.
    fn new(points: impl Iterator<Item = (f64, f64, f64)>, laps: usize) -> Self {
        let (angles, rest): (Vec<f64>, Vec<(f64, f64)>) = points
            .map(|(angle, distance, sigma)| (angle, (distance, sigma)))
            .unzip();
        let n = angles.len();
        let mut sum_distance = vec![0.0; laps * n + 1];
        let mut sum_sigma = vec![0.0; laps * n + 1];
        for k in 0..laps * n {
            sum_distance[k + 1] = sum_distance[k] + rest[k % n].0;
            sum_sigma[k + 1] = sum_sigma[k] + rest[k % n].1;
        }
        Self {
            angles,
            sum_distance,
            sum_sigma,
        }
    }

    /// The angle of point `k` of the laps.
    fn angle(&self, k: usize) -> f64 {
        let n = self.angles.len();
        self.angles[k % n] + TAU * (k / n) as f64
    }

    /// Over points `low..=high` of the laps: the mean distance, the mean
    /// σ and the count; `None` below [`DIP_MIN_POINTS`] points.
    fn mean(&self, low: usize, high: usize) -> Option<(f64, f64, f64)> {
        let count = high + 1 - low;
        if count < DIP_MIN_POINTS {
            return None;
        }
        let count_f = count as f64;
        let mean = (self.sum_distance[high + 1] - self.sum_distance[low]) / count_f;
        let mean_sigma = (self.sum_sigma[high + 1] - self.sum_sigma[low]) / count_f;
        Some((mean, mean_sigma, count_f))
    }
}
