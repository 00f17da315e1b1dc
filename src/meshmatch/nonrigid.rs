//! Where the target is a deformed copy of the source (bent, moved, re-tessellated), no
//! similarity takes one onto the other, so [`super::coincident`] finds nothing to snap, and the
//! nearest-neighbour field and the global map place the texture a few edges from the exact
//! answer. This step finds the deformation instead and snaps each target vertex to the source
//! point under its deformed position.
//!
//! 1. **A smooth warp of space**: a cubic polynomial in the target's normalised coordinates
//!    (20 terms per axis, the similarity included), fitted to the matches (each working target
//!    vertex to its matched source point, trimmed twice), then refined by point-to-plane ICP
//!    against the source surface on a spread sample of vertices (closest points facing the same
//!    way, trimmed, with a tenth of the point-to-point distance beside the planes'). A polynomial warp of space cannot slide the surface along itself as a free
//!    per-vertex displacement can, so the shape's own features pull the warp into place.
//! 2. **Rigid parts**, where the warp leaves a sizeable share of the sample (5%) more than an
//!    edge off the source: a limb turned at a joint, which no smooth warp of the whole shape
//!    turns rigidly against the rest. A similarity is fitted to the rest (to the closest points
//!    the warp found for it) and one to the part (to the part's matches, trimmed); each is
//!    refined by ICP on its own vertices, alternately, a vertex belonging to the part where the
//!    part's similarity lays it on the source and moves it nearer its own match than the rest's
//!    does (the matches are a few edges off, the two similarities many edges apart across the
//!    part). Kept where the two lay more of the sample on the source than the warp did; each
//!    vertex then starts from the rest's similarity, turned into the part's by its smoothed
//!    membership, so the two blend across the joint.
//! 3. **Local rounds**: each deformed vertex's pull to its closest source point, smoothed over
//!    the target (Jacobi averages over the vertex adjacency, weighted by which vertices
//!    pulled), narrowing round by round, lays the warped target onto the source.
//! 4. **Gate and snap**: the shapes count as a deformed copy where at least half the vertices lie
//!    on the source surface (within a quarter of a source edge), facing the same way, near
//!    their own matches; every vertex on the source then snaps to the point under it, its patch
//!    map turned by the rotation between its own normal and its deformed normal.

use glam::{DVec3, Quat, Vec3};
use rayon::prelude::*;

use super::coincident::{
    Closest, MIN_SHARE, ON_SURFACE_EDGES, Similarity, SurfaceSearch, facing, median, snapped_map,
    umeyama, umeyama_trimmed,
};
use super::patch_map::PatchMap;
use crate::features::Frames;
use crate::geometry::cholesky_solve;
use crate::hierarchy::{Level, area_weighted_normals};
use crate::mesh::Csr;

