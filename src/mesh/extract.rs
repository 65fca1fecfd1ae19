//! Surface extraction: the marker's signed distance sampled on a regular
//! grid, Naive Surface Nets (`fast-surface-nets`) chunk by chunk, vertices
//! welded across chunks, then every vertex moved onto the exact surface by
//! Newton steps along the analytic gradient.
//!
//! * **Closed by construction.** The grid is padded so that every sample on
//!   its border is outside; Surface Nets then emits one quad per grid edge
//!   that crosses the surface, and every such edge is owned by exactly one
//!   chunk (the chunk covers points `[kC, kC + C + 1]` per axis and emits
//!   quads for edges starting at `[kC, kC + C)` along the edge and
//!   `[kC + 1, kC + C]` across it), so welding the per-cube vertices by
//!   their global cube index gives one closed surface.
//! * **Narrow band.** The signed distance is 1-Lipschitz, so a block of
//!   samples whose centre is farther from the surface than the block's
//!   half-diagonal plus two cells gets its sign without evaluating each
//!   sample; every sample next to the surface is evaluated exactly, so
//!   chunks agree on shared vertices.
//! * **On the surface.** Surface Nets puts vertices at averaged edge
//!   crossings, up to a fraction of a cell off the surface. Newton's method
//!   on the analytic field, `x ← x − f(x) ∇f / |∇f|²`, puts them on it to
//!   [`PROJECTION_TOLERANCE_MM`]. Faces that this would fold over are
//!   repaired by [`super::repair`].
//!
//! Reference: S. F. F. Gibson, "Constrained elastic surface nets" (1998),
//! the Naive Surface Nets variant of `fast-surface-nets`.

use super::geometry::Marker;
use super::repair;
use super::trimesh::TriangleMesh;
use fast_surface_nets::ndshape::{ConstShape, ConstShape3u32};
use fast_surface_nets::{surface_nets, SurfaceNetsBuffer};
use nalgebra::Vector3;
use rayon::prelude::*;
use std::collections::{HashMap, HashSet};

/// Cubes per chunk along each axis.
pub const CHUNK_CUBES: u32 = 32;
/// Rounds of ambiguity resolution at most (see [`resolve_ambiguities`]);
/// also the halo of extra samples around each chunk that keeps the rounds
/// identical in neighbouring chunks.
pub const AMBIGUITY_ROUNDS: u32 = 4;
/// Samples per chunk along each axis: the chunk's cubes, one more on each
/// side, and the halo.
const CHUNK_POINTS: u32 = CHUNK_CUBES + 2 + 2 * AMBIGUITY_ROUNDS;
type ChunkShape = ConstShape3u32<CHUNK_POINTS, CHUNK_POINTS, CHUNK_POINTS>;
/// Samples per narrow-band block along each axis.
const BLOCK_POINTS: u32 = 6;
/// Edges shorter than this fraction of a cell are collapsed after
/// projection.
pub const COLLAPSE_EDGE_FRACTION: f64 = 0.1;
/// Triangles lower than this fraction of a cell (against their longest
/// edge) have that edge flipped.
pub const CAP_HEIGHT_FRACTION: f64 = 0.02;
/// Newton steps at most when projecting a vertex onto the surface.
pub const PROJECTION_ITERATIONS: usize = 20;
/// A vertex is on the surface when |f| is below this, mm.
pub const PROJECTION_TOLERANCE_MM: f64 = 1e-9;

/// The regular sampling grid.
#[derive(Debug, Clone, Copy)]
pub struct Grid {
    /// Position of sample (0, 0, 0), mm.
    pub origin: Vector3<f64>,
    /// Sample spacing, mm.
    pub spacing: f64,
    /// Samples along each axis.
    pub points: [u32; 3],
}

impl Grid {
    /// A grid over the marker's bounds padded by two cells, so that every
    /// border sample is outside, and shifted so that the grid planes keep
    /// as far as possible from the planes that struts lie tangent to
    /// ([`Marker::tangent_planes`]).
    pub fn around(marker: &Marker, spacing: f64) -> Grid {
        let (lo, hi) = marker.bounds();
        let pad = 2.0 * spacing;
        let tangent = marker.tangent_planes();
        let shift = Vector3::from_fn(|k, _| best_shift(lo[k] - pad, &tangent[k], spacing));
        let origin = lo - Vector3::repeat(pad) - shift;
        let extent = hi - origin + Vector3::repeat(pad);
        let points = [0, 1, 2].map(|k| (extent[k] / spacing).ceil() as u32 + 1);
        Grid {
            origin,
            spacing,
            points,
        }
    }

