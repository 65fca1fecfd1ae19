//! The capture plan: which views of a part to record so that
//! [`super::characterise`] reaches its bar, and the σ each sphere would
//! reach from them.
//!
//! The views face the camera with the part's centroid on the optical axis,
//! tilted about the camera's x axis and panned about its y axis over
//! −40°…40° in 20° steps (25 views), plus four steeper ones, ±55° about
//! each axis: the depth of a sphere along the line of sight is what one
//! view sees worst, and views turned about two axes see it from the side.
//! A view keeps the spheres that are in front, inside the image and not
//! overlapped by a nearer sphere's disc ([`crate::scenario::visibility`];
//! the part's supports are not modelled here), and needs four of them.
//!
//! The predicted σ is the first-order covariance of the characterised
//! centres ([`super::gauge::shape_covariance`]) from the views'
//! information, at a centre noise of `sigma_px` per axis.

use super::bundle::{shape_information, Observation, MIN_FRAMES};
use super::gauge::{shape_covariance, Distance};
use crate::camera::Camera;
use crate::layout::Layout;
use crate::pose::Pose;
use crate::scenario::{sphere_images, visibility};
use nalgebra::{DMatrix, Matrix3, Rotation3, Vector3};
use serde::Serialize;

/// The plan's tilts and pans, degrees (every pair).
pub const PLAN_ANGLES_DEG: [f64; 5] = [-40.0, -20.0, 0.0, 20.0, 40.0];

/// The steeper views' angle, degrees (about each axis alone, both signs).
pub const STEEP_ANGLE_DEG: f64 = 55.0;

/// Default σ of a centre for the plan, px per axis.
pub const DEFAULT_PLAN_SIGMA_PX: f64 = 0.02;

/// Depth step of the search for the nearest depth the plan fits at, mm.
const DEPTH_STEP_MM: f64 = 10.0;

/// One view to capture.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PlannedView {
    /// Rotation about the camera's x axis, degrees.
    pub tilt_deg: f64,
    /// Rotation about the camera's y axis, degrees.
    pub pan_deg: f64,
    /// Depth of the part's centroid, mm.
    pub depth_mm: f64,
    /// The spheres it sees (layout indices).
    pub spheres: Vec<usize>,
    /// The pose, object → camera.
    #[serde(skip)]
    pub pose: Pose,
}

impl PlannedView {
    /// "tilt 20° pan −40° at 450 mm".
    pub fn describe(&self) -> String {
        format!(
            "tilt {:+.0}° pan {:+.0}° at {:.0} mm",
            self.tilt_deg, self.pan_deg, self.depth_mm
        )
    }
}

/// The plan's views of `layout` at `depth_mm`, those that see at least
/// four spheres.
pub fn views(layout: &Layout, camera: &Camera, depth_mm: f64) -> Vec<PlannedView> {
    let shape = layout.positions();
    let centroid = shape.iter().sum::<Vector3<f64>>() / shape.len() as f64;
    let mut angles: Vec<(f64, f64)> = PLAN_ANGLES_DEG
        .iter()
        .flat_map(|&t| PLAN_ANGLES_DEG.iter().map(move |&p| (t, p)))
        .collect();
    for sign in [-1.0, 1.0] {
        angles.push((sign * STEEP_ANGLE_DEG, 0.0));
        angles.push((0.0, sign * STEEP_ANGLE_DEG));
    }
    angles
        .into_iter()
        .filter_map(|(tilt_deg, pan_deg)| {
            let rotation = Rotation3::from_axis_angle(&Vector3::y_axis(), pan_deg.to_radians())
                * Rotation3::from_axis_angle(&Vector3::x_axis(), tilt_deg.to_radians());
            let pose = Pose::new(
                rotation,
                Vector3::new(0.0, 0.0, depth_mm) - rotation * centroid,
            );
            let spheres = seen(layout, camera, &pose);
            (spheres.len() >= 4).then_some(PlannedView {
                tilt_deg,
                pan_deg,
                depth_mm,
                spheres,
                pose,
            })
        })
        .collect()
}

/// The spheres a pose shows clearly.
fn seen(layout: &Layout, camera: &Camera, pose: &Pose) -> Vec<usize> {
    let images = sphere_images(camera, pose, &layout.positions(), layout.sphere_diameter_mm);
    let rules = visibility(&images, camera);
    (0..images.len())
        .filter(|i| {
            !rules.behind.contains(i)
                && !rules.outside.contains(i)
                && !rules.occluded.iter().any(|(hidden, _)| hidden == i)
        })
        .collect()
}

