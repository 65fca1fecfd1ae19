//! Blob detection: bright discs on a dark background, each measured to a
//! fraction of a pixel.
//!
//! 1. **Threshold** ([`Threshold`]): Otsu's level on a 256-bin histogram,
//!    a fixed level, or a local level (the mean of a square window plus an
//!    offset) for uneven illumination.
//! 2. **Components, coarse to fine.** Each 4×4 cell of the frame keeps its
//!    brightest sample; the cells above threshold are labelled into
//!    8-connected components (`imageproc::region_labelling`). Around each
//!    coarse component, the pixels above threshold of its window are
//!    labelled again at full resolution. Every fine component lies inside
//!    one coarse component, so only windows around bright regions are
//!    visited at full resolution, and the labelling never walks the whole
//!    frame pixel by pixel.
//! 3. **Measurement** of each component, in a window padded by
//!    [`WINDOW_PAD_PX`]; pixels of other components are left out:
//!    * background: median of the window's border, noise σ from the
//!      differences between neighbours along it (`neighbour_noise`: a
//!      support crossing the border lifts a stretch of it, which would swell
//!      a spread about one level); plateau: median of the component's
//!      interior, its noise from neighbour differences there too; contrast:
//!      plateau minus background;
//!    * the **intensity-weighted centroid**, weights `I − background` over
//!      the pixels at least [`CENTROID_FLOOR`] of the step above the
//!      background (a dimmer support beside the sphere would pull it);
//!    * **subpixel edge points**: wherever the intensity crosses half-way
//!      between background and plateau between two horizontally or
//!      vertically adjacent pixels, the brighter in this component, and the
//!      scan runs within 45° of the intensity gradient (a scan along the
//!      edge places it poorly), the six samples from two inside to two
//!      outside the crossing are normalised to their own inside and outside
//!      levels, and their sum places the edge: a box-filtered step (and a
//!      narrowly blurred one) keeps its area, so the normalised samples add
//!      up to the bright run's length, whatever the edge's subpixel phase;
//!      linear interpolation of the half level would be off by up to a
//!      tenth of a pixel, periodically in the phase, which a small disc
//!      does not average away. On a **shaded** blob (a matte sphere
//!      darkening towards its limb: its interior's top stands above its
//!      median by more than [`SHADED_RISE`] of its height) no sample inside
//!      holds a level of its own, and the edge is the half level's own
//!      crossing, interpolated between the two pixels that straddle it: a
//!      contour of the shading, a little inside its limb (the pixels a
//!      contour crosses hold a smooth ramp, which linear interpolation
//!      follows closely; its ellipse gives the projected centre exactly,
//!      [`super::analysis`] the silhouette's ellipse centre from that). So
//!      is a flat disc's edge blurred wider than the samples (a lens blur
//!      of about 1 px: the median drop between the two pixels that
//!      straddle the half level below [`SHARP_FALL_SHARE`] of the step),
//!      whose samples would hold neither level. The
//!      local levels also take out a
//!      dimmer support beside the sphere and the limb's darkening. The
//!      outside level is the one under the edge ([`TAIL_SHARE`]): where a
//!      support or the base plate's edge changes the background within
//!      the three samples outside, the level next to the limb is taken;
//!    * with lens distortion, the edge points are undistorted first, so the
//!      silhouette is an exact conic again ([`crate::sphere_image`]);
//!    * the **ellipse** by the direct least-squares fit ([`super::conic`]),
//!      refitted without the edge points farther from it than their noise
//!      allows (a straight occluder's edge, a neighbour's), then without
//!      the **notches** ([`fit_outline`], [`notch_arcs`]): arcs of the
//!      outline whose points lie inside the ellipse along their length,
//!      beyond their noise, where something in front of the sphere (its
//!      own support cone and fillet, seen far off the cone's axis) hides
//!      the limb. Each round cuts the arcs that the current ellipse finds
//!      inside and refits the rest, until the cut settles; the share cut
//!      is the blob's `outline_dropped`. A shallow notch left in the fit
//!      pulls the centre towards it (a quarter of the outline bent by half
//!      a pixel moves a 10 px disc's centre by about a tenth of a pixel);
//!      cut away, the rest of the outline gives the centre;
//!    * the sphere's **projected centre** from the ellipse
//!      ([`super::conic::SphereFromEllipse`]) and, with the radius, its depth;
//!    * a component that no ellipse fits is **split at its bright cores**
//!      ([`split_cores`]: two discs that the blur joins across a pixel's
//!      gap), and each part is measured on its own, the other part's
//!      pixels left out.
//! 4. **Judgement.** A blob is rejected for size, contrast or a shape no
//!    sphere casts; it is **flagged as partly hidden** when it touches the
//!    image border, when its pixels above the half level fill too little of
//!    its fitted ellipse (the part in front hides area, not just outline),
//!    when too many edge points leave the ellipse, when more than
//!    [`DetectorConfig::max_outline_dropped`] of the outline was cut away
//!    as a notch (too little is left to fix the ellipse), when the edge
//!    that is left still dips inside the ellipse along an arc
//!    ([`edge_dip`]), or when the ellipse's axis ratio is not the one a
//!    sphere's silhouette has there. A flagged blob is left out of the
//!    pose. A blob whose notch was cut away and whose remaining outline
//!    fits cleanly is not flagged: it is not left in with a biased centre,
//!    it is measured from its clean outline.
//!
//! Pixel convention: the centre of the pixel in column `x`, row `y` is the
//! point `(x, y)` (OpenCV's).

use super::config::{DetectorConfig, Threshold};
use super::conic::{Ellipse, SphereFromEllipse};
use super::frame::GreyFrame;
use crate::camera::Camera;
use image::{GrayImage, Luma};
use imageproc::region_labelling::{connected_components, Connectivity};
use nalgebra::Vector2;
use serde::Serialize;
use std::f64::consts::SQRT_2;

