//! Canonical correlation analysis (Hotelling 1936; Borga 1998), as used by Mertens et al. 2006
//! eq. (1): `sqrt(Λ) W_xᵀ x ≈ W_yᵀ y`.
//!
//! Computation: standardise every column (so the result does not depend on units), then
//! `K = C_xx^{-1/2} C_xy C_yy^{-1/2} = U S Vᵀ`, `ρ = diag(S)`, `W_x = C_xx^{-1/2} U`,
//! `W_y = C_yy^{-1/2} V`, and undo the standardisation in the weights. `C_xx` and `C_yy` get a
//! ridge `λ tr(C)/p · I` so constant or collinear columns (normal vs. first-band occlusion) stay
//! well posed. The canonical variates `u = W_xᵀ (x - x̄)` have unit variance on the training set.

use faer::{Mat, Side};

use crate::error::{Error, Result};

/// A fitted CCA.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct Cca {
    /// Number of X columns (features).
    pub p: usize,
    /// Number of Y columns.
    pub q: usize,
    /// Number of canonical pairs kept.
    pub d: usize,
    /// Column means of X.
    pub x_mean: Vec<f64>,
    /// Column means of Y.
    pub y_mean: Vec<f64>,
    /// Column standard deviations of X (0 for a constant column).
    pub x_std: Vec<f64>,
    /// X weights, `p × d` row-major (row = feature), in the raw units of X.
    pub wx: Vec<f64>,
    /// Y weights, `q × d` row-major, in the raw units of Y.
    pub wy: Vec<f64>,
    /// Canonical correlations `ρ_1 ≥ … ≥ ρ_d`.
    pub correlations: Vec<f64>,
}

/// Mean and covariance of the columns of `a` (n × c, row-major).
fn moments(a: &[f32], c: usize) -> (Vec<f64>, Vec<f64>) {
    let n = a.len() / c;
    let mut mean = vec![0.0f64; c];
    for r in a.chunks_exact(c) {
        for (m, &x) in mean.iter_mut().zip(r) {
            *m += x as f64;
        }
    }
    mean.iter_mut().for_each(|m| *m /= n.max(1) as f64);
    let mut var = vec![0.0f64; c];
    for r in a.chunks_exact(c) {
        for j in 0..c {
            var[j] += (r[j] as f64 - mean[j]).powi(2);
        }
    }
    var.iter_mut().for_each(|v| *v /= n.max(1) as f64);
    (mean, var)
}

/// `C^{-1/2}` of a symmetric PSD matrix with a relative ridge.
fn inv_sqrt(c: &Mat<f64>, ridge: f64) -> Result<Mat<f64>> {
    let k = c.nrows();
    let tr: f64 = (0..k).map(|i| c[(i, i)]).sum::<f64>().max(1e-300);
    let evd = c
        .self_adjoint_eigen(Side::Lower)
        .map_err(|e| Error::InvalidInput(format!("CCA eigen-decomposition failed: {e:?}")))?;
    let s = evd.S().column_vector();
    let u = evd.U();
    let mut out = Mat::<f64>::zeros(k, k);
    for e in 0..k {
        let l = s[e].max(0.0) + ridge * tr / k as f64;
        let f = 1.0 / l.sqrt();
        for i in 0..k {
            for j in 0..k {
                out[(i, j)] += u[(i, e)] * f * u[(j, e)];
            }
        }
    }
    Ok(out)
}

