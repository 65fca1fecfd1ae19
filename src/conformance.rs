//! Seeded PnP problems for the solver conformance sweep
//! (`cargo run --release --features examples --example conformance`), shared with its tests.
//!
//! A [`Cell`] names one point of the PnP problem space; [`generate`] draws
//! problem `case` of it from `(seed, cell)` alone, so any problem can be
//! replayed on its own and a sweep gives the same problems at any thread
//! count. Cells that differ only in noise σ or in lens distortion share
//! their random stream ([`Cell::stream`]) and so, draw for draw, the same
//! geometry (common random numbers).
//!
//! **How a problem is drawn** (camera: [`Camera::default`], the paper's
//! 1280×720 camera, or [`Camera::paper_with_distortion`] when the cell says
//! so):
//! 1. `n` points uniform in a box `[−½, ½]² × [−t/2, t/2]` (t = thickness:
//!    0 is planar, 0.01 quasi-planar, 1 a cube), redrawn if they are nearly
//!    collinear (second principal extent below [`MIN_SECOND_EXTENT_RATIO`]
//!    of the first); centred on their centroid (the object frame's origin)
//!    and scaled so that their diameter (largest pairwise distance) is
//!    [`OBJECT_DIAMETER_MM`].
//! 2. The centroid's (distorted) pixel: uniform over the image, or the
//!    principal point moved a fraction `f` of the way to one of the four
//!    image corners, chosen at random ([`OffAxis`]). The centroid sits on
//!    that pixel's ray at depth `depth_ratio · diameter` (depth = camera z).
//! 3. A rotation uniform on SO(3), redrawn until every point is in front of
//!    the camera at depth ≥ [`MIN_DEPTH_FRACTION`] of the centroid's; after
//!    [`ROTATION_ATTEMPTS`] failures the points are redrawn. Points are *not*
//!    required to fall inside the image: below depth/size ≈ 3 an object
//!    cannot fit in it, and the solvers see only normalised coordinates.
//! 4. Projection through the camera (distortion included), isotropic
//!    Gaussian pixel noise σ, and back to undistorted normalised points with
//!    [`Camera::pixel_to_normalised`], as the product does
//!    ([`crate::synthetic::project_with_noise`]).

use crate::camera::Camera;
use crate::error_model::first_order::pose_covariance_isotropic;
use crate::pose::Pose;
use crate::spread::Spread;
use crate::synthetic::{project_with_noise, stream_rng, uniform_rotation, Problem};
use nalgebra::{Rotation3, Vector2, Vector3};
use rand::Rng;
use serde::Serialize;

/// Diameter (largest pairwise distance) of every generated point set, mm.
/// Normalised image points do not depend on scale; only depth/size does.
pub const OBJECT_DIAMETER_MM: f64 = 100.0;
/// Every point lies at a camera depth of at least this fraction of the
/// centroid's depth.
pub const MIN_DEPTH_FRACTION: f64 = 0.05;
/// Point sets whose second principal extent is below this fraction of the
/// first are redrawn (nearly collinear: no solver can do well on them).
pub const MIN_SECOND_EXTENT_RATIO: f64 = 0.1;
/// Rotations tried per point set before the points are redrawn.
pub const ROTATION_ATTEMPTS: usize = 200;
/// Point sets tried before [`generate`] gives up (never reached by the
/// sweep's cells).
pub const POINT_ATTEMPTS: usize = 1000;

/// Where the object's centroid projects.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub enum OffAxis {
    /// Anywhere in the image, uniformly.
    Uniform,
    /// The principal point moved this fraction (0 = on the optical axis,
    /// 1 = at the corner) of the way to a randomly chosen image corner.
    TowardCorner(f64),
}

impl std::fmt::Display for OffAxis {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            OffAxis::Uniform => f.write_str("uniform"),
            OffAxis::TowardCorner(x) if *x == 0.0 => f.write_str("axis"),
            OffAxis::TowardCorner(x) if *x == 1.0 => f.write_str("corner"),
            OffAxis::TowardCorner(x) => write!(f, "{x}-corner"),
        }
    }
}

/// One point of the PnP problem space.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Cell {
    /// Centroid depth over object diameter.
    pub depth_ratio: f64,
    /// Number of points.
    pub points: usize,
    /// z side of the sampling box over its x/y side (0 planar, 1 cube).
    pub thickness: f64,
    /// Where the centroid projects.
    pub off_axis: OffAxis,
    /// Whether the camera has the paper's lens distortion.
    pub distortion: bool,
    /// Pixel noise σ, px.
    pub sigma_px: f64,
}

impl Cell {
    /// The camera of this cell: [`Camera::default`] or, with distortion,
    /// [`Camera::paper_with_distortion`].
    pub fn camera(&self) -> Camera {
        if self.distortion {
            Camera::paper_with_distortion()
        } else {
            Camera::default()
        }
    }

