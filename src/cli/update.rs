//! `meshmatch update`.

use std::path::PathBuf;

use super::common::*;
use crate::error::{Error, Result};
use crate::mesh::TriMesh;
use crate::work::{CancelToken, Event};

/// Arguments of `meshmatch update`.
#[derive(clap::Args, Debug)]
pub struct UpdateArgs {
    /// The mesh before the edit, with its texture or vertex colours.
    #[arg(long)]
    pub old: PathBuf,
    /// The edited mesh.
    #[arg(long)]
    pub new: PathBuf,
    /// Output: the edited mesh with vertex colours (.ply), or with a texture baked into its UVs
    /// (or a generated atlas) from the old texture read at full resolution (.glb, .gltf, .obj).
    #[arg(long)]
    pub out: PathBuf,
    /// Size of the baked texture (pixels per side) for .glb/.obj outputs, 20 to 8192 (default:
    /// the old mesh's texture's size, else 2048).
    #[arg(long, allow_negative_numbers = true, value_parser = TEXTURE_SIZE)]
    pub texture_size: Option<u32>,
    #[command(flatten)]
    pub solve: SolveArgs,
}

impl UpdateArgs {
    /// Run the subcommand; returns the exit code.
    pub fn run(&self) -> Result<i32> {
        update(self)
    }
}

fn update(a: &UpdateArgs) -> Result<i32> {
    let params = a.solve.params(1.0)?;
    if let Some(size) = a.texture_size {
        check_texture_size(size)?;
    }
    check_outputs(&[&a.old, &a.new], &[("--out", &a.out, OutKind::Mesh)])?;
    let mut units = WorkingUnits::new();
    let old = units.load(&a.old)?;
    let new = units.load(&a.new)?;
    let bar = progress_bar();
    let sink = |e: Event| bar_sink(&bar, e);
    let t = std::time::Instant::now();
    let ext = a.out.extension().and_then(|e| e.to_str()).unwrap_or("");
    let (out, r) = update_mesh(
        &old,
        &new,
        &params,
        ext,
        a.texture_size,
        &sink,
        &CancelToken::new(),
    )?;
    bar.finish_and_clear();
    eprintln!(
        "updated: {} of {} vertices changed, {:.2} s (energy {:.4})",
        r.changed.iter().filter(|&&c| c).count(),
        r.changed.len(),
        t.elapsed().as_secs_f64(),
        r.energy
    );
    units.save(&out, &a.out)?;
    crate::cli::common::announce_written(&a.out);
    Ok(0)
}

/// `meshmatch update` on meshes in memory (checked as [`load_usable`] checks files): the new
/// mesh with the result on its vertices (`ext` `ply`), or also baked into a texture of
/// `texture_size` (default: the old mesh's texture's size, else 2048) for `glb`/`gltf`/`obj`;
/// and the update's report. The CLI and the Python package call it.
pub fn update_mesh(
    old: &TriMesh,
    new: &TriMesh,
    params: &crate::meshmatch::TransferParams,
    ext: &str,
    texture_size: Option<u32>,
    sink: &dyn Fn(Event),
    cancel: &CancelToken,
) -> Result<(TriMesh, crate::applications::UpdateResult)> {
    params.validate()?;
    if let Some(size) = texture_size {
        check_texture_size(size)?;
    }
    if old.vertex_signal().is_none() {
        return Err(Error::InvalidInput(format!(
            "{}: the old mesh carries no texture or vertex colours",
            old.path
                .as_ref()
                .map(|p| p.display().to_string())
                .unwrap_or_else(|| "old".into())
        )));
    }
    let r = crate::applications::update_texture(old, new, params, sink, cancel)?;
    let colors: Vec<[f32; 3]> = new
        .file_index
        .iter()
        .map(|&f| r.colors[f as usize])
        .collect();
    let out = with_result(
        new,
        colors,
        r.full.as_ref(),
        std::path::Path::new(&format!("out.{ext}")),
        texture_side(texture_size, old),
    )?;
    Ok((out, r))
}
