//! Steering MeshMatch with a global intrinsic shape map ([`crate::geometry::shape_map`]:
//! functional maps + ZoomOut) so that a transfer between similar shapes keeps the source's
//! layout.
//!
//! The map is computed once per solve between the finest hierarchy levels of at most
//! [`MAP_LEVEL_VERTICES`] vertices, with the correspondences as landmarks. It steers the solve
//! twice:
//! - **start**: every coarsest-level target vertex starts at the source vertex nearest to its
//!   mapped point (instead of a random source), and the exhaustive search that follows keeps the
//!   rotation search;
//! - **shape term**: every level's shape vectors get three more dimensions, the source vertex's
//!   position on the source and, for a target vertex, the source position of its mapped point
//!   (children means on coarser levels, the ancestor's value on finer ones), scaled to unit
//!   variance and weighted by the structure value ([`super::structure_weights`]): strongest at
//!   the coarsest level, decaying geometrically to the finest, so coarse levels follow the map and
//!   fine levels the colour (at structure 1 the map leads every level).

use crate::error::{Error, Result};
use std::sync::{Arc, Mutex};

use rayon::prelude::*;

use crate::features::Frames;
use crate::geometry::{FmapParams, Spectrum, functional_map, shape_map};
use crate::hierarchy::{Hierarchy, Level};
use crate::work::{CancelToken, Stopwatch};
use glam::Vec3;

/// Largest hierarchy level on which the map is computed.
pub(super) const MAP_LEVEL_VERTICES: usize = 8_000;
/// Final functional map size inside a solve.
pub(super) const SOLVE_MAP_K: usize = 100;

/// Per prepared mesh: its spectrum on the map level (level, k, spectrum) and, on a target, the
/// latest map (source cache identity, landmarks, map).
#[derive(Debug, Default)]
pub(crate) struct MapCache {
    spectrum: Mutex<Option<(usize, usize, Arc<Spectrum>)>>,
    map: Mutex<Option<CachedMap>>,
}

/// A target's latest map: the source's cache (by address), the landmarks and the map.
type CachedMap = (usize, Vec<(u32, u32)>, Arc<GlobalMap>);

impl MapCache {
    /// The cached spectrum of level `l` with `k` eigenpairs, if it is the one held.
    fn cached_spectrum(&self, l: usize, k: usize) -> Option<Arc<Spectrum>> {
        let g = self.spectrum.lock().ok()?;
        let (cl, ck, sp) = g.as_ref()?;
        (*cl == l && *ck == k).then(|| sp.clone())
    }

    fn store_spectrum(&self, l: usize, k: usize, sp: Arc<Spectrum>) {
        if let Ok(mut g) = self.spectrum.lock() {
            *g = Some((l, k, sp));
        }
    }
}

/// What the map reads of a prepared mesh: its hierarchy and the cache of its spectra and maps
/// (built beside the mesh's other tables when it is prepared).
#[derive(Clone, Copy)]
pub(super) struct MapSide<'a> {
    pub hierarchy: &'a Hierarchy,
    pub map_cache: &'a Arc<MapCache>,
}

/// A level's positions and faces, copied for a detached eigen-solve, with the cache it fills
/// and the level's index.
type SpectrumJob = (Vec<[f32; 3]>, Vec<[u32; 3]>, Arc<MapCache>, usize);

