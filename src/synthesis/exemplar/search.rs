//! Best-match search in the exemplar: exhaustive (the reference, Wei & Levoy 2001 Table 3 line
//! 13-14 over every exemplar neighbourhood, rayon-parallel) and fast (coherence candidates à la
//! Ashikhmin 2001 transported through the neighbours' texture frames, plus PatchMatch random
//! search, Barnes et al. 2009).

use rayon::prelude::*;

use super::neigh::ExemplarLevel;
use crate::stats::beats;

/// Squared L2 distance between a query and candidate `c`, giving up once it exceeds `bound`.
/// The searches keep a candidate only when it [`beats`] the best so far by a margin, so that
/// the choice between two near-equal candidates is the same for the mesh in any units.
#[inline]
pub(crate) fn dist(
    ex: &ExemplarLevel,
    c: u32,
    q_cur: Option<&[f32]>,
    q_par: Option<&[f32]>,
    bound: f32,
) -> f32 {
    if !ex.allowed(c) {
        return f32::INFINITY;
    }
    let c = c as usize;
    let mut d = 0.0f32;
    if let Some(q) = q_par {
        let dp = ex.dim_par();
        let row = &ex.par[c * dp..(c + 1) * dp];
        d += sq(q, row);
        if d >= bound {
            return d;
        }
    }
    if let Some(q) = q_cur {
        let dc = ex.dim_cur();
        let row = &ex.cur[c * dc..(c + 1) * dc];
        for (qa, ra) in q.chunks(24).zip(row.chunks(24)) {
            d += sq(qa, ra);
            if d >= bound {
                return d;
            }
        }
    }
    d
}

#[inline]
fn sq(a: &[f32], b: &[f32]) -> f32 {
    a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum()
}

/// Exhaustive search over all candidates of the level; ties go to the lowest index.
pub(crate) fn exhaustive(
    ex: &ExemplarLevel,
    q_cur: Option<&[f32]>,
    q_par: Option<&[f32]>,
) -> (u32, f32) {
    let n = ex.num_candidates();
    const CHUNK: usize = 256;
    (0..n.div_ceil(CHUNK))
        .into_par_iter()
        .map(|ch| {
            let mut best = (u32::MAX, f32::INFINITY);
            for c in ch * CHUNK..((ch + 1) * CHUNK).min(n) {
                let d = dist(ex, c as u32, q_cur, q_par, best.1);
                if beats(d, best.1) {
                    best = (c as u32, d);
                }
            }
            best
        })
        .reduce(
            || (u32::MAX, f32::INFINITY),
            |a, b| {
                // a total order across chunks (their merge order varies with the threads)
                if b.1 < a.1 || (b.1 == a.1 && b.0 < a.0) {
                    b
                } else {
                    a
                }
            },
        )
}

/// Evaluate a candidate list (duplicates skipped) and refine the best one by PatchMatch random
/// search: samples around it at radii halving from the exemplar size down to one pixel.
pub(crate) fn fast(
    ex: &ExemplarLevel,
    cands: &mut Vec<u32>,
    q_cur: Option<&[f32]>,
    q_par: Option<&[f32]>,
    rng: &mut impl rand::Rng,
) -> (u32, f32) {
    cands.sort_unstable();
    cands.dedup();
    let mut best = (u32::MAX, f32::INFINITY);
    for &c in cands.iter() {
        let d = dist(ex, c, q_cur, q_par, best.1);
        if beats(d, best.1) {
            best = (c, d);
        }
    }
    if best.0 == u32::MAX {
        return best;
    }
    // local refinement: the 8 pixels around the best candidate
    let (bx, by) = ex.pixel(best.0);
    for dy in -1i64..=1 {
        for dx in -1i64..=1 {
            let c = ex.cand_at(bx as i64 + dx, by as i64 + dy);
            let d = dist(ex, c, q_cur, q_par, best.1);
            if beats(d, best.1) {
                best = (c, d);
            }
        }
    }
    for _round in 0..2 {
        let mut radius = ex.cw.max(ex.ch) as i64 / 2;
        while radius >= 1 {
            let (x, y) = ex.pixel(best.0);
            let nx = x as i64 + rng.random_range(-radius..=radius);
            let ny = y as i64 + rng.random_range(-radius..=radius);
            let c = ex.cand_at(nx, ny);
            let d = dist(ex, c, q_cur, q_par, best.1);
            if beats(d, best.1) {
                best = (c, d);
            }
            radius /= 2;
        }
    }
    best
}
