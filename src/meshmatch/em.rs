//! The MeshMatch E- and M-steps on one level pair (Chen et al. 2012, §4): patch distance with
//! rotation search, propagation in breadth-first order, random search through hierarchy hops,
//! Gaussian voting and coarse-to-fine upsampling of the nearest-neighbour field.

use crate::error::{Error, Result};
use crate::features::{
    ANGLE_STEP_DEG, FAN_ANGLES, FAN_RADII, FRAME_RULE, FanSampler, Frames, exp_neg,
};
use crate::geometry::transport_angle;
use crate::hierarchy::{Hierarchy, Level};
use crate::work::CancelToken;
use glam::Vec3;
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};
use rayon::prelude::*;

use crate::stats::beats;

/// Colour channels of the synthesised signal.
pub(crate) const C: usize = 3;
/// Floats per colour fan.
pub(crate) const PER: usize = FAN_RADII * FAN_ANGLES * C;
const STEP: f32 = ANGLE_STEP_DEG * std::f32::consts::PI / 180.0;

/// One side (source or target) of a level pair.
pub(crate) struct Side<'a> {
    pub level: &'a Level,
    pub frames: &'a Frames,
    /// Transport angle along every directed edge (aligned with the CSR adjacency).
    pub eang: &'a [f32],
    /// Weighted shape features (`dsh` per vertex), already scaled so that plain squared L2 applies.
    pub shape: &'a [f32],
    /// Colour fans (`PER` per vertex), unweighted; empty on the target side, whose fans the
    /// E-step takes as it visits each vertex ([`TargetFans`]).
    pub fans: &'a [f32],
    /// Rotation-invariant summaries of the fans ([`ring_summaries_into`], `RING` per vertex).
    /// Read on the source side only, empty on the target's (a target vertex's summary comes
    /// with its gathered fan); an empty source side = no lower bound, every candidate's fan is
    /// compared.
    pub rings: &'a [f32],
}

/// Floats per vertex of the rotation-invariant ring summaries: per ring, the mean colour and the
/// norm of the ring about its mean.
pub(crate) const RING: usize = FAN_RADII * (C + 1);

/// The lower bound is scaled by this just-below-one factor, so that rounding can never make it
/// exceed a distance it bounds and prune a candidate the full comparison would keep.
const BOUND_SLACK: f32 = 0.9999;

/// Rotation-invariant summaries of colour fans (`PER` floats per vertex): per ring of `A`
/// angles, its mean colour `μ` scaled by `√A` and the norm `|x̃|` of the ring minus its mean.
///
/// For two rings `x`, `y` and any cyclic rotation `y_k`, the fan distance splits exactly into
/// `Σ|x - y_k|² = A |μx - μy|² + |x̃ - ỹ_k|²` (the cross term sums centred values to zero), and
/// `|x̃ - ỹ_k| ≥ ||x̃| - |ỹ||` since a rotation keeps the norm. So the squared L2 distance of two
/// summaries is a lower bound of the colour fan distance at every rotation: a candidate whose
/// shape distance plus this bound already loses needs none of its 18 rotations compared.
///
/// Written into `out`, reusing its allocation (the source's, once per level; a target vertex's
/// summary is taken with its gathered fan, [`Ctx::colour`]).
pub(crate) fn ring_summaries_into(fans: &[f32], out: &mut Vec<f32>) {
    let n = fans.len() / PER;
    out.clear();
    out.resize(n * RING, 0.0);
    out.par_chunks_mut(RING)
        .zip(fans.par_chunks(PER))
        .for_each(|(o, f)| ring_summary(f, o));
}

/// [`ring_summaries_into`] of one fan (`PER` floats) into `o` (`RING` floats).
#[inline(always)]
fn ring_summary(f: &[f32], o: &mut [f32]) {
    let sa = (FAN_ANGLES as f32).sqrt();
    for r in 0..FAN_RADII {
        let ring = &f[r * FAN_ANGLES * C..(r + 1) * FAN_ANGLES * C];
        let mut mu = [0.0f32; C];
        for x in ring.chunks_exact(C) {
            for c in 0..C {
                mu[c] += x[c];
            }
        }
        mu.iter_mut().for_each(|m| *m /= FAN_ANGLES as f32);
        let mut ss = 0.0f32;
        for x in ring.chunks_exact(C) {
            for c in 0..C {
                let d = x[c] - mu[c];
                ss += d * d;
            }
        }
        let o = &mut o[r * (C + 1)..(r + 1) * (C + 1)];
        for c in 0..C {
            o[c] = mu[c] * sa;
        }
        o[C] = ss.sqrt();
    }
}

