//! Texture synthesis in texture space: the samples of Wei & Levoy's synthesis are the texels of
//! the target's UV layout (its own UVs or a generated atlas), not the vertices of a refined mesh,
//! and the result is a texture.
//!
//! - **Samples.** Level `k` of the pyramid is the UV layout rasterised at `R / 2^k` texels a
//!   side (conservatively, as the bake does: [`crate::geometry::uv_texels`]); each covered texel
//!   is a surface point (face, barycentric) with its position and interpolated normal. The
//!   working side `R` puts one texel on one exemplar pixel, within a texel budget.
//! - **Neighbourhoods across seams.** A texel's template (Wei & Levoy §3.3: the grid
//!   `c + h (i s - j t)` in its texture frame) is resampled on the *surface*, not in the image:
//!   the target's triangles around the texel (grown across shared edges of the welded mesh, so
//!   across UV seams) are flattened orthographically into the frame, each template point finds the
//!   front-facing triangle under it, and that point's UV names the texels that carry its value
//!   (the texel triangle of the level's grid around it). A chart border is therefore invisible
//!   to the neighbourhoods: a template that leaves one chart reads the texels of the next.
//! - **Adjacency** (orientation relaxation, coherence candidates) is 3D: the grid neighbours in
//!   the same chart, and for texels at a chart border the nearest texels of any chart.
//! - **Parents** are the texels of the next level at the same place (`(x/2, y/2)` when it lies
//!   on the same surface point, else the nearest in 3D).
//! - **Magnification.** Every texel of the output texture (any `texture_size`) takes its colour
//!   from the *full-resolution* exemplar at the synthesized exemplar coordinate of the working
//!   texels around it, offset by its surface distance from each in that texel's frame (texture
//!   coordinate synthesis, as Ying et al. 2001 and Lefebvre & Hoppe 2005 upsample coordinates),
//!   blended by the texel triangle's weights. A budget that shrank the exemplar therefore
//!   still gives a texture with the exemplar's own detail. Transparent exemplar pixels are read
//!   through their pull-push fill, so a hole's colour never appears.

use glam::{Vec2, Vec3};
use rayon::prelude::*;

use super::neigh::{Frame, Stencils, Tap, UNCOVERED, splat_template};
use super::pyramid::{Img, Level};
use super::{
    Anisotropy, LevelsOut, Orientation, SynthParams, anisotropy, feature_field, synthesize_levels,
    transparent_filled, validate,
};
use crate::error::{Error, Result};
use crate::mesh::{Csr, TriMesh};
use crate::work::{CancelToken, Event, Stopwatch};

/// Default most texels synthesized (the working texture's covered texels).
pub const DEFAULT_TEXEL_BUDGET: usize = 300_000;

/// Parameters of texture-space synthesis.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
#[serde(default)]
pub struct TextureParams {
    /// The synthesis itself (scale, orientation, levels, search, seed). `displace` and masks
    /// do not apply to a texture.
    pub synth: SynthParams,
    /// Side of the output texture in texels.
    pub texture_size: u32,
    /// Most texels synthesized; the output is magnified from them (see the module doc).
    pub texel_budget: usize,
    /// Generate a new atlas even when the target's UVs are usable.
    pub new_atlas: bool,
}

impl Default for TextureParams {
    fn default() -> Self {
        TextureParams {
            synth: SynthParams::default(),
            texture_size: 2048,
            texel_budget: DEFAULT_TEXEL_BUDGET,
            new_atlas: false,
        }
    }
}

/// What texture-space synthesis works on.
#[derive(Clone, Copy, Debug)]
pub struct TextureInput<'a> {
    /// The exemplar at full resolution (it is shrunk internally to the working density).
    pub exemplar: &'a image::RgbImage,
    /// Its alpha, if it has transparent pixels (never synthesized).
    pub alpha: Option<&'a image::GrayImage>,
    /// The mesh to texture; without UVs an atlas is generated for it.
    pub target: &'a TriMesh,
    /// An explicit texture "right" per target vertex (used unless the orientation is `Random`
    /// or `Up`); `None` with [`Orientation::Features`] computes the curve-guided field.
    pub field: Option<&'a [[f32; 3]]>,
}

/// Wall-clock seconds per stage.
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct TextureTimings {
    /// Atlas (when generated), texel levels and adjacency.
    pub prepare: f64,
    /// Orientation field.
    pub orientation: f64,
    /// Surface stencils of every texel.
    pub neighbourhoods: f64,
    /// Best-match search.
    pub search: f64,
    /// The output texture from the full-resolution exemplar.
    pub magnify: f64,
    /// Whole call.
    pub total: f64,
}

/// The outcome of [`synthesize_texture`].
#[derive(Clone, Debug)]
pub struct TextureOutput {
    /// The target with UVs (its own, or the generated atlas's) and the synthesized texture;
    /// vertex colours dropped.
    pub mesh: TriMesh,
    /// Charts and coverage of a generated atlas.
    pub atlas: Option<crate::geometry::UvAtlas>,
    /// Why the atlas was generated: no UVs, UVs outside the unit square, overlapping charts, or
    /// asked for.
    pub atlas_reason: Option<String>,
    /// Side of the working (synthesized) texture.
    pub working_size: u32,
    /// Synthesized texels per level, finest first.
    pub level_texels: Vec<usize>,
    /// Mean squared neighbourhood distance per element in each level's last pass, finest first.
    pub level_energy: Vec<f64>,
    /// Width of the exemplar the synthesis ran on (the input's, or shrunk to the budget).
    pub working_exemplar_width: u32,
    /// Surface units per working texel (= per working exemplar pixel).
    pub spacing: f32,
    /// The orientation field used (`Auto` resolved).
    pub orientation_used: Orientation,
    /// The exemplar's measured anisotropy, when `Auto` chose the field.
    pub anisotropy: Option<Anisotropy>,
    /// Stage timings.
    pub timings: TextureTimings,
}