/// Share of the neighbour differences [`neighbour_noise`] keeps.
const NOISE_KEPT: f64 = 0.9;
/// RMS of a standard normal variable over its values within the central
/// 90 % (`NOISE_KEPT`): `√(1 − 2·1.645·φ(1.645)/0.9)`.
const KEPT_RMS: f64 = 0.789;
/// A component whose bright cores ([`split_cores`]) cover less than this
/// share of its pixels is a dimmer region holding brighter discs, not a
/// disc: a sphere's plateau is most of its blob.
pub const DIM_REGION_CORE_SHARE: f64 = 0.25;
/// The quantile of a blob's interior that stands for its top level.
pub const TOP_QUANTILE: f64 = 0.9;
/// A blob is shaded (a matte sphere, darkening towards its limb) when its
/// interior's top ([`TOP_QUANTILE`]) stands above its median by more than
/// this share of the top's height above the background. A flat disc's
/// noise reaches about 1.3 σ (a hundredth of its step), a retroreflector's
/// limb darkening about 0.04; the cosine law of a white matte sphere under
/// a light at the camera, 0.25.
pub const SHADED_RISE: f64 = 0.12;
/// Side of the coarse cells, px.
pub const CELL_PX: usize = 4;
/// Pixels added around a component's bounding box for its measurement (a
/// blurred edge's tail).
pub const WINDOW_PAD_PX: usize = 3;
/// Smallest tolerance of an edge point's distance from the ellipse, px: the
/// linear interpolation of an area-sampled edge is off by up to a tenth of
/// a pixel, so a whole, noise-free disc keeps every point.
pub const MIN_EDGE_TOLERANCE_PX: f64 = 0.3;
/// An edge point is off the ellipse beyond this many σ of its position
/// noise (image noise over the local intensity step).
pub const EDGE_OUTLIER_SIGMAS: f64 = 4.0;
/// The centroid weighs the pixels at least this share of the blob's step
/// above the background (a grey support beside a sphere stays below it).
pub const CENTROID_FLOOR: f64 = 0.25;
/// The window of [`Blob::window_centroid_px`]: the fitted ellipse grown
/// about its centre until its minor semi-axis is this much longer, px.
pub const WINDOW_MARGIN_PX: f64 = 1.5;
/// An edge point's six samples must span at least this share of the
/// blob's step (otherwise the scan runs along a dim stretch of edge).
pub const MIN_LOCAL_STEP: f64 = 0.5;
/// An edge point's position noise over the pixel noise σ and its local
/// step: four normalised samples add up (√4), and the inside and outside
/// levels that normalise them add their own share.
pub const EDGE_SUM_NOISE: f64 = 2.5;
/// Below this median share of the local step between the two pixels that
/// straddle a flat disc's half level, its step is blurred wider than the
/// samples the sum reads, and the half level's crossing places its edge.
/// An area-sampled step under a Gaussian blur of σ 0.5 px falls by up to
/// 0.69 of itself from one pixel to the next, under σ 1 px by up to 0.38,
/// and by less where the scan crosses the edge obliquely; on `render`'s
/// frames no blob at σ 0.5 px has its median below this share.
pub const SHARP_FALL_SHARE: f64 = 0.42;
/// The arc, degrees of the ellipse's parametric angle, over which
/// [`edge_dip`] averages the edge points' distances: a support's notch in
/// a disc spans tens of degrees; the edge model's own errors on a whole
/// disc alternate in sign over a few.
pub const DIP_ARC_DEG: f64 = 30.0;
/// Fewest edge points on an arc that [`edge_dip`] judges.
pub const DIP_MIN_POINTS: usize = 3;
/// [`edge_dip`] discounts this many standard errors of an arc's mean
/// distance.
pub const DIP_SIGMAS: f64 = 2.0;
/// Rounds of refitting without the outlying edge points.
pub const REFIT_ROUNDS: usize = 3;
/// The arc, degrees of the ellipse's parametric angle, centred on each
/// edge point, over which [`notch_arcs`] averages the distances from the
/// ellipse: a support's notch spans tens of degrees.
pub const NOTCH_WINDOW_DEG: f64 = 20.0;
/// [`notch_arcs`] marks a point when the mean distance over its window
/// lies inside the ellipse by more than this many standard errors of that
/// mean, plus [`NOTCH_FLOOR_PX`].
pub const NOTCH_SIGMAS: f64 = 3.0;
/// Least mean depth of a notch's window, px, beyond its noise: the edge
/// model's own errors on a whole noise-free disc reach a few hundredths
/// of a pixel along an arc.
pub const NOTCH_FLOOR_PX: f64 = 0.03;
/// A notch window ([`notch_arcs`]) holds at least this many edge points on
/// either side of its centre.
pub const NOTCH_MIN_SIDE: usize = 3;
/// Rounds of cutting notches away and refitting.
pub const NOTCH_ROUNDS: usize = 4;
/// The notch refit stops short of fitting fewer than this share of the
/// edge points (the blob is flagged well before, at
/// [`DetectorConfig::max_outline_dropped`]).
pub const NOTCH_MIN_KEPT: f64 = 0.5;
/// A blob's axis ratio may exceed a sphere's by this factor before the blob
/// is rejected as no sphere at all (a streak, a reflection).
pub const MAX_AXIS_RATIO_FACTOR: f64 = 1.6;
/// A blob's axis ratio may differ from a sphere's by this much before it is
/// flagged as partly hidden.
pub const MAX_AXIS_RATIO_ERROR: f64 = 0.08;

/// Why a component is not a blob.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct Rejected {
    /// Smaller than `min_area_px`.
    pub small: usize,
    /// Larger than `max_area_px`.
    pub large: usize,
    /// Contrast below `min_contrast`.
    pub contrast: usize,
    /// No ellipse fits, or one no sphere casts.
    pub shape: usize,
}

/// One blob and the detector's figures for it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Blob {
    /// Pixels above threshold.
    pub area_px: usize,
    /// Plateau minus background, fraction of full scale.
    pub contrast: f64,
    /// Background noise σ around the blob, fraction of full scale.
    pub noise: f64,
    /// Intensity-weighted centroid, raw px.
    pub centroid_px: [f64; 2],
    /// The background-subtracted intensity centroid over the fitted ellipse
    /// grown by [`WINDOW_MARGIN_PX`] ([`super::config::CentreMethod::Window`]), raw px.
    pub window_centroid_px: [f64; 2],
    /// Centre of the fitted ellipse, raw px (the undistorted ellipse centre
    /// mapped through the lens).
    pub ellipse_centre_px: [f64; 2],
    /// The sphere's projected centre from the ellipse, raw px.
    pub centre_px: [f64; 2],
    /// Semi-axes of the fitted ellipse (major, minor), undistorted px.
    pub semi_axes_px: [f64; 2],
    /// Depth of the sphere centre from the ellipse and the diameter, mm.
    pub depth_mm: f64,
    /// Edge points found.
    pub edge_points: usize,
    /// RMS distance of the kept edge points from the ellipse, px.
    pub fit_residual_px: f64,
    /// The ellipse centre's σ per axis as its own edges give it: the fit
    /// residual over the kept points, `fit_residual_px · √(2 / kept)`
    /// (the centre of a circle fitted to `n` points of radial noise σ
    /// has σ·√(2/n) per axis), px. What the covariance makes of it:
    /// [`super::uncertainty`].
    pub centre_noise_px: f64,
    /// Whether the blob is a shaded sphere (its interior rises more than
    /// [`SHADED_RISE`] of its height above its median): its outline is a
    /// contour of the shading a little inside the limb, not the silhouette.
    pub shaded: bool,
    /// The windowed centroid's σ per axis from the pixel noise (the
    /// background's and the plateau's, linear in the level between), px.
    pub window_noise_px: f64,
    /// Share of edge points left out as off the ellipse (beyond their
    /// noise, either way), those cut away as a notch not counted.
    pub outlier_fraction: f64,
    /// Share of edge points cut away as a notch: arcs of the outline that
    /// lie inside the ellipse fitted to the rest ([`notch_arcs`]), where
    /// something in front of the sphere (a support, its own cone) hides
    /// its limb. The ellipse and the centres come from the rest.
    pub outline_dropped: f64,
    /// How far the edge dips inside the ellipse along its worst arc, beyond
    /// the noise of its points, px ([`edge_dip`]).
    pub edge_dip_px: f64,
    /// Pixels above the half level over the fitted ellipse's area.
    pub filled_fraction: f64,
    /// Fitted axis ratio (major / minor).
    pub axis_ratio: f64,
    /// The axis ratio a whole sphere has at this place in the image.
    pub expected_axis_ratio: f64,
    /// Why the blob counts as partly hidden (empty: it does not).
    pub hidden_because: Vec<&'static str>,
    /// The label the tracker gave the blob (index into the layout's
    /// spheres), if any.
    pub label: Option<usize>,
    /// The part's bias on this blob's centre, measured on a render of the
    /// part at the tracked pose ([`super::refine`]) and taken off the
    /// measured centre (either method) before the pose; `None` unrefined.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub bias: Option<CentreBias>,
    /// Ellipse centre on the undistorted normalised plane.
    #[serde(skip)]
    pub ellipse_centre_normalised: Vector2<f64>,
    /// Centroid on the undistorted normalised plane.
    #[serde(skip)]
    pub centroid_normalised: Vector2<f64>,
    /// Windowed centroid on the undistorted normalised plane.
    #[serde(skip)]
    pub window_centroid_normalised: Vector2<f64>,
    /// `1 + b²` of the fitted ellipse (normalised minor semi-axis `b`): an
    /// ellipse centre over it is the projected sphere centre.
    #[serde(skip)]
    pub centre_shrink: f64,
    /// The fitted ellipse in undistorted pixels.
    #[serde(skip)]
    pub ellipse_px: Ellipse,
}