/// The target's colour fans, never stored whole: the E-step gathers a vertex's fan through the
/// level's sampling table when it visits the vertex and a candidate first gets past the shape
/// part of the distance ([`Ctx::load`], [`Ctx::colour`]). A stored table of the
/// target's fans held 648 bytes per vertex (648 MB at a million vertices) and was refilled
/// after every M-step; the gather is the same arithmetic, so the fans have the same bits.
#[derive(Clone, Copy)]
pub(crate) struct TargetFans<'a> {
    pub sampler: &'a FanSampler,
    /// The target's current signal, pre-filtered as [`FanSampler::fans`] does
    /// ([`crate::features::smooth`]), `C` values per vertex.
    pub signal: &'a [f32],
}

/// One target vertex as the E-step compares it: its index and, once a candidate gets past the
/// shape part of the distance, its colour fan and the fan's ring summary
/// ([`ring_summaries_into`]). Set by [`Ctx::load`], reused from vertex to vertex.
pub(crate) struct Patch {
    t: usize,
    /// Whether `fan` and `ring` are `t`'s.
    coloured: bool,
    fan: [f32; PER],
    ring: [f32; RING],
}

impl Patch {
    pub fn empty() -> Patch {
        Patch {
            t: 0,
            coloured: false,
            fan: [0.0; PER],
            ring: [0.0; RING],
        }
    }
}

/// Squared L2 distance of two equally long feature vectors, summed in eight lanes (so that it
/// vectorises: one running sum would be a chain of dependent additions), then the lanes pairwise.
#[inline(always)]
fn squared_l2(a: &[f32], b: &[f32]) -> f32 {
    const L: usize = 8;
    let n = a.len().min(b.len());
    let (a, b) = (&a[..n], &b[..n]);
    let mut acc = [0.0f32; L];
    let (ac, bc) = (a.chunks_exact(L), b.chunks_exact(L));
    let (ar, br) = (ac.remainder(), bc.remainder());
    for (x, y) in ac.zip(bc) {
        for l in 0..L {
            let e = x[l] - y[l];
            acc[l] += e * e;
        }
    }
    for (l, (x, y)) in ar.iter().zip(br).enumerate() {
        let e = x - y;
        acc[l] += e * e;
    }
    ((acc[0] + acc[4]) + (acc[2] + acc[6])) + ((acc[1] + acc[5]) + (acc[3] + acc[7]))
}

/// Everything the E-step needs on one level.
pub(crate) struct Ctx<'a> {
    pub s: Side<'a>,
    pub t: Side<'a>,
    pub dsh: usize,
    /// Weight of the colour fan part (1 / (pooled variance * 162)), 0 before the target has colour.
    pub wc: f32,
    /// Source hierarchy (for random hops) and the level index.
    pub hs: &'a Hierarchy,
    pub l: usize,
    /// The target's colour fans; `None` before the target has colour (`wc` is 0 then).
    pub tf: Option<TargetFans<'a>>,
}

