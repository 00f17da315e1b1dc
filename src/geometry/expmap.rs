//! Discrete exponential map of a geodesic disc (Schmidt, Grimm & Wyvill 2006, "Interactive
//! decal compositing with discrete exponential maps", single-parent variant): local 2D
//! coordinates around a seed point, used by mesh quilting to flatten a patch of the base.
//!
//! Dijkstra over the edge graph from the seed (the seed's face corners start at their Euclidean
//! distance from the seed point) grows the disc; a vertex `q` reached through parent `p` gets
//! `uv_q = uv_p + (t·e1_p, t·e2_p)`, where `t` is the edge `q - p` projected onto `p`'s tangent
//! plane and rescaled to the edge length, and `(e1_p, e2_p)` is the seed frame carried to `p` by
//! the minimal rotations between consecutive normals along the Dijkstra tree (discrete parallel
//! transport). On a developable surface this is an isometric unfolding of the disc.

use std::cmp::Reverse;
use std::collections::BinaryHeap;

use glam::Vec3;

use crate::mesh::Csr;

/// The flattened disc: reached vertices in Dijkstra order with their 2D coordinates.
#[derive(Clone, Debug, Default)]
pub struct ExpMap {
    /// Reached vertices, in order of graph distance from the seed.
    pub vertices: Vec<u32>,
    /// 2D coordinates, parallel to `vertices`.
    pub uv: Vec<[f32; 2]>,
    /// Graph distance from the seed point, parallel to `vertices`.
    pub dist: Vec<f32>,
}

/// Rotate `v` by the minimal rotation taking unit `from` onto unit `to` (Rodrigues).
fn rotate_onto(from: Vec3, to: Vec3, v: Vec3) -> Vec3 {
    let cos = from.dot(to);
    if 1.0 + cos < 1e-6 {
        return v - 2.0 * from * from.dot(v);
    }
    let c = from.cross(to);
    cos * v + c.cross(v) + c * (c.dot(v) / (1.0 + cos))
}

/// Frame direction `e1` made tangent to unit `n` (Gram-Schmidt), with a fallback when `e1` is
/// (nearly) parallel to `n`.
pub fn tangent_direction(n: Vec3, e1: Vec3) -> Vec3 {
    let t = e1 - n * n.dot(e1);
    if t.length_squared() > 1e-12 {
        t.normalize()
    } else {
        n.any_orthonormal_vector()
    }
}

/// Where a disc starts: a point on a face, the face's unit normal, and the direction that
/// becomes +u.
#[derive(Clone, Copy, Debug)]
pub struct DiscSeed {
    /// The corners of the face holding `point`.
    pub face: [u32; 3],
    /// The seed point.
    pub point: [f32; 3],
    /// Unit normal at the seed.
    pub normal: [f32; 3],
    /// The +u direction (made tangent).
    pub e1: [f32; 3],
}

/// Flatten the geodesic disc of graph radius `radius` around `seed.point`; `seed.e1` (made
/// tangent) becomes the +u axis. `normals` are unit vertex normals, `adjacency` the vertex
/// adjacency (CSR).
pub fn exp_map(
    positions: &[[f32; 3]],
    normals: &[[f32; 3]],
    adjacency: &Csr,
    seed: &DiscSeed,
    radius: f32,
) -> ExpMap {
    let (seed_face, seed_point, seed_normal, e1) = (seed.face, seed.point, seed.normal, seed.e1);
    let n = positions.len();
    let p0 = Vec3::from(seed_point);
    let n0 = Vec3::from(seed_normal).normalize_or(Vec3::Z);
    let e10 = tangent_direction(n0, Vec3::from(e1));
    let mut dist = vec![f32::INFINITY; n];
    let mut parent = vec![u32::MAX; n];
    let mut done = vec![false; n];
    let mut heap: BinaryHeap<Reverse<(u32, u32)>> = BinaryHeap::new();
    for &v in &seed_face {
        let d = Vec3::from(positions[v as usize]).distance(p0);
        if d < dist[v as usize] {
            dist[v as usize] = d;
            heap.push(Reverse((d.to_bits(), v)));
        }
    }
    let mut out = ExpMap::default();
    let mut frame: Vec<(u32, Vec3, [f32; 2])> = Vec::new(); // (vertex, e1, uv) per done vertex
    let mut slot: std::collections::HashMap<u32, usize> = std::collections::HashMap::new();
    while let Some(Reverse((dbits, v))) = heap.pop() {
        let vi = v as usize;
        if done[vi] {
            continue;
        }
        let d = f32::from_bits(dbits);
        if d > radius {
            break;
        }
        done[vi] = true;
        let pv = Vec3::from(positions[vi]);
        let nv = Vec3::from(normals[vi]).normalize_or(n0);
        let (uv, e1v) = if parent[vi] == u32::MAX {
            let e2 = n0.cross(e10);
            let dv = pv - p0;
            let t = dv - n0 * n0.dot(dv);
            let t = if t.length_squared() > 1e-20 {
                t * (dv.length() / t.length())
            } else {
                t
            };
            let e = tangent_direction(nv, rotate_onto(n0, nv, e10));
            ([t.dot(e10), t.dot(e2)], e)
        } else {
            let p = parent[vi] as usize;
            let (_, e1p, uvp) = frame[slot[&(p as u32)]];
            let np = Vec3::from(normals[p]).normalize_or(n0);
            let e2p = np.cross(e1p);
            let dv = pv - Vec3::from(positions[p]);
            let t = dv - np * np.dot(dv);
            let t = if t.length_squared() > 1e-20 {
                t * (dv.length() / t.length())
            } else {
                t
            };
            let e = tangent_direction(nv, rotate_onto(np, nv, e1p));
            ([uvp[0] + t.dot(e1p), uvp[1] + t.dot(e2p)], e)
        };
        slot.insert(v, frame.len());
        frame.push((v, e1v, uv));
        out.vertices.push(v);
        out.uv.push(uv);
        out.dist.push(d);
        for &w in adjacency.row(vi) {
            let wi = w as usize;
            if done[wi] {
                continue;
            }
            let nd = d + pv.distance(Vec3::from(positions[wi]));
            if nd < dist[wi] {
                dist[wi] = nd;
                parent[wi] = v;
                heap.push(Reverse((nd.to_bits(), w)));
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::vertex_adjacency;

    #[test]
    fn plane_is_unfolded_isometrically() {
        let m = 12;
        let (pos, faces) = crate::testdata::grid_cells(m, m, 0.1);
        let nrm = vec![[0.0, 0.0, 1.0]; pos.len()];
        let adj = vertex_adjacency(pos.len(), &faces);
        let f = faces[2 * (6 * m + 6)];
        let c = [0.63, 0.61, 0.0];
        let seed = DiscSeed {
            face: f,
            point: c,
            normal: [0.0, 0.0, 1.0],
            e1: [1.0, 0.0, 0.0],
        };
        let e = exp_map(&pos, &nrm, &adj, &seed, 0.4);
        assert!(e.vertices.len() > 20);
        for (k, &v) in e.vertices.iter().enumerate() {
            let p = pos[v as usize];
            assert!((e.uv[k][0] - (p[0] - c[0])).abs() < 1e-4);
            assert!((e.uv[k][1] - (p[1] - c[1])).abs() < 1e-4);
        }
    }
}
