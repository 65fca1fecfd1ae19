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
/// plate) hides: in the main view, and at worst over the view cone.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Coverage {
    /// The sphere.
    pub sphere: String,
    /// Main view: fraction of the rays through its disc whose first hit is
    /// on a strut or the plate (not on a sphere, and not on the sphere's
    /// own support behind it).
    pub covered_by_struts: f64,
    /// Main view: fraction whose first hit is on another sphere (the
    /// layout's own occlusion in this view).
    pub covered_by_spheres: f64,
    /// The largest fraction covered by struts over the view cone.
    pub cone_covered_by_struts: f64,
    /// The viewing direction (marker frame) where that happens.
    pub cone_worst_direction: [f64; 3],
    /// The largest fraction covered by other spheres over the view cone.
    pub cone_covered_by_spheres: f64,
}

/// Rays per sphere diameter (each way) for the directions of the view
/// cone other than the main one.
pub const CONE_RAYS_PER_DIAMETER: usize = 16;
/// Rings and outer-ring directions sampled in the view cone.
pub const CONE_RINGS: usize = 2;
/// Directions on the outermost ring of the view cone.
pub const CONE_AZIMUTHS: usize = 12;

/// What the first hit of each ray through sphere `index`'s disc, seen
/// along `direction`, lands on: (covered by struts, covered by spheres),
/// as fractions.
fn disc_coverage(
    marker: &Marker,
    index: usize,
    direction: &Vector3<f64>,
    rays_per_diameter: usize,
) -> (f64, f64) {
    let sphere = &marker.spheres[index];
    let k = direction.iamin();
    let helper = Vector3::from_fn(|r, _| if r == k { 1.0 } else { 0.0 });
    let u = direction.cross(&helper).normalize();
    let w = direction.cross(&u);
    let (lo, hi) = marker.bounds();
    let reach = 0.5 * (hi - lo).norm() + 1.0;
    let middle = 0.5 * (lo + hi);
    let view = marker.view.vector();
    // The sphere's own support: behind its centre, within its cone and the
    // fillet below it.
    let own_reach = sphere.radius
        + marker
            .teardrops
            .get(index)
            .copied()
            .flatten()
            .map_or(0.0, |(tip, _)| (tip - sphere.centre).norm())
        + 2.0 * marker.blend_mm;
    let n = rays_per_diameter;
    let (mut total, mut struts, mut spheres) = (0usize, 0usize, 0usize);
    for i in 0..n {
        for j in 0..n {
            let s = (2.0 * (i as f64 + 0.5) / n as f64 - 1.0) * COVERAGE_DISC_FRACTION;
            let t = (2.0 * (j as f64 + 0.5) / n as f64 - 1.0) * COVERAGE_DISC_FRACTION;
            if s * s + t * t > COVERAGE_DISC_FRACTION * COVERAGE_DISC_FRACTION {
                continue;
            }
            total += 1;
            let through = sphere.centre + (u * s + w * t) * sphere.radius;
            // Start in front of the whole part.
            let start = through - direction * ((through - middle).dot(direction) + reach);
            let Some(hit) = first_hit(marker, start, *direction, 2.0 * reach) else {
                struts += 1; // cannot happen: the ray crosses the sphere
                continue;
            };
            let on = marker.spheres.iter().position(|other| {
                ((hit - other.centre).norm() - other.radius).abs() < ON_SPHERE_MM
            });
            match on {
                Some(k) if k == index => {}
                Some(_) => spheres += 1,
                None => {
                    let offset = hit - sphere.centre;
                    let own = offset.dot(&view) > 0.0 && offset.norm() <= own_reach;
                    if !own {
                        struts += 1;
                    }
                }
            }
        }
    }
    (struts as f64 / total as f64, spheres as f64 / total as f64)
}

