//! Shared checks for the export tests: read every format back with the
//! crates that readers use (`stl_io`, `tobj`, `gltf`), and check a mesh
//! with code independent of the library's own topology counts.

use layout_opt::layout::{Layout, LayoutPoint};
use layout_opt::mesh::geometry::{gltf_rotation, Marker, Node, TEARDROP_HALF_ANGLE_DEG};
use layout_opt::synthetic::stream_rng;
use nalgebra::{Matrix3, Matrix4, Vector3, Vector4};
use rand::Rng;
use std::path::Path;

/// A mesh read back from a file, in the marker frame, mm.
#[derive(Debug, Clone)]
pub struct ReadBack {
    pub positions: Vec<Vector3<f64>>,
    pub triangles: Vec<[usize; 3]>,
}

/// Binary STL (print frame, mm) back to the marker frame.
pub fn read_stl(path: &Path, marker: &Marker) -> ReadBack {
    let mut file = std::fs::File::open(path).unwrap();
    let mesh = stl_io::read_stl(&mut file).unwrap();
    let (rotation, shift) = marker.print_transform();
    let back = rotation.transpose();
    ReadBack {
        positions: mesh
            .vertices
            .iter()
            .map(|v| back * (Vector3::new(v[0] as f64, v[1] as f64, v[2] as f64) - shift))
            .collect(),
        triangles: mesh.faces.iter().map(|f| f.vertices).collect(),
    }
}

/// 3MF (print frame, mm) back to the marker frame: the package's parts
/// are read with the `zip` crate and the model's XML is scanned here,
/// independently of the writer. Checks the package structure on the way.
pub fn read_3mf(path: &Path, marker: &Marker) -> ReadBack {
    use std::io::Read;
    let file = std::fs::File::open(path).unwrap();
    let mut archive = zip::ZipArchive::new(file).unwrap();
    let mut part = |name: &str| {
        let mut text = String::new();
        archive
            .by_name(name)
            .unwrap_or_else(|e| panic!("{}: no part {name}: {e}", path.display()))
            .read_to_string(&mut text)
            .unwrap();
        text
    };
    let types = part("[Content_Types].xml");
    assert!(types.contains("application/vnd.ms-package.3dmanufacturing-3dmodel+xml"));
    let rels = part("_rels/.rels");
    assert!(rels.contains("Target=\"/3D/3dmodel.model\""));
    assert!(rels.contains("http://schemas.microsoft.com/3dmanufacturing/2013/01/3dmodel"));
    let model = part("3D/3dmodel.model");
    assert!(model.contains("unit=\"millimeter\""), "3MF in mm");
    assert!(
        model.contains(&format!("name=\"{}\"", marker.name)),
        "the object is named after the part"
    );
    assert_eq!(model.matches("<object ").count(), 1, "one object");
    assert_eq!(model.matches("<item ").count(), 1, "one build item");
    let attribute = |element: &str, key: &str| -> f64 {
        let start = element
            .find(&format!(" {key}=\""))
            .unwrap_or_else(|| panic!("no {key} in {element}"))
            + key.len()
            + 3;
        let end = start + element[start..].find('"').unwrap();
        element[start..end].parse().unwrap()
    };
    // Each element's attributes, with the space before the first one.
    let elements = |tag: &str| -> Vec<String> {
        model
            .split(&format!("<{tag} "))
            .skip(1)
            .map(|rest| format!(" {}", &rest[..rest.find("/>").unwrap()]))
            .collect()
    };
    let (rotation, shift) = marker.print_transform();
    let back = rotation.transpose();
    ReadBack {
        positions: elements("vertex")
            .iter()
            .map(|v| {
                let p = Vector3::new(attribute(v, "x"), attribute(v, "y"), attribute(v, "z"));
                back * (p - shift)
            })
            .collect(),
        triangles: elements("triangle")
            .iter()
            .map(|t| ["v1", "v2", "v3"].map(|k| attribute(t, k) as usize))
            .collect(),
    }
}

/// OBJ (marker frame, mm).
pub fn read_obj(path: &Path) -> ReadBack {
    let (models, _) = tobj::load_obj(
        path,
        &tobj::LoadOptions {
            single_index: false,
            triangulate: false,
            ignore_points: true,
            ignore_lines: true,
        },
    )
    .unwrap();
    assert_eq!(models.len(), 1, "one object");
    let mesh = &models[0].mesh;
    assert!(
        mesh.face_arities.is_empty(),
        "every face is a triangle (tobj leaves arities empty then)"
    );
    assert_eq!(
        mesh.normals.len(),
        mesh.positions.len(),
        "one normal per vertex"
    );
    ReadBack {
        positions: mesh
            .positions
            .chunks_exact(3)
            .map(|p| Vector3::new(p[0] as f64, p[1] as f64, p[2] as f64))
            .collect(),
        triangles: mesh
            .indices
            .chunks_exact(3)
            .map(|t| [t[0] as usize, t[1] as usize, t[2] as usize])
            .collect(),
    }
}

