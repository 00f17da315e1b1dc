//! Geometry-correlated texture transfer, after Mertens, Kautz, Chen, Bekaert & Durand 2006,
//! "Texture Transfer Using Geometry Correlation" (EGSR 2006).
//!
//! The colour of a textured source mesh (weathering, dirt, patina, moss) is transferred to a
//! target mesh so that it follows the target's geometry the way it follows the source's:
//!
//! 1. Both meshes are refined to the working density (`Params::working_vertices`); the vertices
//!    are the paper's points.
//! 2. Features per vertex (§3.1, [`features`]): normalised height, normal (3), solid-angle
//!    curvature at 4 radii, directional occlusion on SH bands 0 and 1 (4): 12 numbers.
//! 3. Canonical correlation analysis between the source features `x^s` and colours `y^s`
//!    (§3.2, eq. 1: `sqrt(Λ) W_xᵀ x^s ≈ W_yᵀ y^s`) gives the guidance fields
//!    `x* = W_xᵀ (x - x̄^s)` on both meshes (3-D; `W_y` is discarded).
//! 4. Feature matching (§4.1): the target guidance distribution is moved onto the source's by
//!    the n-D PDF transfer of Pitié et al. 2005, and (`Params::multiscale_matching`) so are the
//!    Laplacian bands of the guidance fields over the mesh, Heeger-Bergen style.
//! 5. Parametric synthesis (§4.2, [`parametric`]): k-means segments of the guidance, per-cluster
//!    affine initialisation `Y = A X + b` plus noise, per-cluster Heeger-Bergen matching of the
//!    decorrelated colour channels and of their Laplacian bands on the mesh, feathered blending.
//!
//! Colours are handled in a decorrelated basis: the PCA of the source's sRGB colours.

pub mod feature_maps;
mod features;
mod guidance;
mod matching;
pub mod nonparametric;
pub mod parametric;
pub mod pyramid;
pub mod recipes;
mod regression;

use std::borrow::Cow;
use std::sync::Arc;

use crate::error::{Error, Result};
use crate::geometry::{Refined, refine_to_density};
use crate::mesh::TriMesh;
use crate::work::{CancelToken, Event, Progress, Stopwatch};
use guidance::{ColourBasis, Guidance};

pub use features::{
    CELL_PER_RADIUS, FeatureSet, LEVEL0_CELL_PER_RADIUS, check_feature_name, feature_field,
    feature_names, features, features_on_surface, normalised_height, opening_for_radius,
    wound_inwards,
};

/// The vertical axis (for the normalised-height feature).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Up {
    /// +Y up (glTF, most scans).
    #[default]
    Y,
    /// +Z up (CAD, some scanners).
    Z,
}

impl Up {
    /// Coordinate index of the axis.
    pub fn axis(self) -> usize {
        match self {
            Up::Y => 1,
            Up::Z => 2,
        }
    }
}

impl std::str::FromStr for Up {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        match s.to_ascii_lowercase().as_str() {
            "y" | "+y" => Ok(Up::Y),
            "z" | "+z" => Ok(Up::Z),
            _ => Err(Error::InvalidInput(format!(
                "unknown up axis '{s}' (expected y or z)"
            ))),
        }
    }
}

/// Synthesis method (§4).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Method {
    /// Constrained Heeger-Bergen (§4.2), for unstructured textures: the paper's default.
    #[default]
    Parametric,
    /// Image analogies on the surface (§4.1): copies source colour by guidance, neighbourhood
    /// colour and coherence ([`nonparametric`]); keeps the texture's grain and structure.
    NonParametric,
}

impl std::str::FromStr for Method {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        match s.to_ascii_lowercase().as_str() {
            "parametric" => Ok(Method::Parametric),
            "nonparametric" | "non-parametric" => Ok(Method::NonParametric),
            _ => Err(Error::InvalidInput(format!(
                "unknown method '{s}' (expected parametric or nonparametric)"
            ))),
        }
    }
}

