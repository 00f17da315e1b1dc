//! Baking a surface signal into a texture through per-corner UVs, and the texture's mip chain.
//!
//! [`bake_uv`] rasterises every UV triangle conservatively: a texel whose centre lies inside a
//! triangle takes the signal there; a texel the triangle only touches (its centre within half a
//! texel diagonal of the triangle) takes the signal at the triangle's nearest point, unless a
//! triangle covers its centre. Thin and sliver triangles therefore leave no holes inside charts.
//! [`fill_gutters`] then fills every texel outside the charts by pull-push (a weighted image
//! pyramid, pulled up and pushed back down), so bilinear and mipmapped sampling never meets a
//! background colour at chart borders: gutters carry the colour of the nearest charts.

use rayon::prelude::*;

/// A baked image in floating point with its coverage mask (row 0 at the top of the image).
#[derive(Clone, Debug)]
pub struct BakedImage {
    /// Width in texels.
    pub width: usize,
    /// Height in texels.
    pub height: usize,
    /// Texel values, row-major.
    pub pixels: Vec<[f32; 3]>,
    /// Whether a UV triangle covers (or touches) each texel.
    pub covered: Vec<bool>,
}

impl BakedImage {
    /// The image as 8-bit sRGB.
    pub fn to_rgb8(&self) -> image::RgbImage {
        let mut img = image::RgbImage::new(self.width as u32, self.height as u32);
        let row = 3 * self.width.max(1);
        img.par_chunks_mut(row)
            .zip(self.pixels.par_chunks(self.width.max(1)))
            .for_each(|(out, src)| {
                for (o, c) in out.chunks_exact_mut(3).zip(src) {
                    o.copy_from_slice(&crate::color::to_u8(*c));
                }
            });
        img
    }
}

/// Peak bytes per texel of a bake: the linear image, coverage, per-band distances, the pull-push
/// pyramid and the 8-bit copy (measured about 22 at 4096²; 40 leaves room for the meshes).
pub const BAKE_BYTES_PER_TEXEL: u64 = 40;

/// Refuse a `size²` bake that needs more memory than this process may use, before any of it
/// is allocated.
pub fn check_bake_memory(size: u32) -> crate::error::Result<()> {
    let texels = (size as u64) * (size as u64);
    crate::work::check_memory(
        texels.saturating_mul(BAKE_BYTES_PER_TEXEL),
        &format!("a {size}x{size} texture"),
        "use a smaller --texture-size",
    )
}

/// Rows of texels a worker rasterises at a time.
const BAND_ROWS: usize = 32;
/// Half the diagonal of a texel: how far outside a triangle a touched texel's centre may lie.
const TOUCH: f32 = std::f32::consts::FRAC_1_SQRT_2;

/// Rasterise `faces` triangles whose corners have UVs `uvs[3 * f + k]` (V up, `[0, 1]²`) into a
/// `width × height` image; `sample(f, bary)` gives the signal at barycentric `bary` of face `f`.
/// Texels no triangle touches stay zero and uncovered (see [`fill_gutters`]).
pub fn bake_uv<F>(
    uvs: &[[f32; 2]],
    faces: usize,
    width: usize,
    height: usize,
    sample: F,
) -> BakedImage
where
    F: Fn(usize, [f32; 3]) -> [f32; 3] + Sync,
{
    let (pixels, covered) = rasterize_uv(uvs, faces, width, height, [0.0; 3], sample);
    BakedImage {
        width: width.max(1),
        height: height.max(1),
        pixels,
        covered,
    }
}

/// The surface point of every texel of a `width × height` image: `(face, barycentric)` of the
/// triangle that covers (or touches) its centre, as [`bake_uv`] finds it; `None` outside the
/// charts. Row 0 is the top of the image.
pub fn uv_texels(
    uvs: &[[f32; 2]],
    faces: usize,
    width: usize,
    height: usize,
) -> Vec<Option<(u32, [f32; 3])>> {
    rasterize_uv(uvs, faces, width, height, None, |f, b| Some((f as u32, b))).0
}

