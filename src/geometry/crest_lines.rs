//! Salient curves of a mesh: crest lines (ridges and ravines, after Yoshizawa, Belyaev & Seidel
//! 2005, "Fast and robust detection of crest lines on meshes") and sharp creases by dihedral angle,
//! grouped and broken as Xu et al. 2009 §4.1 asks.
//!
//! Crest lines. With principal curvatures `k_max >= k_min` and directions `t_max, t_min`
//! ([`principal_curvatures`]), a ridge is where `k_max > |k_min|` and `k_max` is extremal along its
//! own curvature line: the zero set of the extremality `e = ∇k_max · t_max` with `∂e/∂t_max < 0`.
//! Ravines are the ridges of the reversed surface (`k = -k_min`, `t = t_min`). `∇k` per vertex is
//! the area-weighted average of the linear per-face gradients projected on the tangent plane. A
//! zero crossing lies on edge `ij` when `e_i · s e_j < 0` with `s = sign(t_i · t_j)` (the
//! directions carry no sign); a face with two crossing edges and `∂e/∂t < 0` gives one segment.
//! Segments join through shared edges into polylines; the strength of a line is `∫ |k| ds`
//! (dimensionless); lines under the threshold are dropped. Faces touching a sharp crease are left
//! to the crease detector.
//!
//! Rounded edges of constant radius (CAD fillets) have `k` flat across them, so `e` is noise
//! there and the crest would land anywhere on the fillet (or, from the estimate's overshoot, at
//! its borders). On such plateaus (`k` over the two-ring within the prominence) two walks along
//! `±t` measure the distances `a, b` to where `k` halves; where both end, the crest function is
//! `k (1 + c)` with the centrality `c = 1 - |a - b| / (a + b)`, and crossings keep only the
//! band's middle (`c >= 0.75`), so the crest is the fillet's middle line. Measured
//! (`examples/rounded_edges`, relaxed meshes of a unit box, fillet radii of 2 to 24 edge
//! lengths): the middle line of all 12 edges at every radius and nothing else up to 12 edge
//! lengths (12 stray lines at 24), where the extremality alone found no middle line above 2
//! edge lengths; the shared horse keeps 276 of its 293 curves.
//!
//! Creases. Interior edges whose dihedral angle (between the face normals) exceeds
//! `crease_angle_deg`, chained through vertices with two crease edges; strength `Σ θ_e |e| / h`
//! (h: mean edge length), the same unit as `∫ |k| ds` since a crease of angle θ spread over one
//! edge length has `k ≈ θ / h`.
//!
//! Preparation (Xu et al. §4.1; thresholds are the guide's proposals): break polylines where the
//! turn over a ±2 point window exceeds `break_angle_deg`; join endpoints closer than
//! `join_distance` mean edge lengths whose continuing tangents differ by less than
//! `join_angle_deg` (bridged along mesh edges); drop curves with fewer than `min_vertices` snapped
//! vertices or shorter than `min_length`. Every curve is also snapped to a path of mesh vertices
//! along mesh edges (`vertices`): the nearest end of each crossing edge, consecutive duplicates
//! removed.

use std::collections::HashMap;

use glam::Vec3;

use super::basic::{face_normals, mean_edge_length};
use super::curvature::{PrincipalCurvatures, principal_curvatures};
use crate::error::{Error, Result};

/// What a curve follows.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum CurveKind {
    /// Convex crest: maximum of `k_max` along its curvature line.
    Ridge,
    /// Concave crest: minimum of `k_min` along its curvature line.
    Ravine,
    /// Sharp edge by dihedral angle.
    Crease,
}

/// One salient curve.
#[derive(Clone, Debug)]
pub struct Curve {
    /// The polyline (crest points on mesh edges, or mesh vertices for creases).
    pub points: Vec<[f32; 3]>,
    /// Per point, the mesh edge `[i, j]` it lies on (`[v, v]` for a point at vertex v).
    pub edges: Vec<[u32; 2]>,
    /// The snapped path: mesh vertices nearest the curve, consecutive ones joined by mesh edges.
    pub vertices: Vec<u32>,
    /// `∫ |k| ds` along the curve (dimensionless).
    pub strength: f32,
    /// Ridge, ravine or crease.
    pub kind: CurveKind,
    /// Whether the polyline closes on itself.
    pub closed: bool,
}

impl Curve {
    /// Arc length of the polyline.
    pub fn length(&self) -> f32 {
        let mut l: f32 = self
            .points
            .windows(2)
            .map(|w| Vec3::from(w[0]).distance(Vec3::from(w[1])))
            .sum();
        if self.closed && self.points.len() > 2 {
            l += Vec3::from(self.points[0]).distance(Vec3::from(*self.points.last().unwrap()));
        }
        l
    }
}

