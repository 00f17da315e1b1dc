//! Stripe patterns (Knöppel, Crane, Pinkall & Schröder 2015, "Stripe Patterns on Surfaces",
//! §4): a phase per vertex that grows at a prescribed frequency along a tangent direction field,
//! as smooth as the field allows, with its unavoidable singularities placed by the solve.
//!
//! Each vertex carries a complex number `ψ_i`; along an edge the field asks for the phase to
//! advance by `ω_ij = ν ⟨(X_i + X_j) / 2, p_j − p_i⟩` (eq. 5, a vector field rather than a line
//! field, so no edge needs conjugation). `ψ` is the eigenvector of the smallest eigenvalue of
//! `A ψ = λ B ψ` with the energy
//! `ψ* A ψ = Σ_ij w_ij |ψ_j − e^{i ω_ij} ψ_i|²` (eq. 6, cotangent weights `w_ij`, negative
//! per-face weights clamped to 0 so `A` stays semi-definite) and `B` the lumped barycentric mass,
//! found by inverse iteration with one sparse Cholesky factorisation of `A + εB`.
//!
//! [`StripePattern::step`] gives the phase difference along an edge (eq. 7's unwrapping:
//! `ω_ij + arg(ψ_j e^{−i ω_ij} / ψ_i)`); a face whose three steps do not sum to zero holds a
//! singularity ([`StripePattern::singular`]). Two patterns along `X` and `n × X` make a lattice
//! parametrisation away from their singularities (used by mesh quilting to place elements on
//! one global lattice).

use faer::linalg::solvers::Solve;
use faer::sparse::linalg::solvers::Llt;
use faer::sparse::{SparseColMat, Triplet};
use faer::{MatMut, Side};
use glam::DVec3;

use super::basic::d3;
use super::laplacian::{check_faces, face_cot_weights, mass_matrix_barycentric};
use crate::error::{Error, Result};

/// Most inverse-iteration steps.
const MAX_ITERS: usize = 60;
/// Stop when the Rayleigh quotient changes by less than this, relatively.
const RAYLEIGH_TOL: f64 = 1e-7;

/// A stripe pattern: a unit phase per vertex and what its edge steps need.
#[derive(Clone, Debug)]
pub struct StripePattern {
    /// Unit phase `(cos θ_i, sin θ_i)` per vertex; `(1, 0)` on vertices in no face.
    pub psi: Vec<[f64; 2]>,
    /// Unit tangent direction per vertex (the field the stripes advance along).
    dirs: Vec<DVec3>,
    /// Frequency `ν` in radians per unit length.
    pub frequency: f64,
    /// The smallest eigenvalue reached, normalised by `ν²` (0 for a pattern that follows the
    /// field exactly; larger where the field has curl or singularities).
    pub energy: f64,
}

impl StripePattern {
    /// The phase advance in radians from vertex `i` to vertex `j` (adjacent), consistent with
    /// the pattern: `ω_ij + arg(ψ_j e^{−i ω_ij} conj ψ_i)`. Antisymmetric.
    pub fn step(&self, positions: &[[f32; 3]], i: u32, j: u32) -> f64 {
        let (i, j) = (i as usize, j as usize);
        let e = d3(positions[j]) - d3(positions[i]);
        let w = self.frequency * 0.5 * (self.dirs[i] + self.dirs[j]).dot(e);
        let (a, b) = (self.psi[i], self.psi[j]);
        // z = ψ_j conj(ψ_i) e^{-iω}
        let (zr, zi) = (a[0] * b[0] + a[1] * b[1], a[0] * b[1] - a[1] * b[0]);
        let (c, s) = (w.cos(), w.sin());
        let (rr, ri) = (zr * c + zi * s, zi * c - zr * s);
        w + ri.atan2(rr)
    }

    /// The phase `θ_i` of vertex `i` in `(−π, π]`.
    pub fn phase(&self, i: u32) -> f64 {
        let p = self.psi[i as usize];
        p[1].atan2(p[0])
    }

    /// Singularity index of face `f`: the sum of its three edge steps over `2π`, rounded (0 on
    /// a regular face).
    pub fn singular(&self, positions: &[[f32; 3]], f: [u32; 3]) -> i32 {
        let s = self.step(positions, f[0], f[1])
            + self.step(positions, f[1], f[2])
            + self.step(positions, f[2], f[0]);
        (s / std::f64::consts::TAU).round() as i32
    }
}

