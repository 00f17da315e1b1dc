//! Multiresolution mesh hierarchy for MeshMatch (Chen et al. 2012, "Non-parametric texture
//! transfer using MeshMatch", §3 and §4.2).
//!
//! Level 0 is the input mesh. Each coarser level is made by collapsing edges shortest-first with
//! the new vertex at the edge midpoint, every vertex taking part in at most one collapse per level
//! (so a level keeps about half the vertices of the one below, spacing grows by ~sqrt(2)). A
//! collapse is accepted only when it passes the link condition (Dey et al. 1999: the common
//! neighbours of the edge's ends are exactly the apexes of its faces) and flips no face normal,
//! so closed manifold input stays closed and manifold.
//!
//! The vertex tree links levels: `parent(l, v)` is the vertex of level `l + 1` that vertex `v` of
//! level `l` collapsed into, and `children(l + 1, p)` lists the level-`l` vertices under `p`.

use crate::error::{Error, Result};
use crate::mesh::{Csr, vertex_adjacency};
use glam::Vec3;
use rand::Rng;
use rayon::slice::ParallelSliceMut;

/// One level of the hierarchy: a triangle mesh with its adjacency, normals and edge scale.
#[derive(Clone, Debug, Default)]
pub struct Level {
    /// Vertex positions.
    pub positions: Vec<[f32; 3]>,
    /// Triangles.
    pub faces: Vec<[u32; 3]>,
    /// Sorted CSR vertex adjacency.
    pub adjacency: Csr,
    /// Area-weighted unit vertex normals.
    pub normals: Vec<[f32; 3]>,
    /// Mean edge length of this level.
    pub mean_edge: f32,
}

impl Level {
    /// A level from positions and faces (adjacency, normals and mean edge length computed).
    pub fn new(positions: Vec<[f32; 3]>, faces: Vec<[u32; 3]>) -> Level {
        let adjacency = vertex_adjacency(positions.len(), &faces);
        let normals = area_weighted_normals(&positions, &faces);
        let mut sum = 0.0f64;
        let mut cnt = 0usize;
        for (i, p) in positions.iter().enumerate() {
            for &j in adjacency.row(i) {
                if (j as usize) > i {
                    sum += (Vec3::from(*p) - Vec3::from(positions[j as usize])).length() as f64;
                    cnt += 1;
                }
            }
        }
        let mean_edge = if cnt > 0 {
            (sum / cnt as f64) as f32
        } else {
            1.0
        };
        Level {
            positions,
            faces,
            adjacency,
            normals,
            mean_edge,
        }
    }

    /// Number of vertices.
    pub fn len(&self) -> usize {
        self.positions.len()
    }

    /// True for a level without vertices.
    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }
}

/// Area-weighted vertex normals: n_v = normalize(sum over incident faces of (b - a) x (c - a)).
pub fn area_weighted_normals(positions: &[[f32; 3]], faces: &[[u32; 3]]) -> Vec<[f32; 3]> {
    let mut acc = vec![Vec3::ZERO; positions.len()];
    for f in faces {
        let [a, b, c] = f.map(|i| Vec3::from(positions[i as usize]));
        let n = (b - a).cross(c - a);
        for &i in f {
            acc[i as usize] += n;
        }
    }
    acc.iter()
        .map(|n| {
            let l = n.length();
            if l > 0.0 && l.is_finite() {
                (*n / l).to_array()
            } else {
                [0.0, 0.0, 1.0]
            }
        })
        .collect()
}

/// The multiresolution hierarchy: levels finest (0) to coarsest, with the vertex tree.
#[derive(Clone, Debug, Default)]
pub struct Hierarchy {
    /// Levels, `levels[0]` = the input mesh.
    pub levels: Vec<Level>,
    /// `parents[l][v]`: vertex of level `l + 1` that vertex `v` of level `l` belongs to.
    pub parents: Vec<Vec<u32>>,
    /// `children[l]`: CSR over vertices of level `l + 1`, listing their level-`l` children.
    pub children: Vec<Csr>,
}

