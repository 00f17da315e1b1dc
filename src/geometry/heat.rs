//! Heat-method geodesic distance (Crane, Weischedel & Wardetzky 2013).

use faer::linalg::solvers::Solve;
use faer::sparse::linalg::solvers::{Llt, SymbolicLlt};
use faer::{MatMut, Side};
use glam::DVec3;
use rayon::prelude::*;

use super::basic::{d3, mean_edge_length};
use super::laplacian::{LaplacePattern, check_faces, mass_matrix_voronoi};
use crate::error::{Error, Result};

/// Geodesic distances by the heat method, prepared once per mesh and reusable for any number of
/// source sets (queries take `&self`, so they can run in parallel).
///
/// Crane et al. 2013, Algorithm 1: (I) integrate the heat flow `(M + tL) u = δ_γ` for one
/// backward-Euler step with `t = h²` (h = mean edge length); (II) evaluate the normalised field
/// `X = -∇u / |∇u|` per face; (III) solve the Poisson equation `L φ = ∇·X` (weak form:
/// `b_i = Σ_f A_f X_f · ∇ψ_i`). `L` is the cotan stiffness, `M` the mixed-Voronoi mass; both
/// sparse Cholesky factorisations (of `M + tL` and of `L + εM`, ε = 10⁻¹⁰ tr L / tr M, which fixes
/// the free constant) are computed here, sharing one symbolic analysis.
pub struct HeatGeodesics {
    n: usize,
    faces: Vec<[u32; 3]>,
    /// Per face: area and the gradients of the three hat functions, `∇ψ_k = N × e_k / (2A)`.
    grads: Vec<(f64, [DVec3; 3])>,
    heat: Llt<usize, f64>,
    poisson: Llt<usize, f64>,
    label: Vec<u32>,
    ncomp: usize,
    active: Vec<bool>,
    t: f64,
}

impl HeatGeodesics {
    /// Build the operators and factorise them (one symbolic analysis, two numeric Cholesky
    /// factorisations).
    pub fn new(positions: &[[f32; 3]], faces: &[[u32; 3]]) -> Result<Self> {
        let n = positions.len();
        check_faces(n, faces)?;
        if faces.is_empty() {
            return Err(Error::InvalidMesh(
                "heat geodesics need a mesh with faces".into(),
            ));
        }
        let faces: Vec<[u32; 3]> = faces
            .iter()
            .copied()
            .filter(|f| {
                let [a, b, c] = f.map(|i| d3(positions[i as usize]));
                let area = (b - a).cross(c - a).length();
                area > 0.0 && area.is_finite()
            })
            .collect();
        if faces.is_empty() {
            return Err(Error::InvalidMesh("every face is degenerate".into()));
        }
        let mass = mass_matrix_voronoi(positions, &faces);
        let active: Vec<bool> = mass.iter().map(|&m| m > 0.0).collect();
        let h = mean_edge_length(positions, &faces) as f64;
        let t = h * h;
        let grads = faces
            .par_iter()
            .map(|f| {
                let p = f.map(|i| d3(positions[i as usize]));
                let nrm = (p[1] - p[0]).cross(p[2] - p[0]);
                let a2 = nrm.length();
                let nu = nrm / a2;
                let mut g = [DVec3::ZERO; 3];
                for k in 0..3 {
                    // edge opposite corner k, counter-clockwise
                    let e = p[(k + 2) % 3] - p[(k + 1) % 3];
                    g[k] = nu.cross(e) / a2;
                }
                (0.5 * a2, g)
            })
            .collect();
        let pat = LaplacePattern::new(n, &faces);
        let lval = pat.cotan_values(positions, &faces);
        let trace_l: f64 = pat.diag.iter().map(|&d| lval[d]).sum();
        let trace_m: f64 = mass.iter().sum();
        let eps = 1e-10 * trace_l / trace_m;
        let build = |lscale: f64, mscale: f64| {
            let mut val: Vec<f64> = lval.iter().map(|&x| x * lscale).collect();
            for (i, &m) in mass.iter().enumerate() {
                // vertices in no face keep an identity row so the system stays definite
                val[pat.diag[i]] += if m > 0.0 { m * mscale } else { 1.0 };
            }
            pat.matrix(val)
        };
        let heat_mat = build(t, 1.0);
        let poisson_mat = build(1.0, eps);
        let sym = SymbolicLlt::try_new(heat_mat.symbolic(), Side::Lower)
            .map_err(|e| Error::InvalidMesh(format!("symbolic Cholesky failed: {e:?}")))?;
        // the two numeric factorisations are independent
        let (heat, poisson) = rayon::join(
            || Llt::try_new_with_symbolic(sym.clone(), heat_mat.as_ref(), Side::Lower),
            || Llt::try_new_with_symbolic(sym.clone(), poisson_mat.as_ref(), Side::Lower),
        );
        let heat =
            heat.map_err(|e| Error::InvalidMesh(format!("Cholesky of M + tL failed: {e:?}")))?;
        let poisson =
            poisson.map_err(|e| Error::InvalidMesh(format!("Cholesky of L + εM failed: {e:?}")))?;
        let (label, ncomp) = crate::mesh::connected_components(n, &faces);
        let ncomp = ncomp.max(label.iter().map(|&l| l as usize + 1).max().unwrap_or(0));
        Ok(HeatGeodesics {
            n,
            faces,
            grads,
            heat,
            poisson,
            label,
            ncomp,
            active,
            t,
        })
    }

