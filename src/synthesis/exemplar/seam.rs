//! The seam where a pasted patch meets what is already on the surface: Efros & Freeman 2001's
//! minimum-error boundary cut, closed around a disc.
//!
//! A feathered rim blends the new patch into the old texture over a band several pixels wide;
//! inside the band both images show at once (ghosting), which neither the image nor its
//! contrast has. Instead, the patch keeps its texels up to a closed seam around its seed and the
//! old texture is kept beyond it, the seam running where the two agree best:
//! 1. the patch's disc is divided into a polar grid over `s`, the radius as a fraction of the
//!    splotch's rim in that direction (so the last ring follows the wobbling rim);
//! 2. each cell sums the squared colour difference between the old texel and the new one over
//!    its covered texels; a texel nothing covers yet forces the seam beyond its ring, so the
//!    patch fills every hole it was started for;
//! 3. the seam is one ring per angle, moving at most [`MAX_STEP`] rings between neighbouring
//!    angles, closed around the disc, of least total cost (a cell's mean difference times its
//!    ring's length, and a step across rings costs the cells it runs through radially, so the
//!    seam does not zigzag): dynamic programming over the angles from each start ring;
//! 4. a texel's alpha falls from 1 to 0 across the seam over about two image pixels (at most
//!    a tenth of the rim's radius), so the seam is not aliased where texels are as fine as the
//!    image's pixels, where the seam runs through agreement; where no closed seam avoids a
//!    mismatch (brick courses that do not line up), the ramp widens with the mismatch the seam
//!    crosses there ([`Seam::mismatch`]) up to the splotch's feathered rim, so a break that
//!    cannot be hidden by the cut is feathered instead (as Kwatra et al. 2003 feather seams the cut cannot hide).
//!
//! A cell no texel fell in costs nothing: at the default texture size a texel is finer than a
//! cell, so that happens where the patch has no faces. Where texels are much coarser than the
//! image's pixels (a small `--texture-size` for the image's scale) empty inner cells let the
//! seam shrink a patch toward its core; filling them with their angle's mean was tried and
//! raised the colour distance (W1) on the three dot images (cat 0.77 -> 1.43, Igea 0.90 ->
//! 2.01, cow 1.99 -> 2.59) at the default size.
//!
//! Where old and new agree everywhere the seam stays at the rim, which is the feathered splotch
//! as before.

/// Rings the seam may move between neighbouring angles.
const MAX_STEP: usize = 2;

/// The polar grid of seam costs of one patch.
pub(super) struct SeamCosts {
    angles: usize,
    rings: usize,
    /// Innermost `s` the seam may reach: the core always shows the new patch.
    inner: f32,
    cost: Vec<f32>,
    count: Vec<u32>,
    /// Per angle, the outermost ring holding an uncovered texel (the seam must lie beyond it).
    forced: Vec<i32>,
}

impl SeamCosts {
    pub(super) fn new(angles: usize, rings: usize, inner: f32) -> SeamCosts {
        SeamCosts {
            angles,
            rings,
            inner,
            cost: vec![0.0; angles * rings],
            count: vec![0; angles * rings],
            forced: vec![-1; angles],
        }
    }

    /// The cell of a texel at `angle` (radians) and relative radius `s`; `None` inside the core.
    fn cell(&self, angle: f32, s: f32) -> Option<(usize, usize)> {
        if s < self.inner {
            return None;
        }
        let a = angle.rem_euclid(std::f32::consts::TAU) / std::f32::consts::TAU;
        let i = ((a * self.angles as f32) as usize).min(self.angles - 1);
        let r = (((s - self.inner) / (1.0 - self.inner)) * self.rings as f32) as usize;
        Some((i, r.min(self.rings - 1)))
    }

    /// A covered texel whose old and new colours differ by `diff2` (squared).
    pub(super) fn add(&mut self, angle: f32, s: f32, diff2: f32) {
        if let Some((i, r)) = self.cell(angle, s) {
            self.cost[i * self.rings + r] += diff2;
            self.count[i * self.rings + r] += 1;
        }
    }

    /// A texel nothing covers yet: the seam passes beyond it.
    pub(super) fn force(&mut self, angle: f32, s: f32) {
        if let Some((i, r)) = self.cell(angle, s) {
            self.forced[i] = self.forced[i].max(r as i32);
        }
    }

