//! The renderer: a pose and the part in, a noise-free radiance image out
//! ([`render_radiance`]), then the sensor ([`super::sensor`]) and the ground
//! truth ([`super::truth`]). No files.
//!
//! **Where rays go.** The background is uniform, so only tiles of
//! [`TILE_PX`] × [`TILE_PX`] pixels that the projection of some primitive's
//! bounding ball may touch are traced, each against the primitives that
//! may touch it. In such a tile one ray goes through every pixel corner.
//! A pixel whose four corners all meet the same surface — the same
//! primitive and material, or the background — takes the mean of its
//! corners; any other pixel, i.e. every pixel an edge crosses, is
//! supersampled on an n × n grid. (An edge that enters a pixel between two
//! corners and leaves it between the same two — a silhouette bulging by
//! its sagitta — is missed: for a curve of radius R px that is at most
//! 1/(8R) px deep, under 0.02 px for the smallest discs drawn.) Every sample is undistorted to its ray through the camera's
//! Brown–Conrady model ([`Camera::pixel_to_normalised`]), exactly as the
//! rest of the tool maps pixels to rays.
//!
//! **Pixels.** Pixel (u, v) is centred on integer coordinates and covers
//! `[u − ½, u + ½] × [v − ½, v + ½]` (OpenCV's convention); its value is the
//! mean radiance over that square (a box filter), then the lens's Gaussian
//! blur.

use super::config::{Appearance, Lighting, RenderConfig};
use super::scene::{Hit, Ray, Scene};
use super::RenderError;
use crate::camera::Camera;
use crate::pose::Pose;
use nalgebra::{Vector2, Vector3};

/// Side of a tile, px.
pub const TILE_PX: usize = 16;
/// Corners of the tile's pixels, per side.
const CORNERS: usize = TILE_PX + 1;
/// Vertices of the polygon that bounds a ball's projected outline.
const OUTLINE_VERTICES: usize = 16;
/// Pixels added around a ball's projected outline (the polygon is
/// inscribed in the outline, and the corner rays see a pixel beyond it).
const OUTLINE_MARGIN_PX: f64 = 2.0;
/// A pixel whose corners meet one surface is taken as the mean of its
/// corners only if their radiances differ by at most this (a fraction of
/// full scale); across a rounded edge, where the shading falls steeply
/// within a pixel, it is supersampled.
const SHADE_SPREAD: f32 = 1.0 / 16.0;
/// The least radiance a unit channel's shading spread is weighed at when
/// deciding to supersample a pixel ([`render_channels_within`]): the
/// brightest support of the presets (the diffuse one's grey body).
const CHANNEL_SPREAD_FLOOR: f64 = 0.5;
/// A surface id for "no surface".
const BACKGROUND: u32 = u32::MAX;

/// A grey image of radiances (fractions of full scale, exposure applied),
/// row-major.
#[derive(Debug, Clone, PartialEq)]
pub struct Radiance {
    /// Width, px.
    pub width: usize,
    /// Height, px.
    pub height: usize,
    /// `height` rows of `width` values.
    pub values: Vec<f32>,
}

/// Renders the part at `pose` without noise: radiance per pixel, box
/// filtered over the pixel and blurred (module docs).
pub fn render_radiance(
    scene: &Scene,
    pose: &Pose,
    config: &RenderConfig,
) -> Result<Radiance, RenderError> {
    render_radiance_within(scene, pose, config, None)
}

/// A part placed in the camera's view: one marker of a scene.
#[derive(Debug, Clone, Copy)]
pub struct Placed<'a> {
    /// The part.
    pub scene: &'a Scene,
    /// Marker → camera.
    pub pose: &'a Pose,
}

/// Renders several parts in one frame without noise, each at its own pose
/// and each hiding what lies behind it of the others (module docs). The
/// blur is one for the frame: none or a fixed Gaussian ([`Blur`]); a
/// defocus, which differs from part to part, is refused.
///
/// [`Blur`]: super::config::Blur
pub fn render_scene(parts: &[Placed], config: &RenderConfig) -> Result<Radiance, RenderError> {
    let sigma_px = scene_blur_px(config, parts)?;
    render_parts(parts, sigma_px, config, None)
}

