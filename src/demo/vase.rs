//! The demo vase: a closed lathe (surface of revolution) with a foot, a wall of finite
//! thickness and a rounded lip, painted with a Greek-style band pattern on its upper part only.

use crate::mesh::TriMesh;
use std::f32::consts::TAU;

/// Height of the vase.
const H: f32 = 1.0;
/// Wall thickness.
const T: f32 = 0.026;
/// Height of the inner floor.
const FLOOR: f32 = 0.07;
/// Lowest height of the painted zone on the outside (the upper 40%).
pub(crate) const PAINT_FROM: f32 = 0.6 * H;
/// Segments around the axis.
const SEGS: usize = 144;
/// Target spacing of profile samples.
const DS: f32 = 0.0095;

/// Outer radius at height `y`: non-uniform Catmull-Rom through hand-placed control points.
fn outer_radius(y: f32) -> f32 {
    const CP: [(f32, f32); 11] = [
        (0.0, 0.165),
        (0.04, 0.168),
        (0.09, 0.135),
        (0.20, 0.225),
        (0.36, 0.292),
        (0.52, 0.268),
        (0.66, 0.185),
        (0.78, 0.128),
        (0.88, 0.135),
        (0.96, 0.170),
        (1.0, 0.192),
    ];
    let y = y.clamp(0.0, 1.0);
    let i = CP
        .iter()
        .rposition(|c| c.0 <= y)
        .unwrap_or(0)
        .min(CP.len() - 2);
    let (y0, r0) = CP[i];
    let (y1, r1) = CP[i + 1];
    let slope = |a: usize, b: usize| (CP[b].1 - CP[a].1) / (CP[b].0 - CP[a].0);
    let m0 = if i == 0 {
        slope(0, 1)
    } else {
        slope(i - 1, i + 1)
    };
    let m1 = if i + 2 >= CP.len() {
        slope(i, i + 1)
    } else {
        slope(i, i + 2)
    };
    let h = y1 - y0;
    let t = (y - y0) / h;
    let (t2, t3) = (t * t, t * t * t);
    (2.0 * t3 - 3.0 * t2 + 1.0) * r0
        + (t3 - 2.0 * t2 + t) * h * m0
        + (-2.0 * t3 + 3.0 * t2) * r1
        + (t3 - t2) * h * m1
}

/// Which part of the profile a sample lies on (decides painting).
#[derive(Clone, Copy, PartialEq)]
enum Part {
    Base,
    Outer,
    Lip,
    Inner,
}

/// The closed profile from the bottom centre, out along the base, up the outside, over the lip,
/// down the inside and in along the floor to the inner centre: `(radius, height, part)`.
fn profile() -> Vec<(f32, f32, Part)> {
    let mut dense = Vec::new();
    let c = 0.012;
    let r0 = outer_radius(0.0);
    let n = 400;
    for i in 0..n {
        dense.push(((r0 - c) * i as f32 / n as f32, 0.0, Part::Base));
    }
    for i in 0..=20 {
        let a = -std::f32::consts::FRAC_PI_2 + std::f32::consts::FRAC_PI_2 * i as f32 / 20.0;
        // Follow the outer radius at the corner's end so the wall joins without a step.
        let rr = r0 - c + c * a.cos();
        dense.push((rr, c + c * a.sin(), Part::Base));
    }
    for i in 1..=2000 {
        let y = c + (H - c) * i as f32 / 2000.0;
        dense.push((outer_radius(y), y, Part::Outer));
    }
    let rh = outer_radius(H);
    for i in 1..40 {
        let a = std::f32::consts::PI * i as f32 / 40.0;
        dense.push((
            rh - T * 0.5 + T * 0.5 * a.cos(),
            H + T * 0.5 * a.sin(),
            Part::Lip,
        ));
    }
    for i in 0..=2000 {
        let y = H - (H - FLOOR - c) * i as f32 / 2000.0;
        dense.push((outer_radius(y) - T, y, Part::Inner));
    }
    let ri = outer_radius(FLOOR + c) - T;
    for i in 1..=20 {
        let a = std::f32::consts::PI * i as f32 / 40.0;
        dense.push((ri - c + c * a.cos(), FLOOR + c - c * a.sin(), Part::Inner));
    }
    for i in 1..=n {
        dense.push(((ri - c) * (1.0 - i as f32 / n as f32), FLOOR, Part::Inner));
    }
    // Resample by arc length.
    let mut len = vec![0.0f32; dense.len()];
    for i in 1..dense.len() {
        let (a, b) = (dense[i - 1], dense[i]);
        len[i] = len[i - 1] + ((b.0 - a.0).powi(2) + (b.1 - a.1).powi(2)).sqrt();
    }
    let total = len[dense.len() - 1];
    let m = (total / DS).round() as usize;
    let mut out = Vec::with_capacity(m + 1);
    let mut j = 0;
    for i in 0..=m {
        let s = total * i as f32 / m as f32;
        while j + 2 < dense.len() && len[j + 1] < s {
            j += 1;
        }
        let t = ((s - len[j]) / (len[j + 1] - len[j]).max(1e-12)).clamp(0.0, 1.0);
        let (a, b) = (dense[j], dense[j + 1]);
        out.push((
            a.0 + (b.0 - a.0) * t,
            a.1 + (b.1 - a.1) * t,
            if t < 0.5 { a.2 } else { b.2 },
        ));
    }
    out[0].0 = 0.0;
    out[m].0 = 0.0;
    out
}

