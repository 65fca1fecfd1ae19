//! Analytic signed distances with gradients: the primitives a marker is made
//! of (balls, capsules, a rounded box with through-holes) and the blends
//! that join them.
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
