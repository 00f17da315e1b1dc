//! Connectivity: CSR adjacency, connected components, boundary loops.

use std::collections::HashMap;

/// Compressed sparse row adjacency: the neighbours of `i` are `indices[offsets[i]..offsets[i+1]]`.
#[derive(Clone, Debug, Default)]
pub struct Csr {
    /// Row offsets, length `n + 1`.
    pub offsets: Vec<u32>,
    /// Concatenated neighbour lists.
    pub indices: Vec<u32>,
}

impl Csr {
    /// Number of rows.
    pub fn len(&self) -> usize {
        self.offsets.len().saturating_sub(1)
    }
    /// True when there are no rows.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// Neighbours of row `i`.
    #[inline]
    pub fn row(&self, i: usize) -> &[u32] {
        &self.indices[self.offsets[i] as usize..self.offsets[i + 1] as usize]
    }
    /// Build from a list of (row, col) pairs; duplicates removed, rows sorted. Every row must
    /// be below `n`. The pairs are bucketed by row (a counting sort) and each row, a handful of
    /// entries, sorted on its own: at a million vertices this is several times faster than
    /// sorting the pairs whole. `pairs` is left empty.
    pub fn from_pairs(n: usize, pairs: &mut Vec<(u32, u32)>) -> Csr {
        let mut start = vec![0u32; n + 1];
        for &(r, _) in pairs.iter() {
            start[r as usize + 1] += 1;
        }
        for i in 0..n {
            start[i + 1] += start[i];
        }
        let mut fill = start.clone();
        let mut cols = vec![0u32; pairs.len()];
        for &(r, c) in pairs.iter() {
            let f = &mut fill[r as usize];
            cols[*f as usize] = c;
            *f += 1;
        }
        pairs.clear();
        pairs.shrink_to_fit();
        // sort and deduplicate each row, compacting towards the front
        let mut offsets = vec![0u32; n + 1];
        let mut w = 0usize;
        for i in 0..n {
            let (a, b) = (start[i] as usize, start[i + 1] as usize);
            cols[a..b].sort_unstable();
            for k in a..b {
                let c = cols[k];
                if k == a || c != cols[k - 1] {
                    cols[w] = c;
                    w += 1;
                }
            }
            offsets[i + 1] = w as u32;
        }
        cols.truncate(w);
        Csr {
            offsets,
            indices: cols,
        }
    }
}

/// Vertex-vertex adjacency of a triangle list (symmetric, sorted, no self loops).
pub fn vertex_adjacency(n: usize, faces: &[[u32; 3]]) -> Csr {
    let mut pairs = Vec::with_capacity(faces.len() * 6);
    for f in faces {
        for k in 0..3 {
            let (a, b) = (f[k], f[(k + 1) % 3]);
            if a != b && (a as usize) < n && (b as usize) < n {
                pairs.push((a, b));
                pairs.push((b, a));
            }
        }
    }
    Csr::from_pairs(n, &mut pairs)
}

/// Vertex-face incidence of a triangle list: `row(v)` lists the faces using `v`, ascending
/// (out-of-range corners are skipped).
pub fn vertex_faces(n: usize, faces: &[[u32; 3]]) -> Csr {
    let mut pairs = Vec::with_capacity(faces.len() * 3);
    for (fi, f) in faces.iter().enumerate() {
        for &v in f {
            if (v as usize) < n {
                pairs.push((v, fi as u32));
            }
        }
    }
    Csr::from_pairs(n, &mut pairs)
}

/// Connected components over faces: per-vertex component label (vertices in no face get their
/// own label) and the number of components that contain at least one face.
pub fn connected_components(n: usize, faces: &[[u32; 3]]) -> (Vec<u32>, usize) {
    let mut parent: Vec<u32> = (0..n as u32).collect();
    fn find(p: &mut [u32], mut x: u32) -> u32 {
        while p[x as usize] != x {
            p[x as usize] = p[p[x as usize] as usize];
            x = p[x as usize];
        }
        x
    }
    for f in faces {
        // `r0` stays the root of the face's set: linking a stale root would overwrite its link
        // and split a component
        let mut r0 = find(&mut parent, f[0]);
        for &v in &f[1..] {
            let r = find(&mut parent, v);
            if r != r0 {
                let (a, b) = (r0.min(r), r0.max(r));
                parent[b as usize] = a;
                r0 = a;
            }
        }
    }
    let mut label = vec![u32::MAX; n];
    let mut used = vec![false; n];
    for f in faces {
        for &v in f {
            used[v as usize] = true;
        }
    }
    let mut next = 0u32;
    let mut root_label = HashMap::new();
    let mut with_faces = 0usize;
    for (v, slot) in label.iter_mut().enumerate().take(n) {
        let r = find(&mut parent, v as u32);
        *slot = *root_label.entry(r).or_insert_with(|| {
            let l = next;
            next += 1;
            l
        });
    }
    let mut seen = vec![false; next as usize];
    for v in 0..n {
        if used[v] && !seen[label[v] as usize] {
            seen[label[v] as usize] = true;
            with_faces += 1;
        }
    }
    (label, with_faces)
}

/// The half-edges (`3 * face + corner`, from that corner to the next) whose undirected edge no
/// other face uses, in the order of the sorted edges.
fn boundary_half_edges(faces: &[[u32; 3]]) -> Vec<usize> {
    let edges = sorted_edges(faces);
    let mut once = Vec::new();
    let mut i = 0;
    while i < edges.len() {
        let mut j = i + 1;
        while j < edges.len() && edges[j].0 == edges[i].0 {
            j += 1;
        }
        if j - i == 1 {
            once.push(edges[i].1 as usize);
        }
        i = j;
    }
    once
}

