//! Step 4's candidates: every swatch element (and, for a periodic tile or a lattice patch, its
//! copies one period apart) centred within the placement disc, mapped through the flattening
//! and into the shell (§3.2's shell map).

use glam::{Vec2, Vec3};

use super::QuiltStats;
use super::elements::{Candidate, centre_and_radius};
use super::flat::uv_to_3d;
use super::flatten::Patch;
use super::setup::Setup;
use super::shell::Base;

/// Maps swatch elements into the shell through one patch's flattening.
pub(super) struct Mapper<'a> {
    pub(super) setup: &'a Setup<'a>,
    pub(super) base: &'a Base<'a>,
    pub(super) patch: &'a Patch,
    /// The patch's rotation (+u to the swatch's +x).
    pub(super) rot: Vec2,
}

impl Mapper<'_> {
    /// Swatch element `e` shifted by `shift` (swatch units), mapped into the shell; `None`
    /// (counted in `stats`) when part of it falls off the flattened base, on too distorted
    /// faces, or tears across a lattice chart's sheets.
    pub(super) fn map(&self, e: usize, shift: Vec2, stats: &mut QuiltStats) -> Option<Candidate> {
        let Mapper {
            setup,
            base,
            patch,
            rot,
        } = *self;
        let (params, sw, s, hscale) = (setup.params, setup.sw, setup.s, setup.hscale);
        let (r_elem, tau, elem_faces) = (setup.r_elem, setup.tau, &setup.elem_faces);
        let (flat, rho, lattice_t) = (&patch.flat, &patch.rho, patch.lattice_t);
        let corners = |f: u32| base.faces[f as usize].map(|v| Vec3::from(base.p[v as usize]));
        let el = &sw.elements[e];
        let uvc = rot.rotate((Vec2::new(el.centre[0], el.centre[1]) + shift) * s);
        let (af, ab, true) = flat.locate(uvc, 0.0)? else {
            return None;
        };
        let mut ps = Vec::with_capacity(el.vertices.len());
        let mut worst = 1.0f32;
        for q in sw.element_positions(e) {
            let uv = rot.rotate((Vec2::new(q[0], q[1]) + shift) * s);
            let Some((f, b, _)) = flat.locate(uv, r_elem + tau) else {
                stats.dropped_unmapped += 1;
                return None;
            };
            worst = worst.max(rho[flat.index[&f] as usize]);
            ps.push(base.shell_point(f, b, q[2] * hscale).to_array());
        }
        if worst > 2.0 * params.max_distortion {
            stats.dropped_distorted += 1;
            return None;
        }
        // a lattice chart that overlaps itself past a singularity can send part of an
        // element to the other sheet: no edge may come out stretched to twice its length
        if lattice_t.is_some() {
            let qs = sw.element_positions(e);
            let torn = elem_faces[e].iter().any(|f| {
                (0..3).any(|k| {
                    let (a, b) = (f[k] as usize, f[(k + 1) % 3] as usize);
                    let d = Vec3::from(qs[a]) - Vec3::from(qs[b]);
                    let want = Vec3::new(d.x * s, d.y * s, d.z * hscale).length();
                    Vec3::from(ps[a]).distance(Vec3::from(ps[b])) > 2.0 * want + tau
                })
            });
            if torn {
                stats.dropped_distorted += 1;
                return None;
            }
        }
        stats.max_element_distortion = stats.max_element_distortion.max(worst);
        let (centre, radius) = centre_and_radius(&ps);
        let k = flat.index[&af] as usize;
        let dir = uv_to_3d(&flat.faces[k].1, corners(af), rot).normalize_or_zero();
        Some(Candidate {
            source: e as u32,
            positions: ps,
            centre,
            radius,
            anchor: (af, ab),
            dir,
            seed_dist: uvc.length(),
            shift,
        })
    }
}

