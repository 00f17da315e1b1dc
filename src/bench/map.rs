//! Shape-map rows (`meshmatch bench --system map`): the map alone and whole transfers with and
//! without it, SMPL man -> woman.

use super::{SystemRow, peak_rss_mb};
use crate::error::Result;
use crate::mesh::TriMesh;
use crate::work::CancelToken;
use std::time::Instant;

/// The SMPL man (coloured by height bands) and the woman refined to `n` vertices and moved, with
/// six landmarks (head top, hands, feet, a toe) on the same SMPL vertices.
fn bodies(n: usize) -> Result<(TriMesh, TriMesh, Vec<crate::correspondence::Correspondence>)> {
    let load = |p: &str| crate::mesh::io::load(&crate::testdata::data_path(p));
    let mut man = load("human/human_man.obj")?;
    man.colors = Some(
        man.positions
            .iter()
            .map(|p| {
                let band = ((p[1] * 12.0).floor() as i32).rem_euclid(2) as f32;
                [0.15 + 0.7 * band, if p[0] > 0.0 { 0.85 } else { 0.15 }, 0.5]
            })
            .collect(),
    );
    let woman = load("human/human_woman.obj")?;
    let r = crate::geometry::refine_to_density(&woman, n);
    let (s, c) = (0.6f32.sin(), 0.6f32.cos());
    let moved = TriMesh::new(
        r.mesh
            .positions
            .iter()
            .map(|p| [c * p[0] + s * p[2] + 0.3, p[1] - 0.2, -s * p[0] + c * p[2]])
            .collect(),
        r.mesh.faces.clone(),
    );
    let corr = [411u32, 2445, 5906, 3354, 6755, 3215]
        .iter()
        .map(|&v| crate::correspondence::Correspondence {
            source_vertex: v,
            target_vertices: vec![v],
        })
        .collect();
    Ok((man, moved, corr))
}

/// The global shape map (`meshmatch map`) from the SMPL man onto the woman refined to `n`
/// vertices and moved, six landmarks.
pub fn map_row(n: usize) -> Result<SystemRow> {
    let (man, woman, corr) = bodies(n)?;
    let t = Instant::now();
    let m = crate::meshmatch::map_meshes(&man, &woman, &corr, &CancelToken::new())?;
    Ok(SystemRow {
        case: format!(
            "map man -> woman (k = {}, computed on {} x {} vertices, isometry score {:.2})",
            m.k, m.map_vertices.0, m.map_vertices.1, m.score
        ),
        vertices: woman.num_vertices(),
        stages: m.timings.clone(),
        total_s: t.elapsed().as_secs_f64(),
        faces: 0,
        peak_rss_mb: peak_rss_mb(),
    })
}

/// A whole transfer man -> woman (as [`map_row`]) at `n` working vertices with the given
/// structure (`None` = auto), to compare its cost with and without the map.
pub fn structure_row(n: usize, structure: Option<f32>) -> Result<SystemRow> {
    let (man, woman, corr) = bodies(n)?;
    let params = crate::meshmatch::TransferParams {
        vertices: n,
        structure,
        ..Default::default()
    };
    let t = Instant::now();
    let r = crate::meshmatch::transfer(&man, &woman, &corr, &params, &|_| {}, &CancelToken::new())?;
    Ok(SystemRow {
        case: format!(
            "transfer man -> woman, structure {} (used {:.2})",
            structure.map_or("auto".to_string(), |x| format!("{x}")),
            r.structure
        ),
        vertices: n,
        stages: r
            .timings
            .iter()
            .filter(|(k, _)| k == "global map" || k.ends_with("prepare") || k == "affinities")
            .cloned()
            .collect(),
        total_s: t.elapsed().as_secs_f64(),
        faces: 0,
        peak_rss_mb: peak_rss_mb(),
    })
}
