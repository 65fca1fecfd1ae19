//! Marker sets: several markers that one camera must tell apart.
//!
//! # The set file (docs/formats.md, "Set file")
//! `{"format": "layout-opt-set", "version": 1, "name": ..., "markers":
//! ["name-1.json", ...]}` lists 2 to [`MAX_MARKERS`] layout files, each
//! path relative to the set file. [`MarkerSet::load`] reads and checks
//! every layout and refuses, naming the file, a missing or bad layout, a
//! layout listed twice and sphere diameters that differ;
//! [`MarkerSet::check_distinct`] refuses two markers that are one marker
//! (one maps onto the other by a rigid motion and a relabelling).
//!
//! # Cross-identifiability
//! Marker `i`'s noise-free blobs in a scenario are offered to marker `j`'s
//! points as the unlabelled solver's model ([`identify`]): the full blob
//! set, and each blob set with one blob missing (the solver accepts one
//! missing blob). The best labelling of `j` within the gate, its pose
//! refitted, leaves a residual `r` whose norm is the **cross margin**;
//! [`wrong_probability`] turns it into the probability that, under the
//! scenario's noise, `j`'s fit beats `i`'s own, exactly as the
//! self-identifiability prediction does for a wrong labelling of one
//! marker. The worst of the blob sets (full or one missing) is the
//! scenario's figure; a scenario where no blob set fits `j` within the gate
//! has its margin above the gate and the gate's probability as a bound.
//! A scenario is cross-identifiable when the probability is at most
//! `1 − min_correct`.
//!
//! # Monte-Carlo
//! Trial `t` of marker `i` in scenario `s` draws noise from
//! `stream_rng(seed, CROSS_STREAM + i·2³² + s, t)`, shuffles the blobs with
//! a second stream and runs [`identify_in_set`]: the unlabelled solver
//! against every marker of the set, the lowest reprojection RMS winning. A
//! trial is right when both the marker and every label are; the counts do
//! not depend on the thread count.
//!
//! # Blob grouping ([`group_blobs`])
//! A frame holding several markers has one unordered blob list. For every
//! marker, every image triple of blobs against every ordered triple of the
//! marker's points gives P3P poses; each projects the marker, every other
//! point takes the nearest free blob within the screening gate (at most
//! `max_missing` points without one), and the matched blobs are refitted
//! ([`ml::refine`]) and kept when every one lies within the gate: a
//! *placement*. The joint fit is then chosen greedily: placements ranked
//! by blobs explained (most first), then reprojection RMS, are accepted
//! when their marker is not yet placed and they share no blob with an
//! accepted one. A placement that shares blobs with an accepted one (a
//! sphere hidden behind another marker's sphere projects into that
//! sphere's blob, the nearest one) is refitted without them and ranked
//! again, when enough blobs are left. Blobs no placement claims are
//! reported as unexplained.

// `!(x > 0.0)` is deliberate: it is true for NaN as well.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod dips;
pub mod grouping;

pub use grouping::{group_blobs, grouping, placements, Grouping, Placement, CROSS_AMBIGUITY_RATIO};

use crate::camera::Camera;
use crate::identifiability::{
    clean_view, normal_upper_tail, wrong_probability, IdentifiabilitySettings, MIN_TRIAL_GATE_PX,
    PREDICTION_GATE_SIGMAS, TRIAL_GATE_SIGMAS,
};
use crate::layout::{Layout, LayoutError};
use crate::montecarlo::Target;
use crate::pnp::ml;
use crate::pnp::unlabelled::{
    identify, identify_without, Labelling, LabellingError, TriplePoses, UnlabelledOptions,
    MIN_POINTS,
};
use crate::pose::{absolute_orientation, Pose};
use crate::scenario::{sphere_images, visibility, Scenario};
use crate::synthetic::stream_rng;
use nalgebra::{Vector2, Vector3};
use rand::seq::SliceRandom;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// The `format` of a set file.
pub const SET_FORMAT: &str = "layout-opt-set";
/// The `version` of a set file this build writes and reads.
pub const SET_VERSION: u64 = 1;
/// Fewest markers in a set.
pub const MIN_MARKERS: usize = 2;
/// Most markers in a set.
pub const MAX_MARKERS: usize = 8;
/// Default share of a marker's visible scenarios in which no other marker
/// may be confused with it (per viewpoint, a predicted confusion
/// probability of at most 1e-3).
pub const DEFAULT_MIN_CROSS: f64 = 0.999;
/// A viewpoint is near failing the cross floor when its confusion
/// probability exceeds this share of the floor's criterion
/// ([`CrossPair::near`]).
pub const NEAR_SHARE: f64 = 0.01;
/// Two markers are one marker when a rigid motion and a relabelling put
/// every point of one within this distance of a point of the other, mm.
pub const IDENTICAL_TOLERANCE_MM: f64 = 1e-3;
/// Random stream (offset) of the set's Monte-Carlo trials, apart from the
/// single-marker streams.
pub const CROSS_STREAM: u64 = 0x5E7_0000_0000_0000;

