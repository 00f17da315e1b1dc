//! Mesh quilting (Zhou et al. 2006): integrity, coverage, shell, non-overlap, planar
//! reproduction, errors, writers.

mod scratch;
use scratch::Scratch;

use std::collections::HashMap;

use glam::Vec3;
use meshmatch::TriMesh;
use meshmatch::mesh::connected_components;
use meshmatch::synthesis::quilting::{
    self, Axis, Input, Params, QuiltOutput, Swatch, SwatchKind, load_swatch, plane, swatch,
};
use meshmatch::work::{CancelToken, no_events};

/// Icosphere of radius `r`, `k` subdivisions.
fn icosphere(r: f32, k: usize) -> TriMesh {
    let (p, f) = meshmatch::testdata::icosphere(k);
    TriMesh::new(
        p.iter().map(|v| (Vec3::from(*v) * r).to_array()).collect(),
        f,
    )
}

fn quilt(base: &TriMesh, sw: &Swatch, params: &Params) -> QuiltOutput {
    quilting::run(
        &Input {
            base,
            swatch: sw,
            field: None,
        },
        params,
        &no_events,
        &CancelToken::new(),
    )
    .expect("quilting runs")
}

/// Every output element is whole: a copy of its swatch element (same vertex and face counts,
/// the same faces up to an index offset, one connected component), or, for an element merged
/// from several copies, one connected, consistently oriented component, closed when its swatch
/// element is, with its swatch element's Euler characteristic and no fewer than half the
/// smallest swatch element's faces (no fragment); for a thread cut short, one connected,
/// consistently oriented component, closed when its element is, with its element's Euler
/// characteristic.
fn check_integrity(out: &QuiltOutput, sw: &Swatch) {
    let m = &out.elements;
    let mut v0 = 0usize;
    let mut f0 = 0usize;
    assert_eq!(out.element_pieces.len(), out.num_elements());
    for (e, &src) in out.element_source.iter().enumerate() {
        let el = &sw.elements[src as usize];
        // the element's vertex and face runs (contiguous)
        let nv = out.element_id[v0..]
            .iter()
            .take_while(|&&x| x as usize == e)
            .count();
        let nf = m.faces[f0..]
            .iter()
            .take_while(|f| (f[0] as usize) < v0 + nv)
            .count();
        let faces: Vec<[u32; 3]> = m.faces[f0..f0 + nf]
            .iter()
            .map(|f| f.map(|v| v - v0 as u32))
            .collect();
        assert!(faces.iter().flatten().all(|&v| (v as usize) < nv));
        let source_faces = sw.element_faces(src as usize);
        let closed = meshmatch::mesh::boundary_loops(&source_faces).is_empty();
        if out.element_share[e] < 1.0 {
            // a thread cut short: one oriented manifold piece, closed (capped) when its
            // element is, of the element's topology, at least a quarter of it
            assert!(
                quilting::merging::oriented_manifold(&faces, closed),
                "trimmed element {e} is not an oriented manifold"
            );
            assert_eq!(
                quilting::merging::euler_characteristic(nv, &faces),
                quilting::merging::euler_characteristic(el.vertices.len(), &source_faces),
                "trimmed element {e} changed topology"
            );
            assert!(
                out.element_share[e] >= 0.2,
                "trimmed element {e} is a fragment"
            );
        } else if out.element_pieces[e] == 1 {
            assert_eq!(nv, el.vertices.len(), "element {e}");
            assert_eq!(faces, source_faces, "element {e}");
        } else {
            assert!(
                quilting::merging::oriented_manifold(&faces, closed),
                "merged element {e} is not an oriented manifold"
            );
            assert_eq!(
                quilting::merging::euler_characteristic(nv, &faces),
                quilting::merging::euler_characteristic(el.vertices.len(), &source_faces),
                "merged element {e} changed topology"
            );
            // no fragment: at least half the smallest swatch element's face count
            let smallest = sw.elements.iter().map(|x| x.faces.len()).min().unwrap_or(0);
            assert!(2 * nf >= smallest, "merged element {e} is a fragment");
        }
        let (_, comps) = connected_components(nv, &faces);
        assert_eq!(comps, 1);
        v0 += nv;
        f0 += nf;
    }
    assert_eq!(v0, m.num_vertices());
    assert_eq!(f0, m.num_faces());
}

/// Smallest distance between vertices of different elements (grid hash with cell `cell`,
/// pairs closer than `cell` only; returns `cell` when none).
fn min_inter_element_distance(out: &QuiltOutput, cell: f32) -> f32 {
    let mut map: HashMap<[i32; 3], Vec<usize>> = HashMap::new();
    let key = |p: Vec3| {
        let q = (p / cell).floor();
        [q.x as i32, q.y as i32, q.z as i32]
    };
    for (i, p) in out.elements.positions.iter().enumerate() {
        map.entry(key(Vec3::from(*p))).or_default().push(i);
    }
    let mut best = cell;
    for (i, p) in out.elements.positions.iter().enumerate() {
        let p = Vec3::from(*p);
        let k = key(p);
        for dz in -1..=1 {
            for dy in -1..=1 {
                for dx in -1..=1 {
                    if let Some(l) = map.get(&[k[0] + dx, k[1] + dy, k[2] + dz]) {
                        for &j in l {
                            if out.element_id[j] != out.element_id[i] {
                                best = best.min(p.distance(Vec3::from(out.elements.positions[j])));
                            }
                        }
                    }
                }
            }
        }
    }
    best
}

/// Fraction of base area (by face centroid) within `r` of some output vertex.
fn coverage(base: &TriMesh, out: &QuiltOutput, r: f32) -> f32 {
    let mut map: HashMap<[i32; 3], Vec<Vec3>> = HashMap::new();
    let key = |p: Vec3| {
        let q = (p / r).floor();
        [q.x as i32, q.y as i32, q.z as i32]
    };
    for p in &out.elements.positions {
        let p = Vec3::from(*p);
        map.entry(key(p)).or_default().push(p);
    }
    let areas = meshmatch::geometry::face_areas(&base.positions, &base.faces);
    let (mut hit, mut all) = (0.0, 0.0);
    for (f, a) in base.faces.iter().zip(&areas) {
        let c = f
            .iter()
            .map(|&v| Vec3::from(base.positions[v as usize]))
            .sum::<Vec3>()
            / 3.0;
        let k = key(c);
        let mut near = false;
        'o: for dz in -1..=1 {
            for dy in -1..=1 {
                for dx in -1..=1 {
                    if let Some(l) = map.get(&[k[0] + dx, k[1] + dy, k[2] + dz])
                        && l.iter().any(|q| q.distance(c) < r)
                    {
                        near = true;
                        break 'o;
                    }
                }
            }
        }
        all += a;
        if near {
            hit += a;
        }
    }
    (hit / all) as f32
}

