//! `meshmatch synth`: Wei-Levoy texture synthesis over a mesh from a 2D exemplar image.

use std::path::PathBuf;

use super::common::*;
use crate::error::{Error, Result};
use crate::mesh::io;
use crate::work::CancelToken;

/// Arguments of `meshmatch synth`.
#[derive(clap::Args, Clone, Debug)]
pub struct SynthArgs {
    /// Exemplar image (PNG or JPEG): colours, or a grey displacement map with --displace.
    #[arg(long)]
    pub exemplar: PathBuf,
    /// Mesh to texture.
    #[arg(long)]
    pub target: PathBuf,
    /// Output: .glb/.gltf/.obj = the target mesh with the result baked into a texture (through
    /// its UVs, or a generated atlas); .ply = the uniform-density synthesized mesh with vertex
    /// colours.
    #[arg(long)]
    pub out: PathBuf,
    /// Also write the uniform-density synthesized mesh with vertex colours (any mesh format).
    #[arg(long)]
    pub out_dense: Option<PathBuf>,
    /// Side of the baked texture in pixels (textured outputs).
    #[arg(long, default_value_t = 2048, allow_negative_numbers = true, value_parser = TEXTURE_SIZE)]
    pub texture_size: u32,
    /// Mesh units spanned by the exemplar's width (default: a quarter of the bounding-box
    /// diagonal); positive, finite.
    #[arg(long, allow_negative_numbers = true)]
    pub scale: Option<f32>,
    /// Shrink the exemplar to at most this many pixels wide first (aspect kept): the texel
    /// spacing is scale / width, so this sets the synthesized vertex count (grows with its square).
    #[arg(long, allow_negative_numbers = true, value_parser = at_least(MIN_EXEMPLAR_WIDTH).unit("pixels"))]
    pub exemplar_width: Option<u32>,
    /// Most vertices to synthesize: without --exemplar-width, a larger exemplar is shrunk until
    /// the texel spacing fits this budget (stderr says what was chosen); 1,000 to 2,000,000.
    #[arg(long, default_value_t = crate::synthesis::exemplar::DEFAULT_VERTEX_BUDGET, allow_negative_numbers = true,
          value_parser = whole(MIN_VERTEX_BUDGET, MAX_BUDGET).unit("vertices"))]
    pub vertex_budget: usize,
    /// Texture orientation field: auto (from the exemplar's anisotropy: random, relax2 or
    /// relax4; stderr says which), random (isotropic textures), up
    /// (projected +Y), relax2 (stripes), relax4 (grids) or features (along the mesh's salient
    /// curves: Xu et al. 2009's curve-guided field; the exemplar's x axis follows the curves).
    #[arg(long, default_value = crate::synthesis::Orientation::default().as_str())]
    pub orientation: String,
    /// Pyramid levels, 1 to 8.
    #[arg(long, default_value_t = 4, allow_negative_numbers = true, value_parser = whole(1, MAX_PYRAMID_LEVELS))]
    pub levels: usize,
    /// Vertex indices (file numbering, one per line) to synthesize; the rest keep their colours.
    #[arg(long)]
    pub mask: Option<PathBuf>,
    /// Neighbourhood search: exhaustive (reference) or fast (coherence + random search).
    #[arg(long, default_value = crate::synthesis::Search::default().as_str())]
    pub search: String,
    /// Random seed.
    #[arg(long, default_value_t = 0, allow_negative_numbers = true, value_parser = SEED)]
    pub seed: u64,
    /// Treat the exemplar as a grey displacement map and displace the surface along its normals.
    #[arg(long)]
    pub displace: bool,
    /// patches (large discs of the image pasted onto the surface and placed by matching their
    /// overlap, lapped textures: keeps the image's contrast, large structures and sharpness; a
    /// textured output only), neighbourhood (Wei-Levoy, coarse to fine), optimize (then surface
    /// texture optimisation, Kwatra et al. 2005: whole 32- and 16-texel patches blended along
    /// the field; slower), or auto (patches for a textured output without --mask, --displace,
    /// --out-dense, --exemplar-width, --align-features or --space surface; neighbourhood
    /// otherwise).
    #[arg(long, default_value = "auto")]
    pub method: String,
    /// Put the exemplar's principal line (its darkest or brightest thin horizontal stroke, or
    /// --feature-mask) exactly on the mesh's salient curves (Xu et al. 2009 §5.2). Implies
    /// --method optimize and --orientation features; an exemplar whose lines are vertical is
    /// turned a quarter turn.
    #[arg(long)]
    pub align_features: bool,
    /// The exemplar's line features for --align-features: an image of the exemplar's size, white
    /// lines on black (default: detected).
    #[arg(long)]
    pub feature_mask: Option<PathBuf>,
    /// Where the synthesis runs: texture (the samples are the texels of the target's UVs or a
    /// generated atlas, and the texture is magnified from the full-resolution exemplar; needs a
    /// .glb/.gltf/.obj output), surface (the vertices of a refined mesh, then baked), or auto
    /// (texture for textured outputs of the neighbourhood method without --mask/--displace/
    /// --out-dense, surface otherwise).
    #[arg(long, default_value = "auto")]
    pub space: String,
    /// Most texels synthesized in texture space (1,000 to 2,000,000); the output texture is
    /// magnified from them.
    #[arg(long, default_value_t = crate::synthesis::exemplar::DEFAULT_TEXEL_BUDGET, allow_negative_numbers = true,
          value_parser = whole(MIN_VERTEX_BUDGET, MAX_BUDGET).unit("texels"))]
    pub texel_budget: usize,
}

