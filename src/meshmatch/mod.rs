//! MeshMatch texture transfer (Chen, Chen, Vouga, Kilgard, Fussell & Huang 2012, "Non-parametric
//! texture transfer using MeshMatch"): a nearest-neighbour field from target patches to source
//! patches (source vertex + rotation) found by PatchMatch-style propagation and random search over
//! shape features and geodesic colour fans, refined coarse-to-fine with Gaussian voting.
//!
//! Pipeline: [`prepare`] each mesh once (weld, refine to the working density with provenance,
//! hierarchy, tangent frames, HKS shape features, source colour fans), then [`solve`] for a set of
//! correspondences (cheap to repeat after edits), then deliver: [`TransferResult::file_signal`]
//! for the target's own vertices and [`bake_texture`] for its UV layout.
//!
//! One file per stage, each with one front door:
//! - [`prepare`] (`prepare.rs`): [`PreparedMesh`], built once per mesh and parameters;
//! - [`solve`] / [`solve_constrained`] (`solve.rs`): the coarse-to-fine EM driver, in named
//!   steps; `affinities.rs` computes the correspondence affinities it uses (§3.2), `em.rs` the
//!   E- and M-steps (§4);
//! - [`deliver`] (`deliver.rs`): colours on the file's vertices, baking into UVs, the dense mesh.

mod affinities;
mod coincident;
mod deliver;
mod em;
mod global_map;
mod nonrigid;
mod patch_map;
mod prepare;
mod resample;
mod solve;
mod working;

use crate::error::{Error, Result};
use crate::mesh::{SignalKind, TriMesh};
use crate::work::{CancelToken, Event};

pub use deliver::{BakeLayout, Delivered, bake_texture, deliver, deliver_dense};
pub use global_map::{POINT_MAP_VERTICES, PointMap, map_meshes};
pub(crate) use prepare::check_working_memory;
pub use prepare::{PreparedMesh, prepare, prepare_pair};
pub use resample::Resampler;
pub use solve::{solve, solve_constrained};
pub use working::WORKING_VERTEX_BYTES;

/// Parameters of a MeshMatch transfer.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default)]
pub struct TransferParams {
    /// Working vertex count: meshes with fewer vertices are refined up to it (paper: 64K).
    pub vertices: usize,
    /// Number of hierarchy levels; `None` = down to about 128 vertices.
    pub levels: Option<usize>,
    /// EM iterations per level at most (paper: 5).
    pub iterations: usize,
    /// A level stops iterating once one EM iteration lowers its mean patch distance by less than
    /// this fraction (0 = always run every one of `iterations`). From the second level down,
    /// upsampling starts each level near its optimum: at 64K one iteration brings the energy
    /// within 0.3% of where five leave it, so the default 0.005 usually stops after two.
    pub tolerance: f32,
    /// Random seed; results are deterministic for a given seed.
    pub seed: u64,
    /// Weight of the shape features relative to the colour fans (1 = equal after normalisation)
    /// at the coarsest level.
    pub shape_weight: f32,
    /// The finest level's shape weight as a fraction of `shape_weight`, geometric in between
    /// (MeshMatch §3.3 allows a lower shape weight at finer levels): coarse levels follow the
    /// shape and the correspondences to lay the texture out, fine levels follow the colour so
    /// small features (patches, stripes) keep their contrast. 1 = the same weight everywhere.
    pub fine_shape_scale: f32,
    /// Final nearest-neighbour copy at the finest level instead of the filtered vote.
    pub sharpen: bool,
    /// Fan radius in mean edge lengths of each level.
    pub fan_radius: f32,
    /// Benchmark diagnostic: target vertices of the finest level whose exact nearest neighbour
    /// (all source vertices x all rotations) is found by brute force after the solve (0 = off).
    pub exact_samples: usize,
    /// How closely the transfer keeps the source's layout, through a global intrinsic shape map
    /// (functional maps + ZoomOut, the correspondences as landmarks): `Some(0.0)` = pure
    /// patch-based synthesis (cross-shape stylisation, no map computed), `Some(1.0)` = follow the
    /// map at every level; in between the map leads the coarse levels and the colour the fine
    /// ones ([`structure_weights`]). `None` = automatic: the map is computed and
    /// [`auto_structure`] picks the value from how close it is to an isometry, so similar shapes
    /// (two bodies, an edited scan) keep the layout and dissimilar ones are synthesised as
    /// before. When the map cannot be computed (several components, a tiny mesh) the solve runs
    /// without it and [`TransferResult::notices`] says why.
    pub structure: Option<f32>,
}

impl Default for TransferParams {
    fn default() -> Self {
        TransferParams {
            vertices: 64_000,
            levels: None,
            iterations: 5,
            tolerance: DEFAULT_TOLERANCE,
            seed: 0,
            shape_weight: 1.0,
            fine_shape_scale: FINE_SHAPE_SCALE,
            sharpen: true,
            fan_radius: 2.5,
            exact_samples: 0,
            structure: None,
        }
    }
}