/// The spectra (`k` eigenpairs) of the source's level `ls` and the target's level `lt`, each
/// computed once per prepared mesh. The missing ones are computed together, detached
/// ([`crate::work::run_cancellable`]): the eigen-solves are long single calls, and cancel must not
/// wait for them.
fn spectra(
    source: MapSide<'_>,
    target: MapSide<'_>,
    (ls, lt): (usize, usize),
    k: usize,
    cancel: &CancelToken,
) -> Result<(Arc<Spectrum>, Arc<Spectrum>)> {
    let (cs, ct) = (
        source.map_cache.cached_spectrum(ls, k),
        target.map_cache.cached_spectrum(lt, k),
    );
    if let (Some(a), Some(b)) = (&cs, &ct) {
        return Ok((a.clone(), b.clone()));
    }
    // Each missing spectrum is stored in its mesh's cache as soon as it is computed, inside the
    // detached work: a cancelled solve's eigen-solves still fill the cache for the next one,
    // and one mesh's failure does not lose the other's spectrum.
    let job = |m: MapSide<'_>, l: usize, cached: &Option<Arc<Spectrum>>| {
        cached.is_none().then(|| {
            let lev = &m.hierarchy.levels[l];
            (
                lev.positions.clone(),
                lev.faces.clone(),
                m.map_cache.clone(),
                l,
            )
        })
    };
    let (need_s, need_t) = (job(source, ls, &cs), job(target, lt, &ct));
    let solve = move |j: Option<SpectrumJob>| -> Result<()> {
        if let Some((p, f, cache, l)) = j {
            cache.store_spectrum(l, k, Arc::new(Spectrum::new(&p, &f, k)?));
        }
        Ok(())
    };
    let (rs, rt) = crate::work::run_cancellable(cancel, move || {
        rayon::join(|| solve(need_s), || solve(need_t))
    })?;
    rs?;
    rt?;
    let get = |m: MapSide<'_>, l: usize| {
        m.map_cache.cached_spectrum(l, k).ok_or_else(|| {
            Error::InvalidInput("shape map: a spectrum was neither cached nor computed".into())
        })
    };
    Ok((get(source, ls)?, get(target, lt)?))
}

/// The map as the solve uses it.
#[derive(Debug)]
pub(super) struct GlobalMap {
    /// Per target level (`0..nl`): the source position of every vertex's mapped point; empty
    /// below the map's level, whose values [`GlobalMap::level_pos`] computes when a solve
    /// reaches them (at a million vertices carrying them to every level took a second before
    /// the first preview). They are not kept: a solve that reuses a cached map computes them
    /// again (about a second at a million vertices, spread over the fine levels), which keeps
    /// them out of the peak memory of a million-vertex solve.
    pub target_pos: Vec<Vec<[f32; 3]>>,
    /// The target level the map was computed on, its vertices' mapped positions and a tree of
    /// its triangles (over that level of the target's hierarchy), for [`GlobalMap::level_pos`].
    map_level: usize,
    base: Vec<[f32; 3]>,
    bvh: Option<crate::geometry::TriangleBvh>,
    /// Start source vertex (coarsest level `nl - 1`) of every coarsest-level target vertex.
    pub top_init: Vec<u32>,
    /// Source centroid and `1 / sqrt(mean squared distance to it)` (unit variance).
    pub centre: [f32; 3],
    pub scale: f32,
    /// Wall time, seconds, and its parts (eigenpairs, fit, ZoomOut, carrying it to the levels).
    pub seconds: f64,
    pub stages: Vec<(&'static str, f64)>,
    /// The map's isometry score ([`crate::geometry::MapQuality::score`]).
    pub score: f64,
}

impl GlobalMap {
    /// The source position of every mapped point of target level `l` (hierarchy `ht`, the one
    /// the map was computed on): the
    /// stored values on and above the map's level; below it, each vertex's closest point on the
    /// map level's surface and the barycentric blend of its corners' mapped positions, so the
    /// term is as fine as the level.
    pub(super) fn level_pos<'a>(
        &'a self,
        ht: &Hierarchy,
        l: usize,
    ) -> std::borrow::Cow<'a, [[f32; 3]]> {
        use std::borrow::Cow;
        match (&self.bvh, self.target_pos.get(l)) {
            (_, Some(p)) if !p.is_empty() || l >= self.map_level => Cow::Borrowed(p),
            (Some(bvh), _) => {
                let anc = ht.ancestor_map(l, self.map_level);
                let faces = &ht.levels[self.map_level].faces;
                Cow::Owned(
                    ht.levels[l]
                        .positions
                        .par_iter()
                        .zip(anc.par_iter())
                        .map(|(&p, &a)| {
                            blend_at(bvh, faces, &self.base, p).unwrap_or(self.base[a as usize])
                        })
                        .collect(),
                )
            }
            _ => Cow::Owned(Vec::new()),
        }
    }

    /// The rotation of each coarsest-level match from the map's transport of the local frame:
    /// every edge `(v, u)` of target vertex `v` has an angle in `v`'s frame and a mapped
    /// displacement `T(u) - T(v)` on the source, whose angle in the matched source vertex's frame
    /// is measured; the rotation index is the circular mean of the differences, weighted by the
    /// mapped edge lengths (a tangent direction at angle `φ` on the target arrives at `φ + k·step`
    /// on the source, as in the upsampling). Locked entries, and vertices whose mapped
    /// neighbourhood collapses, keep their rotation.
    pub(super) fn transport_rotations(
        &self,
        lt: &Level,
        ft: &Frames,
        fs: &Frames,
        nnf: &mut [(u32, u8)],
        locked: &[Option<u32>],
    ) {
        let Some(mapped) = self.target_pos.last() else {
            return;
        };
        if mapped.len() != lt.len() {
            return;
        }
        nnf.par_iter_mut().enumerate().for_each(|(v, e)| {
            if locked[v].is_some() {
                return;
            }
            let s = e.0 as usize;
            let (pv, mv) = (Vec3::from(lt.positions[v]), Vec3::from(mapped[v]));
            let (mut cx, mut cy) = (0.0f32, 0.0f32);
            for &u in lt.adjacency.row(v) {
                let dt = Vec3::from(lt.positions[u as usize]) - pv;
                let at = ft.angle(v, dt);
                let ds = Vec3::from(mapped[u as usize]) - mv;
                let (x, y) = fs.coords(s, ds);
                let len = x.hypot(y);
                if !(len > 0.0 && at.is_finite()) {
                    continue;
                }
                let d = y.atan2(x) - at;
                cx += len * d.cos();
                cy += len * d.sin();
            }
            if cx.hypot(cy) > 0.0 && cx.is_finite() && cy.is_finite() {
                e.1 = super::em::rot_index(cy.atan2(cx));
            }
        });
    }
}

