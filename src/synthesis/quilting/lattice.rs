//! The global lattice (not in the paper; [`super::Params::lattice`]): two stripe patterns
//! (Knöppel et al. 2015) along the smoothed orientation field and across it, one phase cycle
//! per tile period, their singular faces and the faces within an element's reach of them, and
//! each patch's chart of the two phases ([`LatticeChart`]).

use glam::Vec3;

use super::setup::Setup;
use super::shell::Base;
use crate::geometry::{StripePattern, smooth_direction_field, stripe_pattern};
use crate::work::{Event, Progress, Stopwatch};

/// Largest share of a lattice patch's disc area whose flattening is distorted beyond
/// `max_distortion` (or folded); elements on those faces are dropped one by one.
pub(super) const LATTICE_BAD_AREA: f64 = 0.03;

/// A lattice patch's own sheet: faces within this many disc radii of the seed by the
/// exponential map's distance along edges (which runs longer than the geodesic distance the
/// chart measures, so a disc's own faces pass; a sheet wrapped around a singularity or a limb
/// lies farther).
pub(super) const LATTICE_NEAR: f32 = 1.5;

/// The lattice over the whole base, and the chart of the current patch.
pub(super) struct Lattice {
    /// The stripe patterns along and across the field; `None` without the lattice or when a
    /// factorisation failed (every patch is then matched, as in the paper).
    pub(super) patterns: Option<[StripePattern; 2]>,
    /// Per face: either pattern is singular there (empty without patterns).
    pub(super) singular: Vec<bool>,
    /// Per face: within an element's reach of a singular face.
    pub(super) near_singular: Vec<bool>,
    pub(super) chart: LatticeChart,
}

impl Lattice {
    /// The lattice of `base` when `params.lattice` is on (`field_given`: the field was given,
    /// and is not smoothed), with its singular faces and those near them.
    pub(super) fn solve(
        setup: &Setup,
        base: &Base,
        field_given: bool,
        sink: &dyn Fn(Event),
        clock: &Stopwatch,
    ) -> Lattice {
        let patterns = stripes(setup, base, field_given, sink, clock);
        let singular = singular_faces(base, patterns.as_ref());
        let near_singular = near_singular(base, &singular, setup.r_elem);
        Lattice {
            patterns,
            singular,
            near_singular,
            chart: LatticeChart::new(base.p.len(), base.faces.len()),
        }
    }
}

/// The two stripe patterns, one phase cycle per period, along the field (smoothed below a
/// swatch width unless given) and across it.
fn stripes(
    setup: &Setup,
    base: &Base,
    field_given: bool,
    sink: &dyn Fn(Event),
    clock: &Stopwatch,
) -> Option<[StripePattern; 2]> {
    let (mesh_positions, faces, n) = (base.p, base.faces, base.p.len());
    let (l, s, period) = (setup.l, setup.s, setup.period);
    if setup.params.lattice {
        sink(Event::Progress(Progress {
            stage: "quilt: lattice",
            elapsed: clock.secs(),
            ..Default::default()
        }));
        // the default field (an axis projected) jumps where it switches axes near its poles:
        // smoothed below a swatch width, its singularities become isolated points; a given
        // field is taken as it is
        let guide: Vec<[f32; 3]> = base.field.iter().map(|d| d.to_array()).collect();
        let along = if field_given {
            guide
        } else {
            smooth_direction_field(mesh_positions, faces, &base.vn, &guide, l as f64)
                .unwrap_or(guide)
        };
        let across: Vec<[f32; 3]> = (0..n)
            .map(|i| {
                Vec3::from(base.vn[i])
                    .cross(Vec3::from(along[i]))
                    .normalize_or_zero()
                    .to_array()
            })
            .collect();
        let tau_f = std::f64::consts::TAU;
        let (u, v) = rayon::join(
            || {
                stripe_pattern(
                    mesh_positions,
                    faces,
                    &along,
                    tau_f / (period[0] * s) as f64,
                )
            },
            || {
                stripe_pattern(
                    mesh_positions,
                    faces,
                    &across,
                    tau_f / (period[1] * s) as f64,
                )
            },
        );
        // a failed factorisation leaves the paper's matching
        let lattice = match (u, v) {
            (Ok(u), Ok(v)) => Some([u, v]),
            _ => None,
        };
        sink(Event::StageTime("quilt: lattice", clock.secs()));
        lattice
    } else {
        None
    }
}

/// Per face: either pattern is singular there.
fn singular_faces(base: &Base, patterns: Option<&[StripePattern; 2]>) -> Vec<bool> {
    let (mesh_positions, faces) = (base.p, base.faces);
    match patterns {
        Some(lat) => faces
            .iter()
            .map(|f| lat.iter().any(|p| p.singular(mesh_positions, *f) != 0))
            .collect(),
        None => Vec::new(),
    }
}

