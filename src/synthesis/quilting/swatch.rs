//! Swatches for mesh quilting (Zhou et al. 2006, §2.1): a mesh of separate geometric elements
//! (connected components) lying over `z = 0` with `z` up; the x-y extent is the swatch.
//!
//! [`swatch`] builds five procedural, deterministic swatches (periodic in x and y: an element
//! leaving the box on one side is matched by the tiling on the other, so periodic swatches report
//! their period as the extent and elements may poke past the box). [`load_swatch`] turns a user
//! mesh into a [`Swatch`], splitting it into elements and rejecting unusable inputs with one-line
//! errors.

use glam::{Mat3, Vec2, Vec3};
use rand::{Rng, SeedableRng, rngs::SmallRng};

use crate::error::{Error, Result};
use crate::mesh::{TriMesh, connected_components};

/// The procedural swatch kinds.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SwatchKind {
    /// Chain mail (Japanese 4-in-1): flat rings on a square lattice, each linked to its four
    /// neighbours by upright rings on the lattice edges.
    Chain,
    /// Over-under strands in x and y with a small gap at each strand end.
    Weave,
    /// Hexagonal nuts (genus 1) scattered on a jittered grid with random turns and sizes.
    Nuts,
    /// Rounded cylinders on a square grid.
    Studs,
    /// Overlapping fish scales: tilted thin lenses laid like shingles.
    Scales,
}

impl SwatchKind {
    /// All kinds, in a fixed order.
    pub const ALL: [SwatchKind; 5] = [
        SwatchKind::Chain,
        SwatchKind::Weave,
        SwatchKind::Nuts,
        SwatchKind::Studs,
        SwatchKind::Scales,
    ];
    /// The lower-case name (`chain`, `weave`, `nuts`, `studs`, `scales`).
    pub fn as_str(self) -> &'static str {
        match self {
            SwatchKind::Chain => "chain",
            SwatchKind::Weave => "weave",
            SwatchKind::Nuts => "nuts",
            SwatchKind::Studs => "studs",
            SwatchKind::Scales => "scales",
        }
    }
    /// Parse a lower-case name.
    pub fn parse(s: &str) -> Result<Self> {
        SwatchKind::ALL
            .into_iter()
            .find(|k| k.as_str() == s)
            .ok_or_else(|| {
                Error::InvalidInput(format!(
                    "unknown swatch '{s}' (expected chain, weave, nuts, studs or scales)"
                ))
            })
    }
}

/// Which axis of a user swatch points up (away from the surface).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Axis {
    /// +x up.
    X,
    /// +y up.
    Y,
    /// +z up (the swatch convention).
    #[default]
    Z,
}

/// One element of a swatch: a contiguous vertex range and face range of [`Swatch::mesh`].
#[derive(Clone, Debug)]
pub struct Element {
    /// First vertex and one past the last.
    pub vertices: std::ops::Range<u32>,
    /// First face and one past the last.
    pub faces: std::ops::Range<u32>,
    /// Centre of the vertex bounding box.
    pub centre: [f32; 3],
    /// Largest x-y distance of a vertex from `centre`.
    pub radius: f32,
    /// Shape class: elements with equal vertex and face counts share a class.
    pub class: u32,
}

/// A validated swatch: elements stored contiguously, lying in `z >= 0`, over the box
/// `[0, extent[0]] x [0, extent[1]]`.
#[derive(Clone, Debug)]
pub struct Swatch {
    /// All elements, each a contiguous vertex and face range.
    pub mesh: TriMesh,
    /// The elements.
    pub elements: Vec<Element>,
    /// x-y extent of the swatch (the period when `periodic`).
    pub extent: [f32; 2],
    /// Largest z of any vertex (the shell thickness `h_in` of the paper).
    pub height: f32,
    /// True when the swatch tiles the plane with period `extent`.
    pub periodic: bool,
}

