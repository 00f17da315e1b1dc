//! How much of an image's character a texture on a surface keeps, measured texel by texel in
//! the texture's own UV layout, and the baseline artists use instead: triplanar (box)
//! projection of the image at the same world scale, baked into the same layout.
//!
//! - **Contrast**: the standard deviation of the texture's CIE L* over the image's (1 = kept).
//! - **Colour distribution**: the Wasserstein-1 distance ([`crate::stats::wasserstein1`]) between the texture's and the image's
//!   L*, a* and b* distributions (mean of the three; 0 = the same colours in the same amounts).
//! - **Patch distance**: 11x11 patches of the texture, resampled at the image's pixel size in a
//!   chart's texel grid, each to its nearest image patch (the best of 16 rotations of the
//!   texture patch and a mirror of the image): is everything on the surface from the image?
//! - **Reverse distance**: 11x11 image patches, each to its nearest texture patch (the texture's
//!   patches taken at 8 rotations): is all of the image on the surface?
//!
//! Both patch distances are root-mean-square sRGB differences in 0-255 units per pixel and
//! channel; the search is exact, on candidates pre-filtered by a 24-dimensional PCA projection.

use glam::{Vec2, Vec3};
use rand::Rng;
use rayon::prelude::*;

use super::pyramid::stage_rng;
use crate::mesh::TriMesh;

/// Side of a compared patch.
pub const PATCH: usize = 11;
/// Patches compared each way by [`measure`].
pub const SAMPLES: usize = 300;
/// PCA dimensions of the pre-filter.
const PCA_DIMS: usize = 24;
/// Exact distances computed per query, from the PCA's nearest.
const RERANK: usize = 12;

/// A texture's character against its image.
#[derive(Clone, Copy, Debug, Default, serde::Serialize)]
pub struct Character {
    /// Std of L* over the image's.
    pub contrast: f64,
    /// Mean Wasserstein-1 of L*, a*, b* against the image.
    pub lab_w1: f64,
    /// Mean distance of texture patches to their nearest image patch (0-255 RMS).
    pub patch_distance: f64,
    /// Mean distance of image patches to their nearest texture patch (0-255 RMS).
    pub reverse_distance: f64,
}

/// The image as the measures read it: sRGB in [0, 1], and which pixels are opaque.
pub struct Exemplar<'a> {
    /// Colours.
    pub image: &'a image::RgbImage,
    /// Alpha (pixels under 128 are left out), if any.
    pub alpha: Option<&'a image::GrayImage>,
    /// Surface units the image's width spans.
    pub scale: f32,
}

/// Triplanar projection of the image (tiled, at `scale` surface units per image width, blended
/// by the fourth power of the normal's components) baked into `mesh`'s UVs at `size²`, gutters
/// filled. `None` when the mesh has no per-corner UVs.
pub fn triplanar_texture(mesh: &TriMesh, ex: &Exemplar, size: usize) -> Option<image::RgbImage> {
    let uvs = mesh
        .uvs
        .as_ref()
        .filter(|u| u.len() == 3 * mesh.faces.len())?;
    let normals = crate::geometry::vertex_normals(&mesh.positions, &mesh.faces);
    let (w, h) = ex.image.dimensions();
    // transparent pixels show their surroundings' colours, as a projection painted over
    // would
    let filled = ex
        .alpha
        .and_then(|a| super::transparent_filled(ex.image, a).ok())
        .map(|(img, _)| img);
    let pixel = ex.scale / w as f32;
    let read = |x: f32, y: f32| -> [f32; 3] {
        // tiled, bilinear
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let at = |xi: i64, yi: i64| {
            let (x, y) = (
                xi.rem_euclid(w as i64) as u32,
                yi.rem_euclid(h as i64) as u32,
            );
            match &filled {
                Some(f) => f.px[y as usize * f.w + x as usize],
                None => crate::color::from_u8(ex.image.get_pixel(x, y).0),
            }
        };
        let (xi, yi) = (x0 as i64, y0 as i64);
        let (a, b, c, d) = (
            at(xi, yi),
            at(xi + 1, yi),
            at(xi, yi + 1),
            at(xi + 1, yi + 1),
        );
        [0, 1, 2].map(|k| {
            (a[k] * (1.0 - fx) + b[k] * fx) * (1.0 - fy) + (c[k] * (1.0 - fx) + d[k] * fx) * fy
        })
    };
    let mut baked = crate::geometry::bake_uv(uvs, mesh.faces.len(), size, size, |f, b| {
        let face = mesh.faces[f];
        let p = (0..3).fold(Vec3::ZERO, |acc, k| {
            acc + b[k] * Vec3::from(mesh.positions[face[k] as usize])
        });
        let n = (0..3)
            .fold(Vec3::ZERO, |acc, k| {
                acc + b[k] * Vec3::from(normals[face[k] as usize])
            })
            .normalize_or(Vec3::Y);
        let wgt = n.abs().to_array().map(|x| x.powi(4));
        let total: f32 = wgt.iter().sum::<f32>().max(1e-12);
        let planes = [(p.z, p.y), (p.x, p.z), (p.x, p.y)];
        let mut c = [0.0f32; 3];
        for (axis, &(u, v)) in planes.iter().enumerate() {
            if wgt[axis] <= 0.0 {
                continue;
            }
            let s = read(u / pixel, -v / pixel);
            for k in 0..3 {
                c[k] += wgt[axis] / total * s[k];
            }
        }
        c
    });
    crate::geometry::fill_gutters(&mut baked);
    Some(baked.to_rgb8())
}

