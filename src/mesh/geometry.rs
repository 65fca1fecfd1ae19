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

use super::sdf::{self, Sample};
use crate::layout::{Layout, LayoutError};
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
    /// The bed size is not three positive numbers.
    #[error("--bed must be three positive sizes X,Y,Z in mm (e.g. 250,210,210), got \"{0}\"")]
    BadBed(String),
}

/// How the spheres are held.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Structure {
    /// Printable without support material: a base plate behind every
    /// sphere (on the bed), a support rising from it to each sphere, every
    /// support at most [`MAX_OVERHANG_DEG`] less a margin from the vertical,
    /// a cone under each sphere; the camera sees every sphere in front of
    /// its own support.
    Pillars,
    /// The earlier structure: posts to a back plane, back struts to a hub,
    /// a stub along the mount axis to a small plate. Needs support material
    /// to print.
    Routed,
}

impl Structure {
    /// Its CLI name.
    pub fn name(self) -> &'static str {
        match self {
            Structure::Pillars => "pillars",
            Structure::Routed => "routed",
        }
    }
}

impl fmt::Display for Structure {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Structure {
    type Err = GeometryError;
    fn from_str(text: &str) -> Result<Structure, GeometryError> {
        match text.trim().to_ascii_lowercase().as_str() {
            "pillars" => Ok(Structure::Pillars),
            "routed" => Ok(Structure::Routed),
            _ => Err(GeometryError::BadStructure(text.to_string())),
        }
    }
}

/// A printer's build volume (x, y, z), mm.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Bed(pub [f64; 3]);

impl Default for Bed {
    fn default() -> Self {
        Bed(DEFAULT_BED_MM)
    }
}

impl FromStr for Bed {
    type Err = GeometryError;
    /// `X,Y,Z` in mm.
    fn from_str(text: &str) -> Result<Bed, GeometryError> {
        let bad = || GeometryError::BadBed(text.to_string());
        let values: Vec<f64> = text
            .split(',')
            .map(|v| v.trim().parse::<f64>().map_err(|_| bad()))
            .collect::<Result<_, _>>()?;
        match values[..] {
            [x, y, z] if [x, y, z].iter().all(|v| v.is_finite() && *v > 0.0) => Ok(Bed([x, y, z])),
            _ => Err(bad()),
        }
    }
}

/// One of the six signed object axes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Axis {
    /// 0, 1, 2 for x, y, z.
    index: usize,
    /// Whether it points along the positive axis.
    positive: bool,
}

impl Axis {
    /// `+x`.
    pub const POS_X: Axis = Axis::new(0, true);
    /// `-x`.
    pub const NEG_X: Axis = Axis::new(0, false);
    /// `+y`.
    pub const POS_Y: Axis = Axis::new(1, true);
    /// `-y`.
    pub const NEG_Y: Axis = Axis::new(1, false);
    /// `+z`.
    pub const POS_Z: Axis = Axis::new(2, true);
    /// `-z`.
    pub const NEG_Z: Axis = Axis::new(2, false);

    const fn new(index: usize, positive: bool) -> Axis {
        Axis { index, positive }
    }

    /// The unit vector.
    pub fn vector(self) -> Vector3<f64> {
        let mut v = Vector3::zeros();
        v[self.index] = if self.positive { 1.0 } else { -1.0 };
        v
    }

    /// The opposite axis.
    pub fn opposite(self) -> Axis {
        Axis::new(self.index, !self.positive)
    }
}

impl fmt::Display for Axis {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let sign = if self.positive { '+' } else { '-' };
        write!(f, "{sign}{}", ['x', 'y', 'z'][self.index])
    }
}

impl FromStr for Axis {
    type Err = GeometryError;
    fn from_str(text: &str) -> Result<Axis, GeometryError> {
        let lower = text.trim().to_ascii_lowercase();
        let (positive, letter) = match lower.as_bytes() {
            [b'+', letter] | [letter] => (true, *letter),
            [b'-', letter] => (false, *letter),
            _ => return Err(GeometryError::BadAxis(text.to_string())),
        };
        let index = match letter {
            b'x' => 0,
            b'y' => 1,
            b'z' => 2,
            _ => return Err(GeometryError::BadAxis(text.to_string())),
        };
        Ok(Axis::new(index, positive))
    }
}

impl Serialize for Axis {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_str(self)
    }
}

/// Clearance holes through the base plate for metric screws.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MountHoles {
    /// The screw, e.g. "M3".
    pub screw: String,
    /// Clearance hole diameter (ISO 273, medium series), mm.
    pub diameter_mm: f64,
    /// Number of holes: 2 (across the plate) or 4 (at the corners).
    pub count: usize,
}

/// ISO 273 medium-series clearance holes: (screw, hole diameter mm).
const CLEARANCE_HOLES: &[(&str, f64)] = &[
    ("M2", 2.4),
    ("M2.5", 2.9),
    ("M3", 3.4),
    ("M4", 4.5),
    ("M5", 5.5),
    ("M6", 6.6),
    ("M8", 9.0),
];

impl FromStr for MountHoles {
    type Err = GeometryError;
    /// `M3` (two holes) or `M3x4` (four holes).
    fn from_str(text: &str) -> Result<MountHoles, GeometryError> {
        let bad = || GeometryError::BadMountHoles(text.to_string());
        let upper = text.trim().to_ascii_uppercase();
        let (screw, count) = match upper.split_once('X') {
            Some((screw, count)) => (screw, count.parse::<usize>().map_err(|_| bad())?),
            None => (upper.as_str(), 2),
        };
        if count != 2 && count != 4 {
            return Err(bad());
        }
        let &(name, diameter_mm) = CLEARANCE_HOLES
            .iter()
            .find(|(name, _)| *name == screw)
            .ok_or_else(bad)?;
        Ok(MountHoles {
            screw: name.to_string(),
            diameter_mm,
            count,
        })
    }
}

/// How to build the marker.
#[derive(Debug, Clone, PartialEq)]
pub struct MarkerOptions {
    /// Strut diameter, mm.
    pub strut_diameter_mm: f64,
    /// Smallest printable feature: struts, gaps and clearances, mm.
    pub min_feature_mm: f64,
    /// Main viewing direction (the camera looks along it).
    pub view: Axis,
    /// Mount axis: the stub and base plate lie this way; it points down on
    /// the print bed.
    pub mount: Axis,
    /// Optional screw holes through the base plate.
    pub mount_holes: Option<MountHoles>,
    /// How the spheres are held.
    pub structure: Structure,
    /// Half-angle of the cone of viewing directions around `view` over
    /// which supports are chosen not to cover spheres, degrees.
    pub view_cone_deg: f64,
    /// The printer's build volume; a part that does not fit is an error.
    pub bed: Bed,
}

impl Default for MarkerOptions {
    fn default() -> Self {
        MarkerOptions {
            strut_diameter_mm: DEFAULT_STRUT_DIAMETER_MM,
            min_feature_mm: DEFAULT_MIN_FEATURE_MM,
            view: Axis::POS_Z,
            mount: Axis::NEG_Y,
            mount_holes: None,
            structure: Structure::Pillars,
            view_cone_deg: DEFAULT_VIEW_CONE_DEG,
            bed: Bed::default(),
        }
    }
}

/// A sphere marking one feature point.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SphereFeature {
    /// The feature's name.
    pub name: String,
    /// Centre: exactly the layout's position, mm.
    pub centre: Vector3<f64>,
    /// Radius, mm.
    pub radius: f64,
}

/// What a strut does.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum StrutKind {
    /// From a sphere straight back along the view to the back plane.
    Post,
    /// From a sphere to the centre of a sphere behind it.
    Link,
    /// In the back plane, between post feet.
    Back,
    /// From a foot to the base plate.
    Stub,
}

/// A junction of the structure.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Node {
    /// A sphere's centre (index into [`Marker::spheres`]).
    Sphere(usize),
    /// A post foot on the back plane (index into [`Marker::feet`]).
    Foot(usize),
    /// The base plate.
    Plate,
}

