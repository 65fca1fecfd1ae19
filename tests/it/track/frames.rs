//! Frames for `track`'s tests, bench and accuracy example, drawn by the real
//! renderer (`layout_opt::render`) with the part `export` builds (spheres on
//! their supports), and the render's ground truth beside each: exact
//! ellipse centres, projected centres and hidden fractions by cause.
//!
//! One noise-free radiance render per pose; any number of noisy sensor
//! readings of it ([`Rendered::expose`]) cost a pass over the pixels only.

use layout_opt::camera::Camera;
use layout_opt::layout::Layout;
use layout_opt::mesh::{Marker, MarkerOptions};
use layout_opt::pose::Pose;
use layout_opt::render::{
    expose, frame_truth, render_radiance, Blur, FrameTruth, Noise, Radiance, RenderConfig, Scene,
    SphereTruth,
};
use layout_opt::track::GreyFrame;
use nalgebra::Vector2;

/// The search winner and its printed part, built once per caller.
pub struct Part {
    pub layout: Layout,
    pub scene: Scene,
    pub names: Vec<String>,
}

impl Part {
    /// The layout at `path` with the part `export` builds by default.
    pub fn load(path: &std::path::Path) -> Part {
        let layout = Layout::load(path).unwrap();
        let scene = Scene::from_marker(Marker::design(&layout, &MarkerOptions::default()).unwrap());
        let names = layout.points.iter().map(|p| p.name.clone()).collect();
        Part {
            layout,
            scene,
            names,
        }
    }

    /// The repository's search winner.
    pub fn winner() -> Part {
        Part::load(
            &std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("layouts/biprism-search.json"),
        )
    }

    /// The render's ground truth at `pose` alone (no image), with the
    /// hidden fractions counted over `rays` limb rays (the render's own
    /// truth: [`layout_opt::render::truth::SILHOUETTE_RAYS`]; the geometry
    /// is exact either way): tracing the part is the cost of a truth, and a
    /// search for clean views traces many.
    pub fn truth_over(&self, camera: &Camera, pose: &Pose, rays: usize) -> FrameTruth {
        let balls = Scene::spheres_only(self.scene.spheres());
        let mut truth = frame_truth(&balls, &self.names, pose, camera).unwrap();
        for (k, sphere) in truth.spheres.iter_mut().enumerate() {
            sphere.hidden =
                layout_opt::render::truth::hidden_fractions(&self.scene, pose, camera, k, rays);
        }
        truth
    }

    /// Renders the part at `pose` through `config`'s camera, a [`crop`] of
    /// `camera` that holds every disc of `truth` (traced at `camera`, no
    /// sphere cut by its image) wholly: the truth is `truth` moved to the
    /// window's pixels, not traced again (nothing of a disc leaves the
    /// window, so its hidden fractions are the same).
    pub fn render_window(
        &self,
        config: &RenderConfig,
        pose: &Pose,
        camera: &Camera,
        truth: &FrameTruth,
    ) -> Rendered {
        let window = &config.camera;
        let shift = Vector2::new(camera.cx() - window.cx(), camera.cy() - window.cy());
        let mut moved = truth.clone();
        for sphere in &mut moved.spheres {
            assert_eq!(sphere.hidden.outside_image, 0.0, "{}", sphere.name);
            let to = |p: [f64; 2]| [p[0] - shift.x, p[1] - shift.y];
            sphere.ellipse_centre_px = to(sphere.ellipse_centre_px);
            sphere.ellipse_centre_undistorted_px = to(sphere.ellipse_centre_undistorted_px);
            sphere.projected_centre_px = to(sphere.projected_centre_px);
            // The conic in the window's pixels: Tᵀ Q T with T taking a
            // window pixel to the frame's.
            let q = nalgebra::Matrix3::from(sphere.conic_px);
            let t = nalgebra::Matrix3::new(1.0, 0.0, shift.x, 0.0, 1.0, shift.y, 0.0, 0.0, 1.0);
            sphere.conic_px = (t.transpose() * q * t).into();
        }
        Rendered {
            radiance: render_radiance(&self.scene, pose, config).unwrap(),
            truth: moved,
            config: config.clone(),
        }
    }

    /// Renders the part at `pose` (no noise yet) with its ground truth.
    pub fn render(&self, config: &RenderConfig, pose: &Pose) -> Rendered {
        let radiance = render_radiance(&self.scene, pose, config).unwrap();
        let truth = frame_truth(&self.scene, &self.names, pose, &config.camera).unwrap();
        Rendered {
            radiance,
            truth,
            config: config.clone(),
        }
    }
}

