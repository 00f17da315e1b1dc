//! Shape features per level for a solve: the prepared meshes' automatic features (HKS +
//! normal.up) and the correspondence affinities (MeshMatch §3.2), each group normalised.

use rayon::prelude::*;

use super::PreparedMesh;
use crate::features::{SHAPE_DIM, edge_geodesics, min_norm_affine};
use crate::hierarchy::Hierarchy;

/// Per-dimension standard deviations of `dim`-vectors pooled over two arrays.
pub(super) fn pooled_std(a: &[f32], b: &[f32], dim: usize) -> Vec<f32> {
    let n = (a.len() + b.len()) / dim.max(1);
    let mut mean = vec![0.0f64; dim];
    for x in a.chunks(dim).chain(b.chunks(dim)) {
        for k in 0..dim {
            mean[k] += x[k] as f64;
        }
    }
    for m in mean.iter_mut() {
        *m /= n.max(1) as f64;
    }
    let mut var = vec![0.0f64; dim];
    for x in a.chunks(dim).chain(b.chunks(dim)) {
        for k in 0..dim {
            var[k] += (x[k] as f64 - mean[k]).powi(2);
        }
    }
    var.iter()
        .map(|v| ((v / n.max(1) as f64).sqrt() as f32).max(1e-6))
        .collect()
}

/// Build the weighted shape vectors of one level for both meshes: the automatic group (HKS +
/// normal·up) and, with correspondences, the affinity group; each group divided by its
/// per-dimension standard deviation (pooled over both meshes) and sqrt(its dimension), times
/// sqrt(shape_weight), so squared L2 distances weigh each group like the colour fans.
pub(super) fn weighted_shape(
    s_auto: &[f32],
    t_auto: &[f32],
    s_aff: &[f32],
    t_aff: &[f32],
    k: usize,
    shape_weight: f32,
) -> (Vec<f32>, Vec<f32>, usize) {
    let dsh = SHAPE_DIM + k;
    let sd_a = pooled_std(s_auto, t_auto, SHAPE_DIM);
    let sd_b = if k > 0 {
        pooled_std(s_aff, t_aff, k)
    } else {
        Vec::new()
    };
    let w = shape_weight.max(0.0).sqrt();
    let build = |auto: &[f32], aff: &[f32]| -> Vec<f32> {
        let n = auto.len() / SHAPE_DIM;
        let mut out = Vec::with_capacity(n * dsh);
        for v in 0..n {
            for d in 0..SHAPE_DIM {
                out.push(w * auto[v * SHAPE_DIM + d] / (sd_a[d] * (SHAPE_DIM as f32).sqrt()));
            }
            for d in 0..k {
                out.push(w * aff[v * k + d] / (sd_b[d] * (k as f32).sqrt()));
            }
        }
        out
    };
    (build(s_auto, s_aff), build(t_auto, t_aff), dsh)
}

/// Carry per-vertex `dim`-vectors from level 0 up the hierarchy (mean of children).
pub(super) fn to_levels(h: &Hierarchy, base: Vec<f32>, dim: usize) -> Vec<Vec<f32>> {
    let mut out = vec![base];
    for l in 1..h.num_levels() {
        let prev = &out[l - 1];
        let n = h.levels[l].len();
        let mut cur = vec![0.0f32; n * dim];
        for p in 0..n {
            let ch = h.children(l, p as u32);
            for &c in ch {
                for d in 0..dim {
                    cur[p * dim + d] += prev[c as usize * dim + d];
                }
            }
            for d in 0..dim {
                cur[p * dim + d] /= ch.len().max(1) as f32;
            }
        }
        out.push(cur);
    }
    out
}

/// Largest level on which correspondence geodesics are computed.
const GEODESIC_LEVEL_VERTICES: usize = 8_000;

