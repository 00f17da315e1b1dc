//! Texture update after a geometry edit (MeshMatch §5.4): where the new surface coincides with
//! the old one the old colours are copied, only the changed region is synthesised, with the old
//! textured mesh as the example and the unchanged border as constraint.

use crate::error::{Error, Result};
use crate::geometry::{TriangleBvh, mean_edge_length, refine_to_density};
use crate::mesh::TriMesh;
use crate::mesh::{SignalKind, sample_texture};
use crate::meshmatch::{
    BakeLayout, Constraints, Resampler, TransferParams, prepare_pair, solve_constrained,
};
use crate::work::{CancelToken, Event};
use glam::Vec3;
use std::sync::Arc;

/// A new vertex coincides with the old surface when its closest-point distance to it is at most
/// this fraction of the old mesh's mean edge length.
pub const UPDATE_TOLERANCE: f32 = 0.02;

/// Result of [`update_texture`].
#[derive(Clone, Debug)]
pub struct UpdateResult {
    /// sRGB colour of every file vertex of the new mesh.
    pub colors: Vec<[f32; 3]>,
    /// Per file vertex of the new mesh: whether it lies in the changed (synthesised) region.
    pub changed: Vec<bool>,
    /// The new mesh at the working density with its colours.
    pub working: TriMesh,
    /// Final MeshMatch energy (0 when nothing changed).
    pub energy: f64,
    /// Stage timings (seconds).
    pub timings: Vec<(String, f64)>,
    /// The result at full resolution, where something changed: the old surface read through
    /// the solution (exactly where the new surface coincides with it), and where the working
    /// faces lie in the new mesh's faces, for [`crate::meshmatch::deliver`].
    pub full: Option<(Arc<Resampler>, Arc<BakeLayout>)>,
}

/// Colour of the old surface at a closest point (face, barycentric): a corner's own colour, bit
/// for bit, when the point is that corner (within `snap`), else the barycentric blend of the
/// vertex colours or the texture sampled at the interpolated UV.
fn old_color(old: &TriMesh, f: usize, b: [f32; 3], p: [f32; 3], snap: f32) -> [f32; 3] {
    let face = old.faces[f];
    let pv = Vec3::from(p);
    match old.signal_kind() {
        SignalKind::Texture => {
            let (Some(tex), Some(uvs)) = (old.texture.as_ref(), old.uvs.as_ref()) else {
                return [0.0; 3];
            };
            let uv = (0..3).fold([0.0f32; 2], |a, k| {
                let u = uvs[3 * f + k];
                [a[0] + b[k] * u[0], a[1] + b[k] * u[1]]
            });
            sample_texture(tex, uv)
        }
        SignalKind::VertexColors => {
            let Some(cols) = old.colors.as_ref() else {
                return [0.0; 3];
            };
            for k in 0..3 {
                if (Vec3::from(old.positions[face[k] as usize]) - pv).length() <= snap {
                    return cols[face[k] as usize];
                }
            }
            (0..3).fold([0.0f32; 3], |a, k| {
                let c = cols[face[k] as usize];
                [a[0] + b[k] * c[0], a[1] + b[k] * c[1], a[2] + b[k] * c[2]]
            })
        }
        SignalKind::None => [0.0; 3],
    }
}

