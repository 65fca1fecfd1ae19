//! The part's supports as analytic occluders: capsules (struts and
//! pillars), round cones (the cone under each sphere) and boxes (the base
//! plate), with exact ray intersections. [`crate::mesh::Marker::occluders`]
//! lists them from the same design the mesher builds its solid from, so
//! the two cannot drift apart.
//!
//! The fillets that blend parts where they meet a sphere are modelled as
//! well ([`Occluder::Fillet`]): the mesher's smooth union of the sphere's
//! hull and the strut pieces at it, cut down to where a fillet can swell
//! (within a blend radius of a strut piece). The fillets at the base
//! plate are left out: the plate lies behind every sphere.

pub use crate::mesh::sdf::ray_ball;
use crate::mesh::sdf::{ray_capsule, ray_round_cone};
use nalgebra::Vector3;

/// Largest number of sphere-tracing steps on a fillet.
const TRACE_STEPS: usize = 96;
/// Distance at which sphere tracing counts a hit, mm.
const TRACE_HIT_MM: f64 = 1e-5;

/// How much a sphere's own [`Occluder::Fillet`] is grown when the model
/// follows that sphere's sight lines, mm. The printed surface is a mesh
/// of the exact smooth union, up to about 0.08 mm off it at export's
/// default grid; where the fillet leaves the sphere it is seen edge-on at
/// the sphere's rim, and there that error turns into hidden sight lines
/// (a hit counts as a support's only beyond [`super::SURFACE_TOLERANCE_MM`]
/// from every sphere). Other spheres' fillets, seen across, are exact.
pub const FILLET_MARGIN_MM: f64 = 0.1;

/// One analytic part of the supports, in the marker frame, mm.
#[derive(Debug, Clone, PartialEq)]
pub enum Occluder {
    /// A cylinder with round ends from `a` to `b`.
    Capsule {
        /// Start of the axis.
        a: Vector3<f64>,
        /// End of the axis.
        b: Vector3<f64>,
        /// Radius.
        radius: f64,
    },
    /// The convex hull of two balls (a cone with round ends).
    RoundCone {
        /// Centre of the first ball.
        a: Vector3<f64>,
        /// Its radius.
        radius_a: f64,
        /// Centre of the second ball.
        b: Vector3<f64>,
        /// Its radius.
        radius_b: f64,
    },
    /// The fillet where struts meet a sphere: the quadratic smooth union
    /// (blend radius `blend_mm`), in this order, of the `hulls` (each the
    /// convex hull of two balls: a sphere's ball and the tip of the cone
    /// under it, or the ball alone) and the strut `pieces` (capsules),
    /// intersected with the pieces grown by `blend_mm`, outside which the
    /// smooth union adds nothing to its members; grown by
    /// [`FILLET_MARGIN_MM`].
    Fillet {
        /// (centre a, radius a, centre b, radius b) of each hull.
        hulls: Vec<(Vector3<f64>, f64, Vector3<f64>, f64)>,
        /// (axis start, axis end, radius) of each strut piece.
        pieces: Vec<(Vector3<f64>, Vector3<f64>, f64)>,
        /// Blend radius, mm.
        blend_mm: f64,
    },
    /// An axis-aligned box.
    Box {
        /// Centre.
        centre: Vector3<f64>,
        /// Half extents along x, y, z.
        half_extents: Vector3<f64>,
    },
}

impl Occluder {
    /// A ball that holds the whole part: (centre, radius).
    pub fn bounding_ball(&self) -> (Vector3<f64>, f64) {
        match self {
            Occluder::Capsule { a, b, radius } => (0.5 * (a + b), 0.5 * (b - a).norm() + radius),
            Occluder::RoundCone {
                a,
                radius_a,
                b,
                radius_b,
            } => {
                let centre = 0.5 * (a + b);
                let half = 0.5 * (b - a).norm();
                (centre, half + radius_a.max(*radius_b))
            }
            Occluder::Fillet {
                pieces, blend_mm, ..
            } => {
                let (lo, hi) = pieces.iter().fold(
                    (
                        Vector3::repeat(f64::INFINITY),
                        Vector3::repeat(f64::NEG_INFINITY),
                    ),
                    |(lo, hi), (a, b, radius)| {
                        let grow = Vector3::repeat(radius + blend_mm + FILLET_MARGIN_MM);
                        (lo.inf(&(a.inf(b) - grow)), hi.sup(&(a.sup(b) + grow)))
                    },
                );
                if pieces.is_empty() {
                    (Vector3::zeros(), 0.0)
                } else {
                    (0.5 * (lo + hi), 0.5 * (hi - lo).norm())
                }
            }
            Occluder::Box {
                centre,
                half_extents,
            } => (*centre, half_extents.norm()),
        }
    }

