//! Visibility: one model for every command. For a scenario (camera and
//! pose) and a part, the fraction of each sphere's silhouette that is
//! hidden, by cause: the part's own supports, another sphere, or the image
//! border.
//!
//! **Method.** A sphere's silhouette is the cone of sight lines from the
//! camera centre that touch the ball. [`SILHOUETTE_RAYS`] lines spread
//! evenly over the disc it makes on a plane across the line of sight (a
//! sunflower pattern) are followed to the sphere: a line that first meets
//! another sphere is hidden by that sphere, one that first meets a support
//! ([`Occluder`]: capsules, round cones, the plate's box, intersected
//! exactly, and the fillets where struts meet a sphere, traced) is hidden
//! by the supports, and one whose point on the sphere projects outside the
//! image is outside. Parts that cannot reach the cone
//! (their bounding ball is off it, or no nearer than the sphere) are culled
//! first, so a scenario costs little when nothing is in the way.
//!
//! **Rule.** The scenario rules of [`crate::scenario::visibility`] (in front
//! of the camera, inside the image with a margin, no disc overlapping a
//! nearer sphere's) stand; a sphere whose support-hidden fraction exceeds
//! [`MaxHidden`] counts as not seen as well
//! ([`crate::scenario::Visibility::hidden_by_support`]).

pub mod occluders;
pub mod outline;

use crate::camera::Camera;
use crate::config::ConfigError;
use crate::layout::Layout;
use crate::pose::Pose;
use crate::scenario::{
    sphere_images, visibility, Range, Scenario, ScenarioError, ScenarioGrid, Visibility,
};
use nalgebra::{Vector2, Vector3};
pub use occluders::Occluder;
use serde::Serialize;
use std::str::FromStr;

/// Sight lines followed per sphere silhouette.
pub const SILHOUETTE_RAYS: usize = 400;
/// Default [`MaxHidden`]: 1 % of the silhouette.
pub const DEFAULT_MAX_HIDDEN: f64 = 0.01;
/// A support hit within this of a sphere's surface (mm) is the sphere's:
/// the cone under a sphere meets it tangentially, and within a printer's
/// and a mesh's tolerance the two are one outline.
pub const SURFACE_TOLERANCE_MM: f64 = 0.2;
/// The golden angle, radians: the sunflower pattern's turn per ray.
const GOLDEN_ANGLE: f64 = 2.399_963_229_728_653;

/// The largest fraction of a sphere's silhouette that the supports may hide
/// before the sphere counts as not seen, in 0…1.
///
/// ```
/// use layout_opt::visibility::MaxHidden;
/// assert_eq!("0.05".parse::<MaxHidden>()?.fraction(), 0.05);
/// assert!(MaxHidden::new(1.5).is_err());
/// # Ok::<(), layout_opt::config::ConfigError>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct MaxHidden(f64);

impl MaxHidden {
    /// Checks that `fraction` lies in 0…1.
    pub fn new(fraction: f64) -> Result<MaxHidden, ConfigError> {
        if fraction.is_finite() && (0.0..=1.0).contains(&fraction) {
            Ok(MaxHidden(fraction))
        } else {
            Err(ConfigError::new(
                "max_hidden",
                format!("must be a fraction from 0 to 1, got {fraction}"),
            ))
        }
    }

    /// The fraction.
    pub fn fraction(self) -> f64 {
        self.0
    }
}

impl Default for MaxHidden {
    fn default() -> Self {
        MaxHidden(DEFAULT_MAX_HIDDEN)
    }
}

impl FromStr for MaxHidden {
    type Err = ConfigError;
    fn from_str(text: &str) -> Result<MaxHidden, ConfigError> {
        let value: f64 = text.trim().parse().map_err(|_| {
            ConfigError::new(
                "max_hidden",
                format!("must be a fraction from 0 to 1, got \"{text}\""),
            )
        })?;
        MaxHidden::new(value)
    }
}

/// The fractions of one sphere's silhouette hidden by each cause.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct HiddenFractions {
    /// By the part's supports (pillars, struts, cones, plate).
    pub support: f64,
    /// By another sphere.
    pub sphere: f64,
    /// Outside the image.
    pub outside: f64,
}

/// The supports of one part, as analytic occluders in the marker frame.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Supports {
    occluders: Vec<Occluder>,
    bounds: Vec<(Vector3<f64>, f64)>,
    /// Per part, for a round cone: its first ball (centre, radius) and the
    /// cut-off plane it would have as that sphere's own cone
    /// (`own_cone_plane`), worked out once.
    own: Vec<Option<OwnCone>>,
}

/// A round cone's first ball and its plane as that sphere's own cone.
#[derive(Debug, Clone, Copy, PartialEq)]
struct OwnCone {
    centre: Vector3<f64>,
    radius: f64,
    u: Vector3<f64>,
    level: f64,
}

impl Supports {
    /// Supports made of these parts.
    pub fn new(occluders: Vec<Occluder>) -> Supports {
        let bounds = occluders.iter().map(Occluder::bounding_ball).collect();
        let own = occluders
            .iter()
            .map(|occluder| match occluder {
                Occluder::RoundCone { a, radius_a, .. } => own_cone_plane(occluder, a, *radius_a)
                    .map(|(u, level)| OwnCone {
                        centre: *a,
                        radius: *radius_a,
                        u,
                        level,
                    }),
                _ => None,
            })
            .collect();
        Supports {
            occluders,
            bounds,
            own,
        }
    }

    /// Part `p`'s plane as the own cone of the sphere (`centre`,
    /// `radius_mm`): `own_cone_plane`, looked up.
    fn own_plane(&self, p: usize, centre: &Vector3<f64>, radius_mm: f64) -> Plane {
        self.own[p]
            .filter(|own| {
                (own.centre - centre).norm_squared() <= 1e-18
                    && (own.radius - radius_mm).abs() <= 1e-9
            })
            .map(|own| (own.u, own.level))
    }

    /// These supports made for spheres at `from`, following the spheres
    /// to `to` (same order): every point that defines a part and lies
    /// within `reach_mm` of a sphere's old centre moves with the nearest
    /// such sphere (a point at the centre lands exactly on the new one, so
    /// that a sphere's own cone and fillet stay its own); the rest stay
    /// (the plate, the far ends of posts). For small moves this is the
    /// part the router would build again with the same routes.
    pub fn following(&self, from: &[Vector3<f64>], to: &[Vector3<f64>], reach_mm: f64) -> Supports {
        debug_assert_eq!(from.len(), to.len());
        let carry = |p: &Vector3<f64>| {
            let nearest = from
                .iter()
                .enumerate()
                .map(|(i, c)| (i, (p - c).norm()))
                .filter(|&(_, d)| d <= reach_mm)
                .min_by(|x, y| x.1.total_cmp(&y.1));
            match nearest {
                Some((i, d)) if d < 1e-12 => to[i],
                Some((i, _)) => p + (to[i] - from[i]),
                None => *p,
            }
        };
        Supports::new(
            self.occluders
                .iter()
                .map(|part| part.map_points(carry))
                .collect(),
        )
    }

