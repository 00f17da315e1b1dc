//! Parametric synthesis: constrained Heeger-Bergen (Mertens et al. 2006 §4.2).
//!
//! 1. k-means on the guidance values, separately on source and target (`K` clusters).
//! 2. Feathering: soft weights `w_k(x) ∝ exp(-|x - F_k|² / (2σ_k²))`, `σ_k` = RMS member
//!    distance to the centre `F_k`, normalised per point, weights below 1e-3 dropped.
//! 3. Source model per cluster: weighted quantile functions (256 points) of each decorrelated
//!    colour channel and of each of its Laplacian bands (`H^s`), and a weighted least-squares
//!    affine map `Y = A X + b` from guidance to colour.
//! 4. Target model per cluster: Shepard interpolation (weights `1/d²`) of the `k` nearest source
//!    clusters' quantile functions (averaged as inverse CDFs, Matusik et al. 2005) and affine maps.
//! 5. Initialisation `Y^t = Σ_k w_k (A_k X^t + b_k)` plus white noise of the pooled regression
//!    residual's standard deviation.
//! 6. Heeger-Bergen iterations: per channel, decompose, match every band per cluster over its
//!    support and blend by `w_k`, collapse, then the same for the channel values.

use faer::MatRef;
use faer::linalg::solvers::Solve;
use rand::SeedableRng;
use rand::rngs::SmallRng;
use rayon::prelude::*;

use super::pyramid::{collapse, decompose};
use crate::error::{Error, Result};
use crate::mesh::Csr;
use crate::stats::pdf_transfer::gaussian;
use crate::stats::{KMeans, blend_quantiles, kmeans, match_to_quantiles, quantile_function};

/// Points of the quantile functions.
pub const QUANTILES: usize = 256;
/// Feather weights below this are dropped.
const W_MIN: f32 = 1e-3;

/// Sparse feathered membership: per cluster, `(point, weight)` with weights summing to 1 per point.
pub struct Feather {
    /// Per cluster, its support.
    pub support: Vec<Vec<(u32, f32)>>,
}

/// Feathered weights of the `n` points of `x` (`n × dim`) for the clustering `km`.
pub fn feather(x: &[f32], dim: usize, km: &KMeans) -> Feather {
    let k = km.k();
    let n = x.len() / dim;
    // σ_k² = mean squared member distance
    let mut s2 = vec![0.0f64; k];
    let mut cnt = vec![0usize; k];
    for i in 0..n {
        let c = km.labels[i] as usize;
        let d: f32 = x[i * dim..(i + 1) * dim]
            .iter()
            .zip(km.center(c))
            .map(|(a, b)| (a - b) * (a - b))
            .sum();
        s2[c] += d as f64;
        cnt[c] += 1;
    }
    let pooled = s2.iter().sum::<f64>() / n.max(1) as f64;
    let sig2: Vec<f32> = (0..k)
        .map(|c| {
            let v = if cnt[c] > 1 {
                s2[c] / cnt[c] as f64
            } else {
                pooled
            };
            v.max(pooled * 1e-4).max(1e-12) as f32
        })
        .collect();
    let rows: Vec<Vec<(u32, f32)>> = (0..n)
        .into_par_iter()
        .map(|i| {
            let xi = &x[i * dim..(i + 1) * dim];
            let mut e: Vec<f32> = (0..k)
                .map(|c| {
                    let d: f32 = xi
                        .iter()
                        .zip(km.center(c))
                        .map(|(a, b)| (a - b) * (a - b))
                        .sum();
                    -d / (2.0 * sig2[c])
                })
                .collect();
            let m = e.iter().copied().fold(f32::NEG_INFINITY, f32::max);
            let mut total = 0.0f32;
            for v in e.iter_mut() {
                *v = (*v - m).exp();
                total += *v;
            }
            let mut row: Vec<(u32, f32)> = e
                .iter()
                .enumerate()
                .filter(|(_, w)| **w / total >= W_MIN)
                .map(|(c, &w)| (c as u32, w))
                .collect();
            let t: f32 = row.iter().map(|r| r.1).sum();
            row.iter_mut().for_each(|r| r.1 /= t);
            row
        })
        .collect();
    let mut support = vec![Vec::new(); k];
    for (i, row) in rows.iter().enumerate() {
        for &(c, w) in row {
            support[c as usize].push((i as u32, w));
        }
    }
    Feather { support }
}

