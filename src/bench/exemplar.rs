//! Exemplar synthesis rows (`meshmatch bench --system synth|synth-texture|synth-character`):
//! every shared texture on every shared mesh, as a user runs `synth` with its defaults.

use super::{SystemRow, peak_rss_mb, print_rows};
use crate::error::Result;
use crate::work::CancelToken;
use std::time::Instant;

/// `synth` with its defaults (vertex budget, auto orientation, alpha) of one shared texture on
/// one shared mesh: what a user gets from `meshmatch synth --exemplar T --target M --out o.ply`.
pub fn synth_row(mesh: &std::path::Path, texture: &std::path::Path) -> Result<SystemRow> {
    use crate::synthesis::exemplar::{self, DEFAULT_VERTEX_BUDGET, SynthParams};
    let t = Instant::now();
    let mut target = crate::mesh::io::load(mesh)?;
    target.repair()?;
    let (tex, alpha) = crate::mesh::io::load_texture_with_alpha(texture)?;
    let params = SynthParams::default();
    let min = (4u32 << (params.levels.clamp(1, 8) - 1)).max(8);
    let (ex, _) =
        exemplar::fit_exemplar_to_budget(tex.image, &target, None, DEFAULT_VERTEX_BUDGET, min);
    let alpha = alpha.map(|a| exemplar::resize_alpha(a, ex.width(), ex.height()));
    let input = exemplar::Input {
        exemplar: &ex,
        target: &target,
        mask: None,
        alpha: alpha.as_ref(),
    };
    let r = exemplar::run(&input, &params, &|_| {}, &CancelToken::new())?;
    let name = |p: &std::path::Path| {
        p.file_name()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default()
    };
    Ok(SystemRow {
        case: format!(
            "synth {} on {} ({}x{} px, {})",
            name(texture),
            name(mesh),
            ex.width(),
            ex.height(),
            r.orientation_used.as_str()
        ),
        vertices: r.mesh.num_vertices(),
        stages: vec![
            ("prepare".into(), r.timings.prepare),
            ("orientation".into(), r.timings.orientation),
            ("neighbourhoods".into(), r.timings.neighbourhoods),
            ("search".into(), r.timings.search),
        ],
        total_s: t.elapsed().as_secs_f64(),
        faces: 0,
        peak_rss_mb: peak_rss_mb(),
    })
}

/// `synth` into a texture with its defaults (texel budget, auto orientation, alpha, a
/// 2048² texture): what a user gets from `meshmatch synth --exemplar T --target M --out o.glb`.
pub fn synth_texture_row(mesh: &std::path::Path, texture: &std::path::Path) -> Result<SystemRow> {
    use crate::synthesis::exemplar::{TextureInput, TextureParams, synthesize_texture};
    let t = Instant::now();
    let mut target = crate::mesh::io::load(mesh)?;
    target.repair()?;
    let (tex, alpha) = crate::mesh::io::load_texture_with_alpha(texture)?;
    let input = TextureInput {
        exemplar: &tex.image,
        alpha: alpha.as_ref(),
        target: &target,
        field: None,
    };
    let r = synthesize_texture(
        &input,
        &TextureParams::default(),
        &|_| {},
        &CancelToken::new(),
    )?;
    let name = |p: &std::path::Path| {
        p.file_name()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default()
    };
    Ok(SystemRow {
        case: format!(
            "synth {} into {}'s texture ({}, {}² working, exemplar {} px wide, {})",
            name(texture),
            name(mesh),
            if r.atlas.is_some() {
                "atlas"
            } else {
                "own UVs"
            },
            r.working_size,
            r.working_exemplar_width,
            r.orientation_used.as_str()
        ),
        vertices: r.level_texels.first().copied().unwrap_or(0),
        stages: vec![
            ("prepare".into(), r.timings.prepare),
            ("orientation".into(), r.timings.orientation),
            ("neighbourhoods".into(), r.timings.neighbourhoods),
            ("search".into(), r.timings.search),
            ("magnify".into(), r.timings.magnify),
        ],
        total_s: t.elapsed().as_secs_f64(),
        faces: 0,
        peak_rss_mb: peak_rss_mb(),
    })
}

