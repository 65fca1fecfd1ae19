//! The layout file (docs/formats.md, "Layout file", contract): named feature
//! points in millimetres, the diameter of the spheres that mark them, and
//! optional `family` and `provenance` records that are kept verbatim.
//!
//! ```json
//! { "name": "biprism-50", "units": "mm",
//!   "points": [ {"name": "O0", "position": [0,0,0]}, {"name": "P1", "position": [0,0,50]} ],
//!   "sphere_diameter_mm": 10,
//!   "family": {"kind": "biprism"}, "provenance": {"seed": 7} }
//! ```
//!
//! * `family` and `provenance` are optional and round-trip as raw JSON.
//! * Each point may carry `sigma_px` (its own pixel noise) and `fixed`
//!   (held in place by a search). Unknown fields are ignored.
//! * `units` must be `"mm"` when given; `name` defaults to the file stem,
//!   `sphere_diameter_mm` to [`DEFAULT_SPHERE_DIAMETER_MM`].
//!
//! Parsing ([`Layout::from_json`], [`Layout::load`]) checks only the file's
//! structure and units; [`Layout::validate`] checks the geometry (enough
//! points, finite, distinct, noncoplanar, spheres apart). A layout can also
//! be imported from an OBJ point set or an OBJ of spheres
//! ([`Layout::from_obj`]).
//!
//! ```
//! use layout_opt::layout::{Layout, LayoutError};
//!
//! let text = r#"{"name": "tetra", "points": [
//!     {"name": "A", "position": [0, 0, 0]}, {"name": "B", "position": [60, 0, 0]},
//!     {"name": "C", "position": [0, 60, 0]}, {"name": "D", "position": [0, 0, 60]}]}"#;
//! let layout = Layout::from_json(text)?;
//! layout.validate()?;
//! assert_eq!(layout.positions().len(), 4);
//! // Coplanar points are refused with a reason.
//! let flat = text.replace("[0, 0, 60]", "[60, 60, 0]");
//! assert!(Layout::from_json(&flat)?.validate().is_err());
//! # Ok::<(), LayoutError>(())
//! ```

use crate::spread::{Spread, DUPLICATE_TOLERANCE, PLANARITY_TOLERANCE};
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};
use serde_json::Value;
use std::path::{Path, PathBuf};

/// The only length unit layout files use.
pub const LAYOUT_UNITS: &str = "mm";
/// Sphere diameter when a file does not give one (the paper's markers), mm.
pub const DEFAULT_SPHERE_DIAMETER_MM: f64 = 10.0;
/// Arm length of the paper's biprism (its Fig. 6), mm.
pub const PAPER_ARM_MM: f64 = 50.0;
/// Fewest feature points a layout may have (PnP needs four).
pub const MIN_POINTS: usize = 4;
/// Objects of an OBJ file count as spheres when the RMS distance of their
/// vertices from the least-squares sphere is at most this fraction of its
/// radius (a meshed sphere's vertices lie on it to rounding).
pub const OBJ_SPHERE_TOLERANCE: f64 = 0.01;
/// A layout imported from OBJ whose points span less than this (mm) is
/// refused with a hint that the file is probably in metres.
pub const OBJ_MIN_SPAN_MM: f64 = 2.0;
/// Fewest vertices an OBJ object needs to be read as a sphere.
pub const OBJ_SPHERE_MIN_VERTICES: usize = 12;

/// Why a layout could not be read or is not usable.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum LayoutError {
    /// The file could not be read or written.
    #[error("cannot {action} layout file {path}: {source}")]
    Io {
        /// "read" or "write".
        action: &'static str,
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// The text is not a layout (bad JSON or missing fields).
    #[error("malformed layout: {0}")]
    Malformed(String),
    /// An OBJ file could not be parsed.
    #[error("cannot read OBJ layout {path}: {message}")]
    Obj {
        /// The file.
        path: PathBuf,
        /// What went wrong.
        message: String,
    },
    /// The file uses a unit other than millimetres.
    #[error("layout units must be \"mm\", got \"{0}\"")]
    Units(String),
    /// Fewer than [`MIN_POINTS`] points.
    #[error("a layout needs at least {MIN_POINTS} points, got {0}")]
    TooFewPoints(usize),
    /// A coordinate or a point's noise is NaN or infinite.
    #[error("point {name} has a non-finite {field}")]
    NonFinite {
        /// The point's name.
        name: String,
        /// "position" or "sigma_px".
        field: &'static str,
    },
    /// A point's noise is zero or negative.
    #[error("point {name} has sigma_px {sigma_px}; it must be positive")]
    NonPositiveSigma {
        /// The point's name.
        name: String,
        /// The value given.
        sigma_px: f64,
    },
    /// Two points share a name.
    #[error("two points are named {0}; names must be unique")]
    DuplicateName(String),
    /// Two points coincide.
    #[error("points {first} and {second} coincide")]
    DuplicatePoints {
        /// Name of the first point.
        first: String,
        /// Name of the second point.
        second: String,
    },
    /// All points lie on one line.
    #[error("the points are collinear; a marker needs a 3D spread")]
    Collinear,
    /// All points lie in one plane.
    #[error("the points are coplanar; a marker needs noncoplanar points")]
    Coplanar,
    /// The sphere diameter is zero, negative or not finite.
    #[error("sphere_diameter_mm must be positive and finite, got {0}")]
    NonPositiveDiameter(f64),
    /// Two spheres intersect: their centres are closer than one diameter.
    #[error("spheres {first} and {second} overlap: centres {distance_mm:.3} mm apart, less than the sphere diameter {diameter_mm} mm")]
    SpheresOverlap {
        /// Name of the first point.
        first: String,
        /// Name of the second point.
        second: String,
        /// Distance between the centres, mm.
        distance_mm: f64,
        /// Sphere diameter, mm.
        diameter_mm: f64,
    },
}

