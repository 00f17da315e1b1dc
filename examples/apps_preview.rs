//! Render coloured PLY/OBJ meshes to PNG previews with a tiny software rasteriser (no GPU):
//! `cargo run --release --no-default-features --example apps_preview -- OUTDIR MESH...`
//! writes OUTDIR/<mesh stem>.png with three views of each mesh (vertex colours, or grey).

mod common;

use std::path::{Path, PathBuf};

fn main() -> meshmatch::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let outdir = PathBuf::from(args.get(1).cloned().unwrap_or("/tmp/apps_preview".into()));
    std::fs::create_dir_all(&outdir).map_err(|e| meshmatch::Error::io(&outdir, e))?;
    for p in &args[2.min(args.len())..] {
        let path = Path::new(p);
        let mesh = meshmatch::mesh::io::load(path)?;
        let cols = mesh.vertex_signal();
        let stem = path.file_stem().and_then(|s| s.to_str()).unwrap_or("mesh");
        let out = outdir.join(format!("{stem}.png"));
        common::side_by_side(
            &mesh.positions,
            &mesh.faces,
            cols.as_deref(),
            None,
            &common::three_turns(),
            400,
            common::Look::default(),
        )
        .save(&out)
        .map_err(|e| meshmatch::Error::InvalidInput(e.to_string()))?;
        println!("{}", out.display());
    }
    Ok(())
}
