//! Feature-aligned texturing (Xu et al. 2009): salient curves recover known creases (precision,
//! recall), the curve-guided field runs along the curves, and synthesis driven by it lays stripes
//! along the field. Meshes and exemplars are generated here.

mod scratch;
use scratch::Scratch;

use std::collections::HashMap;
use std::time::Instant;

use glam::Vec3;
use meshmatch::geometry::{
    Curve, CurveParams, FieldCurve, FieldParams, curve_tangents, mean_edge_length,
    oriented_curve_field, salient_curves,
};
use meshmatch::mesh::TriMesh;
use meshmatch::synthesis::feature_aligned::{self, Input, Params};
use meshmatch::synthesis::{Orientation, SynthParams};
use meshmatch::work::{CancelToken, no_events};

/// The surface of the cube [-1, 1]^3 as an n x n grid per face, welded, outward orientation;
/// `map` moves each point (e.g. onto a superellipsoid).
fn cube(n: u32, map: impl Fn(Vec3) -> Vec3) -> TriMesh {
    let mut index: HashMap<[i32; 3], u32> = HashMap::new();
    let mut pos = Vec::new();
    let mut faces = Vec::new();
    let n = n as i32;
    let mut id = |k: [i32; 3], pos: &mut Vec<[f32; 3]>| -> u32 {
        *index.entry(k).or_insert_with(|| {
            let q = Vec3::new(k[0] as f32, k[1] as f32, k[2] as f32) * (2.0 / n as f32) - 1.0;
            pos.push(map(q).to_array());
            pos.len() as u32 - 1
        })
    };
    // each side: axis a fixed at 0 or n, (b, c) span the grid
    for a in 0..3 {
        for side in [0, n] {
            let (b, c) = ((a + 1) % 3, (a + 2) % 3);
            for i in 0..n {
                for j in 0..n {
                    let key = |di: i32, dj: i32| {
                        let mut k = [0; 3];
                        k[a] = side;
                        k[b] = i + di;
                        k[c] = j + dj;
                        k
                    };
                    let v00 = id(key(0, 0), &mut pos);
                    let v10 = id(key(1, 0), &mut pos);
                    let v11 = id(key(1, 1), &mut pos);
                    let v01 = id(key(0, 1), &mut pos);
                    // (b x c) = a: counter-clockwise seen from +a
                    let (t1, t2) = if (i + j) % 2 == 0 {
                        ([v00, v10, v11], [v00, v11, v01])
                    } else {
                        ([v00, v10, v01], [v10, v11, v01])
                    };
                    if side == n {
                        faces.push(t1);
                        faces.push(t2);
                    } else {
                        faces.push([t1[0], t1[2], t1[1]]);
                        faces.push([t2[0], t2[2], t2[1]]);
                    }
                }
            }
        }
    }
    TriMesh::new(pos, faces)
}

/// The 12 cube edges, sampled every `step` in the cube's parameter, mapped.
fn cube_edges(map: impl Fn(Vec3) -> Vec3, samples: usize) -> Vec<Vec<Vec3>> {
    let mut out = Vec::new();
    for a in 0..3 {
        let (b, c) = ((a + 1) % 3, (a + 2) % 3);
        for sb in [-1.0f32, 1.0] {
            for sc in [-1.0f32, 1.0] {
                let line = (0..=samples)
                    .map(|s| {
                        let mut q = [0.0f32; 3];
                        q[a] = -1.0 + 2.0 * s as f32 / samples as f32;
                        q[b] = sb;
                        q[c] = sc;
                        map(Vec3::from(q))
                    })
                    .collect();
                out.push(line);
            }
        }
    }
    out
}

/// A closed cylinder of radius 1 along z in [-1, 1]: `nu` around, `nz` along, `nr` cap rings.
fn cylinder(nu: u32, nz: u32, nr: u32) -> TriMesh {
    let mut pos: Vec<[f32; 3]> = Vec::new();
    let tau = std::f32::consts::TAU;
    let ring = |r: f32, z: f32, pos: &mut Vec<[f32; 3]>| -> u32 {
        let s = pos.len() as u32;
        for j in 0..nu {
            let a = tau * j as f32 / nu as f32;
            pos.push([r * a.cos(), r * a.sin(), z]);
        }
        s
    };
    let mut faces = Vec::new();
    let quad = |a0: u32, a1: u32, faces: &mut Vec<[u32; 3]>, flip: bool| {
        for j in 0..nu {
            let (j0, j1) = (j, (j + 1) % nu);
            let (p, q, r, s) = (a0 + j0, a0 + j1, a1 + j1, a1 + j0);
            if flip {
                faces.push([p, r, q]);
                faces.push([p, s, r]);
            } else {
                faces.push([p, q, r]);
                faces.push([p, r, s]);
            }
        }
    };
    // side rings bottom to top
    let side: Vec<u32> = (0..=nz)
        .map(|i| ring(1.0, -1.0 + 2.0 * i as f32 / nz as f32, &mut pos))
        .collect();
    for i in 0..nz as usize {
        quad(side[i], side[i + 1], &mut faces, false);
    }
    // caps: rings shrinking to a centre
    for (z, edge, flip) in [(1.0f32, side[nz as usize], true), (-1.0, side[0], false)] {
        let mut prev = edge;
        for k in 1..nr {
            let r = 1.0 - k as f32 / nr as f32;
            let cur = ring(r, z, &mut pos);
            quad(prev, cur, &mut faces, !flip);
            prev = cur;
        }
        let c = pos.len() as u32;
        pos.push([0.0, 0.0, z]);
        for j in 0..nu {
            let (a, b) = (prev + j, prev + (j + 1) % nu);
            faces.push(if flip { [a, b, c] } else { [b, a, c] });
        }
    }
    TriMesh::new(pos, faces)
}

