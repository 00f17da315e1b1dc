//! Surface texture optimisation (Kwatra, Essa, Bobick & Kwatra 2005, "Texture optimization for
//! example-based synthesis", §3; on surfaces as Kwatra et al. 2007), with the feature-to-feature
//! constraint of Xu et al. 2009, "Feature-aligned shape texturing", §5.1-5.2.
//!
//! The energy, Xu et al. eq. (3):
//!
//! `E_t(X; {z_p}) = Σ_{p ∈ X+} λ_p ω_p |x_p − z_p|²`
//!
//! - `X+`: sample vertices whose `w × w` texel patches, laid out along the orientation field
//!   (x axis = the field, y axis = `n × field`, vertices flattened by projection on the sample's
//!   tangent plane), cover the surface: a Poisson-disk set at spacing `r w` texels, taken along the
//!   salient curves first, then near them by increasing distance, then in seeded random order
//!   (after Chen et al. 2009).
//! - `x_p`: the surface colours of the patch; `z_p`: the most similar exemplar patch. The search
//!   compares `8 × 8` cell means of the patch (PCA to [`Params::pca_dims`] dimensions, k-d tree,
//!   the best four verified on every filled cell, plus the sample's previous patch).
//! - `ω_p = |x_p − z_p|^(r−2)`, `r = 0.8`: Kwatra et al.'s robust re-weighting (§3.1).
//! - `λ_p = 1 / (d(p, C) + ε₀)`, eq. (4), with `d(p, C)` the surface distance to the nearest
//!   salient curve; `λ_p = 1` without curves.
//! - **Feature-to-feature constraint (§5.2):** where a patch covers a curve (`d(p, C) < w/2`),
//!   `z_p` is searched only among exemplar patches whose centre pixel lies at the same distance
//!   (within [`Params::feature_tolerance`] texels) from the exemplar's principal line
//!   ([`exemplar_lines`]). Patches on a curve are therefore centred on the line, and as the field
//!   runs along the curve the line runs along it too.
//!
//! The iteration alternates, as Kwatra et al.: nearest exemplar patch for every sample, then the
//! colours minimising `E_t` (per vertex, the weighted mean of the overlapping patches' predictions,
//! read bilinearly at the vertex's own patch coordinates), until fewer than
//! [`Params::tolerance`] of the `z_p` change or [`Params::iterations`] passes. Kwatra's
//! multi-scale neighbourhoods: a pass at `2w` before `w` ([`Params::multiscale`]). The initial
//! colours are the caller's (the Wei-Levoy multi-resolution synthesis along the same field, in
//! place of Kwatra's coarser image levels). Transparent exemplar pixels never enter a patch.

pub mod exemplar_lines;

use std::sync::Arc;

use glam::Vec3;
use rand::SeedableRng;
use rand::rngs::SmallRng;
use rand::seq::SliceRandom;
use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::stats::KdTree;
use crate::work::{CancelToken, Event, Progress, Stopwatch};

pub use exemplar_lines::{ExemplarLines, find_principal_lines};

/// Cells per patch side in the search vectors.
const CELLS: usize = 8;
/// Patches verified on every cell after the PCA search.
const VERIFY: usize = 4;
/// Shifts (texels, each axis) tried around the best patch at full resolution.
const REFINE: isize = 2;

/// Parameters (Xu et al. 2009 §5 and the guide's proposals: `w = 16`, `r = 0.25`, robust
/// `r = 0.8`, `ε₀ = 1e-6`, constraint tolerance 1 texel, at most 10 iterations, stop under 1%).
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
#[serde(default)]
pub struct Params {
    /// Patch side `w` in texels (a multiple of 8, at least 8).
    pub patch: usize,
    /// Run a scale at `2w` before `w` (Kwatra's multi-scale neighbourhoods).
    pub multiscale: bool,
    /// Sample spacing as a fraction `r` of the patch side.
    pub spacing: f32,
    /// Most iterations per scale.
    pub iterations: usize,
    /// Stop when fewer than this fraction of the samples change patch.
    pub tolerance: f32,
    /// Kwatra's robust exponent `r` in `ω_p = |x_p − z_p|^(r−2)`.
    pub robust: f32,
    /// Constraint tolerance in texels: `|D_exemplar − d(p, C)| <` this.
    pub feature_tolerance: f32,
    /// `ε₀` of eq. (4), in surface units.
    pub eps: f32,
    /// PCA dimensions of the search vectors.
    pub pca_dims: usize,
    /// Random seed (sample order, PCA sample).
    pub seed: u64,
}

impl Default for Params {
    fn default() -> Self {
        Params {
            patch: 16,
            multiscale: true,
            spacing: 0.25,
            iterations: 10,
            tolerance: 0.01,
            robust: 0.8,
            feature_tolerance: 1.0,
            eps: 1e-6,
            pca_dims: 16,
            seed: 0,
        }
    }
}

/// The surface to texture: a mesh at about one vertex per texel, with its orientation field.
#[derive(Clone, Copy, Debug)]
pub struct Surface<'a> {
    /// Vertex positions.
    pub positions: &'a [[f32; 3]],
    /// Triangles.
    pub faces: &'a [[u32; 3]],
    /// Unit vertex normals.
    pub normals: &'a [[f32; 3]],
    /// Unit tangent per vertex: the exemplar's x axis.
    pub field: &'a [[f32; 3]],
    /// Surface length of one exemplar pixel.
    pub texel: f32,
}