/// Weighted least squares `y ≈ A x + b` over a support (`A`: 3 × dim, stored with `b` as
/// `3 × (dim + 1)` row-major, last column `b`); ridge-regularised.
fn fit_affine(x: &[f32], dim: usize, y: &[Vec<f32>], sup: &[(u32, f32)]) -> Vec<f64> {
    let m = dim + 1;
    let mut ata = vec![0.0f64; m * m];
    let mut aty = vec![0.0f64; m * 3];
    let mut z = vec![0.0f64; m];
    for &(i, w) in sup {
        let i = i as usize;
        for j in 0..dim {
            z[j] = x[i * dim + j] as f64;
        }
        z[dim] = 1.0;
        let w = w as f64;
        for a in 0..m {
            for b in 0..m {
                ata[a * m + b] += w * z[a] * z[b];
            }
            for c in 0..3 {
                aty[a * 3 + c] += w * z[a] * y[c][i] as f64;
            }
        }
    }
    let tr: f64 = (0..dim).map(|j| ata[j * m + j]).sum::<f64>();
    for j in 0..dim {
        ata[j * m + j] += 1e-7 * tr / dim.max(1) as f64 + 1e-12;
    }
    // One LU factorisation (partial pivoting) for the three colour channels; singular when a
    // pivot vanishes.
    let lu = MatRef::from_row_major_slice(&ata, m, m).partial_piv_lu();
    let singular = (0..m).any(|i| lu.U()[(i, i)].abs() < 1e-300);
    let mut sol = MatRef::from_row_major_slice(&aty, m, 3).to_owned();
    if !singular {
        lu.solve_in_place(sol.as_mut());
    }
    let mut out = vec![0.0f64; 3 * m];
    for c in 0..3 {
        if singular {
            // fall back to the weighted mean
            let wt: f64 = sup.iter().map(|s| s.1 as f64).sum::<f64>().max(1e-300);
            out[c * m + dim] = sup
                .iter()
                .map(|&(i, w)| w as f64 * y[c][i as usize] as f64)
                .sum::<f64>()
                / wt;
        } else {
            for a in 0..m {
                out[c * m + a] = sol[(a, c)];
            }
        }
    }
    out
}

#[inline]
fn apply_affine(a: &[f64], dim: usize, x: &[f32], c: usize) -> f32 {
    let m = dim + 1;
    let row = &a[c * m..(c + 1) * m];
    (row[dim] + (0..dim).map(|j| row[j] * x[j] as f64).sum::<f64>()) as f32
}

/// The source side of the synthesis: guidance and decorrelated colour of the training points.
pub struct SourceData<'a> {
    /// Guidance, `n × dim`.
    pub guidance: &'a [f32],
    /// The three decorrelated colour channels.
    pub colour: &'a [Vec<f32>; 3],
    /// Per channel, its Laplacian pyramid levels (`levels` entries, last = coarse) on the points.
    pub levels: &'a [Vec<Vec<f32>>; 3],
}

/// Knobs of [`synthesize`].
pub struct SynthKnobs {
    /// Clusters per side.
    pub clusters: usize,
    /// Source clusters interpolated per target cluster.
    pub neighbours: usize,
    /// Heeger-Bergen iterations.
    pub iterations: usize,
    /// Pyramid levels (1 = colour histograms only).
    pub levels: usize,
    /// Multiplier on the pooled residual standard deviation for the initial noise.
    pub noise: f32,
    /// Seed.
    pub seed: u64,
}