/// The map's parameters inside a solve whose smaller map level has `nmin` vertices.
fn map_params(nmin: usize) -> FmapParams {
    FmapParams {
        k_final: SOLVE_MAP_K.min(nmin / 4),
        k_step: 10,
        ..FmapParams::default()
    }
}

/// Eigenpairs of each mesh's spectrum a map with `params` needs.
fn spectrum_size(params: &FmapParams) -> usize {
    params.k_final.max(params.k_init).max(params.k_descriptors)
}

/// The spectrum a solve's map will ask of a mesh with hierarchy `h`, as (level, eigenpairs),
/// when the other mesh's map level is no coarser and the solve keeps every level: computed
/// while the mesh is prepared ([`super::prepare`], beside the fan tables), it is found in the
/// mesh's cache by [`global_map`]. `None` for a mesh too coarse for a map.
pub(super) fn expected_spectrum(h: &Hierarchy) -> Option<(usize, usize)> {
    let l = map_level(h, h.num_levels());
    let params = map_params(h.levels[l].len());
    (params.k_final >= params.k_init).then(|| (l, spectrum_size(&params)))
}

impl MapCache {
    /// A cache holding the spectrum of level `l` with `k` eigenpairs.
    pub(super) fn with_spectrum(l: usize, k: usize, sp: Spectrum) -> MapCache {
        let cache = MapCache::default();
        cache.store_spectrum(l, k, Arc::new(sp));
        cache
    }
}

/// Finest level with at most `MAP_LEVEL_VERTICES` vertices (at most `nl - 1`).
fn map_level(h: &Hierarchy, nl: usize) -> usize {
    (0..nl)
        .find(|&l| h.levels[l].len() <= MAP_LEVEL_VERTICES)
        .unwrap_or(nl - 1)
}

/// The correspondences `pairs` (working vertices) as landmarks on the map levels `ls`, `lt`:
/// sorted, one per target vertex.
fn landmarks(
    hs: &Hierarchy,
    ht: &Hierarchy,
    pairs: &[(u32, Vec<u32>)],
    (ls, lt): (usize, usize),
) -> Vec<(u32, u32)> {
    let mut landmarks: Vec<(u32, u32)> = pairs
        .iter()
        .flat_map(|(s, ts)| {
            let s = hs.ancestor(0, *s, ls);
            ts.iter().map(move |&t| (s, ht.ancestor(0, t, lt)))
        })
        .collect();
    landmarks.sort_unstable();
    landmarks.dedup_by_key(|p| p.1);
    landmarks
}

