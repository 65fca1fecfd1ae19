//! `layout-opt export` end to end: every shipped layout and seeded random
//! layouts are exported in every format, every file is read back with the
//! crates readers use (`stl_io`, `tobj`, `gltf`), and each mesh must be
//! one body, closed (every edge shared by exactly two faces in opposite
//! directions), outward (positive volume), of Euler characteristic
//! 2 − 2·holes, free of degenerate faces, within 2 % of a Monte-Carlo
//! volume of the analytic solid, with sphere centres fitted from the mesh
//! within 0.05 mm of the layout's and faces within 0.1 mm of the surface.

use crate::export_common::*;
use layout_opt::layout::Layout;
use layout_opt::mesh::geometry::{gltf_rotation, print_rotation};
use layout_opt::mesh::workflow::export;
use layout_opt::mesh::{quality, Axis, ExportOptions, Format, Marker, MarkerOptions, MountHoles};
use std::path::{Path, PathBuf};

/// Largest relative difference between the mesh volume and the
/// Monte-Carlo volume of the analytic solid.
const VOLUME_TOLERANCE: f64 = 0.02;
/// Largest distance between a fitted sphere centre and the layout's, mm.
const CENTRE_TOLERANCE_MM: f64 = 0.05;
/// Largest distance of a face from the exact surface at the default
/// resolution, mm.
const SURFACE_TOLERANCE_MM: f64 = 0.1;
/// Monte-Carlo samples per part box.
const MC_SAMPLES_PER_BOX: usize = 20_000;

fn layouts_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("layouts")
}

/// Files of one format in `dir`.
fn file_of(dir: &Path, name: &str, format: Format) -> PathBuf {
    dir.join(format!("{name}.{}", format.name()))
}

/// What one exported layout measured (printed with `--nocapture`).
#[derive(Debug)]
#[allow(dead_code)] // read through Debug
struct Figures {
    faces: usize,
    edges: usize,
    euler_characteristic: i64,
    volume_mm3: f64,
    mc_volume_mm3: f64,
    mc_standard_error_mm3: f64,
    max_volume_deviation: f64,
    max_centre_error_mm: f64,
    max_radius_error_mm: f64,
    max_surface_error_mm: f64,
}

/// Export options for `formats`, seen along `view`, mounted along `mount`
/// with the given mounting holes (e.g. "M3"), at the default resolution.
fn options_with(
    formats: Vec<Format>,
    view: Axis,
    mount: Axis,
    holes: Option<&str>,
) -> ExportOptions {
    ExportOptions {
        formats,
        marker: MarkerOptions {
            view,
            mount,
            mount_holes: holes.map(|h| h.parse::<MountHoles>().unwrap()),
            ..Default::default()
        },
        resolution_mm: None,
        allow_occlusion: true,
        working_range: None,
    }
}

