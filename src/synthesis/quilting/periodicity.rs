//! Periodicity of a swatch, detected rather than assumed: the swatch is matched against shifted
//! copies of itself, and the tile that quilting repeats is cut from it.
//!
//! 1. **Shape key** of every element: vertex and face counts, the covariance of its vertices
//!    about their mean and its box size. Two elements share a key only when one is a
//!    translated copy of the other (a turned or resized copy does not).
//! 2. **Self-matching.** Every difference `t` between the centres of two elements with equal keys
//!    is a candidate translation (from a few anchor elements when the swatch has many: see
//!    [`symmetries`]), tried shortest first. `t` is a symmetry when the swatch shifted by `t`
//!    matches itself wherever the shifted copy stays inside the swatch: every element whose
//!    shifted box lies within the swatch's box must land on an element with its key (centres
//!    within 2% of the shortest centre spacing), and at least two elements must land.
//! 3. **Lattice.** `a` = the shortest symmetry, `b` = the shortest one not parallel to `a`. The
//!    tile is the smallest rectangle spanned by two orthogonal lattice vectors `A`, `B`
//!    (combinations `i a + j b`, `|i|, |j| <= 4`) with `A` along the swatch's x axis when the
//!    lattice has such a vector, else turned so that `A` is the tile's `+x`; each
//!    side is then multiplied until every element either has a copy of its shape one side away
//!    in the swatch itself or clears its copy's box (threads longer than the lattice step keep
//!    their length: a finite weave tiles with its strands end to end; shingles overlapping
//!    their neighbours' boxes keep the lattice step, as the swatch shows them so).
//! 4. **Tile.** Elements are grouped by their centre modulo the tile; of each group the one
//!    nearest the swatch's centre is kept, moved by whole tile periods into the tile.
//!
//! A swatch without two independent symmetries (a scattered cluster, a single row) gets a tile
//! from its spacing instead: its centre box plus its mean nearest-neighbour centre distance
//! (half of it on each side, so that copies meet with the swatch's own spacing), grown in steps
//! of 5% until the copies keep the swatch's clearance. Either way the tile's density (elements
//! per area) is the swatch's own ([`swatch_density`]) unless the spacing tile had to grow.

use glam::{Vec2, Vec3};

use super::swatch::Swatch;
use crate::mesh::TriMesh;
use crate::stats::kdtree::KdTree;

/// What [`detect`] found.
#[derive(Clone, Debug)]
pub struct Periodicity {
    /// The two shortest independent symmetry vectors in swatch units (x-y), when found.
    pub lattice: Option<[[f32; 2]; 2]>,
    /// The swatch to repeat: periodic, its extent the tile's period.
    pub tile: Swatch,
    /// Turn (radians, about z) from the swatch's frame into the tile's.
    pub turn: f32,
    /// The swatch element each tile element copies.
    pub source: Vec<u32>,
    /// How the tile was found: `"periodic"` (a built-in periodic swatch), `"lattice"`
    /// (symmetry vectors of a finite patch) or `"spacing"` (no lattice; tiled by its spacing).
    pub kind: &'static str,
}

struct Key {
    counts: (usize, usize),
    cov: [f32; 6],
    size: Vec3,
    centre: Vec3,
    lo: Vec3,
    hi: Vec3,
}

fn keys(sw: &Swatch) -> Vec<Key> {
    (0..sw.num_elements())
        .map(|e| {
            let ps = sw.element_positions(e);
            let n = ps.len().max(1) as f32;
            let mean = ps.iter().map(|p| Vec3::from(*p)).sum::<Vec3>() / n;
            let mut cov = [0.0f32; 6];
            let mut lo = Vec3::splat(f32::INFINITY);
            let mut hi = Vec3::splat(f32::NEG_INFINITY);
            for p in ps {
                let q = Vec3::from(*p);
                lo = lo.min(q);
                hi = hi.max(q);
                let d = q - mean;
                let v = [
                    d.x * d.x,
                    d.y * d.y,
                    d.z * d.z,
                    d.x * d.y,
                    d.x * d.z,
                    d.y * d.z,
                ];
                for k in 0..6 {
                    cov[k] += v[k] / n;
                }
            }
            Key {
                counts: (ps.len(), sw.elements[e].faces.len()),
                cov,
                size: hi - lo,
                centre: Vec3::from(sw.elements[e].centre),
                lo,
                hi,
            }
        })
        .collect()
}

