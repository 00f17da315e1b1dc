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
pub mod character;
mod metrics;
mod neigh;
mod orient;
pub mod patch_pasting;
mod pyramid;
mod search;
pub mod texture_space;

use std::sync::Arc;

use glam::Vec3;
use rand::seq::SliceRandom;

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
use neigh::{ExemplarLevel, Stencils, build_stencils};
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

/// Neighbourhood sizes of level `k` (0 = finest) in an `l`-level pyramid: current `NxN` and parent
/// size (0 = no parent). Wei & Levoy §4: `{1x1,1}, {3x3,2}, {5x5,2}, {7x7,2}` coarse to fine.
fn sizes(k: usize, l: usize) -> (usize, usize) {
    if k + 1 == l {
        return (if l == 1 { 7 } else { 1 }, 0);
    }
    let s = [7, 5, 3].get(k).copied().unwrap_or(3);
    (s, (s / 2) | 1)
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
    let (resolved, anisotropy);
    let params = if params.orientation == Orientation::Auto {
        let a = anisotropy::exemplar_anisotropy(exemplar, alpha);
        anisotropy = Some(a);
        resolved = SynthParams {
            orientation: anisotropy::choose_orientation(a),
            ..params.clone()
        };
        &resolved
    } else {
        anisotropy = None;
        params
    };
    let total = Stopwatch::start();
    let mut timings = SynthTimings::default();
    // ---- validate
    validate(target, exemplar.dimensions(), params.levels)?;
    let nv = target.num_vertices();
    let (lo, hi) = target
        .bounds()
        .ok_or_else(|| Error::InvalidMesh("empty mesh".into()))?;
    let diag = Vec3::from(hi).distance(Vec3::from(lo));
    if diag <= 0.0 {
        return Err(Error::InvalidMesh("target mesh has zero extent".into()));
    }
    let scale = params.scale.unwrap_or(diag / 4.0);
    if !(scale.is_finite() && scale > 0.0) {
        return Err(Error::InvalidInput(format!(
            "scale must be positive, got {scale}"
        )));
    }
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
    let nlev = params.levels;

    // ---- prepare: finest level (uniform density), mesh pyramid, image pyramid
    let clock = Stopwatch::start();
    sink(Event::Progress(Progress {
        stage: "refine",
        levels: nlev,
        elapsed: total.secs(),
        ..Default::default()
    }));
    let fixed0: Vec<Option<[f32; 3]>> = match mask {
        None => vec![None; nv],
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
    };
    if let Some(f) = field
        && f.len() != nv
    {
        return Err(Error::InvalidInput(format!(
            "orientation field has {} entries, the target has {nv} vertices",
            f.len()
        )));
    }
    let computed;
    let field: Option<&[[f32; 3]]> = match (field, params.orientation) {
        (Some(f), _) => Some(f),
        (None, Orientation::Features) => {
            computed = feature_field(target, cancel)?;
            Some(&computed)
        }
        (None, _) => None,
    };
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
    // Mesh pyramid: the shared MeshMatch hierarchy (shortest-edge-first midpoint collapses, about
    // half the vertices per level), every second level, so each level keeps about a quarter.
    let hier = Hierarchy::build(
        &positions,
        &faces,
        HierarchyOptions {
            min_vertices: 16,
            max_levels: Some(2 * (nlev - 1) + 1),
        },
    )?;
    cancel.check()?;
    let mut levels = vec![Level::new(positions, faces, normals, fixed)];
    let mut rng = stage_rng(params.seed, 1);
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
    drop(hier);
    let (imgs, alphas) = match alpha {
        None => (image_pyramid(Img::from_rgb(exemplar), nlev), None),
        Some(a) => {
            let (img, a) = transparent_filled(exemplar, a)?;
            (image_pyramid(img, nlev), Some(image_pyramid(a, nlev)))
        }
    };
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
        &|k, dirs, h, size, parent| {
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
        },
        sink,
        cancel,
    )?;
    timings.orientation = out.orientation_secs;
    timings.neighbourhoods = out.neighbourhood_secs;
    timings.search = out.search_secs;
    drop(imgs);
    let LevelsOut {
        colors: col,
        sources,
        dirs,
        level_energy,
        exemplar: ex0,
        ..
    } = out;

    // ---- deliver
    let level_vertices: Vec<usize> = levels.iter().map(|l| l.num_vertices()).collect();
    let fine = levels.into_iter().next().expect("finest level");
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
    let file_colors = target.to_file_order(&col[..nv], [0.5; 3]);
    timings.total = total.secs();
    Ok(SynthResult {
        mesh,
        file_colors,
        orientation: dirs,
        source,
        spacing: h0,
        mesh_d,
        level_vertices,
        level_energy,
        displacement,
        timings,
        orientation_used: params.orientation,
        anisotropy,
    })
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