/// A blob centre's bias: what the detector measures on a noise-free render
/// minus the exact ellipse centre there.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct CentreBias {
    /// Raw px.
    pub px: [f64; 2],
    /// On the undistorted normalised plane.
    #[serde(skip)]
    pub normalised: Vector2<f64>,
    /// The render's windowed centroid minus its ellipse centre, raw px:
    /// how far apart the part itself sets the two centres, which the
    /// frame's own [`Blob::disagreement_px`] is judged against.
    pub disagreement_px: [f64; 2],
}

impl Blob {
    /// Whether the blob is flagged as partly hidden.
    pub fn hidden(&self) -> bool {
        !self.hidden_because.is_empty()
    }

    /// How far the windowed centroid lies from the ellipse centre, px,
    /// beyond what the part itself does there when a refinement measured
    /// it ([`CentreBias::disagreement_px`]): zero on a flat bright disc
    /// but for noise, and the measure of how far the frame's look departs
    /// from one ([`super::uncertainty`]).
    pub fn disagreement_px(&self) -> f64 {
        self.disagreement_with(&Vector2::from(self.ellipse_centre_px))
    }

    /// [`Blob::disagreement_px`] against `ellipse_centre_px` (raw px) in
    /// place of the blob's own ellipse centre: a shaded sphere's
    /// silhouette centre, which its outline does not give directly.
    pub fn disagreement_with(&self, ellipse_centre_px: &Vector2<f64>) -> f64 {
        let apart = Vector2::from(self.window_centroid_px) - ellipse_centre_px;
        let expected = self
            .bias
            .map_or(Vector2::zeros(), |b| Vector2::from(b.disagreement_px));
        (apart - expected).norm()
    }
}

/// Why a frame yields no usable detection at all.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum DetectError {
    /// More blobs than the tracker can sort through.
    #[error("more than {max} blobs pass the detector (at least {found}); is this a frame of the marker?")]
    TooManyBlobs {
        /// The most accepted.
        max: usize,
        /// Blobs found before the detector stopped counting.
        found: usize,
    },
}

/// What the detector found in one frame.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Detection {
    /// Accepted blobs (hidden ones included, flagged), in raster order.
    pub blobs: Vec<Blob>,
    /// Components rejected, by reason.
    pub rejected: Rejected,
    /// The threshold applied (never [`Threshold::Auto`]: the one it
    /// chose).
    pub threshold: Threshold,
    /// Threshold level used (global) or the local offset, fraction of full
    /// scale.
    pub threshold_level: f64,
    /// Where the components rejected as no sphere's disc lie (two discs
    /// that touch and merge, a blob cut by something in front).
    pub misshapen: Vec<Misshapen>,
}

/// A component above the threshold that no sphere casts: rejected, not
/// measured, and said where it is.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Misshapen {
    /// Its pixels' box: first column, first row, last column, last row.
    pub box_px: [usize; 4],
    /// Pixels above the threshold.
    pub area_px: usize,
}

/// The threshold as applied: a level per coarse cell, raw units.
enum Levels {
    Global(f64),
    Local {
        cell_levels: Vec<f64>,
        cells_wide: usize,
    },
}

impl Levels {
    fn at(&self, x: usize, y: usize) -> f64 {
        match self {
            Levels::Global(level) => *level,
            Levels::Local {
                cell_levels,
                cells_wide,
            } => cell_levels[(y / CELL_PX) * cells_wide + x / CELL_PX],
        }
    }
}

/// Otsu's threshold bin on a histogram: samples in bins above it are
/// foreground; `None` when every sample falls in one bin.
fn otsu_bin(histogram: &[u64; 256]) -> Option<usize> {
    let total: u64 = histogram.iter().sum();
    let total_sum: f64 = histogram
        .iter()
        .enumerate()
        .map(|(bin, &n)| bin as f64 * n as f64)
        .sum();
    let (mut weight_low, mut sum_low) = (0u64, 0.0);
    let mut best: Option<(f64, usize)> = None;
    for (bin, &count) in histogram.iter().enumerate().take(255) {
        weight_low += count;
        sum_low += bin as f64 * count as f64;
        let weight_high = total - weight_low;
        if weight_low == 0 || weight_high == 0 {
            continue;
        }
        let mean_low = sum_low / weight_low as f64;
        let mean_high = (total_sum - sum_low) / weight_high as f64;
        let between = weight_low as f64 * weight_high as f64 * (mean_high - mean_low).powi(2);
        if best.is_none_or(|(value, _)| between > value) {
            best = Some((between, bin));
        }
    }
    best.map(|(_, bin)| bin)
}

/// The upper of the two bins that split `histogram` into three classes
/// with the largest between-class variance (Otsu's criterion for three
/// classes): samples in bins above it are the brightest class. `None` when
/// the samples fill fewer than three bins ([`Threshold::OtsuUpper`] then
/// applies Otsu's two-class level).
fn otsu_upper_bin(histogram: &[u64; 256]) -> Option<usize> {
    // Prefix counts and sums: a class's weight and its sum in O(1).
    let mut count = [0f64; 257];
    let mut sum = [0f64; 257];
    for (bin, &n) in histogram.iter().enumerate() {
        count[bin + 1] = count[bin] + n as f64;
        sum[bin + 1] = sum[bin] + bin as f64 * n as f64;
    }
    // Σ wₖ μₖ² = Σ sₖ² / wₖ over the classes [0, low], (low, high],
    // (high, 255]; the between-class variance differs from it by a
    // constant.
    let part = |from: usize, to: usize| {
        let w = count[to] - count[from];
        (w > 0.0).then(|| (sum[to] - sum[from]).powi(2) / w)
    };
    let mut best: Option<(f64, usize)> = None;
    for low in 0..254 {
        let Some(first) = part(0, low + 1) else {
            continue;
        };
        for high in low + 1..255 {
            let (Some(middle), Some(last)) = (part(low + 1, high + 1), part(high + 1, 256)) else {
                continue;
            };
            let value = first + middle + last;
            if best.is_none_or(|(b, _)| value > b) {
                best = Some((value, high));
            }
        }
    }
    best.map(|(_, high)| high)
}

