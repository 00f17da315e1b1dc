//! A flat bounding-volume hierarchy over triangles: closest-point and ray queries.

use glam::Vec3;

const LEAF_SIZE: usize = 4;

/// Slack on the barycentric bounds of the ray-triangle test: a ray through a shared vertex or
/// along a shared edge must not slip between the triangles by rounding (and hit the far side).
pub(crate) const BARY_EPS: f32 = 1e-5;

/// A node of a median-split triangle tree ([`median_split`]).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Node {
    /// Bounds of the node's triangles.
    pub lo: Vec3,
    pub hi: Vec3,
    /// Leaf: first index into `order`; inner node: index of the left child (right = left + 1).
    pub start: u32,
    /// Number of triangles for a leaf, 0 for an inner node.
    pub count: u32,
}

/// A bounding-volume hierarchy over a triangle list (median split on the longest centroid axis,
/// leaves of up to 4 triangles, nodes in one flat array). Queries take `&self` and can run in
/// parallel.
#[derive(Clone, Debug)]
pub struct TriangleBvh {
    nodes: Vec<Node>,
    /// Face index of each triangle slot, in leaf order.
    order: Vec<u32>,
    /// Corner positions of each slot.
    tris: Vec<[Vec3; 3]>,
}

/// Deepest traversal stack a query keeps on the stack before spilling to the heap: a median
/// split of up to 2^40 leaves pushes at most two entries per level.
const STACK: usize = 96;

fn box_dist2(lo: Vec3, hi: Vec3, p: Vec3) -> f32 {
    let d = (lo - p).max(p - hi).max(Vec3::ZERO);
    d.length_squared()
}

/// Closest point on segment `ab` to `p`, as the parameter along it.
fn seg_param(a: Vec3, b: Vec3, p: Vec3) -> f32 {
    let ab = b - a;
    let l = ab.length_squared();
    if l > 0.0 {
        ((p - a).dot(ab) / l).clamp(0.0, 1.0)
    } else {
        0.0
    }
}

/// Closest point on triangle `abc` to `p` as barycentric coordinates (Ericson, Real-Time Collision
/// Detection, §5.1.5: Voronoi-region tests on the vertices, edges and face); degenerate
/// triangles fall back to the closest of the three edges.
pub(crate) fn closest_on_triangle(p: Vec3, a: Vec3, b: Vec3, c: Vec3) -> [f32; 3] {
    let ab = b - a;
    let ac = c - a;
    let ap = p - a;
    let d1 = ab.dot(ap);
    let d2 = ac.dot(ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return [1.0, 0.0, 0.0];
    }
    let bp = p - b;
    let d3 = ab.dot(bp);
    let d4 = ac.dot(bp);
    if d3 >= 0.0 && d4 <= d3 {
        return [0.0, 1.0, 0.0];
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return [1.0 - v, v, 0.0];
    }
    let cp = p - c;
    let d5 = ab.dot(cp);
    let d6 = ac.dot(cp);
    if d6 >= 0.0 && d5 <= d6 {
        return [0.0, 0.0, 1.0];
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return [1.0 - w, 0.0, w];
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return [0.0, 1.0 - w, w];
    }
    let sum = va + vb + vc;
    if sum > 0.0 && sum.is_finite() {
        let v = vb / sum;
        let w = vc / sum;
        return [1.0 - v - w, v, w];
    }
    // degenerate: best of the three edges
    let cands = [(a, b, 0usize, 1usize), (b, c, 1, 2), (c, a, 2, 0)];
    let mut best = [1.0, 0.0, 0.0];
    let mut bd = f32::INFINITY;
    for (s, e, i, j) in cands {
        let t = seg_param(s, e, p);
        let q = s + (e - s) * t;
        let d = q.distance_squared(p);
        if d < bd {
            bd = d;
            best = [0.0; 3];
            best[i] = 1.0 - t;
            best[j] += t;
        }
    }
    best
}