/// Why a set file cannot be used.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SetError {
    /// The set file could not be read or written.
    #[error("cannot {action} set file {path}: {source}")]
    Io {
        /// "read" or "write".
        action: &'static str,
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// The text is not a set file.
    #[error("malformed set file {path}: {message}")]
    Malformed {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// The set has too few or too many markers.
    #[error("set file {path} lists {count} markers; a set has {MIN_MARKERS} to {MAX_MARKERS}")]
    Count {
        /// The file.
        path: PathBuf,
        /// Markers listed.
        count: usize,
    },
    /// A listed layout is missing or not a usable layout.
    #[error("set file {set}: marker {marker}: {source}")]
    Layout {
        /// The set file.
        set: PathBuf,
        /// The layout file as resolved.
        marker: PathBuf,
        /// Why the layout cannot be used.
        source: LayoutError,
    },
    /// A layout is listed twice.
    #[error("set file {set} lists {marker} twice")]
    Listed {
        /// The set file.
        set: PathBuf,
        /// The layout listed twice.
        marker: String,
    },
    /// The markers' spheres differ in diameter.
    #[error("set file {set}: marker {marker} has {diameter_mm} mm spheres but {first} has {first_mm} mm; a set's markers share one sphere diameter")]
    Diameters {
        /// The set file.
        set: PathBuf,
        /// The first marker.
        first: String,
        /// Its diameter, mm.
        first_mm: f64,
        /// The marker that differs.
        marker: String,
        /// Its diameter, mm.
        diameter_mm: f64,
    },
    /// Two markers are one marker.
    #[error("set file {set}: markers {first} and {second} are the same marker (a rigid motion and a relabelling map one onto the other within {IDENTICAL_TOLERANCE_MM} mm); no image can tell them apart")]
    Identical {
        /// The set file.
        set: PathBuf,
        /// The first marker's file.
        first: String,
        /// The second marker's file.
        second: String,
    },
}

#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct SetFile {
    format: String,
    version: u64,
    name: String,
    markers: Vec<String>,
}

/// One marker of a set: its file as listed and its layout.
#[derive(Debug, Clone, PartialEq)]
pub struct SetMember {
    /// The path as the set file lists it (relative to the set file).
    pub file: String,
    /// The layout.
    pub layout: Layout,
}

/// A set of markers read from a set file.
#[derive(Debug, Clone, PartialEq)]
pub struct MarkerSet {
    /// The set's name.
    pub name: String,
    /// The set file.
    pub path: PathBuf,
    /// The markers, in file order.
    pub members: Vec<SetMember>,
}

impl MarkerSet {
    /// Reads a set file and every layout it lists (module docs).
    pub fn load(path: &Path) -> Result<MarkerSet, SetError> {
        let text = std::fs::read_to_string(path).map_err(|source| SetError::Io {
            action: "read",
            path: path.to_path_buf(),
            source,
        })?;
        let malformed = |message: String| SetError::Malformed {
            path: path.to_path_buf(),
            message,
        };
        let file: SetFile = serde_json::from_str(&text).map_err(|e| malformed(e.to_string()))?;
        if file.format != SET_FORMAT {
            return Err(malformed(format!(
                "format must be \"{SET_FORMAT}\", got \"{}\"",
                file.format
            )));
        }
        if file.version != SET_VERSION {
            return Err(malformed(format!(
                "version {} is not one this build reads ({SET_VERSION})",
                file.version
            )));
        }
        if !(MIN_MARKERS..=MAX_MARKERS).contains(&file.markers.len()) {
            return Err(SetError::Count {
                path: path.to_path_buf(),
                count: file.markers.len(),
            });
        }
        let base = path.parent().unwrap_or(Path::new(""));
        let mut members: Vec<SetMember> = Vec::with_capacity(file.markers.len());
        for listed in &file.markers {
            if members.iter().any(|m| &m.file == listed) {
                return Err(SetError::Listed {
                    set: path.to_path_buf(),
                    marker: listed.clone(),
                });
            }
            let marker = base.join(listed);
            let bad = |source| SetError::Layout {
                set: path.to_path_buf(),
                marker: marker.clone(),
                source,
            };
            let layout = Layout::load(&marker).map_err(bad)?;
            layout.validate().map_err(bad)?;
            if let Some(first) = members.first() {
                if first.layout.sphere_diameter_mm != layout.sphere_diameter_mm {
                    return Err(SetError::Diameters {
                        set: path.to_path_buf(),
                        first: first.file.clone(),
                        first_mm: first.layout.sphere_diameter_mm,
                        marker: listed.clone(),
                        diameter_mm: layout.sphere_diameter_mm,
                    });
                }
            }
            members.push(SetMember {
                file: listed.clone(),
                layout,
            });
        }
        Ok(MarkerSet {
            name: file.name,
            path: path.to_path_buf(),
            members,
        })
    }

    /// Refuses two markers that are one marker ([`same_marker`]).
    pub fn check_distinct(&self) -> Result<(), SetError> {
        for (i, a) in self.members.iter().enumerate() {
            for b in &self.members[i + 1..] {
                if same_marker(
                    &a.layout.positions(),
                    &b.layout.positions(),
                    IDENTICAL_TOLERANCE_MM,
                ) {
                    return Err(SetError::Identical {
                        set: self.path.clone(),
                        first: a.file.clone(),
                        second: b.file.clone(),
                    });
                }
            }
        }
        Ok(())
    }

    /// The markers' point positions, in set order.
    pub fn objects(&self) -> Vec<Vec<Vector3<f64>>> {
        self.members.iter().map(|m| m.layout.positions()).collect()
    }

    /// The markers' names, in set order.
    pub fn names(&self) -> Vec<String> {
        self.members.iter().map(|m| m.layout.name.clone()).collect()
    }
}

/// The set file's text for markers listed by `files` (relative to it).
pub fn set_file_json(name: &str, files: &[String]) -> String {
    let file = SetFile {
        format: SET_FORMAT.to_string(),
        version: SET_VERSION,
        name: name.to_string(),
        markers: files.to_vec(),
    };
    serde_json::to_string_pretty(&file).expect("a set file always serialises") + "\n"
}