impl Swatch {
    /// Build from a mesh whose elements are already positioned over `z >= 0`; the extent is the
    /// x-y box `[0, extent]`. Reorders vertices so each element is contiguous.
    pub(super) fn from_mesh(mesh: &TriMesh, extent: [f32; 2], periodic: bool) -> Result<Swatch> {
        let n = mesh.num_vertices();
        let (label, count) = connected_components(n, &mesh.faces);
        if mesh.faces.is_empty() || count == 0 {
            return Err(Error::InvalidInput(
                "swatch has no elements (no faces)".into(),
            ));
        }
        // order elements by the lowest face index that uses them (deterministic)
        let mut order: Vec<u32> = Vec::new();
        let mut slot = vec![u32::MAX; n.max(1)];
        for f in &mesh.faces {
            let l = label[f[0] as usize] as usize;
            if slot[l] == u32::MAX {
                slot[l] = order.len() as u32;
                order.push(l as u32);
            }
        }
        let ne = order.len();
        let mut verts_of: Vec<Vec<u32>> = vec![Vec::new(); ne];
        let mut used = vec![false; n];
        for f in &mesh.faces {
            for &v in f {
                used[v as usize] = true;
            }
        }
        for v in 0..n {
            if used[v] {
                verts_of[slot[label[v] as usize] as usize].push(v as u32);
            }
        }
        let mut faces_of: Vec<Vec<[u32; 3]>> = vec![Vec::new(); ne];
        for f in &mesh.faces {
            faces_of[slot[label[f[0] as usize] as usize] as usize].push(*f);
        }
        let mut new_index = vec![u32::MAX; n];
        let mut positions = Vec::with_capacity(n);
        let mut faces = Vec::with_capacity(mesh.faces.len());
        let mut elements = Vec::with_capacity(ne);
        let mut classes: Vec<(usize, usize)> = Vec::new();
        for e in 0..ne {
            let v0 = positions.len() as u32;
            let f0 = faces.len() as u32;
            let mut lo = Vec3::splat(f32::INFINITY);
            let mut hi = Vec3::splat(f32::NEG_INFINITY);
            for &v in &verts_of[e] {
                new_index[v as usize] = positions.len() as u32;
                let p = mesh.positions[v as usize];
                lo = lo.min(Vec3::from(p));
                hi = hi.max(Vec3::from(p));
                positions.push(p);
            }
            for f in &faces_of[e] {
                faces.push(f.map(|v| new_index[v as usize]));
            }
            let c = (lo + hi) * 0.5;
            let radius = verts_of[e]
                .iter()
                .map(|&v| {
                    let p = mesh.positions[v as usize];
                    ((p[0] - c.x).powi(2) + (p[1] - c.y).powi(2)).sqrt()
                })
                .fold(0.0f32, f32::max);
            let sig = (verts_of[e].len(), faces_of[e].len());
            let class = match classes.iter().position(|&s| s == sig) {
                Some(i) => i,
                None => {
                    classes.push(sig);
                    classes.len() - 1
                }
            } as u32;
            elements.push(Element {
                vertices: v0..positions.len() as u32,
                faces: f0..faces.len() as u32,
                centre: c.to_array(),
                radius,
                class,
            });
        }
        let height = positions.iter().map(|p| p[2]).fold(0.0f32, f32::max);
        Ok(Swatch {
            mesh: TriMesh::new(positions, faces),
            elements,
            extent,
            height,
            periodic,
        })
    }

    /// Number of elements.
    pub fn num_elements(&self) -> usize {
        self.elements.len()
    }

    /// The vertex positions of element `e`.
    pub fn element_positions(&self, e: usize) -> &[[f32; 3]] {
        let r = &self.elements[e].vertices;
        &self.mesh.positions[r.start as usize..r.end as usize]
    }

    /// The faces of element `e`, indexed from the element's first vertex.
    pub fn element_faces(&self, e: usize) -> Vec<[u32; 3]> {
        let el = &self.elements[e];
        self.mesh.faces[el.faces.start as usize..el.faces.end as usize]
            .iter()
            .map(|f| f.map(|v| v - el.vertices.start))
            .collect()
    }

    /// Periodic images to consider: offsets `(i px, j py)` for i, j in -1..=1 when periodic,
    /// only the zero offset otherwise.
    pub fn images(&self) -> Vec<[f32; 2]> {
        if self.periodic {
            let mut v = Vec::with_capacity(9);
            for j in -1..=1 {
                for i in -1..=1 {
                    v.push([i as f32 * self.extent[0], j as f32 * self.extent[1]]);
                }
            }
            v
        } else {
            vec![[0.0, 0.0]]
        }
    }

