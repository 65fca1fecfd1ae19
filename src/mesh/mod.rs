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
//! The pipeline ([`build`], then [`export`]):
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

pub mod error;
pub(crate) mod extract;
pub mod format;
pub mod geometry;
pub(crate) mod gltf;
pub(crate) mod obj;
pub mod quality;
pub(crate) mod repair;
pub(crate) mod sdf;
pub(crate) mod sheet;
pub(crate) mod stl;
pub mod summary;
pub(crate) mod threemf;
pub mod trimesh;
pub mod view_cone;
pub mod workflow;

pub use error::ExportError;
pub use format::Format;
pub use geometry::{
    straight_supports, supports_for_range, Axis, GeometryError, Marker, MarkerOptions, MountHoles,
};
pub use sheet::{datum_positions, Datum, DatumPosition, Tolerances, CSV_HEADER};
pub use trimesh::{Topology, TriangleMesh};

use crate::layout::Layout;
use crate::visibility::{LostView, Supports, WorkingRange};
use nalgebra::Vector3;
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Grid spacing when none is asked for (and the features allow it), mm.
pub const DEFAULT_RESOLUTION_MM: f64 = 0.5;
/// The grid spacing may be at most this fraction of the finest feature
/// (strut radius, fillet radius, hole radius, minimum feature).
pub const RESOLUTION_PER_FEATURE: f64 = 0.5;

/// The writer of `format`.
pub fn writer(format: Format) -> &'static dyn MeshWriter {
    match format {
        Format::Stl => &stl::StlWriter,
        Format::Obj => &obj::ObjWriter,
        Format::Gltf => &gltf::GltfWriter { binary: false },
        Format::Glb => &gltf::GltfWriter { binary: true },
        Format::ThreeMf => &threemf::ThreeMfWriter,
    }
}

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
    /// still lose are reported ([`ExportReport::lost_views`]) instead of
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
    let start = Instant::now();
    let marker = match &options.working_range {
        Some(range) => {
            let mut marker_options = options.marker.clone();
            marker_options.working_views =
                range.clear_views(&layout.positions(), layout.sphere_diameter_mm);
            Marker::design(layout, &marker_options)?
        }
        None => Marker::design(layout, &options.marker)?,
    };
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

/// One file written.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct WrittenFile {
    /// Its format, or `None` for the fabrication sheet.
    pub format: Option<Format>,
    /// Where.
    pub path: PathBuf,
    /// Size, bytes.
    pub bytes: u64,
    /// Wall time to write it (with its companions), seconds.
    pub seconds: f64,
}

/// What [`export`] did, for the CLI summary and `<name>-export.json`.
#[derive(Debug, Clone, Serialize)]
pub struct ExportReport {
    /// The layout's name.
    pub name: String,
    /// The mesh's figures.
    pub mesh: MeshReport,
    /// Every file written.
    pub files: Vec<WrittenFile>,
    /// The smallest difference between two pairwise sphere distances, mm.
    pub identification_margin_mm: f64,
    /// How much the marker hides each sphere, in the main view and over
    /// the view cone.
    pub main_view_coverage: Vec<quality::Coverage>,
    /// Half-angle of the view cone, degrees.
    pub view_cone_deg: f64,
    /// Whether a strut covering a sphere was allowed (`--allow-occlusion`).
    pub occlusion_allowed: bool,
    /// Scenarios of the working range, if one was given.
    pub working_range_scenarios: Option<usize>,
    /// The views of the working range that the spheres alone leave
    /// visible but in which the supports hide more than the allowed
    /// fraction of a sphere (empty when no routing had to give one up).
    pub lost_views: Vec<LostView>,
    /// Overhangs as printed.
    pub overhang: quality::Overhang,
    /// How the spheres are held.
    pub structure: geometry::Structure,
    /// The mesh's extents in the print frame, mm.
    pub print_size_mm: [f64; 3],
    /// The build volume it was checked against, mm.
    pub bed_mm: [f64; 3],
    /// Strut diameter, mm.
    pub strut_diameter_mm: f64,
    /// Minimum feature size, mm.
    pub min_feature_mm: f64,
    /// Main viewing direction.
    pub view: Axis,
    /// Mount axis.
    pub mount: Axis,
    /// Screw holes, if any.
    pub mount_holes: Option<MountHoles>,
    /// Sphere centres and hole axes from the datum on the base plate
    /// ([`Datum`]), mm.
    pub datum: Vec<DatumPosition>,
    /// Sphere-centre tolerance from the error model and the workshop
    /// tolerances of the sheet.
    pub tolerances: Tolerances,
}

