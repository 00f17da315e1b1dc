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
            setup, base, patch, ..
        } = *self;
        let (params, sw, hscale) = (setup.params, setup.sw, setup.hscale);
        let (r_elem, tau, elem_faces) = (setup.r_elem, setup.tau, &setup.elem_faces);
        let (flat, rho) = (&patch.flat, &patch.rho);
        let el = &sw.elements[e];
        let c = Vec2::new(el.centre[0], el.centre[1]);
        let (anchor, dir) = self.anchor(c, shift)?;
        let mut ps = Vec::with_capacity(el.vertices.len());
        let mut worst = 1.0f32;
        for q in sw.element_positions(e) {
            let Some((f, b, _)) = flat.locate(self.uv(q, shift), r_elem + tau) else {
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
        if patch.lattice_t.is_some() {
            let qs = sw.element_positions(e);
            let torn = elem_faces[e].iter().any(|f| {
                (0..3).any(|k| {
                    let (a, b) = (f[k] as usize, f[(k + 1) % 3] as usize);
                    self.torn((qs[a], qs[b]), (ps[a], ps[b]))
                })
            });
            if torn {
                stats.dropped_distorted += 1;
                return None;
            }
        }
        stats.max_element_distortion = stats.max_element_distortion.max(worst);
        let (centre, radius) = centre_and_radius(&ps);
        Some(Candidate {
            source: e as u32,
            positions: ps,
            centre,
            radius,
            anchor,
            dir,
            seed_dist: self.uv(&el.centre, shift).length(),
            shift,
        })
    }

    /// Every vertex of swatch element `e` shifted by `shift`, mapped into the shell as [`map`]
    /// maps it; `None` for a vertex off the flattened base (past its border too, where `map`
    /// extrapolates a little) or on a face distorted past twice `max_distortion`, and for both
    /// ends of an edge a lattice chart tears. What [`super::trim`] cuts a thread's clear part
    /// from.
    ///
    /// [`map`]: Mapper::map
    pub(super) fn map_vertices(&self, e: usize, shift: Vec2) -> Vec<Option<[f32; 3]>> {
        let Mapper {
            setup, base, patch, ..
        } = *self;
        let (flat, rho) = (&patch.flat, &patch.rho);
        let limit = 2.0 * setup.params.max_distortion;
        let qs = setup.sw.element_positions(e);
        let mut ps: Vec<Option<[f32; 3]>> = qs
            .iter()
            .map(|q| {
                let (f, b, _) = flat.locate(self.uv(q, shift), 0.0)?;
                (rho[flat.index[&f] as usize] <= limit)
                    .then(|| base.shell_point(f, b, q[2] * setup.hscale).to_array())
            })
            .collect();
        if patch.lattice_t.is_some() {
            for f in &setup.elem_faces[e] {
                for k in 0..3 {
                    let (a, b) = (f[k] as usize, f[(k + 1) % 3] as usize);
                    if let (Some(pa), Some(pb)) = (ps[a], ps[b])
                        && self.torn((qs[a], qs[b]), (pa, pb))
                    {
                        ps[a] = None;
                        ps[b] = None;
                    }
                }
            }
        }
        ps
    }

    /// The patch's uv of swatch point `q` (x-y read, swatch units) shifted by `shift`.
    fn uv(&self, q: &[f32; 3], shift: Vec2) -> Vec2 {
        self.rot
            .rotate((Vec2::new(q[0], q[1]) + shift) * self.setup.s)
    }

    /// Whether the swatch edge `q` came out as `p` stretched past twice its length: a lattice
    /// chart that overlaps itself past a singularity sends part of an element to the other
    /// sheet.
    fn torn(&self, q: ([f32; 3], [f32; 3]), p: ([f32; 3], [f32; 3])) -> bool {
        let (s, hscale) = (self.setup.s, self.setup.hscale);
        let d = Vec3::from(q.0) - Vec3::from(q.1);
        let want = Vec3::new(d.x * s, d.y * s, d.z * hscale).length();
        Vec3::from(p.0).distance(Vec3::from(p.1)) > 2.0 * want + self.setup.tau
    }

    /// The base face and barycentric coordinates under swatch point `q` (x-y, swatch units)
    /// shifted by `shift`, and the 3D direction of the swatch's +x axis there.
    pub(super) fn anchor(&self, q: Vec2, shift: Vec2) -> Option<((u32, [f32; 3]), Vec3)> {
        let flat = &self.patch.flat;
        let (f, b, true) = flat.locate(self.uv(&[q.x, q.y, 0.0], shift), 0.0)? else {
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
