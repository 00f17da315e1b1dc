//! Merging at a seam (§2.7): a thread's new copy that survives the cut and continues an old
//! copy of the same element replaces the old one by the two merged ([`super::merging`]),
//! provided the merged element keeps clear of every other element.

use super::crossing;
use super::elements::{Candidate, Piece, Placement, Selection, centre_and_radius};
use super::merging;
use super::setup::Setup;

/// Joins candidate `j` to the old element `sel.old[k]`: `cached` is their merge against the
/// old one's geometry before this patch (recomputed when it has `grown` since). Returns
/// whether the merged element replaced the old one (the candidate is then accepted); false:
/// the candidate is dropped.
#[allow(clippy::too_many_arguments)]
pub(super) fn join(
    setup: &Setup,
    elements: &mut Placement,
    sel: &mut Selection,
    cands: &[Candidate],
    j: usize,
    k: usize,
    cached: merging::Merged,
    grown: bool,
) -> bool {
    let (tau, elem_faces, merge_delta) = (setup.tau, &setup.elem_faces, setup.merge_delta);
    let c = &cands[j];
    let e = sel.old[k] as usize;
    let merged = if grown {
        merging::merge(
            &elements.placed[e].geometry(elem_faces),
            &c.geometry(elem_faces),
            merge_delta,
        )
    } else {
        Some(cached)
    };
    // the merged element moved half-way: it must still keep clear of the other
    // old elements and of this patch's accepted ones
    let clear = |m: &merging::Merged| {
        let (mc, _) = centre_and_radius(&m.positions);
        let reach = 2.0 * (c.radius + elements.max_radius) + mc.distance(c.centre);
        let old_ok = sel
            .old_hash
            .near(&m.positions, tau)
            .into_iter()
            .all(|k2| k2 as usize == k || !sel.keep_old[k2 as usize])
            && sel.old.iter().enumerate().all(|(k2, e2)| {
                let o = &elements.placed[*e2 as usize];
                k2 == k
                    || !sel.keep_old[k2]
                    || o.centre_distance(c.centre) >= reach
                    || !crossing::surfaces_cross(
                        &o.positions,
                        o.faces(elem_faces),
                        &m.positions,
                        &m.faces,
                    )
            });
        let new_ok = sel.accepted_hash.near(&m.positions, tau).is_empty()
            && sel.accepted.iter().all(|&a| {
                let o = &cands[a];
                o.centre.distance(c.centre) >= reach
                    || !crossing::surfaces_cross(
                        &o.positions,
                        &elem_faces[o.source as usize],
                        &m.positions,
                        &m.faces,
                    )
            });
        old_ok && new_ok
    };
    let Some(m) = merged.filter(clear) else {
        return false;
    };
    sel.accepted_hash
        .insert(sel.accepted.len() as u32, &c.positions);
    sel.accepted.push(j);
    let pe = &mut elements.placed[e];
    elements.out_faces -= pe.faces(elem_faces).len();
    elements.out_faces += m.faces.len();
    pe.positions = m.positions;
    pe.faces = Some(m.faces);
    elements.anchored[c.anchor.0 as usize].push((e as u32, pe.pieces.len() as u32));
    elements.centres.insert(e as u32, &[c.centre.to_array()]);
    pe.pieces.push(Piece {
        centre: c.centre,
        anchor: c.anchor,
        dir: c.dir,
    });
    sel.merged_now[j] = true;
    true
}
