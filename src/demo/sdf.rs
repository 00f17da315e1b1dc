//! Signed-distance toolkit for the demo scene: primitives, smooth blends, grid sampling,
//! marching tetrahedra and on-surface relaxation.
//!
//! Primitives follow Inigo Quilez, "distance functions" (iquilezles.org/articles/distfunctions):
//! exact capsule / sphere / round cone, the `k0 (k0 - 1) / k1` ellipsoid bound, and the
//! quadratic polynomial smooth minimum `min(a, b) - h^2 k / 4`, `h = max(k - |a - b|, 0) / k`.

use crate::geometry::{Fade, value_noise};
use crate::mesh::TriMesh;
use glam::{Quat, Vec3};
use rayon::prelude::*;

/// Distance to a sphere of radius `r` centred at `c`.
#[inline]
pub fn sphere(p: Vec3, c: Vec3, r: f32) -> f32 {
    (p - c).length() - r
}

/// Distance to the capsule of radius `r` around segment `a`-`b`.
#[inline]
pub fn capsule(p: Vec3, a: Vec3, b: Vec3, r: f32) -> f32 {
    let pa = p - a;
    let ba = b - a;
    let h = (pa.dot(ba) / ba.dot(ba)).clamp(0.0, 1.0);
    (pa - ba * h).length() - r
}

/// Distance to a round cone: spheres of radius `r1` at `a` and `r2` at `b` joined by their
/// tangent cone (Quilez `sdRoundCone`, arbitrary endpoints; exact).
#[inline]
pub fn round_cone(p: Vec3, a: Vec3, b: Vec3, r1: f32, r2: f32) -> f32 {
    let ba = b - a;
    let l2 = ba.dot(ba);
    let rr = r1 - r2;
    let a2 = l2 - rr * rr;
    let il2 = 1.0 / l2;
    let pa = p - a;
    let y = pa.dot(ba);
    let z = y - l2;
    let x2 = (pa * l2 - ba * y).length_squared();
    let y2 = y * y * l2;
    let z2 = z * z * l2;
    let k = rr.signum() * rr * rr * x2;
    if z.signum() * a2 * z2 > k {
        return (x2 + z2).sqrt() * il2 - r2;
    }
    if y.signum() * a2 * y2 < k {
        return (x2 + y2).sqrt() * il2 - r1;
    }
    ((x2 * a2 * il2).sqrt() + y * rr) * il2 - r1
}

/// Approximate distance to an ellipsoid with semi-axes `r` centred at `c`, rotated by `q`
/// (Quilez bound `k0 (k0 - 1) / k1`, `k0 = |p / r|`, `k1 = |p / r^2|`).
#[inline]
pub fn ellipsoid(p: Vec3, c: Vec3, r: Vec3, q: Quat) -> f32 {
    let l = if q == Quat::IDENTITY {
        p - c
    } else {
        q.inverse() * (p - c)
    };
    let k0 = (l / r).length();
    let k1 = (l / (r * r)).length();
    if k1 < 1e-12 {
        return -r.min_element();
    }
    k0 * (k0 - 1.0) / k1
}

/// Polynomial smooth minimum with blend radius `k` (Quilez: `min(a,b) - h^2 k / 4`).
#[inline]
pub fn smin(a: f32, b: f32, k: f32) -> f32 {
    let h = (k - (a - b).abs()).max(0.0) / k;
    a.min(b) - h * h * k * 0.25
}

/// Polynomial smooth maximum (smooth intersection), `-smin(-a, -b, k)`.
#[inline]
pub fn smax(a: f32, b: f32, k: f32) -> f32 {
    -smin(-a, -b, k)
}

/// Rotation taking +X to the direction `d` with the smallest turn (for oriented ellipsoids).
pub fn rot_x_to(d: Vec3) -> Quat {
    Quat::from_rotation_arc(Vec3::X, d.normalize())
}

/// Forward-difference gradient of `f` at `p` with step `e`, and the value at `p`.
#[inline]
pub fn gradient(f: &(impl Fn(Vec3) -> f32 + ?Sized), p: Vec3, e: f32) -> (f32, Vec3) {
    let v = f(p);
    let g = Vec3::new(
        f(p + Vec3::X * e) - v,
        f(p + Vec3::Y * e) - v,
        f(p + Vec3::Z * e) - v,
    ) / e;
    (v, g)
}

