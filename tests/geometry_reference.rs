//! The geometry primitives against reference values computed by libigl, SciPy and potpourri3d
//! (`shared/reference/geometry_reference.json`) on Spot, the Viewpoint cow and the bunny.

use std::path::PathBuf;
use std::time::Instant;

use meshmatch::TriMesh;
use meshmatch::geometry::*;

fn reference_path() -> PathBuf {
    meshmatch::testdata::data_dir().join("../reference/geometry_reference.json")
}

/// Load a shared mesh with the crate's loader.
fn load(rel: &str) -> TriMesh {
    let path = meshmatch::testdata::data_path(rel);
    meshmatch::mesh::io::load(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

fn load_welded(rel: &str) -> TriMesh {
    weld(&load(rel)).0
}

struct Case {
    name: &'static str,
    file: &'static str,
    r: serde_json::Value,
}

fn cases() -> Vec<Case> {
    let text = std::fs::read_to_string(reference_path()).expect("reference json");
    let all: serde_json::Value = serde_json::from_str(&text).unwrap();
    [
        ("spot", "spot/spot.obj"),
        ("cow", "cow/cow.ply"),
        ("bunny", "bunny/bunny.obj"),
    ]
    .into_iter()
    .map(|(name, file)| Case {
        name,
        file,
        r: all[name].clone(),
    })
    .collect()
}

fn f64s(v: &serde_json::Value) -> Vec<f64> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect()
}

#[test]
fn weld_matches_reference_counts_and_area() {
    for c in cases() {
        let m = load_welded(c.file);
        assert_eq!(
            m.num_vertices() as u64,
            c.r["n_vertices"].as_u64().unwrap(),
            "{}",
            c.name
        );
        assert_eq!(
            m.num_faces() as u64,
            c.r["n_faces"].as_u64().unwrap(),
            "{}",
            c.name
        );
        let area: f64 = face_areas(&m.positions, &m.faces).iter().sum();
        let ra = c.r["surface_area"].as_f64().unwrap();
        println!("{}: area {area:.6} (reference {ra:.6})", c.name);
        assert!((area - ra).abs() / ra < 1e-6, "{}", c.name);
        let v0 = f64s(&c.r["vertex0_position"]);
        for (x, r) in m.positions[0].iter().zip(&v0) {
            assert!((*x as f64 - r).abs() < 1e-5);
        }
        let mv: f64 = mass_matrix_voronoi(&m.positions, &m.faces).iter().sum();
        assert!((mv - ra).abs() / ra < 1e-6, "Voronoi mass sums to the area");
    }
}

#[test]
fn eigenvalues_and_hks_match_reference() {
    for c in cases() {
        let m = load_welded(c.file);
        let t0 = Instant::now();
        let (vals, vecs) = laplacian_eigen(&m.positions, &m.faces, 40).unwrap();
        let dt = t0.elapsed();
        let rv = f64s(&c.r["eigenvalues"]);
        let mut worst: f64 = 0.0;
        for (i, (&a, &b)) in vals.iter().zip(&rv).enumerate() {
            if b.abs() < 1e-6 {
                assert!(a.abs() < 1e-6, "{} λ{i} = {a}", c.name);
                continue;
            }
            worst = worst.max((a - b).abs() / b);
        }
        println!(
            "{}: {} vertices, 40 eigenpairs in {:.1} ms, max relative eigenvalue error {:.2e}",
            c.name,
            m.num_vertices(),
            dt.as_secs_f64() * 1e3,
            worst
        );
        assert!(worst < 0.01, "{}: eigenvalue error {worst}", c.name);

        let times = hks_times(&vals, 8);
        let rt = f64s(&c.r["hks_times"]);
        for (a, b) in times.iter().zip(&rt) {
            assert!((a - b).abs() / b < 0.01, "{}: hks time {a} vs {b}", c.name);
        }
        // evaluate at the reference's times so only the signature itself is compared
        let h = hks(&vals, &vecs, &rt);
        let probes: Vec<usize> = c.r["hks_probe_vertices"]
            .as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_u64().unwrap() as usize)
            .collect();
        let mut worst_h: f64 = 0.0;
        for (pi, &v) in probes.iter().enumerate() {
            let rh = f64s(&c.r["hks_at_probes"][pi]);
            for j in 0..8 {
                let a = h[v * 8 + j] as f64;
                worst_h = worst_h.max((a - rh[j]).abs() / rh[j]);
            }
        }
        println!(
            "{}: max relative HKS error at probes {:.2e}",
            c.name, worst_h
        );
        assert!(worst_h < 0.02, "{}: HKS error {worst_h}", c.name);
    }
}

