//! Geometry-correlated texture transfer (Mertens et al. 2006), end to end on procedural meshes.

use meshmatch::TriMesh;
use meshmatch::color::srgb_to_lab;
use meshmatch::geometry::{directional_occlusion, vertex_normals};
use meshmatch::stats::pearson;
use meshmatch::synthesis::weathering::{Input, Params, Up, feature_field, features, run};
use meshmatch::work::{CancelToken, Event, no_events};

/// A height field over `[0, 1]²` (Z up) sampled on an `m × m` grid: rolling hills plus sharp
/// crevices (|sin| valleys) whose directions and frequencies depend on `variant`.
fn terrain(m: u32, variant: u32) -> TriMesh {
    let (fa, fb, ph) = match variant {
        0 => (3.0f32, 5.0f32, 0.0f32),
        _ => (4.0, 2.5, 1.3),
    };
    let h = |x: f32, y: f32| -> f32 {
        let hills = 0.06
            * (fa * x * std::f32::consts::TAU + ph).sin()
            * (fb * y * std::f32::consts::TAU).cos();
        let u = (x * 0.8 + y * 0.6) * fb * 2.0 + ph;
        let crevice = -0.05 * (1.0 - (u * std::f32::consts::PI).sin().abs()).powi(6);
        let v = (x * 0.3 - y * 0.95) * fa * 1.5;
        let crevice2 = -0.04 * (1.0 - (v * std::f32::consts::PI).sin().abs()).powi(8);
        hills + crevice + crevice2
    };
    let mut pos = Vec::new();
    for j in 0..m {
        for i in 0..m {
            let (x, y) = (i as f32 / (m - 1) as f32, j as f32 / (m - 1) as f32);
            pos.push([x, y, h(x, y)]);
        }
    }
    let mut faces = Vec::new();
    for j in 0..m - 1 {
        for i in 0..m - 1 {
            let a = j * m + i;
            faces.push([a, a + 1, a + m + 1]);
            faces.push([a, a + m + 1, a + m]);
        }
    }
    TriMesh::new(pos, faces)
}

/// The "truth": a colour made from geometry (dark in occluded crevices, greener where the
/// surface faces up), evaluated on any mesh with 128 rays and its own seed.
fn truth_colours(m: &TriMesh) -> Vec<[f32; 3]> {
    let nrm = vertex_normals(&m.positions, &m.faces);
    let occ = directional_occlusion(&m.positions, &m.faces, &nrm, 128, 99);
    occ.iter()
        .zip(&nrm)
        .map(|(o, n)| {
            let a = ((o[0] - 0.55) / 0.45).clamp(0.0, 1.0);
            let up = n[2].clamp(0.0, 1.0).powi(8);
            let base = [0.15 + 0.65 * a, 0.12 + 0.6 * a, 0.1 + 0.5 * a];
            [
                base[0] * (1.0 - 0.3 * up),
                base[1],
                base[2] * (1.0 - 0.4 * up),
            ]
        })
        .collect()
}

fn params_small() -> Params {
    Params {
        working_vertices: 0,
        up: Up::Z,
        rays: 32,
        clusters: 20,
        ..Params::default()
    }
}

