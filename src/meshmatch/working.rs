//! The working mesh of a preparation: the input welded, refined to the working density by
//! longest-edge bisection (the signal sampled from the texture or colours at every new vertex),
//! and renumbered along the Morton curve, with its maps to and from the file's vertices.

use std::sync::Arc;

use super::TransferParams;
use super::deliver::BakeLayout;
use crate::error::{Error, Result};
use crate::geometry::Refined;
use crate::mesh::{SignalKind, TriMesh, sample_texture};
use crate::work::CancelToken;

/// Memory assumed per working vertex when checking a preparation against the process's limit.
pub const WORKING_VERTEX_BYTES: u64 = 6 << 10;

/// The working mesh and what ties it to the input.
pub(super) struct Working {
    /// Welded, refined and renumbered; per-vertex colours (and the input's texture) when the
    /// input has a signal.
    pub mesh: TriMesh,
    /// Nearest file vertex of every working vertex.
    pub working_to_file: Vec<u32>,
    /// Working vertex of every file vertex.
    pub file_to_working: Vec<u32>,
    /// Where the working faces lie in the input faces.
    pub layout: Arc<BakeLayout>,
    /// `order[new] = old`: the refinement's numbering (the hierarchy breaks ties by it).
    pub order: Vec<u32>,
    /// Signal per working vertex, if the input carries one.
    pub signal: Option<Vec<[f32; 3]>>,
}

/// The input welded, with the input face of every welded face.
struct Welded {
    mesh: TriMesh,
    /// Welded vertex of every input vertex.
    map: Vec<u32>,
    /// Input face of every welded face.
    to_input: Vec<u32>,
}

/// Weld, refine, sample the signal and renumber `mesh` into its working mesh.
pub(super) fn working_mesh(
    mesh: &TriMesh,
    params: &TransferParams,
    cancel: &CancelToken,
) -> Result<Working> {
    let welded = weld_checked(mesh, params)?;
    // Refine the bare welded surface (the signal is sampled below from the input itself).
    let bare = TriMesh::new(welded.mesh.positions.clone(), welded.mesh.faces.clone());
    let r = crate::geometry::refine_to_density(&bare, params.vertices);
    drop(bare);
    let vert_src: Vec<(u32, [f32; 3])> = r
        .vertex_sources()
        .into_iter()
        .map(|(f, b)| if f == u32::MAX { (0, b) } else { (f, b) })
        .collect();
    cancel.check()?;
    let signal0 = sample_signal(mesh, &welded, &r, &vert_src);
    let working_to_file = nearest_file_vertices(mesh, &welded, &r, &vert_src);
    Ok(renumber(mesh, &welded, r, signal0, working_to_file))
}

/// The file's name and a colon, for messages, or nothing.
fn path_prefix(mesh: &TriMesh) -> String {
    mesh.path
        .as_ref()
        .map(|p| format!("{}: ", p.display()))
        .unwrap_or_default()
}

/// Weld the input and refuse what is not a surface MeshMatch can work on, is denser than the
/// working budget, or would not fit in memory.
fn weld_checked(mesh: &TriMesh, params: &TransferParams) -> Result<Welded> {
    let (welded, map) = crate::geometry::weld(mesh);
    if welded.faces.is_empty() {
        return Err(Error::InvalidMesh(
            "mesh has no non-degenerate faces".into(),
        ));
    }
    // A tangle of faces is not a surface: refuse it rather than build a hierarchy over vertices
    // shared by thousands of faces (a PLY of thousands of overlapping 255-gons, say).
    let (edges, non_manifold) = crate::mesh::edge_counts(&welded.faces);
    if non_manifold * 10 > edges {
        return Err(Error::InvalidMesh(format!(
            "{}{non_manifold} of {edges} edges are shared by more than two faces: this is not a \
             surface MeshMatch can work on; clean the mesh (remove overlapping faces) first",
            path_prefix(mesh),
        )));
    }
    // A mesh denser than the working budget is used as it is: refuse it rather than run the
    // solver for hours on it.
    let max_v = crate::mesh::MAX_WORKING_VERTICES;
    if welded.positions.len() > max_v {
        return Err(Error::InvalidMesh(format!(
            "{}{} vertices, more than the working budget of {max_v}; decimate the mesh first",
            path_prefix(mesh),
            welded.positions.len()
        )));
    }
    // Input face of every welded face (weld drops out-of-range and degenerate faces in order).
    let nin = mesh.positions.len();
    let to_input: Vec<u32> = mesh
        .faces
        .iter()
        .enumerate()
        .filter(|(_, f)| {
            if f.iter().any(|&v| v as usize >= nin) {
                return false;
            }
            let w = f.map(|v| map[v as usize]);
            w[0] != w[1] && w[1] != w[2] && w[0] != w[2]
        })
        .map(|(i, _)| i as u32)
        .collect();
    // Refuse up front what cannot fit: about 6 KB per working vertex at peak (hierarchy, frames,
    // fan tables and fans; measured peak RSS is 2.4-4 KB per vertex, plus room for the address
    // space's overheads), rather than abort halfway on a failed allocation.
    let working = welded.positions.len().max(params.vertices) as u64;
    // the mesh's own vertices are kept when there are more of them than asked for
    let advice = if welded.positions.len() > params.vertices {
        format!(
            "the mesh itself has {} vertices after welding; simplify it first",
            welded.positions.len()
        )
    } else {
        "use fewer --vertices".to_string()
    };
    crate::work::check_memory(
        working.saturating_mul(WORKING_VERTEX_BYTES),
        &format!("{working} working vertices"),
        &advice,
    )?;
    Ok(Welded {
        mesh: welded,
        map,
        to_input,
    })
}