/// The median-split tree over `faces` (faces with out-of-range indices are left out): each
/// node is split at the median centroid along the longest axis of its centroids' bounds, down
/// to leaves of at most `leaf_size` triangles; nodes in one flat array (root first, children
/// after their parent, siblings side by side). Returns the nodes and the face of each triangle
/// slot, in leaf order.
pub(crate) fn median_split(
    positions: &[[f32; 3]],
    faces: &[[u32; 3]],
    leaf_size: usize,
) -> (Vec<Node>, Vec<u32>) {
    let n = positions.len();
    let in_range = |f: &[u32; 3]| f.iter().all(|&v| (v as usize) < n);
    let mut order: Vec<u32> = (0..faces.len() as u32)
        .filter(|&f| in_range(&faces[f as usize]))
        .collect();
    // Per face: its bounds and centroid (zero for a face left out), read once per level of
    // the build.
    let fbox: Vec<[Vec3; 3]> = faces
        .iter()
        .map(|f| {
            if in_range(f) {
                let [a, b, c] = f.map(|v| Vec3::from(positions[v as usize]));
                [a.min(b).min(c), a.max(b).max(c), (a + b + c) / 3.0]
            } else {
                [Vec3::ZERO; 3]
            }
        })
        .collect();
    let mut nodes = Vec::with_capacity(2 * order.len() / leaf_size + 1);
    if !order.is_empty() {
        nodes.push(Node {
            lo: Vec3::ZERO,
            hi: Vec3::ZERO,
            start: 0,
            count: order.len() as u32,
        });
        // iterative build: (node, start, end)
        let mut stack = vec![(0usize, 0usize, order.len())];
        while let Some((ni, s, e)) = stack.pop() {
            let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
            let (mut clo, mut chi) = (lo, hi);
            for &f in &order[s..e] {
                let [flo, fhi, fc] = fbox[f as usize];
                lo = lo.min(flo);
                hi = hi.max(fhi);
                clo = clo.min(fc);
                chi = chi.max(fc);
            }
            nodes[ni].lo = lo;
            nodes[ni].hi = hi;
            if e - s <= leaf_size {
                nodes[ni].start = s as u32;
                nodes[ni].count = (e - s) as u32;
                continue;
            }
            let ext = chi - clo;
            let axis = if ext.x >= ext.y && ext.x >= ext.z {
                0
            } else if ext.y >= ext.z {
                1
            } else {
                2
            };
            let mid = (s + e) / 2;
            order[s..e].select_nth_unstable_by(mid - s, |&a, &b| {
                fbox[a as usize][2][axis].total_cmp(&fbox[b as usize][2][axis])
            });
            let left = nodes.len();
            let blank = Node {
                lo: Vec3::ZERO,
                hi: Vec3::ZERO,
                start: 0,
                count: 0,
            };
            nodes.push(blank);
            nodes.push(blank);
            nodes[ni].start = left as u32;
            nodes[ni].count = 0;
            stack.push((left, s, mid));
            stack.push((left + 1, mid, e));
        }
    }
    (nodes, order)
}

impl TriangleBvh {
    /// Build over `faces` (faces with out-of-range indices are left out).
    pub fn new(positions: &[[f32; 3]], faces: &[[u32; 3]]) -> Self {
        let (nodes, order) = median_split(positions, faces, LEAF_SIZE);
        let corner = |f: u32| faces[f as usize].map(|v| Vec3::from(positions[v as usize]));
        let tris = order.iter().map(|&f| corner(f)).collect();
        TriangleBvh { nodes, order, tris }
    }

    /// The closest point of the surface to `p`: `(face, barycentric coordinates of the point in
    /// that face's corner order, distance)`; `None` for an empty mesh or a non-finite `p`.
    pub fn closest_point(&self, p: [f32; 3]) -> Option<(u32, [f32; 3], f32)> {
        let p = Vec3::from(p);
        if self.nodes.is_empty() || !p.is_finite() {
            return None;
        }
        let mut best = (u32::MAX, [0.0; 3], f32::INFINITY);
        let mut stack = Stack::default();
        stack.push((0, box_dist2(self.nodes[0].lo, self.nodes[0].hi, p)));
        while let Some((ni, d2)) = stack.pop() {
            if d2 >= best.2 {
                continue;
            }
            let node = self.nodes[ni as usize];
            if node.count > 0 {
                for slot in node.start..node.start + node.count {
                    let [a, b, c] = self.tris[slot as usize];
                    let bc = closest_on_triangle(p, a, b, c);
                    let q = a * bc[0] + b * bc[1] + c * bc[2];
                    let d = q.distance_squared(p);
                    if d < best.2 {
                        best = (self.order[slot as usize], bc, d);
                    }
                }
            } else {
                let (l, r) = (node.start, node.start + 1);
                let dl = box_dist2(self.nodes[l as usize].lo, self.nodes[l as usize].hi, p);
                let dr = box_dist2(self.nodes[r as usize].lo, self.nodes[r as usize].hi, p);
                // push the farther first so the nearer is visited first
                if dl <= dr {
                    stack.push((r, dr));
                    stack.push((l, dl));
                } else {
                    stack.push((l, dl));
                    stack.push((r, dr));
                }
            }
        }
        (best.0 != u32::MAX).then(|| (best.0, best.1, best.2.sqrt()))
    }

