//! What the workshop measures the printed part against: the datum frame
//! on the base plate, every sphere centre and hole axis from it, the
//! pairwise sphere distances and the identification margin they leave,
//! and the tolerances — the sphere-centre tolerance from the error model
//! and the workshop's own for diameters and holes. The fabrication sheet
//! ([`super::sheet`]) prints them.

use super::geometry::Marker;
use nalgebra::{Matrix3, Vector3};
use serde::Serialize;

/// The datum reference frame of the drawings and the sheet: a corner of
/// the base plate, the face that lies on the bed.
///
/// * Datum A: the plate's bed face (z = 0 of the STL).
/// * Datum B: the plate's side face at the smallest X of the STL.
/// * Datum C: the plate's side face at the smallest Y of the STL.
///
/// Datum coordinates are the STL's print-frame axes (Z up, away from the
/// bed) with the origin where the three faces meet (the corner of the
/// plate's box before its edges are rounded), so a technician measures each
/// sphere from the plate with the part standing as printed.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Datum {
    /// Marker frame → datum frame rotation (the STL's print rotation).
    pub rotation: Matrix3<f64>,
    /// The datum origin in the marker frame, mm.
    pub origin_mm: Vector3<f64>,
}

impl Datum {
    /// The datum of `marker`'s base plate.
    pub fn of(marker: &Marker) -> Datum {
        let (rotation, shift) = marker.print_transform();
        let plate = &marker.plate;
        let corner = rotation * plate.centre - rotation.abs() * plate.half_extents;
        let origin_print = Vector3::new(corner.x, corner.y, 0.0);
        Datum {
            rotation,
            origin_mm: rotation.transpose() * (origin_print - shift),
        }
    }

    /// The datum coordinates (x from B, y from C, z from A) of a
    /// marker-frame point, mm.
    pub fn coordinates(&self, p: &Vector3<f64>) -> Vector3<f64> {
        self.rotation * (p - self.origin_mm)
    }

    /// Datum axis `k` (0: x, 1: y, 2: z) as a marker-frame direction.
    pub fn axis(&self, k: usize) -> Vector3<f64> {
        self.rotation.row(k).transpose()
    }
}

/// A feature located from the [`Datum`]: a sphere centre or a hole axis.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DatumPosition {
    /// "sphere" or "hole".
    pub kind: &'static str,
    /// The sphere's name, or H1, H2, … for holes.
    pub name: String,
    /// Datum coordinates, mm (for a hole, z is the plate's mid-plane).
    pub position_mm: [f64; 3],
}

/// Every sphere centre and hole axis of `marker` in datum coordinates.
pub fn datum_positions(marker: &Marker) -> Vec<DatumPosition> {
    let datum = Datum::of(marker);
    let spheres = marker
        .spheres
        .iter()
        .map(|s| (s.name.clone(), "sphere", s.centre));
    let holes = marker
        .plate
        .holes
        .iter()
        .enumerate()
        .map(|(k, h)| (format!("H{}", k + 1), "hole", h.centre));
    spheres
        .chain(holes)
        .map(|(name, kind, p)| {
            let d = datum.coordinates(&p);
            DatumPosition {
                kind,
                name,
                position_mm: [d.x, d.y, d.z],
            }
        })
        .collect()
}

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

/// Sphere diameter tolerance, ± mm: a workshop figure, not from the error
/// model (the solvers use the centres; the diameter only sizes the image
/// disc a detector fits).
pub const DIAMETER_TOLERANCE_MM: f64 = 0.2;
/// Hole position tolerance, ± mm: for mounting only.
pub const HOLE_TOLERANCE_MM: f64 = 0.2;

/// Whether one image identifies the spheres, as the search that made the
/// layout found it (its provenance's `identifiability`): the unlabelled
/// solver labels the blobs correctly in `identifiable` of the `visible`
/// scenarios of the search's working volume.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct OneImageIdentifiability {
    /// Visible scenarios in which one image identifies the spheres.
    pub identifiable: usize,
    /// Visible scenarios checked.
    pub visible: usize,
}

impl OneImageIdentifiability {
    /// Reads it from a layout's provenance (None when the layout does not
    /// record it, or records it incompletely).
    pub fn from_provenance(provenance: Option<&serde_json::Value>) -> Option<Self> {
        let record = provenance?.get("identifiability")?;
        let count = |key: &str| record.get(key)?.as_u64().map(|v| v as usize);
        Some(OneImageIdentifiability {
            identifiable: count("identifiable")?,
            visible: count("visible")?,
        })
    }

    /// Every visible scenario (at least one) identifiable.
    pub fn everywhere(&self) -> bool {
        self.visible > 0 && self.identifiable == self.visible
    }
}

/// The tolerances the sheet gives.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Tolerances {
    /// Sphere-centre tolerance from the error model, or `None` when no
    /// scenario of the grid sees every sphere.
    pub centre: Option<crate::error_model::fabrication::FabricationTolerance>,
    /// What the centre tolerance was computed over (camera and grid).
    pub basis: String,
    /// Sphere diameter, ± mm ([`DIAMETER_TOLERANCE_MM`]).
    pub diameter_mm: f64,
    /// Hole positions, ± mm ([`HOLE_TOLERANCE_MM`]).
    pub hole_position_mm: f64,
}

impl Tolerances {
    /// The centre tolerance over `validate`'s default camera and grid
    /// (the paper's camera and protocol, tilt step 2°, σ = 0.5 px).
    pub fn for_marker(marker: &Marker) -> Tolerances {
        use crate::error_model::fabrication::{tolerance, TOLERANCE_SHARE};
        let camera = crate::camera::Camera::paper();
        let grid = crate::scenario::ScenarioGrid::paper_protocol(2.0);
        let object: Vec<Vector3<f64>> = marker.spheres.iter().map(|s| s.centre).collect();
        let diameter_mm = marker.spheres.first().map_or(0.0, |s| 2.0 * s.radius);
        Tolerances {
            centre: tolerance(&camera, &grid, &object, diameter_mm, TOLERANCE_SHARE).ok(),
            basis: "validate's default scenarios: the paper's camera, depths 200–1000 mm, x offsets 0/50/100 mm, tilt −90…90° in 2° steps, σ = 0.5 px".to_string(),
            diameter_mm: DIAMETER_TOLERANCE_MM,
            hole_position_mm: HOLE_TOLERANCE_MM,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::workflow::tests::small;
    use crate::mesh::MarkerOptions;

    /// The datum is the corner of the plate's bed face: the datum
    /// coordinates of the plate's corners are 0 and its sizes, and Z is
    /// the STL's z.
    #[test]
    fn datum_is_the_plates_bed_corner() {
        let marker = Marker::design(&small(), &MarkerOptions::default()).unwrap();
        let datum = Datum::of(&marker);
        let (rotation, shift) = marker.print_transform();
        let plate = &marker.plate;
        let mut lo = Vector3::repeat(f64::INFINITY);
        for sx in [-1.0, 1.0] {
            for sy in [-1.0, 1.0] {
                for sz in [-1.0, 1.0] {
                    let corner =
                        plate.centre + plate.half_extents.component_mul(&Vector3::new(sx, sy, sz));
                    lo = lo.inf(&datum.coordinates(&corner));
                }
            }
        }
        assert!(lo.norm() < 1e-9, "{lo}");
        for s in &marker.spheres {
            let d = datum.coordinates(&s.centre);
            let print = rotation * s.centre + shift;
            assert!((d.z - print.z).abs() < 1e-9);
            assert!(d.z > 0.0);
        }
    }
}