/// A strut: a capsule (cylinder with round ends) between two nodes.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Strut {
    /// What it does.
    pub kind: StrutKind,
    /// Where it starts and ends.
    pub ends: [Node; 2],
    /// Start of its axis, mm.
    pub a: Vector3<f64>,
    /// End of its axis, mm.
    pub b: Vector3<f64>,
    /// Radius, mm.
    pub radius: f64,
}

/// A through-hole in the base plate.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Hole {
    /// A point on its axis (in the plate's mid-plane), mm.
    pub centre: Vector3<f64>,
    /// Its axis (the mount axis).
    pub axis: Vector3<f64>,
    /// Radius, mm.
    pub radius: f64,
}

/// The base plate: an axis-aligned box with rounded edges, perpendicular to
/// the mount axis.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Plate {
    /// Centre, mm.
    pub centre: Vector3<f64>,
    /// Half extents along x, y, z, mm.
    pub half_extents: Vector3<f64>,
    /// Edge rounding radius, mm.
    pub rounding: f64,
    /// Screw holes.
    pub holes: Vec<Hole>,
}

/// A foot: where a post meets the back plane.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Foot {
    /// Position, mm.
    pub position: Vector3<f64>,
    /// The sphere whose post ends here.
    pub sphere: usize,
}

/// The designed marker: every primitive, how they join, and the signed
/// distance of their blended union.
#[derive(Debug, Clone, Serialize)]
pub struct Marker {
    /// The layout's name.
    pub name: String,
    /// One sphere per feature point, in layout order.
    pub spheres: Vec<SphereFeature>,
    /// Post feet on the back plane.
    pub feet: Vec<Foot>,
    /// The foot that serves as hub.
    pub hub: usize,
    /// Every strut.
    pub struts: Vec<Strut>,
    /// The base plate.
    pub plate: Plate,
    /// Screw holes asked for.
    pub mount_holes: Option<MountHoles>,
    /// Fillet (smooth-union) radius at junctions, mm.
    pub blend_mm: f64,
    /// Radius of the rounding of the holes' rims, mm.
    pub rim_blend_mm: f64,
    /// Smallest printable feature, mm.
    pub min_feature_mm: f64,
    /// Main viewing direction.
    pub view: Axis,
    /// Mount axis.
    pub mount: Axis,
    /// How the spheres are held.
    pub structure: Structure,
    /// The axis that points down onto the print bed: the mount axis for
    /// [`Structure::Routed`], the view for [`Structure::Pillars`] (the base
    /// plate lies behind the spheres).
    pub down: Axis,
    /// For [`Structure::Pillars`], the cone under each sphere: (tip,
    /// tip radius), the tip on the sphere's vertical axis below it.
    pub teardrops: Vec<Option<(Vector3<f64>, f64)>>,
    /// For [`Structure::Pillars`], the bed plane: the solid is cut flat at
    /// `p · down = level`.
    pub bed_level: Option<f64>,
    /// Half-angle of the view cone the supports were chosen for, degrees.
    pub view_cone_deg: f64,
    /// The junctions, each a smooth union of the parts that meet there.
    junctions: Vec<Junction>,
}

/// A junction: the nodes it joins (several when a strut between them is
/// too short for two separate fillets), the balls of its spheres, the
/// pieces of its struts near it, and whether it holds the plate. Its value
/// is the smooth union of those members.
#[derive(Debug, Clone, Serialize)]
struct Junction {
    spheres: Vec<usize>,
    /// Strut pieces (axis start, axis end, radius).
    pieces: Vec<(Vector3<f64>, Vector3<f64>, f64)>,
    plate: bool,
    /// Bounding ball of the members, for culling.
    centre: Vector3<f64>,
    radius: f64,
}

/// Grows an axis-aligned box to bounding-ball form.
fn bounding_ball(boxes: impl Iterator<Item = (Vector3<f64>, f64)>) -> (Vector3<f64>, f64) {
    let mut lo = Vector3::repeat(f64::INFINITY);
    let mut hi = Vector3::repeat(f64::NEG_INFINITY);
    for (p, r) in boxes {
        lo = lo.inf(&(p - Vector3::repeat(r)));
        hi = hi.sup(&(p + Vector3::repeat(r)));
    }
    (0.5 * (lo + hi), 0.5 * (hi - lo).norm())
}

impl Marker {
    /// Designs the marker for `layout`: validates the layout and the
    /// options, routes the struts, and checks every clearance.
    pub fn design(layout: &Layout, options: &MarkerOptions) -> Result<Marker, GeometryError> {
        layout.validate()?;
        for (option, value) in [
            ("--strut-diameter", options.strut_diameter_mm),
            ("--min-feature", options.min_feature_mm),
        ] {
            if !(value.is_finite() && value > 0.0) {
                return Err(GeometryError::BadOption { option, value });
            }
        }
        if !(options.view_cone_deg.is_finite() && (0.0..80.0).contains(&options.view_cone_deg)) {
            return Err(GeometryError::BadOption {
                option: "--view-cone (degrees, 0 to below 80)",
                value: options.view_cone_deg,
            });
        }
        let min_feature = options.min_feature_mm;
        if options.strut_diameter_mm < min_feature {
            return Err(GeometryError::StrutTooThin {
                strut_diameter_mm: options.strut_diameter_mm,
                min_feature_mm: min_feature,
            });
        }
        let radius = layout.sphere_radius_mm();
        let strut_radius = 0.5 * options.strut_diameter_mm;
        let max_strut_mm = layout.sphere_diameter_mm - 2.0 * min_feature;
        if options.strut_diameter_mm >= max_strut_mm {
            return Err(GeometryError::StrutTooThick {
                strut_diameter_mm: options.strut_diameter_mm,
                sphere_diameter_mm: layout.sphere_diameter_mm,
                max_mm: max_strut_mm,
            });
        }
        if options.mount == options.view.opposite() {
            return Err(GeometryError::MountTowardsCamera {
                mount: options.mount,
                view: options.view,
            });
        }
        let spheres: Vec<SphereFeature> = layout
            .points
            .iter()
            .map(|p| SphereFeature {
                name: p.name.clone(),
                centre: p.position,
                radius,
            })
            .collect();
        for (i, a) in spheres.iter().enumerate() {
            for b in &spheres[i + 1..] {
                let gap_mm = (a.centre - b.centre).norm() - 2.0 * radius;
                if gap_mm < min_feature {
                    return Err(GeometryError::SpheresTooClose {
                        first: a.name.clone(),
                        second: b.name.clone(),
                        gap_mm,
                        min_feature_mm: min_feature,
                    });
                }
            }
        }

        let mut router = Router {
            spheres: &spheres,
            view: options.view.vector(),
            mount: options.mount.vector(),
            mount_along_view: options.mount == options.view,
            radius,
            strut_radius,
            stub_radius: STUB_DIAMETER_FACTOR * strut_radius,
            clearance: min_feature,
            blend: blend_radius(strut_radius, min_feature),
            feet: Vec::new(),
            struts: Vec::new(),
        };
        let (hub, plate, teardrops, bed_level, down) = match options.structure {
            Structure::Routed => {
                router.posts_and_links()?;
                let hub = router.back_plane()?;
                let plate = router.stub_and_plate(hub, options.mount_holes.as_ref());
                (hub, plate, Vec::new(), None, options.mount)
            }
            Structure::Pillars => {
                let tab_side = if options.mount == options.view {
                    let v = options.view.vector();
                    let k = (0..3)
                        .find(|&k| v[k] == 0.0)
                        .expect("an axis is perpendicular");
                    Axis::new(k, false)
                } else {
                    options.mount
                };
                let (plate, teardrops, bed_level) = router.pillars(
                    options.view_cone_deg.to_radians(),
                    tab_side.vector(),
                    options.mount_holes.as_ref(),
                )?;
                (0, plate, teardrops, Some(bed_level), options.view)
            }
        };
        let Router { feet, struts, .. } = router;

        let blend_mm = blend_radius(strut_radius, min_feature);
        let mut marker = Marker {
            name: layout.name.clone(),
            spheres,
            feet,
            hub,
            struts,
            plate,
            mount_holes: options.mount_holes.clone(),
            blend_mm,
            rim_blend_mm: min_feature,
            min_feature_mm: min_feature,
            view: options.view,
            mount: options.mount,
            structure: options.structure,
            down,
            teardrops,
            bed_level,
            view_cone_deg: options.view_cone_deg,
            junctions: Vec::new(),
        };
        marker.junctions = marker.build_junctions();
        marker.check_clearances()?;
        marker.check_sphere_junctions()?;
        marker.check_bed(&options.bed)?;
        Ok(marker)
    }