impl SynthArgs {
    /// Run the subcommand; returns the exit code.
    pub fn run(&self) -> Result<i32> {
        synth(self)
    }
}

/// The smallest `--vertex-budget` and `--texel-budget`: fewer samples cannot show an exemplar's
/// structure.
const MIN_VERTEX_BUDGET: usize = 1000;

/// The largest `--vertex-budget` and `--texel-budget` (`SynthParams::max_vertices`' default).
const MAX_BUDGET: usize = 2_000_000;

/// Most pyramid `--levels`.
const MAX_PYRAMID_LEVELS: usize = 8;

/// The narrowest `--exemplar-width`.
const MIN_EXEMPLAR_WIDTH: u32 = 8;

/// What [`check`] decided from the flags.
#[derive(Clone, Copy, Debug)]
pub struct Plan {
    /// The orientation field (`features` when aligning features).
    pub orientation: crate::synthesis::Orientation,
    /// The neighbourhood search.
    pub search: crate::synthesis::Search,
    /// The method (`optimize` when aligning features).
    pub method: crate::synthesis::Method,
    /// Synthesise on the texels of the target's UV layout.
    pub texture_space: bool,
    /// The output carries a texture (`--out` ends in .glb, .gltf or .obj).
    pub textured_out: bool,
    /// Paste patches of the image ([`crate::synthesis::exemplar::patch_pasting`]).
    pub patches: bool,
}

/// Check `synth`'s flags against each other and their ranges before any file is read (the
/// Python package checks its keyword arguments through the same function), and decide what
/// runs.
pub fn check(a: &SynthArgs) -> Result<Plan> {
    let (orientation, search, method) = parse_choices(a)?;
    let optimise = method == crate::synthesis::Method::Optimize;
    if optimise && a.displace {
        return Err(Error::InvalidInput(
            "--method optimize makes colours: it does not combine with --displace".into(),
        ));
    }
    if optimise && a.mask.is_some() {
        return Err(Error::InvalidInput(
            "--method optimize rewrites every vertex: it does not combine with --mask".into(),
        ));
    }
    let max_budget = check_ranges(a)?;
    let textured_out = matches!(
        a.out
            .extension()
            .and_then(|e| e.to_str())
            .map(|e| e.to_ascii_lowercase())
            .as_deref(),
        Some("glb" | "gltf" | "obj")
    );
    let texture_space = choose_texture_space(a, textured_out, optimise)?;
    if !(MIN_VERTEX_BUDGET..=max_budget).contains(&a.texel_budget) {
        return Err(Error::InvalidInput(format!(
            "--texel-budget {}: use {MIN_VERTEX_BUDGET} to {max_budget} texels",
            a.texel_budget
        )));
    }
    let patches = choose_patches(a, textured_out)?;
    Ok(Plan {
        orientation,
        search,
        method,
        texture_space: texture_space || patches,
        textured_out,
        patches,
    })
}