/// The one blur of a frame of `parts`, px (σ): a lone part's as
/// [`blur_at`]; for several, a fixed Gaussian or none, and a defocus,
/// which differs from part to part, refused.
pub fn scene_blur_px(config: &RenderConfig, parts: &[Placed]) -> Result<f64, RenderError> {
    match (parts, config.optics.blur) {
        ([one], _) => blur_at(config, one.pose, 0),
        (_, super::config::Blur::Defocus { .. }) => {
            Err(RenderError::Config(crate::config::ConfigError::new(
                "blur",
                "a frame of several markers takes one blur (a Gaussian of fixed σ, or none); a defocus differs from marker to marker",
            )))
        }
        (_, blur) => Ok(blur.sigma_px(config.camera.fx(), 1.0)),
    }
}

/// [`render_radiance`] traced only in the tiles that meet one of the
/// `regions` (`(x0, y0, x1, y1)`, px, ends excluded) when given; the rest
/// of the image is left at the background's radiance. Within a region,
/// every pixel farther than the blur's reach from its border is the full
/// render's (to the rounding of a blurred uniform background).
pub fn render_radiance_within(
    scene: &Scene,
    pose: &Pose,
    config: &RenderConfig,
    regions: Option<&[(usize, usize, usize, usize)]>,
) -> Result<Radiance, RenderError> {
    let sigma_px = blur_at(config, pose, 0)?;
    render_parts(&[Placed { scene, pose }], sigma_px, config, regions)
}

/// The render of `parts`, blurred by `sigma_px` (see
/// [`render_radiance_within`] for `regions`).
pub(super) fn render_parts(
    parts: &[Placed],
    sigma_px: f64,
    config: &RenderConfig,
    regions: Option<&[(usize, usize, usize, usize)]>,
) -> Result<Radiance, RenderError> {
    let (width, height, values) = trace_parts::<f32>(parts, config, regions)?;
    let mut image = Radiance {
        width,
        height,
        values: values.pixels,
    };
    if let Some(region) = values.active {
        gaussian_blur(&mut image, sigma_px, region);
    }
    Ok(image)
}

/// The render of one part at `pose` within `regions` (as
/// [`render_radiance_within`]), in three images at once: the sphere's
/// coating alone, the supports alone and the background alone, each at
/// unit radiance, so that the render with radiances `(a, b, c)` is
/// `a·[0] + b·[1] + c·[2]` (the lighting, the shading and the exposure
/// as `config` gives them). One tracing pass: an edge pixel is
/// supersampled where any of the three needs it.
pub fn render_channels_within(
    scene: &Scene,
    pose: &Pose,
    config: &RenderConfig,
    regions: Option<&[(usize, usize, usize, usize)]>,
) -> Result<[Radiance; 3], RenderError> {
    let sigma_px = blur_at(config, pose, 0)?;
    let (width, height, values) =
        trace_parts::<[f32; 3]>(&[Placed { scene, pose }], config, regions)?;
    Ok(std::array::from_fn(|k| {
        let mut image = Radiance {
            width,
            height,
            values: values.pixels.iter().map(|v| v[k]).collect(),
        };
        if let Some(region) = values.active {
            gaussian_blur(&mut image, sigma_px, region);
        }
        image
    }))
}

/// Traced pixels before the blur, and the box of the tiles traced.
struct Traced<T> {
    pixels: Vec<T>,
    active: Option<(usize, usize, usize, usize)>,
}

/// Traces `parts` in the tiles that may show them (within `regions` when
/// given): the image's width, height and pixels (module docs).
fn trace_parts<T: Texel>(
    parts: &[Placed],
    config: &RenderConfig,
    regions: Option<&[(usize, usize, usize, usize)]>,
) -> Result<(usize, usize, Traced<T>), RenderError> {
    let camera = &config.camera;
    let appearance = &config.appearance;
    let (width, height) = (camera.width() as usize, camera.height() as usize);
    let mut traced = Traced {
        pixels: vec![T::background(appearance); width * height],
        active: None,
    };
    let tiles = tile_candidates(parts, camera);
    let tiles_x = width.div_ceil(TILE_PX);
    let shader = Shader {
        camera,
        appearance,
        parts: parts
            .iter()
            .map(|part| {
                let inverse = part.pose.rotation.inverse();
                PartView {
                    scene: part.scene,
                    inverse_rotation: inverse.into_inner(),
                    origin: -(inverse * part.pose.translation),
                    light: inverse * appearance.light_direction_camera(),
                }
            })
            .collect(),
    };
    for (index, candidates) in tiles.iter().enumerate() {
        if candidates.shapes.is_empty() {
            continue;
        }
        let (x0, y0) = ((index % tiles_x) * TILE_PX, (index / tiles_x) * TILE_PX);
        let meets = |&(a, b, c, d): &(usize, usize, usize, usize)| {
            a < x0 + TILE_PX && x0 < c && b < y0 + TILE_PX && y0 < d
        };
        if regions.is_some_and(|regions| !regions.iter().any(meets)) {
            continue;
        }
        render_tile(
            &shader,
            candidates,
            (x0, y0),
            config.optics.supersampling as usize,
            (width, height),
            &mut traced.pixels,
        )?;
        let (x1, y1) = ((x0 + TILE_PX).min(width), (y0 + TILE_PX).min(height));
        traced.active = Some(match traced.active {
            None => (x0, y0, x1, y1),
            Some((a, b, c, d)) => (a.min(x0), b.min(y0), c.max(x1), d.max(y1)),
        });
    }
    Ok((width, height, traced))
}