fn superellipsoid(p: f32) -> impl Fn(Vec3) -> Vec3 {
    move |q: Vec3| {
        let s: f32 = q.abs().to_array().iter().map(|x| x.powf(p)).sum();
        q / s.powf(1.0 / p)
    }
}

fn seg_dist(p: Vec3, a: Vec3, b: Vec3) -> f32 {
    let ab = b - a;
    let t = if ab.length_squared() > 0.0 {
        ((p - a).dot(ab) / ab.length_squared()).clamp(0.0, 1.0)
    } else {
        0.0
    };
    p.distance(a + ab * t)
}

fn polyline_dist(p: Vec3, line: &[Vec3]) -> f32 {
    if line.len() == 1 {
        return p.distance(line[0]);
    }
    line.windows(2)
        .map(|w| seg_dist(p, w[0], w[1]))
        .fold(f32::INFINITY, f32::min)
}

/// (precision, recall): the fraction of curve points within `tol` of the truth, and the fraction
/// of truth samples within `tol` of a curve.
fn precision_recall(curves: &[Curve], truth: &[Vec<Vec3>], tol: f32) -> (f32, f32) {
    let pts: Vec<Vec3> = curves
        .iter()
        .flat_map(|c| c.points.iter().map(|&p| Vec3::from(p)))
        .collect();
    let lines: Vec<Vec<Vec3>> = curves
        .iter()
        .map(|c| {
            let mut l: Vec<Vec3> = c.points.iter().map(|&p| Vec3::from(p)).collect();
            if c.closed {
                l.push(l[0]);
            }
            l
        })
        .collect();
    let good = pts
        .iter()
        .filter(|&&p| truth.iter().any(|t| polyline_dist(p, t) < tol))
        .count();
    let samples: Vec<Vec3> = truth.iter().flatten().copied().collect();
    let covered = samples
        .iter()
        .filter(|&&s| lines.iter().any(|l| polyline_dist(s, l) < tol))
        .count();
    (
        good as f32 / pts.len().max(1) as f32,
        covered as f32 / samples.len().max(1) as f32,
    )
}

/// |cos| between the field and the curve tangent at every snapped curve vertex: (min, mean).
fn field_alignment(mesh: &TriMesh, curves: &[Curve], field: &[[f32; 3]]) -> (f64, f64) {
    let normals = meshmatch::geometry::vertex_normals(&mesh.positions, &mesh.faces);
    let mut min: f64 = 1.0;
    let mut sum = 0.0;
    let mut cnt = 0usize;
    // junctions (vertices of several curves, e.g. cube corners) are where singularities belong
    let mut uses: HashMap<u32, usize> = HashMap::new();
    for c in curves {
        for &v in &c.vertices {
            *uses.entry(v).or_default() += 1;
        }
    }
    for c in curves {
        let t = curve_tangents(&mesh.positions, &normals, &c.vertices, c.closed);
        for (&v, t) in c.vertices.iter().zip(&t) {
            if t.length() < 0.5 || uses[&v] > 1 {
                continue;
            }
            let u = Vec3::from(field[v as usize]).as_dvec3();
            let cs = u.dot(*t).abs();
            min = min.min(cs);
            sum += cs;
            cnt += 1;
        }
    }
    (min, sum / cnt.max(1) as f64)
}

fn field_of(mesh: &TriMesh, curves: &[Curve]) -> meshmatch::geometry::CurveField {
    let fc: Vec<FieldCurve> = curves.iter().map(FieldCurve::from).collect();
    oriented_curve_field(
        &mesh.positions,
        &mesh.faces,
        &fc,
        &FieldParams::default(),
        &CancelToken::new(),
    )
    .unwrap()
}

