//! Synthesize an exemplar over a mesh and render it to PNG with a tiny software rasterizer.
//!
//! `cargo run --release --no-default-features --example synth_preview -- EXEMPLAR MESH.obj|sphere
//!  OUT.png [--size 64] [--scale S] [--orientation random|up|relax2|relax4] [--search fast|exhaustive]
//!  [--levels 4] [--seed N] [--displace] [--measure]`

mod common;

use std::path::Path;

use glam::Mat3;
use meshmatch::TriMesh;
use meshmatch::synthesis::{SynthParams, synthesize};
use meshmatch::work::{CancelToken, no_events};

/// Icosphere: icosahedron subdivided `n` times, projected to the unit sphere.
fn icosphere(n: usize) -> TriMesh {
    let (p, f) = meshmatch::testdata::icosphere(n);
    TriMesh::new(p, f)
}

/// Vertex colours seen from each of `yaws`, tilted down, side by side.
fn render(mesh: &TriMesh, colors: &[[f32; 3]], size: u32, yaws: &[f32]) -> image::RgbImage {
    let turns: Vec<Mat3> = yaws
        .iter()
        .map(|&yaw| Mat3::from_rotation_x(-0.35) * Mat3::from_rotation_y(yaw))
        .collect();
    common::side_by_side(
        &mesh.positions,
        &mesh.faces,
        Some(colors),
        mesh.normals.as_deref(),
        &turns,
        size,
        common::Look {
            background: [40, 40, 48],
            flag_back_faces: false,
        },
    )
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