/// The target's latest map, if it was computed from this source with `nl` levels, and whether
/// it was computed with these `landmarks`.
fn cached_map(
    source: MapSide<'_>,
    target: MapSide<'_>,
    landmarks: &[(u32, u32)],
    nl: usize,
) -> Option<(Arc<GlobalMap>, bool)> {
    let key = Arc::as_ptr(source.map_cache) as usize;
    let g = target.map_cache.map.lock().ok()?;
    let (k, l, m) = g.as_ref()?;
    (*k == key && m.target_pos.len() == nl).then(|| (m.clone(), l.as_slice() == landmarks))
}

/// The map an earlier solve on these two prepared meshes left, when the correspondences have
/// changed since (so [`global_map`] will compute a new one): the preview after a
/// correspondence edit starts from it while the new map is computed.
pub(super) fn previous_map(
    source: MapSide<'_>,
    target: MapSide<'_>,
    pairs: &[(u32, Vec<u32>)],
    nl: usize,
) -> Option<Arc<GlobalMap>> {
    let (hs, ht) = (&source.hierarchy, &target.hierarchy);
    let lv = (map_level(hs, nl), map_level(ht, nl));
    let (m, same) = cached_map(source, target, &landmarks(hs, ht, pairs, lv), nl)?;
    (!same).then_some(m)
}

/// Compute the map between the two prepared meshes (see the module docs). `pairs` are the
/// correspondences in working vertices.
pub(super) fn global_map(
    source: MapSide<'_>,
    target: MapSide<'_>,
    pairs: &[(u32, Vec<u32>)],
    nl: usize,
    cancel: &CancelToken,
) -> Result<Arc<GlobalMap>> {
    let clock = Stopwatch::start();
    let (hs, ht) = (&source.hierarchy, &target.hierarchy);
    let (ls, lt) = (map_level(hs, nl), map_level(ht, nl));
    let (ms, mt) = (&hs.levels[ls], &ht.levels[lt]);
    let nmin = ms.len().min(mt.len());
    let params = map_params(nmin);
    if params.k_final < params.k_init {
        return Err(Error::InvalidInput(format!(
            "shape map: meshes too coarse ({nmin} vertices)"
        )));
    }
    let landmarks = landmarks(hs, ht, pairs, (ls, lt));
    if let Some((m, same)) = cached_map(source, target, &landmarks, nl)
        && same
    {
        return Ok(m);
    }
    let key = Arc::as_ptr(source.map_cache) as usize;
    let k = spectrum_size(&params);
    let (ss, st) = spectra(source, target, (ls, lt), k, cancel)?;
    let eigen_s = clock.secs();
    cancel.check()?;
    let m = functional_map(&ss, &st, &landmarks, &params, cancel)?;
    let fit_s = clock.secs();
    // mapped source positions on the map level, then every target level
    let base: Vec<[f32; 3]> = m
        .target_to_source
        .iter()
        .map(|&s| ms.positions[s as usize])
        .collect();
    let mut target_pos: Vec<Vec<[f32; 3]>> = vec![Vec::new(); nl];
    for l in (lt + 1)..nl {
        let prev: &[[f32; 3]] = if l == lt + 1 {
            &base
        } else {
            &target_pos[l - 1]
        };
        let cur: Vec<[f32; 3]> = (0..ht.levels[l].len())
            .map(|p| {
                let ch = ht.children(l, p as u32);
                let mut a = [0.0f32; 3];
                for &c in ch {
                    for d in 0..3 {
                        a[d] += prev[c as usize][d];
                    }
                }
                a.map(|x| x / ch.len().max(1) as f32)
            })
            .collect();
        target_pos[l] = cur;
    }
    // Finer levels than the map's: computed when a solve reaches them (`level_pos`).
    let bvh = crate::geometry::TriangleBvh::new(&mt.positions, &mt.faces);
    target_pos[lt] = base.clone();
    // start: nearest coarsest-level source vertex to every mapped point
    let top = &hs.levels[nl - 1].positions;
    let d2 = |a: [f32; 3], b: [f32; 3]| (0..3).map(|i| (a[i] - b[i]).powi(2)).sum::<f32>();
    let top_init = target_pos[nl - 1]
        .iter()
        .map(|&p| {
            (0..top.len())
                .min_by(|&a, &b| d2(top[a], p).total_cmp(&d2(top[b], p)))
                .unwrap_or(0) as u32
        })
        .collect();
    let p0 = &hs.levels[0].positions;
    let n = p0.len().max(1) as f64;
    let mut c = [0.0f64; 3];
    for p in p0 {
        for d in 0..3 {
            c[d] += p[d] as f64 / n;
        }
    }
    let var: f64 = p0
        .iter()
        .map(|p| (0..3).map(|d| (p[d] as f64 - c[d]).powi(2)).sum::<f64>())
        .sum::<f64>()
        / n;
    let scale = if var > 0.0 {
        (1.0 / var.sqrt()) as f32
    } else {
        1.0
    };
    let g = Arc::new(GlobalMap {
        target_pos,
        map_level: lt,
        base,
        bvh: Some(bvh),
        top_init,
        centre: c.map(|x| x as f32),
        scale,
        seconds: clock.secs(),
        stages: vec![
            ("map eigen", eigen_s),
            ("map fit", m.timings.first().map_or(0.0, |t| t.1)),
            ("map zoomout", m.timings.get(1).map_or(0.0, |t| t.1)),
            ("map levels", clock.secs() - fit_s),
        ],
        score: m.quality.score(),
    });
    if let Ok(mut c) = target.map_cache.map.lock() {
        *c = Some((key, landmarks, g.clone()));
    }
    Ok(g)
}