/// The shared meshes (one level of folders under the data directory, robustness cases left out)
/// and textures (`textures/`), sorted.
fn shared_meshes_and_textures() -> (Vec<std::path::PathBuf>, Vec<std::path::PathBuf>) {
    let dir = crate::testdata::data_dir();
    let ext = |p: &std::path::Path| {
        p.extension()
            .and_then(|e| e.to_str())
            .map(|e| e.to_ascii_lowercase())
            .unwrap_or_default()
    };
    let mut meshes = Vec::new();
    let mut textures = Vec::new();
    for entry in std::fs::read_dir(&dir).into_iter().flatten().flatten() {
        let sub = entry.path();
        let robustness = sub.file_name().is_some_and(|n| n == "robustness");
        for f in std::fs::read_dir(&sub).into_iter().flatten().flatten() {
            let p = f.path();
            match ext(&p).as_str() {
                "obj" | "ply" | "glb" | "gltf" if !robustness => meshes.push(p),
                "png" | "jpg" | "jpeg" if sub.file_name().is_some_and(|n| n == "textures") => {
                    textures.push(p)
                }
                _ => {}
            }
        }
    }
    meshes.sort();
    textures.sort();
    (meshes, textures)
}

/// `row` for every shared mesh with every shared texture, printed as each finishes (a failed
/// pair prints its error, `synth TEXTURE <joiner> MESH: ...`).
pub(super) fn every_shared_pair(
    row: fn(&std::path::Path, &std::path::Path) -> Result<SystemRow>,
    joiner: &str,
    json: bool,
) {
    let (meshes, textures) = shared_meshes_and_textures();
    for m in &meshes {
        for t in &textures {
            match row(m, t) {
                Ok(r) => print_rows(vec![r], json),
                Err(e) => println!("synth {} {joiner} {}: {e}", t.display(), m.display()),
            }
        }
    }
}

