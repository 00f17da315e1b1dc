//! The command-line interface: `meshmatch [COMMAND]`. No command opens the app.

use crate::jobs::{CancelToken, CorrespondenceFile, Event};
use crate::mesh::{TriMesh, io};
use crate::{Error, Result};
use clap::{Parser, Subcommand};
use std::io::Write;
use std::path::{Path, PathBuf};

/// Example-based texturing of 3D meshes.
#[derive(Parser, Debug)]
#[command(name = "meshmatch", version, about, long_about = None)]
pub struct Cli {
    /// What to do; without a command the desktop app opens on the demo scene.
    #[command(subcommand)]
    pub command: Option<Command>,
}

/// The subcommands.
#[derive(Subcommand, Debug)]
pub enum Command {
    /// Print counts, bounds, components, boundary loops, signal kind and repairs of mesh files.
    Info {
        /// Mesh files (.obj, .ply, .gltf, .glb).
        #[arg(required = true)]
        files: Vec<PathBuf>,
        /// One JSON object per line per file.
        #[arg(long)]
        json: bool,
    },
    /// Convert a mesh between formats (by extension), keeping vertex order, UVs, colours, texture.
    Convert {
        /// Input mesh.
        input: PathBuf,
        /// Output mesh (.ply, .obj, .glb).
        output: PathBuf,
    },
    /// Write the procedural demo scene (zebra, giraffe, cerberus, vase) as GLB files.
    Demo {
        /// Output directory (created if missing).
        #[arg(long)]
        out: PathBuf,
    },
    /// Transfer a texture from a source mesh to a target mesh (MeshMatch).
    Transfer(TransferArgs),
    /// Synthesize a texture over a mesh from a 2D exemplar image (Wei and Levoy 2001).
    Synth(SynthArgs),
    /// Complete a partly painted mesh by example: the painted (or unmasked) vertices are the
    /// example, the rest is synthesised; painted vertices keep their colours exactly.
    Complete(CompleteArgs),
    /// Update the texture after a geometry edit: copy colours where the new surface coincides with
    /// the old one, synthesise only the changed region.
    Update(UpdateArgs),
    /// Transfer geometric detail (displacement along the normal) from a detailed mesh to a smooth one.
    Detail(DetailArgs),
    /// Time the transfer's stages at several working resolutions (Spot -> horse from the shared data).
    Bench {
        /// Working resolutions, e.g. `16k,64k,256k,1m`.
        #[arg(long, default_value = "16k,64k")]
        sizes: String,
        /// One JSON object per line per size.
        #[arg(long)]
        json: bool,
        /// After each size, cancel that many whole transfers at evenly spaced moments and
        /// report how long each took to stop.
        #[arg(long, default_value_t = 0)]
        cancel_probes: usize,
    },
    /// Render a mesh to a PNG offscreen (headlight Lambert shading, vertex colours or texture).
    #[cfg(feature = "gui")]
    Render {
        /// The mesh to render.
        mesh: PathBuf,
        /// Output PNG.
        #[arg(long)]
        out: PathBuf,
        /// Camera azimuth around the up axis, degrees.
        #[arg(long, default_value_t = 30.0, allow_hyphen_values = true)]
        azimuth: f32,
        /// Camera elevation, degrees.
        #[arg(long, default_value_t = 20.0, allow_hyphen_values = true)]
        elevation: f32,
        /// Image size as WxH.
        #[arg(long, default_value = "800x600")]
        size: String,
        /// Draw the wireframe over the shading.
        #[arg(long)]
        wireframe: bool,
        /// Correspondences JSON whose markers to draw: spheres in the app's marker colours
        /// (hidden ones faint).
        #[arg(long)]
        correspondences: Option<PathBuf>,
        /// Which side of the correspondences this mesh is.
        #[arg(long, value_enum, default_value = "target")]
        side: MarkerSide,
    },
}

/// Which side of a correspondence file a rendered mesh is.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum MarkerSide {
    /// The source mesh (`source_vertex`).
    Source,
    /// The target mesh (`target_vertices`).
    Target,
}

