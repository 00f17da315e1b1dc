//! The sample set `X+` and its patches: Poisson-disk samples along the salient curves first
//! (after Chen et al. 2009), and each sample's `w x w` texel patch laid out along the
//! orientation field over the vertices it covers.

use glam::Vec3;
use rand::SeedableRng;
use rand::rngs::SmallRng;
use rand::seq::SliceRandom;
use rayon::prelude::*;

use super::Surface;

/// Patch regions of the samples: per sample, (vertex, x offset, y offset) in texels, and per
/// vertex the entries that cover it.
pub(super) struct Regions {
    pub(super) samples: Vec<u32>,
    pub(super) start: Vec<usize>,
    pub(super) vertex: Vec<u32>,
    pub(super) offset: Vec<[f32; 2]>,
    /// Per vertex, entry indices (CSR).
    pub(super) cover_start: Vec<usize>,
    pub(super) cover: Vec<u32>,
    /// Sample of each entry.
    pub(super) owner: Vec<u32>,
}

pub(super) fn regions(
    surface: &Surface,
    adj: &crate::mesh::Csr,
    samples: Vec<u32>,
    w: usize,
) -> Regions {
    let n = surface.positions.len();
    let half = w as f32 / 2.0;
    let h = surface.texel;
    let per: Vec<Vec<(u32, [f32; 2])>> = samples
        .par_iter()
        .map_init(
            || (vec![u32::MAX; n], Vec::<u32>::new()),
            |(seen, queue), &p| {
                let p = p as usize;
                let pp = Vec3::from(surface.positions[p]);
                let np = Vec3::from(surface.normals[p]);
                let (sx, sy) = frame(np, Vec3::from(surface.field[p]));
                let mut out = Vec::new();
                queue.clear();
                queue.push(p as u32);
                seen[p] = p as u32;
                let mut head = 0;
                while head < queue.len() {
                    let q = queue[head] as usize;
                    head += 1;
                    let d = Vec3::from(surface.positions[q]) - pp;
                    let a = d.dot(sx) / h;
                    let b = -d.dot(sy) / h; // image y runs down
                    let inside = (-half - 0.5..half - 0.5).contains(&a)
                        && (-half - 0.5..half - 0.5).contains(&b)
                        && d.dot(np).abs() < half * h
                        && Vec3::from(surface.normals[q]).dot(np) > 0.0;
                    if !inside {
                        continue;
                    }
                    out.push((q as u32, [a, b]));
                    for &r in adj.row(q) {
                        if seen[r as usize] != p as u32 {
                            seen[r as usize] = p as u32;
                            queue.push(r);
                        }
                    }
                }
                out
            },
        )
        .collect();
    let mut start = Vec::with_capacity(samples.len() + 1);
    start.push(0);
    let total: usize = per.iter().map(|r| r.len()).sum();
    let mut vertex = Vec::with_capacity(total);
    let mut offset = Vec::with_capacity(total);
    let mut owner = Vec::with_capacity(total);
    let mut count = vec![0usize; n + 1];
    for (s, r) in per.into_iter().enumerate() {
        for (v, o) in r {
            vertex.push(v);
            offset.push(o);
            owner.push(s as u32);
            count[v as usize + 1] += 1;
        }
        start.push(vertex.len());
    }
    for i in 0..n {
        count[i + 1] += count[i];
    }
    let cover_start = count.clone();
    let mut fill = count;
    let mut cover = vec![0u32; total];
    for (e, &v) in vertex.iter().enumerate() {
        cover[fill[v as usize]] = e as u32;
        fill[v as usize] += 1;
    }
    Regions {
        samples,
        start,
        vertex,
        offset,
        cover_start,
        cover,
        owner,
    }
}

/// Texture frame at a vertex: (x = field projected on the tangent plane, y = n × x).
pub(super) fn frame(n: Vec3, f: Vec3) -> (Vec3, Vec3) {
    let mut s = f - n * f.dot(n);
    if s.length_squared() < 1e-12 {
        s = n.any_orthonormal_vector();
    }
    let s = s.normalize();
    (s, n.cross(s))
}

/// Poisson-disk samples at `spacing` (surface units): vertices near curves by increasing distance
/// first (those within `near`), then the rest in seeded random order.
pub(super) fn poisson_samples(
    positions: &[[f32; 3]],
    curve_distance: Option<&[f32]>,
    near: f32,
    spacing: f32,
    seed: u64,
) -> Vec<u32> {
    let n = positions.len();
    let mut order: Vec<u32> = (0..n as u32).collect();
    let mut rng = SmallRng::seed_from_u64(seed ^ 0x00c0_ffee);
    order.shuffle(&mut rng);
    if let Some(d) = curve_distance {
        // stable: near vertices by distance, then the shuffled rest
        order.sort_by(|&a, &b| {
            let (da, db) = (d[a as usize], d[b as usize]);
            let (na, nb) = (da < near, db < near);
            nb.cmp(&na).then(if na && nb {
                da.total_cmp(&db)
            } else {
                std::cmp::Ordering::Equal
            })
        });
    }
    let cell = spacing;
    let key = |p: Vec3| {
        let q = p / cell;
        (q.x.floor() as i32, q.y.floor() as i32, q.z.floor() as i32)
    };
    let mut grid: std::collections::HashMap<(i32, i32, i32), Vec<u32>> = Default::default();
    let mut out = Vec::new();
    let s2 = spacing * spacing;
    'outer: for &v in &order {
        let p = Vec3::from(positions[v as usize]);
        let k = key(p);
        for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    if let Some(list) = grid.get(&(k.0 + dx, k.1 + dy, k.2 + dz)) {
                        for &q in list {
                            if Vec3::from(positions[q as usize]).distance_squared(p) < s2 {
                                continue 'outer;
                            }
                        }
                    }
                }
            }
        }
        grid.entry(k).or_default().push(v);
        out.push(v);
    }
    out
}