/// The conservative rasteriser behind [`bake_uv`] and [`uv_texels`]: `sample(f, bary)` per
/// covered texel, `empty` elsewhere, and the coverage mask.
fn rasterize_uv<T, F>(
    uvs: &[[f32; 2]],
    faces: usize,
    width: usize,
    height: usize,
    empty: T,
    sample: F,
) -> (Vec<T>, Vec<bool>)
where
    T: Clone + Send + Sync,
    F: Fn(usize, [f32; 3]) -> T + Sync,
{
    let (w, h) = (width.max(1), height.max(1));
    let faces = faces.min(uvs.len() / 3);
    // Texel-space corners (x right, y down) of every face.
    let corner = |f: usize, k: usize| {
        let u = uvs[3 * f + k];
        [u[0] * w as f32, (1.0 - u[1]) * h as f32]
    };
    // Faces per band of rows (CSR), by their bounding boxes grown by one texel.
    let bands = h.div_ceil(BAND_ROWS);
    let span = |f: usize| -> Option<(usize, usize)> {
        let ys = [corner(f, 0)[1], corner(f, 1)[1], corner(f, 2)[1]];
        if ys.iter().any(|y| !y.is_finite()) {
            return None;
        }
        let lo = ys.iter().copied().fold(f32::INFINITY, f32::min) - 1.0;
        let hi = ys.iter().copied().fold(f32::NEG_INFINITY, f32::max) + 1.0;
        if hi < 0.0 || lo >= h as f32 {
            return None;
        }
        let a = (lo.max(0.0) as usize / BAND_ROWS).min(bands - 1);
        let b = ((hi.min(h as f32 - 1.0)).max(0.0) as usize / BAND_ROWS).min(bands - 1);
        Some((a, b))
    };
    let mut off = vec![0usize; bands + 1];
    for f in 0..faces {
        if let Some((a, b)) = span(f) {
            for band in a..=b {
                off[band + 1] += 1;
            }
        }
    }
    for i in 0..bands {
        off[i + 1] += off[i];
    }
    let mut list = vec![0u32; off[bands]];
    let mut fill = off.clone();
    for f in 0..faces {
        if let Some((a, b)) = span(f) {
            for band in a..=b {
                list[fill[band]] = f as u32;
                fill[band] += 1;
            }
        }
    }
    let mut pixels = vec![empty; w * h];
    let mut covered = vec![false; w * h];
    pixels
        .par_chunks_mut(BAND_ROWS * w)
        .zip(covered.par_chunks_mut(BAND_ROWS * w))
        .enumerate()
        .for_each(|(band, (px, cov))| {
            let y0 = band * BAND_ROWS;
            let rows = px.len() / w;
            // The nearest face of each texel (0 inside a triangle), its barycentrics there, and
            // its distance: found first, so the sampler runs once per texel, not once per face
            // that touches it.
            let mut best = vec![f32::INFINITY; rows * w];
            let mut hit = vec![(u32::MAX, [0.0f32; 3]); rows * w];
            for &f in &list[off[band]..off[band + 1]] {
                let f = f as usize;
                let t = [corner(f, 0), corner(f, 1), corner(f, 2)];
                let det = (t[1][0] - t[0][0]) * (t[2][1] - t[0][1])
                    - (t[2][0] - t[0][0]) * (t[1][1] - t[0][1]);
                if !det.is_finite() || det.abs() < 1e-12 {
                    continue;
                }
                let xs = [t[0][0], t[1][0], t[2][0]];
                let ys = [t[0][1], t[1][1], t[2][1]];
                let lo = |v: [f32; 3]| (v[0].min(v[1]).min(v[2]) - 1.0).floor().max(0.0) as usize;
                let hi = |v: [f32; 3], n: usize| {
                    ((v[0].max(v[1]).max(v[2]) + 1.0).ceil().max(0.0) as usize).min(n)
                };
                let (x0, x1) = (lo(xs), hi(xs, w));
                let (ya, yb) = (lo(ys).max(y0), hi(ys, h).min(y0 + rows));
                // A texel whose distance to an edge's line exceeds the touch distance is not
                // touched (the line bounds the triangle's distance from below), and one inside
                // another face already cannot get nearer: neither needs the edges' distances.
                let reach = edge_reach(&t, det);
                for y in ya..yb {
                    for x in x0..x1 {
                        let i = (y - y0) * w + x;
                        if best[i] <= 0.0 {
                            continue;
                        }
                        let p = [x as f32 + 0.5, y as f32 + 0.5];
                        let b = barycentric(&t, det, p);
                        if b[0] >= 0.0 && b[1] >= 0.0 && b[2] >= 0.0 {
                            best[i] = 0.0;
                            hit[i] = (f as u32, b);
                            continue;
                        }
                        if (0..3).any(|k| -b[k] * reach[k] > TOUCH) {
                            continue;
                        }
                        let (d, bary) = nearest_on_edges(&t, p);
                        if d < best[i] && d <= TOUCH {
                            best[i] = d;
                            hit[i] = (f as u32, bary);
                        }
                    }
                }
            }
            for ((p, c), &(f, bary)) in px.iter_mut().zip(cov.iter_mut()).zip(&hit) {
                if f != u32::MAX {
                    *p = sample(f as usize, bary);
                    *c = true;
                }
            }
        });
    (pixels, covered)
}