#[test]
fn cube_creases_are_recovered_and_the_field_follows_them() {
    let mesh = cube(16, |q| q);
    let h = mean_edge_length(&mesh.positions, &mesh.faces);
    let t = Instant::now();
    let curves = salient_curves(&mesh.positions, &mesh.faces, &CurveParams::default()).unwrap();
    let secs = t.elapsed().as_secs_f64();
    let truth = cube_edges(|q| q, 64);
    let (p, r) = precision_recall(&curves, &truth, 1.5 * h);
    eprintln!(
        "cube: {} vertices, {} curves in {secs:.3} s, precision {p:.3}, recall {r:.3}",
        mesh.num_vertices(),
        curves.len()
    );
    assert_eq!(
        curves.len(),
        12,
        "{:?}",
        curves.iter().map(|c| c.kind).collect::<Vec<_>>()
    );
    assert!(p > 0.99 && r > 0.95, "precision {p}, recall {r}");
    let t = Instant::now();
    let f = field_of(&mesh, &curves);
    let (min, mean) = field_alignment(&mesh, &curves, &f.field);
    eprintln!(
        "cube field: {:.3} s ({} steps, mean {:.4} s/step), |cos| min {min:.4} mean {mean:.4}, {} singular",
        t.elapsed().as_secs_f64(),
        f.step_secs.len(),
        f.step_secs.iter().sum::<f64>() / f.step_secs.len().max(1) as f64,
        f.singular.len()
    );
    assert!(min > 0.95, "min |cos| {min}");
}

/// An L-shaped prism (the profile [0,2]x[0,1] + [0,1]x[1,2], z in [0,1]) with `n` grid cells per
/// unit: 18 sharp edges, one of them concave (the inner corner's vertical edge).
fn l_block(n: u32) -> TriMesh {
    let mut pos: Vec<[f32; 3]> = Vec::new();
    let mut faces: Vec<[u32; 3]> = Vec::new();
    // a rectangle from `o` spanning `a` then `b` (integers, in units); a x b is the outward normal
    let mut rect = |o: Vec3, a: Vec3, b: Vec3| {
        let (na, nb) = (
            (a.length() * n as f32).round() as u32,
            (b.length() * n as f32).round() as u32,
        );
        let base = pos.len() as u32;
        for j in 0..=nb {
            for i in 0..=na {
                let p = o + a * (i as f32 / na as f32) + b * (j as f32 / nb as f32);
                // on the grid exactly, so shared edges weld
                pos.push((p * n as f32).round().to_array().map(|c| c / n as f32));
            }
        }
        let id = |i: u32, j: u32| base + j * (na + 1) + i;
        for j in 0..nb {
            for i in 0..na {
                faces.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
                faces.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
            }
        }
    };
    let (x, y, z) = (Vec3::X, Vec3::Y, Vec3::Z);
    let v = |a: f32, b: f32, c: f32| Vec3::new(a, b, c);
    // bottom (normal -z) and top (+z), each as two rectangles
    rect(v(0.0, 0.0, 0.0), y, 2.0 * x);
    rect(v(0.0, 1.0, 0.0), y, x);
    rect(v(0.0, 0.0, 1.0), 2.0 * x, y);
    rect(v(0.0, 1.0, 1.0), x, y);
    // sides
    rect(v(0.0, 0.0, 0.0), 2.0 * x, z); // y = 0, normal -y
    rect(v(2.0, 0.0, 0.0), y, z); // x = 2, +x
    rect(v(2.0, 1.0, 0.0), -x, z); // y = 1 (x in [1,2]), +y
    rect(v(1.0, 1.0, 0.0), y, z); // x = 1 (y in [1,2]), +x
    rect(v(1.0, 2.0, 0.0), -x, z); // y = 2, +y
    rect(v(0.0, 2.0, 0.0), -2.0 * y, z); // x = 0, -x
    let (m, _) = meshmatch::geometry::weld(&TriMesh::new(pos, faces));
    m
}

