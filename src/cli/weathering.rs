//! `meshmatch weather`: geometry-correlated texture transfer (Mertens et al. 2006): weathering,
//! dirt and moss learned from one textured model and applied to another by its geometry.

use std::path::PathBuf;

use super::common::*;
use crate::error::{Error, Result};
use crate::synthesis::weathering::{self, Mean, Method, Params, Up};
use crate::work::CancelToken;

/// Most `--clusters`.
const MAX_CLUSTERS: usize = 1000;

/// Arguments of `meshmatch weather`.
#[derive(clap::Args, Debug)]
pub struct WeatherArgs {
    /// Textured source (vertex colours or a UV texture): the look to learn.
    #[arg(long)]
    pub source: PathBuf,
    /// Texture image for the source (overrides the one its material names; needs UVs).
    #[arg(long)]
    pub source_texture: Option<PathBuf>,
    /// The shape to texture (no correspondences needed).
    #[arg(long)]
    pub target: PathBuf,
    /// Output: .ply (vertex colours), .glb or .gltf (baked texture if the target has UVs, else COLOR_0),
    /// .obj (+MTL+PNG), exactly as `transfer`.
    #[arg(long)]
    pub out: PathBuf,
    /// Also write the dense working-resolution target with its colours.
    #[arg(long)]
    pub out_dense: Option<PathBuf>,
    /// parametric (histogram matching per cluster; the default) or nonparametric.
    #[arg(long, default_value = "parametric")]
    pub method: String,
    /// The parametric method's mean colour: neighbours (a regression on the features, which
    /// keeps threshold-like rules; the default) or affine (the paper's per-cluster affine maps).
    #[arg(long, default_value = "neighbours")]
    pub mean: String,
    /// Source vertices (file numbering, one per line) to leave out of training.
    #[arg(long)]
    pub mask: Option<PathBuf>,
    /// The objects' up axis, for the height feature: y or z.
    #[arg(long, default_value = "y")]
    pub up: String,
    /// Working vertices per mesh (meshes are refined to about this many), at most 4,000,000.
    #[arg(long, default_value_t = Params::default().working_vertices, allow_negative_numbers = true,
          value_parser = whole(0, crate::mesh::MAX_WORKING_VERTICES).unit("working vertices"))]
    pub vertices: usize,
    /// Occlusion rays per vertex, 1 to 4096.
    #[arg(long, default_value_t = Params::default().rays, allow_negative_numbers = true, value_parser = RAYS)]
    pub rays: usize,
    /// Clusters of the guidance field (the paper's only parameter), 1 to 1000.
    #[arg(long, default_value_t = Params::default().clusters, allow_negative_numbers = true,
          value_parser = whole(1, MAX_CLUSTERS).unit("clusters"))]
    pub clusters: usize,
    /// Random seed.
    #[arg(long, default_value_t = 0, allow_negative_numbers = true, value_parser = SEED)]
    pub seed: u64,
    /// Canonical components (CCA directions, 0 = strongest) to keep, e.g. 0,2: a component
    /// switched off drops the rule it carries (the report lists what each one weighs). All by
    /// default.
    #[arg(long)]
    pub components: Option<String>,
    /// Size of the baked texture (pixels per side) when the target has UVs, 20 to 8192.
    #[arg(long, default_value_t = 1024, allow_negative_numbers = true, value_parser = TEXTURE_SIZE)]
    pub texture_size: u32,
}

