//! Thickness: the mean distance from a surface point to the other side of the object along
//! rays cast inwards, as the thickness bakes of texturing tools (Substance Painter, Blender's
//! "thickness" AO) compute it for translucency and wear masks.
//!
//! Per vertex, `rays` directions stratified over the hemisphere of the inward normal `-n`,
//! cosine-weighted (a jittered `rows × cols` grid in `(cos² θ, φ)`, seeded per vertex so the
//! result does not depend on thread scheduling), are cast from `p - ε n` (`ε = 1e-4 × bbox
//! diagonal`) against the closest-hit query of [`OcclusionBvh`]; the thickness is the mean
//! distance of the rays that hit. Rays that leave an open mesh through a hole do not count; a
//! vertex none of whose rays hit (or with a zero normal) gets `NaN`.

use glam::Vec3;
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};
use rayon::prelude::*;

use super::OcclusionBvh;
use super::occlusion::{frame, strata};
use crate::error::Result;
use crate::work::CancelToken;

/// Thickness (mean inward ray distance, mesh units) of every vertex `positions[v]` with unit
/// normal `normals[v]` against the surface in `bvh` (see the module doc), `rays` rays per vertex
/// (rounded up to fill the strata grid), seed `seed`; checks `cancel` between batches.
pub fn thickness(
    bvh: &OcclusionBvh,
    positions: &[[f32; 3]],
    normals: &[[f32; 3]],
    rays: usize,
    seed: u64,
    cancel: &CancelToken,
) -> Result<Vec<f32>> {
    let n = positions.len().min(normals.len());
    let (rows, cols) = strata(rays);
    let eps = super::occlusion::ray_offset(positions);
    let mut out = vec![f32::NAN; n];
    const BATCH: usize = 2048;
    for (bi, chunk) in out.chunks_mut(BATCH).enumerate() {
        cancel.check()?;
        chunk.par_iter_mut().enumerate().for_each(|(i, o)| {
            let v = bi * BATCH + i;
            let nrm = -Vec3::from(normals[v]);
            let p = Vec3::from(positions[v]);
            if nrm.length_squared().is_nan() || nrm.length_squared() <= 0.5 || !p.is_finite() {
                return;
            }
            let (t, b) = frame(nrm);
            let origin = p + eps * nrm;
            let mut rng = SmallRng::seed_from_u64(
                seed ^ (v as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15) ^ 0x7468_6963,
            );
            let (mut sum, mut hits) = (0.0f32, 0u32);
            for r in 0..rows {
                for c in 0..cols {
                    // cosine-weighted: sin² θ uniform in the strata
                    let s2 = (r as f32 + rng.random::<f32>()) / rows as f32;
                    let phi =
                        std::f32::consts::TAU * (c as f32 + rng.random::<f32>()) / cols as f32;
                    let s = s2.sqrt();
                    let z = (1.0 - s2).max(0.0).sqrt();
                    let d = t * (s * phi.cos()) + b * (s * phi.sin()) + nrm * z;
                    if let Some(dist) = bvh.first_hit(origin, d, f32::INFINITY) {
                        sum += dist;
                        hits += 1;
                    }
                }
            }
            if hits > 0 {
                *o = sum / hits as f32 + eps;
            }
        });
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::testdata::cuboid;

    #[test]
    fn a_thin_slab_is_thinner_than_a_thick_one_and_close_to_its_depth() {
        // The centre of the large face of a 10 × 10 × h slab, normal -z: rays inwards mostly
        // cross the slab's depth h (cosine-weighted, mean 1/cos θ stretches it to about 2h).
        let probe = |h: f32| {
            let (pos, faces) = cuboid(10.0, 10.0, h);
            let bvh = OcclusionBvh::new(&pos, &faces);
            let t = thickness(
                &bvh,
                &[[5.0, 5.0, 0.0]],
                &[[0.0, 0.0, -1.0]],
                256,
                1,
                &CancelToken::new(),
            )
            .unwrap();
            t[0]
        };
        let (thin, thick) = (probe(0.1), probe(1.0));
        assert!(thin > 0.1 && thin < 0.3, "thin slab {thin}");
        assert!(thick > 1.0 && thick < 3.0, "thick slab {thick}");
        assert!(thick > 5.0 * thin, "{thin} vs {thick}");
    }

    #[test]
    fn an_open_plane_has_no_thickness() {
        let pos = vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        let bvh = OcclusionBvh::new(&pos, &[[0, 1, 2]]);
        let t = thickness(
            &bvh,
            &[[0.3, 0.3, 0.0]],
            &[[0.0, 0.0, 1.0]],
            16,
            0,
            &CancelToken::new(),
        )
        .unwrap();
        assert!(t[0].is_nan(), "{}", t[0]);
    }
}
