//! Element merging (Zhou et al. 2006 §2.5-2.7): an element already in the output (`a`,
//! the paper's `C_out`) and a new one from the patch (`b`, `C_in`) that covers part of it are
//! deformed toward each other and joined into one element.
//!
//! 1. **Correspondence (§2.5).** Each vertex of one element is paired with its closest point on
//!    the other; pairs farther apart than `delta` (two mean edge lengths, ZHOU proposal 3) or
//!    whose normals differ by more than 60 degrees (the paper drops opposite ones; a vertex
//!    facing the other's cap is no partner either) are dropped. The two correspond when at least [`MIN_SHARED`] of each one's vertices are paired
//!    and neither is wholly covered ([`MAX_SHARED`]; a covered element is a duplicate, which the
//!    caller's cut resolves by keeping one).
//! 2. **Deformation (§2.6, eq. (4)-(5)).** Every paired vertex gets the goal
//!    `c_i = (v_i + h_i) / 2`, the midpoint with its closest point `h_i`, and each element is
//!    deformed by [`laplacian_deform`] with `mu = 1`: both move half-way. Departure: vertices
//!    more than [`HOLD_RINGS`] edges from every pair are held at their positions too, so a
//!    long element is bent only around the joint and keeps clear of its neighbours elsewhere
//!    (eq. (5) alone lets the free end of a thread swing by the misregistration). Departure: eq. (6)
//!    constrains `C_in` through barycentric combinations of its face corners; here both
//!    elements take vertex constraints from their own pairs, which is the same energy with the
//!    roles swapped and keeps one solver.
//! 3. **Cut (§2.7).** Instead of eq. (7)'s graph cut per element, both elements are cut by one
//!    plane: through the mean of the paired vertices (the middle of the overlap), across the
//!    direction from `a`'s centroid to `b`'s. `a` keeps the faces more than `g` (half a mean
//!    edge length) on its side, `b` those more than `g` on the other, each reduced to the
//!    connected pieces that hold unpaired vertices. Within the overlap the two surfaces
//!    coincide after the deformation, so any cut there is cheap (eq. (7) weighs every edge
//!    there alike), and the plane puts the two cut loops side by side, about `2 g` apart. A
//!    bisector of the two unpaired parts was tried first: on threads misregistered sideways
//!    the unpaired strips along the sides broke its level set into several loops. The plane
//!    suits the elongated elements merging is used for (threads), not elements that bend
//!    back within the overlap.
//! 4. **Stitch (ZHOU proposal 5).** Each new boundary loop of `a`'s piece is paired with the
//!    nearest of `b`'s; the two are walked in step from their closest pair, always advancing
//!    along the shorter diagonal, and the strip between them is triangulated with the
//!    orientation of both pieces. The loop vertices are then relaxed half-way to their 1-ring
//!    mean twice, smoothing the joint.
//!    Open elements (ribbons) whose cut meets their own boundary are not stitched: the cut
//!    edges there are chains inside a boundary loop, and such merges are refused (the strip
//!    check or step 5).
//! 5. **Integrity first.** The result must be one connected component whose edges are used by
//!    at most two faces with opposite orientations (exactly two when the elements are closed)
//!    and whose Euler characteristic equals `a`'s; otherwise nothing is merged
//!    (`None`) and the caller keeps the elements apart.

use glam::Vec3;

use crate::geometry::{TriangleBvh, laplacian_deform, mean_edge_length, vertex_normals};
use crate::mesh::{boundary_loops, connected_components, vertex_adjacency};

/// Smallest fraction of each element's vertices paired with the other for a merge.
pub const MIN_SHARED: f32 = 0.2;
/// Vertices farther than this many edges from every paired vertex are held in place by the
/// deformation (soft constraints at their positions, like the pairs').
pub const HOLD_RINGS: u32 = 3;
/// Largest fraction: above it the element is (nearly) covered by the other, a duplicate.
pub const MAX_SHARED: f32 = 0.9;

/// One element's geometry.
#[derive(Clone, Copy, Debug)]
pub struct ElementGeometry<'a> {
    /// Vertex positions.
    pub positions: &'a [[f32; 3]],
    /// Triangles.
    pub faces: &'a [[u32; 3]],
}