/// Thresholds of [`salient_curves`].
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
#[serde(default)]
pub struct CurveParams {
    /// Minimum strength `∫ |k| ds` of a crest line or crease.
    pub threshold: f32,
    /// Minimum arc length in mesh units (`None`: 5 mean edge lengths).
    pub min_length: Option<f32>,
    /// Detect ridges and ravines.
    pub crest_lines: bool,
    /// Dihedral angle above which an edge is a sharp crease (degrees; >= 180 disables).
    pub crease_angle_deg: f32,
    /// One-ring smoothing passes of the curvature tensor.
    pub smooth: usize,
    /// Prominence: keep a crossing on edge ab only if its `k` exceeds the smallest `k` of the
    /// two-rings of a and b by this fraction of `k` (a cylinder's side, whose constant curvature
    /// makes `e` numerical noise, has none).
    pub min_prominence: f32,
    /// Join endpoints closer than this many mean edge lengths...
    pub join_distance: f32,
    /// ...whose tangents differ by less than this (degrees).
    pub join_angle_deg: f32,
    /// Break where the turn over a ±2 point window exceeds this (degrees).
    pub break_angle_deg: f32,
    /// Drop curves with fewer snapped vertices.
    pub min_vertices: usize,
}

impl Default for CurveParams {
    fn default() -> Self {
        CurveParams {
            threshold: 1.0,
            min_length: None,
            crest_lines: true,
            crease_angle_deg: 40.0,
            smooth: 1,
            min_prominence: 0.1,
            join_distance: 3.0,
            join_angle_deg: 30.0,
            break_angle_deg: 45.0,
            min_vertices: 5,
        }
    }
}

/// Crest lines and creases of a triangle mesh (see the module doc), strongest first.
pub fn salient_curves(
    positions: &[[f32; 3]],
    faces: &[[u32; 3]],
    params: &CurveParams,
) -> Result<Vec<Curve>> {
    let n = positions.len();
    super::laplacian::check_faces(n, faces)?;
    if faces.is_empty() {
        return Err(Error::InvalidMesh("salient curves need faces".into()));
    }
    let h = mean_edge_length(positions, faces).max(1e-12);
    let adj = crate::mesh::vertex_adjacency(n, faces);
    // edge -> incident faces
    let mut edge_faces: HashMap<(u32, u32), Vec<u32>> = HashMap::new();
    for (fi, f) in faces.iter().enumerate() {
        for k in 0..3 {
            let (a, b) = (f[k], f[(k + 1) % 3]);
            edge_faces
                .entry((a.min(b), a.max(b)))
                .or_default()
                .push(fi as u32);
        }
    }
    let fnormals = face_normals(positions, faces);
    let mut raw: Vec<Curve> = Vec::new();
    // ---- creases
    let mut on_crease = vec![false; n];
    if params.crease_angle_deg < 180.0 {
        let cos_t = params.crease_angle_deg.to_radians().cos();
        let mut cedges: Vec<(u32, u32, f32)> = Vec::new();
        for (&(a, b), fs) in &edge_faces {
            if fs.len() != 2 {
                continue;
            }
            let n0 = Vec3::from(fnormals[fs[0] as usize]);
            let n1 = Vec3::from(fnormals[fs[1] as usize]);
            let c = n0.dot(n1);
            if c < cos_t {
                cedges.push((a, b, c.clamp(-1.0, 1.0).acos()));
            }
        }
        cedges.sort_by_key(|e| (e.0, e.1));
        for &(a, b, _) in &cedges {
            on_crease[a as usize] = true;
            on_crease[b as usize] = true;
        }
        raw.extend(chain_creases(positions, &cedges, h));
    }
    // ---- crest lines
    if params.crest_lines {
        let pc = principal_curvatures(positions, faces, params.smooth);
        let blocked: Vec<bool> = faces
            .iter()
            .map(|f| f.iter().any(|&v| on_crease[v as usize]))
            .collect();
        for kind in [CurveKind::Ridge, CurveKind::Ravine] {
            raw.extend(crest_lines(
                positions,
                faces,
                &pc,
                kind,
                &blocked,
                &adj,
                params.min_prominence,
            ));
        }
    }
    // ---- snapping, breaking, joining, filtering
    for c in &mut raw {
        c.vertices = snap(positions, &c.points, &c.edges);
    }
    let mut broken = Vec::new();
    for c in raw {
        broken.extend(break_at_turns(positions, c, params.break_angle_deg));
    }
    let joined = join_curves(
        positions,
        &adj,
        broken,
        params.join_distance * h,
        params.join_angle_deg,
    );
    let min_len = params.min_length.unwrap_or(5.0 * h);
    let mut out: Vec<Curve> = joined
        .into_iter()
        .filter(|c| {
            c.vertices.len() >= params.min_vertices
                && c.length() >= min_len
                && c.strength >= params.threshold
        })
        .collect();
    out.sort_by(|a, b| b.strength.total_cmp(&a.strength));
    Ok(out)
}