fn same_shape(a: &Key, b: &Key) -> bool {
    if a.counts != b.counts {
        return false;
    }
    let scale = a.size.max_element().max(b.size.max_element()).max(1e-12);
    let tr = (a.cov[0] + a.cov[1] + a.cov[2]).max(1e-12);
    (a.size - b.size).abs().max_element() <= 0.02 * scale
        && (0..6).all(|k| (a.cov[k] - b.cov[k]).abs() <= 0.02 * tr)
        && (a.centre.z - b.centre.z).abs() <= 0.02 * scale
}

/// Elements per unit of swatch area: a periodic swatch's count over its period's area; a finite
/// patch with a lattice, its tile's; a finite one without, its count over its centre box grown
/// by its mean nearest-neighbour centre distance ([`spacing_density`]).
pub fn swatch_density(sw: &Swatch) -> f32 {
    let n = sw.num_elements() as f32;
    if sw.periodic {
        return n / (sw.extent[0] * sw.extent[1]);
    }
    let p = detect(sw);
    if p.kind == "lattice" {
        return p.tile.num_elements() as f32 / (p.tile.extent[0] * p.tile.extent[1]);
    }
    spacing_density(sw)
}

/// A finite swatch's count over its centre box grown by its mean nearest-neighbour centre
/// distance (half of it on each side): `1 / d^2` for a square lattice patch of step `d`.
pub fn spacing_density(sw: &Swatch) -> f32 {
    let n = sw.num_elements() as f32;
    let (w, h, d) = spacing_box(sw);
    n / ((w + d) * (h + d))
}

/// Each element's nearest-neighbour centre distance (x-y; copies around a periodic swatch
/// included).
pub fn nearest_spacing(sw: &Swatch) -> Vec<f32> {
    let images = sw.images();
    let centres: Vec<Vec2> = sw
        .elements
        .iter()
        .map(|e| Vec2::new(e.centre[0], e.centre[1]))
        .collect();
    let tree = KdTree::new(&flat(&centres), 2);
    let mut near = Vec::with_capacity(2);
    centres
        .iter()
        .enumerate()
        .map(|(i, &a)| {
            let mut best = f32::INFINITY;
            for im in &images {
                // the element itself is its own nearest in the unshifted copy
                let own = im[0] == 0.0 && im[1] == 0.0;
                tree.knn(
                    &(a - Vec2::from(*im)).to_array(),
                    1 + own as usize,
                    &mut near,
                );
                if let Some(&(d2, _)) = near.iter().find(|n| !(own && n.1 as usize == i)) {
                    best = best.min(d2.sqrt());
                }
            }
            if best.is_finite() { best } else { 0.0 }
        })
        .collect()
}

/// Centre box width and height and mean nearest-neighbour centre distance (x-y).
fn spacing_box(sw: &Swatch) -> (f32, f32, f32) {
    let c: Vec<Vec2> = sw
        .elements
        .iter()
        .map(|e| Vec2::new(e.centre[0], e.centre[1]))
        .collect();
    let mut lo = Vec2::splat(f32::INFINITY);
    let mut hi = Vec2::splat(f32::NEG_INFINITY);
    for p in &c {
        lo = lo.min(*p);
        hi = hi.max(*p);
    }
    let d = nearest_distances(&c)
        .into_iter()
        .filter(|d| d.is_finite())
        .sum::<f32>()
        / c.len().max(1) as f32;
    (hi.x - lo.x, hi.y - lo.y, d)
}

/// Each point's distance to the nearest other point (infinite for a single point).
fn nearest_distances(c: &[Vec2]) -> Vec<f32> {
    let tree = KdTree::new(&flat(c), 2);
    let mut near = Vec::with_capacity(2);
    c.iter()
        .map(|p| {
            tree.knn(&p.to_array(), 2, &mut near);
            near.get(1).map_or(f32::INFINITY, |n| n.0.sqrt())
        })
        .collect()
}

