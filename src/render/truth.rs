//! The ground truth beside every image: the pose and, per sphere, its exact
//! silhouette conic and ellipse centre ([`crate::sphere_image`]), its
//! projected centre and how much of its silhouette is hidden, by cause.
//!
//! **Hidden fractions** are counted over [`SILHOUETTE_RAYS`] rays spread
//! evenly in angle around the sphere's silhouette (the cone of rays
//! tangent to it), each aimed a hair inside the limb: a ray whose limb
//! point projects outside the image counts as *outside the image*; one
//! that meets another sphere's coating first, as hidden *by a sphere*; one
//! that meets anything else of the part first (a pillar, a strut, the
//! plate, a fillet, the sphere's own cone), as hidden *by the support*;
//! in a frame of several markers, one that meets another marker's part
//! first, as hidden *by another marker*, counted per marker.
//! The rays are cast on the same scene as the image's.

use super::analysis::Placed;
use super::scene::{Ray, Scene};
use super::RenderError;
use crate::camera::Camera;
use crate::ellipse::Ellipse;
use crate::pose::Pose;
use crate::sphere_image;
use nalgebra::{Vector2, Vector3};
use serde::Serialize;

/// Rays cast around each sphere's silhouette.
pub const SILHOUETTE_RAYS: usize = 2048;
/// A silhouette ray aims at the limb pulled this fraction of the radius
/// towards the sphere's centre, so that it meets the sphere.
const LIMB_INSET: f64 = 1e-6;

/// Fractions of a sphere's silhouette hidden, by cause (they add up to
/// at most 1).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct Hidden {
    /// Behind the part's own supports (pillars, struts, plate, cones).
    pub by_support: f64,
    /// Behind another sphere.
    pub by_sphere: f64,
    /// Outside the image.
    pub outside_image: f64,
    /// Behind another marker's part (spheres or supports), in a frame of
    /// several markers.
    pub by_other_marker: f64,
}

impl Hidden {
    /// The silhouette hidden, whatever hides it.
    pub fn total(&self) -> f64 {
        (self.by_support + self.by_sphere + self.outside_image + self.by_other_marker).min(1.0)
    }
}

/// How much of a sphere's silhouette one other marker of the frame hides.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct HiddenBy {
    /// The marker, as the frame numbers them (from 1).
    pub marker: usize,
    /// Fraction of the silhouette.
    pub fraction: f64,
}

/// What an image shows of one sphere, exactly.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SphereTruth {
    /// The layout's name for it.
    pub name: String,
    /// Centre in the camera frame, mm.
    pub centre_camera_mm: [f64; 3],
    /// Radius, mm.
    pub radius_mm: f64,
    /// Silhouette conic on undistorted pixel coordinates, positive inside
    /// ([`sphere_image::pixel_conic`]).
    pub conic_px: [[f64; 3]; 3],
    /// Ellipse centre, distorted pixels (`K · distort(m₀)`: the
    /// observation the rest of the tool uses).
    pub ellipse_centre_px: [f64; 2],
    /// Ellipse centre, undistorted pixels (`K · m₀`, the conic's centre).
    pub ellipse_centre_undistorted_px: [f64; 2],
    /// Semi-axes of the conic, undistorted pixels: major, minor.
    pub semi_axes_px: [f64; 2],
    /// The centre projected, distorted pixels.
    pub projected_centre_px: [f64; 2],
    /// Hidden fractions of the silhouette.
    pub hidden: Hidden,
    /// In a frame of several markers: each other marker that hides some of
    /// the silhouette, and how much.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub hidden_by_markers: Vec<HiddenBy>,
}

/// The ground truth of one frame.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FrameTruth {
    /// Rotation, marker to camera (rows).
    #[serde(rename = "R")]
    pub rotation: [[f64; 3]; 3],
    /// Translation: the marker origin in the camera frame, mm.
    #[serde(rename = "t")]
    pub translation: [f64; 3],
    /// Per sphere, layout order.
    pub spheres: Vec<SphereTruth>,
}

/// The truth of the frame at `pose`, or why there is none: a sphere not
/// wholly in front of the camera ([`RenderError::BehindCamera`], naming
/// frame 0).
pub fn frame_truth(
    scene: &Scene,
    names: &[String],
    pose: &Pose,
    camera: &Camera,
) -> Result<FrameTruth, RenderError> {
    part_truth(&[Placed { scene, pose }], 0, names, camera)
}