/// The mean colour of the parametric synthesis (§4.2).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Mean {
    /// The colour regressed on the features (k nearest neighbours, each feature weighed by how
    /// far the colour follows it; [`regression`]) joins the guidance, so the clusters and their
    /// affine maps follow it. Carries rules that are not linear in the features (thresholds, a
    /// rule that needs two features at once). The default.
    #[default]
    Neighbours,
    /// The paper's per-cluster affine maps of the CCA guidance alone.
    Affine,
}

impl std::str::FromStr for Mean {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        match s.to_ascii_lowercase().as_str() {
            "neighbours" | "neighbors" | "knn" => Ok(Mean::Neighbours),
            "affine" => Ok(Mean::Affine),
            _ => Err(Error::InvalidInput(format!(
                "unknown mean '{s}' (expected neighbours or affine)"
            ))),
        }
    }
}

/// Parameters of the transfer; `Default` gives the paper's settings, except [`Params::mean`].
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
#[serde(default)]
pub struct Params {
    /// Both meshes are refined to about this many vertices (meshes already denser are kept).
    pub working_vertices: usize,
    /// Vertical axis for the height feature.
    pub up: Up,
    /// Solid-angle curvature radii, as fractions of the bounding-box diagonal.
    pub curvature_radii: Vec<f32>,
    /// Occlusion rays per vertex.
    pub rays: usize,
    /// Guidance dimensions kept from the CCA (at most 3 with RGB).
    pub cca_dims: usize,
    /// Clusters per mesh (the paper's `K`, its only parameter).
    pub clusters: usize,
    /// Synthesis method.
    pub method: Method,
    /// The parametric synthesis's mean colour: [`Mean::Neighbours`] by default (the paper's is
    /// [`Mean::Affine`]; `docs/systems/weathering.md` has both measured).
    pub mean: Mean,
    /// Random seed (occlusion rays, rotations, k-means, noise).
    pub seed: u64,
    /// Maximum PDF-transfer rotations.
    pub pdf_iterations: usize,
    /// Heeger-Bergen iterations.
    pub hb_iterations: usize,
    /// Laplacian pyramid levels of the colour (1 = colour histograms only).
    pub levels: usize,
    /// Source clusters interpolated per target cluster.
    pub neighbours: usize,
    /// Initial noise as a multiple of the pooled regression residual's standard deviation.
    pub noise: f32,
    /// Multi-scale feature matching (§4.2 of the guide): also match the Laplacian bands of the
    /// guidance fields, not only their values (3 levels, 3 passes).
    pub multiscale_matching: bool,
    /// How far the target's guidance is moved onto the source's distribution (§4.1): 1 = the
    /// paper's full PDF transfer, 0 = none (the guidance compared as it is), in between a blend
    /// of the two.
    pub match_strength: f32,
    /// Canonical components (CCA directions, 0 = the strongest) the guidance keeps; `None` keeps
    /// every one the CCA finds (the paper). Switching one off removes the rule it carries from
    /// matching and synthesis.
    pub components: Option<Vec<usize>>,
}

impl Default for Params {
    fn default() -> Self {
        Params {
            working_vertices: 100_000,
            up: Up::Y,
            curvature_radii: vec![0.01, 0.03, 0.1, 0.3],
            rays: 64,
            cca_dims: 3,
            clusters: 50,
            method: Method::Parametric,
            mean: Mean::Neighbours,
            seed: 0,
            pdf_iterations: 20,
            hb_iterations: 3,
            levels: 3,
            neighbours: 4,
            noise: 1.0,
            multiscale_matching: true,
            match_strength: 1.0,
            components: None,
        }
    }
}

/// What to transfer from and to.
#[derive(Clone, Copy, Debug)]
pub struct Input<'a> {
    /// Textured source (vertex colours or a UV texture).
    pub source: &'a TriMesh,
    /// Target shape.
    pub target: &'a TriMesh,
    /// Optional, indexed by source file vertex: `true` = leave out of training.
    pub source_mask: Option<&'a [bool]>,
}

