//! Printable marker meshes (docs/formats.md, "Report files", `export`): one
//! watertight, outward-wound, manifold solid — a sphere per feature point
//! on a support rising from a base plate behind them all, which prints
//! without support material standing on the plate
//! ([`geometry::Structure::Pillars`]; the earlier strut tree is
//! [`geometry::Structure::Routed`]) — written as STL, OBJ, glTF or GLB,
//! with a fabrication sheet, and checked by ray casting over a cone of
//! viewing directions ([`quality::view_coverage`]) and for overhangs
//! ([`quality::overhang`]).
//!
//! The pipeline ([`build`], [`analysis::analyse`], then
//! [`workflow::export`]):
//! 1. [`geometry::Marker::design`] routes the struts and checks every
//!    clearance; the solid is the zero sublevel set of an analytic signed
//!    distance ([`geometry`], [`sdf`]).
//! 2. [`extract::extract`] meshes it with Surface Nets and moves every
//!    vertex onto the exact surface; [`repair`] removes slivers.
//! 3. The mesh is checked ([`trimesh::Topology`]): closed, consistently
//!    wound, manifold, one body, positive volume, no degenerate faces, and
//!    Euler characteristic 2 − 2·(screw holes). A mesh that fails is an
//!    error, never a file.
//! 4. One writer per format ([`MeshWriter`]) and the sheet ([`sheet`]).
//!
//! **Frames.** Sphere centres sit exactly at the layout's coordinates (mm)
//! in the marker frame.
//! * OBJ: the marker frame, millimetres.
//! * STL: the print frame ([`Marker::print_transform`]): millimetres,
//!   Z up, [`Marker::down`] (the view for pillars, the mount axis for the
//!   routed structure) pointing onto the bed, the bed face at z = 0; a
//!   rotation of the marker frame and a shift along Z.
//! * glTF / GLB: metres, Y up ([`geometry::gltf_rotation`]): the print
//!   frame turned Y-up (without the shift), so again [`Marker::down`]
//!   points down; for a routed part with mount −y this is the marker frame
//!   itself, scaled to metres.
//!
//! ```
//! use layout_opt::layout::Layout;
//! use layout_opt::mesh::{build, ExportOptions};
//!
//! let solid = build(&Layout::paper_biprism(), &ExportOptions::default())?;
//! let topology = &solid.report.topology;
//! // One closed, manifold body, within a fraction of a millimetre of the
//! // exact surface.
//! assert_eq!(topology.boundary_edges, 0);
//! assert_eq!(topology.non_manifold_edges, 0);
//! assert!(solid.report.max_surface_error_mm < 0.1);
//! # Ok::<(), layout_opt::mesh::ExportError>(())
//! ```

pub mod analysis;
pub mod error;
pub(crate) mod extract;
pub mod format;
pub mod geometry;
pub(crate) mod gltf;
pub(crate) mod obj;
pub mod quality;
pub(crate) mod repair;
pub(crate) mod sdf;
pub mod set_workflow;
pub mod sheet;
pub(crate) mod stl;
pub mod summary;
pub(crate) mod threemf;
pub mod tolerance;
pub mod trimesh;
pub mod view_cone;
pub mod workflow;

pub use error::ExportError;
pub use format::Format;
pub use geometry::{
    marker_for_range, routed_as_recorded, straight_supports, supports_for_range, Axis,
    GeometryError, Marker, MarkerOptions, MountHoles,
};
pub use tolerance::{datum_positions, Datum, DatumPosition, Tolerances};
pub use trimesh::{Topology, TriangleMesh};

use crate::layout::Layout;
use crate::visibility::WorkingRange;
use nalgebra::Vector3;
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Grid spacing when none is asked for (and the features allow it), mm.
pub const DEFAULT_RESOLUTION_MM: f64 = 0.5;
/// The grid spacing may be at most this fraction of the finest feature
/// (strut radius, fillet radius, hole radius, minimum feature).
pub const RESOLUTION_PER_FEATURE: f64 = 0.5;