    /// Smallest vertex-to-vertex distance between two distinct elements (periodic images
    /// included), the swatch's own clearance; `f32::INFINITY` with a single element.
    pub fn clearance(&self) -> f32 {
        let images = self.images();
        let ne = self.elements.len();
        // element boxes, found near each other by their centres (a k-d tree), exact vertex
        // distances only for pairs whose boxes come closer than the best so far
        let boxes: Vec<(Vec3, Vec3)> = (0..ne)
            .map(|e| {
                let ps = self.element_positions(e);
                let mut lo = Vec3::splat(f32::INFINITY);
                let mut hi = Vec3::splat(f32::NEG_INFINITY);
                for p in ps {
                    lo = lo.min(Vec3::from(*p));
                    hi = hi.max(Vec3::from(*p));
                }
                (lo, hi)
            })
            .collect();
        let centres: Vec<f32> = boxes
            .iter()
            .flat_map(|(lo, hi)| (0.5 * (*lo + *hi)).to_array())
            .collect();
        let radius: Vec<f32> = boxes
            .iter()
            .map(|(lo, hi)| 0.5 * lo.distance(*hi))
            .collect();
        let rmax = radius.iter().cloned().fold(0.0f32, f32::max);
        let tree = crate::stats::KdTree::new(&centres, 3);
        let exact = |a: usize, b: usize, off: Vec3, best: &mut f32| {
            for p in self.element_positions(a) {
                let p = Vec3::from(*p);
                for q in self.element_positions(b) {
                    *best = best.min(p.distance(Vec3::from(*q) + off));
                }
            }
        };
        let mut best = f32::INFINITY;
        // a first bound: each element against the one whose centre is nearest
        let mut knn = Vec::with_capacity(2);
        for a in 0..ne {
            tree.knn(&centres[3 * a..3 * a + 3], 2, &mut knn);
            if let Some(&(_, b)) = knn.iter().find(|n| n.1 as usize != a) {
                exact(a, b as usize, Vec3::ZERO, &mut best);
            }
        }
        let mut near = Vec::new();
        for a in 0..ne {
            let ca = Vec3::from_slice(&centres[3 * a..3 * a + 3]);
            for im in &images {
                let off = Vec3::new(im[0], im[1], 0.0);
                let r = radius[a] + rmax + best;
                tree.within(&(ca - off).to_array(), r * r, &mut near);
                for &b in &near {
                    let b = b as usize;
                    if a == b && im[0] == 0.0 && im[1] == 0.0 {
                        continue;
                    }
                    if b < a && !self.periodic {
                        continue;
                    }
                    let (la, ha) = boxes[a];
                    let (lb, hb) = (boxes[b].0 + off, boxes[b].1 + off);
                    let gap = (lb - ha).max(la - hb).max(Vec3::ZERO).length();
                    if gap >= best {
                        continue;
                    }
                    exact(a, b, off, &mut best);
                }
            }
        }
        best
    }

    /// Smallest x-y centre distance between elements of classes `a` and `b` (distinct elements,
    /// periodic images included), as a `classes x classes` row-major table; `INFINITY` where no
    /// such pair exists.
    pub fn class_spacing(&self) -> (usize, Vec<f32>) {
        let nc = self.elements.iter().map(|e| e.class + 1).max().unwrap_or(0) as usize;
        let mut t = vec![f32::INFINITY; nc * nc];
        let images = self.images();
        let centre = |e: &Element| Vec2::new(e.centre[0], e.centre[1]);
        if nc > CLASS_TREES_UP_TO {
            // many classes: every pair, as a tree per class would cost as much
            for (i, a) in self.elements.iter().enumerate() {
                for (j, b) in self.elements.iter().enumerate() {
                    for im in &images {
                        if i == j && im[0] == 0.0 && im[1] == 0.0 {
                            continue;
                        }
                        let d = centre(a).distance(centre(b) + Vec2::from(*im));
                        let k = a.class as usize * nc + b.class as usize;
                        t[k] = t[k].min(d);
                        let k = b.class as usize * nc + a.class as usize;
                        t[k] = t[k].min(d);
                    }
                }
            }
            return (nc, t);
        }
        // each element against the nearest centre of every class (a k-d tree per class)
        let mut members: Vec<Vec<usize>> = vec![Vec::new(); nc];
        for (i, e) in self.elements.iter().enumerate() {
            members[e.class as usize].push(i);
        }
        let trees: Vec<crate::stats::KdTree> = members
            .iter()
            .map(|m| {
                let pts: Vec<f32> = m
                    .iter()
                    .flat_map(|&i| centre(&self.elements[i]).to_array())
                    .collect();
                crate::stats::KdTree::new(&pts, 2)
            })
            .collect();
        let mut near = Vec::with_capacity(2);
        for (i, a) in self.elements.iter().enumerate() {
            for (cb, tree) in trees.iter().enumerate() {
                for im in &images {
                    let own = im[0] == 0.0 && im[1] == 0.0;
                    let q = centre(a) - Vec2::from(*im);
                    tree.knn(&q.to_array(), 1 + own as usize, &mut near);
                    let hit = near
                        .iter()
                        .find(|n| !(own && members[cb][n.1 as usize] == i));
                    if let Some(&(d2, _)) = hit {
                        let d = d2.sqrt();
                        let k = a.class as usize * nc + cb;
                        t[k] = t[k].min(d);
                        let k = cb * nc + a.class as usize;
                        t[k] = t[k].min(d);
                    }
                }
            }
        }
        (nc, t)
    }
}

