//! Full-resolution delivery: the source resampled through the solution. MeshMatch solves on
//! working vertices; its result is a nearest-neighbour field (NNF) that gives every working
//! target vertex a source vertex and a rotation. Interpolating the colours voted at the working
//! vertices makes every texel a blend of its three corners, so anything finer than the working
//! mesh (eyes, text, mortar lines) comes out as a blob. Here every output texel is instead
//! carried to a point of the source surface through its patch's local map and reads the source
//! there at the source's own resolution (its texture, with the mip level of the texel's
//! footprint, or its dense vertex colours).
//!
//! Steps ([`Resampler::new`] runs the first two once per result, [`Resampler::sample`] the third
//! per texel):
//! 1. [`fit_patch_maps`]: per working target vertex, the local map of its patch, a similarity
//!    from its tangent plane to its match's tangent plane. Where the NNF is coherent around the
//!    vertex (its two-ring's matches lie where its own match predicts) the map is the least-squares
//!    fit to those matches, which gives sub-vertex position and a continuous rotation; elsewhere
//!    (patch borders) it is the match itself with its 20-degree rotation step.
//! 2. [`corner_images`]: per working face and corner, the images of the face's three corners
//!    under that corner's map, located on the source surface. A corner's map is affine over the
//!    face, so where the three images fall in one UV chart of the source (one face of a
//!    vertex-coloured source) a texel's source point is the barycentric blend of them.
//! 3. [`Resampler::sample`]: a texel's point under each corner's map; the corner nearest the
//!    texel decides, the corners whose maps agree with it there (same source point within a
//!    fraction of an edge) are blended by their barycentric weights and the others left out, so
//!    a patch border stays a clean cut between two copies of the source instead of a ghost of
//!    both. A corner whose images cross a chart is located per texel.

use glam::{Vec2, Vec3};
use rayon::prelude::*;

use super::PreparedMesh;
use super::coincident::SurfaceSearch;
use super::patch_map::PatchMap;
use crate::features::{ANGLE_STEP_DEG, FAN_ANGLES, Frames};
use crate::geometry::closest_on_triangle;
use crate::hierarchy::Level;
use crate::mesh::{Csr, vertex_faces};
use crate::work::CancelToken;

/// Linear light -> sRGB through a table of 4096 steps (within 1/255 of the exact curve; the
/// bake quantises to 8 bits).
#[inline]
fn linear_to_srgb(c: f32) -> f32 {
    static TABLE: std::sync::OnceLock<Vec<f32>> = std::sync::OnceLock::new();
    let t = TABLE.get_or_init(|| {
        (0..=SRGB_STEPS)
            .map(|i| crate::color::linear_to_srgb(i as f32 / SRGB_STEPS as f32))
            .collect()
    });
    let x = c.clamp(0.0, 1.0) * SRGB_STEPS as f32;
    let i = (x as usize).min(SRGB_STEPS - 1);
    let f = x - i as f32;
    t[i] + (t[i + 1] - t[i]) * f
}
const SRGB_STEPS: usize = 4096;

/// Two matches agree at a texel when their source points are closer than this many source mean
/// edges: inside a coherent patch the corner maps differ by a small fraction of an edge, across a
/// patch border by many edges.
const AGREE_EDGES: f32 = 0.75;
/// A neighbour's match is coherent with a vertex's when it lies within this many source mean
/// edges of where the vertex's own match predicts it.
const COHERENT_EDGES: f32 = 1.5;
/// Fewest coherent matches (the vertex included) for a fitted patch map.
const MIN_FIT: usize = 4;
/// Most vertices of a two-ring read by the fit (valence 6 gives 19).
const RING2: usize = 48;

/// The source's surface and what it carries: its working mesh, whose faces lie in the input's
/// faces with UVs (or vertex colours) interpolated exactly from the input's, so a point located
/// on a working face reads the input's texture (or colours) as they are.
struct SourceSurface {
    level: Level,
    frames: Frames,
    faces_of: Csr,
    /// UVs per working corner (textured source).
    uvs: Vec<[f32; 2]>,
    /// Linear-light colour per working vertex (vertex-coloured source).
    colors: Vec<[f32; 3]>,
    look: Look,
}

