//! Validation report and safe repair.

use super::TriMesh;
use crate::error::{Error, Result};
use std::collections::{HashMap, HashSet};

/// Largest vertex count accepted (memory budget: about 4 GB of working data at this size).
pub const MAX_VERTICES: usize = 20_000_000;

/// Largest triangle count a loader builds (checked where instancing can multiply a file's
/// triangles, as glTF nodes sharing a mesh do).
pub const MAX_FACES: usize = 3 * MAX_VERTICES;

/// Largest working resolution (vertices per mesh after refinement) the engine builds: at 1M
/// working vertices a transfer peaks near 3 GB, so this is about 12 GB. Refinement never grows
/// a mesh past it, whatever it is asked for.
pub const MAX_WORKING_VERTICES: usize = 4_000_000;

/// Smallest working resolution accepted: the size MeshMatch's hierarchy stops near (its coarsest
/// level). Below it there is no level to work through, and detail transfer's simplification
/// would collapse the target to nothing.
pub const MIN_WORKING_VERTICES: usize = 128;

/// "all 12 faces are" or "its only face is", for messages about every face of a mesh.
pub fn all_faces(n: usize) -> String {
    if n == 1 {
        "its only face is".into()
    } else {
        format!("all {n} faces are")
    }
}

/// What a mesh looks like: counts and defects.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct ValidationReport {
    /// Vertices in the mesh.
    pub vertices: usize,
    /// Triangles.
    pub faces: usize,
    /// Connected components (with at least one face).
    pub components: usize,
    /// Boundary loops.
    pub boundary_loops: usize,
    /// Edges shared by more than two faces.
    pub non_manifold_edges: usize,
    /// Vertices whose one-ring is not a single fan.
    pub non_manifold_vertices: usize,
    /// Faces with a repeated vertex or zero area.
    pub degenerate_faces: usize,
    /// Faces with the same vertex set as an earlier face.
    pub duplicate_faces: usize,
    /// Vertices used by no face.
    pub isolated_vertices: usize,
    /// Vertices with a NaN or infinite coordinate.
    pub non_finite_vertices: usize,
}

/// What `repair` changed.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct RepairReport {
    /// Degenerate faces removed.
    pub degenerate_faces_removed: usize,
    /// Duplicate faces removed.
    pub duplicate_faces_removed: usize,
    /// Faces removed because they touch a non-finite vertex.
    pub non_finite_faces_removed: usize,
    /// Unreferenced vertices removed (their file indices stay mapped through `file_index`).
    pub unreferenced_vertices_removed: usize,
}

impl RepairReport {
    /// True when nothing was changed.
    pub fn is_empty(&self) -> bool {
        self.degenerate_faces_removed
            + self.duplicate_faces_removed
            + self.non_finite_faces_removed
            + self.unreferenced_vertices_removed
            == 0
    }
    /// One-line human summary.
    pub fn summary(&self) -> String {
        if self.is_empty() {
            return "none".into();
        }
        let mut parts = Vec::new();
        let mut add = |n: usize, what: &str| {
            if n > 0 {
                parts.push(format!("{n} {what}"));
            }
        };
        add(self.degenerate_faces_removed, "degenerate faces removed");
        add(self.duplicate_faces_removed, "duplicate faces removed");
        add(
            self.non_finite_faces_removed,
            "faces with non-finite vertices removed",
        );
        add(
            self.unreferenced_vertices_removed,
            "unreferenced vertices removed",
        );
        parts.join(", ")
    }
}

fn is_degenerate(m: &TriMesh, f: &[u32; 3]) -> bool {
    if f[0] == f[1] || f[1] == f[2] || f[0] == f[2] {
        return true;
    }
    let [a, b, c] = f.map(|i| glam::Vec3::from(m.positions[i as usize]).as_dvec3());
    (b - a).cross(c - a).length_squared() == 0.0
}

fn finite(p: &[f32; 3]) -> bool {
    p.iter().all(|x| x.is_finite())
}

impl TriMesh {
    /// Count the mesh's defects without changing it.
    pub fn validate(&self) -> ValidationReport {
        let n = self.num_vertices();
        let mut r = ValidationReport {
            vertices: n,
            faces: self.num_faces(),
            ..Default::default()
        };
        r.non_finite_vertices = self.positions.iter().filter(|p| !finite(p)).count();
        let mut seen = HashSet::with_capacity(self.faces.len());
        let mut used = vec![false; n];
        let mut kept: Vec<[u32; 3]> = Vec::with_capacity(self.faces.len());
        for f in &self.faces {
            for &v in f {
                used[v as usize] = true;
            }
            if is_degenerate(self, f) {
                r.degenerate_faces += 1;
                continue;
            }
            let mut key = *f;
            key.sort_unstable();
            if !seen.insert(key) {
                r.duplicate_faces += 1;
            }
            kept.push(*f);
        }
        r.isolated_vertices = used.iter().filter(|u| !**u).count();
        r.non_manifold_edges = super::topology::edge_counts(&kept).1;
        r.components = super::connected_components(n, &self.faces).1;
        r.boundary_loops = super::boundary_loops(&self.faces).len();
        r.non_manifold_vertices = count_non_manifold_vertices(n, &self.faces);
        r
    }

