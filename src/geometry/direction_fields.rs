//! Smooth tangent direction fields (Knöppel, Crane, Pinkall & Schröder 2013, "Globally Optimal
//! Direction Fields", §5 with the alignment term of §6.1): the vector field nearest a guide
//! field among the smooth ones, from one sparse linear solve.
//!
//! Unknowns are one complex number per vertex in its tangent frame ([`super::tangent_frames`]);
//! the energy is `Σ_ij w_ij |x_i − e^{i ρ_ij} x_j|²` (cotangent weights `w_ij`, negative per-face
//! weights clamped to 0, `ρ_ij` the discrete Levi-Civita transport of
//! [`super::transport_angle`]). Minimising it plus `t |x − g|²_M` gives
//! `(A + t M) x = t M g`: with `t = 1 / ℓ²` the result follows the guide `g` at scales above
//! `ℓ` and is as smooth as the surface allows below it, so the guide's jumps and
//! spread-out singularities become isolated points.

use faer::linalg::solvers::Solve;
use faer::sparse::linalg::solvers::Llt;
use faer::sparse::{SparseColMat, Triplet};
use faer::{MatMut, Side};
use glam::Vec3;

use super::basic::d3;
use super::frames::{FrameRule, tangent_frames, transport_angle};
use super::laplacian::{check_faces, face_cot_weights, mass_matrix_barycentric};
use crate::error::{Error, Result};

/// The unit tangent field nearest `guide` (one per vertex, projected onto each tangent plane)
/// that is smooth at scales below `length`. `normals` are unit vertex normals. Vertices where
/// the solve gives exactly zero (or a non-finite value) keep their projected guide.
pub fn smooth_direction_field(
    positions: &[[f32; 3]],
    faces: &[[u32; 3]],
    normals: &[[f32; 3]],
    guide: &[[f32; 3]],
    length: f64,
) -> Result<Vec<[f32; 3]>> {
    let n = positions.len();
    check_faces(n, faces)?;
    if normals.len() != n || guide.len() != n {
        return Err(Error::InvalidInput(format!(
            "direction field: {} normals and {} guide vectors for {n} vertices",
            normals.len(),
            guide.len()
        )));
    }
    if !(length.is_finite() && length > 0.0) {
        return Err(Error::InvalidInput(format!(
            "direction field: length must be positive (got {length})"
        )));
    }
    let frames = tangent_frames(normals, FrameRule::Duff);
    let mass = mass_matrix_barycentric(positions, faces);
    let t = 1.0 / (length * length);
    let mut trip: Vec<Triplet<usize, usize, f64>> = Vec::with_capacity(faces.len() * 3 * 12);
    for f in faces {
        let p = f.map(|i| d3(positions[i as usize]));
        let w = face_cot_weights(p);
        for k in 0..3 {
            let wk = w[k].max(0.0);
            if !(wk > 0.0 && wk.is_finite()) {
                continue;
            }
            let (i, j) = (f[(k + 1) % 3] as usize, f[(k + 2) % 3] as usize);
            let (ni, nj) = (Vec3::from(normals[i]), Vec3::from(normals[j]));
            let rho = transport_angle(FrameRule::Duff, nj, frames.get(j), ni, frames.get(i)) as f64;
            let (c, s) = (rho.cos(), rho.sin());
            for d in 0..2 {
                trip.push(Triplet::new(2 * i + d, 2 * i + d, wk));
                trip.push(Triplet::new(2 * j + d, 2 * j + d, wk));
            }
            // block (i, j) = -w R(ρ_ij), block (j, i) = its transpose
            let r = [[c, -s], [s, c]];
            for (a, row) in r.iter().enumerate() {
                for (b, &rab) in row.iter().enumerate() {
                    trip.push(Triplet::new(2 * i + a, 2 * j + b, -wk * rab));
                    trip.push(Triplet::new(2 * j + b, 2 * i + a, -wk * rab));
                }
            }
        }
    }
    // guide in frame coordinates, right-hand side t M g
    let g: Vec<[f64; 2]> = (0..n)
        .map(|i| {
            let gi = Vec3::from(guide[i]);
            let (t1, t2) = frames.get(i);
            let (x, y) = (gi.dot(t1) as f64, gi.dot(t2) as f64);
            let r = (x * x + y * y).sqrt();
            if r > 0.0 && r.is_finite() {
                [x / r, y / r]
            } else {
                [0.0, 0.0]
            }
        })
        .collect();
    let mut rhs = vec![0.0; 2 * n];
    for i in 0..n {
        let m = if mass[i] > 0.0 { t * mass[i] } else { 1.0 };
        trip.push(Triplet::new(2 * i, 2 * i, m));
        trip.push(Triplet::new(2 * i + 1, 2 * i + 1, m));
        rhs[2 * i] = m * g[i][0];
        rhs[2 * i + 1] = m * g[i][1];
    }
    let a = SparseColMat::<usize, f64>::try_new_from_triplets(2 * n, 2 * n, &trip)
        .map_err(|e| Error::InvalidMesh(format!("direction field matrix: {e:?}")))?;
    let llt: Llt<usize, f64> = a
        .sp_cholesky(Side::Lower)
        .map_err(|e| Error::InvalidMesh(format!("direction field: Cholesky failed: {e:?}")))?;
    llt.solve_in_place(MatMut::from_column_major_slice_mut(&mut rhs, 2 * n, 1));
    Ok((0..n)
        .map(|i| {
            let (t1, t2) = frames.get(i);
            let (x, y) = (rhs[2 * i] as f32, rhs[2 * i + 1] as f32);
            let v = t1 * x + t2 * y;
            let fallback = t1 * g[i][0] as f32 + t2 * g[i][1] as f32;
            v.try_normalize()
                .or_else(|| fallback.try_normalize())
                .unwrap_or(t1)
                .to_array()
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_smooth_guide_on_a_plane_is_kept_and_a_jump_is_smoothed() {
        let (nx, ny, h) = (30usize, 20usize, 0.1f32);
        let (pos, faces) = crate::testdata::grid_cells(nx, ny, h);
        let id = |i: usize, j: usize| (j * (nx + 1) + i) as u32;
        let normals = vec![[0.0, 0.0, 1.0]; pos.len()];
        let along = vec![[1.0, 0.0, 0.0]; pos.len()];
        let out = smooth_direction_field(&pos, &faces, &normals, &along, 0.5).unwrap();
        for d in &out {
            assert!((Vec3::from(*d) - Vec3::X).length() < 1e-4);
        }
        // a 90 degree jump at x = 1.5: smoothed into a gradual turn across it
        let jump: Vec<[f32; 3]> = pos
            .iter()
            .map(|p| {
                if p[0] < 1.5 {
                    [1.0, 0.0, 0.0]
                } else {
                    [0.0, 1.0, 0.0]
                }
            })
            .collect();
        let out = smooth_direction_field(&pos, &faces, &normals, &jump, 0.5).unwrap();
        let angle = |i: usize, j: usize| {
            let d = Vec3::from(out[id(i, j) as usize]);
            d.y.atan2(d.x)
        };
        // monotone turn from near 0 to near 90 degrees along a row, no step above 20 degrees
        let mut last = angle(0, 10);
        assert!(last.abs() < 0.2);
        for i in 1..=nx {
            let a = angle(i, 10);
            assert!(
                a >= last - 1e-4 && a - last < 20f32.to_radians(),
                "column {i}"
            );
            last = a;
        }
        assert!((last - std::f32::consts::FRAC_PI_2).abs() < 0.2);
    }
}