    /// No supports: spheres alone.
    pub fn none() -> Supports {
        Supports::default()
    }

    /// The parts.
    pub fn occluders(&self) -> &[Occluder] {
        &self.occluders
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.occluders.is_empty()
    }
}

/// Per sphere, the fractions of its silhouette hidden by each cause under
/// `pose`, or `None` for a sphere not in front of the camera.
pub fn hidden_fractions(
    camera: &Camera,
    pose: &Pose,
    centres: &[Vector3<f64>],
    radius_mm: f64,
    supports: &Supports,
) -> Vec<Option<HiddenFractions>> {
    let eye = pose.camera_centre();
    (0..centres.len())
        .map(|k| {
            Trace {
                visible: false,
                ..Trace::new(camera, pose, &eye, centres, radius_mm, supports)
            }
            .sphere(k)
        })
        .collect()
}

/// Slack on the culling tests' cosines and tangents, which stand for
/// comparisons of angles: a part this close to the boundary is kept
/// (keeping a part that hides nothing changes no result).
const CULL_SLACK: f64 = 1e-9;

/// The cone of sight lines from the camera centre to one sphere: apex
/// `eye`, unit `axis` towards the sphere's centre, the sine and cosine of
/// its half-angle, and `front`, the distance from the eye to the
/// silhouette's rim (no sight line enters the ball further away).
#[derive(Debug, Clone, Copy)]
struct SightCone<'a> {
    eye: &'a Vector3<f64>,
    axis: Vector3<f64>,
    sin_half: f64,
    cos_half: f64,
    front: f64,
}

impl<'a> SightCone<'a> {
    /// The cone from `eye` to the ball (`centre`, `radius_mm`); `None`
    /// when the eye lies inside the ball.
    fn new(eye: &'a Vector3<f64>, centre: &Vector3<f64>, radius_mm: f64) -> Option<Self> {
        let to_centre = centre - eye;
        let distance = to_centre.norm();
        if distance <= radius_mm {
            return None;
        }
        let front = (distance * distance - radius_mm * radius_mm).sqrt();
        Some(SightCone {
            eye,
            axis: to_centre / distance,
            sin_half: radius_mm / distance,
            cos_half: front / distance,
            front,
        })
    }

    /// The tangent of the half-angle.
    fn tan_half(&self) -> f64 {
        self.sin_half / self.cos_half
    }
}

/// Whether the cone of sight lines `cone` can meet a ball (`other`,
/// `other_radius`) in front of the sphere's nearest silhouette point: the
/// angle between the cone's axis and the ball's direction is below the
/// half-angle plus asin(other_radius/distance) (both below a right
/// angle, so their cosines are compared instead).
fn may_cover(cone: &SightCone, other: &Vector3<f64>, other_radius: f64) -> bool {
    let to_other = other - cone.eye;
    // By squares first: most parts are rejected without a root.
    let distance_squared = to_other.norm_squared();
    if distance_squared <= other_radius * other_radius {
        return true;
    }
    let far = cone.front + other_radius;
    if distance_squared >= far * far {
        return false;
    }
    let distance = distance_squared.sqrt();
    let sin_ball = other_radius / distance;
    let cos_ball = (1.0 - sin_ball * sin_ball).max(0.0).sqrt();
    let cos_sum = cone.cos_half * cos_ball - cone.sin_half * sin_ball;
    to_other.dot(&cone.axis) / distance > cos_sum - CULL_SLACK
}

/// The supports that may hide part of the sphere (`centre`, `radius_mm`)
/// whose cone of sight lines from `eye` has `axis` and `half_angle`, and
/// whose silhouette rim lies `front` away, among `among` (all when
/// `None`): culled by bounding ball, a
/// capsule by its axis seen through the cone, and the sphere's own cone
/// (a round cone that starts with the sphere's ball) when the camera sees
/// none of the sphere on the cone's side of the circle where its flank
/// leaves the ball. Conservative: a part left out hides nothing.
///
/// The sphere's own cone is tested by `own_cone_may_cover` alone: it
/// holds the sphere's ball, so its bounding ball and capsule always meet
/// the cone of sight lines.
fn parts_in_cone(
    cone: &SightCone,
    centre: &Vector3<f64>,
    radius_mm: f64,
    supports: &Supports,
    among: Option<&[usize]>,
) -> Parts {
    let may_hide = |p: usize| {
        let occluder = &supports.occluders[p];
        if let Some((u, level)) = supports.own_plane(p, centre, radius_mm) {
            return own_cone_may_cover(cone.eye, centre, radius_mm, &u, level);
        }
        let (c, r) = supports.bounds[p];
        if !may_cover(cone, &c, r) {
            return false;
        }
        match occluder {
            Occluder::Capsule { a, b, radius } => capsule_may_cover(cone, a, b, *radius),
            // The hull of two balls lies in the capsule of the larger
            // radius between their centres.
            Occluder::RoundCone {
                a,
                radius_a,
                b,
                radius_b,
            } => capsule_may_cover(cone, a, b, radius_a.max(*radius_b)),
            // A fillet lies within its pieces grown by its reach.
            fillet @ Occluder::Fillet { pieces, .. } => {
                let reach = fillet.fillet_reach().unwrap_or(0.0);
                pieces
                    .iter()
                    .any(|(a, b, radius)| capsule_may_cover(cone, a, b, radius + reach))
            }
            Occluder::Box { .. } => true,
        }
    };
    match among {
        Some(among) => among.iter().copied().filter(|&p| may_hide(p)).collect(),
        None => (0..supports.occluders.len())
            .filter(|&p| may_hide(p))
            .collect(),
    }
}

/// The parts that may hide one sphere: few, so held on the stack.
type Parts = smallvec::SmallVec<[usize; 8]>;

/// A sphere's own cone's cut-off plane, as a unit axis and a level along
/// it (`own_cone_plane`), where it applies.
type Plane = Option<(Vector3<f64>, f64)>;