/// [`Threshold::Auto`]: the detection at Otsu's level, and where it leaves
/// a blob flagged as partly hidden or a component rejected for its shape
/// or size, or gives up, the detection at the upper three-class level too;
/// of the two, the one with more whole blobs (Otsu's on a tie).
fn detect_auto(
    frame: &GreyFrame,
    camera: &Camera,
    config: &DetectorConfig,
    radius_mm: f64,
    max_blobs: usize,
) -> Result<Detection, DetectError> {
    let at = |threshold| {
        let config = DetectorConfig {
            threshold,
            ..*config
        };
        detect(frame, camera, &config, radius_mm, max_blobs)
    };
    let whole = |detection: &Result<Detection, DetectError>| {
        detection
            .as_ref()
            .map_or(0, |d| d.blobs.iter().filter(|b| !b.hidden()).count())
    };
    let otsu = at(Threshold::Otsu);
    let doubtful = otsu.as_ref().map_or(true, |d| {
        d.rejected.shape + d.rejected.large > 0 || d.blobs.iter().any(Blob::hidden)
    });
    if !doubtful {
        return otsu;
    }
    let upper = at(Threshold::OtsuUpper);
    if whole(&upper) > whole(&otsu) {
        upper
    } else {
        otsu
    }
}

/// Finds and measures the blobs of `frame` (module docs). Stops with
/// [`DetectError::TooManyBlobs`] once more than `max_blobs` are accepted.
pub fn detect(
    frame: &GreyFrame,
    camera: &Camera,
    config: &DetectorConfig,
    radius_mm: f64,
    max_blobs: usize,
) -> Result<Detection, DetectError> {
    if matches!(config.threshold, Threshold::Auto) {
        return detect_auto(frame, camera, config, radius_mm, max_blobs);
    }
    let width = frame.width() as usize;
    let height = frame.height() as usize;
    let pixels = frame.pixels();
    let full_scale = f64::from(frame.full_scale());
    let shift = frame.bit_depth() - 8;
    let cells_wide = width.div_ceil(CELL_PX);
    let cells_high = height.div_ceil(CELL_PX);
    let local = matches!(config.threshold, Threshold::Local { .. });
    // One pass: the histogram, each cell's maximum and (local) sum.
    let mut histogram = [0u64; 256];
    let mut cell_max = vec![0u16; cells_wide * cells_high];
    let mut cell_sum = vec![0u64; if local { cells_wide * cells_high } else { 0 }];
    for (y, row) in pixels.chunks_exact(width).enumerate() {
        let cell_row = (y / CELL_PX) * cells_wide;
        for (cx, chunk) in row.chunks(CELL_PX).enumerate() {
            let mut max = 0u16;
            let mut sum = 0u64;
            for &v in chunk {
                histogram[usize::from(v >> shift)] += 1;
                max = max.max(v);
                sum += u64::from(v);
            }
            let cell = &mut cell_max[cell_row + cx];
            *cell = (*cell).max(max);
            if local {
                cell_sum[cell_row + cx] += sum;
            }
        }
    }
    let bin_scale = f64::from(1u32 << shift);
    let levels = match config.threshold {
        Threshold::Otsu | Threshold::Auto => Levels::Global(match otsu_bin(&histogram) {
            Some(bin) => (bin as f64 + 1.0) * bin_scale - 0.5,
            None => full_scale,
        }),
        Threshold::OtsuUpper => Levels::Global(
            match otsu_upper_bin(&histogram).or_else(|| otsu_bin(&histogram)) {
                Some(bin) => (bin as f64 + 1.0) * bin_scale - 0.5,
                None => full_scale,
            },
        ),
        Threshold::Fixed(level) => Levels::Global(level * full_scale),
        Threshold::Local { radius_px, offset } => {
            let radius_cells = (radius_px as usize).div_ceil(CELL_PX);
            let cell_levels = local_levels(
                &cell_sum,
                cells_wide,
                cells_high,
                (width, height),
                radius_cells,
            )
            .into_iter()
            .map(|mean| mean + offset * full_scale)
            .collect();
            Levels::Local {
                cell_levels,
                cells_wide,
            }
        }
    };
    let threshold_level = match (&levels, config.threshold) {
        (Levels::Global(level), _) => level / full_scale,
        (_, Threshold::Local { offset, .. }) => offset,
        _ => unreachable!("local levels come from a local threshold"),
    };
    // Background of the whole frame: the mean below a global level (or
    // below the median, for a local threshold), for blobs whose window
    // border is all foreground.
    let fallback_background = {
        let cut = match &levels {
            Levels::Global(level) => level / bin_scale,
            Levels::Local { .. } => 127.0,
        };
        let (mut n, mut sum) = (0.0, 0.0);
        for (bin, &count) in histogram.iter().enumerate() {
            if (bin as f64) < cut {
                n += count as f64;
                sum += (bin as f64 + 0.5) * bin_scale * count as f64;
            }
        }
        if n > 0.0 {
            sum / n
        } else {
            0.0
        }
    };

    let mut coarse = GrayImage::new(cells_wide as u32, cells_high as u32);
    for cy in 0..cells_high {
        for cx in 0..cells_wide {
            let level = levels.at(cx * CELL_PX, cy * CELL_PX);
            if f64::from(cell_max[cy * cells_wide + cx]) > level {
                coarse.put_pixel(cx as u32, cy as u32, Luma([255]));
            }
        }
    }
    let coarse_labels = connected_components(&coarse, Connectivity::Eight, Luma([0u8]));
    let coarse_label =
        |x: usize, y: usize| coarse_labels.get_pixel((x / CELL_PX) as u32, (y / CELL_PX) as u32)[0];
    // Bounding boxes of the coarse components, in cells.
    let mut boxes: Vec<[usize; 4]> = Vec::new();
    for (cx, cy, label) in coarse_labels.enumerate_pixels() {
        let label = label[0] as usize;
        if label == 0 {
            continue;
        }
        if boxes.len() < label {
            boxes.resize(label, [usize::MAX, usize::MAX, 0, 0]);
        }
        let b = &mut boxes[label - 1];
        b[0] = b[0].min(cx as usize);
        b[1] = b[1].min(cy as usize);
        b[2] = b[2].max(cx as usize);
        b[3] = b[3].max(cy as usize);
    }

    let context = Context {
        frame,
        camera,
        config,
        radius_mm,
        full_scale,
        fallback_background,
    };
    let mut detection = Detection {
        blobs: Vec::new(),
        rejected: Rejected::default(),
        threshold: config.threshold,
        threshold_level,
        misshapen: Vec::new(),
    };
    let mut order: Vec<(usize, Blob)> = Vec::new();
    for (index, b) in boxes.iter().enumerate() {
        let label = index as u32 + 1;
        let x0 = (b[0] * CELL_PX).saturating_sub(CELL_PX);
        let y0 = (b[1] * CELL_PX).saturating_sub(CELL_PX);
        let x1 = ((b[2] + 2) * CELL_PX).min(width);
        let y1 = ((b[3] + 2) * CELL_PX).min(height);
        let window = Window { x0, y0, x1, y1 };
        let mut mask = GrayImage::new((x1 - x0) as u32, (y1 - y0) as u32);
        for y in y0..y1 {
            for x in x0..x1 {
                if f64::from(pixels[y * width + x]) > levels.at(x, y) {
                    mask.put_pixel((x - x0) as u32, (y - y0) as u32, Luma([255]));
                }
            }
        }
        let fine = connected_components(&mask, Connectivity::Eight, Luma([0u8]));
        let labels: Vec<u32> = fine.into_raw();
        let components = component_stats(&labels, &window);
        for (id, stats) in components.iter().enumerate() {
            let (fx, fy) = stats.first;
            if stats.count == 0 || coarse_label(fx, fy) != label {
                continue;
            }
            let mut measured = vec![(
                stats.first,
                measure(&context, &labels, &window, id as u32 + 1, stats),
            )];
            // Two discs that the blur joins, or discs in front of a dimmer
            // region above the threshold: each bright core on its own.
            let failed = matches!(measured[0].1, Err(Reason::Shape | Reason::Large));
            let flagged = matches!(&measured[0].1, Ok(blob) if blob.hidden());
            if failed || flagged {
                if let Some((split, ids)) = split_cores(
                    frame,
                    &levels,
                    &labels,
                    &window,
                    id as u32 + 1,
                    config,
                    failed,
                ) {
                    let parts = component_stats(&split, &window);
                    let pieces: Vec<_> = ids
                        .iter()
                        .map(|&part| {
                            let stats = &parts[part as usize - 1];
                            (stats.first, measure(&context, &split, &window, part, stats))
                        })
                        .collect();
                    if pieces.iter().any(|(_, m)| m.is_ok()) {
                        measured = pieces;
                    }
                }
            }
            for ((fx, fy), result) in measured {
                match result {
                    Ok(blob) => {
                        order.push((fy * width + fx, blob));
                        if order.len() > max_blobs {
                            return Err(DetectError::TooManyBlobs {
                                max: max_blobs,
                                found: order.len(),
                            });
                        }
                    }
                    Err(reason) => match reason {
                        Reason::Small => detection.rejected.small += 1,
                        Reason::Large => detection.rejected.large += 1,
                        Reason::Contrast => detection.rejected.contrast += 1,
                        Reason::Shape => {
                            detection.rejected.shape += 1;
                            detection.misshapen.push(Misshapen {
                                box_px: [stats.min.0, stats.min.1, stats.max.0, stats.max.1],
                                area_px: stats.count,
                            });
                        }
                    },
                }
            }
        }
    }
    order.sort_by_key(|(first, _)| *first);
    detection.blobs = order.into_iter().map(|(_, blob)| blob).collect();
    Ok(detection)
}

