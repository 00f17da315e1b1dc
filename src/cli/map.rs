//! `meshmatch map`: the global intrinsic shape map between two meshes (functional maps +
//! ZoomOut) as a CSV of target vertex -> source vertex.

use std::path::PathBuf;

use super::common::*;
use crate::correspondence::CorrespondenceFile;
use crate::error::Result;
use crate::work::CancelToken;

/// Arguments of `meshmatch map`.
#[derive(clap::Args, Debug)]
pub struct MapArgs {
    /// Source mesh (OBJ, PLY, glTF/GLB).
    #[arg(long)]
    pub source: PathBuf,
    /// Target mesh.
    #[arg(long)]
    pub target: PathBuf,
    /// Correspondences JSON (as `transfer` reads it), used as landmarks; they also break
    /// left/right symmetry, which the map cannot tell apart on its own.
    #[arg(long)]
    pub correspondences: Option<PathBuf>,
    /// Output CSV: a header line `target_vertex,source_vertex`, then one line per target file
    /// vertex in file order, both indices in file numbering (0-based).
    #[arg(long)]
    pub out: PathBuf,
}

impl MapArgs {
    /// Run the subcommand; returns the exit code.
    pub fn run(&self) -> Result<i32> {
        let inputs = input_paths(&[
            Some(&self.source),
            Some(&self.target),
            self.correspondences.as_ref(),
        ]);
        check_outputs(&inputs, &[("--out", self.out.as_path(), OutKind::File)])?;
        let mut units = WorkingUnits::new();
        let source = units.load(&self.source)?;
        let target = units.load(&self.target)?;
        let corr = match &self.correspondences {
            Some(p) => CorrespondenceFile::load_for(p, Some(&source), Some(&target))?,
            None => Vec::new(),
        };
        let t = std::time::Instant::now();
        let m = crate::meshmatch::map_meshes(&source, &target, &corr, &CancelToken::new())?;
        let mut s = String::with_capacity(16 * m.target_to_source.len() + 32);
        s.push_str("target_vertex,source_vertex\n");
        for (t, src) in m.target_to_source.iter().enumerate() {
            s.push_str(&format!("{t},{src}\n"));
        }
        crate::mesh::io::write_atomic(&self.out, s.as_bytes())?;
        crate::cli::common::announce(format!(
            "map of {} target vertices computed in {:.2} s on {} x {} vertices (k = {}, isometry score {:.2}); wrote {}",
            m.target_to_source.len(),
            t.elapsed().as_secs_f64(),
            m.map_vertices.0,
            m.map_vertices.1,
            m.k,
            m.score,
            self.out.display()
        ));
        for (name, s) in &m.timings {
            eprintln!("  {name:<12} {s:8.3} s");
        }
        Ok(0)
    }
}
