//! Mesh clean-up after projection: Surface Nets vertices of neighbouring
//! cubes can land on (or next to) the same surface point, leaving very
//! short edges and needle or cap triangles. Two local operations remove
//! them without changing the topology:
//!
//! * **edge collapse**: merge the ends of an edge shorter than a threshold
//!   into one vertex on the surface, only when the *link condition* holds
//!   (the ends share exactly the two neighbours opposite the edge, so the
//!   surface stays a manifold) and no surrounding face would fold over or
//!   become degenerate;
//! * **edge flip**: a cap (a triangle whose height is tiny against its
//!   longest edge) has that edge replaced by the other diagonal of the two
//!   faces beside it, when the new faces are sound and face the same way.
//!
//! Reference: Hoppe et al., "Mesh optimization" (SIGGRAPH 1993), for the
//! edge collapse and its legality test (the link condition of Dey et al.
//! 1999).

use super::trimesh::{TriangleMesh, DEGENERATE_AREA_MM2};
use nalgebra::Vector3;
use std::collections::HashSet;

/// Sweeps of collapse + flip at most.
pub const REPAIR_SWEEPS: usize = 4;

/// The clean-up's bookkeeping: faces around each vertex, and which faces
/// and vertices are gone.
struct Editor<'a> {
    mesh: &'a mut TriangleMesh,
    faces_of: Vec<Vec<u32>>,
    face_alive: Vec<bool>,
}

impl<'a> Editor<'a> {
    fn new(mesh: &'a mut TriangleMesh) -> Editor<'a> {
        let mut faces_of = vec![Vec::new(); mesh.positions.len()];
        for (f, t) in mesh.triangles.iter().enumerate() {
            for &v in t {
                faces_of[v as usize].push(f as u32);
            }
        }
        let face_alive = vec![true; mesh.triangles.len()];
        Editor {
            mesh,
            faces_of,
            face_alive,
        }
    }

    fn faces(&self, v: u32) -> impl Iterator<Item = u32> + '_ {
        self.faces_of[v as usize]
            .iter()
            .copied()
            .filter(|&f| self.face_alive[f as usize])
    }

    fn neighbours(&self, v: u32) -> HashSet<u32> {
        self.faces(v)
            .flat_map(|f| self.mesh.triangles[f as usize])
            .filter(|&w| w != v)
            .collect()
    }

    fn cross(&self, t: [u32; 3], moved: Option<(u32, Vector3<f64>)>) -> Vector3<f64> {
        let p = |v: u32| match moved {
            Some((m, at)) if m == v => at,
            _ => self.mesh.positions[v as usize],
        };
        (p(t[1]) - p(t[0])).cross(&(p(t[2]) - p(t[0])))
    }

    /// Collapses edge (a, b) into `a` at `target`, if legal. Returns
    /// whether it did.
    fn collapse(&mut self, a: u32, b: u32, target: Vector3<f64>) -> bool {
        let shared: Vec<u32> = self
            .faces(a)
            .filter(|&f| self.mesh.triangles[f as usize].contains(&b))
            .collect();
        if shared.len() != 2 {
            return false;
        }
        let opposite: HashSet<u32> = shared
            .iter()
            .flat_map(|&f| self.mesh.triangles[f as usize])
            .filter(|&v| v != a && v != b)
            .collect();
        let common: HashSet<u32> = self
            .neighbours(a)
            .intersection(&self.neighbours(b))
            .copied()
            .collect();
        if common != opposite || opposite.len() != 2 {
            return false;
        }
        // Every surviving face around a or b keeps its orientation and area.
        let around: Vec<u32> = self
            .faces(a)
            .chain(self.faces(b))
            .filter(|f| !shared.contains(f))
            .collect();
        for &f in &around {
            let old_t = self.mesh.triangles[f as usize];
            let new_t = old_t.map(|v| if v == b { a } else { v });
            let old = self.cross(old_t, None);
            let new = self.cross(new_t, Some((a, target)));
            if new.dot(&old) <= 0.0 || 0.5 * new.norm() < DEGENERATE_AREA_MM2 {
                return false;
            }
        }
        for &f in &shared {
            self.face_alive[f as usize] = false;
        }
        let moved: Vec<u32> = self.faces(b).collect();
        for f in moved {
            for v in &mut self.mesh.triangles[f as usize] {
                if *v == b {
                    *v = a;
                }
            }
            self.faces_of[a as usize].push(f);
        }
        self.faces_of[b as usize].clear();
        self.mesh.positions[a as usize] = target;
        true
    }

