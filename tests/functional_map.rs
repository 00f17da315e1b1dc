//! Global intrinsic shape map (functional maps + ZoomOut) on the SMPL bodies, which share
//! connectivity (man vertex i ↔ woman vertex i is the ground truth).

mod scratch;
use scratch::Scratch;

use meshmatch::geometry::{FmapParams, refine_to_density, shape_map};
use meshmatch::mesh::TriMesh;
use meshmatch::testdata::data_path;
use meshmatch::work::CancelToken;
use std::time::Instant;

fn load(name: &str) -> TriMesh {
    let m = meshmatch::mesh::io::load(&data_path(&format!("human/{name}.obj"))).expect("load");
    assert_eq!(
        m.positions.len(),
        6890,
        "{name}: SMPL vertex order expected"
    );
    m
}

/// Head top, both hands, both feet, one toe tip: SMPL vertex ids (found on the man's T-pose).
const EXTREMITIES: [u32; 6] = [411, 2445, 5906, 3354, 6755, 3215];

/// Correspondences pairing each vertex with the same vertex id (SMPL: the same body point).
fn same_vertex_pairs(vertices: &[u32]) -> Vec<meshmatch::correspondence::Correspondence> {
    vertices
        .iter()
        .map(|&v| meshmatch::correspondence::Correspondence {
            source_vertex: v,
            target_vertices: vec![v],
        })
        .collect()
}

fn dist(a: [f32; 3], b: [f32; 3]) -> f32 {
    (0..3).map(|i| (a[i] - b[i]).powi(2)).sum::<f32>().sqrt()
}

/// Fraction of target vertices whose mapped source vertex lies within `tol` of `truth[t]` (a
/// position on the source), and the mean error.
fn accuracy(src: &[[f32; 3]], map: &[u32], truth: &[[f32; 3]], tol: f32) -> (f64, f64) {
    let mut good = 0usize;
    let mut sum = 0.0f64;
    for (t, &s) in map.iter().enumerate() {
        let e = dist(src[s as usize], truth[t]);
        sum += e as f64;
        if e <= tol {
            good += 1;
        }
    }
    (good as f64 / map.len() as f64, sum / map.len() as f64)
}

fn nearest_point_map(src: &[[f32; 3]], tgt: &[[f32; 3]]) -> Vec<u32> {
    use rayon::prelude::*;
    tgt.par_iter()
        .map(|&p| {
            (0..src.len())
                .min_by(|&a, &b| dist(src[a], p).total_cmp(&dist(src[b], p)))
                .unwrap() as u32
        })
        .collect()
}

#[test]
fn man_to_woman_beats_nearest_point() {
    let (man, woman) = (load("human_man"), load("human_woman"));
    let tol = 0.1 * man.area().sqrt() as f32;
    let cancel = CancelToken::new();
    let params = FmapParams::default();
    let base = nearest_point_map(&man.positions, &woman.positions);
    let (fb, eb) = accuracy(&man.positions, &base, &man.positions, tol);
    eprintln!(
        "nearest point: {:.1}% within 0.1 sqrt(A), mean error {eb:.4}",
        100.0 * fb
    );
    let mut results = Vec::new();
    // WKS alone without and with landmarks, then WKS + HKS with landmarks.
    let with_hks = FmapParams {
        hks: 16,
        ..FmapParams::default()
    };
    for (lm, params) in [
        (&[][..], &params),
        (&EXTREMITIES[..], &params),
        (&EXTREMITIES[..], &with_hks),
    ] {
        let pairs: Vec<(u32, u32)> = lm.iter().map(|&v| (v, v)).collect();
        let t0 = Instant::now();
        let m = shape_map(
            (&man.positions, &man.faces),
            (&woman.positions, &woman.faces),
            &pairs,
            params,
            &cancel,
        )
        .expect("shape map");
        let (f, e) = accuracy(&man.positions, &m.target_to_source, &man.positions, tol);
        eprintln!(
            "fmap + zoomout, {} landmarks, {} HKS: {:.1}% within 0.1 sqrt(A), mean error {e:.4}, {:.2}s {:?}",
            pairs.len(),
            params.hks,
            100.0 * f,
            t0.elapsed().as_secs_f64(),
            m.timings
        );
        results.push(f);
    }
    assert!(results[1] > 0.8, "with landmarks: {:.3}", results[1]);
    assert!(
        results[2] > 0.97,
        "with landmarks and HKS: {:.3}",
        results[2]
    );
    assert!(
        results[1] > fb,
        "map {:.3} vs nearest point {fb:.3}",
        results[1]
    );
}