    /// Position of a (possibly fractional) grid coordinate.
    pub fn position(&self, coordinate: [f64; 3]) -> Vector3<f64> {
        self.origin + Vector3::from(coordinate) * self.spacing
    }
}

/// Candidate shifts of the grid per cell, tried by [`best_shift`].
const SHIFT_CANDIDATES: usize = 256;

/// Weight of the tangent planes of axis-aligned struts in [`best_shift`]:
/// their strips run along the grid and mesh cleanly unless a grid plane all
/// but touches them, which only piles vertices onto one line.
const ALIGNED_PLANE_WEIGHT: f64 = 0.1;

/// The shift in `[0, spacing)` of grid planes `start − shift + n·spacing`
/// that keeps `planes` (coordinate, oblique?) farthest from a grid plane,
/// oblique ones counting fully and aligned ones with
/// [`ALIGNED_PLANE_WEIGHT`].
///
/// A cylinder lying tangent to a grid plane, within a small fraction of a
/// cell inside it, cuts that plane in a strip thinner than a cell; where the
/// strip runs diagonally across the grid it leaves faces whose diagonal
/// corners have the same sign, and where a grid plane touches it exactly,
/// vertices from both sides land on the same line. Keeping tangent planes
/// away from the grid planes avoids both.
fn best_shift(start: f64, planes: &[(f64, bool)], spacing: f64) -> f64 {
    let clearance = |shift: f64| {
        planes
            .iter()
            .map(|&(v, oblique)| {
                let cells = ((v - (start - shift)) / spacing).rem_euclid(1.0);
                let distance = cells.min(1.0 - cells);
                if oblique {
                    distance
                } else {
                    distance / ALIGNED_PLANE_WEIGHT
                }
            })
            .fold(f64::INFINITY, f64::min)
    };
    (0..SHIFT_CANDIDATES)
        .map(|i| spacing * i as f64 / SHIFT_CANDIDATES as f64)
        .max_by(|a, b| clearance(*a).total_cmp(&clearance(*b)).then(b.total_cmp(a)))
        .unwrap_or(0.0)
}

/// What one chunk produced: vertices keyed by global cube index, and
/// triangles as triples of those keys.
struct ChunkMesh {
    vertices: Vec<(u64, Vector3<f64>)>,
    triangles: Vec<[u64; 3]>,
}

/// Extracts the closed surface of `marker` at grid spacing `resolution_mm`,
/// with every vertex on the exact surface. The winding is outward.
pub fn extract(marker: &Marker, resolution_mm: f64) -> TriangleMesh {
    let grid = Grid::around(marker, resolution_mm);
    let chunks_per_axis = grid
        .points
        .map(|p| (p.saturating_sub(1)).div_ceil(CHUNK_CUBES).max(1));
    let chunk_ids: Vec<[u32; 3]> = (0..chunks_per_axis[2])
        .flat_map(|z| {
            (0..chunks_per_axis[1])
                .flat_map(move |y| (0..chunks_per_axis[0]).map(move |x| [x, y, z]))
        })
        .collect();
    let pieces: Vec<ChunkMesh> = chunk_ids
        .par_iter()
        .filter_map(|&chunk| mesh_chunk(marker, &grid, chunk))
        .collect();

    let mut index: HashMap<u64, u32> = HashMap::new();
    let mut mesh = TriangleMesh::default();
    for piece in &pieces {
        for &(key, position) in &piece.vertices {
            index.entry(key).or_insert_with(|| {
                mesh.positions.push(position);
                (mesh.positions.len() - 1) as u32
            });
        }
    }
    for piece in pieces {
        mesh.triangles
            .extend(piece.triangles.iter().map(|t| t.map(|key| index[&key])));
    }
    if mesh.signed_volume() < 0.0 {
        mesh.flip();
    }
    mesh.positions
        .par_iter_mut()
        .for_each(|p| *p = project_onto_surface(marker, *p, resolution_mm));
    repair::clean(
        &mut mesh,
        COLLAPSE_EDGE_FRACTION * resolution_mm,
        CAP_HEIGHT_FRACTION * resolution_mm,
        |p| project_onto_surface(marker, p, resolution_mm),
    );
    mesh
}

