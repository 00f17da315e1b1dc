//! Surface texture optimisation (Kwatra, Essa, Bobick & Kwatra 2005, "Texture optimization for
//! example-based synthesis", §3; on surfaces as Kwatra et al. 2007), with the feature-to-feature
//! constraint of Xu et al. 2009, "Feature-aligned shape texturing", §5.1-5.2.
//!
//! The energy, Xu et al. eq. (3):
//!
//! `E_t(X; {z_p}) = Σ_{p ∈ X+} λ_p ω_p |x_p − z_p|²`
//!
//! - `X+`: sample vertices whose `w × w` texel patches, laid out along the orientation field
//!   (x axis = the field, y axis = `n × field`, vertices flattened by projection on the sample's
//!   tangent plane), cover the surface: a Poisson-disk set at spacing `r w` texels, taken along the
//!   salient curves first, then near them by increasing distance, then in seeded random order
//!   (after Chen et al. 2009).
//! - `x_p`: the surface colours of the patch; `z_p`: the most similar exemplar patch. The search
//!   compares `8 × 8` cell means of the patch (PCA to [`Params::pca_dims`] dimensions, k-d tree,
//!   the best four verified on every filled cell, plus the sample's previous patch).
//! - `ω_p = |x_p − z_p|^(r−2)`, `r = 0.8`: Kwatra et al.'s robust re-weighting (§3.1).
//! - `λ_p = 1 / (d(p, C) + ε₀)`, eq. (4), with `d(p, C)` the surface distance to the nearest
//!   salient curve; `λ_p = 1` without curves.
//! - **Feature-to-feature constraint (§5.2):** where a patch covers a curve (`d(p, C) < w/2`),
//!   `z_p` is searched only among exemplar patches whose centre pixel lies at the same distance
//!   (within [`Params::feature_tolerance`] texels) from the exemplar's principal line
//!   ([`exemplar_lines`]). Patches on a curve are therefore centred on the line, and as the field
//!   runs along the curve the line runs along it too.
//!
//! The iteration alternates, as Kwatra et al.: nearest exemplar patch for every sample, then the
//! colours minimising `E_t` (per vertex, the weighted mean of the overlapping patches' predictions,
//! read bilinearly at the vertex's own patch coordinates), until fewer than
//! [`Params::tolerance`] of the `z_p` change or [`Params::iterations`] passes. Kwatra's
//! multi-scale neighbourhoods: a pass at `2w` before `w` ([`Params::multiscale`]). The initial
//! colours are the caller's (the Wei-Levoy multi-resolution synthesis along the same field, in
//! place of Kwatra's coarser image levels). Transparent exemplar pixels never enter a patch.

mod exemplar;
pub mod exemplar_lines;
mod samples;
mod search;
mod vote;

use std::sync::Arc;

use crate::error::{Error, Result};
use crate::work::{CancelToken, Event, Progress, Stopwatch};

pub use exemplar_lines::{ExemplarLines, find_principal_lines};

use exemplar::Exemplar;
use samples::{poisson_samples, regions};
use search::{Index, nearest_patches};
use vote::vote;

/// Cells per patch side in the search vectors.
const CELLS: usize = 8;
/// Patches verified on every cell after the PCA search.
const VERIFY: usize = 4;
/// Shifts (texels, each axis) tried around the best patch at full resolution.
const REFINE: isize = 2;

/// Parameters (Xu et al. 2009 §5 and the guide's proposals: `w = 16`, `r = 0.25`, robust
/// `r = 0.8`, `ε₀ = 1e-6`, constraint tolerance 1 texel, at most 10 iterations, stop under 1%).
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
#[serde(default)]
pub struct Params {
    /// Patch side `w` in texels (a multiple of 8, at least 8).
    pub patch: usize,
    /// Run a scale at `2w` before `w` (Kwatra's multi-scale neighbourhoods).
    pub multiscale: bool,
    /// Sample spacing as a fraction `r` of the patch side.
    pub spacing: f32,
    /// Most iterations per scale.
    pub iterations: usize,
    /// Stop when fewer than this fraction of the samples change patch.
    pub tolerance: f32,
    /// Kwatra's robust exponent `r` in `ω_p = |x_p − z_p|^(r−2)`.
    pub robust: f32,
    /// Constraint tolerance in texels: `|D_exemplar − d(p, C)| <` this.
    pub feature_tolerance: f32,
    /// `ε₀` of eq. (4), in surface units.
    pub eps: f32,
    /// PCA dimensions of the search vectors.
    pub pca_dims: usize,
    /// Random seed (sample order, PCA sample).
    pub seed: u64,
}