fn rotate(p: [f32; 3]) -> [f32; 3] {
    let (s, c) = 0.7f32.sin_cos();
    [
        c * p[0] + s * p[2] + 3.0,
        p[1] - 1.0,
        -s * p[0] + c * p[2] + 0.5,
    ]
}

#[test]
fn remeshed_moved_copy_maps_to_identity_and_is_not_flipped() {
    let man = load("human_man");
    let r = refine_to_density(&man, 11_000);
    let truth = r.mesh.positions.clone();
    let moved: Vec<[f32; 3]> = truth.iter().map(|&p| rotate(p)).collect();
    let tol = 0.1 * man.area().sqrt() as f32;
    let cancel = CancelToken::new();
    // landmarks: original vertices keep their ids in the refined mesh
    let pairs: Vec<(u32, u32)> = EXTREMITIES.iter().map(|&v| (v, v)).collect();
    let t0 = Instant::now();
    let m = shape_map(
        (&man.positions, &man.faces),
        (&moved, &r.mesh.faces),
        &pairs,
        &FmapParams::default(),
        &cancel,
    )
    .expect("shape map");
    let (f, e) = accuracy(&man.positions, &m.target_to_source, &truth, tol);
    // flip check: vertices away from the symmetry plane x = 0 keep their side
    let (mut side, mut off) = (0usize, 0usize);
    for (t, &s) in m.target_to_source.iter().enumerate() {
        if truth[t][0].abs() > 0.05 {
            off += 1;
            if (truth[t][0] > 0.0) == (man.positions[s as usize][0] > 0.0) {
                side += 1;
            }
        }
    }
    let side = side as f64 / off as f64;
    eprintln!(
        "self map to a moved copy with {} vertices: {:.1}% within 0.1 sqrt(A), mean error {e:.4}, same side {:.1}%, {:.2}s {:?}",
        truth.len(),
        100.0 * f,
        100.0 * side,
        t0.elapsed().as_secs_f64(),
        m.timings
    );
    assert!(f > 0.9, "identity recovered for {f:.3}");
    assert!(side > 0.95, "flipped: same side {side:.3}");
}

#[test]
fn disconnected_mesh_is_an_error() {
    let man = load("human_man");
    let mut two = man.clone();
    let n = man.positions.len() as u32;
    two.positions
        .extend(man.positions.iter().map(|p| [p[0] + 5.0, p[1], p[2]]));
    two.faces.extend(man.faces.iter().map(|f| f.map(|v| v + n)));
    let r = shape_map(
        (&man.positions, &man.faces),
        (&two.positions, &two.faces),
        &[],
        &FmapParams::default(),
        &CancelToken::new(),
    );
    assert!(r.is_err());
}

/// A colour that is a known function of the man's vertex: bands by height, left/right and
/// front/back halves in the other channels.
fn vertex_colour(p: [f32; 3]) -> [f32; 3] {
    let band = ((p[1] * 12.0).floor() as i32).rem_euclid(2) as f32;
    [
        0.15 + 0.7 * band,
        if p[0] > 0.0 { 0.85 } else { 0.15 },
        if p[2] > 0.0 { 0.8 } else { 0.2 },
    ]
}

#[test]
fn transfer_man_to_woman_lands_colours_better_with_the_map() {
    use meshmatch::meshmatch::{TransferParams, transfer};
    let (mut man, woman) = (load("human_man"), load("human_woman"));
    let truth: Vec<[f32; 3]> = man.positions.iter().map(|&p| vertex_colour(p)).collect();
    man.colors = Some(truth.clone());
    let cancel = CancelToken::new();
    let corr: Vec<meshmatch::correspondence::Correspondence> = same_vertex_pairs(&EXTREMITIES);
    // 2 correspondences (head top, one hand) by default; FMAP_TRANSFER_ALL=1 also runs 0 and 6
    let counts: Vec<usize> = if std::env::var_os("FMAP_TRANSFER_ALL").is_some() {
        vec![0, 2, 6]
    } else {
        vec![2]
    };
    let mut errs = Vec::new();
    for (on, corr) in counts
        .iter()
        .flat_map(|&c| [(false, &corr[..c]), (true, &corr[..c])])
    {
        let params = TransferParams {
            vertices: 6_890,
            iterations: 3,
            // auto: the map's isometry score picks the structure value
            structure: if on { None } else { Some(0.0) },
            ..TransferParams::default()
        };
        let t0 = Instant::now();
        let r = transfer(&man, &woman, corr, &params, &|_| {}, &cancel).expect("transfer");
        assert_eq!(r.file_signal.len(), 6890);
        let de: f64 = r
            .file_signal
            .iter()
            .zip(&truth)
            .map(|(&a, &b)| meshmatch::color::delta_e76(a, b) as f64)
            .sum::<f64>()
            / 6890.0;
        eprintln!(
            "transfer man -> woman, {} correspondences, global map {on}: mean dE76 {de:.2}, {:.2}s, notices {:?}",
            corr.len(),
            t0.elapsed().as_secs_f64(),
            r.notices
        );
        assert!(r.notices.is_empty());
        if on {
            assert!(
                r.structure > 0.6,
                "auto structure {} (score {:?}) between two bodies",
                r.structure,
                r.map_score
            );
        }
        errs.push(de);
    }
    let n = errs.len();
    assert!(
        errs[n - 1] < errs[n - 2],
        "with map {:.2} vs without {:.2}",
        errs[n - 1],
        errs[n - 2]
    );
}

