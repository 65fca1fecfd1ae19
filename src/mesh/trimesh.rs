//! An indexed triangle mesh and the checks that make it printable: closed
//! (every edge shared by exactly two faces, in opposite directions),
//! manifold at every vertex, one connected body, outward-facing, with no
//! degenerate faces.

use nalgebra::Vector3;
use serde::Serialize;

/// A face whose area is below this is degenerate, mm².
pub const DEGENERATE_AREA_MM2: f64 = 1e-6;
/// A face with an edge shorter than this is degenerate, mm.
pub const DEGENERATE_EDGE_MM: f64 = 1e-4;

/// An indexed triangle mesh, counter-clockwise seen from outside, in mm.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TriangleMesh {
    /// Vertex positions.
    pub positions: Vec<Vector3<f64>>,
    /// Triangles as vertex indices.
    pub triangles: Vec<[u32; 3]>,
}

/// The topology and soundness figures of a mesh.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Topology {
    /// Vertices used by some face.
    pub vertices: usize,
    /// Undirected edges.
    pub edges: usize,
    /// Faces.
    pub faces: usize,
    /// Edges used by only one face (holes in the surface).
    pub boundary_edges: usize,
    /// Edges used by three or more faces.
    pub non_manifold_edges: usize,
    /// Edges whose two faces run the same way (inconsistent winding).
    pub misoriented_edges: usize,
    /// Vertices whose faces do not form one fan.
    pub non_manifold_vertices: usize,
    /// Connected components (faces joined through shared edges).
    pub components: usize,
    /// V − E + F.
    pub euler_characteristic: i64,
    /// Faces with a repeated vertex, an area below
    /// [`DEGENERATE_AREA_MM2`] or an edge below [`DEGENERATE_EDGE_MM`].
    pub degenerate_faces: usize,
    /// Signed volume (positive when the faces point outwards), mm³.
    pub signed_volume_mm3: f64,
    /// Surface area, mm².
    pub area_mm2: f64,
    /// Smallest interior angle of any face, degrees.
    pub min_angle_deg: f64,
    /// Shortest edge, mm.
    pub min_edge_mm: f64,
}

impl Topology {
    /// A closed, consistently wound, manifold, connected, outward-facing
    /// surface without degenerate faces.
    pub fn is_watertight_solid(&self) -> bool {
        self.boundary_edges == 0
            && self.non_manifold_edges == 0
            && self.misoriented_edges == 0
            && self.non_manifold_vertices == 0
            && self.components == 1
            && self.degenerate_faces == 0
            && self.signed_volume_mm3 > 0.0
    }

    /// Genus of a closed connected surface: (2 − χ) / 2, the number of
    /// through-holes.
    pub fn genus(&self) -> i64 {
        (2 - self.euler_characteristic) / 2
    }
}

impl TriangleMesh {
    /// The vertices of face `f`.
    pub fn face(&self, f: usize) -> [Vector3<f64>; 3] {
        self.triangles[f].map(|i| self.positions[i as usize])
    }

    /// Face normal scaled by twice the area (right-hand rule).
    pub fn face_cross(&self, f: usize) -> Vector3<f64> {
        let [a, b, c] = self.face(f);
        (b - a).cross(&(c - a))
    }

    /// Signed volume enclosed (divergence theorem), mm³.
    pub fn signed_volume(&self) -> f64 {
        (0..self.triangles.len())
            .map(|f| {
                let [a, b, c] = self.face(f);
                a.dot(&b.cross(&c))
            })
            .sum::<f64>()
            / 6.0
    }

    /// Reverses the winding of every face.
    pub fn flip(&mut self) {
        for t in &mut self.triangles {
            t.swap(1, 2);
        }
    }

    /// Axis-aligned bounds of the vertices (min, max).
    pub fn bounds(&self) -> (Vector3<f64>, Vector3<f64>) {
        self.positions.iter().fold(
            (
                Vector3::repeat(f64::INFINITY),
                Vector3::repeat(f64::NEG_INFINITY),
            ),
            |(lo, hi), p| (lo.inf(p), hi.sup(p)),
        )
    }

