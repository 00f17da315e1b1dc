//! `meshmatch transfer`: MeshMatch texture transfer from a source mesh to a target mesh.

use std::path::PathBuf;

use super::common::*;
use crate::correspondence::CorrespondenceFile;
use crate::error::Result;
use crate::mesh::io;
use crate::work::{CancelToken, Event};

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
    /// Correspondences JSON (`{"correspondences": [{"source_vertex": i, "target_vertices": [j, ..]}]}`),
    /// at most 256 pairs and 1024 target vertices in all.
    #[arg(long)]
    pub correspondences: Option<PathBuf>,
    /// Output: .ply (vertex colours), .glb or .gltf (baked texture if the target has UVs, else COLOR_0), .obj (+MTL+PNG).
    #[arg(long)]
    pub out: PathBuf,
    /// Also write the dense working-resolution target with its colours (.ply/.glb/.gltf/.obj), each
    /// vertex read from the source at full resolution through the solution.
    #[arg(long)]
    pub out_dense: Option<PathBuf>,
    /// Write the nearest-neighbour field as CSV: target_vertex,source_vertex,rotation_deg.
    #[arg(long)]
    pub nnf_out: Option<PathBuf>,
    /// Working resolution (vertices per mesh; denser meshes are used as they are), 128 to
    /// 4,000,000.
    #[arg(long, default_value_t = 64_000, allow_negative_numbers = true,
          value_parser = VERTICES)]
    pub vertices: usize,
    /// Number of hierarchy levels, 1 to 16 (default: down to about 128 vertices, at most 7).
    #[arg(long, allow_negative_numbers = true, value_parser = LEVELS)]
    pub levels: Option<usize>,
    /// EM iterations per level at most, 0 to 1000.
    #[arg(long, default_value_t = 5, allow_negative_numbers = true, value_parser = ITERATIONS)]
    pub iterations: usize,
    /// A level stops iterating once an iteration lowers its energy by less than this fraction
    /// (0 = always run every iteration).
    #[arg(long, default_value_t = crate::meshmatch::DEFAULT_TOLERANCE, allow_negative_numbers = true)]
    pub tolerance: f32,
    /// Random seed (runs with the same seed are identical).
    #[arg(long, default_value_t = 0, allow_negative_numbers = true, value_parser = SEED)]
    pub seed: u64,
    /// Weight of shape features against colour (1 = equal); finite, 0 or more.
    #[arg(long, default_value_t = 1.0, allow_hyphen_values = true)]
    pub shape_weight: f32,
    /// The finest level's shape weight as a fraction of --shape-weight (geometric in between);
    /// below 1, fine levels follow the colour more (sharper patches, looser layout). Positive, finite.
    #[arg(long, allow_hyphen_values = true, default_value_t = crate::meshmatch::FINE_SHAPE_SCALE)]
    pub fine_shape_scale: f32,
    /// Keep the filtered vote at the finest level instead of the nearest-neighbour copy.
    #[arg(long)]
    pub no_sharpen: bool,
    /// How closely to keep the source's layout through a global intrinsic shape map (functional
    /// maps + ZoomOut, the correspondences as landmarks): 0 = pure patch synthesis (no map),
    /// 1 = follow the map at every level, or auto (default): the map is computed and its
    /// isometry score picks the value (1 between near-isometric shapes such as two bodies or a
    /// bent copy, 0 between different animals, linear in between). stderr says what was chosen.
    #[arg(long, default_value = "auto", value_parser = parse_structure, allow_hyphen_values = true)]
    pub structure: StructureArg,
    /// Size of the baked texture (pixels per side) for .glb/.gltf/.obj outputs, 20 to 8192 (default:
    /// the target's own texture's size, else 2048).
    #[arg(long, allow_negative_numbers = true, value_parser = TEXTURE_SIZE)]
    pub texture_size: Option<u32>,
    /// Bake the texture from the working vertices' colours (interpolated between them) instead
    /// of reading the source at full resolution through the solution at every texel.
    #[arg(long)]
    pub working_resolution: bool,
}

impl TransferArgs {
    /// Run the subcommand; returns the exit code.
    pub fn run(&self) -> Result<i32> {
        transfer(self)
    }
}

