//! Directional occlusion by ray casting, projected on spherical harmonics bands 0 and 1
//! (Mertens et al. 2006 §3.1 "directional occlusion"; Sloan, Kautz & Snyder 2002).
//!
//! Per vertex, `rays` directions stratified over the hemisphere of the vertex normal (a jittered
//! `rows × cols` grid in `(cos θ, φ)`, uniform in solid angle, seeded per vertex so the result
//! does not depend on thread scheduling) are cast from `p + ε n` (`ε = 1e-4 × bbox diagonal`)
//! against an any-hit BVH ([`OcclusionBvh`]: stops at the first triangle crossed, no allocation
//! per ray); `V(d) = 1` when the ray escapes. Output per vertex:
//!
//! - `ao = (1/N) Σ V(d)`: the visible fraction (band 0, `c_00 = 2π Y_00 · ao`), 1 on an open
//!   plane, lower in crevices;
//! - `o = (2/N) Σ V(d) d` (3 numbers, object space): band 1 (`c_1m ∝ o_y, o_z, o_x`), the
//!   "open direction" scaled so a fully open point gives `o = n`.
//!
//! The SH constants are left out (a fixed scale per band changes nothing downstream).

use glam::Vec3;
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};
use rayon::prelude::*;

use crate::error::Result;
use crate::work::CancelToken;

const LEAF: usize = 4;

#[derive(Clone, Copy, Debug)]
struct Node {
    lo: Vec3,
    hi: Vec3,
    /// Leaf: first triangle slot; inner: left child (right = left + 1).
    start: u32,
    /// Triangles in a leaf, 0 for an inner node.
    count: u32,
}

/// A BVH for shadow rays (any hit): binned SAH splits (median fallback), leaves of up to 4
/// triangles stored as `(v0, e1, e2)`, traversal with a fixed stack and early exit.
#[derive(Clone, Debug)]
pub struct OcclusionBvh {
    nodes: Vec<Node>,
    tris: Vec<[Vec3; 3]>,
}

fn surface_area(lo: Vec3, hi: Vec3) -> f32 {
    let d = (hi - lo).max(Vec3::ZERO);
    d.x * d.y + d.y * d.z + d.z * d.x
}

/// Partition `tris` for a binned surface-area-heuristic split (12 bins per axis over the
/// centroid bounds `clo..chi`, centroids stored as corner sums); returns the split index, the
/// median on the longest axis when no split beats it.
fn sah_split(tris: &mut [[Vec3; 3]], clo: Vec3, chi: Vec3) -> usize {
    const BINS: usize = 12;
    let n = tris.len();
    let ext = chi - clo;
    let mut best = (f32::INFINITY, 0usize, 0usize); // cost, axis, bins on the left
    for axis in 0..3 {
        if ext[axis] <= 0.0 {
            continue;
        }
        let scale = BINS as f32 / ext[axis];
        let mut cnt = [0usize; BINS];
        let mut blo = [Vec3::splat(f32::INFINITY); BINS];
        let mut bhi = [Vec3::splat(f32::NEG_INFINITY); BINS];
        for t in tris.iter() {
            let c = t[0][axis] + t[1][axis] + t[2][axis];
            let b = (((c - clo[axis]) * scale) as usize).min(BINS - 1);
            cnt[b] += 1;
            for x in t {
                blo[b] = blo[b].min(*x);
                bhi[b] = bhi[b].max(*x);
            }
        }
        // sweep from the right, then from the left
        let mut right_area = [0.0f32; BINS];
        let mut right_cnt = [0usize; BINS];
        let (mut lo, mut hi, mut c) = (
            Vec3::splat(f32::INFINITY),
            Vec3::splat(f32::NEG_INFINITY),
            0,
        );
        for b in (1..BINS).rev() {
            lo = lo.min(blo[b]);
            hi = hi.max(bhi[b]);
            c += cnt[b];
            right_area[b] = surface_area(lo, hi);
            right_cnt[b] = c;
        }
        let (mut lo, mut hi, mut c) = (
            Vec3::splat(f32::INFINITY),
            Vec3::splat(f32::NEG_INFINITY),
            0,
        );
        for b in 0..BINS - 1 {
            lo = lo.min(blo[b]);
            hi = hi.max(bhi[b]);
            c += cnt[b];
            if c == 0 || right_cnt[b + 1] == 0 {
                continue;
            }
            let cost =
                surface_area(lo, hi) * c as f32 + right_area[b + 1] * right_cnt[b + 1] as f32;
            if cost < best.0 {
                best = (cost, axis, b + 1);
            }
        }
    }
    if best.0.is_finite() {
        let (axis, bins) = (best.1, best.2);
        let scale = BINS as f32 / ext[axis];
        let left = |t: &[Vec3; 3]| {
            let c = t[0][axis] + t[1][axis] + t[2][axis];
            ((((c - clo[axis]) * scale) as usize).min(BINS - 1)) < bins
        };
        // in-place partition
        let mut i = 0;
        for j in 0..n {
            if left(&tris[j]) {
                tris.swap(i, j);
                i += 1;
            }
        }
        if i > 0 && i < n {
            return i;
        }
    }
    median_split(tris, clo, chi)
}

