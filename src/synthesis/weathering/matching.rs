//! Feature matching (Mertens et al. §4.1): the target's guidance moved onto the source's
//! distribution by the n-D PDF transfer of Pitié et al. 2005, optionally band by band over the
//! mesh (Heeger-Bergen style), and blended with the raw guidance by `Params::match_strength`.

use super::guidance::Guidance;
use super::{FeatureSet, Params, pyramid};
use crate::error::Result;
use crate::mesh::TriMesh;
use crate::stats::{PdfTransferParams, pdf_transfer};
use crate::work::CancelToken;

/// Move the target guidance (`g.target`) onto the source's: single-scale or multi-scale as
/// `Params::multiscale_matching` says, then blended back by `Params::match_strength`.
pub(super) fn match_features(
    g: &mut Guidance,
    fs: &FeatureSet,
    src: &TriMesh,
    tgt: &TriMesh,
    train: &[u32],
    params: &Params,
    cancel: &CancelToken,
) -> Result<()> {
    let d = g.dim;
    let gt = &mut g.target;
    let pdf = PdfTransferParams {
        iterations: params.pdf_iterations,
        tolerance: 0.01,
        seed: params.seed ^ 0x0070_6466,
    };
    let strength = params.match_strength.clamp(0.0, 1.0);
    if strength > 0.0 {
        let raw = (strength < 1.0).then(|| gt.clone());
        if params.multiscale_matching {
            let gs_all = g.model.project_x(&fs.values);
            match_multiscale(
                gt,
                &tgt.adjacency(),
                &gs_all,
                &src.adjacency(),
                train,
                d,
                &pdf,
                cancel,
            )?;
        } else {
            pdf_transfer(gt, &g.source_train, d, &pdf);
        }
        if let Some(raw) = raw {
            for (g, r) in gt.iter_mut().zip(raw) {
                *g = r + strength * (*g - r);
            }
        }
    }
    Ok(())
}

/// Laplacian pyramid (3 levels) of a `n × d` field, per component: `levels[l]` is `n × d`.
fn field_pyramid(adj: &crate::mesh::Csr, f: &[f32], d: usize, levels: usize) -> Vec<Vec<f32>> {
    let n = f.len() / d;
    let mut out = vec![vec![0.0f32; n * d]; levels];
    for c in 0..d {
        let comp: Vec<f32> = f.iter().skip(c).step_by(d).copied().collect();
        for (l, band) in pyramid::decompose(adj, &comp, levels)
            .into_iter()
            .enumerate()
        {
            for (i, v) in band.into_iter().enumerate() {
                out[l][i * d + c] = v;
            }
        }
    }
    out
}

/// Multi-scale feature matching (Mertens et al. §4.1, after Heeger & Bergen): 3 passes of
/// {PDF-transfer every Laplacian band of the target guidance onto the source's band (3-D),
/// collapse, PDF-transfer the values}. Source statistics use the training vertices only.
#[allow(clippy::too_many_arguments)]
fn match_multiscale(
    gt: &mut Vec<f32>,
    tgt_adj: &crate::mesh::Csr,
    gs_all: &[f32],
    src_adj: &crate::mesh::Csr,
    train: &[u32],
    d: usize,
    pdf: &PdfTransferParams,
    cancel: &CancelToken,
) -> Result<()> {
    const LEVELS: usize = 3;
    const PASSES: usize = 3;
    let pick = |f: &[f32]| -> Vec<f32> {
        train
            .iter()
            .flat_map(|&v| f[v as usize * d..(v as usize + 1) * d].iter().copied())
            .collect()
    };
    let src_levels: Vec<Vec<f32>> = field_pyramid(src_adj, gs_all, d, LEVELS)
        .iter()
        .map(|l| pick(l))
        .collect();
    let src_values = pick(gs_all);
    for pass in 0..PASSES {
        cancel.check()?;
        let mut lv = field_pyramid(tgt_adj, gt, d, LEVELS);
        for b in 0..LEVELS - 1 {
            let p = PdfTransferParams {
                seed: pdf.seed ^ ((pass * 16 + b + 1) as u64),
                ..*pdf
            };
            pdf_transfer(&mut lv[b], &src_levels[b], d, &p);
        }
        let mut g = lv.pop().unwrap_or_default();
        for band in &lv {
            for (x, y) in g.iter_mut().zip(band) {
                *x += y;
            }
        }
        let p = PdfTransferParams {
            seed: pdf.seed ^ ((pass * 16) as u64),
            ..*pdf
        };
        pdf_transfer(&mut g, &src_values, d, &p);
        *gt = g;
    }
    Ok(())
}