/// glTF or GLB (metres, Y up) back to the marker frame in mm; also checks
/// what the glTF specification requires of the POSITION accessor (min and
/// max present and equal to the data's bounds) and that normals are unit.
pub fn read_gltf(path: &Path, marker: &Marker) -> ReadBack {
    let bytes = std::fs::read(path).unwrap();
    let document = gltf::Gltf::from_slice(&bytes).unwrap();
    let buffer: Vec<u8> = match document.blob.clone() {
        Some(blob) => blob,
        None => {
            let buffer = document.buffers().next().expect("a buffer");
            let gltf::buffer::Source::Uri(uri) = buffer.source() else {
                panic!("a .gltf names its .bin");
            };
            std::fs::read(path.parent().unwrap().join(uri)).unwrap()
        }
    };
    assert_eq!(document.as_json().asset.version, "2.0");
    let scene = document.default_scene().expect("a default scene");
    let node = scene.nodes().next().expect("a node");
    let mesh = node.mesh().expect("the node has the mesh");
    let primitive = mesh.primitives().next().expect("a primitive");
    assert_eq!(primitive.mode(), gltf::mesh::Mode::Triangles);
    let reader = primitive.reader(|_| Some(&buffer[..]));
    let positions: Vec<[f32; 3]> = reader.read_positions().expect("POSITION").collect();
    let normals: Vec<[f32; 3]> = reader.read_normals().expect("NORMAL").collect();
    assert_eq!(positions.len(), normals.len());
    for n in &normals {
        let length = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        assert!((length - 1.0).abs() < 1e-5, "unit normals");
    }
    let accessor = primitive
        .get(&gltf::Semantic::Positions)
        .expect("POSITION accessor");
    let (min, max) = (accessor.min().expect("min"), accessor.max().expect("max"));
    for k in 0..3 {
        let lo = positions.iter().map(|p| p[k]).fold(f32::INFINITY, f32::min);
        let hi = positions
            .iter()
            .map(|p| p[k])
            .fold(f32::NEG_INFINITY, f32::max);
        assert_eq!(min[k].as_f64().unwrap() as f32, lo, "POSITION min");
        assert_eq!(max[k].as_f64().unwrap() as f32, hi, "POSITION max");
    }
    let indices: Vec<u32> = reader.read_indices().expect("indices").into_u32().collect();
    let back = gltf_rotation(marker.down).transpose();
    ReadBack {
        positions: positions
            .iter()
            .map(|p| back * Vector3::new(p[0] as f64, p[1] as f64, p[2] as f64) * 1000.0)
            .collect(),
        triangles: indices
            .chunks_exact(3)
            .map(|t| [t[0] as usize, t[1] as usize, t[2] as usize])
            .collect(),
    }
}

/// Soundness figures, computed here from scratch.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Soundness {
    pub vertices: usize,
    pub edges: usize,
    pub faces: usize,
    /// Undirected edges not used by exactly one face each way.
    pub bad_edges: usize,
    pub components: usize,
    pub euler_characteristic: i64,
    pub degenerate_faces: usize,
    pub signed_volume_mm3: f64,
}

/// A face is degenerate when it repeats a vertex or its area is below this
/// (mm²).
pub const DEGENERATE_AREA_MM2: f64 = 1e-6;