/// Chain crease edges `(a, b, angle)` into polylines through vertices of crease degree 2.
fn chain_creases(positions: &[[f32; 3]], cedges: &[(u32, u32, f32)], h: f32) -> Vec<Curve> {
    let mut nbrs: HashMap<u32, Vec<(u32, usize)>> = HashMap::new();
    for (ei, &(a, b, _)) in cedges.iter().enumerate() {
        nbrs.entry(a).or_default().push((b, ei));
        nbrs.entry(b).or_default().push((a, ei));
    }
    let mut used = vec![false; cedges.len()];
    let mut out = Vec::new();
    let walk = |start: u32, first: usize, used: &mut Vec<bool>| -> (Vec<u32>, f32, bool) {
        let mut path = vec![start];
        let mut strength = 0.0f32;
        let mut e = first;
        let mut cur = start;
        loop {
            used[e] = true;
            let (a, b, ang) = cedges[e];
            let next = if a == cur { b } else { a };
            strength += ang
                * Vec3::from(positions[a as usize]).distance(Vec3::from(positions[b as usize]))
                / h;
            if next == start {
                return (path, strength, true);
            }
            path.push(next);
            cur = next;
            let nb = &nbrs[&cur];
            if nb.len() != 2 {
                return (path, strength, false);
            }
            match nb.iter().find(|&&(_, ei)| !used[ei]) {
                Some(&(_, ei)) => e = ei,
                None => return (path, strength, false),
            }
        }
    };
    let mut keys: Vec<u32> = nbrs.keys().copied().collect();
    keys.sort_unstable();
    // open chains from vertices of degree != 2, then the remaining cycles
    for pass in 0..2 {
        for &v in &keys {
            let nb = nbrs[&v].clone();
            if pass == 0 && nb.len() == 2 {
                continue;
            }
            for &(_, ei) in &nb {
                if used[ei] {
                    continue;
                }
                let (path, strength, closed) = walk(v, ei, &mut used);
                out.push(Curve {
                    points: path.iter().map(|&i| positions[i as usize]).collect(),
                    edges: path.iter().map(|&i| [i, i]).collect(),
                    vertices: Vec::new(),
                    strength,
                    kind: CurveKind::Crease,
                    closed,
                });
            }
        }
    }
    out
}

/// Ridges (`kind = Ridge`) or ravines of the mesh as polylines of edge crossings.
///
/// The steps: [`crest_field`] (the crest's curvature, direction, plateau centrality and
/// extremality per vertex), [`crest_segments`] (per face, the segment between the zero crossings
/// of the extremality on two of its edges, [`edge_crossing`]), and [`chain_segments`] (the
/// segments joined into polylines with their strength).
fn crest_lines(
    positions: &[[f32; 3]],
    faces: &[[u32; 3]],
    pc: &PrincipalCurvatures,
    kind: CurveKind,
    blocked: &[bool],
    adj: &crate::mesh::Csr,
    min_prominence: f32,
) -> Vec<Curve> {
    let field = crest_field(positions, faces, pc, kind, adj, min_prominence);
    let mut found = CrestPoints::default();
    let segs = crest_segments(
        positions,
        faces,
        blocked,
        adj,
        &field,
        min_prominence,
        &mut found,
    );
    chain_segments(&found, &segs, kind)
}

/// Per-vertex inputs of crest tracing for one kind of crest.
struct CrestField {
    /// The crest's curvature (`k_max` for ridges, `-k_min` for ravines).
    k: Vec<f32>,
    /// Its principal direction.
    t: Vec<Vec3>,
    /// Whether a crest may pass here (`k > |other curvature|` and `k > 0`).
    valid: Vec<bool>,
    /// Smallest `k` over the closed one-ring.
    kmin1: Vec<f32>,
    /// Centrality inside a constant-curvature band, where there is one.
    band: Vec<Option<f32>>,
    /// Extremality `e = ∇k_c · t` of the crest function, in curvature per length.
    e: Vec<f32>,
}

