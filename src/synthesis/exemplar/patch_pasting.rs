//! Exemplar synthesis by pasting large patches of the image onto the surface: lapped textures
//! (Praun, Finkelstein & Hoppe 2000) with each patch placed by matching its overlap with what is
//! already there (Efros & Freeman 2001's overlap matching, carried onto the surface).
//!
//! Wei-Levoy's per-sample search keeps only what a small neighbourhood sees: an image whose
//! features are larger than the neighbourhood (plumes, bark strips, brick courses) comes out as
//! a scatter of small blotches, and averaging near-ties flattens its contrast. Pasting whole
//! discs of the image keeps everything inside a disc exactly as the image has it (its contrast,
//! colours, large structures and every pixel's sharpness), so only the discs' rims are made up.
//!
//! The steps ([`paste_patches`]):
//! 1. **Layout**: the target's UVs, or a generated atlas, as texture-space synthesis uses; every
//!    texel of the output texture is a surface point.
//! 2. **Orientation** of each patch: random for isotropic images, else the field the image's
//!    anisotropy asks for (a smooth direction field, projected up, or the salient curves'),
//!    read at the patch's seed, with the field's symmetry. A field drawn towards up stands the
//!    image upright (its up along the field's branch nearest up, or upside down for a line
//!    field), never on its side, where the surface is steep enough for up to have a direction:
//!    brick courses stay level on a standing figure, as on a wall.
//! 3. **Seeds**: texels in a random order; the next one not yet covered starts a patch.
//! 4. **Flatten**: the discrete exponential map ([`crate::geometry::exp_map`]) of the geodesic
//!    disc around the seed gives every vertex within reach a 2D coordinate in surface units;
//!    faces whose flattened edges stretch by more than 2x (where the disc wraps around a thin
//!    part and meets itself) or flip are left out of the patch, for another patch to cover.
//!    Where the flattening distorts more than a tenth of the disc's surface (edges stretched or
//!    shrunk by more than a quarter: the disc covers a part rounder than itself, a hand, a
//!    foot, a head), the disc is shrunk a quarter at a time until it fits, down to a quarter of
//!    the radius: the image's pixels keep their size and shape on a smaller patch, where a
//!    large one would show them stretched and torn. A disc wrapped round a limb (a cylinder,
//!    flattened without distortion) keeps its size: it meets itself along one line, a single
//!    seam, and smaller patches would only add seams.
//! 5. **Splotch**: the patch's shape is a disc whose rim wobbles (a few random harmonics, as
//!    lapped textures' hand-drawn splotch), with a feathered edge.
//! 6. **Place**: among random image positions (and rotations, when the field allows), the one
//!    whose image colours best match the texels already covered under the new patch's
//!    footprint (sum of squared differences weighted by both alphas, over the image's colour
//!    variance), plus a penalty for parts of the image that more texels already show than the
//!    average (counted texel by texel, so every part of the image reaches the surface), one for
//!    colours the texture already shows more of than the image has
//!    ([`super::colour_balance`]: a non-stationary image's extremes, a gradient's ends, which
//!    overlap matching alone drifts away from, are drawn in until the texture's colour
//!    distribution is the image's), and one for the transparent share of the disc in an image
//!    with holes (a disc that is mostly hole leaves a crescent, and a surface pieced from
//!    crescents is all seams), refined by a pattern search. Centres stay half a radius inside
//!    the image, nearer a side whose band holds colours the rest lacks (a sky's deepest blue
//!    along its top: [`super::border_reach`]).
//! 7. **Paste**: each texel of the patch's faces reads the full-resolution image at its
//!    coordinate (bilinear). Where something is already there, the patch shows only inside a
//!    closed seam around its seed that runs where old and new agree best (Efros & Freeman's
//!    boundary cut, [`super::seam`]), so patches meet at a sharp seam instead of a blended band,
//!    feathered only where the seam has to cross a mismatch; where nothing is, it is
//!    composited with the splotch's feathered alpha. Where old and new differ by more than the
//!    image's own steps in their low frequencies (a gradient, a sky), that offset is carried
//!    into the patch's rim ([`super::membrane`]), so the seam shows no step.
//!    Transparent image pixels give alpha 0, so they never reach the surface.
//!
//! Texels no patch covers (faces every flattening left out) are filled from their neighbours
//! with the gutters.

use glam::{Vec2, Vec3};
use rand::Rng;
use rand::seq::SliceRandom;
use rayon::prelude::*;

use super::border_reach::Side;
use super::colour_balance::{BANDWIDTH2, ColourBalance};
use super::membrane::Membrane;
use super::pyramid::{Img, stage_rng};
use super::seam::SeamCosts;
use super::texture_space::{
    Surface, TextureInput, TextureParams, check_texture_memory, set_texture, texture_layout,
};
use super::{Orientation, anisotropy, feature_field, transparent_filled};
use crate::error::{Error, Result};
use crate::mesh::{Csr, TriMesh};
use crate::work::{CancelToken, Event, Progress, Stopwatch};

/// Parameters of patch pasting beyond [`TextureParams`].
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
#[serde(default)]
pub struct PatchParams {
    /// A patch's radius as a fraction of the image's shorter side: large enough to hold the
    /// image's large structures whole, small enough to leave room to choose where to cut.
    pub radius: f32,
    /// Width of the feathered rim, as a fraction of the radius.
    pub feather: f32,
    /// How far the splotch's rim wobbles in and out, as a fraction of the radius.
    pub wobble: f32,
    /// Image positions (and rotations) tried per patch before refining the best.
    pub candidates: usize,
    /// How much a placement's score grows with the use of its part of the image (texels showing
    /// it, relative to the mean over the image), against its mismatch in units of the image's
    /// colour variance, so that all of the image reaches the surface in its own proportions.
    pub usage_weight: f32,
    /// How much a placement's score grows with how much the texture already shows the colours
    /// its part of the image holds, relative to the image's share of them (below 1 where the
    /// texture lacks them): parts of the image whose colours nothing else has (a gradient's
    /// ends, a sky's deepest blue) are drawn in until the texture's colours are the image's.
    pub colour_weight: f32,
    /// How much a placement's score grows with the transparent share of its disc (an image with
    /// holes): patches carry the image's opaque parts across their whole disc instead of
    /// leaving crescents around a hole for other patches to fill.
    pub transparency_weight: f32,
    /// The share of a disc's surface its flattening may distort (edges stretched or shrunk by
    /// more than a quarter, where the disc covers a part rounder than itself: a hand, a foot, a
    /// head) before the patch is made smaller, a quarter at a time, down to
    /// [`PatchParams::smallest`]. 1 never shrinks.
    pub distortion_limit: f32,
    /// The smallest patch radius, as a fraction of [`PatchParams::radius`].
    pub smallest: f32,
    /// Carry the low-frequency colour step across each seam into the patch's rim
    /// ([`super::membrane`]), so that patches of an image whose colour changes across it (a
    /// gradient, a sky) meet without a visible step.
    pub membrane: bool,
    /// Let patch centres come nearer a side of the image whose band holds colours the rest of
    /// the image lacks (a sky's deepest blue along its top, [`super::border_reach`]); without
    /// it every centre stays half a radius inside the image.
    pub border_reach: bool,
}

impl Default for PatchParams {
    fn default() -> Self {
        PatchParams {
            radius: 0.3,
            feather: 0.08,
            wobble: 0.18,
            candidates: 192,
            usage_weight: 0.5,
            colour_weight: 1.0,
            transparency_weight: 4.0,
            distortion_limit: 0.1,
            smallest: 0.25,
            membrane: true,
            border_reach: true,
        }
    }
}

