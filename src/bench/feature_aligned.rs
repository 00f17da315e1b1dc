//! Feature-aligned texturing rows (`meshmatch bench --system features`).

use super::{SystemRow, peak_rss_mb};
use crate::error::Result;
use crate::work::CancelToken;
use std::time::Instant;

/// Feature-aligned texturing (Xu et al. 2009) of a subdivided cube of about `n` vertices with
/// [`crate::demo::line_exemplar`]: salient curves, oriented field, field-driven synthesis of about `n`
/// vertices and the texture optimisation with the feature-to-feature constraint.
pub fn features_row(n: usize) -> Result<SystemRow> {
    use crate::synthesis::feature_aligned;
    let k = ((n as f64 / 6.0).sqrt().round() as usize).max(2);
    let target = crate::demo::crease_cube(k);
    let exemplar = crate::demo::line_exemplar();
    // about 4.5 area / h^2 synthesized vertices: h for n of them on the cube's area 6
    let h = (4.5 * 6.0 / n as f64).sqrt() as f32;
    let params = feature_aligned::Params {
        align_features: true,
        synth: crate::synthesis::exemplar::SynthParams {
            scale: Some(h * exemplar.width() as f32),
            max_vertices: (n * 2).max(200_000),
            ..Default::default()
        },
        ..Default::default()
    };
    let t = Instant::now();
    let input = feature_aligned::Input {
        target: &target,
        exemplar: &exemplar,
        curves: None,
        alpha: None,
        feature_mask: None,
    };
    let out = feature_aligned::run(&input, &params, &|_| {}, &CancelToken::new())?;
    Ok(SystemRow {
        case: format!(
            "features: cube of {} vertices, {} curves, a line exemplar aligned",
            target.num_vertices(),
            out.curves.len()
        ),
        vertices: out.synth.mesh.num_vertices(),
        stages: vec![
            ("curves".into(), out.timings.curves),
            ("field".into(), out.timings.field),
            (
                "greedy step (mean)".into(),
                out.field.step_secs.iter().sum::<f64>() / out.field.step_secs.len().max(1) as f64,
            ),
            (
                "greedy step (max)".into(),
                out.field.step_secs.iter().cloned().fold(0.0, f64::max),
            ),
            ("synthesis".into(), out.timings.synthesis),
            ("optimisation".into(), out.timings.optimization),
        ],
        total_s: t.elapsed().as_secs_f64(),
        faces: 0,
        peak_rss_mb: peak_rss_mb(),
    })
}
