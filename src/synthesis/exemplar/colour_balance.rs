//! The texture's colour make-up against the image's, part by part of the image: which parts of
//! the image bring colours the texture already shows more of than the image has, and which bring
//! colours it lacks.
//!
//! Patch pasting ([`super::patch_pasting`]) counts, for each cell of a grid over the image, how
//! many texels show that cell. Evening out those counts keeps every part of the image in use, but
//! it is blind to colour: on a stationary image (bricks, bark) two cells hold the same colours,
//! and preferring one over the other only costs seams; on a non-stationary one (a sky's gradient,
//! a cluster of dots on a plain ground) the cells that overlap matching tends to avoid (the
//! image's extremes, usually near its border) hold colours nothing else has, and the texture's
//! colour distribution drifts from the image's.
//!
//! Here each cell is represented by its mean colour. The image's colour density at a cell is a
//! kernel sum over all cells' mean colours weighted by their opaque area; the texture's is the
//! same sum weighted by the texels showing each cell. Their ratio, per cell, is above 1 where
//! the texture shows that cell's colours more than the image does and below 1 where it lacks
//! them. Cells of similar colour share one ratio, so on a stationary image the ratios stay near
//! 1 wherever the texture reads, and the term leaves placement to the overlap match.

use super::pyramid::Img;

/// The kernel's bandwidth squared, as a fraction of the image's colour variance (summed over
/// the channels): cells whose mean colours differ by about a fifth of the image's spread count
/// as the same colour.
pub(super) const BANDWIDTH2: f32 = 0.05;

/// A cell holding less than this share of a cell's mean opaque area (a cell inside a hole) is
/// left neutral: its mean colour says nothing.
const MIN_OPAQUE: f64 = 0.05;

/// Cells' colours and the image's colour density at each, for a `cells` x `cells` grid over the
/// image.
pub(super) struct ColourBalance {
    cells: usize,
    /// The cells' mean colours.
    mean: Vec<[f32; 3]>,
    /// The kernel's bandwidth squared.
    h2: f32,
    /// `cells⁴` Gaussian weights between the cells' mean colours (row-major, symmetric).
    kernel: Vec<f32>,
    /// The image's colour density at each cell's mean colour (0: a neutral cell).
    image_density: Vec<f32>,
}

impl ColourBalance {
    /// The grid's cells over `image` (pixels weighted by `opacity`, all opaque without it);
    /// `variance` is the image's colour variance, the kernel's scale.
    pub(super) fn new(
        image: &Img,
        opacity: Option<&[f32]>,
        cells: usize,
        variance: f32,
    ) -> ColourBalance {
        let n = cells * cells;
        let (mut sum, mut weight) = (vec![[0.0f64; 3]; n], vec![0.0f64; n]);
        for y in 0..image.h {
            let cy = (y * cells / image.h).min(cells - 1);
            for x in 0..image.w {
                let cx = (x * cells / image.w).min(cells - 1);
                let i = y * image.w + x;
                let a = opacity.map_or(1.0, |o| o[i]) as f64;
                let c = cy * cells + cx;
                weight[c] += a;
                for (s, &v) in sum[c].iter_mut().zip(&image.px[i]) {
                    *s += a * v as f64;
                }
            }
        }
        let mean: Vec<[f32; 3]> = (0..n)
            .map(|c| sum[c].map(|v| (v / weight[c].max(1e-9)) as f32))
            .collect();
        let h2 = (BANDWIDTH2 * variance).max(1e-6);
        let mut kernel = vec![0.0f32; n * n];
        for a in 0..n {
            for b in a..n {
                let d: f32 = (0..3).map(|k| (mean[a][k] - mean[b][k]).powi(2)).sum();
                let g = (-0.5 * d / h2).exp();
                kernel[a * n + b] = g;
                kernel[b * n + a] = g;
            }
        }
        let total: f64 = weight.iter().sum::<f64>().max(1e-9);
        let floor = MIN_OPAQUE * total / n as f64;
        let share: Vec<f32> = weight.iter().map(|&w| (w / total) as f32).collect();
        let image_density = (0..n)
            .map(|a| {
                if weight[a] < floor {
                    return 0.0;
                }
                (0..n).map(|b| kernel[a * n + b] * share[b]).sum::<f32>()
            })
            .collect();
        ColourBalance {
            cells,
            mean,
            h2,
            kernel,
            image_density,
        }
    }

