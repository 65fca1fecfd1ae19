//! Unlabelled pose: which image blob is which object point, from the
//! layout's geometry alone, and the pose that goes with it.
//!
//! **Problem.** Given the object points of a marker and an *unordered* set
//! of image points (normalised, see [`crate::pnp`]), possibly missing up to
//! [`UnlabelledOptions::max_missing`] blobs, find the labelling (for each
//! image point, its object point) whose pose reprojects every blob best,
//! and say how close the best *other* geometrically consistent labelling
//! comes ([`Identification::ambiguity`]).
//!
//! **Method** (hypothesise and verify, as RANSAC-style P3P matchers do):
//! 1. Take the image triple of largest area (the best-conditioned P3P).
//! 2. For every ordered triple of object points, solve P3P
//!    ([`super::p3p`], Lambda Twist); every pose with the triple in front is
//!    one hypothesis.
//! 3. Project every object point under the hypothesis and give each other
//!    image point the nearest projection not yet taken. The hypothesis dies
//!    as soon as one blob is farther than the screening gate
//!    ([`SCREENING_FACTOR`] × `gate`: the pose of a noisy triple
//!    extrapolates its noise to the other points).
//! 4. A surviving labelling is refined by
//!    Levenberg–Marquardt on all its matched points ([`super::ml::refine`],
//!    the maximum-likelihood pose) and kept if every matched blob then lies
//!    within `gate` of its reprojection: it is *geometrically consistent*.
//! 5. The consistent labellings are ranked by their refined reprojection
//!    RMS (each distinct labelling once, with its lowest RMS); the first is
//!    the answer, the second the runner-up.
//!
//! If the first image triple yields no consistent labelling, or only ones
//! that barely pass the gate ([`SETTLED_FRACTION`]), the next largest
//! triples are tried too, up to [`MAX_IMAGE_TRIPLES`].
//!
//! Cost: `n (n−1) (n−2)` P3P solves of up to four roots, each verified with
//! early exit; no allocation inside the hypothesis loop (scratch buffers are
//! allocated once per call).
//!
//! ```
//! use layout_opt_solvers::pnp::unlabelled::{identify, UnlabelledOptions};
//! use layout_opt_solvers::pose::Pose;
//! use layout_opt_solvers::synthetic::biprism_points;
//! use nalgebra::{Rotation3, Vector2, Vector3};
//!
//! // An asymmetric 6-point marker, mm.
//! let object = [
//!     Vector3::new(0.0, 0.0, 0.0),
//!     Vector3::new(60.0, 5.0, 0.0),
//!     Vector3::new(-10.0, 45.0, 10.0),
//!     Vector3::new(20.0, -30.0, 40.0),
//!     Vector3::new(-35.0, -15.0, -25.0),
//!     Vector3::new(30.0, 35.0, -30.0),
//! ];
//! let truth = Pose::new(Rotation3::from_euler_angles(0.5, -0.3, 0.2), Vector3::new(15.0, -5.0, 400.0));
//! // The blobs in some order the detector chose.
//! let order = [3, 0, 5, 2, 1, 4];
//! let image: Vec<Vector2<f64>> = order.iter().map(|&k| truth.project_normalised(&object[k])).collect();
//! let found = identify(&object, &image, &UnlabelledOptions::default())?;
//! assert_eq!(found.best.labels, order);
//! assert!(found.ambiguity().is_none_or(|a| a > 10.0));
//!
//! // The paper's biprism is an octahedron with its centre: every view has
//! // 24 labellings that fit exactly, and the ambiguity says so.
//! let biprism = biprism_points(50.0);
//! let image: Vec<Vector2<f64>> = biprism.iter().map(|p| truth.project_normalised(p)).collect();
//! let found = identify(&biprism, &image, &UnlabelledOptions::default())?;
//! assert!((found.ambiguity().unwrap() - 1.0).abs() < 1e-6);
//! # Ok::<(), layout_opt_solvers::pnp::unlabelled::LabellingError>(())
//! ```

// `!(x > 0.0)` is deliberate throughout: it is true for NaN as well, so
// a non-finite intermediate rejects a root rather than passing it.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

use super::ml;
use super::p3p::{self, P3pCandidates};
use super::{check_finite, check_image_spread, check_scale, PnpError};
use crate::pose::Pose;
use crate::spread::{Spread, DUPLICATE_TOLERANCE, PLANARITY_TOLERANCE};
use nalgebra::{Vector2, Vector3};

