//! Exact Euclidean distance transform of a pixel grid (Felzenszwalb & Huttenlocher 2012: the
//! lower envelope of parabolas, one pass along the columns and one along the rows).

/// Exact Euclidean distance (pixels) of every pixel to the nearest `true` pixel; `f32::INFINITY`
/// everywhere when there is none.
pub fn distance_transform(seeds: &[bool], w: usize, h: usize) -> Vec<f32> {
    const BIG: f32 = 1e20;
    let mut g: Vec<f32> = seeds.iter().map(|&s| if s { 0.0 } else { BIG }).collect();
    let mut f = vec![0.0f32; w.max(h)];
    let mut d = vec![0.0f32; w.max(h)];
    let mut v = vec![0usize; w.max(h)];
    let mut z = vec![0.0f32; w.max(h) + 1];
    for x in 0..w {
        for y in 0..h {
            f[y] = g[y * w + x];
        }
        edt_1d(&f[..h], &mut d[..h], &mut v, &mut z);
        for y in 0..h {
            g[y * w + x] = d[y];
        }
    }
    for y in 0..h {
        f[..w].copy_from_slice(&g[y * w..(y + 1) * w]);
        edt_1d(&f[..w], &mut d[..w], &mut v, &mut z);
        g[y * w..(y + 1) * w].copy_from_slice(&d[..w]);
    }
    g.iter()
        .map(|&s| {
            if s >= BIG * 0.5 {
                f32::INFINITY
            } else {
                s.sqrt()
            }
        })
        .collect()
}

/// Squared-distance transform of a sampled function along one line (lower envelope of parabolas).
fn edt_1d(f: &[f32], d: &mut [f32], v: &mut [usize], z: &mut [f32]) {
    let n = f.len();
    if n == 0 {
        return;
    }
    let mut k = 0usize;
    v[0] = 0;
    z[0] = f32::NEG_INFINITY;
    z[1] = f32::INFINITY;
    for q in 1..n {
        loop {
            let p = v[k];
            let s = ((f[q] + (q * q) as f32) - (f[p] + (p * p) as f32)) / (2.0 * (q - p) as f32);
            if s <= z[k] && k > 0 {
                k -= 1;
                continue;
            }
            if s <= z[k] {
                // k == 0 and the new parabola dominates from -inf
                v[0] = q;
                z[0] = f32::NEG_INFINITY;
                z[1] = f32::INFINITY;
            } else {
                k += 1;
                v[k] = q;
                z[k] = s;
                z[k + 1] = f32::INFINITY;
            }
            break;
        }
    }
    k = 0;
    for (q, dq) in d.iter_mut().enumerate().take(n) {
        while z[k + 1] < q as f32 {
            k += 1;
        }
        let p = v[k];
        *dq = (q as f32 - p as f32).powi(2) + f[p];
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn distance_transform_is_exact() {
        let (w, h) = (23, 17);
        let mut seeds = vec![false; w * h];
        let pts = [(3usize, 4usize), (17, 12), (10, 0)];
        for &(x, y) in &pts {
            seeds[y * w + x] = true;
        }
        let d = distance_transform(&seeds, w, h);
        for y in 0..h {
            for x in 0..w {
                let truth = pts
                    .iter()
                    .map(|&(a, b)| {
                        ((x as f32 - a as f32).powi(2) + (y as f32 - b as f32).powi(2)).sqrt()
                    })
                    .fold(f32::INFINITY, f32::min);
                assert!(
                    (d[y * w + x] - truth).abs() < 1e-4,
                    "({x},{y}): {} vs {truth}",
                    d[y * w + x]
                );
            }
        }
    }
}
