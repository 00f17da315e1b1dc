//! Multi-rule weathering recipes and their evaluation.
//!
//! A [`Recipe`] paints a mesh from its own geometry with a few rules at once, the way real
//! weathered assets combine them: dark dirt where occluded, light wear on convex edges (small
//! radius), a stain in concave dents, moss on exposed upward tops, a tint with height, plus fine
//! grain. The rules read the project's own features ([`super::features`]) with absolute
//! thresholds, so the same recipe means the same thing on any mesh.
//!
//! [`evaluate`] colours a source by a recipe, runs [`super::run`] onto a target and scores the
//! result against the recipe applied to the target: Pearson correlation of L*, a*, b*, the Lab
//! Wasserstein-1 distance (per channel, averaged), and the grain kept (the ratio of the
//! high-frequency L* standard deviation, output over truth). A k-nearest-neighbour regression on
//! the recipe's own features, source to target, is scored beside it as a floor.

use glam::Vec3;

use super::{FeatureSet, Params, Up, features};
use crate::color::srgb_to_lab;
use crate::error::{Error, Result};
use crate::geometry::{Fade, refine_to_density, value_noise};
use crate::mesh::{Csr, TriMesh};
use crate::stats::KdTree;
use crate::work::CancelToken;

/// One weathering rule.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Rule {
    /// Dark dirt where the ambient occlusion is high.
    Dirt,
    /// Light wear on convex edges (solid-angle curvature at the smallest radius).
    Wear,
    /// A rust-brown stain in concave dents (curvature at the second radius).
    Concavity,
    /// Green moss on exposed, upward-facing tops.
    Moss,
    /// Stone tinted from warm dark at the bottom to pale at the top.
    HeightTint,
}

impl Rule {
    /// Every rule.
    pub const ALL: [Rule; 5] = [
        Rule::Dirt,
        Rule::Wear,
        Rule::Concavity,
        Rule::Moss,
        Rule::HeightTint,
    ];
    /// Short name.
    pub fn name(self) -> &'static str {
        match self {
            Rule::Dirt => "dirt",
            Rule::Wear => "wear",
            Rule::Concavity => "concavity",
            Rule::Moss => "moss",
            Rule::HeightTint => "height",
        }
    }
}

/// A set of rules applied in a fixed order (height tint, moss, concavity, dirt, wear) over a
/// stone base, then grain.
#[derive(Clone, Debug)]
pub struct Recipe {
    /// Name for tables.
    pub name: String,
    /// The rules.
    pub rules: Vec<Rule>,
    /// Grain: relative amplitude of the multiplicative value noise (0 = none).
    pub grain: f32,
}

impl Recipe {
    /// A recipe of `rules` with grain 0.06.
    pub fn new(name: &str, rules: &[Rule]) -> Self {
        Recipe {
            name: name.to_string(),
            rules: rules.to_vec(),
            grain: 0.06,
        }
    }
    /// The recipe of one rule (plus grain).
    pub fn single(rule: Rule) -> Self {
        Recipe::new(rule.name(), &[rule])
    }
}

/// The project's multi-rule recipes: `stone` (height, dirt, wear), `mossy` (moss, dirt),
/// `stained` (concavity, wear, height), `ruin` (height, moss, dirt, wear: every rule of the
/// issue's hidden recipe).
pub fn recipes() -> Vec<Recipe> {
    use Rule::*;
    vec![
        Recipe::new("stone", &[HeightTint, Dirt, Wear]),
        Recipe::new("mossy", &[Moss, Dirt]),
        Recipe::new("stained", &[Concavity, Wear, HeightTint]),
        Recipe::new("ruin", &[HeightTint, Moss, Dirt, Wear]),
    ]
}

/// Feature parameters the recipes read (the default radii and rays, the truth's own ray seed).
pub fn recipe_params(up: Up) -> Params {
    Params {
        up,
        seed: 0x7275_7468,
        ..Params::default()
    }
}

