//! The fabrication sheet: `<name>-fabrication.md` (tables for the
//! workshop), `<name>-fabrication.csv` (the same numbers for machines) and
//! `<name>-views.svg` (three dimensioned orthographic views, hand-written
//! SVG).
//!
//! It lists the spheres (names, centres, diameter), every pairwise centre
//! distance and the *identification margin* — the smallest difference
//! between two pairwise distances, which bounds how well spheres can be told
//! apart by distances alone — the part's bounding box, volume and mesh
//! figures, and the frames of the files.

use super::geometry::{gltf_rotation, print_rotation, Marker};
use super::quality::Coverage;
use super::tolerance::{
    datum_positions, identification_margin, pairwise_distances, Datum, DatumPosition,
    OneImageIdentifiability, Tolerances,
};
use super::{write_file, ExportError, Solid};
use nalgebra::{Matrix3, Vector3};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Margin around each view in the SVG, mm (room for the ordinate labels).
const VIEW_MARGIN_MM: f64 = 40.0;
/// Distance of an ordinate dimension's baseline from the part, mm.
const ORDINATE_OFFSET_MM: f64 = 5.0;
/// Smallest spacing of two ordinate labels, mm.
const ORDINATE_SPACING_MM: f64 = 3.2;
/// Text size in the SVG, mm.
const TEXT_MM: f64 = 4.0;
/// The papers the views sheet is laid out on, landscape: name, width and
/// height, mm.
const PAPERS: [(&str, f64, f64); 2] = [("A4", 297.0, 210.0), ("A3", 420.0, 297.0)];
/// Drawing scales tried, 1:n, largest first (ISO 5455's reductions).
const SCALES: [f64; 4] = [1.0, 2.0, 5.0, 10.0];
/// Blank border of the paper, mm.
const PAGE_MARGIN_MM: f64 = 10.0;

/// The paper and scale of a drawing `width` × `height` mm at 1:1: the
/// largest scale of [`SCALES`] on the smallest paper of [`PAPERS`] it fits
/// within the margins, or, for a drawing too large for A3 at 1:10, A3 at
/// the scale (1:n, n whole) that fits it.
fn page(width: f64, height: f64) -> (&'static str, f64, f64, f64) {
    let fits = |n: f64, (_, w, h): (&str, f64, f64)| {
        width / n <= w - 2.0 * PAGE_MARGIN_MM && height / n <= h - 2.0 * PAGE_MARGIN_MM
    };
    for n in SCALES {
        if let Some(&(name, w, h)) = PAPERS.iter().find(|&&paper| fits(n, paper)) {
            return (name, w, h, n);
        }
    }
    let (name, w, h) = PAPERS[PAPERS.len() - 1];
    let n = (width / (w - 2.0 * PAGE_MARGIN_MM))
        .max(height / (h - 2.0 * PAGE_MARGIN_MM))
        .ceil();
    (name, w, h, n)
}

/// Identification margins below this are flagged in the sheet, mm.
pub const MARGIN_WARNING_MM: f64 = 1.0;

/// Writes the sheet's three files into `dir`.
pub fn write(
    solid: &Solid,
    coverage: &[Coverage],
    tolerances: &Tolerances,
    one_image: Option<OneImageIdentifiability>,
    dir: &Path,
) -> Result<Vec<PathBuf>, ExportError> {
    let name = solid.name();
    let md = dir.join(format!("{name}-fabrication.md"));
    let csv = dir.join(format!("{name}-fabrication.csv"));
    let svg = dir.join(format!("{name}-views.svg"));
    write_file(
        &md,
        markdown(solid, coverage, tolerances, one_image, &svg).as_bytes(),
    )?;
    write_file(&csv, &csv_table(&solid.marker, tolerances))?;
    let [lo, hi] = solid.report.bounds_mm;
    write_file(
        &svg,
        views_svg(&solid.marker, (Vector3::from(lo), Vector3::from(hi))).as_bytes(),
    )?;
    Ok(vec![md, csv, svg])
}

fn sphere_pair(marker: &Marker, (i, j): (usize, usize)) -> String {
    format!("{}–{}", marker.spheres[i].name, marker.spheres[j].name)
}

fn frame_rows(rotation: &Matrix3<f64>) -> String {
    let axis = |row: usize| {
        let r = rotation.row(row);
        let k = (0..3).find(|&k| r[k] != 0.0).expect("a signed permutation");
        format!(
            "{}{}",
            if r[k] < 0.0 { "−" } else { "" },
            ["x", "y", "z"][k]
        )
    };
    format!("({}, {}, {})", axis(0), axis(1), axis(2))
}

