//! Quality measures for synthesized textures: colour histograms and neighbourhood match
//! distances against the exemplar (with the exemplar's own leave-one-out baseline).

use glam::Vec3;
use rand::seq::index::sample;
use rayon::prelude::*;

use super::neigh::{ExemplarLevel, Frame, Scratch, Stencils, build_stencil};
use super::pyramid::{Img, Level, stage_rng};
use crate::error::{Error, Result};
use crate::geometry::vertex_normals;
use crate::mesh::TriMesh;

/// The pixels of an image as sRGB colours in [0,1].
pub fn image_colors(img: &image::RgbImage) -> Vec<[f32; 3]> {
    img.pixels()
        .map(|p| p.0.map(|c| c as f32 / 255.0))
        .collect()
}

/// Normalised 3D colour histogram with `bins` bins per sRGB channel (sums to 1).
pub fn color_histogram(colors: &[[f32; 3]], bins: usize) -> Vec<f64> {
    let bins = bins.max(1);
    let mut h = vec![0.0f64; bins * bins * bins];
    let b = |x: f32| ((x.clamp(0.0, 1.0) * bins as f32) as usize).min(bins - 1);
    for c in colors {
        h[(b(c[0]) * bins + b(c[1])) * bins + b(c[2])] += 1.0;
    }
    let n = colors.len().max(1) as f64;
    h.iter_mut().for_each(|x| *x /= n);
    h
}

/// L1 distance between two normalised histograms (0 = identical, 2 = disjoint).
pub fn histogram_l1(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y).abs()).sum()
}

/// Mean over sampled output vertices of the best-match distance (mean squared sRGB difference per
/// element) between the vertex's `size x size` mesh neighbourhood, flattened in its texture frame
/// `dirs` at `spacing` mesh units per texel, and every exemplar neighbourhood of the same size
/// (exhaustive). Vertices whose neighbourhood is not fully covered (mesh boundaries) are skipped.
pub fn neighbourhood_distance(
    exemplar: &image::RgbImage,
    mesh: &TriMesh,
    dirs: &[[f32; 3]],
    spacing: f32,
    size: usize,
    samples: usize,
    seed: u64,
) -> Result<f64> {
    let colors = mesh
        .colors
        .as_ref()
        .ok_or_else(|| Error::InvalidInput("mesh has no colours to measure".into()))?;
    if dirs.len() != mesh.num_vertices() || colors.len() != mesh.num_vertices() {
        return Err(Error::InvalidInput(
            "one direction and colour per vertex expected".into(),
        ));
    }
    let normals = vertex_normals(&mesh.positions, &mesh.faces);
    let lev = Level::new(
        mesh.positions.clone(),
        mesh.faces.clone(),
        normals,
        vec![None; mesh.num_vertices()],
    );
    let ex = ExemplarLevel::new(&Img::from_rgb(exemplar), None, size, 0);
    let mut rng = stage_rng(seed, 77);
    let n = mesh.num_vertices();
    let picks: Vec<usize> = sample(&mut rng, n, samples.min(n)).into_vec();
    let per = size * size;
    let dim = 3 * per;
    let results: Vec<Option<f32>> = picks
        .par_iter()
        .with_min_len(64)
        .map_init(
            || {
                (
                    Scratch::new(&lev),
                    vec![super::neigh::UNCOVERED; per],
                    vec![0.0f32; dim],
                )
            },
            |(sc, taps, q), &v| {
                let nrm = Vec3::from(lev.normals[v]);
                let s = Vec3::from(dirs[v]);
                let f = Frame {
                    c: Vec3::from(lev.positions[v]),
                    s,
                    t: nrm.cross(s),
                    n: nrm,
                    h: spacing,
                };
                build_stencil(&lev, v as u32, &f, size, sc, taps);
                if taps.iter().any(|t| t.idx[0] == u32::MAX) {
                    return None;
                }
                let st = Stencils {
                    per,
                    taps: taps.clone(),
                };
                st.gather(0, colors, ex.mean, q);
                let mut best = f32::INFINITY;
                for c in 0..ex.num_candidates() as u32 {
                    best = best.min(super::search::dist(&ex, c, Some(q), None, best));
                }
                Some(best / dim as f32)
            },
        )
        .collect();
    let ok: Vec<f32> = results.into_iter().flatten().collect();
    if ok.is_empty() {
        return Err(Error::InvalidInput(
            "no fully covered neighbourhood to measure".into(),
        ));
    }
    Ok(ok.iter().map(|&x| x as f64).sum::<f64>() / ok.len() as f64)
}

/// The exemplar's leave-one-out baseline: mean over sampled pixels of the best-match distance
/// (mean squared difference per element) between the pixel's `size x size` neighbourhood and every
/// other neighbourhood whose centre is more than `exclude` pixels away (Chebyshev distance).
pub fn exemplar_loo_distance(
    exemplar: &image::RgbImage,
    size: usize,
    exclude: usize,
    samples: usize,
    seed: u64,
) -> f64 {
    let ex = ExemplarLevel::new(&Img::from_rgb(exemplar), None, size, 0);
    let n = ex.num_candidates();
    let mut rng = stage_rng(seed, 78);
    let picks: Vec<usize> = sample(&mut rng, n, samples.min(n)).into_vec();
    let dim = ex.dim_cur();
    let ex_ref = &ex;
    let total: f64 = picks
        .par_iter()
        .map(|&p| {
            let (px, py) = ex_ref.pixel(p as u32);
            let q = &ex_ref.cur[p * dim..(p + 1) * dim];
            let mut best = f32::INFINITY;
            for c in 0..n as u32 {
                let (x, y) = ex_ref.pixel(c);
                if x.abs_diff(px).max(y.abs_diff(py)) <= exclude {
                    continue;
                }
                best = best.min(super::search::dist(ex_ref, c, Some(q), None, best));
            }
            (best / dim as f32) as f64
        })
        .sum();
    total / picks.len().max(1) as f64
}
