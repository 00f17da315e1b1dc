//! Relinking (not in the paper; [`super::Params::relink`]): after the gaps are filled, an
//! element with fewer links than its tile element has in the swatch (a ring at the end of a
//! chain that a seam broke) gets its missing partners back where that adds links.
//!
//! Where two patches meet, the cut keeps whole elements from either side, and a chain running
//! across the seam ends on both sides with a ring that threads nothing: the partner each end
//! ring should hold is there, but one patch's lattice off. The fill does not mend this: the
//! copies that clear a seam's gap are almost never at a linking position.
//!
//! Per element short of links, in turn: a small patch is flattened around it by the exponential
//! map, oriented and translated so that the tile's lattice passes exactly through it, and each
//! of its swatch partners (the tile's copies linked to it, [`Partners`]) is mapped there. A
//! partner that links the element is placed when the links it makes with the elements it keeps
//! clear of outnumber the links of the at most one element it clashes with (vertex clearance,
//! the fill's centre distances, crossing surfaces), which is then removed. Placing a partner
//! never costs an element, and every accepted move adds a link, so the pass ends; its visits
//! are also limited to twice the elements short of links at the start and to the covering
//! pass's patch count. The lattice is laid along the element's own axis first, and turned by
//! 10 and 20 degrees either way only where that yields no move.

use std::collections::VecDeque;

use glam::{Vec2, Vec3};
use rayon::prelude::*;

use super::QuiltStats;
use super::candidates::Mapper;
use super::crossing;
use super::elements::{Candidate, Placement, VertexHash};
use super::fill::spacing;
use super::flat::dir_to_uv;
use super::flatten;
use super::links::{centre_curve, curve_reach, linking_number};
use super::output::ShellGuard;
use super::setup::Setup;
use super::shell::Base;
use crate::error::Result;
use crate::work::{CancelToken, Event, Progress, Stopwatch};

/// Per tile element, its partners in the swatch: the tile elements, shifted by one of the
/// tile's periodic images ([`Swatch::images`]) when it repeats, whose centre curves link its
/// own.
///
/// [`Swatch::images`]: super::swatch::Swatch::images
pub(super) struct Partners {
    pub(super) of: Vec<Vec<(u32, Vec2)>>,
}

impl Partners {
    pub(super) fn of_tile(setup: &Setup) -> Partners {
        let sw = setup.sw;
        let ne = sw.num_elements();
        let curves: Vec<Option<Vec<Vec3>>> = (0..ne)
            .map(|e| centre_curve(sw.element_positions(e), &sw.element_faces(e)))
            .collect();
        // the copies the swatch's own link rate counts ([`super::measure`])
        let offsets: Vec<Vec2> = sw.images().into_iter().map(Vec2::from).collect();
        let mut of = vec![Vec::new(); ne];
        for (a, ca) in curves.iter().enumerate() {
            let Some(ca) = ca else { continue };
            let (ma, ra) = curve_reach(ca);
            for (b, cb) in curves.iter().enumerate() {
                let Some(cb) = cb else { continue };
                let (mb, rb) = curve_reach(cb);
                for &off in &offsets {
                    if a == b && off == Vec2::ZERO {
                        continue;
                    }
                    let d = Vec3::new(off.x, off.y, 0.0);
                    if ma.distance(mb + d) > ra + rb {
                        continue;
                    }
                    let moved: Vec<Vec3> = cb.iter().map(|p| *p + d).collect();
                    if linking_number(ca, &moved) != 0 {
                        of[a].push((b as u32, off));
                    }
                }
            }
        }
        Partners { of }
    }

    fn any(&self) -> bool {
        self.of.iter().any(|p| !p.is_empty())
    }
}

/// The link graph of the placed elements: each alive element's centre curve and partners.
struct Links {
    curve: Vec<Option<Vec<Vec3>>>,
    adj: Vec<Vec<u32>>,
    /// The vertices of the elements alive at the start and of those placed since, in cells of
    /// the clearance (removed ones stay in it; their ids are skipped as dead).
    verts: VertexHash,
}

