//! The local map of one target vertex's patch onto the source's tangent plane: what the
//! resampler fits to the nearest-neighbour field and what the coincident check snaps.

use glam::Vec2;

/// The local map of one target vertex's patch: a tangent offset `p` (in the target vertex's
/// frame) goes to `origin + L p` in the frame of the source vertex `anchor`, with
/// `L = [[l0, l1], [l2, l3]]` (a rotation and scale where fitted to the NNF).
#[derive(Clone, Copy, Debug)]
pub(crate) struct PatchMap {
    pub(crate) anchor: u32,
    pub(crate) origin: [f32; 2],
    pub(crate) lin: [f32; 4],
}

impl PatchMap {
    /// The similarity `origin + [[a, -b], [b, a]] p`.
    pub(crate) fn similarity(anchor: u32, origin: [f32; 2], a: f32, b: f32) -> PatchMap {
        PatchMap {
            anchor,
            origin,
            lin: [a, -b, b, a],
        }
    }

    #[inline]
    pub(crate) fn apply(&self, p: Vec2) -> Vec2 {
        let l = self.lin;
        Vec2::new(self.origin[0], self.origin[1])
            + Vec2::new(l[0] * p.x + l[1] * p.y, l[2] * p.x + l[3] * p.y)
    }
}
