//! MeshMatch transfer on real data: Spot onto re-tessellated (and deformed) copies of itself,
//! where the true colour and the true source point of every target vertex are known.

use glam::{Mat3, Vec3};
use meshmatch::TriMesh;
use meshmatch::color::delta_e76;
use meshmatch::correspondence::Correspondence;
use meshmatch::meshmatch::{TransferParams, prepare, prepare_pair, solve};
use meshmatch::work::{CancelToken, Event};
use std::time::Instant;

fn data(rel: &str) -> std::path::PathBuf {
    if let Some(d) = std::env::var_os("MESHMATCH_DATA") {
        return std::path::PathBuf::from(d).join(rel);
    }
    let beside = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/data");
    if beside.is_dir() {
        return beside.join(rel);
    }
    std::path::PathBuf::from("/work/shared/data").join(rel)
}

fn spot() -> TriMesh {
    meshmatch::mesh::io::load(&data("spot/spot.obj")).expect("load spot")
}

fn params(vertices: usize) -> TransferParams {
    TransferParams {
        vertices,
        ..Default::default()
    }
}

/// A different tessellation of Spot (refined to `n` vertices, each vertex jittered by a quarter
/// edge within its tangent plane) and the true colour of every vertex (the texture at its UV).
fn retessellated(n: usize) -> (TriMesh, Vec<[f32; 3]>, Vec<u32>) {
    let cancel = CancelToken::new();
    let p = prepare(&spot(), &params(n), &|_| {}, &cancel).unwrap();
    let w = p.working_mesh();
    let truth = w.colors.clone().expect("spot has a texture");
    let lev = &p.hierarchy().levels[0];
    let e = lev.mean_edge;
    let mut positions = w.positions.clone();
    for (i, q) in positions.iter_mut().enumerate() {
        // Deterministic pseudo-random tangent jitter.
        let h = (i as u32).wrapping_mul(2_654_435_761);
        let a = (h % 3600) as f32 / 3600.0 * std::f32::consts::TAU;
        let nrm = Vec3::from(lev.normals[i]);
        let t1 = nrm.any_orthonormal_vector();
        let t2 = nrm.cross(t1);
        let d = 0.25 * e * (a.cos() * t1 + a.sin() * t2);
        *q = (Vec3::from(*q) + d).to_array();
    }
    (
        TriMesh::new(positions, w.faces.clone()),
        truth,
        p.file_to_working().to_vec(),
    )
}

/// Median and mean colour error (CIE76 dE) of a transferred signal against the truth.
fn de_stats(signal: &[[f32; 3]], truth: &[[f32; 3]]) -> (f32, f32) {
    let mut de: Vec<f32> = signal
        .iter()
        .zip(truth)
        .map(|(a, b)| delta_e76(*a, *b))
        .collect();
    let mean = de.iter().sum::<f32>() / de.len() as f32;
    de.sort_by(|a, b| a.total_cmp(b));
    (de[de.len() / 2], mean)
}

#[test]
fn spot_onto_retessellated_spot() {
    let cancel = CancelToken::new();
    let t0 = Instant::now();
    let (target, truth, _) = retessellated(11_000);
    let prm = params(20_000);
    let ps = prepare(&spot(), &prm, &|_| {}, &cancel).unwrap();
    let pt = prepare(&target, &prm, &|_| {}, &cancel).unwrap();
    let t_prep = t0.elapsed().as_secs_f64();
    let energies = std::sync::Mutex::new(Vec::new());
    let sink = |e: Event| {
        if let Event::Progress(p) = e {
            energies
                .lock()
                .unwrap()
                .push((p.level, p.iteration, p.energy));
        }
    };
    let r = solve(&ps, &pt, &[], &prm, &sink, &cancel).unwrap();
    let (median, mean) = de_stats(&r.file_signal, &truth);
    println!(
        "spot->spot retessellated: median dE {median:.2}, mean dE {mean:.2}, energy {:.4}, prepare {t_prep:.2}s, total {:.2}s",
        r.energy,
        t0.elapsed().as_secs_f64()
    );
    println!("energies {:?}", energies.lock().unwrap());
    println!("timings {:?}", r.timings);
    println!(
        "prepare source {:?}\nprepare target {:?}",
        ps.timings(),
        pt.timings()
    );
    assert_eq!(r.file_signal.len(), target.file_vertex_count);
    assert!(median < 5.0, "median dE {median}");
}