    /// The random stream of this cell: a hash of its geometry (depth ratio,
    /// n, thickness, off-axis), so that cells differing only in σ or
    /// distortion draw the same objects, rotations and noise directions, and
    /// adding cells to a sweep changes no other cell.
    pub fn stream(&self) -> u64 {
        let (kind, fraction) = match self.off_axis {
            OffAxis::Uniform => (0u64, 0.0),
            OffAxis::TowardCorner(f) => (1, f),
        };
        let words = [
            self.depth_ratio.to_bits(),
            self.points as u64,
            self.thickness.to_bits(),
            kind,
            fraction.to_bits(),
        ];
        // FNV-1a over the words' bytes: stable across platforms and releases.
        let mut hash: u64 = 0xcbf2_9ce4_8422_2325;
        for byte in words.iter().flat_map(|w| w.to_le_bytes()) {
            hash ^= u64::from(byte);
            hash = hash.wrapping_mul(0x0100_0000_01b3);
        }
        hash
    }
}

/// Depth/size of the far-field regime: a 100 mm object at 2–5 m, where DLS
/// once failed (depth/size ≥ 20).
pub const FAR_FIELD_DEPTH_RATIO: std::ops::Range<f64> = 20.0..50.0;
/// Point counts of the far-field regime.
pub const FAR_FIELD_POINTS: std::ops::RangeInclusive<usize> = 6..=12;

/// One far-field problem's cell, drawn from `rng`: depth/size uniform in
/// `depth_ratio`, n uniform in [`FAR_FIELD_POINTS`], a cube (t = 1), the
/// centroid anywhere in the image, no distortion, noise σ. The sweep's
/// far-field regime draws it with [`FAR_FIELD_DEPTH_RATIO`], then the
/// problem with [`generate_with`] from the same stream.
pub fn far_field_cell(
    rng: &mut impl Rng,
    depth_ratio: std::ops::Range<f64>,
    sigma_px: f64,
) -> Cell {
    Cell {
        depth_ratio: rng.random_range(depth_ratio),
        points: rng.random_range(FAR_FIELD_POINTS),
        thickness: 1.0,
        off_axis: OffAxis::Uniform,
        distortion: false,
        sigma_px,
    }
}

/// A generated problem and the sampling box side it was drawn with.
#[derive(Debug, Clone)]
pub struct Generated {
    /// Object points (centred on their centroid), pixels, solver input and
    /// the true pose.
    pub problem: Problem,
    /// Side of the sampling box in x and y after scaling, mm; its z side is
    /// `thickness · side_mm`.
    pub side_mm: f64,
}

/// Problem `case` of `cell` under `seed` (module docs give the recipe).
///
/// # Panics
/// If no valid problem is found in [`POINT_ATTEMPTS`] point sets (a cell far
/// outside the sweep's, e.g. depth ratio ≤ 0).
pub fn generate(cell: &Cell, seed: u64, case: u64) -> Generated {
    let mut rng = stream_rng(seed, cell.stream(), case);
    generate_with(&mut rng, cell)
        .unwrap_or_else(|| panic!("no valid problem for {cell:?} in {POINT_ATTEMPTS} point sets"))
}

/// [`generate`] from a caller's random stream; `None` when every attempt
/// failed.
pub fn generate_with(rng: &mut impl Rng, cell: &Cell) -> Option<Generated> {
    let camera = cell.camera();
    for _ in 0..POINT_ATTEMPTS {
        let (object, side_mm) = draw_points(rng, cell.points, cell.thickness);
        let extents = Spread::of(&object).extents;
        if extents[1] < MIN_SECOND_EXTENT_RATIO * extents[0] {
            continue;
        }
        let depth_mm = cell.depth_ratio * OBJECT_DIAMETER_MM;
        if let Some(problem) =
            place_and_observe(rng, &camera, object, depth_mm, cell.off_axis, cell.sigma_px)
        {
            return Some(Generated { problem, side_mm });
        }
    }
    None
}

/// `count` points uniform in `[−½, ½]² × [−t/2, t/2]`, centred on their
/// centroid and scaled to diameter [`OBJECT_DIAMETER_MM`]; also returns the
/// scaled box side.
fn draw_points(rng: &mut impl Rng, count: usize, thickness: f64) -> (Vec<Vector3<f64>>, f64) {
    let mut points: Vec<Vector3<f64>> = (0..count)
        .map(|_| {
            Vector3::new(
                rng.random::<f64>() - 0.5,
                rng.random::<f64>() - 0.5,
                (rng.random::<f64>() - 0.5) * thickness,
            )
        })
        .collect();
    let centroid = points.iter().sum::<Vector3<f64>>() / count as f64;
    let diameter = diameter(&points);
    let scale = OBJECT_DIAMETER_MM / diameter;
    for p in &mut points {
        *p = (*p - centroid) * scale;
    }
    (points, scale)
}

