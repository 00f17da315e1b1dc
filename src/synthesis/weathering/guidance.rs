//! CCA guidance (Mertens et al. §3.2): the source colours in their PCA basis, and the
//! canonical directions `x* = W_xᵀ (x - x̄^s)` that relate the features to them (eq. 1).

use faer::{Mat, Side};

use super::{CcaReport, FeatureSet, Params};
use crate::error::{Error, Result};
use crate::stats::{Cca, cca};

/// PCA basis of colours: mean and orthonormal axes (columns of a 3×3, row-major
/// `axes[i * 3 + k]` = component `i` of axis `k`), largest variance first.
pub(super) struct ColourBasis {
    mean: [f64; 3],
    axes: [f64; 9],
}

impl ColourBasis {
    /// The PCA basis of the colours `c`.
    pub(super) fn fit(c: &[[f32; 3]]) -> Result<Self> {
        let n = c.len().max(1) as f64;
        let mut m = [0.0f64; 3];
        for x in c {
            for k in 0..3 {
                m[k] += x[k] as f64 / n;
            }
        }
        let mut cov = Mat::<f64>::zeros(3, 3);
        for x in c {
            for i in 0..3 {
                for j in 0..3 {
                    cov[(i, j)] += (x[i] as f64 - m[i]) * (x[j] as f64 - m[j]) / n;
                }
            }
        }
        let evd = cov
            .self_adjoint_eigen(Side::Lower)
            .map_err(|e| Error::InvalidInput(format!("colour PCA failed: {e:?}")))?;
        let u = evd.U();
        let mut b = [0.0f64; 9];
        for k in 0..3 {
            // eigenvalues ascend: axis k = eigenvector 2 - k; sign: positive sum (towards white)
            let col = 2 - k;
            let s: f64 = (0..3).map(|i| u[(i, col)]).sum();
            let sgn = if s < 0.0 { -1.0 } else { 1.0 };
            for i in 0..3 {
                b[i * 3 + k] = sgn * u[(i, col)];
            }
        }
        Ok(ColourBasis { mean: m, axes: b })
    }

    /// An sRGB colour in the decorrelated basis.
    pub(super) fn decorrelated(&self, c: [f32; 3]) -> [f32; 3] {
        let (cmean, cb) = (&self.mean, &self.axes);
        let d = [0, 1, 2].map(|i| c[i] as f64 - cmean[i]);
        [0, 1, 2].map(|k| (0..3).map(|i| cb[i * 3 + k] * d[i]).sum::<f64>() as f32)
    }

    /// A decorrelated colour back in sRGB, clamped to [0, 1].
    pub(super) fn srgb(&self, y: [f32; 3]) -> [f32; 3] {
        let (cmean, cb) = (&self.mean, &self.axes);
        [0, 1, 2].map(|i| {
            let v = cmean[i] + (0..3).map(|k| cb[i * 3 + k] * y[k] as f64).sum::<f64>();
            (v as f32).clamp(0.0, 1.0)
        })
    }
}

/// The guidance fields and the CCA behind them.
pub(super) struct Guidance {
    /// The CCA, less the components switched off.
    pub model: Cca,
    /// The CCA in words and numbers (every component, with the ones kept marked).
    pub report: CcaReport,
    /// Guidance on the training vertices, `train.len() × dim`.
    pub source_train: Vec<f32>,
    /// Guidance on the target, `n × dim`.
    pub target: Vec<f32>,
    /// Guidance dimension.
    pub dim: usize,
    /// The colour weights (`W_y` columns, decorrelated channels) of the components switched
    /// off: the colour directions a regressed mean must not vary along.
    pub dropped: Vec<[f64; 3]>,
}

/// Fit the CCA between the source features and decorrelated colours on the training vertices,
/// drop the components [`Params::components`] switches off, and project both meshes' features.
pub(super) fn fit_guidance(
    fs: &FeatureSet,
    ft: &FeatureSet,
    train: &[u32],
    src_dec: &[[f32; 3]],
    params: &Params,
) -> Result<Guidance> {
    let p = fs.dim;
    let xs_train: Vec<f32> = train
        .iter()
        .flat_map(|&v| fs.row(v as usize).iter().copied())
        .collect();
    let ys_train: Vec<f32> = train.iter().flat_map(|&v| src_dec[v as usize]).collect();
    let model: Cca =
        cca(&xs_train, p, &ys_train, 3, params.cca_dims, 1e-6).map_err(|e| match e {
            Error::InvalidInput(m) if m.contains("colour is constant") => Error::InvalidInput(
                "source colour is constant: there is no texture to transfer".into(),
            ),
            other => other,
        })?;
    let d = model.d;
    let sw_std = model.standardised_wx();
    let enabled: Vec<bool> = match &params.components {
        None => vec![true; d],
        Some(keep) => (0..d).map(|k| keep.contains(&k)).collect(),
    };
    let report = CcaReport {
        feature_names: fs.names.clone(),
        weights: (0..p)
            .map(|i| sw_std[i * d..(i + 1) * d].to_vec())
            .collect(),
        correlations: model.correlations.clone(),
        training_vertices: train.len(),
        enabled: enabled.clone(),
        mean_weights: Vec::new(),
    };
    let q = model.q.min(3);
    let dropped: Vec<[f64; 3]> = (0..d)
        .filter(|&k| !enabled[k])
        .map(|k| {
            let mut w = [0.0f64; 3];
            for (r, x) in w.iter_mut().enumerate().take(q) {
                *x = model.wy[r * d + k];
            }
            w
        })
        .collect();
    // the components switched off leave the guidance (none off: the model as the paper has it)
    let model = if enabled.iter().all(|&e| e) {
        model
    } else {
        let keep: Vec<usize> = (0..d).filter(|&k| enabled[k]).collect();
        if keep.is_empty() {
            return Err(Error::InvalidInput(format!(
                "every canonical component is switched off (the CCA found {d}: 0 to {}); keep at least one",
                d - 1
            )));
        }
        model.keep(&keep)
    };
    let dim = model.d;
    let source_train = model.project_x(&xs_train);
    let target = model.project_x(&ft.values);
    Ok(Guidance {
        model,
        report,
        source_train,
        target,
        dim,
        dropped,
    })
}