/// The crest's curvature and direction, where crests may lie, the bands and the extremality.
fn crest_field(
    positions: &[[f32; 3]],
    faces: &[[u32; 3]],
    pc: &PrincipalCurvatures,
    kind: CurveKind,
    adj: &crate::mesh::Csr,
    min_prominence: f32,
) -> CrestField {
    let n = positions.len();
    let ridge = kind == CurveKind::Ridge;
    let k: Vec<f32> = (0..n)
        .map(|i| if ridge { pc.k_max[i] } else { -pc.k_min[i] })
        .collect();
    let other: Vec<f32> = (0..n)
        .map(|i| if ridge { pc.k_min[i] } else { pc.k_max[i] })
        .collect();
    let t: Vec<Vec3> = (0..n)
        .map(|i| Vec3::from(if ridge { pc.d_max[i] } else { pc.d_min[i] }))
        .collect();
    let valid: Vec<bool> = (0..n)
        .map(|i| k[i] > other[i].abs() && k[i] > 0.0)
        .collect();
    // smallest k over each closed one-ring (plateaus and crossings compare with the two-ring)
    let kmin1: Vec<f32> = (0..n)
        .map(|i| {
            adj.row(i)
                .iter()
                .map(|&v| k[v as usize])
                .fold(k[i], f32::min)
        })
        .collect();
    // Bands: a constant-radius fillet has k flat across it (k over the two-ring within the
    // prominence), so its extremality is noise and its crest would land anywhere on it; there
    // the ridge is the band's middle line.
    let flat: Vec<bool> = (0..n)
        .map(|i| {
            let kring = adj
                .row(i)
                .iter()
                .map(|&v| kmin1[v as usize])
                .fold(kmin1[i], f32::min);
            valid[i] && k[i] - kring < min_prominence * k[i]
        })
        .collect();
    let band = band_centrality(positions, adj, &k, &t, &flat);
    let kc: Vec<f32> = (0..n)
        .map(|i| match band[i] {
            Some(c) => k[i] * (1.0 + BAND_GAIN * c),
            None => k[i],
        })
        .collect();
    let e = extremality(positions, faces, &pc.normals, &kc, &t);
    CrestField {
        k,
        t,
        valid,
        kmin1,
        band,
        e,
    }
}

/// A triangle's unit normal and twice its area; `None` when it is degenerate (or not finite).
fn unit_normal_and_double_area(p: &[Vec3; 3]) -> Option<(Vec3, f32)> {
    let nrm = (p[1] - p[0]).cross(p[2] - p[0]);
    let a2 = nrm.length();
    (!a2.is_nan() && a2 > 0.0).then(|| (nrm / a2, a2))
}

/// Per-vertex area-weighted sum of the linear per-face gradients of `vals` (weights: twice the
/// face areas).
fn vertex_gradient(positions: &[[f32; 3]], faces: &[[u32; 3]], vals: &[f32]) -> Vec<Vec3> {
    let mut g = vec![Vec3::ZERO; positions.len()];
    for f in faces {
        let p = f.map(|i| Vec3::from(positions[i as usize]));
        let Some((nu, a2)) = unit_normal_and_double_area(&p) else {
            continue;
        };
        let mut gf = Vec3::ZERO;
        for c in 0..3 {
            let e = p[(c + 2) % 3] - p[(c + 1) % 3];
            gf += nu.cross(e) / a2 * vals[f[c] as usize];
        }
        for &v in f {
            g[v as usize] += gf * a2;
        }
    }
    g
}

/// Extremality `e = ∇kc · t` per vertex: the tangential gradient of the crest function along its
/// direction, normalised by the gradient's weights so it stays in curvature per length.
fn extremality(
    positions: &[[f32; 3]],
    faces: &[[u32; 3]],
    normals: &[[f32; 3]],
    kc: &[f32],
    t: &[Vec3],
) -> Vec<f32> {
    let n = positions.len();
    let gk = vertex_gradient(positions, faces, kc);
    let e: Vec<f32> = (0..n)
        .map(|i| {
            let nv = Vec3::from(normals[i]);
            let g = gk[i] - gk[i].dot(nv) * nv;
            // vertex_gradient sums a2-weighted gradients; the scale does not change signs,
            // normalise by the weight so magnitudes stay in curvature per length
            g.dot(t[i])
        })
        .collect();
    let wsum: Vec<f32> = {
        let mut w = vec![0.0f32; n];
        for f in faces {
            let p = f.map(|i| Vec3::from(positions[i as usize]));
            let a2 = (p[1] - p[0]).cross(p[2] - p[0]).length();
            for &v in f {
                w[v as usize] += a2;
            }
        }
        w
    };
    e.iter()
        .zip(&wsum)
        .map(|(&x, &w)| if w > 0.0 { x / w } else { 0.0 })
        .collect()
}

/// Crest points found so far: one per crossed mesh edge, in the order they were found.
#[derive(Default)]
struct CrestPoints {
    /// Position of each crest point.
    points: Vec<[f32; 3]>,
    /// The mesh edge each lies on.
    edges: Vec<[u32; 2]>,
    /// The crest's curvature there.
    k: Vec<f32>,
    /// Edge (smaller vertex first) -> crest point.
    index: HashMap<(u32, u32), u32>,
}

