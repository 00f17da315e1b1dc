//! Step 4, selection (§2.5-2.7): the conflict graph between the patch's candidates and the
//! old elements near them, the maximum-weight independent set solved as an s-t min cut
//! ([`super::maxflow`]), then the greedy pass over the survivors nearest the seed first, where
//! a thread continuing an old copy is joined to it ([`super::join`]).

use super::QuiltStats;
use super::crossing;
use super::elements::{Candidate, Placement, Selection, VertexHash};
use super::join;
use super::maxflow;
use super::merging;
use super::setup::Setup;
use crate::stats::KdTree;

/// Which old elements and candidates of the patch survive, and which candidates are accepted.
pub(super) fn select(
    setup: &Setup,
    elements: &mut Placement,
    cands: &[Candidate],
    stats: &mut QuiltStats,
) -> Selection {
    let (old, old_hash, conflicts, partner) = conflict_graph(setup, elements, cands);
    let (keep_old, keep_new) =
        maxflow::keep_by_cut(&vec![1.1; old.len()], &vec![1.0; cands.len()], &conflicts);
    retire(setup, elements, &old, &keep_old, stats);
    let mut sel = Selection {
        old,
        old_hash,
        keep_old,
        accepted: Vec::new(),
        accepted_hash: VertexHash::new(setup.tau),
        merged_now: vec![false; cands.len()],
        retry: Vec::new(),
    };
    greedy(setup, elements, &mut sel, cands, partner, &keep_new, stats);
    sel
}

/// Per candidate, the old element it joins (index into the old elements) when it survives,
/// and the merged element as computed against that old one's present geometry.
type Partners = Vec<Option<(usize, merging::Merged)>>;

/// The alive elements whose centres are near a candidate's (3D hash: not only those anchored
/// in the disc), their vertex hash, the conflicts (old index, candidate) and each candidate's
/// partner to merge with.
#[allow(clippy::type_complexity)]
fn conflict_graph(
    setup: &Setup,
    elements: &Placement,
    cands: &[Candidate],
) -> (Vec<u32>, VertexHash, Vec<(usize, usize)>, Partners) {
    let (params, sw, tau, elem_faces) = (setup.params, setup.sw, setup.tau, &setup.elem_faces);
    let (max_conflict, nudge_reach) = (setup.max_conflict, setup.nudge_reach);
    let (placed, centres, max_radius) = (&elements.placed, &elements.centres, elements.max_radius);
    let mut near_old: Vec<u32> = Vec::new();
    for c in cands {
        near_old.extend(
            centres
                .near(
                    &[c.centre.to_array()],
                    (c.radius + max_radius + tau + nudge_reach)
                        .max(max_conflict + nudge_reach)
                        .min(centres.cell),
                )
                .into_iter()
                .filter(|&e| placed[e as usize].alive),
        );
    }
    near_old.sort_unstable();
    near_old.dedup();
    let old: Vec<u32> = near_old;
    let mut old_hash = VertexHash::new(tau);
    for (k, e) in old.iter().enumerate() {
        old_hash.insert(k as u32, &placed[*e as usize].positions);
    }
    let mut conflicts: Vec<(usize, usize)> = Vec::new();
    let mut partner: Partners = vec![None; cands.len()];
    // the old elements' piece centres, so that each candidate meets only those within its
    // reach: a conflict needs centres closer than the largest conflict distance or than twice
    // the two radii
    let mut piece_centres: Vec<f32> = Vec::new();
    let mut piece_of: Vec<u32> = Vec::new();
    for (k, e) in old.iter().enumerate() {
        for q in &placed[*e as usize].pieces {
            piece_centres.extend_from_slice(&q.centre.to_array());
            piece_of.push(k as u32);
        }
    }
    let pieces = KdTree::new(&piece_centres, 3);
    let mut within: Vec<u32> = Vec::new();
    let mut reached: Vec<u32> = Vec::new();
    for (j, c) in cands.iter().enumerate() {
        let cl = sw.elements[c.source as usize].class;
        let mut near = old_hash.near(&c.positions, tau);
        let reach = setup.conflict_reach.max(2.0 * (c.radius + max_radius));
        pieces.within(&c.centre.to_array(), reach * reach, &mut within);
        reached.clear();
        reached.extend(within.iter().map(|&i| piece_of[i as usize]));
        reached.sort_unstable();
        reached.dedup();
        for &k in &reached {
            let (k, e) = (k as usize, &old[k as usize]);
            let pe = &placed[*e as usize];
            let d = pe.centre_distance(c.centre);
            if d < setup.conflict_dist(pe.source, c.source)
                || (d < 2.0 * (c.radius + max_radius)
                    && crossing::surfaces_cross(
                        &pe.positions,
                        pe.faces(elem_faces),
                        &c.positions,
                        &elem_faces[c.source as usize],
                    ))
            {
                near.push(k as u32);
            }
        }
        near.sort_unstable();
        near.dedup();
        // the first same-class old element it can merge with is no conflict (§2.7)
        if params.merge_elements && setup.elongated[c.source as usize] {
            partner[j] = near.iter().map(|&k| k as usize).find_map(|k| {
                let pe = &placed[old[k] as usize];
                if sw.elements[pe.source as usize].class != cl
                    || !setup.elongated[pe.source as usize]
                {
                    return None;
                }
                merging::merge(
                    &pe.geometry(elem_faces),
                    &c.geometry(elem_faces),
                    setup.merge_delta,
                )
                .map(|m| (k, m))
            });
        }
        let joins = partner[j].as_ref().map(|p| p.0);
        conflicts.extend(
            near.into_iter()
                .map(|k| k as usize)
                .filter(|&k| joins != Some(k))
                .map(|k| (k, j)),
        );
    }
    (old, old_hash, conflicts, partner)
}

