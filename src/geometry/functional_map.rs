//! Global intrinsic shape map: functional maps (Ovsjanikov et al. 2012, "Functional maps: a
//! flexible representation of maps between shapes") refined by ZoomOut (Melzi et al. 2019,
//! "ZoomOut: spectral upsampling for efficient shape correspondence").
//!
//! Notation. `Φ_s` (`n_s × k`) and `Φ_t` (`n_t × k`) are the smallest Laplacian eigenvectors of the
//! source and target, M-orthonormal on the unit-area rescaled surfaces (`Φᵀ M Φ = I`). A point map
//! `T: target → source` pulls a source function back, `f ∘ T`; its functional map is the
//! `k × k` matrix
//!
//! ```text
//! C = Φ_tᵀ M_t Π Φ_s,        Π Φ_s ≈ Φ_t C      (Π: n_t × n_s, Π[t, T(t)] = 1)
//! ```
//!
//! so the coefficients of a source function `a` become `C a` on the target.
//!
//! 1. **Descriptors.** Wave kernel signature (Aubry et al. 2011) at `descriptors` log-energies,
//!    `WKS(x, e) = Σ_i φ_i(x)² g_e(λ_i) / Σ_i g_e(λ_i)`, `g_e(λ) = exp(-(e - ln λ)² / 2σ²)`, and
//!    for every landmark pair `(s_j, t_j)` the landmark wave kernels
//!    `Σ_i φ_i(x) φ_i(s_j) g_e(λ_i)` at a few energies; the heat kernel signature (Sun et al.
//!    2009) `HKS(x, t) = Σ_i exp(-λ_i t) φ_i(x)²` at `hks` times log-spaced over
//!    `[4 ln 10 / λ_max, 4 ln 10 / λ_1]` adds the coarse, diffusion-scale part. Each descriptor is
//!    scaled to unit M-norm.
//! 2. **Initial map.** With `A = Φ_sᵀ M_s F_s`, `B = Φ_tᵀ M_t F_t` (`k0 × d`):
//!    `min_C ‖C A − B‖² + μ Σ_ij C_ij² (λ^t_i − λ^s_j)²` (descriptor preservation + Laplacian
//!    commutativity, the squared eigenvalue differences normalised to unit Frobenius norm). The
//!    problem separates by rows of `C`: `(A Aᵀ + μ diag(D_i)) c_i = A b_i`.
//! 3. **ZoomOut.** For `k = k0, k0 + step, …, k_final`: the point map takes every target vertex
//!    to the source vertex whose row of `Φ_s[:, :k] Cᵀ` is nearest to its row of `Φ_t[:, :k]`
//!    (Melzi et al. eq. 3), then
//!    `C ← Φ_t[:, :k']ᵀ M_t Π Φ_s[:, :k']` with `k' = k + step`. Landmark target vertices keep
//!    their landmark source vertex.
//!
//! Landmarks break intrinsic symmetries (left/right flips); without them a symmetric pair of shapes
//! may map flipped. Disconnected and tiny meshes, and failed eigen-solves, return an error: callers
//! fall back to whatever they did without the map.

use std::time::Instant;

use faer::linalg::matmul::matmul;
use faer::linalg::solvers::Solve;
use faer::{Accum, MatMut, MatRef, Par, Side};
use rayon::prelude::*;

use super::eigen::laplacian_eigen;
use super::laplacian::mass_matrix_voronoi;
use crate::error::{Error, Result};
use crate::work::CancelToken;

/// Parameters of [`shape_map`] / [`functional_map`].
#[derive(Clone, Debug, PartialEq)]
pub struct FmapParams {
    /// Size of the initial functional map (descriptor fit).
    pub k_init: usize,
    /// Size of the final map after ZoomOut (also the eigenpairs computed per mesh).
    pub k_final: usize,
    /// ZoomOut step.
    pub k_step: usize,
    /// Eigenpairs used by the descriptors.
    pub k_descriptors: usize,
    /// WKS energies.
    pub descriptors: usize,
    /// HKS times (Sun et al. 2009), log-spaced over the spectra's common range; 0 = WKS only
    /// (the default: on SMPL man -> woman HKS changes nothing with landmarks, and without them
    /// 16 times flip parts of the map, mean error 0.27 against 0.034; `examples/fmap_params`).
    pub hks: usize,
    /// Energies per landmark.
    pub landmark_energies: usize,
    /// Weight of Laplacian commutativity relative to descriptor preservation.
    pub commutativity: f64,
    /// Weight of the orientation-preserving term (Ren et al. 2018) relative to descriptor
    /// preservation (0 = off); computed on every `orientation_stride`-th WKS descriptor.
    pub orientation: f64,
    pub orientation_stride: usize,
}

impl Default for FmapParams {
    fn default() -> Self {
        FmapParams {
            k_init: 20,
            k_final: 100,
            k_step: 10,
            k_descriptors: 50,
            descriptors: 100,
            hks: 0,
            landmark_energies: 25,
            commutativity: 1e-2,
            orientation: 1.0,
            orientation_stride: 4,
        }
    }
}

