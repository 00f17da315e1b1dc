//! Gap filling (not in the paper; [`super::Params::fill`]): after every face is covered by a
//! patch, the base faces still farther than the swatch's own largest gap from any element are
//! visited in order. Each seeds a patch as in step 2, registered with the elements around it as
//! in step 3; the tile's copies that reach the gap are tried at the registered translation,
//! then moved by an eighth to a half of the tile's smallest spacing in twelve directions
//! (threads: a quarter and a half in eight, as the nudge), and the first that clears every
//! element (vertex clearance, the centre distances the cut and the nudge keep, no crossing
//! surfaces) is placed. The registered translation comes first, so a filler continues its
//! neighbours' lattice (and their links) where the seams allow it. Where a try fails, the gap
//! faces within half the gap width (threads: the whole width) are not tried again.
//!
//! Gaps within reach of an open base's border are left as the covering pass leaves them, but
//! for threads cut short ([`trim`]), which stop at the border.
//!
//! Where patches meet, the cut keeps whole elements and drops the copies that clash, which
//! leaves holes along the seams: on the horse, with the ring patch a tenth of its diagonal
//! wide, a sixth of the area, filled to a twentieth (`examples/quilt_finite`).

use glam::{Vec2, Vec3};
use rand::rngs::SmallRng;

use super::QuiltStats;
use super::candidates::{Mapper, candidates_within, copies_within};
use super::crossing;
use super::elements::{Candidate, Placement, VertexHash};
use super::flatten;
use super::lattice::Lattice;
use super::matching;
use super::setup::Setup;
use super::shell::Base;
use super::trim;
use crate::error::Result;
use crate::work::{CancelToken, Event, Progress, Stopwatch};

/// Fills the gaps wider than `reach` (base units) between the placed elements, with at most
/// twice `patches` tries (each costs what a patch of the covering pass costs), as many for a
/// tile of threads alone (long elements, costly to map and test, which rarely fit a gap);
/// returns how many elements were added, and how many of them are threads cut short
/// ([`trim`]).
#[allow(clippy::too_many_arguments)]
pub(super) fn fill(
    setup: &Setup,
    base: &Base,
    lattice: &mut Lattice,
    elements: &mut Placement,
    axes: &trim::Axes,
    reach: f32,
    patches: usize,
    rng: &mut SmallRng,
    (sink, clock, cancel): (&dyn Fn(Event), &Stopwatch, &CancelToken),
) -> Result<(usize, usize)> {
    let sw = setup.sw;
    if reach.is_nan() || reach <= 0.0 || !setup.min_spacing.is_finite() {
        return Ok((0, 0));
    }
    let mut verts = VertexHash::new(reach);
    for (k, pe) in elements.placed.iter().enumerate() {
        if pe.alive {
            verts.insert(k as u32, &pe.positions);
        }
    }
    let centroid = |f: usize| {
        base.faces[f]
            .iter()
            .map(|&v| Vec3::from(base.p[v as usize]))
            .sum::<Vec3>()
            / 3.0
    };
    let gap =
        |verts: &VertexHash, f: usize| !verts.any_near(&[centroid(f).to_array()], reach, |_| true);
    // an open base's border keeps its own margin (elements past it are dropped, as the
    // covering pass drops them): gaps within an element's reach of it are left
    let border_reach = reach + 2.0 * setup.r_elem;
    let mut border = VertexHash::new(border_reach);
    for (f, _) in base.on_boundary.iter().enumerate().filter(|x| *x.1) {
        border.insert(0, &[centroid(f).to_array()]);
    }
    // threads cut short stop at the border: their gaps there are filled too, with pieces only
    let trims = setup.params.trim && axes.any();
    let near_border = |f: usize| border.any_near(&[centroid(f).to_array()], border_reach, |_| true);
    let gaps: Vec<usize> = (0..base.faces.len())
        .filter(|&f| gap(&verts, f) && (trims || !near_border(f)))
        .collect();
    // compact elements are tried on a fine ring of moves; threads (long, costly to map and
    // to test) on the nudge's coarse one
    let step = setup.min_spacing;
    let threads = setup.elongated.iter().all(|&e| e);
    let (moves, dirs): (&[f32], usize) = if threads {
        (&[0.25, 0.5], 8)
    } else {
        (&[0.125, 0.25, 0.375, 0.5], 12)
    };
    // where a try failed, the faces within `skip` are not tried again
    let skip = if threads { reach } else { 0.5 * reach };
    let budget = if threads { patches } else { 2 * patches };
    let mut offsets = vec![Vec2::ZERO];
    for m in moves {
        for k in 0..dirs {
            let a = std::f32::consts::TAU * k as f32 / dirs as f32;
            offsets.push(Vec2::new(a.cos(), a.sin()) * (m * step));
        }
    }
    // every try's disc, and how far around a gap an element may touch, cross or crowd a copy
    // reaching into it: the copy's reach plus two element radii and the clearance, or the
    // largest centre distance kept
    let rp = (3.0 * setup.r_elem + reach).min(setup.params.patch_radius * setup.l);
    let ne = sw.num_elements() as u32;
    let kept = (0..ne * ne)
        .map(|k| spacing(setup, k / ne, k % ne))
        .fold(0.0f32, f32::max);
    let around = |elements: &Placement| {
        reach + setup.r_elem + (setup.r_elem + elements.max_radius + setup.tau).max(kept)
    };
    // the tries' counters stay out of the run's
    let mut scratch = QuiltStats::default();
    let mut trimmed = 0;
    let mut added = 0;
    let mut tries = 0;
    let mut failed = VertexHash::new(reach);
    let n = gaps.len();
    for (i, f) in gaps.into_iter().enumerate() {
        if i % 16 == 0 {
            cancel.check()?;
            sink(Event::Progress(Progress {
                stage: "quilt: gaps",
                iteration: i,
                elapsed: clock.secs(),
                fraction: i as f32 / n as f32,
                ..Default::default()
            }));
        }
        let c0 = centroid(f);
        if !gap(&verts, f) || failed.any_near(&[c0.to_array()], skip, |_| true) {
            continue;
        }
        if tries == budget {
            break;
        }
        tries += 1;
        let patch = flatten::flatten(setup, base, lattice, f, rp, &mut scratch);
        let (rot, t) = matching::register(setup, base, &patch, elements, rng);
        let mapper = Mapper {
            setup,
            base,
            patch: &patch,
            rot,
        };
        let near = Neighbours::new(
            setup,
            elements,
            c0,
            around(elements),
            axes.soft_cell(setup.s),
        );
        // at each move: a whole copy (away from the border), else (threads) the clear part
        // of one
        let whole = !near_border(f);
        let mut found = None;
        'tries: for d in &offsets {
            let copies = if whole {
                candidates_within(&mapper, t + *d, setup.r_elem + reach, &mut scratch)
            } else {
                Vec::new()
            };
            for c in copies {
                let covers = c
                    .positions
                    .iter()
                    .any(|p| Vec3::from(*p).distance(c0) <= reach);
                if covers && near.clears(setup, elements, &c) {
                    found = Some(Filler::Whole(c));
                    break 'tries;
                }
            }
            if trims
                && let Some(p) = near.trimmed(setup, elements, axes, &mapper, t + *d, c0, reach)
            {
                found = Some(Filler::Trimmed(p));
                break;
            }
        }
        if let Some(filler) = found {
            let id = elements.placed.len() as u32;
            match filler {
                Filler::Whole(c) => {
                    verts.insert(id, &c.positions);
                    elements.place_one(c, sw);
                }
                Filler::Trimmed(p) => {
                    verts.insert(id, &p.positions);
                    trim::place(elements, p);
                    trimmed += 1;
                }
            }
            added += 1;
        } else {
            failed.insert(0, &[c0.to_array()]);
        }
    }
    Ok((added, trimmed))
}