#[test]
fn plane_reproduces_a_periodic_swatch() {
    let sw = swatch(SwatchKind::Studs, 1);
    let base = plane(16.0, 16.0, 32, 32);
    let params = Params {
        swatch_size: Some(4.0), // s = 1: swatch units are base units
        ..Default::default()
    };
    let fractions = std::cell::RefCell::new(Vec::new());
    let filling = std::cell::Cell::new(false);
    let sink = |e: meshmatch::work::Event| {
        if let meshmatch::work::Event::Progress(p) = e {
            // the lattice's solve first, then one event per patch, then the gaps filled
            if p.stage == "quilt: lattice" {
                assert!(fractions.borrow().is_empty());
                return;
            }
            if p.stage == "quilt: gaps" {
                filling.set(true);
                return;
            }
            assert_eq!(p.stage, "quilt");
            assert!(!filling.get(), "a patch after the gap filling began");
            fractions.borrow_mut().push(p.fraction);
        }
    };
    let out = quilting::run(
        &Input {
            base: &base,
            swatch: &sw,
            field: None,
        },
        &params,
        &sink,
        &CancelToken::new(),
    )
    .unwrap();
    let fr = fractions.into_inner();
    assert_eq!(fr.len(), out.stats.patches);
    assert!(fr.windows(2).all(|w| w[1] >= w[0]) && (fr[fr.len() - 1] - 1.0).abs() < 1e-6);
    // the exponential map of a plane is an isometry
    assert!(
        out.stats.max_distortion < 1.001,
        "{}",
        out.stats.max_distortion
    );
    check_integrity(&out, &sw);
    // one stud per unit square: 256 on the plane (studs past the border are dropped)
    let n = out.num_elements();
    assert!((200..=260).contains(&n), "{n} studs on a 16 x 16 plane");
    // rigid copies: every element is its source translated, on the swatch lattice
    let mut v0 = 0;
    let mut phase: Option<[f32; 2]> = None;
    for &src in &out.element_source {
        let sp = sw.element_positions(src as usize);
        let d = Vec3::from(out.elements.positions[v0]) - Vec3::from(sp[0]);
        for (k, q) in sp.iter().enumerate() {
            let p = Vec3::from(out.elements.positions[v0 + k]);
            assert!((p - Vec3::from(*q) - d).length() < 1e-3, "not a rigid copy");
        }
        assert!(d.z.abs() < 1e-4);
        let ph = [d.x.rem_euclid(1.0), d.y.rem_euclid(1.0)];
        let p0 = *phase.get_or_insert(ph);
        let wrap = |a: f32, b: f32| ((a - b + 0.5).rem_euclid(1.0) - 0.5).abs();
        assert!(
            wrap(ph[0], p0[0]) < 0.02 && wrap(ph[1], p0[1]) < 0.02,
            "off the lattice"
        );
        v0 += sp.len();
    }
    assert!(coverage(&base, &out, 1.0) > 0.97);
}

#[test]
fn chain_mail_on_a_sphere_is_whole_covering_in_shell_and_clear() {
    let sw = swatch(SwatchKind::Chain, 2);
    let r = 1.0;
    let base = icosphere(r, 4);
    let l = 0.8;
    let params = Params {
        swatch_size: Some(l),
        ..Default::default()
    };
    let t = std::time::Instant::now();
    let out = quilt(&base, &sw, &params);
    let secs = t.elapsed().as_secs_f64();
    check_integrity(&out, &sw);
    let h = out.stats.thickness;
    // shell: 0 <= |p| - r <= H (1 + tol), up to the chordal error of the base
    let chord = 0.01;
    for p in &out.elements.positions {
        let d = Vec3::from(*p).length() - r;
        assert!(
            d >= -chord && d <= h * 1.05 + chord,
            "outside the shell: {d} (H = {h})"
        );
    }
    // the tetrahedral shell: none inverted, its stretch minimisation never raises L2
    assert_eq!(out.stats.shell_inverted, 0);
    assert!(out.stats.shell_stretch <= out.stats.shell_stretch_before);
    assert!(out.stats.shell_stretch.is_finite());
    let cov = coverage(&base, &out, l / 2.0);
    assert!(cov > 0.95, "coverage {cov}");
    let s = l / sw.extent[0];
    let tau = 0.5 * sw.clearance() * s;
    let dmin = min_inter_element_distance(&out, tau);
    assert!(dmin >= 0.99 * tau, "elements {dmin} apart, tau {tau}");
    eprintln!(
        "sphere chain: {} elements, {} faces, {:.2} s, coverage {cov:.3}, stats {:?}",
        out.num_elements(),
        out.elements.num_faces(),
        secs,
        out.stats
    );
}

#[test]
fn concave_guard_keeps_offsets_below_the_radius_of_curvature() {
    // inside of a unit sphere (faces flipped: normals point to the centre), shell thicker than
    // the radius: without the guard elements would cross the centre
    let mut base = icosphere(1.0, 3);
    for f in &mut base.faces {
        f.swap(1, 2);
    }
    let sw = swatch(SwatchKind::Studs, 0);
    let mut params = Params {
        swatch_size: Some(1.0),
        thickness: Some(1.5),
        // the inside, as wound: not turned outwards
        outward: false,
        ..Default::default()
    };
    // signed height of every vertex along its element's base direction (vertex 0 of a stud is
    // its bottom pole, on the base): negative = crossed the centre
    let lowest = |out: &QuiltOutput| {
        let mut v0 = 0;
        let mut worst = f32::INFINITY;
        for &src in &out.element_source {
            let nv = sw.elements[src as usize].vertices.len();
            let d = Vec3::from(out.elements.positions[v0]).normalize();
            for p in &out.elements.positions[v0..v0 + nv] {
                worst = worst.min(Vec3::from(*p).dot(d));
            }
            v0 += nv;
        }
        worst
    };
    let out = quilt(&base, &sw, &params);
    check_integrity(&out, &sw);
    let guarded = lowest(&out);
    assert!(guarded > 0.0, "offset crossed the centre: {guarded}");
    assert_eq!(out.stats.shell_inverted, 0);
    params.concave_guard = false;
    let raw = lowest(&quilt(&base, &sw, &params));
    assert!(raw < 0.0, "{raw}");
}

