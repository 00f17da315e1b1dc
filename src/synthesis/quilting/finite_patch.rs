//! Finite swatches as an artist models them: a patch of separate elements over `z = 0`, z up,
//! not periodic (nothing wraps around its border). Deterministic under a seed; used by the
//! tests, the benches and `meshmatch swatch --kind rings-patch|weave-patch|pebbles`.
//!
//! - **Rings**: 3 rows of 4 rings, a chain along each row: rings alternate between lying in the
//!   row's plane and standing across it, each threaded through its neighbours, the whole row
//!   tilted by 30 degrees about its axis. Centre radius 0.3, tube 0.04, 0.4 between centres,
//!   rows 0.75 apart. Two ring shapes (the lying and the standing one), lattice `(0.8, 0)`,
//!   `(0, 0.75)`; 9 links, 1.5 per ring (2 per ring in an endless chain).
//! - **Weave**: 6 strands along x over-under 6 strands along y, one unit apart, each strand 5.8
//!   long (ending 0.4 past the last crossing it meets).
//! - **Pebbles**: 36 flattened ellipsoids of random size and turn, thrown into a disc 1.5 wide
//!   in radius, at least 0.05 apart: no two are translated copies, so there is no lattice.

use glam::{Mat3, Vec3};
use rand::{Rng, SeedableRng, rngs::SmallRng};

use super::swatch::{Builder, circle_profile};
use crate::error::{Error, Result};
use crate::mesh::TriMesh;

/// The procedural finite patches.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PatchKind {
    /// Interlinked tilted rings, 3 rows of 4.
    Rings,
    /// A finite over-under weave of 6 + 6 strands.
    Weave,
    /// A scattered cluster of 36 pebbles.
    Pebbles,
}

impl PatchKind {
    /// All kinds.
    pub const ALL: [PatchKind; 3] = [PatchKind::Rings, PatchKind::Weave, PatchKind::Pebbles];
    /// The name used on the command line.
    pub fn as_str(self) -> &'static str {
        match self {
            PatchKind::Rings => "rings-patch",
            PatchKind::Weave => "weave-patch",
            PatchKind::Pebbles => "pebbles",
        }
    }
    /// Parse a name (`rings-patch`, `weave-patch`, `pebbles`).
    pub fn parse(s: &str) -> Result<Self> {
        PatchKind::ALL
            .into_iter()
            .find(|k| k.as_str() == s)
            .ok_or_else(|| Error::InvalidInput(format!("unknown finite patch {s}")))
    }
}

/// The patch as a plain mesh (what a swatch file holds), elements as separate components.
pub fn finite_patch(kind: PatchKind, seed: u64) -> TriMesh {
    let mut b = Builder::default();
    match kind {
        PatchKind::Rings => {
            let (r, tube, d, e) = (0.3f32, 0.04f32, 0.4f32, 0.75f32);
            let tilt = Mat3::from_rotation_x(30f32.to_radians());
            let stand = Mat3::from_rotation_x(std::f32::consts::FRAC_PI_2);
            let zc = r * 30f32.to_radians().cos() + tube + 0.01;
            let prof = circle_profile(r, 0.0, tube, 8);
            for j in 0..3 {
                for k in 0..4 {
                    let c = Vec3::new(k as f32 * d, j as f32 * e, zc);
                    let m = if k % 2 == 0 { tilt } else { tilt * stand };
                    b.revolve(&prof, true, 24, |p| m * p + c);
                }
            }
        }
        PatchKind::Weave => {
            let (rw, rh, amp) = (0.18f32, 0.07f32, 0.09f32);
            let zc = amp + rh + 0.01;
            let (n, x0, x1, samples) = (6usize, 0.1f32, 5.9f32, 48usize);
            let path = |phase: f32, shift: f32| -> Vec<Vec3> {
                (0..=samples)
                    .map(|s| {
                        let x = x0 + (x1 - x0) * s as f32 / samples as f32;
                        let z = zc + amp * (std::f32::consts::PI * (x - shift) + phase).cos();
                        Vec3::new(x, 0.0, z)
                    })
                    .collect()
            };
            let pi = std::f32::consts::PI;
            for j in 0..n {
                let y = j as f32 + 0.25;
                let ph = if j % 2 == 0 { 0.0 } else { pi };
                b.strand(&path(ph, 0.75), rw, rh, 8, |p| Vec3::new(p.x, y + p.y, p.z));
            }
            for i in 0..n {
                let x = i as f32 + 0.75;
                let ph = if i % 2 == 0 { pi } else { 0.0 };
                b.strand(&path(ph, 0.25), rw, rh, 8, |p| Vec3::new(x - p.y, p.x, p.z));
            }
        }
        PatchKind::Pebbles => {
            let mut rng = SmallRng::seed_from_u64(seed ^ 0x5045_4242_4c45);
            let prof: Vec<(f32, f32)> = (0..=8)
                .map(|i| {
                    let t = std::f32::consts::PI * i as f32 / 8.0;
                    (t.sin(), -t.cos())
                })
                .collect();
            let mut placed: Vec<(f32, f32, f32)> = Vec::new();
            let mut tries = 0;
            while placed.len() < 36 && tries < 20000 {
                tries += 1;
                let a: f32 = rng.random_range(0.12..0.22);
                let bb = a * rng.random_range(0.6..1.0);
                let c = bb * rng.random_range(0.4..0.7);
                let (px, py): (f32, f32) =
                    (rng.random_range(-1.5..1.5), rng.random_range(-1.5..1.5));
                let turn: f32 = rng.random_range(0.0..std::f32::consts::TAU);
                if px * px + py * py > 1.5 * 1.5
                    || placed
                        .iter()
                        .any(|&(x, y, r)| (x - px).hypot(y - py) < r + a + 0.05)
                {
                    continue;
                }
                placed.push((px, py, a));
                let rot = Mat3::from_rotation_z(turn);
                b.revolve(&prof, false, 12, |p| {
                    rot * Vec3::new(a * p.x, bb * p.y, 0.0)
                        + Vec3::new(px, py, c * (p.z + 1.0) + 0.005)
                });
            }
        }
    }
    TriMesh::new(b.positions, b.faces)
}