/// Exports, reads every format back and checks every acceptance criterion.
fn export_and_check(layout: &Layout, options: &ExportOptions, label: &str) -> Figures {
    let dir = tempfile::tempdir().unwrap();
    let report = export(layout, options, dir.path())
        .unwrap_or_else(|e| panic!("{label}: export failed: {e}"));
    let marker = Marker::design(layout, &options.marker).unwrap();
    // The design keeps every sphere exactly where the layout puts it.
    for (sphere, point) in marker.spheres.iter().zip(&layout.points) {
        assert_eq!(sphere.centre, point.position, "{label}");
    }
    let expected_chi = 2 - 2 * marker.plate.holes.len() as i64;
    let (mc_volume, mc_error) = monte_carlo_volume(&marker, MC_SAMPLES_PER_BOX, 7);
    let mut figures = Figures {
        faces: report.mesh.topology.faces,
        edges: report.mesh.topology.edges,
        euler_characteristic: report.mesh.topology.euler_characteristic,
        volume_mm3: report.mesh.topology.signed_volume_mm3,
        mc_volume_mm3: mc_volume,
        mc_standard_error_mm3: mc_error,
        max_volume_deviation: 0.0,
        max_centre_error_mm: 0.0,
        max_radius_error_mm: 0.0,
        max_surface_error_mm: 0.0,
    };
    let name = layout_opt::mesh::file_stem(&layout.name);
    for &format in &options.formats {
        let path = file_of(dir.path(), &name, format);
        let mesh = match format {
            Format::Stl => read_stl(&path, &marker),
            Format::ThreeMf => read_3mf(&path, &marker),
            Format::Obj => read_obj(&path),
            Format::Gltf | Format::Glb => read_gltf(&path, &marker),
        };
        let what = format!("{label}, {format}");
        let s = soundness(&mesh);
        assert_eq!(s.components, 1, "{what}: one connected body");
        assert_eq!(
            s.bad_edges, 0,
            "{what}: every edge shared by two faces, opposite ways"
        );
        assert!(
            s.signed_volume_mm3 > 0.0,
            "{what}: outward, positive volume"
        );
        assert_eq!(
            s.euler_characteristic, expected_chi,
            "{what}: Euler characteristic"
        );
        assert_eq!(s.degenerate_faces, 0, "{what}: no degenerate faces");
        assert_eq!(
            s.faces, report.mesh.topology.faces,
            "{what}: all faces written"
        );
        let deviation = (s.signed_volume_mm3 - mc_volume) / mc_volume;
        assert!(
            deviation.abs() < VOLUME_TOLERANCE,
            "{what}: volume {:.1} vs Monte-Carlo {mc_volume:.1} ± {mc_error:.1} mm³",
            s.signed_volume_mm3
        );
        figures.max_volume_deviation = figures.max_volume_deviation.max(deviation.abs());
        for (sphere, centre_error, radius_error, used) in sphere_fits(&marker, &mesh) {
            assert!(
                used >= 50,
                "{what}: only {used} vertices on sphere {sphere}"
            );
            assert!(
                centre_error < CENTRE_TOLERANCE_MM,
                "{what}: sphere {sphere} centre off by {centre_error} mm"
            );
            assert!(
                radius_error < CENTRE_TOLERANCE_MM,
                "{what}: sphere {sphere} radius off by {radius_error} mm"
            );
            figures.max_centre_error_mm = figures.max_centre_error_mm.max(centre_error);
            figures.max_radius_error_mm = figures.max_radius_error_mm.max(radius_error);
        }
        if format == Format::Stl {
            let back = layout_opt::mesh::TriangleMesh {
                positions: mesh.positions.clone(),
                triangles: mesh.triangles.iter().map(|t| t.map(|v| v as u32)).collect(),
            };
            figures.max_surface_error_mm = quality::max_surface_error(&marker, &back);
            assert!(
                figures.max_surface_error_mm <= SURFACE_TOLERANCE_MM,
                "{what}: surface error {} mm",
                figures.max_surface_error_mm
            );
        }
    }
    figures
}

#[test]
fn shipped_layouts_export_sound_meshes_in_every_format() {
    for file in ["biprism-paper.json", "tetrahedron.json"] {
        let layout = Layout::load(&layouts_dir().join(file)).unwrap();
        let figures = export_and_check(&layout, &ExportOptions::default(), file);
        println!("{file}: {figures:?}");
    }
}

#[test]
fn shipped_biprism_is_the_built_in_one() {
    let shipped = Layout::load(&layouts_dir().join("biprism-paper.json")).unwrap();
    let built_in = Layout::paper_biprism();
    assert_eq!(shipped.name, built_in.name);
    assert_eq!(shipped.positions(), built_in.positions());
    let names: Vec<&str> = shipped.points.iter().map(|p| p.name.as_str()).collect();
    assert_eq!(names, ["O0", "P1", "P2", "P3", "P4", "P5", "P6"]);
    assert_eq!(shipped.sphere_diameter_mm, 10.0);
}

