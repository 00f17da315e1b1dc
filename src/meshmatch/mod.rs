//! MeshMatch texture transfer (Chen, Chen, Vouga, Kilgard, Fussell & Huang 2012, "Non-parametric
//! texture transfer using MeshMatch"): a nearest-neighbour field from target patches to source
//! patches (source vertex + rotation) found by PatchMatch-style propagation and random search over
//! shape features and geodesic colour fans, refined coarse-to-fine with Gaussian voting.
//!
//! Pipeline: [`prepare`] each mesh once (weld, refine to the working density with provenance,
//! hierarchy, tangent frames, HKS shape features, source colour fans), then [`solve`] for a set of
//! correspondences (cheap to repeat after edits), then deliver: [`TransferResult::file_signal`]
//! for the target's own vertices and [`bake_texture`] for its UV layout.

mod em;

use crate::features::{
    self, FAN_ANGLES, FanSampler, Frames, SHAPE_DIM, edge_geodesics, edge_transport_angles,
    min_norm_affine, tangent_frames,
};
use crate::hierarchy::{Hierarchy, HierarchyOptions};
use crate::jobs::{self, CancelToken, Event, Progress, Stopwatch};
use crate::mesh::{SignalKind, TriMesh, sample_texture};
use crate::{Error, Result};
use em::{C, Ctx, PER, Side};
use glam::Vec3;
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};
use rayon::prelude::*;
use std::sync::Arc;

/// Parameters of a MeshMatch transfer.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default)]
pub struct TransferParams {
    /// Working vertex count: meshes with fewer vertices are refined up to it (paper: 64K).
    pub vertices: usize,
    /// Number of hierarchy levels; `None` = down to about 128 vertices.
    pub levels: Option<usize>,
    /// EM iterations per level (paper: 5).
    pub iterations: usize,
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
}

impl Default for TransferParams {
    fn default() -> Self {
        TransferParams {
            vertices: 64_000,
            levels: None,
            iterations: 5,
            seed: 0,
            shape_weight: 1.0,
            fine_shape_scale: FINE_SHAPE_SCALE,
            sharpen: true,
            fan_radius: 2.5,
            exact_samples: 0,
        }
    }
}

/// Default [`TransferParams::fine_shape_scale`]: the same shape weight on every level. At 0.3
/// Spot -> horse (no correspondences) keeps more of Spot's black patches, but the zebra ->
/// giraffe neck stripes lose their regular rings, so the default leaves it to the user.
pub const FINE_SHAPE_SCALE: f32 = 1.0;

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

/// Working vertex count up to which a target keeps its fan sampling tables between solves.
const KEEP_SAMPLERS_UP_TO: usize = 300_000;

/// A mesh made ready for MeshMatch: the working mesh (welded + refined), its hierarchy, frames,
/// shape features and, when it carries a signal, per-level signals and colour fans. Reusable
/// across correspondence edits.
#[derive(Clone, Debug)]
pub struct PreparedMesh {
    working: TriMesh,
    working_to_file: Vec<u32>,
    file_to_working: Vec<u32>,
    /// Where the working faces lie in the input faces (built once, shared with every result).
    layout: Arc<BakeLayout>,
    hierarchy: Hierarchy,
    frames: Vec<Frames>,
    edge_angles: Vec<Vec<f32>>,
    shape: Vec<Vec<f32>>,
    signal: Option<Vec<Vec<[f32; 3]>>>,
    fans: Option<Vec<Vec<f32>>>,
    /// Fan sampling tables per level (built once; reused by every solve on this mesh).
    samplers: Vec<FanSampler>,
    fan_radius: f32,
    timings: Vec<(String, f64)>,
}

impl PreparedMesh {
    /// The working mesh (welded and refined; per-vertex colours when it has a signal).
    pub fn working_mesh(&self) -> &TriMesh {
        &self.working
    }
    /// Nearest file vertex of every working vertex.
    pub fn working_to_file(&self) -> &[u32] {
        &self.working_to_file
    }
    /// Working vertex of every file vertex (length = the file's vertex count).
    pub fn file_to_working(&self) -> &[u32] {
        &self.file_to_working
    }
    /// The multiresolution hierarchy (level 0 = working mesh).
    pub fn hierarchy(&self) -> &Hierarchy {
        &self.hierarchy
    }
    /// Per-vertex signal of the working mesh, if the mesh carries one.
    pub fn signal(&self) -> Option<&[[f32; 3]]> {
        self.signal.as_ref().map(|s| s[0].as_slice())
    }
    /// Stage timings of the preparation (seconds).
    pub fn timings(&self) -> &[(String, f64)] {
        &self.timings
    }
}

/// Result of a transfer.
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
    /// Final energy: mean patch distance of the NNF.
    pub energy: f64,
    /// The exact-search comparison, when `exact_samples` asked for one.
    pub exact: Option<ExactCheck>,
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
}

/// Extra constraints on the target: vertices whose signal is fixed (paint-by-example masks and
/// locked regions for texture updates), in working-vertex indices.
#[derive(Clone, Debug, Default)]
pub struct Constraints {
    /// (target working vertex, fixed sRGB signal).
    pub fixed: Vec<(u32, [f32; 3])>,
}

fn progress(stage: &'static str, watch: &Stopwatch, fraction: f32) -> Progress {
    Progress {
        stage,
        elapsed: watch.secs(),
        fraction,
        ..Default::default()
    }
}

