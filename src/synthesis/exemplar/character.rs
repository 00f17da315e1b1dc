//! How much of an image's character a texture on a surface keeps, measured texel by texel in
//! the texture's own UV layout, and the baseline artists use instead: triplanar (box)
//! projection of the image at the same world scale, baked into the same layout.
//!
//! - **Contrast**: the standard deviation of the texture's CIE L* over the image's (1 = kept).
//! - **Colour distribution**: the Wasserstein-1 distance ([`crate::stats::wasserstein1`]) between the texture's and the image's
//!   L*, a* and b* distributions (mean of the three; 0 = the same colours in the same amounts).
//! - **Patch distance**: 11x11 patches of the texture, read at the image's pixel size through
//!   each face's own texel frame (so a stretched or sheared chart reads the surface as it is),
//!   each to its nearest image patch (the best of 16 rotations of the texture patch and a
//!   mirror of the image): is everything on the surface from the image?
//! - **Reverse distance**: 11x11 image patches and their mirrors, each to its nearest texture
//!   patch (the texture's patches taken at 8 rotations): is all of the image on the surface?
//!
//! Both patch distances are root-mean-square sRGB differences in 0-255 units per pixel and
//! channel. The nearest patch is found as a continuum, not a sample: candidates by a
//! 12-dimensional PCA of patches smoothed by a one-pixel Gaussian, exact distances for the 12
//! nearest, and the best three refined by a pattern search in position and angle. An exact
//! copy of the image at any offset and turn measures near zero, and a blurred one further.

use std::f32::consts::TAU;

use glam::{Mat2, Vec2, Vec3};
use rand::Rng;
use rayon::prelude::*;

use super::pyramid::stage_rng;
use crate::mesh::TriMesh;

