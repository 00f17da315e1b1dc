//! Texture synthesis over arbitrary surfaces from a 2D exemplar image, after Wei & Levoy 2001,
//! "Texture synthesis over arbitrary manifold surfaces" (SIGGRAPH 2001).
//!
//! Pipeline (paper Table 3): refine the target to a uniform vertex density set by `scale`
//! (`d = sqrt(2 A)` template spacing matches the exemplar's texel size), build a mesh pyramid with
//! about a quarter of the vertices per level and a Gaussian image pyramid, assign a texture
//! orientation per vertex (random, projected up axis, or n-way symmetric relaxation), then
//! synthesize coarse to fine: each vertex, visited in random order, gets the exemplar pixel whose
//! multiresolution neighbourhood (`{1x1,1}, {3x3,2}, {5x5,2}, {7x7,2}`) best matches the mesh
//! neighbourhood, flattened into its tangent frame and resampled on the template grid. Two passes
//! per level: parent level only, then current + parent level.

pub mod anisotropy;
mod border_reach;
pub mod character;
mod colour_balance;
mod levels;
mod membrane;
mod metrics;
mod neigh;
mod orient;
pub mod patch_pasting;
mod pyramid;
mod seam;
mod search;
pub mod texture_space;

use glam::Vec3;

use crate::error::{Error, Result};
use crate::mesh::TriMesh;
use crate::work::{CancelToken, Event, Progress, Stopwatch};

pub use metrics::{
    color_histogram, exemplar_loo_distance, histogram_l1, image_colors, neighbourhood_distance,
};
pub use orient::orientation_energy;
pub use texture_space::{
    DEFAULT_TEXEL_BUDGET, TextureInput, TextureOutput, TextureParams, TextureTimings,
    synthesize_texture,
};

use crate::geometry::vertex_normals;
use crate::hierarchy::{Hierarchy, HierarchyOptions};
pub use anisotropy::{Anisotropy, choose_orientation, exemplar_anisotropy};
use levels::{LevelsOut, synthesize_levels};
use neigh::build_stencils;
use pyramid::{Img, Level, aggregate_fixed, coarsen, image_pyramid, refine_edges, stage_rng};

/// How the local texture orientation (texture "right" `s`) is assigned per vertex.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Orientation {
    /// Chosen from the exemplar ([`anisotropy::choose_orientation`]): random for isotropic
    /// textures, `Relax2` for striped ones, `Relax4` for grids.
    #[default]
    Auto,
    /// Random direction per vertex (isotropic textures; Wei & Levoy §3.1).
    Random,
    /// Texture up = the +Y axis projected into the tangent plane.
    Up,
    /// 2-way symmetric relaxation (stripes).
    Relax2,
    /// 4-way symmetric relaxation (grids).
    Relax4,
    /// Along the salient curves of the target: the curve-guided field of Xu et al. 2009
    /// ([`crate::geometry::oriented_curve_field`] on [`crate::geometry::salient_curves`] with
    /// default thresholds), or the explicit field given to [`synthesize_with_field`].
    Features,
}

impl Orientation {
    /// The CLI spelling: `random`, `up`, `relax2`, `relax4`.
    pub fn as_str(self) -> &'static str {
        match self {
            Orientation::Auto => "auto",
            Orientation::Random => "random",
            Orientation::Up => "up",
            Orientation::Relax2 => "relax2",
            Orientation::Relax4 => "relax4",
            Orientation::Features => "features",
        }
    }
}

impl std::str::FromStr for Orientation {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        match s {
            "auto" => Ok(Orientation::Auto),
            "random" => Ok(Orientation::Random),
            "up" => Ok(Orientation::Up),
            "relax2" => Ok(Orientation::Relax2),
            "relax4" => Ok(Orientation::Relax4),
            "features" => Ok(Orientation::Features),
            _ => Err(Error::InvalidInput(format!(
                "unknown orientation '{s}' (expected auto, random, up, relax2, relax4 or features)"
            ))),
        }
    }
}

/// Best-match search strategy.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Search {
    /// Every exemplar neighbourhood of the level (the reference; rayon-parallel per query).
    Exhaustive,
    /// Coherence candidates from the neighbours' and parent's source pixels plus PatchMatch
    /// random search.
    #[default]
    Fast,
}

