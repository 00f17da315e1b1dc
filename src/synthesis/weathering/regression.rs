//! The colour regressed on the features, as three more guidance fields of the parametric
//! synthesis ([`super::Mean::Neighbours`]).
//!
//! The paper's mean colour is a per-cluster affine map of the 3-D guidance, and its histogram
//! matching re-ranks the colour inside each cluster. Rules that are not linear in the features (a
//! stain past a curvature threshold, moss where the surface faces up *and* is exposed) are then
//! carried only as far as a linear projection can carry them, and where a cluster mixes stained
//! and clean points, matching its histogram scatters the stain over the clean ones. Here:
//! 1. **Standardise** every feature column by the training vertices' mean and deviation.
//! 2. **Weigh** each column by its relevance to the colour, from the CCA (the components switched
//!    off give no weight): half a uniform weight, half the geometric mean of its correlation
//!    ratio with the canonical colour variates and of its canonical weight ([`relevance`]), the
//!    most relevant column 1. Columns that no colour direction follows weigh half as much, so
//!    they scatter the neighbours less, but a rule the linear CCA ranks low keeps its columns.
//! 3. **Regress**: each vertex gets the mean colour of its `k` nearest training vertices in the
//!    weighted space (a training vertex leaves itself out).
//! 4. **Guide**: the regressed colour joins the guidance ([`extend_guidance`]), so the clusters
//!    separate what the regression tells apart and their affine maps follow it, while the
//!    histogram matching still gives each cluster the source's colours, crisp where the geometry
//!    does not decide them.

use rayon::prelude::*;

use super::FeatureSet;
use crate::stats::{Cca, KdTree};

/// Neighbours averaged per vertex.
pub const NEIGHBOURS: usize = 8;

/// The regressed mean colour (decorrelated channels) on every source and target vertex, and the
/// feature weights it used.
pub(super) struct Prediction {
    /// Per channel, on every source vertex (leave-one-out on the training vertices).
    pub source: [Vec<f32>; 3],
    /// Per channel, on every target vertex.
    pub target: [Vec<f32>; 3],
    /// Weight of each feature column in the distance.
    pub weights: Vec<f32>,
}

/// Regress the decorrelated source colours `src_dec` of the training vertices `train` on the
/// features `fs` (source) and `ft` (target), weighted by their relevance to the CCA `model`.
pub(super) fn predict(
    fs: &FeatureSet,
    ft: &FeatureSet,
    train: &[u32],
    src_dec: &[[f32; 3]],
    model: &Cca,
) -> Prediction {
    let p = fs.dim;
    let (mean, scale) = column_scales(fs, train);
    let ys: Vec<f32> = train.iter().flat_map(|&v| src_dec[v as usize]).collect();
    let vy = model.project_y(&ys);
    let weights = relevance(fs, train, &vy, model);
    let (xs, xt) = (
        standardised(fs, &mean, &scale, &weights),
        standardised(ft, &mean, &scale, &weights),
    );
    let xtrain: Vec<f32> = train
        .iter()
        .flat_map(|&v| xs[v as usize * p..(v as usize + 1) * p].iter().copied())
        .collect();
    let tree = KdTree::new(&xtrain, p);
    let k = NEIGHBOURS.min(train.len().saturating_sub(1)).max(1);
    let colours: Vec<[f32; 3]> = train.iter().map(|&v| src_dec[v as usize]).collect();
    let channels = |rows: Vec<[f32; 3]>| -> [Vec<f32>; 3] {
        [0, 1, 2].map(|c| rows.iter().map(|r| r[c]).collect())
    };
    Prediction {
        source: channels(knn_mean(&tree, &colours, &xs, p, k, Some(train))),
        target: channels(knn_mean(&tree, &colours, &xt, p, k, None)),
        weights,
    }
}

