//! How far a render of the part departs from a camera frame around one
//! blob ([`Likeness`]): the check `track --refine` makes before it keeps a
//! sphere's correction ([`super::refine`]).

use super::detect::Blob;
use super::frame::GreyFrame;
use nalgebra::{Matrix4, Vector2, Vector4};
use serde::Serialize;

/// Pixels around a blob's ellipse (its semi-major axis from the ellipse
/// centre, plus this) over which [`Likeness`] compares the frame with the
/// render: the limb's blurred ramp and the background right outside it,
/// what the blob's edge points see.
pub const LIKENESS_MARGIN_PX: f64 = 2.0;
/// Pixels this close to the blob's fitted outline are left out of
/// [`Likeness`]: there the render drawn at the first pose differs from the
/// frame by the pose's own error (a tenth of a pixel moves a sharp edge's
/// pixels by a tenth of the step, beyond what a linear shift takes up),
/// which is what the refinement is there to remove, not a mismatch of look.
pub const LIKENESS_EDGE_BAND_PX: f64 = 1.5;
/// A render matches the frame around a blob when the residual RMS is at
/// most this many times the frame's own pixel noise there.
pub const MAX_MISMATCH: f64 = 1.3;
/// The least noise [`Likeness::matches`] judges against, fraction of full
/// scale: a noise-free frame still differs from the render by its own
/// sampling and quantisation.
pub const LIKENESS_NOISE_FLOOR: f64 = 0.003;

/// How far a render at the pose departs from the frame around one blob
/// (docs/formats.md, "`track` output"). The render is fitted to the frame
/// first (least squares: a gain, an offset and a subpixel shift), so
/// exposure, the radiances' scale and the pose's own small error do not
/// count; what is left is the look: the sphere's shading, the support's
/// and the background's levels relative to the sphere's, the blur.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Likeness {
    /// RMS of the frame less the fitted render, fraction of full scale.
    pub residual: f64,
    /// The frame's pixel noise there: the spread of the residual's
    /// differences between horizontal neighbours over √2. White noise
    /// doubles its variance in such a difference; a mismatch of look,
    /// smooth over pixels, hardly shows in it.
    pub noise: f64,
    /// The gain fitted to the render.
    pub gain: f64,
}

impl Likeness {
    /// The likeness over the pixels within [`LIKENESS_MARGIN_PX`] of `blob`'s
    /// ellipse (a disc about its centre); `None` when too few pixels lie in
    /// the frame or the render is flat there.
    pub fn around(frame: &GreyFrame, render: &GreyFrame, blob: &Blob) -> Option<Likeness> {
        let (width, height) = (frame.width() as usize, frame.height() as usize);
        if (render.width() as usize, render.height() as usize) != (width, height) {
            return None;
        }
        let [u, v] = blob.ellipse_centre_px;
        let reach = blob.semi_axes_px[0] + LIKENESS_MARGIN_PX;
        let f_scale = 1.0 / f64::from(frame.full_scale());
        let g_scale = 1.0 / f64::from(render.full_scale());
        let rows =
            (v - reach).floor().max(0.0) as usize..((v + reach).ceil() as usize + 1).min(height);
        let columns =
            (u - reach).floor().max(0.0) as usize..((u + reach).ceil() as usize + 1).min(width);
        let outline = &blob.ellipse_px;
        let inside = |x: usize, y: usize| {
            let p = Vector2::new(x as f64, y as f64);
            (p - Vector2::new(u, v)).norm_squared() <= reach * reach
                && outline.distance(&p).abs() >= LIKENESS_EDGE_BAND_PX
        };
        let at = |image: &GreyFrame, x: usize, y: usize, scale: f64| {
            f64::from(image.pixels()[y * width + x]) * scale
        };
        // Least squares of frame = gain · render + offset + a shift of
        // the render (its gradient, by central differences, times the
        // shift): the pose the render is drawn at is off by the error the
        // refinement is there to take away, which moves every edge a
        // little, and that is no mismatch of look.
        let features = |x: usize, y: usize| -> Vector4<f64> {
            let g = |x: usize, y: usize| at(render, x, y, g_scale);
            let dx = 0.5 * (g((x + 1).min(width - 1), y) - g(x.saturating_sub(1), y));
            let dy = 0.5 * (g(x, (y + 1).min(height - 1)) - g(x, y.saturating_sub(1)));
            Vector4::new(g(x, y), 1.0, dx, dy)
        };
        let mut normal = Matrix4::zeros();
        let mut moment = Vector4::zeros();
        let mut n = 0usize;
        for y in rows.clone() {
            for x in columns.clone().filter(|&x| inside(x, y)) {
                let a = features(x, y);
                normal += a * a.transpose();
                moment += a * at(frame, x, y, f_scale);
                n += 1;
            }
        }
        if n < 16 {
            return None;
        }
        let fit = normal.cholesky()?.solve(&moment);
        let residual_at = |x: usize, y: usize| at(frame, x, y, f_scale) - fit.dot(&features(x, y));
        let (mut squares, mut differences, mut pairs) = (0.0f64, 0.0, 0usize);
        for y in rows.clone() {
            for x in columns.clone().filter(|&x| inside(x, y)) {
                let r = residual_at(x, y);
                squares += r * r;
                if x + 1 < width && inside(x + 1, y) {
                    differences += (r - residual_at(x + 1, y)).powi(2);
                    pairs += 1;
                }
            }
        }
        let n = n as f64;
        let pairs = pairs.max(1) as f64;
        let gain = fit[0];
        Some(Likeness {
            residual: (squares / n).sqrt(),
            noise: (differences / (2.0 * pairs)).sqrt(),
            gain,
        })
    }

    /// Whether the render is like the frame (module docs): the residual
    /// within [`MAX_MISMATCH`] times the noise (at least
    /// [`LIKENESS_NOISE_FLOOR`]).
    pub fn matches(&self) -> bool {
        self.residual <= MAX_MISMATCH * self.noise.max(LIKENESS_NOISE_FLOOR)
    }
}