/// A merged element.
#[derive(Clone, Debug)]
pub struct Merged {
    /// Vertex positions.
    pub positions: Vec<[f32; 3]>,
    /// Triangles.
    pub faces: Vec<[u32; 3]>,
}

/// Euler characteristic `V - E + F` over the vertices used by faces.
pub fn euler_characteristic(n: usize, faces: &[[u32; 3]]) -> i64 {
    let mut used = vec![false; n];
    for f in faces {
        for &v in f {
            used[v as usize] = true;
        }
    }
    let v = used.iter().filter(|&&u| u).count() as i64;
    let (e, _) = crate::mesh::edge_counts(faces);
    v - e as i64 + faces.len() as i64
}

/// Whether every edge is used by at most two faces with opposite orientations (and by exactly
/// two when `closed`).
pub fn oriented_manifold(faces: &[[u32; 3]], closed: bool) -> bool {
    let e = crate::mesh::sorted_edges(faces);
    let mut i = 0;
    while i < e.len() {
        let mut j = i + 1;
        while j < e.len() && e[j].0 == e[i].0 {
            j += 1;
        }
        match j - i {
            1 if closed => return false,
            1 => {}
            2 => {
                let dir = |h: u32| {
                    let f = faces[h as usize / 3];
                    f[h as usize % 3] < f[(h as usize % 3 + 1) % 3]
                };
                if dir(e[i].1) == dir(e[i + 1].1) {
                    return false;
                }
            }
            _ => return false,
        }
        i = j;
    }
    true
}

/// The closest point of `geom` (through its `bvh`) to `p`: position, distance and the face's
/// unit normal.
fn closest(bvh: &TriangleBvh, geom: &ElementGeometry, p: [f32; 3]) -> Option<(Vec3, f32, Vec3)> {
    let (f, b, d) = bvh.closest_point(p)?;
    let c = geom.faces[f as usize].map(|v| Vec3::from(geom.positions[v as usize]));
    let n = (c[1] - c[0]).cross(c[2] - c[0]).normalize_or_zero();
    Some((c[0] * b[0] + c[1] * b[1] + c[2] * b[2], d, n))
}

/// Merge `a` (already placed) with `b` (new) when they correspond (module documentation);
/// `delta`: the largest distance of a correspondence pair. `None`: no correspondence, a
/// duplicate, or a join that would break the element's topology.
pub fn merge(a: &ElementGeometry, b: &ElementGeometry, delta: f32) -> Option<Merged> {
    try_merge(a, b, delta).ok()
}

/// [`merge`] with the reason a merge is refused.
pub fn try_merge(
    a: &ElementGeometry,
    b: &ElementGeometry,
    delta: f32,
) -> Result<Merged, &'static str> {
    let (na, nb) = (a.positions.len(), b.positions.len());
    if na == 0
        || nb == 0
        || a.faces.is_empty()
        || b.faces.is_empty()
        || delta.is_nan()
        || delta <= 0.0
    {
        return Err("empty element");
    }
    let bvh_a = TriangleBvh::new(a.positions, a.faces);
    let bvh_b = TriangleBvh::new(b.positions, b.faces);
    // 1. correspondence pairs: closer than delta, normals within 60 degrees (a vertex facing
    // the other element's cap or side is no partner)
    let ha = pairs(a, &bvh_b, b, delta);
    let hb = pairs(b, &bvh_a, a, delta);
    let fa = ha.iter().filter(|h| h.is_some()).count() as f32 / na as f32;
    let fb = hb.iter().filter(|h| h.is_some()).count() as f32 / nb as f32;
    if fa < MIN_SHARED || fb < MIN_SHARED {
        return Err("no correspondence");
    }
    if fa > MAX_SHARED || fb > MAX_SHARED {
        return Err("duplicate");
    }
    // 2. both half-way (eq. (5), mu = 1)
    let wa = half_way(a, &ha);
    let wb = half_way(b, &hb);
    // 3. the common cut, 4. the new loops stitched
    let mut joined = cut_across(a, b, (&wa, &wb), (&ha, &hb))?;
    let (la, lb) = stitch(a, b, &mut joined, delta)?;
    // 5. integrity, then the joint smoothed
    let Joined {
        mut positions,
        faces,
        ..
    } = joined;
    let closed = boundary_loops(a.faces).is_empty() && boundary_loops(b.faces).is_empty();
    if !oriented_manifold(&faces, closed)
        || euler_characteristic(positions.len(), &faces) != euler_characteristic(na, a.faces)
        || connected_components(positions.len(), &faces).1 != 1
    {
        return Err("stitched element breaks the topology");
    }
    smooth_seam(
        &mut positions,
        &faces,
        la.iter().chain(&lb).flatten().copied().collect(),
    );
    Ok(Merged { positions, faces })
}