/// Options for [`Hierarchy::build`].
#[derive(Clone, Copy, Debug)]
pub struct HierarchyOptions {
    /// Stop when a level has at most this many vertices (default 128).
    pub min_vertices: usize,
    /// Stop at this many levels in all (including level 0); `None` = until `min_vertices`.
    pub max_levels: Option<usize>,
}

impl Default for HierarchyOptions {
    fn default() -> Self {
        HierarchyOptions {
            min_vertices: 128,
            max_levels: None,
        }
    }
}

impl Hierarchy {
    /// Build the hierarchy of a triangle mesh by shortest-edge-first midpoint collapses (MeshMatch
    /// §3: about half the vertices per level, stop near `min_vertices`).
    pub fn build(
        positions: &[[f32; 3]],
        faces: &[[u32; 3]],
        opts: HierarchyOptions,
    ) -> Result<Hierarchy> {
        Self::build_cancellable(positions, faces, opts, &crate::work::CancelToken::new())
    }

    /// [`Hierarchy::build`] that checks `cancel` before every level and stops with
    /// [`Error::Cancelled`] once it is set.
    pub fn build_cancellable(
        positions: &[[f32; 3]],
        faces: &[[u32; 3]],
        opts: HierarchyOptions,
        cancel: &crate::work::CancelToken,
    ) -> Result<Hierarchy> {
        Self::build_keyed(positions, faces, None, opts, cancel)
    }

    /// [`Hierarchy::build_cancellable`] breaking ties between equally long edges by `tie_keys`
    /// (one distinct key per vertex; `None`: the vertex indices). The collapses depend on the
    /// keys' order only, so a mesh renumbered with its old indices as keys gets the same
    /// hierarchy, renumbered: on regular meshes, where most edges tie, the tie order decides the
    /// hierarchy's shape.
    pub fn build_keyed(
        positions: &[[f32; 3]],
        faces: &[[u32; 3]],
        tie_keys: Option<&[u32]>,
        opts: HierarchyOptions,
        cancel: &crate::work::CancelToken,
    ) -> Result<Hierarchy> {
        if tie_keys.is_some_and(|k| k.len() != positions.len()) {
            return Err(Error::InvalidInput(
                "hierarchy: one tie key per vertex is needed".into(),
            ));
        }
        if positions.is_empty() || faces.is_empty() {
            return Err(Error::InvalidMesh(
                "hierarchy: the mesh has no vertices or no faces".into(),
            ));
        }
        let n = positions.len() as u32;
        if faces.iter().any(|f| f.iter().any(|&i| i >= n)) {
            return Err(Error::InvalidMesh(
                "hierarchy: a face references a missing vertex".into(),
            ));
        }
        let mut h = Hierarchy {
            levels: vec![Level::new(positions.to_vec(), faces.to_vec())],
            ..Default::default()
        };
        let max_levels = opts.max_levels.unwrap_or(usize::MAX).max(1);
        let min_v = opts.min_vertices.max(4);
        let mut keys: Vec<u32> = match tie_keys {
            Some(k) => k.to_vec(),
            None => (0..n).collect(),
        };
        while h.levels.len() < max_levels {
            cancel.check()?;
            let cur = h.levels.last().expect("one level");
            if cur.len() <= min_v {
                break;
            }
            let target = (cur.len() / 2).max(min_v);
            let (next, parent, next_keys) = collapse_level(cur, target, &keys);
            keys = next_keys;
            // A level that barely shrank (collapses blocked everywhere) ends the hierarchy.
            if next.len() as f64 > 0.9 * cur.len() as f64 || next.faces.is_empty() {
                break;
            }
            let mut pairs: Vec<(u32, u32)> = parent
                .iter()
                .enumerate()
                .map(|(v, &p)| (p, v as u32))
                .collect();
            let children = Csr::from_pairs(next.len(), &mut pairs);
            h.levels.push(next);
            h.parents.push(parent);
            h.children.push(children);
        }
        Ok(h)
    }