    /// Refuse meshes nothing can be done with: no faces, no finite coordinates, too many vertices.
    pub fn check_usable(&self) -> Result<()> {
        let name = self
            .path
            .as_ref()
            .map(|p| format!("{}: ", p.display()))
            .unwrap_or_default();
        if self.num_vertices() > MAX_VERTICES {
            return Err(Error::InvalidMesh(format!(
                "{name}{} vertices exceed the budget of {MAX_VERTICES}",
                self.num_vertices()
            )));
        }
        if self.faces.is_empty() {
            return Err(Error::InvalidMesh(format!("{name}mesh has no faces")));
        }
        if !self.positions.iter().any(finite) {
            return Err(Error::InvalidMesh(format!(
                "{name}no vertex has finite coordinates"
            )));
        }
        Ok(())
    }

    /// Refuse a vertex with a NaN or infinite coordinate (the engine's front doors call this,
    /// so a library user gets this message instead of a failure deep in the solver).
    pub fn check_finite(&self) -> Result<()> {
        if let Some((i, p)) = self.positions.iter().enumerate().find(|(_, p)| !finite(p)) {
            let name = self
                .path
                .as_ref()
                .map(|p| format!("{}: ", p.display()))
                .unwrap_or_default();
            let file_i = self.file_index.get(i).copied().unwrap_or(i as u32);
            return Err(Error::InvalidMesh(format!(
                "{name}vertex {file_i} has a coordinate that is not a finite number ({} {} {})",
                p[0], p[1], p[2]
            )));
        }
        Ok(())
    }

    /// Drop degenerate and duplicate faces, faces touching non-finite vertices, and then
    /// unreferenced vertices, keeping `file_index` so every vertex maps back to the file.
    /// Fails (without changing anything) if no usable face would remain.
    pub fn repair(&mut self) -> Result<RepairReport> {
        self.check_usable()?;
        let mut rep = RepairReport::default();
        let mut seen = HashSet::with_capacity(self.faces.len());
        let mut keep = Vec::with_capacity(self.faces.len());
        for (fi, f) in self.faces.iter().enumerate() {
            if f.iter().any(|&v| !finite(&self.positions[v as usize])) {
                rep.non_finite_faces_removed += 1;
            } else if is_degenerate(self, f) {
                rep.degenerate_faces_removed += 1;
            } else {
                let mut key = *f;
                key.sort_unstable();
                if seen.insert(key) {
                    keep.push(fi);
                } else {
                    rep.duplicate_faces_removed += 1;
                }
            }
        }
        if keep.is_empty() {
            return Err(Error::InvalidMesh(format!(
                "{}no valid faces (all degenerate or non-finite)",
                self.path
                    .as_ref()
                    .map(|p| format!("{}: ", p.display()))
                    .unwrap_or_default()
            )));
        }
        if keep.len() != self.faces.len() {
            self.faces = keep.iter().map(|&f| self.faces[f]).collect();
            if let Some(uv) = &self.uvs {
                self.uvs = Some(
                    keep.iter()
                        .flat_map(|&f| [uv[3 * f], uv[3 * f + 1], uv[3 * f + 2]])
                        .collect(),
                );
            }
        }
        let n = self.num_vertices();
        let mut used = vec![false; n];
        for f in &self.faces {
            for &v in f {
                used[v as usize] = true;
            }
        }
        let kept = used.iter().filter(|u| **u).count();
        if kept != n {
            rep.unreferenced_vertices_removed = n - kept;
            let mut remap = vec![u32::MAX; n];
            let mut next = 0u32;
            for v in 0..n {
                if used[v] {
                    remap[v] = next;
                    next += 1;
                }
            }
            let filt = |v: &Vec<[f32; 3]>| {
                (0..n)
                    .filter(|&i| used[i])
                    .map(|i| v[i])
                    .collect::<Vec<_>>()
            };
            let positions = std::mem::take(&mut self.positions);
            self.positions = (0..n).filter(|&i| used[i]).map(|i| positions[i]).collect();
            self.normals = self.normals.as_ref().map(filt);
            self.colors = self.colors.as_ref().map(filt);
            self.file_index = (0..n)
                .filter(|&i| used[i])
                .map(|i| self.file_index[i])
                .collect();
            for f in &mut self.faces {
                *f = f.map(|v| remap[v as usize]);
            }
        }
        Ok(rep)
    }
}

/// Vertices whose incident faces do not form one edge-connected fan.
fn count_non_manifold_vertices(n: usize, faces: &[[u32; 3]]) -> usize {
    // For each vertex, union the incident faces that share an edge through the vertex.
    let mut incident: Vec<Vec<(u32, u32)>> = vec![Vec::new(); n];
    for f in faces {
        for k in 0..3 {
            let v = f[k] as usize;
            incident[v].push((f[(k + 1) % 3], f[(k + 2) % 3]));
        }
    }
    let mut bad = 0;
    let mut parent: Vec<usize> = Vec::new();
    for inc in &incident {
        if inc.len() <= 1 {
            continue;
        }
        parent.clear();
        parent.extend(0..inc.len());
        fn find(p: &mut [usize], mut x: usize) -> usize {
            while p[x] != x {
                p[x] = p[p[x]];
                x = p[x];
            }
            x
        }
        let mut by_vertex: HashMap<u32, usize> = HashMap::new();
        for (i, &(a, b)) in inc.iter().enumerate() {
            for w in [a, b] {
                if let Some(&j) = by_vertex.get(&w) {
                    let (ri, rj) = (find(&mut parent, i), find(&mut parent, j));
                    parent[ri] = rj;
                } else {
                    by_vertex.insert(w, i);
                }
            }
        }
        let root = find(&mut parent, 0);
        if (1..inc.len()).any(|i| find(&mut parent, i) != root) {
            bad += 1;
        }
    }
    bad
}