    /// The distance from `p` to the part (0 inside).
    pub fn distance(&self, p: &Vector3<f64>) -> f64 {
        match self {
            Occluder::Capsule { a, b, radius } => {
                ((p - closest_on_segment(p, a, b)).norm() - radius).max(0.0)
            }
            Occluder::RoundCone {
                a,
                radius_a,
                b,
                radius_b,
            } => round_cone_distance(p, a, *radius_a, b, *radius_b).max(0.0),
            Occluder::Fillet {
                hulls,
                pieces,
                blend_mm,
            } => fillet_distance(p, hulls, pieces, *blend_mm).max(0.0),
            Occluder::Box {
                centre,
                half_extents,
            } => ((p - centre).abs() - half_extents)
                .sup(&Vector3::zeros())
                .norm(),
        }
    }

    /// The entry distance of the ray `origin + t·direction` (unit
    /// direction, origin outside the part) into the part.
    pub fn ray_hit(&self, origin: &Vector3<f64>, direction: &Vector3<f64>) -> Option<f64> {
        self.ray_hit_before(origin, direction, f64::INFINITY)
    }

    /// [`Occluder::ray_hit`], for a caller that asks only whether the ray
    /// enters the part before `limit`: a hit at or beyond it may be
    /// reported as none (a round cone's tracing stops there).
    pub fn ray_hit_before(
        &self,
        origin: &Vector3<f64>,
        direction: &Vector3<f64>,
        limit: f64,
    ) -> Option<f64> {
        self.ray_hit_grown(origin, direction, limit, 0.0)
    }

    /// [`Occluder::ray_hit_before`] for the part grown by `grow_mm`: every
    /// point within `grow_mm` of it (a box grows to the box `grow_mm`
    /// wider on every side, which holds that).
    pub fn ray_hit_grown(
        &self,
        origin: &Vector3<f64>,
        direction: &Vector3<f64>,
        limit: f64,
        grow_mm: f64,
    ) -> Option<f64> {
        match self {
            Occluder::Capsule { a, b, radius } => {
                ray_capsule(origin, direction, a, b, radius + grow_mm)
            }
            Occluder::RoundCone {
                a,
                radius_a,
                b,
                radius_b,
            } => ray_round_cone(
                origin,
                direction,
                (a, radius_a + grow_mm),
                (b, radius_b + grow_mm),
            ),
            Occluder::Fillet {
                hulls,
                pieces,
                blend_mm,
            } => self.trace(origin, direction, limit, grow_mm, |p| {
                fillet_distance(p, hulls, pieces, *blend_mm)
            }),
            Occluder::Box {
                centre,
                half_extents,
            } => {
                let (mut near, mut far) = (f64::NEG_INFINITY, f64::INFINITY);
                for k in 0..3 {
                    let lo = centre[k] - half_extents[k] - grow_mm - origin[k];
                    let hi = centre[k] + half_extents[k] + grow_mm - origin[k];
                    if direction[k] == 0.0 {
                        if lo > 0.0 || hi < 0.0 {
                            return None;
                        }
                        continue;
                    }
                    let (t0, t1) = (lo / direction[k], hi / direction[k]);
                    near = near.max(t0.min(t1));
                    far = far.min(t0.max(t1));
                }
                (near <= far && far >= 0.0).then_some(near.max(0.0))
            }
        }
    }
}