/// Fit CCA between `x` (n × p, row-major) and `y` (n × q) keeping `d = min(d, p, q)` pairs,
/// with relative ridge `ridge` (1e-6 is a good default). Errors (one line) when there are fewer
/// than 2 rows, or when X or Y has no varying column.
pub fn cca(x: &[f32], p: usize, y: &[f32], q: usize, d: usize, ridge: f64) -> Result<Cca> {
    if p == 0
        || q == 0
        || !x.len().is_multiple_of(p)
        || !y.len().is_multiple_of(q)
        || x.len() / p != y.len() / q
    {
        return Err(Error::InvalidInput(
            "CCA needs X and Y with the same number of rows".into(),
        ));
    }
    let n = x.len() / p;
    if n < 2 {
        return Err(Error::InvalidInput("CCA needs at least 2 samples".into()));
    }
    let (xm, xv) = moments(x, p);
    let (ym, yv) = moments(y, q);
    let xs: Vec<f64> = xv.iter().map(|v| v.sqrt()).collect();
    let ys: Vec<f64> = yv.iter().map(|v| v.sqrt()).collect();
    let scale_max = |s: &[f64]| s.iter().copied().fold(0.0f64, f64::max);
    let tiny = |s: f64, m: f64| s <= 1e-12 * m.max(1e-30);
    let (xmax, ymax) = (scale_max(&xs), scale_max(&ys));
    if xs.iter().all(|&s| tiny(s, xmax.max(1.0))) {
        return Err(Error::InvalidInput("CCA: every feature is constant".into()));
    }
    if ys.iter().all(|&s| tiny(s, ymax.max(1.0))) {
        return Err(Error::InvalidInput(
            "CCA: the colour is constant over the training set".into(),
        ));
    }
    let xinv: Vec<f64> = xs
        .iter()
        .map(|&s| if tiny(s, xmax) { 0.0 } else { 1.0 / s })
        .collect();
    let yinv: Vec<f64> = ys
        .iter()
        .map(|&s| if tiny(s, ymax) { 0.0 } else { 1.0 / s })
        .collect();
    // correlation-type covariances of the standardised columns
    let mut cxx = Mat::<f64>::zeros(p, p);
    let mut cyy = Mat::<f64>::zeros(q, q);
    let mut cxy = Mat::<f64>::zeros(p, q);
    let mut zx = vec![0.0f64; p];
    let mut zy = vec![0.0f64; q];
    for (rx, ry) in x.chunks_exact(p).zip(y.chunks_exact(q)) {
        for j in 0..p {
            zx[j] = (rx[j] as f64 - xm[j]) * xinv[j];
        }
        for j in 0..q {
            zy[j] = (ry[j] as f64 - ym[j]) * yinv[j];
        }
        for i in 0..p {
            for j in 0..=i {
                cxx[(i, j)] += zx[i] * zx[j];
            }
            for j in 0..q {
                cxy[(i, j)] += zx[i] * zy[j];
            }
        }
        for i in 0..q {
            for j in 0..=i {
                cyy[(i, j)] += zy[i] * zy[j];
            }
        }
    }
    let nf = n as f64;
    for i in 0..p {
        for j in 0..=i {
            let v = cxx[(i, j)] / nf;
            cxx[(i, j)] = v;
            cxx[(j, i)] = v;
        }
        for j in 0..q {
            cxy[(i, j)] /= nf;
        }
    }
    for i in 0..q {
        for j in 0..=i {
            let v = cyy[(i, j)] / nf;
            cyy[(i, j)] = v;
            cyy[(j, i)] = v;
        }
    }
    let ridge = ridge.max(0.0);
    let ax = inv_sqrt(&cxx, ridge)?;
    let ay = inv_sqrt(&cyy, ridge)?;
    let k = &ax * &cxy * &ay;
    let svd = k
        .thin_svd()
        .map_err(|e| Error::InvalidInput(format!("CCA SVD failed: {e:?}")))?;
    let d = d.min(p).min(q).max(1);
    let u = svd.U();
    let v = svd.V();
    let s = svd.S().column_vector();
    let wx_std = &ax * u.subcols(0, d);
    let wy_std = &ay * v.subcols(0, d);
    let mut wx = vec![0.0f64; p * d];
    let mut wy = vec![0.0f64; q * d];
    let mut corr = vec![0.0f64; d];
    for c in 0..d {
        // sign convention: the colour side's weights sum to a positive value (a brighter colour
        // raises the variate), ties broken by the largest weight
        let sum: f64 = (0..q).map(|i| wy_std[(i, c)]).sum();
        let big = (0..q)
            .map(|i| wy_std[(i, c)])
            .fold(0.0f64, |a, b| if b.abs() > a.abs() { b } else { a });
        let sgn = if sum.abs() > 1e-9 {
            sum.signum()
        } else {
            big.signum().max(0.0) * 2.0 - 1.0
        };
        for i in 0..p {
            wx[i * d + c] = sgn * wx_std[(i, c)] * xinv[i];
        }
        for i in 0..q {
            wy[i * d + c] = sgn * wy_std[(i, c)] * yinv[i];
        }
        corr[c] = s[c].clamp(0.0, 1.0);
    }
    Ok(Cca {
        p,
        q,
        d,
        x_mean: xm,
        y_mean: ym,
        x_std: xs,
        wx,
        wy,
        correlations: corr,
    })
}