/// Human name of the method.
pub const NAME: &str = "unlabelled identification";
/// Fewest object points (and image points) accepted: with three, every
/// P3P root is a consistent labelling and nothing can be decided.
pub const MIN_POINTS: usize = 4;
/// Most object points accepted (labels are tracked in a 64-bit set).
pub const MAX_POINTS: usize = 64;
/// The screening gate is this many times `gate`. The P3P pose of the image
/// triple fits those three blobs exactly, so their noise goes unaveraged
/// into the other points' predictions; at σ = 0.5 px a factor of 4 keeps
/// the true labelling on the near-field sets we test (see the tests), and
/// the final decision uses `gate` itself on the refined pose.
pub const SCREENING_FACTOR: f64 = 4.0;
/// Image triples tried, largest area first, while none has produced a
/// labelling with RMS below [`SETTLED_FRACTION`] of the gate.
pub const MAX_IMAGE_TRIPLES: usize = 4;
/// The search stops after an image triple whose best consistent labelling
/// has an RMS below this fraction of the gate. A labelling that only just
/// passes the gate may be a wrong one standing in for a true root that the
/// triple's P3P lost (a near-degenerate view of that triple): the next
/// triple is tried then. With the gate at 5–6σ, this stops at 1.5–1.8σ;
/// the true labelling of 7 points has an RMS of about 1.07σ, so most calls
/// stop after one triple. Measured on the 7-point search winner over
/// 200–1000 mm at σ = 0.5 px with a 6σ gate (`layout-opt validate
/// layouts/biprism-search.json --depth 200..1000 --offset-x 0..100 --tilt
/// -60..60:10 --solvers ml --trials 50`, the identifiability section's
/// `missed` count: trials ending on a labelling that fits worse than the
/// truth, of 38,200): 52 at 0.5, 12 at 0.42, none at 0.35, 0.3 and 0.25.
/// 0.3 keeps a margin; `cargo bench --bench unlabelled` for n = 7 reads
/// 0.70 ms at 0.35, 0.77 ms at 0.3 and 1.06 ms at 0.25 (idle machine).
pub const SETTLED_FRACTION: f64 = 0.3;
/// [`Identification::ambiguity`] counts RMS values below this (normalised
/// units, 1e-9 px on a 1000 px focal length) as this: rounding-level fits
/// are equally exact, so two of them have ambiguity 1 and a noise-free fit
/// beside a wrong one a large finite ratio.
pub const MIN_RMS: f64 = 1e-12;
/// The gate of [`UnlabelledOptions::default`], normalised units: 2.5 px on
/// a 1300 px focal length (the paper's camera), 5σ at σ = 0.5 px.
pub const DEFAULT_GATE: f64 = 2.5 / 1300.0;

/// How the search decides consistency.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct UnlabelledOptions {
    /// Per-point reprojection gate on the normalised image plane: a labelling is
    /// geometrically consistent when every matched image point lies within `gate`
    /// of its reprojection under the labelling's pose.
    pub gate: f64,
    /// How many object points may have no blob (0 or 1).
    pub max_missing: usize,
}

impl Default for UnlabelledOptions {
    /// [`DEFAULT_GATE`], one missing blob allowed.
    fn default() -> Self {
        Self {
            gate: DEFAULT_GATE,
            max_missing: 1,
        }
    }
}

impl UnlabelledOptions {
    /// Options with a gate given in pixels for a camera of focal length
    /// `focal_px` (the smaller of fx, fy when they differ).
    pub fn with_gate_px(gate_px: f64, focal_px: f64, max_missing: usize) -> Self {
        Self {
            gate: gate_px / focal_px,
            max_missing,
        }
    }
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
    /// The consistent labelling with the lowest refined RMS.
    pub best: Labelling,
    /// Best geometrically consistent labelling whose labels differ from `best`'s.
    pub runner_up: Option<Labelling>,
    /// Number of P3P hypotheses tried (for reports and benches).
    pub hypotheses: usize,
}

impl Identification {
    /// `runner_up.rms / best.rms` (each at least [`MIN_RMS`]): near 1, two
    /// labellings explain the image equally well (a symmetric view); `None`
    /// when no other labelling is consistent.
    pub fn ambiguity(&self) -> Option<f64> {
        self.runner_up
            .as_ref()
            .map(|r| r.rms.max(MIN_RMS) / self.best.rms.max(MIN_RMS))
    }
}

