//! Completion by example ("paint by example", MeshMatch §5.4): the painted part of a mesh is the
//! example, the rest is synthesised with automatic (HKS) shape features; painted vertices keep
//! their colours exactly.

use super::fill_from_known;
use crate::error::{Error, Result};
use crate::geometry::refine_to_density;
use crate::mesh::SignalKind;
use crate::mesh::TriMesh;
use crate::meshmatch::{
    BakeLayout, Constraints, Resampler, TransferParams, prepare_pair, solve_constrained,
};
use crate::work::{CancelToken, Event};
use std::sync::Arc;

/// Result of [`complete`].
#[derive(Clone, Debug)]
pub struct CompletionResult {
    /// sRGB colour of every file vertex: painted ones exactly as given, the rest synthesised.
    pub colors: Vec<[f32; 3]>,
    /// The working mesh (the input refined to the working density) with the completed colours.
    pub working: TriMesh,
    /// Per working vertex: whether it was synthesised.
    pub synthesized: Vec<bool>,
    /// Final MeshMatch energy (mean patch distance).
    pub energy: f64,
    /// Stage timings (seconds).
    pub timings: Vec<(String, f64)>,
    /// The result at full resolution: the example read through the solution (exactly where the
    /// mesh is painted), and where the working faces lie in the mesh's faces, for
    /// [`crate::meshmatch::deliver`]. A textured mesh's example carries the texture itself.
    pub full: Option<(Arc<Resampler>, Arc<BakeLayout>)>,
}

/// Which file vertices of a painted copy are unpainted: a vertex is unpainted when its colour,
/// quantised to 8 bits per channel, equals the clay colour quantised the same way. `clay = None`
/// takes the most frequent quantised colour (an unpainted region is one flat colour, a painted
/// one varies). Returns one flag per file vertex (`true` = unpainted, to synthesise); a mesh
/// without vertex colours or texture is an error.
pub fn unpainted_mask(painted: &TriMesh, clay: Option<[f32; 3]>) -> Result<Vec<bool>> {
    let Some(cols) = painted.vertex_signal() else {
        return Err(Error::InvalidInput(
            "the painted mesh has no vertex colours or texture".into(),
        ));
    };
    let q: Vec<[u8; 3]> = cols.iter().map(|&c| crate::color::to_u8(c)).collect();
    let clay = match clay {
        Some(c) => crate::color::to_u8(c),
        None => {
            let mut counts: std::collections::HashMap<[u8; 3], usize> = Default::default();
            for c in &q {
                *counts.entry(*c).or_default() += 1;
            }
            counts
                .into_iter()
                .max_by_key(|&(c, n)| (n, c))
                .map(|(c, _)| c)
                .unwrap_or([0; 3])
        }
    };
    let flags: Vec<bool> = q.iter().map(|&c| c == clay).collect();
    Ok(painted.to_file_order(&flags, false))
}

/// Complete a partly painted mesh by example (MeshMatch §5.4, paint-by-example): the vertices with
/// `synthesize[file vertex] == false` are the example. The mesh is refined to
/// `params.vertices` (a new vertex is painted when both endpoints of its edge are), the example
/// mesh is the sub-mesh of fully painted working faces, the target is the whole working mesh with
/// every painted working vertex fixed to its colour ([`solve_constrained`]); automatic shape
/// features (HKS + normal·up) guide the search. Colours come back in file order; painted file
/// vertices keep their input colours bit for bit.
pub fn complete(
    mesh: &TriMesh,
    synthesize: &[bool],
    params: &TransferParams,
    sink: &dyn Fn(Event),
    cancel: &CancelToken,
) -> Result<CompletionResult> {
    params.validate()?;
    // No global shape map here (the known part of the same surface is the source: a shape map of a mesh onto itself would copy the hole onto itself).
    let params = &TransferParams {
        structure: Some(0.0),
        ..params.clone()
    };
    mesh.check_finite()?;
    let (base, painted_in) = painted_vertices(mesh, synthesize)?;
    let n = mesh.positions.len();
    if painted_in.iter().all(|&p| p) {
        return Ok(CompletionResult {
            colors: mesh.to_file_order(&base, [0.0; 3]),
            working: {
                let mut w = TriMesh::new(mesh.positions.clone(), mesh.faces.clone());
                w.colors = Some(base.clone());
                w
            },
            synthesized: vec![false; n],
            energy: 0.0,
            timings: Vec::new(),
            full: None,
        });
    }
    let w = painted_working_mesh(mesh, &base, &painted_in, params);
    let nw = w.mesh.positions.len();
    let source = example_mesh(mesh, &w)?;
    let target = TriMesh::new(w.mesh.positions.clone(), w.mesh.faces.clone());
    let (ps, pt) = prepare_pair(
        &source,
        &TransferParams {
            vertices: source.positions.len(),
            ..params.clone()
        },
        &target,
        &TransferParams {
            vertices: nw,
            ..params.clone()
        },
        sink,
        cancel,
    )?;
    let fixed: Vec<(u32, [f32; 3])> = pt
        .working_to_file()
        .iter()
        .enumerate()
        .filter(|&(_, &v)| w.painted[v as usize])
        .map(|(wv, &v)| (wv as u32, w.colors[v as usize]))
        .collect();
    let r = solve_constrained(&ps, &pt, &[], &Constraints { fixed }, params, sink, cancel)?;
    let full = Resampler::in_place(&ps, &pt, &r.nnf, cancel)?.map(|res| {
        let layout = BakeLayout::of(&pt).through(&w.source_face, &w.source_bary, mesh.faces.len());
        (Arc::new(res), Arc::new(layout))
    });
    let (out_w, out_in) = completed_colours(
        &w,
        &r.working_signal,
        pt.file_to_working(),
        &base,
        &painted_in,
    );
    let w_painted = w.painted;
    let mut working = w.mesh;
    working.colors = Some(out_w);
    let timings = stage_timings(&ps, &pt, &r.timings);
    Ok(CompletionResult {
        colors: mesh.to_file_order(&out_in, [0.0; 3]),
        working,
        synthesized: w_painted.iter().map(|&p| !p).collect(),
        energy: r.energy,
        timings,
        full,
    })
}