impl Cca {
    /// Canonical X variates `W_xᵀ (x - x̄)` of the rows of `x` (n × p): n × d, row-major. The
    /// same (training) mean is used for every input, as Mertens et al. do for the target.
    pub fn project_x(&self, x: &[f32]) -> Vec<f32> {
        project(x, self.p, &self.x_mean, &self.wx, self.d)
    }
    /// Canonical Y variates `W_yᵀ (y - ȳ)` (n × d).
    pub fn project_y(&self, y: &[f32]) -> Vec<f32> {
        project(y, self.q, &self.y_mean, &self.wy, self.d)
    }
    /// The model restricted to the canonical pairs `keep` (indices into `0..d`, in the order
    /// given): projections then give only those variates. Out-of-range indices are skipped.
    pub fn keep(&self, keep: &[usize]) -> Cca {
        let keep: Vec<usize> = keep.iter().copied().filter(|&k| k < self.d).collect();
        let cols = |w: &[f64], rows: usize| -> Vec<f64> {
            (0..rows)
                .flat_map(|r| keep.iter().map(move |&k| w[r * self.d + k]))
                .collect()
        };
        Cca {
            p: self.p,
            q: self.q,
            d: keep.len(),
            x_mean: self.x_mean.clone(),
            y_mean: self.y_mean.clone(),
            x_std: self.x_std.clone(),
            wx: cols(&self.wx, self.p),
            wy: cols(&self.wy, self.q),
            correlations: keep.iter().map(|&k| self.correlations[k]).collect(),
        }
    }
    /// X weights in standardised units (`w · std`): comparable magnitudes, one row per feature.
    pub fn standardised_wx(&self) -> Vec<f64> {
        (0..self.p * self.d)
            .map(|i| self.wx[i] * self.x_std[i / self.d])
            .collect()
    }
}

fn project(a: &[f32], c: usize, mean: &[f64], w: &[f64], d: usize) -> Vec<f32> {
    use rayon::prelude::*;
    let mut out = vec![0.0f32; a.len() / c * d];
    out.par_chunks_mut(d)
        .zip(a.par_chunks(c))
        .for_each(|(o, r)| {
            for k in 0..d {
                let mut s = 0.0f64;
                for j in 0..c {
                    s += (r[j] as f64 - mean[j]) * w[j * d + k];
                }
                o[k] = s as f32;
            }
        });
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::stats::pdf_transfer::gaussian;
    use crate::stats::pearson;
    use rand::SeedableRng;
    use rand::rngs::SmallRng;

    #[test]
    fn recovers_a_planted_linear_relation() {
        let mut rng = SmallRng::seed_from_u64(11);
        let (n, p, q) = (4000, 12, 3);
        let scales: Vec<f64> = (0..p).map(|i| 0.1 + i as f64 * 0.7).collect();
        let mut x = Vec::with_capacity(n * p);
        let mut y = Vec::with_capacity(n * q);
        for _ in 0..n {
            let row: Vec<f64> = scales.iter().map(|s| s * gaussian(&mut rng)).collect();
            // feature 11 has by far the largest variance and is unrelated to colour (PCA trap)
            let mut row = row;
            row[11] *= 100.0;
            let (a, b) = (row[3] / scales[3], row[7] / scales[7]);
            y.extend([
                (a + 0.5 * b + 0.01 * gaussian(&mut rng)) as f32,
                (b - 0.2 * a + 0.01 * gaussian(&mut rng)) as f32,
                gaussian(&mut rng) as f32,
            ]);
            x.extend(row.iter().map(|&v| v as f32));
        }
        let c = cca(&x, p, &y, q, 3, 1e-6).unwrap();
        assert!(
            c.correlations[0] > 0.99 && c.correlations[1] > 0.99,
            "{:?}",
            c.correlations
        );
        assert!(c.correlations[2] < 0.1, "{:?}", c.correlations);
        // the top two directions span e3, e7 (in standardised units)
        let w = c.standardised_wx();
        for k in 0..2 {
            let norm: f64 = (0..p).map(|i| w[i * 3 + k].powi(2)).sum::<f64>().sqrt();
            let inplane = (w[3 * 3 + k].powi(2) + w[7 * 3 + k].powi(2)).sqrt();
            assert!(inplane / norm > 0.9998, "{k}: {inplane} / {norm}");
            assert!(w[11 * 3 + k].abs() / norm < 0.02);
        }
        // rescaling a feature by 1000 leaves the variates unchanged
        let u = c.project_x(&x);
        let mut x2 = x.clone();
        x2.iter_mut().skip(3).step_by(p).for_each(|v| *v *= 1000.0);
        let c2 = cca(&x2, p, &y, q, 3, 1e-6).unwrap();
        let u2 = c2.project_x(&x2);
        for k in 0..2 {
            let a: Vec<f32> = u.iter().skip(k).step_by(3).copied().collect();
            let b: Vec<f32> = u2.iter().skip(k).step_by(3).copied().collect();
            assert!(pearson(&a, &b).abs() > 0.9999);
        }
        // eq. (1): rho * u predicts the Y variate
        let v = c.project_y(&y);
        let a: Vec<f32> = u.iter().step_by(3).copied().collect();
        let b: Vec<f32> = v.iter().step_by(3).copied().collect();
        assert!(pearson(&a, &b) > 0.99);
        // a constant column is harmless; constant colour is an error
        let mut x3 = x.clone();
        x3.iter_mut().step_by(p).for_each(|v| *v = 2.0);
        assert!(cca(&x3, p, &y, q, 3, 1e-6).is_ok());
        assert!(cca(&x, p, &vec![0.5; n * q], q, 3, 1e-6).is_err());
    }
}