/// The orientation, search and method the flags name (`--align-features` turns `auto` into
/// `features` and the method into `optimize`).
fn parse_choices(
    a: &SynthArgs,
) -> Result<(
    crate::synthesis::Orientation,
    crate::synthesis::Search,
    crate::synthesis::Method,
)> {
    use crate::synthesis::{Orientation, Search};
    let orientation: Orientation = a.orientation.parse().map_err(|_| {
        Error::InvalidInput(format!(
            "--orientation {}: use auto, random, up, relax2, relax4 or features",
            a.orientation
        ))
    })?;
    let search: Search = a.search.parse().map_err(|_| {
        Error::InvalidInput(format!("--search {}: use exhaustive or fast", a.search))
    })?;
    let asked = a.method.to_ascii_lowercase();
    let mut method: crate::synthesis::Method = match asked.as_str() {
        "auto" | "patches" => crate::synthesis::Method::Neighbourhood,
        m => m.parse().map_err(|_| {
            Error::InvalidInput(format!(
                "--method {}: use auto, patches, neighbourhood or optimize",
                a.method
            ))
        })?,
    };
    let mut orientation = orientation;
    if a.feature_mask.is_some() && !a.align_features {
        return Err(Error::InvalidInput(
            "--feature-mask is read by --align-features: add it".into(),
        ));
    }
    if a.align_features {
        match orientation {
            Orientation::Features => {}
            Orientation::Auto => orientation = Orientation::Features,
            o => {
                return Err(Error::InvalidInput(format!(
                    "--align-features places lines along the salient curves: use --orientation \
                     features, not {}",
                    o.as_str()
                )));
            }
        }
        method = crate::synthesis::Method::Optimize;
    }
    Ok((orientation, search, method))
}

/// Refuse `--scale`, `--levels`, `--texture-size` and `--vertex-budget` out of range; the
/// largest budget.
fn check_ranges(a: &SynthArgs) -> Result<usize> {
    if let Some(s) = a.scale
        && !(s.is_finite() && s > 0.0)
    {
        return Err(Error::InvalidInput(format!(
            "--scale {s}: must be a positive finite number"
        )));
    }
    if !(1..=MAX_PYRAMID_LEVELS).contains(&a.levels) {
        return Err(Error::InvalidInput(format!(
            "--levels {}: use 1 to {MAX_PYRAMID_LEVELS}",
            a.levels
        )));
    }
    check_texture_size(a.texture_size)?;
    let max_budget = MAX_BUDGET.min(crate::synthesis::SynthParams::default().max_vertices);
    if !(MIN_VERTEX_BUDGET..=max_budget).contains(&a.vertex_budget) {
        return Err(Error::InvalidInput(format!(
            "--vertex-budget {}: use {MIN_VERTEX_BUDGET} to {max_budget} vertices",
            a.vertex_budget
        )));
    }
    Ok(max_budget)
}

/// Whether the synthesis runs in texture space: `--space texture` (refused where another flag
/// needs the surface), `surface`, or `auto` (a textured output with nothing that needs the
/// surface).
fn choose_texture_space(a: &SynthArgs, textured_out: bool, optimise: bool) -> Result<bool> {
    Ok(match a.space.as_str() {
        "surface" => false,
        "texture" => {
            let clash = if !textured_out {
                Some("an output with a texture (.glb, .gltf or .obj)")
            } else if a.displace {
                Some("no --displace (it changes the geometry)")
            } else if a.mask.is_some() {
                Some("no --mask")
            } else if optimise {
                Some("--method neighbourhood")
            } else if a.out_dense.is_some() {
                Some("no --out-dense (there is no dense mesh)")
            } else {
                None
            };
            if let Some(c) = clash {
                return Err(Error::InvalidInput(format!("--space texture needs {c}")));
            }
            true
        }
        "auto" => {
            textured_out
                && !a.displace
                && a.mask.is_none()
                && !optimise
                && a.out_dense.is_none()
                && a.exemplar_width.is_none()
        }
        o => {
            return Err(Error::InvalidInput(format!(
                "--space {o}: use auto, texture or surface"
            )));
        }
    })
}

