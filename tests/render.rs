//! Offscreen rendering: a coloured mesh renders to a PNG that shows its colours.
#![cfg(feature = "gui")]

use meshmatch::TriMesh;
use meshmatch::render::{RenderOptions, render_image, render_to_png};

/// A UV sphere of radius 1 centred at the origin.
fn sphere(rings: u32, segments: u32) -> TriMesh {
    let mut positions = vec![[0.0, 1.0, 0.0]];
    for r in 1..rings {
        let theta = std::f32::consts::PI * r as f32 / rings as f32;
        for s in 0..segments {
            let phi = 2.0 * std::f32::consts::PI * s as f32 / segments as f32;
            positions.push([
                theta.sin() * phi.cos(),
                theta.cos(),
                theta.sin() * phi.sin(),
            ]);
        }
    }
    positions.push([0.0, -1.0, 0.0]);
    let south = positions.len() as u32 - 1;
    let idx = |r: u32, s: u32| 1 + (r - 1) * segments + (s % segments);
    let mut faces = Vec::new();
    for s in 0..segments {
        faces.push([0, idx(1, s + 1), idx(1, s)]);
        faces.push([south, idx(rings - 1, s), idx(rings - 1, s + 1)]);
    }
    for r in 1..rings - 1 {
        for s in 0..segments {
            faces.push([idx(r, s), idx(r, s + 1), idx(r + 1, s + 1)]);
            faces.push([idx(r, s), idx(r + 1, s + 1), idx(r + 1, s)]);
        }
    }
    TriMesh::new(positions, faces)
}

fn half_red_half_blue(mesh: &TriMesh) -> Vec<[f32; 3]> {
    mesh.positions
        .iter()
        .map(|p| {
            if p[0] > 0.0 {
                [1.0, 0.0, 0.0]
            } else {
                [0.0, 0.0, 1.0]
            }
        })
        .collect()
}

fn is_red(p: &image::Rgba<u8>) -> bool {
    p[0] > 120 && p[1] < 40 && p[2] < 40
}
fn is_blue(p: &image::Rgba<u8>) -> bool {
    p[2] > 120 && p[0] < 40 && p[1] < 40
}

#[test]
fn half_red_half_blue_sphere_renders_both_colours_on_background() {
    let mesh = sphere(32, 64);
    let colors = half_red_half_blue(&mesh);
    let dir = std::env::temp_dir().join(format!("meshmatch_render_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let out = dir.join("sphere.png");
    let opts = RenderOptions {
        azimuth_deg: 0.0,
        elevation_deg: 0.0,
        width: 160,
        height: 120,
        wireframe: false,
    };
    render_to_png(&mesh, Some(&colors), &opts, &out).expect("render");
    let img = image::open(&out).expect("png").to_rgba8();
    assert_eq!(img.dimensions(), (160, 120));
    // Seen from +Z with +Y up, +X is on the right: red right of centre, blue left of it.
    assert!(
        is_red(img.get_pixel(100, 60)),
        "{:?}",
        img.get_pixel(100, 60)
    );
    assert!(
        is_blue(img.get_pixel(60, 60)),
        "{:?}",
        img.get_pixel(60, 60)
    );
    let red = img.pixels().filter(|p| is_red(p)).count();
    let blue = img.pixels().filter(|p| is_blue(p)).count();
    assert!(red > 1500 && blue > 1500, "red {red} blue {blue}");
    let ratio = red as f64 / blue as f64;
    assert!((0.8..1.25).contains(&ratio), "red/blue {ratio}");
    // Corners are background: neither colour, all the same.
    let bg = *img.get_pixel(0, 0);
    for (x, y) in [(159, 0), (0, 119), (159, 119), (5, 60)] {
        assert_eq!(*img.get_pixel(x, y), bg);
    }
    assert!(!is_red(&bg) && !is_blue(&bg));
    // Headlight shading: the silhouette is darker than the centre of each half.
    let centre_red = img.get_pixel(95, 60)[0];
    let edge_red = (80..160)
        .rev()
        .map(|x| img.get_pixel(x, 60))
        .find(|p| is_red(p))
        .unwrap()[0];
    assert!(edge_red < centre_red, "edge {edge_red} centre {centre_red}");
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn wireframe_draws_dark_edges_and_view_angle_changes_the_picture() {
    let mesh = sphere(8, 12);
    let colors = vec![[1.0, 1.0, 1.0]; mesh.positions.len()];
    let base = RenderOptions {
        azimuth_deg: 0.0,
        elevation_deg: 0.0,
        width: 128,
        height: 128,
        wireframe: false,
    };
    let plain = render_image(&mesh, Some(&colors), &base).unwrap();
    let wire = render_image(
        &mesh,
        Some(&colors),
        &RenderOptions {
            wireframe: true,
            ..base.clone()
        },
    )
    .unwrap();
    let dark = |img: &image::RgbaImage| {
        img.enumerate_pixels()
            .filter(|(x, y, _)| (*x as i32 - 64).pow(2) + (*y as i32 - 64).pow(2) < 30 * 30)
            .filter(|(_, _, p)| p[0] < 150)
            .count()
    };
    assert_eq!(dark(&plain), 0);
    assert!(dark(&wire) > 100, "wire pixels {}", dark(&wire));
    // Half-coloured sphere seen from the -X side shows only blue.
    let colors = half_red_half_blue(&mesh);
    let side = render_image(
        &mesh,
        Some(&colors),
        &RenderOptions {
            azimuth_deg: -90.0,
            ..base
        },
    )
    .unwrap();
    let blue = side.pixels().filter(|p| is_blue(p)).count();
    let red = side.pixels().filter(|p| is_red(p)).count();
    // Only rim pixels of faces straddling x = 0 may show red.
    assert!(blue > 2000 && red * 100 < blue, "blue {blue} red {red}");
}

#[test]
fn bad_inputs_are_errors_not_panics() {
    let mesh = sphere(6, 8);
    let opts = RenderOptions::default();
    assert!(render_image(&mesh, Some(&[[1.0, 0.0, 0.0]]), &opts).is_err());
    let empty = TriMesh::new(vec![], vec![]);
    assert!(render_image(&empty, None, &opts).is_err());
    let zero = RenderOptions { width: 0, ..opts };
    assert!(render_image(&mesh, None, &zero).is_err());
}