/// Whether the capsule `a`–`b` of `radius` can meet the cone of sight
/// lines (apex `eye`, `axis`, `half_angle`) nearer than `front`: its axis,
/// seen on the plane one unit along the cone's axis (where a straight line
/// stays straight and the cone is a disc), comes within the disc grown by
/// the capsule's largest angular radius (the half-angle plus
/// asin(radius/nearest), its tangent taken by the sum formula).
fn capsule_may_cover(cone: &SightCone, a: &Vector3<f64>, b: &Vector3<f64>, radius: f64) -> bool {
    let eye = cone.eye;
    let nearest = (eye - occluders::closest_on_segment(eye, a, b)).norm();
    if nearest <= radius {
        return true;
    }
    if nearest - radius >= cone.front {
        return false;
    }
    let Some(least) = axis_on_plane(eye, &cone.axis, a, b, radius) else {
        return true;
    };
    let tan_half = cone.tan_half();
    let tan_ball = radius / (nearest * nearest - radius * radius).sqrt();
    // tan(h + β) = (tan h + tan β)/(1 − tan h·tan β); at or past a right
    // angle when the denominator is not positive.
    let denominator = 1.0 - tan_half * tan_ball;
    denominator <= CULL_SLACK || least * denominator < (tan_half + tan_ball) * (1.0 + CULL_SLACK)
}

/// The least distance from the cone's axis of the segment `a`–`b` seen on
/// the plane one unit along `axis` from `eye` (where a straight line stays
/// straight): the tangent of the least angle between `axis` and a point of
/// the segment. `None` when an end lies within `radius` of the plane
/// through the eye, or behind it (no plane to see it on).
fn axis_on_plane(
    eye: &Vector3<f64>,
    axis: &Vector3<f64>,
    a: &Vector3<f64>,
    b: &Vector3<f64>,
    radius: f64,
) -> Option<f64> {
    nearest_on_plane(eye, axis, a, b, radius).map(|q| q.norm())
}

/// The point of `axis_on_plane`'s segment nearest the cone's axis, as an
/// offset across the axis on the plane one unit along it.
fn nearest_on_plane(
    eye: &Vector3<f64>,
    axis: &Vector3<f64>,
    a: &Vector3<f64>,
    b: &Vector3<f64>,
    radius: f64,
) -> Option<Vector3<f64>> {
    let (pa, pb) = (a - eye, b - eye);
    let (za, zb) = (pa.dot(axis), pb.dot(axis));
    if za <= radius || zb <= radius {
        return None;
    }
    let on_plane = |p: &Vector3<f64>, z: f64| (p - axis * z) / z;
    let (qa, qb) = (on_plane(&pa, za), on_plane(&pb, zb));
    let ab = qb - qa;
    let t = if ab.norm_squared() > 0.0 {
        (-qa.dot(&ab) / ab.norm_squared()).clamp(0.0, 1.0)
    } else {
        0.0
    };
    Some(qa + ab * t)
}

/// Whether a sphere's own cone (the round cone that starts with its ball
/// (`a`, `radius_a`), with unit axis `u` and cut-off `level` from
/// `own_cone_plane`) can hide any of the sphere from `eye`. What the cone
/// hides lies beyond the plane at `level` along `u`; the camera sees the
/// ball's cap within the angle acos(radius/distance) of its own
/// direction, and when that cap stays on the near side of the plane (and
/// the eye does), every sight line to it does too. The angles are
/// compared by their cosines: the farthest seen point of the ball along
/// `u` lies at the angle ψ − cap from it, ψ the angle between `u` and the
/// eye's direction.
fn own_cone_may_cover(
    eye: &Vector3<f64>,
    a: &Vector3<f64>,
    radius_a: f64,
    u: &Vector3<f64>,
    level: f64,
) -> bool {
    let w = eye - a;
    let distance = w.norm();
    if distance <= radius_a {
        return true;
    }
    let along = w.dot(u);
    if along > level {
        return true;
    }
    let cos_psi = (along / distance).clamp(-1.0, 1.0);
    let cos_cap = radius_a / distance;
    let reach = if cos_psi >= cos_cap {
        1.0
    } else {
        cos_psi * cos_cap + (1.0 - cos_psi * cos_psi).sqrt() * (1.0 - cos_cap * cos_cap).sqrt()
    };
    reach > level / radius_a - CULL_SLACK
}

/// For the round cone under the sphere (`centre`, `radius_mm`) (one that
/// starts with the sphere's own ball): the unit axis `u` from the sphere to
/// the cone's tip and the level along it before which the cone hides
/// nothing of the sphere (`own_cone_level`). `None` for any other part.
fn own_cone_plane(
    occluder: &Occluder,
    centre: &Vector3<f64>,
    radius_mm: f64,
) -> Option<(Vector3<f64>, f64)> {
    let Occluder::RoundCone {
        a,
        radius_a,
        b,
        radius_b,
    } = occluder
    else {
        return None;
    };
    let length = (b - a).norm();
    if (a - centre).norm() > 1e-9
        || (radius_a - radius_mm).abs() > 1e-9
        || length <= (radius_a - radius_b).abs()
    {
        return None;
    }
    Some((
        (b - a) / length,
        own_cone_level(*radius_a, length, *radius_b),
    ))
}

/// Margin taken off [`own_cone_level`]'s tolerance-based level, mm, for
/// the rounding of the hit points it is compared with.
const LEVEL_MARGIN_MM: f64 = 1e-6;

/// The level along a sphere's own cone's axis (from the sphere's centre,
/// the sphere's radius `radius`, the tip's ball `radius_b` at `length`)
/// below which every point of the cone lies within
/// [`SURFACE_TOLERANCE_MM`] of the sphere's ball, so that no hit there
/// counts as the supports'. Below the circle where the flank leaves the
/// ball (at `radius·sine` along the axis, sine = (radius − radius_b)/length)
/// the cone is the ball; past it the flank runs on at the cone's
/// half-angle, and its point at `s` along a generator from that circle
/// lies √(radius² + s²) − radius from the ball: within the tolerance up
/// to s₀ = √(τ·(2·radius + τ)), at the level radius·sine + s₀·cosine. When
/// the flank is shorter than s₀ (or the cone does not narrow), the level
/// is the circle's, or the tip ball's start (`length − radius_b`) if
/// lower.
fn own_cone_level(radius: f64, length: f64, radius_b: f64) -> f64 {
    let sine = (radius - radius_b) / length;
    let circle = (radius * sine).min(length - radius_b);
    if !(sine > 0.0 && sine < 1.0) {
        return circle;
    }
    let cosine = (1.0 - sine * sine).sqrt();
    let tolerated =
        (SURFACE_TOLERANCE_MM * (2.0 * radius + SURFACE_TOLERANCE_MM)).sqrt() - LEVEL_MARGIN_MM;
    if tolerated <= 0.0 || tolerated >= length * cosine {
        return circle;
    }
    circle.max(radius * sine + tolerated * cosine - LEVEL_MARGIN_MM)
}