/// The CCA, in words and numbers, for printing.
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct CcaReport {
    /// Feature names (rows of `weights`).
    pub feature_names: Vec<String>,
    /// Per feature, its weight in each canonical direction, in standardised units (weight ×
    /// the feature's standard deviation on the source), so magnitudes compare.
    pub weights: Vec<Vec<f64>>,
    /// Canonical correlations `ρ_1 ≥ ρ_2 ≥ …`.
    pub correlations: Vec<f64>,
    /// Source vertices used for training (after the mask).
    pub training_vertices: usize,
    /// Per canonical direction, whether the guidance kept it ([`Params::components`]).
    #[serde(default)]
    pub enabled: Vec<bool>,
    /// Per feature, its weight in the colour regression's distance ([`Mean::Neighbours`],
    /// the most relevant 1, none below 0.5); empty with [`Mean::Affine`] and the non-parametric method.
    #[serde(default)]
    pub mean_weights: Vec<f32>,
}

impl CcaReport {
    /// A small table: one line per feature, one column per canonical direction, then the
    /// correlations.
    pub fn to_text(&self) -> String {
        let d = self.correlations.len();
        let mut s = format!("{:<14}", "feature");
        for k in 0..d {
            s += &format!(" {:>8}", format!("dir{}", k + 1));
        }
        if !self.mean_weights.is_empty() {
            s += &format!(" {:>8}", "mean");
        }
        s.push('\n');
        for (j, (name, w)) in self.feature_names.iter().zip(&self.weights).enumerate() {
            s += &format!("{name:<14}");
            for x in w {
                s += &format!(" {x:>8.3}");
            }
            if let Some(m) = self.mean_weights.get(j) {
                s += &format!(" {m:>8.3}");
            }
            s.push('\n');
        }
        s += &format!("{:<14}", "correlation");
        for r in &self.correlations {
            s += &format!(" {r:>8.3}");
        }
        s.push('\n');
        if self.enabled.iter().any(|e| !e) {
            s += &format!("{:<14}", "used");
            for e in &self.enabled {
                s += &format!(" {:>8}", if *e { "on" } else { "off" });
            }
            s.push('\n');
        }
        s
    }

    /// The `count` features with the largest standardised weight (in magnitude) in canonical
    /// direction `k`, largest first, with their signed weights.
    pub fn top_features(&self, k: usize, count: usize) -> Vec<(String, f64)> {
        let mut w: Vec<(String, f64)> = self
            .feature_names
            .iter()
            .zip(&self.weights)
            .map(|(n, w)| (n.clone(), w.get(k).copied().unwrap_or(0.0)))
            .collect();
        w.sort_by(|a, b| b.1.abs().total_cmp(&a.1.abs()));
        w.truncate(count);
        w
    }
}

/// Refuse a component list ([`Params::components`]) that is empty or names a component past
/// the `cca_dims` the CCA keeps (at most 3 with RGB colour).
pub fn check_components(keep: &[usize], cca_dims: usize) -> Result<()> {
    let most = cca_dims.min(3);
    if keep.is_empty() {
        return Err(Error::InvalidInput(
            "--components: keep at least one canonical component".into(),
        ));
    }
    if let Some(k) = keep.iter().find(|&&k| k >= most) {
        return Err(Error::InvalidInput(format!(
            "--components: there is no component {k} (the CCA has at most {most}: 0 to {})",
            most.saturating_sub(1)
        )));
    }
    Ok(())
}

/// The components of a `--components` list such as `0,2`.
pub fn parse_components(s: &str) -> Result<Vec<usize>> {
    s.split(',')
        .map(|t| {
            t.trim().parse::<usize>().map_err(|_| {
                Error::InvalidInput(format!(
                    "--components {s}: expected component numbers such as 0,2"
                ))
            })
        })
        .collect()
}

