//! Correspondences between a source and a target mesh, in the files' own vertex numbering, and
//! their JSON file (`{"correspondences": [...]}`).

/// Which of the two meshes of a transfer.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
pub enum Side {
    /// The exemplar (coloured) mesh.
    Source,
    /// The mesh to texture.
    Target,
}

/// One correspondence: a source vertex and one or more target vertices (one-to-many), in the
/// files' own vertex numbering.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Correspondence {
    /// Source file vertex index.
    pub source_vertex: u32,
    /// Target file vertex indices (several = one-to-many).
    pub target_vertices: Vec<u32>,
}

impl Correspondence {
    /// The pair's vertices on `side`: the source vertex, or the target vertices.
    pub fn vertices(&self, side: Side) -> &[u32] {
        match side {
            Side::Source => std::slice::from_ref(&self.source_vertex),
            Side::Target => &self.target_vertices,
        }
    }
}

/// Most correspondence pairs accepted: each pair costs a geodesic solve per level and feature
/// dimensions per vertex, so thousands of pairs would run for many minutes.
pub const MAX_CORRESPONDENCES: usize = 256;

/// Most target vertices over all pairs together (one-to-many pairs count each of theirs).
pub const MAX_CORRESPONDENCE_TARGETS: usize = 1024;

/// Refuse more than [`MAX_CORRESPONDENCES`] pairs or [`MAX_CORRESPONDENCE_TARGETS`] target
/// vertices, or a pair with no target vertex.
pub fn check_limits(corr: &[Correspondence]) -> crate::error::Result<()> {
    let bad = |m: String| Err(crate::error::Error::InvalidInput(m));
    if corr.len() > MAX_CORRESPONDENCES {
        return bad(format!(
            "{} correspondences: at most {MAX_CORRESPONDENCES} pairs are supported",
            corr.len()
        ));
    }
    let targets: usize = corr.iter().map(|c| c.target_vertices.len()).sum();
    if targets > MAX_CORRESPONDENCE_TARGETS {
        return bad(format!(
            "correspondences name {targets} target vertices: at most {MAX_CORRESPONDENCE_TARGETS} in all are supported"
        ));
    }
    Ok(())
}

/// Where a pair's vertices were when it was written: the source vertex's position and each
/// target vertex's, in the meshes' coordinates.
#[derive(Clone, Debug, PartialEq)]
pub struct StoredPositions {
    /// Position of the source vertex.
    pub source: [f32; 3],
    /// Position of every target vertex, in the order of `target_vertices`.
    pub targets: Vec<[f32; 3]>,
}

/// The correspondences file: `{"correspondences": [...]}`, each entry with its vertex indices
/// and, in files written since positions were stored, their positions (`source_position`,
/// `target_positions`), so the pairs survive a mesh whose vertices were renumbered (re-exported
/// by another tool). Files without positions (older ones, hand-written ones) load as they are.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(from = "FileRepr", into = "FileRepr")]
pub struct CorrespondenceFile {
    /// The pairs.
    pub correspondences: Vec<Correspondence>,
    /// The positions stored with each pair (`None` where the file has none): one per pair, or
    /// empty.
    pub positions: Vec<Option<StoredPositions>>,
}

/// One entry of the file as written.
#[derive(Clone, serde::Serialize, serde::Deserialize)]
struct EntryRepr {
    source_vertex: u32,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    source_position: Option<[f32; 3]>,
    target_vertices: Vec<u32>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    target_positions: Option<Vec<[f32; 3]>>,
}

#[derive(Clone, serde::Serialize, serde::Deserialize)]
struct FileRepr {
    correspondences: Vec<EntryRepr>,
}

impl From<FileRepr> for CorrespondenceFile {
    fn from(r: FileRepr) -> Self {
        let mut out = CorrespondenceFile::default();
        for e in r.correspondences {
            // Positions count only when they are complete and finite.
            let stored = match (e.source_position, e.target_positions) {
                (Some(s), Some(t))
                    if t.len() == e.target_vertices.len()
                        && s.iter().chain(t.iter().flatten()).all(|x| x.is_finite()) =>
                {
                    Some(StoredPositions {
                        source: s,
                        targets: t,
                    })
                }
                _ => None,
            };
            out.positions.push(stored);
            out.correspondences.push(Correspondence {
                source_vertex: e.source_vertex,
                target_vertices: e.target_vertices,
            });
        }
        if out.positions.iter().all(Option::is_none) {
            out.positions.clear();
        }
        out
    }
}

