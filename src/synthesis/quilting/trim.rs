//! Thread trimming (the cut of Zhou et al. 2006 §2.7 for threads, simplified;
//! [`super::Params::trim`]): a thread that no whole copy fits keeps its clear part, cut across
//! and capped. Three places ask for one: [`after_cut`], for the threads a patch's cut dropped
//! and the copies that tore off its chart (a strand longer than a limb is round) or lay on too
//! distorted faces; and the gap filling ([`super::fill`]), where no whole copy fits a gap or
//! the gap lies by an open base's border.
//!
//! 1. **Axis.** Each thread of the tile (an elongated element, [`super::setup::Setup`]'s
//!    `elongated`) gets its principal axis in the swatch's x-y plane, each vertex its
//!    coordinate along it in [`BINS`] equal slices, and its width across it.
//! 2. **Clear slices.** The copy is mapped vertex by vertex ([`Mapper::map_vertices`]); a slice
//!    is blocked when one of its vertices falls off the flattened base, on a torn or too
//!    distorted face, or within the clearance of an element already placed.
//! 3. **The run.** The longest run of clear slices holding a vertex within the gap, less one
//!    slice at each end that borders a blocked slice, is kept when it spans at least
//!    [`MIN_SHARE`] of the thread and not all of it (a whole copy is the fill's to place).
//!    The faces with all three corners in the run are kept (their largest connected part,
//!    should the thread bend back into its own slices) and every boundary loop the cut opened
//!    on a closed thread is capped by a fan around its centroid.
//! 4. **Checks.** The piece must cross no element's surface, and must not lie closer to the
//!    elements around it than the thread does in the swatch: the share of its vertices within
//!    half the thread's width of another element's is at most [`CROWD_SLACK`] times the
//!    thread's own share in the tile (with its copies around it) plus 0.05. That keeps a piece
//!    from sliding in beside a parallel thread, which the vertex clearance alone would allow
//!    (a woven strand's own clearance is the hair between it and the strands it crosses).
//!    Where the piece crosses an element, the pairs of slices whose faces cross it are blocked
//!    and the run is chosen again (four rounds at most).
//!
//! A piece counts for the share of its element's faces it kept in the density
//! ([`super::measure`]).

use glam::{Vec2, Vec3};

use super::candidates::Mapper;
use super::crossing;
use super::elements::{Piece, Placement, VertexHash, centre_and_radius};
use super::setup::Setup;

/// Slices along a thread.
pub const BINS: usize = 32;
/// Smallest share of a thread's length a piece keeps.
pub const MIN_SHARE: f32 = 0.25;
/// How much more crowded than in the swatch a piece may lie.
pub const CROWD_SLACK: f32 = 1.25;

/// A thread cut short, ready to place.
pub(super) struct Trimmed {
    pub(super) source: u32,
    pub(super) positions: Vec<[f32; 3]>,
    pub(super) faces: Vec<[u32; 3]>,
    /// Kept faces over the element's.
    pub(super) share: f32,
    pub(super) centre: Vec3,
    pub(super) radius: f32,
    pub(super) anchor: (u32, [f32; 3]),
    pub(super) dir: Vec3,
}

/// One thread's axis in swatch units.
struct Axis {
    /// Unit direction in x-y, and the point `t = 0` on it.
    dir: Vec2,
    mid: Vec2,
    /// Each vertex's slice along the axis.
    slice: Vec<u16>,
    /// The slices' `t` bounds.
    lo: f32,
    step: f32,
    /// Width across the axis.
    width: f32,
    /// Share of its vertices within half its width of another element's in the tile.
    crowd: f32,
    /// Whether the thread is closed (every edge used by two faces).
    closed: bool,
}

/// The axes of the tile's threads (`None` for compact elements).
pub(super) struct Axes {
    per: Vec<Option<Axis>>,
}