fn transfer(a: &TransferArgs) -> Result<i32> {
    use crate::meshmatch::TransferParams;
    let params = TransferParams {
        vertices: a.vertices,
        levels: a.levels,
        iterations: a.iterations,
        tolerance: a.tolerance,
        seed: a.seed,
        shape_weight: a.shape_weight,
        fine_shape_scale: a.fine_shape_scale,
        sharpen: !a.no_sharpen,
        structure: a.structure.0,
        ..TransferParams::default()
    };
    params.validate()?;
    if let Some(size) = a.texture_size {
        check_texture_size(size)?;
    }
    // Make sure every output can be written before spending minutes on the transfer.
    let inputs = input_paths(&[
        Some(&a.source),
        Some(&a.target),
        a.source_texture.as_ref(),
        a.correspondences.as_ref(),
    ]);
    let mut outputs = vec![("--out", a.out.as_path(), OutKind::Mesh)];
    if let Some(p) = &a.out_dense {
        outputs.push(("--out-dense", p, OutKind::Mesh));
    }
    if let Some(p) = &a.nnf_out {
        outputs.push(("--nnf-out", p, OutKind::File));
    }
    check_outputs(&inputs, &outputs)?;
    let mut units = WorkingUnits::new();
    let source = units.load_signal_source(&a.source, a.source_texture.as_deref())?;
    let target = units.load(&a.target)?;
    let texture_size = texture_side(a.texture_size, &target);
    check_texture_size(texture_size)?;
    let corr = match &a.correspondences {
        Some(p) => CorrespondenceFile::load_for(p, Some(&source), Some(&target))?,
        None => Vec::new(),
    };
    let bar = progress_bar();
    let sink = |e: Event| bar_sink(&bar, e);
    let ext = a.out.extension().and_then(|e| e.to_str()).unwrap_or("");
    let t = transfer_meshes(
        &source,
        &target,
        &corr,
        &params,
        &Delivery {
            ext,
            texture_size,
            full_resolution: !a.working_resolution,
            dense: a.out_dense.is_some(),
        },
        &sink,
        &CancelToken::new(),
    )?;
    bar.finish_and_clear();
    let result = &t.result;
    eprintln!(
        "transfer finished in {:.2} s (energy {:.4})",
        t.solve_seconds, result.energy
    );
    for (name, s) in &result.timings {
        eprintln!("  {name:<12} {s:8.3} s");
    }
    let its: Vec<String> = result.iterations.iter().map(|i| i.to_string()).collect();
    eprintln!("  EM iterations per level, finest first: {}", its.join(" "));
    for n in &result.notices {
        eprintln!("note: {n}");
    }
    eprintln!("{}", structure_line(params.structure, result));
    if !ext.eq_ignore_ascii_case("ply") {
        eprintln!(
            "  {:<12} {:8.3} s ({} texels per side{})",
            "texture",
            t.deliver_seconds,
            texture_size,
            if a.working_resolution {
                ", working vertices interpolated"
            } else {
                ", source read at full resolution"
            }
        );
    }
    if let Some(line) = t.delivered.atlas_line(texture_size) {
        eprintln!("{line}");
    }
    let out_mesh = &t.delivered;
    units.save(&out_mesh.mesh, &a.out)?;
    crate::cli::common::announce_written(&a.out);
    if let (Some(path), Some(d)) = (&a.out_dense, &t.dense) {
        units.save(d, path)?;
        crate::cli::common::announce_written(path);
    }
    if let Some(nnf) = &a.nnf_out {
        let mut csv = String::from("target_vertex,source_vertex,rotation_deg\n");
        for (t, (s, r)) in result.file_nnf.iter().enumerate() {
            csv.push_str(&format!("{t},{s},{r}\n"));
        }
        io::write_atomic(nnf, csv.as_bytes())?;
        crate::cli::common::announce_written(nnf);
    }
    Ok(0)
}

/// How a transfer's result is delivered ([`transfer_meshes`]).
#[derive(Clone, Copy, Debug)]
pub struct Delivery<'a> {
    /// The output's extension: `ply` gives colours on the target's vertices; `glb`/`gltf`/`obj`
    /// also bake a texture into its UVs (or a generated atlas), as `mm::deliver` does.
    pub ext: &'a str,
    /// Texels per side of a baked texture.
    pub texture_size: u32,
    /// Read the source at full resolution through the solution (`false`: interpolate the
    /// working vertices' colours, `--working-resolution`).
    pub full_resolution: bool,
    /// Also make the dense working-resolution target (`--out-dense`).
    pub dense: bool,
}

