//! Mesh quilting: geometric textures (chain mail, weaves, nuts, studs, scales) stitched over a
//! surface from a swatch of separate elements (Zhou, Huang, Wang, Guo & Shum 2006, "Mesh
//! Quilting for Geometric Texture Synthesis"; guide in `shared/docs/ZHOU.md`).
//!
//! What runs, in order, and where it departs from the paper:
//!
//! 0. **Periodicity, detected** ([`periodicity`], not in the paper, which pastes the swatch
//!    itself patch by patch): a loaded swatch is matched against shifted copies of itself; a
//!    finite patch with a lattice of translated copies repeats its lattice tile (one element
//!    per orbit), one without repeats a tile cut by its own spacing, a built-in periodic swatch
//!    its period. Everything below works on that tile; `L` still names the given swatch's width.
//!    Links (rings threaded through rings, [`links`]) are told apart from crossing surfaces by
//!    the linking number of centre curves, and the output is measured against the swatch
//!    ([`measure`]: density, links reproduced, coverage; in [`QuiltStats`]).
//! 1. **Scale.** `L` = swatch x extent in base units (default a tenth of the base's bounding-box
//!    diagonal), `s = L / l_in`; shell thickness `H` (default `s h_in`).
//! 2. **Patch growing (§3.1).** Seed = the uncovered base triangle with the most covered
//!    triangles around its corners (the first at random under the seed). The patch is the
//!    geodesic disc of radius `R_place = patch_radius L` around its centroid, grown by Dijkstra
//!    and flattened by the discrete exponential map ([`crate::geometry::exp_map`]) instead of
//!    DCM/LSCM: it is isometric on developable bases and needs no solve. The disc is flattened
//!    out to `R_place + 2 r_elem + ...` so that every element centred inside `R_place` lands on
//!    flattened triangles. Orientation: the circular mean of the +x axes of the elements
//!    already placed in the disc (carried into the flattening through each anchor triangle's
//!    affine map) when they agree, so the lattice continues across seams; otherwise (first
//!    patch, new component, `follow_neighbours = false`) the orientation field at the seed
//!    becomes the swatch +x axis (ZHOU proposal 8). Default field: the base x axis projected
//!    onto each tangent plane (y near the poles of x); an input field replaces it. Area
//!    distortion `max(rho, 1/rho)` over the triangles of the placement disc (proposal 7) above
//!    `max_distortion` (default 2, the paper uses 4) shrinks the disc by 0.75 and retries, down
//!    to `max(0.15 L, smallest element spacing)`; there, candidates on triangles distorted
//!    more than `2 max_distortion` are dropped rather than stretched.
//!
//!    **Global lattice** (not in the paper; `lattice`, on by default): before any patch, the
//!    orientation field is smoothed below a swatch width
//!    ([`crate::geometry::smooth_direction_field`], unless a field is given) and two stripe
//!    patterns ([`crate::geometry::stripe_pattern`], Knöppel et al. 2015) are solved along it
//!    and across it, one phase cycle per swatch period (the extent of a periodic swatch, else
//!    its box plus its own clearance). A patch then unwraps both phases face by face outwards
//!    from its seed over the flattened disc, never through a face where either pattern is
//!    singular, and uses them (scaled to swatch units) as its flattening, with the translation
//!    that puts the swatch's lattice on the phases' and no rotation: every such patch lays its
//!    copies on the same lattice, so copies of neighbouring patches coincide instead of
//!    clashing at seams. Where the unwrapped chart overlaps itself (around a singularity) the
//!    sheet nearer the seed is used, coverage and distortion count only faces within the disc's
//!    geodesic radius, and a candidate with an edge stretched past twice its length is
//!    dropped. A patch falls back to the exponential map and the matching below when its seed
//!    lies within an element's reach (`r_elem`) of a singular face, more than 3% of its disc's
//!    area is distorted beyond `max_distortion` or folded, or its chart's mean area scale is off
//!    by more than `lattice_scale`; lattice patches leave the faces near a singularity
//!    uncovered for matched patches. Measured with `examples/quilt_clearance` (a tenth of the
//!    diagonal): the weave's face density on the bunny 0.66 -> 0.80 of the swatch's, the chain
//!    1.08 -> 1.05, element area CV 0.04-0.08 -> 0.09-0.14 (the stripes' period drifts where
//!    the field turns), run times equal or shorter; on the horse the weave 0.51 -> 0.54.
//! 3. **Matching (§2.4, simplified).** Eq. (1)-(3) are taken at the element level: the
//!    already-placed elements whose centres fall in the patch are brought into swatch
//!    coordinates and every swatch translation `t` on a grid of `l_in / 16` (one period for
//!    periodic swatches; keeping the disc inside the swatch otherwise) is scored by
//!    `E(t) = sum_old min_j (|c_old - (c_j + t)| / cell + [class_j != class_old])`, capped per
//!    element at 4 (class = elements with equal vertex and face counts). The best `t` is then
//!    refined continuously by the mean residual of matched same-class pairs, so a periodic
//!    swatch re-registers exactly with what is already there.
//! 4. **Element correspondences, merging and graph cut (§2.5-2.7).** A new element
//!    *conflicts* with an old one when their centres
//!    are closer than 0.7 of the smallest centre spacing of their two classes in the swatch, or
//!    any two of their vertices are closer than half the swatch's own clearance between
//!    elements. Which elements survive is a maximum-weight independent set of this bipartite
//!    conflict graph, solved exactly as an s-t min cut (Dinic max-flow, [`maxflow`]): SOURCE ->
//!    old (weight 1.1), old -> new (infinite) per conflict, new -> SINK (weight 1). Then new
//!    elements that conflict with each other (flattening distortion) are dropped greedily,
//!    nearest to the seed first. Two elements whose surfaces cross ([`crossing`]: an edge of one
//!    piercing a triangle of the other, which the vertex test misses for interlinked rings and
//!    crossing strands bent by the shell map or meeting across a seam) conflict too. So two
//!    survivors never overlap and elements stay whole. Before the cut, a new copy of an
//!    elongated element (a thread: principal aspect >= `merge_min_aspect`) that continues an
//!    old copy of the same class is taken out of the conflict graph when [`merging`] can join
//!    them: both deformed half-way with Laplacian coordinates (eq. (4)-(5)), cut across the
//!    overlap, the cut loops stitched, the result checked to be one oriented manifold with the
//!    element's Euler characteristic. If the new copy survives the cut and the greedy pass,
//!    the old element is replaced by the merged one, provided that still keeps clear of
//!    every other element (vertex distance and surface crossing); otherwise the new copy is
//!    dropped. Compact elements (rings, studs, nuts) are never merged: a fused pair of offset
//!    rings reads as a defect, while the cut keeps one of them whole.
//!
//!    **Nudge** (not in the paper; `nudge`, on by default): each elongated candidate (a
//!    thread, as for merging) the cut or the greedy pass drops, nearest to the seed first,
//!    unless a same-class element already holds
//!    its spot (centres within 0.35 of the class spacing), is mapped again with its swatch
//!    translation moved by a quarter, then a half of its class's centre spacing in eight
//!    directions, and the first position that clears every element (vertex distance, centres
//!    at least 0.9 of the swatch's spacing apart, no crossing surfaces) is kept. It fills the
//!    gaps that long elements leave where the lattices of neighbouring patches disagree
//!    sideways, without packing elements denser than the swatch. Measured with
//!    `examples/quilt_clearance` (a tenth of the diagonal): the weave's face density 0.60 ->
//!    0.66 of the swatch's on the bunny (2.1 -> 4.6 s) and 0.46 -> 0.51 on the horse (16.7 ->
//!    18.0 s). Compact elements are not nudged: their density is already within 10% of the
//!    swatch's, nudging them added up to 5% (the bunny's chain to 1.13, denser than the swatch)
//!    at 2.5 times the run time.
//! 5. **Shell map (§3.2).** A swatch point `(x, y, z)` goes to `uv = s R (x + t)` in the
//!    flattened patch, to the base triangle and barycentric coordinates `b` containing it
//!    (affine extrapolation from the nearest triangle for points just past a base boundary),
//!    and into the shell ([`crate::geometry::shell_map`]) at height fraction `w = z / h_in`. The
//!    offset surface starts at `H` along the area-weighted vertex normals, scaled by
//!    `g = min(1, 0.9 / (kappa H))` per base vertex (`kappa` the largest concave normal
//!    curvature `|n_j - n_i| / |p_j - p_i|` over its edges), is shortened where a tetrahedron
//!    of the shell (each prism cut in three) would still be inverted (ZHOU proposal 9), and its
//!    vertices then slide in their tangent planes to minimise the shell's L2 stretch (eq. 8-9,
//!    Sander-style random line search, `shell_sweeps` sweeps; the stretch before and after is
//!    in [`QuiltStats`]). The point itself is `sum b_i ((1 - w) p_i + w q_i)`, the ruled
//!    interpolation between the base and the offset triangle, instead of the paper's map
//!    through the tetrahedra (`shell_tetrahedra`): the tetrahedra bend every element along
//!    their internal faces. Measured with `examples/quilt_clearance` on the bunny and the
//!    horse, against the earlier map along interpolated normals: element counts within 1% at
//!    the default thickness (the tetrahedra lost 8% of the horse's weave), element area CV
//!    1-13% lower (the horse's nuts 1% higher); with a shell half a swatch thick on the
//!    bunny, 1-6% more elements and a CV of 0.25 instead of 0.29 (chain).
//! 6. **Departures in merging** (listed in [`merging`]): both elements take vertex constraints
//!    (eq. (5) for both instead of eq. (6) for `C_in`); the cut is a plane across the middle of
//!    the overlap instead of eq. (7)'s per-element graph cut; vertices away from the joint are
//!    held. Measured with `examples/quilt_clearance` (weave at a tenth of the diagonal): 127
//!    merged threads on the bunny, 35 on the horse, no crossing surfaces; the face density is
//!    unchanged (bunny 0.60 -> 0.59, horse 0.46 -> 0.44 of the swatch's), since the gaps a
//!    weave leaves on curved bases come from lattices of neighbouring patches that disagree
//!    sideways, which no end-to-end join repairs.
//!
//! Output: all kept elements merged in one [`TriMesh`], with a per-vertex element id and a
//! per-element source (swatch element index). Planar quilting is the same code on a flat base
//! ([`plane`]).
//!
//! Measured (release, 2 shared cores): chain mail on the Stanford bunny (6598 faces) at the
//! default scale: 464 patches, about 5070 elements, 0.97 M faces, about 7 s; a periodic swatch
//! on a plane is reproduced exactly (rigid copies on one lattice).

