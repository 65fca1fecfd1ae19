//! The ground truth beside every image: the pose and, per sphere, its exact
//! silhouette conic and ellipse centre ([`crate::sphere_image`]), its
//! projected centre and how much of its silhouette is hidden, by cause.
//!
//! **Hidden fractions** come from the tool's one visibility model
//! ([`crate::visibility::hidden_fractions`]), the same figures `validate`,
//! `search` and `export` count, with the supports
//! ([`crate::mesh::Marker::occluders`]) of the part in the image: the
//! shares of the sight lines through the sphere's disc that meet another
//! sphere first (*by a sphere*), a pillar, strut, cone or the plate first
//! (*by the support*), or whose point on the sphere projects outside the
//! image (*outside the image*). The integration tests check them against
//! an independent dense count of the renderer's own rays.

use super::scene::Scene;
use super::RenderError;
use crate::camera::Camera;
use crate::config::ConfigError;
use crate::ellipse::Ellipse;
use crate::pose::Pose;
use crate::sphere_image;
use crate::visibility::{self, HiddenFractions};
use nalgebra::{Vector2, Vector3};
use serde::Serialize;

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
/// frame 0), or spheres of several radii, which the visibility model does
/// not take ([`RenderError::Config`]).
pub fn frame_truth(
    scene: &Scene,
    names: &[String],
    pose: &Pose,
    camera: &Camera,
) -> Result<FrameTruth, RenderError> {
    let hidden = hidden_fractions(scene, pose, camera)?;
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
        spheres.push(SphereTruth {
            name,
            centre_camera_mm: c.into(),
            radius_mm: radius,
            conic_px: conic.transpose().into(),
            ellipse_centre_px: camera.normalised_to_pixel(&m0).into(),
            ellipse_centre_undistorted_px: undistorted.into(),
            semi_axes_px: ellipse.map_or([f64::NAN; 2], |e| [e.semi_major, e.semi_minor]),
            projected_centre_px: projected.into(),
            hidden: hidden[index],
        });
    }
    Ok(FrameTruth {
        rotation: pose.rotation.matrix().transpose().into(),
        translation: pose.translation.into(),
        spheres,
    })
}

/// Per sphere, the hidden fractions of the visibility model (module docs).
/// The model gives none for a sphere not in front of the camera, which
/// [`frame_truth`] has refused before; such a sphere would count as wholly
/// outside the image.
pub fn hidden_fractions(
    scene: &Scene,
    pose: &Pose,
    camera: &Camera,
) -> Result<Vec<Hidden>, RenderError> {
    let spheres = scene.spheres();
    let Some(&(_, radius)) = spheres.first() else {
        return Ok(Vec::new());
    };
    if spheres.iter().any(|&(_, r)| r != radius) {
        return Err(ConfigError::new(
            "spheres",
            "the visibility model takes spheres of one radius".to_string(),
        )
        .into());
    }
    let centres: Vec<Vector3<f64>> = spheres.iter().map(|&(c, _)| c).collect();
    let fractions = visibility::hidden_fractions(camera, pose, &centres, radius, scene.supports());
    Ok(fractions
        .into_iter()
        .map(|f| match f {
            Some(HiddenFractions {
                support,
                sphere,
                outside,
            }) => Hidden {
                by_support: support,
                by_sphere: sphere,
                outside_image: outside,
            },
            None => Hidden {
                outside_image: 1.0,
                ..Hidden::default()
            },
        })
        .collect())
}