/// One feature point: the centre of a sphere on the marker.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LayoutPoint {
    /// Name, unique within the layout (e.g. "O0", "P1").
    pub name: String,
    /// Position in the marker frame, mm.
    #[serde(with = "vector3_as_array")]
    pub position: Vector3<f64>,
    /// This point's own pixel noise (σ, px), when it differs from the rest.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sigma_px: Option<f64>,
    /// Whether a search must leave this point where it is.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub fixed: bool,
}

impl LayoutPoint {
    /// A free point with no noise of its own.
    pub fn new(name: impl Into<String>, position: Vector3<f64>) -> LayoutPoint {
        LayoutPoint {
            name: name.into(),
            position,
            sigma_px: None,
            fixed: false,
        }
    }
}

/// A marker layout: feature points, the sphere that marks each of them,
/// and where the layout came from.
#[derive(Debug, Clone, PartialEq)]
pub struct Layout {
    /// Name of the layout (used for output file names).
    pub name: String,
    /// The feature points, in file order.
    pub points: Vec<LayoutPoint>,
    /// Diameter of every sphere, mm.
    pub sphere_diameter_mm: f64,
    /// The family and parameters that generated the layout, verbatim.
    pub family: Option<Value>,
    /// How the layout was made (command, seed, objective...), verbatim.
    pub provenance: Option<Value>,
}

/// Serialises in the file format (so a layout can be embedded in reports).
impl Serialize for Layout {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        self.to_file().serialize(s)
    }
}

/// Deserialises from the file format, with the checks and defaults of
/// [`Layout::from_json`].
impl<'de> Deserialize<'de> for Layout {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Layout, D::Error> {
        let file = LayoutFile::deserialize(d)?;
        Layout::from_file(file, "custom").map_err(serde::de::Error::custom)
    }
}

/// The file form of a layout: optional fields get their defaults here.
#[derive(Debug, Deserialize, Serialize)]
struct LayoutFile {
    #[serde(default)]
    name: Option<String>,
    #[serde(default)]
    units: Option<String>,
    points: Vec<LayoutPoint>,
    #[serde(default)]
    sphere_diameter_mm: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    family: Option<Value>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    provenance: Option<Value>,
}

/// How to read a layout from an OBJ file ([`Layout::from_obj`]).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ObjImport {
    /// The sphere diameter, mm. `None`: measured from the spheres when the
    /// OBJ holds spheres, else [`DEFAULT_SPHERE_DIAMETER_MM`].
    pub sphere_diameter_mm: Option<f64>,
    /// The layout's name. `None`: the file stem.
    pub name: Option<String>,
}

/// The paper's biprism (Fig. 6), named and unnamed; they live with the
/// synthetic problems of the solver crate, whose tests solve it.
pub use crate::synthetic::{biprism, biprism_points};

impl Layout {
    /// The paper's biprism (its Fig. 6): O0 at the origin and P1..P6 at
    /// ±[`PAPER_ARM_MM`] on the axes, in the order and with the names of
    /// [`biprism`], with 10 mm spheres.
    pub fn paper_biprism() -> Layout {
        Layout {
            name: "biprism-paper".to_string(),
            points: biprism(PAPER_ARM_MM)
                .into_iter()
                .map(|(name, position)| LayoutPoint::new(name, position))
                .collect(),
            sphere_diameter_mm: DEFAULT_SPHERE_DIAMETER_MM,
            family: Some(serde_json::json!({
                "kind": "biprism",
                "parameters": {"arm_mm": vec![PAPER_ARM_MM; 6], "centre": true}
            })),
            provenance: Some(serde_json::json!({
                "source": "Hu, Li & Tan, Fig. 6 (the paper's biprism)"
            })),
        }
    }

    /// The feature positions, mm, in file order.
    pub fn positions(&self) -> Vec<Vector3<f64>> {
        self.points.iter().map(|p| p.position).collect()
    }

    /// Each point's own pixel noise (σ, px), in file order.
    pub fn point_sigmas(&self) -> Vec<Option<f64>> {
        self.points.iter().map(|p| p.sigma_px).collect()
    }