impl Default for Params {
    fn default() -> Self {
        Params {
            patch: 16,
            multiscale: true,
            spacing: 0.25,
            iterations: 10,
            tolerance: 0.01,
            robust: 0.8,
            feature_tolerance: 1.0,
            eps: 1e-6,
            pca_dims: 16,
            seed: 0,
        }
    }
}

/// The surface to texture: a mesh at about one vertex per texel, with its orientation field.
#[derive(Clone, Copy, Debug)]
pub struct Surface<'a> {
    /// Vertex positions.
    pub positions: &'a [[f32; 3]],
    /// Triangles.
    pub faces: &'a [[u32; 3]],
    /// Unit vertex normals.
    pub normals: &'a [[f32; 3]],
    /// Unit tangent per vertex: the exemplar's x axis.
    pub field: &'a [[f32; 3]],
    /// Surface length of one exemplar pixel.
    pub texel: f32,
}

/// The feature-to-feature constraint's data.
#[derive(Clone, Copy, Debug)]
pub struct Constraint<'a> {
    /// Per vertex, the surface distance to the nearest salient curve (surface units).
    pub curve_distance: &'a [f32],
    /// The exemplar's principal lines (same size as the exemplar).
    pub lines: &'a ExemplarLines,
}

/// What one scale did.
#[derive(Clone, Debug, Default)]
pub struct ScaleReport {
    /// Patch side in texels.
    pub patch: usize,
    /// Samples in `X+`.
    pub samples: usize,
    /// Samples under the feature constraint.
    pub constrained: usize,
    /// Per iteration, the mean RMS patch distance `|x_p − z_p|` (sRGB units).
    pub energy: Vec<f64>,
    /// Per iteration, the fraction of samples whose patch changed.
    pub changed: Vec<f64>,
}

/// The optimisation's report.
#[derive(Clone, Debug, Default)]
pub struct Report {
    /// Per scale, coarse first.
    pub scales: Vec<ScaleReport>,
    /// Per vertex, the exemplar pixel of its strongest patch prediction.
    pub source: Vec<[u32; 2]>,
    /// Wall time in seconds.
    pub seconds: f64,
}

