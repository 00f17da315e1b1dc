//! MeshMatch's tangent frames per vertex ([`geometry::tangent_frames`] by
//! [`FrameRule::AxisProjection`]) and the frame-to-frame transport angle along every edge of a
//! level, which carries patch orientations across edges and levels (MeshMatch §4.1).

use crate::geometry::{self, FrameRule};
use crate::hierarchy::Level;
use glam::Vec3;
use rayon::prelude::*;

pub use crate::geometry::Frames;

/// The frame rule of MeshMatch's fans and patch orientations.
pub const FRAME_RULE: FrameRule = FrameRule::AxisProjection;

/// Tangent frames of a level's normals by [`FRAME_RULE`].
pub fn tangent_frames(normals: &[[f32; 3]]) -> Frames {
    geometry::tangent_frames(normals, FRAME_RULE)
}

/// Transport angles along every directed edge of a level, aligned with `level.adjacency.indices`:
/// entry for (i -> j) is [`geometry::transport_angle`] from i's frame to j's frame.
pub fn edge_transport_angles(level: &Level, frames: &Frames) -> Vec<f32> {
    let adj = &level.adjacency;
    (0..level.len())
        .into_par_iter()
        .flat_map_iter(|i| {
            let ni = Vec3::from(level.normals[i]);
            let fi = frames.get(i);
            adj.row(i).iter().map(move |&j| {
                let j = j as usize;
                geometry::transport_angle(
                    FRAME_RULE,
                    ni,
                    fi,
                    Vec3::from(level.normals[j]),
                    frames.get(j),
                )
            })
        })
        .collect()
}