impl Axes {
    /// Measured on the tile of `setup`; empty when the tile has no thread.
    pub(super) fn new(setup: &Setup) -> Axes {
        let sw = setup.sw;
        let mut per: Vec<Option<Axis>> = (0..sw.num_elements())
            .map(|e| {
                if !setup.elongated[e] {
                    return None;
                }
                axis(sw.element_positions(e), &setup.elem_faces[e])
            })
            .collect();
        // the swatch's own crowding: its vertices (copies around the tile included) hashed
        // once, each thread's vertices tested against the other elements'
        let widest = per.iter().flatten().map(|a| a.width).fold(0.0f32, f32::max);
        if widest > 0.0 {
            let mut hash = VertexHash::new(0.5 * widest);
            let mut id = 0u32;
            for im in sw.images() {
                for e in 0..sw.num_elements() {
                    let ps: Vec<[f32; 3]> = sw
                        .element_positions(e)
                        .iter()
                        .map(|p| [p[0] + im[0], p[1] + im[1], p[2]])
                        .collect();
                    hash.insert(id, &ps);
                    id += 1;
                }
            }
            let ne = sw.num_elements() as u32;
            // the tile itself is the image at offset (0, 0)
            let own = sw
                .images()
                .iter()
                .position(|im| *im == [0.0, 0.0])
                .unwrap_or(0) as u32;
            for (e, a) in per.iter_mut().enumerate() {
                if let Some(a) = a {
                    let me = own * ne + e as u32;
                    let ps = sw.element_positions(e);
                    let near = ps
                        .iter()
                        .filter(|p| hash.any_near(&[**p], 0.5 * a.width, |k| k != me))
                        .count();
                    a.crowd = near as f32 / ps.len().max(1) as f32;
                }
            }
        }
        Axes { per }
    }

    /// The cell (base units, at swatch scale `s`) a hash needs for the crowding test: half
    /// the widest thread's width.
    pub(super) fn soft_cell(&self, s: f32) -> f32 {
        0.5 * s
            * self
                .per
                .iter()
                .flatten()
                .map(|a| a.width)
                .fold(0.0f32, f32::max)
    }

    /// Whether the tile has a thread to trim.
    pub(super) fn any(&self) -> bool {
        self.per.iter().any(|a| a.is_some())
    }

    /// Whether copy `e` at swatch translation `shift` passes within `reach` (swatch units,
    /// plus half its width) of the patch's seed (the swatch point `-shift`).
    pub(super) fn passes_near_seed(&self, e: usize, shift: Vec2, reach: f32) -> bool {
        let Some(a) = &self.per[e] else {
            return false;
        };
        let p = -shift - a.mid;
        let t = p.dot(a.dir).clamp(a.lo, a.lo + a.step * BINS as f32);
        (p - a.dir * t).length() <= reach + 0.5 * a.width
    }
}

/// The principal axis of a thread's vertices in x-y, its slices and width.
fn axis(ps: &[[f32; 3]], faces: &[[u32; 3]]) -> Option<Axis> {
    if ps.len() < 3 {
        return None;
    }
    let n = ps.len() as f32;
    let mid = ps.iter().map(|p| Vec2::new(p[0], p[1])).sum::<Vec2>() / n;
    let (mut cxx, mut cxy, mut cyy) = (0.0f32, 0.0f32, 0.0f32);
    for p in ps {
        let d = Vec2::new(p[0], p[1]) - mid;
        cxx += d.x * d.x;
        cxy += d.x * d.y;
        cyy += d.y * d.y;
    }
    // the larger eigenvector of [[cxx, cxy], [cxy, cyy]]
    let angle = 0.5 * (2.0 * cxy).atan2(cxx - cyy);
    let dir = Vec2::new(angle.cos(), angle.sin());
    let ts: Vec<f32> = ps
        .iter()
        .map(|p| (Vec2::new(p[0], p[1]) - mid).dot(dir))
        .collect();
    let (lo, hi) = ts
        .iter()
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), &t| {
            (a.min(t), b.max(t))
        });
    let across = ps
        .iter()
        .map(|p| (Vec2::new(p[0], p[1]) - mid).perp_dot(dir));
    let (wlo, whi) = across.fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), w| {
        (a.min(w), b.max(w))
    });
    // (false for NaN bounds too)
    let spans = hi > lo && whi >= wlo;
    if !spans {
        return None;
    }
    let step = (hi - lo) / BINS as f32;
    let slice = ts
        .iter()
        .map(|&t| (((t - lo) / step) as usize).min(BINS - 1) as u16)
        .collect();
    let closed = !faces.is_empty() && crate::mesh::boundary_loops(faces).is_empty();
    Some(Axis {
        dir,
        mid,
        slice,
        lo,
        step,
        width: (whi - wlo).max(1e-6),
        crowd: 0.0,
        closed,
    })
}

/// The alive elements around a point, with their vertices hashed for the clearance test and
/// for the crowding test.
pub(super) struct Nearby {
    pub(super) ids: Vec<u32>,
    pub(super) hash: VertexHash,
    pub(super) soft: VertexHash,
    /// Whether `soft` is kept (the tile has threads).
    soft_on: bool,
}