/// Component `id` of the window's `labels` split at its bright cores: the
/// pixels above the level half-way from the threshold to the component's
/// peak, 8-connected (those of at least a quarter of `min_area_px`).
/// * When the cores cover less than [`DIM_REGION_CORE_SHARE`] of the
///   component, it is a dimmer region holding brighter discs (a grey base
///   plate above a global threshold, with spheres in front of it): each
///   core grows, breadth first (8-connected), into the component's pixels
///   at least [`CENTROID_FLOOR`] of the way from the threshold to the peak,
///   and the rest of the region is left out. One core is enough.
/// * Otherwise, only for a component that failed as one disc (`failed`:
///   no ellipse fits it, or it is too large), with two or more cores: every
///   pixel of the component goes to the core it reaches first, so that two
///   discs the blur joins across a gap of a pixel come apart along the dim
///   neck between them.
///
/// Returns the window's labels with the component's pixels relabelled and
/// the new labels, or `None` when neither case applies.
fn split_cores(
    frame: &GreyFrame,
    levels: &Levels,
    labels: &[u32],
    window: &Window,
    id: u32,
    config: &DetectorConfig,
    failed: bool,
) -> Option<(Vec<u32>, Vec<u32>)> {
    let w = window.width();
    let h = window.y1 - window.y0;
    let width = frame.width() as usize;
    let value =
        |i: usize| f64::from(frame.pixels()[(window.y0 + i / w) * width + window.x0 + i % w]);
    let level = |i: usize| levels.at(window.x0 + i % w, window.y0 + i / w);
    let peak = (0..labels.len())
        .filter(|&i| labels[i] == id)
        .map(value)
        .fold(f64::MIN, f64::max);
    let mut mask = GrayImage::new(w as u32, h as u32);
    for i in (0..labels.len()).filter(|&i| labels[i] == id) {
        if value(i) > level(i) + 0.5 * (peak - level(i)) {
            mask.put_pixel((i % w) as u32, (i / w) as u32, Luma([255]));
        }
    }
    let cores = connected_components(&mask, Connectivity::Eight, Luma([0u8])).into_raw();
    let mut sizes: Vec<usize> = Vec::new();
    for &core in cores.iter().filter(|&&c| c > 0) {
        if sizes.len() < core as usize {
            sizes.resize(core as usize, 0);
        }
        sizes[core as usize - 1] += 1;
    }
    let min_core = config.min_area_px.div_ceil(4).max(1);
    let next = labels.iter().copied().max().unwrap_or(0) + 1;
    // Kept cores, numbered from `next` in order of their first pixel.
    let mut renumber = vec![0u32; sizes.len()];
    let mut ids = Vec::new();
    for &core in &cores {
        if core > 0 && sizes[core as usize - 1] >= min_core && renumber[core as usize - 1] == 0 {
            renumber[core as usize - 1] = next + ids.len() as u32;
            ids.push(next + ids.len() as u32);
        }
    }
    let count = labels.iter().filter(|&&l| l == id).count();
    let core_pixels: usize = sizes.iter().filter(|&&n| n >= min_core).sum();
    let dim_region = (core_pixels as f64) < DIM_REGION_CORE_SHARE * count as f64;
    let applies = (dim_region && !ids.is_empty()) || (failed && ids.len() >= 2);
    if !applies {
        return None;
    }
    // In a dim region a core keeps to its own ramp; joined discs share all.
    let floor = |i: usize| {
        if dim_region {
            level(i) + CENTROID_FLOOR * (peak - level(i))
        } else {
            f64::MIN
        }
    };
    let mut split = labels.to_vec();
    let mut queue = std::collections::VecDeque::new();
    for i in 0..split.len() {
        if split[i] == id {
            let core = cores[i];
            if core > 0 && renumber[core as usize - 1] > 0 {
                split[i] = renumber[core as usize - 1];
                queue.push_back(i);
            } else {
                split[i] = 0;
            }
        }
    }
    while let Some(i) = queue.pop_front() {
        let (x, y) = ((i % w) as isize, (i / w) as isize);
        for (dx, dy) in [
            (-1, -1),
            (0, -1),
            (1, -1),
            (-1, 0),
            (1, 0),
            (-1, 1),
            (0, 1),
            (1, 1),
        ] {
            let (nx, ny) = (x + dx, y + dy);
            if nx < 0 || ny < 0 || nx >= w as isize || ny >= h as isize {
                continue;
            }
            let j = ny as usize * w + nx as usize;
            if labels[j] == id && split[j] == 0 && value(j) > floor(j) {
                split[j] = split[i];
                queue.push_back(j);
            }
        }
    }
    Some((split, ids))
}

