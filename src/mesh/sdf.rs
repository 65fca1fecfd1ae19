//! Analytic signed distances with gradients: the primitives a marker is made
//! of (balls, capsules, a rounded box with through-holes) and the blends
//! that join them; and a ray's exact entry into a ball, a capsule and a
//! round cone (the convex hull of two balls), which the visibility model
//! and the renderer both cast.
//!
//! Every function here is 1-Lipschitz (|∇f| ≤ 1), and so is every blend of
//! them ([`smooth_min`] combines gradients with weights in [0, 1] that sum to
//! one): a value `f(p)` proves that no surface lies within `|f(p)|` of `p`.
//! Meshing relies on this to skip empty space.
//!
//! Reference: I. Quilez, "Smooth minimum" (the quadratic polynomial blend)
//! and "Distance functions" (capsule, rounded box).

use nalgebra::Vector3;

/// A signed distance and its gradient at one point (negative inside).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sample {
    /// Signed distance, mm (negative inside).
    pub value: f64,
    /// Gradient of the signed distance (a unit vector for exact distances).
    pub gradient: Vector3<f64>,
}

/// A unit vector perpendicular to `v` (for gradients on a medial point,
/// where any direction is as good as another).
fn any_unit(v: Vector3<f64>) -> Vector3<f64> {
    let norm = v.norm();
    if norm > 0.0 {
        v / norm
    } else {
        Vector3::x()
    }
}

/// Ball of `radius` around `centre`.
pub fn ball(p: &Vector3<f64>, centre: &Vector3<f64>, radius: f64) -> Sample {
    let d = p - centre;
    Sample {
        value: d.norm() - radius,
        gradient: any_unit(d),
    }
}

