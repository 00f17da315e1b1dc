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
//!    diagonal), `s = L / l_in`; shell thickness `H` (default `s h_in`). A base with edges
//!    longer than a patch's radius (the slivers of a CAD cone or cylinder, spanning its whole
//!    height) is first split on the same surface by longest-edge bisection until none is
//!    ([`crate::geometry::refine_to_edge_length`]): every face under a patch would otherwise
//!    hold elements from all along the surface, and each patch would read them all.
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
//!
//!    **Fill** (not in the paper; `fill`, on by default): once the base is covered, each gap
//!    wider than the swatch's own largest gets the first copy of a tile element, registered
//!    with its neighbours or moved by up to half the tile's spacing, that clears every
//!    element ([`fill`]). Measured with `examples/quilt_finite` (a tenth of the diagonal): the
//!    ring patch on the horse from 0.71 to 0.88 of the swatch's density, coverage 0.85 to 0.94.
//!
//!    **Trim** (§2.7's cut, for threads; `trim`, on by default): a thread the cut drops, a copy
//!    of one that tears off the patch's chart, or one that no whole copy fits in a gap keeps
//!    its longest clear run along its axis (at least a quarter of it), cut across and capped
//!    ([`trim`]); a run must cross no element and lie no closer to its neighbours than the
//!    thread does in the swatch. Whole elements stay the rule; compact elements are never
//!    cut. Measured with `examples/quilt_finite` (a tenth of the diagonal): the finite weave's
//!    density on the horse 0.63 -> 0.86 of the swatch's, coverage 0.81 -> 0.99; on the bunny
//!    0.83 -> 0.88 and 0.94 -> 0.99.
//!
//!    **Relink** (not in the paper; `relink`, on by default): once the gaps are filled, an
//!    element with fewer links than its tile element has in the swatch (a ring ending a chain
//!    at a seam) gets each missing partner where that adds links: a copy laid through it on the
//!    tile's lattice (turned by up to 20 degrees, moved by up to 0.3 of the partner's
//!    distance), placed when it links the element, crosses nothing and makes more links than
//!    the at most one element it replaces ([`relink`]). Measured with `examples/quilt_finite`
//!    (a tenth of the diagonal): the ring patch on the horse from 65% to 81% of the swatch's
//!    links, coverage 0.943 to 0.962; on the bunny 84% to 92%.
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
//! Where the steps live: [`run`] chains them, one file each: `setup.rs` (1, and the tile's
//! distances the later steps compare against), `shell.rs` (5's shell, built first),
//! `lattice.rs` (2's global lattice), `seed.rs` and `flatten.rs` (2, on `flat.rs`'s point
//! location), `matching.rs` (3), `candidates.rs` (4's candidates through 5's shell map),
//! `cut.rs` (4's conflicts, cut and greedy pass), `join.rs` (a merge at a seam, through
//! [`merging`]), `nudge.rs`, `fill.rs`, `trim.rs`, `relink.rs`, and `output.rs` (the shell
//! guard and the measures).
//!
//! Output: all kept elements merged in one [`TriMesh`], with a per-vertex element id and a
//! per-element source (swatch element index). Planar quilting is the same code on a flat base
//! ([`plane`]).
//!
//! Measured (release, 2 shared cores): chain mail on the Stanford bunny (6598 faces) at the
//! default scale: 464 patches, about 5070 elements, 0.97 M faces, about 7 s; a periodic swatch
//! on a plane is reproduced exactly (rigid copies on one lattice).

mod candidates;
mod crossing;
mod cut;
mod elements;
mod fill;
mod finite_patch;
mod flat;
mod flatten;
mod io;
mod join;
mod lattice;
pub mod links;
mod matching;
pub mod maxflow;
pub mod measure;
pub mod merging;
mod nudge;
mod output;
pub mod periodicity;
mod relink;
mod seed;
mod setup;
mod shell;
mod swatch;
mod trim;

pub use crossing::crossing_pairs;
pub use finite_patch::{PatchKind, finite_patch};
pub use io::{save_quilt_obj, save_quilt_ply};
pub use swatch::{Axis, Element, Swatch, SwatchKind, load_swatch, swatch};

use std::collections::HashMap;

use glam::Vec3;
use rand::{Rng, SeedableRng, rngs::SmallRng};