/// The source's colours at full resolution.
enum Look {
    /// A texture: each working face's UV chart and the texture's mip chain (UVs per working
    /// corner in the working mesh).
    Texture { charts: Vec<u32>, mips: Vec<Mip> },
    /// sRGB colours of the working vertices, interpolated over the working faces.
    Colors,
}

/// One mip level, linear-light RGB.
struct Mip {
    w: usize,
    h: usize,
    px: Vec<[f32; 3]>,
}

impl Mip {
    /// Bilinear lookup at `uv` (V up, wrapping, as the loaders' sampler).
    #[inline]
    fn bilinear(&self, uv: [f32; 2]) -> Vec3 {
        if !(uv[0].is_finite() && uv[1].is_finite()) {
            return Vec3::ZERO;
        }
        let x = uv[0] * self.w as f32 - 0.5;
        let y = (1.0 - uv[1]) * self.h as f32 - 0.5;
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let (w, h) = (self.w as i64, self.h as i64);
        let xa = (x0 as i64).rem_euclid(w) as usize;
        let ya = (y0 as i64).rem_euclid(h) as usize;
        let xb = (x0 as i64 + 1).rem_euclid(w) as usize;
        let yb = (y0 as i64 + 1).rem_euclid(h) as usize;
        let p = |x: usize, y: usize| Vec3::from(self.px[y * self.w + x]);
        let top = p(xa, ya).lerp(p(xb, ya), fx);
        let bot = p(xa, yb).lerp(p(xb, yb), fx);
        top.lerp(bot, fy)
    }
}

/// The mip chain of an sRGB texture in linear light, 2x2 box filtered down to 1x1.
fn mip_chain(img: &image::RgbImage) -> Vec<Mip> {
    let lut: [f32; 256] = std::array::from_fn(|i| crate::color::srgb_to_linear(i as f32 / 255.0));
    let (w, h) = (img.width() as usize, img.height() as usize);
    let px: Vec<[f32; 3]> = img
        .as_raw()
        .par_chunks_exact(3)
        .map(|p| [lut[p[0] as usize], lut[p[1] as usize], lut[p[2] as usize]])
        .collect();
    let mut levels = vec![Mip { w, h, px }];
    while let Some(top) = levels.last() {
        if top.w <= 1 && top.h <= 1 {
            break;
        }
        let (nw, nh) = (top.w.div_ceil(2).max(1), top.h.div_ceil(2).max(1));
        let next: Vec<[f32; 3]> = (0..nw * nh)
            .into_par_iter()
            .map(|i| {
                let (x, y) = (i % nw, i / nw);
                let mut acc = Vec3::ZERO;
                for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                    let (sx, sy) = ((2 * x + dx).min(top.w - 1), (2 * y + dy).min(top.h - 1));
                    acc += Vec3::from(top.px[sy * top.w + sx]);
                }
                (acc * 0.25).to_array()
            })
            .collect();
        levels.push(Mip {
            w: nw,
            h: nh,
            px: next,
        });
    }
    levels
}

/// UV chart of every face: faces sharing an edge whose two corners have the same UVs in both
/// are in one chart (a texture is continuous across such an edge and nowhere else).
fn uv_charts(faces: &[[u32; 3]], uvs: &[[f32; 2]]) -> Vec<u32> {
    let nf = faces.len().min(uvs.len() / 3);
    let mut parent: Vec<u32> = (0..nf as u32).collect();
    fn find(p: &mut [u32], mut x: u32) -> u32 {
        while p[x as usize] != x {
            p[x as usize] = p[p[x as usize] as usize];
            x = p[x as usize];
        }
        x
    }
    // edge (low, high) -> (first face, its UVs at low and high)
    type Seen = (u32, [f32; 2], [f32; 2]);
    let mut edges: std::collections::HashMap<(u32, u32), Seen> =
        std::collections::HashMap::with_capacity(nf * 2);
    for (f, face) in faces.iter().enumerate().take(nf) {
        for k in 0..3 {
            let (a, b) = (face[k], face[(k + 1) % 3]);
            let (ua, ub) = (uvs[3 * f + k], uvs[3 * f + (k + 1) % 3]);
            let (key, u0, u1) = if a < b {
                ((a, b), ua, ub)
            } else {
                ((b, a), ub, ua)
            };
            match edges.get(&key) {
                Some(&(g, v0, v1)) if v0 == u0 && v1 == u1 => {
                    let (x, y) = (find(&mut parent, f as u32), find(&mut parent, g));
                    if x != y {
                        parent[x.max(y) as usize] = x.min(y);
                    }
                }
                Some(_) => {}
                None => {
                    edges.insert(key, (f as u32, u0, u1));
                }
            }
        }
    }
    (0..nf as u32).map(|f| find(&mut parent, f)).collect()
}