/// Median split on the longest centroid axis.
fn median_split(tris: &mut [[Vec3; 3]], clo: Vec3, chi: Vec3) -> usize {
    let n = tris.len();
    let ext = chi - clo;
    let axis = if ext.x >= ext.y && ext.x >= ext.z {
        0
    } else if ext.y >= ext.z {
        1
    } else {
        2
    };
    let mid = n / 2;
    tris.select_nth_unstable_by(mid, |a, b| {
        (a[0][axis] + a[1][axis] + a[2][axis]).total_cmp(&(b[0][axis] + b[1][axis] + b[2][axis]))
    });
    mid
}

impl OcclusionBvh {
    /// Build over `faces` (faces with out-of-range indices are left out).
    pub fn new(positions: &[[f32; 3]], faces: &[[u32; 3]]) -> Self {
        Self::build(positions, faces, true)
    }

    fn build(positions: &[[f32; 3]], faces: &[[u32; 3]], sah: bool) -> Self {
        let nv = positions.len();
        let mut tris: Vec<[Vec3; 3]> = faces
            .iter()
            .filter(|f| f.iter().all(|&v| (v as usize) < nv))
            .map(|f| f.map(|v| Vec3::from(positions[v as usize])))
            .collect();
        let mut nodes = Vec::with_capacity(2 * tris.len() / LEAF + 2);
        let blank = Node {
            lo: Vec3::ZERO,
            hi: Vec3::ZERO,
            start: 0,
            count: 0,
        };
        if !tris.is_empty() {
            nodes.push(blank);
            let mut stack = vec![(0usize, 0usize, tris.len())];
            while let Some((ni, s, e)) = stack.pop() {
                let mut lo = Vec3::splat(f32::INFINITY);
                let mut hi = Vec3::splat(f32::NEG_INFINITY);
                let (mut clo, mut chi) = (lo, hi);
                for t in &tris[s..e] {
                    for x in t {
                        lo = lo.min(*x);
                        hi = hi.max(*x);
                    }
                    let c = t[0] + t[1] + t[2];
                    clo = clo.min(c);
                    chi = chi.max(c);
                }
                nodes[ni].lo = lo;
                nodes[ni].hi = hi;
                if e - s <= LEAF {
                    nodes[ni].start = s as u32;
                    nodes[ni].count = (e - s) as u32;
                    continue;
                }
                let mid = if sah {
                    sah_split(&mut tris[s..e], clo, chi)
                } else {
                    median_split(&mut tris[s..e], clo, chi)
                } + s;
                let left = nodes.len();
                nodes.push(blank);
                nodes.push(blank);
                nodes[ni].start = left as u32;
                stack.push((left, s, mid));
                stack.push((left + 1, mid, e));
            }
        }
        for t in tris.iter_mut() {
            *t = [t[0], t[1] - t[0], t[2] - t[0]];
        }
        OcclusionBvh { nodes, tris }
    }