/// Per face whose extremality decreases along the crest direction (a maximum), the segment
/// between the crest points on two of its edges.
fn crest_segments(
    positions: &[[f32; 3]],
    faces: &[[u32; 3]],
    blocked: &[bool],
    adj: &crate::mesh::Csr,
    field: &CrestField,
    min_prominence: f32,
    found: &mut CrestPoints,
) -> Vec<(u32, u32)> {
    let (t, e, valid) = (&field.t, &field.e, &field.valid);
    let mut segs: Vec<(u32, u32)> = Vec::new();
    for (fi, f) in faces.iter().enumerate() {
        if blocked[fi] || !f.iter().all(|&v| valid[v as usize]) {
            continue;
        }
        // maximum test: the gradient of the (consistently signed) extremality along t is negative
        let t0 = t[f[0] as usize];
        let sg = f.map(|v| {
            if t[v as usize].dot(t0) >= 0.0 {
                1.0
            } else {
                -1.0
            }
        });
        let p = f.map(|i| Vec3::from(positions[i as usize]));
        let Some((nu, a2)) = unit_normal_and_double_area(&p) else {
            continue;
        };
        let mut ge = Vec3::ZERO;
        let mut tsum = Vec3::ZERO;
        for c in 0..3 {
            let ed = p[(c + 2) % 3] - p[(c + 1) % 3];
            ge += nu.cross(ed) / a2 * (sg[c] * e[f[c] as usize]);
            tsum += sg[c] * t[f[c] as usize];
        }
        if ge.dot(tsum) >= 0.0 {
            continue;
        }
        let xs: Vec<u32> = (0..3)
            .filter_map(|c| {
                edge_crossing(
                    positions,
                    adj,
                    field,
                    min_prominence,
                    found,
                    (f[c], f[(c + 1) % 3]),
                )
            })
            .collect();
        if xs.len() == 2 {
            segs.push((xs[0], xs[1]));
        }
    }
    segs
}

/// The crest point on edge `ab` (found once, then shared): the zero crossing of the extremality,
/// kept where the crest is prominent or, inside a band, near its middle.
fn edge_crossing(
    positions: &[[f32; 3]],
    adj: &crate::mesh::Csr,
    field: &CrestField,
    min_prominence: f32,
    found: &mut CrestPoints,
    (a, b): (u32, u32),
) -> Option<u32> {
    let CrestField {
        k,
        t,
        valid,
        kmin1,
        band,
        e,
    } = field;
    let key = (a.min(b), a.max(b));
    if let Some(&i) = found.index.get(&key) {
        return Some(i);
    }
    let (ai, bi) = (key.0 as usize, key.1 as usize);
    if !(valid[ai] && valid[bi]) {
        return None;
    }
    let s = if t[ai].dot(t[bi]) >= 0.0 { 1.0 } else { -1.0 };
    let (ea, eb) = (e[ai], s * e[bi]);
    if ea * eb >= 0.0 {
        return None;
    }
    let w = ea / (ea - eb);
    // no prominence (constant curvature, e.g. a cylinder's side): no crest
    let kk = k[ai] * (1.0 - w) + k[bi] * w;
    let kring = adj
        .row(ai)
        .iter()
        .chain(adj.row(bi))
        .map(|&v| kmin1[v as usize])
        .fold(f32::INFINITY, f32::min);
    // inside a band the centrality makes the crest: no prominence asked, but only its
    // middle part holds crests (off it, the maxima are the estimate's overshoot at the
    // band's borders, one each side of the true crest)
    let centre = match (band[ai], band[bi]) {
        (Some(ca), Some(cb)) => Some(ca * (1.0 - w) + cb * w),
        _ => None,
    };
    match centre {
        Some(c) if c < BAND_MIDDLE => return None,
        Some(_) => {}
        None if kk - kring < min_prominence * kk => return None,
        None => {}
    }
    let pa = Vec3::from(positions[ai]);
    let pb = Vec3::from(positions[bi]);
    let i = found.points.len() as u32;
    found.points.push(pa.lerp(pb, w).to_array());
    found.edges.push([key.0, key.1]);
    found.k.push(k[ai] * (1.0 - w) + k[bi] * w);
    found.index.insert(key, i);
    Some(i)
}