/// A point on the source: working face and barycentric coordinates there.
#[derive(Clone, Copy, Debug, Default)]
struct Spot {
    face: u32,
    bary: [f32; 3],
    /// The working vertex nearest the point (where a later search starts).
    near: u32,
}

impl SourceSurface {
    fn new(ps: &PreparedMesh) -> Option<Self> {
        let level = &ps.hierarchy.levels[0];
        let mesh = &ps.working;
        if mesh.faces.len() != level.faces.len() {
            return None;
        }
        let (mut uvs, mut colors) = (Vec::new(), Vec::new());
        let look = match (&mesh.texture, &mesh.uvs, &mesh.colors) {
            (Some(tex), Some(u), _) if u.len() == 3 * mesh.faces.len() => {
                if tex.image.width() == 0 || tex.image.height() == 0 {
                    return None;
                }
                uvs = u.clone();
                Look::Texture {
                    charts: uv_charts(&mesh.faces, u),
                    mips: mip_chain(&tex.image),
                }
            }
            (_, _, Some(c)) if c.len() == mesh.positions.len() => {
                colors = c
                    .iter()
                    .map(|c| c.map(crate::color::srgb_to_linear))
                    .collect();
                Look::Colors
            }
            _ => return None,
        };
        Some(SourceSurface {
            level: level.clone(),
            frames: ps.frames[0].clone(),
            faces_of: vertex_faces(level.len(), &level.faces),
            uvs,
            colors,
            look,
        })
    }

    /// The point of the surface closest to `goal`, searched around the working vertex `start`:
    /// greedy steps to the vertex nearest `goal`, then the closest point over its faces.
    fn locate(&self, goal: Vec3, start: u32) -> Spot {
        let pos = &self.level.positions;
        let mut best = start as usize;
        let mut bd = (Vec3::from(pos[best]) - goal).length_squared();
        for _ in 0..16 {
            let cur = best;
            for &u in self.level.adjacency.row(cur) {
                let d = (Vec3::from(pos[u as usize]) - goal).length_squared();
                if d < bd {
                    bd = d;
                    best = u as usize;
                }
            }
            if best == cur {
                break;
            }
        }
        let mut out = (f32::INFINITY, 0u32, [1.0f32, 0.0, 0.0]);
        for &wf in self.faces_of.row(best) {
            let f = self.level.faces[wf as usize];
            let [a, b, c] = f.map(|v| Vec3::from(pos[v as usize]));
            let l = closest_on_triangle(goal, a, b, c);
            let q = a * l[0] + b * l[1] + c * l[2];
            let d = (q - goal).length_squared();
            if d < out.0 {
                out = (d, wf, l);
            }
        }
        Spot {
            face: out.1,
            bary: out.2,
            near: best as u32,
        }
    }

    /// UV of a point of a textured source.
    #[inline]
    fn uv(&self, s: &Spot) -> [f32; 2] {
        let uvs = &self.uvs;
        let f = s.face as usize;
        let mut uv = [0.0f32; 2];
        for k in 0..3 {
            let u = uvs.get(3 * f + k).copied().unwrap_or([0.0; 2]);
            uv[0] += s.bary[k] * u[0];
            uv[1] += s.bary[k] * u[1];
        }
        uv
    }

    /// Linear-light colour at a texture coordinate, trilinear between mip levels at `lod`.
    #[inline]
    fn texel(&self, uv: [f32; 2], lod: f32) -> Vec3 {
        let Look::Texture { mips, .. } = &self.look else {
            return Vec3::ZERO;
        };
        let lod = lod.clamp(0.0, (mips.len() - 1) as f32);
        let l0 = lod.floor() as usize;
        let t = lod - l0 as f32;
        let a = mips[l0].bilinear(uv);
        if t < 1e-3 || l0 + 1 >= mips.len() {
            a
        } else {
            a.lerp(mips[l0 + 1].bilinear(uv), t)
        }
    }