/// Step 1: per vertex of `g`, its closest point on `og` (through `other`, its BVH) when closer
/// than `delta` with normals within 60 degrees.
fn pairs(
    g: &ElementGeometry,
    other: &TriangleBvh,
    og: &ElementGeometry,
    delta: f32,
) -> Vec<Option<Vec3>> {
    let vn = vertex_normals(g.positions, g.faces);
    g.positions
        .iter()
        .zip(&vn)
        .map(|(&p, n)| {
            closest(other, og, p)
                .filter(|x| x.1 <= delta && x.2.dot(Vec3::from(*n)) >= 0.5)
                .map(|x| x.0)
        })
        .collect::<Vec<Option<Vec3>>>()
}

/// Step 2: `g` deformed with its paired vertices (`h`) half-way to their partners; vertices
/// more than [`HOLD_RINGS`] edges from any paired one stay where they are, so an element
/// changes only around the joint.
fn half_way(g: &ElementGeometry, h: &[Option<Vec3>]) -> Vec<[f32; 3]> {
    let adj = vertex_adjacency(g.positions.len(), g.faces);
    laplacian_deform(g.positions, &adj, &goals(g, h, &adj), 1.0, 400)
}

/// The deformation's goals: paired vertices half-way, those beyond [`HOLD_RINGS`] held.
fn goals(g: &ElementGeometry, h: &[Option<Vec3>], adj: &crate::mesh::Csr) -> Vec<(u32, [f32; 3])> {
    let n = h.len();
    let mut hops = vec![u32::MAX; n];
    let mut queue: std::collections::VecDeque<u32> =
        (0..n as u32).filter(|&i| h[i as usize].is_some()).collect();
    for &i in &queue {
        hops[i as usize] = 0;
    }
    while let Some(i) = queue.pop_front() {
        let d = hops[i as usize];
        if d >= HOLD_RINGS {
            continue;
        }
        for &j in adj.row(i as usize) {
            if hops[j as usize] == u32::MAX {
                hops[j as usize] = d + 1;
                queue.push_back(j);
            }
        }
    }
    (0..n)
        .filter_map(|i| match h[i] {
            Some(h) => Some((
                i as u32,
                ((Vec3::from(g.positions[i]) + h) * 0.5).to_array(),
            )),
            None if hops[i] >= HOLD_RINGS => Some((i as u32, g.positions[i])),
            None => None,
        })
        .collect::<Vec<(u32, [f32; 3])>>()
}

/// The two pieces joined in one vertex numbering (`a`'s used vertices, then from `split` on
/// `b`'s), before the stitch.
struct Joined {
    positions: Vec<[f32; 3]>,
    faces: Vec<[u32; 3]>,
    map_a: Vec<u32>,
    map_b: Vec<u32>,
    split: u32,
    /// Half the larger mean edge length: the gap each piece keeps from the cutting plane.
    g: f32,
}