/// What [`paste_patches`] made.
#[derive(Clone, Debug)]
pub struct PatchOutput {
    /// The target with UVs (its own or the generated atlas's) and the texture; no vertex colours.
    pub mesh: TriMesh,
    /// Charts and coverage of a generated atlas.
    pub atlas: Option<crate::geometry::UvAtlas>,
    /// Why the atlas was generated.
    pub atlas_reason: Option<String>,
    /// Patches pasted.
    pub patches: usize,
    /// Patch radius in surface units.
    pub radius: f32,
    /// Patches made smaller than `radius` to fit a part rounder than a disc.
    pub shrunk: usize,
    /// Share of the layout's texels no patch reached (filled from their neighbours).
    pub uncovered: f64,
    /// The orientation used (`Auto` resolved).
    pub orientation_used: Orientation,
    /// The image's measured anisotropy, when `Auto` chose the orientation.
    pub anisotropy: Option<anisotropy::Anisotropy>,
    /// Wall-clock seconds of the whole call.
    pub seconds: f64,
}

/// The factor a distorted patch's radius shrinks by per try: a quarter at a time, so that a
/// disc loses no more than it must (halving gave up whole structures for more seams).
const SHRINK: f32 = 0.75;

/// The stretch beyond which a kept face counts as distorted: an edge flattened more than a
/// quarter longer or shorter than it is.
const DISTORTED: f32 = 1.25;

/// Overlap texels a placement is scored on, at most.
const SCORE_SAMPLES: usize = 384;

/// Most patches: a scale this small against the surface is a tiling job, not patch pasting
/// (about a minute of placing on two cores; the shared images at their default scale take
/// 100-400).
const MAX_PATCHES: f64 = 20_000.0;

/// Synthesize the exemplar into the target's texture by pasting patches (see the module doc).
/// Uses `params.synth`'s scale (image width in surface units, default a quarter of the
/// bounding-box diagonal), orientation and seed, and `params.texture_size`; emits progress and
/// honours `cancel`.
pub fn paste_patches(
    input: &TextureInput,
    params: &TextureParams,
    pp: &PatchParams,
    sink: &dyn Fn(Event),
    cancel: &CancelToken,
) -> Result<PatchOutput> {
    let total = Stopwatch::start();
    check_inputs(input, params, pp)?;
    let (pixel, radius) = patch_size(input, params, pp)?;

    // 1. layout
    let (mut mesh, atlas, atlas_reason) = texture_layout(input.target, params, cancel)?;
    let uvs = mesh.uvs.clone().expect("the layout sets UVs");
    let surface = Surface::new(&mesh, &uvs);
    let size = params.texture_size as usize;
    let texels = crate::geometry::uv_texels(&uvs, surface.faces.len(), size, size);
    let face_texels = face_texel_lists(&texels, surface.faces.len());
    cancel.check()?;

    // 2. orientation
    let image = match input.alpha {
        None => Img::from_rgb(input.exemplar),
        Some(a) => transparent_filled(input.exemplar, a)?.0,
    };
    // fades over the image's border and its holes alike
    let border_fade = (pp.feather * radius / pixel).max(1.0);
    let opacity: Option<Vec<f32>> = input.alpha.map(|a| hole_fade(a, border_fade));
    let turn = patch_orientation(input, &surface, params.synth.orientation, radius, cancel)?;

    // 3.-7. seeds, flatten, splotch, place, paste
    let variance = colour_variance(&image, opacity.as_deref());
    let ctx = Context {
        surface: &surface,
        adjacency: crate::mesh::vertex_adjacency(surface.positions.len(), &surface.faces),
        vertex_faces: crate::mesh::vertex_faces(surface.positions.len(), &surface.faces),
        texels: &texels,
        face_texels: &face_texels,
        image: &image,
        opacity: opacity.as_deref(),
        pixel,
        radius,
        edge: longest_edge(&surface),
        face_area: crate::geometry::face_areas(surface.positions, &surface.faces),
        border_fade,
        variance,
        pp,
        balance: ColourBalance::new(&image, opacity.as_deref(), USAGE, variance),
        image_step: super::membrane::image_step(&image, opacity.as_deref()),
        reach: if pp.border_reach {
            let margin = CENTRE_MARGIN * radius / pixel;
            let op = opacity.as_deref();
            super::border_reach::side_factors(&image, op, margin, variance, BANDWIDTH2)
        } else {
            [1.0; 4]
        },
    };
    let (canvas, patches, shrunk) =
        ctx.paste_all(&turn, params.synth.seed, &total, sink, cancel)?;

    let (pixels, covered, uncovered) = canvas.texture(&texels);
    set_texture(&mut mesh, size, pixels, covered);
    Ok(PatchOutput {
        mesh,
        atlas,
        atlas_reason,
        patches,
        radius,
        shrunk,
        uncovered,
        orientation_used: turn.orientation,
        anisotropy: turn.anisotropy,
        seconds: total.secs(),
    })
}

/// An image pixel's size and a patch's radius on the surface (`params.synth`'s scale is the
/// image's width in surface units, default a quarter of the bounding-box diagonal); refuses a
/// scale at which the surface would need too many patches, or a texture that does not fit in
/// memory.
fn patch_size(
    input: &TextureInput,
    params: &TextureParams,
    pp: &PatchParams,
) -> Result<(f32, f32)> {
    let target = input.target;
    let scale = super::surface_scale(target, params.synth.scale)?;
    let (ew, eh) = input.exemplar.dimensions();
    let pixel = scale / ew as f32;
    let radius = pp.radius * ew.min(eh) as f32 * pixel;
    let area = target.area().max(1e-30);
    let expected = area / (std::f64::consts::PI * (radius as f64 * 0.7).powi(2));
    if expected > MAX_PATCHES {
        return Err(Error::InvalidInput(format!(
            "at scale {scale} the image is too small against the surface for patches (about \
             {expected:.0} of them): use a larger scale or --method neighbourhood"
        )));
    }
    check_texture_memory(params.texture_size)?;
    Ok((pixel, radius))
}

/// How patches turn: the orientation used (`auto` reads the image's anisotropy), the field
/// they follow, and its symmetry.
struct Turn {
    orientation: Orientation,
    anisotropy: Option<anisotropy::Anisotropy>,
    field: Option<Vec<[f32; 3]>>,
    /// 0: patches turn freely (no field); else the field's symmetry.
    symmetry: usize,
    /// Whether the field was drawn towards "up" (`up`, `relax2`, `relax4`): each patch then
    /// stands the image upright along the field's branch nearest up (or upside down, for a
    /// 2- or 4-fold field; never on its side), where the surface is steep enough for up to
    /// have a direction, as a photograph of a wall or bark is seen.
    upright: bool,
}

/// Step 2: the orientation patches follow.
fn patch_orientation(
    input: &TextureInput,
    surface: &Surface,
    asked: Orientation,
    radius: f32,
    cancel: &CancelToken,
) -> Result<Turn> {
    let ew = input.exemplar.width();
    let anis = (asked == Orientation::Auto).then(|| {
        let probe = super::shrink_exemplar(input.exemplar.clone(), ew.min(256));
        let pa = input
            .alpha
            .map(|a| super::resize_alpha(a.clone(), probe.width(), probe.height()));
        anisotropy::exemplar_anisotropy(&probe, pa.as_ref())
    });
    let orientation = anis.map_or(asked, anisotropy::choose_orientation);
    let field = orientation_field(input, surface, orientation, radius, cancel)?;
    let symmetry = match (&field, orientation) {
        (None, _) => 0,
        (_, Orientation::Relax4) => 4,
        (_, Orientation::Relax2 | Orientation::Features) => 2,
        _ => 1,
    };
    let upright = field.is_some()
        && input.field.is_none()
        && matches!(
            orientation,
            Orientation::Up | Orientation::Relax2 | Orientation::Relax4
        );
    cancel.check()?;
    Ok(Turn {
        orientation,
        anisotropy: anis,
        field,
        symmetry,
        upright,
    })
}