    /// "characterised from N frames of NOMINAL, residual RMS X px" when
    /// `characterise` measured this layout from images of a printed part
    /// (its provenance says so); `None` for a designed layout.
    pub fn characterised(&self) -> Option<String> {
        let c = self.provenance.as_ref()?.get("characterised")?;
        Some(format!(
            "characterised from {} frames of {}, residual RMS {:.4} px",
            c.get("frames")?.as_u64()?,
            c.get("nominal")?.as_str()?,
            c.get("residual_rms_px")?.as_f64()?
        ))
    }

    /// Each point's 3×3 centre covariance, mm², when `characterise`
    /// measured this layout (its provenance's
    /// `characterised.covariance_mm2`); `None` otherwise or when a point's
    /// is missing or malformed.
    pub fn characterised_covariances(&self) -> Option<Vec<nalgebra::Matrix3<f64>>> {
        let blocks = self
            .provenance
            .as_ref()?
            .get("characterised")?
            .get("covariance_mm2")?;
        self.points
            .iter()
            .map(|p| {
                let rows: [[f64; 3]; 3] =
                    serde_json::from_value(blocks.get(&p.name)?.clone()).ok()?;
                let m = nalgebra::Matrix3::from_fn(|r, c| rows[r][c]);
                m.iter().all(|v| v.is_finite()).then_some(m)
            })
            .collect()
    }

    /// Sphere radius, mm.
    pub fn sphere_radius_mm(&self) -> f64 {
        0.5 * self.sphere_diameter_mm
    }

    /// Parses a layout from JSON text. Checks the structure and the units
    /// only; call [`Layout::validate`] for the geometry. A missing `name`
    /// becomes "custom".
    pub fn from_json(text: &str) -> Result<Layout, LayoutError> {
        Layout::parse(text, "custom")
    }

    fn parse(text: &str, default_name: &str) -> Result<Layout, LayoutError> {
        let file: LayoutFile =
            serde_json::from_str(text).map_err(|e| LayoutError::Malformed(e.to_string()))?;
        Layout::from_file(file, default_name)
    }

    fn from_file(file: LayoutFile, default_name: &str) -> Result<Layout, LayoutError> {
        if let Some(units) = &file.units {
            if units != LAYOUT_UNITS {
                return Err(LayoutError::Units(units.clone()));
            }
        }
        Ok(Layout {
            name: file.name.unwrap_or_else(|| default_name.to_string()),
            points: file.points,
            sphere_diameter_mm: file
                .sphere_diameter_mm
                .unwrap_or(DEFAULT_SPHERE_DIAMETER_MM),
            family: file.family,
            provenance: file.provenance,
        })
    }

    fn to_file(&self) -> LayoutFile {
        LayoutFile {
            name: Some(self.name.clone()),
            units: Some(LAYOUT_UNITS.to_string()),
            points: self.points.clone(),
            sphere_diameter_mm: Some(self.sphere_diameter_mm),
            family: self.family.clone(),
            provenance: self.provenance.clone(),
        }
    }

    /// Reads a layout file (JSON). A missing `name` becomes the file stem.
    /// Checks the structure and units only, like [`Layout::from_json`].
    pub fn load(path: &Path) -> Result<Layout, LayoutError> {
        let text = std::fs::read_to_string(path).map_err(|source| LayoutError::Io {
            action: "read",
            path: path.to_path_buf(),
            source,
        })?;
        Layout::parse(&text, &file_stem(path))
    }

