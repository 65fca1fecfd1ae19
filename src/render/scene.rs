//! The part as rays meet it: the primitives [`Marker::design`] builds
//! (balls, capsules, the round cones under the spheres of a printable part,
//! the base plate with its holes, the flat cut on the bed), intersected
//! exactly where a closed form is short (balls, capsules, round cones, the
//! plate's box) and by sphere tracing of the primitive's own signed
//! distance ([`crate::mesh::sdf`]) where it is not (the plate's rounded
//! edges and hole rims). Near a junction, where the mesher blends primitives
//! into fillets, a hit is refined on the marker's full signed-distance
//! function ([`Marker::signed_distance`]), so the image shows the solid
//! `export` meshes, fillets included.
//!
//! Everything here is in the marker frame (mm); a ray comes in already
//! transformed from the camera.

use crate::mesh::sdf;
use crate::mesh::Marker;
use nalgebra::Vector3;

/// A traced hit is accepted this close to the surface, mm.
pub const SURFACE_EPSILON_MM: f64 = 1e-5;
/// Most sphere-tracing steps along one ray through one primitive.
const MAX_TRACE_STEPS: usize = 160;
/// A hit point this close to a sphere's ball belongs to the sphere (its
/// coating), mm; farther, to the support.
pub const SPHERE_MATERIAL_TOLERANCE_MM: f64 = 5e-5;

/// One primitive of the part.
#[derive(Debug, Clone)]
pub(crate) enum Shape {
    /// A feature sphere, with the cone under it on a printable part
    /// (`(tip, tip radius)`: the round cone from the ball to the tip).
    Sphere {
        centre: Vector3<f64>,
        radius: f64,
        teardrop: Option<(Vector3<f64>, f64)>,
    },
    /// A strut: a capsule.
    Capsule {
        a: Vector3<f64>,
        b: Vector3<f64>,
        radius: f64,
    },
    /// The base plate (the marker's, with its holes).
    Plate,
}

/// A ray in the marker frame: origin and unit direction.
#[derive(Debug, Clone, Copy)]
pub struct Ray {
    /// Origin (the camera centre), mm.
    pub origin: Vector3<f64>,
    /// Unit direction.
    pub direction: Vector3<f64>,
}

impl Ray {
    fn at(&self, t: f64) -> Vector3<f64> {
        self.origin + self.direction * t
    }
}

/// What a ray meets first.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hit {
    /// Distance along the ray, mm.
    pub t: f64,
    /// The primitive hit (index into the scene's shapes).
    pub shape: usize,
    /// The sphere whose coating was hit, `None` for a support.
    pub sphere: Option<usize>,
    /// Outward unit normal at the hit, marker frame.
    pub normal: Vector3<f64>,
}

/// The part, ready for rays.
#[derive(Debug, Clone)]
pub struct Scene {
    pub(crate) shapes: Vec<Shape>,
    /// The spheres: (centre, radius), layout order.
    pub(crate) spheres: Vec<(Vector3<f64>, f64)>,
    /// The whole marker, for fillets and the plate; `None` for spheres
    /// alone.
    marker: Option<Marker>,
    /// The flat cut: the solid keeps `p · down ≤ level`.
    bed: Option<(Vector3<f64>, f64)>,
    /// For each primitive, a ball holding it: `(centre, radius)`.
    enclosing: Vec<(Vector3<f64>, f64)>,
}

impl Scene {
    /// The part [`Marker::design`] built.
    pub fn from_marker(marker: Marker) -> Scene {
        let mut shapes: Vec<Shape> = marker
            .spheres
            .iter()
            .enumerate()
            .map(|(index, s)| Shape::Sphere {
                centre: s.centre,
                radius: s.radius,
                teardrop: marker.teardrops.get(index).copied().flatten(),
            })
            .collect();
        shapes.extend(marker.struts.iter().map(|s| Shape::Capsule {
            a: s.a,
            b: s.b,
            radius: s.radius,
        }));
        shapes.push(Shape::Plate);
        let spheres = marker
            .spheres
            .iter()
            .map(|s| (s.centre, s.radius))
            .collect();
        let bed = marker.bed_level.map(|level| (marker.down.vector(), level));
        let enclosing = shapes
            .iter()
            .map(|shape| enclosing_ball(shape, &marker))
            .collect();
        Scene {
            shapes,
            spheres,
            marker: Some(marker),
            bed,
            enclosing,
        }
    }