impl Search {
    /// The CLI spelling: `exhaustive`, `fast`.
    pub fn as_str(self) -> &'static str {
        match self {
            Search::Exhaustive => "exhaustive",
            Search::Fast => "fast",
        }
    }
}

impl std::str::FromStr for Search {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        match s {
            "exhaustive" => Ok(Search::Exhaustive),
            "fast" => Ok(Search::Fast),
            _ => Err(Error::InvalidInput(format!(
                "unknown search '{s}' (expected exhaustive or fast)"
            ))),
        }
    }
}

/// The system's parameters (the paper's defaults): see [`SynthParams`].
pub type Params = SynthParams;

/// The system's output: see [`SynthResult`].
pub type Output = SynthResult;

/// What the system works on.
#[derive(Clone, Copy, Debug)]
pub struct Input<'a> {
    /// The exemplar image (sRGB colours, or a grey displacement map with `displace`).
    pub exemplar: &'a image::RgbImage,
    /// The mesh to texture.
    pub target: &'a TriMesh,
    /// Per vertex of `target`: true = synthesise, false = keep its colour (`None`: every vertex).
    pub mask: Option<&'a [bool]>,
    /// The exemplar's alpha (same size), if it has transparent pixels: pixels under one half are
    /// never candidates, so their colour is never synthesized.
    pub alpha: Option<&'a image::GrayImage>,
}

/// The system's front door: [`synthesize`] on an [`Input`].
pub fn run(
    input: &Input,
    params: &Params,
    sink: &dyn Fn(Event),
    cancel: &CancelToken,
) -> Result<Output> {
    synthesize_with_alpha(
        input.exemplar,
        input.alpha,
        input.target,
        input.mask,
        None,
        params,
        sink,
        cancel,
    )
}

/// Parameters of surface texture synthesis.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
#[serde(default)]
pub struct SynthParams {
    /// Mesh units spanned by one exemplar width; `None` = a quarter of the bounding-box diagonal.
    pub scale: Option<f32>,
    /// Texture orientation field.
    pub orientation: Orientation,
    /// Pyramid levels (mesh and image), 1..=8.
    pub levels: usize,
    /// Search strategy.
    pub search: Search,
    /// Random seed (orientation, visiting order, initialisation, random search).
    pub seed: u64,
    /// Apply the synthesized grey value as a displacement along the normals.
    pub displace: bool,
    /// Displacement for a full black-to-white step, in mesh units; `None` = `scale / 20`.
    pub displace_amount: Option<f32>,
    /// Passes per level (the first uses the parent level only), at least 1.
    pub passes: usize,
    /// Random candidates per vertex in fast search.
    pub random_candidates: usize,
    /// Relaxation sweeps on the coarsest level (finer levels use a quarter).
    pub relax_sweeps: usize,
    /// Refuse to refine the target beyond this many vertices.
    pub max_vertices: usize,
}

impl Default for SynthParams {
    fn default() -> Self {
        SynthParams {
            scale: None,
            orientation: Orientation::Auto,
            levels: 4,
            search: Search::Fast,
            seed: 0,
            displace: false,
            displace_amount: None,
            passes: 2,
            random_candidates: 4,
            relax_sweeps: 60,
            max_vertices: 2_000_000,
        }
    }
}

/// Wall-clock seconds per stage.
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct SynthTimings {
    /// Refinement and mesh/image pyramids.
    pub prepare: f64,
    /// Orientation field.
    pub orientation: f64,
    /// Mesh stencils (patch flattening) and exemplar neighbourhoods.
    pub neighbourhoods: f64,
    /// Best-match search and colour assignment (all levels and passes).
    pub search: f64,
    /// Whole call.
    pub total: f64,
}