    /// Linear-light colour of a point on a face with barycentric `bary` of a vertex-coloured
    /// source.
    #[inline]
    fn vertex_colour(&self, face: u32, bary: [f32; 3]) -> Vec3 {
        let f = self.level.faces[face as usize];
        let mut out = Vec3::ZERO;
        for k in 0..3 {
            out += bary[k] * Vec3::from(self.colors[f[k] as usize]);
        }
        out
    }

    /// Linear-light colour at a located point.
    #[inline]
    fn colour(&self, s: &Spot, lod: f32) -> Vec3 {
        match self.look {
            Look::Texture { .. } => self.texel(self.uv(s), lod),
            Look::Colors => self.vertex_colour(s.face, s.bary),
        }
    }

    /// Chart of a located point: its UV chart, inside which barycentric blends of located
    /// points' UVs stay on the texture's layout (one chart for a vertex-coloured source, whose
    /// corner images are blended by colour).
    #[inline]
    fn chart(&self, s: &Spot) -> u32 {
        match &self.look {
            Look::Texture { charts, .. } => charts.get(s.face as usize).copied().unwrap_or(0),
            Look::Colors => 0,
        }
    }
}

/// Step 1: the local map of every working target vertex's patch (see the module doc).
pub(crate) fn fit_patch_maps(
    ps: &PreparedMesh,
    pt: &PreparedMesh,
    nnf: &[(u32, u8)],
) -> Vec<PatchMap> {
    let (ls, lt) = (&ps.hierarchy.levels[0], &pt.hierarchy.levels[0]);
    let (fs, ft) = (&ps.frames[0], &pt.frames[0]);
    let ratio = ls.mean_edge / lt.mean_edge.max(1e-12);
    let tol = COHERENT_EDGES * ls.mean_edge;
    let ns = ls.len() as u32;
    (0..lt.len())
        .into_par_iter()
        .map(|v| {
            let (s, k) = nnf.get(v).copied().unwrap_or((0, 0));
            let s = s.min(ns.saturating_sub(1));
            let th = (k as usize % FAN_ANGLES) as f32 * ANGLE_STEP_DEG.to_radians();
            let (sn, c) = th.sin_cos();
            let base = PatchMap::similarity(s, [0.0; 2], ratio * c, ratio * sn);
            let xv = Vec3::from(lt.positions[v]);
            let (t1v, t2v) = (Vec3::from(ft.t1[v]), Vec3::from(ft.t2[v]));
            let xs = Vec3::from(ls.positions[s as usize]);
            let (t1s, t2s) = (Vec3::from(fs.t1[s as usize]), Vec3::from(fs.t2[s as usize]));
            // The two-ring, without allocating.
            let mut ring = [0u32; RING2];
            let mut n = 0usize;
            for &u in lt.adjacency.row(v) {
                if n < RING2 {
                    ring[n] = u;
                    n += 1;
                }
            }
            let first = n;
            for i in 0..first {
                for &u in lt.adjacency.row(ring[i] as usize) {
                    if u as usize != v && n < RING2 && !ring[..n].contains(&u) {
                        ring[n] = u;
                        n += 1;
                    }
                }
            }
            // Coherent neighbours: (target offset, source offset, weight).
            let mut pts = [(Vec2::ZERO, Vec2::ZERO, 0.0f32); RING2 + 1];
            pts[0] = (Vec2::ZERO, Vec2::ZERO, 2.0);
            let mut m = 1usize;
            for &u in &ring[..n] {
                let d = Vec3::from(lt.positions[u as usize]) - xv;
                let p = Vec2::new(d.dot(t1v), d.dot(t2v));
                let su = nnf.get(u as usize).map(|x| x.0).unwrap_or(s).min(ns - 1);
                let e = Vec3::from(ls.positions[su as usize]) - xs;
                let q = Vec2::new(e.dot(t1s), e.dot(t2s));
                let pred = base.apply(p);
                if (q - pred).length() < tol && e.length() < pred.length() + tol {
                    pts[m] = (p, q, 1.0);
                    m += 1;
                }
            }
            if m < MIN_FIT {
                return base;
            }
            let (mut w, mut pm, mut qm) = (0.0f32, Vec2::ZERO, Vec2::ZERO);
            for &(p, q, wi) in &pts[..m] {
                w += wi;
                pm += wi * p;
                qm += wi * q;
            }
            pm /= w;
            qm /= w;
            let (mut sxx, mut dot, mut cross) = (0.0f32, 0.0f32, 0.0f32);
            for &(p, q, wi) in &pts[..m] {
                let (p, q) = (p - pm, q - qm);
                sxx += wi * p.length_squared();
                dot += wi * p.dot(q);
                cross += wi * (p.x * q.y - p.y * q.x);
            }
            if sxx <= 1e-20 {
                return base;
            }
            let (a, b) = (dot / sxx, cross / sxx);
            let scale = (a * a + b * b).sqrt();
            let origin = qm - Vec2::new(a * pm.x - b * pm.y, b * pm.x + a * pm.y);
            let plausible = scale > 0.5 * ratio && scale < 2.0 * ratio && origin.is_finite();
            if !plausible || origin.length() > tol {
                return base;
            }
            PatchMap::similarity(s, origin.to_array(), a, b)
        })
        .collect()
}

