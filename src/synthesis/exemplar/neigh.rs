//! Neighbourhoods (Wei & Levoy 2001 §3.3): mesh neighbourhoods by flattening the local patch into
//! the vertex's texture frame and resampling it on the template grid, and the matching exemplar
//! neighbourhoods of every pyramid level.

use glam::{Vec2, Vec3};
use rayon::prelude::*;

use super::pyramid::{Img, Level};

/// One template sample: barycentric interpolation of three vertex values; `idx[0] == u32::MAX`
/// marks a sample the flattened patch does not cover (it reads the exemplar's mean colour).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Tap {
    pub idx: [u32; 3],
    pub w: [f32; 3],
}

pub(crate) const UNCOVERED: Tap = Tap {
    idx: [u32::MAX; 3],
    w: [0.0; 3],
};

/// Precomputed resampling stencils: `taps[v * per + t]` is template sample `t` (row-major, rows
/// going down the image) of vertex `v`.
#[derive(Clone, Debug, Default)]
pub(crate) struct Stencils {
    pub per: usize,
    pub taps: Vec<Tap>,
}

impl Stencils {
    #[inline]
    pub fn of(&self, v: usize) -> &[Tap] {
        &self.taps[v * self.per..(v + 1) * self.per]
    }

    /// Resample per-vertex colours into a feature vector (3 floats per sample).
    #[inline]
    pub fn gather(&self, v: usize, colors: &[[f32; 3]], default: [f32; 3], out: &mut [f32]) {
        for (t, tap) in self.of(v).iter().enumerate() {
            let c = if tap.idx[0] == u32::MAX {
                default
            } else {
                let mut c = [0.0f32; 3];
                for k in 0..3 {
                    let x = colors[tap.idx[k] as usize];
                    c[0] += tap.w[k] * x[0];
                    c[1] += tap.w[k] * x[1];
                    c[2] += tap.w[k] * x[2];
                }
                c
            };
            out[3 * t..3 * t + 3].copy_from_slice(&c);
        }
    }
}

/// Reusable per-thread buffers for patch flattening.
pub(crate) struct Scratch {
    vstamp: Vec<u32>,
    fstamp: Vec<u32>,
    stamp: u32,
    queue: Vec<u32>,
    faces: Vec<u32>,
    depth: Vec<f32>,
}

impl Scratch {
    pub fn new(level: &Level) -> Scratch {
        Scratch {
            vstamp: vec![0; level.num_vertices()],
            fstamp: vec![0; level.faces.len()],
            stamp: 0,
            queue: Vec::new(),
            faces: Vec::new(),
            depth: Vec::new(),
        }
    }
}

/// The frame of a neighbourhood: centre, texture right `s`, texture up `t`, normal `n`, and the
/// template spacing `h` in mesh units.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Frame {
    pub c: Vec3,
    pub s: Vec3,
    pub t: Vec3,
    pub n: Vec3,
    pub h: f32,
}

/// Flatten the patch of `mesh` around `seed` orthographically into `frame` (the seed triangles'
/// projection of Wei & Levoy §3.3, applied to the whole patch: vertices within the template's
/// reach, grown breadth-first from `seed`), then resample the `size x size` template at grid
/// points `c + h (i s - j t)`: each point takes the front-facing flattened triangle containing it
/// (the one nearest the tangent plane where several overlap). Back-facing (flipped) triangles
/// are skipped; uncovered points get `UNCOVERED`.
pub(crate) fn build_stencil(
    mesh: &Level,
    seed: u32,
    f: &Frame,
    size: usize,
    sc: &mut Scratch,
    out: &mut [Tap],
) {
    // a vertex grows the patch while its flattened position lies within the template square
    // widened by a margin of 1.5 texels (so covering triangles are found), and near the tangent
    // plane (which keeps the far side of thin parts out)
    let box_half = (size / 2) as f32 + 1.5;
    let zmax = f.h * (size as f32 + 2.0);
    let inv_h = 1.0 / f.h;
    sc.stamp = sc.stamp.wrapping_add(1);
    if sc.stamp == 0 {
        sc.vstamp.iter_mut().for_each(|x| *x = 0);
        sc.fstamp.iter_mut().for_each(|x| *x = 0);
        sc.stamp = 1;
    }
    let stamp = sc.stamp;
    sc.queue.clear();
    sc.faces.clear();
    sc.queue.push(seed);
    sc.vstamp[seed as usize] = stamp;
    let mut head = 0;
    const MAX_PATCH: usize = 20_000;
    while head < sc.queue.len() && sc.queue.len() < MAX_PATCH {
        let v = sc.queue[head] as usize;
        head += 1;
        for &fi in mesh.vf.row(v) {
            if sc.fstamp[fi as usize] != stamp {
                sc.fstamp[fi as usize] = stamp;
                sc.faces.push(fi);
            }
        }
        let d = Vec3::from(mesh.positions[v]) - f.c;
        let inside = (d.dot(f.s) * inv_h).abs() <= box_half
            && (d.dot(f.t) * inv_h).abs() <= box_half
            && d.dot(f.n).abs() <= zmax;
        if !inside && head > 1 {
            continue;
        }
        for &q in mesh.adj.row(v) {
            if sc.vstamp[q as usize] != stamp {
                sc.vstamp[q as usize] = stamp;
                sc.queue.push(q);
            }
        }
    }
    out.fill(UNCOVERED);
    sc.depth.clear();
    sc.depth.resize(size * size, f32::INFINITY);
    for &fi in &sc.faces {
        let face = mesh.faces[fi as usize];
        let mut uv = [Vec2::ZERO; 3];
        let mut z = [0.0f32; 3];
        for k in 0..3 {
            let d = Vec3::from(mesh.positions[face[k] as usize]) - f.c;
            uv[k] = Vec2::new(d.dot(f.s), d.dot(f.t)) * inv_h;
            z[k] = d.dot(f.n);
        }
        splat_template(&uv, &z, size, &mut sc.depth, |t, b| {
            out[t] = Tap { idx: face, w: b };
        });
    }
}