    /// The layout as pretty JSON in the file format.
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(&self.to_file()).expect("a layout always serialises") + "\n"
    }

    /// Writes the layout so that readers never see a partial file: the JSON
    /// goes to a temporary file in the same directory, is flushed to disk,
    /// and is then renamed over `path`.
    pub fn save_atomic(&self, path: &Path) -> Result<(), LayoutError> {
        crate::files::write_atomic(path, self.to_json().as_bytes()).map_err(|source| {
            LayoutError::Io {
                action: "write",
                path: path.to_path_buf(),
                source,
            }
        })
    }

    /// Checks the geometry: at least [`MIN_POINTS`] points with unique
    /// names, finite coordinates (and positive `sigma_px` where given), no
    /// duplicates, not collinear or coplanar (relative to the spread, with
    /// [`PLANARITY_TOLERANCE`] as the PnP solvers use), a positive sphere
    /// diameter, and no two spheres overlapping (centres closer than one
    /// diameter).
    pub fn validate(&self) -> Result<(), LayoutError> {
        if self.points.len() < MIN_POINTS {
            return Err(LayoutError::TooFewPoints(self.points.len()));
        }
        for point in &self.points {
            if !point.position.iter().all(|v| v.is_finite()) {
                return Err(LayoutError::NonFinite {
                    name: point.name.clone(),
                    field: "position",
                });
            }
            if let Some(sigma_px) = point.sigma_px {
                if !sigma_px.is_finite() {
                    return Err(LayoutError::NonFinite {
                        name: point.name.clone(),
                        field: "sigma_px",
                    });
                }
                if sigma_px <= 0.0 {
                    return Err(LayoutError::NonPositiveSigma {
                        name: point.name.clone(),
                        sigma_px,
                    });
                }
            }
        }
        let mut names: Vec<&str> = self.points.iter().map(|p| p.name.as_str()).collect();
        names.sort_unstable();
        if let Some(pair) = names.windows(2).find(|pair| pair[0] == pair[1]) {
            return Err(LayoutError::DuplicateName(pair[0].to_string()));
        }
        if !(self.sphere_diameter_mm.is_finite() && self.sphere_diameter_mm > 0.0) {
            return Err(LayoutError::NonPositiveDiameter(self.sphere_diameter_mm));
        }
        let positions = self.positions();
        let spread = Spread::of(&positions);
        let scale = spread.extents[0];
        let duplicate_distance = DUPLICATE_TOLERANCE * scale;
        for (i, a) in self.points.iter().enumerate() {
            for b in &self.points[i + 1..] {
                if (a.position - b.position).norm() <= duplicate_distance {
                    return Err(LayoutError::DuplicatePoints {
                        first: a.name.clone(),
                        second: b.name.clone(),
                    });
                }
            }
        }
        if spread.extents[1] <= PLANARITY_TOLERANCE * scale {
            return Err(LayoutError::Collinear);
        }
        if spread.extents[2] <= PLANARITY_TOLERANCE * scale {
            return Err(LayoutError::Coplanar);
        }
        for (i, a) in self.points.iter().enumerate() {
            for b in &self.points[i + 1..] {
                let distance_mm = (a.position - b.position).norm();
                if distance_mm < self.sphere_diameter_mm {
                    return Err(LayoutError::SpheresOverlap {
                        first: a.name.clone(),
                        second: b.name.clone(),
                        distance_mm,
                        diameter_mm: self.sphere_diameter_mm,
                    });
                }
            }
        }
        Ok(())
    }

    /// Imports a layout from an OBJ file with `tobj`.
    ///
    /// * A file with faces is a set of meshed spheres: every object must be
    ///   one ([`fit_sphere`]: the least-squares sphere through its
    ///   vertices, whose RMS residual must be at most
    ///   [`OBJ_SPHERE_TOLERANCE`] of its radius), and becomes a feature
    ///   point at the sphere's centre, named after the object; the diameter
    ///   is measured (the mean) unless `options` gives one. An object that is
    ///   not a sphere, or has no faces, is an error that names it.
    /// * A file without faces is a point set: every distinct vertex (`v`
    ///   line) becomes a feature point `V1, V2, ...` in file order.
    ///
    /// Coordinates are taken as millimetres; points spanning less than
    /// [`OBJ_MIN_SPAN_MM`] are refused with a hint that the file is
    /// probably in metres. The result is not validated.
    pub fn from_obj(path: &Path, options: &ObjImport) -> Result<Layout, LayoutError> {
        let obj_error = |message: String| LayoutError::Obj {
            path: path.to_path_buf(),
            message,
        };
        let text = std::fs::read_to_string(path).map_err(|source| LayoutError::Io {
            action: "read",
            path: path.to_path_buf(),
            source,
        })?;
        let load_options = tobj::LoadOptions {
            single_index: true,
            triangulate: false,
            ignore_points: false,
            ignore_lines: false,
        };
        let load = |text: &str| {
            tobj::load_obj_buf(&mut text.as_bytes(), &load_options, |_| {
                Ok(Default::default())
            })
            .map(|(models, _)| models)
            .map_err(|e| obj_error(e.to_string()))
        };
        let mut models = load(&text)?;
        if models.iter().all(|m| m.mesh.positions.is_empty()) {
            // A bare point set: tobj keeps only the vertices that elements
            // use (and skips `p` elements), so give each `v` a one-vertex
            // element, which tobj reads as a point.
            let count = text
                .lines()
                .filter(|line| line.split_whitespace().next() == Some("v"))
                .count();
            if count == 0 {
                return Err(obj_error("it has no vertices".to_string()));
            }
            let mut with_points = text.clone();
            with_points.push_str("\no points\n");
            for i in 1..=count {
                with_points.push_str(&format!("l {i}\n"));
            }
            models = load(&with_points)?;
        }
        let name = options.name.clone().unwrap_or_else(|| file_stem(path));
        let (points, diameter): (Vec<LayoutPoint>, f64) = if models.iter().any(has_faces) {
            let mut spheres: Vec<(String, Vector3<f64>, f64)> = Vec::with_capacity(models.len());
            for (k, model) in models.iter().enumerate() {
                let label = if model.name.is_empty() {
                    format!("object {}", k + 1)
                } else {
                    format!("object '{}'", model.name)
                };
                if !has_faces(model) {
                    return Err(obj_error(format!(
                        "{label} has no faces while others do: a file is read either as meshed spheres (every object one sphere) or, without faces, as a point set"
                    )));
                }
                let vertices = distinct_vertices(std::slice::from_ref(model));
                let fit = fit_sphere(&vertices).ok_or_else(|| {
                    obj_error(format!(
                        "{label} is not a sphere: no sphere fits its {} vertices (a sphere needs at least {OBJ_SPHERE_MIN_VERTICES}, not all on one plane)",
                        vertices.len()
                    ))
                })?;
                if fit.rms_residual_mm > OBJ_SPHERE_TOLERANCE * fit.radius_mm {
                    return Err(obj_error(format!(
                        "{label} is not a sphere: its vertices lie {:.3} mm (RMS) from the best-fitting sphere of radius {:.3} mm, more than {}% of it",
                        fit.rms_residual_mm,
                        fit.radius_mm,
                        100.0 * OBJ_SPHERE_TOLERANCE
                    )));
                }
                spheres.push((model.name.clone(), fit.centre, fit.radius_mm));
            }
            let mean_radius = spheres.iter().map(|(_, _, r)| r).sum::<f64>() / spheres.len() as f64;
            let points = spheres
                .into_iter()
                .map(|(name, centre, _)| LayoutPoint::new(name, centre))
                .collect();
            (
                points,
                options.sphere_diameter_mm.unwrap_or(2.0 * mean_radius),
            )
        } else {
            let points = distinct_vertices(&models)
                .into_iter()
                .enumerate()
                .map(|(i, p)| LayoutPoint::new(format!("V{}", i + 1), p))
                .collect();
            (
                points,
                options
                    .sphere_diameter_mm
                    .unwrap_or(DEFAULT_SPHERE_DIAMETER_MM),
            )
        };
        let positions: Vec<Vector3<f64>> = points.iter().map(|p| p.position).collect();
        let span = positions
            .iter()
            .flat_map(|a| positions.iter().map(move |b| (a - b).norm()))
            .fold(0.0, f64::max);
        if positions.len() > 1 && span < OBJ_MIN_SPAN_MM {
            return Err(obj_error(format!(
                "its points span only {span:.4} mm; OBJ layouts are read in millimetres, so a file in metres must be scaled by 1000 first"
            )));
        }
        Ok(Layout {
            name,
            points,
            sphere_diameter_mm: diameter,
            family: None,
            provenance: Some(serde_json::json!({"imported_from": path.display().to_string()})),
        })
    }
}