    /// The seam: per angle, the `s` it passes at (the middle of its ring).
    pub(super) fn cut(&self) -> Seam {
        let (na, nr) = (self.angles, self.rings);
        // nothing covered under the patch: the whole patch shows, up to its feathered rim
        if self.count.iter().all(|&c| c == 0) {
            return Seam {
                rho: vec![1.0; na],
                mismatch: vec![0.0; na],
            };
        }
        let ring_s = |r: usize| self.inner + (r as f32 + 0.5) / nr as f32 * (1.0 - self.inner);
        // a cell's cost: its mean difference along the seam's length there; a ring's own length
        // breaks ties toward the rim, so agreeing textures keep the whole patch
        let cell_cost: Vec<f32> = (0..na * nr)
            .map(|k| {
                let r = k % nr;
                let allowed = r as i32 > self.forced[k / nr] || r == nr - 1;
                if !allowed {
                    return f32::INFINITY;
                }
                let mean = if self.count[k] > 0 {
                    self.cost[k] / self.count[k] as f32
                } else {
                    0.0
                };
                mean * ring_s(r) + 1e-6 * (nr - 1 - r) as f32
            })
            .collect();
        // a step across rings runs the seam radially through them too
        let step = |i: usize, r: usize, j: usize, p: usize| {
            p.abs_diff(r) as f32 * 0.5 * (cell_cost[i * nr + r] + cell_cost[j * nr + p])
        };
        let mut best: (f32, Vec<usize>) = (f32::INFINITY, Vec::new());
        let mut acc = vec![0.0f32; nr];
        let mut next = vec![0.0f32; nr];
        let mut from = vec![0u16; na * nr];
        for r0 in 0..nr {
            if !cell_cost[r0].is_finite() {
                continue;
            }
            acc.fill(f32::INFINITY);
            acc[r0] = cell_cost[r0];
            for i in 1..na {
                for r in 0..nr {
                    let lo = r.saturating_sub(MAX_STEP);
                    let hi = (r + MAX_STEP).min(nr - 1);
                    let (mut m, mut arg) = (f32::INFINITY, r);
                    for (p, &v) in acc.iter().enumerate().take(hi + 1).skip(lo) {
                        let total = v + step(i, r, i - 1, p);
                        if total < m {
                            m = total;
                            arg = p;
                        }
                    }
                    next[r] = m + cell_cost[i * nr + r];
                    from[i * nr + r] = arg as u16;
                }
                std::mem::swap(&mut acc, &mut next);
            }
            // closed: the last angle's ring within a step of the first's
            let lo = r0.saturating_sub(MAX_STEP);
            let hi = (r0 + MAX_STEP).min(nr - 1);
            for (r, &v) in acc.iter().enumerate().take(hi + 1).skip(lo) {
                let total = v + step(0, r0, na - 1, r);
                if total < best.0 {
                    let mut path = vec![0usize; na];
                    path[na - 1] = r;
                    for i in (1..na).rev() {
                        path[i - 1] = from[i * nr + path[i]] as usize;
                    }
                    best = (total, path);
                }
            }
        }
        if best.1.is_empty() {
            return Seam {
                rho: vec![1.0; na],
                mismatch: vec![0.0; na],
            };
        }
        // the outermost ring stands for the rim itself: the splotch's feather ends the patch
        let rho = best
            .1
            .iter()
            .map(|&r| if r == nr - 1 { 1.0 } else { ring_s(r) })
            .collect();
        let mismatch = best
            .1
            .iter()
            .enumerate()
            .map(|(i, &r)| {
                let k = i * nr + r;
                if r == nr - 1 || self.count[k] == 0 {
                    0.0
                } else {
                    self.cost[k] / self.count[k] as f32
                }
            })
            .collect();
        Seam { rho, mismatch }
    }
}

/// A closed seam around a patch's seed.
pub(super) struct Seam {
    rho: Vec<f32>,
    /// The mean squared colour difference between old and new in the seam's cell at each
    /// angle (0 on the rim).
    mismatch: Vec<f32>,
}

impl Seam {
    /// How much of the new patch shows at `angle` and relative radius `s`: 1 inside the seam,
    /// 0 beyond it, a ramp `blend` wide (in `s`) across it; the seam is interpolated between
    /// the angles' centres.
    pub(super) fn alpha(&self, angle: f32, s: f32, blend: f32) -> f32 {
        let rho = self.lerp(&self.rho, angle);
        if rho >= 1.0 {
            return 1.0;
        }
        ((rho - s) / blend.max(1e-6) + 0.5).clamp(0.0, 1.0)
    }

