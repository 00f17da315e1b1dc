//! `meshmatch info`: counts, bounds, components, boundary loops, signal kind and repairs.

use std::io::Write;
use std::path::{Path, PathBuf};

use crate::error::Result;
use crate::mesh::io;

/// Arguments of `meshmatch info`.
#[derive(clap::Args, Debug)]
pub struct InfoArgs {
    /// Mesh files (.obj, .ply, .gltf, .glb).
    #[arg(required = true)]
    pub files: Vec<PathBuf>,
    /// One JSON object per line per file.
    #[arg(long)]
    pub json: bool,
}

impl InfoArgs {
    /// Run the subcommand; returns the exit code.
    pub fn run(&self) -> Result<i32> {
        Ok(info(&self.files, self.json))
    }
}

/// The `info` report of one file as a JSON object (loader warnings printed on stderr).
pub fn info_json(path: &Path) -> Result<serde_json::Value> {
    let (v, warnings) = info_report(path)?;
    io::print_warnings(&warnings);
    Ok(v)
}

/// The `info` report of one file and the loader's warnings (printed by the caller only on
/// success, so a refused file gives exactly one line on stderr).
fn info_report(path: &Path) -> Result<(serde_json::Value, Vec<String>)> {
    let (mesh, warnings) = io::load_with_warnings(path)?;
    // The budget and the other refusals first: `validate` allocates per vertex and face.
    mesh.check_usable()?;
    let report = mesh.validate();
    let mut repaired = mesh.clone();
    let repairs = repaired.repair()?;
    let (lo, hi) = mesh.bounds().unwrap_or(([0.0; 3], [0.0; 3]));
    let v = serde_json::json!({
        "path": path.display().to_string(),
        "vertices": mesh.file_vertex_count,
        "faces": mesh.num_faces(),
        "components": report.components,
        "boundary_loops": report.boundary_loops,
        "signal": mesh.signal_kind().as_str(),
        "uvs": mesh.uvs.is_some(),
        "normals": mesh.normals.is_some(),
        "texture": mesh.texture.as_ref().map(|t| format!("{}x{}", t.image.width(), t.image.height())),
        "bounds": {"min": lo, "max": hi},
        "area": mesh.area(),
        "non_manifold_edges": report.non_manifold_edges,
        "non_manifold_vertices": report.non_manifold_vertices,
        "degenerate_faces": report.degenerate_faces,
        "duplicate_faces": report.duplicate_faces,
        "isolated_vertices": report.isolated_vertices,
        "non_finite_vertices": report.non_finite_vertices,
        "repairs": repairs,
        "repairs_summary": repairs.summary(),
    });
    Ok((v, warnings))
}

/// `meshmatch info`: a report per file on stdout, one error line per bad file on stderr.
/// A closed stdout (`| head -1`) ends the command quietly with status 0.
fn info(files: &[PathBuf], json: bool) -> i32 {
    let mut code = 0;
    for f in files {
        match info_report(f) {
            Ok((v, warnings)) => {
                io::print_warnings(&warnings);
                let mut out = std::io::stdout().lock();
                let written = if json {
                    writeln!(out, "{v}")
                } else {
                    print_info(&mut out, &v)
                }
                .and_then(|()| out.flush());
                match written {
                    Ok(()) => {}
                    Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => return 0,
                    Err(e) => {
                        let _ = writeln!(std::io::stderr().lock(), "meshmatch: stdout: {e}");
                        return 2;
                    }
                }
            }
            Err(e) => {
                let _ = writeln!(std::io::stderr().lock(), "meshmatch: {e}");
                code = 2;
            }
        }
    }
    code
}

fn print_info(out: &mut impl Write, v: &serde_json::Value) -> std::io::Result<()> {
    let b = &v["bounds"];
    writeln!(out, "{}", v["path"].as_str().unwrap_or(""))?;
    writeln!(out, "  vertices        {}", v["vertices"])?;
    writeln!(out, "  faces           {}", v["faces"])?;
    writeln!(out, "  components      {}", v["components"])?;
    writeln!(out, "  boundary loops  {}", v["boundary_loops"])?;
    writeln!(out, "  bounds          {} .. {}", b["min"], b["max"])?;
    writeln!(
        out,
        "  area            {:.6}",
        v["area"].as_f64().unwrap_or(0.0)
    )?;
    writeln!(
        out,
        "  signal          {}{}",
        v["signal"].as_str().unwrap_or(""),
        v["texture"]
            .as_str()
            .map(|t| format!(" ({t})"))
            .unwrap_or_default()
    )?;
    writeln!(out, "  uvs / normals   {} / {}", v["uvs"], v["normals"])?;
    writeln!(
        out,
        "  defects         {} non-manifold edges, {} non-manifold vertices, {} degenerate faces, {} duplicate faces, {} isolated vertices, {} non-finite vertices",
        v["non_manifold_edges"],
        v["non_manifold_vertices"],
        v["degenerate_faces"],
        v["duplicate_faces"],
        v["isolated_vertices"],
        v["non_finite_vertices"]
    )?;
    writeln!(
        out,
        "  repairs         {}",
        v["repairs_summary"].as_str().unwrap_or("")
    )
}