/// The per-vertex `values` of a surface (`faces`, searched by `bvh`) blended barycentrically at
/// the closest point to `p`; `None` when there is none (empty surface, non-finite `p`).
fn blend_at(
    bvh: &crate::geometry::TriangleBvh,
    faces: &[[u32; 3]],
    values: &[[f32; 3]],
    p: [f32; 3],
) -> Option<[f32; 3]> {
    let (f, b, _) = bvh.closest_point(p)?;
    let mut q = [0.0f32; 3];
    for (k, &c) in faces[f as usize].iter().enumerate() {
        for d in 0..3 {
            q[d] += b[k] * values[c as usize][d];
        }
    }
    Some(q)
}

/// Map weight of level `l` of `nl` for structure `s` ([`super::structure_weights`]): the
/// coarsest weight at the coarsest level, geometric down to its fine fraction at the finest.
fn level_map_weight(s: f32, l: usize, nl: usize) -> f32 {
    let (coarse, fine) = super::structure_weights(s);
    let t = if nl > 1 {
        1.0 - l as f32 / (nl - 1) as f32
    } else {
        1.0
    };
    coarse * fine.powf(t)
}

/// Append the mapped-position dimensions to level `l`'s weighted shape vectors (`dsh` per vertex;
/// `structure` the structure value): returns the new vectors and dimension.
#[allow(clippy::too_many_arguments)]
pub(super) fn append_map_term(
    gm: &GlobalMap,
    hs: &Hierarchy,
    ht: &Hierarchy,
    shapes: (Vec<f32>, Vec<f32>, usize),
    l: usize,
    nl: usize,
    structure: f32,
) -> (Vec<f32>, Vec<f32>, usize) {
    let (s, t, dsh) = shapes;
    let g = level_map_weight(structure, l, nl).sqrt() * gm.scale;
    let add = |v: Vec<f32>, pos: &[[f32; 3]]| -> Vec<f32> {
        let mut out = Vec::with_capacity(pos.len() * (dsh + 3));
        for (i, p) in pos.iter().enumerate() {
            out.extend_from_slice(&v[i * dsh..(i + 1) * dsh]);
            for (x, c) in p.iter().zip(&gm.centre) {
                out.push(g * (x - c));
            }
        }
        out
    };
    (
        add(s, &hs.levels[l].positions),
        add(t, &gm.level_pos(ht, l)),
        dsh + 3,
    )
}

/// A point-to-point map between two meshes' file vertices ([`map_meshes`]).
#[derive(Clone, Debug)]
pub struct PointMap {
    /// Source file vertex of every target file vertex.
    pub target_to_source: Vec<u32>,
    /// The functional map's isometry score ([`crate::geometry::MapQuality::score`]).
    pub score: f64,
    /// Final functional map size.
    pub k: usize,
    /// Vertices of the surfaces the map was computed on (source, target).
    pub map_vertices: (usize, usize),
    /// Stage timings (seconds).
    pub timings: Vec<(String, f64)>,
}

