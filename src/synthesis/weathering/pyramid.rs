//! A Laplacian pyramid of a scalar field on a mesh (Adelson & Burt 1981), without subsampling:
//! `G_0 = f`, `G_{l+1}` = `G_l` smoothed by `2·4^l` Jacobi sweeps of the umbrella operator
//! (`x ← ½ x + ½ mean(neighbours)`, so the smoothing scale doubles per level);
//! bands `L_l = G_l - G_{l+1}` for `l < levels - 1`, the coarsest `G_{levels-1}` kept as is.
//! `collapse(decompose(f)) = f` up to rounding.

use rayon::prelude::*;

use crate::mesh::Csr;

/// One Jacobi sweep of `x ← ½ x + ½ mean(neighbours)` from `src` into `dst`.
pub fn smooth_step(adj: &Csr, src: &[f32], dst: &mut [f32]) {
    dst.par_iter_mut().enumerate().for_each(|(i, d)| {
        let row = adj.row(i);
        if row.is_empty() {
            *d = src[i];
        } else {
            let m: f32 = row.iter().map(|&j| src[j as usize]).sum::<f32>() / row.len() as f32;
            *d = 0.5 * (src[i] + m);
        }
    });
}

/// `sweeps` Jacobi smoothing sweeps of `f` (buffer `tmp` reused).
pub fn smooth(adj: &Csr, f: &mut Vec<f32>, tmp: &mut Vec<f32>, sweeps: usize) {
    tmp.resize(f.len(), 0.0);
    for _ in 0..sweeps {
        smooth_step(adj, f, tmp);
        std::mem::swap(f, tmp);
    }
}

/// Decompose `f` into `levels` pyramid levels: `levels - 1` bands, finest first, then the
/// coarsest Gaussian level.
pub fn decompose(adj: &Csr, f: &[f32], levels: usize) -> Vec<Vec<f32>> {
    let levels = levels.max(1);
    let mut out = Vec::with_capacity(levels);
    let mut g = f.to_vec();
    let mut tmp = Vec::new();
    for l in 0..levels - 1 {
        let mut next = g.clone();
        smooth(adj, &mut next, &mut tmp, 2 << (2 * l));
        let band: Vec<f32> = g.iter().zip(&next).map(|(a, b)| a - b).collect();
        out.push(band);
        g = next;
    }
    out.push(g);
    out
}

/// Sum of all levels (inverse of [`decompose`]).
pub fn collapse(levels: &[Vec<f32>]) -> Vec<f32> {
    let mut out = levels.last().cloned().unwrap_or_default();
    for band in &levels[..levels.len().saturating_sub(1)] {
        for (o, b) in out.iter_mut().zip(band) {
            *o += b;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn collapse_inverts_decompose() {
        let m = 20u32;
        let mut faces = Vec::new();
        for y in 0..m {
            for x in 0..m {
                let i = y * (m + 1) + x;
                faces.push([i, i + 1, i + m + 2]);
                faces.push([i, i + m + 2, i + m + 1]);
            }
        }
        let n = ((m + 1) * (m + 1)) as usize;
        let adj = crate::mesh::vertex_adjacency(n, &faces);
        let f: Vec<f32> = (0..n).map(|i| ((i * 37) % 11) as f32 * 0.1).collect();
        let lv = decompose(&adj, &f, 3);
        assert_eq!(lv.len(), 3);
        let g = collapse(&lv);
        assert!(f.iter().zip(&g).all(|(a, b)| (a - b).abs() < 1e-5));
        // the coarse level is smoother than the input
        let tv = |x: &[f32]| -> f32 {
            (0..n)
                .map(|i| {
                    adj.row(i)
                        .iter()
                        .map(|&j| (x[i] - x[j as usize]).abs())
                        .sum::<f32>()
                })
                .sum()
        };
        assert!(tv(&lv[2]) < 0.3 * tv(&f));
    }
}
