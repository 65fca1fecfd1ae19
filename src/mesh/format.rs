//! The mesh formats `export` writes, by their stable CLI names.

use super::ExportError;
use serde::Serialize;
use std::fmt;
use std::str::FromStr;

/// An output mesh format.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Format {
    /// Binary STL, mm, print frame (Z up).
    Stl,
    /// Wavefront OBJ, mm, marker frame.
    Obj,
    /// glTF 2.0 JSON + .bin, metres, Y up.
    Gltf,
    /// Binary glTF 2.0, metres, Y up.
    Glb,
    /// 3MF (zipped XML), mm, print frame (Z up), for slicers.
    #[serde(rename = "3mf")]
    ThreeMf,
}

impl Format {
    /// Every format, in the order files are written.
    pub const ALL: &'static [Format] = &[
        Format::Stl,
        Format::ThreeMf,
        Format::Obj,
        Format::Gltf,
        Format::Glb,
    ];

    /// Its CLI name and file extension.
    pub fn name(self) -> &'static str {
        match self {
            Format::Stl => "stl",
            Format::Obj => "obj",
            Format::Gltf => "gltf",
            Format::Glb => "glb",
            Format::ThreeMf => "3mf",
        }
    }
}

impl fmt::Display for Format {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Format {
    type Err = ExportError;
    fn from_str(text: &str) -> Result<Format, ExportError> {
        let lower = text.trim().to_ascii_lowercase();
        Format::ALL
            .iter()
            .copied()
            .find(|f| f.name() == lower)
            .ok_or_else(|| ExportError::UnknownFormat(text.to_string()))
    }
}
