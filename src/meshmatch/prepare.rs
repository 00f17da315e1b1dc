//! Prepare: a mesh made ready for MeshMatch once, reused by every solve on it.

use std::sync::Arc;

use glam::Vec3;

use super::TransferParams;
use super::deliver::BakeLayout;
use super::em::C;
use super::global_map;
use super::working;
use crate::error::{Error, Result};
use crate::features::{self, FanSampler, Frames, edge_transport_angles, tangent_frames};
use crate::geometry::Spectrum;
use crate::hierarchy::{Hierarchy, HierarchyOptions};
use crate::mesh::TriMesh;
use crate::work::{CancelToken, Event, Progress, Stopwatch};

/// Working vertex count up to which a target keeps its fan sampling tables between solves.
const KEEP_SAMPLERS_UP_TO: usize = 300_000;

/// A mesh made ready for MeshMatch: the working mesh (welded + refined), its hierarchy, frames,
/// shape features and, when it carries a signal, per-level signals and colour fans. Reusable
/// across correspondence edits.
#[derive(Clone, Debug)]
pub struct PreparedMesh {
    pub(super) working: TriMesh,
    pub(super) working_to_file: Vec<u32>,
    pub(super) file_to_working: Vec<u32>,
    /// Where the working faces lie in the input faces (built once, shared with every result).
    pub(super) layout: Arc<BakeLayout>,
    pub(super) hierarchy: Hierarchy,
    pub(super) frames: Vec<Frames>,
    pub(super) edge_angles: Vec<Vec<f32>>,
    pub(super) shape: Vec<Vec<f32>>,
    pub(super) signal: Option<Vec<Vec<[f32; 3]>>>,
    pub(super) fans: Option<Vec<Vec<f32>>>,
    /// Fan sampling tables per level (built once; reused by every solve on this mesh).
    pub(super) samplers: Vec<FanSampler>,
    pub(super) fan_radius: f32,
    pub(super) timings: Vec<(String, f64)>,
    /// The global map's per-mesh spectrum and latest map (shared by clones, which have the same
    /// geometry), so that solves after a parameter edit do not recompute them.
    pub(super) map_cache: Arc<super::global_map::MapCache>,
}

impl PreparedMesh {
    /// What the global map reads of this mesh.
    pub(super) fn map_side(&self) -> global_map::MapSide<'_> {
        global_map::MapSide {
            hierarchy: &self.hierarchy,
            map_cache: &self.map_cache,
        }
    }

    /// The working mesh (welded, refined and numbered in Morton order; per-vertex colours when
    /// it has a signal).
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

fn progress(stage: &'static str, watch: &Stopwatch, fraction: f32) -> Progress {
    Progress {
        stage,
        elapsed: watch.secs(),
        fraction,
        ..Default::default()
    }
}

/// Refuse, before either mesh is refined or simplified, working meshes of `vertices` that
/// cannot fit, for callers that build both working meshes first and then prepare them
/// (`detail`): the bound of each preparation's own check (the measured peak of a transfer per
/// working vertex) plus the two working meshes held meanwhile (positions, faces and the detail
/// signal: about 256 bytes per vertex each, with room), so that the preparation's check, which
/// sees them in the memory already used, does not refuse what this one let through.
pub(crate) fn check_working_memory(vertices: usize) -> Result<()> {
    crate::work::check_memory(
        (vertices as u64).saturating_mul(super::WORKING_VERTEX_BYTES + 2 * 256),
        &format!("{vertices} working vertices"),
        "use fewer --vertices",
    )
}