    /// Free-floating spheres and nothing else (to check the silhouettes
    /// against the exact model).
    pub fn spheres_only(spheres: &[(Vector3<f64>, f64)]) -> Scene {
        Scene {
            shapes: spheres
                .iter()
                .map(|&(centre, radius)| Shape::Sphere {
                    centre,
                    radius,
                    teardrop: None,
                })
                .collect(),
            spheres: spheres.to_vec(),
            marker: None,
            bed: None,
            enclosing: spheres.to_vec(),
        }
    }

    /// The spheres: (centre, radius) in the marker frame, layout order.
    pub fn spheres(&self) -> &[(Vector3<f64>, f64)] {
        &self.spheres
    }

    /// How many primitives.
    pub fn shape_count(&self) -> usize {
        self.shapes.len()
    }

    /// The corners of a box holding the whole part, marker frame.
    pub fn bounding_corners(&self) -> [Vector3<f64>; 8] {
        let (lo, hi) = match &self.marker {
            Some(marker) => marker.bounds(),
            None => {
                let mut lo = Vector3::repeat(f64::INFINITY);
                let mut hi = Vector3::repeat(f64::NEG_INFINITY);
                for (c, r) in &self.spheres {
                    lo = lo.inf(&(c - Vector3::repeat(*r)));
                    hi = hi.sup(&(c + Vector3::repeat(*r)));
                }
                (lo, hi)
            }
        };
        std::array::from_fn(|k| {
            Vector3::new(
                if k & 1 == 0 { lo.x } else { hi.x },
                if k & 2 == 0 { lo.y } else { hi.y },
                if k & 4 == 0 { lo.z } else { hi.z },
            )
        })
    }

    /// Balls that together hold each primitive: `(shape, centre, radius)`.
    /// Long struts and the plate are cut into pieces so that the balls
    /// stay tight; the renderer projects them to find the pixels the part
    /// may cover.
    pub fn bounding_balls(&self) -> Vec<(usize, Vector3<f64>, f64)> {
        let mut balls = Vec::new();
        let segment = |balls: &mut Vec<(usize, Vector3<f64>, f64)>,
                       shape: usize,
                       a: Vector3<f64>,
                       b: Vector3<f64>,
                       radius: f64| {
            let length = (b - a).norm();
            let pieces = ((length / (2.0 * radius).max(1e-9)).ceil() as usize).clamp(1, 64);
            for k in 0..pieces {
                let p0 = a + (b - a) * (k as f64 / pieces as f64);
                let p1 = a + (b - a) * ((k + 1) as f64 / pieces as f64);
                balls.push((shape, 0.5 * (p0 + p1), radius + 0.5 * (p1 - p0).norm()));
            }
        };
        for (index, shape) in self.shapes.iter().enumerate() {
            match shape {
                Shape::Sphere {
                    centre,
                    radius,
                    teardrop,
                    ..
                } => match teardrop {
                    Some((tip, tip_radius)) => {
                        segment(&mut balls, index, *centre, *tip, radius.max(*tip_radius))
                    }
                    None => balls.push((index, *centre, *radius)),
                },
                Shape::Capsule { a, b, radius } => segment(&mut balls, index, *a, *b, *radius),
                Shape::Plate => {
                    let plate = &self.marker.as_ref().expect("a plate has a marker").plate;
                    let h = plate.half_extents;
                    let cells =
                        Vector3::from_fn(|k, _| ((h[k] / h.min()).ceil() as usize).clamp(1, 16));
                    let cell = Vector3::from_fn(|k, _| 2.0 * h[k] / cells[k] as f64);
                    for i in 0..cells.x {
                        for j in 0..cells.y {
                            for l in 0..cells.z {
                                let centre = plate.centre - h
                                    + Vector3::new(
                                        (i as f64 + 0.5) * cell.x,
                                        (j as f64 + 0.5) * cell.y,
                                        (l as f64 + 0.5) * cell.z,
                                    );
                                balls.push((index, centre, 0.5 * cell.norm()));
                            }
                        }
                    }
                }
            }
        }
        balls
    }

