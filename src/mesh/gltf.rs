//! glTF 2.0 (`gltf-json`): `.gltf` + `.bin`, or one binary `.glb`.
//!
//! As the glTF specification requires: metres, Y up
//! ([`super::geometry::gltf_rotation`]: the print frame turned Y-up, so the
//! base points down, [`super::Marker::down`]), counter-clockwise front faces, one mesh with
//! float POSITION (with its `min`/`max`, required for positions), unit
//! NORMAL and unsigned-int indices, in buffer views aligned to four bytes.

use super::geometry::gltf_rotation;
use super::{write_file, ExportError, Format, MeshWriter, Solid};
use gltf_json as json;
use json::validation::Checked::Valid;
use json::validation::USize64;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// Millimetres per metre.
const MM_PER_M: f64 = 1000.0;

/// Writes `<name>.gltf` + `<name>.bin`, or `<name>.glb`.
#[derive(Debug, Clone, Copy)]
pub struct GltfWriter {
    /// `.glb` rather than `.gltf` + `.bin`.
    pub binary: bool,
}

/// The binary buffer and the JSON document that describes it.
fn encode(solid: &Solid, buffer_uri: Option<String>) -> (json::Root, Vec<u8>) {
    let rotation = gltf_rotation(solid.marker.down);
    let positions: Vec<[f32; 3]> = solid
        .mesh
        .positions
        .iter()
        .map(|p| (rotation * p / MM_PER_M).map(|v| v as f32).into())
        .collect();
    let normals: Vec<[f32; 3]> = solid
        .normals
        .iter()
        .map(|n| (rotation * n).map(|v| v as f32).into())
        .collect();
    let indices: Vec<u32> = solid.mesh.triangles.iter().flatten().copied().collect();

    let mut min = [f32::INFINITY; 3];
    let mut max = [f32::NEG_INFINITY; 3];
    for p in &positions {
        for k in 0..3 {
            min[k] = min[k].min(p[k]);
            max[k] = max[k].max(p[k]);
        }
    }
    let mut bin: Vec<u8> = Vec::with_capacity(24 * positions.len() + 4 * indices.len());
    for v in positions.iter().chain(&normals).flatten() {
        bin.extend_from_slice(&v.to_le_bytes());
    }
    for i in &indices {
        bin.extend_from_slice(&i.to_le_bytes());
    }
    let vertex_bytes = 12 * positions.len();

    let mut root = json::Root {
        asset: json::Asset {
            generator: Some(format!("layout-opt {}", env!("CARGO_PKG_VERSION"))),
            ..Default::default()
        },
        ..Default::default()
    };
    let buffer = root.push(json::Buffer {
        byte_length: USize64::from(bin.len()),
        extensions: Default::default(),
        extras: Default::default(),
        name: None,
        uri: buffer_uri,
    });
    let view = |root: &mut json::Root, offset: usize, length: usize, target| {
        root.push(json::buffer::View {
            buffer,
            byte_length: USize64::from(length),
            byte_offset: Some(USize64::from(offset)),
            byte_stride: None,
            extensions: Default::default(),
            extras: Default::default(),
            name: None,
            target: Some(Valid(target)),
        })
    };
    let position_view = view(
        &mut root,
        0,
        vertex_bytes,
        json::buffer::Target::ArrayBuffer,
    );
    let normal_view = view(
        &mut root,
        vertex_bytes,
        vertex_bytes,
        json::buffer::Target::ArrayBuffer,
    );
    let index_view = view(
        &mut root,
        2 * vertex_bytes,
        4 * indices.len(),
        json::buffer::Target::ElementArrayBuffer,
    );
    let accessor = |root: &mut json::Root,
                    view,
                    count: usize,
                    component,
                    type_,
                    bounds: Option<([f32; 3], [f32; 3])>| {
        root.push(json::Accessor {
            buffer_view: Some(view),
            byte_offset: Some(USize64(0)),
            count: USize64::from(count),
            component_type: Valid(json::accessor::GenericComponentType(component)),
            extensions: Default::default(),
            extras: Default::default(),
            type_: Valid(type_),
            min: bounds.map(|(lo, _)| json::Value::from(lo.to_vec())),
            max: bounds.map(|(_, hi)| json::Value::from(hi.to_vec())),
            name: None,
            normalized: false,
            sparse: None,
        })
    };
    use json::accessor::{ComponentType, Type};
    let position_accessor = accessor(
        &mut root,
        position_view,
        positions.len(),
        ComponentType::F32,
        Type::Vec3,
        Some((min, max)),
    );
    let normal_accessor = accessor(
        &mut root,
        normal_view,
        normals.len(),
        ComponentType::F32,
        Type::Vec3,
        None,
    );
    let index_accessor = accessor(
        &mut root,
        index_view,
        indices.len(),
        ComponentType::U32,
        Type::Scalar,
        None,
    );
    let primitive = json::mesh::Primitive {
        attributes: BTreeMap::from([
            (Valid(json::mesh::Semantic::Positions), position_accessor),
            (Valid(json::mesh::Semantic::Normals), normal_accessor),
        ]),
        extensions: Default::default(),
        extras: Default::default(),
        indices: Some(index_accessor),
        material: None,
        mode: Valid(json::mesh::Mode::Triangles),
        targets: None,
    };
    let mesh = root.push(json::Mesh {
        extensions: Default::default(),
        extras: Default::default(),
        name: Some(solid.marker.name.clone()),
        primitives: vec![primitive],
        weights: None,
    });
    let node = root.push(json::Node {
        mesh: Some(mesh),
        name: Some(solid.marker.name.clone()),
        ..Default::default()
    });
    let scene = root.push(json::Scene {
        extensions: Default::default(),
        extras: Default::default(),
        name: Some(solid.marker.name.clone()),
        nodes: vec![node],
    });
    root.scene = Some(scene);
    (root, bin)
}

impl MeshWriter for GltfWriter {
    fn format(&self) -> Format {
        if self.binary {
            Format::Glb
        } else {
            Format::Gltf
        }
    }

    fn write(&self, solid: &Solid, dir: &Path) -> Result<Vec<PathBuf>, ExportError> {
        let name = solid.name();
        let gltf_error = |e: json::Error| ExportError::Gltf(e.to_string());
        if self.binary {
            let (root, bin) = encode(solid, None);
            let text = json::serialize::to_string(&root).map_err(gltf_error)?;
            let glb = ::gltf::binary::Glb {
                header: ::gltf::binary::Header {
                    magic: *b"glTF",
                    version: 2,
                    length: 0, // computed by `to_vec`
                },
                json: text.into_bytes().into(),
                bin: Some(bin.into()),
            };
            let bytes = glb.to_vec().map_err(|e| ExportError::Gltf(e.to_string()))?;
            let path = dir.join(format!("{name}.glb"));
            write_file(&path, &bytes)?;
            Ok(vec![path])
        } else {
            let bin_name = format!("{name}.bin");
            let (root, bin) = encode(solid, Some(bin_name.clone()));
            let text = json::serialize::to_string_pretty(&root).map_err(gltf_error)? + "\n";
            let gltf_path = dir.join(format!("{name}.gltf"));
            let bin_path = dir.join(bin_name);
            write_file(&bin_path, &bin)?;
            write_file(&gltf_path, text.as_bytes())?;
            Ok(vec![gltf_path, bin_path])
        }
    }
}