/// The feature-to-feature constraint's data.
#[derive(Clone, Copy, Debug)]
pub struct Constraint<'a> {
    /// Per vertex, the surface distance to the nearest salient curve (surface units).
    pub curve_distance: &'a [f32],
    /// The exemplar's principal lines (same size as the exemplar).
    pub lines: &'a ExemplarLines,
}

/// What one scale did.
#[derive(Clone, Debug, Default)]
pub struct ScaleReport {
    /// Patch side in texels.
    pub patch: usize,
    /// Samples in `X+`.
    pub samples: usize,
    /// Samples under the feature constraint.
    pub constrained: usize,
    /// Per iteration, the mean RMS patch distance `|x_p − z_p|` (sRGB units).
    pub energy: Vec<f64>,
    /// Per iteration, the fraction of samples whose patch changed.
    pub changed: Vec<f64>,
}

/// The optimisation's report.
#[derive(Clone, Debug, Default)]
pub struct Report {
    /// Per scale, coarse first.
    pub scales: Vec<ScaleReport>,
    /// Per vertex, the exemplar pixel of its strongest patch prediction.
    pub source: Vec<[u32; 2]>,
    /// Wall time in seconds.
    pub seconds: f64,
}

/// The exemplar as floats, with summed-area tables for cell means and a transparency count.
struct Exemplar {
    w: usize,
    h: usize,
    px: Vec<[f32; 3]>,
    /// (w+1) × (h+1) per channel, f64.
    sat: [Vec<f64>; 3],
    /// (w+1) × (h+1): transparent pixels.
    clear: Vec<u32>,
}

impl Exemplar {
    fn new(img: &image::RgbImage, alpha: Option<&image::GrayImage>) -> Result<Exemplar> {
        let (w, h) = (img.width() as usize, img.height() as usize);
        let px: Vec<[f32; 3]> = match alpha {
            None => img
                .pixels()
                .map(|p| p.0.map(|c| c as f32 / 255.0))
                .collect(),
            Some(a) => {
                crate::synthesis::wei_levoy::transparent_filled(img, a)?
                    .0
                    .px
            }
        };
        let mut sat = [
            vec![0.0f64; (w + 1) * (h + 1)],
            vec![0.0f64; (w + 1) * (h + 1)],
            vec![0.0f64; (w + 1) * (h + 1)],
        ];
        let mut clear = vec![0u32; (w + 1) * (h + 1)];
        for y in 0..h {
            let mut row = [0.0f64; 3];
            let mut rc = 0u32;
            for x in 0..w {
                let c = px[y * w + x];
                for k in 0..3 {
                    row[k] += c[k] as f64;
                    sat[k][(y + 1) * (w + 1) + x + 1] = sat[k][y * (w + 1) + x + 1] + row[k];
                }
                if alpha.is_some_and(|a| a.as_raw()[y * w + x] < 128) {
                    rc += 1;
                }
                clear[(y + 1) * (w + 1) + x + 1] = clear[y * (w + 1) + x + 1] + rc;
            }
        }
        Ok(Exemplar {
            w,
            h,
            px,
            sat,
            clear,
        })
    }

    /// Sum over pixels `x0..x1`, `y0..y1` of a (w+1)-wide table.
    fn rect<T: Copy + Into<f64>>(
        &self,
        t: &[T],
        x0: usize,
        y0: usize,
        x1: usize,
        y1: usize,
    ) -> f64 {
        let s = self.w + 1;
        t[y1 * s + x1].into() - t[y0 * s + x1].into() - t[y1 * s + x0].into()
            + t[y0 * s + x0].into()
    }

    /// The pixel nearest continuous coordinates (centres at integers), clamped.
    fn nearest(&self, x: f32, y: f32) -> [f32; 3] {
        let xi = (x.round() as isize).clamp(0, self.w as isize - 1) as usize;
        let yi = (y.round() as isize).clamp(0, self.h as isize - 1) as usize;
        self.px[yi * self.w + xi]
    }

    /// Bilinear lookup at continuous pixel coordinates (centres at integers), clamped.
    fn bilinear(&self, x: f32, y: f32) -> [f32; 3] {
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let at = |xi: f32, yi: f32| {
            let xi = (xi as isize).clamp(0, self.w as isize - 1) as usize;
            let yi = (yi as isize).clamp(0, self.h as isize - 1) as usize;
            self.px[yi * self.w + xi]
        };
        let (a, b, c, d) = (
            at(x0, y0),
            at(x0 + 1.0, y0),
            at(x0, y0 + 1.0),
            at(x0 + 1.0, y0 + 1.0),
        );
        let mut o = [0.0; 3];
        for k in 0..3 {
            o[k] =
                (a[k] * (1.0 - fx) + b[k] * fx) * (1.0 - fy) + (c[k] * (1.0 - fx) + d[k] * fx) * fy;
        }
        o
    }

