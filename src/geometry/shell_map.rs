//! Shell maps: the volume between a base surface and an offset of it, cut into tetrahedra, and
//! the piecewise-linear map from texture space (base point, height) into it (Porumbescu et al.
//! 2005, "Shell maps"), with the low-distortion offset of Zhou et al. 2006, "Mesh Quilting",
//! §3.2, eq. (8)-(9).
//!
//! - **Texture space.** Over each base triangle, the right prism of the nominal thickness `H`:
//!   base corners `p_i`, top corners `p_i + H n_f` (`n_f` the unit face normal). A texture
//!   point is (face, barycentric `b`, height fraction `w` in `[0, 1]`).
//! - **Shell space.** The same prism with the top corners at the offset surface `q_i`.
//! - **Tetrahedra.** Every prism is cut into three by the vertex-index rule (corners sorted by
//!   global index `a < b < c`: `[Ba Bb Bc Ta]`, `[Bb Bc Ta Tb]`, `[Bc Ta Tb Tc]`), so a
//!   lateral quad is cut along the same diagonal from both sides and the map is continuous.
//!   [`shell_point`] locates the tetrahedron in closed form and applies its affine map;
//!   [`shell_point_ruled`] interpolates between the base and the offset triangle instead.
//! - **Offset.** [`offset_surface`]: `q_i = p_i + H s_i n_i` along the area-weighted vertex
//!   normal, with `s_i` shortened (x0.8 per round, floor 0.05) at the top corners of every
//!   tetrahedron whose shell volume is not positive (our reading of the paper's "until every
//!   tet has positive volume"). A vertex whose normal points away from one of its faces can
//!   leave tetrahedra inverted even at the floor; [`ShellStretch::inverted`] counts them.
//! - **Stretch, eq. (8)-(9).** Per tetrahedron the Jacobian `J` of the texture -> shell map
//!   (the inverse direction of the paper's `g`, which is what its volume weighting and Sander et
//!   al.'s normalisation fit), `L2(T)^2 = tr(J^T J) / 3`; over the shell
//!   `L2 = sqrt(sum L2(T)^2 |T_t| / sum |T_t|) * (sum |T_t| / sum |T_s|)^(1/3)`. The cube root
//!   (the paper prints a square root, which in 3D leaves `k^(-1/2)` for a uniform scale `k`)
//!   makes a rigid or uniformly scaled shell score exactly 1. It is not a lower bound in 3D: a
//!   shell whose tetrahedra are compressed unevenly (a shortened offset over a concave region)
//!   can score below 1, and compression lowers the measure, which is why the minimisation
//!   keeps every tetrahedron at least half its starting volume.
//! - **Minimisation.** [`minimize_shell_stretch`]: the paper's random line search (after Sander
//!   et al. 2001). Per offset vertex, a random unit direction in its tangent plane; along it the
//!   energy of the incident tetrahedra is an exact quadratic and their volumes are affine, so the
//!   feasible range (every incident tetrahedron keeps at least half its volume ratio) is exact
//!   and a golden-section search on the normalised L2 picks the step. A step is taken only when
//!   it lowers the shell's L2, so the optimisation never raises L2 nor inverts a tetrahedron.
//!   Boundary vertices of an open base stay put (the paper's fixed lateral boundary).

use glam::{Mat3, Vec3};
use rand::{Rng, SeedableRng, rngs::SmallRng};

use crate::mesh::{boundary_loops, vertex_faces};

/// Shell volume ratios at or below this count as inverted.
const MIN_RATIO: f32 = 1e-4;

/// The three tetrahedra of the prism over `face`, as corner indices into
/// `[Ba, Bb, Bc, Ta, Tb, Tc]` with `a < b < c` the face's vertices in index order; also returns
/// that order.
fn prism_order(face: [u32; 3]) -> [u32; 3] {
    let mut s = face;
    s.sort_unstable();
    s
}

/// Corner `k` of the prism over the sorted vertices `s`: `k < 3` base, `k >= 3` top.
const TETS: [[usize; 4]; 3] = [[0, 1, 2, 3], [1, 2, 3, 4], [2, 3, 4, 5]];

