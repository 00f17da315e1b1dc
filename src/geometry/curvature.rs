//! Per-vertex principal curvatures and directions by tensor averaging (after Rusinkiewicz 2004,
//! "Estimating curvatures and their derivatives on triangle meshes").
//!
//! Per face, the second fundamental form `II = [[a, b], [b, c]]` in the face frame `(u, v)` is the
//! least-squares solution of `II (e·u, e·v) = (Δn·u, Δn·v)` over the three edges `e` (Δn: the
//! difference of the vertex normals along the edge). Each face's tensor `a uu + b (uv + vu) + c vv`
//! is added to its vertices with a third of the face area as weight (projected on the vertex's
//! tangent plane), then diagonalised in the vertex's tangent basis. Signs: with outward normals a
//! convex surface has positive curvature (sphere of radius r: `k_max = k_min = 1/r`).

use glam::{DMat3, DVec3};

use super::basic::{d3, vertex_normals};

/// Principal curvatures per vertex, `k_max >= k_min` (signed), with unit tangent directions.
#[derive(Clone, Debug, Default)]
pub struct PrincipalCurvatures {
    /// Larger principal curvature.
    pub k_max: Vec<f32>,
    /// Smaller principal curvature.
    pub k_min: Vec<f32>,
    /// Direction of `k_max` (unit, tangent; sign arbitrary).
    pub d_max: Vec<[f32; 3]>,
    /// Direction of `k_min` (unit, tangent; sign arbitrary).
    pub d_min: Vec<[f32; 3]>,
    /// The unit vertex normals used.
    pub normals: Vec<[f32; 3]>,
}

/// An orthonormal tangent basis of unit normal `n`.
pub(crate) fn onb(n: DVec3) -> (DVec3, DVec3) {
    let sign = 1.0f64.copysign(n.z);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    let e1 = DVec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
    let e2 = DVec3::new(b, sign + n.y * n.y * a, -n.y);
    (e1, e2)
}

/// Principal curvatures of a triangle mesh (see the module doc). `smooth` extra passes average
/// each vertex tensor with its one-ring (0 = none). Vertices in no face get zeros.
pub fn principal_curvatures(
    positions: &[[f32; 3]],
    faces: &[[u32; 3]],
    smooth: usize,
) -> PrincipalCurvatures {
    let n = positions.len();
    let normals = vertex_normals(positions, faces);
    let mut tens = vec![DMat3::ZERO; n];
    let mut wsum = vec![0.0f64; n];
    for f in faces {
        if f.iter().any(|&v| v as usize >= n) {
            continue;
        }
        let p = f.map(|i| d3(positions[i as usize]));
        let nn = f.map(|i| d3(normals[i as usize]));
        let fnrm = (p[1] - p[0]).cross(p[2] - p[0]);
        let a2 = fnrm.length();
        if !(a2 > 0.0 && a2.is_finite()) {
            continue;
        }
        let nf = fnrm / a2;
        let u = (p[1] - p[0]).normalize();
        let v = nf.cross(u);
        // normal equations of the 6x3 least-squares system
        let mut m = DMat3::ZERO;
        let mut r = DVec3::ZERO;
        for k in 0..3 {
            let (i, j) = ((k + 1) % 3, (k + 2) % 3);
            let e = p[j] - p[i];
            let dn = nn[j] - nn[i];
            let (eu, ev) = (e.dot(u), e.dot(v));
            let (du, dv) = (dn.dot(u), dn.dot(v));
            let r1 = DVec3::new(eu, ev, 0.0);
            let r2 = DVec3::new(0.0, eu, ev);
            m += outer(r1, r1) + outer(r2, r2);
            r += r1 * du + r2 * dv;
        }
        // degenerate relative to the face's size (the same test in any units)
        let size = (m.x_axis.x + m.y_axis.y + m.z_axis.z) / 3.0;
        let det = m.determinant().abs();
        if det.is_nan() || det <= 1e-12 * size * size * size {
            continue;
        }
        let x = m.inverse() * r;
        let t = outer(u, u) * x.x + (outer(u, v) + outer(v, u)) * x.y + outer(v, v) * x.z;
        let w = a2 / 6.0;
        for &vi in f {
            tens[vi as usize] += t * w;
            wsum[vi as usize] += w;
        }
    }
    for (t, &w) in tens.iter_mut().zip(&wsum) {
        if w > 0.0 {
            *t *= 1.0 / w;
        }
    }
    if smooth > 0 {
        let adj = crate::mesh::vertex_adjacency(n, faces);
        for _ in 0..smooth {
            let prev = tens.clone();
            for (i, t) in tens.iter_mut().enumerate() {
                let row = adj.row(i);
                let mut s = prev[i];
                for &j in row {
                    s += prev[j as usize];
                }
                *t = s * (1.0 / (row.len() + 1) as f64);
            }
        }
    }
    let mut out = PrincipalCurvatures {
        k_max: vec![0.0; n],
        k_min: vec![0.0; n],
        d_max: vec![[0.0; 3]; n],
        d_min: vec![[0.0; 3]; n],
        normals: normals.clone(),
    };
    for i in 0..n {
        let nv = d3(normals[i]);
        if nv.length_squared() < 0.5 {
            continue;
        }
        let (e1, e2) = onb(nv);
        let t = tens[i];
        let m11 = e1.dot(t * e1);
        let m22 = e2.dot(t * e2);
        let m12 = 0.5 * (e1.dot(t * e2) + e2.dot(t * e1));
        let mean = 0.5 * (m11 + m22);
        let dif = 0.5 * (m11 - m22);
        let rad = (dif * dif + m12 * m12).sqrt();
        let (k1, k2) = (mean + rad, mean - rad);
        // eigenvector of k1: angle phi with tan 2phi = 2 m12 / (m11 - m22)
        let phi = 0.5 * m12.atan2(dif);
        let dmax = e1 * phi.cos() + e2 * phi.sin();
        let dmin = nv.cross(dmax);
        out.k_max[i] = k1 as f32;
        out.k_min[i] = k2 as f32;
        out.d_max[i] = dmax.as_vec3().to_array();
        out.d_min[i] = dmin.as_vec3().to_array();
    }
    out
}

#[inline]
fn outer(a: DVec3, b: DVec3) -> DMat3 {
    DMat3::from_cols(a * b.x, a * b.y, a * b.z)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// UV sphere of radius `r`, `nu` vertices a ring, `nv` rings of faces.
    fn sphere(r: f32, nu: usize, nv: usize) -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
        let (p, f) = crate::testdata::uv_sphere(nv, nu);
        (p.iter().map(|&v| v.map(|x| r * x)).collect(), f)
    }

    #[test]
    fn sphere_curvature_is_one_over_r() {
        let (pos, faces) = sphere(2.0, 48, 24);
        let pc = principal_curvatures(&pos, &faces, 0);
        // away from the poles' fans of skinny triangles
        for v in (1 + 4 * 48..1 + 19 * 48).step_by(37) {
            assert!((pc.k_max[v] - 0.5).abs() < 0.03, "{}", pc.k_max[v]);
            assert!((pc.k_min[v] - 0.5).abs() < 0.03, "{}", pc.k_min[v]);
        }
    }
}