/// Prepare a source and a target at once ([`prepare`] of each): the target on a thread of its
/// own, so that each mesh's sequential stages (refinement, hierarchy, the HKS eigen-solve)
/// overlap the other's work. Progress events come from the source's preparation only (`sink`
/// is called on this thread); `cancel` stops both, and an error in one stops the other. The
/// target's parallel loops run in rayon's global pool.
///
/// One after the other instead, as [`prepare`] twice: when called from a rayon pool's thread
/// (`bench --threads` measures that pool's cores; a blocked worker could starve the HKS solve)
/// and with one thread. At a million target vertices the overlap takes the target's sequential
/// refinement and hierarchy (about 9 s) beside the source's parallel fan tables: 42.1-42.2 ->
/// 38.2-38.4 s end to end for 70 MiB more peak memory (1890 -> 1960 MiB). It was once left
/// out above 300K vertices, when it measured no faster there and the target's stored fans
/// left no memory to spare.
pub fn prepare_pair(
    source: &TriMesh,
    source_params: &TransferParams,
    target: &TriMesh,
    target_params: &TransferParams,
    sink: &dyn Fn(Event),
    cancel: &CancelToken,
) -> Result<(PreparedMesh, PreparedMesh)> {
    // Inside a rayon pool (`bench --threads`, a caller's `install`) the target's thread could
    // not use that pool, and a blocked worker is what the HKS solve must not meet.
    let in_pool = rayon::current_thread_index().is_some();
    if in_pool || rayon::current_num_threads() < 2 {
        let ps = prepare(source, source_params, sink, cancel)?;
        let pt = prepare(target, target_params, sink, cancel)?;
        return Ok((ps, pt));
    }
    let (for_source, for_target) = (cancel.child(), cancel.child());
    // The target on a thread of its own, never as a job of the rayon pool: a preparation blocks
    // its thread while the HKS eigen-solve runs detached (`work::run_cancellable`), and that
    // solve's own parallel loops need the pool's workers free.
    std::thread::scope(|scope| {
        let target_job = std::thread::Builder::new()
            .name("meshmatch-prepare-target".into())
            .spawn_scoped(scope, || {
                let stop_source = CancelOnDrop(Some(&for_source));
                let r = prepare(target, target_params, &crate::work::no_events, &for_target);
                if r.is_ok() {
                    stop_source.disarm();
                }
                r
            })
            .map_err(|e| Error::InvalidInput(format!("cannot start a thread: {e}")))?;
        let stop_target = CancelOnDrop(Some(&for_target));
        let ps = prepare(source, source_params, sink, &for_source);
        if ps.is_ok() {
            stop_target.disarm();
        }
        let pt = target_job
            .join()
            .map_err(|_| Error::InvalidInput("preparing the target panicked".into()))?;
        // The first real error, not the `Cancelled` it caused in the other mesh.
        match (ps, pt) {
            (Ok(ps), Ok(pt)) => Ok((ps, pt)),
            (Err(e), Err(Error::Cancelled)) | (Err(Error::Cancelled), Err(e)) => Err(e),
            (Err(e), _) | (_, Err(e)) => Err(e),
        }
    })
}

/// `work` on a copy of `level`'s positions and faces, timed, on a thread of its own, so an
/// eigen-solve runs beside the fan tables. In a one-thread pool (`bench --threads 1` measures
/// one core) it is waited for at once, as the pair's preparations are run one after the other
/// there.
fn beside_tables<T: Send + 'static>(
    level: &crate::hierarchy::Level,
    cancel: &CancelToken,
    work: impl FnOnce(&[[f32; 3]], &[[u32; 3]]) -> T + Send + 'static,
) -> Result<crate::work::Detached<(T, f64)>> {
    let (p, f) = (level.positions.clone(), level.faces.clone());
    let job = crate::work::spawn_detached(move || {
        let clock = Stopwatch::start();
        let out = work(&p, &f);
        (out, clock.secs())
    })?;
    Ok(if rayon::current_num_threads() == 1 {
        crate::work::Detached::done(job.wait(cancel)?)
    } else {
        job
    })
}

/// Cancels its token when dropped armed: on an error or a panic in one mesh's preparation, so
/// that the other stops instead of running to its end.
struct CancelOnDrop<'a>(Option<&'a CancelToken>);

impl CancelOnDrop<'_> {
    fn disarm(mut self) {
        self.0 = None;
    }
}

impl Drop for CancelOnDrop<'_> {
    fn drop(&mut self) {
        if let Some(c) = self.0 {
            c.cancel();
        }
    }
}

/// The level whose HKS the shape features carry down the vertex tree: the finest of at most
/// this many vertices.
const HKS_VERTICES: usize = 2000;

/// Prepare a mesh for MeshMatch: weld, refine to `params.vertices` by longest-edge bisection
/// (signal sampled from the texture/colours at every new vertex), renumber along the Morton
/// curve (`working_to_file` and `file_to_working` map through it), build the hierarchy (§3), tangent
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
    params.validate()?;
    mesh.check_finite()?;
    let watch = Stopwatch::start();
    let mut timings = Vec::new();
    let stage = |name: &'static str, t: f64, timings: &mut Vec<(String, f64)>| {
        sink(Event::StageTime(name, t));
        timings.push((name.to_string(), t));
    };
    sink(Event::Progress(progress("refine", &watch, 0.0)));
    let clock = Stopwatch::start();
    let working = working::working_mesh(mesh, params, cancel)?;
    stage("refine", clock.secs(), &mut timings);

    sink(Event::Progress(progress("hierarchy", &watch, 0.2)));
    let clock = Stopwatch::start();
    let (hierarchy, frames, edge_angles) =
        hierarchy_and_frames(&working.mesh, &working.order, params, cancel)?;
    stage("hierarchy", clock.secs(), &mut timings);
    cancel.check()?;

    // Shape features on a thread of their own while the fan tables are built: the HKS
    // eigen-solve is sequential and the tables are parallel, so together they fill the cores.
    sink(Event::Progress(progress("features", &watch, 0.5)));
    let lc = features::hks_level(&hierarchy, HKS_VERTICES);
    let hks = beside_tables(&hierarchy.levels[lc], cancel, |p, f| {
        features::hks_scaled(p, f, features::HKS_EIGENPAIRS)
    })?;
    let spectrum = start_map_spectrum(&hierarchy, params, cancel)?;

    sink(Event::Progress(progress("fans", &watch, 0.6)));
    let clock = Stopwatch::start();
    let nv = working.mesh.num_vertices();
    let fans = level_fans(&hierarchy, &frames, working.signal, nv, params, cancel)?;
    stage("fans", clock.secs(), &mut timings);
    let (hks, secs) = hks.wait(cancel)?;
    let shape = features::shape_features_from(&hierarchy, lc, hks?);
    stage("features", secs, &mut timings);
    // A spectrum that failed is left to the solve, which reports why its map is not used.
    let map_cache = match spectrum {
        Some((l, k, job)) => {
            let (sp, secs) = job.wait(cancel)?;
            stage("map spectrum", secs, &mut timings);
            match sp {
                Ok(sp) => global_map::MapCache::with_spectrum(l, k, sp),
                Err(_) => global_map::MapCache::default(),
            }
        }
        None => global_map::MapCache::default(),
    };
    cancel.check()?;
    sink(Event::Progress(progress("prepare", &watch, 1.0)));
    Ok(PreparedMesh {
        working: working.mesh,
        working_to_file: working.working_to_file,
        file_to_working: working.file_to_working,
        layout: working.layout,
        hierarchy,
        frames,
        edge_angles,
        shape,
        signal: fans.signal,
        fans: fans.fans,
        samplers: fans.samplers,
        fan_radius: params.fan_radius,
        timings,
        map_cache: Arc::new(map_cache),
    })
}

