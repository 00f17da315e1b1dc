//! Cotangent Laplacian and lumped mass matrices (Pinkall & Polthier 1993; Meyer et al. 2003).

use faer::sparse::{SparseColMat, SymbolicSparseColMat, Triplet};
use glam::DVec3;

use super::basic::d3;
use crate::error::{Error, Result};

/// Cotangent of the angle between `a` and `b`: `cot θ = (a·b) / |a × b|` (0 when degenerate).
#[inline]
pub(crate) fn cot(a: DVec3, b: DVec3) -> f64 {
    let s = a.cross(b).length();
    if s > 0.0 && s.is_finite() {
        a.dot(b) / s
    } else {
        0.0
    }
}

/// The cotangent weights of one face: `w[k] = cot(angle at corner k) / 2`, the weight of the
/// edge opposite corner k.
#[inline]
pub(crate) fn face_cot_weights(p: [DVec3; 3]) -> [f64; 3] {
    let mut w = [0.0; 3];
    for k in 0..3 {
        let (i, j, l) = (p[k], p[(k + 1) % 3], p[(k + 2) % 3]);
        w[k] = 0.5 * cot(j - i, l - i);
    }
    w
}

/// The cotangent triplets of `L` (diagonal entries per face, duplicates summed by faer).
pub(crate) fn cotan_triplets(
    positions: &[[f32; 3]],
    faces: &[[u32; 3]],
    scale: f64,
    out: &mut Vec<Triplet<usize, usize, f64>>,
) {
    for f in faces {
        let p = f.map(|i| d3(positions[i as usize]));
        let w = face_cot_weights(p);
        for k in 0..3 {
            let (j, l) = (f[(k + 1) % 3] as usize, f[(k + 2) % 3] as usize);
            let wk = w[k] * scale;
            out.push(Triplet::new(j, l, -wk));
            out.push(Triplet::new(l, j, -wk));
            out.push(Triplet::new(j, j, wk));
            out.push(Triplet::new(l, l, wk));
        }
    }
}

/// Check that every face index is in range.
pub(crate) fn check_faces(n: usize, faces: &[[u32; 3]]) -> Result<()> {
    if let Some(f) = faces.iter().find(|f| f.iter().any(|&v| v as usize >= n)) {
        return Err(Error::InvalidInput(format!(
            "face {f:?} references a vertex beyond the {n} positions"
        )));
    }
    Ok(())
}

/// The sparsity pattern of a mesh Laplacian: vertex adjacency plus the diagonal, in compressed
/// sparse column form with sorted row indices (symmetric, so it is also the CSR form).
pub(crate) struct LaplacePattern {
    pub n: usize,
    pub col_ptr: Vec<usize>,
    pub row_idx: Vec<usize>,
    /// Position of the diagonal entry of each column in `row_idx`.
    pub diag: Vec<usize>,
}

impl LaplacePattern {
    /// The pattern of the faces' edges (faces must index into `0..n`).
    pub fn new(n: usize, faces: &[[u32; 3]]) -> Self {
        let adj = crate::mesh::vertex_adjacency(n, faces);
        let mut col_ptr = Vec::with_capacity(n + 1);
        let mut row_idx = Vec::with_capacity(adj.indices.len() + n);
        let mut diag = Vec::with_capacity(n);
        col_ptr.push(0);
        for i in 0..n {
            let row = adj.row(i);
            let split = row.partition_point(|&j| (j as usize) < i);
            row_idx.extend(row[..split].iter().map(|&j| j as usize));
            diag.push(row_idx.len());
            row_idx.push(i);
            row_idx.extend(row[split..].iter().map(|&j| j as usize));
            col_ptr.push(row_idx.len());
        }
        LaplacePattern {
            n,
            col_ptr,
            row_idx,
            diag,
        }
    }

    /// Index of entry (row, col) in the value array.
    #[inline]
    fn find(&self, row: usize, col: usize) -> usize {
        let (s, e) = (self.col_ptr[col], self.col_ptr[col + 1]);
        s + self.row_idx[s..e].partition_point(|&r| r < row)
    }

    /// The cotan stiffness values on this pattern (see [`cotan_laplacian`]).
    pub fn cotan_values(&self, positions: &[[f32; 3]], faces: &[[u32; 3]]) -> Vec<f64> {
        let mut val = vec![0.0; self.row_idx.len()];
        for f in faces {
            let p = f.map(|i| d3(positions[i as usize]));
            let w = face_cot_weights(p);
            for k in 0..3 {
                let (j, l) = (f[(k + 1) % 3] as usize, f[(k + 2) % 3] as usize);
                if j == l || w[k] == 0.0 {
                    continue;
                }
                val[self.find(l, j)] -= w[k];
                val[self.find(j, l)] -= w[k];
                val[self.diag[j]] += w[k];
                val[self.diag[l]] += w[k];
            }
        }
        val
    }

    /// A sparse matrix with this pattern and the given values.
    pub fn matrix(&self, val: Vec<f64>) -> SparseColMat<usize, f64> {
        let sym = SymbolicSparseColMat::new_checked(
            self.n,
            self.n,
            self.col_ptr.clone(),
            None,
            self.row_idx.clone(),
        );
        SparseColMat::new(sym, val)
    }
}