    /// The first surface along `ray` among the primitives `candidates`
    /// (indices into the shapes), or `None`.
    pub fn first_hit(&self, ray: &Ray, candidates: &[u32]) -> Option<Hit> {
        let (low, high) = self.bed_interval(ray);
        if low > high {
            return None;
        }
        let mut best: Option<Hit> = None;
        for &index in candidates {
            let limit = best.map_or(high, |b| b.t.min(high));
            if let Some(hit) = self.shape_hit(index as usize, ray, low, limit) {
                if best.is_none_or(|b| hit.t < b.t) {
                    best = Some(hit);
                }
            }
        }
        let hit = best?;
        Some(self.refine_at_junction(ray, hit, candidates))
    }

    /// Every primitive's index, for a ray with no tile to narrow it.
    pub fn all_shapes(&self) -> Vec<u32> {
        (0..self.shapes.len() as u32).collect()
    }

    /// The sphere whose coating covers `p`, if any.
    fn sphere_at(&self, p: &Vector3<f64>) -> Option<usize> {
        self.spheres
            .iter()
            .position(|(c, r)| (p - c).norm() <= r + SPHERE_MATERIAL_TOLERANCE_MM)
    }

    /// The part of the ray on the solid's side of the bed cut, `t > 0`.
    fn bed_interval(&self, ray: &Ray) -> (f64, f64) {
        let (mut low, mut high) = (0.0, f64::INFINITY);
        if let Some((down, level)) = self.bed {
            let along = ray.direction.dot(&down);
            let start = ray.origin.dot(&down) - level;
            if along.abs() < 1e-15 {
                if start > 0.0 {
                    return (1.0, 0.0);
                }
            } else if along > 0.0 {
                high = -start / along;
            } else {
                low = f64::max(low, -start / along);
            }
        }
        (low, high)
    }

    /// A primitive's signed distance (the bed cut applied).
    fn shape_distance(&self, index: usize, p: &Vector3<f64>) -> sdf::Sample {
        let value = match &self.shapes[index] {
            Shape::Sphere {
                centre,
                radius,
                teardrop,
                ..
            } => match teardrop {
                Some((tip, tip_radius)) => sdf::round_cone(p, centre, *radius, tip, *tip_radius),
                None => sdf::ball(p, centre, *radius),
            },
            Shape::Capsule { a, b, radius } => sdf::capsule(p, a, b, *radius),
            Shape::Plate => {
                let marker = self.marker.as_ref().expect("a plate has a marker");
                let plate = &marker.plate;
                let mut value =
                    sdf::rounded_box(p, &plate.centre, &plate.half_extents, plate.rounding);
                for hole in &plate.holes {
                    let cut = sdf::cylinder(p, &hole.centre, &hole.axis, hole.radius);
                    value = sdf::smooth_subtract(value, cut, marker.rim_blend_mm);
                }
                value
            }
        };
        match self.bed {
            Some((down, level)) => sdf::max(value, sdf::half_space(p, &down, level)),
            None => value,
        }
    }

