//! Solve: the coarse-to-fine EM driver (MeshMatch §4).

use std::sync::Arc;

use glam::Vec3;
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};

use super::affinities::{affinities, to_levels, weighted_shape};
use super::em::{self, C, Ctx, PER, Patch, Side, TargetFans};
use super::global_map;
use super::{
    Constraints, ExactCheck, PreparedMesh, TransferParams, TransferResult, level_shape_weight,
};
use crate::error::{Error, Result};
use crate::features::{FAN_ANGLES, FanSampler};
use crate::hierarchy::Hierarchy;
use crate::work::{CancelToken, Event, Progress, Stopwatch};

/// Solve for the target's signal given both prepared meshes and correspondences (file indices):
/// coarse-to-fine EM (§4) with exhaustive search on the coarsest level, then per level
/// `params.iterations` rounds of propagation + random search + Gaussian voting, upsampling between
/// levels and the optional nearest-neighbour sharpening at the finest level.
pub fn solve(
    source: &PreparedMesh,
    target: &PreparedMesh,
    corr: &[crate::correspondence::Correspondence],
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
///
/// The steps, each a function below: [`working_pairs`] (correspondences in working vertices),
/// [`level_affinities`] (correspondence affinities per level), [`locked_per_level`] and
/// [`fixed_per_level`] (constraints carried up the hierarchy), then per level, coarsest first,
/// [`Levels::build_shapes`] (the level's weighted shape vectors), [`Levels::start_level`] (random field plus exhaustive search on the coarsest level, upsampling
/// from the coarser level elsewhere) and [`Levels::iterate`] (M-step, fans, E-step), and finally
/// [`Levels::finish`] (nearest-neighbour copy and the file-order result).
pub fn solve_constrained(
    source: &PreparedMesh,
    target: &PreparedMesh,
    corr: &[crate::correspondence::Correspondence],
    constraints: &Constraints,
    params: &TransferParams,
    sink: &dyn Fn(Event),
    cancel: &CancelToken,
) -> Result<TransferResult> {
    params.validate()?;
    crate::correspondence::check_limits(corr)?;
    let watch = Stopwatch::start();
    let (Some(sig_s), Some(fans_s)) = (source.signal.as_ref(), source.fans.as_ref()) else {
        return Err(Error::InvalidInput(
            "the source mesh has no signal (vertex colours or a texture) to transfer".into(),
        ));
    };
    let pairs = working_pairs(source, target, corr)?;
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

    // Correspondences and constraints per level (they do not depend on the global map).
    let clock = Stopwatch::start();
    let mut affinities = level_affinities(source, target, &pairs);
    let mut locked = locked_per_level(hs, ht, &pairs, nl);
    let mut fixed = fixed_per_level(ht, constraints, nt0, nl);
    let affinities_s = clock.secs();

    // After a correspondence edit the map is computed anew (about half a second at any size);
    // the first preview does not wait for it: the coarsest level is solved once with the map
    // the previous solve left and the new correspondences, and shown. The solve below is the
    // same as without it (its own random numbers, nothing carried over).
    let previous = (params.structure != Some(0.0) && nl > 1)
        .then(|| global_map::previous_map(source.map_side(), target.map_side(), &pairs, nl))
        .flatten();
    if let Some(prev) = previous {
        let top = nl - 1;
        let kept = (affinities.0[top].clone(), affinities.1[top].clone());
        let s = params
            .structure
            .unwrap_or_else(|| super::auto_structure(prev.score));
        let preview_params = TransferParams {
            iterations: 0,
            exact_samples: 0,
            ..params.clone()
        };
        let mut preview = Levels::new(
            (source, target, sig_s, fans_s),
            (affinities, locked, fixed),
            s,
            (s > 0.0).then_some(prev),
            Vec::new(),
            &preview_params,
            sink,
            cancel,
            watch,
            nl,
        );
        let r = preview.level(top);
        (affinities, locked, fixed) = (preview.affinities, preview.locked, preview.fixed);
        (affinities.0[top], affinities.1[top]) = kept;
        r?;
    }

    let mut notices = Vec::new();
    let mut gmap = None;
    let mut map_secs = None;
    let mut map_stages = Vec::new();
    let mut structure = params.structure.unwrap_or(0.0);
    let mut map_score = None;
    if params.structure != Some(0.0) {
        match global_map::global_map(source.map_side(), target.map_side(), &pairs, nl, cancel) {
            Ok(g) => {
                map_secs = Some(g.seconds);
                map_stages = g.stages.clone();
                map_score = Some(g.score);
                if params.structure.is_none() {
                    structure = super::auto_structure(g.score);
                }
                if structure > 0.0 {
                    gmap = Some(g);
                }
            }
            Err(Error::Cancelled) => return Err(Error::Cancelled),
            Err(e) => {
                structure = 0.0;
                notices.push(format!(
                    "global map not used ({e}); starting from the exhaustive search"
                ))
            }
        }
    }
    let mut run = Levels::new(
        (source, target, sig_s, fans_s),
        (affinities, locked, fixed),
        structure,
        gmap,
        notices,
        params,
        sink,
        cancel,
        watch,
        nl,
    );
    if let Some(t) = map_secs {
        run.stage("global map", t);
        for (name, t) in map_stages {
            run.stage(name, t);
        }
    }
    run.stage("affinities", affinities_s);
    cancel.check()?;
    for l in (0..nl).rev() {
        let sw_level = Stopwatch::start();
        run.level(l)?;
        let name: &'static str = LEVEL_NAMES.get(l).copied().unwrap_or("level >=10");
        run.stage(name, sw_level.secs());
    }
    let mut r = run.finish();
    r.structure = structure;
    r.map_score = map_score;
    Ok(r)
}

/// Correspondences from file indices to working vertices (one source vertex, its target set).
fn working_pairs(
    source: &PreparedMesh,
    target: &PreparedMesh,
    corr: &[crate::correspondence::Correspondence],
) -> Result<Vec<(u32, Vec<u32>)>> {
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
    Ok(pairs)
}

/// Correspondence affinities of both meshes on every level (`k` per vertex, empty without
/// correspondences) and `k`.
fn level_affinities(
    source: &PreparedMesh,
    target: &PreparedMesh,
    pairs: &[(u32, Vec<u32>)],
) -> (Vec<Vec<f32>>, Vec<Vec<f32>>, usize) {
    let (hs, ht) = (&source.hierarchy, &target.hierarchy);
    let k = pairs.len();
    if k == 0 {
        return (
            vec![Vec::new(); hs.num_levels()],
            vec![Vec::new(); ht.num_levels()],
            0,
        );
    }
    let (a, b) = affinities(source, target, pairs);
    (to_levels(hs, a, k), to_levels(ht, b, k), k)
}

/// Locked NNF entries per level: every target vertex of a correspondence (and its ancestors)
/// maps to the source vertex's ancestor on that level.
fn locked_per_level(
    hs: &Hierarchy,
    ht: &Hierarchy,
    pairs: &[(u32, Vec<u32>)],
    nl: usize,
) -> Vec<Vec<Option<u32>>> {
    (0..nl)
        .map(|l| {
            let mut lk = vec![None; ht.levels[l].len()];
            for (s, ts) in pairs {
                let sl = hs.ancestor(0, *s, l);
                for &t in ts {
                    lk[ht.ancestor(0, t, l) as usize] = Some(sl);
                }
            }
            lk
        })
        .collect()
}

/// Fixed signal per level: a coarse vertex is fixed (to its fixed children's mean) when at least
/// half of its children are.
fn fixed_per_level(
    ht: &Hierarchy,
    constraints: &Constraints,
    nt0: usize,
    nl: usize,
) -> Vec<Vec<Option<[f32; 3]>>> {
    if constraints.fixed.is_empty() {
        // nothing fixed: no per-vertex entries (16 bytes a vertex at every level)
        return vec![Vec::new(); nl];
    }
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
}

/// Accumulated stage times of the level loop (seconds).
#[derive(Default)]
struct Timers {
    search: f64,
    vote: f64,
    /// "fan updates": the target's tables built in the solve (large targets), the source's ring
    /// summaries and the per-iteration pre-filter of the target's signal.
    fans: f64,
    /// Finest level alone (the per-iteration figures the benchmark reports).
    search0: f64,
    vote0: f64,
    prop0: f64,
}

/// The level loop's state: inputs borrowed for the solve, the NNF and signal carried from level
/// to level, progress and timings.
struct Levels<'a> {
    source: &'a PreparedMesh,
    target: &'a PreparedMesh,
    sig_s: &'a [Vec<[f32; 3]>],
    fans_s: &'a [Vec<f32>],
    /// Correspondence affinities per level (source, target, `k`), each level's taken when its
    /// shape vectors are built.
    affinities: (Vec<Vec<f32>>, Vec<Vec<f32>>, usize),
    structure: f32,
    /// Weighted shape vectors (source, target, dimension) of the level being solved and of
    /// the finest once reached; built as each level starts ([`Levels::build_shapes`]), so the
    /// first preview does not wait for every level's, and a level's are dropped when the next
    /// finer one starts.
    shapes: Vec<(Vec<f32>, Vec<f32>, usize)>,
    locked: Vec<Vec<Option<u32>>>,
    fixed: Vec<Vec<Option<[f32; 3]>>>,
    params: &'a TransferParams,
    sink: &'a dyn Fn(Event),
    cancel: &'a CancelToken,
    watch: Stopwatch,
    nl: usize,
    exhaustive_top: bool,
    total_work: f64,
    done_work: f64,
    /// The global map, when the structure value uses it: the coarsest level's start.
    gmap: Option<std::sync::Arc<super::global_map::GlobalMap>>,
    notices: Vec<String>,
    /// E-steps run per level.
    iterations: Vec<usize>,
    /// Ring summaries of the current level's source fans ([`em::ring_summaries_into`]): the
    /// E-step's rotation-invariant lower bound (the target's are taken with its fans).
    rings_s: Vec<f32>,
    /// The target's current signal pre-filtered for its fans ([`em::TargetFans`]).
    signal_t: Vec<f32>,
    nnf: Vec<(u32, u8)>,
    signal: Vec<[f32; 3]>,
    energy: f64,
    exact: Option<ExactCheck>,
    rng: SmallRng,
    t: Timers,
    timings: Vec<(String, f64)>,
}