/// The stripe pattern of frequency `frequency` (radians per unit length) along the field
/// `dirs` (one per vertex, tangent to the surface; it is normalised, not projected).
/// Deterministic.
///
/// Errors: mismatched lengths, a non-positive frequency, a failed factorisation.
pub fn stripe_pattern(
    positions: &[[f32; 3]],
    faces: &[[u32; 3]],
    dirs: &[[f32; 3]],
    frequency: f64,
) -> Result<StripePattern> {
    let n = positions.len();
    check_faces(n, faces)?;
    if dirs.len() != n {
        return Err(Error::InvalidInput(format!(
            "stripe pattern: {} directions for {n} vertices",
            dirs.len()
        )));
    }
    if !(frequency.is_finite() && frequency > 0.0) {
        return Err(Error::InvalidInput(format!(
            "stripe pattern: frequency must be positive (got {frequency})"
        )));
    }
    let dirs: Vec<DVec3> = dirs
        .iter()
        .map(|d| d3(*d).try_normalize().unwrap_or(DVec3::ZERO))
        .collect();
    let mass = mass_matrix_barycentric(positions, faces);
    // A in real form: unknowns (re, im) of vertex i at 2i, 2i + 1
    let mut trip: Vec<Triplet<usize, usize, f64>> = Vec::with_capacity(faces.len() * 3 * 12);
    let mut trace_a = 0.0;
    for f in faces {
        let p = f.map(|i| d3(positions[i as usize]));
        let w = face_cot_weights(p);
        for k in 0..3 {
            let wk = w[k].max(0.0);
            if !(wk > 0.0 && wk.is_finite()) {
                continue;
            }
            let (i, j) = (f[(k + 1) % 3] as usize, f[(k + 2) % 3] as usize);
            let om = frequency * 0.5 * (dirs[i] + dirs[j]).dot(p[(k + 2) % 3] - p[(k + 1) % 3]);
            let (c, s) = (om.cos(), om.sin());
            for d in 0..2 {
                trip.push(Triplet::new(2 * i + d, 2 * i + d, wk));
                trip.push(Triplet::new(2 * j + d, 2 * j + d, wk));
            }
            trace_a += 4.0 * wk;
            // block (j, i) = -w R(ω), block (i, j) = -w R(ω)^T
            let r = [[c, -s], [s, c]];
            for (a, row) in r.iter().enumerate() {
                for (b, &rab) in row.iter().enumerate() {
                    trip.push(Triplet::new(2 * j + a, 2 * i + b, -wk * rab));
                    trip.push(Triplet::new(2 * i + b, 2 * j + a, -wk * rab));
                }
            }
        }
    }
    let trace_m: f64 = 2.0 * mass.iter().sum::<f64>();
    if trace_m.is_nan() || trace_m <= 0.0 {
        return Err(Error::InvalidMesh(
            "stripe pattern: the mesh has no area".into(),
        ));
    }
    let eps = 1e-9 * trace_a.max(1e-300) / trace_m;
    for (i, &m) in mass.iter().enumerate() {
        let diag = if m > 0.0 { eps * m } else { 1.0 };
        trip.push(Triplet::new(2 * i, 2 * i, diag));
        trip.push(Triplet::new(2 * i + 1, 2 * i + 1, diag));
    }
    let a = SparseColMat::<usize, f64>::try_new_from_triplets(2 * n, 2 * n, &trip)
        .map_err(|e| Error::InvalidMesh(format!("stripe pattern matrix: {e:?}")))?;
    let llt: Llt<usize, f64> = a
        .sp_cholesky(Side::Lower)
        .map_err(|e| Error::InvalidMesh(format!("stripe pattern: Cholesky failed: {e:?}")))?;

    // inverse iteration, normalised per connected component so that every component keeps its
    // own smallest eigenvector at full precision
    let (label, ncomp) = crate::mesh::connected_components(n, faces);
    // vertices in no face carry labels past the count of components with faces
    let ncomp = ncomp.max(label.iter().map(|&l| l as usize + 1).max().unwrap_or(0));
    let mut x: Vec<f64> = (0..2 * n)
        .map(|k| {
            // a fixed, smooth-free start: a hash of the index in [-1, 1]
            let h = (k as u64)
                .wrapping_mul(0x9E37_79B9_7F4A_7C15)
                .rotate_left(17)
                .wrapping_mul(0xBF58_476D_1CE4_E5B9);
            (h >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
        })
        .collect();
    let normalise = |x: &mut [f64]| {
        let mut norm = vec![0.0; ncomp];
        for i in 0..n {
            norm[label[i] as usize] += mass[i] * (x[2 * i].powi(2) + x[2 * i + 1].powi(2));
        }
        for i in 0..n {
            let q = norm[label[i] as usize];
            if q > 0.0 {
                let inv = q.sqrt().recip();
                x[2 * i] *= inv;
                x[2 * i + 1] *= inv;
            }
        }
    };
    normalise(&mut x);
    let mut y = vec![0.0; 2 * n];
    let mut last = f64::INFINITY;
    let mut rayleigh = 0.0;
    for _ in 0..MAX_ITERS {
        for i in 0..n {
            y[2 * i] = mass[i] * x[2 * i];
            y[2 * i + 1] = mass[i] * x[2 * i + 1];
        }
        llt.solve_in_place(MatMut::from_column_major_slice_mut(&mut y, 2 * n, 1));
        // Rayleigh quotient of the shifted operator: x^T B x / x^T B y = λ + ε
        let (mut num, mut den) = (0.0, 0.0);
        for i in 0..n {
            num += mass[i] * (x[2 * i].powi(2) + x[2 * i + 1].powi(2));
            den += mass[i] * (x[2 * i] * y[2 * i] + x[2 * i + 1] * y[2 * i + 1]);
        }
        rayleigh = if den > 0.0 { num / den - eps } else { 0.0 };
        std::mem::swap(&mut x, &mut y);
        normalise(&mut x);
        if (rayleigh - last).abs() <= RAYLEIGH_TOL * rayleigh.abs().max(1e-300) {
            break;
        }
        last = rayleigh;
    }
    let psi = (0..n)
        .map(|i| {
            let (re, im) = (x[2 * i], x[2 * i + 1]);
            let r = (re * re + im * im).sqrt();
            if r > 0.0 && r.is_finite() {
                [re / r, im / r]
            } else {
                [1.0, 0.0]
            }
        })
        .collect();
    Ok(StripePattern {
        psi,
        dirs,
        frequency,
        energy: rayleigh.max(0.0) / (frequency * frequency),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::testdata::grid_cells as grid;

    #[test]
    fn a_constant_field_on_a_plane_gives_straight_stripes_of_the_asked_period() {
        let (pos, faces) = grid(40, 30, 0.05);
        // field at 30 degrees, period 0.4
        let a = 30f32.to_radians();
        let d = [a.cos(), a.sin(), 0.0];
        let dirs = vec![d; pos.len()];
        let nu = std::f64::consts::TAU / 0.4;
        let sp = stripe_pattern(&pos, &faces, &dirs, nu).unwrap();
        assert!(sp.energy < 1e-6, "energy {}", sp.energy);
        // the phase is nu <d, p> + const everywhere: steps match nu <d, e> and no face is
        // singular
        for f in &faces {
            assert_eq!(sp.singular(&pos, *f), 0);
            for k in 0..3 {
                let (i, j) = (f[k], f[(k + 1) % 3]);
                let e = d3(pos[j as usize]) - d3(pos[i as usize]);
                let want = nu * d3(d).dot(e);
                assert!((sp.step(&pos, i, j) - want).abs() < 1e-6);
            }
        }
        let p0 = d3(pos[0]);
        for (i, p) in pos.iter().enumerate() {
            let want = sp.phase(0) + nu * d3(d).dot(d3(*p) - p0);
            let diff = (sp.phase(i as u32) - want).rem_euclid(std::f64::consts::TAU);
            assert!(diff.min(std::f64::consts::TAU - diff) < 1e-5, "vertex {i}");
        }
    }

    #[test]
    fn a_vortex_field_forces_a_singularity() {
        // field circling the centre of a disc-like grid: the stripes along it are radial
        // spokes, which must meet in a singular face near the centre
        let (pos, faces) = grid(30, 30, 0.1);
        let c = glam::Vec3::new(1.5, 1.5, 0.0);
        let dirs: Vec<[f32; 3]> = pos
            .iter()
            .map(|p| {
                let r = glam::Vec3::from(*p) - c;
                glam::Vec3::new(-r.y, r.x, 0.0)
                    .normalize_or(glam::Vec3::X)
                    .to_array()
            })
            .collect();
        let sp = stripe_pattern(&pos, &faces, &dirs, std::f64::consts::TAU / 0.5).unwrap();
        let singular = faces.iter().filter(|f| sp.singular(&pos, **f) != 0).count();
        assert!(singular >= 1);
        assert!(sp.energy > 0.0);
    }

    #[test]
    fn vertices_in_no_face_are_harmless() {
        let (mut pos, faces) = grid(6, 6, 0.1);
        pos.push([5.0, 5.0, 5.0]);
        let dirs = vec![[1.0, 0.0, 0.0]; pos.len()];
        let sp = stripe_pattern(&pos, &faces, &dirs, std::f64::consts::TAU / 0.3).unwrap();
        assert_eq!(sp.psi.len(), pos.len());
        assert!(faces.iter().all(|f| sp.singular(&pos, *f) == 0));
    }

    #[test]
    fn bad_input_is_an_error() {
        let (pos, faces) = grid(2, 2, 1.0);
        let dirs = vec![[1.0, 0.0, 0.0]; pos.len()];
        assert!(stripe_pattern(&pos, &faces, &dirs[1..], 1.0).is_err());
        assert!(stripe_pattern(&pos, &faces, &dirs, 0.0).is_err());
        assert!(stripe_pattern(&pos, &faces, &dirs, f64::NAN).is_err());
    }
}
