//! A k-d tree over points of a few dimensions (flat row-major storage), for exact k-nearest
//! neighbour queries: median splits on the widest axis, leaves of up to 8 points.

/// A k-d tree over `n` points of `dim` coordinates.
pub struct KdTree {
    dim: usize,
    /// Points permuted into tree order, row-major.
    points: Vec<f32>,
    /// Original index of each point in tree order.
    index: Vec<u32>,
    /// Nodes: (start, end, split axis or `usize::MAX` for a leaf, split value).
    nodes: Vec<(u32, u32, usize, f32)>,
}

const LEAF: usize = 8;

impl KdTree {
    /// Build over `points` (row-major, `dim` per point).
    pub fn new(points: &[f32], dim: usize) -> Self {
        let dim = dim.max(1);
        let n = points.len() / dim;
        let mut order: Vec<u32> = (0..n as u32).collect();
        let mut nodes = Vec::with_capacity(2 * n / LEAF + 1);
        build(points, dim, &mut order, 0, n, &mut nodes);
        let mut pts = Vec::with_capacity(n * dim);
        for &i in &order {
            pts.extend_from_slice(&points[i as usize * dim..(i as usize + 1) * dim]);
        }
        KdTree {
            dim,
            points: pts,
            index: order,
            nodes,
        }
    }

    /// The `k` nearest points to `q` as `(squared distance, original index)`, nearest first.
    /// `out` is reused (cleared first).
    pub fn knn(&self, q: &[f32], k: usize, out: &mut Vec<(f32, u32)>) {
        out.clear();
        if self.nodes.is_empty() || k == 0 {
            return;
        }
        self.search(0, q, k, out);
        out.sort_by(|a, b| a.0.total_cmp(&b.0));
    }

    /// Every point within squared distance `r2` of `q` (inclusive), as original indices in
    /// tree order. `out` is reused (cleared first).
    pub fn within(&self, q: &[f32], r2: f32, out: &mut Vec<u32>) {
        out.clear();
        if !self.nodes.is_empty() {
            self.gather(0, q, r2, out);
        }
    }

    fn gather(&self, node: usize, q: &[f32], r2: f32, out: &mut Vec<u32>) {
        let (start, end, axis, split) = self.nodes[node];
        if axis == usize::MAX {
            for i in start as usize..end as usize {
                let p = &self.points[i * self.dim..(i + 1) * self.dim];
                let d: f32 = p.iter().zip(q).map(|(a, b)| (a - b) * (a - b)).sum();
                if d <= r2 {
                    out.push(self.index[i]);
                }
            }
            return;
        }
        // the left child holds coordinates up to the split, the right from it
        let diff = q[axis] - split;
        if diff <= 0.0 || diff * diff <= r2 {
            self.gather(node + 1, q, r2, out);
        }
        if diff >= 0.0 || diff * diff <= r2 {
            self.gather(end as usize, q, r2, out);
        }
    }

    fn search(&self, node: usize, q: &[f32], k: usize, out: &mut Vec<(f32, u32)>) {
        let (start, end, axis, split) = self.nodes[node];
        if axis == usize::MAX {
            for i in start as usize..end as usize {
                let p = &self.points[i * self.dim..(i + 1) * self.dim];
                let d: f32 = p.iter().zip(q).map(|(a, b)| (a - b) * (a - b)).sum();
                if out.len() < k {
                    out.push((d, self.index[i]));
                } else {
                    let (w, worst) = out.iter().enumerate().fold((0, f32::MIN), |acc, (j, e)| {
                        if e.0 > acc.1 { (j, e.0) } else { acc }
                    });
                    if d < worst {
                        out[w] = (d, self.index[i]);
                    }
                }
            }
            return;
        }
        // Children are stored right after their parent: left at node + 1, right at the index
        // recorded in `end` for inner nodes.
        let (left, right) = (node + 1, end as usize);
        let diff = q[axis] - split;
        let (near, far) = if diff < 0.0 {
            (left, right)
        } else {
            (right, left)
        };
        self.search(near, q, k, out);
        let worst = if out.len() < k {
            f32::INFINITY
        } else {
            out.iter().fold(f32::MIN, |m, e| m.max(e.0))
        };
        if diff * diff < worst {
            self.search(far, q, k, out);
        }
    }
}

