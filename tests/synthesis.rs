//! Surface texture synthesis (Wei & Levoy 2001) on real meshes and real exemplars: colour
//! statistics, neighbourhood similarity to the exemplar, orientation fields, search strategies,
//! masks, displacement, events and cancellation.

use std::cell::RefCell;

use glam::Vec3;
use meshmatch::TriMesh;
use meshmatch::synthesis::exemplar::{
    color_histogram, exemplar_loo_distance, histogram_l1, image_colors, neighbourhood_distance,
    orientation_energy,
};
use meshmatch::synthesis::{Orientation, Search, SynthParams, SynthResult, synthesize};
use meshmatch::testdata::data_path;
use meshmatch::work::{CancelToken, Event, no_events};

/// Unit icosphere: icosahedron subdivided `n` times.
fn icosphere(n: usize) -> TriMesh {
    let (p, f) = meshmatch::testdata::icosphere(n);
    TriMesh::new(p, f)
}

/// A real exemplar from the shared data, downsampled to `size x size`.
fn exemplar(name: &str, size: u32) -> image::RgbImage {
    let img = image::open(data_path(&format!("textures/{name}")))
        .expect("texture")
        .to_rgb8();
    image::imageops::resize(&img, size, size, image::imageops::FilterType::Triangle)
}

/// Diagonal two-colour stripes with period 8 px (a 2-way symmetric texture).
fn stripes(size: u32) -> image::RgbImage {
    image::RgbImage::from_fn(size, size, |x, y| {
        let s = ((x as f32 + 0.3 * y as f32) * std::f32::consts::TAU / 8.0).sin();
        if s > 0.0 {
            image::Rgb([220, 200, 60])
        } else {
            image::Rgb([40, 50, 120])
        }
    })
}

fn run(ex: &image::RgbImage, mesh: &TriMesh, params: &SynthParams) -> SynthResult {
    synthesize(ex, mesh, None, params, &no_events, &CancelToken::new()).expect("synthesis")
}

fn nd(ex: &image::RgbImage, r: &SynthResult, size: usize) -> f64 {
    neighbourhood_distance(ex, &r.mesh, &r.orientation, r.spacing, size, 600, 5).expect("measure")
}

#[test]
fn bunny_colour_histogram_matches_exemplar() {
    let ex = exemplar("1.jpg", 64);
    let bunny = meshmatch::mesh::io::load(&data_path("bunny/bunny.obj")).expect("bunny");
    let (lo, hi) = bunny.bounds().unwrap();
    let diag = Vec3::from(hi).distance(Vec3::from(lo));
    let params = SynthParams {
        scale: Some(diag / 2.0),
        seed: 1,
        ..Default::default()
    };
    let r = run(&ex, &bunny, &params);
    let out = r.mesh.colors.as_ref().unwrap();
    println!(
        "bunny: levels {:?}, timings {:?}",
        r.level_vertices, r.timings
    );
    assert!(r.mesh.num_vertices() > bunny.num_vertices());
    assert_eq!(r.file_colors.len(), bunny.file_vertex_count);
    assert_eq!(&r.file_colors[..], &out[..bunny.num_vertices()]);
    let hx = color_histogram(&image_colors(&ex), 8);
    let ho = color_histogram(out, 8);
    let l1 = histogram_l1(&hx, &ho);
    // baselines: uniformly random colours, and the exemplar's mean colour everywhere
    let mut s = 12345u64;
    let mut rnd = || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        (s % 1000) as f32 / 1000.0
    };
    let random: Vec<[f32; 3]> = (0..out.len()).map(|_| [rnd(), rnd(), rnd()]).collect();
    let exc = image_colors(&ex);
    let mean = exc
        .iter()
        .fold([0.0f32; 3], |a, c| [a[0] + c[0], a[1] + c[1], a[2] + c[2]])
        .map(|x| x / exc.len() as f32);
    let l1_random = histogram_l1(&hx, &color_histogram(&random, 8));
    let l1_mean = histogram_l1(&hx, &color_histogram(&vec![mean; out.len()], 8));
    println!("histogram L1: output {l1:.3}, random {l1_random:.3}, mean colour {l1_mean:.3}");
    assert!(l1 < 0.5, "histogram L1 {l1}");
    assert!(l1 < 0.3 * l1_random && l1 < 0.3 * l1_mean);
    // neighbourhoods: output vs exemplar compared with the exemplar's leave-one-out baseline
    let loo = exemplar_loo_distance(&ex, 5, 2, 600, 5);
    let d = nd(&ex, &r, 5);
    println!(
        "5x5 neighbourhood distance: output {d:.5}, exemplar leave-one-out {loo:.5}, ratio {:.2}",
        d / loo
    );
    assert!(d < 1.5 * loo, "output {d} vs leave-one-out {loo}");
    // and far from what unstructured output gives: the same colours shuffled over the vertices
    let mut shuffled = r.clone();
    let cols = shuffled.mesh.colors.as_mut().unwrap();
    let n = cols.len();
    for i in 0..n {
        cols.swap(i, (i * 7919 + 13) % n);
    }
    let d_shuffled = nd(&ex, &shuffled, 5);
    println!("shuffled colours: {d_shuffled:.5}");
    assert!(d < 0.7 * d_shuffled);
}