/// Dijkstra along mesh edges from `src` (an upper bound of the geodesic distance).
fn dijkstra(m: &TriMesh, src: u32) -> Vec<f64> {
    use std::cmp::Reverse;
    use std::collections::BinaryHeap;
    let adj = m.adjacency();
    let mut d = vec![f64::INFINITY; m.num_vertices()];
    let mut heap = BinaryHeap::new();
    d[src as usize] = 0.0;
    heap.push(Reverse((0u64, src)));
    while let Some(Reverse((dk, v))) = heap.pop() {
        let dv = f64::from_bits(dk);
        if dv > d[v as usize] {
            continue;
        }
        let p = m.positions[v as usize];
        for &w in adj.row(v as usize) {
            let q = m.positions[w as usize];
            let e = ((p[0] - q[0]) as f64)
                .hypot((p[1] - q[1]) as f64)
                .hypot((p[2] - q[2]) as f64);
            if dv + e < d[w as usize] {
                d[w as usize] = dv + e;
                heap.push(Reverse(((dv + e).to_bits(), w)));
            }
        }
    }
    d
}

#[test]
fn heat_geodesics_match_reference_and_dijkstra() {
    for c in cases() {
        let m = load_welded(c.file);
        let t0 = Instant::now();
        let hg = HeatGeodesics::new(&m.positions, &m.faces).unwrap();
        let t1 = Instant::now();
        let d = hg.distance(&[0]);
        let t2 = Instant::now();
        let g = &c.r["geodesic_from_vertex0_heat_method"];
        let probes: Vec<usize> = g["probe_vertices"]
            .as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_u64().unwrap() as usize)
            .collect();
        let rd = f64s(&g["distances"]);
        let dj = dijkstra(&m, 0);
        let mut worst: f64 = 0.0;
        for (&v, &r) in probes.iter().zip(&rd) {
            if r == 0.0 {
                assert!(d[v].abs() < 1e-9);
                continue;
            }
            let rel = (d[v] - r).abs() / r;
            worst = worst.max(rel);
            println!(
                "{} vertex {v}: heat {:.4}  reference {:.4}  dijkstra {:.4}  rel.err {:.2}%",
                c.name,
                d[v],
                r,
                dj[v],
                100.0 * rel
            );
            // edge paths are never shorter than geodesics, and not much longer on these meshes
            assert!(
                d[v] <= dj[v] * 1.02 && d[v] >= dj[v] * 0.8,
                "{} {v}",
                c.name
            );
        }
        let rmax = g["max"].as_f64().unwrap();
        let dmax = d.iter().copied().fold(0.0, f64::max);
        println!(
            "{}: max distance {dmax:.4} (reference {rmax:.4}); factorise {:.1} ms, solve {:.1} ms; worst probe error {:.2}%",
            c.name,
            (t1 - t0).as_secs_f64() * 1e3,
            (t2 - t1).as_secs_f64() * 1e3,
            100.0 * worst
        );
        assert!(worst < 0.05, "{}: geodesic error {worst}", c.name);
        // the reference refines to an intrinsic Delaunay triangulation first; on the cow's sliver
        // triangles that changes the far end by a few percent
        assert!(
            (dmax - rmax).abs() / rmax < 0.1,
            "{}: max {dmax} vs {rmax}",
            c.name
        );
        // every vertex: heat distance close to the edge-path distance overall
        let ratio: f64 =
            d.iter().zip(&dj).skip(1).map(|(a, b)| a / b).sum::<f64>() / (d.len() - 1) as f64;
        println!("{}: mean heat/dijkstra ratio {ratio:.3}", c.name);
        assert!(ratio > 0.85 && ratio < 1.0);
    }
}

