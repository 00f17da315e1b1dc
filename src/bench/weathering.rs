//! Weathering rows (`meshmatch bench --system weather|weather-recipes`).

use super::{SystemRow, peak_rss_mb};
use crate::error::Result;
use crate::work::CancelToken;
use std::time::Instant;

/// Geometry-correlated transfer, Spot (textured) -> the horse, both at `n` surface points:
/// features, CCA, matching and synthesis by `method`.
pub fn weather_row(n: usize, method: crate::synthesis::weathering::Method) -> Result<SystemRow> {
    use crate::synthesis::weathering;
    let mut source = crate::mesh::io::load(&crate::testdata::data_path("spot/spot.obj"))?;
    source.repair()?;
    let mut target = crate::mesh::io::load(&crate::testdata::data_path("horse/horse.ply"))?;
    target.repair()?;
    let params = weathering::Params {
        working_vertices: n,
        method,
        ..weathering::Params::default()
    };
    let t = Instant::now();
    let input = weathering::Input {
        source: &source,
        target: &target,
        source_mask: None,
    };
    let out = weathering::run(&input, &params, &|_| {}, &CancelToken::new())?;
    Ok(SystemRow {
        case: format!("weather spot -> horse, {method:?}").to_lowercase(),
        vertices: out.target.mesh.num_vertices(),
        stages: out
            .timings
            .iter()
            .map(|(k, s)| (k.to_string(), *s))
            .collect(),
        total_s: t.elapsed().as_secs_f64(),
        faces: 0,
        peak_rss_mb: peak_rss_mb(),
    })
}

/// Multi-rule weathering recipes (`synthesis::weathering::recipes`) transferred cow -> cat and
/// igea -> bunny at `n` points with the default parameters: per recipe, the correlation of L*,
/// a*, b* with the recipe applied to the target, the Lab W1 distance and the grain kept, and the
/// k-nearest-neighbour floor beside (`meshmatch bench --system weather-recipes`).
pub fn weather_recipe_rows(n: usize, json: bool) -> Result<()> {
    use crate::synthesis::weathering::{self, recipes};
    let cancel = CancelToken::new();
    for (s, t) in [
        ("cow/cow.ply", "cat/cat.obj"),
        ("igea/igea.ply", "bunny/bunny.obj"),
    ] {
        let load = |p: &str| -> Result<crate::mesh::TriMesh> {
            let mut m = crate::mesh::io::load(&crate::testdata::data_path(p))?;
            m.repair()?;
            Ok(m)
        };
        let pair = recipes::prepare(&load(s)?, &load(t)?, n, weathering::Up::Y, &cancel)?;
        for r in recipes::recipes() {
            let e = recipes::evaluate(&pair, &r, &weathering::Params::default(), &cancel)?;
            if json {
                println!(
                    "{}",
                    serde_json::json!({"pair": format!("{s} -> {t}"), "recipe": r.name,
                        "points": n, "method": e.method, "knn": e.knn, "seconds": e.seconds})
                );
            } else {
                let f = |x: &recipes::Scores| {
                    format!(
                        "L {:.2} a {:.2} b {:.2} W1 {:.2} grain {:.2}",
                        x.corr[0], x.corr[1], x.corr[2], x.w1, x.grain
                    )
                };
                println!(
                    "weather {s} -> {t} {:<8} {n} pts: {} | kNN floor {} | {:.1} s",
                    r.name,
                    f(&e.method),
                    f(&e.knn),
                    e.seconds
                );
            }
        }
    }
    Ok(())
}

/// Every feature map (`features MESH --out X.png --feature all`) of a shared mesh baked at
/// `size²`: Spot through its own UVs, the bunny through a generated atlas.
pub fn feature_map_rows(size: u32) -> Result<Vec<SystemRow>> {
    use crate::synthesis::weathering::feature_maps::{MAP_NAMES, MapParams, bake_feature_maps};
    let mut rows = Vec::new();
    for (name, rel) in [
        ("Spot (own UVs)", "spot/spot.obj"),
        ("bunny (atlas)", "bunny/bunny.obj"),
    ] {
        let mut mesh = crate::mesh::io::load(&crate::testdata::data_path(rel))?;
        mesh.repair()?;
        let p = MapParams {
            texture_size: size,
            ..MapParams::default()
        };
        let t = Instant::now();
        let maps = bake_feature_maps(&mesh, &MAP_NAMES, &p, &|_| {}, &CancelToken::new())?;
        rows.push(SystemRow {
            case: format!(
                "feature maps: {name}, all {} at {size}², {}",
                maps.maps.len(),
                if maps.atlas.is_some() {
                    "atlas generated"
                } else {
                    "own UVs"
                }
            ),
            vertices: mesh.num_vertices(),
            stages: Vec::new(),
            total_s: t.elapsed().as_secs_f64(),
            faces: 0,
            peak_rss_mb: peak_rss_mb(),
        });
    }
    Ok(rows)
}
