//! `meshmatch complete`.

use std::path::PathBuf;

use super::common::*;
use crate::error::{Error, Result};
use crate::mesh::io;
use crate::work::{CancelToken, Event};

/// Arguments of `meshmatch complete`.
#[derive(clap::Args, Debug)]
pub struct CompleteArgs {
    /// The mesh (its vertex colours or texture are the example unless --painted is given).
    #[arg(long)]
    pub mesh: PathBuf,
    /// A copy of the mesh (same vertices) whose vertex colours mark the painted vertices: a vertex
    /// is unpainted when its 8-bit colour equals the clay colour (--clay, default: the most
    /// frequent colour); its colours are the example.
    #[arg(long, conflicts_with = "mask")]
    pub painted: Option<PathBuf>,
    /// Text file listing the vertex indices to synthesise, one per line ('#' starts a comment).
    #[arg(long)]
    pub mask: Option<PathBuf>,
    /// Clay (unpainted) colour as R,G,B in 0-255, for --painted.
    #[arg(long)]
    pub clay: Option<String>,
    /// Output: the mesh with vertex colours (.ply), or with a texture baked into its UVs (or a
    /// generated atlas), the example read at full resolution (.glb, .gltf, .obj).
    #[arg(long)]
    pub out: PathBuf,
    /// Size of the baked texture (pixels per side) for .glb/.obj outputs, 1 to 8192 (default:
    /// the mesh's texture's size, else 2048).
    #[arg(long, allow_negative_numbers = true, value_parser = TEXTURE_SIZE)]
    pub texture_size: Option<u32>,
    #[command(flatten)]
    pub solve: SolveArgs,
}

impl CompleteArgs {
    /// Run the subcommand; returns the exit code.
    pub fn run(&self) -> Result<i32> {
        complete(self)
    }
}

fn complete(a: &CompleteArgs) -> Result<i32> {
    let params = a.solve.params(1.0)?;
    if let Some(size) = a.texture_size {
        check_texture_size(size)?;
    }
    let inputs = input_paths(&[Some(&a.mesh), a.painted.as_ref(), a.mask.as_ref()]);
    check_outputs(&inputs, &[("--out", &a.out, OutKind::Mesh)])?;
    let mut mesh = load_usable(&a.mesh)?;
    let synth = match (&a.painted, &a.mask) {
        (Some(p), _) => {
            let painted = load_usable(p)?;
            if painted.file_vertex_count != mesh.file_vertex_count {
                return Err(Error::InvalidInput(format!(
                    "{}: has {} vertices but {} has {}",
                    p.display(),
                    painted.file_vertex_count,
                    a.mesh.display(),
                    mesh.file_vertex_count
                )));
            }
            let clay = a.clay.as_deref().map(parse_rgb).transpose()?;
            let synth = crate::applications::unpainted_mask(&painted, clay)?;
            // The painted copy's colours are the example, on the mesh's own vertices.
            let cols =
                painted.to_file_order(&painted.vertex_signal().unwrap_or_default(), [0.0; 3]);
            mesh.colors = Some(
                mesh.file_index
                    .iter()
                    .map(|&f| cols.get(f as usize).copied().unwrap_or([0.0; 3]))
                    .collect(),
            );
            mesh.texture = None;
            synth
        }
        (None, Some(m)) => read_mask(m, mesh.file_vertex_count)?,
        (None, None) => {
            return Err(Error::InvalidInput(
                "complete needs --painted or --mask".into(),
            ));
        }
    };
    let bar = progress_bar();
    let sink = |e: Event| bar_sink(&bar, e);
    let t = std::time::Instant::now();
    let r = crate::applications::complete(&mesh, &synth, &params, &sink, &CancelToken::new())?;
    bar.finish_and_clear();
    eprintln!(
        "completed {} of {} vertices in {:.2} s (energy {:.4})",
        synth.iter().filter(|&&s| s).count(),
        synth.len(),
        t.elapsed().as_secs_f64(),
        r.energy
    );
    let colors: Vec<[f32; 3]> = mesh
        .file_index
        .iter()
        .map(|&f| r.colors[f as usize])
        .collect();
    let out = with_result(
        &mesh,
        colors,
        r.full.as_ref(),
        &a.out,
        texture_side(a.texture_size, &mesh),
    )?;
    io::save(&out, &a.out)?;
    eprintln!("wrote {}", a.out.display());
    Ok(0)
}
