//! Preview MeshMatch transfers as PNGs with a tiny software rasteriser (no GPU needed):
//! `cargo run --release --no-default-features --example engine_preview -- [vertices] [outdir]`.
//! Transfers Spot's texture onto the horse and the cow and renders source and results from
//! several views.

mod common;

use meshmatch::TriMesh;
use meshmatch::meshmatch::{TransferParams, prepare, solve};
use meshmatch::work::{CancelToken, Event};
use std::path::PathBuf;

/// The three turns of a vertex-coloured mesh, side by side.
fn views(
    positions: &[[f32; 3]],
    faces: &[[u32; 3]],
    colors: Option<&[[f32; 3]]>,
) -> image::RgbImage {
    common::side_by_side(
        positions,
        faces,
        colors,
        None,
        &common::three_turns(),
        400,
        common::Look::default(),
    )
}

fn data(rel: &str) -> PathBuf {
    meshmatch::testdata::data_path(rel)
}

fn main() -> meshmatch::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let vertices: usize = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(30_000);
    let outdir = PathBuf::from(args.get(2).cloned().unwrap_or("/tmp/engine_preview".into()));
    std::fs::create_dir_all(&outdir).map_err(|e| meshmatch::Error::io(&outdir, e))?;
    let params = TransferParams {
        vertices,
        ..Default::default()
    };
    let cancel = CancelToken::new();
    let spot = meshmatch::mesh::io::load(&data("spot/spot.obj"))?;
    let t = std::time::Instant::now();
    let ps = prepare(&spot, &params, &|_| {}, &cancel)?;
    println!(
        "spot prepared in {:.2}s {:?}",
        t.elapsed().as_secs_f64(),
        ps.timings()
    );
    let w = ps.working_mesh();
    views(&w.positions, &w.faces, w.colors.as_deref())
        .save(outdir.join("spot_source.png"))
        .unwrap();
    let targets: Vec<(&str, &str)> = match args.get(3) {
        Some(list) => list
            .split(',')
            .map(|n| match n {
                "horse" => ("horse", "horse/horse.ply"),
                "cow" => ("cow", "cow/cow.ply"),
                "spot" => ("spot", "spot/spot.obj"),
                other => panic!("unknown target {other}"),
            })
            .collect(),
        None => vec![("cow", "cow/cow.ply"), ("horse", "horse/horse.ply")],
    };
    for (name, rel) in targets {
        let mesh: TriMesh = meshmatch::mesh::io::load(&data(rel))?;
        let (lo, hi) = mesh.bounds().unwrap();
        println!(
            "{name}: {} vertices, bounds {lo:?} {hi:?}",
            mesh.num_vertices()
        );
        let t = std::time::Instant::now();
        let pt = prepare(&mesh, &params, &|_| {}, &cancel)?;
        println!(
            "{name} prepared in {:.2}s {:?}",
            t.elapsed().as_secs_f64(),
            pt.timings()
        );
        let t = std::time::Instant::now();
        let sink = |e: Event| {
            if let Event::Progress(p) = e
                && p.stage == "solve"
                && p.iteration == params.iterations
            {
                println!(
                    "  level {} energy {:.4} at {:.1}s",
                    p.level, p.energy, p.elapsed
                );
            }
        };
        let r = solve(&ps, &pt, &[], &params, &sink, &cancel)?;
        println!(
            "{name} solved in {:.2}s, energy {:.4}",
            t.elapsed().as_secs_f64(),
            r.energy
        );
        for (k, v) in &r.timings {
            println!("    {k}: {v:.3}s");
        }
        let tw = pt.working_mesh();
        views(&tw.positions, &tw.faces, Some(&r.working_signal))
            .save(outdir.join(format!("spot_to_{name}.png")))
            .unwrap();
        let mut colored = tw.clone();
        colored.colors = Some(r.working_signal.clone());
        meshmatch::mesh::io::save(&colored, &outdir.join(format!("spot_to_{name}.ply")))?;
    }
    Ok(())
}