/// The result of [`run`].
#[derive(Clone, Debug)]
pub struct Output {
    /// The refined target (working mesh; its first vertices are the target's own, with
    /// `source_face` / `source_bary` to bake or map back).
    pub target: Refined,
    /// sRGB colour in [0, 1] per vertex of `target.mesh`.
    pub colors: Vec<[f32; 3]>,
    /// Colours on the target's own vertices, in the file's vertex order.
    pub file_colors: Vec<[f32; 3]>,
    /// The CCA report.
    pub report: CcaReport,
    /// Target features (on `target.mesh`), for display.
    pub target_features: FeatureSet,
    /// Target guidance after feature matching, `n × d` (on `target.mesh`).
    pub target_guidance: Vec<f32>,
    /// Guidance dimension `d`.
    pub guidance_dim: usize,
    /// Source vertices after refinement.
    pub source_vertices: usize,
    /// Wall seconds per stage.
    pub timings: Vec<(&'static str, f64)>,
}

fn validate(m: &TriMesh, what: &str) -> Result<()> {
    if m.faces.is_empty() || m.positions.is_empty() {
        return Err(Error::InvalidInput(format!("{what} mesh has no faces")));
    }
    if m.positions.iter().flatten().any(|x| !x.is_finite()) {
        return Err(Error::InvalidInput(format!(
            "{what} mesh has non-finite coordinates"
        )));
    }
    let n = m.num_vertices();
    if m.faces.iter().flatten().any(|&i| i as usize >= n) {
        return Err(Error::InvalidInput(format!(
            "{what} face refers to a missing vertex"
        )));
    }
    let area = m.area();
    if area.is_nan() || area <= 0.0 {
        return Err(Error::InvalidInput(format!("{what} mesh has zero area")));
    }
    Ok(())
}

/// Transfer the source's colour onto the target (see the module doc). Emits `Event::Progress`
/// per stage, `Event::StageTime`, and `Event::Partial` (colours on the refined target) after the
/// initialisation and every Heeger-Bergen iteration; checks `cancel` between stages and batches.
pub fn run(
    input: &Input,
    params: &Params,
    sink: &dyn Fn(Event),
    cancel: &CancelToken,
) -> Result<Output> {
    let mut stages = Stages::new(sink);
    let (src, tgt) = (input.source, input.target);
    check_input(input, params)?;

    let clock = stages.begin("refine", 0.0);
    let (rs, rt, src_colors) = refine_pair(src, tgt, params)?;
    stages.end("refine", clock);
    cancel.check()?;

    let train = training_vertices(&rs, src, input.source_mask)?;

    let clock = stages.begin("features", 0.05);
    let (fs, ft) = features_pair(input, &rs, &rt, params, cancel)?;
    stages.end("features", clock);
    cancel.check()?;

    let clock = stages.begin("cca", 0.65);
    let train_cols: Vec<[f32; 3]> = train.iter().map(|&v| src_colors[v as usize]).collect();
    let basis = ColourBasis::fit(&train_cols)?;
    let src_dec: Vec<[f32; 3]> = src_colors.iter().map(|&c| basis.decorrelated(c)).collect();
    let mut guidance = guidance::fit_guidance(&fs, &ft, &train, &src_dec, params)?;
    stages.end("cca", clock);
    cancel.check()?;

    let clock = stages.begin("match", 0.68);
    matching::match_features(
        &mut guidance,
        &fs,
        &rs.mesh,
        &rt.mesh,
        &train,
        params,
        cancel,
    )?;
    stages.end("match", clock);
    cancel.check()?;

    let clock = stages.begin("synthesis", 0.72);
    let colours = ColourSource {
        basis: &basis,
        decorrelated: &src_dec,
        train: &train,
        features: &fs,
        target_features: &ft,
    };
    let (colors, mean_weights) = synthesize_colours(
        &guidance, &colours, &rs.mesh, &rt.mesh, params, &stages, cancel,
    )?;
    guidance.report.mean_weights = mean_weights;
    stages.end("synthesis", clock);
    let nv = tgt.num_vertices();
    let file_colors = tgt.to_file_order(&colors[..nv], [0.5; 3]);
    stages.timings.push(("total", stages.total.secs()));
    stages.progress("done", 1.0);
    Ok(Output {
        target: rt,
        colors,
        file_colors,
        report: guidance.report,
        target_features: ft,
        target_guidance: guidance.target,
        guidance_dim: guidance.dim,
        source_vertices: rs.mesh.num_vertices(),
        timings: stages.timings,
    })
}

/// The run's clock, its stage timings and its progress events.
struct Stages<'a> {
    total: Stopwatch,
    timings: Vec<(&'static str, f64)>,
    sink: &'a dyn Fn(Event),
}

impl<'a> Stages<'a> {
    /// Start the run's clock.
    fn new(sink: &'a dyn Fn(Event)) -> Self {
        Stages {
            total: Stopwatch::start(),
            timings: Vec::new(),
            sink,
        }
    }

