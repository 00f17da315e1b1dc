//! Working-resolution refinement by longest-edge bisection.

use std::cmp::Reverse;
use std::collections::{BinaryHeap, HashMap};
use std::hash::{BuildHasherDefault, Hasher};

use glam::Vec3;

use crate::color::{linear_to_srgb, srgb_to_linear};
use crate::mesh::{SignalKind, TriMesh};

/// A multiplicative hasher for integer keys (the edge map is the hot loop of refinement).
#[derive(Default)]
pub(crate) struct IntHasher(u64);

impl Hasher for IntHasher {
    fn finish(&self) -> u64 {
        // the product's entropy is in its high bits; fold them into the low bits that pick
        // the bucket
        self.0 ^ (self.0 >> 29)
    }
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.write_u64(b as u64);
        }
    }
    fn write_u64(&mut self, x: u64) {
        self.0 = (self.0.rotate_left(5) ^ x).wrapping_mul(0x517c_c1b7_2722_0a95);
    }
}

/// A hash map on integer keys with a fast multiplicative hash.
pub(crate) type IntMap<V> = HashMap<u64, V, BuildHasherDefault<IntHasher>>;

#[inline]
fn edge_key(a: u32, b: u32) -> u64 {
    let (lo, hi) = if a < b { (a, b) } else { (b, a) };
    ((lo as u64) << 32) | hi as u64
}

/// The faces using one edge: two inline slots, overflow only for non-manifold edges.
#[derive(Default)]
struct EdgeFaces {
    f: [u32; 2],
    n: u8,
    extra: Vec<u32>,
}

impl EdgeFaces {
    fn push(&mut self, f: u32) {
        if (self.n as usize) < 2 {
            self.f[self.n as usize] = f;
        } else {
            self.extra.push(f);
        }
        self.n = self.n.saturating_add(1);
    }
    fn replace(&mut self, old: u32, new: u32) {
        for s in self.f.iter_mut().take((self.n as usize).min(2)) {
            if *s == old {
                *s = new;
                return;
            }
        }
        for s in &mut self.extra {
            if *s == old {
                *s = new;
                return;
            }
        }
    }
    fn list(&self) -> impl Iterator<Item = u32> + '_ {
        self.f[..(self.n as usize).min(2)]
            .iter()
            .copied()
            .chain(self.extra.iter().copied())
    }
}

/// A refined mesh and where its vertices and faces came from.
#[derive(Clone, Debug)]
pub struct Refined {
    /// The refined mesh: its first `n` vertices are the input's `n` vertices in order.
    pub mesh: TriMesh,
    /// For every refined vertex, the endpoints of the edge it was inserted on (`[i, i]` for an
    /// input vertex `i`; a later vertex's parents may themselves be inserted vertices).
    pub parent_map: Vec<[u32; 2]>,
    /// For every refined face, the input face (index into the input's `faces`) it lies in.
    pub source_face: Vec<u32>,
    /// For every refined face, the barycentric coordinates of its three corners in its
    /// `source_face` (a refined face is the affine image of these points).
    pub source_bary: Vec<[[f32; 3]; 3]>,
}

impl Refined {
    /// For every refined vertex, one input face containing it and its barycentric coordinates
    /// there (the first refined face using the vertex decides); `(u32::MAX, [0; 3])` for a
    /// vertex no face uses.
    pub fn vertex_sources(&self) -> Vec<(u32, [f32; 3])> {
        let mut out = vec![(u32::MAX, [0.0f32; 3]); self.mesh.positions.len()];
        for (fi, face) in self.mesh.faces.iter().enumerate() {
            for k in 0..3 {
                let slot = &mut out[face[k] as usize];
                if slot.0 == u32::MAX {
                    *slot = (self.source_face[fi], self.source_bary[fi][k]);
                }
            }
        }
        out
    }
}