fn flat(c: &[Vec2]) -> Vec<f32> {
    c.iter().flat_map(|p| p.to_array()).collect()
}

/// Swatches of up to this many elements anchor candidates at every element.
const ALL_ANCHORS_UP_TO: usize = 64;
/// Anchors nearest the centre, and nearest each corner, of a larger swatch.
const ANCHORS_PER_PLACE: usize = 3;

/// Elements that anchor the candidate translations: every one for a small swatch, else those
/// nearest the centre and nearest each corner of the swatch (by their boxes, the ones a shift
/// towards the opposite corner keeps inside longest).
fn anchors(k: &[Key], extent: Vec2) -> Vec<usize> {
    let ne = k.len();
    if ne <= ALL_ANCHORS_UP_TO {
        return (0..ne).collect();
    }
    let centre = 0.5 * extent;
    let scores: [&dyn Fn(&Key) -> f32; 5] = [
        &|a| a.centre.truncate().distance(centre),
        &|a| a.hi.x + a.hi.y,
        &|a| a.hi.x + (extent.y - a.lo.y),
        &|a| (extent.x - a.lo.x) + a.hi.y,
        &|a| (extent.x - a.lo.x) + (extent.y - a.lo.y),
    ];
    let mut out: Vec<usize> = Vec::new();
    for score in scores {
        let mut order: Vec<usize> = (0..ne).collect();
        order.select_nth_unstable_by(ANCHORS_PER_PLACE, |&i, &j| {
            score(&k[i]).total_cmp(&score(&k[j]))
        });
        out.extend_from_slice(&order[..ANCHORS_PER_PLACE]);
    }
    out.sort_unstable();
    out.dedup();
    out
}

/// The shortest symmetry translation of a finite swatch and the shortest one not parallel to
/// it (x-y, swatch units): none, one or two, shortest first.
///
/// Candidates are the differences between an anchor element's centre and the centres of the
/// elements with its shape ([`anchors`]: all of a small swatch's), tried shortest first, each
/// checked element by element with a nearest-centre lookup and given up at its first element
/// that lands on nothing, so a swatch of thousands of elements is decided in about a second.
pub fn symmetries(sw: &Swatch) -> Vec<Vec2> {
    let k = keys(sw);
    let ne = k.len();
    if ne < 2 {
        return Vec::new();
    }
    let centres: Vec<Vec2> = k.iter().map(|a| a.centre.truncate()).collect();
    let spacing = nearest_distances(&centres)
        .into_iter()
        .fold(f32::INFINITY, f32::min);
    if !spacing.is_finite() || spacing <= 0.0 {
        return Vec::new();
    }
    let tol = 0.02 * spacing;
    let extent = Vec2::new(sw.extent[0], sw.extent[1]);
    // candidates in the half plane x > 0 (or x = 0, y > 0): -t is a symmetry when t is
    let mut cands: Vec<Vec2> = Vec::new();
    for i in anchors(&k, extent) {
        for j in 0..ne {
            if i == j || !same_shape(&k[i], &k[j]) {
                continue;
            }
            let t = centres[j] - centres[i];
            let t = if t.x < -tol || (t.x.abs() <= tol && t.y <= 0.0) {
                -t
            } else {
                t
            };
            cands.push(t);
        }
    }
    cands.sort_by(|a, b| a.length().total_cmp(&b.length()).then(a.x.total_cmp(&b.x)));
    // one candidate per translation: a cell of `tol` holds at most a few, and a repeat lies in
    // its cell or a neighbour
    let cell = |t: Vec2| ((t.x / tol).floor() as i64, (t.y / tol).floor() as i64);
    let mut seen: std::collections::HashMap<(i64, i64), Vec<Vec2>> = Default::default();
    let tree = KdTree::new(&flat(&centres), 2);
    let mut near = Vec::with_capacity(1);
    let mut is_symmetry = |t: Vec2| -> bool {
        let (margin, lo, hi) = (0.02 * spacing, Vec2::ZERO, extent);
        let mut landed = 0usize;
        for a in &k {
            let (blo, bhi) = (a.lo.truncate() + t, a.hi.truncate() + t);
            if blo.x < lo.x - margin
                || blo.y < lo.y - margin
                || bhi.x > hi.x + margin
                || bhi.y > hi.y + margin
            {
                continue;
            }
            // centres are at least `spacing` apart, so only the nearest can be within `tol`
            tree.knn(&(a.centre.truncate() + t).to_array(), 1, &mut near);
            match near.first() {
                Some(&(d2, b)) if d2.sqrt() <= tol && same_shape(a, &k[b as usize]) => landed += 1,
                _ => return false,
            }
        }
        landed >= 2
    };
    let mut out: Vec<Vec2> = Vec::new();
    for t in cands {
        let (cx, cy) = cell(t);
        let repeat = (-1..=1).any(|dx| {
            (-1..=1).any(|dy| {
                seen.get(&(cx + dx, cy + dy))
                    .is_some_and(|v| v.iter().any(|s| s.distance(t) <= tol))
            })
        });
        if repeat {
            continue;
        }
        seen.entry((cx, cy)).or_default().push(t);
        let independent = out
            .first()
            .is_none_or(|a| a.perp_dot(t).abs() > 0.1 * a.length() * t.length());
        if independent && is_symmetry(t) {
            out.push(t);
            if out.len() == 2 {
                break;
            }
        }
    }
    out
}

