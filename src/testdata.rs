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

/// A closed unit UV sphere: `rings - 1` rings of `segs` vertices plus two poles, counter-clockwise
/// seen from outside (`2 segs (rings - 1)` faces): a small known closed surface for tests.
pub fn uv_sphere(rings: usize, segs: usize) -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
    let mut p = vec![[0.0, 0.0, 1.0]];
    for i in 1..rings {
        let th = std::f32::consts::PI * i as f32 / rings as f32;
        for j in 0..segs {
            let ph = 2.0 * std::f32::consts::PI * j as f32 / segs as f32;
            p.push([th.sin() * ph.cos(), th.sin() * ph.sin(), th.cos()]);
        }
    }
    p.push([0.0, 0.0, -1.0]);
    let s = segs as u32;
    let idx = |i: usize, j: u32| 1 + (i as u32 - 1) * s + (j % s);
    let mut f = Vec::new();
    for j in 0..s {
        f.push([0, idx(1, j), idx(1, j + 1)]);
    }
    for i in 1..rings - 1 {
        for j in 0..s {
            f.push([idx(i, j), idx(i + 1, j), idx(i + 1, j + 1)]);
            f.push([idx(i, j), idx(i + 1, j + 1), idx(i, j + 1)]);
        }
    }
    let last = p.len() as u32 - 1;
    for j in 0..s {
        f.push([last, idx(rings - 1, j + 1), idx(rings - 1, j)]);
    }
    (p, f)
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
