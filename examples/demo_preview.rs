//! Render the demo scene's meshes to PNG previews with a tiny software rasterizer
//! (orthographic, z-buffered, vertex colours, Lambert shading in linear light).
//!
//! Usage: `cargo run --release --no-default-features --example demo_preview [OUT_DIR]`
//! (default `/tmp/demo_preview`).

mod common;

use glam::Vec3;
use meshmatch::TriMesh;
use std::path::PathBuf;

/// `mesh` seen from direction `eye` (from the object to the camera), `w` x `h`, back faces red.
fn render(mesh: &TriMesh, eye: Vec3, (w, h): (u32, u32)) -> image::RgbImage {
    let normals = mesh
        .normals
        .clone()
        .unwrap_or_else(|| meshmatch::geometry::vertex_normals(&mesh.positions, &mesh.faces));
    common::render(
        &mesh.positions,
        &mesh.faces,
        Some(
            mesh.colors
                .as_deref()
                .unwrap_or(&vec![[0.78, 0.74, 0.66]; mesh.num_vertices()]),
        ),
        Some(&normals),
        common::look_from(eye),
        (w, h),
        common::Look {
            background: [220, 220, 215],
            flag_back_faces: true,
        },
    )
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
            image::imageops::replace(
                &mut img,
                &render(mesh, *v, (w, h)),
                (i as u32 * w) as i64,
                0,
            );
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
    let mut head = scene.zebra.clone();
    let keep: Vec<bool> = head
        .positions
        .iter()
        .map(|p| p[0] > 0.35 && p[1] > 0.95)
        .collect();
    head.faces.retain(|f| f.iter().all(|&v| keep[v as usize]));
    render(&head_only(&head), Vec3::new(0.6, 0.3, -1.0), (w, h))
        .save(dir.join("zebra_head.png"))
        .expect("write png");
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