/// Detect the swatch's periodicity and build the tile quilting repeats.
pub fn detect(sw: &Swatch) -> Periodicity {
    if sw.periodic {
        return Periodicity {
            lattice: Some([[sw.extent[0], 0.0], [0.0, sw.extent[1]]]),
            tile: sw.clone(),
            turn: 0.0,
            source: (0..sw.num_elements() as u32).collect(),
            kind: "periodic",
        };
    }
    if let [a, b] = symmetries(sw)[..]
        && let Some(t) = lattice_tile(sw, a, b)
    {
        return t;
    }
    spacing_tile(sw)
}

fn lattice_tile(sw: &Swatch, a: Vec2, b: Vec2) -> Option<Periodicity> {
    // smallest rectangle of two orthogonal lattice vectors, the first nearest the x axis
    let mut vecs: Vec<Vec2> = Vec::new();
    for i in -4i32..=4 {
        for j in -4i32..=4 {
            if (i, j) != (0, 0) {
                vecs.push(a * i as f32 + b * j as f32);
            }
        }
    }
    // a rectangle along the swatch's own x axis when there is one (the swatch keeps its
    // orientation to the field), else the smallest turned one
    let along_x = vecs
        .iter()
        .any(|p| p.x > 0.0 && p.y.abs() <= 1e-3 * p.length());
    let mut best: Option<(f32, f32, Vec2, Vec2)> = None;
    for &p in &vecs {
        if p.x < 0.0 || (p.x == 0.0 && p.y < 0.0) {
            continue;
        }
        if along_x && p.y.abs() > 1e-3 * p.length() {
            continue;
        }
        for &q in &vecs {
            if p.dot(q).abs() > 1e-3 * p.length() * q.length() || p.perp_dot(q) <= 0.0 {
                continue;
            }
            let area = p.length() * q.length();
            let tilt = p.y.atan2(p.x).abs();
            let better = match best {
                None => true,
                Some((ba, bt, _, _)) => {
                    area < ba * (1.0 - 1e-3) || (area <= ba * (1.0 + 1e-3) && tilt < bt - 1e-4)
                }
            };
            if better {
                best = Some((area, tilt, p, q));
            }
        }
    }
    let (_, _, pa, pb) = best?;
    let turn = -pa.y.atan2(pa.x);
    let rot = glam::Mat2::from_angle(turn);
    let k = keys(sw);
    // element extents in the tile frame
    // an element must keep half the swatch's own clearance from its copy one period away
    let clearance = 0.5 * sw.clearance().min(0.05 * pa.length().min(pb.length()));
    let mut period = [pa.length(), pb.length()];
    for axis in 0..2 {
        let step = period[axis];
        let mut m = 1.0f32;
        // an element may sit one period from its own copy when the swatch shows a copy of its
        // shape there; otherwise it must clear its copy's box
        let clashes = |m: f32| {
            let mut shift = Vec2::ZERO;
            shift[axis] = m * step;
            let shift = rot.inverse() * shift;
            let off = Vec3::new(shift.x, shift.y, 0.0);
            let tol = 0.02 * step;
            k.iter().any(|key| {
                let shown = k.iter().any(|a| {
                    same_shape(a, key)
                        && k.iter().any(|b| {
                            same_shape(a, b) && (b.centre - a.centre - off).length() <= tol
                        })
                });
                let gap = ((key.lo + off) - key.hi).max(key.lo - (key.hi + off));
                !shown && gap.max_element() <= clearance
            })
        };
        while clashes(m) && m < 64.0 {
            m += 1.0;
        }
        period[axis] = m * step;
    }
    let centre = Vec2::new(sw.extent[0], sw.extent[1]) * 0.5;
    // group elements by centre modulo the tile, keep the most central of each
    let mut groups: Vec<(Vec2, usize, f32)> = Vec::new();
    let tol = 0.02 * pa.length().min(pb.length());
    for (e, key) in k.iter().enumerate() {
        let c = rot * key.centre.truncate();
        let m = Vec2::new(c.x.rem_euclid(period[0]), c.y.rem_euclid(period[1]));
        let d = key.centre.truncate().distance(centre);
        let wrap = |x: f32, p: f32| {
            let r = x.rem_euclid(p);
            r.min(p - r)
        };
        match groups.iter_mut().find(|(g, ge, _)| {
            wrap(g.x - m.x, period[0]) <= tol
                && wrap(g.y - m.y, period[1]) <= tol
                && same_shape(&k[*ge], key)
        }) {
            Some(g) => {
                if d < g.2 {
                    g.1 = e;
                    g.2 = d;
                }
            }
            None => groups.push((m, e, d)),
        }
    }
    groups.sort_by_key(|g| g.1);
    let mut positions = Vec::new();
    let mut faces = Vec::new();
    for &(_, e, _) in &groups {
        let c = rot * k[e].centre.truncate();
        let shift = Vec2::new(
            c.x.rem_euclid(period[0]) - c.x,
            c.y.rem_euclid(period[1]) - c.y,
        );
        let v0 = positions.len() as u32;
        for p in sw.element_positions(e) {
            let q = rot * Vec2::new(p[0], p[1]) + shift;
            positions.push([q.x, q.y, p[2]]);
        }
        faces.extend(sw.element_faces(e).iter().map(|f| f.map(|v| v + v0)));
    }
    let tile = Swatch::from_mesh(&TriMesh::new(positions, faces), period, true).ok()?;
    Some(Periodicity {
        lattice: Some([a.to_array(), b.to_array()]),
        source: groups.iter().map(|g| g.1 as u32).collect(),
        tile,
        turn,
        kind: "lattice",
    })
}