fn markdown(
    solid: &Solid,
    coverage: &[Coverage],
    tolerances: &Tolerances,
    one_image: Option<OneImageIdentifiability>,
    svg: &Path,
) -> String {
    let marker = &solid.marker;
    let report = &solid.report;
    let t = &report.topology;
    let mut md = String::new();
    let _ = writeln!(md, "# Fabrication sheet: {}\n", marker.name);
    let _ = writeln!(
        md,
        "Made by `layout-opt export` (version {}). All lengths in millimetres, in the marker frame (the layout's coordinates) unless stated.\n",
        env!("CARGO_PKG_VERSION")
    );
    if let Some(e) = &marker.engraving {
        let _ = writeln!(
            md,
            "**Part number {}**, engraved into the base plate's face opposite the bed ({} mm deep, strokes {} mm wide, a {:.1} × {:.1} mm box from ({:.1}, {:.1}, {:.1})){}. Check it before mounting: the parts of a set look alike.\n",
            e.text,
            e.depth_mm,
            e.stroke_mm,
            e.size_mm[0],
            e.size_mm[1],
            e.origin.x,
            e.origin.y,
            e.origin.z,
            if e.plate_grown {
                "; the plate was lengthened to make room for it"
            } else {
                ""
            }
        );
    }
    let _ = writeln!(
        md,
        "## Spheres\n\n| sphere | x | y | z | diameter |\n|---|---:|---:|---:|---:|"
    );
    for s in &marker.spheres {
        let _ = writeln!(
            md,
            "| {} | {:.3} | {:.3} | {:.3} | {:.3} |",
            s.name,
            s.centre.x,
            s.centre.y,
            s.centre.z,
            2.0 * s.radius
        );
    }
    let _ = writeln!(
        md,
        "\n## Pairwise centre distances\n\n| pair | distance |\n|---|---:|"
    );
    for (i, j, d) in pairwise_distances(marker) {
        let _ = writeln!(md, "| {} | {:.3} |", sphere_pair(marker, (i, j)), d);
    }
    let (margin, pairs) = identification_margin(marker);
    let _ = write!(
        md,
        "\n**Identification margin** (smallest difference between two pairwise distances): {margin:.3} mm"
    );
    if let Some([a, b]) = pairs {
        let _ = write!(
            md,
            ", between {} and {}",
            sphere_pair(marker, a),
            sphere_pair(marker, b)
        );
    }
    let _ = writeln!(md, ".");
    let _ = write!(md, "{}", margin_warning(marker, tolerances, one_image));
    let _ = write!(md, "{}", tolerance_section(tolerances));
    let _ = write!(md, "{}", datum_section(marker, tolerances));

    let [lo, hi] = report.bounds_mm;
    let size = [hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]];
    let _ = writeln!(md, "\n## Part\n");
    let _ = writeln!(
        md,
        "- Bounding box: x {:.2} … {:.2}, y {:.2} … {:.2}, z {:.2} … {:.2} (size {:.2} × {:.2} × {:.2})",
        lo[0], hi[0], lo[1], hi[1], lo[2], hi[2], size[0], size[1], size[2]
    );
    let _ = writeln!(
        md,
        "- Volume: {:.1} mm³ ({:.2} cm³); surface area {:.1} mm²",
        t.signed_volume_mm3,
        t.signed_volume_mm3 / 1000.0,
        t.area_mm2
    );
    let strut = marker
        .struts
        .iter()
        .find(|s| s.kind != super::geometry::StrutKind::Stub)
        .map_or(0.0, |s| 2.0 * s.radius);
    let stub = marker
        .struts
        .iter()
        .find(|s| s.kind == super::geometry::StrutKind::Stub)
        .map_or(0.0, |s| 2.0 * s.radius);
    match marker.structure {
        super::geometry::Structure::Pillars => {
            let _ = writeln!(
                md,
                "- Structure: pillars. Base plate {:.1} × {:.1} × {:.1} behind every sphere (along the view {}); a support {:.2} in diameter rises from it to each sphere (at most {}° from the vertical), widening under the sphere into a cone of half-angle {}°; fillets of radius {:.2}",
                2.0 * marker.plate.half_extents.x,
                2.0 * marker.plate.half_extents.y,
                2.0 * marker.plate.half_extents.z,
                marker.view,
                strut,
                super::geometry::SUPPORT_SLANTS_DEG.iter().fold(0.0f64, |m, &s| m.max(s)),
                super::geometry::TEARDROP_HALF_ANGLE_DEG,
                marker.blend_mm,
            );
            let _ = writeln!(
                md,
                "- Print orientation: the STL as written: base plate face down on the bed (z = 0), spheres up. Supports: none needed (no downward-facing surface steeper than {}° from the vertical above the first layer). Suggested layer height 0.2 mm or finer (0.1 mm for spheres of 6 mm or less)",
                super::geometry::MAX_OVERHANG_DEG
            );
            match &marker.mount_holes {
                Some(h) => {
                    let _ = writeln!(
                        md,
                        "- Mounting holes: {} × {} clearance, {:.1} diameter (ISO 273 medium), through the plate along {}, in a tab on its {} side",
                        h.count, h.screw, h.diameter_mm, marker.view, marker.mount
                    );
                }
                None => {
                    let _ = writeln!(md, "- Mounting holes: none (glue or clamp the plate)");
                }
            }
        }
        super::geometry::Structure::Routed => {
            let _ = writeln!(
                md,
                "- Struts: {:.2} diameter, filleted with radius {:.2}; mounting stub {:.2} diameter along {}; base plate {:.1} × {:.1} × {:.1}",
                strut,
                marker.blend_mm,
                stub,
                marker.mount,
                2.0 * marker.plate.half_extents.x,
                2.0 * marker.plate.half_extents.y,
                2.0 * marker.plate.half_extents.z
            );
            match &marker.mount_holes {
                Some(h) => {
                    let _ = writeln!(
                        md,
                        "- Mounting holes: {} × {} clearance, {:.1} diameter (ISO 273 medium), through the plate along {}",
                        h.count, h.screw, h.diameter_mm, marker.mount
                    );
                }
                None => {
                    let _ = writeln!(md, "- Mounting holes: none");
                }
            }
            let _ = writeln!(
                md,
                "- Print orientation: the STL as written, plate on the bed; this structure needs support material"
            );
        }
    }
    let _ = writeln!(
        md,
        "- Main viewing direction: {} (every sphere stands in front of its own support; the base plate lies behind all spheres); view cone checked: ±{}°",
        marker.view, marker.view_cone_deg
    );
    let _ = writeln!(
        md,
        "- Mesh: {} triangles, {} vertices, grid {:.3}; every one of the {} edges is shared by exactly two faces in opposite directions; {} body; Euler characteristic {} (genus {}); largest distance of a face from the exact surface {:.4}",
        t.faces,
        t.vertices,
        report.resolution_mm,
        t.edges,
        t.components,
        t.euler_characteristic,
        t.genus(),
        report.max_surface_error_mm
    );
    let covered: Vec<String> = coverage
        .iter()
        .filter(|c| c.covered_by_struts > 0.0)
        .map(|c| format!("{} {:.1} %", c.sphere, 100.0 * c.covered_by_struts))
        .collect();
    let _ = writeln!(
        md,
        "- Struts covering spheres in the main view (orthographic, along {}): {}",
        marker.view,
        if covered.is_empty() {
            "none".to_string()
        } else {
            covered.join(", ")
        }
    );

    let _ = writeln!(
        md,
        "\n## Files and frames\n\n| file | units | the file's (X, Y, Z) axes are the marker's |\n|---|---|---|"
    );
    let _ = writeln!(md, "| `.obj` | mm | marker frame (x, y, z) |");
    let _ = writeln!(
        md,
        "| `.stl` | mm | print frame, Z up, mount axis down: {} |",
        frame_rows(&print_rotation(marker.down))
    );
    let _ = writeln!(
        md,
        "| `.gltf`, `.glb` | m | glTF, Y up, mount axis down: {} |",
        frame_rows(&gltf_rotation(marker.down))
    );
    let _ = writeln!(
        md,
        "\n## Views\n\n![three orthographic views]({})",
        svg.file_name()
            .map(|f| f.to_string_lossy().into_owned())
            .unwrap_or_default()
    );
    md
}