/// A mesh's Laplacian spectrum on its unit-area rescaling.
#[derive(Clone, Debug)]
pub struct Spectrum {
    /// Vertex count.
    pub n: usize,
    /// Eigenvalues ascending (unit-area scale).
    pub evals: Vec<f64>,
    /// Eigenvectors, flat column-major `n × k` (`evecs[i * n + v]`), M-orthonormal on unit area.
    pub evecs: Vec<f64>,
    /// Voronoi vertex areas of the unit-area surface.
    pub mass: Vec<f64>,
    /// The mesh's true area.
    pub area: f64,
    /// Positions rescaled to unit area, and the faces (for the orientation operators).
    pub positions: Vec<[f64; 3]>,
    pub faces: Vec<[u32; 3]>,
    /// Per-face gradients of the leading basis functions, made on first use (the orientation
    /// operators of every descriptor and every landmark edit share them).
    face_basis: std::sync::OnceLock<FaceBasis>,
}

/// Per face of a [`Spectrum`]: the gradient operator (unit normal and the three corner
/// gradient vectors `n × e / 2A`) and, for the first `k` basis functions, their gradients
/// (`grads[f * k + j]`) and area-lumped corner sums (`lumped`, column-major `F × k`:
/// `A/3 · Σ_corners φ_j`).
#[derive(Clone, Debug)]
struct FaceBasis {
    k: usize,
    gradient: Vec<[[f64; 3]; 3]>,
    normal: Vec<[f64; 3]>,
    grads: Vec<[f64; 3]>,
    lumped: Vec<f64>,
}

impl Spectrum {
    /// Smallest `k` eigenpairs of `positions`/`faces`, rescaled to unit area. Errors on meshes
    /// with more than one connected component, fewer than `k + 1` vertices or zero area.
    pub fn new(positions: &[[f32; 3]], faces: &[[u32; 3]], k: usize) -> Result<Spectrum> {
        let n = positions.len();
        if n < k + 1 || n < 10 || faces.is_empty() {
            return Err(Error::InvalidInput(format!(
                "shape map: mesh too small ({n} vertices) for {k} eigenpairs"
            )));
        }
        let (label, _) = crate::mesh::connected_components(n, faces);
        let mut used = vec![false; n];
        for f in faces {
            for &v in f {
                used[v as usize] = true;
            }
        }
        let first = label[used.iter().position(|&u| u).unwrap_or(0)];
        if (0..n).any(|v| used[v] && label[v] != first) {
            return Err(Error::InvalidInput(
                "shape map: the mesh has several connected components".into(),
            ));
        }
        let mass0 = mass_matrix_voronoi(positions, faces);
        let area: f64 = mass0.iter().sum();
        if area.is_nan() || area <= 0.0 {
            return Err(Error::InvalidInput("shape map: mesh has no area".into()));
        }
        let (mut evals, mut evecs) = laplacian_eigen(positions, faces, k)?;
        if evals.iter().any(|x| !x.is_finite()) || evecs.iter().any(|x| !x.is_finite()) {
            return Err(Error::InvalidInput(
                "shape map: the eigen-solve did not converge".into(),
            ));
        }
        // unit area: λ' = λ A, φ' = φ √A, M' = M / A
        let sa = area.sqrt();
        evals.iter_mut().for_each(|l| *l *= area);
        evecs.iter_mut().for_each(|x| *x *= sa);
        let mass = mass0.iter().map(|m| m / area).collect();
        let positions = positions.iter().map(|p| p.map(|x| x as f64 / sa)).collect();
        Ok(Spectrum {
            n,
            evals,
            evecs,
            mass,
            area,
            positions,
            faces: faces.to_vec(),
            face_basis: std::sync::OnceLock::new(),
        })
    }

    /// Eigenpairs held.
    pub fn k(&self) -> usize {
        self.evals.len()
    }

    /// The per-face basis gradients for `k` functions: made once (other threads wait for it),
    /// or afresh for another `k`.
    fn face_basis(&self, k: usize) -> std::borrow::Cow<'_, FaceBasis> {
        let b = self.face_basis.get_or_init(|| FaceBasis::new(self, k));
        if b.k == k {
            std::borrow::Cow::Borrowed(b)
        } else {
            std::borrow::Cow::Owned(FaceBasis::new(self, k))
        }
    }

    fn phi(&self, i: usize) -> &[f64] {
        &self.evecs[i * self.n..(i + 1) * self.n]
    }

    /// `Φ[:, :k]ᵀ M f` for a vertex function `f`.
    fn project(&self, f: &[f64], k: usize) -> Vec<f64> {
        (0..k)
            .map(|i| {
                self.phi(i)
                    .iter()
                    .zip(f)
                    .zip(&self.mass)
                    .map(|((p, x), m)| p * x * m)
                    .sum()
            })
            .collect()
    }
}

/// A point-to-point map target → source and its functional map.
#[derive(Clone, Debug)]
pub struct ShapeMap {
    /// Source vertex of every target vertex.
    pub target_to_source: Vec<u32>,
    /// Final functional map, row-major `k × k` (`c[i * k + j]`): source coefficients → target.
    pub c: Vec<f64>,
    /// Size of `c`.
    pub k: usize,
    /// How close the map is to an isometry ([`MapQuality`]).
    pub quality: MapQuality,
    /// Stage timings (seconds).
    pub timings: Vec<(String, f64)>,
}

/// How close a functional map is to that of an isometry, on its leading `k` × `k` block
/// (`k` at most [`QUALITY_K`]): an isometry's `C` is orthogonal and commutes with the Laplacians
/// (Ovsjanikov et al. 2012, §6.1), so both defects are near 0 between similar shapes and grow as
/// the shapes differ.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MapQuality {
    /// `‖CᵀC − I‖_F / ‖I‖_F`.
    pub orthogonality: f64,
    /// `‖C Λ_s − Λ_t C‖_F / ‖C Λ_s‖_F`.
    pub commutativity: f64,
}

