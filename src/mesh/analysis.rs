//! The export's analysis: the part designed, meshed and checked for a
//! layout, with every figure its files and summary report — what the
//! supports hide, lost views of the working range, overhangs, the datum
//! positions and the tolerances — and no file written. The workflow
//! ([`super::workflow`]) writes the files and fills
//! [`ExportReport::files`].

use super::geometry::{self, Axis, Marker, MountHoles};
use super::tolerance::{self, DatumPosition, Tolerances};
use super::{build_numbered, quality, ExportError, ExportOptions, Format, MeshReport, Solid};
use crate::layout::Layout;
use crate::visibility::{LostView, Supports};
use nalgebra::Vector3;
use serde::Serialize;
use std::path::PathBuf;

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

/// What [`export`](super::workflow::export) did, for the CLI summary and `<name>-export.json`.
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
    /// Whether one image identifies the spheres, from the layout's
    /// provenance (the search that made it); None when it does not say.
    pub one_image_identifiability: Option<tolerance::OneImageIdentifiability>,
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
    /// The number engraved into the base plate, if any.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub engraving: Option<geometry::Engraving>,
}

/// What the analysis found: the built part, how much the marker hides each
/// sphere over the view cone, and the report with no files yet.
#[derive(Debug, Clone)]
pub struct Analysis {
    /// The designed, meshed and checked part.
    pub solid: Solid,
    /// The report, its `files` empty.
    pub report: ExportReport,
}

/// Designs, meshes and checks the part for `layout`, and computes every
/// figure of its report. Without a working range and without
/// `allow_occlusion`, a strut covering a sphere from the view cone is
/// [`ExportError::Occluded`].
pub fn analyse(layout: &Layout, options: &ExportOptions) -> Result<Analysis, ExportError> {
    analyse_numbered(layout, options, None)
}

/// [`analyse`], with `number` engraved into the base plate when given
/// ([`super::build_numbered`]).
pub fn analyse_numbered(
    layout: &Layout,
    options: &ExportOptions,
    number: Option<&str>,
) -> Result<Analysis, ExportError> {
    if options.formats.is_empty() {
        return Err(ExportError::NoFormat);
    }
    let solid = build_numbered(layout, options, number)?;
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
    let report = ExportReport {
        name: solid.marker.name.clone(),
        mesh: solid.report.clone(),
        files: Vec::new(),
        identification_margin_mm: tolerance::identification_margin(&solid.marker).0,
        one_image_identifiability: tolerance::OneImageIdentifiability::from_provenance(
            layout.provenance.as_ref(),
        ),
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
        datum: tolerance::datum_positions(&solid.marker),
        tolerances: Tolerances::for_marker(&solid.marker),
        engraving: solid.marker.engraving.clone(),
    };
    Ok(Analysis { solid, report })
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