#[test]
fn transfer_follows_the_target_geometry() {
    let mut src = terrain(110, 0);
    src.colors = Some(truth_colours(&src));
    let tgt = terrain(100, 1);
    let params = params_small();
    let t = std::time::Instant::now();
    let partials = std::sync::atomic::AtomicUsize::new(0);
    let sink = |e: Event| {
        if let Event::Partial { signal, .. } = e {
            assert_eq!(signal.len(), tgt.num_vertices());
            partials.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        }
    };
    let out = run(
        &Input {
            source: &src,
            target: &tgt,
            source_mask: None,
        },
        &params,
        &sink,
        &CancelToken::new(),
    )
    .unwrap();
    let secs = t.elapsed().as_secs_f64();
    assert_eq!(
        partials.load(std::sync::atomic::Ordering::Relaxed),
        params.hb_iterations + 1
    );
    assert_eq!(out.colors.len(), out.target.mesh.num_vertices());
    assert_eq!(out.file_colors.len(), tgt.file_vertex_count);
    let want: Vec<f32> = truth_colours(&out.target.mesh)
        .iter()
        .map(|c| srgb_to_lab(*c)[0])
        .collect();
    let got: Vec<f32> = out.colors.iter().map(|c| srgb_to_lab(*c)[0]).collect();
    let r = pearson(&got, &want);
    eprintln!(
        "terrain -> terrain: {} -> {} vertices, {secs:.2} s, lightness correlation {r:.3}\n{}\ntimings {:?}",
        out.source_vertices,
        out.colors.len(),
        out.report.to_text(),
        out.timings
    );
    assert!(
        out.report.correlations[0] > 0.8,
        "{:?}",
        out.report.correlations
    );
    assert!(r > 0.7, "lightness correlation {r}");
    // the greenish tint (a* lower where the surface faces up) also follows
    let want_a: Vec<f32> = truth_colours(&out.target.mesh)
        .iter()
        .map(|c| srgb_to_lab(*c)[1])
        .collect();
    let got_a: Vec<f32> = out.colors.iter().map(|c| srgb_to_lab(*c)[1]).collect();
    eprintln!("a* correlation {:.3}", pearson(&got_a, &want_a));
}

#[test]
fn features_have_names_and_sane_values() {
    let m = terrain(60, 0);
    let p = params_small();
    let fs = features(&m.positions, &m.faces, &p, &CancelToken::new()).unwrap();
    assert_eq!(fs.dim, 12);
    assert_eq!(fs.names.len(), 12);
    let ao = feature_field(&fs, "ao").unwrap();
    assert!(ao.iter().all(|&x| (0.0..=1.0).contains(&x)));
    let h = feature_field(&fs, "height").unwrap();
    assert!(h.iter().cloned().fold(f32::INFINITY, f32::min).abs() < 1e-6);
    assert!((h.iter().cloned().fold(0.0f32, f32::max) - 1.0).abs() < 1e-6);
    assert!(feature_field(&fs, "curvature:1").is_ok());
    assert!(feature_field(&fs, "occlusion-y").is_ok());
    assert!(feature_field(&fs, "bogus").is_err());
    assert!(!fs.flipped);
    let flipped = TriMesh::new(
        m.positions.clone(),
        m.faces.iter().map(|f| [f[0], f[2], f[1]]).collect(),
    );
    assert!(
        !features(&flipped.positions, &flipped.faces, &p, &CancelToken::new())
            .unwrap()
            .flipped
    );
    // a closed mesh wound inwards is detected and evaluated outward
    let horse =
        meshmatch::mesh::io::load(&meshmatch::testdata::data_path("horse/horse.ply")).unwrap();
    assert!(meshmatch::synthesis::weathering::wound_inwards(
        &horse.positions,
        &horse.faces
    ));
    let out: Vec<[u32; 3]> = horse.faces.iter().map(|f| [f[0], f[2], f[1]]).collect();
    assert!(!meshmatch::synthesis::weathering::wound_inwards(
        &horse.positions,
        &out
    ));
}

