//! Sparse evaluation of smooth per-vertex fields: a grid subsample of the vertices, and the
//! interpolation of values known there back to every vertex.
//!
//! Geometric features such as solid-angle curvature at radius `r` or ray-cast occlusion are
//! expensive per vertex and vary on their own scale, not the mesh's: curvature at radius `r`
//! changes over distances of about `r`, and a working mesh refined to 500K points carries no
//! more of it than one sample every `r / 4`. This is the point of the Gaussian pyramid in
//! Mertens et al. 2006 §3.1: each feature is evaluated at the resolution its scale needs.
//!
//! **Samples.** One vertex per occupied grid cell of side `cell` *and* per normal bin (the sign
//! and axis of the normal's largest component, 6 bins), the vertex nearest the cell's centre:
//! the two sides of a part thinner than a cell both get samples of their own.
//!
//! **Interpolation.** A vertex `x` with normal `n` takes a weighted linear fit (moving least
//! squares in its tangent plane, the slopes lightly damped) of the samples `s` in the 27 cells
//! around it, with weights `exp(-|x - s|² / cell²) · max(0, n·n_s)²`: nearby samples facing the
//! same way. When no sample in reach faces its way (a sharp fold narrower
//! than a cell), it takes its nearest sample's value. Every sample vertex keeps its own value
//! exactly.

use glam::Vec3;
use rayon::prelude::*;

use super::IntMap;

/// A grid subsample of a mesh's vertices (see the module doc).
#[derive(Clone, Debug)]
pub struct SparseSamples {
    /// The sampled vertices, ascending.
    pub vertices: Vec<u32>,
    /// Grid cell side in mesh units.
    pub cell: f32,
    /// Positions in `vertices` of the samples in each grid cell.
    grid: IntMap<Vec<u32>>,
}

fn cell_of(p: Vec3, cell: f32) -> [i32; 3] {
    let q = (p / cell).floor();
    [q.x as i32, q.y as i32, q.z as i32]
}

/// 21 bits per coordinate: far cells may share a key, which costs only time (weights and the
/// nearest sample use true distances).
fn key(c: [i32; 3]) -> u64 {
    let m = |x: i32| (x as u32 as u64) & 0x1f_ffff;
    (m(c[0]) << 42) | (m(c[1]) << 21) | m(c[2])
}

fn normal_bin(n: Vec3) -> u8 {
    let a = n.abs();
    let (axis, comp) = if a.x >= a.y && a.x >= a.z {
        (0, n.x)
    } else if a.y >= a.z {
        (1, n.y)
    } else {
        (2, n.z)
    };
    axis * 2 + u8::from(comp < 0.0)
}

/// One vertex per occupied cell of side `cell` and normal bin (module doc). Vertices with a
/// non-finite position are never sampled. A non-positive or non-finite `cell` samples every
/// vertex.
pub fn sparse_samples(positions: &[[f32; 3]], normals: &[[f32; 3]], cell: f32) -> SparseSamples {
    let n = positions.len();
    if !(cell > 0.0 && cell.is_finite()) {
        let vertices: Vec<u32> = (0..n as u32).collect();
        return SparseSamples {
            vertices,
            cell: f32::INFINITY,
            grid: IntMap::default(),
        };
    }
    // per cell, the best vertex of each normal bin
    let mut best: IntMap<[(u32, f32); 6]> = IntMap::default();
    for (v, p) in positions.iter().enumerate() {
        let p = Vec3::from(*p);
        if !p.is_finite() {
            continue;
        }
        let c = cell_of(p, cell);
        let centre = (Vec3::new(c[0] as f32, c[1] as f32, c[2] as f32) + 0.5) * cell;
        let d = p.distance_squared(centre);
        let nb = normal_bin(normals.get(v).map_or(Vec3::Z, |&n| Vec3::from(n)));
        let slot = &mut best.entry(key(c)).or_insert([(u32::MAX, f32::INFINITY); 6])[nb as usize];
        if d < slot.1 {
            *slot = (v as u32, d);
        }
    }
    let mut vertices: Vec<u32> = best
        .values()
        .flatten()
        .filter(|e| e.0 != u32::MAX)
        .map(|e| e.0)
        .collect();
    vertices.sort_unstable();
    let mut grid: IntMap<Vec<u32>> = IntMap::default();
    for (i, &v) in vertices.iter().enumerate() {
        grid.entry(key(cell_of(Vec3::from(positions[v as usize]), cell)))
            .or_default()
            .push(i as u32);
    }
    SparseSamples {
        vertices,
        cell,
        grid,
    }
}