/// Optimise `colors` (per vertex of `surface`, sRGB in [0, 1]) towards the exemplar: Xu et al.
/// eq. (3) by Kwatra's alternation, with the feature constraint when given. `sink` receives a
/// partial result after every iteration.
#[allow(clippy::too_many_arguments)]
pub fn optimize(
    surface: &Surface,
    colors: &mut [[f32; 3]],
    exemplar: &image::RgbImage,
    alpha: Option<&image::GrayImage>,
    constraint: Option<Constraint>,
    params: &Params,
    sink: &dyn Fn(Event),
    cancel: &CancelToken,
) -> Result<Report> {
    let clock = Stopwatch::start();
    validate(surface, colors, exemplar, constraint.as_ref(), params)?;
    let n = surface.positions.len();
    let ex = Exemplar::new(exemplar, alpha)?;
    let scales = patch_scales(&ex, params)?;
    let adj = crate::mesh::vertex_adjacency(n, surface.faces);
    let h = surface.texel;
    // λ_p of eq. (4): curve-free components share the farthest finite distance.
    let lambda_of: Box<dyn Fn(usize) -> f32 + Sync> = match &constraint {
        None => Box::new(|_| 1.0),
        Some(c) => {
            let far = c
                .curve_distance
                .iter()
                .copied()
                .filter(|d| d.is_finite())
                .fold(h, f32::max);
            let eps = params.eps;
            let d = c.curve_distance;
            Box::new(move |v| 1.0 / (d[v].min(far) + eps))
        }
    };
    let mut report = Report::default();
    let mut source = vec![[u32::MAX; 2]; n];
    let total_iters = (scales.len() * params.iterations.max(1)) as f32;
    let mut iter_done = 0usize;
    for (si, &w) in scales.iter().enumerate() {
        cancel.check()?;
        let lines = constraint.as_ref().map(|c| c.lines);
        let index = Index::build(
            &ex,
            w,
            lines,
            params.feature_tolerance,
            params.pca_dims,
            params.seed,
        )?;
        cancel.check()?;
        let near = w as f32 / 2.0 * h;
        let samples = poisson_samples(
            surface.positions,
            constraint.as_ref().map(|c| c.curve_distance),
            near,
            params.spacing * w as f32 * h,
            params.seed.wrapping_add(si as u64),
        );
        let reg = regions(surface, &adj, samples, w);
        cancel.check()?;
        let ns = reg.samples.len();
        // per sample: constrained target distance in texels (None = free)
        let target_d: Vec<Option<f32>> = reg
            .samples
            .iter()
            .map(|&p| {
                let c = constraint.as_ref()?;
                let d = c.curve_distance[p as usize];
                (d < near && !index.bins.is_empty()).then_some(d / h)
            })
            .collect();
        let lambda: Vec<f32> = reg.samples.iter().map(|&p| lambda_of(p as usize)).collect();
        let mut sr = ScaleReport {
            patch: w,
            samples: ns,
            constrained: target_d.iter().filter(|d| d.is_some()).count(),
            ..Default::default()
        };
        let mut z: Vec<u32> = vec![u32::MAX; ns];
        let mut dist: Vec<f32> = vec![0.0; ns];
        for it in 0..params.iterations.max(1) {
            cancel.check()?;
            // ---- E: nearest exemplar patch per sample
            let found = nearest_patches(
                &index,
                &ex,
                &reg,
                colors,
                w,
                &target_d,
                lines,
                &z,
                params.feature_tolerance,
            );
            let mut changed = 0usize;
            let mut energy = 0.0f64;
            for (s, &(c, d)) in found.iter().enumerate() {
                if c != z[s] {
                    changed += 1;
                }
                z[s] = c;
                dist[s] = if d.is_finite() { d } else { 0.0 };
                energy += dist[s] as f64;
            }
            // ---- M: per vertex, the weighted mean of the covering patches' predictions
            vote(
                &reg,
                &ex,
                &index,
                &z,
                &dist,
                &lambda,
                params.robust,
                colors,
                &mut source,
            );
            let frac = changed as f64 / ns.max(1) as f64;
            sr.energy.push(energy / ns.max(1) as f64);
            sr.changed.push(frac);
            iter_done += 1;
            let progress = Progress {
                stage: "optimize",
                level: scales.len() - 1 - si,
                levels: scales.len(),
                iteration: it + 1,
                energy: energy / ns.max(1) as f64,
                elapsed: clock.secs(),
                fraction: (iter_done as f32 / total_iters).min(1.0),
            };
            let signal: Arc<[[f32; 3]]> = colors.to_vec().into();
            sink(Event::Partial { progress, signal });
            if it >= 1 && frac < params.tolerance as f64 {
                break;
            }
        }
        report.scales.push(sr);
    }
    report.source = source;
    report.seconds = clock.secs();
    sink(Event::StageTime("optimize", report.seconds));
    Ok(report)
}

/// The inputs and parameters [`optimize`] refuses, as one-line errors.
fn validate(
    surface: &Surface,
    colors: &[[f32; 3]],
    exemplar: &image::RgbImage,
    constraint: Option<&Constraint>,
    params: &Params,
) -> Result<()> {
    let n = surface.positions.len();
    for (what, len) in [
        ("colours", colors.len()),
        ("normals", surface.normals.len()),
        ("field", surface.field.len()),
    ] {
        if len != n {
            return Err(Error::InvalidInput(format!(
                "texture optimisation: {len} {what} for {n} vertices"
            )));
        }
    }
    if let Some(c) = constraint
        && (c.curve_distance.len() != n
            || (c.lines.width, c.lines.height)
                != (exemplar.width() as usize, exemplar.height() as usize))
    {
        return Err(Error::InvalidInput(
            "texture optimisation: the constraint does not match the mesh or the exemplar".into(),
        ));
    }
    if !(surface.texel.is_finite() && surface.texel > 0.0) {
        return Err(Error::InvalidInput(format!(
            "texture optimisation: texel size {}",
            surface.texel
        )));
    }
    if params.patch < CELLS || !params.patch.is_multiple_of(CELLS) {
        return Err(Error::InvalidInput(format!(
            "patch size {}: use a multiple of {CELLS}",
            params.patch
        )));
    }
    if !(params.spacing > 0.0 && params.spacing <= 1.0) {
        return Err(Error::InvalidInput(format!(
            "sample spacing {}: use a fraction in (0, 1]",
            params.spacing
        )));
    }
    Ok(())
}