/// The nearest depth in `[near_mm, far_mm]`, in steps of 10 mm, at which
/// every view of the plan keeps all its spheres inside the image; `far_mm`
/// when none does.
pub fn nearest_depth(layout: &Layout, camera: &Camera, near_mm: f64, far_mm: f64) -> f64 {
    let mut depth = near_mm;
    while depth < far_mm {
        let inside = views(layout, camera, depth).iter().all(|v| {
            let images = sphere_images(
                camera,
                &v.pose,
                &layout.positions(),
                layout.sphere_diameter_mm,
            );
            visibility(&images, camera).outside.is_empty()
        });
        if inside {
            return depth;
        }
        depth += DEPTH_STEP_MM;
    }
    far_mm
}

/// A view's noise-free observations of `shape` (frame 0).
fn observations(shape: &[Vector3<f64>], view: &PlannedView) -> Vec<Observation> {
    view.spheres
        .iter()
        .map(|&sphere| Observation {
            frame: 0,
            sphere,
            normalised: view.pose.project_normalised(&shape[sphere]),
        })
        .collect()
}

/// The reduced information of `shape` from one view (normalised units).
fn view_information(shape: &[Vector3<f64>], view: &PlannedView) -> Option<DMatrix<f64>> {
    let observations = observations(shape, view);
    shape_information(
        shape,
        &[view.pose],
        &observations,
        &vec![1.0; observations.len()],
    )
    .ok()
}

/// Each centre's predicted 3×3 covariance, mm², once `layout` is
/// characterised from the capture plan's views (at the nearest depth in
/// `[near_mm, far_mm]` where they fit) with `sigma_px` of centre noise per
/// axis, at the nominal's scale; `None` when fewer than
/// [`MIN_FRAMES`] views see four spheres or the views leave the shape
/// unobserved.
pub fn predicted_covariances(
    layout: &Layout,
    camera: &Camera,
    near_mm: f64,
    far_mm: f64,
    sigma_px: f64,
) -> Option<Vec<Matrix3<f64>>> {
    let depth_mm = nearest_depth(layout, camera, near_mm, far_mm);
    let views = views(layout, camera, depth_mm);
    if views.len() < MIN_FRAMES {
        return None;
    }
    let shape = layout.positions();
    let focal = 0.5 * (camera.fx() + camera.fy());
    let covariance = shape_covariance(
        &plan_information(&shape, &views),
        &shape,
        (sigma_px / focal).powi(2),
        &[],
    )?;
    Some(
        (0..shape.len())
            .map(|i| covariance.fixed_view::<3, 3>(3 * i, 3 * i).into_owned())
            .collect(),
    )
}

/// The summed reduced information of `shape` over `views`.
fn plan_information(shape: &[Vector3<f64>], views: &[PlannedView]) -> DMatrix<f64> {
    let n = 3 * shape.len();
    views
        .iter()
        .filter_map(|v| view_information(shape, v))
        .fold(DMatrix::zeros(n, n), |sum, s| sum + s)
}

/// Each sphere's largest predicted 1σ, mm, from `information` at centre
/// noise σ² (normalised units²); `None` where the views leave the shape
/// unobserved.
fn largest_sigmas(
    information: &DMatrix<f64>,
    shape: &[Vector3<f64>],
    sigma_squared: f64,
    distances: &[Distance],
) -> Option<Vec<f64>> {
    let covariance = shape_covariance(information, shape, sigma_squared, distances)?;
    let sigmas: Vec<f64> = (0..shape.len())
        .map(|i| {
            let block = covariance.fixed_view::<3, 3>(3 * i, 3 * i).into_owned();
            block.symmetric_eigen().eigenvalues.max().max(0.0).sqrt()
        })
        .collect();
    sigmas.iter().all(|s| s.is_finite()).then_some(sigmas)
}

/// A capture plan and what it would give.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CapturePlan {
    /// The layout.
    pub layout: String,
    /// The views, in capture order.
    pub views: Vec<PlannedView>,
    /// The centre σ assumed, px per axis.
    pub sigma_px: f64,
    /// Each sphere's predicted largest 1σ, mm (layout order).
    pub sphere_sigma_mm: Vec<f64>,
    /// The spheres' names.
    pub names: Vec<String>,
}

/// Why no plan could be made.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum PlanError {
    /// Too few views see four spheres.
    #[error("at {depth_mm:.0} mm only {views} of the plan's views see four spheres or more of {layout}; the part does not fit the image there, or its spheres hide each other")]
    TooFewViews {
        /// The layout.
        layout: String,
        /// The depth.
        depth_mm: f64,
        /// Views that see enough.
        views: usize,
    },
    /// A configuration value is out of range.
    #[error(transparent)]
    Config(#[from] crate::config::ConfigError),
}

