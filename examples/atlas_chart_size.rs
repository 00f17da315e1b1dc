//! What the atlas's chart-size cap (`AtlasParams::max_chart_faces`) buys and costs: for shared
//! meshes of growing density, the atlas for a 2048² texture without a cap and with caps of 8192,
//! 4096 and 2048 faces per chart: charts, the fraction of the texture covered, texels per unit
//! of surface length, and the time. `cargo run --release --example atlas_chart_size`
//! (`MESH=igea/igea.ply` for one mesh).
use std::time::Instant;

use meshmatch::geometry::{AtlasParams, uv_atlas};
use meshmatch::work::CancelToken;

fn main() {
    let only = std::env::var("MESH").ok();
    for name in [
        "bunny/bunny.obj",
        "spot/spot.obj",
        "penguin/penguin.obj",
        "horse/horse.ply",
        "igea/igea.ply",
    ] {
        if only.as_deref().is_some_and(|o| o != name) {
            continue;
        }
        let path = meshmatch::testdata::data_path(name);
        let Ok(mut mesh) = meshmatch::mesh::io::load(&path) else {
            eprintln!("skipping {}: not found", path.display());
            continue;
        };
        mesh.repair().expect("repair");
        for cap in [0usize, 8192, 4096, 2048] {
            let params = AtlasParams {
                max_chart_faces: cap,
                ..AtlasParams::default()
            };
            let t = Instant::now();
            let a = uv_atlas(
                &mesh.positions,
                &mesh.faces,
                &params,
                &|_| {},
                &CancelToken::new(),
            )
            .expect("atlas");
            println!(
                "{name}: {} faces, cap {}: {} charts, {:.1}% of the texture covered, {:.0} texels per unit, {:.2} s",
                mesh.faces.len(),
                if cap == 0 {
                    "none".to_string()
                } else {
                    cap.to_string()
                },
                a.charts,
                100.0 * a.utilization,
                a.texels_per_unit,
                t.elapsed().as_secs_f64()
            );
        }
    }
}