#[test]
fn fandisk_like_part_gives_its_convex_and_concave_creases() {
    let mesh = l_block(12);
    let h = mean_edge_length(&mesh.positions, &mesh.faces);
    let curves = salient_curves(&mesh.positions, &mesh.faces, &CurveParams::default()).unwrap();
    // the 18 edges: the profile's 6 edges at z = 0 and z = 1, and its 6 corners extruded
    let profile = [
        Vec3::new(0.0, 0.0, 0.0),
        Vec3::new(2.0, 0.0, 0.0),
        Vec3::new(2.0, 1.0, 0.0),
        Vec3::new(1.0, 1.0, 0.0),
        Vec3::new(1.0, 2.0, 0.0),
        Vec3::new(0.0, 2.0, 0.0),
    ];
    let seg =
        |a: Vec3, b: Vec3| -> Vec<Vec3> { (0..=48).map(|i| a.lerp(b, i as f32 / 48.0)).collect() };
    let mut truth = Vec::new();
    for k in 0..6 {
        let (a, b) = (profile[k], profile[(k + 1) % 6]);
        truth.push(seg(a, b));
        truth.push(seg(a + Vec3::Z, b + Vec3::Z));
        truth.push(seg(a, a + Vec3::Z));
    }
    let (p, r) = precision_recall(&curves, &truth, 1.5 * h);
    for t in &truth {
        let (_, rt) = precision_recall(&curves, std::slice::from_ref(t), 1.5 * h);
        if rt < 0.95 {
            eprintln!("  edge {:?} -> {:?}: recall {rt:.3}", t[0], t[t.len() - 1]);
        }
    }
    // the concave edge on its own
    let concave = vec![seg(profile[3], profile[3] + Vec3::Z)];
    let (_, rc) = precision_recall(&curves, &concave, 1.5 * h);
    eprintln!(
        "L-block: {} vertices, {} curves, precision {p:.3}, recall {r:.3}, concave edge recall {rc:.3}",
        mesh.num_vertices(),
        curves.len()
    );
    assert!(p > 0.99 && r > 0.95, "precision {p}, recall {r}");
    assert!(rc > 0.95, "the concave crease: recall {rc}");
    let f = field_of(&mesh, &curves);
    let (min, mean) = field_alignment(&mesh, &curves, &f.field);
    eprintln!("L-block field: |cos| min {min:.4} mean {mean:.4}");
    assert!(mean > 0.95, "mean |cos| {mean}");
}

#[test]
fn cylinder_rims_are_recovered_without_spurious_lines() {
    let mesh = cylinder(64, 20, 8);
    let h = mean_edge_length(&mesh.positions, &mesh.faces);
    let curves = salient_curves(&mesh.positions, &mesh.faces, &CurveParams::default()).unwrap();
    let circle = |z: f32| -> Vec<Vec3> {
        (0..=256)
            .map(|i| {
                let a = std::f32::consts::TAU * i as f32 / 256.0;
                Vec3::new(a.cos(), a.sin(), z)
            })
            .collect()
    };
    let truth = vec![circle(-1.0), circle(1.0)];
    let (p, r) = precision_recall(&curves, &truth, 1.5 * h);
    eprintln!(
        "cylinder: {} curves ({:?}), precision {p:.3}, recall {r:.3}",
        curves.len(),
        curves
            .iter()
            .map(|c| (c.kind, c.closed, c.vertices.len()))
            .collect::<Vec<_>>()
    );
    assert!(p > 0.95 && r > 0.95, "precision {p}, recall {r}");
    let f = field_of(&mesh, &curves);
    let (min, mean) = field_alignment(&mesh, &curves, &f.field);
    eprintln!("cylinder field: |cos| min {min:.4} mean {mean:.4}");
    assert!(min > 0.95);
    // between the rims the field runs around the axis
    let mut worst: f32 = 1.0;
    for (v, p) in mesh.positions.iter().enumerate() {
        let p = Vec3::from(*p);
        if p.z.abs() < 0.8 && (p.x * p.x + p.y * p.y) > 0.99 {
            let around = Vec3::new(-p.y, p.x, 0.0).normalize();
            worst = worst.min(Vec3::from(f.field[v]).dot(around).abs());
        }
    }
    eprintln!("cylinder side: min |cos(field, circumferential)| {worst:.4}");
    assert!(worst > 0.95);
}

#[test]
fn smooth_cylinder_side_gives_no_spurious_crest_lines() {
    // the side alone (caps removed): constant curvature, no crest
    let mesh = cylinder(64, 20, 8);
    let faces: Vec<[u32; 3]> = mesh
        .faces
        .iter()
        .copied()
        .filter(|f| {
            f.iter().all(|&v| {
                let p = mesh.positions[v as usize];
                p[0] * p[0] + p[1] * p[1] > 0.999
            })
        })
        .collect();
    let curves = salient_curves(&mesh.positions, &faces, &CurveParams::default()).unwrap();
    eprintln!(
        "open tube: {} curves ({:?})",
        curves.len(),
        curves
            .iter()
            .map(|c| (c.kind, c.vertices.len(), c.strength))
            .collect::<Vec<_>>()
    );
    assert!(curves.is_empty());
}

