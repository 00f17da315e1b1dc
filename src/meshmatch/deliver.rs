//! Deliver: the solved signal on the target file's own vertices, baked into its UV layout, or
//! on the dense working mesh.

use std::sync::Arc;

use super::PreparedMesh;
use crate::mesh::TriMesh;

/// Bake a working-mesh signal into the target's own UV layout: every texel inside a UV triangle
/// finds its surface point (barycentric in that input face), the working face containing it (from
/// the refinement provenance) and interpolates the working signal there; texels outside every
/// island are filled from their neighbours for a few texels (dilation against seams). A mesh
/// without UVs, or one that is not the mesh `prepared_target` came from, gives a black image
/// except for what can be located by nearest working vertex.
pub fn bake_texture(
    target: &TriMesh,
    prepared_target: &PreparedMesh,
    working_signal: &[[f32; 3]],
    size: u32,
) -> image::RgbImage {
    prepared_target.layout.bake(target, working_signal, size)
}

/// Where a prepared mesh's working faces lie in its input faces (the refinement provenance): what
/// baking a working signal into the input's UV layout needs, without the rest of the preparation.
#[derive(Clone, Debug, Default)]
pub struct BakeLayout {
    pub(super) working_faces: Vec<[u32; 3]>,
    pub(super) working_vertices: usize,
    /// Input face (index into the prepared `TriMesh::faces`) of every working face.
    pub(super) face_input: Vec<u32>,
    /// Barycentric coordinates of every working face's corners in its input face.
    pub(super) face_bary: Vec<[[f32; 3]; 3]>,
    pub(super) input_faces: usize,
}

impl BakeLayout {
    /// The layout of a prepared mesh (shared, not copied: built once by [`prepare`]).
    pub fn of(prepared: &PreparedMesh) -> Arc<Self> {
        prepared.layout.clone()
    }

    /// The layout of `r`, a refinement of `input` made without welding (systems that refine the
    /// loaded mesh directly): every refined face lies in its `source_face`.
    pub fn of_refined(input: &TriMesh, r: &crate::geometry::Refined) -> Self {
        BakeLayout {
            working_faces: r.mesh.faces.clone(),
            working_vertices: r.mesh.positions.len(),
            face_input: r.source_face.clone(),
            face_bary: r.source_bary.clone(),
            input_faces: input.faces.len(),
        }
    }

    /// [`bake_texture`] through this layout (`target` is the mesh it was prepared from).
    pub fn bake(
        &self,
        target: &TriMesh,
        working_signal: &[[f32; 3]],
        size: u32,
    ) -> image::RgbImage {
        bake_layout(target, self, working_signal, size)
    }
}

/// The result as `transfer --out` delivers it at a path with extension `ext` (case-insensitive):
/// the target file mesh with the signal on its own vertices, and, for `.glb`/`.obj` when the
/// target has UVs, a `baseColorTexture` of `texture_size` pixels baked into its UV layout (a
/// `.glb` then carries the texture alone, without vertex colours).
pub fn deliver(
    target: &TriMesh,
    layout: &BakeLayout,
    working_signal: &[[f32; 3]],
    file_signal: &[[f32; 3]],
    ext: &str,
    texture_size: u32,
) -> TriMesh {
    let ext = ext.to_ascii_lowercase();
    let mut out = target.clone();
    out.colors = Some(file_signal.to_vec());
    out.texture = None;
    if ext != "ply" && target.uvs.is_some() {
        let image = layout.bake(target, working_signal, texture_size);
        out.texture = Some(std::sync::Arc::new(crate::mesh::Texture {
            image,
            path: None,
        }));
        if ext == "glb" {
            out.colors = None;
        }
    }
    out
}

/// The dense result (`transfer --out-dense`): the working mesh with the signal on its vertices.
pub fn deliver_dense(working: &TriMesh, working_signal: &[[f32; 3]]) -> TriMesh {
    let mut d = working.clone();
    d.colors = Some(working_signal.to_vec());
    d.texture = None;
    d.uvs = None;
    d
}