/// Prepare a mesh for MeshMatch: weld, refine to `params.vertices` by longest-edge bisection
/// (signal sampled from the texture/colours at every new vertex), build the hierarchy (§3), tangent
/// frames, HKS + normal·up shape features and, with a signal, per-level signals (children means)
/// and geodesic colour fans.
pub fn prepare(
    mesh: &TriMesh,
    params: &TransferParams,
    sink: &dyn Fn(Event),
    cancel: &CancelToken,
) -> Result<PreparedMesh> {
    if mesh.positions.is_empty() || mesh.faces.is_empty() {
        return Err(Error::InvalidMesh(
            "mesh has no vertices or no faces".into(),
        ));
    }
    if params.fan_radius.is_nan() || params.fan_radius <= 0.0 {
        return Err(Error::InvalidInput("fan_radius must be positive".into()));
    }
    let watch = Stopwatch::start();
    let mut timings = Vec::new();
    let stage = |name: &'static str, t: f64, timings: &mut Vec<(String, f64)>| {
        sink(Event::StageTime(name, t));
        timings.push((name.to_string(), t));
    };
    sink(Event::Progress(progress("refine", &watch, 0.0)));
    let sw = Stopwatch::start();
    let (welded, map) = crate::geometry::weld(mesh);
    if welded.faces.is_empty() {
        return Err(Error::InvalidMesh(
            "mesh has no non-degenerate faces".into(),
        ));
    }
    // Input face of every welded face (weld drops out-of-range and degenerate faces in order).
    let nin = mesh.positions.len();
    let welded_to_input: Vec<u32> = mesh
        .faces
        .iter()
        .enumerate()
        .filter(|(_, f)| {
            if f.iter().any(|&v| v as usize >= nin) {
                return false;
            }
            let w = f.map(|v| map[v as usize]);
            w[0] != w[1] && w[1] != w[2] && w[0] != w[2]
        })
        .map(|(i, _)| i as u32)
        .collect();
    // Refine the bare welded surface (the signal is sampled below from the input itself).
    let bare = TriMesh::new(welded.positions.clone(), welded.faces.clone());
    let r = crate::geometry::refine_to_density(&bare, params.vertices);
    drop(bare);
    let vert_src: Vec<(u32, [f32; 3])> = r
        .vertex_sources()
        .into_iter()
        .map(|(f, b)| if f == u32::MAX { (0, b) } else { (f, b) })
        .collect();
    cancel.check()?;
    let nw = welded.positions.len();
    // Per working vertex signal.
    let signal0: Option<Vec<[f32; 3]>> = match mesh.signal_kind() {
        SignalKind::None => None,
        kind => {
            let base = mesh.vertex_signal();
            let mut sig = vec![[0.0f32; 3]; r.mesh.positions.len()];
            if let Some(base) = base {
                for (i, &w) in map.iter().enumerate() {
                    sig[w as usize] = base[i];
                }
            }
            for (v, slot) in sig.iter_mut().enumerate().skip(nw) {
                let (wf, b) = vert_src[v];
                let f = welded_to_input[wf as usize] as usize;
                *slot = match kind {
                    SignalKind::Texture => {
                        let (tex, uvs) = (
                            mesh.texture.as_ref().expect("texture"),
                            mesh.uvs.as_ref().expect("uvs"),
                        );
                        let uv = (0..3).fold([0.0f32; 2], |a, k| {
                            let u = uvs[3 * f + k];
                            [a[0] + b[k] * u[0], a[1] + b[k] * u[1]]
                        });
                        sample_texture(tex, uv)
                    }
                    _ => {
                        let cols = mesh.colors.as_ref().expect("colours");
                        let fc = mesh.faces[f];
                        (0..3).fold([0.0f32; 3], |a, k| {
                            let c = cols[fc[k] as usize];
                            [a[0] + b[k] * c[0], a[1] + b[k] * c[1], a[2] + b[k] * c[2]]
                        })
                    }
                };
            }
            Some(sig)
        }
    };
    // File maps. Welded vertex -> one input vertex; working vertex -> nearest input corner.
    let mut welded_first = vec![u32::MAX; nw];
    for (i, &w) in map.iter().enumerate() {
        if welded_first[w as usize] == u32::MAX {
            welded_first[w as usize] = i as u32;
        }
    }
    let file_of_input = |i: u32| mesh.file_index.get(i as usize).copied().unwrap_or(i);
    let working_to_file: Vec<u32> = (0..r.mesh.positions.len())
        .map(|v| {
            let wv = if v < nw {
                v as u32
            } else {
                let (wf, b) = vert_src[v];
                let k = (0..3).max_by(|&a, &c| b[a].total_cmp(&b[c])).unwrap_or(0);
                welded.faces[wf as usize][k]
            };
            file_of_input(welded_first[wv as usize])
        })
        .collect();
    let mut file_to_working = vec![0u32; mesh.file_vertex_count.max(mesh.positions.len())];
    file_to_working.truncate(mesh.file_vertex_count.max(1));
    for (i, &w) in map.iter().enumerate() {
        if let Some(slot) = file_to_working.get_mut(file_of_input(i as u32) as usize) {
            *slot = w;
        }
    }
    let face_input: Vec<u32> = r
        .source_face
        .iter()
        .map(|&f| welded_to_input[f as usize])
        .collect();
    let mut working = TriMesh::new(r.mesh.positions, r.mesh.faces);
    working.colors = signal0.clone();
    stage("refine", sw.secs(), &mut timings);

    sink(Event::Progress(progress("hierarchy", &watch, 0.2)));
    let sw = Stopwatch::start();
    let hierarchy = Hierarchy::build_cancellable(
        &working.positions,
        &working.faces,
        HierarchyOptions {
            min_vertices: 128,
            max_levels: params.levels,
        },
        cancel,
    )?;
    let frames: Vec<Frames> = hierarchy
        .levels
        .iter()
        .map(|l| tangent_frames(&l.normals))
        .collect();
    let edge_angles: Vec<Vec<f32>> = hierarchy
        .levels
        .iter()
        .zip(&frames)
        .map(|(l, f)| edge_transport_angles(l, f))
        .collect();
    stage("hierarchy", sw.secs(), &mut timings);
    cancel.check()?;

    sink(Event::Progress(progress("features", &watch, 0.5)));
    let sw = Stopwatch::start();
    let shape = features::shape_features_cancellable(&hierarchy, 2000, cancel)?;
    stage("features", sw.secs(), &mut timings);
    cancel.check()?;

    // Fan sampling tables of every level. A mesh with a signal builds each level's table, takes
    // its fans and drops it. A mesh without one (a target) keeps them, so a correspondence edit
    // only re-runs the solve; very large targets rebuild them level by level in the solve
    // instead of holding ~2 KB per vertex.
    sink(Event::Progress(progress("fans", &watch, 0.6)));
    let sw = Stopwatch::start();
    let table = |l: usize| {
        let lev = &hierarchy.levels[l];
        FanSampler::new_cancellable(lev, &frames[l], params.fan_radius * lev.mean_edge, cancel)
    };
    let mut samplers = Vec::new();
    let (signal, fans) = if let Some(s0) = signal0 {
        let mut sig = vec![s0];
        for l in 1..hierarchy.num_levels() {
            let prev = &sig[l - 1];
            let cur: Vec<[f32; 3]> = (0..hierarchy.levels[l].len())
                .map(|p| {
                    let ch = hierarchy.children(l, p as u32);
                    let mut a = Vec3::ZERO;
                    for &c in ch {
                        a += Vec3::from(prev[c as usize]);
                    }
                    (a / ch.len().max(1) as f32).to_array()
                })
                .collect();
            sig.push(cur);
        }
        let mut fans = Vec::with_capacity(sig.len());
        for (l, s) in sig.iter().enumerate() {
            cancel.check()?;
            fans.push(table(l)?.fans(&hierarchy.levels[l], s.as_flattened(), C));
        }
        (Some(sig), Some(fans))
    } else {
        if working.num_vertices() <= KEEP_SAMPLERS_UP_TO {
            for l in 0..hierarchy.num_levels() {
                cancel.check()?;
                samplers.push(table(l)?);
            }
        }
        (None, None)
    };
    stage("fans", sw.secs(), &mut timings);
    sink(Event::Progress(progress("prepare", &watch, 1.0)));
    let layout = Arc::new(BakeLayout {
        working_faces: working.faces.clone(),
        working_vertices: working.positions.len(),
        face_input,
        face_bary: r.source_bary,
        input_faces: mesh.faces.len(),
    });
    Ok(PreparedMesh {
        working,
        working_to_file,
        file_to_working,
        layout,
        hierarchy,
        frames,
        edge_angles,
        shape,
        signal,
        fans,
        samplers,
        fan_radius: params.fan_radius,
        timings,
    })
}

