//! Where the target coincides with the source up to a similarity (a re-tessellated or remeshed
//! copy, a moved or scaled one, the untouched part of an edited mesh), the exact answer is known:
//! the source point under the target point. The NNF finds it only to within a fraction of a
//! working edge (its matches are vertices, and the global map drifts by about half an edge),
//! which at texel scale shifts thin lines and small features by several texels. This step
//! recovers the exact answer where it exists.
//!
//! 1. [`umeyama`]: the similarity (rotation, uniform scale, translation) that best takes the
//!    target's working vertices to their matched source points (Umeyama 1991), trimmed of the
//!    matches farthest from it.
//! 2. ICP (Besl and McKay 1992): the similarity refitted to the closest source points of the
//!    moved target vertices, a few rounds.
//! 3. A target vertex is snapped where its moved position lies on the source surface (within a
//!    quarter of a source edge), facing the same way, near its own match; its patch map becomes
//!    the similarity itself. Where fewer than half the vertices qualify the shapes do not
//!    coincide and nothing is snapped; the ICP's spread sample settles that first where its
//!    share is well below half, so a bent or different target costs only the ICP rounds.

use glam::{DMat3, DVec3, Vec2, Vec3};
use rayon::prelude::*;

use super::patch_map::PatchMap;
use crate::features::Frames;
use crate::geometry::{TriangleBvh, closest_point_walk};
use crate::hierarchy::Level;
use crate::mesh::Csr;

/// A moved target vertex is on the source surface within this many source mean edges.
pub(super) const ON_SURFACE_EDGES: f32 = 0.25;
/// ... and, for the shapes to count as coinciding, within this many source mean edges of its
/// own match.
const NEAR_MATCH_EDGES: f32 = 3.0;
/// Fewest snapped vertices, as a share of all, for the shapes to count as coinciding.
pub(super) const MIN_SHARE: f64 = 0.5;
/// The ICP sample's share of agreeing vertices below this fraction of [`MIN_SHARE`] settles that
/// the shapes do not coincide (the sample is spread over the surface: its share is within a few
/// percent of the whole's).
const SAMPLE_MARGIN: f64 = 0.8;
/// ICP rounds after the fit to the matches.
const ICP_ROUNDS: usize = 4;
/// Vertices the ICP rounds fit to.
const ICP_SAMPLES: usize = 8192;

/// `x -> scale * rot * x + shift`.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Similarity {
    pub rot: DMat3,
    pub scale: f64,
    pub shift: DVec3,
}

impl Similarity {
    #[inline]
    pub(super) fn apply(&self, x: Vec3) -> Vec3 {
        (self.scale * (self.rot * x.as_dvec3()) + self.shift).as_vec3()
    }
}

/// The least-squares similarity taking `x[i]` to `y[i]` over the pairs `keep` selects
/// (Umeyama 1991); `None` with fewer than three pairs or a degenerate spread.
pub(crate) fn umeyama(x: &[[f32; 3]], y: &[[f32; 3]], keep: &[bool]) -> Option<Similarity> {
    let n = keep.iter().filter(|&&k| k).count();
    if n < 3 {
        return None;
    }
    let (mut mx, mut my) = (DVec3::ZERO, DVec3::ZERO);
    for i in (0..x.len()).filter(|&i| keep[i]) {
        mx += Vec3::from(x[i]).as_dvec3();
        my += Vec3::from(y[i]).as_dvec3();
    }
    mx /= n as f64;
    my /= n as f64;
    let mut cov = faer::Mat::<f64>::zeros(3, 3);
    let mut var = 0.0f64;
    for i in (0..x.len()).filter(|&i| keep[i]) {
        let a = Vec3::from(x[i]).as_dvec3() - mx;
        let b = Vec3::from(y[i]).as_dvec3() - my;
        var += a.length_squared();
        for r in 0..3 {
            for c in 0..3 {
                cov[(r, c)] += b[r] * a[c];
            }
        }
    }
    var /= n as f64;
    if var <= 1e-30 {
        return None;
    }
    for r in 0..3 {
        for c in 0..3 {
            cov[(r, c)] /= n as f64;
        }
    }
    let svd = cov.thin_svd().ok()?;
    let (u, v) = (svd.U(), svd.V());
    let s = svd.S().column_vector();
    let to = |m: faer::MatRef<f64>| {
        DMat3::from_cols(
            DVec3::new(m[(0, 0)], m[(1, 0)], m[(2, 0)]),
            DVec3::new(m[(0, 1)], m[(1, 1)], m[(2, 1)]),
            DVec3::new(m[(0, 2)], m[(1, 2)], m[(2, 2)]),
        )
    };
    let (u, v) = (to(u), to(v));
    let flip = if u.determinant() * v.determinant() < 0.0 {
        -1.0
    } else {
        1.0
    };
    let d = DMat3::from_diagonal(DVec3::new(1.0, 1.0, flip));
    let rot = u * d * v.transpose();
    let scale = (s[0] + s[1] + flip * s[2]) / var;
    if !(scale.is_finite() && scale > 0.0) {
        return None;
    }
    Some(Similarity {
        rot,
        scale,
        shift: my - scale * (rot * mx),
    })
}

