//! k-means clustering (Lloyd 1982) with k-means++ seeding (Arthur & Vassilvitskii 2007):
//! deterministic under a seed, rayon-parallel assignment, flat row-major data.

use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};
use rayon::prelude::*;

/// A clustering: `k` centres of dimension `dim` (flat row-major) and a label per point.
#[derive(Clone, Debug, Default)]
pub struct KMeans {
    /// Point dimension.
    pub dim: usize,
    /// Cluster centres, `k × dim`.
    pub centers: Vec<f32>,
    /// Cluster of each point.
    pub labels: Vec<u32>,
    /// Sum of squared distances of the points to their centres.
    pub inertia: f64,
}

impl KMeans {
    /// Number of clusters.
    pub fn k(&self) -> usize {
        self.centers.len() / self.dim.max(1)
    }
    /// Centre `c`.
    pub fn center(&self, c: usize) -> &[f32] {
        &self.centers[c * self.dim..(c + 1) * self.dim]
    }
}

#[inline]
fn d2(a: &[f32], b: &[f32]) -> f32 {
    a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum()
}

/// Nearest centre of `x` and its squared distance; a later centre must [`beat`](super::beats)
/// the nearest so far by a margin, so that the same data in other units (off in their last
/// bits) are labelled the same.
#[inline]
pub fn nearest(centers: &[f32], dim: usize, x: &[f32]) -> (u32, f32) {
    let mut best = (0u32, f32::INFINITY);
    for (c, ctr) in centers.chunks_exact(dim).enumerate() {
        let d = d2(ctr, x);
        if super::beats(d, best.1) {
            best = (c as u32, d);
        }
    }
    best
}

/// Cluster `data` (n points × `dim`, flat) into at most `k` clusters (fewer when there are
/// fewer distinct points): k-means++ seeding, then up to `iterations` Lloyd steps (stops when
/// no label changes). An empty cluster is re-seeded at the point farthest from its centre.
pub fn kmeans(data: &[f32], dim: usize, k: usize, iterations: usize, seed: u64) -> KMeans {
    let n = data.len().checked_div(dim).unwrap_or(0);
    let k = k.min(n);
    if k == 0 {
        return KMeans {
            dim,
            ..Default::default()
        };
    }
    let pt = |i: usize| &data[i * dim..(i + 1) * dim];
    let mut rng = SmallRng::seed_from_u64(seed ^ 0x6b6d_6561_6e73);
    // ---- k-means++
    let mut centers: Vec<f32> = Vec::with_capacity(k * dim);
    centers.extend_from_slice(pt(rng.random_range(0..n)));
    let mut dist: Vec<f32> = (0..n)
        .into_par_iter()
        .map(|i| d2(pt(i), &centers[..dim]))
        .collect();
    while centers.len() < k * dim {
        let total: f64 = dist.iter().map(|&x| x as f64).sum();
        if total <= 0.0 {
            break; // fewer distinct points than k
        }
        let mut t = rng.random::<f64>() * total;
        let mut pick = n - 1;
        for (i, &x) in dist.iter().enumerate() {
            t -= x as f64;
            if t <= 0.0 && x > 0.0 {
                pick = i;
                break;
            }
        }
        let c0 = centers.len();
        centers.extend_from_slice(pt(pick));
        let c = &centers[c0..c0 + dim];
        dist.par_iter_mut()
            .enumerate()
            .for_each(|(i, di)| *di = di.min(d2(pt(i), c)));
    }
    let k = centers.len() / dim;
    // ---- Lloyd
    let mut labels = vec![u32::MAX; n];
    let mut inertia = 0.0f64;
    for it in 0..iterations.max(1) {
        let assign: Vec<(u32, f32)> = (0..n)
            .into_par_iter()
            .map(|i| nearest(&centers, dim, pt(i)))
            .collect();
        let changed = assign
            .iter()
            .zip(&labels)
            .filter(|(a, l)| a.0 != **l)
            .count();
        inertia = assign.iter().map(|a| a.1 as f64).sum();
        for (l, a) in labels.iter_mut().zip(&assign) {
            *l = a.0;
        }
        if changed == 0 || it + 1 == iterations.max(1) {
            break;
        }
        let mut sum = vec![0.0f64; k * dim];
        let mut cnt = vec![0usize; k];
        for (i, &l) in labels.iter().enumerate() {
            let c = l as usize;
            cnt[c] += 1;
            for (s, &x) in sum[c * dim..(c + 1) * dim].iter_mut().zip(pt(i)) {
                *s += x as f64;
            }
        }
        for c in 0..k {
            if cnt[c] > 0 {
                for j in 0..dim {
                    centers[c * dim + j] = (sum[c * dim + j] / cnt[c] as f64) as f32;
                }
            } else {
                // re-seed at the worst-fitting point
                let far = (0..n)
                    .max_by(|&a, &b| assign[a].1.total_cmp(&assign[b].1).then(b.cmp(&a)))
                    .unwrap_or(0);
                centers[c * dim..(c + 1) * dim].copy_from_slice(pt(far));
            }
        }
    }
    KMeans {
        dim,
        centers,
        labels,
        inertia,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn separates_blobs() {
        let mut rng = SmallRng::seed_from_u64(3);
        let means = [[0.0f32, 0.0], [10.0, 0.0], [0.0, 10.0], [10.0, 10.0]];
        let mut data = Vec::new();
        let mut truth = Vec::new();
        for i in 0..2000 {
            let m = means[i % 4];
            data.push(m[0] + rng.random::<f32>() - 0.5);
            data.push(m[1] + rng.random::<f32>() - 0.5);
            truth.push(i % 4);
        }
        let km = kmeans(&data, 2, 4, 25, 7);
        assert_eq!(km.k(), 4);
        // each true blob maps to a single label, and labels differ between blobs
        let mut map = [u32::MAX; 4];
        for (i, &t) in truth.iter().enumerate() {
            if map[t] == u32::MAX {
                map[t] = km.labels[i];
            }
            assert_eq!(map[t], km.labels[i]);
        }
        let mut m = map.to_vec();
        m.sort();
        m.dedup();
        assert_eq!(m.len(), 4);
        // deterministic
        assert_eq!(kmeans(&data, 2, 4, 25, 7).labels, km.labels);
        // fewer distinct points than k
        let few = kmeans(&[1.0, 1.0, 1.0, 1.0], 2, 5, 10, 0);
        assert_eq!(few.k(), 1);
    }
}