/// Per query row of `xq` (`d` per row), the mean colour of its `k` nearest points of `tree`
/// (whose point `j` has colour `colours[j]`). With `leave_out = Some(ids)`, the query rows are
/// vertices and a tree point `j` whose vertex `ids[j]` is the query's own is skipped.
pub(crate) fn knn_mean(
    tree: &KdTree,
    colours: &[[f32; 3]],
    xq: &[f32],
    d: usize,
    k: usize,
    leave_out: Option<&[u32]>,
) -> Vec<[f32; 3]> {
    let k = k.max(1);
    let query = k + usize::from(leave_out.is_some());
    xq.par_chunks(d)
        .enumerate()
        .map_init(Vec::new, |buf, (v, q)| {
            tree.knn(q, query, buf);
            let mut m = [0.0f32; 3];
            let mut n = 0usize;
            for &(_, j) in buf.iter() {
                if n == k || leave_out.is_some_and(|ids| ids[j as usize] == v as u32) {
                    continue;
                }
                for (mk, ck) in m.iter_mut().zip(colours[j as usize]) {
                    *mk += ck;
                }
                n += 1;
            }
            m.map(|s| s / n.max(1) as f32)
        })
        .collect()
}

/// The guidance of the training vertices (`g_train`, `dim` per row) and of the target (`g_target`)
/// with the regressed colours appended as three more fields, each scaled to unit standard
/// deviation over the training vertices, as the canonical variates are.
pub(super) fn extend_guidance(
    g_train: &[f32],
    g_target: &[f32],
    dim: usize,
    train: &[u32],
    source: &[Vec<f32>; 3],
    target: &[Vec<f32>; 3],
) -> (Vec<f32>, Vec<f32>) {
    let n = train.len().max(1) as f64;
    let scale: [f32; 3] = [0, 1, 2].map(|c| {
        let m = train
            .iter()
            .map(|&i| source[c][i as usize] as f64)
            .sum::<f64>()
            / n;
        let var = train
            .iter()
            .map(|&i| (source[c][i as usize] as f64 - m).powi(2))
            .sum::<f64>()
            / n;
        if var > 1e-18 {
            (1.0 / var.sqrt()) as f32
        } else {
            0.0
        }
    });
    let rows = |g: &[f32], colour: &dyn Fn(usize, usize) -> f32| -> Vec<f32> {
        g.chunks(dim.max(1))
            .enumerate()
            .flat_map(|(k, r)| {
                let mut row = r.to_vec();
                row.extend((0..3).map(|c| colour(k, c) * scale[c]));
                row
            })
            .collect()
    };
    (
        rows(g_train, &|k, c| source[c][train[k] as usize]),
        rows(g_target, &|v, c| target[c][v]),
    )
}

/// Remove from the regressed colours `y` (decorrelated channels) their variation along each
/// canonical colour direction in `dropped` (a switched-off component's `W_y` column): with
/// `v = wᵀ (y - ȳ)` and the direction's loading `a = Σ_yy w` over the training colours,
/// `y ← y - a v`, so the component's variate is constant (at its mean) and the other
/// components, uncorrelated with it, keep theirs.
pub(super) fn drop_directions(
    y: &mut [Vec<f32>; 3],
    dropped: &[[f64; 3]],
    train: &[u32],
    src_dec: &[[f32; 3]],
) {
    if dropped.is_empty() || train.is_empty() {
        return;
    }
    let n = train.len() as f64;
    let mut mean = [0.0f64; 3];
    for &v in train {
        for (m, &c) in mean.iter_mut().zip(&src_dec[v as usize]) {
            *m += c as f64 / n;
        }
    }
    let mut cov = [[0.0f64; 3]; 3];
    for &v in train {
        let c = src_dec[v as usize];
        for i in 0..3 {
            for j in 0..3 {
                cov[i][j] += (c[i] as f64 - mean[i]) * (c[j] as f64 - mean[j]) / n;
            }
        }
    }
    for w in dropped {
        let a: [f64; 3] = [0, 1, 2].map(|i| (0..3).map(|j| cov[i][j] * w[j]).sum());
        for i in 0..y[0].len() {
            let v: f64 = (0..3).map(|c| w[c] * (y[c][i] as f64 - mean[c])).sum();
            for c in 0..3 {
                y[c][i] -= (a[c] * v) as f32;
            }
        }
    }
}

/// The rows of `fs`, each column `j` standardised by `mean[j]` and `scale[j]`
/// ([`column_scales`]) and multiplied by `weights[j]`.
pub(super) fn standardised(
    fs: &FeatureSet,
    mean: &[f64],
    scale: &[f64],
    weights: &[f32],
) -> Vec<f32> {
    let p = fs.dim;
    fs.values
        .iter()
        .enumerate()
        .map(|(i, &v)| {
            let j = i % p;
            ((v as f64 - mean[j]) * scale[j]) as f32 * weights[j]
        })
        .collect()
}