/// Callback for partial results: `(iteration, channels)`; an error stops the synthesis.
pub type PartialFn<'a> = dyn FnMut(usize, &[Vec<f32>; 3]) -> Result<()> + 'a;

/// Constrained Heeger-Bergen synthesis of three decorrelated colour channels on the target
/// (`tgt_guidance`: `n × dim`, `adj`: the target's vertex adjacency). `partial(stage, channels)`
/// is called after the initialisation and after every iteration; an error from it stops.
pub fn synthesize(
    src: &SourceData,
    tgt_guidance: &[f32],
    adj: &Csr,
    dim: usize,
    knobs: &SynthKnobs,
    partial: &mut PartialFn,
) -> Result<[Vec<f32>; 3]> {
    let ns = src.guidance.len() / dim;
    let nt = tgt_guidance.len() / dim;
    if ns == 0 || nt == 0 {
        return Err(Error::InvalidInput("nothing to synthesize".into()));
    }
    let levels = knobs.levels.max(1);
    // ---- 1. clusters
    let ks = kmeans(
        src.guidance,
        dim,
        knobs.clusters.max(1),
        25,
        knobs.seed ^ 0x51,
    );
    let kt = kmeans(
        tgt_guidance,
        dim,
        knobs.clusters.max(1),
        25,
        knobs.seed ^ 0x7a,
    );
    // ---- 2. feathering
    let fs = feather(src.guidance, dim, &ks);
    let ft = feather(tgt_guidance, dim, &kt);
    // ---- 3. source model, 4. target model
    let src_models = source_models(src, dim, &fs, levels);
    let sigma = residual_sigma(src, dim, &fs, &src_models);
    let tgt_models = target_models(&ks, &kt, knobs.neighbours, &src_models, dim, levels);
    // ---- 5. initialisation
    let mut y = initialise(tgt_guidance, dim, &ft, &tgt_models, sigma, knobs);
    partial(0, &y)?;
    // ---- 6. Heeger-Bergen iterations
    for it in 0..knobs.iterations {
        heeger_bergen_iteration(&mut y, adj, levels, &ft, &tgt_models);
        partial(it + 1, &y)?;
    }
    Ok(y)
}

/// A cluster's colour model: per channel, the quantiles of its values then of each of its
/// Laplacian bands (`3 × levels` lists), and the affine map from guidance to colour.
struct ClusterModel {
    quantiles: Vec<Vec<f32>>,
    affine: Vec<f64>,
}

/// The source model: per source cluster, per channel, the value and band quantiles under the
/// cluster's feathered weights, and its affine map.
fn source_models(src: &SourceData, dim: usize, fs: &Feather, levels: usize) -> Vec<ClusterModel> {
    let nq = levels; // value + (levels - 1) bands per channel
    fs.support
        .par_iter()
        .map(|sup| {
            let idx: Vec<u32> = sup.iter().map(|s| s.0).collect();
            let w: Vec<f32> = sup.iter().map(|s| s.1).collect();
            let gather = |v: &[f32]| -> Vec<f32> { idx.iter().map(|&i| v[i as usize]).collect() };
            let mut qs = Vec::with_capacity(3 * nq);
            for c in 0..3 {
                qs.push(quantile_function(
                    &gather(&src.colour[c]),
                    Some(&w),
                    QUANTILES,
                ));
                for b in 0..levels - 1 {
                    qs.push(quantile_function(
                        &gather(&src.levels[c][b]),
                        Some(&w),
                        QUANTILES,
                    ));
                }
            }
            let aff = fit_affine(src.guidance, dim, src.colour, sup);
            ClusterModel {
                quantiles: qs,
                affine: aff,
            }
        })
        .collect()
}