impl Ctx<'_> {
    /// Target vertex `t` into `p`; its colour fan is gathered when a distance first needs it
    /// ([`Ctx::colour`]): a vertex whose candidates all lose on shape alone needs none.
    #[inline(always)]
    pub fn load(&self, t: usize, p: &mut Patch) {
        p.t = t;
        p.coloured = false;
    }

    /// `p`'s colour fan and ring summary, gathered once per [`Ctx::load`].
    #[inline(always)]
    fn colour(&self, p: &mut Patch) {
        if p.coloured {
            return;
        }
        p.coloured = true;
        debug_assert!(self.tf.is_some(), "a colour weight needs the target's fans");
        if let Some(tf) = &self.tf {
            tf.sampler.gather(p.t, tf.signal, C, &mut p.fan);
            ring_summary(&p.fan, &mut p.ring);
        }
    }

    /// Patch distance D(vS, vT) for rotation k (squared L2 of the weighted feature vectors, colour
    /// fan rotated by a cyclic shift of k angle steps), stopping early once it reaches `best`.
    #[inline(always)]
    ///
    /// Callers keep a candidate only when it [`beats`] the best so far by a margin, so that the
    /// search's choices are the same in any units.
    pub fn dist(&self, p: &mut Patch, s: usize, k: usize, best: f32) -> f32 {
        let d = self.shape_dist(p.t, s);
        if d >= best {
            return d;
        }
        if self.wc == 0.0 {
            return d;
        }
        self.colour(p);
        let lb = d + self.ring_bound(p, s);
        if lb >= best {
            return lb;
        }
        self.fan_dist(p, s, k, d, best)
    }

    /// A lower bound of the weighted colour fan distance at every rotation
    /// ([`ring_summaries_into`]); 0 without summaries.
    #[inline(always)]
    fn ring_bound(&self, p: &Patch, s: usize) -> f32 {
        if self.s.rings.is_empty() {
            return 0.0;
        }
        BOUND_SLACK * self.wc * squared_l2(&p.ring, &self.s.rings[s * RING..(s + 1) * RING])
    }

    /// The rotation-independent part of [`Ctx::dist`]: squared L2 of the weighted shape
    /// features.
    #[inline(always)]
    pub fn shape_dist(&self, t: usize, s: usize) -> f32 {
        let dsh = self.dsh;
        squared_l2(
            &self.t.shape[t * dsh..(t + 1) * dsh],
            &self.s.shape[s * dsh..(s + 1) * dsh],
        )
    }

    /// `d` plus the weighted colour fan distance at rotation k, ring by ring, stopping once the
    /// sum reaches `best`.
    #[inline(always)]
    fn fan_dist(&self, p: &Patch, s: usize, k: usize, mut d: f32, best: f32) -> f32 {
        let tf = &p.fan;
        let sf = &self.s.fans[s * PER..(s + 1) * PER];
        let ring = FAN_ANGLES * C;
        let sh = (k % FAN_ANGLES) * C;
        let n1 = ring - sh;
        for r in 0..FAN_RADII {
            let tb = &tf[r * ring..(r + 1) * ring];
            let sb = &sf[r * ring..(r + 1) * ring];
            let acc = squared_l2(&tb[..n1], &sb[sh..]) + squared_l2(&tb[n1..], &sb[..sh]);
            d += self.wc * acc;
            if d >= best {
                return d;
            }
        }
        d
    }

    /// Best rotation of source vertex `s` for target `t`: (distance, rotation index).
    #[inline(always)]
    pub fn best_rotation(&self, p: &mut Patch, s: usize, best: f32) -> (f32, u8) {
        let mut bd = best;
        let mut bk = u8::MAX;
        if self.wc == 0.0 {
            let d = self.dist(p, s, 0, f32::INFINITY);
            return if beats(d, best) {
                (d, 0)
            } else {
                (best, u8::MAX)
            };
        }
        // The shape part is the same for every rotation: once, and out early if it already
        // loses.
        let sd = self.shape_dist(p.t, s);
        if sd >= bd {
            return (bd, bk);
        }
        self.colour(p);
        if sd + self.ring_bound(p, s) >= bd {
            return (bd, bk);
        }
        for k in 0..FAN_ANGLES {
            let d = self.fan_dist(p, s, k, sd, bd);
            if beats(d, bd) {
                bd = d;
                bk = k as u8;
            }
        }
        (bd, bk)
    }
}

/// Exact nearest-neighbour distance of each of `targets`: every source vertex, every rotation.
pub(crate) fn exact_distances(ctx: &Ctx, targets: &[usize]) -> Vec<f32> {
    let ns = ctx.s.level.len();
    targets
        .par_iter()
        .map_init(Patch::empty, |p, &t| {
            ctx.load(t, p);
            let mut best = f32::INFINITY;
            for s in 0..ns {
                best = ctx.best_rotation(p, s, best).0;
            }
            best
        })
        .collect()
}

/// Rotation index of an angle in radians.
#[inline]
pub(crate) fn rot_index(angle: f32) -> u8 {
    ((angle / STEP).round() as i64).rem_euclid(FAN_ANGLES as i64) as u8
}