    /// The first hit on one primitive within `[low, high]`.
    fn shape_hit(&self, index: usize, ray: &Ray, low: f64, high: f64) -> Option<Hit> {
        match &self.shapes[index] {
            Shape::Sphere {
                centre,
                radius,
                teardrop,
                ..
            } => {
                match teardrop {
                    None => self.clipped_hit(
                        index,
                        ray,
                        ball_interval(ray, centre, *radius)?,
                        low,
                        high,
                    ),
                    Some((tip, tip_radius)) => {
                        // The round cone is convex: its chord runs from the
                        // ray's entry to the reversed ray's entry from
                        // beyond the capsule that holds it.
                        let bound = capsule_interval(ray, centre, tip, radius.max(*tip_radius))?;
                        let cone = |origin: &Vector3<f64>, direction: &Vector3<f64>| {
                            sdf::ray_round_cone(
                                origin,
                                direction,
                                (centre, *radius),
                                (tip, *tip_radius),
                            )
                        };
                        let entry = cone(&ray.origin, &ray.direction)?;
                        let exit = bound.1 - cone(&ray.at(bound.1), &-ray.direction)?;
                        self.clipped_hit(index, ray, (entry, exit), low, high)
                    }
                }
            }
            Shape::Capsule { a, b, radius } => {
                let interval = capsule_interval(ray, a, b, *radius)?;
                self.clipped_hit(index, ray, interval, low, high)
            }
            Shape::Plate => {
                let plate = &self.marker.as_ref()?.plate;
                let (t0, t1) = box_interval(ray, &plate.centre, &plate.half_extents)?;
                let t = self.trace(index, ray, t0.max(low), t1.min(high))?;
                Some(self.hit_at(index, ray, t))
            }
        }
    }

    /// The hit of a convex primitive whose chord is `(t0, t1)`, clipped to
    /// `[low, high]`: on its surface, or on the bed face where the cut
    /// removes its front.
    fn clipped_hit(
        &self,
        index: usize,
        ray: &Ray,
        (t0, t1): (f64, f64),
        low: f64,
        high: f64,
    ) -> Option<Hit> {
        let start = t0.max(low);
        if start > t1.min(high) || start <= 0.0 {
            return None;
        }
        if t0 >= low {
            return Some(self.hit_at(index, ray, start));
        }
        let (down, _) = self.bed.expect("only the bed cut clips a chord");
        Some(Hit {
            t: start,
            shape: index,
            sphere: None,
            normal: down,
        })
    }

    /// A hit on primitive `index` at `t`, its normal from the primitive's
    /// gradient and its material from where it lies.
    fn hit_at(&self, index: usize, ray: &Ray, t: f64) -> Hit {
        let p = ray.at(t);
        Hit {
            t,
            shape: index,
            sphere: self.sphere_at(&p),
            normal: self.shape_distance(index, &p).gradient,
        }
    }

    /// Sphere tracing of one primitive on `[start, stop]`.
    fn trace(&self, index: usize, ray: &Ray, start: f64, stop: f64) -> Option<f64> {
        let mut t = start;
        for _ in 0..MAX_TRACE_STEPS {
            if t > stop {
                return None;
            }
            let value = self.shape_distance(index, &ray.at(t)).value;
            if value < SURFACE_EPSILON_MM {
                return Some(t);
            }
            t += value;
        }
        None
    }

    /// Near a junction the mesher blends the primitives into fillets that
    /// stand in front of them: where another primitive lies within the
    /// blend radius of the hit, walk back along the ray on the marker's
    /// full signed distance to where the blended solid begins.
    fn refine_at_junction(&self, ray: &Ray, hit: Hit, candidates: &[u32]) -> Hit {
        let Some(marker) = &self.marker else {
            return hit;
        };
        if marker.blend_mm <= 0.0 {
            return hit;
        }
        let p = ray.at(hit.t);
        // A primitive is at least as far from `p` as its enclosing ball,
        // so only those whose ball lies within the blend radius are
        // evaluated.
        let near_other = candidates.iter().any(|&j| {
            let (centre, radius) = &self.enclosing[j as usize];
            j as usize != hit.shape
                && (p - centre).norm() - radius < marker.blend_mm
                && self.shape_distance(j as usize, &p).value < marker.blend_mm
        });
        if !near_other {
            return hit;
        }
        // March back from inside by the signed distance, which never
        // crosses the surface, to the front of the blended solid.
        let mut t = hit.t;
        let mut sample = marker.sample(&ray.at(t));
        for _ in 0..MAX_TRACE_STEPS {
            if sample.value > -SURFACE_EPSILON_MM {
                break;
            }
            t += sample.value;
            sample = marker.sample(&ray.at(t));
        }
        let p = ray.at(t);
        Hit {
            t,
            shape: hit.shape,
            sphere: self.sphere_at(&p),
            normal: sample.gradient,
        }
    }
}