/// The outcome of [`synthesize`].
#[derive(Clone, Debug)]
pub struct SynthResult {
    /// The uniform-density synthesized mesh (the target refined; its first vertices are the
    /// target's own) with sRGB vertex colours, displaced when asked.
    pub mesh: TriMesh,
    /// Colours on the target's own vertices, in the file's vertex order.
    pub file_colors: Vec<[f32; 3]>,
    /// Texture "right" direction per vertex of `mesh`.
    pub orientation: Vec<[f32; 3]>,
    /// Source exemplar pixel `[x, y]` per vertex of `mesh` (`u32::MAX` for fixed vertices).
    pub source: Vec<[u32; 2]>,
    /// Mesh units per exemplar pixel at the finest level (`scale / exemplar width`).
    pub spacing: f32,
    /// The paper's template spacing `d = sqrt(2 * mean triangle area)` of the finest mesh.
    pub mesh_d: f32,
    /// Vertex count per pyramid level, finest first.
    pub level_vertices: Vec<usize>,
    /// Mean squared neighbourhood distance per element in each level's last pass, finest first.
    pub level_energy: Vec<f64>,
    /// Displacement per vertex of `mesh` (mesh units) when `displace` was set.
    pub displacement: Option<Vec<f32>>,
    /// Stage timings.
    pub timings: SynthTimings,
    /// The orientation field used (`Auto` resolved).
    pub orientation_used: Orientation,
    /// The exemplar's measured anisotropy, when `Auto` chose the field.
    pub anisotropy: Option<Anisotropy>,
}

/// Shrink an exemplar to at most `width` pixels wide, keeping its aspect (Triangle filter); an
/// image already that narrow, or `width == 0`, is returned unchanged. The exemplar's width in
/// pixels sets the texel spacing on the surface (`scale / width`), so the synthesized vertex count
/// grows with its square.
pub fn shrink_exemplar(img: image::RgbImage, width: u32) -> image::RgbImage {
    let (w, h) = img.dimensions();
    if width == 0 || w <= width {
        return img;
    }
    let nh = ((h as f64 * width as f64 / w as f64).round() as u32).max(1);
    image::imageops::resize(&img, width, nh, image::imageops::FilterType::Triangle)
}

/// `alpha` resized to `width × height` (Triangle filter), as the exemplar it belongs to was.
pub fn resize_alpha(alpha: image::GrayImage, width: u32, height: u32) -> image::GrayImage {
    if alpha.dimensions() == (width, height) {
        return alpha;
    }
    image::imageops::resize(&alpha, width, height, image::imageops::FilterType::Triangle)
}

/// Vertices the uniform refinement makes per exemplar texel of surface area (`area / h0²`):
/// edges end in (0.8 h0, 1.6 h0], slightly shorter than h0 on average. Measured: 1.22 (Spot),
/// 1.28 (penguin).
pub const REFINED_PER_TEXEL: f64 = 1.25;

/// A vertex count for a message: digits, or a power of ten when absurd.
fn count(x: f64) -> String {
    if x < 1e12 {
        format!("{x:.0}")
    } else {
        format!("{x:.1e}")
    }
}

/// Default vertex budget of a synthesis run chosen by [`fit_exemplar_to_budget`].
pub const DEFAULT_VERTEX_BUDGET: usize = 300_000;

/// Choose the working density from a vertex budget: the texel spacing is `scale / width`, so the
/// synthesized mesh has about `area / (scale / width)^2` vertices; when that exceeds `budget`,
/// the exemplar is shrunk (aspect kept) until it fits, never below the `min_width` the pyramid
/// needs. Returns the exemplar to use and, when it was shrunk, a sentence saying so.
/// `scale = None` means the synthesis default, a quarter of the bounding-box diagonal.
pub fn fit_exemplar_to_budget(
    exemplar: image::RgbImage,
    target: &TriMesh,
    scale: Option<f32>,
    budget: usize,
    min_width: u32,
) -> (image::RgbImage, Option<String>) {
    let Some((lo, hi)) = target.bounds() else {
        return (exemplar, None);
    };
    let diag = Vec3::from(hi).distance(Vec3::from(lo));
    let scale = scale.unwrap_or(diag / 4.0);
    let (w, h) = exemplar.dimensions();
    if !(scale.is_finite() && scale > 0.0) || w == 0 || budget == 0 {
        return (exemplar, None);
    }
    let estimate = |width: f64| REFINED_PER_TEXEL * target.area() * (width / scale as f64).powi(2);
    let before = estimate(w as f64);
    if before <= budget as f64 {
        return (exemplar, None);
    }
    let fit = (w as f64 * (budget as f64 / before).sqrt()).floor() as u32;
    // Keep the smaller side at least `min_width` too.
    let min_w = if h < w {
        (min_width as f64 * w as f64 / h as f64).ceil() as u32
    } else {
        min_width
    };
    let width = fit.max(min_w).min(w);
    if width >= w {
        return (exemplar, None);
    }
    if estimate(width as f64) > SynthParams::default().max_vertices as f64 {
        // Even the smallest exemplar cannot fit: the synthesis refuses the scale in one line.
        return (exemplar, None);
    }
    let out = shrink_exemplar(exemplar, width);
    let note = format!(
        "the exemplar ({w}x{h}) at this scale needs about {before:.0} vertices, over the budget of \
         {budget}: shrunk to {}x{} pixels (about {:.0} vertices; a larger --scale or \
         --vertex-budget keeps more of it)",
        out.width(),
        out.height(),
        estimate(out.width() as f64)
    );
    (out, Some(note))
}

