//! Detailed procedural textures: what a working-resolution result cannot carry (mortar lines of
//! 2-3 texels, checkers of 2-4 texels, hairlines, glyphs, eyes).

/// Which detailed texture.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TextureKind {
    /// Running-bond bricks (about 24 x 10 texels at 1024^2, scaled with the size) with mortar
    /// lines of 2-3 texels and a per-brick tint.
    Bricks,
    /// Bands of checkers of 2, 3 and 4 texels, one-texel hairlines, rows of glyphs and eyes
    /// (concentric rings with a highlight).
    Mixed,
}

/// 5x7 glyphs (one row of bits per line, high bit on the left) for the texture's text rows.
const GLYPHS: [[u8; 7]; 8] = [
    [0x0E, 0x11, 0x11, 0x1F, 0x11, 0x11, 0x11], // A
    [0x1E, 0x11, 0x11, 0x1E, 0x11, 0x11, 0x1E], // B
    [0x11, 0x1B, 0x15, 0x15, 0x11, 0x11, 0x11], // M
    [0x1F, 0x10, 0x10, 0x1E, 0x10, 0x10, 0x1F], // E
    [0x0E, 0x11, 0x10, 0x17, 0x11, 0x11, 0x0F], // G
    [0x1F, 0x04, 0x04, 0x04, 0x04, 0x04, 0x04], // T
    [0x11, 0x11, 0x11, 0x11, 0x11, 0x11, 0x0E], // U
    [0x1E, 0x11, 0x11, 0x1E, 0x14, 0x12, 0x11], // R
];

/// A `size x size` sRGB texture of `kind` (deterministic).
pub fn detailed_texture(kind: TextureKind, size: u32) -> image::RgbImage {
    let s = size.max(16);
    let scale = s as f32 / 1024.0;
    image::RgbImage::from_fn(s, s, |x, y| {
        let c = match kind {
            TextureKind::Bricks => brick(x, y, scale),
            TextureKind::Mixed => mixed(x, y, s),
        };
        image::Rgb(c)
    })
}

fn hash(a: u32, b: u32) -> u32 {
    let mut h = a.wrapping_mul(0x9E37_79B1) ^ b.wrapping_mul(0x85EB_CA77);
    h ^= h >> 15;
    h = h.wrapping_mul(0x2C1B_3C6D);
    h ^ (h >> 12)
}

fn brick(x: u32, y: u32, scale: f32) -> [u8; 3] {
    let bw = (24.0 * scale).round().max(6.0) as u32;
    let bh = (10.0 * scale).round().max(4.0) as u32;
    let mortar = if scale >= 1.5 { 3 } else { 2 };
    let row = y / bh;
    let shift = if row % 2 == 1 { bw / 2 } else { 0 };
    let col = (x + shift) / bw;
    let (lx, ly) = ((x + shift) % bw, y % bh);
    if lx < mortar || ly < mortar {
        return [214, 208, 196];
    }
    let t = hash(col, row) % 60;
    [150 + (t as u8) / 2, 52 + (t as u8) / 3, 38 + (t as u8) / 4]
}

fn mixed(x: u32, y: u32, size: u32) -> [u8; 3] {
    let band = size / 8;
    let b = (y / band.max(1)) % 4;
    match b {
        // checkers of 2, 3 and 4 texels side by side
        0 => {
            let third = size / 3;
            let cell = 2 + (x / third.max(1)).min(2);
            if ((x / cell) + (y / cell)).is_multiple_of(2) {
                [20, 20, 24]
            } else {
                [236, 232, 220]
            }
        }
        // hairlines: one texel wide, every 6 texels, both directions
        1 => {
            if x.is_multiple_of(6) || y.is_multiple_of(9) {
                [30, 40, 160]
            } else {
                [240, 236, 228]
            }
        }
        // glyph rows: 5x7 letters at 2 texels per dot
        2 => {
            let (gx, gy) = (x / 2 % 7, y / 2 % 9);
            let g = GLYPHS[((x / 14 + y / 18 * 3) % 8) as usize];
            if gx < 5 && gy < 7 && (g[gy as usize] >> (4 - gx)) & 1 == 1 {
                [10, 10, 10]
            } else {
                [250, 214, 90]
            }
        }
        // eyes: rings of sclera, iris and pupil with a highlight, 40 texels apart
        _ => {
            let (cx, cy) = ((x % 40) as f32 - 19.5, (y % 40) as f32 - 19.5);
            let r = (cx * cx + cy * cy).sqrt();
            let (hx, hy) = (cx + 4.0, cy + 4.0);
            if (hx * hx + hy * hy).sqrt() < 2.5 {
                [255, 255, 255]
            } else if r < 5.0 {
                [5, 5, 5]
            } else if r < 10.0 {
                [40, 120, 60]
            } else if r < 16.0 {
                [245, 245, 240]
            } else {
                [120, 80, 60]
            }
        }
    }
}