/// Why the blobs could not be labelled: input that no PnP method could
/// use ([`PnpError`]), or a problem that only unlabelled blobs have.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum LabellingError {
    /// The object or image points are not usable input for PnP (too few,
    /// non-finite, coincident, collinear, badly scaled).
    Pnp(PnpError),
    /// More image blobs than object points.
    TooManyBlobs {
        /// Number of object points.
        object: usize,
        /// Number of image points.
        image: usize,
    },
    /// More object points without a blob than allowed.
    TooManyMissing {
        /// Number of object points.
        object: usize,
        /// Number of image points.
        image: usize,
        /// Most object points allowed to have no blob.
        max_missing: usize,
    },
    /// Two blobs at the same place.
    DuplicateBlobs {
        /// Index of the first blob.
        first: usize,
        /// Index of the second blob.
        second: usize,
    },
    /// The reprojection gate must be a positive distance.
    BadGate {
        /// The gate given (normalised units).
        gate: f64,
    },
    /// No labelling puts every blob within the gate of its reprojection.
    NoConsistentLabelling {
        /// P3P hypotheses tried.
        hypotheses: usize,
    },
}

impl std::fmt::Display for LabellingError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            // Transparent: the PnP error's own message.
            LabellingError::Pnp(error) => std::fmt::Display::fmt(error, f),
            LabellingError::TooManyBlobs { object, image } => write!(
                f,
                "{image} image points but only {object} object points: every blob must be one of the object points"
            ),
            LabellingError::TooManyMissing {
                object,
                image,
                max_missing,
            } => write!(
                f,
                "{image} image points for {object} object points: {} missing, at most {max_missing} allowed",
                object - image
            ),
            LabellingError::DuplicateBlobs { first, second } => {
                write!(f, "image points {first} and {second} coincide")
            }
            LabellingError::BadGate { gate } => write!(
                f,
                "the reprojection gate must be a positive finite distance, got {gate}"
            ),
            LabellingError::NoConsistentLabelling { hypotheses } => write!(
                f,
                "no labelling of the image points is geometrically consistent with the object points ({hypotheses} P3P hypotheses tried); the blobs may not come from this marker, or the gate is too tight for the noise"
            ),
        }
    }
}

impl std::error::Error for LabellingError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            // Transparent: the PnP error stands in for this one, so its
            // source is this one's.
            LabellingError::Pnp(error) => std::error::Error::source(error),
            _ => None,
        }
    }
}

impl From<PnpError> for LabellingError {
    fn from(error: PnpError) -> Self {
        LabellingError::Pnp(error)
    }
}

/// Finds the labelling of `image` (unordered blobs, normalised coordinates)
/// against `object` and its pose; see the module docs.
///
/// Errors: fewer than [`MIN_POINTS`] object or image points, more than
/// [`MAX_POINTS`] object points, more blobs than object points, more missing
/// than `max_missing`, a bad gate, non-finite coordinates, coincident object
/// points or blobs, collinear object points, coincident or collinear blobs,
/// and no consistent labelling at all.
pub fn identify(
    object: &[Vector3<f64>],
    image: &[Vector2<f64>],
    options: &UnlabelledOptions,
) -> Result<Identification, LabellingError> {
    validate(object, image, options)?;
    run_search(
        Search::new(object, image, options),
        options,
        |search, triple| search.run_triple(triple),
    )
}

/// The P3P poses of every ordered object triple against image triples of
/// one image, kept for [`identify_without`] calls on that image with
/// different blobs left out: the calls share every image triple their
/// searches have in common, and solve it once.
#[derive(Debug, Default)]
pub struct TriplePoses {
    /// Per image triple solved (indices into the whole image): each pose
    /// with its ordered object triple, in the order [`identify`] meets
    /// them.
    solved: Vec<([usize; 3], Vec<TriplePose>)>,
}

/// A P3P pose with the ordered object triple it came from.
type TriplePose = (Pose, [usize; 3]);

impl TriplePoses {
    /// An empty store.
    pub fn new() -> Self {
        Self::default()
    }