fn corners(p: &[[f32; 3]], top: &[[f32; 3]], s: [u32; 3]) -> [Vec3; 6] {
    [
        Vec3::from(p[s[0] as usize]),
        Vec3::from(p[s[1] as usize]),
        Vec3::from(p[s[2] as usize]),
        Vec3::from(top[s[0] as usize]),
        Vec3::from(top[s[1] as usize]),
        Vec3::from(top[s[2] as usize]),
    ]
}

fn edge_matrix(c: &[Vec3; 6], t: [usize; 4]) -> Mat3 {
    let o = c[t[0]];
    Mat3::from_cols(c[t[1]] - o, c[t[2]] - o, c[t[3]] - o)
}

/// The texture prism's corners over `face` in index order: base corners and their lift by `h`
/// along the face normal. `None` for a degenerate face.
fn texture_corners(p: &[[f32; 3]], face: [u32; 3], h: f32) -> Option<[Vec3; 6]> {
    let s = prism_order(face);
    let (a, b, c) = (
        Vec3::from(p[s[0] as usize]),
        Vec3::from(p[s[1] as usize]),
        Vec3::from(p[s[2] as usize]),
    );
    // the normal of the face's own winding, not of the index order
    let [f0, f1, f2] = face.map(|v| Vec3::from(p[v as usize]));
    let n = (f1 - f0).cross(f2 - f0);
    let len = n.length();
    // slivers (area below 1e-6 of the longest edge squared) map with unbounded stretch: skipped
    let longest = (f1 - f0)
        .length_squared()
        .max((f2 - f1).length_squared())
        .max((f0 - f2).length_squared());
    let usable = len > 1e-6 * longest && h > 0.0 && n.is_finite();
    if !usable {
        return None;
    }
    let lift = n / len * h;
    Some([a, b, c, a + lift, b + lift, c + lift])
}

/// A point of the shell: face `f`, barycentric `b` (in the face's corner order, extrapolated
/// affinely when outside the triangle) and height fraction `w` (0 on the base, 1 on the
/// offset surface `top`), through the tetrahedron that contains it.
pub fn shell_point(
    p: &[[f32; 3]],
    top: &[[f32; 3]],
    faces: &[[u32; 3]],
    f: u32,
    b: [f32; 3],
    w: f32,
) -> Vec3 {
    let face = faces[f as usize];
    // barycentric coordinates in index order
    let mut idx = [0usize, 1, 2];
    idx.sort_unstable_by_key(|&k| face[k]);
    let s = idx.map(|k| face[k]);
    let beta = idx.map(|k| b[k]);
    let c = corners(p, top, s);
    // the piece by the raw coordinates: the pieces agree where they meet, so the map stays
    // continuous when extrapolated past the triangle
    if w <= beta[0] {
        c[0] * (beta[0] - w) + c[1] * beta[1] + c[2] * beta[2] + c[3] * w
    } else if w <= beta[0] + beta[1] {
        let e = w - beta[0];
        c[3] * beta[0] + c[1] * (beta[1] - e) + c[2] * beta[2] + c[4] * e
    } else {
        let e = w - beta[0] - beta[1];
        c[3] * beta[0] + c[4] * beta[1] + c[2] * (beta[2] - e) + c[5] * e
    }
}

/// The ruled shell point: `sum b_i ((1 - w) p_i + w q_i)`, linear along every segment from a
/// base point to its offset and smooth inside a prism (the tetrahedral map [`shell_point`]
/// bends along the prism's internal faces). Agrees with [`shell_point`] on the base, on the
/// offset surface and along every vertical edge.
pub fn shell_point_ruled(
    p: &[[f32; 3]],
    top: &[[f32; 3]],
    faces: &[[u32; 3]],
    f: u32,
    b: [f32; 3],
    w: f32,
) -> Vec3 {
    let c = faces[f as usize];
    let mut out = Vec3::ZERO;
    for k in 0..3 {
        let v = c[k] as usize;
        out += (Vec3::from(p[v]) * (1.0 - w) + Vec3::from(top[v]) * w) * b[k];
    }
    out
}