/// The hierarchy (§3) of the working mesh, and per level its tangent frames and edge transport
/// angles.
fn hierarchy_and_frames(
    working: &TriMesh,
    order: &[u32],
    params: &TransferParams,
    cancel: &CancelToken,
) -> Result<(Hierarchy, Vec<Frames>, Vec<Vec<f32>>)> {
    // Ties between equally long edges are broken by the refinement's numbering, so the
    // hierarchy is the one the mesh had before its Morton renumbering (on a regular grid most
    // edges tie, and the tie order shapes every level).
    let hierarchy = Hierarchy::build_keyed(
        &working.positions,
        &working.faces,
        Some(order),
        HierarchyOptions {
            min_vertices: crate::mesh::MIN_WORKING_VERTICES,
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
    Ok((hierarchy, frames, edge_angles))
}

/// A spectrum job running beside the fan tables: its level, its eigenpair count and the job.
type SpectrumJob = (usize, usize, crate::work::Detached<(Result<Spectrum>, f64)>);

/// Start the spectrum the solve's global map will want (unless the map is off), beside the
/// tables: the eigen-solve scales less well than the tables, and after the preparation it would
/// run alone.
fn start_map_spectrum(
    hierarchy: &Hierarchy,
    params: &TransferParams,
    cancel: &CancelToken,
) -> Result<Option<SpectrumJob>> {
    Ok(match global_map::expected_spectrum(hierarchy) {
        Some((l, k)) if params.structure != Some(0.0) => Some((
            l,
            k,
            beside_tables(&hierarchy.levels[l], cancel, move |p, f| {
                Spectrum::new(p, f, k)
            })?,
        )),
        _ => None,
    })
}

/// Per-level signals and colour fans, or the fan sampling tables a target keeps.
struct LevelFans {
    signal: Option<Vec<Vec<[f32; 3]>>>,
    fans: Option<Vec<Vec<f32>>>,
    samplers: Vec<FanSampler>,
}

/// Fan sampling tables of every level. A mesh with a signal builds each level's table, takes
/// its fans and drops it. A mesh without one (a target) keeps them, so a correspondence edit
/// only re-runs the solve; very large targets rebuild them level by level in the solve
/// instead of holding about 1 KB per vertex (u32 indices and 16-bit weights, 162 taps).
fn level_fans(
    hierarchy: &Hierarchy,
    frames: &[Frames],
    signal0: Option<Vec<[f32; 3]>>,
    working_vertices: usize,
    params: &TransferParams,
    cancel: &CancelToken,
) -> Result<LevelFans> {
    let table = |l: usize| {
        let lev = &hierarchy.levels[l];
        FanSampler::in_vertex_order(lev, &frames[l], params.fan_radius * lev.mean_edge, cancel)
    };
    let mut samplers = Vec::new();
    let (signal, fans) = if let Some(s0) = signal0 {
        let sig = level_signals(hierarchy, s0);
        let mut fans = Vec::with_capacity(sig.len());
        for (l, s) in sig.iter().enumerate() {
            cancel.check()?;
            fans.push(table(l)?.fans(&hierarchy.levels[l], s.as_flattened(), C));
        }
        (Some(sig), Some(fans))
    } else {
        if working_vertices <= KEEP_SAMPLERS_UP_TO {
            for l in 0..hierarchy.num_levels() {
                cancel.check()?;
                samplers.push(table(l)?);
            }
        }
        (None, None)
    };
    Ok(LevelFans {
        signal,
        fans,
        samplers,
    })
}

/// The signal on every level: level 0's, then each coarser vertex the mean of its children.
fn level_signals(hierarchy: &Hierarchy, s0: Vec<[f32; 3]>) -> Vec<Vec<[f32; 3]>> {
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
    sig
}
