//! Correspondences between a source and a target mesh, in the files' own vertex numbering, and
//! their JSON file (`{"correspondences": [...]}`).

/// Which of the two meshes of a transfer.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
pub enum Side {
    /// The exemplar (coloured) mesh.
    Source,
    /// The mesh to texture.
    Target,
}

/// One correspondence: a source vertex and one or more target vertices (one-to-many), in the
/// files' own vertex numbering.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Correspondence {
    /// Source file vertex index.
    pub source_vertex: u32,
    /// Target file vertex indices (several = one-to-many).
    pub target_vertices: Vec<u32>,
}

impl Correspondence {
    /// The pair's vertices on `side`: the source vertex, or the target vertices.
    pub fn vertices(&self, side: Side) -> &[u32] {
        match side {
            Side::Source => std::slice::from_ref(&self.source_vertex),
            Side::Target => &self.target_vertices,
        }
    }
}

/// The correspondences file: `{"correspondences": [...]}`.
#[derive(Clone, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct CorrespondenceFile {
    /// The pairs.
    pub correspondences: Vec<Correspondence>,
}

impl CorrespondenceFile {
    /// Read and parse a correspondences JSON file.
    pub fn load(path: &std::path::Path) -> crate::error::Result<Self> {
        let text = std::fs::read_to_string(path).map_err(|e| crate::error::Error::io(path, e))?;
        serde_json::from_str(&text).map_err(|e| {
            crate::error::Error::format(path, format!("invalid correspondences JSON: {e}"))
        })
    }
    /// Write as pretty JSON (atomically).
    pub fn save(&self, path: &std::path::Path) -> crate::error::Result<()> {
        let text = serde_json::to_string_pretty(self).expect("serialisable");
        crate::mesh::io::write_atomic(path, text.as_bytes())
    }
}
