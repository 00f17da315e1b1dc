//! Per-vertex features for MeshMatch (Chen et al. 2012, §3.2 and §4.1): shape features (Heat
//! Kernel Signature + normal·up, geodesic affinities to correspondences) and geodesic fans of a
//! pre-filtered signal (Zelinka & Garland 2004), plus local tangent frames and the frame-to-frame
//! rotation used to carry patch orientations across edges and levels.

use crate::error::{Error, Result};
use crate::hierarchy::{Hierarchy, Level};
use crate::mesh::Csr;
use crate::work::CancelToken;
use glam::Vec3;
use rayon::prelude::*;
use std::cmp::Reverse;
use std::collections::BinaryHeap;

/// Number of fan radii (MeshMatch: R = 3).
pub const FAN_RADII: usize = 3;
/// Number of fan angles (MeshMatch: A = 18, 20 degrees apart).
pub const FAN_ANGLES: usize = 18;
/// Degrees per fan angle step.
pub const ANGLE_STEP_DEG: f32 = 360.0 / FAN_ANGLES as f32;
/// Number of HKS time scales.
pub const HKS_TIMES: usize = 8;
/// Laplacian eigenpairs the automatic HKS sums over.
pub const HKS_EIGENPAIRS: usize = 120;
/// Automatic shape feature size: 8 HKS scales + normal·up.
pub const SHAPE_DIM: usize = HKS_TIMES + 1;

/// A tangent frame per vertex: `t1`, `t2` orthonormal and orthogonal to the vertex normal.
#[derive(Clone, Debug, Default)]
pub struct Frames {
    /// First tangent (the polar reference direction, angle 0).
    pub t1: Vec<[f32; 3]>,
    /// Second tangent, `n x t1` (angle 90 degrees).
    pub t2: Vec<[f32; 3]>,
}

/// Tangent frame of one normal: the reference direction is the global axis least aligned with
/// the normal, projected into the tangent plane (an arbitrary but smooth choice, as in §3.1).
#[inline]
pub fn frame_of(n: Vec3) -> (Vec3, Vec3) {
    let a = if n.x.abs() < 0.6 {
        Vec3::X
    } else if n.y.abs() < 0.6 {
        Vec3::Y
    } else {
        Vec3::Z
    };
    let t1 = (a - n * n.dot(a)).normalize_or(Vec3::X);
    let t2 = n.cross(t1);
    (t1, t2)
}

/// Tangent frames of a level (see [`frame_of`]).
pub fn tangent_frames(normals: &[[f32; 3]]) -> Frames {
    let (t1, t2) = normals
        .iter()
        .map(|n| {
            let (a, b) = frame_of(Vec3::from(*n));
            (a.to_array(), b.to_array())
        })
        .unzip();
    Frames { t1, t2 }
}

/// Angle (radians) that a direction gains when carried from frame x to frame y: a tangent
/// direction at polar angle θ in x's frame, parallel-transported (minimal rotation taking n_x to
/// n_y), has polar angle θ + result in y's frame.
#[inline]
pub fn transport_angle(nx: Vec3, t1x: Vec3, ny: Vec3, t1y: Vec3, t2y: Vec3) -> f32 {
    // Minimal rotation n_x -> n_y applied to t1x (Rodrigues), then measured in y's frame.
    let axis = nx.cross(ny);
    let s = axis.length();
    let c = nx.dot(ny);
    let t = if s > 1e-6 {
        let k = axis / s;
        t1x * c + k.cross(t1x) * s + k * k.dot(t1x) * (1.0 - c)
    } else {
        t1x
    };
    t.dot(t2y).atan2(t.dot(t1y))
}

/// Transport angles along every directed edge of a level, aligned with `level.adjacency.indices`:
/// entry for (i -> j) is `transport_angle` from i's frame to j's frame.
pub fn edge_transport_angles(level: &Level, frames: &Frames) -> Vec<f32> {
    let adj = &level.adjacency;
    (0..level.len())
        .into_par_iter()
        .flat_map_iter(|i| {
            let ni = Vec3::from(level.normals[i]);
            let ti = Vec3::from(frames.t1[i]);
            adj.row(i).iter().map(move |&j| {
                let j = j as usize;
                transport_angle(
                    ni,
                    ti,
                    Vec3::from(level.normals[j]),
                    Vec3::from(frames.t1[j]),
                    Vec3::from(frames.t2[j]),
                )
            })
        })
        .collect()
}

/// Multi-source graph geodesic distances (Dijkstra along mesh edges) from `sources` on a level.
/// Edge paths overestimate true geodesics by a few percent; used for correspondence affinities.
pub fn edge_geodesics(level: &Level, sources: &[u32]) -> Vec<f32> {
    let n = level.len();
    let mut dist = vec![f32::INFINITY; n];
    let mut heap = BinaryHeap::new();
    for &s in sources {
        if (s as usize) < n {
            dist[s as usize] = 0.0;
            heap.push(Reverse((0u32, s)));
        }
    }
    while let Some(Reverse((dbits, v))) = heap.pop() {
        let d = f32::from_bits(dbits);
        if d > dist[v as usize] {
            continue;
        }
        let pv = Vec3::from(level.positions[v as usize]);
        for &u in level.adjacency.row(v as usize) {
            let nd = d + (Vec3::from(level.positions[u as usize]) - pv).length();
            if nd < dist[u as usize] {
                dist[u as usize] = nd;
                // Non-negative f32 bit patterns order like the floats.
                heap.push(Reverse((nd.to_bits(), u)));
            }
        }
    }
    // Unreachable vertices (other components) get the largest finite distance.
    let maxd = dist
        .iter()
        .copied()
        .filter(|d| d.is_finite())
        .fold(0.0f32, f32::max);
    for d in dist.iter_mut() {
        if !d.is_finite() {
            *d = maxd;
        }
    }
    dist
}