/// The exemplar with its transparent pixels (alpha < 1/2) filled by pull-push from the opaque
/// ones, and its alpha as an image (grey in all channels) for the pyramid. Refuses an exemplar
/// with no opaque pixel, or an alpha of another size.
pub(crate) fn transparent_filled(
    exemplar: &image::RgbImage,
    alpha: &image::GrayImage,
) -> Result<(Img, Img)> {
    if alpha.dimensions() != exemplar.dimensions() {
        return Err(Error::InvalidInput(format!(
            "the exemplar's alpha is {:?}, its colours {:?}",
            alpha.dimensions(),
            exemplar.dimensions()
        )));
    }
    let img = Img::from_rgb(exemplar);
    let covered: Vec<bool> = alpha.pixels().map(|p| p.0[0] >= 128).collect();
    if !covered.iter().any(|&c| c) {
        return Err(Error::InvalidInput(
            "the exemplar is transparent everywhere: nothing to synthesize from".into(),
        ));
    }
    let mut baked = crate::geometry::BakedImage {
        width: img.w,
        height: img.h,
        pixels: img.px,
        covered,
    };
    crate::geometry::fill_gutters(&mut baked);
    let a = Img {
        w: img.w,
        h: img.h,
        px: alpha.pixels().map(|p| [p.0[0] as f32 / 255.0; 3]).collect(),
    };
    Ok((
        Img {
            w: img.w,
            h: img.h,
            px: baked.pixels,
        },
        a,
    ))
}

/// Synthesize the exemplar's texture over `target` (Wei & Levoy 2001). `mask` (one flag per
/// target vertex, `true` = synthesize) keeps the target's own colours elsewhere and uses them as
/// constraints. Emits `Event::Partial` (colours on the finest synthesized mesh) after every pass
/// and honours `cancel` between small batches of vertices.
pub fn synthesize(
    exemplar: &image::RgbImage,
    target: &TriMesh,
    mask: Option<&[bool]>,
    params: &SynthParams,
    sink: &dyn Fn(Event),
    cancel: &CancelToken,
) -> Result<SynthResult> {
    synthesize_with_field(exemplar, target, mask, None, params, sink, cancel)
}

/// The curve-guided orientation field of `target` with default thresholds (Xu et al. 2009):
/// salient curves, greedy orientation, harmonic diffusion; unit tangents per target vertex.
/// The same field as feature-aligned texturing's with its defaults
/// ([`super::curve_field::curves_and_field`]).
pub fn feature_field(target: &TriMesh, cancel: &CancelToken) -> Result<Vec<[f32; 3]>> {
    let (curves, field) = (
        crate::geometry::CurveParams::default(),
        crate::geometry::FieldParams::default(),
    );
    let stage = super::curve_field::FieldStage {
        curves: &curves,
        field: &field,
        coarse_greedy_above: None,
        greedy_vertices: 0,
    };
    let (_, field, _) = super::curve_field::curves_and_field(target, None, &stage, cancel)?;
    Ok(field.field)
}

