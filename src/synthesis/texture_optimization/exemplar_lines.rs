//! The exemplar's line features for the feature-to-feature constraint (Xu et al. 2009 §5.2):
//! a line mask (detected as thin dark or bright valleys of lightness, as Wu & Yu 2004's
//! curvilinear feature maps, or given by the user), thinned to the centre lines of its
//! horizontal strokes (the principal lines: the field runs along the exemplar's x axis), and the
//! exact Euclidean distance of every pixel to them (Felzenszwalb & Huttenlocher 2012).

use crate::error::{Error, Result};
use crate::geometry::distance_transform;

/// Principal line features of an exemplar.
#[derive(Clone, Debug)]
pub struct ExemplarLines {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// Centre-line pixels of the principal (horizontal) lines, row-major.
    pub centre: Vec<bool>,
    /// Per pixel, the distance in pixels to the nearest centre-line pixel.
    pub distance: Vec<f32>,
}

/// Lightness in [0, 1] (Rec. 709 luma of the sRGB values).
fn luma(p: &image::Rgb<u8>) -> f32 {
    (0.2126 * p.0[0] as f32 + 0.7152 * p.0[1] as f32 + 0.0722 * p.0[2] as f32) / 255.0
}

/// Box mean of `v` (w × h, row-major) over a (2r+1)² window clamped at the borders.
fn box_mean(v: &[f32], w: usize, h: usize, r: usize) -> Vec<f32> {
    let mut sat = vec![0.0f64; (w + 1) * (h + 1)];
    for y in 0..h {
        let mut row = 0.0f64;
        for x in 0..w {
            row += v[y * w + x] as f64;
            sat[(y + 1) * (w + 1) + x + 1] = sat[y * (w + 1) + x + 1] + row;
        }
    }
    let mut out = vec![0.0f32; w * h];
    for y in 0..h {
        let (y0, y1) = (y.saturating_sub(r), (y + r + 1).min(h));
        for x in 0..w {
            let (x0, x1) = (x.saturating_sub(r), (x + r + 1).min(w));
            let s = sat[y1 * (w + 1) + x1] - sat[y0 * (w + 1) + x1] - sat[y1 * (w + 1) + x0]
                + sat[y0 * (w + 1) + x0];
            out[y * w + x] = (s / ((x1 - x0) * (y1 - y0)) as f64) as f32;
        }
    }
    out
}

/// Detect thin line features: pixels darker (or brighter, whichever carries more contrast) than
/// their neighbourhood's mean by more than half the 99th percentile of that contrast. Transparent
/// pixels (alpha < 1/2) are never features. Returns the mask and every pixel's contrast (its
/// lightness difference to the neighbourhood mean, signed so that features are positive).
pub fn detect_line_mask(
    img: &image::RgbImage,
    alpha: Option<&image::GrayImage>,
) -> (Vec<bool>, Vec<f32>) {
    let (w, h) = (img.width() as usize, img.height() as usize);
    let l: Vec<f32> = img.pixels().map(luma).collect();
    let r = (w.min(h) / 12).max(3);
    let b = box_mean(&l, w, h, r);
    let res: Vec<f32> = l.iter().zip(&b).map(|(a, m)| a - m).collect();
    let opaque = |i: usize| alpha.is_none_or(|a| a.as_raw()[i] >= 128);
    let mut mags: Vec<f32> = (0..w * h)
        .filter(|&i| opaque(i))
        .map(|i| res[i].abs())
        .collect();
    if mags.is_empty() {
        return (vec![false; w * h], vec![0.0; w * h]);
    }
    let k = ((mags.len() as f64 * 0.99) as usize).min(mags.len() - 1);
    let (_, q, _) = mags.select_nth_unstable_by(k, f32::total_cmp);
    let tau = (0.5 * *q).max(0.04);
    let (mut dark, mut bright) = (0.0f64, 0.0f64);
    for i in (0..w * h).filter(|&i| opaque(i)) {
        if res[i] < -tau {
            dark -= res[i] as f64;
        } else if res[i] > tau {
            bright += res[i] as f64;
        }
    }
    let sign = if dark >= bright { -1.0 } else { 1.0 };
    let mask = (0..w * h)
        .map(|i| opaque(i) && sign * res[i] > tau)
        .collect();
    (mask, res.iter().map(|r| sign * r).collect())
}