    /// The `CELLS² × 3` cell means of the `w`-patch centred at pixel `(cx, cy)` (offsets
    /// `-w/2 .. w/2` on both axes, y down as the image).
    fn cells(&self, cx: usize, cy: usize, w: usize, out: &mut [f32]) {
        let s = w / CELLS;
        let inv = 1.0 / (s * s) as f64;
        for j in 0..CELLS {
            let y0 = cy + j * s - w / 2;
            for i in 0..CELLS {
                let x0 = cx + i * s - w / 2;
                for k in 0..3 {
                    out[(j * CELLS + i) * 3 + k] =
                        (self.rect(&self.sat[k], x0, y0, x0 + s, y0 + s) * inv) as f32;
                }
            }
        }
    }
}

/// One scale's exemplar index: valid patch centres, PCA basis, k-d tree, constraint bins.
struct Index {
    /// Valid centres as pixel indices `cy * W + cx`.
    centres: Vec<u32>,
    /// Per exemplar pixel, its index in `centres` (`u32::MAX`: not a valid centre).
    slot: Vec<u32>,
    mean: Vec<f32>,
    /// `dim × k`, row-major by input dimension.
    basis: Vec<f32>,
    k: usize,
    tree: KdTree,
    /// Projections of `centres`, row-major `k` per centre.
    proj: Vec<f32>,
    /// Per integer exemplar distance `b` (0..=w/2): centres whose line distance is within
    /// `tolerance + 0.5` of `b`.
    bins: Vec<Vec<u32>>,
}

const DIM: usize = CELLS * CELLS * 3;

impl Index {
    fn build(
        ex: &Exemplar,
        w: usize,
        lines: Option<&ExemplarLines>,
        tol: f32,
        dims: usize,
        seed: u64,
    ) -> Result<Index> {
        let mut centres = Vec::new();
        if ex.w > w && ex.h > w {
            for cy in w / 2..=ex.h - w / 2 {
                for cx in w / 2..=ex.w - w / 2 {
                    let clear = ex.rect(&ex.clear, cx - w / 2, cy - w / 2, cx + w / 2, cy + w / 2);
                    if clear == 0.0 {
                        centres.push((cy * ex.w + cx) as u32);
                    }
                }
            }
        }
        if centres.is_empty() {
            return Err(Error::InvalidInput(format!(
                "the exemplar ({}x{}) has no fully opaque {w}x{w} patch to optimise with",
                ex.w, ex.h
            )));
        }
        // PCA on a sample of the patch vectors.
        let mut rng = SmallRng::seed_from_u64(seed ^ 0x5eed_0f7a);
        let mut pick: Vec<u32> = centres.clone();
        pick.shuffle(&mut rng);
        pick.truncate(4000);
        let vecs: Vec<f32> = pick
            .par_iter()
            .flat_map_iter(|&c| {
                let mut v = vec![0.0f32; DIM];
                ex.cells(c as usize % ex.w, c as usize / ex.w, w, &mut v);
                v
            })
            .collect();
        let m = pick.len();
        let mut mean = vec![0.0f64; DIM];
        for r in vecs.chunks_exact(DIM) {
            for (a, &b) in mean.iter_mut().zip(r) {
                *a += b as f64;
            }
        }
        mean.iter_mut().for_each(|a| *a /= m as f64);
        let mut cov = faer::Mat::<f64>::zeros(DIM, DIM);
        for r in vecs.chunks_exact(DIM) {
            for i in 0..DIM {
                let di = r[i] as f64 - mean[i];
                for j in 0..=i {
                    cov[(i, j)] += di * (r[j] as f64 - mean[j]);
                }
            }
        }
        let evd = cov
            .self_adjoint_eigen(faer::Side::Lower)
            .map_err(|e| Error::InvalidInput(format!("patch PCA failed: {e:?}")))?;
        let k = dims.clamp(1, DIM);
        // faer sorts eigenvalues ascending: the last k columns
        let u = evd.U();
        let mut basis = vec![0.0f32; DIM * k];
        for e in 0..k {
            let col = DIM - 1 - e;
            for i in 0..DIM {
                basis[i * k + e] = u[(i, col)] as f32;
            }
        }
        let mean: Vec<f32> = mean.iter().map(|&x| x as f32).collect();
        let proj: Vec<f32> = centres
            .par_iter()
            .flat_map_iter(|&c| {
                let mut v = [0.0f32; DIM];
                ex.cells(c as usize % ex.w, c as usize / ex.w, w, &mut v);
                project(&v, &mean, &basis, k)
            })
            .collect();
        let tree = KdTree::new(&proj, k);
        let bins = match lines {
            None => Vec::new(),
            Some(l) => {
                let mut bins = vec![Vec::new(); w / 2 + 1];
                for (i, &c) in centres.iter().enumerate() {
                    let d = l.distance[c as usize];
                    for (b, bin) in bins.iter_mut().enumerate() {
                        if (d - b as f32).abs() <= tol + 0.5 {
                            bin.push(i as u32);
                        }
                    }
                }
                bins
            }
        };
        let mut slot = vec![u32::MAX; ex.w * ex.h];
        for (i, &c) in centres.iter().enumerate() {
            slot[c as usize] = i as u32;
        }
        Ok(Index {
            centres,
            slot,
            mean,
            basis,
            k,
            tree,
            proj,
            bins,
        })
    }
}