/// Per sphere, the fraction of its silhouette that the supports hide under
/// `pose`, for a scenario in which every sphere is in front, inside the
/// image and clear of the others (the only scenarios in which the rule of
/// [`MaxHidden`] is asked): the same sight lines as [`hidden_fractions`],
/// but a sphere that no support can reach costs no sight line at all.
/// Equals `hidden_fractions(…)[k].support` in such a scenario.
pub fn support_fractions(
    camera: &Camera,
    pose: &Pose,
    centres: &[Vector3<f64>],
    radius_mm: f64,
    supports: &Supports,
) -> Vec<f64> {
    let eye = pose.camera_centre();
    let trace = Trace::new(camera, pose, &eye, centres, radius_mm, supports);
    (0..centres.len())
        .map(|k| {
            let centre = centres[k];
            let Some(cone) = SightCone::new(&eye, &centre, radius_mm) else {
                return 0.0;
            };
            if parts_in_cone(&cone, &centre, radius_mm, supports, None).is_empty() {
                return 0.0;
            }
            trace.sphere(k).map_or(0.0, |f| f.support)
        })
        .collect()
}

/// One scenario's sight lines: what [`Trace::sphere`] follows them with.
struct Trace<'a> {
    camera: &'a Camera,
    pose: &'a Pose,
    /// The camera centre in the marker frame.
    eye: &'a Vector3<f64>,
    centres: &'a [Vector3<f64>],
    radius_mm: f64,
    supports: &'a Supports,
    /// Whether the scenario is visible (every disc inside the image and
    /// clear of the nearer ones): no line is then outside or hidden by a
    /// sphere, and those checks are skipped.
    visible: bool,
    /// The only supports that may hide the sphere, if known.
    among: Option<&'a [usize]>,
    /// Stop following lines once more than this many are hidden by the
    /// supports (the fractions are then those of the lines followed).
    stop_above: usize,
}

impl<'a> Trace<'a> {
    /// A trace of a visible scenario that follows every line and may meet
    /// every part (fields changed by struct update where a caller knows
    /// more).
    fn new(
        camera: &'a Camera,
        pose: &'a Pose,
        eye: &'a Vector3<f64>,
        centres: &'a [Vector3<f64>],
        radius_mm: f64,
        supports: &'a Supports,
    ) -> Self {
        Trace {
            camera,
            pose,
            eye,
            centres,
            radius_mm,
            supports,
            visible: true,
            among: None,
            stop_above: usize::MAX,
        }
    }

    /// The fractions of sphere `k`'s silhouette hidden by each cause, or
    /// `None` for a sphere not in front of the camera.
    fn sphere(&self, k: usize) -> Option<HiddenFractions> {
        let Trace {
            camera,
            pose,
            eye,
            centres,
            radius_mm,
            supports,
            visible,
            among,
            stop_above,
        } = *self;
        let centre = centres[k];
        if pose.transform(&centre).z <= 0.0 {
            return None;
        }
        // Sight lines enter the ball no further than the silhouette's rim
        // (`SightCone::front`).
        let cone = SightCone::new(eye, &centre, radius_mm)?;
        // In a visible scenario no sphere hides another (see below).
        let spheres: Parts = if visible {
            Parts::new()
        } else {
            (0..centres.len())
                .filter(|&j| j != k && may_cover(&cone, &centres[j], radius_mm))
                .collect()
        };
        let parts = parts_in_cone(&cone, &centre, radius_mm, supports, among);
        if visible && parts.is_empty() {
            // Nothing can hide it: no sight line to follow.
            return Some(HiddenFractions::default());
        }
        // The sphere's own cone hides nothing of it before a plane across
        // the cone's axis (`own_cone_plane`): a sight line whose both ends,
        // the camera and its point on the sphere, lie before that plane
        // cannot meet the cone there, and is not traced.
        let planes: smallvec::SmallVec<[Plane; 8]> = parts
            .iter()
            .map(|&p| {
                supports
                    .own_plane(p, &centre, radius_mm)
                    .filter(|(u, level)| (eye - centre).dot(u) <= *level)
            })
            .collect();
        // The sphere's own fillet is grown by the mesh's error
        // ([`occluders::FILLET_MARGIN_MM`]): it is seen edge-on at the rim.
        let grow: smallvec::SmallVec<[f64; 8]> = parts
            .iter()
            .map(|&p| {
                if supports.occluders[p].is_fillet_of(&centre) {
                    occluders::FILLET_MARGIN_MM
                } else {
                    0.0
                }
            })
            .collect();
        let rays = SILHOUETTE_RAYS;
        // In a visible scenario only the supports can hide a line, and a
        // part can meet only the lines at least as far from the cone's axis
        // as its nearest point: the sunflower runs outwards, so the lines
        // inside the least such angle over the parts are not followed.
        let tangents: smallvec::SmallVec<[f64; 8]> = if visible {
            parts
                .iter()
                .zip(&planes)
                .map(|(&p, plane)| {
                    least_tangent(&cone, &centre, radius_mm, &supports.occluders[p], plane)
                })
                .collect()
        } else {
            smallvec::SmallVec::new()
        };
        let skip = if visible {
            inner_lines(tangents.iter().copied().fold(f64::INFINITY, f64::min) / cone.tan_half())
        } else {
            0
        };
        let basis = LineBasis::new(eye, &centre, radius_mm);
        // When only the decision is asked (`stop_above`), the lines next to
        // the part nearest the cone's axis are followed first: where that
        // part hides the sphere, the hidden lines are found at once. The
        // count of hidden lines does not depend on the order, and every
        // line is still followed unless the count is already over the
        // limit.
        let probe = if visible && stop_above < SILHOUETTE_RAYS {
            parts
                .iter()
                .zip(&planes)
                .zip(&tangents)
                .filter(|((_, plane), _)| plane.is_none())
                .min_by(|(_, x), (_, y)| x.total_cmp(y))
                .and_then(|((&p, _), _)| basis.azimuth_of(eye, &supports.occluders[p]))
        } else {
            None
        };
        let (mut by_support, mut by_sphere, mut outside) = (0usize, 0usize, 0usize);
        // Follows line `i`; true once the decision is known.
        let mut follow = |i: usize| {
            let direction = basis.line(i);
            let t_sphere = occluders::ray_ball(eye, &direction, &centre, radius_mm)
                .unwrap_or_else(|| (centre - eye).dot(&direction));
            let on_sphere = eye + direction * t_sphere;
            // In a visible scenario (`visible`) every disc lies inside the
            // image and clear of the nearer ones, so no sight line is outside
            // or hidden by a sphere; those checks are skipped.
            let in_image = visible
                || camera
                    .project(&pose.transform(&on_sphere))
                    .is_some_and(|px: Vector2<f64>| camera.contains(&px, 0.0));
            if !in_image {
                outside += 1;
            } else if !visible
                && spheres.iter().any(|&j| {
                    occluders::ray_ball(eye, &direction, &centres[j], radius_mm)
                        .is_some_and(|t| t < t_sphere)
                })
            {
                by_sphere += 1;
            } else if parts
                .iter()
                .zip(&planes)
                .enumerate()
                .any(|(i, (&p, plane))| {
                    if plane.is_some_and(|(u, level)| (on_sphere - centre).dot(&u) <= level) {
                        return false;
                    }
                    supports.occluders[p]
                        .ray_hit_grown(eye, &direction, t_sphere - SURFACE_TOLERANCE_MM, grow[i])
                        .is_some_and(|t| {
                            // A hit on a sphere's surface (the round cone under a
                            // sphere starts with the sphere's own ball) is the
                            // sphere's, not a support's.
                            let hit = eye + direction * t;
                            t < t_sphere - SURFACE_TOLERANCE_MM
                                && centres
                                    .iter()
                                    .all(|c| (hit - c).norm() > radius_mm + SURFACE_TOLERANCE_MM)
                        })
                })
            {
                by_support += 1;
            }
            by_support > stop_above
        };
        let mut followed = [0u64; SILHOUETTE_RAYS.div_ceil(64)];
        let mut known = false;
        if let Some(azimuth) = probe {
            let budget = (4 * (stop_above + 1) + 8).min(SILHOUETTE_RAYS);
            for i in by_azimuth_from(azimuth).filter(|&i| i >= skip).take(budget) {
                followed[i / 64] |= 1 << (i % 64);
                if follow(i) {
                    known = true;
                    break;
                }
            }
        }
        if !known {
            for i in skip..SILHOUETTE_RAYS {
                if followed[i / 64] & (1 << (i % 64)) == 0 && follow(i) {
                    break;
                }
            }
        }
        let share = |n: usize| n as f64 / rays as f64;
        Some(HiddenFractions {
            support: share(by_support),
            sphere: share(by_sphere),
            outside: share(outside),
        })
    }
}

