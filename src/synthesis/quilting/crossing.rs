//! Whether the surfaces of two elements cross: some edge of one pierces a triangle of the other
//! (for triangles not coplanar, two triangles intersect exactly when an edge of one of them
//! pierces the other). The vertex clearance of the placement does not see this: interlinked
//! rings and crossing strands can pass through each other with every vertex far from the other
//! element. Only the triangles inside the overlap of the two bounding boxes are tested
//! (Möller & Trumbore 1997 segment-triangle test).

use glam::Vec3;

fn bounds(p: &[[f32; 3]]) -> (Vec3, Vec3) {
    p.iter().fold(
        (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
        |(lo, hi), q| (lo.min(Vec3::from(*q)), hi.max(Vec3::from(*q))),
    )
}

/// The triangles of `(p, f)` whose boxes meet the box `(lo, hi)`, as corner positions.
fn triangles_in(p: &[[f32; 3]], f: &[[u32; 3]], lo: Vec3, hi: Vec3) -> Vec<[Vec3; 3]> {
    f.iter()
        .filter_map(|t| {
            let c = t.map(|v| Vec3::from(p[v as usize]));
            let (tl, th) = (c[0].min(c[1]).min(c[2]), c[0].max(c[1]).max(c[2]));
            (tl.cmple(hi).all() && th.cmpge(lo).all()).then_some(c)
        })
        .collect()
}

/// Does the open segment `a -> b` pierce triangle `t` (strictly inside both)?
fn segment_pierces(a: Vec3, b: Vec3, t: &[Vec3; 3]) -> bool {
    let d = b - a;
    let (e1, e2) = (t[1] - t[0], t[2] - t[0]);
    let pv = d.cross(e2);
    let det = e1.dot(pv);
    if det.abs() <= 1e-12 * e1.length_squared().max(e2.length_squared()) * d.length() {
        return false;
    }
    let inv = 1.0 / det;
    let s = a - t[0];
    let u = s.dot(pv) * inv;
    if !(0.0..=1.0).contains(&u) {
        return false;
    }
    let q = s.cross(e1);
    let v = d.dot(q) * inv;
    if v < 0.0 || u + v > 1.0 {
        return false;
    }
    let tt = e2.dot(q) * inv;
    tt > 1e-5 && tt < 1.0 - 1e-5
}

/// Triangles bucketed in a uniform grid over a box (CSR: `start[c]..start[c + 1]` in `items`),
/// so that an edge meets only the triangles of the cells its box touches.
struct TriGrid {
    lo: Vec3,
    inv: Vec3,
    dims: [usize; 3],
    start: Vec<u32>,
    items: Vec<u32>,
}

impl TriGrid {
    fn new(tris: &[[Vec3; 3]], lo: Vec3, hi: Vec3) -> Self {
        // about two triangles a cell, at most 16 cells an axis
        let n = ((tris.len() as f32 / 2.0).cbrt().ceil() as usize).clamp(1, 16);
        let ext = (hi - lo).max(Vec3::splat(1e-12));
        let dims = [n; 3];
        let inv = Vec3::splat(n as f32) / ext;
        let mut g = TriGrid {
            lo,
            inv,
            dims,
            start: vec![0; n * n * n + 1],
            items: Vec::new(),
        };
        for pass in 0..2 {
            for (i, t) in tris.iter().enumerate() {
                let (a, b) = g.cells(t[0].min(t[1]).min(t[2]), t[0].max(t[1]).max(t[2]));
                for z in a[2]..=b[2] {
                    for y in a[1]..=b[1] {
                        for x in a[0]..=b[0] {
                            let c = (z * n + y) * n + x;
                            if pass == 0 {
                                g.start[c + 1] += 1;
                            } else {
                                g.items[g.start[c] as usize] = i as u32;
                                g.start[c] += 1;
                            }
                        }
                    }
                }
            }
            if pass == 0 {
                for c in 0..n * n * n {
                    g.start[c + 1] += g.start[c];
                }
                g.items = vec![0; g.start[n * n * n] as usize];
            } else {
                // each cell's start moved to its end: shift back
                for c in (1..=n * n * n).rev() {
                    g.start[c] = g.start[c - 1];
                }
                g.start[0] = 0;
            }
        }
        g
    }
    /// The (clamped) cell range of the box `lo..hi`.
    fn cells(&self, lo: Vec3, hi: Vec3) -> ([usize; 3], [usize; 3]) {
        let f = |p: Vec3| {
            let q = (p - self.lo) * self.inv;
            [0, 1, 2].map(|k| (q[k].floor().max(0.0) as usize).min(self.dims[k] - 1))
        };
        (f(lo), f(hi))
    }
}

fn edges_pierce(a: &[[Vec3; 3]], b: &[[Vec3; 3]]) -> bool {
    let hit = |p: Vec3, q: Vec3, tb: &[Vec3; 3]| {
        let (lo, hi) = (p.min(q), p.max(q));
        let (tl, th) = (tb[0].min(tb[1]).min(tb[2]), tb[0].max(tb[1]).max(tb[2]));
        tl.cmple(hi).all() && th.cmpge(lo).all() && segment_pierces(p, q, tb)
    };
    if a.len() * b.len() <= 256 {
        return a
            .iter()
            .any(|ta| (0..3).any(|k| b.iter().any(|tb| hit(ta[k], ta[(k + 1) % 3], tb))));
    }
    let (lo, hi) = b.iter().fold(
        (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
        |(l, h), t| {
            (
                l.min(t[0]).min(t[1]).min(t[2]),
                h.max(t[0]).max(t[1]).max(t[2]),
            )
        },
    );
    let grid = TriGrid::new(b, lo, hi);
    let n = grid.dims[0];
    a.iter().any(|ta| {
        (0..3).any(|k| {
            let (p, q) = (ta[k], ta[(k + 1) % 3]);
            let (el, eh) = (p.min(q), p.max(q));
            if el.cmpgt(hi).any() || eh.cmplt(lo).any() {
                return false;
            }
            let (c0, c1) = grid.cells(el, eh);
            (c0[2]..=c1[2]).any(|z| {
                (c0[1]..=c1[1]).any(|y| {
                    (c0[0]..=c1[0]).any(|x| {
                        let c = (z * n + y) * n + x;
                        grid.items[grid.start[c] as usize..grid.start[c + 1] as usize]
                            .iter()
                            .any(|&i| hit(p, q, &b[i as usize]))
                    })
                })
            })
        })
    })
}

/// Do the surfaces of element `a` (positions, faces indexing them) and element `b` cross?
pub(crate) fn surfaces_cross(
    pa: &[[f32; 3]],
    fa: &[[u32; 3]],
    pb: &[[f32; 3]],
    fb: &[[u32; 3]],
) -> bool {
    let (la, ha) = bounds(pa);
    let (lb, hb) = bounds(pb);
    let (lo, hi) = (la.max(lb), ha.min(hb));
    if lo.cmpgt(hi).any() {
        return false;
    }
    let ta = triangles_in(pa, fa, lo, hi);
    if ta.is_empty() {
        return false;
    }
    let tb = triangles_in(pb, fb, lo, hi);
    !tb.is_empty() && (edges_pierce(&ta, &tb) || edges_pierce(&tb, &ta))
}

/// The pairs of output elements whose surfaces cross, found independently of the placement's
/// test: a ray along every output edge (a BVH over the whole output) that hits a triangle of
/// another element strictly inside the edge. Hits at the edge's very start are contacts (strands
/// of a weave touch where they cross), not crossings. Pairs as `(smaller, larger)` element ids,
/// sorted.
pub fn crossing_pairs(out: &super::QuiltOutput) -> Vec<(u32, u32)> {
    let pos = &out.elements.positions;
    let bvh = crate::geometry::TriangleBvh::new(pos, &out.elements.faces);
    let face_elem: Vec<u32> = out
        .elements
        .faces
        .iter()
        .map(|f| out.element_id[f[0] as usize])
        .collect();
    let mut pairs = Vec::new();
    for f in &out.elements.faces {
        for k in 0..3 {
            let (a, b) = (f[k] as usize, f[(k + 1) % 3] as usize);
            let (pa, pb) = (Vec3::from(pos[a]), Vec3::from(pos[b]));
            let o = pa + 1e-4 * (pb - pa);
            if let Some((t, _, dist)) = bvh.ray_hit(o.to_array(), (pb - o).to_array()) {
                let (e, g) = (out.element_id[a], face_elem[t as usize]);
                if dist > 1e-3 && dist < 1.0 - 1e-4 && e != g {
                    pairs.push((e.min(g), e.max(g)));
                }
            }
        }
    }
    pairs.sort_unstable();
    pairs.dedup();
    pairs
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square(z: f32, shift: [f32; 2], tilt: bool) -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
        let c = |x: f32, y: f32| {
            let zz = if tilt { z + x } else { z };
            [x + shift[0], y + shift[1], zz]
        };
        (
            vec![c(-1.0, -1.0), c(1.0, -1.0), c(1.0, 1.0), c(-1.0, 1.0)],
            vec![[0, 1, 2], [0, 2, 3]],
        )
    }

    #[test]
    fn crossing_and_clear_squares() {
        let (pa, fa) = square(0.0, [0.0, 0.0], false);
        // a tilted square through the first one
        let (pb, fb) = square(0.0, [0.3, 0.2], true);
        assert!(surfaces_cross(&pa, &fa, &pb, &fb));
        // the same lifted clear of it
        let (pc, fc) = square(3.0, [0.3, 0.2], true);
        assert!(!surfaces_cross(&pa, &fa, &pc, &fc));
        // parallel, just above: clear
        let (pd, fd) = square(0.01, [0.5, 0.5], false);
        assert!(!surfaces_cross(&pa, &fa, &pd, &fd));
    }

    #[test]
    fn the_grid_finds_what_the_pairwise_test_finds() {
        // two wavy sheets, shifted so that some pairs pierce and some do not
        let sheet = |n: usize, dz: f32, phase: f32| -> Vec<[Vec3; 3]> {
            let p = |i: usize, j: usize| {
                let (x, y) = (i as f32 / n as f32, j as f32 / n as f32);
                Vec3::new(x, y, dz + 0.05 * (9.0 * x + phase).sin() * (7.0 * y).cos())
            };
            let mut t = Vec::new();
            for j in 0..n {
                for i in 0..n {
                    t.push([p(i, j), p(i + 1, j), p(i + 1, j + 1)]);
                    t.push([p(i, j), p(i + 1, j + 1), p(i, j + 1)]);
                }
            }
            t
        };
        let brute = |a: &[[Vec3; 3]], b: &[[Vec3; 3]]| {
            a.iter().any(|ta| {
                (0..3).any(|k| {
                    b.iter()
                        .any(|tb| segment_pierces(ta[k], ta[(k + 1) % 3], tb))
                })
            })
        };
        let a = sheet(20, 0.0, 0.0);
        let mut seen = [0usize; 2];
        for s in 0..40 {
            let dz = -0.12 + 0.006 * s as f32;
            let b = sheet(17, dz, 1.3);
            let (g, f) = (edges_pierce(&a, &b), brute(&a, &b));
            assert_eq!(g, f, "offset {dz}");
            seen[g as usize] += 1;
        }
        assert!(seen[0] > 0 && seen[1] > 0, "{seen:?}");
    }

    #[test]
    fn built_in_swatches_have_no_crossing_elements() {
        use crate::synthesis::quilting::{SwatchKind, swatch};
        for kind in SwatchKind::ALL {
            let sw = swatch(kind, 1);
            let n = sw.elements.len();
            let mut crossing = Vec::new();
            for a in 0..n {
                for b in a + 1..n {
                    if surfaces_cross(
                        sw.element_positions(a),
                        &sw.element_faces(a),
                        sw.element_positions(b),
                        &sw.element_faces(b),
                    ) {
                        crossing.push((a, b));
                    }
                }
            }
            assert!(
                crossing.is_empty(),
                "{kind:?}: elements cross: {crossing:?}"
            );
        }
    }
}
