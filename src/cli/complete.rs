//! `meshmatch complete`.

use std::path::PathBuf;

use super::common::*;
use crate::error::{Error, Result};
use crate::mesh::TriMesh;
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
    /// Size of the baked texture (pixels per side) for .glb/.obj outputs, 20 to 8192 (default:
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
    let mut units = WorkingUnits::new();
    let mesh = units.load(&a.mesh)?;
    let clay = a.clay.as_deref().map(parse_rgb).transpose()?;
    let painted = a.painted.as_deref().map(|p| units.load(p)).transpose()?;
    let example = match (&painted, &a.mask) {
        (Some(p), _) => Example::Painted(p, clay),
        (None, Some(m)) => Example::Mask(read_mask(m, mesh.file_vertex_count)?),
        (None, None) => {
            return Err(Error::InvalidInput(
                "complete needs --painted or --mask".into(),
            ));
        }
    };
    let bar = progress_bar();
    let sink = |e: Event| bar_sink(&bar, e);
    let t = std::time::Instant::now();
    let ext = a.out.extension().and_then(|e| e.to_str()).unwrap_or("");
    let c = complete_mesh(
        mesh,
        example,
        &params,
        ext,
        a.texture_size,
        &sink,
        &CancelToken::new(),
    )?;
    bar.finish_and_clear();
    eprintln!(
        "completed {} of {} vertices in {:.2} s (energy {:.4})",
        c.synthesized,
        c.vertices,
        t.elapsed().as_secs_f64(),
        c.energy
    );
    units.save(&c.mesh, &a.out)?;
    crate::cli::common::announce_written(&a.out);
    Ok(0)
}

/// Where `complete` takes its example from.
pub enum Example<'a> {
    /// A copy of the mesh (same file vertices) whose colours are the example; its vertices of
    /// the clay colour (default: the most frequent colour) are synthesised (`--painted`).
    Painted(&'a TriMesh, Option<[f32; 3]>),
    /// Per file vertex, whether to synthesise it; the mesh's own colours or texture are the
    /// example (`--mask`).
    Mask(Vec<bool>),
}

/// A completion computed in memory ([`complete_mesh`]).
pub struct Completed {
    /// The mesh with the result, as `--out` writes it for a path ending in the given extension.
    pub mesh: TriMesh,
    /// Vertices synthesised, and vertices in all.
    pub synthesized: usize,
    /// See `synthesized`.
    pub vertices: usize,
    /// The solve's final energy.
    pub energy: f64,
}

/// `meshmatch complete` on a mesh in memory (checked as [`load_usable`] checks files): the
/// result on the mesh's vertices (`ext` `ply`), or also baked into a texture of
/// `texture_size` (default: the mesh's texture's size, else 2048) for `glb`/`gltf`/`obj`. The
/// CLI and the Python package call it.
pub fn complete_mesh(
    mut mesh: TriMesh,
    example: Example,
    params: &crate::meshmatch::TransferParams,
    ext: &str,
    texture_size: Option<u32>,
    sink: &dyn Fn(Event),
    cancel: &CancelToken,
) -> Result<Completed> {
    params.validate()?;
    if let Some(size) = texture_size {
        check_texture_size(size)?;
    }
    let name = |m: &TriMesh| {
        m.path
            .as_ref()
            .map(|p| p.display().to_string())
            .unwrap_or_else(|| "the painted mesh".into())
    };
    let synth = match example {
        Example::Painted(painted, clay) => {
            if painted.file_vertex_count != mesh.file_vertex_count {
                return Err(Error::InvalidInput(format!(
                    "{}: has {} vertices but {} has {}",
                    name(painted),
                    painted.file_vertex_count,
                    mesh.path
                        .as_ref()
                        .map(|p| p.display().to_string())
                        .unwrap_or_else(|| "the mesh".into()),
                    mesh.file_vertex_count
                )));
            }
            let synth = crate::applications::unpainted_mask(painted, clay)?;
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
        Example::Mask(m) => {
            if m.len() != mesh.file_vertex_count {
                return Err(Error::InvalidInput(format!(
                    "the mask has {} entries but the mesh has {} vertices",
                    m.len(),
                    mesh.file_vertex_count
                )));
            }
            m
        }
    };
    let size = texture_side(texture_size, &mesh);
    let r = crate::applications::complete(&mesh, &synth, params, sink, cancel)?;
    let colors: Vec<[f32; 3]> = mesh
        .file_index
        .iter()
        .map(|&f| r.colors[f as usize])
        .collect();
    let out = with_result(
        &mesh,
        colors,
        r.full.as_ref(),
        std::path::Path::new(&format!("out.{ext}")),
        size,
    )?;
    Ok(Completed {
        mesh: out,
        synthesized: synth.iter().filter(|&&s| s).count(),
        vertices: synth.len(),
        energy: r.energy,
    })
}
