//! Non-parametric synthesis for geometry-correlated transfer (Mertens et al. 2006, §4.1): image
//! analogies on the surface. Every target vertex copies the colour of one source vertex, chosen
//! by its guidance (the matched CCA projection of the geometry features) and by the colour of its
//! neighbourhood, with a coherence term that prefers continuing the source patches its
//! neighbours already copy (Ashikhmin / Hertzmann et al. 2001).
//!
//! Pass 0 takes each target vertex's nearest source vertex in guidance (a k-d tree). Each later
//! pass, in parallel over the target vertices (Jacobi style: it reads the previous pass, so the
//! result does not depend on the thread count), compares two kinds of candidates under
//! `cost = |g_t - g_s|^2 / var_g + w |n_t - n_s|^2 / var_n`, with `n` the mean colour of the
//! 1-ring: the `k` nearest in guidance ("approximate") and the source vertices its neighbours
//! copy plus their 1-rings ("coherent"); a coherent candidate wins unless the best approximate
//! one is cheaper by more than the factor `1 + kappa`.

use rayon::prelude::*;

use crate::error::Result;
use crate::mesh::Csr;
use crate::stats::KdTree;

/// Knobs of the non-parametric synthesis.
#[derive(Clone, Debug)]
pub struct Knobs {
    /// Refinement passes after the guidance-only pass.
    pub passes: usize,
    /// Approximate candidates per vertex (nearest in guidance).
    pub candidates: usize,
    /// Coherence `kappa`: a coherent candidate wins unless an approximate one costs less than
    /// `1 / (1 + kappa)` of it.
    pub coherence: f32,
    /// Weight of the neighbourhood colour against the guidance.
    pub colour_weight: f32,
}

impl Default for Knobs {
    fn default() -> Self {
        Knobs {
            passes: 3,
            candidates: 8,
            coherence: 1.0,
            colour_weight: 1.0,
        }
    }
}

fn ring_means(adj: &Csr, colour: &[[f32; 3]]) -> Vec<[f32; 3]> {
    (0..adj.len())
        .into_par_iter()
        .map(|v| {
            let row = adj.row(v);
            let mut m = [0.0f32; 3];
            for &u in row {
                for c in 0..3 {
                    m[c] += colour[u as usize][c];
                }
            }
            let k = row.len().max(1) as f32;
            m.map(|x| x / k)
        })
        .collect()
}

fn variance(rows: impl Iterator<Item = f32> + Clone, n: usize) -> f32 {
    let n = n.max(1) as f64;
    let mean = rows.clone().map(|x| x as f64).sum::<f64>() / n;
    let var = rows.map(|x| (x as f64 - mean).powi(2)).sum::<f64>() / n;
    (var as f32).max(1e-12)
}

/// Called after every pass with its index and the colours so far.
pub type PassSink<'a> = dyn FnMut(usize, &[[f32; 3]]) -> Result<()> + 'a;

/// Synthesize the target's colour: `gs` is the guidance of every source vertex (`d` per vertex),
/// `train` the source vertices that may be copied, `colour` every source vertex's colour, `gt`
/// the target's matched guidance. Returns the colour per target vertex (in `colour`'s space) and
/// calls `partial` after every pass.
#[allow(clippy::too_many_arguments)]
pub fn synthesize(
    gs: &[f32],
    train: &[u32],
    colour: &[[f32; 3]],
    src_adj: &Csr,
    gt: &[f32],
    tgt_adj: &Csr,
    d: usize,
    knobs: &Knobs,
    partial: &mut PassSink,
) -> Result<Vec<[f32; 3]>> {
    let d = d.max(1);
    let nt = gt.len() / d;
    let mut is_train = vec![false; colour.len()];
    for &s in train {
        is_train[s as usize] = true;
    }
    let train_g: Vec<f32> = train
        .iter()
        .flat_map(|&s| gs[s as usize * d..(s as usize + 1) * d].iter().copied())
        .collect();
    let tree = KdTree::new(&train_g, d);
    let src_ring = ring_means(src_adj, colour);
    // Normalisers over the training set: total guidance variance, neighbourhood colour variance.
    let var_g: f32 = (0..d)
        .map(|k| variance(train_g.iter().skip(k).step_by(d).copied(), train.len()))
        .sum();
    let var_n: f32 = (0..3)
        .map(|c| variance(train.iter().map(|&s| src_ring[s as usize][c]), train.len()))
        .sum();
    let g_of = |s: u32| &gs[s as usize * d..(s as usize + 1) * d];

    // Pass 0: nearest in guidance.
    let mut matched: Vec<u32> = (0..nt)
        .into_par_iter()
        .map_init(Vec::new, |buf, v| {
            tree.knn(&gt[v * d..(v + 1) * d], 1, buf);
            buf.first().map_or(train[0], |e| train[e.1 as usize])
        })
        .collect();
    let mut out: Vec<[f32; 3]> = matched.iter().map(|&s| colour[s as usize]).collect();
    partial(0, &out)?;

    for pass in 1..=knobs.passes {
        let tgt_ring = ring_means(tgt_adj, &out);
        let prev = &matched;
        let next: Vec<u32> = (0..nt)
            .into_par_iter()
            .map_init(Vec::new, |buf, v| {
                let q = &gt[v * d..(v + 1) * d];
                let ring = tgt_ring[v];
                let cost = |s: u32| -> f32 {
                    let g: f32 = g_of(s).iter().zip(q).map(|(a, b)| (a - b) * (a - b)).sum();
                    let r = src_ring[s as usize];
                    let n: f32 = (0..3).map(|c| (r[c] - ring[c]).powi(2)).sum();
                    g / var_g + knobs.colour_weight * n / var_n
                };
                tree.knn(q, knobs.candidates.max(1), buf);
                let mut best_app = (f32::INFINITY, prev[v]);
                for &(_, i) in buf.iter() {
                    let s = train[i as usize];
                    let c = cost(s);
                    if c < best_app.0 {
                        best_app = (c, s);
                    }
                }
                let mut best_coh = (f32::INFINITY, prev[v]);
                let mut consider = |s: u32| {
                    if is_train[s as usize] {
                        let c = cost(s);
                        if c < best_coh.0 {
                            best_coh = (c, s);
                        }
                    }
                };
                consider(prev[v]);
                for &u in tgt_adj.row(v) {
                    let m = prev[u as usize];
                    consider(m);
                    for &w in src_adj.row(m as usize) {
                        consider(w);
                    }
                }
                if best_coh.0 <= best_app.0 * (1.0 + knobs.coherence) {
                    best_coh.1
                } else {
                    best_app.1
                }
            })
            .collect();
        matched = next;
        out = matched.iter().map(|&s| colour[s as usize]).collect();
        partial(pass, &out)?;
    }
    Ok(out)
}