/// Size of the leading block on which [`MapQuality`] is measured (the low frequencies, which a
/// map between similar shapes preserves most reliably).
pub const QUALITY_K: usize = 30;

impl MapQuality {
    /// Measure the leading block of a row-major `k × k` map `c` (source → target coefficients).
    pub fn of(c: &[f64], k: usize, source_evals: &[f64], target_evals: &[f64]) -> MapQuality {
        let q = k
            .min(QUALITY_K)
            .min(source_evals.len())
            .min(target_evals.len());
        let at = |i: usize, j: usize| c[i * k + j];
        let mut ortho = 0.0;
        for a in 0..q {
            for b in 0..q {
                let dot: f64 = (0..q).map(|i| at(i, a) * at(i, b)).sum();
                let d = dot - if a == b { 1.0 } else { 0.0 };
                ortho += d * d;
            }
        }
        let (mut num, mut den) = (0.0, 0.0);
        for (i, &lt) in target_evals.iter().enumerate().take(q) {
            for (j, &ls) in source_evals.iter().enumerate().take(q) {
                let x = at(i, j) * ls;
                let y = lt * at(i, j);
                num += (x - y) * (x - y);
                den += x * x;
            }
        }
        MapQuality {
            orthogonality: (ortho / q.max(1) as f64).sqrt(),
            commutativity: if den > 0.0 { (num / den).sqrt() } else { 1.0 },
        }
    }

    /// One number in `[0, 1]`: 1 for an isometry, falling as the defects grow (the larger defect
    /// counts; each reaches 0.5 at [`QUALITY_HALF`]).
    pub fn score(&self) -> f64 {
        let d = self.orthogonality.max(self.commutativity);
        if d.is_finite() {
            1.0 / (1.0 + (d / QUALITY_HALF).powi(2))
        } else {
            0.0
        }
    }
}

/// Defect at which [`MapQuality::score`] is 0.5.
pub const QUALITY_HALF: f64 = 0.5;

/// Spectra of both meshes plus [`functional_map`]. `landmarks` are (source vertex, target vertex)
/// pairs.
pub fn shape_map(
    source: (&[[f32; 3]], &[[u32; 3]]),
    target: (&[[f32; 3]], &[[u32; 3]]),
    landmarks: &[(u32, u32)],
    params: &FmapParams,
    cancel: &CancelToken,
) -> Result<ShapeMap> {
    let t0 = Instant::now();
    let k = params.k_final.max(params.k_init).max(params.k_descriptors);
    let (ss, st) = rayon::join(
        || Spectrum::new(source.0, source.1, k),
        || Spectrum::new(target.0, target.1, k),
    );
    let (ss, st) = (ss?, st?);
    let te = t0.elapsed().as_secs_f64();
    cancel.check()?;
    let mut m = functional_map(&ss, &st, landmarks, params, cancel)?;
    m.timings.insert(0, ("eigen".into(), te));
    Ok(m)
}

/// The smallest non-zero and the largest eigenvalue of a spectrum (`λ_1`, `λ_max`).
fn nonzero_range(v: &[f64]) -> (f64, f64) {
    let lmax = v.iter().copied().fold(0.0f64, f64::max);
    let l1 = v
        .iter()
        .copied()
        .filter(|&l| l > 1e-9 * lmax)
        .fold(f64::INFINITY, f64::min);
    (l1, lmax)
}

/// Log-energies and σ of the WKS over the non-zero eigenvalues of both spectra (`kd` pairs).
fn wks_energies(a: &[f64], b: &[f64], count: usize) -> (Vec<f64>, f64) {
    let pos = |v: &[f64]| -> (f64, f64) {
        let (l1, lmax) = nonzero_range(v);
        (l1.ln(), lmax.ln())
    };
    let (a0, a1) = pos(a);
    let (b0, b1) = pos(b);
    let (e0, e1) = (a0.max(b0), a1.min(b1) - 0.02);
    let count = count.max(2);
    let step = (e1 - e0) / (count - 1) as f64;
    let e = (0..count).map(|j| e0 + step * j as f64).collect();
    (e, 7.0 * step)
}

/// HKS times: `count` log-spaced over `[4 ln 10 / λ_max, 4 ln 10 / λ_1]` on the non-zero
/// eigenvalues common to both spectra (Sun et al. 2009).
fn hks_times(a: &[f64], b: &[f64], count: usize) -> Vec<f64> {
    if count == 0 {
        return Vec::new();
    }
    let ((a1, an), (b1, bn)) = (nonzero_range(a), nonzero_range(b));
    let (l1, ln) = (a1.max(b1), an.min(bn));
    if !(l1.is_finite() && ln > l1) {
        return Vec::new();
    }
    let (t0, t1) = ((4.0 * 10f64.ln() / ln).ln(), (4.0 * 10f64.ln() / l1).ln());
    (0..count)
        .map(|j| (t0 + (t1 - t0) * j as f64 / (count - 1).max(1) as f64).exp())
        .collect()
}