impl Occluder {
    /// The same part with every point that defines it passed through `f`
    /// (radii, blend and a box's extents kept).
    pub fn map_points(&self, f: impl Fn(&Vector3<f64>) -> Vector3<f64>) -> Occluder {
        match self {
            Occluder::Capsule { a, b, radius } => Occluder::Capsule {
                a: f(a),
                b: f(b),
                radius: *radius,
            },
            Occluder::RoundCone {
                a,
                radius_a,
                b,
                radius_b,
            } => Occluder::RoundCone {
                a: f(a),
                radius_a: *radius_a,
                b: f(b),
                radius_b: *radius_b,
            },
            Occluder::Fillet {
                hulls,
                pieces,
                blend_mm,
            } => Occluder::Fillet {
                hulls: hulls
                    .iter()
                    .map(|(a, ra, b, rb)| (f(a), *ra, f(b), *rb))
                    .collect(),
                pieces: pieces.iter().map(|(a, b, r)| (f(a), f(b), *r)).collect(),
                blend_mm: *blend_mm,
            },
            Occluder::Box {
                centre,
                half_extents,
            } => Occluder::Box {
                centre: f(centre),
                half_extents: *half_extents,
            },
        }
    }
}

impl Occluder {
    /// For a fillet, how far beyond its pieces' surfaces it can reach
    /// (its own sphere's margin, [`FILLET_MARGIN_MM`], included).
    pub fn fillet_reach(&self) -> Option<f64> {
        match self {
            Occluder::Fillet {
                hulls,
                pieces,
                blend_mm,
            } => Some(fillet_reach(hulls.len() + pieces.len(), *blend_mm) + FILLET_MARGIN_MM),
            _ => None,
        }
    }

    /// Whether this is the fillet of the sphere centred at `centre` (one
    /// of its hulls starts with that sphere's ball).
    pub fn is_fillet_of(&self, centre: &Vector3<f64>) -> bool {
        match self {
            Occluder::Fillet { hulls, .. } => {
                hulls.iter().any(|(a, ..)| (a - centre).norm() < 1e-9)
            }
            _ => false,
        }
    }

    /// Sphere tracing of a lower bound on the distance (`distance`, at
    /// most 1-Lipschitz) less `grow_mm`, from where the ray enters the
    /// bounding ball grown as much.
    fn trace(
        &self,
        origin: &Vector3<f64>,
        direction: &Vector3<f64>,
        limit: f64,
        grow_mm: f64,
        distance: impl Fn(&Vector3<f64>) -> f64,
    ) -> Option<f64> {
        let (centre, bound) = self.bounding_ball();
        let bound = bound + grow_mm;
        let start = ray_ball(origin, direction, &centre, bound)?;
        let end = (start + 2.0 * bound).min(limit);
        let mut t = start;
        for _ in 0..TRACE_STEPS {
            let d = distance(&(origin + direction * t)) - grow_mm;
            if d < TRACE_HIT_MM {
                return Some(t);
            }
            t += d;
            if t > end {
                return None;
            }
        }
        None
    }
}

/// The quadratic smooth minimum of two distances with blend radius `k`
/// (the mesher's junction blend, `mesh::sdf::smooth_min`).
fn smooth_min(a: f64, b: f64, k: f64) -> f64 {
    let h = (k - (a - b).abs()).max(0.0) / k;
    a.min(b) - 0.25 * k * h * h
}

/// How far from its pieces a fillet of `members` members can reach: each
/// smooth minimum lies at most a quarter blend below the lesser of its two
/// values and adds nothing where they differ by a blend or more, so a
/// point the union holds is within a blend plus the deepest blend below
/// the union's members of every piece that shapes it.
fn fillet_reach(members: usize, blend_mm: f64) -> f64 {
    blend_mm * (1.0 + 0.25 * members.saturating_sub(1) as f64)
}

/// Signed distance bound of [`Occluder::Fillet`] (negative inside): the
/// smooth union of hulls then pieces, cut to the pieces grown by the blend.
fn fillet_distance(
    p: &Vector3<f64>,
    hulls: &[(Vector3<f64>, f64, Vector3<f64>, f64)],
    pieces: &[(Vector3<f64>, Vector3<f64>, f64)],
    blend_mm: f64,
) -> f64 {
    let capsule = |(a, b, r): &(Vector3<f64>, Vector3<f64>, f64)| {
        (p - closest_on_segment(p, a, b)).norm() - r
    };
    let nearest_piece = pieces.iter().map(capsule).fold(f64::INFINITY, f64::min);
    let members = hulls
        .iter()
        .map(|(a, ra, b, rb)| round_cone_distance(p, a, *ra, b, *rb))
        .chain(pieces.iter().map(capsule));
    let union = members
        .reduce(|v, s| smooth_min(v, s, blend_mm))
        .unwrap_or(f64::INFINITY);
    union.max(nearest_piece - fillet_reach(hulls.len() + pieces.len(), blend_mm))
}