    /// The poses of image triple `key` (indices into `image`), solved on
    /// first use.
    fn poses(
        &mut self,
        object: &[Vector3<f64>],
        image: &[Vector2<f64>],
        key: [usize; 3],
    ) -> &[TriplePose] {
        let at = match self.solved.iter().position(|(k, _)| *k == key) {
            Some(at) => at,
            None => {
                let bearings = key.map(|i| Vector3::new(image[i].x, image[i].y, 1.0).normalize());
                let mut found = Vec::new();
                let mut poses = P3pCandidates::new();
                for_each_object_triple(object.len(), |[a, b, c]| {
                    p3p::solve_bearings(&[object[a], object[b], object[c]], &bearings, &mut poses);
                    found.extend(poses.iter().map(|pose| (*pose, [a, b, c])));
                });
                self.solved.push((key, found));
                self.solved.len() - 1
            }
        };
        &self.solved[at].1
    }
}

/// [`identify`] of `image` with blob `missing` left out (the result's
/// labels are for the blobs kept, in order), its P3P poses taken from
/// (and added to) `poses`, which must hold poses of this `object` and
/// `image` only. The result equals [`identify`]'s on the blobs kept.
pub fn identify_without(
    object: &[Vector3<f64>],
    image: &[Vector2<f64>],
    missing: Option<usize>,
    options: &UnlabelledOptions,
    poses: &mut TriplePoses,
) -> Result<Identification, LabellingError> {
    let kept: Vec<usize> = (0..image.len()).filter(|&i| Some(i) != missing).collect();
    let view: Vec<Vector2<f64>> = kept.iter().map(|&i| image[i]).collect();
    validate(object, &view, options)?;
    run_search(
        Search::new(object, &view, options),
        options,
        |search, triple| {
            let key = triple.map(|i| kept[i]);
            search.run_poses(triple, poses.poses(object, image, key));
        },
    )
}

/// Every ordered triple of distinct indices below `n`, in [`identify`]'s
/// order.
fn for_each_object_triple(n: usize, mut each: impl FnMut([usize; 3])) {
    for a in 0..n {
        for b in 0..n {
            if b == a {
                continue;
            }
            for c in 0..n {
                if c == a || c == b {
                    continue;
                }
                each([a, b, c]);
            }
        }
    }
}