    /// Number of levels.
    pub fn num_levels(&self) -> usize {
        self.levels.len()
    }

    /// Index of the coarsest level.
    pub fn top(&self) -> usize {
        self.levels.len() - 1
    }

    /// Project vertex `v` of level `l` onto level `l + 1` (its parent in the vertex tree).
    #[inline]
    pub fn parent(&self, l: usize, v: u32) -> u32 {
        self.parents[l][v as usize]
    }

    /// Children (in level `l - 1`) of vertex `v` of level `l >= 1`.
    #[inline]
    pub fn children(&self, l: usize, v: u32) -> &[u32] {
        self.children[l - 1].row(v as usize)
    }

    /// The ancestor of vertex `v` of level `l` at level `to >= l`.
    #[inline]
    pub fn ancestor(&self, l: usize, v: u32, to: usize) -> u32 {
        let mut v = v;
        for k in l..to.min(self.top()) {
            v = self.parents[k][v as usize];
        }
        v
    }

    /// Map from every vertex of level `l` to its ancestor at level `to >= l`.
    pub fn ancestor_map(&self, l: usize, to: usize) -> Vec<u32> {
        let mut map: Vec<u32> = (0..self.levels[l].len() as u32).collect();
        for k in l..to.min(self.top()) {
            for m in map.iter_mut() {
                *m = self.parents[k][*m as usize];
            }
        }
        map
    }

    /// Random hop (MeshMatch §4.2): from vertex `v` of level `l`, go up `j` levels through the
    /// parents, then back down to level `l` choosing a random child at every step. The result
    /// lies at a distance of roughly sqrt(2)^j edge lengths from `v`.
    pub fn random_hop<R: Rng>(&self, l: usize, v: u32, j: usize, rng: &mut R) -> u32 {
        let up = (l + j).min(self.top());
        let mut u = self.ancestor(l, v, up);
        for k in (l + 1..=up).rev() {
            let ch = self.children(k, u);
            u = ch[rng.random_range(0..ch.len())];
        }
        u
    }

    /// Expand per-vertex values at level `l` to level 0 (each vertex takes its ancestor's value).
    pub fn expand_to_finest<T: Copy>(&self, l: usize, values: &[T]) -> Vec<T> {
        self.ancestor_map(0, l)
            .iter()
            .map(|&a| values[a as usize])
            .collect()
    }
}

/// Collapse-order bins per octave of edge length: lengths within about 0.3% of each other (the
/// same bin) count as ties, broken by the vertices' keys.
const BINS_PER_OCTAVE: f64 = 256.0;

/// The collapse order's key of a squared edge length: its bin on a log scale relative to
/// `mean`, the mean squared edge length, the same for the mesh in any units. Bins this wide
/// (rather than the lengths' last bits) decide the order, so that a mesh 1000 times larger,
/// rounded differently, collapses the same way: a length lands in another bin only when it lies
/// within rounding of a bin's edge.
fn length_bins(mean: f64) -> impl Fn(f32) -> u32 {
    let ok = mean > 0.0 && mean.is_finite();
    move |l2: f32| {
        if !ok || l2 <= 0.0 || !l2.is_finite() {
            return if l2 > 0.0 { u32::MAX } else { 0 };
        }
        // half the log2 of the squared ratio: octaves of length, from 2^-64 of the mean up
        let octaves = 0.5 * (l2 as f64 / mean).log2() + 64.0;
        (octaves * BINS_PER_OCTAVE)
            .floor()
            .clamp(1.0, u32::MAX as f64) as u32
    }
}