/// Writes `layouts` as `<name>-1.json … <name>-N.json` and the set file
/// `<name>.set.json` into `dir`, each atomically (the set file last, so a
/// reader never sees a set file whose layouts are not there). Returns the
/// set file's path.
pub fn write_set(dir: &Path, name: &str, layouts: &[Layout]) -> Result<PathBuf, SetError> {
    let mut files = Vec::with_capacity(layouts.len());
    for (k, layout) in layouts.iter().enumerate() {
        let file = format!("{name}-{}.json", k + 1);
        let path = dir.join(&file);
        let mut layout = layout.clone();
        layout.name = format!("{name}-{}", k + 1);
        layout
            .save_atomic(&path)
            .map_err(|source| SetError::Layout {
                set: dir.join(format!("{name}.set.json")),
                marker: path.clone(),
                source,
            })?;
        files.push(file);
    }
    let path = dir.join(format!("{name}.set.json"));
    crate::files::write_atomic(&path, set_file_json(name, &files).as_bytes()).map_err(
        |source| SetError::Io {
            action: "write",
            path: path.clone(),
            source,
        },
    )?;
    Ok(path)
}

/// Whether `a` and `b` are one marker: as many points, and a proper rigid
/// motion with a relabelling that puts every point of `a` within
/// `tolerance_mm` of a distinct point of `b`. A mirror image is not the
/// same marker (no proper rotation maps it).
pub fn same_marker(a: &[Vector3<f64>], b: &[Vector3<f64>], tolerance_mm: f64) -> bool {
    let n = a.len();
    if n != b.len() || n < 3 {
        return false;
    }
    // A well-conditioned triple of `a`: point 0, the farthest from it, and
    // the farthest from their line.
    let first = 0;
    let second = (1..n)
        .max_by(|&x, &y| {
            (a[x] - a[first])
                .norm()
                .total_cmp(&(a[y] - a[first]).norm())
        })
        .unwrap_or(1);
    let axis = (a[second] - a[first]).normalize();
    let off_line = |p: &Vector3<f64>| (p - a[first]).cross(&axis).norm();
    let third = (0..n)
        .filter(|&k| k != first && k != second)
        .max_by(|&x, &y| off_line(&a[x]).total_cmp(&off_line(&a[y])))
        .unwrap_or(2);
    let triple = [a[first], a[second], a[third]];
    let close = |x: f64, y: f64| (x - y).abs() <= 2.0 * tolerance_mm;
    let d01 = (triple[0] - triple[1]).norm();
    let d02 = (triple[0] - triple[2]).norm();
    let d12 = (triple[1] - triple[2]).norm();
    for p in 0..n {
        for q in 0..n {
            if q == p || !close((b[p] - b[q]).norm(), d01) {
                continue;
            }
            for r in 0..n {
                if r == p
                    || r == q
                    || !close((b[p] - b[r]).norm(), d02)
                    || !close((b[q] - b[r]).norm(), d12)
                {
                    continue;
                }
                let pose =
                    absolute_orientation(triple.iter().copied(), [b[p], b[q], b[r]].into_iter());
                let mut used = vec![false; n];
                let all = a.iter().all(|point| {
                    let mapped = pose.transform(point);
                    match (0..n)
                        .filter(|&k| !used[k])
                        .map(|k| (k, (b[k] - mapped).norm()))
                        .min_by(|x, y| x.1.total_cmp(&y.1))
                    {
                        Some((k, d)) if d <= tolerance_mm => {
                            used[k] = true;
                            true
                        }
                        _ => false,
                    }
                });
                if all {
                    return true;
                }
            }
        }
    }
    false
}

/// The best fit of another marker to one marker's noise-free blobs.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CrossPrediction {
    /// The cross margin: the residual norm of the rival's best fit over the
    /// blobs it explains, px; None when no blob set fits the rival within
    /// the gate, so the margin exceeds `gate_px`.
    pub margin_px: Option<f64>,
    /// The gate of the search, px (per blob).
    pub gate_px: f64,
    /// Predicted probability that the rival's fit beats the marker's own
    /// (for a margin above the gate, the gate's: an upper bound).
    pub confusion_probability: f64,
    /// The blob left out in the worst case (None: every blob seen).
    pub missing: Option<usize>,
    /// For each blob of the worst case, the rival's point it was given.
    pub labels: Option<Vec<usize>>,
    /// The rival's refitted pose in the worst case.
    #[serde(skip)]
    pub pose: Option<Pose>,
    /// Every blob set's best labelling within the gate, with its margin
    /// (px): what a dip search follows from this viewpoint
    /// ([`dips::find_dips`]).
    #[serde(skip)]
    pub fits: Vec<(Option<usize>, Vec<usize>, f64)>,
}