/// Per-level correspondence affinities, locked entries and fixed signal, as [`Levels`] holds
/// them.
type PerLevel = (
    (Vec<Vec<f32>>, Vec<Vec<f32>>, usize),
    Vec<Vec<Option<u32>>>,
    Vec<Vec<Option<[f32; 3]>>>,
);

/// The two prepared meshes and the source's per-level signal and colour fans.
type Inputs<'a> = (
    &'a PreparedMesh,
    &'a PreparedMesh,
    &'a [Vec<[f32; 3]>],
    &'a [Vec<f32>],
);

impl<'a> Levels<'a> {
    /// A level loop over both prepared meshes (and the source's per-level signal and fans),
    /// with nothing solved yet; `watch` is the solve's clock (progress events' elapsed time).
    #[allow(clippy::too_many_arguments)]
    fn new(
        (source, target, sig_s, fans_s): Inputs<'a>,
        (affinities, locked, fixed): PerLevel,
        structure: f32,
        gmap: Option<Arc<global_map::GlobalMap>>,
        notices: Vec<String>,
        params: &'a TransferParams,
        sink: &'a dyn Fn(Event),
        cancel: &'a CancelToken,
        watch: Stopwatch,
        nl: usize,
    ) -> Self {
        let (hs, ht) = (&source.hierarchy, &target.hierarchy);
        Levels {
            source,
            target,
            sig_s,
            fans_s,
            affinities,
            structure,
            shapes: vec![(Vec::new(), Vec::new(), 0); nl],
            locked,
            fixed,
            params,
            sink,
            cancel,
            watch,
            nl,
            // The coarsest level is searched exhaustively when that is cheap (the usual
            // ~128-250 vertices); a hierarchy cut short by `levels` starts from the random
            // field instead.
            exhaustive_top: (hs.levels[nl - 1].len() as f64) * (ht.levels[nl - 1].len() as f64)
                <= 4.0e6,
            total_work: (0..nl)
                .map(|l| ht.levels[l].len() as f64 * (params.iterations + 1) as f64)
                .sum(),
            done_work: 0.0,
            gmap,
            notices,
            iterations: vec![0; nl],
            rings_s: Vec::new(),
            signal_t: Vec::new(),
            nnf: Vec::new(),
            signal: Vec::new(),
            energy: 0.0,
            exact: None,
            rng: SmallRng::seed_from_u64(params.seed),
            t: Timers::default(),
            timings: Vec::new(),
        }
    }

