//! An independent check of how much a printed part hides its own spheres:
//! a ray cast of the exported mesh (`layout-opt export … --format obj`),
//! triangle by triangle. The mesh side shares nothing with the visibility
//! model but the scenario poses and the camera.
//!
//! ```text
//! cargo run --release --features examples --example raycast_check -- LAYOUT.json PART.obj \
//!     [--depth 400..1000:200] [--offset-x 0..100:50] [--offset-y=-50,0] \
//!     [--tilt=-60..60:10] [--pan=-20..20:20] [--grid 24] [--max-hidden 0.01]
//! ```
//!
//! For every scenario that the spheres alone leave visible
//! ([`layout_opt::scenario::visibility`]) and every sphere, sight lines from
//! the camera centre through a square grid of points over the sphere's
//! silhouette (`--grid` per diameter) are followed to the first triangle
//! they meet (Möller–Trumbore). A line that meets the mesh well before the
//! sphere, at a point that is on no sphere, is hidden by a support.
//!
//! It prints two sets of figures. Over the views the spheres alone leave
//! visible: how many the mesh's supports hide at least 1 % (and 10 %) of a
//! sphere in, and the clean views. Over `validate`'s visible scenarios (the
//! supports counted: the model's supports for the default structure, routed
//! for this grid, hide no more than `--max-hidden` of any sphere): the same
//! counts, which the visibility model promises to be 0, and each view in
//! which the mesh and the model disagree.

use layout_opt::camera::Camera;
use layout_opt::layout::Layout;
use layout_opt::mesh::{supports_for_range, MarkerOptions};
use layout_opt::scenario::{sphere_images, visibility, Range, Scenario, ScenarioGrid};
use layout_opt::visibility::{hidden_fractions, MaxHidden, WorkingRange};
use nalgebra::Vector3;
use rayon::prelude::*;

/// A mesh hit this much nearer than the sphere (mm) and this far from every
/// sphere surface lies on a support (the mesh's surface error is far
/// below it).
const SURFACE_TOLERANCE_MM: f64 = 0.2;

struct Mesh {
    triangles: Vec<[Vector3<f64>; 3]>,
}

fn read_obj(path: &str) -> Mesh {
    let (models, _) = tobj::load_obj(
        path,
        &tobj::LoadOptions {
            triangulate: true,
            single_index: true,
            ..Default::default()
        },
    )
    .unwrap_or_else(|e| panic!("cannot read {path}: {e}"));
    let mut triangles = Vec::new();
    for model in models {
        let m = model.mesh;
        let vertex = |i: u32| {
            let i = i as usize * 3;
            Vector3::new(
                f64::from(m.positions[i]),
                f64::from(m.positions[i + 1]),
                f64::from(m.positions[i + 2]),
            )
        };
        for t in m.indices.chunks(3) {
            triangles.push([vertex(t[0]), vertex(t[1]), vertex(t[2])]);
        }
    }
    Mesh { triangles }
}

/// Möller–Trumbore: the distance along the ray to the triangle.
fn ray_triangle(
    origin: &Vector3<f64>,
    direction: &Vector3<f64>,
    t: &[Vector3<f64>; 3],
) -> Option<f64> {
    let e1 = t[1] - t[0];
    let e2 = t[2] - t[0];
    let p = direction.cross(&e2);
    let det = e1.dot(&p);
    if det.abs() < 1e-14 {
        return None;
    }
    let inv = 1.0 / det;
    let s = origin - t[0];
    let u = s.dot(&p) * inv;
    if !(0.0..=1.0).contains(&u) {
        return None;
    }
    let q = s.cross(&e1);
    let v = direction.dot(&q) * inv;
    if v < 0.0 || u + v > 1.0 {
        return None;
    }
    let distance = e2.dot(&q) * inv;
    (distance > 0.0).then_some(distance)
}