/// Geodesic distance from every finest-level vertex to each of `sets` (finest-level vertex
/// sets): the heat method (Crane et al. 2013, `geometry::HeatGeodesics`) on the first hierarchy
/// level with at most [`GEODESIC_LEVEL_VERTICES`] vertices, carried to the finest level through
/// the vertex tree (affinities are smooth at the scale of σ = max distance / 3). Falls back to
/// edge-graph Dijkstra on the finest level if the heat method cannot factor the level.
pub(super) fn geodesics(h: &Hierarchy, sets: &[Vec<u32>]) -> Vec<Vec<f32>> {
    let l = (0..h.num_levels())
        .find(|&l| h.levels[l].len() <= GEODESIC_LEVEL_VERTICES)
        .unwrap_or(h.num_levels() - 1);
    let lev = &h.levels[l];
    match crate::geometry::HeatGeodesics::new(&lev.positions, &lev.faces) {
        Ok(heat) => {
            let map = h.ancestor_map(0, l);
            let coarse: Vec<Vec<u32>> = sets
                .iter()
                .map(|s| s.iter().map(|&v| map[v as usize]).collect())
                .collect();
            heat.distances(&coarse)
                .into_iter()
                .map(|d| map.iter().map(|&a| d[a as usize] as f32).collect())
                .collect()
        }
        Err(_) => sets
            .par_iter()
            .map(|s| edge_geodesics(&h.levels[0], s))
            .collect(),
    }
}

/// Correspondence affinities (MeshMatch §3.2): geodesic distances ([`geodesics`]) to each constrained point (a
/// one-to-many target point set is one multi-source), target distances mapped by the affine map of
/// [`min_norm_affine`], then G'(v) = exp(-G(v)² / (2σ²)) with σ = (max source geodesic distance)
/// / 3. We square the distance: the paper's printed exp(-G/(2σ²)) mixes units (length over length²)
/// and is not a Gaussian; with the square, the affinity is a Gaussian RBF of width σ in the
/// (mapped) distance, scale-free and equal to 1 at the constraint.
pub(super) fn affinities(
    source: &PreparedMesh,
    target: &PreparedMesh,
    pairs: &[(u32, Vec<u32>)],
) -> (Vec<f32>, Vec<f32>) {
    let k = pairs.len();
    let (ls, lt) = (&source.hierarchy.levels[0], &target.hierarchy.levels[0]);
    let src_sets: Vec<Vec<u32>> = pairs.iter().map(|(s, _)| vec![*s]).collect();
    let tgt_sets: Vec<Vec<u32>> = pairs.iter().map(|(_, t)| t.clone()).collect();
    let gs = geodesics(&source.hierarchy, &src_sets);
    let gt = geodesics(&target.hierarchy, &tgt_sets);
    let row = |g: &[Vec<f32>], v: u32| -> Vec<f32> { g.iter().map(|d| d[v as usize]).collect() };
    let mut trows = Vec::new();
    let mut srows = Vec::new();
    for (s, ts) in pairs {
        for &t in ts {
            trows.push(row(&gt, t));
            srows.push(row(&gs, *s));
        }
    }
    let m = min_norm_affine(&trows, &srows, k);
    let maxd = gs
        .iter()
        .flat_map(|d| d.iter().copied())
        .filter(|d| d.is_finite())
        .fold(0.0f32, f32::max);
    let sigma = (maxd / 3.0).max(1e-12);
    let inv = 1.0 / (2.0 * sigma * sigma);
    let ns = ls.len();
    let nt = lt.len();
    let mut aff_s = vec![0.0f32; ns * k];
    for v in 0..ns {
        for r in 0..k {
            let d = gs[r][v];
            aff_s[v * k + r] = (-d * d * inv).exp();
        }
    }
    let mut aff_t = vec![0.0f32; nt * k];
    aff_t.par_chunks_mut(k).enumerate().for_each(|(v, out)| {
        for r in 0..k {
            let mut d = m[r * (k + 1) + k];
            for c in 0..k {
                d += m[r * (k + 1) + c] * gt[c][v] as f64;
            }
            let d = d as f32;
            out[r] = (-d * d * inv).exp();
        }
    });
    (aff_s, aff_t)
}
