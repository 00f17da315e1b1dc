//! Mesh and image pyramids for surface texture synthesis (Wei & Levoy 2001, §3.1 "retiling"):
//! a uniform-density finest mesh, coarser levels with about a quarter of the vertices each, and a
//! Gaussian image pyramid of the exemplar.

use std::collections::HashMap;

use glam::Vec3;
use rand::{Rng, SeedableRng, rngs::SmallRng};

use crate::error::{Error, Result};
use crate::mesh::{Csr, vertex_adjacency, vertex_faces};

/// One level of the mesh pyramid.
#[derive(Clone, Debug)]
pub(crate) struct Level {
    /// Vertex positions.
    pub positions: Vec<[f32; 3]>,
    /// Triangles (coarse levels may contain slivers; they are only sampled, never exported).
    pub faces: Vec<[u32; 3]>,
    /// Unit vertex normals.
    pub normals: Vec<[f32; 3]>,
    /// Vertex-vertex adjacency.
    pub adj: Csr,
    /// Vertex-face incidence.
    pub vf: Csr,
    /// For every vertex, its parent vertex on the next coarser level (empty on the coarsest).
    pub parent: Vec<u32>,
    /// Fixed colour (a vertex outside the synthesis mask), `None` = synthesize.
    pub fixed: Vec<Option<[f32; 3]>>,
}

impl Level {
    pub fn new(
        positions: Vec<[f32; 3]>,
        faces: Vec<[u32; 3]>,
        normals: Vec<[f32; 3]>,
        fixed: Vec<Option<[f32; 3]>>,
    ) -> Level {
        let n = positions.len();
        let adj = vertex_adjacency(n, &faces);
        let vf = vertex_faces(n, &faces);
        Level {
            positions,
            faces,
            normals,
            adj,
            vf,
            parent: Vec::new(),
            fixed,
        }
    }

    pub fn num_vertices(&self) -> usize {
        self.positions.len()
    }

    /// Mean triangle area (used for the paper's template spacing `d = sqrt(2 A)`).
    pub fn mean_face_area(&self) -> f64 {
        if self.faces.is_empty() {
            return 0.0;
        }
        let total: f64 = self
            .faces
            .iter()
            .map(|f| {
                let [a, b, c] = f.map(|i| Vec3::from(self.positions[i as usize]).as_dvec3());
                0.5 * (b - a).cross(c - a).length()
            })
            .sum();
        total / self.faces.len() as f64
    }
}

/// Refine a mesh until no edge is longer than `max_len` by conforming longest-edge bisection:
/// every marked edge gets its midpoint, every face is split recursively at its longest marked
/// edge (red-green refinement without closure). Original vertices keep their indices; `attr`
/// (one value per vertex) is interpolated with `mix` at new midpoints.
pub(crate) fn refine_edges<T: Clone>(
    positions: &mut Vec<[f32; 3]>,
    faces: &mut Vec<[u32; 3]>,
    attr: &mut Vec<T>,
    max_len: f32,
    max_vertices: usize,
    mix: impl Fn(&T, &T) -> T,
) -> Result<()> {
    let max2 = max_len * max_len;
    let len2 = |p: &[[f32; 3]], a: u32, b: u32| {
        Vec3::from(p[a as usize]).distance_squared(Vec3::from(p[b as usize]))
    };
    for _round in 0..64 {
        let mut mids: HashMap<(u32, u32), u32> = HashMap::new();
        for f in faces.iter() {
            for k in 0..3 {
                let (a, b) = (f[k], f[(k + 1) % 3]);
                let key = (a.min(b), a.max(b));
                if !mids.contains_key(&key) && len2(positions, a, b) > max2 {
                    let m = positions.len() as u32;
                    let pa = Vec3::from(positions[a as usize]);
                    let pb = Vec3::from(positions[b as usize]);
                    positions.push(((pa + pb) * 0.5).to_array());
                    attr.push(mix(&attr[a as usize], &attr[b as usize]));
                    mids.insert(key, m);
                }
            }
        }
        if mids.is_empty() {
            return Ok(());
        }
        if positions.len() > max_vertices {
            return Err(Error::InvalidInput(format!(
                "refining to the requested scale needs more than {max_vertices} vertices; \
                 use a larger --scale or a smaller exemplar"
            )));
        }
        let mut out = Vec::with_capacity(faces.len() * 2);
        let mut stack: Vec<[u32; 3]> = Vec::new();
        for &f in faces.iter() {
            stack.push(f);
            while let Some(f) = stack.pop() {
                // longest marked edge of this (sub)face
                let mut best: Option<(usize, f32, u32)> = None;
                for k in 0..3 {
                    let (a, b) = (f[k], f[(k + 1) % 3]);
                    if let Some(&m) = mids.get(&(a.min(b), a.max(b))) {
                        let l = len2(positions, a, b);
                        if best.is_none_or(|(_, bl, _)| l > bl) {
                            best = Some((k, l, m));
                        }
                    }
                }
                match best {
                    None => out.push(f),
                    Some((k, _, m)) => {
                        let (a, b, c) = (f[k], f[(k + 1) % 3], f[(k + 2) % 3]);
                        stack.push([a, m, c]);
                        stack.push([m, b, c]);
                    }
                }
            }
        }
        *faces = out;
    }
    Ok(())
}