fn project(v: &[f32], mean: &[f32], basis: &[f32], k: usize) -> Vec<f32> {
    let mut o = vec![0.0f32; k];
    project_into(v, mean, basis, &mut o);
    o
}

/// [`project`] into `o` (its length is the number of dimensions).
fn project_into(v: &[f32], mean: &[f32], basis: &[f32], o: &mut [f32]) {
    let k = o.len();
    o.iter_mut().for_each(|a| *a = 0.0);
    for i in 0..DIM {
        let d = v[i] - mean[i];
        let row = &basis[i * k..(i + 1) * k];
        for (a, &b) in o.iter_mut().zip(row) {
            *a += d * b;
        }
    }
}

/// Patch regions of the samples: per sample, (vertex, x offset, y offset) in texels, and per
/// vertex the entries that cover it.
struct Regions {
    samples: Vec<u32>,
    start: Vec<usize>,
    vertex: Vec<u32>,
    offset: Vec<[f32; 2]>,
    /// Per vertex, entry indices (CSR).
    cover_start: Vec<usize>,
    cover: Vec<u32>,
    /// Sample of each entry.
    owner: Vec<u32>,
}

fn regions(surface: &Surface, adj: &crate::mesh::Csr, samples: Vec<u32>, w: usize) -> Regions {
    let n = surface.positions.len();
    let half = w as f32 / 2.0;
    let h = surface.texel;
    let per: Vec<Vec<(u32, [f32; 2])>> = samples
        .par_iter()
        .map_init(
            || (vec![u32::MAX; n], Vec::<u32>::new()),
            |(seen, queue), &p| {
                let p = p as usize;
                let pp = Vec3::from(surface.positions[p]);
                let np = Vec3::from(surface.normals[p]);
                let (sx, sy) = frame(np, Vec3::from(surface.field[p]));
                let mut out = Vec::new();
                queue.clear();
                queue.push(p as u32);
                seen[p] = p as u32;
                let mut head = 0;
                while head < queue.len() {
                    let q = queue[head] as usize;
                    head += 1;
                    let d = Vec3::from(surface.positions[q]) - pp;
                    let a = d.dot(sx) / h;
                    let b = -d.dot(sy) / h; // image y runs down
                    let inside = (-half - 0.5..half - 0.5).contains(&a)
                        && (-half - 0.5..half - 0.5).contains(&b)
                        && d.dot(np).abs() < half * h
                        && Vec3::from(surface.normals[q]).dot(np) > 0.0;
                    if !inside {
                        continue;
                    }
                    out.push((q as u32, [a, b]));
                    for &r in adj.row(q) {
                        if seen[r as usize] != p as u32 {
                            seen[r as usize] = p as u32;
                            queue.push(r);
                        }
                    }
                }
                out
            },
        )
        .collect();
    let mut start = Vec::with_capacity(samples.len() + 1);
    start.push(0);
    let total: usize = per.iter().map(|r| r.len()).sum();
    let mut vertex = Vec::with_capacity(total);
    let mut offset = Vec::with_capacity(total);
    let mut owner = Vec::with_capacity(total);
    let mut count = vec![0usize; n + 1];
    for (s, r) in per.into_iter().enumerate() {
        for (v, o) in r {
            vertex.push(v);
            offset.push(o);
            owner.push(s as u32);
            count[v as usize + 1] += 1;
        }
        start.push(vertex.len());
    }
    for i in 0..n {
        count[i + 1] += count[i];
    }
    let cover_start = count.clone();
    let mut fill = count;
    let mut cover = vec![0u32; total];
    for (e, &v) in vertex.iter().enumerate() {
        cover[fill[v as usize]] = e as u32;
        fill[v as usize] += 1;
    }
    Regions {
        samples,
        start,
        vertex,
        offset,
        cover_start,
        cover,
        owner,
    }
}

/// Texture frame at a vertex: (x = field projected on the tangent plane, y = n × x).
fn frame(n: Vec3, f: Vec3) -> (Vec3, Vec3) {
    let mut s = f - n * f.dot(n);
    if s.length_squared() < 1e-12 {
        s = n.any_orthonormal_vector();
    }
    let s = s.normalize();
    (s, n.cross(s))
}

/// Poisson-disk samples at `spacing` (surface units): vertices near curves by increasing distance
/// first (those within `near`), then the rest in seeded random order.
fn poisson_samples(
    positions: &[[f32; 3]],
    curve_distance: Option<&[f32]>,
    near: f32,
    spacing: f32,
    seed: u64,
) -> Vec<u32> {
    let n = positions.len();
    let mut order: Vec<u32> = (0..n as u32).collect();
    let mut rng = SmallRng::seed_from_u64(seed ^ 0x00c0_ffee);
    order.shuffle(&mut rng);
    if let Some(d) = curve_distance {
        // stable: near vertices by distance, then the shuffled rest
        order.sort_by(|&a, &b| {
            let (da, db) = (d[a as usize], d[b as usize]);
            let (na, nb) = (da < near, db < near);
            nb.cmp(&na).then(if na && nb {
                da.total_cmp(&db)
            } else {
                std::cmp::Ordering::Equal
            })
        });
    }
    let cell = spacing;
    let key = |p: Vec3| {
        let q = p / cell;
        (q.x.floor() as i32, q.y.floor() as i32, q.z.floor() as i32)
    };
    let mut grid: std::collections::HashMap<(i32, i32, i32), Vec<u32>> = Default::default();
    let mut out = Vec::new();
    let s2 = spacing * spacing;
    'outer: for &v in &order {
        let p = Vec3::from(positions[v as usize]);
        let k = key(p);
        for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    if let Some(list) = grid.get(&(k.0 + dx, k.1 + dy, k.2 + dz)) {
                        for &q in list {
                            if Vec3::from(positions[q as usize]).distance_squared(p) < s2 {
                                continue 'outer;
                            }
                        }
                    }
                }
            }
        }
        grid.entry(k).or_default().push(v);
        out.push(v);
    }
    out
}