#[test]
fn rounded_block_crest_lines_are_recovered() {
    let map = superellipsoid(6.0);
    let mesh = cube(24, &map);
    let h = mean_edge_length(&mesh.positions, &mesh.faces);
    let t = Instant::now();
    let curves = salient_curves(&mesh.positions, &mesh.faces, &CurveParams::default()).unwrap();
    let secs = t.elapsed().as_secs_f64();
    let truth = cube_edges(&map, 96);
    let (p, r) = precision_recall(&curves, &truth, 2.0 * h);
    eprintln!(
        "rounded block: {} vertices, {} curves ({:?}) in {secs:.3} s, precision {p:.3}, recall {r:.3}",
        mesh.num_vertices(),
        curves.len(),
        curves
            .iter()
            .map(|c| (c.kind, c.vertices.len(), c.strength as i32))
            .collect::<Vec<_>>()
    );
    assert!(
        curves
            .iter()
            .all(|c| c.kind != meshmatch::geometry::CurveKind::Crease)
    );
    assert!(p > 0.95 && r > 0.9, "precision {p}, recall {r}");
    let f = field_of(&mesh, &curves);
    let (min, mean) = field_alignment(&mesh, &curves, &f.field);
    eprintln!("rounded block field: |cos| min {min:.4} mean {mean:.4}");
    assert!(mean > 0.95);
}

#[test]
fn constant_radius_fillets_give_their_middle_lines() {
    // a unit box whose 12 edges are rounded with radius 0.12 (about six edge lengths): k is flat
    // across each fillet, the crest is its middle line
    let r = 0.12f32;
    let half = Vec3::splat(0.5);
    let f = move |p: Vec3| {
        let q = p.abs() - (half - Vec3::splat(r));
        q.max(Vec3::ZERO).length() + q.max_element().min(0.0) - r
    };
    let mut mesh = meshmatch::demo::sdf::mesh_sdf(&f, Vec3::splat(-0.6), Vec3::splat(0.6), 0.02);
    meshmatch::demo::sdf::relax(&mut mesh, &f, 5, 1e-4);
    let h = mean_edge_length(&mesh.positions, &mesh.faces);
    let curves = salient_curves(&mesh.positions, &mesh.faces, &CurveParams::default()).unwrap();
    // the middle lines, over the straight part of each edge
    let c = 0.5 - r + r * std::f32::consts::FRAC_1_SQRT_2;
    let mut truth = Vec::new();
    for axis in 0..3 {
        for (sa, sb) in [(1.0f32, 1.0f32), (1.0, -1.0), (-1.0, 1.0), (-1.0, -1.0)] {
            truth.push(
                (0..=64)
                    .map(|i| {
                        let mut p = [0.0f32; 3];
                        p[axis] = (0.5 - r) * (-1.0 + 2.0 * i as f32 / 64.0);
                        p[(axis + 1) % 3] = sa * c;
                        p[(axis + 2) % 3] = sb * c;
                        Vec3::from(p)
                    })
                    .collect::<Vec<_>>(),
            );
        }
    }
    let (p, rc) = precision_recall(&curves, &truth, 2.0 * h);
    for cv in &curves {
        let (pp, _) = precision_recall(std::slice::from_ref(cv), &truth, 2.0 * h);
        let far = cv
            .points
            .iter()
            .map(|q| {
                let q = Vec3::from(*q).abs();
                (0..3)
                    .map(|a| ((q[(a + 1) % 3] - c).powi(2) + (q[(a + 2) % 3] - c).powi(2)).sqrt())
                    .fold(f32::INFINITY, f32::min)
            })
            .fold(0.0f32, f32::max);
        eprintln!(
            "  {:?} {} points, length {:.3}, strength {:.1}: {:.0}% near, farthest from a middle line {:.1} h",
            cv.kind,
            cv.points.len(),
            cv.length(),
            cv.strength,
            100.0 * pp,
            far / h
        );
    }
    eprintln!(
        "filleted box: {} vertices, r = {:.1} h, {} curves, precision {p:.3}, recall {rc:.3}",
        mesh.num_vertices(),
        r / h,
        curves.len()
    );
    assert!(rc > 0.85, "recall {rc}");
    assert!(p > 0.8, "precision {p}");
}

/// Horizontal stripes: colour varies along y only, so they run along the exemplar's x axis.
/// Feature-aligned texturing of `mesh` with `ex` (curves found), and its wall time.
fn run_timed(
    mesh: &TriMesh,
    ex: &image::RgbImage,
    params: &Params,
) -> (feature_aligned::Output, f64) {
    let t = Instant::now();
    let out = feature_aligned::run(
        &Input {
            target: mesh,
            exemplar: ex,
            curves: None,
            alpha: None,
            feature_mask: None,
        },
        params,
        &no_events,
        &CancelToken::new(),
    )
    .unwrap();
    (out, t.elapsed().as_secs_f64())
}

fn stripes(w: u32, period: u32) -> image::RgbImage {
    image::RgbImage::from_fn(w, w, |_, y| {
        if (y / (period / 2)).is_multiple_of(2) {
            image::Rgb([230, 230, 230])
        } else {
            image::Rgb([30, 30, 30])
        }
    })
}