/// The target's surface as the texel stencils need it: welded topology (so templates cross UV
/// seams), per-corner UVs, smooth normals, and each face's surface length per unit of UV.
pub(super) struct Surface<'a> {
    pub(super) positions: &'a [[f32; 3]],
    pub(super) faces: Vec<[u32; 3]>,
    pub(super) uvs: &'a [[f32; 2]],
    pub(super) normals: Vec<[f32; 3]>,
    /// Faces sharing an edge with each face (welded).
    face_adj: Csr,
    /// sqrt(surface area / UV area) of each face: one UV unit in surface units.
    pub(super) uv_scale: Vec<f32>,
}

impl<'a> Surface<'a> {
    pub(super) fn new(mesh: &'a TriMesh, uvs: &'a [[f32; 2]]) -> Surface<'a> {
        // weld exactly coincident positions (files split at UV seams)
        let mut ids: std::collections::HashMap<[u32; 3], u32> = Default::default();
        let canon: Vec<u32> = mesh
            .positions
            .iter()
            .enumerate()
            .map(|(i, p)| *ids.entry(p.map(f32::to_bits)).or_insert(i as u32))
            .collect();
        let faces: Vec<[u32; 3]> = mesh
            .faces
            .iter()
            .map(|f| f.map(|v| canon[v as usize]))
            .collect();
        let normals = crate::geometry::vertex_normals(&mesh.positions, &faces);
        let mut edges: Vec<(u64, u32)> = Vec::with_capacity(faces.len() * 3);
        for (fi, f) in faces.iter().enumerate() {
            for k in 0..3 {
                let (a, b) = (f[k], f[(k + 1) % 3]);
                if a != b {
                    edges.push((((a.min(b) as u64) << 32) | a.max(b) as u64, fi as u32));
                }
            }
        }
        edges.sort_unstable();
        let mut pairs: Vec<(u32, u32)> = Vec::new();
        let mut i = 0;
        while i < edges.len() {
            let mut j = i + 1;
            while j < edges.len() && edges[j].0 == edges[i].0 {
                j += 1;
            }
            for a in i..j {
                for b in i..j {
                    if a != b {
                        pairs.push((edges[a].1, edges[b].1));
                    }
                }
            }
            i = j;
        }
        let face_adj = Csr::from_pairs(faces.len(), &mut pairs);
        let uv_scale = faces
            .iter()
            .enumerate()
            .map(|(fi, f)| {
                let p = f.map(|v| Vec3::from(mesh.positions[v as usize]));
                let a3 = 0.5 * (p[1] - p[0]).cross(p[2] - p[0]).length();
                let t = [0, 1, 2].map(|k| Vec2::from(uvs[3 * fi + k]));
                let a2 = 0.5 * (t[1] - t[0]).perp_dot(t[2] - t[0]).abs();
                if a2 > 1e-20 && a3.is_finite() {
                    (a3 / a2).sqrt()
                } else {
                    f32::INFINITY
                }
            })
            .collect();
        Surface {
            positions: &mesh.positions,
            faces,
            uvs,
            normals,
            face_adj,
            uv_scale,
        }
    }

    pub(super) fn point(&self, f: u32, b: [f32; 3]) -> Vec3 {
        let face = self.faces[f as usize];
        (0..3).fold(Vec3::ZERO, |acc, k| {
            acc + b[k] * Vec3::from(self.positions[face[k] as usize])
        })
    }

    pub(super) fn normal(&self, f: u32, b: [f32; 3]) -> Vec3 {
        let face = self.faces[f as usize];
        let n = (0..3).fold(Vec3::ZERO, |acc, k| {
            acc + b[k] * Vec3::from(self.normals[face[k] as usize])
        });
        let n = n.normalize_or_zero();
        if n == Vec3::ZERO {
            let p = face.map(|v| Vec3::from(self.positions[v as usize]));
            (p[1] - p[0]).cross(p[2] - p[0]).normalize_or(Vec3::Z)
        } else {
            n
        }
    }

    fn uv(&self, f: u32, b: [f32; 3]) -> Vec2 {
        (0..3).fold(Vec2::ZERO, |acc, k| {
            acc + b[k] * Vec2::from(self.uvs[3 * f as usize + k])
        })
    }

    /// The UV area the layout covers (overlapping charts counted once each).
    fn uv_area(&self) -> f64 {
        uv_area(self.uvs, self.faces.len())
    }
}

/// The summed UV area of `faces` triangles with per-corner `uvs`.
fn uv_area(uvs: &[[f32; 2]], faces: usize) -> f64 {
    (0..faces)
        .map(|f| {
            let t = [0, 1, 2].map(|k| Vec2::from(uvs[3 * f + k]).as_dvec2());
            0.5 * (t[1] - t[0]).perp_dot(t[2] - t[0]).abs()
        })
        .sum()
}