/// Boundary loops: chains of directed edges used by exactly one face, as vertex sequences.
/// Non-manifold boundary vertices may split or join loops arbitrarily; every boundary edge is
/// in exactly one returned loop (an open chain is returned as is).
pub fn boundary_loops(faces: &[[u32; 3]]) -> Vec<Vec<u32>> {
    // Undirected edges sorted (no hashing: millions of edges sort in well under a second), then
    // the directed boundary half-edges a->b (the face's orientation) of edges used once.
    let mut boundary: Vec<(u32, u32)> = boundary_half_edges(faces)
        .into_iter()
        .map(|h| {
            let f = faces[h / 3];
            (f[h % 3], f[(h % 3 + 1) % 3])
        })
        .collect();
    // in face order within each start vertex (stable sort), popped from the end as a stack
    boundary.sort_by_key(|e| e.0);
    let nedges = boundary.len();
    let mut starts: Vec<u32> = boundary.iter().map(|e| e.0).collect();
    starts.dedup();
    // per start vertex: its range in `boundary` and how many are left
    let mut range: std::collections::HashMap<u32, (usize, usize)> =
        std::collections::HashMap::with_capacity(starts.len());
    let mut k = 0;
    while k < nedges {
        let mut e = k + 1;
        while e < nedges && boundary[e].0 == boundary[k].0 {
            e += 1;
        }
        range.insert(boundary[k].0, (k, e));
        k = e;
    }
    let mut pop = |v: u32| -> Option<u32> {
        let r = range.get_mut(&v)?;
        if r.1 > r.0 {
            r.1 -= 1;
            Some(boundary[r.1].1)
        } else {
            None
        }
    };
    let mut loops = Vec::new();
    let mut used = 0usize;
    for s in starts {
        while let Some(first) = pop(s) {
            let mut lp = vec![s];
            let mut nb = first;
            loop {
                used += 1;
                if nb == s {
                    break;
                }
                lp.push(nb);
                if used > nedges {
                    break;
                }
                match pop(nb) {
                    Some(x) => nb = x,
                    None => break,
                }
            }
            loops.push(lp);
        }
    }
    loops
}

/// Per face: whether one of its edges is used by no other face (it lies on a boundary).
pub fn boundary_faces(faces: &[[u32; 3]]) -> Vec<bool> {
    let mut on = vec![false; faces.len()];
    for h in boundary_half_edges(faces) {
        on[h / 3] = true;
    }
    on
}

/// Every face edge as (undirected key `min << 32 | max`, half-edge `3 * face + k`), sorted by key.
pub fn sorted_edges(faces: &[[u32; 3]]) -> Vec<(u64, u32)> {
    let mut e: Vec<(u64, u32)> = Vec::with_capacity(faces.len() * 3);
    for (fi, f) in faces.iter().enumerate() {
        for k in 0..3 {
            let (a, b) = (f[k], f[(k + 1) % 3]);
            e.push((
                ((a.min(b) as u64) << 32) | a.max(b) as u64,
                (3 * fi + k) as u32,
            ));
        }
    }
    e.sort_unstable();
    e
}

/// Undirected edges and, among them, those shared by more than two faces (non-manifold).
pub fn edge_counts(faces: &[[u32; 3]]) -> (usize, usize) {
    let e = sorted_edges(faces);
    let (mut edges, mut non_manifold) = (0, 0);
    let mut i = 0;
    while i < e.len() {
        let mut j = i + 1;
        while j < e.len() && e[j].0 == e[i].0 {
            j += 1;
        }
        edges += 1;
        if j - i > 2 {
            non_manifold += 1;
        }
        i = j;
    }
    (edges, non_manifold)
}

#[cfg(test)]
mod tests {
    use super::*;
    #[test]
    fn square_has_one_loop_one_component() {
        let faces = vec![[0, 1, 2], [0, 2, 3]];
        let loops = boundary_loops(&faces);
        assert_eq!(loops.len(), 1);
        assert_eq!(loops[0].len(), 4);
        let (_, c) = connected_components(4, &faces);
        assert_eq!(c, 1);
        let adj = vertex_adjacency(4, &faces);
        assert_eq!(adj.row(0), &[1, 2, 3]);
        assert_eq!(adj.row(1), &[0, 2]);
    }
    /// A face whose first vertex's set is joined under a lower root before its last vertex is
    /// linked: `[5, 2, 1]` after `[2, 3, 4]` and `[5, 6, 7]` must give one component, and so
    /// must every renumbering of a connected strip.
    #[test]
    fn components_do_not_split_when_a_faces_root_changes_midway() {
        let faces = vec![[2, 3, 4], [5, 6, 7], [5, 2, 1]];
        let (label, c) = connected_components(8, &faces);
        assert_eq!(c, 1);
        assert!((1..8).all(|v| label[v] == label[1]));
        assert_ne!(label[0], label[1], "vertex 0 is in no face");
        // a strip of 40 triangles, renumbered by a few permutations
        let strip: Vec<[u32; 3]> = (0..40u32).map(|i| [i, i + 1, i + 2]).collect();
        for mult in [1u32, 7, 11, 13, 17, 19, 23] {
            let perm = |v: u32| (v * mult) % 43;
            let faces: Vec<[u32; 3]> = strip.iter().map(|f| f.map(perm)).collect();
            let (_, c) = connected_components(43, &faces);
            assert_eq!(c, 1, "permutation x{mult}");
        }
    }
    #[test]
    fn tetrahedron_is_closed() {
        let faces = vec![[0, 2, 1], [0, 1, 3], [1, 2, 3], [2, 0, 3]];
        assert!(boundary_loops(&faces).is_empty());
    }
}
