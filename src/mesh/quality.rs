//! Measurements of a finished mesh against the analytic solid: how far the
//! faces stray from the true surface, which faces point inwards, and how
//! much of each sphere the struts hide in the main view.

use super::geometry::Marker;
use super::trimesh::TriangleMesh;
use nalgebra::Vector3;
use rayon::prelude::*;
use serde::Serialize;

/// Rays per sphere diameter (each way) in the main-view coverage test.
pub const COVERAGE_RAYS_PER_DIAMETER: usize = 24;
/// Fraction of a sphere's radius covered by the coverage rays (the rim,
/// where a ray grazes the sphere, is left out).
pub const COVERAGE_DISC_FRACTION: f64 = 0.95;
/// A ray hits the surface when the field is below this, mm.
const RAY_HIT_MM: f64 = 1e-4;
/// A hit point is on a sphere when it lies this close to one, mm.
const ON_SPHERE_MM: f64 = 1e-3;

/// The largest distance from the exact surface of any face's centroid or
/// edge midpoint (vertices lie on it), estimated as |f| / |∇f|, mm.
pub fn max_surface_error(marker: &Marker, mesh: &TriangleMesh) -> f64 {
    (0..mesh.triangles.len())
        .into_par_iter()
        .map(|f| {
            let [a, b, c] = mesh.face(f);
            [
                (a + b + c) / 3.0,
                0.5 * (a + b),
                0.5 * (b + c),
                0.5 * (c + a),
            ]
            .iter()
            .map(|p| {
                let s = marker.sample(p);
                s.value.abs() / s.gradient.norm().max(f64::EPSILON)
            })
            .fold(0.0, f64::max)
        })
        .reduce(|| 0.0, f64::max)
}

/// Faces whose normal points against the field's gradient at their
/// centroid (folded over).
pub fn inverted_faces(marker: &Marker, mesh: &TriangleMesh) -> usize {
    (0..mesh.triangles.len())
        .into_par_iter()
        .filter(|&f| {
            let [a, b, c] = mesh.face(f);
            mesh.face_cross(f)
                .dot(&marker.sample(&((a + b + c) / 3.0)).gradient)
                <= 0.0
        })
        .count()
}

/// Unit outward normals at the vertices: the field's gradient there.
pub fn vertex_normals(marker: &Marker, mesh: &TriangleMesh) -> Vec<Vector3<f64>> {
    mesh.positions
        .par_iter()
        .map(|p| {
            let g = marker.sample(p).gradient;
            let norm = g.norm();
            if norm > 0.0 {
                g / norm
            } else {
                Vector3::z()
            }
        })
        .collect()
}

/// How much of one sphere the rest of the marker (struts, fillets, the
/// plate) hides in the main view.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Coverage {
    /// The sphere.
    pub sphere: String,
    /// Fraction of the rays through its disc whose first hit is not on a
    /// sphere.
    pub covered_by_struts: f64,
    /// Fraction whose first hit is on another sphere (the layout's own
    /// occlusion in this view).
    pub covered_by_spheres: f64,
}

/// Casts rays along the main viewing direction through a grid of points on
/// each sphere's disc (orthographic view) and reports what they hit first.
pub fn main_view_coverage(marker: &Marker) -> Vec<Coverage> {
    let view = marker.view.vector();
    // Two unit vectors spanning the image plane.
    let k = (0..3)
        .find(|&k| view[k] == 0.0)
        .expect("an axis is perpendicular");
    let u = Vector3::from_fn(|r, _| if r == k { 1.0 } else { 0.0 });
    let w = view.cross(&u);
    let (lo, hi) = marker.bounds();
    let front = lo.dot(&view).min(hi.dot(&view)) - 1.0;
    let back = lo.dot(&view).max(hi.dot(&view)) + 1.0;
    let n = COVERAGE_RAYS_PER_DIAMETER;
    marker
        .spheres
        .par_iter()
        .enumerate()
        .map(|(index, sphere)| {
            let (mut total, mut struts, mut spheres) = (0usize, 0usize, 0usize);
            for i in 0..n {
                for j in 0..n {
                    let s = (2.0 * (i as f64 + 0.5) / n as f64 - 1.0) * COVERAGE_DISC_FRACTION;
                    let t = (2.0 * (j as f64 + 0.5) / n as f64 - 1.0) * COVERAGE_DISC_FRACTION;
                    if s * s + t * t > COVERAGE_DISC_FRACTION * COVERAGE_DISC_FRACTION {
                        continue;
                    }
                    total += 1;
                    let lateral = sphere.centre - view * sphere.centre.dot(&view)
                        + (u * s + w * t) * sphere.radius;
                    let Some(hit) = first_hit(marker, lateral + view * front, view, back - front)
                    else {
                        struts += 1; // cannot happen: the ray crosses the sphere
                        continue;
                    };
                    let on = marker.spheres.iter().position(|other| {
                        ((hit - other.centre).norm() - other.radius).abs() < ON_SPHERE_MM
                    });
                    match on {
                        Some(k) if k == index => {}
                        Some(_) => spheres += 1,
                        None => struts += 1,
                    }
                }
            }
            Coverage {
                sphere: sphere.name.clone(),
                covered_by_struts: struts as f64 / total as f64,
                covered_by_spheres: spheres as f64 / total as f64,
            }
        })
        .collect()
}

/// Sphere tracing: the first point along `origin + t·direction`, t in
/// [0, length], where the field drops below [`RAY_HIT_MM`].
fn first_hit(
    marker: &Marker,
    origin: Vector3<f64>,
    direction: Vector3<f64>,
    length: f64,
) -> Option<Vector3<f64>> {
    let mut t = 0.0;
    while t <= length {
        let p = origin + direction * t;
        let d = marker.signed_distance(&p);
        if d < RAY_HIT_MM {
            return Some(p);
        }
        t += d;
    }
    None
}