/// [`synthesize`] with an explicit texture "right" direction per target vertex (`field`, one per
/// vertex of `target`; used unless the orientation is `Random` or `Up`; with
/// [`Orientation::Features`], `None` computes [`feature_field`]). The field is carried onto
/// the refined mesh by averaging edge ends, onto coarser levels by averaging children, and
/// projected on each tangent plane.
pub fn synthesize_with_field(
    exemplar: &image::RgbImage,
    target: &TriMesh,
    mask: Option<&[bool]>,
    field: Option<&[[f32; 3]]>,
    params: &SynthParams,
    sink: &dyn Fn(Event),
    cancel: &CancelToken,
) -> Result<SynthResult> {
    synthesize_with_alpha(exemplar, None, target, mask, field, params, sink, cancel)
}

/// [`synthesize_with_field`] for an exemplar with transparent pixels: where `alpha` (the
/// exemplar's size) is under one half, pixels are never candidates, so their colour never
/// appears in the result; their colour is first replaced by a pull-push fill from the opaque
/// pixels around them, so neighbourhoods that overlap a hole compare against plausible colours.
#[allow(clippy::too_many_arguments)]
pub fn synthesize_with_alpha(
    exemplar: &image::RgbImage,
    alpha: Option<&image::GrayImage>,
    target: &TriMesh,
    mask: Option<&[bool]>,
    field: Option<&[[f32; 3]]>,
    params: &SynthParams,
    sink: &dyn Fn(Event),
    cancel: &CancelToken,
) -> Result<SynthResult> {
    // `Auto`: the field the exemplar's anisotropy asks for.
    let (resolved, anisotropy) = resolve_auto(params, exemplar, alpha);
    let params = &resolved;
    let total = Stopwatch::start();
    let mut timings = SynthTimings::default();
    let (scale, h0) = check_surface_input(exemplar, target, mask, params)?;
    let nlev = params.levels;

    // ---- prepare: finest level (uniform density), mesh pyramid, image pyramid
    let clock = Stopwatch::start();
    sink(Event::Progress(Progress {
        stage: "refine",
        levels: nlev,
        elapsed: total.secs(),
        ..Default::default()
    }));
    let fixed0 = kept_colours(target, mask)?;
    let nv = target.num_vertices();
    if let Some(f) = field
        && f.len() != nv
    {
        return Err(Error::InvalidInput(format!(
            "orientation field has {} entries, the target has {nv} vertices",
            f.len()
        )));
    }
    let computed = match (field, params.orientation) {
        (None, Orientation::Features) => Some(feature_field(target, cancel)?),
        _ => None,
    };
    let field: Option<&[[f32; 3]]> = field.or(computed.as_deref());
    let (levels, carried) = surface_levels(target, fixed0, field, h0, params, cancel)?;
    let (imgs, alphas) = exemplar_pyramids(exemplar, alpha, nlev)?;
    let mesh_d = (2.0 * levels[0].mean_face_area()).sqrt() as f32;
    timings.prepare = clock.secs();
    sink(Event::StageTime("prepare", timings.prepare));
    cancel.check()?;

    let out = synthesize_levels(
        &levels,
        field.is_some().then_some(&carried[..]),
        &imgs,
        alphas.as_deref(),
        h0,
        params,
        &total,
        &|k, dirs, h, size, parent| mesh_stencils(&levels, k, dirs, h, size, parent),
        sink,
        cancel,
    )?;
    timings.orientation = out.orientation_secs;
    timings.neighbourhoods = out.neighbourhood_secs;
    timings.search = out.search_secs;
    drop(imgs);

    // ---- deliver
    let level_vertices: Vec<usize> = levels.iter().map(|l| l.num_vertices()).collect();
    let fine = levels.into_iter().next().expect("finest level");
    let delivered = deliver_surface(target, fine, out, params, scale);
    timings.total = total.secs();
    Ok(SynthResult {
        mesh: delivered.mesh,
        file_colors: delivered.file_colors,
        orientation: delivered.dirs,
        source: delivered.source,
        spacing: h0,
        mesh_d,
        level_vertices,
        level_energy: delivered.level_energy,
        displacement: delivered.displacement,
        timings,
        orientation_used: params.orientation,
        anisotropy,
    })
}

