//! 3MF for slicers: one object in millimetres, in the print frame like the
//! STL (Z up, the bed face at z = 0, [`Solid::print_transform`]), named
//! after the part.
//!
//! A 3MF file is an Open Packaging Conventions zip holding three parts: the
//! content types, the package relationships pointing at the model, and the
//! model itself (3MF Core Specification 1.3, §2–4). The model lists the
//! indexed mesh once (shared vertices, counter-clockwise triangles seen from
//! outside), which is what the core specification's "model" objects require
//! of a manifold, oriented solid; slicers then need no repair.

use super::{write_file, ExportError, Format, MeshWriter, Solid};
use std::fmt::Write as _;
use std::io::Write as _;
use std::path::{Path, PathBuf};

/// Path of the model part inside the package.
pub const MODEL_PART: &str = "3D/3dmodel.model";

/// The 3MF core namespace (2015/02, the one every current slicer reads).
const CORE_NAMESPACE: &str = "http://schemas.microsoft.com/3dmanufacturing/core/2015/02";

const CONTENT_TYPES: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<Types xmlns="http://schemas.openxmlformats.org/package/2006/content-types">
 <Default Extension="rels" ContentType="application/vnd.openxmlformats-package.relationships+xml"/>
 <Default Extension="model" ContentType="application/vnd.ms-package.3dmanufacturing-3dmodel+xml"/>
</Types>
"#;

const RELATIONSHIPS: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<Relationships xmlns="http://schemas.openxmlformats.org/package/2006/relationships">
 <Relationship Target="/3D/3dmodel.model" Id="rel0" Type="http://schemas.microsoft.com/3dmanufacturing/2013/01/3dmodel"/>
</Relationships>
"#;

/// Writes `<name>.3mf`.
#[derive(Debug, Clone, Copy)]
pub struct ThreeMfWriter;

impl MeshWriter for ThreeMfWriter {
    fn format(&self) -> Format {
        Format::ThreeMf
    }

    fn write(&self, solid: &Solid, dir: &Path) -> Result<Vec<PathBuf>, ExportError> {
        let path = dir.join(format!("{}.3mf", solid.name()));
        let io_error = |source: std::io::Error| ExportError::Io {
            path: path.clone(),
            source,
        };
        let (rotation, shift) = solid.print_transform();
        let mesh = solid.mesh.transformed(|p| rotation * p + shift);
        let model = model_xml(&solid.marker.name, &mesh);
        let mut zip = zip::ZipWriter::new(std::io::Cursor::new(Vec::new()));
        let deflated = zip::write::SimpleFileOptions::default()
            .compression_method(zip::CompressionMethod::Deflated);
        for (name, text) in [
            ("[Content_Types].xml", CONTENT_TYPES),
            ("_rels/.rels", RELATIONSHIPS),
            (MODEL_PART, model.as_str()),
        ] {
            zip.start_file(name, deflated)
                .map_err(|e| io_error(e.into()))?;
            zip.write_all(text.as_bytes()).map_err(io_error)?;
        }
        let bytes = zip.finish().map_err(|e| io_error(e.into()))?.into_inner();
        write_file(&path, &bytes)?;
        Ok(vec![path])
    }
}

/// The model part: metadata naming the part, one mesh object, one build item.
pub fn model_xml(part_name: &str, mesh: &super::TriangleMesh) -> String {
    let name = escape(part_name);
    // About 70 bytes per vertex and 50 per triangle.
    let mut xml =
        String::with_capacity(512 + 70 * mesh.positions.len() + 50 * mesh.triangles.len());
    let _ = write!(
        xml,
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n\
         <model unit=\"millimeter\" xml:lang=\"en-US\" xmlns=\"{CORE_NAMESPACE}\">\n \
         <metadata name=\"Title\">{name}</metadata>\n \
         <metadata name=\"Application\">layout-opt {}</metadata>\n \
         <resources>\n  <object id=\"1\" type=\"model\" name=\"{name}\">\n   <mesh>\n    <vertices>\n",
        env!("CARGO_PKG_VERSION")
    );
    // Micrometre precision is far below any printer's; shortest round-trip
    // formatting of the rounded value keeps the file small.
    let round = |v: f64| (v * 1e4).round() / 1e4;
    for p in &mesh.positions {
        let _ = writeln!(
            xml,
            "     <vertex x=\"{}\" y=\"{}\" z=\"{}\"/>",
            round(p.x),
            round(p.y),
            round(p.z)
        );
    }
    xml.push_str("    </vertices>\n    <triangles>\n");
    for [a, b, c] in &mesh.triangles {
        let _ = writeln!(xml, "     <triangle v1=\"{a}\" v2=\"{b}\" v3=\"{c}\"/>");
    }
    xml.push_str(
        "    </triangles>\n   </mesh>\n  </object>\n </resources>\n <build>\n  <item objectid=\"1\"/>\n </build>\n</model>\n",
    );
    xml
}

/// Escapes the five XML special characters.
fn escape(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&apos;"),
            c if c.is_control() => out.push(' '),
            c => out.push(c),
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::TriangleMesh;
    use nalgebra::Vector3;

    #[test]
    fn the_model_names_the_part_in_millimetres_and_escapes_it() {
        let mesh = TriangleMesh {
            positions: vec![
                Vector3::new(0.0, 0.0, 0.0),
                Vector3::new(1.0, 0.0, 0.0),
                Vector3::new(0.0, 1.0, 0.0),
                Vector3::new(0.0, 0.0, 1.123456789),
            ],
            triangles: vec![[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]],
        };
        let xml = model_xml("a<b & \"c\"", &mesh);
        assert!(xml.contains("unit=\"millimeter\""));
        assert!(xml.contains("<metadata name=\"Title\">a&lt;b &amp; &quot;c&quot;</metadata>"));
        assert!(xml.contains("name=\"a&lt;b &amp; &quot;c&quot;\""));
        assert_eq!(xml.matches("<vertex ").count(), 4);
        assert_eq!(xml.matches("<triangle ").count(), 4);
        assert!(xml.contains("z=\"1.1235\""));
        assert!(xml.contains("<item objectid=\"1\"/>"));
    }
}
