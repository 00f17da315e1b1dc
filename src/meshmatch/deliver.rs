//! Deliver: the solved signal on the target file's own vertices, baked into its UV layout, or
//! on the dense working mesh.

use std::sync::Arc;

use super::PreparedMesh;
use super::resample::Resampler;
use crate::mesh::TriMesh;

/// Bake a working-mesh signal into the target's own UV layout: every texel inside a UV triangle
/// finds its surface point (barycentric in that input face), the working face containing it (from
/// the refinement provenance) and interpolates the working signal there; texels outside every
/// island (the gutters) are filled by pull-push from the nearest islands, so no background shows
/// under filtering. A mesh
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

    /// This layout carried one refinement further out: `self` lies in the faces of a mesh that
    /// was itself made by refining another (`outer_face[f]` and `outer_bary[f]` say where face
    /// `f` of it lies in that other mesh, which has `input_faces` faces), as when an application
    /// prepares an already refined copy of the caller's mesh. The result lies in the other mesh.
    pub fn through(
        &self,
        outer_face: &[u32],
        outer_bary: &[[[f32; 3]; 3]],
        input_faces: usize,
    ) -> BakeLayout {
        let mut face_input = Vec::with_capacity(self.face_input.len());
        let mut face_bary = Vec::with_capacity(self.face_bary.len());
        for (&f, cb) in self.face_input.iter().zip(&self.face_bary) {
            let f = f as usize;
            let (of, ob) = match (outer_face.get(f), outer_bary.get(f)) {
                (Some(&of), Some(ob)) => (of, *ob),
                _ => (0, [[1.0, 0.0, 0.0]; 3]),
            };
            face_input.push(of);
            face_bary.push(cb.map(|b| {
                let mut out = [0.0f32; 3];
                for (j, bj) in b.iter().enumerate() {
                    for (i, o) in out.iter_mut().enumerate() {
                        *o += bj * ob[j][i];
                    }
                }
                out
            }));
        }
        BakeLayout {
            working_faces: self.working_faces.clone(),
            working_vertices: self.working_vertices,
            face_input,
            face_bary,
            input_faces,
        }
    }

    /// The UVs of every working face's corners in `target`'s UV layout (`target` is the mesh
    /// this layout was made from), or `None` without UVs or for another mesh.
    pub fn working_uvs(&self, target: &TriMesh) -> Option<Vec<[f32; 2]>> {
        let uvs = target.uvs.as_ref()?;
        if self.input_faces != target.faces.len()
            || self.face_input.len() != self.working_faces.len()
            || uvs.len() < 3 * target.faces.len()
        {
            return None;
        }
        Some(
            self.face_input
                .iter()
                .zip(&self.face_bary)
                .flat_map(|(&f, cb)| {
                    let f = f as usize;
                    cb.map(|b| {
                        (0..3).fold([0.0f32; 2], |a, k| {
                            let u = uvs[3 * f + k];
                            [a[0] + b[k] * u[0], a[1] + b[k] * u[1]]
                        })
                    })
                })
                .collect(),
        )
    }

    /// Bake the source read at full resolution through a solution ([`Resampler::sample`]) into
    /// `target`'s UV layout: the working faces are rasterised in UV space, so every texel knows
    /// its working face and barycentric coordinates at once; gutters are filled by pull-push. A
    /// target without UVs (or another mesh) gives a black image.
    pub fn bake_resampled(&self, target: &TriMesh, r: &Resampler, size: u32) -> image::RgbImage {
        let size = size.max(1);
        let Some(wuv) = self.working_uvs(target) else {
            return image::RgbImage::new(size, size);
        };
        let s2 = (size as f32) * (size as f32);
        let area: Vec<f32> = wuv
            .chunks_exact(3)
            .map(|t| {
                let (a, b, c) = (t[0], t[1], t[2]);
                ((b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1])).abs() * 0.5 * s2
            })
            .collect();
        let (w, h) = (size as usize, size as usize);
        let mut baked = crate::geometry::bake_uv(&wuv, self.working_faces.len(), w, h, |wf, b| {
            r.sample(wf, b, area[wf])
        });
        crate::geometry::fill_gutters(&mut baked);
        baked.to_rgb8()
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

/// What [`deliver`] made: the mesh to write, and the atlas it generated for a target without UVs.
#[derive(Clone, Debug)]
pub struct Delivered {
    /// The target file mesh with the result (vertex colours and/or a baked texture).
    pub mesh: TriMesh,
    /// The atlas generated for a target without UVs (`.glb`/`.obj` outputs), if one was.
    pub atlas: Option<crate::geometry::UvAtlas>,
}

impl Delivered {
    /// One line for stderr or the status bar about the generated atlas, if any.
    pub fn atlas_line(&self, texture_size: u32) -> Option<String> {
        self.atlas.as_ref().map(|a| {
            format!(
                "generated a UV atlas for the target: {} charts, {:.0}% of the {texture_size}x{texture_size} texture",
                a.charts,
                100.0 * a.utilization
            )
        })
    }
}

/// The result as `transfer --out` delivers it at a path with extension `ext` (case-insensitive):
/// the target file mesh with the signal on its own vertices, and, for `.glb`/`.obj`, a
/// `baseColorTexture` of `texture_size` pixels baked into its UV layout (a `.glb` or `.gltf` then carries
/// the texture alone, without vertex colours). A target without UVs first gets a generated atlas
/// ([`crate::geometry::uv_atlas`]); `cancel` stops that. With a [`Resampler`] every texel reads
/// the source at full resolution through the solution; without one the texture interpolates
/// `working_signal`.
#[allow(clippy::too_many_arguments)]
pub fn deliver(
    target: &TriMesh,
    layout: &BakeLayout,
    working_signal: &[[f32; 3]],
    file_signal: &[[f32; 3]],
    ext: &str,
    texture_size: u32,
    full: Option<&Resampler>,
    cancel: &crate::work::CancelToken,
) -> crate::error::Result<Delivered> {
    let ext = ext.to_ascii_lowercase();
    if ext != "ply" {
        crate::geometry::check_bake_memory(texture_size)?;
    }
    let mut out = target.clone();
    out.colors = Some(file_signal.to_vec());
    out.texture = None;
    let mut atlas = None;
    if ext != "ply" {
        if out.uvs.is_none() {
            let params = crate::geometry::AtlasParams {
                texture_size,
                ..Default::default()
            };
            let a =
                crate::geometry::uv_atlas(&out.positions, &out.faces, &params, &|_| {}, cancel)?;
            out.uvs = Some(a.uvs.clone());
            atlas = Some(a);
        }
        let image = match full {
            Some(r) => layout.bake_resampled(&out, r, texture_size),
            None => layout.bake(&out, working_signal, texture_size),
        };
        out.texture = Some(std::sync::Arc::new(crate::mesh::Texture {
            image,
            path: None,
        }));
        if ext == "glb" || ext == "gltf" {
            out.colors = None;
        }
    }
    Ok(Delivered { mesh: out, atlas })
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
    let mut baked = crate::geometry::bake_uv(uvs, target.faces.len(), w, h, sample);
    crate::geometry::fill_gutters(&mut baked);
    baked.to_rgb8()
}