/// Largest surface [`map_meshes`] computes the spectral map on directly; denser meshes are
/// simplified to it (the hierarchy's midpoint collapses) and the map is interpolated back.
pub const POINT_MAP_VERTICES: usize = 8_000;

/// The global intrinsic map between two meshes (functional maps + ZoomOut,
/// [`crate::geometry::shape_map`]) as a point map on every target file vertex, with the
/// correspondences as landmarks.
///
/// Both meshes are welded (UV seams closed) and, above [`POINT_MAP_VERTICES`], simplified. On a
/// simplified target every vertex takes the closest point of the simplified surface; its mapped
/// position is the barycentric blend of the corners' mapped source positions, and its source
/// vertex the welded source vertex nearest to that blend, so the map is finer than the surface
/// it was computed on.
pub fn map_meshes(
    source: &crate::mesh::TriMesh,
    target: &crate::mesh::TriMesh,
    corr: &[crate::correspondence::Correspondence],
    cancel: &CancelToken,
) -> Result<PointMap> {
    crate::correspondence::check_limits(corr)?;
    let mut timings = Vec::new();
    let clock = Stopwatch::start();
    let (s, t) = rayon::join(
        || simplified(source, "source", cancel),
        || simplified(target, "target", cancel),
    );
    let (s, t) = (s?, t?);
    timings.push(("simplify".to_string(), clock.secs()));
    cancel.check()?;
    let sf = file_to_welded(source, &s.input_to_welded);
    let tf = file_to_welded(target, &t.input_to_welded);
    let landmarks = map_landmarks(corr, (&sf, &s), (&tf, &t))?;
    let (ms, mt) = (&s.hierarchy.levels[s.level], &t.hierarchy.levels[t.level]);
    let nmin = ms.len().min(mt.len());
    let params = FmapParams {
        k_final: 100.min(nmin / 4),
        ..FmapParams::default()
    };
    if params.k_final < params.k_init {
        return Err(Error::InvalidInput(format!(
            "shape map: the meshes are too coarse ({nmin} vertices; at least {} needed)",
            4 * params.k_init
        )));
    }
    let m = shape_map(
        (&ms.positions, &ms.faces),
        (&mt.positions, &mt.faces),
        &landmarks,
        &params,
        cancel,
    )?;
    timings.extend(m.timings.iter().cloned());
    let clock = Stopwatch::start();
    let mut welded_map = welded_point_map(&s, &t, &m.target_to_source);
    // the landmarks' own target vertices keep their source vertex
    for c in corr {
        let s = sf[c.source_vertex as usize];
        for &t in &c.target_vertices {
            welded_map[tf[t as usize] as usize] = s;
        }
    }
    let target_to_source = file_point_map(&sf, &tf, &welded_map, s.hierarchy.levels[0].len());
    timings.push(("interpolate".to_string(), clock.secs()));
    Ok(PointMap {
        target_to_source,
        score: m.quality.score(),
        k: m.k,
        map_vertices: (ms.len(), mt.len()),
        timings,
    })
}

/// One mesh of a point map, welded and simplified.
struct Simplified {
    /// The welded mesh's hierarchy.
    hierarchy: Hierarchy,
    /// Welded vertex of every input vertex.
    input_to_welded: Vec<u32>,
    /// The level the shape map runs on: the finest of at most `POINT_MAP_VERTICES`.
    level: usize,
}

/// Weld a mesh (refusing one without faces or with non-finite coordinates) and build its
/// hierarchy down to the shape map's level.
fn simplified(m: &crate::mesh::TriMesh, what: &str, cancel: &CancelToken) -> Result<Simplified> {
    use crate::hierarchy::HierarchyOptions;
    if m.positions.is_empty() || m.faces.is_empty() {
        return Err(Error::InvalidMesh(format!(
            "the {what} mesh has no vertices or no faces"
        )));
    }
    m.check_finite()?;
    let (w, input_to_welded) = crate::geometry::weld(m);
    if w.faces.is_empty() {
        return Err(Error::InvalidMesh(format!(
            "the {what} mesh has no faces of non-zero size"
        )));
    }
    let h = Hierarchy::build_cancellable(
        &w.positions,
        &w.faces,
        HierarchyOptions {
            min_vertices: POINT_MAP_VERTICES,
            max_levels: None,
        },
        cancel,
    )?;
    let l = (0..h.num_levels())
        .find(|&l| h.levels[l].len() <= POINT_MAP_VERTICES)
        .unwrap_or(h.num_levels() - 1);
    Ok(Simplified {
        hierarchy: h,
        input_to_welded,
        level: l,
    })
}