#[test]
fn sphere_neighbourhoods_match_exemplar_7x7() {
    let ex = exemplar("1.jpg", 64);
    let sphere = icosphere(3);
    let params = SynthParams {
        scale: Some(2.0),
        seed: 3,
        ..Default::default()
    };
    let r = run(&ex, &sphere, &params);
    let loo = exemplar_loo_distance(&ex, 7, 3, 600, 5);
    let d = nd(&ex, &r, 7);
    println!(
        "sphere 7x7: output {d:.5}, leave-one-out {loo:.5}, ratio {:.2}",
        d / loo
    );
    assert!(d < 1.5 * loo, "output {d} vs leave-one-out {loo}");
    // a high-contrast exemplar: structure, not noise (shuffled colours are far worse)
    let ex = exemplar("2.jpg", 64);
    let r = run(&ex, &sphere, &params);
    let loo = exemplar_loo_distance(&ex, 7, 3, 600, 5);
    let d = nd(&ex, &r, 7);
    let mut shuffled = r.clone();
    let cols = shuffled.mesh.colors.as_mut().unwrap();
    let n = cols.len();
    for i in 0..n {
        cols.swap(i, (i * 7919 + 13) % n);
    }
    let d_shuffled = nd(&ex, &shuffled, 7);
    println!("sphere 2.jpg 7x7: output {d:.5}, leave-one-out {loo:.5}, shuffled {d_shuffled:.5}");
    assert!(d < 1.5 * loo, "output {d} vs leave-one-out {loo}");
    assert!(d < 0.5 * d_shuffled, "output {d} vs shuffled {d_shuffled}");
}

#[test]
fn relax2_orients_stripes_better_than_random() {
    let ex = stripes(64);
    let sphere = icosphere(3);
    let mut res = Vec::new();
    for o in [Orientation::Random, Orientation::Relax2] {
        let params = SynthParams {
            scale: Some(1.5),
            orientation: o,
            seed: 4,
            ..Default::default()
        };
        let r = run(&ex, &sphere, &params);
        let e = orientation_energy(&r.mesh.positions, &r.mesh.faces, &r.orientation, 2);
        let d = nd(&ex, &r, 7);
        println!("{o:?}: orientation energy {e:.4} rad^2, 7x7 neighbourhood distance {d:.5}");
        res.push((e, d));
    }
    let (random, relax) = (res[0], res[1]);
    assert!(relax.0 < 0.1 * random.0, "energy {relax:?} vs {random:?}");
    // the stripes survive only with a coherent field
    assert!(relax.1 < 0.6 * random.1, "distance {relax:?} vs {random:?}");
}

#[test]
fn up_orientation_is_tangent_and_follows_y() {
    let ex = exemplar("1.jpg", 32);
    let sphere = icosphere(2);
    let params = SynthParams {
        scale: Some(2.0),
        orientation: Orientation::Up,
        levels: 3,
        ..Default::default()
    };
    let r = run(&ex, &sphere, &params);
    let normals = r.mesh.normals.as_ref().unwrap();
    let mut checked = 0;
    for ((s, n), p) in r.orientation.iter().zip(normals).zip(&r.mesh.positions) {
        let (s, n) = (Vec3::from(*s), Vec3::from(*n));
        assert!((s.length() - 1.0).abs() < 1e-3);
        assert!(s.dot(n).abs() < 0.05);
        // texture up t = n x s is the projected +Y away from the poles
        if p[1].abs() < 0.8 {
            let t = n.cross(s);
            let y = (Vec3::Y - Vec3::Y.dot(n) * n).normalize();
            assert!(t.dot(y) > 0.99, "t {t} vs projected Y {y}");
            checked += 1;
        }
    }
    assert!(checked > 100);
}