/// Global cube key from its integer grid coordinates.
fn cube_key(cube: [u32; 3]) -> u64 {
    (cube[0] as u64) | ((cube[1] as u64) << 21) | ((cube[2] as u64) << 42)
}

/// Samples one chunk and runs Surface Nets on it; `None` when the chunk is
/// provably far from the surface.
fn mesh_chunk(marker: &Marker, grid: &Grid, chunk: [u32; 3]) -> Option<ChunkMesh> {
    // Global index of local sample 0 (may be negative in the halo).
    let first = chunk.map(|c| (c * CHUNK_CUBES) as i64 - AMBIGUITY_ROUNDS as i64);
    let h = grid.spacing;
    let chunk_span = (CHUNK_POINTS - 1) as f64;
    let centre = grid.position(first.map(|f| f as f64 + 0.5 * chunk_span));
    let half_diagonal = 0.5 * chunk_span * h * 3f64.sqrt();
    if marker.signed_distance(&centre).abs() > half_diagonal + 2.0 * h {
        return None;
    }
    // Every sample of the chunk lies within its half-diagonal of the
    // centre: there the cut-down marker's field is the marker's, exactly.
    let marker = &marker.near(&centre, half_diagonal);

    let outside = (4.0 * chunk_span * h) as f32;
    let mut sdf = vec![outside; ChunkShape::USIZE];
    let in_grid = |g: [i64; 3]| (0..3).all(|k| g[k] >= 0 && g[k] < grid.points[k] as i64);
    let mut any_negative = false;
    let mut any_positive = false;
    let block_span = (BLOCK_POINTS - 1) as f64;
    let block_half_diagonal = 0.5 * block_span * h * 3f64.sqrt();
    for bz in (0..CHUNK_POINTS).step_by(BLOCK_POINTS as usize) {
        for by in (0..CHUNK_POINTS).step_by(BLOCK_POINTS as usize) {
            for bx in (0..CHUNK_POINTS).step_by(BLOCK_POINTS as usize) {
                let block = [bx, by, bz];
                let block_centre = grid.position(
                    [0, 1, 2].map(|k| first[k] as f64 + block[k] as f64 + 0.5 * block_span),
                );
                let far = marker.signed_distance(&block_centre);
                let skip = far.abs() > block_half_diagonal + 2.0 * h;
                for z in bz..(bz + BLOCK_POINTS).min(CHUNK_POINTS) {
                    for y in by..(by + BLOCK_POINTS).min(CHUNK_POINTS) {
                        for x in bx..(bx + BLOCK_POINTS).min(CHUNK_POINTS) {
                            let global = [
                                first[0] + x as i64,
                                first[1] + y as i64,
                                first[2] + z as i64,
                            ];
                            if !in_grid(global) {
                                continue; // stays outside
                            }
                            let value = if skip {
                                far.signum() * (far.abs() - block_half_diagonal)
                            } else {
                                marker.signed_distance(&grid.position(global.map(|g| g as f64)))
                            };
                            let value = value as f32;
                            any_negative |= value < 0.0;
                            any_positive |= value >= 0.0;
                            sdf[ChunkShape::linearize([x, y, z]) as usize] = value;
                        }
                    }
                }
            }
        }
    }
    if !(any_negative && any_positive) {
        return None;
    }

    // Corners of a cube that the surface crosses lie within a cube
    // diagonal of it (the field is 1-Lipschitz).
    let near = (3f64.sqrt() * h) as f32 * 1.01;
    resolve_ambiguities(&mut sdf, near, |local: [f64; 3]| {
        marker.signed_distance(&grid.position([0, 1, 2].map(|k| first[k] as f64 + local[k])))
    });

    let mut buffer = SurfaceNetsBuffer::default();
    let halo = AMBIGUITY_ROUNDS;
    surface_nets(
        &sdf,
        &ChunkShape {},
        [halo; 3],
        [halo + CHUNK_CUBES + 1; 3],
        &mut buffer,
    );
    let vertices: Vec<(u64, Vector3<f64>)> = buffer
        .surface_points
        .iter()
        .zip(&buffer.positions)
        .map(|(cube, local)| {
            let global = [0, 1, 2].map(|k| (first[k] + cube[k] as i64) as u32);
            let position = grid.position([0, 1, 2].map(|k| first[k] as f64 + local[k] as f64));
            (cube_key(global), position)
        })
        .collect();
    let triangles = buffer
        .indices
        .chunks_exact(3)
        .map(|t| [0, 1, 2].map(|k| vertices[t[k] as usize].0))
        .collect();
    Some(ChunkMesh {
        vertices,
        triangles,
    })
}

