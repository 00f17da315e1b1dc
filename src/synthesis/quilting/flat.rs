//! A flattened patch: the base faces of a disc with their 2D corners, a grid to locate points
//! in them (or, just past the base's boundary, extrapolated from the nearest boundary face), and the
//! flattening's area distortion.

use std::collections::HashMap;

use glam::{Vec2, Vec3};

use super::shell::Base;

/// A flattened edge longer than this many times its length on the base tears the flattening.
const TEAR: f32 = 3.0;

/// A flattened patch with a point-location grid.
pub(super) struct Flat {
    /// Base face -> index into `faces`.
    pub(super) index: HashMap<u32, u32>,
    /// Base faces whose three corners are flattened, with their 2D corners.
    pub(super) faces: Vec<(u32, [Vec2; 3])>,
    lo: Vec2,
    cell: f32,
    dims: [usize; 2],
    grid: Vec<Vec<u32>>,
    /// The faces points just past the base's boundary are extrapolated from: those with an
    /// edge on the base's boundary, away from any tear (no vertex shared with a torn face).
    extrapolating: Vec<u32>,
    /// Where several faces hold a point, take the first in `faces` (a chart grown outwards
    /// from the seed that overlaps itself past a singularity: the sheet nearer the seed wins).
    prefer_first: bool,
}

fn bary2(p: Vec2, t: &[Vec2; 3]) -> Option<[f32; 3]> {
    let (a, b, c) = (t[0], t[1], t[2]);
    let d = (b - a).perp_dot(c - a);
    if d.abs() < 1e-20 {
        return None;
    }
    let l1 = (p - a).perp_dot(c - a) / d;
    let l2 = (b - a).perp_dot(p - a) / d;
    Some([1.0 - l1 - l2, l1, l2])
}

/// The 3D direction of the 2D direction `w` through the affine map from flattened triangle
/// `q` to base triangle `p`.
pub(super) fn uv_to_3d(q: &[Vec2; 3], p: [Vec3; 3], w: Vec2) -> Vec3 {
    let (e1, e2) = (q[1] - q[0], q[2] - q[0]);
    let d = e1.perp_dot(e2);
    if d.abs() < 1e-20 {
        return Vec3::ZERO;
    }
    let l1 = w.perp_dot(e2) / d;
    let l2 = e1.perp_dot(w) / d;
    (p[1] - p[0]) * l1 + (p[2] - p[0]) * l2
}

/// The 2D direction of the 3D direction `d` (projected onto the triangle's plane, least
/// squares) through the affine map from base triangle `p` to flattened triangle `q`.
pub(super) fn dir_to_uv(q: &[Vec2; 3], p: [Vec3; 3], d: Vec3) -> Vec2 {
    let (a, b) = (p[1] - p[0], p[2] - p[0]);
    let (aa, ab, bb) = (a.dot(a), a.dot(b), b.dot(b));
    let det = aa * bb - ab * ab;
    if det.abs() < 1e-30 {
        return Vec2::ZERO;
    }
    let (ra, rb) = (a.dot(d), b.dot(d));
    let l1 = (bb * ra - ab * rb) / det;
    let l2 = (aa * rb - ab * ra) / det;
    (q[1] - q[0]) * l1 + (q[2] - q[0]) * l2
}

fn seg_dist(p: Vec2, a: Vec2, b: Vec2) -> f32 {
    let ab = b - a;
    let t = ((p - a).dot(ab) / ab.length_squared().max(1e-30)).clamp(0.0, 1.0);
    p.distance(a + ab * t)
}

impl Flat {
    pub(super) fn new(base: &Base, verts: &[u32], uvs: &[[f32; 2]]) -> Flat {
        let uv: HashMap<u32, Vec2> = verts
            .iter()
            .zip(uvs)
            .map(|(&v, &u)| (v, Vec2::from(u)))
            .collect();
        let mut faces = Vec::new();
        for &v in verts {
            for &f in base.vf.row(v as usize) {
                let c = base.faces[f as usize];
                // count each face once: at its largest corner index present
                if c.iter().max() != Some(&v) {
                    continue;
                }
                if let (Some(a), Some(b), Some(d)) = (uv.get(&c[0]), uv.get(&c[1]), uv.get(&c[2])) {
                    faces.push((f, [*a, *b, *d]));
                }
            }
        }
        faces.sort_unstable_by_key(|x| x.0);
        Flat::from_faces(base, faces, false)
    }

