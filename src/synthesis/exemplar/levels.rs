//! The coarse-to-fine synthesis on a pyramid of sample levels (mesh vertices, or the texels of
//! a UV layout), Wei & Levoy 2001 §4: a texture orientation per level, then per level, coarse to
//! fine, a random start and passes of best-match search, each sample in random order taking the
//! exemplar pixel whose multiresolution neighbourhood best matches its own (exhaustively, or
//! among Ashikhmin's coherence candidates and a few random ones).

use std::sync::Arc;

use glam::Vec3;
use rand::rngs::SmallRng;
use rand::seq::SliceRandom;

use super::neigh::{ExemplarLevel, Stencils};
use super::pyramid::{Img, Level, stage_rng};
use super::{Orientation, Search, SynthParams, orient, search};
use crate::error::Result;
use crate::work::{CancelToken, Event, Progress, Stopwatch};

/// Neighbourhood sizes of level `k` (0 = finest) in an `l`-level pyramid: current `NxN` and parent
/// size (0 = no parent). Wei & Levoy §4: `{1x1,1}, {3x3,2}, {5x5,2}, {7x7,2}` coarse to fine.
fn sizes(k: usize, l: usize) -> (usize, usize) {
    if k + 1 == l {
        return (if l == 1 { 7 } else { 1 }, 0);
    }
    let s = [7, 5, 3].get(k).copied().unwrap_or(3);
    (s, (s / 2) | 1)
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
    let clock = Stopwatch::start();
    let mut dirs = orient_levels(levels, carried, params, cancel)?;
    let orientation_secs = clock.secs();
    sink(Event::StageTime("orientation", orientation_secs));

    // ---- synthesis, coarse to fine
    let work: f64 = levels.iter().map(|l| l.num_vertices() as f64).sum::<f64>() * passes as f64;
    let mut report = PassReport {
        up: finest_ancestors(levels),
        work,
        done: 0.0,
        total,
        sink,
    };
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
        let level = LevelSearch {
            k,
            level: &levels[k],
            dirs: &dirs[k],
            ex: &ex,
            h,
            current: &cur_st,
            parent: has_parent.then(|| ParentLevel {
                level: &levels[k + 1],
                stencils: par_st.as_ref(),
                colors: &colors[k + 1],
                sources: &srcs[k + 1],
                exemplar: exemplars[k + 1].as_ref(),
            }),
            params,
        };
        let schedule = pass_schedule(has_parent, size, passes);
        let (src, col) = synthesize_level(
            &level,
            &schedule,
            &mut level_energy[k],
            &mut report,
            &mut rng,
            cancel,
        )?;
        report.done += levels[k].num_vertices() as f64 * (passes - schedule.len()) as f64;
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

/// The texture direction of every sample on every level, coarse to fine: an explicit field
/// (fine to coarse, children averaged, projected on each level), random, the projected up axis,
/// or 2- or 4-way symmetric relaxation started from the parent level.
fn orient_levels(
    levels: &[Level],
    carried: Option<&[[f32; 3]]>,
    params: &SynthParams,
    cancel: &CancelToken,
) -> Result<Vec<Vec<[f32; 3]>>> {
    let nlev = levels.len();
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
    Ok(dirs)
}

/// The ancestor of every finest sample on each level (for partial results on the finest level).
fn finest_ancestors(levels: &[Level]) -> Vec<Vec<u32>> {
    let mut up: Vec<Vec<u32>> = vec![(0..levels[0].num_vertices() as u32).collect()];
    for k in 1..levels.len() {
        let prev = &up[k - 1];
        let map = &levels[k - 1].parent;
        up.push(prev.iter().map(|&v| map[v as usize]).collect());
    }
    up
}

/// The passes of a level, as (current level used, parent level used): parent only then both
/// with a parent, the current level alone on the coarsest, none at all for `{1x1,1}`.
fn pass_schedule(has_parent: bool, size: usize, passes: usize) -> Vec<(bool, bool)> {
    if has_parent {
        (0..passes).map(|p| (p > 0, true)).collect()
    } else if size > 1 {
        (0..passes).map(|_| (true, false)).collect()
    } else {
        Vec::new() // coarsest {1x1,1}: the random copy is the result
    }
}

/// The coarser level a level's neighbourhoods and candidates read.
struct ParentLevel<'a> {
    level: &'a Level,
    stencils: Option<&'a Stencils>,
    colors: &'a [[f32; 3]],
    sources: &'a [u32],
    exemplar: Option<&'a ExemplarLevel>,
}

/// What the search of level `k` reads.
struct LevelSearch<'a> {
    k: usize,
    level: &'a Level,
    dirs: &'a [[f32; 3]],
    ex: &'a ExemplarLevel,
    /// Sample spacing on this level.
    h: f32,
    current: &'a Stencils,
    parent: Option<ParentLevel<'a>>,
    params: &'a SynthParams,
}

/// Progress over the passes of every level: `Event::Partial` with the colours carried onto
/// the finest samples.
struct PassReport<'a> {
    up: Vec<Vec<u32>>,
    work: f64,
    done: f64,
    total: &'a Stopwatch,
    sink: &'a dyn Fn(Event),
}