    /// Flips the edge (a, b) of face `f` to the other diagonal of the two
    /// faces beside it, if the result is sound. Returns whether it did.
    fn flip(&mut self, f: u32, a: u32, b: u32) -> bool {
        let t = self.mesh.triangles[f as usize];
        let c = third_vertex(t, a, b);
        let others: Vec<u32> = self
            .faces(a)
            .filter(|&g| g != f && self.mesh.triangles[g as usize].contains(&b))
            .collect();
        let [g] = others[..] else {
            return false;
        };
        let u = self.mesh.triangles[g as usize];
        let d = third_vertex(u, a, b);
        if d == c || self.neighbours(c).contains(&d) {
            return false;
        }
        // Orient: f runs a → b, so the quad boundary is a, d, b, c.
        let k = t.iter().position(|&v| v == a).expect("a in f");
        let (a, b) = if t[(k + 1) % 3] == b { (a, b) } else { (b, a) };
        let new_f = [a, d, c];
        let new_g = [d, b, c];
        let normal = self.cross(t, None) + self.cross(u, None);
        let (nf, ng) = (self.cross(new_f, None), self.cross(new_g, None));
        let sound = |n: Vector3<f64>| n.dot(&normal) > 0.0 && 0.5 * n.norm() >= DEGENERATE_AREA_MM2;
        if !(sound(nf) && sound(ng)) {
            return false;
        }
        // The new faces must be better than the cap they replace.
        let height = |t: [u32; 3]| {
            let p = t.map(|v| self.mesh.positions[v as usize]);
            let longest = (0..3)
                .map(|i| (p[(i + 1) % 3] - p[i]).norm())
                .fold(0.0, f64::max);
            self.cross(t, None).norm() / longest
        };
        if height(new_f).min(height(new_g)) <= height(t).min(height(u)) {
            return false;
        }
        self.mesh.triangles[f as usize] = new_f;
        self.mesh.triangles[g as usize] = new_g;
        self.faces_of[d as usize].push(f);
        self.faces_of[c as usize].push(g);
        self.faces_of[a as usize].retain(|&h| h != g);
        self.faces_of[b as usize].retain(|&h| h != f);
        true
    }

    /// Drops dead faces and unused vertices.
    fn finish(self) {
        let mesh = self.mesh;
        let triangles: Vec<[u32; 3]> = mesh
            .triangles
            .iter()
            .zip(&self.face_alive)
            .filter(|(_, &alive)| alive)
            .map(|(t, _)| *t)
            .collect();
        // Keep the surviving vertices in their original order.
        let mut used = vec![false; mesh.positions.len()];
        for t in &triangles {
            for &v in t {
                used[v as usize] = true;
            }
        }
        let mut new_index = vec![u32::MAX; mesh.positions.len()];
        let mut positions = Vec::new();
        for (v, &keep) in used.iter().enumerate() {
            if keep {
                new_index[v] = positions.len() as u32;
                positions.push(mesh.positions[v]);
            }
        }
        mesh.triangles = triangles
            .into_iter()
            .map(|t| t.map(|v| new_index[v as usize]))
            .collect();
        mesh.positions = positions;
    }
}

/// What the clean-up did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct RepairCounts {
    /// Edges collapsed.
    pub collapsed: usize,
    /// Edges flipped.
    pub flipped: usize,
}