/// Coherence candidates for vertex `v` (Ashikhmin 2001 on a surface): its current source, each
/// neighbour q's source shifted by `p - q` expressed in q's texture frame, and the parent's source
/// (doubled, shifted by `p - parent` in p's frame).
#[allow(clippy::too_many_arguments)]
fn collect_candidates(
    cands: &mut Vec<u32>,
    v: usize,
    lev: &Level,
    dirs: &[[f32; 3]],
    src: &[u32],
    ex: &ExemplarLevel,
    h: f32,
    parent: Option<(&Level, &[u32], &ExemplarLevel)>,
) {
    let pv = Vec3::from(lev.positions[v]);
    if src[v] != u32::MAX {
        cands.push(src[v]);
    }
    for &q in lev.adj.row(v) {
        let q = q as usize;
        if src[q] == u32::MAX {
            continue;
        }
        let nq = Vec3::from(lev.normals[q]);
        let sq = Vec3::from(dirs[q]);
        let tq = nq.cross(sq);
        let d = pv - Vec3::from(lev.positions[q]);
        let (x, y) = ex.pixel(src[q]);
        let nx = x as f32 + d.dot(sq) / h;
        let ny = y as f32 - d.dot(tq) / h;
        cands.push(ex.cand_at(nx.round() as i64, ny.round() as i64));
    }
    if let Some((plev, psrc, pex)) = parent {
        let a = lev.parent[v] as usize;
        if psrc[a] != u32::MAX {
            let nv = Vec3::from(lev.normals[v]);
            let sv = Vec3::from(dirs[v]);
            let tv = nv.cross(sv);
            let d = pv - Vec3::from(plev.positions[a]);
            let (x, y) = pex.pixel(psrc[a]);
            let px = x as f32 + d.dot(sv) / (2.0 * h);
            let py = y as f32 - d.dot(tv) / (2.0 * h);
            let fx = 2.0 * px + 0.5;
            let fy = 2.0 * py + 0.5;
            cands.push(ex.cand_at(fx.round() as i64, fy.round() as i64));
        }
    }
}

/// What [`synthesize_levels`] gives back: the finest level's colours, exemplar candidates
/// (`u32::MAX` for fixed samples), texture directions, and the numbers.
pub(crate) struct LevelsOut {
    pub colors: Vec<[f32; 3]>,
    pub sources: Vec<u32>,
    pub dirs: Vec<[f32; 3]>,
    pub level_energy: Vec<f64>,
    pub exemplar: ExemplarLevel,
    pub orientation_secs: f64,
    pub neighbourhood_secs: f64,
    pub search_secs: f64,
}

/// Resampling stencils of level `k` in its samples' frames `dirs` at spacing `h` and template
/// `size`: on the level itself, or (`parent = true`) on level `k + 1`.
pub(crate) type StencilBuilder<'a> =
    dyn Fn(usize, &[[f32; 3]], f32, usize, bool) -> Stencils + Sync + 'a;