#[test]
fn shipped_tetrahedron_is_regular_with_its_centre() {
    let layout = Layout::load(&layouts_dir().join("tetrahedron.json")).unwrap();
    layout.validate().unwrap();
    let p = layout.positions();
    assert_eq!(p.len(), 5);
    assert_eq!(p[0], nalgebra::Vector3::zeros());
    for i in 1..5 {
        assert!(
            ((p[i] - p[0]).norm() - 50.0).abs() < 1e-5,
            "vertex {i} at 50 mm"
        );
        for j in i + 1..5 {
            assert!(((p[i] - p[j]).norm() - 50.0 * (8f64 / 3.0).sqrt()).abs() < 1e-5);
        }
    }
}

#[test]
fn mounting_holes_views_and_mounts() {
    let layout = Layout::paper_biprism();
    // View +z with mount −y and M3 holes is `random_layouts_export_sound_meshes`'
    // case 1.
    let cases = [
        (Axis::POS_Z, Axis::POS_Z, Some("M4x4")),
        (Axis::POS_X, Axis::NEG_Z, Some("M3")),
        (Axis::NEG_Y, Axis::POS_X, None),
    ];
    for (view, mount, holes) in cases {
        let options = options_with(vec![Format::Stl, Format::Glb], view, mount, holes);
        let label = format!("view {view}, mount {mount}, holes {holes:?}");
        let figures = export_and_check(&layout, &options, &label);
        println!("{label}: {figures:?}");
    }
}

#[test]
fn random_layouts_export_sound_meshes() {
    // Seeded: case k of stream 31 under seed 2024 (see random_layout).
    let options_for = |case: u64| {
        let (view, mount, holes) = match case % 4 {
            0 => (Axis::POS_Z, Axis::NEG_Y, None),
            1 => (Axis::POS_Z, Axis::NEG_Y, Some("M3")),
            2 => (Axis::POS_X, Axis::NEG_Z, None),
            _ => (Axis::POS_Z, Axis::POS_Z, Some("M4x4")),
        };
        let mut options = options_with(Format::ALL.to_vec(), view, mount, holes);
        if case % 4 == 3 {
            // The earlier routed structure stays tested.
            options.marker.structure = layout_opt::mesh::geometry::Structure::Routed;
        }
        options
    };
    // Six cases: every option set, and 4, 9, 7, 5, 10 and 8 points; each
    // case meshes and checks every format, about 1.5 s apiece on this
    // machine (the whole suite is CPU-bound on two cores).
    for case in 0..6 {
        let count = 4 + (case as usize * 5) % 7; // 4..=10 points
        let layout = random_layout(2024, case, count, 100.0);
        let figures = export_and_check(&layout, &options_for(case), &layout.name);
        println!("{} ({count} points): {figures:?}", layout.name);
    }
}

#[test]
fn file_frames_are_as_documented() {
    // Mount −y: STL is (x, −z, y) in mm, glTF is the marker frame in metres.
    assert_eq!(
        print_rotation(Axis::NEG_Y),
        rows([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])
    );
    assert_eq!(gltf_rotation(Axis::NEG_Y), nalgebra::Matrix3::identity());
    let layout = Layout::paper_biprism();
    let dir = tempfile::tempdir().unwrap();
    let options = ExportOptions {
        formats: vec![Format::Stl, Format::Gltf],
        ..Default::default()
    };
    export(&layout, &options, dir.path()).unwrap();
    // Raw STL: Z up, the base plate behind the spheres (view +z) on the bed
    // at z = 0: (x, −y, −z) shifted up by the bed face's depth.
    let marker = Marker::design(&layout, &options.marker).unwrap();
    assert_eq!(marker.down, Axis::POS_Z);
    assert_eq!(
        print_rotation(Axis::POS_Z),
        rows([[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]])
    );
    let raw = std::fs::read(dir.path().join("biprism-paper.stl")).unwrap();
    let header = String::from_utf8_lossy(&raw[..80]);
    assert!(
        header.contains("part biprism-paper; units mm"),
        "the STL header names the part and its units: {header}"
    );
    let mut file = std::fs::File::open(dir.path().join("biprism-paper.stl")).unwrap();
    let stl = stl_io::read_stl(&mut file).unwrap();
    let lowest_z = stl
        .vertices
        .iter()
        .map(|v| v[2])
        .fold(f32::INFINITY, f32::min);
    let highest_z = stl
        .vertices
        .iter()
        .map(|v| v[2])
        .fold(f32::NEG_INFINITY, f32::max);
    assert!(lowest_z.abs() < 0.01, "the plate on the bed, {lowest_z}");
    let level = marker.bed_face_level() as f32;
    assert!(
        (highest_z - (level + 55.0)).abs() < 1e-3,
        "P3's top (z = −55 mm) highest: {highest_z}"
    );
    // Raw glTF: metres, Y up, P3's top at 0.055 m.
    let gltf = std::fs::read(dir.path().join("biprism-paper.gltf")).unwrap();
    let document = gltf::Gltf::from_slice(&gltf).unwrap();
    let accessor = document.accessors().next().unwrap();
    let max_y = accessor.max().unwrap()[1].as_f64().unwrap();
    assert!((max_y - 0.055).abs() < 1e-6, "{max_y}");
    assert!(dir.path().join("biprism-paper.bin").exists());
}