/// Vertex clustering on a uniform grid (Rossignac & Borrel 1993): every vertex maps to the cell
/// of `floor((p - origin) / cell)`; a cluster's position is the mean of its members; faces whose
/// corners fall into three distinct clusters survive (duplicates removed). Returns
/// (positions, faces, parent map fine->coarse).
fn cluster(
    positions: &[[f32; 3]],
    faces: &[[u32; 3]],
    cell: f32,
    origin: Vec3,
) -> (Vec<[f32; 3]>, Vec<[u32; 3]>, Vec<u32>) {
    let mut ids: HashMap<[i32; 3], u32> = HashMap::new();
    let mut parent = Vec::with_capacity(positions.len());
    let mut acc: Vec<[f64; 4]> = Vec::new();
    for p in positions {
        let q = (Vec3::from(*p) - origin) / cell;
        let key = [q.x.floor() as i32, q.y.floor() as i32, q.z.floor() as i32];
        let next = ids.len() as u32;
        let id = *ids.entry(key).or_insert(next);
        if id as usize == acc.len() {
            acc.push([0.0; 4]);
        }
        let a = &mut acc[id as usize];
        a[0] += p[0] as f64;
        a[1] += p[1] as f64;
        a[2] += p[2] as f64;
        a[3] += 1.0;
        parent.push(id);
    }
    let pos: Vec<[f32; 3]> = acc
        .iter()
        .map(|a| {
            [
                (a[0] / a[3]) as f32,
                (a[1] / a[3]) as f32,
                (a[2] / a[3]) as f32,
            ]
        })
        .collect();
    let mut seen = std::collections::HashSet::new();
    let mut out = Vec::new();
    for f in faces {
        let g = f.map(|v| parent[v as usize]);
        if g[0] == g[1] || g[1] == g[2] || g[0] == g[2] {
            continue;
        }
        let mut key = g;
        key.sort_unstable();
        if seen.insert(key) {
            out.push(g);
        }
    }
    (pos, out, parent)
}