/// The point of segment `ab` nearest to `p`.
pub fn closest_on_segment(p: &Vector3<f64>, a: &Vector3<f64>, b: &Vector3<f64>) -> Vector3<f64> {
    let ab = b - a;
    let length_squared = ab.norm_squared();
    if length_squared == 0.0 {
        return *a;
    }
    a + ab * ((p - a).dot(&ab) / length_squared).clamp(0.0, 1.0)
}

/// Exact distance to the convex hull of two balls (negative inside).
fn round_cone_distance(
    p: &Vector3<f64>,
    a: &Vector3<f64>,
    radius_a: f64,
    b: &Vector3<f64>,
    radius_b: f64,
) -> f64 {
    let axis_vector = b - a;
    let length = axis_vector.norm();
    if length <= (radius_a - radius_b).abs() {
        // One ball holds the other.
        return if radius_a >= radius_b {
            (p - a).norm() - radius_a
        } else {
            (p - b).norm() - radius_b
        };
    }
    let axis = axis_vector / length;
    let rel = p - a;
    let along = rel.dot(&axis);
    let radial = (rel - axis * along).norm();
    let sine = (radius_a - radius_b) / length;
    let cosine = (1.0 - sine * sine).sqrt();
    let position_on_flank =
        (along - radius_a * sine) * cosine - (radial - radius_a * cosine) * sine;
    if position_on_flank <= 0.0 {
        (p - a).norm() - radius_a
    } else if position_on_flank >= length * cosine {
        (p - b).norm() - radius_b
    } else {
        along * sine + radial * cosine - radius_a
    }
}

