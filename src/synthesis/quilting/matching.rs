//! Step 3, matching (§2.4, simplified): the patch's orientation (continuing the elements
//! already placed in it) and the swatch translation that best explains them (eq. (1)-(3) at
//! the element level).

use glam::{Vec2, Vec3};
use rand::{Rng, rngs::SmallRng};

use super::elements::{Placed, Placement};
use super::flat::dir_to_uv;
use super::flatten::Patch;
use super::setup::{Centres, Setup};
use super::shell::Base;
use super::swatch::Swatch;

/// The patch's rotation (its +u axis to the swatch's +x) and the swatch translation `t`
/// (swatch units) with `uv = s R (x + t)`.
pub(super) fn register(
    setup: &Setup,
    base: &Base,
    patch: &Patch,
    elements: &Placement,
    rng: &mut SmallRng,
) -> (Vec2, Vec2) {
    let (params, s, sw) = (setup.params, setup.s, setup.sw);
    let cell = setup.cell;
    let (faces, mesh_positions) = (base.faces, base.p);
    let (flat, rp, lattice_t) = (&patch.flat, patch.rp, patch.lattice_t);
    let (anchored, placed) = (&elements.anchored, &elements.placed);
    // old elements in the patch, in swatch coordinates
    let corners = |f: u32| faces[f as usize].map(|v| Vec3::from(mesh_positions[v as usize]));
    let mut old: Vec<(u32, Vec2)> = Vec::new();
    let mut turn = Vec2::ZERO;
    for (f, t) in &flat.faces {
        for &(e, k) in &anchored[*f as usize] {
            let pe = &placed[e as usize];
            if !pe.alive {
                continue;
            }
            let piece = &pe.pieces[k as usize];
            let b = piece.anchor.1;
            let uv = t[0] * b[0] + t[1] * b[1] + t[2] * b[2];
            old.push((e, uv));
            turn += dir_to_uv(t, corners(*f), piece.dir).normalize_or_zero();
        }
    }
    // orientation: continue the neighbours' lattice (circular mean of their +x axes in
    // the patch frame) when they agree, else the field at the seed (+u)
    let rot = if lattice_t.is_some() {
        Vec2::X // the lattice's chart is already oriented
    } else if params.follow_neighbours && turn.length() > 0.5 * old.len() as f32 {
        turn.normalize()
    } else {
        Vec2::X
    };
    let inv = Vec2::new(rot.x, -rot.y);
    for o in &mut old {
        o.1 = inv.rotate(o.1) / s;
    }

    // the translation t (swatch units) with uv = s (x + t)
    let t = match lattice_t {
        Some(t) => t,
        None => choose_translation(sw, &setup.centres, placed, &old, cell, rp / s, rng),
    };
    (rot, t)
}

/// Old elements the translation's grid search scores, at most.
const MATCHED_OLD: usize = 128;

/// Eq. (1)-(3) at the element level: the swatch translation (swatch units) that best explains
/// the old elements `old` (id, position in swatch coordinates of the patch frame).
fn choose_translation(
    sw: &Swatch,
    centres: &Centres,
    placed: &[Placed],
    old: &[(u32, Vec2)],
    cell: f32,
    rs: f32,
    rng: &mut SmallRng,
) -> Vec2 {
    let (ex, ey) = (sw.extent[0], sw.extent[1]);
    // translations: t with the seed at swatch point -t
    let range = |e: f32| -> (f32, f32) {
        if sw.periodic {
            (0.0, e)
        } else if e > 2.0 * rs {
            (-(e - rs), -rs)
        } else {
            (-e / 2.0, -e / 2.0)
        }
    };
    let (rx, ry) = (range(ex), range(ey));
    if old.is_empty() {
        return Vec2::new(
            if rx.1 > rx.0 {
                rng.random_range(rx.0..rx.1)
            } else {
                rx.0
            },
            if ry.1 > ry.0 {
                rng.random_range(ry.0..ry.1)
            } else {
                ry.0
            },
        );
    }
    // (cost, residual to the nearest same-class centre): that centre's distance in cells, or
    // another class's plus one, at most 4
    let mut near = Vec::with_capacity(1);
    let mut cost = |t: Vec2, x: Vec2, cl: u32| -> (f32, Vec2) {
        let (res, any) = centres.nearest(x - t, cl, &mut near);
        let best = (res.length() / cell).min(any / cell + 1.0).min(4.0);
        (best, res)
    };
    let steps = |r: (f32, f32)| -> Vec<f32> {
        if r.1 <= r.0 {
            return vec![r.0];
        }
        let k = ((r.1 - r.0) / cell).ceil() as usize;
        (0..k.max(1)).map(|i| r.0 + i as f32 * cell).collect()
    };
    // the grid search scores at most MATCHED_OLD of the old elements, spread over the patch
    // (a swatch of thousands of small elements puts thousands in a patch); the refinement
    // below reads them all
    let stride = old.len().div_ceil(MATCHED_OLD).max(1);
    let mut best = (f32::INFINITY, Vec2::ZERO);
    for &ty in &steps(ry) {
        for &tx in &steps(rx) {
            let t = Vec2::new(tx, ty);
            let mut e = 0.0;
            for (id, x) in old.iter().step_by(stride) {
                let cl = sw.elements[placed[*id as usize].source as usize].class;
                e += cost(t, *x, cl).0;
                if e >= best.0 {
                    break;
                }
            }
            if e < best.0 {
                best = (e, t);
            }
        }
    }
    // continuous refinement by the mean residual of matched same-class pairs
    let mut t = best.1;
    for _ in 0..2 {
        let mut acc = Vec2::ZERO;
        let mut k = 0;
        for (id, x) in old {
            let cl = sw.elements[placed[*id as usize].source as usize].class;
            let (_, r) = cost(t, *x, cl);
            if r.length() < cell {
                acc += r;
                k += 1;
            }
        }
        if k == 0 {
            break;
        }
        t += acc / k as f32;
    }
    t
}