/// The search over the image triples of `search`'s image, largest first,
/// each run by `run`, until a labelling settles it (module docs).
fn run_search(
    mut search: Search<'_>,
    options: &UnlabelledOptions,
    mut run: impl FnMut(&mut Search<'_>, [usize; 3]),
) -> Result<Identification, LabellingError> {
    for triple in image_triples(search.image) {
        run(&mut search, triple);
        if search
            .best
            .as_ref()
            .is_some_and(|best| best.rms <= SETTLED_FRACTION * options.gate)
        {
            break;
        }
    }
    let hypotheses = search.hypotheses;
    match search.best {
        Some(best) => Ok(Identification {
            best,
            runner_up: search.runner_up,
            hypotheses,
        }),
        None => Err(LabellingError::NoConsistentLabelling { hypotheses }),
    }
}

fn validate(
    object: &[Vector3<f64>],
    image: &[Vector2<f64>],
    options: &UnlabelledOptions,
) -> Result<(), LabellingError> {
    if !(options.gate > 0.0 && options.gate.is_finite()) {
        return Err(LabellingError::BadGate { gate: options.gate });
    }
    if object.len() < MIN_POINTS {
        return Err(LabellingError::Pnp(PnpError::TooFewPoints {
            solver: NAME,
            needed: MIN_POINTS,
            got: object.len(),
        }));
    }
    if object.len() > MAX_POINTS {
        return Err(LabellingError::Pnp(PnpError::TooManyPoints {
            solver: NAME,
            max: MAX_POINTS,
            got: object.len(),
        }));
    }
    if image.len() > object.len() {
        return Err(LabellingError::TooManyBlobs {
            object: object.len(),
            image: image.len(),
        });
    }
    if object.len() - image.len() > options.max_missing {
        return Err(LabellingError::TooManyMissing {
            object: object.len(),
            image: image.len(),
            max_missing: options.max_missing,
        });
    }
    if image.len() < MIN_POINTS {
        return Err(LabellingError::Pnp(PnpError::TooFewPoints {
            solver: NAME,
            needed: MIN_POINTS,
            got: image.len(),
        }));
    }
    check_finite(object, image)?;
    let centroid = object.iter().sum::<Vector3<f64>>() / object.len() as f64;
    let magnitude = object
        .iter()
        .map(|p| (p - centroid).amax())
        .fold(0.0, f64::max);
    if magnitude == 0.0 {
        return Err(LabellingError::Pnp(PnpError::DuplicatePoints {
            first: 0,
            second: 1,
        }));
    }
    check_scale("object", magnitude)?;
    let spread = Spread::of(object);
    let duplicate_sq = (DUPLICATE_TOLERANCE * spread.extents[0]).powi(2);
    for (i, a) in object.iter().enumerate() {
        for (j, b) in object.iter().enumerate().skip(i + 1) {
            if (a - b).norm_squared() <= duplicate_sq {
                return Err(LabellingError::Pnp(PnpError::DuplicatePoints {
                    first: i,
                    second: j,
                }));
            }
        }
    }
    if spread.extents[1] <= PLANARITY_TOLERANCE * spread.extents[0] {
        return Err(LabellingError::Pnp(PnpError::Collinear));
    }
    let image_magnitude = image.iter().map(|m| m.amax()).fold(0.0, f64::max);
    if image_magnitude > super::MAX_COORDINATE_SCALE {
        return Err(LabellingError::Pnp(PnpError::BadScale {
            kind: "image",
            magnitude: image_magnitude,
        }));
    }
    check_image_spread(image)?;
    for (i, a) in image.iter().enumerate() {
        for (j, b) in image.iter().enumerate().skip(i + 1) {
            if a == b {
                return Err(LabellingError::DuplicateBlobs {
                    first: i,
                    second: j,
                });
            }
        }
    }
    Ok(())
}

/// Up to [`MAX_IMAGE_TRIPLES`] image triples with non-collinear bearings,
/// largest triangle area first (ties by index, so the order is fixed).
fn image_triples(image: &[Vector2<f64>]) -> Vec<[usize; 3]> {
    let mut triples: Vec<(f64, [usize; 3])> = Vec::new();
    for i in 0..image.len() {
        for j in i + 1..image.len() {
            for k in j + 1..image.len() {
                let area = (image[j] - image[i]).perp(&(image[k] - image[i])).abs();
                triples.push((area, [i, j, k]));
            }
        }
    }
    triples.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
    triples
        .into_iter()
        .filter(|(_, t)| {
            p3p::bearings_span_space(
                &t.map(|i| Vector3::new(image[i].x, image[i].y, 1.0).normalize()),
            )
        })
        .take(MAX_IMAGE_TRIPLES)
        .map(|(_, t)| t)
        .collect()
}

/// The search state: inputs, scratch buffers and the two best labellings.
struct Search<'a> {
    object: &'a [Vector3<f64>],
    image: &'a [Vector2<f64>],
    gate_sq: f64,
    screening_gate_sq: f64,
    /// Projections of the object points under the current hypothesis
    /// (`None` behind the camera).
    projections: Vec<Option<Vector2<f64>>>,
    labels: Vec<usize>,
    matched_object: Vec<Vector3<f64>>,
    /// Every labelling refined so far (`image.len()` labels each) and the
    /// screening cost of the hypothesis it was refined from.
    refined: Vec<usize>,
    refined_costs: Vec<f64>,
    /// Screening cost (sum of squared blob distances) of the current
    /// hypothesis.
    screening_cost: f64,
    best: Option<Labelling>,
    runner_up: Option<Labelling>,
    hypotheses: usize,
}

impl<'a> Search<'a> {
    fn new(
        object: &'a [Vector3<f64>],
        image: &'a [Vector2<f64>],
        options: &UnlabelledOptions,
    ) -> Self {
        Self {
            object,
            image,
            gate_sq: options.gate * options.gate,
            screening_gate_sq: (SCREENING_FACTOR * options.gate).powi(2),
            projections: vec![None; object.len()],
            labels: vec![0; image.len()],
            matched_object: Vec::with_capacity(image.len()),
            refined: Vec::new(),
            refined_costs: Vec::new(),
            screening_cost: 0.0,
            best: None,
            runner_up: None,
            hypotheses: 0,
        }
    }

    /// Every ordered object triple against the image triple.
    fn run_triple(&mut self, triple: [usize; 3]) {
        let bearings =
            triple.map(|i| Vector3::new(self.image[i].x, self.image[i].y, 1.0).normalize());
        let object = self.object;
        let mut poses = P3pCandidates::new();
        for_each_object_triple(object.len(), |[a, b, c]| {
            p3p::solve_bearings(&[object[a], object[b], object[c]], &bearings, &mut poses);
            for pose in &poses {
                self.hypothesis(pose, triple, [a, b, c]);
            }
        });
    }