impl PassReport<'_> {
    /// Count a pass of level `k` over `n` samples and send its partial result.
    fn pass_done(&mut self, k: usize, pass: usize, n: usize, energy: f64, col: &[[f32; 3]]) {
        self.done += n as f64;
        let progress = Progress {
            stage: "synth",
            level: k,
            levels: self.up.len(),
            iteration: pass + 1,
            energy,
            elapsed: self.total.secs(),
            fraction: (self.done / self.work) as f32,
        };
        let signal: Arc<[[f32; 3]]> = self.up[k].iter().map(|&a| col[a as usize]).collect();
        (self.sink)(Event::Partial { progress, signal });
    }
}

/// One level: a random start from this level's exemplar (equalises histograms, §3.1), then the
/// scheduled passes over its free samples in a fresh random order each; its exemplar
/// candidates and colours. `energy` is the last pass's mean squared distance per element.
fn synthesize_level(
    s: &LevelSearch,
    schedule: &[(bool, bool)],
    energy: &mut f64,
    report: &mut PassReport,
    rng: &mut SmallRng,
    cancel: &CancelToken,
) -> Result<(Vec<u32>, Vec<[f32; 3]>)> {
    let (lev, ex) = (s.level, s.ex);
    let n = lev.num_vertices();
    let mut src = vec![u32::MAX; n];
    let mut col = vec![[0.0f32; 3]; n];
    for v in 0..n {
        if let Some(c) = lev.fixed[v] {
            col[v] = c;
        } else {
            let c = ex.random_candidate(rng);
            src[v] = c;
            col[v] = ex.color(c);
        }
    }
    let mut order: Vec<u32> = (0..n as u32)
        .filter(|&v| lev.fixed[v as usize].is_none())
        .collect();
    let mut scratch = Scratch {
        qc: vec![0.0f32; ex.dim_cur()],
        qp: vec![0.0f32; ex.dim_par()],
        cands: Vec::with_capacity(64),
    };
    for (pass, &uses) in schedule.iter().enumerate() {
        order.shuffle(rng);
        let total = search_pass(
            s,
            &order,
            uses,
            &mut src,
            &mut col,
            &mut scratch,
            rng,
            cancel,
        )?;
        let (use_cur, use_par) = uses;
        let dim =
            (if use_cur { ex.dim_cur() } else { 0 }) + (if use_par { ex.dim_par() } else { 0 });
        *energy = total / (order.len().max(1) * dim.max(1)) as f64;
        report.pass_done(s.k, pass, n, *energy, &col);
    }
    Ok((src, col))
}

/// The query vectors and candidate list a pass reuses from sample to sample.
struct Scratch {
    qc: Vec<f32>,
    qp: Vec<f32>,
    cands: Vec<u32>,
}

/// One pass of best-match search over the samples in `order`: each gathers its neighbourhood
/// (current level, parent level or both, as `uses` says) and takes the best exemplar pixel;
/// the summed distance of the matches.
#[allow(clippy::too_many_arguments)]
fn search_pass(
    s: &LevelSearch,
    order: &[u32],
    (use_cur, use_par): (bool, bool),
    src: &mut [u32],
    col: &mut [[f32; 3]],
    scratch: &mut Scratch,
    rng: &mut SmallRng,
    cancel: &CancelToken,
) -> Result<f64> {
    let ex = s.ex;
    let pcol: &[[f32; 3]] = s.parent.as_ref().map_or(&[], |p| p.colors);
    let psrc: &[u32] = s.parent.as_ref().map_or(&[], |p| p.sources);
    let pex = s.parent.as_ref().and_then(|p| p.exemplar);
    let par_st = s.parent.as_ref().and_then(|p| p.stencils);
    let pdefault = pex.map_or(ex.mean, |e| e.mean);
    let Scratch { qc, qp, cands } = scratch;
    let mut energy = 0.0f64;
    for (i, &v) in order.iter().enumerate() {
        if i % 256 == 0 {
            cancel.check()?;
        }
        let v = v as usize;
        if use_cur {
            s.current.gather(v, col, ex.mean, qc);
        }
        if let (true, Some(ps)) = (use_par, par_st) {
            ps.gather(v, pcol, pdefault, qp);
        }
        let q_cur = use_cur.then_some(&qc[..]);
        let q_par = use_par.then_some(&qp[..]);
        let (best, d) = match s.params.search {
            Search::Exhaustive => search::exhaustive(ex, q_cur, q_par),
            Search::Fast => {
                cands.clear();
                collect_candidates(
                    cands,
                    v,
                    s.level,
                    s.dirs,
                    src,
                    ex,
                    s.h,
                    s.parent
                        .as_ref()
                        .map(|p| (p.level, psrc, pex.expect("parent"))),
                );
                for _ in 0..s.params.random_candidates {
                    cands.push(ex.random_candidate(rng));
                }
                search::fast(ex, cands, q_cur, q_par, rng)
            }
        };
        if best != u32::MAX {
            src[v] = best;
            col[v] = ex.color(best);
            energy += d as f64;
        }
    }
    Ok(energy)
}
