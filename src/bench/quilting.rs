//! Quilting rows (`meshmatch bench --system quilt`).

use super::{SystemRow, peak_rss_mb};
use crate::error::Result;
use crate::work::CancelToken;
use std::time::Instant;

/// Mesh quilting of the chain-mail swatch over a plane (`planar`) or the bunny, with the swatch
/// `1 / swatches` of the base's bounding-box diagonal wide.
pub fn quilt_row(planar: bool, swatches: f32) -> Result<SystemRow> {
    quilt_row_of(
        crate::synthesis::quilting::SwatchKind::Chain,
        planar,
        swatches,
        false,
    )
}

/// Mesh quilting of `kind` over a plane or the bunny, threads merged across seams or not.
pub fn quilt_row_of(
    kind: crate::synthesis::quilting::SwatchKind,
    planar: bool,
    swatches: f32,
    merge: bool,
) -> Result<SystemRow> {
    use crate::synthesis::quilting;
    let base = if planar {
        quilting::plane(1.0, 1.0, 64, 64)
    } else {
        let mut b = crate::mesh::io::load(&crate::testdata::data_path("bunny/bunny.obj"))?;
        b.repair()?;
        b
    };
    let (lo, hi) = base
        .bounds()
        .ok_or_else(|| crate::error::Error::InvalidMesh("empty base".into()))?;
    let diag = glam::Vec3::from(hi).distance(glam::Vec3::from(lo));
    let swatch = quilting::swatch(kind, 1);
    let params = quilting::Params {
        swatch_size: Some(diag / swatches),
        merge_elements: merge,
        ..quilting::Params::default()
    };
    let t = Instant::now();
    let input = quilting::Input {
        base: &base,
        swatch: &swatch,
        field: None,
    };
    let out = quilting::run(&input, &params, &|_| {}, &CancelToken::new())?;
    Ok(SystemRow {
        case: format!(
            "quilt {} on {} (swatch = diagonal / {swatches}){}",
            kind.as_str(),
            if planar { "a plane" } else { "the bunny" },
            if merge { ", threads merged" } else { "" }
        ),
        vertices: base.num_vertices(),
        stages: vec![("quilt".into(), out.stats.seconds)],
        total_s: t.elapsed().as_secs_f64(),
        faces: out.elements.num_faces(),
        peak_rss_mb: peak_rss_mb(),
    })
}

/// Mesh quilting of a finite swatch (`quilting::finite_patch`, loaded as a swatch file would
/// be) over the bunny or the horse, the swatch a tenth of the diagonal wide.
pub fn quilt_finite_row(
    kind: crate::synthesis::quilting::PatchKind,
    horse: bool,
) -> Result<SystemRow> {
    use crate::synthesis::quilting;
    let name = if horse {
        "horse/horse.ply"
    } else {
        "bunny/bunny.obj"
    };
    let mut base = crate::mesh::io::load(&crate::testdata::data_path(name))?;
    base.repair()?;
    let (lo, hi) = base
        .bounds()
        .ok_or_else(|| crate::error::Error::InvalidMesh("empty base".into()))?;
    let diag = glam::Vec3::from(hi).distance(glam::Vec3::from(lo));
    let swatch = quilting::load_swatch(quilting::finite_patch(kind, 1), quilting::Axis::Z)?;
    let params = quilting::Params {
        swatch_size: Some(diag / 10.0),
        ..quilting::Params::default()
    };
    let t = Instant::now();
    let input = quilting::Input {
        base: &base,
        swatch: &swatch,
        field: None,
    };
    let out = quilting::run(&input, &params, &|_| {}, &CancelToken::new())?;
    Ok(SystemRow {
        case: format!(
            "quilt finite {} on the {} (swatch = diagonal / 10; {})",
            kind.as_str(),
            if horse { "horse" } else { "bunny" },
            out.stats.arrangement_summary()
        ),
        vertices: base.num_vertices(),
        stages: vec![("quilt".into(), out.stats.seconds)],
        total_s: t.elapsed().as_secs_f64(),
        faces: out.elements.num_faces(),
        peak_rss_mb: peak_rss_mb(),
    })
}