/// Largest pairwise distance of a point set.
pub fn diameter(points: &[Vector3<f64>]) -> f64 {
    let mut largest_sq: f64 = 0.0;
    for (i, a) in points.iter().enumerate() {
        for b in &points[i + 1..] {
            largest_sq = largest_sq.max((a - b).norm_squared());
        }
    }
    largest_sq.sqrt()
}

/// Places `object` (its frame's origin is the point that [`OffAxis`] aims)
/// at camera depth `depth_mm` with a rotation uniform on SO(3), redrawn until
/// every point is at depth ≥ [`MIN_DEPTH_FRACTION`]` · depth_mm`, then
/// observes it through `camera` with pixel noise `sigma_px`. `None` if no
/// rotation in [`ROTATION_ATTEMPTS`] keeps the points in front, or a pixel
/// cannot be undistorted.
pub fn place_and_observe(
    rng: &mut impl Rng,
    camera: &Camera,
    object: Vec<Vector3<f64>>,
    depth_mm: f64,
    off_axis: OffAxis,
    sigma_px: f64,
) -> Option<Problem> {
    let pixel = centroid_pixel(rng, camera, off_axis);
    let ray = camera.pixel_to_normalised(&pixel).ok()?;
    let translation = Vector3::new(ray.x, ray.y, 1.0) * depth_mm;
    let rotation = in_front_rotation(rng, &object, &translation, depth_mm)?;
    project_with_noise(
        rng,
        camera,
        object,
        Pose::new(rotation, translation),
        sigma_px,
    )
}

fn centroid_pixel(rng: &mut impl Rng, camera: &Camera, off_axis: OffAxis) -> Vector2<f64> {
    let (width, height) = (f64::from(camera.width()), f64::from(camera.height()));
    match off_axis {
        OffAxis::Uniform => Vector2::new(rng.random::<f64>() * width, rng.random::<f64>() * height),
        OffAxis::TowardCorner(fraction) => {
            let corner = match rng.random_range(0..4) {
                0 => Vector2::new(0.0, 0.0),
                1 => Vector2::new(width, 0.0),
                2 => Vector2::new(0.0, height),
                _ => Vector2::new(width, height),
            };
            let principal = Vector2::new(camera.cx(), camera.cy());
            principal + (corner - principal) * fraction
        }
    }
}

fn in_front_rotation(
    rng: &mut impl Rng,
    object: &[Vector3<f64>],
    translation: &Vector3<f64>,
    depth_mm: f64,
) -> Option<Rotation3<f64>> {
    let nearest_allowed = MIN_DEPTH_FRACTION * depth_mm;
    (0..ROTATION_ATTEMPTS).find_map(|_| {
        let rotation = uniform_rotation(rng);
        object
            .iter()
            .all(|p| (rotation * p + translation).z >= nearest_allowed)
            .then_some(rotation)
    })
}

/// The first-order (Cramér–Rao) RMS rotation error of `problem` under
/// isotropic pixel noise `sigma_px` through `camera`, degrees
/// ([`crate::error_model::first_order`]); `None` for σ = 0 or an
/// unobservable pose.
pub fn rotation_limit_deg(camera: &Camera, problem: &Problem, sigma_px: f64) -> Option<f64> {
    if sigma_px <= 0.0 {
        return None;
    }
    pose_covariance_isotropic(camera, &problem.truth, &problem.object, sigma_px)
        .ok()
        .map(|c| c.rms_rotation_deg())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn off_axis_names() {
        assert_eq!(OffAxis::Uniform.to_string(), "uniform");
        assert_eq!(OffAxis::TowardCorner(0.0).to_string(), "axis");
        assert_eq!(OffAxis::TowardCorner(1.0).to_string(), "corner");
        assert_eq!(OffAxis::TowardCorner(0.5).to_string(), "0.5-corner");
    }

    #[test]
    fn corner_fraction_one_projects_the_centroid_to_a_corner() {
        let cell = Cell {
            depth_ratio: 5.0,
            points: 6,
            thickness: 1.0,
            off_axis: OffAxis::TowardCorner(1.0),
            distortion: true,
            sigma_px: 0.0,
        };
        let camera = cell.camera();
        for case in 0..20 {
            let generated = generate(&cell, 3, case);
            let pixel = camera
                .project(&generated.problem.truth.translation)
                .unwrap();
            let on_corner = [0.0, 1280.0].iter().any(|&u| (pixel.x - u).abs() < 1e-6)
                && [0.0, 720.0].iter().any(|&v| (pixel.y - v).abs() < 1e-6);
            assert!(on_corner, "centroid at {pixel:?}");
        }
    }
}