/// Whether patches are pasted: `--method patches` (refused where another flag clashes), or
/// `auto` on a textured output with nothing that needs the surface or the optimisation.
fn choose_patches(a: &SynthArgs, textured_out: bool) -> Result<bool> {
    Ok(match a.method.to_ascii_lowercase().as_str() {
        "patches" => {
            let clash = if !textured_out {
                Some("an output with a texture (.glb, .gltf or .obj)")
            } else if a.displace {
                Some("no --displace")
            } else if a.mask.is_some() {
                Some("no --mask")
            } else if a.out_dense.is_some() {
                Some("no --out-dense (there is no dense mesh)")
            } else if a.align_features {
                Some("no --align-features (it runs the texture optimisation)")
            } else if a.space == "surface" {
                Some("no --space surface (patches go into the texture)")
            } else {
                None
            };
            if let Some(c) = clash {
                return Err(Error::InvalidInput(format!("--method patches needs {c}")));
            }
            true
        }
        "auto" => {
            textured_out
                && !a.displace
                && a.mask.is_none()
                && a.out_dense.is_none()
                && a.exemplar_width.is_none()
                && !a.align_features
                && a.space != "surface"
        }
        _ => false,
    })
}

fn synth(a: &SynthArgs) -> Result<i32> {
    let plan = check(a)?;
    let inputs = input_paths(&[
        Some(&a.exemplar),
        Some(&a.target),
        a.mask.as_ref(),
        a.feature_mask.as_ref(),
    ]);
    let mut outputs = vec![("--out", a.out.as_path(), OutKind::Mesh)];
    if let Some(d) = &a.out_dense {
        outputs.push(("--out-dense", d.as_path(), OutKind::Mesh));
    }
    check_outputs(&inputs, &outputs)?;
    let (tex, alpha) = io::load_texture_with_alpha(&a.exemplar)?;
    let (exemplar, alpha) = prepare_exemplar(a, tex.image, alpha, &a.exemplar)?;
    let mut units = WorkingUnits::new();
    let target = units.load(&a.target)?;
    // --scale is a length in the target's file units
    let a = &SynthArgs {
        scale: a.scale.map(|s| units.length(s)),
        ..a.clone()
    };
    // The mask file numbers vertices as the file does.
    let mask = match &a.mask {
        Some(p) => Some(read_mask(p, target.file_vertex_count)?),
        None => None,
    };
    let feature_mask = match &a.feature_mask {
        Some(p) => Some(image::DynamicImage::ImageRgb8(io::load_texture(p)?.image).to_luma8()),
        None => None,
    };
    let bar = progress_bar();
    let sink = |e: crate::work::Event| bar_sink(&bar, e);
    let s = synthesize(
        a,
        &plan,
        &exemplar,
        alpha.as_ref(),
        &target,
        mask.as_deref(),
        feature_mask.as_ref(),
        &sink,
        &CancelToken::new(),
    )?;
    bar.finish_and_clear();
    units.save(&s.mesh, &a.out)?;
    crate::cli::common::announce_written(&a.out);
    if let (Some(d), Some(dense)) = (&a.out_dense, &s.dense) {
        units.save(dense, d)?;
        crate::cli::common::announce_written(d);
    }
    Ok(0)
}

/// A synthesis computed in memory ([`synthesize`]).
pub struct Synthesized {
    /// What `--out` writes: the target with a baked texture (textured outputs), or the
    /// uniform-density synthesized mesh with vertex colours (or displaced).
    pub mesh: crate::mesh::TriMesh,
    /// The uniform-density synthesized mesh (surface synthesis; `None` in texture space).
    pub dense: Option<crate::mesh::TriMesh>,
}