#[test]
fn fast_search_nearly_matches_exhaustive_and_is_faster() {
    let ex = exemplar("1.jpg", 48);
    let sphere = icosphere(3);
    let mut out = Vec::new();
    for s in [Search::Exhaustive, Search::Fast] {
        let params = SynthParams {
            scale: Some(3.0),
            search: s,
            seed: 2,
            ..Default::default()
        };
        let r = run(&ex, &sphere, &params);
        let d = nd(&ex, &r, 7);
        println!(
            "{s:?}: {} vertices, search {:.3} s, total {:.3} s, 7x7 distance {d:.5}",
            r.mesh.num_vertices(),
            r.timings.search,
            r.timings.total
        );
        out.push((r.timings.search, d));
    }
    let (ex_t, ex_d) = out[0];
    let (fa_t, fa_d) = out[1];
    assert!(fa_d < 1.2 * ex_d, "fast {fa_d} vs exhaustive {ex_d}");
    assert!(fa_t * 3.0 < ex_t, "fast {fa_t} s vs exhaustive {ex_t} s");
}

#[test]
fn partial_events_per_pass_and_cancel() {
    let ex = exemplar("2.jpg", 32);
    let sphere = icosphere(2);
    let params = SynthParams {
        scale: Some(2.0),
        levels: 3,
        ..Default::default()
    };
    let partials = RefCell::new(Vec::new());
    let sink = |e: Event| {
        if let Event::Partial { progress, signal } = e {
            partials
                .borrow_mut()
                .push((progress.level, progress.iteration, signal.len()));
        }
    };
    let r = synthesize(&ex, &sphere, None, &params, &sink, &CancelToken::new()).unwrap();
    let p = partials.into_inner();
    // coarsest level is the random copy; two passes on each of the two finer levels
    assert_eq!(
        p.iter().map(|x| (x.0, x.1)).collect::<Vec<_>>(),
        vec![(1, 1), (1, 2), (0, 1), (0, 2)]
    );
    assert!(p.iter().all(|x| x.2 == r.mesh.num_vertices()));
    // determinism under a seed
    let again = run(&ex, &sphere, &params);
    assert_eq!(again.mesh.colors, r.mesh.colors);
    // cancel during the first partial: the call stops with Cancelled
    let token = CancelToken::new();
    let t2 = token.clone();
    let sink = move |e: Event| {
        if matches!(e, Event::Partial { .. }) {
            t2.cancel();
        }
    };
    let err = synthesize(&ex, &sphere, None, &params, &sink, &token).unwrap_err();
    assert!(matches!(err, meshmatch::Error::Cancelled));
}

#[test]
fn mask_keeps_colours_outside() {
    let ex = exemplar("1.jpg", 32);
    let mut sphere = icosphere(3);
    let n = sphere.num_vertices();
    sphere.colors = Some(vec![[1.0, 0.0, 0.0]; n]);
    // synthesize the upper half only
    let mask: Vec<bool> = sphere.positions.iter().map(|p| p[1] > 0.0).collect();
    let params = SynthParams {
        scale: Some(2.0),
        levels: 3,
        ..Default::default()
    };
    let r = synthesize(
        &ex,
        &sphere,
        Some(&mask),
        &params,
        &no_events,
        &CancelToken::new(),
    )
    .unwrap();
    let mut inside_red = 0;
    for (i, c) in r.file_colors.iter().enumerate() {
        if mask[i] {
            inside_red += (*c == [1.0, 0.0, 0.0]) as usize;
        } else {
            assert_eq!(*c, [1.0, 0.0, 0.0]);
        }
    }
    assert_eq!(inside_red, 0, "synthesized vertices copy exemplar pixels");
    // wrong mask length and a mask without target colours are refused
    let bad = vec![true; n - 1];
    assert!(
        synthesize(
            &ex,
            &sphere,
            Some(&bad),
            &params,
            &no_events,
            &CancelToken::new()
        )
        .is_err()
    );
    sphere.colors = None;
    assert!(
        synthesize(
            &ex,
            &sphere,
            Some(&mask),
            &params,
            &no_events,
            &CancelToken::new()
        )
        .is_err()
    );
}

#[test]
fn displacement_follows_grey_values_along_normals() {
    let ex = image::imageops::grayscale(&exemplar("2.jpg", 32));
    let ex = image::DynamicImage::ImageLuma8(ex).to_rgb8();
    let sphere = icosphere(2);
    let params = SynthParams {
        scale: Some(2.0),
        levels: 3,
        displace: true,
        displace_amount: Some(0.1),
        ..Default::default()
    };
    let r = run(&ex, &sphere, &params);
    let plain = run(
        &ex,
        &sphere,
        &SynthParams {
            displace: false,
            ..params.clone()
        },
    );
    assert_eq!(plain.mesh.colors, r.mesh.colors);
    assert!(plain.displacement.is_none());
    let disp = r.displacement.as_ref().unwrap();
    let cols = r.mesh.colors.as_ref().unwrap();
    let lo_d = disp.iter().cloned().fold(f32::MAX, f32::min);
    let hi_d = disp.iter().cloned().fold(f32::MIN, f32::max);
    assert!(hi_d - lo_d > 0.02, "displacement spread {}", hi_d - lo_d);
    let normals = plain.mesh.normals.as_ref().unwrap();
    for ((p, q), (n, d)) in r
        .mesh
        .positions
        .iter()
        .zip(&plain.mesh.positions)
        .zip(normals.iter().zip(disp))
    {
        let step = Vec3::from(*p) - Vec3::from(*q);
        assert!((step - Vec3::from(*n) * *d).length() < 1e-5);
        assert!(d.abs() <= 0.1 + 1e-4);
    }
    // brighter vertices sit further out
    let (mut hi, mut lo) = ((0.0, 0), (0.0, 0));
    for (d, c) in disp.iter().zip(cols) {
        if c[0] > 0.6 {
            hi = (hi.0 + d, hi.1 + 1);
        } else if c[0] < 0.4 {
            lo = (lo.0 + d, lo.1 + 1);
        }
    }
    assert!(hi.1 > 0 && lo.1 > 0);
    assert!(hi.0 / hi.1 as f32 > lo.0 / lo.1 as f32);
}

