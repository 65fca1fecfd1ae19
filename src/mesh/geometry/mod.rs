//! The printable marker as a solid: a sphere at each feature point, struts
//! that carry every sphere to a hub, and a mounting stub ending in a base
//! plate, optionally with screw holes. The solid is the zero sublevel set of
//! one analytic signed-distance function ([`Marker::sample`]); sphere
//! centres are exactly the layout's coordinates.
//!
//! **Routing.** The main viewing direction `view` (default `+z`: the base
//! attitude of docs/formats.md, "Conventions", puts the camera on the
//! marker's −z side, looking along +z) decides where the struts go, so that
//! in the main (orthographic) view no strut covers another sphere:
//! 1. Each sphere gets a *post* running straight back along `view`, which in
//!    the main view hides behind the sphere itself (struts are thinner than
//!    spheres). When a post would pass within the clearance of a sphere
//!    further back, the sphere is instead *linked* to the centre of a sphere
//!    behind it — the nearest whose disc overlaps its own in the main view,
//!    else the nearest at all — whose own strut carries it on. Links are
//!    chosen from the back to the front, so that each keeps clear of the
//!    other spheres and meets the struts already at its target at an open
//!    angle.
//! 2. The posts end on a *back plane* behind every sphere. There *back
//!    struts* join each post foot to the hub (the foot nearest the centroid
//!    of the feet): a shortest-path tree grown one foot at a time, whose
//!    struts keep clear of the feet they do not join and meet at open
//!    angles. Everything in the back plane lies behind every sphere.
//! 3. A *stub* of twice the strut diameter runs from the foot furthest along
//!    the mount axis (or from the hub, when the mount axis is `view`) out
//!    beyond all other parts to a rounded *base plate* perpendicular to the
//!    mount axis, with optional clearance holes for screws. The plate's
//!    outer face is flat: it goes on the print bed.
//!
//! **Blending.** Where parts meet (a sphere and its struts, a foot and its
//! struts, the stub and the plate: a *junction*), the pieces of the struts
//! near the junction are joined with a quadratic smooth minimum of radius
//! [`Marker::blend_mm`], which puts a fillet in every joint; whole struts and
//! junctions are then combined with the exact minimum, so blending acts only
//! near junctions and gaps between parts that do not meet keep their width.
//! Junctions joined by a strut too short for two fillets are merged into one.
//!
//! **Checks.** Struts at least `min_feature` thick and thinner than the
//! spheres by twice that; spheres at least `min_feature` apart; every pair
//! of parts that do not join, and every junction's fillets (grown by
//! [`junction_growth`]) and parts that do not join it, at least
//! `min_feature` apart; struts leaving a sphere parted by `min_feature` at
//! its surface. Bad input is a [`GeometryError`], never a silently altered
//! part.
//!
//! **Files.** `options` (how to build), `parts` (spheres, struts, plate),
//! `solid` (the design and its signed distance), `checks` (clearances and
//! printability), `router` (where the supports run) and `frames` (the
//! print and glTF frames).

use super::sdf::{self, Sample};
use crate::layout::{Layout, LayoutError};
use crate::visibility::occluders::{ball_covers_sphere, Occluder};
use nalgebra::{Matrix3, Vector3};
use serde::Serialize;
use std::fmt;
use std::str::FromStr;

