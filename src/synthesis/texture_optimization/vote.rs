//! Kwatra et al.'s M-step: the colours minimising `E_t` given the patches, per vertex the
//! weighted mean of the covering patches' predictions (read bilinearly at the vertex's own patch
//! coordinates), then the prediction nearest that mean.

use rayon::prelude::*;

use super::exemplar::Exemplar;
use super::samples::Regions;
use super::search::Index;

/// The vote: every vertex covered by a sample's patch (`z`, at distance `dist`, weighted by
/// `lambda` and Kwatra's robust exponent `robust`) takes the covering prediction nearest their
/// weighted mean into `colors`, and the exemplar pixel of its strongest prediction into
/// `source`.
#[allow(clippy::too_many_arguments)]
pub(super) fn vote(
    reg: &Regions,
    ex: &Exemplar,
    index: &Index,
    z: &[u32],
    dist: &[f32],
    lambda: &[f32],
    robust: f32,
    colors: &mut [[f32; 3]],
    source: &mut [[u32; 2]],
) {
    let weight: Vec<f32> = (0..z.len())
        .map(|s| {
            if z[s] == u32::MAX {
                0.0
            } else {
                lambda[s] * dist[s].max(1e-3).powf(robust - 2.0)
            }
        })
        .collect();
    let centre_xy: Vec<[f32; 2]> = z
        .iter()
        .map(|&c| {
            if c == u32::MAX {
                [0.0; 2]
            } else {
                let pix = index.centres[c as usize] as usize;
                [(pix % ex.w) as f32, (pix / ex.w) as f32]
            }
        })
        .collect();
    colors
        .par_iter_mut()
        .zip(source.par_iter_mut())
        .enumerate()
        .for_each(|(v, (col, src))| {
            let mut acc = [0.0f64; 3];
            let mut wsum = 0.0f64;
            let mut strongest = (0.0f32, [u32::MAX; 2]);
            for &e in &reg.cover[reg.cover_start[v]..reg.cover_start[v + 1]] {
                let s = reg.owner[e as usize] as usize;
                let wt = weight[s];
                if wt <= 0.0 {
                    continue;
                }
                let o = reg.offset[e as usize];
                let (x, y) = (centre_xy[s][0] + o[0], centre_xy[s][1] + o[1]);
                let c = ex.bilinear(x, y);
                for k in 0..3 {
                    acc[k] += wt as f64 * c[k] as f64;
                }
                wsum += wt as f64;
                if wt > strongest.0 {
                    let px = x.round().clamp(0.0, (ex.w - 1) as f32) as u32;
                    let py = y.round().clamp(0.0, (ex.h - 1) as f32) as u32;
                    strongest = (wt, [px, py]);
                }
            }
            if wsum > 0.0 {
                let mean = acc.map(|a| (a / wsum) as f32);
                // The prediction nearest the weighted mean (the vote's mode, as
                // Wexler et al. 2007): an exemplar colour, not a blend of misregistered
                // patches.
                let mut pick = (f32::INFINITY, mean);
                for &e in &reg.cover[reg.cover_start[v]..reg.cover_start[v + 1]] {
                    let s = reg.owner[e as usize] as usize;
                    if weight[s] <= 0.0 {
                        continue;
                    }
                    let o = reg.offset[e as usize];
                    let c = ex.nearest(centre_xy[s][0] + o[0], centre_xy[s][1] + o[1]);
                    let d = (0..3).map(|k| (c[k] - mean[k]).powi(2)).sum::<f32>();
                    if d < pick.0 {
                        pick = (d, c);
                    }
                }
                *col = pick.1;
                *src = strongest.1;
            }
        });
}