/// The most a pairwise distance moves when both centres are within ±`t`
/// per coordinate: 2·√3·t.
fn distance_change_mm(t: f64) -> f64 {
    2.0 * 3f64.sqrt() * t
}

/// The identification-margin warning (empty when the margin is ample),
/// or, for a design one image identifies (`one_image`, from the search
/// that made it), a note that the margin concerns stereo trackers only.
fn margin_warning(
    marker: &Marker,
    tolerances: &Tolerances,
    one_image: Option<OneImageIdentifiability>,
) -> String {
    let (margin, pairs) = identification_margin(marker);
    if margin < MARGIN_WARNING_MM {
        if let Some(one) = one_image.filter(OneImageIdentifiability::everywhere) {
            return format!(
                "\nOne image identifies the spheres in all {} visible scenarios of the search that made this layout (its provenance): a camera tells them apart by the image they make, not by their distances. The margin above matters only to a stereo tracker that identifies spheres by measured pairwise distances.\n",
                one.visible
            );
        }
    }
    let names = pairs.map_or(String::new(), |[a, b]| {
        format!(
            " ({} and {})",
            sphere_pair(marker, a),
            sphere_pair(marker, b)
        )
    });
    let drift = tolerances
        .centre
        .as_ref()
        .map(|c| distance_change_mm(c.tolerance_mm));
    if margin < 1e-6 {
        format!(
            "\n> **Warning: repeated distances.** Two pairs of spheres{names} are the same distance apart, so an image of the marker cannot be matched to its spheres by pairwise distances alone: those spheres are interchangeable for a distance-based identification, which needs other cues (sphere colour or size, the view's known range, tracking from a known start). Printing errors do not help: they are random, not a code.\n"
        )
    } else if margin < MARGIN_WARNING_MM {
        let within = drift.map_or(String::new(), |d| {
            format!(
                "; a part within the centre tolerance can change a distance by up to {d:.3} mm{}",
                if d >= margin {
                    ", enough to swap these two"
                } else {
                    ""
                }
            )
        });
        format!(
            "\n> **Warning: small identification margin.** {margin:.3} mm{names} is below {MARGIN_WARNING_MM} mm (search's default `--min-distance-diff`): matching by distances needs the measured distances to be better than half of it{within}.\n"
        )
    } else {
        String::new()
    }
}

/// The "Tolerances" section of the sheet.
fn tolerance_section(tolerances: &Tolerances) -> String {
    let mut md = String::from("\n## Tolerances\n\n");
    match &tolerances.centre {
        Some(c) => {
            let w = &c.worst_scenario;
            let _ = writeln!(
                md,
                "- **Sphere centres: ±{:.3} mm** in each datum coordinate (X, Y, Z) of every sphere. From the error model: a part whose centres are off by errors of standard deviation σ_fab per coordinate, solved with the nominal layout, has a first-order RMS rotation error of {:.4}° per mm of σ_fab in the worst case; with σ_fab ≤ {:.3} mm it stays at most {:.0} % of the image-noise RMS rotation error in every one of the {} scenarios (of {}) that see every sphere, over {} (worst: depth {} mm, x offset {} mm, tilt {}°, where the noise gives {:.4}°). Added in quadrature, {:.0} % raises the total error by {:.1} %. Errors within ±T have an RMS of at most T whatever their distribution, so the tolerance is the σ_fab bound itself. Check a design with `layout-opt validate LAYOUT --fabrication-sigma {:.3}`.",
                c.tolerance_mm,
                c.rotation_deg_per_mm,
                c.max_sigma_mm,
                100.0 * c.share,
                c.scenarios,
                c.grid_scenarios,
                tolerances.basis,
                w.depth_mm,
                w.offset_x_mm,
                w.tilt_deg,
                c.noise_rotation_deg,
                100.0 * c.share,
                100.0 * ((1.0 + c.share * c.share).sqrt() - 1.0),
                c.tolerance_mm
            );
            let _ = writeln!(
                md,
                "  The tolerance scales with the share: at ±{:.3} mm the fabrication error would equal the noise error (the total rising by 41 %).",
                c.tolerance_mm / c.share
            );
            let _ = writeln!(md, "{}", printable_tolerances(c));
        }
        None => {
            let _ = writeln!(
                md,
                "- **Sphere centres:** no tolerance from the error model: no scenario of {} sees every sphere.",
                tolerances.basis
            );
        }
    }
    let _ = writeln!(
        md,
        "- **Sphere diameter: ±{:.2} mm** (a workshop tolerance, not from the error model: the pose uses the centres; the diameter only sizes the image disc a detector fits).",
        tolerances.diameter_mm
    );
    let _ = writeln!(
        md,
        "- **Hole positions: ±{:.2} mm** (for mounting only; the holes do not enter the pose).",
        tolerances.hole_position_mm
    );
    md
}