/// The render's settings for the tests: `camera`, the retroreflective
/// preset, σ 0.5 px blur, `supersampling`² samples on edge pixels, a 16-bit
/// sensor without noise.
pub fn noise_free(camera: Camera, supersampling: u32) -> RenderConfig {
    let mut config = RenderConfig::new(camera);
    config.optics.supersampling = supersampling;
    config.optics.blur = Blur::Gaussian { sigma_px: 0.5 };
    config.sensor.bit_depth = 16;
    config.sensor.noise = None;
    config
}

/// As [`noise_free`], read by an 8-bit sensor with the default shot and
/// read noise.
pub fn noisy(camera: Camera, supersampling: u32) -> RenderConfig {
    let mut config = noise_free(camera, supersampling);
    config.sensor.bit_depth = 8;
    config.sensor.noise = Some(Noise::default());
    config
}

/// One pose's noise-free render and its truth.
pub struct Rendered {
    pub radiance: Radiance,
    pub truth: FrameTruth,
    pub config: RenderConfig,
}

impl Rendered {
    /// The sensor's reading `realisation` (seeded by `seed`).
    pub fn expose(&self, seed: u64, realisation: u64) -> GreyFrame {
        let digital = expose(&self.radiance, &self.config.sensor, seed, 0, realisation);
        GreyFrame::new(
            digital.width as u32,
            digital.height as u32,
            digital.bit_depth,
            digital.values,
        )
        .unwrap()
    }

    /// The noise-free reading.
    pub fn frame(&self) -> GreyFrame {
        self.expose(0, 0)
    }
}

/// A dark bar in front of everything, px.
pub struct Bar {
    /// A point on its centre line.
    pub centre: Vector2<f64>,
    /// Direction of its long axis, rad.
    pub angle: f64,
    /// Half its width.
    pub half_width: f64,
    /// Half its length.
    pub half_length: f64,
}

impl Bar {
    /// How far `p` is outside the bar (≤ 0 inside), px.
    fn outside(&self, p: Vector2<f64>) -> f64 {
        let along = Vector2::new(self.angle.cos(), self.angle.sin());
        let normal = Vector2::new(-along.y, along.x);
        let d = p - self.centre;
        let a = d.dot(&along).abs() - self.half_length;
        let n = d.dot(&normal).abs() - self.half_width;
        if a > 0.0 && n > 0.0 {
            a.hypot(n)
        } else {
            a.max(n)
        }
    }
}

/// Paints `bar` at radiance `level` over `rendered`, area-sampled on a 4×4
/// grid per pixel. Returns, per sphere, the share of its exact outline
/// (undistorted camera) under the bar and the outline's distance from the
/// bar, px (0 when it is under it).
pub fn paint_bar(rendered: &mut Rendered, bar: &Bar, level: f32) -> Vec<(f64, f64)> {
    let covers = |p: Vector2<f64>| bar.outside(p) < 0.0;
    let width = rendered.radiance.width;
    // Only pixels within the bar's circumscribed circle (plus a pixel) can
    // be covered; the rest keep their values.
    let reach = bar.half_length.hypot(bar.half_width) + 1.0;
    for (i, v) in rendered.radiance.values.iter_mut().enumerate() {
        let (x, y) = ((i % width) as f64, (i / width) as f64);
        if (x - bar.centre.x).abs() > reach || (y - bar.centre.y).abs() > reach {
            continue;
        }
        let mut covered = 0;
        for sy in 0..4 {
            for sx in 0..4 {
                let p = Vector2::new(
                    x - 0.5 + (sx as f64 + 0.5) / 4.0,
                    y - 0.5 + (sy as f64 + 0.5) / 4.0,
                );
                covered += usize::from(covers(p));
            }
        }
        let share = covered as f32 / 16.0;
        *v = *v * (1.0 - share) + level * share;
    }
    rendered
        .truth
        .spheres
        .iter()
        .map(|sphere| {
            let conic = nalgebra::Matrix3::from_fn(|i, j| sphere.conic_px[j][i]);
            let ellipse = layout_opt::ellipse::Ellipse::from_conic(&conic).unwrap();
            let (s, c) = ellipse.angle_rad.sin_cos();
            const POINTS: usize = 720;
            let outline: Vec<f64> = (0..POINTS)
                .map(|k| {
                    let phi = std::f64::consts::TAU * k as f64 / POINTS as f64;
                    let (u, w) = (
                        ellipse.semi_major * phi.cos(),
                        ellipse.semi_minor * phi.sin(),
                    );
                    bar.outside(ellipse.centre + Vector2::new(c * u - s * w, s * u + c * w))
                })
                .collect();
            let under = outline.iter().filter(|d| **d < 0.0).count();
            (
                under as f64 / POINTS as f64,
                outline
                    .iter()
                    .cloned()
                    .fold(f64::INFINITY, f64::min)
                    .max(0.0),
            )
        })
        .collect()
}