#[test]
fn every_swatch_quilts_a_sphere_deterministically() {
    let base = icosphere(1.0, 3);
    for kind in SwatchKind::ALL {
        let sw = swatch(kind, 3);
        let params = Params {
            swatch_size: Some(1.2),
            seed: 5,
            ..Default::default()
        };
        let a = quilt(&base, &sw, &params);
        check_integrity(&a, &sw);
        assert!(a.num_elements() > 20, "{kind:?}: {}", a.num_elements());
        assert!(coverage(&base, &a, 0.6) > 0.9, "{kind:?}");
        let b = quilt(&base, &sw, &params);
        assert_eq!(
            a.elements.positions, b.elements.positions,
            "{kind:?} not deterministic"
        );
    }
}

#[test]
fn bunny_chain_mail() {
    let path = meshmatch::testdata::data_path("bunny/bunny.obj");
    if !path.exists() {
        eprintln!("skipping: {} missing", path.display());
        return;
    }
    let base = meshmatch::mesh::io::load(&path).unwrap();
    let sw = swatch(SwatchKind::Chain, 1);
    let (lo, hi) = base.bounds().unwrap();
    let diag = Vec3::from(hi).distance(Vec3::from(lo));
    // merging on: threads merge, rings never do
    let params = Params {
        merge_elements: true,
        swatch_size: Some(diag / 6.0),
        ..Default::default()
    };
    let t = std::time::Instant::now();
    let out = quilt(&base, &sw, &params);
    let secs = t.elapsed().as_secs_f64();
    check_integrity(&out, &sw);
    let l = out.stats.swatch_size;
    let cov = coverage(&base, &out, l / 2.0);
    eprintln!(
        "bunny chain (L = diag/6): {} elements, {} faces, {:.2} s, coverage {cov:.3}",
        out.num_elements(),
        out.elements.num_faces(),
        secs
    );
    assert!(cov > 0.9, "coverage {cov}");
    let tau = 0.5 * sw.clearance() * l / sw.extent[0];
    let dmin = min_inter_element_distance(&out, tau);
    assert!(dmin >= 0.99 * tau, "elements {dmin} apart, tau {tau}");
    // interlinked rings bent over the bunny and meeting across patch seams: their surfaces
    // must not pass through each other
    let crossing = quilting::crossing_pairs(&out).len();
    assert_eq!(crossing, 0, "{crossing} pairs of rings cross");
    // rings never merge, even with merging on (compact elements are kept whole or dropped by
    // the cut)
    assert!(out.element_pieces.iter().all(|&k| k == 1));
    // crossing strands of a weave, the same
    let weave = swatch(SwatchKind::Weave, 1);
    let out = quilt(&base, &weave, &params);
    check_integrity(&out, &weave);
    // strands from neighbouring patches that continue each other are merged (deformed
    // half-way and stitched) rather than one of them dropped
    let merged = out.element_pieces.iter().filter(|&&k| k > 1).count();
    assert!(merged > 0 && out.stats.merged >= merged, "no strand merged");

    let crossing = quilting::crossing_pairs(&out).len();
    let cov = coverage(&base, &out, out.stats.swatch_size / 2.0);
    eprintln!(
        "bunny weave: {} elements, coverage {cov:.3}",
        out.num_elements()
    );
    assert_eq!(crossing, 0, "{crossing} pairs of strands cross");
}

#[test]
#[ignore = "measurement: chain mail on the bunny at the default scale, writes /tmp/quilt_bunny_chain.obj"]
fn measure_bunny_chain_default_scale() {
    let path = meshmatch::testdata::data_path("bunny/bunny.obj");
    let base = meshmatch::mesh::io::load(&path).unwrap();
    let sw = swatch(SwatchKind::Chain, 1);
    let t = std::time::Instant::now();
    let out = quilt(&base, &sw, &Params::default());
    let secs = t.elapsed().as_secs_f64();
    check_integrity(&out, &sw);
    let cov = coverage(&base, &out, out.stats.swatch_size / 2.0);
    eprintln!(
        "bunny chain (default L = diag/10): base {} faces, {} elements, {} faces, {} vertices, {:.2} s, coverage {cov:.3}\n{:?}",
        base.num_faces(),
        out.num_elements(),
        out.elements.num_faces(),
        out.elements.num_vertices(),
        secs,
        out.stats
    );
    quilting::save_quilt_obj(
        &out,
        Some(&base),
        std::path::Path::new("/tmp/quilt_bunny_chain.obj"),
    )
    .unwrap();
    quilting::save_quilt_obj(
        &out,
        None,
        std::path::Path::new("/tmp/quilt_bunny_chain_only.obj"),
    )
    .unwrap();
}

#[test]
fn bad_inputs_give_one_line_errors() {
    let one_line = |e: meshmatch::Error| {
        let s = e.to_string();
        assert!(!s.contains('\n') && !s.is_empty());
        s
    };
    let e = one_line(load_swatch(TriMesh::new(vec![], vec![]), Axis::Z).unwrap_err());
    assert!(e.contains("no elements"));
    let studs = swatch(SwatchKind::Studs, 0);
    let single = TriMesh::new(studs.element_positions(0).to_vec(), studs.element_faces(0));
    let e = one_line(load_swatch(single, Axis::Z).unwrap_err());
    assert!(
        e.contains("one element covers the swatch; quilting needs several"),
        "{e}"
    );
    // rotated so the up axis is y: loading with Axis::Z puts elements below the ground
    let lying: Vec<[f32; 3]> = studs
        .mesh
        .positions
        .iter()
        .map(|p| [p[0], p[2], -p[1]])
        .collect();
    let lying = TriMesh::new(lying, studs.mesh.faces.clone());
    let e = one_line(load_swatch(lying.clone(), Axis::Z).unwrap_err());
    assert!(e.contains("below the ground"), "{e}");
    assert_eq!(load_swatch(lying, Axis::Y).unwrap().num_elements(), 16);
    // a plate under all studs makes one element span the swatch
    let mut pos = studs.mesh.positions.clone();
    let mut faces = studs.mesh.faces.clone();
    let k = pos.len() as u32;
    pos.extend([
        [0.0, 0.0, 0.0],
        [4.0, 0.0, 0.0],
        [4.0, 4.0, 0.0],
        [0.0, 4.0, 0.0],
    ]);
    faces.extend([[k, k + 1, k + 2], [k, k + 2, k + 3]]);
    let e = one_line(load_swatch(TriMesh::new(pos, faces), Axis::Z).unwrap_err());
    assert!(e.contains("covers the whole swatch"), "{e}");
    // a good user swatch loads
    let ok = load_swatch(studs.mesh.clone(), Axis::Z).unwrap();
    assert_eq!(ok.num_elements(), 16);

    let base = plane(4.0, 4.0, 4, 4);
    let run = |base: &TriMesh, field: Option<&[[f32; 3]]>, params: &Params| {
        quilting::run(
            &Input {
                base,
                swatch: &studs,
                field,
            },
            params,
            &no_events,
            &CancelToken::new(),
        )
    };
    let e = one_line(run(&TriMesh::new(vec![], vec![]), None, &Params::default()).unwrap_err());
    assert!(e.contains("no faces"));
    let e = one_line(run(&base, Some(&[[1.0, 0.0, 0.0]]), &Params::default()).unwrap_err());
    assert!(e.contains("orientation field"));
    let tiny = Params {
        swatch_size: Some(0.001),
        ..Default::default()
    };
    let e = one_line(run(&base, None, &tiny).unwrap_err());
    assert!(e.contains("faces"), "{e}");
    let neg = Params {
        swatch_size: Some(-1.0),
        ..Default::default()
    };
    one_line(run(&base, None, &neg).unwrap_err());
    // cancel
    let c = CancelToken::new();
    c.cancel();
    let r = quilting::run(
        &Input {
            base: &base,
            swatch: &studs,
            field: None,
        },
        &Params::default(),
        &no_events,
        &c,
    );
    assert!(matches!(r, Err(meshmatch::Error::Cancelled)));
}