/// Distances of the current NNF for every target vertex (the energy terms).
pub(crate) fn all_distances(ctx: &Ctx, nnf: &[(u32, u8)]) -> Vec<f32> {
    nnf.par_iter()
        .enumerate()
        .map_init(Patch::empty, |p, (t, &(s, k))| {
            ctx.load(t, p);
            ctx.dist(p, s as usize, k as usize, f32::INFINITY)
        })
        .collect()
}

/// Exhaustive search (every source vertex, every rotation): used on the coarsest level, where it
/// is cheap and replaces the random initialisation with the exact nearest neighbours.
pub(crate) fn exhaustive(
    ctx: &Ctx,
    nnf: &mut [(u32, u8)],
    dist: &mut [f32],
    locked: &[Option<u32>],
    cancel: &CancelToken,
) -> Result<()> {
    let ns = ctx.s.level.len();
    nnf.par_iter_mut()
        .zip(dist.par_iter_mut())
        .enumerate()
        .try_for_each_init(Patch::empty, |p, (t, (m, d))| {
            if cancel.is_cancelled() {
                return Err(Error::Cancelled);
            }
            ctx.load(t, p);
            let (lo, hi) = match locked[t] {
                Some(s) => (s as usize, s as usize + 1),
                None => (0, ns),
            };
            let mut bd = f32::INFINITY;
            let mut best = (lo as u32, 0u8);
            for s in lo..hi {
                let (dd, k) = ctx.best_rotation(p, s, bd);
                if k != u8::MAX && beats(dd, bd) {
                    bd = dd;
                    best = (s as u32, k);
                }
            }
            *m = best;
            *d = ctx.dist(p, best.0 as usize, best.1 as usize, f32::INFINITY);
            Ok(())
        })
}

/// Breadth-first visiting order over all components, starting at `start` (MeshMatch §4.2: the
/// next iteration starts where this order ended).
pub(crate) fn bfs_order(level: &Level, start: usize) -> Vec<u32> {
    let n = level.len();
    let mut seen = vec![false; n];
    let mut order = Vec::with_capacity(n);
    let mut roots = std::iter::once(start.min(n.saturating_sub(1))).chain(0..n);
    while order.len() < n {
        let Some(r) = roots.next() else { break };
        if seen[r] {
            continue;
        }
        seen[r] = true;
        let mut head = order.len();
        order.push(r as u32);
        while head < order.len() {
            let v = order[head] as usize;
            head += 1;
            for &u in level.adjacency.row(v) {
                if !seen[u as usize] {
                    seen[u as usize] = true;
                    order.push(u);
                }
            }
        }
    }
    order
}

/// Bands of the breadth-first order swept concurrently by [`propagate`] on levels of 8192 or
/// more vertices (a constant, so results do not depend on the machine's core count).
pub(crate) const PROPAGATION_BANDS: usize = 8;

/// Propagation (MeshMatch §4.2): in `order`, each target vertex tries every source vertex
/// adjacent to (or equal to) the match of each of its neighbours, with the rotation carried
/// through the frames: target frame -> neighbour frame (edge transport) -> neighbour's matched
/// source frame (its rotation) -> candidate frame (source edge transport); the best is kept and
/// its rotation refined by ±1 step.
pub(crate) fn propagate(
    ctx: &Ctx,
    nnf: &mut [(u32, u8)],
    dist: &mut [f32],
    order: &[u32],
    locked: &[Option<u32>],
    cancel: &CancelToken,
) -> Result<()> {
    // Parallel sweeps: the order is cut into contiguous parts (bands of the breadth-first
    // order) swept concurrently; inside a part every vertex sees its predecessors' fresh
    // matches, across a part boundary the matches from before this sweep. The number of parts
    // depends on the level's size only, never on the thread count, so a seed gives the same
    // result on every machine.
    let n = order.len();
    let parts = if n < 8192 { 1 } else { PROPAGATION_BANDS };
    let len = n.div_ceil(parts.max(1)).max(1);
    let mut pos = vec![0u32; nnf.len()];
    for (i, &v) in order.iter().enumerate() {
        pos[v as usize] = i as u32;
    }
    // Nothing writes `nnf` until every part is done: the parts read the matches from before
    // this sweep from it directly.
    let before: &[(u32, u8)] = nnf;
    let results: Vec<Vec<((u32, u8), f32)>> = order
        .par_chunks(len)
        .enumerate()
        .map(|(p, chunk)| {
            let lo = p * len;
            let mut local: Vec<((u32, u8), f32)> = Vec::with_capacity(chunk.len());
            let mut patch = Patch::empty();
            for (i, &vt) in chunk.iter().enumerate() {
                if i % 2048 == 0 {
                    cancel.check()?;
                }
                let vt = vt as usize;
                let get = |v: usize| {
                    let q = pos[v] as usize;
                    if q >= lo && q < lo + i {
                        local[q - lo].0
                    } else {
                        before[v]
                    }
                };
                let r =
                    propagate_one_fast(ctx, &mut patch, vt, before[vt], dist[vt], locked[vt], &get);
                local.push(r);
            }
            Ok(local)
        })
        .collect::<Result<_>>()?;
    for (p, local) in results.into_iter().enumerate() {
        for (i, (m, d)) in local.into_iter().enumerate() {
            let v = order[p * len + i] as usize;
            nnf[v] = m;
            dist[v] = d;
        }
    }
    Ok(())
}