/// Per-dimension standard deviations of `dim`-vectors pooled over two arrays.
fn pooled_std(a: &[f32], b: &[f32], dim: usize) -> Vec<f32> {
    let n = (a.len() + b.len()) / dim.max(1);
    let mut mean = vec![0.0f64; dim];
    for x in a.chunks(dim).chain(b.chunks(dim)) {
        for k in 0..dim {
            mean[k] += x[k] as f64;
        }
    }
    for m in mean.iter_mut() {
        *m /= n.max(1) as f64;
    }
    let mut var = vec![0.0f64; dim];
    for x in a.chunks(dim).chain(b.chunks(dim)) {
        for k in 0..dim {
            var[k] += (x[k] as f64 - mean[k]).powi(2);
        }
    }
    var.iter()
        .map(|v| ((v / n.max(1) as f64).sqrt() as f32).max(1e-6))
        .collect()
}

/// Build the weighted shape vectors of one level for both meshes: the automatic group (HKS +
/// normal·up) and, with correspondences, the affinity group; each group divided by its
/// per-dimension standard deviation (pooled over both meshes) and sqrt(its dimension), times
/// sqrt(shape_weight), so squared L2 distances weigh each group like the colour fans.
fn weighted_shape(
    s_auto: &[f32],
    t_auto: &[f32],
    s_aff: &[f32],
    t_aff: &[f32],
    k: usize,
    shape_weight: f32,
) -> (Vec<f32>, Vec<f32>, usize) {
    let dsh = SHAPE_DIM + k;
    let sd_a = pooled_std(s_auto, t_auto, SHAPE_DIM);
    let sd_b = if k > 0 {
        pooled_std(s_aff, t_aff, k)
    } else {
        Vec::new()
    };
    let w = shape_weight.max(0.0).sqrt();
    let build = |auto: &[f32], aff: &[f32]| -> Vec<f32> {
        let n = auto.len() / SHAPE_DIM;
        let mut out = Vec::with_capacity(n * dsh);
        for v in 0..n {
            for d in 0..SHAPE_DIM {
                out.push(w * auto[v * SHAPE_DIM + d] / (sd_a[d] * (SHAPE_DIM as f32).sqrt()));
            }
            for d in 0..k {
                out.push(w * aff[v * k + d] / (sd_b[d] * (k as f32).sqrt()));
            }
        }
        out
    };
    (build(s_auto, s_aff), build(t_auto, t_aff), dsh)
}

/// Carry per-vertex `dim`-vectors from level 0 up the hierarchy (mean of children).
fn to_levels(h: &Hierarchy, base: Vec<f32>, dim: usize) -> Vec<Vec<f32>> {
    let mut out = vec![base];
    for l in 1..h.num_levels() {
        let prev = &out[l - 1];
        let n = h.levels[l].len();
        let mut cur = vec![0.0f32; n * dim];
        for p in 0..n {
            let ch = h.children(l, p as u32);
            for &c in ch {
                for d in 0..dim {
                    cur[p * dim + d] += prev[c as usize * dim + d];
                }
            }
            for d in 0..dim {
                cur[p * dim + d] /= ch.len().max(1) as f32;
            }
        }
        out.push(cur);
    }
    out
}

/// Largest level on which correspondence geodesics are computed.
const GEODESIC_LEVEL_VERTICES: usize = 8_000;

