//! Synthesis in texture space: the texels of a UV layout are the samples, the result is a
//! texture. Checked on Spot's own UVs (seams, sharpness) and on a mesh without UVs (generated
//! atlas, transparent exemplar pixels).

use glam::{Vec2, Vec3};
use meshmatch::TriMesh;
use meshmatch::synthesis::SynthParams;
use meshmatch::synthesis::exemplar::{TextureInput, TextureParams, synthesize_texture};
use meshmatch::testdata::data_path;
use meshmatch::work::{CancelToken, no_events};

fn load(rel: &str) -> TriMesh {
    meshmatch::mesh::io::load(&data_path(rel)).expect(rel)
}

fn exemplar(name: &str) -> image::RgbImage {
    image::open(data_path(&format!("textures/{name}")))
        .expect(name)
        .to_rgb8()
}

/// The texture's value at UV `uv` (V up), bilinear, in [0, 1].
fn sample(img: &image::RgbImage, uv: Vec2) -> Vec3 {
    let (w, h) = (img.width() as f32, img.height() as f32);
    let x = (uv.x * w - 0.5).clamp(0.0, w - 1.0);
    let y = ((1.0 - uv.y) * h - 0.5).clamp(0.0, h - 1.0);
    let (x0, y0) = (x.floor() as u32, y.floor() as u32);
    let (x1, y1) = (
        (x0 + 1).min(img.width() - 1),
        (y0 + 1).min(img.height() - 1),
    );
    let (fx, fy) = (x - x0 as f32, y - y0 as f32);
    let px = |x: u32, y: u32| {
        let p = img.get_pixel(x, y).0;
        Vec3::new(p[0] as f32, p[1] as f32, p[2] as f32) / 255.0
    };
    (px(x0, y0) * (1.0 - fx) + px(x1, y0) * fx) * (1.0 - fy)
        + (px(x0, y1) * (1.0 - fx) + px(x1, y1) * fx) * fy
}

/// Seam samples of a mesh with per-corner UVs: the same surface point read through the UVs of
/// the two faces of every edge whose corners differ in UV, at a quarter, half and three quarters.
fn seam_pairs(mesh: &TriMesh) -> Vec<(Vec2, Vec2)> {
    let uvs = mesh.uvs.as_ref().expect("uvs");
    let mut edges: std::collections::BTreeMap<(u32, u32), Vec<(usize, usize)>> = Default::default();
    for (f, face) in mesh.faces.iter().enumerate() {
        for k in 0..3 {
            let (a, b) = (face[k], face[(k + 1) % 3]);
            edges.entry((a.min(b), a.max(b))).or_default().push((f, k));
        }
    }
    let corner = |f: usize, v: u32| {
        let k = mesh.faces[f].iter().position(|&x| x == v).unwrap();
        Vec2::from(uvs[3 * f + k])
    };
    let mut out = Vec::new();
    for (&(a, b), list) in &edges {
        if list.len() != 2 {
            continue;
        }
        let (f, g) = (list[0].0, list[1].0);
        let (fa, fb, ga, gb) = (corner(f, a), corner(f, b), corner(g, a), corner(g, b));
        if fa.distance(ga) + fb.distance(gb) < 1e-5 {
            continue; // not a seam
        }
        for t in [0.25f32, 0.5, 0.75] {
            out.push((fa.lerp(fb, t), ga.lerp(gb, t)));
        }
    }
    out
}