/// Per tetrahedron of every prism: the inverse texture edge matrix and its determinant (six
/// times the signed texture volume; 0 for a skipped sliver).
struct TextureTets {
    inv: Vec<Mat3>,
    det: Vec<f32>,
}

impl TextureTets {
    /// Texture volume of tetrahedron `ti`.
    fn vol(&self, ti: usize) -> f32 {
        self.det[ti].abs() / 6.0
    }
}

fn texture_tets(p: &[[f32; 3]], faces: &[[u32; 3]], h: f32) -> TextureTets {
    let mut inv = Vec::with_capacity(faces.len() * 3);
    let mut det = Vec::with_capacity(faces.len() * 3);
    for &f in faces {
        let c = texture_corners(p, f, h);
        for t in TETS {
            let (i, d) = c
                .map(|c| {
                    let e = edge_matrix(&c, t).as_dmat3();
                    (e.inverse().as_mat3(), e.determinant())
                })
                .filter(|(i, d)| i.is_finite() && d.is_finite() && *d != 0.0)
                .unwrap_or((Mat3::ZERO, 0.0));
            inv.push(i);
            det.push(d as f32);
        }
    }
    TextureTets { inv, det }
}

/// Shell volume over texture volume of every tetrahedron (NaN where the texture tetrahedron
/// is skipped).
fn volume_ratios(
    p: &[[f32; 3]],
    top: &[[f32; 3]],
    faces: &[[u32; 3]],
    tex: &TextureTets,
) -> Vec<f32> {
    let mut out = Vec::with_capacity(faces.len() * 3);
    for (fi, &f) in faces.iter().enumerate() {
        let c = corners(p, top, prism_order(f));
        for (k, t) in TETS.iter().enumerate() {
            let d = tex.det[3 * fi + k];
            out.push(if d == 0.0 {
                f32::NAN
            } else {
                edge_matrix(&c, *t).determinant() / d
            });
        }
    }
    out
}

/// A volume ratio that counts as inverted.
fn is_inverted(r: f32) -> bool {
    r.is_nan() || r <= MIN_RATIO
}

/// The offset surface `q_i = p_i + H s_i n_i`, with `s_i` starting at `scale` (1 where `None`)
/// and shortened at the top corners of inverted tetrahedra until none is left (or every such
/// corner is at the floor of 0.05). Returns the offset and the final scales.
pub fn offset_surface(
    p: &[[f32; 3]],
    faces: &[[u32; 3]],
    normals: &[[f32; 3]],
    thickness: f32,
    scale: Option<&[f32]>,
    keep_positive: bool,
) -> (Vec<[f32; 3]>, Vec<f32>) {
    let n = p.len();
    let mut s: Vec<f32> = match scale {
        Some(sc) => sc.iter().map(|x| x.clamp(0.05, 1.0)).collect(),
        None => vec![1.0; n],
    };
    let lift = |i: usize, s: f32| -> [f32; 3] {
        (Vec3::from(p[i]) + Vec3::from(normals[i]) * (thickness * s)).to_array()
    };
    let mut top: Vec<[f32; 3]> = (0..n).map(|i| lift(i, s[i])).collect();
    if !keep_positive || thickness.is_nan() || thickness <= 0.0 {
        return (top, s);
    }
    let tex = texture_tets(p, faces, thickness);
    let mut shrink = vec![false; n];
    for _round in 0..40 {
        shrink.iter_mut().for_each(|x| *x = false);
        let mut any = false;
        let ratios = volume_ratios(p, &top, faces, &tex);
        for (fi, &f) in faces.iter().enumerate() {
            let so = prism_order(f);
            for (k, t) in TETS.iter().enumerate() {
                let ti = 3 * fi + k;
                if tex.det[ti] == 0.0 || !is_inverted(ratios[ti]) {
                    continue;
                }
                for &corner in t.iter().filter(|&&c| c >= 3) {
                    let v = so[corner - 3] as usize;
                    if s[v] > 0.05 {
                        shrink[v] = true;
                        any = true;
                    }
                }
            }
        }
        if !any {
            break;
        }
        for i in 0..n {
            if shrink[i] {
                s[i] = (s[i] * 0.8).max(0.05);
                top[i] = lift(i, s[i]);
            }
        }
    }
    (top, s)
}