/// Builds the marker for `layout` and writes every requested format, the
/// fabrication sheet (`<name>-fabrication.md`, `.csv`, `<name>-views.svg`)
/// and this report as `<name>-export.json` into `out_dir` (created if
/// missing), as a set: every file is first written into a staging
/// directory inside `out_dir` and then renamed into place, so that a
/// failure part-way leaves none of the new files (see [`FileSet`]).
pub fn export(
    layout: &Layout,
    options: &ExportOptions,
    out_dir: &Path,
) -> Result<ExportReport, ExportError> {
    export_observed(layout, options, out_dir, &|| false)
}

/// [`export`], asking `interrupted` between the steps: once it says yes,
/// the export stops with [`ExportError::Interrupted`] and leaves none of
/// its files.
fn export_observed(
    layout: &Layout,
    options: &ExportOptions,
    out_dir: &Path,
    interrupted: &dyn Fn() -> bool,
) -> Result<ExportReport, ExportError> {
    if options.formats.is_empty() {
        return Err(ExportError::NoFormat);
    }
    let solid = build(layout, options)?;
    let coverage = quality::view_coverage(&solid.marker, options.marker.view_cone_deg);
    let lost_views = match &options.working_range {
        Some(range) => range.lost_views(
            &layout.positions(),
            layout.sphere_diameter_mm,
            &Supports::new(solid.marker.occluders()),
        ),
        None => {
            if !options.allow_occlusion {
                check_occlusion(&solid.marker, &coverage)?;
            }
            Vec::new()
        }
    };
    let (rotation, shift) = solid.print_transform();
    let overhang = quality::overhang(
        &solid.marker,
        &solid.mesh,
        &rotation,
        &shift,
        geometry::MAX_OVERHANG_DEG,
    );
    let tolerances = sheet::Tolerances::for_marker(&solid.marker);
    if interrupted() {
        return Err(ExportError::Interrupted);
    }
    std::fs::create_dir_all(out_dir).map_err(|source| ExportError::Io {
        path: out_dir.to_path_buf(),
        source,
    })?;
    let mut set = FileSet::stage(out_dir, &solid.name())?;
    let staging = set.staging.clone();
    let mut files = Vec::new();
    let mut formats = options.formats.clone();
    formats.sort();
    formats.dedup();
    for format in formats {
        let start = Instant::now();
        let written = writer(format).write(&solid, &staging)?;
        let seconds = start.elapsed().as_secs_f64();
        for path in written {
            files.push(WrittenFile {
                format: Some(format),
                bytes: file_size(&path),
                path,
                seconds,
            });
            set.wrote()?;
        }
        if interrupted() {
            return Err(ExportError::Interrupted);
        }
    }
    let start = Instant::now();
    let sheet_files = sheet::write(&solid, &coverage, &tolerances, &staging)?;
    let seconds = start.elapsed().as_secs_f64();
    for path in sheet_files {
        files.push(WrittenFile {
            format: None,
            bytes: file_size(&path),
            path,
            seconds,
        });
        set.wrote()?;
    }
    if interrupted() {
        return Err(ExportError::Interrupted);
    }
    // The report names the files where they will be.
    for file in &mut files {
        if let Some(name) = file.path.file_name() {
            file.path = out_dir.join(name);
        }
    }
    let mut report = ExportReport {
        name: solid.marker.name.clone(),
        mesh: solid.report.clone(),
        files,
        identification_margin_mm: sheet::identification_margin(&solid.marker).0,
        main_view_coverage: coverage,
        view_cone_deg: options.marker.view_cone_deg,
        occlusion_allowed: options.allow_occlusion,
        working_range_scenarios: options.working_range.as_ref().map(|r| r.scenarios.len()),
        lost_views,
        overhang,
        structure: solid.marker.structure,
        print_size_mm: {
            // The mesh's own extents (the design's bounds are padded by
            // the most blending could add).
            let [lo, hi] = solid.report.bounds_mm;
            let size = rotation.abs() * (Vector3::from(hi) - Vector3::from(lo));
            [size.x, size.y, size.z]
        },
        bed_mm: options.marker.bed.0,
        strut_diameter_mm: options.marker.strut_diameter_mm,
        min_feature_mm: options.marker.min_feature_mm,
        view: options.marker.view,
        mount: solid.marker.mount,
        mount_holes: options.marker.mount_holes.clone(),
        datum: sheet::datum_positions(&solid.marker),
        tolerances,
    };
    let json_name = format!("{}-export.json", solid.name());
    report.files.push(WrittenFile {
        format: None,
        path: out_dir.join(&json_name),
        bytes: 0,
        seconds: 0.0,
    });
    let json = serde_json::to_string_pretty(&report).expect("the report serialises") + "\n";
    write_file(&staging.join(&json_name), json.as_bytes())?;
    set.wrote()?;
    set.commit()?;
    if let Some(last) = report.files.last_mut() {
        last.bytes = json.len() as u64;
    }
    Ok(report)
}