/// Fallback when the shared hierarchy stops early: build the next coarser level with about
/// `ratio` of the vertices of `fine` by grid clustering,
/// searching the cell size so the vertex count lands near the target. Sets `fine.parent`.
/// Coarse normals are the normalised mean of the children's normals.
pub(crate) fn coarsen(fine: &mut Level, ratio: f64, rng: &mut SmallRng) -> Level {
    let n = fine.num_vertices();
    let target = ((n as f64) * ratio).max(4.0);
    let (lo, hi) = bounds(&fine.positions);
    let diag = (hi - lo).length().max(1e-12);
    // mean edge length as the first guess: clustering at cell = 2 * edge keeps ~1/4
    let mut edge = 0.0f64;
    let mut cnt = 0usize;
    for f in fine.faces.iter().take(20000) {
        let a = Vec3::from(fine.positions[f[0] as usize]);
        let b = Vec3::from(fine.positions[f[1] as usize]);
        edge += a.distance(b) as f64;
        cnt += 1;
    }
    let mut cell = if cnt > 0 {
        (2.0 * edge / cnt as f64) as f32
    } else {
        diag * 0.1
    };
    let origin = lo - Vec3::splat(cell) * rng.random::<f32>();
    let mut best = cluster(&fine.positions, &fine.faces, cell, origin);
    for _ in 0..6 {
        let m = best.0.len() as f64;
        let err = m / target;
        if (0.8..1.25).contains(&err) {
            break;
        }
        // vertex count scales ~ 1/cell^2 on a surface
        cell *= err.sqrt().clamp(0.5, 2.0) as f32;
        let cand = cluster(&fine.positions, &fine.faces, cell, origin);
        if ((cand.0.len() as f64) / target).ln().abs() < (m / target).ln().abs() {
            best = cand;
        }
    }
    let (pos, faces, parent) = best;
    let m = pos.len();
    let mut nacc = vec![Vec3::ZERO; m];
    for (&p, nrm) in parent.iter().zip(&fine.normals) {
        nacc[p as usize] += Vec3::from(*nrm);
    }
    let normals = nacc
        .iter()
        .map(|v| v.try_normalize().unwrap_or(Vec3::Z).to_array())
        .collect();
    let fixed = aggregate_fixed(&fine.fixed, &parent, m);
    fine.parent = parent;
    Level::new(pos, faces, normals, fixed)
}

/// Fixed colours of a coarse level: a coarse vertex is fixed (outside the mask) only when all its
/// children are, with their mean colour.
pub(crate) fn aggregate_fixed(
    fine: &[Option<[f32; 3]>],
    parent: &[u32],
    m: usize,
) -> Vec<Option<[f32; 3]>> {
    let mut acc = vec![([0.0f32; 3], 0u32, 0u32); m];
    for (&p, fx) in parent.iter().zip(fine) {
        let e = &mut acc[p as usize];
        e.2 += 1;
        if let Some(c) = fx {
            e.0[0] += c[0];
            e.0[1] += c[1];
            e.0[2] += c[2];
            e.1 += 1;
        }
    }
    acc.iter()
        .map(|(c, k, all)| (*k == *all && *k > 0).then(|| c.map(|x| x / *k as f32)))
        .collect()
}

fn bounds(p: &[[f32; 3]]) -> (Vec3, Vec3) {
    let mut lo = Vec3::splat(f32::INFINITY);
    let mut hi = Vec3::splat(f32::NEG_INFINITY);
    for q in p {
        lo = lo.min(Vec3::from(*q));
        hi = hi.max(Vec3::from(*q));
    }
    (lo, hi)
}

/// A float RGB image (sRGB values in [0,1]), row-major, row 0 at the top.
#[derive(Clone, Debug)]
pub(crate) struct Img {
    pub w: usize,
    pub h: usize,
    pub px: Vec<[f32; 3]>,
}

impl Img {
    pub fn from_rgb(img: &image::RgbImage) -> Img {
        Img {
            w: img.width() as usize,
            h: img.height() as usize,
            px: img
                .pixels()
                .map(|p| p.0.map(|c| c as f32 / 255.0))
                .collect(),
        }
    }

    #[inline]
    pub fn at(&self, x: isize, y: isize) -> [f32; 3] {
        let x = x.clamp(0, self.w as isize - 1) as usize;
        let y = y.clamp(0, self.h as isize - 1) as usize;
        self.px[y * self.w + x]
    }