/// Per feature column, the training vertices' mean and the reciprocal of their standard
/// deviation (0 for a constant column).
pub(super) fn column_scales(fs: &FeatureSet, train: &[u32]) -> (Vec<f64>, Vec<f64>) {
    let p = fs.dim;
    let n = train.len().max(1) as f64;
    let mut mean = vec![0.0f64; p];
    for &v in train {
        for (m, &x) in mean.iter_mut().zip(fs.row(v as usize)) {
            *m += x as f64 / n;
        }
    }
    let mut var = vec![0.0f64; p];
    for &v in train {
        for ((s, &x), m) in var.iter_mut().zip(fs.row(v as usize)).zip(&mean) {
            *s += (x as f64 - m).powi(2) / n;
        }
    }
    let scale = var
        .iter()
        .map(|&s| if s > 1e-18 { 1.0 / s.sqrt() } else { 0.0 })
        .collect();
    (mean, scale)
}

/// Per feature column, how far the colour follows it: half a uniform weight and half the
/// geometric mean of two measures over the canonical pairs of `model`, each the root sum of
/// squares over the pairs and scaled so its largest column is 1:
/// - its correlation ratio with the canonical colour variates `vy` (`train.len() × d`): the
///   colour follows the column, linearly or not (a column that merely varies with a relevant
///   one also scores here);
/// - its standardised canonical weight times the pair's canonical correlation: the CCA needs
///   the column beside the others (a stand-in for a relevant column scores low here).
///
/// Both measures come from a linear model of the colour, which ranks a column that a weaker
/// rule follows through a threshold (moss on exposed tops beside dark dirt and a height tint)
/// far below the strongest rule's columns; the uniform half keeps every column in the distance
/// ([`UNIFORM_SHARE`]).
fn relevance(fs: &FeatureSet, train: &[u32], vy: &[f32], model: &Cca) -> Vec<f32> {
    let d = model.d;
    let variates: Vec<Vec<f32>> = (0..d)
        .map(|k| vy.iter().skip(k).step_by(d.max(1)).copied().collect())
        .collect();
    let follows: Vec<f32> = (0..fs.dim)
        .map(|j| {
            let col: Vec<f32> = train.iter().map(|&v| fs.row(v as usize)[j]).collect();
            let bins = quantile_bins(&col, BINS);
            variates
                .iter()
                .map(|vk| correlation_ratio(&bins, vk, BINS))
                .sum::<f64>()
                .sqrt() as f32
        })
        .collect();
    let sw = model.standardised_wx();
    let needed: Vec<f32> = (0..fs.dim)
        .map(|j| {
            (0..d)
                .map(|k| (model.correlations[k] * sw[j * d + k]).powi(2))
                .sum::<f64>()
                .sqrt() as f32
        })
        .collect();
    let unit = |w: Vec<f32>| -> Option<Vec<f32>> {
        let top = w.iter().copied().fold(0.0f32, f32::max);
        (top > 0.0 && top.is_finite()).then(|| w.iter().map(|x| x / top).collect())
    };
    let both = match (unit(follows), unit(needed)) {
        (Some(a), Some(b)) => a.iter().zip(&b).map(|(x, y)| (x * y).sqrt()).collect(),
        _ => vec![1.0; fs.dim],
    };
    unit(both)
        .unwrap_or_else(|| vec![1.0; fs.dim])
        .into_iter()
        .map(|w| UNIFORM_SHARE + (1.0 - UNIFORM_SHARE) * w)
        .collect()
}

/// The share of every feature's weight in [`relevance`] that is the same for all. Measured on
/// the recipe pairs at 12K points (`examples/weather_recipes`, the least correlation of L, a*
/// and b*): 0 gives 0.52 (`ruin` on cow -> cat; cow -> cat and igea -> bunny), 0.3 gives 0.65
/// (the same pairs), 0.5 gives 0.73 and 0.7 gives 0.74 (all twelve); 1, every feature alike,
/// loses single rules (concavity on cow -> cat 0.69).
const UNIFORM_SHARE: f32 = 0.5;