/// What a sample carries: one radiance ([`f32`]), or the three unit
/// channels of [`render_channels_within`] (`[f32; 3]`: the coating, the
/// supports, the background).
trait Texel: Copy {
    /// The background's value.
    fn background(appearance: &Appearance) -> Self;
    /// A surface's value: `factor` (its shading and the exposure) times
    /// its radiance, on the sphere's coating when `sphere`.
    fn surface(appearance: &Appearance, sphere: bool, factor: f64) -> Self;
    /// The mean of four corners.
    fn mean4(corners: [Self; 4]) -> Self;
    /// The largest spread between the four corners, over the channels,
    /// as a fraction of full scale under `appearance`.
    fn spread(corners: [Self; 4], appearance: &Appearance) -> f32;
    /// Adds the value to a running sum, in f64.
    fn accumulate(self, sum: &mut [f64; 3]);
    /// A sum over `n` samples made a mean.
    fn mean_of(sum: [f64; 3], n: usize) -> Self;
}

fn spread_of(values: [f32; 4]) -> f32 {
    let (low, high) = values
        .iter()
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(l, h), &c| {
            (l.min(c), h.max(c))
        });
    high - low
}

impl Texel for f32 {
    fn background(a: &Appearance) -> Self {
        (a.background_radiance * a.exposure) as f32
    }
    fn surface(a: &Appearance, sphere: bool, factor: f64) -> Self {
        let radiance = if sphere {
            a.sphere_radiance
        } else {
            a.support_radiance
        };
        (radiance * factor) as f32
    }
    fn mean4(c: [Self; 4]) -> Self {
        0.25 * (c[0] + c[1] + c[2] + c[3])
    }
    fn spread(c: [Self; 4], _: &Appearance) -> f32 {
        spread_of(c)
    }
    fn accumulate(self, sum: &mut [f64; 3]) {
        sum[0] += f64::from(self);
    }
    fn mean_of(sum: [f64; 3], n: usize) -> Self {
        (sum[0] / n as f64) as f32
    }
}

impl Texel for [f32; 3] {
    fn background(a: &Appearance) -> Self {
        [0.0, 0.0, a.exposure as f32]
    }
    fn surface(_: &Appearance, sphere: bool, factor: f64) -> Self {
        let factor = factor as f32;
        if sphere {
            [factor, 0.0, 0.0]
        } else {
            [0.0, factor, 0.0]
        }
    }
    fn mean4(c: [Self; 4]) -> Self {
        std::array::from_fn(|k| 0.25 * (c[0][k] + c[1][k] + c[2][k] + c[3][k]))
    }
    /// Each unit channel's spread at the look's radiance, or at
    /// [`CHANNEL_SPREAD_FLOOR`] where the look's is dimmer: the levels are
    /// fitted after the render, and may come out brighter than the look's.
    fn spread(c: [Self; 4], a: &Appearance) -> f32 {
        let weights = [
            a.sphere_radiance.max(CHANNEL_SPREAD_FLOOR),
            a.support_radiance.max(CHANNEL_SPREAD_FLOOR),
            1.0,
        ];
        (0..3)
            .map(|k| weights[k] as f32 * spread_of([c[0][k], c[1][k], c[2][k], c[3][k]]))
            .fold(0.0, f32::max)
    }
    fn accumulate(self, sum: &mut [f64; 3]) {
        for (s, v) in sum.iter_mut().zip(self) {
            *s += f64::from(v);
        }
    }
    fn mean_of(sum: [f64; 3], n: usize) -> Self {
        sum.map(|s| (s / n as f64) as f32)
    }
}

