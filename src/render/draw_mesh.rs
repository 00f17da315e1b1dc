//! The vertices a mesh is drawn with: corners split where the surface is sharp (normals split by
//! angle, as DCC tools' "smooth by angle" does) or where the UV layout has a seam, and shared
//! everywhere else.
//!
//! Each corner's normal is the area-weighted mean of the face normals around its vertex that lie
//! within [`SHARP_ANGLE_DEG`] of its own face's normal, so a cube draws with flat faces and a
//! smooth surface draws smooth. Corners with the same vertex, normal and UV become one drawn
//! vertex; a smooth mesh without UVs draws with exactly its own vertices.

use crate::mesh::TriMesh;

/// Faces meeting at a larger dihedral angle than this (degrees) are drawn with a hard edge.
pub const SHARP_ANGLE_DEG: f32 = crate::mesh::SHARP_ANGLE_DEG;

/// A mesh as the GPU draws it.
#[derive(Clone, Debug, Default)]
pub struct DrawMesh {
    /// Drawn vertex positions.
    pub positions: Vec<[f32; 3]>,
    /// Drawn vertex normals (unit, or zero at degenerate spots).
    pub normals: Vec<[f32; 3]>,
    /// Texture coordinates in image convention (row 0 at the top: `v = 1 - V`); zero without UVs.
    pub uvs: Vec<[f32; 2]>,
    /// Mesh vertex of every drawn vertex (per-vertex colours are drawn through it).
    pub vertex: Vec<u32>,
    /// Triangles over drawn vertices (faces with out-of-range indices are left out).
    pub triangles: Vec<u32>,
    /// A drawn vertex of every mesh vertex (`u32::MAX` if no face uses it): for edges.
    pub first: Vec<u32>,
}