/// The closest point to `p` on the segment `a`–`b`.
pub fn closest_on_segment(p: &Vector3<f64>, a: &Vector3<f64>, b: &Vector3<f64>) -> Vector3<f64> {
    let ab = b - a;
    let length2 = ab.norm_squared();
    let t = if length2 > 0.0 {
        ((p - a).dot(&ab) / length2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    a + ab * t
}

/// Capsule of `radius` around the segment `a`–`b` (a strut with round ends).
pub fn capsule(p: &Vector3<f64>, a: &Vector3<f64>, b: &Vector3<f64>, radius: f64) -> Sample {
    let d = p - closest_on_segment(p, a, b);
    Sample {
        value: d.norm() - radius,
        gradient: any_unit(d),
    }
}

/// Infinite cylinder of `radius` around the line through `origin` along the
/// unit vector `axis`.
pub fn cylinder(
    p: &Vector3<f64>,
    origin: &Vector3<f64>,
    axis: &Vector3<f64>,
    radius: f64,
) -> Sample {
    let along = p - origin;
    let radial = along - axis * along.dot(axis);
    Sample {
        value: radial.norm() - radius,
        gradient: any_unit(radial),
    }
}

/// Axis-aligned box with `half_extents` around `centre`, its edges and
/// corners rounded with `rounding` (≤ every half extent).
pub fn rounded_box(
    p: &Vector3<f64>,
    centre: &Vector3<f64>,
    half_extents: &Vector3<f64>,
    rounding: f64,
) -> Sample {
    let local = p - centre;
    let q = local.abs() - (half_extents - Vector3::repeat(rounding));
    let outside = q.map(|v| v.max(0.0));
    let outside_norm = outside.norm();
    if outside_norm > 0.0 {
        let gradient = Vector3::from_fn(|k, _| outside[k] * local[k].signum()) / outside_norm;
        Sample {
            value: outside_norm - rounding,
            gradient,
        }
    } else {
        let k = q.imax();
        let mut gradient = Vector3::zeros();
        gradient[k] = local[k].signum();
        Sample {
            value: q[k] - rounding,
            gradient,
        }
    }
}

/// Round cone: the convex hull of the ball of radius `radius_a` around `a`
/// and the smaller ball of radius `radius_b` around `b` (`radius_a ≥
/// radius_b`, `|b − a| > radius_a − radius_b`): two balls joined by the cone
/// tangent to both. Its flank makes the angle `asin((radius_a − radius_b) /
/// |b − a|)` with the axis. Exact outside; inside, the distance to the
/// nearest of the two spheres and the flank selected by the point's
/// projection onto the flank (Quilez, "Distance functions", round cone).
pub fn round_cone(
    p: &Vector3<f64>,
    a: &Vector3<f64>,
    radius_a: f64,
    b: &Vector3<f64>,
    radius_b: f64,
) -> Sample {
    let axis_vector = b - a;
    let length = axis_vector.norm();
    let axis = axis_vector / length;
    let rel = p - a;
    let along = rel.dot(&axis);
    let radial_vector = rel - axis * along;
    let radial = radial_vector.norm();
    let radial_unit = any_unit(radial_vector);
    // The flank's outward normal in the (along, radial) half-plane, and its
    // direction from the tangent point on ball a to that on ball b.
    let sine = ((radius_a - radius_b) / length).clamp(-1.0, 1.0);
    let cosine = (1.0 - sine * sine).sqrt();
    let (normal_along, normal_radial) = (sine, cosine);
    let position_on_flank =
        (along - radius_a * normal_along) * cosine - (radial - radius_a * normal_radial) * sine;
    if position_on_flank <= 0.0 {
        ball(p, a, radius_a)
    } else if position_on_flank >= length * cosine {
        ball(p, b, radius_b)
    } else {
        Sample {
            value: along * normal_along + radial * normal_radial - radius_a,
            gradient: axis * normal_along + radial_unit * normal_radial,
        }
    }
}

/// Quadratic polynomial smooth minimum with blend radius `blend_mm`: equal
/// to `min(a, b)` where the two differ by more than `blend_mm`, and at most
/// `blend_mm / 4` below it where they are close, which rounds the crease
/// where two surfaces meet into a fillet.
pub fn smooth_min(a: Sample, b: Sample, blend_mm: f64) -> Sample {
    let h = (blend_mm - (a.value - b.value).abs()).max(0.0) / blend_mm;
    let (low, high) = if a.value <= b.value { (a, b) } else { (b, a) };
    if h == 0.0 {
        return low;
    }
    // d/d(low) = 1 − h/2, d/d(high) = h/2.
    Sample {
        value: low.value - 0.25 * blend_mm * h * h,
        gradient: low.gradient * (1.0 - 0.5 * h) + high.gradient * (0.5 * h),
    }
}

/// Smooth difference `a \ b`: `max(a, −b)`, blended like [`smooth_min`] so
/// that the rim is rounded.
pub fn smooth_subtract(a: Sample, b: Sample, blend_mm: f64) -> Sample {
    let negated = |s: Sample| Sample {
        value: -s.value,
        gradient: -s.gradient,
    };
    negated(smooth_min(negated(a), b, blend_mm))
}

/// Half-space `{p : normal·p ≤ level}` (unit `normal`).
pub fn half_space(p: &Vector3<f64>, normal: &Vector3<f64>, level: f64) -> Sample {
    Sample {
        value: normal.dot(p) - level,
        gradient: *normal,
    }
}

/// Exact maximum (the value and gradient of the larger): intersection.
pub fn max(a: Sample, b: Sample) -> Sample {
    if a.value >= b.value {
        a
    } else {
        b
    }
}

/// Exact minimum (the value and gradient of the smaller).
pub fn min(a: Sample, b: Sample) -> Sample {
    if a.value <= b.value {
        a
    } else {
        b
    }
}

/// The entry distance of the ray `origin + t·direction` (unit direction)
/// into the ball, if it meets it ahead of the origin.
pub fn ray_ball(
    origin: &Vector3<f64>,
    direction: &Vector3<f64>,
    centre: &Vector3<f64>,
    radius: f64,
) -> Option<f64> {
    let oc = origin - centre;
    let b = oc.dot(direction);
    let c = oc.norm_squared() - radius * radius;
    let h = b * b - c;
    if h < 0.0 {
        return None;
    }
    let root = h.sqrt();
    let t = -b - root;
    if t >= 0.0 {
        Some(t)
    } else if -b + root >= 0.0 {
        Some(0.0)
    } else {
        None
    }
}

/// Entry distance of the ray `origin + t·direction` (unit direction) into
/// the convex hull of two balls, if it meets it ahead of the origin: the
/// first of its entries into either ball and into the frustum between the
/// circles where the flank touches them (a nappe of the cone through both
/// balls, cut by two planes across its axis), each exact.
pub fn ray_round_cone(
    origin: &Vector3<f64>,
    direction: &Vector3<f64>,
    first: (&Vector3<f64>, f64),
    second: (&Vector3<f64>, f64),
) -> Option<f64> {
    // The larger ball first.
    let ((a, radius_a), (b, radius_b)) = if first.1 >= second.1 {
        (first, second)
    } else {
        (second, first)
    };
    let along = b - a;
    let length = along.norm();
    if length <= radius_a - radius_b {
        return ray_ball(origin, direction, a, radius_a);
    }
    let sine = (radius_a - radius_b) / length;
    if sine < 1e-9 {
        return ray_capsule(origin, direction, a, b, radius_a);
    }
    let balls = [
        ray_ball(origin, direction, a, radius_a),
        ray_ball(origin, direction, b, radius_b),
    ];
    let mut best = balls.into_iter().flatten().reduce(f64::min);
    let axis = along / length;
    // The cone's apex lies beyond the smaller ball; `s` measures distance
    // from it back along the axis, towards the larger ball. The flank
    // touches the balls at s = ra/sine − ra·sine and at s = ra/sine −
    // length − rb·sine.
    let apex_s = radius_a / sine;
    let co = origin - (a + axis * apex_s);
    let (dv, cv) = (-direction.dot(&axis), -co.dot(&axis));
    let (s_low, s_high) = (apex_s - length - radius_b * sine, apex_s - radius_a * sine);
    // Where the ray lies between the two planes.
    let (low, high) = if dv.abs() < 1e-15 {
        if cv < s_low || cv > s_high {
            return best;
        }
        (0.0, f64::INFINITY)
    } else {
        let (t0, t1) = ((s_low - cv) / dv, (s_high - cv) / dv);
        (t0.min(t1).max(0.0), t0.max(t1))
    };
    if low > high {
        return best;
    }
    // Inside the cone: (x·w)² ≥ cos²·|x|² with x·w > 0, which the planes
    // already hold; as a quadratic in t, q(t) = qa·t² + 2·qb·t + qc ≥ 0.
    let cos2 = 1.0 - sine * sine;
    let qa = dv * dv - cos2;
    let qb = dv * cv - cos2 * direction.dot(&co);
    let qc = cv * cv - cos2 * co.norm_squared();
    let mut enter = |from: f64, to: f64| {
        let (from, to) = (from.max(low), to.min(high));
        if from <= to {
            best = Some(best.map_or(from, |t| t.min(from)));
        }
    };
    if qa.abs() < 1e-15 {
        // One root: the ray runs parallel to a generator.
        if qb.abs() < 1e-300 {
            if qc >= 0.0 {
                enter(low, high);
            }
        } else {
            let root = -qc / (2.0 * qb);
            if qb > 0.0 {
                enter(root, f64::INFINITY);
            } else {
                enter(f64::NEG_INFINITY, root);
            }
        }
        return best;
    }
    let discriminant = qb * qb - qa * qc;
    if discriminant < 0.0 {
        if qa > 0.0 {
            enter(low, high);
        }
        return best;
    }
    let root = discriminant.sqrt();
    let (r0, r1) = {
        let (x, y) = ((-qb - root) / qa, (-qb + root) / qa);
        (x.min(y), x.max(y))
    };
    if qa < 0.0 {
        enter(r0, r1);
    } else {
        enter(f64::NEG_INFINITY, r0);
        enter(r1, f64::INFINITY);
    }
    best
}

/// Entry distance of a ray into a capsule: its cylinder, else its end balls.
pub fn ray_capsule(
    origin: &Vector3<f64>,
    direction: &Vector3<f64>,
    a: &Vector3<f64>,
    b: &Vector3<f64>,
    radius: f64,
) -> Option<f64> {
    let ba = b - a;
    let oa = origin - a;
    let baba = ba.norm_squared();
    let bard = ba.dot(direction);
    let baoa = ba.dot(&oa);
    let rdoa = direction.dot(&oa);
    let oaoa = oa.norm_squared();
    let qa = baba - bard * bard;
    let mut best: Option<f64> = None;
    let mut take = |t: Option<f64>| {
        if let Some(t) = t {
            best = Some(best.map_or(t, |b: f64| b.min(t)));
        }
    };
    if qa > 1e-12 * baba {
        let qb = baba * rdoa - baoa * bard;
        let qc = baba * oaoa - baoa * baoa - radius * radius * baba;
        let h = qb * qb - qa * qc;
        if h >= 0.0 {
            let t = (-qb - h.sqrt()) / qa;
            let y = baoa + t * bard;
            if t >= 0.0 && y > 0.0 && y < baba {
                return Some(t);
            }
        }
    }
    take(ray_ball(origin, direction, a, radius));
    take(ray_ball(origin, direction, b, radius));
    best
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    /// Central-difference gradient of a scalar function.
    fn numeric_gradient(f: impl Fn(&Vector3<f64>) -> f64, p: &Vector3<f64>) -> Vector3<f64> {
        let step = 1e-6;
        Vector3::from_fn(|k, _| {
            let mut plus = *p;
            let mut minus = *p;
            plus[k] += step;
            minus[k] -= step;
            (f(&plus) - f(&minus)) / (2.0 * step)
        })
    }

    fn check_gradient(f: impl Fn(&Vector3<f64>) -> Sample, p: Vector3<f64>) {
        let analytic = f(&p).gradient;
        let numeric = numeric_gradient(|q| f(q).value, &p);
        assert_relative_eq!(analytic, numeric, epsilon = 1e-6);
    }

    #[test]
    fn primitive_values() {
        let o = Vector3::zeros();
        assert_relative_eq!(ball(&Vector3::new(3.0, 4.0, 0.0), &o, 2.0).value, 3.0);
        let a = Vector3::new(0.0, 0.0, 0.0);
        let b = Vector3::new(0.0, 0.0, 10.0);
        assert_relative_eq!(
            capsule(&Vector3::new(3.0, 0.0, 5.0), &a, &b, 1.0).value,
            2.0
        );
        assert_relative_eq!(
            capsule(&Vector3::new(0.0, 0.0, 13.0), &a, &b, 1.0).value,
            2.0
        );
        assert_relative_eq!(
            cylinder(&Vector3::new(0.0, 2.0, 99.0), &o, &Vector3::z(), 0.5).value,
            1.5
        );
        let half = Vector3::new(2.0, 3.0, 4.0);
        assert_relative_eq!(
            rounded_box(&Vector3::new(0.0, 0.0, 5.0), &o, &half, 0.5).value,
            1.0
        );
        assert_relative_eq!(
            rounded_box(&Vector3::new(0.0, 0.0, 0.0), &o, &half, 0.5).value,
            -2.0
        );
        // Corner: distance to the rounding sphere centred at the inner
        // corner (1.5, 2.5, 3.5).
        let corner = rounded_box(&Vector3::new(3.0, 4.0, 5.0), &o, &half, 0.5);
        assert_relative_eq!(corner.value, 3f64.sqrt() * 1.5 - 0.5, epsilon = 1e-12);
    }

    #[test]
    fn gradients_match_finite_differences() {
        let c = Vector3::new(1.0, -2.0, 0.5);
        let a = Vector3::new(-3.0, 1.0, 2.0);
        let b = Vector3::new(4.0, 0.0, -1.0);
        let half = Vector3::new(5.0, 2.0, 3.0);
        for p in [
            Vector3::new(0.3, 0.7, -0.2),
            Vector3::new(6.0, 2.5, 1.0),
            Vector3::new(-4.0, -3.0, 5.0),
            Vector3::new(1.1, -1.9, 0.4),
        ] {
            check_gradient(|q| ball(q, &c, 2.0), p);
            check_gradient(|q| capsule(q, &a, &b, 1.5), p);
            check_gradient(|q| cylinder(q, &c, &Vector3::y(), 0.7), p);
            check_gradient(|q| rounded_box(q, &c, &half, 1.0), p);
            check_gradient(|q| round_cone(q, &a, 3.0, &b, 1.0), p);
            check_gradient(
                |q| smooth_min(ball(q, &c, 2.0), capsule(q, &a, &b, 1.5), 2.0),
                p,
            );
            check_gradient(
                |q| {
                    smooth_subtract(
                        rounded_box(q, &c, &half, 1.0),
                        cylinder(q, &c, &Vector3::x(), 1.0),
                        1.0,
                    )
                },
                p,
            );
        }
    }

    #[test]
    fn round_cone_values() {
        // Ball of 5 at the origin, ball of 1 at z = 8: flank at asin(0.5).
        let a = Vector3::zeros();
        let b = Vector3::new(0.0, 0.0, 8.0);
        let f = |p: Vector3<f64>| round_cone(&p, &a, 5.0, &b, 1.0).value;
        assert_relative_eq!(f(Vector3::new(0.0, 0.0, -7.0)), 2.0, epsilon = 1e-12);
        assert_relative_eq!(f(Vector3::new(0.0, 0.0, 11.0)), 2.0, epsilon = 1e-12);
        assert_relative_eq!(f(Vector3::new(0.0, 6.0, 0.0)), 1.0, epsilon = 1e-12);
        // The flank's tangent point on ball a lies at angle 30° past the
        // equator towards b; a point 1 mm out along its normal.
        let n = Vector3::new(0.0, 30f64.to_radians().cos(), 30f64.to_radians().sin());
        assert_relative_eq!(f(n * 6.0), 1.0, epsilon = 1e-12);
        // Halfway along the flank, 2 mm out.
        let tangent_a = n * 5.0;
        let tangent_b = b + n * 1.0;
        let mid = 0.5 * (tangent_a + tangent_b) + n * 2.0;
        assert_relative_eq!(f(mid), 2.0, epsilon = 1e-12);
    }

    #[test]
    fn smooth_min_is_min_away_from_the_crease_and_bounded_near_it() {
        let s = |value: f64| Sample {
            value,
            gradient: Vector3::x(),
        };
        assert_eq!(smooth_min(s(1.0), s(3.5), 2.0).value, 1.0);
        assert_relative_eq!(smooth_min(s(1.0), s(1.0), 2.0).value, 0.5);
        let blended = smooth_min(s(1.0), s(2.0), 2.0);
        assert!(blended.value < 1.0 && blended.value >= 0.5);
    }
}
