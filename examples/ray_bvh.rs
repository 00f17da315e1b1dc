//! Shadow rays per second: the hand-written binned-SAH tree the project used for occlusion
//! (kept below as `HandBvh`: any-hit with early exit) against obvhs's compressed wide BVH8
//! (PLOC build, `medium_build`, first-hit early exit through `ray_traverse_dynamic`), which
//! `geometry::OcclusionBvh` now wraps, on the shared bunny and Nefertiti:
//! `cargo run --release --example ray_bvh`. Per vertex, 64 directions over the hemisphere of its
//! normal (a Fibonacci spiral) from `p + 1e-4 diag n`, as the directional occlusion casts them;
//! both trees must give the same answer for every ray; both run on all cores (rayon).
use std::time::{Duration, Instant};

use glam::Vec3;
use meshmatch::geometry::vertex_normals;
use obvhs::BvhBuildParams;
use obvhs::cwbvh::builder::build_cwbvh_from_tris;
use obvhs::ray::{Ray, RayHit};
use obvhs::triangle::Triangle;
use rayon::prelude::*;

const RAYS: usize = 64;

const LEAF: usize = 4;

#[derive(Clone, Copy, Debug)]
struct Node {
    lo: Vec3,
    hi: Vec3,
    /// Leaf: first triangle slot; inner: left child (right = left + 1).
    start: u32,
    /// Triangles in a leaf, 0 for an inner node.
    count: u32,
}

/// A BVH for shadow rays (any hit): binned SAH splits (median fallback), leaves of up to 4
/// triangles stored as `(v0, e1, e2)`, traversal with a fixed stack and early exit.
#[derive(Clone, Debug)]
struct HandBvh {
    nodes: Vec<Node>,
    tris: Vec<[Vec3; 3]>,
}

fn surface_area(lo: Vec3, hi: Vec3) -> f32 {
    let d = (hi - lo).max(Vec3::ZERO);
    d.x * d.y + d.y * d.z + d.z * d.x
}

/// Partition `tris` for a binned surface-area-heuristic split (12 bins per axis over the
/// centroid bounds `clo..chi`, centroids stored as corner sums); returns the split index, the
/// median on the longest axis when no split beats it.
fn sah_split(tris: &mut [[Vec3; 3]], clo: Vec3, chi: Vec3) -> usize {
    const BINS: usize = 12;
    let n = tris.len();
    let ext = chi - clo;
    let mut best = (f32::INFINITY, 0usize, 0usize); // cost, axis, bins on the left
    for axis in 0..3 {
        if ext[axis] <= 0.0 {
            continue;
        }
        let scale = BINS as f32 / ext[axis];
        let mut cnt = [0usize; BINS];
        let mut blo = [Vec3::splat(f32::INFINITY); BINS];
        let mut bhi = [Vec3::splat(f32::NEG_INFINITY); BINS];
        for t in tris.iter() {
            let c = t[0][axis] + t[1][axis] + t[2][axis];
            let b = (((c - clo[axis]) * scale) as usize).min(BINS - 1);
            cnt[b] += 1;
            for x in t {
                blo[b] = blo[b].min(*x);
                bhi[b] = bhi[b].max(*x);
            }
        }
        // sweep from the right, then from the left
        let mut right_area = [0.0f32; BINS];
        let mut right_cnt = [0usize; BINS];
        let (mut lo, mut hi, mut c) = (
            Vec3::splat(f32::INFINITY),
            Vec3::splat(f32::NEG_INFINITY),
            0,
        );
        for b in (1..BINS).rev() {
            lo = lo.min(blo[b]);
            hi = hi.max(bhi[b]);
            c += cnt[b];
            right_area[b] = surface_area(lo, hi);
            right_cnt[b] = c;
        }
        let (mut lo, mut hi, mut c) = (
            Vec3::splat(f32::INFINITY),
            Vec3::splat(f32::NEG_INFINITY),
            0,
        );
        for b in 0..BINS - 1 {
            lo = lo.min(blo[b]);
            hi = hi.max(bhi[b]);
            c += cnt[b];
            if c == 0 || right_cnt[b + 1] == 0 {
                continue;
            }
            let cost =
                surface_area(lo, hi) * c as f32 + right_area[b + 1] * right_cnt[b + 1] as f32;
            if cost < best.0 {
                best = (cost, axis, b + 1);
            }
        }
    }
    if best.0.is_finite() {
        let (axis, bins) = (best.1, best.2);
        let scale = BINS as f32 / ext[axis];
        let left = |t: &[Vec3; 3]| {
            let c = t[0][axis] + t[1][axis] + t[2][axis];
            ((((c - clo[axis]) * scale) as usize).min(BINS - 1)) < bins
        };
        // in-place partition
        let mut i = 0;
        for j in 0..n {
            if left(&tris[j]) {
                tris.swap(i, j);
                i += 1;
            }
        }
        if i > 0 && i < n {
            return i;
        }
    }
    median_split(tris, clo, chi)
}