/// Heat Kernel Signature (Sun, Ovsjanikov & Guibas 2009) of a small mesh scaled to unit area:
/// HKS(v, t) = sum_i exp(-λ_i t) φ_i(v)^2 over the smallest eigenpairs of L φ = λ M φ
/// (`geometry::laplacian_eigen`), at 8 times log-spaced in [4 ln10 / λ_max, 4 ln10 / λ_1]
/// (`geometry::hks_times`), divided by the heat trace sum_i exp(-λ_i t) and log-scaled.
/// Returns `n * HKS_TIMES` values.
pub fn hks_scaled(positions: &[[f32; 3]], faces: &[[u32; 3]], k: usize) -> Result<Vec<f32>> {
    let n = positions.len();
    if n < 4 {
        return Err(Error::InvalidMesh("HKS: mesh too small".into()));
    }
    let mut area = 0.0f64;
    for f in faces {
        let p = f.map(|i| Vec3::from(positions[i as usize]).as_dvec3());
        area += 0.5 * (p[1] - p[0]).cross(p[2] - p[0]).length();
    }
    let s = if area > 0.0 { 1.0 / area.sqrt() } else { 1.0 } as f32;
    let pts: Vec<[f32; 3]> = positions.iter().map(|p| p.map(|x| x * s)).collect();
    let k = k.min(n - 1).max(2);
    let (evals, evecs) = crate::geometry::laplacian_eigen(&pts, faces, k)?;
    let times = crate::geometry::hks_times(&evals, HKS_TIMES);
    if times.len() != HKS_TIMES {
        return Err(Error::InvalidMesh("HKS: degenerate spectrum".into()));
    }
    let raw = crate::geometry::hks(&evals, &evecs, &times);
    let traces: Vec<f64> = times
        .iter()
        .map(|&t| {
            evals
                .iter()
                .map(|&l| (-l * t).exp())
                .sum::<f64>()
                .max(1e-30)
        })
        .collect();
    Ok(raw
        .chunks(HKS_TIMES)
        .flat_map(|row| {
            row.iter()
                .zip(&traces)
                .map(|(&h, &tr)| ((h as f64 / tr).max(1e-30)).ln() as f32)
                .collect::<Vec<_>>()
        })
        .collect())
}

/// Automatic shape features per level: 8 HKS scales computed on the level closest to
/// `hks_vertices` and carried down the vertex tree (each vertex takes its parent's value, then two
/// passes of 1-ring averaging) and up it (mean of children), plus normal·up (up = +Y).
/// Returns, per level, `len * SHAPE_DIM` raw (unnormalised) values.
pub fn shape_features(h: &Hierarchy, hks_vertices: usize) -> Result<Vec<Vec<f32>>> {
    shape_features_cancellable(h, hks_vertices, &CancelToken::new())
}

/// [`shape_features`] that returns `Err(Cancelled)` within about 10 ms of `cancel` being set:
/// the eigen-solve (one dense factorisation, about 0.4 s at 2000 vertices) runs on its own thread
/// (see [`crate::work::run_cancellable`]).
pub fn shape_features_cancellable(
    h: &Hierarchy,
    hks_vertices: usize,
    cancel: &CancelToken,
) -> Result<Vec<Vec<f32>>> {
    let lc = hks_level(h, hks_vertices);
    let (positions, faces) = (h.levels[lc].positions.clone(), h.levels[lc].faces.clone());
    let base = crate::work::run_cancellable(cancel, move || {
        hks_scaled(&positions, &faces, HKS_EIGENPAIRS)
    })??;
    Ok(shape_features_from(h, lc, base))
}

/// The level the automatic HKS is computed on: the finest with at most `hks_vertices` vertices
/// (or the coarsest).
pub fn hks_level(h: &Hierarchy, hks_vertices: usize) -> usize {
    (0..h.num_levels())
        .find(|&l| h.levels[l].len() <= hks_vertices)
        .unwrap_or(h.top())
}

/// Shape features per level as [`shape_features`] makes them, from the HKS (`HKS_TIMES` values
/// per vertex) of level `lc`: carried down the vertex tree to the finer levels and up it to the
/// coarser ones, plus normal·up.
pub fn shape_features_from(h: &Hierarchy, lc: usize, base: Vec<f32>) -> Vec<Vec<f32>> {
    let mut hks: Vec<Vec<f32>> = vec![Vec::new(); h.num_levels()];
    hks[lc] = base;
    for l in (0..lc).rev() {
        let lev = &h.levels[l];
        let coarse = &hks[l + 1];
        let mut cur: Vec<f32> = (0..lev.len())
            .flat_map(|v| {
                let p = h.parent(l, v as u32) as usize;
                coarse[p * HKS_TIMES..(p + 1) * HKS_TIMES].to_vec()
            })
            .collect();
        for _ in 0..2 {
            cur = smooth(lev, &cur, HKS_TIMES);
        }
        hks[l] = cur;
    }
    for l in lc + 1..h.num_levels() {
        let n = h.levels[l].len();
        let mut cur = vec![0.0f32; n * HKS_TIMES];
        for p in 0..n {
            let ch = h.children(l, p as u32);
            for &c in ch {
                for k in 0..HKS_TIMES {
                    cur[p * HKS_TIMES + k] += hks[l - 1][c as usize * HKS_TIMES + k];
                }
            }
            for k in 0..HKS_TIMES {
                cur[p * HKS_TIMES + k] /= ch.len().max(1) as f32;
            }
        }
        hks[l] = cur;
    }
    (0..h.num_levels())
        .map(|l| {
            let lev = &h.levels[l];
            let mut out = Vec::with_capacity(lev.len() * SHAPE_DIM);
            for v in 0..lev.len() {
                out.extend_from_slice(&hks[l][v * HKS_TIMES..(v + 1) * HKS_TIMES]);
                out.push(lev.normals[v][1]);
            }
            out
        })
        .collect()
}

/// One pass of 1-ring averaging: x_v <- (x_v + mean of neighbours) / 2, `dim` values per vertex.
pub fn smooth(level: &Level, x: &[f32], dim: usize) -> Vec<f32> {
    let adj = &level.adjacency;
    let mut out = vec![0.0f32; x.len()];
    out.par_chunks_mut(dim).enumerate().for_each(|(v, o)| {
        let row = adj.row(v);
        let inv = 1.0 / row.len().max(1) as f32;
        for k in 0..dim {
            let mut m = 0.0;
            for &u in row {
                m += x[u as usize * dim + k];
            }
            o[k] = 0.5 * x[v * dim + k]
                + if row.is_empty() {
                    0.5 * x[v * dim + k]
                } else {
                    0.5 * m * inv
                };
        }
    });
    out
}