/// Bake the per-vertex colours of another surface into a mesh's UV layout, as DCC tools transfer
/// maps from a high-resolution mesh: every texel's point on the mesh (`positions`, `faces`,
/// per-corner `uvs`) takes the colour interpolated at the closest point of the source surface
/// (`source` over `source_faces`, colours per source vertex). Gutters are filled by pull-push.
pub fn bake_closest(
    positions: &[[f32; 3]],
    faces: &[[u32; 3]],
    uvs: &[[f32; 2]],
    size: usize,
    source: &super::TriangleBvh,
    source_faces: &[[u32; 3]],
    source_colors: &[[f32; 3]],
) -> BakedImage {
    let mut img = bake_uv(uvs, faces.len(), size, size, |f, b| {
        let face = faces[f];
        let mut p = [0.0f32; 3];
        for k in 0..3 {
            let q = positions[face[k] as usize];
            for c in 0..3 {
                p[c] += b[k] * q[c];
            }
        }
        match source.closest_point(p) {
            Some((sf, sb, _)) => {
                let sface = source_faces[sf as usize];
                let mut out = [0.0f32; 3];
                for k in 0..3 {
                    let col = source_colors
                        .get(sface[k] as usize)
                        .copied()
                        .unwrap_or([0.0; 3]);
                    for c in 0..3 {
                        out[c] += sb[k] * col[c];
                    }
                }
                out
            }
            None => [0.0; 3],
        }
    });
    fill_gutters(&mut img);
    img
}

/// `target` with the colours of `source` (another surface of the same shape, colours per source
/// vertex) baked into a `size²` texture: through its own UVs, or through an atlas generated for
/// it when it has none or `new_atlas` is set. Vertex colours are dropped. Returns the mesh and
/// the atlas it generated, if any.
pub fn bake_onto(
    target: &crate::mesh::TriMesh,
    source: &crate::mesh::TriMesh,
    source_colors: &[[f32; 3]],
    size: u32,
    new_atlas: bool,
    progress: &(dyn Fn(f32) + Sync),
    cancel: &crate::work::CancelToken,
) -> crate::error::Result<(crate::mesh::TriMesh, Option<super::UvAtlas>)> {
    check_bake_memory(size)?;
    let mut out = target.clone();
    let mut atlas = None;
    if out.uvs.is_none() || new_atlas {
        let params = super::AtlasParams {
            texture_size: size,
            ..Default::default()
        };
        let a = super::uv_atlas(&out.positions, &out.faces, &params, progress, cancel)?;
        out.uvs = Some(a.uvs.clone());
        atlas = Some(a);
    }
    cancel.check()?;
    let bvh = super::TriangleBvh::new(&source.positions, &source.faces);
    let baked = bake_closest(
        &out.positions,
        &out.faces,
        out.uvs.as_deref().unwrap_or(&[]),
        size as usize,
        &bvh,
        &source.faces,
        source_colors,
    );
    let image = baked.to_rgb8();
    out.colors = None;
    out.texture = Some(std::sync::Arc::new(crate::mesh::Texture {
        image,
        path: None,
    }));
    Ok((out, atlas))
}

