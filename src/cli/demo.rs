//! `meshmatch demo`: the procedural demo scene as GLB files.

use std::path::{Path, PathBuf};

use crate::error::{Error, Result};
use crate::mesh::io;

/// Arguments of `meshmatch demo`.
#[derive(clap::Args, Debug)]
pub struct DemoArgs {
    /// Output directory (created if missing).
    #[arg(long)]
    pub out: PathBuf,
}

impl DemoArgs {
    /// Run the subcommand; returns the exit code.
    pub fn run(&self) -> Result<i32> {
        demo(&self.out)
    }
}

fn demo(out: &Path) -> Result<i32> {
    if let Some(file) = out
        .ancestors()
        .find(|a| !a.as_os_str().is_empty() && a.exists() && !a.is_dir())
    {
        return Err(Error::InvalidInput(format!(
            "--out {}: {} is a file, not a folder",
            out.display(),
            file.display()
        )));
    }
    io::create_folders(out).map_err(|e| Error::io(out, e))?;
    let t = std::time::Instant::now();
    let scene = crate::demo::scene();
    eprintln!(
        "generated the demo scene in {:.2} s",
        t.elapsed().as_secs_f64()
    );
    for (name, mesh) in [
        ("zebra", &scene.zebra),
        ("giraffe", &scene.giraffe),
        ("cerberus", &scene.cerberus),
        ("vase", &scene.vase),
    ] {
        let path = out.join(format!("{name}.glb"));
        io::save(mesh, &path)?;
        println!(
            "{} ({} vertices, {} faces)",
            path.display(),
            mesh.num_vertices(),
            mesh.num_faces()
        );
    }
    // Feature-aligned texturing: a block with straight and circular crests and a line exemplar.
    let block = crate::demo::crest_block(48);
    let path = out.join("block.obj");
    io::save(&block, &path)?;
    println!(
        "{} ({} vertices, {} faces)",
        path.display(),
        block.num_vertices(),
        block.num_faces()
    );
    let path = out.join("line.png");
    let mut png = Vec::new();
    crate::demo::line_exemplar()
        .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .map_err(|e| Error::InvalidInput(format!("{}: {e}", path.display())))?;
    io::write_atomic(&path, &png)?;
    println!("{}", path.display());
    // The default correspondences the app starts with, for `meshmatch transfer --correspondences`.
    let zebra_marks = crate::demo::landmarks_zebra();
    for (name, mesh, marks) in [
        (
            "zebra_to_giraffe",
            &scene.giraffe,
            crate::demo::landmarks_giraffe(),
        ),
        (
            "zebra_to_cerberus",
            &scene.cerberus,
            crate::demo::landmarks_cerberus(),
        ),
    ] {
        let path = out.join(format!("{name}.json"));
        crate::demo::default_correspondences(&scene.zebra, &zebra_marks, mesh, &marks)
            .save(&path)?;
        println!("{}", path.display());
    }
    Ok(0)
}