/// A writer of one mesh format.
pub trait MeshWriter: Sync {
    /// The format it writes.
    fn format(&self) -> Format;
    /// Writes `solid` into `dir` as `<name>.<extension>` (and any companion
    /// files); returns the files written.
    fn write(&self, solid: &Solid, dir: &Path) -> Result<Vec<PathBuf>, ExportError>;
}

/// Everything an export needs besides the layout.
#[derive(Debug, Clone, PartialEq)]
pub struct ExportOptions {
    /// Formats to write.
    pub formats: Vec<Format>,
    /// Struts, clearances, view and mount.
    pub marker: MarkerOptions,
    /// Grid spacing, mm; `None`: [`DEFAULT_RESOLUTION_MM`], or finer when
    /// a feature needs it.
    pub resolution_mm: Option<f64>,
    /// Write the files even when a strut covers a sphere from the view
    /// cone (else that is [`ExportError::Occluded`]).
    pub allow_occlusion: bool,
    /// The working range the supports are routed for
    /// ([`MarkerOptions::working_views`]); its views that the supports
    /// still lose are reported ([`analysis::ExportReport::lost_views`]) instead of
    /// checking the view cone.
    pub working_range: Option<WorkingRange>,
}

impl Default for ExportOptions {
    fn default() -> Self {
        ExportOptions {
            formats: Format::ALL.to_vec(),
            marker: MarkerOptions::default(),
            resolution_mm: None,
            allow_occlusion: false,
            working_range: None,
        }
    }
}

/// Soundness and accuracy figures of a mesh.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MeshReport {
    /// Grid spacing used, mm.
    pub resolution_mm: f64,
    /// Topology counts.
    pub topology: Topology,
    /// Largest distance of a face from the exact surface, mm.
    pub max_surface_error_mm: f64,
    /// Faces pointing against the surface normal.
    pub inverted_faces: usize,
    /// Screw holes through the plate (each lowers χ by 2).
    pub holes: usize,
    /// The Euler characteristic a sound mesh must have: 2 − 2·holes.
    pub expected_euler_characteristic: i64,
    /// Axis-aligned bounds of the mesh in the marker frame, mm.
    pub bounds_mm: [[f64; 3]; 2],
    /// Wall time of design + meshing + checks, seconds.
    pub seconds: f64,
}

/// A built marker: its design, its checked mesh (marker frame, mm) and
/// the vertex normals.
#[derive(Debug, Clone)]
pub struct Solid {
    /// The design the mesh was made from.
    pub marker: Marker,
    /// The mesh, marker frame, mm, outward-wound.
    pub mesh: TriangleMesh,
    /// Unit outward vertex normals (the field's gradient).
    pub normals: Vec<Vector3<f64>>,
    /// Soundness and accuracy.
    pub report: MeshReport,
}

impl Solid {
    /// The marker → STL (print) frame motion `p ↦ R·p + shift`: the
    /// rotation [`geometry::print_rotation`] of the axis that points onto
    /// the bed, then a shift along Z that puts the bed face at z = 0
    /// ([`Marker::bed_face_level`]).
    pub fn print_transform(&self) -> (nalgebra::Matrix3<f64>, Vector3<f64>) {
        self.marker.print_transform()
    }

    /// The layout's name as used in file names: characters other than
    /// ASCII letters, digits, `.`, `_` and `-` become `_`.
    pub fn name(&self) -> String {
        file_stem(&self.marker.name)
    }
}

/// A layout name made safe for file names (and glTF buffer URIs).
pub fn file_stem(name: &str) -> String {
    let stem: String = name
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || matches!(c, '.' | '_' | '-') {
                c
            } else {
                '_'
            }
        })
        .collect();
    if stem.is_empty() || stem.starts_with('.') {
        format!("marker{stem}")
    } else {
        stem
    }
}