/// Predicts how well `rival` explains the noise-free view `observed`
/// (normalised, in object order) of `object` at `truth` with per-point
/// noise `sigmas_px`: the full blob set and each set with one blob missing
/// (module docs). `gate_px` bounds the search.
pub fn predict_cross(
    camera: &Camera,
    truth: &Pose,
    object: &[Vector3<f64>],
    observed: &[Vector2<f64>],
    sigmas_px: &[f64],
    rival: &[Vector3<f64>],
    gate_px: f64,
) -> CrossPrediction {
    let focal = camera.fx().min(camera.fy());
    let n = object.len();
    let sigma = sigmas_px.iter().copied().fold(0.0, f64::max);
    let mut worst = CrossPrediction {
        margin_px: None,
        gate_px,
        confusion_probability: normal_upper_tail(gate_px / (2.0 * sigma)),
        missing: None,
        labels: None,
        pose: None,
        fits: Vec::new(),
    };
    let dropped = (n > MIN_POINTS).then_some(0..n).into_iter().flatten();
    // The blob sets share most of their image triples: each is solved once.
    let mut poses = TriplePoses::new();
    for missing in std::iter::once(None).chain(dropped.map(Some)) {
        let m = n - usize::from(missing.is_some());
        if rival.len() < m || rival.len() - m > 1 {
            continue;
        }
        let options = UnlabelledOptions::with_gate_px(gate_px, focal, rival.len() - m);
        let Ok(found) = identify_without(rival, observed, missing, &options, &mut poses) else {
            continue;
        };
        let (margin, probability, pose) = fit_labelling(
            camera,
            truth,
            (object, observed, sigmas_px),
            rival,
            missing,
            &found.best.labels,
            &found.best.pose,
        );
        worst
            .fits
            .push((missing, found.best.labels.clone(), margin));
        // A fit within the gate replaces the gate's bound; among fits, the
        // most probable confusion (then the smaller margin) is kept.
        let worse = worst.margin_px.is_none_or(|w| {
            probability > worst.confusion_probability
                || (probability == worst.confusion_probability && margin < w)
        });
        if worse {
            worst = CrossPrediction {
                margin_px: Some(margin),
                gate_px,
                confusion_probability: probability,
                missing,
                labels: Some(found.best.labels.clone()),
                pose: Some(pose),
                fits: std::mem::take(&mut worst.fits),
            };
        }
    }
    worst
}

/// One labelling of a view refitted: `rival`'s points `labels` given to
/// the blobs of `object`'s view (`observed`, normalised, in object order,
/// with per-point noise; blob `missing` left out), the pose refined from
/// `start`. Returns the cross margin (px), the predicted probability that
/// this fit beats the marker's own, and the refitted pose.
fn fit_labelling(
    camera: &Camera,
    truth: &Pose,
    (object, observed, sigmas_px): (&[Vector3<f64>], &[Vector2<f64>], &[f64]),
    rival: &[Vector3<f64>],
    missing: Option<usize>,
    labels: &[usize],
    start: &Pose,
) -> (f64, f64, Pose) {
    let keep: Vec<usize> = (0..object.len()).filter(|&k| Some(k) != missing).collect();
    let view: Vec<Vector2<f64>> = keep.iter().map(|&k| observed[k]).collect();
    let assigned: Vec<Vector3<f64>> = labels.iter().map(|&l| rival[l]).collect();
    let own: Vec<Vector3<f64>> = keep.iter().map(|&k| object[k]).collect();
    let sigmas: Vec<f64> = keep.iter().map(|&k| sigmas_px[k]).collect();
    let pose = ml::refine(start, &assigned, &view);
    let (margin, probability) =
        wrong_probability(camera, truth, &pose, &own, &assigned, &view, &sigmas);
    (margin, probability, pose)
}

/// A marker's noise-free view: its blobs (normalised, in object order)
/// and their noise σ (px).
pub type SeenView = (Vec<Vector2<f64>>, Vec<f64>);

/// Marker `target`'s noise-free view in `scenario` when it is visible
/// there.
pub fn seen_view(
    target: &Target,
    scenario: &Scenario,
    settings: &IdentifiabilitySettings,
) -> Option<SeenView> {
    let images = sphere_images(
        target.camera,
        &scenario.pose(),
        target.object,
        target.sphere_diameter_mm,
    );
    if !visibility(&images, target.camera).is_visible() {
        return None;
    }
    let (_, normalised, sigmas) =
        clean_view(target, scenario, settings.observation, &settings.noise)?;
    let sigma = sigmas.iter().copied().fold(0.0, f64::max);
    (sigma > 0.0 && sigma.is_finite()).then_some((normalised, sigmas))
}

/// The predicted probability that one fixed confusion beats a marker's
/// own fit in `scenario`: the blobs of its `view` ([`seen_view`] of
/// `object`; blob `missing` left out) explained by `rival`'s points
/// `labels`, the pose refined from `start`. A repair prices a confusion
/// that a cross check found this way, without searching the labellings
/// again. None when the labels do not fit the blobs and the rival.
pub fn labelled_confusion(
    camera: &Camera,
    scenario: &Scenario,
    (object, view): (&[Vector3<f64>], &SeenView),
    rival: &[Vector3<f64>],
    (missing, labels, start): (Option<usize>, &[usize], &Pose),
) -> Option<f64> {
    let kept = object.len() - usize::from(missing.is_some());
    if labels.len() != kept
        || labels.iter().any(|&l| l >= rival.len())
        || view.0.len() != object.len()
    {
        return None;
    }
    let (_, probability, _) = fit_labelling(
        camera,
        &scenario.pose(),
        (object, &view.0, &view.1),
        rival,
        missing,
        labels,
        start,
    );
    Some(probability)
}

/// The cross prediction of one (marker, rival) pair in one scenario; None
/// when the marker is not visible there (or a sphere's image cannot be
/// made).
pub fn cross_scenario(
    target: &Target,
    rival: &[Vector3<f64>],
    scenario: &Scenario,
    settings: &IdentifiabilitySettings,
) -> Option<CrossPrediction> {
    let (normalised, sigmas) = seen_view(target, scenario, settings)?;
    let sigma = sigmas.iter().copied().fold(0.0, f64::max);
    Some(predict_cross(
        target.camera,
        &scenario.pose(),
        target.object,
        &normalised,
        &sigmas,
        rival,
        PREDICTION_GATE_SIGMAS * sigma,
    ))
}

