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
    if n == 0 {
        return (Vec::new(), Vec::new());
    }
    grid_cells(n - 1, n - 1, 1.0)
}

/// A flat grid of `nx × ny` square cells of side `h` in the z = 0 plane (vertex `j (nx + 1) + i`
/// at `(i h, j h)`), each cell split into two counter-clockwise triangles.
pub fn grid_cells(nx: usize, ny: usize, h: f32) -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
    let mut positions = Vec::with_capacity((nx + 1) * (ny + 1));
    for j in 0..=ny {
        for i in 0..=nx {
            positions.push([i as f32 * h, j as f32 * h, 0.0]);
        }
    }
    (positions, grid_faces(nx, ny))
}

/// The faces of a grid of `nx × ny` cells whose vertex `(i, j)` is `j (nx + 1) + i`, each cell
/// split into two counter-clockwise triangles (normal +z when `i` runs along x and `j` along y).
pub fn grid_faces(nx: usize, ny: usize) -> Vec<[u32; 3]> {
    let id = |i: usize, j: usize| (j * (nx + 1) + i) as u32;
    let mut faces = Vec::with_capacity(2 * nx * ny);
    for j in 0..ny {
        for i in 0..nx {
            faces.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
            faces.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
        }
    }
    faces
}

/// A closed axis-aligned box `[0, a] × [0, b] × [0, c]` (corner `i` at `(i & 1, i & 2, i & 4)`
/// scaled), wound outwards, 12 triangles.
pub fn cuboid(a: f32, b: f32, c: f32) -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
    let pos: Vec<[f32; 3]> = (0..8)
        .map(|i| {
            [
                if i & 1 != 0 { a } else { 0.0 },
                if i & 2 != 0 { b } else { 0.0 },
                if i & 4 != 0 { c } else { 0.0 },
            ]
        })
        .collect();
    let quads = [
        [0, 2, 3, 1],
        [4, 5, 7, 6],
        [0, 1, 5, 4],
        [2, 6, 7, 3],
        [0, 4, 6, 2],
        [1, 3, 7, 5],
    ];
    let faces = quads
        .iter()
        .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
        .collect();
    (pos, faces)
}

/// An open cylinder of radius `r` and length `len` along z, centred at the origin, `nc` quads
/// around and `nl` along (normals outwards): a limb.
pub fn cylinder(r: f32, len: f32, nc: usize, nl: usize) -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
    let (nc, nl) = (nc.max(3), nl.max(1));
    let mut pos = Vec::with_capacity(nc * (nl + 1));
    for j in 0..=nl {
        for i in 0..nc {
            let a = std::f32::consts::TAU * i as f32 / nc as f32;
            pos.push([r * a.cos(), r * a.sin(), len * (j as f32 / nl as f32 - 0.5)]);
        }
    }
    let v = |i: usize, j: usize| (j * nc + i % nc) as u32;
    let mut faces = Vec::with_capacity(2 * nc * nl);
    for j in 0..nl {
        for i in 0..nc {
            faces.push([v(i, j), v(i + 1, j), v(i + 1, j + 1)]);
            faces.push([v(i, j), v(i + 1, j + 1), v(i, j + 1)]);
        }
    }
    (pos, faces)
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

/// [`uv_sphere`] with its poles on the y axis instead: vertex `v` at `(x, z, y)` of
/// `uv_sphere`'s, each face's winding reversed so that it stays counter-clockwise from outside.
pub fn uv_sphere_y_up(rings: usize, segs: usize) -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
    let (p, f) = uv_sphere(rings, segs);
    (
        p.into_iter().map(|[x, y, z]| [x, z, y]).collect(),
        f.into_iter().map(|[a, b, c]| [a, c, b]).collect(),
    )
}

/// The regular icosahedron's 12 corners `(±1, ±t, 0)` and cyclic permutations (`t` the golden
/// ratio, not normalised) and its 20 counter-clockwise faces.
fn icosahedron() -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
    let t = (1.0 + 5f32.sqrt()) / 2.0;
    let p = vec![
        [-1.0, t, 0.0],
        [1.0, t, 0.0],
        [-1.0, -t, 0.0],
        [1.0, -t, 0.0],
        [0.0, -1.0, t],
        [0.0, 1.0, t],
        [0.0, -1.0, -t],
        [0.0, 1.0, -t],
        [t, 0.0, -1.0],
        [t, 0.0, 1.0],
        [-t, 0.0, -1.0],
        [-t, 0.0, 1.0],
    ];
    let f = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    (p, f)
}

/// `k` 1-to-4 splits of the triangles `(p, f)`: each edge's midpoint `mid(a, b)` is added once
/// (in the order the edges are first met), each face `abc` becomes `[a, ab, ca]`, `[b, bc, ab]`,
/// `[c, ca, bc]`, `[ab, bc, ca]`.
fn subdivide(
    mut p: Vec<[f32; 3]>,
    mut f: Vec<[u32; 3]>,
    k: usize,
    mid: impl Fn(glam::Vec3, glam::Vec3) -> glam::Vec3,
) -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
    use glam::Vec3;
    for _ in 0..k {
        let mut seen = std::collections::HashMap::new();
        let mut nf = Vec::with_capacity(4 * f.len());
        let mut m = |a: u32, b: u32, p: &mut Vec<[f32; 3]>| {
            *seen.entry((a.min(b), a.max(b))).or_insert_with(|| {
                let v = mid(Vec3::from(p[a as usize]), Vec3::from(p[b as usize]));
                p.push(v.to_array());
                p.len() as u32 - 1
            })
        };
        for [a, b, c] in f {
            let ab = m(a, b, &mut p);
            let bc = m(b, c, &mut p);
            let ca = m(c, a, &mut p);
            nf.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        f = nf;
    }
    (p, f)
}

/// A closed unit icosphere: the icosahedron split `k` times, every new vertex projected to the
/// sphere as it is made (`10·4^k + 2` vertices, `20·4^k` counter-clockwise faces).
pub fn icosphere(k: usize) -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
    let (p, f) = icosahedron();
    let p = p
        .into_iter()
        .map(|v| glam::Vec3::from(v).normalize().to_array())
        .collect();
    subdivide(p, f, k, |a, b| (a + b).normalize())
}

/// The icosahedron split `k` times into flat triangles, then every vertex projected to the
/// unit sphere: the vertices and faces of [`icosphere`] in the same order, at other positions
/// (the triangles less even in size).
pub fn flat_split_icosphere(k: usize) -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
    let (p, f) = icosahedron();
    let (p, f) = subdivide(p, f, k, |a, b| 0.5 * (a + b));
    let p = p
        .into_iter()
        .map(|v| glam::Vec3::from(v).normalize().to_array())
        .collect();
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