/// Eq. (8)-(9) over a whole shell.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ShellStretch {
    /// Normalised L2 stretch (1 for a rigid or uniformly scaled shell).
    pub l2: f64,
    /// Tetrahedra whose shell volume is not positive.
    pub inverted: usize,
}

/// Sums for the normalised L2: `sum L2(T)^2 |T_t|`, `sum |T_t|`, `sum |T_s|` (signed).
#[derive(Clone, Copy, Default)]
struct Sums {
    energy: f64,
    tex: f64,
    shell: f64,
}

impl Sums {
    fn l2(&self) -> f64 {
        if self.tex <= 0.0 || self.shell <= 0.0 {
            return f64::INFINITY;
        }
        (self.energy / self.tex).sqrt() * (self.tex / self.shell).cbrt()
    }
}

/// L2 stretch of one tetrahedron's texture -> shell map (squared) and its shell/texture volume
/// ratio.
fn tet_terms(c: &[Vec3; 6], t: [usize; 4], inv: &Mat3, det_t: f32) -> (f32, f32) {
    let es = edge_matrix(c, t);
    let j = es * *inv;
    let fro = j.x_axis.length_squared() + j.y_axis.length_squared() + j.z_axis.length_squared();
    (fro / 3.0, es.determinant() / det_t)
}

fn sums(p: &[[f32; 3]], top: &[[f32; 3]], faces: &[[u32; 3]], tex: &TextureTets) -> (Sums, usize) {
    let mut out = Sums::default();
    let mut inverted = 0;
    for (fi, &f) in faces.iter().enumerate() {
        let so = prism_order(f);
        let c = corners(p, top, so);
        for (k, t) in TETS.iter().enumerate() {
            let ti = 3 * fi + k;
            if tex.det[ti] == 0.0 {
                continue;
            }
            let (l2sq, r) = tet_terms(&c, *t, &tex.inv[ti], tex.det[ti]);
            if is_inverted(r) {
                inverted += 1;
            }
            let v = tex.vol(ti) as f64;
            out.energy += l2sq as f64 * v;
            out.tex += v;
            out.shell += r as f64 * v;
        }
    }
    (out, inverted)
}

/// Eq. (8)-(9): the normalised L2 stretch of the shell between `p` and `top` against texture
/// prisms of height `thickness`.
pub fn shell_stretch(
    p: &[[f32; 3]],
    top: &[[f32; 3]],
    faces: &[[u32; 3]],
    thickness: f32,
) -> ShellStretch {
    let tex = texture_tets(p, faces, thickness);
    let (s, inverted) = sums(p, top, faces, &tex);
    ShellStretch {
        l2: s.l2(),
        inverted,
    }
}

/// What [`minimize_shell_stretch`] did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct StretchReport {
    /// Normalised L2 before.
    pub before: f64,
    /// Normalised L2 after.
    pub after: f64,
    /// Sweeps run.
    pub sweeps: usize,
    /// Line-search steps taken.
    pub moves: usize,
    /// Tetrahedra inverted at the end ([`ShellStretch::inverted`]).
    pub inverted: usize,
}