fn spacing_tile(sw: &Swatch) -> Periodicity {
    let (w, h, d) = spacing_box(sw);
    let lo = sw
        .elements
        .iter()
        .map(|e| Vec2::new(e.centre[0], e.centre[1]))
        .fold(Vec2::splat(f32::INFINITY), Vec2::min);
    let own = sw.clearance();
    let mut grow = 1.0f32;
    let mut tile = None;
    for _ in 0..20 {
        let period = [(w + d) * grow, (h + d) * grow];
        let shift = Vec2::splat(0.5 * d) - lo;
        let positions: Vec<[f32; 3]> = sw
            .mesh
            .positions
            .iter()
            .map(|p| [p[0] + shift.x, p[1] + shift.y, p[2]])
            .collect();
        let t = Swatch::from_mesh(
            &TriMesh::new(positions, sw.mesh.faces.clone()),
            period,
            true,
        )
        .expect("a valid swatch stays valid when moved");
        let ok = !own.is_finite() || t.clearance() >= 0.999 * own;
        tile = Some(t);
        if ok {
            break;
        }
        grow *= 1.05;
    }
    Periodicity {
        lattice: None,
        tile: tile.expect("at least one try"),
        turn: 0.0,
        source: (0..sw.num_elements() as u32).collect(),
        kind: "spacing",
    }
}
