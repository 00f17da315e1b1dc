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

/// Most correspondence pairs accepted: each pair costs a geodesic solve per level and feature
/// dimensions per vertex, so thousands of pairs would run for many minutes.
pub const MAX_CORRESPONDENCES: usize = 256;

/// Most target vertices over all pairs together (one-to-many pairs count each of theirs).
pub const MAX_CORRESPONDENCE_TARGETS: usize = 1024;

/// Refuse more than [`MAX_CORRESPONDENCES`] pairs or [`MAX_CORRESPONDENCE_TARGETS`] target
/// vertices, or a pair with no target vertex.
pub fn check_limits(corr: &[Correspondence]) -> crate::error::Result<()> {
    let bad = |m: String| Err(crate::error::Error::InvalidInput(m));
    if corr.len() > MAX_CORRESPONDENCES {
        return bad(format!(
            "{} correspondences: at most {MAX_CORRESPONDENCES} pairs are supported",
            corr.len()
        ));
    }
    let targets: usize = corr.iter().map(|c| c.target_vertices.len()).sum();
    if targets > MAX_CORRESPONDENCE_TARGETS {
        return bad(format!(
            "correspondences name {targets} target vertices: at most {MAX_CORRESPONDENCE_TARGETS} in all are supported"
        ));
    }
    Ok(())
}

/// The correspondences file: `{"correspondences": [...]}`.
#[derive(Clone, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct CorrespondenceFile {
    /// The pairs.
    pub correspondences: Vec<Correspondence>,
}

impl CorrespondenceFile {
    /// Read and parse a correspondences JSON file: a regular file of at most
    /// [`crate::mesh::io::MAX_TEXT_FILE_BYTES`], with at most [`MAX_CORRESPONDENCES`] pairs and
    /// [`MAX_CORRESPONDENCE_TARGETS`] target vertices.
    pub fn load(path: &std::path::Path) -> crate::error::Result<Self> {
        let text = crate::mesh::io::read_text_file(path, "the correspondences file")?;
        let file: Self = serde_json::from_str(&text).map_err(|e| {
            crate::error::Error::format(path, format!("invalid correspondences JSON: {e}"))
        })?;
        check_limits(&file.correspondences)
            .map_err(|e| crate::error::Error::format(path, e.to_string()))?;
        Ok(file)
    }
    /// Write as pretty JSON (atomically).
    pub fn save(&self, path: &std::path::Path) -> crate::error::Result<()> {
        let text = serde_json::to_string_pretty(self).expect("serialisable");
        crate::mesh::io::write_atomic(path, text.as_bytes())
    }
}
