//! Multi-scale solid-angle curvature (Connolly 1986, as used by Mertens et al. 2006 §3.1).
//!
//! The paper's descriptor at a surface point `p` and radius `r` is the fraction `f` of the
//! sphere `S(p, r)` that lies inside the object (exact: spherical excess of the intersection
//! curve). We compute the same number through the surface instead of the curve: the closed
//! surface formed by the mesh patch `P = M ∩ B(p, r)` and the inner part of the sphere subtends
//! a solid angle of `2π` at its (smooth) boundary point `p`, so
//!
//! `f = 1/2 - Ω_P / (4π)`, with `Ω_P = ∫_P (x - p)·n / |x - p|³ dA`
//!
//! the signed solid angle of the patch seen from `p` (outward normals; exact per triangle by
//! Van Oosterom & Strackee 1983). We return `κ = 1 - 2f = Ω_P / (2π)`: 0 on a plane, `r / (2R)`
//! at any point of a sphere of radius `R` (convex: positive), `-r / (2R)` inside a spherical
//! cavity (concave: negative), within [-1, 1]. It needs no closed mesh (open scans just see the
//! patch they have).
//!
//! Speed: a Barnes-Hut traversal of a triangle tree (as in Barill et al. 2018, "Fast winding
//! numbers"): a node entirely inside the ball and far from `p` relative to its size contributes
//! its dipole `N·(c - p) / |c - p|³` (`N` = sum of area vectors, `c` = area centroid); leaves
//! are evaluated exactly, a triangle cut by the sphere counts with the fraction of its area
//! inside, and so does a node cut by the sphere that is small against it (`< 0.08 r`, dipole ×
//! fraction, the sphere taken as planar across the node). Cost per query is then about
//! independent of both the radius and the mesh resolution.
//!
//! Vertices: on a polyhedral surface the tangent cone at a vertex is not a half-space, so the
//! `2π` above becomes the cone's interior solid angle `4π - Ω_out`, where `Ω_out` (the solid
//! angle on the normal side) is the signed sum over the incident faces `(p, a, b)` of the
//! spherical triangles `(n̂, â, b̂)`. This puts back the curvature a coarse mesh concentrates at
//! its vertices (without it a sphere reads `r/(2R) (1 - O(h/r))`). Boundary vertices keep `2π`.

use glam::Vec3;
use rayon::prelude::*;

use super::bvh::median_split;
use crate::error::Result;
use crate::work::CancelToken;

const LEAF: usize = 8;
/// Opening criterion: a node is summarised when `|c - p| > BETA * radius`.
///
/// The default for every vertex of a mesh. The dipole of a node is accurate to about
/// `(1 / BETA)²` of its solid angle, and at large radii the ball holds much of the surface whose
/// contributions cancel (a closed part inside the ball sums to zero), so the error grows with
/// the radius: on the horse, the mean error of `κ` against every triangle summed exactly is
/// 0.003 at 3% of the diagonal and 0.03 at 30% with `BETA = 2.5`, 0.003 at 30% with 8, for
/// 2.7× the time (`examples/feature_sampling.rs`, `BRUTE=1`). [`SolidAngleCurvature::at`] takes
/// it per call.
pub const BETA: f32 = 2.5;
/// Nodes cut by the sphere and smaller than this fraction of the radius are summarised too.
const SMALL: f32 = 0.08;

#[derive(Clone, Copy, Debug)]
struct Node {
    lo: Vec3,
    hi: Vec3,
    /// Area centroid.
    c: Vec3,
    /// Sum of area vectors `(b - a) × (c - a) / 2`.
    n: Vec3,
    /// Radius of a ball around `c` holding the node.
    rad: f32,
    /// Leaf: first triangle slot; inner: left child (right = left + 1).
    start: u32,
    /// Triangles in a leaf, 0 for an inner node.
    count: u32,
}

/// A triangle tree for solid-angle sums: the median-split tree of [`super::TriangleBvh`] (leaves
/// of up to 8 triangles) with a dipole summary per node.
#[derive(Clone, Debug)]
pub struct SolidAngleTree {
    nodes: Vec<Node>,
    tris: Vec<[Vec3; 3]>,
}

fn area_vec(t: &[Vec3; 3]) -> Vec3 {
    0.5 * (t[1] - t[0]).cross(t[2] - t[0])
}

