//! The text summary of one export that `layout-opt export` prints: the
//! mesh and its watertightness, the files written, what the struts cover,
//! the sphere-centre tolerance and the print. It renders an
//! [`ExportReport`](super::analysis::ExportReport) and computes nothing new.

use super::analysis::ExportReport;
use std::fmt::Write as _;

/// Lost views printed on the summary line (all are in the export JSON).
const LOST_VIEWS_SHOWN: usize = 8;

/// The export's summary, one line per fact, each ending in a newline.
pub fn summary(report: &ExportReport) -> String {
    let mut out = String::new();
    let m = &report.mesh;
    let t = &m.topology;
    let _ = writeln!(
        out,
        "{}: {} triangles, {} vertices, volume {:.1} mm³, grid {} mm, meshed in {:.2} s",
        report.name, t.faces, t.vertices, t.signed_volume_mm3, m.resolution_mm, m.seconds
    );
    let _ = writeln!(
        out,
        "watertight: all {} edges shared by exactly 2 faces in opposite directions; {} body; Euler characteristic {} (2 - 2 x {} holes); no degenerate or inverted faces; max surface error {:.3} mm",
        t.edges, t.components, t.euler_characteristic, m.holes, m.max_surface_error_mm
    );
    for file in &report.files {
        let timing = match file.format {
            Some(format) => format!(", {format} in {:.2} s", file.seconds),
            None => String::new(),
        };
        let _ = writeln!(
            out,
            "wrote {} ({}{timing})",
            file.path.display(),
            megabytes(file.bytes)
        );
    }
    let strut_covered = |fraction: f64, sphere: &str| {
        (fraction > 0.0).then(|| format!("{sphere} {:.1} %", 100.0 * fraction))
    };
    let main: Vec<String> = report
        .main_view_coverage
        .iter()
        .filter_map(|c| strut_covered(c.covered_by_struts, &c.sphere))
        .collect();
    let cone: Vec<String> = report
        .main_view_coverage
        .iter()
        .filter_map(|c| strut_covered(c.cone_covered_by_struts, &c.sphere))
        .collect();
    let verdict = |covered: &[String]| {
        if covered.is_empty() {
            "no strut covers a sphere".to_string()
        } else {
            format!("struts cover {}", covered.join(", "))
        }
    };
    let _ = writeln!(
        out,
        "main view ({}): {}; view cone ±{}°: {}{}; identification margin {:.3} mm",
        report.view,
        verdict(&main),
        report.view_cone_deg,
        verdict(&cone),
        if report.occlusion_allowed && !cone.is_empty() {
            " (allowed by --allow-occlusion)"
        } else {
            ""
        },
        report.identification_margin_mm
    );
    if let Some(scenarios) = report.working_range_scenarios {
        let _ = writeln!(
            out,
            "working range ({scenarios} scenarios): {}",
            lost_views(report)
        );
    }
    let _ = match &report.tolerances.centre {
        Some(c) => writeln!(
        out,
            "sphere-centre tolerance ±{:.3} mm per coordinate, from the datum on the plate (keeps the fabrication share of the RMS rotation error at most {:.0} % of the image noise's over {} scenarios; see the sheet)",
            c.tolerance_mm,
            100.0 * c.share,
            c.scenarios
        ),
        None => writeln!(out, "sphere-centre tolerance: none from the error model (no default scenario sees every sphere)"),
    };
    let o = &report.overhang;
    let [x, y, z] = report.print_size_mm;
    let _ = writeln!(
        out,
        "print ({}): {x:.1} × {y:.1} × {z:.1} mm on a {} × {} × {} mm bed, lowest point at z = 0; overhangs steeper than {}° from vertical: {:.1} mm² (plus {:.1} mm² of sphere undersides); support estimate {:.0} mm³ ({:.1} % of the part); {:.0} mm² on the bed",
        report.structure,
        report.bed_mm[0],
        report.bed_mm[1],
        report.bed_mm[2],
        o.limit_deg,
        o.area_mm2,
        o.sphere_area_mm2,
        o.support_estimate_mm3,
        100.0 * o.support_estimate_mm3 / t.signed_volume_mm3,
        o.bed_contact_mm2,
    );
    out
}

/// What the supports still hide in the working range, in words.
fn lost_views(report: &ExportReport) -> String {
    let mut lost: Vec<usize> = report.lost_views.iter().map(|l| l.scenario.index).collect();
    lost.dedup();
    if lost.is_empty() {
        return "the supports hide no sphere in any view the spheres leave visible".to_string();
    }
    let views: Vec<String> = report
        .lost_views
        .iter()
        .take(LOST_VIEWS_SHOWN)
        .map(|l| {
            let s = &l.scenario;
            format!(
                "{} {:.0} % at depth {} x {} y {} tilt {} pan {}",
                sphere_name(report, l.sphere),
                100.0 * l.hidden_fraction,
                s.depth_mm,
                s.offset_x_mm,
                s.offset_y_mm,
                s.tilt_deg,
                s.pan_deg
            )
        })
        .collect();
    format!(
        "{} views lost, no route of the supports clears them: {}{} (all in the export JSON)",
        lost.len(),
        views.join("; "),
        if report.lost_views.len() > LOST_VIEWS_SHOWN {
            "; …"
        } else {
            ""
        }
    )
}

/// The name of sphere `index` in the report's datum table.
fn sphere_name(report: &ExportReport, index: usize) -> String {
    report
        .datum
        .iter()
        .filter(|d| d.kind == "sphere")
        .nth(index)
        .map_or_else(|| format!("sphere {index}"), |d| d.name.clone())
}

/// A file size in kB below 1 MiB, else in MB, one decimal.
pub fn megabytes(bytes: u64) -> String {
    if bytes >= 1 << 20 {
        format!("{:.1} MB", bytes as f64 / (1u64 << 20) as f64)
    } else {
        format!("{:.1} kB", bytes as f64 / 1024.0)
    }
}