/// Optimise `colors` (per vertex of `surface`, sRGB in [0, 1]) towards the exemplar: Xu et al.
/// eq. (3) by Kwatra's alternation, with the feature constraint when given. `sink` receives a
/// partial result after every iteration.
#[allow(clippy::too_many_arguments)]
pub fn optimize(
    surface: &Surface,
    colors: &mut [[f32; 3]],
    exemplar: &image::RgbImage,
    alpha: Option<&image::GrayImage>,
    constraint: Option<Constraint>,
    params: &Params,
    sink: &dyn Fn(Event),
    cancel: &CancelToken,
) -> Result<Report> {
    let sw = Stopwatch::start();
    let n = surface.positions.len();
    for (what, len) in [
        ("colours", colors.len()),
        ("normals", surface.normals.len()),
        ("field", surface.field.len()),
    ] {
        if len != n {
            return Err(Error::InvalidInput(format!(
                "texture optimisation: {len} {what} for {n} vertices"
            )));
        }
    }
    if let Some(c) = &constraint
        && (c.curve_distance.len() != n
            || (c.lines.width, c.lines.height)
                != (exemplar.width() as usize, exemplar.height() as usize))
    {
        return Err(Error::InvalidInput(
            "texture optimisation: the constraint does not match the mesh or the exemplar".into(),
        ));
    }
    if !(surface.texel.is_finite() && surface.texel > 0.0) {
        return Err(Error::InvalidInput(format!(
            "texture optimisation: texel size {}",
            surface.texel
        )));
    }
    if params.patch < CELLS || !params.patch.is_multiple_of(CELLS) {
        return Err(Error::InvalidInput(format!(
            "patch size {}: use a multiple of {CELLS}",
            params.patch
        )));
    }
    if !(params.spacing > 0.0 && params.spacing <= 1.0) {
        return Err(Error::InvalidInput(format!(
            "sample spacing {}: use a fraction in (0, 1]",
            params.spacing
        )));
    }
    let ex = Exemplar::new(exemplar, alpha)?;
    // The largest patch the exemplar holds, at most the asked one.
    let fit = (ex.w.min(ex.h).saturating_sub(1) / CELLS) * CELLS;
    let w0 = params.patch.min(fit);
    if w0 < CELLS {
        return Err(Error::InvalidInput(format!(
            "the exemplar ({}x{}) is too small for texture optimisation (needs at least {}x{})",
            ex.w,
            ex.h,
            CELLS + 1,
            CELLS + 1
        )));
    }
    let mut scales = vec![w0];
    if params.multiscale && 2 * w0 <= fit {
        scales.insert(0, 2 * w0);
    }
    let adj = crate::mesh::vertex_adjacency(n, surface.faces);
    let h = surface.texel;
    // λ_p of eq. (4): curve-free components share the farthest finite distance.
    let lambda_of: Box<dyn Fn(usize) -> f32 + Sync> = match &constraint {
        None => Box::new(|_| 1.0),
        Some(c) => {
            let far = c
                .curve_distance
                .iter()
                .copied()
                .filter(|d| d.is_finite())
                .fold(h, f32::max);
            let eps = params.eps;
            let d = c.curve_distance;
            Box::new(move |v| 1.0 / (d[v].min(far) + eps))
        }
    };
    let mut report = Report::default();
    let mut source = vec![[u32::MAX; 2]; n];
    let total_iters = (scales.len() * params.iterations.max(1)) as f32;
    let mut iter_done = 0usize;
    for (si, &w) in scales.iter().enumerate() {
        cancel.check()?;
        let lines = constraint.as_ref().map(|c| c.lines);
        let index = Index::build(
            &ex,
            w,
            lines,
            params.feature_tolerance,
            params.pca_dims,
            params.seed,
        )?;
        cancel.check()?;
        let near = w as f32 / 2.0 * h;
        let samples = poisson_samples(
            surface.positions,
            constraint.as_ref().map(|c| c.curve_distance),
            near,
            params.spacing * w as f32 * h,
            params.seed.wrapping_add(si as u64),
        );
        let reg = regions(surface, &adj, samples, w);
        cancel.check()?;
        let ns = reg.samples.len();
        // per sample: constrained target distance in texels (None = free)
        let target_d: Vec<Option<f32>> = reg
            .samples
            .iter()
            .map(|&p| {
                let c = constraint.as_ref()?;
                let d = c.curve_distance[p as usize];
                (d < near && !index.bins.is_empty()).then_some(d / h)
            })
            .collect();
        let lambda: Vec<f32> = reg.samples.iter().map(|&p| lambda_of(p as usize)).collect();
        let mut sr = ScaleReport {
            patch: w,
            samples: ns,
            constrained: target_d.iter().filter(|d| d.is_some()).count(),
            ..Default::default()
        };
        let mut z: Vec<u32> = vec![u32::MAX; ns];
        let mut dist: Vec<f32> = vec![0.0; ns];
        for it in 0..params.iterations.max(1) {
            cancel.check()?;
            // ---- E: nearest exemplar patch per sample
            let found: Vec<(u32, f32)> = (0..ns)
                .into_par_iter()
                .map_init(
                    || {
                        (
                            vec![0.0f32; DIM],
                            vec![0u32; CELLS * CELLS],
                            Vec::new(),
                            vec![0.0f32; DIM],
                            vec![0.0f32; index.k],
                            Vec::with_capacity(VERIFY + 1),
                            Vec::with_capacity(VERIFY + 1),
                        )
                    },
                    |(cells, cnt, knn, exv, q, cands, best_k), s| {
                        patch_cells(&reg, s, colors, w, cells, cnt);
                        project_into(cells, &index.mean, &index.basis, q);
                        cands.clear();
                        if let Some(dt) = target_d[s] {
                            constrained_knn(
                                &index,
                                lines.expect("lines"),
                                q,
                                dt,
                                params.feature_tolerance,
                                best_k,
                                cands,
                            );
                        }
                        if cands.is_empty() {
                            index.tree.knn(q, VERIFY, knn);
                            cands.extend(knn.iter().map(|&(_, i)| i));
                        }
                        if z[s] != u32::MAX && !cands.contains(&z[s]) {
                            // coherence: keep the previous patch if it still satisfies the constraint
                            let ok = match target_d[s] {
                                Some(dt) => {
                                    let c = index.centres[z[s] as usize] as usize;
                                    (lines.expect("lines").distance[c] - dt).abs()
                                        < params.feature_tolerance
                                }
                                None => true,
                            };
                            if ok {
                                cands.push(z[s]);
                            }
                        }
                        let mut best = (u32::MAX, f32::INFINITY);
                        for &c in cands.iter() {
                            let pix = index.centres[c as usize] as usize;
                            ex.cells(pix % ex.w, pix / ex.w, w, exv);
                            let d = masked_rms(cells, exv, cnt);
                            if d < best.1 {
                                best = (c, d);
                            }
                        }
                        if best.0 == u32::MAX {
                            return best;
                        }
                        // Register at full resolution: the cells see the patch at w/8 texels,
                        // so its phase is found among the shifts within a cell.
                        let pix = index.centres[best.0 as usize] as usize;
                        let (bx, by) = ((pix % ex.w) as isize, (pix / ex.w) as isize);
                        let mut fine = (best.0, f32::INFINITY);
                        for dy in -REFINE..=REFINE {
                            for dx in -REFINE..=REFINE {
                                let (x, y) = (bx + dx, by + dy);
                                if x < 0 || y < 0 || x >= ex.w as isize || y >= ex.h as isize {
                                    continue;
                                }
                                let q = y as usize * ex.w + x as usize;
                                let c = index.slot[q];
                                if c == u32::MAX {
                                    continue;
                                }
                                if let Some(dt) = target_d[s]
                                    && (lines.expect("lines").distance[q] - dt).abs()
                                        >= params.feature_tolerance
                                {
                                    continue;
                                }
                                let d = full_rms(&reg, s, colors, &ex, x as f32, y as f32, fine.1);
                                if d < fine.1 {
                                    fine = (c, d);
                                }
                            }
                        }
                        if fine.1.is_finite() { fine } else { best }
                    },
                )
                .collect();
            let mut changed = 0usize;
            let mut energy = 0.0f64;
            for (s, &(c, d)) in found.iter().enumerate() {
                if c != z[s] {
                    changed += 1;
                }
                z[s] = c;
                dist[s] = if d.is_finite() { d } else { 0.0 };
                energy += dist[s] as f64;
            }
            // ---- M: per vertex, the weighted mean of the covering patches' predictions
            let weight: Vec<f32> = (0..ns)
                .map(|s| {
                    if z[s] == u32::MAX {
                        0.0
                    } else {
                        lambda[s] * dist[s].max(1e-3).powf(params.robust - 2.0)
                    }
                })
                .collect();
            let centre_xy: Vec<[f32; 2]> = z
                .iter()
                .map(|&c| {
                    if c == u32::MAX {
                        [0.0; 2]
                    } else {
                        let pix = index.centres[c as usize] as usize;
                        [(pix % ex.w) as f32, (pix / ex.w) as f32]
                    }
                })
                .collect();
            colors
                .par_iter_mut()
                .zip(source.par_iter_mut())
                .enumerate()
                .for_each(|(v, (col, src))| {
                    let mut acc = [0.0f64; 3];
                    let mut wsum = 0.0f64;
                    let mut strongest = (0.0f32, [u32::MAX; 2]);
                    for &e in &reg.cover[reg.cover_start[v]..reg.cover_start[v + 1]] {
                        let s = reg.owner[e as usize] as usize;
                        let wt = weight[s];
                        if wt <= 0.0 {
                            continue;
                        }
                        let o = reg.offset[e as usize];
                        let (x, y) = (centre_xy[s][0] + o[0], centre_xy[s][1] + o[1]);
                        let c = ex.bilinear(x, y);
                        for k in 0..3 {
                            acc[k] += wt as f64 * c[k] as f64;
                        }
                        wsum += wt as f64;
                        if wt > strongest.0 {
                            let px = x.round().clamp(0.0, (ex.w - 1) as f32) as u32;
                            let py = y.round().clamp(0.0, (ex.h - 1) as f32) as u32;
                            strongest = (wt, [px, py]);
                        }
                    }
                    if wsum > 0.0 {
                        let mean = acc.map(|a| (a / wsum) as f32);
                        // The prediction nearest the weighted mean (the vote's mode, as
                        // Wexler et al. 2007): an exemplar colour, not a blend of misregistered
                        // patches.
                        let mut pick = (f32::INFINITY, mean);
                        for &e in &reg.cover[reg.cover_start[v]..reg.cover_start[v + 1]] {
                            let s = reg.owner[e as usize] as usize;
                            if weight[s] <= 0.0 {
                                continue;
                            }
                            let o = reg.offset[e as usize];
                            let c = ex.nearest(centre_xy[s][0] + o[0], centre_xy[s][1] + o[1]);
                            let d = (0..3).map(|k| (c[k] - mean[k]).powi(2)).sum::<f32>();
                            if d < pick.0 {
                                pick = (d, c);
                            }
                        }
                        *col = pick.1;
                        *src = strongest.1;
                    }
                });
            let frac = changed as f64 / ns.max(1) as f64;
            sr.energy.push(energy / ns.max(1) as f64);
            sr.changed.push(frac);
            iter_done += 1;
            let progress = Progress {
                stage: "optimize",
                level: scales.len() - 1 - si,
                levels: scales.len(),
                iteration: it + 1,
                energy: energy / ns.max(1) as f64,
                elapsed: sw.secs(),
                fraction: (iter_done as f32 / total_iters).min(1.0),
            };
            let signal: Arc<[[f32; 3]]> = colors.to_vec().into();
            sink(Event::Partial { progress, signal });
            if it >= 1 && frac < params.tolerance as f64 {
                break;
            }
        }
        report.scales.push(sr);
    }
    report.source = source;
    report.seconds = sw.secs();
    sink(Event::StageTime("optimize", report.seconds));
    Ok(report)
}