    /// Report progress at `fraction` of the run, in `stage`.
    fn progress(&self, stage: &'static str, fraction: f32) {
        (self.sink)(Event::Progress(Progress {
            stage,
            elapsed: self.total.secs(),
            fraction,
            ..Default::default()
        }))
    }

    /// Report the start of a stage and start its clock.
    fn begin(&self, stage: &'static str, fraction: f32) -> Stopwatch {
        self.progress(stage, fraction);
        Stopwatch::start()
    }

    /// Record a stage's time and report it.
    fn end(&mut self, stage: &'static str, clock: Stopwatch) {
        self.timings.push((stage, clock.secs()));
        (self.sink)(Event::StageTime(stage, clock.secs()));
    }
}

/// Refuse meshes, masks and parameters the transfer cannot use, and working sizes that would
/// not fit in memory.
fn check_input(input: &Input, params: &Params) -> Result<()> {
    let (src, tgt) = (input.source, input.target);
    validate(src, "source")?;
    validate(tgt, "target")?;
    // Measured peak: about 1.3 KB per working vertex for source and target together (refined
    // meshes, pyramids, 12-D features, guidance, BVHs); 3 KB leaves room for the inputs.
    let working = params
        .working_vertices
        .max(src.num_vertices().max(tgt.num_vertices())) as u64;
    crate::work::check_memory(
        working.saturating_mul(3 << 10),
        &format!("{working} working vertices"),
        "use fewer --vertices",
    )?;
    if src.vertex_signal().is_none() {
        return Err(Error::InvalidInput(
            "source mesh has no colours or texture to transfer".into(),
        ));
    }
    if let Some(m) = input.source_mask {
        if m.len() != src.file_vertex_count {
            return Err(Error::InvalidInput(format!(
                "source mask has {} entries, the source file has {} vertices",
                m.len(),
                src.file_vertex_count
            )));
        }
        if m.iter().all(|&x| x) {
            return Err(Error::InvalidInput(
                "source mask excludes every vertex: nothing to learn from".into(),
            ));
        }
    }
    if params
        .curvature_radii
        .iter()
        .any(|r| !(r.is_finite() && *r > 0.0))
    {
        return Err(Error::InvalidInput(
            "curvature radii must be positive".into(),
        ));
    }
    if let Some(keep) = &params.components {
        check_components(keep, params.cca_dims)?;
    }
    if params.clusters == 0 || params.cca_dims == 0 {
        return Err(Error::InvalidInput(
            "clusters and cca_dims must be at least 1".into(),
        ));
    }
    Ok(())
}

/// Both meshes refined to the working density, and the source's colour per working vertex.
fn refine_pair(
    src: &TriMesh,
    tgt: &TriMesh,
    params: &Params,
) -> Result<(Refined, Refined, Vec<[f32; 3]>)> {
    let (rs, rt) = rayon::join(
        || refine_to_density(src, params.working_vertices),
        || refine_to_density(tgt, params.working_vertices),
    );
    let src_colors: Vec<[f32; 3]> = match rs.mesh.colors.clone() {
        Some(c) if c.len() == rs.mesh.num_vertices() => c,
        _ => rs.mesh.vertex_signal().ok_or_else(|| {
            Error::InvalidInput("source mesh has no colours or texture to transfer".into())
        })?,
    };
    Ok((rs, rt, src_colors))
}

/// The working source vertices to learn from: every one, or those whose nearest file vertex
/// the mask leaves in; at least 16.
fn training_vertices(rs: &Refined, src: &TriMesh, mask: Option<&[bool]>) -> Result<Vec<u32>> {
    let ns_all = rs.mesh.num_vertices();
    let train: Vec<u32> = match mask {
        None => (0..ns_all as u32).collect(),
        Some(mask) => rs
            .vertex_sources()
            .iter()
            .enumerate()
            .filter(|(_, (f, b))| {
                if *f == u32::MAX {
                    return false;
                }
                let face = src.faces[*f as usize];
                let k = (0..3).max_by(|&i, &j| b[i].total_cmp(&b[j])).unwrap_or(0);
                let fi = src
                    .file_index
                    .get(face[k] as usize)
                    .copied()
                    .unwrap_or(u32::MAX);
                !mask.get(fi as usize).copied().unwrap_or(true)
            })
            .map(|(v, _)| v as u32)
            .collect(),
    };
    if train.len() < 16 {
        return Err(Error::InvalidInput(format!(
            "the source mask leaves only {} vertices to learn from",
            train.len()
        )));
    }
    Ok(train)
}

/// The features (§3.1) of both working meshes, at once.
fn features_pair(
    input: &Input,
    rs: &Refined,
    rt: &Refined,
    params: &Params,
    cancel: &CancelToken,
) -> Result<(FeatureSet, FeatureSet)> {
    let (src, tgt) = (input.source, input.target);
    // the working meshes are bisections of the inputs: the inputs' triangles carry the same
    // surface for the curvature tree and the occlusion rays
    // both meshes at once: the trees' builds and the sampling passes are serial
    let (fs, ft) = rayon::join(
        || {
            features_on_surface(
                &rs.mesh.positions,
                &rs.mesh.faces,
                Some((&src.positions, &src.faces)),
                params,
                cancel,
            )
        },
        || {
            features_on_surface(
                &rt.mesh.positions,
                &rt.mesh.faces,
                Some((&tgt.positions, &tgt.faces)),
                params,
                cancel,
            )
        },
    );
    Ok((fs?, ft?))
}

/// What the synthesis reads of the source's colour.
struct ColourSource<'a> {
    basis: &'a ColourBasis,
    /// Colour per working source vertex, in the decorrelated basis.
    decorrelated: &'a [[f32; 3]],
    train: &'a [u32],
    features: &'a FeatureSet,
    /// The target's features (for [`Mean::Neighbours`]).
    target_features: &'a FeatureSet,
}

