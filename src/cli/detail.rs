//! `meshmatch detail`.

use std::path::PathBuf;

use super::common::*;
use crate::error::Result;
use crate::work::{CancelToken, Event};

/// Arguments of `meshmatch detail`.
#[derive(clap::Args, Debug)]
pub struct DetailArgs {
    /// The detailed mesh to take the detail from.
    #[arg(long)]
    pub source: PathBuf,
    /// The smooth mesh to receive it.
    #[arg(long)]
    pub target: PathBuf,
    /// Output: the displaced target at the working resolution (.ply, .glb, .gltf, .obj).
    #[arg(long)]
    pub out: PathBuf,
    /// Scale of the transferred displacement (1 = the source's amplitude relative to its edge length).
    #[arg(long, default_value_t = 1.0, allow_hyphen_values = true)]
    pub strength: f32,
    #[command(flatten)]
    pub solve: SolveArgs,
}

impl DetailArgs {
    /// Run the subcommand; returns the exit code.
    pub fn run(&self) -> Result<i32> {
        detail(self)
    }
}

fn detail(a: &DetailArgs) -> Result<i32> {
    let params = a.solve.params(crate::applications::DETAIL_SHAPE_WEIGHT)?;
    check_strength(a.strength)?;
    check_outputs(&[&a.source, &a.target], &[("--out", &a.out, OutKind::Mesh)])?;
    let mut units = WorkingUnits::new();
    let source = units.load(&a.source)?;
    let target = units.load(&a.target)?;
    let bar = progress_bar();
    let sink = |e: Event| bar_sink(&bar, e);
    let t = std::time::Instant::now();
    let r = detail_mesh(
        &source,
        &target,
        a.strength,
        &params,
        &sink,
        &CancelToken::new(),
    )?;
    bar.finish_and_clear();
    let stat = |d: &[f32]| {
        let n = d.len().max(1) as f64;
        let m = d.iter().map(|&x| x as f64).sum::<f64>() / n;
        (
            m,
            (d.iter().map(|&x| (x as f64 - m).powi(2)).sum::<f64>() / n).sqrt(),
        )
    };
    let (ms, ss) = stat(&r.source_displacement);
    let (mt, st) = stat(&r.target_displacement);
    eprintln!(
        "detail transferred in {:.2} s: displacement (mean edge lengths) source mean {ms:.4} std {ss:.4}, result mean {mt:.4} std {st:.4}",
        t.elapsed().as_secs_f64()
    );
    units.save(&r.mesh, &a.out)?;
    crate::cli::common::announce(format!(
        "wrote {} ({} vertices)",
        a.out.display(),
        r.mesh.num_vertices()
    ));
    Ok(0)
}

/// Refuse a `--strength` that is not a finite number.
fn check_strength(strength: f32) -> Result<()> {
    if !strength.is_finite() {
        return Err(crate::error::Error::InvalidInput(format!(
            "--strength {strength}: must be a finite number"
        )));
    }
    Ok(())
}

/// `meshmatch detail` on meshes in memory (checked as [`load_usable`] checks files): the target
/// displaced at the working resolution, and the displacement statistics. The CLI and the
/// Python package call it.
pub fn detail_mesh(
    source: &crate::mesh::TriMesh,
    target: &crate::mesh::TriMesh,
    strength: f32,
    params: &crate::meshmatch::TransferParams,
    sink: &dyn Fn(crate::work::Event),
    cancel: &CancelToken,
) -> Result<crate::applications::DetailResult> {
    check_strength(strength)?;
    params.validate()?;
    crate::applications::transfer_detail(source, target, strength, params, sink, cancel)
}