/// Mean |Δ grey| per unit length over mesh edges of the cylinder's side that run along `dir`
/// (|cos| > 0.9) and across it (|cos| < 0.3).
fn along_across(mesh: &TriMesh, dir: &[[f32; 3]]) -> (f64, f64) {
    let cols = mesh.colors.as_ref().expect("colours");
    let grey = |v: usize| (cols[v][0] + cols[v][1] + cols[v][2]) as f64 / 3.0;
    let (mut a, mut na, mut c, mut nc) = (0.0, 0usize, 0.0, 0usize);
    for f in &mesh.faces {
        for k in 0..3 {
            let (i, j) = (f[k] as usize, f[(k + 1) % 3] as usize);
            let (pi, pj) = (Vec3::from(mesh.positions[i]), Vec3::from(mesh.positions[j]));
            if pi.z.abs() > 0.8 || pj.z.abs() > 0.8 {
                continue;
            }
            let e = pj - pi;
            let cs = e.normalize().dot(Vec3::from(dir[i])).abs();
            let d = (grey(i) - grey(j)).abs() / e.length() as f64;
            if cs > 0.9 {
                a += d;
                na += 1;
            } else if cs < 0.3 {
                c += d;
                nc += 1;
            }
        }
    }
    (a / na.max(1) as f64, c / nc.max(1) as f64)
}

#[test]
fn stripes_run_along_the_feature_field() {
    let mesh = cylinder(64, 20, 8);
    let ex = stripes(48, 8);
    let params = Params {
        synth: SynthParams {
            scale: Some(1.5),
            levels: 3,
            seed: 7,
            ..SynthParams::default()
        },
        ..Params::default()
    };
    let (out, secs) = run_timed(&mesh, &ex, &params);
    let (along, across) = along_across(&out.synth.mesh, &out.synth.orientation);
    // circumferential reference direction on the synthesized mesh
    let around: Vec<[f32; 3]> = out
        .synth
        .mesh
        .positions
        .iter()
        .map(|p| Vec3::new(-p[1], p[0], 0.0).normalize_or_zero().to_array())
        .collect();
    let (along_c, across_c) = along_across(&out.synth.mesh, &around);
    eprintln!(
        "stripes on cylinder: {} vertices in {secs:.2} s (curves {:.3} s, field {:.3} s, synthesis \
         {:.2} s); grey change per unit along field {along:.3}, across {across:.3}; along the \
         circumference {along_c:.3}, along the axis {across_c:.3}",
        out.synth.mesh.num_vertices(),
        out.timings.curves,
        out.timings.field,
        out.timings.synthesis,
    );
    assert!(along < 0.5 * across, "along {along} across {across}");
    assert!(along_c < 0.5 * across_c, "around {along_c} axis {across_c}");
    // the same through the plain synthesis entry with Orientation::Features
    let r = meshmatch::synthesis::synthesize(
        &ex,
        &mesh,
        None,
        &SynthParams {
            orientation: Orientation::Features,
            ..params.synth.clone()
        },
        &no_events,
        &CancelToken::new(),
    )
    .unwrap();
    assert_eq!(r.orientation.len(), r.mesh.num_vertices());
}

/// `meshmatch curves` and `meshmatch synth --orientation features` through the CLI parser.
#[test]
fn cli_curves_and_synth_features() {
    use clap::Parser;
    let dir = Scratch::new("xu-cli");
    let mesh = cube(8, |q| q);
    let obj = dir.join("cube.obj");
    let mut s = String::new();
    for p in &mesh.positions {
        s.push_str(&format!("v {} {} {}\n", p[0], p[1], p[2]));
    }
    for f in &mesh.faces {
        s.push_str(&format!("f {} {} {}\n", f[0] + 1, f[1] + 1, f[2] + 1));
    }
    std::fs::write(&obj, s).unwrap();
    let out = dir.join("curves.obj");
    let cli = meshmatch::cli::Cli::try_parse_from([
        "meshmatch",
        "curves",
        obj.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ])
    .unwrap();
    assert_eq!(cli.command.unwrap().run().unwrap(), 0);
    let text = std::fs::read_to_string(&out).unwrap();
    assert_eq!(text.lines().filter(|l| l.starts_with("l ")).count(), 12);
    assert!(text.lines().filter(|l| l.starts_with("v ")).count() >= 12 * 9);
    let ex = dir.join("stripes.png");
    stripes(32, 8).save(&ex).unwrap();
    let synth_out = dir.join("synth.ply");
    let cli = meshmatch::cli::Cli::try_parse_from([
        "meshmatch",
        "synth",
        "--exemplar",
        ex.to_str().unwrap(),
        "--target",
        obj.to_str().unwrap(),
        "--out",
        synth_out.to_str().unwrap(),
        "--orientation",
        "features",
        "--levels",
        "2",
        "--scale",
        "2.0",
    ])
    .unwrap();
    assert_eq!(cli.command.unwrap().run().unwrap(), 0);
    assert!(std::fs::metadata(&synth_out).unwrap().len() > 0);
    let _ = std::fs::remove_dir_all(&dir);
}