/// Refuse what cannot be pasted, in one line each.
fn check_inputs(input: &TextureInput, params: &TextureParams, pp: &PatchParams) -> Result<()> {
    let (ew, eh) = input.exemplar.dimensions();
    if ew.min(eh) < 8 {
        return Err(Error::InvalidInput(format!(
            "the exemplar is {ew}x{eh} pixels: patches need at least 8 a side"
        )));
    }
    if !(16..=8192).contains(&params.texture_size) {
        return Err(Error::InvalidInput(format!(
            "texture size must be between 16 and 8192, got {}",
            params.texture_size
        )));
    }
    if input.target.faces.is_empty() {
        return Err(Error::InvalidMesh("the target has no faces".into()));
    }
    if let Some(f) = input.field
        && f.len() != input.target.num_vertices()
    {
        return Err(Error::InvalidInput(format!(
            "orientation field has {} entries, the target has {} vertices",
            f.len(),
            input.target.num_vertices()
        )));
    }
    let ok = |x: f32, lo: f32, hi: f32| x.is_finite() && x >= lo && x <= hi;
    if !(ok(pp.radius, 0.05, 0.5)
        && ok(pp.feather, 0.01, 0.5)
        && ok(pp.wobble, 0.0, 0.5)
        && ok(pp.usage_weight, 0.0, 10.0)
        && ok(pp.colour_weight, 0.0, 10.0)
        && ok(pp.transparency_weight, 0.0, 100.0)
        && ok(pp.distortion_limit, 0.0, 1.0)
        && ok(pp.smallest, 0.05, 1.0))
        || pp.candidates == 0
    {
        return Err(Error::InvalidInput(format!(
            "patch parameters out of range: radius {} (0.05-0.5), feather {} (0.01-0.5), wobble \
             {} (0-0.5), usage weight {} (0-10), colour weight {} (0-10), transparency weight {} \
             (0-100), distortion limit {} (0-1), smallest {} (0.05-1), candidates {} (1 or more)",
            pp.radius,
            pp.feather,
            pp.wobble,
            pp.usage_weight,
            pp.colour_weight,
            pp.transparency_weight,
            pp.distortion_limit,
            pp.smallest,
            pp.candidates
        )));
    }
    Ok(())
}

/// The output texels of each face (CSR, face-major).
fn face_texel_lists(texels: &[Option<(u32, [f32; 3])>], faces: usize) -> Csr {
    let mut offsets = vec![0u32; faces + 1];
    for (f, _) in texels.iter().flatten() {
        offsets[*f as usize + 1] += 1;
    }
    for i in 0..faces {
        offsets[i + 1] += offsets[i];
    }
    let mut fill = offsets.clone();
    let mut indices = vec![0u32; offsets[faces] as usize];
    for (t, hit) in texels.iter().enumerate() {
        if let Some((f, _)) = hit {
            let slot = &mut fill[*f as usize];
            indices[*slot as usize] = t as u32;
            *slot += 1;
        }
    }
    Csr { offsets, indices }
}

/// The longest edge of the surface: a disc's flattening reaches this much beyond its rim, so the
/// faces the rim crosses have all three corners.
fn longest_edge(surface: &Surface) -> f32 {
    surface
        .faces
        .par_iter()
        .map(|f| {
            let p = f.map(|v| Vec3::from(surface.positions[v as usize]));
            p[0].distance(p[1])
                .max(p[1].distance(p[2]))
                .max(p[2].distance(p[0]))
        })
        .reduce(|| 0.0, f32::max)
}

/// The texture direction per vertex the orientation asks for, or `None` for random patches.
fn orientation_field(
    input: &TextureInput,
    surface: &Surface,
    orientation: Orientation,
    radius: f32,
    cancel: &CancelToken,
) -> Result<Option<Vec<[f32; 3]>>> {
    if let Some(f) = input.field
        && !matches!(orientation, Orientation::Random | Orientation::Up)
    {
        return Ok(Some(f.to_vec()));
    }
    Ok(match orientation {
        Orientation::Random | Orientation::Auto => None,
        Orientation::Up => Some(vec![UP.to_array(); surface.positions.len()]),
        Orientation::Features => Some(feature_field(input.target, cancel)?),
        Orientation::Relax2 | Orientation::Relax4 => {
            // the smoothest field nearest "up", smooth at the patches' size
            let guide = vec![UP.to_array(); surface.positions.len()];
            Some(crate::geometry::smooth_direction_field(
                surface.positions,
                &surface.faces,
                &surface.normals,
                &guide,
                radius as f64,
            )?)
        }
    })
}

/// The patch's +u direction at its seed: the field there (made tangent), or a random tangent.
fn seed_direction(
    surface: &Surface,
    field: Option<&[[f32; 3]]>,
    face: u32,
    bary: [f32; 3],
    n: Vec3,
    rng: &mut impl Rng,
) -> Vec3 {
    if let Some(f) = field {
        let corners = surface.faces[face as usize];
        let d = (0..3).fold(Vec3::ZERO, |acc, k| {
            acc + bary[k] * Vec3::from(f[corners[k] as usize])
        });
        let t = d - n * n.dot(d);
        if t.length_squared() > 1e-12 {
            return t.normalize();
        }
    }
    let a = n.any_orthonormal_vector();
    let b = n.cross(a);
    let angle = rng.random::<f32>() * std::f32::consts::TAU;
    a * angle.cos() + b * angle.sin()
}

/// Up, for fields drawn towards it (the guide of [`orientation_field`]).
const UP: Vec3 = Vec3::Y;

/// Least share of up in the tangent plane for a patch to stand upright: surfaces within 60
/// degrees of vertical. On flatter ones up has no direction to give.
const UPRIGHT_MIN: f32 = 0.5;

/// The `e1` that stands the image upright (its up, the patch's `n × e1`, along the branch of
/// the `symmetry`-fold field `dir` nearest up), or `None` where the surface at normal `n` is too
/// flat for up to have a direction.
fn upright(dir: Vec3, n: Vec3, symmetry: usize) -> Option<Vec3> {
    let up = UP - n * n.dot(UP);
    if up.length() < UPRIGHT_MIN || symmetry == 0 {
        return None;
    }
    let side = n.cross(dir);
    let best = (0..symmetry)
        .map(|k| {
            let a = k as f32 * std::f32::consts::TAU / symmetry as f32;
            dir * a.cos() + side * a.sin()
        })
        .max_by(|a, b| a.dot(up).total_cmp(&b.dot(up)))?;
    Some(best.cross(n).normalize_or_zero()).filter(|e| e.length_squared() > 0.5)
}

/// What every patch reads.
struct Context<'a> {
    surface: &'a Surface<'a>,
    adjacency: Csr,
    vertex_faces: Csr,
    texels: &'a [Option<(u32, [f32; 3])>],
    face_texels: &'a Csr,
    image: &'a Img,
    opacity: Option<&'a [f32]>,
    /// Surface units per image pixel.
    pixel: f32,
    /// Patch radius in surface units.
    radius: f32,
    /// The longest edge: how far beyond a disc's rim a flattening reaches.
    edge: f32,
    /// Each face's area.
    face_area: Vec<f64>,
    /// Image pixels over which a patch fades out at the image's border.
    border_fade: f32,
    /// The image's colour variance (summed over the channels, opaque pixels): half the mean
    /// squared difference of two random pixels, the scale of a placement's colour mismatch.
    variance: f32,
    /// The image's own steps ([`super::membrane::image_step`]): an offset across a seam no
    /// larger may be the image's.
    image_step: f32,
    pp: &'a PatchParams,
    /// The texture's colour make-up against the image's, by usage cell.
    balance: ColourBalance,
    /// Per side of the image (left, right, top, bottom), the factor on a patch centre's margin
    /// from it ([`super::border_reach`]).
    reach: [f32; 4],
}