/// Signed solid angle of triangle `abc` seen from the origin (Van Oosterom & Strackee 1983);
/// positive when the origin is behind the counter-clockwise side.
#[inline]
fn tri_solid_angle(a: Vec3, b: Vec3, c: Vec3) -> f32 {
    let (la, lb, lc) = (a.length(), b.length(), c.length());
    let num = a.dot(b.cross(c));
    let den = la * lb * lc + a.dot(b) * lc + a.dot(c) * lb + b.dot(c) * la;
    if num == 0.0 && den == 0.0 {
        return 0.0;
    }
    2.0 * num.atan2(den)
}

/// Fraction of a triangle's area where the linear interpolant of the corner values `s` is
/// negative (exact for a linear field).
fn negative_fraction(s: [f32; 3]) -> f32 {
    let neg = s.iter().filter(|&&x| x < 0.0).count();
    match neg {
        0 => 0.0,
        3 => 1.0,
        1 | 2 => {
            // the lone corner on one side: fraction of the small triangle at it
            let lone_neg = neg == 1;
            let i = (0..3).find(|&i| (s[i] < 0.0) == lone_neg).unwrap_or(0);
            let (a, b, c) = (s[i], s[(i + 1) % 3], s[(i + 2) % 3]);
            let f = (a * a / ((a - b) * (a - c))).clamp(0.0, 1.0);
            if lone_neg { f } else { 1.0 - f }
        }
        _ => 0.0,
    }
}

/// Solid angle of the part of triangle `t` (relative to `p`) inside the ball of radius `r`:
/// the full triangle's, times the fraction of its area inside (the sphere taken as planar across
/// the triangle: `|x| - r` interpolated linearly). Triangles with every corner outside are left
/// out (they can only graze the ball when far larger than it).
#[inline]
fn clipped_solid_angle(t: [Vec3; 3], r: f32) -> f32 {
    let s = t.map(|x| x.length() - r);
    let f = negative_fraction(s);
    if f <= 0.0 {
        0.0
    } else {
        f * tri_solid_angle(t[0], t[1], t[2])
    }
}

impl SolidAngleTree {
    /// Build over `faces` (faces with out-of-range indices are left out).
    pub fn new(positions: &[[f32; 3]], faces: &[[u32; 3]]) -> Self {
        let (tree, order) = median_split(positions, faces, LEAF);
        let tris: Vec<[Vec3; 3]> = order
            .iter()
            .map(|&f| faces[f as usize].map(|v| Vec3::from(positions[v as usize])))
            .collect();
        let mut nodes: Vec<Node> = tree
            .iter()
            .map(|b| Node {
                lo: b.lo,
                hi: b.hi,
                c: Vec3::ZERO,
                n: Vec3::ZERO,
                rad: 0.0,
                start: b.start,
                count: b.count,
            })
            .collect();
        // dipoles bottom-up (children always have larger indices than their parent): sum of
        // area vectors, area, and area-weighted centroid
        let mut area = vec![0.0f32; nodes.len()];
        for ni in (0..nodes.len()).rev() {
            let node = nodes[ni];
            let (mut n, mut c, mut a) = (Vec3::ZERO, Vec3::ZERO, 0.0f32);
            if node.count > 0 {
                for t in &tris[node.start as usize..(node.start + node.count) as usize] {
                    let av = area_vec(t);
                    let ar = av.length();
                    n += av;
                    c += ar * (t[0] + t[1] + t[2]) / 3.0;
                    a += ar;
                }
            } else {
                for ch in [node.start as usize, node.start as usize + 1] {
                    n += nodes[ch].n;
                    c += nodes[ch].c * area[ch];
                    a += area[ch];
                }
            }
            let mid = (node.lo + node.hi) * 0.5;
            let c = if a > 0.0 { c / a } else { mid };
            nodes[ni].n = n;
            nodes[ni].c = c;
            nodes[ni].rad = ((node.hi - node.lo) * 0.5).length() + c.distance(mid);
            area[ni] = a;
        }
        SolidAngleTree { nodes, tris }
    }