/// Arguments of `meshmatch transfer`.
#[derive(clap::Args, Debug)]
pub struct TransferArgs {
    /// Source mesh carrying the texture or vertex colours.
    #[arg(long)]
    pub source: PathBuf,
    /// Texture image for the source (overrides the one its material names; needs UVs).
    #[arg(long)]
    pub source_texture: Option<PathBuf>,
    /// Target mesh to texture.
    #[arg(long)]
    pub target: PathBuf,
    /// Correspondences JSON (`{"correspondences": [{"source_vertex": i, "target_vertices": [j, ..]}]}`).
    #[arg(long)]
    pub correspondences: Option<PathBuf>,
    /// Output: .ply (vertex colours), .glb (baked texture if the target has UVs, else COLOR_0), .obj (+MTL+PNG).
    #[arg(long)]
    pub out: PathBuf,
    /// Also write the dense working-resolution target with its colours (.ply/.glb/.obj).
    #[arg(long)]
    pub out_dense: Option<PathBuf>,
    /// Write the nearest-neighbour field as CSV: target_vertex,source_vertex,rotation_deg.
    #[arg(long)]
    pub nnf_out: Option<PathBuf>,
    /// Working resolution (vertices per mesh; denser meshes are used as they are).
    #[arg(long, default_value_t = 64_000)]
    pub vertices: usize,
    /// Number of hierarchy levels (default: down to about 128 vertices, at most 7).
    #[arg(long)]
    pub levels: Option<usize>,
    /// EM iterations per level.
    #[arg(long, default_value_t = 5)]
    pub iterations: usize,
    /// Random seed (runs with the same seed are identical).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Weight of shape features against colour (1 = equal).
    #[arg(long, default_value_t = 1.0)]
    pub shape_weight: f32,
    /// The finest level's shape weight as a fraction of --shape-weight (geometric in between);
    /// below 1, fine levels follow the colour more (sharper patches, looser layout).
    #[arg(long, default_value_t = crate::meshmatch::FINE_SHAPE_SCALE)]
    pub fine_shape_scale: f32,
    /// Keep the filtered vote at the finest level instead of the nearest-neighbour copy.
    #[arg(long)]
    pub no_sharpen: bool,
    /// Size of the baked texture (pixels per side) when the target has UVs.
    #[arg(long, default_value_t = 1024)]
    pub texture_size: u32,
}

