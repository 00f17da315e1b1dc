//! Distance over a surface to a set of polylines lying on it (salient curves): exact Euclidean
//! distance to the polylines' segments near them, continued by Dijkstra along mesh edges farther
//! out. Near a curve (within `near`) the Euclidean distance equals the geodesic one on the faces
//! beside it, which is where the feature-to-feature constraint of Xu et al. 2009 (§5.2) reads it;
//! beyond, edge paths overestimate the geodesic by a few percent, which only changes weights.

use std::cmp::Ordering;
use std::collections::{BinaryHeap, HashMap};

use glam::Vec3;

use crate::mesh::Csr;

/// One polyline: its points and whether it closes on itself.
#[derive(Clone, Copy, Debug)]
pub struct Polyline<'a> {
    /// Points along the polyline.
    pub points: &'a [[f32; 3]],
    /// Whether the last point joins the first.
    pub closed: bool,
}

/// Per vertex, the distance over the surface to the nearest polyline: Euclidean within `near`
/// of a segment, then along mesh edges (`adjacency`) up to `far`; `f32::INFINITY` beyond `far`
/// or in components the polylines do not touch.
pub fn distance_to_polylines(
    positions: &[[f32; 3]],
    adjacency: &Csr,
    polylines: &[Polyline],
    near: f32,
    far: f32,
) -> Vec<f32> {
    let n = positions.len();
    let mut dist = vec![f32::INFINITY; n];
    if n == 0 || near.is_nan() || near <= 0.0 {
        return dist;
    }
    // Uniform hash grid of the vertices, cell = near.
    let cell = near;
    let key = |p: Vec3| -> (i32, i32, i32) {
        let q = p / cell;
        (q.x.floor() as i32, q.y.floor() as i32, q.z.floor() as i32)
    };
    let mut grid: HashMap<(i32, i32, i32), Vec<u32>> = HashMap::new();
    for (i, p) in positions.iter().enumerate() {
        grid.entry(key(Vec3::from(*p))).or_default().push(i as u32);
    }
    for pl in polylines {
        let m = pl.points.len();
        if m == 0 {
            continue;
        }
        let segs = if pl.closed && m > 2 {
            m
        } else {
            m.saturating_sub(1).max(1)
        };
        for s in 0..segs {
            let a = Vec3::from(pl.points[s]);
            let b = Vec3::from(pl.points[(s + 1) % m]);
            let (lo, hi) = (
                key(a.min(b) - Vec3::splat(near)),
                key(a.max(b) + Vec3::splat(near)),
            );
            for x in lo.0..=hi.0 {
                for y in lo.1..=hi.1 {
                    for z in lo.2..=hi.2 {
                        let Some(list) = grid.get(&(x, y, z)) else {
                            continue;
                        };
                        for &v in list {
                            let d = point_segment(Vec3::from(positions[v as usize]), a, b);
                            if d <= near && d < dist[v as usize] {
                                dist[v as usize] = d;
                            }
                        }
                    }
                }
            }
        }
    }
    // Dijkstra outwards from every vertex with a distance.
    let mut heap: BinaryHeap<Item> = dist
        .iter()
        .enumerate()
        .filter(|(_, d)| d.is_finite())
        .map(|(v, &d)| Item(d, v as u32))
        .collect();
    while let Some(Item(d, v)) = heap.pop() {
        if d > dist[v as usize] {
            continue;
        }
        let pv = Vec3::from(positions[v as usize]);
        for &q in adjacency.row(v as usize) {
            let nd = d + pv.distance(Vec3::from(positions[q as usize]));
            if nd < dist[q as usize] && nd <= far {
                dist[q as usize] = nd;
                heap.push(Item(nd, q));
            }
        }
    }
    dist
}

/// Distance from `p` to the segment `ab`.
fn point_segment(p: Vec3, a: Vec3, b: Vec3) -> f32 {
    let ab = b - a;
    let l2 = ab.length_squared();
    let t = if l2 > 0.0 {
        ((p - a).dot(ab) / l2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    p.distance(a + t * ab)
}

/// Min-heap entry (distance, vertex).
#[derive(PartialEq)]
struct Item(f32, u32);

impl Eq for Item {}

impl Ord for Item {
    fn cmp(&self, o: &Self) -> Ordering {
        o.0.total_cmp(&self.0).then(o.1.cmp(&self.1))
    }
}

impl PartialOrd for Item {
    fn partial_cmp(&self, o: &Self) -> Option<Ordering> {
        Some(self.cmp(o))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn distance_on_a_grid_to_a_straight_line_is_exact_near_and_close_far() {
        // 41x41 unit grid in the xy plane; the line x = 20 (a column of the grid).
        let (positions, faces) = crate::testdata::grid(41);
        let adj = crate::mesh::vertex_adjacency(positions.len(), &faces);
        let line = [[20.0, -5.0, 0.0], [20.0, 45.0, 0.0]];
        let d = distance_to_polylines(
            &positions,
            &adj,
            &[Polyline {
                points: &line,
                closed: false,
            }],
            6.0,
            100.0,
        );
        for (p, &dv) in positions.iter().zip(&d) {
            let truth = (p[0] - 20.0).abs();
            if truth <= 6.0 {
                assert!((dv - truth).abs() < 1e-5, "near: {dv} vs {truth}");
            } else {
                // edge paths along the grid's axis-aligned edges reach it exactly too
                assert!(
                    dv >= truth - 1e-5 && dv <= truth * 1.1 + 1e-5,
                    "{dv} vs {truth}"
                );
            }
        }
    }
}
