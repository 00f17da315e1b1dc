//! The minimum-norm affine map between geodesic-distance vectors (MeshMatch §3.2).

/// Solve the small dense system `a x = b` (n x n, row-major) by Gaussian elimination with partial
/// pivoting; `None` if singular.
fn solve_dense(mut a: Vec<f64>, mut b: Vec<f64>, n: usize) -> Option<Vec<f64>> {
    for c in 0..n {
        let p = (c..n).max_by(|&i, &j| a[i * n + c].abs().total_cmp(&a[j * n + c].abs()))?;
        if a[p * n + c].abs() < 1e-14 {
            return None;
        }
        if p != c {
            for k in 0..n {
                a.swap(c * n + k, p * n + k);
            }
            b.swap(c, p);
        }
        for r in c + 1..n {
            let f = a[r * n + c] / a[c * n + c];
            if f != 0.0 {
                for k in c..n {
                    a[r * n + k] -= f * a[c * n + k];
                }
                b[r] -= f * b[c];
            }
        }
    }
    let mut x = vec![0.0; n];
    for r in (0..n).rev() {
        let mut s = b[r];
        for k in r + 1..n {
            s -= a[r * n + k] * x[k];
        }
        x[r] = s / a[r * n + r];
    }
    Some(x)
}

/// The affine map of MeshMatch §3.2 taking target geodesic-distance vectors to source ones:
/// returns `K x (K + 1)` row-major `[M | b]` with `M g_T + b = g_S` at every constrained pair
/// (rows `target_rows[i]` -> `source_rows[i]`, each a K-vector). Among all exact solutions we
/// take the one of minimum Frobenius distance to the identity `[I | 0]` (the "minimum-norm"
/// correction, so that already-agreeing shapes keep M = I); with more equations than unknowns
/// (one-to-many) it is the ridge-regularised least-squares fit. Closed form per output row r:
/// m_r = e_r + Aᵀ (A Aᵀ + εI)⁻¹ (y_r − A e_r), A = rows [g_T, 1].
pub fn min_norm_affine(target_rows: &[Vec<f32>], source_rows: &[Vec<f32>], k: usize) -> Vec<f64> {
    let p = target_rows.len();
    let cols = k + 1;
    let a: Vec<f64> = target_rows
        .iter()
        .flat_map(|g| g.iter().map(|&x| x as f64).chain(std::iter::once(1.0)))
        .collect();
    let scale = a.iter().map(|x| x * x).sum::<f64>() / p.max(1) as f64;
    let mut aat = vec![0.0f64; p * p];
    for i in 0..p {
        for j in 0..p {
            aat[i * p + j] = (0..cols).map(|c| a[i * cols + c] * a[j * cols + c]).sum();
        }
        aat[i * p + i] += 1e-6 * scale.max(1e-12);
    }
    let mut out = vec![0.0f64; k * cols];
    for r in 0..k {
        // Residual of the identity row.
        let resid: Vec<f64> = (0..p)
            .map(|i| source_rows[i][r] as f64 - a[i * cols + r])
            .collect();
        let y = solve_dense(aat.clone(), resid, p).unwrap_or_else(|| vec![0.0; p]);
        for c in 0..cols {
            let mut m = if c == r { 1.0 } else { 0.0 };
            for i in 0..p {
                m += a[i * cols + c] * y[i];
            }
            out[r * cols + c] = m;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn affine_map_is_exact_at_constraints_and_identity_when_equal() {
        let g: Vec<Vec<f32>> = vec![
            vec![0.0, 2.0, 3.0],
            vec![2.0, 0.0, 1.5],
            vec![3.0, 1.5, 0.0],
        ];
        let m = min_norm_affine(&g, &g, 3);
        for r in 0..3 {
            for c in 0..4 {
                let e = if r == c { 1.0 } else { 0.0 };
                assert!((m[r * 4 + c] - e).abs() < 1e-4);
            }
        }
        let s: Vec<Vec<f32>> = g
            .iter()
            .map(|v| v.iter().map(|x| 2.0 * x + 0.5).collect())
            .collect();
        let m = min_norm_affine(&g, &s, 3);
        for (gt, gs) in g.iter().zip(&s) {
            for r in 0..3 {
                let y: f64 =
                    (0..3).map(|c| m[r * 4 + c] * gt[c] as f64).sum::<f64>() + m[r * 4 + 3];
                assert!((y - gs[r] as f64).abs() < 1e-3, "{y} vs {}", gs[r]);
            }
        }
    }
}