/// Split `mesh` into drawn vertices, with its per-corner UVs when `with_uvs` and it has them.
pub fn draw_mesh(mesh: &TriMesh, with_uvs: bool) -> DrawMesh {
    let n = mesh.positions.len();
    let nv = n as u32;
    let faces: Vec<(usize, [u32; 3])> = mesh
        .faces
        .iter()
        .copied()
        .enumerate()
        .filter(|(_, f)| f.iter().all(|&i| i < nv))
        .collect();
    let uvs = mesh
        .uvs
        .as_ref()
        .filter(|u| with_uvs && u.len() == 3 * mesh.faces.len());
    // Corner normals split at sharp edges (the mesh layer's, as every exported file carries).
    let cn = crate::mesh::corner_normals(&mesh.positions, &mesh.faces, SHARP_ANGLE_DEG);
    // Vertex -> faces (CSR over the kept faces).
    let mut pairs: Vec<(u32, u32)> = faces
        .iter()
        .enumerate()
        .flat_map(|(k, (_, f))| f.map(|v| (v, k as u32)))
        .collect();
    let vf = crate::mesh::Csr::from_pairs(n, &mut pairs);
    // Corner keys: (vertex, uv bits, quantised normal), then one drawn vertex per distinct key.
    let quant = |n: glam::Vec3| -> u64 {
        let q = |x: f32| (((x.clamp(-1.0, 1.0) + 1.0) * 32767.5) as u64) & 0xffff;
        q(n.x) | (q(n.y) << 16) | (q(n.z) << 32)
    };
    let mut out = DrawMesh {
        first: vec![u32::MAX; n],
        triangles: vec![0; 3 * faces.len()],
        ..Default::default()
    };
    // Corners are merged per vertex: a vertex's corners (its faces' CSR row, a handful) sorted by
    // (uv bits, quantised normal, corner) and deduplicated, vertices in ascending order; drawn
    // vertices come out ordered by (vertex, uv, normal), as a sort of every corner would give,
    // without sorting three entries per face at once.
    let mut group: Vec<(u64, u64, u32, glam::Vec3)> = Vec::new();
    for v in 0..nv {
        group.clear();
        for &k in vf.row(v as usize) {
            let (f, face) = faces[k as usize];
            for (c, &fv) in face.iter().enumerate() {
                if fv != v {
                    continue;
                }
                let nrm = glam::Vec3::from(cn[3 * f + c]);
                let uv = uvs.map_or(0u64, |u| {
                    let t = u[3 * f + c];
                    (t[0].to_bits() as u64) | ((t[1].to_bits() as u64) << 32)
                });
                group.push((uv, quant(nrm), 3 * k + c as u32, nrm));
            }
        }
        group.sort_unstable_by_key(|&(uv, qn, corner, _)| (uv, qn, corner));
        let mut prev: Option<(u64, u64)> = None;
        for &(uv, qn, corner, nrm) in &group {
            if prev != Some((uv, qn)) {
                prev = Some((uv, qn));
                let (f, _) = faces[corner as usize / 3];
                out.positions.push(mesh.positions[v as usize]);
                out.normals.push(nrm.to_array());
                out.uvs.push(uvs.map_or([0.0; 2], |u| {
                    let t = u[3 * f + corner as usize % 3];
                    [t[0], 1.0 - t[1]]
                }));
                out.vertex.push(v);
                if out.first[v as usize] == u32::MAX {
                    out.first[v as usize] = out.positions.len() as u32 - 1;
                }
            }
            out.triangles[corner as usize] = out.positions.len() as u32 - 1;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cube() -> TriMesh {
        let p = (0..8)
            .map(|i| [(i & 1) as f32, ((i >> 1) & 1) as f32, ((i >> 2) & 1) as f32])
            .collect();
        TriMesh::new(
            p,
            vec![
                [0, 2, 1],
                [1, 2, 3],
                [4, 5, 6],
                [5, 7, 6],
                [0, 1, 4],
                [1, 5, 4],
                [2, 6, 3],
                [3, 6, 7],
                [0, 4, 2],
                [2, 4, 6],
                [1, 3, 5],
                [3, 7, 5],
            ],
        )
    }

    #[test]
    fn a_cube_draws_flat_faces() {
        let d = draw_mesh(&cube(), false);
        // Three faces meet at every corner at right angles: 24 drawn vertices.
        assert_eq!(d.positions.len(), 24);
        for (k, t) in d.triangles.chunks(3).enumerate() {
            let n0 = d.normals[t[0] as usize];
            for &c in t {
                assert_eq!(d.normals[c as usize], n0, "face {k} is not flat");
            }
            // Axis-aligned unit normal.
            let big = n0.iter().filter(|x| x.abs() > 0.999).count();
            assert_eq!(big, 1, "{n0:?}");
        }
    }

    #[test]
    fn a_smooth_surface_keeps_its_vertices_and_uv_seams_split() {
        // A gently curved 20x20 grid: no dihedral angle near 30 degrees.
        let k = 21u32;
        let mut m = TriMesh::default();
        for y in 0..k {
            for x in 0..k {
                let (u, v) = (x as f32 / 20.0, y as f32 / 20.0);
                m.positions
                    .push([u, v, 0.2 * (3.0 * u).sin() * (2.0 * v).cos()]);
            }
        }
        for y in 0..k - 1 {
            for x in 0..k - 1 {
                let a = y * k + x;
                m.faces.push([a, a + 1, a + k]);
                m.faces.push([a + 1, a + k + 1, a + k]);
            }
        }
        m.file_index = (0..m.positions.len() as u32).collect();
        let d = draw_mesh(&m, false);
        assert_eq!(d.positions.len(), m.positions.len());
        // UVs continuous except along the column x = 10, where the right half is shifted: that
        // column's 21 vertices are drawn twice.
        let uvs: Vec<[f32; 2]> = m
            .faces
            .iter()
            .flat_map(|f| {
                let right = f.iter().all(|&v| v % k >= 10) && f.iter().any(|&v| v % k > 10);
                f.map(|v| {
                    let p = m.positions[v as usize];
                    [p[0] + if right { 0.5 } else { 0.0 }, p[1]]
                })
            })
            .collect();
        m.uvs = Some(uvs);
        let d = draw_mesh(&m, true);
        assert_eq!(d.positions.len(), m.positions.len() + 21);
        let without = draw_mesh(&m, false);
        assert_eq!(without.positions.len(), m.positions.len());
    }
}