    /// A readable name of a strut, e.g. "post P1", "link P3-O0", "back strut
    /// P2-P1" (feet named after their spheres), "stub".
    pub fn strut_name(&self, index: usize) -> String {
        let strut = &self.struts[index];
        let node = |n: Node| match n {
            Node::Sphere(i) => self.spheres[i].name.clone(),
            Node::Foot(k) => self.spheres[self.feet[k].sphere].name.clone(),
            Node::Plate => "plate".to_string(),
        };
        match strut.kind {
            StrutKind::Post => format!("post {}", node(strut.ends[0])),
            StrutKind::Link => format!("link {}-{}", node(strut.ends[0]), node(strut.ends[1])),
            StrutKind::Back => {
                format!("back strut {}-{}", node(strut.ends[0]), node(strut.ends[1]))
            }
            StrutKind::Stub => "mount stub".to_string(),
        }
    }

    /// How far a node's parts reach from its point: the sphere's radius,
    /// the thickest strut at a foot, half the plate's thickness.
    fn node_extent(&self, node: Node) -> f64 {
        match node {
            Node::Sphere(i) => self.spheres[i].radius,
            Node::Foot(k) => self
                .struts
                .iter()
                .filter(|s| s.ends.contains(&Node::Foot(k)))
                .map(|s| s.radius)
                .fold(0.0, f64::max),
            Node::Plate => self.plate.half_extents.dot(&self.down.vector().abs()),
        }
    }

    /// How far from a node its fillets can reach: past the node's parts by
    /// twice the blend radius, and past the point where every two of its
    /// struts are a blend radius apart (beyond which the smooth minimum
    /// equals the exact one).
    fn junction_reach(&self, node: Node) -> f64 {
        let at: Vec<&Strut> = self
            .struts
            .iter()
            .filter(|s| s.ends.contains(&node))
            .collect();
        let direction = |s: &Strut| {
            let (near, far) = if s.ends[0] == node {
                (s.a, s.b)
            } else {
                (s.b, s.a)
            };
            (far - near).normalize()
        };
        let mut reach = self.node_extent(node) + 2.0 * self.blend_mm;
        for (k, a) in at.iter().enumerate() {
            for b in &at[k + 1..] {
                let angle = direction(a).dot(&direction(b)).clamp(-1.0, 1.0).acos();
                let half_sine = (0.5 * angle).sin().max(MIN_HALF_ANGLE_SINE);
                reach = reach.max((self.blend_mm + a.radius + b.radius) / (2.0 * half_sine));
            }
        }
        reach
    }

    /// The junctions: nodes joined by a strut whose exposed length (between
    /// the parts of its two nodes) is under two blend radii plus the minimum
    /// feature are merged, so that their fillets form one smooth surface.
    fn build_junctions(&self) -> Vec<Junction> {
        let nodes: Vec<Node> = (0..self.spheres.len())
            .map(Node::Sphere)
            .chain((0..self.feet.len()).map(Node::Foot))
            .chain([Node::Plate])
            .collect();
        let position = |n: Node| nodes.iter().position(|&m| m == n).expect("a node");
        let mut parent: Vec<usize> = (0..nodes.len()).collect();
        fn root(parent: &mut [usize], mut x: usize) -> usize {
            while parent[x] != x {
                parent[x] = parent[parent[x]];
                x = parent[x];
            }
            x
        }
        for strut in &self.struts {
            let exposed = (strut.b - strut.a).norm()
                - self.node_extent(strut.ends[0])
                - self.node_extent(strut.ends[1]);
            if exposed < 2.0 * self.blend_mm + self.min_feature_mm {
                let (a, b) = (position(strut.ends[0]), position(strut.ends[1]));
                let (ra, rb) = (root(&mut parent, a), root(&mut parent, b));
                parent[ra] = rb;
            }
        }
        if self.structure == Structure::Pillars {
            // Every support foot stands on the plate: one junction.
            let plate = position(Node::Plate);
            for k in 0..self.feet.len() {
                let foot = position(Node::Foot(k));
                let (ra, rb) = (root(&mut parent, foot), root(&mut parent, plate));
                parent[ra] = rb;
            }
        }
        let reach: Vec<f64> = nodes.iter().map(|&n| self.junction_reach(n)).collect();
        let mut junctions = Vec::new();
        for r in 0..nodes.len() {
            if root(&mut parent, r) != r {
                continue;
            }
            let members: Vec<usize> = (0..nodes.len())
                .filter(|&m| root(&mut parent, m) == r)
                .collect();
            let inside = |n: Node| members.contains(&position(n));
            let spheres: Vec<usize> = members
                .iter()
                .filter_map(|&m| match nodes[m] {
                    Node::Sphere(i) => Some(i),
                    _ => None,
                })
                .collect();
            let plate = members.iter().any(|&m| nodes[m] == Node::Plate);
            let mut pieces = Vec::new();
            for strut in &self.struts {
                let (in_a, in_b) = (inside(strut.ends[0]), inside(strut.ends[1]));
                let length = (strut.b - strut.a).norm();
                let unit = (strut.b - strut.a) / length;
                match (in_a, in_b) {
                    (true, true) => pieces.push((strut.a, strut.b, strut.radius)),
                    (true, false) => {
                        let l = reach[position(strut.ends[0])].min(length);
                        pieces.push((strut.a, strut.a + unit * l, strut.radius));
                    }
                    (false, true) => {
                        let l = reach[position(strut.ends[1])].min(length);
                        pieces.push((strut.b - unit * l, strut.b, strut.radius));
                    }
                    (false, false) => {}
                }
            }
            if spheres.is_empty() && pieces.is_empty() && !plate {
                continue;
            }
            let (centre, radius) = bounding_ball(
                spheres
                    .iter()
                    .map(|&i| (self.spheres[i].centre, self.spheres[i].radius))
                    .chain(pieces.iter().flat_map(|&(a, b, r)| [(a, r), (b, r)]))
                    .chain(if plate {
                        vec![
                            (self.plate.centre - self.plate.half_extents, 0.0),
                            (self.plate.centre + self.plate.half_extents, 0.0),
                        ]
                    } else {
                        Vec::new()
                    }),
            );
            junctions.push(Junction {
                spheres,
                pieces,
                plate,
                centre,
                radius,
            });
        }
        junctions
    }

    /// The plate with its holes cut out (rims rounded).
    fn plate_sample(&self, p: &Vector3<f64>) -> Sample {
        let plate = &self.plate;
        let mut value = sdf::rounded_box(p, &plate.centre, &plate.half_extents, plate.rounding);
        for hole in &plate.holes {
            let cut = sdf::cylinder(p, &hole.centre, &hole.axis, hole.radius);
            value = sdf::smooth_subtract(value, cut, self.rim_blend_mm);
        }
        value
    }

    fn junction_sample(&self, junction: &Junction, p: &Vector3<f64>) -> Sample {
        let mut value: Option<Sample> = None;
        let mut blend = |s: Sample| {
            value = Some(match value {
                Some(v) => sdf::smooth_min(v, s, self.blend_mm),
                None => s,
            })
        };
        for &i in &junction.spheres {
            let sphere = &self.spheres[i];
            blend(match self.teardrops.get(i).copied().flatten() {
                Some((tip, tip_radius)) => {
                    sdf::round_cone(p, &sphere.centre, sphere.radius, &tip, tip_radius)
                }
                None => sdf::ball(p, &sphere.centre, sphere.radius),
            });
        }
        if junction.plate {
            blend(self.plate_sample(p));
        }
        for (a, b, radius) in &junction.pieces {
            blend(sdf::capsule(p, a, b, *radius));
        }
        let value = value.expect("every junction has a member");
        if junction.plate {
            // The bed face stays flat: the stub's fillet must not bulge
            // through the plate.
            let m = self.down.vector();
            let bed = self
                .bed_level
                .unwrap_or(self.plate.centre.dot(&m) + self.plate.half_extents.dot(&m.abs()));
            sdf::max(value, sdf::half_space(p, &m, bed))
        } else {
            value
        }
    }