/// Why `mesh`'s UVs cannot carry a synthesized texture, if they cannot: none; faces outside
/// the unit square (tiled or wrapped layouts, whose texels would be shared); or charts that
/// overlap (mirrored or stacked halves: one texel would be two surface places); or a layout that
/// covers under 5% of the texture. Coverage is counted in texels at 512², overlap as UV area
/// beyond it.
fn unusable_uvs(mesh: &TriMesh) -> Option<String> {
    let Some(uvs) = mesh
        .uvs
        .as_ref()
        .filter(|u| u.len() == 3 * mesh.faces.len())
    else {
        return Some("the target has no UVs".into());
    };
    // a few corners just past the border are common in real layouts; faces whose centre lies
    // outside are a tiled or wrapped layout
    let outside = (0..mesh.faces.len())
        .filter(|&f| {
            let c = (0..3).fold(Vec2::ZERO, |a, k| a + Vec2::from(uvs[3 * f + k])) / 3.0;
            !(c.is_finite() && (0.0..=1.0).contains(&c.x) && (0.0..=1.0).contains(&c.y))
        })
        .count();
    if outside * 100 > mesh.faces.len() {
        return Some(format!(
            "{outside} of its {} faces lie outside the UV unit square (a tiled or wrapped layout)",
            mesh.faces.len()
        ));
    }
    let area = uv_area(uvs, mesh.faces.len());
    const PROBE: usize = 512;
    let covered = crate::geometry::uv_texels(uvs, mesh.faces.len(), PROBE, PROBE)
        .iter()
        .filter(|t| t.is_some())
        .count() as f64
        / (PROBE * PROBE) as f64;
    // a layout in a corner of the image would give the surface a few texels
    if covered < 0.05 {
        return Some(format!(
            "its UVs cover only {:.1}% of the texture",
            100.0 * covered
        ));
    }
    // conservative coverage exceeds the area of a layout without overlaps (chart borders)
    if area > 1.1 * covered + 1e-3 {
        return Some(format!(
            "its UV charts overlap ({:.0}% of their area is shared)",
            100.0 * (1.0 - covered / area)
        ));
    }
    None
}

/// The target with the UV layout a synthesized texture goes through: its own UVs when they can
/// carry one ([`unusable_uvs`]), else a generated atlas (also when `params.new_atlas`), with the
/// atlas and the reason it was generated.
pub(super) fn texture_layout(
    target: &TriMesh,
    params: &TextureParams,
    cancel: &CancelToken,
) -> Result<(TriMesh, Option<crate::geometry::UvAtlas>, Option<String>)> {
    let mut mesh = target.clone();
    let mut atlas = None;
    let atlas_reason = if params.new_atlas {
        Some("asked for".to_string())
    } else {
        unusable_uvs(&mesh)
    };
    if atlas_reason.is_some() {
        let ap = crate::geometry::AtlasParams {
            texture_size: params.texture_size,
            ..Default::default()
        };
        let a = crate::geometry::uv_atlas(&mesh.positions, &mesh.faces, &ap, &|_| {}, cancel)?;
        mesh.uvs = Some(a.uvs.clone());
        atlas = Some(a);
    }
    cancel.check()?;
    Ok((mesh, atlas, atlas_reason))
}

/// Give `mesh` the `size²` texture of `pixels` (row 0 at the top), its texels outside
/// `covered` filled as gutters, in place of its vertex colours.
pub(super) fn set_texture(
    mesh: &mut TriMesh,
    size: usize,
    pixels: Vec<[f32; 3]>,
    covered: Vec<bool>,
) {
    let mut baked = crate::geometry::BakedImage {
        width: size,
        height: size,
        pixels,
        covered,
    };
    crate::geometry::fill_gutters(&mut baked);
    mesh.colors = None;
    mesh.texture = Some(std::sync::Arc::new(crate::mesh::Texture {
        image: baked.to_rgb8(),
        path: None,
    }));
}

/// One level of texels: the grid side, the sample index of every texel (`u32::MAX` outside the
/// charts) and the surface point of every sample.
struct TexelGrid {
    side: usize,
    index: Vec<u32>,
    texel: Vec<u32>,
    hit: Vec<(u32, [f32; 3])>,
}

impl TexelGrid {
    fn new(surface: &Surface, side: usize) -> TexelGrid {
        let texels = crate::geometry::uv_texels(surface.uvs, surface.faces.len(), side, side);
        let mut index = vec![u32::MAX; side * side];
        let mut texel = Vec::new();
        let mut hit = Vec::new();
        for (i, t) in texels.into_iter().enumerate() {
            if let Some(h) = t
                && surface.uv_scale[h.0 as usize].is_finite()
            {
                index[i] = hit.len() as u32;
                texel.push(i as u32);
                hit.push(h);
            }
        }
        TexelGrid {
            side,
            index,
            texel,
            hit,
        }
    }

    /// Surface length of one texel of this grid at sample `s`.
    fn texel_len(&self, surface: &Surface, s: usize) -> f32 {
        surface.uv_scale[self.hit[s].0 as usize] / self.side as f32
    }