/// A user's feature mask: pixels lighter than mid-grey are features. Resized (nearest) to the
/// exemplar's size when it differs.
pub fn mask_from_image(mask: &image::GrayImage, width: u32, height: u32) -> Vec<bool> {
    let m = if mask.dimensions() == (width, height) {
        mask.clone()
    } else {
        image::imageops::resize(mask, width, height, image::imageops::FilterType::Nearest)
    };
    m.pixels().map(|p| p.0[0] >= 128).collect()
}

/// Pieces whose mean contrast is below this fraction of the strongest piece's are secondary
/// lines, not principal ones.
const PRINCIPAL_CONTRAST: f32 = 0.7;

/// The centre lines of the mask's horizontal strokes: per column, the middle pixel of every run
/// no thicker than a sixth of the height, kept where its 8-connected piece spans at least a
/// quarter of the width (a line, not a blot). With `contrast` (per pixel, features positive), only
/// the principal pieces are kept: those whose mean contrast along the centre line reaches
/// [`PRINCIPAL_CONTRAST`] of the strongest piece's (a dark groove, not the faint grain beside it).
pub fn horizontal_centre_lines(
    mask: &[bool],
    contrast: Option<&[f32]>,
    w: usize,
    h: usize,
) -> Vec<bool> {
    let mut centre = vec![false; w * h];
    let max_run = (h / 6).max(2);
    for x in 0..w {
        let mut y = 0;
        while y < h {
            if !mask[y * w + x] {
                y += 1;
                continue;
            }
            let y0 = y;
            while y < h && mask[y * w + x] {
                y += 1;
            }
            if y - y0 <= max_run {
                centre[((y0 + y - 1) / 2) * w + x] = true;
            }
        }
    }
    // 8-connected pieces by flood fill; keep the wide ones.
    let mut label = vec![u32::MAX; w * h];
    let mut keep = vec![false; w * h];
    let mut stack = Vec::new();
    let mut piece = Vec::new();
    // (mean contrast, pixels) of every wide piece
    let mut pieces: Vec<(f32, Vec<usize>)> = Vec::new();
    for start in 0..w * h {
        if !centre[start] || label[start] != u32::MAX {
            continue;
        }
        label[start] = start as u32;
        stack.push(start);
        piece.clear();
        let (mut xmin, mut xmax) = (usize::MAX, 0usize);
        while let Some(i) = stack.pop() {
            piece.push(i);
            let (x, y) = (i % w, i / w);
            xmin = xmin.min(x);
            xmax = xmax.max(x);
            for dy in -1i64..=1 {
                for dx in -1i64..=1 {
                    let (nx, ny) = (x as i64 + dx, y as i64 + dy);
                    if nx < 0 || ny < 0 || nx >= w as i64 || ny >= h as i64 {
                        continue;
                    }
                    let j = ny as usize * w + nx as usize;
                    if centre[j] && label[j] == u32::MAX {
                        label[j] = start as u32;
                        stack.push(j);
                    }
                }
            }
        }
        if xmax + 1 - xmin >= (w / 4).max(4) {
            let c = contrast.map_or(1.0, |c| {
                piece.iter().map(|&i| c[i]).sum::<f32>() / piece.len() as f32
            });
            pieces.push((c, piece.clone()));
        }
    }
    let best = pieces.iter().map(|p| p.0).fold(f32::NEG_INFINITY, f32::max);
    for (c, piece) in &pieces {
        if *c >= PRINCIPAL_CONTRAST * best {
            for &i in piece {
                keep[i] = true;
            }
        }
    }
    keep
}