mod crossing;
mod finite_patch;
mod io;
pub mod links;
pub mod maxflow;
pub mod measure;
pub mod merging;
pub mod periodicity;
mod swatch;

pub use crossing::crossing_pairs;
pub use finite_patch::{PatchKind, finite_patch};
pub use io::{save_quilt_obj, save_quilt_ply};
pub use swatch::{Axis, Element, Swatch, SwatchKind, load_swatch, swatch};

use std::collections::HashMap;

use glam::{Vec2, Vec3};
use rand::{Rng, SeedableRng, rngs::SmallRng};

use crate::error::{Error, Result};
use crate::geometry::{
    DiscSeed, StripePattern, TriangleBvh, exp_map, face_areas, face_normals,
    minimize_shell_stretch, offset_surface, shell_point, shell_point_ruled, shell_stretch,
    smooth_direction_field, stripe_pattern, tangent_direction, vertex_normals,
};
use crate::mesh::{Csr, TriMesh, vertex_adjacency, vertex_faces};
use crate::work::{CancelToken, Event, Progress, Stopwatch};

/// Parameters of [`run`].
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
#[serde(default)]
pub struct Params {
    /// Swatch x extent in base units (`L`); `None`: a tenth of the base's bbox diagonal.
    pub swatch_size: Option<f32>,
    /// Shell thickness `H` in base units; `None`: the swatch height scaled like its extent.
    pub thickness: Option<f32>,
    /// Random seed (first placement, first seed triangle).
    pub seed: u64,
    /// Refuse runs whose output would exceed this many faces (estimated up front and checked
    /// while running).
    pub max_faces: usize,
    /// Largest accepted flattening area distortion `max(rho, 1/rho)` of a patch before it is
    /// shrunk (paper: 4).
    pub max_distortion: f32,
    /// Radius of the placement disc in units of `L`.
    pub patch_radius: f32,
    /// Limit offsets in concave regions by the local radius of curvature, and shorten them
    /// where a shell tetrahedron would be inverted.
    pub concave_guard: bool,
    /// Sweeps of the shell's stretch minimisation (eq. 8-9); 0: the plain offset shell.
    pub shell_sweeps: usize,
    /// Map elements through the shell's three tetrahedra per prism (the paper's piecewise-linear
    /// map) instead of the ruled interpolation between base and offset triangle (smooth inside
    /// a prism; measured: as many elements, more even sizes).
    pub shell_tetrahedra: bool,
    /// Orient each patch like the elements already placed in it (keeps the lattice continuous
    /// across seams); the field only orients patches with no placed neighbours. Off: every
    /// patch follows the field at its seed.
    pub follow_neighbours: bool,
    /// Merge a new element with an overlapping old copy of the same element (Laplacian
    /// deformation half-way, cut, stitch: §2.6-2.7) instead of keeping only one of them. Off
    /// by default: measured on weaves over curved bases it leaves the face density as it is
    /// (within 5%) at 2.5-3 times the run time; the threads it joins run on across seams.
    pub merge_elements: bool,
    /// Try each thread (an element at least `merge_min_aspect` elongated) the cut drops again,
    /// moved by a quarter or half of its class's spacing in eight directions, and keep the
    /// first position that clears every element (fills the gaps left where the lattices of
    /// neighbouring patches disagree). Compact elements are never moved.
    pub nudge: bool,
    /// Place every patch on one global lattice: two stripe patterns along the orientation field
    /// and across it (Knöppel et al. 2015, period one swatch) give each patch its flattening,
    /// so that neighbouring patches lay their copies on the same lattice and threads meet
    /// end to end across seams. A patch seeded within an element's reach of a singularity of
    /// the lattice, with more than 3% of its disc distorted beyond `max_distortion` (or folded),
    /// or with a mean scale beyond `lattice_scale`, falls back to the exponential map and the
    /// matching of §2.4. Off: every patch is matched as in the paper.
    pub lattice: bool,
    /// Largest mean area scale `max(k, 1/k)` of a patch's lattice chart against the surface
    /// (the stripes' period drifts where the field turns): beyond it the patch falls back to
    /// the exponential map. Measured on the bunny's weave: at 1.25 a face density of 0.80 of
    /// the swatch's with element areas varying by 12% (CV); looser bounds add a few percent of
    /// density and more size variation.
    pub lattice_scale: f32,
    /// Only elements at least this elongated merge (ratio of their two largest principal
    /// standard deviations in the swatch: strands of a weave about 9, rings and studs 1-2).
    pub merge_min_aspect: f32,
    /// Detect the swatch's periodicity ([`periodicity`]): a finite patch with a lattice of
    /// translated copies repeats its lattice tile, one without repeats a tile cut by its own
    /// spacing. Off: a swatch not built periodic tiles with its box plus its clearance.
    pub detect_period: bool,
    /// Quilt a closed base whose faces are wound inwards (negative enclosed volume, as scans
    /// often are) on its outside. Off: the shell always follows the faces' winding (the inside
    /// of a closed surface can be quilted).
    pub outward: bool,
}

impl Default for Params {
    fn default() -> Self {
        Params {
            swatch_size: None,
            thickness: None,
            seed: 1,
            max_faces: 5_000_000,
            max_distortion: 2.0,
            patch_radius: 0.5,
            concave_guard: true,
            shell_sweeps: 10,
            shell_tetrahedra: false,
            follow_neighbours: true,
            merge_elements: false,
            nudge: true,
            lattice: true,
            lattice_scale: 1.25,
            merge_min_aspect: 3.0,
            detect_period: true,
            outward: true,
        }
    }
}

/// What to quilt: a base surface, a swatch and an optional per-vertex orientation field (the
/// swatch +x axis follows it; tangent to the base or not, it is projected).
#[derive(Clone, Copy, Debug)]
pub struct Input<'a> {
    /// The base surface.
    pub base: &'a TriMesh,
    /// The swatch.
    pub swatch: &'a Swatch,
    /// Optional per-vertex direction field, one per base vertex.
    pub field: Option<&'a [[f32; 3]]>,
}

