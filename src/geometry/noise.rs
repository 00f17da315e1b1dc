//! Deterministic 3D value noise: hashed lattice values in [-1, 1], blended trilinearly with a
//! fade curve.

use glam::Vec3;

/// The curve that blends lattice values along each axis.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Fade {
    /// `3t² - 2t³` (C¹ across cells).
    Cubic,
    /// `6t⁵ - 15t⁴ + 10t³` (C², Perlin 2002).
    Quintic,
}

impl Fade {
    #[inline]
    fn at(self, t: f32) -> f32 {
        match self {
            Fade::Cubic => t * t * (3.0 - 2.0 * t),
            Fade::Quintic => t * t * t * (t * (t * 6.0 - 15.0) + 10.0),
        }
    }
}

/// The value in [-1, 1] of lattice point `(x, y, z)` under `key` (an integer hash).
#[inline]
fn lattice_value(x: i32, y: i32, z: i32, key: u32) -> f32 {
    let mut h = (x as u32).wrapping_mul(0x8da6_b343)
        ^ (y as u32).wrapping_mul(0xd816_3841)
        ^ (z as u32).wrapping_mul(0xcb1a_b31f)
        ^ key;
    h ^= h >> 15;
    h = h.wrapping_mul(0x2c1b_3c6d);
    h ^= h >> 12;
    h = h.wrapping_mul(0x297a_2d39);
    h ^= h >> 15;
    (h as f32 / u32::MAX as f32) * 2.0 - 1.0
}

/// Value noise in [-1, 1] at `p` on the unit lattice. `key` selects the lattice values: a seed
/// times an odd constant of the caller's (each caller's constant keeps its noises apart from
/// the others'); `fade` the blend between them.
pub fn value_noise(p: Vec3, key: u32, fade: Fade) -> f32 {
    let fl = p.floor();
    let fr = p - fl;
    let w = [fade.at(fr.x), fade.at(fr.y), fade.at(fr.z)];
    let (x, y, z) = (fl.x as i32, fl.y as i32, fl.z as i32);
    let mut acc = 0.0;
    for c in 0..8 {
        let (dx, dy, dz) = (c & 1, (c >> 1) & 1, c >> 2);
        let wx = if dx == 1 { w[0] } else { 1.0 - w[0] };
        let wy = if dy == 1 { w[1] } else { 1.0 - w[1] };
        let wz = if dz == 1 { w[2] } else { 1.0 - w[2] };
        acc += wx * wy * wz * lattice_value(x + dx, y + dy, z + dz, key);
    }
    acc
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn noise_is_the_lattice_value_at_lattice_points_and_bounded_between() {
        for fade in [Fade::Cubic, Fade::Quintic] {
            for (i, p) in [[0, 0, 0], [3, -2, 5], [-7, 1, -1]].into_iter().enumerate() {
                let key = (i as u32 + 1).wrapping_mul(0x9e37_79b9);
                let v = value_noise(Vec3::new(p[0] as f32, p[1] as f32, p[2] as f32), key, fade);
                assert_eq!(v, lattice_value(p[0], p[1], p[2], key));
            }
            let at = |k: usize| value_noise(Vec3::new(k as f32 * 0.01, 0.3, -0.2), 5, fade);
            let mut prev = at(0);
            for k in 1..=400 {
                let v = at(k);
                assert!((-1.0..=1.0).contains(&v));
                assert!((v - prev).abs() < 0.1, "not continuous at step {k}");
                prev = v;
            }
        }
    }
}
