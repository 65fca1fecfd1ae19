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
use super::{write_file, ExportError, Solid};
use nalgebra::{Matrix3, Vector3};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Margin around each view in the SVG, mm.
const VIEW_MARGIN_MM: f64 = 22.0;
/// Text size in the SVG, mm.
const TEXT_MM: f64 = 4.0;
/// Identification margins below this are flagged in the sheet, mm.
pub const MARGIN_WARNING_MM: f64 = 1.0;

/// Every pair of spheres with the distance between their centres, sorted
/// by distance (ties in layout order).
pub fn pairwise_distances(marker: &Marker) -> Vec<(usize, usize, f64)> {
    let s = &marker.spheres;
    let mut pairs: Vec<(usize, usize, f64)> = (0..s.len())
        .flat_map(|i| (i + 1..s.len()).map(move |j| (i, j)))
        .map(|(i, j)| (i, j, (s[i].centre - s[j].centre).norm()))
        .collect();
    pairs.sort_by(|a, b| a.2.total_cmp(&b.2));
    pairs
}

/// The identification margin (mm) and the two pairs that set it: the
/// smallest difference between two pairwise centre distances.
pub fn identification_margin(marker: &Marker) -> (f64, Option<[(usize, usize); 2]>) {
    let pairs = pairwise_distances(marker);
    pairs
        .windows(2)
        .map(|w| (w[1].2 - w[0].2, Some([(w[0].0, w[0].1), (w[1].0, w[1].1)])))
        .min_by(|a, b| a.0.total_cmp(&b.0))
        .unwrap_or((f64::INFINITY, None))
}

/// Writes the sheet's three files into `dir`.
pub fn write(
    solid: &Solid,
    coverage: &[Coverage],
    dir: &Path,
) -> Result<Vec<PathBuf>, ExportError> {
    let name = solid.name();
    let md = dir.join(format!("{name}-fabrication.md"));
    let csv = dir.join(format!("{name}-fabrication.csv"));
    let svg = dir.join(format!("{name}-views.svg"));
    write_file(&md, markdown(solid, coverage, &svg).as_bytes())?;
    write_file(&csv, &csv_table(&solid.marker))?;
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

fn markdown(solid: &Solid, coverage: &[Coverage], svg: &Path) -> String {
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
    if margin < MARGIN_WARNING_MM {
        let _ = writeln!(
            md,
            "\n> Below {MARGIN_WARNING_MM} mm: these spheres cannot be told apart by their distances alone."
        );
    }

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

fn csv_table(marker: &Marker) -> Vec<u8> {
    let mut writer = csv::Writer::from_writer(Vec::new());
    let f = |v: f64| format!("{v:.6}");
    let _ = writer.write_record([
        "kind",
        "name",
        "x_mm",
        "y_mm",
        "z_mm",
        "diameter_mm",
        "distance_mm",
    ]);
    for s in &marker.spheres {
        let _ = writer.write_record([
            "sphere".to_string(),
            s.name.clone(),
            f(s.centre.x),
            f(s.centre.y),
            f(s.centre.z),
            f(2.0 * s.radius),
            String::new(),
        ]);
    }
    for (i, j, d) in pairwise_distances(marker) {
        let _ = writer.write_record([
            "distance".to_string(),
            format!("{}-{}", marker.spheres[i].name, marker.spheres[j].name),
            String::new(),
            String::new(),
            String::new(),
            String::new(),
            f(d),
        ]);
    }
    let (margin, _) = identification_margin(marker);
    let _ = writer.write_record(["identification_margin", "", "", "", "", "", &f(margin)]);
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
    let mut svg = String::new();
    let _ = writeln!(
        svg,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{:.0}mm" height="{:.0}mm" viewBox="0 0 {:.3} {:.3}" font-family="sans-serif" font-size="{TEXT_MM}">"#,
        total_w, panel_h, total_w, panel_h
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
    let mut x0 = 0.0;
    for (view, width) in views.iter().zip(&panel_w) {
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

    #[test]
    fn csv_lists_spheres_distances_and_margin() {
        let marker = Marker::design(&Layout::paper_biprism(), &MarkerOptions::default()).unwrap();
        let text = String::from_utf8(csv_table(&marker)).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines[0], "kind,name,x_mm,y_mm,z_mm,diameter_mm,distance_mm");
        assert_eq!(lines[1], "sphere,O0,0.000000,0.000000,0.000000,10.000000,");
        assert_eq!(lines.len(), 1 + 7 + 21 + 1);
        assert!(lines[8].starts_with("distance,O0-P1,"), "{}", lines[8]);
    }
}
