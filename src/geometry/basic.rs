//! Per-element basics: vertex welding, normals, areas, edge lengths, Taubin smoothing.

use std::collections::HashMap;

use glam::{DVec3, Vec3};
use rayon::prelude::*;

use crate::mesh::{Csr, TriMesh};

#[inline]
pub(crate) fn v3(p: [f32; 3]) -> Vec3 {
    Vec3::from(p)
}

#[inline]
pub(crate) fn d3(p: [f32; 3]) -> DVec3 {
    Vec3::from(p).as_dvec3()
}

/// Merge vertices whose positions are bit-identical (UV-seam and glTF split duplicates; `-0.0`
/// equals `0.0`), keeping first-occurrence order.
///
/// Returns the welded mesh and `map[i]` = welded index of input vertex `i`. Faces keep their
/// per-corner UVs; colours, normals and `file_index` come from each welded vertex's first
/// occurrence; the texture is carried; faces that become degenerate (a repeated vertex) are
/// dropped together with their corner UVs.
pub fn weld(mesh: &TriMesh) -> (TriMesh, Vec<u32>) {
    let n = mesh.positions.len();
    let mut lookup: HashMap<[u32; 3], u32> = HashMap::with_capacity(n);
    let mut map = Vec::with_capacity(n);
    let mut first = Vec::with_capacity(n);
    for (i, p) in mesh.positions.iter().enumerate() {
        // adding 0.0 turns -0.0 into +0.0 so both zeros weld
        let key = p.map(|x| (x + 0.0).to_bits());
        let next = first.len() as u32;
        let w = *lookup.entry(key).or_insert(next);
        if w == next {
            first.push(i as u32);
        }
        map.push(w);
    }
    let pick = |src: &[[f32; 3]]| first.iter().map(|&i| src[i as usize]).collect::<Vec<_>>();
    let positions = pick(&mesh.positions);
    let mut faces = Vec::with_capacity(mesh.faces.len());
    let mut uvs = mesh
        .uvs
        .as_ref()
        .map(|_| Vec::with_capacity(mesh.faces.len() * 3));
    for (f, face) in mesh.faces.iter().enumerate() {
        if face.iter().any(|&v| v as usize >= n) {
            continue;
        }
        let w = face.map(|v| map[v as usize]);
        if w[0] == w[1] || w[1] == w[2] || w[0] == w[2] {
            continue;
        }
        faces.push(w);
        if let (Some(out), Some(src)) = (uvs.as_mut(), mesh.uvs.as_ref()) {
            out.extend_from_slice(&src[3 * f..3 * f + 3]);
        }
    }
    let file_index = first
        .iter()
        .map(|&i| mesh.file_index.get(i as usize).copied().unwrap_or(i))
        .collect();
    let welded = TriMesh {
        positions,
        faces,
        normals: mesh.normals.as_deref().map(pick),
        uvs,
        colors: mesh.colors.as_deref().map(pick),
        texture: mesh.texture.clone(),
        file_index,
        file_vertex_count: mesh.file_vertex_count,
        path: mesh.path.clone(),
    };
    (welded, map)
}

/// Unit face normals `n_f = (b - a) x (c - a) / |(b - a) x (c - a)|` (zero for degenerate faces).
/// The power of two nearest the size (bounding-box diagonal) of the finite `positions`, as its
/// exponent: a computation on the positions times `2^-e` runs on a mesh of about unit size, the
/// same steps whatever the units (scaling by a power of two is exact in floating point). 0 for
/// no or one distinct point.
pub fn unit_exponent(positions: &[[f32; 3]]) -> i32 {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for p in positions.iter().filter(|p| p.iter().all(|x| x.is_finite())) {
        for a in 0..3 {
            lo[a] = lo[a].min(p[a] as f64);
            hi[a] = hi[a].max(p[a] as f64);
        }
    }
    let diag = (0..3).map(|a| (hi[a] - lo[a]).powi(2)).sum::<f64>().sqrt();
    if diag.is_finite() && diag > 0.0 {
        // within f32's exponent range, so that 2^-e is a normal number
        (diag.log2().round() as i32).clamp(-120, 120)
    } else {
        0
    }
}

/// `positions` times `2^e` (exact in floating point within f32's range: the same computation
/// on the result takes the same steps as on the input, in units `2^e` times smaller).
pub fn scaled_by_power_of_two(positions: &[[f32; 3]], e: i32) -> Vec<[f32; 3]> {
    let f = 2f32.powi(e);
    positions.iter().map(|p| p.map(|x| x * f)).collect()
}

pub fn face_normals(positions: &[[f32; 3]], faces: &[[u32; 3]]) -> Vec<[f32; 3]> {
    faces
        .par_iter()
        .map(|f| {
            let [a, b, c] = f.map(|i| d3(positions[i as usize]));
            let n = (b - a).cross(c - a);
            let l = n.length();
            if l > 0.0 && l.is_finite() {
                (n / l).as_vec3().to_array()
            } else {
                [0.0; 3]
            }
        })
        .collect()
}