/// How far apart three maps' images of one point are: the largest of their distances.
#[inline]
fn spread(g: [Vec3; 3]) -> f32 {
    (g[0] - g[1])
        .length()
        .max((g[1] - g[2]).length())
        .max((g[0] - g[2]).length())
}

/// The images of one working face's three corners under one corner's patch map.
#[derive(Clone, Copy, Debug, Default)]
struct CornerImage {
    /// The mapped points before projection onto the source (a texel's point under this map is
    /// their barycentric blend).
    goal: [[f32; 3]; 3],
    /// The mapped points located on the source.
    at: [Spot; 3],
    /// Whether the three located points lie in one chart (so blends of their UVs or barycentric
    /// coordinates stay on the surface).
    one_chart: bool,
    /// Their UVs on a textured source.
    uv: [[f32; 2]; 3],
    /// Area of the UV triangle they span, in source texels (the footprint of the face there).
    texel_area: f32,
    /// Half its base-2 logarithm (where it is positive).
    half_log2_area: f32,
    /// Their linear-light colours on a vertex-coloured source (whose colours are linear over
    /// working faces of about a target face's size, so a texel blends these three).
    col: [[f32; 3]; 3],
}

/// The source read at full resolution through a transfer's solution: see the module doc.
pub struct Resampler {
    src: SourceSurface,
    target_positions: Vec<[f32; 3]>,
    target_frames: Frames,
    maps: Vec<PatchMap>,
    /// Per working target face, per corner.
    images: Vec<[CornerImage; 3]>,
    agree: f32,
    /// Per working face, whether its three maps agree all over it and read one chart of a
    /// texture ([`Resampler::sample`]'s single reading everywhere on it).
    agreeing: Vec<bool>,
    /// Target vertices where the shapes coincide, read exactly ([`super::coincident`]).
    snapped: usize,
    /// Seconds of each step of [`Resampler::new`].
    timings: Vec<(&'static str, f64)>,
}

/// Step 2: every working target face's corner images (see the module doc). A face's corner
/// `k` maps the face's corners `j`: the vertex itself, or a neighbour along an edge, so the
/// images are computed once per vertex and per directed edge (about 7 per vertex instead of 9
/// per face) and gathered per face.
fn corner_images(
    src: &SourceSurface,
    lt: &Level,
    ft: &Frames,
    maps: &[PatchMap],
    cancel: &CancelToken,
) -> crate::error::Result<Vec<[CornerImage; 3]>> {
    let (w, h) = match &src.look {
        Look::Texture { mips, .. } => (mips[0].w as f32, mips[0].h as f32),
        Look::Colors => (1.0, 1.0),
    };
    let adj = &lt.adjacency;
    // Per vertex: its own image, then one per neighbour in adjacency order.
    let image = |v: usize, x: Vec3| {
        let m = &maps[v];
        let g = map_point(src, &lt.positions, ft, m, v, x);
        (g.to_array(), src.locate(g, m.anchor))
    };
    // Flat rows: vertex v's own image at `offsets[v] + v`, its neighbours' after it in
    // adjacency order (the adjacency's offsets shifted by one slot per vertex).
    let row_start = |v: usize| adj.offsets[v] as usize + v;
    let slots: Vec<(usize, u32)> = (0..lt.len())
        .flat_map(|v| {
            std::iter::once(v as u32)
                .chain(adj.row(v).iter().copied())
                .map(move |u| (v, u))
        })
        .collect();
    let images: Vec<([f32; 3], Spot)> = slots
        .par_iter()
        .map(|&(v, u)| {
            if cancel.is_cancelled() {
                return ([0.0; 3], Spot::default());
            }
            image(v, Vec3::from(lt.positions[u as usize]))
        })
        .collect();
    drop(slots);
    cancel.check()?;
    let find = |v: usize, u: u32| -> ([f32; 3], Spot) {
        if u as usize == v {
            return images[row_start(v)];
        }
        match adj.row(v).binary_search(&u) {
            Ok(i) => images[row_start(v) + 1 + i],
            Err(_) => image(v, Vec3::from(lt.positions[u as usize])),
        }
    };
    let out: Vec<[CornerImage; 3]> = lt
        .faces
        .par_iter()
        .map(|f| {
            std::array::from_fn(|k| {
                let v = f[k] as usize;
                let mut img = CornerImage::default();
                for (j, &u) in f.iter().enumerate() {
                    let (g, at) = find(v, u);
                    img.goal[j] = g;
                    img.at[j] = at;
                }
                let c0 = src.chart(&img.at[0]);
                img.one_chart = (1..3).all(|j| src.chart(&img.at[j]) == c0);
                if let Look::Colors = src.look {
                    img.col = img.at.map(|s| src.vertex_colour(s.face, s.bary).to_array());
                }
                if let Look::Texture { .. } = src.look {
                    img.uv = img.at.map(|s| src.uv(&s));
                    let [a, b, c] = img.uv;
                    let area =
                        ((b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1])).abs() * 0.5;
                    img.texel_area = area * w * h;
                    img.half_log2_area = 0.5 * img.texel_area.log2();
                }
                img
            })
        })
        .collect();
    Ok(out)
}