    /// The taps that carry the value at UV `uv` (surface point `p`, on a face whose texel is
    /// `len` long): the texel triangle of the grid cell around it, without texels of another
    /// chart (farther than two texels from `p`), renormalised; the nearest covered texel when
    /// none of the three is usable.
    fn taps_at(&self, uv: Vec2, p: Vec3, len: f32, positions: &[[f32; 3]]) -> Tap {
        let n = self.side as f32;
        let x = uv.x * n - 0.5;
        let y = (1.0 - uv.y) * n - 0.5;
        if !(x.is_finite() && y.is_finite()) {
            return UNCOVERED;
        }
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let (xi, yi) = (x0 as i64, y0 as i64);
        let corners: [((i64, i64), f32); 3] = if fx + fy <= 1.0 {
            [
                ((xi, yi), 1.0 - fx - fy),
                ((xi + 1, yi), fx),
                ((xi, yi + 1), fy),
            ]
        } else {
            [
                ((xi + 1, yi + 1), fx + fy - 1.0),
                ((xi, yi + 1), 1.0 - fx),
                ((xi + 1, yi), 1.0 - fy),
            ]
        };
        let reach2 = (2.0 * len).powi(2);
        let sample = |cx: i64, cy: i64| -> Option<u32> {
            if cx < 0 || cy < 0 || cx >= self.side as i64 || cy >= self.side as i64 {
                return None;
            }
            let s = self.index[cy as usize * self.side + cx as usize];
            (s != u32::MAX && Vec3::from(positions[s as usize]).distance_squared(p) <= reach2)
                .then_some(s)
        };
        let mut tap = Tap {
            idx: [u32::MAX; 3],
            w: [0.0; 3],
        };
        let mut total = 0.0;
        let mut first = u32::MAX;
        for (k, &((cx, cy), w)) in corners.iter().enumerate() {
            if let Some(s) = sample(cx, cy) {
                tap.idx[k] = s;
                tap.w[k] = w;
                total += w;
                if first == u32::MAX {
                    first = s;
                }
            }
        }
        if first == u32::MAX || total <= 1e-6 {
            let near =
                sample(x.round() as i64, y.round() as i64).or((first != u32::MAX).then_some(first));
            return match near {
                Some(s) => Tap {
                    idx: [s; 3],
                    w: [1.0, 0.0, 0.0],
                },
                None => UNCOVERED,
            };
        }
        for k in 0..3 {
            if tap.idx[k] == u32::MAX {
                tap.idx[k] = first;
                tap.w[k] = 0.0;
            } else {
                tap.w[k] /= total;
            }
        }
        tap
    }
}

/// A 3D hash grid over sample positions (with their normals).
struct PointGrid<'a> {
    cell: f32,
    map: std::collections::HashMap<[i32; 3], Vec<u32>>,
    positions: &'a [[f32; 3]],
    normals: &'a [[f32; 3]],
}

impl<'a> PointGrid<'a> {
    fn new(positions: &'a [[f32; 3]], normals: &'a [[f32; 3]], cell: f32) -> PointGrid<'a> {
        let mut map: std::collections::HashMap<[i32; 3], Vec<u32>> = Default::default();
        for (i, p) in positions.iter().enumerate() {
            map.entry(Self::key(*p, cell)).or_default().push(i as u32);
        }
        PointGrid {
            cell,
            map,
            positions,
            normals,
        }
    }

    fn key(p: [f32; 3], cell: f32) -> [i32; 3] {
        p.map(|x| (x / cell).floor().clamp(-1e9, 1e9) as i32)
    }

    /// Samples within `r` of `p` (r at most one cell), nearest first, each with
    /// normal agreement above zero unless `n` is zero; `skip` excluded.
    fn near(&self, p: Vec3, n: Vec3, r: f32, skip: u32, out: &mut Vec<(f32, u32)>) {
        out.clear();
        let c = Self::key(p.to_array(), self.cell);
        for dz in -1..=1 {
            for dy in -1..=1 {
                for dx in -1..=1 {
                    if let Some(list) = self.map.get(&[c[0] + dx, c[1] + dy, c[2] + dz]) {
                        for &s in list {
                            if s == skip {
                                continue;
                            }
                            let d2 = Vec3::from(self.positions[s as usize]).distance_squared(p);
                            if d2 <= r * r
                                && (n == Vec3::ZERO
                                    || Vec3::from(self.normals[s as usize]).dot(n) > 0.0)
                            {
                                out.push((d2, s));
                            }
                        }
                    }
                }
            }
        }
        out.sort_unstable_by(|a, b| a.0.total_cmp(&b.0));
    }
}

/// Neighbours per texel in the adjacency (grid neighbours of the same chart, or the nearest).
const MAX_NEIGHBOURS: usize = 8;

/// The median of `values` (1 when empty): the typical texel length of a level.
fn median(values: &[f32]) -> f32 {
    if values.is_empty() {
        return 1.0;
    }
    let mut v = values.to_vec();
    let m = v.len() / 2;
    *v.select_nth_unstable_by(m, |a, b| a.total_cmp(b)).1
}

/// The synthesis level of a texel grid: positions, normals, 3D adjacency.
fn texel_level(surface: &Surface, grid: &TexelGrid) -> Level {
    let positions: Vec<[f32; 3]> = grid
        .hit
        .iter()
        .map(|&(f, b)| surface.point(f, b).to_array())
        .collect();
    let normals: Vec<[f32; 3]> = grid
        .hit
        .iter()
        .map(|&(f, b)| surface.normal(f, b).to_array())
        .collect();
    let lens: Vec<f32> = (0..grid.hit.len())
        .map(|s| grid.texel_len(surface, s))
        .collect();
    let cell = (2.5 * median(&lens)).max(1e-12);
    let pgrid = PointGrid::new(&positions, &normals, cell);
    let side = grid.side as i64;
    let rows: Vec<Vec<u32>> = (0..grid.hit.len())
        .into_par_iter()
        .map_init(Vec::new, |buf, s| {
            let t = grid.texel[s] as i64;
            let (x, y) = (t % side, t / side);
            let p = Vec3::from(positions[s]);
            let reach2 = (2.0 * lens[s]).powi(2);
            let mut row: Vec<u32> = Vec::with_capacity(MAX_NEIGHBOURS);
            for dy in -1..=1 {
                for dx in -1..=1 {
                    let (cx, cy) = (x + dx, y + dy);
                    if (dx, dy) == (0, 0) || cx < 0 || cy < 0 || cx >= side || cy >= side {
                        continue;
                    }
                    let q = grid.index[(cy * side + cx) as usize];
                    if q != u32::MAX
                        && Vec3::from(positions[q as usize]).distance_squared(p) <= reach2
                    {
                        row.push(q);
                    }
                }
            }
            if row.len() < MAX_NEIGHBOURS {
                // a chart border: the nearest texels of any chart
                let n = Vec3::from(normals[s]);
                pgrid.near(p, n, cell, s as u32, buf);
                for &(_, q) in buf.iter() {
                    if row.len() >= MAX_NEIGHBOURS {
                        break;
                    }
                    if !row.contains(&q) {
                        row.push(q);
                    }
                }
            }
            row
        })
        .collect();
    let mut offsets = Vec::with_capacity(rows.len() + 1);
    offsets.push(0u32);
    let mut indices = Vec::new();
    for r in &rows {
        indices.extend_from_slice(r);
        offsets.push(indices.len() as u32);
    }
    let n = positions.len();
    Level {
        positions,
        faces: Vec::new(),
        normals,
        adj: Csr { offsets, indices },
        vf: Csr {
            offsets: vec![0; n + 1],
            indices: Vec::new(),
        },
        parent: Vec::new(),
        fixed: vec![None; n],
    }
}

