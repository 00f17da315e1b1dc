//! The triangle mesh core: flat per-vertex arrays, CSR adjacency, components, boundary loops,
//! validation and safe repair.
//!
//! A `TriMesh` keeps the file's own vertex order: vertex `i` of a freshly loaded mesh is the file's
//! vertex `i` (OBJ `v` line, PLY `vertex` element, glTF POSITION entry with primitives concatenated).
//! When repair drops unreferenced vertices, `file_index` maps every remaining vertex back.

pub mod io;
mod normals;
mod topology;
mod validate;

use std::path::PathBuf;
use std::sync::Arc;

pub use normals::{SHARP_ANGLE_DEG, corner_normals, vertex_normals};
pub use topology::{
    Csr, boundary_faces, boundary_loops, connected_components, edge_counts, sorted_edges,
    vertex_adjacency, vertex_faces,
};
pub use validate::{
    MAX_FACES, MAX_VERTICES, MAX_WORKING_VERTICES, MIN_WORKING_VERTICES, RepairReport,
    ValidationReport, all_faces,
};

/// An sRGB texture image (8-bit RGB), as referenced by `map_Kd` or `baseColorTexture`.
#[derive(Clone, Debug)]
pub struct Texture {
    /// The pixels, sRGB-encoded, row 0 at the top of the image.
    pub image: image::RgbImage,
    /// Where it was loaded from, if it came from a file.
    pub path: Option<PathBuf>,
}

/// What signal a mesh carries for synthesis.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SignalKind {
    /// Per-vertex colours.
    VertexColors,
    /// A texture image sampled through UVs.
    Texture,
    /// Nothing to transfer from.
    None,
}

impl SignalKind {
    /// The name used by `meshmatch info --json`.
    pub fn as_str(self) -> &'static str {
        match self {
            SignalKind::VertexColors => "vertex_colors",
            SignalKind::Texture => "texture",
            SignalKind::None => "none",
        }
    }
}

/// A triangle mesh with flat per-vertex and per-corner attribute arrays.
#[derive(Clone, Debug, Default)]
pub struct TriMesh {
    /// Vertex positions.
    pub positions: Vec<[f32; 3]>,
    /// Triangles as vertex indices, counter-clockwise seen from outside.
    pub faces: Vec<[u32; 3]>,
    /// Optional per-vertex normals (from the file; `geometry::vertex_normals` computes them).
    pub normals: Option<Vec<[f32; 3]>>,
    /// Optional per-corner texture coordinates: `uvs[3 * f + k]` is corner `k` of face `f`.
    /// Per-corner storage keeps UV seams without splitting vertices. V points up (OBJ/PLY convention).
    pub uvs: Option<Vec<[f32; 2]>>,
    /// Optional per-vertex colours, sRGB-encoded in [0,1].
    pub colors: Option<Vec<[f32; 3]>>,
    /// Optional texture sampled through `uvs`.
    pub texture: Option<Arc<Texture>>,
    /// For each vertex, its index in the source file (identity unless repair dropped vertices).
    pub file_index: Vec<u32>,
    /// Number of vertices the source file declared.
    pub file_vertex_count: usize,
    /// The file this mesh came from, if any.
    pub path: Option<PathBuf>,
}

impl TriMesh {
    /// A mesh from positions and faces, with the identity file map.
    pub fn new(positions: Vec<[f32; 3]>, faces: Vec<[u32; 3]>) -> Self {
        let n = positions.len();
        TriMesh {
            positions,
            faces,
            file_index: (0..n as u32).collect(),
            file_vertex_count: n,
            ..Default::default()
        }
    }

    /// Number of vertices.
    pub fn num_vertices(&self) -> usize {
        self.positions.len()
    }

    /// Number of triangles.
    pub fn num_faces(&self) -> usize {
        self.faces.len()
    }

    /// The signal this mesh carries: vertex colours first, else a texture with UVs, else none.
    pub fn signal_kind(&self) -> SignalKind {
        if self.colors.is_some() {
            SignalKind::VertexColors
        } else if self.texture.is_some() && self.uvs.is_some() {
            SignalKind::Texture
        } else {
            SignalKind::None
        }
    }