/// Default [`TransferParams::tolerance`]: a level stops once an iteration gains less than 0.5%.
pub const DEFAULT_TOLERANCE: f32 = 0.005;

/// Most EM iterations per level accepted ([`TransferParams::validate`]); the paper uses 5.
pub const MAX_ITERATIONS: usize = 1000;

/// Most hierarchy levels accepted ([`TransferParams::validate`]); halving from the working
/// budget reaches about 128 vertices in 15 levels.
pub const MAX_LEVELS: usize = 16;

impl TransferParams {
    /// Refuse parameters no transfer can honour, before any work: `vertices` above the working
    /// budget ([`crate::mesh::MAX_WORKING_VERTICES`]), `iterations` above [`MAX_ITERATIONS`],
    /// `levels` outside 1..=[`MAX_LEVELS`], a negative or non-finite `shape_weight`, a
    /// `fine_shape_scale` or `fan_radius` that is not positive and finite.
    pub fn validate(&self) -> Result<()> {
        let bad = |msg: String| Err(Error::InvalidInput(msg));
        let max_v = crate::mesh::MAX_WORKING_VERTICES;
        if self.vertices > max_v {
            return bad(format!(
                "--vertices {}: the working resolution is at most {max_v} vertices",
                self.vertices
            ));
        }
        if self.iterations > MAX_ITERATIONS {
            return bad(format!(
                "--iterations {}: use 0 to {MAX_ITERATIONS} iterations per level",
                self.iterations
            ));
        }
        if let Some(l) = self.levels
            && !(1..=MAX_LEVELS).contains(&l)
        {
            return bad(format!("--levels {l}: use 1 to {MAX_LEVELS} levels"));
        }
        if !(self.shape_weight.is_finite() && self.shape_weight >= 0.0) {
            return bad(format!(
                "--shape-weight {}: must be a finite number, 0 or more",
                self.shape_weight
            ));
        }
        if !(self.fine_shape_scale.is_finite() && self.fine_shape_scale > 0.0) {
            return bad(format!(
                "--fine-shape-scale {}: must be a positive finite number",
                self.fine_shape_scale
            ));
        }
        if !(self.tolerance.is_finite() && (0.0..1.0).contains(&self.tolerance)) {
            return bad(format!(
                "--tolerance {}: use a fraction from 0 (run every iteration) up to, not including, 1",
                self.tolerance
            ));
        }
        if !(self.fan_radius.is_finite() && self.fan_radius > 0.0) {
            return bad(format!(
                "fan radius {}: must be a positive finite number",
                self.fan_radius
            ));
        }
        if let Some(x) = self.structure
            && !(0.0..=1.0).contains(&x)
        {
            return bad(format!(
                "--structure {x}: use a number from 0 (pure synthesis) to 1 (follow the map), or auto"
            ));
        }
        if self.exact_samples > crate::mesh::MAX_WORKING_VERTICES {
            return bad(format!("exact samples {}: too many", self.exact_samples));
        }
        Ok(())
    }
}

/// Default [`TransferParams::fine_shape_scale`]: the same shape weight on every level. At 0.3
/// Spot -> horse (no correspondences) keeps more of Spot's black patches, but the zebra ->
/// giraffe neck stripes lose their regular rings, so the default leaves it to the user.
pub const FINE_SHAPE_SCALE: f32 = 1.0;

/// Map weights for a structure value `s` in `(0, 1]`: (coarsest-level weight, finest level's
/// fraction of it), geometric in between; log-linear in `s`, `(2, 0.05)` at `s = 0.5` and
/// `(32, 1)` at `s = 1` (the map dominates every level). The weight is relative to the automatic
/// shape features, both at unit variance.
pub fn structure_weights(s: f32) -> (f32, f32) {
    let s = s.clamp(0.0, 1.0);
    (2.0 * 16f32.powf(2.0 * s - 1.0), 0.05f32.powf(2.0 - 2.0 * s))
}

/// The automatic structure value from a map's isometry score ([`crate::geometry::MapQuality`]):
/// 0 up to [`AUTO_SCORE_MIN`] (dissimilar shapes: synthesis as without the map), rising linearly
/// to 1 (follow the map) at [`AUTO_SCORE_FULL`] and above.
pub fn auto_structure(score: f64) -> f32 {
    if score.is_nan() || score <= AUTO_SCORE_MIN {
        return 0.0;
    }
    ((score - AUTO_SCORE_MIN) / (AUTO_SCORE_FULL - AUTO_SCORE_MIN)).clamp(0.0, 1.0) as f32
}