/// Cell means of sample `s`'s patch from the current colours; `cnt` = vertices per cell. Empty
/// cells take the patch mean (they are left out of the verified distance).
fn patch_cells(
    reg: &Regions,
    s: usize,
    colors: &[[f32; 3]],
    w: usize,
    cells: &mut [f32],
    cnt: &mut [u32],
) {
    cells.iter_mut().for_each(|c| *c = 0.0);
    cnt.iter_mut().for_each(|c| *c = 0);
    let step = (w / CELLS) as f32;
    let half = w as f32 / 2.0;
    let mut mean = [0.0f32; 3];
    let mut m = 0u32;
    for e in reg.start[s]..reg.start[s + 1] {
        let o = reg.offset[e];
        let i = (((o[0] + half + 0.5) / step) as usize).min(CELLS - 1);
        let j = (((o[1] + half + 0.5) / step) as usize).min(CELLS - 1);
        let c = colors[reg.vertex[e] as usize];
        let cell = j * CELLS + i;
        for k in 0..3 {
            cells[cell * 3 + k] += c[k];
            mean[k] += c[k];
        }
        cnt[cell] += 1;
        m += 1;
    }
    let m = m.max(1) as f32;
    for cell in 0..CELLS * CELLS {
        for k in 0..3 {
            cells[cell * 3 + k] = if cnt[cell] > 0 {
                cells[cell * 3 + k] / cnt[cell] as f32
            } else {
                mean[k] / m
            };
        }
    }
}