/// Side of a compared patch.
pub const PATCH: usize = 11;
/// Patches compared each way by [`measure`].
pub const SAMPLES: usize = 300;
/// PCA dimensions of the pre-filter (of patches smoothed by a one-pixel Gaussian, whose energy
/// lies in few directions).
const PCA_DIMS: usize = 12;
/// Image positions read (each also mirrored): every pixel of an image of up to about 410²,
/// evenly spaced beyond. A sample grid half a pixel off a thin line reads it at half its
/// contrast, so a sparser set misses the copy a texture patch is.
const IMAGE_POSITIONS: usize = 170_000;
/// Texture patches the reverse distance searches.
const TEXTURE_PATCHES: usize = 96_000;
/// Exact distances computed per query, from the PCA's nearest.
const RERANK: usize = 12;
/// Of those (over every rotation of a query), how many are refined in position and angle.
const REFINED: usize = 3;

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

    // per face, the texel offsets one image pixel apart along two orthogonal directions of
    // the surface: a patch of the texture is read at the image's pixel size wherever its chart
    // is stretched or sheared
    let pixel = ex.scale / iw as f32;
    let frames = texel_frames(mesh, uvs, tw, th, pixel);
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

    // image patches (with a mirror) at every pixel up to IMAGE_POSITIONS, and texture patches
    // (8 rotations)
    let stride = ((iw * ih) as f64 / IMAGE_POSITIONS as f64)
        .sqrt()
        .ceil()
        .max(1.0) as usize;
    let mut image_poses: Vec<Pose> = Vec::new();
    for y in (PATCH / 2..ih.saturating_sub(PATCH / 2)).step_by(stride) {
        for x in (PATCH / 2..iw.saturating_sub(PATCH / 2)).step_by(stride) {
            for mirror in [false, true] {
                image_poses.push(Pose {
                    c: Vec2::new(x as f32, y as f32),
                    angle: 0.0,
                    mirror,
                    frame: Mat2::IDENTITY,
                });
            }
        }
    }
    let centres: Vec<usize> = (0..tw * th).filter(|&i| covered[i]).collect();
    if centres.is_empty() || image_poses.is_empty() {
        return None;
    }
    let mut texture_poses: Vec<Pose> = Vec::new();
    let mut queries: Vec<Vec<Vec<f32>>> = Vec::new(); // per sample, its 16 rotations
    let mut tries = 0;
    while (texture_poses.len() < TEXTURE_PATCHES || queries.len() < samples)
        && tries < 400_000.max(4 * samples)
    {
        tries += 1;
        let c = centres[rng.random_range(0..centres.len())];
        let at = Vec2::new((c % tw) as f32, (c / tw) as f32);
        let Some(frame) = texels[c].and_then(|(f, _)| frames[f as usize]) else {
            continue;
        };
        if queries.len() < samples {
            let rots: Vec<Vec<f32>> = (0..16)
                .filter_map(|r| {
                    tex_img.read(Pose {
                        c: at,
                        angle: r as f32 * TAU / 16.0,
                        mirror: false,
                        frame,
                    })
                })
                .collect();
            if rots.len() == 16 {
                queries.push(rots);
                continue;
            }
        }
        if texture_poses.len() < TEXTURE_PATCHES {
            let a = rng.random::<f32>() * TAU;
            for r in 0..8 {
                let pose = Pose {
                    c: at,
                    angle: a + r as f32 * TAU / 8.0,
                    mirror: false,
                    frame,
                };
                texture_poses.push(pose);
            }
        }
    }
    if queries.is_empty() || texture_poses.is_empty() {
        return None;
    }
    // each image patch as it is and mirrored: a chart may show the surface either way round
    let image_queries: Vec<[Vec<f32>; 2]> = (0..samples)
        .filter_map(|_| {
            let x = rng.random_range(PATCH / 2..iw.saturating_sub(PATCH / 2).max(PATCH / 2 + 1));
            let y = rng.random_range(PATCH / 2..ih.saturating_sub(PATCH / 2).max(PATCH / 2 + 1));
            let read = |mirror| {
                img_grid.read(Pose {
                    c: Vec2::new(x as f32, y as f32),
                    angle: 0.0,
                    mirror,
                    frame: Mat2::IDENTITY,
                })
            };
            Some([read(false)?, read(true)?])
        })
        .collect();

    let basis = pca_basis(&img_grid, &image_poses)?;
    let forward = Index::new(&image_poses, &basis, &img_grid);
    // the image's patches lie `stride` pixels apart and the queries' rotations a sixteenth of
    // a turn: the nearest is refined within those gaps
    let patch_distance = queries
        .par_iter()
        .map(|rots| forward.distance(rots, |_| stride as f32 / 2.0, TAU / 32.0) as f64)
        .sum::<f64>()
        / queries.len() as f64;
    // the texture's patches lie at random texels, eight turns each: refined from half an image
    // pixel (in texels, through the patch's frame) and a sixteenth of a turn
    let reverse = Index::new(&texture_poses, &basis, &tex_img);
    let reverse_distance = image_queries
        .par_iter()
        .map(|both| {
            let half_pixel = |p: Pose| 0.5 * p.frame.determinant().abs().sqrt();
            reverse.distance(both, half_pixel, TAU / 16.0) as f64
        })
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

/// Per face, the texel offset of a step of `pixel` surface units along each of two orthogonal
/// directions in its plane (the first along its first edge), in the `tw × th` texture's pixel
/// grid (x right, y down); `None` for a face degenerate in space or in UV.
fn texel_frames(
    mesh: &TriMesh,
    uvs: &[[f32; 2]],
    tw: usize,
    th: usize,
    pixel: f32,
) -> Vec<Option<Mat2>> {
    (0..mesh.faces.len())
        .map(|f| {
            let p = mesh.faces[f].map(|v| Vec3::from(mesh.positions[v as usize]));
            let t = [0, 1, 2].map(|k| {
                let u = uvs[3 * f + k];
                Vec2::new(u[0] * tw as f32, (1.0 - u[1]) * th as f32)
            });
            let (e1, e2) = (p[1] - p[0], p[2] - p[0]);
            let n = e1.cross(e2);
            let (a, b) = (e1.normalize_or_zero(), n.cross(e1).normalize_or_zero());
            // the face's edges in its own orthonormal frame, and in texels
            let surface = Mat2::from_cols(
                Vec2::new(e1.dot(a), e1.dot(b)),
                Vec2::new(e2.dot(a), e2.dot(b)),
            );
            let texels = Mat2::from_cols(t[1] - t[0], t[2] - t[0]);
            if n.length_squared() <= 1e-30 || texels.determinant().abs() <= 1e-12 {
                return None;
            }
            // texel offset per surface offset, times the pixel's length
            let m = texels * surface.inverse() * pixel;
            m.is_finite().then_some(m)
        })
        .collect()
}