/// `camera` cut down to the window of its image that holds the discs of
/// the spheres `which` accepts (per `truth`, at `camera`) with `margin_px`
/// round them, clipped to the image: the same lens with the principal
/// point moved by the window's whole-pixel corner, so a render through it
/// is the full frame's pixels in that window (and its truth the same
/// spheres), at the cost of the window alone. The tracker then reads the
/// marker with none of the frame's far background.
pub fn crop(
    camera: &Camera,
    truth: &FrameTruth,
    margin_px: f64,
    which: impl Fn(usize) -> bool,
) -> Camera {
    let (mut low, mut high) = (
        Vector2::new(f64::INFINITY, f64::INFINITY),
        Vector2::new(f64::NEG_INFINITY, f64::NEG_INFINITY),
    );
    for (k, sphere) in truth.spheres.iter().enumerate() {
        if !which(k) {
            continue;
        }
        let reach = Vector2::repeat(sphere.semi_axes_px[0] + margin_px);
        let centre = ellipse_centre(sphere);
        low = low.inf(&(centre - reach));
        high = high.sup(&(centre + reach));
    }
    let x0 = low.x.floor().max(0.0);
    let y0 = low.y.floor().max(0.0);
    let x1 = high.x.ceil().min(camera.width() as f64);
    let y1 = high.y.ceil().min(camera.height() as f64);
    Camera::new(
        camera.fx(),
        camera.fy(),
        camera.cx() - x0,
        camera.cy() - y0,
        (x1 - x0).max(1.0) as u32,
        (y1 - y0).max(1.0) as u32,
        camera.distortion(),
    )
    .unwrap()
}

/// Exact ellipse centre of a sphere, raw px.
pub fn ellipse_centre(sphere: &SphereTruth) -> Vector2<f64> {
    Vector2::from(sphere.ellipse_centre_px)
}

/// Share of a sphere's silhouette hidden, any cause.
pub fn hidden_fraction(sphere: &SphereTruth) -> f64 {
    sphere.hidden.total()
}

/// Whether every sphere is whole, inside the frame with a margin, and no
/// two come within a few pixels of each other.
pub fn clean_view(truth: &FrameTruth, camera: &Camera) -> bool {
    let spheres = &truth.spheres;
    spheres.iter().enumerate().all(|(i, a)| {
        let e = ellipse_centre(a);
        let r = a.semi_axes_px[0] + 4.0;
        hidden_fraction(a) == 0.0
            && e.x > r
            && e.y > r
            && e.x < camera.width() as f64 - r
            && e.y < camera.height() as f64 - r
            && spheres.iter().enumerate().all(|(j, b)| {
                i == j
                    || (e - ellipse_centre(b)).norm() > a.semi_axes_px[0] + b.semi_axes_px[0] + 4.0
            })
    })
}

/// The blob nearest each sphere's true ellipse centre (within its
/// semi-major axis).
pub fn blob_of_sphere(
    blobs: &[layout_opt::track::detect::Blob],
    sphere: &SphereTruth,
) -> Option<usize> {
    blobs
        .iter()
        .enumerate()
        .map(|(i, b)| {
            (
                i,
                (Vector2::from(b.ellipse_centre_px) - ellipse_centre(sphere)).norm(),
            )
        })
        .filter(|(_, d)| *d < sphere.semi_axes_px[0])
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(i, _)| i)
}