/// Descriptor functions (each unit M-norm) of one shape: WKS, HKS, then landmark wave kernels.
fn descriptors(
    sp: &Spectrum,
    kd: usize,
    energies: &[f64],
    sigma: f64,
    hks: &[f64],
    landmarks: &[u32],
    lm_energies: &[f64],
) -> Vec<Vec<f64>> {
    let ev = &sp.evals[..kd];
    let lmax = ev.iter().copied().fold(0.0f64, f64::max);
    let g = |e: f64| -> Vec<f64> {
        ev.iter()
            .map(|&l| {
                if l > 1e-9 * lmax {
                    (-(e - l.ln()).powi(2) / (2.0 * sigma * sigma)).exp()
                } else {
                    0.0
                }
            })
            .collect()
    };
    let n = sp.n;
    let mut out: Vec<Vec<f64>> = energies
        .par_iter()
        .map(|&e| {
            let w = g(e);
            let tot: f64 = w.iter().sum::<f64>().max(1e-300);
            let mut f = vec![0.0; n];
            for (i, wi) in w.iter().enumerate() {
                if *wi < 1e-12 {
                    continue;
                }
                for (fv, p) in f.iter_mut().zip(sp.phi(i)) {
                    *fv += wi * p * p;
                }
            }
            f.iter_mut().for_each(|x| *x /= tot);
            f
        })
        .collect();
    let heat: Vec<Vec<f64>> = hks
        .par_iter()
        .map(|&t| {
            let mut f = vec![0.0; n];
            for (i, &l) in ev.iter().enumerate() {
                let w = (-l * t).exp();
                if w < 1e-12 {
                    continue;
                }
                for (fv, p) in f.iter_mut().zip(sp.phi(i)) {
                    *fv += w * p * p;
                }
            }
            f
        })
        .collect();
    out.extend(heat);
    let lm: Vec<Vec<f64>> = landmarks
        .par_iter()
        .flat_map_iter(|&l| {
            lm_energies.iter().map(move |&e| {
                let w = g(e);
                let mut f = vec![0.0; n];
                for (i, wi) in w.iter().enumerate() {
                    let c = wi * sp.phi(i)[l as usize];
                    if c == 0.0 {
                        continue;
                    }
                    for (fv, p) in f.iter_mut().zip(sp.phi(i)) {
                        *fv += c * p;
                    }
                }
                f
            })
        })
        .collect();
    out.extend(lm);
    for f in &mut out {
        let nrm: f64 = f
            .iter()
            .zip(&sp.mass)
            .map(|(x, m)| x * x * m)
            .sum::<f64>()
            .sqrt();
        if nrm > 0.0 {
            f.iter_mut().for_each(|x| *x /= nrm);
        }
    }
    out
}

/// Solve the SPD system `a x = b` (`a` row-major `k × k`, its lower triangle read) by Cholesky;
/// `None` when not PD.
pub(crate) fn cholesky_solve(a: &[f64], b: &[f64], k: usize) -> Option<Vec<f64>> {
    let llt = MatRef::from_row_major_slice(a, k, k)
        .llt(Side::Lower)
        .ok()?;
    let mut x = b.to_vec();
    llt.solve_in_place(MatMut::from_column_major_slice_mut(&mut x, k, 1));
    Some(x)
}