/// The old elements the cut drops die.
fn retire(
    setup: &Setup,
    elements: &mut Placement,
    old: &[u32],
    keep_old: &[bool],
    stats: &mut QuiltStats,
) {
    let elem_faces = &setup.elem_faces;
    for (k, e) in old.iter().enumerate() {
        if !keep_old[k] {
            let pe = &mut elements.placed[*e as usize];
            pe.alive = false;
            elements.out_faces -= pe.faces(elem_faces).len();
            stats.replaced_old += 1;
        }
    }
}

/// The greedy pass: the candidates the cut keeps, nearest to the seed first, dropped when
/// they conflict with one accepted before (flattening distortion), joined to the old element
/// they continue when they have a partner.
fn greedy(
    setup: &Setup,
    elements: &mut Placement,
    sel: &mut Selection,
    cands: &[Candidate],
    mut partner: Partners,
    keep_new: &[bool],
    stats: &mut QuiltStats,
) {
    let (tau, elem_faces) = (setup.tau, &setup.elem_faces);
    let mut order: Vec<usize> = (0..cands.len()).filter(|&j| keep_new[j]).collect();
    stats.dropped_conflict += cands.len() - order.len();
    // dropped candidates, tried again nudged (below)
    sel.retry = (0..cands.len()).filter(|&j| !keep_new[j]).collect();
    order.sort_by(|&a, &b| {
        cands[a]
            .seed_dist
            .total_cmp(&cands[b].seed_dist)
            .then(a.cmp(&b))
    });
    // old elements grown by a merge in this patch (their cached merges are stale)
    let mut grown = vec![false; sel.old.len()];
    // the accepted candidates' centres: a clash needs centres closer than twice the two radii
    let r_cand = cands.iter().map(|c| c.radius).fold(0.0f32, f32::max);
    let mut accepted_centres = VertexHash::new((4.0 * r_cand).max(f32::MIN_POSITIVE));
    for j in order {
        let c = &cands[j];
        let clash = sel.accepted_hash.any_near(&c.positions, tau, |_| true)
            || accepted_centres
                .within(c.centre, 2.0 * (c.radius + r_cand))
                .into_iter()
                .any(|i| {
                    let o = &cands[sel.accepted[i as usize]];
                    let d = o.centre.distance(c.centre);
                    d < setup
                        .conflict_dist(o.source, c.source)
                        .min(0.9 * (o.radius + c.radius))
                        || (d < 2.0 * (o.radius + c.radius)
                            && crossing::surfaces_cross(
                                &o.positions,
                                &elem_faces[o.source as usize],
                                &c.positions,
                                &elem_faces[c.source as usize],
                            ))
                });
        if clash {
            stats.dropped_conflict += 1;
            sel.retry.push(j);
            continue;
        }
        // a candidate joining a surviving old element: merge now (the old one may have
        // grown by an earlier merge of this patch); a failed merge drops it
        if let Some((k, cached)) = partner[j].take()
            && sel.keep_old[k]
        {
            if join::join(setup, elements, sel, cands, j, k, cached, grown[k]) {
                grown[k] = true;
                stats.merged += 1;
            } else {
                stats.dropped_conflict += 1;
            }
            continue;
        }
        sel.accepted_hash
            .insert(sel.accepted.len() as u32, &c.positions);
        accepted_centres.insert(sel.accepted.len() as u32, &[c.centre.to_array()]);
        sel.accepted.push(j);
    }
}