/// Geodesic distance from every finest-level vertex to each of `sets` (finest-level vertex
/// sets): the heat method (Crane et al. 2013, `geometry::HeatGeodesics`) on the first hierarchy
/// level with at most [`GEODESIC_LEVEL_VERTICES`] vertices, carried to the finest level through
/// the vertex tree (affinities are smooth at the scale of σ = max distance / 3). Falls back to
/// edge-graph Dijkstra on the finest level if the heat method cannot factor the level.
fn geodesics(h: &Hierarchy, sets: &[Vec<u32>]) -> Vec<Vec<f32>> {
    let l = (0..h.num_levels())
        .find(|&l| h.levels[l].len() <= GEODESIC_LEVEL_VERTICES)
        .unwrap_or(h.num_levels() - 1);
    let lev = &h.levels[l];
    match crate::geometry::HeatGeodesics::new(&lev.positions, &lev.faces) {
        Ok(heat) => {
            let map = h.ancestor_map(0, l);
            let coarse: Vec<Vec<u32>> = sets
                .iter()
                .map(|s| s.iter().map(|&v| map[v as usize]).collect())
                .collect();
            heat.distances(&coarse)
                .into_iter()
                .map(|d| map.iter().map(|&a| d[a as usize] as f32).collect())
                .collect()
        }
        Err(_) => sets
            .par_iter()
            .map(|s| edge_geodesics(&h.levels[0], s))
            .collect(),
    }
}

/// Correspondence affinities (MeshMatch §3.2): geodesic distances ([`geodesics`]) to each constrained point (a
/// one-to-many target point set is one multi-source), target distances mapped by the affine map of
/// [`min_norm_affine`], then G'(v) = exp(-G(v)² / (2σ²)) with σ = (max source geodesic distance)
/// / 3. We square the distance: the paper's printed exp(-G/(2σ²)) mixes units (length over length²)
/// and is not a Gaussian; with the square, the affinity is a Gaussian RBF of width σ in the
/// (mapped) distance, scale-free and equal to 1 at the constraint.
fn affinities(
    source: &PreparedMesh,
    target: &PreparedMesh,
    pairs: &[(u32, Vec<u32>)],
) -> (Vec<f32>, Vec<f32>) {
    let k = pairs.len();
    let (ls, lt) = (&source.hierarchy.levels[0], &target.hierarchy.levels[0]);
    let src_sets: Vec<Vec<u32>> = pairs.iter().map(|(s, _)| vec![*s]).collect();
    let tgt_sets: Vec<Vec<u32>> = pairs.iter().map(|(_, t)| t.clone()).collect();
    let gs = geodesics(&source.hierarchy, &src_sets);
    let gt = geodesics(&target.hierarchy, &tgt_sets);
    let row = |g: &[Vec<f32>], v: u32| -> Vec<f32> { g.iter().map(|d| d[v as usize]).collect() };
    let mut trows = Vec::new();
    let mut srows = Vec::new();
    for (s, ts) in pairs {
        for &t in ts {
            trows.push(row(&gt, t));
            srows.push(row(&gs, *s));
        }
    }
    let m = min_norm_affine(&trows, &srows, k);
    let maxd = gs
        .iter()
        .flat_map(|d| d.iter().copied())
        .filter(|d| d.is_finite())
        .fold(0.0f32, f32::max);
    let sigma = (maxd / 3.0).max(1e-12);
    let inv = 1.0 / (2.0 * sigma * sigma);
    let ns = ls.len();
    let nt = lt.len();
    let mut aff_s = vec![0.0f32; ns * k];
    for v in 0..ns {
        for r in 0..k {
            let d = gs[r][v];
            aff_s[v * k + r] = (-d * d * inv).exp();
        }
    }
    let mut aff_t = vec![0.0f32; nt * k];
    aff_t.par_chunks_mut(k).enumerate().for_each(|(v, out)| {
        for r in 0..k {
            let mut d = m[r * (k + 1) + k];
            for c in 0..k {
                d += m[r * (k + 1) + c] * gt[c][v] as f64;
            }
            let d = d as f32;
            out[r] = (-d * d * inv).exp();
        }
    });
    (aff_s, aff_t)
}

/// Solve for the target's signal given both prepared meshes and correspondences (file indices):
/// coarse-to-fine EM (§4) with exhaustive search on the coarsest level, then per level
/// `params.iterations` rounds of propagation + random search + Gaussian voting, upsampling between
/// levels and the optional nearest-neighbour sharpening at the finest level.
pub fn solve(
    source: &PreparedMesh,
    target: &PreparedMesh,
    corr: &[jobs::Correspondence],
    params: &TransferParams,
    sink: &dyn Fn(Event),
    cancel: &CancelToken,
) -> Result<TransferResult> {
    solve_constrained(
        source,
        target,
        corr,
        &Constraints::default(),
        params,
        sink,
        cancel,
    )
}