    /// The first hit of the ray `origin + t dir`, `t ≥ 0` (Möller & Trumbore 1997 ray-triangle
    /// test, slab test on the boxes): `(face, barycentric coordinates, t)` with `t` in units of
    /// `dir` (which need not be normalised); both triangle sides count.
    pub fn ray_hit(&self, origin: [f32; 3], dir: [f32; 3]) -> Option<(u32, [f32; 3], f32)> {
        let o = Vec3::from(origin);
        let d = Vec3::from(dir);
        if self.nodes.is_empty() || !o.is_finite() || !d.is_finite() || d == Vec3::ZERO {
            return None;
        }
        let inv = d.recip();
        let slab = |n: &Node, tmax: f32| -> Option<f32> {
            let t0 = (n.lo - o) * inv;
            let t1 = (n.hi - o) * inv;
            // NaN (0 * inf) from axis-parallel rays on a slab boundary: treat as "inside"
            let tmin_v = t0.min(t1);
            let tmax_v = t0.max(t1);
            let lo = tmin_v.x.max(tmin_v.y).max(tmin_v.z).max(0.0);
            let hi = tmax_v.x.min(tmax_v.y).min(tmax_v.z).min(tmax);
            (lo <= hi).then_some(lo)
        };
        let mut best: Option<(u32, [f32; 3], f32)> = None;
        let mut tbest = f32::INFINITY;
        let mut stack: Vec<u32> = Vec::with_capacity(64);
        if slab(&self.nodes[0], tbest).is_some() {
            stack.push(0);
        }
        while let Some(ni) = stack.pop() {
            let node = self.nodes[ni as usize];
            if slab(&node, tbest).is_none() {
                continue;
            }
            if node.count > 0 {
                for slot in node.start..node.start + node.count {
                    let [a, b, c] = self.tris[slot as usize];
                    let e1 = b - a;
                    let e2 = c - a;
                    let pv = d.cross(e2);
                    let det = e1.dot(pv);
                    if det.abs() < f32::MIN_POSITIVE {
                        continue;
                    }
                    let id = 1.0 / det;
                    let tv = o - a;
                    let u = tv.dot(pv) * id;
                    if !(-BARY_EPS..=1.0 + BARY_EPS).contains(&u) {
                        continue;
                    }
                    let qv = tv.cross(e1);
                    let v = d.dot(qv) * id;
                    if v < -BARY_EPS || u + v > 1.0 + BARY_EPS {
                        continue;
                    }
                    let t = e2.dot(qv) * id;
                    if t >= 0.0 && t < tbest {
                        tbest = t;
                        best = Some((self.order[slot as usize], [1.0 - u - v, u, v], t));
                    }
                }
            } else {
                stack.push(node.start + 1);
                stack.push(node.start);
            }
        }
        best
    }
}

/// A traversal stack on the call's own stack, spilling to the heap past [`STACK`] entries (no
/// allocation per query).
struct Stack {
    fixed: [(u32, f32); STACK],
    len: usize,
    spill: Vec<(u32, f32)>,
}

impl Default for Stack {
    fn default() -> Self {
        Stack {
            fixed: [(0, 0.0); STACK],
            len: 0,
            spill: Vec::new(),
        }
    }
}

impl Stack {
    fn push(&mut self, x: (u32, f32)) {
        if self.len < STACK {
            self.fixed[self.len] = x;
            self.len += 1;
        } else {
            self.spill.push(x);
        }
    }

    fn pop(&mut self) -> Option<(u32, f32)> {
        if let Some(x) = self.spill.pop() {
            return Some(x);
        }
        if self.len == 0 {
            return None;
        }
        self.len -= 1;
        Some(self.fixed[self.len])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn closest_point_and_ray_on_a_grid() {
        let m = 20u32;
        let mut pos = Vec::new();
        for y in 0..=m {
            for x in 0..=m {
                pos.push([x as f32, y as f32, ((x * 7 + y * 3) % 5) as f32 * 0.1]);
            }
        }
        let mut faces = Vec::new();
        for y in 0..m {
            for x in 0..m {
                let i = y * (m + 1) + x;
                faces.push([i, i + 1, i + m + 2]);
                faces.push([i, i + m + 2, i + m + 1]);
            }
        }
        let bvh = TriangleBvh::new(&pos, &faces);
        // brute force agreement
        for k in 0..200 {
            let p = Vec3::new(
                (k * 37 % 230) as f32 * 0.1 - 1.0,
                (k * 53 % 210) as f32 * 0.1 - 0.5,
                (k % 7) as f32 * 0.3 - 1.0,
            );
            let (f, bc, d) = bvh.closest_point(p.to_array()).unwrap();
            let bf = faces
                .iter()
                .map(|t| {
                    let [a, b, c] = t.map(|v| Vec3::from(pos[v as usize]));
                    let w = closest_on_triangle(p, a, b, c);
                    (a * w[0] + b * w[1] + c * w[2]).distance(p)
                })
                .fold(f32::INFINITY, f32::min);
            assert!((d - bf).abs() < 1e-4, "{k}: {d} vs {bf}");
            let [a, b, c] = faces[f as usize].map(|v| Vec3::from(pos[v as usize]));
            let q = a * bc[0] + b * bc[1] + c * bc[2];
            assert!((q.distance(p) - d).abs() < 1e-4);
        }
        // a ray straight down hits the face under it
        let (f, bc, t) = bvh.ray_hit([3.25, 7.5, 5.0], [0.0, 0.0, -2.0]).unwrap();
        let [a, b, c] = faces[f as usize].map(|v| Vec3::from(pos[v as usize]));
        let q = a * bc[0] + b * bc[1] + c * bc[2];
        assert!((q.x - 3.25).abs() < 1e-4 && (q.y - 7.5).abs() < 1e-4);
        assert!((5.0 - 2.0 * t - q.z).abs() < 1e-4);
        assert!(bvh.ray_hit([3.25, 7.5, 5.0], [0.0, 0.0, 1.0]).is_none());
        assert!(
            TriangleBvh::new(&pos, &[])
                .closest_point([0.0; 3])
                .is_none()
        );
    }
}