    /// The image triple against poses already solved for it, each with
    /// its object triple.
    fn run_poses(&mut self, triple: [usize; 3], poses: &[TriplePose]) {
        for (pose, object_triple) in poses {
            self.hypothesis(pose, triple, *object_triple);
        }
    }

    /// One hypothesis: screened, then refined and ranked if it passes.
    fn hypothesis(&mut self, pose: &Pose, triple: [usize; 3], object_triple: [usize; 3]) {
        self.hypotheses += 1;
        if self.assign(pose, triple, object_triple) {
            self.verify(pose);
        }
    }

    /// Labels every image point under `pose`: the triple as hypothesised,
    /// each other blob the nearest unused projection. False as soon as a
    /// blob is beyond the screening gate.
    fn assign(&mut self, pose: &Pose, triple: [usize; 3], object_triple: [usize; 3]) -> bool {
        let mut used: u64 = 0;
        for (&i, &k) in triple.iter().zip(&object_triple) {
            self.labels[i] = k;
            used |= 1 << k;
        }
        for (k, p) in self.object.iter().enumerate() {
            self.projections[k] = if used & (1 << k) != 0 {
                None
            } else {
                let c = pose.transform(p);
                (c.z > 0.0).then(|| Vector2::new(c.x / c.z, c.y / c.z))
            };
        }
        self.screening_cost = 0.0;
        for (i, m) in self.image.iter().enumerate() {
            if triple.contains(&i) {
                continue;
            }
            let mut nearest: Option<(f64, usize)> = None;
            for (k, projection) in self.projections.iter().enumerate() {
                if used & (1 << k) != 0 {
                    continue;
                }
                if let Some(projection) = projection {
                    let distance_sq = (projection - m).norm_squared();
                    if nearest.is_none_or(|(d, _)| distance_sq < d) {
                        nearest = Some((distance_sq, k));
                    }
                }
            }
            match nearest {
                Some((distance_sq, k)) if distance_sq <= self.screening_gate_sq => {
                    self.screening_cost += distance_sq;
                    self.labels[i] = k;
                    used |= 1 << k;
                }
                _ => return false,
            }
        }
        true
    }

    /// Refines the current labelling from `start` and ranks it if consistent.
    fn verify(&mut self, start: &Pose) {
        let count = self.image.len();
        // The same labels from another hypothesis are refined again only
        // if that hypothesis fits the blobs better: the first may have
        // been a poorer P3P root whose refinement stopped in a local
        // minimum.
        if let Some(index) = self
            .refined
            .chunks_exact(count)
            .position(|seen| seen == self.labels.as_slice())
        {
            if self.screening_cost >= self.refined_costs[index] {
                return;
            }
            self.refined_costs[index] = self.screening_cost;
        } else {
            self.refined.extend_from_slice(&self.labels);
            self.refined_costs.push(self.screening_cost);
        }
        self.matched_object.clear();
        self.matched_object
            .extend(self.labels.iter().map(|&k| self.object[k]));
        let pose = ml::refine(start, &self.matched_object, self.image);
        let mut sum_sq = 0.0;
        for (p, m) in self.matched_object.iter().zip(self.image) {
            let c = pose.transform(p);
            if !(c.z > 0.0) {
                return;
            }
            let error_sq = (Vector2::new(c.x / c.z, c.y / c.z) - m).norm_squared();
            if !(error_sq <= self.gate_sq) {
                return;
            }
            sum_sq += error_sq;
        }
        let labelling = Labelling {
            labels: self.labels.clone(),
            pose,
            rms: (sum_sq / count as f64).sqrt(),
        };
        self.offer(labelling);
    }