/// Moves the offset vertices `top` in their tangent planes (normal `normals[i]`) to lower the
/// shell's normalised L2 stretch: at most `sweeps` sweeps of one random line search per
/// vertex, stopping early when a sweep gains less than 1e-4 relative. Never raises L2, never
/// makes a tetrahedron's volume ratio fall below half of what it was before the first sweep
/// (nor below the inversion threshold).
///
/// The steps: [`boundary_vertices`] (held fixed), [`ratio_floors`] (the lowest volume ratio each
/// tetrahedron may reach), then per sweep and vertex, a random tangent direction,
/// [`line_terms`] (the incident tetrahedra's energy and volume along it), [`feasible_range`],
/// and [`golden_section`] on the shell's L2, taking the step where it lowers L2.
pub fn minimize_shell_stretch(
    p: &[[f32; 3]],
    faces: &[[u32; 3]],
    normals: &[[f32; 3]],
    top: &mut [[f32; 3]],
    thickness: f32,
    sweeps: usize,
    seed: u64,
) -> StretchReport {
    let n = p.len();
    let tex = texture_tets(p, faces, thickness);
    let (mut total, inverted) = sums(p, top, faces, &tex);
    let before = total.l2();
    let mut report = StretchReport {
        before,
        after: before,
        sweeps: 0,
        moves: 0,
        inverted,
    };
    if !before.is_finite() || n == 0 {
        return report;
    }
    let vf = vertex_faces(n, faces);
    let fixed = boundary_vertices(n, faces);
    let floor = ratio_floors(p, top, faces, &tex);
    let mut rng = SmallRng::seed_from_u64(seed);
    let mut lines: Vec<LineTerm> = Vec::new();
    for _ in 0..sweeps {
        report.sweeps += 1;
        let start = total.l2();
        for i in 0..n {
            if fixed[i] {
                continue;
            }
            let ni = Vec3::from(normals[i]).normalize_or_zero();
            if ni == Vec3::ZERO {
                continue;
            }
            let (u, v) = ni.any_orthonormal_pair();
            let a: f32 = rng.random_range(0.0..std::f32::consts::TAU);
            let d = u * a.cos() + v * a.sin();
            let shell = ShellView {
                p,
                top,
                faces,
                tex: &tex,
                floor: &floor,
            };
            let Some(reach) = line_terms(&shell, vf.row(i), i, d, &mut lines) else {
                continue;
            };
            let Some((lo, hi)) = feasible_range(&lines, reach) else {
                continue;
            };
            let (e_loc0, v_loc0) = lines.iter().fold((0.0f64, 0.0f64), |(e, v), l| {
                (e + (l.e0 * l.w) as f64, v + (l.r0 * l.w) as f64)
            });
            let objective = |t: f32| -> f64 {
                let (e, v) = local_sums(&lines, t);
                Sums {
                    energy: total.energy - e_loc0 + e,
                    tex: total.tex,
                    shell: total.shell - v_loc0 + v,
                }
                .l2()
            };
            let (t, ft) = golden_section(lo, hi, objective);
            let f0 = total.l2();
            if ft < f0 * (1.0 - 1e-9) && t != 0.0 {
                let (e, v) = local_sums(&lines, t);
                total.energy += e - e_loc0;
                total.shell += v - v_loc0;
                top[i] = (Vec3::from(top[i]) + d * t).to_array();
                report.moves += 1;
            }
        }
        // re-sum to shed rounding drift
        (total, report.inverted) = sums(p, top, faces, &tex);
        let end = total.l2();
        if (start - end).is_nan() || start - end <= 1e-4 * start {
            break;
        }
    }
    report.after = total.l2();
    report
}

/// Vertices on the base's boundary loops (the paper's fixed lateral boundary).
fn boundary_vertices(n: usize, faces: &[[u32; 3]]) -> Vec<bool> {
    let mut fixed = vec![false; n];
    for lp in boundary_loops(faces) {
        for v in lp {
            fixed[v as usize] = true;
        }
    }
    fixed
}

/// Each tetrahedron's lowest allowed volume ratio: half its ratio at the start (at least twice
/// the inversion threshold, at most the ratio), or the ratio itself where already inverted.
fn ratio_floors(
    p: &[[f32; 3]],
    top: &[[f32; 3]],
    faces: &[[u32; 3]],
    tex: &TextureTets,
) -> Vec<f32> {
    volume_ratios(p, top, faces, tex)
        .into_iter()
        .map(|r| {
            if r > MIN_RATIO {
                (0.5 * r).max(2.0 * MIN_RATIO).min(r)
            } else {
                r
            }
        })
        .collect()
}

/// The shell as the line search reads it.
struct ShellView<'a> {
    p: &'a [[f32; 3]],
    top: &'a [[f32; 3]],
    faces: &'a [[u32; 3]],
    tex: &'a TextureTets,
    /// Per tetrahedron, its lowest allowed volume ratio.
    floor: &'a [f32],
}

/// One incident tetrahedron along a line `top[i] + t d`: energy `e0 + t e1 + t^2 e2`, volume
/// ratio `r0 + t r1` with its floor, and its texture volume `w`.
struct LineTerm {
    e0: f32,
    e1: f32,
    e2: f32,
    r0: f32,
    r1: f32,
    floor: f32,
    w: f32,
}