/// Tolerances that FDM and SLA printers hold, ± mm.
const PRINTABLE_TOLERANCES_MM: [f64; 2] = [0.1, 0.2];

/// What holding a printable tolerance instead costs, from the same linear
/// model: at σ_fab = T the fabrication RMS rotation error in the worst
/// scenario is `T · rotation_deg_per_mm`, added in quadrature to the
/// noise's there.
fn printable_tolerances(c: &crate::error_model::fabrication::FabricationTolerance) -> String {
    let costs: Vec<String> = PRINTABLE_TOLERANCES_MM
        .iter()
        .map(|&t| {
            let fabrication = t * c.rotation_deg_per_mm;
            let total = c.noise_rotation_deg.hypot(fabrication);
            format!(
                "±{t} mm gives up to {fabrication:.4}° from the part, {:.1}× the noise's {:.4}°, and raises the total by {:.0} %",
                fabrication / c.noise_rotation_deg,
                c.noise_rotation_deg,
                100.0 * (total / c.noise_rotation_deg - 1.0)
            )
        })
        .collect();
    format!(
        "  **Printable tolerances.** An FDM or SLA printer holds about ±0.1–0.2 mm, not ±{:.3} mm. Printed as it comes, in the same worst scenario: {}. To keep the noise-limited accuracy, measure the printed centres against the datum below and solve with a layout file of the measured centres (the model's fabrication error is that of a part solved with its nominal layout).",
        c.tolerance_mm,
        costs.join("; ")
    )
}

/// The "Datum" section: what the datum is, and the spheres and holes from
/// it with blank columns for the as-measured values.
fn datum_section(marker: &Marker, tolerances: &Tolerances) -> String {
    let mut md = String::from("\n## Datum and positions to measure\n\n");
    let _ = writeln!(
        md,
        "Stand the part as printed (plate on a surface plate). **Datum A** is the plate's bed face, **datum B** its side face at the STL's smallest X, **datum C** its side face at the STL's smallest Y. Every position below is measured from them: X from B, Y from C, Z (height) from A, along the STL's axes; the origin is the corner of the plate's box before its edges were rounded (radius {:.1} mm). The views mark the datum corner and give the same values.\n",
        marker.plate.rounding
    );
    let centre = tolerances
        .centre
        .as_ref()
        .map_or("—".to_string(), |c| format!("±{:.3}", c.tolerance_mm));
    let _ = writeln!(
        md,
        "| sphere | X | Y | Z | ⌀ | centre tol. | ⌀ tol. | measured X | measured Y | measured Z | measured ⌀ | X ok | Y ok | Z ok | ⌀ ok |\n|---|---:|---:|---:|---:|---:|---:|---|---|---|---|---|---|---|---|"
    );
    let positions = datum_positions(marker);
    for (p, s) in positions
        .iter()
        .filter(|p| p.kind == "sphere")
        .zip(&marker.spheres)
    {
        let [x, y, z] = p.position_mm;
        let _ = writeln!(
            md,
            "| {} | {x:.3} | {y:.3} | {z:.3} | {:.3} | {centre} | ±{:.2} | | | | | | | | |",
            p.name,
            2.0 * s.radius,
            tolerances.diameter_mm
        );
    }
    let holes: Vec<&DatumPosition> = positions.iter().filter(|p| p.kind == "hole").collect();
    if !holes.is_empty() {
        let diameter = marker.plate.holes.first().map_or(0.0, |h| 2.0 * h.radius);
        let _ = writeln!(
            md,
            "\n| hole | X | Y | ⌀ | position tol. | measured X | measured Y | X ok | Y ok |\n|---|---:|---:|---:|---:|---|---|---|---|"
        );
        for h in holes {
            let [x, y, _] = h.position_mm;
            let _ = writeln!(
                md,
                "| {} | {x:.3} | {y:.3} | {diameter:.2} | ±{:.2} | | | | |",
                h.name, tolerances.hole_position_mm
            );
        }
    }
    let _ = writeln!(
        md,
        "\nA coordinate is *ok* when |measured − nominal| ≤ its tolerance; a part with every sphere coordinate ok meets the error model's bound above."
    );
    md
}

/// Columns of `<name>-fabrication.csv`.
pub const CSV_HEADER: [&str; 16] = [
    "kind",
    "name",
    "x_mm",
    "y_mm",
    "z_mm",
    "diameter_mm",
    "distance_mm",
    "datum_x_mm",
    "datum_y_mm",
    "datum_z_mm",
    "tolerance_mm",
    "measured_x_mm",
    "measured_y_mm",
    "measured_z_mm",
    "measured_diameter_mm",
    "pass",
];

