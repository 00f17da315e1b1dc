//! Synthesize an exemplar over a mesh and render it to PNG with a tiny software rasterizer.
//!
//! `cargo run --release --no-default-features --example synth_preview -- EXEMPLAR MESH.obj|sphere
//!  OUT.png [--size 64] [--scale S] [--orientation random|up|relax2|relax4] [--search fast|exhaustive]
//!  [--levels 4] [--seed N] [--displace] [--measure]`

use std::path::Path;

use glam::{Mat3, Vec3};
use meshmatch::TriMesh;
use meshmatch::synthesis::{SynthParams, synthesize};
use meshmatch::work::{CancelToken, no_events};

/// Icosphere: icosahedron subdivided `n` times, projected to the unit sphere.
fn icosphere(n: usize) -> TriMesh {
    let (p, f) = meshmatch::testdata::icosphere(n);
    TriMesh::new(p, f)
}

/// Render vertex colours with Lambert shading from `views` yaw angles side by side.
fn render(mesh: &TriMesh, colors: &[[f32; 3]], size: u32, yaws: &[f32]) -> image::RgbImage {
    let (lo, hi) = mesh.bounds().unwrap();
    let c = (Vec3::from(lo) + Vec3::from(hi)) * 0.5;
    let r = (Vec3::from(hi) - Vec3::from(lo)).length() * 0.5;
    let mut img =
        image::RgbImage::from_pixel(size * yaws.len() as u32, size, image::Rgb([40, 40, 48]));
    let normals = mesh
        .normals
        .clone()
        .unwrap_or_else(|| vec![[0.0, 0.0, 1.0]; mesh.num_vertices()]);
    for (vi, &yaw) in yaws.iter().enumerate() {
        let rot = Mat3::from_rotation_x(-0.35) * Mat3::from_rotation_y(yaw);
        let s = size as f32;
        let proj: Vec<Vec3> = mesh
            .positions
            .iter()
            .map(|p| {
                let q = rot * ((Vec3::from(*p) - c) / r);
                Vec3::new(
                    (q.x * 0.95 + 1.0) * 0.5 * s,
                    (1.0 - q.y * 0.95) * 0.5 * s,
                    q.z,
                )
            })
            .collect();
        let light = Vec3::new(0.3, 0.5, 1.0).normalize();
        let shade: Vec<Vec3> = normals
            .iter()
            .zip(colors)
            .map(|(n, col)| {
                let l = (rot * Vec3::from(*n)).dot(light).abs();
                Vec3::from(*col) * (0.35 + 0.65 * l)
            })
            .collect();
        let mut zb = vec![f32::NEG_INFINITY; (size * size) as usize];
        for f in &mesh.faces {
            let [a, b, cc] = f.map(|i| proj[i as usize]);
            let area = (b.x - a.x) * (cc.y - a.y) - (b.y - a.y) * (cc.x - a.x);
            if area.abs() < 1e-12 {
                continue;
            }
            let x0 = a.x.min(b.x).min(cc.x).floor().max(0.0) as i32;
            let x1 = a.x.max(b.x).max(cc.x).ceil().min(s - 1.0) as i32;
            let y0 = a.y.min(b.y).min(cc.y).floor().max(0.0) as i32;
            let y1 = a.y.max(b.y).max(cc.y).ceil().min(s - 1.0) as i32;
            for y in y0..=y1 {
                for x in x0..=x1 {
                    let (px, py) = (x as f32 + 0.5, y as f32 + 0.5);
                    let w0 = ((b.x - px) * (cc.y - py) - (b.y - py) * (cc.x - px)) / area;
                    let w1 = ((cc.x - px) * (a.y - py) - (cc.y - py) * (a.x - px)) / area;
                    let w2 = 1.0 - w0 - w1;
                    if w0 < 0.0 || w1 < 0.0 || w2 < 0.0 {
                        continue;
                    }
                    let z = w0 * a.z + w1 * b.z + w2 * cc.z;
                    let k = (y as u32 * size + x as u32) as usize;
                    if z > zb[k] {
                        zb[k] = z;
                        let col = shade[f[0] as usize] * w0
                            + shade[f[1] as usize] * w1
                            + shade[f[2] as usize] * w2;
                        let px = col.to_array().map(|v| (v.clamp(0.0, 1.0) * 255.0) as u8);
                        img.put_pixel(vi as u32 * size + x as u32, y as u32, image::Rgb(px));
                    }
                }
            }
        }
    }
    img
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if args.len() < 4 {
        eprintln!("usage: synth_preview EXEMPLAR MESH|sphere OUT.png [options]");
        std::process::exit(2);
    }
    let mut params = SynthParams::default();
    let mut size = 64u32;
    let mut measure = false;
    let mut i = 4;
    while i < args.len() {
        let v = args.get(i + 1).cloned().unwrap_or_default();
        match args[i].as_str() {
            "--size" => size = v.parse().unwrap(),
            "--scale" => params.scale = Some(v.parse().unwrap()),
            "--orientation" => params.orientation = v.parse().unwrap(),
            "--search" => params.search = v.parse().unwrap(),
            "--levels" => params.levels = v.parse().unwrap(),
            "--seed" => params.seed = v.parse().unwrap(),
            "--measure" => {
                measure = true;
                i += 1;
                continue;
            }
            "--displace" => {
                params.displace = true;
                i += 1;
                continue;
            }
            o => panic!("unknown option {o}"),
        }
        i += 2;
    }
    let ex = if args[1] == "stripes" {
        image::RgbImage::from_fn(size, size, |x, y| {
            let s = ((x as f32 + 0.3 * y as f32) * std::f32::consts::TAU / 8.0).sin();
            if s > 0.0 {
                image::Rgb([220, 200, 60])
            } else {
                image::Rgb([40, 50, 120])
            }
        })
    } else {
        let img = image::open(&args[1]).expect("exemplar").to_rgb8();
        image::imageops::resize(&img, size, size, image::imageops::FilterType::Triangle)
    };
    let target = if args[2] == "sphere" {
        icosphere(3)
    } else {
        meshmatch::mesh::io::load(Path::new(&args[2])).expect("load mesh")
    };
    let res =
        synthesize(&ex, &target, None, &params, &no_events, &CancelToken::new()).expect("synth");
    println!(
        "vertices per level {:?}, d = {:.5}, spacing = {:.5}, energy {:?}, timings {:?}",
        res.level_vertices, res.mesh_d, res.spacing, res.level_energy, res.timings
    );
    if measure {
        use meshmatch::synthesis::exemplar::{exemplar_loo_distance, neighbourhood_distance};
        let d = neighbourhood_distance(&ex, &res.mesh, &res.orientation, res.spacing, 7, 1000, 5)
            .expect("measure");
        let loo = exemplar_loo_distance(&ex, 7, 3, 1000, 5);
        println!(
            "7x7 neighbourhood distance {d:.5}, exemplar leave-one-out {loo:.5}, ratio {:.2}",
            d / loo
        );
    }
    let colors = res.mesh.colors.clone().unwrap();
    let mut img = render(&res.mesh, &colors, 400, &[0.0, 1.9, 3.6]);
    let big = image::imageops::resize(&ex, 128, 128, image::imageops::FilterType::Nearest);
    image::imageops::overlay(&mut img, &big, 0, 0);
    img.save(&args[3]).expect("save png");
}