/// One cell of the cross matrix: how marker `marker`'s views fare against
/// `rival`'s points.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CrossPair {
    /// The marker whose blobs are seen (row).
    pub marker: usize,
    /// The marker offered as the model (column).
    pub rival: usize,
    /// Scenarios in which `marker` is visible.
    pub visible: usize,
    /// The smallest cross margin over them, px; None when every one is
    /// above its gate.
    pub smallest_margin_px: Option<f64>,
    /// The largest predicted confusion probability.
    pub worst_confusion: f64,
    /// The mean predicted confusion probability (the expected confusion
    /// rate per viewpoint).
    pub mean_confusion: f64,
    /// Visible scenarios whose confusion probability is within the floor.
    pub cross_identifiable: usize,
    /// Grid indices of the scenarios that fail the floor.
    pub failing: Vec<usize>,
    /// Grid indices of the scenarios whose confusion probability exceeds
    /// [`NEAR_SHARE`] of the floor's criterion (those failing among them):
    /// the viewpoints a small change of either marker may make fail.
    #[serde(skip)]
    pub near: Vec<usize>,
    /// The labellings the check found within the gate, each with the
    /// viewpoints where it was found: where a dip search follows them from
    /// ([`dips::find_dips`]).
    #[serde(skip)]
    pub found: Vec<FoundLabelling>,
}

/// A labelling of the seen marker's blobs (blob `missing` left out) by the
/// rival's points `labels` that a cross check found within the gate.
#[derive(Debug, Clone, PartialEq)]
pub struct FoundLabelling {
    /// The blob left out (None: every blob).
    pub missing: Option<usize>,
    /// For each blob kept, in order, the rival point given to it.
    pub labels: Vec<usize>,
    /// The viewpoints (scenario index, margin px) where it was found, the
    /// smallest margins first, at most [`dips::NEAREST_SAMPLES`].
    pub at: Vec<(usize, f64)>,
}

/// Notes that labelling (`missing`, `labels`) was found at viewpoint
/// `index` with margin `margin_px` (px), keeping each labelling's
/// [`dips::NEAREST_SAMPLES`] smallest margins.
fn note_found(
    found: &mut Vec<FoundLabelling>,
    (missing, labels): (Option<usize>, &[usize]),
    index: usize,
    margin_px: f64,
) {
    let entry = match found
        .iter()
        .position(|f| f.missing == missing && f.labels == labels)
    {
        Some(k) => &mut found[k],
        None => {
            found.push(FoundLabelling {
                missing,
                labels: labels.to_vec(),
                at: Vec::new(),
            });
            found.last_mut().expect("just pushed")
        }
    };
    let at = entry
        .at
        .partition_point(|&(i, m)| m.total_cmp(&margin_px).then(i.cmp(&index)).is_lt());
    entry.at.insert(at, (index, margin_px));
    entry.at.truncate(dips::NEAREST_SAMPLES);
}

impl CrossPair {
    /// The share of visible scenarios that meet the floor (1 when none is
    /// visible).
    pub fn share(&self) -> f64 {
        if self.visible == 0 {
            1.0
        } else {
            self.cross_identifiable as f64 / self.visible as f64
        }
    }
}

/// The N×N cross matrix of a set over a scenario list.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CrossMatrix {
    /// The markers' names, in set order.
    pub markers: Vec<String>,
    /// The per-viewpoint floor (share of correct identifications).
    pub min_cross: f64,
    /// Every ordered pair (marker ≠ rival), row by row.
    pub pairs: Vec<CrossPair>,
}

impl CrossMatrix {
    /// The cell of row `marker`, column `rival`.
    pub fn pair(&self, marker: usize, rival: usize) -> Option<&CrossPair> {
        self.pairs
            .iter()
            .find(|p| p.marker == marker && p.rival == rival)
    }

    /// The smallest share of cross-identifiable scenarios over every pair.
    pub fn worst_share(&self) -> f64 {
        self.pairs.iter().map(CrossPair::share).fold(1.0, f64::min)
    }

    /// The smallest cross margin over every pair, px (None: all above the
    /// gate).
    pub fn smallest_margin_px(&self) -> Option<f64> {
        self.pairs
            .iter()
            .filter_map(|p| p.smallest_margin_px)
            .min_by(f64::total_cmp)
    }

    /// Whether every pair meets the floor in every visible scenario of the
    /// share the floor asks for.
    pub fn meets_floor(&self) -> bool {
        self.pairs.iter().all(|p| p.share() >= self.min_cross)
    }

    /// Adds `other`, a check of the same pairs over other scenarios, as if
    /// both had been one check.
    pub fn absorb(&mut self, other: CrossMatrix) {
        for theirs in other.pairs {
            let Some(ours) = self
                .pairs
                .iter_mut()
                .find(|p| p.marker == theirs.marker && p.rival == theirs.rival)
            else {
                self.pairs.push(theirs);
                continue;
            };
            let visible = ours.visible + theirs.visible;
            if visible > 0 {
                ours.mean_confusion = (ours.mean_confusion * ours.visible as f64
                    + theirs.mean_confusion * theirs.visible as f64)
                    / visible as f64;
            }
            ours.visible = visible;
            ours.smallest_margin_px = match (ours.smallest_margin_px, theirs.smallest_margin_px) {
                (Some(a), Some(b)) => Some(a.min(b)),
                (a, b) => a.or(b),
            };
            ours.worst_confusion = ours.worst_confusion.max(theirs.worst_confusion);
            ours.cross_identifiable += theirs.cross_identifiable;
            ours.failing.extend(theirs.failing);
            ours.near.extend(theirs.near);
            for f in theirs.found {
                for (index, margin) in f.at {
                    note_found(&mut ours.found, (f.missing, &f.labels), index, margin);
                }
            }
        }
    }
}