#[test]
fn bad_inputs_are_one_line_errors() {
    let mut src = terrain(30, 0);
    let tgt = terrain(30, 1);
    let p = params_small();
    let cancel = CancelToken::new();
    let go = |s: &TriMesh, t: &TriMesh, mask: Option<&[bool]>| {
        run(
            &Input {
                source: s,
                target: t,
                source_mask: mask,
            },
            &p,
            &no_events,
            &cancel,
        )
    };
    let e = go(&src, &tgt, None).unwrap_err().to_string();
    assert!(e.contains("no colours"), "{e}");
    src.colors = Some(vec![[0.5; 3]; src.num_vertices()]);
    let e = go(&src, &tgt, None).unwrap_err().to_string();
    assert!(e.contains("constant"), "{e}");
    src.colors = Some(truth_colours(&src));
    let all = vec![true; src.num_vertices()];
    let e = go(&src, &tgt, Some(&all)).unwrap_err().to_string();
    assert!(e.contains("mask"), "{e}");
    let empty = TriMesh::new(vec![[0.0; 3]; 3], vec![]);
    assert!(
        go(&src, &empty, None)
            .unwrap_err()
            .to_string()
            .contains("no faces")
    );
    let flat = TriMesh::new(
        vec![[0.0; 3], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]],
        vec![[0, 1, 2]],
    );
    assert!(
        go(&src, &flat, None)
            .unwrap_err()
            .to_string()
            .contains("zero area")
    );
    let e = go(&src, &flat, None).unwrap_err().to_string();
    assert!(!e.contains('\n'));
    // a partial mask works, and the same seed gives the same output
    let half: Vec<bool> = (0..src.num_vertices()).map(|i| i % 30 < 10).collect();
    let a = go(&src, &tgt, Some(&half)).unwrap();
    let b = go(&src, &tgt, Some(&half)).unwrap();
    assert_eq!(a.colors, b.colors);
    assert!(a.report.training_vertices < src.num_vertices());
    // cancel
    let c = CancelToken::new();
    c.cancel();
    let r = run(
        &Input {
            source: &src,
            target: &tgt,
            source_mask: None,
        },
        &p,
        &no_events,
        &c,
    );
    assert!(matches!(r, Err(meshmatch::Error::Cancelled)));
}

