//! Render coloured PLY/OBJ meshes to PNG previews with a tiny software rasteriser (no GPU):
//! `cargo run --release --no-default-features --example apps_preview -- OUTDIR MESH...`
//! writes OUTDIR/<mesh stem>.png with three views of each mesh (vertex colours, or grey).

use glam::Mat3;
use glam::Vec3;
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

fn main() -> meshmatch::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let outdir = PathBuf::from(args.get(1).cloned().unwrap_or("/tmp/apps_preview".into()));
    std::fs::create_dir_all(&outdir).map_err(|e| meshmatch::Error::io(&outdir, e))?;
    for p in &args[2.min(args.len())..] {
        let path = Path::new(p);
        let mesh = meshmatch::mesh::io::load(path)?;
        let cols = mesh
            .vertex_signal()
            .unwrap_or_else(|| vec![[0.8, 0.8, 0.8]; mesh.num_vertices()]);
        let stem = path.file_stem().and_then(|s| s.to_str()).unwrap_or("mesh");
        let out = outdir.join(format!("{stem}.png"));
        views(&mesh.positions, &mesh.faces, &cols, Mat3::IDENTITY)
            .save(&out)
            .map_err(|e| meshmatch::Error::InvalidInput(e.to_string()))?;
        println!("{}", out.display());
    }
    Ok(())
}