#[test]
fn refine_spot_to_64k_keeps_texture_detail_and_heat_scales() {
    let spot = load("spot/spot.obj");
    assert!(spot.texture.is_some() && spot.uvs.is_some());
    let n0 = spot.num_vertices();
    let t0 = Instant::now();
    let r = refine_to_density(&spot, 64_000);
    let dt = t0.elapsed();
    let m = &r.mesh;
    println!(
        "refine spot {} -> {} vertices, {} faces in {:.1} ms",
        n0,
        m.num_vertices(),
        m.num_faces(),
        dt.as_secs_f64() * 1e3
    );
    assert!((m.num_vertices() as f64 - 64_000.0).abs() / 64_000.0 < 0.1);
    assert_eq!(&m.positions[..n0], &spot.positions[..]);
    assert_eq!(r.parent_map.len(), m.num_vertices());
    assert!((m.area() - spot.area()).abs() / spot.area() < 1e-4);
    assert_eq!(m.uvs.as_ref().unwrap().len(), 3 * m.num_faces());
    // Spot's texture is dark-grey patches on white: the baked colours must keep both
    let cols = m
        .colors
        .as_ref()
        .expect("texture baked into vertex colours");
    assert_eq!(cols.len(), m.num_vertices());
    let lum: Vec<f32> = cols.iter().map(|c| (c[0] + c[1] + c[2]) / 3.0).collect();
    let dark = lum.iter().filter(|&&l| l < 0.35).count();
    let light = lum.iter().filter(|&&l| l > 0.8).count();
    let mut hist = [0usize; 10];
    for &l in &lum {
        hist[((l * 10.0) as usize).min(9)] += 1;
    }
    println!("refined spot: {dark} dark and {light} light vertices; luminance histogram {hist:?}");
    assert!(dark > m.num_vertices() / 20 && light > m.num_vertices() / 5);
    // inserted vertices carry detail too: colours vary among them
    let new_lum = &lum[n0..];
    let mean = new_lum.iter().sum::<f32>() / new_lum.len() as f32;
    let var = new_lum.iter().map(|l| (l - mean).powi(2)).sum::<f32>() / new_lum.len() as f32;
    assert!(var.sqrt() > 0.2, "std {}", var.sqrt());
    // the edge lengths even out
    let h0 = mean_edge_length(&spot.positions, &spot.faces);
    let h1 = mean_edge_length(&m.positions, &m.faces);
    println!("mean edge length {h0:.4} -> {h1:.4}");
    assert!(h1 < h0 / 3.0);
    let near = nearest_original(m, n0);
    assert!(near.iter().all(|&v| (v as usize) < n0));
    assert_eq!(near[..n0].to_vec(), (0..n0 as u32).collect::<Vec<_>>());

    // heat method at the working resolution
    let t0 = Instant::now();
    let hg = HeatGeodesics::new(&m.positions, &m.faces).unwrap();
    let t1 = Instant::now();
    let d = hg.distance(&[0]);
    let t2 = Instant::now();
    println!(
        "heat geodesics on {} vertices: factorise {:.1} ms, one solve {:.1} ms",
        m.num_vertices(),
        (t1 - t0).as_secs_f64() * 1e3,
        (t2 - t1).as_secs_f64() * 1e3
    );
    // agrees with the coarse solution (vertex indices < n0 are shared)
    let coarse = HeatGeodesics::new(&spot.positions, &spot.faces)
        .unwrap()
        .distance(&[0]);
    for v in [976usize, 1953, 2929] {
        let rel = (d[v] - coarse[v]).abs() / coarse[v];
        println!("vertex {v}: fine {:.4} coarse {:.4}", d[v], coarse[v]);
        assert!(rel < 0.05);
    }
}