/// [`umeyama`] over the pairs `allowed` selects, refitted twice to those within three times
/// the median residual (at least `floor`).
pub(crate) fn umeyama_trimmed(
    x: &[[f32; 3]],
    y: &[[f32; 3]],
    allowed: &[bool],
    floor: f32,
) -> Option<Similarity> {
    let mut sim = umeyama(x, y, allowed)?;
    for _ in 0..2 {
        let res: Vec<f32> = x
            .par_iter()
            .zip(y)
            .map(|(x, y)| (sim.apply(Vec3::from(*x)) - Vec3::from(*y)).length())
            .collect();
        let inside: Vec<f32> = res
            .iter()
            .zip(allowed)
            .filter(|(_, a)| **a)
            .map(|(r, _)| *r)
            .collect();
        let cut = 3.0 * median(&inside).max(floor);
        let keep: Vec<bool> = res
            .iter()
            .zip(allowed)
            .map(|(r, a)| *a && *r < cut)
            .collect();
        sim = umeyama(x, y, &keep)?;
    }
    Some(sim)
}

/// The snapped patch maps (see the module doc): `Some(map)` for every snapped target vertex,
/// or `None` when the shapes do not coincide. `matched[v]` is target vertex `v`'s source
/// point under its fitted patch map.
pub(crate) fn snap_coincident(
    search: &SurfaceSearch,
    source_frames: &Frames,
    target: &Level,
    target_frames: &Frames,
    matched: &[[f32; 3]],
) -> Option<Vec<Option<PatchMap>>> {
    let source = search.level;
    let n = target.len();
    if n < 3 || matched.len() != n {
        return None;
    }
    let edge = source.mean_edge.max(1e-12);
    // 1. The similarity to the matches, trimmed twice.
    let mut sim = umeyama_trimmed(&target.positions, matched, &vec![true; n], 0.25 * edge)?;
    // 2. ICP against the source surface, on a spread subset of the kept vertices (every
    //    `stride`-th: Morton-ordered working vertices are spread over the surface).
    //    Each sampled vertex's closest point is walked from its last one.
    let stride = (n / ICP_SAMPLES).max(1);
    let sample: Vec<usize> = (0..n).step_by(stride).collect();
    let xs: Vec<[f32; 3]> = sample.iter().map(|&v| target.positions[v]).collect();
    let mut hints = vec![u32::MAX; sample.len()];
    let mut closest_of = |sim: &Similarity| -> Vec<Closest> {
        let c: Vec<Closest> = xs
            .par_iter()
            .zip(&hints)
            .map(|(x, &h)| search.tracked(sim.apply(Vec3::from(*x)), h))
            .collect();
        hints.iter_mut().zip(&c).for_each(|(h, c)| *h = c.2);
        c
    };
    for _ in 0..ICP_ROUNDS {
        let c = closest_of(&sim);
        let d: Vec<f32> = c.iter().map(|x| x.1).collect();
        let cut = 3.0 * median(&d).max(0.05 * edge);
        let keep: Vec<bool> = d.iter().map(|&x| x < cut).collect();
        let y: Vec<[f32; 3]> = c.iter().map(|x| x.0).collect();
        match umeyama(&xs, &y, &keep) {
            Some(s) => sim = s,
            None => break,
        }
    }
    // 3. Where the sample already shows that the shapes do not coincide (a bent or another
    //    shape), stop before the closest points of every vertex.
    let agreeing = sample
        .iter()
        .zip(&closest_of(&sim))
        .filter(|&(&v, c)| {
            lies_on(source, target, &sim, v, c)
                && (Vec3::from(c.0) - Vec3::from(matched[v])).length() <= NEAR_MATCH_EDGES * edge
        })
        .count();
    if (agreeing as f64) < SAMPLE_MARGIN * MIN_SHARE * sample.len() as f64 {
        return None;
    }
    // 4. Snap.
    snap(
        search,
        source_frames,
        target,
        target_frames,
        &sim,
        Some(matched),
    )
}

