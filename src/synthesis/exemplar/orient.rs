//! Local texture orientation per vertex (Wei & Levoy 2001, §3.1): random, projected up axis, or
//! n-way symmetric relaxation coarse to fine.

use std::f32::consts::TAU;

use glam::Vec3;
use rand::{Rng, rngs::SmallRng, seq::SliceRandom};

use super::pyramid::Level;

/// An orthonormal tangent basis (e1, e2) for unit normal `n` (Duff et al. 2017 branchless ONB).
#[inline]
pub(crate) fn tangent_basis(n: Vec3) -> (Vec3, Vec3) {
    let sign = 1.0f32.copysign(n.z);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    let e1 = Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
    let e2 = Vec3::new(b, sign + n.y * n.y * a, -n.y);
    (e1, e2)
}

/// Project `d` into the tangent plane of `n` and normalise; falls back to any tangent direction.
#[inline]
pub(crate) fn project_tangent(d: Vec3, n: Vec3) -> Vec3 {
    (d - d.dot(n) * n)
        .try_normalize()
        .unwrap_or_else(|| tangent_basis(n).0)
}

/// Random unit tangent directions (isotropic textures).
pub(crate) fn random_dirs(level: &Level, rng: &mut SmallRng) -> Vec<[f32; 3]> {
    level
        .normals
        .iter()
        .map(|n| {
            let (e1, e2) = tangent_basis(Vec3::from(*n));
            let a = rng.random::<f32>() * TAU;
            (e1 * a.cos() + e2 * a.sin()).to_array()
        })
        .collect()
}

/// Texture "right" `s = t x n` where the texture "up" `t` is +Y projected into the tangent plane
/// (+X where the normal is parallel to Y).
pub(crate) fn up_dirs(level: &Level) -> Vec<[f32; 3]> {
    level
        .normals
        .iter()
        .map(|n| {
            let n = Vec3::from(*n);
            let t = if n.y.abs() > 0.999 {
                project_tangent(Vec3::X, n)
            } else {
                project_tangent(Vec3::Y, n)
            };
            t.cross(n).normalize_or_zero().to_array()
        })
        .collect()
}

/// Directions `d` projected into each tangent plane and normalised (any tangent where `d` is 0).
pub(crate) fn project_all(level: &Level, d: &[[f32; 3]]) -> Vec<[f32; 3]> {
    level
        .normals
        .iter()
        .zip(d)
        .map(|(n, d)| project_tangent(Vec3::from(*d), Vec3::from(*n)).to_array())
        .collect()
}

/// Coarse directions as the projected sum of their children's (`parent`: fine vertex -> coarse).
pub(crate) fn from_children(
    level: &Level,
    parent: &[u32],
    child_dirs: &[[f32; 3]],
) -> Vec<[f32; 3]> {
    let mut sum = vec![Vec3::ZERO; level.num_vertices()];
    for (c, &p) in parent.iter().enumerate() {
        sum[p as usize] += Vec3::from(child_dirs[c]);
    }
    let sum: Vec<[f32; 3]> = sum.iter().map(|v| v.to_array()).collect();
    project_all(level, &sum)
}

/// n-way symmetric relaxation (Wei & Levoy 2001 §3.1; the n-RoSy averaging of Hertzmann & Zorin
/// 2000): Gauss-Seidel sweeps in random order set each `s_p` to `arg(sum_q e^{i n phi_q}) / n`,
/// where `phi_q` is the angle of neighbour `s_q` (and of the parent's `s`, when `parent_dirs` is
/// given) projected into p's tangent plane. This minimises `E = sum |phi - round(phi/(2pi/n))
/// 2pi/n|^2` locally.
pub(crate) fn relax(
    level: &Level,
    dirs: &mut [[f32; 3]],
    parent: Option<(&[u32], &[[f32; 3]])>,
    nsym: u32,
    sweeps: usize,
    rng: &mut SmallRng,
) {
    let n = level.num_vertices();
    // Random order by blocks of consecutive samples: as random as the blocks are small against
    // the level, and each block reads memory in order (a fully shuffled order spent most of a
    // sweep on cache misses at 300K samples).
    const BLOCK: usize = 64;
    let mut blocks: Vec<u32> = (0..n.div_ceil(BLOCK) as u32).collect();
    let nf = nsym as f32;
    for _ in 0..sweeps {
        blocks.shuffle(rng);
        for p in blocks
            .iter()
            .flat_map(|&b| (b as usize * BLOCK)..((b as usize + 1) * BLOCK).min(n))
        {
            let np = Vec3::from(level.normals[p]);
            let (e1, e2) = tangent_basis(np);
            let (mut re, mut im) = (0.0f32, 0.0f32);
            // e^{i n phi} as the n-th power of the unit complex number (x + i y) / r: no
            // trigonometry per neighbour
            let mut add = |d: Vec3, w: f32| {
                let (x, y) = (d.dot(e1), d.dot(e2));
                let r2 = x * x + y * y;
                if r2 < 1e-24 {
                    return;
                }
                let inv = r2.sqrt().recip();
                let (br, bi) = (x * inv, y * inv);
                let (mut zr, mut zi) = (br, bi);
                for _ in 1..nsym {
                    (zr, zi) = (zr * br - zi * bi, zr * bi + zi * br);
                }
                re += w * zr;
                im += w * zi;
            };
            for &q in level.adj.row(p) {
                add(Vec3::from(dirs[q as usize]), 1.0);
            }
            if let Some((map, pd)) = parent {
                add(Vec3::from(pd[map[p] as usize]), 1.0);
            }
            if re * re + im * im < 1e-12 {
                continue;
            }
            let th = im.atan2(re) / nf;
            dirs[p] = (e1 * th.cos() + e2 * th.sin()).to_array();
        }
    }
}

/// Initialise fine directions from the parents' directions projected into each tangent plane.
pub(crate) fn from_parent(level: &Level, parent_dirs: &[[f32; 3]]) -> Vec<[f32; 3]> {
    (0..level.num_vertices())
        .map(|v| {
            let d = Vec3::from(parent_dirs[level.parent[v] as usize]);
            project_tangent(d, Vec3::from(level.normals[v])).to_array()
        })
        .collect()
}

/// Orientation mismatch energy of Wei & Levoy 2001 §3.1, averaged over directed mesh edges:
/// `E = mean_{p, q~p} |phi_qp - round(phi_qp / (2pi/n)) 2pi/n|^2` (radians^2), where `phi_qp` is the
/// angle between `s_p` and `s_q` projected into p's tangent plane.
pub fn orientation_energy(
    positions: &[[f32; 3]],
    faces: &[[u32; 3]],
    dirs: &[[f32; 3]],
    nsym: u32,
) -> f64 {
    let normals = crate::geometry::vertex_normals(positions, faces);
    let adj = crate::mesh::vertex_adjacency(positions.len(), faces);
    let period = TAU / nsym.max(1) as f32;
    let mut sum = 0.0f64;
    let mut cnt = 0usize;
    for p in 0..positions.len() {
        let np = Vec3::from(normals[p]);
        let sp = project_tangent(Vec3::from(dirs[p]), np);
        let tp = np.cross(sp);
        for &q in adj.row(p) {
            let sq = Vec3::from(dirs[q as usize]);
            let phi = sq.dot(tp).atan2(sq.dot(sp));
            let r = phi - (phi / period).round() * period;
            sum += (r * r) as f64;
            cnt += 1;
        }
    }
    if cnt == 0 { 0.0 } else { sum / cnt as f64 }
}