/// An export's files as a set: written into a staging directory inside the
/// output directory (`.<name>.export.<pid>.<n>.tmp`), then renamed into
/// place one by one by [`FileSet::commit`]. Dropped before the commit
/// finished (an error, an interruption), it removes the staging directory
/// and any file it had already moved into place, so that an export leaves
/// all of its files or none of them. Files of an earlier export that a
/// renamed file replaced are not restored.
struct FileSet {
    out_dir: PathBuf,
    staging: PathBuf,
    moved: Vec<PathBuf>,
    committed: bool,
    /// Files staged so far (for the test-only failure point).
    #[cfg(test)]
    written: usize,
}

#[cfg(test)]
thread_local! {
    /// Test-only failure point: fail once this many files are staged.
    static FAIL_AFTER_FILES: std::cell::Cell<Option<usize>> = const { std::cell::Cell::new(None) };
}

impl FileSet {
    fn stage(out_dir: &Path, name: &str) -> Result<FileSet, ExportError> {
        static NEXT: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
        let n = NEXT.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let staging = out_dir.join(format!(".{name}.export.{}.{n}.tmp", std::process::id()));
        std::fs::create_dir(&staging).map_err(|source| ExportError::Io {
            path: staging.clone(),
            source,
        })?;
        Ok(FileSet {
            out_dir: out_dir.to_path_buf(),
            staging,
            moved: Vec::new(),
            committed: false,
            #[cfg(test)]
            written: 0,
        })
    }

    /// One more file is staged.
    fn wrote(&mut self) -> Result<(), ExportError> {
        #[cfg(test)]
        {
            self.written += 1;
            if FAIL_AFTER_FILES.with(|f| f.get()) == Some(self.written) {
                return Err(ExportError::Io {
                    path: self.staging.clone(),
                    source: std::io::Error::other("injected failure"),
                });
            }
        }
        Ok(())
    }

    /// Moves every staged file into the output directory.
    fn commit(mut self) -> Result<(), ExportError> {
        let io = |path: &Path| {
            let path = path.to_path_buf();
            move |source| ExportError::Io { path, source }
        };
        let mut staged: Vec<PathBuf> = std::fs::read_dir(&self.staging)
            .map_err(io(&self.staging))?
            .map(|entry| entry.map(|e| e.path()))
            .collect::<Result<_, _>>()
            .map_err(io(&self.staging))?;
        staged.sort();
        for from in staged {
            let Some(name) = from.file_name() else {
                continue;
            };
            let to = self.out_dir.join(name);
            std::fs::rename(&from, &to).map_err(io(&to))?;
            self.moved.push(to);
        }
        self.committed = true;
        let _ = std::fs::remove_dir(&self.staging);
        Ok(())
    }
}

impl Drop for FileSet {
    fn drop(&mut self) {
        if !self.committed {
            for path in &self.moved {
                let _ = std::fs::remove_file(path);
            }
            let _ = std::fs::remove_dir_all(&self.staging);
        }
    }
}

/// The sphere a strut covers most, in the main view or from the view cone,
/// as an error. A sphere that another sphere covers from some direction of
/// the cone is left out: every support of the sphere in front passes in
/// front of it close to that direction (the paper's biprism seen along z
/// hides O0 and P1 behind P3), so that is the layout's own occlusion,
/// reported but not an error.
fn check_occlusion(marker: &Marker, coverage: &[quality::Coverage]) -> Result<(), ExportError> {
    let worst = coverage
        .iter()
        .filter(|c| c.cone_covered_by_spheres == 0.0)
        .filter(|c| c.cone_covered_by_struts > 0.0)
        .max_by(|a, b| {
            a.cone_covered_by_struts
                .total_cmp(&b.cone_covered_by_struts)
        });
    match worst {
        None => Ok(()),
        Some(c) => {
            let main_view = c.covered_by_struts > 0.0;
            let (fraction, angle_deg) = if main_view {
                (c.covered_by_struts, 0.0)
            } else {
                (
                    c.cone_covered_by_struts,
                    quality::angle_from_view_deg(marker, &c.cone_worst_direction),
                )
            };
            Err(ExportError::Occluded {
                sphere: c.sphere.clone(),
                fraction,
                angle_deg,
                view: marker.view,
                main_view,
            })
        }
    }
}

fn file_size(path: &Path) -> u64 {
    std::fs::metadata(path).map(|m| m.len()).unwrap_or(0)
}