/// The parent of every sample of `fine` on `coarse`: the texel at `(x/2, y/2)` when it is the
/// same surface place, else the nearest coarse sample in 3D.
fn texel_parents(
    surface: &Surface,
    fine_grid: &TexelGrid,
    fine: &Level,
    coarse_grid: &TexelGrid,
    coarse: &Level,
) -> Vec<u32> {
    let lens: Vec<f32> = (0..coarse_grid.hit.len())
        .map(|s| coarse_grid.texel_len(surface, s))
        .collect();
    let cell = (4.0 * median(&lens)).max(1e-12);
    let pgrid = PointGrid::new(&coarse.positions, &coarse.normals, cell);
    let (fs, cs) = (fine_grid.side, coarse_grid.side);
    (0..fine.num_vertices())
        .into_par_iter()
        .map_init(Vec::new, |buf, s| {
            let t = fine_grid.texel[s] as usize;
            let (x, y) = ((t % fs) / 2, (t / fs) / 2);
            let p = Vec3::from(fine.positions[s]);
            if x < cs && y < cs {
                let q = coarse_grid.index[y * cs + x];
                if q != u32::MAX
                    && Vec3::from(coarse.positions[q as usize]).distance(p)
                        <= 2.0 * lens[q as usize]
                {
                    return q;
                }
            }
            let n = Vec3::from(fine.normals[s]);
            pgrid.near(p, n, cell, u32::MAX, buf);
            if let Some(&(_, q)) = buf.first() {
                return q;
            }
            // nothing near facing the same way (inconsistent normals): the nearest near at all
            pgrid.near(p, Vec3::ZERO, cell, u32::MAX, buf);
            if let Some(&(_, q)) = buf.first() {
                return q;
            }
            // nothing near in 3D: the nearest covered texel around (x/2, y/2) in the image, or
            // (a layout that stretches one place across many texels) the first
            let (cx, cy) = (x.min(cs - 1) as i64, y.min(cs - 1) as i64);
            for r in 1..=(cs as i64).min(16) {
                for dy in -r..=r {
                    for dx in -r..=r {
                        if dx.abs() != r && dy.abs() != r {
                            continue;
                        }
                        let (qx, qy) = (cx + dx, cy + dy);
                        if qx >= 0 && qy >= 0 && qx < cs as i64 && qy < cs as i64 {
                            let q = coarse_grid.index[qy as usize * cs + qx as usize];
                            if q != u32::MAX {
                                return q;
                            }
                        }
                    }
                }
            }
            0
        })
        .collect()
}

/// Per-thread buffers of the surface flattening.
struct FlatScratch {
    fstamp: Vec<u32>,
    stamp: u32,
    queue: Vec<u32>,
    depth: Vec<f32>,
}

/// The surface point under every template point of `frame` (`size x size`, row-major, rows going
/// down): the target's triangles grown from `seed` across shared edges while their flattened
/// footprint meets the template and they lie near the tangent plane, projected orthographically
/// into the frame; each point takes the front-facing triangle containing it nearest the plane.
fn flatten_surface(
    surface: &Surface,
    seed: u32,
    f: &Frame,
    size: usize,
    sc: &mut FlatScratch,
    out: &mut [(u32, [f32; 3])],
) {
    let ri = (size / 2) as i32;
    let reach = ri as f32 + 1.0;
    let zmax = f.h * (size as f32 + 2.0);
    let inv_h = 1.0 / f.h;
    sc.stamp = sc.stamp.wrapping_add(1);
    if sc.stamp == 0 {
        sc.fstamp.iter_mut().for_each(|x| *x = 0);
        sc.stamp = 1;
    }
    let stamp = sc.stamp;
    out.fill((u32::MAX, [0.0; 3]));
    sc.depth.clear();
    sc.depth.resize(size * size, f32::INFINITY);
    sc.queue.clear();
    sc.queue.push(seed);
    sc.fstamp[seed as usize] = stamp;
    let mut head = 0;
    const MAX_PATCH: usize = 20_000;
    while head < sc.queue.len() && head < MAX_PATCH {
        let fi = sc.queue[head];
        head += 1;
        let face = surface.faces[fi as usize];
        let mut uv = [Vec2::ZERO; 3];
        let mut z = [0.0f32; 3];
        for k in 0..3 {
            let d = Vec3::from(surface.positions[face[k] as usize]) - f.c;
            uv[k] = Vec2::new(d.dot(f.s), d.dot(f.t)) * inv_h;
            z[k] = d.dot(f.n);
        }
        let lo = uv[0].min(uv[1]).min(uv[2]);
        let hi = uv[0].max(uv[1]).max(uv[2]);
        let zmin = z[0].abs().min(z[1].abs()).min(z[2].abs());
        let meets = lo.x <= reach && hi.x >= -reach && lo.y <= reach && hi.y >= -reach;
        if head > 1 && !(meets && zmin <= zmax) {
            continue;
        }
        for &g in surface.face_adj.row(fi as usize) {
            if sc.fstamp[g as usize] != stamp {
                sc.fstamp[g as usize] = stamp;
                sc.queue.push(g);
            }
        }
        splat_template(&uv, &z, size, &mut sc.depth, |t, b| {
            out[t] = (fi, b.map(|x| x.max(0.0)));
        });
    }
}