/// Whether an OBJ object has polygons (tobj leaves `face_arities` empty
/// when every element is a triangle).
fn has_faces(model: &tobj::Model) -> bool {
    let arities = &model.mesh.face_arities;
    if arities.is_empty() {
        model.mesh.indices.len() >= 3
    } else {
        arities.iter().any(|&a| a >= 3)
    }
}

/// The distinct vertices of `models`, in file order.
fn distinct_vertices(models: &[tobj::Model]) -> Vec<Vector3<f64>> {
    let mut vertices: Vec<Vector3<f64>> = Vec::new();
    for model in models {
        for chunk in model.mesh.positions.chunks_exact(3) {
            let p = Vector3::new(chunk[0] as f64, chunk[1] as f64, chunk[2] as f64);
            if !vertices.contains(&p) {
                vertices.push(p);
            }
        }
    }
    vertices
}

/// A sphere fitted to points ([`fit_sphere`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SphereFit {
    /// The centre, mm.
    pub centre: Vector3<f64>,
    /// The radius, mm.
    pub radius_mm: f64,
    /// RMS distance of the points from the sphere, mm.
    pub rms_residual_mm: f64,
}

/// The least-squares sphere through `points`: the algebraic fit
/// `|p|² = 2 c·p + k` (linear in the centre c and `k = r² − |c|²`, solved
/// about the points' centroid for conditioning), which is exact for points
/// on a sphere however they are spread over it, unlike their centroid. `None`
/// with fewer than [`OBJ_SPHERE_MIN_VERTICES`] points or when they do not
/// determine a sphere (all on one plane or line).
pub fn fit_sphere(points: &[Vector3<f64>]) -> Option<SphereFit> {
    if points.len() < OBJ_SPHERE_MIN_VERTICES {
        return None;
    }
    let mean = points.iter().sum::<Vector3<f64>>() / points.len() as f64;
    let mut normal = nalgebra::Matrix4::<f64>::zeros();
    let mut rhs = nalgebra::Vector4::<f64>::zeros();
    for p in points {
        let q = p - mean;
        let row = nalgebra::Vector4::new(2.0 * q.x, 2.0 * q.y, 2.0 * q.z, 1.0);
        normal += row * row.transpose();
        rhs += row * q.norm_squared();
    }
    let solution = crate::linalg::solve_positive_definite(&normal, &rhs)?;
    let offset = Vector3::new(solution[0], solution[1], solution[2]);
    let radius_sq = solution[3] + offset.norm_squared();
    if !(radius_sq > 0.0 && radius_sq.is_finite()) {
        return None;
    }
    let radius_mm = radius_sq.sqrt();
    let centre = mean + offset;
    let rms_residual_mm = (points
        .iter()
        .map(|p| ((p - centre).norm() - radius_mm).powi(2))
        .sum::<f64>()
        / points.len() as f64)
        .sqrt();
    Some(SphereFit {
        centre,
        radius_mm,
        rms_residual_mm,
    })
}

fn file_stem(path: &Path) -> String {
    path.file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "custom".to_string())
}

