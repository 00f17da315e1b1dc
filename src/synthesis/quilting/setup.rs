//! What a quilt fixes before its first patch (§3.1's scale, and what the later steps read of
//! the tile): the swatch's width `L` and the scale `s` on the base, the shell thickness `H`,
//! and the tile's clearances, spacings, periods and element shapes at that scale.

use glam::{Vec2, Vec3};

use super::periodicity::{self, Periodicity};
use super::swatch::Swatch;
use super::{Input, Params};
use crate::error::{Error, Result};
use crate::mesh::TriMesh;
use crate::stats::KdTree;

/// The swatch's scale on the base.
#[derive(Clone, Copy)]
pub(super) struct Size {
    /// `L`: the given swatch's x extent in base units.
    pub(super) l: f32,
    /// `s = L / l_in`: base units per swatch unit.
    pub(super) s: f32,
    /// `H`: the shell thickness in base units.
    pub(super) h: f32,
    /// Base units per swatch unit of height (`H / h_in`; 0 for a flat tile).
    pub(super) hscale: f32,
}

/// Step 1, the scale: `L` (default a tenth of the base's bounding-box diagonal), `s` and `H`
/// for the tile `sw` of `input.swatch` on the base `mesh`, with the parameters and the field
/// checked.
pub(super) fn size(input: &Input, mesh: &TriMesh, sw: &Swatch, params: &Params) -> Result<Size> {
    if let Some(f) = input.field
        && f.len() != mesh.num_vertices()
    {
        return Err(Error::InvalidInput(format!(
            "orientation field has {} vectors for {} base vertices",
            f.len(),
            mesh.num_vertices()
        )));
    }
    let ok = params.max_distortion.is_finite()
        && params.max_distortion >= 1.0
        && params.patch_radius.is_finite()
        && params.patch_radius > 0.0
        && params.lattice_scale.is_finite()
        && params.lattice_scale >= 1.0;
    if !ok {
        return Err(Error::InvalidInput(
            "max_distortion and lattice_scale must be >= 1 and patch_radius > 0".into(),
        ));
    }
    let (lo, hi) = mesh.bounds().expect("validated");
    let diag = Vec3::from(hi).distance(Vec3::from(lo));
    let l = params.swatch_size.unwrap_or(diag / 10.0);
    if !(l.is_finite() && l > 0.0) {
        return Err(Error::InvalidInput(format!(
            "swatch size must be positive (got {l})"
        )));
    }
    // the size names the swatch as given (a finite patch's width), not its tile
    let s = l / input.swatch.extent[0];
    let h = params.thickness.unwrap_or(sw.height * s);
    if !(h.is_finite() && h >= 0.0) {
        return Err(Error::InvalidInput(format!(
            "thickness must be non-negative (got {h})"
        )));
    }
    if let Some(t) = params.thickness
        && t > diag
    {
        return Err(Error::InvalidInput(format!(
            "thickness {t} is more than the base's bounding-box diagonal ({diag}); the shell \
             would swallow the base"
        )));
    }
    let hscale = if sw.height > 0.0 { h / sw.height } else { 0.0 };
    Ok(Size { l, s, h, hscale })
}

/// Refuses a quilt estimated (from the base's area `total_area`) above `params.max_faces`
/// faces or above the memory there is.
pub(super) fn check_output_size(
    sw: &Swatch,
    total_area: f64,
    s: f32,
    params: &Params,
) -> Result<()> {
    let swatch_faces: usize = sw.mesh.num_faces();
    let est_faces =
        total_area / ((sw.extent[0] * sw.extent[1] * s * s) as f64) * swatch_faces as f64;
    if est_faces > params.max_faces as f64 {
        return Err(Error::InvalidInput(format!(
            "the quilt would have about {:.0} faces, above the limit of {}; use a larger swatch size",
            est_faces, params.max_faces
        )));
    }
    // Output faces, their vertices, element records and the candidates of a cut: under 100
    // bytes per output face at peak (measured), 200 with the base's own structures.
    crate::work::check_memory(
        (est_faces as u64).saturating_mul(200),
        &format!("a quilt of about {est_faces:.0} faces"),
        "use a larger --swatch-size",
    )?;
    Ok(())
}