/// A ball holding one primitive of `marker`: `(centre, radius)`.
fn enclosing_ball(shape: &Shape, marker: &Marker) -> (Vector3<f64>, f64) {
    let segment = |a: &Vector3<f64>, b: &Vector3<f64>, radius: f64| {
        (0.5 * (a + b), 0.5 * (b - a).norm() + radius)
    };
    match shape {
        Shape::Sphere {
            centre,
            radius,
            teardrop,
        } => match teardrop {
            Some((tip, tip_radius)) => segment(centre, tip, radius.max(*tip_radius)),
            None => (*centre, *radius),
        },
        Shape::Capsule { a, b, radius } => segment(a, b, *radius),
        Shape::Plate => (marker.plate.centre, marker.plate.half_extents.norm()),
    }
}

/// The chord of a ball, `(entry, exit)`.
fn ball_interval(ray: &Ray, centre: &Vector3<f64>, radius: f64) -> Option<(f64, f64)> {
    let oc = ray.origin - centre;
    let b = oc.dot(&ray.direction);
    let c = oc.norm_squared() - radius * radius;
    let discriminant = b * b - c;
    if discriminant < 0.0 {
        return None;
    }
    let root = discriminant.sqrt();
    Some((-b - root, -b + root))
}

/// The chord of a capsule: the union of its end balls and its cylinder
/// (a convex solid, so one interval).
fn capsule_interval(
    ray: &Ray,
    a: &Vector3<f64>,
    b: &Vector3<f64>,
    radius: f64,
) -> Option<(f64, f64)> {
    let axis = b - a;
    let length = axis.norm();
    if length > 0.0 {
        // The capsule lies within the infinite cylinder of its radius
        // about its axis: a ray whose line passes farther from the axis
        // line misses it (the common case, and a cheap one).
        let normal = ray.direction.cross(&axis);
        let normal_norm = normal.norm();
        if normal_norm > 1e-12 * length
            && (ray.origin - a).dot(&normal).abs() > radius * (1.0 + 1e-9) * normal_norm
        {
            return None;
        }
    }
    let mut result: Option<(f64, f64)> = None;
    let mut merge = |interval: (f64, f64)| {
        result = Some(match result {
            None => interval,
            Some((t0, t1)) => (t0.min(interval.0), t1.max(interval.1)),
        });
    };
    if let Some(i) = ball_interval(ray, a, radius) {
        merge(i);
    }
    if let Some(i) = ball_interval(ray, b, radius) {
        merge(i);
    }
    if length > 0.0 {
        let u = axis / length;
        let oa = ray.origin - a;
        let d_along = ray.direction.dot(&u);
        let o_along = oa.dot(&u);
        let d_perp = ray.direction - u * d_along;
        let o_perp = oa - u * o_along;
        let qa = d_perp.norm_squared();
        let qb = o_perp.dot(&d_perp);
        let qc = o_perp.norm_squared() - radius * radius;
        let radial = if qa < 1e-18 {
            (qc <= 0.0).then_some((f64::NEG_INFINITY, f64::INFINITY))
        } else {
            let discriminant = qb * qb - qa * qc;
            (discriminant >= 0.0).then(|| {
                let root = discriminant.sqrt();
                ((-qb - root) / qa, (-qb + root) / qa)
            })
        };
        let slab = if d_along.abs() < 1e-18 {
            (0.0..=length)
                .contains(&o_along)
                .then_some((f64::NEG_INFINITY, f64::INFINITY))
        } else {
            let (s0, s1) = (-o_along / d_along, (length - o_along) / d_along);
            Some((s0.min(s1), s0.max(s1)))
        };
        if let (Some(r), Some(s)) = (radial, slab) {
            let (t0, t1) = (r.0.max(s.0), r.1.min(s.1));
            if t0 <= t1 {
                merge((t0, t1));
            }
        }
    }
    result
}

