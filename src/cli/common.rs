//! Helpers shared by the subcommands: loading, output paths, progress bars, masks, solver flags.

use std::path::Path;

use crate::error::{Error, Result};
use crate::mesh::{TriMesh, io};
use crate::work::Event;

pub fn load_usable(path: &Path) -> Result<TriMesh> {
    let m = io::load(path)?;
    m.check_usable()?;
    Ok(m)
}

/// Fail early on an output path with an unknown extension; create its folder.
pub fn prepare_output(p: &Path) -> Result<()> {
    let ext = p
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase());
    if !matches!(ext.as_deref(), Some("ply" | "glb" | "obj")) {
        return Err(Error::InvalidInput(format!(
            "{}: output must end in .ply, .glb or .obj",
            p.display()
        )));
    }
    if let Some(dir) = p.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    }
    Ok(())
}

/// A progress bar and the event sink that drives it (stage times printed above the bar).
pub fn progress_bar() -> indicatif::ProgressBar {
    let bar = indicatif::ProgressBar::new(1000);
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "{spinner} [{elapsed_precise}] {bar:30} {percent:>3}% {msg}",
        )
        .expect("valid template"),
    );
    bar
}

pub fn bar_sink(bar: &indicatif::ProgressBar, e: Event) {
    match e {
        Event::Progress(p) | Event::Partial { progress: p, .. } => {
            bar.set_position((p.fraction.clamp(0.0, 1.0) * 1000.0) as u64);
            if p.iteration > 0 {
                bar.set_message(format!(
                    "{} level {}/{} iteration {} energy {:.4}",
                    p.stage, p.level, p.levels, p.iteration, p.energy
                ));
            } else {
                bar.set_message(p.stage.to_string());
            }
        }
        Event::StageTime(name, s) => bar.println(format!("  {name:<12} {s:8.3} s")),
    }
}

/// Read a mask file: vertex indices (file numbering), one per line; `#` comments and blank lines
/// are ignored. Returns per-vertex flags of length `n`.
pub fn read_mask(path: &Path, n: usize) -> Result<Vec<bool>> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    let mut mask = vec![false; n];
    for (i, line) in text.lines().enumerate() {
        let t = line.split('#').next().unwrap_or("").trim();
        if t.is_empty() {
            continue;
        }
        let v: usize = t.parse().map_err(|_| {
            Error::format(path, format!("line {}: '{t}' is not a vertex index", i + 1))
        })?;
        if v >= n {
            return Err(Error::format(
                path,
                format!("line {}: vertex {v} out of range (the mesh has {n})", i + 1),
            ));
        }
        mask[v] = true;
    }
    Ok(mask)
}

/// Parse "R,G,B" (0-255) into an sRGB colour in [0, 1].
pub fn parse_rgb(s: &str) -> Result<[f32; 3]> {
    let v: Vec<&str> = s.split(',').map(str::trim).collect();
    let bad = || Error::InvalidInput(format!("--clay {s}: expected R,G,B with values 0-255"));
    if v.len() != 3 {
        return Err(bad());
    }
    let mut c = [0.0f32; 3];
    for (k, x) in v.iter().enumerate() {
        c[k] = x.parse::<u8>().map_err(|_| bad())? as f32 / 255.0;
    }
    Ok(c)
}

/// Solver settings shared by `complete`, `update` and `detail`.
#[derive(clap::Args, Debug)]
pub struct SolveArgs {
    /// Working resolution (vertices; coarser meshes are refined to it).
    #[arg(long, default_value_t = 64_000)]
    pub vertices: usize,
    /// Number of hierarchy levels (default: down to about 128 vertices).
    #[arg(long)]
    pub levels: Option<usize>,
    /// EM iterations per level.
    #[arg(long, default_value_t = 5)]
    pub iterations: usize,
    /// Random seed (runs with the same seed are identical).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Weight of shape features against colour (1 = equal).
    #[arg(long)]
    pub shape_weight: Option<f32>,
    /// Keep the filtered vote at the finest level instead of the nearest-neighbour copy.
    #[arg(long)]
    pub no_sharpen: bool,
}

impl SolveArgs {
    /// The transfer parameters, with `shape_weight` defaulting to `default_shape_weight`.
    pub fn params(&self, default_shape_weight: f32) -> crate::meshmatch::TransferParams {
        crate::meshmatch::TransferParams {
            vertices: self.vertices,
            levels: self.levels,
            iterations: self.iterations,
            seed: self.seed,
            shape_weight: self.shape_weight.unwrap_or(default_shape_weight),
            sharpen: !self.no_sharpen,
            ..Default::default()
        }
    }
}

/// Load a source that must carry a signal: its own texture or vertex colours, or `texture`
/// (which needs UVs) in their place.
pub fn load_signal_source(path: &Path, texture: Option<&Path>) -> Result<TriMesh> {
    let mut source = load_usable(path)?;
    if let Some(tex) = texture {
        if source.uvs.is_none() {
            return Err(Error::InvalidInput(format!(
                "{}: --source-texture needs a source with UVs",
                path.display()
            )));
        }
        source.texture = Some(std::sync::Arc::new(io::load_texture(tex)?));
        source.colors = None;
    }
    if source.vertex_signal().is_none() {
        return Err(Error::InvalidInput(format!(
            "{}: the source carries no texture or vertex colours to transfer (use --source-texture)",
            path.display()
        )));
    }
    Ok(source)
}