/// The coarse-to-fine synthesis on a pyramid of sample levels (mesh vertices, or texels of an
/// atlas): orientation (an explicit field `carried` on the finest level, or the params'), then
/// per level and pass the best-match search over the neighbourhoods `stencils` builds. Partial
/// results are colours per finest-level sample.
#[allow(clippy::too_many_arguments)]
pub(crate) fn synthesize_levels(
    levels: &[Level],
    carried: Option<&[[f32; 3]]>,
    imgs: &[Img],
    alphas: Option<&[Img]>,
    h0: f32,
    params: &SynthParams,
    total: &Stopwatch,
    stencils: &StencilBuilder,
    sink: &dyn Fn(Event),
    cancel: &CancelToken,
) -> Result<LevelsOut> {
    let nlev = levels.len();
    let passes = params.passes.max(1);
    // ---- orientation, coarse to fine
    let clock = Stopwatch::start();
    let mut dirs: Vec<Vec<[f32; 3]>> = vec![Vec::new(); nlev];
    // an explicit field: fine to coarse (children averaged), projected on each level
    let mut field_dirs: Vec<Vec<[f32; 3]>> = Vec::new();
    if let Some(carried) = carried
        && !matches!(params.orientation, Orientation::Random | Orientation::Up)
    {
        field_dirs.push(orient::project_all(&levels[0], carried));
        for k in 1..nlev {
            let d = orient::from_children(&levels[k], &levels[k - 1].parent, &field_dirs[k - 1]);
            field_dirs.push(d);
        }
    }
    let mut rng = stage_rng(params.seed, 2);
    for k in (0..nlev).rev() {
        let lev = &levels[k];
        dirs[k] = match params.orientation {
            Orientation::Random => orient::random_dirs(lev, &mut rng),
            Orientation::Up => orient::up_dirs(lev),
            _ if !field_dirs.is_empty() => std::mem::take(&mut field_dirs[k]),
            Orientation::Features | Orientation::Auto => {
                unreachable!("the feature field is computed and auto resolved above")
            }
            Orientation::Relax2 | Orientation::Relax4 => {
                let nsym = if params.orientation == Orientation::Relax2 {
                    2
                } else {
                    4
                };
                if k + 1 == nlev {
                    let mut d = orient::random_dirs(lev, &mut rng);
                    orient::relax(lev, &mut d, None, nsym, params.relax_sweeps, &mut rng);
                    d
                } else {
                    let pd = &dirs[k + 1];
                    let mut d = orient::from_parent(lev, pd);
                    let sweeps = (params.relax_sweeps / 4).max(2);
                    orient::relax(lev, &mut d, Some((&lev.parent, pd)), nsym, sweeps, &mut rng);
                    d
                }
            }
        };
        cancel.check()?;
    }
    let orientation_secs = clock.secs();
    sink(Event::StageTime("orientation", orientation_secs));

    // ancestor of every finest vertex on each level (for partial results on the finest mesh)
    let mut up: Vec<Vec<u32>> = vec![(0..levels[0].num_vertices() as u32).collect()];
    for k in 1..nlev {
        let prev = &up[k - 1];
        let map = &levels[k - 1].parent;
        up.push(prev.iter().map(|&v| map[v as usize]).collect());
    }

    // ---- synthesis, coarse to fine
    let work: f64 = levels.iter().map(|l| l.num_vertices() as f64).sum::<f64>() * passes as f64;
    let mut done = 0.0f64;
    let mut colors: Vec<Vec<[f32; 3]>> = vec![Vec::new(); nlev];
    let mut srcs: Vec<Vec<u32>> = vec![Vec::new(); nlev];
    let mut exemplars: Vec<Option<ExemplarLevel>> = vec![None; nlev];
    let mut level_energy = vec![0.0f64; nlev];
    let mut rng = stage_rng(params.seed, 3);
    let mut search_secs = 0.0;
    let mut neigh_secs = 0.0;
    for k in (0..nlev).rev() {
        let (size, psize) = sizes(k, nlev);
        let clock = Stopwatch::start();
        let lev = &levels[k];
        let n = lev.num_vertices();
        let h = h0 * (1u32 << k) as f32;
        let has_parent = psize > 0;
        let mut ex = ExemplarLevel::new(&imgs[k], has_parent.then(|| &imgs[k + 1]), size, psize);
        if let Some(a) = alphas {
            ex.restrict_to_opaque(&a[k]);
        }
        let cur_st = stencils(k, &dirs[k], h, size, false);
        cancel.check()?;
        let par_st: Option<Stencils> =
            has_parent.then(|| stencils(k, &dirs[k], 2.0 * h, psize, true));
        neigh_secs += clock.secs();
        let clock = Stopwatch::start();
        // random initialisation from this level's exemplar (equalises histograms, §3.1)
        let mut src = vec![u32::MAX; n];
        let mut col = vec![[0.0f32; 3]; n];
        for v in 0..n {
            if let Some(c) = lev.fixed[v] {
                col[v] = c;
            } else {
                let c = ex.random_candidate(&mut rng);
                src[v] = c;
                col[v] = ex.color(c);
            }
        }
        let run_passes: Vec<(bool, bool)> = if has_parent {
            (0..passes).map(|p| (p > 0, true)).collect()
        } else if size > 1 {
            (0..passes).map(|_| (true, false)).collect()
        } else {
            Vec::new() // coarsest {1x1,1}: the random copy is the result
        };
        let pcol: &[[f32; 3]] = if has_parent { &colors[k + 1] } else { &[] };
        let psrc: &[u32] = if has_parent { &srcs[k + 1] } else { &[] };
        let pex = if has_parent {
            exemplars[k + 1].as_ref()
        } else {
            None
        };
        let pdefault = pex.map_or(ex.mean, |e| e.mean);
        let mut qc = vec![0.0f32; ex.dim_cur()];
        let mut qp = vec![0.0f32; ex.dim_par()];
        let mut cands: Vec<u32> = Vec::with_capacity(64);
        let mut order: Vec<u32> = (0..n as u32)
            .filter(|&v| lev.fixed[v as usize].is_none())
            .collect();
        for (pass, &(use_cur, use_par)) in run_passes.iter().enumerate() {
            order.shuffle(&mut rng);
            let mut energy = 0.0f64;
            for (i, &v) in order.iter().enumerate() {
                if i % 256 == 0 {
                    cancel.check()?;
                }
                let v = v as usize;
                if use_cur {
                    cur_st.gather(v, &col, ex.mean, &mut qc);
                }
                if let (true, Some(ps)) = (use_par, &par_st) {
                    ps.gather(v, pcol, pdefault, &mut qp);
                }
                let q_cur = use_cur.then_some(&qc[..]);
                let q_par = use_par.then_some(&qp[..]);
                let (best, d) = match params.search {
                    Search::Exhaustive => search::exhaustive(&ex, q_cur, q_par),
                    Search::Fast => {
                        cands.clear();
                        collect_candidates(
                            &mut cands,
                            v,
                            lev,
                            &dirs[k],
                            &src,
                            &ex,
                            h,
                            has_parent.then(|| (&levels[k + 1], psrc, pex.expect("parent"))),
                        );
                        for _ in 0..params.random_candidates {
                            cands.push(ex.random_candidate(&mut rng));
                        }
                        search::fast(&ex, &mut cands, q_cur, q_par, &mut rng)
                    }
                };
                if best != u32::MAX {
                    src[v] = best;
                    col[v] = ex.color(best);
                    energy += d as f64;
                }
            }
            let dim =
                (if use_cur { ex.dim_cur() } else { 0 }) + (if use_par { ex.dim_par() } else { 0 });
            level_energy[k] = energy / (order.len().max(1) * dim.max(1)) as f64;
            done += n as f64;
            let progress = Progress {
                stage: "synth",
                level: k,
                levels: nlev,
                iteration: pass + 1,
                energy: level_energy[k],
                elapsed: total.secs(),
                fraction: (done / work) as f32,
            };
            let signal: Arc<[[f32; 3]]> = up[k].iter().map(|&a| col[a as usize]).collect();
            sink(Event::Partial { progress, signal });
        }
        done += n as f64 * (passes - run_passes.len()) as f64;
        colors[k] = col;
        srcs[k] = src;
        exemplars[k] = Some(ex);
        search_secs += clock.secs();
        // free what the next (finer) level no longer needs
        if k + 2 < nlev {
            colors[k + 2] = Vec::new();
            srcs[k + 2] = Vec::new();
            exemplars[k + 2] = None;
        }
    }
    sink(Event::StageTime("neighbourhoods", neigh_secs));
    sink(Event::StageTime("search", search_secs));
    Ok(LevelsOut {
        colors: std::mem::take(&mut colors[0]),
        sources: std::mem::take(&mut srcs[0]),
        dirs: std::mem::take(&mut dirs[0]),
        level_energy,
        exemplar: exemplars[0].take().expect("finest level synthesized"),
        orientation_secs,
        neighbourhood_secs: neigh_secs,
        search_secs,
    })
}