/// The exemplar as `synth` uses it: refused when transparent everywhere (`name` names it), shrunk
/// to `--exemplar-width`.
pub fn prepare_exemplar(
    a: &SynthArgs,
    mut exemplar: image::RgbImage,
    alpha: Option<image::GrayImage>,
    name: &std::path::Path,
) -> Result<(image::RgbImage, Option<image::GrayImage>)> {
    if let Some(al) = &alpha {
        let clear = al.pixels().filter(|p| p.0[0] < 128).count();
        if clear as u64 == al.width() as u64 * al.height() as u64 {
            return Err(Error::InvalidInput(format!(
                "{}: the exemplar is transparent everywhere: nothing to synthesize from",
                name.display()
            )));
        }
        eprintln!(
            "the exemplar has {clear} transparent pixels ({:.0}%): they are never synthesized",
            100.0 * clear as f64 / (al.width() as f64 * al.height() as f64)
        );
    }
    if let Some(w) = a.exemplar_width {
        if w < MIN_EXEMPLAR_WIDTH {
            return Err(Error::InvalidInput(format!(
                "--exemplar-width {w}: use {MIN_EXEMPLAR_WIDTH} or more pixels"
            )));
        }
        exemplar = crate::synthesis::exemplar::shrink_exemplar(exemplar, w);
    }
    Ok((exemplar, alpha))
}

/// `meshmatch synth` on an exemplar and a mesh in memory, as [`check`] planned it from `a` (whose
/// paths are not read): `file_mask` flags the target's file vertices to synthesise (`--mask`),
/// `feature_mask` is `--feature-mask`'s image. The CLI and the Python package call it.
#[allow(clippy::too_many_arguments)]
pub fn synthesize(
    a: &SynthArgs,
    plan: &Plan,
    exemplar: &image::RgbImage,
    alpha: Option<&image::GrayImage>,
    target: &crate::mesh::TriMesh,
    file_mask: Option<&[bool]>,
    feature_mask: Option<&image::GrayImage>,
    sink: &dyn Fn(crate::work::Event),
    cancel: &CancelToken,
) -> Result<Synthesized> {
    use crate::synthesis::{Orientation, SynthParams};
    let Plan {
        orientation,
        search,
        method,
        texture_space,
        textured_out,
        patches,
    } = *plan;
    if let Some(m) = file_mask
        && m.len() != target.file_vertex_count
    {
        return Err(Error::InvalidInput(format!(
            "the mask has {} entries but the target has {} vertices",
            m.len(),
            target.file_vertex_count
        )));
    }
    if patches {
        let mesh = synth_patches(a, exemplar, alpha, target, orientation, sink, cancel)?;
        return Ok(Synthesized { mesh, dense: None });
    }
    if texture_space {
        let mesh = synth_texture(
            a,
            exemplar,
            alpha,
            target,
            orientation,
            search,
            sink,
            cancel,
        )?;
        return Ok(Synthesized { mesh, dense: None });
    }
    let (exemplar, alpha) = surface_exemplar(a, exemplar, alpha, target);
    // The mask file numbers vertices as the file does; the synthesis takes one flag per vertex
    // of the loaded mesh (repair may have dropped unreferenced file vertices).
    let mask: Option<Vec<bool>> =
        file_mask.map(|m| target.file_index.iter().map(|&f| m[f as usize]).collect());
    let params = SynthParams {
        scale: a.scale,
        orientation,
        levels: a.levels,
        search,
        seed: a.seed,
        displace: a.displace,
        ..SynthParams::default()
    };
    let job = SurfaceJob {
        exemplar: &exemplar,
        alpha: alpha.as_ref(),
        target,
        mask: mask.as_deref(),
        params: &params,
    };
    let t = std::time::Instant::now();
    let r = if orientation == Orientation::Features {
        synth_along_features(a, method, &job, feature_mask, sink, cancel)?
    } else {
        synth_surface(a, method, &job, sink, cancel)?
    };
    print_anisotropy(r.anisotropy, r.orientation_used);
    eprintln!(
        "synthesized {} vertices in {:.2} s (search {:.2} s, {} search, orientation {}, method \
         {}); finest-level neighbourhood energy {:.5}",
        r.mesh.num_vertices(),
        t.elapsed().as_secs_f64(),
        r.timings.search,
        search.as_str(),
        r.orientation_used.as_str(),
        method.as_str(),
        r.level_energy.first().copied().unwrap_or(0.0)
    );
    // A texture on the target, unless the geometry is the result (displacement).
    let mesh = if !a.displace && textured_out {
        bake_result(a, target, &r.mesh, cancel)?
    } else {
        r.mesh.clone()
    };
    Ok(Synthesized {
        mesh,
        dense: Some(r.mesh),
    })
}