/// Measure `texture` (through `mesh`'s UVs) against the image. `None` when the mesh has no
/// per-corner UVs or the layout covers too little to sample patches.
pub fn measure(
    mesh: &TriMesh,
    texture: &image::RgbImage,
    ex: &Exemplar,
    seed: u64,
) -> Option<Character> {
    measure_with(mesh, texture, ex, seed, SAMPLES)
}

/// [`measure`] with `samples` patches compared each way: the patch and reverse distances are
/// means over samples, so their standard error falls as one over its square root.
pub fn measure_with(
    mesh: &TriMesh,
    texture: &image::RgbImage,
    ex: &Exemplar,
    seed: u64,
    samples: usize,
) -> Option<Character> {
    let samples = samples.max(1);
    let uvs = mesh
        .uvs
        .as_ref()
        .filter(|u| u.len() == 3 * mesh.faces.len())?;
    let (tw, th) = (texture.width() as usize, texture.height() as usize);
    let texels = crate::geometry::uv_texels(uvs, mesh.faces.len(), tw, th);
    let covered: Vec<bool> = texels.iter().map(|t| t.is_some()).collect();
    let tex: Vec<[f32; 3]> = texture
        .pixels()
        .map(|p| crate::color::from_u8(p.0))
        .collect();
    let (iw, ih) = (ex.image.width() as usize, ex.image.height() as usize);
    let img: Vec<[f32; 3]> = ex
        .image
        .pixels()
        .map(|p| crate::color::from_u8(p.0))
        .collect();
    let opaque: Vec<bool> = match ex.alpha {
        Some(a) => a.pixels().map(|p| p.0[0] >= 128).collect(),
        None => vec![true; iw * ih],
    };

    let (contrast, lab_w1) = colour_character(&tex, &covered, &img, &opaque)?;

    // texels per image pixel: the layout's mean surface length per texel against the image's
    let mut uv_area = 0.0f64;
    for f in 0..mesh.faces.len() {
        let t = [0, 1, 2].map(|k| Vec2::from(uvs[3 * f + k]).as_dvec2());
        uv_area += 0.5 * (t[1] - t[0]).perp_dot(t[2] - t[0]).abs();
    }
    let texel_len = (mesh.area() / (uv_area.max(1e-12) * (tw * th) as f64)).sqrt();
    let step = (ex.scale as f64 / iw as f64 / texel_len) as f32;
    let tex_img = Grid {
        w: tw,
        h: th,
        px: &tex,
        ok: &covered,
    };
    let img_grid = Grid {
        w: iw,
        h: ih,
        px: &img,
        ok: &opaque,
    };
    let mut rng = stage_rng(seed, 41);

    // image patches (with a mirror) and texture patches (8 rotations)
    let stride = ((iw * ih) as f64 / 40_000.0).sqrt().ceil().max(1.0) as usize;
    let mut image_patches: Vec<Vec<f32>> = Vec::new();
    for y in (PATCH / 2..ih.saturating_sub(PATCH / 2)).step_by(stride) {
        for x in (PATCH / 2..iw.saturating_sub(PATCH / 2)).step_by(stride) {
            for mirror in [false, true] {
                if let Some(p) = img_grid.patch(Vec2::new(x as f32, y as f32), 1.0, 0.0, mirror) {
                    image_patches.push(p);
                }
            }
        }
    }
    let centres: Vec<usize> = (0..tw * th).filter(|&i| covered[i]).collect();
    if centres.is_empty() || image_patches.is_empty() {
        return None;
    }
    let mut texture_patches: Vec<Vec<f32>> = Vec::new();
    let mut queries: Vec<Vec<Vec<f32>>> = Vec::new(); // per sample, its 16 rotations
    let mut tries = 0;
    while (texture_patches.len() < 96_000 || queries.len() < samples)
        && tries < 400_000.max(4 * samples)
    {
        tries += 1;
        let c = centres[rng.random_range(0..centres.len())];
        let at = Vec2::new((c % tw) as f32, (c / tw) as f32);
        if queries.len() < samples {
            let rots: Vec<Vec<f32>> = (0..16)
                .filter_map(|r| {
                    tex_img.patch(at, step, r as f32 * std::f32::consts::TAU / 16.0, false)
                })
                .collect();
            if rots.len() == 16 {
                queries.push(rots);
                continue;
            }
        }
        if texture_patches.len() < 96_000 {
            let a = rng.random::<f32>() * std::f32::consts::TAU;
            for r in 0..8 {
                if let Some(p) =
                    tex_img.patch(at, step, a + r as f32 * std::f32::consts::TAU / 8.0, false)
                {
                    texture_patches.push(p);
                }
            }
        }
    }
    if queries.is_empty() || texture_patches.is_empty() {
        return None;
    }
    let image_queries: Vec<Vec<f32>> = (0..samples)
        .filter_map(|_| {
            let x = rng.random_range(PATCH / 2..iw.saturating_sub(PATCH / 2).max(PATCH / 2 + 1));
            let y = rng.random_range(PATCH / 2..ih.saturating_sub(PATCH / 2).max(PATCH / 2 + 1));
            img_grid.patch(Vec2::new(x as f32, y as f32), 1.0, 0.0, false)
        })
        .collect();

    let basis = pca_basis(&image_patches);
    let forward = Index::new(&image_patches, &basis);
    let patch_distance = queries
        .par_iter()
        .map(|rots| {
            rots.iter()
                .map(|q| forward.nearest(q))
                .fold(f32::INFINITY, f32::min) as f64
        })
        .sum::<f64>()
        / queries.len() as f64;
    let reverse = Index::new(&texture_patches, &basis);
    let reverse_distance = image_queries
        .par_iter()
        .map(|q| reverse.nearest(q) as f64)
        .sum::<f64>()
        / image_queries.len().max(1) as f64;
    Some(Character {
        contrast,
        lab_w1,
        patch_distance: 255.0 * patch_distance,
        reverse_distance: 255.0 * reverse_distance,
    })
}

