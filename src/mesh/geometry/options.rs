//! How to build the marker: structure, bed, axes, mount holes, options.

use super::*;

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

    pub(super) const fn new(index: usize, positive: bool) -> Axis {
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
    /// Camera centres, in the marker frame, of the views of the working
    /// range ([`crate::visibility::clear_views`]): when given, each
    /// [`Structure::Pillars`] support is routed so as to hide as few
    /// spheres from these views as it can (none when some route allows),
    /// instead of keeping clear of the view cone.
    pub working_views: Vec<Vector3<f64>>,
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
            working_views: Vec::new(),
        }
    }
}