    /// Does the ray `o + t d`, `0 ≤ t ≤ tmax`, cross any triangle (either side)?
    pub fn occluded(&self, o: Vec3, d: Vec3, tmax: f32) -> bool {
        if self.nodes.is_empty() {
            return false;
        }
        let inv = d.recip();
        let mut stack = [0u32; 64];
        let mut sp = 1usize;
        while sp > 0 {
            sp -= 1;
            let node = &self.nodes[stack[sp] as usize];
            let t0 = (node.lo - o) * inv;
            let t1 = (node.hi - o) * inv;
            let tn = t0.min(t1);
            let tf = t0.max(t1);
            let near = tn.x.max(tn.y).max(tn.z).max(0.0);
            let far = tf.x.min(tf.y).min(tf.z).min(tmax);
            if near > far {
                continue;
            }
            if node.count > 0 {
                for t in &self.tris[node.start as usize..(node.start + node.count) as usize] {
                    let [a, e1, e2] = *t;
                    let pv = d.cross(e2);
                    let det = e1.dot(pv);
                    if det.abs() < 1e-20 {
                        continue;
                    }
                    let id = 1.0 / det;
                    let tv = o - a;
                    let u = tv.dot(pv) * id;
                    if !(0.0..=1.0).contains(&u) {
                        continue;
                    }
                    let qv = tv.cross(e1);
                    let v = d.dot(qv) * id;
                    if v < 0.0 || u + v > 1.0 {
                        continue;
                    }
                    let th = e2.dot(qv) * id;
                    if th >= 0.0 && th <= tmax {
                        return true;
                    }
                }
            } else if sp + 2 <= stack.len() {
                stack[sp] = node.start;
                stack[sp + 1] = node.start + 1;
                sp += 2;
            }
        }
        false
    }
}

/// Grid of strata used for `rays` directions: `(rows, cols)`, `rows × cols ≥ rays`.
pub fn strata(rays: usize) -> (usize, usize) {
    let rows = ((rays as f64).sqrt().round() as usize).max(1);
    (rows, rays.max(1).div_ceil(rows))
}

/// An orthonormal frame `(t, b)` completing the unit normal `n` (Duff et al. 2017).
#[inline]
fn frame(n: Vec3) -> (Vec3, Vec3) {
    let s = 1.0f32.copysign(n.z);
    let a = -1.0 / (s + n.z);
    let b = n.x * n.y * a;
    (
        Vec3::new(1.0 + s * n.x * n.x * a, s * b, -s * n.x),
        Vec3::new(b, s + n.y * n.y * a, -n.y),
    )
}

/// Directional occlusion `[ao, o_x, o_y, o_z]` of every vertex (see the module doc), with
/// `rays` rays per vertex (rounded up to fill the strata grid) and `seed`. Vertices with a zero
/// normal get `[1, 0, 0, 0]`.
pub fn directional_occlusion(
    positions: &[[f32; 3]],
    faces: &[[u32; 3]],
    normals: &[[f32; 3]],
    rays: usize,
    seed: u64,
) -> Vec<[f32; 4]> {
    let bvh = OcclusionBvh::new(positions, faces);
    directional_occlusion_with(&bvh, positions, normals, rays, seed, &CancelToken::new())
        .unwrap_or_default()
}