#[test]
fn fabrication_sheet_lists_spheres_distances_and_margin() {
    let layout = Layout::load(&layouts_dir().join("tetrahedron.json")).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let options = ExportOptions {
        formats: vec![Format::Obj],
        ..Default::default()
    };
    let report = export(&layout, &options, dir.path()).unwrap();
    let md = std::fs::read_to_string(dir.path().join("tetrahedron-fabrication.md")).unwrap();
    assert!(
        md.contains("| T1 | 28.868 | 28.868 | 28.868 | 10.000 |"),
        "{md}"
    );
    assert!(md.contains("| O0–T1 | 50.000 |"), "{md}");
    assert!(md.contains("| T1–T2 | 81.650 |"), "{md}");
    assert!(md.contains("**Identification margin**"));
    assert!(md.contains("Bounding box"));
    assert!(md.contains("Volume:"));
    assert!(md.contains("tetrahedron-views.svg"));
    // Tolerances, the datum, the as-measured columns and the warning of
    // repeated distances.
    assert!(md.contains("## Tolerances"), "{md}");
    assert!(md.contains("**Sphere centres: ±"), "{md}");
    assert!(md.contains("**Datum A**"), "{md}");
    assert!(
        md.contains("| measured X | measured Y | measured Z |"),
        "{md}"
    );
    assert!(md.contains("Warning: repeated distances"), "{md}");
    let centre = report.tolerances.centre.as_ref().unwrap();
    assert!(
        centre.tolerance_mm > 0.0 && centre.tolerance_mm < 1.0,
        "{centre:?}"
    );
    assert_eq!(report.datum.len(), 5);
    // A regular tetrahedron has only two distinct distances: margin 0.
    assert!(report.identification_margin_mm.abs() < 1e-5);
    let csv = std::fs::read_to_string(dir.path().join("tetrahedron-fabrication.csv")).unwrap();
    assert_eq!(csv.lines().count(), 1 + 5 + 10 + 1);
    let svg = std::fs::read_to_string(dir.path().join("tetrahedron-views.svg")).unwrap();
    assert!(svg.starts_with("<svg") && svg.trim_end().ends_with("</svg>"));
    assert_eq!(
        svg.matches("<circle").count(),
        3 * 5,
        "five spheres in three views"
    );
    assert!(svg.contains("main view"));
    let json = std::fs::read_to_string(dir.path().join("tetrahedron-export.json")).unwrap();
    let value: serde_json::Value = serde_json::from_str(&json).unwrap();
    assert_eq!(value["mesh"]["topology"]["euler_characteristic"], 2);
}

#[test]
fn struts_cover_no_sphere_of_the_shipped_layouts_in_the_main_view() {
    for file in ["biprism-paper.json", "tetrahedron.json"] {
        let layout = Layout::load(&layouts_dir().join(file)).unwrap();
        let marker = Marker::design(&layout, &MarkerOptions::default()).unwrap();
        for coverage in quality::main_view_coverage(&marker) {
            assert_eq!(coverage.covered_by_struts, 0.0, "{file}: {coverage:?}");
        }
    }
}