/// The recipe's features of a mesh (see [`recipe_params`]).
pub fn recipe_features(m: &TriMesh, up: Up, cancel: &CancelToken) -> Result<FeatureSet> {
    features(&m.positions, &m.faces, &recipe_params(up), cancel)
}

fn smoothstep(e0: f32, e1: f32, x: f32) -> f32 {
    let t = ((x - e0) / (e1 - e0)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

fn lerp(a: [f32; 3], b: [f32; 3], t: f32) -> [f32; 3] {
    [0, 1, 2].map(|k| a[k] + (b[k] - a[k]) * t)
}

/// The strength in [0, 1] of one rule at vertex `v` (features `fs`, up axis `up`).
pub fn rule_strength(rule: Rule, fs: &FeatureSet, v: usize, up: Up) -> f32 {
    let row = fs.row(v);
    let nr = fs.radii.len();
    // columns: height, normal (3), curvature (nr; 0 on a plane, positive where convex), ao (the
    // visible fraction, 1 = fully exposed), occlusion (3)
    let open = row[4 + nr];
    let c0 = row[4];
    let c1 = row[4 + 1.min(nr.saturating_sub(1))];
    match rule {
        Rule::Dirt => smoothstep(0.75, 0.35, open),
        Rule::Wear => smoothstep(0.2, 0.45, c0),
        Rule::Concavity => smoothstep(-0.05, -0.25, c1),
        Rule::Moss => smoothstep(0.5, 0.9, row[1 + up.axis()]) * smoothstep(0.8, 0.95, open),
        Rule::HeightTint => row[0],
    }
}

/// Paint the vertices of a mesh (positions and its recipe features `fs`) by `recipe`; sRGB in
/// [0, 1].
pub fn paint(recipe: &Recipe, fs: &FeatureSet, positions: &[[f32; 3]], up: Up) -> Vec<[f32; 3]> {
    let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
    for p in positions {
        lo = lo.min(Vec3::from(*p));
        hi = hi.max(Vec3::from(*p));
    }
    let cell = ((hi - lo).length() * 0.004).max(1e-12);
    let has = |r: Rule| recipe.rules.contains(&r);
    (0..fs.len())
        .map(|v| {
            let s = |r: Rule| rule_strength(r, fs, v, up);
            let mut c = [0.55, 0.52, 0.48];
            if has(Rule::HeightTint) {
                c = lerp([0.42, 0.36, 0.30], [0.70, 0.68, 0.64], s(Rule::HeightTint));
            }
            if has(Rule::Moss) {
                c = lerp(c, [0.28, 0.46, 0.16], 0.85 * s(Rule::Moss));
            }
            if has(Rule::Concavity) {
                c = lerp(c, [0.50, 0.26, 0.14], 0.75 * s(Rule::Concavity));
            }
            if has(Rule::Dirt) {
                c = lerp(c, [0.12, 0.10, 0.08], 0.85 * s(Rule::Dirt));
            }
            if has(Rule::Wear) {
                c = lerp(c, [0.90, 0.88, 0.84], 0.8 * s(Rule::Wear));
            }
            let g = if recipe.grain > 0.0 {
                1.0 + recipe.grain
                    * value_noise(
                        Vec3::from(positions[v]) / cell,
                        17u32.wrapping_mul(0x9e37_79b9),
                        Fade::Cubic,
                    )
            } else {
                1.0
            };
            c.map(|x| (x * g).clamp(0.0, 1.0))
        })
        .collect()
}

/// Scores of one colouring against the truth, on the same vertices.
#[derive(Clone, Copy, Debug, Default, serde::Serialize)]
pub struct Scores {
    /// Pearson correlation of L*, a*, b* with the truth.
    pub corr: [f64; 3],
    /// Lab Wasserstein-1 distance of the value distributions, per channel, averaged.
    pub w1: f64,
    /// High-frequency L* standard deviation (value minus its 1-ring mean), output over truth.
    pub grain: f64,
}

fn high_freq_std(adj: &Csr, x: &[f32]) -> f64 {
    let n = x.len();
    let hf: Vec<f64> = (0..n)
        .map(|v| {
            let row = adj.row(v);
            let m =
                row.iter().map(|&u| x[u as usize] as f64).sum::<f64>() / row.len().max(1) as f64;
            x[v] as f64 - m
        })
        .collect();
    let mean = hf.iter().sum::<f64>() / n.max(1) as f64;
    (hf.iter().map(|h| (h - mean).powi(2)).sum::<f64>() / n.max(1) as f64).sqrt()
}

/// Score `out` against `truth` (sRGB per vertex of a mesh with adjacency `adj`).
pub fn score(out: &[[f32; 3]], truth: &[[f32; 3]], adj: &Csr) -> Scores {
    let lab = |c: &[[f32; 3]]| -> [Vec<f32>; 3] {
        let l: Vec<[f32; 3]> = c.iter().map(|&x| srgb_to_lab(x)).collect();
        [0, 1, 2].map(|k| l.iter().map(|x| x[k]).collect())
    };
    let (o, t) = (lab(out), lab(truth));
    let ht = high_freq_std(adj, &t[0]);
    Scores {
        corr: [0, 1, 2].map(|k| crate::stats::pearson(&o[k], &t[k])),
        w1: (0..3)
            .map(|k| crate::stats::wasserstein1(&o[k], &t[k]))
            .sum::<f64>()
            / 3.0,
        grain: high_freq_std(adj, &o[0]) / ht.max(1e-12),
    }
}

/// k-nearest-neighbour regression of colour on features: every target vertex gets the mean
/// colour of its `k` nearest source vertices in standardised feature space.
pub fn knn_regression(
    src: &FeatureSet,
    src_colors: &[[f32; 3]],
    tgt: &FeatureSet,
    k: usize,
) -> Vec<[f32; 3]> {
    use super::regression::{column_scales, standardised};
    let all: Vec<u32> = (0..src.len() as u32).collect();
    let (mean, scale) = column_scales(src, &all);
    let alike = vec![1.0f32; src.dim];
    let xs = standardised(src, &mean, &scale, &alike);
    let xt = standardised(tgt, &mean, &scale, &alike);
    knn_on(&xs, src_colors, &xt, src.dim, k)
}

/// k-nearest-neighbour regression on given coordinates (`d` per row): the mean colour of the
/// `k` nearest source rows.
pub fn knn_on(
    xs: &[f32],
    src_colors: &[[f32; 3]],
    xt: &[f32],
    d: usize,
    k: usize,
) -> Vec<[f32; 3]> {
    super::regression::knn_mean(&KdTree::new(xs, d), src_colors, xt, d, k, None)
}

/// A source/target pair prepared for [`evaluate`]: the source refined to the working density
/// with its recipe features, the target as given, and the target refined as [`super::run`]
/// refines it, with its recipe features.
pub struct Prepared {
    /// Refined source (no colours).
    pub source: TriMesh,
    /// Recipe features of `source`.
    pub source_features: FeatureSet,
    /// The target as given.
    pub target: TriMesh,
    /// The target at the working density.
    pub target_refined: TriMesh,
    /// Recipe features of `target_refined`.
    pub target_features: FeatureSet,
    /// Up axis.
    pub up: Up,
    /// Working vertices.
    pub vertices: usize,
}

/// Refine both meshes to `vertices` and compute their recipe features.
pub fn prepare(
    source: &TriMesh,
    target: &TriMesh,
    vertices: usize,
    up: Up,
    cancel: &CancelToken,
) -> Result<Prepared> {
    let rs = refine_to_density(source, vertices).mesh;
    let rt = refine_to_density(target, vertices).mesh;
    let (fs, ft) = rayon::join(
        || recipe_features(&rs, up, cancel),
        || recipe_features(&rt, up, cancel),
    );
    Ok(Prepared {
        source: rs,
        source_features: fs?,
        target: target.clone(),
        target_refined: rt,
        target_features: ft?,
        up,
        vertices,
    })
}

/// The result of [`evaluate`].
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct Evaluation {
    /// The transfer's scores.
    pub method: Scores,
    /// The k-nearest-neighbour floor's scores.
    pub knn: Scores,
    /// Seconds of [`super::run`].
    pub seconds: f64,
    /// Canonical correlations of the run.
    pub correlations: Vec<f64>,
    /// The run's CCA report (which features each component weighs, which were kept).
    #[serde(skip)]
    pub report: super::CcaReport,
    /// The transfer's colours on the refined target (`Prepared::target_refined`).
    #[serde(skip)]
    pub colors: Vec<[f32; 3]>,
}

/// Colour the prepared source by `recipe`, transfer to the target with `params` (its
/// `working_vertices` and `up` are set from the pair) and score against the recipe on the
/// target, with the kNN floor (k = 8) beside.
pub fn evaluate(
    pair: &Prepared,
    recipe: &Recipe,
    params: &Params,
    cancel: &CancelToken,
) -> Result<Evaluation> {
    let src_colors = paint(
        recipe,
        &pair.source_features,
        &pair.source.positions,
        pair.up,
    );
    let truth = paint(
        recipe,
        &pair.target_features,
        &pair.target_refined.positions,
        pair.up,
    );
    let mut source = pair.source.clone();
    source.colors = Some(src_colors.clone());
    let params = Params {
        working_vertices: pair.vertices,
        up: pair.up,
        ..params.clone()
    };
    let clock = crate::work::Stopwatch::start();
    let out = super::run(
        &super::Input {
            source: &source,
            target: &pair.target,
            source_mask: None,
        },
        &params,
        &|_| {},
        cancel,
    )?;
    let seconds = clock.secs();
    if out.target.mesh.num_vertices() != pair.target_refined.num_vertices() {
        return Err(Error::InvalidInput(
            "the transfer refined the target differently".into(),
        ));
    }
    let adj = pair.target_refined.adjacency();
    let knn = knn_regression(&pair.source_features, &src_colors, &pair.target_features, 8);
    Ok(Evaluation {
        method: score(&out.colors, &truth, &adj),
        knn: score(&knn, &truth, &adj),
        seconds,
        correlations: out.report.correlations.clone(),
        report: out.report,
        colors: out.colors,
    })
}

/// Where a recipe is lost, by k-nearest-neighbour regression (k = 8) on each stage's
/// coordinates, scored against the truth on the target: `[all features, CCA guidance (d dims),
/// CCA guidance after the PDF transfer of the target's onto the source's]`.
pub fn diagnose(pair: &Prepared, recipe: &Recipe, d: usize) -> Result<[Scores; 3]> {
    use crate::stats::{PdfTransferParams, cca, pdf_transfer};
    let src_colors = paint(
        recipe,
        &pair.source_features,
        &pair.source.positions,
        pair.up,
    );
    let truth = paint(
        recipe,
        &pair.target_features,
        &pair.target_refined.positions,
        pair.up,
    );
    let adj = pair.target_refined.adjacency();
    let fs = &pair.source_features;
    let ft = &pair.target_features;
    let all = knn_regression(fs, &src_colors, ft, 8);
    let y: Vec<f32> = src_colors.iter().flatten().copied().collect();
    let model = cca(&fs.values, fs.dim, &y, 3, d, 1e-6)?;
    let gs = model.project_x(&fs.values);
    let mut gt = model.project_x(&ft.values);
    let raw = knn_on(&gs, &src_colors, &gt, model.d, 8);
    pdf_transfer(
        &mut gt,
        &gs,
        model.d,
        &PdfTransferParams {
            iterations: 20,
            tolerance: 0.01,
            seed: 7,
        },
    );
    let matched = knn_on(&gs, &src_colors, &gt, model.d, 8);
    Ok([
        score(&all, &truth, &adj),
        score(&raw, &truth, &adj),
        score(&matched, &truth, &adj),
    ])
}