/// `(L + P) x = P b` is solved to the penalty's precision, constraints are met, and a greedy step
/// on a ~14K-vertex mesh takes milliseconds.
#[test]
fn field_solve_residual_and_step_timing() {
    use meshmatch::geometry::{HarmonicFieldSolver, cotan_laplacian};
    let map = superellipsoid(6.0);
    let mesh = cube(48, &map);
    let curves = salient_curves(&mesh.positions, &mesh.faces, &CurveParams::default()).unwrap();
    let h = mean_edge_length(&mesh.positions, &mesh.faces);
    for prom in [0.05f32, 0.1, 0.2] {
        let cp = CurveParams {
            min_prominence: prom,
            ..CurveParams::default()
        };
        let c = salient_curves(&mesh.positions, &mesh.faces, &cp).unwrap();
        let (p, r) = precision_recall(&c, &cube_edges(&map, 192), 2.0 * h);
        eprintln!(
            "rounded block 48: prominence {prom}: {} curves, precision {p:.3}, recall {r:.3}",
            c.len()
        );
    }
    let t = Instant::now();
    let f = field_of(&mesh, &curves);
    let total = t.elapsed().as_secs_f64();
    let steps = f.step_secs.len();
    eprintln!(
        "field on {} vertices, {} curves: {total:.3} s (symbolic {:.3} s, {steps} steps, mean {:.4} s, max {:.4} s)",
        mesh.num_vertices(),
        curves.len(),
        f.setup_secs,
        f.step_secs.iter().sum::<f64>() / steps.max(1) as f64,
        f.step_secs.iter().cloned().fold(0.0, f64::max)
    );
    // residual of one solve, with constraints b = the final field at the constrained vertices
    let solver = HarmonicFieldSolver::new(&mesh.positions, &mesh.faces, 1e8).unwrap();
    let cons: Vec<(u32, glam::DVec3)> = f
        .constrained
        .iter()
        .map(|&v| (v, Vec3::from(f.field[v as usize]).as_dvec3()))
        .collect();
    let x = solver.solve(&cons).unwrap();
    let l = cotan_laplacian(&mesh.positions, &mesh.faces);
    let n = mesh.num_vertices();
    let mut res = vec![glam::DVec3::ZERO; n];
    for (col, xc) in x.iter().enumerate().take(n) {
        let rows = l.symbolic().row_idx_of_col_raw(col);
        let vals = l.val_of_col(col);
        for (&r, &v) in rows.iter().zip(vals) {
            res[r] += *xc * v;
        }
    }
    let (mut num, mut den) = (0.0, 0.0);
    let mut is_c = vec![false; n];
    for &(v, b) in &cons {
        is_c[v as usize] = true;
        res[v as usize] += 1e8 * (x[v as usize] - b);
        den += (1e8 * b).length_squared();
    }
    for r in &res {
        num += r.length_squared();
    }
    let rel = (num / den).sqrt();
    let worst = cons
        .iter()
        .map(|&(v, b)| (x[v as usize] - b).length())
        .fold(0.0, f64::max);
    eprintln!("relative residual {rel:.2e}, worst constraint error {worst:.2e}");
    assert!(rel < 1e-8, "{rel}");
    assert!(worst < 1e-5);
}

/// A light 32x32 exemplar with mild texture and one dark horizontal band two pixels thick
/// (rows 15 and 16), as an artist's "line" exemplar.
fn dark_line_exemplar() -> image::RgbImage {
    image::RgbImage::from_fn(32, 32, |x, y| {
        let n = ((x * 7 + y * 13) % 5) as u8 * 6;
        if (15..17).contains(&y) {
            image::Rgb([30 + n, 25, 25])
        } else {
            image::Rgb([200 + n, 190 + n, 160])
        }
    })
}

/// Mean lightness of the synthesized vertices within `tol` of a cube edge, and elsewhere.
fn crease_and_rest_lightness(out: &feature_aligned::Output, tol: f32) -> (f64, f64) {
    let mesh = &out.synth.mesh;
    let col = mesh.colors.as_ref().unwrap();
    let (mut on, mut non, mut off, mut noff) = (0.0, 0usize, 0.0, 0usize);
    for (p, c) in mesh.positions.iter().zip(col) {
        let near1 = p.iter().filter(|x| (x.abs() - 1.0).abs() < tol).count();
        let l = (c[0] + c[1] + c[2]) as f64 / 3.0;
        if near1 >= 2 {
            on += l;
            non += 1;
        } else if p.iter().filter(|x| (x.abs() - 1.0).abs() < 0.3).count() < 2 {
            off += l;
            noff += 1;
        }
    }
    (on / non.max(1) as f64, off / noff.max(1) as f64)
}