/// Bins of the feature values in [`relevance`]'s correlation ratios.
const BINS: usize = 32;

/// The quantile bin (of `bins`) of every value of `x` (ties share a bin).
fn quantile_bins(x: &[f32], bins: usize) -> Vec<u16> {
    let mut order: Vec<u32> = (0..x.len() as u32).collect();
    order.sort_unstable_by(|&a, &b| x[a as usize].total_cmp(&x[b as usize]));
    let mut out = vec![0u16; x.len()];
    let n = x.len().max(1);
    let mut bin = 0usize;
    for (r, &i) in order.iter().enumerate() {
        // a new bin only where the value changes, so equal values never straddle two
        let due = r * bins / n;
        if due > bin && r > 0 && x[order[r - 1] as usize] != x[i as usize] {
            bin = due;
        }
        out[i as usize] = bin as u16;
    }
    out
}

/// The correlation ratio η² of `y` on the bins of a feature: the share of `y`'s variance its
/// bin means explain, the feature's dependence whether or not it is linear (a stain past a
/// threshold, moss on the upper side).
fn correlation_ratio(bins: &[u16], y: &[f32], nb: usize) -> f64 {
    let mut sum = vec![0.0f64; nb];
    let mut count = vec![0usize; nb];
    for (&b, &v) in bins.iter().zip(y) {
        sum[b as usize] += v as f64;
        count[b as usize] += 1;
    }
    let n = y.len().max(1) as f64;
    let mean = sum.iter().sum::<f64>() / n;
    let total: f64 = y.iter().map(|&v| (v as f64 - mean).powi(2)).sum();
    let between: f64 = sum
        .iter()
        .zip(&count)
        .filter(|(_, c)| **c > 0)
        .map(|(s, &c)| c as f64 * (s / c as f64 - mean).powi(2))
        .sum();
    if total > 0.0 { between / total } else { 0.0 }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::stats::{cca, pearson};
    use rand::rngs::SmallRng;
    use rand::{Rng, SeedableRng};

    /// A colour that steps where one of six features passes a threshold, the other five noise:
    /// the regression recovers the step (a linear map of the features cannot), and the five
    /// unrelated columns get little more than the uniform share of the weight.
    #[test]
    fn a_threshold_rule_is_regressed_and_unrelated_features_weigh_little() {
        let mut rng = SmallRng::seed_from_u64(5);
        let (n, p) = (4000, 6);
        let make = |rng: &mut SmallRng| -> FeatureSet {
            let values: Vec<f32> = (0..n * p).map(|_| rng.random::<f32>()).collect();
            FeatureSet {
                values,
                dim: p,
                names: (0..p).map(|j| format!("f{j}")).collect(),
                ..FeatureSet::default()
            }
        };
        let (fs, ft) = (make(&mut rng), make(&mut rng));
        let rule = |f: &FeatureSet, v: usize| -> [f32; 3] {
            let s = if f.row(v)[2] > 0.7 { 1.0 } else { 0.0 };
            [s, 0.3 * s, 0.0]
        };
        let src: Vec<[f32; 3]> = (0..n).map(|v| rule(&fs, v)).collect();
        let train: Vec<u32> = (0..n as u32).collect();
        let ys: Vec<f32> = src.iter().flatten().copied().collect();
        let model = cca(&fs.values, p, &ys, 3, 3, 1e-6).unwrap();
        let pr = predict(&fs, &ft, &train, &src, &model);
        assert!((pr.weights[2] - 1.0).abs() < 1e-6, "{:?}", pr.weights);
        for (j, w) in pr.weights.iter().enumerate() {
            if j != 2 {
                let relevance = (w - UNIFORM_SHARE) / (1.0 - UNIFORM_SHARE);
                assert!(relevance < 0.2, "column {j} weighs {w}");
            }
        }
        let truth: Vec<f32> = (0..n).map(|v| rule(&ft, v)[0]).collect();
        let r = pearson(&pr.target[0], &truth);
        assert!(r > 0.9, "correlation {r}");
        // leave-one-out: a lone training point far from the others does not predict itself
        let wrong = (0..n)
            .filter(|&v| (pr.source[0][v] - src[v][0]).abs() > 0.5)
            .count();
        assert!(wrong < n / 20, "{wrong} source vertices mispredicted");
    }
}
