//! The subpixel measures of one blob ([`super`], module docs, step 3):
//! where a half-level crossing places the edge, and the windowed centroid
//! with its σ from the pixel noise.

use super::{EDGE_SUM_NOISE, WINDOW_MARGIN_PX};
use crate::track::conic::Ellipse;
use nalgebra::Vector2;

/// How [`window_centroid`] reads the frame: a pixel's level, whether it
/// may count (inside the labelled window and no other component's), and
/// its undistorted position.
pub(super) struct WindowAccess<'a> {
    pub(super) value: &'a dyn Fn(usize, usize) -> f64,
    pub(super) usable: &'a dyn Fn(usize, usize) -> bool,
    pub(super) ideal: &'a dyn Fn(&Vector2<f64>) -> Option<Vector2<f64>>,
}

/// The pixel noise [`window_centroid`] propagates: σ at the background
/// and on the plateau (shot noise grows with the level), and the step
/// between them, in the frame's levels.
pub(super) struct LevelNoise {
    pub(super) background: f64,
    pub(super) plateau: f64,
    pub(super) step: f64,
}

impl LevelNoise {
    /// The variance of a pixel `above` the background: the two ends'
    /// variances, linear in the level between them (shot noise).
    fn variance(&self, above: f64) -> f64 {
        let share = if self.step > 0.0 {
            (above / self.step).clamp(0.0, 1.0)
        } else {
            0.0
        };
        self.background.powi(2) + share * (self.plateau.powi(2) - self.background.powi(2))
    }
}

/// The windowed centroid of [`super::Blob::window_centroid_px`], undistorted px,
/// and its σ per axis from `noise` ([`super::Blob::window_noise_px`]):
/// over the usable pixels inside `ellipse` (undistorted px, about
/// `raw_centre` in the frame) grown by [`WINDOW_MARGIN_PX`] along its minor
/// axis, each weighing its level above `background` (none below it),
/// however far from the half level. `None` when no pixel rises above it.
pub(super) fn window_centroid(
    ellipse: &Ellipse,
    raw_centre: Vector2<f64>,
    (width, height): (usize, usize),
    access: &WindowAccess<'_>,
    background: f64,
    noise: &LevelNoise,
) -> Option<(Vector2<f64>, f64)> {
    let (major, minor, _) = ellipse.axes();
    let scale = 1.0 + WINDOW_MARGIN_PX / minor;
    let reach = scale * major + 1.0;
    let span = |c: f64, size: usize| {
        let low = (c - reach).floor().max(0.0) as usize;
        let high = ((c + reach).ceil().max(0.0) as usize).min(size - 1);
        low..=high
    };
    let (mut sum, mut moment) = (0.0, Vector2::zeros());
    // Σ σᵢ², Σ σᵢ² pᵢ and Σ σᵢ² pᵢ² per axis: the centroid's variance
    // Σ σᵢ² (pᵢ − c)² / sum² once c is known. A pixel at the background
    // counts too: its noise decides whether it weighs in.
    let (mut variance, mut variance_moment, mut variance_square) =
        (0.0, Vector2::zeros(), Vector2::zeros());
    for y in span(raw_centre.y, height) {
        for x in span(raw_centre.x, width) {
            if !(access.usable)(x, y) {
                continue;
            }
            let Some(p) = (access.ideal)(&Vector2::new(x as f64, y as f64)) else {
                continue;
            };
            let d = p - ellipse.centre;
            if d.dot(&(ellipse.shape * d)) > scale * scale {
                continue;
            }
            let w = (access.value)(x, y) - background;
            let v = noise.variance(w);
            variance += v;
            variance_moment += v * p;
            variance_square += v * p.component_mul(&p);
            if w > 0.0 {
                sum += w;
                moment += w * p;
            }
        }
    }
    if sum <= 0.0 {
        return None;
    }
    let c = moment / sum;
    let spread =
        variance_square - 2.0 * variance_moment.component_mul(&c) + variance * c.component_mul(&c);
    let sigma = (0.5 * spread.map(|s| s.max(0.0)).sum()).sqrt() / sum;
    Some((c, sigma))
}

/// One half-level crossing of a blob's edge ([`super`], module docs): the brighter
/// pixel, the unit step from it to the darker one, the six samples at
/// −2…3 steps from it, and the local outside level and step there.
pub(super) struct Crossing {
    pub(super) bright: (f64, f64),
    pub(super) step: (f64, f64),
    pub(super) samples: [f64; 6],
    pub(super) outside_level: f64,
    pub(super) local_step: f64,
}

impl Crossing {
    /// The edge point and its position noise over the pixel noise: at the
    /// `half` level's own crossing, interpolated between the two pixels
    /// that straddle it, where the step is `wide` (a shaded sphere, or a
    /// blur wider than the samples); else where the samples' shares of
    /// the local step put it.
    pub(super) fn placed(&self, wide: bool, half: f64) -> (Vector2<f64>, f64) {
        let samples = &self.samples;
        let (t, noise_gain) = if wide {
            // A shaded sphere's radiance rises all the way in from its
            // limb, and a widely blurred step's samples hold no level of
            // their own: a step placed against one would sit deeper or
            // shallower with the edge's subpixel phase and the scan's
            // angle to the outline (a ripple of a few tenths of a pixel
            // that reads as notches). The half level's crossing is a
            // contour of the profile: on a shaded sphere an outline of the
            // silhouette's centre a little inside its limb, on a blurred
            // flat disc the limb itself.
            let fall = samples[2] - samples[3];
            let t = (samples[2] - half) / fall;
            (t, ((1.0 - t).powi(2) + t * t).sqrt() / fall)
        } else {
            // A box-filtered (and narrowly blurred) step: the samples'
            // shares of the local step add up to the bright run's length,
            // so the edge lies Σ u − 1.5 steps beyond `bright` (exact for
            // an area-sampled straight edge, whatever its phase).
            let run: f64 = samples[1..5]
                .iter()
                .map(|v| ((v - self.outside_level) / self.local_step).clamp(0.0, 1.0))
                .sum();
            (run - 1.5, EDGE_SUM_NOISE / self.local_step)
        };
        (
            Vector2::new(
                self.bright.0 + t * self.step.0,
                self.bright.1 + t * self.step.1,
            ),
            noise_gain,
        )
    }
}
