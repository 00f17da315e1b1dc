//! `meshmatch features --out X.png|glb`: the feature maps artists bake (ambient occlusion,
//! curvature, cavity, thickness, normal, height) in a mesh's UVs (spot) or a generated atlas (the
//! bunny): texels inside a face carry the vertex values interpolated there, gutters are filled,
//! 16-bit maps carry 16 bits, `--feature all` writes every map, bad input is one line.

mod scratch;
use scratch::Scratch;
use std::path::Path;
use std::process::Command;

use meshmatch::cli::common::load_usable;
use meshmatch::synthesis::weathering::feature_maps::{
    MAP_NAMES, MapParams, VertexMap, bake_feature_maps, vertex_maps,
};
use meshmatch::testdata::data_path;
use meshmatch::work::CancelToken;

/// A scratch folder of its own, removed when the test ends.
fn dir(name: &str) -> Scratch {
    Scratch::new(&format!("feature-maps-{name}"))
}

fn cli(args: &[&str]) -> (i32, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_meshmatch"))
        .args(args)
        .output()
        .expect("run meshmatch");
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// The texel whose centre lies well inside UV triangle `f` (its centroid's texel, when that
/// texel's centre has every barycentric coordinate above `margin`): `(x, y, bary)`.
fn interior_texel(
    uvs: &[[f32; 2]],
    f: usize,
    size: usize,
    margin: f32,
) -> Option<(usize, usize, [f32; 3])> {
    let t: Vec<[f32; 2]> = (0..3)
        .map(|k| {
            let u = uvs[3 * f + k];
            [u[0] * size as f32, (1.0 - u[1]) * size as f32]
        })
        .collect();
    let c = [
        (t[0][0] + t[1][0] + t[2][0]) / 3.0,
        (t[0][1] + t[1][1] + t[2][1]) / 3.0,
    ];
    if !(c[0] >= 0.0 && c[1] >= 0.0) {
        return None;
    }
    let (x, y) = (c[0] as usize, c[1] as usize);
    if x >= size || y >= size {
        return None;
    }
    let p = [x as f32 + 0.5, y as f32 + 0.5];
    let det = (t[1][0] - t[0][0]) * (t[2][1] - t[0][1]) - (t[2][0] - t[0][0]) * (t[1][1] - t[0][1]);
    if det.abs() < 1e-9 {
        return None;
    }
    let b1 =
        ((p[0] - t[0][0]) * (t[2][1] - t[0][1]) - (t[2][0] - t[0][0]) * (p[1] - t[0][1])) / det;
    let b2 =
        ((t[1][0] - t[0][0]) * (p[1] - t[0][1]) - (p[0] - t[0][0]) * (t[1][1] - t[0][1])) / det;
    let b = [1.0 - b1 - b2, b1, b2];
    b.iter().all(|&v| v > margin).then_some((x, y, b))
}

/// A grey map's vertex values interpolated at `bary` of face `f`.
fn interpolate(m: &VertexMap, faces: &[[u32; 3]], f: usize, b: [f32; 3]) -> f32 {
    (0..3)
        .map(|k| b[k] * m.values[faces[f][k] as usize * m.channels])
        .sum()
}

/// UV triangles that overlap another one cannot be checked texel by texel: the faces whose
/// UV-space centroids fall in the same texel as another face's are left out.
fn probe_faces(uvs: &[[f32; 2]], nf: usize, size: usize) -> Vec<(usize, usize, usize, [f32; 3])> {
    let mut seen = std::collections::HashMap::new();
    let mut out = Vec::new();
    for f in 0..nf {
        if let Some((x, y, b)) = interior_texel(uvs, f, size, 0.02) {
            *seen.entry((x, y)).or_insert(0) += 1;
            out.push((f, x, y, b));
        }
    }
    out.retain(|(_, x, y, _)| seen[&(*x, *y)] == 1);
    out
}

fn spot_params(size: u32) -> MapParams {
    MapParams {
        texture_size: size,
        rays: 32,
        ..MapParams::default()
    }
}

#[test]
fn all_maps_of_spot_carry_the_vertex_features_at_texel_centres_and_fill_their_gutters() {
    let d = dir("spot_all");
    let spot = data_path("spot/spot.obj");
    let out = d.join("spot.png");
    let (code, err) = cli(&[
        "features",
        s(&spot),
        "--feature",
        "all",
        "--out",
        s(&out),
        "--texture-size",
        "512",
        "--rays",
        "32",
    ]);
    assert_eq!(code, 0, "{err}");
    // every map written, one PNG each, at the size asked
    for name in MAP_NAMES {
        let p = d.join(format!("spot_{name}.png"));
        let img = image::open(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
        assert_eq!((img.width(), img.height()), (512, 512), "{name}");
    }
    assert!(!out.exists(), "all maps go beside --out, not to it");

    let mesh = load_usable(&spot).unwrap();
    let uvs = mesh.uvs.clone().expect("spot has UVs");
    let vm = vertex_maps(&mesh, &MAP_NAMES, &spot_params(512), &CancelToken::new()).unwrap();
    let probes = probe_faces(&uvs, mesh.faces.len(), 512);
    assert!(probes.len() > 1000, "{} faces probed", probes.len());
    for m in vm.iter().filter(|m| m.channels == 1) {
        let img = image::open(d.join(format!("spot_{}.png", m.name)))
            .unwrap()
            .to_luma8();
        let mut worst = 0.0f32;
        for &(f, x, y, b) in &probes {
            let want = interpolate(m, &mesh.faces, f, b);
            let got = img.get_pixel(x as u32, y as u32).0[0] as f32 / 255.0;
            worst = worst.max((got - want).abs());
        }
        eprintln!(
            "{}: worst texel error {worst:.5} over {} faces",
            m.name,
            probes.len()
        );
        // 8-bit rounding is half a step; the interpolation itself is exact at texel centres
        assert!(worst <= 0.5 / 255.0 + 1e-4, "{}: {worst}", m.name);
    }
    // the normal: interpolated, renormalised
    let nimg = image::open(d.join("spot_normal.png")).unwrap().to_rgb8();
    let nm = vm.iter().find(|m| m.name == "normal").unwrap();
    let mut worst = 0.0f32;
    for &(f, x, y, b) in &probes {
        let mut n = [0.0f32; 3];
        for (&v, &bk) in mesh.faces[f].iter().zip(&b) {
            let v = v as usize;
            for (c, nc) in n.iter_mut().enumerate() {
                *nc += bk * (2.0 * nm.values[3 * v + c] - 1.0);
            }
        }
        let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        let px = nimg.get_pixel(x as u32, y as u32).0;
        for c in 0..3 {
            let want = 0.5 + 0.5 * n[c] / len;
            worst = worst.max((px[c] as f32 / 255.0 - want).abs());
        }
    }
    assert!(worst <= 0.5 / 255.0 + 1e-3, "normal: {worst}");

    // Gutters: every texel outside the charts and within two texels of one takes a value inside
    // the range of the chart texels around it (a background black would fall outside on at least
    // one of the normal's channels), and no texel anywhere is left black.
    let covered: Vec<bool> = meshmatch::geometry::uv_texels(&uvs, mesh.faces.len(), 512, 512)
        .iter()
        .map(|t| t.is_some())
        .collect();
    let (mut gutters, mut bad) = (0, 0);
    for y in 2..510usize {
        for x in 2..510usize {
            if covered[y * 512 + x] {
                continue;
            }
            let mut lo = [255u8; 3];
            let mut hi = [0u8; 3];
            let mut near = false;
            for yy in y - 2..=y + 2 {
                for xx in x - 2..=x + 2 {
                    if covered[yy * 512 + xx] {
                        near = true;
                        let p = nimg.get_pixel(xx as u32, yy as u32).0;
                        for c in 0..3 {
                            lo[c] = lo[c].min(p[c]);
                            hi[c] = hi[c].max(p[c]);
                        }
                    }
                }
            }
            if !near {
                continue;
            }
            gutters += 1;
            let p = nimg.get_pixel(x as u32, y as u32).0;
            if (0..3).any(|c| (p[c] as i32) < lo[c] as i32 - 1 || p[c] as i32 > hi[c] as i32 + 1) {
                bad += 1;
            }
        }
    }
    eprintln!("gutter texels {gutters}, {bad} outside their neighbourhood's range");
    assert!(gutters > 1000, "{gutters} gutter texels");
    assert_eq!(bad, 0, "{bad} of {gutters} gutter texels off");
    assert!(
        nimg.pixels().all(|p| p.0 != [0, 0, 0]),
        "a texel was left background"
    );
}

#[test]
fn a_mesh_without_uvs_gets_an_atlas_and_its_maps_interpolate_the_vertex_features() {
    let mut bunny = load_usable(&data_path("bunny/bunny.obj")).unwrap();
    bunny.uvs = None;
    let p = spot_params(512);
    let maps = bake_feature_maps(
        &bunny,
        &["ao", "cavity", "thickness"],
        &p,
        &|_| {},
        &CancelToken::new(),
    )
    .unwrap();
    assert!(maps.atlas.is_some(), "no atlas generated");
    let probes = probe_faces(&maps.uvs, bunny.faces.len(), 512);
    assert!(probes.len() > 500, "{} faces probed", probes.len());
    for (m, vm) in maps.maps.iter().zip(&maps.vertex) {
        let mut worst = 0.0f32;
        for &(f, x, y, b) in &probes {
            let want = interpolate(vm, &bunny.faces, f, b);
            worst = worst.max((m.image.pixels[y * 512 + x][0] - want).abs());
        }
        eprintln!("bunny {}: worst texel error {worst:.2e}", m.name);
        assert!(worst < 1e-5, "{}: {worst}", m.name);
        // gutters: every texel has a value from a chart, none is left at the background 0
        // unless the chart around it is 0 too
        let uncovered = m.image.covered.iter().filter(|c| !**c).count();
        assert!(uncovered > 0);
        let lo = vm.values.iter().copied().fold(f32::INFINITY, f32::min);
        assert!(
            m.image
                .pixels
                .iter()
                .all(|p| p[0] >= lo - 1e-4 && p[0] <= 1.0 + 1e-4),
            "{}: a gutter texel outside the map's range",
            m.name
        );
    }
    // the maps differ from one another: each is its own feature
    let a = &maps.vertex[0].values;
    let c = &maps.vertex[1].values;
    assert!(a.iter().zip(c).any(|(x, y)| (x - y).abs() > 0.1));
}

#[test]
fn sixteen_bit_maps_carry_sixteen_bits() {
    let d = dir("bits16");
    let spot = data_path("spot/spot.obj");
    let out = d.join("ao16.png");
    let (code, err) = cli(&[
        "features",
        s(&spot),
        "--feature",
        "ao",
        "--out",
        s(&out),
        "--texture-size",
        "256",
        "--rays",
        "32",
        "--bits",
        "16",
    ]);
    assert_eq!(code, 0, "{err}");
    let img = image::open(&out).unwrap();
    assert_eq!(img.color(), image::ColorType::L16, "not a 16-bit grey PNG");
    let img = img.to_luma16();
    let mesh = load_usable(&spot).unwrap();
    let uvs = mesh.uvs.clone().unwrap();
    let vm = vertex_maps(&mesh, &["ao"], &spot_params(256), &CancelToken::new()).unwrap();
    let probes = probe_faces(&uvs, mesh.faces.len(), 256);
    assert!(probes.len() > 300, "{}", probes.len());
    let mut worst = 0.0f32;
    let (mut not_8bit, mut saturated) = (0, 0);
    for &(f, x, y, b) in &probes {
        let v = img.get_pixel(x as u32, y as u32).0[0];
        // open texels are exactly 1 (65535 = 255 × 257); the rest fall between 8-bit steps
        not_8bit += !v.is_multiple_of(257) as usize;
        saturated += (v == 65535) as usize;
        let want = interpolate(&vm[0], &mesh.faces, f, b);
        worst = worst.max((v as f32 / 65535.0 - want).abs());
    }
    eprintln!(
        "16-bit: worst error {worst:.2e}, {not_8bit} of {} off the 8-bit steps",
        probes.len()
    );
    // far finer than an 8-bit step (1/255 = 3.9e-3)
    assert!(worst < 1e-4, "{worst}");
    let graded = probes.len() - saturated;
    assert!(graded > 300, "{graded}");
    assert!(not_8bit * 10 > graded * 9, "{not_8bit} of {graded}");
}

#[test]
fn a_map_baked_into_a_glb_loads_back_textured() {
    let d = dir("glb");
    let out = d.join("cavity.glb");
    let (code, err) = cli(&[
        "features",
        s(&data_path("spot/spot.obj")),
        "--feature",
        "cavity",
        "--out",
        s(&out),
        "--texture-size",
        "256",
        "--rays",
        "16",
    ]);
    assert_eq!(code, 0, "{err}");
    let m = meshmatch::mesh::io::load(&out).unwrap();
    let tex = m.texture.expect("a texture");
    assert_eq!(tex.image.dimensions(), (256, 256));
    assert!(m.uvs.is_some());
    // a cavity map is mostly white with dark creases
    let px: Vec<u8> = tex.image.pixels().map(|p| p.0[0]).collect();
    let white = px.iter().filter(|&&v| v > 240).count();
    let dark = px.iter().filter(|&&v| v < 128).count();
    assert!(
        white > px.len() / 2 && dark > 0,
        "white {white} dark {dark}"
    );
}

#[test]
fn bad_input_is_one_line() {
    let d = dir("bad");
    let spot = data_path("spot/spot.obj");
    let png = d.join("x.png");
    for (args, mention) in [
        (vec!["--feature", "bogus"], "unknown map"),
        (vec!["--bits", "12"], "--bits"),
        (vec!["--radius", "0"], "--radius"),
        (vec!["--texture-size", "0"], "--texture-size"),
    ] {
        let mut all = vec!["features", s(&spot), "--out", s(&png)];
        all.extend(args.iter().copied());
        let (code, err) = cli(&all);
        assert_eq!(code, 2, "{all:?}: {err}");
        assert_eq!(err.trim_end().lines().count(), 1, "{all:?}: {err}");
        assert!(err.contains(mention), "{all:?}: {err}");
    }
    let (code, err) = cli(&["features", s(&d.join("missing.obj")), "--out", s(&png)]);
    assert_ne!(code, 0);
    assert_eq!(err.trim_end().lines().count(), 1, "{err}");
    // 16 bits need PNG maps
    let (code, err) = cli(&[
        "features",
        s(&spot),
        "--out",
        s(&d.join("x.glb")),
        "--bits",
        "16",
    ]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("16"), "{err}");
    assert!(!png.exists());
}