/// The blur of a render at `pose`, px (σ), or [`RenderError::TooBlurred`]
/// for frame `frame` when the defocus there exceeds what a render draws.
pub fn blur_at(config: &RenderConfig, pose: &Pose, frame: usize) -> Result<f64, RenderError> {
    let depth_mm = pose.translation.z;
    let sigma_px = config.optics.blur.sigma_px(config.camera.fx(), depth_mm);
    let max = super::config::MAX_BLUR_SIGMA_PX;
    if sigma_px.is_nan() || sigma_px > max {
        return Err(RenderError::TooBlurred {
            frame,
            sigma_px,
            depth_mm,
            max,
        });
    }
    Ok(sigma_px)
}

/// The primitives that may meet a tile: their indices, part after part,
/// and where each part's run of them ends.
#[derive(Debug, Clone, Default)]
struct TileList {
    shapes: Vec<u32>,
    /// (part, end of its run in `shapes`), parts in order.
    parts: Vec<(usize, usize)>,
}

impl TileList {
    fn push(&mut self, part: usize, shape: u32) {
        match self.parts.last_mut() {
            Some((last, end)) if *last == part => {
                if self.shapes.last() != Some(&shape) {
                    self.shapes.push(shape);
                    *end += 1;
                }
            }
            _ => {
                self.shapes.push(shape);
                self.parts.push((part, self.shapes.len()));
            }
        }
    }

    /// Each part with its primitives.
    fn runs(&self) -> impl Iterator<Item = (usize, &[u32])> {
        let mut start = 0;
        self.parts.iter().map(move |&(part, end)| {
            let run = &self.shapes[start..end];
            start = end;
            (part, run)
        })
    }
}

/// For each tile, row-major, the primitives whose bounding balls' outlines
/// reach it.
fn tile_candidates(parts: &[Placed], camera: &Camera) -> Vec<TileList> {
    let (width, height) = (camera.width() as usize, camera.height() as usize);
    let (tiles_x, tiles_y) = (width.div_ceil(TILE_PX), height.div_ceil(TILE_PX));
    let mut tiles = vec![TileList::default(); tiles_x * tiles_y];
    for (part, placed) in parts.iter().enumerate() {
        for (shape, centre, radius) in placed.scene.bounding_balls() {
            let Some((lo, hi)) = outline_box(camera, &placed.pose.transform(&centre), radius)
            else {
                continue;
            };
            let clamp_tile = |value: f64, tiles: usize| -> Option<usize> {
                if value < 0.0 {
                    Some(0)
                } else {
                    let t = (value / TILE_PX as f64) as usize;
                    (t < tiles).then_some(t)
                }
            };
            if hi.x < 0.0 || hi.y < 0.0 {
                continue;
            }
            let (Some(tx0), Some(ty0)) = (clamp_tile(lo.x, tiles_x), clamp_tile(lo.y, tiles_y))
            else {
                continue;
            };
            let tx1 = clamp_tile(hi.x, tiles_x).unwrap_or(tiles_x - 1);
            let ty1 = clamp_tile(hi.y, tiles_y).unwrap_or(tiles_y - 1);
            for ty in ty0..=ty1 {
                for tx in tx0..=tx1 {
                    tiles[ty * tiles_x + tx].push(part, shape as u32);
                }
            }
        }
    }
    tiles
}