#[test]
fn bad_inputs_are_errors() {
    let ex = exemplar("1.jpg", 64);
    let empty = TriMesh::new(vec![[0.0; 3]; 3], vec![]);
    let ok = SynthParams::default();
    assert!(synthesize(&ex, &empty, None, &ok, &no_events, &CancelToken::new()).is_err());
    let sphere = icosphere(1);
    let tiny = image::RgbImage::new(4, 4);
    assert!(synthesize(&tiny, &sphere, None, &ok, &no_events, &CancelToken::new()).is_err());
    let p = SynthParams {
        scale: Some(1e-5),
        ..Default::default()
    };
    assert!(synthesize(&ex, &sphere, None, &p, &no_events, &CancelToken::new()).is_err());
    let p = SynthParams {
        levels: 0,
        ..Default::default()
    };
    assert!(synthesize(&ex, &sphere, None, &p, &no_events, &CancelToken::new()).is_err());
    let mut nan = icosphere(1);
    nan.positions[0][0] = f32::NAN;
    assert!(synthesize(&ex, &nan, None, &ok, &no_events, &CancelToken::new()).is_err());
    // the CLI spellings parse, unknown ones are errors; params round-trip through serde
    assert_eq!(
        "relax4".parse::<Orientation>().unwrap(),
        Orientation::Relax4
    );
    assert!("spiral".parse::<Orientation>().is_err());
    assert_eq!("exhaustive".parse::<Search>().unwrap(), Search::Exhaustive);
    let json = serde_json::to_string(&SynthParams::default()).unwrap();
    let back: SynthParams = serde_json::from_str(&json).unwrap();
    assert_eq!(back.levels, 4);
}

#[test]
fn an_exemplars_transparent_hole_is_never_synthesized() {
    let (rgb, alpha) = meshmatch::testdata::exemplar_with_hole(48);
    let sphere = icosphere(3);
    let params = SynthParams {
        scale: Some(1.5),
        levels: 3,
        ..SynthParams::default()
    };
    let magenta = |c: &[f32; 3]| c[0] > 0.8 && c[1] < 0.25 && c[2] > 0.8;
    let run_with = |a: Option<&image::GrayImage>| {
        meshmatch::synthesis::exemplar::run(
            &meshmatch::synthesis::exemplar::Input {
                exemplar: &rgb,
                target: &sphere,
                mask: None,
                alpha: a,
            },
            &params,
            &no_events,
            &CancelToken::new(),
        )
        .unwrap()
    };
    // Without the alpha, a sixth of the exemplar is the disc: its colour shows.
    let plain = run_with(None);
    let shown = plain
        .mesh
        .colors
        .as_ref()
        .unwrap()
        .iter()
        .filter(|c| magenta(c))
        .count();
    assert!(
        shown > 50,
        "the control run shows the disc colour at {shown} vertices"
    );
    // With it, never; and the result still carries the exemplar's opaque colours.
    let r = run_with(Some(&alpha));
    let cols = r.mesh.colors.as_ref().unwrap();
    let bad = cols.iter().filter(|c| magenta(c)).count();
    assert_eq!(
        bad,
        0,
        "{bad} of {} vertices took the transparent colour",
        cols.len()
    );
    for (v, s) in r.source.iter().enumerate() {
        if s[0] != u32::MAX {
            let a = alpha.get_pixel(s[0], s[1]).0[0];
            assert!(a >= 128, "vertex {v} copies transparent pixel {s:?}");
        }
    }
    let greenish = cols.iter().filter(|c| c[1] > c[0] && c[1] > 0.45).count();
    assert!(
        greenish * 10 > cols.len() * 9,
        "{greenish} of {} vertices look like the exemplar",
        cols.len()
    );
}