/// Corner offsets of a unit cube, in the order of the bits of their index
/// (bit 0: x, bit 1: y, bit 2: z).
const CUBE_CORNERS: [[u32; 3]; 8] = [
    [0, 0, 0],
    [1, 0, 0],
    [0, 1, 0],
    [1, 1, 0],
    [0, 0, 1],
    [1, 0, 1],
    [0, 1, 1],
    [1, 1, 1],
];

/// Removes the sign patterns that Naive Surface Nets cannot mesh as a
/// manifold, using the analytic field `field(local coordinate)` to decide
/// the true connectivity below the grid's resolution:
///
/// * a *face* whose diagonal corners share a sign (a checkerboard) would
///   give an edge four faces; the field at the face centre says whether the
///   inside (centre negative) or the outside connects across it;
/// * a *cube* whose inside or outside corners fall apart into several
///   pieces would give a vertex two fans; the field at the cube centre
///   decides likewise.
///
/// Either way the corner of the disconnected sign that lies nearest the
/// surface is moved just across it, so the pieces join (or part) as the
/// field says. A round fixes every ambiguity found in the samples as they
/// were at its start; rounds repeat, at most [`AMBIGUITY_ROUNDS`], until
/// none is left. Values at least `r` samples from the border after `r`
/// rounds depend only on samples in the array, which keeps chunks with a
/// halo of [`AMBIGUITY_ROUNDS`] in agreement.
fn resolve_ambiguities(sdf: &mut [f32], near: f32, field: impl Fn([f64; 3]) -> f64) {
    let n = CHUNK_POINTS;
    let at = |p: [u32; 3]| ChunkShape::linearize(p) as usize;
    // A corner is moved at most once, so rounds cannot undo each other.
    let mut moved: HashSet<usize> = HashSet::new();
    for _ in 0..AMBIGUITY_ROUNDS {
        let mut flips: Vec<(usize, f32)> = Vec::new();
        // Faces: for each axis, faces spanned by the two other axes.
        for normal in 0..3 {
            let (u, v) = ((normal + 1) % 3, (normal + 2) % 3);
            for z in 0..n {
                for y in 0..n {
                    for x in 0..n {
                        let p = [x, y, z];
                        // A face with both signs has every corner within a
                        // face diagonal of the surface.
                        if p[u] + 1 >= n || p[v] + 1 >= n || sdf[at(p)].abs() > near {
                            continue;
                        }
                        let corner = |du: u32, dv: u32| {
                            let mut q = p;
                            q[u] += du;
                            q[v] += dv;
                            q
                        };
                        let corners = [corner(0, 0), corner(1, 0), corner(1, 1), corner(0, 1)];
                        let values = corners.map(|q| sdf[at(q)]);
                        let negative = values.map(|v| v < 0.0);
                        let checkerboard = negative[0] == negative[2]
                            && negative[1] == negative[3]
                            && negative[0] != negative[1];
                        if !checkerboard {
                            continue;
                        }
                        let mut centre = p.map(|c| c as f64);
                        centre[u] += 0.5;
                        centre[v] += 0.5;
                        let inside_connects = field(centre) < 0.0;
                        // Move the corner of the sign that must not connect
                        // across (positive if the inside connects).
                        flips.extend(corner_to_move(
                            &corners.map(at),
                            &values,
                            inside_connects,
                            &moved,
                        ));
                    }
                }
            }
        }
        // Cubes whose corners of one sign form several pieces.
        for z in 0..n - 1 {
            for y in 0..n - 1 {
                for x in 0..n - 1 {
                    if sdf[at([x, y, z])].abs() > near {
                        continue;
                    }
                    let corners = CUBE_CORNERS.map(|c| [x + c[0], y + c[1], z + c[2]]);
                    let values = corners.map(|q| sdf[at(q)]);
                    let negative = values.map(|v| v < 0.0);
                    let pieces = |sign: bool| {
                        let mut seen = [false; 8];
                        let mut count = 0;
                        for start in 0..8 {
                            if negative[start] != sign || seen[start] {
                                continue;
                            }
                            count += 1;
                            let mut stack = vec![start];
                            seen[start] = true;
                            while let Some(c) = stack.pop() {
                                for bit in [1, 2, 4] {
                                    let d = c ^ bit;
                                    if negative[d] == sign && !seen[d] {
                                        seen[d] = true;
                                        stack.push(d);
                                    }
                                }
                            }
                        }
                        count
                    };
                    if pieces(true) <= 1 && pieces(false) <= 1 {
                        continue;
                    }
                    // A checkerboard face of this cube is the face rule's to
                    // resolve; acting here too could undo it.
                    let checkerboard_face = [
                        (0, 1, 3, 2),
                        (4, 5, 7, 6),
                        (0, 1, 5, 4),
                        (2, 3, 7, 6),
                        (0, 2, 6, 4),
                        (1, 3, 7, 5),
                    ]
                    .iter()
                    .any(|&(a, b, c, d)| {
                        negative[a] == negative[c]
                            && negative[b] == negative[d]
                            && negative[a] != negative[b]
                    });
                    if checkerboard_face {
                        continue;
                    }
                    let inside_connects =
                        field([x as f64 + 0.5, y as f64 + 0.5, z as f64 + 0.5]) < 0.0;
                    flips.extend(corner_to_move(
                        &corners.map(at),
                        &values,
                        inside_connects,
                        &moved,
                    ));
                }
            }
        }
        if flips.is_empty() {
            break;
        }
        for (index, value) in flips {
            if !moved.insert(index) {
                continue; // already moved this round
            }
            // Just across the surface: the sign changes, the crossing stays
            // at this corner.
            sdf[index] = if value < 0.0 {
                f32::MIN_POSITIVE
            } else {
                -f32::MIN_POSITIVE
            };
        }
    }
}