/// Segments joined through shared crest points into polylines (open chains from points of
/// degree other than two first, then the remaining cycles), each with its strength `∫ |k| ds`.
fn chain_segments(found: &CrestPoints, segs: &[(u32, u32)], kind: CurveKind) -> Vec<Curve> {
    let (points, pedges, pk) = (&found.points, &found.edges, &found.k);
    let np = points.len();
    let mut nb: Vec<Vec<(u32, usize)>> = vec![Vec::new(); np];
    for (si, &(a, b)) in segs.iter().enumerate() {
        nb[a as usize].push((b, si));
        nb[b as usize].push((a, si));
    }
    let mut used = vec![false; segs.len()];
    let mut out = Vec::new();
    for pass in 0..2 {
        for start in 0..np {
            if pass == 0 && nb[start].len() == 2 {
                continue;
            }
            for j in 0..nb[start].len() {
                let (_, s0) = nb[start][j];
                if used[s0] {
                    continue;
                }
                let (path, closed) = walk_segments(segs, &nb, &mut used, start as u32, s0);
                let mut strength = 0.0f32;
                let m = path.len();
                let nseg = if closed { m } else { m - 1 };
                for i in 0..nseg {
                    let (a, b) = (path[i] as usize, path[(i + 1) % m] as usize);
                    let l = Vec3::from(points[a]).distance(Vec3::from(points[b]));
                    strength += 0.5 * (pk[a].abs() + pk[b].abs()) * l;
                }
                out.push(Curve {
                    points: path.iter().map(|&i| points[i as usize]).collect(),
                    edges: path.iter().map(|&i| pedges[i as usize]).collect(),
                    vertices: Vec::new(),
                    strength,
                    kind,
                    closed,
                });
            }
        }
    }
    out
}

/// Walk from crest point `start` along segment `s0` through points of degree two, marking the
/// segments used: the points passed and whether the walk came back to `start`.
fn walk_segments(
    segs: &[(u32, u32)],
    nb: &[Vec<(u32, usize)>],
    used: &mut [bool],
    start: u32,
    s0: usize,
) -> (Vec<u32>, bool) {
    let mut path = vec![start];
    let mut cur = start;
    let mut s = s0;
    loop {
        used[s] = true;
        let (a, b) = segs[s];
        let next = if a == cur { b } else { a };
        if next == start {
            return (path, true);
        }
        path.push(next);
        cur = next;
        let row = &nb[cur as usize];
        if row.len() != 2 {
            return (path, false);
        }
        match row.iter().find(|&&(_, si)| !used[si]) {
            Some(&(_, si)) => s = si,
            None => return (path, false),
        }
    }
}

/// Weight of the band centrality in the crest function: `k (1 + BAND_GAIN c)`, `c` in `[0, 1]`.
const BAND_GAIN: f32 = 1.0;
/// Bands narrower than this many edge lengths are left to the extremality alone.
const BAND_MIN_WIDTH: f32 = 4.0;
/// Crossings inside a band keep only its middle part: centrality at least this.
const BAND_MIDDLE: f32 = 0.75;
/// Steps a band walk takes at most on each side.
const BAND_STEPS: usize = 96;
/// A band's walk ends where `k` falls below this fraction of the start's.
const BAND_DROP: f32 = 0.5;

/// Per vertex, its centrality across a band of high `k`, or `None` outside bands. From each
/// plateau vertex (`flat`: `k` over its two-ring within the prominence, where the extremality is
/// noise), two walks follow `±t` (the curvature line across a fillet: at each step the
/// neighbour furthest along the current direction, `t` re-signed to it) until `k` falls below
/// [`BAND_DROP`] of the start's value; lengths `a` and `b`. A vertex whose walks both end within
/// [`BAND_STEPS`] steps, in a band at least [`BAND_MIN_WIDTH`] of its own edge lengths wide, gets
/// `c = 1 - |a - b| / (a + b)` (1 on the middle line, 0 at the borders). A cylinder's side is
/// no band (walking around it never finds lower `k`); a ridge whose `k` peaks sharply keeps its
/// peak (the centrality only adds `BAND_GAIN` at the middle of its half-width).
fn band_centrality(
    positions: &[[f32; 3]],
    adj: &crate::mesh::Csr,
    k: &[f32],
    t: &[Vec3],
    flat: &[bool],
) -> Vec<Option<f32>> {
    use rayon::prelude::*;
    let n = positions.len();

    let p = |i: usize| Vec3::from(positions[i]);
    let walk = |start: usize, sign: f32| -> Option<f32> {
        let limit = BAND_DROP * k[start];
        let mut cur = start;
        let mut dir = t[start] * sign;
        let mut len = 0.0f32;
        for _ in 0..BAND_STEPS {
            let pc = p(cur);
            let mut best: Option<(f32, usize)> = None;
            for &w in adj.row(cur) {
                let d = p(w as usize) - pc;
                let l = d.length();
                if l <= 0.0 {
                    continue;
                }
                let along = d.dot(dir) / l;
                if along > 0.5 && best.is_none_or(|(b, _)| along > b) {
                    best = Some((along, w as usize));
                }
            }
            let (_, w) = best?;
            let d = p(w) - pc;
            len += d.length();
            if k[w] < limit || !k[w].is_finite() {
                return Some(len - 0.5 * d.length());
            }
            let tw = t[w];
            dir = if tw.dot(dir) >= 0.0 { tw } else { -tw };
            cur = w;
        }
        None
    };
    (0..n)
        .into_par_iter()
        .map(|i| {
            if !flat[i] || k[i] <= 0.0 || t[i].length_squared() < 0.5 {
                return None;
            }
            let a = walk(i, 1.0)?;
            let b = walk(i, -1.0)?;
            // the mean edge length around the vertex
            let row = adj.row(i);
            let h = row
                .iter()
                .map(|&w| p(w as usize).distance(p(i)))
                .sum::<f32>()
                / row.len().max(1) as f32;
            if a + b < BAND_MIN_WIDTH * h {
                return None;
            }
            Some(1.0 - (a - b).abs() / (a + b))
        })
        .collect()
}