/// The pixel box holding the projected outline of a ball (camera frame),
/// grown by a margin; the whole plane when the ball reaches the camera's
/// plane.
fn outline_box(
    camera: &Camera,
    centre: &Vector3<f64>,
    radius: f64,
) -> Option<(Vector2<f64>, Vector2<f64>)> {
    let everywhere = Some((
        Vector2::repeat(f64::NEG_INFINITY),
        Vector2::repeat(f64::INFINITY),
    ));
    let distance = centre.norm();
    if centre.z <= radius * 1.01 || distance <= radius {
        return everywhere;
    }
    // The circle of tangency seen from the camera centre.
    let axis = centre / distance;
    let circle_centre = centre * (1.0 - radius * radius / (distance * distance));
    let circle_radius = radius * (distance * distance - radius * radius).sqrt() / distance;
    let (e1, e2) = crate::linalg::perpendicular_pair(&axis);
    let mut lo = Vector2::repeat(f64::INFINITY);
    let mut hi = Vector2::repeat(f64::NEG_INFINITY);
    for k in 0..OUTLINE_VERTICES {
        let phi = std::f64::consts::TAU * k as f64 / OUTLINE_VERTICES as f64;
        let point = circle_centre + (e1 * phi.cos() + e2 * phi.sin()) * circle_radius;
        let pixel = camera.project(&point)?;
        lo = lo.inf(&pixel);
        hi = hi.sup(&pixel);
    }
    // The polygon is inscribed: its sides cut inside the outline by at most
    // 1 − cos(π/n) of its size.
    let sag = (1.0 - (std::f64::consts::PI / OUTLINE_VERTICES as f64).cos()) * (hi - lo).max();
    let margin = Vector2::repeat(sag + OUTLINE_MARGIN_PX);
    Some((lo - margin, hi + margin))
}

/// One part as the rays meet it: its scene, and the camera's centre and
/// the light in its frame.
struct PartView<'a> {
    scene: &'a Scene,
    inverse_rotation: nalgebra::Matrix3<f64>,
    origin: Vector3<f64>,
    light: Vector3<f64>,
}

/// Everything a sample needs: the parts, the camera and the lighting.
struct Shader<'a> {
    camera: &'a Camera,
    appearance: &'a Appearance,
    parts: Vec<PartView<'a>>,
}

/// Bits of a surface id that name the primitive within its part.
const SHAPE_BITS: u32 = 20;

impl Shader<'_> {
    /// The ray through pixel position `(u, v)`, camera frame.
    fn direction(&self, u: f64, v: f64) -> Result<Vector3<f64>, RenderError> {
        let m = self
            .camera
            .pixel_to_normalised(&Vector2::new(u, v))
            .map_err(RenderError::Camera)?;
        Ok(Vector3::new(m.x, m.y, 1.0).normalize())
    }

    /// The surface id and value seen at pixel position `(u, v)`: the
    /// nearest hit over the parts.
    fn sample<T: Texel>(
        &self,
        u: f64,
        v: f64,
        candidates: &TileList,
    ) -> Result<(u32, T), RenderError> {
        let direction = self.direction(u, v)?;
        let mut nearest: Option<(usize, Hit, Vector3<f64>)> = None;
        for (part, shapes) in candidates.runs() {
            let view = &self.parts[part];
            let ray = Ray {
                origin: view.origin,
                direction: view.inverse_rotation * direction,
            };
            if let Some(hit) = view.scene.first_hit(&ray, shapes) {
                if nearest.is_none_or(|(_, best, _)| hit.t < best.t) {
                    nearest = Some((part, hit, ray.direction));
                }
            }
        }
        Ok(match nearest {
            None => (BACKGROUND, T::background(self.appearance)),
            Some((part, hit, direction)) => (
                2 * (((part as u32) << SHAPE_BITS) | hit.shape as u32)
                    + u32::from(hit.sphere.is_some()),
                T::surface(
                    self.appearance,
                    hit.sphere.is_some(),
                    self.shading(&self.parts[part], &hit, &direction),
                ),
            ),
        })
    }

    /// Radiance of a hit on `part` seen along `direction` (its frame;
    /// module docs of [`Lighting`]).
    #[cfg(test)]
    fn shade(&self, part: &PartView, hit: &Hit, direction: &Vector3<f64>) -> f64 {
        let a = self.appearance;
        let radiance = match hit.sphere {
            Some(_) => a.sphere_radiance,
            None => a.support_radiance,
        };
        radiance * self.shading(part, hit, direction)
    }

    /// What multiplies a hit's radiance (its coating's or its support's):
    /// its shading under the lighting, and the exposure.
    fn shading(&self, part: &PartView, hit: &Hit, direction: &Vector3<f64>) -> f64 {
        let a = self.appearance;
        let facing = (-hit.normal.dot(direction)).max(0.0);
        let lit = a.ambient + (1.0 - a.ambient) * hit.normal.dot(&part.light).max(0.0);
        let factor = match (a.lighting, hit.sphere.is_some()) {
            (Lighting::Retroreflective | Lighting::Lambertian, true) => {
                1.0 - a.sphere_limb_falloff * (1.0 - facing)
            }
            (Lighting::Retroreflective | Lighting::Lambertian, false) => facing,
            (Lighting::Diffuse, _) => lit,
        };
        factor * a.exposure
    }
}