/// Default strut diameter, mm.
pub const DEFAULT_STRUT_DIAMETER_MM: f64 = 3.0;
/// Default smallest printable feature (strut, wall, gap), mm.
pub const DEFAULT_MIN_FEATURE_MM: f64 = 1.0;
/// The stub is this many times as thick as the struts.
pub const STUB_DIAMETER_FACTOR: f64 = 2.0;
/// Length of the stub when the mount axis is the viewing direction, mm.
pub const STUB_LENGTH_MM: f64 = 10.0;
/// Thickness of the base plate, mm, at least (it is made thicker than the
/// stub's radius plus twice the minimum feature, so that the stub's round
/// end stays inside it).
pub const PLATE_THICKNESS_MM: f64 = 4.0;
/// Smallest side of the square base plate, mm.
pub const PLATE_MIN_SIDE_MM: f64 = 24.0;
/// Radius of the base plate's rounded edges, mm.
pub const PLATE_ROUNDING_MM: f64 = 1.5;
/// Half-angle of the cone under each sphere of a printable part, between
/// its flank and the vertical, degrees: the flank then faces down at
/// 90° minus this from the vertical, within [`MAX_OVERHANG_DEG`].
pub const TEARDROP_HALF_ANGLE_DEG: f64 = 40.0;
/// Steepest overhang a printer makes without support, from the vertical,
/// degrees.
pub const MAX_OVERHANG_DEG: f64 = 45.0;
/// Slants from the vertical that a support may take, degrees, in order of
/// preference (each at most [`MAX_OVERHANG_DEG`] less a margin).
pub const SUPPORT_SLANTS_DEG: &[f64] = &[0.0, 10.0, 20.0, 30.0, 35.0];
/// Directions around the vertical tried for a slanted support.
pub const SUPPORT_AZIMUTHS: usize = 16;
/// Default half-angle of the cone of viewing directions around the main
/// view over which no strut may cover a sphere, degrees.
pub const DEFAULT_VIEW_CONE_DEG: f64 = 20.0;
/// Default build volume of the printer (x, y, z), mm.
pub const DEFAULT_BED_MM: [f64; 3] = [250.0, 210.0, 210.0];
/// Spacing of the points of a support tested against the view cone, mm.
const SUPPORT_SAMPLE_MM: f64 = 0.5;
/// Edge rounding of the base plate of a printable part, mm: its rim on the
/// bed overhangs by more than 45° only in the lowest 1 − cos 45° of it
/// (0.29 mm, within the first layer,
/// [`super::quality::FIRST_LAYER_MM`]).
pub const PILLAR_PLATE_ROUNDING_MM: f64 = 1.0;
/// Smallest angle between two struts that meet at a foot, degrees.
pub const MIN_JUNCTION_ANGLE_DEG: f64 = 40.0;
/// Floor on sin(θ/2) of the angle θ between two struts at a junction when
/// computing how far its fillets reach (θ ≈ 1°).
const MIN_HALF_ANGLE_SINE: f64 = 0.01;

