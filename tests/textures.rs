//! Textures as artists use them: a UV atlas generated for a mesh without UVs, a result baked
//! into it and exported, read back and sampled where the surface is.

mod scratch;
use scratch::Scratch;

use meshmatch::TriMesh;
use meshmatch::geometry::{mip_chain, refine_to_density, sample_bilinear};
use meshmatch::mesh::io;
use meshmatch::meshmatch::{BakeLayout, deliver};
use meshmatch::work::CancelToken;

/// A smooth colour that is a known function of position (low frequency over the unit box).
fn known(p: [f32; 3]) -> [f32; 3] {
    [
        0.5 + 0.4 * (3.0 * p[0]).sin(),
        0.5 + 0.4 * (2.5 * p[1] + 1.0).sin(),
        0.5 + 0.4 * (2.0 * p[2] + 2.0).cos(),
    ]
}

/// Spot's geometry without its UVs and texture (a target as a scan would arrive), scaled into
/// the unit box.
fn bare_spot() -> TriMesh {
    let path = meshmatch::testdata::data_path("spot/spot.obj");
    let m = io::load(&path).expect("spot loads");
    let mut bare = TriMesh::new(m.positions.clone(), m.faces.clone());
    let (mut lo, mut hi) = ([f32::MAX; 3], [f32::MIN; 3]);
    for p in &bare.positions {
        for k in 0..3 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    let s = (0..3).map(|k| hi[k] - lo[k]).fold(0.0f32, f32::max);
    for p in &mut bare.positions {
        for k in 0..3 {
            p[k] = (p[k] - lo[k]) / s;
        }
    }
    bare
}

/// Largest channel error between the texture of `m` (bilinear at the interpolated UV) and
/// [`known`] at the surface point, for every `step`-th face and each barycentric weight.
fn texture_errors(
    m: &TriMesh,
    rgba: &image::RgbaImage,
    step: usize,
    weights: &[[f32; 3]],
) -> Vec<f32> {
    let uvs = m.uvs.as_ref().expect("UVs");
    let mut errs = Vec::new();
    for f in (0..m.faces.len()).step_by(step) {
        let face = m.faces[f];
        for &w in weights {
            let p = lerp3(
                m.positions[face[0] as usize],
                m.positions[face[1] as usize],
                m.positions[face[2] as usize],
                w,
            );
            let uv = lerp3(
                [uvs[3 * f][0], uvs[3 * f][1], 0.0],
                [uvs[3 * f + 1][0], uvs[3 * f + 1][1], 0.0],
                [uvs[3 * f + 2][0], uvs[3 * f + 2][1], 0.0],
                w,
            );
            let got = sample_bilinear(rgba, [uv[0], uv[1]]);
            let want = known(p);
            errs.push(
                (0..3)
                    .map(|k| (got[k] - want[k]).abs())
                    .fold(0.0f32, f32::max),
            );
        }
    }
    errs
}

fn lerp3(a: [f32; 3], b: [f32; 3], c: [f32; 3], w: [f32; 3]) -> [f32; 3] {
    [0, 1, 2].map(|k| w[0] * a[k] + w[1] * b[k] + w[2] * c[k])
}

#[test]
fn atlas_bake_export_round_trip_reproduces_the_signal_on_a_mesh_without_uvs() {
    let target = bare_spot();
    assert!(target.uvs.is_none());
    let refined = refine_to_density(&target, 20_000);
    let layout = BakeLayout::of_refined(&target, &refined);
    let working: Vec<[f32; 3]> = refined.mesh.positions.iter().map(|&p| known(p)).collect();
    let file: Vec<[f32; 3]> = target.positions.iter().map(|&p| known(p)).collect();
    let size = 1024;
    let out = deliver(
        &target,
        &layout,
        &working,
        &file,
        "glb",
        size,
        None,
        &CancelToken::new(),
    )
    .expect("deliver");
    let atlas = out.atlas.as_ref().expect("an atlas was generated");
    assert!(atlas.charts >= 2, "{} charts", atlas.charts);
    assert!(
        atlas.utilization > 0.3,
        "atlas covers {:.2}",
        atlas.utilization
    );
    // Exported as GLB with the texture and read back.
    let dir = tempfile_dir("atlas_round_trip");
    let path = dir.join("spot_baked.glb");
    io::save(&out.mesh, &path).expect("save");
    let back = io::load(&path).expect("load back");
    assert!(back.uvs.is_some(), "UVs in the file");
    let tex = back.texture.as_ref().expect("texture in the file");
    assert_eq!(tex.image.dimensions(), (size, size));
    assert!(
        back.colors.is_none(),
        "a textured GLB carries no vertex colours"
    );
    let rgba = image::DynamicImage::ImageRgb8(tex.image.clone()).to_rgba8();
    // Surface points (face, barycentric) across the whole mesh: the texture gives the signal.
    let mut errs = texture_errors(
        &back,
        &rgba,
        3,
        &[[1.0 / 3.0; 3], [0.6, 0.2, 0.2], [0.1, 0.1, 0.8]],
    );
    errs.sort_by(f32::total_cmp);
    let mean = errs.iter().sum::<f32>() / errs.len() as f32;
    let p99 = errs[errs.len() * 99 / 100];
    assert!(mean < 0.015, "mean error {mean:.4}");
    assert!(p99 < 0.05, "99th percentile error {p99:.4}");
}

#[test]
fn no_background_bleeds_at_chart_borders_at_mip_level_2() {
    let target = bare_spot();
    let refined = refine_to_density(&target, 8_000);
    let layout = BakeLayout::of_refined(&target, &refined);
    let red = [0.9f32, 0.1, 0.1];
    let working = vec![red; refined.mesh.positions.len()];
    let file = vec![red; target.positions.len()];
    let out = deliver(
        &target,
        &layout,
        &working,
        &file,
        "obj",
        512,
        None,
        &CancelToken::new(),
    )
    .expect("deliver");
    let uvs = out.mesh.uvs.as_ref().expect("UVs");
    let tex = out.mesh.texture.as_ref().expect("texture");
    let rgba = image::DynamicImage::ImageRgb8(tex.image.clone()).to_rgba8();
    let mips = mip_chain(&rgba);
    assert!(mips.len() > 2);
    // Every corner lies on its chart's border or inside; bilinear at mip 2 reaches about two
    // texels of the full image past it. Nothing but the chart colour may show there.
    let mut worst = 0.0f32;
    for uv in uvs {
        for mip in &mips[..=2] {
            let c = sample_bilinear(mip, *uv);
            let d = (0..3).map(|k| (c[k] - red[k]).abs()).fold(0.0f32, f32::max);
            worst = worst.max(d);
        }
    }
    assert!(
        worst < 0.02,
        "a chart border sample strays {worst:.3} from the chart colour"
    );
}

#[test]
fn a_target_that_has_uvs_keeps_them() {
    let path = meshmatch::testdata::data_path("spot/spot.obj");
    let spot = io::load(&path).expect("spot");
    let refined = refine_to_density(&spot, 6_000);
    let layout = BakeLayout::of_refined(&spot, &refined);
    let working = vec![[0.2, 0.4, 0.6]; refined.mesh.positions.len()];
    let file = vec![[0.2, 0.4, 0.6]; spot.positions.len()];
    let out = deliver(
        &spot,
        &layout,
        &working,
        &file,
        "glb",
        256,
        None,
        &CancelToken::new(),
    )
    .unwrap();
    assert!(out.atlas.is_none());
    assert_eq!(out.mesh.uvs, spot.uvs);
    // PLY carries vertex colours only: no atlas, no texture.
    let ply = deliver(
        &spot,
        &layout,
        &working,
        &file,
        "ply",
        256,
        None,
        &CancelToken::new(),
    )
    .unwrap();
    assert!(ply.mesh.texture.is_none() && ply.atlas.is_none());
}

fn tempfile_dir(name: &str) -> Scratch {
    Scratch::new(&format!("textures-{name}"))
}

#[test]
fn bake_command_puts_a_dense_result_into_a_generated_atlas() {
    // A dense coloured sphere-like mesh (Spot refined, coloured by a known function) baked onto
    // Spot's bare geometry: the output carries UVs, a texture, and the function.
    let dir = tempfile_dir("bake_cmd");
    let target = bare_spot();
    let dense = refine_to_density(&target, 30_000).mesh;
    let mut coloured = dense.clone();
    coloured.colors = Some(dense.positions.iter().map(|&p| known(p)).collect());
    let from = dir.join("dense.ply");
    let to = dir.join("bare.obj");
    let out = dir.join("baked.glb");
    io::save(&coloured, &from).unwrap();
    io::save(&target, &to).unwrap();
    let st = std::process::Command::new(env!("CARGO_BIN_EXE_meshmatch"))
        .args(["bake", "--texture-size", "512", "--from"])
        .arg(&from)
        .arg("--to")
        .arg(&to)
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert!(
        st.status.success(),
        "{}",
        String::from_utf8_lossy(&st.stderr)
    );
    let back = io::load(&out).unwrap();
    assert!(back.uvs.is_some());
    let rgba =
        image::DynamicImage::ImageRgb8(back.texture.as_ref().expect("texture").image.clone())
            .to_rgba8();
    let errs = texture_errors(&back, &rgba, 1, &[[1.0 / 3.0; 3]]);
    let worst = errs.iter().copied().fold(0.0f32, f32::max);
    let sum: f32 = errs.iter().sum();
    let mean = sum / errs.len() as f32;
    assert!(
        mean < 0.015 && worst < 0.08,
        "mean {mean:.4}, worst {worst:.4}"
    );
    // Refused: a PLY output cannot carry a texture.
    let st = std::process::Command::new(env!("CARGO_BIN_EXE_meshmatch"))
        .args(["bake", "--from"])
        .arg(&from)
        .arg("--to")
        .arg(&to)
        .arg("--out")
        .arg(dir.join("x.ply"))
        .output()
        .unwrap();
    assert_eq!(
        st.status.code(),
        Some(2),
        "{}",
        String::from_utf8_lossy(&st.stderr)
    );
}

#[test]
fn synth_with_defaults_stays_within_its_vertex_budget() {
    use meshmatch::synthesis::exemplar::DEFAULT_VERTEX_BUDGET;
    // The penguin with the bricks (transparent hole, oriented): the defaults a new user runs.
    let row = meshmatch::bench::synth_row(
        &meshmatch::testdata::data_path("penguin/penguin.obj"),
        &meshmatch::testdata::data_path("textures/bricks.png"),
    )
    .expect("synth with defaults");
    let budget = DEFAULT_VERTEX_BUDGET as f64;
    assert!(
        (row.vertices as f64) < 1.1 * budget && (row.vertices as f64) > 0.7 * budget,
        "{} vertices for a budget of {budget}",
        row.vertices
    );
    assert!(
        row.case.contains("relax"),
        "{}: bricks are oriented",
        row.case
    );
}

#[test]
fn synth_to_glb_writes_the_target_with_a_baked_texture() {
    let dir = tempfile_dir("synth_glb");
    let out = dir.join("spot_water.glb");
    let dense = dir.join("spot_water_dense.ply");
    let st = std::process::Command::new(env!("CARGO_BIN_EXE_meshmatch"))
        .args([
            "synth",
            "--vertex-budget",
            "20000",
            "--texture-size",
            "256",
            "--exemplar",
        ])
        .arg(meshmatch::testdata::data_path("textures/1.jpg"))
        .arg("--target")
        .arg(meshmatch::testdata::data_path("spot/spot.obj"))
        .arg("--out")
        .arg(&out)
        .arg("--out-dense")
        .arg(&dense)
        .output()
        .unwrap();
    assert!(
        st.status.success(),
        "{}",
        String::from_utf8_lossy(&st.stderr)
    );
    let spot = io::load(&meshmatch::testdata::data_path("spot/spot.obj")).unwrap();
    let back = io::load(&out).unwrap();
    // The target's own faces and UVs (GLB splits vertices at UV seams), with a new texture that
    // is the water (blue-green).
    assert_eq!(back.num_faces(), spot.num_faces());
    let (a, b) = (back.uvs.as_ref().unwrap(), spot.uvs.as_ref().unwrap());
    assert_eq!(a.len(), b.len());
    let off = a
        .iter()
        .zip(b)
        .map(|(p, q)| (p[0] - q[0]).abs().max((p[1] - q[1]).abs()))
        .fold(0.0f32, f32::max);
    assert!(off < 1e-5, "UVs moved by {off}");
    let tex = back.texture.as_ref().expect("texture");
    assert_eq!(tex.image.dimensions(), (256, 256));
    let blue = tex.image.pixels().filter(|p| p.0[2] > p.0[0] + 30).count();
    assert!(blue > 256 * 256 / 2, "{blue} blue texels");
    // And the dense mesh beside it.
    let d = io::load(&dense).unwrap();
    assert!(d.num_vertices() > 10_000 && d.colors.is_some());
}