/// Nearest end of each point's edge, consecutive duplicates removed.
fn snap(positions: &[[f32; 3]], points: &[[f32; 3]], edges: &[[u32; 2]]) -> Vec<u32> {
    let mut out: Vec<u32> = Vec::with_capacity(points.len());
    for (p, &[a, b]) in points.iter().zip(edges) {
        let p = Vec3::from(*p);
        let v = if p.distance_squared(Vec3::from(positions[a as usize]))
            <= p.distance_squared(Vec3::from(positions[b as usize]))
        {
            a
        } else {
            b
        };
        if out.last() != Some(&v) {
            out.push(v);
        }
    }
    out
}

/// Split a curve where the turn between `p_i - p_{i-2}` and `p_{i+2} - p_i` exceeds the angle
/// (at the local maximum of the turn).
fn break_at_turns(positions: &[[f32; 3]], c: Curve, max_deg: f32) -> Vec<Curve> {
    let m = c.points.len();
    if m < 5 {
        return vec![c];
    }
    let cos_t = max_deg.to_radians().cos();
    let turn = |i: usize| -> f32 {
        let a = Vec3::from(c.points[i]) - Vec3::from(c.points[i - 2]);
        let b = Vec3::from(c.points[i + 2]) - Vec3::from(c.points[i]);
        match (a.try_normalize(), b.try_normalize()) {
            (Some(a), Some(b)) => a.dot(b),
            _ => 1.0,
        }
    };
    let cosv: Vec<f32> = (0..m)
        .map(|i| if i >= 2 && i + 2 < m { turn(i) } else { 1.0 })
        .collect();
    let mut cuts = Vec::new();
    let mut i = 2;
    while i + 2 < m {
        if cosv[i] < cos_t {
            // walk to the sharpest point of this bend
            let mut best = i;
            while best + 1 + 2 < m && cosv[best + 1] < cosv[best] {
                best += 1;
            }
            cuts.push(best);
            i = best + 3;
        } else {
            i += 1;
        }
    }
    if cuts.is_empty() {
        return vec![c];
    }
    let total = c.length().max(1e-20);
    let mut out = Vec::new();
    let mut start = 0;
    for &cut in cuts.iter().chain(std::iter::once(&(m - 1))) {
        if cut <= start {
            continue;
        }
        let pts = c.points[start..=cut].to_vec();
        let eds = c.edges[start..=cut].to_vec();
        let mut piece = Curve {
            points: pts,
            edges: eds,
            vertices: Vec::new(),
            strength: 0.0,
            kind: c.kind,
            closed: false,
        };
        piece.strength = c.strength * piece.length() / total;
        piece.vertices = snap(positions, &piece.points, &piece.edges);
        out.push(piece);
        start = cut;
    }
    out
}