/// The tile at its scale on the base, and the distances the steps compare against.
pub(super) struct Setup<'a> {
    pub(super) params: &'a Params,
    /// The tile repeated (the swatch itself, or its detected tile).
    pub(super) sw: &'a Swatch,
    pub(super) l: f32,
    pub(super) s: f32,
    pub(super) hscale: f32,
    /// Vertex clearance: two elements with vertices closer than this overlap.
    pub(super) tau: f32,
    /// Number of element classes, and the smallest centre spacing per pair of classes
    /// (swatch units, `nc x nc`).
    pub(super) nc: usize,
    pub(super) spacing: Vec<f32>,
    /// Per element: its nearest-neighbour centre distance in a tile cut by spacing, else 0.
    pub(super) own_spacing: Vec<f32>,
    pub(super) min_spacing: f32,
    /// Largest element radius, base units.
    pub(super) r_elem: f32,
    /// Grid step of the matching's translations, swatch units.
    pub(super) cell: f32,
    /// The tile's element centres, for the matching's nearest-centre queries.
    pub(super) centres: Centres,
    /// Each tile element's own triangles.
    pub(super) elem_faces: Vec<Vec<[u32; 3]>>,
    /// The base's mean edge length.
    pub(super) mean_edge: f32,
    /// The tile's period, swatch units: its extent when periodic, else its box plus its own
    /// clearance between elements.
    pub(super) period: [f32; 2],
    /// Correspondence distance for merging, base units.
    pub(super) merge_delta: f32,
    /// Per element: elongated enough to merge and to be nudged (a thread).
    pub(super) elongated: Vec<bool>,
    /// Largest conflict distance between centres, base units.
    pub(super) max_conflict: f32,
    /// Largest centre distance at which [`Setup::conflict_dist`] can call two elements in
    /// conflict (its class term, [`Setup::max_conflict`], or its own-spacing term), base units,
    /// with a little slack for rounding.
    pub(super) conflict_reach: f32,
    /// How far a nudged candidate may move, base units.
    pub(super) nudge_reach: f32,
    /// Cell of the hash of placed elements' centres.
    pub(super) centre_cell: f32,
    /// Smallest placement disc radius a distorted patch shrinks to.
    pub(super) rp_min: f32,
}

impl<'a> Setup<'a> {
    /// The tile `sw` (`found` when detected) at `size` on the base `mesh`.
    pub(super) fn new(
        params: &'a Params,
        sw: &'a Swatch,
        found: Option<&Periodicity>,
        size: Size,
        mesh: &TriMesh,
    ) -> Setup<'a> {
        let Size { l, s, hscale, .. } = size;
        let faces = &mesh.faces;
        let clearance = sw.clearance();
        let tau = if clearance.is_finite() {
            0.5 * clearance * s
        } else {
            0.05 * l
        }
        .max(1e-7 * l);
        let (nc, spacing) = sw.class_spacing();
        // a tile cut by spacing (no lattice: every element differs) keeps each element's own
        // spacing: two copies of different patches conflict closer than 1.1 times the mean of
        // their nearest-neighbour centre distances in the swatch, not only 0.7 of the closest
        // pair of their class (copies of one patch keep the swatch's own layout: the cut's
        // greedy pass bounds them by their radii). Measured on the pebble cluster at a tenth of
        // the diagonal (density over the swatch's, bunny / horse / saddle): 0.9 of the mean
        // 1.09 / 1.22 / 1.02, the mean 1.05 / 1.16 / 1.01, 1.1 times it 1.02 / 1.09 / 1.00,
        // coverage the same
        let own_spacing: Vec<f32> = if found.is_some_and(|p| p.kind == "spacing") {
            periodicity::nearest_spacing(sw)
        } else {
            vec![0.0; sw.num_elements()]
        };
        let min_spacing = spacing.iter().cloned().fold(f32::INFINITY, f32::min);
        let r_elem = sw.elements.iter().map(|e| e.radius).fold(0.0f32, f32::max) * s;
        let cell = sw.extent[0].min(sw.extent[1]) / 16.0;
        let elem_faces: Vec<Vec<[u32; 3]>> = (0..sw.elements.len())
            .map(|e| sw.element_faces(e))
            .collect();
        let mean_edge = crate::geometry::mean_edge_length(&mesh.positions, faces);