fn bake_layout(
    target: &TriMesh,
    pm: &BakeLayout,
    working_signal: &[[f32; 3]],
    size: u32,
) -> image::RgbImage {
    let size = size.max(1);
    let (w, h) = (size as usize, size as usize);
    let mut acc = vec![[0.0f32; 3]; w * h];
    let mut have = vec![false; w * h];
    let Some(uvs) = target.uvs.as_ref() else {
        return image::RgbImage::new(size, size);
    };
    let same = pm.input_faces == target.faces.len()
        && working_signal.len() == pm.working_vertices
        && pm.face_input.len() == pm.working_faces.len();
    // Input face -> working faces (CSR).
    let nf = target.faces.len();
    let mut off = vec![0usize; nf + 1];
    if same {
        for &f in &pm.face_input {
            off[f as usize + 1] += 1;
        }
        for i in 0..nf {
            off[i + 1] += off[i];
        }
    }
    let mut fill = off.clone();
    let mut list = vec![0u32; if same { pm.face_input.len() } else { 0 }];
    if same {
        for (wf, &f) in pm.face_input.iter().enumerate() {
            list[fill[f as usize]] = wf as u32;
            fill[f as usize] += 1;
        }
    }
    let sample = |f: usize, b: [f32; 3]| -> [f32; 3] {
        if !same {
            return [0.0; 3];
        }
        let mut best = (f32::NEG_INFINITY, 0usize, [1.0f32, 0.0, 0.0]);
        for &wf in &list[off[f]..off[f + 1]] {
            let cb = pm.face_bary[wf as usize];
            // Solve b = l0 cb0 + l1 cb1 + l2 cb2 in the first two barycentric coordinates.
            let (a0, a1) = (cb[0][0] - cb[2][0], cb[1][0] - cb[2][0]);
            let (c0, c1) = (cb[0][1] - cb[2][1], cb[1][1] - cb[2][1]);
            let det = a0 * c1 - a1 * c0;
            if det.abs() < 1e-12 {
                continue;
            }
            let (r0, r1) = (b[0] - cb[2][0], b[1] - cb[2][1]);
            let l0 = (r0 * c1 - a1 * r1) / det;
            let l1 = (a0 * r1 - r0 * c0) / det;
            let l = [l0, l1, 1.0 - l0 - l1];
            let m = l[0].min(l[1]).min(l[2]);
            if m > best.0 {
                best = (m, wf as usize, l);
            }
            if m >= 0.0 {
                break;
            }
        }
        let (_, wf, l) = best;
        let face = pm.working_faces[wf];
        let l = l.map(|x| x.max(0.0));
        let s = (l[0] + l[1] + l[2]).max(1e-12);
        let mut out = [0.0f32; 3];
        for k in 0..3 {
            let c = working_signal[face[k] as usize];
            for ch in 0..3 {
                out[ch] += l[k] / s * c[ch];
            }
        }
        out
    };
    for (f, _) in target.faces.iter().enumerate() {
        let uv = [uvs[3 * f], uvs[3 * f + 1], uvs[3 * f + 2]]
            .map(|u| [u[0] * w as f32, (1.0 - u[1]) * h as f32]);
        let minx = uv
            .iter()
            .map(|p| p[0])
            .fold(f32::INFINITY, f32::min)
            .floor()
            .max(0.0) as usize;
        let maxx = (uv
            .iter()
            .map(|p| p[0])
            .fold(f32::NEG_INFINITY, f32::max)
            .ceil() as usize)
            .min(w);
        let miny = uv
            .iter()
            .map(|p| p[1])
            .fold(f32::INFINITY, f32::min)
            .floor()
            .max(0.0) as usize;
        let maxy = (uv
            .iter()
            .map(|p| p[1])
            .fold(f32::NEG_INFINITY, f32::max)
            .ceil() as usize)
            .min(h);
        let det = (uv[1][0] - uv[0][0]) * (uv[2][1] - uv[0][1])
            - (uv[2][0] - uv[0][0]) * (uv[1][1] - uv[0][1]);
        if !det.is_finite() || det.abs() < 1e-12 {
            continue;
        }
        for y in miny..maxy {
            for x in minx..maxx {
                let p = [x as f32 + 0.5, y as f32 + 0.5];
                let b1 = ((p[0] - uv[0][0]) * (uv[2][1] - uv[0][1])
                    - (uv[2][0] - uv[0][0]) * (p[1] - uv[0][1]))
                    / det;
                let b2 = ((uv[1][0] - uv[0][0]) * (p[1] - uv[0][1])
                    - (p[0] - uv[0][0]) * (uv[1][1] - uv[0][1]))
                    / det;
                let b0 = 1.0 - b1 - b2;
                if b0 < -1e-4 || b1 < -1e-4 || b2 < -1e-4 {
                    continue;
                }
                let i = y * w + x;
                acc[i] = sample(f, [b0, b1, b2]);
                have[i] = true;
            }
        }
    }
    // Dilate a few texels past island borders.
    for _ in 0..4 {
        let prev = have.clone();
        let snap = acc.clone();
        for y in 0..h {
            for x in 0..w {
                let i = y * w + x;
                if prev[i] {
                    continue;
                }
                let mut a = [0.0f32; 3];
                let mut c = 0;
                for (dx, dy) in [(-1i64, 0i64), (1, 0), (0, -1), (0, 1)] {
                    let (xx, yy) = (x as i64 + dx, y as i64 + dy);
                    if xx < 0 || yy < 0 || xx >= w as i64 || yy >= h as i64 {
                        continue;
                    }
                    let j = yy as usize * w + xx as usize;
                    if prev[j] {
                        for ch in 0..3 {
                            a[ch] += snap[j][ch];
                        }
                        c += 1;
                    }
                }
                if c > 0 {
                    acc[i] = a.map(|v| v / c as f32);
                    have[i] = true;
                }
            }
        }
    }
    let mut img = image::RgbImage::new(size, size);
    for (i, p) in img.pixels_mut().enumerate() {
        p.0 = crate::color::to_u8(acc[i]);
    }
    img
}