/// Refine `mesh` to about `target_vertices` vertices by longest-edge bisection (Rivara 1984):
/// repeatedly split the longest edge at its midpoint (a max-priority queue on edge length),
/// splitting every face on it in two, which keeps the mesh conforming. No-op if the mesh already
/// has at least `target_vertices` vertices.
///
/// The first `n` vertices are the input's, in order (their `file_index` kept; inserted vertices
/// get `u32::MAX`). New vertices interpolate positions, normals and vertex colours (in linear
/// light); per-corner UVs are interpolated within each split face, so UV seams stay seams. When
/// the mesh's signal is a texture, the result also gets per-vertex colours: the texture sampled
/// bilinearly at each vertex's corner UVs, averaged in linear light (`TriMesh::vertex_signal`),
/// so the image's detail survives at the working resolution. Faces with out-of-range indices
/// are dropped; faces with a repeated vertex are kept but never split.
///
/// The steps: [`Refining::start`] (the valid faces and their records),
/// [`Refining::bisect`] (through [`Refining::add_midpoint`] and
/// [`Refining::split_face`]) and [`Refining::finish`].
pub fn refine_to_density(mesh: &TriMesh, target_vertices: usize) -> Refined {
    let mut r = Refining::start(mesh);
    // A hard cap tied to the memory budget: never grow past the working-vertex budget, whatever
    // is asked (a caller's runaway target, e.g. from a zero or NaN area ratio, stops here).
    let target_vertices = target_vertices.min(crate::mesh::MAX_WORKING_VERTICES);
    if target_vertices > r.n0 && !r.faces.is_empty() {
        r.bisect(target_vertices, None);
    }
    r.finish(mesh)
}

/// Refine `mesh` by longest-edge bisection until no edge is longer than `max_length`, or it has `max_vertices` vertices. The records are those of
/// [`refine_to_density`]; a mesh with no longer edge comes back as it is.
pub fn refine_to_edge_length(mesh: &TriMesh, max_length: f32, max_vertices: usize) -> Refined {
    let mut r = Refining::start(mesh);
    let max_vertices = max_vertices.min(crate::mesh::MAX_WORKING_VERTICES);
    if max_vertices > r.n0 && !r.faces.is_empty() && max_length > 0.0 {
        r.bisect(max_vertices, Some(max_length * max_length));
    }
    r.finish(mesh)
}

/// A mesh being refined, with the records of where its vertices and faces came from.
struct Refining {
    /// The input's vertex count.
    n0: usize,
    positions: Vec<[f32; 3]>,
    faces: Vec<[u32; 3]>,
    /// Whether the input has one UV per corner (then `uvs` has one per corner of `faces`).
    has_uv: bool,
    uvs: Vec<[f32; 2]>,
    /// Vertex colours in linear light, where the signal is vertex colours.
    colors: Option<Vec<[f32; 3]>>,
    normals: Option<Vec<[f32; 3]>>,
    parent_map: Vec<[u32; 2]>,
    source_face: Vec<u32>,
    source_bary: Vec<[[f32; 3]; 3]>,
    signal: SignalKind,
}

impl Refining {
    /// The input's valid faces (indices in range) with their UVs, colours in linear light,
    /// normals, and every vertex and face its own source.
    fn start(mesh: &TriMesh) -> Refining {
        let n0 = mesh.positions.len();
        let positions = mesh.positions.clone();
        let mut faces = Vec::with_capacity(mesh.faces.len());
        let has_uv = mesh
            .uvs
            .as_ref()
            .is_some_and(|u| u.len() == 3 * mesh.faces.len());
        let mut uvs: Vec<[f32; 2]> = Vec::new();
        let mut source_face: Vec<u32> = Vec::with_capacity(mesh.faces.len());
        for (f, face) in mesh.faces.iter().enumerate() {
            if face.iter().all(|&v| (v as usize) < n0) {
                faces.push(*face);
                source_face.push(f as u32);
                if has_uv {
                    uvs.extend_from_slice(&mesh.uvs.as_ref().unwrap()[3 * f..3 * f + 3]);
                }
            }
        }
        let signal = mesh.signal_kind();
        let colors: Option<Vec<[f32; 3]>> = match signal {
            SignalKind::VertexColors => mesh
                .colors
                .as_ref()
                .filter(|c| c.len() == n0)
                .map(|c| c.iter().map(|x| x.map(srgb_to_linear)).collect()),
            _ => None,
        };
        let normals = mesh.normals.clone().filter(|n| n.len() == n0);
        let parent_map: Vec<[u32; 2]> = (0..n0 as u32).map(|i| [i, i]).collect();
        const UNIT: [[f32; 3]; 3] = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        let source_bary: Vec<[[f32; 3]; 3]> = vec![UNIT; faces.len()];
        Refining {
            n0,
            positions,
            faces,
            has_uv,
            uvs,
            colors,
            normals,
            parent_map,
            source_face,
            source_bary,
            signal,
        }
    }