/// How many of the [`SILHOUETTE_RAYS`] sunflower lines lie strictly
/// within `fraction` of the disc's radius (the pattern runs outwards: line
/// i at √((i + ½)/N)), less one for rounding.
fn inner_lines(fraction: f64) -> usize {
    if fraction.is_nan() || fraction <= 0.0 {
        return 0;
    }
    let n = SILHOUETTE_RAYS as f64;
    ((n * fraction.min(1.0).powi(2) - 1.5).floor().max(0.0) as usize).min(SILHOUETTE_RAYS)
}

/// A lower bound on the tangent of the angle, seen from `eye`, between
/// `axis` (towards the sphere at `centre`) and any point of `part` that
/// can hide some of the sphere; 0 where no bound is known. For the
/// sphere's own cone with its cut-off plane (`plane`, as in
/// [`Trace::sphere`]): only lines that meet the ball beyond the plane are
/// followed, and the ball's cap beyond it lies at least ψ − acos(level/r)
/// from the direction to the eye (ψ the angle between that direction and
/// the plane's normal), which the eye sees at least atan(r·sin γ /
/// (d − r·cos γ)) off its axis. For a capsule (and a round cone or a
/// fillet by the capsule that holds it): the least angle of its axis, less
/// the angle its radius subtends at its nearest point.
fn least_tangent(
    cone: &SightCone,
    centre: &Vector3<f64>,
    radius_mm: f64,
    part: &Occluder,
    plane: &Option<(Vector3<f64>, f64)>,
) -> f64 {
    let (eye, axis) = (cone.eye, &cone.axis);
    if let Some((u, level)) = plane {
        let to_eye = eye - centre;
        let distance = to_eye.norm();
        let psi = (to_eye.dot(u) / distance).clamp(-1.0, 1.0).acos();
        let gamma = psi - (level / radius_mm).clamp(-1.0, 1.0).acos();
        if gamma <= 0.0 {
            return 0.0;
        }
        let silhouette = (radius_mm / distance).clamp(-1.0, 1.0).acos();
        let gamma = gamma.min(silhouette);
        return radius_mm * gamma.sin() / (distance - radius_mm * gamma.cos());
    }
    let capsule_angle = |a: &Vector3<f64>, b: &Vector3<f64>, radius: f64| {
        let nearest = (eye - occluders::closest_on_segment(eye, a, b)).norm();
        match axis_on_plane(eye, axis, a, b, radius) {
            Some(least) if nearest > radius => (least.atan() - (radius / nearest).asin()).max(0.0),
            _ => 0.0,
        }
    };
    let angle = match part {
        Occluder::Capsule { a, b, radius } => capsule_angle(a, b, *radius),
        Occluder::RoundCone {
            a,
            radius_a,
            b,
            radius_b,
        } => capsule_angle(a, b, radius_a.max(*radius_b)),
        fillet @ Occluder::Fillet { pieces, .. } => {
            let reach = fillet.fillet_reach().unwrap_or(0.0);
            pieces
                .iter()
                .map(|(a, b, radius)| capsule_angle(a, b, radius + reach))
                .fold(f64::INFINITY, f64::min)
        }
        Occluder::Box { .. } => 0.0,
    };
    if angle >= std::f64::consts::FRAC_PI_2 {
        f64::INFINITY
    } else {
        angle.tan()
    }
}

/// The [`SILHOUETTE_RAYS`] unit directions from `eye` that the model
/// follows to the sphere (`centre`, `radius_mm`): a sunflower pattern,
/// even over the disc the silhouette cone cuts from a plane across the
/// line of sight.
pub fn silhouette_directions(
    eye: &Vector3<f64>,
    centre: &Vector3<f64>,
    radius_mm: f64,
) -> impl ExactSizeIterator<Item = Vector3<f64>> {
    lines_from(eye, centre, radius_mm, 0)
}

/// [`silhouette_directions`] from line `first` on (the pattern runs
/// outwards), the lines before it not computed.
fn lines_from(
    eye: &Vector3<f64>,
    centre: &Vector3<f64>,
    radius_mm: f64,
    first: usize,
) -> impl ExactSizeIterator<Item = Vector3<f64>> {
    let basis = LineBasis::new(eye, centre, radius_mm);
    (first.min(SILHOUETTE_RAYS)..SILHOUETTE_RAYS).map(move |i| basis.line(i))
}

