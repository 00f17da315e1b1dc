//! Laplacian surface editing with uniform Laplacian coordinates (Sorkine et al. 2004, in the
//! form mesh quilting uses to join overlapping elements: Zhou et al. 2006 eq. (4)-(5)).
//!
//! Eq. (4): `L(v_i) = v_i - (1 / #N(i)) sum_{j in N(i)} v_j` over the 1-ring `N(i)`.
//! Eq. (5): the new positions `w` minimise
//! `sum_i |L(w_i) - L(v_i)|^2 + mu sum_c |w_c - c|^2`
//! over the constrained vertices `c`. The original (not rotated) coordinates are kept, as in the
//! paper: the deformations it serves are small. The normal equations
//! `(L^T L + mu C^T C) w = L^T L v + mu C^T c` are solved per coordinate by conjugate gradients,
//! matrix-free on the CSR 1-rings, starting from `v`: constraints at the current positions give
//! exactly zero motion, and a connected component without constraints does not move.

use crate::mesh::Csr;

/// Positions minimising eq. (5) for `positions` with 1-rings `adj`, the soft position
/// constraints `constraints` (vertex, goal; repeated vertices pool their goals) and weight `mu`
/// (the paper: 1). Conjugate gradients to a relative residual of `1e-7` or `max_iter`
/// iterations (a few hundred suffice for elements of a few thousand vertices).
pub fn laplacian_deform(
    positions: &[[f32; 3]],
    adj: &Csr,
    constraints: &[(u32, [f32; 3])],
    mu: f32,
    max_iter: usize,
) -> Vec<[f32; 3]> {
    let n = positions.len();
    let mu = mu as f64;
    // per-vertex constraint weight and weighted goal sum
    let mut wc = vec![0.0f64; n];
    let mut goal = vec![[0.0f64; 3]; n];
    for &(v, c) in constraints {
        let v = v as usize;
        if v >= n {
            continue;
        }
        wc[v] += mu;
        for a in 0..3 {
            goal[v][a] += mu * c[a] as f64;
        }
    }
    let inv_deg: Vec<f64> = (0..n)
        .map(|i| {
            let d = adj.row(i).len();
            if d > 0 { 1.0 / d as f64 } else { 0.0 }
        })
        .collect();
    // y = L x
    let apply_l = |x: &[f64], y: &mut [f64]| {
        for i in 0..n {
            let row = adj.row(i);
            if row.is_empty() {
                y[i] = 0.0;
                continue;
            }
            let s: f64 = row.iter().map(|&j| x[j as usize]).sum();
            y[i] = x[i] - s * inv_deg[i];
        }
    };
    // y = L^T x (the 1-rings are symmetric: j in N(i) iff i in N(j))
    let apply_lt = |x: &[f64], y: &mut [f64]| {
        for i in 0..n {
            let row = adj.row(i);
            let own = if row.is_empty() { 0.0 } else { x[i] };
            let s: f64 = row
                .iter()
                .map(|&j| x[j as usize] * inv_deg[j as usize])
                .sum();
            y[i] = own - s;
        }
    };
    let mut tmp = vec![0.0f64; n];
    let apply_a = |x: &[f64], y: &mut [f64], tmp: &mut [f64]| {
        apply_l(x, tmp);
        apply_lt(tmp, y);
        for i in 0..n {
            y[i] += wc[i] * x[i];
        }
    };
    let mut out = positions.to_vec();
    let (mut r, mut p, mut ap) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    for a in 0..3 {
        let v: Vec<f64> = positions.iter().map(|q| q[a] as f64).collect();
        // b = L^T L v + mu C^T c; r = b - A v = mu (C^T c - wc v)
        let mut x = v.clone();
        for i in 0..n {
            r[i] = goal[i][a] - wc[i] * v[i];
        }
        let b_norm = {
            apply_a(&v, &mut ap, &mut tmp);
            ap.iter()
                .zip(&r)
                .map(|(q, s)| (q + s) * (q + s))
                .sum::<f64>()
                .sqrt()
                .max(1e-300)
        };
        p.copy_from_slice(&r);
        let mut rr: f64 = r.iter().map(|x| x * x).sum();
        for _ in 0..max_iter {
            if rr.sqrt() <= 1e-7 * b_norm {
                break;
            }
            apply_a(&p, &mut ap, &mut tmp);
            let pap: f64 = p.iter().zip(&ap).map(|(x, y)| x * y).sum();
            if pap <= 0.0 || !pap.is_finite() {
                break;
            }
            let alpha = rr / pap;
            for i in 0..n {
                x[i] += alpha * p[i];
                r[i] -= alpha * ap[i];
            }
            let rr_new: f64 = r.iter().map(|x| x * x).sum();
            let beta = rr_new / rr;
            rr = rr_new;
            for i in 0..n {
                p[i] = r[i] + beta * p[i];
            }
        }
        for (o, xi) in out.iter_mut().zip(&x) {
            o[a] = *xi as f32;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::vertex_adjacency;

    /// A strip of `n` quads along x (unit squares), two triangles each.
    fn strip(n: usize) -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
        let mut p = Vec::new();
        for i in 0..=n {
            p.push([i as f32, 0.0, 0.0]);
            p.push([i as f32, 1.0, 0.0]);
        }
        let mut f = Vec::new();
        for i in 0..n as u32 {
            let (a, b, c, d) = (2 * i, 2 * i + 2, 2 * i + 3, 2 * i + 1);
            f.push([a, b, c]);
            f.push([a, c, d]);
        }
        (p, f)
    }

    #[test]
    fn constraints_at_current_positions_give_zero_motion() {
        let (p, f) = strip(8);
        let adj = vertex_adjacency(p.len(), &f);
        let cons: Vec<(u32, [f32; 3])> = vec![(0, p[0]), (5, p[5]), (17, p[17])];
        let w = laplacian_deform(&p, &adj, &cons, 1.0, 500);
        assert_eq!(w, p);
    }

    #[test]
    fn moving_every_constraint_alike_translates_the_mesh() {
        let (p, f) = strip(8);
        let adj = vertex_adjacency(p.len(), &f);
        let d = [0.25f32, -0.5, 0.75];
        let cons: Vec<(u32, [f32; 3])> = [0u32, 1, 16, 17]
            .iter()
            .map(|&v| {
                let q = p[v as usize];
                (v, [q[0] + d[0], q[1] + d[1], q[2] + d[2]])
            })
            .collect();
        let w = laplacian_deform(&p, &adj, &cons, 1.0, 1000);
        for (a, b) in w.iter().zip(&p) {
            for k in 0..3 {
                assert!((a[k] - b[k] - d[k]).abs() < 1e-4, "{a:?} vs {b:?}");
            }
        }
    }

    #[test]
    fn lifting_one_end_bends_the_strip_smoothly_and_keeps_the_other() {
        let (p, f) = strip(10);
        let adj = vertex_adjacency(p.len(), &f);
        // the left end held, the right end lifted by 1 (soft, mu = 1)
        let mut cons: Vec<(u32, [f32; 3])> = vec![(0, p[0]), (1, p[1])];
        cons.push((20, [10.0, 0.0, 1.0]));
        cons.push((21, [10.0, 1.0, 1.0]));
        let w = laplacian_deform(&p, &adj, &cons, 1.0, 2000);
        // heights rise monotonically along the strip, from near 0 to near 1
        let z: Vec<f32> = (0..=10).map(|i| w[2 * i][2]).collect();
        assert!(z[0].abs() < 0.2 && z[10] > 0.8, "{z:?}");
        assert!(z.windows(2).all(|s| s[1] >= s[0] - 1e-5), "{z:?}");
    }
}
