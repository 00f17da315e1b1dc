//! A smooth colour offset that carries a pasted patch into the texture around it where the
//! two differ in their low frequencies: the membrane of gradient-domain compositing (Pérez,
//! Gangnet & Blake 2003; as a boundary interpolant, Farbman et al. 2009), kept to the patch's
//! rim.
//!
//! The seam ([`super::seam`]) hides a patch's border where the old texture and the new patch
//! agree. On an image whose colour changes across its extent (a gradient, a sky, light
//! falling off) no two placements agree in their mean colour, so every seam crosses a step
//! and the surface reads as a patchwork of discs. The step is low-frequency: the offset
//! between the two images' local means. It is measured along the patch's edge (its seam, or
//! nearer where the patch runs off the image), smoothed around it, and added to the new
//! patch's colours, fully at the edge and fading to nothing a fixed share of the rim's radius
//! inside it:
//! 1. each covered texel near the edge, on either side, adds its old-minus-new colour to its
//!    angle;
//! 2. the sums and counts are smoothed around the circle (a Gaussian over a forty-eighth of a
//!    turn), so what is carried over is the offset between the two images' means, not their
//!    grain; where the edge runs over texels nothing covered yet (nothing to meet) the offset
//!    fades to zero;
//! 3. an offset no larger than the image's own steps ([`image_step`]: a stone's edge, a dot on
//!    its ground, a brick against mortar) may be the image's and is left alone; one beyond
//!    twice them is carried over fully, with a smoothstep between;
//! 4. a texel at relative radius `s` takes the offset at its angle times a smoothstep that is
//!    1 at the edge and 0 at [`WIDTH`] inside it.
//!
//! Unlike Poisson compositing the patch's core keeps its own colours: an offset carried into
//! the whole patch would pull every patch toward its neighbours' mean and flatten the image's
//! range. On an image with edges of its own (bricks, bark, dots, stones) step 3 leaves the
//! result as it was, and on one with soft features (ink clouds) lets a few seams through; on a
//! smooth one (a gradient, a sky) the seams' steps become ramps as wide as a patch's rim.

use std::f32::consts::TAU;

use super::pyramid::Img;

/// How far inside the seam (in `s`, the radius over the rim's) the offset fades to zero.
pub(super) const WIDTH: f32 = 0.45;
/// The half-width of the band around the seam whose texels measure the offset (in `s`).
const BAND: f32 = 0.08;
/// The Gaussian's standard deviation around the circle, in turns.
const SIGMA: f32 = 1.0 / 48.0;

/// The offset per angle around a patch's seed.
pub(super) struct Membrane {
    sum: Vec<[f32; 3]>,
    count: Vec<f32>,
}

impl Membrane {
    pub(super) fn new(angles: usize) -> Membrane {
        Membrane {
            sum: vec![[0.0; 3]; angles.max(1)],
            count: vec![0.0; angles.max(1)],
        }
    }

    /// Whether a texel at relative radius `s` lies in the band that measures the offset of an
    /// edge at `rho`: both sides of it, since a seam may run just beyond texels nothing
    /// covered (where only its outside has something to meet).
    pub(super) fn measures(s: f32, rho: f32) -> bool {
        (s - rho).abs() < BAND
    }

    fn bin(&self, angle: f32) -> usize {
        let n = self.sum.len();
        ((angle.rem_euclid(TAU) / TAU * n as f32) as usize).min(n - 1)
    }

    /// A texel in the band: `diff` is old minus new, `None` where nothing covered it.
    pub(super) fn add(&mut self, angle: f32, diff: Option<[f32; 3]>) {
        let i = self.bin(angle);
        if let Some(d) = diff {
            for (s, d) in self.sum[i].iter_mut().zip(d) {
                *s += d;
            }
            self.count[i] += 1.0;
        }
    }

    /// Steps 2 and 3: the smoothed offset per angle (zero where no texel measured it), against
    /// the image's own steps `image_step`.
    pub(super) fn solve(self, image_step: f32) -> Offsets {
        let n = self.sum.len();
        let sigma = (SIGMA * n as f32).max(0.5);
        let reach = (3.0 * sigma).ceil() as i64;
        let kernel: Vec<f32> = (-reach..=reach)
            .map(|k| (-0.5 * (k as f32 / sigma).powi(2)).exp())
            .collect();
        // where the edge runs over texels nothing covered, the offset fades to zero: a prior
        // of zero weighing a fiftieth of the best-measured angle's count
        let prior = 0.02 * self.count.iter().fold(0.0f32, |m, &c| m.max(c)) * sigma * TAU.sqrt();
        let offset = (0..n)
            .map(|i| {
                let (mut sum, mut count) = ([0.0f32; 3], prior);
                for (k, &w) in (-reach..=reach).zip(&kernel) {
                    let j = (i as i64 + k).rem_euclid(n as i64) as usize;
                    for (a, b) in sum.iter_mut().zip(self.sum[j]) {
                        *a += w * b;
                    }
                    count += w * self.count[j];
                }
                if count <= 1e-6 {
                    return [0.0; 3];
                }
                let offset = sum.map(|x| x / count);
                // step 3: an offset no larger than the steps the image itself has may be the
                // image's own; one beyond them is the seam's
                let step = offset.iter().map(|x| x * x).sum::<f32>().sqrt();
                let t = (step / image_step - 1.0).clamp(0.0, 1.0);
                let gain = t * t * (3.0 - 2.0 * t);
                offset.map(|x| x * gain)
            })
            .collect();
        Offsets { offset }
    }
}

/// The smoothed offset around a patch's seed.
pub(super) struct Offsets {
    offset: Vec<[f32; 3]>,
}