    /// The signed distance of the marker (negative inside) and its gradient
    /// at `p`: the exact minimum of every strut and of every junction's
    /// smooth union. 1-Lipschitz.
    pub fn sample(&self, p: &Vector3<f64>) -> Sample {
        let mut best: Option<Sample> = None;
        for strut in &self.struts {
            // A strut's value is at least its distance to the ball around
            // it, so struts that cannot be the minimum are skipped without
            // changing the result.
            if let Some(b) = &best {
                let half = 0.5 * (strut.b - strut.a).norm();
                let lower = (p - 0.5 * (strut.a + strut.b)).norm() - half - strut.radius;
                if lower > b.value {
                    continue;
                }
            }
            let s = sdf::capsule(p, &strut.a, &strut.b, strut.radius);
            best = Some(best.map_or(s, |b| sdf::min(b, s)));
        }
        let mut best = best.expect("a marker has struts");
        for junction in &self.junctions {
            // A junction's value is at least its distance to its bounding
            // ball minus the deepest blend, so junctions that cannot be the
            // minimum are skipped without changing the result.
            let lower = (p - junction.centre).norm() - junction.radius - self.blend_depth(junction);
            if lower > best.value {
                continue;
            }
            best = sdf::min(best, self.junction_sample(junction, p));
        }
        match self.bed_level {
            Some(level) => sdf::max(best, sdf::half_space(p, &self.down.vector(), level)),
            None => best,
        }
    }

    /// The signed distance alone.
    pub fn signed_distance(&self, p: &Vector3<f64>) -> f64 {
        self.sample(p).value
    }

    /// Axis-aligned bounds of the solid (min, max), mm: the primitives'
    /// bounds grown by the most that blending can add.
    pub fn bounds(&self) -> (Vector3<f64>, Vector3<f64>) {
        let mut lo = Vector3::repeat(f64::INFINITY);
        let mut hi = Vector3::repeat(f64::NEG_INFINITY);
        let mut grow = |p: Vector3<f64>, r: f64| {
            lo = lo.inf(&(p - Vector3::repeat(r)));
            hi = hi.sup(&(p + Vector3::repeat(r)));
        };
        for s in &self.spheres {
            grow(s.centre, s.radius);
        }
        for s in &self.struts {
            grow(s.a, s.radius);
            grow(s.b, s.radius);
        }
        grow(self.plate.centre - self.plate.half_extents, 0.0);
        grow(self.plate.centre + self.plate.half_extents, 0.0);
        let depth = self
            .junctions
            .iter()
            .map(|j| self.blend_depth(j))
            .fold(0.0, f64::max);
        let margin = Vector3::repeat(depth);
        let (mut lo, mut hi) = (lo - margin, hi + margin);
        if let Some(level) = self.bed_level {
            // The solid ends at the bed plane: p · down ≤ level.
            let down = self.down.vector();
            let k = down.iamax();
            if down[k] > 0.0 {
                hi[k] = hi[k].min(level);
            } else {
                lo[k] = lo[k].max(-level);
            }
        }
        (lo, hi)
    }

    /// The most a junction's smooth union can lie below its members'
    /// minimum: a quarter blend radius per smooth minimum taken.
    fn blend_depth(&self, junction: &Junction) -> f64 {
        let members = junction.spheres.len() + junction.pieces.len() + usize::from(junction.plate);
        0.25 * self.blend_mm * members.saturating_sub(1) as f64
    }

    /// For each axis, the coordinates of the planes perpendicular to it
    /// that a strut lies tangent to along a line (struts perpendicular to
    /// the axis), each with a flag: `true` for a strut oblique to the other
    /// axes, whose tangent strip runs diagonally across the grid.
    pub fn tangent_planes(&self) -> [Vec<(f64, bool)>; 3] {
        let mut planes: [Vec<(f64, bool)>; 3] = Default::default();
        if let Some(level) = self.bed_level {
            let down = self.down.vector();
            let k = down.iamax();
            planes[k].push((level * down[k], false));
        }
        for strut in &self.struts {
            let d = strut.b - strut.a;
            let length = d.norm();
            if length == 0.0 {
                continue;
            }
            let along_axis = (0..3).any(|k| (d[k].abs() - length).abs() <= 1e-12 * length);
            for (k, axis_planes) in planes.iter_mut().enumerate() {
                if d[k].abs() <= 1e-12 * length {
                    axis_planes.push((strut.a[k] - strut.radius, !along_axis));
                    axis_planes.push((strut.a[k] + strut.radius, !along_axis));
                }
            }
        }
        planes
    }

    /// The thinnest feature the mesh must resolve, mm: the strut radius,
    /// the fillet radius, the holes' radius and rim rounding, and the
    /// smallest gap (the minimum feature size).
    pub fn finest_feature_mm(&self) -> f64 {
        let mut finest = self
            .struts
            .iter()
            .map(|s| s.radius)
            .fold(self.min_feature_mm, f64::min)
            .min(self.blend_mm)
            .min(self.plate.rounding);
        for hole in &self.plate.holes {
            finest = finest.min(hole.radius).min(self.rim_blend_mm);
        }
        finest
    }

    /// Whether two struts (by index) share a node.
    fn struts_join(&self, a: usize, b: usize) -> bool {
        let (a, b) = (&self.struts[a], &self.struts[b]);
        a.ends.iter().any(|n| b.ends.contains(n))
    }

    /// Every pair of parts that do not join must keep `min_feature` apart.
    fn check_clearances(&self) -> Result<(), GeometryError> {
        let too_close = |first: String, second: String, gap_mm: f64| GeometryError::Clearance {
            first,
            second,
            gap_mm,
            min_feature_mm: self.min_feature_mm,
        };
        // Tolerance for clearances that routing makes exactly equal to the
        // minimum.
        let slack = 1e-9 * (1.0 + self.min_feature_mm);
        for (s, strut) in self.struts.iter().enumerate() {
            for (i, sphere) in self.spheres.iter().enumerate() {
                if strut.ends.contains(&Node::Sphere(i)) {
                    continue;
                }
                let axis = sdf::closest_on_segment(&sphere.centre, &strut.a, &strut.b);
                let gap = (sphere.centre - axis).norm() - sphere.radius - strut.radius;
                if gap < self.min_feature_mm - slack {
                    return Err(too_close(
                        self.strut_name(s),
                        format!("sphere {}", sphere.name),
                        gap,
                    ));
                }
            }
            for t in s + 1..self.struts.len() {
                if self.struts_join(s, t) {
                    continue;
                }
                let other = &self.struts[t];
                let gap = segment_distance(&strut.a, &strut.b, &other.a, &other.b)
                    - strut.radius
                    - other.radius;
                if gap < self.min_feature_mm - slack {
                    return Err(too_close(self.strut_name(s), self.strut_name(t), gap));
                }
            }
        }
        // Fillets swell a junction beyond its parts by up to
        // `junction_growth`: every blob of a junction (a foot with its
        // thickest strut, or a strut where it leaves its sphere) keeps the
        // minimum feature from parts that do not join it.
        let growth = junction_growth(self.blend_mm);
        for (node, centre, radius, name) in self.junction_blobs() {
            let joins = |s: &Strut| s.ends.contains(&node);
            for (s, strut) in self.struts.iter().enumerate() {
                if joins(strut) {
                    continue;
                }
                let axis = sdf::closest_on_segment(&centre, &strut.a, &strut.b);
                let gap = (centre - axis).norm() - strut.radius - radius - growth;
                if gap < self.min_feature_mm - slack {
                    return Err(too_close(name.clone(), self.strut_name(s), gap));
                }
            }
            for (i, sphere) in self.spheres.iter().enumerate() {
                let joined = node == Node::Sphere(i)
                    || self
                        .struts
                        .iter()
                        .any(|s| s.ends.contains(&node) && s.ends.contains(&Node::Sphere(i)));
                if joined {
                    continue;
                }
                let gap = (centre - sphere.centre).norm() - sphere.radius - radius - growth;
                if gap < self.min_feature_mm - slack {
                    return Err(too_close(
                        name.clone(),
                        format!("sphere {}", sphere.name),
                        gap,
                    ));
                }
            }
        }
        Ok(())
    }