/// Whether a ball of radius `ball_radius` at `q` covers any of the sphere
/// (`centre`, `radius`) seen from `camera`: it lies in the cone of sight
/// lines from the camera to the sphere, nearer than the sphere's centre.
/// Conservative (a ball just behind the sphere's rim counts).
pub fn ball_covers_sphere(
    camera: &Vector3<f64>,
    q: &Vector3<f64>,
    ball_radius: f64,
    centre: &Vector3<f64>,
    radius: f64,
) -> bool {
    let to_sphere = centre - camera;
    let distance = to_sphere.norm();
    let to_ball = q - camera;
    let ball_distance = to_ball.norm();
    if ball_distance <= ball_radius {
        return true;
    }
    let cosine = (to_ball.dot(&to_sphere) / (ball_distance * distance)).clamp(-1.0, 1.0);
    if ball_distance * cosine - ball_radius >= distance {
        return false;
    }
    let half_angle = (radius / distance).clamp(-1.0, 1.0).asin();
    let ball_angle = (ball_radius / ball_distance).clamp(-1.0, 1.0).asin();
    cosine.acos() < half_angle + ball_angle
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn capsule_hits_side_and_end() {
        let capsule = Occluder::Capsule {
            a: Vector3::new(0.0, 0.0, 0.0),
            b: Vector3::new(0.0, 0.0, 10.0),
            radius: 1.0,
        };
        let origin = Vector3::new(-5.0, 0.0, 5.0);
        let t = capsule.ray_hit(&origin, &Vector3::x()).expect("a hit");
        assert_relative_eq!(t, 4.0, epsilon = 1e-12);
        let t = capsule
            .ray_hit(&Vector3::new(0.0, 0.0, -5.0), &Vector3::z())
            .expect("the end ball");
        assert_relative_eq!(t, 4.0, epsilon = 1e-12);
        assert!(capsule
            .ray_hit(&Vector3::new(-5.0, 2.0, 5.0), &Vector3::x())
            .is_none());
    }

    #[test]
    fn box_and_round_cone_agree_with_their_distance() {
        let parts = [
            Occluder::Box {
                centre: Vector3::new(1.0, 2.0, 3.0),
                half_extents: Vector3::new(2.0, 1.0, 0.5),
            },
            Occluder::RoundCone {
                a: Vector3::new(0.0, 0.0, 0.0),
                radius_a: 5.0,
                b: Vector3::new(0.0, 0.0, 6.0),
                radius_b: 1.5,
            },
        ];
        for part in &parts {
            let (centre, _) = part.bounding_ball();
            for k in 0..40 {
                let angle = k as f64 * 0.37;
                let origin = centre + Vector3::new(angle.cos(), angle.sin(), 0.3) * 30.0;
                let aim = centre + Vector3::new(0.0, 0.1 * (k % 7) as f64, 0.5 * (k % 5) as f64);
                let direction = (aim - origin).normalize();
                if let Some(t) = part.ray_hit(&origin, &direction) {
                    let hit = origin + direction * t;
                    assert!(part.distance(&hit) < 1e-4, "{part:?} {k}");
                    // Nothing of the part lies nearer along the ray.
                    for s in 0..100 {
                        let before = origin + direction * (t * s as f64 / 100.0);
                        assert!(part.distance(&before) > 0.0 || s == 100);
                    }
                }
            }
        }
    }

    #[test]
    fn round_cone_hits_agree_with_a_fine_march_along_the_ray() {
        // Long and short cones, either ball the larger, and a near cylinder.
        let cones = [
            (
                Vector3::new(0.0, 0.0, 0.0),
                5.0,
                Vector3::new(0.0, 0.0, 6.22),
                1.0,
            ),
            (
                Vector3::new(1.0, -2.0, 3.0),
                1.0,
                Vector3::new(4.0, 5.0, -6.0),
                3.0,
            ),
            (
                Vector3::new(0.0, 0.0, 0.0),
                2.0,
                Vector3::new(0.0, 9.0, 0.0),
                2.0 - 1e-12,
            ),
            (
                Vector3::new(0.0, 0.0, 0.0),
                4.0,
                Vector3::new(0.0, 0.0, 1.0),
                2.0,
            ),
        ];
        let mut hits = 0;
        for (c, &(a, radius_a, b, radius_b)) in cones.iter().enumerate() {
            let part = Occluder::RoundCone {
                a,
                radius_a,
                b,
                radius_b,
            };
            let (centre, bound) = part.bounding_ball();
            for k in 0..400 {
                let u = k as f64 * 0.618_033_988_75;
                let v = k as f64 * 0.414_213_562_37;
                let origin =
                    centre + Vector3::new(u.cos() * v.sin(), u.sin() * v.sin(), v.cos()) * 40.0;
                let aim = centre
                    + Vector3::new((3.1 * u).sin(), (1.7 * v).cos(), (2.3 * u).cos()) * bound;
                let direction = (aim - origin).normalize();
                let exact = part.ray_hit(&origin, &direction);
                // March by the exact distance, at least 1 µm a step, to the
                // first point inside: no step passes over the part.
                let mut marched = None;
                let mut t = 0.0;
                while t < 120.0 {
                    let d = part.distance(&(origin + direction * t));
                    if d <= 0.0 {
                        marched = Some(t);
                        break;
                    }
                    t += d.max(1e-3);
                }
                match (exact, marched) {
                    (Some(t), Some(m)) => {
                        hits += 1;
                        assert!((t - m).abs() < 2e-3, "cone {c} ray {k}: {t} {m}");
                    }
                    (None, None) => {}
                    other => panic!("cone {c} ray {k}: {other:?}"),
                }
            }
        }
        assert!(hits > 200, "{hits}");
    }

    #[test]
    fn a_ball_between_camera_and_sphere_covers_it() {
        let camera = Vector3::new(0.0, 0.0, -500.0);
        let centre = Vector3::zeros();
        assert!(ball_covers_sphere(
            &camera,
            &Vector3::new(0.0, 5.5, -20.0),
            1.0,
            &centre,
            5.0
        ));
        assert!(!ball_covers_sphere(
            &camera,
            &Vector3::new(0.0, 8.0, -20.0),
            1.0,
            &centre,
            5.0
        ));
        // Behind the sphere: never.
        assert!(!ball_covers_sphere(
            &camera,
            &Vector3::new(0.0, 0.0, 20.0),
            1.0,
            &centre,
            5.0
        ));
    }
}
