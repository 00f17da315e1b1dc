//! Generated inputs for feature-aligned texturing: meshes with known creases (straight and
//! circular) and an exemplar with one dark line, so the system's demo and benchmark need no data.

use crate::mesh::TriMesh;

/// A unit cube subdivided `n` times per edge (welded): twelve straight creases, eight corners.
pub fn crease_cube(n: usize) -> TriMesh {
    let n = n.max(1);
    let mut index = std::collections::HashMap::new();
    let mut positions: Vec<[f32; 3]> = Vec::new();
    let mut faces = Vec::new();
    // (axis of the normal, sign)
    for (axis, sign) in [
        (0, 1.0f32),
        (0, -1.0),
        (1, 1.0),
        (1, -1.0),
        (2, 1.0),
        (2, -1.0),
    ] {
        let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
        let mut id = |i: usize, j: usize| -> u32 {
            let mut p = [0.0f32; 3];
            p[axis] = 0.5 * sign;
            p[u] = i as f32 / n as f32 - 0.5;
            p[v] = j as f32 / n as f32 - 0.5;
            let key = p.map(|c| ((c + 0.5) * n as f32).round() as i64);
            *index.entry(key).or_insert_with(|| {
                positions.push(p);
                (positions.len() - 1) as u32
            })
        };
        for j in 0..n {
            for i in 0..n {
                let (a, b, c, d) = (id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
                if sign > 0.0 {
                    faces.push([a, b, c]);
                    faces.push([a, c, d]);
                } else {
                    faces.push([a, c, b]);
                    faces.push([a, d, c]);
                }
            }
        }
    }
    TriMesh::new(positions, faces)
}

/// A 64-pixel line exemplar: light grain with a dark 4-pixel groove across its middle.
pub fn line_exemplar() -> image::RgbImage {
    image::RgbImage::from_fn(64, 64, |x, y| {
        let grain = ((x.wrapping_mul(7919) ^ y.wrapping_mul(104_729)) % 17) as u8;
        match y {
            30..=33 => image::Rgb([50 + grain, 34, 26]),
            10 | 52 => image::Rgb([150 + grain, 120, 90]),
            _ => image::Rgb([205 + grain, 190, 160]),
        }
    })
}

/// A block with straight and circular crests: [`crease_cube`] (`n` per edge, at x = -0.8) beside a
/// closed cylinder of radius 0.5 and height 1 (axis y, at x = +0.8) with matching density.
pub fn crest_block(n: usize) -> TriMesh {
    let n = n.max(2);
    let mut mesh = crease_cube(n);
    for p in &mut mesh.positions {
        p[0] -= 0.8;
    }
    let mut positions = mesh.positions.clone();
    let mut faces = mesh.faces.clone();
    let nu = (std::f32::consts::PI * n as f32).round().max(8.0) as usize;
    let nr = (n / 2).max(2);
    let base = positions.len() as u32;
    let ring = |y: f32, r: f32, out: &mut Vec<[f32; 3]>| {
        for i in 0..nu {
            let t = std::f32::consts::TAU * i as f32 / nu as f32;
            out.push([0.8 + r * t.cos(), y, r * t.sin()]);
        }
    };
    for j in 0..=n {
        ring(j as f32 / n as f32 - 0.5, 0.5, &mut positions);
    }
    let at = |j: usize, i: usize| base + (j * nu + i % nu) as u32;
    for j in 0..n {
        for i in 0..nu {
            faces.push([at(j, i), at(j + 1, i), at(j, i + 1)]);
            faces.push([at(j, i + 1), at(j + 1, i), at(j + 1, i + 1)]);
        }
    }
    // caps: concentric rings down to a centre vertex
    for (rim, y) in [(0usize, -0.5f32), (n, 0.5)] {
        let mut prev: Vec<u32> = (0..nu).map(|i| at(rim, i)).collect();
        for r in (1..nr).rev() {
            let start = positions.len() as u32;
            ring(y, 0.5 * r as f32 / nr as f32, &mut positions);
            let cur: Vec<u32> = (0..nu as u32).map(|i| start + i).collect();
            for i in 0..nu {
                let (a, b, c, d) = (prev[i], prev[(i + 1) % nu], cur[i], cur[(i + 1) % nu]);
                if y > 0.0 {
                    faces.push([a, c, b]);
                    faces.push([b, c, d]);
                } else {
                    faces.push([a, b, c]);
                    faces.push([b, d, c]);
                }
            }
            prev = cur;
        }
        positions.push([0.8, y, 0.0]);
        let centre = positions.len() as u32 - 1;
        for i in 0..nu {
            let (a, b) = (prev[i], prev[(i + 1) % nu]);
            faces.push(if y > 0.0 {
                [a, centre, b]
            } else {
                [a, b, centre]
            });
        }
    }
    TriMesh::new(positions, faces)
}
