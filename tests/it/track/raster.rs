//! A small, exact test rasteriser for `track`'s tests and bench: bright,
//! uniform sphere silhouettes (the exact image conics of
//! `layout_opt::sphere_image`) on a dark background, area-sampled on an
//! `n × n` grid of subsamples per pixel, with optional dark occluding bars,
//! a Gaussian blur and seeded Gaussian noise. Pixel `(x, y)` covers
//! `[x − ½, x + ½] × [y − ½, y + ½]` (OpenCV's centres).
//!
//! It stands in for the `render` command until that lands: [`render`] takes
//! a [`Scene`] and returns the frame with each sphere's ground truth
//! ([`SphereTruth`]: ellipse centre, projected centre, hidden fraction), the
//! fields `render`'s ground-truth JSON carries, so a test can swap it for
//! `render` by producing the same two things.

use layout_opt::camera::Camera;
use layout_opt::pose::Pose;
use layout_opt::sphere_image::SphereSilhouette;
use layout_opt::track::GreyFrame;
use nalgebra::{Matrix3, Vector2, Vector3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

/// A dark bar in front of everything, in pixels.
#[derive(Debug, Clone, Copy)]
pub struct Bar {
    /// A point on the bar's centre line, px.
    pub centre: [f64; 2],
    /// Direction of its long axis, rad.
    pub angle: f64,
    /// Half its width, px.
    pub half_width: f64,
    /// Half its length, px.
    pub half_length: f64,
}

impl Bar {
    fn covers(&self, p: &Vector2<f64>) -> bool {
        let along = Vector2::new(self.angle.cos(), self.angle.sin());
        let normal = Vector2::new(-along.y, along.x);
        let d = p - Vector2::new(self.centre[0], self.centre[1]);
        d.dot(&normal).abs() < self.half_width && d.dot(&along).abs() < self.half_length
    }
}

/// What to draw.
#[derive(Debug, Clone)]
pub struct Scene<'a> {
    pub camera: &'a Camera,
    pub object: &'a [Vector3<f64>],
    pub radius_mm: f64,
    pub pose: Pose,
    pub bit_depth: u8,
    /// Background and sphere levels, fractions of full scale.
    pub background: f64,
    pub sphere: f64,
    /// Gaussian blur σ, px (0: none).
    pub blur_px: f64,
    /// Gaussian noise σ, fraction of full scale (0: none).
    pub noise: f64,
    pub bars: Vec<Bar>,
    pub supersampling: usize,
    pub seed: u64,
}

impl<'a> Scene<'a> {
    /// A clean 16-bit scene at `pose`: background 0.05, spheres 0.85, 8×8.
    pub fn clean(
        camera: &'a Camera,
        object: &'a [Vector3<f64>],
        radius_mm: f64,
        pose: Pose,
    ) -> Self {
        Scene {
            camera,
            object,
            radius_mm,
            pose,
            bit_depth: 16,
            background: 0.05,
            sphere: 0.85,
            blur_px: 0.0,
            noise: 0.0,
            bars: Vec::new(),
            supersampling: 8,
            seed: 0,
        }
    }
}

/// The ground truth of one sphere.
#[derive(Debug, Clone, Copy)]
pub struct SphereTruth {
    /// Exact ellipse centre, raw px.
    pub ellipse_centre_px: Vector2<f64>,
    /// Projected sphere centre, raw px.
    pub centre_px: Vector2<f64>,
    /// Semi-major axis, px (approximate with distortion).
    pub semi_major_px: f64,
    /// Share of the silhouette hidden by a bar, a nearer sphere or the
    /// image border.
    pub hidden_fraction: f64,
}

struct Disc {
    conic: Matrix3<f64>,
    depth: f64,
    bounds: [i64; 4],
}

fn inside(camera: &Camera, conic: &Matrix3<f64>, p: &Vector2<f64>) -> bool {
    let m = if camera.has_distortion() {
        match camera.pixel_to_normalised(p) {
            Ok(m) => m,
            Err(_) => return false,
        }
    } else {
        Vector2::new(
            (p.x - camera.cx()) / camera.fx(),
            (p.y - camera.cy()) / camera.fy(),
        )
    };
    let h = Vector3::new(m.x, m.y, 1.0);
    h.dot(&(conic * h)) > 0.0
}