/// Arguments of `meshmatch synth`.
#[derive(clap::Args, Debug)]
pub struct SynthArgs {
    /// Exemplar image (PNG or JPEG): colours, or a grey displacement map with --displace.
    #[arg(long)]
    pub exemplar: PathBuf,
    /// Mesh to texture.
    #[arg(long)]
    pub target: PathBuf,
    /// Output mesh (.ply, .glb, .obj): the uniform-density synthesized mesh with vertex colours.
    #[arg(long)]
    pub out: PathBuf,
    /// Mesh units spanned by the exemplar's width (default: a quarter of the bounding-box diagonal).
    #[arg(long)]
    pub scale: Option<f32>,
    /// Shrink the exemplar to at most this many pixels wide first (aspect kept): the texel
    /// spacing is scale / width, so this sets the synthesized vertex count (grows with its square).
    #[arg(long)]
    pub exemplar_width: Option<u32>,
    /// Texture orientation field: random (isotropic textures; the library's default too), up
    /// (projected +Y), relax2 (stripes) or relax4 (grids).
    #[arg(long, default_value = crate::synthesis::Orientation::default().as_str())]
    pub orientation: String,
    /// Pyramid levels.
    #[arg(long, default_value_t = 4)]
    pub levels: usize,
    /// Vertex indices (file numbering, one per line) to synthesize; the rest keep their colours.
    #[arg(long)]
    pub mask: Option<PathBuf>,
    /// Neighbourhood search: exhaustive (reference) or fast (coherence + random search).
    #[arg(long, default_value = crate::synthesis::Search::default().as_str())]
    pub search: String,
    /// Random seed.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Treat the exemplar as a grey displacement map and displace the surface along its normals.
    #[arg(long)]
    pub displace: bool,
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

fn synth(a: &SynthArgs) -> Result<i32> {
    use crate::synthesis::{Orientation, Search, SynthParams};
    let orientation: Orientation = a.orientation.parse().map_err(|_| {
        Error::InvalidInput(format!(
            "--orientation {}: use random, up, relax2 or relax4",
            a.orientation
        ))
    })?;
    let search: Search = a.search.parse().map_err(|_| {
        Error::InvalidInput(format!("--search {}: use exhaustive or fast", a.search))
    })?;
    if let Some(dir) = a.out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    }
    let mut exemplar = io::load_texture(&a.exemplar)?.image;
    if let Some(w) = a.exemplar_width {
        if w < 8 {
            return Err(Error::InvalidInput(format!(
                "--exemplar-width {w}: use at least 8 pixels"
            )));
        }
        exemplar = crate::synthesis::wei_levoy::shrink_exemplar(exemplar, w);
    }
    let target = load_usable(&a.target)?;
    // The mask file numbers vertices as the file does; the synthesis takes one flag per vertex
    // of the loaded mesh (repair may have dropped unreferenced file vertices).
    let mask = match &a.mask {
        Some(p) => {
            let file_mask = read_mask(p, target.file_vertex_count)?;
            Some(
                target
                    .file_index
                    .iter()
                    .map(|&f| file_mask[f as usize])
                    .collect::<Vec<bool>>(),
            )
        }
        None => None,
    };
    let params = SynthParams {
        scale: a.scale,
        orientation,
        levels: a.levels,
        search,
        seed: a.seed,
        displace: a.displace,
        ..SynthParams::default()
    };
    let t = std::time::Instant::now();
    let r = crate::synthesis::synthesize(
        &exemplar,
        &target,
        mask.as_deref(),
        &params,
        &crate::jobs::no_events,
        &CancelToken::new(),
    )?;
    eprintln!(
        "synthesized {} vertices in {:.2} s (search {:.2} s, {} search, orientation {}); \
         finest-level neighbourhood energy {:.5}",
        r.mesh.num_vertices(),
        t.elapsed().as_secs_f64(),
        r.timings.search,
        search.as_str(),
        orientation.as_str(),
        r.level_energy.first().copied().unwrap_or(0.0)
    );
    io::save(&r.mesh, &a.out)?;
    eprintln!("wrote {}", a.out.display());
    Ok(0)
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
    fn params(&self, default_shape_weight: f32) -> crate::meshmatch::TransferParams {
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
    /// Output mesh with vertex colours (.ply, .glb, .obj).
    #[arg(long)]
    pub out: PathBuf,
    #[command(flatten)]
    pub solve: SolveArgs,
}

/// Arguments of `meshmatch update`.
#[derive(clap::Args, Debug)]
pub struct UpdateArgs {
    /// The mesh before the edit, with its texture or vertex colours.
    #[arg(long)]
    pub old: PathBuf,
    /// The edited mesh.
    #[arg(long)]
    pub new: PathBuf,
    /// Output: the edited mesh with vertex colours (.ply, .glb, .obj).
    #[arg(long)]
    pub out: PathBuf,
    #[command(flatten)]
    pub solve: SolveArgs,
}

/// Arguments of `meshmatch detail`.
#[derive(clap::Args, Debug)]
pub struct DetailArgs {
    /// The detailed mesh to take the detail from.
    #[arg(long)]
    pub source: PathBuf,
    /// The smooth mesh to receive it.
    #[arg(long)]
    pub target: PathBuf,
    /// Output: the displaced target at the working resolution (.ply, .glb, .obj).
    #[arg(long)]
    pub out: PathBuf,
    /// Scale of the transferred displacement (1 = the source's amplitude relative to its edge length).
    #[arg(long, default_value_t = 1.0, allow_hyphen_values = true)]
    pub strength: f32,
    #[command(flatten)]
    pub solve: SolveArgs,
}

/// Run the CLI; returns the process exit code.
pub fn main() -> i32 {
    std::panic::set_hook(Box::new(|info| {
        let msg = info
            .payload()
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| info.payload().downcast_ref::<String>().cloned())
            .unwrap_or_else(|| "unknown".into());
        if is_broken_pipe(&msg) {
            // stdout was closed by the reader (`| head`): not an error, nothing to say.
            return;
        }
        let at = info
            .location()
            .map(|l| format!(" at {}:{}", l.file(), l.line()))
            .unwrap_or_default();
        // Never panic inside the hook (eprintln! would, if stderr is gone too).
        let _ = writeln!(
            std::io::stderr().lock(),
            "meshmatch: internal error: {msg}{at}"
        );
    }));
    let cli = Cli::parse();
    let res = std::panic::catch_unwind(|| run(cli));
    match res {
        Ok(Ok(code)) => code,
        Ok(Err(e)) => {
            let _ = writeln!(std::io::stderr().lock(), "meshmatch: {e}");
            2
        }
        Err(payload) => {
            let msg = payload
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| payload.downcast_ref::<String>().cloned())
                .unwrap_or_default();
            if is_broken_pipe(&msg) { 0 } else { 2 }
        }
    }
}