/// The frame in which the sunflower lines to one sphere are laid out:
/// the unit `axis` from the eye to the sphere's centre, two unit
/// directions across it, and the tangent of the silhouette's half-angle.
#[derive(Debug, Clone, Copy)]
struct LineBasis {
    axis: Vector3<f64>,
    e1: Vector3<f64>,
    e2: Vector3<f64>,
    tan_half: f64,
}

impl LineBasis {
    fn new(eye: &Vector3<f64>, centre: &Vector3<f64>, radius_mm: f64) -> LineBasis {
        let to_centre = centre - eye;
        let distance = to_centre.norm();
        let axis = to_centre / distance;
        let tan_half = (radius_mm / distance).clamp(-1.0, 1.0).asin().tan();
        let (e1, e2) = crate::linalg::perpendicular_pair(&axis);
        LineBasis {
            axis,
            e1,
            e2,
            tan_half,
        }
    }

    /// The unit direction of sunflower line `i`.
    fn line(&self, i: usize) -> Vector3<f64> {
        let (x, y) = sunflower()[i];
        (self.axis + (self.e1 * x + self.e2 * y) * self.tan_half).normalize()
    }

    /// The azimuth, on the disc of the lines, of the point of `part`'s
    /// axis nearest the cone's axis as seen from `eye`; `None` for a part
    /// without one axis (a box, a fillet) or one not wholly in front.
    fn azimuth_of(&self, eye: &Vector3<f64>, part: &Occluder) -> Option<f64> {
        let (a, b, radius) = match part {
            Occluder::Capsule { a, b, radius } => (a, b, *radius),
            Occluder::RoundCone {
                a,
                radius_a,
                b,
                radius_b,
            } => (a, b, radius_a.max(*radius_b)),
            _ => return None,
        };
        let q = nearest_on_plane(eye, &self.axis, a, b, radius)?;
        Some(q.dot(&self.e2).atan2(q.dot(&self.e1)))
    }
}

/// The sunflower's line numbers ordered by their azimuth on the disc
/// (from −π), with those azimuths, computed once.
fn by_azimuth() -> &'static [(f64, usize)] {
    static ORDER: std::sync::OnceLock<Vec<(f64, usize)>> = std::sync::OnceLock::new();
    ORDER.get_or_init(|| {
        let mut order: Vec<(f64, usize)> = sunflower()
            .iter()
            .enumerate()
            .map(|(i, &(x, y))| (y.atan2(x), i))
            .collect();
        order.sort_by(|p, q| p.0.total_cmp(&q.0));
        order
    })
}

/// Every sunflower line number once, nearest in azimuth to `azimuth`
/// first: the lines from it onwards and back, taken in turn.
fn by_azimuth_from(azimuth: f64) -> impl Iterator<Item = usize> {
    let order = by_azimuth();
    let n = order.len();
    let start = order.partition_point(|&(a, _)| a < azimuth) % n;
    (0..n).map(move |m| {
        let j = if m % 2 == 0 {
            (start + m / 2) % n
        } else {
            (start + n - 1 - m / 2) % n
        };
        order[j].1
    })
}

/// The [`SILHOUETTE_RAYS`] points of the sunflower pattern on the unit
/// disc, computed once.
fn sunflower() -> &'static [(f64, f64)] {
    static POINTS: std::sync::OnceLock<Vec<(f64, f64)>> = std::sync::OnceLock::new();
    POINTS.get_or_init(|| {
        (0..SILHOUETTE_RAYS)
            .map(|i| {
                let spread = ((i as f64 + 0.5) / SILHOUETTE_RAYS as f64).sqrt();
                let turn = i as f64 * GOLDEN_ANGLE;
                (spread * turn.cos(), spread * turn.sin())
            })
            .collect()
    })
}

/// [`crate::scenario::visibility`] with the supports counted: a sphere that
/// is otherwise seen, but whose support-hidden fraction exceeds
/// `max_hidden`, is listed in [`Visibility::hidden_by_support`].
pub fn visibility_with_supports(
    camera: &Camera,
    pose: &Pose,
    centres: &[Vector3<f64>],
    sphere_diameter_mm: f64,
    supports: &Supports,
    max_hidden: MaxHidden,
) -> Visibility {
    let images = sphere_images(camera, pose, centres, sphere_diameter_mm);
    let mut result = visibility(&images, camera);
    if supports.is_empty() || !result.is_visible() {
        return result;
    }
    let fractions = support_fractions(camera, pose, centres, 0.5 * sphere_diameter_mm, supports);
    for (k, f) in fractions.iter().enumerate() {
        if *f > max_hidden.fraction() {
            result.hidden_by_support.push(k);
        }
    }
    result
}

/// The camera centres of a set of scenarios, in the marker frame, held as
/// a cone of directions from the frame's origin: what a candidate's
/// supports are screened against once, before any scenario
/// ([`EyeCone::screen`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EyeCone {
    /// Mean direction to the eyes.
    axis: Vector3<f64>,
    /// Largest angle between it and the direction to an eye, radians.
    half_angle: f64,
    /// Nearest and farthest eye from the origin, mm.
    nearest_mm: f64,
    farthest_mm: f64,
}

impl EyeCone {
    /// The cone of the camera centres of `scenarios`; `None` for none.
    pub fn of(scenarios: &[Scenario]) -> Option<EyeCone> {
        let eyes: Vec<Vector3<f64>> = scenarios.iter().map(|s| s.pose().camera_centre()).collect();
        let nearest_mm = eyes.iter().map(|e| e.norm()).fold(f64::INFINITY, f64::min);
        let farthest_mm = eyes.iter().map(|e| e.norm()).fold(0.0, f64::max);
        if eyes.is_empty() || nearest_mm <= 0.0 {
            return None;
        }
        let sum: Vector3<f64> = eyes.iter().map(|e| e / e.norm()).sum();
        let (axis, half_angle) = if sum.norm() < 1e-9 * eyes.len() as f64 {
            (Vector3::z(), std::f64::consts::PI)
        } else {
            let axis = sum.normalize();
            let widest = eyes
                .iter()
                .map(|e| (e.dot(&axis) / e.norm()).clamp(-1.0, 1.0).acos())
                .fold(0.0, f64::max);
            (axis, widest)
        };
        Some(EyeCone {
            axis,
            half_angle,
            nearest_mm,
            farthest_mm,
        })
    }