/// `meshmatch bench --system synth-character`: for each shared mesh and image (or the pairs in
/// `MESHMATCH_PAIRS`, `mesh.obj:image.png,...` by file name), what `synth` gives with its
/// defaults for a textured output (patch pasting), with `--method neighbourhood` (Wei-Levoy in
/// texture space), and triplanar projection at the same scale, all in the same layout, measured
/// texel by texel ([`crate::synthesis::exemplar::character`]); `MESHMATCH_METHODS` picks
/// among `patches,neighbourhood,triplanar`, `MESHMATCH_SEED` the synthesis's seed.
pub fn synth_character_rows(json: bool) -> Result<()> {
    use crate::synthesis::exemplar::character::{
        Exemplar, SAMPLES, measure_with, triplanar_texture,
    };
    use crate::synthesis::exemplar::patch_pasting::paste_patches;
    use crate::synthesis::exemplar::{TextureInput, TextureParams, synthesize_texture};
    let (meshes, textures) = shared_meshes_and_textures();
    let wanted: Option<Vec<(String, String)>> = std::env::var("MESHMATCH_PAIRS").ok().map(|v| {
        v.split(',')
            .filter_map(|p| p.split_once(':'))
            .map(|(m, t)| (m.to_string(), t.to_string()))
            .collect()
    });
    let name = |p: &std::path::Path| {
        p.file_name()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default()
    };
    if !json {
        println!(
            "| mesh x image | method | contrast | Lab W1 | patch distance | reverse distance | seconds |"
        );
        println!("| --- | --- | ---: | ---: | ---: | ---: | ---: |");
    }
    // the settings every pair shares, read once
    let samples = match std::env::var("MESHMATCH_MEASURE_SAMPLES") {
        Err(_) => SAMPLES,
        Ok(v) => v.parse().map_err(|_| {
            crate::error::Error::InvalidInput(format!(
                "MESHMATCH_MEASURE_SAMPLES: '{v}' is not a count"
            ))
        })?,
    };
    let methods = std::env::var("MESHMATCH_METHODS")
        .unwrap_or_else(|_| "patches,neighbourhood,triplanar".into());
    let mut params = TextureParams::default();
    if let Ok(v) = std::env::var("MESHMATCH_SEED") {
        params.synth.seed = v.parse().map_err(|_| {
            crate::error::Error::InvalidInput(format!("MESHMATCH_SEED: '{v}' is not a seed"))
        })?;
    }
    let patch_params = patch_params()?;
    for m in &meshes {
        for t in &textures {
            if let Some(w) = &wanted
                && !w.iter().any(|(wm, wt)| *wm == name(m) && *wt == name(t))
            {
                continue;
            }
            let mut target = crate::mesh::io::load(m)?;
            target.repair()?;
            let (tex, alpha) = crate::mesh::io::load_texture_with_alpha(t)?;
            let (lo, hi) = target.bounds().unwrap_or(([0.0; 3], [0.0; 3]));
            let scale = glam::Vec3::from(hi).distance(glam::Vec3::from(lo)) / 4.0;
            let ex = Exemplar {
                image: &tex.image,
                alpha: alpha.as_ref(),
                scale,
            };
            let input = TextureInput {
                exemplar: &tex.image,
                alpha: alpha.as_ref(),
                target: &target,
                field: None,
            };
            let cancel = CancelToken::new();
            // patch pasting lays the texture out (the target's UVs or an atlas); the others
            // go into the same layout
            let t0 = Instant::now();
            let patches = paste_patches(&input, &params, &patch_params, &|_| {}, &cancel)?;
            let secs = t0.elapsed().as_secs_f64();
            let laid = &patches.mesh;
            let texture = |m: &crate::mesh::TriMesh| m.texture.as_ref().map(|x| x.image.clone());
            for method in methods.split(',') {
                let (tx, secs) = match method {
                    "patches" => (texture(laid), secs),
                    "neighbourhood" => {
                        let mut m = target.clone();
                        m.uvs.clone_from(&laid.uvs);
                        let t0 = Instant::now();
                        let r = synthesize_texture(
                            &TextureInput {
                                target: &m,
                                ..input
                            },
                            &params,
                            &|_| {},
                            &cancel,
                        )?;
                        (texture(&r.mesh), t0.elapsed().as_secs_f64())
                    }
                    "triplanar" => (
                        triplanar_texture(laid, &ex, params.texture_size as usize),
                        0.0,
                    ),
                    _ => continue,
                };
                if let Some(tx) = tx
                    && let Some(c) = measure_with(laid, &tx, &ex, 1, samples)
                {
                    print_character(json, &name(m), &name(t), method, &c, secs);
                }
            }
        }
    }
    Ok(())
}

/// The patch parameters: the defaults, or `MESHMATCH_PATCH_PARAMS` (JSON, e.g.
/// `{"radius":0.35,"feather":0.05}`; fields left out keep their defaults) to compare settings.
fn patch_params() -> Result<crate::synthesis::exemplar::patch_pasting::PatchParams> {
    match std::env::var("MESHMATCH_PATCH_PARAMS") {
        Err(_) => Ok(Default::default()),
        Ok(v) => serde_json::from_str(&v)
            .map_err(|e| crate::error::Error::InvalidInput(format!("MESHMATCH_PATCH_PARAMS: {e}"))),
    }
}

fn print_character(
    json: bool,
    mesh: &str,
    image: &str,
    method: &str,
    c: &crate::synthesis::exemplar::character::Character,
    secs: f64,
) {
    if json {
        println!(
            "{}",
            serde_json::json!({"mesh": mesh, "image": image, "method": method, "character": c, "seconds": secs})
        );
    } else {
        println!(
            "| {mesh} x {image} | {method} | {:.2} | {:.1} | {:.1} | {:.1} | {:.1} |",
            c.contrast, c.lab_w1, c.patch_distance, c.reverse_distance, secs
        );
    }
}