/// True for the panic of `print!`/`println!` when stdout is a closed pipe: the reader (e.g.
/// `head`) has all it wants, so the program stops quietly with status 0, as Unix tools do.
fn is_broken_pipe(panic_msg: &str) -> bool {
    panic_msg.starts_with("failed printing to stdout") && panic_msg.contains("Broken pipe")
}

fn run(cli: Cli) -> Result<i32> {
    match cli.command {
        None => open_app(),
        Some(Command::Info { files, json }) => Ok(info(&files, json)),
        Some(Command::Convert { input, output }) => {
            // The mesh is written as loaded, not repaired: the output keeps the input file's
            // vertices, their order and its faces (degenerate and duplicate ones included).
            let (mesh, warnings) = io::load_with_warnings(&input)?;
            mesh.check_usable()?;
            io::save(&mesh, &output)?;
            io::print_warnings(&warnings);
            eprintln!("wrote {}", output.display());
            Ok(0)
        }
        Some(Command::Demo { out }) => demo(&out),
        Some(Command::Transfer(args)) => transfer(&args),
        Some(Command::Synth(args)) => synth(&args),
        Some(Command::Complete(args)) => complete(&args),
        Some(Command::Update(args)) => update(&args),
        Some(Command::Detail(args)) => detail(&args),
        Some(Command::Bench {
            sizes,
            json,
            cancel_probes,
        }) => {
            crate::bench::run(&crate::bench::parse_sizes(&sizes)?, json, cancel_probes)?;
            Ok(0)
        }
        #[cfg(feature = "gui")]
        Some(Command::Render {
            mesh,
            out,
            azimuth,
            elevation,
            size,
            wireframe,
            correspondences,
            side,
        }) => {
            let (width, height) = parse_size(&size)?;
            let m = io::load(&mesh)?;
            m.check_usable()?;
            let colors = m.vertex_signal();
            let markers = match &correspondences {
                Some(p) => render_markers(&m, &CorrespondenceFile::load(p)?.correspondences, side)?,
                None => Vec::new(),
            };
            let opts = crate::render::RenderOptions {
                azimuth_deg: azimuth,
                elevation_deg: elevation,
                width,
                height,
                wireframe,
                markers,
            };
            crate::render::render_to_png(&m, colors.as_deref(), &opts, &out)?;
            eprintln!("wrote {}", out.display());
            Ok(0)
        }
    }
}

/// Marker spheres for `side` of `corr` on `mesh`: the app's colours, a radius of 2% of the
/// mesh's bounding radius.
#[cfg(feature = "gui")]
fn render_markers(
    mesh: &crate::TriMesh,
    corr: &[crate::jobs::Correspondence],
    side: MarkerSide,
) -> Result<Vec<crate::render::MarkerInstance>> {
    let radius = crate::render::Frame::of_points(&mesh.positions).radius * 0.02;
    let mut out = Vec::new();
    for (pair, c) in corr.iter().enumerate() {
        let side = match side {
            MarkerSide::Source => crate::jobs::worker::Side::Source,
            MarkerSide::Target => crate::jobs::worker::Side::Target,
        };
        for &v in c.vertices(side) {
            let p = mesh.positions.get(v as usize).ok_or_else(|| {
                Error::InvalidInput(format!(
                    "correspondence {}: vertex {v} is out of range ({} vertices)",
                    pair + 1,
                    mesh.positions.len()
                ))
            })?;
            out.push(crate::render::MarkerInstance {
                center: *p,
                radius,
                color: crate::render::marker_color(pair).map(|x| x as f32 / 255.0),
                rim: 0.0,
            });
        }
    }
    Ok(out)
}