    /// The places where fillets swell the solid: each foot (centre, its
    /// thickest strut's radius) and each strut's exit from its sphere.
    fn junction_blobs(&self) -> Vec<(Node, Vector3<f64>, f64, String)> {
        let mut blobs = Vec::new();
        for (k, foot) in self.feet.iter().enumerate() {
            let node = Node::Foot(k);
            blobs.push((
                node,
                foot.position,
                self.node_extent(node),
                format!(
                    "the junction at the foot of {}",
                    self.spheres[foot.sphere].name
                ),
            ));
        }
        for (i, sphere) in self.spheres.iter().enumerate() {
            let node = Node::Sphere(i);
            for strut in self.struts.iter().filter(|s| s.ends.contains(&node)) {
                let far = if strut.ends[0] == node {
                    strut.b
                } else {
                    strut.a
                };
                let exit = sphere.centre + (far - sphere.centre).normalize() * sphere.radius;
                blobs.push((
                    node,
                    exit,
                    strut.radius,
                    format!("the fillet where a strut leaves sphere {}", sphere.name),
                ));
            }
        }
        blobs
    }

    /// The level `p · down` of the face that lies on the bed: the most any
    /// point of the solid reaches along [`Marker::down`].
    pub fn bed_face_level(&self) -> f64 {
        let m = self.down.vector();
        self.bed_level
            .unwrap_or(self.plate.centre.dot(&m) + self.plate.half_extents.dot(&m.abs()))
    }

    /// The marker → print frame motion `p ↦ R·p + shift` of the STL: Z up,
    /// [`Marker::down`] pointing onto the bed, the bed face at z = 0.
    pub fn print_transform(&self) -> (Matrix3<f64>, Vector3<f64>) {
        (
            print_rotation(self.down),
            Vector3::new(0.0, 0.0, self.bed_face_level()),
        )
    }

    /// The part's extents in the print frame (x, y, z), mm, from
    /// [`Marker::bounds`] (so at most the blend depth too large: the bed
    /// check errs on the safe side).
    pub fn print_size_mm(&self) -> [f64; 3] {
        let (lo, hi) = self.bounds();
        let size = print_rotation(self.down).abs() * (hi - lo);
        [size.x, size.y, size.z]
    }

    /// The part must fit the build volume, turned on the bed if need be.
    fn check_bed(&self, bed: &Bed) -> Result<(), GeometryError> {
        let size_mm = self.print_size_mm();
        let [x, y, z] = bed.0;
        let fits = size_mm[2] <= z
            && ((size_mm[0] <= x && size_mm[1] <= y) || (size_mm[1] <= x && size_mm[0] <= y));
        if fits {
            Ok(())
        } else {
            Err(GeometryError::DoesNotFitBed {
                size_mm,
                bed_mm: bed.0,
            })
        }
    }

    /// Struts that meet at a sphere must part before they leave it:
    /// at the sphere's surface their gap is at least the minimum feature.
    fn check_sphere_junctions(&self) -> Result<(), GeometryError> {
        for (i, sphere) in self.spheres.iter().enumerate() {
            let node = Node::Sphere(i);
            let at: Vec<usize> = (0..self.struts.len())
                .filter(|&s| self.struts[s].ends.contains(&node))
                .collect();
            for (k, &s) in at.iter().enumerate() {
                for &t in &at[k + 1..] {
                    let direction = |index: usize| {
                        let strut = &self.struts[index];
                        let far = if strut.ends[0] == node {
                            strut.b
                        } else {
                            strut.a
                        };
                        (far - sphere.centre).normalize()
                    };
                    let angle = direction(s).dot(&direction(t)).clamp(-1.0, 1.0).acos();
                    let gap = 2.0 * sphere.radius * (0.5 * angle).sin()
                        - self.struts[s].radius
                        - self.struts[t].radius;
                    if gap < self.min_feature_mm {
                        return Err(GeometryError::NarrowJunction {
                            sphere: sphere.name.clone(),
                            first: self.strut_name(s),
                            second: self.strut_name(t),
                            angle_deg: angle.to_degrees(),
                            min_feature_mm: self.min_feature_mm,
                        });
                    }
                }
            }
        }
        Ok(())
    }
}

/// Builds the struts (see the module documentation).
struct Router<'a> {
    spheres: &'a [SphereFeature],
    view: Vector3<f64>,
    mount: Vector3<f64>,
    mount_along_view: bool,
    radius: f64,
    strut_radius: f64,
    stub_radius: f64,
    clearance: f64,
    blend: f64,
    feet: Vec<Foot>,
    struts: Vec<Strut>,
}