        let period: [f32; 2] = if sw.periodic {
            sw.extent
        } else {
            let gap = if clearance.is_finite() {
                clearance
            } else {
                0.0
            };
            [sw.extent[0] + gap, sw.extent[1] + gap]
        };
        // correspondence distance for merging: two mean edge lengths of the swatch's elements
        // (ZHOU proposal 3), scaled
        let merge_delta =
            2.0 * s * crate::geometry::mean_edge_length(&sw.mesh.positions, &sw.mesh.faces);
        // only elongated elements (threads, strands) merge: their copies meet end to end across
        // seams; a fused pair of offset compact elements (rings, studs) reads as a defect, and the
        // cut keeps one of them whole instead
        let elongated: Vec<bool> = (0..sw.elements.len())
            .map(|e| principal_aspect(sw.element_positions(e)) >= params.merge_min_aspect)
            .collect();
        // all placed elements by centre, for conflicts with elements outside the flattened disc
        let r3 = sw
            .elements
            .iter()
            .enumerate()
            .map(|(e, el)| {
                let c = Vec3::from(el.centre);
                sw.element_positions(e)
                    .iter()
                    .map(|p| {
                        let d = Vec3::from(*p) - c;
                        (d.x * d.x + d.y * d.y).sqrt() * s + d.z.abs() * hscale
                    })
                    .fold(0.0f32, f32::max)
            })
            .fold(0.0f32, f32::max);
        let max_conflict = spacing
            .iter()
            .filter(|x| x.is_finite())
            .fold(0.0f32, |a, &b| a.max(0.7 * b * s));
        let own_max = own_spacing.iter().cloned().fold(0.0f32, f32::max);
        let conflict_reach = 1.001 * max_conflict.max(1.1 * own_max * s);
        // how far a nudged candidate may move (at most half of a class's spacing); only threads are
        // nudged, so a swatch without any widens no search
        let nudge_reach = if params.nudge && elongated.iter().any(|&long| long) {
            0.5 * spacing
                .iter()
                .filter(|x| x.is_finite())
                .fold(0.0f32, |a, &b| a.max(b * s))
        } else {
            0.0
        };
        let centre_cell = (4.0 * r3 + 2.0 * tau + 2.0 * nudge_reach)
            .max(max_conflict + nudge_reach)
            .max(1e-6 * l);
        let rp_min = (0.15 * l)
            .max(if min_spacing.is_finite() {
                min_spacing * s
            } else {
                0.0
            })
            .min(params.patch_radius * l);
        Setup {
            params,
            sw,
            l,
            s,
            hscale,
            tau,
            nc,
            spacing,
            own_spacing,
            min_spacing,
            r_elem,
            cell,
            centres: Centres::new(sw),
            elem_faces,
            mean_edge,
            period,
            merge_delta,
            elongated,
            max_conflict,
            conflict_reach,
            nudge_reach,
            centre_cell,
            rp_min,
        }
    }

    /// Two copies of elements `a` and `b` (tile indices) conflict with centres closer than
    /// this: 0.7 of the closest pair of their classes in the swatch, or 1.1 times the mean of
    /// their own nearest-neighbour distances in a tile cut by spacing.
    pub(super) fn conflict_dist(&self, a: u32, b: u32) -> f32 {
        let (sw, spacing, nc, s) = (self.sw, &self.spacing, self.nc, self.s);
        let own_spacing = &self.own_spacing;
        let (ca, cb) = (sw.elements[a as usize].class, sw.elements[b as usize].class);
        let c = spacing[ca as usize * nc + cb as usize];
        let by_class = if c.is_finite() { 0.7 * c * s } else { 0.0 };
        by_class.max(0.55 * (own_spacing[a as usize] + own_spacing[b as usize]) * s)
    }

    /// A nudged copy of class `b` keeps centres at least this far from a class `a` element:
    /// 0.9 of their classes' closest pair in the swatch.
    pub(super) fn nudge_spacing(&self, a: u32, b: u32) -> f32 {
        let (spacing, nc, s) = (&self.spacing, self.nc, self.s);
        let c = spacing[a as usize * nc + b as usize];
        if c.is_finite() { 0.9 * c * s } else { 0.0 }
    }
}