/// A target point `x` carried by vertex `v`'s patch map onto the source's tangent plane at the
/// map's anchor.
#[inline]
fn map_point(
    src: &SourceSurface,
    positions: &[[f32; 3]],
    ft: &Frames,
    m: &PatchMap,
    v: usize,
    x: Vec3,
) -> Vec3 {
    let d = x - Vec3::from(positions[v]);
    let p = Vec2::new(d.dot(Vec3::from(ft.t1[v])), d.dot(Vec3::from(ft.t2[v])));
    let q = m.apply(p);
    let a = m.anchor as usize;
    Vec3::from(src.level.positions[a])
        + q.x * Vec3::from(src.frames.t1[a])
        + q.y * Vec3::from(src.frames.t2[a])
}

/// Every target vertex's point on the source under its patch map.
fn mapped_points(
    src: &SourceSurface,
    positions: &[[f32; 3]],
    frames: &Frames,
    maps: &[PatchMap],
) -> Vec<[f32; 3]> {
    (0..positions.len())
        .into_par_iter()
        .map(|v| {
            let m = &maps[v];
            let g = map_point(src, positions, frames, m, v, Vec3::from(positions[v]));
            let s = src.locate(g, m.anchor);
            let f = src.level.faces[s.face as usize];
            let c = f.map(|u| Vec3::from(src.level.positions[u as usize]));
            (c[0] * s.bary[0] + c[1] * s.bary[1] + c[2] * s.bary[2]).to_array()
        })
        .collect()
}

impl std::fmt::Debug for Resampler {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Resampler")
            .field("source_vertices", &self.src.level.len())
            .field("target_vertices", &self.target_positions.len())
            .field("target_faces", &self.images.len())
            .finish()
    }
}