/// The cross matrix of `targets` (one camera) over `scenarios`, in
/// parallel; the result does not depend on the thread count.
pub fn cross_matrix(
    targets: &[Target],
    names: &[String],
    scenarios: &[Scenario],
    settings: &IdentifiabilitySettings,
) -> CrossMatrix {
    cross_pairs(
        targets,
        names,
        scenarios,
        settings,
        &all_pairs(targets.len()),
    )
}

/// Every ordered pair (marker, rival) of `n` markers, row by row.
pub fn all_pairs(n: usize) -> Vec<(usize, usize)> {
    (0..n)
        .flat_map(|i| (0..n).filter(move |&j| j != i).map(move |j| (i, j)))
        .collect()
}

/// [`cross_matrix`] over the ordered `pairs` (marker, rival) alone: a
/// set designed marker by marker checks only the pairs of its newest
/// marker.
pub fn cross_pairs(
    targets: &[Target],
    names: &[String],
    scenarios: &[Scenario],
    settings: &IdentifiabilitySettings,
    pairs: &[(usize, usize)],
) -> CrossMatrix {
    let cells: Vec<Vec<Option<CrossPrediction>>> = scenarios
        .par_iter()
        .map(|s| {
            pairs
                .iter()
                .map(|&(i, j)| cross_scenario(&targets[i], targets[j].object, s, settings))
                .collect()
        })
        .collect();
    let max_wrong = settings.max_wrong();
    let pairs = pairs
        .iter()
        .enumerate()
        .map(|(k, &(i, j))| {
            let mut pair = CrossPair {
                marker: i,
                rival: j,
                visible: 0,
                smallest_margin_px: None,
                worst_confusion: 0.0,
                mean_confusion: 0.0,
                cross_identifiable: 0,
                failing: Vec::new(),
                near: Vec::new(),
                found: Vec::new(),
            };
            let mut sum = 0.0;
            for (s, row) in scenarios.iter().zip(&cells) {
                let Some(prediction) = &row[k] else {
                    continue;
                };
                pair.visible += 1;
                sum += prediction.confusion_probability;
                pair.worst_confusion = pair.worst_confusion.max(prediction.confusion_probability);
                if let Some(margin) = prediction.margin_px {
                    pair.smallest_margin_px = Some(
                        pair.smallest_margin_px
                            .map_or(margin, |m: f64| m.min(margin)),
                    );
                }
                if prediction.confusion_probability <= max_wrong {
                    pair.cross_identifiable += 1;
                } else {
                    pair.failing.push(s.index);
                }
                if prediction.confusion_probability > NEAR_SHARE * max_wrong {
                    pair.near.push(s.index);
                }
                for (missing, labels, margin) in &prediction.fits {
                    note_found(&mut pair.found, (*missing, labels), s.index, *margin);
                }
            }
            if pair.visible > 0 {
                pair.mean_confusion = sum / pair.visible as f64;
            }
            pair
        })
        .collect();
    CrossMatrix {
        markers: names.to_vec(),
        min_cross: settings.min_correct,
        pairs,
    }
}

/// Which marker of a set a blob group is, and its labels.
#[derive(Debug, Clone, PartialEq)]
pub struct SetIdentification {
    /// The marker (index in the set) whose labelling fits best.
    pub marker: usize,
    /// Its labelling.
    pub best: Labelling,
    /// The next best marker and its RMS (normalised), if any other marker
    /// fits within the gate.
    pub runner_up: Option<(usize, f64)>,
}

/// The unlabelled solver ([`identify`]) against every marker of a set; the
/// lowest reprojection RMS wins (ties: the lower index). Markers that
/// cannot take the blobs (fewer points than blobs, or more missing than
/// allowed) are skipped; the error is the first marker's when none fits.
pub fn identify_in_set(
    objects: &[Vec<Vector3<f64>>],
    image: &[Vector2<f64>],
    options: &UnlabelledOptions,
) -> Result<SetIdentification, LabellingError> {
    let mut fits: Vec<(usize, Labelling)> = Vec::new();
    let mut first_error = None;
    for (j, object) in objects.iter().enumerate() {
        match identify(object, image, options) {
            Ok(found) => fits.push((j, found.best)),
            Err(e) => {
                first_error.get_or_insert(e);
            }
        }
    }
    fits.sort_by(|a, b| a.1.rms.total_cmp(&b.1.rms).then(a.0.cmp(&b.0)));
    let mut fits = fits.into_iter();
    match fits.next() {
        Some((marker, best)) => Ok(SetIdentification {
            marker,
            best,
            runner_up: fits.next().map(|(j, l)| (j, l.rms)),
        }),
        None => Err(first_error.unwrap_or(LabellingError::NoConsistentLabelling { hypotheses: 0 })),
    }
}

/// Seeded trials of a set, per marker.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct SetTrialCounts {
    /// Trials run (over the marker's visible scenarios).
    pub trials: usize,
    /// Trials that named another marker.
    pub wrong_marker: usize,
    /// Trials that named this marker with a wrong label.
    pub wrong_labels: usize,
    /// Trials in which no marker fitted.
    pub failed: usize,
    /// Visible scenarios in which at least one trial named another marker.
    pub confused_scenarios: usize,
    /// Visible scenarios with trials.
    pub scenarios: usize,
}

impl SetTrialCounts {
    /// The share of trials that named another marker.
    pub fn confusion_rate(&self) -> Option<f64> {
        (self.trials > 0).then(|| self.wrong_marker as f64 / self.trials as f64)
    }
}

