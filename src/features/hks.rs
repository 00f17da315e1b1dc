//! Shape features: the Heat Kernel Signature (Sun, Ovsjanikov & Guibas 2009) on a coarse
//! level, carried up the hierarchy and smoothed, with normal·up (MeshMatch §3.2).

use super::{HKS_EIGENPAIRS, HKS_TIMES, SHAPE_DIM};
use crate::error::{Error, Result};
use crate::hierarchy::{Hierarchy, Level};
use crate::work::CancelToken;
use glam::Vec3;
use rayon::prelude::*;

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