/// Barycentric coordinates of `p` in triangle `t` (`det` its doubled signed area).
#[inline]
fn barycentric(t: &[[f32; 2]; 3], det: f32, p: [f32; 2]) -> [f32; 3] {
    let b1 =
        ((p[0] - t[0][0]) * (t[2][1] - t[0][1]) - (t[2][0] - t[0][0]) * (p[1] - t[0][1])) / det;
    let b2 =
        ((t[1][0] - t[0][0]) * (p[1] - t[0][1]) - (p[0] - t[0][0]) * (t[1][1] - t[0][1])) / det;
    [1.0 - b1 - b2, b1, b2]
}

/// Per barycentric coordinate `k`, the distance from the line of the opposite edge per unit of
/// `-b[k]` (the triangle's height over that edge): `-b[k] * reach[k]` is a point's distance from
/// that line on the far side, a lower bound of its distance from the triangle.
fn edge_reach(t: &[[f32; 2]; 3], det: f32) -> [f32; 3] {
    std::array::from_fn(|k| {
        let (a, b) = (t[(k + 1) % 3], t[(k + 2) % 3]);
        let len = ((b[0] - a[0]).powi(2) + (b[1] - a[1]).powi(2)).sqrt();
        if len > 0.0 { det.abs() / len } else { 0.0 }
    })
}

