//! `meshmatch convert`: a mesh from one format to another, as loaded.

use std::path::PathBuf;

use crate::error::Result;
use crate::mesh::io;

/// Arguments of `meshmatch convert`.
#[derive(clap::Args, Debug)]
pub struct ConvertArgs {
    /// Input mesh.
    pub input: PathBuf,
    /// Output mesh (.ply, .obj, .glb).
    pub output: PathBuf,
}

impl ConvertArgs {
    /// Run the subcommand; returns the exit code.
    pub fn run(&self) -> Result<i32> {
        // The mesh is written as loaded, not repaired: the output keeps the input file's
        // vertices, their order and its faces (degenerate and duplicate ones included).
        super::common::check_outputs(
            &[&self.input],
            &[("output", &self.output, super::common::OutKind::Mesh)],
        )?;
        let (mesh, warnings) = io::load_with_warnings(&self.input)?;
        mesh.check_usable()?;
        io::save(&mesh, &self.output)?;
        io::print_warnings(&warnings);
        crate::cli::common::announce_written(&self.output);
        Ok(0)
    }
}