/// RMS colour difference between sample `s`'s patch and the exemplar patch centred at
/// `(cx, cy)`, every covered vertex against its nearest exemplar pixel; stops early (returning
/// infinity) once the sum exceeds `bound`'s.
fn full_rms(
    reg: &Regions,
    s: usize,
    colors: &[[f32; 3]],
    ex: &Exemplar,
    cx: f32,
    cy: f32,
    bound: f32,
) -> f32 {
    let (lo, hi) = (reg.start[s], reg.start[s + 1]);
    let m = (hi - lo).max(1) as f32 * 3.0;
    let cap = if bound.is_finite() {
        bound * bound * m
    } else {
        f32::INFINITY
    };
    let mut sum = 0.0f32;
    for e in lo..hi {
        let o = reg.offset[e];
        let x = ((cx + o[0]).round() as isize).clamp(0, ex.w as isize - 1) as usize;
        let y = ((cy + o[1]).round() as isize).clamp(0, ex.h as isize - 1) as usize;
        let a = ex.px[y * ex.w + x];
        let b = colors[reg.vertex[e] as usize];
        for k in 0..3 {
            let d = a[k] - b[k];
            sum += d * d;
        }
        if sum > cap {
            return f32::INFINITY;
        }
    }
    (sum / m).sqrt()
}