#[test]
fn map_command_writes_every_target_vertex_within_tolerance() {
    let dir = Scratch::new("map");
    let corr = meshmatch::correspondence::CorrespondenceFile {
        correspondences: same_vertex_pairs(&EXTREMITIES),
        ..Default::default()
    };
    corr.save(&dir.join("lm.json")).unwrap();
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_meshmatch"))
        .arg("map")
        .arg("--source")
        .arg(data_path("human/human_man.obj"))
        .arg("--target")
        .arg(data_path("human/human_woman.obj"))
        .arg("--correspondences")
        .arg(dir.join("lm.json"))
        .arg("--out")
        .arg(dir.join("map.csv"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    eprintln!("{err}");
    let text = std::fs::read_to_string(dir.join("map.csv")).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("target_vertex,source_vertex"));
    let map: Vec<u32> = lines
        .enumerate()
        .map(|(i, l)| {
            let (t, s) = l.split_once(',').expect("two columns");
            assert_eq!(t.parse::<usize>().unwrap(), i, "file order");
            s.parse().unwrap()
        })
        .collect();
    assert_eq!(map.len(), 6890);
    let man = load("human_man");
    let tol = 0.1 * man.area().sqrt() as f32;
    let (f, e) = accuracy(&man.positions, &map, &man.positions, tol);
    eprintln!(
        "map command: {:.1}% within 0.1 sqrt(A), mean error {e:.4}",
        100.0 * f
    );
    assert!(f >= 0.97, "{:.1}% within tolerance", 100.0 * f);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn map_command_interpolates_a_dense_remeshed_moved_target() {
    // above the map's own resolution: the map is computed on simplified surfaces and
    // interpolated back to every target vertex
    use meshmatch::meshmatch::{POINT_MAP_VERTICES, map_meshes};
    let man = load("human_man");
    let r = refine_to_density(&man, 20_000);
    assert!(r.mesh.positions.len() > POINT_MAP_VERTICES);
    let truth = r.mesh.positions.clone();
    let moved = TriMesh::new(
        truth.iter().map(|&p| rotate(p)).collect(),
        r.mesh.faces.clone(),
    );
    let corr: Vec<meshmatch::correspondence::Correspondence> = same_vertex_pairs(&EXTREMITIES);
    let t0 = Instant::now();
    let m = map_meshes(&man, &moved, &corr, &CancelToken::new()).expect("map");
    let secs = t0.elapsed().as_secs_f64();
    assert_eq!(m.target_to_source.len(), truth.len());
    let tol = 0.1 * man.area().sqrt() as f32;
    let (f, e) = accuracy(&man.positions, &m.target_to_source, &truth, tol);
    eprintln!(
        "map onto a {}-vertex moved copy (computed on {:?}): {:.1}% within 0.1 sqrt(A), mean error {e:.4}, score {:.2}, {secs:.2}s {:?}",
        truth.len(),
        m.map_vertices,
        100.0 * f,
        m.score,
        m.timings
    );
    assert!(f >= 0.97, "{:.1}% within tolerance", 100.0 * f);
}

#[test]
fn auto_structure_follows_similar_shapes_and_leaves_different_ones_alone() {
    use meshmatch::meshmatch::{AUTO_SCORE_MIN, auto_structure, map_meshes};
    let cancel = CancelToken::new();
    let (man, woman) = (load("human_man"), load("human_woman"));
    let two: Vec<meshmatch::correspondence::Correspondence> = same_vertex_pairs(&EXTREMITIES[..2]);
    let bodies = map_meshes(&man, &woman, &two, &cancel).expect("bodies");
    let data = |p: &str| meshmatch::mesh::io::load(&data_path(p)).expect(p);
    let (spot, horse) = (data("spot/spot.obj"), data("horse/horse.ply"));
    let animals = map_meshes(&spot, &horse, &[], &cancel).expect("animals");
    let (zebra, giraffe) = (meshmatch::demo::zebra(), meshmatch::demo::giraffe());
    let kin = map_meshes(&zebra, &giraffe, &[], &cancel).expect("zebra -> giraffe");
    eprintln!(
        "isometry score: man -> woman {:.3}, Spot -> horse {:.3}, zebra -> giraffe {:.3}",
        bodies.score, animals.score, kin.score
    );
    // two bodies: follow the map
    assert_eq!(auto_structure(bodies.score), 1.0);
    // a cow onto a horse: pure synthesis, as without the map
    assert!(animals.score < AUTO_SCORE_MIN && auto_structure(animals.score) == 0.0);
    // two quadrupeds of different build: in between, well below the bodies
    assert!(
        auto_structure(kin.score) < 0.6,
        "zebra -> giraffe {}",
        kin.score
    );
}

/// A correspondence edit in the app: the first preview comes from the map the previous solve
/// left (before the new map is computed), lands the colours about as well as the new map's
/// first preview, and the finished transfer is the one a fresh solve gives.
#[test]
fn an_edit_previews_from_the_previous_map_and_finishes_as_a_fresh_solve() {
    use meshmatch::meshmatch::{TransferParams, prepare_pair, solve};
    use meshmatch::work::Event;
    use std::sync::Mutex;
    let (mut man, woman) = (load("human_man"), load("human_woman"));
    let truth: Vec<[f32; 3]> = man.positions.iter().map(|&p| vertex_colour(p)).collect();
    man.colors = Some(truth.clone());
    let corr = same_vertex_pairs(&EXTREMITIES);
    let params = TransferParams {
        vertices: 6_890,
        iterations: 3,
        ..TransferParams::default()
    };
    let cancel = CancelToken::new();
    let prepared =
        || prepare_pair(&man, &params, &woman, &params, &|_| {}, &cancel).expect("prepare");
    // Each event of a solve in order ("P" a partial result, else the stage's name) and the
    // first partial result.
    let run = |ps, pt, corr: &[meshmatch::correspondence::Correspondence]| {
        let events = Mutex::new(Vec::<String>::new());
        let first = Mutex::new(None::<Vec<[f32; 3]>>);
        let sink = |e: Event| match e {
            Event::Partial { signal, .. } => {
                events.lock().unwrap().push("P".into());
                first.lock().unwrap().get_or_insert_with(|| signal.to_vec());
            }
            Event::StageTime(name, _) => events.lock().unwrap().push(name.into()),
            _ => {}
        };
        let r = solve(ps, pt, corr, &params, &sink, &cancel).expect("solve");
        (
            r,
            events.into_inner().unwrap(),
            first.into_inner().unwrap().unwrap(),
        )
    };
    // mean dE76 of a working signal of the woman against the truth (same vertex ids)
    let de = |pt: &meshmatch::meshmatch::PreparedMesh, sig: &[[f32; 3]]| {
        let f2w = pt.file_to_working();
        (0..6890)
            .map(|v| meshmatch::color::delta_e76(sig[f2w[v] as usize], truth[v]) as f64)
            .sum::<f64>()
            / 6890.0
    };

    let (ps, pt) = prepared();
    let (before, ..) = run(&ps, &pt, &corr[..2]);
    assert!(before.structure > 0.6, "the map steers this pair");
    // the edit: a third correspondence
    let (edited, events, preview) = run(&ps, &pt, &corr[..3]);
    let at = |name: &str| events.iter().position(|e| e == name).unwrap();
    assert!(
        at("P") < at("global map"),
        "the first preview waited for the new map: {events:?}"
    );
    // the same edit on meshes prepared afresh (no earlier map): the map comes first
    let (fs, ft) = prepared();
    let (fresh, events_fresh, fresh_preview) = run(&fs, &ft, &corr[..3]);
    let at = |name: &str| events_fresh.iter().position(|e| e == name).unwrap();
    assert!(at("global map") < at("P"), "{events_fresh:?}");
    assert_eq!(edited.file_signal, fresh.file_signal);
    assert_eq!(edited.file_nnf, fresh.file_nnf);
    let (e_preview, e_fresh) = (de(&pt, &preview), de(&ft, &fresh_preview));
    let e_final = de(&pt, &edited.working_signal);
    eprintln!(
        "edit preview dE76 {e_preview:.2} (from the previous map), {e_fresh:.2} (new map), \
         finished {e_final:.2}"
    );
    assert!(
        e_preview <= 1.2 * e_fresh,
        "preview from the previous map {e_preview:.2} against the new map's {e_fresh:.2}"
    );
}