/// Collapses edges shorter than `min_edge_mm` (the merged vertex placed by
/// `place`, which should put the edge's midpoint on the surface) and flips
/// the longest edge of caps lower than `min_height_mm`, in up to
/// [`REPAIR_SWEEPS`] sweeps. Keeps the mesh closed and manifold.
pub fn clean(
    mesh: &mut TriangleMesh,
    min_edge_mm: f64,
    min_height_mm: f64,
    place: impl Fn(Vector3<f64>) -> Vector3<f64>,
) -> RepairCounts {
    let mut counts = RepairCounts::default();
    for _ in 0..REPAIR_SWEEPS {
        let before = counts;
        let mut editor = Editor::new(mesh);
        let mut short: Vec<(f64, u32, u32)> = Vec::new();
        for t in &editor.mesh.triangles {
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                if a < b {
                    let length = (editor.mesh.positions[a as usize]
                        - editor.mesh.positions[b as usize])
                        .norm();
                    if length < min_edge_mm {
                        short.push((length, a, b));
                    }
                }
            }
        }
        short.sort_by(|x, y| x.0.total_cmp(&y.0));
        let mut removed = vec![false; editor.mesh.positions.len()];
        for (_, a, b) in short {
            if removed[a as usize] || removed[b as usize] {
                continue;
            }
            let (pa, pb) = (
                editor.mesh.positions[a as usize],
                editor.mesh.positions[b as usize],
            );
            if (pa - pb).norm() >= min_edge_mm {
                continue;
            }
            if editor.collapse(a, b, place(0.5 * (pa + pb))) {
                removed[b as usize] = true;
                counts.collapsed += 1;
            }
        }
        for f in 0..editor.mesh.triangles.len() as u32 {
            if !editor.face_alive[f as usize] {
                continue;
            }
            let t = editor.mesh.triangles[f as usize];
            let p = t.map(|v| editor.mesh.positions[v as usize]);
            let (k, longest) = (0..3)
                .map(|i| (i, (p[(i + 1) % 3] - p[i]).norm()))
                .max_by(|x, y| x.1.total_cmp(&y.1))
                .expect("three edges");
            let height = editor.cross(t, None).norm() / longest;
            if height < min_height_mm && editor.flip(f, t[k], t[(k + 1) % 3]) {
                counts.flipped += 1;
            }
        }
        editor.finish();
        if counts == before {
            break;
        }
    }
    counts
}

/// The vertex of triangle `t` other than `a` and `b`.
fn third_vertex(t: [u32; 3], a: u32, b: u32) -> u32 {
    t.into_iter()
        .find(|&v| v != a && v != b)
        .expect("a triangle has a third vertex")
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An octahedron with one vertex split into two very close ones.
    fn split_octahedron() -> TriangleMesh {
        let positions = vec![
            Vector3::new(1.0, 0.0, 0.0),
            Vector3::new(-1.0, 0.0, 0.0),
            Vector3::new(0.0, 1.0, 0.0),
            Vector3::new(0.0, -1.0, 0.0),
            Vector3::new(0.0, 0.0, 1.0),
            Vector3::new(0.0, 0.0, -1.0),
        ];
        let triangles = vec![
            [0, 2, 4],
            [2, 1, 4],
            [1, 3, 4],
            [3, 0, 4],
            [2, 0, 5],
            [1, 2, 5],
            [3, 1, 5],
            [0, 3, 5],
        ];
        TriangleMesh {
            positions,
            triangles,
        }
    }

    #[test]
    fn collapses_a_short_edge_and_stays_closed() {
        let mut mesh = split_octahedron();
        // Split vertex 4 (top) into 4 and 6, joined by a tiny edge.
        mesh.positions.push(Vector3::new(0.0, 1e-5, 1.0));
        mesh.triangles = vec![
            [0, 2, 6],
            [2, 1, 6],
            [1, 4, 6],
            [1, 3, 4],
            [3, 0, 4],
            [0, 6, 4],
            [2, 0, 5],
            [1, 2, 5],
            [3, 1, 5],
            [0, 3, 5],
        ];
        assert!(mesh.topology().is_watertight_solid() || mesh.topology().degenerate_faces > 0);
        let counts = clean(&mut mesh, 1e-3, 1e-6, |p| p);
        assert_eq!(counts.collapsed, 1);
        let t = mesh.topology();
        assert_eq!((t.vertices, t.faces), (6, 8));
        assert!(t.is_watertight_solid(), "{t:?}");
    }

    #[test]
    fn leaves_a_good_mesh_alone() {
        let mut mesh = split_octahedron();
        let before = mesh.clone();
        assert_eq!(clean(&mut mesh, 1e-3, 1e-6, |p| p), RepairCounts::default());
        assert_eq!(mesh, before);
    }
}
