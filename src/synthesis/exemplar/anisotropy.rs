//! How oriented an exemplar is: the 2-fold and 4-fold circular harmonics of its gradient
//! orientations, weighted by squared gradient magnitude (the coherence of the mean structure
//! tensor, and its 4-fold analogue), measured on the exemplar smoothed to the scale the
//! synthesis matches (one Gaussian pyramid step), over its opaque pixels.
//!
//! Stripes and bark (gradients along one axis) score high 2-fold; bricks, weaves and grids
//! (gradients along two perpendicular axes) score high 4-fold; isotropic textures (sand, foliage,
//! noise) score low on both. [`choose_orientation`] picks the field a user would: random for
//! isotropic exemplars (Wei & Levoy §3.1), a smooth 2- or 4-fold field for oriented ones, which
//! keeps rows of bricks and strips of bark coherent across the surface.

use super::Orientation;

/// The exemplar's orientation harmonics, each in [0, 1].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Anisotropy {
    /// `|Σ |g|² e^{2iθ}| / Σ |g|²`: one dominant gradient axis (stripes).
    pub twofold: f32,
    /// `|Σ |g|² e^{4iθ}| / Σ |g|²`: two perpendicular gradient axes (grids, bricks).
    pub fourfold: f32,
}

/// Harmonic (2- or 4-fold) from which an exemplar counts as oriented. Measured on the shared
/// textures at the sizes `synth` works with: water, ink and dots 0.04-0.18; birch bark 0.32
/// (2-fold); bricks 0.21-0.32.
pub const ORIENTED: f32 = 0.2;

/// Measure `img` (sRGB; `alpha` under one half excluded) at two scales, the exemplar and its
/// half-size level (the pyramid the synthesis matches on), keeping the stronger of each harmonic:
/// bricks are oriented at the scale of their rows, not of the grain inside each brick.
pub fn exemplar_anisotropy(img: &image::RgbImage, alpha: Option<&image::GrayImage>) -> Anisotropy {
    let fine = anisotropy_at(img, alpha);
    let (w, h) = (img.width() / 2, img.height() / 2);
    if w < 16 || h < 16 {
        return fine;
    }
    let half = image::imageops::resize(img, w, h, image::imageops::FilterType::Triangle);
    let half_alpha =
        alpha.map(|a| image::imageops::resize(a, w, h, image::imageops::FilterType::Triangle));
    let coarse = anisotropy_at(&half, half_alpha.as_ref());
    Anisotropy {
        twofold: fine.twofold.max(coarse.twofold),
        fourfold: fine.fourfold.max(coarse.fourfold),
    }
}

