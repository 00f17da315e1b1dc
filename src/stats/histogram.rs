//! One-dimensional distribution matching: quantile functions (optionally weighted), histogram
//! matching by ranks (Heeger & Bergen 1995, "Pyramid-based texture analysis/synthesis",
//! `match-histogram`) and the Kolmogorov-Smirnov distance used to check it.

/// Sorted copy of the finite values of `v`.
pub fn sorted(v: &[f32]) -> Vec<f32> {
    let mut s: Vec<f32> = v.iter().copied().filter(|x| x.is_finite()).collect();
    s.sort_unstable_by(f32::total_cmp);
    s
}

/// Value of the empirical quantile function of the sorted sample `s` at probability `p` in
/// [0, 1]: linear interpolation between order statistics placed at `(i + 0.5) / n`; 0 when `s`
/// is empty.
#[inline]
pub fn quantile_sorted(s: &[f32], p: f32) -> f32 {
    let n = s.len();
    if n == 0 {
        return 0.0;
    }
    let x = p * n as f32 - 0.5;
    if x <= 0.0 {
        return s[0];
    }
    let i = x.floor() as usize;
    if i + 1 >= n {
        return s[n - 1];
    }
    let t = x - i as f32;
    s[i] + t * (s[i + 1] - s[i])
}

/// The `m`-point quantile function of `values` (weights `w`, or all 1): entry `i` is the
/// (weighted) quantile at `(i + 0.5) / m`. Samples with weight `<= 0` or non-finite values are
/// left out; an empty sample gives `m` zeros.
pub fn quantile_function(values: &[f32], weights: Option<&[f32]>, m: usize) -> Vec<f32> {
    let mut pairs: Vec<(f32, f32)> = match weights {
        Some(w) => values
            .iter()
            .zip(w)
            .filter(|(v, w)| v.is_finite() && **w > 0.0 && w.is_finite())
            .map(|(&v, &w)| (v, w))
            .collect(),
        None => values
            .iter()
            .filter(|v| v.is_finite())
            .map(|&v| (v, 1.0))
            .collect(),
    };
    if pairs.is_empty() || m == 0 {
        return vec![0.0; m];
    }
    pairs.sort_unstable_by(|a, b| a.0.total_cmp(&b.0));
    let total: f64 = pairs.iter().map(|p| p.1 as f64).sum();
    // cumulative weight at each sample's centre: c_i = (sum_{j<i} w_j + w_i / 2) / total
    let mut out = Vec::with_capacity(m);
    let mut acc = 0.0f64;
    let mut j = 0usize;
    let mut prev_c = f64::NEG_INFINITY;
    let mut prev_v = pairs[0].0;
    let mut cur_c = pairs[0].1 as f64 * 0.5 / total;
    for i in 0..m {
        let p = (i as f64 + 0.5) / m as f64;
        while j < pairs.len() && cur_c < p {
            prev_c = cur_c;
            prev_v = pairs[j].0;
            acc += pairs[j].1 as f64;
            j += 1;
            if j < pairs.len() {
                cur_c = (acc + pairs[j].1 as f64 * 0.5) / total;
            }
        }
        let v = if j >= pairs.len() {
            pairs[pairs.len() - 1].0
        } else if prev_c == f64::NEG_INFINITY {
            pairs[0].0
        } else {
            let t = ((p - prev_c) / (cur_c - prev_c).max(1e-300)).clamp(0.0, 1.0);
            prev_v + (t as f32) * (pairs[j].0 - prev_v)
        };
        out.push(v);
    }
    out
}

/// Heeger-Bergen histogram matching: remap `values` monotonically so that their distribution
/// becomes the one described by the quantile function `q` (`q[i]` at `(i + 0.5) / m`, e.g. from
/// [`quantile_function`] or a sorted sample). Ranks are taken among the entries of `values` with
/// weight `> 0` (`weights`, or all); entries with zero weight are returned unchanged.
/// Ties keep their index order, so the mapping is deterministic.
pub fn match_to_quantiles(values: &mut [f32], weights: Option<&[f32]>, q: &[f32]) {
    if q.is_empty() {
        return;
    }
    let mut idx: Vec<u32> = (0..values.len() as u32)
        .filter(|&i| weights.is_none_or(|w| w[i as usize] > 0.0))
        .collect();
    if idx.is_empty() {
        return;
    }
    idx.sort_unstable_by(|&a, &b| {
        values[a as usize]
            .total_cmp(&values[b as usize])
            .then(a.cmp(&b))
    });
    let total: f64 = match weights {
        Some(w) => idx.iter().map(|&i| w[i as usize] as f64).sum(),
        None => idx.len() as f64,
    };
    let mut acc = 0.0f64;
    for &i in &idx {
        let wi = weights.map_or(1.0, |w| w[i as usize] as f64);
        let p = ((acc + 0.5 * wi) / total) as f32;
        acc += wi;
        values[i as usize] = quantile_sorted(q, p);
    }
}

