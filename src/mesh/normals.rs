//! Vertex and corner normals: area-weighted vertex normals, and corner normals split at sharp
//! edges by angle (the "smooth by angle" of DCC tools). The renderer draws with the corner
//! normals, and every exported mesh without normals of its own carries them.

use glam::DVec3;
use rayon::prelude::*;

/// Faces meeting at a larger dihedral angle than this (degrees) have a hard edge between them.
pub const SHARP_ANGLE_DEG: f32 = 30.0;

fn d3(p: [f32; 3]) -> DVec3 {
    DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64)
}

/// Area-weighted vertex normals: `n_v = normalize(sum_{f ∋ v} (b - a) x (c - a))` (the
/// unnormalised cross product is twice the area times the face normal). Vertices in no
/// non-degenerate face get `[0, 0, 1]`; faces with an out-of-range index are skipped.
pub fn vertex_normals(positions: &[[f32; 3]], faces: &[[u32; 3]]) -> Vec<[f32; 3]> {
    let n = positions.len();
    let mut acc = vec![DVec3::ZERO; n];
    for f in faces {
        if f.iter().any(|&i| i as usize >= n) {
            continue;
        }
        let [a, b, c] = f.map(|i| d3(positions[i as usize]));
        let nrm = (b - a).cross(c - a);
        if !nrm.is_finite() {
            continue;
        }
        for &v in f {
            acc[v as usize] += nrm;
        }
    }
    acc.par_iter()
        .map(|n| {
            let l = n.length();
            if l > 0.0 {
                (*n / l).as_vec3().to_array()
            } else {
                [0.0, 0.0, 1.0]
            }
        })
        .collect()
}

/// Corner normals split at sharp edges: `out[3 * f + k]` is the area-weighted mean of the face
/// normals around vertex `faces[f][k]` that lie within `sharp_angle_deg` of face `f`'s own
/// normal (always including face `f`), so a cube gets flat faces and a smooth surface smooth
/// vertex normals. Corners of one vertex whose normals agree to 16 bits per component share one
/// value bit for bit, so writers can split vertices by exact equality. Unit length, or zero for
/// corners of degenerate faces and of faces with an out-of-range index.
pub fn corner_normals(
    positions: &[[f32; 3]],
    faces: &[[u32; 3]],
    sharp_angle_deg: f32,
) -> Vec<[f32; 3]> {
    let n = positions.len();
    let valid = |f: &[u32; 3]| f.iter().all(|&i| (i as usize) < n);
    let p = |i: u32| glam::Vec3::from(positions[i as usize]);
    // Area-weighted face normals (length = 2 x area) and their unit directions.
    let fnorm: Vec<glam::Vec3> = faces
        .iter()
        .map(|f| {
            if !valid(f) {
                return glam::Vec3::ZERO;
            }
            let c = (p(f[1]) - p(f[0])).cross(p(f[2]) - p(f[0]));
            if c.is_finite() { c } else { glam::Vec3::ZERO }
        })
        .collect();
    let fdir: Vec<glam::Vec3> = fnorm.iter().map(|c| c.normalize_or_zero()).collect();
    let mut pairs: Vec<(u32, u32)> = faces
        .iter()
        .enumerate()
        .filter(|(_, f)| valid(f))
        .flat_map(|(k, f)| f.map(|v| (v, k as u32)))
        .collect();
    let vf = super::Csr::from_pairs(n, &mut pairs);
    let cos_sharp = sharp_angle_deg.to_radians().cos();
    let quant = |n: glam::Vec3| -> u64 {
        let q = |x: f32| (((x.clamp(-1.0, 1.0) + 1.0) * 32767.5) as u64) & 0xffff;
        q(n.x) | (q(n.y) << 16) | (q(n.z) << 32)
    };
    let mut out = vec![[0.0f32; 3]; 3 * faces.len()];
    // Per vertex: its corners' normals, the first of each quantised value kept for all.
    let rows: Vec<Vec<(usize, [f32; 3])>> = (0..n)
        .into_par_iter()
        .map(|v| {
            let row = vf.row(v);
            let mut seen: Vec<(u64, [f32; 3])> = Vec::new();
            let mut corners = Vec::new();
            for &k in row {
                let k = k as usize;
                let own = fdir[k];
                let mut acc = glam::Vec3::ZERO;
                for &g in row {
                    let g = g as usize;
                    if g == k || own == glam::Vec3::ZERO || fdir[g].dot(own) >= cos_sharp {
                        acc += fnorm[g];
                    }
                }
                let nrm = acc.normalize_or_zero();
                let q = quant(nrm);
                let value = match seen.iter().find(|(s, _)| *s == q) {
                    Some(&(_, val)) => val,
                    None => {
                        seen.push((q, nrm.to_array()));
                        nrm.to_array()
                    }
                };
                for (c, &fv) in faces[k].iter().enumerate() {
                    if fv as usize == v {
                        corners.push((3 * k + c, value));
                    }
                }
            }
            corners
        })
        .collect();
    for row in rows {
        for (corner, value) in row {
            out[corner] = value;
        }
    }
    out
}