/// Renders one tile, its corner `(x0, y0)`, into `pixels` of an image of
/// `size` (module docs).
fn render_tile<T: Texel>(
    shader: &Shader,
    candidates: &TileList,
    (x0, y0): (usize, usize),
    supersampling: usize,
    (width, height): (usize, usize),
    pixels: &mut [T],
) -> Result<(), RenderError> {
    let mut ids = [[0u32; CORNERS]; CORNERS];
    let mut shades = [[T::background(shader.appearance); CORNERS]; CORNERS];
    let rows = TILE_PX.min(height - y0);
    let columns = TILE_PX.min(width - x0);
    for (j, (id_row, shade_row)) in ids
        .iter_mut()
        .zip(shades.iter_mut())
        .take(rows + 1)
        .enumerate()
    {
        let v = y0 as f64 - 0.5 + j as f64;
        for i in 0..=columns {
            let u = x0 as f64 - 0.5 + i as f64;
            (id_row[i], shade_row[i]) = shader.sample(u, v, candidates)?;
        }
    }
    for j in 0..rows {
        for i in 0..columns {
            let id = ids[j][i];
            let corners = [
                shades[j][i],
                shades[j][i + 1],
                shades[j + 1][i],
                shades[j + 1][i + 1],
            ];
            let uniform = ids[j][i + 1] == id
                && ids[j + 1][i] == id
                && ids[j + 1][i + 1] == id
                && T::spread(corners, shader.appearance) <= SHADE_SPREAD;
            let value = if uniform {
                T::mean4(corners)
            } else {
                supersample(shader, candidates, x0 + i, y0 + j, supersampling)?
            };
            pixels[(y0 + j) * width + x0 + i] = value;
        }
    }
    Ok(())
}

/// The mean value of pixel `(x, y)` over an n × n grid of samples.
fn supersample<T: Texel>(
    shader: &Shader,
    candidates: &TileList,
    x: usize,
    y: usize,
    supersampling: usize,
) -> Result<T, RenderError> {
    let step = 1.0 / supersampling as f64;
    let (u0, v0) = (x as f64 - 0.5, y as f64 - 0.5);
    let mut sum = [0.0f64; 3];
    for b in 0..supersampling {
        for a in 0..supersampling {
            let u = u0 + (a as f64 + 0.5) * step;
            let v = v0 + (b as f64 + 0.5) * step;
            shader.sample::<T>(u, v, candidates)?.1.accumulate(&mut sum);
        }
    }
    Ok(T::mean_of(sum, supersampling * supersampling))
}

/// Blurs the pixels of `region` (x0, y0, x1, y1) grown by the kernel's
/// reach with a separable Gaussian of `sigma_px`; the image's edge pixels
/// repeat beyond it. Outside the grown region the image is uniform, so
/// the blur leaves it as it is.
pub fn gaussian_blur(image: &mut Radiance, sigma_px: f64, region: (usize, usize, usize, usize)) {
    if sigma_px <= 0.0 {
        return;
    }
    let reach = (3.0 * sigma_px).ceil() as usize;
    let kernel: Vec<f64> = (0..=2 * reach)
        .map(|k| {
            let x = k as f64 - reach as f64;
            (-0.5 * x * x / (sigma_px * sigma_px)).exp()
        })
        .collect();
    let total: f64 = kernel.iter().sum();
    let kernel: Vec<f32> = kernel.iter().map(|k| (k / total) as f32).collect();
    let (width, height) = (image.width, image.height);
    let x0 = region.0.saturating_sub(reach);
    let y0 = region.1.saturating_sub(reach);
    let x1 = (region.2 + reach).min(width);
    let y1 = (region.3 + reach).min(height);
    let clamp = |value: isize, size: usize| value.clamp(0, size as isize - 1) as usize;
    // Along rows: the source row padded with its edge pixels, so that every
    // tap reads without a bounds clamp.
    let mut padded = vec![0f32; x1 - x0 + 2 * reach];
    for y in y0..y1 {
        let line = &image.values[y * width..(y + 1) * width];
        for (k, value) in padded.iter_mut().enumerate() {
            *value = line[clamp(x0 as isize + k as isize - reach as isize, width)];
        }
        let out = &mut image.values[y * width + x0..y * width + x1];
        for (x, value) in out.iter_mut().enumerate() {
            *value = weighted(&kernel, |k| padded[x + k]);
        }
    }
    // Along columns, a row at a time: each output row is the weighted sum
    // of the source rows around it (the same taps in the same order as a
    // pixel at a time, so the same sums), over a copy of the region grown
    // by the kernel's reach and padded with the edge rows.
    let span = x1 - x0;
    let rows = y1 - y0 + 2 * reach;
    let mut source = vec![0f32; span * rows];
    for (r, chunk) in source.chunks_mut(span).enumerate() {
        let y = clamp(y0 as isize + r as isize - reach as isize, height);
        chunk.copy_from_slice(&image.values[y * width + x0..y * width + x1]);
    }
    let mut sums = vec![0f32; span];
    for y in y0..y1 {
        sums.fill(-0.0);
        for (k, w) in kernel.iter().enumerate() {
            let r = y - y0 + k;
            for (sum, value) in sums.iter_mut().zip(&source[r * span..(r + 1) * span]) {
                *sum += w * value;
            }
        }
        image.values[y * width + x0..y * width + x1].copy_from_slice(&sums);
    }
}