/// [`sparse_samples`], or every vertex when the grid would hold more than half of them (a
/// subsample that small a saving is not worth its interpolation error).
pub fn sparse_samples_if_worth_it(
    positions: &[[f32; 3]],
    normals: &[[f32; 3]],
    cell: f32,
) -> SparseSamples {
    let s = sparse_samples(positions, normals, cell);
    if s.len() * 2 <= positions.len() {
        s
    } else {
        sparse_samples(positions, normals, 0.0)
    }
}

impl SparseSamples {
    /// Number of samples.
    pub fn len(&self) -> usize {
        self.vertices.len()
    }

    /// True when nothing was sampled.
    pub fn is_empty(&self) -> bool {
        self.vertices.is_empty()
    }

    /// Values known at the samples (`len() × dim`, sample-major, in `vertices` order) spread to
    /// every vertex of the mesh: `positions.len() × dim`, vertex-major (module doc).
    pub fn interpolate(
        &self,
        positions: &[[f32; 3]],
        normals: &[[f32; 3]],
        values: &[f32],
        dim: usize,
    ) -> Vec<f32> {
        let n = positions.len();
        let mut out = vec![0.0f32; n * dim];
        if dim == 0 || values.len() < self.len() * dim {
            return out;
        }
        if self.grid.is_empty() {
            // every vertex is a sample
            for (i, &v) in self.vertices.iter().enumerate() {
                out[v as usize * dim..(v as usize + 1) * dim]
                    .copy_from_slice(&values[i * dim..(i + 1) * dim]);
            }
            return out;
        }
        let inv = 1.0 / (self.cell * self.cell);
        let nrm = |v: usize| normals.get(v).map_or(Vec3::ZERO, |&n| Vec3::from(n));
        out.par_chunks_mut(dim).enumerate().for_each_init(
            || vec![0.0f32; 2 * dim],
            |first, (v, o)| {
                let p = Vec3::from(positions[v]);
                if !p.is_finite() {
                    return;
                }
                let nv = nrm(v);
                let (tu, tv) = nv.any_orthonormal_pair();
                first.fill(0.0);
                // weighted moments of the tangent offsets (x, y): w, x, y, xx, xy, yy
                let mut m = [0.0f32; 6];
                let mut nearest = (u32::MAX, f32::INFINITY);
                let c = cell_of(p, self.cell);
                for dz in -1..=1 {
                    for dy in -1..=1 {
                        for dx in -1..=1 {
                            let Some(list) = self.grid.get(&key([c[0] + dx, c[1] + dy, c[2] + dz]))
                            else {
                                continue;
                            };
                            for &i in list {
                                let s = self.vertices[i as usize] as usize;
                                let d = Vec3::from(positions[s]) - p;
                                let d2 = d.length_squared();
                                if d2 < nearest.1 {
                                    nearest = (i, d2);
                                }
                                let facing = nv.dot(nrm(s)).max(0.0);
                                let w = (-d2 * inv).exp() * facing * facing;
                                if w <= 1e-12 {
                                    continue;
                                }
                                let (x, y) = (d.dot(tu) / self.cell, d.dot(tv) / self.cell);
                                m[0] += w;
                                m[1] += w * x;
                                m[2] += w * y;
                                m[3] += w * x * x;
                                m[4] += w * x * y;
                                m[5] += w * y * y;
                                let row = &values[i as usize * dim..(i as usize + 1) * dim];
                                for (k, &f) in row.iter().enumerate() {
                                    o[k] += w * f;
                                    first[k] += w * x * f;
                                    first[dim + k] += w * y * f;
                                }
                            }
                        }
                    }
                }
                if m[0] <= 1e-12 {
                    if nearest.0 != u32::MAX {
                        let i = nearest.0 as usize;
                        o.copy_from_slice(&values[i * dim..(i + 1) * dim]);
                    }
                    return;
                }
                // a local linear fit f ≈ a + b x + c y (moving least squares), a = the value at
                // the vertex: no one-sided bias at boundaries and where samples are uneven. The
                // slope terms are damped (ridge) so that a one-sided or collinear neighbourhood
                // falls back towards the weighted mean.
                let ridge = 0.05 * m[0];
                let (w, sx, sy) = (m[0], m[1], m[2]);
                let (sxx, sxy, syy) = (m[3] + ridge, m[4], m[5] + ridge);
                let det = w * (sxx * syy - sxy * sxy) - sx * (sx * syy - sxy * sy)
                    + sy * (sx * sxy - sxx * sy);
                if det.abs() > 1e-9 * w * w * w {
                    // first row of the inverse of the symmetric 3×3 moment matrix
                    let i0 = (sxx * syy - sxy * sxy) / det;
                    let i1 = (sy * sxy - sx * syy) / det;
                    let i2 = (sx * sxy - sy * sxx) / det;
                    for k in 0..dim {
                        o[k] = i0 * o[k] + i1 * first[k] + i2 * first[dim + k];
                    }
                } else {
                    for a in o.iter_mut() {
                        *a /= w;
                    }
                }
            },
        );
        // samples keep their own values exactly
        for (i, &v) in self.vertices.iter().enumerate() {
            out[v as usize * dim..(v as usize + 1) * dim]
                .copy_from_slice(&values[i * dim..(i + 1) * dim]);
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid_plane(k: usize) -> (Vec<[f32; 3]>, Vec<[f32; 3]>) {
        let mut p = Vec::new();
        for j in 0..k {
            for i in 0..k {
                p.push([i as f32 / (k - 1) as f32, j as f32 / (k - 1) as f32, 0.0]);
            }
        }
        let n = vec![[0.0, 0.0, 1.0]; p.len()];
        (p, n)
    }

    #[test]
    fn a_smooth_field_comes_back_from_a_sparse_sample() {
        let (p, n) = grid_plane(200);
        let f = |q: [f32; 3]| (3.0 * q[0]).sin() + q[1] * q[1];
        let s = sparse_samples(&p, &n, 0.04);
        assert!(s.len() < p.len() / 50, "{} samples", s.len());
        let vals: Vec<f32> = s.vertices.iter().map(|&v| f(p[v as usize])).collect();
        let out = s.interpolate(&p, &n, &vals, 1);
        let (mut inner, mut border) = (0.0f32, 0.0f32);
        for (q, o) in p.iter().zip(&out) {
            let e = (f(*q) - o).abs();
            let edge = q[0].min(q[1]).min(1.0 - q[0]).min(1.0 - q[1]) < 0.04;
            if edge {
                border = border.max(e);
            } else {
                inner = inner.max(e);
            }
        }
        // a local linear fit of samples a cell apart: second-order error on a field of
        // curvature up to 9 inside; at the border (one-sided neighbourhoods) the damped slope
        // leaves a first-order remainder
        assert!(inner < 0.01, "max error inside {inner}");
        assert!(border < 0.03, "max error at the border {border}");
    }

    #[test]
    fn the_two_sides_of_a_thin_plate_keep_their_own_values() {
        // two parallel planes 0.001 apart with opposite normals, in one layer of cells
        let (mut p, mut n) = grid_plane(60);
        let m = p.len();
        for i in 0..m {
            p.push([p[i][0], p[i][1], 0.001]);
            n.push([0.0, 0.0, -1.0]);
        }
        let s = sparse_samples(&p, &n, 0.1);
        let vals: Vec<f32> = s
            .vertices
            .iter()
            .map(|&v| if (v as usize) < m { 1.0 } else { -1.0 })
            .collect();
        let out = s.interpolate(&p, &n, &vals, 1);
        assert!(out[..m].iter().all(|&x| (x - 1.0).abs() < 1e-5));
        assert!(out[m..].iter().all(|&x| (x + 1.0).abs() < 1e-5));
    }
}