pub fn soundness(mesh: &ReadBack) -> Soundness {
    // Every side of every face as (low vertex, high vertex, runs low to
    // high, face), sorted so that the sides of one undirected edge lie
    // together. A sound edge has one side each way.
    let mut sides: Vec<(usize, usize, bool, usize)> = mesh
        .triangles
        .iter()
        .enumerate()
        .flat_map(|(f, t)| {
            (0..3).map(move |k| {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                (a.min(b), a.max(b), a < b, f)
            })
        })
        .collect();
    sides.sort_unstable();
    // Components: faces joined by the edges they share (union-find).
    let mut parent: Vec<usize> = (0..mesh.triangles.len()).collect();
    fn root(parent: &mut [usize], mut f: usize) -> usize {
        while parent[f] != f {
            parent[f] = parent[parent[f]];
            f = parent[f];
        }
        f
    }
    let mut edges = 0;
    let mut bad_edges = 0;
    for edge in sides.chunk_by(|x, y| (x.0, x.1) == (y.0, y.1)) {
        edges += 1;
        let forward = edge.iter().filter(|side| side.2).count();
        if (forward, edge.len() - forward) != (1, 1) {
            bad_edges += 1;
        }
        let first = root(&mut parent, edge[0].3);
        for side in &edge[1..] {
            let other = root(&mut parent, side.3);
            parent[other] = first;
        }
    }
    let components = (0..parent.len()).filter(|&f| parent[f] == f).count();

    let mut used = vec![false; mesh.positions.len()];
    let mut degenerate_faces = 0;
    let mut volume = 0.0;
    for t in &mesh.triangles {
        for &v in t {
            used[v] = true;
        }
        let [a, b, c] = t.map(|v| mesh.positions[v]);
        volume += a.dot(&b.cross(&c)) / 6.0;
        let area = 0.5 * (b - a).cross(&(c - a)).norm();
        if t[0] == t[1] || t[1] == t[2] || t[0] == t[2] || area < DEGENERATE_AREA_MM2 {
            degenerate_faces += 1;
        }
    }
    let vertices = used.iter().filter(|&&u| u).count();
    Soundness {
        vertices,
        edges,
        faces: mesh.triangles.len(),
        bad_edges,
        components,
        euler_characteristic: vertices as i64 - edges as i64 + mesh.triangles.len() as i64,
        degenerate_faces,
        signed_volume_mm3: volume,
    }
}

/// Monte-Carlo volume of the solid, from its analytic definition (the
/// marker's signed distance: spheres, capsules, fillets, plate and holes),
/// never the mesh. Points are drawn uniformly in boxes around the parts,
/// each box grown by the most a fillet can add, and every point is weighted
/// by 1 / (number of boxes holding it), which makes the sum over boxes an
/// unbiased estimate of the union's volume. Returns (volume, standard
/// error), mm³.
pub fn monte_carlo_volume(marker: &Marker, samples_per_box: usize, seed: u64) -> (f64, f64) {
    let (lo, hi) = marker.bounds();
    let mut parts: Vec<(Vector3<f64>, Vector3<f64>)> = Vec::new();
    let margin = growth_margin(marker);
    for s in &marker.spheres {
        let r = Vector3::repeat(s.radius + margin);
        parts.push((s.centre - r, s.centre + r));
    }
    for s in &marker.struts {
        let r = Vector3::repeat(s.radius + margin);
        parts.push((s.a.inf(&s.b) - r, s.a.sup(&s.b) + r));
    }
    let p = &marker.plate;
    let r = Vector3::repeat(margin);
    parts.push((p.centre - p.half_extents - r, p.centre + p.half_extents + r));
    for (a, b) in &mut parts {
        *a = a.sup(&lo);
        *b = b.inf(&hi);
    }
    let mut rng = stream_rng(seed, 77, 0);
    let mut total = 0.0;
    let mut variance = 0.0;
    for (a, b) in &parts {
        let size = b - a;
        let box_volume = size.x * size.y * size.z;
        let mut sum = 0.0;
        let mut sum2 = 0.0;
        for _ in 0..samples_per_box {
            let x = a + size.component_mul(&Vector3::from_fn(|_, _| rng.random::<f64>()));
            if marker.signed_distance(&x) < 0.0 {
                let holders = parts
                    .iter()
                    .filter(|(c, d)| (0..3).all(|k| x[k] >= c[k] && x[k] <= d[k]))
                    .count() as f64;
                let w = 1.0 / holders;
                sum += w;
                sum2 += w * w;
            }
        }
        let n = samples_per_box as f64;
        let mean = sum / n;
        total += box_volume * mean;
        variance += box_volume * box_volume * (sum2 / n - mean * mean) / n;
    }
    (total, variance.sqrt())
}

/// How far the solid can reach beyond its parts: the bounds' margin.
fn growth_margin(marker: &Marker) -> f64 {
    let (lo, _) = marker.bounds();
    let mut tight = Vector3::repeat(f64::INFINITY);
    for s in &marker.spheres {
        tight = tight.inf(&(s.centre - Vector3::repeat(s.radius)));
    }
    for s in &marker.struts {
        tight = tight.inf(&(s.a - Vector3::repeat(s.radius)));
        tight = tight.inf(&(s.b - Vector3::repeat(s.radius)));
    }
    tight = tight.inf(&(marker.plate.centre - marker.plate.half_extents));
    (tight - lo).max()
}