/// Median split on the longest centroid axis.
fn median_split(tris: &mut [[Vec3; 3]], clo: Vec3, chi: Vec3) -> usize {
    let n = tris.len();
    let ext = chi - clo;
    let axis = if ext.x >= ext.y && ext.x >= ext.z {
        0
    } else if ext.y >= ext.z {
        1
    } else {
        2
    };
    let mid = n / 2;
    tris.select_nth_unstable_by(mid, |a, b| {
        (a[0][axis] + a[1][axis] + a[2][axis]).total_cmp(&(b[0][axis] + b[1][axis] + b[2][axis]))
    });
    mid
}

impl HandBvh {
    /// Build over `faces` (faces with out-of-range indices are left out).
    fn new(positions: &[[f32; 3]], faces: &[[u32; 3]]) -> Self {
        Self::build(positions, faces, true)
    }

    fn build(positions: &[[f32; 3]], faces: &[[u32; 3]], sah: bool) -> Self {
        let nv = positions.len();
        let mut tris: Vec<[Vec3; 3]> = faces
            .iter()
            .filter(|f| f.iter().all(|&v| (v as usize) < nv))
            .map(|f| f.map(|v| Vec3::from(positions[v as usize])))
            .collect();
        let mut nodes = Vec::with_capacity(2 * tris.len() / LEAF + 2);
        let blank = Node {
            lo: Vec3::ZERO,
            hi: Vec3::ZERO,
            start: 0,
            count: 0,
        };
        if !tris.is_empty() {
            nodes.push(blank);
            let mut stack = vec![(0usize, 0usize, tris.len())];
            while let Some((ni, s, e)) = stack.pop() {
                let mut lo = Vec3::splat(f32::INFINITY);
                let mut hi = Vec3::splat(f32::NEG_INFINITY);
                let (mut clo, mut chi) = (lo, hi);
                for t in &tris[s..e] {
                    for x in t {
                        lo = lo.min(*x);
                        hi = hi.max(*x);
                    }
                    let c = t[0] + t[1] + t[2];
                    clo = clo.min(c);
                    chi = chi.max(c);
                }
                nodes[ni].lo = lo;
                nodes[ni].hi = hi;
                if e - s <= LEAF {
                    nodes[ni].start = s as u32;
                    nodes[ni].count = (e - s) as u32;
                    continue;
                }
                let mid = if sah {
                    sah_split(&mut tris[s..e], clo, chi)
                } else {
                    median_split(&mut tris[s..e], clo, chi)
                } + s;
                let left = nodes.len();
                nodes.push(blank);
                nodes.push(blank);
                nodes[ni].start = left as u32;
                stack.push((left, s, mid));
                stack.push((left + 1, mid, e));
            }
        }
        for t in tris.iter_mut() {
            *t = [t[0], t[1] - t[0], t[2] - t[0]];
        }
        HandBvh { nodes, tris }
    }

    /// Does the ray `o + t d`, `0 ≤ t ≤ tmax`, cross any triangle (either side)?
    fn occluded(&self, o: Vec3, d: Vec3, tmax: f32) -> bool {
        if self.nodes.is_empty() {
            return false;
        }
        let inv = d.recip();
        let mut stack = [0u32; 64];
        let mut sp = 1usize;
        while sp > 0 {
            sp -= 1;
            let node = &self.nodes[stack[sp] as usize];
            let t0 = (node.lo - o) * inv;
            let t1 = (node.hi - o) * inv;
            let tn = t0.min(t1);
            let tf = t0.max(t1);
            let near = tn.x.max(tn.y).max(tn.z).max(0.0);
            let far = tf.x.min(tf.y).min(tf.z).min(tmax);
            if near > far {
                continue;
            }
            if node.count > 0 {
                for t in &self.tris[node.start as usize..(node.start + node.count) as usize] {
                    let [a, e1, e2] = *t;
                    let pv = d.cross(e2);
                    let det = e1.dot(pv);
                    if det.abs() < 1e-20 {
                        continue;
                    }
                    let id = 1.0 / det;
                    let tv = o - a;
                    let u = tv.dot(pv) * id;
                    if !(0.0..=1.0).contains(&u) {
                        continue;
                    }
                    let qv = tv.cross(e1);
                    let v = d.dot(qv) * id;
                    if v < 0.0 || u + v > 1.0 {
                        continue;
                    }
                    let th = e2.dot(qv) * id;
                    if th >= 0.0 && th <= tmax {
                        return true;
                    }
                }
            } else if sp + 2 <= stack.len() {
                stack[sp] = node.start;
                stack[sp + 1] = node.start + 1;
                sp += 2;
            }
        }
        false
    }
}