/// Timings on real meshes (run with `--ignored --nocapture`): occlusion rays/s and curvature on
/// the horse (~97K triangles), and an end-to-end transfer of crevice dirt from the horse to the
/// bunny at 30K working vertices, with PLYs written to the temp directory.
#[test]
#[ignore]
fn timings_on_real_meshes() {
    use meshmatch::geometry::solid_angle_curvature;
    use meshmatch::testdata::data_path;
    let mut horse = meshmatch::mesh::io::load(&data_path("horse/horse.ply")).unwrap();
    // the horse file is wound inwards: flip it so the "truth" below sees outward normals
    let vol: f64 = horse
        .faces
        .iter()
        .map(|f| {
            let [a, b, c] = f.map(|v| glam::Vec3::from(horse.positions[v as usize]).as_dvec3());
            a.dot(b.cross(c))
        })
        .sum();
    if vol < 0.0 {
        horse.faces.iter_mut().for_each(|f| f.swap(1, 2));
    }
    eprintln!("horse signed volume {vol:.4} (flipped: {})", vol < 0.0);
    let (pos, faces) = (&horse.positions, &horse.faces);
    let nrm = vertex_normals(pos, faces);
    let t = std::time::Instant::now();
    let occ = directional_occlusion(pos, faces, &nrm, 64, 1);
    let s = t.elapsed().as_secs_f64();
    let rays = 64.0 * pos.len() as f64;
    eprintln!(
        "occlusion: {} vertices, {} triangles, 64 rays: {s:.2} s, {:.2} M rays/s (threads {})",
        pos.len(),
        faces.len(),
        rays / s / 1e6,
        rayon::current_num_threads()
    );
    assert_eq!(occ.len(), pos.len());
    let (lo, hi) = horse.bounds().unwrap();
    let diag = glam::Vec3::from(hi).distance(glam::Vec3::from(lo));
    let radii: Vec<f32> = [0.01, 0.03, 0.1, 0.3].iter().map(|r| r * diag).collect();
    for &r in &radii {
        let t = std::time::Instant::now();
        let _ = solid_angle_curvature(pos, faces, &[r]);
        eprintln!(
            "curvature r = {:.3} diag: {:.2} s",
            r / diag,
            t.elapsed().as_secs_f64()
        );
    }
    let t = std::time::Instant::now();
    let k = solid_angle_curvature(pos, faces, &radii);
    eprintln!("curvature 4 radii: {:.2} s", t.elapsed().as_secs_f64());
    let mean: Vec<f32> = (0..4)
        .map(|j| k.iter().skip(j).step_by(4).sum::<f32>() / pos.len() as f32)
        .collect();
    eprintln!("mean curvature per radius {mean:?}");

    // dirt in crevices: lightness from 128-ray ambient occlusion
    let dirt = |m: &TriMesh| -> Vec<[f32; 3]> {
        let nrm = vertex_normals(&m.positions, &m.faces);
        directional_occlusion(&m.positions, &m.faces, &nrm, 128, 99)
            .iter()
            .map(|o| {
                let a = ((o[0] - 0.4) / 0.6).clamp(0.0, 1.0);
                [0.2 + 0.7 * a, 0.15 + 0.65 * a, 0.1 + 0.55 * a]
            })
            .collect()
    };
    if std::env::var_os("MERTENS_LARGE").is_some() {
        // features + CCA at a larger size: the Igea scan (134K vertices) with a planted colour
        let igea = meshmatch::mesh::io::load(&data_path("igea/igea.ply")).unwrap();
        let p = Params::default();
        let t = std::time::Instant::now();
        let fs = features(&igea.positions, &igea.faces, &p, &CancelToken::new()).unwrap();
        let tf = t.elapsed().as_secs_f64();
        let ao = feature_field(&fs, "ao").unwrap();
        let y: Vec<f32> = ao.iter().flat_map(|&a| [a, 0.5 * a, 0.2]).collect();
        let t = std::time::Instant::now();
        let c = meshmatch::stats::cca(&fs.values, fs.dim, &y, 3, 3, 1e-6).unwrap();
        eprintln!(
            "igea {} vertices {} faces: features {tf:.2} s (height+normals {:.2}, curvature {:.2}, \
             occlusion {:.2}; flipped {}), CCA {:.3} s, rho {:?}",
            igea.num_vertices(),
            igea.num_faces(),
            fs.seconds[0],
            fs.seconds[1],
            fs.seconds[2],
            fs.flipped,
            t.elapsed().as_secs_f64(),
            c.correlations
        );
    }
    if std::env::var_os("MERTENS_FEATURES_ONLY").is_some() {
        return;
    }
    let mut src = horse.clone();
    src.colors = Some(dirt(&src));
    let bunny = meshmatch::mesh::io::load(&data_path("bunny/bunny.obj")).unwrap();
    let params = Params {
        working_vertices: 30_000,
        ..Params::default()
    };
    let t = std::time::Instant::now();
    let out = run(
        &Input {
            source: &src,
            target: &bunny,
            source_mask: None,
        },
        &params,
        &no_events,
        &CancelToken::new(),
    )
    .unwrap();
    let secs = t.elapsed().as_secs_f64();
    let want: Vec<f32> = dirt(&out.target.mesh)
        .iter()
        .map(|c| srgb_to_lab(*c)[0])
        .collect();
    let got: Vec<f32> = out.colors.iter().map(|c| srgb_to_lab(*c)[0]).collect();
    eprintln!(
        "horse ({} v) -> bunny ({} v): {secs:.2} s, lightness correlation {:.3}\n{}{:?}",
        out.source_vertices,
        out.colors.len(),
        pearson(&got, &want),
        out.report.to_text(),
        out.timings
    );
    let dir = std::env::temp_dir();
    let mut m = out.target.mesh.clone();
    m.colors = Some(out.colors.clone());
    m.uvs = None;
    m.texture = None;
    meshmatch::mesh::io::save(&m, &dir.join("mertens_bunny.ply")).unwrap();
    let mut w = out.target.mesh.clone();
    w.colors = Some(dirt(&out.target.mesh));
    meshmatch::mesh::io::save(&w, &dir.join("mertens_bunny_truth.ply")).unwrap();
    meshmatch::mesh::io::save(&src, &dir.join("mertens_horse_source.ply")).unwrap();
    // a quick look: orthographic renders (view along -Z, Y up) of source, truth and result
    let views = [
        render(&src, src.colors.as_ref().unwrap(), 320),
        render(&w, w.colors.as_ref().unwrap(), 320),
        render(&m, &out.colors, 320),
    ];
    let mut img = image::RgbImage::new(960, 320);
    for (k, v) in views.iter().enumerate() {
        image::imageops::replace(&mut img, v, 320 * k as i64, 0);
    }
    img.save(dir.join("mertens_horse_bunny.png")).unwrap();
}