    /// The relative radius the seam passes at `angle` (1 on the rim).
    pub(super) fn rho(&self, angle: f32) -> f32 {
        self.lerp(&self.rho, angle)
    }

    /// The mean squared colour difference between old and new where the seam runs at `angle`
    /// (0 where it runs on the rim).
    pub(super) fn mismatch(&self, angle: f32) -> f32 {
        self.lerp(&self.mismatch, angle)
    }

    /// A per-angle value at `angle`, interpolated between the angles' centres.
    fn lerp(&self, v: &[f32], angle: f32) -> f32 {
        let (i0, i1, t) = around(v.len(), angle);
        v[i0] * (1.0 - t) + v[i1] * t
    }
}

/// Where `angle` (radians) falls among `n` values per angle, each at the centre of its turn's
/// `n`th: the two neighbouring indices and the weight of the second.
pub(super) fn around(n: usize, angle: f32) -> (usize, usize, f32) {
    let x = angle.rem_euclid(std::f32::consts::TAU) / std::f32::consts::TAU * n as f32 - 0.5;
    let i0 = x.floor();
    let t = x - i0;
    let i0 = (i0 as i64).rem_euclid(n as i64) as usize;
    (i0, (i0 + 1) % n, t)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f32::consts::TAU;

    /// A `na x nr` grid (inner radius 0.25) with difference `d(angle index, s)` at every
    /// cell's centre.
    fn costs(na: usize, nr: usize, d: impl Fn(usize, f32) -> f32) -> SeamCosts {
        let mut c = SeamCosts::new(na, nr, 0.25);
        for i in 0..na {
            let a = (i as f32 + 0.5) / na as f32 * TAU;
            for r in 0..nr {
                let s = 0.25 + (r as f32 + 0.5) / nr as f32 * 0.75;
                c.add(a, s, d(i, s));
            }
        }
        c
    }

    #[test]
    fn the_seam_runs_where_old_and_new_agree_and_beyond_every_hole() {
        let (na, nr) = (32, 16);
        // old and new agree only on the ring at s = 0.5; everywhere else they differ
        let mut c = costs(
            na,
            nr,
            |_, s| if (s - 0.5).abs() < 0.03 { 0.0 } else { 1.0 },
        );
        // a hole at s = 0.8 in one direction pushes the seam out there
        c.force(0.5 / na as f32 * TAU, 0.8);
        let seam = c.cut();
        for i in 5..na - 5 {
            let a = (i as f32 + 0.5) / na as f32 * TAU;
            let inside = seam.alpha(a, 0.4, 0.01);
            let outside = seam.alpha(a, 0.7, 0.01);
            assert!(
                inside > 0.99 && outside < 0.01,
                "angle {i}: {inside} {outside}"
            );
        }
        assert!(seam.alpha(0.5 / na as f32 * TAU, 0.8, 0.01) > 0.99);
    }

    #[test]
    fn agreeing_textures_keep_the_whole_patch() {
        let mut c = SeamCosts::new(24, 12, 0.25);
        for i in 0..24 {
            c.add((i as f32 + 0.5) / 24.0 * TAU, 0.6, 0.0);
        }
        let seam = c.cut();
        assert!((0..24).all(|i| seam.alpha(i as f32 / 24.0 * TAU, 0.999, 0.01) == 1.0));
    }

    #[test]
    fn the_seam_reports_the_mismatch_it_had_to_cross() {
        let (na, nr) = (32, 16);
        // on one half old and new agree on a ring; on the other half they differ by 0.3
        // inside and by 1.0 near the rim, so the seam has to cross the mismatch there
        let c = costs(na, nr, |i, s| {
            let agree = i < na / 2 && (s - 0.5).abs() < 0.03;
            match (agree, s < 0.85) {
                (true, _) => 0.0,
                (false, true) => 0.3,
                (false, false) => 1.0,
            }
        });
        let seam = c.cut();
        let at = |i: usize| (i as f32 + 0.5) / na as f32 * TAU;
        for i in 4..na / 2 - 4 {
            assert!(
                seam.mismatch(at(i)) < 1e-6,
                "angle {i}: {}",
                seam.mismatch(at(i))
            );
        }
        for i in na / 2 + 4..na - 4 {
            let m = seam.mismatch(at(i));
            assert!((m - 0.3).abs() < 1e-4, "angle {i}: {m}");
        }
    }
}