/// File vertex -> welded vertex (through the first input vertex of each file vertex;
/// `u32::MAX` for a file vertex the mesh dropped).
fn file_to_welded(m: &crate::mesh::TriMesh, input_to_welded: &[u32]) -> Vec<u32> {
    let nf = m.file_vertex_count.max(m.positions.len());
    let mut out = vec![u32::MAX; nf];
    for (i, &w) in input_to_welded.iter().enumerate() {
        let f = m.file_index.get(i).copied().unwrap_or(i as u32) as usize;
        if f < nf && out[f] == u32::MAX {
            out[f] = w;
        }
    }
    out
}

/// The correspondences as landmark pairs of the shape map's levels (sorted, one per target
/// vertex); refuses a file vertex out of range.
fn map_landmarks(
    corr: &[crate::correspondence::Correspondence],
    (sf, s): (&[u32], &Simplified),
    (tf, t): (&[u32], &Simplified),
) -> Result<Vec<(u32, u32)>> {
    let mut landmarks = Vec::new();
    for c in corr {
        let sv = sf
            .get(c.source_vertex as usize)
            .copied()
            .filter(|&v| v != u32::MAX);
        let Some(sv) = sv else {
            return Err(Error::InvalidInput(format!(
                "correspondence source vertex {} is out of range (source has {} vertices)",
                c.source_vertex,
                sf.len()
            )));
        };
        for &tv in &c.target_vertices {
            let Some(tv) = tf.get(tv as usize).copied().filter(|&v| v != u32::MAX) else {
                return Err(Error::InvalidInput(format!(
                    "correspondence target vertex {tv} is out of range (target has {} vertices)",
                    tf.len()
                )));
            };
            landmarks.push((
                s.hierarchy.ancestor(0, sv, s.level),
                t.hierarchy.ancestor(0, tv, t.level),
            ));
        }
    }
    landmarks.sort_unstable();
    landmarks.dedup_by_key(|p| p.1);
    Ok(landmarks)
}

/// Welded target vertex -> welded source vertex: the coarse map's source positions blended at
/// each fine target vertex's closest point on the coarse target, then the nearest fine source
/// vertex (the coarse map itself where both levels are the finest).
fn welded_point_map(s: &Simplified, t: &Simplified, coarse_map: &[u32]) -> Vec<u32> {
    let (hs, ht, lt) = (&s.hierarchy, &t.hierarchy, t.level);
    let (ms, mt) = (&hs.levels[s.level], &ht.levels[lt]);
    let mapped: Vec<[f32; 3]> = coarse_map
        .iter()
        .map(|&s| ms.positions[s as usize])
        .collect();
    let fine_s = &hs.levels[0].positions;
    let fine_t = &ht.levels[0].positions;
    if lt == 0 && s.level == 0 {
        return coarse_map.to_vec();
    }
    let bvh = crate::geometry::TriangleBvh::new(&mt.positions, &mt.faces);
    let flat: Vec<f32> = fine_s.iter().flatten().copied().collect();
    let tree = crate::stats::kdtree::KdTree::new(&flat, 3);
    fine_t
        .par_iter()
        .enumerate()
        .map_init(Vec::new, |buf, (v, &p)| {
            let q = blend_at(&bvh, &mt.faces, &mapped, p)
                .unwrap_or_else(|| mapped[ht.ancestor(0, v as u32, lt) as usize]);
            tree.knn(&q, 1, buf);
            buf.first().map_or(0, |x| x.1)
        })
        .collect()
}