/// The composited texture so far: premultiplied colour and alpha per texel, and how often each
/// part of the image has been pasted.
struct Canvas {
    color: Vec<[f32; 3]>,
    alpha: Vec<f32>,
    /// Texels with alpha at least 0.5.
    covered: usize,
    /// Texels now showing each cell of a `USAGE²` grid over the image: the texture's make-up
    /// by where in the image its texels come from.
    usage: Vec<f32>,
    /// The usage cell each texel shows ([`NO_CELL`]: none yet).
    source: Vec<u16>,
    /// Per usage cell, the sum of the colour offsets ([`super::membrane`]) its texels carry.
    shift: Vec<[f32; 3]>,
    /// The offset each texel carries (empty without the membrane).
    texel_shift: Vec<[f32; 3]>,
}

/// A texel no patch has shown yet.
const NO_CELL: u16 = u16::MAX;

/// Cells a side of the image's usage grid.
const USAGE: usize = 16;

impl Canvas {
    /// The texture: colours un-premultiplied, which texels patches cover (alpha at least one
    /// half; the rest are left to the gutter fill, since un-premultiplying a faint rim would
    /// show whatever it read at full strength, a hole's halo included), and the share of layout
    /// texels left to the fill.
    fn texture(&self, texels: &[Option<(u32, [f32; 3])>]) -> (Vec<[f32; 3]>, Vec<bool>, f64) {
        let layout_texels = texels.iter().filter(|t| t.is_some()).count().max(1);
        let mut uncovered = 0usize;
        let covered: Vec<bool> = self
            .alpha
            .iter()
            .zip(texels)
            .map(|(&a, t)| {
                if t.is_some() && a < 0.5 {
                    uncovered += 1;
                }
                a >= 0.5
            })
            .collect();
        let pixels: Vec<[f32; 3]> = self
            .color
            .par_iter()
            .zip(self.alpha.par_iter())
            .map(|(c, &a)| {
                if a >= 0.5 {
                    c.map(|x| (x / a).clamp(0.0, 1.0))
                } else {
                    [0.0; 3]
                }
            })
            .collect();
        (pixels, covered, uncovered as f64 / layout_texels as f64)
    }
}

/// Per-vertex flattening buffers, reused across patches.
struct Scratch {
    uv: Vec<[f32; 2]>,
    stamp: Vec<u32>,
    fstamp: Vec<u32>,
    now: u32,
}

/// A flattened patch: its faces, and each face's corners in surface units around the seed.
struct Patch {
    faces: Vec<u32>,
    corners: Vec<[Vec2; 3]>,
}

/// A splotch: the rim's radius at angle `a` is `1 + Σ amp_k cos(k a + phase_k)` (in radii).
struct Splotch {
    harmonics: [(f32, f32); 4],
    feather: f32,
    /// The patch's radius in surface units.
    radius: f32,
}

impl Splotch {
    fn random(rng: &mut impl Rng, pp: &PatchParams, radius: f32) -> Splotch {
        let mut harmonics = [(0.0, 0.0); 4];
        let mut total = 0.0;
        for (k, h) in harmonics.iter_mut().enumerate() {
            let amp = rng.random::<f32>() / (k + 1) as f32;
            total += amp;
            *h = (amp, rng.random::<f32>() * std::f32::consts::TAU);
        }
        let norm = if total > 0.0 { pp.wobble / total } else { 0.0 };
        for h in harmonics.iter_mut() {
            h.0 *= norm;
        }
        Splotch {
            harmonics,
            feather: pp.feather,
            radius,
        }
    }

    /// Alpha at `q` (in radii from the seed): 1 inside, 0 beyond the rim, a linear ramp of
    /// `feather` radii inside it.
    fn alpha(&self, q: Vec2) -> f32 {
        let rho = q.length();
        if rho < 1.0 - self.harmonics.iter().map(|h| h.0).sum::<f32>() - self.feather {
            return 1.0;
        }
        ((self.rim(q.y.atan2(q.x)) - rho) / self.feather).clamp(0.0, 1.0)
    }

    /// The rim's radius (in radii) at angle `a`.
    fn rim(&self, a: f32) -> f32 {
        1.0 + self
            .harmonics
            .iter()
            .enumerate()
            .map(|(k, &(amp, ph))| amp * ((k + 1) as f32 * a + ph).cos())
            .sum::<f32>()
    }
}

/// Where a patch reads the image: the image point at the seed and the rotation of the surface's
/// (u, v) into the image's (x right, y down).
#[derive(Clone, Copy, Debug)]
struct Placement {
    centre: Vec2,
    cos: f32,
    sin: f32,
}

impl Placement {
    fn new(centre: Vec2, angle: f32) -> Placement {
        Placement {
            centre,
            cos: angle.cos(),
            sin: angle.sin(),
        }
    }

    /// The image point (pixel units, centres at integers) of surface offset `q` (surface units
    /// divided by the pixel size).
    fn image_point(&self, q: Vec2) -> Vec2 {
        Vec2::new(
            self.centre.x + self.cos * q.x - self.sin * q.y,
            self.centre.y - (self.sin * q.x + self.cos * q.y),
        )
    }
}