/// [`propagate_one`], compiled for AVX2 too where the processor has it (the patch distances then
/// run 8 wide).
#[inline]
fn propagate_one_fast(
    ctx: &Ctx,
    p: &mut Patch,
    vt: usize,
    cur: (u32, u8),
    curd: f32,
    locked: Option<u32>,
    get: &dyn Fn(usize) -> (u32, u8),
) -> ((u32, u8), f32) {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        #[target_feature(enable = "avx2")]
        unsafe fn avx2(
            ctx: &Ctx,
            p: &mut Patch,
            vt: usize,
            cur: (u32, u8),
            curd: f32,
            locked: Option<u32>,
            get: &dyn Fn(usize) -> (u32, u8),
        ) -> ((u32, u8), f32) {
            propagate_one(ctx, p, vt, cur, curd, locked, get)
        }
        // SAFETY: the processor supports AVX2 (checked just above).
        return unsafe { avx2(ctx, p, vt, cur, curd, locked, get) };
    }
    propagate_one(ctx, p, vt, cur, curd, locked, get)
}

/// One propagation step at target vertex `vt` (current match `cur` at distance `curd`;
/// `get(v)` reads a neighbour's match), `vt` loaded into `p`: the new match and its distance.
#[inline(always)]
fn propagate_one(
    ctx: &Ctx,
    p: &mut Patch,
    vt: usize,
    cur: (u32, u8),
    curd: f32,
    locked: Option<u32>,
    get: impl Fn(usize) -> (u32, u8),
) -> ((u32, u8), f32) {
    let adj_t = &ctx.t.level.adjacency;
    let adj_s = &ctx.s.level.adjacency;
    ctx.load(vt, p);
    if let Some(s) = locked {
        let (d, k) = ctx.best_rotation(p, s as usize, f32::INFINITY);
        return ((s, k), d);
    }
    let (mut bs, mut bk) = cur;
    let mut bd = curd;
    let off_t = adj_t.offsets[vt] as usize;
    for (ni, &vn) in adj_t.row(vt).iter().enumerate() {
        let (sn, kn) = get(vn as usize);
        let base = ctx.t.eang[off_t + ni] + kn as f32 * STEP;
        try_candidate(ctx, p, sn, base, &mut bs, &mut bk, &mut bd);
        let off_s = adj_s.offsets[sn as usize] as usize;
        for (ci, &c) in adj_s.row(sn as usize).iter().enumerate() {
            try_candidate(
                ctx,
                p,
                c,
                base + ctx.s.eang[off_s + ci],
                &mut bs,
                &mut bk,
                &mut bd,
            );
        }
    }
    if (bs, bk) != cur && ctx.wc > 0.0 {
        for dk in [1, FAN_ANGLES - 1] {
            let k = (bk as usize + dk) % FAN_ANGLES;
            let d = ctx.dist(p, bs as usize, k, bd);
            if beats(d, bd) {
                bd = d;
                bk = k as u8;
            }
        }
    }
    ((bs, bk), bd)
}