    /// Signed solid angle `Ω` of the surface inside the ball `B(p, r)` seen from `p`.
    /// `beta`: the opening criterion ([`BETA`] by default).
    pub fn solid_angle_in_ball(&self, p: [f32; 3], r: f32, beta: f32, stack: &mut Vec<u32>) -> f32 {
        let p = Vec3::from(p);
        if self.nodes.is_empty() || !p.is_finite() || r.is_nan() || r <= 0.0 {
            return 0.0;
        }
        let r2 = r * r;
        let mut omega = 0.0f32;
        stack.clear();
        stack.push(0);
        while let Some(ni) = stack.pop() {
            let node = &self.nodes[ni as usize];
            let dmin = (node.lo - p).max(p - node.hi).max(Vec3::ZERO);
            if dmin.length_squared() > r2 {
                continue;
            }
            let far = (node.lo - p).abs().max((node.hi - p).abs());
            let inside = far.length_squared() <= r2;
            let d = node.c - p;
            let dl = d.length();
            if dl > beta * node.rad {
                if inside {
                    omega += node.n.dot(d) / (dl * dl * dl);
                    continue;
                }
                if node.rad < SMALL * r {
                    // a node small against the ball, cut by its sphere: its dipole times the
                    // fraction inside, the sphere taken as planar across the node
                    let f = ((r - dl) / (2.0 * node.rad) + 0.5).clamp(0.0, 1.0);
                    omega += f * node.n.dot(d) / (dl * dl * dl);
                    continue;
                }
            }
            if node.count > 0 {
                for t in &self.tris[node.start as usize..(node.start + node.count) as usize] {
                    let q = t.map(|x| x - p);
                    omega += if inside {
                        tri_solid_angle(q[0], q[1], q[2])
                    } else {
                        clipped_solid_angle(q, r)
                    };
                }
            } else {
                stack.push(node.start);
                stack.push(node.start + 1);
            }
        }
        omega
    }
}

/// Solid-angle curvature `κ = Ω_P / (2π)` (see the module doc) of every vertex at every radius
/// in `radii` (mesh units): `n × radii.len()`, vertex-major. Rayon-parallel over vertices.
pub fn solid_angle_curvature(
    positions: &[[f32; 3]],
    faces: &[[u32; 3]],
    radii: &[f32],
) -> Vec<f32> {
    solid_angle_curvature_cancellable(positions, faces, radii, &CancelToken::new())
        .unwrap_or_default()
}

/// [`solid_angle_curvature`] that checks `cancel` between batches of vertices and stops with
/// `Error::Cancelled`.
pub fn solid_angle_curvature_cancellable(
    positions: &[[f32; 3]],
    faces: &[[u32; 3]],
    radii: &[f32],
    cancel: &CancelToken,
) -> Result<Vec<f32>> {
    let all: Vec<u32> = (0..positions.len() as u32).collect();
    SolidAngleCurvature::new(positions, faces).at(&all, radii, BETA, cancel)
}

/// The tree and the vertex cone corrections of one mesh, to evaluate the curvature at any subset
/// of its vertices ([`SolidAngleCurvature::at`]) and at several radii. The tree must be the
/// mesh's own: a triangle cut by the sphere counts with the fraction of its area inside, which
/// holds for triangles small against the radius, and a coarser triangulation of the same surface
/// (the input a working mesh was refined from) breaks it (measured: correlation 0.16 at the
/// smallest radius on the horse).
pub struct SolidAngleCurvature<'a> {
    positions: &'a [[f32; 3]],
    tree: SolidAngleTree,
    cone: Vec<f32>,
}

impl<'a> SolidAngleCurvature<'a> {
    /// Build the tree over `faces` and the cone corrections of every vertex.
    pub fn new(positions: &'a [[f32; 3]], faces: &[[u32; 3]]) -> Self {
        SolidAngleCurvature {
            positions,
            tree: SolidAngleTree::new(positions, faces),
            cone: cone_excess(positions, faces),
        }
    }