/// One level of collapses: a greedy shortest-first matching of edges, each accepted collapse
/// merging its two (so far untouched) ends into their midpoint. Equally long edges are taken in
/// the order of their ends' `keys` (lower, then higher), and the end with the lower key
/// survives. Returns the coarse level, the parent of every fine vertex and the coarse vertices'
/// keys (their survivors').
///
/// The steps: [`VertexFaces::new`] (incident faces), [`collapse_order`] (edges shortest first),
/// then per edge [`passes_link_condition`] and [`flips_a_face`], and [`compact`] (the coarse
/// level from the surviving vertices).
fn collapse_level(fine: &Level, target: usize, keys: &[u32]) -> (Level, Vec<u32>, Vec<u32>) {
    let n = fine.len();
    let vf = VertexFaces::new(n, &fine.faces);
    let edges = collapse_order(fine, keys);
    let mut state = Collapsing {
        rep: (0..n as u32).collect(),
        touched: vec![false; n],
        cur: fine.positions.iter().map(|p| Vec3::from(*p)).collect(),
        remaining: n,
    };
    let mut na: Vec<u32> = Vec::with_capacity(32);
    let mut nb: Vec<u32> = Vec::with_capacity(32);
    for &(_, _, _, a, b) in &edges {
        if state.remaining <= target {
            break;
        }
        if state.touched[a as usize] || state.touched[b as usize] {
            continue;
        }
        if !passes_link_condition(&fine.faces, &vf, &state.rep, a, b, (&mut na, &mut nb)) {
            continue;
        }
        let mid = 0.5 * (state.cur[a as usize] + state.cur[b as usize]);
        if flips_a_face(fine, &vf, &state, (a, b), mid) {
            continue;
        }
        state.touched[a as usize] = true;
        state.touched[b as usize] = true;
        state.rep[b as usize] = a;
        state.cur[a as usize] = mid;
        state.remaining -= 1;
    }
    compact(&fine.faces, keys, &state)
}

/// Vertex -> incident faces (CSR).
struct VertexFaces {
    off: Vec<u32>,
    faces: Vec<u32>,
}

impl VertexFaces {
    /// The faces incident to each of the `n` vertices.
    fn new(n: usize, faces: &[[u32; 3]]) -> VertexFaces {
        let mut vf_off = vec![0u32; n + 1];
        for f in faces {
            for &i in f {
                vf_off[i as usize + 1] += 1;
            }
        }
        for i in 0..n {
            vf_off[i + 1] += vf_off[i];
        }
        let mut fill = vf_off.clone();
        let mut vf = vec![0u32; vf_off[n] as usize];
        for (fi, f) in faces.iter().enumerate() {
            for &i in f {
                vf[fill[i as usize] as usize] = fi as u32;
                fill[i as usize] += 1;
            }
        }
        VertexFaces {
            off: vf_off,
            faces: vf,
        }
    }

    /// The faces incident to vertex `v`.
    fn row(&self, v: u32) -> &[u32] {
        &self.faces[self.off[v as usize] as usize..self.off[v as usize + 1] as usize]
    }
}

/// The state of a level's collapses.
struct Collapsing {
    /// Per fine vertex, the vertex it has merged into (itself while it survives).
    rep: Vec<u32>,
    /// Vertices that took part in a collapse of this level.
    touched: Vec<bool>,
    /// Current positions (a survivor at its collapse's midpoint).
    cur: Vec<Vec3>,
    /// Vertices left.
    remaining: usize,
}