/// Distance from `p` to the nearest of triangle `t`'s edges and the barycentric coordinates of
/// that nearest point (for a `p` outside the triangle: its distance to the triangle).
fn nearest_on_edges(t: &[[f32; 2]; 3], p: [f32; 2]) -> (f32, [f32; 3]) {
    let mut best = (f32::INFINITY, [1.0f32, 0.0, 0.0]);
    for k in 0..3 {
        let (a, b) = (t[k], t[(k + 1) % 3]);
        let e = [b[0] - a[0], b[1] - a[1]];
        let len2 = e[0] * e[0] + e[1] * e[1];
        let s = if len2 > 0.0 {
            (((p[0] - a[0]) * e[0] + (p[1] - a[1]) * e[1]) / len2).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let q = [a[0] + s * e[0] - p[0], a[1] + s * e[1] - p[1]];
        let d = (q[0] * q[0] + q[1] * q[1]).sqrt();
        if d < best.0 {
            let mut bary = [0.0f32; 3];
            bary[k] = 1.0 - s;
            bary[(k + 1) % 3] = s;
            best = (d, bary);
        }
    }
    best
}

/// Fill every uncovered texel of `img` from the covered ones by pull-push: each texel outside
/// the charts takes the (bilinearly upsampled) weighted mean of the coarsest pyramid level that
/// has coverage around it. Covered texels are unchanged. An image with no coverage is unchanged.
pub fn fill_gutters(img: &mut BakedImage) {
    let weights: Vec<f32> = img.covered.iter().map(|&c| c as u8 as f32).collect();
    pull_push(&mut img.pixels, &weights, img.width, img.height);
}

/// [`fill_gutters`] after `rings` rings of dilation, as the bakers of Substance Painter and
/// Blender extend their charts: each ring, every uncovered texel next to the charts (8
/// neighbours) takes the mean of its covered or already dilated neighbours; pull-push fills the
/// rest. Bilinear filtering and the first mip levels at a chart border then see the border's own
/// values. `img.covered` still marks the charts alone.
pub fn fill_gutters_dilated(img: &mut BakedImage, rings: usize) {
    let (w, h) = (img.width, img.height);
    let mut done = img.covered.clone();
    for _ in 0..rings {
        let next: Vec<Option<[f32; 3]>> = (0..w * h)
            .into_par_iter()
            .map(|i| {
                if done[i] {
                    return None;
                }
                let (x, y) = (i % w, i / w);
                let mut acc = [0.0f32; 3];
                let mut k = 0.0f32;
                for yy in y.saturating_sub(1)..(y + 2).min(h) {
                    for xx in x.saturating_sub(1)..(x + 2).min(w) {
                        let j = yy * w + xx;
                        if done[j] {
                            for (a, v) in acc.iter_mut().zip(img.pixels[j]) {
                                *a += v;
                            }
                            k += 1.0;
                        }
                    }
                }
                (k > 0.0).then(|| acc.map(|a| a / k))
            })
            .collect();
        let mut grew = false;
        for (i, v) in next.into_iter().enumerate() {
            if let Some(v) = v {
                img.pixels[i] = v;
                done[i] = true;
                grew = true;
            }
        }
        if !grew {
            break;
        }
    }
    let weights: Vec<f32> = done.iter().map(|&c| c as u8 as f32).collect();
    pull_push(&mut img.pixels, &weights, w, h);
}

fn pull_push(px: &mut [[f32; 3]], wt: &[f32], w: usize, h: usize) {
    if w <= 1 && h <= 1 {
        return;
    }
    let (cw, ch) = (w.div_ceil(2), h.div_ceil(2));
    // Pull: each coarse texel the weighted mean of its (up to) four fine ones, rows in parallel.
    let mut cpx = vec![[0.0f32; 3]; cw * ch];
    let mut cwt = vec![0.0f32; cw * ch];
    cpx.par_chunks_mut(cw)
        .zip(cwt.par_chunks_mut(cw))
        .enumerate()
        .for_each(|(y, (prow, wrow))| {
            for (x, (cp, cw_)) in prow.iter_mut().zip(wrow.iter_mut()).enumerate() {
                let mut acc = [0.0f32; 3];
                let mut s = 0.0f32;
                for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                    let (xx, yy) = (2 * x + dx, 2 * y + dy);
                    if xx < w && yy < h {
                        let i = yy * w + xx;
                        for c in 0..3 {
                            acc[c] += wt[i] * px[i][c];
                        }
                        s += wt[i];
                    }
                }
                if s > 0.0 {
                    *cp = acc.map(|a| a / s);
                }
                *cw_ = s.min(1.0);
            }
        });
    if cwt.iter().all(|&s| s == 0.0) {
        return;
    }
    pull_push(&mut cpx, &cwt, cw, ch);
    // Push: uncovered fine texels (weight < 1) blend towards the bilinear coarse value.
    px.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
        let fy = ((y as f32 + 0.5) / 2.0 - 0.5).clamp(0.0, (ch - 1) as f32);
        let (y0, ty) = (fy.floor() as usize, fy.fract());
        let y1 = (y0 + 1).min(ch - 1);
        for (x, p) in row.iter_mut().enumerate() {
            let wi = wt[y * w + x];
            if wi >= 1.0 {
                continue;
            }
            let fx = ((x as f32 + 0.5) / 2.0 - 0.5).clamp(0.0, (cw - 1) as f32);
            let (x0, tx) = (fx.floor() as usize, fx.fract());
            let x1 = (x0 + 1).min(cw - 1);
            let mut q = [0.0f32; 3];
            for c in 0..3 {
                let a = cpx[y0 * cw + x0][c] * (1.0 - tx) + cpx[y0 * cw + x1][c] * tx;
                let b = cpx[y1 * cw + x0][c] * (1.0 - tx) + cpx[y1 * cw + x1][c] * tx;
                q[c] = a * (1.0 - ty) + b * ty;
            }
            for c in 0..3 {
                p[c] = wi * p[c] + (1.0 - wi) * q[c];
            }
        }
    });
}

/// The mip chain of an sRGB image down to 1×1, with a GPU's level sizes (each side halved and
/// rounded down, at least 1: `floor(log2(max side)) + 1` levels, so that any size uploads as a
/// sampled texture): each level the 2×2 box average of the one above in linear light (an odd
/// side's last row or column is left out, as a GPU's own box filter leaves it). Level 0 is `img`
/// itself.
pub fn mip_chain(img: &image::RgbaImage) -> Vec<image::RgbaImage> {
    let mut levels = vec![img.clone()];
    while let Some(top) = levels.last() {
        let (w, h) = top.dimensions();
        if w <= 1 && h <= 1 {
            break;
        }
        let (nw, nh) = ((w / 2).max(1), (h / 2).max(1));
        let mut next = image::RgbaImage::new(nw, nh);
        for y in 0..nh {
            for x in 0..nw {
                let mut acc = [0.0f32; 4];
                for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                    let p = top
                        .get_pixel((2 * x + dx).min(w - 1), (2 * y + dy).min(h - 1))
                        .0;
                    for c in 0..3 {
                        acc[c] += crate::color::srgb_to_linear(p[c] as f32 / 255.0);
                    }
                    acc[3] += p[3] as f32 / 255.0;
                }
                let px = [
                    crate::color::linear_to_srgb(acc[0] / 4.0),
                    crate::color::linear_to_srgb(acc[1] / 4.0),
                    crate::color::linear_to_srgb(acc[2] / 4.0),
                    acc[3] / 4.0,
                ];
                next.put_pixel(
                    x,
                    y,
                    image::Rgba(px.map(|v| (v.clamp(0.0, 1.0) * 255.0).round() as u8)),
                );
            }
        }
        levels.push(next);
    }
    levels
}