impl Links {
    fn new(setup: &Setup, elements: &Placement) -> Links {
        let curve: Vec<Option<Vec<Vec3>>> = elements
            .placed
            .iter()
            .map(|pe| {
                (pe.alive && pe.pieces.len() == 1)
                    .then(|| centre_curve(&pe.positions, pe.faces(&setup.elem_faces)))
                    .flatten()
            })
            .collect();
        let mut adj = vec![Vec::new(); curve.len()];
        for (a, b) in super::links::linked_pairs(&curve) {
            adj[a as usize].push(b);
            adj[b as usize].push(a);
        }
        let mut verts = VertexHash::new(setup.tau);
        for (k, pe) in elements.placed.iter().enumerate() {
            if pe.alive {
                verts.insert(k as u32, &pe.positions);
            }
        }
        Links { curve, adj, verts }
    }

    fn degree(&self, e: u32) -> usize {
        self.adj[e as usize].len()
    }

    /// Element `e` removed.
    fn remove(&mut self, e: u32) {
        for o in std::mem::take(&mut self.adj[e as usize]) {
            self.adj[o as usize].retain(|&x| x != e);
        }
        self.curve[e as usize] = None;
    }

    /// Element `e` added with its curve and partners.
    fn add(&mut self, e: u32, positions: &[[f32; 3]], curve: Vec<Vec3>, partners: &[u32]) {
        self.verts.insert(e, positions);
        debug_assert_eq!(e as usize, self.curve.len());
        self.curve.push(Some(curve));
        self.adj.push(partners.to_vec());
        for &o in partners {
            self.adj[o as usize].push(e);
        }
    }
}

/// Gives elements short of links their swatch partners where that adds links (module
/// documentation), visiting at most twice as many elements as are short of links at the start
/// and at most `patches` (the covering pass's count); returns how many partners were placed and
/// how many elements they replaced.
pub(super) fn relink(
    setup: &Setup,
    base: &Base,
    elements: &mut Placement,
    guard: &ShellGuard,
    patches: usize,
    (sink, clock, cancel): (&dyn Fn(Event), &Stopwatch, &CancelToken),
) -> Result<(usize, usize)> {
    let partners = Partners::of_tile(setup);
    if !partners.any() {
        return Ok((0, 0));
    }
    let want = |src: u32| partners.of[src as usize].len();
    let mut links = Links::new(setup, elements);
    let short = |links: &Links, elements: &Placement, e: u32| {
        let pe = &elements.placed[e as usize];
        pe.alive && links.curve[e as usize].is_some() && links.degree(e) < want(pe.source)
    };
    let mut queue: VecDeque<u32> = (0..elements.placed.len() as u32)
        .filter(|&e| short(&links, elements, e))
        .collect();
    // each visit costs about what a patch of the covering pass costs
    let budget = (2 * queue.len()).min(patches.max(1));
    // the disc around an element: as wide as the farthest partner's centre lies from the tile's
    // origin (a partner that falls off it does not map and is not tried)
    let reach = partners
        .of
        .iter()
        .flatten()
        .map(|&(b, off)| {
            let c = setup.sw.elements[b as usize].centre;
            (Vec2::new(c[0], c[1]) + off).length()
        })
        .fold(0.0f32, f32::max);
    let (mut placed, mut removed, mut tries) = (0, 0, 0);
    while let Some(a) = queue.pop_front() {
        if tries == budget {
            break;
        }
        if !short(&links, elements, a) {
            continue;
        }
        if tries % 16 == 0 {
            cancel.check()?;
            sink(Event::Progress(Progress {
                stage: "quilt: links",
                iteration: tries,
                elapsed: clock.secs(),
                fraction: tries as f32 / budget.max(1) as f32,
                ..Default::default()
            }));
        }
        tries += 1;
        let m = Move::best(setup, base, elements, &links, &partners, a, reach, guard);
        let Some(m) = m else {
            continue;
        };
        // the move: the clashing element out, the partner in
        let mut touched: Vec<u32> = Vec::new();
        for &o in &m.clash {
            touched.extend_from_slice(&links.adj[o as usize]);
            links.remove(o);
            let pe = &mut elements.placed[o as usize];
            pe.alive = false;
            elements.out_faces -= pe.faces(&setup.elem_faces).len();
            removed += 1;
        }
        let id = elements.placed.len() as u32;
        touched.extend_from_slice(&m.linked);
        links.add(id, &m.partner.positions, m.curve, &m.linked);
        elements.place_one(m.partner, setup.sw);
        placed += 1;
        touched.push(id);
        touched.push(a);
        for e in touched {
            if short(&links, elements, e) {
                queue.push_back(e);
            }
        }
    }
    Ok((placed, removed))
}

