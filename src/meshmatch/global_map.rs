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
//!   variance and weighted [`MAP_WEIGHT`] at the coarsest level, decaying geometrically to
//!   `MAP_WEIGHT * MAP_FINE_SCALE` at the finest, so coarse levels follow the map and fine levels
//!   the colour.

use super::prepare::PreparedMesh;
use crate::error::{Error, Result};
use crate::geometry::{FmapParams, shape_map};
use crate::hierarchy::Hierarchy;
use crate::work::{CancelToken, Stopwatch};

/// Largest hierarchy level on which the map is computed.
pub(super) const MAP_LEVEL_VERTICES: usize = 6_000;
/// Weight of the mapped-position term at the coarsest level, relative to the automatic shape
/// features (both at unit total variance).
pub(super) const MAP_WEIGHT: f32 = 2.0;
/// The finest level's map weight as a fraction of [`MAP_WEIGHT`].
pub(super) const MAP_FINE_SCALE: f32 = 0.05;

/// The map as the solve uses it.
pub(super) struct GlobalMap {
    /// Per target level (`0..nl`): the source position of every vertex's mapped point.
    pub target_pos: Vec<Vec<[f32; 3]>>,
    /// Start source vertex (coarsest level `nl - 1`) of every coarsest-level target vertex.
    pub top_init: Vec<u32>,
    /// Source centroid and `1 / sqrt(mean squared distance to it)` (unit variance).
    pub centre: [f32; 3],
    pub scale: f32,
    /// Wall time, seconds.
    pub seconds: f64,
}

/// Finest level with at most `MAP_LEVEL_VERTICES` vertices (at most `nl - 1`).
fn map_level(h: &Hierarchy, nl: usize) -> usize {
    (0..nl)
        .find(|&l| h.levels[l].len() <= MAP_LEVEL_VERTICES)
        .unwrap_or(nl - 1)
}

/// Compute the map between the two prepared meshes (see the module docs). `pairs` are the
/// correspondences in working vertices.
pub(super) fn global_map(
    source: &PreparedMesh,
    target: &PreparedMesh,
    pairs: &[(u32, Vec<u32>)],
    nl: usize,
    cancel: &CancelToken,
) -> Result<GlobalMap> {
    let sw = Stopwatch::start();
    let (hs, ht) = (&source.hierarchy, &target.hierarchy);
    let (ls, lt) = (map_level(hs, nl), map_level(ht, nl));
    let (ms, mt) = (&hs.levels[ls], &ht.levels[lt]);
    let nmin = ms.len().min(mt.len());
    let params = FmapParams {
        k_final: 100.min(nmin / 4),
        k_step: 10,
        ..FmapParams::default()
    };
    if params.k_final < params.k_init {
        return Err(Error::InvalidInput(format!(
            "shape map: meshes too coarse ({nmin} vertices)"
        )));
    }
    let mut landmarks: Vec<(u32, u32)> = pairs
        .iter()
        .flat_map(|(s, ts)| {
            let s = hs.ancestor(0, *s, ls);
            ts.iter().map(move |&t| (s, ht.ancestor(0, t, lt)))
        })
        .collect();
    landmarks.sort_unstable();
    landmarks.dedup_by_key(|p| p.1);
    let m = shape_map(
        (&ms.positions, &ms.faces),
        (&mt.positions, &mt.faces),
        &landmarks,
        &params,
        cancel,
    )?;
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
    for (l, slot) in target_pos.iter_mut().enumerate().take(lt + 1) {
        *slot = ht
            .ancestor_map(l, lt)
            .iter()
            .map(|&a| base[a as usize])
            .collect();
    }
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
    Ok(GlobalMap {
        target_pos,
        top_init,
        centre: c.map(|x| x as f32),
        scale,
        seconds: sw.secs(),
    })
}

/// Map weight multiplier of level `l` of `nl`: `MAP_WEIGHT` at the coarsest, geometric down to
/// `MAP_WEIGHT * MAP_FINE_SCALE` at the finest.
fn level_map_weight(l: usize, nl: usize) -> f32 {
    let t = if nl > 1 {
        1.0 - l as f32 / (nl - 1) as f32
    } else {
        1.0
    };
    MAP_WEIGHT * MAP_FINE_SCALE.powf(t)
}

/// Append the mapped-position dimensions to level `l`'s weighted shape vectors (`dsh` per vertex;
/// `w` the level's shape weight): returns the new vectors and dimension.
pub(super) fn append_map_term(
    gm: &GlobalMap,
    hs: &Hierarchy,
    shapes: (Vec<f32>, Vec<f32>, usize),
    l: usize,
    nl: usize,
    w: f32,
) -> (Vec<f32>, Vec<f32>, usize) {
    let (s, t, dsh) = shapes;
    let g = (w.max(0.0) * level_map_weight(l, nl)).sqrt() * gm.scale;
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
        add(t, &gm.target_pos[l]),
        dsh + 3,
    )
}