impl Nearby {
    /// The alive elements centred within `r` of `c`; `soft_cell` ([`Axes::soft_cell`], 0 for
    /// none) sizes the crowding test's hash.
    pub(super) fn new(
        setup: &Setup,
        elements: &Placement,
        c: Vec3,
        r: f32,
        soft_cell: f32,
    ) -> Nearby {
        let ids: Vec<u32> = elements
            .centres
            .within(c, r)
            .into_iter()
            .filter(|&e| elements.placed[e as usize].alive)
            .collect();
        let mut hash = VertexHash::new(setup.tau);
        let mut soft = VertexHash::new(soft_cell.max(setup.tau));
        for (k, &e) in ids.iter().enumerate() {
            hash.insert(k as u32, &elements.placed[e as usize].positions);
            if soft_cell > 0.0 {
                soft.insert(k as u32, &elements.placed[e as usize].positions);
            }
        }
        Nearby {
            ids,
            hash,
            soft,
            soft_on: soft_cell > 0.0,
        }
    }

    /// Adds element `id` (just placed) with its vertices.
    pub(super) fn add(&mut self, id: u32, positions: &[[f32; 3]]) {
        let k = self.ids.len() as u32;
        self.ids.push(id);
        self.hash.insert(k, positions);
        if self.soft_on {
            self.soft.insert(k, positions);
        }
    }

    /// The view [`trim`] reads.
    pub(super) fn view<'a>(&'a self, elements: &'a Placement) -> Around<'a> {
        Around {
            elements,
            ids: &self.ids,
            hash: &self.hash,
            soft: &self.soft,
        }
    }
}

/// What a piece must keep clear of: the elements around it.
pub(super) struct Around<'a> {
    pub(super) elements: &'a Placement,
    /// Alive elements near the gap.
    pub(super) ids: &'a [u32],
    /// Their vertices, hashed in cells of at least the clearance.
    pub(super) hash: &'a VertexHash,
    /// The same, in cells of at least [`Axes::soft_cell`].
    pub(super) soft: &'a VertexHash,
}

/// The clear part of thread copy `e` at `shift` (its vertices `mapped` into the shell, `None`
/// where they do not map), cut and capped; with `gap = Some((point, reach))` only a run
/// reaching within `reach` of the point. `None` when no run long enough is clear (module
/// documentation).
#[allow(clippy::too_many_arguments)]
pub(super) fn trim(
    axes: &Axes,
    mapper: &Mapper,
    e: usize,
    shift: Vec2,
    mapped: &[Option<[f32; 3]>],
    around: &Around,
    gap: Option<(Vec3, f32)>,
) -> Option<Trimmed> {
    let a = axes.per[e].as_ref()?;
    let setup = mapper.setup;
    let (tau, s) = (setup.tau, setup.s);
    let soft = 0.5 * a.width * s;
    let mut blocked = [false; BINS];
    let mut covers = [gap.is_none(); BINS];
    for (v, p) in mapped.iter().enumerate() {
        let b = a.slice[v] as usize;
        match p {
            None => blocked[b] = true,
            Some(p) => {
                if around.hash.any_near(&[*p], tau, |_| true) {
                    blocked[b] = true;
                }
                if let Some((g, reach)) = gap
                    && Vec3::from(*p).distance(g) <= reach
                {
                    covers[b] = true;
                }
            }
        }
    }
    let faces = &setup.elem_faces[e];
    // a run that crosses an element loses the slices whose faces cross it, and is chosen again
    for _ in 0..4 {
        let (lo, hi) = longest_run(&blocked, &covers)?;
        let piece = cut(a, faces, mapped, lo, hi)?;
        // not more crowded than the swatch has it
        let crowded = piece.positions[..piece.kept_vertices]
            .iter()
            .filter(|p| around.soft.any_near(&[**p], soft, |_| true))
            .count();
        if crowded as f32 > (CROWD_SLACK * a.crowd + 0.05) * piece.kept_vertices as f32 {
            return None;
        }
        let (centre, radius) = centre_and_radius(&piece.positions);
        let crossed: Vec<&super::elements::Placed> = around
            .ids
            .iter()
            .map(|&id| &around.elements.placed[id as usize])
            .filter(|o| {
                o.centre_distance(centre) < 2.0 * (radius + around.elements.max_radius)
                    && crossing::surfaces_cross(
                        &o.positions,
                        o.faces(&setup.elem_faces),
                        &piece.positions,
                        &piece.faces,
                    )
            })
            .collect();
        if crossed.is_empty() {
            let t_mid = a.lo + a.step * 0.5 * (lo + hi) as f32;
            let (anchor, dir) = mapper.anchor(a.mid + a.dir * t_mid, shift)?;
            return Some(Trimmed {
                source: e as u32,
                share: piece.kept_faces as f32 / faces.len().max(1) as f32,
                positions: piece.positions,
                faces: piece.faces,
                centre,
                radius,
                anchor,
                dir,
            });
        }
        // block the pairs of slices whose faces cross
        let mut any = false;
        for c in (lo..hi).step_by(2) {
            let Some(part) = cut(a, faces, mapped, c, (c + 2).min(hi)) else {
                continue;
            };
            let hit = crossed.iter().any(|o| {
                crossing::surfaces_cross(
                    &o.positions,
                    o.faces(&setup.elem_faces),
                    &part.positions,
                    &part.faces,
                )
            });
            if hit {
                blocked[c..(c + 2).min(hi)].fill(true);
                any = true;
            }
        }
        if !any {
            // the crossing is at a cap, or between slices: shorten the run at both ends
            blocked[lo] = true;
            blocked[hi - 1] = true;
        }
    }
    None
}