/// [`solve`] with fixed target signal (paint-by-example masks, locked vertices for texture
/// updates): fixed vertices keep their signal at every level and in the result.
pub fn solve_constrained(
    source: &PreparedMesh,
    target: &PreparedMesh,
    corr: &[jobs::Correspondence],
    constraints: &Constraints,
    params: &TransferParams,
    sink: &dyn Fn(Event),
    cancel: &CancelToken,
) -> Result<TransferResult> {
    let watch = Stopwatch::start();
    let mut timings: Vec<(String, f64)> = Vec::new();
    let stage = |name: &'static str, t: f64, timings: &mut Vec<(String, f64)>| {
        sink(Event::StageTime(name, t));
        timings.push((name.to_string(), t));
    };
    let (Some(sig_s), Some(fans_s)) = (source.signal.as_ref(), source.fans.as_ref()) else {
        return Err(Error::InvalidInput(
            "the source mesh has no signal (vertex colours or a texture) to transfer".into(),
        ));
    };
    // Correspondences: file indices -> working vertices.
    let mut pairs: Vec<(u32, Vec<u32>)> = Vec::with_capacity(corr.len());
    for c in corr {
        let s = *source
            .file_to_working
            .get(c.source_vertex as usize)
            .ok_or_else(|| {
                Error::InvalidInput(format!(
                    "correspondence source vertex {} is out of range (source has {} vertices)",
                    c.source_vertex,
                    source.file_to_working.len()
                ))
            })?;
        if c.target_vertices.is_empty() {
            return Err(Error::InvalidInput(format!(
                "correspondence for source vertex {} has no target vertex",
                c.source_vertex
            )));
        }
        let mut ts = Vec::with_capacity(c.target_vertices.len());
        for &t in &c.target_vertices {
            ts.push(*target.file_to_working.get(t as usize).ok_or_else(|| {
                Error::InvalidInput(format!(
                    "correspondence target vertex {t} is out of range (target has {} vertices)",
                    target.file_to_working.len()
                ))
            })?);
        }
        pairs.push((s, ts));
    }
    let nt0 = target.working.positions.len();
    for &(v, _) in &constraints.fixed {
        if v as usize >= nt0 {
            return Err(Error::InvalidInput(format!(
                "fixed target vertex {v} is out of range ({nt0} working vertices)"
            )));
        }
    }
    let (hs, ht) = (&source.hierarchy, &target.hierarchy);
    let mut nl = hs.num_levels().min(ht.num_levels());
    if let Some(k) = params.levels {
        nl = nl.min(k.max(1));
    }
    let top = nl - 1;
    // The coarsest level is searched exhaustively when that is cheap (the usual ~128-250
    // vertices); a hierarchy cut short by `levels` starts from the random field instead.
    let exhaustive_top = (hs.levels[top].len() as f64) * (ht.levels[top].len() as f64) <= 4.0e6;

    // Shape features, per level.
    let sw = Stopwatch::start();
    let k = pairs.len();
    let (aff_s, aff_t) = if k > 0 {
        let (a, b) = affinities(source, target, &pairs);
        (to_levels(hs, a, k), to_levels(ht, b, k))
    } else {
        (
            vec![Vec::new(); hs.num_levels()],
            vec![Vec::new(); ht.num_levels()],
        )
    };
    let shapes: Vec<(Vec<f32>, Vec<f32>, usize)> = (0..nl)
        .map(|l| {
            weighted_shape(
                &source.shape[l],
                &target.shape[l],
                &aff_s[l],
                &aff_t[l],
                k,
                level_shape_weight(params, l, nl),
            )
        })
        .collect();
    // Locked NNF entries (correspondences) and fixed signal per level.
    let locked: Vec<Vec<Option<u32>>> = (0..nl)
        .map(|l| {
            let mut lk = vec![None; ht.levels[l].len()];
            for (s, ts) in &pairs {
                let sl = hs.ancestor(0, *s, l);
                for &t in ts {
                    lk[ht.ancestor(0, t, l) as usize] = Some(sl);
                }
            }
            lk
        })
        .collect();
    let fixed: Vec<Vec<Option<[f32; 3]>>> = {
        let mut f0 = vec![None; nt0];
        for &(v, c) in &constraints.fixed {
            f0[v as usize] = Some(c);
        }
        let mut out = vec![f0];
        for l in 1..nl {
            let prev = &out[l - 1];
            let cur: Vec<Option<[f32; 3]>> = (0..ht.levels[l].len())
                .map(|p| {
                    let ch = ht.children(l, p as u32);
                    let mut a = Vec3::ZERO;
                    let mut cnt = 0;
                    for &c in ch {
                        if let Some(x) = prev[c as usize] {
                            a += Vec3::from(x);
                            cnt += 1;
                        }
                    }
                    (2 * cnt >= ch.len() && cnt > 0).then(|| (a / cnt as f32).to_array())
                })
                .collect();
            out.push(cur);
        }
        out
    };
    stage("affinities", sw.secs(), &mut timings);
    cancel.check()?;

    let apply_fixed = |sig: &mut [[f32; 3]], l: usize| {
        for (v, f) in fixed[l].iter().enumerate() {
            if let Some(c) = f {
                sig[v] = *c;
            }
        }
    };
    let total_work: f64 = (0..nl)
        .map(|l| ht.levels[l].len() as f64 * (params.iterations + 1) as f64)
        .sum();
    let mut done_work = 0.0f64;
    let mut nnf: Vec<(u32, u8)> = Vec::new();
    let mut signal: Vec<[f32; 3]> = Vec::new();
    let mut energy = 0.0f64;
    let mut t_search = 0.0;
    let mut t_vote = 0.0;
    // Finest level alone (the per-iteration figures the benchmark reports).
    let (mut t_search0, mut t_vote0, mut t_prop0) = (0.0, 0.0, 0.0);
    let mut t_fans = 0.0;
    let mut exact = None;
    let mut rng = SmallRng::seed_from_u64(params.seed);
    for l in (0..nl).rev() {
        let sw_level = Stopwatch::start();
        let (ls, lt) = (&hs.levels[l], &ht.levels[l]);
        let ratio = ls.mean_edge / lt.mean_edge.max(1e-12);
        let (sh_s, sh_t, dsh) = &shapes[l];
        let side_s = Side {
            level: ls,
            frames: &source.frames[l],
            eang: &source.edge_angles[l],
            shape: sh_s,
            fans: &fans_s[l],
        };
        let var = {
            let f = &fans_s[l];
            let n = (f.len() / C).max(1) as f64;
            let mut m = [0.0f64; C];
            for x in f.chunks(C) {
                for c in 0..C {
                    m[c] += x[c] as f64;
                }
            }
            let mut v = 0.0;
            for x in f.chunks(C) {
                for c in 0..C {
                    v += (x[c] as f64 - m[c] / n).powi(2);
                }
            }
            v / (n * C as f64)
        };
        let wc = if var > 1e-10 {
            (1.0 / (var * PER as f64)) as f32
        } else {
            0.0
        };
        let fan_r = source.fan_radius * lt.mean_edge;
        let sw = Stopwatch::start();
        let built;
        let sampler_t = if target.fan_radius == source.fan_radius && target.samplers.len() > l {
            &target.samplers[l]
        } else {
            built = FanSampler::new_cancellable(lt, &target.frames[l], fan_r, cancel)?;
            &built
        };
        t_fans += sw.secs();
        let mut fans_t = vec![0.0f32; lt.len() * PER];
        let mut dist = vec![0.0f32; lt.len()];
        // Initial NNF of this level.
        if l == top {
            // Random initialisation (respecting constraints), then exhaustive search on shape.
            nnf = (0..lt.len())
                .map(|v| match locked[l][v] {
                    Some(s) => (s, 0),
                    None => (
                        rng.random_range(0..ls.len() as u32),
                        rng.random_range(0..FAN_ANGLES as u8),
                    ),
                })
                .collect();
            let ctx = Ctx {
                s: side_s_clone(&side_s),
                t: Side {
                    level: lt,
                    frames: &target.frames[l],
                    eang: &target.edge_angles[l],
                    shape: sh_t,
                    fans: &fans_t,
                },
                dsh: *dsh,
                wc: 0.0,
                hs,
                l,
            };
            if exhaustive_top {
                let sw = Stopwatch::start();
                em::exhaustive(&ctx, &mut nnf, &mut dist, &locked[l], cancel)?;
                t_search += sw.secs();
            }
        } else {
            nnf = em::upsample(hs, ht, &source.frames, &target.frames, l, &nnf, ratio);
        }
        let mut order_start = if l == top {
            rng.random_range(0..lt.len())
        } else {
            0
        };
        for it in 0..=params.iterations {
            cancel.check()?;
            // M-step: vote the target signal from the current NNF, then its colour fans.
            let sw = Stopwatch::start();
            signal = em::vote(
                &side_s,
                &Side {
                    level: lt,
                    frames: &target.frames[l],
                    eang: &target.edge_angles[l],
                    shape: sh_t,
                    fans: &[],
                },
                &sig_s[l],
                &nnf,
                ratio,
            );
            apply_fixed(&mut signal, l);
            t_vote += sw.secs();
            if l == 0 && it > 0 {
                t_vote0 += sw.secs();
            }
            let sw = Stopwatch::start();
            sampler_t.fans_into(lt, signal.as_flattened(), C, &mut fans_t);
            t_fans += sw.secs();
            let ctx = Ctx {
                s: side_s_clone(&side_s),
                t: Side {
                    level: lt,
                    frames: &target.frames[l],
                    eang: &target.edge_angles[l],
                    shape: sh_t,
                    fans: &fans_t,
                },
                dsh: *dsh,
                wc,
                hs,
                l,
            };
            dist = em::all_distances(&ctx, &nnf);
            energy = dist.iter().map(|&d| d as f64).sum::<f64>() / dist.len().max(1) as f64;
            done_work += lt.len() as f64;
            let prog = Progress {
                stage: "solve",
                level: l,
                levels: nl,
                iteration: it,
                energy,
                elapsed: watch.secs(),
                fraction: (done_work / total_work) as f32,
            };
            sink(Event::Progress(prog.clone()));
            let expanded: Arc<[[f32; 3]]> = if l == 0 {
                signal.clone().into()
            } else {
                ht.expand_to_finest(l, &signal).into()
            };
            sink(Event::Partial {
                progress: prog,
                signal: expanded,
            });
            if it == params.iterations {
                if l == 0 && params.exact_samples > 0 {
                    exact = Some(exact_check(&ctx, &dist, &locked[0], params, watch.secs()));
                }
                break;
            }
            // E-step.
            let sw = Stopwatch::start();
            if l == top && exhaustive_top {
                em::exhaustive(&ctx, &mut nnf, &mut dist, &locked[l], cancel)?;
            } else {
                let order = em::bfs_order(lt, order_start);
                order_start = *order.last().unwrap_or(&0) as usize;
                let swp = Stopwatch::start();
                em::propagate(&ctx, &mut nnf, &mut dist, &order, &locked[l], cancel)?;
                if l == 0 {
                    t_prop0 += swp.secs();
                }
                em::random_search(
                    &ctx,
                    &mut nnf,
                    &mut dist,
                    &locked[l],
                    params.seed ^ ((it as u64 + 1) << 40),
                    cancel,
                )?;
            }
            t_search += sw.secs();
            if l == 0 {
                t_search0 += sw.secs();
            }
        }
        let name: &'static str = LEVEL_NAMES.get(l).copied().unwrap_or("level >=10");
        stage(name, sw_level.secs(), &mut timings);
    }
    stage("search", t_search, &mut timings);
    stage("vote", t_vote, &mut timings);
    stage("search finest", t_search0, &mut timings);
    stage("vote finest", t_vote0, &mut timings);
    stage("propagate finest", t_prop0, &mut timings);
    stage("fan updates", t_fans, &mut timings);
    if params.sharpen {
        let s0 = &sig_s[0];
        for (v, &(s, _)) in nnf.iter().enumerate() {
            signal[v] = s0[s as usize];
        }
        apply_fixed(&mut signal, 0);
    }
    // Levels may stop above the finest if `levels` limited the pair count: expand.
    let sw = Stopwatch::start();
    let file_signal: Vec<[f32; 3]> = target
        .file_to_working
        .iter()
        .map(|&w| signal[w as usize])
        .collect();
    let file_nnf: Vec<(u32, f32)> = target
        .file_to_working
        .iter()
        .map(|&w| {
            let (s, k) = nnf[w as usize];
            (
                source.working_to_file[s as usize],
                k as f32 * crate::features::ANGLE_STEP_DEG,
            )
        })
        .collect();
    stage("deliver", sw.secs(), &mut timings);
    let prog = Progress {
        stage: "solve",
        level: 0,
        levels: nl,
        iteration: params.iterations,
        energy,
        elapsed: watch.secs(),
        fraction: 1.0,
    };
    sink(Event::Partial {
        progress: prog,
        signal: signal.clone().into(),
    });
    Ok(TransferResult {
        working_signal: signal,
        nnf,
        file_signal,
        file_nnf,
        timings,
        energy,
        exact,
    })
}