/// The mesh's colour per vertex and, per vertex, whether it is painted (the example); refuses a
/// mask of the wrong length, a mesh without colours and a mesh with nothing painted.
fn painted_vertices(mesh: &TriMesh, synthesize: &[bool]) -> Result<(Vec<[f32; 3]>, Vec<bool>)> {
    let nfile = mesh.file_vertex_count;
    if synthesize.len() != nfile {
        return Err(Error::InvalidInput(format!(
            "the mask has {} entries but the mesh has {nfile} vertices",
            synthesize.len()
        )));
    }
    let Some(base) = mesh.vertex_signal() else {
        return Err(Error::InvalidInput(
            "the mesh has no vertex colours or texture to complete from".into(),
        ));
    };
    let n = mesh.positions.len();
    let synth_in: Vec<bool> = (0..n)
        .map(|i| {
            let f = mesh.file_index.get(i).copied().unwrap_or(i as u32) as usize;
            synthesize.get(f).copied().unwrap_or(false)
        })
        .collect();
    let painted_in: Vec<bool> = synth_in.iter().map(|&s| !s).collect();
    if !painted_in.iter().any(|&p| p) {
        return Err(Error::InvalidInput(
            "nothing is painted: completion needs an example region".into(),
        ));
    }
    Ok((base, painted_in))
}

/// The working mesh of a completion and what it knows.
struct PaintedWorking {
    mesh: TriMesh,
    /// Input face and corner barycentrics of every working face.
    source_face: Vec<u32>,
    source_bary: Vec<[[f32; 3]; 3]>,
    /// Per working vertex: painted (both ends of its edge painted, for a new vertex).
    painted: Vec<bool>,
    /// Per working vertex: its colour (the texture's, on a textured mesh).
    colors: Vec<[f32; 3]>,
    /// Per working face corner: its UV in the input's texture (textured meshes only).
    corner_uvs: Vec<[f32; 2]>,
    textured: bool,
}