/// Faces within an element's reach of a singularity: elements there would straddle it, so
/// lattice patches leave them uncovered and patches seeded on them are matched instead.
fn near_singular(base: &Base, singular: &[bool], r_elem: f32) -> Vec<bool> {
    let (mesh_positions, faces, n) = (base.p, base.faces, base.p.len());
    if singular.iter().any(|&x| x) {
        let mut dist = vec![f32::INFINITY; n];
        let mut heap = std::collections::BinaryHeap::new();
        for (f, _) in singular.iter().enumerate().filter(|(_, x)| **x) {
            for &v in &faces[f] {
                dist[v as usize] = 0.0;
                heap.push(std::cmp::Reverse((0u32, v)));
            }
        }
        while let Some(std::cmp::Reverse((d, v))) = heap.pop() {
            let d = f32::from_bits(d);
            if d > dist[v as usize] || d > r_elem {
                continue;
            }
            let pv = Vec3::from(mesh_positions[v as usize]);
            for &w in base.adj.row(v as usize) {
                let nd = d + pv.distance(Vec3::from(mesh_positions[w as usize]));
                if nd < dist[w as usize] {
                    dist[w as usize] = nd;
                    heap.push(std::cmp::Reverse((nd.to_bits(), w)));
                }
            }
        }
        faces
            .iter()
            .map(|f| f.iter().any(|&v| dist[v as usize] < r_elem))
            .collect()
    } else {
        vec![false; faces.len()]
    }
}

/// A patch's chart of the global lattice: the two stripe phases unwrapped face by face,
/// outwards from the seed face, best first by the mean exponential-map distance of each face's
/// corners, never through a face where either pattern is singular. Each face keeps its
/// own corner values, so a chart that wraps around a singularity overlaps itself there
/// instead of tearing; [`super::flat::Flat::locate`] then takes the sheet nearer the seed. Scratch sized to
/// the base, reused per patch.
pub(super) struct LatticeChart {
    /// Exponential-map distance per vertex of the current disc (valid where `in_disc`).
    dist: Vec<f32>,
    in_disc: Vec<u32>,
    face_done: Vec<u32>,
    stamp: u32,
}

impl LatticeChart {
    fn new(n: usize, nf: usize) -> Self {
        LatticeChart {
            dist: vec![0.0; n],
            in_disc: vec![0; n],
            face_done: vec![0; nf],
            stamp: 0,
        }
    }

    /// The faces of the disc (`verts` with their distances) reached from `seed` without
    /// crossing a singular face, each with its corners' unwrapped phases, in the order they
    /// were reached; `None` when the seed face itself is singular or not wholly in the disc.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn unwrap(
        &mut self,
        lat: &[StripePattern; 2],
        singular: &[bool],
        pos: &[[f32; 3]],
        base: &Base,
        verts: &[u32],
        dist: &[f32],
        seed: u32,
    ) -> Option<Vec<(u32, [[f64; 2]; 3])>> {
        if singular[seed as usize] {
            return None;
        }
        self.stamp += 1;
        let st = self.stamp;
        for (&v, &d) in verts.iter().zip(dist) {
            self.in_disc[v as usize] = st;
            self.dist[v as usize] = d;
        }
        let c = base.faces[seed as usize];
        if c.iter().any(|&v| self.in_disc[v as usize] != st) {
            return None;
        }
        let step = |a: u32, b: u32| [lat[0].step(pos, a, b), lat[1].step(pos, a, b)];
        let v0 = [lat[0].phase(c[0]), lat[1].phase(c[0])];
        let (s1, s2) = (step(c[0], c[1]), step(c[0], c[2]));
        let first = [
            v0,
            [v0[0] + s1[0], v0[1] + s1[1]],
            [v0[0] + s2[0], v0[1] + s2[1]],
        ];
        let key = |f: [u32; 3], d: &[f32]| -> u32 {
            let m = (d[f[0] as usize] + d[f[1] as usize] + d[f[2] as usize]) / 3.0;
            (m.max(0.0)).to_bits() // non-negative floats order like their bits
        };
        let mut out: Vec<(u32, [[f64; 2]; 3])> = Vec::new();
        let mut heap = std::collections::BinaryHeap::new();
        // corner values of the faces pushed, by index
        let mut vals: Vec<[[f64; 2]; 3]> = vec![first];
        heap.push(std::cmp::Reverse((key(c, &self.dist), seed, 0u32)));
        self.face_done[seed as usize] = st;
        // faces are marked when pushed: the first parent to reach a face unwraps it
        while let Some(std::cmp::Reverse((_, f, vi))) = heap.pop() {
            let val = vals[vi as usize];
            let cf = base.faces[f as usize];
            out.push((f, val));
            for k in 0..3 {
                let (a, b) = (cf[k], cf[(k + 1) % 3]);
                let (va, vb) = (val[k], val[(k + 1) % 3]);
                for &g in base.vf.row(a as usize) {
                    if self.face_done[g as usize] == st {
                        continue;
                    }
                    let cg = base.faces[g as usize];
                    if !cg.contains(&b) || cg.iter().any(|&v| self.in_disc[v as usize] != st) {
                        continue;
                    }
                    if singular[g as usize] {
                        continue;
                    }
                    self.face_done[g as usize] = st;
                    let mut vg = [[0.0; 2]; 3];
                    for (i, &w) in cg.iter().enumerate() {
                        vg[i] = if w == a {
                            va
                        } else if w == b {
                            vb
                        } else {
                            let sa = step(a, w);
                            [va[0] + sa[0], va[1] + sa[1]]
                        };
                    }
                    heap.push(std::cmp::Reverse((
                        key(cg, &self.dist),
                        g,
                        vals.len() as u32,
                    )));
                    vals.push(vg);
                }
            }
        }
        Some(out)
    }

    /// Whether every corner of face `f` lies within `r` of the last chart's seed (exponential
    /// map distance), on the near sheet of an overlapping chart.
    pub(super) fn within(&self, base: &Base, f: u32, r: f32) -> bool {
        base.faces[f as usize]
            .iter()
            .all(|&v| self.in_disc[v as usize] == self.stamp && self.dist[v as usize] <= r)
    }
}