/// [`propagate_one`]'s candidate: source vertex `c` at the rotation nearest `ang`, kept in
/// (`bs`, `bk`, `bd`) when it beats them.
#[inline(always)]
fn try_candidate(
    ctx: &Ctx,
    p: &mut Patch,
    c: u32,
    ang: f32,
    bs: &mut u32,
    bk: &mut u8,
    bd: &mut f32,
) {
    let k = rot_index(ang);
    if c == *bs && k == *bk {
        return;
    }
    let d = ctx.dist(p, c as usize, k as usize, *bd);
    if beats(d, *bd) {
        *bd = d;
        *bs = c;
        *bk = k;
    }
}

/// Random search (MeshMatch §4.2): candidates at growing distance from the current match by
/// hopping j = 1, 2, ... levels up the source hierarchy and back down through random children,
/// plus uniformly random source vertices (max(1, 8 - hops) of them); each candidate with its best of 18 rotations.
/// Deterministic: one RNG per (seed, level, iteration, vertex).
pub(crate) fn random_search(
    ctx: &Ctx,
    nnf: &mut [(u32, u8)],
    dist: &mut [f32],
    locked: &[Option<u32>],
    seed: u64,
    cancel: &CancelToken,
) -> Result<()> {
    let hs = ctx.hs;
    let l = ctx.l;
    let hops = hs.top().saturating_sub(l);
    let ns = ctx.s.level.len() as u32;
    let job = RandomSearch {
        ctx,
        locked,
        seed,
        hops,
        ns,
    };
    nnf.par_chunks_mut(1024)
        .zip(dist.par_chunks_mut(1024))
        .enumerate()
        .try_for_each(|(ci, (m, d))| {
            if cancel.is_cancelled() {
                return Err(Error::Cancelled);
            }
            job.chunk(ci, m, d);
            Ok(())
        })
}

/// What every chunk of [`random_search`] shares.
struct RandomSearch<'a, 'b> {
    ctx: &'a Ctx<'b>,
    locked: &'a [Option<u32>],
    seed: u64,
    hops: usize,
    ns: u32,
}

impl RandomSearch<'_, '_> {
    /// Chunk `ci` (1024 target vertices from `ci * 1024`): its matches `m` and distances `d`.
    /// Compiled for AVX2 too, where the processor has it (the patch distances then run 8 wide).
    fn chunk(&self, ci: usize, m: &mut [(u32, u8)], d: &mut [f32]) {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the processor supports AVX2 (checked just above).
            return unsafe { self.chunk_avx2(ci, m, d) };
        }
        self.chunk_body(ci, m, d)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn chunk_avx2(&self, ci: usize, m: &mut [(u32, u8)], d: &mut [f32]) {
        self.chunk_body(ci, m, d)
    }

