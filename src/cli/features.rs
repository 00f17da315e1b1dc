//! `meshmatch features`: the geometric features of a mesh (the ambient occlusion, curvature,
//! cavity, thickness, normal and height bakes texturing tools offer), from the features of the
//! geometry-correlated transfer: as vertex colours (.ply), or baked into textures in the mesh's
//! UVs or a generated atlas (.png maps, 8 or 16 bits; a textured .glb, .gltf or .obj).

use std::path::PathBuf;

use super::common::*;
use crate::error::{Error, Result};
use crate::synthesis::weathering::feature_maps::{self, MapParams};
use crate::synthesis::weathering::{self, Params, Up};
use crate::work::CancelToken;

/// Arguments of `meshmatch features`.
#[derive(clap::Args, Debug)]
pub struct FeaturesArgs {
    /// The mesh.
    pub mesh: PathBuf,
    /// Output: .png bakes the map(s) into textures in the mesh's UVs (or a generated atlas);
    /// .glb, .gltf or .obj writes the mesh textured with the map; .ply writes the feature as grey
    /// vertex colours on the mesh's own vertices. Several maps go to <stem>_<map>.<ext> beside it.
    #[arg(long)]
    pub out: PathBuf,
    /// Baked maps (.png, .glb, .gltf, .obj): all, or ao, curvature, cavity, thickness, normal,
    /// height (comma-separated). Vertex colours (.ply): ao, height, curvature[:i] (i = 0..3,
    /// radius index, small to large), normal-x|y|z, occlusion-x|y|z, or one of the maps.
    #[arg(long, default_value = "ao")]
    pub feature: String,
    /// Side of the baked textures in pixels.
    #[arg(long, default_value_t = 2048, allow_negative_numbers = true, value_parser = TEXTURE_SIZE)]
    pub texture_size: u32,
    /// Bits per channel of baked PNG maps: 8 or 16.
    #[arg(long, default_value_t = 8, allow_negative_numbers = true)]
    pub bits: u8,
    /// Curvature radius of the curvature map, fraction of the bounding-box diagonal.
    #[arg(long, default_value_t = MapParams::default().radius, allow_negative_numbers = true)]
    pub radius: f32,
    /// Radius of the cavity map's fine-scale curvature, fraction of the diagonal.
    #[arg(long, default_value_t = MapParams::default().cavity_radius, allow_negative_numbers = true)]
    pub cavity_radius: f32,
    /// Lay out a new atlas even if the mesh has UVs.
    #[arg(long)]
    pub new_atlas: bool,
    /// The object's up axis, for height: y or z.
    #[arg(long, default_value = "y")]
    pub up: String,
    /// Occlusion rays per vertex, 1 to 4096.
    #[arg(long, default_value_t = Params::default().rays, allow_negative_numbers = true, value_parser = RAYS)]
    pub rays: usize,
    /// Random seed (ray directions).
    #[arg(long, default_value_t = 0, allow_negative_numbers = true, value_parser = SEED)]
    pub seed: u64,
}

impl FeaturesArgs {
    /// Run the subcommand; returns the exit code.
    pub fn run(&self) -> Result<i32> {
        let up: Up = self.up.parse()?;
        check_rays(self.rays)?;
        // every range before any file is read, whichever output is asked for
        feature_maps::check_map_params(&self.map_params(up))?;
        if !matches!(self.bits, 8 | 16) {
            return Err(Error::InvalidInput(format!(
                "--bits {}: use 8 or 16",
                self.bits
            )));
        }
        let ext = self
            .out
            .extension()
            .and_then(|e| e.to_str())
            .unwrap_or("")
            .to_ascii_lowercase();
        let is_map = feature_maps::parse_map_names(&self.feature).is_ok();
        if ext == "png" || (matches!(ext.as_str(), "glb" | "gltf" | "obj") && is_map) {
            return self.bake(up, ext == "png");
        }
        if ext == "ply" && is_map && weathering::check_feature_name(&self.feature, 4).is_err() {
            return self.vertex_maps(up);
        }
        check_outputs(&[&self.mesh], &[("--out", &self.out, OutKind::Mesh)])?;
        let mut units = WorkingUnits::new();
        let mesh = units.load(&self.mesh)?;
        let params = Params {
            up,
            rays: self.rays,
            seed: self.seed,
            ..Params::default()
        };
        weathering::check_feature_name(&self.feature, params.curvature_radii.len())?;
        let t = std::time::Instant::now();
        let field = feature_values(&mesh, &self.feature, &params, &CancelToken::new())?;
        let (lo, hi) = field
            .iter()
            .filter(|x| x.is_finite())
            .fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), &x| {
                (a.min(x), b.max(x))
            });
        if !(lo.is_finite() && hi.is_finite()) {
            return Err(Error::InvalidInput(format!(
                "feature '{}' has no finite value on this mesh",
                self.feature
            )));
        }
        // Occlusion and height have natural [0, 1] ranges; others are stretched to [0, 1].
        let natural = matches!(self.feature.as_str(), "ao" | "height") && lo >= 0.0 && hi <= 1.0;
        let (lo, hi) = if natural { (0.0, 1.0) } else { (lo, hi) };
        let span = (hi - lo).max(1e-12);
        let grey: Vec<[f32; 3]> = field
            .iter()
            .map(|&x| {
                let g = ((x - lo) / span).clamp(0.0, 1.0);
                [g, g, g]
            })
            .collect();
        let mut out = mesh.clone();
        out.colors = Some(grey);
        out.texture = None;
        units.save(&out, &self.out)?;
        eprintln!(
            "feature {} in {:.2} s: range {lo:.4} .. {hi:.4}{}",
            self.feature,
            t.elapsed().as_secs_f64(),
            if natural {
                ""
            } else {
                " (stretched to black .. white)"
            }
        );
        crate::cli::common::announce_written(&self.out);
        Ok(0)
    }
}

