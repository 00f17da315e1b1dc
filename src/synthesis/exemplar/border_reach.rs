//! How close to each side of the image a patch's centre may come.
//!
//! Patch pasting keeps a patch's centre half a radius inside the image: a disc centred at the
//! border runs half off the image, and the half disc's straight edge is one more seam for the
//! patches around it to cover. On a stationary image (bricks, bark, dots on a ground) nothing is
//! lost by it, since the colours near the border are found further in as well. But uniformly
//! drawn discs cover a band along the border less than the middle (a pixel at the border lies
//! under about a fifth as many centres as one inside), and on an image whose colours change
//! towards a side (a sky graded from deep blue at the top to orange at the bottom, a gradient)
//! that band holds colours nothing else has: they reach the surface only in discs' rims, which
//! later patches' seams cut first, and the texture's colour distribution loses its ends.
//!
//! So each side's margin follows how well the image inside the margins holds the colours of
//! that side's band. A cell of the band is held by the inside in the share of its colour's
//! density (a Gaussian kernel over cells' mean colours, as [`super::colour_balance`]) that comes
//! from inside cells; on a stationary image that share equals the inside's share of the image.
//! A side's factor is the mean, over its band's cells (corners left out: they are two sides'),
//! of that share over [`HELD`] times the inside's area share, at most 1 each: the margin is
//! kept in full where the inside holds the band's colours well enough for the colour balance to
//! make them up, and shrinks towards the border as the band's colours become the band's alone.

use super::pyramid::Img;
use rayon::prelude::*;

/// Cells along the image's longer side (fewer on a smaller image: at most one per pixel).
const GRID: usize = 64;

/// A band cell whose colour the inside holds at this share of the inside's area share or more
/// counts as held: the colour balance ([`super::colour_balance`]) draws patches towards colours
/// the texture lacks, and makes up that much from the inside; below it the colour is the
/// band's own. (On the shared photographs, dots and bricks a side's mean is then 0.85-1; it
/// would be 0.66-0.98 counting only what the inside holds in full, since even a stationary
/// image's cells scatter about the inside's share.)
const HELD: f32 = 0.5;

/// The sides in the order of [`side_factors`]'s result.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Side {
    Left = 0,
    Right = 1,
    Top = 2,
    Bottom = 3,
}

/// For each side (left, right, top, bottom: [`Side`]), the factor in [0, 1] on a patch centre's
/// margin of `margin` pixels from that side, for `image` weighted by `opacity` (its colour
/// variance `variance`, the kernel's scale as for the colour balance's `bandwidth2`).
pub(super) fn side_factors(
    image: &Img,
    opacity: Option<&[f32]>,
    margin: f32,
    variance: f32,
    bandwidth2: f32,
) -> [f32; 4] {
    let (w, h) = (image.w as f32, image.h as f32);
    if image.w == 0 || image.h == 0 || 2.0 * margin >= w.min(h) {
        return [1.0; 4];
    }
    let cells = cells_of(image, opacity);
    // a cell's sides, by where its centre lies
    let side_of = |c: &Cell| -> [bool; 4] {
        [
            c.centre[0] < margin,
            c.centre[0] > w - margin,
            c.centre[1] < margin,
            c.centre[1] > h - margin,
        ]
    };
    let inside: Vec<bool> = cells
        .iter()
        .map(|c| !side_of(c).iter().any(|&s| s))
        .collect();
    let total: f32 = cells.iter().map(|c| c.weight).sum();
    let inside_weight: f32 = cells
        .iter()
        .zip(&inside)
        .filter(|(_, i)| **i)
        .map(|(c, _)| c.weight)
        .sum();
    if total <= 0.0 || inside_weight <= 0.0 {
        return [1.0; 4];
    }
    let inside_share = inside_weight / total;
    let h2 = (bandwidth2 * variance).max(1e-6);
    // per band cell, the share of its colour's density that inside cells bring
    let held: Vec<f32> = cells
        .par_iter()
        .zip(&inside)
        .map(|(a, &a_inside)| {
            if a_inside || a.weight <= 0.0 {
                return 0.0;
            }
            let (mut all, mut ins) = (0.0f32, 0.0f32);
            for (b, &b_inside) in cells.iter().zip(&inside) {
                let d: f32 = (0..3).map(|k| (a.colour[k] - b.colour[k]).powi(2)).sum();
                let g = b.weight * (-0.5 * d / h2).exp();
                all += g;
                if b_inside {
                    ins += g;
                }
            }
            if all > 0.0 { ins / all } else { 0.0 }
        })
        .collect();
    // each side over the cells of its band alone (a corner's cells are both sides' and neither
    // side's to judge)
    let mut factors = [1.0f32; 4];
    for (s, factor) in factors.iter_mut().enumerate() {
        let (mut sum, mut weight) = (0.0f32, 0.0f32);
        for (c, &held) in cells.iter().zip(&held) {
            let sides = side_of(c);
            if sides[s] && sides.iter().filter(|&&b| b).count() == 1 {
                sum += c.weight * (held / (HELD * inside_share)).min(1.0);
                weight += c.weight;
            }
        }
        if weight > 0.0 {
            *factor = (sum / weight).clamp(0.0, 1.0);
        }
    }
    factors
}

