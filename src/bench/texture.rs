//! Full-resolution delivery rows (`meshmatch bench --system texture`).

use super::{SystemRow, peak_rss_mb};
use crate::error::Result;
use crate::meshmatch::TransferParams;
use crate::work::CancelToken;
use std::time::Instant;

/// Full-resolution delivery (`meshmatch bench --system texture`): a ground-truth task (Spot with
/// a detailed brick texture, re-tessellated, bent and moved, a UV atlas on the target) solved
/// once at `n` working vertices, then its texture delivered at 1024^2, 2048^2 and 4096^2 (and the
/// same task posed at a joint, at 2048^2): the
/// resampler (patch maps, the coincident check, corner images) and the bake timed apart, the
/// working-vertex bake beside them, each row with its scores against the truth.
pub fn texture_rows(n: usize) -> Result<Vec<SystemRow>> {
    use crate::ground_truth::{Deformation, TextureKind, detailed_texture};
    let mut source = crate::mesh::io::load(&crate::testdata::data_path("spot/spot.obj"))?;
    source.texture = Some(std::sync::Arc::new(crate::mesh::Texture {
        image: detailed_texture(TextureKind::Bricks, 2048),
        path: None,
    }));
    let mut rows = Vec::new();
    for (deformation, sizes, label) in [
        (
            Deformation::BentAndMoved,
            &[1024u32, 2048, 4096][..],
            "bent",
        ),
        (Deformation::PosedAndMoved, &[2048u32][..], "posed"),
    ] {
        rows.extend(deformation_rows(&source, n, deformation, sizes, label)?);
    }
    Ok(rows)
}

/// The rows of one deformation of the task, one per texture side in `sizes`.
fn deformation_rows(
    source: &crate::mesh::TriMesh,
    n: usize,
    deformation: crate::ground_truth::Deformation,
    sizes: &[u32],
    label: &str,
) -> Result<Vec<SystemRow>> {
    use crate::ground_truth::{TexelTask, score};
    use crate::meshmatch::{BakeLayout, Resampler, prepare_pair, solve};
    let task = TexelTask::new(source.clone(), 12_000, deformation, 4096, 7)?;
    let params = TransferParams {
        vertices: n,
        ..TransferParams::default()
    };
    let cancel = CancelToken::new();
    let (ps, pt) = prepare_pair(
        &task.source,
        &params,
        &task.target,
        &params,
        &|_| {},
        &cancel,
    )?;
    let r = solve(&ps, &pt, &task.correspondences, &params, &|_| {}, &cancel)?;
    let layout = BakeLayout::of(&pt);
    let mut rows = Vec::new();
    for &size in sizes {
        let (truth, covered) = task.truth(size);
        let t = Instant::now();
        let full = Resampler::new(&ps, &pt, &r.nnf, &cancel)?.ok_or_else(|| {
            crate::error::Error::InvalidInput("the source cannot be resampled".into())
        })?;
        let t_resampler = t.elapsed().as_secs_f64();
        let t = Instant::now();
        let image = layout.bake_resampled(&task.target, &full, size);
        let t_bake = t.elapsed().as_secs_f64();
        let s_full = score(&image, &truth, &covered);
        let t = Instant::now();
        let image = layout.bake(&task.target, &r.working_signal, size);
        let t_working = t.elapsed().as_secs_f64();
        let s_working = score(&image, &truth, &covered);
        rows.push(SystemRow {
            case: format!(
                "texture {size}^2, bricks on Spot {label}: full resolution dE {:.2} SSIM {:.3} \
                 sharpness {:.2}, working vertices dE {:.2} SSIM {:.3} sharpness {:.2}",
                s_full.delta_e,
                s_full.ssim,
                s_full.sharpness,
                s_working.delta_e,
                s_working.ssim,
                s_working.sharpness
            ),
            vertices: pt.working_mesh().num_vertices(),
            stages: full
                .timings()
                .iter()
                .map(|(k, s)| (k.to_string(), *s))
                .chain([
                    ("resampler".into(), t_resampler),
                    ("bake".into(), t_bake),
                    ("working-vertex bake".into(), t_working),
                ])
                .collect(),
            total_s: t_resampler + t_bake,
            faces: 0,
            peak_rss_mb: peak_rss_mb(),
        });
    }
    Ok(rows)
}