    /// Split the longest edge (a max-priority queue on squared length) until the mesh has
    /// `target_vertices` vertices, no edge is left, or (with `down_to`, a squared length) the
    /// longest edge's bin is below that length's.
    fn bisect(&mut self, target_vertices: usize, down_to: Option<f32>) {
        let extra = (target_vertices - self.n0).min(1 << 24);
        self.positions.reserve(extra);
        self.parent_map.reserve(extra);
        self.faces.reserve(2 * extra + 16);
        self.source_face.reserve(2 * extra + 16);
        self.source_bary.reserve(2 * extra + 16);
        let mut edges = edge_faces(&self.faces, extra);
        let mut heap: BinaryHeap<(u64, Reverse<u64>)> = edges
            .keys()
            .map(|&k| {
                (
                    length_key(&self.positions, (k >> 32) as u32, k as u32),
                    Reverse(k),
                )
            })
            .collect();
        let stop = down_to.map(|l2| squared_length_key(l2 as f64));
        let mut flist: Vec<u32> = Vec::with_capacity(4);
        while self.positions.len() < target_vertices {
            if let (Some(stop), Some((top, _))) = (stop, heap.peek())
                && *top < stop
            {
                break;
            }
            let Some((_, Reverse(key))) = heap.pop() else {
                break;
            };
            let Some(ef) = edges.remove(&key) else {
                continue; // already split
            };
            let (a, b) = ((key >> 32) as u32, key as u32);
            let m = self.add_midpoint(a, b);
            flist.clear();
            flist.extend(ef.list());
            for &fi in &flist {
                if let Some(p2) = self.split_face(fi, (a, b), m, &mut edges) {
                    heap.push((length_key(&self.positions, m, p2), Reverse(edge_key(m, p2))));
                }
            }
            heap.push((length_key(&self.positions, a, m), Reverse(edge_key(a, m))));
            heap.push((length_key(&self.positions, m, b), Reverse(edge_key(m, b))));
        }
    }

    /// A new vertex at the midpoint of edge `ab`, its colour and normal interpolated; returns
    /// its index.
    fn add_midpoint(&mut self, a: u32, b: u32) -> u32 {
        let positions = &mut self.positions;
        let m = positions.len() as u32;
        let (pa, pb) = (
            Vec3::from(positions[a as usize]),
            Vec3::from(positions[b as usize]),
        );
        positions.push(((pa + pb) * 0.5).to_array());
        self.parent_map.push([a, b]);
        if let Some(c) = self.colors.as_mut() {
            let (ca, cb) = (c[a as usize], c[b as usize]);
            c.push([0, 1, 2].map(|k| 0.5 * (ca[k] + cb[k])));
        }
        if let Some(nr) = self.normals.as_mut() {
            let s = Vec3::from(nr[a as usize]) + Vec3::from(nr[b as usize]);
            nr.push(s.normalize_or(Vec3::from(nr[a as usize])).to_array());
        }
        m
    }