/// Exhaustive nearest neighbours of an evenly spaced sample of unconstrained target vertices.
fn exact_check(
    ctx: &Ctx,
    dist: &[f32],
    locked: &[Option<u32>],
    params: &TransferParams,
    solve_seconds: f64,
) -> ExactCheck {
    let n = dist.len();
    let free: Vec<usize> = (0..n).filter(|&v| locked[v].is_none()).collect();
    let k = params.exact_samples.min(free.len());
    let sample: Vec<usize> = (0..k).map(|i| free[i * free.len() / k.max(1)]).collect();
    let sw = Stopwatch::start();
    let exact = em::exact_distances(ctx, &sample);
    let secs = sw.secs();
    let mean = |x: &mut dyn Iterator<Item = f64>| x.sum::<f64>() / k.max(1) as f64;
    ExactCheck {
        samples: k,
        meshmatch_energy: mean(&mut sample.iter().map(|&v| dist[v] as f64)),
        exact_energy: mean(&mut exact.iter().map(|&d| d as f64)),
        exact_seconds: secs * n as f64 / k.max(1) as f64,
        meshmatch_seconds: solve_seconds,
    }
}

const LEVEL_NAMES: [&str; 10] = [
    "level 0", "level 1", "level 2", "level 3", "level 4", "level 5", "level 6", "level 7",
    "level 8", "level 9",
];