impl Router<'_> {
    /// Step 1: a post back along the view from every sphere, unless it
    /// would pass within the clearance (plus the swell of the fillet where
    /// it leaves its sphere) of a sphere behind; then a link to the first
    /// sphere behind whose disc overlaps this one's in the main view (or,
    /// failing those, the nearest sphere behind) to which a straight link
    /// keeps clear of every other sphere and meets that sphere's struts at
    /// an open angle.
    fn posts_and_links(&mut self) -> Result<(), GeometryError> {
        let depth = |i: usize| self.spheres[i].centre.dot(&self.view);
        // Behind the rearmost sphere, far enough that the fillets where its
        // post leaves it and where the post meets the back plane stay apart.
        let back_depth = (0..self.spheres.len())
            .map(depth)
            .fold(f64::NEG_INFINITY, f64::max)
            + self.radius
            + 2.0 * self.blend
            + self.clearance
            + self.stub_radius;
        let growth = junction_growth(self.blend);
        let reach = self.radius + self.strut_radius + growth + self.clearance;
        let overlap = reach.max(2.0 * self.radius);
        // Decide from the back to the front, so that when a sphere picks a
        // sphere behind it, that sphere's own strut and the links already
        // arriving at it are known (to keep the junction open).
        let mut order: Vec<usize> = (0..self.spheres.len()).collect();
        order.sort_by(|&a, &b| depth(b).total_cmp(&depth(a)));
        let mut link_to: Vec<Option<usize>> = vec![None; self.spheres.len()];
        let mut posts = Vec::new();
        for i in order {
            let sphere = &self.spheres[i];
            // (index, distance behind, distance across the view)
            let behind: Vec<(usize, f64, f64)> = self
                .spheres
                .iter()
                .enumerate()
                .filter(|&(j, _)| j != i)
                .map(|(j, other)| {
                    let offset = other.centre - sphere.centre;
                    let along = offset.dot(&self.view);
                    (j, along, (offset - self.view * along).norm())
                })
                .filter(|&(_, along, _)| along > 0.0)
                .collect();
            if behind.iter().all(|&(_, _, across)| across >= reach) {
                posts.push(i);
                continue;
            }
            // First the spheres whose disc overlaps this one's in the main
            // view, nearest first (a link to them hides best); failing
            // those, any sphere behind, by distance.
            let mut candidates: Vec<(usize, f64)> = behind
                .iter()
                .filter(|&&(_, _, across)| across < overlap)
                .map(|&(j, along, _)| (j, along))
                .collect();
            candidates.sort_by(|a, b| a.1.total_cmp(&b.1));
            let mut others: Vec<(usize, f64)> = behind
                .iter()
                .filter(|&&(_, _, across)| across >= overlap)
                .map(|&(j, along, across)| (j, along.hypot(across)))
                .collect();
            others.sort_by(|a, b| a.1.total_cmp(&b.1));
            candidates.extend(others);
            let clear = |j: usize| {
                let (a, b) = (sphere.centre, self.spheres[j].centre);
                self.spheres.iter().enumerate().all(|(k, other)| {
                    k == i || k == j || {
                        let axis = sdf::closest_on_segment(&other.centre, &a, &b);
                        (other.centre - axis).norm() - other.radius - self.strut_radius
                            >= self.clearance + growth
                    }
                })
            };
            // The struts already at j: its own (a post along the view or a
            // link further back) and the links arriving from the front.
            let open_at = |j: usize| {
                let centre = self.spheres[j].centre;
                let arriving = (sphere.centre - centre).normalize();
                let own = match link_to[j] {
                    Some(k) => (self.spheres[k].centre - centre).normalize(),
                    None => self.view,
                };
                std::iter::once(own)
                    .chain(
                        (0..self.spheres.len())
                            .filter(|&k| link_to[k] == Some(j))
                            .map(|k| (self.spheres[k].centre - centre).normalize()),
                    )
                    .all(|u| {
                        let angle = arriving.dot(&u).clamp(-1.0, 1.0).acos();
                        2.0 * self.radius * (0.5 * angle).sin() - 2.0 * self.strut_radius
                            >= self.clearance
                    })
            };
            let j = candidates
                .iter()
                .map(|&(j, _)| j)
                .find(|&j| clear(j) && open_at(j))
                .ok_or_else(|| GeometryError::RoutingFailed {
                    from: format!("sphere {}", sphere.name),
                    reason: "its post would pass too close to a sphere behind it, and no straight link to a sphere behind it keeps clear of the others and meets that sphere's struts at an open angle".into(),
                })?;
            link_to[i] = Some(j);
        }
        for (i, target) in link_to.iter().enumerate() {
            if let Some(j) = *target {
                self.struts.push(Strut {
                    kind: StrutKind::Link,
                    ends: [Node::Sphere(i), Node::Sphere(j)],
                    a: self.spheres[i].centre,
                    b: self.spheres[j].centre,
                    radius: self.strut_radius,
                });
            }
        }
        posts.sort_unstable();
        for i in posts {
            let centre = self.spheres[i].centre;
            let foot = centre + self.view * (back_depth - depth(i));
            self.feet.push(Foot {
                position: foot,
                sphere: i,
            });
            self.struts.push(Strut {
                kind: StrutKind::Post,
                ends: [Node::Sphere(i), Node::Foot(self.feet.len() - 1)],
                a: centre,
                b: foot,
                radius: self.strut_radius,
            });
        }
        Ok(())
    }

    /// The foot at which the stub starts: the one furthest along the mount
    /// axis (ties: nearest the hub), or the hub when mounting along the
    /// view.
    fn mount_foot(&self, hub: usize) -> usize {
        if self.mount_along_view {
            return hub;
        }
        let along = |k: usize| self.feet[k].position.dot(&self.mount);
        let best = (0..self.feet.len())
            .map(along)
            .fold(f64::NEG_INFINITY, f64::max);
        (0..self.feet.len())
            .filter(|&k| along(k) >= best - 1e-9)
            .min_by(|&a, &b| {
                let d = |k: usize| (self.feet[k].position - self.feet[hub].position).norm();
                d(a).total_cmp(&d(b))
            })
            .expect("there is at least one foot")
    }

    /// Clearance radius of a foot: the stub's where the stub starts.
    fn foot_radius(&self, k: usize, mount_foot: usize) -> f64 {
        if k == mount_foot && !self.mount_along_view {
            self.stub_radius
        } else {
            self.strut_radius
        }
    }

    /// Step 2: back struts from every foot to the hub, as a shortest-path
    /// tree whose struts keep clear of the other feet and of each other and
    /// meet at open angles. Returns the hub.
    fn back_plane(&mut self) -> Result<usize, GeometryError> {
        let count = self.feet.len();
        let centroid = self.feet.iter().map(|f| f.position).sum::<Vector3<f64>>() / count as f64;
        let hub = (0..count)
            .min_by(|&a, &b| {
                let d = |k: usize| (self.feet[k].position - centroid).norm();
                d(a).total_cmp(&d(b))
            })
            .expect("there is at least one foot");
        let mount_foot = self.mount_foot(hub);
        let position = |k: usize| self.feet[k].position;
        let min_cos = MIN_JUNCTION_ANGLE_DEG.to_radians().cos();

        // Path length to the hub along the tree, and the back struts so far.
        let mut path: Vec<Option<f64>> = vec![None; count];
        path[hub] = Some(0.0);
        let mut edges: Vec<(usize, usize)> = Vec::new();
        // Grow the tree one foot at a time: of all feet not yet joined, the
        // one with the shortest feasible path to the hub.
        let feasible = |foot: usize, target: usize, edges: &[(usize, usize)]| -> bool {
            let (a, b) = (position(foot), position(target));
            // Clear of every other foot.
            let feet_clear = (0..count).filter(|&g| g != foot && g != target).all(|g| {
                let axis = sdf::closest_on_segment(&position(g), &a, &b);
                (position(g) - axis).norm()
                    >= self.strut_radius
                        + self.foot_radius(g, mount_foot)
                        + junction_growth(self.blend)
                        + self.clearance
            });
            // Clear of the back struts it does not join.
            let struts_clear = edges
                .iter()
                .filter(|&&(p, q)| p != foot && q != foot && p != target && q != target)
                .all(|&(p, q)| {
                    segment_distance(&a, &b, &position(p), &position(q))
                        >= 2.0 * self.strut_radius + self.clearance
                });
            // Open angles with the struts already at the target: at
            // least MIN_JUNCTION_ANGLE_DEG, and wide enough that the two
            // struts are a blend radius plus the clearance apart before
            // the shorter one ends (else the fillet between them would
            // leave a slit).
            let direction = (a - b).normalize();
            let angles_open = edges
                .iter()
                .filter_map(|&(p, q)| {
                    if p == target {
                        Some(q)
                    } else if q == target {
                        Some(p)
                    } else {
                        None
                    }
                })
                .all(|other| {
                    let shorter = (a - b).norm().min((position(other) - b).norm());
                    let apart = 2.0 * self.strut_radius + self.blend + self.clearance;
                    let needed = 2.0 * (apart / (2.0 * shorter)).min(1.0).asin();
                    let cos = direction.dot(&(position(other) - b).normalize());
                    cos <= min_cos && cos <= needed.cos()
                });
            feet_clear && struts_clear && angles_open
        };
        while path.iter().any(Option::is_none) {
            let joined = &path;
            let best = (0..count)
                .filter(|&foot| joined[foot].is_none())
                .flat_map(|foot| {
                    (0..count).filter_map(move |t| {
                        joined[t].map(|p| (p + (position(foot) - position(t)).norm(), foot, t))
                    })
                })
                .filter(|&(_, foot, target)| feasible(foot, target, &edges))
                .min_by(|a, b| a.0.total_cmp(&b.0));
            let Some((length, foot, target)) = best else {
                let foot = (0..count)
                    .find(|&k| path[k].is_none())
                    .expect("a foot is left");
                return Err(GeometryError::RoutingFailed {
                    from: format!("foot of {}", self.spheres[self.feet[foot].sphere].name),
                    reason: "no back strut towards the hub keeps clear of the other feet and struts with open junction angles".into(),
                });
            };
            path[foot] = Some(length);
            edges.push((foot, target));
        }
        for (foot, target) in edges {
            self.struts.push(Strut {
                kind: StrutKind::Back,
                ends: [Node::Foot(foot), Node::Foot(target)],
                a: position(foot),
                b: position(target),
                radius: self.strut_radius,
            });
        }
        Ok(hub)
    }

    /// [`Structure::Pillars`]: a cone under every sphere, a support from its
    /// tip down to the base plate (or onto a sphere behind), and the plate
    /// behind every sphere, perpendicular to the view, on the bed. Supports
    /// are chosen back to front: straight down when that keeps clear of
    /// the other parts and covers no sphere from the view cone (of
    /// half-angle `cone_rad`), else the slant and direction (or the sphere
    /// to stand on) that covers least. Returns the plate, the cones and
    /// the bed level (along the view).
    #[allow(clippy::type_complexity)]
    fn pillars(
        &mut self,
        cone_rad: f64,
        tab_side: Vector3<f64>,
        holes: Option<&MountHoles>,
    ) -> Result<(Plate, Vec<Option<(Vector3<f64>, f64)>>, f64), GeometryError> {
        let v = self.view;
        let count = self.spheres.len();
        let (radius, strut_radius) = (self.radius, self.strut_radius);
        let drop_length = (radius - strut_radius) / TEARDROP_HALF_ANGLE_DEG.to_radians().sin();
        let tips: Vec<Vector3<f64>> = self
            .spheres
            .iter()
            .map(|s| s.centre + v * drop_length)
            .collect();
        let depth = |p: &Vector3<f64>| p.dot(&v);
        let inner = tips.iter().map(depth).fold(f64::NEG_INFINITY, f64::max)
            + strut_radius
            + 2.0 * self.blend
            + self.clearance;
        let growth = junction_growth(self.blend);
        let directions = view_cone_directions(&v, cone_rad, 2, 12);
        let kv = v.iamax();
        let unit = |k: usize| Vector3::from_fn(|r, _| if r == k { 1.0 } else { 0.0 });
        let (e1, e2) = (unit((kv + 1) % 3), unit((kv + 2) % 3));
        let mut order: Vec<usize> = (0..count).collect();
        order.sort_by(|&a, &b| {
            depth(&self.spheres[b].centre).total_cmp(&depth(&self.spheres[a].centre))
        });
        // Each sphere's support: its end and the sphere it stands on, if any.
        let mut supports: Vec<Option<(Vector3<f64>, Option<usize>)>> = vec![None; count];
        let hits = |q: &Vector3<f64>, d: &Vector3<f64>, centre: &Vector3<f64>, r: f64| {
            let w = centre - q;
            let t = w.dot(d);
            if t < 0.0 {
                w.norm_squared() < r * r
            } else {
                w.norm_squared() - t * t < r * r
            }
        };
        let centroid = self.spheres.iter().map(|s| s.centre).sum::<Vector3<f64>>() / count as f64;
        for &i in &order {
            let tip = tips[i];
            // Slanted supports try directions towards the middle of the
            // layout first, which keeps the plate small.
            let inward = centroid - self.spheres[i].centre;
            let phi_inward = inward.dot(&e2).atan2(inward.dot(&e1));
            let mut candidates: Vec<(Vector3<f64>, Option<usize>)> = Vec::new();
            for &slant_deg in SUPPORT_SLANTS_DEG {
                let slant = slant_deg.to_radians();
                let azimuths = if slant_deg == 0.0 {
                    1
                } else {
                    SUPPORT_AZIMUTHS
                };
                for a in 0..azimuths {
                    // 0, +1, −1, +2, −2, … steps away from inward.
                    let step = a.div_ceil(2) as f64 * if a % 2 == 1 { 1.0 } else { -1.0 };
                    let phi = phi_inward + std::f64::consts::TAU * step / azimuths as f64;
                    let direction =
                        v * slant.cos() + (e1 * phi.cos() + e2 * phi.sin()) * slant.sin();
                    candidates.push((
                        tip + direction * ((inner - depth(&tip)) / slant.cos()),
                        None,
                    ));
                }
            }
            let steepest = SUPPORT_SLANTS_DEG
                .iter()
                .fold(0.0f64, |m, &s| m.max(s))
                .to_radians();
            for j in 0..count {
                if j == i
                    || supports[j].is_none()
                    || supports
                        .iter()
                        .any(|s| matches!(s, Some((_, Some(k))) if *k == j))
                {
                    continue;
                }
                let offset = self.spheres[j].centre - tip;
                let along = offset.dot(&v);
                let across = (offset - v * along).norm();
                if along > radius + strut_radius + 2.0 * self.blend
                    && across <= along * steepest.tan()
                {
                    candidates.push((self.spheres[j].centre, Some(j)));
                }
            }
            // Feet within the layout's footprint (grown by a sphere
            // diameter) first, which keeps the plate small; any foot only
            // when none of those is feasible.
            let footprint = |p: &Vector3<f64>| {
                [e1, e2].iter().all(|e| {
                    let (lo, hi) = self
                        .spheres
                        .iter()
                        .map(|s| s.centre.dot(e))
                        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), x| {
                            (lo.min(x), hi.max(x))
                        });
                    (lo - 2.0 * radius..=hi + 2.0 * radius).contains(&p.dot(e))
                })
            };
            let (inside, outside): (Vec<_>, Vec<_>) =
                candidates.into_iter().partition(|(end, _)| footprint(end));
            let mut best: Option<(f64, Vector3<f64>, Option<usize>)> = None;
            for (end, onto) in inside.into_iter().chain(outside) {
                if best.is_some() && !footprint(&end) {
                    break;
                }
                // Clear of every other sphere and its cone, and of every
                // support chosen so far (but the one it stands on).
                let clear_spheres = (0..count).filter(|&k| k != i && Some(k) != onto).all(|k| {
                    segment_distance(&tip, &end, &self.spheres[k].centre, &tips[k])
                        - radius
                        - strut_radius
                        >= self.clearance + growth
                });
                let clear_supports =
                    (0..count)
                        .filter(|&k| k != i && Some(k) != onto)
                        .all(|k| match supports[k] {
                            Some((other_end, _)) => {
                                segment_distance(&tip, &end, &tips[k], &other_end)
                                    - 2.0 * strut_radius
                                    >= self.clearance + growth
                            }
                            None => true,
                        });
                if !(clear_spheres && clear_supports) {
                    continue;
                }
                // How much it covers: sample points along it, rays towards
                // every other sphere in the cone that its own sphere does
                // not shadow.
                let length = (end - tip).norm();
                let steps = (length / SUPPORT_SAMPLE_MM).ceil().max(1.0) as usize;
                let mut covered = 0usize;
                for step in 0..=steps {
                    let q = tip + (end - tip) * (step as f64 / steps as f64);
                    for d in &directions {
                        if hits(&q, &(-d), &self.spheres[i].centre, radius - strut_radius) {
                            continue;
                        }
                        covered += (0..count)
                            .filter(|&k| {
                                k != i
                                    && hits(&q, d, &self.spheres[k].centre, radius + strut_radius)
                            })
                            .count();
                    }
                }
                let score = covered as f64 * length / steps as f64;
                if best.as_ref().is_none_or(|b| score < b.0) {
                    best = Some((score, end, onto));
                }
                if score == 0.0 {
                    break;
                }
            }
            let Some((_, end, onto)) = best else {
                return Err(GeometryError::RoutingFailed {
                    from: format!("sphere {}", self.spheres[i].name),
                    reason: "no support down to the base plate or onto a sphere behind it, at most 35 degrees from the view, keeps clear of the other spheres and supports (--structure routed may route it)".into(),
                });
            };
            supports[i] = Some((end, onto));
        }
        // The struts, and feet on the plate.
        for i in 0..count {
            let (end, onto) = supports[i].expect("every sphere has a support");
            match onto {
                Some(j) => self.struts.push(Strut {
                    kind: StrutKind::Link,
                    ends: [Node::Sphere(i), Node::Sphere(j)],
                    a: tips[i],
                    b: end,
                    radius: strut_radius,
                }),
                None => {
                    self.feet.push(Foot {
                        position: end,
                        sphere: i,
                    });
                    self.struts.push(Strut {
                        kind: StrutKind::Post,
                        ends: [Node::Sphere(i), Node::Foot(self.feet.len() - 1)],
                        a: tips[i],
                        b: end,
                        radius: strut_radius,
                    });
                }
            }
        }
        // The plate: the feet's footprint with a margin for the fillets, at
        // least PLATE_MIN_SIDE_MM, and a tab for the screw holes on the
        // mount side (two holes) or on both sides (four).
        let margin = strut_radius + self.blend + self.clearance + PLATE_ROUNDING_MM;
        let thickness = PLATE_THICKNESS_MM;
        let mut lo = [f64::INFINITY; 2];
        let mut hi = [f64::NEG_INFINITY; 2];
        for foot in &self.feet {
            for (k, e) in [e1, e2].iter().enumerate() {
                lo[k] = lo[k].min(foot.position.dot(e) - margin);
                hi[k] = hi[k].max(foot.position.dot(e) + margin);
            }
        }
        for k in 0..2 {
            let grow = (PLATE_MIN_SIDE_MM - (hi[k] - lo[k])).max(0.0);
            lo[k] -= 0.5 * grow;
            hi[k] += 0.5 * grow;
        }
        let mut hole_centres: Vec<[f64; 2]> = Vec::new();
        let hole_radius = 0.5 * holes.map_or(0.0, |h| h.diameter_mm);
        if let Some(spec) = holes {
            let wall = hole_radius.max(2.0 * self.clearance);
            let tab = 2.0 * (hole_radius + wall);
            // The tab axis (0 or 1) and side; the holes spread across it.
            let axis = if tab_side.dot(&e1) != 0.0 { 0 } else { 1 };
            let positive = tab_side.dot(if axis == 0 { &e1 } else { &e2 }) > 0.0;
            let other = 1 - axis;
            let spread = 0.25 * (hi[other] - lo[other]);
            let mid = 0.5 * (hi[other] + lo[other]);
            let mut sides = vec![positive];
            if spec.count == 4 {
                sides.push(!positive);
            }
            for side in sides {
                let at = if side {
                    hi[axis] += tab;
                    hi[axis] - 0.5 * tab
                } else {
                    lo[axis] -= tab;
                    lo[axis] + 0.5 * tab
                };
                for across in [mid - spread, mid + spread] {
                    let mut c = [0.0; 2];
                    c[axis] = at;
                    c[other] = across;
                    hole_centres.push(c);
                }
            }
        }
        let bed_level = inner + thickness;
        // The bed face's rounded rim rises no more than one layer before it
        // is steep enough to print (PILLAR_PLATE_ROUNDING_MM).
        let depth_mid = inner + 0.5 * thickness;
        let point = |a: f64, b: f64, d: f64| e1 * a + e2 * b + v * d;
        let centre = point(0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]), depth_mid);
        let half_extents = (point(
            0.5 * (hi[0] - lo[0]),
            0.5 * (hi[1] - lo[1]),
            0.5 * thickness,
        ))
        .abs();
        let plate = Plate {
            centre,
            half_extents,
            rounding: PILLAR_PLATE_ROUNDING_MM,
            holes: hole_centres
                .iter()
                .map(|c| Hole {
                    centre: point(c[0], c[1], inner + 0.5 * thickness),
                    axis: v,
                    radius: hole_radius,
                })
                .collect(),
        };
        let teardrops = tips.iter().map(|&tip| Some((tip, strut_radius))).collect();
        Ok((plate, teardrops, bed_level))
    }

    /// Step 3: the stub and the base plate with its holes.
    fn stub_and_plate(&mut self, hub: usize, holes: Option<&MountHoles>) -> Plate {
        let mount_foot = self.mount_foot(hub);
        let start = self.feet[mount_foot].position;
        let m = self.mount;
        // The plate's inner face: beyond every other part by the clearance,
        // and far enough out that the stub between the foot's fillets and
        // the plate's stays exposed for two blend radii plus the clearance
        // (so the two junctions, and their fillets, stay apart).
        let shortest = start.dot(&m) + self.stub_radius + 2.0 * self.blend + self.clearance;
        let inner = if self.mount_along_view {
            (start.dot(&m) + STUB_LENGTH_MM).max(shortest)
        } else {
            let spheres = self
                .spheres
                .iter()
                .map(|s| s.centre.dot(&m) + s.radius)
                .fold(f64::NEG_INFINITY, f64::max);
            let struts = self
                .struts
                .iter()
                .flat_map(|s| [s.a.dot(&m) + s.radius, s.b.dot(&m) + s.radius])
                .fold(f64::NEG_INFINITY, f64::max);
            (spheres.max(struts) + self.clearance).max(shortest)
        };
        let thickness = PLATE_THICKNESS_MM.max(self.stub_radius + 2.0 * self.clearance);
        let face_point = start + m * (inner - start.dot(&m));
        let centre = face_point + m * (0.5 * thickness);
        // The stub ends on the plate's inner face; its round end sinks into
        // the plate (thicker than the stub's radius) and leaves the bed face
        // flat.
        self.struts.push(Strut {
            kind: StrutKind::Stub,
            ends: [Node::Foot(mount_foot), Node::Plate],
            a: start,
            b: face_point,
            radius: self.stub_radius,
        });

        // In-plane axes: `across` is perpendicular to both the mount axis and
        // the view (or the first object axis perpendicular to the mount).
        let across = if self.mount_along_view {
            let k = (0..3)
                .find(|&k| m[k] == 0.0)
                .expect("an axis is perpendicular");
            Vector3::from_fn(|r, _| if r == k { 1.0 } else { 0.0 })
        } else {
            m.cross(&self.view)
        };
        let other = m.cross(&across);
        let blend = self.blend;
        let (offset, side) = match holes {
            Some(spec) => {
                let hole_radius = 0.5 * spec.diameter_mm;
                // Clear of the stub and its fillet, with a wall to the edge.
                let offset = self.stub_radius + blend + self.clearance + hole_radius;
                let wall = hole_radius.max(2.0 * self.clearance);
                (offset, 2.0 * (offset + hole_radius + wall))
            }
            None => (0.0, 0.0),
        };
        let side = side.max(PLATE_MIN_SIDE_MM).max(4.0 * self.stub_radius);
        let half_extents = Vector3::from_fn(|k, _| {
            if m[k] != 0.0 {
                0.5 * thickness
            } else {
                0.5 * side
            }
        });
        let hole_offsets: Vec<Vector3<f64>> = match holes.map(|h| h.count) {
            Some(4) => [(1.0, 1.0), (1.0, -1.0), (-1.0, 1.0), (-1.0, -1.0)]
                .iter()
                .map(|&(a, b)| (across * a + other * b) * (offset / 2f64.sqrt()))
                .collect(),
            Some(_) => vec![across * offset, -across * offset],
            None => Vec::new(),
        };
        Plate {
            centre,
            half_extents,
            rounding: PLATE_ROUNDING_MM,
            holes: hole_offsets
                .into_iter()
                .map(|o| Hole {
                    centre: centre + o,
                    axis: m,
                    radius: 0.5 * holes.map_or(0.0, |h| h.diameter_mm),
                })
                .collect(),
        }
    }
}

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

/// The object → print-frame rotation: the print frame is Z-up with the
/// mount axis pointing down (−Z) onto the bed; its X is the first object
/// axis perpendicular to the mount axis, and Y = Z × X. For the default
/// mount −y this is (x, y, z) → (x, −z, y).
pub fn print_rotation(mount: Axis) -> Matrix3<f64> {
    let up = -mount.vector();
    let k = (0..3)
        .find(|&k| up[k] == 0.0)
        .expect("an axis is perpendicular");
    let x = Vector3::from_fn(|r, _| if r == k { 1.0 } else { 0.0 });
    let y = up.cross(&x);
    Matrix3::from_rows(&[x.transpose(), y.transpose(), up.transpose()])
}

/// The object → glTF rotation: the print frame turned Y-up, (x, y, z)_print
/// → (x, z, −y). glTF's up (+Y) is again opposite the mount axis; for the
/// default mount −y it is the identity.
pub fn gltf_rotation(mount: Axis) -> Matrix3<f64> {
    let z_up_to_y_up = Matrix3::new(1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, -1.0, 0.0);
    z_up_to_y_up * print_rotation(mount)
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