/// Casts rays through a grid of points on each sphere's disc
/// (orthographic views) along the main viewing direction and along
/// directions over the view cone of half-angle `cone_deg`
/// ([`super::geometry::view_cone_directions`]), and reports what they hit
/// first.
pub fn view_coverage(marker: &Marker, cone_deg: f64) -> Vec<Coverage> {
    let view = marker.view.vector();
    let directions = super::geometry::view_cone_directions(
        &view,
        cone_deg.to_radians(),
        CONE_RINGS,
        CONE_AZIMUTHS,
    );
    (0..marker.spheres.len())
        .into_par_iter()
        .map(|index| {
            let (struts, spheres) = disc_coverage(marker, index, &view, COVERAGE_RAYS_PER_DIAMETER);
            let mut worst = (struts, view, spheres);
            for d in &directions[1..] {
                let (s, o) = disc_coverage(marker, index, d, CONE_RAYS_PER_DIAMETER);
                if s > worst.0 {
                    worst.0 = s;
                    worst.1 = *d;
                }
                worst.2 = worst.2.max(o);
            }
            Coverage {
                sphere: marker.spheres[index].name.clone(),
                covered_by_struts: struts,
                covered_by_spheres: spheres,
                cone_covered_by_struts: worst.0,
                cone_worst_direction: worst.1.into(),
                cone_covered_by_spheres: worst.2,
            }
        })
        .collect()
}

/// [`view_coverage`] in the main view alone.
pub fn main_view_coverage(marker: &Marker) -> Vec<Coverage> {
    view_coverage(marker, 0.0)
}

/// The angle of a viewing direction from the main view, degrees.
pub fn angle_from_view_deg(marker: &Marker, direction: &[f64; 3]) -> f64 {
    Vector3::from(*direction)
        .dot(&marker.view.vector())
        .clamp(-1.0, 1.0)
        .acos()
        .to_degrees()
}

/// Faces this close to the bed (print frame, z) lie on it, mm.
pub const ON_BED_MM: f64 = 0.01;
/// Overhangs lower than this above the bed are printed within the first
/// layer, on the bed, and need no support, mm.
pub const FIRST_LAYER_MM: f64 = 0.3;

/// Downward-facing surface of the part as printed.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Overhang {
    /// The steepest overhang allowed without support, from the vertical,
    /// degrees.
    pub limit_deg: f64,
    /// Area facing down more steeply than the limit, off the bed (and above
    /// the first layer, [`FIRST_LAYER_MM`]) and off the spheres, mm².
    pub area_mm2: f64,
    /// Area of sphere undersides facing down more steeply than the limit,
    /// mm² (above the supports' cones).
    pub sphere_area_mm2: f64,
    /// Support material a slicer would need under all of those, at most:
    /// each overhanging face's area projected on the bed times its height
    /// above the bed, mm³.
    pub support_estimate_mm3: f64,
    /// Area of the part on the bed, mm².
    pub bed_contact_mm2: f64,
}

/// Measures the overhangs of `mesh` (marker frame) as printed: `rotation`
/// and `shift` map it into the print frame (Z up, bed at z = 0).
pub fn overhang(
    marker: &Marker,
    mesh: &TriangleMesh,
    rotation: &nalgebra::Matrix3<f64>,
    shift: &Vector3<f64>,
    limit_deg: f64,
) -> Overhang {
    let cos_limit = limit_deg.to_radians().cos();
    let mut result = Overhang {
        limit_deg,
        area_mm2: 0.0,
        sphere_area_mm2: 0.0,
        support_estimate_mm3: 0.0,
        bed_contact_mm2: 0.0,
    };
    for f in 0..mesh.triangles.len() {
        let corners = mesh.face(f).map(|p| rotation * p + shift);
        let cross = (corners[1] - corners[0]).cross(&(corners[2] - corners[0]));
        let area = 0.5 * cross.norm();
        if area == 0.0 {
            continue;
        }
        let normal = cross / (2.0 * area);
        if corners.iter().all(|c| c.z.abs() < ON_BED_MM) {
            if normal.z < 0.0 {
                result.bed_contact_mm2 += area;
            }
            continue;
        }
        let height = (corners[0].z + corners[1].z + corners[2].z) / 3.0;
        if normal.z >= -cos_limit || height < FIRST_LAYER_MM {
            continue;
        }
        let centroid_marker = mesh.face(f).iter().sum::<Vector3<f64>>() / 3.0;
        let on_sphere = marker
            .spheres
            .iter()
            .any(|s| ((centroid_marker - s.centre).norm() - s.radius).abs() < ON_SPHERE_MM);
        result.support_estimate_mm3 += area * -normal.z * height;
        if on_sphere {
            result.sphere_area_mm2 += area;
        } else {
            result.area_mm2 += area;
        }
    }
    result
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