/// Jacobi smoothing iterations of the local pulls, round by round.
const LOCAL_ROUNDS: [usize; 6] = [16, 16, 8, 8, 4, 4];
/// ICP rounds of the warp (point-to-plane Gauss-Newton steps; point-to-point ICP slides along
/// the surface slowly, and the slide is what the warp is for: on the bent Spot, placement p90
/// 0.59 working source edges after 300 point-to-point rounds, 0.45 after 30 point-to-plane).
const WARP_ROUNDS: usize = 40;
/// The round after which a sample mostly off the source or far from its own matches settles
/// that the target is another shape (zebra -> giraffe: 5% of the sample agrees; the bent Spot
/// 65%), so a transfer between different shapes pays only these rounds.
const EARLY_ROUND: usize = 20;
const EARLY_EDGES: f32 = 1.0;
const EARLY_SHARE: f64 = 0.4;
/// Vertices the warp's ICP fits to (a quarter of them before [`EARLY_ROUND`]).
const WARP_SAMPLES: usize = 4096;
/// Vertices the warp's first fit, to the matches, takes.
const FIT_SAMPLES: usize = 16384;
/// A sample vertex farther than this many source mean edges from the source under the warp
/// (or facing away) is left off by it.
const PART_OFF_EDGES: f32 = 1.0;
/// The least share of the sample the warp must leave off for rigid parts to be tried.
const PART_SHARE: f64 = 0.05;
/// ICP rounds of each part's similarity per alternation.
const PART_ROUNDS: usize = 30;
/// Alternations between the part's similarity and the rest's.
const PART_ALTERNATIONS: usize = 3;
/// Jacobi iterations smoothing each vertex's choice between the two.
const BLEND_ITERS: usize = 32;
/// A deformed vertex on the source surface (as [`super::coincident`] counts it) must also be
/// within this many source mean edges of its own match for the shapes to count as a deformed
/// copy (the
/// global map's own error on a bend is a few edges; between different shapes most vertices
/// are far from their matches).
const NEAR_MATCH_EDGES: f32 = 5.0;
/// Monomials of degree at most 3 in three variables.
const TERMS: usize = 20;
const EXPONENTS: [[u8; 3]; TERMS] = [
    [0, 0, 0],
    [1, 0, 0],
    [0, 1, 0],
    [0, 0, 1],
    [2, 0, 0],
    [0, 2, 0],
    [0, 0, 2],
    [1, 1, 0],
    [1, 0, 1],
    [0, 1, 1],
    [3, 0, 0],
    [0, 3, 0],
    [0, 0, 3],
    [2, 1, 0],
    [2, 0, 1],
    [1, 2, 0],
    [0, 2, 1],
    [1, 0, 2],
    [0, 1, 2],
    [1, 1, 1],
];

/// A cubic warp of space: `x -> x + sum_k phi_k((x - centre) / scale) c_k`.
struct Warp {
    centre: DVec3,
    scale: f64,
    coef: [DVec3; TERMS],
}

impl Warp {
    fn basis(&self, x: Vec3) -> [f64; TERMS] {
        let q = (x.as_dvec3() - self.centre) / self.scale;
        EXPONENTS.map(|e| q.x.powi(e[0] as i32) * q.y.powi(e[1] as i32) * q.z.powi(e[2] as i32))
    }

    fn apply(&self, x: Vec3) -> Vec3 {
        self.apply_with(x, &self.basis(x))
    }

    /// [`Self::apply`] with `x`'s terms `b` already computed.
    fn apply_with(&self, x: Vec3, b: &[f64; TERMS]) -> Vec3 {
        let d = b
            .iter()
            .zip(&self.coef)
            .fold(DVec3::ZERO, |acc, (bk, ck)| acc + *bk * *ck);
        (x.as_dvec3() + d).as_vec3()
    }

    /// The warped normal (inverse transpose of the Jacobian).
    fn normal(&self, x: Vec3, n: Vec3) -> Vec3 {
        let q = (x.as_dvec3() - self.centre) / self.scale;
        let p = |v: f64, e: u8| if e == 0 { 1.0 } else { v.powi(e as i32) };
        let dp = |v: f64, e: u8| if e == 0 { 0.0 } else { e as f64 * p(v, e - 1) };
        let mut j = glam::DMat3::IDENTITY;
        for (k, e) in EXPONENTS.iter().enumerate() {
            let g = DVec3::new(
                dp(q.x, e[0]) * p(q.y, e[1]) * p(q.z, e[2]),
                p(q.x, e[0]) * dp(q.y, e[1]) * p(q.z, e[2]),
                p(q.x, e[0]) * p(q.y, e[1]) * dp(q.z, e[2]),
            ) / self.scale;
            // J += c_k g^T
            let c = self.coef[k];
            j.x_axis += c * g.x;
            j.y_axis += c * g.y;
            j.z_axis += c * g.z;
        }
        (j.inverse().transpose() * n.as_dvec3())
            .normalize_or_zero()
            .as_vec3()
    }