/// The convergence stop: at tolerance 0 every level runs every iteration; at the default it
/// stops levels early and the result stays as good (energy within 1%, the mean colour error
/// against the known truth within 5%).
#[test]
fn levels_stop_at_convergence_without_losing_quality() {
    let cancel = CancelToken::new();
    let (target, truth, _) = retessellated(8_000);
    let every = TransferParams {
        tolerance: 0.0,
        ..params(12_000)
    };
    let (ps, pt) = prepare_pair(&spot(), &every, &target, &every, &|_| {}, &cancel).unwrap();
    let full = solve(&ps, &pt, &[], &every, &|_| {}, &cancel).unwrap();
    let fast = solve(&ps, &pt, &[], &params(12_000), &|_| {}, &cancel).unwrap();
    assert!(full.iterations.iter().all(|&i| i == every.iterations));
    assert!(fast.iterations.iter().all(|&i| i <= every.iterations));
    let (n_full, n_fast): (usize, usize) =
        (full.iterations.iter().sum(), fast.iterations.iter().sum());
    let (m_full, m_fast) = (
        de_stats(&full.file_signal, &truth).1,
        de_stats(&fast.file_signal, &truth).1,
    );
    println!(
        "iterations {n_full} -> {n_fast} ({:?}), energy {:.4} -> {:.4}, mean dE {m_full:.2} -> {m_fast:.2}",
        fast.iterations, full.energy, fast.energy
    );
    assert!(n_fast < n_full, "the stop never ended a level early");
    assert!(fast.energy <= 1.01 * full.energy, "energy");
    assert!(m_fast <= 1.05 * m_full + 0.1, "colour error");
}

/// The deformation of the second test: a non-rigid stretch x *= 1 + 0.3 y, then a rotation,
/// scale and translation.
fn deform(p: Vec3, rot: Mat3) -> Vec3 {
    let q = Vec3::new(p.x * (1.0 + 0.3 * p.y), p.y, p.z);
    rot * q * 1.7 + Vec3::new(3.0, -1.0, 0.5)
}

fn undeform(p: Vec3, rot: Mat3) -> Vec3 {
    let q = rot.transpose() * ((p - Vec3::new(3.0, -1.0, 0.5)) / 1.7);
    Vec3::new(q.x / (1.0 + 0.3 * q.y), q.y, q.z)
}

#[test]
fn spot_onto_stretched_moved_spot_with_correspondences() {
    let cancel = CancelToken::new();
    let t0 = Instant::now();
    let src = spot();
    let (mut target, truth, spot_vertex) = retessellated(11_000);
    let rot = Mat3::from_axis_angle(Vec3::new(0.3, 1.0, 0.2).normalize(), 1.1);
    for p in target.positions.iter_mut() {
        *p = deform(Vec3::from(*p), rot).to_array();
    }
    // Six source vertices spread over the body (farthest-point sampling); every Spot vertex is
    // one of the target's (refinement keeps them), at `spot_vertex[i]`.
    let mut picks = vec![0usize];
    let mut dmin: Vec<f32> = src
        .positions
        .iter()
        .map(|p| (Vec3::from(*p) - Vec3::from(src.positions[0])).length())
        .collect();
    while picks.len() < 6 {
        let far = (0..dmin.len())
            .max_by(|&a, &b| dmin[a].total_cmp(&dmin[b]))
            .unwrap();
        picks.push(far);
        for (i, d) in dmin.iter_mut().enumerate() {
            *d = d.min((Vec3::from(src.positions[i]) - Vec3::from(src.positions[far])).length());
        }
    }
    let corr: Vec<Correspondence> = picks
        .iter()
        .map(|&i| Correspondence {
            source_vertex: i as u32,
            target_vertices: vec![spot_vertex[i]],
        })
        .collect();
    let prm = params(20_000);
    let ps = prepare(&src, &prm, &|_| {}, &cancel).unwrap();
    let pt = prepare(&target, &prm, &|_| {}, &cancel).unwrap();
    let r = solve(&ps, &pt, &corr, &prm, &|_| {}, &cancel).unwrap();
    let tol = 0.1 * (src.area() as f32).sqrt();
    let sw = ps.working_mesh();
    let tw = pt.working_mesh();
    let good = r
        .nnf
        .iter()
        .enumerate()
        .filter(|&(v, &(s, _))| {
            let truep = undeform(Vec3::from(tw.positions[v]), rot);
            (Vec3::from(sw.positions[s as usize]) - truep).length() < tol
        })
        .count();
    let frac = good as f32 / r.nnf.len() as f32;
    let (median, mean) = de_stats(&r.file_signal, &truth);
    println!(
        "spot->stretched spot, 6 corr: {:.1}% within 0.1 sqrt(A), median dE {median:.2}, mean dE {mean:.2}, {:.2}s",
        100.0 * frac,
        t0.elapsed().as_secs_f64()
    );
    assert!(frac >= 0.85, "only {:.1}% mapped correctly", 100.0 * frac);
    assert!(mean <= 8.0, "mean dE {mean}");
}