/// Runs `settings.trials` noisy, shuffled trials of every marker in every
/// scenario where it is visible, each identified against the whole set
/// ([`identify_in_set`]); also the counts of which marker each trial named
/// (`named[i][j]`: trials of marker `i` that named `j`).
pub fn set_trials(
    targets: &[Target],
    scenarios: &[Scenario],
    settings: &IdentifiabilitySettings,
) -> (Vec<SetTrialCounts>, Vec<Vec<usize>>) {
    let objects: Vec<Vec<Vector3<f64>>> = targets.iter().map(|t| t.object.to_vec()).collect();
    let n_markers = targets.len();
    let jobs: Vec<(usize, &Scenario)> = (0..n_markers)
        .flat_map(|i| scenarios.iter().map(move |s| (i, s)))
        .collect();
    let results: Vec<Option<ScenarioTrials>> = jobs
        .par_iter()
        .map(|&(i, s)| trial_scenario(&targets[i], i, &objects, (s, None), settings))
        .collect();
    let mut counts = vec![SetTrialCounts::default(); n_markers];
    let mut named = vec![vec![0usize; n_markers]; n_markers];
    for (&(i, _), result) in jobs.iter().zip(&results) {
        let Some((trials, markers, wrong_labels)) = result else {
            continue;
        };
        let c = &mut counts[i];
        c.scenarios += 1;
        c.trials += trials;
        c.wrong_labels += wrong_labels;
        let mut confused = false;
        for m in markers {
            match m {
                Some(j) => {
                    named[i][*j] += 1;
                    if *j != i {
                        c.wrong_marker += 1;
                        confused = true;
                    }
                }
                None => c.failed += 1,
            }
        }
        if confused {
            c.confused_scenarios += 1;
        }
    }
    (counts, named)
}

/// One marker's trials in one scenario: trials, the marker each named (None:
/// no marker fitted), wrong-label trials.
type ScenarioTrials = (usize, Vec<Option<usize>>, usize);

/// Seeded trials of marker `index` of a set in `scenario` with blob
/// `missing` left out of every frame (None: every blob seen), each
/// identified against the whole set with that blob allowed missing: how
/// often a confusion predicted at a dip ([`dips`]) happens. Returns the
/// trials run and those that named another marker; None when the marker
/// is not visible there.
pub fn missing_blob_trials(
    targets: &[Target],
    index: usize,
    scenario: &Scenario,
    missing: Option<usize>,
    settings: &IdentifiabilitySettings,
) -> Option<(usize, usize)> {
    let objects: Vec<Vec<Vector3<f64>>> = targets.iter().map(|t| t.object.to_vec()).collect();
    let (trials, named, _) = trial_scenario(
        &targets[index],
        index,
        &objects,
        (scenario, missing),
        settings,
    )?;
    let wrong = named
        .iter()
        .filter(|m| m.is_some_and(|j| j != index))
        .count();
    Some((trials, wrong))
}