/// The corner of an ambiguous face or cube that [`resolve_ambiguities`]
/// moves: of the corners (sample indices, with their values) whose sign must
/// not connect across (positive if the inside connects), the one nearest the
/// surface that has not been moved yet, with its value.
fn corner_to_move(
    corners: &[usize],
    values: &[f32],
    inside_connects: bool,
    moved: &HashSet<usize>,
) -> Option<(usize, f32)> {
    corners
        .iter()
        .zip(values)
        .filter(|&(index, &value)| (value < 0.0) != inside_connects && !moved.contains(index))
        .min_by(|a, b| a.1.abs().total_cmp(&b.1.abs()))
        .map(|(&index, &value)| (index, value))
}

/// Moves `start` onto the zero level set by Newton steps along the
/// gradient, each step capped at one cell and the whole move at two cells
/// (a vertex of Surface Nets is always within one cell of the surface).
pub fn project_onto_surface(marker: &Marker, start: Vector3<f64>, cell_mm: f64) -> Vector3<f64> {
    let mut p = start;
    for _ in 0..PROJECTION_ITERATIONS {
        let sample = marker.sample(&p);
        if sample.value.abs() < PROJECTION_TOLERANCE_MM {
            break;
        }
        let g2 = sample.gradient.norm_squared();
        if g2 < 1e-12 {
            break;
        }
        let mut step = sample.gradient * (sample.value / g2);
        let length = step.norm();
        if length > cell_mm {
            step *= cell_mm / length;
        }
        let next = p - step;
        if (next - start).norm() > 2.0 * cell_mm {
            break;
        }
        p = next;
    }
    p
}