/// Per-cell local means over a square of `radius_cells` cells, raw units.
fn local_levels(
    cell_sum: &[u64],
    cells_wide: usize,
    cells_high: usize,
    (width, height): (usize, usize),
    radius_cells: usize,
) -> Vec<f64> {
    // Summed-area tables of the sums and of the pixel counts per cell.
    let stride = cells_wide + 1;
    let mut sums = vec![0.0f64; stride * (cells_high + 1)];
    let mut counts = vec![0.0f64; stride * (cells_high + 1)];
    for cy in 0..cells_high {
        for cx in 0..cells_wide {
            let cell_w = CELL_PX.min(width - cx * CELL_PX);
            let cell_h = CELL_PX.min(height - cy * CELL_PX);
            let i = (cy + 1) * stride + cx + 1;
            sums[i] = cell_sum[cy * cells_wide + cx] as f64 + sums[i - 1] + sums[i - stride]
                - sums[i - stride - 1];
            counts[i] = (cell_w * cell_h) as f64 + counts[i - 1] + counts[i - stride]
                - counts[i - stride - 1];
        }
    }
    let mut out = Vec::with_capacity(cells_wide * cells_high);
    for cy in 0..cells_high {
        let (ya, yb) = (
            cy.saturating_sub(radius_cells),
            (cy + radius_cells + 1).min(cells_high),
        );
        for cx in 0..cells_wide {
            let (xa, xb) = (
                cx.saturating_sub(radius_cells),
                (cx + radius_cells + 1).min(cells_wide),
            );
            let area = |table: &[f64]| {
                table[yb * stride + xb] - table[ya * stride + xb] - table[yb * stride + xa]
                    + table[ya * stride + xa]
            };
            out.push(area(&sums) / area(&counts));
        }
    }
    out
}

/// A window of the frame: columns `x0..x1`, rows `y0..y1`.
#[derive(Debug, Clone, Copy)]
struct Window {
    x0: usize,
    y0: usize,
    x1: usize,
    y1: usize,
}

impl Window {
    fn width(&self) -> usize {
        self.x1 - self.x0
    }
}

#[derive(Debug, Clone, Copy)]
struct Stats {
    count: usize,
    first: (usize, usize),
    min: (usize, usize),
    max: (usize, usize),
}

fn component_stats(labels: &[u32], window: &Window) -> Vec<Stats> {
    let mut stats: Vec<Stats> = Vec::new();
    let w = window.width();
    for (i, &label) in labels.iter().enumerate() {
        if label == 0 {
            continue;
        }
        let (x, y) = (window.x0 + i % w, window.y0 + i / w);
        let index = label as usize - 1;
        if stats.len() <= index {
            stats.resize(
                index + 1,
                Stats {
                    count: 0,
                    first: (0, 0),
                    min: (usize::MAX, usize::MAX),
                    max: (0, 0),
                },
            );
        }
        let s = &mut stats[index];
        if s.count == 0 {
            s.first = (x, y);
        }
        s.count += 1;
        s.min = (s.min.0.min(x), s.min.1.min(y));
        s.max = (s.max.0.max(x), s.max.1.max(y));
    }
    stats
}

struct Context<'a> {
    frame: &'a GreyFrame,
    camera: &'a Camera,
    config: &'a DetectorConfig,
    radius_mm: f64,
    full_scale: f64,
    fallback_background: f64,
}

enum Reason {
    Small,
    Large,
    Contrast,
    Shape,
}

/// The pixel noise σ from `differences`, the absolute differences between
/// neighbouring pixels: the RMS of the smallest [`NOISE_KEPT`] of them (the
/// rest may straddle an edge), rescaled to a normal variable's full RMS,
/// over √2 (a difference adds two pixels' noise). Unlike a median, it
/// stays above zero when the noise is below one quantisation step.
fn neighbour_noise(differences: &mut [f64]) -> f64 {
    differences.sort_unstable_by(f64::total_cmp);
    let kept = &differences[..((NOISE_KEPT * differences.len() as f64).ceil() as usize).max(1)];
    let mean_square = kept.iter().map(|d| d * d).sum::<f64>() / kept.len() as f64;
    mean_square.sqrt() / KEPT_RMS / SQRT_2
}

fn median(values: &mut [f64]) -> f64 {
    quantile(values, 0.5)
}

/// The value `share` of the way up `values` (reordered), which must not be
/// empty.
fn quantile(values: &mut [f64], share: f64) -> f64 {
    let at = ((values.len() as f64 * share) as usize).min(values.len() - 1);
    let (_, m, _) = values.select_nth_unstable_by(at, f64::total_cmp);
    *m
}

/// `p` moved `k` steps along `(ax, ay)`, if that pixel is in the window and
/// of no other component.
fn shift_across(
    p: (usize, usize),
    (ax, ay): (usize, usize),
    k: isize,
    inside: &impl Fn(usize, usize) -> bool,
    foreign: &impl Fn(usize, usize) -> bool,
) -> Option<(usize, usize)> {
    let x = p.0.checked_add_signed(k * ax as isize)?;
    let y = p.1.checked_add_signed(k * ay as isize)?;
    (inside(x, y) && !foreign(x, y)).then_some((x, y))
}

/// The share of the step beyond the edge that a blurred edge's tail may
/// leave in the sample just outside, over the one before it (about a tenth
/// at the render's σ 0.5 px blur; a wider blur leaves more).
pub const TAIL_SHARE: f64 = 0.3;

/// The background level under an edge point's crossing, from the samples
/// one (`dark`), two (`outer`) and three (`outer2`) steps beyond the
/// bright pixel. On an even background the sample two out holds what is
/// left of the blurred edge's tail, so the level is `outer2`. Where the
/// background itself changes within those pixels (a support or the base
/// plate's edge just behind the limb), the level farthest out is not the
/// one under the edge:
/// * the profile dips right outside the limb (`outer` below `outer2`
///   beyond the noise): the background darkens towards the limb, and the
///   level is carried on from `outer2` through `outer` by one more step;
/// * the profile falls from `outer` to `outer2` by more than an edge's
///   tail can (`TAIL_SHARE` of what `dark` stands above `outer2`): the
///   background steps down between them, and `outer`, next to the edge,
///   is the level.
fn local_outside_level(dark: f64, outer: f64, outer2: f64, noise: f64) -> f64 {
    let margin = 3.0 * noise;
    if outer < outer2 - margin {
        (2.0 * outer - outer2).min(outer)
    } else if outer - outer2 > TAIL_SHARE * (dark - outer2).max(0.0) + margin {
        outer
    } else {
        outer2
    }
}