/// Spot and the cow, with small parameters: 6,000 working vertices, two iterations a level.
fn spot_cow_at_6k() -> (TriMesh, TriMesh, TransferParams) {
    let cow = meshmatch::mesh::io::load(&data("cow/cow.ply")).unwrap();
    let prm = TransferParams {
        vertices: 6_000,
        iterations: 2,
        ..Default::default()
    };
    (spot(), cow, prm)
}

#[test]
fn file_outputs_follow_the_target_file() {
    let cancel = CancelToken::new();
    let (src, cow, prm) = spot_cow_at_6k();
    let ps = prepare(&src, &prm, &|_| {}, &cancel).unwrap();
    let pt = prepare(&cow, &prm, &|_| {}, &cancel).unwrap();
    let corr = [Correspondence {
        source_vertex: 10,
        target_vertices: vec![20, 30],
    }];
    let r = solve(&ps, &pt, &corr, &prm, &|_| {}, &cancel).unwrap();
    assert_eq!(r.file_signal.len(), cow.file_vertex_count);
    assert_eq!(r.file_nnf.len(), cow.file_vertex_count);
    assert!(
        r.file_nnf
            .iter()
            .all(|&(s, rot)| (s as usize) < src.file_vertex_count && (0.0..360.0).contains(&rot))
    );
    assert_eq!(r.working_signal.len(), pt.working_mesh().num_vertices());
    // Out-of-range correspondence indices are reported, naming the index.
    let bad = [Correspondence {
        source_vertex: 999_999,
        target_vertices: vec![1],
    }];
    let err = solve(&ps, &pt, &bad, &prm, &|_| {}, &cancel).unwrap_err();
    assert!(err.to_string().contains("999999"), "{err}");
    // A cancelled token stops the solve.
    let c2 = CancelToken::new();
    c2.cancel();
    assert!(matches!(
        solve(&ps, &pt, &[], &prm, &|_| {}, &c2),
        Err(meshmatch::Error::Cancelled)
    ));
}

/// Preparing both meshes together gives what preparing them one after the other gives (the
/// same working meshes, the same transfer), and an error in one mesh is reported as itself, not
/// as the cancellation it causes in the other.
#[test]
fn preparing_a_pair_together_matches_preparing_each() {
    let cancel = CancelToken::new();
    let (src, cow, prm) = spot_cow_at_6k();
    let ps = prepare(&src, &prm, &|_| {}, &cancel).unwrap();
    let pt = prepare(&cow, &prm, &|_| {}, &cancel).unwrap();
    let (qs, qt) = prepare_pair(&src, &prm, &cow, &prm, &|_| {}, &cancel).unwrap();
    for (a, b) in [(&ps, &qs), (&pt, &qt)] {
        assert_eq!(a.working_mesh().positions, b.working_mesh().positions);
        assert_eq!(a.working_mesh().faces, b.working_mesh().faces);
        assert_eq!(a.working_to_file(), b.working_to_file());
    }
    let a = solve(&ps, &pt, &[], &prm, &|_| {}, &cancel).unwrap();
    let b = solve(&qs, &qt, &[], &prm, &|_| {}, &cancel).unwrap();
    assert_eq!(a.nnf, b.nnf);
    assert_eq!(a.working_signal, b.working_signal);
    // a broken target: its own error, whichever mesh finishes first
    let empty = TriMesh::new(Vec::new(), Vec::new());
    for (s, t) in [(&src, &empty), (&empty, &cow)] {
        let err = prepare_pair(s, &prm, t, &prm, &|_| {}, &cancel).unwrap_err();
        assert!(matches!(err, meshmatch::Error::InvalidMesh(_)), "{err}");
    }
    // the caller's cancel stops both
    let stopped = CancelToken::new();
    stopped.cancel();
    assert!(matches!(
        prepare_pair(&src, &prm, &cow, &prm, &|_| {}, &stopped),
        Err(meshmatch::Error::Cancelled)
    ));
}