    /// One Gauss-Newton step of point-to-plane ICP: the change of the coefficients that best
    /// moves the warped `x[i]` onto the planes through `y[i]` with normals `n[i]` (weights
    /// `w`), with a tenth of the point-to-point distance beside it so that the step stays put
    /// along flat parts.
    fn step_to_planes(&mut self, x: &[Vec3], y: &[Vec3], n: &[Vec3], w: &[f32]) {
        const DIM: usize = 3 * TERMS;
        const POINT: f64 = 0.1;
        // The normal equations' matrix is a sum over the points of (b b^T) kron (n n^T) for the
        // planes plus POINT (b b^T) kron I: kept as the six distinct products n_d n_e times the
        // upper triangle of b b^T, and that triangle alone, so a point costs about 1,500
        // multiply-adds instead of 4,800; summed in parallel.
        let acc = (0..x.len())
            .into_par_iter()
            .with_min_len(256)
            .fold(Normal::default, |mut acc, i| {
                if w[i] <= 0.0 {
                    return acc;
                }
                let b = self.basis(x[i]);
                let e = (y[i] - self.apply_with(x[i], &b)).as_dvec3();
                let nn = n[i].as_dvec3();
                let wi = w[i] as f64;
                acc.wsum += wi;
                let r = nn.dot(e);
                let nd = [
                    nn.x * nn.x,
                    nn.x * nn.y,
                    nn.x * nn.z,
                    nn.y * nn.y,
                    nn.y * nn.z,
                    nn.z * nn.z,
                ];
                let mut j = 0;
                for k in 0..TERMS {
                    let wb = wi * b[k];
                    for d in 0..3 {
                        acc.rhs[3 * k + d] += wb * (nn[d] * r + POINT * e[d]);
                    }
                    for &bl in &b[k..] {
                        let bb = wb * bl;
                        acc.bb[j] += bb;
                        for (m, f) in acc.planes.iter_mut().zip(nd) {
                            m[j] += bb * f;
                        }
                        j += 1;
                    }
                }
                acc
            })
            .reduce(Normal::default, Normal::add);
        let mut a = vec![0.0f64; DIM * DIM];
        let pair = |d: usize, e: usize| match (d.min(e), d.max(e)) {
            (0, 0) => 0,
            (0, 1) => 1,
            (0, 2) => 2,
            (1, 1) => 3,
            (1, 2) => 4,
            _ => 5,
        };
        let mut j = 0;
        for k in 0..TERMS {
            for l in k..TERMS {
                for d in 0..3 {
                    for e in 0..3 {
                        let mut v = acc.planes[pair(d, e)][j];
                        if d == e {
                            v += POINT * acc.bb[j];
                        }
                        a[(3 * k + d) * DIM + 3 * l + e] = v;
                        a[(3 * l + e) * DIM + 3 * k + d] = v;
                    }
                }
                j += 1;
            }
        }
        for p in 0..DIM {
            a[p * DIM + p] += 1e-6 * acc.wsum.max(1e-12);
        }
        if let Some(delta) = cholesky_solve(&a, &acc.rhs, DIM) {
            for k in 0..TERMS {
                self.coef[k] += DVec3::new(delta[3 * k], delta[3 * k + 1], delta[3 * k + 2]);
            }
        }
    }