/// The resampling stencils of mesh level `k` (a stencil builder): on the level itself, or on its
/// parent level.
fn mesh_stencils(
    levels: &[Level],
    k: usize,
    dirs: &[[f32; 3]],
    h: f32,
    size: usize,
    parent: bool,
) -> neigh::Stencils {
    if parent {
        build_stencils(
            &levels[k],
            dirs,
            &levels[k + 1],
            Some(&levels[k].parent),
            h,
            size,
        )
    } else {
        build_stencils(&levels[k], dirs, &levels[k], None, h, size)
    }
}

/// The parameters with `Auto` orientation resolved from the exemplar's anisotropy (and that
/// anisotropy); other orientations as they are.
fn resolve_auto(
    params: &SynthParams,
    exemplar: &image::RgbImage,
    alpha: Option<&image::GrayImage>,
) -> (SynthParams, Option<Anisotropy>) {
    if params.orientation == Orientation::Auto {
        let a = anisotropy::exemplar_anisotropy(exemplar, alpha);
        let resolved = SynthParams {
            orientation: anisotropy::choose_orientation(a),
            ..params.clone()
        };
        (resolved, Some(a))
    } else {
        (params.clone(), None)
    }
}

/// The image's width in surface units: `scale`, or a quarter of the target's bounding-box
/// diagonal; refuses a mesh without extent and a scale that is not positive.
pub(crate) fn surface_scale(target: &TriMesh, scale: Option<f32>) -> Result<f32> {
    let (lo, hi) = target
        .bounds()
        .ok_or_else(|| Error::InvalidMesh("empty mesh".into()))?;
    let diag = Vec3::from(hi).distance(Vec3::from(lo));
    if !(diag > 0.0 && diag.is_finite()) {
        return Err(Error::InvalidMesh("target mesh has zero extent".into()));
    }
    let scale = scale.unwrap_or(diag / 4.0);
    if !(scale.is_finite() && scale > 0.0) {
        return Err(Error::InvalidInput(format!(
            "scale must be positive, got {scale}"
        )));
    }
    Ok(scale)
}

/// Refuse a target, exemplar, scale or mask the surface synthesis cannot use, or a refined mesh
/// over the vertex limit or the memory; the scale and the texel spacing `h0` it gives.
fn check_surface_input(
    exemplar: &image::RgbImage,
    target: &TriMesh,
    mask: Option<&[bool]>,
    params: &SynthParams,
) -> Result<(f32, f32)> {
    validate(target, exemplar.dimensions(), params.levels)?;
    let nv = target.num_vertices();
    let scale = surface_scale(target, params.scale)?;
    if let Some(m) = mask {
        if m.len() != nv {
            return Err(Error::InvalidInput(format!(
                "mask has {} entries, the target has {nv} vertices",
                m.len()
            )));
        }
        if !m.iter().any(|&b| b) {
            return Err(Error::InvalidInput("mask selects no vertex".into()));
        }
    }
    let h0 = scale / exemplar.width() as f32;
    let area = target.area();
    let estimate = REFINED_PER_TEXEL * area / (h0 as f64 * h0 as f64);
    if estimate > params.max_vertices as f64 {
        return Err(Error::InvalidInput(format!(
            "scale {} needs about {} vertices (limit {}); use a larger scale or a smaller \
             exemplar",
            if (1e-4..1e6).contains(&scale) {
                format!("{scale}")
            } else {
                format!("{scale:e}")
            },
            count(estimate),
            params.max_vertices
        )));
    }
    // Measured peak: about 1.8 KB per synthesized vertex (mesh pyramid, frames, neighbourhood
    // vectors, search structures); 4 KB leaves room for the input and the exemplar pyramid.
    let working = estimate.max(nv as f64) as u64;
    crate::work::check_memory(
        working.saturating_mul(4 << 10),
        &format!("{working} synthesized vertices"),
        "use a larger --scale or a smaller --vertex-budget",
    )?;
    Ok((scale, h0))
}