use crate::error::{Error, Result};
use crate::mesh::TriMesh;
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
    /// Once every face is covered by a patch, visit the gaps wider than the swatch's own
    /// largest gap (seams where the cut dropped clashing copies) and place there the first
    /// copy of a tile element, registered with its neighbours or moved by up to half the
    /// tile's spacing, that clears every element ([`fill`]).
    pub fill: bool,
    /// Keep the clear part of a thread that no whole copy fits (the cut dropped it, or a gap
    /// is too small for it): cut across the thread and capped, at least a third of its
    /// length ([`trim`]; the paper's cut, §2.7). Compact elements are never cut.
    pub trim: bool,
    /// Once the gaps are filled, give each element with fewer links than its tile element has
    /// in the swatch (a chain broken at a seam) its missing partners where that adds links:
    /// a partner copy placed at the swatch's offset from it, replacing at most one element it
    /// clashes with, and only when it makes more links than that element had ([`relink`]).
    pub relink: bool,
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
            fill: true,
            trim: true,
            relink: true,
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
    /// Elements placed in gaps after the patches ([`Params::fill`]).
    pub filled: usize,
    /// Threads cut short to fit where no whole copy fits ([`Params::trim`]), after a patch's
    /// cut or in a gap (then also counted in `filled`).
    pub trimmed: usize,
    /// Partners placed where a chain was broken ([`Params::relink`]); each replaced at most one
    /// element (counted in `replaced_old`).
    pub relinked: usize,
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
    /// Links per element among the swatch's own elements as modelled, without copies (lower
    /// than [`QuiltStats::swatch_links_per_element`] for a finite patch, whose border elements
    /// have fewer partners).
    pub modelled_links_per_element: f32,
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
    /// The share of its swatch element each output element holds: 1 for a whole copy, less
    /// for a thread cut short to fit a gap ([`trim`]); densities count elements by it.
    pub element_share: Vec<f32>,
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
                "{:.0}% of the swatch's links ({:.2} per element; the swatch {:.2} on its \
                 lattice, {:.2} as modelled)",
                100.0 * x,
                self.links_per_element,
                self.swatch_links_per_element,
                self.modelled_links_per_element
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
    TriMesh::new(positions, crate::testdata::grid_faces(n, n))
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
    TriMesh::new(pos, crate::testdata::grid_faces(nx, ny))
}

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
/// [`run`] on a base of about unit size: the steps of the module documentation, in order.
fn run_unit(
    input: &Input,
    params: &Params,
    sink: &dyn Fn(Event),
    cancel: &CancelToken,
) -> Result<QuiltOutput> {
    let clock = Stopwatch::start();
    // a closed base wound inwards (negative enclosed volume, as the shared horse) would grow
    // its shell, and the elements, inside: quilt over the same surface wound outwards
    let outward = (params.outward && wound_inwards(input.base)).then(|| flipped(input.base));
    let mesh = outward.as_ref().unwrap_or(input.base);
    if input.swatch.elements.is_empty() {
        return Err(Error::InvalidInput("swatch has no elements".into()));
    }
    // 0. the tile to repeat: the swatch's own periodicity, detected
    let found = params
        .detect_period
        .then(|| periodicity::detect(input.swatch));
    let sw: &Swatch = found.as_ref().map_or(input.swatch, |p| &p.tile);
    let swatch_measures = measure::swatch_measures(
        sw,
        found.as_ref().is_none_or(|p| p.kind != "spacing") && sw.periodic,
    );
    // 1. the scale, and the shell it sets (5)
    let size = setup::size(input, mesh, sw, params)?;
    // faces longer than a patch (a CAD cone's or cylinder's slivers, spanning its height) put
    // every patch over hundreds of faces and every element's anchor search through them:
    // split, on the same surface, until no edge is longer than the patch radius
    let fine = split_long_faces(mesh, input.field, params.patch_radius * size.l);
    let (mesh, field) = match &fine {
        Some((m, f)) => (m, f.as_deref()),
        None => (mesh, input.field),
    };
    let (base, shell) = shell::build(mesh, field, params, size.h);
    setup::check_output_size(sw, base.area.iter().sum(), size.s, params)?;
    let setup = setup::Setup::new(params, sw, found.as_ref(), size, mesh);
    // 2. the global lattice
    let mut lattice = lattice::Lattice::solve(&setup, &base, field.is_some(), sink, &clock);
    cancel.check()?;

    let axes = trim::Axes::new(&setup);
    let mut rng = SmallRng::seed_from_u64(params.seed);
    let mut coverage = seed::Coverage::new(&base);
    let mut elements = elements::Placement::new(base.faces.len(), setup.centre_cell);
    let mut stats = QuiltStats {
        swatch_size: size.l,
        thickness: size.h,
        shell_stretch_before: shell.before,
        shell_stretch: shell.after,
        shell_inverted: shell.inverted,
        max_distortion: 1.0,
        max_element_distortion: 1.0,
        ..Default::default()
    };
    let first = rng.random_range(0..base.faces.len());
    loop {
        cancel.check()?;
        // 2. the patch: seed, flatten
        let first_patch = elements.placed.is_empty() && stats.patches == 0;
        let Some(seed) = coverage.next_seed(first_patch.then_some(first)) else {
            break;
        };
        let patch = cover_patch(
            (&setup, &base, &axes),
            &mut lattice,
            &mut elements,
            seed,
            &mut rng,
            &mut stats,
        )?;
        // the patch's disc is covered
        stats.covered_fraction = coverage.cover(&base, &patch, &lattice);
        stats.patches += 1;
        sink(Event::Progress(Progress {
            stage: "quilt",
            iteration: stats.patches,
            elapsed: clock.secs(),
            fraction: stats.covered_fraction,
            ..Default::default()
        }));
    }

    // the gaps the seams left
    if params.fill {
        let reach = swatch_measures.largest_gap * size.s;
        let (filled, trimmed) = fill::fill(
            &setup,
            &base,
            &mut lattice,
            &mut elements,
            &axes,
            reach,
            stats.patches,
            &mut rng,
            (sink, &clock, cancel),
        )?;
        stats.filled = filled;
        stats.trimmed += trimmed;
    }

    // chains broken at seams
    if params.relink {
        let guard = output::ShellGuard::new(&mesh.positions, base.faces, &stats);
        let (placed, removed) = relink::relink(
            &setup,
            &base,
            &mut elements,
            &guard,
            stats.patches,
            (sink, &clock, cancel),
        )?;
        stats.relinked = placed;
        stats.replaced_old += removed;
    }

    // the output: the shell guard, then the arrangement measured
    let mut out = output::assemble(
        &elements,
        &setup.elem_faces,
        &mesh.positions,
        base.faces,
        stats,
        found.as_ref(),
    );
    cancel.check()?;
    output::measure(
        &mut out,
        mesh,
        sw,
        found.as_ref(),
        &swatch_measures,
        (size.s, size.l),
    );
    out.stats.modelled_links_per_element = measure::modelled_links_per_element(input.swatch);
    out.stats.seconds = clock.secs();
    sink(Event::StageTime("quilt", out.stats.seconds));
    Ok(out)
}