/// The terms of the tetrahedra incident to offset vertex `i` (faces `incident`) along direction
/// `d`, into `lines`; returns the step bound (half the mean distance from the vertex to its
/// faces' corners), or `None` where there is nothing to move.
fn line_terms(
    shell: &ShellView,
    incident: &[u32],
    i: usize,
    d: Vec3,
    lines: &mut Vec<LineTerm>,
) -> Option<f32> {
    let (p, top, faces, tex) = (shell.p, shell.top, shell.faces, shell.tex);
    let mut reach = 0.0f32;
    let mut count = 0;
    lines.clear();
    for &f in incident {
        let fi = f as usize;
        let so = prism_order(faces[fi]);
        let slot = so.iter().position(|&x| x as usize == i).unwrap_or(0) + 3;
        let c = corners(p, top, so);
        for k in 0..3 {
            reach += (c[k] - c[slot - 3]).length();
            count += 1;
        }
        let mut c1 = c;
        c1[slot] += d;
        for (k, t) in TETS.iter().enumerate() {
            if !t.contains(&slot) {
                continue;
            }
            let ti = 3 * fi + k;
            if tex.det[ti] == 0.0 {
                continue;
            }
            let inv = tex.inv[ti];
            let j0 = edge_matrix(&c, *t) * inv;
            let j1 = edge_matrix(&c1, *t) * inv - j0;
            let dot = |a: &Mat3, b: &Mat3| {
                a.x_axis.dot(b.x_axis) + a.y_axis.dot(b.y_axis) + a.z_axis.dot(b.z_axis)
            };
            let r0 = edge_matrix(&c, *t).determinant() / tex.det[ti];
            let r1 = edge_matrix(&c1, *t).determinant() / tex.det[ti] - r0;
            lines.push(LineTerm {
                e0: dot(&j0, &j0) / 3.0,
                e1: 2.0 * dot(&j0, &j1) / 3.0,
                e2: dot(&j1, &j1) / 3.0,
                r0,
                r1,
                floor: shell.floor[ti].min(r0),
                w: tex.vol(ti),
            });
        }
    }
    if lines.is_empty() || count == 0 {
        return None;
    }
    Some(0.5 * reach / count as f32)
}

/// The steps `[lo, hi]` within `±reach` that keep every ratio above its floor (compression pays
/// in the texture -> shell stretch, so without a floor the search would flatten tetrahedra), or,
/// if already below, do not lower it; `None` where no step is allowed.
fn feasible_range(lines: &[LineTerm], reach: f32) -> Option<(f32, f32)> {
    let (mut lo, mut hi) = (-reach, reach);
    for l in lines {
        // r0 + t r1 >= floor
        if l.r1 > 0.0 {
            lo = lo.max((l.floor - l.r0) / l.r1);
        } else if l.r1 < 0.0 {
            hi = hi.min((l.floor - l.r0) / l.r1);
        }
    }
    if lo >= 0.0 || hi <= 0.0 || lo.is_nan() || hi.is_nan() {
        lo = lo.min(0.0);
        hi = hi.max(0.0);
        if hi <= lo || hi.is_nan() || lo.is_nan() {
            return None;
        }
    }
    Some((lo, hi))
}

/// The incident tetrahedra's weighted energy and shell volume at step `t`.
fn local_sums(lines: &[LineTerm], t: f32) -> (f64, f64) {
    let (mut e, mut v) = (0.0f64, 0.0f64);
    for l in lines {
        e += ((l.e0 + t * (l.e1 + t * l.e2)) * l.w) as f64;
        v += ((l.r0 + t * l.r1) * l.w) as f64;
    }
    (e, v)
}