    fn stage(&mut self, name: &'static str, t: f64) {
        (self.sink)(Event::StageTime(name, t));
        self.timings.push((name.to_string(), t));
    }

    fn apply_fixed(&self, sig: &mut [[f32; 3]], l: usize) {
        for (v, f) in self.fixed[l].iter().enumerate() {
            if let Some(c) = f {
                sig[v] = *c;
            }
        }
    }

    fn source_side(&self, l: usize) -> Side<'_> {
        Side {
            level: &self.source.hierarchy.levels[l],
            frames: &self.source.frames[l],
            eang: &self.source.edge_angles[l],
            shape: &self.shapes[l].0,
            fans: &self.fans_s[l],
            rings: &self.rings_s,
        }
    }

    fn target_side(&self, l: usize) -> Side<'_> {
        Side {
            level: &self.target.hierarchy.levels[l],
            frames: &self.target.frames[l],
            eang: &self.target.edge_angles[l],
            shape: &self.shapes[l].1,
            fans: &[],
            rings: &[],
        }
    }

    /// The E-step's context on level `l`; `sampler_t`, the target level's fan table, gives it
    /// the target's colour fans of `signal_t` (none before the target has colour).
    fn ctx<'s>(&'s self, l: usize, sampler_t: Option<&'s FanSampler>, wc: f32) -> Ctx<'s> {
        Ctx {
            s: self.source_side(l),
            t: self.target_side(l),
            dsh: self.shapes[l].2,
            wc,
            hs: &self.source.hierarchy,
            l,
            tf: sampler_t.map(|sampler| TargetFans {
                sampler,
                signal: &self.signal_t,
            }),
        }
    }

    /// Weight of the colour fans on level `l`: 1 / (variance of the source fans x fan length).
    fn colour_weight(&self, l: usize) -> f32 {
        let f = &self.fans_s[l];
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
        let var = v / (n * C as f64);
        if var > 1e-10 {
            (1.0 / (var * PER as f64)) as f32
        } else {
            0.0
        }
    }

    /// Level `l`'s weighted shape vectors: automatic features plus correspondence affinities
    /// with the level's shape weight ([`level_shape_weight`]), and the global map's term when
    /// the solve uses it; the coarser level's are dropped.
    fn build_shapes(&mut self, l: usize) {
        let (hs, ht) = (&self.source.hierarchy, &self.target.hierarchy);
        let k = self.affinities.2;
        let aff_s = std::mem::take(&mut self.affinities.0[l]);
        let aff_t = std::mem::take(&mut self.affinities.1[l]);
        let mut sh = weighted_shape(
            &self.source.shape[l],
            &self.target.shape[l],
            &aff_s,
            &aff_t,
            k,
            level_shape_weight(self.params, l, self.nl),
        );
        if let Some(g) = &self.gmap {
            sh = global_map::append_map_term(g, hs, ht, sh, l, self.nl, self.structure);
        }
        self.shapes[l] = sh;
        if l + 1 < self.nl {
            self.shapes[l + 1] = (Vec::new(), Vec::new(), 0);
        }
    }

    /// One level: its shape vectors and sampler, its starting NNF, then the EM iterations.
    fn level(&mut self, l: usize) -> Result<()> {
        self.build_shapes(l);
        let (source, target) = (self.source, self.target);
        let lt = &target.hierarchy.levels[l];
        let fan_r = source.fan_radius * lt.mean_edge;
        let clock = Stopwatch::start();
        let built;
        let sampler_t = if target.fan_radius == source.fan_radius && target.samplers.len() > l {
            &target.samplers[l]
        } else {
            built = FanSampler::in_vertex_order(lt, &target.frames[l], fan_r, self.cancel)?;
            &built
        };
        self.t.fans += clock.secs();
        let mut dist = vec![0.0f32; lt.len()];
        let clock = Stopwatch::start();
        em::ring_summaries_into(&self.fans_s[l], &mut self.rings_s);
        self.t.fans += clock.secs();
        self.start_level(l, &mut dist)?;
        self.iterate(l, sampler_t, &mut dist)
    }

    /// The level's starting NNF: on the coarsest level a random field (respecting the locked
    /// entries) improved by exhaustive search on shape; elsewhere the coarser level's field
    /// upsampled (§4.3).
    fn start_level(&mut self, l: usize, dist: &mut [f32]) -> Result<()> {
        let (hs, ht) = (&self.source.hierarchy, &self.target.hierarchy);
        let (ls, lt) = (&hs.levels[l], &ht.levels[l]);
        if l == self.nl - 1 {
            let rng = &mut self.rng;
            let mut nnf: Vec<(u32, u8)> = (0..lt.len())
                .map(|v| match self.locked[l][v] {
                    Some(s) => (s, 0),
                    None => (
                        rng.random_range(0..ls.len() as u32),
                        rng.random_range(0..FAN_ANGLES as u8),
                    ),
                })
                .collect();
            if let Some(g) = &self.gmap {
                // the global map's start: the mapped source vertex
                for (v, e) in nnf.iter_mut().enumerate() {
                    if self.locked[l][v].is_none() {
                        e.0 = g.top_init[v];
                    }
                }
            }
            if self.exhaustive_top {
                let clock = Stopwatch::start();
                let ctx = self.ctx(l, None, 0.0);
                em::exhaustive(&ctx, &mut nnf, dist, &self.locked[l], self.cancel)?;
                self.t.search += clock.secs();
            }
            if let Some(g) = &self.gmap {
                // Rotations from the map's transport of the local frame: the shape-only search
                // above cannot tell them (its distance is the same for every rotation).
                g.transport_rotations(
                    lt,
                    &self.target.frames[l],
                    &self.source.frames[l],
                    &mut nnf,
                    &self.locked[l],
                );
                let ctx = self.ctx(l, None, 0.0);
                let mut p = Patch::empty();
                for (v, e) in nnf.iter().enumerate() {
                    ctx.load(v, &mut p);
                    dist[v] = ctx.dist(&mut p, e.0 as usize, e.1 as usize, f32::INFINITY);
                }
            }
            self.nnf = nnf;
        } else {
            let ratio = ls.mean_edge / lt.mean_edge.max(1e-12);
            self.nnf = em::upsample(
                hs,
                ht,
                &self.source.frames,
                &self.target.frames,
                l,
                &self.nnf,
                ratio,
            );
        }
        Ok(())
    }

    /// The EM iterations of level `l` (§4.1): M-step (vote the signal from the NNF, pre-filter
    /// it for the target's colour fans), progress and a partial result, then the E-step (exhaustive search
    /// on the coarsest level, else propagation in breadth-first order plus random search).
    fn iterate(&mut self, l: usize, sampler_t: &FanSampler, dist: &mut Vec<f32>) -> Result<()> {
        let (hs, ht) = (&self.source.hierarchy, &self.target.hierarchy);
        let (ls, lt) = (&hs.levels[l], &ht.levels[l]);
        let ratio = ls.mean_edge / lt.mean_edge.max(1e-12);
        let top = l == self.nl - 1;
        let wc = self.colour_weight(l);
        let mut order_start = if top {
            self.rng.random_range(0..lt.len())
        } else {
            0
        };
        let iterations = self.params.iterations;
        let mut prev_energy = f64::INFINITY;
        for it in 0..=iterations {
            self.cancel.check()?;
            let clock = Stopwatch::start();
            let mut signal = em::vote(
                &self.source_side(l),
                &self.target_side(l),
                &self.sig_s[l],
                &self.nnf,
                ratio,
            );
            self.apply_fixed(&mut signal, l);
            self.signal = signal;
            self.t.vote += clock.secs();
            if l == 0 && it > 0 {
                self.t.vote0 += clock.secs();
            }
            let clock = Stopwatch::start();
            self.signal_t = crate::features::smooth(lt, self.signal.as_flattened(), C);
            self.t.fans += clock.secs();
            let mut nnf = std::mem::take(&mut self.nnf);
            let ctx = self.ctx(l, Some(sampler_t), wc);
            *dist = em::all_distances(&ctx, &nnf);
            let energy = dist.iter().map(|&d| d as f64).sum::<f64>() / dist.len().max(1) as f64;
            // Converged: the last E-step gained less than `tolerance` of the energy (MeshMatch's
            // upsampled start is already close on every level below the coarsest). A rise counts
            // as converged too, except at tolerance 0, which runs every iteration.
            let converged = self.params.tolerance > 0.0
                && it > 0
                && prev_energy.is_finite()
                && prev_energy - energy < self.params.tolerance as f64 * prev_energy;
            let last = it == iterations || converged;
            prev_energy = energy;
            let prog = Progress {
                stage: "solve",
                level: l,
                levels: self.nl,
                iteration: it,
                energy,
                elapsed: self.watch.secs(),
                fraction: ((self.done_work + lt.len() as f64) / self.total_work) as f32,
            };
            (self.sink)(Event::Progress(prog.clone()));
            let expanded: Arc<[[f32; 3]]> = if l == 0 {
                self.signal.clone().into()
            } else {
                ht.expand_to_finest(l, &self.signal).into()
            };
            (self.sink)(Event::Partial {
                progress: prog,
                signal: expanded,
            });
            let mut exact = None;
            let (mut t_search, mut t_prop) = (0.0, 0.0);
            if last {
                if l == 0 && self.params.exact_samples > 0 {
                    exact = Some(exact_check(
                        &ctx,
                        dist,
                        &self.locked[0],
                        self.params,
                        self.watch.secs(),
                    ));
                }
            } else {
                let clock = Stopwatch::start();
                if top && self.exhaustive_top {
                    em::exhaustive(&ctx, &mut nnf, dist, &self.locked[l], self.cancel)?;
                } else {
                    let order = em::bfs_order(lt, order_start);
                    order_start = *order.last().unwrap_or(&0) as usize;
                    let swp = Stopwatch::start();
                    em::propagate(&ctx, &mut nnf, dist, &order, &self.locked[l], self.cancel)?;
                    t_prop = swp.secs();
                    em::random_search(
                        &ctx,
                        &mut nnf,
                        dist,
                        &self.locked[l],
                        self.params.seed ^ ((it as u64 + 1) << 40),
                        self.cancel,
                    )?;
                }
                t_search = clock.secs();
            }
            self.nnf = nnf;
            self.energy = energy;
            self.done_work += lt.len() as f64;
            if exact.is_some() {
                self.exact = exact;
            }
            if last {
                // the skipped iterations count as done, so progress stays proportional
                self.done_work += (iterations - it) as f64 * lt.len() as f64;
                self.iterations[l] = it;
                break;
            }
            self.t.search += t_search;
            if l == 0 {
                self.t.search0 += t_search;
                self.t.prop0 += t_prop;
            }
        }
        Ok(())
    }

    /// The final copy: with `sharpen`, every finest vertex takes its nearest neighbour's signal
    /// (fixed vertices keep theirs); then the result in the target file's vertex order.
    fn finish(mut self) -> TransferResult {
        let t = std::mem::take(&mut self.t);
        self.stage("search", t.search);
        self.stage("vote", t.vote);
        self.stage("search finest", t.search0);
        self.stage("vote finest", t.vote0);
        self.stage("propagate finest", t.prop0);
        self.stage("fan updates", t.fans);
        let (source, target) = (self.source, self.target);
        let mut signal = std::mem::take(&mut self.signal);
        if self.params.sharpen {
            let s0 = &self.sig_s[0];
            for (v, &(s, _)) in self.nnf.iter().enumerate() {
                signal[v] = s0[s as usize];
            }
            self.apply_fixed(&mut signal, 0);
        }
        let clock = Stopwatch::start();
        let file_signal: Vec<[f32; 3]> = target
            .file_to_working
            .iter()
            .map(|&w| signal[w as usize])
            .collect();
        let file_nnf: Vec<(u32, f32)> = target
            .file_to_working
            .iter()
            .map(|&w| {
                let (s, k) = self.nnf[w as usize];
                (
                    source.working_to_file[s as usize],
                    k as f32 * crate::features::ANGLE_STEP_DEG,
                )
            })
            .collect();
        self.stage("deliver", clock.secs());
        let prog = Progress {
            stage: "solve",
            level: 0,
            levels: self.nl,
            iteration: self.params.iterations,
            energy: self.energy,
            elapsed: self.watch.secs(),
            fraction: 1.0,
        };
        (self.sink)(Event::Partial {
            progress: prog,
            signal: signal.clone().into(),
        });
        TransferResult {
            working_signal: signal,
            nnf: self.nnf,
            file_signal,
            file_nnf,
            timings: self.timings,
            energy: self.energy,
            exact: self.exact,
            notices: self.notices,
            iterations: self.iterations,
            ..TransferResult::default()
        }
    }
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
    let clock = Stopwatch::start();
    let exact = em::exact_distances(ctx, &sample);
    let secs = clock.secs();
    fn side<'a>(x: &em::Side<'a>) -> em::Side<'a> {
        em::Side {
            level: x.level,
            frames: x.frames,
            eang: x.eang,
            shape: &[],
            fans: x.fans,
            rings: x.rings,
        }
    }
    let colour_only = Ctx {
        s: side(&ctx.s),
        t: side(&ctx.t),
        dsh: 0,
        wc: ctx.wc,
        hs: ctx.hs,
        l: ctx.l,
        tf: ctx.tf,
    };
    let coherence = em::exact_distances(&colour_only, &sample);
    let check_seconds = clock.secs();
    let mean = |x: &mut dyn Iterator<Item = f64>| x.sum::<f64>() / k.max(1) as f64;
    ExactCheck {
        samples: k,
        meshmatch_energy: mean(&mut sample.iter().map(|&v| dist[v] as f64)),
        exact_energy: mean(&mut exact.iter().map(|&d| d as f64)),
        exact_seconds: secs * n as f64 / k.max(1) as f64,
        meshmatch_seconds: solve_seconds,
        coherence: mean(&mut coherence.iter().map(|&d| d as f64)),
        check_seconds,
    }
}

const LEVEL_NAMES: [&str; 10] = [
    "level 0", "level 1", "level 2", "level 3", "level 4", "level 5", "level 6", "level 7",
    "level 8", "level 9",
];