/// Solve the small dense system `a x = b` (n x n, row-major) by Gaussian elimination with partial
/// pivoting; `None` if singular.
fn solve_dense(mut a: Vec<f64>, mut b: Vec<f64>, n: usize) -> Option<Vec<f64>> {
    for c in 0..n {
        let p = (c..n).max_by(|&i, &j| a[i * n + c].abs().total_cmp(&a[j * n + c].abs()))?;
        if a[p * n + c].abs() < 1e-14 {
            return None;
        }
        if p != c {
            for k in 0..n {
                a.swap(c * n + k, p * n + k);
            }
            b.swap(c, p);
        }
        for r in c + 1..n {
            let f = a[r * n + c] / a[c * n + c];
            if f != 0.0 {
                for k in c..n {
                    a[r * n + k] -= f * a[c * n + k];
                }
                b[r] -= f * b[c];
            }
        }
    }
    let mut x = vec![0.0; n];
    for r in (0..n).rev() {
        let mut s = b[r];
        for k in r + 1..n {
            s -= a[r * n + k] * x[k];
        }
        x[r] = s / a[r * n + r];
    }
    Some(x)
}

/// The affine map of MeshMatch §3.2 taking target geodesic-distance vectors to source ones:
/// returns `K x (K + 1)` row-major `[M | b]` with `M g_T + b = g_S` at every constrained pair
/// (rows `target_rows[i]` -> `source_rows[i]`, each a K-vector). Among all exact solutions we
/// take the one of minimum Frobenius distance to the identity `[I | 0]` (the "minimum-norm"
/// correction, so that already-agreeing shapes keep M = I); with more equations than unknowns
/// (one-to-many) it is the ridge-regularised least-squares fit. Closed form per output row r:
/// m_r = e_r + Aᵀ (A Aᵀ + εI)⁻¹ (y_r − A e_r), A = rows [g_T, 1].
pub fn min_norm_affine(target_rows: &[Vec<f32>], source_rows: &[Vec<f32>], k: usize) -> Vec<f64> {
    let p = target_rows.len();
    let cols = k + 1;
    let a: Vec<f64> = target_rows
        .iter()
        .flat_map(|g| g.iter().map(|&x| x as f64).chain(std::iter::once(1.0)))
        .collect();
    let scale = a.iter().map(|x| x * x).sum::<f64>() / p.max(1) as f64;
    let mut aat = vec![0.0f64; p * p];
    for i in 0..p {
        for j in 0..p {
            aat[i * p + j] = (0..cols).map(|c| a[i * cols + c] * a[j * cols + c]).sum();
        }
        aat[i * p + i] += 1e-6 * scale.max(1e-12);
    }
    let mut out = vec![0.0f64; k * cols];
    for r in 0..k {
        // Residual of the identity row.
        let resid: Vec<f64> = (0..p)
            .map(|i| source_rows[i][r] as f64 - a[i * cols + r])
            .collect();
        let y = solve_dense(aat.clone(), resid, p).unwrap_or_else(|| vec![0.0; p]);
        for c in 0..cols {
            let mut m = if c == r { 1.0 } else { 0.0 };
            for i in 0..p {
                m += a[i * cols + c] * y[i];
            }
            out[r * cols + c] = m;
        }
    }
    out
}

/// exp(-x) for x >= 0, relative error below 1e-4 (0 past x = 87, where f32 turns subnormal): 2^-x·log2(e) split into a power of
/// two and a degree-6 Taylor polynomial (much cheaper than libm's `expf` in the fan builder's
/// hot loop, where it only weights taps).
#[inline]
pub(crate) fn exp_neg(x: f32) -> f32 {
    if x >= 87.0 {
        return 0.0;
    }
    let y = x.max(0.0) * std::f32::consts::LOG2_E;
    // `y` is in [0, 126): truncation is its floor, without a call to libm's `floorf`
    let n = (y as i32) as f32;
    let t = (y - n) * std::f32::consts::LN_2;
    let p = 1.0
        - t * (1.0
            - t * (0.5
                - t * (1.0 / 6.0 - t * (1.0 / 24.0 - t * (1.0 / 120.0 - t * (1.0 / 720.0))))));
    p * f32::from_bits(((127 - n as i32) as u32) << 23)
}

/// Most vertices one fan gathers (dense spots of non-uniform meshes stop early; the walk is
/// breadth-first, so the nearest vertices come first).
pub const MAX_FAN_VERTICES: usize = 400;

/// Entries kept per fan bin by [`FanSampler`].
pub const FAN_TAPS: usize = 3;

/// A precomputed fan sampling table of one level: for every vertex and fan bin, the `FAN_TAPS`
/// vertices with the largest Gaussian splat weights and their normalised weights. Building it
/// costs one geodesic-neighbourhood walk per vertex; applying it to a signal is a cheap gather,
/// so a target's fans can follow its signal after every M-step (MeshMatch gathers each target
/// fan as its E-step visits the vertex, [`FanSampler::gather`]).
///
/// Compact layout (at a million vertices the table is the largest structure of a transfer):
/// each vertex lists its distinct tap vertices once (about 40, never more than
/// `R * A * FAN_TAPS` = 162), a tap is a one-byte index into that list, and a bin stores two
/// 16-bit weights, the third being what is left of 1. 162 + 216 + 5 bytes plus 4 per listed
/// vertex, against 648 + 324 for u32 indices and three u16 weights.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FanSampler {
    /// Per chunk of the build (consecutive vertices of the visiting order), the tap lists of its
    /// vertices: the table is never copied whole to concatenate them.
    lists: Vec<Vec<u32>>,
    /// The build chunk that listed `v`'s taps.
    part: Vec<u16>,
    /// `lists[part[v]][off[v]..off[v] + len[v]]`: the distinct tap vertices of `v`.
    off: Vec<u32>,
    len: Vec<u8>,
    /// `tap[(v * R * A + bin) * FAN_TAPS + k]`: index into `v`'s list.
    tap: Vec<u8>,
    /// `w[(v * R * A + bin) * 2 + k]`, `k < 2`, in units of `1 / 65535`; the third weight is
    /// `65535 - w0 - w1`.
    w: Vec<u16>,
}

/// A flat table of rows of `width` values written by parallel tasks in an order of their own
/// (the vertices' visiting order), each row by exactly one task.
struct ScatterRows<'a, T> {
    ptr: *mut T,
    rows: usize,
    width: usize,
    _data: std::marker::PhantomData<&'a mut [T]>,
}

// SAFETY: the rows handed out are disjoint (the callers' contract on `row`), so sending the
// table to other threads is as sound as splitting a `&mut [T]` into chunks.
unsafe impl<T: Send> Send for ScatterRows<'_, T> {}
// SAFETY: as above: shared use only ever produces disjoint rows.
unsafe impl<T: Send> Sync for ScatterRows<'_, T> {}