/// Serialises a `Vector3<f64>` as a plain `[x, y, z]` array.
mod vector3_as_array {
    use nalgebra::Vector3;
    use serde::{Deserialize, Deserializer, Serialize, Serializer};

    pub fn serialize<S: Serializer>(v: &Vector3<f64>, s: S) -> Result<S::Ok, S::Error> {
        [v.x, v.y, v.z].serialize(s)
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Vector3<f64>, D::Error> {
        let [x, y, z] = <[f64; 3]>::deserialize(d)?;
        Ok(Vector3::new(x, y, z))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tetra() -> Layout {
        Layout {
            name: "t".into(),
            points: vec![
                LayoutPoint::new("A", Vector3::new(0.0, 0.0, 0.0)),
                LayoutPoint::new("B", Vector3::new(40.0, 0.0, 0.0)),
                LayoutPoint::new("C", Vector3::new(0.0, 40.0, 0.0)),
                LayoutPoint::new("D", Vector3::new(0.0, 0.0, 40.0)),
            ],
            sphere_diameter_mm: 10.0,
            family: None,
            provenance: None,
        }
    }

    #[test]
    fn paper_biprism_is_valid_and_drawn_as_in_the_paper() {
        let layout = Layout::paper_biprism();
        layout.validate().unwrap();
        let names: Vec<&str> = layout.points.iter().map(|p| p.name.as_str()).collect();
        assert_eq!(names, ["O0", "P1", "P2", "P3", "P4", "P5", "P6"]);
        // O0P1 = +z, O0P2 = +x, O0P5 = +y, each PAPER_ARM_MM long, and the
        // opposite vertices mirror them through O0.
        let p = layout.positions();
        assert_eq!(p[0], Vector3::zeros());
        assert_eq!(p[1], Vector3::z() * PAPER_ARM_MM);
        assert_eq!(p[2], Vector3::x() * PAPER_ARM_MM);
        assert_eq!(p[5], Vector3::y() * PAPER_ARM_MM);
        for (a, b) in [(1, 3), (2, 4), (5, 6)] {
            assert_eq!(p[a], -p[b]);
        }
    }

    #[test]
    fn json_round_trip_keeps_everything() {
        let text = r#"{"name": "x", "units": "mm", "points": [
            {"name": "A", "position": [0,0,0], "sigma_px": 0.3, "colour": "red"},
            {"name": "B", "position": [40,0,0], "fixed": true},
            {"name": "C", "position": [0,40,0]},
            {"name": "D", "position": [0,0,40]}],
            "sphere_diameter_mm": 8, "family": {"kind": "custom", "n": [1,2]},
            "provenance": {"seed": 7}, "comment": "ignored"}"#;
        let layout = Layout::from_json(text).unwrap();
        assert_eq!(layout.points[0].sigma_px, Some(0.3));
        assert!(layout.points[1].fixed);
        assert_eq!(layout.sphere_diameter_mm, 8.0);
        let again = Layout::from_json(&layout.to_json()).unwrap();
        assert_eq!(again, layout);
        assert!(layout.to_json().contains("\"units\": \"mm\""));
    }

    #[test]
    fn embeds_in_other_json_through_serde() {
        let layout = Layout::paper_biprism();
        let wrapped = serde_json::json!({ "layout": layout });
        assert_eq!(wrapped["layout"]["units"], "mm");
        let back: Layout = serde_json::from_value(wrapped["layout"].clone()).unwrap();
        assert_eq!(back, layout);
        let bad = serde_json::json!({"units": "cm", "points": []});
        let e = serde_json::from_value::<Layout>(bad).unwrap_err();
        assert!(e.to_string().contains("layout units must be \"mm\""), "{e}");
    }