/// Face areas `A_f = |(b - a) x (c - a)| / 2`.
pub fn face_areas(positions: &[[f32; 3]], faces: &[[u32; 3]]) -> Vec<f64> {
    faces
        .par_iter()
        .map(|f| {
            let [a, b, c] = f.map(|i| d3(positions[i as usize]));
            0.5 * (b - a).cross(c - a).length()
        })
        .collect()
}

/// Area-weighted vertex normals: `n_v = normalize(sum_{f ∋ v} (b - a) x (c - a))` (the
/// unnormalised cross product is twice the area times the face normal). Vertices in no
/// non-degenerate face get `[0, 0, 1]`. The one implementation is the mesh layer's, which the
/// writers use for files without normals.
pub fn vertex_normals(positions: &[[f32; 3]], faces: &[[u32; 3]]) -> Vec<[f32; 3]> {
    crate::mesh::vertex_normals(positions, faces)
}

/// Mean length of the mesh's undirected edges (each interior edge counted once; 0 without faces).
pub fn mean_edge_length(positions: &[[f32; 3]], faces: &[[u32; 3]]) -> f32 {
    let adj = crate::mesh::vertex_adjacency(positions.len(), faces);
    let (mut sum, mut count) = (0.0f64, 0usize);
    for i in 0..adj.len() {
        for &j in adj.row(i).iter().filter(|&&j| j as usize > i) {
            sum += d3(positions[i]).distance(d3(positions[j as usize]));
            count += 1;
        }
    }
    if count == 0 {
        0.0
    } else {
        (sum / count as f64) as f32
    }
}

/// Taubin λ|μ smoothing (Taubin 1995, "A signal processing approach to fair surface design"):
/// alternately `p ← p + λ Δp` and `p ← p + μ Δp` with the umbrella operator
/// `Δp_i = mean_{j ∈ N(i)} p_j - p_i`, `iterations` times (λ > 0 > μ, |μ| slightly above λ,
/// e.g. λ = 0.5, μ = -0.53). Vertices without neighbours stay put.
pub fn taubin_smooth(
    positions: &[[f32; 3]],
    adjacency: &Csr,
    iterations: usize,
    lambda: f32,
    mu: f32,
) -> Vec<[f32; 3]> {
    let mut cur = positions.to_vec();
    let mut next = positions.to_vec();
    let n = positions.len().min(adjacency.len());
    for _ in 0..iterations {
        for factor in [lambda, mu] {
            next[..n].par_iter_mut().enumerate().for_each(|(i, out)| {
                let nb = adjacency.row(i);
                let p = v3(cur[i]);
                if nb.is_empty() {
                    *out = cur[i];
                    return;
                }
                let mut s = Vec3::ZERO;
                for &j in nb {
                    s += v3(cur[j as usize]);
                }
                let lap = s / nb.len() as f32 - p;
                *out = (p + factor * lap).to_array();
            });
            std::mem::swap(&mut cur, &mut next);
        }
    }
    cur
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn weld_merges_duplicates_and_drops_collapsed_faces() {
        let positions = vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.0, 1.0, -0.0],
        ];
        let faces = vec![[0, 1, 2], [3, 4, 2], [1, 3, 4]];
        let mut m = TriMesh::new(positions, faces);
        m.uvs = Some((0..9).map(|i| [i as f32, 0.0]).collect());
        let (w, map) = weld(&m);
        assert_eq!(map, vec![0, 1, 2, 1, 3]);
        assert_eq!(w.positions.len(), 4);
        assert_eq!(w.faces, vec![[0, 1, 2], [1, 3, 2]]);
        let uvs = w.uvs.unwrap();
        assert_eq!(uvs.len(), 6);
        assert_eq!(uvs[3], [3.0, 0.0]);
    }

    #[test]
    fn taubin_keeps_flat_grid_flat_and_shrinks_noise() {
        // 5x5 grid with a bump in the middle
        let mut pos = Vec::new();
        for y in 0..5 {
            for x in 0..5 {
                pos.push([x as f32, y as f32, if x == 2 && y == 2 { 1.0 } else { 0.0 }]);
            }
        }
        let mut faces = Vec::new();
        for y in 0..4u32 {
            for x in 0..4u32 {
                let i = y * 5 + x;
                faces.push([i, i + 1, i + 6]);
                faces.push([i, i + 6, i + 5]);
            }
        }
        let adj = crate::mesh::vertex_adjacency(pos.len(), &faces);
        let s = taubin_smooth(&pos, &adj, 10, 0.5, -0.53);
        assert!(s[12][2] < 0.5, "bump not smoothed: {}", s[12][2]);
        assert!(mean_edge_length(&pos, &faces) > 1.0);
    }
}