/// The principal lines of an exemplar from a mask (detected or the user's).
pub fn principal_lines(
    mask: &[bool],
    contrast: Option<&[f32]>,
    w: usize,
    h: usize,
) -> ExemplarLines {
    let centre = horizontal_centre_lines(mask, contrast, w, h);
    let distance = distance_transform(&centre, w, h);
    ExemplarLines {
        width: w,
        height: h,
        centre,
        distance,
    }
}

/// The exemplar's principal lines, and whether the exemplar must be turned a quarter turn so
/// that they run along its x axis (the mask's strokes are vertical). Refuses an exemplar
/// without a line feature in either direction, in one line.
pub fn find_principal_lines(
    img: &image::RgbImage,
    alpha: Option<&image::GrayImage>,
    user_mask: Option<&image::GrayImage>,
) -> Result<(ExemplarLines, bool)> {
    let (w, h) = (img.width() as usize, img.height() as usize);
    let (mask, contrast) = match user_mask {
        Some(m) => (mask_from_image(m, img.width(), img.height()), None),
        None => {
            let (m, c) = detect_line_mask(img, alpha);
            (m, Some(c))
        }
    };
    let lines = principal_lines(&mask, contrast.as_deref(), w, h);
    let along: usize = lines.centre.iter().filter(|&&c| c).count();
    // The same mask turned a quarter turn clockwise (as `image::imageops::rotate90`).
    let mut turned = vec![false; w * h];
    let mut turned_contrast = vec![0.0f32; w * h];
    for y in 0..h {
        for x in 0..w {
            // rotate90: (x, y) -> (h - 1 - y, x) in a h-wide, w-high image
            turned[x * h + (h - 1 - y)] = mask[y * w + x];
            if let Some(c) = &contrast {
                turned_contrast[x * h + (h - 1 - y)] = c[y * w + x];
            }
        }
    }
    let across = principal_lines(
        &turned,
        contrast.as_ref().map(|_| turned_contrast.as_slice()),
        h,
        w,
    );
    let n_across: usize = across.centre.iter().filter(|&&c| c).count();
    if along == 0 && n_across == 0 {
        return Err(Error::InvalidInput(format!(
            "no line feature found in the {w}x{h} exemplar{}: give one with --feature-mask \
             (white lines on black, the exemplar's size)",
            if user_mask.is_some() { " mask" } else { "" }
        )));
    }
    // Turn only when the vertical strokes clearly dominate.
    if n_across > 2 * along {
        Ok((across, true))
    } else {
        Ok((lines, false))
    }
}

/// The roll (rows down, wrapping) that brings the principal lines at least `margin` rows away
/// from the top and bottom borders, putting the image's new border in the middle of the widest
/// band free of lines; `None` when they are already clear of the borders (or cannot be).
/// A line on the border of a tileable exemplar (a tile's grout) otherwise has no whole patch
/// centred on it.
pub fn border_roll(lines: &ExemplarLines, margin: usize) -> Option<usize> {
    let (w, h) = (lines.width, lines.height);
    let rows: Vec<usize> = (0..h)
        .filter(|&y| lines.centre[y * w..(y + 1) * w].iter().any(|&c| c))
        .collect();
    if rows.is_empty() || h < 2 * margin + 1 {
        return None;
    }
    if rows.iter().all(|&y| y >= margin && y + margin < h) {
        return None;
    }
    // widest circular gap between consecutive line rows
    let mut best = (0usize, rows[0]);
    for (i, &y) in rows.iter().enumerate() {
        let next = if i + 1 < rows.len() {
            rows[i + 1]
        } else {
            rows[0] + h
        };
        if next - y > best.0 {
            best = (next - y, y);
        }
    }
    let cut = (best.1 + best.0 / 2) % h;
    let dy = (h - cut) % h;
    (dy != 0).then_some(dy)
}

