//! Texel-by-texel scores of a delivered texture against the truth, over the texels the target's
//! charts cover: mean CIE76 colour difference, SSIM of the lightness, and edge strength where the
//! truth's edges are strongest.

use rayon::prelude::*;

use crate::color::{from_u8, srgb_to_lab};

/// Half-width of the SSIM window (7x7 box).
const SSIM_HALF: usize = 3;
/// The share of covered texels, strongest truth gradient first, that edge strength is measured
/// on.
const EDGE_SHARE: f64 = 0.05;

/// A delivered texture against the truth.
#[derive(Clone, Copy, Debug, Default, serde::Serialize)]
pub struct TexelScores {
    /// Mean CIE76 colour difference per covered texel.
    pub delta_e: f64,
    /// Mean SSIM of the lightness (L*/100) over 7x7 windows of covered texels.
    pub ssim: f64,
    /// Sum of the result's lightness gradient magnitude over the truth's strongest edges (its top
    /// 5% of gradient magnitude) divided by the truth's there: 1 = as sharp as the truth.
    pub edges: f64,
    /// Mean lightness gradient magnitude of the result over the truth's, over all covered texels:
    /// how sharp the result is wherever its edges lie (1 = as sharp as the truth).
    pub sharpness: f64,
}

/// Score `result` against `truth` (same size) over `covered` texels.
pub fn score(result: &image::RgbImage, truth: &image::RgbImage, covered: &[bool]) -> TexelScores {
    let (w, h) = (truth.width() as usize, truth.height() as usize);
    assert_eq!(
        result.dimensions(),
        truth.dimensions(),
        "images differ in size"
    );
    assert_eq!(covered.len(), w * h);
    let lab = |img: &image::RgbImage| -> Vec<[f32; 3]> {
        img.pixels()
            .collect::<Vec<_>>()
            .par_iter()
            .map(|p| srgb_to_lab(from_u8(p.0)))
            .collect()
    };
    let (lr, lt) = (lab(result), lab(truth));
    let n = covered.iter().filter(|&&c| c).count().max(1);
    let delta_e = (0..w * h)
        .into_par_iter()
        .filter(|&i| covered[i])
        .map(|i| {
            let (a, b) = (lr[i], lt[i]);
            let d = [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
            ((d[0] * d[0] + d[1] * d[1] + d[2] * d[2]) as f64).sqrt()
        })
        .sum::<f64>()
        / n as f64;
    let x: Vec<f32> = lr.iter().map(|c| c[0] / 100.0).collect();
    let y: Vec<f32> = lt.iter().map(|c| c[0] / 100.0).collect();
    let (gx, gy) = (gradient(&x, covered, w, h), gradient(&y, covered, w, h));
    TexelScores {
        delta_e,
        ssim: ssim(&x, &y, covered, w, h),
        edges: edge_strength(&gx, &gy),
        sharpness: sharpness(&gx, &gy),
    }
}

/// Mean SSIM (Wang et al. 2004, C1 = 0.01², C2 = 0.03²) over 7x7 windows whose texels are all
/// covered.
fn ssim(x: &[f32], y: &[f32], covered: &[bool], w: usize, h: usize) -> f64 {
    let r = SSIM_HALF;
    let (c1, c2) = (1e-4f64, 9e-4f64);
    let rows: Vec<(f64, usize)> = (r..h.saturating_sub(r))
        .into_par_iter()
        .map(|cy| {
            let (mut sum, mut cnt) = (0.0f64, 0usize);
            for cx in r..w.saturating_sub(r) {
                let (mut sx, mut sy, mut sxx, mut syy, mut sxy) = (0.0f64, 0.0, 0.0, 0.0, 0.0);
                let mut full = true;
                'win: for yy in cy - r..=cy + r {
                    for xx in cx - r..=cx + r {
                        let i = yy * w + xx;
                        if !covered[i] {
                            full = false;
                            break 'win;
                        }
                        let (a, b) = (x[i] as f64, y[i] as f64);
                        sx += a;
                        sy += b;
                        sxx += a * a;
                        syy += b * b;
                        sxy += a * b;
                    }
                }
                if !full {
                    continue;
                }
                let m = ((2 * r + 1) * (2 * r + 1)) as f64;
                let (mx, my) = (sx / m, sy / m);
                let vx = (sxx / m - mx * mx).max(0.0);
                let vy = (syy / m - my * my).max(0.0);
                let cxy = sxy / m - mx * my;
                sum += ((2.0 * mx * my + c1) * (2.0 * cxy + c2))
                    / ((mx * mx + my * my + c1) * (vx + vy + c2));
                cnt += 1;
            }
            (sum, cnt)
        })
        .collect();
    let (s, c) = rows
        .iter()
        .fold((0.0, 0usize), |(s, c), &(a, b)| (s + a, c + b));
    if c == 0 { 0.0 } else { s / c as f64 }
}

/// Sobel gradient magnitude at every texel whose 3x3 neighbourhood is covered (`None` elsewhere).
fn gradient(v: &[f32], covered: &[bool], w: usize, h: usize) -> Vec<Option<f32>> {
    (0..w * h)
        .into_par_iter()
        .map(|i| {
            let (x, y) = (i % w, i / w);
            if x == 0 || y == 0 || x + 1 >= w || y + 1 >= h {
                return None;
            }
            let at = |dx: isize, dy: isize| {
                let j = ((y as isize + dy) as usize) * w + (x as isize + dx) as usize;
                covered[j].then(|| v[j])
            };
            let mut k = [[0.0f32; 3]; 3];
            for (dy, row) in k.iter_mut().enumerate() {
                for (dx, c) in row.iter_mut().enumerate() {
                    *c = at(dx as isize - 1, dy as isize - 1)?;
                }
            }
            let gx = (k[0][2] + 2.0 * k[1][2] + k[2][2]) - (k[0][0] + 2.0 * k[1][0] + k[2][0]);
            let gy = (k[2][0] + 2.0 * k[2][1] + k[2][2]) - (k[0][0] + 2.0 * k[0][1] + k[0][2]);
            Some((gx * gx + gy * gy).sqrt())
        })
        .collect()
}

/// The result's gradient over the truth's on the truth's strongest edges (see
/// [`TexelScores::edges`]).
fn edge_strength(gx: &[Option<f32>], gy: &[Option<f32>]) -> f64 {
    let mut idx: Vec<(f32, usize)> = gy
        .iter()
        .enumerate()
        .filter_map(|(i, g)| g.map(|g| (g, i)))
        .collect();
    if idx.is_empty() {
        return 0.0;
    }
    idx.sort_by(|a, b| b.0.total_cmp(&a.0));
    let k = ((idx.len() as f64 * EDGE_SHARE).ceil() as usize).clamp(1, idx.len());
    let (mut num, mut den) = (0.0f64, 0.0f64);
    for &(g, i) in &idx[..k] {
        den += g as f64;
        num += gx[i].unwrap_or(0.0) as f64;
    }
    if den > 0.0 { num / den } else { 0.0 }
}

/// Mean gradient of the result over the truth's (see [`TexelScores::sharpness`]).
fn sharpness(gx: &[Option<f32>], gy: &[Option<f32>]) -> f64 {
    let (mut a, mut b) = (0.0f64, 0.0f64);
    for (x, y) in gx.iter().zip(gy) {
        if let (Some(x), Some(y)) = (x, y) {
            a += *x as f64;
            b += *y as f64;
        }
    }
    if b > 0.0 { a / b } else { 0.0 }
}