impl Resampler {
    /// The resampler of a solution `nnf` (a [`super::TransferResult::nnf`]) from the prepared
    /// source `ps` onto the prepared target `pt`; `None` when the source carries no signal to
    /// read or `nnf` is not a solution on `pt`.
    pub fn new(
        ps: &PreparedMesh,
        pt: &PreparedMesh,
        nnf: &[(u32, u8)],
        cancel: &CancelToken,
    ) -> crate::error::Result<Option<Self>> {
        Self::build(ps, pt, nnf, false, cancel)
    }

    /// [`Self::new`] for a target that lies in the same space as the source where they share
    /// surface (an edited copy of it, a mesh completed from its own painted part): every target
    /// vertex on the source surface reads the source exactly under it, however little of the
    /// target that is.
    pub fn in_place(
        ps: &PreparedMesh,
        pt: &PreparedMesh,
        nnf: &[(u32, u8)],
        cancel: &CancelToken,
    ) -> crate::error::Result<Option<Self>> {
        Self::build(ps, pt, nnf, true, cancel)
    }

    fn build(
        ps: &PreparedMesh,
        pt: &PreparedMesh,
        nnf: &[(u32, u8)],
        in_place: bool,
        cancel: &CancelToken,
    ) -> crate::error::Result<Option<Self>> {
        let lt = &pt.hierarchy.levels[0];
        if nnf.len() != lt.len() {
            return Ok(None);
        }
        let watch = crate::work::Stopwatch::start();
        let mut timings = Vec::new();
        let Some(src) = SourceSurface::new(ps) else {
            return Ok(None);
        };
        timings.push(("source", watch.secs()));
        let mut maps = fit_patch_maps(ps, pt, nnf);
        timings.push(("patch maps", watch.secs()));
        cancel.check()?;
        let search = SurfaceSearch::new(&src.level, &src.faces_of);
        let snap = if in_place {
            super::coincident::snap_in_place(&search, &src.frames, lt, &pt.frames[0])
        } else {
            let matched = mapped_points(&src, &lt.positions, &pt.frames[0], &maps);
            super::coincident::snap_coincident(&search, &src.frames, lt, &pt.frames[0], &matched)
                .or_else(|| {
                    super::nonrigid::snap_deformed(
                        &search,
                        &src.frames,
                        lt,
                        &pt.frames[0],
                        &matched,
                    )
                })
        };
        let mut snapped = 0;
        if let Some(snap) = snap {
            for (m, s) in maps.iter_mut().zip(snap) {
                if let Some(s) = s {
                    *m = s;
                    snapped += 1;
                }
            }
        }
        timings.push(("coincident", watch.secs()));
        cancel.check()?;
        let images = corner_images(&src, lt, &pt.frames[0], &maps, cancel)?;
        timings.push(("corner images", watch.secs()));
        // cumulative -> per stage
        for i in (1..timings.len()).rev() {
            timings[i].1 -= timings[i - 1].1;
        }
        let agree = AGREE_EDGES * src.level.mean_edge;
        let mut resampler = Resampler {
            src,
            target_positions: lt.positions.clone(),
            target_frames: pt.frames[0].clone(),
            maps,
            images,
            agree,
            snapped,
            timings,
            agreeing: Vec::new(),
        };
        // The distance between two maps' images is a norm of an affine function over the face,
        // so it is largest at a corner: where the corners agree, every point agrees.
        resampler.agreeing = resampler
            .images
            .par_iter()
            .map(|imgs| {
                let spread = (0..3)
                    .map(|j| spread(imgs.map(|im| Vec3::from(im.goal[j]))))
                    .fold(0.0f32, f32::max);
                spread < agree && resampler.one_texture_chart(imgs)
            })
            .collect();
        Ok(Some(resampler))
    }

