//! Geodesic fans (Zelinka & Garland 2004) of a pre-filtered signal: the per-level sampling
//! table ([`FanSampler`]) and the fans it gathers (MeshMatch §4.1).

use super::{ANGLE_STEP_DEG, FAN_ANGLES, FAN_RADII, Frames, smooth};
use crate::error::{Error, Result};
use crate::hierarchy::Level;
use crate::mesh::Csr;
use crate::work::CancelToken;
use glam::Vec3;
use rayon::prelude::*;

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
    ///
    /// Per vertex: [`TableJob::walk_taps`] (the nearest taps of every bin, by a breadth-first
    /// walk), [`gaussian_weights`], [`bin_taps`] (three taps per bin, weights summing to one) and
    /// [`write_row`] (the vertex's distinct taps and its table row). Every step is inlined, so
    /// each compiles for the same processor features as [`TableJob::chunk_avx2`].
    #[inline(always)]
    unsafe fn chunk_body(&self, vs: std::ops::Range<usize>) -> (Vec<u32>, Vec<u8>) {
        let mut verts: Vec<u32> = Vec::new();
        let mut counts: Vec<u8> = Vec::new();
        if self.cancel.is_cancelled() {
            return (verts, counts);
        }
        let mut s = ChunkScratch::new(self.n, self.nb, self.cut2);
        verts.reserve(vs.len() * 48);
        counts.reserve(vs.len());
        // `v`, `u` and the taps below are walk vertices; `vl` is `v` on the level
        for v in vs {
            let vl = self.order[v] as usize;
            // SAFETY: `order` is a permutation and the ranges of the calls are disjoint
            // (`chunk`'s contract), so row `vl` is taken here and nowhere else.
            let (fi, fw) = unsafe { (self.tap_rows.row(vl), self.w_rows.row(vl)) };
            self.walk_taps(v, vl, &mut s);
            gaussian_weights(&mut s.top, self.inv2s2);
            bin_taps(&s.top, &mut s.fin, self.nb, v as u32);
            let count = write_row(&s.fin, &mut s.local, self.order, &mut verts, (fi, fw));
            counts.push(count);
        }
        verts.shrink_to_fit();
        (verts, counts)
    }

    /// The breadth-first walk around walk vertex `v` (level vertex `vl`): every vertex reached
    /// within `reach`, in `v`'s tangent frame at its true distance, enters the top lists of the
    /// bins it is near.
    #[inline(always)]
    fn walk_taps(&self, v: usize, vl: usize, s: &mut ChunkScratch) {
        let walk = self.walk;
        let pv = Vec3::from(walk.positions[v]);
        let t1 = Vec3::from(self.frames.t1[vl]);
        let t2 = Vec3::from(self.frames.t2[vl]);
        s.top
            .iter_mut()
            .for_each(|x| *x = (f32::INFINITY, v as u32));
        s.worst.fill(self.cut2);
        s.queue[0] = v as u32;
        let mut qlen = 1;
        s.stamp[v] = v as u32;
        let mut head = 0;
        while head < qlen {
            let u = s.queue[head] as usize;
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
            self.enter_top_lists(u, (x, y), len, s);
            continue_walk(
                walk,
                &mut s.queue,
                &mut qlen,
                &mut s.stamp,
                u,
                v,
                pv,
                self.reach,
            );
        }
    }

    /// Tap `u` at tangent-plane position `(x, y)`, distance `rho`: into the sorted top list of
    /// every bin of a ring within the cut-off where it beats the list's last entry.
    #[inline(always)]
    fn enter_top_lists(&self, u: usize, (x, y): (f32, f32), rho: f32, s: &mut ChunkScratch) {
        let (rks, dirs, cut, cut2) = (&self.rks, &self.dirs, self.cut, self.cut2);
        // |x - bin|² = ρ² + r_k² - 2 r_k (x cos θ_a + y sin θ_a): the 18
        // projections are shared by the three rings, so each ring costs one
        // multiply-add per bin (cheaper than locating the angular window with
        // atan2/acos).
        let mut any = false;
        for &rk in rks.iter() {
            any |= (rho - rk).abs() < cut;
        }
        if !any {
            return;
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
            let wr = &s.worst[r * FAN_ANGLES..(r + 1) * FAN_ANGLES];
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
                let t = &mut s.top[b * FAN_TAPS..(b + 1) * FAN_TAPS];
                // Insert into the sorted (ascending) top list.
                let mut j = FAN_TAPS - 1;
                while j > 0 && t[j - 1].0 > d2 {
                    t[j] = t[j - 1];
                    j -= 1;
                }
                t[j] = (d2, u as u32);
                s.worst[b] = t[FAN_TAPS - 1].0.min(cut2);
            }
        }
    }
}