/// Why a marker cannot be built from this layout with these options.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum GeometryError {
    /// The layout itself is invalid.
    #[error(transparent)]
    Layout(#[from] LayoutError),
    /// An option is not a positive finite number.
    #[error("{option} must be positive and finite, got {value}")]
    BadOption {
        /// The option's name.
        option: &'static str,
        /// The value given.
        value: f64,
    },
    /// The struts are thinner than the printer can make.
    #[error("strut diameter {strut_diameter_mm} mm is too thin to print: below the minimum feature size {min_feature_mm} mm (--min-feature)")]
    StrutTooThin {
        /// Strut diameter, mm.
        strut_diameter_mm: f64,
        /// Smallest printable feature, mm.
        min_feature_mm: f64,
    },
    /// The struts are too thick to hide behind the spheres.
    #[error("strut diameter {strut_diameter_mm} mm is too thick for {sphere_diameter_mm} mm spheres: it must be below the sphere diameter minus twice the minimum feature size ({max_mm} mm)")]
    StrutTooThick {
        /// Strut diameter, mm.
        strut_diameter_mm: f64,
        /// Sphere diameter, mm.
        sphere_diameter_mm: f64,
        /// Largest strut diameter allowed, mm.
        max_mm: f64,
    },
    /// Two spheres are closer than the printer can keep apart.
    #[error("spheres {first} and {second} are {gap_mm:.3} mm apart, below the minimum feature size {min_feature_mm} mm (--min-feature); they would fuse when printed")]
    SpheresTooClose {
        /// First sphere.
        first: String,
        /// Second sphere.
        second: String,
        /// Gap between the sphere surfaces, mm.
        gap_mm: f64,
        /// Smallest printable feature, mm.
        min_feature_mm: f64,
    },
    /// The mount axis points at the camera.
    #[error("the mount axis {mount} points at the camera (the view is along {view}); choose another --mount")]
    MountTowardsCamera {
        /// Mount axis.
        mount: Axis,
        /// Viewing direction.
        view: Axis,
    },
    /// The struts cannot be routed with the required clearances.
    #[error(
        "cannot route the strut from {from}: {reason}; try another --view or move the spheres"
    )]
    RoutingFailed {
        /// The part that could not be joined.
        from: String,
        /// Why.
        reason: String,
    },
    /// Two parts that do not join come closer than the minimum feature.
    #[error("{first} and {second} pass {gap_mm:.3} mm apart, below the minimum feature size {min_feature_mm} mm; try another --view or move the spheres")]
    Clearance {
        /// First part.
        first: String,
        /// Second part.
        second: String,
        /// Gap between their surfaces, mm.
        gap_mm: f64,
        /// Smallest printable feature, mm.
        min_feature_mm: f64,
    },
    /// Two struts meet at a sphere at so narrow an angle that they would
    /// leave a slit too thin to print.
    #[error("struts {first} and {second} meet at sphere {sphere} at {angle_deg:.1} degrees, leaving a gap below {min_feature_mm} mm outside the sphere")]
    NarrowJunction {
        /// Sphere where they meet.
        sphere: String,
        /// First strut.
        first: String,
        /// Second strut.
        second: String,
        /// Angle between them, degrees.
        angle_deg: f64,
        /// Smallest printable feature, mm.
        min_feature_mm: f64,
    },
    /// Unknown screw size or hole count.
    #[error("unknown mount holes \"{0}\": expected a metric screw M2, M2.5, M3, M4, M5, M6 or M8, optionally with a count x2 or x4 (e.g. M3, M4x4)")]
    BadMountHoles(String),
    /// Unknown axis name.
    #[error("unknown axis \"{0}\": expected one of +x, -x, +y, -y, +z, -z")]
    BadAxis(String),
    /// Unknown structure name.
    #[error("unknown structure \"{0}\": expected pillars or routed")]
    BadStructure(String),
    /// The part is larger than the printer's build volume.
    #[error("the part ({:.1} × {:.1} × {:.1} mm, print frame) does not fit the build volume {} × {} × {} mm (--bed); scale the layout down or give the printer's build volume", size_mm[0], size_mm[1], size_mm[2], bed_mm[0], bed_mm[1], bed_mm[2])]
    DoesNotFitBed {
        /// Part extents in the print frame (x, y, z), mm.
        size_mm: [f64; 3],
        /// Build volume, mm.
        bed_mm: [f64; 3],
    },
    /// The number to engrave is not digits, or finds no room.
    #[error("cannot engrave \"{0}\" into the base plate: the engraving takes digits 0-9 and needs room on the plate")]
    BadEngraving(String),
    /// The bed size is not three positive numbers.
    #[error("--bed must be three positive sizes X,Y,Z in mm (e.g. 250,210,210), got \"{0}\"")]
    BadBed(String),
}

mod checks;
mod engraving;
mod frames;
mod options;
mod parts;
mod router;
mod solid;

pub use engraving::{stroke_width_mm, Engraving, ENGRAVING_DEPTH_MM, PLACEMENT_STEP_MM};
pub use frames::{gltf_rotation, print_rotation};
pub use options::{Axis, Bed, MarkerOptions, MountHoles, Structure};
pub use parts::{Foot, Hole, Node, Plate, SphereFeature, Strut, StrutKind};
use router::Router;
pub use router::{marker_for_range, routed_as_recorded, straight_supports, supports_for_range};
pub use solid::Marker;