/// The exemplar (and alpha) the surface synthesis runs on: shrunk to fit `--vertex-budget`
/// unless `--exemplar-width` set its width.
fn surface_exemplar(
    a: &SynthArgs,
    exemplar: &image::RgbImage,
    alpha: Option<&image::GrayImage>,
    target: &crate::mesh::TriMesh,
) -> (image::RgbImage, Option<image::GrayImage>) {
    let mut exemplar = exemplar.clone();
    if a.exemplar_width.is_none() {
        let min = (4u32 << (a.levels.clamp(1, 8) - 1)).max(8);
        let (fitted, note) = crate::synthesis::exemplar::fit_exemplar_to_budget(
            exemplar,
            target,
            a.scale,
            a.vertex_budget,
            min,
        );
        exemplar = fitted;
        if let Some(n) = note {
            eprintln!("{n}");
        }
    }
    let alpha = alpha.map(|al| {
        crate::synthesis::exemplar::resize_alpha(al.clone(), exemplar.width(), exemplar.height())
    });
    (exemplar, alpha)
}

/// What a surface synthesis runs on.
struct SurfaceJob<'a> {
    exemplar: &'a image::RgbImage,
    alpha: Option<&'a image::GrayImage>,
    target: &'a crate::mesh::TriMesh,
    /// One flag per vertex of the loaded target (`true` = synthesise).
    mask: Option<&'a [bool]>,
    params: &'a crate::synthesis::SynthParams,
}

/// `--orientation features`: through feature-aligned texturing (the curves are needed to align
/// features), or, with a mask, the plain field-driven synthesis (it honours a mask).
fn synth_along_features(
    a: &SynthArgs,
    method: crate::synthesis::Method,
    job: &SurfaceJob,
    feature_mask: Option<&image::GrayImage>,
    sink: &dyn Fn(crate::work::Event),
    cancel: &CancelToken,
) -> Result<crate::synthesis::SynthResult> {
    let (exemplar, target) = (job.exemplar, job.target);
    let fa = crate::synthesis::feature_aligned::Params {
        synth: job.params.clone(),
        method,
        align_features: a.align_features,
        ..Default::default()
    };
    let input = crate::synthesis::feature_aligned::Input {
        target,
        exemplar,
        curves: None,
        alpha: job.alpha,
        feature_mask,
    };
    if let Some(m) = job.mask {
        // a mask keeps colours: the plain field-driven synthesis honours it
        let field = crate::synthesis::exemplar::feature_field(target, cancel)?;
        return crate::synthesis::exemplar::synthesize_with_alpha(
            exemplar,
            job.alpha,
            target,
            Some(m),
            Some(&field),
            job.params,
            sink,
            cancel,
        );
    }
    let out = crate::synthesis::feature_aligned::run(&input, &fa, sink, cancel)?;
    eprintln!(
        "{} salient curves (curves {:.2} s, field {:.2} s)",
        out.curves.len(),
        out.timings.curves,
        out.timings.field
    );
    if out.exemplar_turned {
        eprintln!(
            "the exemplar's lines are vertical: turned it a quarter turn to run along the curves"
        );
    }
    if out.exemplar_rolled > 0 {
        eprintln!(
            "the exemplar's line lies on its border: rolled it down {} rows (wrapping) so \
             whole patches centre on it",
            out.exemplar_rolled
        );
    }
    if let Some(l) = &out.lines {
        eprintln!(
            "the exemplar's principal lines: {} centre-line pixels",
            l.centre.iter().filter(|&&c| c).count()
        );
    }
    if let Some(rep) = &out.optimization {
        print_optimization(rep);
    }
    Ok(out.synth)
}