    /// Split face `fi` on edge `ab` at its midpoint `m` into two (the new one appended), with
    /// their source barycentrics, UVs and edge records; returns the opposite corner (the new
    /// edge `m p2` is a candidate), or `None` if the face no longer has edge `ab`.
    fn split_face(
        &mut self,
        fi: u32,
        (a, b): (u32, u32),
        m: u32,
        edges: &mut IntMap<EdgeFaces>,
    ) -> Option<u32> {
        let face = self.faces[fi as usize];
        let k = (0..3).find(|&k| {
            let (x, y) = (face[k], face[(k + 1) % 3]);
            (x == a && y == b) || (x == b && y == a)
        })?;
        let (p0, p1, p2) = (face[k], face[(k + 1) % 3], face[(k + 2) % 3]);
        let g = self.faces.len() as u32;
        self.faces[fi as usize] = [p0, m, p2];
        self.faces.push([m, p1, p2]);
        let fb = self.source_bary[fi as usize];
        let (b0, b1, b2) = (fb[k], fb[(k + 1) % 3], fb[(k + 2) % 3]);
        let bm = [0, 1, 2].map(|c| 0.5 * (b0[c] + b1[c]));
        self.source_bary[fi as usize] = [b0, bm, b2];
        self.source_bary.push([bm, b1, b2]);
        self.source_face.push(self.source_face[fi as usize]);
        if self.has_uv {
            let uvs = &mut self.uvs;
            let base = 3 * fi as usize;
            let (u0, u1, u2) = (
                uvs[base + k],
                uvs[base + (k + 1) % 3],
                uvs[base + (k + 2) % 3],
            );
            let um = [0.5 * (u0[0] + u1[0]), 0.5 * (u0[1] + u1[1])];
            uvs[base] = u0;
            uvs[base + 1] = um;
            uvs[base + 2] = u2;
            uvs.extend_from_slice(&[um, u1, u2]);
        }
        edges.entry(edge_key(p0, m)).or_default().push(fi);
        edges.entry(edge_key(m, p1)).or_default().push(g);
        let e = edges.entry(edge_key(m, p2)).or_default();
        e.push(fi);
        e.push(g);
        if let Some(e) = edges.get_mut(&edge_key(p1, p2)) {
            e.replace(fi, g);
        }
        Some(p2)
    }

    /// The refined mesh (colours back in sRGB, the input's `file_index` for its vertices,
    /// per-vertex colours sampled from a texture signal) and its source records.
    fn finish(self, mesh: &TriMesh) -> Refined {
        let n = self.positions.len();
        let mut file_index = mesh.file_index.clone();
        file_index.resize(self.n0, u32::MAX);
        file_index.resize(n, u32::MAX);
        let mut out = TriMesh {
            positions: self.positions,
            faces: self.faces,
            normals: self.normals,
            uvs: self.has_uv.then_some(self.uvs),
            colors: self
                .colors
                .map(|c| c.iter().map(|x| x.map(linear_to_srgb)).collect()),
            texture: mesh.texture.clone(),
            file_index,
            file_vertex_count: mesh.file_vertex_count,
            path: mesh.path.clone(),
        };
        if self.signal == SignalKind::Texture && self.has_uv {
            out.colors = out.vertex_signal();
        }
        Refined {
            mesh: out,
            parent_map: self.parent_map,
            source_face: self.source_face,
            source_bary: self.source_bary,
        }
    }
}

/// Edge -> the faces on it, for every face without a repeated vertex (room for `extra` more
/// vertices' edges).
fn edge_faces(faces: &[[u32; 3]], extra: usize) -> IntMap<EdgeFaces> {
    let mut edges: IntMap<EdgeFaces> = IntMap::default();
    edges.reserve(faces.len() * 3 / 2 + 3 * extra);
    for (fi, f) in faces.iter().enumerate() {
        if f[0] == f[1] || f[1] == f[2] || f[0] == f[2] {
            continue;
        }
        for k in 0..3 {
            edges
                .entry(edge_key(f[k], f[(k + 1) % 3]))
                .or_default()
                .push(fi as u32);
        }
    }
    edges
}

/// The priority of edge `ab`: its squared length's bits (as f64, which order as the lengths).
fn length_key(p: &[[f32; 3]], a: u32, b: u32) -> u64 {
    let d = Vec3::from(p[a as usize]).distance_squared(Vec3::from(p[b as usize])) as f64;
    squared_length_key(d)
}

/// [`length_key`] of the squared length `d`: 0 for nothing to split (zero, NaN).
fn squared_length_key(d: f64) -> u64 {
    if d.is_nan() || d <= 0.0 {
        0
    } else {
        d.to_bits()
    }
}