/// Stencils of every sample of `level` (on `grid`) read from the texels of `read` (the same
/// level, or the next coarser one for parent neighbourhoods), through the surface.
fn texel_stencils(
    surface: &Surface,
    grid: &TexelGrid,
    level: &Level,
    dirs: &[[f32; 3]],
    read: (&TexelGrid, &Level),
    h: f32,
    size: usize,
) -> Stencils {
    let per = size * size;
    let mut taps = vec![UNCOVERED; level.num_vertices() * per];
    let (rgrid, rlevel) = read;
    const BLOCK: usize = 256;
    taps.par_chunks_mut(per * BLOCK).enumerate().for_each_init(
        || {
            (
                FlatScratch {
                    fstamp: vec![0; surface.faces.len()],
                    stamp: 0,
                    queue: Vec::new(),
                    depth: Vec::new(),
                },
                vec![(u32::MAX, [0.0f32; 3]); per],
            )
        },
        |(sc, flat), (b, block)| {
            for (i, out) in block.chunks_mut(per).enumerate() {
                let v = b * BLOCK + i;
                let n = Vec3::from(level.normals[v]);
                let s = Vec3::from(dirs[v]);
                let frame = Frame {
                    c: Vec3::from(level.positions[v]),
                    s,
                    t: n.cross(s),
                    n,
                    h,
                };
                flatten_surface(surface, grid.hit[v].0, &frame, size, sc, flat);
                for (o, &(f, bary)) in out.iter_mut().zip(flat.iter()) {
                    if f == u32::MAX {
                        continue;
                    }
                    let uv = surface.uv(f, bary);
                    let p = surface.point(f, bary);
                    let len = surface.uv_scale[f as usize] / rgrid.side as f32;
                    *o = rgrid.taps_at(uv, p, len, &rlevel.positions);
                }
            }
        },
    );
    Stencils { per, taps }
}

/// Synthesize the exemplar's texture into the target's texture space (see the module doc):
/// the result is the target with a `texture_size²` texture through its UVs, or through an atlas
/// generated for it. Emits progress (partial results are texels, so they go out as progress
/// only) and honours `cancel`.
pub fn synthesize_texture(
    input: &TextureInput,
    params: &TextureParams,
    sink: &dyn Fn(Event),
    cancel: &CancelToken,
) -> Result<TextureOutput> {
    let total = Stopwatch::start();
    let mut timings = TextureTimings::default();
    let target = input.target;
    let scale = check_texture_input(input, params)?;

    // ---- the UV layout, the working density and exemplar, the texel levels
    let clock = Stopwatch::start();
    let (mut mesh, atlas, atlas_reason) = texture_layout(target, params, cancel)?;
    let uvs = mesh.uvs.clone().expect("UVs set above");
    let surface = Surface::new(&mesh, &uvs);
    let density = working_density(&surface, &mesh, input, params, scale)?;
    let (side, spacing) = (density.side, density.spacing);
    let ex = working_exemplar(input, &params.synth, density.exemplar_width)?;
    let sp = &ex.params;
    let (grids, levels) = texel_levels(&surface, side, sp.levels, cancel)?;
    let carried = carried_field(input, sp.orientation, &grids[0], cancel)?;
    timings.prepare = clock.secs();
    sink(Event::StageTime("prepare", timings.prepare));
    cancel.check()?;

    // ---- synthesis: partial results are texels, passed on as progress
    let relay = |e: Event| match e {
        Event::Partial { progress, .. } => sink(Event::Progress(progress)),
        e => sink(e),
    };
    let out: LevelsOut = synthesize_levels(
        &levels,
        carried.as_deref(),
        &ex.imgs,
        ex.alphas.as_deref(),
        spacing,
        sp,
        &total,
        &|k, dirs, h, size, parent| {
            let read = if parent { k + 1 } else { k };
            texel_stencils(
                &surface,
                &grids[k],
                &levels[k],
                dirs,
                (&grids[read], &levels[read]),
                h,
                size,
            )
        },
        &relay,
        cancel,
    )?;
    timings.orientation = out.orientation_secs;
    timings.neighbourhoods = out.neighbourhood_secs;
    timings.search = out.search_secs;

    // ---- magnify into the output texture from the full-resolution exemplar
    let clock = Stopwatch::start();
    let size = params.texture_size as usize;
    let (pixels, covered) = magnify(
        &surface,
        &uvs,
        (&grids[0], &levels[0]),
        &out,
        &ex,
        spacing,
        size,
    );
    set_texture(&mut mesh, size, pixels, covered);
    timings.magnify = clock.secs();
    sink(Event::StageTime("magnify", timings.magnify));
    timings.total = total.secs();
    Ok(TextureOutput {
        mesh,
        atlas,
        atlas_reason,
        working_size: side as u32,
        level_texels: levels.iter().map(|l| l.num_vertices()).collect(),
        level_energy: out.level_energy,
        working_exemplar_width: ex.working.width(),
        spacing,
        orientation_used: sp.orientation,
        anisotropy: ex.anisotropy,
        timings,
    })
}