impl WeatherArgs {
    /// Run the subcommand; returns the exit code.
    pub fn run(&self) -> Result<i32> {
        let a = self;
        let method: Method = a.method.parse()?;
        let mean: Mean = a.mean.parse()?;
        let up: Up = a.up.parse()?;
        check_weather(a.vertices, a.rays, a.clusters, a.texture_size)?;
        let components = match &a.components {
            Some(c) => {
                let keep = weathering::parse_components(c)?;
                weathering::check_components(&keep, Params::default().cca_dims)?;
                Some(keep)
            }
            None => None,
        };
        let inputs = input_paths(&[
            Some(&a.source),
            Some(&a.target),
            a.source_texture.as_ref(),
            a.mask.as_ref(),
        ]);
        let mut outputs = vec![("--out", a.out.as_path(), OutKind::Mesh)];
        if let Some(p) = &a.out_dense {
            outputs.push(("--out-dense", p, OutKind::Mesh));
        }
        check_outputs(&inputs, &outputs)?;
        let mut units = WorkingUnits::new();
        let source = units.load_signal_source(&a.source, a.source_texture.as_deref())?;
        let target = units.load(&a.target)?;
        let mask = match &a.mask {
            Some(p) => Some(read_mask(p, source.file_vertex_count)?),
            None => None,
        };
        let params = Params {
            working_vertices: a.vertices,
            up,
            rays: a.rays,
            clusters: a.clusters,
            method,
            mean,
            seed: a.seed,
            components,
            ..Params::default()
        };
        let bar = progress_bar();
        let sink = |e| bar_sink(&bar, e);
        let t = std::time::Instant::now();
        let ext = a.out.extension().and_then(|e| e.to_str()).unwrap_or("");
        let w = weather_meshes(
            &source,
            &target,
            mask.as_deref(),
            &params,
            ext,
            a.texture_size,
            &sink,
            &CancelToken::new(),
        )?;
        bar.finish_and_clear();
        let out = &w.output;
        eprintln!(
            "weather finished in {:.2} s ({} source and {} target vertices, {} training)",
            t.elapsed().as_secs_f64(),
            out.source_vertices,
            out.target.mesh.num_vertices(),
            out.report.training_vertices
        );
        eprintln!("which features matter (CCA weights, standardised):");
        eprint!("{}", out.report.to_text());
        for (name, s) in &out.timings {
            eprintln!("  {name:<12} {s:8.3} s");
        }
        let out_mesh = &w.delivered;
        if let Some(line) = out_mesh.atlas_line(a.texture_size) {
            eprintln!("{line}");
        }
        units.save(&out_mesh.mesh, &a.out)?;
        crate::cli::common::announce_written(&a.out);
        if let Some(dense) = &a.out_dense {
            let d = crate::meshmatch::deliver_dense(&out.target.mesh, &out.colors);
            units.save(&d, dense)?;
            crate::cli::common::announce_written(dense);
        }
        Ok(0)
    }
}

/// Refuse `weather` settings outside their ranges, in the CLI's words.
pub fn check_weather(
    vertices: usize,
    rays: usize,
    clusters: usize,
    texture_size: u32,
) -> Result<()> {
    check_texture_size(texture_size)?;
    check_rays(rays)?;
    if !(1..=MAX_CLUSTERS).contains(&clusters) {
        return Err(Error::InvalidInput(format!(
            "--clusters {clusters}: use 1 to {MAX_CLUSTERS}"
        )));
    }
    let max_v = crate::mesh::MAX_WORKING_VERTICES;
    if vertices > max_v {
        return Err(Error::InvalidInput(format!(
            "--vertices {vertices}: the working resolution is at most {max_v} vertices"
        )));
    }
    Ok(())
}

/// A weathering computed in memory ([`weather_meshes`]).
pub struct Weathered {
    /// The system's output (dense target, colours, report, timings).
    pub output: weathering::Output,
    /// The target with the result, as `--out` writes it.
    pub delivered: crate::meshmatch::Delivered,
}

/// `meshmatch weather` on meshes in memory (checked as [`load_usable`] checks files): the
/// target with the result on its vertices (`ext` `ply`), or also baked into a texture of
/// `texture_size` for `glb`/`gltf`/`obj`. The CLI and the Python package call it.
#[allow(clippy::too_many_arguments)]
pub fn weather_meshes(
    source: &crate::mesh::TriMesh,
    target: &crate::mesh::TriMesh,
    source_mask: Option<&[bool]>,
    params: &Params,
    ext: &str,
    texture_size: u32,
    sink: &dyn Fn(crate::work::Event),
    cancel: &CancelToken,
) -> Result<Weathered> {
    check_weather(
        params.working_vertices,
        params.rays,
        params.clusters,
        texture_size,
    )?;
    if source.vertex_signal().is_none() {
        return Err(Error::InvalidInput(
            "the source carries no texture or vertex colours to learn from".into(),
        ));
    }
    if let Some(m) = source_mask
        && m.len() != source.file_vertex_count
    {
        return Err(Error::InvalidInput(format!(
            "the mask has {} entries but the source has {} vertices",
            m.len(),
            source.file_vertex_count
        )));
    }
    let input = weathering::Input {
        source,
        target,
        source_mask,
    };
    let output = weathering::run(&input, params, sink, cancel)?;
    let layout = crate::meshmatch::BakeLayout::of_refined(target, &output.target);
    let delivered = crate::meshmatch::deliver(
        target,
        &layout,
        &output.colors,
        &output.file_colors,
        ext,
        texture_size,
        None,
        cancel,
    )?;
    Ok(Weathered { output, delivered })
}