/// Bilinear sample (sRGB values, interpolated in linear light) of `img` at `uv` (V up,
/// clamp-to-edge), as a GPU samples one mip level.
pub fn sample_bilinear(img: &image::RgbaImage, uv: [f32; 2]) -> [f32; 3] {
    let (w, h) = img.dimensions();
    let fx = (uv[0] * w as f32 - 0.5).clamp(0.0, (w - 1) as f32);
    let fy = ((1.0 - uv[1]) * h as f32 - 0.5).clamp(0.0, (h - 1) as f32);
    let (x0, y0) = (fx.floor() as u32, fy.floor() as u32);
    let (x1, y1) = ((x0 + 1).min(w - 1), (y0 + 1).min(h - 1));
    let (tx, ty) = (fx - x0 as f32, fy - y0 as f32);
    let lin = |x: u32, y: u32, c: usize| {
        crate::color::srgb_to_linear(img.get_pixel(x, y).0[c] as f32 / 255.0)
    };
    let mut out = [0.0f32; 3];
    for (c, o) in out.iter_mut().enumerate() {
        let a = lin(x0, y0, c) * (1.0 - tx) + lin(x1, y0, c) * tx;
        let b = lin(x0, y1, c) * (1.0 - tx) + lin(x1, y1, c) * tx;
        *o = crate::color::linear_to_srgb(a * (1.0 - ty) + b * ty);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_sliver_triangle_leaves_no_hole_and_gutters_are_filled() {
        // A needle triangle thinner than a texel, red, and a big green triangle elsewhere.
        let uvs = vec![
            [0.1, 0.1],
            [0.9, 0.1005],
            [0.9, 0.1],
            [0.2, 0.5],
            [0.8, 0.5],
            [0.5, 0.9],
        ];
        let mut img = bake_uv(&uvs, 2, 64, 64, |f, _| {
            if f == 0 {
                [1.0, 0.0, 0.0]
            } else {
                [0.0, 1.0, 0.0]
            }
        });
        // The needle's row is covered along its whole length.
        let y = ((1.0 - 0.1) * 64.0) as usize;
        let row: usize = (8..56)
            .filter(|&x| img.covered[y * 64 + x] || img.covered[(y - 1) * 64 + x])
            .count();
        assert_eq!(row, 48, "needle covered at {row} of 48 columns");
        fill_gutters(&mut img);
        // Every texel now has a colour from a chart: no black left.
        assert!(
            img.pixels.iter().all(|p| p[0] + p[1] > 0.99),
            "a texel stayed background"
        );
        // Covered texels were not changed by the fill.
        let c = (0.5 * 64.0) as usize;
        assert_eq!(img.pixels[(64 - c) * 64 + c], [0.0, 1.0, 0.0]);
    }

    #[test]
    fn mips_average_in_linear_light() {
        let mut img = image::RgbaImage::new(2, 2);
        img.put_pixel(0, 0, image::Rgba([255, 255, 255, 255]));
        img.put_pixel(1, 1, image::Rgba([255, 255, 255, 255]));
        let m = mip_chain(&img);
        assert_eq!(m.len(), 2);
        // Half white, half black in linear light is sRGB 188, not 128.
        let v = m[1].get_pixel(0, 0).0[0];
        assert!((186..=190).contains(&v), "{v}");
    }
}