/// The truth of part `part` of a frame of several `parts` (markers), its
/// spheres named by `names`: as [`frame_truth`], with what the other parts
/// hide of each sphere.
pub fn part_truth(
    parts: &[Placed],
    part: usize,
    names: &[String],
    camera: &Camera,
) -> Result<FrameTruth, RenderError> {
    let Placed { scene, pose } = parts[part];
    let mut spheres = Vec::with_capacity(scene.spheres().len());
    for (index, &(centre, radius)) in scene.spheres().iter().enumerate() {
        let name = names
            .get(index)
            .cloned()
            .unwrap_or_else(|| format!("S{index}"));
        let c = pose.transform(&centre);
        let conic = sphere_image::pixel_conic(camera, &c, radius).map_err(|source| {
            RenderError::BehindCamera {
                frame: 0,
                sphere: name.clone(),
                source,
            }
        })?;
        let m0 = sphere_image::ellipse_centre_normalised(&c, radius).map_err(|source| {
            RenderError::BehindCamera {
                frame: 0,
                sphere: name.clone(),
                source,
            }
        })?;
        let ellipse = Ellipse::from_conic(&conic).ok();
        let undistorted = Vector2::new(
            camera.fx() * m0.x + camera.cx(),
            camera.fy() * m0.y + camera.cy(),
        );
        let projected = camera.project(&c).unwrap_or(Vector2::repeat(f64::NAN));
        let (hidden, by_part) = hidden_among(parts, part, camera, index, SILHOUETTE_RAYS);
        spheres.push(SphereTruth {
            name,
            centre_camera_mm: c.into(),
            radius_mm: radius,
            conic_px: conic.transpose().into(),
            ellipse_centre_px: camera.normalised_to_pixel(&m0).into(),
            ellipse_centre_undistorted_px: undistorted.into(),
            semi_axes_px: ellipse.map_or([f64::NAN; 2], |e| [e.semi_major, e.semi_minor]),
            projected_centre_px: projected.into(),
            hidden,
            hidden_by_markers: by_part
                .iter()
                .enumerate()
                .filter(|&(_, &fraction)| fraction > 0.0)
                .map(|(other, &fraction)| HiddenBy {
                    marker: other + 1,
                    fraction,
                })
                .collect(),
        });
    }
    Ok(FrameTruth {
        rotation: pose.rotation.matrix().transpose().into(),
        translation: pose.translation.into(),
        spheres,
    })
}

/// The points where `rays` rays evenly spread in angle touch the sphere
/// `(centre, radius)` (camera frame) tangentially: its limb.
pub fn limb_points(centre: &Vector3<f64>, radius: f64, rays: usize) -> Vec<Vector3<f64>> {
    let distance = centre.norm();
    let axis = centre / distance;
    let circle_centre = centre * (1.0 - radius * radius / (distance * distance));
    let circle_radius = radius * (distance * distance - radius * radius).max(0.0).sqrt() / distance;
    let (e1, e2) = crate::linalg::perpendicular_pair(&axis);
    (0..rays)
        .map(|k| {
            let phi = std::f64::consts::TAU * (k as f64 + 0.5) / rays as f64;
            circle_centre + (e1 * phi.cos() + e2 * phi.sin()) * circle_radius
        })
        .collect()
}

/// Whether a pixel position lies on the image (pixel squares of
/// `[−½, w − ½] × [−½, h − ½]`).
pub fn on_image(camera: &Camera, pixel: &Vector2<f64>) -> bool {
    pixel.x >= -0.5
        && pixel.y >= -0.5
        && pixel.x <= camera.width() as f64 - 0.5
        && pixel.y <= camera.height() as f64 - 0.5
}

/// The hidden fractions of sphere `index`'s silhouette over `rays` rays
/// (module docs).
pub fn hidden_fractions(
    scene: &Scene,
    pose: &Pose,
    camera: &Camera,
    index: usize,
    rays: usize,
) -> Hidden {
    hidden_among(&[Placed { scene, pose }], 0, camera, index, rays).0
}

/// The hidden fractions of sphere `index` of part `part` among `parts`,
/// and the fraction each part hides (zero for `part` itself).
fn hidden_among(
    parts: &[Placed],
    part: usize,
    camera: &Camera,
    index: usize,
    rays: usize,
) -> (Hidden, Vec<f64>) {
    let Placed { scene, pose } = parts[part];
    let (centre, radius) = scene.spheres()[index];
    let c = pose.transform(&centre);
    let views: Vec<(Vector3<f64>, nalgebra::Rotation3<f64>, Vec<u32>)> = parts
        .iter()
        .map(|p| {
            let inverse = p.pose.rotation.inverse();
            (
                -(inverse * p.pose.translation),
                inverse,
                p.scene.all_shapes(),
            )
        })
        .collect();
    let mut counts = [0usize; 3];
    let mut by_part = vec![0usize; parts.len()];
    for limb in limb_points(&c, radius, rays) {
        let visible_on_image = camera.project(&limb).is_some_and(|p| on_image(camera, &p));
        if !visible_on_image {
            counts[2] += 1;
            continue;
        }
        let aim = (c + (limb - c) * (1.0 - LIMB_INSET)).normalize();
        let nearest = parts
            .iter()
            .zip(&views)
            .enumerate()
            .filter_map(|(k, (p, (origin, inverse, all)))| {
                let ray = Ray {
                    origin: *origin,
                    direction: inverse * aim,
                };
                p.scene.first_hit(&ray, all).map(|hit| (k, hit))
            })
            .min_by(|a, b| a.1.t.total_cmp(&b.1.t));
        match nearest {
            Some((k, _)) if k != part => by_part[k] += 1,
            Some((_, hit)) if hit.sphere == Some(index) => {}
            Some((_, hit)) if hit.sphere.is_some() => counts[1] += 1,
            Some(_) => counts[0] += 1,
            None => {}
        }
    }
    let n = rays as f64;
    let hidden = Hidden {
        by_support: counts[0] as f64 / n,
        by_sphere: counts[1] as f64 / n,
        outside_image: counts[2] as f64 / n,
        by_other_marker: by_part.iter().sum::<usize>() as f64 / n,
    };
    (hidden, by_part.iter().map(|&k| k as f64 / n).collect())
}