/// Rasterise the template points (`size x size`, point (i, j) at flattened uv = (i, -j), in
/// template units) that fall inside one flattened triangle `uv` with heights `z` over the
/// tangent plane: each covered point whose |height| is below `depth[t]` takes it and is passed
/// to `set(t, barycentric)`. Back-facing and degenerate triangles cover nothing.
pub(crate) fn splat_template(
    uv: &[Vec2; 3],
    z: &[f32; 3],
    size: usize,
    depth: &mut [f32],
    mut set: impl FnMut(usize, [f32; 3]),
) {
    let ri = (size / 2) as i32;
    let e1 = uv[1] - uv[0];
    let e2 = uv[2] - uv[0];
    let area = e1.perp_dot(e2);
    if area <= 1e-9 {
        return; // flipped or degenerate after flattening
    }
    let lo = uv[0].min(uv[1]).min(uv[2]);
    let hi = uv[0].max(uv[1]).max(uv[2]);
    let i0 = fast_ceil(lo.x).max(-ri);
    let i1 = fast_floor(hi.x).min(ri);
    let j0 = fast_ceil(-hi.y).max(-ri);
    let j1 = fast_floor(-lo.y).min(ri);
    for j in j0..=j1 {
        for i in i0..=i1 {
            let p = Vec2::new(i as f32, -j as f32) - uv[0];
            let b1 = p.perp_dot(e2) / area;
            let b2 = e1.perp_dot(p) / area;
            let b0 = 1.0 - b1 - b2;
            const EPS: f32 = -1e-4;
            if b0 < EPS || b1 < EPS || b2 < EPS {
                continue;
            }
            let t = ((j + ri) as usize) * size + (i + ri) as usize;
            let d = (b0 * z[0] + b1 * z[1] + b2 * z[2]).abs();
            if d < depth[t] {
                depth[t] = d;
                set(t, [b0, b1, b2]);
            }
        }
    }
}

/// `ceil` for values well inside the i32 range (clamped), without a libm call.
#[inline]
fn fast_ceil(x: f32) -> i32 {
    let x = x.clamp(-1e6, 1e6);
    let t = x as i32;
    if (t as f32) < x { t + 1 } else { t }
}

/// `floor` for values well inside the i32 range (clamped), without a libm call.
#[inline]
fn fast_floor(x: f32) -> i32 {
    let x = x.clamp(-1e6, 1e6);
    let t = x as i32;
    if (t as f32) > x { t - 1 } else { t }
}

/// Stencils for every vertex of `level` sampled on `mesh` (the level itself, or the next coarser
/// level for parent neighbourhoods, seeded at each vertex's parent), in the vertex's own frame.
pub(crate) fn build_stencils(
    level: &Level,
    dirs: &[[f32; 3]],
    mesh: &Level,
    seeds: Option<&[u32]>,
    h: f32,
    size: usize,
) -> Stencils {
    let per = size * size;
    let mut taps = vec![UNCOVERED; level.num_vertices() * per];
    const BLOCK: usize = 512;
    taps.par_chunks_mut(per * BLOCK)
        .enumerate()
        .for_each(|(b, block)| {
            let mut sc = Scratch::new(mesh);
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
                let seed = seeds.map_or(v as u32, |m| m[v]);
                build_stencil(mesh, seed, &frame, size, &mut sc, out);
            }
        });
    Stencils { per, taps }
}

/// Exemplar neighbourhoods of one pyramid level: for every candidate pixel (those whose
/// neighbourhoods stay inside the image, margin `m`), the current-level `size x size` window and
/// the parent-level `psize x psize` window (bilinear at the parent coordinate `(x + 1/2)/2 - 1/2`).
#[derive(Clone, Debug)]
pub(crate) struct ExemplarLevel {
    pub img: Img,
    pub mean: [f32; 3],
    pub m: usize,
    pub cw: usize,
    pub ch: usize,
    pub size: usize,
    pub psize: usize,
    pub cur: Vec<f32>,
    pub par: Vec<f32>,
    /// Candidates whose centre pixel is opaque (alpha >= 1/2), when the exemplar has
    /// transparent pixels: the others are never chosen.
    pub opaque: Option<Vec<bool>>,
    /// The opaque candidates, for random picks.
    pub opaque_list: Vec<u32>,
}