/// Classes up to which [`Swatch::class_spacing`] searches a k-d tree per class.
const CLASS_TREES_UP_TO: usize = 64;

/// Split a user mesh into elements and validate it as a swatch. `up` names the axis that points
/// away from the surface; it is rotated onto +z. The x-y extent is the bounding box, moved to
/// start at the origin; the swatch is not periodic.
///
/// Errors (one line each): no faces; one element only (it covers the swatch); an element whose
/// x-y box covers the whole swatch; vertices below the ground (`z < 0` after the rotation, with a
/// small tolerance); non-finite coordinates.
pub fn load_swatch(mesh: TriMesh, up: Axis) -> Result<Swatch> {
    if mesh.faces.is_empty() {
        return Err(Error::InvalidInput(
            "swatch has no elements (no faces)".into(),
        ));
    }
    if mesh
        .positions
        .iter()
        .any(|p| p.iter().any(|x| !x.is_finite()))
    {
        return Err(Error::InvalidInput(
            "swatch has non-finite vertex coordinates".into(),
        ));
    }
    if mesh
        .faces
        .iter()
        .flatten()
        .any(|&v| v as usize >= mesh.num_vertices())
    {
        return Err(Error::InvalidInput(
            "swatch has a face with an out-of-range vertex index".into(),
        ));
    }
    let rot = |p: [f32; 3]| -> [f32; 3] {
        match up {
            Axis::Z => p,
            Axis::Y => [p[2], p[0], p[1]],
            Axis::X => [p[1], p[2], p[0]],
        }
    };
    let positions: Vec<[f32; 3]> = mesh.positions.iter().map(|&p| rot(p)).collect();
    let mut lo = [f32::INFINITY; 3];
    let mut hi = [f32::NEG_INFINITY; 3];
    for f in &mesh.faces {
        for &v in f {
            let p = positions[v as usize];
            for k in 0..3 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
    }
    let size = (0..3).map(|k| hi[k] - lo[k]).fold(0.0f32, f32::max);
    if lo[2] < -1e-4 * size.max(f32::MIN_POSITIVE) {
        return Err(Error::InvalidInput(format!(
            "swatch elements reach below the ground (lowest z = {}); elements must lie over z = 0 with the up axis pointing away from the surface",
            lo[2]
        )));
    }
    if hi[0] - lo[0] <= 0.0 || hi[1] - lo[1] <= 0.0 {
        return Err(Error::InvalidInput(
            "swatch is degenerate: zero x or y extent".into(),
        ));
    }
    let moved: Vec<[f32; 3]> = positions
        .iter()
        .map(|p| [p[0] - lo[0], p[1] - lo[1], p[2].max(0.0)])
        .collect();
    let extent = [hi[0] - lo[0], hi[1] - lo[1]];
    let s = Swatch::from_mesh(&TriMesh::new(moved, mesh.faces.clone()), extent, false)?;
    if s.elements.len() == 1 {
        return Err(Error::InvalidInput(
            "one element covers the swatch; quilting needs several".into(),
        ));
    }
    for (i, e) in s.elements.iter().enumerate() {
        let ps = s.element_positions(i);
        let (mut x0, mut x1, mut y0, mut y1) = (
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::INFINITY,
            f32::NEG_INFINITY,
        );
        for p in ps {
            x0 = x0.min(p[0]);
            x1 = x1.max(p[0]);
            y0 = y0.min(p[1]);
            y1 = y1.max(p[1]);
        }
        if x1 - x0 >= 0.95 * extent[0] && y1 - y0 >= 0.95 * extent[1] {
            return Err(Error::InvalidInput(format!(
                "element {i} ({} faces) covers the whole swatch; quilting needs several separate elements",
                e.faces.len()
            )));
        }
    }
    Ok(s)
}

// ---------------------------------------------------------------------------------------------
// Procedural swatches

/// Mesh builder: appends closed surfaces as separate components.
#[derive(Default)]
pub(super) struct Builder {
    pub(super) positions: Vec<[f32; 3]>,
    pub(super) faces: Vec<[u32; 3]>,
}

impl Builder {
    /// Revolve a profile `(r, z)` around the z axis in `n` steps, then map every point by `f`.
    /// A closed profile gives a torus-like surface; an open profile must start and end on the
    /// axis (`r = 0`) and gives a sphere-like surface with one pole vertex at each end. The
    /// profile runs so that the outward normal is on its right when going along it in (r, z).
    pub(super) fn revolve(
        &mut self,
        profile: &[(f32, f32)],
        closed: bool,
        n: usize,
        f: impl Fn(Vec3) -> Vec3,
    ) {
        let base = self.positions.len() as u32;
        let ring = |i: usize, k: usize| -> [f32; 3] {
            let a = std::f32::consts::TAU * k as f32 / n as f32;
            let (r, z) = profile[i];
            f(Vec3::new(r * a.cos(), r * a.sin(), z)).to_array()
        };
        if closed {
            let m = profile.len();
            for i in 0..m {
                for k in 0..n {
                    self.positions.push(ring(i, k));
                }
            }
            let id = |i: usize, k: usize| base + ((i % m) * n + (k % n)) as u32;
            for i in 0..m {
                for k in 0..n {
                    let (a, b, c, d) = (id(i, k), id(i, k + 1), id(i + 1, k + 1), id(i + 1, k));
                    self.faces.push([a, b, c]);
                    self.faces.push([a, c, d]);
                }
            }
        } else {
            let m = profile.len();
            assert!(m >= 3);
            self.positions
                .push(f(Vec3::new(0.0, 0.0, profile[0].1)).to_array());
            for i in 1..m - 1 {
                for k in 0..n {
                    self.positions.push(ring(i, k));
                }
            }
            self.positions
                .push(f(Vec3::new(0.0, 0.0, profile[m - 1].1)).to_array());
            let top = self.positions.len() as u32 - 1;
            let id = |i: usize, k: usize| base + 1 + ((i - 1) * n + (k % n)) as u32;
            for k in 0..n {
                self.faces.push([base, id(1, k + 1), id(1, k)]);
            }
            for i in 1..m - 2 {
                for k in 0..n {
                    let (a, b, c, d) = (id(i, k), id(i, k + 1), id(i + 1, k + 1), id(i + 1, k));
                    self.faces.push([a, b, c]);
                    self.faces.push([a, c, d]);
                }
            }
            for k in 0..n {
                self.faces.push([id(m - 2, k), id(m - 2, k + 1), top]);
            }
        }
    }

    /// A tube of radius `(rw, rh)` (width, height) swept along `path` (points in the x-z plane
    /// mapped by `f` afterwards), capped at both ends.
    pub(super) fn strand(
        &mut self,
        path: &[Vec3],
        rw: f32,
        rh: f32,
        n: usize,
        f: impl Fn(Vec3) -> Vec3,
    ) {
        let base = self.positions.len() as u32;
        let m = path.len();
        self.positions.push(f(path[0]).to_array());
        for i in 0..m {
            let t = if i == 0 {
                path[1] - path[0]
            } else if i == m - 1 {
                path[m - 1] - path[m - 2]
            } else {
                path[i + 1] - path[i - 1]
            }
            .normalize();
            let side = Vec3::Y;
            let up = t.cross(side).normalize() * -1.0;
            let up = if up.z < 0.0 { -up } else { up };
            for k in 0..n {
                let a = std::f32::consts::TAU * k as f32 / n as f32;
                let p = path[i] + side * (rw * a.cos()) + up * (rh * a.sin());
                self.positions.push(f(p).to_array());
            }
        }
        self.positions.push(f(path[m - 1]).to_array());
        let end = self.positions.len() as u32 - 1;
        let id = |i: usize, k: usize| base + 1 + (i * n + (k % n)) as u32;
        for k in 0..n {
            self.faces.push([base, id(0, k + 1), id(0, k)]);
        }
        for i in 0..m - 1 {
            for k in 0..n {
                let (a, b, c, d) = (id(i, k), id(i, k + 1), id(i + 1, k + 1), id(i + 1, k));
                self.faces.push([a, b, c]);
                self.faces.push([a, c, d]);
            }
        }
        for k in 0..n {
            self.faces.push([id(m - 1, k + 1), end, id(m - 1, k)]);
        }
    }
}

pub(super) fn circle_profile(rc: f32, zc: f32, r: f32, m: usize) -> Vec<(f32, f32)> {
    (0..m)
        .map(|i| {
            let a = std::f32::consts::TAU * i as f32 / m as f32;
            (rc + r * a.cos(), zc + r * a.sin())
        })
        .collect()
}

/// A procedural swatch, deterministic under `seed` (only `nuts` uses randomness). All are
/// periodic with the reported extent as period; unit spacing between neighbouring elements.
///
/// One function per kind builds its elements on a 4 x 4 grid of cells and returns the extent.
pub fn swatch(kind: SwatchKind, seed: u64) -> Swatch {
    let mut b = Builder::default();
    let mut rng = SmallRng::seed_from_u64(seed ^ 0x5157_4154_4348);
    let (nx, ny) = (4usize, 4usize);
    let extent = match kind {
        SwatchKind::Chain => chain_rings(&mut b, nx, ny),
        SwatchKind::Weave => weave_strands(&mut b, nx, ny),
        SwatchKind::Nuts => scattered_nuts(&mut b, nx, ny, &mut rng),
        SwatchKind::Studs => studs(&mut b, nx, ny),
        SwatchKind::Scales => shingled_scales(&mut b, nx, ny),
    };
    let mesh = TriMesh::new(b.positions, b.faces);
    Swatch::from_mesh(&mesh, extent, true).expect("procedural swatches are valid")
}

/// Chain mail: flat rings at the cell centres, linked by upright rings on the cell edges.
fn chain_rings(b: &mut Builder, nx: usize, ny: usize) -> [f32; 2] {
    // flat rings at cell centres, upright rings on the cell edges between them; the
    // upright circle crosses z = zc at 0.2 from each flat ring's centre (inside its
    // hole), 0.1 clear of the flat ring's centre line, tubes 0.035 thick.
    let (rf, rv, tube) = (0.3f32, 0.3f32, 0.035f32);
    let squash = 0.6f32;
    let zc = rv * squash + tube + 0.01;
    let tor = circle_profile(rf, 0.0, tube, 6);
    for j in 0..ny {
        for i in 0..nx {
            let c = Vec3::new(i as f32 + 0.5, j as f32 + 0.5, zc);
            b.revolve(&tor, true, 16, |p| p + c);
            // upright ring between (i, j) and (i + 1, j), in the x-z plane
            let cx = Vec3::new(i as f32 + 1.0, j as f32 + 0.5, zc);
            let ring = circle_profile(rv, 0.0, tube, 6);
            let rx = Mat3::from_rotation_x(std::f32::consts::FRAC_PI_2);
            b.revolve(&ring, true, 16, |p| {
                let q = rx * p;
                Vec3::new(q.x, q.y, q.z * squash) + cx
            });
            // upright ring between (i, j) and (i, j + 1), in the y-z plane
            let cy = Vec3::new(i as f32 + 0.5, j as f32 + 1.0, zc);
            let ry = Mat3::from_rotation_y(std::f32::consts::FRAC_PI_2);
            b.revolve(&ring, true, 16, |p| {
                let q = ry * p;
                Vec3::new(q.x, q.y, q.z * squash) + cy
            });
        }
    }
    [nx as f32, ny as f32]
}

/// Over-under strands along x and along y, over at alternate crossings.
fn weave_strands(b: &mut Builder, nx: usize, ny: usize) -> [f32; 2] {
    // strands along x at y = j + 0.25 and along y at x = i + 0.75; x strands go over
    // at even crossings, y strands at odd; period 2 crossings per strand.
    let (rw, rh, amp, gap) = (0.18f32, 0.07f32, 0.09f32, 0.06f32);
    let zc = amp + rh + 0.01;
    let len = nx as f32;
    let samples = 32usize;
    for j in 0..ny {
        let phase = if j % 2 == 0 {
            0.0
        } else {
            std::f32::consts::PI
        };
        let path: Vec<Vec3> = (0..=samples)
            .map(|s| {
                let x = gap / 2.0 + (len - gap) * s as f32 / samples as f32;
                let z = zc + amp * (std::f32::consts::PI * (x - 0.75) + phase).cos();
                Vec3::new(x, 0.0, z)
            })
            .collect();
        let y = j as f32 + 0.25;
        b.strand(&path, rw, rh, 8, |p| Vec3::new(p.x, y + p.y, p.z));
    }
    for i in 0..nx {
        let phase = if i % 2 == 0 {
            std::f32::consts::PI
        } else {
            0.0
        };
        let path: Vec<Vec3> = (0..=samples)
            .map(|s| {
                let t = gap / 2.0 + (len - gap) * s as f32 / samples as f32;
                let z = zc + amp * (std::f32::consts::PI * (t - 0.25) + phase).cos();
                Vec3::new(t, 0.0, z)
            })
            .collect();
        let x = i as f32 + 0.75;
        // swap x and y: the strand runs along y
        b.strand(&path, rw, rh, 8, |p| Vec3::new(x - p.y, p.x, p.z));
    }
    [nx as f32, ny as f32]
}

/// Hexagonal nuts (a rectangle revolved in six steps) on a jittered grid, random turns and sizes.
fn scattered_nuts(b: &mut Builder, nx: usize, ny: usize, rng: &mut SmallRng) -> [f32; 2] {
    for j in 0..ny {
        for i in 0..nx {
            let size: f32 = rng.random_range(0.75..1.0);
            let (ri, ro, hgt) = (0.14 * size, 0.32 * size, 0.2 * size);
            let turn: f32 = rng.random_range(0.0..std::f32::consts::TAU);
            let jx: f32 = rng.random_range(-0.1..0.1);
            let jy: f32 = rng.random_range(-0.1..0.1);
            let c = Vec3::new(i as f32 + 0.5 + jx, j as f32 + 0.5 + jy, 0.0);
            let rot = Mat3::from_rotation_z(turn);
            // rectangle profile (inner wall, top, outer wall, bottom), closed
            let prof = [(ri, 0.0), (ro, 0.0), (ro, hgt), (ri, hgt)];
            b.revolve(&prof, true, 6, |p| rot * p + c);
        }
    }
    [nx as f32, ny as f32]
}

/// Rounded cylinders, one per cell.
fn studs(b: &mut Builder, nx: usize, ny: usize) -> [f32; 2] {
    let (r, h, fillet) = (0.3f32, 0.35f32, 0.08f32);
    let mut prof = vec![(0.0, 0.0), (r, 0.0)];
    for k in 0..=4 {
        let a = std::f32::consts::FRAC_PI_2 * k as f32 / 4.0;
        prof.push((r - fillet + fillet * a.cos(), h - fillet + fillet * a.sin()));
    }
    prof.push((0.0, h));
    // outward normal on the right of the profile direction: reverse for revolve order
    for j in 0..ny {
        for i in 0..nx {
            let c = Vec3::new(i as f32 + 0.5, j as f32 + 0.5, 0.0);
            b.revolve(&prof, false, 16, |p| p + c);
        }
    }
    [nx as f32, ny as f32]
}

/// Fish scales: thin lenses on a staggered lattice, tilted to overlap like shingles.
fn shingled_scales(b: &mut Builder, nx: usize, ny: usize) -> [f32; 2] {
    // lattice (i + (j odd) / 2, j / 2); each scale a thin lens (rx 0.65, ry 0.48)
    // tilted up along +x with slope 0.25 so neighbours lie like shingles.
    let (rx, ry, t, slope) = (0.65f32, 0.48f32, 0.03f32, 0.25f32);
    let rows = 2 * ny;
    let m = 6usize;
    let mut prof = vec![(0.0f32, -t)];
    for k in 1..m {
        let rr = k as f32 / m as f32;
        prof.push((rr, -t * (1.0 - rr * rr)));
    }
    prof.push((1.0, 0.0));
    for k in (1..m).rev() {
        let rr = k as f32 / m as f32;
        prof.push((rr, t * (1.0 - rr * rr)));
    }
    prof.push((0.0, t));
    for j in 0..rows {
        for i in 0..nx {
            let c = Vec3::new(
                i as f32 + 0.5 + 0.5 * (j % 2) as f32,
                0.5 * j as f32 + 0.25,
                0.0,
            );
            let z0 = slope * rx + t + 0.01;
            b.revolve(&prof, false, 16, |p| {
                let x = p.x * rx;
                let y = p.y * ry;
                Vec3::new(c.x + x, c.y + y, z0 + slope * x + p.z)
            });
        }
    }
    [nx as f32, 0.5 * rows as f32]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::face_normals;

    #[test]
    fn procedural_swatches_are_valid_and_clear() {
        for kind in SwatchKind::ALL {
            let s = swatch(kind, 7);
            assert!(s.num_elements() >= 8, "{kind:?}");
            assert!(s.height > 0.0);
            assert!(
                s.mesh.positions.iter().all(|p| p[2] >= -1e-5),
                "{kind:?} below ground"
            );
            let c = s.clearance();
            assert!(c > 0.005, "{kind:?} elements touch: clearance {c}");
            // closed and outward: signed volume of each element positive
            for e in 0..s.num_elements() {
                let ps = s.element_positions(e);
                let fs = s.element_faces(e);
                let vol: f32 = fs
                    .iter()
                    .map(|f| {
                        let (a, b, c) = (
                            Vec3::from(ps[f[0] as usize]),
                            Vec3::from(ps[f[1] as usize]),
                            Vec3::from(ps[f[2] as usize]),
                        );
                        a.dot(b.cross(c)) / 6.0
                    })
                    .sum();
                assert!(vol > 0.0, "{kind:?} element {e} volume {vol}");
                // closed manifold: every edge in two faces; Euler characteristic of a torus
                // (rings, nuts) or a sphere (studs, strands, scales)
                let mut edges = std::collections::HashMap::new();
                for f in &fs {
                    for k in 0..3 {
                        let (a, b) = (f[k], f[(k + 1) % 3]);
                        *edges.entry((a.min(b), a.max(b))).or_insert(0) += 1;
                    }
                }
                assert!(
                    edges.values().all(|&c| c == 2),
                    "{kind:?} element {e} not closed"
                );
                let chi = ps.len() as i64 - edges.len() as i64 + fs.len() as i64;
                let want = match kind {
                    SwatchKind::Chain | SwatchKind::Nuts => 0,
                    _ => 2,
                };
                assert_eq!(chi, want, "{kind:?} element {e}");
                assert!(face_normals(ps, &fs).len() == fs.len());
            }
        }
        // deterministic
        let a = swatch(SwatchKind::Nuts, 3);
        let b = swatch(SwatchKind::Nuts, 3);
        assert_eq!(a.mesh.positions, b.mesh.positions);
    }

    #[test]
    fn bad_swatches_give_one_line_errors() {
        let empty = TriMesh::new(vec![], vec![]);
        let e = load_swatch(empty, Axis::Z).unwrap_err().to_string();
        assert!(e.contains("no elements") && !e.contains('\n'));
        let one = swatch(SwatchKind::Studs, 0);
        let r = one.element_positions(0).to_vec();
        let f = one.element_faces(0);
        let e = load_swatch(TriMesh::new(r.clone(), f.clone()), Axis::Z)
            .unwrap_err()
            .to_string();
        assert!(e.contains("one element covers the swatch"), "{e}");
        let below: Vec<[f32; 3]> = one
            .mesh
            .positions
            .iter()
            .map(|p| [p[0], p[1], p[2] - 0.1])
            .collect();
        let e = load_swatch(TriMesh::new(below, one.mesh.faces.clone()), Axis::Z)
            .unwrap_err()
            .to_string();
        assert!(e.contains("below the ground") && !e.contains('\n'), "{e}");
        let ok = load_swatch(one.mesh.clone(), Axis::Z).unwrap();
        assert_eq!(ok.num_elements(), 16);
        assert!(!ok.periodic);
    }
}