#[test]
fn field_orients_the_swatch_and_writers_round_trip() {
    let sw = swatch(SwatchKind::Weave, 0);
    let base = plane(8.0, 8.0, 16, 16);
    // field along +y: x strands of the swatch run along y on the base
    let field = vec![[0.0, 1.0, 0.0]; base.num_vertices()];
    let out = quilting::run(
        &Input {
            base: &base,
            swatch: &sw,
            field: Some(&field),
        },
        &Params {
            swatch_size: Some(4.0),
            ..Default::default()
        },
        &no_events,
        &CancelToken::new(),
    )
    .unwrap();
    check_integrity(&out, &sw);
    // element 0 of the weave is an x strand: in the output it spans y, not x
    let mut v0 = 0;
    for &src in &out.element_source {
        let nv = sw.elements[src as usize].vertices.len();
        if src == 0 {
            let ps = &out.elements.positions[v0..v0 + nv];
            let span = |k: usize| {
                ps.iter().map(|p| p[k]).fold(f32::NEG_INFINITY, f32::max)
                    - ps.iter().map(|p| p[k]).fold(f32::INFINITY, f32::min)
            };
            assert!(span(1) > 3.0 * span(0), "strand not turned by the field");
        }
        v0 += nv;
    }
    let dir = Scratch::new("quilt");
    let obj = dir.join("q.obj");
    quilting::save_quilt_obj(&out, Some(&base), &obj).unwrap();
    let text = std::fs::read_to_string(&obj).unwrap();
    // One object per element plus the base (Blender's importer makes each a separate object),
    // each element named by its id, with smooth normals on every face corner.
    let objects: Vec<&str> = text.lines().filter(|l| l.starts_with("o ")).collect();
    assert_eq!(objects.len(), out.num_elements() + 1);
    assert!(!text.contains("\ng "));
    for e in 0..out.num_elements() {
        assert!(objects.contains(&format!("o element_{e}").as_str()));
    }
    assert_eq!(objects.last(), Some(&"o base"));
    assert!(text.lines().any(|l| l.starts_with("vn ")));
    assert!(
        text.lines()
            .filter(|l| l.starts_with("f "))
            .all(|l| l.split_whitespace().skip(1).all(|c| c.contains("//")))
    );
    let back = meshmatch::mesh::io::load(&obj).unwrap();
    assert_eq!(
        back.num_vertices(),
        out.elements.num_vertices() + base.num_vertices()
    );
    assert!(back.normals.is_some());
    let ply = dir.join("q.ply");
    quilting::save_quilt_ply(&out, &ply).unwrap();
    let back = meshmatch::mesh::io::load(&ply).unwrap();
    assert_eq!(back.num_vertices(), out.elements.num_vertices());
    assert_eq!(back.num_faces(), out.elements.num_faces());
    assert!(back.normals.is_some(), "the quilted PLY carries nx ny nz");
    let _ = std::fs::remove_dir_all(&dir);
}

/// A tiny orthographic z-buffer rasteriser (view along -z after rotating by `yaw` about y),
/// Lambert-shaded, for eyeballing outputs in measurement runs.
fn render_png(
    meshes: &[(&TriMesh, [u8; 3])],
    yaw: f32,
    zoom: f32,
    centre_frac: [f32; 2],
    size: usize,
    path: &str,
) {
    let rot = glam::Mat3::from_rotation_y(yaw);
    let mut lo = Vec3::splat(f32::INFINITY);
    let mut hi = Vec3::splat(f32::NEG_INFINITY);
    for (m, _) in meshes {
        for p in &m.positions {
            let q = rot * Vec3::from(*p);
            lo = lo.min(q);
            hi = hi.max(q);
        }
    }
    let ext = (hi - lo).x.max((hi - lo).y) / zoom;
    let c = glam::Vec2::new(
        lo.x + (hi.x - lo.x) * centre_frac[0],
        lo.y + (hi.y - lo.y) * centre_frac[1],
    );
    let mut depth = vec![f32::NEG_INFINITY; size * size];
    let mut img =
        image::RgbImage::from_pixel(size as u32, size as u32, image::Rgb([255, 255, 255]));
    let light = Vec3::new(0.3, 0.5, 1.0).normalize();
    for (m, col) in meshes {
        for f in &m.faces {
            let [a, b, cc] = f.map(|v| rot * Vec3::from(m.positions[v as usize]));
            let n = (b - a).cross(cc - a).normalize_or_zero();
            let shade = 0.25 + 0.75 * n.dot(light).abs();
            let px = |p: Vec3| {
                glam::Vec2::new(
                    ((p.x - c.x) / ext + 0.5) * size as f32,
                    (0.5 - (p.y - c.y) / ext) * size as f32,
                )
            };
            let (pa, pb, pc) = (px(a), px(b), px(cc));
            let x0 = pa.x.min(pb.x).min(pc.x).floor().max(0.0) as i64;
            let x1 = pa.x.max(pb.x).max(pc.x).ceil().min(size as f32 - 1.0) as i64;
            let y0 = pa.y.min(pb.y).min(pc.y).floor().max(0.0) as i64;
            let y1 = pa.y.max(pb.y).max(pc.y).ceil().min(size as f32 - 1.0) as i64;
            let d = (pb - pa).perp_dot(pc - pa);
            if d.abs() < 1e-12 {
                continue;
            }
            for y in y0..=y1 {
                for x in x0..=x1 {
                    let p = glam::Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
                    let l1 = (p - pa).perp_dot(pc - pa) / d;
                    let l2 = (pb - pa).perp_dot(p - pa) / d;
                    let l0 = 1.0 - l1 - l2;
                    if l0 < 0.0 || l1 < 0.0 || l2 < 0.0 {
                        continue;
                    }
                    let z = a.z * l0 + b.z * l1 + cc.z * l2;
                    let k = y as usize * size + x as usize;
                    if z > depth[k] {
                        depth[k] = z;
                        img.put_pixel(
                            x as u32,
                            y as u32,
                            image::Rgb(col.map(|c| (c as f32 * shade) as u8)),
                        );
                    }
                }
            }
        }
    }
    img.save(path).unwrap();
}

