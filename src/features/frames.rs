//! Local tangent frames per vertex and the frame-to-frame rotation that carries patch
//! orientations across edges and levels (MeshMatch §4.1). `geometry/frames.rs` keeps the
//! surface tools' own frames, with another convention.

use crate::hierarchy::Level;
use glam::Vec3;
use rayon::prelude::*;

/// A tangent frame per vertex: `t1`, `t2` orthonormal and orthogonal to the vertex normal.
#[derive(Clone, Debug, Default)]
pub struct Frames {
    /// First tangent (the polar reference direction, angle 0).
    pub t1: Vec<[f32; 3]>,
    /// Second tangent, `n x t1` (angle 90 degrees).
    pub t2: Vec<[f32; 3]>,
}

/// Tangent frame of one normal: the reference direction is the global axis least aligned with
/// the normal, projected into the tangent plane (an arbitrary but smooth choice, as in §3.1).
#[inline]
pub fn frame_of(n: Vec3) -> (Vec3, Vec3) {
    let a = if n.x.abs() < 0.6 {
        Vec3::X
    } else if n.y.abs() < 0.6 {
        Vec3::Y
    } else {
        Vec3::Z
    };
    let t1 = (a - n * n.dot(a)).normalize_or(Vec3::X);
    let t2 = n.cross(t1);
    (t1, t2)
}

/// Tangent frames of a level (see [`frame_of`]).
pub fn tangent_frames(normals: &[[f32; 3]]) -> Frames {
    let (t1, t2) = normals
        .iter()
        .map(|n| {
            let (a, b) = frame_of(Vec3::from(*n));
            (a.to_array(), b.to_array())
        })
        .unzip();
    Frames { t1, t2 }
}

/// Angle (radians) that a direction gains when carried from frame x to frame y: a tangent
/// direction at polar angle θ in x's frame, parallel-transported (minimal rotation taking n_x to
/// n_y), has polar angle θ + result in y's frame.
#[inline]
pub fn transport_angle(nx: Vec3, t1x: Vec3, ny: Vec3, t1y: Vec3, t2y: Vec3) -> f32 {
    // Minimal rotation n_x -> n_y applied to t1x (Rodrigues), then measured in y's frame.
    let axis = nx.cross(ny);
    let s = axis.length();
    let c = nx.dot(ny);
    let t = if s > 1e-6 {
        let k = axis / s;
        t1x * c + k.cross(t1x) * s + k * k.dot(t1x) * (1.0 - c)
    } else {
        t1x
    };
    t.dot(t2y).atan2(t.dot(t1y))
}

/// Transport angles along every directed edge of a level, aligned with `level.adjacency.indices`:
/// entry for (i -> j) is `transport_angle` from i's frame to j's frame.
pub fn edge_transport_angles(level: &Level, frames: &Frames) -> Vec<f32> {
    let adj = &level.adjacency;
    (0..level.len())
        .into_par_iter()
        .flat_map_iter(|i| {
            let ni = Vec3::from(level.normals[i]);
            let ti = Vec3::from(frames.t1[i]);
            adj.row(i).iter().map(move |&j| {
                let j = j as usize;
                transport_angle(
                    ni,
                    ti,
                    Vec3::from(level.normals[j]),
                    Vec3::from(frames.t1[j]),
                    Vec3::from(frames.t2[j]),
                )
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn transport_angle_is_consistent() {
        let n = Vec3::Z;
        let (t1, t2) = frame_of(n);
        // Same normal, frame rotated by 30 degrees.
        let th = 30f32.to_radians();
        let t1y = t1 * th.cos() + t2 * th.sin();
        let t2y = n.cross(t1y);
        let a = transport_angle(n, t1, n, t1y, t2y);
        assert!((a + th).abs() < 1e-5, "{a}");
    }
}