/// The image rolled down by `dy` rows, wrapping (row `y` moves to `(y + dy) % h`).
pub fn roll_rows<P: image::Pixel>(
    img: &image::ImageBuffer<P, Vec<P::Subpixel>>,
    dy: usize,
) -> image::ImageBuffer<P, Vec<P::Subpixel>> {
    let h = img.height() as usize;
    image::ImageBuffer::from_fn(img.width(), img.height(), |x, y| {
        *img.get_pixel(x, ((y as usize + h - dy % h) % h) as u32)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A light exemplar with a dark 3-pixel horizontal band at rows 20..23 and a mild texture.
    fn band_exemplar(vertical: bool) -> image::RgbImage {
        let (w, h) = if vertical { (48, 64) } else { (64, 48) };
        image::RgbImage::from_fn(w, h, |x, y| {
            let (x, y) = if vertical { (y, x) } else { (x, y) };
            let noise = ((x * 7 + y * 13) % 5) as u8 * 4;
            if (20..23).contains(&y) {
                image::Rgb([40 + noise, 30, 30])
            } else {
                image::Rgb([200 + noise, 190, 170])
            }
        })
    }

    #[test]
    fn a_dark_band_is_found_at_its_centre_row() {
        let img = band_exemplar(false);
        let (lines, turned) = find_principal_lines(&img, None, None).unwrap();
        assert!(!turned);
        for x in 0..64 {
            assert!(lines.centre[21 * 64 + x], "column {x}");
            assert!(lines.distance[30 * 64 + x] == 9.0);
        }
        let n: usize = lines.centre.iter().filter(|&&c| c).count();
        assert_eq!(n, 64, "one centre row only");
    }

    #[test]
    fn a_vertical_band_asks_for_a_quarter_turn_and_a_plain_image_is_refused() {
        let img = band_exemplar(true);
        assert_eq!((img.width(), img.height()), (48, 64));
        let (lines, turned) = find_principal_lines(&img, None, None).unwrap();
        assert!(turned);
        let turned_img = image::imageops::rotate90(&img);
        let (again, t2) = find_principal_lines(&turned_img, None, None).unwrap();
        assert!(!t2);
        assert_eq!(lines.centre, again.centre);
        let plain = image::RgbImage::from_pixel(32, 32, image::Rgb([120, 120, 120]));
        let e = find_principal_lines(&plain, None, None)
            .unwrap_err()
            .to_string();
        assert!(e.contains("no line feature"), "{e}");
    }

    #[test]
    fn the_dark_groove_is_principal_and_the_faint_grain_beside_it_is_not() {
        let img = image::RgbImage::from_fn(96, 96, |x, y| {
            let noise = ((x * 5 + y * 11) % 7) as u8 * 2;
            let v = match y {
                45..=50 => 40,
                14 | 15 | 78 | 79 => 140,
                _ => 205,
            };
            image::Rgb([v + noise, v, v])
        });
        let (lines, turned) = find_principal_lines(&img, None, None).unwrap();
        assert!(!turned);
        let rows: std::collections::BTreeSet<usize> = (0..96 * 96)
            .filter(|&i| lines.centre[i])
            .map(|i| i / 96)
            .collect();
        assert_eq!(rows.into_iter().collect::<Vec<_>>(), vec![47]);
    }

    #[test]
    fn a_line_on_the_border_is_rolled_to_the_middle() {
        // a tile whose dark grout runs along the top and bottom rows
        let img = image::RgbImage::from_fn(64, 64, |x, y| {
            let noise = ((x * 5 + y * 11) % 7) as u8 * 2;
            let v = if !(2..=61).contains(&y) { 40 } else { 205 };
            image::Rgb([v + noise, v, v])
        });
        let (lines, _) = find_principal_lines(&img, None, None).unwrap();
        let dy = border_roll(&lines, 16).expect("the grout is on the border");
        let rolled = roll_rows(&img, dy);
        let (again, _) = find_principal_lines(&rolled, None, None).unwrap();
        assert_eq!(border_roll(&again, 16), None);
        let rows: Vec<usize> = (0..64)
            .filter(|&y| again.centre[y * 64..(y + 1) * 64].iter().any(|&c| c))
            .collect();
        assert!(rows.iter().all(|&y| (24..40).contains(&y)), "{rows:?}");
        // a line already in the middle is left alone
        let (mid, _) = find_principal_lines(&band_exemplar(false), None, None).unwrap();
        assert_eq!(border_roll(&mid, 16), None);
    }
}