/// Step 3: both deformed elements (`wa`, `wb`, paired as `ha`, `hb`) cut by the plane through
/// the middle of the overlap (the mean of the paired vertices, deformed) across the direction
/// from a's centroid to b's.
fn cut_across(
    a: &ElementGeometry,
    b: &ElementGeometry,
    (wa, wb): (&[[f32; 3]], &[[f32; 3]]),
    (ha, hb): (&[Option<Vec3>], &[Option<Vec3>]),
) -> Result<Joined, &'static str> {
    let (na, nb) = (a.positions.len(), b.positions.len());
    let mean = |w: &[[f32; 3]]| w.iter().map(|&p| Vec3::from(p)).sum::<Vec3>() / w.len() as f32;
    let axis = (mean(wb) - mean(wa)).normalize_or_zero();
    if axis == Vec3::ZERO {
        return Err("the elements share a centroid");
    }
    let (mut mid, mut k) = (Vec3::ZERO, 0usize);
    for (w, h) in [(wa, ha), (wb, hb)] {
        for (p, h) in w.iter().zip(h.iter()) {
            if h.is_some() {
                mid += Vec3::from(*p);
                k += 1;
            }
        }
    }
    let mid = mid / k.max(1) as f32;
    let side = |p: [f32; 3]| (Vec3::from(p) - mid).dot(axis);
    let g =
        0.5 * mean_edge_length(a.positions, a.faces).max(mean_edge_length(b.positions, b.faces));
    let sa: Vec<f32> = wa.iter().map(|&p| side(p)).collect();
    let sb: Vec<f32> = wb.iter().map(|&p| side(p)).collect();
    let keep = |faces: &[[u32; 3]], s: &[f32], h: &[Option<Vec3>], want_a: bool| {
        let kept: Vec<[u32; 3]> = faces
            .iter()
            .filter(|f| {
                f.iter().all(|&v| {
                    let x = s[v as usize];
                    if want_a { x < -g } else { x > g }
                })
            })
            .copied()
            .collect();
        // only the connected pieces holding unpaired vertices
        let (label, _) = connected_components(s.len(), &kept);
        let mut good = std::collections::HashSet::new();
        for f in &kept {
            for &v in f {
                if h[v as usize].is_none() {
                    good.insert(label[v as usize]);
                }
            }
        }
        kept.into_iter()
            .filter(|f| good.contains(&label[f[0] as usize]))
            .collect::<Vec<_>>()
    };
    let ka = keep(a.faces, &sa, ha, true);
    let kb = keep(b.faces, &sb, hb, false);
    if ka.is_empty() || kb.is_empty() {
        return Err("nothing kept");
    }
    // merged vertex numbering: a's used vertices, then b's
    let mut map_a = vec![u32::MAX; na];
    let mut map_b = vec![u32::MAX; nb];
    let mut positions: Vec<[f32; 3]> = Vec::new();
    for f in &ka {
        for &v in f {
            if map_a[v as usize] == u32::MAX {
                map_a[v as usize] = positions.len() as u32;
                positions.push(wa[v as usize]);
            }
        }
    }
    let split = positions.len() as u32;
    for f in &kb {
        for &v in f {
            if map_b[v as usize] == u32::MAX {
                map_b[v as usize] = positions.len() as u32;
                positions.push(wb[v as usize]);
            }
        }
    }
    let mut faces: Vec<[u32; 3]> = ka.iter().map(|f| f.map(|v| map_a[v as usize])).collect();
    faces.extend(kb.iter().map(|f| f.map(|v| map_b[v as usize])));
    Ok(Joined {
        positions,
        faces,
        map_a,
        map_b,
        split,
        g,
    })
}