/// Counters and measured values of one run.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct QuiltStats {
    /// Patches placed.
    pub patches: usize,
    /// Elements in the output.
    pub elements: usize,
    /// New elements dropped by the cut or the greedy overlap check.
    pub dropped_conflict: usize,
    /// Already placed elements replaced by new ones in a cut.
    pub replaced_old: usize,
    /// New elements merged into an overlapping old one (§2.6-2.7).
    pub merged: usize,
    /// Dropped candidates kept after all, nudged into a gap.
    pub nudged: usize,
    /// Candidates dropped because part of them fell off the flattened base.
    pub dropped_unmapped: usize,
    /// Elements dropped at the end because a vertex lay outside the shell (distorted or
    /// extrapolated patches on thin parts).
    pub dropped_outside_shell: usize,
    /// Patches flattened by the global lattice ([`Params::lattice`]); the rest by the
    /// exponential map.
    pub lattice_patches: usize,
    /// Patch retries with a smaller disc because of area distortion.
    pub shrunk_patches: usize,
    /// Candidates dropped because they lie on flattened triangles distorted by more than twice
    /// `max_distortion` (left in patches that could not shrink further).
    pub dropped_distorted: usize,
    /// Largest flattening distortion under a kept element.
    pub max_element_distortion: f32,
    /// Largest flattening distortion of an accepted patch's placement disc.
    pub max_distortion: f32,
    /// Fraction of base area covered by patches.
    pub covered_fraction: f32,
    /// `L` used.
    pub swatch_size: f32,
    /// `H` used.
    pub thickness: f32,
    /// Normalised L2 stretch of the shell (eq. 9) before its minimisation.
    pub shell_stretch_before: f64,
    /// Normalised L2 stretch of the shell after its minimisation.
    pub shell_stretch: f64,
    /// Shell tetrahedra left inverted (vertices whose normal disagrees with a face's).
    pub shell_inverted: usize,
    /// How the repeated tile was found ([`periodicity::Periodicity::kind`]; `"box"` without
    /// detection).
    pub periodicity: String,
    /// The swatch's symmetry vectors (swatch units), when it has a lattice.
    pub lattice_vectors: Option<[[f32; 2]; 2]>,
    /// Elements in the repeated tile.
    pub tile_elements: usize,
    /// Element density of the output over the swatch's ([`measure`]).
    pub density_ratio: f32,
    /// The same over convex regions of the base.
    pub density_ratio_convex: Option<f32>,
    /// The same over saddle-shaped regions of the base.
    pub density_ratio_saddle: Option<f32>,
    /// Output links per element over the swatch's (`None`: the swatch has no links).
    pub link_share: Option<f32>,
    /// Links per element in the swatch (with its copies around it on a lattice).
    pub swatch_links_per_element: f32,
    /// Links per element in the output.
    pub links_per_element: f32,
    /// Share of the base's area with no gap larger than the swatch's largest.
    pub coverage: f32,
    /// Wall time in seconds.
    pub seconds: f64,
}

/// The system's output (the house shape's name for [`QuiltOutput`]).
pub type Output = QuiltOutput;

/// The quilted geometry.
#[derive(Clone, Debug)]
pub struct QuiltOutput {
    /// All elements merged, each a contiguous vertex and face range.
    pub elements: TriMesh,
    /// Output element index per vertex.
    pub element_id: Vec<u32>,
    /// Swatch element index per output element (the first copy's, for a merged element).
    pub element_source: Vec<u32>,
    /// Swatch copies joined in each output element: 1 for a (deformed) copy, more for an
    /// element merged across patch seams ([`merging`]).
    pub element_pieces: Vec<u32>,
    /// Counters.
    pub stats: QuiltStats,
}

impl QuiltOutput {
    /// Number of output elements.
    pub fn num_elements(&self) -> usize {
        self.element_source.len()
    }
}

impl QuiltStats {
    /// One line on how well the swatch's arrangement came through: element density over the
    /// swatch's (and on convex and saddle regions), the share of the swatch's links reproduced
    /// and the coverage (base area without gaps larger than the swatch's largest).
    pub fn arrangement_summary(&self) -> String {
        let region =
            |name: &str, r: Option<f32>| r.map_or(String::new(), |r| format!(", {name} {r:.2}"));
        let links = match self.link_share {
            Some(x) => format!(
                "{:.0}% of the swatch's links ({:.2} per element, swatch {:.2})",
                100.0 * x,
                self.links_per_element,
                self.swatch_links_per_element
            ),
            None => "no links in the swatch".into(),
        };
        format!(
            "density {:.2} of the swatch's{}{}; {}; coverage {:.1}%; swatch tiled by {} ({} elements per tile)",
            self.density_ratio,
            region("convex", self.density_ratio_convex),
            region("saddle", self.density_ratio_saddle),
            links,
            100.0 * self.coverage,
            self.periodicity,
            self.tile_elements
        )
    }
}

/// A saddle `z = k (x^2 - y^2)` over the square `[-1, 1]^2`, split into `n x n` quads of two
/// triangles (normal up): a base of negative Gaussian curvature everywhere.
pub fn saddle(k: f32, n: usize) -> TriMesh {
    let n = n.max(1);
    let mut positions = Vec::with_capacity((n + 1) * (n + 1));
    for j in 0..=n {
        for i in 0..=n {
            let x = -1.0 + 2.0 * i as f32 / n as f32;
            let y = -1.0 + 2.0 * j as f32 / n as f32;
            positions.push([x, y, k * (x * x - y * y)]);
        }
    }
    let id = |i: usize, j: usize| (j * (n + 1) + i) as u32;
    let mut faces = Vec::with_capacity(2 * n * n);
    for j in 0..n {
        for i in 0..n {
            faces.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
            faces.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
        }
    }
    TriMesh::new(positions, faces)
}

/// A flat `w x h` rectangle in the z = 0 plane (normal +z), corner at the origin, split into
/// `nx x ny` quads of two triangles: the base of planar quilting.
pub fn plane(w: f32, h: f32, nx: usize, ny: usize) -> TriMesh {
    let (nx, ny) = (nx.max(1), ny.max(1));
    let mut pos = Vec::with_capacity((nx + 1) * (ny + 1));
    for j in 0..=ny {
        for i in 0..=nx {
            pos.push([w * i as f32 / nx as f32, h * j as f32 / ny as f32, 0.0]);
        }
    }
    let id = |i: usize, j: usize| (j * (nx + 1) + i) as u32;
    let mut faces = Vec::with_capacity(2 * nx * ny);
    for j in 0..ny {
        for i in 0..nx {
            faces.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
            faces.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
        }
    }
    TriMesh::new(pos, faces)
}

/// The base surface with what the shell map needs.
struct Base<'a> {
    p: &'a [[f32; 3]],
    faces: &'a [[u32; 3]],
    vn: Vec<[f32; 3]>,
    fnrm: Vec<[f32; 3]>,
    area: Vec<f64>,
    adj: Csr,
    vf: Csr,
    /// The offset surface bounding the shell.
    top: Vec<[f32; 3]>,
    /// Shell thickness `H` (height fraction 1).
    thickness: f32,
    /// Map through the shell's tetrahedra instead of the ruled prism interpolation.
    tetrahedra: bool,
    field: Vec<Vec3>,
}

impl Base<'_> {
    /// The shell map: base point at barycentric `b` of face `f`, at height `h` (base units,
    /// `H` at the offset surface), through the shell's tetrahedra.
    fn shell_point(&self, f: u32, b: [f32; 3], h: f32) -> Vec3 {
        let w = if self.thickness > 0.0 {
            h / self.thickness
        } else {
            0.0
        };
        if self.tetrahedra {
            shell_point(self.p, &self.top, self.faces, f, b, w)
        } else {
            shell_point_ruled(self.p, &self.top, self.faces, f, b, w)
        }
    }
}