/// Renders `scene` (module docs). Panics on a sphere not in front (tests
/// choose their poses).
pub fn render(scene: &Scene) -> (GreyFrame, Vec<SphereTruth>) {
    let camera = scene.camera;
    let (width, height) = (camera.width() as i64, camera.height() as i64);
    let n = scene.supersampling;
    let mut discs = Vec::new();
    let mut truths = Vec::new();
    for p in scene.object {
        let c = scene.pose.transform(p);
        let silhouette =
            SphereSilhouette::new(camera, &c, scene.radius_mm).expect("sphere in front");
        let conic = layout_opt::sphere_image::normalised_conic(&c, scene.radius_mm).unwrap();
        let (along, _) =
            layout_opt::sphere_image::semi_axes_normalised(&c, scene.radius_mm).unwrap();
        let semi_major_px = along * camera.fx().max(camera.fy());
        let reach = semi_major_px * 1.2 + 3.0;
        let e = silhouette.ellipse_centre_px;
        discs.push(Disc {
            conic,
            depth: c.z,
            bounds: [
                (e.x - reach).floor() as i64,
                (e.y - reach).floor() as i64,
                (e.x + reach).ceil() as i64,
                (e.y + reach).ceil() as i64,
            ],
        });
        truths.push(SphereTruth {
            ellipse_centre_px: silhouette.ellipse_centre_px,
            centre_px: silhouette.centre_px,
            semi_major_px,
            hidden_fraction: 0.0,
        });
    }
    let sample = |x: i64, y: i64, sx: usize, sy: usize| {
        Vector2::new(
            x as f64 - 0.5 + (sx as f64 + 0.5) / n as f64,
            y as f64 - 0.5 + (sy as f64 + 0.5) / n as f64,
        )
    };
    // Hidden fractions, over each disc's whole (unclipped) box.
    for (i, disc) in discs.iter().enumerate() {
        let (mut total, mut hidden) = (0usize, 0usize);
        for y in disc.bounds[1]..=disc.bounds[3] {
            for x in disc.bounds[0]..=disc.bounds[2] {
                for sy in 0..n {
                    for sx in 0..n {
                        let p = sample(x, y, sx, sy);
                        if !inside(camera, &disc.conic, &p) {
                            continue;
                        }
                        total += 1;
                        let off_image = x < 0 || y < 0 || x >= width || y >= height;
                        let by_bar = scene.bars.iter().any(|b| b.covers(&p));
                        let by_sphere = discs.iter().enumerate().any(|(j, d)| {
                            j != i && d.depth < disc.depth && inside(camera, &d.conic, &p)
                        });
                        if off_image || by_bar || by_sphere {
                            hidden += 1;
                        }
                    }
                }
            }
        }
        truths[i].hidden_fraction = hidden as f64 / total.max(1) as f64;
    }
    // Coverage over the union of the boxes.
    let mut coverage = vec![0.0f64; (width * height) as usize];
    let mut visited = vec![false; (width * height) as usize];
    for disc in &discs {
        for y in disc.bounds[1].max(0)..=disc.bounds[3].min(height - 1) {
            for x in disc.bounds[0].max(0)..=disc.bounds[2].min(width - 1) {
                let index = (y * width + x) as usize;
                if std::mem::replace(&mut visited[index], true) {
                    continue;
                }
                let mut covered = 0usize;
                for sy in 0..n {
                    for sx in 0..n {
                        let p = sample(x, y, sx, sy);
                        if scene.bars.iter().any(|b| b.covers(&p)) {
                            continue;
                        }
                        if discs.iter().any(|d| inside(camera, &d.conic, &p)) {
                            covered += 1;
                        }
                    }
                }
                coverage[index] = covered as f64 / (n * n) as f64;
            }
        }
    }
    let mut values: Vec<f64> = coverage
        .iter()
        .map(|c| scene.background + (scene.sphere - scene.background) * c)
        .collect();
    if scene.blur_px > 0.0 {
        // Only around the discs: elsewhere the frame is uniform.
        let margin = (3.0 * scene.blur_px).ceil() as i64 + 1;
        let rect = [
            (discs.iter().map(|d| d.bounds[0]).min().unwrap() - margin).max(0),
            (discs.iter().map(|d| d.bounds[1]).min().unwrap() - margin).max(0),
            (discs.iter().map(|d| d.bounds[2]).max().unwrap() + margin).min(width - 1),
            (discs.iter().map(|d| d.bounds[3]).max().unwrap() + margin).min(height - 1),
        ];
        values = blur(
            &values,
            width as usize,
            height as usize,
            scene.blur_px,
            rect,
        );
    }
    let full_scale = if scene.bit_depth == 8 { 255.0 } else { 65535.0 };
    let mut rng = ChaCha8Rng::seed_from_u64(scene.seed);
    let normal = Normal::new(0.0, scene.noise.max(0.0)).unwrap();
    let pixels: Vec<u16> = values
        .iter()
        .map(|v| {
            let noisy = if scene.noise > 0.0 {
                v + normal.sample(&mut rng)
            } else {
                *v
            };
            (noisy * full_scale).round().clamp(0.0, full_scale) as u16
        })
        .collect();
    let frame = GreyFrame::new(width as u32, height as u32, scene.bit_depth, pixels).unwrap();
    (frame, truths)
}

/// Separable Gaussian blur with a kernel of ±3σ, edges clamped.
fn blur(values: &[f64], width: usize, height: usize, sigma: f64, rect: [i64; 4]) -> Vec<f64> {
    let radius = (3.0 * sigma).ceil() as i64;
    let kernel: Vec<f64> = (-radius..=radius)
        .map(|k| (-(k * k) as f64 / (2.0 * sigma * sigma)).exp())
        .collect();
    let total: f64 = kernel.iter().sum();
    let kernel: Vec<f64> = kernel.iter().map(|k| k / total).collect();
    let pass = |input: &[f64], horizontal: bool| -> Vec<f64> {
        let mut out = input.to_vec();
        for y in rect[1]..=rect[3] {
            for x in rect[0]..=rect[2] {
                let mut sum = 0.0;
                for (k, weight) in kernel.iter().enumerate() {
                    let offset = k as i64 - radius;
                    let (sx, sy) = if horizontal {
                        ((x + offset).clamp(0, width as i64 - 1), y)
                    } else {
                        (x, (y + offset).clamp(0, height as i64 - 1))
                    };
                    sum += weight * input[(sy * width as i64 + sx) as usize];
                }
                out[(y * width as i64 + x) as usize] = sum;
            }
        }
        out
    };
    pass(&pass(values, true), false)
}

/// Encodes a frame as PNG bytes.
#[allow(dead_code)]
pub fn png(frame: &GreyFrame) -> Vec<u8> {
    frame.to_png()
}