#[test]
fn aligned_features_put_the_exemplar_line_on_the_creases() {
    let mesh = cube(12, |p| p);
    let ex = dark_line_exemplar();
    let band = (30.0 + 25.0 + 25.0 + 12.0) / 3.0 / 255.0; // the band's mean lightness, roughly
    let run = |align: bool| {
        let params = Params {
            synth: SynthParams {
                scale: Some(1.0),
                levels: 3,
                seed: 3,
                ..SynthParams::default()
            },
            method: meshmatch::synthesis::Method::Optimize,
            align_features: align,
            ..Params::default()
        };
        run_timed(&mesh, &ex, &params)
    };
    let (with, t_with) = run(true);
    let (without, t_without) = run(false);
    let h = with.synth.spacing;
    let (on_w, rest_w) = crease_and_rest_lightness(&with, 0.5 * h);
    let (on_wo, rest_wo) = crease_and_rest_lightness(&without, 0.5 * h);
    let rep = with.optimization.as_ref().unwrap();
    eprintln!(
        "line on cube creases: {} vertices, h {h:.4}; with the constraint {t_with:.1} s, crease \
         lightness {on_w:.3}, faces {rest_w:.3}; without {t_without:.1} s, crease {on_wo:.3}, faces \
         {rest_wo:.3}; band {band:.3}; scales {:?}",
        with.synth.mesh.num_vertices(),
        rep.scales
            .iter()
            .map(|s| (s.patch, s.samples, s.constrained, s.energy.len()))
            .collect::<Vec<_>>()
    );
    assert!(!with.exemplar_turned);
    assert!(rep.scales.iter().all(|s| s.constrained > 0));
    // the dark line sits on the creases: crease vertices close to the band's colour
    assert!(on_w < band + 0.15, "crease lightness {on_w} vs band {band}");
    // and the faces away from them keep the light ground
    assert!(rest_w > 0.55, "faces {rest_w}");
    // without the constraint the creases are not dark
    assert!(on_wo > on_w + 0.2, "without {on_wo} vs with {on_w}");
}

/// The greedy orientation run on a coarse level (here at 12K of the horse's 48K vertices) decides
/// the curves as the full-resolution greedy does, and the full-resolution field still follows
/// the curves.
#[test]
fn coarse_greedy_orients_the_curves_as_the_full_greedy() {
    use meshmatch::geometry::{FieldParams, oriented_curve_field};
    let mut mesh =
        meshmatch::mesh::io::load(&meshmatch::testdata::data_path("horse/horse.ply")).unwrap();
    mesh.repair().unwrap();
    let params = feature_aligned::Params::default();
    assert!(mesh.num_vertices() > feature_aligned::COARSE_GREEDY);
    let t = std::time::Instant::now();
    let (curves, coarse, _) =
        feature_aligned::curves_and_field(&mesh, None, &params, &CancelToken::new()).unwrap();
    let coarse_s = t.elapsed().as_secs_f64();
    let fc: Vec<FieldCurve> = curves.iter().map(FieldCurve::from).collect();
    let t = std::time::Instant::now();
    let full = oriented_curve_field(
        &mesh.positions,
        &mesh.faces,
        &fc,
        &FieldParams::default(),
        &CancelToken::new(),
    )
    .unwrap();
    let full_s = t.elapsed().as_secs_f64();
    // agreement weighted by curve length
    let total: f32 = curves.iter().map(Curve::length).sum();
    let same: f32 = curves
        .iter()
        .enumerate()
        .filter(|(i, _)| coarse.forward[*i] == full.forward[*i])
        .map(|(_, c)| c.length())
        .sum();
    let (_, mean_c) = field_alignment(&mesh, &curves, &coarse.field);
    let (_, mean_f) = field_alignment(&mesh, &curves, &full.field);
    println!(
        "horse: {} curves; coarse greedy {coarse_s:.2} s ({} steps), full {full_s:.2} s ({} steps); \
         same orientation for {:.1}% of the curve length; |cos| at curve vertices {mean_c:.4} vs {mean_f:.4}",
        curves.len(),
        coarse.step_secs.len(),
        full.step_secs.len(),
        100.0 * same / total
    );
    assert!(same >= 0.85 * total, "{same} of {total}");
    assert!(mean_c > 0.95, "{mean_c}");
    // the field the user sees is as smooth as the full greedy's (mean |f_a - f_b|² on edges)
    let rough = |f: &[[f32; 3]]| meshmatch::geometry::field_roughness(&mesh.faces, f);
    let (rc, rf) = (rough(&coarse.field), rough(&full.field));
    println!("roughness: coarse greedy {rc:.5}, full greedy {rf:.5}");
    assert!(rc <= 1.1 * rf, "coarse greedy field rougher: {rc} vs {rf}");
}