    /// `κ` of `vertices` (indices into the mesh) at every radius in `radii`:
    /// `vertices.len() × radii.len()`, vertex-major. Rayon-parallel; checks `cancel` between
    /// batches. `beta`: the tree's opening criterion ([`BETA`] by default; larger is more exact
    /// and slower).
    pub fn at(
        &self,
        vertices: &[u32],
        radii: &[f32],
        beta: f32,
        cancel: &CancelToken,
    ) -> Result<Vec<f32>> {
        let k = radii.len();
        let mut out = vec![0.0f32; vertices.len() * k];
        if k == 0 {
            return Ok(out);
        }
        const BATCH: usize = 4096;
        for (bi, chunk) in out.chunks_mut(BATCH * k).enumerate() {
            cancel.check()?;
            chunk.par_chunks_mut(k).enumerate().for_each_init(
                || Vec::with_capacity(128),
                |stack, (i, o)| {
                    let v = vertices[bi * BATCH + i] as usize;
                    let (Some(&p), Some(&cone)) = (self.positions.get(v), self.cone.get(v)) else {
                        return;
                    };
                    for (j, &r) in radii.iter().enumerate() {
                        let om = self.tree.solid_angle_in_ball(p, r, beta, stack) + cone;
                        o[j] = (om / std::f32::consts::TAU).clamp(-1.0, 1.0);
                    }
                },
            );
        }
        Ok(out)
    }
}

/// Per vertex, `Ω_out - 2π`: how much the solid angle on the normal side of the polyhedral
/// tangent cone exceeds a half-space (positive at convex vertices); 0 on the boundary and at
/// vertices without a usable normal.
fn cone_excess(positions: &[[f32; 3]], faces: &[[u32; 3]]) -> Vec<f32> {
    let n = positions.len();
    let normals = super::vertex_normals(positions, faces);
    let mut acc = vec![0.0f32; n];
    let mut open = vec![false; n];
    for l in crate::mesh::boundary_loops(faces) {
        for v in l {
            if let Some(o) = open.get_mut(v as usize) {
                *o = true;
            }
        }
    }
    for f in faces {
        if f.iter().any(|&v| v as usize >= n) {
            continue;
        }
        for k in 0..3 {
            let (p, a, b) = (
                f[k] as usize,
                f[(k + 1) % 3] as usize,
                f[(k + 2) % 3] as usize,
            );
            let pp = Vec3::from(positions[p]);
            let ea = (Vec3::from(positions[a]) - pp).normalize_or_zero();
            let eb = (Vec3::from(positions[b]) - pp).normalize_or_zero();
            let nn = Vec3::from(normals[p]);
            if ea == Vec3::ZERO || eb == Vec3::ZERO || nn == Vec3::ZERO {
                continue;
            }
            acc[p] += tri_solid_angle(nn, ea, eb);
        }
    }
    acc.iter()
        .zip(&open)
        .map(|(&a, &o)| {
            if o || !a.is_finite() {
                0.0
            } else {
                a - std::f32::consts::TAU
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plane_sphere_and_cavity() {
        // plane: a 41x41 grid
        let m = 40u32;
        let mut pos = Vec::new();
        for y in 0..=m {
            for x in 0..=m {
                pos.push([x as f32 / m as f32, y as f32 / m as f32, 0.0]);
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
        let k = solid_angle_curvature(&pos, &faces, &[0.05, 0.2]);
        let c = (m / 2 * (m + 1) + m / 2) as usize;
        assert!(
            k[2 * c].abs() < 1e-4 && k[2 * c + 1].abs() < 1e-4,
            "{:?}",
            &k[2 * c..2 * c + 2]
        );

        // (the poles' triangle fans concentrate curvature at one vertex: skip them)
        let (pos, faces) = crate::testdata::uv_sphere(96, 192);
        let radii = [0.1, 0.3, 0.6];
        let k = solid_angle_curvature(&pos, &faces, &radii);
        for v in (1000..pos.len() - 1000).step_by(997) {
            for (j, &r) in radii.iter().enumerate() {
                let want = r / 2.0;
                let got = k[v * 3 + j];
                assert!(
                    (got - want).abs() < 0.02 * want.max(0.1) + 0.004,
                    "v{v} r{r}: {got} vs {want}"
                );
            }
        }
        // inside a spherical cavity (faces flipped): negative
        let flipped: Vec<[u32; 3]> = faces.iter().map(|f| [f[0], f[2], f[1]]).collect();
        let k = solid_angle_curvature(&pos, &flipped, &radii);
        for v in (1000..pos.len() - 1000).step_by(1311) {
            assert!((k[v * 3 + 1] + 0.15).abs() < 0.01, "{}", k[v * 3 + 1]);
        }
    }
}