/// An eight-point layout that is not a family member.
fn custom_eight() -> Layout {
    let points = [
        [0.0, 0.0, 0.0],
        [45.0, 5.0, -30.0],
        [-40.0, 35.0, -10.0],
        [10.0, -45.0, 20.0],
        [-30.0, -25.0, 40.0],
        [35.0, 40.0, 25.0],
        [-5.0, 15.0, -45.0],
        [25.0, -15.0, 45.0],
    ];
    Layout {
        name: "custom-8".into(),
        points: points
            .iter()
            .enumerate()
            .map(|(i, p)| layout_opt::layout::LayoutPoint::new(format!("S{i}"), (*p).into()))
            .collect(),
        sphere_diameter_mm: 10.0,
        family: None,
        provenance: None,
    }
}

#[test]
fn printable_parts_stand_on_the_bed_without_support() {
    let layouts = [
        Layout::load(&layouts_dir().join("biprism-paper.json")).unwrap(),
        Layout::load(&layouts_dir().join("tetrahedron.json")).unwrap(),
        Layout::load(&layouts_dir().join("biprism-search.json")).unwrap(),
        custom_eight(),
    ];
    for layout in &layouts {
        let dir = tempfile::tempdir().unwrap();
        let options = ExportOptions {
            formats: vec![Format::Stl],
            ..Default::default()
        };
        let start = std::time::Instant::now();
        let report =
            export(layout, &options, dir.path()).unwrap_or_else(|e| panic!("{}: {e}", layout.name));
        let seconds = start.elapsed().as_secs_f64();
        let volume = report.mesh.topology.signed_volume_mm3;
        let o = &report.overhang;
        println!(
            "{}: volume {volume:.0} mm³, overhang {:.1} mm² (+{:.1} on spheres), support estimate {:.0} mm³, {seconds:.2} s",
            layout.name, o.area_mm2, o.sphere_area_mm2, o.support_estimate_mm3
        );
        assert!(
            o.support_estimate_mm3 <= 0.02 * volume,
            "{}: support {:.0} mm³ for {volume:.0} mm³",
            layout.name,
            o.support_estimate_mm3
        );
        assert!(
            o.bed_contact_mm2 > 500.0,
            "{}: stands on its plate",
            layout.name
        );
        let mut file =
            std::fs::File::open(dir.path().join(format!("{}.stl", layout.name))).unwrap();
        let stl = stl_io::read_stl(&mut file).unwrap();
        let lowest = stl
            .vertices
            .iter()
            .map(|v| v[2])
            .fold(f32::INFINITY, f32::min);
        assert!(
            lowest.abs() < 0.01,
            "{}: lowest point at z = {lowest}",
            layout.name
        );
        // Every sphere that no other sphere hides from the view cone is
        // covered by no strut from it.
        for c in &report.main_view_coverage {
            if c.cone_covered_by_spheres == 0.0 {
                assert_eq!(c.cone_covered_by_struts, 0.0, "{}: {c:?}", layout.name);
            }
        }
    }
}

#[test]
fn a_part_larger_than_the_bed_is_refused() {
    let mut layout = Layout::paper_biprism();
    for p in &mut layout.points {
        p.position *= 10.0;
    }
    let dir = tempfile::tempdir().unwrap();
    let error = export(&layout, &ExportOptions::default(), dir.path()).unwrap_err();
    let text = error.to_string();
    assert!(
        text.contains("does not fit the build volume 250 × 210 × 210 mm"),
        "{text}"
    );
    assert_eq!(
        std::fs::read_dir(dir.path()).unwrap().count(),
        0,
        "nothing written"
    );
}