/// Where the target lies on the source in the same space (an edited copy, a mesh completed from
/// its own painted part): every target vertex on the source surface, facing the same way, snaps
/// to the point under it.
pub(crate) fn snap_in_place(
    search: &SurfaceSearch,
    source_frames: &Frames,
    target: &Level,
    target_frames: &Frames,
) -> Option<Vec<Option<PatchMap>>> {
    let identity = Similarity {
        rot: DMat3::IDENTITY,
        scale: 1.0,
        shift: DVec3::ZERO,
    };
    snap(
        search,
        source_frames,
        target,
        target_frames,
        &identity,
        None,
    )
}

/// Step 3 under the similarity `sim`: with `matched`, only when enough vertices also lie near
/// their own matches (see the module doc).
fn snap(
    search: &SurfaceSearch,
    source_frames: &Frames,
    target: &Level,
    target_frames: &Frames,
    sim: &Similarity,
    matched: Option<&[[f32; 3]]>,
) -> Option<Vec<Option<PatchMap>>> {
    let source = search.level;
    let n = target.len();
    let edge = source.mean_edge.max(1e-12);
    let closest_of = |v: usize| search.closest(sim.apply(Vec3::from(target.positions[v])));
    let c: Vec<Closest> = (0..n).into_par_iter().map(closest_of).collect();
    // A vertex is on the source where its moved position lies on the surface facing the same
    // way; the shapes coincide where enough of them are also near their own matches (so the
    // similarity is the NNF's, not a chance fit), and then every vertex on the source snaps,
    // the ones the NNF placed badly included.
    let on: Vec<bool> = (0..n)
        .into_par_iter()
        .map(|v| lies_on(source, target, sim, v, &c[v]))
        .collect();
    if let Some(matched) = matched {
        let agreeing = (0..n)
            .filter(|&v| {
                on[v]
                    && (Vec3::from(c[v].0) - Vec3::from(matched[v])).length()
                        <= NEAR_MATCH_EDGES * edge
            })
            .count();
        if (agreeing as f64) < MIN_SHARE * n as f64 {
            return None;
        }
    }
    let snapped: Vec<Option<PatchMap>> = (0..n)
        .into_par_iter()
        .map(|v| {
            if !on[v] {
                return None;
            }
            let z = sim.apply(Vec3::from(target.positions[v]));
            let lin3 = |t: Vec3| (sim.scale * (sim.rot * t.as_dvec3())).as_vec3();
            let w1 = lin3(Vec3::from(target_frames.t1[v]));
            let w2 = lin3(Vec3::from(target_frames.t2[v]));
            Some(snapped_map(source, source_frames, z, &c[v], w1, w2))
        })
        .collect();
    Some(snapped)
}

/// The patch map of a target vertex whose moved position `z` lies on the source at `c` (its
/// closest point), with its tangent frame moved to `w1`, `w2`: anchored at the nearest corner of
/// `c`'s face, in that corner's frame.
pub(super) fn snapped_map(
    source: &Level,
    source_frames: &Frames,
    z: Vec3,
    c: &Closest,
    w1: Vec3,
    w2: Vec3,
) -> PatchMap {
    let a = anchor_corner(source, c);
    let (t1a, t2a) = (
        Vec3::from(source_frames.t1[a]),
        Vec3::from(source_frames.t2[a]),
    );
    let e = z - Vec3::from(source.positions[a]);
    PatchMap {
        anchor: a as u32,
        origin: Vec2::new(e.dot(t1a), e.dot(t2a)).to_array(),
        lin: [w1.dot(t1a), w2.dot(t1a), w1.dot(t2a), w2.dot(t2a)],
    }
}

/// The corner of the closest point `c`'s face nearest to it (largest barycentric).
pub(super) fn anchor_corner(source: &Level, c: &Closest) -> usize {
    let (_, _, f, b) = *c;
    let face = source.faces[f as usize];
    face[(0..3).max_by(|&i, &j| b[i].total_cmp(&b[j])).unwrap_or(0)] as usize
}

