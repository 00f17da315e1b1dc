//! Working-resolution refinement with provenance: longest-edge-first bisection (Rivara 1984)
//! until the mesh has the requested vertex count. Every working face remembers the input face it
//! lies in and the barycentric coordinates of its corners in that face, so per-vertex signals can
//! be sampled from the input's texture or colours and baked textures can find their surface point
//! exactly.

use glam::Vec3;
use std::collections::{BinaryHeap, HashMap};

/// A refined mesh and where every piece of it came from.
pub(crate) struct Refined {
    /// Vertex positions (the first `n` are the input's).
    pub positions: Vec<[f32; 3]>,
    /// Triangles.
    pub faces: Vec<[u32; 3]>,
    /// Input face containing each working face.
    pub face_src: Vec<u32>,
    /// Barycentric coordinates of each working face's corners in its input face.
    pub face_bary: Vec<[[f32; 3]; 3]>,
    /// Input face and barycentric coordinates of every vertex.
    pub vert_src: Vec<(u32, [f32; 3])>,
}

#[inline]
fn key(a: u32, b: u32) -> u64 {
    let (a, b) = (a.min(b), a.max(b));
    ((a as u64) << 32) | b as u64
}

/// Bisect the longest edge (in both its faces) until there are at least `target` vertices.
pub(crate) fn refine(positions: &[[f32; 3]], faces: &[[u32; 3]], target: usize) -> Refined {
    let n = positions.len();
    let mut pos: Vec<[f32; 3]> = positions.to_vec();
    let mut fcs: Vec<[u32; 3]> = faces.to_vec();
    let mut face_src: Vec<u32> = (0..faces.len() as u32).collect();
    let unit = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    let mut face_bary: Vec<[[f32; 3]; 3]> = vec![unit; faces.len()];
    let mut vert_src: Vec<(u32, [f32; 3])> = vec![(u32::MAX, [0.0; 3]); n];
    for (fi, f) in faces.iter().enumerate() {
        for k in 0..3 {
            if vert_src[f[k] as usize].0 == u32::MAX {
                vert_src[f[k] as usize] = (fi as u32, unit[k]);
            }
        }
    }
    for v in vert_src.iter_mut() {
        if v.0 == u32::MAX {
            v.0 = 0;
        }
    }
    if target <= n {
        return Refined {
            positions: pos,
            faces: fcs,
            face_src,
            face_bary,
            vert_src,
        };
    }
    let mut emap: HashMap<u64, Vec<u32>> = HashMap::with_capacity(faces.len() * 2);
    for (fi, f) in faces.iter().enumerate() {
        for k in 0..3 {
            emap.entry(key(f[k], f[(k + 1) % 3]))
                .or_default()
                .push(fi as u32);
        }
    }
    let len = |p: &[[f32; 3]], a: u32, b: u32| {
        (Vec3::from(p[a as usize]) - Vec3::from(p[b as usize])).length()
    };
    let mut heap: BinaryHeap<(u32, u32, u32)> = emap
        .keys()
        .map(|&k| {
            let (a, b) = ((k >> 32) as u32, k as u32);
            (len(&pos, a, b).to_bits(), a, b)
        })
        .collect();
    while pos.len() < target {
        let Some((_, a, b)) = heap.pop() else { break };
        let Some(fs) = emap.remove(&key(a, b)) else {
            continue;
        };
        let m = pos.len() as u32;
        let pm = 0.5 * (Vec3::from(pos[a as usize]) + Vec3::from(pos[b as usize]));
        pos.push(pm.to_array());
        let mut first = true;
        for &fi in &fs {
            let f = fcs[fi as usize];
            let Some(i) = (0..3).find(|&i| {
                let (x, y) = (f[i], f[(i + 1) % 3]);
                (x == a && y == b) || (x == b && y == a)
            }) else {
                continue;
            };
            let (x, y, z) = (f[i], f[(i + 1) % 3], f[(i + 2) % 3]);
            let fb = face_bary[fi as usize];
            let (bx, by, bz) = (fb[i], fb[(i + 1) % 3], fb[(i + 2) % 3]);
            let bm = [0.0, 1.0, 2.0].map(|c: f32| {
                let c = c as usize;
                0.5 * (bx[c] + by[c])
            });
            if first {
                vert_src.push((face_src[fi as usize], bm));
                first = false;
            }
            let g = fcs.len() as u32;
            fcs[fi as usize] = [x, m, z];
            face_bary[fi as usize] = [bx, bm, bz];
            fcs.push([m, y, z]);
            face_bary.push([bm, by, bz]);
            face_src.push(face_src[fi as usize]);
            emap.entry(key(x, m)).or_default().push(fi);
            emap.entry(key(m, y)).or_default().push(g);
            emap.entry(key(m, z)).or_default().extend([fi, g]);
            if let Some(l) = emap.get_mut(&key(y, z)) {
                for e in l.iter_mut() {
                    if *e == fi {
                        *e = g;
                    }
                }
            }
            heap.push((len(&pos, m, z).to_bits(), m, z));
        }
        if first {
            // No face held the edge (cannot happen for a consistent map); drop the vertex.
            pos.pop();
            continue;
        }
        heap.push((len(&pos, a, m).to_bits(), a, m));
        heap.push((len(&pos, m, b).to_bits(), m, b));
    }
    Refined {
        positions: pos,
        faces: fcs,
        face_src,
        face_bary,
        vert_src,
    }
}
