//! Interlinked elements: two rings that thread through each other, told apart from two surfaces
//! that pass through each other.
//!
//! A *crossing* is a surface intersection: an edge of one element pierces a triangle of the
//! other ([`super::crossing`]); the quilt never keeps one. A *link* is topological: the two
//! surfaces stay apart, but the centre curve of one element passes through the hole of the other
//! an odd number of times, i.e. the linking number of the two centre curves is not zero.
//!
//! **Centre curve** of an element with one hole (Euler characteristic 0, a ring, a nut, a
//! chain link): its vertices are split into 24 angular sectors (16, 12 or 8 when a sector stays empty) around their mean, in the plane
//! of the two largest principal axes; the curve joins the sectors' mean points. An element
//! with an empty sector even at 8 (a pebble, a strand, a disc) has none and links nothing.
//!
//! **Linking number** of two closed polygons `A`, `B`: the signed number of times `B`'s edges
//! pierce the fan of triangles from `A`'s mean point to its edges, a spanning disc of `A` (exact
//! for curves that are star-shaped about their mean point, as ring centre curves are).

use glam::Vec3;

use super::merging::euler_characteristic;

const SECTORS: [usize; 4] = [24, 16, 12, 8];

/// The centre curve of an element with one hole (see the module doc), or `None`.
pub fn centre_curve(positions: &[[f32; 3]], faces: &[[u32; 3]]) -> Option<Vec<Vec3>> {
    if positions.len() < 8 || euler_characteristic(positions.len(), faces) != 0 {
        return None;
    }
    let n = positions.len() as f32;
    let mean = positions.iter().map(|p| Vec3::from(*p)).sum::<Vec3>() / n;
    let mut c = glam::Mat3::ZERO;
    for p in positions {
        let d = Vec3::from(*p) - mean;
        c += glam::Mat3::from_cols(d * d.x, d * d.y, d * d.z);
    }
    let normal = smallest_axis(c / n);
    let e1 = normal.any_orthonormal_vector();
    let e2 = normal.cross(e1);
    let curve = SECTORS.iter().find_map(|&m| {
        let mut sum = vec![Vec3::ZERO; m];
        let mut count = vec![0u32; m];
        for p in positions {
            let d = Vec3::from(*p) - mean;
            let a = d.dot(e2).atan2(d.dot(e1));
            let k = (((a / std::f32::consts::TAU) + 0.5) * m as f32) as usize % m;
            sum[k] += Vec3::from(*p);
            count[k] += 1;
        }
        (!count.contains(&0)).then(|| (0..m).map(|k| sum[k] / count[k] as f32).collect::<Vec<_>>())
    })?;
    // a curve through the element's material, not around a hole, has its points near the mean
    let r_min = curve
        .iter()
        .map(|p| (*p - mean).reject_from(normal).length())
        .fold(f32::INFINITY, f32::min);
    let r_max = curve
        .iter()
        .map(|p| (*p - mean).reject_from(normal).length())
        .fold(0.0f32, f32::max);
    (r_min > 0.2 * r_max).then_some(curve)
}

/// Unit eigenvector of the smallest eigenvalue of a symmetric 3x3 matrix (inverse iteration on
/// the shifted matrix).
fn smallest_axis(m: glam::Mat3) -> Vec3 {
    let tr = m.x_axis.x + m.y_axis.y + m.z_axis.z;
    // power iteration on (tr I - m): its largest eigenvector is m's smallest
    let s = glam::Mat3::from_diagonal(Vec3::splat(tr)) - m;
    let mut v = Vec3::new(0.31, 0.53, 0.79).normalize();
    for _ in 0..64 {
        let w = s * v;
        if w.length() <= 1e-30 {
            break;
        }
        v = w.normalize();
    }
    v
}

fn segment_triangle(a: Vec3, b: Vec3, t: [Vec3; 3]) -> i32 {
    let (e1, e2) = (t[1] - t[0], t[2] - t[0]);
    let n = e1.cross(e2);
    let (da, db) = ((a - t[0]).dot(n), (b - t[0]).dot(n));
    if (da > 0.0) == (db > 0.0) || da == db {
        return 0;
    }
    let p = a + (b - a) * (da / (da - db));
    let q = p - t[0];
    let (d00, d01, d11) = (e1.dot(e1), e1.dot(e2), e2.dot(e2));
    let (d20, d21) = (q.dot(e1), q.dot(e2));
    let den = d00 * d11 - d01 * d01;
    if den == 0.0 {
        return 0;
    }
    let v = (d11 * d20 - d01 * d21) / den;
    let w = (d00 * d21 - d01 * d20) / den;
    // half-open on the spokes (v > 0, w >= 0): a point on the spoke two fan triangles share
    // counts once
    if v > 0.0 && w >= 0.0 && v + w <= 1.0 {
        if da < 0.0 { 1 } else { -1 }
    } else {
        0
    }
}