/// Ratio of the two largest principal standard deviations of the points (1 for a ring or a
/// stud, large for a thread; an upright ring, flat in x-y, is still about 1.7).
pub(super) fn principal_aspect(ps: &[[f32; 3]]) -> f32 {
    use glam::{DMat3, DVec3};
    if ps.len() < 2 {
        return 1.0;
    }
    let n = ps.len() as f64;
    let m = ps.iter().map(|p| Vec3::from(*p).as_dvec3()).sum::<DVec3>() / n;
    let mut c = DMat3::ZERO;
    for p in ps {
        let d = Vec3::from(*p).as_dvec3() - m;
        c += DMat3::from_cols(d * d.x, d * d.y, d * d.z);
    }
    // the largest eigenvalue by power iteration, then the largest of the deflated matrix
    let top = |a: DMat3| -> (f64, DVec3) {
        let mut v = DVec3::new(0.6, 0.7, 0.4);
        for _ in 0..100 {
            let w = a * v;
            let l = w.length();
            if l <= 1e-300 {
                return (0.0, v);
            }
            v = w / l;
        }
        (v.dot(a * v), v)
    };
    let (l1, v1) = top(c);
    let d = c - DMat3::from_cols(v1 * v1.x, v1 * v1.y, v1 * v1.z) * l1;
    let (l2, _) = top(d);
    if l2 <= 1e-12 * l1.max(1e-300) {
        return f32::INFINITY;
    }
    (l1 / l2).sqrt() as f32
}

/// The tile's element centres for the matching's nearest-centre queries: one k-d tree over
/// all of them and one per class, with the copies around the tile when it repeats.
pub(super) struct Centres {
    /// The tile's extent when it repeats (queries are wrapped into it).
    period: Option<Vec2>,
    all: (KdTree, Vec<Vec2>),
    by_class: Vec<(KdTree, Vec<Vec2>)>,
}

impl Centres {
    pub(super) fn new(sw: &Swatch) -> Centres {
        let period = sw.periodic.then(|| Vec2::new(sw.extent[0], sw.extent[1]));
        let shifts: Vec<Vec2> = match period {
            Some(e) => (-1..=1)
                .flat_map(|j| (-1..=1).map(move |i| Vec2::new(i as f32 * e.x, j as f32 * e.y)))
                .collect(),
            None => vec![Vec2::ZERO],
        };
        let nc = sw.elements.iter().map(|e| e.class + 1).max().unwrap_or(0) as usize;
        let mut all = Vec::new();
        let mut by_class = vec![Vec::new(); nc];
        for el in &sw.elements {
            for sh in &shifts {
                let c = Vec2::new(el.centre[0], el.centre[1]) + *sh;
                all.push(c);
                by_class[el.class as usize].push(c);
            }
        }
        let tree = |pts: Vec<Vec2>| {
            let flat: Vec<f32> = pts.iter().flat_map(|p| p.to_array()).collect();
            (KdTree::new(&flat, 2), pts)
        };
        Centres {
            period,
            all: tree(all),
            by_class: by_class.into_iter().map(tree).collect(),
        }
    }

    /// For a point `x` of the tile's frame and a class: the offset from the nearest centre of
    /// that class (`x` minus it; infinite when the class has none) and the distance to the
    /// nearest centre of any class.
    pub(super) fn nearest(&self, x: Vec2, class: u32, near: &mut Vec<(f32, u32)>) -> (Vec2, f32) {
        let x = match self.period {
            Some(e) => x - (x / e).floor() * e,
            None => x,
        };
        let mut residual = Vec2::splat(f32::INFINITY);
        if let Some((tree, pts)) = self.by_class.get(class as usize) {
            tree.knn(&x.to_array(), 1, near);
            if let Some(&(_, i)) = near.first() {
                residual = x - pts[i as usize];
            }
        }
        self.all.0.knn(&x.to_array(), 1, near);
        let any = near.first().map_or(f32::INFINITY, |n| n.0.sqrt());
        (residual, any)
    }
}