/// Exact histogram matching of `values` onto the empirical distribution of `reference`.
pub fn match_histogram(values: &mut [f32], reference: &[f32]) {
    let s = sorted(reference);
    match_to_quantiles(values, None, &s);
}

/// Two-sample Kolmogorov-Smirnov distance `sup |F_a - F_b|` (0 = same distribution, 1 = disjoint).
pub fn ks_distance(a: &[f32], b: &[f32]) -> f32 {
    ks_distance_sorted(&sorted(a), &sorted(b))
}

/// [`ks_distance`] of two samples already sorted ascending (finite values).
pub fn ks_distance_sorted(a: &[f32], b: &[f32]) -> f32 {
    if a.is_empty() || b.is_empty() {
        return if a.len() == b.len() { 0.0 } else { 1.0 };
    }
    let (na, nb) = (a.len() as f64, b.len() as f64);
    let (mut i, mut j, mut d) = (0usize, 0usize, 0.0f64);
    while i < a.len() && j < b.len() {
        let x = a[i].min(b[j]);
        while i < a.len() && a[i] <= x {
            i += 1;
        }
        while j < b.len() && b[j] <= x {
            j += 1;
        }
        d = d.max((i as f64 / na - j as f64 / nb).abs());
    }
    d as f32
}

/// Blend quantile functions (all of the same length) with weights (normalised here): the
/// quantile-domain average of Matusik et al. 2005, which interpolates shapes, not mixtures.
pub fn blend_quantiles(qs: &[&[f32]], weights: &[f32]) -> Vec<f32> {
    let m = qs.first().map_or(0, |q| q.len());
    let total: f32 = weights.iter().sum();
    let mut out = vec![0.0f32; m];
    if total <= 0.0 {
        return out;
    }
    for (q, &w) in qs.iter().zip(weights) {
        for (o, &v) in out.iter_mut().zip(q.iter()) {
            *o += v * w / total;
        }
    }
    out
}

/// Wasserstein-1 (earth mover's) distance between the value distributions of `a` and `b`: the
/// mean absolute difference of their quantile functions, compared at as many levels as the
/// shorter sample has values.
pub fn wasserstein1(a: &[f32], b: &[f32]) -> f64 {
    let mut a = a.to_vec();
    let mut b = b.to_vec();
    a.sort_by(f32::total_cmp);
    b.sort_by(f32::total_cmp);
    let n = a.len().min(b.len()).max(1);
    if a.is_empty() || b.is_empty() {
        return 0.0;
    }
    let q = |v: &[f32], i: usize| v[(i * v.len()) / n] as f64;
    (0..n).map(|i| (q(&a, i) - q(&b, i)).abs()).sum::<f64>() / n as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn matching_makes_distributions_equal_and_quantile_blend_is_unimodal() {
        let a: Vec<f32> = (0..1000)
            .map(|i| ((i * 7919) % 1000) as f32 / 1000.0)
            .collect();
        let b: Vec<f32> = (0..700)
            .map(|i| ((i * 31) % 700) as f32 * 0.01 + 3.0)
            .collect();
        assert!(ks_distance(&a, &b) > 0.99);
        let mut c = a.clone();
        match_histogram(&mut c, &b);
        assert!(ks_distance(&c, &b) < 0.01, "{}", ks_distance(&c, &b));
        // monotone: order kept
        for i in 0..a.len() {
            for j in 0..20 {
                if a[i] < a[j] {
                    assert!(c[i] <= c[j]);
                }
            }
        }
        // weighted quantiles: weights 0 drop samples
        let v = [0.0, 1.0, 2.0, 100.0];
        let q = quantile_function(&v, Some(&[1.0, 1.0, 1.0, 0.0]), 3);
        assert!(q.iter().all(|&x| x <= 2.0), "{q:?}");
        // N(0,1)-like and N(4,1)-like uniform blocks blended at 1/2: centred at 2, unimodal
        let q0: Vec<f32> = (0..256)
            .map(|i| (i as f32 + 0.5) / 256.0 * 2.0 - 1.0)
            .collect();
        let q4: Vec<f32> = q0.iter().map(|x| x + 4.0).collect();
        let qb = blend_quantiles(&[&q0, &q4], &[1.0, 1.0]);
        assert!((qb[0] - 1.0).abs() < 0.01 && (qb[255] - 3.0).abs() < 0.01);
    }
}
