//! The uses of MeshMatch beyond colour transfer that the paper demonstrates (Chen et al. 2012,
//! §5.3-5.4): completion by example within one mesh ([`complete`]), texture update after a
//! geometry edit ([`update_texture`]) and geometric detail transfer ([`transfer_detail`]).
//!
//! All three are thin layers over [`crate::meshmatch::prepare`] and
//! [`crate::meshmatch::solve_constrained`]: they build the example (source) mesh, the working
//! target mesh and the fixed target vertices, and map the result back to the caller's vertices.

mod complete;
mod detail;
mod update;

pub use complete::{CompletionResult, complete, unpainted_mask};
pub use detail::{
    DETAIL_SHAPE_WEIGHT, DETAIL_SMOOTH_ITERATIONS, DetailResult, match_histogram, split_detail,
    transfer_detail,
};
pub use update::{UPDATE_TOLERANCE, UpdateResult, update_texture};

use crate::mesh::Csr;

/// Colour of every vertex from the nearest vertex (in edge hops, multi-source BFS) whose `known`
/// flag is set; vertices of components without a known vertex keep their own colour.
pub(crate) fn fill_from_known(adj: &Csr, colors: &[[f32; 3]], known: &[bool]) -> Vec<[f32; 3]> {
    let n = colors.len();
    let mut out = colors.to_vec();
    let mut seen: Vec<bool> = known.to_vec();
    let mut queue: Vec<u32> = (0..n as u32).filter(|&v| known[v as usize]).collect();
    let mut head = 0;
    while head < queue.len() {
        let v = queue[head] as usize;
        head += 1;
        for &u in adj.row(v) {
            if !seen[u as usize] {
                seen[u as usize] = true;
                out[u as usize] = out[v];
                queue.push(u);
            }
        }
    }
    out
}