    /// Per cell, the texture's colour density at the cell's colour over the image's, given the
    /// texels showing each cell (`usage`) and the sum of the colour offsets those texels carry
    /// (`shift`, [`super::membrane`]: a cell's texels show its mean colour plus their mean
    /// offset), into `out`: 1 for a neutral cell, and for all while nothing is shown.
    pub(super) fn ratios(&self, usage: &[f32], shift: &[[f32; 3]], out: &mut Vec<f32>) {
        let n = self.cells * self.cells;
        out.clear();
        let total: f32 = usage.iter().sum();
        if total <= 0.0 {
            out.resize(n, 1.0);
            return;
        }
        // the cells whose texels show colours off their mean: their colour as shown
        let shown: Vec<(usize, [f32; 3])> = (0..n)
            .filter(|&b| usage[b] > 0.0 && shift[b] != [0.0; 3])
            .map(|b| {
                (
                    b,
                    [0, 1, 2].map(|k| self.mean[b][k] + shift[b][k] / usage[b]),
                )
            })
            .collect();
        out.extend((0..n).map(|a| {
            let img = self.image_density[a];
            if img <= 0.0 {
                return 1.0;
            }
            let row = &self.kernel[a * n..(a + 1) * n];
            let mut tex: f32 = row.iter().zip(usage).map(|(k, u)| k * u).sum::<f32>();
            for &(b, c) in &shown {
                let d: f32 = (0..3).map(|k| (self.mean[a][k] - c[k]).powi(2)).sum();
                tex += usage[b] * ((-0.5 * d / self.h2).exp() - row[b]);
            }
            tex.max(0.0) / total / img
        }));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 64² vertical gradient: its rows are distinct colours.
    fn vertical_gradient() -> Img {
        let (w, h) = (64, 64);
        let px = (0..w * h)
            .map(|i| {
                let t = (i / w) as f32 / (h - 1) as f32;
                [t, 0.5, 1.0 - t]
            })
            .collect();
        Img { w, h, px }
    }

    /// A vertical gradient: its rows are distinct colours, so a texture that shows only the
    /// middle rows lacks the top's and bottom's colours and over-shows the middle's.
    #[test]
    fn a_texture_showing_only_the_middle_of_a_gradient_lacks_its_ends() {
        let image = vertical_gradient();
        let variance = 2.0 * (1.0f32 / 12.0);
        let cells = 8;
        let balance = ColourBalance::new(&image, None, cells, variance);
        let no_shift = vec![[0.0; 3]; cells * cells];
        let mut usage = vec![0.0; cells * cells];
        for row in 3..5 {
            for c in 0..cells {
                usage[row * cells + c] = 10.0;
            }
        }
        let mut ratios = Vec::new();
        balance.ratios(&usage, &no_shift, &mut ratios);
        let row_mean = |r: usize| ratios[r * cells..(r + 1) * cells].iter().sum::<f32>() / 8.0;
        assert!(row_mean(0) < 0.1 && row_mean(7) < 0.1, "{ratios:?}");
        assert!(row_mean(3) > 2.0 && row_mean(4) > 2.0, "{ratios:?}");
        // all of the image in use: balanced everywhere
        balance.ratios(&vec![1.0; cells * cells], &no_shift, &mut ratios);
        assert!(ratios.iter().all(|r| (r - 1.0).abs() < 0.2), "{ratios:?}");
    }

    /// A stationary image: every cell holds the same two colours, so however unevenly the
    /// texture uses the cells, its colours stay balanced.
    #[test]
    fn uneven_use_of_a_stationary_image_stays_balanced() {
        let (w, h) = (64, 64);
        let px = (0..w * h)
            .map(|i| {
                let (x, y) = (i % w, i / w);
                if (x / 2 + y / 2) % 2 == 0 {
                    [0.9, 0.2, 0.1]
                } else {
                    [0.3, 0.3, 0.3]
                }
            })
            .collect();
        let image = Img { w, h, px };
        let cells = 8;
        let balance = ColourBalance::new(&image, None, cells, 0.2);
        let no_shift = vec![[0.0; 3]; cells * cells];
        let mut usage = vec![0.0; cells * cells];
        usage[9] = 100.0;
        let mut ratios = Vec::new();
        balance.ratios(&usage, &no_shift, &mut ratios);
        assert!(ratios.iter().all(|r| (r - 1.0).abs() < 0.05), "{ratios:?}");
    }

    /// The ends of a gradient in use, but their texels shifted towards the middle's colour (a
    /// seam's offset carried into them): the texture shows the middle, and lacks the ends.
    #[test]
    fn texels_shifted_off_their_cells_colour_count_as_the_colour_they_show() {
        let image = vertical_gradient();
        let cells = 8;
        let balance = ColourBalance::new(&image, None, cells, 2.0 * (1.0f32 / 12.0));
        let usage = vec![1.0; cells * cells];
        let mut shift = vec![[0.0; 3]; cells * cells];
        let mut ratios = Vec::new();
        balance.ratios(&usage, &shift, &mut ratios);
        assert!(ratios.iter().all(|r| (r - 1.0).abs() < 0.2), "{ratios:?}");
        // rows 0 and 7 shown as rows 3 and 4
        for c in 0..cells {
            shift[c] = [3.0 / 7.0, 0.0, -3.0 / 7.0];
            shift[7 * cells + c] = [-3.0 / 7.0, 0.0, 3.0 / 7.0];
        }
        balance.ratios(&usage, &shift, &mut ratios);
        let row_mean = |r: usize| ratios[r * cells..(r + 1) * cells].iter().sum::<f32>() / 8.0;
        assert!(row_mean(0) < 0.7 && row_mean(7) < 0.7, "{ratios:?}");
        assert!(row_mean(3) > 1.2 && row_mean(4) > 1.2, "{ratios:?}");
    }
}