impl From<CorrespondenceFile> for FileRepr {
    fn from(f: CorrespondenceFile) -> Self {
        let correspondences = f
            .correspondences
            .into_iter()
            .enumerate()
            .map(|(i, c)| {
                let p = f.positions.get(i).and_then(Option::as_ref);
                EntryRepr {
                    source_vertex: c.source_vertex,
                    source_position: p.map(|p| p.source),
                    target_vertices: c.target_vertices,
                    target_positions: p.map(|p| p.targets.clone()),
                }
            })
            .collect();
        FileRepr { correspondences }
    }
}

/// Position of file vertex `v` of `mesh` (its `file_index` numbering), if it has one.
fn file_position(mesh: &crate::mesh::TriMesh, v: u32) -> Option<[f32; 3]> {
    let i = if mesh.file_index.is_empty() {
        v
    } else {
        mesh.from_file_index(v)?
    };
    mesh.positions.get(i as usize).copied()
}

/// The file vertex of `mesh` nearest to `p`.
fn nearest_file_vertex(mesh: &crate::mesh::TriMesh, p: [f32; 3]) -> Option<u32> {
    let d2 = |q: &[f32; 3]| (0..3).map(|k| ((q[k] - p[k]) as f64).powi(2)).sum::<f64>();
    let (i, _) = mesh
        .positions
        .iter()
        .enumerate()
        .filter(|(_, q)| q.iter().all(|x| x.is_finite()))
        .min_by(|a, b| d2(a.1).total_cmp(&d2(b.1)))?;
    Some(mesh.file_index.get(i).copied().unwrap_or(i as u32))
}

/// Bounding-box diagonal of `mesh`'s finite positions.
fn diagonal(mesh: &crate::mesh::TriMesh) -> f64 {
    let (mut lo, mut hi) = ([f64::MAX; 3], [f64::MIN; 3]);
    for p in mesh
        .positions
        .iter()
        .filter(|p| p.iter().all(|x| x.is_finite()))
    {
        for k in 0..3 {
            lo[k] = lo[k].min(p[k] as f64);
            hi[k] = hi[k].max(p[k] as f64);
        }
    }
    if lo[0] > hi[0] {
        return 0.0;
    }
    (0..3).map(|k| (hi[k] - lo[k]).powi(2)).sum::<f64>().sqrt()
}

/// A stored vertex farther than this fraction of the bounding-box diagonal from its stored
/// position is taken to have been renumbered.
pub const POSITION_TOLERANCE: f64 = 1e-4;

impl CorrespondenceFile {
    /// The pairs with the positions of their vertices on `source` and `target` (file
    /// numbering), as written by the app and `demo`. A vertex out of range stores no positions.
    pub fn with_positions(
        correspondences: Vec<Correspondence>,
        source: &crate::mesh::TriMesh,
        target: &crate::mesh::TriMesh,
    ) -> Self {
        let positions = correspondences
            .iter()
            .map(|c| {
                Some(StoredPositions {
                    source: file_position(source, c.source_vertex)?,
                    targets: c
                        .target_vertices
                        .iter()
                        .map(|&t| file_position(target, t))
                        .collect::<Option<Vec<_>>>()?,
                })
            })
            .collect();
        CorrespondenceFile {
            correspondences,
            positions,
        }
    }