/// Contrast (std of L* over the image's) and Lab W1 (Wasserstein-1 of L*, a*, b*, mean) of the
/// covered texels against the opaque image pixels; `None` when either is empty.
fn colour_character(
    tex: &[[f32; 3]],
    covered: &[bool],
    img: &[[f32; 3]],
    opaque: &[bool],
) -> Option<(f64, f64)> {
    let lab_t: Vec<[f32; 3]> = tex
        .iter()
        .zip(covered)
        .filter(|(_, c)| **c)
        .map(|(c, _)| crate::color::srgb_to_lab(*c))
        .collect();
    let lab_i: Vec<[f32; 3]> = img
        .iter()
        .zip(opaque)
        .filter(|(_, o)| **o)
        .map(|(c, _)| crate::color::srgb_to_lab(*c))
        .collect();
    if lab_t.is_empty() || lab_i.is_empty() {
        return None;
    }
    let std_l = |v: &[[f32; 3]]| {
        let n = v.len() as f64;
        let m = v.iter().map(|c| c[0] as f64).sum::<f64>() / n;
        (v.iter().map(|c| (c[0] as f64 - m).powi(2)).sum::<f64>() / n).sqrt()
    };
    let contrast = std_l(&lab_t) / std_l(&lab_i).max(1e-9);
    let lab_w1 = (0..3)
        .map(|k| {
            crate::stats::wasserstein1(
                &lab_t.iter().map(|c| c[k]).collect::<Vec<_>>(),
                &lab_i.iter().map(|c| c[k]).collect::<Vec<_>>(),
            )
        })
        .sum::<f64>()
        / 3.0;

    Some((contrast, lab_w1))
}

/// An image with a validity mask.
struct Grid<'a> {
    w: usize,
    h: usize,
    px: &'a [[f32; 3]],
    ok: &'a [bool],
}

impl Grid<'_> {
    /// The `PATCH²` patch centred at `c`, its samples `step` pixels apart along axes turned by
    /// `angle` (mirrored in x when asked), bilinear; `None` when a sample's nearest pixels are
    /// not all valid.
    fn patch(&self, c: Vec2, step: f32, angle: f32, mirror: bool) -> Option<Vec<f32>> {
        let (s, co) = angle.sin_cos();
        let mut out = Vec::with_capacity(PATCH * PATCH * 3);
        let r = (PATCH / 2) as f32;
        for j in 0..PATCH {
            for i in 0..PATCH {
                let mut u = (i as f32 - r) * step;
                let v = (j as f32 - r) * step;
                if mirror {
                    u = -u;
                }
                let x = c.x + co * u - s * v;
                let y = c.y + s * u + co * v;
                let (x0, y0) = (x.floor(), y.floor());
                if x0 < 0.0 || y0 < 0.0 || x0 + 1.0 >= self.w as f32 || y0 + 1.0 >= self.h as f32 {
                    return None;
                }
                let (xi, yi) = (x0 as usize, y0 as usize);
                let (fx, fy) = (x - x0, y - y0);
                let idx = [
                    yi * self.w + xi,
                    yi * self.w + xi + 1,
                    (yi + 1) * self.w + xi,
                    (yi + 1) * self.w + xi + 1,
                ];
                if idx.iter().any(|&k| !self.ok[k]) {
                    return None;
                }
                let wts = [
                    (1.0 - fx) * (1.0 - fy),
                    fx * (1.0 - fy),
                    (1.0 - fx) * fy,
                    fx * fy,
                ];
                for ch in 0..3 {
                    out.push((0..4).map(|k| wts[k] * self.px[idx[k]][ch]).sum());
                }
            }
        }
        Some(out)
    }
}