/// [`directional_occlusion`] on a prebuilt BVH, checking `cancel` between batches.
pub fn directional_occlusion_with(
    bvh: &OcclusionBvh,
    positions: &[[f32; 3]],
    normals: &[[f32; 3]],
    rays: usize,
    seed: u64,
    cancel: &CancelToken,
) -> Result<Vec<[f32; 4]>> {
    let n = positions.len().min(normals.len());
    let (rows, cols) = strata(rays);
    let total = (rows * cols) as f32;
    let mut lo = Vec3::splat(f32::INFINITY);
    let mut hi = Vec3::splat(f32::NEG_INFINITY);
    for p in positions {
        let p = Vec3::from(*p);
        if p.is_finite() {
            lo = lo.min(p);
            hi = hi.max(p);
        }
    }
    let eps = if lo.x <= hi.x {
        1e-4 * (hi - lo).length()
    } else {
        0.0
    };
    let mut out = vec![[1.0f32, 0.0, 0.0, 0.0]; n];
    const BATCH: usize = 2048;
    for (bi, chunk) in out.chunks_mut(BATCH).enumerate() {
        cancel.check()?;
        chunk.par_iter_mut().enumerate().for_each(|(i, o)| {
            let v = bi * BATCH + i;
            let nrm = Vec3::from(normals[v]);
            let p = Vec3::from(positions[v]);
            if nrm.length_squared().is_nan() || nrm.length_squared() <= 0.5 || !p.is_finite() {
                return;
            }
            let (t, b) = frame(nrm);
            let origin = p + eps * nrm;
            let mut rng = SmallRng::seed_from_u64(
                seed ^ (v as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15) ^ 0x6f63_636c,
            );
            let mut vis = 0.0f32;
            let mut dir_sum = Vec3::ZERO;
            for r in 0..rows {
                for c in 0..cols {
                    let z = (r as f32 + rng.random::<f32>()) / rows as f32;
                    let phi =
                        std::f32::consts::TAU * (c as f32 + rng.random::<f32>()) / cols as f32;
                    let s = (1.0 - z * z).max(0.0).sqrt();
                    let d = t * (s * phi.cos()) + b * (s * phi.sin()) + nrm * z;
                    if !bvh.occluded(origin, d, f32::INFINITY) {
                        vis += 1.0;
                        dir_sum += d;
                    }
                }
            }
            let od = dir_sum * (2.0 / total);
            *o = [vis / total, od.x, od.y, od.z];
        });
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A grid `[0,m]²` at z = 0 with a square pit of depth `depth` over cells `[a, b)²`.
    fn pit(m: u32, a: u32, b: u32, depth: f32) -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
        let mut pos = Vec::new();
        for y in 0..=m {
            for x in 0..=m {
                let inside = (a + 1..b).contains(&x) && (a + 1..b).contains(&y);
                pos.push([x as f32, y as f32, if inside { -depth } else { 0.0 }]);
            }
        }
        let mut faces = Vec::new();
        for y in 0..m {
            for x in 0..m {
                let i = y * (m + 1) + x;
                faces.push([i, i + 1, i + m + 2]);
                faces.push([i, i + m + 2, i + m + 1]);
            }
        }
        (pos, faces)
    }

    /// SAH vs median-split trees on the horse (`--ignored --nocapture`), alternating.
    #[test]
    #[ignore]
    fn sah_vs_median_rays_per_second() {
        let m = crate::mesh::io::load(&crate::testdata::data_path("horse/horse.ply")).unwrap();
        let mut faces = m.faces.clone();
        faces.iter_mut().for_each(|f| f.swap(1, 2)); // the horse is wound inwards
        let nrm = crate::geometry::vertex_normals(&m.positions, &faces);
        for round in 0..2 {
            for sah in [false, true] {
                let t = std::time::Instant::now();
                let bvh = OcclusionBvh::build(&m.positions, &faces, sah);
                let tb = t.elapsed().as_secs_f64();
                let t = std::time::Instant::now();
                let o = directional_occlusion_with(
                    &bvh,
                    &m.positions,
                    &nrm,
                    64,
                    1,
                    &CancelToken::new(),
                )
                .unwrap();
                let s = t.elapsed().as_secs_f64();
                let mean = o.iter().map(|x| x[0] as f64).sum::<f64>() / o.len() as f64;
                eprintln!(
                    "round {round} sah {sah}: build {tb:.3} s, {:.2} M rays/s, mean ao {mean:.4}",
                    64.0 * o.len() as f64 / s / 1e6
                );
            }
        }
    }

    #[test]
    fn plane_is_open_and_pit_bottom_is_dark() {
        let (pos, faces) = pit(30, 10, 20, 0.0);
        let nrm = crate::geometry::vertex_normals(&pos, &faces);
        let occ = directional_occlusion(&pos, &faces, &nrm, 64, 1);
        for o in &occ {
            assert!((o[0] - 1.0).abs() < 1e-6);
            // open direction ~ normal (+z) up to sampling noise
            assert!((o[3] - 1.0).abs() < 0.1 && o[0..3].iter().all(|x| x.is_finite()));
        }
        let (pos, faces) = pit(30, 10, 20, 4.0);
        let nrm = crate::geometry::vertex_normals(&pos, &faces);
        let occ = directional_occlusion(&pos, &faces, &nrm, 64, 1);
        let id = |x: u32, y: u32| (y * 31 + x) as usize;
        let bottom = occ[id(15, 15)][0];
        let rim = occ[id(10, 5)][0];
        assert!(rim > 0.99, "rim {rim}");
        assert!(bottom < 0.5, "bottom {bottom}");
        // deterministic
        assert_eq!(directional_occlusion(&pos, &faces, &nrm, 64, 1), occ);
    }
}