/// The pooled standard deviation per channel of the source colour about its clusters' affine
/// maps (feathered weights).
fn residual_sigma(src: &SourceData, dim: usize, fs: &Feather, models: &[ClusterModel]) -> [f32; 3] {
    let mut res = [0.0f64; 3];
    let mut wsum = 0.0f64;
    for (k, sup) in fs.support.iter().enumerate() {
        let aff = &models[k].affine;
        for &(i, w) in sup {
            let x = &src.guidance[i as usize * dim..(i as usize + 1) * dim];
            for (c, r) in res.iter_mut().enumerate() {
                let e = src.colour[c][i as usize] - apply_affine(aff, dim, x, c);
                *r += w as f64 * (e as f64).powi(2);
            }
            wsum += w as f64;
        }
    }
    res.map(|r| (r / wsum.max(1e-300)).sqrt() as f32)
}

/// The target model: per target cluster, Shepard interpolation (inverse squared distance) of
/// the `neighbours` nearest source clusters' quantiles and affine maps.
fn target_models(
    ks: &KMeans,
    kt: &KMeans,
    neighbours: usize,
    src_models: &[ClusterModel],
    dim: usize,
    levels: usize,
) -> Vec<ClusterModel> {
    let nq = levels;
    let kk = ks.k();
    let nb = neighbours.clamp(1, kk);
    (0..kt.k())
        .into_par_iter()
        .map(|j| {
            let f = kt.center(j);
            let mut d: Vec<(f32, usize)> = (0..kk)
                .map(|k| {
                    let d2: f32 = f
                        .iter()
                        .zip(ks.center(k))
                        .map(|(a, b)| (a - b) * (a - b))
                        .sum();
                    (d2, k)
                })
                .collect();
            d.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
            let near: Vec<(f32, usize)> = if d[0].0 < 1e-12 {
                vec![(1.0, d[0].1)]
            } else {
                d[..nb].iter().map(|&(d2, k)| (1.0 / d2, k)).collect()
            };
            let wts: Vec<f32> = near.iter().map(|n| n.0).collect();
            let qs: Vec<Vec<f32>> = (0..3 * nq)
                .map(|q| {
                    let list: Vec<&[f32]> = near
                        .iter()
                        .map(|n| &src_models[n.1].quantiles[q][..])
                        .collect();
                    blend_quantiles(&list, &wts)
                })
                .collect();
            let total: f32 = wts.iter().sum();
            let mut aff = vec![0.0f64; 3 * (dim + 1)];
            for (w, k) in &near {
                for (a, s) in aff.iter_mut().zip(&src_models[*k].affine) {
                    *a += (*w / total) as f64 * s;
                }
            }
            ClusterModel {
                quantiles: qs,
                affine: aff,
            }
        })
        .collect()
}

/// The initial colour: per target point, its clusters' affine maps blended by the feathered
/// weights, plus Gaussian noise of `noise × sigma` per channel.
fn initialise(
    tgt_guidance: &[f32],
    dim: usize,
    ft: &Feather,
    tgt_models: &[ClusterModel],
    sigma: [f32; 3],
    knobs: &SynthKnobs,
) -> [Vec<f32>; 3] {
    let nt = tgt_guidance.len() / dim;
    let mut wrow: Vec<Vec<(u32, f32)>> = vec![Vec::new(); nt];
    for (j, sup) in ft.support.iter().enumerate() {
        for &(i, w) in sup {
            wrow[i as usize].push((j as u32, w));
        }
    }
    let mut y: [Vec<f32>; 3] = [vec![0.0; nt], vec![0.0; nt], vec![0.0; nt]];
    let mut rng = SmallRng::seed_from_u64(knobs.seed ^ 0x006e_6f69_7365);
    for i in 0..nt {
        let x = &tgt_guidance[i * dim..(i + 1) * dim];
        for c in 0..3 {
            let mut v = 0.0f32;
            for &(j, w) in &wrow[i] {
                v += w * apply_affine(&tgt_models[j as usize].affine, dim, x, c);
            }
            y[c][i] = v + knobs.noise * sigma[c] * gaussian(&mut rng) as f32;
        }
    }
    y
}