/// Per target vertex, the colour a mask keeps (`Some`) or `None` where it is synthesized.
fn kept_colours(target: &TriMesh, mask: Option<&[bool]>) -> Result<Vec<Option<[f32; 3]>>> {
    Ok(match mask {
        None => vec![None; target.num_vertices()],
        Some(m) => {
            let signal = target.vertex_signal().ok_or_else(|| {
                Error::InvalidInput(
                    "a mask keeps the target's colours outside it, but the target has none".into(),
                )
            })?;
            m.iter()
                .zip(signal)
                .map(|(&syn, c)| if syn { None } else { Some(c) })
                .collect()
        }
    })
}

/// The sample levels on the surface: the target refined to the texel spacing `h0` (kept colours
/// and the field carried along), then the mesh pyramid; the field per finest vertex.
fn surface_levels(
    target: &TriMesh,
    fixed0: Vec<Option<[f32; 3]>>,
    field: Option<&[[f32; 3]]>,
    h0: f32,
    params: &SynthParams,
    cancel: &CancelToken,
) -> Result<(Vec<Level>, Vec<[f32; 3]>)> {
    let nlev = params.levels;
    let mut positions = target.positions.clone();
    let mut faces = target.faces.clone();
    let mut fixed: Vec<(Option<[f32; 3]>, [f32; 3])> = match field {
        Some(f) => fixed0.into_iter().zip(f.iter().copied()).collect(),
        None => fixed0.into_iter().map(|x| (x, [0.0; 3])).collect(),
    };
    // Bisection leaves edges in (T/2, T]; T = 1.6 h0 gives mean triangle area close to h0^2 / 2,
    // i.e. the paper's d = sqrt(2 A) close to the texel spacing h0.
    refine_edges(
        &mut positions,
        &mut faces,
        &mut fixed,
        1.6 * h0,
        params.max_vertices,
        |a, b| {
            let c = match (&a.0, &b.0) {
                (Some(x), Some(y)) => Some([0, 1, 2].map(|k| 0.5 * (x[k] + y[k]))),
                _ => None,
            };
            (c, [0, 1, 2].map(|k| a.1[k] + b.1[k]))
        },
    )?;
    let (fixed, carried): (Vec<_>, Vec<_>) = fixed.into_iter().unzip();
    cancel.check()?;
    let normals = vertex_normals(&positions, &faces);
    let levels = mesh_pyramid(
        Level::new(positions, faces, normals, fixed),
        nlev,
        params.seed,
        cancel,
    )?;
    Ok((levels, carried))
}

/// Mesh pyramid: the shared MeshMatch hierarchy (shortest-edge-first midpoint collapses, about
/// half the vertices per level), every second level, so each level keeps about a quarter; grid
/// clustering where the hierarchy stops early.
fn mesh_pyramid(finest: Level, nlev: usize, seed: u64, cancel: &CancelToken) -> Result<Vec<Level>> {
    let hier = Hierarchy::build(
        &finest.positions,
        &finest.faces,
        HierarchyOptions {
            min_vertices: 16,
            max_levels: Some(2 * (nlev - 1) + 1),
        },
    )?;
    cancel.check()?;
    let mut levels = vec![finest];
    let mut rng = stage_rng(seed, 1);
    let mut hl = 0usize; // hierarchy level of levels.last()
    while levels.len() < nlev {
        let fine = levels.last_mut().expect("non-empty");
        if hl + 2 < hier.num_levels() {
            let (p0, p1) = (&hier.parents[hl], &hier.parents[hl + 1]);
            let parent: Vec<u32> = p0.iter().map(|&p| p1[p as usize]).collect();
            let h = &hier.levels[hl + 2];
            let fixed = aggregate_fixed(&fine.fixed, &parent, h.positions.len());
            fine.parent = parent;
            levels.push(Level::new(
                h.positions.clone(),
                h.faces.clone(),
                h.normals.clone(),
                fixed,
            ));
            hl += 2;
        } else {
            // the hierarchy stopped early (collapses blocked): grid clustering instead
            let coarse = coarsen(fine, 0.25, &mut rng);
            levels.push(coarse);
            hl = usize::MAX / 2;
        }
    }
    Ok(levels)
}

