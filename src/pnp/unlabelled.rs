//! Unlabelled pose, **stand-in**: the `unlabelled` branch's contract
//! (`UnlabelledOptions`, `Labelling`, `Identification`, `identify`) by
//! exhaustive search, so that identifiability (`crate::identifiability`)
//! builds and is tested before that branch lands. Merging it replaces this
//! file (take theirs). Every labelling (all n! of them, n ≤
//! [`MAX_POINTS`]) is fitted by the `ml` solver; those with every point
//! within `gate` of its reprojection are consistent, ranked by RMS.
#![allow(clippy::module_name_repetitions)]

use super::{PnpError, Solver};
use crate::pose::Pose;
use nalgebra::{Vector2, Vector3};

/// Human name of the method.
pub const NAME: &str = "unlabelled identification (exhaustive stand-in)";
/// Most points the exhaustive search accepts (8! = 40,320 labellings).
pub const MAX_POINTS: usize = 8;

/// How the search decides consistency.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct UnlabelledOptions {
    /// Per-point reprojection gate on the normalised image plane.
    pub gate: f64,
    /// How many object points may have no blob (the stand-in supports 0).
    pub max_missing: usize,
}

/// One labelling and its pose.
#[derive(Debug, Clone, PartialEq)]
pub struct Labelling {
    /// labels[i] = index of the object point that image point i is.
    pub labels: Vec<usize>,
    /// The maximum-likelihood pose on all matched points.
    pub pose: Pose,
    /// Reprojection RMS over matched points, normalised units.
    pub rms: f64,
}

/// The answer of [`identify`].
#[derive(Debug, Clone, PartialEq)]
pub struct Identification {
    /// The consistent labelling with the lowest RMS.
    pub best: Labelling,
    /// Best consistent labelling whose labels differ from `best`'s.
    pub runner_up: Option<Labelling>,
    /// Labellings tried.
    pub hypotheses: usize,
}

impl Identification {
    /// `runner_up.rms / best.rms`; `None` when no other labelling is
    /// consistent.
    pub fn ambiguity(&self) -> Option<f64> {
        self.runner_up
            .as_ref()
            .map(|r| r.rms / self.best.rms.max(1e-15))
    }
}

fn permutations(n: usize) -> Vec<Vec<usize>> {
    if n == 0 {
        return vec![Vec::new()];
    }
    let mut out = Vec::new();
    for p in permutations(n - 1) {
        for k in 0..n {
            let mut q = p.clone();
            q.insert(k, n - 1);
            out.push(q);
        }
    }
    out
}

/// Finds the labelling of `image` (unordered blobs, normalised) against
/// `object`, and the runner-up; see the module docs.
pub fn identify(
    object: &[Vector3<f64>],
    image: &[Vector2<f64>],
    options: &UnlabelledOptions,
) -> Result<Identification, PnpError> {
    if object.len() != image.len() {
        return Err(PnpError::MismatchedLengths {
            object: object.len(),
            image: image.len(),
        });
    }
    if object.len() > MAX_POINTS {
        return Err(PnpError::Degenerate {
            solver: NAME,
            reason: "more than 8 points",
        });
    }
    let mut found: Vec<Labelling> = Vec::new();
    let mut hypotheses = 0;
    let mut assigned = Vec::with_capacity(object.len());
    for labels in permutations(object.len()) {
        hypotheses += 1;
        assigned.clear();
        assigned.extend(labels.iter().map(|&l| object[l]));
        let Ok(pose) = Solver::Ml.solve_best(&assigned, image) else {
            continue;
        };
        let (mut worst, mut sum) = (0.0f64, 0.0);
        for (p, m) in assigned.iter().zip(image) {
            let d = (pose.project_normalised(p) - m).norm();
            worst = worst.max(d);
            sum += d * d;
        }
        if worst <= options.gate && pose.all_in_front(&assigned) {
            found.push(Labelling {
                labels,
                pose,
                rms: (sum / image.len() as f64).sqrt(),
            });
        }
    }
    found.sort_by(|a, b| a.rms.total_cmp(&b.rms));
    let mut ranked = found.into_iter();
    let best = ranked.next().ok_or(PnpError::Degenerate {
        solver: NAME,
        reason: "no labelling is consistent within the gate",
    })?;
    Ok(Identification {
        best,
        runner_up: ranked.next(),
        hypotheses,
    })
}