#[test]
#[ignore = "measurement: renders PNG previews of quilts to /tmp"]
fn render_previews() {
    let path = meshmatch::testdata::data_path("bunny/bunny.obj");
    let base = meshmatch::mesh::io::load(&path).unwrap();
    for kind in SwatchKind::ALL {
        let sw = swatch(kind, 1);
        let out = quilt(&base, &sw, &Params::default());
        let name = kind.as_str();
        render_png(
            &[(&base, [150, 120, 90]), (&out.elements, [200, 200, 210])],
            0.0,
            1.0,
            [0.5, 0.5],
            900,
            &format!("/tmp/quilt_bunny_{name}.png"),
        );
        render_png(
            &[(&base, [150, 120, 90]), (&out.elements, [200, 200, 210])],
            0.0,
            4.0,
            [0.45, 0.45],
            900,
            &format!("/tmp/quilt_bunny_{name}_zoom.png"),
        );
        eprintln!(
            "{name}: {} elements, {} faces, {:.2} s",
            out.num_elements(),
            out.elements.num_faces(),
            out.stats.seconds
        );
    }
    // the weave with threads merged across seams, the same view as the plain one
    let sw = swatch(SwatchKind::Weave, 1);
    let out = quilt(
        &base,
        &sw,
        &Params {
            merge_elements: true,
            ..Params::default()
        },
    );
    render_png(
        &[(&base, [150, 120, 90]), (&out.elements, [200, 200, 210])],
        0.0,
        4.0,
        [0.45, 0.45],
        900,
        "/tmp/quilt_bunny_weave_merged_zoom.png",
    );
    let sw = swatch(SwatchKind::Chain, 1);
    let sphere = icosphere(1.0, 4);
    let out = quilt(
        &sphere,
        &sw,
        &Params {
            swatch_size: Some(0.8),
            ..Default::default()
        },
    );
    render_png(
        &[(&sphere, [150, 120, 90]), (&out.elements, [200, 200, 210])],
        0.0,
        1.0,
        [0.5, 0.5],
        900,
        "/tmp/quilt_sphere_chain.png",
    );
    render_png(
        &[(&sphere, [150, 120, 90]), (&out.elements, [200, 200, 210])],
        0.0,
        4.0,
        [0.5, 0.5],
        900,
        "/tmp/quilt_sphere_chain_zoom.png",
    );
    let sw = swatch(SwatchKind::Chain, 1);
    let pl = plane(8.0, 8.0, 16, 16);
    let out = quilt(
        &pl,
        &sw,
        &Params {
            swatch_size: Some(4.0),
            ..Default::default()
        },
    );
    render_png(
        &[(&pl, [150, 120, 90]), (&out.elements, [200, 200, 210])],
        0.0,
        2.0,
        [0.5, 0.5],
        900,
        "/tmp/quilt_plane_chain.png",
    );
}

#[test]
fn a_loaded_non_periodic_swatch_quilts_a_plane() {
    // a user swatch: the nuts mesh loaded as a plain mesh (not periodic, extent = its bbox)
    let studs = swatch(SwatchKind::Nuts, 4);
    let sw = load_swatch(studs.mesh.clone(), Axis::Z).unwrap();
    assert!(!sw.periodic);
    let base = plane(12.0, 12.0, 24, 24);
    let out = quilt(
        &base,
        &sw,
        &Params {
            swatch_size: Some(sw.extent[0]),
            ..Default::default()
        },
    );
    check_integrity(&out, &sw);
    assert!(out.num_elements() > 80, "{}", out.num_elements());
    assert!(coverage(&base, &out, 1.0) > 0.9);
    let tau = 0.5 * sw.clearance();
    let dmin = min_inter_element_distance(&out, tau);
    assert!(dmin >= 0.99 * tau, "elements {dmin} apart, tau {tau}");
    for p in &out.elements.positions {
        assert!(p[2] >= -1e-4 && p[2] <= sw.height * 1.01);
    }
}

#[test]
fn no_element_leaves_the_shell_on_thin_legs_and_horns() {
    // The demo giraffe's legs, neck and ossicones are thin against a weave strand at the default
    // swatch size: patches there distort and extrapolate. Nothing may be flung off the surface.
    // Refined as the app's working mesh is (64K vertices): its long thin triangles on the legs
    // flung strands off the surface before the shell guard.
    let base = meshmatch::geometry::refine_to_density(&meshmatch::demo::giraffe(), 64_000).mesh;
    let sw = swatch(SwatchKind::Weave, 1);
    let out = quilt(&base, &sw, &Params::default());
    check_integrity(&out, &sw);
    let bvh = meshmatch::geometry::TriangleBvh::new(&base.positions, &base.faces);
    let limit = 1.5 * out.stats.thickness + 0.05 * out.stats.swatch_size;
    let worst = out
        .elements
        .positions
        .iter()
        .map(|p| bvh.closest_point(*p).unwrap().2)
        .fold(0.0f32, f32::max);
    println!(
        "giraffe weave: {} elements, {} dropped outside the shell, worst distance {worst:.4} (H {:.4})",
        out.stats.elements, out.stats.dropped_outside_shell, out.stats.thickness
    );
    assert!(
        worst <= limit,
        "a vertex {worst} from the base (limit {limit})"
    );
    assert!(out.stats.elements > 50, "{} elements", out.stats.elements);
}