    /// Per sphere (`centres`, `radius_mm`), the supports that may hide
    /// some of it from some eye of the cone; conservative: a part left out
    /// hides nothing of that sphere from any of them. A part may hide a
    /// sphere only where a point of it lies within the sphere's sight-line
    /// cone from an eye: seen from the sphere's centre, within the angle
    /// asin(r/(distance − part radius)) + asin(part radius/distance) of the
    /// direction to that eye (for a part nearer than the sphere), and
    /// every such direction lies within the cone's half-angle plus the
    /// parallax of the centre (asin(|centre|/nearest eye)) of its axis.
    /// The sphere's own cone may hide it only where an eye sees the
    /// sphere beyond the circle its flank leaves from.
    pub fn screen(
        &self,
        centres: &[Vector3<f64>],
        radius_mm: f64,
        supports: &Supports,
    ) -> Vec<Vec<usize>> {
        centres
            .iter()
            .map(|centre| {
                let parallax = (centre.norm() / self.nearest_mm).min(1.0).asin();
                let spread = self.half_angle + parallax;
                (0..supports.occluders.len())
                    .filter(|&p| self.may_hide(centre, radius_mm, spread, &supports.occluders[p]))
                    .collect()
            })
            .collect()
    }

    fn may_hide(
        &self,
        centre: &Vector3<f64>,
        radius_mm: f64,
        spread: f64,
        occluder: &Occluder,
    ) -> bool {
        if spread >= std::f64::consts::PI {
            return true;
        }
        let (a, b, radius) = match occluder {
            Occluder::Capsule { a, b, radius } => (*a, *b, *radius),
            Occluder::RoundCone {
                a,
                radius_a,
                b,
                radius_b,
            } => {
                if let Some((u, level)) = own_cone_plane(occluder, centre, radius_mm) {
                    return self.own_cone_may_hide(a, *radius_a, &u, level, spread);
                }
                (*a, *b, radius_a.max(*radius_b))
            }
            other => {
                let (c, r) = other.bounding_ball();
                (c, c, r + other.fillet_reach().unwrap_or(0.0))
            }
        };
        let (from_a, along) = (a - centre, b - a);
        let nearest = (centre - occluders::closest_on_segment(centre, &a, &b)).norm();
        let reach = radius_mm + radius;
        if nearest <= reach {
            return true;
        }
        // The least angle between the cone's axis and a point of the
        // segment seen from the centre: at an end or where d(cos)/dt = 0.
        let cosine = |t: f64| {
            let v = from_a + along * t;
            v.dot(&self.axis) / v.norm()
        };
        let (alpha0, alpha1) = (from_a.dot(&self.axis), along.dot(&self.axis));
        let (p00, p01, p11) = (
            from_a.norm_squared(),
            from_a.dot(&along),
            along.norm_squared(),
        );
        let denominator = alpha1 * p01 - alpha0 * p11;
        let mut best = cosine(0.0).max(cosine(1.0));
        if denominator.abs() > 1e-12 {
            let t = (alpha0 * p01 - alpha1 * p00) / denominator;
            if (0.0..=1.0).contains(&t) {
                best = best.max(cosine(t));
            }
        }
        // A point of the part within `radius` of the axis point q lies
        // within asin(radius/|q|) of q's direction and no nearer than
        // |q| − radius; the line through it to the ball, within
        // asin(radius_mm/(|q| − radius)) of the eye's.
        let least = best.clamp(-1.0, 1.0).acos();
        least
            <= spread
                + (radius_mm / (nearest - radius)).min(1.0).asin()
                + (radius / nearest).min(1.0).asin()
    }

    /// Whether an eye of the cone may see the sphere (`a`, `radius_a`)
    /// beyond its own cone's plane (unit axis `u`, `level`, as from
    /// `own_cone_plane`), as in `own_cone_may_cover` with the eye's
    /// direction anywhere within `spread` of the axis.
    fn own_cone_may_hide(
        &self,
        a: &Vector3<f64>,
        radius_a: f64,
        u: &Vector3<f64>,
        level: f64,
        spread: f64,
    ) -> bool {
        if self.nearest_mm - a.norm() <= radius_a {
            return true;
        }
        let sine = level / radius_a;
        let psi = (self.axis.dot(u).clamp(-1.0, 1.0).acos() - spread).max(0.0);
        // The seen cap is widest from the farthest eye.
        let cap = (radius_a / (self.farthest_mm + a.norm())).min(1.0).acos();
        let reach = if psi - cap <= 0.0 {
            1.0
        } else {
            (psi - cap).cos()
        };
        reach > sine - 1e-12 || psi < std::f64::consts::FRAC_PI_2
    }
}

/// The spheres whose support-hidden fraction exceeds `max_hidden` under
/// `pose`, in a scenario in which every sphere is in front, inside the
/// image and clear of the others: the decision of
/// [`visibility_with_supports`], with each sphere's supports taken from
/// `screen` ([`EyeCone::screen`] for a cone that holds this scenario's
/// eye) and its sight lines followed only until the decision is known.
/// Lazy, in layout order: a caller that asks only whether any sphere is
/// hidden (`.next()`) traces no sphere after the first hidden one.
pub fn spheres_hidden_by_supports<'a>(
    camera: &'a Camera,
    pose: &'a Pose,
    centres: &'a [Vector3<f64>],
    radius_mm: f64,
    supports: &'a Supports,
    screen: &'a [Vec<usize>],
    max_hidden: MaxHidden,
) -> impl Iterator<Item = usize> + 'a {
    let eye = pose.camera_centre();
    let stop_above = (max_hidden.fraction() * SILHOUETTE_RAYS as f64).floor() as usize;
    (0..centres.len()).filter(move |&k| {
        if screen[k].is_empty() {
            return false;
        }
        let trace = Trace {
            among: Some(&screen[k]),
            stop_above,
            ..Trace::new(camera, pose, &eye, centres, radius_mm, supports)
        };
        trace
            .sphere(k)
            .is_some_and(|f| f.support > max_hidden.fraction())
    })
}

/// The views of a working range that the spheres alone leave usable: the
/// camera centre, in the marker frame, of every scenario in which every
/// sphere is in front, inside the image and clear of the others.
/// Supports are routed so as to hide no sphere from these.
pub fn clear_views(
    camera: &Camera,
    scenarios: &[Scenario],
    centres: &[Vector3<f64>],
    sphere_diameter_mm: f64,
) -> Vec<Vector3<f64>> {
    scenarios
        .iter()
        .filter_map(|s| {
            let pose = s.pose();
            let images = sphere_images(camera, &pose, centres, sphere_diameter_mm);
            visibility(&images, camera)
                .is_visible()
                .then(|| pose.camera_centre())
        })
        .collect()
}

/// The axes of a working range as a user gives them; each missing one is
/// taken from the search's grid recorded in a layout's provenance
/// (`provenance.range`: each axis's values by name), else 0.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RangeAxes {
    /// Depths, mm.
    pub depth: Option<Range>,
    /// X offsets, mm.
    pub offset_x: Option<Range>,
    /// Y offsets, mm.
    pub offset_y: Option<Range>,
    /// Tilts about X, degrees.
    pub tilt: Option<Range>,
    /// Pans about Y, degrees.
    pub pan: Option<Range>,
}