/// The mesh refined to the working density, unpainted colours pre-filled from the nearest
/// painted vertex so that interpolation at the border does not mix in the clay colour.
fn painted_working_mesh(
    mesh: &TriMesh,
    base: &[[f32; 3]],
    painted_in: &[bool],
    params: &TransferParams,
) -> PaintedWorking {
    let n = mesh.positions.len();
    let mut plain = TriMesh::new(mesh.positions.clone(), mesh.faces.clone());
    plain.colors = Some(fill_from_known(&plain.adjacency(), base, painted_in));
    let refined = refine_to_density(&plain, params.vertices);
    let textured = mesh.signal_kind() == SignalKind::Texture;
    let sources = if textured {
        refined.vertex_sources()
    } else {
        Vec::new()
    };
    let wmesh = refined.mesh;
    let nw = wmesh.positions.len();
    let mut painted_w = vec![false; nw];
    for v in 0..nw {
        painted_w[v] = if v < n {
            painted_in[v]
        } else {
            let [a, b] = refined.parent_map[v];
            painted_w[a as usize] && painted_w[b as usize]
        };
    }
    let mut wcols = wmesh.colors.clone().unwrap_or_else(|| vec![[0.0; 3]; nw]);
    // A textured mesh: the example carries the texture itself (per-corner UVs through the
    // refinement), and the fixed colours are the texture's at the working vertices.
    let uvs = mesh.uvs.as_deref().unwrap_or(&[]);
    let uv_at = |f: usize, b: [f32; 3]| -> [f32; 2] {
        (0..3).fold([0.0f32; 2], |a, k| {
            let u = uvs.get(3 * f + k).copied().unwrap_or([0.0; 2]);
            [a[0] + b[k] * u[0], a[1] + b[k] * u[1]]
        })
    };
    if textured && let Some(tex) = mesh.texture.as_ref() {
        for (v, (f, b)) in sources.into_iter().enumerate() {
            if f == u32::MAX {
                continue;
            }
            wcols[v] = crate::mesh::sample_texture(tex, uv_at(f as usize, b));
        }
    }
    let corner_uvs = if textured {
        (0..refined.source_face.len())
            .flat_map(|wf| {
                let f = refined.source_face[wf] as usize;
                refined.source_bary[wf].map(|b| uv_at(f, b))
            })
            .collect()
    } else {
        Vec::new()
    };
    PaintedWorking {
        mesh: wmesh,
        source_face: refined.source_face,
        source_bary: refined.source_bary,
        painted: painted_w,
        colors: wcols,
        corner_uvs,
        textured,
    }
}

/// The example: the fully painted working faces, compacted, with their colours (or, textured,
/// their UVs and the texture).
fn example_mesh(mesh: &TriMesh, w: &PaintedWorking) -> Result<TriMesh> {
    let wmesh = &w.mesh;
    let nw = wmesh.positions.len();
    let mut remap = vec![u32::MAX; nw];
    let mut spos = Vec::new();
    let mut scol = Vec::new();
    let mut sfaces = Vec::new();
    let mut suvs = Vec::new();
    for (wf, f) in wmesh.faces.iter().enumerate() {
        if f.iter().all(|&v| w.painted[v as usize]) {
            if w.textured {
                suvs.extend_from_slice(&w.corner_uvs[3 * wf..3 * wf + 3]);
            }
            let g = f.map(|v| {
                if remap[v as usize] == u32::MAX {
                    remap[v as usize] = spos.len() as u32;
                    spos.push(wmesh.positions[v as usize]);
                    scol.push(w.colors[v as usize]);
                }
                remap[v as usize]
            });
            sfaces.push(g);
        }
    }
    if sfaces.is_empty() {
        return Err(Error::InvalidInput(
            "the painted region contains no whole triangle to learn from".into(),
        ));
    }
    let mut source = TriMesh::new(spos, sfaces);
    if w.textured {
        source.uvs = Some(suvs);
        source.texture = mesh.texture.clone();
    } else {
        source.colors = Some(scol);
    }
    Ok(source)
}

/// The completed colours: per working vertex its painted colour or the solve's, and per input
/// vertex its own colour where painted, the working vertex's elsewhere.
fn completed_colours(
    w: &PaintedWorking,
    working_signal: &[[f32; 3]],
    f2w: &[u32],
    base: &[[f32; 3]],
    painted_in: &[bool],
) -> (Vec<[f32; 3]>, Vec<[f32; 3]>) {
    let nw = w.mesh.positions.len();
    let out_w: Vec<[f32; 3]> = (0..nw)
        .map(|v| {
            if w.painted[v] {
                w.colors[v]
            } else {
                working_signal[f2w[v] as usize]
            }
        })
        .collect();
    let out_in: Vec<[f32; 3]> = (0..painted_in.len())
        .map(|i| if painted_in[i] { base[i] } else { out_w[i] })
        .collect();
    (out_w, out_in)
}

/// The example's and the target's preparation timings, named so, then the solve's.
fn stage_timings(
    ps: &crate::meshmatch::PreparedMesh,
    pt: &crate::meshmatch::PreparedMesh,
    solve: &[(String, f64)],
) -> Vec<(String, f64)> {
    let mut timings: Vec<(String, f64)> = ps
        .timings()
        .iter()
        .map(|(k, s)| (format!("example {k}"), *s))
        .chain(
            pt.timings()
                .iter()
                .map(|(k, s)| (format!("target {k}"), *s)),
        )
        .collect();
    timings.extend(solve.iter().cloned());
    timings
}