fn csv_table(marker: &Marker, tolerances: &Tolerances) -> Vec<u8> {
    let mut writer = csv::Writer::from_writer(Vec::new());
    let f = |v: f64| format!("{v:.6}");
    let _ = writer.write_record(CSV_HEADER);
    let blank = || String::new();
    let centre_tolerance = tolerances
        .centre
        .as_ref()
        .map_or(String::new(), |c| f(c.tolerance_mm));
    let positions = datum_positions(marker);
    let mut row = |fields: [String; 7], datum: [f64; 3], tolerance: String| {
        let mut record: Vec<String> = fields.to_vec();
        record.extend(datum.iter().map(|&v| f(v)));
        record.push(tolerance);
        record.extend((0..5).map(|_| blank()));
        let _ = writer.write_record(&record);
    };
    for (s, p) in marker.spheres.iter().zip(&positions) {
        row(
            [
                "sphere".to_string(),
                s.name.clone(),
                f(s.centre.x),
                f(s.centre.y),
                f(s.centre.z),
                f(2.0 * s.radius),
                blank(),
            ],
            p.position_mm,
            centre_tolerance.clone(),
        );
    }
    for (h, p) in marker
        .plate
        .holes
        .iter()
        .zip(positions.iter().filter(|p| p.kind == "hole"))
    {
        row(
            [
                "hole".to_string(),
                p.name.clone(),
                f(h.centre.x),
                f(h.centre.y),
                f(h.centre.z),
                f(2.0 * h.radius),
                blank(),
            ],
            p.position_mm,
            f(tolerances.hole_position_mm),
        );
    }
    let mut plain = |kind: &str, name: String, distance: f64| {
        let mut record = vec![kind.to_string(), name];
        record.extend((0..4).map(|_| blank()));
        record.push(f(distance));
        record.extend((0..9).map(|_| blank()));
        let _ = writer.write_record(&record);
    };
    for (i, j, d) in pairwise_distances(marker) {
        plain(
            "distance",
            format!("{}-{}", marker.spheres[i].name, marker.spheres[j].name),
            d,
        );
    }
    let (margin, _) = identification_margin(marker);
    plain("identification_margin", String::new(), margin);
    writer.into_inner().unwrap_or_default()
}

/// One view: looking along `forward`, image right and down as given.
struct View {
    title: String,
    right: Vector3<f64>,
    down: Vector3<f64>,
    forward: Vector3<f64>,
}

fn views(marker: &Marker) -> [View; 3] {
    let axis = |k: usize| Vector3::from_fn(|r, _| if r == k { 1.0 } else { 0.0 });
    let names = ["x", "y", "z"];
    // Looking along +z, +x, +y; right × down = forward in each.
    [(2, 0, 1), (0, 1, 2), (1, 2, 0)].map(|(f, r, d)| {
        let main = marker.view.vector() == axis(f);
        View {
            title: format!(
                "looking along +{} (→ {}, ↓ {}){}",
                names[f],
                names[r],
                names[d],
                if main { " — main view" } else { "" }
            ),
            right: axis(r),
            down: axis(d),
            forward: axis(f),
        }
    })
}