impl RangeAxes {
    /// The grid of these axes for `layout` (σ 0.5 px, no roll), or `None`
    /// when neither a depth is given nor the layout records one.
    pub fn grid_for(&self, layout: &Layout) -> Result<Option<ScenarioGrid>, ScenarioError> {
        let searched = |axis: &str| -> Option<Range> {
            let values = layout.provenance.as_ref()?.get("range")?.get(axis)?;
            let values: Vec<f64> = serde_json::from_value(values.clone()).ok()?;
            (!values.is_empty()).then(|| Range::list(&values))
        };
        let Some(depth) = self.depth.clone().or_else(|| searched("depth")) else {
            return Ok(None);
        };
        let axis = |given: &Option<Range>, name: &str| {
            given
                .clone()
                .or_else(|| searched(name))
                .unwrap_or(Range::single(0.0))
        };
        Ok(Some(ScenarioGrid::new(
            depth,
            axis(&self.offset_x, "offset-x"),
            axis(&self.offset_y, "offset-y"),
            axis(&self.tilt, "tilt"),
            axis(&self.pan, "pan"),
            Range::single(0.0),
            Range::single(0.5),
        )?))
    }

    /// The working range of [`RangeAxes::grid_for`] seen by the paper
    /// camera, a sphere hidden more than `max_hidden` counting as not
    /// seen: the range `export` routes a part's supports for; `None` as
    /// for the grid.
    pub fn working_range(
        &self,
        layout: &Layout,
        max_hidden: MaxHidden,
    ) -> Result<Option<WorkingRange>, ScenarioError> {
        Ok(self.grid_for(layout)?.map(|grid| WorkingRange {
            camera: crate::camera::Camera::paper(),
            scenarios: grid.scenarios(),
            max_hidden,
        }))
    }
}

/// The working range a part is designed for: the camera, the scenarios
/// (as `validate`'s grid flags give them) and the largest hidden fraction
/// that still counts as seen.
#[derive(Debug, Clone, PartialEq)]
pub struct WorkingRange {
    /// The camera.
    pub camera: Camera,
    /// The scenarios.
    pub scenarios: Vec<Scenario>,
    /// The largest support-hidden fraction that counts as seen.
    pub max_hidden: MaxHidden,
}

impl WorkingRange {
    /// [`clear_views`] of this range for the spheres at `centres`.
    pub fn clear_views(
        &self,
        centres: &[Vector3<f64>],
        sphere_diameter_mm: f64,
    ) -> Vec<Vector3<f64>> {
        clear_views(&self.camera, &self.scenarios, centres, sphere_diameter_mm)
    }

    /// [`lost_views`] of this range for the spheres at `centres` held by
    /// `supports`.
    pub fn lost_views(
        &self,
        centres: &[Vector3<f64>],
        sphere_diameter_mm: f64,
        supports: &Supports,
    ) -> Vec<LostView> {
        lost_views(
            &self.camera,
            &self.scenarios,
            centres,
            sphere_diameter_mm,
            supports,
            self.max_hidden,
        )
    }
}

/// A view of the working range in which the supports hide a sphere.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LostView {
    /// The scenario.
    pub scenario: Scenario,
    /// The sphere hidden (index into the layout's points).
    pub sphere: usize,
    /// Its fraction hidden by the supports.
    pub hidden_fraction: f64,
}

/// Every scenario of `scenarios` that the spheres alone leave visible but
/// in which the supports hide more than `max_hidden` of a sphere: the views
/// the part loses to its supports.
pub fn lost_views(
    camera: &Camera,
    scenarios: &[Scenario],
    centres: &[Vector3<f64>],
    sphere_diameter_mm: f64,
    supports: &Supports,
    max_hidden: MaxHidden,
) -> Vec<LostView> {
    let mut lost = Vec::new();
    for scenario in scenarios {
        let pose = scenario.pose();
        let images = sphere_images(camera, &pose, centres, sphere_diameter_mm);
        if !visibility(&images, camera).is_visible() {
            continue;
        }
        let fractions =
            support_fractions(camera, &pose, centres, 0.5 * sphere_diameter_mm, supports);
        for (sphere, &f) in fractions.iter().enumerate() {
            if f > max_hidden.fraction() {
                lost.push(LostView {
                    scenario: *scenario,
                    sphere,
                    hidden_fraction: f,
                });
            }
        }
    }
    lost
}

/// What each cause costs over a set of scenarios, each scenario counted
/// once, under the first rule it breaks in the order behind the camera,
/// outside the image, a sphere behind another, a sphere behind the
/// supports.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct CauseCounts {
    /// Scenarios.
    pub scenarios: usize,
    /// Some sphere behind the camera.
    pub behind: usize,
    /// Some sphere's disc leaves the image.
    pub outside: usize,
    /// Some disc overlaps a nearer sphere's.
    pub occluded: usize,
    /// Otherwise seen, but the supports hide more than the allowed
    /// fraction of some sphere.
    pub hidden_by_support: usize,
    /// Seen with the supports counted.
    pub visible: usize,
}

impl CauseCounts {
    /// Visible when the supports are not counted.
    pub fn visible_without_supports(&self) -> usize {
        self.visible + self.hidden_by_support
    }
}

/// [`CauseCounts`] of `scenarios` for the spheres at `centres` held by
/// `supports` (in parallel; the counts do not depend on the thread count).
pub fn count_causes(
    camera: &Camera,
    scenarios: &[Scenario],
    centres: &[Vector3<f64>],
    sphere_diameter_mm: f64,
    supports: &Supports,
    max_hidden: MaxHidden,
) -> CauseCounts {
    use rayon::prelude::*;
    let classes: Vec<usize> = scenarios
        .par_iter()
        .map(|s| {
            let v = visibility_with_supports(
                camera,
                &s.pose(),
                centres,
                sphere_diameter_mm,
                supports,
                max_hidden,
            );
            if !v.behind.is_empty() {
                0
            } else if !v.outside.is_empty() {
                1
            } else if !v.occluded.is_empty() {
                2
            } else if !v.hidden_by_support.is_empty() {
                3
            } else {
                4
            }
        })
        .collect();
    let count = |class: usize| classes.iter().filter(|&&c| c == class).count();
    CauseCounts {
        scenarios: scenarios.len(),
        behind: count(0),
        outside: count(1),
        occluded: count(2),
        hidden_by_support: count(3),
        visible: count(4),
    }
}

#[cfg(test)]
mod tests;