/// A grid cell: its centre in pixels, its mean colour and its opaque area.
struct Cell {
    centre: [f32; 2],
    colour: [f32; 3],
    weight: f32,
}

/// The image's cells, [`GRID`] along its longer side.
fn cells_of(image: &Img, opacity: Option<&[f32]>) -> Vec<Cell> {
    let long = image.w.max(image.h);
    let size = long.div_ceil(GRID).max(1);
    let (gw, gh) = (image.w.div_ceil(size), image.h.div_ceil(size));
    let mut sum = vec![[0.0f64; 3]; gw * gh];
    let mut weight = vec![0.0f64; gw * gh];
    let mut pos = vec![[0.0f64; 2]; gw * gh];
    let mut count = vec![0.0f64; gw * gh];
    for y in 0..image.h {
        for x in 0..image.w {
            let c = (y / size) * gw + x / size;
            let i = y * image.w + x;
            let a = opacity.map_or(1.0, |o| o[i]) as f64;
            weight[c] += a;
            for (s, &v) in sum[c].iter_mut().zip(&image.px[i]) {
                *s += a * v as f64;
            }
            pos[c][0] += x as f64 + 0.5;
            pos[c][1] += y as f64 + 0.5;
            count[c] += 1.0;
        }
    }
    (0..gw * gh)
        .map(|c| Cell {
            centre: pos[c].map(|p| (p / count[c].max(1.0)) as f32),
            colour: sum[c].map(|v| (v / weight[c].max(1e-9)) as f32),
            weight: weight[c] as f32,
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn image(w: usize, h: usize, f: impl Fn(usize, usize) -> [f32; 3]) -> Img {
        Img {
            w,
            h,
            px: (0..w * h).map(|i| f(i % w, i / w)).collect(),
        }
    }

    fn variance(img: &Img) -> f32 {
        let n = img.px.len() as f32;
        (0..3)
            .map(|k| {
                let m = img.px.iter().map(|p| p[k]).sum::<f32>() / n;
                img.px.iter().map(|p| (p[k] - m).powi(2)).sum::<f32>() / n
            })
            .sum()
    }

    #[test]
    fn a_stationary_image_keeps_every_margin() {
        // a checker of two colours much finer than the margin: every band holds what the
        // inside holds
        let img = image(128, 128, |x, y| {
            if (x / 4 + y / 4) % 2 == 0 {
                [0.2, 0.3, 0.8]
            } else {
                [0.9, 0.8, 0.1]
            }
        });
        let f = side_factors(&img, None, 20.0, variance(&img), 0.05);
        for (s, v) in f.iter().enumerate() {
            assert!(*v > 0.9, "side {s}: factor {v}");
        }
    }

    #[test]
    fn a_sky_frees_its_top_and_bottom_only() {
        // deep blue along the top, orange along the bottom, a pale grade between them, the same
        // along each row
        let img = image(128, 128, |_, y| {
            let t = y as f32 / 127.0;
            if y < 16 {
                [0.05, 0.1, 0.4]
            } else if y >= 112 {
                [0.95, 0.5, 0.1]
            } else {
                [0.55 + 0.3 * t, 0.7, 0.9 - 0.3 * t]
            }
        });
        let f = side_factors(&img, None, 20.0, variance(&img), 0.05);
        assert!(f[Side::Left as usize] > 0.9, "{f:?}");
        assert!(f[Side::Right as usize] > 0.9, "{f:?}");
        assert!(f[Side::Top as usize] < 0.6, "{f:?}");
        assert!(f[Side::Bottom as usize] < 0.6, "{f:?}");
    }

    #[test]
    fn a_transparent_band_is_not_reached_for() {
        // the sky's distinct top and bottom, but transparent there: nothing to reach
        let img = image(128, 128, |_, y| {
            if y < 24 {
                [0.05, 0.1, 0.4]
            } else if y >= 104 {
                [0.95, 0.5, 0.1]
            } else {
                [0.6, 0.7, 0.8]
            }
        });
        let opacity: Vec<f32> = (0..128 * 128)
            .map(|i| {
                if (24..104).contains(&(i / 128)) {
                    1.0
                } else {
                    0.0
                }
            })
            .collect();
        let f = side_factors(&img, Some(&opacity), 20.0, variance(&img), 0.05);
        assert_eq!(f[Side::Top as usize], 1.0, "{f:?}");
        assert_eq!(f[Side::Bottom as usize], 1.0, "{f:?}");
    }

    #[test]
    fn margins_wider_than_half_the_image_are_left_alone() {
        let img = image(16, 16, |x, _| [x as f32 / 15.0; 3]);
        assert_eq!(
            side_factors(&img, None, 9.0, variance(&img), 0.05),
            [1.0; 4]
        );
    }
}