impl<'a, T> ScatterRows<'a, T> {
    fn new(data: &'a mut [T], width: usize) -> Self {
        let width = width.max(1);
        ScatterRows {
            ptr: data.as_mut_ptr(),
            rows: data.len() / width,
            width,
            _data: std::marker::PhantomData,
        }
    }

    /// Row `r`, mutably.
    ///
    /// # Safety
    /// No other reference to row `r` may exist while the returned one lives: every row is
    /// taken at most once (callers visit a permutation of the rows).
    #[inline]
    #[allow(clippy::mut_from_ref)]
    unsafe fn row(&self, r: usize) -> &mut [T] {
        assert!(r < self.rows, "row {r} of {}", self.rows);
        // SAFETY: in bounds (checked above), and unaliased by the caller's contract.
        unsafe { std::slice::from_raw_parts_mut(self.ptr.add(r * self.width), self.width) }
    }
}

/// Whether `order` lists each of `0..n` exactly once.
fn is_permutation(order: &[u32], n: usize) -> bool {
    if order.len() != n {
        return false;
    }
    let mut seen = vec![false; n];
    for &v in order {
        match seen.get_mut(v as usize) {
            Some(s) if !*s => *s = true,
            _ => return false,
        }
    }
    true
}

/// Scale of [`FanSampler`]'s weights.
const WEIGHT_ONE: f32 = 65535.0;

impl FanSampler {
    /// Geodesic fans (Zelinka & Garland 2004, as used by MeshMatch §3.1) of one level: every
    /// vertex's bins at polar positions (r_k = (k+1)/R * radius, θ_a = a * 20°) in its tangent
    /// frame. The surrounding vertices (breadth-first walk up to radius + 2.5σ, at most `MAX_FAN_VERTICES`) are unfolded into the
    /// tangent plane (direction projected, length kept = Euclidean distance as the local geodesic)
    /// and weighted by exp(-|x - bin|² / 2σ²), σ = 0.6 mean edge lengths; the `FAN_TAPS` largest
    /// weights are kept and normalised. Empty bins take the entries one ring inwards (the centre
    /// vertex for the first ring).
    pub fn new(level: &Level, frames: &Frames, radius: f32) -> FanSampler {
        Self::new_cancellable(level, frames, radius, &CancelToken::new())
            .expect("an un-cancelled token never stops the build")
    }

    /// [`FanSampler::new`] that stops within one chunk of vertices (1/64 of the level, at least
    /// 256) once `cancel` is set, returning `Err(Cancelled)`: at a million vertices a level's
    /// table takes seconds, longer than a user waits for Cancel.
    pub fn new_cancellable(
        level: &Level,
        frames: &Frames,
        radius: f32,
        cancel: &CancelToken,
    ) -> Result<FanSampler> {
        let order = crate::geometry::morton_order(&level.positions);
        Self::with_order(level, frames, radius, &order, cancel)
    }

    /// [`FanSampler::new_cancellable`] visiting the vertices in the level's own order, on the
    /// level itself (no renumbered copy): for levels already numbered in a cache-friendly order,
    /// as MeshMatch's working meshes and their hierarchies are (Morton order, see
    /// `meshmatch::prepare`).
    pub fn in_vertex_order(
        level: &Level,
        frames: &Frames,
        radius: f32,
        cancel: &CancelToken,
    ) -> Result<FanSampler> {
        let identity: Vec<u32> = (0..level.len() as u32).collect();
        Self::with_order(level, frames, radius, &identity, cancel)
    }

    /// [`FanSampler::new_cancellable`] visiting the vertices in `order` (a permutation of the
    /// level's vertices; anything else is an `InvalidInput` error). The table is the same for
    /// every order; the order decides how well the walks around consecutive vertices share the
    /// cache (`examples/fan_order` measures the identity against the Morton order).
    pub fn with_order(
        level: &Level,
        frames: &Frames,
        radius: f32,
        order: &[u32],
        cancel: &CancelToken,
    ) -> Result<FanSampler> {
        let n = level.len();
        if !is_permutation(order, n) {
            return Err(Error::InvalidInput(format!(
                "a fan table's visiting order must list each of the {n} vertices once"
            )));
        }
        let nb = FAN_RADII * FAN_ANGLES;
        let per = nb * FAN_TAPS;
        let mut tap =
            crate::error::try_filled(n.saturating_mul(per), 0u8, "the fan sampling table")?;
        let mut wts =
            crate::error::try_filled(n.saturating_mul(nb * 2), 0u16, "the fan sampling weights")?;
        let sigma = 0.6 * level.mean_edge;
        // Gaussian cut-off at 2.5σ (weight 0.044).
        let cut = 2.5 * sigma;
        let reach = radius + cut;
        let inv2s2 = 1.0 / (2.0 * sigma * sigma);
        let dirs: [[f32; 2]; FAN_ANGLES] = std::array::from_fn(|a| {
            let th = (a as f32 * ANGLE_STEP_DEG).to_radians();
            [th.cos(), th.sin()]
        });
        // Few enough chunks that the per-chunk visit stamps stay cheap on large meshes.
        let chunk = (n / 64).max(256);
        let cut2 = cut * cut;
        let rks: [f32; FAN_RADII] =
            std::array::from_fn(|r| (r + 1) as f32 / FAN_RADII as f32 * radius);
        // per chunk: its vertices' tap lists, concatenated, and their lengths
        let tap_rows = ScatterRows::new(&mut tap, per);
        let w_rows = ScatterRows::new(&mut wts, nb * 2);
        // The walks run on a copy of the level renumbered in the visiting order, so the
        // neighbourhoods of consecutive vertices are close in memory too (the table itself is
        // in the level's numbering; adjacency rows keep their order, so every walk visits the
        // same vertices in the same order as on the level).
        let walk = WalkMesh::new(level, order);
        let job = TableJob {
            walk: &walk,
            order,
            frames,
            n,
            nb,
            cut,
            cut2,
            reach,
            inv2s2,
            dirs,
            rks,
            tap_rows: &tap_rows,
            w_rows: &w_rows,
            cancel,
        };
        let lists: Vec<(Vec<u32>, Vec<u8>)> = (0..n.div_ceil(chunk))
            .into_par_iter()
            // SAFETY: `order` is a permutation (checked above) and the ranges are disjoint.
            .map(|c| unsafe { job.chunk(c * chunk..((c + 1) * chunk).min(n)) })
            .collect();
        cancel.check()?;
        let mut off = vec![0u32; n];
        let mut len = vec![0u8; n];
        let mut part = vec![0u16; n];
        let mut chunks = Vec::with_capacity(lists.len());
        for ((ci, (vs, counts)), visited) in lists.into_iter().enumerate().zip(order.chunks(chunk))
        {
            let mut o = 0u32;
            for (c, &v) in counts.into_iter().zip(visited) {
                let v = v as usize;
                off[v] = o;
                len[v] = c;
                part[v] = ci as u16;
                o += c as u32;
            }
            chunks.push(vs);
        }
        Ok(FanSampler {
            lists: chunks,
            part,
            off,
            len,
            tap,
            w: wts,
        })
    }