    /// Applies `f` to every vertex.
    pub fn transformed(&self, f: impl Fn(&Vector3<f64>) -> Vector3<f64>) -> TriangleMesh {
        TriangleMesh {
            positions: self.positions.iter().map(f).collect(),
            triangles: self.triangles.clone(),
        }
    }

    /// Counts everything [`Topology`] reports.
    pub fn topology(&self) -> Topology {
        // Every half-edge under its undirected edge (smaller vertex in the
        // high bits), with its face and whether it runs from the smaller
        // vertex; sorted, each edge's half-edges lie together.
        let mut half_edges: Vec<(u64, u32, bool)> = Vec::with_capacity(self.triangles.len() * 3);
        for (f, t) in self.triangles.iter().enumerate() {
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                let key = ((a.min(b) as u64) << 32) | a.max(b) as u64;
                half_edges.push((key, f as u32, a < b));
            }
        }
        half_edges.sort_unstable_by_key(|h| h.0);
        let mut edges = 0;
        let mut boundary_edges = 0;
        let mut non_manifold_edges = 0;
        let mut misoriented_edges = 0;
        // Components through shared edges (union-find over faces).
        let mut parent: Vec<u32> = (0..self.triangles.len() as u32).collect();
        fn root(parent: &mut [u32], mut x: u32) -> u32 {
            while parent[x as usize] != x {
                parent[x as usize] = parent[parent[x as usize] as usize];
                x = parent[x as usize];
            }
            x
        }
        for run in half_edges.chunk_by(|a, b| a.0 == b.0) {
            edges += 1;
            let forward = run.iter().filter(|h| h.2).count();
            let backward = run.len() - forward;
            match (run.len(), forward, backward) {
                (1, _, _) => boundary_edges += 1,
                (2, 1, 1) => {}
                (2, _, _) => misoriented_edges += 1,
                _ => non_manifold_edges += 1,
            }
            let first = root(&mut parent, run[0].1);
            for h in &run[1..] {
                let r = root(&mut parent, h.1);
                parent[r as usize] = first;
            }
        }
        let components = (0..self.triangles.len() as u32)
            .filter(|&f| root(&mut parent, f) == f)
            .count();

        // Vertex fans: at a manifold vertex of a closed surface, the faces
        // around it link into a single cycle through their opposite edges.
        // Each vertex's links (next, previous corner), grouped by vertex.
        let mut start = vec![0usize; self.positions.len() + 1];
        for t in &self.triangles {
            for &v in t {
                start[v as usize + 1] += 1;
            }
        }
        for v in 0..self.positions.len() {
            start[v + 1] += start[v];
        }
        let mut filled = start.clone();
        let mut links = vec![(0u32, 0u32); self.triangles.len() * 3];
        for t in &self.triangles {
            for k in 0..3 {
                let v = t[k] as usize;
                links[filled[v]] = (t[(k + 1) % 3], t[(k + 2) % 3]);
                filled[v] += 1;
            }
        }
        let mut vertices = 0;
        let mut non_manifold_vertices = 0;
        for v in 0..self.positions.len() {
            let fan = &mut links[start[v]..start[v + 1]];
            if fan.is_empty() {
                continue;
            }
            vertices += 1;
            if !is_single_fan(fan) {
                non_manifold_vertices += 1;
            }
        }

