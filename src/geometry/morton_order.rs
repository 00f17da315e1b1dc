//! A cache-friendly vertex order: vertices sorted along the Morton (Z-order) curve of their
//! positions, so that vertices one after the other are near each other in space. MeshMatch
//! numbers its working meshes in this order (`meshmatch::prepare`), so neighbourhood reads in
//! every stage find most of the next vertex's neighbourhood still in cache; the fan sampling
//! table visits other meshes' vertices in it (`examples/fan_order` measures both).

/// Spreads the low 21 bits of `x` to every third bit.
fn spread3(x: u32) -> u64 {
    let mut v = x as u64 & 0x1f_ffff;
    v = (v | v << 32) & 0x001f_0000_0000_ffff;
    v = (v | v << 16) & 0x001f_0000_ff00_00ff;
    v = (v | v << 8) & 0x100f_00f0_0f00_f00f;
    v = (v | v << 4) & 0x10c3_0c30_c30c_30c3;
    (v | v << 2) & 0x1249_2492_4924_9249
}

/// The vertices in Morton order of their positions (21 bits per axis over the bounding box's
/// largest side): `order[new] = old`. Ties keep their input order; a non-finite coordinate counts
/// as the box's lowest on its axis (the order stays a permutation).
pub fn morton_order(positions: &[[f32; 3]]) -> Vec<u32> {
    let (mut lo, mut hi) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
    for p in positions {
        for k in 0..3 {
            if p[k].is_finite() {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
    }
    let ext = (0..3)
        .map(|k| hi[k] - lo[k])
        .filter(|e| e.is_finite())
        .fold(0.0f32, f32::max);
    let scale = if ext > 0.0 { 2_097_151.0 / ext } else { 0.0 };
    let key = |p: &[f32; 3]| -> u64 {
        let q = |k: usize| {
            let x = (p[k] - lo[k]) * scale;
            if x.is_finite() {
                x.clamp(0.0, 2_097_151.0) as u32
            } else {
                0
            }
        };
        spread3(q(0)) | spread3(q(1)) << 1 | spread3(q(2)) << 2
    };
    let mut keyed: Vec<(u64, u32)> = positions
        .iter()
        .enumerate()
        .map(|(i, p)| (key(p), i as u32))
        .collect();
    keyed.sort_unstable();
    keyed.into_iter().map(|(_, i)| i).collect()
}

/// The inverse of a visiting order: `inverse[old] = new` for `order[new] = old` (the new number
/// of every vertex when a mesh is renumbered in `order`). `order` must be a permutation.
pub fn inverse_order(order: &[u32]) -> Vec<u32> {
    let mut inverse = vec![0u32; order.len()];
    for (new, &old) in order.iter().enumerate() {
        inverse[old as usize] = new as u32;
    }
    inverse
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spread_interleaves_bits() {
        assert_eq!(spread3(0b1), 0b1);
        assert_eq!(spread3(0b11), 0b1001);
        assert_eq!(spread3(0x1f_ffff).count_ones(), 21);
    }

    #[test]
    fn the_order_is_a_permutation_that_keeps_neighbours_close() {
        // a 32 x 32 grid listed in a scrambled order
        let n = 32usize;
        let mut pos = Vec::new();
        for i in 0..n * n {
            let j = (i * 389) % (n * n);
            pos.push([(j % n) as f32, (j / n) as f32, 0.0]);
        }
        let order = morton_order(&pos);
        let mut seen = vec![false; pos.len()];
        for &o in &order {
            assert!(!seen[o as usize]);
            seen[o as usize] = true;
        }
        // mean distance between consecutive vertices: under 2 along the Z curve (unit steps
        // plus its jumps), about a third of the grid in the scrambled one
        let step = |ord: &mut dyn Iterator<Item = usize>| {
            let v: Vec<usize> = ord.collect();
            v.windows(2)
                .map(|w| {
                    let (a, b) = (pos[w[0]], pos[w[1]]);
                    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt()
                })
                .sum::<f32>()
                / (v.len() - 1) as f32
        };
        let morton = step(&mut order.iter().map(|&o| o as usize));
        let scrambled = step(&mut (0..pos.len()));
        assert!(morton < 2.0, "{morton}");
        assert!(scrambled > 5.0 * morton, "{scrambled} vs {morton}");
        // non-finite positions do not panic
        let order = morton_order(&[[f32::NAN, 0.0, 0.0], [1.0, 2.0, 3.0]]);
        assert_eq!(order.len(), 2);
    }
}