fn anisotropy_at(img: &image::RgbImage, alpha: Option<&image::GrayImage>) -> Anisotropy {
    let (w, h) = (img.width() as usize, img.height() as usize);
    if w < 4 || h < 4 {
        return Anisotropy::default();
    }
    // Luminance, then a [1 2 1]² blur: pixel noise out, structure in.
    let lum: Vec<f32> = img
        .pixels()
        .map(|p| 0.2126 * p.0[0] as f32 + 0.7152 * p.0[1] as f32 + 0.0722 * p.0[2] as f32)
        .collect();
    let at = |v: &[f32], x: isize, y: isize| {
        v[(y.clamp(0, h as isize - 1) as usize) * w + x.clamp(0, w as isize - 1) as usize]
    };
    let mut blur = vec![0.0f32; w * h];
    for y in 0..h as isize {
        for x in 0..w as isize {
            let mut s = 0.0;
            for (dy, ky) in [(-1, 1.0), (0, 2.0), (1, 1.0)] {
                for (dx, kx) in [(-1, 1.0), (0, 2.0), (1, 1.0)] {
                    s += ky * kx * at(&lum, x + dx, y + dy);
                }
            }
            blur[y as usize * w + x as usize] = s / 16.0;
        }
    }
    let (mut s2, mut s4, mut total, mut total2) = ([0.0f64; 2], [0.0f64; 2], 0.0f64, 0.0f64);
    for y in 1..h as isize - 1 {
        for x in 1..w as isize - 1 {
            if let Some(a) = alpha
                && [(0, 0), (-1, 0), (1, 0), (0, -1), (0, 1)]
                    .iter()
                    .any(|&(dx, dy)| a.get_pixel((x + dx) as u32, (y + dy) as u32).0[0] < 128)
            {
                continue;
            }
            let gx = (at(&blur, x + 1, y) - at(&blur, x - 1, y)) as f64;
            let gy = (at(&blur, x, y + 1) - at(&blur, x, y - 1)) as f64;
            let m2 = gx * gx + gy * gy;
            if m2 <= 0.0 {
                continue;
            }
            // |g|² e^{2iθ} = (gx + i gy)², and |g|² e^{4iθ} = (gx + i gy)^4 / |g|².
            let (c2, d2) = (gx * gx - gy * gy, 2.0 * gx * gy);
            s2[0] += c2;
            s2[1] += d2;
            s4[0] += (c2 * c2 - d2 * d2) / m2;
            s4[1] += 2.0 * c2 * d2 / m2;
            total += m2;
            total2 += m2 * m2;
        }
    }
    if total <= 0.0 {
        return Anisotropy::default();
    }
    // A harmonic of N independent random orientations has magnitude about 1/sqrt(N): below
    // three times that it is noise, not structure (a tiny exemplar). N is the effective count of
    // the weighted samples over the 3x3 footprint the blur and the differences correlate.
    let n_eff = total * total / total2.max(f64::MIN_POSITIVE) / 9.0;
    let floor = 3.0 / n_eff.sqrt();
    let significant = |h: f64| if h >= floor { h as f32 } else { 0.0 };
    Anisotropy {
        twofold: significant(s2[0].hypot(s2[1]) / total),
        fourfold: significant(s4[0].hypot(s4[1]) / total),
    }
}

/// The orientation field for an exemplar of this anisotropy: `Random` for isotropic textures
/// (both harmonics under [`ORIENTED`]), else `Relax4` where the 4-fold harmonic leads (grids)
/// and `Relax2` where the 2-fold one does (stripes, rows).
pub fn choose_orientation(a: Anisotropy) -> Orientation {
    if a.twofold.max(a.fourfold) < ORIENTED {
        Orientation::Random
    } else if a.fourfold > a.twofold {
        Orientation::Relax4
    } else {
        Orientation::Relax2
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn image(f: impl Fn(u32, u32) -> u8) -> image::RgbImage {
        image::RgbImage::from_fn(96, 96, |x, y| {
            let v = f(x, y);
            image::Rgb([v, v, v])
        })
    }

    #[test]
    fn stripes_grids_and_noise_get_their_fields() {
        let stripes = image(|x, _| if (x / 6) % 2 == 0 { 220 } else { 40 });
        let grid = image(|x, y| if x % 12 < 2 || y % 12 < 2 { 30 } else { 200 });
        let noise =
            image(|x, y| ((x.wrapping_mul(2_654_435_761) ^ y.wrapping_mul(40_503)) % 251) as u8);
        let (s, g, n) = (
            exemplar_anisotropy(&stripes, None),
            exemplar_anisotropy(&grid, None),
            exemplar_anisotropy(&noise, None),
        );
        assert!(s.twofold > 0.9, "{s:?}");
        assert!(g.fourfold > 0.5 && g.twofold < 0.2, "{g:?}");
        assert!(n.twofold < 0.15 && n.fourfold < 0.15, "{n:?}");
        assert_eq!(choose_orientation(s), Orientation::Relax2);
        assert_eq!(choose_orientation(g), Orientation::Relax4);
        assert_eq!(choose_orientation(n), Orientation::Random);
    }

    #[test]
    fn transparent_pixels_do_not_count() {
        // Stripes everywhere except a transparent half that holds a grid: still stripes.
        let img = image(|x, y| {
            if y < 48 {
                if (x / 6) % 2 == 0 { 220 } else { 40 }
            } else if x % 12 < 2 || y % 12 < 2 {
                30
            } else {
                200
            }
        });
        let alpha =
            image::GrayImage::from_fn(96, 96, |_, y| image::Luma([if y < 48 { 255 } else { 0 }]));
        let a = exemplar_anisotropy(&img, Some(&alpha));
        assert!(a.twofold > 0.8, "{a:?}");
    }
}