/// `Σ_k kernel[k] · value(k)`, summed in the order of the taps from −0.0
/// (as [`Iterator::sum`] does).
fn weighted(kernel: &[f32], value: impl Fn(usize) -> f32) -> f32 {
    let mut sum = -0.0f32;
    for (k, w) in kernel.iter().enumerate() {
        sum += w * value(k);
    }
    sum
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The three unit channels, weighted by a look's radiances, are that
    /// look's render, in every lighting: to within the pixels near a limb
    /// that the channels supersample (a unit channel's shading spreads
    /// more across a pixel than a dimmer look's) and the single render
    /// takes as the mean of its corners.
    #[test]
    fn the_channels_weighted_by_the_radiances_are_the_render() {
        let layout = crate::layout::Layout::paper_biprism();
        let marker =
            crate::mesh::Marker::design(&layout, &crate::mesh::MarkerOptions::default()).unwrap();
        let scene = Scene::from_marker(marker);
        let pose = Pose::new(
            nalgebra::Rotation3::from_euler_angles(0.5, -0.2, 0.3),
            Vector3::new(10.0, -5.0, 450.0),
        );
        for lighting in [
            Lighting::Retroreflective,
            Lighting::Lambertian,
            Lighting::Diffuse,
        ] {
            let mut config = RenderConfig::new(Camera::paper());
            config.appearance = Appearance::preset(lighting);
            config.appearance.background_radiance = 0.07;
            config.appearance.exposure = 0.9;
            let single = render_radiance(&scene, &pose, &config).unwrap();
            let channels = render_channels_within(&scene, &pose, &config, None).unwrap();
            let a = &config.appearance;
            let weights = [a.sphere_radiance, a.support_radiance, a.background_radiance];
            // differ: pixels apart by more than float rounding.
            let (mut worst, mut total, mut differ) = (0f64, 0f64, 0usize);
            for (i, &value) in single.values.iter().enumerate() {
                let combined: f64 = (0..3)
                    .map(|k| weights[k] * f64::from(channels[k].values[i]))
                    .sum();
                let error = (combined - f64::from(value)).abs();
                worst = worst.max(error);
                total += error;
                differ += usize::from(error > 1e-5);
            }
            let mean = total / single.values.len() as f64;
            assert!(
                worst < 0.02 && mean < 2e-5,
                "{lighting:?}: worst {worst}, mean {mean}, {differ} pixels apart by over 1e-5"
            );
        }
    }

    /// Traced within regions, the image is the full render's inside each
    /// region (beyond the blur's reach from its border) and the
    /// background beyond the tiles traced.
    #[test]
    fn a_render_within_regions_is_the_full_render_there() {
        let spheres = [
            (Vector3::new(-30.0, 0.0, 400.0), 5.0),
            (Vector3::new(30.0, 10.0, 420.0), 5.0),
        ];
        let scene = Scene::spheres_only(&spheres);
        let config = RenderConfig::new(Camera::paper());
        let pose = Pose::new(nalgebra::Rotation3::identity(), Vector3::zeros());
        let full = render_radiance(&scene, &pose, &config).unwrap();
        let camera = &config.camera;
        let centre = camera.normalised_to_pixel(&Vector2::new(-30.0 / 400.0, 0.0));
        let (x, y) = (centre.x as usize, centre.y as usize);
        let region = (x - 30, y - 30, x + 30, y + 30);
        let part = render_radiance_within(&scene, &pose, &config, Some(&[region])).unwrap();
        let background =
            (config.appearance.background_radiance * config.appearance.exposure) as f32;
        // The tiles traced (those meeting the region), grown by the
        // blur's reach.
        let traced = (
            region.0 / TILE_PX * TILE_PX - 2,
            region.1 / TILE_PX * TILE_PX - 2,
            region.2.div_ceil(TILE_PX) * TILE_PX + 2,
            region.3.div_ceil(TILE_PX) * TILE_PX + 2,
        );
        let within = |(x0, y0, x1, y1): (usize, usize, usize, usize), x: usize, y: usize| {
            (x0..x1).contains(&x) && (y0..y1).contains(&y)
        };
        let inner = (region.0 + 2, region.1 + 2, region.2 - 2, region.3 - 2);
        let mut inside = 0;
        for y in 0..full.height {
            for x in 0..full.width {
                let (a, b) = (
                    full.values[y * full.width + x],
                    part.values[y * full.width + x],
                );
                if within(inner, x, y) {
                    // Equal but for the rounding of a blurred background
                    // (the full render blurs a larger box).
                    assert!((a - b).abs() < 1e-6, "({x}, {y}): {a} against {b}");
                    inside += usize::from(a > background);
                } else if !within(traced, x, y) {
                    assert!((b - background).abs() < 1e-6, "({x}, {y}): {b}");
                }
            }
        }
        // The first sphere's disc (about 32 px across) is inside.
        assert!(inside > 150, "{inside}");
        assert!(full.values.iter().filter(|v| **v > background).count() > 2 * inside);
    }

    #[test]
    fn the_blur_keeps_the_total_and_leaves_a_uniform_image_alone() {
        let mut image = Radiance {
            width: 40,
            height: 30,
            values: vec![0.25; 1200],
        };
        gaussian_blur(&mut image, 1.3, (0, 0, 40, 30));
        assert!(image.values.iter().all(|v| (v - 0.25).abs() < 1e-6));
        image.values[15 * 40 + 20] = 1.25;
        let before: f32 = image.values.iter().sum();
        gaussian_blur(&mut image, 1.0, (20, 15, 21, 16));
        let after: f32 = image.values.iter().sum();
        assert!((before - after).abs() < 1e-3);
        assert!(image.values[15 * 40 + 20] < 0.5 && image.values[15 * 40 + 21] > 0.26);
    }

    #[test]
    fn diffuse_light_is_the_ambient_share_plus_the_lamp_by_its_cosine() {
        let scene = Scene::spheres_only(&[(Vector3::new(0.0, 0.0, 100.0), 5.0)]);
        let camera = Camera::paper();
        let appearance = Appearance {
            ambient: 0.4,
            ..Appearance::preset(Lighting::Diffuse)
        };
        let light = Vector3::new(0.0, 0.0, -1.0);
        let part = PartView {
            scene: &scene,
            inverse_rotation: nalgebra::Matrix3::identity(),
            origin: Vector3::zeros(),
            light,
        };
        let shader = Shader {
            camera: &camera,
            appearance: &appearance,
            parts: Vec::new(),
        };
        let hit = |normal: Vector3<f64>, sphere: Option<usize>| Hit {
            t: 95.0,
            shape: 0,
            sphere,
            normal,
        };
        let (l, a) = (appearance.sphere_radiance, appearance.support_radiance);
        let facing = shader.shade(&part, &hit(light, Some(0)), &Vector3::z());
        assert!((facing - l).abs() < 1e-12, "{facing}");
        // Turned 60° from the lamp: the ambient share and half the lamp.
        let turned = Vector3::new(60f64.to_radians().sin(), 0.0, -0.5);
        let side = shader.shade(&part, &hit(turned, Some(0)), &Vector3::z());
        assert!((side - l * (0.4 + 0.6 * 0.5)).abs() < 1e-12, "{side}");
        // Facing away: the ambient share alone, for a support as well.
        let away = shader.shade(&part, &hit(Vector3::x(), None), &Vector3::z());
        assert!((away - a * 0.4).abs() < 1e-12, "{away}");
    }
}
