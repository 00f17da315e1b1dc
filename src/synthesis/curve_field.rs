//! The first two stages of feature-aligned texturing (Xu et al. 2009, §3-4): the salient
//! curves of a mesh and the field oriented along them, with the greedy orientation on a
//! coarse level for large meshes. Exemplar synthesis reads the same field for its
//! `features` orientation.

use crate::error::Result;
use crate::geometry::{
    Curve, CurveField, CurveParams, FieldCurve, FieldParams, curve_field_completing_orientations,
    oriented_curve_field, salient_curves,
};
use crate::mesh::TriMesh;
use crate::work::{CancelToken, Stopwatch};

/// What the field stage reads of feature-aligned texturing's parameters.
#[derive(Clone, Copy, Debug)]
pub struct FieldStage<'a> {
    /// Salient curve extraction and preparation.
    pub curves: &'a CurveParams,
    /// Field: penalty weight, junction release.
    pub field: &'a FieldParams,
    /// Above this many vertices the greedy orientation runs on a coarse level (`None`:
    /// [`COARSE_GREEDY`]).
    pub coarse_greedy_above: Option<usize>,
    /// The coarse level's size (0: [`GREEDY_VERTICES`]).
    pub greedy_vertices: usize,
}

/// The salient curves of `target` (or the given ones) and their oriented field, with the
/// seconds each took.
pub fn curves_and_field(
    target: &TriMesh,
    curves: Option<&[Curve]>,
    params: &FieldStage<'_>,
    cancel: &CancelToken,
) -> Result<(Vec<Curve>, CurveField, (f64, f64))> {
    let mut t = (0.0, 0.0);
    let clock = Stopwatch::start();
    let curves = match curves {
        Some(c) => c.to_vec(),
        None => salient_curves(&target.positions, &target.faces, params.curves)?,
    };
    t.0 = clock.secs();
    cancel.check()?;
    let clock = Stopwatch::start();
    let fc: Vec<FieldCurve> = curves.iter().map(FieldCurve::from).collect();
    let above = params.coarse_greedy_above.unwrap_or(COARSE_GREEDY);
    let field = if target.num_vertices() > above {
        let coarse = if params.greedy_vertices == 0 {
            GREEDY_VERTICES
        } else {
            params.greedy_vertices
        };
        coarse_greedy_field(target, &fc, params.field, coarse, cancel)?
    } else {
        oriented_curve_field(&target.positions, &target.faces, &fc, params.field, cancel)?
    };
    t.1 = clock.secs();
    Ok((curves, field, t))
}

/// Above this many vertices the greedy orientation runs on a coarser level of the mesh by
/// default: below it a full-resolution greedy step (one numeric factorisation, three solves,
/// the scoring) already takes about 50 ms or less.
pub const COARSE_GREEDY: usize = 16_000;

/// The coarse level's size for the greedy orientation. Measured
/// (`cargo run --release --example field_steps`, 2 cores), horse (48K vertices, 276 curves):
/// a full-resolution greedy step takes 169 ms; at 24K vertices 68 ms, at 16K 59 ms, at 12K
/// 36 ms, at 8K 11 ms, orienting 97%, 92%, 92% and 77% of the curves' length as the full greedy
/// does, with fields 3%, 1%, 4% and 5% rougher: 12K is the smallest level that keeps the
/// decisions within the 50 ms a step.
pub const GREEDY_VERTICES: usize = 12_000;

/// The greedy orientation (Xu et al. §4.1) on a coarse level of the mesh's hierarchy (at most
/// `coarse` vertices, shortest-edge collapses), the curves carried down to their
/// vertices' ancestors; then at full resolution: curves that shrank below three coarse vertices
/// (their coarse tangent, hence their score, is lost) are oriented against the fine field of the
/// others, and one last solve takes them all
/// ([`crate::geometry::curve_field_completing_orientations`]). Each greedy step then costs a
/// coarse factorisation ([`GREEDY_VERTICES`]) instead of a full one (0.5 s at 100K); the
/// orientation decisions need the field's sign along each curve, which the coarse field gives.
fn coarse_greedy_field(
    target: &TriMesh,
    curves: &[FieldCurve],
    params: &FieldParams,
    coarse: usize,
    cancel: &CancelToken,
) -> Result<CurveField> {
    let h = crate::hierarchy::Hierarchy::build_cancellable(
        &target.positions,
        &target.faces,
        crate::hierarchy::HierarchyOptions {
            min_vertices: coarse.max(1000),
            max_levels: None,
        },
        cancel,
    )?;
    let top = h.top();
    let up = h.ancestor_map(0, top);
    let coarse_curves: Vec<FieldCurve> = curves
        .iter()
        .map(|c| {
            let mut v: Vec<u32> = c.vertices.iter().map(|&v| up[v as usize]).collect();
            v.dedup();
            if c.closed && v.len() > 1 && v.first() == v.last() {
                v.pop();
            }
            FieldCurve {
                vertices: v,
                closed: c.closed,
            }
        })
        .collect();
    let level = &h.levels[top];
    let coarse = oriented_curve_field(
        &level.positions,
        &level.faces,
        &coarse_curves,
        params,
        cancel,
    )?;
    cancel.check()?;
    let decided: Vec<bool> = coarse_curves
        .iter()
        .map(|c| c.vertices.len() >= 3)
        .collect();
    let mut fine = curve_field_completing_orientations(
        &target.positions,
        &target.faces,
        curves,
        &coarse.forward,
        &decided,
        coarse.order.clone(),
        params,
    )?;
    fine.final_solve_secs = fine.step_secs.iter().sum();
    fine.step_secs = coarse.step_secs;
    Ok(fine)
}