/// The exemplar's image pyramid (transparent pixels filled from the opaque ones) and, with an
/// alpha, the alpha's pyramid.
pub(crate) fn exemplar_pyramids(
    exemplar: &image::RgbImage,
    alpha: Option<&image::GrayImage>,
    nlev: usize,
) -> Result<(Vec<Img>, Option<Vec<Img>>)> {
    Ok(match alpha {
        None => (image_pyramid(Img::from_rgb(exemplar), nlev), None),
        Some(a) => {
            let (img, a) = transparent_filled(exemplar, a)?;
            (image_pyramid(img, nlev), Some(image_pyramid(a, nlev)))
        }
    })
}

/// What the surface synthesis delivers from its finest level.
struct Delivered {
    mesh: TriMesh,
    file_colors: Vec<[f32; 3]>,
    dirs: Vec<[f32; 3]>,
    source: Vec<[u32; 2]>,
    level_energy: Vec<f64>,
    displacement: Option<Vec<f32>>,
}

/// The synthesized mesh (displaced along its normals by the colour's luminance when asked),
/// its colours in the target's file order, and each vertex's exemplar pixel.
fn deliver_surface(
    target: &TriMesh,
    fine: Level,
    out: LevelsOut,
    params: &SynthParams,
    scale: f32,
) -> Delivered {
    let LevelsOut {
        colors: col,
        sources,
        dirs,
        level_energy,
        exemplar: ex0,
        ..
    } = out;
    let source: Vec<[u32; 2]> = sources
        .iter()
        .map(|&c| {
            if c == u32::MAX {
                [u32::MAX; 2]
            } else {
                let (x, y) = ex0.pixel(c);
                [x as u32, y as u32]
            }
        })
        .collect();
    let mut positions = fine.positions;
    let displacement = params.displace.then(|| {
        let amount = params.displace_amount.unwrap_or(scale / 20.0);
        let luma = |c: [f32; 3]| 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2];
        let mean = luma(ex0.mean);
        let disp: Vec<f32> = col.iter().map(|&c| (luma(c) - mean) * amount).collect();
        for (p, (n, d)) in positions.iter_mut().zip(fine.normals.iter().zip(&disp)) {
            for k in 0..3 {
                p[k] += n[k] * d;
            }
        }
        disp
    });
    let mut mesh = TriMesh::new(positions, fine.faces);
    mesh.normals = Some(vertex_normals(&mesh.positions, &mesh.faces));
    mesh.colors = Some(col.clone());
    mesh.path = None;
    let nv = target.num_vertices();
    let file_colors = target.to_file_order(&col[..nv], [0.5; 3]);
    Delivered {
        mesh,
        file_colors,
        dirs,
        source,
        level_energy,
        displacement,
    }
}

/// The checks every synthesis entry makes on its target, exemplar and level count, as one-line
/// errors: faces, finite coordinates, face indices, 1 to 8 levels, and an exemplar at least
/// `4 * 2^(levels - 1)` (and 8) pixels on its smaller side.
pub(crate) fn validate(target: &TriMesh, exemplar: (u32, u32), levels: usize) -> Result<()> {
    if target.faces.is_empty() || target.positions.is_empty() {
        return Err(Error::InvalidMesh("target mesh has no faces".into()));
    }
    if target.positions.iter().flatten().any(|x| !x.is_finite()) {
        return Err(Error::InvalidMesh(
            "target mesh has non-finite coordinates".into(),
        ));
    }
    let nv = target.num_vertices();
    if target.faces.iter().flatten().any(|&i| i as usize >= nv) {
        return Err(Error::InvalidMesh(
            "target face refers to a missing vertex".into(),
        ));
    }
    if !(1..=8).contains(&levels) {
        return Err(Error::InvalidInput(format!(
            "levels must be between 1 and 8, got {levels}"
        )));
    }
    let (ew, eh) = exemplar;
    let m = (4u32 << (levels - 1)).max(8);
    if ew.min(eh) < m {
        return Err(Error::InvalidInput(format!(
            "exemplar {ew}x{eh} is too small for {levels} levels (needs at least {m}x{m})"
        )));
    }
    Ok(())
}