fn frame(n: Vec3) -> (Vec3, Vec3) {
    let a = if n.x.abs() < 0.9 { Vec3::X } else { Vec3::Y };
    let u = n.cross(a).normalize();
    (u, n.cross(u))
}

fn main() {
    let names: Vec<String> = std::env::args().skip(1).collect();
    let names = if names.is_empty() {
        vec![
            "bunny/bunny.obj".to_string(),
            "nefertiti/nefertiti.obj".to_string(),
        ]
    } else {
        names
    };
    // hemisphere directions in the local frame (z = normal)
    let golden = std::f32::consts::PI * (3.0 - 5f32.sqrt());
    let local: Vec<Vec3> = (0..RAYS)
        .map(|i| {
            let z = 1.0 - (i as f32 + 0.5) / RAYS as f32;
            let r = (1.0 - z * z).max(0.0).sqrt();
            let a = golden * i as f32;
            Vec3::new(r * a.cos(), r * a.sin(), z)
        })
        .collect();
    for name in names {
        let mut mesh =
            meshmatch::mesh::io::load(&meshmatch::testdata::data_path(&name)).expect("mesh");
        mesh.repair().expect("repair");
        let normals = vertex_normals(&mesh.positions, &mesh.faces);
        let (lo, hi) = mesh.bounds().expect("bounds");
        let eps = 1e-4 * Vec3::from(hi).distance(Vec3::from(lo));
        let rays = |i: usize| {
            let n = Vec3::from(normals[i]);
            let (u, v) = frame(n);
            let o = Vec3::from(mesh.positions[i]) + eps * n;
            local.iter().map(move |d| (o, u * d.x + v * d.y + n * d.z))
        };
        let total = mesh.num_vertices() * RAYS;

        let t = Instant::now();
        let ours = HandBvh::new(&mesh.positions, &mesh.faces);
        let ours_build = t.elapsed().as_secs_f64();
        let t = Instant::now();
        let ours_hits: Vec<u8> = (0..mesh.num_vertices())
            .into_par_iter()
            .flat_map_iter(|i| rays(i).map(|(o, d)| ours.occluded(o, d, f32::INFINITY) as u8))
            .collect();
        let ours_s = t.elapsed().as_secs_f64();

        let t = Instant::now();
        let tris: Vec<Triangle> = mesh
            .faces
            .iter()
            .map(|f| {
                let p = |k: usize| glam::Vec3A::from(mesh.positions[f[k] as usize]);
                Triangle {
                    v0: p(0),
                    v1: p(1),
                    v2: p(2),
                }
            })
            .collect();
        let cw = build_cwbvh_from_tris(
            &tris,
            BvhBuildParams::medium_build(),
            &mut Duration::default(),
        );
        let theirs_build = t.elapsed().as_secs_f64();
        let t = Instant::now();
        let theirs_hits: Vec<u8> = (0..mesh.num_vertices())
            .into_par_iter()
            .flat_map_iter(|i| {
                rays(i).map(|(o, d)| {
                    let ray = Ray::new(o.into(), d.into(), 0.0, f32::INFINITY);
                    let mut state = cw.new_ray_traversal(ray);
                    let mut hit = RayHit::none();
                    cw.ray_traverse_dynamic(&mut state, &mut hit, |ray, id| {
                        tris[cw.primitive_indices[id] as usize].intersect(ray)
                    }) as u8
                })
            })
            .collect();
        let theirs_s = t.elapsed().as_secs_f64();
        let differ = ours_hits
            .iter()
            .zip(&theirs_hits)
            .filter(|(a, b)| a != b)
            .count();
        let occluded = ours_hits.iter().filter(|&&h| h == 1).count();
        println!(
            "{name}: {} triangles, {total} rays ({:.1}% occluded); hand-written SAH BVH: build {ours_build:.3} s, {:.2} M rays/s; obvhs CWBVH: build {theirs_build:.3} s, {:.2} M rays/s; answers differ on {differ} rays ({:.4}%)",
            mesh.faces.len(),
            100.0 * occluded as f64 / total as f64,
            total as f64 / ours_s / 1e6,
            total as f64 / theirs_s / 1e6,
            100.0 * differ as f64 / total as f64
        );
    }
}
