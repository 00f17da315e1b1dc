//! Nudge (not in the paper; [`super::Params::nudge`]): each thread the cut or the greedy pass
//! dropped, nearest to the seed first, unless a copy of its class already holds its spot, is
//! mapped again with its swatch translation moved by a quarter, then a half of its class's
//! spacing in eight directions, and the first position that clears every element (vertex
//! distance, centres at least 0.9 of the swatch's spacing apart, no crossing surfaces) is kept.
//! It fills the gaps that long elements leave where the lattices of neighbouring patches
//! disagree sideways.

use glam::Vec2;

use super::QuiltStats;
use super::candidates::Mapper;
use super::crossing;
use super::elements::{Candidate, Placement, Selection};

/// Tries the dropped candidates `sel.retry` again, nudged; those that fit are accepted.
pub(super) fn nudge(
    mapper: &Mapper,
    elements: &Placement,
    sel: &mut Selection,
    cands: &mut [Candidate],
    stats: &mut QuiltStats,
) {
    let setup = mapper.setup;
    let (sw, s, tau) = (setup.sw, setup.s, setup.tau);
    let (spacing, nc, min_spacing) = (&setup.spacing, setup.nc, setup.min_spacing);
    let (elongated, nudge_reach) = (&setup.elongated, setup.nudge_reach);
    sel.retry.sort_by(|&a, &b| {
        cands[a]
            .seed_dist
            .total_cmp(&cands[b].seed_dist)
            .then(a.cmp(&b))
    });
    // counters of the tries that fail stay out of the run's
    let mut scratch = QuiltStats::default();
    for j in std::mem::take(&mut sel.retry) {
        let (src, shift0) = (cands[j].source as usize, cands[j].shift);
        if !elongated[src] {
            continue;
        }
        let cl = sw.elements[src].class;
        let sp = spacing[cl as usize * nc + cl as usize];
        let sp = if sp.is_finite() { sp } else { min_spacing };
        if !sp.is_finite() {
            continue;
        }
        // a spot already held by a copy of the same class needs no second one
        let c0 = cands[j].centre;
        let held = |o_cl: u32, d: f32| o_cl == cl && d < 0.35 * sp * s;
        let occupied = sel.old.iter().enumerate().any(|(k2, e2)| {
            let o = &elements.placed[*e2 as usize];
            sel.keep_old[k2] && held(sw.elements[o.source as usize].class, o.centre_distance(c0))
        }) || sel.accepted.iter().any(|&a| {
            held(
                sw.elements[cands[a].source as usize].class,
                cands[a].centre.distance(c0),
            )
        });
        if occupied {
            continue;
        }
        let mut found = None;
        'tries: for m in [0.25f32, 0.5] {
            for k in 0..8 {
                let a = std::f32::consts::FRAC_PI_4 * k as f32;
                let d = Vec2::new(a.cos(), a.sin()) * (m * sp);
                scratch.max_element_distortion = 1.0;
                let Some(c) = mapper.map(src, shift0 + d, &mut scratch) else {
                    continue;
                };
                if (c.centre.distance(cands[j].centre)) > nudge_reach + tau {
                    continue; // the flattening folds here
                }
                if clears(mapper, elements, sel, cands, &c, src) {
                    found = Some(c);
                    break 'tries;
                }
            }
        }
        if let Some(c) = found {
            stats.max_element_distortion = stats
                .max_element_distortion
                .max(scratch.max_element_distortion);
            sel.accepted_hash
                .insert(sel.accepted.len() as u32, &c.positions);
            cands[j] = c;
            sel.accepted.push(j);
            stats.dropped_conflict -= 1;
            stats.nudged += 1;
        }
    }
}

/// Whether the nudged copy `c` of tile element `src` clears every element the patch keeps:
/// no vertex within the clearance, centres at least 0.9 of the swatch's spacing apart, no
/// crossing surfaces.
fn clears(
    mapper: &Mapper,
    elements: &Placement,
    sel: &Selection,
    cands: &[Candidate],
    c: &Candidate,
    src: usize,
) -> bool {
    let setup = mapper.setup;
    let (sw, tau, elem_faces) = (setup.sw, setup.tau, &setup.elem_faces);
    let cl = sw.elements[src].class;
    // cheap tests first: vertices within tau, centres too close
    if sel
        .old_hash
        .any_near(&c.positions, tau, |k2| sel.keep_old[k2 as usize])
        || sel.accepted_hash.any_near(&c.positions, tau, |_| true)
    {
        return false;
    }
    // a nudged copy keeps the swatch's own spacing (nearly), so that
    // the fill never packs elements denser than the swatch
    let too_close_old = sel.old.iter().enumerate().any(|(k2, e2)| {
        let o = &elements.placed[*e2 as usize];
        sel.keep_old[k2]
            && o.centre_distance(c.centre)
                < setup.nudge_spacing(sw.elements[o.source as usize].class, cl)
    });
    let too_close_new = sel.accepted.iter().any(|&a| {
        let o = &cands[a];
        o.centre.distance(c.centre) < setup.nudge_spacing(sw.elements[o.source as usize].class, cl)
    });
    if too_close_old || too_close_new {
        return false;
    }
    let cross_old = sel.old.iter().enumerate().any(|(k2, e2)| {
        let o = &elements.placed[*e2 as usize];
        sel.keep_old[k2]
            && o.centre_distance(c.centre) < 2.0 * (c.radius + elements.max_radius)
            && crossing::surfaces_cross(
                &o.positions,
                o.faces(elem_faces),
                &c.positions,
                &elem_faces[src],
            )
    });
    let cross_new = !cross_old
        && sel.accepted.iter().any(|&a| {
            let o = &cands[a];
            o.centre.distance(c.centre) < 2.0 * (o.radius + c.radius)
                && crossing::surfaces_cross(
                    &o.positions,
                    &elem_faces[o.source as usize],
                    &c.positions,
                    &elem_faces[src],
                )
        });
    !cross_old && !cross_new
}