/// Isometry score up to which the automatic structure is 0 (Spot -> horse scores 0.37; the map
/// lowers its patch coherence).
pub const AUTO_SCORE_MIN: f64 = 0.4;
/// Isometry score from which the automatic structure is 1. Measured (`examples/structure_eval`,
/// 20K vertices): Spot bent scores 0.76 and lands colours best at 1 (dE 2.08 against 2.21 at
/// 0.66); zebra -> giraffe (0.64, auto 0.69) has better patch coherence at 1 than at 0, and
/// zebra -> cerberus (0.54, auto 0.41) gets the regular torso stripes that 0.1 missed.
pub const AUTO_SCORE_FULL: f64 = 0.75;

/// Shape weight of level `l` of `nl` (0 = finest): `shape_weight` at the coarsest level,
/// `shape_weight * fine_shape_scale` at the finest, geometric in between.
pub fn level_shape_weight(params: &TransferParams, l: usize, nl: usize) -> f32 {
    let scale = if params.fine_shape_scale.is_finite() && params.fine_shape_scale > 0.0 {
        params.fine_shape_scale
    } else {
        1.0
    };
    let t = if nl > 1 {
        1.0 - l as f32 / (nl - 1) as f32
    } else {
        1.0
    };
    params.shape_weight * scale.powf(t)
}

#[derive(Clone, Debug, Default)]
pub struct TransferResult {
    /// Synthesised sRGB signal on the target's working mesh.
    pub working_signal: Vec<[f32; 3]>,
    /// NNF on the working mesh: source working vertex and rotation index (20° steps).
    pub nnf: Vec<(u32, u8)>,
    /// Signal in the target file's vertex order (length = file vertex count).
    pub file_signal: Vec<[f32; 3]>,
    /// Per target file vertex: source file vertex and rotation in degrees.
    pub file_nnf: Vec<(u32, f32)>,
    /// Stage timings (seconds).
    pub timings: Vec<(String, f64)>,
    /// EM iterations (E-steps) run on each level, finest first: at most
    /// [`TransferParams::iterations`], fewer where the level converged
    /// ([`TransferParams::tolerance`]).
    pub iterations: Vec<usize>,
    /// Final energy: mean patch distance of the NNF.
    pub energy: f64,
    /// The exact-search comparison, when `exact_samples` asked for one.
    pub exact: Option<ExactCheck>,
    /// One-line notices for the user (e.g. why the global map was not used).
    pub notices: Vec<String>,
    /// The structure value used (after `auto`), and the map's isometry score when a map was
    /// computed.
    pub structure: f32,
    pub map_score: Option<f64>,
}

/// MeshMatch's final NNF against exhaustive search on a sample of finest-level target vertices.
#[derive(Clone, Debug)]
pub struct ExactCheck {
    /// Target vertices compared.
    pub samples: usize,
    /// Mean patch distance of MeshMatch's NNF on the sample.
    pub meshmatch_energy: f64,
    /// Mean exact nearest-neighbour patch distance on the sample.
    pub exact_energy: f64,
    /// Exhaustive search time extrapolated to every finest-level target vertex, seconds.
    pub exact_seconds: f64,
    /// The whole solve's time, seconds.
    pub meshmatch_seconds: f64,
    /// Patch coherence of the result: mean colour-fan distance (no shape terms) of each sampled
    /// target vertex to its nearest source patch over every source vertex and rotation, in the
    /// level's colour weighting. Lower = the target is made of source patches more faithfully.
    pub coherence: f64,
    /// Wall time of this check (both exhaustive searches over the sample), seconds: a
    /// diagnostic, not part of a transfer (`exact_samples` is 0 by default).
    pub check_seconds: f64,
}

/// Extra constraints on the target: vertices whose signal is fixed (paint-by-example masks and
/// locked regions for texture updates), in working-vertex indices.
#[derive(Clone, Debug, Default)]
pub struct Constraints {
    /// (target working vertex, fixed sRGB signal).
    pub fixed: Vec<(u32, [f32; 3])>,
}

/// Prepare both meshes and solve ([`prepare`] + [`solve`]).
pub fn transfer(
    source: &TriMesh,
    target: &TriMesh,
    corr: &[crate::correspondence::Correspondence],
    params: &TransferParams,
    sink: &dyn Fn(Event),
    cancel: &CancelToken,
) -> Result<TransferResult> {
    if source.signal_kind() == SignalKind::None {
        return Err(Error::InvalidInput(
            "the source mesh has no signal (vertex colours or a texture) to transfer".into(),
        ));
    }
    let (ps, pt) = prepare_pair(source, params, target, params, sink, cancel)?;
    let mut r = solve(&ps, &pt, corr, params, sink, cancel)?;
    let mut t: Vec<(String, f64)> = ps
        .timings()
        .iter()
        .map(|(n, s)| (format!("source {n}"), *s))
        .chain(
            pt.timings()
                .iter()
                .map(|(n, s)| (format!("target {n}"), *s)),
        )
        .collect();
    t.append(&mut r.timings);
    r.timings = t;
    Ok(r)
}