/// Synthesize the target's colour (§4) from the matched guidance, by the parametric or the
/// non-parametric method, emitting `Event::Partial` per iteration; sRGB per target vertex, and
/// the feature weights of the regressed mean (empty without one).
fn synthesize_colours(
    g: &Guidance,
    colours: &ColourSource,
    src: &TriMesh,
    tgt: &TriMesh,
    params: &Params,
    stages: &Stages,
    cancel: &CancelToken,
) -> Result<(Vec<[f32; 3]>, Vec<f32>)> {
    let (train, src_dec, d) = (colours.train, colours.decorrelated, g.dim);
    let src_adj = src.adjacency();
    let levels = params.levels.max(1);
    let tgt_adj = tgt.adjacency();
    let knobs = parametric::SynthKnobs {
        clusters: params.clusters,
        neighbours: params.neighbours,
        iterations: params.hb_iterations,
        levels,
        noise: params.noise,
        seed: params.seed,
    };
    let to_srgb = |y: &[Vec<f32>; 3]| -> Vec<[f32; 3]> {
        (0..y[0].len())
            .map(|i| colours.basis.srgb([y[0][i], y[1][i], y[2][i]]))
            .collect()
    };
    let iters = params.hb_iterations;
    let mut partial = |it: usize, y: &[Vec<f32>; 3]| -> Result<()> {
        cancel.check()?;
        let prog = Progress {
            stage: "synthesis",
            level: 0,
            levels: 1,
            iteration: it,
            energy: 0.0,
            elapsed: stages.total.secs(),
            fraction: 0.72 + 0.28 * it as f32 / (iters + 1) as f32,
        };
        let signal: Arc<[[f32; 3]]> = to_srgb(y).into();
        (stages.sink)(Event::Partial {
            progress: prog,
            signal,
        });
        Ok(())
    };
    let (y, weights) = if params.method == Method::NonParametric {
        let gs_all = g.model.project_x(&colours.features.values);
        let mut partial_np = |it: usize, c: &[[f32; 3]]| -> Result<()> {
            let y: [Vec<f32>; 3] = [0, 1, 2].map(|k| c.iter().map(|x| x[k]).collect());
            partial(it, &y)
        };
        let knobs = nonparametric::Knobs {
            passes: iters.max(1),
            ..nonparametric::Knobs::default()
        };
        let c = nonparametric::synthesize(
            &gs_all,
            train,
            src_dec,
            &src_adj,
            &g.target,
            &tgt_adj,
            d,
            &knobs,
            &mut partial_np,
        )?;
        let y = [0, 1, 2].map(|k| c.iter().map(|x| x[k]).collect::<Vec<f32>>());
        (y, Vec::new())
    } else {
        parametric_colours(g, colours, src_adj, &tgt_adj, params, &knobs, &mut partial)?
    };
    Ok((to_srgb(&y), weights))
}