    /// The distinct tap vertices of `v`.
    #[inline]
    fn list(&self, v: usize) -> &[u32] {
        let o = self.off[v] as usize;
        &self.lists[self.part[v] as usize][o..o + self.len[v] as usize]
    }

    /// Tap vertices and weights of bin `b` of vertex `v`.
    #[inline]
    pub fn taps(&self, v: usize, b: usize) -> [(u32, f32); FAN_TAPS] {
        let i = v * FAN_RADII * FAN_ANGLES + b;
        Self::decode(
            self.list(v),
            &self.tap[i * FAN_TAPS..(i + 1) * FAN_TAPS],
            &self.w[i * 2..i * 2 + 2],
        )
    }

    /// One bin of a vertex whose tap list is `list`, from its `FAN_TAPS` tap indices and two
    /// stored weights: the one decoder of the compact layout ([`FanSampler::taps`] and
    /// [`FanSampler::gather`] go through it).
    #[inline(always)]
    fn decode(list: &[u32], tap: &[u8], w: &[u16]) -> [(u32, f32); FAN_TAPS] {
        let (w0, w1) = (w[0], w[1]);
        let w2 = u16::MAX - w0 - w1;
        let s = 1.0 / WEIGHT_ONE;
        [
            (list[tap[0] as usize], w0 as f32 * s),
            (list[tap[1] as usize], w1 as f32 * s),
            (list[tap[2] as usize], w2 as f32 * s),
        ]
    }

    /// Vertex `v`'s fan of `sig` (`channels` values per vertex, already pre-filtered as
    /// [`FanSampler::fans`] does with [`smooth`]) into `fan` (`R * A * channels` values, layout
    /// as [`FanSampler::fans`]'s rows): the one gather, so a fan taken alone (MeshMatch's
    /// E-step takes the target's as it visits a vertex) has the same bits as the whole table's.
    #[inline(always)]
    pub fn gather(&self, v: usize, sig: &[f32], channels: usize, fan: &mut [f32]) {
        match channels {
            // colour: whole pixels, one bounds check per tap
            3 => self.gather_n(v, sig.as_chunks::<3>().0, fan.as_chunks_mut::<3>().0),
            c => {
                let nb = FAN_RADII * FAN_ANGLES;
                let list = self.list(v);
                let tap = &self.tap[v * nb * FAN_TAPS..(v + 1) * nb * FAN_TAPS];
                let w = &self.w[v * nb * 2..(v + 1) * nb * 2];
                let bins = tap.chunks_exact(FAN_TAPS).zip(w.chunks_exact(2));
                for (dst, (t, w)) in fan.chunks_exact_mut(c).zip(bins) {
                    let [(u0, w0), (u1, w1), (u2, w2)] = Self::decode(list, t, w);
                    let (u0, u1, u2) = (u0 as usize * c, u1 as usize * c, u2 as usize * c);
                    for ch in 0..c {
                        dst[ch] = w0 * sig[u0 + ch] + w1 * sig[u1 + ch] + w2 * sig[u2 + ch];
                    }
                }
            }
        }
    }

    /// [`FanSampler::gather`] of `N` channels per vertex.
    #[inline(always)]
    fn gather_n<const N: usize>(&self, v: usize, sig: &[[f32; N]], fan: &mut [[f32; N]]) {
        let nb = FAN_RADII * FAN_ANGLES;
        let list = self.list(v);
        let tap = &self.tap[v * nb * FAN_TAPS..(v + 1) * nb * FAN_TAPS];
        let w = &self.w[v * nb * 2..(v + 1) * nb * 2];
        let bins = tap.chunks_exact(FAN_TAPS).zip(w.chunks_exact(2));
        for (dst, (t, w)) in fan[..nb].iter_mut().zip(bins) {
            let [(u0, w0), (u1, w1), (u2, w2)] = Self::decode(list, t, w);
            let (a, b, c) = (&sig[u0 as usize], &sig[u1 as usize], &sig[u2 as usize]);
            for ch in 0..N {
                dst[ch] = w0 * a[ch] + w1 * b[ch] + w2 * c[ch];
            }
        }
    }

    /// Fans of a signal with `channels` values per vertex, pre-filtered by one pass of 1-ring
    /// averaging before the gather. Layout: `fans[((v * R + r) * A + a) * C + c]`.
    pub fn fans(&self, level: &Level, signal: &[f32], channels: usize) -> Vec<f32> {
        let mut out = Vec::new();
        self.fans_into(level, signal, channels, &mut out);
        out
    }

    /// [`FanSampler::fans`] into an existing buffer (resized as needed), so the EM loop reuses
    /// one allocation instead of holding the old and the new fans at once.
    pub fn fans_into(&self, level: &Level, signal: &[f32], channels: usize, out: &mut Vec<f32>) {
        let c = channels;
        let sig = smooth(level, signal, c);
        let nb = FAN_RADII * FAN_ANGLES;
        out.resize(level.len() * nb * c, 0.0);
        // In vertex order: visiting in the build's Morton order made the gather slower
        // (`examples/fan_order`: the scattered row writes cost more than the taps' locality gains).
        out.par_chunks_mut(nb * c)
            .enumerate()
            .for_each(|(v, fan)| self.gather(v, &sig, c, fan));
    }
}

/// A level renumbered in a visiting order, for [`FanSampler::with_order`]'s walks: walk vertex
/// `i` is level vertex `order[i]`, and its adjacency row lists the same neighbours in the same
/// order as the level's.
/// The level itself, not a copy, when the order is the identity (a level already numbered in a
/// cache-friendly order, as MeshMatch's working meshes are).
struct WalkMesh<'a> {
    positions: std::borrow::Cow<'a, [[f32; 3]]>,
    adjacency: std::borrow::Cow<'a, Csr>,
}