/// The main view `view` and rings of directions around it out to
/// `half_angle_rad`: `rings` rings at equal steps of angle, the outermost
/// with `azimuths` directions and the inner ones with proportionally fewer
/// (at least four).
pub fn view_cone_directions(
    view: &Vector3<f64>,
    half_angle_rad: f64,
    rings: usize,
    azimuths: usize,
) -> Vec<Vector3<f64>> {
    let mut directions = vec![*view];
    if half_angle_rad <= 0.0 || rings == 0 {
        return directions;
    }
    let k = view.iamax();
    let unit = |k: usize| Vector3::from_fn(|r, _| if r == k { 1.0 } else { 0.0 });
    let (e1, e2) = (unit((k + 1) % 3), unit((k + 2) % 3));
    for ring in 1..=rings {
        let polar = half_angle_rad * ring as f64 / rings as f64;
        let n = (azimuths * ring / rings).max(4);
        for a in 0..n {
            let phi = std::f64::consts::TAU * a as f64 / n as f64;
            directions.push(view * polar.cos() + (e1 * phi.cos() + e2 * phi.sin()) * polar.sin());
        }
    }
    directions
}

/// The fillet radius at junctions: the strut diameter, and at least the
/// minimum feature size.
pub fn blend_radius(strut_radius_mm: f64, min_feature_mm: f64) -> f64 {
    (2.0 * strut_radius_mm).max(min_feature_mm)
}

/// How far fillets can swell a junction beyond its parts: the quadratic
/// smooth minimum of three equal members lies 0.39 blend radii below them
/// (k/4 for the first two, then k/4·(3/4)² for the third), and near a
/// junction's surface at most three of its parts are close together.
pub fn junction_growth(blend_mm: f64) -> f64 {
    let first = 0.25 * blend_mm;
    let second = 0.25 * blend_mm * (1.0 - first / blend_mm).powi(2);
    first + second
}