#[test]
fn spot_texture_space_synthesis_is_seamless_and_keeps_the_exemplars_detail() {
    let spot = load("spot/spot.obj");
    let ex = exemplar("bricks.png");
    let params = TextureParams {
        synth: SynthParams {
            scale: Some(1.2),
            ..Default::default()
        },
        texture_size: 1024,
        texel_budget: 60_000,
        new_atlas: false,
    };
    let input = TextureInput {
        exemplar: &ex,
        alpha: None,
        target: &spot,
        field: None,
    };
    let r = synthesize_texture(&input, &params, &no_events, &CancelToken::new()).unwrap();
    let tex = &r.mesh.texture.as_ref().expect("a texture").image;
    assert_eq!(tex.dimensions(), (1024, 1024));
    assert!(r.atlas.is_none(), "Spot's own UVs are used");
    assert!(
        r.level_texels[0] <= 75_000 && r.level_texels[0] >= 40_000,
        "{} texels synthesized for a budget of 60,000",
        r.level_texels[0]
    );
    // The budget shrank the exemplar; the texture still reads the full one.
    assert!(r.working_exemplar_width < ex.width());

    // Seams: the same surface point through the two charts' UVs.
    let pairs = seam_pairs(&spot);
    assert!(pairs.len() > 300, "{} seam samples", pairs.len());
    let seam: f32 = pairs
        .iter()
        .map(|&(a, b)| (sample(tex, a) - sample(tex, b)).abs().element_sum() / 3.0)
        .sum::<f32>()
        / pairs.len() as f32;
    // Against: points one working texel apart inside a chart, and unrelated points.
    let step = 1.0 / r.working_size as f32;
    let near: f32 = pairs
        .iter()
        .map(|&(a, _)| {
            let d = Vec2::new(step, 0.0);
            (sample(tex, a) - sample(tex, a + d)).abs().element_sum() / 3.0
        })
        .sum::<f32>()
        / pairs.len() as f32;
    // (every seam point against six others spread over the seams)
    let unrelated: f32 = (1..=6)
        .map(|k| {
            pairs
                .iter()
                .zip(pairs.iter().cycle().skip(k * pairs.len() / 7))
                .map(|(&(a, _), &(_, b))| {
                    (sample(tex, a) - sample(tex, b)).abs().element_sum() / 3.0
                })
                .sum::<f32>()
        })
        .sum::<f32>()
        / (6 * pairs.len()) as f32;
    eprintln!("seam {seam:.4}, one texel apart {near:.4}, unrelated points {unrelated:.4}");
    assert!(
        seam < 0.6 * unrelated,
        "across seams the texture differs by {seam:.4}, as much as unrelated points ({unrelated:.4})"
    );
    assert!(
        seam < 1.5 * near,
        "across seams {seam:.4}, one working texel apart in a chart {near:.4}"
    );

    // Detail: the same synthesis on the surface's vertices at the same budget, baked into
    // the same UVs, is softer: its texels interpolate vertex colours, ours read the full
    // exemplar at each texel's own place.
    let (small, _) = meshmatch::synthesis::exemplar::fit_exemplar_to_budget(
        ex.clone(),
        &spot,
        Some(1.2),
        60_000,
        32,
    );
    let surf = meshmatch::synthesis::exemplar::run(
        &meshmatch::synthesis::exemplar::Input {
            exemplar: &small,
            target: &spot,
            mask: None,
            alpha: None,
        },
        &params.synth,
        &no_events,
        &CancelToken::new(),
    )
    .unwrap();
    let (baked, _) = meshmatch::geometry::bake_onto(
        &spot,
        &surf.mesh,
        surf.mesh.colors.as_ref().unwrap(),
        1024,
        false,
        &|_| {},
        &CancelToken::new(),
    )
    .unwrap();
    let baked = &baked.texture.as_ref().unwrap().image;
    let texels =
        meshmatch::geometry::uv_texels(spot.uvs.as_ref().unwrap(), spot.faces.len(), 1024, 1024);
    let inside = |x: u32, y: u32| {
        (0..3).all(|dy| {
            (0..3).all(|dx| {
                let (xx, yy) = ((x + dx).saturating_sub(1), (y + dy).saturating_sub(1));
                texels[(yy * 1024 + xx).min(1024 * 1024 - 1) as usize].is_some()
            })
        })
    };
    let contrast = |img: &image::RgbImage| {
        let (mut s, mut n) = (0.0f64, 0usize);
        let p = |x, y| {
            let c: [u8; 3] = img.get_pixel(x, y).0;
            (c[0] as f64 + c[1] as f64 + c[2] as f64) / 765.0
        };
        for y in 1..img.height() - 1 {
            for x in 1..img.width() - 1 {
                if inside(x, y) {
                    s += (p(x + 1, y) - p(x, y)).abs() + (p(x, y + 1) - p(x, y)).abs();
                    n += 1;
                }
            }
        }
        s / n.max(1) as f64
    };
    let (ours, theirs) = (contrast(tex), contrast(baked));
    eprintln!("texel-to-texel contrast: texture space {ours:.4}, surface bake {theirs:.4}");
    assert!(
        ours > 1.2 * theirs,
        "texture space {ours:.4} is not sharper than the surface bake {theirs:.4}"
    );
}