    /// A flattening given face by face (2D corners per base face, each face once).
    ///
    /// A face the flattening tears (folded over, or an edge stretched past [`TEAR`] times its
    /// length: the exponential map past its cut locus, around a limb thinner than the disc, puts
    /// the faces straddling the cut across the whole chart) holds no point: points there are
    /// not on the patch, and nothing is extrapolated from the faces around the tear.
    pub(super) fn from_faces(
        base: &Base,
        faces: Vec<(u32, [Vec2; 3])>,
        prefer_first: bool,
    ) -> Flat {
        let torn: Vec<bool> = faces
            .iter()
            .map(|(f, t)| {
                let c = base.faces[*f as usize].map(|v| Vec3::from(base.p[v as usize]));
                (t[1] - t[0]).perp_dot(t[2] - t[0]) <= 0.0
                    || (0..3).any(|k| {
                        let (a, b) = (k, (k + 1) % 3);
                        t[a].distance(t[b]) > TEAR * c[a].distance(c[b])
                    })
            })
            .collect();
        let cut: std::collections::HashSet<u32> = faces
            .iter()
            .zip(&torn)
            .filter(|x| *x.1)
            .flat_map(|((f, _), _)| base.faces[*f as usize])
            .collect();
        let extrapolating: Vec<u32> = (0..faces.len() as u32)
            .filter(|&k| {
                let f = faces[k as usize].0 as usize;
                base.on_boundary[f] && !base.faces[f].iter().any(|v| cut.contains(v))
            })
            .collect();
        let mut lo = Vec2::splat(f32::INFINITY);
        let mut hi = Vec2::splat(f32::NEG_INFINITY);
        for (_, t) in &faces {
            for q in t {
                lo = lo.min(*q);
                hi = hi.max(*q);
            }
        }
        let ext = (hi - lo).max(Vec2::splat(1e-12));
        let cell = ((ext.x * ext.y) / faces.len().max(1) as f32)
            .sqrt()
            .max(1e-12)
            * 1.5;
        let dims = [
            ((ext.x / cell) as usize + 1).min(512),
            ((ext.y / cell) as usize + 1).min(512),
        ];
        let cell = (ext.x / dims[0] as f32)
            .max(ext.y / dims[1] as f32)
            .max(1e-12);
        let mut grid = vec![Vec::new(); dims[0] * dims[1]];
        for (k, (_, t)) in faces.iter().enumerate() {
            if torn[k] {
                continue;
            }
            let mut a = Vec2::splat(f32::INFINITY);
            let mut b = Vec2::splat(f32::NEG_INFINITY);
            for q in t {
                a = a.min(*q);
                b = b.max(*q);
            }
            let (i0, j0) = Self::cell_of(lo, cell, dims, a);
            let (i1, j1) = Self::cell_of(lo, cell, dims, b);
            for j in j0..=j1 {
                for i in i0..=i1 {
                    grid[j * dims[0] + i].push(k as u32);
                }
            }
        }
        let index = faces
            .iter()
            .enumerate()
            .map(|(k, (f, _))| (*f, k as u32))
            .collect();
        Flat {
            index,
            faces,
            lo,
            cell,
            dims,
            grid,
            extrapolating,
            prefer_first,
        }
    }

    fn cell_of(lo: Vec2, cell: f32, dims: [usize; 2], p: Vec2) -> (usize, usize) {
        let q = (p - lo) / cell;
        (
            (q.x.max(0.0) as usize).min(dims[0] - 1),
            (q.y.max(0.0) as usize).min(dims[1] - 1),
        )
    }