    #[inline(always)]
    fn chunk_body(&self, ci: usize, m: &mut [(u32, u8)], d: &mut [f32]) {
        let RandomSearch {
            ctx,
            locked,
            seed,
            hops,
            ns,
        } = *self;
        let hs = ctx.hs;
        let l = ctx.l;
        let mut p = Patch::empty();
        for (k, (mm, dd)) in m.iter_mut().zip(d.iter_mut()).enumerate() {
            let t = ci * 1024 + k;
            if locked[t].is_some() {
                continue;
            }
            ctx.load(t, &mut p);
            let mut rng = SmallRng::seed_from_u64(
                seed ^ (t as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ ((l as u64) << 56),
            );
            // Uniform candidates make up for missing hops near the top of the hierarchy.
            let uniform = 8usize.saturating_sub(hops).max(1);
            for j in 1..=hops + uniform {
                let c = if j <= hops {
                    hs.random_hop(l, mm.0, j, &mut rng)
                } else {
                    rng.random_range(0..ns)
                };
                if c == mm.0 {
                    continue;
                }
                let (bd, bk) = ctx.best_rotation(&mut p, c as usize, *dd);
                if bk != u8::MAX && beats(bd, *dd) {
                    *dd = bd;
                    *mm = (c, bk);
                }
            }
        }
    }
}

/// Tangent-plane polar offset of `q` seen from vertex `v` of `level`: (radius, angle).
#[inline]
fn polar(level: &Level, frames: &Frames, v: usize, q: Vec3) -> (f32, f32) {
    let d = q - Vec3::from(level.positions[v]);
    (d.length(), frames.angle(v, d))
}

/// Walk on the source level from `s` towards the point at tangent offset `(x, y)` in `s`'s
/// frame: greedy steps to the neighbour closest to that point (at most 4 steps).
#[inline]
fn walk(level: &Level, frames: &Frames, s: usize, x: f32, y: f32) -> usize {
    let ps = Vec3::from(level.positions[s]);
    let goal = ps + x * Vec3::from(frames.t1[s]) + y * Vec3::from(frames.t2[s]);
    descend(level, goal, s, (ps - goal).length_squared())
}

/// Greedy descent on `level` towards `goal` from vertex `start` (at squared distance `d0`):
/// at most 4 steps, each to the neighbour nearest the goal that [`beats`] the current one.
#[inline]
fn descend(level: &Level, goal: Vec3, start: usize, d0: f32) -> usize {
    let mut best = start;
    let mut bd = d0;
    for _ in 0..4 {
        let cur = best;
        for &u in level.adjacency.row(cur) {
            let d = (Vec3::from(level.positions[u as usize]) - goal).length_squared();
            if beats(d, bd) {
                bd = d;
                best = u as usize;
            }
        }
        if best == cur {
            break;
        }
    }
    best
}

/// (cos, sin) of every rotation step.
fn rotations() -> [(f32, f32); FAN_ANGLES] {
    std::array::from_fn(|k| (k as f32 * STEP).sin_cos()).map(|(s, c)| (c, s))
}

/// M-step, Gaussian voting (MeshMatch §4.3): the signal at target vertex vT is the average over
/// vp ∈ {vT} ∪ 1-ring(vT), weighted by exp(-|vT - vp|² / 2σ²) with σ = the level's mean edge
/// length, of the source signal found at vT's offset from vp (in vp's frame, rotated by vp's
/// match rotation, scaled by the source/target edge-length ratio) walked from vp's source match.
pub(crate) fn vote(
    s: &Side,
    t: &Side,
    src_signal: &[[f32; 3]],
    nnf: &[(u32, u8)],
    ratio: f32,
) -> Vec<[f32; 3]> {
    let lt = t.level;
    let sigma = lt.mean_edge.max(1e-12);
    let inv2s2 = 1.0 / (2.0 * sigma * sigma);
    let rot = rotations();
    (0..lt.len())
        .into_par_iter()
        .map(|vt| {
            let (s0, _) = nnf[vt];
            let mut acc = Vec3::from(src_signal[s0 as usize]);
            let mut wsum = 1.0f32;
            let pt = Vec3::from(lt.positions[vt]);
            for &vp in lt.adjacency.row(vt) {
                let vp = vp as usize;
                // vT's offset from vp: tangent direction of vp's frame, length kept.
                let d = pt - Vec3::from(lt.positions[vp]);
                let (x, y) = (
                    d.dot(Vec3::from(t.frames.t1[vp])),
                    d.dot(Vec3::from(t.frames.t2[vp])),
                );
                let rho2 = d.length_squared();
                let w = exp_neg(rho2 * inv2s2);
                let scale = ratio * (rho2 / (x * x + y * y).max(1e-30)).sqrt();
                let (sp, kp) = nnf[vp];
                let (c, sn) = rot[kp as usize];
                let u = walk(
                    s.level,
                    s.frames,
                    sp as usize,
                    scale * (c * x - sn * y),
                    scale * (sn * x + c * y),
                );
                acc += w * Vec3::from(src_signal[u]);
                wsum += w;
            }
            (acc / wsum).to_array()
        })
        .collect()
}

/// Upsample the NNF from level l+1 to level l (MeshMatch §4.4): each finer target vertex takes
/// its parent's match, carries its offset from the parent (in the parent's frame, rotated, scaled)
/// over to the matched coarse source vertex, picks the closest child of that source vertex and
/// walks to the finer source vertex closest to the carried point; the rotation is carried through
/// the coarse and fine frames.
#[allow(clippy::too_many_arguments)]
pub(crate) fn upsample(
    hs: &Hierarchy,
    ht: &Hierarchy,
    fs: &[Frames],
    ft: &[Frames],
    l: usize,
    coarse: &[(u32, u8)],
    ratio: f32,
) -> Vec<(u32, u8)> {
    let (ltf, ltc) = (&ht.levels[l], &ht.levels[l + 1]);
    let (lsf, lsc) = (&hs.levels[l], &hs.levels[l + 1]);
    (0..ltf.len())
        .into_par_iter()
        .map(|vf| {
            let pc = ht.parent(l, vf as u32) as usize;
            let (sc, k) = coarse[pc];
            let sc = sc as usize;
            let (rho, phi) = polar(ltc, &ft[l + 1], pc, Vec3::from(ltf.positions[vf]));
            let ang = phi + k as f32 * STEP;
            let ps = Vec3::from(lsc.positions[sc]);
            let goal = ps
                + rho
                    * ratio
                    * (ang.cos() * Vec3::from(fs[l + 1].t1[sc])
                        + ang.sin() * Vec3::from(fs[l + 1].t2[sc]));
            let mut best = usize::MAX;
            let mut bd = f32::INFINITY;
            // nearest the goal; a nearer one must [`beat`](beats) the one found first
            for &c in hs.children(l + 1, sc as u32) {
                let d = (Vec3::from(lsf.positions[c as usize]) - goal).length_squared();
                if beats(d, bd) {
                    bd = d;
                    best = c as usize;
                }
            }
            let best = descend(lsf, goal, best, bd);
            // Target fine frame -> target coarse frame -> (rotation k) -> source coarse frame ->
            // source fine frame.
            let a1 = transport_angle(
                FRAME_RULE,
                Vec3::from(ltf.normals[vf]),
                ft[l].get(vf),
                Vec3::from(ltc.normals[pc]),
                ft[l + 1].get(pc),
            );
            let a2 = transport_angle(
                FRAME_RULE,
                Vec3::from(lsc.normals[sc]),
                fs[l + 1].get(sc),
                Vec3::from(lsf.normals[best]),
                fs[l].get(best),
            );
            (best as u32, rot_index(a1 + k as f32 * STEP + a2))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The summaries' squared distance never exceeds the colour fan distance at any rotation,
    /// and it is 0, as the distance is, for a fan against its own rotated copy.
    #[test]
    fn ring_summaries_bound_the_fan_distance_at_every_rotation() {
        let mut rng = SmallRng::seed_from_u64(7);
        let n = 64;
        let mut fans: Vec<f32> = (0..n * PER).map(|_| rng.random::<f32>()).collect();
        // vertex 1 is vertex 0 rotated by 5 steps: its distance at the right rotation is 0
        let ring = FAN_ANGLES * C;
        for r in 0..FAN_RADII {
            for i in 0..ring {
                fans[PER + r * ring + i] = fans[r * ring + (i + 5 * C) % ring];
            }
        }
        let mut sums = Vec::new();
        ring_summaries_into(&fans, &mut sums);
        let fan_d = |a: usize, b: usize, k: usize| -> f32 {
            let mut d = 0.0;
            for r in 0..FAN_RADII {
                for i in 0..ring {
                    let x = fans[a * PER + r * ring + i]
                        - fans[b * PER + r * ring + (i + k * C) % ring];
                    d += x * x;
                }
            }
            d
        };
        let sum_d = |a: usize, b: usize| -> f32 {
            (0..RING)
                .map(|i| (sums[a * RING + i] - sums[b * RING + i]).powi(2))
                .sum()
        };
        for a in 0..n {
            for b in 0..n {
                let lb = sum_d(a, b);
                let best = (0..FAN_ANGLES)
                    .map(|k| fan_d(a, b, k))
                    .fold(f32::INFINITY, f32::min);
                assert!(
                    lb <= best * 1.0001 + 1e-5,
                    "bound {lb} above the distance {best}"
                );
            }
        }
        assert!(sum_d(0, 1) < 1e-5, "a rotated copy has the same summary");
        let to_copy = (0..FAN_ANGLES)
            .map(|k| fan_d(0, 1, k))
            .fold(f32::INFINITY, f32::min);
        assert!(to_copy < 1e-6, "the copy is found at its rotation");
    }
}