/// A PCA basis: the mean and the leading directions (power iteration with deflation on a
/// sample).
struct Basis {
    mean: Vec<f32>,
    dirs: Vec<Vec<f32>>,
}

fn pca_basis(patches: &[Vec<f32>]) -> Basis {
    let d = patches[0].len();
    let step = (patches.len() / 4000).max(1);
    let sample: Vec<&Vec<f32>> = patches.iter().step_by(step).collect();
    let mut mean = vec![0.0f32; d];
    for p in &sample {
        for k in 0..d {
            mean[k] += p[k];
        }
    }
    mean.iter_mut().for_each(|m| *m /= sample.len() as f32);
    // covariance
    let mut cov = vec![0.0f64; d * d];
    for p in &sample {
        let c: Vec<f64> = (0..d).map(|k| (p[k] - mean[k]) as f64).collect();
        for i in 0..d {
            for j in i..d {
                cov[i * d + j] += c[i] * c[j];
            }
        }
    }
    for i in 0..d {
        for j in 0..i {
            cov[i * d + j] = cov[j * d + i];
        }
    }
    let mut dirs: Vec<Vec<f32>> = Vec::new();
    let mut rng = stage_rng(7, 43);
    for _ in 0..PCA_DIMS.min(d) {
        let mut v: Vec<f64> = (0..d).map(|_| rng.random::<f64>() - 0.5).collect();
        for _ in 0..60 {
            let mut w = vec![0.0f64; d];
            for i in 0..d {
                let row = &cov[i * d..(i + 1) * d];
                w[i] = row.iter().zip(&v).map(|(a, b)| a * b).sum();
            }
            for u in &dirs {
                let dot: f64 = w.iter().zip(u).map(|(a, b)| a * *b as f64).sum();
                for k in 0..d {
                    w[k] -= dot * u[k] as f64;
                }
            }
            let n = w.iter().map(|x| x * x).sum::<f64>().sqrt();
            if n <= 1e-12 {
                break;
            }
            v = w.iter().map(|x| x / n).collect();
        }
        dirs.push(v.iter().map(|&x| x as f32).collect());
    }
    Basis { mean, dirs }
}

/// Patches with their PCA coordinates, for nearest-patch queries.
struct Index<'a> {
    patches: &'a [Vec<f32>],
    coords: Vec<f32>,
    basis: &'a Basis,
}

impl<'a> Index<'a> {
    fn new(patches: &'a [Vec<f32>], basis: &'a Basis) -> Index<'a> {
        let coords = patches
            .par_iter()
            .flat_map_iter(|p| project(basis, p))
            .collect();
        Index {
            patches,
            coords,
            basis,
        }
    }

    /// RMS distance (per element, in [0, 1] units) of `q` to its nearest patch.
    fn nearest(&self, q: &[f32]) -> f32 {
        let pq = project(self.basis, q);
        let k = pq.len();
        let mut best: Vec<(f32, usize)> = Vec::with_capacity(RERANK + 1);
        for (i, c) in self.coords.chunks_exact(k).enumerate() {
            let d: f32 = c.iter().zip(&pq).map(|(a, b)| (a - b) * (a - b)).sum();
            if best.len() < RERANK || d < best[best.len() - 1].0 {
                let at = best.partition_point(|e| e.0 <= d);
                best.insert(at, (d, i));
                best.truncate(RERANK);
            }
        }
        best.iter()
            .map(|&(_, i)| {
                self.patches[i]
                    .iter()
                    .zip(q)
                    .map(|(a, b)| (a - b) * (a - b))
                    .sum::<f32>()
            })
            .fold(f32::INFINITY, f32::min)
            .max(0.0)
            .sqrt()
            / (q.len() as f32).sqrt()
    }
}

fn project(basis: &Basis, p: &[f32]) -> Vec<f32> {
    basis
        .dirs
        .iter()
        .map(|u| {
            u.iter()
                .zip(p.iter().zip(&basis.mean))
                .map(|(a, (x, m))| a * (x - m))
                .sum()
        })
        .collect()
}
