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

/// A flat `n × n`-vertex grid of unit spacing in the z = 0 plane (vertex `j n + i` at `(i, j)`),
/// each square split into two counter-clockwise triangles: a small known surface for tests.
pub fn grid(n: usize) -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
    let mut positions = Vec::with_capacity(n * n);
    for j in 0..n {
        for i in 0..n {
            positions.push([i as f32, j as f32, 0.0]);
        }
    }
    let mut faces = Vec::with_capacity(2 * n.saturating_sub(1).pow(2));
    for j in 0..n.saturating_sub(1) {
        for i in 0..n - 1 {
            let a = (j * n + i) as u32;
            faces.push([a, a + 1, a + n as u32 + 1]);
            faces.push([a, a + n as u32 + 1, a + n as u32]);
        }
    }
    (positions, faces)
}

/// Path of a file inside the shared data directory, e.g. `data_path("spot/spot.obj")`.
pub fn data_path(rel: &str) -> PathBuf {
    data_dir().join(rel)
}
