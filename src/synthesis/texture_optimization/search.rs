//! The nearest-patch search (Kwatra et al. 2005 §3's E-step, accelerated): per scale, the
//! exemplar's valid patch centres, their `8 x 8` cell means reduced by PCA in a k-d tree, bins of
//! centres by line distance for the feature constraint (Xu et al. 2009 §5.2); the best few
//! verified on every filled cell, then registered at full resolution.

use rand::SeedableRng;
use rand::rngs::SmallRng;
use rand::seq::SliceRandom;
use rayon::prelude::*;

use super::exemplar::Exemplar;
use super::exemplar_lines::ExemplarLines;
use super::samples::Regions;
use super::{CELLS, REFINE, VERIFY};
use crate::error::{Error, Result};
use crate::stats::KdTree;

/// One scale's exemplar index: valid patch centres, PCA basis, k-d tree, constraint bins.
pub(super) struct Index {
    /// Valid centres as pixel indices `cy * W + cx`.
    pub(super) centres: Vec<u32>,
    /// Per exemplar pixel, its index in `centres` (`u32::MAX`: not a valid centre).
    pub(super) slot: Vec<u32>,
    pub(super) mean: Vec<f32>,
    /// `dim × k`, row-major by input dimension.
    pub(super) basis: Vec<f32>,
    pub(super) k: usize,
    pub(super) tree: KdTree,
    /// Projections of `centres`, row-major `k` per centre.
    pub(super) proj: Vec<f32>,
    /// Per integer exemplar distance `b` (0..=w/2): centres whose line distance is within
    /// `tolerance + 0.5` of `b`.
    pub(super) bins: Vec<Vec<u32>>,
}

pub(super) const DIM: usize = CELLS * CELLS * 3;

impl Index {
    pub(super) fn build(
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

pub(super) fn project(v: &[f32], mean: &[f32], basis: &[f32], k: usize) -> Vec<f32> {
    let mut o = vec![0.0f32; k];
    project_into(v, mean, basis, &mut o);
    o
}

/// [`project`] into `o` (its length is the number of dimensions).
pub(super) fn project_into(v: &[f32], mean: &[f32], basis: &[f32], o: &mut [f32]) {
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

/// Cell means of sample `s`'s patch from the current colours; `cnt` = vertices per cell. Empty
/// cells take the patch mean (they are left out of the verified distance).
pub(super) fn patch_cells(
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
pub(super) fn full_rms(
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
pub(super) fn masked_rms(a: &[f32], b: &[f32], cnt: &[u32]) -> f32 {
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
pub(super) fn constrained_knn(
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

/// Kwatra et al.'s E-step: per sample of `reg`, the nearest exemplar patch of width `w` to its
/// patch under `colors` (the index's candidates, constrained to the line distance `target_d`
/// within `tolerance` where given, plus the previous patch `z`), verified on every filled cell
/// and registered at full resolution; (centre slot, distance), `u32::MAX` where none.
#[allow(clippy::too_many_arguments)]
pub(super) fn nearest_patches(
    index: &Index,
    ex: &Exemplar,
    reg: &Regions,
    colors: &[[f32; 3]],
    w: usize,
    target_d: &[Option<f32>],
    lines: Option<&ExemplarLines>,
    z: &[u32],
    tolerance: f32,
) -> Vec<(u32, f32)> {
    (0..reg.samples.len())
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
                patch_cells(reg, s, colors, w, cells, cnt);
                project_into(cells, &index.mean, &index.basis, q);
                cands.clear();
                if let Some(dt) = target_d[s] {
                    constrained_knn(
                        index,
                        lines.expect("lines"),
                        q,
                        dt,
                        tolerance,
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
                            (lines.expect("lines").distance[c] - dt).abs() < tolerance
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
                            && (lines.expect("lines").distance[q] - dt).abs() >= tolerance
                        {
                            continue;
                        }
                        let d = full_rms(reg, s, colors, ex, x as f32, y as f32, fine.1);
                        if d < fine.1 {
                            fine = (c, d);
                        }
                    }
                }
                if fine.1.is_finite() { fine } else { best }
            },
        )
        .collect()
}