/// The longest run of clear slices holding a covering one, less a slice beside each blocked
/// slice, when it spans at least [`MIN_SHARE`] of the thread and not all of it.
fn longest_run(blocked: &[bool; BINS], covers: &[bool; BINS]) -> Option<(usize, usize)> {
    let min_bins = (MIN_SHARE * BINS as f32).ceil() as usize;
    let mut best: Option<(usize, usize)> = None;
    let mut i = 0;
    while i < BINS {
        if blocked[i] {
            i += 1;
            continue;
        }
        let mut j = i;
        while j < BINS && !blocked[j] {
            j += 1;
        }
        let (lo, hi) = (i + (i > 0) as usize, j - (j < BINS) as usize);
        if hi > lo
            && hi - lo >= min_bins
            && hi - lo < BINS
            && covers[lo..hi].iter().any(|&c| c)
            && best.is_none_or(|(l, h)| hi - lo > h - l)
        {
            best = Some((lo, hi));
        }
        i = j;
    }
    best
}

/// A cut piece of a thread: its kept vertices first, then the caps' centres.
struct Cut {
    positions: Vec<[f32; 3]>,
    faces: Vec<[u32; 3]>,
    kept_vertices: usize,
    kept_faces: usize,
}

/// The faces of the thread with all corners in slices `lo..hi`, its vertices compacted (the
/// kept ones first) and the loops the cut opened capped; `None` when nothing is left.
fn cut(
    a: &Axis,
    faces: &[[u32; 3]],
    mapped: &[Option<[f32; 3]>],
    lo: usize,
    hi: usize,
) -> Option<Cut> {
    let inside = |v: u32| {
        let b = a.slice[v as usize] as usize;
        b >= lo && b < hi && mapped[v as usize].is_some()
    };
    let mut map = vec![u32::MAX; mapped.len()];
    let mut positions = Vec::new();
    let mut out = Vec::new();
    for f in faces {
        if f.iter().all(|&v| inside(v)) {
            let g = f.map(|v| {
                if map[v as usize] == u32::MAX {
                    map[v as usize] = positions.len() as u32;
                    positions.push(mapped[v as usize].expect("inside"));
                }
                map[v as usize]
            });
            out.push(g);
        }
    }
    if out.is_empty() {
        return None;
    }
    // a thread that bends back (a hairpin) can leave several parts in the slices: the largest
    let (label, parts) = crate::mesh::connected_components(positions.len(), &out);
    if parts > 1 {
        let mut size = std::collections::HashMap::<u32, usize>::new();
        for f in &out {
            *size.entry(label[f[0] as usize]).or_default() += 1;
        }
        let (&keep, _) = size
            .iter()
            .max_by_key(|&(&l, &n)| (n, std::cmp::Reverse(l)))
            .expect("faces");
        let mut remap = vec![u32::MAX; positions.len()];
        let mut kept = Vec::new();
        out.retain(|f| label[f[0] as usize] == keep);
        for f in &mut out {
            for v in f.iter_mut() {
                if remap[*v as usize] == u32::MAX {
                    remap[*v as usize] = kept.len() as u32;
                    kept.push(positions[*v as usize]);
                }
                *v = remap[*v as usize];
            }
        }
        positions = kept;
    }
    let (kept_vertices, kept_faces) = (positions.len(), out.len());
    if a.closed {
        // the loops the cut opened, along their faces' orientation: a fan [b, a, centroid] each
        let mut caps = Vec::new();
        for lp in crate::mesh::boundary_loops(&out) {
            if lp.len() < 3 {
                continue;
            }
            let c = lp
                .iter()
                .map(|&v| Vec3::from(positions[v as usize]))
                .sum::<Vec3>()
                / lp.len() as f32;
            let cv = positions.len() as u32;
            positions.push(c.to_array());
            for k in 0..lp.len() {
                let (x, y) = (lp[k], lp[(k + 1) % lp.len()]);
                caps.push([y, x, cv]);
            }
        }
        out.extend(caps);
    }
    Some(Cut {
        positions,
        faces: out,
        kept_vertices,
        kept_faces,
    })
}