/// The parametric synthesis (§4.2) of the decorrelated colour channels on the target. With
/// [`Mean::Neighbours`] the colour regressed on the features ([`regression`]) joins the guidance
/// as three more fields, so the clusters separate what the regression tells apart and their
/// affine maps follow it; with [`Mean::Affine`] the guidance is the CCA's alone. Also returns
/// the regression's feature weights (empty with [`Mean::Affine`]).
fn parametric_colours(
    g: &Guidance,
    colours: &ColourSource,
    src_adj: crate::mesh::Csr,
    tgt_adj: &crate::mesh::Csr,
    params: &Params,
    knobs: &parametric::SynthKnobs,
    partial: &mut parametric::PartialFn,
) -> Result<([Vec<f32>; 3], Vec<f32>)> {
    let (train, src_dec) = (colours.train, colours.decorrelated);
    let (src_guidance, tgt_guidance, dim, weights) = match params.mean {
        Mean::Affine => (
            Cow::Borrowed(&g.source_train[..]),
            Cow::Borrowed(&g.target[..]),
            g.dim,
            Vec::new(),
        ),
        Mean::Neighbours => {
            let pr = regression::predict(
                colours.features,
                colours.target_features,
                train,
                src_dec,
                &g.model,
            );
            let mut target = pr.target;
            regression::drop_directions(&mut target, &g.dropped, train, src_dec);
            let (gs, gt) = regression::extend_guidance(
                &g.source_train,
                &g.target,
                g.dim,
                train,
                &pr.source,
                &target,
            );
            (Cow::Owned(gs), Cow::Owned(gt), g.dim + 3, pr.weights)
        }
    };
    // the colour channels and their Laplacian bands, on the training vertices
    let channels: [Vec<f32>; 3] =
        [0, 1, 2].map(|c| src_dec.iter().map(|y| y[c]).collect::<Vec<f32>>());
    let pick = |v: &[f32]| -> Vec<f32> { train.iter().map(|&i| v[i as usize]).collect() };
    let src_levels: [Vec<Vec<f32>>; 3] = [0, 1, 2].map(|c| {
        pyramid::decompose(&src_adj, &channels[c], knobs.levels)
            .iter()
            .map(|l| pick(l))
            .collect()
    });
    let src_channels: [Vec<f32>; 3] = [0, 1, 2].map(|c| pick(&channels[c]));
    drop(src_adj);
    let y = parametric::synthesize(
        &parametric::SourceData {
            guidance: &src_guidance,
            colour: &src_channels,
            levels: &src_levels,
        },
        &tgt_guidance,
        tgt_adj,
        dim,
        knobs,
        partial,
    )?;
    Ok((y, weights))
}