/// Join curve ends closer than `dist` whose continuing tangents differ by less than `deg`
/// (closest pairs first), bridging the snapped paths along mesh edges.
///
/// A join leaves the other ends of both curves as they were, so the closest-first greedy is one
/// pass over the candidate pairs sorted by distance (ends found through a grid of cell `dist`):
/// a pair links when both ends are still free and the curves are not already one chain (a curve
/// never closes on itself here). Then the chains are assembled. `O(m log m)` in the number of
/// ends, where recomputing every pair after each join was cubic (minutes on a rounded box's
/// thousands of crest fragments).
fn join_curves(
    positions: &[[f32; 3]],
    adj: &crate::mesh::Csr,
    curves: Vec<Curve>,
    dist: f32,
    deg: f32,
) -> Vec<Curve> {
    let cos_t = deg.to_radians().cos();
    let m = curves.len();
    let joinable = |c: &Curve| !c.closed && c.points.len() >= 2;
    // end e = 2 c + s (s = 0: the first point, 1: the last): position and outward tangent
    let end = |e: usize| -> (Vec3, Vec3) {
        let c = &curves[e / 2];
        let k = c.points.len();
        let (p, q) = if e % 2 == 1 {
            (c.points[k - 1], c.points[k.saturating_sub(3)])
        } else {
            (c.points[0], c.points[2.min(k - 1)])
        };
        let p = Vec3::from(p);
        (p, (p - Vec3::from(q)).normalize_or_zero())
    };
    let cell = dist.max(1e-12);
    let key = |p: Vec3| (p / cell).floor().as_ivec3();
    let mut grid: HashMap<glam::IVec3, Vec<usize>> = HashMap::new();
    for e in 0..2 * m {
        if joinable(&curves[e / 2]) {
            grid.entry(key(end(e).0)).or_default().push(e);
        }
    }
    let mut pairs: Vec<(f32, usize, usize)> = Vec::new();
    for e in 0..2 * m {
        if !joinable(&curves[e / 2]) {
            continue;
        }
        let (pi, ti) = end(e);
        let k = key(pi);
        for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    let Some(list) = grid.get(&(k + glam::IVec3::new(dx, dy, dz))) else {
                        continue;
                    };
                    for &f in list {
                        if f / 2 <= e / 2 {
                            continue;
                        }
                        let (pj, tj) = end(f);
                        let d = pi.distance(pj);
                        if d > dist {
                            continue;
                        }
                        // the curves continue each other: outward tangents opposite, and the gap
                        // runs along them
                        let ok_t = -ti.dot(tj) > cos_t;
                        let gap = (pj - pi).try_normalize();
                        let ok_g = gap.is_none_or(|g| g.dot(ti) > cos_t && -g.dot(tj) > cos_t);
                        if ok_t && ok_g {
                            pairs.push((d, e, f));
                        }
                    }
                }
            }
        }
    }
    pairs.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)).then(a.2.cmp(&b.2)));
    let mut link: Vec<Option<usize>> = vec![None; 2 * m];
    let mut root: Vec<usize> = (0..m).collect();
    fn find(root: &mut [usize], mut x: usize) -> usize {
        while root[x] != x {
            root[x] = root[root[x]];
            x = root[x];
        }
        x
    }
    for &(_, e, f) in &pairs {
        if link[e].is_some() || link[f].is_some() {
            continue;
        }
        let (a, b) = (find(&mut root, e / 2), find(&mut root, f / 2));
        if a == b {
            continue;
        }
        root[a] = b;
        link[e] = Some(f);
        link[f] = Some(e);
    }
    // assemble: start at a curve with a free end, walk the links
    let mut slots: Vec<Option<Curve>> = curves.into_iter().map(Some).collect();
    let mut out = Vec::new();
    for c in 0..m {
        if slots[c].is_none() {
            continue;
        }
        let free = if link[2 * c].is_none() {
            0
        } else if link[2 * c + 1].is_none() {
            1
        } else {
            // an inner curve of a chain: reached from that chain's first curve
            continue;
        };
        let mut a = slots[c].take().expect("unvisited");
        if free == 1 {
            reverse(&mut a);
        }
        let mut out_end = 2 * c + (1 - free);
        while let Some(f) = link[out_end] {
            let c2 = f / 2;
            let mut b = slots[c2].take().expect("a chain visits each curve once");
            if f % 2 == 1 {
                reverse(&mut b);
            }
            append(positions, adj, &mut a, b);
            out_end = 2 * c2 + (1 - f % 2);
        }
        out.push(a);
    }
    out
}

fn reverse(c: &mut Curve) {
    c.points.reverse();
    c.edges.reverse();
    c.vertices.reverse();
}

/// Append `b` to `a` (`a`'s last point meets `b`'s first), bridging the snapped paths along
/// mesh edges (greedy descent on distance).
fn append(positions: &[[f32; 3]], adj: &crate::mesh::Csr, a: &mut Curve, b: Curve) {
    let from = *a.vertices.last().expect("snapped");
    let to = b.vertices[0];
    let mut cur = from;
    let target = Vec3::from(positions[to as usize]);
    for _ in 0..64 {
        if cur == to {
            break;
        }
        let next = adj
            .row(cur as usize)
            .iter()
            .copied()
            .min_by(|&x, &y| {
                Vec3::from(positions[x as usize])
                    .distance_squared(target)
                    .total_cmp(&Vec3::from(positions[y as usize]).distance_squared(target))
            })
            .unwrap_or(to);
        if Vec3::from(positions[next as usize]).distance_squared(target)
            >= Vec3::from(positions[cur as usize]).distance_squared(target)
        {
            break;
        }
        cur = next;
        if cur != to {
            a.vertices.push(cur);
            a.points.push(positions[cur as usize]);
            a.edges.push([cur, cur]);
        }
    }
    a.points.extend(b.points);
    a.edges.extend(b.edges);
    for v in b.vertices {
        if a.vertices.last() != Some(&v) {
            a.vertices.push(v);
        }
    }
    a.strength += b.strength;
    if a.kind != b.kind {
        a.kind = if a.kind == CurveKind::Crease || b.kind == CurveKind::Crease {
            CurveKind::Crease
        } else {
            a.kind
        };
    }
}
