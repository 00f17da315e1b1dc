//! Where the shared test data lives (meshes and textures read by tests, benches and examples).

use std::path::PathBuf;

/// The shared data directory: `$MESHMATCH_DATA`, else `<crate>/../shared/data`, else
/// `/work/shared/data`.
pub fn data_dir() -> PathBuf {
    if let Some(d) = std::env::var_os("MESHMATCH_DATA") {
        return PathBuf::from(d);
    }
    let beside = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/data");
    if beside.is_dir() {
        return beside;
    }
    PathBuf::from("/work/shared/data")
}

/// Path of a file inside the shared data directory, e.g. `data_path("spot/spot.obj")`.
pub fn data_path(rel: &str) -> PathBuf {
    data_dir().join(rel)
}