impl Offsets {
    /// Step 4: the offset a texel at `angle` and relative radius `s` takes, the seam being at
    /// `rho` there.
    pub(super) fn at(&self, angle: f32, s: f32, rho: f32) -> [f32; 3] {
        let width = WIDTH.min(rho);
        if width <= 0.0 {
            return [0.0; 3];
        }
        let t = ((s - (rho - width)) / width).clamp(0.0, 1.0);
        let w = t * t * (3.0 - 2.0 * t);
        if w <= 0.0 {
            return [0.0; 3];
        }
        // interpolated between the angles' centres
        let (i0, i1, f) = super::seam::around(self.offset.len(), angle);
        let (a, b) = (self.offset[i0], self.offset[i1]);
        [0, 1, 2].map(|k| w * (a[k] * (1.0 - f) + b[k] * f))
    }
}

/// The image's own steps: the 99th percentile of the colour difference (Euclidean over the
/// channels) between opaque pixels four apart along x or y in the image smoothed by a 5x5
/// binomial, as the offset is measured over many texels: a sharp edge counts at its full
/// height, the grain of a photograph at a fraction.
pub(super) fn image_step(image: &Img, opacity: Option<&[f32]>) -> f32 {
    const GAP: usize = 4;
    let (w, h) = (image.w, image.h);
    let smooth = image.binomial_smoothed().px;
    let opaque = |i: usize| opacity.is_none_or(|o| o[i] >= 1.0);
    let mut steps: Vec<f32> = Vec::with_capacity(2 * w * h);
    let diff = |i: usize, j: usize| {
        let (a, b) = (smooth[i], smooth[j]);
        (0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<f32>().sqrt()
    };
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            if !opaque(i) {
                continue;
            }
            if x + GAP < w && opaque(i + GAP) {
                steps.push(diff(i, i + GAP));
            }
            if y + GAP < h && opaque(i + GAP * w) {
                steps.push(diff(i, i + GAP * w));
            }
        }
    }
    if steps.is_empty() {
        return 1.0;
    }
    let k = ((steps.len() - 1) as f32 * 0.99) as usize;
    let (_, v, _) = steps.select_nth_unstable_by(k, f32::total_cmp);
    v.max(1.0 / 255.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_constant_step_is_carried_to_the_seam_and_fades_to_the_core() {
        let mut m = Membrane::new(64);
        for i in 0..640 {
            m.add(i as f32 / 640.0 * TAU, Some([0.2, -0.1, 0.0]));
        }
        let o = m.solve(0.01);
        let at_seam = o.at(1.0, 0.9, 0.9);
        assert!((at_seam[0] - 0.2).abs() < 0.005 && (at_seam[1] + 0.1).abs() < 0.005);
        let core = o.at(1.0, 0.9 - WIDTH - 0.01, 0.9);
        assert_eq!(core, [0.0; 3]);
        let mid = o.at(1.0, 0.9 - 0.5 * WIDTH, 0.9);
        assert!(mid[0] > 0.05 && mid[0] < 0.15, "{mid:?}");
    }

    #[test]
    fn grain_along_the_seam_averages_out_and_uncovered_texels_pull_to_zero() {
        // old and new differ by alternating signs (grain, not an offset)
        let mut m = Membrane::new(96);
        for i in 0..960 {
            let d = if i % 2 == 0 { 0.3 } else { -0.3 };
            m.add(i as f32 / 960.0 * TAU, Some([d; 3]));
        }
        let o = m.solve(0.01);
        for i in 0..96 {
            let v = o.at(i as f32 / 96.0 * TAU, 0.7, 0.7);
            assert!(v[0].abs() < 0.02, "angle {i}: {v:?}");
        }
        // half the seam over an uncovered region: the offset there is zero
        let mut m = Membrane::new(96);
        for i in 0..960 {
            let a = i as f32 / 960.0 * TAU;
            m.add(a, (a < std::f32::consts::PI).then_some([0.2; 3]));
        }
        let o = m.solve(0.01);
        assert!(o.at(0.5 * std::f32::consts::PI, 0.8, 0.8)[0] > 0.19);
        assert!(o.at(1.5 * std::f32::consts::PI, 0.8, 0.8)[0].abs() < 0.01);
    }

    #[test]
    fn an_offset_within_the_images_own_steps_is_left_alone() {
        let step = |d: f32| {
            let mut m = Membrane::new(32);
            for i in 0..320 {
                m.add(i as f32 / 320.0 * TAU, Some([d, 0.0, 0.0]));
            }
            m.solve(0.1).at(0.0, 0.9, 0.9)[0]
        };
        assert_eq!(step(0.08), 0.0);
        assert!(step(0.15) > 0.0 && step(0.15) < 0.15);
        assert!((step(0.3) - 0.3).abs() < 0.01);
    }

    #[test]
    fn a_sharp_edge_is_a_step_of_the_image_and_a_gradient_is_none() {
        let (w, h) = (64, 64);
        let img = |f: &dyn Fn(usize, usize) -> f32| Img {
            w,
            h,
            px: (0..w * h).map(|i| [f(i % w, i / w); 3]).collect(),
        };
        // stripes 8 pixels wide, 0.2 and 0.7: a fifth of pixel pairs four apart cross an edge
        let stripes = img(&|x, _| if (x / 8) % 2 == 0 { 0.2 } else { 0.7 });
        let edge = image_step(&stripes, None);
        // the edge's height, 0.5 in each channel, less the smoothing's tail
        let height = 0.5 * 3f32.sqrt();
        assert!(edge > 0.9 * height && edge <= height + 1e-5, "{edge}");
        let gradient = img(&|x, y| (x + y) as f32 / 126.0);
        let smooth = image_step(&gradient, None);
        assert!(smooth < 0.06, "{smooth}");
    }
}