#[test]
fn a_mesh_without_uvs_gets_an_atlas_and_never_the_exemplars_hole() {
    let bunny = load("bunny/bunny.obj");
    assert!(bunny.uvs.is_none());
    let (rgb, alpha) = meshmatch::testdata::exemplar_with_hole(96);
    let params = TextureParams {
        synth: SynthParams {
            levels: 3,
            ..Default::default()
        },
        texture_size: 512,
        texel_budget: 30_000,
        new_atlas: false,
    };
    let input = TextureInput {
        exemplar: &rgb,
        alpha: Some(&alpha),
        target: &bunny,
        field: None,
    };
    let r = synthesize_texture(&input, &params, &no_events, &CancelToken::new()).unwrap();
    assert!(r.atlas.is_some());
    assert!(
        r.atlas_reason
            .as_deref()
            .is_some_and(|s| s.contains("no UVs")),
        "{:?}",
        r.atlas_reason
    );
    let uvs = r.mesh.uvs.as_ref().expect("the atlas's UVs");
    let tex = &r.mesh.texture.as_ref().expect("a texture").image;
    let texels = meshmatch::geometry::uv_texels(uvs, r.mesh.faces.len(), 512, 512);
    let inside: Vec<[u8; 3]> = texels
        .iter()
        .zip(tex.pixels())
        .filter(|(t, _)| t.is_some())
        .map(|(_, p)| p.0)
        .collect();
    assert!(
        inside.len() > 20_000,
        "{} texels in the charts",
        inside.len()
    );
    let magenta = inside
        .iter()
        .filter(|c| c[0] > 200 && c[1] < 64 && c[2] > 200)
        .count();
    assert_eq!(magenta, 0, "{magenta} texels show the transparent colour");
    let greenish = inside.iter().filter(|c| c[1] > c[0] && c[1] > 115).count();
    assert!(
        greenish * 10 > inside.len() * 9,
        "{greenish} of {} texels look like the exemplar",
        inside.len()
    );
}

#[test]
fn unusable_uvs_get_an_atlas_and_bad_parameters_are_errors() {
    let spot = load("spot/spot.obj");
    let ex = exemplar("1.jpg");
    let params = TextureParams {
        synth: SynthParams {
            levels: 2,
            ..Default::default()
        },
        texture_size: 128,
        texel_budget: 2_000,
        new_atlas: false,
    };
    let run = |mesh: &TriMesh, p: &TextureParams| {
        synthesize_texture(
            &TextureInput {
                exemplar: &ex,
                alpha: None,
                target: mesh,
                field: None,
            },
            p,
            &no_events,
            &CancelToken::new(),
        )
    };
    // tiled UVs: corners outside the unit square
    let mut tiled = spot.clone();
    for t in tiled.uvs.as_mut().unwrap() {
        t[0] *= 3.0;
    }
    let r = run(&tiled, &params).unwrap();
    assert!(
        r.atlas_reason
            .as_deref()
            .is_some_and(|s| s.contains("outside")),
        "{:?}",
        r.atlas_reason
    );
    // stacked UVs: every face on the same triangle
    let mut stacked = spot.clone();
    for (i, t) in stacked.uvs.as_mut().unwrap().iter_mut().enumerate() {
        *t = [[0.1, 0.1], [0.9, 0.1], [0.5, 0.9]][i % 3];
    }
    let r = run(&stacked, &params).unwrap();
    assert!(
        r.atlas_reason
            .as_deref()
            .is_some_and(|s| s.contains("overlap")),
        "{:?}",
        r.atlas_reason
    );
    // a layout squeezed into a corner
    let mut corner = spot.clone();
    for t in corner.uvs.as_mut().unwrap() {
        t[0] *= 0.1;
        t[1] *= 0.1;
    }
    let r = run(&corner, &params).unwrap();
    assert!(
        r.atlas_reason
            .as_deref()
            .is_some_and(|s| s.contains("cover only")),
        "{:?}",
        r.atlas_reason
    );
    // Spot's own UVs are used as they are
    let own = run(&spot, &params).unwrap().atlas_reason;
    assert!(own.is_none(), "{own:?}");
    // one-line errors
    let bad = [
        TextureParams {
            synth: SynthParams {
                displace: true,
                ..params.synth.clone()
            },
            ..params.clone()
        },
        TextureParams {
            texel_budget: 10,
            ..params.clone()
        },
        TextureParams {
            texture_size: 8,
            ..params.clone()
        },
        TextureParams {
            synth: SynthParams {
                scale: Some(f32::NAN),
                ..params.synth.clone()
            },
            ..params.clone()
        },
    ];
    for p in &bad {
        let e = run(&spot, p).unwrap_err().to_string();
        assert!(!e.contains('\n') && !e.is_empty(), "{e}");
    }
}