        let mut degenerate_faces = 0;
        let mut area = 0.0;
        let mut min_angle = f64::INFINITY;
        let mut min_edge = f64::INFINITY;
        for (f, t) in self.triangles.iter().enumerate() {
            let [a, b, c] = self.face(f);
            let face_area = 0.5 * self.face_cross(f).norm();
            area += face_area;
            let lengths = [(b - a).norm(), (c - b).norm(), (a - c).norm()];
            let shortest = lengths.iter().copied().fold(f64::INFINITY, f64::min);
            min_edge = min_edge.min(shortest);
            for k in 0..3 {
                let (p, q, r) = ([a, b, c][k], [a, b, c][(k + 1) % 3], [a, b, c][(k + 2) % 3]);
                let (u, v) = (q - p, r - p);
                let angle = u.cross(&v).norm().atan2(u.dot(&v));
                min_angle = min_angle.min(angle.to_degrees());
            }
            if t[0] == t[1]
                || t[1] == t[2]
                || t[0] == t[2]
                || face_area < DEGENERATE_AREA_MM2
                || shortest < DEGENERATE_EDGE_MM
            {
                degenerate_faces += 1;
            }
        }
        Topology {
            vertices,
            edges,
            faces: self.triangles.len(),
            boundary_edges,
            non_manifold_edges,
            misoriented_edges,
            non_manifold_vertices,
            components,
            euler_characteristic: vertices as i64 - edges as i64 + self.triangles.len() as i64,
            degenerate_faces,
            signed_volume_mm3: self.signed_volume(),
            area_mm2: area,
            min_angle_deg: min_angle,
            min_edge_mm: min_edge,
        }
    }
}

/// Whether a vertex's links (next, previous corner of each face around
/// it) form one cycle: following `next[a] = b` from any link visits every
/// link once and comes back. Sorts `links`.
fn is_single_fan(links: &mut [(u32, u32)]) -> bool {
    links.sort_unstable();
    if links.windows(2).any(|w| w[0].0 == w[1].0) {
        return false; // two faces leave the vertex by the same edge
    }
    let start = links[0].0;
    let mut at = start;
    for step in 1..=links.len() {
        match links.binary_search_by_key(&at, |l| l.0) {
            Ok(i) => at = links[i].1,
            Err(_) => return false,
        }
        if at == start {
            return step == links.len();
        }
    }
    false
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A unit tetrahedron, outward-facing.
    fn tetrahedron() -> TriangleMesh {
        TriangleMesh {
            positions: vec![
                Vector3::new(0.0, 0.0, 0.0),
                Vector3::new(1.0, 0.0, 0.0),
                Vector3::new(0.0, 1.0, 0.0),
                Vector3::new(0.0, 0.0, 1.0),
            ],
            triangles: vec![[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]],
        }
    }

    #[test]
    fn tetrahedron_is_a_watertight_solid() {
        let t = tetrahedron().topology();
        assert!(t.is_watertight_solid(), "{t:?}");
        assert_eq!((t.vertices, t.edges, t.faces), (4, 6, 4));
        assert_eq!(t.euler_characteristic, 2);
        assert!((t.signed_volume_mm3 - 1.0 / 6.0).abs() < 1e-15);
    }

    #[test]
    fn defects_are_counted() {
        let mut open = tetrahedron();
        open.triangles.pop();
        let t = open.topology();
        assert_eq!(t.boundary_edges, 3);
        assert!(!t.is_watertight_solid());

        let mut flipped = tetrahedron();
        flipped.triangles[0].swap(1, 2);
        assert_eq!(flipped.topology().misoriented_edges, 3);

        let mut inside_out = tetrahedron();
        inside_out.flip();
        assert!(inside_out.topology().signed_volume_mm3 < 0.0);

        // Two tetrahedra sharing one vertex: closed edges, pinched vertex.
        let mut two = tetrahedron();
        two.positions.extend([
            Vector3::new(-1.0, 0.0, 0.0),
            Vector3::new(0.0, -1.0, 0.0),
            Vector3::new(0.0, 0.0, -1.0),
        ]);
        two.triangles
            .extend([[0, 4, 5], [0, 6, 4], [0, 5, 6], [4, 6, 5]]);
        let t = two.topology();
        assert_eq!(
            t.boundary_edges + t.non_manifold_edges + t.misoriented_edges,
            0
        );
        assert_eq!(t.non_manifold_vertices, 1);
        assert_eq!(t.components, 2);
    }
}