impl Context<'_> {
    /// Steps 3-7 for every patch: seeds in a random order, each not yet covered starting a
    /// patch that is flattened, shaped, placed and pasted. Returns the canvas, the patches'
    /// count and how many of them were made smaller.
    fn paste_all(
        &self,
        turn: &Turn,
        seed: u64,
        total: &Stopwatch,
        sink: &dyn Fn(Event),
        cancel: &CancelToken,
    ) -> Result<(Canvas, usize, usize)> {
        let (s, texels) = (self.surface, self.texels);
        let mut canvas = Canvas {
            color: vec![[0.0; 3]; texels.len()],
            alpha: vec![0.0; texels.len()],
            covered: 0,
            usage: vec![0.0; USAGE * USAGE],
            source: vec![NO_CELL; texels.len()],
            shift: vec![[0.0; 3]; USAGE * USAGE],
            texel_shift: if self.pp.membrane {
                vec![[0.0; 3]; texels.len()]
            } else {
                Vec::new()
            },
        };
        let layout_texels = texels.iter().filter(|t| t.is_some()).count().max(1);
        let mut rng = stage_rng(seed, 11);
        let mut order: Vec<u32> = (0..texels.len() as u32)
            .filter(|&t| texels[t as usize].is_some())
            .collect();
        order.shuffle(&mut rng);
        let mut scratch = Scratch {
            uv: vec![[0.0; 2]; s.positions.len()],
            stamp: vec![0; s.positions.len()],
            fstamp: vec![0; s.faces.len()],
            now: 0,
        };
        let (mut patches, mut shrunk) = (0usize, 0usize);
        let mut last_report = Stopwatch::start();
        for &seed_texel in &order {
            if canvas.alpha[seed_texel as usize] >= 0.5 {
                continue;
            }
            cancel.check()?;
            let (face, bary) = texels[seed_texel as usize].expect("a layout texel");
            let n = s.normal(face, bary);
            let e1 = seed_direction(s, turn.field.as_deref(), face, bary, n, &mut rng);
            // upright, or upside down where the field is a line field: not on its side
            let (e1, symmetry) = match turn
                .upright
                .then(|| upright(e1, n, turn.symmetry))
                .flatten()
            {
                Some(up) => (up, turn.symmetry.min(2)),
                None => (e1, turn.symmetry),
            };
            let Some((patch, radius)) = self.flatten_fitting(face, bary, n, e1, &mut scratch)
            else {
                continue;
            };
            shrunk += usize::from(radius < self.radius);
            let splotch = Splotch::random(&mut rng, self.pp, radius);
            let place = self.place(&patch, &splotch, &canvas, symmetry, &mut rng);
            self.paste(&patch, &splotch, &place, &mut canvas);
            patches += 1;
            if last_report.secs() > 0.1 {
                last_report = Stopwatch::start();
                sink(Event::Progress(Progress {
                    stage: "patches",
                    level: 0,
                    levels: 1,
                    iteration: patches,
                    energy: 0.0,
                    elapsed: total.secs(),
                    fraction: canvas.covered as f32 / layout_texels as f32,
                }));
            }
        }
        Ok((canvas, patches, shrunk))
    }

    /// Step 4 at the largest radius whose disc the surface holds: the full radius, shrunk by
    /// [`SHRINK`] while the flattening distorts more than [`PatchParams::distortion_limit`] of
    /// the disc (down to [`PatchParams::smallest`]). The patch and its radius; `None` when even
    /// the smallest leaves out the seed's own face.
    fn flatten_fitting(
        &self,
        face: u32,
        bary: [f32; 3],
        n: Vec3,
        e1: Vec3,
        sc: &mut Scratch,
    ) -> Option<(Patch, f32)> {
        let smallest = self.radius * self.pp.smallest;
        let mut radius = self.radius;
        loop {
            let flat = self.flatten(face, bary, n, e1, radius, sc);
            let fits = flat
                .as_ref()
                .is_some_and(|(_, distortion)| *distortion <= self.pp.distortion_limit);
            if fits || SHRINK * radius < smallest * 0.999 {
                return flat.map(|(patch, _)| (patch, radius));
            }
            radius *= SHRINK;
        }
    }

    /// Step 4: the faces around the seed within a disc of `radius` flattened by the exponential
    /// map, without the faces the flattening stretches or flips, and the share of the disc's
    /// surface area it distorts (kept faces with an edge stretched or shrunk by more than
    /// [`DISTORTED`]); `None` when the seed's own face is left out.
    fn flatten(
        &self,
        face: u32,
        bary: [f32; 3],
        n: Vec3,
        e1: Vec3,
        radius: f32,
        sc: &mut Scratch,
    ) -> Option<(Patch, f32)> {
        let s = self.surface;
        let corners = s.faces[face as usize];
        let seed = crate::geometry::DiscSeed {
            face: corners,
            point: s.point(face, bary).to_array(),
            normal: n.to_array(),
            e1: e1.to_array(),
        };
        let rim = radius * (1.0 + self.pp.wobble);
        let reach = rim * 1.1 + self.edge;
        let em = crate::geometry::exp_map(s.positions, &s.normals, &self.adjacency, &seed, reach);
        sc.now = sc.now.wrapping_add(1);
        if sc.now == 0 {
            sc.stamp.fill(0);
            sc.fstamp.fill(0);
            sc.now = 1;
        }
        let now = sc.now;
        for (&v, uv) in em.vertices.iter().zip(&em.uv) {
            sc.stamp[v as usize] = now;
            sc.uv[v as usize] = *uv;
        }
        let mut patch = Patch {
            faces: Vec::new(),
            corners: Vec::new(),
        };
        let mut seed_kept = false;
        // the surface area of the disc's faces: kept, kept but distorted, and left out
        let (mut kept_area, mut distorted_area, mut torn_area) = (0.0f32, 0.0f32, 0.0f32);
        for &v in &em.vertices {
            for &f in self.vertex_faces.row(v as usize) {
                if sc.fstamp[f as usize] == now {
                    continue;
                }
                sc.fstamp[f as usize] = now;
                let c = s.faces[f as usize];
                if c.iter().any(|&w| sc.stamp[w as usize] != now) {
                    continue;
                }
                let q = c.map(|w| Vec2::from(sc.uv[w as usize]));
                // the face's flattening must meet the disc
                let near = (0..3).any(|k| q[k].length() <= rim)
                    || segment_meets_disc(q[0], q[1], rim)
                    || segment_meets_disc(q[1], q[2], rim)
                    || segment_meets_disc(q[2], q[0], rim)
                    || contains_origin(&q);
                if !near {
                    continue;
                }
                let p = c.map(|w| Vec3::from(s.positions[w as usize]));
                let area = self.face_area[f as usize] as f32;
                if !faithful(&p, &q) {
                    torn_area += area;
                    continue;
                }
                kept_area += area;
                if !within_stretch(&p, &q, DISTORTED) {
                    distorted_area += area;
                }
                seed_kept |= f == face;
                patch.faces.push(f);
                patch.corners.push(q);
            }
        }
        let distortion = distorted_area / (kept_area + torn_area).max(f32::MIN_POSITIVE);
        seed_kept.then_some((patch, distortion))
    }

    /// Alpha and image point of a texel at barycentric `b` of a patch face with flattened
    /// `corners`, under `splotch` and `place`.
    #[inline]
    fn sample(
        &self,
        corners: &[Vec2; 3],
        b: [f32; 3],
        splotch: &Splotch,
        place: &Placement,
    ) -> (f32, Vec2) {
        let q = corners[0] * b[0] + corners[1] * b[1] + corners[2] * b[2];
        self.sample_at(q, splotch, place)
    }

    /// [`Self::sample`] at the flattened point `q` (surface units from the seed).
    #[inline]
    fn sample_at(&self, q: Vec2, splotch: &Splotch, place: &Placement) -> (f32, Vec2) {
        let a = splotch.alpha(q / splotch.radius);
        if a <= 0.0 {
            return (0.0, Vec2::ZERO);
        }
        let p = place.image_point(q / self.pixel);
        // faded over the image's border, so a patch that runs off the image ends softly
        let (w, h) = (self.image.w as f32, self.image.h as f32);
        let border = (p.x + 0.5)
            .min(p.y + 0.5)
            .min(w - 0.5 - p.x)
            .min(h - 0.5 - p.y);
        if border <= 0.0 {
            return (0.0, p);
        }
        let a = a * (border / self.border_fade).min(1.0);
        let a = match self.opacity {
            None => a,
            Some(op) => a * bilinear_scalar(op, self.image.w, self.image.h, p),
        };
        (a, p)
    }

    /// Where the patch ends at `angle` (in `s`, the radius over the rim's) because its ray
    /// there leaves the image: half-way through the fade over the image's border; beyond 1
    /// where the ray stays on the image up to the rim.
    fn image_reach(&self, splotch: &Splotch, place: &Placement, angle: f32) -> f32 {
        let d = place.image_point(Vec2::new(angle.cos(), angle.sin())) - place.centre;
        let inset = 0.5 * self.border_fade - 0.5;
        let (lo, hi) = (
            Vec2::splat(inset),
            Vec2::new(self.image.w as f32, self.image.h as f32) - 1.0 - inset,
        );
        let along = |c: f32, d: f32, lo: f32, hi: f32| -> f32 {
            if d > 1e-9 {
                (hi - c) / d
            } else if d < -1e-9 {
                (lo - c) / d
            } else {
                f32::INFINITY
            }
        };
        let t = along(place.centre.x, d.x, lo.x, hi.x).min(along(place.centre.y, d.y, lo.y, hi.y));
        (t.max(0.0) * self.pixel / (splotch.rim(angle) * splotch.radius)).min(2.0)
    }

    /// The texels already covered under the patch (texel, patch face), a spread subset of at
    /// most [`SCORE_SAMPLES`].
    fn overlap(&self, patch: &Patch, canvas: &Canvas) -> Vec<(u32, usize)> {
        let mut overlap: Vec<(u32, usize)> = Vec::new();
        for (i, &f) in patch.faces.iter().enumerate() {
            for &t in self.face_texels.row(f as usize) {
                if canvas.alpha[t as usize] > 0.05 {
                    overlap.push((t, i));
                }
            }
        }
        if overlap.len() > SCORE_SAMPLES {
            let step = overlap.len() as f64 / SCORE_SAMPLES as f64;
            overlap = (0..SCORE_SAMPLES)
                .map(|k| overlap[(k as f64 * step) as usize])
                .collect();
        }
        overlap
    }

    /// Step 6: the placement whose image best matches the covered texels under the patch.
    fn place(
        &self,
        patch: &Patch,
        splotch: &Splotch,
        canvas: &Canvas,
        symmetry: usize,
        rng: &mut dyn rand::RngCore,
    ) -> Placement {
        let overlap = self.overlap(patch, canvas);
        let (w, h) = (self.image.w as f32, self.image.h as f32);
        // centres within half a radius of the border: a patch may run off the image (it fades
        // there and other patches cover the rest), so every part of the image can be a core;
        // nearer a side whose band holds colours the rest of the image lacks
        let margin = CENTRE_MARGIN * splotch.radius / self.pixel;
        let span = |len: f32, lo: f32, hi: f32| -> (f32, f32) {
            if len > 2.0 * margin {
                (margin * lo, len - margin * hi)
            } else {
                (0.5 * len, 0.5 * len)
            }
        };
        let r = |s: Side| self.reach[s as usize];
        let (xs, ys) = (
            span(w, r(Side::Left), r(Side::Right)),
            span(h, r(Side::Top), r(Side::Bottom)),
        );
        // without a field a patch turns freely; with one it keeps the field's direction up to
        // the field's symmetry
        let free_rotation = symmetry == 0;
        let draw = |rng: &mut dyn rand::RngCore| -> Placement {
            let angle = |rng: &mut dyn rand::RngCore| -> f32 {
                if free_rotation {
                    rng.random::<f32>() * std::f32::consts::TAU
                } else {
                    rng.random_range(0..symmetry) as f32 * std::f32::consts::TAU / symmetry as f32
                }
            };
            for _ in 0..16 {
                let c = Vec2::new(
                    xs.0 + rng.random::<f32>() * (xs.1 - xs.0),
                    ys.0 + rng.random::<f32>() * (ys.1 - ys.0),
                );
                let opaque = self
                    .opacity
                    .is_none_or(|op| bilinear_scalar(op, self.image.w, self.image.h, c) > 0.5);
                if opaque {
                    return Placement::new(c, angle(rng));
                }
            }
            Placement::new(Vec2::new(0.5 * (xs.0 + xs.1), 0.5 * (ys.0 + ys.1)), 0.0)
        };
        if overlap.is_empty() {
            return draw(rng);
        }
        let score = |pl: &Placement| -> f32 {
            let mut sum = 0.0f32;
            let mut wsum = 0.0f32;
            for &(t, i) in &overlap {
                let (_, b) = self.texels[t as usize].expect("a layout texel");
                let (a, p) = self.sample(&patch.corners[i], b, splotch, pl);
                if a <= 0.0 {
                    continue;
                }
                let old_a = canvas.alpha[t as usize];
                let old = canvas.color[t as usize].map(|x| x / old_a);
                let new = self.image.bilinear(p.x, p.y);
                let wgt = a * old_a;
                let d: f32 = (0..3).map(|k| (old[k] - new[k]).powi(2)).sum();
                sum += wgt * d;
                wsum += wgt;
            }
            if wsum > 1e-6 {
                sum / wsum
            } else {
                f32::INFINITY
            }
        };
        // a placement over parts of the image that more texels show than the rest scores worse,
        // so that all of the image reaches the surface in the image's own proportions (its
        // colour distribution): the mismatch, in units of the image's colour variance, plus the
        // weighted use relative to the mean. Added, not multiplied: a multiplied penalty vanishes
        // where the match is near perfect, which over flat parts of an image (pale background,
        // mortar) it always is, and those parts then win every time.
        let core_px = splotch.radius * (1.0 - self.pp.wobble - self.pp.feather) / self.pixel;
        let mean_usage = canvas.usage.iter().sum::<f32>() / canvas.usage.len() as f32;
        // and one for colours the texture already shows more of than the image has
        let mut colour_ratio = Vec::new();
        if self.pp.colour_weight > 0.0 {
            self.balance
                .ratios(&canvas.usage, &canvas.shift, &mut colour_ratio);
        }
        let score = |pl: &Placement| -> f32 {
            let s = score(pl) / (2.0 * self.variance)
                + self.pp.transparency_weight * self.transparent_share(pl.centre, splotch.radius);
            if mean_usage <= 0.0 {
                return s;
            }
            let u = grid_mean_under(
                &canvas.usage,
                self.image.w,
                self.image.h,
                pl.centre,
                core_px,
            );
            let c = if colour_ratio.is_empty() {
                0.0
            } else {
                let (w, h) = (self.image.w, self.image.h);
                self.pp.colour_weight * grid_mean_under(&colour_ratio, w, h, pl.centre, core_px)
            };
            s + self.pp.usage_weight * u / mean_usage + c
        };
        let mut best = draw(rng);
        let mut best_score = score(&best);
        for _ in 1..self.pp.candidates {
            let c = draw(rng);
            let sc = score(&c);
            if sc < best_score {
                best = c;
                best_score = sc;
            }
        }
        let bounds = (xs, ys);
        let astep = if free_rotation { 0.2 } else { 0.0 };
        pattern_search(
            best,
            best_score,
            (margin * 0.25).max(1.0),
            astep,
            bounds,
            score,
        )
    }

    /// The transparent share of a patch's disc centred at image point `c` (0 for an opaque
    /// image).
    fn transparent_share(&self, c: Vec2, radius: f32) -> f32 {
        self.opacity.map_or(0.0, |op| {
            transparent_share(op, self.image.w, self.image.h, c, radius / self.pixel)
        })
    }

    /// Step 7: composite the patch's texels over the canvas.
    fn paste(&self, patch: &Patch, splotch: &Splotch, place: &Placement, canvas: &mut Canvas) {
        let (w, h) = (self.image.w as f32, self.image.h as f32);
        let cell_of = |p: Vec2| -> u16 {
            let cx = ((p.x + 0.5) / w * USAGE as f32).clamp(0.0, USAGE as f32 - 1.0) as usize;
            let cy = ((p.y + 0.5) / h * USAGE as f32).clamp(0.0, USAGE as f32 - 1.0) as usize;
            (cy * USAGE + cx) as u16
        };
        // the patch's texels, and the seam's costs over them
        let mut texels: Vec<PatchTexel> = Vec::new();
        // the seam's grid: about a cell per two image pixels along the rim, at most the full
        // grid, so a small patch's seam is cut on a grid of its own size
        let rim_px = splotch.radius * (1.0 + self.pp.wobble) / self.pixel;
        let angles = ((std::f32::consts::PI * rim_px) as usize).clamp(8, SEAM_ANGLES);
        let rings = ((0.5 * (1.0 - SEAM_INNER) * rim_px) as usize).clamp(2, SEAM_RINGS);
        let mut costs = SeamCosts::new(angles, rings, SEAM_INNER);
        for (i, &f) in patch.faces.iter().enumerate() {
            let corners = &patch.corners[i];
            for &t in self.face_texels.row(f as usize) {
                let (_, b) = self.texels[t as usize].expect("a layout texel");
                let q = corners[0] * b[0] + corners[1] * b[1] + corners[2] * b[2];
                let (a, p) = self.sample_at(q, splotch, place);
                if a <= 0.0 {
                    continue;
                }
                let color = self.image.bilinear(p.x, p.y);
                let angle = q.y.atan2(q.x);
                let rim = splotch.rim(angle) * splotch.radius;
                let s = q.length() / rim;
                let old_a = canvas.alpha[t as usize];
                if old_a < 0.5 {
                    costs.force(angle, s);
                } else {
                    let old = canvas.color[t as usize].map(|x| x / old_a);
                    costs.add(angle, s, (0..3).map(|k| (old[k] - color[k]).powi(2)).sum());
                }
                // the seam's ramp: two image pixels wide, at most a tenth of the rim's radius
                let blend = (2.0 * self.pixel / rim).min(0.1);
                texels.push(PatchTexel {
                    texel: t,
                    cell: cell_of(p),
                    angle,
                    s,
                    blend,
                    alpha: a,
                    color,
                });
            }
        }
        let seam = costs.cut();
        // the low-frequency step where the new patch meets the old texture (at the seam, or
        // nearer where the patch runs off the image), carried into the patch's rim
        let edge = |angle: f32| seam.rho(angle).min(self.image_reach(splotch, place, angle));
        let offsets = self.pp.membrane.then(|| {
            let mut m = Membrane::new(angles);
            for pt in &texels {
                if Membrane::measures(pt.s, edge(pt.angle)) {
                    let t = pt.texel as usize;
                    let old_a = canvas.alpha[t];
                    let diff = (old_a >= 0.5)
                        .then(|| [0, 1, 2].map(|k| canvas.color[t][k] / old_a - pt.color[k]));
                    m.add(pt.angle, diff);
                }
            }
            m.solve(self.image_step)
        });
        // a seam cell's mismatch in units of the image's colour variance: at one variance (half
        // the mean difference of two random pixels) the seam is feathered fully
        let feather_unit = 1.0 / self.variance.max(1e-12);
        for pt in &texels {
            let t = pt.texel as usize;
            let old = canvas.alpha[t];
            // a texel nothing covers takes the patch as the splotch shows it; a covered one
            // only inside the seam
            let a = if old < 0.5 {
                pt.alpha
            } else {
                // sharp where the seam runs through agreement, feathered as wide as the
                // splotch's rim where it has to cross a mismatch (Kwatra et al. 2003)
                let bad = (seam.mismatch(pt.angle) * feather_unit).min(1.0);
                let blend = pt.blend + bad * (self.pp.feather - pt.blend).max(0.0);
                pt.alpha * seam.alpha(pt.angle, pt.s, blend)
            };
            if a <= 0.0 {
                continue;
            }
            let mut color = pt.color;
            if let Some(o) = &offsets {
                let d = o.at(pt.angle, pt.s, edge(pt.angle));
                for (c, d) in color.iter_mut().zip(d) {
                    *c = (*c + d).clamp(0.0, 1.0);
                }
            }
            for (dst, src) in canvas.color[t].iter_mut().zip(color) {
                *dst = a * src + (1.0 - a) * *dst;
            }
            let new = a + (1.0 - a) * old;
            if old < 0.5 && new >= 0.5 {
                canvas.covered += 1;
            }
            canvas.alpha[t] = new;
            // the texel now shows the patch's part of the image when the patch dominates it
            let was = canvas.source[t];
            if (a >= 0.5 || was == NO_CELL) && new >= 0.5 && was != pt.cell {
                if was != NO_CELL {
                    canvas.usage[was as usize] -= 1.0;
                }
                canvas.usage[pt.cell as usize] += 1.0;
                canvas.source[t] = pt.cell;
                // and the colour it shows, its cell's plus the offset it carries
                if !canvas.texel_shift.is_empty() {
                    let applied: [f32; 3] = std::array::from_fn(|k| color[k] - pt.color[k]);
                    if was != NO_CELL {
                        let old = canvas.texel_shift[t];
                        for (s, o) in canvas.shift[was as usize].iter_mut().zip(old) {
                            *s -= o;
                        }
                    }
                    for (s, a) in canvas.shift[pt.cell as usize].iter_mut().zip(applied) {
                        *s += a;
                    }
                    canvas.texel_shift[t] = applied;
                }
            }
        }
    }
}

