//! Pearson's correlation coefficient of two samples.

/// Pearson's correlation of `a` and `b` (paired by index, the shorter's length; sums in f64):
/// 1 for a perfect increasing linear relation, -1 for a decreasing one, 0 where either sample
/// is constant.
pub fn pearson(a: &[f32], b: &[f32]) -> f64 {
    let n = a.len().max(1) as f64;
    let ma = a.iter().map(|&x| x as f64).sum::<f64>() / n;
    let mb = b.iter().map(|&x| x as f64).sum::<f64>() / n;
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for (&x, &y) in a.iter().zip(b) {
        let (dx, dy) = (x as f64 - ma, y as f64 - mb);
        sab += dx * dy;
        saa += dx * dx;
        sbb += dy * dy;
    }
    sab / (saa * sbb).sqrt().max(1e-300)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn linear_relations_correlate_fully_and_a_constant_not_at_all() {
        let a: Vec<f32> = (0..50).map(|i| (i as f32 * 0.37).sin()).collect();
        let up: Vec<f32> = a.iter().map(|x| 3.0 * x + 1.0).collect();
        let down: Vec<f32> = a.iter().map(|x| 2.0 - 0.5 * x).collect();
        assert!((pearson(&a, &up) - 1.0).abs() < 1e-9);
        assert!((pearson(&a, &down) + 1.0).abs() < 1e-9);
        assert_eq!(pearson(&a, &[4.0; 50]), 0.0);
        let noise: Vec<f32> = (0..50).map(|i| ((i * 7919) % 13) as f32).collect();
        assert!(pearson(&a, &noise).abs() < 0.5);
    }
}
