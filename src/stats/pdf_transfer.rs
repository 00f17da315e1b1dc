//! N-dimensional PDF transfer by iterated 1-D marginal matching along random rotations
//! (Pitié, Kokaram & Dahyot 2005, "N-dimensional probability density function transfer and its
//! application to colour transfer", ICCV): repeat { draw a random orthonormal basis R; project
//! both sets on R's axes; remap each target projection by 1-D histogram matching
//! `T = F_src^-1 ∘ F_tgt`; add the change back along the axis }. Each step is monotone per axis.

use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};
use rayon::prelude::*;

use super::histogram::{ks_distance_sorted, quantile_sorted};

/// Parameters of [`pdf_transfer`].
#[derive(Clone, Copy, Debug, serde::Serialize, serde::Deserialize)]
pub struct PdfTransferParams {
    /// Maximum number of random rotations (20 after the MERTENS guide).
    pub iterations: usize,
    /// Stop early when every axis of a fresh rotation has a KS distance below this.
    pub tolerance: f32,
    /// Seed of the rotations.
    pub seed: u64,
}

impl Default for PdfTransferParams {
    fn default() -> Self {
        PdfTransferParams {
            iterations: 20,
            tolerance: 0.01,
            seed: 0,
        }
    }
}

/// A standard normal deviate (Box-Muller).
pub(crate) fn gaussian<R: Rng>(rng: &mut R) -> f64 {
    let u1: f64 = rng.random::<f64>().max(1e-300);
    let u2: f64 = rng.random();
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

/// A uniformly random `d × d` orthonormal basis (Gram-Schmidt on a Gaussian matrix), rows are
/// the axes, flat row-major.
pub fn random_rotation<R: Rng>(d: usize, rng: &mut R) -> Vec<f64> {
    loop {
        let mut m: Vec<f64> = (0..d * d).map(|_| gaussian(rng)).collect();
        let mut ok = true;
        for i in 0..d {
            for j in 0..i {
                let dot: f64 = (0..d).map(|k| m[i * d + k] * m[j * d + k]).sum();
                for k in 0..d {
                    m[i * d + k] -= dot * m[j * d + k];
                }
            }
            let n: f64 = (0..d).map(|k| m[i * d + k].powi(2)).sum::<f64>().sqrt();
            if n < 1e-9 {
                ok = false;
                break;
            }
            for k in 0..d {
                m[i * d + k] /= n;
            }
        }
        if ok {
            return m;
        }
    }
}

fn project(data: &[f32], d: usize, axis: &[f64]) -> Vec<f32> {
    data.par_chunks(d)
        .map(|x| x.iter().zip(axis).map(|(&a, &b)| a as f64 * b).sum::<f64>() as f32)
        .collect()
}

/// Move the distribution of `target` (n_t points, `d` values each, flat row-major) onto that of
/// `source` (n_s points), in place. Returns the number of rotations applied. Deterministic under
/// `params.seed`. `d == 0` or an empty set does nothing.
pub fn pdf_transfer(
    target: &mut [f32],
    source: &[f32],
    d: usize,
    params: &PdfTransferParams,
) -> usize {
    if d == 0 || target.len() < d || source.len() < d {
        return 0;
    }
    let mut rng = SmallRng::seed_from_u64(params.seed ^ 0x9e37_79b9_7f4a_7c15);
    for it in 0..params.iterations {
        let r = random_rotation(d, &mut rng);
        let mut worst = 0.0f32;
        for a in 0..d {
            let axis = &r[a * d..(a + 1) * d];
            let mut ps: Vec<f32> = project(source, d, axis)
                .into_iter()
                .filter(|x| x.is_finite())
                .collect();
            ps.par_sort_unstable_by(f32::total_cmp);
            // target projections with their indices, sorted: the rank of each
            let mut pt: Vec<(f32, u32)> = project(target, d, axis)
                .into_iter()
                .enumerate()
                .map(|(i, x)| (x, i as u32))
                .collect();
            pt.par_sort_unstable_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)));
            let finite: Vec<f32> = pt.iter().map(|x| x.0).filter(|x| x.is_finite()).collect();
            worst = worst.max(ks_distance_sorted(&finite, &ps));
            let n = pt.len() as f32;
            let moved: Vec<f32> = pt
                .par_iter()
                .enumerate()
                .map(|(rank, &(x, _))| quantile_sorted(&ps, (rank as f32 + 0.5) / n) - x)
                .collect();
            let mut delta = vec![0.0f32; pt.len()];
            for (&(_, i), &m) in pt.iter().zip(&moved) {
                delta[i as usize] = m;
            }
            target
                .par_chunks_mut(d)
                .zip(delta.par_iter())
                .for_each(|(x, &dl)| {
                    for k in 0..d {
                        x[k] += (dl as f64 * axis[k]) as f32;
                    }
                });
        }
        if worst < params.tolerance {
            return it + 1;
        }
    }
    params.iterations
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::stats::histogram::ks_distance;

    #[test]
    fn transfer_matches_random_marginals() {
        let mut rng = SmallRng::seed_from_u64(5);
        let d = 3;
        // source: an anisotropic, skewed cloud; target: a shifted isotropic Gaussian
        let source: Vec<f32> = (0..6000)
            .flat_map(|_| {
                let a = gaussian(&mut rng);
                let b = gaussian(&mut rng);
                let c: f64 = rng.random::<f64>();
                [(2.0 * a + b) as f32, (0.3 * b) as f32, (c * c * 4.0) as f32]
            })
            .collect();
        let mut target: Vec<f32> = (0..5000)
            .flat_map(|_| [0; 3].map(|_| (gaussian(&mut rng) + 5.0) as f32))
            .collect();
        let p = PdfTransferParams {
            iterations: 30,
            tolerance: 0.005,
            seed: 1,
        };
        pdf_transfer(&mut target, &source, d, &p);
        let mut worst = 0.0f32;
        for _ in 0..50 {
            let r = random_rotation(d, &mut rng);
            let ks = ks_distance(&project(&target, d, &r[..3]), &project(&source, d, &r[..3]));
            worst = worst.max(ks);
        }
        assert!(worst < 0.03, "worst KS {worst}");
        // identical inputs: identity
        let mut same = source.clone();
        pdf_transfer(&mut same, &source, d, &p);
        let err = same
            .iter()
            .zip(&source)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0f32, f32::max);
        assert!(err < 1e-4, "{err}");
    }
}