/// The surface synthesis, followed by the texture optimisation for `--method optimize`.
fn synth_surface(
    a: &SynthArgs,
    method: crate::synthesis::Method,
    job: &SurfaceJob,
    sink: &dyn Fn(crate::work::Event),
    cancel: &CancelToken,
) -> Result<crate::synthesis::SynthResult> {
    let input = crate::synthesis::exemplar::Input {
        exemplar: job.exemplar,
        target: job.target,
        mask: job.mask,
        alpha: job.alpha,
    };
    let mut r = crate::synthesis::exemplar::run(&input, job.params, sink, cancel)?;
    if method == crate::synthesis::Method::Optimize {
        let rep = crate::synthesis::texture_optimization::optimize_result(
            &mut r,
            job.target,
            job.exemplar,
            job.alpha,
            None,
            &crate::synthesis::texture_optimization::Params {
                seed: a.seed,
                ..Default::default()
            },
            sink,
            cancel,
        )?;
        print_optimization(&rep);
    }
    Ok(r)
}

/// The synthesized colours baked into a `--texture-size` texture on the target (through an atlas
/// generated for it if its UVs are unusable).
fn bake_result(
    a: &SynthArgs,
    target: &crate::mesh::TriMesh,
    dense: &crate::mesh::TriMesh,
    cancel: &CancelToken,
) -> Result<crate::mesh::TriMesh> {
    let colors = dense
        .colors
        .as_ref()
        .ok_or_else(|| Error::InvalidInput("synthesis gave no colours".into()))?;
    let (baked, atlas) = crate::geometry::bake_onto(
        target,
        dense,
        colors,
        a.texture_size,
        false,
        &|_| {},
        cancel,
    )?;
    if let Some(at) = atlas {
        eprintln!(
            "generated a UV atlas for the target: {} charts, {:.0}% of the texture",
            at.charts,
            100.0 * at.utilization
        );
    }
    eprintln!(
        "baked the result into a {0}x{0} texture on the target's {1} vertices",
        a.texture_size,
        baked.num_vertices()
    );
    Ok(baked)
}

/// `synth --space texture`: the synthesis on the texels of the target's UV layout.
#[allow(clippy::too_many_arguments)]
fn synth_texture(
    a: &SynthArgs,
    exemplar: &image::RgbImage,
    alpha: Option<&image::GrayImage>,
    target: &crate::mesh::TriMesh,
    orientation: crate::synthesis::Orientation,
    search: crate::synthesis::Search,
    sink: &dyn Fn(crate::work::Event),
    cancel: &CancelToken,
) -> Result<crate::mesh::TriMesh> {
    use crate::synthesis::exemplar::{TextureInput, synthesize_texture};
    let mut params = texture_params(a, orientation);
    params.synth.search = search;
    let input = TextureInput {
        exemplar,
        alpha,
        target,
        field: None,
    };
    let t = std::time::Instant::now();
    let r = synthesize_texture(&input, &params, sink, cancel)?;
    print_anisotropy(r.anisotropy, r.orientation_used);
    print_atlas(r.atlas.as_ref(), r.atlas_reason.as_deref());
    let (ew, _) = exemplar.dimensions();
    eprintln!(
        "synthesized in texture space: {} texels of a {w}x{w} working texture ({:.4} units a \
         texel), exemplar {}{}; levels {:?} texels",
        r.level_texels.first().copied().unwrap_or(0),
        r.spacing,
        r.working_exemplar_width,
        if r.working_exemplar_width < ew {
            format!(
                " pixels wide (shrunk from {ew} to the --texel-budget; the texture reads the full one)"
            )
        } else {
            " pixels wide (full)".to_string()
        },
        r.level_texels,
        w = r.working_size,
    );
    eprintln!(
        "synthesized in {:.2} s (prepare {:.2}, orientation {:.2}, neighbourhoods {:.2}, search \
         {:.2}, magnify {:.2}); finest-level neighbourhood energy {:.5}; texture {}x{}",
        t.elapsed().as_secs_f64(),
        r.timings.prepare,
        r.timings.orientation,
        r.timings.neighbourhoods,
        r.timings.search,
        r.timings.magnify,
        r.level_energy.first().copied().unwrap_or(0.0),
        a.texture_size,
        a.texture_size
    );
    Ok(r.mesh)
}