/// The three views, dimensioned with the mesh's own bounds `(lo, hi)`
/// (marker frame, mm): the analytic [`Marker::bounds`] are padded by the
/// most blending could add, which overstates the part.
fn views_svg(marker: &Marker, (lo, hi): (Vector3<f64>, Vector3<f64>)) -> String {
    let views = views(marker);
    let extent = |v: &View| {
        let a = [lo.dot(&v.right), hi.dot(&v.right)];
        let b = [lo.dot(&v.down), hi.dot(&v.down)];
        (
            a[0].min(a[1]),
            a[0].max(a[1]),
            b[0].min(b[1]),
            b[0].max(b[1]),
        )
    };
    let panel_w: Vec<f64> = views
        .iter()
        .map(|v| {
            let e = extent(v);
            e.1 - e.0 + 2.0 * VIEW_MARGIN_MM
        })
        .collect();
    let panel_h = views
        .iter()
        .map(|v| {
            let e = extent(v);
            e.3 - e.2 + 2.0 * VIEW_MARGIN_MM
        })
        .fold(0.0, f64::max);
    let total_w: f64 = panel_w.iter().sum();
    // The views side by side, with the scale's line under them, on the
    // paper they fit at the largest standard scale.
    let total_h = panel_h + 2.0 * TEXT_MM;
    let (paper, paper_w, paper_h, n) = page(total_w, total_h);
    let mut svg = String::new();
    let _ = writeln!(
        svg,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{paper_w:.0}mm" height="{paper_h:.0}mm" viewBox="{:.3} {:.3} {:.3} {:.3}" font-family="sans-serif" font-size="{TEXT_MM}">"#,
        // Centred on the paper.
        -0.5 * (paper_w * n - total_w),
        -0.5 * (paper_h * n - total_h),
        paper_w * n,
        paper_h * n
    );
    let _ = writeln!(
        svg,
        r#"<text class="scale" x="2" y="{:.3}" font-size="{TEXT_MM}">Scale 1:{n} on {paper} landscape ({paper_w:.0} × {paper_h:.0} mm): print at 100 %. Dimensions are true sizes in mm.</text>"#,
        panel_h + 1.5 * TEXT_MM
    );
    let _ = writeln!(
        svg,
        r#"<title>{} — three orthographic views, mm</title>"#,
        xml(&marker.name)
    );
    let _ = writeln!(
        svg,
        r##"<defs><marker id="arrow" viewBox="0 0 10 10" refX="10" refY="5" markerWidth="6" markerHeight="6" orient="auto-start-reverse"><path d="M 0 0 L 10 5 L 0 10 z" fill="#333"/></marker></defs>"##
    );
    // Ordinate dimensions from the datum: X and Y in the view along the
    // datum's Z (looking at the plate), Z in the next view.
    let datum = Datum::of(marker);
    let datum_axis_of = |screen: &Vector3<f64>| {
        (0..3)
            .find(|&k| datum.axis(k).dot(screen).abs() > 0.5)
            .expect("views and datum are axis-aligned")
    };
    let top = views
        .iter()
        .position(|v| datum.axis(2).dot(&v.forward).abs() > 0.5)
        .expect("one view looks along the datum's Z");
    let side = (top + 1) % 3;
    let mut plan: [Vec<(bool, usize)>; 3] = Default::default();
    plan[top] = vec![
        (true, datum_axis_of(&views[top].right)),
        (false, datum_axis_of(&views[top].down)),
    ];
    plan[side] = [true, false]
        .into_iter()
        .map(|along_right| {
            let v = &views[side];
            (
                along_right,
                datum_axis_of(if along_right { &v.right } else { &v.down }),
            )
        })
        .filter(|&(_, k)| k == 2)
        .collect();
    let _ = writeln!(
        svg,
        r#"<text x="2" y="{:.3}" font-size="{:.2}">Ordinates from the datum (mm): X from face B, Y from face C, Z from face A (the bed face); origin ⊕ at the plate corner.</text>"#,
        panel_h - 2.0,
        0.7 * TEXT_MM
    );
    let mut x0 = 0.0;
    for (index, (view, width)) in views.iter().zip(&panel_w).enumerate() {
        let (r0, r1, d0, d1) = extent(view);
        let ox = x0 + VIEW_MARGIN_MM - r0;
        let oy = VIEW_MARGIN_MM - d0;
        let at = |p: &Vector3<f64>| (ox + p.dot(&view.right), oy + p.dot(&view.down));
        let _ = writeln!(svg, r#"<g>"#);
        let _ = writeln!(
            svg,
            r#"<text x="{:.3}" y="{:.3}" font-size="{}">{}</text>"#,
            x0 + 2.0,
            TEXT_MM + 1.0,
            TEXT_MM,
            xml(&view.title)
        );
        // Painter's order: far parts first.
        enum Part<'a> {
            Plate,
            Strut(&'a super::geometry::Strut),
            Sphere(&'a super::geometry::SphereFeature),
        }
        let mut parts: Vec<(f64, Part)> = Vec::new();
        parts.push((marker.plate.centre.dot(&view.forward), Part::Plate));
        for s in &marker.struts {
            parts.push((
                s.a.dot(&view.forward).max(s.b.dot(&view.forward)),
                Part::Strut(s),
            ));
        }
        for s in &marker.spheres {
            parts.push((s.centre.dot(&view.forward), Part::Sphere(s)));
        }
        parts.sort_by(|a, b| b.0.total_cmp(&a.0));
        for (_, part) in &parts {
            match part {
                Part::Plate => {
                    let p = &marker.plate;
                    let w = 2.0 * p.half_extents.dot(&view.right.abs());
                    let h = 2.0 * p.half_extents.dot(&view.down.abs());
                    let (cx, cy) = at(&p.centre);
                    let _ = writeln!(
                        svg,
                        r##"<rect x="{:.3}" y="{:.3}" width="{:.3}" height="{:.3}" rx="{:.3}" fill="#d8d8d8" stroke="#555" stroke-width="0.3"/>"##,
                        cx - w / 2.0,
                        cy - h / 2.0,
                        w,
                        h,
                        p.rounding
                    );
                    for hole in &p.holes {
                        let (hx, hy) = at(&hole.centre);
                        if hole.axis.dot(&view.forward).abs() > 0.5 {
                            let _ = writeln!(
                                svg,
                                r##"<circle cx="{hx:.3}" cy="{hy:.3}" r="{:.3}" fill="#fff" stroke="#555" stroke-width="0.3"/>"##,
                                hole.radius
                            );
                        } else {
                            let along_right = hole.axis.dot(&view.right).abs() > 0.5;
                            let (hw, hh) = if along_right {
                                (w, 2.0 * hole.radius)
                            } else {
                                (2.0 * hole.radius, h)
                            };
                            let _ = writeln!(
                                svg,
                                r##"<rect x="{:.3}" y="{:.3}" width="{:.3}" height="{:.3}" fill="none" stroke="#555" stroke-width="0.25" stroke-dasharray="1 1"/>"##,
                                hx - hw / 2.0,
                                hy - hh / 2.0,
                                hw,
                                hh
                            );
                        }
                    }
                }
                Part::Strut(s) => {
                    let (ax, ay) = at(&s.a);
                    let (bx, by) = at(&s.b);
                    let _ = writeln!(
                        svg,
                        r##"<line x1="{ax:.3}" y1="{ay:.3}" x2="{bx:.3}" y2="{by:.3}" stroke="#555" stroke-width="{:.3}" stroke-linecap="round"/><line x1="{ax:.3}" y1="{ay:.3}" x2="{bx:.3}" y2="{by:.3}" stroke="#aaa" stroke-width="{:.3}" stroke-linecap="round"/>"##,
                        2.0 * s.radius,
                        (2.0 * s.radius - 0.6).max(0.1)
                    );
                }
                Part::Sphere(s) => {
                    let (cx, cy) = at(&s.centre);
                    let _ = writeln!(
                        svg,
                        r##"<circle cx="{cx:.3}" cy="{cy:.3}" r="{:.3}" fill="#fff" stroke="#000" stroke-width="0.4"/><text x="{cx:.3}" y="{:.3}" text-anchor="middle" font-size="{:.2}">{}</text>"##,
                        s.radius,
                        cy + 0.35 * TEXT_MM * 0.8,
                        TEXT_MM * 0.8,
                        xml(&s.name)
                    );
                }
            }
        }
        if index == top {
            let (x, y) = at(&datum.origin_mm);
            let _ = writeln!(
                svg,
                r##"<path class="datum-origin" d="M {:.3},{y:.3} a 1.5,1.5 0 1,0 3,0 a 1.5,1.5 0 1,0 -3,0 M {:.3},{y:.3} h 5 M {x:.3},{:.3} v 5" fill="none" stroke="#c00" stroke-width="0.3"/>"##,
                x - 1.5,
                x - 2.5,
                y - 2.5
            );
        }
        for &(along_right, k) in &plan[index] {
            let mut features: Vec<(String, Vector3<f64>)> = marker
                .spheres
                .iter()
                .map(|s| (s.name.clone(), s.centre))
                .collect();
            if k != 2 {
                features.extend(
                    marker
                        .plate
                        .holes
                        .iter()
                        .enumerate()
                        .map(|(h, hole)| (format!("H{}", h + 1), hole.centre)),
                );
            }
            ordinates(
                &mut svg,
                &datum,
                k,
                &features,
                &OrdinateFrame {
                    along_right,
                    at: &at,
                    baseline: if along_right {
                        oy + d0 - ORDINATE_OFFSET_MM
                    } else {
                        ox + r0 - ORDINATE_OFFSET_MM
                    },
                },
            );
        }
        // Overall dimensions: width below, height on the right.
        let (left, right) = (ox + r0, ox + r1);
        let (top, bottom) = (oy + d0, oy + d1);
        let dim_y = bottom + 8.0;
        let dim_x = right + 8.0;
        let _ = writeln!(
            svg,
            r##"<g stroke="#333" stroke-width="0.25" fill="none"><line x1="{left:.3}" y1="{bottom:.3}" x2="{left:.3}" y2="{:.3}"/><line x1="{right:.3}" y1="{bottom:.3}" x2="{right:.3}" y2="{:.3}"/><line x1="{left:.3}" y1="{dim_y:.3}" x2="{right:.3}" y2="{dim_y:.3}" marker-start="url(#arrow)" marker-end="url(#arrow)"/><line x1="{right:.3}" y1="{top:.3}" x2="{:.3}" y2="{top:.3}"/><line x1="{right:.3}" y1="{bottom:.3}" x2="{:.3}" y2="{bottom:.3}"/><line x1="{dim_x:.3}" y1="{top:.3}" x2="{dim_x:.3}" y2="{bottom:.3}" marker-start="url(#arrow)" marker-end="url(#arrow)"/></g>"##,
            dim_y + 2.0,
            dim_y + 2.0,
            dim_x + 2.0,
            dim_x + 2.0
        );
        let _ = writeln!(
            svg,
            r#"<text x="{:.3}" y="{:.3}" text-anchor="middle">{:.1}</text><text x="{:.3}" y="{:.3}" text-anchor="middle" transform="rotate(-90 {:.3} {:.3})">{:.1}</text>"#,
            0.5 * (left + right),
            dim_y - 1.0,
            r1 - r0,
            dim_x - 1.0,
            0.5 * (top + bottom),
            dim_x - 1.0,
            0.5 * (top + bottom),
            d1 - d0
        );
        let _ = writeln!(svg, "</g>");
        x0 += width;
    }
    svg.push_str("</svg>\n");
    svg
}

/// Where one ordinate dimension goes in a view.
struct OrdinateFrame<'a> {
    /// Along the view's right (labels above the part) or down (labels to
    /// its left).
    along_right: bool,
    /// Marker point → SVG coordinates.
    at: &'a dyn Fn(&Vector3<f64>) -> (f64, f64),
    /// The baseline's SVG coordinate (y when along right, x when down).
    baseline: f64,
}

/// Draws ordinate dimensions of datum coordinate `k` for `features` and
/// the datum face itself (0): an extension line from each feature to the
/// baseline and a label with its names and value; features with the same
/// value share a label, and labels closer than [`ORDINATE_SPACING_MM`] are
/// jogged apart.
fn ordinates(
    svg: &mut String,
    datum: &Datum,
    k: usize,
    features: &[(String, Vector3<f64>)],
    frame: &OrdinateFrame,
) {
    let face = ["B", "C", "A"][k];
    let axis = ["X", "Y", "Z"][k];
    let screen_of = |p: &Vector3<f64>| {
        let (x, y) = (frame.at)(p);
        if frame.along_right {
            (x, y)
        } else {
            (y, x)
        }
    };
    // (position along the baseline, value, names, feature's other screen
    // coordinate).
    let mut ticks: Vec<(f64, f64, Vec<String>, Option<f64>)> = Vec::new();
    // The datum face: the origin projected on this axis.
    let (origin_along, _) = screen_of(&datum.origin_mm);
    ticks.push((origin_along, 0.0, vec![format!("face {face}")], None));
    for (name, p) in features {
        let value = datum.coordinates(p)[k];
        let (along, across) = screen_of(p);
        match ticks
            .iter_mut()
            .find(|t| t.3.is_some() && (t.1 - value).abs() < 0.005)
        {
            Some(t) => t.2.push(name.clone()),
            None => ticks.push((along, value, vec![name.clone()], Some(across))),
        }
    }
    ticks.sort_by(|a, b| a.0.total_cmp(&b.0));
    // Labels spread apart along the baseline, centred on their ticks.
    let mut placed: Vec<f64> = ticks.iter().map(|t| t.0).collect();
    for i in 1..placed.len() {
        placed[i] = placed[i].max(placed[i - 1] + ORDINATE_SPACING_MM);
    }
    let size = 0.7 * TEXT_MM;
    let b = frame.baseline;
    // Outward: up (−y) for labels above, left (−x) for labels at the left.
    let jog = 2.0;
    let _ = writeln!(
        svg,
        r##"<g class="ordinates" data-datum="{axis}" stroke-width="0.15" fill="none">"##
    );
    for (tick, label_at) in ticks.iter().zip(&placed) {
        let (along, value, names, across) = tick;
        let point = |a: f64, c: f64| {
            if frame.along_right {
                (a, c)
            } else {
                (c, a)
            }
        };
        let mut path = Vec::new();
        if let Some(across) = across {
            path.push(point(*along, *across));
        }
        path.push(point(*along, b));
        path.push(point(*label_at, b - jog));
        let points: Vec<String> = path.iter().map(|(x, y)| format!("{x:.3},{y:.3}")).collect();
        let _ = writeln!(
            svg,
            r##"<polyline points="{}" stroke="{}" stroke-dasharray="{}"/>"##,
            points.join(" "),
            if across.is_some() { "#777" } else { "#000" },
            if across.is_some() { "0.8 0.6" } else { "none" }
        );
        let (tx, ty) = point(*label_at, b - jog - 0.8);
        let text = format!("{} {value:.2}", names.join(","));
        if frame.along_right {
            let (tx, ty) = (tx + 0.35 * size, ty);
            let _ = writeln!(
                svg,
                r##"<text class="ordinate" data-datum="{axis}" data-mm="{value:.3}" x="{tx:.3}" y="{ty:.3}" font-size="{size:.2}" fill="#000" stroke="none" text-anchor="start" transform="rotate(-90 {tx:.3} {ty:.3})">{}</text>"##,
                xml(&text)
            );
        } else {
            let _ = writeln!(
                svg,
                r##"<text class="ordinate" data-datum="{axis}" data-mm="{value:.3}" x="{tx:.3}" y="{:.3}" font-size="{size:.2}" fill="#000" stroke="none" text-anchor="end">{}</text>"##,
                ty + 0.35 * size,
                xml(&text)
            );
        }
    }
    let _ = writeln!(svg, "</g>");
}

/// Escapes text for XML.
fn xml(text: &str) -> String {
    text.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::layout::Layout;
    use crate::mesh::MarkerOptions;

    #[test]
    fn paper_biprism_cannot_be_identified_by_distances() {
        let marker = Marker::design(&Layout::paper_biprism(), &MarkerOptions::default()).unwrap();
        let pairs = pairwise_distances(&marker);
        assert_eq!(pairs.len(), 21);
        assert!((pairs[0].2 - 50.0).abs() < 1e-12);
        assert!((pairs[20].2 - 100.0).abs() < 1e-12);
        // Six arms of 50 mm: the margin is zero.
        assert_eq!(identification_margin(&marker).0, 0.0);
    }

    /// A design the search found identifiable from one image gets no
    /// distance-margin warning; one it did not, or a layout that does not
    /// say, keeps it.
    #[test]
    fn no_distance_warning_for_a_design_one_image_identifies() {
        let marker = Marker::design(&Layout::paper_biprism(), &MarkerOptions::default()).unwrap();
        let tolerances = Tolerances {
            centre: None,
            basis: String::new(),
            diameter_mm: 0.1,
            hole_position_mm: 0.2,
        };
        let provenance = |identifiable: usize| serde_json::json!({"identifiability": {"identifiable": identifiable, "visible": 191}});
        let everywhere = OneImageIdentifiability::from_provenance(Some(&provenance(191)));
        assert_eq!(
            everywhere,
            Some(OneImageIdentifiability {
                identifiable: 191,
                visible: 191
            })
        );
        let text = margin_warning(&marker, &tolerances, everywhere);
        assert!(!text.contains("Warning"), "{text}");
        assert!(text.contains("all 191 visible scenarios"), "{text}");
        let partly = OneImageIdentifiability::from_provenance(Some(&provenance(190)));
        for one_image in [partly, None] {
            let text = margin_warning(&marker, &tolerances, one_image);
            assert!(text.contains("Warning: repeated distances"), "{text}");
        }
        assert_eq!(
            OneImageIdentifiability::from_provenance(Some(&serde_json::json!({"seed": 7}))),
            None
        );
    }

    /// The views of the paper's biprism (591 mm wide side by side at 1:1)
    /// go on A3 at 1:2, and the sheet says so.
    #[test]
    fn views_fit_a3_at_a_stated_scale() {
        assert_eq!(page(250.0, 150.0), ("A4", 297.0, 210.0, 1.0));
        assert_eq!(page(591.0, 211.0), ("A3", 420.0, 297.0, 2.0));
        assert_eq!(page(8000.0, 100.0), ("A3", 420.0, 297.0, 20.0));
        let marker = Marker::design(&Layout::paper_biprism(), &MarkerOptions::default()).unwrap();
        let svg = views_svg(
            &marker,
            (Vector3::repeat(-60.0), Vector3::new(60.0, 60.0, 75.0)),
        );
        let head = svg.lines().next().unwrap();
        assert!(head.contains(r#"width="420mm" height="297mm""#), "{head}");
        assert!(
            svg.contains("Scale 1:2 on A3 landscape (420 × 297 mm)"),
            "{svg}"
        );
    }

    #[test]
    fn csv_lists_spheres_distances_and_margin() {
        let marker = Marker::design(&Layout::paper_biprism(), &MarkerOptions::default()).unwrap();
        let tolerances = Tolerances::for_marker(&marker);
        let text = String::from_utf8(csv_table(&marker, &tolerances)).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines[0], CSV_HEADER.join(","));
        assert!(
            lines[1].starts_with("sphere,O0,0.000000,0.000000,0.000000,10.000000,,"),
            "{}",
            lines[1]
        );
        assert!(lines[1].ends_with(",,,,,"), "blank as-measured columns");
        assert_eq!(lines.len(), 1 + 7 + 21 + 1);
        assert!(lines[8].starts_with("distance,O0-P1,"), "{}", lines[8]);
    }
}