/// The capture plan of `layout` at the nearest depth in
/// `[near_mm, far_mm]` where it fits, at centre noise `sigma_px`.
pub fn capture_plan(
    layout: &Layout,
    camera: &Camera,
    near_mm: f64,
    far_mm: f64,
    sigma_px: f64,
) -> Result<CapturePlan, PlanError> {
    layout
        .validate()
        .map_err(|e| crate::config::ConfigError::new("layout", e.to_string()))?;
    if !(near_mm.is_finite() && near_mm > 0.0 && far_mm >= near_mm && far_mm.is_finite()) {
        return Err(
            crate::config::ConfigError::new("depth", "must be a positive range NEAR..FAR").into(),
        );
    }
    if !(sigma_px.is_finite() && sigma_px > 0.0) {
        return Err(crate::config::ConfigError::new("sigma_px", "must be positive").into());
    }
    let depth_mm = nearest_depth(layout, camera, near_mm, far_mm);
    let views = views(layout, camera, depth_mm);
    let shape = layout.positions();
    let information = plan_information(&shape, &views);
    let focal = 0.5 * (camera.fx() + camera.fy());
    let too_few = || PlanError::TooFewViews {
        layout: layout.name.clone(),
        depth_mm,
        views: views.len(),
    };
    if views.len() < MIN_FRAMES {
        return Err(too_few());
    }
    let sphere_sigma_mm = largest_sigmas(&information, &shape, (sigma_px / focal).powi(2), &[])
        .ok_or_else(too_few)?;
    Ok(CapturePlan {
        layout: layout.name.clone(),
        views,
        sigma_px,
        sphere_sigma_mm,
        names: layout.points.iter().map(|p| p.name.clone()).collect(),
    })
}

/// What a characterisation's frames observed, in its gauge.
#[derive(Debug, Clone, Copy)]
pub(super) struct Observed<'a> {
    /// The characterised centres.
    pub shape: &'a [Vector3<f64>],
    /// The frames' poses.
    pub poses: &'a [Pose],
    /// The centres measured.
    pub observations: &'a [Observation],
    /// Their robust weights.
    pub weights: &'a [f64],
    /// A centre's σ², normalised units.
    pub sigma_squared: f64,
    /// The measured distances.
    pub distances: &'a [Distance],
}

/// Most views [`views_to_add`] names.
const MAX_VIEWS_TO_ADD: usize = 12;

/// The plan's views that, added to the frames a characterisation had,
/// bring every sphere's σ down fastest (greedily, worst sphere first),
/// until the bar is met or [`MAX_VIEWS_TO_ADD`] are named; at the frames'
/// median depth.
pub(super) fn views_to_add(
    nominal: &Layout,
    camera: &Camera,
    max_sigma_mm: f64,
    observed: &Observed<'_>,
) -> Vec<String> {
    let Observed {
        shape,
        poses,
        observations,
        weights,
        sigma_squared,
        distances,
    } = *observed;
    let Ok(mut information) = shape_information(shape, poses, observations, weights) else {
        return Vec::new();
    };
    let mut depths: Vec<f64> = poses.iter().map(|p| p.translation.norm()).collect();
    let depth_mm = crate::statistics::median(&mut depths).unwrap_or(500.0);
    let mut layout = nominal.clone();
    for (point, x) in layout.points.iter_mut().zip(shape) {
        point.position = *x;
    }
    let mut candidates: Vec<(PlannedView, DMatrix<f64>)> = views(&layout, camera, depth_mm)
        .into_iter()
        .filter_map(|v| {
            let information = view_information(shape, &v)?;
            Some((v, information))
        })
        .collect();
    let worst = |information: &DMatrix<f64>| {
        largest_sigmas(information, shape, sigma_squared, distances)
            .map_or(f64::INFINITY, |s| s.into_iter().fold(0.0, f64::max))
    };
    let mut chosen = Vec::new();
    while chosen.len() < MAX_VIEWS_TO_ADD && !candidates.is_empty() {
        let (best, sigma) = candidates
            .iter()
            .enumerate()
            .map(|(k, (_, s))| (k, worst(&(&information + s))))
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .expect("candidates is not empty");
        let (view, view_information) = candidates.remove(best);
        information += view_information;
        chosen.push(view.describe());
        if sigma <= max_sigma_mm {
            break;
        }
    }
    chosen
}