/// Writes a whole file atomically, mapping errors to [`ExportError::Io`].
pub(crate) fn write_file(path: &Path, bytes: &[u8]) -> Result<(), ExportError> {
    crate::files::write_atomic(path, bytes).map_err(|source| ExportError::Io {
        path: path.to_path_buf(),
        source,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::layout::LayoutPoint;
    use std::cell::Cell;

    /// A small part that meshes in a fraction of a second.
    fn small() -> Layout {
        let points = [
            [0.0, 0.0, 0.0],
            [30.0, 0.0, -10.0],
            [0.0, 26.0, -5.0],
            [-12.0, -14.0, 15.0],
        ];
        Layout {
            name: "small".into(),
            points: points
                .iter()
                .enumerate()
                .map(|(i, p)| LayoutPoint::new(format!("S{i}"), (*p).into()))
                .collect(),
            sphere_diameter_mm: 6.0,
            family: None,
            provenance: None,
        }
    }

    fn options() -> ExportOptions {
        ExportOptions {
            formats: vec![Format::Stl, Format::Obj],
            allow_occlusion: true,
            ..Default::default()
        }
    }

    /// Every entry of `dir`, sorted.
    fn entries(dir: &Path) -> Vec<String> {
        let mut names: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        names
    }

    #[test]
    fn a_failure_part_way_leaves_none_of_the_files() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("keep.txt"), "not ours").unwrap();
        let report = export(&small(), &options(), dir.path()).unwrap();
        // stl, obj, the sheet's three files, the report.
        assert_eq!(report.files.len(), 6);
        assert!(report.files.iter().all(|f| f.path.exists()), "{report:?}");
        assert_eq!(entries(dir.path()).len(), 7);
        for fail_after in [1, 4, 6] {
            let other = tempfile::tempdir().unwrap();
            std::fs::write(other.path().join("keep.txt"), "not ours").unwrap();
            FAIL_AFTER_FILES.with(|f| f.set(Some(fail_after)));
            let result = export(&small(), &options(), other.path());
            FAIL_AFTER_FILES.with(|f| f.set(None));
            let error = result.unwrap_err();
            assert!(error.to_string().contains("injected failure"), "{error}");
            assert_eq!(
                entries(other.path()),
                ["keep.txt"],
                "failing after {fail_after}"
            );
        }
    }

    #[test]
    fn a_rename_that_fails_takes_back_the_files_already_moved() {
        let dir = tempfile::tempdir().unwrap();
        // The last file moved into place (names sorted) cannot replace a
        // directory that holds a file.
        std::fs::create_dir(dir.path().join("small.stl")).unwrap();
        std::fs::write(dir.path().join("small.stl").join("x"), "x").unwrap();
        let error = export(&small(), &options(), dir.path()).unwrap_err();
        assert!(
            matches!(&error, ExportError::Io { path, .. } if path.ends_with("small.stl")),
            "{error}"
        );
        assert_eq!(entries(dir.path()), ["small.stl"]);
    }

    #[test]
    fn an_interruption_part_way_leaves_none_of_the_files() {
        for polls in [1, 2, 3] {
            let dir = tempfile::tempdir().unwrap();
            let asked = Cell::new(0);
            let interrupted = || {
                asked.set(asked.get() + 1);
                asked.get() >= polls
            };
            let result = export_observed(&small(), &options(), dir.path(), &interrupted);
            assert!(matches!(result, Err(ExportError::Interrupted)));
            assert!(entries(dir.path()).is_empty(), "after {polls} polls");
        }
    }

    /// The datum is the corner of the plate's bed face: the datum
    /// coordinates of the plate's corners are 0 and its sizes, and Z is
    /// the STL's z.
    #[test]
    fn datum_is_the_plates_bed_corner() {
        let marker = Marker::design(&small(), &options().marker).unwrap();
        let datum = Datum::of(&marker);
        let (rotation, shift) = marker.print_transform();
        let plate = &marker.plate;
        let mut lo = Vector3::repeat(f64::INFINITY);
        for sx in [-1.0, 1.0] {
            for sy in [-1.0, 1.0] {
                for sz in [-1.0, 1.0] {
                    let corner =
                        plate.centre + plate.half_extents.component_mul(&Vector3::new(sx, sy, sz));
                    lo = lo.inf(&datum.coordinates(&corner));
                }
            }
        }
        assert!(lo.norm() < 1e-9, "{lo}");
        for s in &marker.spheres {
            let d = datum.coordinates(&s.centre);
            let print = rotation * s.centre + shift;
            assert!((d.z - print.z).abs() < 1e-9);
            assert!(d.z > 0.0);
        }
    }
}