/// Output faces per base area over the swatch's faces per (scaled) swatch area.
fn face_density(base: &TriMesh, sw: &Swatch, out: &QuiltOutput) -> f64 {
    let area: f64 = meshmatch::geometry::face_areas(&base.positions, &base.faces)
        .iter()
        .sum();
    let s = (out.stats.swatch_size / sw.extent[0]) as f64;
    let swatch = sw.mesh.num_faces() as f64 / (sw.extent[0] as f64 * sw.extent[1] as f64 * s * s);
    out.elements.num_faces() as f64 / area / swatch
}

#[test]
fn nudged_strands_fill_the_gaps_between_patches_on_a_curved_base() {
    // a weave's long strands, crossing each other, over a sphere: where the lattices of two
    // patches disagree, the cut drops whole strands; moved by part of a spacing, some fit
    let base = icosphere(1.0, 4);
    let sw = swatch(SwatchKind::Weave, 1);
    // the paper's matching on every patch (the global lattice leaves few gaps to fill), and
    // no gap filling after the patches (it fills some of the same gaps)
    let params = Params {
        swatch_size: Some(0.9),
        lattice: false,
        fill: false,
        ..Default::default()
    };
    let plain = quilt(
        &base,
        &sw,
        &Params {
            nudge: false,
            ..params.clone()
        },
    );
    let nudged = quilt(&base, &sw, &params);
    check_integrity(&nudged, &sw);
    let (dp, dn) = (
        face_density(&base, &sw, &plain),
        face_density(&base, &sw, &nudged),
    );
    eprintln!(
        "weave on a sphere: face density {dp:.3} -> {dn:.3} of the swatch's, {} strands nudged",
        nudged.stats.nudged
    );
    assert!(nudged.stats.nudged > 0);
    assert!(dn > 1.04 * dp, "density {dp} -> {dn}");
    // never denser than the swatch, and every nudged strand clear of the others
    assert!(dn < 1.05, "density {dn}");
    let l = nudged.stats.swatch_size;
    let tau = 0.5 * sw.clearance() * l / sw.extent[0];
    let dmin = min_inter_element_distance(&nudged, tau);
    assert!(dmin >= 0.99 * tau, "elements {dmin} apart, tau {tau}");
    let crossing = quilting::crossing_pairs(&nudged).len();
    assert_eq!(crossing, 0, "{crossing} pairs of strands cross");
    // and within the shell
    let bvh = meshmatch::geometry::TriangleBvh::new(base.positions.as_slice(), &base.faces);
    let limit = 1.5 * nudged.stats.thickness + 0.05 * l;
    assert!(
        nudged
            .elements
            .positions
            .iter()
            .all(|q| bvh.closest_point(*q).is_some_and(|(_, _, d)| d <= limit))
    );
}

#[test]
fn the_global_lattice_joins_a_weave_across_patches_on_a_curved_base() {
    // patches flattened by the two stripe patterns lay their strands on one lattice, so the
    // crossings line up across seams and the cut drops few strands (whole strands only: the
    // trimming keeps parts of dropped strands either way, and is tested on its own)
    let base = icosphere(1.0, 4);
    let sw = swatch(SwatchKind::Weave, 1);
    let params = Params {
        swatch_size: Some(0.9),
        trim: false,
        ..Default::default()
    };
    let matched = quilt(
        &base,
        &sw,
        &Params {
            lattice: false,
            ..params.clone()
        },
    );
    let lattice = quilt(&base, &sw, &params);
    check_integrity(&lattice, &sw);
    let (dm, dl) = (
        face_density(&base, &sw, &matched),
        face_density(&base, &sw, &lattice),
    );
    eprintln!(
        "weave on a sphere: face density {dm:.3} matched -> {dl:.3} on the lattice ({} of {} \
         patches)",
        lattice.stats.lattice_patches, lattice.stats.patches
    );
    assert!(lattice.stats.lattice_patches * 2 > lattice.stats.patches);
    assert!(dl > 1.1 * dm, "density {dm} -> {dl}");
    assert!(dl > 0.75 && dl < 1.05, "density {dl} of the swatch's");
    let l = lattice.stats.swatch_size;
    let tau = 0.5 * sw.clearance() * l / sw.extent[0];
    let dmin = min_inter_element_distance(&lattice, tau);
    assert!(dmin >= 0.99 * tau, "elements {dmin} apart, tau {tau}");
    let crossing = quilting::crossing_pairs(&lattice).len();
    assert_eq!(crossing, 0, "{crossing} pairs of strands cross");
    let bvh = meshmatch::geometry::TriangleBvh::new(base.positions.as_slice(), &base.faces);
    let limit = 1.5 * lattice.stats.thickness + 0.05 * l;
    assert!(
        lattice
            .elements
            .positions
            .iter()
            .all(|q| bvh.closest_point(*q).is_some_and(|(_, _, d)| d <= limit))
    );
}

#[test]
fn a_base_with_a_vertex_in_no_face_quilts_on_the_lattice() {
    // the lattice's solves see every vertex, used or not
    let mut base = icosphere(1.0, 3);
    base.positions.push([3.0, 0.0, 0.0]);
    let sw = swatch(SwatchKind::Studs, 1);
    let out = quilt(
        &base,
        &sw,
        &Params {
            swatch_size: Some(0.8),
            ..Default::default()
        },
    );
    check_integrity(&out, &sw);
    assert!(out.stats.lattice_patches > 0);
}