impl<'a> WalkMesh<'a> {
    fn new(level: &'a Level, order: &[u32]) -> WalkMesh<'a> {
        use std::borrow::Cow;
        if order.iter().enumerate().all(|(i, &v)| v as usize == i) {
            return WalkMesh {
                positions: Cow::Borrowed(&level.positions),
                adjacency: Cow::Borrowed(&level.adjacency),
            };
        }
        let n = order.len();
        let inv = crate::geometry::inverse_order(order);
        let positions = order.iter().map(|&v| level.positions[v as usize]).collect();
        let mut offsets = Vec::with_capacity(n + 1);
        offsets.push(0u32);
        let mut indices = Vec::with_capacity(level.adjacency.indices.len());
        for &v in order {
            indices.extend(
                level
                    .adjacency
                    .row(v as usize)
                    .iter()
                    .map(|&w| inv[w as usize]),
            );
            offsets.push(indices.len() as u32);
        }
        WalkMesh {
            positions: Cow::Owned(positions),
            adjacency: Cow::Owned(Csr { offsets, indices }),
        }
    }
}

/// What every chunk of [`FanSampler::with_order`]'s build shares.
struct TableJob<'a, 'b> {
    walk: &'a WalkMesh<'a>,
    /// Level vertex of every walk vertex (the visiting order).
    order: &'a [u32],
    frames: &'a Frames,
    n: usize,
    nb: usize,
    cut: f32,
    cut2: f32,
    reach: f32,
    inv2s2: f32,
    dirs: [[f32; 2]; FAN_ANGLES],
    rks: [f32; FAN_RADII],
    tap_rows: &'a ScatterRows<'b, u8>,
    w_rows: &'a ScatterRows<'b, u16>,
    cancel: &'a CancelToken,
}

impl TableJob<'_, '_> {
    /// The table rows of the vertices `vs` (consecutive in the visiting order): their tap lists,
    /// concatenated, and their lengths. Compiled twice, for AVX2 where the processor has it (the
    /// 18-bin loops then run 8 wide) and for the baseline; both give the same bits (no fused
    /// multiply-adds).
    ///
    /// # Safety
    /// `order` must be a permutation of the level's vertices, and no two calls on one job may
    /// run on overlapping ranges: each writes the table rows of `order[vs]` through
    /// `ScatterRows`, which hands out rows without checking that they are taken once.
    unsafe fn chunk(&self, vs: std::ops::Range<usize>) -> (Vec<u32>, Vec<u8>) {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the processor supports AVX2 (checked just above).
            // and the caller keeps `chunk`'s contract.
            return unsafe { self.chunk_avx2(vs) };
        }
        // SAFETY: the caller keeps `chunk`'s contract.
        unsafe { self.chunk_body(vs) }
    }

    /// # Safety
    /// As [`TableJob::chunk`], and the processor must support AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn chunk_avx2(&self, vs: std::ops::Range<usize>) -> (Vec<u32>, Vec<u8>) {
        // SAFETY: the caller keeps `chunk`'s contract.
        unsafe { self.chunk_body(vs) }
    }

    /// # Safety
    /// As [`TableJob::chunk`].
    #[inline(always)]
    unsafe fn chunk_body(&self, vs: std::ops::Range<usize>) -> (Vec<u32>, Vec<u8>) {
        let TableJob {
            walk,
            order,
            frames,
            n,
            nb,
            cut,
            cut2,
            reach,
            inv2s2,
            dirs,
            rks,
            tap_rows,
            w_rows,
            cancel,
        } = *self;
        let mut verts: Vec<u32> = Vec::new();
        let mut counts: Vec<u8> = Vec::new();
        if cancel.is_cancelled() {
            return (verts, counts);
        }
        let mut stamp = vec![u32::MAX; n];
        let mut local = vec![u8::MAX; n];
        // the walk's queue; its last slot takes the writes of rejected neighbours
        let mut queue = [0u32; MAX_FAN_VERTICES + 1];
        let mut qlen;
        // Top taps per bin as (squared distance, vertex), nearest first: ranking by
        // distance is ranking by Gaussian weight, so exp runs only on the kept taps.
        let mut top = vec![(f32::INFINITY, 0u32); nb * FAN_TAPS];
        // per bin, the squared distance a vertex must beat to enter its top list: the
        // last kept tap's, capped at the Gaussian cut-off
        let mut worst = [cut2; FAN_RADII * FAN_ANGLES];
        // final (vertex, weight) per tap
        let mut fin = vec![(0u32, 0u16); nb * FAN_TAPS];
        verts.reserve(vs.len() * 48);
        counts.reserve(vs.len());
        // `v`, `u` and the taps below are walk vertices; `vl` is `v` on the level
        for v in vs {
            let vl = order[v] as usize;
            // SAFETY: `order` is a permutation and the ranges of the calls are disjoint
            // (`chunk`'s contract), so row `vl` is taken here and nowhere else.
            let (fi, fw) = unsafe { (tap_rows.row(vl), w_rows.row(vl)) };
            let pv = Vec3::from(walk.positions[v]);
            let t1 = Vec3::from(frames.t1[vl]);
            let t2 = Vec3::from(frames.t2[vl]);
            top.iter_mut().for_each(|x| *x = (f32::INFINITY, v as u32));
            worst.fill(cut2);
            queue[0] = v as u32;
            qlen = 1;
            stamp[v] = v as u32;
            let mut head = 0;
            while head < qlen {
                let u = queue[head] as usize;
                head += 1;
                let d = Vec3::from(walk.positions[u]) - pv;
                let len = d.length();
                let (x, y) = (d.dot(t1), d.dot(t2));
                let pl = (x * x + y * y).sqrt();
                let (x, y) = if pl > 1e-12 {
                    (x * len / pl, y * len / pl)
                } else {
                    (0.0, 0.0)
                };
                let rho = len;
                // |x - bin|² = ρ² + r_k² - 2 r_k (x cos θ_a + y sin θ_a): the 18
                // projections are shared by the three rings, so each ring costs one
                // multiply-add per bin (cheaper than locating the angular window with
                // atan2/acos).
                let mut any = false;
                for &rk in rks.iter() {
                    any |= (rho - rk).abs() < cut;
                }
                if !any {
                    continue_walk(walk, &mut queue, &mut qlen, &mut stamp, u, v, pv, reach);
                    continue;
                }
                let mut proj = [0.0f32; FAN_ANGLES];
                for (a, p) in proj.iter_mut().enumerate() {
                    *p = x * dirs[a][0] + y * dirs[a][1];
                }
                let rho2 = x * x + y * y;
                for (r, &rk) in rks.iter().enumerate() {
                    if (rho - rk).abs() >= cut {
                        continue;
                    }
                    let base = rho2 + rk * rk;
                    let two_rk = 2.0 * rk;
                    // The ring's 18 distances and which of them enter a top list, in a
                    // branch-free pass; only those then take the (rare) sorted insert.
                    let wr = &worst[r * FAN_ANGLES..(r + 1) * FAN_ANGLES];
                    let mut d2s = [0.0f32; FAN_ANGLES];
                    let mut enter = 0u32;
                    for a in 0..FAN_ANGLES {
                        let d2 = (base - two_rk * proj[a]).max(0.0);
                        d2s[a] = d2;
                        enter |= ((d2 < wr[a]) as u32) << a;
                    }
                    while enter != 0 {
                        let a = enter.trailing_zeros() as usize;
                        enter &= enter - 1;
                        let d2 = d2s[a];
                        let b = r * FAN_ANGLES + a;
                        let t = &mut top[b * FAN_TAPS..(b + 1) * FAN_TAPS];
                        // Insert into the sorted (ascending) top list.
                        let mut j = FAN_TAPS - 1;
                        while j > 0 && t[j - 1].0 > d2 {
                            t[j] = t[j - 1];
                            j -= 1;
                        }
                        t[j] = (d2, u as u32);
                        worst[b] = t[FAN_TAPS - 1].0.min(cut2);
                    }
                }
                continue_walk(walk, &mut queue, &mut qlen, &mut stamp, u, v, pv, reach);
            }
            for e in top.iter_mut() {
                e.0 = if e.0.is_finite() {
                    exp_neg(e.0 * inv2s2)
                } else {
                    0.0
                };
            }
            for b in 0..nb {
                let t = &top[b * FAN_TAPS..(b + 1) * FAN_TAPS];
                let sum: f32 = t.iter().map(|x| x.0).sum();
                let o = b * FAN_TAPS;
                if sum > 1e-3 {
                    // the first two rounded, the last what is left, so they sum to 1
                    let w0 = (t[0].0 / sum * WEIGHT_ONE).round() as u16;
                    let w1 = ((t[1].0 / sum * WEIGHT_ONE).round() as u16).min(u16::MAX - w0);
                    fin[o] = (t[0].1, w0);
                    fin[o + 1] = (t[1].1, w1);
                    fin[o + 2] = (t[2].1, u16::MAX - w0 - w1);
                } else if b < FAN_ANGLES {
                    fin[o] = (v as u32, u16::MAX);
                    fin[o + 1] = (v as u32, 0);
                    fin[o + 2] = (v as u32, 0);
                } else {
                    let inner = (b - FAN_ANGLES) * FAN_TAPS;
                    for j in 0..FAN_TAPS {
                        fin[o + j] = fin[inner + j];
                    }
                }
            }
            // the vertex's distinct taps, in order of first use
            for &(u, _) in &fin {
                local[u as usize] = u8::MAX;
            }
            let first = verts.len();
            for (j, &(u, w)) in fin.iter().enumerate() {
                let l = &mut local[u as usize];
                if *l == u8::MAX {
                    *l = (verts.len() - first) as u8;
                    verts.push(order[u as usize]);
                }
                fi[j] = *l;
                let (b, k) = (j / FAN_TAPS, j % FAN_TAPS);
                if k < 2 {
                    fw[b * 2 + k] = w;
                }
            }
            counts.push((verts.len() - first) as u8);
        }
        verts.shrink_to_fit();
        (verts, counts)
    }
}

