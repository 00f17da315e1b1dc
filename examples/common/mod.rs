//! The preview examples' one software rasteriser (`mod common;` in each): orthographic,
//! z-buffered, Lambert-shaded vertex colours, for machines without a GPU (`meshmatch render`
//! draws with wgpu). Not an example itself: Cargo only builds the `.rs` files directly under
//! `examples/`.

#![allow(dead_code)] // each example uses part of it

use glam::{Mat3, Vec3};

/// How a preview looks beyond the mesh: its background, and whether faces seen from behind
/// (by their normals) show red, so that orientation errors are visible.
#[derive(Clone, Copy)]
pub struct Look {
    pub background: [u8; 3],
    pub flag_back_faces: bool,
}

impl Default for Look {
    fn default() -> Self {
        Look {
            background: [235, 235, 240],
            flag_back_faces: false,
        }
    }
}

/// The rotation that views a mesh from direction `eye` (pointing from the object to the
/// camera), y up: the camera looks down the rotated frame's -z.
pub fn look_from(eye: Vec3) -> Mat3 {
    let back = eye.normalize();
    let right = Vec3::Y.cross(back).normalize_or(Vec3::X);
    let up = back.cross(right);
    Mat3::from_cols(right, up, back).transpose()
}

/// Render a mesh turned by `rot` (the camera looks down -z, y up), framed by its bounding
/// sphere, into a `w` x `h` image. `colors` per vertex (sRGB, 0-1; grey without), `normals`
/// per vertex (the faces' own without), shaded two-sided by a headlight from above left.
pub fn render(
    positions: &[[f32; 3]],
    faces: &[[u32; 3]],
    colors: Option<&[[f32; 3]]>,
    normals: Option<&[[f32; 3]]>,
    rot: Mat3,
    (w, h): (u32, u32),
    look: Look,
) -> image::RgbImage {
    let mut img = image::RgbImage::from_pixel(w, h, image::Rgb(look.background));
    let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
    for p in positions {
        lo = lo.min(Vec3::from(*p));
        hi = hi.max(Vec3::from(*p));
    }
    if !(lo.is_finite() && hi.is_finite()) {
        return img;
    }
    let centre = 0.5 * (lo + hi);
    let radius = (0.5 * (hi - lo).length()).max(1e-12);
    let scale = 0.96 * w.min(h) as f32 / (2.0 * radius);
    let screen: Vec<Vec3> = positions
        .iter()
        .map(|p| {
            let q = rot * (Vec3::from(*p) - centre);
            Vec3::new(
                0.5 * w as f32 + q.x * scale,
                0.5 * h as f32 - q.y * scale,
                q.z,
            )
        })
        .collect();
    let light = Vec3::new(0.3, 0.5, 1.0).normalize();
    let grey = [0.8, 0.8, 0.8];
    let colour = |v: u32| colors.map_or(grey, |c| c[v as usize]);
    let mut depth = vec![f32::NEG_INFINITY; (w * h) as usize];
    for f in faces {
        let [a, b, c] = f.map(|i| screen[i as usize]);
        let area = (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
        if area.abs() < 1e-12 {
            continue;
        }
        let face_normal = {
            let [p, q, r] = f.map(|i| rot * Vec3::from(positions[i as usize]));
            (q - p).cross(r - p).normalize_or_zero()
        };
        let x0 = a.x.min(b.x).min(c.x).floor().max(0.0) as i64;
        let x1 = a.x.max(b.x).max(c.x).ceil().min(w as f32 - 1.0) as i64;
        let y0 = a.y.min(b.y).min(c.y).floor().max(0.0) as i64;
        let y1 = a.y.max(b.y).max(c.y).ceil().min(h as f32 - 1.0) as i64;
        for y in y0..=y1 {
            for x in x0..=x1 {
                let (px, py) = (x as f32 + 0.5, y as f32 + 0.5);
                let w0 = ((b.x - px) * (c.y - py) - (b.y - py) * (c.x - px)) / area;
                let w1 = ((c.x - px) * (a.y - py) - (c.y - py) * (a.x - px)) / area;
                let w2 = 1.0 - w0 - w1;
                if w0 < 0.0 || w1 < 0.0 || w2 < 0.0 {
                    continue;
                }
                let z = w0 * a.z + w1 * b.z + w2 * c.z;
                let k = (y as u32 * w + x as u32) as usize;
                if z <= depth[k] {
                    continue;
                }
                depth[k] = z;
                let n = match normals {
                    Some(nv) => (rot
                        * (Vec3::from(nv[f[0] as usize]) * w0
                            + Vec3::from(nv[f[1] as usize]) * w1
                            + Vec3::from(nv[f[2] as usize]) * w2))
                        .normalize_or_zero(),
                    None => face_normal,
                };
                let rgb = if look.flag_back_faces && n.z < -0.2 {
                    [1.0, 0.0, 0.0]
                } else {
                    let shade = 0.35 + 0.65 * n.dot(light).abs();
                    let [c0, c1, c2] = f.map(colour);
                    std::array::from_fn(|i| (c0[i] * w0 + c1[i] * w1 + c2[i] * w2) * shade)
                };
                img.put_pixel(
                    x as u32,
                    y as u32,
                    image::Rgb(rgb.map(|v: f32| (v.clamp(0.0, 1.0) * 255.0).round() as u8)),
                );
            }
        }
    }
    img
}

/// [`render`] from each of `rots`, side by side, each view `size` square.
pub fn side_by_side(
    positions: &[[f32; 3]],
    faces: &[[u32; 3]],
    colors: Option<&[[f32; 3]]>,
    normals: Option<&[[f32; 3]]>,
    rots: &[Mat3],
    size: u32,
    look: Look,
) -> image::RgbImage {
    let mut out = image::RgbImage::new(size * rots.len() as u32, size);
    for (k, rot) in rots.iter().enumerate() {
        let view = render(positions, faces, colors, normals, *rot, (size, size), look);
        image::imageops::replace(&mut out, &view, (k as u32 * size) as i64, 0);
    }
    out
}

/// The three turns the transfer previews show: front left, back right and side, tilted down.
pub fn three_turns() -> Vec<Mat3> {
    [0.6f32, 2.2, -1.6]
        .iter()
        .map(|yaw| Mat3::from_rotation_x(0.25) * Mat3::from_rotation_y(*yaw))
        .collect()
}
