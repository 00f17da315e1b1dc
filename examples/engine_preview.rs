//! Preview MeshMatch transfers as PNGs with a tiny software rasteriser (no GPU needed):
//! `cargo run --release --no-default-features --example engine_preview -- [vertices] [outdir]`.
//! Transfers Spot's texture onto the horse and the cow and renders source and results from
//! several views.

use glam::{Mat3, Vec3};
use meshmatch::TriMesh;
use meshmatch::meshmatch::{TransferParams, prepare, solve};
use meshmatch::work::{CancelToken, Event};
use std::path::{Path, PathBuf};

/// Render a vertex-coloured mesh orthographically, looking along `-dir` with `up`, Lambert-shaded.
fn render(
    positions: &[[f32; 3]],
    faces: &[[u32; 3]],
    colors: &[[f32; 3]],
    rot: Mat3,
    size: u32,
) -> image::RgbImage {
    let pts: Vec<Vec3> = positions.iter().map(|p| rot * Vec3::from(*p)).collect();
    let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
    for p in &pts {
        lo = lo.min(*p);
        hi = hi.max(*p);
    }
    let c = 0.5 * (lo + hi);
    let ext = (hi - lo).x.max((hi - lo).y) * 1.05;
    let s = size as f32 / ext;
    let proj = |p: Vec3| {
        Vec3::new(
            (p.x - c.x) * s + size as f32 / 2.0,
            (c.y - p.y) * s + size as f32 / 2.0,
            p.z,
        )
    };
    let mut img = image::RgbImage::from_pixel(size, size, image::Rgb([235, 235, 240]));
    let mut z = vec![f32::NEG_INFINITY; (size * size) as usize];
    let light = Vec3::new(0.3, 0.5, 1.0).normalize();
    for f in faces {
        let [a, b, cc] = f.map(|i| proj(pts[i as usize]));
        let n = (pts[f[1] as usize] - pts[f[0] as usize])
            .cross(pts[f[2] as usize] - pts[f[0] as usize])
            .normalize_or_zero();
        let shade = 0.35 + 0.65 * n.dot(light).abs();
        let det = (b.x - a.x) * (cc.y - a.y) - (cc.x - a.x) * (b.y - a.y);
        if det.abs() < 1e-9 {
            continue;
        }
        let x0 = a.x.min(b.x).min(cc.x).floor().max(0.0) as u32;
        let x1 = (a.x.max(b.x).max(cc.x).ceil() as u32).min(size - 1);
        let y0 = a.y.min(b.y).min(cc.y).floor().max(0.0) as u32;
        let y1 = (a.y.max(b.y).max(cc.y).ceil() as u32).min(size - 1);
        for y in y0..=y1 {
            for x in x0..=x1 {
                let (px, py) = (x as f32 + 0.5, y as f32 + 0.5);
                let w1 = ((px - a.x) * (cc.y - a.y) - (cc.x - a.x) * (py - a.y)) / det;
                let w2 = ((b.x - a.x) * (py - a.y) - (px - a.x) * (b.y - a.y)) / det;
                let w0 = 1.0 - w1 - w2;
                if w0 < 0.0 || w1 < 0.0 || w2 < 0.0 {
                    continue;
                }
                let depth = w0 * a.z + w1 * b.z + w2 * cc.z;
                let i = (y * size + x) as usize;
                if depth <= z[i] {
                    continue;
                }
                z[i] = depth;
                let col = [0, 1, 2].map(|k| {
                    let v = w0 * colors[f[0] as usize][k]
                        + w1 * colors[f[1] as usize][k]
                        + w2 * colors[f[2] as usize][k];
                    ((v * shade).clamp(0.0, 1.0) * 255.0) as u8
                });
                img.put_pixel(x, y, image::Rgb(col));
            }
        }
    }
    img
}

fn views(
    positions: &[[f32; 3]],
    faces: &[[u32; 3]],
    colors: &[[f32; 3]],
    up_fix: Mat3,
) -> image::RgbImage {
    let size = 400;
    let mut out = image::RgbImage::new(size * 3, size);
    for (k, yaw) in [0.6f32, 2.2, -1.6].iter().enumerate() {
        let rot = Mat3::from_rotation_x(0.25) * Mat3::from_rotation_y(*yaw) * up_fix;
        let img = render(positions, faces, colors, rot, size);
        image::imageops::replace(&mut out, &img, (k as u32 * size) as i64, 0);
    }
    out
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
    views(
        &w.positions,
        &w.faces,
        w.colors.as_ref().unwrap(),
        Mat3::IDENTITY,
    )
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
        views(&tw.positions, &tw.faces, &r.working_signal, Mat3::IDENTITY)
            .save(outdir.join(format!("spot_to_{name}.png")))
            .unwrap();
        let mut colored = tw.clone();
        colored.colors = Some(r.working_signal.clone());
        meshmatch::mesh::io::save(&colored, &outdir.join(format!("spot_to_{name}.ply")))?;
    }
    let _ = Path::new(".");
    Ok(())
}