/// The candidate edges `(length bin, lower key, higher key, end with the lower key, other end)`
/// shortest first (lengths of untouched vertices never change in a level), lengths compared in
/// bins (not to their last bits) so the order is the same for the mesh in any units, ties by
/// the ends' keys.
fn collapse_order(fine: &Level, keys: &[u32]) -> Vec<(u32, u32, u32, u32, u32)> {
    let n = fine.len();
    let pos = &fine.positions;
    let adj = &fine.adjacency;
    let mut edges: Vec<(u32, u32, u32, u32, u32)> = Vec::with_capacity(adj.indices.len() / 2);
    let squared = |a: usize, b: usize| (Vec3::from(pos[a]) - Vec3::from(pos[b])).length_squared();
    let bin = {
        let (mut sum, mut count) = (0.0f64, 0usize);
        for a in 0..n {
            for &b in adj.row(a).iter().filter(|&&b| b as usize > a) {
                sum += squared(a, b as usize) as f64;
                count += 1;
            }
        }
        length_bins(sum / count.max(1) as f64)
    };
    for a in 0..n {
        for &b in adj.row(a) {
            if (b as usize) > a {
                let l = bin(squared(a, b as usize));
                let (ka, kb) = (keys[a], keys[b as usize]);
                edges.push(if ka <= kb {
                    (l, ka, kb, a as u32, b)
                } else {
                    (l, kb, ka, b, a as u32)
                });
            }
        }
    }
    // a total order (ties by the ends' keys), so the parallel sort gives the one result
    edges.par_sort_unstable_by(|x, y| {
        x.0.cmp(&y.0)
            .then(x.1.cmp(&y.1))
            .then(x.2.cmp(&y.2))
            .then(x.3.cmp(&y.3))
    });
    edges
}

/// Whether collapsing edge `ab` keeps the mesh manifold: its ends' common neighbours (through
/// the representatives) are exactly the apexes of its live faces, and the merged vertex keeps a
/// valence of at least 3. `na`, `nb` are scratch buffers.
fn passes_link_condition(
    faces: &[[u32; 3]],
    vf: &VertexFaces,
    rep: &[u32],
    a: u32,
    b: u32,
    (na, nb): (&mut Vec<u32>, &mut Vec<u32>),
) -> bool {
    let r = |i: u32| rep[i as usize];
    let live = |f: &[u32; 3]| {
        let q = f.map(r);
        q[0] != q[1] && q[1] != q[2] && q[0] != q[2]
    };
    // Current neighbour sets (through representatives) and the live faces on edge (a, b).
    na.clear();
    nb.clear();
    let mut shared_faces = 0usize;
    for &fi in vf.row(a) {
        let f = &faces[fi as usize];
        if !live(f) {
            continue;
        }
        let q = f.map(r);
        if q.contains(&b) {
            shared_faces += 1;
        }
        for &x in &q {
            if x != a {
                na.push(x);
            }
        }
    }
    for &fi in vf.row(b) {
        let f = &faces[fi as usize];
        if !live(f) {
            continue;
        }
        let q = f.map(r);
        for &x in &q {
            if x != b {
                nb.push(x);
            }
        }
    }
    na.sort_unstable();
    na.dedup();
    nb.sort_unstable();
    nb.dedup();
    let common = na
        .iter()
        .filter(|x| **x != b && nb.binary_search(x).is_ok())
        .count();
    if shared_faces == 0 || common != shared_faces {
        return false;
    }
    // Keep a vertex valence of at least 3 around the merged vertex.
    na.len() + nb.len() >= common + 2 + 3 + 2
}

/// Whether moving `a` and `b` to `mid` flips (or nearly flips) a surviving face, compared with
/// the face's normal at the start of the level, so that several collapses around one face
/// cannot add up to a flip.
fn flips_a_face(
    fine: &Level,
    vf: &VertexFaces,
    state: &Collapsing,
    (a, b): (u32, u32),
    mid: Vec3,
) -> bool {
    let (faces, pos, cur) = (&fine.faces, &fine.positions, &state.cur);
    for &fi in vf.row(a).iter().chain(vf.row(b).iter()) {
        let f = &faces[fi as usize];
        let q = f.map(|i| state.rep[i as usize]);
        if q[0] == q[1] || q[1] == q[2] || q[0] == q[2] {
            continue;
        }
        if q.contains(&a) && q.contains(&b) {
            continue;
        }
        let p = f.map(|i| Vec3::from(pos[i as usize]));
        let n0 = (p[1] - p[0]).cross(p[2] - p[0]);
        let moved = q.map(|i| {
            if i == a || i == b {
                mid
            } else {
                cur[i as usize]
            }
        });
        let n1 = (moved[1] - moved[0]).cross(moved[2] - moved[0]);
        let l0 = n0.length();
        let l1 = n1.length();
        if l1 <= 1e-12 * l0 || n0.dot(n1) < 0.5 * l0 * l1 {
            return true;
        }
    }
    false
}

