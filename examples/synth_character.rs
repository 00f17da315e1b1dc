//! Writes what `docs/images/synth_character.png` shows: for a shared mesh and image, the target
//! textured by patch pasting (`synth`'s default), by Wei-Levoy synthesis in texture space
//! (`--method neighbourhood`) and by triplanar projection at the same scale in the same atlas,
//! as three GLBs, with the character measures of each on stdout.
//!
//! `cargo run --release --example synth_character -- bunny/bunny.obj textures/2.jpg OUT_DIR`

use meshmatch::synthesis::exemplar::character::{Exemplar, measure, triplanar_texture};
use meshmatch::synthesis::exemplar::patch_pasting::{PatchParams, paste_patches};
use meshmatch::synthesis::exemplar::{TextureInput, TextureParams, synthesize_texture};
use meshmatch::testdata::data_path;
use meshmatch::work::CancelToken;

fn main() -> meshmatch::error::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [mesh, image, out] = &args[..] else {
        eprintln!("usage: synth_character MESH IMAGE OUT_DIR (paths under the shared data folder)");
        std::process::exit(2);
    };
    let out = std::path::PathBuf::from(out);
    std::fs::create_dir_all(&out).expect("an output folder");
    let mut target = meshmatch::mesh::io::load(&data_path(mesh))?;
    target.repair()?;
    let (tex, alpha) = meshmatch::mesh::io::load_texture_with_alpha(&data_path(image))?;
    let input = TextureInput {
        exemplar: &tex.image,
        alpha: alpha.as_ref(),
        target: &target,
        field: None,
    };
    let params = TextureParams::default();
    let cancel = CancelToken::new();
    let patches = paste_patches(&input, &params, &PatchParams::default(), &|_| {}, &cancel)?;
    // Wei-Levoy into the same layout (the patches' UVs, the target's own or the atlas)
    let mut laid_out = target.clone();
    laid_out.uvs.clone_from(&patches.mesh.uvs);
    let neighbourhood = synthesize_texture(
        &TextureInput {
            target: &laid_out,
            ..input
        },
        &params,
        &|_| {},
        &cancel,
    )?
    .mesh;
    let (lo, hi) = target.bounds().expect("a mesh");
    let ex = Exemplar {
        image: &tex.image,
        alpha: alpha.as_ref(),
        scale: glam::Vec3::from(hi).distance(glam::Vec3::from(lo)) / 4.0,
    };
    let mut projected = patches.mesh.clone();
    let tri = triplanar_texture(&patches.mesh, &ex, params.texture_size as usize)
        .expect("the atlas has UVs");
    projected.texture = Some(std::sync::Arc::new(meshmatch::mesh::Texture {
        image: tri,
        path: None,
    }));
    for (name, m) in [
        ("patches", &patches.mesh),
        ("neighbourhood", &neighbourhood),
        ("triplanar", &projected),
    ] {
        let t = &m.texture.as_ref().expect("textured").image;
        if let Some(c) = measure(m, t, &ex, 1) {
            println!(
                "{name}: contrast {:.2}, Lab W1 {:.1}, patch distance {:.1}, reverse distance {:.1}",
                c.contrast, c.lab_w1, c.patch_distance, c.reverse_distance
            );
        }
        meshmatch::mesh::io::save(m, &out.join(format!("{name}.glb")))?;
    }
    Ok(())
}