/// Orthographic z-buffered render of a vertex-coloured mesh (view along -Z, Y up), lit by
/// nothing: what you see is the colour signal.
fn render(m: &TriMesh, col: &[[f32; 3]], size: u32) -> image::RgbImage {
    let (lo, hi) = m.bounds().unwrap();
    let s = (size as f32 * 0.9) / (hi[0] - lo[0]).max(hi[1] - lo[1]);
    let (cx, cy) = ((lo[0] + hi[0]) * 0.5, (lo[1] + hi[1]) * 0.5);
    let proj = |p: [f32; 3]| {
        [
            size as f32 * 0.5 + (p[0] - cx) * s,
            size as f32 * 0.5 - (p[1] - cy) * s,
            p[2],
        ]
    };
    let mut img = image::RgbImage::from_pixel(size, size, image::Rgb([40, 40, 60]));
    let mut z = vec![f32::NEG_INFINITY; (size * size) as usize];
    for f in &m.faces {
        let q = f.map(|v| proj(m.positions[v as usize]));
        let (x0, x1) = (
            q.iter().map(|p| p[0]).fold(f32::INFINITY, f32::min),
            q.iter().map(|p| p[0]).fold(f32::NEG_INFINITY, f32::max),
        );
        let (y0, y1) = (
            q.iter().map(|p| p[1]).fold(f32::INFINITY, f32::min),
            q.iter().map(|p| p[1]).fold(f32::NEG_INFINITY, f32::max),
        );
        let area =
            (q[1][0] - q[0][0]) * (q[2][1] - q[0][1]) - (q[2][0] - q[0][0]) * (q[1][1] - q[0][1]);
        if area.abs() < 1e-12 {
            continue;
        }
        for y in (y0.floor().max(0.0) as u32)..=(y1.ceil().min(size as f32 - 1.0) as u32) {
            for x in (x0.floor().max(0.0) as u32)..=(x1.ceil().min(size as f32 - 1.0) as u32) {
                let (px, py) = (x as f32 + 0.5, y as f32 + 0.5);
                let e = |a: [f32; 3], b: [f32; 3]| {
                    (b[0] - a[0]) * (py - a[1]) - (px - a[0]) * (b[1] - a[1])
                };
                let w = [
                    e(q[1], q[2]) / area,
                    e(q[2], q[0]) / area,
                    e(q[0], q[1]) / area,
                ];
                if w.iter().any(|&t| t < 0.0) {
                    continue;
                }
                let depth = w[0] * q[0][2] + w[1] * q[1][2] + w[2] * q[2][2];
                let i = (y * size + x) as usize;
                if depth > z[i] {
                    z[i] = depth;
                    let c = [0, 1, 2]
                        .map(|k| (0..3).map(|j| w[j] * col[f[j] as usize][k]).sum::<f32>());
                    img.put_pixel(x, y, image::Rgb(meshmatch::color::to_u8(c)));
                }
            }
        }
    }
    img
}