/// A texel under a patch being pasted: where it lies in the patch (angle and radius relative
/// to the rim there), the seam ramp's width there, and what the patch gives it.
struct PatchTexel {
    texel: u32,
    /// The usage cell of the image point it reads.
    cell: u16,
    angle: f32,
    s: f32,
    blend: f32,
    alpha: f32,
    color: [f32; 3],
}

/// The seam's polar grid at most: angles around the seed, rings between [`SEAM_INNER`] and the
/// rim.
const SEAM_ANGLES: usize = 96;
const SEAM_RINGS: usize = 24;
/// The share of the rim's radius that always shows the new patch.
const SEAM_INNER: f32 = 0.25;

/// Opaque pixels as wide as a transparent region's antialiased fringe: they take the colour of
/// what was cut away (a halo) and are not pasted.
const FRINGE: f32 = 1.5;

/// How much of each image pixel a patch shows: nothing over a transparent pixel (alpha under
/// one half) or its fringe, then a ramp over `fade` pixels, as a patch fades at its rim and at
/// the image's border, so a hole's edge is feathered like the rest of the patch's border and
/// the texture under it shows through instead of meeting it at a hard edge.
fn hole_fade(alpha: &image::GrayImage, fade: f32) -> Vec<f32> {
    let (w, h) = (alpha.width() as usize, alpha.height() as usize);
    let hole: Vec<bool> = alpha.pixels().map(|p| p.0[0] < 128).collect();
    crate::geometry::distance_transform(&hole, w, h)
        .into_iter()
        .map(|d| ((d - FRINGE) / fade).clamp(0.0, 1.0))
        .collect()
}