/// One Heeger-Bergen iteration: per channel, each Laplacian band and then the collapsed values
/// matched, cluster by cluster, to the target model's quantiles and feathered back together.
fn heeger_bergen_iteration(
    y: &mut [Vec<f32>; 3],
    adj: &Csr,
    levels: usize,
    ft: &Feather,
    tgt_models: &[ClusterModel],
) {
    let nq = levels;
    for (c, yc) in y.iter_mut().enumerate() {
        if levels > 1 {
            let mut lv = decompose(adj, yc, levels);
            for (b, band) in lv.iter_mut().take(levels - 1).enumerate() {
                *band = match_blend(ft, tgt_models, band, c * nq + 1 + b);
            }
            *yc = collapse(&lv);
        }
        *yc = match_blend(ft, tgt_models, yc, c * nq);
    }
}

/// `vals` matched, per target cluster, to its model's quantile list `q` under the feathered
/// weights, and blended back by those weights.
fn match_blend(ft: &Feather, tgt_models: &[ClusterModel], vals: &[f32], q: usize) -> Vec<f32> {
    let pieces: Vec<(usize, Vec<f32>)> = ft
        .support
        .par_iter()
        .enumerate()
        .map(|(j, sup)| {
            let mut v: Vec<f32> = sup.iter().map(|s| vals[s.0 as usize]).collect();
            let w: Vec<f32> = sup.iter().map(|s| s.1).collect();
            match_to_quantiles(&mut v, Some(&w), &tgt_models[j].quantiles[q]);
            (j, v)
        })
        .collect();
    let mut out = vec![0.0f32; vals.len()];
    for (j, v) in pieces {
        for (&(i, w), m) in ft.support[j].iter().zip(v) {
            out[i as usize] += w * m;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::Rng;

    #[test]
    fn feather_weights_sum_to_one_and_planted_affine_is_reproduced() {
        let mut rng = SmallRng::seed_from_u64(2);
        let n = 3000;
        let dim = 3;
        let x: Vec<f32> = (0..n * dim).map(|_| rng.random::<f32>() * 4.0).collect();
        let km = kmeans(&x, dim, 12, 25, 1);
        let f = feather(&x, dim, &km);
        let mut sum = vec![0.0f32; n];
        for sup in &f.support {
            for &(i, w) in sup {
                assert!(w >= 0.0);
                sum[i as usize] += w;
            }
        }
        assert!(sum.iter().all(|s| (s - 1.0).abs() < 1e-5));
        // colour = M x + b exactly: the initialisation (no noise, no iterations) reproduces it
        let m = [[0.3f32, -0.2, 0.1], [0.05, 0.4, -0.3], [-0.1, 0.0, 0.25]];
        let b = [0.5f32, -0.1, 0.2];
        let colour: [Vec<f32>; 3] = [0, 1, 2].map(|c| {
            (0..n)
                .map(|i| b[c] + (0..3).map(|j| m[c][j] * x[i * dim + j]).sum::<f32>())
                .collect()
        });
        let levels: [Vec<Vec<f32>>; 3] = [0, 1, 2].map(|c| vec![colour[c].clone()]);
        let adj = crate::mesh::Csr::default();
        let knobs = SynthKnobs {
            clusters: 12,
            neighbours: 4,
            iterations: 0,
            levels: 1,
            noise: 0.0,
            seed: 3,
        };
        let y = synthesize(
            &SourceData {
                guidance: &x,
                colour: &colour,
                levels: &levels,
            },
            &x,
            &adj,
            dim,
            &knobs,
            &mut |_, _| Ok(()),
        )
        .unwrap();
        for c in 0..3 {
            let err = y[c]
                .iter()
                .zip(&colour[c])
                .map(|(a, b)| (a - b).abs())
                .fold(0.0f32, f32::max);
            assert!(err < 1e-3, "channel {c}: {err}");
        }
    }
}