/// Periodicity is detected from the swatch's own layout: finite patches with a lattice of
/// translated copies get their symmetry vectors, the built-in periodic swatches written to a
/// file and loaded again are found periodic, a scattered cluster is not.
#[test]
fn periodicity_is_detected_from_the_swatch_itself() {
    use quilting::periodicity::{detect, swatch_density, symmetries};
    let rings = load_swatch(
        quilting::finite_patch(quilting::PatchKind::Rings, 1),
        Axis::Z,
    )
    .unwrap();
    assert_eq!(rings.num_elements(), 12);
    let p = detect(&rings);
    assert_eq!(p.kind, "lattice");
    // shortest first: (0, 0.75) between rows, (0.8, 0) along a row (a lying ring to the next)
    let [a, b] = p.lattice.unwrap();
    assert!(a[0].abs() < 1e-3 && (a[1] - 0.75).abs() < 1e-3, "{a:?}");
    assert!((b[0] - 0.8).abs() < 1e-3 && b[1].abs() < 1e-3, "{b:?}");
    assert!((p.tile.extent[0] - 0.8).abs() < 1e-3 && (p.tile.extent[1] - 0.75).abs() < 1e-3);
    assert_eq!(p.tile.num_elements(), 2);
    // an n x m lattice patch has the density of its lattice
    assert!((swatch_density(&rings) - 2.0 / (0.8 * 0.75)).abs() < 1e-3);
    assert!((swatch_density(&p.tile) - swatch_density(&rings)).abs() < 1e-3);
    // the finite weave: strands longer than the lattice step keep their length
    let weave = load_swatch(
        quilting::finite_patch(quilting::PatchKind::Weave, 1),
        Axis::Z,
    )
    .unwrap();
    let p = detect(&weave);
    assert_eq!(p.kind, "lattice");
    assert!((p.tile.extent[0] - 6.0).abs() < 1e-3 && (p.tile.extent[1] - 6.0).abs() < 1e-3);
    assert_eq!(p.tile.num_elements(), 12);
    // pebbles: no two are translated copies
    let pebbles = load_swatch(
        quilting::finite_patch(quilting::PatchKind::Pebbles, 1),
        Axis::Z,
    )
    .unwrap();
    assert!(pebbles.num_elements() >= 30);
    assert!(symmetries(&pebbles).is_empty());
    assert_eq!(detect(&pebbles).kind, "spacing");
    // built-in swatches, written as a plain mesh and loaded: the tile is the lattice's cell
    // (the weave's strands, 3.94 long on a lattice step of 2, need two steps)
    for (kind, cell) in [
        (SwatchKind::Chain, [1.0, 1.0]),
        (SwatchKind::Studs, [1.0, 1.0]),
        (SwatchKind::Scales, [1.0, 1.0]),
        (SwatchKind::Weave, [4.0, 4.0]),
    ] {
        let built = swatch(kind, 1);
        let loaded = load_swatch(built.mesh.clone(), Axis::Z).unwrap();
        let p = detect(&loaded);
        assert_eq!(p.kind, "lattice", "{kind:?}");
        let t = p.tile.extent;
        assert!(
            (t[0] - cell[0]).abs() < 1e-3 && (t[1] - cell[1]).abs() < 1e-3,
            "{kind:?} {t:?}"
        );
        // the tile repeats the built-in swatch's density
        let d = built.num_elements() as f32 / (built.extent[0] * built.extent[1]);
        assert!((swatch_density(&p.tile) - d).abs() < 1e-3 * d, "{kind:?}");
        assert_eq!(detect(&built).kind, "periodic");
    }
}

/// The interlinked ring patch over a coarse sphere (convex) and a saddle: density within 15%
/// of the swatch's, at least 80% of its links per ring reproduced, no crossing surfaces, the
/// base covered without gaps larger than the swatch's largest; and the pebble cluster, which
/// has no lattice, keeps its density too.
#[test]
fn a_finite_ring_patch_keeps_its_links_and_density_on_convex_and_saddle_bases() {
    let rings = load_swatch(
        quilting::finite_patch(quilting::PatchKind::Rings, 1),
        Axis::Z,
    )
    .unwrap();
    let pebbles = load_swatch(
        quilting::finite_patch(quilting::PatchKind::Pebbles, 1),
        Axis::Z,
    )
    .unwrap();
    let sphere = icosphere(1.0, 3);
    let saddle = quilting::saddle(0.5, 24);
    for (name, base, sw, size) in [
        ("sphere", &sphere, &rings, 0.6f32),
        ("saddle", &saddle, &rings, 0.6),
        ("saddle", &saddle, &pebbles, 1.0),
    ] {
        let out = quilt(
            base,
            sw,
            &Params {
                swatch_size: Some(size),
                ..Default::default()
            },
        );
        check_integrity(&out, sw);
        let s = &out.stats;
        let label = format!("{name}: {}", s.arrangement_summary());
        assert!((0.85..=1.15).contains(&s.density_ratio), "{label}");
        let region = if name == "sphere" {
            s.density_ratio_convex
        } else {
            s.density_ratio_saddle
        };
        assert!(
            region.is_some_and(|r| (0.85..=1.15).contains(&r)),
            "{label}"
        );
        if sw.num_elements() == 12 {
            assert!(s.link_share.is_some_and(|x| x >= 0.8), "{label}");
            // the patch's rows of rings as modelled: its border rings have one partner, so
            // fewer links per ring than on its lattice
            assert!(
                s.modelled_links_per_element > 1.0
                    && s.modelled_links_per_element < s.swatch_links_per_element,
                "{label}"
            );
        }
        assert!(s.coverage >= 0.95, "{label}");
        assert_eq!(quilting::crossing_pairs(&out).len(), 0, "{label}");
    }
}

/// A finite patch quilted `swatch_size` wide over a limb (a cylinder of radius 1 and length
/// 12): the swatch, the quilt with the defaults changed by `without`, and with the defaults.
fn on_a_limb(
    kind: quilting::PatchKind,
    swatch_size: f32,
    without: impl Fn(&mut Params),
) -> (Swatch, QuiltOutput, QuiltOutput) {
    let sw = load_swatch(quilting::finite_patch(kind, 1), Axis::Z).unwrap();
    let (p, f) = meshmatch::testdata::cylinder(1.0, 12.0, 64, 200);
    let limb = TriMesh::new(p, f);
    let params = Params {
        swatch_size: Some(swatch_size),
        ..Default::default()
    };
    let mut changed = params.clone();
    without(&mut changed);
    let before = quilt(&limb, &sw, &changed);
    let out = quilt(&limb, &sw, &params);
    (sw, before, out)
}

#[test]
fn a_limb_thinner_than_a_patch_is_covered_and_its_gaps_filled() {
    // a limb (a horse's leg) whose half girth is the patch's radius: the exponential map wraps
    // around it and tears along the far side; the faces straddling the tear once spanned the
    // whole chart, so every element seemed distorted and the limb stayed bare
    // patch radius 3.1, half the girth pi
    let (rings, unfilled, out) = on_a_limb(quilting::PatchKind::Rings, 6.2, |p| p.fill = false);
    check_integrity(&out, &rings);
    let (a, b) = (&unfilled.stats, &out.stats);
    eprintln!(
        "limb: {}\n  without filling: {}",
        b.arrangement_summary(),
        a.arrangement_summary()
    );
    assert!(
        a.elements > 0 && a.density_ratio >= 0.6,
        "{}",
        a.arrangement_summary()
    );
    // the filling adds elements in the gaps, never denser than the swatch allows
    assert!(b.filled > 0 && b.coverage > a.coverage);
    assert!(
        (0.85..=1.15).contains(&b.density_ratio),
        "{}",
        b.arrangement_summary()
    );
    assert_eq!(quilting::crossing_pairs(&out).len(), 0);
}