#[test]
fn bvh_and_normals_on_real_meshes() {
    let m = load_welded("bunny/bunny.obj");
    let bvh = TriangleBvh::new(&m.positions, &m.faces);
    for (v, p) in m.positions.iter().enumerate() {
        let (f, bc, d) = bvh.closest_point(*p).unwrap();
        assert!(d < 1e-6, "vertex {v} at distance {d}");
        let q = m.faces[f as usize]
            .iter()
            .zip(bc)
            .fold([0.0f32; 3], |acc, (&i, w)| {
                let x = m.positions[i as usize];
                [acc[0] + w * x[0], acc[1] + w * x[1], acc[2] + w * x[2]]
            });
        assert!((0..3).all(|k| (q[k] - p[k]).abs() < 1e-5));
    }
    // rays shot down onto face centroids hit that face (or one touching the same point)
    let fnrm = face_normals(&m.positions, &m.faces);
    let mut hits = 0;
    for (f, face) in m.faces.iter().enumerate().step_by(7) {
        let c = face.iter().fold([0.0f32; 3], |a, &i| {
            let x = m.positions[i as usize];
            [a[0] + x[0] / 3.0, a[1] + x[1] / 3.0, a[2] + x[2] / 3.0]
        });
        let n = fnrm[f];
        let o = [
            c[0] + 0.001 * n[0],
            c[1] + 0.001 * n[1],
            c[2] + 0.001 * n[2],
        ];
        let (hf, _, t) = bvh
            .ray_hit(o, [-n[0], -n[1], -n[2]])
            .expect("ray hits the surface");
        assert!(t <= 0.001 + 1e-6, "face {f}: t {t}");
        hits += (hf as usize == f && (t - 0.001).abs() < 1e-5) as usize;
    }
    assert!(hits > m.num_faces() / 7 * 9 / 10, "{hits}");
}

#[test]
fn vertex_normals_of_a_sphere_point_outwards() {
    // icosphere by refining an octahedron and projecting to the unit sphere
    let oct = TriMesh::new(
        vec![
            [1.0, 0.0, 0.0],
            [-1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, -1.0, 0.0],
            [0.0, 0.0, 1.0],
            [0.0, 0.0, -1.0],
        ],
        vec![
            [0, 2, 4],
            [2, 1, 4],
            [1, 3, 4],
            [3, 0, 4],
            [2, 0, 5],
            [1, 2, 5],
            [3, 1, 5],
            [0, 3, 5],
        ],
    );
    let mut s = refine_to_density(&oct, 3000).mesh;
    for p in &mut s.positions {
        let l = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
        *p = p.map(|x| x / l);
    }
    let nrm = vertex_normals(&s.positions, &s.faces);
    let worst = s
        .positions
        .iter()
        .zip(&nrm)
        .map(|(p, n)| p[0] * n[0] + p[1] * n[1] + p[2] * n[2])
        .fold(1.0f32, f32::min);
    println!(
        "sphere: {} vertices, min normal·position {worst:.5}",
        s.num_vertices()
    );
    assert!(worst > 0.99);
    let fnrm = face_normals(&s.positions, &s.faces);
    assert!(fnrm.iter().zip(&s.faces).all(|(n, f)| {
        let c = s.positions[f[0] as usize];
        n[0] * c[0] + n[1] * c[1] + n[2] * c[2] > 0.9
    }));
    let frames = tangent_frames(&nrm, FrameRule::Duff);
    assert_eq!(frames.len(), nrm.len());
}