#[test]
fn self_transfer_keeps_the_colours() {
    let mut src = terrain(70, 0);
    src.colors = Some(truth_colours(&src));
    let out = run(
        &Input {
            source: &src,
            target: &src,
            source_mask: None,
        },
        &params_small(),
        &no_events,
        &CancelToken::new(),
    )
    .unwrap();
    let sc = src.colors.as_ref().unwrap();
    let mean = |c: &[[f32; 3]]| -> [f32; 3] {
        let n = c.len() as f32;
        [0, 1, 2].map(|k| c.iter().map(|x| x[k]).sum::<f32>() / n)
    };
    let (a, b) = (mean(sc), mean(&out.colors));
    let l = |c: &[[f32; 3]]| -> Vec<f32> { c.iter().map(|x| srgb_to_lab(*x)[0]).collect() };
    let r = pearson(&l(sc), &l(&out.colors));
    eprintln!("self-transfer: mean {a:?} -> {b:?}, lightness correlation {r:.3}");
    assert!((0..3).all(|k| (a[k] - b[k]).abs() < 0.02), "{a:?} vs {b:?}");
    assert!(r > 0.85, "{r}");
}

#[test]
fn textured_source_spot_to_bunny() {
    use meshmatch::testdata::data_path;
    let spot = meshmatch::mesh::io::load(&data_path("spot/spot.obj")).unwrap();
    assert!(spot.texture.is_some() && spot.colors.is_none());
    let bunny = meshmatch::mesh::io::load(&data_path("bunny/bunny.obj")).unwrap();
    let params = Params {
        working_vertices: 8000,
        rays: 32,
        clusters: 20,
        ..Params::default()
    };
    let out = run(
        &Input {
            source: &spot,
            target: &bunny,
            source_mask: None,
        },
        &params,
        &no_events,
        &CancelToken::new(),
    )
    .unwrap();
    assert_eq!(out.file_colors.len(), bunny.file_vertex_count);
    let l: Vec<f32> = out.colors.iter().map(|c| srgb_to_lab(*c)[0]).collect();
    let mean = l.iter().sum::<f32>() / l.len() as f32;
    let sd = (l.iter().map(|x| (x - mean).powi(2)).sum::<f32>() / l.len() as f32).sqrt();
    eprintln!(
        "spot (texture) -> bunny: L mean {mean:.1} sd {sd:.1}, correlations {:?}",
        out.report.correlations
    );
    assert!(sd > 1.0 && out.colors.iter().flatten().all(|x| (0.0..=1.0).contains(x)));
}

#[test]
fn nonparametric_copies_source_colours_where_the_geometry_asks_for_them() {
    use meshmatch::synthesis::weathering::Method;
    let mut src = terrain(110, 0);
    let truth = truth_colours(&src);
    // The grain: a per-vertex noise on top of the geometric rule, which only a method that
    // copies source colours (rather than fitting histograms) carries over exactly.
    let grainy: Vec<[f32; 3]> = truth
        .iter()
        .enumerate()
        .map(|(i, c)| {
            let n = ((i as u32).wrapping_mul(2_654_435_761) >> 24) as f32 / 255.0 - 0.5;
            c.map(|x| (x + 0.08 * n).clamp(0.0, 1.0))
        })
        .collect();
    src.colors = Some(grainy.clone());
    let tgt = terrain(100, 1);
    let params = Params {
        method: Method::NonParametric,
        ..params_small()
    };
    let out = run(
        &Input {
            source: &src,
            target: &tgt,
            source_mask: None,
        },
        &params,
        &|_| {},
        &CancelToken::new(),
    )
    .unwrap();
    let want: Vec<f32> = truth_colours(&out.target.mesh)
        .iter()
        .map(|c| srgb_to_lab(*c)[0])
        .collect();
    let got: Vec<f32> = out.colors.iter().map(|c| srgb_to_lab(*c)[0]).collect();
    let r = pearson(&got, &want);
    // Every output colour is one of the source's (up to the colour-space round trip).
    let quant = |c: [f32; 3]| c.map(|x| (x * 255.0).round() as i32);
    let palette: std::collections::HashSet<[i32; 3]> = grainy.iter().map(|c| quant(*c)).collect();
    let near = |c: [f32; 3]| {
        let q = quant(c);
        (-1..=1).any(|a| {
            (-1..=1).any(|b| (-1..=1).any(|d| palette.contains(&[q[0] + a, q[1] + b, q[2] + d])))
        })
    };
    let copied = out.colors.iter().filter(|c| near(**c)).count() as f64 / out.colors.len() as f64;
    eprintln!(
        "non-parametric terrain -> terrain: lightness correlation {r:.3}, {:.1}% of colours are source colours, timings {:?}",
        100.0 * copied,
        out.timings
    );
    assert!(r > 0.7, "lightness correlation {r}");
    assert!(copied > 0.99, "{copied}");
}