/// Whether the source surface at its closest point `c` faces the way of `normal` (within 60
/// degrees); false where there is no closest point.
pub(super) fn facing(source: &Level, c: &Closest, normal: Vec3) -> bool {
    if c.2 == u32::MAX || !c.1.is_finite() {
        return false;
    }
    Vec3::from(source.normals[anchor_corner(source, c)]).dot(normal) >= 0.5
}

/// Whether target vertex `v`, moved by `sim`, lies on the source surface (`c`, its closest
/// point there, within a quarter of a source edge) facing the same way.
fn lies_on(source: &Level, target: &Level, sim: &Similarity, v: usize, c: &Closest) -> bool {
    if c.1 > ON_SURFACE_EDGES * source.mean_edge.max(1e-12) {
        return false;
    }
    let nt = (sim.rot * Vec3::from(target.normals[v]).as_dvec3()).as_vec3();
    facing(source, c, nt)
}

/// A closest point on the source: (point, distance, face, barycentric); face `u32::MAX` when
/// there is none.
pub(super) type Closest = ([f32; 3], f32, u32, [f32; 3]);

/// The source surface and its two searches for closest points: a tree for a point anywhere, a
/// walk over the surface for a point tracked over rounds.
pub(crate) struct SurfaceSearch<'a> {
    pub level: &'a Level,
    bvh: TriangleBvh,
    faces_of: &'a Csr,
}

impl<'a> SurfaceSearch<'a> {
    /// `faces_of` is `level`'s vertex-to-face CSR.
    pub fn new(level: &'a Level, faces_of: &'a Csr) -> Self {
        SurfaceSearch {
            level,
            bvh: TriangleBvh::new(&level.positions, &level.faces),
            faces_of,
        }
    }

    /// The closest point of the surface to `z` ([`Closest`]).
    pub fn closest(&self, z: Vec3) -> Closest {
        self.closest_found(z, self.bvh.closest_point(z.to_array()))
    }

    /// The closest point of the surface to `z`, a point tracked over rounds whose closest point
    /// in the last round was on face `hint` (`u32::MAX` for none yet): walked over the surface
    /// from there ([`closest_point_walk`]; the point moved little, so the walk takes a step or
    /// two where the tree's search descends from its root).
    pub fn tracked(&self, z: Vec3, hint: u32) -> Closest {
        if hint == u32::MAX {
            return self.closest(z);
        }
        let s = self.level;
        match closest_point_walk(&s.positions, &s.faces, self.faces_of, z, hint) {
            Some(found) => self.closest_found(z, Some(found)),
            None => self.closest(z),
        }
    }

    fn closest_found(&self, z: Vec3, found: Option<(u32, [f32; 3], f32)>) -> Closest {
        let s = self.level;
        match found {
            Some((f, b, d)) => {
                let c = s.faces[f as usize].map(|u| Vec3::from(s.positions[u as usize]));
                let q = c[0] * b[0] + c[1] * b[1] + c[2] * b[2];
                (q.to_array(), d, f, b)
            }
            None => (z.to_array(), f32::INFINITY, u32::MAX, [0.0; 3]),
        }
    }
}

pub(super) fn median(x: &[f32]) -> f32 {
    if x.is_empty() {
        return 0.0;
    }
    let mut v: Vec<f32> = x.iter().copied().filter(|a| a.is_finite()).collect();
    if v.is_empty() {
        return 0.0;
    }
    let k = v.len() / 2;
    v.select_nth_unstable_by(k, |a, b| a.total_cmp(b));
    v[k]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn umeyama_recovers_a_similarity() {
        let x: Vec<[f32; 3]> = (0..50)
            .map(|i| {
                let t = i as f32 * 0.37;
                [t.sin() * 2.0, (t * 1.3).cos(), t * 0.1]
            })
            .collect();
        let rot = DMat3::from_rotation_z(0.4) * DMat3::from_rotation_x(-0.3);
        let truth = Similarity {
            rot,
            scale: 1.7,
            shift: DVec3::new(0.5, -2.0, 3.0),
        };
        let y: Vec<[f32; 3]> = x
            .iter()
            .map(|p| truth.apply(Vec3::from(*p)).to_array())
            .collect();
        let s = umeyama(&x, &y, &vec![true; x.len()]).expect("fit");
        assert!((s.scale - 1.7).abs() < 1e-4, "scale {}", s.scale);
        for p in &x {
            let d = s.apply(Vec3::from(*p)) - truth.apply(Vec3::from(*p));
            assert!(d.length() < 1e-4, "{d}");
        }
    }
}