/// The resolution to use: the one asked for (checked against the finest
/// feature), else [`DEFAULT_RESOLUTION_MM`] or finer.
pub fn resolution_for(marker: &Marker, asked_mm: Option<f64>) -> Result<f64, ExportError> {
    let finest_mm = marker.finest_feature_mm();
    let max_mm = RESOLUTION_PER_FEATURE * finest_mm;
    match asked_mm {
        None => Ok(DEFAULT_RESOLUTION_MM.min(max_mm)),
        Some(r) if !(r.is_finite() && r > 0.0) => Err(ExportError::BadResolution(r)),
        Some(r) if r > max_mm * (1.0 + 1e-12) => Err(ExportError::ResolutionTooCoarse {
            resolution_mm: r,
            finest_mm,
            max_mm,
        }),
        Some(r) => Ok(r),
    }
}

/// Designs and meshes the marker for `layout`, and checks the mesh.
pub fn build(layout: &Layout, options: &ExportOptions) -> Result<Solid, ExportError> {
    build_numbered(layout, options, None)
}

/// [`build`], with `number` (digits) engraved into the base plate when
/// given ([`Marker::engrave`]).
pub fn build_numbered(
    layout: &Layout,
    options: &ExportOptions,
    number: Option<&str>,
) -> Result<Solid, ExportError> {
    let start = Instant::now();
    let mut marker = match &options.working_range {
        Some(range) => marker_for_range(layout, &options.marker, range)?,
        None => Marker::design(layout, &options.marker)?,
    };
    if let Some(number) = number {
        marker.engrave(number, &options.marker.bed)?;
    }
    let resolution_mm = resolution_for(&marker, options.resolution_mm)?;
    let mesh = extract::extract(&marker, resolution_mm);
    let topology = mesh.topology();
    let holes = marker.plate.holes.len();
    let expected_euler_characteristic = 2 - 2 * holes as i64;
    let inverted_faces = quality::inverted_faces(&marker, &mesh);
    let mut problems = Vec::new();
    let mut count = |n: usize, what: &str| {
        if n > 0 {
            problems.push(format!("{n} {what}"));
        }
    };
    count(topology.boundary_edges, "open edges");
    count(
        topology.non_manifold_edges,
        "edges shared by more than two faces",
    );
    count(topology.misoriented_edges, "inconsistently wound edges");
    count(topology.non_manifold_vertices, "pinched vertices");
    count(topology.degenerate_faces, "degenerate faces");
    count(inverted_faces, "inverted faces");
    if topology.components != 1 {
        problems.push(format!("{} separate bodies", topology.components));
    }
    if topology.signed_volume_mm3 <= 0.0 {
        problems.push("non-positive volume".to_string());
    }
    if topology.euler_characteristic != expected_euler_characteristic {
        problems.push(format!(
            "Euler characteristic {} instead of {expected_euler_characteristic}",
            topology.euler_characteristic
        ));
    }
    if !problems.is_empty() {
        return Err(ExportError::NotWatertight(problems.join(", ")));
    }
    let max_surface_error_mm = quality::max_surface_error(&marker, &mesh);
    let normals = quality::vertex_normals(&marker, &mesh);
    let (lo, hi) = mesh.bounds();
    Ok(Solid {
        report: MeshReport {
            resolution_mm,
            topology,
            max_surface_error_mm,
            inverted_faces,
            holes,
            expected_euler_characteristic,
            bounds_mm: [lo.into(), hi.into()],
            seconds: start.elapsed().as_secs_f64(),
        },
        marker,
        mesh,
        normals,
    })
}

/// Writes a whole file atomically, mapping errors to [`ExportError::Io`].
pub(crate) fn write_file(path: &Path, bytes: &[u8]) -> Result<(), ExportError> {
    crate::files::write_atomic(path, bytes).map_err(|source| ExportError::Io {
        path: path.to_path_buf(),
        source,
    })
}