/// Several pair preparations at once (tests, the app's worker beside a tool) all finish: each
/// preparation blocks its thread while the HKS eigen-solve runs detached, and that solve's
/// parallel loops must still find rayon's workers free (run as rayon jobs, the targets'
/// preparations took every worker and waited forever).
#[test]
fn concurrent_pair_preparations_all_finish() {
    let src = std::sync::Arc::new(spot());
    let cow = std::sync::Arc::new(meshmatch::mesh::io::load(&data("cow/cow.ply")).unwrap());
    let (tx, rx) = std::sync::mpsc::channel();
    let jobs = 2 * rayon::current_num_threads().max(2);
    for _ in 0..jobs {
        let (src, cow, tx) = (src.clone(), cow.clone(), tx.clone());
        std::thread::spawn(move || {
            let prm = TransferParams {
                vertices: 3_000,
                ..Default::default()
            };
            let r = prepare_pair(&src, &prm, &cow, &prm, &|_| {}, &CancelToken::new());
            let _ = tx.send(r.is_ok());
        });
    }
    for _ in 0..jobs {
        let ok = rx
            .recv_timeout(std::time::Duration::from_secs(300))
            .expect("a pair preparation did not finish in 5 minutes");
        assert!(ok);
    }
}

/// A seed makes a run reproducible, whatever the machine's core count: the same transfer in a
/// one-thread and a three-thread pool gives the identical NNF and colours; another seed does not.
#[test]
fn a_seed_reproduces_the_transfer_on_any_core_count() {
    let src = spot();
    let cow = meshmatch::mesh::io::load(&data("cow/cow.ply")).unwrap();
    let corr = [Correspondence {
        source_vertex: 10,
        target_vertices: vec![20],
    }];
    let run = |threads: usize, seed: u64| {
        let prm = TransferParams {
            vertices: 12_000,
            iterations: 2,
            seed,
            ..Default::default()
        };
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| {
                meshmatch::meshmatch::transfer(
                    &src,
                    &cow,
                    &corr,
                    &prm,
                    &|_| {},
                    &CancelToken::new(),
                )
                .unwrap()
            })
    };
    let a = run(1, 7);
    let b = run(3, 7);
    assert!(
        a.nnf.len() > 8192,
        "the finest level must use banded sweeps"
    );
    assert_eq!(a.nnf, b.nnf, "same seed, different core count");
    assert_eq!(a.working_signal, b.working_signal);
    assert_eq!(a.file_signal, b.file_signal);
    let c = run(3, 8);
    let differ = a.nnf.iter().zip(&c.nnf).filter(|(x, y)| x != y).count();
    assert!(differ > 0, "another seed gives another NNF");
}

/// Per-level shape weights: the coarsest level has `shape_weight`, the finest
/// `shape_weight * fine_shape_scale`, geometric and monotone in between; the default is flat.
#[test]
fn shape_weight_per_level() {
    use meshmatch::meshmatch::level_shape_weight;
    let p = TransferParams {
        shape_weight: 2.0,
        fine_shape_scale: 0.25,
        ..Default::default()
    };
    let nl = 5;
    let w: Vec<f32> = (0..nl).map(|l| level_shape_weight(&p, l, nl)).collect();
    assert!(
        (w[nl - 1] - 2.0).abs() < 1e-6 && (w[0] - 0.5).abs() < 1e-6,
        "{w:?}"
    );
    assert!(w.windows(2).all(|x| x[0] < x[1]), "{w:?}");
    assert!((w[2] - 1.0).abs() < 1e-5, "geometric midpoint {w:?}");
    let flat = TransferParams::default();
    assert!((0..nl).all(|l| level_shape_weight(&flat, l, nl) == flat.shape_weight));
}