/// Steps 2-4 for one patch seeded at face `seed`: flattened, registered, its candidates cut
/// against the elements placed, nudged, placed, and its dropped threads cut short.
fn cover_patch(
    (setup, base, axes): (&setup::Setup, &shell::Base, &trim::Axes),
    lattice: &mut lattice::Lattice,
    elements: &mut elements::Placement,
    seed: usize,
    rng: &mut SmallRng,
    stats: &mut QuiltStats,
) -> Result<flatten::Patch> {
    let (params, sw, size_l) = (setup.params, setup.sw, setup.l);
    let rp = params.patch_radius * size_l;
    let patch = flatten::flatten(setup, base, lattice, seed, rp, stats);
    // 3. matching
    let (rot, t) = matching::register(setup, base, &patch, elements, rng);
    // 4. candidates, the cut (with merging), nudge
    let mapper = candidates::Mapper {
        setup,
        base,
        patch: &patch,
        rot,
    };
    let (mut cands, unmapped) = candidates::candidates(&mapper, t, &setup.elongated, stats);
    let mut selection = cut::select(setup, elements, &cands, stats);
    if params.nudge {
        nudge::nudge(&mapper, elements, &mut selection, &mut cands, stats);
    }
    // threads the cut dropped, or that did not map whole, keep their clear part
    let dropped: Vec<usize> = if params.trim && axes.any() {
        let mut taken = vec![false; cands.len()];
        for &j in &selection.accepted {
            taken[j] = true;
        }
        (0..cands.len()).filter(|&j| !taken[j]).collect()
    } else {
        Vec::new()
    };
    elements.place(&mut cands, &selection, sw, params.max_faces)?;
    if params.trim && axes.any() {
        stats.trimmed += trim::after_cut(axes, &mapper, elements, &cands, dropped, unmapped);
    }
    Ok(patch)
}

/// Most vertices [`split_long_faces`] adds to a base.
const MAX_SPLIT_VERTICES: usize = 400_000;

/// `mesh` with every edge longer than `max_length` bisected (the same surface), and the
/// orientation field carried to the new vertices (the normalised mean of the split edge's
/// ends'); `None` when no edge is that long.
fn split_long_faces(
    mesh: &TriMesh,
    field: Option<&[[f32; 3]]>,
    max_length: f32,
) -> Option<(TriMesh, Option<Vec<[f32; 3]>>)> {
    let r = crate::geometry::refine_to_edge_length(
        &TriMesh::new(mesh.positions.clone(), mesh.faces.clone()),
        max_length,
        mesh.positions.len() + MAX_SPLIT_VERTICES,
    );
    if r.mesh.positions.len() == mesh.positions.len() {
        return None;
    }
    let field = field.map(|f| {
        let mut out: Vec<[f32; 3]> = f.to_vec();
        for &[a, b] in &r.parent_map[f.len()..] {
            let (fa, fb) = (
                glam::Vec3::from(out[a as usize]),
                glam::Vec3::from(out[b as usize]),
            );
            let m = (fa + fb).normalize_or_zero();
            out.push(if m == glam::Vec3::ZERO { fa } else { m }.into());
        }
        out
    });
    Some((r.mesh, field))
}

/// The same surface wound the other way.
fn flipped(base: &TriMesh) -> TriMesh {
    TriMesh::new(
        base.positions.clone(),
        base.faces.iter().map(|f| [f[0], f[2], f[1]]).collect(),
    )
}