/// How far into sphere `index`'s silhouette the part's supports reach, px
/// (0 when nothing of the part hides its outline). The render's hidden
/// fractions count hidden outline; this is the depth of the notch an
/// occluder cuts into the disc, which is what an image can show: a round
/// cone seen just past the angle where it starts to cover the limb hides
/// a tenth of the outline and bends the edge by a hundredth of a pixel.
///
/// Along each of `rays` limb rays whose first hit is a support, the aim is
/// pulled towards the sphere's centre, in steps of a quarter pixel and
/// then by bisection, until the ray meets the sphere's own coating; the
/// reach is the largest distance moved, measured in the image.
pub fn support_reach_px(
    scene: &Scene,
    pose: &Pose,
    camera: &Camera,
    index: usize,
    rays: usize,
) -> f64 {
    use layout_opt::render::scene::Ray;
    const STEP_PX: f64 = 0.25;
    const BISECTIONS: usize = 4;
    let (centre, radius) = scene.spheres()[index];
    let c = pose.transform(&centre);
    let inverse = pose.rotation.inverse();
    let origin = -(inverse * pose.translation);
    let all = scene.all_shapes();
    let Some(centre_px) = camera.project(&c) else {
        return f64::NAN;
    };
    let sphere_at = |aim: nalgebra::Vector3<f64>| {
        scene.first_hit(
            &Ray {
                origin,
                direction: inverse * aim.normalize(),
            },
            &all,
        )
    };
    let mut reach: f64 = 0.0;
    for limb in layout_opt::render::truth::limb_points(&c, radius, rays) {
        let Some(limb_px) = camera.project(&limb) else {
            continue;
        };
        let inset = |s: f64| c + (limb - c) * (1.0 - s);
        let hidden_by_support = sphere_at(inset(1e-6)).is_some_and(|h| h.sphere.is_none());
        if !hidden_by_support {
            continue;
        }
        let own = |s: f64| sphere_at(inset(s)).is_some_and(|h| h.sphere == Some(index));
        let steps = ((limb_px - centre_px).norm() / STEP_PX).ceil().max(1.0) as usize;
        let Some(k) = (1..=steps).find(|&k| own(k as f64 / steps as f64)) else {
            continue;
        };
        let (mut hidden, mut seen) = ((k - 1) as f64 / steps as f64, k as f64 / steps as f64);
        for _ in 0..BISECTIONS {
            let mid = 0.5 * (hidden + seen);
            if own(mid) {
                seen = mid;
            } else {
                hidden = mid;
            }
        }
        let aim_px = camera.project(&inset(seen)).unwrap_or(limb_px);
        reach = reach.max((limb_px - aim_px).norm());
    }
    reach
}

/// Share of sphere `index`'s silhouette area that something in front
/// hides, or that lies outside the image: rays through `SAMPLES` points
/// spread evenly over its exact ellipse (sunflower pattern), each checked
/// for meeting the sphere first.
pub fn area_hidden(
    scene: &Scene,
    pose: &Pose,
    camera: &Camera,
    sphere: &SphereTruth,
    index: usize,
) -> f64 {
    use layout_opt::render::scene::Ray;
    use layout_opt::track::conic::Ellipse;
    const SAMPLES: usize = 400;
    let conic = nalgebra::Matrix3::from_fn(|i, j| sphere.conic_px[i][j]);
    let Some(ellipse) = Ellipse::from_conic(&conic) else {
        return f64::NAN;
    };
    let eigen = nalgebra::SymmetricEigen::new(ellipse.shape);
    let inverse = pose.rotation.inverse();
    let origin = -(inverse * pose.translation);
    let all = scene.all_shapes();
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    let hidden = (0..SAMPLES)
        .filter(|&k| {
            let rho = 0.995 * ((k as f64 + 0.5) / SAMPLES as f64).sqrt();
            let angle = golden * k as f64;
            let local = Vector2::new(
                rho * angle.cos() / eigen.eigenvalues[0].sqrt(),
                rho * angle.sin() / eigen.eigenvalues[1].sqrt(),
            );
            let p = ellipse.centre + eigen.eigenvectors * local;
            if p.x < -0.5
                || p.y < -0.5
                || p.x > camera.width() as f64 - 0.5
                || p.y > camera.height() as f64 - 0.5
            {
                return true;
            }
            let m = nalgebra::Vector3::new(
                (p.x - camera.cx()) / camera.fx(),
                (p.y - camera.cy()) / camera.fy(),
                1.0,
            );
            let ray = Ray {
                origin,
                direction: inverse * m.normalize(),
            };
            scene
                .first_hit(&ray, &all)
                .is_some_and(|hit| hit.sphere != Some(index))
        })
        .count();
    hidden as f64 / SAMPLES as f64
}