/// Target file vertex -> source file vertex, through the welded map (the first file vertex of
/// each welded source vertex; 0 where there is none).
fn file_point_map(sf: &[u32], tf: &[u32], welded_map: &[u32], source_welded: usize) -> Vec<u32> {
    let mut s_first = vec![u32::MAX; source_welded];
    for (f, &w) in sf.iter().enumerate() {
        if w != u32::MAX && s_first[w as usize] == u32::MAX {
            s_first[w as usize] = f as u32;
        }
    }
    tf.iter()
        .map(|&w| {
            if w == u32::MAX {
                0
            } else {
                let s = s_first[welded_map[w as usize] as usize];
                if s == u32::MAX { 0 } else { s }
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::features::{ANGLE_STEP_DEG, FAN_ANGLES};

    /// A flat grid mapped onto itself turned by `turn` degrees about its normal, with the
    /// source frames turned by `frame` degrees: a target direction at angle φ lands at
    /// φ + turn - frame in the source frame.
    fn rotations(turn: f32, frame: f32) -> Vec<u8> {
        let (positions, faces) = crate::testdata::grid(6);
        let level = Level::new(positions.clone(), faces);
        let (s, c) = turn.to_radians().sin_cos();
        let mapped: Vec<[f32; 3]> = positions
            .iter()
            .map(|p| [c * p[0] - s * p[1], s * p[0] + c * p[1], 0.0])
            .collect();
        let nv = positions.len();
        let ft = Frames {
            t1: vec![[1.0, 0.0, 0.0]; nv],
            t2: vec![[0.0, 1.0, 0.0]; nv],
        };
        let (fs_, fc) = frame.to_radians().sin_cos();
        let fs = Frames {
            t1: vec![[fc, fs_, 0.0]; nv],
            t2: vec![[-fs_, fc, 0.0]; nv],
        };
        let g = GlobalMap {
            target_pos: vec![mapped],
            map_level: 0,
            base: Vec::new(),
            bvh: None,
            top_init: (0..nv as u32).collect(),
            centre: [0.0; 3],
            scale: 1.0,
            seconds: 0.0,
            stages: Vec::new(),
            score: 1.0,
        };
        let mut nnf: Vec<(u32, u8)> = (0..nv as u32).map(|v| (v, 0)).collect();
        let mut locked = vec![None; nv];
        locked[0] = Some(0);
        g.transport_rotations(&level, &ft, &fs, &mut nnf, &locked);
        assert_eq!(nnf[0].1, 0, "a locked entry keeps its rotation");
        nnf[1..].iter().map(|e| e.1).collect()
    }

    #[test]
    fn start_rotations_follow_the_maps_transport_of_the_frame() {
        let step = ANGLE_STEP_DEG;
        for (turn, frame) in [(3.0 * step, 0.0), (3.0 * step, step), (-2.0 * step, 0.0)] {
            let want = (((turn - frame) / step).round() as i64).rem_euclid(FAN_ANGLES as i64) as u8;
            let got = rotations(turn, frame);
            assert!(
                got.iter().all(|&k| k == want),
                "turn {turn} frame {frame}: {got:?}, want {want}"
            );
        }
    }

    /// A preparation computes the spectrum the solve's map asks for, beside its fan tables,
    /// and it is the one the solve would compute itself; with the map off it computes none.
    #[test]
    fn a_prepared_mesh_holds_the_spectrum_its_solve_asks_for() {
        let (positions, faces) = crate::testdata::uv_sphere(48, 96);
        let mesh = crate::mesh::TriMesh::new(positions, faces);
        let params = super::super::TransferParams {
            vertices: 12_000,
            ..Default::default()
        };
        let cancel = CancelToken::new();
        let p = super::super::prepare(&mesh, &params, &crate::work::no_events, &cancel)
            .expect("prepared");
        let (l, k) = expected_spectrum(&p.hierarchy).expect("a mesh fine enough for a map");
        assert_eq!(l, map_level(&p.hierarchy, p.hierarchy.num_levels()));
        assert!(p.hierarchy.levels[l].len() <= MAP_LEVEL_VERTICES);
        assert_eq!(k, SOLVE_MAP_K);
        let held = p.map_cache.cached_spectrum(l, k).expect("held");
        let lev = &p.hierarchy.levels[l];
        let fresh = Spectrum::new(&lev.positions, &lev.faces, k).expect("spectrum");
        assert_eq!(held.evals, fresh.evals);
        assert_eq!(held.evecs, fresh.evecs);

        let off = super::super::TransferParams {
            structure: Some(0.0),
            ..params
        };
        let q =
            super::super::prepare(&mesh, &off, &crate::work::no_events, &cancel).expect("prepared");
        assert!(q.map_cache.cached_spectrum(l, k).is_none());
    }
}