fn side_s_clone<'a>(s: &Side<'a>) -> Side<'a> {
    Side {
        level: s.level,
        frames: s.frames,
        eang: s.eang,
        shape: s.shape,
        fans: s.fans,
    }
}

/// Prepare both meshes and solve ([`prepare`] + [`solve`]).
pub fn transfer(
    source: &TriMesh,
    target: &TriMesh,
    corr: &[jobs::Correspondence],
    params: &TransferParams,
    sink: &dyn Fn(Event),
    cancel: &CancelToken,
) -> Result<TransferResult> {
    if source.signal_kind() == SignalKind::None {
        return Err(Error::InvalidInput(
            "the source mesh has no signal (vertex colours or a texture) to transfer".into(),
        ));
    }
    let ps = prepare(source, params, sink, cancel)?;
    let pt = prepare(target, params, sink, cancel)?;
    let mut r = solve(&ps, &pt, corr, params, sink, cancel)?;
    let mut t: Vec<(String, f64)> = ps
        .timings
        .iter()
        .map(|(n, s)| (format!("source {n}"), *s))
        .chain(pt.timings.iter().map(|(n, s)| (format!("target {n}"), *s)))
        .collect();
    t.append(&mut r.timings);
    r.timings = t;
    Ok(r)
}

/// Bake a working-mesh signal into the target's own UV layout: every texel inside a UV triangle
/// finds its surface point (barycentric in that input face), the working face containing it (from
/// the refinement provenance) and interpolates the working signal there; texels outside every
/// island are filled from their neighbours for a few texels (dilation against seams). A mesh
/// without UVs, or one that is not the mesh `prepared_target` came from, gives a black image
/// except for what can be located by nearest working vertex.
pub fn bake_texture(
    target: &TriMesh,
    prepared_target: &PreparedMesh,
    working_signal: &[[f32; 3]],
    size: u32,
) -> image::RgbImage {
    prepared_target.layout.bake(target, working_signal, size)
}

/// Where a prepared mesh's working faces lie in its input faces (the refinement provenance): what
/// baking a working signal into the input's UV layout needs, without the rest of the preparation.
#[derive(Clone, Debug, Default)]
pub struct BakeLayout {
    working_faces: Vec<[u32; 3]>,
    working_vertices: usize,
    /// Input face (index into the prepared `TriMesh::faces`) of every working face.
    face_input: Vec<u32>,
    /// Barycentric coordinates of every working face's corners in its input face.
    face_bary: Vec<[[f32; 3]; 3]>,
    input_faces: usize,
}

impl BakeLayout {
    /// The layout of a prepared mesh (shared, not copied: built once by [`prepare`]).
    pub fn of(prepared: &PreparedMesh) -> Arc<Self> {
        prepared.layout.clone()
    }

    /// [`bake_texture`] through this layout (`target` is the mesh it was prepared from).
    pub fn bake(
        &self,
        target: &TriMesh,
        working_signal: &[[f32; 3]],
        size: u32,
    ) -> image::RgbImage {
        bake_layout(target, self, working_signal, size)
    }
}

/// The result as `transfer --out` delivers it at a path with extension `ext` (case-insensitive):
/// the target file mesh with the signal on its own vertices, and, for `.glb`/`.obj` when the
/// target has UVs, a `baseColorTexture` of `texture_size` pixels baked into its UV layout (a
/// `.glb` then carries the texture alone, without vertex colours).
pub fn deliver(
    target: &TriMesh,
    layout: &BakeLayout,
    working_signal: &[[f32; 3]],
    file_signal: &[[f32; 3]],
    ext: &str,
    texture_size: u32,
) -> TriMesh {
    let ext = ext.to_ascii_lowercase();
    let mut out = target.clone();
    out.colors = Some(file_signal.to_vec());
    out.texture = None;
    if ext != "ply" && target.uvs.is_some() {
        let image = layout.bake(target, working_signal, texture_size);
        out.texture = Some(std::sync::Arc::new(crate::mesh::Texture {
            image,
            path: None,
        }));
        if ext == "glb" {
            out.colors = None;
        }
    }
    out
}

/// The dense result (`transfer --out-dense`): the working mesh with the signal on its vertices.
pub fn deliver_dense(working: &TriMesh, working_signal: &[[f32; 3]]) -> TriMesh {
    let mut d = working.clone();
    d.colors = Some(working_signal.to_vec());
    d.texture = None;
    d.uvs = None;
    d
}