impl ExemplarLevel {
    pub fn new(img: &Img, parent: Option<&Img>, size: usize, psize: usize) -> ExemplarLevel {
        let r = size / 2;
        let rp = if parent.is_some() { psize / 2 } else { 0 };
        let want = r.max(2 * rp + 1);
        let m = want.min((img.w.min(img.h) - 1) / 2);
        let cw = img.w - 2 * m;
        let ch = img.h - 2 * m;
        let dc = 3 * size * size;
        let dp = if parent.is_some() {
            3 * psize * psize
        } else {
            0
        };
        let n = cw * ch;
        let mut cur = vec![0.0f32; n * dc];
        let mut par = vec![0.0f32; n * dp];
        cur.par_chunks_mut(dc.max(1))
            .enumerate()
            .for_each(|(c, out)| {
                let (x, y) = ((c % cw + m) as isize, (c / cw + m) as isize);
                let ri = r as isize;
                let mut t = 0;
                for j in -ri..=ri {
                    for i in -ri..=ri {
                        out[3 * t..3 * t + 3].copy_from_slice(&img.at(x + i, y + j));
                        t += 1;
                    }
                }
            });
        if let Some(pimg) = parent {
            par.par_chunks_mut(dp).enumerate().for_each(|(c, out)| {
                let (x, y) = ((c % cw + m) as f32, (c / cw + m) as f32);
                let (px, py) = ((x + 0.5) * 0.5 - 0.5, (y + 0.5) * 0.5 - 0.5);
                let ri = (psize / 2) as i32;
                let mut t = 0;
                for j in -ri..=ri {
                    for i in -ri..=ri {
                        let v = pimg.bilinear(px + i as f32, py + j as f32);
                        out[3 * t..3 * t + 3].copy_from_slice(&v);
                        t += 1;
                    }
                }
            });
        }
        ExemplarLevel {
            img: img.clone(),
            mean: img.mean(),
            m,
            cw,
            ch,
            size,
            psize: if parent.is_some() { psize } else { 0 },
            cur,
            par,
            opaque: None,
            opaque_list: Vec::new(),
        }
    }

    /// Exclude candidates whose centre pixel has alpha (grey in `alpha`, this level's size)
    /// under one half. A level with no opaque candidate keeps all (a coarse level of a sparse
    /// exemplar; its colours are the pull-push fill, never the hole colour).
    pub fn restrict_to_opaque(&mut self, alpha: &Img) {
        let opaque: Vec<bool> = (0..self.num_candidates() as u32)
            .map(|c| {
                let (x, y) = self.pixel(c);
                alpha.px[y * alpha.w + x][0] >= 0.5
            })
            .collect();
        let list: Vec<u32> = (0..opaque.len() as u32)
            .filter(|&c| opaque[c as usize])
            .collect();
        if !list.is_empty() {
            self.opaque = Some(opaque);
            self.opaque_list = list;
        }
    }

    /// Whether candidate `c` may be chosen.
    #[inline]
    pub fn allowed(&self, c: u32) -> bool {
        self.opaque.as_ref().is_none_or(|o| o[c as usize])
    }

    /// A uniformly random allowed candidate.
    pub fn random_candidate(&self, rng: &mut impl rand::Rng) -> u32 {
        if self.opaque.is_some() {
            self.opaque_list[rng.random_range(0..self.opaque_list.len())]
        } else {
            rng.random_range(0..self.num_candidates() as u32)
        }
    }

    pub fn num_candidates(&self) -> usize {
        self.cw * self.ch
    }
    pub fn dim_cur(&self) -> usize {
        3 * self.size * self.size
    }
    pub fn dim_par(&self) -> usize {
        3 * self.psize * self.psize
    }
    /// Candidate index of the pixel nearest to (x, y), clamped into the candidate rectangle.
    #[inline]
    pub fn cand_at(&self, x: i64, y: i64) -> u32 {
        let cx = (x - self.m as i64).clamp(0, self.cw as i64 - 1) as usize;
        let cy = (y - self.m as i64).clamp(0, self.ch as i64 - 1) as usize;
        (cy * self.cw + cx) as u32
    }
    /// Pixel coordinates of a candidate.
    #[inline]
    pub fn pixel(&self, c: u32) -> (usize, usize) {
        let c = c as usize;
        (c % self.cw + self.m, c / self.cw + self.m)
    }
    /// Colour of a candidate's centre pixel.
    #[inline]
    pub fn color(&self, c: u32) -> [f32; 3] {
        let (x, y) = self.pixel(c);
        self.img.px[y * self.img.w + x]
    }
}