impl Mapper<'_> {
    /// Every vertex of swatch element `e` shifted by `shift`, mapped into the shell as [`map`]
    /// maps it; `None` for a vertex off the flattened base (past its border too, where `map`
    /// extrapolates a little) or on a face distorted past twice
    /// `max_distortion`, and for both ends of an edge a lattice chart tears (stretched past
    /// twice its length). What [`super::trim`] cuts a thread's clear part from.
    ///
    /// [`map`]: Mapper::map
    pub(super) fn map_vertices(&self, e: usize, shift: Vec2) -> Vec<Option<[f32; 3]>> {
        let Mapper {
            setup,
            base,
            patch,
            rot,
        } = *self;
        let (params, sw, s, hscale) = (setup.params, setup.sw, setup.s, setup.hscale);
        let (r_elem, tau) = (setup.r_elem, setup.tau);
        let (flat, rho) = (&patch.flat, &patch.rho);
        let qs = sw.element_positions(e);
        let mut ps: Vec<Option<[f32; 3]>> = qs
            .iter()
            .map(|q| {
                let uv = rot.rotate((Vec2::new(q[0], q[1]) + shift) * s);
                let (f, b, true) = flat.locate(uv, r_elem + tau)? else {
                    return None;
                };
                (rho[flat.index[&f] as usize] <= 2.0 * params.max_distortion)
                    .then(|| base.shell_point(f, b, q[2] * hscale).to_array())
            })
            .collect();
        if patch.lattice_t.is_some() {
            for f in &setup.elem_faces[e] {
                for k in 0..3 {
                    let (a, b) = (f[k] as usize, f[(k + 1) % 3] as usize);
                    let (Some(pa), Some(pb)) = (ps[a], ps[b]) else {
                        continue;
                    };
                    let d = Vec3::from(qs[a]) - Vec3::from(qs[b]);
                    let want = Vec3::new(d.x * s, d.y * s, d.z * hscale).length();
                    if Vec3::from(pa).distance(Vec3::from(pb)) > 2.0 * want + tau {
                        ps[a] = None;
                        ps[b] = None;
                    }
                }
            }
        }
        ps
    }

    /// The base face and barycentric coordinates under swatch point `q` (x-y, swatch units)
    /// shifted by `shift`, and the 3D direction of the swatch's +x axis there.
    pub(super) fn anchor(&self, q: Vec2, shift: Vec2) -> Option<((u32, [f32; 3]), Vec3)> {
        let (flat, s) = (&self.patch.flat, self.setup.s);
        let uv = self.rot.rotate((q + shift) * s);
        let (f, b, true) = flat.locate(uv, 0.0)? else {
            return None;
        };
        let corners = self.base.faces[f as usize].map(|v| Vec3::from(self.base.p[v as usize]));
        let k = flat.index[&f] as usize;
        let dir = uv_to_3d(&flat.faces[k].1, corners, self.rot).normalize_or_zero();
        Some(((f, b), dir))
    }
}

/// The patch's candidates at translation `t` (swatch units): each element within the disc,
/// with its copies one period apart when the tile repeats; and the copies of threads
/// (`elongated`) that did not map whole, `(element, swatch translation)`, for
/// [`super::trim`].
pub(super) fn candidates(
    mapper: &Mapper,
    t: Vec2,
    elongated: &[bool],
    stats: &mut QuiltStats,
) -> (Vec<Candidate>, Vec<(usize, Vec2)>) {
    let mut cands = Vec::new();
    let mut unmapped = Vec::new();
    for (e, shift) in copies_within(mapper, t, mapper.patch.rp) {
        match mapper.map(e, shift, stats) {
            Some(c) => cands.push(c),
            None if elongated[e] => unmapped.push((e, shift)),
            None => {}
        }
    }
    (cands, unmapped)
}

/// [`candidates`] centred within `rp` (base units) of the patch's seed.
pub(super) fn candidates_within(
    mapper: &Mapper,
    t: Vec2,
    rp: f32,
    stats: &mut QuiltStats,
) -> Vec<Candidate> {
    let mut cands: Vec<Candidate> = Vec::new();
    for (e, shift) in copies_within(mapper, t, rp) {
        if let Some(cand) = mapper.map(e, shift, stats) {
            cands.push(cand);
        }
    }
    cands
}

/// The tile's elements and copies at translation `t` (swatch units) centred within `rp`
/// (base units) of the patch's seed: `(element, its swatch translation)`.
pub(super) fn copies_within(mapper: &Mapper, t: Vec2, rp: f32) -> Vec<(usize, Vec2)> {
    let (sw, s, period) = (mapper.setup.sw, mapper.setup.s, mapper.setup.period);
    let lattice_t = mapper.patch.lattice_t;
    let mut copies = Vec::new();
    let rs = rp / s;
    for (e, el) in sw.elements.iter().enumerate() {
        let c = Vec2::new(el.centre[0], el.centre[1]) + t;
        let ranges: [(i64, i64); 2] = if sw.periodic || lattice_t.is_some() {
            let mut r = [(0, 0); 2];
            for a in 0..2 {
                let p = period[a];
                r[a] = (
                    ((-rs - c[a]) / p).ceil() as i64,
                    ((rs - c[a]) / p).floor() as i64,
                );
            }
            r
        } else {
            [(0, 0), (0, 0)]
        };
        for jy in ranges[1].0..=ranges[1].1 {
            for jx in ranges[0].0..=ranges[0].1 {
                let off = Vec2::new(jx as f32 * period[0], jy as f32 * period[1]);
                if ((c + off) * s).length() > rp {
                    continue;
                }
                copies.push((e, t + off));
            }
        }
    }
    copies
}
