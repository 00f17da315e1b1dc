//! Graph geodesic distances along mesh edges (Dijkstra), for the correspondence affinities.

use crate::hierarchy::Level;
use glam::Vec3;
use std::cmp::Reverse;
use std::collections::BinaryHeap;

/// Multi-source graph geodesic distances (Dijkstra along mesh edges) from `sources` on a level.
/// Edge paths overestimate true geodesics by a few percent; used for correspondence affinities.
pub fn edge_geodesics(level: &Level, sources: &[u32]) -> Vec<f32> {
    let n = level.len();
    let mut dist = vec![f32::INFINITY; n];
    let mut heap = BinaryHeap::new();
    for &s in sources {
        if (s as usize) < n {
            dist[s as usize] = 0.0;
            heap.push(Reverse((0u32, s)));
        }
    }
    while let Some(Reverse((dbits, v))) = heap.pop() {
        let d = f32::from_bits(dbits);
        if d > dist[v as usize] {
            continue;
        }
        let pv = Vec3::from(level.positions[v as usize]);
        for &u in level.adjacency.row(v as usize) {
            let nd = d + (Vec3::from(level.positions[u as usize]) - pv).length();
            if nd < dist[u as usize] {
                dist[u as usize] = nd;
                // Non-negative f32 bit patterns order like the floats.
                heap.push(Reverse((nd.to_bits(), u)));
            }
        }
    }
    // Unreachable vertices (other components) get the largest finite distance.
    let maxd = dist
        .iter()
        .copied()
        .filter(|d| d.is_finite())
        .fold(0.0f32, f32::max);
    for d in dist.iter_mut() {
        if !d.is_finite() {
            *d = maxd;
        }
    }
    dist
}