    #[test]
    fn minimal_file_needs_only_points() {
        let layout = Layout::from_json(
            r#"{"points": [{"name":"A","position":[0,0,0]},{"name":"B","position":[40,0,0]},
            {"name":"C","position":[0,40,0]},{"name":"D","position":[0,0,40]}]}"#,
        )
        .unwrap();
        assert_eq!(layout.name, "custom");
        assert_eq!(layout.sphere_diameter_mm, DEFAULT_SPHERE_DIAMETER_MM);
        layout.validate().unwrap();
    }

    #[test]
    fn error_messages() {
        let e = Layout::from_json(r#"{"units": "inch", "points": []}"#).unwrap_err();
        assert_eq!(e.to_string(), "layout units must be \"mm\", got \"inch\"");
        let e = Layout::from_json("{").unwrap_err();
        assert!(e.to_string().starts_with("malformed layout: "), "{e}");

        let mut layout = tetra();
        layout.points.pop();
        assert_eq!(
            layout.validate().unwrap_err().to_string(),
            "a layout needs at least 4 points, got 3"
        );

        let mut layout = tetra();
        layout.points[2].position.y = f64::NAN;
        assert_eq!(
            layout.validate().unwrap_err().to_string(),
            "point C has a non-finite position"
        );

        let mut layout = tetra();
        layout.points[1].sigma_px = Some(0.0);
        assert_eq!(
            layout.validate().unwrap_err().to_string(),
            "point B has sigma_px 0; it must be positive"
        );

        let mut layout = tetra();
        layout.points[3].name = "A".into();
        assert_eq!(
            layout.validate().unwrap_err().to_string(),
            "two points are named A; names must be unique"
        );

        let mut layout = tetra();
        layout.points[3].position = layout.points[1].position;
        assert_eq!(
            layout.validate().unwrap_err().to_string(),
            "points B and D coincide"
        );

        let mut layout = tetra();
        layout.points[3].position = Vector3::new(40.0, 40.0, 0.0);
        assert_eq!(
            layout.validate().unwrap_err().to_string(),
            "the points are coplanar; a marker needs noncoplanar points"
        );

        let mut layout = tetra();
        for (i, p) in layout.points.iter_mut().enumerate() {
            p.position = Vector3::new(20.0 * i as f64, 0.0, 0.0);
        }
        assert_eq!(
            layout.validate().unwrap_err().to_string(),
            "the points are collinear; a marker needs a 3D spread"
        );

        let mut layout = tetra();
        layout.sphere_diameter_mm = 0.0;
        assert_eq!(
            layout.validate().unwrap_err().to_string(),
            "sphere_diameter_mm must be positive and finite, got 0"
        );

        let mut layout = tetra();
        layout.points[1].position.x = 9.0;
        assert_eq!(
            layout.validate().unwrap_err().to_string(),
            "spheres A and B overlap: centres 9.000 mm apart, less than the sphere diameter 10 mm"
        );
    }

    #[test]
    fn save_atomic_then_load() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("m.json");
        let layout = Layout::paper_biprism();
        layout.save_atomic(&path).unwrap();
        layout.save_atomic(&path).unwrap();
        assert_eq!(Layout::load(&path).unwrap(), layout);
        let leftovers: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
        assert_eq!(leftovers.len(), 1, "no temporary file is left behind");
    }

    const ICOSAHEDRON_FACES: [[usize; 3]; 20] = [
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];

    #[test]
    fn obj_point_set_and_spheres() {
        let dir = tempfile::tempdir().unwrap();
        let points = dir.path().join("points.obj");
        std::fs::write(
            &points,
            "# four points\nv 0 0 0\nv 40 0 0\nv 0 40 0\nv 0 0 40\n",
        )
        .unwrap();
        let layout = Layout::from_obj(&points, &ObjImport::default()).unwrap();
        assert_eq!(layout.name, "points");
        assert_eq!(layout.points.len(), 4);
        assert_eq!(layout.points[3].name, "V4");
        assert_eq!(layout.points[1].position, Vector3::new(40.0, 0.0, 0.0));
        layout.validate().unwrap();

        // Four "spheres" (icosahedra of radius 4) as separate objects.
        let mut text = String::new();
        let mut base = 0;
        let phi = (1.0 + 5f64.sqrt()) / 2.0;
        let ico: Vec<[f64; 3]> = [
            [-1.0, phi, 0.0],
            [1.0, phi, 0.0],
            [-1.0, -phi, 0.0],
            [1.0, -phi, 0.0],
            [0.0, -1.0, phi],
            [0.0, 1.0, phi],
            [0.0, -1.0, -phi],
            [0.0, 1.0, -phi],
            [phi, 0.0, -1.0],
            [phi, 0.0, 1.0],
            [-phi, 0.0, -1.0],
            [-phi, 0.0, 1.0],
        ]
        .to_vec();
        let scale = 4.0 / (1.0 + phi * phi).sqrt();
        for (name, centre) in [
            ("A", [0.0, 0.0, 0.0]),
            ("B", [40.0, 0.0, 0.0]),
            ("C", [0.0, 40.0, 0.0]),
            ("D", [0.0, 0.0, 40.0]),
        ] {
            text += &format!("o {name}\n");
            for v in &ico {
                text += &format!(
                    "v {} {} {}\n",
                    centre[0] + scale * v[0],
                    centre[1] + scale * v[1],
                    centre[2] + scale * v[2]
                );
            }
            for face in ICOSAHEDRON_FACES {
                text += &format!(
                    "f {} {} {}\n",
                    base + face[0] + 1,
                    base + face[1] + 1,
                    base + face[2] + 1
                );
            }
            base += 12;
        }
        let spheres = dir.path().join("spheres.obj");
        std::fs::write(&spheres, text).unwrap();
        let layout = Layout::from_obj(&spheres, &ObjImport::default()).unwrap();
        assert_eq!(layout.points.len(), 4);
        assert_eq!(layout.points[1].name, "B");
        assert!((layout.points[1].position - Vector3::new(40.0, 0.0, 0.0)).norm() < 1e-5);
        assert!((layout.sphere_diameter_mm - 8.0).abs() < 1e-5);
    }

    /// OBJ text for one object: `vertices`, and faces that use them (a fan;
    /// the import reads vertices, the faces only mark a mesh).
    fn obj_object(name: &str, vertices: &[Vector3<f64>], base: usize) -> String {
        let mut text = format!("o {name}\n");
        for v in vertices {
            text += &format!("v {} {} {}\n", v.x, v.y, v.z);
        }
        for k in 1..vertices.len() - 1 {
            text += &format!("f {} {} {}\n", base + 1, base + k + 1, base + k + 2);
        }
        text
    }

    /// Points on the sphere (centre, radius), crowded towards its +z pole:
    /// their centroid is pulled towards the pole, the fitted centre is not.
    fn lopsided_sphere(centre: Vector3<f64>, radius: f64) -> Vec<Vector3<f64>> {
        let mut points = Vec::new();
        for ring in 1..12 {
            // Polar angles squeezed towards 0.
            let polar = std::f64::consts::PI * (ring as f64 / 12.0).powi(2);
            for k in 0..8 {
                let azimuth = std::f64::consts::TAU * k as f64 / 8.0;
                points.push(
                    centre
                        + radius
                            * Vector3::new(
                                polar.sin() * azimuth.cos(),
                                polar.sin() * azimuth.sin(),
                                polar.cos(),
                            ),
                );
            }
        }
        points
    }

    #[test]
    fn obj_spheres_are_fitted_and_other_objects_refused_by_name() {
        let dir = tempfile::tempdir().unwrap();
        let centres = [
            Vector3::new(0.0, 0.0, 0.0),
            Vector3::new(40.0, 0.0, 0.0),
            Vector3::new(0.0, 40.0, 0.0),
            Vector3::new(0.0, 0.0, 40.0),
        ];
        let mut text = String::new();
        let mut base = 0;
        let mut all = Vec::new();
        for (k, centre) in centres.iter().enumerate() {
            let vertices = lopsided_sphere(*centre, 5.0);
            text += &obj_object(&format!("S{k}"), &vertices, base);
            base += vertices.len();
            all.push(vertices);
        }
        let path = dir.path().join("lopsided.obj");
        std::fs::write(&path, &text).unwrap();
        let layout = Layout::from_obj(&path, &ObjImport::default()).unwrap();
        for (point, (centre, vertices)) in layout.points.iter().zip(centres.iter().zip(&all)) {
            // Exact to the file's printed precision, where the vertex
            // centroid is off by more than a millimetre.
            assert!((point.position - centre).norm() < 1e-6, "{point:?}");
            let centroid = vertices.iter().sum::<Vector3<f64>>() / vertices.len() as f64;
            assert!((centroid - centre).norm() > 1.0);
        }
        assert!((layout.sphere_diameter_mm - 10.0).abs() < 1e-6);
        layout.validate().unwrap();

        // An ellipsoid among the spheres is named in the error.
        let ellipsoid: Vec<Vector3<f64>> = lopsided_sphere(Vector3::zeros(), 5.0)
            .iter()
            .map(|p| Vector3::new(3.0 * p.x, p.y, p.z) + Vector3::new(80.0, 0.0, 0.0))
            .collect();
        let with_ellipsoid = text.clone() + &obj_object("Egg", &ellipsoid, base);
        std::fs::write(&path, with_ellipsoid).unwrap();
        let error = Layout::from_obj(&path, &ObjImport::default()).unwrap_err();
        assert!(
            error.to_string().contains("object 'Egg' is not a sphere"),
            "{error}"
        );

        // A point set only when there are no faces: a faceless object among
        // meshed ones is an error, not a silent re-read as points.
        let with_points =
            text + &format!("o Loose\nv 1 2 3\nv 4 5 6\nl {} {}\n", base + 1, base + 2);
        std::fs::write(&path, with_points).unwrap();
        let error = Layout::from_obj(&path, &ObjImport::default()).unwrap_err();
        assert!(
            error.to_string().contains("object 'Loose' has no faces"),
            "{error}"
        );

        // Coordinates in metres get a hint.
        let metres = dir.path().join("metres.obj");
        std::fs::write(&metres, "v 0 0 0\nv 0.04 0 0\nv 0 0.04 0\nv 0 0 0.04\n").unwrap();
        let error = Layout::from_obj(&metres, &ObjImport::default()).unwrap_err();
        assert!(error.to_string().contains("metres"), "{error}");
    }

    #[test]
    fn sphere_fit_needs_enough_points_off_a_plane() {
        let on_sphere = lopsided_sphere(Vector3::new(1.0, -2.0, 3.0), 7.0);
        let fit = fit_sphere(&on_sphere).unwrap();
        assert!((fit.centre - Vector3::new(1.0, -2.0, 3.0)).norm() < 1e-9);
        assert!((fit.radius_mm - 7.0).abs() < 1e-9);
        assert!(fit.rms_residual_mm < 1e-9);
        assert!(fit_sphere(&on_sphere[..OBJ_SPHERE_MIN_VERTICES - 1]).is_none());
        let planar: Vec<Vector3<f64>> = (0..20)
            .map(|k| Vector3::new(k as f64, (k * k) as f64, 0.0))
            .collect();
        assert!(fit_sphere(&planar).is_none());
    }
}
