//! Offscreen rendering: a coloured mesh renders to a PNG that shows its colours.

#![cfg(feature = "gui")]

mod scratch;
use scratch::Scratch;

use meshmatch::TriMesh;
use meshmatch::render::{
    Camera, Frame, MarkerInstance, RenderOptions, render_image, render_to_png,
};

/// A UV sphere of radius 1 centred at the origin, poles on the y axis.
fn sphere(rings: u32, segments: u32) -> TriMesh {
    let (p, f) = meshmatch::testdata::uv_sphere_y_up(rings as usize, segments as usize);
    TriMesh::new(p, f)
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
    let dir = Scratch::new("render");
    let out = dir.join("sphere.png");
    let opts = RenderOptions {
        azimuth_deg: 0.0,
        elevation_deg: 0.0,
        width: 160,
        height: 120,
        wireframe: false,
        markers: Vec::new(),
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
        markers: Vec::new(),
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
    // The wireframe is blended over the shading (45% dark edges, antialiased): edge pixels are
    // clearly darker than the same pixels without it, and the surface between edges keeps its
    // shade.
    let inner = |x: u32, y: u32| (x as i32 - 64).pow(2) + (y as i32 - 64).pow(2) < 30 * 30;
    let (mut darker, mut same, mut total) = (0, 0, 0);
    for (x, y, p) in wire.enumerate_pixels() {
        if inner(x, y) {
            total += 1;
            let q = plain.get_pixel(x, y);
            if (p[0] as i32) + 20 < q[0] as i32 {
                darker += 1;
            } else if (p[0] as i32 - q[0] as i32).abs() <= 2 {
                same += 1;
            }
        }
    }
    assert!(darker > 100, "edge pixels {darker} of {total}");
    assert!(
        same > total / 2,
        "untouched surface pixels {same} of {total}"
    );
    assert!(
        plain
            .enumerate_pixels()
            .all(|(x, y, p)| !inner(x, y) || p[0] > 150),
        "the plain white sphere has no dark pixels"
    );
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

#[test]
fn marker_spheres_show_in_front_and_faintly_through_the_mesh() {
    let mesh = sphere(32, 64);
    let grey = vec![[0.5, 0.5, 0.5]; mesh.positions.len()];
    let (s, c) = (30f32.to_radians().sin(), 30f32.to_radians().cos());
    // One marker on the side facing the camera (+Z), one on the far side.
    let front = [s, 0.0, c];
    let back = [-s, 0.0, -c];
    let marker = |center: [f32; 3], color: [f32; 3]| MarkerInstance {
        center,
        radius: 0.08,
        color,
        rim: 0.0,
    };
    let opts = RenderOptions {
        azimuth_deg: 0.0,
        elevation_deg: 0.0,
        width: 200,
        height: 160,
        wireframe: false,
        markers: vec![
            marker(front, [0.0, 0.9, 0.0]),
            marker(back, [0.9, 0.0, 0.0]),
        ],
    };
    let with = render_image(&mesh, Some(&grey), &opts).expect("render");
    let without = render_image(
        &mesh,
        Some(&grey),
        &RenderOptions {
            markers: Vec::new(),
            ..opts.clone()
        },
    )
    .expect("render");
    // Where the app's camera puts those points on screen.
    let cam = Camera {
        azimuth_deg: 0.0,
        elevation_deg: 0.0,
        ..Camera::default()
    };
    let frame = Frame::of_points(&mesh.positions);
    let size = glam::Vec2::new(200.0, 160.0);
    let px = |p: [f32; 3]| {
        let v = cam.project(&frame, glam::Vec3::from(p), size).unwrap();
        (v.x.round() as u32, v.y.round() as u32)
    };
    let rgb = |img: &image::RgbaImage, (x, y): (u32, u32)| {
        let p = img.get_pixel(x, y);
        [p[0] as i32, p[1] as i32, p[2] as i32]
    };
    // The visible marker covers the surface in its own colour.
    let f = rgb(&with, px(front));
    assert!(
        f[1] > f[0] + 80 && f[1] > f[2] + 80,
        "front marker pixel {f:?}"
    );
    let f0 = rgb(&without, px(front));
    assert!((f0[0] - f0[1]).abs() < 6, "grey surface {f0:?}");
    // The hidden marker only tints the surface in front of it.
    let b = rgb(&with, px(back));
    let b0 = rgb(&without, px(back));
    assert!((b0[0] - b0[1]).abs() < 6, "grey surface {b0:?}");
    assert!(b[0] - b[1] > 20, "hidden marker should tint red: {b:?}");
    assert!(
        b[0] - b[1] < 120,
        "hidden marker must not look unoccluded: {b:?}"
    );
}

/// A cube of 8 vertices whose six faces each carry the whole of a checkerboard texture.
fn checker_cube() -> TriMesh {
    let p: Vec<[f32; 3]> = (0..8)
        .map(|i| {
            [
                (i & 1) as f32 - 0.5,
                ((i >> 1) & 1) as f32 - 0.5,
                ((i >> 2) & 1) as f32 - 0.5,
            ]
        })
        .collect();
    // Quads as (a, b, c, d) counter-clockwise seen from outside.
    let quads = [
        [4, 5, 7, 6], // +z
        [1, 0, 2, 3], // -z
        [5, 1, 3, 7], // +x
        [0, 4, 6, 2], // -x
        [6, 7, 3, 2], // +y
        [0, 1, 5, 4], // -y
    ];
    let mut m = TriMesh::new(p, Vec::new());
    let mut uvs = Vec::new();
    let q = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
    for [a, b, c, d] in quads {
        m.faces.push([a, b, c]);
        uvs.extend([q[0], q[1], q[2]]);
        m.faces.push([a, c, d]);
        uvs.extend([q[0], q[2], q[3]]);
    }
    m.uvs = Some(uvs);
    let img = image::RgbImage::from_fn(64, 64, |x, y| {
        if (x / 8 + y / 8) % 2 == 0 {
            image::Rgb([240, 240, 240])
        } else {
            image::Rgb([20, 20, 20])
        }
    });
    m.texture = Some(std::sync::Arc::new(meshmatch::mesh::Texture {
        image: img,
        path: None,
    }));
    m
}

#[test]
fn a_checker_textured_cube_of_8_vertices_renders_its_checker_per_pixel() {
    let cube = checker_cube();
    let img = render_image(
        &cube,
        None,
        &RenderOptions {
            azimuth_deg: 0.0,
            elevation_deg: 0.0,
            width: 400,
            height: 400,
            ..Default::default()
        },
    )
    .unwrap();
    // The +z face fills the middle of the picture: light and dark squares, many transitions
    // along a row through the middle of a band of squares (8 squares across the face).
    let row = 183u32;
    let lum = |x: u32, y: u32| img.get_pixel(x, y).0[0] as i32;
    let (mut light, mut dark, mut flips) = (0, 0, 0);
    let mut prev = None;
    for x in 120..280 {
        let l = lum(x, row);
        let class = if l > 150 {
            Some(true)
        } else if l < 60 {
            Some(false)
        } else {
            None
        };
        match class {
            Some(true) => light += 1,
            Some(false) => dark += 1,
            None => {}
        }
        if class.is_some() {
            if prev.is_some() && prev != class {
                flips += 1;
            }
            prev = class;
        }
    }
    assert!(light > 40 && dark > 40, "light {light}, dark {dark}");
    assert!(flips >= 5, "{flips} light/dark transitions across the face");
}

#[test]
fn textures_of_any_size_render_not_only_powers_of_two() {
    // a texture's mip chain must have the GPU's level count and sizes (100 -> 50 -> 25 -> 12
    // ...): a chain that rounded odd sides up had one level too many for 100², 3², 354 x 352
    for (w, h) in [(100u32, 100u32), (354, 352), (3, 3), (300, 1), (1000, 1000)] {
        let mut cube = checker_cube();
        cube.texture = Some(std::sync::Arc::new(meshmatch::mesh::Texture {
            image: image::RgbImage::from_fn(w, h, |x, y| {
                if (8 * x / w + 8 * y / h.max(8)) % 2 == 0 {
                    image::Rgb([240, 240, 240])
                } else {
                    image::Rgb([20, 20, 20])
                }
            }),
            path: None,
        }));
        let img = render_image(
            &cube,
            None,
            &RenderOptions {
                azimuth_deg: 0.0,
                elevation_deg: 0.0,
                width: 200,
                height: 200,
                ..Default::default()
            },
        )
        .unwrap_or_else(|e| panic!("a {w} x {h} texture: {e}"));
        // the +z face shows the texture: light and dark squares along its middle row
        let row: Vec<u8> = (60..140).map(|x| img.get_pixel(x, 100).0[0]).collect();
        let (lo, hi) = (row.iter().min().unwrap(), row.iter().max().unwrap());
        assert!(
            *hi > 150 && (w < 8 || hi - lo > 80),
            "a {w} x {h} texture: row {row:?}"
        );
    }
}

#[test]
fn mip_chains_have_the_gpu_level_sizes() {
    for (w, h) in [
        (100u32, 100u32),
        (354, 352),
        (3, 3),
        (300, 1),
        (64, 64),
        (1, 1),
    ] {
        let img = image::RgbaImage::new(w, h);
        let chain = meshmatch::geometry::mip_chain(&img);
        let levels = 32 - w.max(h).leading_zeros();
        assert_eq!(chain.len() as u32, levels, "{w} x {h}");
        for (l, m) in chain.iter().enumerate() {
            assert_eq!(
                m.dimensions(),
                ((w >> l).max(1), (h >> l).max(1)),
                "{w} x {h}, level {l}"
            );
        }
    }
}

#[test]
fn a_cube_draws_flat_faces_with_sharp_edges() {
    let mut cube = checker_cube();
    cube.texture = None;
    cube.uvs = None;
    let white = vec![[1.0f32; 3]; 8];
    let img = render_image(
        &cube,
        Some(&white),
        &RenderOptions {
            azimuth_deg: 30.0,
            elevation_deg: 25.0,
            width: 400,
            height: 400,
            ..Default::default()
        },
    )
    .unwrap();
    // Three faces show, each flat-shaded: along a row through the middle, the shading jumps
    // where the +z face meets the +x face (vertex normals averaged across the edge would make
    // it continuous), and nowhere else changes by more than a few levels per pixel.
    let bg = img.get_pixel(0, 0).0;
    let y = 230u32;
    let inside: Vec<u32> = (0..400).filter(|&x| img.get_pixel(x, y).0 != bg).collect();
    assert!(
        inside.len() > 150,
        "the cube covers {} pixels of the row",
        inside.len()
    );
    let (x0, x1) = (inside[0] + 3, inside[inside.len() - 1] - 3);
    let lum = |x: u32| img.get_pixel(x, y).0[0] as i32;
    let jumps: Vec<(u32, i32)> = (x0..x1)
        .map(|x| (x, (lum(x + 1) - lum(x)).abs()))
        .filter(|&(_, d)| d > 12)
        .collect();
    assert!(
        !jumps.is_empty(),
        "no hard edge between the two visible side faces"
    );
    let span = jumps.last().unwrap().0 - jumps[0].0;
    assert!(
        span <= 2,
        "shading changes sharply at {jumps:?}: expected one edge"
    );
}