/// A pattern search from `best` (score `best_score`): steps of `step` pixels along x and y and
/// of `astep` radians in angle, halved when none improves, within `bounds` (the centre's x and
/// y ranges).
fn pattern_search(
    mut best: Placement,
    mut best_score: f32,
    mut step: f32,
    mut astep: f32,
    bounds: ((f32, f32), (f32, f32)),
    score: impl Fn(&Placement) -> f32,
) -> Placement {
    let (xs, ys) = bounds;
    let mut angle = best.sin.atan2(best.cos);
    for _ in 0..12 {
        let mut improved = false;
        let mut tries: Vec<(Vec2, f32)> = vec![
            (best.centre + Vec2::new(step, 0.0), angle),
            (best.centre - Vec2::new(step, 0.0), angle),
            (best.centre + Vec2::new(0.0, step), angle),
            (best.centre - Vec2::new(0.0, step), angle),
        ];
        if astep > 0.0 {
            tries.push((best.centre, angle + astep));
            tries.push((best.centre, angle - astep));
        }
        for (c, a) in tries {
            if c.x < xs.0 || c.x > xs.1 || c.y < ys.0 || c.y > ys.1 {
                continue;
            }
            let pl = Placement::new(c, a);
            let sc = score(&pl);
            if sc < best_score {
                best = pl;
                best_score = sc;
                angle = a;
                improved = true;
            }
        }
        if !improved {
            step *= 0.5;
            astep *= 0.5;
            if step < 0.5 {
                break;
            }
        }
    }
    best
}