#[test]
fn drawing_dimensions_match_the_mesh() {
    let layout = Layout::load(&layouts_dir().join("tetrahedron.json")).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let options = ExportOptions {
        formats: vec![Format::Obj],
        ..Default::default()
    };
    export(&layout, &options, dir.path()).unwrap();
    let mesh = read_obj(&dir.path().join("tetrahedron.obj"));
    let lo = mesh
        .positions
        .iter()
        .fold(nalgebra::Vector3::repeat(f64::INFINITY), |a, p| a.inf(p));
    let hi = mesh
        .positions
        .iter()
        .fold(nalgebra::Vector3::repeat(f64::NEG_INFINITY), |a, p| {
            a.sup(p)
        });
    let extents = hi - lo;
    let svg = std::fs::read_to_string(dir.path().join("tetrahedron-views.svg")).unwrap();
    // The overall dimensions: the numbers written as dimension texts.
    let numbers: Vec<f64> = svg
        .split(r#"text-anchor="middle""#)
        .skip(1)
        .filter_map(|rest| {
            let text = rest.split_once('>')?.1.split_once('<')?.0;
            text.trim().parse::<f64>().ok()
        })
        .collect();
    assert_eq!(
        numbers.len(),
        6,
        "width and height of three views: {numbers:?}"
    );
    for n in &numbers {
        assert!(
            extents.iter().any(|e| (e - n).abs() <= 0.1),
            "dimension {n} matches no extent of the mesh {extents:?}"
        );
    }
}

/// A CSV row of the sheet: name, datum x, y, z, diameter.
fn sheet_rows(csv: &str, kind: &str) -> Vec<(String, [f64; 3], f64)> {
    let mut reader = csv::Reader::from_reader(csv.as_bytes());
    let header = reader.headers().unwrap().clone();
    let column = |name: &str| header.iter().position(|h| h == name).unwrap();
    let (k, n, d) = (column("kind"), column("name"), column("diameter_mm"));
    let datum = [
        column("datum_x_mm"),
        column("datum_y_mm"),
        column("datum_z_mm"),
    ];
    reader
        .records()
        .map(|r| r.unwrap())
        .filter(|r| &r[k] == kind)
        .map(|r| {
            (
                r[n].to_string(),
                datum.map(|c| r[c].parse::<f64>().unwrap()),
                r[d].parse::<f64>().unwrap(),
            )
        })
        .collect()
}

/// The ordinate labels of one datum axis in the views: (names, value).
fn ordinate_labels(svg: &str, axis: &str) -> Vec<(Vec<String>, f64)> {
    let marker = format!(r#"class="ordinate" data-datum="{axis}" data-mm=""#);
    svg.split(&marker)
        .skip(1)
        .map(|rest| {
            let value: f64 = rest.split('"').next().unwrap().parse().unwrap();
            let text = rest.split_once('>').unwrap().1.split_once('<').unwrap().0;
            let names = text.rsplit_once(' ').unwrap().0;
            (names.split(',').map(str::to_string).collect(), value)
        })
        .collect()
}

/// The sheet and the drawing place every sphere and hole from the datum on
/// the plate (its bed face and two side faces), and so does the mesh: the
/// faces found in the STL and the sphere and hole centres fitted to its
/// vertices agree with the sheet to 0.1 mm.
#[test]
fn datum_positions_match_the_mesh() {
    let layout = Layout::load(&layouts_dir().join("biprism-search.json")).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let options = ExportOptions {
        formats: vec![Format::Stl],
        marker: MarkerOptions {
            mount_holes: Some("M3x4".parse().unwrap()),
            ..Default::default()
        },
        ..Default::default()
    };
    export(&layout, &options, dir.path()).unwrap();
    let name = &layout.name;
    let mut file = std::fs::File::open(dir.path().join(format!("{name}.stl"))).unwrap();
    let stl = stl_io::read_stl(&mut file).unwrap();
    let vertices: Vec<nalgebra::Vector3<f64>> = stl
        .vertices
        .iter()
        .map(|v| nalgebra::Vector3::new(v[0] as f64, v[1] as f64, v[2] as f64))
        .collect();
    // Datum A at z = 0; B and C are the plate's side faces, the extremes of
    // the flat band of the 4 mm plate's sides.
    let lowest = vertices.iter().map(|v| v.z).fold(f64::INFINITY, f64::min);
    assert!(lowest.abs() < 0.01, "{lowest}");
    let band: Vec<&nalgebra::Vector3<f64>> = vertices
        .iter()
        .filter(|v| (1.5..=2.5).contains(&v.z))
        .collect();
    let face_b = band.iter().map(|v| v.x).fold(f64::INFINITY, f64::min);
    let face_c = band.iter().map(|v| v.y).fold(f64::INFINITY, f64::min);
    let origin = nalgebra::Vector3::new(face_b, face_c, 0.0);
    let csv = std::fs::read_to_string(dir.path().join(format!("{name}-fabrication.csv"))).unwrap();
    let svg = std::fs::read_to_string(dir.path().join(format!("{name}-views.svg"))).unwrap();
    let labels = ["X", "Y", "Z"].map(|axis| ordinate_labels(&svg, axis));
    let spheres = sheet_rows(&csv, "sphere");
    assert_eq!(spheres.len(), layout.points.len());
    for (sphere, datum, diameter) in &spheres {
        let nominal = origin + nalgebra::Vector3::from(*datum);
        let radius = 0.5 * diameter;
        let surface: Vec<nalgebra::Vector3<f64>> = vertices
            .iter()
            .filter(|v| ((*v - nominal).norm() - radius).abs() < 0.1)
            .copied()
            .collect();
        let fit = layout_opt::layout::fit_sphere(&surface)
            .unwrap_or_else(|| panic!("{sphere}: no sphere near {nominal}"));
        let error = fit.centre - nominal;
        assert!(
            error.amax() <= 0.1,
            "{sphere}: the mesh's centre is {error} from the sheet's"
        );
        for (k, axis_labels) in labels.iter().enumerate() {
            assert!(
                axis_labels
                    .iter()
                    // Spheres whose ordinates print alike (two decimals)
                    // share one label, placed at the first one's value.
                    .any(|(names, v)| names.contains(sphere) && (v - datum[k]).abs() < 5e-3),
                "{sphere}: no ordinate {} of {:.3} in the views",
                ["X", "Y", "Z"][k],
                datum[k]
            );
        }
    }
    let holes = sheet_rows(&csv, "hole");
    assert_eq!(holes.len(), 4);
    for (hole, datum, diameter) in &holes {
        let centre = origin + nalgebra::Vector3::from(*datum);
        let wall: Vec<&&nalgebra::Vector3<f64>> = band
            .iter()
            .filter(|v| {
                let r = ((v.x - centre.x).powi(2) + (v.y - centre.y).powi(2)).sqrt();
                (r - 0.5 * diameter).abs() < 0.1
            })
            .collect();
        assert!(wall.len() >= 8, "{hole}: {} wall vertices", wall.len());
        // Kåsa's algebraic circle fit: x² + y² + a·x + b·y + c = 0.
        let mut normal = nalgebra::Matrix3::<f64>::zeros();
        let mut rhs = nalgebra::Vector3::<f64>::zeros();
        for v in &wall {
            let row = nalgebra::Vector3::new(v.x, v.y, 1.0);
            normal += row * row.transpose();
            rhs -= row * (v.x * v.x + v.y * v.y);
        }
        let abc = normal.lu().solve(&rhs).unwrap();
        let fitted = nalgebra::Vector2::new(-0.5 * abc.x, -0.5 * abc.y);
        let error = fitted - centre.xy();
        assert!(
            error.amax() <= 0.1,
            "{hole}: the mesh's hole is {error} from the sheet's"
        );
        for (k, axis_labels) in labels.iter().take(2).enumerate() {
            assert!(
                axis_labels
                    .iter()
                    .any(|(names, v)| names.contains(hole) && (v - datum[k]).abs() < 1e-3),
                "{hole}: no ordinate in the views"
            );
        }
    }
}