fn build(
    points: &[f32],
    dim: usize,
    order: &mut [u32],
    start: usize,
    end: usize,
    nodes: &mut Vec<(u32, u32, usize, f32)>,
) {
    let me = nodes.len();
    if end - start <= LEAF {
        nodes.push((start as u32, end as u32, usize::MAX, 0.0));
        return;
    }
    let coord = |i: u32, a: usize| points[i as usize * dim + a];
    let mut axis = 0;
    let mut widest = -1.0f32;
    for a in 0..dim {
        let (lo, hi) = order[start..end]
            .iter()
            .fold((f32::INFINITY, f32::NEG_INFINITY), |(l, h), &i| {
                (l.min(coord(i, a)), h.max(coord(i, a)))
            });
        if hi - lo > widest {
            widest = hi - lo;
            axis = a;
        }
    }
    let mid = (start + end) / 2;
    order[start..end].select_nth_unstable_by(mid - start, |&a, &b| {
        coord(a, axis).total_cmp(&coord(b, axis))
    });
    let split = coord(order[mid], axis);
    nodes.push((start as u32, 0, axis, split));
    build(points, dim, order, start, mid, nodes);
    let right = nodes.len();
    nodes[me].1 = right as u32;
    build(points, dim, order, mid, end, nodes);
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng, rngs::SmallRng};

    #[test]
    fn within_finds_every_point_in_the_ball_and_no_other() {
        let mut rng = SmallRng::seed_from_u64(5);
        let dim = 2;
        // a grid (coordinates on split values) and random points
        let mut pts: Vec<f32> = (0..400)
            .flat_map(|i| [(i % 20) as f32 / 20.0, (i / 20) as f32 / 20.0])
            .collect();
        pts.extend((0..2000 * dim).map(|_| rng.random::<f32>()));
        let tree = KdTree::new(&pts, dim);
        let mut out = Vec::new();
        for _ in 0..200 {
            let q = [rng.random::<f32>(), rng.random::<f32>()];
            let r2 = 0.02 * rng.random::<f32>();
            tree.within(&q, r2, &mut out);
            out.sort_unstable();
            let brute: Vec<u32> = (0..pts.len() / dim)
                .filter(|&i| {
                    let d = (pts[2 * i] - q[0]).powi(2) + (pts[2 * i + 1] - q[1]).powi(2);
                    d <= r2
                })
                .map(|i| i as u32)
                .collect();
            assert_eq!(out, brute);
        }
    }

    #[test]
    fn knn_matches_brute_force() {
        let mut rng = SmallRng::seed_from_u64(3);
        let dim = 3;
        let pts: Vec<f32> = (0..3000 * dim).map(|_| rng.random::<f32>()).collect();
        let tree = KdTree::new(&pts, dim);
        let mut out = Vec::new();
        for _ in 0..200 {
            let q: Vec<f32> = (0..dim).map(|_| rng.random::<f32>()).collect();
            tree.knn(&q, 5, &mut out);
            let mut brute: Vec<(f32, u32)> = (0..3000)
                .map(|i| {
                    let d = (0..dim).map(|a| (pts[i * dim + a] - q[a]).powi(2)).sum();
                    (d, i as u32)
                })
                .collect();
            brute.sort_by(|a, b| a.0.total_cmp(&b.0));
            let got: Vec<u32> = out.iter().map(|e| e.1).collect();
            let want: Vec<u32> = brute[..5].iter().map(|e| e.1).collect();
            assert_eq!(got, want);
        }
    }
}