    /// Per-vertex sRGB signal: the vertex colours, or the texture sampled (bilinear, in linear
    /// light) at each vertex's corner UVs and averaged over its corners; `None` without a signal.
    pub fn vertex_signal(&self) -> Option<Vec<[f32; 3]>> {
        match self.signal_kind() {
            SignalKind::VertexColors => self.colors.clone(),
            SignalKind::Texture => {
                let tex = self.texture.as_ref()?;
                let uvs = self.uvs.as_ref()?;
                let mut acc = vec![[0.0f32; 4]; self.num_vertices()];
                for (f, face) in self.faces.iter().enumerate() {
                    for k in 0..3 {
                        let c = sample_texture_linear(tex, uvs[3 * f + k]);
                        let a = &mut acc[face[k] as usize];
                        a[0] += c[0];
                        a[1] += c[1];
                        a[2] += c[2];
                        a[3] += 1.0;
                    }
                }
                Some(
                    acc.iter()
                        .map(|a| {
                            let w = a[3].max(1.0);
                            [a[0] / w, a[1] / w, a[2] / w].map(crate::color::linear_to_srgb)
                        })
                        .collect(),
                )
            }
            SignalKind::None => None,
        }
    }

    /// Axis-aligned bounds (min, max) over finite positions; `None` for an empty mesh.
    pub fn bounds(&self) -> Option<([f32; 3], [f32; 3])> {
        let mut lo = [f32::INFINITY; 3];
        let mut hi = [f32::NEG_INFINITY; 3];
        let mut any = false;
        for p in &self.positions {
            if p.iter().all(|x| x.is_finite()) {
                any = true;
                for k in 0..3 {
                    lo[k] = lo[k].min(p[k]);
                    hi[k] = hi[k].max(p[k]);
                }
            }
        }
        any.then_some((lo, hi))
    }

    /// Total surface area.
    pub fn area(&self) -> f64 {
        self.faces
            .iter()
            .map(|f| {
                let [a, b, c] = f.map(|i| glam::Vec3::from(self.positions[i as usize]).as_dvec3());
                0.5 * (b - a).cross(c - a).length()
            })
            .sum()
    }

    /// CSR vertex-vertex adjacency (sorted neighbour lists).
    pub fn adjacency(&self) -> Csr {
        vertex_adjacency(self.num_vertices(), &self.faces)
    }

    /// Expand a per-vertex array to the file's vertex order; file vertices dropped by repair get
    /// `fill`.
    pub fn to_file_order<T: Clone>(&self, data: &[T], fill: T) -> Vec<T> {
        let mut out = vec![fill; self.file_vertex_count];
        for (i, &fi) in self.file_index.iter().enumerate() {
            if let Some(slot) = out.get_mut(fi as usize) {
                *slot = data[i].clone();
            }
        }
        out
    }

    /// Map a file vertex index to this mesh's vertex index, if the vertex survived repair.
    pub fn from_file_index(&self, file_vertex: u32) -> Option<u32> {
        // file_index is strictly increasing (repair only drops vertices), so binary search works.
        self.file_index
            .binary_search(&file_vertex)
            .ok()
            .map(|i| i as u32)
    }
}

/// Bilinear texture lookup at `uv` (wrapping, V up), returning linear-light RGB.
pub fn sample_texture_linear(tex: &Texture, uv: [f32; 2]) -> [f32; 3] {
    let img = &tex.image;
    let (w, h) = (img.width() as i64, img.height() as i64);
    if w == 0 || h == 0 || !uv[0].is_finite() || !uv[1].is_finite() {
        return [0.0; 3];
    }
    let x = uv[0] * w as f32 - 0.5;
    let y = (1.0 - uv[1]) * h as f32 - 0.5;
    let (x0, y0) = (x.floor(), y.floor());
    let (fx, fy) = (x - x0, y - y0);
    let (x0, y0) = (x0 as i64, y0 as i64);
    let px = |xi: i64, yi: i64| {
        let p = img
            .get_pixel(xi.rem_euclid(w) as u32, yi.rem_euclid(h) as u32)
            .0;
        p.map(|c| crate::color::srgb_to_linear(c as f32 / 255.0))
    };
    let (a, b, c, d) = (
        px(x0, y0),
        px(x0 + 1, y0),
        px(x0, y0 + 1),
        px(x0 + 1, y0 + 1),
    );
    let mut out = [0.0; 3];
    for k in 0..3 {
        let top = a[k] * (1.0 - fx) + b[k] * fx;
        let bot = c[k] * (1.0 - fx) + d[k] * fx;
        out[k] = top * (1.0 - fy) + bot * fy;
    }
    out
}

/// Bilinear texture lookup at `uv`, returning an sRGB-encoded colour (filtered in linear light).
pub fn sample_texture(tex: &Texture, uv: [f32; 2]) -> [f32; 3] {
    sample_texture_linear(tex, uv).map(crate::color::linear_to_srgb)
}
