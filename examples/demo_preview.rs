//! Render the demo scene's meshes to PNG previews with a tiny software rasterizer
//! (orthographic, z-buffered, vertex colours, Lambert shading in linear light).
//!
//! Usage: `cargo run --release --no-default-features --example demo_preview [OUT_DIR]`
//! (default `/tmp/demo_preview`).

use glam::Vec3;
use meshmatch::TriMesh;
use meshmatch::color::{linear_to_srgb, srgb_to_linear};
use std::path::PathBuf;

/// Render `mesh` seen from direction `eye_dir` (pointing from the object to the camera) into a
/// `w` x `h` RGB buffer region starting at column `x0` of `img`.
fn render(mesh: &TriMesh, eye_dir: Vec3, img: &mut image::RgbImage, x0: u32, w: u32, h: u32) {
    let fwd = -eye_dir.normalize();
    let right = fwd.cross(Vec3::Y).normalize();
    let up = right.cross(fwd);
    let (lo, hi) = mesh.bounds().expect("non-empty mesh");
    let (lo, hi) = (Vec3::from(lo), Vec3::from(hi));
    let centre = (lo + hi) * 0.5;
    let radius = (hi - lo).length() * 0.5;
    let scale = 0.96 * (w.min(h) as f32) / (2.0 * radius);
    let proj = |p: Vec3| {
        let d = p - centre;
        Vec3::new(
            w as f32 * 0.5 + d.dot(right) * scale,
            h as f32 * 0.5 - d.dot(up) * scale,
            d.dot(fwd),
        )
    };
    let normals = mesh
        .normals
        .clone()
        .unwrap_or_else(|| meshmatch::geometry::vertex_normals(&mesh.positions, &mesh.faces));
    let light =
        (Vec3::new(0.0, 1.0, 0.0) * 0.8 + eye_dir.normalize() * 0.6 + right * -0.5).normalize();
    let base = [0.78f32, 0.74, 0.66];
    let sp: Vec<Vec3> = mesh
        .positions
        .iter()
        .map(|&p| proj(Vec3::from(p)))
        .collect();
    let mut zbuf = vec![f32::INFINITY; (w * h) as usize];
    // Background.
    for y in 0..h {
        for x in 0..w {
            let g = 0.92 - 0.18 * y as f32 / h as f32;
            img.put_pixel(
                x0 + x,
                y,
                image::Rgb([(g * 255.0) as u8, (g * 255.0) as u8, (g * 250.0) as u8]),
            );
        }
    }
    for f in &mesh.faces {
        let [a, b, c] = f.map(|i| sp[i as usize]);
        let area = (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
        if area.abs() < 1e-12 {
            continue;
        }
        let minx = a.x.min(b.x).min(c.x).floor().max(0.0) as i32;
        let maxx = a.x.max(b.x).max(c.x).ceil().min(w as f32 - 1.0) as i32;
        let miny = a.y.min(b.y).min(c.y).floor().max(0.0) as i32;
        let maxy = a.y.max(b.y).max(c.y).ceil().min(h as f32 - 1.0) as i32;
        for py in miny..=maxy {
            for px in minx..=maxx {
                let (x, y) = (px as f32 + 0.5, py as f32 + 0.5);
                let w0 = ((b.x - x) * (c.y - y) - (b.y - y) * (c.x - x)) / area;
                let w1 = ((c.x - x) * (a.y - y) - (c.y - y) * (a.x - x)) / area;
                let w2 = 1.0 - w0 - w1;
                if w0 < 0.0 || w1 < 0.0 || w2 < 0.0 {
                    continue;
                }
                let z = w0 * a.z + w1 * b.z + w2 * c.z;
                let idx = (py as u32 * w + px as u32) as usize;
                if z >= zbuf[idx] {
                    continue;
                }
                zbuf[idx] = z;
                let n = (Vec3::from(normals[f[0] as usize]) * w0
                    + Vec3::from(normals[f[1] as usize]) * w1
                    + Vec3::from(normals[f[2] as usize]) * w2)
                    .normalize_or_zero();
                let col = match &mesh.colors {
                    Some(c) => {
                        let [c0, c1, c2] = f.map(|i| c[i as usize]);
                        std::array::from_fn(|k| c0[k] * w0 + c1[k] * w1 + c2[k] * w2)
                    }
                    None => base,
                };
                // Back faces (seen from inside) show red so orientation errors are visible.
                let facing = n.dot(eye_dir);
                let lam = 0.22 + 0.78 * n.dot(light).max(0.0);
                let rgb: [f32; 3] = if facing < -0.2 {
                    [1.0, 0.0, 0.0]
                } else {
                    col.map(|c| linear_to_srgb(srgb_to_linear(c) * lam))
                };
                img.put_pixel(
                    x0 + px as u32,
                    py as u32,
                    image::Rgb(rgb.map(|c| (c * 255.0).round() as u8)),
                );
            }
        }
    }
}

fn main() {
    let dir = PathBuf::from(
        std::env::args()
            .nth(1)
            .unwrap_or_else(|| "/tmp/demo_preview".into()),
    );
    std::fs::create_dir_all(&dir).expect("create output dir");
    let t = std::time::Instant::now();
    let scene = meshmatch::demo::scene();
    println!("scene() in {:.3} s", t.elapsed().as_secs_f64());
    let views = [
        ("three_quarter", Vec3::new(1.0, 0.45, -1.1)),
        ("side", Vec3::new(0.0, 0.1, -1.0)),
        ("back_right", Vec3::new(-1.0, 0.5, 1.0)),
    ];
    let (w, h) = (800u32, 800u32);
    for (name, mesh) in [
        ("zebra", &scene.zebra),
        ("giraffe", &scene.giraffe),
        ("cerberus", &scene.cerberus),
        ("vase", &scene.vase),
    ] {
        let mut img = image::RgbImage::new(w * views.len() as u32, h);
        for (i, (_, v)) in views.iter().enumerate() {
            render(mesh, *v, &mut img, i as u32 * w, w, h);
        }
        let flipped = img.pixels().filter(|p| p.0 == [255, 0, 0]).count();
        println!("{name}: {flipped} pixels show a back-facing normal");
        let path = dir.join(format!("{name}.png"));
        img.save(&path).expect("write png");
        println!(
            "{name}: {} vertices, {} faces -> {}",
            mesh.num_vertices(),
            mesh.num_faces(),
            path.display()
        );
    }
    // Close-up of the zebra's head and neck.
    let mut img = image::RgbImage::new(w, h);
    let mut head = scene.zebra.clone();
    let keep: Vec<bool> = head
        .positions
        .iter()
        .map(|p| p[0] > 0.35 && p[1] > 0.95)
        .collect();
    head.faces.retain(|f| f.iter().all(|&v| keep[v as usize]));
    render(
        &head_only(&head),
        Vec3::new(0.6, 0.3, -1.0),
        &mut img,
        0,
        w,
        h,
    );
    img.save(dir.join("zebra_head.png")).expect("write png");
}

/// The faces of `m` with only their referenced vertices (so bounds fit the kept part).
fn head_only(m: &TriMesh) -> TriMesh {
    let mut remap = vec![u32::MAX; m.num_vertices()];
    let mut pos = Vec::new();
    let mut col = Vec::new();
    let mut nrm = Vec::new();
    for f in &m.faces {
        for &v in f {
            if remap[v as usize] == u32::MAX {
                remap[v as usize] = pos.len() as u32;
                pos.push(m.positions[v as usize]);
                col.push(m.colors.as_ref().map(|c| c[v as usize]).unwrap_or([0.8; 3]));
                nrm.push(
                    m.normals
                        .as_ref()
                        .map(|c| c[v as usize])
                        .unwrap_or([0.0, 1.0, 0.0]),
                );
            }
        }
    }
    let faces = m
        .faces
        .iter()
        .map(|f| f.map(|v| remap[v as usize]))
        .collect();
    let mut out = TriMesh::new(pos, faces);
    out.colors = Some(col);
    out.normals = Some(nrm);
    out
}