/// Measures component `id` of the window's labels (module docs, step 3).
fn measure(
    context: &Context,
    labels: &[u32],
    window: &Window,
    id: u32,
    stats: &Stats,
) -> Result<Blob, Reason> {
    let config = context.config;
    if stats.count < config.min_area_px {
        return Err(Reason::Small);
    }
    if stats.count > config.max_area_px {
        return Err(Reason::Large);
    }
    let frame = context.frame;
    let (width, height) = (frame.width() as usize, frame.height() as usize);
    let value = |x: usize, y: usize| f64::from(frame.pixels()[y * width + x]);
    let label = |x: usize, y: usize| labels[(y - window.y0) * window.width() + (x - window.x0)];
    let x0 = stats.min.0.saturating_sub(WINDOW_PAD_PX).max(window.x0);
    let y0 = stats.min.1.saturating_sub(WINDOW_PAD_PX).max(window.y0);
    let x1 = (stats.max.0 + WINDOW_PAD_PX).min(window.x1 - 1);
    let y1 = (stats.max.1 + WINDOW_PAD_PX).min(window.y1 - 1);
    let touches_border = stats.min.0 == 0
        || stats.min.1 == 0
        || stats.max.0 + 1 == width
        || stats.max.1 + 1 == height;
    let foreign = |x: usize, y: usize| {
        let l = label(x, y);
        l != 0 && l != id
    };

    // Background and noise from the window's border: the background is
    // the median of its pixels, the noise the spread of the differences
    // between neighbours along it (a support crossing the border shifts
    // the level of a stretch of it, which the median ignores but a spread
    // about one level would not).
    let border: Vec<(usize, usize)> = (x0..=x1)
        .map(|x| (x, y0))
        .chain((y0 + 1..=y1).map(|y| (x1, y)))
        .chain((x0..x1).rev().map(|x| (x, y1)))
        .chain((y0 + 1..y1).rev().map(|y| (x0, y)))
        .collect();
    let mut ring: Vec<f64> = border
        .iter()
        .filter(|p| label(p.0, p.1) == 0)
        .map(|p| value(p.0, p.1))
        .collect();
    let mut steps: Vec<f64> = border
        .iter()
        .zip(border.iter().cycle().skip(1))
        .filter(|(a, b)| label(a.0, a.1) == 0 && label(b.0, b.1) == 0)
        .map(|(a, b)| (value(a.0, a.1) - value(b.0, b.1)).abs())
        .collect();
    let (background, noise) = if ring.len() >= 8 && steps.len() >= 8 {
        (median(&mut ring), neighbour_noise(&mut steps))
    } else {
        (context.fallback_background, 0.0)
    };
    // Plateau: the component's interior (all four neighbours in it).
    let mut interior = Vec::new();
    let mut interior_steps = Vec::new();
    let mut interior_curvatures = Vec::new();
    let mut previous_interior: Option<(usize, usize, f64, Option<f64>)> = None;
    let mut peak = f64::MIN;
    for y in stats.min.1..=stats.max.1 {
        for x in stats.min.0..=stats.max.0 {
            if label(x, y) != id {
                continue;
            }
            let v = value(x, y);
            peak = peak.max(v);
            let inside = x > window.x0
                && y > window.y0
                && x + 1 < window.x1
                && y + 1 < window.y1
                && label(x - 1, y) == id
                && label(x + 1, y) == id
                && label(x, y - 1) == id
                && label(x, y + 1) == id;
            if inside {
                interior.push(v);
                let left = previous_interior.filter(|&(px, py, _, _)| py == y && px + 1 == x);
                if let Some((_, _, pv, before)) = left {
                    interior_steps.push((v - pv).abs());
                    if let Some(w) = before {
                        interior_curvatures.push((v - 2.0 * pv + w).abs());
                    }
                }
                previous_interior = Some((x, y, v, left.map(|(_, _, pv, _)| pv)));
            }
        }
    }
    let (plateau, top) = if interior.len() >= 3 {
        (median(&mut interior), quantile(&mut interior, TOP_QUANTILE))
    } else {
        (peak, peak)
    };
    let plateau_noise = if interior_steps.len() >= 8 {
        neighbour_noise(&mut interior_steps)
    } else {
        noise
    };
    let step = plateau - background;
    let contrast = step / context.full_scale;
    if !(contrast >= config.min_contrast && step > 0.0) {
        return Err(Reason::Contrast);
    }
    let half = background + 0.5 * step;
    // A shaded sphere (module docs): its interior's top stands above its
    // median by a share of the step that a flat disc's noise and a
    // retroreflector's slight limb darkening do not reach.
    let shaded = top - plateau > SHADED_RISE * (top - background);

    // The pixels above the half level, other components out; the centroid
    // over the pixels at least `CENTROID_FLOOR` of the step above the
    // background, so that a dimmer support beside the sphere, below that
    // floor, does not pull it.
    let floor = CENTROID_FLOOR * step;
    let (mut bright_area, mut centroid_sum, mut sum_x, mut sum_y) = (0usize, 0.0, 0.0, 0.0);
    for y in y0..=y1 {
        for x in x0..=x1 {
            if foreign(x, y) {
                continue;
            }
            let w = value(x, y) - background;
            bright_area += usize::from(value(x, y) >= half);
            if w >= floor {
                centroid_sum += w;
                sum_x += w * x as f64;
                sum_y += w * y as f64;
            }
        }
    }
    let centroid_px = Vector2::new(sum_x / centroid_sum, sum_y / centroid_sum);

    // Subpixel edge points (module docs): a crossing of the global half
    // level between neighbours, the brighter in this component, marks an
    // edge; it is kept when the scan runs within 45° of the intensity
    // gradient there, and placed where the profile of four samples along
    // the scan crosses the half-way level between its own inside and
    // outside levels.
    let inside = |x: usize, y: usize| x >= x0 && x <= x1 && y >= y0 && y <= y1;
    let mut crossings: Vec<Crossing> = Vec::new();
    let mut crossing = |a: (usize, usize), b: (usize, usize)| {
        if foreign(a.0, a.1) || foreign(b.0, b.1) {
            return;
        }
        let (va, vb) = (value(a.0, a.1), value(b.0, b.1));
        if (va >= half) == (vb >= half) {
            return;
        }
        let (bright, dark) = if va >= half { (a, b) } else { (b, a) };
        if label(bright.0, bright.1) != id {
            return;
        }
        // Unit step from bright to dark, and the samples one further in
        // and one further out.
        let (dx, dy) = (
            dark.0 as isize - bright.0 as isize,
            dark.1 as isize - bright.1 as isize,
        );
        let shift = |p: (usize, usize), k: isize| -> Option<(usize, usize)> {
            let x = p.0.checked_add_signed(k * dx)?;
            let y = p.1.checked_add_signed(k * dy)?;
            (inside(x, y) && !foreign(x, y)).then_some((x, y))
        };
        let (Some(inner2), Some(inner), Some(outer), Some(outer2)) = (
            shift(bright, -2),
            shift(bright, -1),
            shift(dark, 1),
            shift(dark, 2),
        ) else {
            return;
        };
        // The gradient at the crossing, by central differences across it.
        let (ax, ay) = (dy.unsigned_abs(), dx.unsigned_abs());
        let across = |p: (usize, usize)| -> Option<f64> {
            let plus = shift_across(p, (ax, ay), 1, &inside, &foreign)?;
            let minus = shift_across(p, (ax, ay), -1, &inside, &foreign)?;
            Some(value(plus.0, plus.1) - value(minus.0, minus.1))
        };
        let along = value(outer.0, outer.1) - value(inner.0, inner.1);
        let (Some(across_bright), Some(across_dark)) = (across(bright), across(dark)) else {
            return;
        };
        let across = 0.5 * (across_bright + across_dark);
        if along.abs() < across.abs() {
            return;
        }
        // Six samples along the scan, at −2…3 steps from `bright`.
        let samples = [inner2, inner, bright, dark, outer, outer2].map(|q| value(q.0, q.1));
        let inside_level = samples[0];
        let outside_level = local_outside_level(samples[3], samples[4], samples[5], noise);
        let local_step = inside_level - outside_level;
        if local_step < MIN_LOCAL_STEP * step {
            return;
        }
        crossings.push(Crossing {
            bright: (bright.0 as f64, bright.1 as f64),
            step: (dx as f64, dy as f64),
            samples,
            outside_level,
            local_step,
        });
    };
    for y in y0..=y1 {
        for x in x0..=x1 {
            if x < x1 {
                crossing((x, y), (x + 1, y));
            }
            if y < y1 {
                crossing((x, y), (x, y + 1));
            }
        }
    }
    // A flat disc's step blurred wider than the six samples (the lens's
    // blur about 1 px or more) leaves too little of the step inside them
    // for the sum; its half level's crossing is the edge then, as on a
    // shaded sphere (module docs).
    let mut falls: Vec<f64> = crossings
        .iter()
        .map(|c| (c.samples[2] - c.samples[3]) / c.local_step)
        .collect();
    let wide = shaded || (!falls.is_empty() && median(&mut falls) < SHARP_FALL_SHARE);
    let edges: Vec<(Vector2<f64>, f64)> = crossings.iter().map(|c| c.placed(wide, half)).collect();
    // Undistorted pixels: K · undistort(p).
    let camera = context.camera;
    let focal = Vector2::new(camera.fx(), camera.fy());
    let principal = Vector2::new(camera.cx(), camera.cy());
    let ideal = |p: &Vector2<f64>| -> Option<Vector2<f64>> {
        if camera.has_distortion() {
            camera
                .pixel_to_normalised(p)
                .ok()
                .map(|m| m.component_mul(&focal) + principal)
        } else {
            Some(*p)
        }
    };
    let mut points = Vec::with_capacity(edges.len());
    let mut tolerances = Vec::with_capacity(edges.len());
    // Edge samples straddle the background and the plateau, whose noise
    // differs (shot noise).
    let edge_noise = (0.5 * (noise * noise + plateau_noise * plateau_noise)).sqrt();
    let mut sigmas = Vec::with_capacity(edges.len());
    for (p, noise_gain) in &edges {
        if let Some(q) = ideal(p) {
            points.push(q);
            let sigma = noise_gain * edge_noise;
            sigmas.push(sigma);
            tolerances.push(MIN_EDGE_TOLERANCE_PX.max(EDGE_OUTLIER_SIGMAS * sigma));
        }
    }
    let Some(OutlineFit {
        ellipse,
        kept: inliers,
        notch,
    }) = fit_outline(&points, &sigmas, &tolerances)
    else {
        return Err(Reason::Shape);
    };
    let kept = inliers.iter().filter(|k| **k).count();
    let fit_residual_px = (points
        .iter()
        .zip(&inliers)
        .filter(|(_, keep)| **keep)
        .map(|(p, _)| ellipse.distance(p).powi(2))
        .sum::<f64>()
        / kept.max(1) as f64)
        .sqrt();
    let cut = notch.iter().filter(|c| **c).count();
    let total = points.len().max(1) as f64;
    let outline_dropped = cut as f64 / total;
    let outlier_fraction = inliers
        .iter()
        .zip(&notch)
        .filter(|(keep, cut)| !**keep && !**cut)
        .count() as f64
        / total;
    // The dip of what is left: a notch too shallow or short to cut away.
    let (kept_points, kept_sigmas): (Vec<Vector2<f64>>, Vec<f64>) = points
        .iter()
        .zip(&sigmas)
        .zip(&notch)
        .filter(|(_, cut)| !**cut)
        .map(|((p, s), _)| (*p, *s))
        .unzip();
    let edge_dip_px = edge_dip(&ellipse, &kept_points, &kept_sigmas);
    // The pixels above the half level cover the silhouette's area (the
    // edge lies at the half level), however the sphere's shading falls
    // off towards its limb.
    let filled_fraction = bright_area as f64 / ellipse.area();

    let normalised = ellipse.scaled(
        &Vector2::new(1.0 / focal.x, 1.0 / focal.y),
        &Vector2::new(-principal.x / focal.x, -principal.y / focal.y),
    );
    let sphere = SphereFromEllipse::of(&normalised);
    let limit = MAX_AXIS_RATIO_FACTOR * sphere.expected_axis_ratio;
    if sphere.axis_ratio.is_nan() || sphere.axis_ratio > limit {
        return Err(Reason::Shape);
    }
    let centroid_normalised = camera
        .pixel_to_normalised(&centroid_px)
        .map_err(|_| Reason::Shape)?;
    let (major, minor, _) = ellipse.axes();
    let usable = |x: usize, y: usize| {
        (window.x0..window.x1).contains(&x) && (window.y0..window.y1).contains(&y) && !foreign(x, y)
    };
    let (window_ideal, window_noise_px) = window_centroid(
        &ellipse,
        camera.normalised_to_pixel(&(ellipse.centre - principal).component_div(&focal)),
        (width, height),
        &WindowAccess {
            value: &value,
            usable: &usable,
            ideal: &ideal,
        },
        background,
        &LevelNoise {
            background: noise,
            // Second differences along the rows: a shaded sphere's radiance
            // slopes across its interior, which a first difference counts
            // as noise (a second difference has three times a first
            // difference's variance).
            plateau: if interior_curvatures.len() >= 8 {
                neighbour_noise(&mut interior_curvatures) / 3f64.sqrt()
            } else {
                plateau_noise
            },
            step,
        },
    )
    .ok_or(Reason::Shape)?;
    let window_centroid_normalised = (window_ideal - principal).component_div(&focal);
    let centre_shrink = 1.0 + sphere.minor_normalised.powi(2);

    let mut hidden_because = Vec::new();
    if touches_border {
        hidden_because.push("touches the image border");
    }
    if filled_fraction < config.min_filled_fraction {
        hidden_because.push("fills too little of its ellipse");
    }
    if outlier_fraction > config.max_outlier_fraction {
        hidden_because.push("edge leaves the ellipse");
    }
    if outline_dropped > config.max_outline_dropped {
        hidden_because.push("too much outline cut away");
    }
    if edge_dip_px > config.max_edge_dip_px {
        hidden_because.push("edge dips inside the ellipse");
    }
    if (sphere.axis_ratio - sphere.expected_axis_ratio).abs() > MAX_AXIS_RATIO_ERROR {
        hidden_because.push("axis ratio not a sphere's");
    }
    let to_array = |v: Vector2<f64>| [v.x, v.y];
    Ok(Blob {
        area_px: stats.count,
        contrast,
        noise: noise / context.full_scale,
        centroid_px: to_array(centroid_px),
        window_centroid_px: to_array(camera.normalised_to_pixel(&window_centroid_normalised)),
        ellipse_centre_px: to_array(camera.normalised_to_pixel(&normalised.centre)),
        centre_px: to_array(camera.normalised_to_pixel(&sphere.centre_normalised)),
        semi_axes_px: [major, minor],
        depth_mm: sphere.depth_mm(context.radius_mm),
        edge_points: points.len(),
        fit_residual_px,
        centre_noise_px: fit_residual_px * (2.0 / kept.max(1) as f64).sqrt(),
        shaded,
        window_noise_px,
        outlier_fraction,
        outline_dropped,
        edge_dip_px,
        filled_fraction,
        axis_ratio: sphere.axis_ratio,
        expected_axis_ratio: sphere.expected_axis_ratio,
        hidden_because,
        label: None,
        bias: None,
        ellipse_centre_normalised: normalised.centre,
        centroid_normalised,
        window_centroid_normalised,
        centre_shrink,
        ellipse_px: ellipse,
    })
}

mod outline;
mod subpixel;
pub use outline::{edge_dip, fit_outline, notch_arcs, OutlineFit};
use subpixel::{window_centroid, Crossing, LevelNoise, WindowAccess};

#[cfg(test)]
mod tests;