/// Positive semi-definite cotangent stiffness matrix (Pinkall & Polthier 1993):
/// `L_ij = -(cot α_ij + cot β_ij) / 2` for an edge ij with opposite angles α, β, and
/// `L_ii = -sum_j L_ij` — i.e. `L = -cotmatrix` of libigl. Degenerate faces contribute nothing;
/// every edge and diagonal entry is stored (possibly as an explicit zero).
///
/// Faces must index into `positions` (out-of-range faces are skipped).
pub fn cotan_laplacian(positions: &[[f32; 3]], faces: &[[u32; 3]]) -> SparseColMat<usize, f64> {
    let n = positions.len();
    let valid: Vec<[u32; 3]> = faces
        .iter()
        .copied()
        .filter(|f| f.iter().all(|&v| (v as usize) < n))
        .collect();
    let pat = LaplacePattern::new(n, &valid);
    let val = pat.cotan_values(positions, &valid);
    pat.matrix(val)
}

/// Diagonal mixed-Voronoi mass (Meyer, Desbrun, Schröder & Barr 2003, Fig. 4): for a non-obtuse
/// triangle, vertex i receives its Voronoi area `(|e_ij|² cot θ_k + |e_ik|² cot θ_j) / 8`; for an
/// obtuse triangle the obtuse vertex receives `A/2` and the others `A/4` (libigl
/// `MASSMATRIX_TYPE_VORONOI`).
pub fn mass_matrix_voronoi(positions: &[[f32; 3]], faces: &[[u32; 3]]) -> Vec<f64> {
    let n = positions.len();
    let mut m = vec![0.0; n];
    for f in faces {
        if f.iter().any(|&v| v as usize >= n) {
            continue;
        }
        let p = f.map(|i| d3(positions[i as usize]));
        let area = 0.5 * (p[1] - p[0]).cross(p[2] - p[0]).length();
        if !(area > 0.0 && area.is_finite()) {
            continue;
        }
        // cosine sign at each corner decides obtuseness
        let obtuse = (0..3).find(|&k| {
            let (i, j, l) = (p[k], p[(k + 1) % 3], p[(k + 2) % 3]);
            (j - i).dot(l - i) < 0.0
        });
        match obtuse {
            Some(k) => {
                for c in 0..3 {
                    m[f[c] as usize] += if c == k { area / 2.0 } else { area / 4.0 };
                }
            }
            None => {
                for k in 0..3 {
                    let (i, j, l) = (p[k], p[(k + 1) % 3], p[(k + 2) % 3]);
                    let cot_j = cot(i - j, l - j);
                    let cot_l = cot(i - l, j - l);
                    m[f[k] as usize] +=
                        ((i - j).length_squared() * cot_l + (i - l).length_squared() * cot_j) / 8.0;
                }
            }
        }
    }
    m
}

/// Diagonal barycentric mass: each vertex receives a third of the area of each incident face.
pub fn mass_matrix_barycentric(positions: &[[f32; 3]], faces: &[[u32; 3]]) -> Vec<f64> {
    let n = positions.len();
    let mut m = vec![0.0; n];
    for f in faces {
        if f.iter().any(|&v| v as usize >= n) {
            continue;
        }
        let p = f.map(|i| d3(positions[i as usize]));
        let area = 0.5 * (p[1] - p[0]).cross(p[2] - p[0]).length();
        if area.is_finite() {
            for &v in f {
                m[v as usize] += area / 3.0;
            }
        }
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn laplacian_rows_sum_to_zero_and_mass_sums_to_area() {
        // regular tetrahedron-ish + one obtuse triangle fan
        let pos = vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
            [3.0, 0.2, 0.0],
        ];
        let faces = vec![[0, 2, 1], [0, 1, 3], [1, 2, 3], [2, 0, 3], [1, 4, 2]];
        let l = cotan_laplacian(&pos, &faces);
        let d = l.to_dense();
        for i in 0..5 {
            let s: f64 = (0..5).map(|j| d[(i, j)]).sum();
            assert!(s.abs() < 1e-12);
            assert!(d[(i, i)] >= 0.0);
            for j in 0..5 {
                assert!((d[(i, j)] - d[(j, i)]).abs() < 1e-12);
            }
        }
        let area: f64 = super::super::face_areas(&pos, &faces).iter().sum();
        let mv: f64 = mass_matrix_voronoi(&pos, &faces).iter().sum();
        let mb: f64 = mass_matrix_barycentric(&pos, &faces).iter().sum();
        assert!((mv - area).abs() < 1e-9 && (mb - area).abs() < 1e-9);
        // right isoceles triangle: the right angle is not obtuse, Voronoi areas are 1/4,1/8,1/8
        let m = mass_matrix_voronoi(&pos[..3], &[[0, 1, 2]]);
        assert!((m[0] - 0.25).abs() < 1e-12 && (m[1] - 0.125).abs() < 1e-12);
    }
}