/// Refuse what texture-space synthesis cannot do (a displacement, sizes out of range, a field
/// of the wrong length, a texture that would not fit in memory, a flat target); the scale the
/// synthesis runs at (`scale`, or a quarter of the target's diagonal).
fn check_texture_input(input: &TextureInput, params: &TextureParams) -> Result<f32> {
    let sp = &params.synth;
    let target = input.target;
    if sp.displace {
        return Err(Error::InvalidInput(
            "a displacement changes the geometry: it cannot be synthesized into a texture".into(),
        ));
    }
    validate(target, input.exemplar.dimensions(), sp.levels)?;
    let nv = target.num_vertices();
    if !(16..=8192).contains(&params.texture_size) {
        return Err(Error::InvalidInput(format!(
            "texture size must be between 16 and 8192, got {}",
            params.texture_size
        )));
    }
    if params.texel_budget < 1000 {
        return Err(Error::InvalidInput(format!(
            "texel budget must be at least 1000, got {}",
            params.texel_budget
        )));
    }
    if let Some(f) = input.field
        && f.len() != nv
    {
        return Err(Error::InvalidInput(format!(
            "orientation field has {} entries, the target has {nv} vertices",
            f.len()
        )));
    }
    check_texture_memory(params.texture_size)?;
    super::surface_scale(target, sp.scale)
}

/// Refuses an output texture of `size²` texels that does not fit in memory: its texel hits
/// (20 bytes), colours, coverage, pull-push pyramid and 8-bit copy.
pub(super) fn check_texture_memory(size: u32) -> Result<()> {
    crate::work::check_memory(
        (size as u64).pow(2).saturating_mul(64),
        &format!("a {size}x{size} texture"),
        "use a smaller --texture-size",
    )
}

/// The working texture's size and the exemplar's working width.
struct Density {
    /// Side of the working (synthesized) texture.
    side: usize,
    /// Surface units per working texel.
    spacing: f32,
    /// Width the exemplar is shrunk to, one pixel per texel.
    exemplar_width: u32,
}

/// Working density: one texel per exemplar pixel, within the budget and the output, and no
/// coarser than the pyramid needs; refuses a working texture that would not fit in memory.
fn working_density(
    surface: &Surface,
    mesh: &TriMesh,
    input: &TextureInput,
    params: &TextureParams,
    scale: f32,
) -> Result<Density> {
    let nlev = params.synth.levels;
    let (ew, eh) = input.exemplar.dimensions();
    let min_side = ((4u32 << (nlev - 1)).max(8)) as f64;
    let uv_area = surface.uv_area().clamp(1e-6, 1.0);
    let area = mesh.area().max(1e-30);
    let align = 1usize << (nlev - 1);
    let h_full = scale as f64 / ew as f64;
    let want = area / (h_full * h_full); // samples at the exemplar's own resolution
    let texels = want.min(params.texel_budget as f64);
    let side_for = |n: f64| (n / uv_area).sqrt();
    let mut side = side_for(texels).min(params.texture_size as f64);
    // the exemplar may not shrink below what the pyramid needs
    let texel_len = |side: f64| (area / (uv_area * side * side)).sqrt();
    let min_width = min_side * ew as f64 / ew.min(eh) as f64;
    if scale as f64 / texel_len(side) < min_width {
        side = (side * min_width * texel_len(side) / scale as f64).min(params.texture_size as f64);
    }
    let side = ((side.ceil() as usize).div_ceil(align) * align).max(align * 4);
    let spacing = texel_len(side as f64) as f32;
    let work_w = ((scale / spacing).round() as u32).clamp(1, ew);
    let work_h = ((eh as f64 * work_w as f64 / ew as f64).round() as u32).max(1);
    if work_w.min(work_h) < min_side as u32 {
        return Err(Error::InvalidInput(format!(
            "at scale {scale} the exemplar would shrink to {work_w}x{work_h} pixels, too small \
             for {nlev} levels: use a larger scale or a larger texture size"
        )));
    }
    let expected = uv_area * (side * side) as f64;
    let working = expected as u64;
    crate::work::check_memory(
        working.saturating_mul(6 << 10),
        &format!("{working} synthesized texels"),
        "use a smaller --texel-budget",
    )?;
    Ok(Density {
        side,
        spacing,
        exemplar_width: work_w,
    })
}

/// The exemplar as the synthesis reads it.
struct WorkingExemplar {
    /// Shrunk to the working density.
    working: image::RgbImage,
    /// Its measured anisotropy, when the orientation is `Auto`.
    anisotropy: Option<Anisotropy>,
    /// The synthesis parameters with `Auto` resolved.
    params: SynthParams,
    /// Its image pyramid (transparent pixels filled).
    imgs: Vec<Img>,
    /// The alpha's pyramid, if it has one.
    alphas: Option<Vec<Img>>,
    /// The full-resolution exemplar the output reads, holes filled.
    full: Img,
}