/// Move `p` onto the zero set of `f` with a few Newton steps along the gradient.
pub fn project(f: &(impl Fn(Vec3) -> f32 + ?Sized), mut p: Vec3, e: f32) -> Vec3 {
    for _ in 0..4 {
        let (v, g) = gradient(f, p, e);
        let g2 = g.length_squared();
        if g2 < 1e-12 {
            break;
        }
        p -= g * (v / g2);
        if v.abs() < 1e-5 {
            break;
        }
    }
    p
}

/// Sample `f` on a regular grid and extract its zero level set `f = 0` (inside `f < 0`) by
/// marching tetrahedra over the Kuhn (Freudenthal) split of each cube into six tetrahedra
/// sharing the main diagonal. The level set of a piecewise-linear function at a regular value
/// on a simplicial complex is a closed 2-manifold, so the result is watertight and manifold by
/// construction; vertices are shared through one index per grid edge, faces are oriented with
/// the outward gradient (counter-clockwise seen from outside). Only the largest connected
/// component is kept.
pub fn mesh_sdf(f: &(impl Fn(Vec3) -> f32 + Sync + ?Sized), lo: Vec3, hi: Vec3, h: f32) -> TriMesh {
    // Pad by two cells so the grid boundary is outside the shape.
    let lo = lo - Vec3::splat(2.0 * h);
    let hi = hi + Vec3::splat(2.0 * h);
    let dims = ((hi - lo) / h).ceil().as_uvec3() + 1;
    let (nx, ny, nz) = (dims.x as usize, dims.y as usize, dims.z as usize);
    let slice = nx * ny;
    let point = |i: usize, j: usize, k: usize| lo + Vec3::new(i as f32, j as f32, k as f32) * h;

    // 1. Field values, one z-slice per task. Narrow band: the field is first sampled at the
    //    centres of B^3-point blocks; a block whose centre value exceeds (with margin) its
    //    half-diagonal cannot contain the surface for a 1-Lipschitz field, so its points take
    //    that value without further evaluation. Exact zeros are nudged outside (regular value).
    const B: usize = 4;
    let (bx, by, bz) = (nx.div_ceil(B), ny.div_ceil(B), nz.div_ceil(B));
    let coarse: Vec<f32> = (0..bx * by * bz)
        .into_par_iter()
        .map(|b| {
            let (i, j, k) = (b % bx, (b / bx) % by, b / (bx * by));
            let c = lo
                + (Vec3::new(i as f32, j as f32, k as f32) * B as f32 + (B - 1) as f32 * 0.5) * h;
            f(c)
        })
        .collect();
    let far = 1.5 * (B as f32 * 0.5 * 3f32.sqrt() * h) + 2.0 * h;
    let mut vals = vec![0.0f32; slice * nz];
    vals.par_chunks_mut(slice).enumerate().for_each(|(k, s)| {
        for j in 0..ny {
            for i in 0..nx {
                let cv = coarse[i / B + bx * (j / B + by * (k / B))];
                let v = if cv.abs() > far {
                    cv
                } else {
                    f(point(i, j, k))
                };
                s[i + nx * j] = if v == 0.0 { 1e-7 } else { v };
            }
        }
    });
    // Boundary points are forced outside so the surface cannot touch the grid border.
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                if i == 0 || j == 0 || k == 0 || i == nx - 1 || j == ny - 1 || k == nz - 1 {
                    let v = &mut vals[i + nx * (j + ny * k)];
                    *v = v.abs().max(1e-7);
                }
            }
        }
    }

    // 2. One vertex per sign-changing edge; the 7 edge directions from a point are the nonzero
    //    0/1 offsets (bit 0 = +x, bit 1 = +y, bit 2 = +z), edge id = 7 * point + (bits - 1).
    let offs: [usize; 8] =
        std::array::from_fn(|b| (b & 1) + nx * ((b >> 1) & 1) + slice * (b >> 2));
    let per_slice: Vec<Vec<(usize, Vec3)>> = (0..nz - 1)
        .into_par_iter()
        .map(|k| {
            let mut out = Vec::new();
            for j in 0..ny - 1 {
                for i in 0..nx - 1 {
                    let p = i + nx * (j + ny * k);
                    let v0 = vals[p];
                    for bits in 1..8usize {
                        let v1 = vals[p + offs[bits]];
                        if (v0 < 0.0) != (v1 < 0.0) {
                            let t = (v0 / (v0 - v1)).clamp(0.01, 0.99);
                            let d = Vec3::new(
                                (bits & 1) as f32,
                                ((bits >> 1) & 1) as f32,
                                (bits >> 2) as f32,
                            );
                            out.push((7 * p + bits - 1, point(i, j, k) + d * (t * h)));
                        }
                    }
                }
            }
            out
        })
        .collect();
    let mut edge_vertex = vec![u32::MAX; 7 * slice * nz];
    let mut positions = Vec::new();
    for s in &per_slice {
        for &(e, p) in s {
            edge_vertex[e] = positions.len() as u32;
            positions.push(p);
        }
    }
    drop(per_slice);

    // 3. Triangles per tetrahedron. The six Kuhn tetrahedra of a cube follow monotone paths
    //    000 -> 111 through one axis per step, so every tet edge is a positive-direction edge.
    const PERMS: [[usize; 3]; 6] = [
        [0, 1, 2],
        [0, 2, 1],
        [1, 0, 2],
        [1, 2, 0],
        [2, 0, 1],
        [2, 1, 0],
    ];
    let per_slice_faces: Vec<Vec<[u32; 3]>> = (0..nz - 1)
        .into_par_iter()
        .map(|k| {
            let mut out = Vec::new();
            for j in 0..ny - 1 {
                for i in 0..nx - 1 {
                    let p = i + nx * (j + ny * k);
                    // Skip cubes with no sign change.
                    let neg = (0..8).filter(|&b| vals[p + offs[b]] < 0.0).count();
                    if neg == 0 || neg == 8 {
                        continue;
                    }
                    for perm in PERMS {
                        let mut bits = [0usize; 4];
                        for s in 0..3 {
                            bits[s + 1] = bits[s] | (1 << perm[s]);
                        }
                        tet(&bits, p, &offs, &vals, &edge_vertex, &positions, &mut out);
                    }
                }
            }
            out
        })
        .collect();
    let faces: Vec<[u32; 3]> = per_slice_faces.concat();
    let positions: Vec<[f32; 3]> = positions.iter().map(|p| p.to_array()).collect();
    let mut mesh = largest_component(positions, faces);
    orient_consistently(&mut mesh);
    mesh
}