/// One marker's trials in one scenario, blob `missing` left out of every
/// frame (and one missing blob then allowed); None when the marker is not
/// visible.
fn trial_scenario(
    target: &Target,
    index: usize,
    objects: &[Vec<Vector3<f64>>],
    (scenario, missing): (&Scenario, Option<usize>),
    settings: &IdentifiabilitySettings,
) -> Option<ScenarioTrials> {
    let camera = target.camera;
    let images = sphere_images(
        camera,
        &scenario.pose(),
        target.object,
        target.sphere_diameter_mm,
    );
    if !visibility(&images, camera).is_visible() || settings.trials == 0 {
        return None;
    }
    let (pixels, _, sigmas) = clean_view(target, scenario, settings.observation, &settings.noise)?;
    let sigma = sigmas.iter().copied().fold(0.0, f64::max);
    let focal = camera.fx().min(camera.fy());
    let options = UnlabelledOptions::with_gate_px(
        (TRIAL_GATE_SIGMAS * sigma).max(MIN_TRIAL_GATE_PX),
        focal,
        usize::from(missing.is_some()),
    );
    let n = pixels.len();
    // Trials with a blob left out draw from streams of their own.
    let stream = CROSS_STREAM
        + ((index as u64) << 32)
        + scenario.index as u64
        + missing.map_or(0, |k| (k as u64 + 1) << 40);
    let mut order: Vec<usize> = (0..n).filter(|&k| Some(k) != missing).collect();
    let mut named = Vec::with_capacity(settings.trials);
    let mut wrong_labels = 0;
    for trial in 0..settings.trials {
        let mut rng = stream_rng(settings.seed, stream, trial as u64);
        let mut noisy = Vec::with_capacity(n);
        for (pixel, sigma) in pixels.iter().zip(&sigmas) {
            let [dx, dy] = settings.noise.draw(&mut rng, *sigma);
            match camera.pixel_to_normalised(&Vector2::new(pixel.x + dx, pixel.y + dy)) {
                Ok(m) => noisy.push(m),
                Err(_) => break,
            }
        }
        if noisy.len() < n {
            named.push(None);
            continue;
        }
        let mut shuffle = stream_rng(settings.seed, stream ^ (1 << 62), trial as u64);
        order.shuffle(&mut shuffle);
        let shuffled: Vec<Vector2<f64>> = order.iter().map(|&k| noisy[k]).collect();
        // (`order` holds the kept blobs' object indices: the true labels.)
        match identify_in_set(objects, &shuffled, &options) {
            Ok(found) => {
                if found.marker == index && found.best.labels != order {
                    wrong_labels += 1;
                }
                named.push(Some(found.marker));
            }
            Err(_) => named.push(None),
        }
    }
    Some((settings.trials, named, wrong_labels))
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Rotation3;

    fn marker() -> Vec<Vector3<f64>> {
        vec![
            Vector3::new(0.0, 0.0, 0.0),
            Vector3::new(60.0, 5.0, 0.0),
            Vector3::new(-10.0, 45.0, 10.0),
            Vector3::new(20.0, -30.0, 40.0),
            Vector3::new(-35.0, -15.0, -25.0),
            Vector3::new(30.0, 35.0, -30.0),
        ]
    }

    #[test]
    fn a_moved_relabelled_copy_is_the_same_marker_and_a_mirror_is_not() {
        let a = marker();
        let motion = Pose::new(
            Rotation3::from_euler_angles(0.4, -1.1, 2.0),
            Vector3::new(5.0, -7.0, 12.0),
        );
        let mut b: Vec<Vector3<f64>> = a.iter().map(|p| motion.transform(p)).collect();
        b.reverse();
        assert!(same_marker(&a, &b, IDENTICAL_TOLERANCE_MM));
        let mirror: Vec<Vector3<f64>> = a.iter().map(|p| Vector3::new(-p.x, p.y, p.z)).collect();
        assert!(!same_marker(&a, &mirror, IDENTICAL_TOLERANCE_MM));
        let mut moved = a.clone();
        moved[3].z += 0.5;
        assert!(!same_marker(&a, &moved, IDENTICAL_TOLERANCE_MM));
    }

    /// Blobs that two markers of a set fit about as well are given to
    /// neither: a near copy of the marker (one point 0.2 mm off) against
    /// noisy blobs of the marker; with the copy's point 30 mm off (the
    /// copy then explains one blob fewer), the marker is placed.
    #[test]
    fn blobs_two_markers_fit_alike_are_given_to_neither() {
        use rand::SeedableRng;
        use rand_distr::{Distribution, Normal};
        let a = marker();
        let pose = Pose::new(
            Rotation3::from_euler_angles(0.3, -0.2, 0.5),
            Vector3::new(10.0, -5.0, 500.0),
        );
        let focal = 1300.0;
        let noise = Normal::new(0.0, 0.3 / focal).unwrap();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(4);
        let image: Vec<Vector2<f64>> = a
            .iter()
            .map(|p| {
                let c = pose.transform(p);
                Vector2::new(c.x / c.z, c.y / c.z)
                    + Vector2::new(noise.sample(&mut rng), noise.sample(&mut rng))
            })
            .collect();
        let options = UnlabelledOptions::with_gate_px(2.5, focal, 1);
        for (offset_mm, placed) in [(0.2, false), (30.0, true)] {
            let mut copy = a.clone();
            copy[2].x += offset_mm;
            let grouping = grouping(&[a.clone(), copy], &image, &options);
            let markers: Vec<usize> = grouping.placements.iter().map(|p| p.marker).collect();
            if placed {
                assert_eq!(markers, [0], "{grouping:?}");
                assert!(grouping.ambiguous.is_empty());
            } else {
                assert!(markers.is_empty(), "{grouping:?}");
                assert_eq!(grouping.ambiguous.len(), 1, "{grouping:?}");
            }
        }
    }

    /// A check over two halves of a grid, one absorbed into the other,
    /// is the check over the whole grid: counts, extremes, the mean, the
    /// failing and near viewpoints, and every labelling found with its
    /// smallest margins.
    #[test]
    fn a_check_absorbed_into_another_is_one_check_over_both() {
        use crate::identifiability::IdentifiabilitySettings;
        use crate::noise::NoiseModel;
        use crate::scenario::ScenarioGrid;
        use crate::sphere_image::Observation;
        let camera = Camera::paper();
        let a = marker();
        // A near copy: confused in some viewpoints, not in others.
        let mut b = a.clone();
        b[1].x += 3.0;
        b[4].y -= 4.0;
        b[2].z += 2.5;
        let scenarios = ScenarioGrid::new(
            "300,600,900".parse().unwrap(),
            "0,40".parse().unwrap(),
            "0".parse().unwrap(),
            "-40,-10,20,50".parse().unwrap(),
            "0".parse().unwrap(),
            "0".parse().unwrap(),
            "0.5".parse().unwrap(),
        )
        .unwrap()
        .scenarios();
        let sigmas = vec![None; a.len()];
        let objects = [a, b];
        let targets: Vec<Target> = objects
            .iter()
            .map(|object| Target {
                camera: &camera,
                object,
                sphere_diameter_mm: 8.0,
                point_sigma_px: &sigmas,
            })
            .collect();
        let settings = IdentifiabilitySettings {
            min_correct: 0.999,
            trials: 0,
            seed: 5,
            observation: Observation::Centre,
            noise: NoiseModel::default(),
        };
        let names = ["a".to_string(), "b".to_string()];
        let whole = cross_matrix(&targets, &names, &scenarios, &settings);
        let (first, second) = scenarios.split_at(scenarios.len() / 3);
        let mut joined = cross_matrix(&targets, &names, first, &settings);
        joined.absorb(cross_matrix(&targets, &names, second, &settings));
        assert!(whole.pairs.iter().any(|p| !p.failing.is_empty()));
        assert!(whole.pairs.iter().any(|p| p.cross_identifiable > 0));
        for (w, j) in whole.pairs.iter().zip(&joined.pairs) {
            assert!(!w.found.is_empty());
            assert!((w.mean_confusion - j.mean_confusion).abs() <= 1e-12 * w.mean_confusion);
            let mean = CrossPair {
                mean_confusion: w.mean_confusion,
                ..j.clone()
            };
            assert_eq!(w, &mean);
        }
    }
}
