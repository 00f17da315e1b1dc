//! The exemplar as the optimisation reads it: pixels as floats, summed-area tables for the
//! cell means of any patch, and a count of transparent pixels.

use super::CELLS;
use crate::error::Result;

/// The exemplar as floats, with summed-area tables for cell means and a transparency count.
pub(super) struct Exemplar {
    pub(super) w: usize,
    pub(super) h: usize,
    pub(super) px: Vec<[f32; 3]>,
    /// (w+1) × (h+1) per channel, f64.
    pub(super) sat: [Vec<f64>; 3],
    /// (w+1) × (h+1): transparent pixels.
    pub(super) clear: Vec<u32>,
}

impl Exemplar {
    pub(super) fn new(img: &image::RgbImage, alpha: Option<&image::GrayImage>) -> Result<Exemplar> {
        let (w, h) = (img.width() as usize, img.height() as usize);
        let px: Vec<[f32; 3]> = match alpha {
            None => img
                .pixels()
                .map(|p| p.0.map(|c| c as f32 / 255.0))
                .collect(),
            Some(a) => crate::synthesis::exemplar::transparent_filled(img, a)?.0.px,
        };
        let mut sat = [
            vec![0.0f64; (w + 1) * (h + 1)],
            vec![0.0f64; (w + 1) * (h + 1)],
            vec![0.0f64; (w + 1) * (h + 1)],
        ];
        let mut clear = vec![0u32; (w + 1) * (h + 1)];
        for y in 0..h {
            let mut row = [0.0f64; 3];
            let mut rc = 0u32;
            for x in 0..w {
                let c = px[y * w + x];
                for k in 0..3 {
                    row[k] += c[k] as f64;
                    sat[k][(y + 1) * (w + 1) + x + 1] = sat[k][y * (w + 1) + x + 1] + row[k];
                }
                if alpha.is_some_and(|a| a.as_raw()[y * w + x] < 128) {
                    rc += 1;
                }
                clear[(y + 1) * (w + 1) + x + 1] = clear[y * (w + 1) + x + 1] + rc;
            }
        }
        Ok(Exemplar {
            w,
            h,
            px,
            sat,
            clear,
        })
    }

    /// Sum over pixels `x0..x1`, `y0..y1` of a (w+1)-wide table.
    pub(super) fn rect<T: Copy + Into<f64>>(
        &self,
        t: &[T],
        x0: usize,
        y0: usize,
        x1: usize,
        y1: usize,
    ) -> f64 {
        let s = self.w + 1;
        t[y1 * s + x1].into() - t[y0 * s + x1].into() - t[y1 * s + x0].into()
            + t[y0 * s + x0].into()
    }

    /// The pixel nearest continuous coordinates (centres at integers), clamped.
    pub(super) fn nearest(&self, x: f32, y: f32) -> [f32; 3] {
        let xi = (x.round() as isize).clamp(0, self.w as isize - 1) as usize;
        let yi = (y.round() as isize).clamp(0, self.h as isize - 1) as usize;
        self.px[yi * self.w + xi]
    }

    /// Bilinear lookup at continuous pixel coordinates (centres at integers), clamped.
    pub(super) fn bilinear(&self, x: f32, y: f32) -> [f32; 3] {
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let at = |xi: f32, yi: f32| {
            let xi = (xi as isize).clamp(0, self.w as isize - 1) as usize;
            let yi = (yi as isize).clamp(0, self.h as isize - 1) as usize;
            self.px[yi * self.w + xi]
        };
        let (a, b, c, d) = (
            at(x0, y0),
            at(x0 + 1.0, y0),
            at(x0, y0 + 1.0),
            at(x0 + 1.0, y0 + 1.0),
        );
        let mut o = [0.0; 3];
        for k in 0..3 {
            o[k] =
                (a[k] * (1.0 - fx) + b[k] * fx) * (1.0 - fy) + (c[k] * (1.0 - fx) + d[k] * fx) * fy;
        }
        o
    }

    /// The `CELLS² × 3` cell means of the `w`-patch centred at pixel `(cx, cy)` (offsets
    /// `-w/2 .. w/2` on both axes, y down as the image).
    pub(super) fn cells(&self, cx: usize, cy: usize, w: usize, out: &mut [f32]) {
        let s = w / CELLS;
        let inv = 1.0 / (s * s) as f64;
        for j in 0..CELLS {
            let y0 = cy + j * s - w / 2;
            for i in 0..CELLS {
                let x0 = cx + i * s - w / 2;
                for k in 0..3 {
                    out[(j * CELLS + i) * 3 + k] =
                        (self.rect(&self.sat[k], x0, y0, x0 + s, y0 + s) * inv) as f32;
                }
            }
        }
    }
}