/// Least-squares sphere through `points`: the algebraic fit
/// |p|² = 2 c·p + (r² − |c|²), then Gauss–Newton on the geometric
/// residuals |p − c| − r. Returns (centre, radius).
pub fn fit_sphere(points: &[Vector3<f64>]) -> (Vector3<f64>, f64) {
    let mut normal = Matrix4::<f64>::zeros();
    let mut rhs = Vector4::<f64>::zeros();
    for p in points {
        let row = Vector4::new(2.0 * p.x, 2.0 * p.y, 2.0 * p.z, 1.0);
        normal += row * row.transpose();
        rhs += row * p.norm_squared();
    }
    let solution = normal.lu().solve(&rhs).expect("a well-spread point set");
    let mut centre = Vector3::new(solution[0], solution[1], solution[2]);
    let mut radius = (solution[3] + centre.norm_squared()).sqrt();
    for _ in 0..10 {
        let mut jtj = Matrix4::<f64>::zeros();
        let mut jtr = Vector4::<f64>::zeros();
        for p in points {
            let d = p - centre;
            let distance = d.norm();
            let residual = distance - radius;
            let u = d / distance;
            let row = Vector4::new(-u.x, -u.y, -u.z, -1.0);
            jtj += row * row.transpose();
            jtr += row * residual;
        }
        let step = jtj.lu().solve(&(-jtr)).expect("well conditioned");
        centre += Vector3::new(step[0], step[1], step[2]);
        radius += step[3];
        if step.norm() < 1e-12 {
            break;
        }
    }
    (centre, radius)
}

/// For each sphere: the mesh vertices within 1 mm of its surface, away
/// from the cones in which its struts leave it (and their fillets), fitted
/// with [`fit_sphere`]; returns (sphere name, centre error mm, radius error
/// mm, vertices used).
pub fn sphere_fits(marker: &Marker, mesh: &ReadBack) -> Vec<(String, f64, f64, usize)> {
    marker
        .spheres
        .iter()
        .enumerate()
        .map(|(i, sphere)| {
            let node = Node::Sphere(i);
            let directions: Vec<(Vector3<f64>, f64)> = marker
                .struts
                .iter()
                .filter(|s| s.ends.contains(&node))
                .map(|s| {
                    let far = if s.ends[0] == node { s.b } else { s.a };
                    let reach = ((s.radius + marker.blend_mm) / sphere.radius)
                        .min(1.0)
                        .asin();
                    (
                        (far - sphere.centre).normalize(),
                        reach + 10f64.to_radians(),
                    )
                })
                .chain(
                    // The cone under a sphere of a printable part meets it
                    // TEARDROP_HALF_ANGLE_DEG short of its equator.
                    marker.teardrops.get(i).copied().flatten().map(|(tip, _)| {
                        (
                            (tip - sphere.centre).normalize(),
                            (90.0 - TEARDROP_HALF_ANGLE_DEG + 10.0).to_radians(),
                        )
                    }),
                )
                .collect();
            let near: Vec<Vector3<f64>> = mesh
                .positions
                .iter()
                .copied()
                .filter(|p| ((p - sphere.centre).norm() - sphere.radius).abs() < 1.0)
                .filter(|p| {
                    let u = (p - sphere.centre).normalize();
                    directions
                        .iter()
                        .all(|(d, cone)| u.dot(d).clamp(-1.0, 1.0).acos() > *cone)
                })
                .collect();
            let (centre, radius) = fit_sphere(&near);
            (
                sphere.name.clone(),
                (centre - sphere.centre).norm(),
                (radius - sphere.radius).abs(),
                near.len(),
            )
        })
        .collect()
}

/// A seeded random layout that is valid for export: `count` points in a
/// cube of side `size_mm`, 10 mm spheres at least 1 mm apart.
pub fn random_layout(seed: u64, case: u64, count: usize, size_mm: f64) -> Layout {
    let mut rng = stream_rng(seed, 31, case);
    loop {
        let points: Vec<LayoutPoint> = (0..count)
            .map(|i| {
                LayoutPoint::new(
                    format!("S{i}"),
                    Vector3::from_fn(|_, _| (rng.random::<f64>() - 0.5) * size_mm),
                )
            })
            .collect();
        let layout = Layout {
            name: format!("random-{seed}-{case}"),
            points,
            sphere_diameter_mm: 10.0,
            family: None,
            provenance: None,
        };
        let apart = (0..count).all(|i| {
            (i + 1..count)
                .all(|j| (layout.points[i].position - layout.points[j].position).norm() >= 11.0)
        });
        if apart && layout.validate().is_ok() {
            return layout;
        }
    }
}

/// The rotation matrix with rows `rows`.
pub fn rows(rows: [[f64; 3]; 3]) -> Matrix3<f64> {
    Matrix3::from_fn(|r, c| rows[r][c])
}