/// The signal per refined vertex: the input's own at welded vertices, interpolated in the input
/// face (texture or colours) at new ones; `None` without a signal.
fn sample_signal(
    mesh: &TriMesh,
    welded: &Welded,
    r: &Refined,
    vert_src: &[(u32, [f32; 3])],
) -> Option<Vec<[f32; 3]>> {
    let nw = welded.mesh.positions.len();
    match mesh.signal_kind() {
        SignalKind::None => None,
        kind => {
            let base = mesh.vertex_signal();
            let mut sig = vec![[0.0f32; 3]; r.mesh.positions.len()];
            if let Some(base) = base {
                for (i, &w) in welded.map.iter().enumerate() {
                    sig[w as usize] = base[i];
                }
            }
            for (v, slot) in sig.iter_mut().enumerate().skip(nw) {
                let (wf, b) = vert_src[v];
                let f = welded.to_input[wf as usize] as usize;
                *slot = match kind {
                    SignalKind::Texture => {
                        let (tex, uvs) = (
                            mesh.texture.as_ref().expect("texture"),
                            mesh.uvs.as_ref().expect("uvs"),
                        );
                        let uv = (0..3).fold([0.0f32; 2], |a, k| {
                            let u = uvs[3 * f + k];
                            [a[0] + b[k] * u[0], a[1] + b[k] * u[1]]
                        });
                        sample_texture(tex, uv)
                    }
                    _ => {
                        let cols = mesh.colors.as_ref().expect("colours");
                        let fc = mesh.faces[f];
                        (0..3).fold([0.0f32; 3], |a, k| {
                            let c = cols[fc[k] as usize];
                            [a[0] + b[k] * c[0], a[1] + b[k] * c[1], a[2] + b[k] * c[2]]
                        })
                    }
                };
            }
            Some(sig)
        }
    }
}

/// The file vertex of an input vertex.
fn file_of_input(mesh: &TriMesh, i: u32) -> u32 {
    mesh.file_index.get(i as usize).copied().unwrap_or(i)
}

/// The nearest file vertex of every refined vertex: a welded vertex's first input vertex, a new
/// vertex's nearest corner of the welded face it lies in.
fn nearest_file_vertices(
    mesh: &TriMesh,
    welded: &Welded,
    r: &Refined,
    vert_src: &[(u32, [f32; 3])],
) -> Vec<u32> {
    let nw = welded.mesh.positions.len();
    let mut welded_first = vec![u32::MAX; nw];
    for (i, &w) in welded.map.iter().enumerate() {
        if welded_first[w as usize] == u32::MAX {
            welded_first[w as usize] = i as u32;
        }
    }
    (0..r.mesh.positions.len())
        .map(|v| {
            let wv = if v < nw {
                v as u32
            } else {
                let (wf, b) = vert_src[v];
                let k = (0..3).max_by(|&a, &c| b[a].total_cmp(&b[c])).unwrap_or(0);
                welded.mesh.faces[wf as usize][k]
            };
            file_of_input(mesh, welded_first[wv as usize])
        })
        .collect()
}

/// The refined mesh renumbered along the Morton curve of its positions: refinement appends its
/// vertices in split order, scattered over the surface, and every later stage (hierarchy, fan
/// tables and gathers, the EM's neighbourhood reads) reads a vertex's neighbours, which this
/// order keeps close in memory. Its signal, file maps and bake layout follow.
fn renumber(
    mesh: &TriMesh,
    welded: &Welded,
    r: Refined,
    signal0: Option<Vec<[f32; 3]>>,
    working_to_file: Vec<u32>,
) -> Working {
    let order = crate::geometry::morton_order(&r.mesh.positions);
    let renumber = crate::geometry::inverse_order(&order);
    let permute = |v: &mut Vec<[f32; 3]>| *v = order.iter().map(|&o| v[o as usize]).collect();
    let working_to_file = order.iter().map(|&o| working_to_file[o as usize]).collect();
    let signal0 = signal0.map(|mut s| {
        permute(&mut s);
        s
    });
    let mut file_to_working = vec![0u32; mesh.file_vertex_count.max(mesh.positions.len())];
    file_to_working.truncate(mesh.file_vertex_count.max(1));
    for (i, &w) in welded.map.iter().enumerate() {
        if let Some(slot) = file_to_working.get_mut(file_of_input(mesh, i as u32) as usize) {
            *slot = renumber[w as usize];
        }
    }
    let face_input: Vec<u32> = r
        .source_face
        .iter()
        .map(|&f| welded.to_input[f as usize])
        .collect();
    let mut positions = r.mesh.positions;
    permute(&mut positions);
    let faces: Vec<[u32; 3]> = r
        .mesh
        .faces
        .iter()
        .map(|f| f.map(|v| renumber[v as usize]))
        .collect();
    drop(renumber);
    let mut working = TriMesh::new(positions, faces);
    working.colors = signal0.clone();
    let layout = Arc::new(BakeLayout {
        working_faces: working.faces.clone(),
        working_vertices: working.positions.len(),
        face_input,
        face_bary: r.source_bary,
        input_faces: mesh.faces.len(),
    });
    // A textured input keeps its texture on the working mesh (UVs interpolated into every working
    // corner), so views draw it per pixel rather than through the vertex colours.
    if mesh.signal_kind() == SignalKind::Texture
        && let Some(wuv) = layout.working_uvs(mesh)
    {
        working.uvs = Some(wuv);
        working.texture = mesh.texture.clone();
    }
    Working {
        mesh: working,
        working_to_file,
        file_to_working,
        layout,
        order,
        signal: signal0,
    }
}