    /// Number of vertices.
    pub fn num_vertices(&self) -> usize {
        self.n
    }

    /// The diffusion time `t = h²` used in step (I).
    pub fn time(&self) -> f64 {
        self.t
    }

    /// [`HeatGeodesics::distance`] for many source sets at once, in parallel.
    pub fn distances(&self, source_sets: &[Vec<u32>]) -> Vec<Vec<f64>> {
        source_sets.par_iter().map(|s| self.distance(s)).collect()
    }

    /// Distance from every vertex to the nearest of `sources`, shifted per connected component
    /// so that the smallest value over the component's sources is 0. Vertices in components
    /// without a source (or in no face) get `f64::INFINITY`; out-of-range sources are ignored.
    pub fn distance(&self, sources: &[u32]) -> Vec<f64> {
        let n = self.n;
        let mut out = vec![f64::INFINITY; n];
        let valid: Vec<usize> = sources
            .iter()
            .map(|&s| s as usize)
            .filter(|&s| s < n)
            .collect();
        if valid.is_empty() {
            return out;
        }
        // (I) heat flow
        let mut u = vec![0.0; n];
        for &s in &valid {
            u[s] = 1.0;
        }
        self.heat
            .solve_in_place(MatMut::from_column_major_slice_mut(&mut u, n, 1));
        // (II)+(III) normalised gradient, integrated divergence
        let mut b = vec![0.0; n];
        for (f, (area, g)) in self.faces.iter().zip(&self.grads) {
            let grad = g[0] * u[f[0] as usize] + g[1] * u[f[1] as usize] + g[2] * u[f[2] as usize];
            let len = grad.length();
            if !(len > 0.0 && len.is_finite()) {
                continue;
            }
            let x = -grad / len;
            for k in 0..3 {
                b[f[k] as usize] += area * x.dot(g[k]);
            }
        }
        self.poisson
            .solve_in_place(MatMut::from_column_major_slice_mut(&mut b, n, 1));
        // shift per component
        let mut shift = vec![f64::INFINITY; self.ncomp];
        for &s in &valid {
            let c = self.label[s] as usize;
            if self.active[s] {
                shift[c] = shift[c].min(b[s]);
            }
        }
        for v in 0..n {
            let c = self.label[v] as usize;
            if self.active[v] && shift[c].is_finite() {
                out[v] = b[v] - shift[c];
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plane_distances_are_euclidean() {
        // 41x41 grid on [-1,1]^2, distances from the centre
        let m = 41;
        let mut pos = Vec::new();
        for y in 0..m {
            for x in 0..m {
                let s = 2.0 / (m - 1) as f32;
                pos.push([x as f32 * s - 1.0, y as f32 * s - 1.0, 0.0]);
            }
        }
        let mut faces = Vec::new();
        for y in 0..m as u32 - 1 {
            for x in 0..m as u32 - 1 {
                let i = y * m as u32 + x;
                faces.push([i, i + 1, i + m as u32 + 1]);
                faces.push([i, i + m as u32 + 1, i + m as u32]);
            }
        }
        let hg = HeatGeodesics::new(&pos, &faces).unwrap();
        let c = (m * m / 2) as u32;
        let d = hg.distance(&[c]);
        assert_eq!(d[c as usize], 0.0);
        for v in [0usize, 20, 400, 1000, 1680] {
            let p = pos[v];
            let e = ((p[0] * p[0] + p[1] * p[1]) as f64).sqrt();
            assert!((d[v] - e).abs() < 0.06 * e.max(0.1), "{v}: {} vs {e}", d[v]);
        }
        // two sources: distance to the nearest
        let d2 = hg.distance(&[0, (m * m - 1) as u32]);
        assert!(d2[0].abs() < 1e-3 && d2[m * m - 1].abs() < 1e-3);
        assert!(
            (d2[c as usize] - 2f64.sqrt()).abs() < 0.1,
            "{}",
            d2[c as usize]
        );
        assert!(hg.distance(&[]).iter().all(|x| x.is_infinite()));

        // a second, disjoint copy: unreachable from a source in the first
        let nv = pos.len() as u32;
        let mut pos2 = pos.clone();
        pos2.extend(pos.iter().map(|p| [p[0] + 5.0, p[1], p[2]]));
        let mut faces2 = faces.clone();
        faces2.extend(faces.iter().map(|f| f.map(|v| v + nv)));
        let hg2 = HeatGeodesics::new(&pos2, &faces2).unwrap();
        let d3 = hg2.distance(&[c, nv + c, 10 * nv]);
        assert!(
            d3[..nv as usize]
                .iter()
                .zip(&d)
                .all(|(a, b)| (a - b).abs() < 1e-6)
        );
        assert!(
            d3[nv as usize..]
                .iter()
                .zip(&d)
                .all(|(a, b)| (a - b).abs() < 1e-6)
        );
        let batch = hg2.distances(&[vec![c], vec![c, nv + c, 10 * nv]]);
        let close =
            |a: &[f64], b: &[f64]| a.iter().zip(b).all(|(x, y)| x == y || (x - y).abs() < 1e-9);
        assert!(close(&batch[1], &d3));
        let d4 = hg2.distance(&[c]);
        assert!(close(&batch[0], &d4));
        assert!(d4[nv as usize..].iter().all(|x| x.is_infinite()));
        assert!(HeatGeodesics::new(&pos, &[[0, 1, 99_999]]).is_err());
    }
}