/// One chunk's working buffers, reused from vertex to vertex.
struct ChunkScratch {
    /// The walk vertex whose walk last saw each vertex.
    stamp: Vec<u32>,
    /// Per vertex, its index among the current vertex's distinct taps (`u8::MAX`: none).
    local: Vec<u8>,
    /// The walk's queue; its last slot takes the writes of rejected neighbours.
    queue: [u32; MAX_FAN_VERTICES + 1],
    /// Top taps per bin as (squared distance, vertex), nearest first: ranking by distance is
    /// ranking by Gaussian weight, so exp runs only on the kept taps. Then (weight, vertex).
    top: Vec<(f32, u32)>,
    /// Per bin, the squared distance a vertex must beat to enter its top list: the last kept
    /// tap's, capped at the Gaussian cut-off.
    worst: [f32; FAN_RADII * FAN_ANGLES],
    /// Final (vertex, weight) per tap.
    fin: Vec<(u32, u16)>,
}

impl ChunkScratch {
    /// Buffers for a level of `n` vertices, `nb` bins and the squared cut-off `cut2`.
    fn new(n: usize, nb: usize, cut2: f32) -> ChunkScratch {
        ChunkScratch {
            stamp: vec![u32::MAX; n],
            local: vec![u8::MAX; n],
            queue: [0u32; MAX_FAN_VERTICES + 1],
            top: vec![(f32::INFINITY, 0u32); nb * FAN_TAPS],
            worst: [cut2; FAN_RADII * FAN_ANGLES],
            fin: vec![(0u32, 0u16); nb * FAN_TAPS],
        }
    }
}

/// The top lists' squared distances turned into Gaussian weights (0 for an empty slot).
#[inline(always)]
fn gaussian_weights(top: &mut [(f32, u32)], inv2s2: f32) {
    for e in top.iter_mut() {
        e.0 = if e.0.is_finite() {
            exp_neg(e.0 * inv2s2)
        } else {
            0.0
        };
    }
}

/// Per bin its three taps with 16-bit weights summing to one: the top list normalised where it
/// has weight, else the centre `v` for an inner-ring bin, or the bin of the ring inside it.
#[inline(always)]
fn bin_taps(top: &[(f32, u32)], fin: &mut [(u32, u16)], nb: usize, v: u32) {
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
            fin[o] = (v, u16::MAX);
            fin[o + 1] = (v, 0);
            fin[o + 2] = (v, 0);
        } else {
            let inner = (b - FAN_ANGLES) * FAN_TAPS;
            for j in 0..FAN_TAPS {
                fin[o + j] = fin[inner + j];
            }
        }
    }
}

/// The vertex's distinct taps, in order of first use, appended to `verts` as level vertices;
/// its tap row `fi` (indices into them) and weight row `fw` (the first two of each bin).
/// Returns how many distinct taps it has.
#[inline(always)]
fn write_row(
    fin: &[(u32, u16)],
    local: &mut [u8],
    order: &[u32],
    verts: &mut Vec<u32>,
    (fi, fw): (&mut [u8], &mut [u16]),
) -> u8 {
    for &(u, _) in fin {
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
    (verts.len() - first) as u8
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
    use crate::features::tangent_frames;

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
}