/// The colour variance of `image` summed over its channels, over the pixels `opacity` shows
/// (all without it); a small floor keeps a flat image's scores finite.
fn colour_variance(image: &Img, opacity: Option<&[f32]>) -> f32 {
    let (mut w, mut sum, mut sq) = (0.0f64, [0.0f64; 3], [0.0f64; 3]);
    for (i, c) in image.px.iter().enumerate() {
        let a = opacity.map_or(1.0, |o| o[i]) as f64;
        w += a;
        for k in 0..3 {
            sum[k] += a * c[k] as f64;
            sq[k] += a * (c[k] as f64).powi(2);
        }
    }
    let w = w.max(1e-9);
    let var: f64 = (0..3).map(|k| sq[k] / w - (sum[k] / w).powi(2)).sum();
    (var as f32).max(1e-4)
}

/// A patch centre's margin from the image's border, in patch radii, before
/// [`super::border_reach`]'s factors.
const CENTRE_MARGIN: f32 = 0.5;

/// The mean of a `USAGE²` grid's values (the cells' use, or their colour ratios) over the cells
/// within `r` pixels of `c` (the nearest cell's when none is).
fn grid_mean_under(usage: &[f32], w: usize, h: usize, c: Vec2, r: f32) -> f32 {
    let (cw, ch) = (w as f32 / USAGE as f32, h as f32 / USAGE as f32);
    let (mut sum, mut n) = (0.0, 0);
    for cy in 0..USAGE {
        for cx in 0..USAGE {
            let p = Vec2::new((cx as f32 + 0.5) * cw, (cy as f32 + 0.5) * ch);
            if p.distance(c) <= r {
                sum += usage[cy * USAGE + cx];
                n += 1;
            }
        }
    }
    if n > 0 {
        return sum / n as f32;
    }
    let cx = ((c.x / cw) as usize).min(USAGE - 1);
    let cy = ((c.y / ch) as usize).min(USAGE - 1);
    usage[cy * USAGE + cx]
}

/// The transparent share of a disc of radius `r` pixels centred at image point `c` under the
/// `w` x `h` opacity `op`, read at the centre and on two rings at 0.4 and 0.75 of the radius: a
/// disc that is mostly hole covers only a crescent of its seed's surroundings, and a surface
/// pieced together from crescents is all seams and fades. Points past the image's border read
/// its edge.
fn transparent_share(op: &[f32], w: usize, h: usize, c: Vec2, r: f32) -> f32 {
    let mut opaque = bilinear_scalar(op, w, h, c);
    for k in 0..8 {
        let dir = Vec2::from_angle(k as f32 * std::f32::consts::TAU / 8.0);
        for ring in [0.4, 0.75] {
            opaque += bilinear_scalar(op, w, h, c + dir * ring * r);
        }
    }
    1.0 - opaque / 17.0
}

/// Whether a face's flattening is faithful: not flipped, and no edge stretched or shrunk by more
/// than 2x (where a disc wraps around a thin part its two fronts meet with unrelated
/// coordinates).
fn faithful(p: &[Vec3; 3], q: &[Vec2; 3]) -> bool {
    let area2 = (q[1] - q[0]).perp_dot(q[2] - q[0]);
    area2 > 0.0 && within_stretch(p, q, 2.0)
}

/// Whether no edge of a face (corners `p` on the surface) is flattened (to `q`) more than
/// `limit` times longer or shorter than it is.
fn within_stretch(p: &[Vec3; 3], q: &[Vec2; 3], limit: f32) -> bool {
    (0..3).all(|k| {
        let l3 = p[k].distance(p[(k + 1) % 3]);
        let l2 = q[k].distance(q[(k + 1) % 3]);
        l3 <= 1e-20 || (l2 <= limit * l3 && l2 * limit >= l3)
    })
}

/// Whether segment `a`-`b` passes within `r` of the origin.
fn segment_meets_disc(a: Vec2, b: Vec2, r: f32) -> bool {
    let d = b - a;
    let len2 = d.length_squared();
    let t = if len2 > 0.0 {
        (-a.dot(d) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (a + d * t).length() <= r
}

/// Whether the triangle `q` contains the origin.
fn contains_origin(q: &[Vec2; 3]) -> bool {
    let s = [0, 1, 2].map(|k| q[k].perp_dot(q[(k + 1) % 3]));
    (s[0] >= 0.0 && s[1] >= 0.0 && s[2] >= 0.0) || (s[0] <= 0.0 && s[1] <= 0.0 && s[2] <= 0.0)
}

/// Bilinear lookup of a scalar image at pixel coordinates (centres at integers), clamped.
fn bilinear_scalar(v: &[f32], w: usize, h: usize, p: Vec2) -> f32 {
    let (x0, y0) = (p.x.floor(), p.y.floor());
    let (fx, fy) = (p.x - x0, p.y - y0);
    let at = |x: f32, y: f32| {
        let xi = (x as isize).clamp(0, w as isize - 1) as usize;
        let yi = (y as isize).clamp(0, h as isize - 1) as usize;
        v[yi * w + xi]
    };
    (at(x0, y0) * (1.0 - fx) + at(x0 + 1.0, y0) * fx) * (1.0 - fy)
        + (at(x0, y0 + 1.0) * (1.0 - fx) + at(x0 + 1.0, y0 + 1.0) * fx) * fy
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_disc_over_a_hole_reads_as_mostly_transparent() {
        // a 100 x 100 image with a round hole of radius 30 in the middle
        let (w, h) = (100, 100);
        let op: Vec<f32> = (0..w * h)
            .map(|i| {
                let p = Vec2::new((i % w) as f32, (i / w) as f32);
                if p.distance(Vec2::splat(50.0)) < 30.0 {
                    0.0
                } else {
                    1.0
                }
            })
            .collect();
        let share = |c: Vec2| transparent_share(&op, w, h, c, 20.0);
        assert!(
            share(Vec2::splat(50.0)) > 0.99,
            "{}",
            share(Vec2::splat(50.0))
        );
        assert!(
            share(Vec2::splat(15.0)) < 0.01,
            "{}",
            share(Vec2::splat(15.0))
        );
        // a disc on the hole's rim: about half hole
        let rim = share(Vec2::new(80.0, 50.0));
        assert!((0.3..0.7).contains(&rim), "{rim}");
    }

    #[test]
    fn a_patch_stands_upright_on_a_wall_and_turns_freely_on_a_floor() {
        let wall = Vec3::Z;
        for (dir, symmetry) in [(Vec3::Y, 4), (Vec3::X, 4), (-Vec3::X, 4), (-Vec3::Y, 2)] {
            let e1 = upright(dir, wall, symmetry).expect("a wall has an up");
            // the image's up is the patch's n × e1
            let image_up = wall.cross(e1);
            assert!(
                image_up.dot(Vec3::Y).abs() > 0.999,
                "{dir} ({symmetry}-fold): the image's up is {image_up}"
            );
        }
        // a 2-fold field across a wall stays as the field says: up is not one of its branches
        let across = upright(Vec3::X, wall, 2).expect("a wall has an up");
        assert!(wall.cross(across).dot(Vec3::X).abs() > 0.999);
        // a floor gives no up, nor a tilted roof beyond 60 degrees from vertical
        assert!(upright(Vec3::X, Vec3::Y, 4).is_none());
        let roof = Vec3::new(0.0, 70f32.to_radians().sin(), 70f32.to_radians().cos());
        assert!(upright(Vec3::X, roof, 4).is_none());
    }
}