/// A partner to place: the copy, its centre curve, the elements it links and the one it
/// replaces.
struct Move {
    partner: Candidate,
    curve: Vec<Vec3>,
    linked: Vec<u32>,
    clash: Vec<u32>,
    gain: isize,
}

impl Move {
    /// The best of element `a`'s missing partners, mapped through a patch flattened around it
    /// with the tile's lattice through it; `None` when none adds links.
    #[allow(clippy::too_many_arguments)]
    fn best(
        setup: &Setup,
        base: &Base,
        elements: &Placement,
        links: &Links,
        partners: &Partners,
        a: u32,
        reach: f32,
        guard: &ShellGuard,
    ) -> Option<Move> {
        let pa = &elements.placed[a as usize];
        let piece = pa.pieces.first()?;
        let (face, bary) = piece.anchor;
        let rp = reach * setup.s + setup.r_elem;
        let mut scratch = QuiltStats::default();
        let patch = flatten::by_exp_map_at(setup, base, face as usize, rp, &mut scratch);
        let flat = &patch.flat;
        let k = *flat.index.get(&face)? as usize;
        let uv = flat.faces[k].1;
        let corners = base.faces[face as usize].map(|v| Vec3::from(base.p[v as usize]));
        let rot = dir_to_uv(&uv, corners, piece.dir).normalize_or_zero();
        if rot == Vec2::ZERO {
            return None;
        }
        let ua = uv[0] * bary[0] + uv[1] * bary[1] + uv[2] * bary[2];
        let c = setup.sw.elements[pa.source as usize].centre;
        let c = Vec2::new(c[0], c[1]);
        let of = &partners.of[pa.source as usize];
        let mapper_at = |turn: f32| {
            // the tile's lattice turned by `turn` about `a`, through `a`
            let rot = Vec2::from_angle(turn).rotate(rot);
            let shift = Vec2::new(rot.x, -rot.y).rotate(ua) / setup.s - c;
            let mapper = Mapper {
                setup,
                base,
                patch: &patch,
                rot,
            };
            (mapper, shift)
        };
        // the partners `a` holds already: one of its links sits where the copy lands
        let (straight, shift0) = mapper_at(0.0);
        let missing: Vec<usize> = (0..of.len())
            .filter(|&i| {
                let (b, off) = of[i];
                let Some((anchor, _)) = straight.anchor(centre_xy(setup, b), shift0 + off) else {
                    return true;
                };
                let at = rough_centre(setup, base, b, anchor);
                !links.adj[a as usize].iter().any(|&o| {
                    let q = &elements.placed[o as usize];
                    q.source == b && q.centre_distance(at) < spacing(setup, q.source, b)
                })
            })
            .collect();
        // every turn, missing partner and move, in parallel; the most links win, the first
        // tried among equals
        let tries: Vec<(f32, usize, Vec2)> = TURNS
            .iter()
            .map(|d| d.to_radians())
            .flat_map(|turn| {
                missing.iter().flat_map(move |&i| {
                    let (b, off) = of[i];
                    let step = (centre_xy(setup, b) - c + off).length();
                    jitter(step).into_iter().map(move |d| (turn, i, d))
                })
            })
            .collect();
        // the lattice along the element's own axis first; turned only when that fails
        let split = tries.partition_point(|t| t.0 == 0.0);
        let stage = |range: std::ops::Range<usize>| {
            tries[range.clone()]
                .par_iter()
                .zip(range)
                .filter_map(|(&(turn, i, d), k)| {
                    let (b, off) = of[i];
                    let (mapper, shift) = mapper_at(turn);
                    // the copy's centre, roughly, first: mapping it whole costs more
                    let (anchor, _) = mapper.anchor(centre_xy(setup, b), shift + off + d)?;
                    if crowded(setup, elements, a, b, rough_centre(setup, base, b, anchor)) {
                        return None;
                    }
                    let p = mapper.map(b as usize, shift + off + d, &mut QuiltStats::default())?;
                    Move::evaluate(setup, elements, links, a, p, guard).map(|m| (k, m))
                })
                .min_by_key(|(k, m)| (-m.gain, *k))
                .map(|x| x.1)
        };
        stage(0..split).or_else(|| stage(split..tries.len()))
    }
}

/// The x-y centre of tile element `b`, swatch units.
fn centre_xy(setup: &Setup, b: u32) -> Vec2 {
    let c = setup.sw.elements[b as usize].centre;
    Vec2::new(c[0], c[1])
}