/// The coarse level from the surviving representatives (in fine order), the parent of every
/// fine vertex and the survivors' keys; faces collapsed to an edge or a point are dropped.
fn compact(faces: &[[u32; 3]], keys: &[u32], state: &Collapsing) -> (Level, Vec<u32>, Vec<u32>) {
    let (rep, cur) = (&state.rep, &state.cur);
    let n = rep.len();
    let mut new_index = vec![u32::MAX; n];
    let mut positions = Vec::with_capacity(state.remaining);
    let mut coarse_keys = Vec::with_capacity(state.remaining);
    for v in 0..n {
        if rep[v] == v as u32 {
            new_index[v] = positions.len() as u32;
            positions.push(cur[v].to_array());
            coarse_keys.push(keys[v]);
        }
    }
    let parent: Vec<u32> = (0..n).map(|v| new_index[rep[v] as usize]).collect();
    let mut new_faces: Vec<[u32; 3]> = Vec::with_capacity(faces.len());
    for f in faces {
        let q = f.map(|i| parent[i as usize]);
        if q[0] != q[1] && q[1] != q[2] && q[0] != q[2] {
            new_faces.push(q);
        }
    }
    (Level::new(positions, new_faces), parent, coarse_keys)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand::rngs::SmallRng;
    use std::collections::HashMap;

    use crate::testdata::flat_split_icosphere as icosphere;

    fn check_closed_manifold(l: &Level) {
        let mut edges: HashMap<(u32, u32), usize> = HashMap::new();
        for f in &l.faces {
            for k in 0..3 {
                *edges.entry((f[k], f[(k + 1) % 3])).or_default() += 1;
            }
        }
        for (&(a, b), &c) in &edges {
            assert_eq!(c, 1, "directed edge ({a},{b}) used {c} times");
            assert!(edges.contains_key(&(b, a)), "edge ({a},{b}) has no twin");
        }
        // Euler characteristic of a sphere.
        let e = edges.len() / 2;
        assert_eq!(l.len() as i64 - e as i64 + l.faces.len() as i64, 2);
    }

    #[test]
    fn sphere_hierarchy_halves_and_stays_manifold() {
        let (p, f) = icosphere(6); // 40962 vertices
        let t = std::time::Instant::now();
        let h = Hierarchy::build(&p, &f, HierarchyOptions::default()).unwrap();
        let secs = t.elapsed().as_secs_f64();
        let sizes: Vec<usize> = h.levels.iter().map(|l| l.len()).collect();
        println!("levels {sizes:?} in {secs:.3}s");
        assert!(secs < 2.0);
        assert!(*sizes.last().unwrap() <= 200, "{sizes:?}");
        for w in sizes.windows(2) {
            let ratio = w[1] as f64 / w[0] as f64;
            assert!((0.45..0.75).contains(&ratio), "{sizes:?}");
        }
        for (li, l) in h.levels.iter().enumerate() {
            check_closed_manifold(l);
            let mut worst = 1.0f32;
            // Normals of a sphere point outwards: no flipped faces.
            for face in &l.faces {
                let [a, b, c] = face.map(|i| Vec3::from(l.positions[i as usize]));
                let n = (b - a).cross(c - a);
                worst = worst.min(n.normalize().dot((a + b + c).normalize()));
            }
            println!("level {li}: worst normal/radial cosine {worst:.3}");
            assert!(worst > 0.0, "level {li} has an inward face");
        }
        // Spacing grows by about sqrt(2) per level.
        for w in h.levels.windows(2) {
            let r = w[1].mean_edge / w[0].mean_edge;
            assert!((1.2..1.7).contains(&r), "edge ratio {r}");
        }
        // Tree consistency: children lists invert parents.
        for l in 0..h.top() {
            for v in 0..h.levels[l].len() as u32 {
                let p = h.parent(l, v);
                assert!(h.children(l + 1, p).contains(&v));
            }
        }
    }

    #[test]
    fn random_hops_grow_with_j() {
        let (p, f) = icosphere(5);
        let h = Hierarchy::build(&p, &f, HierarchyOptions::default()).unwrap();
        let mut rng = SmallRng::seed_from_u64(1);
        let l0 = &h.levels[0];
        let mut prev = 0.0;
        for j in 1..=6 {
            let mut sum = 0.0;
            for s in 0..2000u32 {
                let v = s * 5;
                let u = h.random_hop(0, v, j, &mut rng);
                sum += (Vec3::from(l0.positions[v as usize])
                    - Vec3::from(l0.positions[u as usize]))
                .length();
            }
            let mean = sum / 2000.0 / l0.mean_edge;
            println!("j={j}: mean hop {mean:.2} edges");
            assert!(mean > prev, "hop distance should grow with j");
            prev = mean;
        }
        assert!(prev > 3.0);
    }

    /// A regular grid (every edge ties with thousands of others) renumbered in Morton order,
    /// with its old indices as tie keys, gets the grid's own hierarchy: the same vertex tree and
    /// positions at every level, up to the renumbering.
    #[test]
    fn renumbered_mesh_with_old_indices_as_keys_gets_the_same_hierarchy() {
        let (p, f) = crate::testdata::grid(48);
        let opts = HierarchyOptions::default();
        let plain = Hierarchy::build(&p, &f, opts).unwrap();
        let order = crate::geometry::morton_order(&p);
        assert!(order.iter().enumerate().any(|(i, &o)| i as u32 != o));
        let renumber = crate::geometry::inverse_order(&order);
        let pm: Vec<[f32; 3]> = order.iter().map(|&o| p[o as usize]).collect();
        let fm: Vec<[u32; 3]> = f.iter().map(|t| t.map(|v| renumber[v as usize])).collect();
        let keyed = Hierarchy::build_keyed(
            &pm,
            &fm,
            Some(&order),
            opts,
            &crate::work::CancelToken::new(),
        )
        .unwrap();
        let unkeyed = Hierarchy::build(&pm, &fm, opts).unwrap();
        assert_eq!(keyed.num_levels(), plain.num_levels());
        // a coarse vertex is the same when its (sorted) finest descendants are
        let descendants = |h: &Hierarchy, l: usize, to_old: &dyn Fn(u32) -> u32| {
            let mut sets = vec![Vec::new(); h.levels[l].len()];
            for (v, &a) in h.ancestor_map(0, l).iter().enumerate() {
                sets[a as usize].push(to_old(v as u32));
            }
            for s in &mut sets {
                s.sort_unstable();
            }
            sets.sort();
            sets
        };
        let mut differs_without_keys = false;
        for l in 1..plain.num_levels() {
            assert_eq!(keyed.levels[l].len(), plain.levels[l].len(), "level {l}");
            let a = descendants(&plain, l, &|v| v);
            let b = descendants(&keyed, l, &|v| order[v as usize]);
            assert_eq!(a, b, "level {l}: the vertex trees differ");
            let mut pa = plain.levels[l].positions.clone();
            let mut pb = keyed.levels[l].positions.clone();
            pa.sort_by(|x, y| x.partial_cmp(y).unwrap());
            pb.sort_by(|x, y| x.partial_cmp(y).unwrap());
            assert_eq!(pa, pb, "level {l}: positions differ");
            if l < unkeyed.num_levels() {
                differs_without_keys |= descendants(&unkeyed, l, &|v| order[v as usize]) != a;
            }
        }
        // without the keys the renumbering changes the hierarchy (what the keys are for)
        assert!(differs_without_keys);
    }
}