    /// Check the pairs' vertices on `side` against `mesh` by their stored positions: a vertex
    /// out of range, or farther than [`POSITION_TOLERANCE`] of the bounding-box diagonal from
    /// its stored position (a mesh re-exported with its vertices renumbered), is moved to the
    /// vertex nearest to the stored position. Pairs without positions are left as they are.
    /// Returns, per pair, whether it moved.
    pub fn resolve_side(&mut self, side: Side, mesh: &crate::mesh::TriMesh) -> Vec<bool> {
        let mut moved = vec![false; self.correspondences.len()];
        if self.positions.is_empty() {
            return moved;
        }
        let tol = POSITION_TOLERANCE * diagonal(mesh);
        let far = |v: u32, p: [f32; 3]| match file_position(mesh, v) {
            None => true,
            Some(q) => {
                let d = (0..3)
                    .map(|k| ((q[k] - p[k]) as f64).powi(2))
                    .sum::<f64>()
                    .sqrt();
                d.is_nan() || d > tol
            }
        };
        for (i, c) in self.correspondences.iter_mut().enumerate() {
            let Some(Some(stored)) = self.positions.get(i) else {
                continue;
            };
            let (verts, stored): (&mut [u32], &[[f32; 3]]) = match side {
                Side::Source => (
                    std::slice::from_mut(&mut c.source_vertex),
                    std::slice::from_ref(&stored.source),
                ),
                Side::Target => (&mut c.target_vertices[..], &stored.targets[..]),
            };
            for (v, &p) in verts.iter_mut().zip(stored) {
                if far(*v, p)
                    && let Some(n) = nearest_file_vertex(mesh, p)
                {
                    moved[i] |= n != *v;
                    *v = n;
                }
            }
        }
        moved
    }

    /// [`Self::resolve_side`] on both meshes; returns the one warning line for the file
    /// (`path`) when any pair moved: "3 of 12 correspondences moved to the nearest vertex of
    /// their stored position".
    pub fn resolve(
        &mut self,
        source: Option<&crate::mesh::TriMesh>,
        target: Option<&crate::mesh::TriMesh>,
        path: &std::path::Path,
    ) -> Option<String> {
        let mut moved = vec![false; self.correspondences.len()];
        for (side, mesh) in [(Side::Source, source), (Side::Target, target)] {
            if let Some(m) = mesh {
                for (a, b) in moved.iter_mut().zip(self.resolve_side(side, m)) {
                    *a |= b;
                }
            }
        }
        let n = moved.iter().filter(|&&m| m).count();
        (n > 0).then(|| {
            format!(
                "{}: {n} of {} correspondences moved to the nearest vertex of their stored position",
                path.display(),
                self.correspondences.len()
            )
        })
    }

    /// Read and parse a correspondences JSON file: a regular file of at most
    /// [`crate::mesh::io::MAX_TEXT_FILE_BYTES`], with at most [`MAX_CORRESPONDENCES`] pairs and
    /// [`MAX_CORRESPONDENCE_TARGETS`] target vertices. Resolve it against the meshes with
    /// [`Self::resolve`] (or use [`Self::load_for`]).
    pub fn load(path: &std::path::Path) -> crate::error::Result<Self> {
        let text = crate::mesh::io::read_text_file(path, "the correspondences file")?;
        let file: Self = serde_json::from_str(&text).map_err(|e| {
            crate::error::Error::format(path, format!("invalid correspondences JSON: {e}"))
        })?;
        check_limits(&file.correspondences)
            .map_err(|e| crate::error::Error::format(path, e.to_string()))?;
        Ok(file)
    }

    /// [`Self::load`], then [`Self::resolve`] against the meshes given, printing its warning
    /// line on stderr; returns the pairs.
    pub fn load_for(
        path: &std::path::Path,
        source: Option<&crate::mesh::TriMesh>,
        target: Option<&crate::mesh::TriMesh>,
    ) -> crate::error::Result<Vec<Correspondence>> {
        let mut f = Self::load(path)?;
        if let Some(w) = f.resolve(source, target, path) {
            crate::mesh::io::print_warnings(&[w]);
        }
        Ok(f.correspondences)
    }

    /// Write as pretty JSON (atomically).
    pub fn save(&self, path: &std::path::Path) -> crate::error::Result<()> {
        let text = serde_json::to_string_pretty(self).expect("serialisable");
        crate::mesh::io::write_atomic(path, text.as_bytes())
    }
}
