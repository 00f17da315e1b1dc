//! `meshmatch transfer` end to end: outputs in the target's own vertex order, the NNF CSV, the
//! dense mesh, baked textures, and clean failures on bad correspondences.

mod scratch;
use scratch::Scratch;

use meshmatch::mesh::io;
use meshmatch::testdata::data_path;

use std::process::Command;

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_meshmatch"))
}

fn tmpdir(name: &str) -> Scratch {
    Scratch::new(&format!("transfer-{name}"))
}

#[test]
fn spot_to_cow_writes_every_output_in_file_order() {
    let d = tmpdir("cow");
    let corr = d.join("corr.json");
    std::fs::write(
        &corr,
        r#"{"correspondences": [{"source_vertex": 0, "target_vertices": [5]}]}"#,
    )
    .unwrap();
    let (out, dense, nnf) = (d.join("cow.ply"), d.join("dense.ply"), d.join("nnf.csv"));
    let st = bin()
        .args([
            "transfer",
            "--vertices",
            "6000",
            "--iterations",
            "2",
            "--seed",
            "3",
        ])
        .arg("--source")
        .arg(data_path("spot/spot.obj"))
        .arg("--target")
        .arg(data_path("cow/cow.ply"))
        .arg("--correspondences")
        .arg(&corr)
        .arg("--out")
        .arg(&out)
        .arg("--out-dense")
        .arg(&dense)
        .arg("--nnf-out")
        .arg(&nnf)
        .output()
        .unwrap();
    assert!(
        st.status.success(),
        "{}",
        String::from_utf8_lossy(&st.stderr)
    );
    let cow = io::load(&data_path("cow/cow.ply")).unwrap();
    let result = io::load(&out).unwrap();
    assert_eq!(result.num_vertices(), cow.num_vertices());
    assert_eq!(result.faces, cow.faces, "faces in the file's own order");
    assert_eq!(
        result.positions, cow.positions,
        "positions in the file's own order"
    );
    let colors = result.colors.expect("vertex colours");
    // Spot's palette: mostly white with black patches; the cow must get both, not one flat colour.
    let lum: Vec<f32> = colors
        .iter()
        .map(|c| meshmatch::color::srgb_to_lab(*c)[0])
        .collect();
    let dark = lum.iter().filter(|&&l| l < 40.0).count() as f32 / lum.len() as f32;
    let light = lum.iter().filter(|&&l| l > 70.0).count() as f32 / lum.len() as f32;
    assert!(dark > 0.02 && light > 0.3, "dark {dark}, light {light}");

    let text = std::fs::read_to_string(&nnf).unwrap();
    let mut lines = text.lines();
    assert_eq!(
        lines.next(),
        Some("target_vertex,source_vertex,rotation_deg")
    );
    let rows: Vec<_> = lines.collect();
    assert_eq!(rows.len(), cow.num_vertices());
    for (i, row) in rows.iter().enumerate() {
        let f: Vec<&str> = row.split(',').collect();
        assert_eq!(f.len(), 3);
        assert_eq!(f[0].parse::<usize>().unwrap(), i);
        assert!(f[1].parse::<usize>().unwrap() < 2930);
        let r: f32 = f[2].parse().unwrap();
        assert!((0.0..360.0).contains(&r));
    }
    let dense = io::load(&dense).unwrap();
    assert!(
        dense.num_vertices() >= 5000,
        "dense working mesh has {} vertices",
        dense.num_vertices()
    );
    assert!(dense.colors.is_some());
}

#[test]
fn textured_target_gets_a_baked_texture_in_its_own_uv_layout() {
    let d = tmpdir("bake");
    let out = d.join("spot_onto_spot.glb");
    let st = bin()
        .args([
            "transfer",
            "--vertices",
            "6000",
            "--iterations",
            "1",
            "--texture-size",
            "256",
        ])
        .arg("--source")
        .arg(data_path("spot/spot.obj"))
        .arg("--target")
        .arg(data_path("spot/spot.obj"))
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert!(
        st.status.success(),
        "{}",
        String::from_utf8_lossy(&st.stderr)
    );
    let m = io::load(&out).unwrap();
    let tex = m.texture.as_ref().expect("baked baseColorTexture");
    assert_eq!((tex.image.width(), tex.image.height()), (256, 256));
    assert!(m.uvs.is_some());
    // The bake is not one flat colour: Spot's dark patches and its pale hide both show, and the
    // gutters between islands carry island colours (pull-push), never a black background.
    let px: Vec<[u8; 3]> = tex.image.pixels().map(|p| p.0).collect();
    let dark = px.iter().filter(|p| p.iter().all(|&c| c < 110)).count();
    let pale = px.iter().filter(|p| p.iter().all(|&c| c > 200)).count();
    assert!(
        dark > 500 && pale > 20_000,
        "dark texels {dark}, pale {pale}"
    );
    for (x, y) in [(0, 0), (255, 0), (0, 255), (255, 255)] {
        let c = tex.image.get_pixel(x, y).0;
        assert!(
            c.iter().any(|&v| v > 60),
            "texel ({x}, {y}) outside the islands is {c:?}"
        );
    }
}

#[test]
fn bad_correspondences_and_outputs_fail_cleanly() {
    let d = tmpdir("bad");
    let corr = d.join("corr.json");
    std::fs::write(
        &corr,
        r#"{"correspondences": [{"source_vertex": 999999, "target_vertices": [5]}]}"#,
    )
    .unwrap();
    let garbage = d.join("garbage.json");
    std::fs::write(&garbage, "{not json").unwrap();
    for (c, out, mention) in [
        (&corr, d.join("x.ply"), "999999"),
        (&garbage, d.join("x.ply"), "garbage.json"),
        (&corr, d.join("x.stl"), "x.stl"),
    ] {
        let o = bin()
            .args(["transfer", "--vertices", "3000"])
            .arg("--source")
            .arg(data_path("spot/spot.obj"))
            .arg("--target")
            .arg(data_path("cow/cow.ply"))
            .arg("--correspondences")
            .arg(c)
            .arg("--out")
            .arg(&out)
            .output()
            .unwrap();
        assert_eq!(o.status.code(), Some(2));
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(err.contains(mention), "{err}");
        assert!(!err.contains("panicked"), "{err}");
    }
    // An untextured source has nothing to transfer.
    let o = bin()
        .arg("transfer")
        .arg("--source")
        .arg(data_path("cow/cow.ply"))
        .arg("--target")
        .arg(data_path("bunny/bunny.obj"))
        .arg("--out")
        .arg(d.join("y.ply"))
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("cow.ply"));
}