/// Make the orientation of a closed manifold mesh consistent by breadth-first propagation
/// across edges (a neighbour must traverse the shared edge in the opposite direction), then
/// flip everything if the signed volume is negative. Repairs the rare tetrahedron whose
/// geometric orientation test was decided by rounding.
pub fn orient_consistently(mesh: &mut TriMesh) {
    let nf = mesh.faces.len();
    let mut edges: Vec<(u32, u32, u32)> = Vec::with_capacity(3 * nf);
    for (fi, f) in mesh.faces.iter().enumerate() {
        for k in 0..3 {
            let (a, b) = (f[k], f[(k + 1) % 3]);
            edges.push((a.min(b), a.max(b), fi as u32));
        }
    }
    edges.par_sort_unstable();
    // Face neighbours across each edge (manifold: exactly two faces per edge).
    let mut nbr: Vec<Vec<u32>> = vec![Vec::new(); nf];
    for w in edges.windows(2) {
        if w[0].0 == w[1].0 && w[0].1 == w[1].1 {
            nbr[w[0].2 as usize].push(w[1].2);
            nbr[w[1].2 as usize].push(w[0].2);
        }
    }
    let has_directed =
        |f: &[u32; 3], a: u32, b: u32| (0..3).any(|k| f[k] == a && f[(k + 1) % 3] == b);
    let mut done = vec![false; nf];
    let mut queue = std::collections::VecDeque::new();
    for start in 0..nf {
        if done[start] {
            continue;
        }
        done[start] = true;
        queue.push_back(start);
        while let Some(fi) = queue.pop_front() {
            let f = mesh.faces[fi];
            for &g in &nbr[fi] {
                let g = g as usize;
                if done[g] {
                    continue;
                }
                // Shared edge traversed the same way by both faces means g is flipped.
                let same = (0..3).any(|k| has_directed(&mesh.faces[g], f[k], f[(k + 1) % 3]));
                if same {
                    mesh.faces[g].swap(1, 2);
                }
                done[g] = true;
                queue.push_back(g);
            }
        }
    }
    if signed_volume(mesh) < 0.0 {
        for f in &mut mesh.faces {
            f.swap(1, 2);
        }
    }
}