#[cfg(feature = "gui")]
fn parse_size(s: &str) -> Result<(u32, u32)> {
    let bad = || Error::InvalidInput(format!("--size {s}: expected WxH, e.g. 800x600"));
    let (w, h) = s.split_once(['x', 'X']).ok_or_else(bad)?;
    let (w, h): (u32, u32) = (
        w.trim().parse().map_err(|_| bad())?,
        h.trim().parse().map_err(|_| bad())?,
    );
    if w == 0 || h == 0 || w > 8192 || h > 8192 {
        return Err(bad());
    }
    Ok((w, h))
}

#[cfg(feature = "gui")]
fn open_app() -> Result<i32> {
    crate::app::run(crate::app::Startup::default())?;
    Ok(0)
}

#[cfg(not(feature = "gui"))]
fn open_app() -> Result<i32> {
    eprintln!(
        "meshmatch was built without the `gui` feature; run `meshmatch --help` for the commands"
    );
    Ok(2)
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

fn demo(out: &Path) -> Result<i32> {
    std::fs::create_dir_all(out).map_err(|e| Error::io(out, e))?;
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

fn load_usable(path: &Path) -> Result<TriMesh> {
    let m = io::load(path)?;
    m.check_usable()?;
    Ok(m)
}

fn transfer(a: &TransferArgs) -> Result<i32> {
    use crate::meshmatch::{self as mm, TransferParams};
    for p in [Some(&a.out), a.out_dense.as_ref()].into_iter().flatten() {
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
    }
    // Make sure every output can be written before spending minutes on the transfer.
    for p in [Some(&a.out), a.out_dense.as_ref(), a.nnf_out.as_ref()]
        .into_iter()
        .flatten()
    {
        if let Some(dir) = p.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
        }
    }
    let mut source = load_usable(&a.source)?;
    if let Some(tex) = &a.source_texture {
        if source.uvs.is_none() {
            return Err(Error::InvalidInput(format!(
                "{}: --source-texture needs a source with UVs",
                a.source.display()
            )));
        }
        source.texture = Some(std::sync::Arc::new(io::load_texture(tex)?));
        source.colors = None;
    }
    if source.vertex_signal().is_none() {
        return Err(Error::InvalidInput(format!(
            "{}: the source carries no texture or vertex colours to transfer (use --source-texture)",
            a.source.display()
        )));
    }
    let target = load_usable(&a.target)?;
    let corr = match &a.correspondences {
        Some(p) => CorrespondenceFile::load(p)?.correspondences,
        None => Vec::new(),
    };
    let params = TransferParams {
        vertices: a.vertices,
        levels: a.levels,
        iterations: a.iterations,
        seed: a.seed,
        shape_weight: a.shape_weight,
        fine_shape_scale: a.fine_shape_scale,
        sharpen: !a.no_sharpen,
        ..TransferParams::default()
    };
    let bar = indicatif::ProgressBar::new(1000);
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "{spinner} [{elapsed_precise}] {bar:30} {percent:>3}% {msg}",
        )
        .expect("valid template"),
    );
    let sink = |e: Event| match e {
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
    };
    let cancel = CancelToken::new();
    let t = std::time::Instant::now();
    let prepared_source = mm::prepare(&source, &params, &sink, &cancel)?;
    let prepared_target = mm::prepare(&target, &params, &sink, &cancel)?;
    let result = mm::solve(
        &prepared_source,
        &prepared_target,
        &corr,
        &params,
        &sink,
        &cancel,
    )?;
    bar.finish_and_clear();
    eprintln!(
        "transfer finished in {:.2} s (energy {:.4})",
        t.elapsed().as_secs_f64(),
        result.energy
    );
    for (name, s) in &result.timings {
        eprintln!("  {name:<12} {s:8.3} s");
    }

    // Deliver on the target's own vertices (file order), or baked into its UV layout.
    let ext = a.out.extension().and_then(|e| e.to_str()).unwrap_or("");
    let out_mesh = mm::deliver(
        &target,
        &mm::BakeLayout::of(&prepared_target),
        &result.working_signal,
        &result.file_signal,
        ext,
        a.texture_size,
    );
    io::save(&out_mesh, &a.out)?;
    eprintln!("wrote {}", a.out.display());
    if let Some(dense) = &a.out_dense {
        let d = mm::deliver_dense(prepared_target.working_mesh(), &result.working_signal);
        io::save(&d, dense)?;
        eprintln!("wrote {}", dense.display());
    }
    if let Some(nnf) = &a.nnf_out {
        let mut csv = String::from("target_vertex,source_vertex,rotation_deg\n");
        for (t, (s, r)) in result.file_nnf.iter().enumerate() {
            csv.push_str(&format!("{t},{s},{r}\n"));
        }
        io::write_atomic(nnf, csv.as_bytes())?;
        eprintln!("wrote {}", nnf.display());
    }
    Ok(0)
}