/// The chord of an axis-aligned box (slab method).
fn box_interval(
    ray: &Ray,
    centre: &Vector3<f64>,
    half_extents: &Vector3<f64>,
) -> Option<(f64, f64)> {
    let (mut t0, mut t1) = (f64::NEG_INFINITY, f64::INFINITY);
    for k in 0..3 {
        let (lo, hi) = (centre[k] - half_extents[k], centre[k] + half_extents[k]);
        let d = ray.direction[k];
        let o = ray.origin[k];
        if d.abs() < 1e-18 {
            if o < lo || o > hi {
                return None;
            }
        } else {
            let (a, b) = ((lo - o) / d, (hi - o) / d);
            t0 = t0.max(a.min(b));
            t1 = t1.min(a.max(b));
        }
    }
    (t0 <= t1 && t1 > 0.0).then_some((t0, t1))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ray(origin: [f64; 3], direction: [f64; 3]) -> Ray {
        Ray {
            origin: Vector3::from(origin),
            direction: Vector3::from(direction).normalize(),
        }
    }

    #[test]
    fn chords_of_a_ball_a_capsule_and_a_box_are_exact() {
        let r = ray([0.0, 0.0, -10.0], [0.0, 0.0, 1.0]);
        let (t0, t1) = ball_interval(&r, &Vector3::new(0.0, 0.0, 5.0), 2.0).unwrap();
        assert!((t0 - 13.0).abs() < 1e-12 && (t1 - 17.0).abs() < 1e-12);
        let far = ray([0.0, 0.0, 10.0], [0.0, 0.0, -1.0]);
        let (t0, _) = ball_interval(&far, &Vector3::new(0.0, 0.0, 5.0), 2.0).unwrap();
        assert!((t0 - 3.0).abs() < 1e-12);
        // Across a capsule along x, and into its round end.
        let across = ray([3.0, 0.0, -10.0], [0.0, 0.0, 1.0]);
        let (a, b) = (Vector3::zeros(), Vector3::new(6.0, 0.0, 0.0));
        let (t0, t1) = capsule_interval(&across, &a, &b, 1.0).unwrap();
        assert!((t0 - 9.0).abs() < 1e-12 && (t1 - 11.0).abs() < 1e-12);
        let end = ray([-10.0, 0.0, 0.0], [1.0, 0.0, 0.0]);
        let (t0, t1) = capsule_interval(&end, &a, &b, 1.0).unwrap();
        assert!((t0 - 9.0).abs() < 1e-12 && (t1 - 17.0).abs() < 1e-12);
        assert!(capsule_interval(&ray([3.0, 2.0, -10.0], [0.0, 0.0, 1.0]), &a, &b, 1.0).is_none());
        let (t0, t1) = box_interval(&r, &Vector3::zeros(), &Vector3::repeat(1.0)).unwrap();
        assert!((t0 - 9.0).abs() < 1e-12 && (t1 - 11.0).abs() < 1e-12);
    }

    #[test]
    fn the_nearer_sphere_is_hit_first_and_named() {
        let scene = Scene::spheres_only(&[
            (Vector3::new(0.0, 0.0, 100.0), 5.0),
            (Vector3::new(0.0, 0.0, 50.0), 5.0),
        ]);
        let hit = scene
            .first_hit(&ray([0.0, 0.0, 0.0], [0.0, 0.0, 1.0]), &scene.all_shapes())
            .unwrap();
        assert_eq!(hit.sphere, Some(1));
        assert!((hit.t - 45.0).abs() < 1e-12);
        assert!((hit.normal - Vector3::new(0.0, 0.0, -1.0)).norm() < 1e-12);
    }
}