/// A flattened patch with a point-location grid.
struct Flat {
    /// Base face -> index into `faces`.
    index: HashMap<u32, u32>,
    /// Base faces whose three corners are flattened, with their 2D corners.
    faces: Vec<(u32, [Vec2; 3])>,
    lo: Vec2,
    cell: f32,
    dims: [usize; 2],
    grid: Vec<Vec<u32>>,
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
fn uv_to_3d(q: &[Vec2; 3], p: [Vec3; 3], w: Vec2) -> Vec3 {
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
fn dir_to_uv(q: &[Vec2; 3], p: [Vec3; 3], d: Vec3) -> Vec2 {
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
    fn new(base: &Base, verts: &[u32], uvs: &[[f32; 2]]) -> Flat {
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
        Flat::from_faces(faces, false)
    }

    /// A flattening given face by face (2D corners per base face, each face once).
    fn from_faces(faces: Vec<(u32, [Vec2; 3])>, prefer_first: bool) -> Flat {
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
    /// `extrapolate > 0` the nearest face within that distance, with affine (possibly
    /// negative) barycentric coordinates. Returns `(face, b, inside)`.
    fn locate(&self, p: Vec2, extrapolate: f32) -> Option<(u32, [f32; 3], bool)> {
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
        let r = (extrapolate / self.cell).ceil() as i64 + 1;
        let q = ((p - self.lo) / self.cell).floor();
        let (ci, cj) = (q.x as i64, q.y as i64);
        let mut best: Option<(u32, [f32; 3], f32)> = None;
        for j in (cj - r).max(0)..=(cj + r).min(self.dims[1] as i64 - 1) {
            for i in (ci - r).max(0)..=(ci + r).min(self.dims[0] as i64 - 1) {
                for &k in &self.grid[j as usize * self.dims[0] + i as usize] {
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
            }
        }
        best.map(|(f, b, _)| (f, b, false))
    }

    /// Flattening area distortion over faces whose corners lie within `r` of the origin:
    /// `max(rho, 1/rho)`, `rho = (A_2D / A_3D) / (sum A_2D / sum A_3D)`; infinite for a flipped
    /// face.
    fn distortion(&self, base: &Base, r: f32) -> (f32, Vec<f32>) {
        let (worst, rho, _) = self.distortion_and_scale(base, r, |_| true);
        (worst, rho)
    }

    /// [`Flat::distortion`] and the mean area scale `sum A_2D / sum A_3D` over the same faces,
    /// counting only the faces `near` accepts (a chart overlapping itself: the near sheet).
    fn distortion_and_scale(
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

/// Largest share of a lattice patch's disc area whose flattening is distorted beyond
/// `max_distortion` (or folded); elements on those faces are dropped one by one.
const LATTICE_BAD_AREA: f64 = 0.03;

/// A lattice patch's own sheet: faces within this many disc radii of the seed by the
/// exponential map's distance along edges (which runs longer than the geodesic distance the
/// chart measures, so a disc's own faces pass; a sheet wrapped around a singularity or a limb
/// lies farther).
const LATTICE_NEAR: f32 = 1.5;

/// A patch's chart of the global lattice: the two stripe phases unwrapped face by face,
/// outwards from the seed face, best first by the mean exponential-map distance of each face's
/// corners, never through a face where either pattern is singular. Each face keeps its
/// own corner values, so a chart that wraps around a singularity overlaps itself there
/// instead of tearing; [`Flat::locate`] then takes the sheet nearer the seed. Scratch sized to
/// the base, reused per patch.
struct LatticeChart {
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
    fn unwrap(
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
    fn within(&self, base: &Base, f: u32, r: f32) -> bool {
        base.faces[f as usize]
            .iter()
            .all(|&v| self.in_disc[v as usize] == self.stamp && self.dist[v as usize] <= r)
    }
}

/// One swatch copy inside a placed element (a merged element holds several).
struct Piece {
    centre: Vec3,
    anchor: (u32, [f32; 3]),
    /// Unit 3D tangent of the swatch +x axis at the copy.
    dir: Vec3,
}

/// One placed element.
struct Placed {
    source: u32,
    positions: Vec<[f32; 3]>,
    /// Its own triangles once merged ([`merging`]); `None`: the source element's.
    faces: Option<Vec<[u32; 3]>>,
    pieces: Vec<Piece>,
    alive: bool,
}

impl Placed {
    fn faces<'a>(&'a self, elem_faces: &'a [Vec<[u32; 3]>]) -> &'a [[u32; 3]] {
        self.faces
            .as_deref()
            .unwrap_or(&elem_faces[self.source as usize])
    }
    fn geometry<'a>(&'a self, elem_faces: &'a [Vec<[u32; 3]>]) -> merging::ElementGeometry<'a> {
        merging::ElementGeometry {
            positions: &self.positions,
            faces: self.faces(elem_faces),
        }
    }
    /// Distance from `p` to the nearest piece centre.
    fn centre_distance(&self, p: Vec3) -> f32 {
        self.pieces
            .iter()
            .map(|q| q.centre.distance(p))
            .fold(f32::INFINITY, f32::min)
    }
}

/// A candidate element of the current patch.
struct Candidate {
    source: u32,
    positions: Vec<[f32; 3]>,
    centre: Vec3,
    radius: f32,
    anchor: (u32, [f32; 3]),
    dir: Vec3,
    seed_dist: f32,
    /// Swatch translation (swatch units) of this copy.
    shift: Vec2,
}

impl Candidate {
    fn geometry<'a>(&'a self, elem_faces: &'a [Vec<[u32; 3]>]) -> merging::ElementGeometry<'a> {
        merging::ElementGeometry {
            positions: &self.positions,
            faces: &elem_faces[self.source as usize],
        }
    }
}

fn centre_and_radius(ps: &[[f32; 3]]) -> (Vec3, f32) {
    let mut lo = Vec3::splat(f32::INFINITY);
    let mut hi = Vec3::splat(f32::NEG_INFINITY);
    for p in ps {
        lo = lo.min(Vec3::from(*p));
        hi = hi.max(Vec3::from(*p));
    }
    let c = (lo + hi) * 0.5;
    let r = ps
        .iter()
        .map(|p| Vec3::from(*p).distance(c))
        .fold(0.0f32, f32::max);
    (c, r)
}

/// Vertex hash for the "vertices closer than tau" overlap test.
struct VertexHash {
    cell: f32,
    map: rustc_hash::FxHashMap<[i32; 3], Vec<(u32, Vec3)>>,
}

impl VertexHash {
    fn new(cell: f32) -> Self {
        VertexHash {
            cell,
            map: Default::default(),
        }
    }
    fn key(&self, p: Vec3) -> [i32; 3] {
        let q = (p / self.cell).floor();
        [q.x as i32, q.y as i32, q.z as i32]
    }
    fn insert(&mut self, id: u32, ps: &[[f32; 3]]) {
        for p in ps {
            let p = Vec3::from(*p);
            let k = self.key(p);
            self.map.entry(k).or_default().push((id, p));
        }
    }
    /// Whether some id passing `keep` has a vertex closer than `tau` (<= cell) to one of `ps`.
    fn any_near(&self, ps: &[[f32; 3]], tau: f32, keep: impl Fn(u32) -> bool) -> bool {
        ps.iter().any(|p| {
            let p = Vec3::from(*p);
            let k = self.key(p);
            (-1..=1).any(|dz| {
                (-1..=1).any(|dy| {
                    (-1..=1).any(|dx| {
                        self.map
                            .get(&[k[0] + dx, k[1] + dy, k[2] + dz])
                            .is_some_and(|list| {
                                list.iter()
                                    .any(|&(id, q)| q.distance_squared(p) < tau * tau && keep(id))
                            })
                    })
                })
            })
        })
    }
    /// Ids with a vertex closer than `tau` (<= cell) to one of `ps`, sorted, deduplicated.
    fn near(&self, ps: &[[f32; 3]], tau: f32) -> Vec<u32> {
        let mut out = Vec::new();
        for p in ps {
            let p = Vec3::from(*p);
            let k = self.key(p);
            for dz in -1..=1 {
                for dy in -1..=1 {
                    for dx in -1..=1 {
                        if let Some(list) = self.map.get(&[k[0] + dx, k[1] + dy, k[2] + dz]) {
                            for &(id, q) in list {
                                if q.distance_squared(p) < tau * tau {
                                    out.push(id);
                                }
                            }
                        }
                    }
                }
            }
        }
        out.sort_unstable();
        out.dedup();
        out
    }
}

/// True for a closed (or nearly closed: under 1% boundary edges) base whose faces enclose a
/// negative volume, i.e. are wound with their normals pointing inwards.
fn wound_inwards(base: &TriMesh) -> bool {
    let mut edges: HashMap<(u32, u32), i32> = HashMap::with_capacity(3 * base.faces.len());
    for f in &base.faces {
        for k in 0..3 {
            let (a, b) = (f[k], f[(k + 1) % 3]);
            *edges.entry((a.min(b), a.max(b))).or_default() += 1;
        }
    }
    let boundary = edges.values().filter(|&&c| c == 1).count();
    if boundary * 100 > edges.len() {
        return false;
    }
    let c = base.positions.iter().map(|p| Vec3::from(*p)).sum::<Vec3>()
        / base.num_vertices().max(1) as f32;
    let volume: f64 = base
        .faces
        .iter()
        .map(|f| {
            let [a, b, d] = f.map(|v| Vec3::from(base.positions[v as usize]) - c);
            a.dot(b.cross(d)) as f64
        })
        .sum();
    volume < 0.0
}

fn validate_base(base: &TriMesh) -> Result<()> {
    if base.faces.is_empty() {
        return Err(Error::InvalidInput("base mesh has no faces".into()));
    }
    let n = base.num_vertices();
    if base.faces.iter().flatten().any(|&v| v as usize >= n) {
        return Err(Error::InvalidInput(
            "base mesh has a face with an out-of-range vertex index".into(),
        ));
    }
    if base
        .positions
        .iter()
        .any(|p| p.iter().any(|x| !x.is_finite()))
    {
        return Err(Error::InvalidInput(
            "base mesh has non-finite vertex coordinates".into(),
        ));
    }
    Ok(())
}

/// Quilt `input.swatch` over `input.base` (see the module documentation for the method).
/// Reports `Event::Progress` (stage `"quilt"`, fraction = covered base area) after every patch
/// and checks `cancel` as often. Errors: empty or invalid base, bad parameters, a field of the
/// wrong length, an output estimated above `params.max_faces` faces.
///
/// The quilt is built on the base scaled by the power of two nearest its size (exact in
/// floating point) and scaled back, so the same base in any units gets the same elements, in
/// its units.
pub fn run(
    input: &Input,
    params: &Params,
    sink: &dyn Fn(Event),
    cancel: &CancelToken,
) -> Result<QuiltOutput> {
    validate_base(input.base)?;
    let e = crate::geometry::unit_exponent(&input.base.positions);
    if e == 0 {
        return run_unit(input, params, sink, cancel);
    }
    use crate::geometry::scaled_by_power_of_two;
    let (down, up) = (2f32.powi(-e), 2f32.powi(e));
    let mut base = input.base.clone();
    base.positions = scaled_by_power_of_two(&base.positions, -e);
    let unit_params = Params {
        swatch_size: params.swatch_size.map(|l| l * down),
        thickness: params.thickness.map(|h| h * down),
        ..params.clone()
    };
    let unit_input = Input {
        base: &base,
        ..*input
    };
    let mut out = run_unit(&unit_input, &unit_params, sink, cancel)?;
    out.elements.positions = scaled_by_power_of_two(&out.elements.positions, e);
    out.stats.swatch_size *= up;
    out.stats.thickness *= up;
    Ok(out)
}

/// [`run`] on a base of about unit size.
fn run_unit(
    input: &Input,
    params: &Params,
    sink: &dyn Fn(Event),
    cancel: &CancelToken,
) -> Result<QuiltOutput> {
    let clock = Stopwatch::start();
    // a closed base wound inwards (negative enclosed volume, as the shared horse) would grow
    // its shell, and the elements, inside: quilt over the same surface wound outwards
    let outward;
    let mesh: &TriMesh = if params.outward && wound_inwards(input.base) {
        outward = TriMesh::new(
            input.base.positions.clone(),
            input
                .base
                .faces
                .iter()
                .map(|f| [f[0], f[2], f[1]])
                .collect(),
        );
        &outward
    } else {
        input.base
    };
    if input.swatch.elements.is_empty() {
        return Err(Error::InvalidInput("swatch has no elements".into()));
    }
    // the tile to repeat: the swatch's own periodicity, detected
    let found = params
        .detect_period
        .then(|| periodicity::detect(input.swatch));
    let sw: &Swatch = found.as_ref().map_or(input.swatch, |p| &p.tile);
    let swatch_measures = measure::swatch_measures(
        sw,
        found.as_ref().is_none_or(|p| p.kind != "spacing") && sw.periodic,
    );
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

    // ---- base preparation
    let n = mesh.num_vertices();
    let faces = &mesh.faces;
    let vn = vertex_normals(&mesh.positions, faces);
    let fnrm = face_normals(&mesh.positions, faces);
    let area = face_areas(&mesh.positions, faces);
    let total_area: f64 = area.iter().sum();
    let adj = vertex_adjacency(n, faces);
    let vf = vertex_faces(n, faces);
    let guard: Vec<f32> = (0..n)
        .map(|i| {
            if !params.concave_guard || h <= 0.0 {
                return 1.0;
            }
            let (pi, ni) = (Vec3::from(mesh.positions[i]), Vec3::from(vn[i]));
            let mut kappa = 0.0f32;
            for &j in adj.row(i) {
                let (pj, nj) = (
                    Vec3::from(mesh.positions[j as usize]),
                    Vec3::from(vn[j as usize]),
                );
                let (dp, dn) = (pj - pi, nj - ni);
                if dp.dot(dn) < 0.0 && dp.length() > 0.0 {
                    kappa = kappa.max(dn.length() / dp.length());
                }
            }
            if kappa > 0.0 {
                (0.9 / (kappa * h)).min(1.0)
            } else {
                1.0
            }
        })
        .collect();
    let field: Vec<Vec3> = (0..n)
        .map(|i| {
            let nv = Vec3::from(vn[i]);
            match input.field {
                Some(f) => tangent_direction(nv, Vec3::from(f[i])),
                None => {
                    let t = Vec3::X - nv * nv.x;
                    if t.length() > 0.3 {
                        t.normalize()
                    } else {
                        tangent_direction(nv, Vec3::Y)
                    }
                }
            }
        })
        .collect();
    let (mut top, _) = offset_surface(
        &mesh.positions,
        faces,
        &vn,
        h,
        Some(&guard),
        params.concave_guard,
    );
    let (stretch_before, stretch_after, shell_inverted) = if params.shell_sweeps > 0 && h > 0.0 {
        let rep = minimize_shell_stretch(
            &mesh.positions,
            faces,
            &vn,
            &mut top,
            h,
            params.shell_sweeps,
            params.seed,
        );
        (rep.before, rep.after, rep.inverted)
    } else {
        let plain = shell_stretch(&mesh.positions, &top, faces, h);
        (plain.l2, plain.l2, plain.inverted)
    };
    let base = Base {
        p: &mesh.positions,
        faces,
        vn,
        fnrm,
        area,
        adj,
        vf,
        top,
        thickness: h,
        tetrahedra: params.shell_tetrahedra,
        field,
    };

    // ---- swatch preparation
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
    let clearance = sw.clearance();
    let tau = if clearance.is_finite() {
        0.5 * clearance * s
    } else {
        0.05 * l
    }
    .max(1e-7 * l);
    let (nc, spacing) = sw.class_spacing();
    // a tile cut by spacing (no lattice: every element differs) keeps each element's own
    // spacing: two copies conflict closer than 0.9 of the mean of their nearest-neighbour
    // centre distances in the swatch (no pair of the swatch itself is closer than that), not
    // only 0.7 of the closest pair of their class
    let own_spacing: Vec<f32> = if found.as_ref().is_some_and(|p| p.kind == "spacing") {
        periodicity::nearest_spacing(sw)
    } else {
        vec![0.0; sw.num_elements()]
    };
    let conflict_dist = |a: u32, b: u32| -> f32 {
        let (ca, cb) = (sw.elements[a as usize].class, sw.elements[b as usize].class);
        let c = spacing[ca as usize * nc + cb as usize];
        let by_class = if c.is_finite() { 0.7 * c * s } else { 0.0 };
        by_class.max(0.45 * (own_spacing[a as usize] + own_spacing[b as usize]) * s)
    };
    let min_spacing = spacing.iter().cloned().fold(f32::INFINITY, f32::min);
    let nudge_spacing = |a: u32, b: u32| -> f32 {
        let c = spacing[a as usize * nc + b as usize];
        if c.is_finite() { 0.9 * c * s } else { 0.0 }
    };
    let r_elem = sw.elements.iter().map(|e| e.radius).fold(0.0f32, f32::max) * s;
    let cell = sw.extent[0].min(sw.extent[1]) / 16.0;
    let classes: Vec<u32> = sw.elements.iter().map(|e| e.class).collect();
    let images = sw.images();
    let elem_faces: Vec<Vec<[u32; 3]>> = (0..sw.elements.len())
        .map(|e| sw.element_faces(e))
        .collect();
    let mean_edge = crate::geometry::mean_edge_length(&mesh.positions, faces);

    // ---- the global lattice: the swatch tiles with period `period` (its extent when periodic,
    // else its box plus its own clearance between elements); one stripe pattern per axis,
    // one phase cycle per period
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
    let lattice: Option<[StripePattern; 2]> = if params.lattice {
        sink(Event::Progress(Progress {
            stage: "quilt: lattice",
            elapsed: clock.secs(),
            ..Default::default()
        }));
        // the default field (an axis projected) jumps where it switches axes near its poles:
        // smoothed below a swatch width, its singularities become isolated points; a given
        // field is taken as it is
        let guide: Vec<[f32; 3]> = base.field.iter().map(|d| d.to_array()).collect();
        let along = match input.field {
            Some(_) => guide,
            None => smooth_direction_field(&mesh.positions, faces, &base.vn, &guide, l as f64)
                .unwrap_or(guide),
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
                    &mesh.positions,
                    faces,
                    &along,
                    tau_f / (period[0] * s) as f64,
                )
            },
            || {
                stripe_pattern(
                    &mesh.positions,
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
    };
    let singular: Vec<bool> = match &lattice {
        Some(lat) => faces
            .iter()
            .map(|f| lat.iter().any(|p| p.singular(&mesh.positions, *f) != 0))
            .collect(),
        None => Vec::new(),
    };
    // faces within an element's reach of a singularity: elements there would straddle it, so
    // lattice patches leave them uncovered and patches seeded on them are matched instead
    let near_singular: Vec<bool> = if singular.iter().any(|&x| x) {
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
            let pv = Vec3::from(mesh.positions[v as usize]);
            for &w in base.adj.row(v as usize) {
                let nd = d + pv.distance(Vec3::from(mesh.positions[w as usize]));
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
    };
    let mut chart = LatticeChart::new(n, faces.len());
    cancel.check()?;

    let mut rng = SmallRng::seed_from_u64(params.seed);
    let nf = faces.len();
    let mut covered = vec![false; nf];
    let mut score = vec![0u32; nf];
    let mut covered_area = 0.0f64;
    let mut placed: Vec<Placed> = Vec::new();
    // (element, piece) per anchor face
    let mut anchored: Vec<Vec<(u32, u32)>> = vec![Vec::new(); nf];
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
    let mut centres = VertexHash::new(
        (4.0 * r3 + 2.0 * tau + 2.0 * nudge_reach)
            .max(max_conflict + nudge_reach)
            .max(1e-6 * l),
    );
    let mut max_radius = 0.0f32;
    let mut stats = QuiltStats {
        swatch_size: l,
        thickness: h,
        shell_stretch_before: stretch_before,
        shell_stretch: stretch_after,
        shell_inverted,
        max_distortion: 1.0,
        max_element_distortion: 1.0,
        ..Default::default()
    };
    let mut out_faces = 0usize;
    let rp_min = (0.15 * l)
        .max(if min_spacing.is_finite() {
            min_spacing * s
        } else {
            0.0
        })
        .min(params.patch_radius * l);
    let first = rng.random_range(0..nf);

    loop {
        cancel.check()?;
        // ---- seed: the uncovered face with most covered faces around its corners
        let seed = if placed.is_empty() && stats.patches == 0 {
            Some(first)
        } else {
            let mut best: Option<(u32, usize)> = None;
            for f in 0..nf {
                if !covered[f] && best.is_none_or(|b| score[f] > b.0) {
                    best = Some((score[f], f));
                }
            }
            best.map(|b| b.1)
        };
        let Some(seed) = seed else { break };
        let sc = faces[seed];
        let centroid = sc
            .iter()
            .map(|&v| Vec3::from(mesh.positions[v as usize]))
            .sum::<Vec3>()
            / 3.0;
        let n0 = Vec3::from(base.fnrm[seed]).normalize_or(Vec3::from(base.vn[sc[0] as usize]));
        let e1 = tangent_direction(n0, sc.iter().map(|&v| base.field[v as usize]).sum::<Vec3>());

        // ---- flatten: by the global lattice where it is regular and little distorted, else by
        // the exponential map, shrinking while distorted
        let mut rp = params.patch_radius * l;
        // the lattice's translation (swatch units) when the lattice flattens this patch
        let mut lattice_t: Option<Vec2> = None;
        // the disc flattened by the exponential map, out to where elements centred within `rp`
        // still land on flattened triangles
        let disc = |rp: f32| {
            exp_map(
                &mesh.positions,
                &base.vn,
                &base.adj,
                &DiscSeed {
                    face: sc,
                    point: centroid.to_array(),
                    normal: n0.to_array(),
                    e1: e1.to_array(),
                },
                rp + 2.0 * r_elem + 2.0 * mean_edge + tau,
            )
        };
        // the lattice's try computes the disc at the full radius; the fallback starts from it
        let mut first_disc = None;
        let (flat, rho) = 'flat: {
            if let Some(lat) = lattice.as_ref().filter(|_| !near_singular[seed]) {
                let em = first_disc.insert(disc(rp));
                if let Some(g) = chart.unwrap(
                    lat,
                    &singular,
                    &mesh.positions,
                    &base,
                    &em.vertices,
                    &em.dist,
                    seed as u32,
                ) {
                    // swatch coordinates: one phase cycle per period; the seed point (the
                    // seed face's centroid) at the origin of the patch
                    let k = [
                        period[0] as f64 / std::f64::consts::TAU,
                        period[1] as f64 / std::f64::consts::TAU,
                    ];
                    let c0 = g[0].1;
                    let g0 = [
                        (c0[0][0] + c0[1][0] + c0[2][0]) * k[0] / 3.0,
                        (c0[0][1] + c0[1][1] + c0[2][1]) * k[1] / 3.0,
                    ];
                    let to_uv = |q: [f64; 2]| {
                        Vec2::new(
                            ((q[0] * k[0] - g0[0]) * s as f64) as f32,
                            ((q[1] * k[1] - g0[1]) * s as f64) as f32,
                        )
                    };
                    let flat = Flat::from_faces(
                        g.into_iter().map(|(f, c)| (f, c.map(to_uv))).collect(),
                        true,
                    );
                    let near = |f: u32| chart.within(&base, f, LATTICE_NEAR * rp);
                    let (_, rho, scale) = flat.distortion_and_scale(&base, rp, near);
                    // the share of the disc's area distorted beyond the limit (folded faces
                    // included): elements on those faces are dropped one by one below, so a
                    // few slivers need not cost the patch its lattice
                    let (mut bad, mut all, mut worst) = (0.0f64, 0.0f64, 1.0f32);
                    for ((f, t), &q) in flat.faces.iter().zip(&rho) {
                        if t.iter().all(|p| p.length() <= rp) && near(*f) {
                            let a = base.area[*f as usize];
                            all += a;
                            if q > params.max_distortion {
                                bad += a;
                            } else {
                                worst = worst.max(q);
                            }
                        }
                    }
                    let win = params.lattice_scale.max(1.0) as f64;
                    if all > 0.0
                        && bad <= LATTICE_BAD_AREA * all
                        && (1.0 / win..=win).contains(&scale)
                    {
                        stats.max_distortion = stats.max_distortion.max(worst);
                        stats.lattice_patches += 1;
                        lattice_t = Some(Vec2::new(
                            -(g0[0].rem_euclid(period[0] as f64)) as f32,
                            -(g0[1].rem_euclid(period[1] as f64)) as f32,
                        ));
                        break 'flat (flat, rho);
                    }
                }
            }
            loop {
                let em = first_disc.take().unwrap_or_else(|| disc(rp));
                let flat = Flat::new(&base, &em.vertices, &em.uv);
                let (d, rho) = flat.distortion(&base, rp);
                if d <= params.max_distortion || rp <= rp_min * 1.0001 {
                    if d.is_finite() {
                        stats.max_distortion = stats.max_distortion.max(d);
                    }
                    break (flat, rho);
                }
                stats.shrunk_patches += 1;
                rp = (rp * 0.75).max(rp_min);
            }
        };

        // ---- old elements in the patch, in swatch coordinates
        let corners = |f: u32| faces[f as usize].map(|v| Vec3::from(mesh.positions[v as usize]));
        let mut old: Vec<(u32, Vec2)> = Vec::new();
        let mut turn = Vec2::ZERO;
        for (f, t) in &flat.faces {
            for &(e, k) in &anchored[*f as usize] {
                let pe = &placed[e as usize];
                if !pe.alive {
                    continue;
                }
                let piece = &pe.pieces[k as usize];
                let b = piece.anchor.1;
                let uv = t[0] * b[0] + t[1] * b[1] + t[2] * b[2];
                old.push((e, uv));
                turn += dir_to_uv(t, corners(*f), piece.dir).normalize_or_zero();
            }
        }
        // orientation: continue the neighbours' lattice (circular mean of their +x axes in
        // the patch frame) when they agree, else the field at the seed (+u)
        let rot = if lattice_t.is_some() {
            Vec2::X // the lattice's chart is already oriented
        } else if params.follow_neighbours && turn.length() > 0.5 * old.len() as f32 {
            turn.normalize()
        } else {
            Vec2::X
        };
        let inv = Vec2::new(rot.x, -rot.y);
        for o in &mut old {
            o.1 = inv.rotate(o.1) / s;
        }

        // ---- matching: the translation t (swatch units) with uv = s (x + t)
        let t = match lattice_t {
            Some(t) => t,
            None => {
                choose_translation(sw, &classes, &images, &placed, &old, cell, rp / s, &mut rng)
            }
        };

        // ---- candidates
        // swatch element `e` shifted by `shift` (swatch units), mapped into the shell
        let map_element = |e: usize, shift: Vec2, stats: &mut QuiltStats| -> Option<Candidate> {
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
        };
        let mut cands: Vec<Candidate> = Vec::new();
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
                    if let Some(cand) = map_element(e, t + off, &mut stats) {
                        cands.push(cand);
                    }
                }
            }
        }

        // ---- conflicts between old and new, then the cut: every alive element whose centre
        // is near a candidate's (3D hash), not only those anchored in the disc
        let mut near_old: Vec<u32> = Vec::new();
        for c in &cands {
            near_old.extend(
                centres
                    .near(
                        &[c.centre.to_array()],
                        (c.radius + max_radius + tau + nudge_reach)
                            .max(max_conflict + nudge_reach)
                            .min(centres.cell),
                    )
                    .into_iter()
                    .filter(|&e| placed[e as usize].alive),
            );
        }
        near_old.sort_unstable();
        near_old.dedup();
        let old: Vec<(u32, ())> = near_old.into_iter().map(|e| (e, ())).collect();
        let mut hash = VertexHash::new(tau);
        for (k, (e, _)) in old.iter().enumerate() {
            hash.insert(k as u32, &placed[*e as usize].positions);
        }
        let mut conflicts: Vec<(usize, usize)> = Vec::new();
        // per candidate: the old element it joins (index into `old`) when it survives, and the
        // merged element as computed against that old one's present geometry
        let mut partner: Vec<Option<(usize, merging::Merged)>> = vec![None; cands.len()];
        for (j, c) in cands.iter().enumerate() {
            let cl = sw.elements[c.source as usize].class;
            let mut near = hash.near(&c.positions, tau);
            for (k, (e, _)) in old.iter().enumerate() {
                let pe = &placed[*e as usize];
                let d = pe.centre_distance(c.centre);
                if d < conflict_dist(pe.source, c.source)
                    || (d < 2.0 * (c.radius + max_radius)
                        && crossing::surfaces_cross(
                            &pe.positions,
                            pe.faces(&elem_faces),
                            &c.positions,
                            &elem_faces[c.source as usize],
                        ))
                {
                    near.push(k as u32);
                }
            }
            near.sort_unstable();
            near.dedup();
            // the first same-class old element it can merge with is no conflict (§2.7)
            if params.merge_elements && elongated[c.source as usize] {
                partner[j] = near.iter().map(|&k| k as usize).find_map(|k| {
                    let pe = &placed[old[k].0 as usize];
                    if sw.elements[pe.source as usize].class != cl || !elongated[pe.source as usize]
                    {
                        return None;
                    }
                    merging::merge(
                        &pe.geometry(&elem_faces),
                        &c.geometry(&elem_faces),
                        merge_delta,
                    )
                    .map(|m| (k, m))
                });
            }
            let joins = partner[j].as_ref().map(|p| p.0);
            conflicts.extend(
                near.into_iter()
                    .map(|k| k as usize)
                    .filter(|&k| joins != Some(k))
                    .map(|k| (k, j)),
            );
        }
        let (keep_old, keep_new) =
            maxflow::keep_by_cut(&vec![1.1; old.len()], &vec![1.0; cands.len()], &conflicts);
        for (k, (e, _)) in old.iter().enumerate() {
            if !keep_old[k] {
                let pe = &mut placed[*e as usize];
                pe.alive = false;
                out_faces -= pe.faces(&elem_faces).len();
                stats.replaced_old += 1;
            }
        }
        // greedy: new elements conflicting with each other, nearest to the seed first
        let mut order: Vec<usize> = (0..cands.len()).filter(|&j| keep_new[j]).collect();
        stats.dropped_conflict += cands.len() - order.len();
        // dropped candidates, tried again nudged (below)
        let mut retry: Vec<usize> = (0..cands.len()).filter(|&j| !keep_new[j]).collect();
        order.sort_by(|&a, &b| {
            cands[a]
                .seed_dist
                .total_cmp(&cands[b].seed_dist)
                .then(a.cmp(&b))
        });
        let mut accepted_hash = VertexHash::new(tau);
        let mut accepted: Vec<usize> = Vec::new();
        // candidates merged into an old element (accepted, but not placed on their own), and
        // old elements grown by a merge in this patch (their cached merges are stale)
        let mut merged_now = vec![false; cands.len()];
        let mut grown = vec![false; old.len()];
        for j in order {
            let c = &cands[j];
            let clash = accepted_hash.any_near(&c.positions, tau, |_| true)
                || accepted.iter().any(|&a| {
                    let o = &cands[a];
                    let d = o.centre.distance(c.centre);
                    d < conflict_dist(o.source, c.source).min(0.9 * (o.radius + c.radius))
                        || (d < 2.0 * (o.radius + c.radius)
                            && crossing::surfaces_cross(
                                &o.positions,
                                &elem_faces[o.source as usize],
                                &c.positions,
                                &elem_faces[c.source as usize],
                            ))
                });
            if clash {
                stats.dropped_conflict += 1;
                retry.push(j);
                continue;
            }
            // a candidate joining a surviving old element: merge now (the old one may have
            // grown by an earlier merge of this patch); a failed merge drops it
            if let Some((k, cached)) = partner[j].take()
                && keep_old[k]
            {
                let e = old[k].0 as usize;
                let merged = if grown[k] {
                    merging::merge(
                        &placed[e].geometry(&elem_faces),
                        &c.geometry(&elem_faces),
                        merge_delta,
                    )
                } else {
                    Some(cached)
                };
                // the merged element moved half-way: it must still keep clear of the other
                // old elements and of this patch's accepted ones
                let clear = |m: &merging::Merged| {
                    let (mc, _) = centre_and_radius(&m.positions);
                    let reach = 2.0 * (c.radius + max_radius) + mc.distance(c.centre);
                    let old_ok = hash
                        .near(&m.positions, tau)
                        .into_iter()
                        .all(|k2| k2 as usize == k || !keep_old[k2 as usize])
                        && old.iter().enumerate().all(|(k2, (e2, _))| {
                            let o = &placed[*e2 as usize];
                            k2 == k
                                || !keep_old[k2]
                                || o.centre_distance(c.centre) >= reach
                                || !crossing::surfaces_cross(
                                    &o.positions,
                                    o.faces(&elem_faces),
                                    &m.positions,
                                    &m.faces,
                                )
                        });
                    let new_ok = accepted_hash.near(&m.positions, tau).is_empty()
                        && accepted.iter().all(|&a| {
                            let o = &cands[a];
                            o.centre.distance(c.centre) >= reach
                                || !crossing::surfaces_cross(
                                    &o.positions,
                                    &elem_faces[o.source as usize],
                                    &m.positions,
                                    &m.faces,
                                )
                        });
                    old_ok && new_ok
                };
                let Some(m) = merged.filter(clear) else {
                    stats.dropped_conflict += 1;
                    continue;
                };
                accepted_hash.insert(accepted.len() as u32, &c.positions);
                accepted.push(j);
                let pe = &mut placed[e];
                out_faces -= pe.faces(&elem_faces).len();
                out_faces += m.faces.len();
                pe.positions = m.positions;
                pe.faces = Some(m.faces);
                anchored[c.anchor.0 as usize].push((e as u32, pe.pieces.len() as u32));
                centres.insert(e as u32, &[c.centre.to_array()]);
                pe.pieces.push(Piece {
                    centre: c.centre,
                    anchor: c.anchor,
                    dir: c.dir,
                });
                merged_now[j] = true;
                grown[k] = true;
                stats.merged += 1;
                continue;
            }
            accepted_hash.insert(accepted.len() as u32, &c.positions);
            accepted.push(j);
        }
        // ---- nudge: a dropped candidate moved by a fraction of its class's spacing (eight
        // directions, two distances) into a gap that the lattices of neighbouring patches left
        // between their elements, kept whole, where it clears everything
        if params.nudge {
            retry.sort_by(|&a, &b| {
                cands[a]
                    .seed_dist
                    .total_cmp(&cands[b].seed_dist)
                    .then(a.cmp(&b))
            });
            // counters of the tries that fail stay out of the run's
            let mut scratch = QuiltStats::default();
            for j in retry {
                let (src, shift0) = (cands[j].source as usize, cands[j].shift);
                if !elongated[src] {
                    continue;
                }
                let cl = sw.elements[src].class;
                let sp = spacing[cl as usize * nc + cl as usize];
                let sp = if sp.is_finite() { sp } else { min_spacing };
                if !sp.is_finite() {
                    continue;
                }
                // a spot already held by a copy of the same class needs no second one
                let c0 = cands[j].centre;
                let held = |o_cl: u32, d: f32| o_cl == cl && d < 0.35 * sp * s;
                let occupied = old.iter().enumerate().any(|(k2, (e2, _))| {
                    let o = &placed[*e2 as usize];
                    keep_old[k2]
                        && held(sw.elements[o.source as usize].class, o.centre_distance(c0))
                }) || accepted.iter().any(|&a| {
                    held(
                        sw.elements[cands[a].source as usize].class,
                        cands[a].centre.distance(c0),
                    )
                });
                if occupied {
                    continue;
                }
                let mut found = None;
                'tries: for m in [0.25f32, 0.5] {
                    for k in 0..8 {
                        let a = std::f32::consts::FRAC_PI_4 * k as f32;
                        let d = Vec2::new(a.cos(), a.sin()) * (m * sp);
                        scratch.max_element_distortion = 1.0;
                        let Some(c) = map_element(src, shift0 + d, &mut scratch) else {
                            continue;
                        };
                        if (c.centre.distance(cands[j].centre)) > nudge_reach + tau {
                            continue; // the flattening folds here
                        }
                        // cheap tests first: vertices within tau, centres too close
                        if hash.any_near(&c.positions, tau, |k2| keep_old[k2 as usize])
                            || accepted_hash.any_near(&c.positions, tau, |_| true)
                        {
                            continue;
                        }
                        // a nudged copy keeps the swatch's own spacing (nearly), so that
                        // the fill never packs elements denser than the swatch
                        let too_close_old = old.iter().enumerate().any(|(k2, (e2, _))| {
                            let o = &placed[*e2 as usize];
                            keep_old[k2]
                                && o.centre_distance(c.centre)
                                    < nudge_spacing(sw.elements[o.source as usize].class, cl)
                        });
                        let too_close_new = accepted.iter().any(|&a| {
                            let o = &cands[a];
                            o.centre.distance(c.centre)
                                < nudge_spacing(sw.elements[o.source as usize].class, cl)
                        });
                        if too_close_old || too_close_new {
                            continue;
                        }
                        let cross_old = old.iter().enumerate().any(|(k2, (e2, _))| {
                            let o = &placed[*e2 as usize];
                            keep_old[k2]
                                && o.centre_distance(c.centre) < 2.0 * (c.radius + max_radius)
                                && crossing::surfaces_cross(
                                    &o.positions,
                                    o.faces(&elem_faces),
                                    &c.positions,
                                    &elem_faces[src],
                                )
                        });
                        let cross_new = !cross_old
                            && accepted.iter().any(|&a| {
                                let o = &cands[a];
                                o.centre.distance(c.centre) < 2.0 * (o.radius + c.radius)
                                    && crossing::surfaces_cross(
                                        &o.positions,
                                        &elem_faces[o.source as usize],
                                        &c.positions,
                                        &elem_faces[src],
                                    )
                            });
                        if !cross_old && !cross_new {
                            found = Some(c);
                            break 'tries;
                        }
                    }
                }
                if let Some(c) = found {
                    stats.max_element_distortion = stats
                        .max_element_distortion
                        .max(scratch.max_element_distortion);
                    accepted_hash.insert(accepted.len() as u32, &c.positions);
                    cands[j] = c;
                    accepted.push(j);
                    stats.dropped_conflict -= 1;
                    stats.nudged += 1;
                }
            }
        }
        for j in accepted {
            if merged_now[j] {
                continue;
            }
            let c = std::mem::replace(
                &mut cands[j],
                Candidate {
                    source: 0,
                    positions: Vec::new(),
                    centre: Vec3::ZERO,
                    radius: 0.0,
                    anchor: (0, [0.0; 3]),
                    dir: Vec3::ZERO,
                    seed_dist: 0.0,
                    shift: Vec2::ZERO,
                },
            );
            out_faces += sw.elements[c.source as usize].faces.len();
            anchored[c.anchor.0 as usize].push((placed.len() as u32, 0));
            centres.insert(placed.len() as u32, &[c.centre.to_array()]);
            max_radius = max_radius.max(c.radius);
            placed.push(Placed {
                source: c.source,
                positions: c.positions,
                faces: None,
                pieces: vec![Piece {
                    centre: c.centre,
                    anchor: c.anchor,
                    dir: c.dir,
                }],
                alive: true,
            });
        }
        if out_faces > params.max_faces {
            return Err(Error::InvalidInput(format!(
                "the quilt exceeded the limit of {} faces; use a larger swatch size",
                params.max_faces
            )));
        }

        // ---- coverage
        let mut mark = |f: usize, covered: &mut Vec<bool>, score: &mut Vec<u32>| {
            if covered[f] {
                return;
            }
            covered[f] = true;
            covered_area += base.area[f];
            for &v in &faces[f] {
                for &g in base.vf.row(v as usize) {
                    score[g as usize] += 1;
                }
            }
        };
        mark(seed, &mut covered, &mut score);
        for (f, tri) in &flat.faces {
            if tri.iter().all(|q| q.length() <= rp)
                && (lattice_t.is_none()
                    || (chart.within(&base, *f, LATTICE_NEAR * rp) && !near_singular[*f as usize]))
            {
                mark(*f as usize, &mut covered, &mut score);
            }
        }
        stats.patches += 1;
        let fraction = if total_area > 0.0 {
            (covered_area / total_area) as f32
        } else {
            1.0
        };
        stats.covered_fraction = fraction;
        sink(Event::Progress(Progress {
            stage: "quilt",
            iteration: stats.patches,
            elapsed: clock.secs(),
            fraction,
            ..Default::default()
        }));
    }

    // ---- output
    let mut positions = Vec::new();
    let mut out_f = Vec::new();
    let mut element_id = Vec::new();
    let mut element_source = Vec::new();
    let mut element_pieces = Vec::new();
    // Shell guard: an element mapped through a strongly distorted or extrapolated patch (thin
    // parts such as ears, legs and a giraffe's horns) can be flung away from the surface; keep
    // only elements whose every vertex lies within the shell, at most 1.5 H (plus a twentieth
    // of the swatch width for the base's chordal error) from the base.
    let bvh = TriangleBvh::new(input.base.positions.as_slice(), faces);
    let limit = 1.5 * stats.thickness + 0.05 * stats.swatch_size;
    let inside = |pe: &&Placed| {
        pe.positions
            .iter()
            .all(|q| bvh.closest_point(*q).is_some_and(|(_, _, d)| d <= limit))
    };
    let before = placed.iter().filter(|p| p.alive).count();
    let kept: Vec<&Placed> = placed.iter().filter(|p| p.alive).filter(inside).collect();
    stats.dropped_outside_shell = before - kept.len();
    for pe in kept {
        let id = element_source.len() as u32;
        let v0 = positions.len() as u32;
        positions.extend_from_slice(&pe.positions);
        element_id.extend(std::iter::repeat_n(id, pe.positions.len()));
        out_f.extend(pe.faces(&elem_faces).iter().map(|f| f.map(|v| v + v0)));
        element_source.push(pe.source);
        element_pieces.push(pe.pieces.len() as u32);
    }
    stats.elements = element_source.len();
    let mut out = QuiltOutput {
        elements: TriMesh::new(positions, out_f),
        element_id,
        element_source,
        element_pieces,
        stats,
    };
    if let Some(p) = &found {
        for src in &mut out.element_source {
            *src = p.source[*src as usize];
        }
    }
    cancel.check()?;
    let m = measure::quilt_measures(&out, mesh, &swatch_measures, s, l);
    let st = &mut out.stats;
    st.periodicity = found
        .as_ref()
        .map_or(if sw.periodic { "periodic" } else { "box" }, |p| p.kind)
        .to_string();
    st.lattice_vectors = found.as_ref().and_then(|p| p.lattice);
    st.tile_elements = sw.num_elements();
    st.density_ratio = m.density_ratio;
    st.density_ratio_convex = m.density_ratio_convex;
    st.density_ratio_saddle = m.density_ratio_saddle;
    st.link_share = m.link_share;
    st.swatch_links_per_element = swatch_measures.links_per_element;
    st.links_per_element = m.links_per_element;
    st.coverage = m.coverage;
    st.seconds = clock.secs();
    sink(Event::StageTime("quilt", st.seconds));
    Ok(out)
}

/// Eq. (1)-(3) at the element level: the swatch translation (swatch units) that best explains
/// the old elements `old` (id, position in swatch coordinates of the patch frame).
#[allow(clippy::too_many_arguments)]
fn choose_translation(
    sw: &Swatch,
    classes: &[u32],
    images: &[[f32; 2]],
    placed: &[Placed],
    old: &[(u32, Vec2)],
    cell: f32,
    rs: f32,
    rng: &mut SmallRng,
) -> Vec2 {
    let (ex, ey) = (sw.extent[0], sw.extent[1]);
    // translations: t with the seed at swatch point -t
    let range = |e: f32| -> (f32, f32) {
        if sw.periodic {
            (0.0, e)
        } else if e > 2.0 * rs {
            (-(e - rs), -rs)
        } else {
            (-e / 2.0, -e / 2.0)
        }
    };
    let (rx, ry) = (range(ex), range(ey));
    if old.is_empty() {
        return Vec2::new(
            if rx.1 > rx.0 {
                rng.random_range(rx.0..rx.1)
            } else {
                rx.0
            },
            if ry.1 > ry.0 {
                rng.random_range(ry.0..ry.1)
            } else {
                ry.0
            },
        );
    }
    let cost = |t: Vec2, x: Vec2, cl: u32| -> (f32, Vec2) {
        // (cost, residual to the nearest same-class centre)
        let mut best = 4.0f32;
        let mut res = Vec2::splat(f32::INFINITY);
        for (j, el) in sw.elements.iter().enumerate() {
            let c = Vec2::new(el.centre[0], el.centre[1]) + t;
            for im in images {
                let mut d = x - c - Vec2::from(*im);
                if sw.periodic {
                    d.x -= (d.x / ex).round() * ex;
                    d.y -= (d.y / ey).round() * ey;
                }
                let penalty = if classes[j] == cl { 0.0 } else { 1.0 };
                let e = d.length() / cell + penalty;
                if e < best {
                    best = e;
                    if penalty == 0.0 {
                        res = d;
                    }
                }
                if sw.periodic {
                    break; // wrapped distance already covers the images
                }
            }
        }
        (best, res)
    };
    let steps = |r: (f32, f32)| -> Vec<f32> {
        if r.1 <= r.0 {
            return vec![r.0];
        }
        let k = ((r.1 - r.0) / cell).ceil() as usize;
        (0..k.max(1)).map(|i| r.0 + i as f32 * cell).collect()
    };
    let mut best = (f32::INFINITY, Vec2::ZERO);
    for &ty in &steps(ry) {
        for &tx in &steps(rx) {
            let t = Vec2::new(tx, ty);
            let mut e = 0.0;
            for (id, x) in old {
                let cl = sw.elements[placed[*id as usize].source as usize].class;
                e += cost(t, *x, cl).0;
                if e >= best.0 {
                    break;
                }
            }
            if e < best.0 {
                best = (e, t);
            }
        }
    }
    // continuous refinement by the mean residual of matched same-class pairs
    let mut t = best.1;
    for _ in 0..2 {
        let mut acc = Vec2::ZERO;
        let mut k = 0;
        for (id, x) in old {
            let cl = sw.elements[placed[*id as usize].source as usize].class;
            let (_, r) = cost(t, *x, cl);
            if r.length() < cell {
                acc += r;
                k += 1;
            }
        }
        if k == 0 {
            break;
        }
        t += acc / k as f32;
    }
    t
}

/// Ratio of the two largest principal standard deviations of the points (1 for a ring or a
/// stud, large for a thread; an upright ring, flat in x-y, is still about 1.7).
fn principal_aspect(ps: &[[f32; 3]]) -> f32 {
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