/// A transfer computed in memory ([`transfer_meshes`]).
pub struct Transferred {
    /// The solve's result (energy, timings, nearest-neighbour field).
    pub result: crate::meshmatch::TransferResult,
    /// The target with the result, as `--out` writes it.
    pub delivered: crate::meshmatch::Delivered,
    /// The dense working-resolution target with its colours, when asked for.
    pub dense: Option<crate::mesh::TriMesh>,
    /// Seconds of preparation and solve.
    pub solve_seconds: f64,
    /// Seconds of delivery (the texture bake).
    pub deliver_seconds: f64,
}

/// `meshmatch transfer` on meshes in memory (checked as [`load_usable`] checks files): prepare,
/// solve and deliver as `delivery` says. The CLI and the Python package call it.
#[allow(clippy::too_many_arguments)]
pub fn transfer_meshes(
    source: &crate::mesh::TriMesh,
    target: &crate::mesh::TriMesh,
    corr: &[crate::correspondence::Correspondence],
    params: &crate::meshmatch::TransferParams,
    delivery: &Delivery,
    sink: &dyn Fn(Event),
    cancel: &CancelToken,
) -> Result<Transferred> {
    use crate::meshmatch as mm;
    params.validate()?;
    check_texture_size(delivery.texture_size)?;
    let t = std::time::Instant::now();
    let (prepared_source, prepared_target) =
        mm::prepare_pair(source, params, target, params, sink, cancel)?;
    let result = mm::solve(
        &prepared_source,
        &prepared_target,
        corr,
        params,
        sink,
        cancel,
    )?;
    let solve_seconds = t.elapsed().as_secs_f64();
    // Deliver on the target's own vertices (file order), or baked into its UV layout.
    let t = std::time::Instant::now();
    let full = if delivery.full_resolution {
        mm::Resampler::new(&prepared_source, &prepared_target, &result.nnf, cancel)?
    } else {
        None
    };
    let delivered = mm::deliver(
        target,
        &mm::BakeLayout::of(&prepared_target),
        &result.working_signal,
        &result.file_signal,
        delivery.ext,
        delivery.texture_size,
        full.as_ref(),
        cancel,
    )?;
    let deliver_seconds = t.elapsed().as_secs_f64();
    let dense = delivery.dense.then(|| match &full {
        Some(r) => mm::deliver_dense(prepared_target.working_mesh(), &r.vertex_signal()),
        None => mm::deliver_dense(prepared_target.working_mesh(), &result.working_signal),
    });
    Ok(Transferred {
        result,
        delivered,
        dense,
        solve_seconds,
        deliver_seconds,
    })
}

/// The stderr line saying which structure value the transfer used and why.
pub(crate) fn structure_line(asked: Option<f32>, r: &crate::meshmatch::TransferResult) -> String {
    match (asked, r.map_score) {
        (Some(0.0), _) => "structure 0: pure synthesis, no global map".into(),
        (None, Some(q)) => format!(
            "structure auto: {:.2} (the global map's isometry score is {q:.2}; 0 up to {:.2}, 1 from {:.2})",
            r.structure,
            crate::meshmatch::AUTO_SCORE_MIN,
            crate::meshmatch::AUTO_SCORE_FULL
        ),
        (_, Some(q)) => format!(
            "structure {:.2} (the global map's isometry score is {q:.2})",
            r.structure
        ),
        (_, None) => "structure 0: the global map could not be used".into(),
    }
}

/// `--structure`: `None` = auto.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StructureArg(pub Option<f32>);

/// `--structure`: `auto` or a number from 0 to 1.
pub fn parse_structure(s: &str) -> std::result::Result<StructureArg, String> {
    if s.eq_ignore_ascii_case("auto") {
        return Ok(StructureArg(None));
    }
    match s.parse::<f32>() {
        Ok(x) if (0.0..=1.0).contains(&x) => Ok(StructureArg(Some(x))),
        _ => Err("use auto or a number from 0 (pure synthesis) to 1 (follow the map)".into()),
    }
}