/// Where a copy of tile element `b` anchored at `anchor` has its centre, roughly: above the
/// anchor along the face normal at the centre's height.
fn rough_centre(setup: &Setup, base: &Base, b: u32, (f, w): (u32, [f32; 3])) -> Vec3 {
    let corners = base.faces[f as usize].map(|v| Vec3::from(base.p[v as usize]));
    let h = setup.sw.elements[b as usize].centre[2] * setup.hscale;
    corners[0] * w[0]
        + corners[1] * w[1]
        + corners[2] * w[2]
        + Vec3::from(base.fnrm[f as usize]).normalize_or_zero() * h
}

impl Move {
    /// Partner copy `p` of element `a`: the elements it clashes with and those it links;
    /// `None` unless it links `a`, clashes with at most [`MAX_CLASH`] others (not `a`) and
    /// makes more links than they lose.
    fn evaluate(
        setup: &Setup,
        elements: &Placement,
        links: &Links,
        a: u32,
        p: Candidate,
        guard: &ShellGuard,
    ) -> Option<Move> {
        let elem_faces = &setup.elem_faces;
        let b = p.source;
        if !guard.inside(&p.positions) {
            return None;
        }
        let curve = centre_curve(&p.positions, &elem_faces[b as usize])?;
        let (cm, cr) = curve_reach(&curve);
        let around = elements
            .centres
            .within(p.centre, 2.0 * (p.radius + elements.max_radius) + setup.tau);
        let touching = links.verts.near(&p.positions, setup.tau);
        let mut clash = Vec::new();
        let mut linked = Vec::new();
        for o in around {
            let q = &elements.placed[o as usize];
            if !q.alive {
                continue;
            }
            // `a` and its partner keep the swatch's own centre distance
            let clashes = (o != a && q.centre_distance(p.centre) < spacing(setup, q.source, b))
                || touching.binary_search(&o).is_ok()
                || crossing::surfaces_cross(
                    &q.positions,
                    q.faces(elem_faces),
                    &p.positions,
                    &elem_faces[b as usize],
                );
            if clashes {
                if o == a {
                    return None;
                }
                clash.push(o);
                continue;
            }
            if let Some(qc) = &links.curve[o as usize] {
                let (qm, qr) = curve_reach(qc);
                if qm.distance(cm) <= qr + cr && linking_number(&curve, qc) != 0 {
                    linked.push(o);
                }
            }
        }
        if !linked.contains(&a) {
            return None;
        }
        if clash.len() > MAX_CLASH {
            return None;
        }
        let lost: usize = clash.iter().map(|&o| links.degree(o)).sum();
        let gain = linked.len() as isize - lost as isize;
        // a move that costs an element must win a link more for it
        (gain > clash.len().saturating_sub(1) as isize).then_some(Move {
            partner: p,
            curve,
            linked,
            clash,
            gain,
        })
    }
}

/// Whether more than [`MAX_CLASH`] alive elements other than `a` lie so near `rough` (a copy
/// of tile element `b` there, roughly) that a copy there would clash with them all: centres
/// closer than 0.8 of the distance [`Move::evaluate`] demands.
fn crowded(setup: &Setup, elements: &Placement, a: u32, b: u32, rough: Vec3) -> bool {
    let near = elements
        .centres
        .within(rough, setup.conflict_reach.max(setup.max_conflict));
    near.into_iter()
        .filter(|&o| {
            let q = &elements.placed[o as usize];
            o != a && q.alive && q.centre_distance(rough) < 0.8 * spacing(setup, q.source, b)
        })
        .count()
        > MAX_CLASH
}

/// Most elements one placed partner may replace.
const MAX_CLASH: usize = 1;

/// The turns of the tile's lattice about the element a partner is tried at, degrees: where
/// two patches meet at an angle, the partner of one patch's element lies between both.
const TURNS: [f32; 5] = [0.0, -10.0, 10.0, -20.0, 20.0];

/// The moves a partner copy is tried at, swatch units, for partners `step` apart: none, then
/// 0.15 and 0.3 of the step in eight directions.
fn jitter(step: f32) -> Vec<Vec2> {
    let mut out = vec![Vec2::ZERO];
    for m in [0.15, 0.3] {
        for k in 0..8 {
            let a = std::f32::consts::TAU * k as f32 / 8.0;
            out.push(Vec2::new(a.cos(), a.sin()) * (m * step));
        }
    }
    out
}