/// `synth --method patches`: large patches of the image pasted into the target's texture.
fn synth_patches(
    a: &SynthArgs,
    exemplar: &image::RgbImage,
    alpha: Option<&image::GrayImage>,
    target: &crate::mesh::TriMesh,
    orientation: crate::synthesis::Orientation,
    sink: &dyn Fn(crate::work::Event),
    cancel: &CancelToken,
) -> Result<crate::mesh::TriMesh> {
    use crate::synthesis::exemplar::TextureInput;
    use crate::synthesis::exemplar::patch_pasting::{PatchParams, paste_patches};
    let params = texture_params(a, orientation);
    let input = TextureInput {
        exemplar,
        alpha,
        target,
        field: None,
    };
    let r = paste_patches(&input, &params, &PatchParams::default(), sink, cancel)?;
    print_anisotropy(r.anisotropy, r.orientation_used);
    print_atlas(r.atlas.as_ref(), r.atlas_reason.as_deref());
    eprintln!(
        "pasted {} patches of radius {:.4} ({} made smaller to fit round parts; orientation {}) \
         in {:.2} s; {:.2}% of the texels filled from their neighbours; texture {}x{}",
        r.patches,
        r.radius,
        r.shrunk,
        r.orientation_used.as_str(),
        r.seconds,
        100.0 * r.uncovered,
        a.texture_size,
        a.texture_size
    );
    Ok(r.mesh)
}

/// The texture-space parameters the flags ask for (patch pasting reads the scale, orientation,
/// seed and texture size of them).
fn texture_params(
    a: &SynthArgs,
    orientation: crate::synthesis::Orientation,
) -> crate::synthesis::exemplar::TextureParams {
    crate::synthesis::exemplar::TextureParams {
        synth: crate::synthesis::SynthParams {
            scale: a.scale,
            orientation,
            levels: a.levels,
            seed: a.seed,
            ..Default::default()
        },
        texture_size: a.texture_size,
        texel_budget: a.texel_budget,
        new_atlas: false,
    }
}

/// The atlas generated for a texture-space result and why, on stderr.
fn print_atlas(atlas: Option<&crate::geometry::UvAtlas>, why: Option<&str>) {
    if let (Some(at), Some(why)) = (atlas, why) {
        eprintln!(
            "generated a UV atlas for the target ({why}): {} charts, {:.0}% of the texture",
            at.charts,
            100.0 * at.utilization
        );
    }
}

/// What `auto` measured and chose, on stderr.
fn print_anisotropy(
    anisotropy: Option<crate::synthesis::exemplar::Anisotropy>,
    used: crate::synthesis::Orientation,
) {
    if let Some(an) = anisotropy {
        eprintln!(
            "orientation auto: {} (the exemplar's gradient harmonics: 2-fold {:.2}, 4-fold {:.2}; \
             oriented from {:.2})",
            used.as_str(),
            an.twofold,
            an.fourfold,
            crate::synthesis::exemplar::anisotropy::ORIENTED,
        );
    }
}

/// The texture optimisation's numbers on stderr.
fn print_optimization(rep: &crate::synthesis::texture_optimization::Report) {
    for s in &rep.scales {
        eprintln!(
            "texture optimisation, {0}x{0} patches: {1} samples ({2} on or near curves), {3} \
             iterations, patch distance {4:.4} -> {5:.4}",
            s.patch,
            s.samples,
            s.constrained,
            s.energy.len(),
            s.energy.first().copied().unwrap_or(0.0),
            s.energy.last().copied().unwrap_or(0.0)
        );
    }
    eprintln!("texture optimisation took {:.2} s", rep.seconds);
}
