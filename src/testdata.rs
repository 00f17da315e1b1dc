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

/// A speckled green-blue exemplar `size` pixels square with a transparent magenta disc
/// (a quarter of the side in radius) in the middle, and its alpha: what tests of transparent
/// exemplar pixels synthesize from.
pub fn exemplar_with_hole(size: u32) -> (image::RgbImage, image::GrayImage) {
    let c = size as f32 / 2.0;
    let mut rgb = image::RgbImage::new(size, size);
    let mut alpha = image::GrayImage::new(size, size);
    for y in 0..size {
        for x in 0..size {
            let inside =
                ((x as f32 - c).powi(2) + (y as f32 - c).powi(2)).sqrt() < size as f32 / 4.0;
            let h = (x.wrapping_mul(73_856_093) ^ y.wrapping_mul(19_349_663)) % 97;
            let p = if inside {
                [255, 0, 255]
            } else {
                [30 + h as u8, 140 + (h as u8 / 2), 60 + (97 - h as u8)]
            };
            rgb.put_pixel(x, y, image::Rgb(p));
            alpha.put_pixel(x, y, image::Luma([if inside { 0 } else { 255 }]));
        }
    }
    (rgb, alpha)
}