    /// Bilinear lookup at continuous pixel coordinates (pixel centres at integers), clamped.
    pub fn bilinear(&self, x: f32, y: f32) -> [f32; 3] {
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let (xi, yi) = (x0 as isize, y0 as isize);
        let (a, b, c, d) = (
            self.at(xi, yi),
            self.at(xi + 1, yi),
            self.at(xi, yi + 1),
            self.at(xi + 1, yi + 1),
        );
        let mut o = [0.0; 3];
        for k in 0..3 {
            o[k] =
                (a[k] * (1.0 - fx) + b[k] * fx) * (1.0 - fy) + (c[k] * (1.0 - fx) + d[k] * fx) * fy;
        }
        o
    }

    pub fn mean(&self) -> [f32; 3] {
        let mut s = [0.0f64; 3];
        for p in &self.px {
            for k in 0..3 {
                s[k] += p[k] as f64;
            }
        }
        let n = self.px.len().max(1) as f64;
        s.map(|x| (x / n) as f32)
    }

    /// The image smoothed by the separable binomial [1 4 6 4 1] / 16 (a Gaussian of one
    /// pixel), its border clamped.
    pub fn binomial_smoothed(&self) -> Img {
        const K: [f32; 5] = [1.0 / 16.0, 4.0 / 16.0, 6.0 / 16.0, 4.0 / 16.0, 1.0 / 16.0];
        let pass = |img: &Img, dx: isize, dy: isize| -> Vec<[f32; 3]> {
            (0..img.w * img.h)
                .map(|i| {
                    let (x, y) = ((i % img.w) as isize, (i / img.w) as isize);
                    let mut o = [0.0f32; 3];
                    for (t, k) in K.iter().enumerate() {
                        let d = t as isize - 2;
                        let p = img.at(x + d * dx, y + d * dy);
                        for c in 0..3 {
                            o[c] += k * p[c];
                        }
                    }
                    o
                })
                .collect()
        };
        let rows = Img {
            w: self.w,
            h: self.h,
            px: pass(self, 1, 0),
        };
        Img {
            w: self.w,
            h: self.h,
            px: pass(&rows, 0, 1),
        }
    }

    /// Half-resolution Gaussian level: separable [1 3 3 1]/8 filter centred between pixel pairs,
    /// so level-(k+1) pixel X sits at level-k coordinate 2X + 1/2.
    pub fn downsample(&self) -> Img {
        let (w2, h2) = (self.w.div_ceil(2).max(1), self.h.div_ceil(2).max(1));
        const K: [f32; 4] = [1.0 / 8.0, 3.0 / 8.0, 3.0 / 8.0, 1.0 / 8.0];
        let mut tmp = vec![[0.0f32; 3]; w2 * self.h];
        for y in 0..self.h {
            for x in 0..w2 {
                let mut o = [0.0; 3];
                for (t, k) in K.iter().enumerate() {
                    let p = self.at(2 * x as isize - 1 + t as isize, y as isize);
                    for c in 0..3 {
                        o[c] += k * p[c];
                    }
                }
                tmp[y * w2 + x] = o;
            }
        }
        let mut px = vec![[0.0f32; 3]; w2 * h2];
        for y in 0..h2 {
            for x in 0..w2 {
                let mut o = [0.0; 3];
                for (t, k) in K.iter().enumerate() {
                    let yy =
                        (2 * y as isize - 1 + t as isize).clamp(0, self.h as isize - 1) as usize;
                    let p = tmp[yy * w2 + x];
                    for c in 0..3 {
                        o[c] += k * p[c];
                    }
                }
                px[y * w2 + x] = o;
            }
        }
        Img { w: w2, h: h2, px }
    }
}

/// Gaussian pyramid, index 0 = finest.
pub(crate) fn image_pyramid(img: Img, levels: usize) -> Vec<Img> {
    let mut out = vec![img];
    while out.len() < levels {
        let next = out.last().expect("non-empty").downsample();
        out.push(next);
    }
    out
}

/// A seeded RNG for a named stage, so stages stay deterministic independently of each other.
pub(crate) fn stage_rng(seed: u64, stage: u64) -> SmallRng {
    SmallRng::seed_from_u64(seed ^ stage.wrapping_mul(0x9E37_79B9_7F4A_7C15))
}