fn sub3(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn cross3(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
fn dot3(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

impl FaceBasis {
    fn new(sp: &Spectrum, k: usize) -> FaceBasis {
        let nf = sp.faces.len();
        let mut gradient = vec![[[0.0; 3]; 3]; nf];
        let mut normal = vec![[0.0; 3]; nf];
        let mut area3 = vec![0.0; nf];
        for (fi, face) in sp.faces.iter().enumerate() {
            let p = face.map(|i| sp.positions[i as usize]);
            let nn = cross3(sub3(p[1], p[0]), sub3(p[2], p[0]));
            let a2 = dot3(nn, nn).sqrt();
            if a2 <= 1e-300 {
                continue; // zero gradients and weight: the face adds nothing
            }
            let n = nn.map(|c| c / a2);
            normal[fi] = n;
            // n × e_c / (2A), e_c the edge opposite corner c (counter-clockwise)
            gradient[fi] = std::array::from_fn(|c| {
                cross3(n, sub3(p[(c + 2) % 3], p[(c + 1) % 3])).map(|x| x / a2)
            });
            area3[fi] = a2 / 6.0;
        }
        let mut grads = vec![[0.0; 3]; nf * k];
        let mut lumped = vec![0.0; nf * k];
        for j in 0..k {
            let phi = sp.phi(j);
            for (fi, face) in sp.faces.iter().enumerate() {
                let v = face.map(|i| phi[i as usize]);
                grads[fi * k + j] = apply_gradient(&gradient[fi], v);
                lumped[j * nf + fi] = area3[fi] * (v[0] + v[1] + v[2]);
            }
        }
        FaceBasis {
            k,
            gradient,
            normal,
            grads,
            lumped,
        }
    }
}

fn apply_gradient(basis: &[[f64; 3]; 3], vals: [f64; 3]) -> [f64; 3] {
    let mut g = [0.0; 3];
    for c in 0..3 {
        for d in 0..3 {
            g[d] += vals[c] * basis[c][d];
        }
    }
    g
}

/// `X_f = Φᵀ M O_f Φ` (`k × k`, row-major) for the orientation operator
/// `O_f(g) = ⟨n × ∇f, ∇g⟩` (Ren, Poulenard, Liu, Ovsjanikov 2018), per face, lumped to the
/// corners with a third of the face area: `X = Lᵀ G` with `L` the lumped basis and
/// `G[f, j] = (n × ∇f) · ∇φ_j` on face `f`.
fn orientation_operator(sp: &Spectrum, f: &[f64], k: usize) -> Vec<f64> {
    let fb = sp.face_basis(k);
    let nf = sp.faces.len();
    let mut g = vec![0.0; nf * k];
    for (fi, face) in sp.faces.iter().enumerate() {
        let rot = cross3(
            fb.normal[fi],
            apply_gradient(&fb.gradient[fi], face.map(|i| f[i as usize])),
        );
        for j in 0..k {
            g[j * nf + fi] = dot3(rot, fb.grads[fi * k + j]);
        }
    }
    // x (row-major k × k) = Lᵀ G, written as the column-major transpose xᵀ = Gᵀ L
    let mut x = vec![0.0; k * k];
    matmul(
        MatMut::from_column_major_slice_mut(&mut x, k, k),
        Accum::Replace,
        MatRef::from_column_major_slice(&g, nf, k).transpose(),
        MatRef::from_column_major_slice(&fb.lumped, nf, k),
        1.0f64,
        Par::Seq,
    );
    x
}

/// The initial `k × k` map from descriptor preservation + Laplacian commutativity (row-major).
#[allow(clippy::too_many_arguments)]
fn fit_initial(
    ss: &Spectrum,
    st: &Spectrum,
    fs: &[Vec<f64>],
    ft: &[Vec<f64>],
    k: usize,
    mu: f64,
    fo: &[(usize, usize)],
    orient: f64,
) -> Result<Vec<f64>> {
    let d = fs.len();
    let fo: Vec<(&[f64], &[f64])> = fo.iter().map(|&(i, j)| (&fs[i][..], &ft[j][..])).collect();
    let fo = &fo[..];
    // a: k × d (column j = coefficients of descriptor j), stored row-major a[i * d + j]
    let proj = |sp: &Spectrum, f: &[Vec<f64>]| -> Vec<f64> {
        let cols: Vec<Vec<f64>> = f.par_iter().map(|x| sp.project(x, k)).collect();
        let mut a = vec![0.0; k * d];
        for (j, c) in cols.iter().enumerate() {
            for i in 0..k {
                a[i * d + j] = c[i];
            }
        }
        a
    };
    let a = proj(ss, fs);
    let b = proj(st, ft);
    let mut aat = vec![0.0; k * k];
    for i in 0..k {
        for j in 0..k {
            aat[i * k + j] = (0..d).map(|p| a[i * d + p] * a[j * d + p]).sum();
        }
    }
    let mut dd = vec![0.0; k * k];
    for i in 0..k {
        for j in 0..k {
            dd[i * k + j] = (st.evals[i] - ss.evals[j]).powi(2);
        }
    }
    let dn = dd.iter().map(|x| x * x).sum::<f64>().sqrt().max(1e-300);
    // scale μ with the descriptor term's size so the ratio is meaningful
    let tr = (0..k).map(|i| aat[i * k + i]).sum::<f64>() / k as f64;
    let mu = mu * tr * k as f64;
    if orient > 0.0 && !fo.is_empty() {
        return fit_joint(ss, st, &a, &b, d, &aat, &dd, dn, mu, tr, k, fo, orient);
    }
    let mut c = vec![0.0; k * k];
    for i in 0..k {
        let mut m = aat.clone();
        for j in 0..k {
            m[j * k + j] += mu * dd[i * k + j] / dn + 1e-12 * tr;
        }
        let rhs: Vec<f64> = (0..k)
            .map(|j| (0..d).map(|p| a[j * d + p] * b[i * d + p]).sum())
            .collect();
        let row = cholesky_solve(&m, &rhs, k).ok_or_else(|| {
            Error::InvalidInput("shape map: descriptor system is singular".into())
        })?;
        c[i * k..(i + 1) * k].copy_from_slice(&row);
    }
    Ok(c)
}

/// The initial map with the orientation term: all of `C` at once, normal equations on `vec(C)`
/// (`k² × k²`, entry `(a, b)` at `a k + b`):
/// `H[(a,b),(c,d)] = δ_ac (AAᵀ)_bd + μ δ_ac δ_bd D_ab / ‖D‖ + w Σ_f [δ_ac (XXᵀ)_bd + δ_bd (YᵀY)_ac
/// − X_bd Y_ac − X_db Y_ca]` with `X = X_f` on the source and `Y = X_f` on the target.
#[allow(clippy::too_many_arguments)]
fn fit_joint(
    ss: &Spectrum,
    st: &Spectrum,
    a: &[f64],
    b: &[f64],
    d: usize,
    aat: &[f64],
    dd: &[f64],
    dn: f64,
    mu: f64,
    tr: f64,
    k: usize,
    fo: &[(&[f64], &[f64])],
    orient: f64,
) -> Result<Vec<f64>> {
    let kk = k * k;
    let ops: Vec<(Vec<f64>, Vec<f64>)> = fo
        .par_iter()
        .map(|(fs, ft)| {
            (
                orientation_operator(ss, fs, k),
                orientation_operator(st, ft, k),
            )
        })
        .collect();
    let mut ho = vec![0.0; kk * kk];
    for (x, y) in &ops {
        let mut xxt = vec![0.0; kk];
        let mut yty = vec![0.0; kk];
        for p in 0..k {
            for q in 0..k {
                xxt[p * k + q] = (0..k).map(|r| x[p * k + r] * x[q * k + r]).sum();
                yty[p * k + q] = (0..k).map(|r| y[r * k + p] * y[r * k + q]).sum();
            }
        }
        for ai in 0..k {
            for bi in 0..k {
                let row = (ai * k + bi) * kk;
                for ci in 0..k {
                    for di in 0..k {
                        let mut h =
                            -x[bi * k + di] * y[ai * k + ci] - x[di * k + bi] * y[ci * k + ai];
                        if ai == ci {
                            h += xxt[bi * k + di];
                        }
                        if bi == di {
                            h += yty[ai * k + ci];
                        }
                        ho[row + ci * k + di] += h;
                    }
                }
            }
        }
    }
    // the orientation term's size relative to the descriptor term's
    let tro = (0..kk).map(|i| ho[i * kk + i]).sum::<f64>() / kk as f64;
    let wo = if tro > 0.0 { orient * tr / tro } else { 0.0 };
    let mut h: Vec<f64> = ho.iter().map(|x| wo * x).collect();
    let mut rhs = vec![0.0; kk];
    for ai in 0..k {
        for bi in 0..k {
            let r = ai * k + bi;
            for di in 0..k {
                h[r * kk + ai * k + di] += aat[bi * k + di];
            }
            h[r * kk + r] += mu * dd[ai * k + bi] / dn + 1e-12 * tr;
            rhs[r] = (0..d).map(|p| b[ai * d + p] * a[bi * d + p]).sum();
        }
    }
    cholesky_solve(&h, &rhs, kk)
        .ok_or_else(|| Error::InvalidInput("shape map: descriptor system is singular".into()))
}

/// Nearest row of `src` (`ns × k`, column-major f32) for every row of `tgt` (`nt × k`), brute
/// force in blocks with a matrix product.
fn nearest_rows(src: &[f32], ns: usize, tgt: &[f32], nt: usize, k: usize) -> Vec<u32> {
    const BLOCK: usize = 256;
    let s = MatRef::from_column_major_slice(src, ns, k);
    let t = MatRef::from_column_major_slice(tgt, nt, k);
    let snorm: Vec<f32> = (0..ns)
        .map(|r| (0..k).map(|c| src[c * ns + r].powi(2)).sum())
        .collect();
    let blocks: Vec<usize> = (0..nt).step_by(BLOCK).collect();
    let res: Vec<Vec<u32>> = blocks
        .par_iter()
        .map(|&b0| {
            let nb = BLOCK.min(nt - b0);
            let mut dots = vec![0.0f32; ns * nb];
            matmul(
                MatMut::from_column_major_slice_mut(&mut dots, ns, nb),
                Accum::Replace,
                s,
                t.subrows(b0, nb).transpose(),
                1.0f32,
                Par::Seq,
            );
            (0..nb)
                .map(|j| argmin_distance(&snorm, &dots[j * ns..(j + 1) * ns]))
                .collect()
        })
        .collect();
    res.concat()
}

/// The first `r` minimising `snorm[r] - 2 dots[r]` (a squared distance less the query's own
/// norm); 0 when no entry is below infinity. Eight running minima, one per lane, so the scan
/// vectorises (the scalar loop's compare-and-keep chain ran at a few cycles per source row);
/// the lanes' minima are merged with ties to the lower row, which gives the scalar scan's row.
fn argmin_distance(snorm: &[f32], dots: &[f32]) -> u32 {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        #[target_feature(enable = "avx2")]
        unsafe fn avx2(snorm: &[f32], dots: &[f32]) -> u32 {
            argmin_distance_body(snorm, dots)
        }
        // SAFETY: the processor supports AVX2 (checked just above).
        return unsafe { avx2(snorm, dots) };
    }
    argmin_distance_body(snorm, dots)
}

#[inline(always)]
fn argmin_distance_body(snorm: &[f32], dots: &[f32]) -> u32 {
    const L: usize = 8;
    let n = snorm.len().min(dots.len());
    let (sn, dt) = (&snorm[..n], &dots[..n]);
    let mut best = [f32::INFINITY; L];
    let mut at = [0u32; L];
    let mut row: [u32; L] = std::array::from_fn(|l| l as u32);
    let (sc, st) = sn.as_chunks::<L>();
    let (dc, dt_tail) = dt.as_chunks::<L>();
    for (s, d) in sc.iter().zip(dc) {
        for l in 0..L {
            let v = s[l] - 2.0 * d[l];
            let better = v < best[l];
            best[l] = if better { v } else { best[l] };
            at[l] = if better { row[l] } else { at[l] };
            row[l] += L as u32;
        }
    }
    let mut out = (f32::INFINITY, 0u32);
    for l in 0..L {
        if best[l] < out.0 || (best[l] == out.0 && at[l] < out.1) {
            out = (best[l], at[l]);
        }
    }
    let base = sc.len() * L;
    for (i, (&s, &d)) in st.iter().zip(dt_tail).enumerate() {
        let v = s - 2.0 * d;
        if v < out.0 {
            out = (v, (base + i) as u32);
        }
    }
    out.1
}

/// Point map from a `k × k` functional map: nearest neighbours of `Φ_t C` among `Φ_s`.
fn point_map(ss: &Spectrum, st: &Spectrum, c: &[f64], k: usize, fixed: &[(u32, u32)]) -> Vec<u32> {
    let all: Vec<u32> = (0..st.n as u32).collect();
    point_map_rows(ss, st, c, k, fixed, &all, None)
}

/// [`point_map`] for the target vertices `rows` only (the result is per row), against every
/// source vertex or the source vertices `cols` only.
fn point_map_rows(
    ss: &Spectrum,
    st: &Spectrum,
    c: &[f64],
    k: usize,
    fixed: &[(u32, u32)],
    rows: &[u32],
    cols: Option<&[u32]>,
) -> Vec<u32> {
    // ZoomOut's point map (Melzi et al. 2019, eq. 3): every target row Φ_t(x) against the source
    // rows mapped into the target basis, Φ_s(y) Cᵀ (which, unlike comparing Φ_t(x) C with
    // Φ_s(y), stays right when C is not orthogonal).
    let m = rows.len();
    let mut tgt = vec![0.0f32; m * k];
    tgt.par_chunks_mut(m.max(1))
        .enumerate()
        .for_each(|(i, col)| {
            let phi = st.phi(i);
            for (o, &r) in col.iter_mut().zip(rows) {
                *o = phi[r as usize] as f32;
            }
        });
    // Φ_s[cols, :k] Cᵀ: C row-major is Cᵀ column-major.
    let gathered: Vec<f64>;
    let (phi_s, ns) = match cols {
        None => (&ss.evecs[..ss.n * k], ss.n),
        Some(cols) => {
            gathered = (0..k)
                .flat_map(|i| {
                    let phi = ss.phi(i);
                    cols.iter().map(move |&v| phi[v as usize])
                })
                .collect();
            (&gathered[..], cols.len())
        }
    };
    let mut src64 = vec![0.0f64; ns * k];
    matmul(
        MatMut::from_column_major_slice_mut(&mut src64, ns, k),
        Accum::Replace,
        MatRef::from_column_major_slice(phi_s, ns, k),
        MatRef::from_column_major_slice(&c[..k * k], k, k),
        1.0f64,
        Par::rayon(0),
    );
    let src: Vec<f32> = src64.iter().map(|&x| x as f32).collect();
    drop(src64);
    let mut map = nearest_rows(&src, ns, &tgt, m, k);
    if let Some(cols) = cols {
        map.iter_mut().for_each(|s| *s = cols[*s as usize]);
    }
    for &(s, t) in fixed {
        if let Ok(r) = rows.binary_search(&t) {
            map[r] = s;
        }
    }
    map
}

/// Largest mesh the intermediate ZoomOut steps use whole; bigger ones use a random sample of
/// about this many vertices (plus the landmarks): target rows for the integrals of `C`, source
/// rows as the candidates. Only the last step maps every target vertex among every source
/// vertex.
pub const ZOOMOUT_SAMPLE: usize = 4_000;

/// `C` (row-major `k × k`) estimated from the target vertices `rows` and their images `map`:
/// `C ≈ w Φ_t[rows, :k]ᵀ M_t Φ_s[map, :k]`, with `w` the total mass over the sampled mass.
fn map_to_fmap_rows(ss: &Spectrum, st: &Spectrum, rows: &[u32], map: &[u32], k: usize) -> Vec<f64> {
    let total: f64 = st.mass.iter().sum();
    let sampled: f64 = rows.iter().map(|&t| st.mass[t as usize]).sum();
    let w = if sampled > 0.0 { total / sampled } else { 1.0 };
    fmap_from_pairs(
        ss,
        st,
        rows.iter().copied().zip(map.iter().copied()),
        rows.len(),
        k,
        w,
    )
}

/// `C = Φ_t[:, :k]ᵀ M_t Π Φ_s[:, :k]` (row-major) for a point map target → source.
fn map_to_fmap(ss: &Spectrum, st: &Spectrum, map: &[u32], k: usize) -> Vec<f64> {
    fmap_from_pairs(
        ss,
        st,
        (0..st.n as u32).zip(map.iter().copied()),
        st.n,
        k,
        1.0,
    )
}

/// `w Σ_(t, s) M_t[t] Φ_t[t, i] Φ_s[s, j]` over `m` (target, source) pairs, as one product of
/// the gathered rows (row-major `k × k`).
fn fmap_from_pairs(
    ss: &Spectrum,
    st: &Spectrum,
    pairs: impl Iterator<Item = (u32, u32)> + Clone,
    m: usize,
    k: usize,
    w: f64,
) -> Vec<f64> {
    let mut a = vec![0.0f64; m * k];
    let mut b = vec![0.0f64; m * k];
    for i in 0..k {
        let (pt, ps) = (st.phi(i), ss.phi(i));
        let (ca, cb) = (&mut a[i * m..(i + 1) * m], &mut b[i * m..(i + 1) * m]);
        for (r, (t, s)) in pairs.clone().enumerate() {
            ca[r] = pt[t as usize] * st.mass[t as usize];
            cb[r] = ps[s as usize];
        }
    }
    // c[i k + j] = C[i, j] is the column-major Cᵀ = w Bᵀ A.
    let mut c = vec![0.0f64; k * k];
    matmul(
        MatMut::from_column_major_slice_mut(&mut c, k, k),
        Accum::Replace,
        MatRef::from_column_major_slice(&b, m, k).transpose(),
        MatRef::from_column_major_slice(&a, m, k),
        w,
        Par::rayon(0),
    );
    c
}

/// Functional map between two spectra plus ZoomOut (module docs), with `landmarks` as
/// (source vertex, target vertex) pairs.
pub fn functional_map(
    ss: &Spectrum,
    st: &Spectrum,
    landmarks: &[(u32, u32)],
    params: &FmapParams,
    cancel: &CancelToken,
) -> Result<ShapeMap> {
    let kmax = ss.k().min(st.k());
    let k0 = params.k_init.clamp(2, kmax);
    let kf = params.k_final.clamp(k0, kmax);
    let kd = params.k_descriptors.clamp(k0, kmax);
    if landmarks
        .iter()
        .any(|&(s, t)| s as usize >= ss.n || t as usize >= st.n)
    {
        return Err(Error::InvalidInput(
            "shape map: landmark out of range".into(),
        ));
    }
    let mut timings = Vec::new();
    let t0 = Instant::now();
    let (energies, sigma) = wks_energies(&ss.evals[..kd], &st.evals[..kd], params.descriptors);
    let lm_count = params.landmark_energies.min(energies.len());
    let lm_energies: Vec<f64> = (0..lm_count)
        .map(|j| energies[j * energies.len() / lm_count.max(1)])
        .collect();
    let ls: Vec<u32> = landmarks.iter().map(|p| p.0).collect();
    let lt: Vec<u32> = landmarks.iter().map(|p| p.1).collect();
    let times = hks_times(&ss.evals[..kd], &st.evals[..kd], params.hks);
    let (fs, ft) = rayon::join(
        || descriptors(ss, kd, &energies, sigma, &times, &ls, &lm_energies),
        || descriptors(st, kd, &energies, sigma, &times, &lt, &lm_energies),
    );
    let fo: Vec<(usize, usize)> = (0..energies.len() + times.len())
        .step_by(params.orientation_stride.max(1))
        .map(|i| (i, i))
        .collect();
    let mut c = fit_initial(
        ss,
        st,
        &fs,
        &ft,
        k0,
        params.commutativity,
        &fo,
        params.orientation,
    )?;
    timings.push(("initial map".into(), t0.elapsed().as_secs_f64()));
    cancel.check()?;
    let t0 = Instant::now();
    let step = params.k_step.max(1);
    let mut k = k0;
    // intermediate steps on a sample of a large target (deterministic: a hash of the index)
    // Intermediate steps on samples of large meshes (deterministic: a hash of the index; the
    // landmarks always in): every target row's image among the sampled source rows.
    let sample = |n: usize, keep_too: Vec<u32>| -> Option<Vec<u32>> {
        (n > ZOOMOUT_SAMPLE * 3 / 2).then(|| {
            let keep = (ZOOMOUT_SAMPLE as u64).saturating_mul(1 << 32) / n as u64;
            let mut lm = keep_too;
            lm.sort_unstable();
            (0..n as u32)
                .filter(|&v| {
                    (v.wrapping_mul(2_654_435_761) as u64) < keep || lm.binary_search(&v).is_ok()
                })
                .collect()
        })
    };
    let rows = sample(st.n, landmarks.iter().map(|l| l.1).collect());
    let cols = sample(ss.n, landmarks.iter().map(|l| l.0).collect());
    let rows = rows.or_else(|| cols.as_ref().map(|_| (0..st.n as u32).collect()));
    let map = loop {
        if k >= kf {
            break point_map(ss, st, &c, k, landmarks);
        }
        let next = (k + step).min(kf);
        c = match &rows {
            Some(r) => {
                let m = point_map_rows(ss, st, &c, k, landmarks, r, cols.as_deref());
                map_to_fmap_rows(ss, st, r, &m, next)
            }
            None => map_to_fmap(ss, st, &point_map(ss, st, &c, k, landmarks), next),
        };
        k = next;
        cancel.check()?;
    };
    timings.push(("zoomout".into(), t0.elapsed().as_secs_f64()));
    // the quality of the final point map itself, on the leading block (exact integrals)
    let q = k.min(QUALITY_K);
    let quality = MapQuality::of(&map_to_fmap(ss, st, &map, q), q, &ss.evals, &st.evals);
    Ok(ShapeMap {
        target_to_source: map,
        c,
        k,
        quality,
        timings,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fmap_cholesky_solves() {
        let a = [4.0, 1.0, 1.0, 3.0];
        let x = cholesky_solve(&a, &[1.0, 2.0], 2).unwrap();
        assert!((4.0 * x[0] + x[1] - 1.0).abs() < 1e-12);
        assert!((x[0] + 3.0 * x[1] - 2.0).abs() < 1e-12);
    }

    #[test]
    fn fmap_nearest_rows_brute_force() {
        let src = [0.0f32, 1.0, 5.0, 0.0, 1.0, 5.0]; // 3 × 2
        let tgt = [4.0f32, 0.9, 4.0, 1.1]; // 2 × 2
        assert_eq!(nearest_rows(&src, 3, &tgt, 2, 2), vec![2, 1]);
    }

    #[test]
    fn argmin_distance_is_the_scalar_scans_row() {
        // Coarse values make ties common; some infinities and NaNs too.
        let mut seed = 7u64;
        let mut next = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 33) as u32
        };
        for n in [0usize, 1, 5, 8, 9, 31, 64, 1000] {
            for _ in 0..20 {
                let sn: Vec<f32> = (0..n).map(|_| (next() % 7) as f32).collect();
                let d: Vec<f32> = (0..n)
                    .map(|_| match next() % 50 {
                        0 => f32::NAN,
                        1 => f32::NEG_INFINITY,
                        _ => (next() % 5) as f32 * 0.5,
                    })
                    .collect();
                let mut want = (f32::INFINITY, 0u32);
                for r in 0..n {
                    let v = sn[r] - 2.0 * d[r];
                    if v < want.0 {
                        want = (v, r as u32);
                    }
                }
                assert_eq!(argmin_distance(&sn, &d), want.1, "n {n}");
            }
        }
    }

    #[test]
    fn fmap_rejects_disconnected_and_tiny() {
        let p = vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [5.0, 0.0, 0.0],
            [6.0, 0.0, 0.0],
            [5.0, 1.0, 0.0],
        ];
        let f = vec![[0, 1, 2], [3, 4, 5]];
        assert!(Spectrum::new(&p, &f, 3).is_err());
        assert!(Spectrum::new(&p[..3], &f[..1], 2).is_err());
    }
}