#[test]
fn chains_broken_where_patches_meet_on_a_limb_are_relinked() {
    // rings a third of the limb's radius across, as on a horse's neck and legs at a tenth of
    // its diagonal: the matched patches around the limb meet at seams where chains end on a
    // ring that threads nothing; relinking gives those rings their partners back
    let (rings, unlinked, out) = on_a_limb(quilting::PatchKind::Rings, 1.85, |p| p.relink = false);
    check_integrity(&out, &rings);
    let (a, b) = (&unlinked.stats, &out.stats);
    eprintln!(
        "limb: {}, {} relinked\n  without relinking: {}",
        b.arrangement_summary(),
        b.relinked,
        a.arrangement_summary()
    );
    let share = |s: &quilting::QuiltStats| s.link_share.expect("rings link");
    // measured: 83% -> 88% of the swatch's links
    assert!(
        b.relinked > 0 && share(b) >= 0.8 && share(b) >= share(a) + 0.04,
        "{}",
        b.arrangement_summary()
    );
    // partners go where they add links, never more densely than the swatch allows, and never
    // through another element
    assert!(
        (0.85..=1.15).contains(&b.density_ratio) && b.coverage >= a.coverage,
        "{}",
        b.arrangement_summary()
    );
    assert_eq!(quilting::crossing_pairs(&out).len(), 0);
}

#[test]
fn a_weave_over_a_limb_keeps_the_clear_parts_of_its_strands() {
    // a finite weave whose strands are longer than the limb is wide (as on a horse's legs at
    // a tenth of its diagonal): whole strands wrapped around it tear off the patch's chart or
    // cross their neighbours and are dropped; the cut keeps their clear parts, capped
    // strands 1.8 long, the limb 2 wide
    let (weave, whole, out) = on_a_limb(quilting::PatchKind::Weave, 1.85, |p| p.trim = false);
    check_integrity(&out, &weave);
    let (a, b) = (&whole.stats, &out.stats);
    eprintln!(
        "limb: {}, {} trimmed\n  whole strands only: {}",
        b.arrangement_summary(),
        b.trimmed,
        a.arrangement_summary()
    );
    assert!(b.trimmed > 0 && b.coverage > a.coverage && b.density_ratio > a.density_ratio);
    assert!(b.coverage >= 0.95, "{}", b.arrangement_summary());
    assert!(
        (0.85..=1.15).contains(&b.density_ratio),
        "{}",
        b.arrangement_summary()
    );
    assert_eq!(quilting::crossing_pairs(&out).len(), 0);
}

/// A swatch of `n x n` small tetrahedra on a unit square, each moved by up to `jitter` of the
/// step (a deterministic hash).
fn tetra_field(n: usize, jitter: f32) -> TriMesh {
    let step = 1.0 / n as f32;
    let size = 0.3 * step;
    let hash = |i: usize, k: u32| {
        let h = (i as u32)
            .wrapping_mul(2_654_435_761)
            .wrapping_add(k.wrapping_mul(40_503));
        ((h ^ (h >> 13)).wrapping_mul(1_274_126_177) >> 8) as f32 / (1u32 << 24) as f32 - 0.5
    };
    let mut positions = Vec::new();
    let mut faces = Vec::new();
    for i in 0..n * n {
        let x = ((i % n) as f32 + 0.5 + jitter * hash(i, 1)) * step;
        let y = ((i / n) as f32 + 0.5 + jitter * hash(i, 2)) * step;
        let b = positions.len() as u32;
        positions.extend([
            [x, y, 0.0],
            [x + size, y, 0.0],
            [x, y + size, 0.0],
            [x + size / 3.0, y + size / 3.0, size],
        ]);
        faces.extend([[0, 2, 1], [0, 1, 3], [1, 2, 3], [2, 0, 3]].map(|f| f.map(|v| v + b)));
    }
    TriMesh::new(positions, faces)
}

/// Swatches of thousands of elements are read as quickly as small ones: the lattice of a
/// 60 x 60 grid of copies is found (a tile of one element), a jittered grid has none, and the
/// clearance between elements is the true one.
#[test]
fn a_swatch_of_thousands_of_elements_is_read_in_full() {
    use quilting::periodicity::{detect, symmetries};
    let grid = load_swatch(tetra_field(60, 0.0), Axis::Z).unwrap();
    assert_eq!(grid.num_elements(), 3600);
    let p = detect(&grid);
    assert_eq!(p.kind, "lattice");
    let [a, b] = p.lattice.unwrap();
    let step = 1.0 / 60.0;
    for v in [a, b] {
        let len = (v[0] * v[0] + v[1] * v[1]).sqrt();
        assert!((len - step).abs() < 1e-3 * step, "{v:?}");
    }
    assert_eq!(p.tile.num_elements(), 1);
    let jittered = load_swatch(tetra_field(60, 0.4), Axis::Z).unwrap();
    assert!(symmetries(&jittered).is_empty());
    assert_eq!(detect(&jittered).kind, "spacing");
    // the clearance against every pair of vertices of distinct elements
    let small = load_swatch(tetra_field(12, 0.4), Axis::Z).unwrap();
    let mut brute = f32::INFINITY;
    for a in 0..small.num_elements() {
        for b in a + 1..small.num_elements() {
            for p in small.element_positions(a) {
                for q in small.element_positions(b) {
                    brute = brute.min(Vec3::from(*p).distance(Vec3::from(*q)));
                }
            }
        }
    }
    assert_eq!(small.clearance(), brute);
    // and the centre spacing of its one class against every pair of centres
    let centres: Vec<[f32; 3]> = small.elements.iter().map(|e| e.centre).collect();
    let mut nearest = f32::INFINITY;
    for (i, a) in centres.iter().enumerate() {
        for b in &centres[i + 1..] {
            nearest = nearest.min((a[0] - b[0]).hypot(a[1] - b[1]));
        }
    }
    let (classes, spacing) = small.class_spacing();
    assert_eq!(classes, 1);
    assert!(
        (spacing[0] - nearest).abs() <= 1e-6 * nearest,
        "{} {nearest}",
        spacing[0]
    );
}
