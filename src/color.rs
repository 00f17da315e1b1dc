//! Colour conversions: sRGB <-> linear, CIE Lab (D65) and the CIE76 colour difference.

/// sRGB-encoded channel in [0,1] -> linear light.
#[inline]
pub fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// Linear light channel in [0,1] -> sRGB encoding.
#[inline]
pub fn linear_to_srgb(c: f32) -> f32 {
    let c = c.clamp(0.0, 1.0);
    if c <= 0.003_130_8 {
        c * 12.92
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    }
}

/// sRGB colour in [0,1]^3 -> CIE L*a*b* (D65 white), L in [0,100].
pub fn srgb_to_lab(c: [f32; 3]) -> [f32; 3] {
    let r = srgb_to_linear(c[0]);
    let g = srgb_to_linear(c[1]);
    let b = srgb_to_linear(c[2]);
    let x = (0.412_456_4 * r + 0.357_576_1 * g + 0.180_437_5 * b) / 0.950_47;
    let y = 0.212_672_9 * r + 0.715_152_2 * g + 0.072_175 * b;
    let z = (0.019_333_9 * r + 0.119_192 * g + 0.950_304_1 * b) / 1.088_83;
    let f = |t: f32| {
        if t > 0.008_856 {
            t.cbrt()
        } else {
            7.787 * t + 16.0 / 116.0
        }
    };
    let (fx, fy, fz) = (f(x), f(y), f(z));
    [116.0 * fy - 16.0, 500.0 * (fx - fy), 200.0 * (fy - fz)]
}

/// CIE76 colour difference (Euclidean distance in Lab) between two sRGB colours.
pub fn delta_e76(a: [f32; 3], b: [f32; 3]) -> f32 {
    let la = srgb_to_lab(a);
    let lb = srgb_to_lab(b);
    ((la[0] - lb[0]).powi(2) + (la[1] - lb[1]).powi(2) + (la[2] - lb[2]).powi(2)).sqrt()
}

/// sRGB colour in [0,1] -> 8-bit channels (rounded, clamped).
#[inline]
pub fn to_u8(c: [f32; 3]) -> [u8; 3] {
    c.map(|x| (x.clamp(0.0, 1.0) * 255.0 + 0.5) as u8)
}

/// 8-bit sRGB channels -> sRGB colour in [0,1].
#[inline]
pub fn from_u8(c: [u8; 3]) -> [f32; 3] {
    c.map(|x| x as f32 / 255.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    #[test]
    fn lab_of_white_and_black() {
        let w = srgb_to_lab([1.0; 3]);
        assert!((w[0] - 100.0).abs() < 0.1 && w[1].abs() < 0.1 && w[2].abs() < 0.1);
        let k = srgb_to_lab([0.0; 3]);
        assert!(k[0].abs() < 1e-3);
        assert!(delta_e76([1.0, 0.0, 0.0], [0.0, 1.0, 0.0]) > 100.0);
    }
}