impl FeaturesArgs {
    fn map_params(&self, up: Up) -> MapParams {
        MapParams {
            texture_size: self.texture_size,
            radius: self.radius,
            cavity_radius: self.cavity_radius,
            rays: self.rays,
            seed: self.seed,
            up,
            new_atlas: self.new_atlas,
        }
    }

    /// The outputs `names` go to (`--out` itself for one map).
    fn outputs(&self, names: &[&str]) -> Vec<PathBuf> {
        names
            .iter()
            .map(|n| feature_maps::map_path(&self.out, n, names.len() == 1))
            .collect()
    }

    /// Maps baked into textures: PNGs (`png`), else textured meshes.
    fn bake(&self, up: Up, png: bool) -> Result<i32> {
        let names = feature_maps::parse_map_names(&self.feature)?;
        check_texture_size(self.texture_size)?;
        if !matches!(self.bits, 8 | 16) {
            return Err(Error::InvalidInput(format!(
                "--bits {}: use 8 or 16",
                self.bits
            )));
        }
        if !png && self.bits != 8 {
            return Err(Error::InvalidInput(format!(
                "--bits {}: a mesh's texture has 8 bits; write .png maps for 16",
                self.bits
            )));
        }
        let params = self.map_params(up);
        feature_maps::check_map_params(&params)?;
        let outs = self.outputs(&names);
        let kind = if png { OutKind::Png } else { OutKind::Mesh };
        let checks: Vec<(&str, &std::path::Path, OutKind)> =
            outs.iter().map(|p| ("--out", p.as_path(), kind)).collect();
        check_outputs(&[&self.mesh], &checks)?;
        let mut units = WorkingUnits::new();
        let mesh = units.load(&self.mesh)?;
        let t = std::time::Instant::now();
        let bar = progress_bar();
        bar.set_message("feature maps");
        let maps = feature_maps::bake_feature_maps(
            &mesh,
            &names,
            &params,
            &|f| bar.set_position((f * 1000.0) as u64),
            &CancelToken::new(),
        )?;
        bar.finish_and_clear();
        if let Some(a) = &maps.atlas {
            eprintln!(
                "generated a UV atlas: {} charts, {:.0}% of the texture, {:.1} texels per unit",
                a.charts,
                100.0 * a.utilization,
                a.texels_per_unit / units.unit() as f32,
            );
        }
        for m in &maps.maps {
            eprintln!("{}: {}", m.name, m.scale);
        }
        eprintln!(
            "baked {} map(s) of {} vertices into {}x{} texels in {:.2} s",
            maps.maps.len(),
            mesh.num_vertices(),
            self.texture_size,
            self.texture_size,
            t.elapsed().as_secs_f64()
        );
        if png {
            for p in feature_maps::save_map_pngs(&maps, &self.out, self.bits)? {
                crate::cli::common::announce_written(&p);
            }
        } else {
            for (m, p) in maps.maps.iter().zip(&outs) {
                units.save(&feature_maps::textured_with(&mesh, &maps, m), p)?;
                crate::cli::common::announce_written(p);
            }
        }
        Ok(0)
    }

    /// Maps as vertex colours (.ply).
    fn vertex_maps(&self, up: Up) -> Result<i32> {
        let names = feature_maps::parse_map_names(&self.feature)?;
        let params = self.map_params(up);
        feature_maps::check_map_params(&params)?;
        let outs = self.outputs(&names);
        let checks: Vec<(&str, &std::path::Path, OutKind)> = outs
            .iter()
            .map(|p| ("--out", p.as_path(), OutKind::Mesh))
            .collect();
        check_outputs(&[&self.mesh], &checks)?;
        let mut units = WorkingUnits::new();
        let mesh = units.load(&self.mesh)?;
        let t = std::time::Instant::now();
        let vm = feature_maps::vertex_maps(&mesh, &names, &params, &CancelToken::new())?;
        eprintln!("{} map(s) in {:.2} s", vm.len(), t.elapsed().as_secs_f64());
        for (m, p) in vm.iter().zip(&outs) {
            let c = m.channels;
            let mut out = mesh.clone();
            out.colors = Some(
                (0..mesh.num_vertices())
                    .map(|v| std::array::from_fn(|k| m.values[v * c + k.min(c - 1)]))
                    .collect(),
            );
            out.texture = None;
            units.save(&out, p)?;
            eprintln!("{}: {}", m.name, m.scale);
            crate::cli::common::announce_written(p);
        }
        Ok(0)
    }
}

/// One feature of `meshmatch features` (`ao`, `height`, `curvature[:i]`, `normal-x|y|z`,
/// `occlusion-x|y|z`) per vertex of a mesh in memory, as the system computes it (not stretched
/// to grey). The CLI and the Python package call it.
pub fn feature_values(
    mesh: &crate::mesh::TriMesh,
    feature: &str,
    params: &Params,
    cancel: &CancelToken,
) -> Result<Vec<f32>> {
    check_rays(params.rays)?;
    weathering::check_feature_name(feature, params.curvature_radii.len())?;
    let fs = weathering::features(&mesh.positions, &mesh.faces, params, cancel)?;
    weathering::feature_field(&fs, feature)
}