/// What fills a gap: a whole copy, or a thread cut short.
enum Filler {
    Whole(Candidate),
    Trimmed(trim::Trimmed),
}

/// The alive elements around a gap ([`trim::Nearby`]), and what a copy must keep clear of them.
type Neighbours = trim::Nearby;

impl Neighbours {
    /// The longest clear piece of a thread copy at translation `t` reaching the gap at `c0`
    /// ([`trim`]).
    #[allow(clippy::too_many_arguments)]
    fn trimmed(
        &self,
        setup: &Setup,
        elements: &Placement,
        axes: &trim::Axes,
        mapper: &Mapper,
        t: Vec2,
        c0: Vec3,
        reach: f32,
    ) -> Option<trim::Trimmed> {
        let around = self.view(elements);
        // a thread's copies reach a gap from as far as half its length
        let mut best: Option<trim::Trimmed> = None;
        for (e, shift) in copies_within(mapper, t, setup.r_elem + reach) {
            if !axes.passes_near_seed(e, shift, reach / setup.s) {
                continue;
            }
            let mapped = mapper.map_vertices(e, shift);
            if let Some(p) = trim::trim(axes, mapper, e, shift, &mapped, &around, Some((c0, reach)))
                && best.as_ref().is_none_or(|b| p.share > b.share)
            {
                best = Some(p);
            }
        }
        best
    }

    /// Whether `c` clears every neighbour: no vertex within the clearance, centres at least
    /// [`spacing`] apart, no crossing surfaces.
    fn clears(&self, setup: &Setup, elements: &Placement, c: &Candidate) -> bool {
        let (tau, elem_faces) = (setup.tau, &setup.elem_faces);
        if self.hash.any_near(&c.positions, tau, |_| true) {
            return false;
        }
        for &e in &self.ids {
            let o = &elements.placed[e as usize];
            if o.centre_distance(c.centre) < spacing(setup, o.source, c.source) {
                return false;
            }
        }
        for &e in &self.ids {
            let o = &elements.placed[e as usize];
            if o.centre_distance(c.centre) < 2.0 * (c.radius + elements.max_radius)
                && crossing::surfaces_cross(
                    &o.positions,
                    o.faces(elem_faces),
                    &c.positions,
                    &elem_faces[c.source as usize],
                )
            {
                return false;
            }
        }
        true
    }
}

/// Two copies of tile elements `a` and `b` keep centres at least this far apart: what the
/// covering pass's cut demands ([`Setup::conflict_dist`]) and 0.9 of their classes' closest
/// pair in the swatch, as a nudged thread.
pub(super) fn spacing(setup: &Setup, a: u32, b: u32) -> f32 {
    let (ca, cb) = (
        setup.sw.elements[a as usize].class,
        setup.sw.elements[b as usize].class,
    );
    setup.conflict_dist(a, b).max(setup.nudge_spacing(ca, cb))
}