/// Fail early on an output path with an unknown extension; create its folder.
fn prepare_output(p: &Path) -> Result<()> {
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
fn progress_bar() -> indicatif::ProgressBar {
    let bar = indicatif::ProgressBar::new(1000);
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "{spinner} [{elapsed_precise}] {bar:30} {percent:>3}% {msg}",
        )
        .expect("valid template"),
    );
    bar
}

fn bar_sink(bar: &indicatif::ProgressBar, e: Event) {
    match e {
        Event::Progress(p) | Event::Partial { progress: p, .. } => {
            bar.set_position((p.fraction.clamp(0.0, 1.0) * 1000.0) as u64);
            bar.set_message(p.stage.to_string());
        }
        Event::StageTime(name, s) => bar.println(format!("  {name:<12} {s:8.3} s")),
    }
}

/// Parse "R,G,B" (0-255) into an sRGB colour in [0, 1].
fn parse_rgb(s: &str) -> Result<[f32; 3]> {
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

fn complete(a: &CompleteArgs) -> Result<i32> {
    prepare_output(&a.out)?;
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
    let params = a.solve.params(1.0);
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
    let mut out = mesh.clone();
    out.colors = Some(
        mesh.file_index
            .iter()
            .map(|&f| r.colors[f as usize])
            .collect(),
    );
    out.texture = None;
    io::save(&out, &a.out)?;
    eprintln!("wrote {}", a.out.display());
    Ok(0)
}

fn update(a: &UpdateArgs) -> Result<i32> {
    prepare_output(&a.out)?;
    let old = load_usable(&a.old)?;
    if old.vertex_signal().is_none() {
        return Err(Error::InvalidInput(format!(
            "{}: the old mesh carries no texture or vertex colours",
            a.old.display()
        )));
    }
    let new = load_usable(&a.new)?;
    let params = a.solve.params(1.0);
    let bar = progress_bar();
    let sink = |e: Event| bar_sink(&bar, e);
    let t = std::time::Instant::now();
    let r = crate::applications::update_texture(&old, &new, &params, &sink, &CancelToken::new())?;
    bar.finish_and_clear();
    eprintln!(
        "updated: {} of {} vertices changed, {:.2} s (energy {:.4})",
        r.changed.iter().filter(|&&c| c).count(),
        r.changed.len(),
        t.elapsed().as_secs_f64(),
        r.energy
    );
    let mut out = new.clone();
    out.colors = Some(
        new.file_index
            .iter()
            .map(|&f| r.colors[f as usize])
            .collect(),
    );
    out.texture = None;
    io::save(&out, &a.out)?;
    eprintln!("wrote {}", a.out.display());
    Ok(0)
}

fn detail(a: &DetailArgs) -> Result<i32> {
    prepare_output(&a.out)?;
    let source = load_usable(&a.source)?;
    let target = load_usable(&a.target)?;
    let params = a.solve.params(crate::applications::DETAIL_SHAPE_WEIGHT);
    let bar = progress_bar();
    let sink = |e: Event| bar_sink(&bar, e);
    let t = std::time::Instant::now();
    let r = crate::applications::transfer_detail(
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
    io::save(&r.mesh, &a.out)?;
    eprintln!(
        "wrote {} ({} vertices)",
        a.out.display(),
        r.mesh.num_vertices()
    );
    Ok(0)
}