/// Update the texture of an edited mesh (MeshMatch §5.4): the new mesh is refined to
/// `params.vertices`; every working vertex whose closest point on the old surface
/// ([`TriangleBvh::closest_point`]) is within [`UPDATE_TOLERANCE`] × the old mean edge length
/// copies the old colour there and is fixed; the rest is synthesised by MeshMatch with the old
/// textured mesh (refined to the same density) as the example ([`solve_constrained`]). Colours
/// come back in the new mesh's file order.
pub fn update_texture(
    old: &TriMesh,
    new: &TriMesh,
    params: &TransferParams,
    sink: &dyn Fn(Event),
    cancel: &CancelToken,
) -> Result<UpdateResult> {
    params.validate()?;
    // No global shape map here (the locked vertices already carry the old layout).
    let params = &TransferParams {
        structure: Some(0.0),
        ..params.clone()
    };
    old.check_finite()?;
    new.check_finite()?;
    if old.signal_kind() == SignalKind::None {
        return Err(Error::InvalidInput(
            "the old mesh has no vertex colours or texture to update from".into(),
        ));
    }
    if old.faces.is_empty() || new.faces.is_empty() {
        return Err(Error::InvalidMesh(
            "both meshes need vertices and faces".into(),
        ));
    }
    let bvh = TriangleBvh::new(&old.positions, &old.faces);
    let me = mean_edge_length(&old.positions, &old.faces);
    let tol = UPDATE_TOLERANCE * me;
    let snap = 1e-6 * me;
    let n = new.positions.len();
    let plain = TriMesh::new(new.positions.clone(), new.faces.clone());
    let refined = refine_to_density(&plain, params.vertices);
    let wmesh = refined.mesh;
    let nw = wmesh.positions.len();
    let copied: Vec<Option<[f32; 3]>> = wmesh
        .positions
        .iter()
        .map(|&p| match bvh.closest_point(p) {
            Some((f, b, d)) if d <= tol => Some(old_color(old, f as usize, b, p, snap)),
            _ => None,
        })
        .collect();
    cancel.check()?;
    let changed_w: Vec<bool> = copied.iter().map(|c| c.is_none()).collect();
    let changed_in: Vec<bool> = changed_w[..n].to_vec();
    let mut timings = Vec::new();
    let mut full = None;
    let (out_w, energy) = if !changed_w.iter().any(|&c| c) {
        (copied.iter().map(|c| c.unwrap_or([0.0; 3])).collect(), 0.0)
    } else {
        // The example at the target's density, within 4x the working resolution and the budget:
        // a degenerate or rescaled new mesh (zero, NaN or tiny area) must not ask for billions.
        let area_ratio = old.area() / new.area();
        let cap = (4 * params.vertices.max(nw)).min(crate::mesh::MAX_WORKING_VERTICES);
        let vs = if area_ratio.is_finite() {
            ((nw as f64) * area_ratio).round().clamp(1.0, cap as f64) as usize
        } else {
            cap
        };
        let target = TriMesh::new(wmesh.positions.clone(), wmesh.faces.clone());
        let (ps, pt) = prepare_pair(
            old,
            &TransferParams {
                vertices: vs,
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
            .filter_map(|(w, &v)| copied[v as usize].map(|c| (w as u32, c)))
            .collect();
        let r = solve_constrained(&ps, &pt, &[], &Constraints { fixed }, params, sink, cancel)?;
        let f2w = pt.file_to_working();
        timings.extend(
            ps.timings()
                .iter()
                .map(|(k, s)| (format!("example {k}"), *s))
                .chain(
                    pt.timings()
                        .iter()
                        .map(|(k, s)| (format!("target {k}"), *s)),
                ),
        );
        timings.extend(r.timings.iter().cloned());
        let t = std::time::Instant::now();
        if let Some(res) = Resampler::in_place(&ps, &pt, &r.nnf, cancel)? {
            let layout = BakeLayout::of(&pt).through(
                &refined.source_face,
                &refined.source_bary,
                new.faces.len(),
            );
            full = Some((Arc::new(res), Arc::new(layout)));
        }
        timings.push(("resampler".into(), t.elapsed().as_secs_f64()));
        (
            (0..nw)
                .map(|v| copied[v].unwrap_or(r.working_signal[f2w[v] as usize]))
                .collect::<Vec<_>>(),
            r.energy,
        )
    };
    let out_in: Vec<[f32; 3]> = out_w[..n].to_vec();
    let mut working = wmesh;
    working.colors = Some(out_w);
    Ok(UpdateResult {
        colors: new.to_file_order(&out_in, [0.0; 3]),
        changed: new.to_file_order(&changed_in, false),
        working,
        energy,
        timings,
        full,
    })
}