    /// The warp taking `x[i]` to `y[i]` (weights `w`) in least squares (the upper triangle of
    /// the normal equations summed in parallel).
    fn fit(&mut self, x: &[Vec3], y: &[Vec3], w: &[f32]) {
        let (bb, rhs, wsum) = (0..x.len())
            .into_par_iter()
            .with_min_len(1024)
            .fold(
                || ([0.0f64; PAIRS], [[0.0f64; TERMS]; 3], 0.0f64),
                |(mut bb, mut rhs, mut wsum), i| {
                    if w[i] > 0.0 {
                        let b = self.basis(x[i]);
                        let r = (y[i] - x[i]).as_dvec3();
                        let wi = w[i] as f64;
                        wsum += wi;
                        let mut j = 0;
                        for k in 0..TERMS {
                            let wb = wi * b[k];
                            for (d, rd) in rhs.iter_mut().enumerate() {
                                rd[k] += wb * r[d];
                            }
                            for &bl in &b[k..] {
                                bb[j] += wb * bl;
                                j += 1;
                            }
                        }
                    }
                    (bb, rhs, wsum)
                },
            )
            .reduce(
                || ([0.0f64; PAIRS], [[0.0f64; TERMS]; 3], 0.0f64),
                |(mut a, mut r, w), (b, s, v)| {
                    a.iter_mut().zip(&b).for_each(|(x, y)| *x += y);
                    for (rd, sd) in r.iter_mut().zip(&s) {
                        rd.iter_mut().zip(sd).for_each(|(x, y)| *x += y);
                    }
                    (a, r, w + v)
                },
            );
        let mut a = vec![0.0f64; TERMS * TERMS];
        let mut j = 0;
        for k in 0..TERMS {
            for l in k..TERMS {
                a[k * TERMS + l] = bb[j];
                a[l * TERMS + k] = bb[j];
                j += 1;
            }
        }
        // a touch of ridge so a sample that does not span a term leaves it at 0
        for k in 0..TERMS {
            a[k * TERMS + k] += 1e-6 * wsum.max(1e-12);
        }
        let solved: Option<Vec<Vec<f64>>> =
            rhs.iter().map(|r| cholesky_solve(&a, r, TERMS)).collect();
        if let Some(c) = solved {
            for (k, coef) in self.coef.iter_mut().enumerate() {
                *coef = DVec3::new(c[0][k], c[1][k], c[2][k]);
            }
        }
    }
}

/// Distinct products of the terms, `b_k b_l` for `k <= l`.
const PAIRS: usize = TERMS * (TERMS + 1) / 2;

/// The point-to-plane normal equations summed over part of the points
/// ([`Warp::step_to_planes`]).
struct Normal {
    /// Per distinct product of normal components (xx, xy, xz, yy, yz, zz), the weighted sums of
    /// `b_k b_l` times it.
    planes: [[f64; PAIRS]; 6],
    /// The weighted sums of `b_k b_l`.
    bb: [f64; PAIRS],
    rhs: [f64; 3 * TERMS],
    wsum: f64,
}

impl Default for Normal {
    fn default() -> Self {
        Normal {
            planes: [[0.0; PAIRS]; 6],
            bb: [0.0; PAIRS],
            rhs: [0.0; 3 * TERMS],
            wsum: 0.0,
        }
    }
}

impl Normal {
    fn add(mut self, o: Normal) -> Normal {
        for (a, b) in self.planes.iter_mut().zip(&o.planes) {
            a.iter_mut().zip(b).for_each(|(x, y)| *x += y);
        }
        self.bb.iter_mut().zip(&o.bb).for_each(|(x, y)| *x += y);
        self.rhs.iter_mut().zip(&o.rhs).for_each(|(x, y)| *x += y);
        self.wsum += o.wsum;
        self
    }
}

