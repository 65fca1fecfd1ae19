//! The parts of the marker: spheres, struts, holes, the plate, feet.

use super::*;

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
