//! Binary STL for printers (`stl_io`): millimetres, in the print frame —
//! Z up, the base pointing down onto the bed
//! ([`super::geometry::print_rotation`] of [`super::Marker::down`]) and
//! shifted along Z so that the lowest point lies on the bed at z = 0: a
//! rigid motion of the marker frame, so that sphere centres keep their
//! distances and map exactly ([`Solid::print_transform`]). The 80-byte
//! header names the part and its units ([`header`]).

use super::{write_file, ExportError, Format, MeshWriter, Solid};
use std::path::{Path, PathBuf};

/// Writes `<name>.stl`.
#[derive(Debug, Clone, Copy)]
pub struct StlWriter;

impl MeshWriter for StlWriter {
    fn format(&self) -> Format {
        Format::Stl
    }

    fn write(&self, solid: &Solid, dir: &Path) -> Result<Vec<PathBuf>, ExportError> {
        let (rotation, shift) = solid.print_transform();
        let mesh = solid.mesh.transformed(|p| rotation * p + shift);
        let triangles: Vec<stl_io::Triangle> = (0..mesh.triangles.len())
            .map(|f| {
                let normal = mesh.face_cross(f).normalize();
                stl_io::Triangle {
                    normal: stl_io::Normal::new(normal.map(|v| v as f32).into()),
                    vertices: mesh
                        .face(f)
                        .map(|p| stl_io::Vertex::new(p.map(|v| v as f32).into())),
                }
            })
            .collect();
        let mut bytes = Vec::with_capacity(84 + 50 * triangles.len());
        stl_io::write_stl(&mut bytes, triangles.iter()).map_err(|source| ExportError::Io {
            path: dir.to_path_buf(),
            source,
        })?;
        bytes[..80].copy_from_slice(&header(&solid.marker.name));
        let path = dir.join(format!("{}.stl", solid.name()));
        write_file(&path, &bytes)?;
        Ok(vec![path])
    }
}

/// The 80-byte binary STL header: the part's name and units, padded with
/// spaces (never starting with `solid`, which readers take for ASCII STL).
pub fn header(part_name: &str) -> [u8; 80] {
    let text = format!("layout-opt part {part_name}; units mm; Z up");
    let mut header = [b' '; 80];
    for (slot, byte) in header.iter_mut().zip(text.bytes()) {
        *slot = byte;
    }
    header
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_header_names_the_part_and_its_units() {
        let header = header("biprism-paper");
        let text = std::str::from_utf8(&header).unwrap();
        assert!(text.starts_with("layout-opt part biprism-paper; units mm; Z up"));
        assert!(!text.starts_with("solid"));
        let long = "x".repeat(200);
        assert_eq!(super::header(&long).len(), 80);
    }
}