/// Emit the 0, 1 or 2 triangles of one tetrahedron (corners given as cube-corner bit masks).
#[inline]
fn tet(
    bits: &[usize; 4],
    p: usize,
    offs: &[usize; 8],
    vals: &[f32],
    edge_vertex: &[u32],
    positions: &[Vec3],
    out: &mut Vec<[u32; 3]>,
) {
    let neg: [bool; 4] = std::array::from_fn(|c| vals[p + offs[bits[c]]] < 0.0);
    let n_in = neg.iter().filter(|&&b| b).count();
    if n_in == 0 || n_in == 4 {
        return;
    }
    // Vertex on the edge between tet corners a and b (a path-earlier corner is the lower point).
    let ev = |a: usize, b: usize| -> u32 {
        let (a, b) = if a < b { (a, b) } else { (b, a) };
        let dir = bits[b] & !bits[a];
        edge_vertex[7 * (p + offs[bits[a]]) + dir - 1]
    };
    let corner = |c: usize| {
        let b = bits[c];
        Vec3::new((b & 1) as f32, ((b >> 1) & 1) as f32, (b >> 2) as f32)
    };
    let ins: Vec<usize> = (0..4).filter(|&c| neg[c]).collect();
    let outs: Vec<usize> = (0..4).filter(|&c| !neg[c]).collect();
    // Outward direction: from an inside corner to an outside corner (the gradient of the linear
    // interpolant has a positive component along it).
    let outward = corner(outs[0]) - corner(ins[0]);
    let mut emit_poly = |poly: &[u32]| {
        let q: Vec<Vec3> = poly.iter().map(|&v| positions[v as usize]).collect();
        // Newell normal of the (planar, convex) polygon.
        let mut n = Vec3::ZERO;
        for a in 0..q.len() {
            n += q[a].cross(q[(a + 1) % q.len()]);
        }
        let flip = n.dot(outward) < 0.0;
        for t in 1..poly.len() - 1 {
            let tri = [poly[0], poly[t], poly[t + 1]];
            out.push(if flip { [tri[0], tri[2], tri[1]] } else { tri });
        }
    };
    match n_in {
        1 => emit_poly(&[
            ev(ins[0], outs[0]),
            ev(ins[0], outs[1]),
            ev(ins[0], outs[2]),
        ]),
        3 => emit_poly(&[
            ev(outs[0], ins[0]),
            ev(outs[0], ins[1]),
            ev(outs[0], ins[2]),
        ]),
        _ => emit_poly(&[
            ev(ins[0], outs[0]),
            ev(ins[0], outs[1]),
            ev(ins[1], outs[1]),
            ev(ins[1], outs[0]),
        ]),
    }
}

/// Keep the faces of the largest connected component and drop unreferenced vertices.
pub fn largest_component(positions: Vec<[f32; 3]>, faces: Vec<[u32; 3]>) -> TriMesh {
    let n = positions.len();
    let (labels, _) = crate::mesh::connected_components(n, &faces);
    let mut count = vec![0usize; n];
    for f in &faces {
        count[labels[f[0] as usize] as usize] += 1;
    }
    let best = (0..n)
        .max_by_key(|&l| (count[l], std::cmp::Reverse(l)))
        .unwrap_or(0) as u32;
    let faces: Vec<[u32; 3]> = faces
        .into_iter()
        .filter(|f| labels[f[0] as usize] == best)
        .collect();
    let mut remap = vec![u32::MAX; n];
    let mut kept = Vec::new();
    for f in &faces {
        for &v in f {
            if remap[v as usize] == u32::MAX {
                remap[v as usize] = 0;
            }
        }
    }
    for v in 0..n {
        if remap[v] != u32::MAX {
            remap[v] = kept.len() as u32;
            kept.push(positions[v]);
        }
    }
    let faces = faces
        .into_iter()
        .map(|f| f.map(|v| remap[v as usize]))
        .collect();
    TriMesh::new(kept, faces)
}