/// The exemplar shrunk to `work_w` pixels wide, its pyramids, the orientation `Auto` resolves
/// to, and the full-resolution image the output is magnified from.
fn working_exemplar(
    input: &TextureInput,
    sp: &SynthParams,
    work_w: u32,
) -> Result<WorkingExemplar> {
    let nlev = sp.levels;
    let work_ex = super::shrink_exemplar(input.exemplar.clone(), work_w);
    let work_alpha = input
        .alpha
        .map(|a| super::resize_alpha(a.clone(), work_ex.width(), work_ex.height()));
    // `Auto`: the field the exemplar's anisotropy asks for, measured at the working scale as
    // the surface synthesis measures it
    let anis = (sp.orientation == Orientation::Auto)
        .then(|| anisotropy::exemplar_anisotropy(&work_ex, work_alpha.as_ref()));
    let sp = SynthParams {
        orientation: anis.map_or(sp.orientation, anisotropy::choose_orientation),
        ..sp.clone()
    };
    let (imgs, alphas) = super::exemplar_pyramids(&work_ex, work_alpha.as_ref(), nlev)?;
    // the full-resolution exemplar the output reads, holes filled
    let full = match input.alpha {
        None => Img::from_rgb(input.exemplar),
        Some(a) => transparent_filled(input.exemplar, a)?.0,
    };
    Ok(WorkingExemplar {
        working: work_ex,
        anisotropy: anis,
        params: sp,
        imgs,
        alphas,
        full,
    })
}

/// The texel grids of every level (side halved per level) and their sample levels, each linked
/// to its parent level.
fn texel_levels(
    surface: &Surface,
    side: usize,
    nlev: usize,
    cancel: &CancelToken,
) -> Result<(Vec<TexelGrid>, Vec<Level>)> {
    let mut grids: Vec<TexelGrid> = Vec::with_capacity(nlev);
    let mut levels: Vec<Level> = Vec::with_capacity(nlev);
    for k in 0..nlev {
        let g = TexelGrid::new(surface, (side >> k).max(1));
        if g.hit.is_empty() {
            return Err(Error::InvalidMesh(
                "the target's UV layout covers no texel (degenerate UVs)".into(),
            ));
        }
        levels.push(texel_level(surface, &g));
        grids.push(g);
        cancel.check()?;
    }
    for k in 0..nlev - 1 {
        let p = texel_parents(
            surface,
            &grids[k],
            &levels[k],
            &grids[k + 1],
            &levels[k + 1],
        );
        levels[k].parent = p;
    }
    Ok((grids, levels))
}

/// The orientation field (the input's, or the curve-guided one `Features` asks for) carried
/// onto the finest texels; `None` where the orientation needs none.
fn carried_field(
    input: &TextureInput,
    orientation: Orientation,
    grid: &TexelGrid,
    cancel: &CancelToken,
) -> Result<Option<Vec<[f32; 3]>>> {
    let target = input.target;
    let field_computed;
    let field = match (input.field, orientation) {
        (Some(f), _) => Some(f),
        (None, Orientation::Features) => {
            field_computed = feature_field(target, cancel)?;
            Some(&field_computed[..])
        }
        _ => None,
    };
    Ok(field.map(|f| {
        grid.hit
            .iter()
            .map(|&(fi, b)| {
                let face = target.faces[fi as usize];
                (0..3)
                    .fold(Vec3::ZERO, |acc, k| {
                        acc + b[k] * Vec3::from(f[face[k] as usize])
                    })
                    .to_array()
            })
            .collect()
    }))
}

/// The output texture (`size²`) magnified from the full-resolution exemplar: every covered
/// texel reads the exemplar at its finest texels' synthesized coordinates, offset by its
/// distance from them; the colours and the coverage.
fn magnify(
    surface: &Surface,
    uvs: &[[f32; 2]],
    (g0, l0): (&TexelGrid, &Level),
    out: &LevelsOut,
    ex: &WorkingExemplar,
    spacing: f32,
    size: usize,
) -> (Vec<[f32; 3]>, Vec<bool>) {
    let full = &ex.full;
    let out_texels = crate::geometry::uv_texels(uvs, surface.faces.len(), size, size);
    let (sx, sy) = (
        full.w as f32 / ex.working.width() as f32,
        full.h as f32 / ex.working.height() as f32,
    );
    let ex0 = &out.exemplar;
    let pixels: Vec<[f32; 3]> = out_texels
        .par_iter()
        .map(|t| {
            let Some((f, b)) = *t else {
                return [0.0; 3];
            };
            if !surface.uv_scale[f as usize].is_finite() {
                return [0.0; 3];
            }
            let uv = surface.uv(f, b);
            let p = surface.point(f, b);
            let len = surface.uv_scale[f as usize] / g0.side as f32;
            let tap = g0.taps_at(uv, p, len, &l0.positions);
            if tap.idx[0] == u32::MAX {
                return ex0.mean;
            }
            let mut c = [0.0f32; 3];
            for k in 0..3 {
                if tap.w[k] <= 0.0 {
                    continue;
                }
                let s = tap.idx[k] as usize;
                let col = if out.sources[s] == u32::MAX {
                    out.colors[s]
                } else {
                    let (x, y) = ex0.pixel(out.sources[s]);
                    let n = Vec3::from(l0.normals[s]);
                    let d = p - Vec3::from(l0.positions[s]);
                    let ds = Vec3::from(out.dirs[s]);
                    let dt = n.cross(ds);
                    let ex = x as f32 + d.dot(ds) / spacing;
                    let ey = y as f32 - d.dot(dt) / spacing;
                    full.bilinear((ex + 0.5) * sx - 0.5, (ey + 0.5) * sy - 0.5)
                };
                for ch in 0..3 {
                    c[ch] += tap.w[k] * col[ch];
                }
            }
            c
        })
        .collect();
    let covered: Vec<bool> = out_texels.iter().map(|t| t.is_some()).collect();
    (pixels, covered)
}