/// Step 4: each new boundary loop of `a`'s piece paired with the nearest of `b`'s and the strip
/// between them triangulated into `joined`; returns the loops (a's, b's).
#[allow(clippy::type_complexity)]
fn stitch(
    a: &ElementGeometry,
    b: &ElementGeometry,
    joined: &mut Joined,
    delta: f32,
) -> Result<(Vec<Vec<u32>>, Vec<Vec<u32>>), &'static str> {
    let Joined {
        positions,
        faces,
        map_a,
        map_b,
        split,
        g,
    } = joined;
    let (split, g) = (*split, *g);
    let old_boundary = |faces: &[[u32; 3]], map: &[u32]| -> std::collections::HashSet<(u32, u32)> {
        boundary_loops(faces)
            .iter()
            .flat_map(|l| (0..l.len()).map(move |i| (l[i], l[(i + 1) % l.len()])))
            .map(|(x, y)| (map[x as usize], map[y as usize]))
            .collect()
    };
    let mut was = old_boundary(a.faces, map_a);
    was.extend(old_boundary(b.faces, map_b));
    let loops: Vec<Vec<u32>> = boundary_loops(faces)
        .into_iter()
        .filter(|l| {
            l.len() >= 3 && (0..l.len()).any(|i| !was.contains(&(l[i], l[(i + 1) % l.len()])))
        })
        .collect();
    let (la, lb): (Vec<Vec<u32>>, Vec<Vec<u32>>) = loops.into_iter().partition(|l| l[0] < split);
    if la.is_empty()
        || la.len() != lb.len()
        || la
            .iter()
            .chain(&lb)
            .any(|l| l.iter().any(|&v| (v < split) != (l[0] < split)))
    {
        return Err("cut loops do not pair");
    }
    let pos = |v: u32| Vec3::from(positions[v as usize]);
    let centroid = |l: &[u32]| l.iter().map(|&v| pos(v)).sum::<Vec3>() / l.len() as f32;
    let ca: Vec<Vec3> = la.iter().map(|l| centroid(l)).collect();
    let cb: Vec<Vec3> = lb.iter().map(|l| centroid(l)).collect();
    let mut used_b = vec![false; lb.len()];
    let reach = 6.0 * g + 2.0 * delta;
    for (i, l) in la.iter().enumerate() {
        let j = (0..lb.len())
            .filter(|&j| !used_b[j])
            .min_by(|&x, &y| ca[i].distance(cb[x]).total_cmp(&ca[i].distance(cb[y])))
            .ok_or("cut loops do not pair")?;
        used_b[j] = true;
        let m = &lb[j];
        // start at the closest pair
        let (mut i0, mut j0, mut best) = (0usize, 0usize, f32::INFINITY);
        for (p, &u) in l.iter().enumerate() {
            for (q, &w) in m.iter().enumerate() {
                let d = pos(u).distance(pos(w));
                if d < best {
                    (i0, j0, best) = (p, q, d);
                }
            }
        }
        if best > reach {
            return Err("cut loops too far apart");
        }
        // a forward, b backward: triangles (a_{i+1}, a_i, b_j) and (b_j, b_{j-1}, a_i)
        let (n, k) = (l.len(), m.len());
        let at = |s: usize| l[(i0 + s) % n];
        let bt = |s: usize| m[(j0 + k - s % k) % k];
        let (mut si, mut sj) = (0usize, 0usize);
        while si < n || sj < k {
            let adv_a = if si == n {
                false
            } else if sj == k {
                true
            } else {
                pos(at(si + 1)).distance(pos(bt(sj))) <= pos(at(si)).distance(pos(bt(sj + 1)))
            };
            if adv_a {
                faces.push([at(si + 1), at(si), bt(sj)]);
                si += 1;
            } else {
                faces.push([bt(sj), bt(sj + 1), at(si)]);
                sj += 1;
            }
            if pos(at(si)).distance(pos(bt(sj))) > reach {
                return Err("stitch too long");
            }
        }
    }
    Ok((la, lb))
}

/// The joint smoothed: the `seam` vertices half-way to their 1-ring mean, twice.
fn smooth_seam(positions: &mut [[f32; 3]], faces: &[[u32; 3]], seam: Vec<u32>) {
    let adj = vertex_adjacency(positions.len(), faces);
    for _ in 0..2 {
        let moved: Vec<[f32; 3]> = seam
            .iter()
            .map(|&v| {
                let row = adj.row(v as usize);
                let mean = row.iter().map(|&u| pos_of(positions, u)).sum::<Vec3>()
                    / row.len().max(1) as f32;
                ((pos_of(positions, v) + mean) * 0.5).to_array()
            })
            .collect();
        for (&v, p) in seam.iter().zip(moved) {
            positions[v as usize] = p;
        }
    }
}