/// Places a thread cut short as an element of its own.
pub(super) fn place(elements: &mut Placement, t: Trimmed) {
    let piece = Piece {
        centre: t.centre,
        anchor: t.anchor,
        dir: t.dir,
    };
    let n_faces = t.faces.len();
    elements.push(
        t.source,
        t.positions,
        Some(t.faces),
        piece,
        t.radius,
        n_faces,
        t.share,
    );
}

/// A thread copy [`after_cut`] tries: its distance from the seed, element, swatch translation,
/// vertices mapped (where they map) and the mapped part's centre and radius.
struct Try {
    seed_dist: f32,
    e: usize,
    shift: Vec2,
    mapped: Vec<Option<[f32; 3]>>,
    centre: Vec3,
    radius: f32,
}

/// After a patch's cut: each thread candidate it dropped (`dropped`, indices into `cands`) and
/// each copy of a thread that did not map whole (`unmapped`: torn, distorted or off the
/// flattened disc), nearest to the seed first, keeps its longest clear part ([`trim`]);
/// returns how many pieces were placed.
pub(super) fn after_cut(
    axes: &Axes,
    mapper: &Mapper,
    elements: &mut Placement,
    cands: &[super::elements::Candidate],
    dropped: Vec<usize>,
    unmapped: Vec<(usize, Vec2)>,
) -> usize {
    let setup = mapper.setup;
    let mut tries: Vec<Try> = Vec::new();
    for j in dropped {
        let c = &cands[j];
        if axes.per[c.source as usize].is_some() {
            tries.push(Try {
                seed_dist: c.seed_dist,
                e: c.source as usize,
                shift: c.shift,
                mapped: c.positions.iter().copied().map(Some).collect(),
                centre: c.centre,
                radius: c.radius,
            });
        }
    }
    for (e, shift) in unmapped {
        let mapped = mapper.map_vertices(e, shift);
        let some: Vec<[f32; 3]> = mapped.iter().flatten().copied().collect();
        if (some.len() as f32) < MIN_SHARE * mapped.len() as f32 {
            continue;
        }
        let (centre, radius) = centre_and_radius(&some);
        let el = &setup.sw.elements[e];
        let seed_dist = ((Vec2::new(el.centre[0], el.centre[1]) + shift) * setup.s).length();
        tries.push(Try {
            seed_dist,
            e,
            shift,
            mapped,
            centre,
            radius,
        });
    }
    if tries.is_empty() {
        return 0;
    }
    tries.sort_by(|a, b| a.seed_dist.total_cmp(&b.seed_dist).then(a.e.cmp(&b.e)));
    // one neighbourhood for the patch: every element that may touch a thread tried
    let mid = tries.iter().map(|x| x.centre).sum::<Vec3>() / tries.len() as f32;
    let reach = tries
        .iter()
        .map(|x| x.centre.distance(mid) + x.radius)
        .fold(0.0f32, f32::max);
    let r = reach + elements.max_radius + setup.tau;
    let mut near = Nearby::new(setup, elements, mid, r, axes.soft_cell(setup.s));
    let mut placed = 0;
    for x in tries {
        let piece = trim(
            axes,
            mapper,
            x.e,
            x.shift,
            &x.mapped,
            &near.view(elements),
            None,
        );
        if let Some(p) = piece {
            let id = elements.placed.len() as u32;
            near.add(id, &p.positions);
            place(elements, p);
            placed += 1;
        }
    }
    placed
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synthesis::quilting::merging::{euler_characteristic, oriented_manifold};
    use crate::synthesis::quilting::{Axis, PatchKind, finite_patch, load_swatch};

    #[test]
    fn a_strand_cut_short_is_a_closed_piece_of_its_share() {
        // the first strand of the finite weave: a closed tube along x
        let sw = load_swatch(finite_patch(PatchKind::Weave, 1), Axis::Z).unwrap();
        let (ps, faces) = (sw.element_positions(0), sw.element_faces(0));
        let a = axis(ps, &faces).expect("a strand has an axis");
        assert!(a.closed && a.dir.x.abs() > 0.99, "axis {:?}", a.dir);
        let mapped: Vec<Option<[f32; 3]>> = ps.iter().copied().map(Some).collect();
        let piece = cut(&a, &faces, &mapped, 8, 24).expect("a piece");
        // half the strand, capped at both ends: a closed oriented manifold of the strand's
        // topology
        assert!(oriented_manifold(&piece.faces, true));
        assert_eq!(
            euler_characteristic(piece.positions.len(), &piece.faces),
            euler_characteristic(ps.len(), &faces)
        );
        assert_eq!(piece.positions.len(), piece.kept_vertices + 2, "two caps");
        let share = piece.kept_faces as f32 / faces.len() as f32;
        assert!((0.4..0.55).contains(&share), "share {share}");
        // every kept vertex lies within the run's slices
        let (lo, hi) = (a.lo + 8.0 * a.step, a.lo + 24.0 * a.step);
        for p in &piece.positions[..piece.kept_vertices] {
            let t = (Vec2::new(p[0], p[1]) - a.mid).dot(a.dir);
            assert!(t >= lo - 1e-4 && t <= hi + 1e-4, "t {t} outside {lo}..{hi}");
        }
        // a vertex that does not map takes its faces out
        let mut torn = mapped.clone();
        let v = (0..ps.len()).find(|&v| a.slice[v] == 20).unwrap();
        torn[v] = None;
        let holed = cut(&a, &faces, &torn, 8, 24).expect("a piece");
        assert!(holed.kept_faces < piece.kept_faces);
    }

    #[test]
    fn a_hairpin_cut_across_both_legs_keeps_one_piece() {
        // a thread bent back on itself: its slices away from the bend hold both legs
        let mut path = Vec::new();
        for i in 0..=20 {
            path.push(Vec3::new(4.0 * i as f32 / 20.0, 0.0, 0.0));
        }
        for i in 1..12 {
            let a = std::f32::consts::PI * i as f32 / 12.0;
            path.push(Vec3::new(4.0 + 0.5 * a.sin(), 0.0, 0.5 - 0.5 * a.cos()));
        }
        for i in 0..=20 {
            path.push(Vec3::new(4.0 - 4.0 * i as f32 / 20.0, 0.0, 1.0));
        }
        let mut b = super::super::swatch::Builder::default();
        b.strand(&path, 0.1, 0.05, 8, |p| Vec3::new(p.x, p.z, p.y + 0.1));
        let a = axis(&b.positions, &b.faces).expect("an axis");
        let mapped: Vec<Option<[f32; 3]>> = b.positions.iter().copied().map(Some).collect();
        let piece = cut(&a, &b.faces, &mapped, 0, 16).expect("a piece");
        let (_, parts) = crate::mesh::connected_components(piece.positions.len(), &piece.faces);
        assert_eq!(parts, 1);
        assert!(oriented_manifold(&piece.faces, true));
        assert!(
            piece.kept_faces * 3 < b.faces.len(),
            "one leg's part, not both"
        );
    }

    #[test]
    fn the_run_is_the_longest_clear_one_reaching_the_gap() {
        let mut blocked = [false; BINS];
        let covers = [true; BINS];
        // a whole clear thread is not a piece (the fill places whole copies)
        assert_eq!(longest_run(&blocked, &covers), None);
        blocked[10] = true;
        // 0..10 less its slice beside the block: 0..9; 11..32 less one: 12..32
        assert_eq!(longest_run(&blocked, &covers), Some((12, BINS)));
        // the run must reach the gap
        let mut near_start = [false; BINS];
        near_start[3] = true;
        assert_eq!(longest_run(&blocked, &near_start), Some((0, 9)));
        // and span a quarter of the thread at least
        blocked[5] = true;
        blocked[20] = true;
        assert_eq!(longest_run(&blocked, &near_start), None);
        assert_eq!(longest_run(&blocked, &covers), Some((22, BINS)));
    }
}