/// Golden-section search (30 steps) for the minimum of `objective` on `[lo, hi]`: the step and
/// its value.
fn golden_section(lo: f32, hi: f32, objective: impl Fn(f32) -> f64) -> (f32, f64) {
    let g = 0.618_034f32;
    let (mut a0, mut b0) = (lo, hi);
    let mut x1 = b0 - g * (b0 - a0);
    let mut x2 = a0 + g * (b0 - a0);
    let (mut f1, mut f2) = (objective(x1), objective(x2));
    for _ in 0..30 {
        if f1 < f2 {
            b0 = x2;
            x2 = x1;
            f2 = f1;
            x1 = b0 - g * (b0 - a0);
            f1 = objective(x1);
        } else {
            a0 = x1;
            x1 = x2;
            f1 = f2;
            x2 = a0 + g * (b0 - a0);
            f2 = objective(x2);
        }
    }
    if f1 < f2 { (x1, f1) } else { (x2, f2) }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::vertex_normals;
    use crate::testdata::uv_sphere;

    fn grid(nx: usize, ny: usize, bump: f32) -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
        let mut p = Vec::new();
        for j in 0..=ny {
            for i in 0..=nx {
                let (x, y) = (i as f32 / nx as f32, j as f32 / ny as f32);
                let z =
                    bump * (std::f32::consts::TAU * x).sin() * (std::f32::consts::TAU * y).cos();
                p.push([x, y, z]);
            }
        }
        let mut f = Vec::new();
        let w = nx as u32 + 1;
        for j in 0..ny as u32 {
            for i in 0..nx as u32 {
                let a = j * w + i;
                f.push([a, a + 1, a + w + 1]);
                f.push([a, a + w + 1, a + w]);
            }
        }
        (p, f)
    }

    #[test]
    fn a_flat_base_with_a_translated_offset_has_stretch_one() {
        let (p, f) = grid(6, 5, 0.0);
        let n = vertex_normals(&p, &f);
        let (top, _) = offset_surface(&p, &f, &n, 0.1, None, true);
        let st = shell_stretch(&p, &top, &f, 0.1);
        assert_eq!(st.inverted, 0);
        assert!((st.l2 - 1.0).abs() < 1e-5, "{st:?}");
        // a uniformly scaled shell (thicker offset) scores above 1
        let (top2, _) = offset_surface(&p, &f, &n, 0.2, None, true);
        let st2 = shell_stretch(&p, &top2, &f, 0.1);
        assert!(st2.l2 > 1.01, "{st2:?}");
    }

    #[test]
    fn shell_points_interpolate_the_prism_and_agree_across_faces() {
        let (p, f) = grid(4, 4, 0.2);
        let n = vertex_normals(&p, &f);
        let (top, _) = offset_surface(&p, &f, &n, 0.05, None, true);
        for (fi, face) in f.iter().enumerate() {
            for k in 0..3 {
                let mut b = [0.0; 3];
                b[k] = 1.0;
                let v = face[k] as usize;
                for w in [0.0, 0.4, 1.0] {
                    let a = shell_point(&p, &top, &f, fi as u32, b, w);
                    let r = shell_point_ruled(&p, &top, &f, fi as u32, b, w);
                    let want = Vec3::from(p[v]).lerp(Vec3::from(top[v]), w);
                    assert!(a.distance(want) < 1e-6 && r.distance(want) < 1e-6);
                }
            }
        }
        // face 0 = [0, 1, 6] and face 3 = [1, 7, 6] share the edge 1-6, which sits at index
        // positions (1, 2) in the first and (0, 1) in the second: a point on it maps to the
        // same place from both sides at any height
        assert_eq!((f[0], f[3]), ([0, 1, 6], [1, 7, 6]));
        for w in [0.0, 0.3, 0.7, 1.0] {
            for t in [0.2f32, 0.5, 0.9] {
                let a = shell_point(&p, &top, &f, 0, [0.0, 1.0 - t, t], w);
                let b = shell_point(&p, &top, &f, 3, [1.0 - t, 0.0, t], w);
                assert!(a.distance(b) < 1e-5, "w {w} t {t}: {a} vs {b}");
            }
        }
    }

    #[test]
    fn the_closed_form_location_matches_barycentric_coordinates_in_the_tetrahedra() {
        // a texture point (b, w) lies in one of the prism's three texture tetrahedra; its
        // barycentric coordinates there, applied to the shell tetrahedron, are the shell point
        let (p, f) = grid(3, 3, 0.3);
        let n = vertex_normals(&p, &f);
        let h = 0.2;
        let (mut top, _) = offset_surface(&p, &f, &n, h, None, false);
        let mut rng = SmallRng::seed_from_u64(7);
        for q in &mut top {
            for x in q.iter_mut() {
                *x += rng.random_range(-0.03..0.03);
            }
        }
        let mut checked = 0;
        for (fi, &face) in f.iter().enumerate() {
            let tex = texture_corners(&p, face, h).expect("face");
            let shell = corners(&p, &top, prism_order(face));
            let mut idx = [0usize, 1, 2];
            idx.sort_unstable_by_key(|&k| face[k]);
            for _ in 0..20 {
                let (u, v): (f32, f32) = (rng.random_range(0.0..1.0), rng.random_range(0.0..1.0));
                let (u, v) = if u + v > 1.0 {
                    (1.0 - u, 1.0 - v)
                } else {
                    (u, v)
                };
                let b = [1.0 - u - v, u, v];
                let w: f32 = rng.random_range(0.0..1.0);
                // the texture point, with corners in index order
                let bs = idx.map(|k| b[k]);
                let x = tex[0] * bs[0] + tex[1] * bs[1] + tex[2] * bs[2] + (tex[3] - tex[0]) * w;
                let got = shell_point(&p, &top, &f, fi as u32, b, w);
                let mut found = false;
                for t in TETS {
                    let l = edge_matrix(&tex, t).inverse() * (x - tex[t[0]]);
                    let l0 = 1.0 - l.x - l.y - l.z;
                    if l0.min(l.min_element()) < -1e-4 {
                        continue;
                    }
                    let want = shell[t[0]] + edge_matrix(&shell, t) * l;
                    assert!(got.distance(want) < 1e-4, "{got} vs {want}");
                    found = true;
                }
                assert!(found);
                checked += 1;
            }
        }
        assert_eq!(checked, 20 * f.len());
    }

    #[test]
    fn inverted_tets_in_concave_regions_are_shortened_away() {
        // inside of a unit sphere (normals to the centre), offset thicker than the radius: the
        // plain offset crosses the centre and inverts its tetrahedra
        let (sp, mut f) = uv_sphere(12, 24);
        for t in &mut f {
            t.swap(1, 2);
        }
        let n = vertex_normals(&sp, &f);
        let (raw, _) = offset_surface(&sp, &f, &n, 1.5, None, false);
        assert!(shell_stretch(&sp, &raw, &f, 1.5).inverted > 0);
        let (top, sc) = offset_surface(&sp, &f, &n, 1.5, None, true);
        assert_eq!(shell_stretch(&sp, &top, &f, 1.5).inverted, 0);
        assert!(sc.iter().all(|x| (0.05..=1.0).contains(x)));
        assert!(sc.iter().filter(|&&x| x < 1.0).count() * 2 > sc.len());
        for q in &top {
            assert!(Vec3::from(*q).length() > 0.0);
        }
    }

    #[test]
    fn minimisation_lowers_stretch_and_keeps_every_tet_positive() {
        let (p, f) = grid(16, 16, 0.15);
        let n = vertex_normals(&p, &f);
        let h = 0.1;
        let (mut top, _) = offset_surface(&p, &f, &n, h, None, true);
        let before = shell_stretch(&p, &top, &f, h);
        assert_eq!(before.inverted, 0);
        let rep = minimize_shell_stretch(&p, &f, &n, &mut top, h, 10, 3);
        let after = shell_stretch(&p, &top, &f, h);
        assert_eq!(after.inverted, 0);
        assert!((rep.before - before.l2).abs() < 1e-6 * before.l2);
        assert!(
            (rep.after - after.l2).abs() < 1e-4 * after.l2,
            "{rep:?} {after:?}"
        );
        eprintln!("{before:?} -> {after:?} {rep:?}");
        assert!(after.l2 < before.l2 - 1e-3, "{before:?} -> {after:?}");
        assert!(after.l2.is_finite());
        // boundary vertices stay where they were
        let (plain, _) = offset_surface(&p, &f, &n, h, None, true);
        for i in 0..=16 {
            assert_eq!(top[i], plain[i]);
        }
    }
}