fn pos_of(p: &[[f32; 3]], v: u32) -> Vec3 {
    Vec3::from(p[v as usize])
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A closed capsule-like tube along x from `x0` to `x0 + len`: `rings` rings of `k`
    /// vertices (radius `r`), one cap vertex at each end.
    fn tube(x0: f32, len: f32, y: f32, rings: usize, k: usize, r: f32) -> Merged {
        let mut p = vec![[x0 - 0.5 * r, y, 0.0]];
        for i in 0..rings {
            let x = x0 + len * i as f32 / (rings - 1) as f32;
            for j in 0..k {
                let a = std::f32::consts::TAU * j as f32 / k as f32;
                p.push([x, y + r * a.cos(), r * a.sin()]);
            }
        }
        p.push([x0 + len + 0.5 * r, y, 0.0]);
        let end = p.len() as u32 - 1;
        let id = |i: usize, j: usize| 1 + (i * k + j % k) as u32;
        let mut f = Vec::new();
        for j in 0..k {
            f.push([0, id(0, j + 1), id(0, j)]);
        }
        for i in 0..rings - 1 {
            for j in 0..k {
                f.push([id(i, j), id(i, j + 1), id(i + 1, j + 1)]);
                f.push([id(i, j), id(i + 1, j + 1), id(i + 1, j)]);
            }
        }
        for j in 0..k {
            f.push([id(rings - 1, j + 1), end, id(rings - 1, j)]);
        }
        Merged {
            positions: p,
            faces: f,
        }
    }

    fn geom(m: &Merged) -> ElementGeometry<'_> {
        ElementGeometry {
            positions: &m.positions,
            faces: &m.faces,
        }
    }

    #[test]
    fn a_tube_and_its_shifted_copy_join_into_one_closed_longer_tube() {
        let a = tube(0.0, 4.0, 0.0, 33, 8, 0.2);
        // shifted half its length, slightly off its axis (a misregistered copy)
        let b = tube(2.03, 4.0, 0.04, 33, 8, 0.2);
        assert!(oriented_manifold(&a.faces, true));
        assert_eq!(euler_characteristic(a.positions.len(), &a.faces), 2);
        let m = try_merge(&geom(&a), &geom(&b), 0.25).expect("merged");
        assert!(
            oriented_manifold(&m.faces, true),
            "not a closed oriented surface"
        );
        assert_eq!(euler_characteristic(m.positions.len(), &m.faces), 2);
        assert_eq!(connected_components(m.positions.len(), &m.faces).1, 1);
        let (lo, hi) = m
            .positions
            .iter()
            .fold((f32::MAX, f32::MIN), |(l, h), p| (l.min(p[0]), h.max(p[0])));
        assert!(lo < 0.0 && hi > 6.0, "spans {lo}..{hi}");
        // the joint stays a tube: every vertex within the radius (plus the offset) of the axis
        for p in &m.positions {
            let r = (p[1] - 0.02).hypot(p[2]);
            assert!(r < 0.2 + 0.06, "vertex {p:?} off the tube");
        }
        // fewer vertices than both copies (the overlap is kept once), more than one
        assert!(m.positions.len() < a.positions.len() + b.positions.len());
        assert!(m.positions.len() > a.positions.len());
    }

    #[test]
    fn crossing_duplicate_or_distant_elements_are_not_merged() {
        let a = tube(0.0, 4.0, 0.0, 33, 8, 0.2);
        // an exact duplicate: wholly covered
        assert!(merge(&geom(&a), &geom(&a), 0.25).is_none());
        // parallel, a full spacing apart: no correspondence
        let b = tube(1.0, 4.0, 1.0, 33, 8, 0.2);
        assert!(merge(&geom(&a), &geom(&b), 0.25).is_none());
        // crossing at right angles: too few pairs
        let mut c = tube(-2.0, 4.0, 0.0, 33, 8, 0.2);
        for p in &mut c.positions {
            *p = [2.0 + p[1], p[0], p[2] + 0.1];
        }
        assert!(merge(&geom(&a), &geom(&c), 0.25).is_none());
    }

    #[test]
    fn open_ribbons_are_refused_not_broken() {
        // a flat strip of quads along x (an open element: one boundary loop)
        let ribbon = |x0: f32, y: f32| -> Merged {
            let mut p = Vec::new();
            for i in 0..=32 {
                let x = x0 + 4.0 * i as f32 / 32.0;
                p.push([x, y - 0.2, 0.0]);
                p.push([x, y + 0.2, 0.0]);
            }
            let mut f = Vec::new();
            for i in 0..32u32 {
                let (a, b, c, d) = (2 * i, 2 * i + 2, 2 * i + 3, 2 * i + 1);
                f.push([a, b, c]);
                f.push([a, c, d]);
            }
            Merged {
                positions: p,
                faces: f,
            }
        };
        let a = ribbon(0.0, 0.0);
        let b = ribbon(2.0, 0.03);
        // the cut runs into the ribbon's own boundary: the cut edges are chains within one
        // boundary loop, not loops of their own, and bridging whole loops would close the
        // ribbon into a sphere; the topology check refuses it (integrity first)
        assert!(try_merge(&geom(&a), &geom(&b), 0.3).is_err());
    }
}