/// One step of [`FanSampler::new`]'s breadth-first walk around `v`: queue the unvisited
/// neighbours of `u` within `reach` (Euclidean) of `pv`, up to [`MAX_FAN_VERTICES`]. Branch-free:
/// every neighbour is written at the queue's end, and the end moves on only for one that is new
/// and within reach (whether a neighbour was seen before is as good as random to the processor).
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn continue_walk(
    level: &WalkMesh,
    queue: &mut [u32; MAX_FAN_VERTICES + 1],
    qlen: &mut usize,
    stamp: &mut [u32],
    u: usize,
    v: usize,
    pv: Vec3,
    reach: f32,
) {
    let reach2 = reach * reach;
    for &w in level.adjacency.row(u) {
        let wi = w as usize;
        let fresh = stamp[wi] != v as u32;
        stamp[wi] = v as u32;
        let near = (Vec3::from(level.positions[wi]) - pv).length_squared() <= reach2;
        queue[*qlen] = w;
        *qlen += (fresh & near & (*qlen < MAX_FAN_VERTICES)) as usize;
    }
}

/// Geodesic fans of a signal on one level ([`FanSampler::new`] then [`FanSampler::fans`]).
pub fn compute_fans(
    level: &Level,
    frames: &Frames,
    signal: &[f32],
    channels: usize,
    radius: f32,
) -> Vec<f32> {
    FanSampler::new(level, frames, radius).fans(level, signal, channels)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid(n: usize) -> Level {
        let (p, f) = crate::testdata::grid(n);
        Level::new(p, f)
    }

    #[test]
    fn fan_table_build_honours_cancel_and_matches_when_not_cancelled() {
        let l = grid(40);
        let frames = tangent_frames(&l.normals);
        let stopped = CancelToken::new();
        stopped.cancel();
        assert!(matches!(
            FanSampler::new_cancellable(&l, &frames, 2.5, &stopped),
            Err(Error::Cancelled)
        ));
        let a = FanSampler::new(&l, &frames, 2.5);
        let b = FanSampler::new_cancellable(&l, &frames, 2.5, &CancelToken::new()).unwrap();
        assert_eq!(a, b);
        // every bin's weights sum to one and its taps lie within the fan's reach
        let reach = 2.5 * l.mean_edge + 2.5 * 0.6 * l.mean_edge;
        for v in 0..l.len() {
            for bin in 0..FAN_RADII * FAN_ANGLES {
                let t = a.taps(v, bin);
                let sum: f32 = t.iter().map(|x| x.1).sum();
                assert!((sum - 1.0).abs() < 1e-6, "{sum}");
                for (u, w) in t {
                    let d =
                        Vec3::from(l.positions[u as usize]).distance(Vec3::from(l.positions[v]));
                    assert!(w == 0.0 || d <= reach * 1.001, "{d} > {reach}");
                }
            }
        }
    }

    #[test]
    fn the_visiting_order_changes_neither_the_table_nor_the_fans() {
        // a sphere of 4,584 vertices: 18 build chunks, so rows, lists and chunk ids all scatter
        let (p, f) = crate::testdata::uv_sphere(80, 58);
        let l = Level::new(p, f);
        let n = l.len();
        let frames = tangent_frames(&l.normals);
        let r = 2.5 * l.mean_edge;
        let cancel = CancelToken::new();
        let identity: Vec<u32> = (0..n as u32).collect();
        let scrambled: Vec<u32> = (0..n).map(|i| ((i * 2741) % n) as u32).collect();
        let plain = FanSampler::with_order(&l, &frames, r, &identity, &cancel).unwrap();
        let signal: Vec<f32> = l
            .positions
            .iter()
            .flat_map(|q| [q[0], q[1] * q[2], (3.0 * q[2]).sin()])
            .collect();
        let want = plain.fans(&l, &signal, 3);
        for other in [
            FanSampler::new(&l, &frames, r),
            FanSampler::with_order(&l, &frames, r, &scrambled, &cancel).unwrap(),
        ] {
            for v in 0..n {
                for b in 0..FAN_RADII * FAN_ANGLES {
                    assert_eq!(plain.taps(v, b), other.taps(v, b), "vertex {v}, bin {b}");
                }
            }
            assert_eq!(want, other.fans(&l, &signal, 3));
        }
        // One vertex's fan alone (as MeshMatch's E-step takes the target's) has the bits of the
        // whole table's row, and is the decoded taps' weighted sum of the pre-filtered signal.
        let sig = smooth(&l, &signal, 3);
        let nb = FAN_RADII * FAN_ANGLES;
        let mut fan = vec![f32::NAN; nb * 3];
        for v in 0..n {
            plain.gather(v, &sig, 3, &mut fan);
            assert_eq!(fan, want[v * nb * 3..(v + 1) * nb * 3], "vertex {v}");
            for b in 0..nb {
                let [(u0, w0), (u1, w1), (u2, w2)] = plain.taps(v, b);
                let (u0, u1, u2) = (u0 as usize * 3, u1 as usize * 3, u2 as usize * 3);
                for c in 0..3 {
                    let x = w0 * sig[u0 + c] + w1 * sig[u1 + c] + w2 * sig[u2 + c];
                    assert_eq!(fan[b * 3 + c], x, "vertex {v}, bin {b}");
                }
            }
        }
        // an order that is not a permutation is refused, not a data race
        for bad in [
            vec![0u32; n],
            (0..n as u32 - 1).collect(),
            (1..=n as u32).collect(),
        ] {
            assert!(matches!(
                FanSampler::with_order(&l, &frames, r, &bad, &cancel),
                Err(Error::InvalidInput(_))
            ));
        }
    }

    #[test]
    fn exp_neg_matches_exp() {
        assert_eq!(exp_neg(100.0), 0.0);
        for i in 0..8_700 {
            let x = i as f32 * 0.01;
            let (a, b) = (exp_neg(x), (-x).exp());
            assert!((a - b).abs() <= 1e-4 * b, "exp(-{x}): {a} vs {b}");
        }
    }

    #[test]
    fn fans_rotate_by_cyclic_shift() {
        // A linear ramp along x: fan of the centre vertex; rotating the ramp by 90 degrees shifts the
        // fan's angle index by 90 / 20 = 4.5 -> compare against a 180-degree rotation (9 steps).
        let lev = grid(21);
        let fr = tangent_frames(&lev.normals);
        let ramp: Vec<f32> = lev.positions.iter().map(|p| p[0]).collect();
        let neg: Vec<f32> = lev.positions.iter().map(|p| -p[0]).collect();
        let v = 10 * 21 + 10;
        let fa = compute_fans(&lev, &fr, &ramp, 1, 2.5);
        let fb = compute_fans(&lev, &fr, &neg, 1, 2.5);
        let per = FAN_RADII * FAN_ANGLES;
        let a = &fa[v * per..(v + 1) * per];
        let b = &fb[v * per..(v + 1) * per];
        let mut err = 0.0f32;
        for r in 0..FAN_RADII {
            for k in 0..FAN_ANGLES {
                let x = a[r * FAN_ANGLES + (k + 9) % FAN_ANGLES] - 10.0;
                let y = b[r * FAN_ANGLES + k] + 10.0;
                err = err.max((x - y).abs());
            }
        }
        assert!(err < 0.05, "rotated fans differ by {err}");
        // The ramp is sampled in the right place: outer ring, angle 0 ≈ centre + 2.5 * cos θ.
        let t1 = fr.t1[v];
        let expected = 10.0 + 2.5 * t1[0];
        assert!(
            (a[2 * FAN_ANGLES] - expected).abs() < 0.3,
            "{} vs {expected}",
            a[2 * FAN_ANGLES]
        );
    }

    #[test]
    fn affine_map_is_exact_at_constraints_and_identity_when_equal() {
        let g: Vec<Vec<f32>> = vec![
            vec![0.0, 2.0, 3.0],
            vec![2.0, 0.0, 1.5],
            vec![3.0, 1.5, 0.0],
        ];
        let m = min_norm_affine(&g, &g, 3);
        for r in 0..3 {
            for c in 0..4 {
                let e = if r == c { 1.0 } else { 0.0 };
                assert!((m[r * 4 + c] - e).abs() < 1e-4);
            }
        }
        let s: Vec<Vec<f32>> = g
            .iter()
            .map(|v| v.iter().map(|x| 2.0 * x + 0.5).collect())
            .collect();
        let m = min_norm_affine(&g, &s, 3);
        for (gt, gs) in g.iter().zip(&s) {
            for r in 0..3 {
                let y: f64 =
                    (0..3).map(|c| m[r * 4 + c] * gt[c] as f64).sum::<f64>() + m[r * 4 + 3];
                assert!((y - gs[r] as f64).abs() < 1e-3, "{y} vs {}", gs[r]);
            }
        }
    }

    #[test]
    fn transport_angle_is_consistent() {
        let n = Vec3::Z;
        let (t1, t2) = frame_of(n);
        // Same normal, frame rotated by 30 degrees.
        let th = 30f32.to_radians();
        let t1y = t1 * th.cos() + t2 * th.sin();
        let t2y = n.cross(t1y);
        let a = transport_angle(n, t1, n, t1y, t2y);
        assert!((a + th).abs() < 1e-5, "{a}");
    }
}