    /// Ranks a consistent labelling. The same labels can come from several
    /// hypotheses (another P3P root that still passed the screening, whose
    /// refinement may stop in a poorer local minimum): each labelling is
    /// kept once, with its lowest RMS.
    fn offer(&mut self, labelling: Labelling) {
        if let Some(best) = &self.best {
            if best.labels == labelling.labels {
                if labelling.rms < best.rms {
                    self.best = Some(labelling);
                }
                return;
            }
        }
        if let Some(runner_up) = &self.runner_up {
            if runner_up.labels == labelling.labels {
                if labelling.rms < runner_up.rms {
                    self.runner_up = Some(labelling);
                    if let (Some(best), Some(runner_up)) = (&self.best, &self.runner_up) {
                        if runner_up.rms < best.rms {
                            std::mem::swap(&mut self.best, &mut self.runner_up);
                        }
                    }
                }
                return;
            }
        }
        match &self.best {
            Some(best) if labelling.rms >= best.rms => {
                if self
                    .runner_up
                    .as_ref()
                    .is_none_or(|r| labelling.rms < r.rms)
                {
                    self.runner_up = Some(labelling);
                }
            }
            _ => {
                self.runner_up = self.best.take();
                self.best = Some(labelling);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synthetic::{biprism_points, random_points, random_pose, stream_rng};
    use rand::seq::SliceRandom;
    use rand::Rng;

    fn shuffled_image(
        object: &[Vector3<f64>],
        truth: &Pose,
        rng: &mut impl rand::Rng,
        missing: Option<usize>,
    ) -> (Vec<Vector2<f64>>, Vec<usize>) {
        let mut order: Vec<usize> = (0..object.len()).filter(|k| Some(*k) != missing).collect();
        order.shuffle(rng);
        let image = order
            .iter()
            .map(|&k| truth.project_normalised(&object[k]))
            .collect();
        (image, order)
    }

    #[test]
    fn noise_free_shuffled_random_sets_are_labelled() {
        for n in [4, 5, 6, 7, 10, 12, 16] {
            for case in 0..20u64 {
                let mut rng = stream_rng(5, n as u64, case);
                let object = random_points(&mut rng, n, 100.0);
                let truth = random_pose(&mut rng, 400.0, 0.2);
                let (image, order) = shuffled_image(&object, &truth, &mut rng, None);
                let found = identify(&object, &image, &UnlabelledOptions::default()).unwrap();
                assert!(
                    found.best.rms < 1e-10,
                    "n {n} case {case}: {}",
                    found.best.rms
                );
                assert_eq!(found.best.labels, order, "n {n} case {case}");
                assert!(found.hypotheses > 0);
            }
        }
    }

    /// Blob sets of one image with each blob left out in turn, searched
    /// with shared P3P poses: exactly what [`identify`] finds on each set,
    /// for the marker itself and for another marker offered as the model
    /// (a set's cross check), noise-free and with 1 px of noise.
    #[test]
    fn shared_triple_poses_give_what_each_blob_set_gives_alone() {
        for case in 0..12u64 {
            let mut rng = stream_rng(7, 31, case);
            let n = 6 + (case % 3) as usize;
            let object = random_points(&mut rng, n, 100.0);
            let other = random_points(&mut rng, n, 100.0);
            let truth = random_pose(&mut rng, 500.0, 0.2);
            let noise = if case % 2 == 0 { 0.0 } else { 1.0 / 1000.0 };
            let image: Vec<Vector2<f64>> = object
                .iter()
                .map(|p| {
                    truth.project_normalised(p)
                        + noise * Vector2::new(rng.random::<f64>() - 0.5, rng.random::<f64>() - 0.5)
                })
                .collect();
            for model in [&object, &other] {
                let mut poses = TriplePoses::new();
                for missing in std::iter::once(None).chain((0..n).map(Some)) {
                    let kept: Vec<Vector2<f64>> = (0..n)
                        .filter(|&k| Some(k) != missing)
                        .map(|k| image[k])
                        .collect();
                    let options = UnlabelledOptions {
                        gate: 0.02,
                        max_missing: usize::from(missing.is_some()),
                    };
                    let alone = identify(model, &kept, &options);
                    let shared = identify_without(model, &image, missing, &options, &mut poses);
                    assert_eq!(
                        format!("{alone:?}"),
                        format!("{shared:?}"),
                        "case {case}, missing {missing:?}"
                    );
                }
            }
        }
    }

    /// Each point of a random 7-point set missing in turn: the rest are
    /// labelled. The biprism, symmetric, fits exactly with ambiguity 1.
    #[test]
    fn one_missing_blob() {
        let truth = Pose::new(
            nalgebra::Rotation3::from_euler_angles(0.4, 0.3, -0.2),
            Vector3::new(10.0, 20.0, 350.0),
        );
        let object = random_points(&mut stream_rng(5, 98, 0), 7, 100.0);
        let biprism = biprism_points(50.0);
        for missing in 0..object.len() {
            let mut rng = stream_rng(5, 99, missing as u64);
            let (image, order) = shuffled_image(&object, &truth, &mut rng, Some(missing));
            let found = identify(&object, &image, &UnlabelledOptions::default()).unwrap();
            assert_eq!(found.best.labels, order, "missing {missing}");
            let (image, _) = shuffled_image(&biprism, &truth, &mut rng, Some(missing));
            let found = identify(&biprism, &image, &UnlabelledOptions::default()).unwrap();
            assert!(found.best.rms < 1e-12, "{}", found.best.rms);
            let ambiguity = found.ambiguity().unwrap();
            assert!((ambiguity - 1.0).abs() < 1e-6, "{ambiguity}");
        }
    }

    #[test]
    fn bad_input_is_refused() {
        let mut rng = stream_rng(5, 100, 0);
        let object = random_points(&mut rng, 6, 100.0);
        let truth = random_pose(&mut rng, 400.0, 0.2);
        let image: Vec<Vector2<f64>> = object.iter().map(|p| truth.project_normalised(p)).collect();
        let options = UnlabelledOptions::default();
        let err = |o: &[Vector3<f64>], i: &[Vector2<f64>], opt: &UnlabelledOptions| {
            identify(o, i, opt).unwrap_err()
        };
        // The input errors that every PnP method shares.
        let pnp_err = |o: &[Vector3<f64>], i: &[Vector2<f64>], opt: &UnlabelledOptions| match err(
            o, i, opt,
        ) {
            LabellingError::Pnp(e) => e,
            other => panic!("expected a PnP input error, got {other:?}"),
        };
        assert!(matches!(
            pnp_err(&object[..3], &image[..3], &options),
            PnpError::TooFewPoints {
                needed: 4,
                got: 3,
                ..
            }
        ));
        assert_eq!(
            err(&object[..5], &image, &options),
            LabellingError::TooManyBlobs {
                object: 5,
                image: 6
            }
        );
        assert_eq!(
            err(&object, &image[..4], &options),
            LabellingError::TooManyMissing {
                object: 6,
                image: 4,
                max_missing: 1
            }
        );
        let strict = UnlabelledOptions {
            max_missing: 0,
            ..options
        };
        assert!(matches!(
            err(&object, &image[..5], &strict),
            LabellingError::TooManyMissing { .. }
        ));
        assert!(matches!(
            pnp_err(&object[..4], &image[..3], &options),
            PnpError::TooFewPoints { got: 3, .. }
        ));
        for gate in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            assert!(matches!(
                err(&object, &image, &UnlabelledOptions { gate, ..options }),
                LabellingError::BadGate { .. }
            ));
        }
        let mut nan = image.clone();
        nan[2].x = f64::NAN;
        assert_eq!(
            pnp_err(&object, &nan, &options),
            PnpError::NonFinite {
                kind: "image",
                index: 2
            }
        );
        let mut dup = object.clone();
        dup[4] = dup[1];
        assert_eq!(
            pnp_err(&dup, &image, &options),
            PnpError::DuplicatePoints {
                first: 1,
                second: 4
            }
        );
        let mut blobs = image.clone();
        blobs[5] = blobs[0];
        assert_eq!(
            err(&object, &blobs, &options),
            LabellingError::DuplicateBlobs {
                first: 0,
                second: 5
            }
        );
        let line: Vec<_> = (0..6)
            .map(|i| Vector3::new(i as f64, 2.0 * i as f64, 1.0))
            .collect();
        assert_eq!(pnp_err(&line, &image, &options), PnpError::Collinear);
        let on_line: Vec<_> = (0..6)
            .map(|i| Vector2::new(0.01 * i as f64, 0.02 * i as f64))
            .collect();
        assert_eq!(
            pnp_err(&object, &on_line, &options),
            PnpError::CollinearImagePoints
        );
        // Blobs that no pose of this object explains.
        let scattered: Vec<_> = (0..6)
            .map(|i| Vector2::new(0.3 * (i as f64).sin(), 0.2 * (i as f64 * 2.3).cos()))
            .collect();
        let tight = UnlabelledOptions {
            gate: 1e-6,
            ..options
        };
        assert!(
            matches!(err(&object, &scattered, &tight), LabellingError::NoConsistentLabelling { hypotheses } if hypotheses > 0)
        );
    }
}