    /// sRGB colour of the point with barycentric `bary` in working target face `wf`, read from
    /// the source at full resolution (see the module doc); `texel_area` is the face's area in
    /// output texels (it picks the source's mip level; 0 = the finest).
    pub fn sample(&self, wf: usize, bary: [f32; 3], texel_area: f32) -> [f32; 3] {
        let imgs = &self.images[wf];
        let half_log2 = if texel_area > 0.0 {
            0.5 * texel_area.log2()
        } else {
            0.0
        };
        let lod = |k: usize| {
            if texel_area > 0.0 && imgs[k].texel_area > 0.0 {
                imgs[k].half_log2_area - half_log2
            } else {
                0.0
            }
        };
        let at_uv = |k: usize| {
            let u = &imgs[k].uv;
            Vec2::from(u[0]) * bary[0] + Vec2::from(u[1]) * bary[1] + Vec2::from(u[2]) * bary[2]
        };
        // Inside a patch the three maps agree: one lookup at their blended UV (the sharpest
        // reading, and the exact one where the shapes coincide).
        let one_reading = || {
            let (mut uv, mut l) = (Vec2::ZERO, 0.0f32);
            for (k, &w) in bary.iter().enumerate() {
                uv += w * at_uv(k);
                l += w * lod(k);
            }
            self.src
                .texel(uv.to_array(), l)
                .to_array()
                .map(linear_to_srgb)
        };
        if self.agreeing[wf] {
            return one_reading();
        }
        let goal = |k: usize| {
            let g = &imgs[k].goal;
            Vec3::from(g[0]) * bary[0] + Vec3::from(g[1]) * bary[1] + Vec3::from(g[2]) * bary[2]
        };
        let g = [goal(0), goal(1), goal(2)];
        if spread(g) < self.agree && self.one_texture_chart(imgs) {
            return one_reading();
        }
        // Across a patch border (or a chart border of the source) each corner reads the source
        // through its own map and the readings are blended with barycentric weights:
        // continuous, each reading sharp, the border's transition one triangle wide as the
        // patch synthesis placed it.
        let (mut acc, mut wsum) = (Vec3::ZERO, 0.0f32);
        for (k, img) in imgs.iter().enumerate() {
            let w = bary[k];
            if w < 1e-8 {
                continue;
            }
            let c = if img.one_chart {
                match self.src.look {
                    Look::Texture { .. } => self.src.texel(at_uv(k).to_array(), lod(k)),
                    Look::Colors => {
                        let c = &img.col;
                        Vec3::from(c[0]) * bary[0]
                            + Vec3::from(c[1]) * bary[1]
                            + Vec3::from(c[2]) * bary[2]
                    }
                }
            } else {
                let near = img.at[(0..3)
                    .max_by(|&a, &b| bary[a].total_cmp(&bary[b]))
                    .unwrap_or(0)]
                .near;
                let s = self.src.locate(g[k], near);
                self.src.colour(&s, lod(k))
            };
            acc += w * c;
            wsum += w;
        }
        if wsum <= 0.0 {
            return [0.0; 3];
        }
        (acc / wsum).to_array().map(linear_to_srgb)
    }

    /// Whether a face's three corner maps read a texture within one of its charts.
    fn one_texture_chart(&self, imgs: &[CornerImage; 3]) -> bool {
        if let Look::Texture { .. } = self.src.look {
            let chart = self.src.chart(&imgs[0].at[0]);
            (0..3).all(|k| imgs[k].one_chart && self.src.chart(&imgs[k].at[0]) == chart)
        } else {
            false
        }
    }

    /// The source surface point of every working target vertex under its patch map (where
    /// [`Self::vertex_signal`] reads the source).
    pub fn vertex_points(&self) -> Vec<[f32; 3]> {
        mapped_points(
            &self.src,
            &self.target_positions,
            &self.target_frames,
            &self.maps,
        )
    }

    /// Seconds of each step of [`Resampler::new`].
    pub fn timings(&self) -> &[(&'static str, f64)] {
        &self.timings
    }

    /// The share of working target vertices where the target coincides with the source up to a
    /// similarity, so the source is read exactly under them (0 between different shapes).
    pub fn coincident_share(&self) -> f64 {
        self.snapped as f64 / self.target_positions.len().max(1) as f64
    }

    /// sRGB colour of every working target vertex, read from the source at its patch map's
    /// point (a point sample at the source's full resolution).
    pub fn vertex_signal(&self) -> Vec<[f32; 3]> {
        let pos = &self.target_positions;
        (0..pos.len())
            .into_par_iter()
            .map(|v| {
                let m = &self.maps[v];
                let g = map_point(
                    &self.src,
                    pos,
                    &self.target_frames,
                    m,
                    v,
                    Vec3::from(pos[v]),
                );
                let s = self.src.locate(g, m.anchor);
                self.src.colour(&s, 0.0).to_array().map(linear_to_srgb)
            })
            .collect()
    }
}
