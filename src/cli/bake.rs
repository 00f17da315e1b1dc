//! `meshmatch bake`: the colours of a dense result (`synth`, `quilt`, `--out-dense` outputs, any
//! coloured mesh) baked into a texture on another mesh of the same shape, through its UVs or a
//! generated atlas: what game engines and DCC tools load.

use std::path::PathBuf;

use super::common::*;
use crate::error::{Error, Result};
use crate::geometry::bake_onto;
use crate::work::CancelToken;

/// Arguments of `meshmatch bake`.
#[derive(clap::Args, Debug)]
pub struct BakeArgs {
    /// The coloured mesh to bake from (vertex colours, or a texture with UVs).
    #[arg(long)]
    pub from: PathBuf,
    /// The mesh to bake onto (its UVs are kept; without UVs it gets a generated atlas).
    #[arg(long)]
    pub to: PathBuf,
    /// Output mesh with its texture (.glb, .gltf or .obj; the texture is a PNG beside an OBJ).
    #[arg(long)]
    pub out: PathBuf,
    /// Side of the baked texture in pixels.
    #[arg(long, default_value_t = 2048, allow_negative_numbers = true, value_parser = TEXTURE_SIZE)]
    pub texture_size: u32,
    /// Lay out a new atlas even if the mesh has UVs (overlapping or tiled UVs bake badly).
    #[arg(long)]
    pub new_atlas: bool,
}

impl BakeArgs {
    /// Run the subcommand; returns the exit code.
    pub fn run(&self) -> Result<i32> {
        check_texture_size(self.texture_size)?;
        let ext = self
            .out
            .extension()
            .and_then(|e| e.to_str())
            .unwrap_or("")
            .to_ascii_lowercase();
        if !matches!(ext.as_str(), "glb" | "gltf" | "obj") {
            return Err(Error::InvalidInput(format!(
                "{}: bake writes a textured .glb, .gltf or .obj",
                self.out.display()
            )));
        }
        check_outputs(
            &[&self.from, &self.to],
            &[("--out", &self.out, OutKind::Mesh)],
        )?;
        let mut units = WorkingUnits::new();
        let src = units.load(&self.from)?;
        let target = units.load(&self.to)?;
        let t = std::time::Instant::now();
        let bar = progress_bar();
        bar.set_message("UV atlas");
        let (target, atlas) = bake_mesh(
            &target,
            &src,
            self.texture_size,
            self.new_atlas,
            &|f| bar.set_position((f * 1000.0) as u64),
            &CancelToken::new(),
        )?;
        bar.finish_and_clear();
        if let Some(a) = atlas {
            eprintln!(
                "generated a UV atlas: {} charts, {:.0}% of the texture, {:.1} texels per unit",
                a.charts,
                100.0 * a.utilization,
                a.texels_per_unit / units.unit() as f32,
            );
        }
        eprintln!(
            "baked {} vertices' colours of {} into {}x{} texels in {:.2} s",
            src.num_vertices(),
            self.from.display(),
            self.texture_size,
            self.texture_size,
            t.elapsed().as_secs_f64()
        );
        units.save(&target, &self.out)?;
        crate::cli::common::announce_written(&self.out);
        Ok(0)
    }
}

/// `meshmatch bake` on meshes in memory: `from`'s colours (or texture) baked into a texture of
/// `texture_size` on `to`, through its UVs or a generated atlas (always one with `new_atlas`);
/// returns `to` with its texture and the atlas made, if any. The CLI and the Python package call
/// it.
pub fn bake_mesh(
    to: &crate::mesh::TriMesh,
    from: &crate::mesh::TriMesh,
    texture_size: u32,
    new_atlas: bool,
    progress: &(dyn Fn(f32) + Sync),
    cancel: &CancelToken,
) -> Result<(crate::mesh::TriMesh, Option<crate::geometry::UvAtlas>)> {
    check_texture_size(texture_size)?;
    let colors = from.vertex_signal().ok_or_else(|| {
        Error::InvalidInput(format!(
            "{}: has no colours or texture to bake",
            from.path
                .as_ref()
                .map(|p| p.display().to_string())
                .unwrap_or_else(|| "the mesh to bake from".into())
        ))
    })?;
    bake_onto(to, from, &colors, texture_size, new_atlas, progress, cancel)
}