/// Smoothstep.
#[inline]
fn smoothstep(e0: f32, e1: f32, x: f32) -> f32 {
    let t = ((x - e0) / (e1 - e0)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// Greek-style band pattern at angle `theta` and height `y` (sRGB): terracotta ground, black
/// rules, a black zigzag band, a row of cream dots and black wave crests under a black rim.
fn painted_color(theta: f32, y: f32) -> [f32; 3] {
    const GROUND: [f32; 3] = [0.80, 0.42, 0.20];
    const BLACK: [f32; 3] = [0.09, 0.07, 0.06];
    const CREAM: [f32; 3] = [0.94, 0.86, 0.68];
    let aa = 0.004;
    let band = |lo: f32, hi: f32| {
        smoothstep(lo - aa, lo + aa, y) * (1.0 - smoothstep(hi - aa, hi + aa, y))
    };
    let mut black: f32 = 0.0;
    // Rules.
    black = black
        .max(band(0.615, 0.635))
        .max(band(0.745, 0.755))
        .max(band(0.815, 0.83));
    // Zigzag between the first two rules.
    let u = theta / TAU * 12.0;
    let tri = 2.0 * (u - u.floor() - 0.5).abs();
    let zig = 0.655 + 0.07 * tri;
    black = black.max(1.0 - smoothstep(0.011 - aa, 0.011 + aa, (y - zig).abs()));
    // Black tongues hanging from a rule below the rim.
    let w = theta / TAU * 16.0;
    let tongue = 0.90 - 0.045 * (std::f32::consts::PI * (w - w.floor())).sin();
    black = black
        .max(band(tongue, 0.93))
        .max(band(0.925, 0.94))
        .max(band(0.975, 2.0));
    let mut c: [f32; 3] = std::array::from_fn(|k| GROUND[k] + (BLACK[k] - GROUND[k]) * black);
    // Cream dots between the second and third rule.
    let v = theta / TAU * 36.0;
    let du = (v - v.floor() - 0.5) * TAU / 36.0 * outer_radius(y);
    let dist = (du * du + (y - 0.785).powi(2)).sqrt();
    let dot = 1.0 - smoothstep(0.011 - aa, 0.011 + aa, dist);
    for k in 0..3 {
        c[k] += (CREAM[k] - c[k]) * dot;
    }
    c
}

/// The vase mesh and which vertices are painted (see the module doc).
pub(crate) fn vase_with_mask() -> (TriMesh, Vec<bool>) {
    const CLAY: [f32; 3] = [0.70, 0.66, 0.60];
    let prof = profile();
    let m = prof.len();
    let rings = m - 2;
    let nv = 2 + rings * SEGS;
    let mut pos = Vec::with_capacity(nv);
    let mut col = Vec::with_capacity(nv);
    let mut mask = Vec::with_capacity(nv);
    let paint = |part: Part, y: f32| match part {
        Part::Outer => y >= PAINT_FROM,
        Part::Lip => true,
        Part::Inner => y >= H - 0.06,
        Part::Base => false,
    };
    pos.push([0.0, prof[0].1, 0.0]);
    col.push(CLAY);
    mask.push(false);
    for &(r, y, part) in &prof[1..m - 1] {
        let painted = paint(part, y);
        for s in 0..SEGS {
            let th = TAU * s as f32 / SEGS as f32;
            pos.push([r * th.cos(), y, r * th.sin()]);
            mask.push(painted);
            col.push(if painted {
                if part == Part::Outer {
                    painted_color(th, y)
                } else {
                    [0.09, 0.07, 0.06]
                }
            } else {
                CLAY
            });
        }
    }
    pos.push([0.0, prof[m - 1].1, 0.0]);
    col.push(CLAY);
    mask.push(false);
    let last = (nv - 1) as u32;
    let ring = |i: usize, s: usize| (1 + i * SEGS + s % SEGS) as u32;
    let mut faces = Vec::with_capacity(2 * rings * SEGS);
    for s in 0..SEGS {
        faces.push([0, ring(0, s + 1), ring(0, s)]);
    }
    for i in 0..rings - 1 {
        for s in 0..SEGS {
            let (a, b, c, d) = (
                ring(i, s),
                ring(i, s + 1),
                ring(i + 1, s),
                ring(i + 1, s + 1),
            );
            faces.push([a, b, d]);
            faces.push([a, d, c]);
        }
    }
    for s in 0..SEGS {
        faces.push([last, ring(rings - 1, s), ring(rings - 1, s + 1)]);
    }
    let mut mesh = TriMesh::new(pos, faces);
    if super::sdf::signed_volume(&mesh) < 0.0 {
        for f in &mut mesh.faces {
            f.swap(1, 2);
        }
    }
    mesh.colors = Some(col);
    mesh.normals = Some(crate::geometry::vertex_normals(
        &mesh.positions,
        &mesh.faces,
    ));
    (mesh, mask)
}