/// An image with a validity mask.
struct Grid<'a> {
    w: usize,
    h: usize,
    px: &'a [[f32; 3]],
    ok: &'a [bool],
}

/// Where a patch is read in a [`Grid`]: its centre in pixels, the angle its axes are turned
/// by, whether it is mirrored in x, and the grid offset of a step of one image pixel along each
/// axis (the identity in the image; the chart's local stretch in a texture).
#[derive(Clone, Copy, Debug)]
struct Pose {
    c: Vec2,
    angle: f32,
    mirror: bool,
    frame: Mat2,
}

impl Grid<'_> {
    /// The `PATCH²` patch at `pose`, bilinear; `None` when a sample's nearest pixels are not
    /// all valid.
    fn read(&self, pose: Pose) -> Option<Vec<f32>> {
        let Pose {
            c,
            angle,
            mirror,
            frame,
        } = pose;
        let (s, co) = angle.sin_cos();
        let mut out = Vec::with_capacity(PATCH * PATCH * 3);
        let r = (PATCH / 2) as f32;
        for j in 0..PATCH {
            for i in 0..PATCH {
                let mut u = i as f32 - r;
                let v = j as f32 - r;
                if mirror {
                    u = -u;
                }
                let at = c + frame * Vec2::new(co * u - s * v, s * u + co * v);
                let (x, y) = (at.x, at.y);
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

fn pca_basis(grid: &Grid, poses: &[Pose]) -> Option<Basis> {
    let step = (poses.len() / 4000).max(1);
    let sample: Vec<Vec<f32>> = poses
        .iter()
        .step_by(step)
        .filter_map(|&p| grid.read(p))
        .map(|p| smoothed(&p))
        .collect();
    let d = sample.first()?.len();
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
    Some(Basis { mean, dirs })
}

/// Patches read from a grid, with their poses and PCA coordinates, for nearest-patch queries.
struct Index<'a> {
    /// The patches that can be read; each is read again when its exact distance is asked.
    poses: Vec<Pose>,
    coords: Vec<f32>,
    basis: &'a Basis,
    grid: &'a Grid<'a>,
}

impl<'a> Index<'a> {
    fn new(poses: &[Pose], basis: &'a Basis, grid: &'a Grid<'a>) -> Index<'a> {
        let read: Vec<(Pose, Vec<f32>)> = poses
            .par_iter()
            .filter_map(|&pose| Some((pose, project(basis, &grid.read(pose)?))))
            .collect();
        let coords = read.iter().flat_map(|(_, c)| c.iter().copied()).collect();
        Index {
            poses: read.into_iter().map(|(p, _)| p).collect(),
            coords,
            basis,
            grid,
        }
    }

    /// RMS distance (per element, in [0, 1] units) of `q` to the patch read at `pose`;
    /// infinite where it cannot be read.
    fn distance_at(&self, q: &[f32], pose: Pose) -> f32 {
        self.grid.read(pose).map_or(f32::INFINITY, |p| rms(&p, q))
    }

    /// The distance of `q` to the grid's patch nearest it in position and angle, starting from
    /// stored patch `i` at distance `d`: a pattern search in the centre (from `dp` pixels) and
    /// the angle (from `da`), each halved four times. The stored patches are samples of a
    /// continuum; a texture that is an exact copy of the image at some offset and turn should
    /// read as such, not as far as the nearest sample happens to be.
    fn refine(&self, q: &[f32], i: usize, d: f32, dp: f32, da: f32) -> f32 {
        let mut pose = self.poses[i];
        let mut best = d;
        let (mut dp, mut da) = (dp, da);
        for _ in 0..5 {
            loop {
                let mut moved = false;
                for (dx, dy, dt) in [
                    (dp, 0.0, 0.0),
                    (-dp, 0.0, 0.0),
                    (0.0, dp, 0.0),
                    (0.0, -dp, 0.0),
                    (0.0, 0.0, da),
                    (0.0, 0.0, -da),
                ] {
                    let p = Pose {
                        c: pose.c + Vec2::new(dx, dy),
                        angle: pose.angle + dt,
                        ..pose
                    };
                    let e = self.distance_at(q, p);
                    if e < best {
                        best = e;
                        pose = p;
                        moved = true;
                    }
                }
                if !moved {
                    break;
                }
            }
            dp *= 0.5;
            da *= 0.5;
        }
        best
    }

    /// The distance of the nearest of `readings` (a patch's rotations, or it and its mirror)
    /// to the grid: the stored candidates of every reading, the best [`REFINED`] of them
    /// refined from `dp(pose)` pixels and `da` radians.
    fn distance(&self, readings: &[Vec<f32>], dp: impl Fn(Pose) -> f32, da: f32) -> f32 {
        let mut found: Vec<(f32, usize, usize)> = readings
            .iter()
            .enumerate()
            .flat_map(|(r, q)| self.nearest(q).into_iter().map(move |(d, i)| (d, i, r)))
            .collect();
        found.sort_by(|a, b| a.0.total_cmp(&b.0));
        found
            .iter()
            .take(REFINED)
            .map(|&(d, i, r)| self.refine(&readings[r], i, d, dp(self.poses[i]), da))
            .fold(f32::INFINITY, f32::min)
    }

    /// The stored patches nearest `q` by their smoothed PCA coordinates, each with its RMS
    /// distance to `q` (per element, in [0, 1] units).
    fn nearest(&self, q: &[f32]) -> Vec<(f32, usize)> {
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
            .map(|&(_, i)| (self.distance_at(q, self.poses[i]), i))
            .collect()
    }
}

/// RMS difference of two patches, per element.
fn rms(a: &[f32], b: &[f32]) -> f32 {
    (a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum::<f32>() / b.len().max(1) as f32)
        .max(0.0)
        .sqrt()
}

/// `p` smoothed by a [1 4 6 4 1] binomial (a Gaussian of one pixel) in each direction, its
/// border clamped: sharp content that a sampling grid half a pixel or a few degrees off
/// misreads stays near in these coordinates, so the exact search that follows starts from the
/// right place.
fn smoothed(p: &[f32]) -> Vec<f32> {
    const K: [f32; 5] = [1.0 / 16.0, 4.0 / 16.0, 6.0 / 16.0, 4.0 / 16.0, 1.0 / 16.0];
    let at = |i: isize| i.clamp(0, PATCH as isize - 1) as usize;
    let mut rows = vec![0.0f32; p.len()];
    for j in 0..PATCH {
        for i in 0..PATCH {
            for ch in 0..3 {
                rows[(j * PATCH + i) * 3 + ch] = (0..5)
                    .map(|k| K[k] * p[(j * PATCH + at(i as isize + k as isize - 2)) * 3 + ch])
                    .sum();
            }
        }
    }
    let mut out = vec![0.0f32; p.len()];
    for j in 0..PATCH {
        for i in 0..PATCH {
            for ch in 0..3 {
                out[(j * PATCH + i) * 3 + ch] = (0..5)
                    .map(|k| K[k] * rows[(at(j as isize + k as isize - 2) * PATCH + i) * 3 + ch])
                    .sum();
            }
        }
    }
    out
}

/// PCA coordinates of `p` smoothed.
fn project(basis: &Basis, p: &[f32]) -> Vec<f32> {
    let p = smoothed(p);
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