    /// Locate `p`: the face containing it (largest smallest barycentric coordinate), or with
    /// `extrapolate > 0` the nearest face on the base's boundary within that distance, with
    /// affine (possibly negative) barycentric coordinates. Returns `(face, b, inside)`.
    pub(super) fn locate(&self, p: Vec2, extrapolate: f32) -> Option<(u32, [f32; 3], bool)> {
        if self.faces.is_empty() || !p.is_finite() {
            return None;
        }
        let inside_box = {
            let q = (p - self.lo) / self.cell;
            q.x >= 0.0
                && q.y >= 0.0
                && (q.x as usize) < self.dims[0]
                && (q.y as usize) < self.dims[1]
        };
        if inside_box {
            let (i, j) = Self::cell_of(self.lo, self.cell, self.dims, p);
            let mut best: Option<(u32, [f32; 3], f32)> = None;
            for &k in &self.grid[j * self.dims[0] + i] {
                let (f, t) = &self.faces[k as usize];
                if let Some(b) = bary2(p, t) {
                    let m = b[0].min(b[1]).min(b[2]);
                    if m >= -1e-5 && best.is_none_or(|x| m > x.2) {
                        best = Some((*f, b, m));
                        if self.prefer_first {
                            break; // cell lists are in face order
                        }
                    }
                }
            }
            if let Some((f, b, _)) = best {
                return Some((f, b, true));
            }
        }
        if extrapolate <= 0.0 {
            return None;
        }
        let mut best: Option<(u32, [f32; 3], f32)> = None;
        for &k in &self.extrapolating {
            let (f, t) = &self.faces[k as usize];
            let d = seg_dist(p, t[0], t[1])
                .min(seg_dist(p, t[1], t[2]))
                .min(seg_dist(p, t[2], t[0]));
            if d <= extrapolate
                && best.is_none_or(|x| d < x.2)
                && let Some(b) = bary2(p, t)
            {
                best = Some((*f, b, d));
            }
        }
        best.map(|(f, b, _)| (f, b, false))
    }

    /// Flattening area distortion over faces whose corners lie within `r` of the origin:
    /// `max(rho, 1/rho)`, `rho = (A_2D / A_3D) / (sum A_2D / sum A_3D)`; infinite for a flipped
    /// face.
    pub(super) fn distortion(&self, base: &Base, r: f32) -> (f32, Vec<f32>) {
        let (worst, rho, _) = self.distortion_and_scale(base, r, |_| true);
        (worst, rho)
    }

    /// [`Flat::distortion`] and the mean area scale `sum A_2D / sum A_3D` over the same faces,
    /// counting only the faces `near` accepts (a chart overlapping itself: the near sheet).
    pub(super) fn distortion_and_scale(
        &self,
        base: &Base,
        r: f32,
        near: impl Fn(u32) -> bool,
    ) -> (f32, Vec<f32>, f64) {
        let (mut s2, mut s3) = (0.0f64, 0.0f64);
        let mut worst = 1.0f64;
        let ratio: Vec<f64> = self
            .faces
            .iter()
            .map(|(f, t)| {
                let a2 = 0.5 * (t[1] - t[0]).perp_dot(t[2] - t[0]) as f64;
                let a3 = base.area[*f as usize];
                if a3 <= 1e-30 {
                    return f64::NAN; // degenerate base face: no say
                }
                if t.iter().all(|q| q.length() <= r) && near(*f) {
                    s2 += a2.max(0.0);
                    s3 += a3;
                    if a2 <= 0.0 {
                        worst = f64::INFINITY;
                    }
                }
                if a2 <= 0.0 { 0.0 } else { a2 / a3 }
            })
            .collect();
        let mean = if s2 > 0.0 && s3 > 0.0 { s2 / s3 } else { 1.0 };
        let rho: Vec<f32> = ratio
            .iter()
            .map(|&x| {
                if x.is_nan() {
                    1.0
                } else if x <= 0.0 {
                    f32::INFINITY
                } else {
                    let r = x / mean;
                    r.max(1.0 / r) as f32
                }
            })
            .collect();
        for ((f, t), &q) in self.faces.iter().zip(&rho) {
            if t.iter().all(|p| p.length() <= r) && near(*f) {
                worst = worst.max(q as f64);
            }
        }
        (worst as f32, rho, mean)
    }
}