/// The snapped patch maps (see the module doc): `Some(map)` for every snapped target vertex,
/// or `None` when the target is not a deformed copy of the source.
pub(crate) fn snap_deformed(
    search: &SurfaceSearch,
    source_frames: &Frames,
    target: &Level,
    target_frames: &Frames,
    matched: &[[f32; 3]],
) -> Option<Vec<Option<PatchMap>>> {
    let source = search.level;
    let n = target.len();
    if n < 3 || matched.len() != n {
        return None;
    }
    let edge = source.mean_edge.max(1e-12);
    let x: Vec<Vec3> = target.positions.iter().map(|p| Vec3::from(*p)).collect();
    let (lo, hi) = x.iter().fold(
        (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
        |(lo, hi), p| (lo.min(*p), hi.max(*p)),
    );
    let mut warp = Warp {
        centre: (0.5 * (lo + hi)).as_dvec3(),
        scale: (0.5 * (hi - lo).length() as f64).max(1e-30),
        coef: [DVec3::ZERO; TERMS],
    };
    // 1. the warp: fitted to the matches (trimmed twice), then ICP on a spread sample
    //    (Morton-ordered working vertices: every k-th is spread over the surface)
    let spread = |count: usize| -> Vec<usize> { (0..n).step_by((n / count).max(1)).collect() };
    let fit_sample = spread(FIT_SAMPLES);
    let (xf, mf): (Vec<Vec3>, Vec<Vec3>) = fit_sample
        .iter()
        .map(|&v| (x[v], Vec3::from(matched[v])))
        .unzip();
    let mut w = vec![1.0f32; xf.len()];
    warp.fit(&xf, &mf, &w);
    for _ in 0..2 {
        let r: Vec<f32> = xf
            .par_iter()
            .zip(&mf)
            .map(|(x, m)| (warp.apply(*x) - *m).length())
            .collect();
        let cut = 3.0 * median(&r).max(0.25 * edge);
        w.iter_mut()
            .zip(&r)
            .for_each(|(w, r)| *w = if *r < cut { 1.0 } else { 0.0 });
        warp.fit(&xf, &mf, &w);
    }
    let m: Vec<Vec3> = matched.iter().map(|p| Vec3::from(*p)).collect();
    //    (the first rounds, which settle whether the target is a deformed copy at all, on a
    //    quarter of the sample)
    let samples = [spread(WARP_SAMPLES / 4), spread(WARP_SAMPLES)];
    let xss: [Vec<Vec3>; 2] = std::array::from_fn(|k| samples[k].iter().map(|&v| x[v]).collect());
    // each query starts from the face the last one found (the warp moves a point little)
    let mut hints = vec![u32::MAX; n];
    let mut last = Vec::new();
    for round in 0..WARP_ROUNDS {
        let fine = (round >= EARLY_ROUND) as usize;
        let (sample, xs) = (&samples[fine], &xss[fine]);
        let c: Vec<(Closest, Vec3)> = sample
            .par_iter()
            .map(|&v| {
                (
                    search.tracked(warp.apply(x[v]), hints[v]),
                    warp.normal(x[v], Vec3::from(target.normals[v])),
                )
            })
            .collect();
        for (&v, c) in sample.iter().zip(&c) {
            hints[v] = c.0.2;
        }
        let d: Vec<f32> = c.iter().map(|c| c.0.1).collect();
        let cut = 3.0 * median(&d).max(0.05 * edge);
        // another shape: after the first rounds most of the sample is still off the surface
        if round == EARLY_ROUND {
            let near = c
                .iter()
                .zip(sample)
                .filter(|((c, nrm), v)| {
                    c.1 <= EARLY_EDGES * edge
                        && facing(source, c, *nrm)
                        && (Vec3::from(c.0) - m[**v]).length() <= NEAR_MATCH_EDGES * edge
                })
                .count();
            if (near as f64) < EARLY_SHARE * sample.len() as f64 {
                return None;
            }
        }
        let ys: Vec<Vec3> = c.iter().map(|c| Vec3::from(c.0.0)).collect();
        let ws: Vec<f32> = c
            .iter()
            .map(|(c, nrm)| {
                if c.1 < cut && facing(source, c, *nrm) {
                    1.0
                } else {
                    0.0
                }
            })
            .collect();
        let ns: Vec<Vec3> = c
            .iter()
            .map(|(c, _)| {
                if c.2 == u32::MAX {
                    return Vec3::Z;
                }
                let f = source.faces[c.2 as usize];
                (0..3)
                    .fold(Vec3::ZERO, |acc, k| {
                        acc + c.3[k] * Vec3::from(source.normals[f[k] as usize])
                    })
                    .normalize_or(Vec3::Z)
            })
            .collect();
        warp.step_to_planes(xs, &ys, &ns, &ws);
        last = c;
    }
    // 2. rigid parts, where the warp leaves a part off (a limb turned at a joint)
    let parts = rigid_parts(search, target, &x, &m, &samples[1], &last);
    // 3. local rounds
    let mut u: Vec<Vec3> = match &parts {
        Some(p) => p.displacement(search, target, &x, &m),
        None => x.iter().map(|p| warp.apply(*p) - *p).collect(),
    };
    let mut state = closest(search, target, &x, &u, &mut hints);
    for &iters in &LOCAL_ROUNDS {
        let (c, normals) = &state;
        let d: Vec<f32> = c.iter().map(|c| c.1).collect();
        let cut = 3.0 * median(&d).max(0.05 * edge);
        let (pull, w): (Vec<Vec3>, Vec<f32>) = (0..n)
            .map(|v| {
                if d[v] < cut && facing(source, &c[v], normals[v]) {
                    (Vec3::from(c[v].0) - (x[v] + u[v]), 1.0)
                } else {
                    (Vec3::ZERO, 0.0)
                }
            })
            .unzip();
        let step = smooth(&target.adjacency, &pull, &w, iters);
        u.iter_mut().zip(&step).for_each(|(a, b)| *a += *b);
        state = closest(search, target, &x, &u, &mut hints);
    }
    // 4. the gate, then the snap
    let (c, normals) = &state;
    let on: Vec<bool> = (0..n)
        .map(|v| c[v].1 <= ON_SURFACE_EDGES * edge && facing(source, &c[v], normals[v]))
        .collect();
    let agreeing = (0..n)
        .filter(|&v| {
            on[v]
                && (Vec3::from(c[v].0) - Vec3::from(matched[v])).length() <= NEAR_MATCH_EDGES * edge
        })
        .count();
    if (agreeing as f64) < MIN_SHARE * n as f64 {
        return None;
    }
    Some(
        (0..n)
            .into_par_iter()
            .map(|v| {
                if !on[v] {
                    return None;
                }
                let turn = Quat::from_rotation_arc(Vec3::from(target.normals[v]), normals[v]);
                let w1 = turn * Vec3::from(target_frames.t1[v]);
                let w2 = turn * Vec3::from(target_frames.t2[v]);
                Some(snapped_map(
                    source,
                    source_frames,
                    Vec3::from(c[v].0),
                    &c[v],
                    w1,
                    w2,
                ))
            })
            .collect(),
    )
}

/// A target laid on the source by two similarities blended: the rest of the shape, and a part
/// turned rigidly against it (a posed limb), which no smooth warp of the whole shape follows.
struct RigidParts {
    rest: Similarity,
    part: Similarity,
}

/// One ICP round of a similarity on the sample vertices (`sample`, their positions `xs`) that
/// `take` selects: each one's closest source
/// point under it (walked from `hints`, which it updates) and moved normal, then the similarity
/// refitted (Umeyama) to those facing the same way within three times the median distance.
/// Returns the closest points and normals before the refit.
fn rigid_round(
    sim: &mut Similarity,
    search: &SurfaceSearch,
    target: &Level,
    (sample, xs): (&[usize], &[[f32; 3]]),
    take: &[bool],
    hints: &mut [u32],
) -> Vec<(Closest, Vec3)> {
    let source = search.level;
    let edge = source.mean_edge.max(1e-12);
    let c: Vec<(Closest, Vec3)> = sample
        .par_iter()
        .enumerate()
        .map(|(i, &v)| {
            let nrm = (sim.rot * Vec3::from(target.normals[v]).as_dvec3()).as_vec3();
            (search.tracked(sim.apply(Vec3::from(xs[i])), hints[v]), nrm)
        })
        .collect();
    for (&v, c) in sample.iter().zip(&c) {
        hints[v] = c.0.2;
    }
    let d: Vec<f32> = c
        .iter()
        .zip(take)
        .filter(|(_, t)| **t)
        .map(|(c, _)| c.0.1)
        .collect();
    let cut = 3.0 * median(&d).max(0.05 * edge);
    let keep: Vec<bool> = c
        .iter()
        .zip(take)
        .map(|((c, nrm), t)| *t && c.1 < cut && facing(source, c, *nrm))
        .collect();
    let ys: Vec<[f32; 3]> = c.iter().map(|c| c.0.0).collect();
    if let Some(s) = umeyama(xs, &ys, &keep) {
        *sim = s;
    }
    c
}

/// Whether a vertex belongs to the turned part: the part's similarity lays it on the source
/// (`p`, its closest point and moved normal there), and moves it nearer its own match `m` than
/// the rest's does (`by_part`, `by_rest`: the vertex moved by each).
fn in_part(by_rest: Vec3, by_part: Vec3, p: &(Closest, Vec3), source: &Level, m: Vec3) -> bool {
    let edge = source.mean_edge.max(1e-12);
    facing(source, &p.0, p.1)
        && p.0.1 <= EARLY_EDGES * edge
        && (by_part - m).length() < (by_rest - m).length()
}

/// The rigid parts (see [`RigidParts`]), where the warp's last round (`last`, on `sample`) left
/// a sizeable share of the sample off the source: a similarity fitted to the rest (to the
/// closest points the warp found for it) and one to the part (to its matches, trimmed), each
/// refined by ICP on its own vertices, alternately, as the vertices move between them. Kept
/// where the two lay more of the sample on the source than the warp did.
fn rigid_parts(
    search: &SurfaceSearch,
    target: &Level,
    x: &[Vec3],
    m: &[Vec3],
    sample: &[usize],
    last: &[(Closest, Vec3)],
) -> Option<RigidParts> {
    let source = search.level;
    let edge = source.mean_edge.max(1e-12);
    // a similarity has seven degrees of freedom: a quarter of the sample is plenty
    let sample: Vec<usize> = sample.iter().step_by(4).copied().collect();
    let last: Vec<(Closest, Vec3)> = last.iter().step_by(4).copied().collect();
    let (sample, last) = (&sample[..], &last[..]);
    let on = |c: &(Closest, Vec3), within: f32| c.0.1 <= within * edge && facing(source, &c.0, c.1);
    let mut member: Vec<bool> = last.iter().map(|c| !on(c, PART_OFF_EDGES)).collect();
    let off = member.iter().filter(|&&b| b).count();
    if (off as f64) < PART_SHARE * sample.len() as f64 {
        return None;
    }
    let xs: Vec<[f32; 3]> = sample.iter().map(|&v| x[v].to_array()).collect();
    let ys: Vec<[f32; 3]> = last.iter().map(|c| c.0.0).collect();
    let ms: Vec<[f32; 3]> = sample.iter().map(|&v| m[v].to_array()).collect();
    let not: Vec<bool> = member.iter().map(|b| !b).collect();
    let mut rest = umeyama(&xs, &ys, &not)?;
    let mut part = umeyama_trimmed(&xs, &ms, &member, 0.25 * edge)?;
    let n = x.len();
    let (mut rest_hints, mut part_hints) = (vec![u32::MAX; n], vec![u32::MAX; n]);
    let (mut cr, mut cp) = (Vec::new(), Vec::new());
    for _ in 0..PART_ALTERNATIONS {
        let not: Vec<bool> = member.iter().map(|b| !b).collect();
        for _ in 0..PART_ROUNDS {
            cp = rigid_round(
                &mut part,
                search,
                target,
                (sample, &xs),
                &member,
                &mut part_hints,
            );
        }
        for _ in 0..PART_ROUNDS {
            cr = rigid_round(
                &mut rest,
                search,
                target,
                (sample, &xs),
                &not,
                &mut rest_hints,
            );
        }
        for i in 0..sample.len() {
            let v = sample[i];
            member[i] = in_part(rest.apply(x[v]), part.apply(x[v]), &cp[i], source, m[v]);
        }
    }
    let laid = (0..sample.len())
        .filter(|&i| on(&cr[i], ON_SURFACE_EDGES) || on(&cp[i], ON_SURFACE_EDGES))
        .count();
    let by_warp = last.iter().filter(|c| on(c, ON_SURFACE_EDGES)).count();
    (laid > by_warp).then_some(RigidParts { rest, part })
}

impl RigidParts {
    /// Every target vertex's displacement: the rest's similarity, turned into the part's where
    /// the part lays the vertex on the source ([`in_part`]), the choice smoothed over the target so
    /// the two blend across the joint.
    fn displacement(
        &self,
        search: &SurfaceSearch,
        target: &Level,
        x: &[Vec3],
        m: &[Vec3],
    ) -> Vec<Vec3> {
        let source = search.level;
        let n = x.len();
        let choice: Vec<Vec3> = (0..n)
            .into_par_iter()
            .map(|v| {
                let (a, b) = (self.rest.apply(x[v]), self.part.apply(x[v]));
                // the part's closest point only where the part moves the vertex nearer its match
                if (b - m[v]).length() >= (a - m[v]).length() {
                    return Vec3::ZERO;
                }
                let nv = Vec3::from(target.normals[v]).as_dvec3();
                let p = (search.closest(b), (self.part.rot * nv).as_vec3());
                Vec3::splat(in_part(a, b, &p, source, m[v]) as u8 as f32)
            })
            .collect();
        let weight = smooth(&target.adjacency, &choice, &vec![1.0f32; n], BLEND_ITERS);
        (0..n)
            .into_par_iter()
            .map(|v| {
                let a = self.rest.apply(x[v]);
                let b = self.part.apply(x[v]);
                a + weight[v].x * (b - a) - x[v]
            })
            .collect()
    }
}

/// The closest source point of every displaced target vertex, and the displaced normals; each
/// query starts from its vertex's face in `hints`, which it updates.
fn closest(
    search: &SurfaceSearch,
    target: &Level,
    x: &[Vec3],
    u: &[Vec3],
    hints: &mut [u32],
) -> (Vec<Closest>, Vec<Vec3>) {
    let p: Vec<[f32; 3]> = x.iter().zip(u).map(|(a, b)| (*a + *b).to_array()).collect();
    let normals: Vec<Vec3> = area_weighted_normals(&p, &target.faces)
        .into_iter()
        .map(Vec3::from)
        .collect();
    let c: Vec<Closest> = p
        .par_iter()
        .zip(hints.par_iter())
        .map(|(q, &h)| search.tracked(Vec3::from(*q), h))
        .collect();
    hints.iter_mut().zip(&c).for_each(|(h, c)| *h = c.2);
    (c, normals)
}

/// `values` weighted by `weights`, averaged `iters` times over each vertex and its neighbours,
/// over the averaged weights (0 where no weight reached).
fn smooth(adj: &Csr, values: &[Vec3], weights: &[f32], iters: usize) -> Vec<Vec3> {
    let mut a: Vec<(Vec3, f32)> = values
        .iter()
        .zip(weights)
        .map(|(v, w)| (*v * *w, *w))
        .collect();
    let mut b = a.clone();
    for _ in 0..iters {
        b.par_iter_mut().enumerate().for_each(|(i, out)| {
            let row = adj.row(i);
            let mut s = a[i];
            for &j in row {
                s.0 += a[j as usize].0;
                s.1 += a[j as usize].1;
            }
            let k = 1.0 / (1 + row.len()) as f32;
            *out = (s.0 * k, s.1 * k);
        });
        std::mem::swap(&mut a, &mut b);
    }
    a.iter()
        .map(|(v, w)| if *w > 1e-6 { *v / *w } else { Vec3::ZERO })
        .collect()
}
