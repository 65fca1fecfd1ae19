//! Why an export fails: the one error of building, checking and writing a
//! printable part.

use super::geometry::{Axis, GeometryError};
use std::path::PathBuf;

/// Why an export failed.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ExportError {
    /// The observer asked to stop (Ctrl-C); none of the export's files
    /// were left.
    #[error("export interrupted; none of its files were written")]
    Interrupted,
    /// The output directory was refused (it is a file, a file in it is
    /// an input, another run holds it) or a file could not be written.
    #[error(transparent)]
    Output(#[from] crate::kernel::OutputError),
    /// The marker cannot be built (layout or geometry options).
    #[error(transparent)]
    Geometry(#[from] GeometryError),
    /// The resolution is not a positive finite number.
    #[error("--resolution must be positive and finite, got {0}")]
    BadResolution(f64),
    /// The grid is too coarse for the finest feature.
    #[error("--resolution {resolution_mm} mm is too coarse for the finest feature ({finest_mm} mm); use at most {max_mm} mm")]
    ResolutionTooCoarse {
        /// Resolution asked for, mm.
        resolution_mm: f64,
        /// Finest feature of the marker, mm.
        finest_mm: f64,
        /// Largest resolution allowed, mm.
        max_mm: f64,
    },
    /// The mesh failed a soundness check.
    #[error("the mesh is not a watertight solid ({0}); try a finer --resolution")]
    NotWatertight(String),
    /// A format name is unknown.
    #[error("unknown format \"{0}\": expected stl, 3mf, obj, gltf or glb")]
    UnknownFormat(String),
    /// No format was asked for.
    #[error("no output format given; expected stl, 3mf, obj, gltf or glb")]
    NoFormat,
    /// A file could not be written.
    #[error("cannot write {path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// A strut covers a sphere from the view cone.
    #[error("{} covers {:.1} % of sphere {sphere} seen {angle_deg:.0} degrees off the main view ({view}); the camera would lose that sphere. Try another --view, a smaller --view-cone, --structure, or pass --allow-occlusion", if *main_view { "in the main view a strut" } else { "a strut" }, 100.0 * fraction)]
    Occluded {
        /// The sphere.
        sphere: String,
        /// Fraction of its disc covered.
        fraction: f64,
        /// Angle of the viewing direction from the main view, degrees.
        angle_deg: f64,
        /// The main view.
        view: Axis,
        /// Whether it happens in the main view itself.
        main_view: bool,
    },
    /// A part of a marker set cannot be exported.
    #[error("part {number} of the set ({file}): {source}")]
    SetPart {
        /// The part's number (1…N, set order).
        number: usize,
        /// Its layout file as the set file lists it.
        file: String,
        /// Why.
        source: Box<ExportError>,
    },
    /// glTF serialisation failed.
    #[error("cannot encode glTF: {0}")]
    Gltf(String),
}