/// Per sphere, the fraction of its silhouette grid hidden by a support.
fn support_hidden(
    mesh: &Mesh,
    scenario: &Scenario,
    centres: &[Vector3<f64>],
    radius: f64,
    grid: usize,
) -> Vec<f64> {
    let pose = scenario.pose();
    let r = pose.rotation.matrix();
    // Triangles in camera coordinates, with their bounds on the normalised
    // image plane (unbounded when a corner is not in front) and nearest
    // depth.
    let cam: Vec<([Vector3<f64>; 3], [f64; 4], f64)> = mesh
        .triangles
        .iter()
        .map(|t| {
            let c = t.map(|p| pose.transform(&p));
            let near = c.iter().map(|p| p.z).fold(f64::INFINITY, f64::min);
            let bounds = if near > 0.0 {
                let xs = c.map(|p| p.x / p.z);
                let ys = c.map(|p| p.y / p.z);
                [
                    xs.iter().copied().fold(f64::INFINITY, f64::min),
                    xs.iter().copied().fold(f64::NEG_INFINITY, f64::max),
                    ys.iter().copied().fold(f64::INFINITY, f64::min),
                    ys.iter().copied().fold(f64::NEG_INFINITY, f64::max),
                ]
            } else {
                [
                    f64::NEG_INFINITY,
                    f64::INFINITY,
                    f64::NEG_INFINITY,
                    f64::INFINITY,
                ]
            };
            (c, bounds, near)
        })
        .collect();
    centres
        .iter()
        .map(|centre| {
            let c = pose.transform(centre);
            let distance = c.norm();
            let axis = c / distance;
            let half = (radius / distance).asin();
            let (e1, e2) = layout_opt::linalg::perpendicular_pair(&axis);
            let tan_half = half.tan();
            // The disc's bounds on the normalised image plane, from its
            // rim, with a margin.
            let mut disc = [
                f64::INFINITY,
                f64::NEG_INFINITY,
                f64::INFINITY,
                f64::NEG_INFINITY,
            ];
            for step in 0..64 {
                let angle = std::f64::consts::TAU * step as f64 / 64.0;
                let d = axis + (e1 * angle.cos() + e2 * angle.sin()) * (1.01 * tan_half);
                disc[0] = disc[0].min(d.x / d.z);
                disc[1] = disc[1].max(d.x / d.z);
                disc[2] = disc[2].min(d.y / d.z);
                disc[3] = disc[3].max(d.y / d.z);
            }
            let candidates: Vec<&[Vector3<f64>; 3]> = cam
                .iter()
                .filter(|(_, b, near)| {
                    *near < distance
                        && b[0] <= disc[1]
                        && b[1] >= disc[0]
                        && b[2] <= disc[3]
                        && b[3] >= disc[2]
                })
                .map(|(t, _, _)| t)
                .collect();
            let (mut total, mut hidden) = (0usize, 0usize);
            for a in 0..grid {
                for b in 0..grid {
                    let u = 2.0 * (a as f64 + 0.5) / grid as f64 - 1.0;
                    let v = 2.0 * (b as f64 + 0.5) / grid as f64 - 1.0;
                    if u * u + v * v > 1.0 {
                        continue;
                    }
                    total += 1;
                    let direction = (axis + (e1 * u + e2 * v) * tan_half).normalize();
                    let origin = Vector3::zeros();
                    let oc = -c;
                    let bq = oc.dot(&direction);
                    let h = (bq * bq - oc.norm_squared() + radius * radius).max(0.0);
                    let t_sphere = -bq - h.sqrt();
                    let nearest = candidates
                        .iter()
                        .filter_map(|t| ray_triangle(&origin, &direction, t))
                        .fold(f64::INFINITY, f64::min);
                    if nearest < t_sphere - SURFACE_TOLERANCE_MM {
                        let hit_object = r.transpose() * (direction * nearest - pose.translation);
                        let on_sphere = centres
                            .iter()
                            .any(|s| (hit_object - s).norm() < radius + SURFACE_TOLERANCE_MM);
                        if !on_sphere {
                            hidden += 1;
                        }
                    }
                }
            }
            hidden as f64 / total.max(1) as f64
        })
        .collect()
}

fn flag(args: &[String], name: &str, default: &str) -> String {
    args.iter()
        .position(|a| a == name)
        .and_then(|i| args.get(i + 1).cloned())
        .or_else(|| {
            args.iter()
                .find_map(|a| a.strip_prefix(&format!("{name}=")).map(str::to_string))
        })
        .unwrap_or_else(|| default.to_string())
}

/// One visible view: the scenario, the mesh's support-hidden fraction per
/// sphere, and the model's.
struct View {
    scenario: Scenario,
    mesh: Vec<f64>,
    model: Vec<f64>,
}

