//! The minimum-norm affine map between geodesic-distance vectors (MeshMatch §3.2).

use faer::linalg::solvers::Solve;
use faer::{Mat, Side};

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
    let mut aat = Mat::<f64>::from_fn(p, p, |i, j| {
        (0..cols).map(|c| a[i * cols + c] * a[j * cols + c]).sum()
    });
    for i in 0..p {
        aat[(i, i)] += 1e-6 * scale.max(1e-12);
    }
    // Residuals of the identity rows, one column per output row, all solved with one
    // factorisation of the (symmetric positive definite) A Aᵀ + εI.
    let mut y = Mat::<f64>::from_fn(p, k, |i, r| source_rows[i][r] as f64 - a[i * cols + r]);
    match aat.llt(Side::Lower) {
        Ok(llt) => llt.solve_in_place(y.as_mut()),
        Err(_) => y.fill(0.0),
    }
    let mut out = vec![0.0f64; k * cols];
    for r in 0..k {
        for c in 0..cols {
            let mut m = if c == r { 1.0 } else { 0.0 };
            for i in 0..p {
                m += a[i * cols + c] * y[(i, r)];
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