/// Shortest distance between the segments `p0`–`p1` and `q0`–`q1`
/// (Ericson, Real-Time Collision Detection, §5.1.9).
pub fn segment_distance(
    p0: &Vector3<f64>,
    p1: &Vector3<f64>,
    q0: &Vector3<f64>,
    q1: &Vector3<f64>,
) -> f64 {
    let d1 = p1 - p0;
    let d2 = q1 - q0;
    let r = p0 - q0;
    let a = d1.norm_squared();
    let e = d2.norm_squared();
    let f = d2.dot(&r);
    let tiny = 1e-18;
    let (s, t) = if a <= tiny && e <= tiny {
        (0.0, 0.0)
    } else if a <= tiny {
        (0.0, (f / e).clamp(0.0, 1.0))
    } else {
        let c = d1.dot(&r);
        if e <= tiny {
            ((-c / a).clamp(0.0, 1.0), 0.0)
        } else {
            let b = d1.dot(&d2);
            let denom = a * e - b * b;
            let mut s = if denom > tiny * a * e {
                ((b * f - c * e) / denom).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let mut t = (b * s + f) / e;
            if t < 0.0 {
                t = 0.0;
                s = (-c / a).clamp(0.0, 1.0);
            } else if t > 1.0 {
                t = 1.0;
                s = ((b - c) / a).clamp(0.0, 1.0);
            }
            (s, t)
        }
    };
    ((p0 + d1 * s) - (q0 + d2 * t)).norm()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn axes_parse_and_print() {
        assert_eq!("-y".parse::<Axis>().unwrap(), Axis::NEG_Y);
        assert_eq!("Z".parse::<Axis>().unwrap(), Axis::POS_Z);
        assert_eq!(Axis::NEG_X.to_string(), "-x");
        assert_eq!(
            "up".parse::<Axis>().unwrap_err().to_string(),
            "unknown axis \"up\": expected one of +x, -x, +y, -y, +z, -z"
        );
    }

    #[test]
    fn mount_holes_parse() {
        let holes: MountHoles = "m3".parse().unwrap();
        assert_eq!(
            (holes.screw.as_str(), holes.diameter_mm, holes.count),
            ("M3", 3.4, 2)
        );
        let holes: MountHoles = "M4x4".parse().unwrap();
        assert_eq!((holes.diameter_mm, holes.count), (4.5, 4));
        assert!("M7".parse::<MountHoles>().is_err());
        assert!("M3x3".parse::<MountHoles>().is_err());
    }

    #[test]
    fn print_and_gltf_frames() {
        // Mount −y: print (x, −z, y); glTF identity.
        let r = print_rotation(Axis::NEG_Y);
        assert_eq!(
            r * Vector3::new(1.0, 2.0, 3.0),
            Vector3::new(1.0, -3.0, 2.0)
        );
        assert_eq!(gltf_rotation(Axis::NEG_Y), Matrix3::identity());
        for mount in [
            Axis::POS_X,
            Axis::NEG_X,
            Axis::POS_Y,
            Axis::NEG_Y,
            Axis::POS_Z,
            Axis::NEG_Z,
        ] {
            let r = print_rotation(mount);
            assert!((r.determinant() - 1.0).abs() < 1e-12);
            assert_eq!(r * mount.vector(), -Vector3::z(), "mount points down");
            assert_eq!(gltf_rotation(mount) * mount.vector(), -Vector3::y());
        }
    }

    #[test]
    fn segment_distances() {
        let o = Vector3::zeros();
        let x = Vector3::new(10.0, 0.0, 0.0);
        let a = Vector3::new(5.0, 3.0, -1.0);
        let b = Vector3::new(5.0, 3.0, 1.0);
        assert!((segment_distance(&o, &x, &a, &b) - 3.0).abs() < 1e-12);
        let c = Vector3::new(12.0, 0.0, 0.0);
        let d = Vector3::new(20.0, 0.0, 0.0);
        assert!((segment_distance(&o, &x, &c, &d) - 2.0).abs() < 1e-12);
        assert!((segment_distance(&o, &x, &o, &x)).abs() < 1e-12);
    }

    #[test]
    fn paper_biprism_routing() {
        let routed = MarkerOptions {
            structure: Structure::Routed,
            ..MarkerOptions::default()
        };
        let marker = Marker::design(&Layout::paper_biprism(), &routed).unwrap();
        let names: Vec<String> = (0..marker.struts.len())
            .map(|s| marker.strut_name(s))
            .collect();
        // P3 (front) hangs from O0, O0 from P1; the rest have posts.
        assert!(names.contains(&"link P3-O0".to_string()), "{names:?}");
        assert!(names.contains(&"link O0-P1".to_string()), "{names:?}");
        assert_eq!(marker.feet.len(), 5);
        assert_eq!(marker.spheres[marker.feet[marker.hub].sphere].name, "P1");
        // On the +x side of every sphere, away from its struts, the surface
        // is exactly the sphere.
        for s in &marker.spheres {
            let p = s.centre + Vector3::new(s.radius, 0.0, 0.0);
            assert_eq!(marker.signed_distance(&p), 0.0, "{}", s.name);
        }
    }

    #[test]
    fn paper_biprism_pillars() {
        let marker = Marker::design(&Layout::paper_biprism(), &MarkerOptions::default()).unwrap();
        assert_eq!(marker.down, Axis::POS_Z);
        // Every support leaves its sphere's cone tip at most 35° from the
        // view, and the plate lies behind every sphere.
        for strut in &marker.struts {
            let d = (strut.b - strut.a).normalize();
            assert!(d.z >= 35f64.to_radians().cos() - 1e-12, "{strut:?}");
        }
        let level = marker.bed_level.unwrap();
        for s in &marker.spheres {
            assert!(s.centre.z + s.radius < level - PLATE_THICKNESS_MM);
        }
        assert!("pillars".parse::<Structure>().unwrap() == Structure::Pillars);
        assert_eq!(
            "tree".parse::<Structure>().unwrap_err().to_string(),
            "unknown structure \"tree\": expected pillars or routed"
        );
        assert_eq!(
            "200,200,180".parse::<Bed>().unwrap().0,
            [200.0, 200.0, 180.0]
        );
        assert!("200,200".parse::<Bed>().is_err());
        assert!("200,-1,180".parse::<Bed>().is_err());
    }

    #[test]
    fn fillet_occluders_hold_the_swell_at_the_spheres() {
        use crate::visibility::Occluder;
        let marker = Marker::design(&Layout::paper_biprism(), &MarkerOptions::default()).unwrap();
        let occluders = marker.occluders();
        let (fillets, parts): (Vec<&Occluder>, Vec<&Occluder>) = occluders
            .iter()
            .partition(|o| matches!(o, Occluder::Fillet { .. }));
        assert!(!fillets.is_empty());
        // Points of the solid within a sphere's diameter of its centre that
        // no sphere, strut, cone or plate holds lie in the fillet where its
        // support leaves it; every one must be inside a fillet occluder.
        let mut swell = 0;
        for s in &marker.spheres {
            let step = 0.25;
            for i in -48..=48 {
                for j in -48..=48 {
                    for k in 0..=48 {
                        let p = s.centre + Vector3::new(i as f64, j as f64, k as f64) * step;
                        if (p - s.centre).norm() > 2.0 * s.radius
                            || marker.signed_distance(&p) > 0.0
                            || marker
                                .spheres
                                .iter()
                                .any(|o| (p - o.centre).norm() <= o.radius)
                            || parts.iter().any(|o| o.distance(&p) == 0.0)
                        {
                            continue;
                        }
                        swell += 1;
                        assert!(
                            fillets.iter().any(|f| f.distance(&p) == 0.0),
                            "{} {p:?}",
                            s.name
                        );
                    }
                }
            }
        }
        assert!(swell > 100, "{swell}");
    }

    #[test]
    fn error_messages() {
        let layout = Layout::paper_biprism();
        let options = |f: &dyn Fn(&mut MarkerOptions)| {
            let mut o = MarkerOptions::default();
            f(&mut o);
            o
        };
        let e = Marker::design(&layout, &options(&|o| o.strut_diameter_mm = 0.8)).unwrap_err();
        assert_eq!(e.to_string(), "strut diameter 0.8 mm is too thin to print: below the minimum feature size 1 mm (--min-feature)");
        let e = Marker::design(&layout, &options(&|o| o.strut_diameter_mm = 8.0)).unwrap_err();
        assert_eq!(e.to_string(), "strut diameter 8 mm is too thick for 10 mm spheres: it must be below the sphere diameter minus twice the minimum feature size (8 mm)");
        let e = Marker::design(&layout, &options(&|o| o.mount = Axis::NEG_Z)).unwrap_err();
        assert_eq!(
            e.to_string(),
            "the mount axis -z points at the camera (the view is along +z); choose another --mount"
        );
        let e = Marker::design(&layout, &options(&|o| o.min_feature_mm = f64::NAN)).unwrap_err();
        assert_eq!(
            e.to_string(),
            "--min-feature must be positive and finite, got NaN"
        );
        let mut close = layout.clone();
        close.points[2].position.x = 10.5;
        let e = Marker::design(&close, &MarkerOptions::default()).unwrap_err();
        assert_eq!(e.to_string(), "spheres O0 and P2 are 0.500 mm apart, below the minimum feature size 1 mm (--min-feature); they would fuse when printed");
        let mut overlapping = layout.clone();
        overlapping.points[2].position.x = 9.0;
        let e = Marker::design(&overlapping, &MarkerOptions::default()).unwrap_err();
        assert!(
            e.to_string().starts_with("spheres O0 and P2 overlap"),
            "{e}"
        );
    }
}
