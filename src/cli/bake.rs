//! `meshmatch bake`: the colours of a dense result (`synth`, `quilt`, `--out-dense` outputs, any
//! coloured mesh) baked into a texture on another mesh of the same shape, through its UVs or a
//! generated atlas: what game engines and DCC tools load.

use std::path::PathBuf;

use super::common::*;
use crate::error::{Error, Result};
use crate::geometry::{AtlasParams, TriangleBvh, bake_closest, uv_atlas};
use crate::mesh::{Texture, io};
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
    #[arg(long, default_value_t = 2048)]
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
        let src = load_usable(&self.from)?;
        let colors = src.vertex_signal().ok_or_else(|| {
            Error::InvalidInput(format!(
                "{}: has no colours or texture to bake",
                self.from.display()
            ))
        })?;
        let mut target = load_usable(&self.to)?;
        let t = std::time::Instant::now();
        if target.uvs.is_none() || self.new_atlas {
            let params = AtlasParams {
                texture_size: self.texture_size,
                ..Default::default()
            };
            let bar = progress_bar();
            bar.set_message("UV atlas");
            let a = uv_atlas(
                &target.positions,
                &target.faces,
                &params,
                &|f| bar.set_position((f * 1000.0) as u64),
                &CancelToken::new(),
            )?;
            bar.finish_and_clear();
            eprintln!(
                "generated a UV atlas: {} charts, {:.0}% of the texture, {:.1} texels per unit ({:.2} s)",
                a.charts,
                100.0 * a.utilization,
                a.texels_per_unit,
                t.elapsed().as_secs_f64()
            );
            target.uvs = Some(a.uvs);
        }
        let t = std::time::Instant::now();
        let bvh = TriangleBvh::new(&src.positions, &src.faces);
        let size = self.texture_size as usize;
        let baked = bake_closest(
            &target.positions,
            &target.faces,
            target.uvs.as_deref().unwrap_or(&[]),
            size,
            &bvh,
            &src.faces,
            &colors,
        );
        let covered = baked.covered.iter().filter(|&&c| c).count();
        let mut image = image::RgbImage::new(self.texture_size, self.texture_size);
        for (p, c) in image.pixels_mut().zip(&baked.pixels) {
            p.0 = crate::color::to_u8(*c);
        }
        eprintln!(
            "baked {} of {} vertices' colours into {size}x{size} texels ({covered} on the surface) in {:.2} s",
            src.num_vertices(),
            self.from.display(),
            t.elapsed().as_secs_f64()
        );
        target.colors = None;
        target.texture = Some(std::sync::Arc::new(Texture { image, path: None }));
        io::save(&target, &self.out)?;
        eprintln!("wrote {}", self.out.display());
        Ok(0)
    }
}