/// On-surface relaxation: `iters` rounds of a damped tangential umbrella step
/// (`p += s (I - n n^T)(mean(N(p)) - p)`, Taubin-style Laplacian smoothing restricted to the
/// tangent plane) followed by a Newton projection back onto `f = 0`. Evens out the marching
/// tetrahedra triangles without shrinking the shape; sets `normals` to the normalised gradient.
pub fn relax(mesh: &mut TriMesh, f: &(impl Fn(Vec3) -> f32 + Sync + ?Sized), iters: usize, e: f32) {
    let adj = mesh.adjacency();
    let mut pos: Vec<Vec3> = mesh.positions.iter().map(|&p| Vec3::from(p)).collect();
    let mut next = pos.clone();
    // Unit normals from the gradient, refreshed at each new position.
    let mut nrm: Vec<Vec3> = pos
        .par_iter()
        .map(|&p| gradient(f, p, e).1.normalize_or_zero())
        .collect();
    let mut next_nrm = nrm.clone();
    for _ in 0..iters {
        next.par_iter_mut()
            .zip(next_nrm.par_iter_mut())
            .enumerate()
            .for_each(|(i, (out, out_n))| {
                let p = pos[i];
                let row = adj.row(i);
                if row.is_empty() {
                    *out = p;
                    *out_n = nrm[i];
                    return;
                }
                let mut m = Vec3::ZERO;
                for &j in row {
                    m += pos[j as usize];
                }
                m /= row.len() as f32;
                let n = nrm[i];
                let d = m - p;
                let q = p + 0.5 * (d - n * n.dot(d));
                // One Newton step back to the surface (the tangential step leaves it only
                // slightly).
                let (v, g) = gradient(f, q, e);
                let g2 = g.length_squared();
                *out = if g2 > 1e-12 { q - g * (v / g2) } else { q };
                *out_n = g.normalize_or(n);
            });
        std::mem::swap(&mut pos, &mut next);
        std::mem::swap(&mut nrm, &mut next_nrm);
    }
    // Untangle: Gauss-Seidel umbrella steps on the few triangles that the Jacobi rounds left
    // folded (face normal against its vertex normals) and on their one-rings.
    for _ in 0..30 {
        let mut verts: Vec<u32> = mesh
            .faces
            .par_iter()
            .filter(|f| {
                let [a, b, c] = f.map(|v| pos[v as usize]);
                let vn = nrm[f[0] as usize] + nrm[f[1] as usize] + nrm[f[2] as usize];
                (b - a).cross(c - a).dot(vn) <= 0.0
            })
            .flat_map_iter(|f| {
                f.iter()
                    .flat_map(|&v| std::iter::once(v).chain(adj.row(v as usize).iter().copied()))
                    .collect::<Vec<_>>()
            })
            .collect();
        if verts.is_empty() {
            break;
        }
        verts.sort_unstable();
        verts.dedup();
        for &i in &verts {
            let i = i as usize;
            let row = adj.row(i);
            let mut m = Vec3::ZERO;
            for &j in row {
                m += pos[j as usize];
            }
            m /= row.len().max(1) as f32;
            let n = nrm[i];
            let d = m - pos[i];
            let q = pos[i] + (d - n * n.dot(d));
            let (v, g) = gradient(f, q, e);
            let g2 = g.length_squared();
            pos[i] = if g2 > 1e-12 { q - g * (v / g2) } else { q };
            nrm[i] = g.normalize_or(n);
        }
    }
    let normals: Vec<[f32; 3]> = nrm
        .iter()
        .map(|n| n.normalize_or(Vec3::Y).to_array())
        .collect();
    mesh.positions = pos.iter().map(|p| p.to_array()).collect();
    mesh.normals = Some(normals);
}

/// Signed volume of a closed mesh (divergence theorem); positive for outward orientation.
pub fn signed_volume(mesh: &TriMesh) -> f64 {
    mesh.faces
        .iter()
        .map(|f| {
            let [a, b, c] = f.map(|i| Vec3::from(mesh.positions[i as usize]).as_dvec3());
            a.dot(b.cross(c)) / 6.0
        })
        .sum()
}

/// Deterministic smooth 3D value noise in [-1, 1] (quintic fade, [`value_noise`]).
pub fn noise3(p: Vec3, seed: u32) -> f32 {
    value_noise(p, seed.wrapping_mul(0x1656_67b1), Fade::Quintic)
}