/// RMS difference over the filled cells.
fn masked_rms(a: &[f32], b: &[f32], cnt: &[u32]) -> f32 {
    let mut s = 0.0f32;
    let mut m = 0usize;
    for (cell, &c) in cnt.iter().enumerate() {
        if c == 0 {
            continue;
        }
        for k in 0..3 {
            let d = a[cell * 3 + k] - b[cell * 3 + k];
            s += d * d;
        }
        m += 3;
    }
    if m == 0 { 0.0 } else { (s / m as f32).sqrt() }
}

/// The best [`VERIFY`] constrained centres in PCA space: line distance within `tol` of `dt`.
fn constrained_knn(
    index: &Index,
    lines: &ExemplarLines,
    q: &[f32],
    dt: f32,
    tol: f32,
    best: &mut Vec<(f32, u32)>,
    out: &mut Vec<u32>,
) {
    let b = (dt.round() as usize).min(index.bins.len() - 1);
    best.clear();
    for &i in &index.bins[b] {
        let c = index.centres[i as usize] as usize;
        if (lines.distance[c] - dt).abs() >= tol {
            continue;
        }
        let p = &index.proj[i as usize * index.k..(i as usize + 1) * index.k];
        let d: f32 = p.iter().zip(q).map(|(a, b)| (a - b) * (a - b)).sum();
        if best.len() < VERIFY || d < best[best.len() - 1].0 {
            let at = best.partition_point(|e| e.0 <= d);
            best.insert(at, (d, i));
            best.truncate(VERIFY);
        }
    }
    out.extend(best.iter().map(|&(_, i)| i));
}

/// How `synth` and feature-aligned texturing make their texture.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum Method {
    /// Wei-Levoy neighbourhood matching, coarse to fine (fast).
    #[default]
    Neighbourhood,
    /// Wei-Levoy, then surface texture optimisation ([`optimize`]): whole patches, the
    /// exemplar's structure kept over larger areas, and the feature constraint when asked.
    Optimize,
}

impl Method {
    /// The CLI spelling.
    pub fn as_str(self) -> &'static str {
        match self {
            Method::Neighbourhood => "neighbourhood",
            Method::Optimize => "optimize",
        }
    }
}

impl std::str::FromStr for Method {
    type Err = ();
    fn from_str(s: &str) -> std::result::Result<Self, ()> {
        match s {
            "neighbourhood" | "neighborhood" => Ok(Method::Neighbourhood),
            "optimize" | "optimise" => Ok(Method::Optimize),
            _ => Err(()),
        }
    }
}

/// Optimise a Wei-Levoy result in place ([`optimize`] on its uniform-density mesh, along its
/// orientation field, at its texel size), with the feature constraint when `constraint` gives the
/// salient curves (in the target's coordinates) and the exemplar's principal lines. Updates the
/// mesh colours, the per-file-vertex colours of `target` and the source pixels.
#[allow(clippy::too_many_arguments)]
pub fn optimize_result(
    result: &mut crate::synthesis::SynthResult,
    target: &crate::mesh::TriMesh,
    exemplar: &image::RgbImage,
    alpha: Option<&image::GrayImage>,
    constraint: Option<(&[crate::geometry::Curve], &ExemplarLines)>,
    params: &Params,
    sink: &dyn Fn(Event),
    cancel: &CancelToken,
) -> Result<Report> {
    if result.displacement.is_some() {
        return Err(Error::InvalidInput(
            "texture optimisation works on colours, not on a displacement".into(),
        ));
    }
    let mesh = &result.mesh;
    let normals = match &mesh.normals {
        Some(n) => n.clone(),
        None => crate::geometry::vertex_normals(&mesh.positions, &mesh.faces),
    };
    let mut colors = mesh
        .colors
        .clone()
        .ok_or_else(|| Error::InvalidInput("the synthesis gave no colours".into()))?;
    let distance = constraint.map(|(curves, _)| {
        let adj = crate::mesh::vertex_adjacency(mesh.positions.len(), &mesh.faces);
        let polylines: Vec<crate::geometry::Polyline> = curves
            .iter()
            .map(|c| crate::geometry::Polyline {
                points: &c.points,
                closed: c.closed,
            })
            .collect();
        let near = (2 * params.patch + 2) as f32 * result.spacing;
        crate::geometry::distance_to_polylines(
            &mesh.positions,
            &adj,
            &polylines,
            near,
            f32::INFINITY,
        )
    });
    let surface = Surface {
        positions: &mesh.positions,
        faces: &mesh.faces,
        normals: &normals,
        field: &result.orientation,
        texel: result.spacing,
    };
    let report = optimize(
        &surface,
        &mut colors,
        exemplar,
        alpha,
        distance
            .as_deref()
            .zip(constraint)
            .map(|(d, (_, lines))| Constraint {
                curve_distance: d,
                lines,
            }),
        params,
        sink,
        cancel,
    )?;
    let nv = target.num_vertices();
    result.file_colors = target.to_file_order(&colors[..nv], [0.5; 3]);
    result.source = report.source.clone();
    result.mesh.colors = Some(colors);
    Ok(report)
}