fn worst_of(h: &[f64]) -> f64 {
    h.iter().copied().fold(0.0, f64::max)
}

/// Prints the counts over `views` under `title`.
fn summarise(title: &str, views: &[&View]) {
    let at_least = |share: f64| views.iter().filter(|v| worst_of(&v.mesh) >= share).count();
    let hidden_1 = at_least(0.01);
    println!(
        "{title}: {} visible; a support hides >= 1 % of a sphere in {}, >= 10 % in {}; clean views {}",
        views.len(),
        hidden_1,
        at_least(0.10),
        views.len() - hidden_1
    );
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [layout_path, obj_path] = [&args[0], &args[1]];
    let layout = Layout::load(std::path::Path::new(layout_path)).expect("a layout");
    let mesh = read_obj(obj_path);
    let range = |name: &str, default: &str| -> Range {
        flag(&args, name, default).parse().expect("a range")
    };
    let grid = ScenarioGrid::new(
        range("--depth", "400..1000:200"),
        range("--offset-x", "0..100:50"),
        range("--offset-y", "-50,0"),
        range("--tilt", "-60..60:10"),
        range("--pan", "-20..20:20"),
        Range::single(0.0),
        Range::single(0.5),
    )
    .expect("a grid");
    let rays: usize = flag(&args, "--grid", "24").parse().expect("a count");
    let max_hidden: MaxHidden = flag(&args, "--max-hidden", "0.01")
        .parse()
        .expect("a fraction");
    let camera = Camera::paper();
    let centres = layout.positions();
    let radius = 0.5 * layout.sphere_diameter_mm;
    let working = WorkingRange {
        camera,
        scenarios: grid.scenarios(),
        max_hidden,
    };
    let supports =
        supports_for_range(&layout, &MarkerOptions::default(), &working).expect("supports");
    let views: Vec<View> = grid
        .scenarios()
        .par_iter()
        .filter(|s| {
            let images = sphere_images(&camera, &s.pose(), &centres, layout.sphere_diameter_mm);
            visibility(&images, &camera).is_visible()
        })
        .map(|s| View {
            scenario: *s,
            mesh: support_hidden(&mesh, s, &centres, radius, rays),
            model: hidden_fractions(&camera, &s.pose(), &centres, radius, &supports)
                .iter()
                .map(|f| f.map_or(0.0, |f| f.support))
                .collect(),
        })
        .collect();
    println!(
        "{}: {} triangles; {} scenarios",
        layout.name,
        mesh.triangles.len(),
        grid.len()
    );
    let all: Vec<&View> = views.iter().collect();
    summarise("spheres alone", &all);
    let counted: Vec<&View> = views
        .iter()
        .filter(|v| worst_of(&v.model) <= max_hidden.fraction())
        .collect();
    summarise("supports counted (validate)", &counted);
    let where_ = |s: &Scenario| {
        format!(
            "depth {} x {} y {} tilt {} pan {}",
            s.depth_mm, s.offset_x_mm, s.offset_y_mm, s.tilt_deg, s.pan_deg
        )
    };
    if let Some(v) = views
        .iter()
        .max_by(|a, b| worst_of(&a.mesh).total_cmp(&worst_of(&b.mesh)))
        .filter(|v| worst_of(&v.mesh) > 0.0)
    {
        let (k, f) = v
            .mesh
            .iter()
            .enumerate()
            .max_by(|a, b| a.1.total_cmp(b.1))
            .expect("spheres");
        println!(
            "worst: {} {:.1} % hidden at {}",
            layout.points[k].name,
            100.0 * f,
            where_(&v.scenario)
        );
    }
    let mut gap = 0.0f64;
    for v in &views {
        for (k, (mesh, model)) in v.mesh.iter().zip(&v.model).enumerate() {
            gap = gap.max((mesh - model).abs());
            if *mesh >= 0.01 && *model <= max_hidden.fraction() {
                println!(
                    "model counts it seen, mesh hides it: {} mesh {:.2} % model {:.2} % at {}",
                    layout.points[k].name,
                    100.0 * mesh,
                    100.0 * model,
                    where_(&v.scenario)
                );
            }
        }
    }
    println!(
        "largest |mesh - model| of a sphere: {:.2} points",
        100.0 * gap
    );
}