/// Linking number of two closed polygons (see the module doc).
pub fn linking_number(a: &[Vec3], b: &[Vec3]) -> i32 {
    let ca = a.iter().copied().sum::<Vec3>() / a.len() as f32;
    let mut n = 0;
    for i in 0..a.len() {
        let t = [ca, a[i], a[(i + 1) % a.len()]];
        for j in 0..b.len() {
            n += segment_triangle(b[j], b[(j + 1) % b.len()], t);
        }
    }
    n
}

/// Centre and reach (largest distance of a curve point from the centre) of a curve.
pub fn curve_reach(c: &[Vec3]) -> (Vec3, f32) {
    let m = c.iter().copied().sum::<Vec3>() / c.len() as f32;
    (m, c.iter().map(|p| p.distance(m)).fold(0.0f32, f32::max))
}

/// Linked pairs `(i, j)`, `i < j`, among curves (`None`: no hole), found through a hash grid on
/// the curves' centres.
pub fn linked_pairs(curves: &[Option<Vec<Vec3>>]) -> Vec<(u32, u32)> {
    let reach: Vec<Option<(Vec3, f32)>> = curves
        .iter()
        .map(|c| c.as_ref().map(|c| curve_reach(c)))
        .collect();
    let r = reach.iter().flatten().map(|x| x.1).fold(0.0f32, f32::max);
    if r <= 0.0 {
        return Vec::new();
    }
    let cell = 2.0 * r;
    let key = |p: Vec3| (p / cell).floor().as_ivec3();
    let mut grid: std::collections::HashMap<glam::IVec3, Vec<u32>> = Default::default();
    for (i, x) in reach.iter().enumerate() {
        if let Some((c, _)) = x {
            grid.entry(key(*c)).or_default().push(i as u32);
        }
    }
    let mut out = Vec::new();
    for (i, x) in reach.iter().enumerate() {
        let Some((ci, ri)) = x else { continue };
        let k = key(*ci);
        for dz in -1..=1 {
            for dy in -1..=1 {
                for dx in -1..=1 {
                    let Some(list) = grid.get(&(k + glam::IVec3::new(dx, dy, dz))) else {
                        continue;
                    };
                    for &j in list {
                        if j as usize <= i {
                            continue;
                        }
                        let (cj, rj) = reach[j as usize].expect("listed");
                        if ci.distance(cj) > ri + rj {
                            continue;
                        }
                        let (a, b) = (
                            curves[i].as_ref().expect("listed"),
                            curves[j as usize].as_ref().expect("listed"),
                        );
                        if linking_number(a, b) != 0 {
                            out.push((i as u32, j));
                        }
                    }
                }
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn circle(c: Vec3, u: Vec3, v: Vec3, r: f32) -> Vec<Vec3> {
        (0..32)
            .map(|k| {
                let a = std::f32::consts::TAU * k as f32 / 32.0;
                c + (u * a.cos() + v * a.sin()) * r
            })
            .collect()
    }

    #[test]
    fn chain_links_are_linked_and_side_by_side_rings_are_not() {
        let a = circle(Vec3::ZERO, Vec3::X, Vec3::Y, 1.0);
        // through a's hole: upright, centred near a's rim (general position: no curve passes
        // exactly through the other's mean point)
        let up = Vec3::new(0.0, 0.1, 1.0).normalize();
        let b = circle(Vec3::new(0.9, 0.05, 0.02), Vec3::X, up, 0.8);
        assert_eq!(linking_number(&a, &b).abs(), 1);
        assert_eq!(linking_number(&b, &a).abs(), 1);
        // the same ring moved out of a's hole
        let c = circle(Vec3::new(2.5, 0.05, 0.02), Vec3::X, up, 0.8);
        assert_eq!(linking_number(&a, &c), 0);
        // parallel and stacked: never linked
        let d = circle(Vec3::new(0.5, 0.0, 0.3), Vec3::X, Vec3::Y, 1.0);
        assert_eq!(linking_number(&a, &d), 0);
        let pairs = linked_pairs(&[Some(a), Some(b), Some(c), Some(d), None]);
        // d, lying over a, is threaded by the upright b as a is
        assert_eq!(pairs, vec![(0, 1), (1, 3)]);
    }
}