/// The patch widths, coarse first: the asked one, or the largest the exemplar holds, and twice
/// it before it with [`Params::multiscale`].
fn patch_scales(ex: &Exemplar, params: &Params) -> Result<Vec<usize>> {
    // The largest patch the exemplar holds, at most the asked one.
    let fit = (ex.w.min(ex.h).saturating_sub(1) / CELLS) * CELLS;
    let w0 = params.patch.min(fit);
    if w0 < CELLS {
        return Err(Error::InvalidInput(format!(
            "the exemplar ({}x{}) is too small for texture optimisation (needs at least {}x{})",
            ex.w,
            ex.h,
            CELLS + 1,
            CELLS + 1
        )));
    }
    let mut scales = vec![w0];
    if params.multiscale && 2 * w0 <= fit {
        scales.insert(0, 2 * w0);
    }
    Ok(scales)
}

/// How `synth` and feature-aligned texturing make their texture.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum Method {
    /// Wei-Levoy neighbourhood matching, coarse to fine (fast).
    #[default]
    Neighbourhood,
    /// Wei-Levoy, then surface texture optimisation ([`optimize`]): whole patches, the
    /// exemplar's structure kept over larger areas, and the feature constraint when asked.
    Optimize,
}

impl Method {
    /// The CLI spelling.
    pub fn as_str(self) -> &'static str {
        match self {
            Method::Neighbourhood => "neighbourhood",
            Method::Optimize => "optimize",
        }
    }
}

impl std::str::FromStr for Method {
    type Err = ();
    fn from_str(s: &str) -> std::result::Result<Self, ()> {
        match s {
            "neighbourhood" | "neighborhood" => Ok(Method::Neighbourhood),
            "optimize" | "optimise" => Ok(Method::Optimize),
            _ => Err(()),
        }
    }
}

/// Optimise a Wei-Levoy result in place ([`optimize`] on its uniform-density mesh, along its
/// orientation field, at its texel size), with the feature constraint when `constraint` gives the
/// salient curves (in the target's coordinates) and the exemplar's principal lines. Updates the
/// mesh colours, the per-file-vertex colours of `target` and the source pixels.
#[allow(clippy::too_many_arguments)]
pub fn optimize_result(
    result: &mut crate::synthesis::SynthResult,
    target: &crate::mesh::TriMesh,
    exemplar: &image::RgbImage,
    alpha: Option<&image::GrayImage>,
    constraint: Option<(&[crate::geometry::Curve], &ExemplarLines)>,
    params: &Params,
    sink: &dyn Fn(Event),
    cancel: &CancelToken,
) -> Result<Report> {
    if result.displacement.is_some() {
        return Err(Error::InvalidInput(
            "texture optimisation works on colours, not on a displacement".into(),
        ));
    }
    let mesh = &result.mesh;
    let normals = match &mesh.normals {
        Some(n) => n.clone(),
        None => crate::geometry::vertex_normals(&mesh.positions, &mesh.faces),
    };
    let mut colors = mesh
        .colors
        .clone()
        .ok_or_else(|| Error::InvalidInput("the synthesis gave no colours".into()))?;
    let distance = constraint.map(|(curves, _)| {
        let adj = crate::mesh::vertex_adjacency(mesh.positions.len(), &mesh.faces);
        let polylines: Vec<crate::geometry::Polyline> = curves
            .iter()
            .map(|c| crate::geometry::Polyline {
                points: &c.points,
                closed: c.closed,
            })
            .collect();
        let near = (2 * params.patch + 2) as f32 * result.spacing;
        crate::geometry::distance_to_polylines(
            &mesh.positions,
            &adj,
            &polylines,
            near,
            f32::INFINITY,
        )
    });
    let surface = Surface {
        positions: &mesh.positions,
        faces: &mesh.faces,
        normals: &normals,
        field: &result.orientation,
        texel: result.spacing,
    };
    let report = optimize(
        &surface,
        &mut colors,
        exemplar,
        alpha,
        distance
            .as_deref()
            .zip(constraint)
            .map(|(d, (_, lines))| Constraint {
                curve_distance: d,
                lines,
            }),
        params,
        sink,
        cancel,
    )?;
    let nv = target.num_vertices();
    result.file_colors = target.to_file_order(&colors[..nv], [0.5; 3]);
    result.source = report.source.clone();
    result.mesh.colors = Some(colors);
    Ok(report)
}