/// For every vertex of `refined`, the nearest of its first `n_orig` vertices (the original
/// ones) by shortest path along edges (multi-source Dijkstra with Euclidean edge lengths);
/// original vertices map to themselves, unreachable vertices to `u32::MAX`.
pub fn nearest_original(refined: &TriMesh, n_orig: usize) -> Vec<u32> {
    let n = refined.num_vertices();
    let n_orig = n_orig.min(n);
    let adj = refined.adjacency();
    let mut dist = vec![f32::INFINITY; n];
    let mut label = vec![u32::MAX; n];
    let mut heap = BinaryHeap::with_capacity(n);
    for v in 0..n_orig {
        dist[v] = 0.0;
        label[v] = v as u32;
        heap.push(Reverse((0u32, v as u32)));
    }
    while let Some(Reverse((dk, v))) = heap.pop() {
        let dv = f32::from_bits(dk);
        if dv > dist[v as usize] {
            continue;
        }
        let p = Vec3::from(refined.positions[v as usize]);
        for &w in adj.row(v as usize) {
            let nd = dv + p.distance(Vec3::from(refined.positions[w as usize]));
            if nd < dist[w as usize] {
                dist[w as usize] = nd;
                label[w as usize] = label[v as usize];
                heap.push(Reverse((nd.to_bits(), w)));
            }
        }
    }
    label
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn refine_square_conforms_and_interpolates() {
        let pos = vec![
            [0.0, 0.0, 0.0],
            [2.0, 0.0, 0.0],
            [2.0, 1.0, 0.0],
            [0.0, 1.0, 0.0],
        ];
        let mut m = TriMesh::new(pos, vec![[0, 1, 2], [0, 2, 3]]);
        m.colors = Some(vec![[0.0; 3], [1.0; 3], [1.0; 3], [0.0; 3]]);
        m.uvs = Some(vec![
            [0.0, 0.0],
            [1.0, 0.0],
            [1.0, 1.0],
            [0.5, 0.5],
            [1.0, 1.0],
            [0.0, 1.0],
        ]);
        let r = refine_to_density(&m, 60);
        let out = &r.mesh;
        assert_eq!(out.num_vertices(), 60);
        assert_eq!(&out.positions[..4], &m.positions[..]);
        let area: f64 = out.area();
        assert!((area - 2.0).abs() < 1e-5);
        // conforming: every interior edge has two faces, boundary edges one
        let mut cnt: HashMap<u64, u32> = HashMap::new();
        for f in &out.faces {
            for k in 0..3 {
                *cnt.entry(edge_key(f[k], f[(k + 1) % 3])).or_default() += 1;
            }
        }
        assert!(cnt.values().all(|&c| c <= 2));
        let boundary = crate::mesh::boundary_loops(&out.faces);
        assert_eq!(boundary.len(), 1);
        // UVs stay affine in position within the first face's region; the seam corner at
        // vertex 0 keeps uv (0.5, 0.5) in faces that came from face 1
        let uvs = out.uvs.as_ref().unwrap();
        for (f, face) in out.faces.iter().enumerate() {
            for k in 0..3 {
                let p = out.positions[face[k] as usize];
                let uv = uvs[3 * f + k];
                let from_first = (0..3).all(|j| {
                    let q = out.positions[face[j] as usize];
                    q[1] <= q[0] * 0.5 + 1e-6
                });
                if from_first {
                    assert!((uv[0] - p[0] / 2.0).abs() < 1e-5 && (uv[1] - p[1]).abs() < 1e-5);
                }
            }
        }
        // colours interpolate: the midpoint of edge 0-1 is grey (0.5 in linear light)
        let c = out.colors.as_ref().unwrap();
        let (i, _) = r
            .parent_map
            .iter()
            .enumerate()
            .find(|(_, p)| **p == [0, 1] || **p == [1, 0])
            .unwrap();
        assert!((srgb_to_linear(c[i][0]) - 0.5).abs() < 1e-4);
        let near = nearest_original(out, 4);
        assert_eq!(&near[..4], &[0, 1, 2, 3]);
        assert!(near.iter().all(|&v| v < 4));
        assert_eq!(out.file_index[59], u32::MAX);
        // already dense enough: unchanged
        assert_eq!(refine_to_density(&m, 3).mesh.num_vertices(), 4);
    }

    #[test]
    fn slivers_are_split_until_no_edge_is_longer_than_asked() {
        // a cone of 60 slivers from rim to apex, each 1.4 long and 0.1 wide at the rim
        let n = 60u32;
        let mut pos: Vec<[f32; 3]> = (0..n)
            .map(|i| {
                let a = std::f32::consts::TAU * i as f32 / n as f32;
                [a.cos(), a.sin(), 0.0]
            })
            .collect();
        pos.push([0.0, 0.0, 1.0]);
        let faces: Vec<[u32; 3]> = (0..n).map(|i| [n, i, (i + 1) % n]).collect();
        let m = TriMesh::new(pos, faces);
        let r = refine_to_edge_length(&m, 0.2, 100_000);
        let out = &r.mesh;
        let longest = out
            .faces
            .iter()
            .flat_map(|f| (0..3).map(move |k| (f[k], f[(k + 1) % 3])))
            .map(|(a, b)| {
                Vec3::from(out.positions[a as usize])
                    .distance(Vec3::from(out.positions[b as usize]))
            })
            .fold(0.0f32, f32::max);
        assert!(longest <= 0.2 + 1e-6, "longest edge {longest}");
        assert!(out.num_vertices() > m.num_vertices());
        // the same surface: every face inside its input face (the records), the area kept
        for (fi, face) in out.faces.iter().enumerate() {
            let src = m.faces[r.source_face[fi] as usize];
            for (&corner, b) in face.iter().zip(&r.source_bary[fi]) {
                let p = (0..3).fold(Vec3::ZERO, |a, k| {
                    a + b[k] * Vec3::from(m.positions[src[k] as usize])
                });
                assert!(p.distance(Vec3::from(out.positions[corner as usize])) < 1e-5);
            }
        }
        let area = |mesh: &TriMesh| -> f32 {
            crate::geometry::face_areas(&mesh.positions, &mesh.faces)
                .iter()
                .map(|&a| a as f32)
                .sum()
        };
        assert!((area(out) - area(&m)).abs() < 1e-4 * area(&m));
        // nothing to do: the mesh comes back as it is
        let same = refine_to_edge_length(&m, 2.0, 100_000);
        assert_eq!(same.mesh.positions, m.positions);
    }

    #[test]
    fn refine_records_source_face_and_barycentrics() {
        // a bent strip of three faces, plus one face with an out-of-range index that is dropped
        let pos = vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [1.0, 1.0, 0.5],
            [2.0, 0.5, 1.0],
        ];
        let m = TriMesh::new(pos, vec![[0, 1, 2], [9, 1, 2], [1, 3, 2], [1, 4, 3]]);
        let r = refine_to_density(&m, 200);
        let out = &r.mesh;
        assert_eq!(out.num_vertices(), 200);
        assert_eq!(r.source_face.len(), out.faces.len());
        assert_eq!(r.source_bary.len(), out.faces.len());
        assert!(r.source_face.iter().all(|&f| f != 1 && (f as usize) < 4));
        // every corner is the barycentric combination of its source face's corners
        let lerp = |f: u32, b: [f32; 3]| {
            let face = m.faces[f as usize];
            (0..3).fold(Vec3::ZERO, |a, k| {
                a + b[k] * Vec3::from(m.positions[face[k] as usize])
            })
        };
        for (fi, face) in out.faces.iter().enumerate() {
            for (&corner, &b) in face.iter().zip(&r.source_bary[fi]) {
                assert!((b.iter().sum::<f32>() - 1.0).abs() < 1e-6);
                assert!(b.iter().all(|&x| x >= 0.0));
                let p = lerp(r.source_face[fi], b);
                assert!(p.distance(Vec3::from(out.positions[corner as usize])) < 1e-5);
            }
        }
        // the refined faces of each input face tile it exactly
        let tri_area = |a: Vec3, b: Vec3, c: Vec3| 0.5 * (b - a).cross(c - a).length();
        for f in [0u32, 2, 3] {
            let face = m.faces[f as usize];
            let want = tri_area(
                Vec3::from(m.positions[face[0] as usize]),
                Vec3::from(m.positions[face[1] as usize]),
                Vec3::from(m.positions[face[2] as usize]),
            );
            let got: f32 = (0..out.faces.len())
                .filter(|&i| r.source_face[i] == f)
                .map(|i| {
                    let q = out.faces[i].map(|v| Vec3::from(out.positions[v as usize]));
                    tri_area(q[0], q[1], q[2])
                })
                .sum();
            assert!(
                (got - want).abs() < 1e-4 * want.max(1.0),
                "face {f}: {got} vs {want}"
            );
        }
        // vertex sources locate every vertex on the surface
        for (v, (f, b)) in r.vertex_sources().into_iter().enumerate() {
            assert!(lerp(f, b).distance(Vec3::from(out.positions[v])) < 1e-5);
        }
    }
}