fn bake_layout(
    target: &TriMesh,
    pm: &BakeLayout,
    working_signal: &[[f32; 3]],
    size: u32,
) -> image::RgbImage {
    let size = size.max(1);
    let (w, h) = (size as usize, size as usize);
    let mut acc = vec![[0.0f32; 3]; w * h];
    let mut have = vec![false; w * h];
    let Some(uvs) = target.uvs.as_ref() else {
        return image::RgbImage::new(size, size);
    };
    let same = pm.input_faces == target.faces.len()
        && working_signal.len() == pm.working_vertices
        && pm.face_input.len() == pm.working_faces.len();
    // Input face -> working faces (CSR).
    let nf = target.faces.len();
    let mut off = vec![0usize; nf + 1];
    if same {
        for &f in &pm.face_input {
            off[f as usize + 1] += 1;
        }
        for i in 0..nf {
            off[i + 1] += off[i];
        }
    }
    let mut fill = off.clone();
    let mut list = vec![0u32; if same { pm.face_input.len() } else { 0 }];
    if same {
        for (wf, &f) in pm.face_input.iter().enumerate() {
            list[fill[f as usize]] = wf as u32;
            fill[f as usize] += 1;
        }
    }
    let sample = |f: usize, b: [f32; 3]| -> [f32; 3] {
        if !same {
            return [0.0; 3];
        }
        let mut best = (f32::NEG_INFINITY, 0usize, [1.0f32, 0.0, 0.0]);
        for &wf in &list[off[f]..off[f + 1]] {
            let cb = pm.face_bary[wf as usize];
            // Solve b = l0 cb0 + l1 cb1 + l2 cb2 in the first two barycentric coordinates.
            let (a0, a1) = (cb[0][0] - cb[2][0], cb[1][0] - cb[2][0]);
            let (c0, c1) = (cb[0][1] - cb[2][1], cb[1][1] - cb[2][1]);
            let det = a0 * c1 - a1 * c0;
            if det.abs() < 1e-12 {
                continue;
            }
            let (r0, r1) = (b[0] - cb[2][0], b[1] - cb[2][1]);
            let l0 = (r0 * c1 - a1 * r1) / det;
            let l1 = (a0 * r1 - r0 * c0) / det;
            let l = [l0, l1, 1.0 - l0 - l1];
            let m = l[0].min(l[1]).min(l[2]);
            if m > best.0 {
                best = (m, wf as usize, l);
            }
            if m >= 0.0 {
                break;
            }
        }
        let (_, wf, l) = best;
        let face = pm.working_faces[wf];
        let l = l.map(|x| x.max(0.0));
        let s = (l[0] + l[1] + l[2]).max(1e-12);
        let mut out = [0.0f32; 3];
        for k in 0..3 {
            let c = working_signal[face[k] as usize];
            for ch in 0..3 {
                out[ch] += l[k] / s * c[ch];
            }
        }
        out
    };
    for (f, _) in target.faces.iter().enumerate() {
        let uv = [uvs[3 * f], uvs[3 * f + 1], uvs[3 * f + 2]]
            .map(|u| [u[0] * w as f32, (1.0 - u[1]) * h as f32]);
        let minx = uv
            .iter()
            .map(|p| p[0])
            .fold(f32::INFINITY, f32::min)
            .floor()
            .max(0.0) as usize;
        let maxx = (uv
            .iter()
            .map(|p| p[0])
            .fold(f32::NEG_INFINITY, f32::max)
            .ceil() as usize)
            .min(w);
        let miny = uv
            .iter()
            .map(|p| p[1])
            .fold(f32::INFINITY, f32::min)
            .floor()
            .max(0.0) as usize;
        let maxy = (uv
            .iter()
            .map(|p| p[1])
            .fold(f32::NEG_INFINITY, f32::max)
            .ceil() as usize)
            .min(h);
        let det = (uv[1][0] - uv[0][0]) * (uv[2][1] - uv[0][1])
            - (uv[2][0] - uv[0][0]) * (uv[1][1] - uv[0][1]);
        if !det.is_finite() || det.abs() < 1e-12 {
            continue;
        }
        for y in miny..maxy {
            for x in minx..maxx {
                let p = [x as f32 + 0.5, y as f32 + 0.5];
                let b1 = ((p[0] - uv[0][0]) * (uv[2][1] - uv[0][1])
                    - (uv[2][0] - uv[0][0]) * (p[1] - uv[0][1]))
                    / det;
                let b2 = ((uv[1][0] - uv[0][0]) * (p[1] - uv[0][1])
                    - (p[0] - uv[0][0]) * (uv[1][1] - uv[0][1]))
                    / det;
                let b0 = 1.0 - b1 - b2;
                if b0 < -1e-4 || b1 < -1e-4 || b2 < -1e-4 {
                    continue;
                }
                let i = y * w + x;
                acc[i] = sample(f, [b0, b1, b2]);
                have[i] = true;
            }
        }
    }
    // Dilate a few texels past island borders.
    for _ in 0..4 {
        let prev = have.clone();
        let snap = acc.clone();
        for y in 0..h {
            for x in 0..w {
                let i = y * w + x;
                if prev[i] {
                    continue;
                }
                let mut a = [0.0f32; 3];
                let mut c = 0;
                for (dx, dy) in [(-1i64, 0i64), (1, 0), (0, -1), (0, 1)] {
                    let (xx, yy) = (x as i64 + dx, y as i64 + dy);
                    if xx < 0 || yy < 0 || xx >= w as i64 || yy >= h as i64 {
                        continue;
                    }
                    let j = yy as usize * w + xx as usize;
                    if prev[j] {
                        for ch in 0..3 {
                            a[ch] += snap[j][ch];
                        }
                        c += 1;
                    }
                }
                if c > 0 {
                    acc[i] = a.map(|v| v / c as f32);
                    have[i] = true;
                }
            }
        }
    }
    let mut img = image::RgbImage::new(size, size);
    for (i, p) in img.pixels_mut().enumerate() {
        p.0 = crate::color::to_u8(acc[i]);
    }
    img
}