/// At a working density above the features' finest grid, the features are evaluated on grid
/// samples and interpolated back: on the bunny refined to 60K points they must agree with every
/// vertex evaluated (curvature, the same opening criterion), and the sparse occlusion must be as
/// close to the full one as a second full evaluation with other rays is.
#[test]
fn sparse_features_agree_with_every_vertex_evaluated() {
    use meshmatch::geometry::{SolidAngleCurvature, refine_to_density};
    use meshmatch::synthesis::weathering::{features_on_surface, opening_for_radius};
    use meshmatch::testdata::data_path;
    let mut bunny = meshmatch::mesh::io::load(&data_path("bunny/bunny.obj")).expect("bunny");
    bunny.repair().expect("repair");
    let r = refine_to_density(&bunny, 60_000);
    let (p, f) = (&r.mesh.positions, &r.mesh.faces);
    let params = Params {
        curvature_radii: vec![0.05, 0.15, 0.3],
        rays: 32,
        ..Params::default()
    };
    let cancel = CancelToken::new();
    let fs = features_on_surface(
        p,
        f,
        Some((&bunny.positions, &bunny.faces)),
        &params,
        &cancel,
    )
    .expect("features");
    assert!(
        fs.evaluated * 3 < p.len(),
        "{} of {} vertices evaluated: the sampling did not take over",
        fs.evaluated,
        p.len()
    );
    let flipped: Vec<[u32; 3]> = f.iter().map(|t| [t[0], t[2], t[1]]).collect();
    let f = if fs.flipped { &flipped } else { f };
    let all: Vec<u32> = (0..p.len() as u32).collect();
    let sac = SolidAngleCurvature::new(p, f);
    let r_min = fs.radii[0];
    for (j, &rad) in fs.radii.iter().enumerate() {
        let full = sac
            .at(&all, &[rad], opening_for_radius(rad, r_min), &cancel)
            .expect("curvature");
        let sparse = feature_field(&fs, &format!("curvature-{j}")).expect("column");
        let c = pearson(&sparse, &full);
        eprintln!("curvature-{j}: {c:.4}");
        assert!(
            c > 0.98,
            "curvature-{j}: correlation {c:.4} with every vertex evaluated"
        );
    }
    let nrm = vertex_normals(p, f);
    let full = directional_occlusion(p, f, &nrm, params.rays, params.seed);
    let other = directional_occlusion(p, f, &nrm, params.rays, params.seed + 7);
    let ao = |o: &[[f32; 4]]| o.iter().map(|x| x[0]).collect::<Vec<f32>>();
    let sparse = feature_field(&fs, "ao").expect("ao");
    let (c_sparse, c_noise) = (
        pearson(&sparse, &ao(&full)),
        pearson(&ao(&other), &ao(&full)),
    );
    eprintln!(
        "{} of {} evaluated; ao {c_sparse:.4}, other rays {c_noise:.4}",
        fs.evaluated,
        p.len()
    );
    assert!(
        c_sparse > c_noise - 0.01,
        "ambient occlusion: sparse {c_sparse:.4} against full, other rays {c_noise:.4}"
    );
}
