//! Wavefront OBJ: millimetres, in the marker frame (the layout's
//! coordinates), with per-vertex normals. Written by hand: OBJ is plain
//! text and `tobj`, which reads it back in the tests, only reads.

use super::{write_file, ExportError, Format, MeshWriter, Solid};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Writes `<name>.obj`.
#[derive(Debug, Clone, Copy)]
pub struct ObjWriter;

impl MeshWriter for ObjWriter {
    fn format(&self) -> Format {
        Format::Obj
    }

    fn write(&self, solid: &Solid, dir: &Path) -> Result<Vec<PathBuf>, ExportError> {
        let mesh = &solid.mesh;
        let mut text =
            String::with_capacity(64 * (mesh.positions.len() * 2 + mesh.triangles.len()));
        let _ = writeln!(
            text,
            "# layout-opt {} export of {}\n# units: millimetres; frame: the marker's (layout coordinates)\n# {} vertices, {} triangles",
            env!("CARGO_PKG_VERSION"),
            solid.name(),
            mesh.positions.len(),
            mesh.triangles.len()
        );
        let _ = writeln!(text, "o {}", solid.name());
        for p in &mesh.positions {
            let _ = writeln!(text, "v {:.6} {:.6} {:.6}", p.x, p.y, p.z);
        }
        for n in &solid.normals {
            let _ = writeln!(text, "vn {:.6} {:.6} {:.6}", n.x, n.y, n.z);
        }
        for t in &mesh.triangles {
            let [a, b, c] = t.map(|v| v + 1);
            let _ = writeln!(text, "f {a}//{a} {b}//{b} {c}//{c}");
        }
        let path = dir.join(format!("{}.obj", solid.name()));
        write_file(&path, text.as_bytes())?;
        Ok(vec![path])
    }
}
