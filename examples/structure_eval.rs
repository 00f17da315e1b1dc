//! How the global shape map's structure value changes a transfer, on pairs with ground truth and
//! on cross-shape pairs:
//! `cargo run --release --no-default-features --example structure_eval -- [vertices] [values]`.
//!
//! - With truth (the target is the source deformed and moved, so target vertex i is source vertex
//!   i): SMPL man -> woman, Spot bent, Spot with its neck stretched. Prints the mean dE76 of the
//!   result against the source's colours.
//! - Cross-shape (zebra -> giraffe, zebra -> cerberus, Spot -> horse): prints the patch coherence
//!   (mean colour-only distance of sampled target patches to their nearest source patch).
//!
//! Every row also prints the map's isometry score and the structure `auto` picks from it.

use meshmatch::correspondence::Correspondence;
use meshmatch::demo;
use meshmatch::mesh::{TriMesh, sample_texture};
use meshmatch::meshmatch::{TransferParams, transfer};
use meshmatch::testdata::data_path;
use meshmatch::work::CancelToken;
use std::time::Instant;

/// A colour that is a known function of position: bands along y, halves in x and z, and a fine
/// texture-like pattern (a few centimetres) so that only the right layout gets the detail right.
fn body_colour(p: [f32; 3]) -> [f32; 3] {
    let band = ((p[1] * 12.0).floor() as i32).rem_euclid(2) as f32;
    let fine = 0.5 + 0.5 * ((p[0] * 90.0).sin() * (p[1] * 70.0).sin() * (p[2] * 80.0 + 1.0).cos());
    [
        0.1 + 0.6 * band + 0.3 * fine,
        if p[0] > 0.0 { 0.75 } else { 0.15 } + 0.2 * fine,
        if p[2] > 0.0 { 0.8 } else { 0.2 },
    ]
}

/// Spot with per-vertex colours sampled from its texture (no UVs), so truth is per vertex.
fn spot_coloured() -> TriMesh {
    let m = meshmatch::mesh::io::load(&data_path("spot/spot.obj")).expect("spot");
    let tex = m.texture.clone().expect("spot texture");
    let uvs = m.uvs.clone().expect("spot uvs");
    let mut out = TriMesh::new(m.positions.clone(), m.faces.clone());
    out.colors = Some(uvs.iter().map(|&uv| sample_texture(&tex, uv)).collect());
    out
}

fn rigid(p: [f32; 3]) -> [f32; 3] {
    let (s, c) = (0.6f32.sin(), 0.6f32.cos());
    [
        c * p[0] + s * p[2] + 0.3,
        p[1] - 0.2,
        -s * p[0] + c * p[2] + 0.5,
    ]
}

/// Bend about the z axis by an angle growing along x, then move.
fn bend(p: [f32; 3]) -> [f32; 3] {
    let a = 0.6 * p[0];
    let (s, c) = (a.sin(), a.cos());
    rigid([c * p[0] - s * p[1], s * p[0] + c * p[1], p[2]])
}

/// Stretch the front third along x (Spot's head and neck) by 40 %, then move.
fn stretch_neck(p: [f32; 3], x0: f32) -> [f32; 3] {
    let x = if p[0] > x0 {
        x0 + 1.4 * (p[0] - x0)
    } else {
        p[0]
    };
    rigid([x, p[1], p[2]])
}

fn deformed(m: &TriMesh, f: impl Fn([f32; 3]) -> [f32; 3]) -> TriMesh {
    TriMesh::new(m.positions.iter().map(|&p| f(p)).collect(), m.faces.clone())
}

fn corr(pairs: &[(u32, u32)]) -> Vec<Correspondence> {
    pairs
        .iter()
        .map(|&(s, t)| Correspondence {
            source_vertex: s,
            target_vertices: vec![t],
        })
        .collect()
}

/// `n` well-spread vertices (farthest points from the first, by Euclidean distance).
fn spread(m: &TriMesh, n: usize) -> Vec<u32> {
    let p = &m.positions;
    let d2 = |a: [f32; 3], b: [f32; 3]| (0..3).map(|i| (a[i] - b[i]).powi(2)).sum::<f32>();
    let mut out = vec![0u32];
    let mut best: Vec<f32> = p.iter().map(|&q| d2(q, p[0])).collect();
    while out.len() < n {
        let (i, _) = best
            .iter()
            .enumerate()
            .max_by(|a, b| a.1.total_cmp(b.1))
            .unwrap();
        out.push(i as u32);
        for (j, b) in best.iter_mut().enumerate() {
            *b = b.min(d2(p[j], p[i]));
        }
    }
    out
}

struct Task {
    name: &'static str,
    source: TriMesh,
    target: TriMesh,
    corr: Vec<Correspondence>,
    /// Per target file vertex, when known.
    truth: Option<Vec<[f32; 3]>>,
}

fn tasks() -> Vec<Task> {
    let mut out = Vec::new();
    let load = |n: &str| meshmatch::mesh::io::load(&data_path(n)).expect(n);
    let mut man = load("human/human_man.obj");
    let woman = load("human/human_woman.obj");
    let truth: Vec<[f32; 3]> = man.positions.iter().map(|&p| body_colour(p)).collect();
    man.colors = Some(truth.clone());
    let lm: Vec<(u32, u32)> = [411u32, 2445, 5906, 3354, 6755, 3215]
        .iter()
        .map(|&v| (v, v))
        .collect();
    out.push(Task {
        name: "man -> woman, moved",
        source: man.clone(),
        target: deformed(&woman, rigid),
        corr: corr(&lm),
        truth: Some(truth),
    });
    let spot = spot_coloured();
    let spot_truth = spot.colors.clone();
    let spot_lm: Vec<(u32, u32)> = spread(&spot, 6).iter().map(|&v| (v, v)).collect();
    let (lo, hi) = spot
        .positions
        .iter()
        .fold((f32::MAX, f32::MIN), |(a, b), p| (a.min(p[0]), b.max(p[0])));
    out.push(Task {
        name: "Spot bent, moved",
        source: spot.clone(),
        target: deformed(&spot, bend),
        corr: corr(&spot_lm),
        truth: spot_truth.clone(),
    });
    let x0 = hi - (hi - lo) / 3.0;
    out.push(Task {
        name: "Spot neck stretched",
        source: spot.clone(),
        target: deformed(&spot, |p| stretch_neck(p, x0)),
        corr: corr(&spot_lm),
        truth: spot_truth,
    });
    let scene = demo::scene();
    let pick = |m: &TriMesh, l: &[(demo::Landmark, [f32; 3])]| -> Vec<(demo::Landmark, u32)> {
        l.iter()
            .filter_map(|&(k, p)| demo::nearest_vertex(m, p).map(|v| (k, v)))
            .collect()
    };
    let zl = pick(&scene.zebra, &demo::landmarks_zebra());
    for (name, tgt, tl) in [
        (
            "zebra -> giraffe",
            &scene.giraffe,
            pick(&scene.giraffe, &demo::landmarks_giraffe()),
        ),
        (
            "zebra -> cerberus",
            &scene.cerberus,
            pick(&scene.cerberus, &demo::landmarks_cerberus()),
        ),
    ] {
        let pairs: Vec<(u32, u32)> = zl
            .iter()
            .filter_map(|&(k, s)| tl.iter().find(|x| x.0 == k).map(|x| (s, x.1)))
            .collect();
        out.push(Task {
            name,
            source: scene.zebra.clone(),
            target: tgt.clone(),
            corr: corr(&pairs),
            truth: None,
        });
    }
    out.push(Task {
        name: "Spot -> horse",
        source: load("spot/spot.obj"),
        target: load("horse/horse.ply"),
        corr: Vec::new(),
        truth: None,
    });
    out
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let vertices: usize = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(20_000);
    let values: Vec<Option<f32>> = args
        .get(2)
        .map(|s| s.as_str())
        .unwrap_or("0,0.25,0.5,0.75,1,auto")
        .split(',')
        .map(|v| v.parse().ok())
        .collect();
    let only: Option<String> = args.get(3).cloned();
    let cancel = CancelToken::new();
    println!("| task | structure | used | map score | mean dE76 | coherence | seconds |");
    println!("| --- | --- | --- | --- | --- | --- | --- |");
    for t in tasks() {
        if only.as_ref().is_some_and(|o| !t.name.contains(o.as_str())) {
            continue;
        }
        if let Some(truth) = &t.truth {
            // the map alone: colours pulled back through the point map
            let t0 = Instant::now();
            if let Ok(m) = meshmatch::meshmatch::map_meshes(&t.source, &t.target, &t.corr, &cancel)
            {
                let src = t.source.colors.as_ref().expect("coloured source");
                let de = m
                    .target_to_source
                    .iter()
                    .zip(truth)
                    .map(|(&s, &b)| meshmatch::color::delta_e76(src[s as usize], b) as f64)
                    .sum::<f64>()
                    / truth.len() as f64;
                println!(
                    "| {} | map only | - | {:.3} | {de:.2} | - | {:.1} |",
                    t.name,
                    m.score,
                    t0.elapsed().as_secs_f64()
                );
            }
        }
        for &s in &values {
            let params = TransferParams {
                vertices,
                structure: s,
                exact_samples: 400,
                ..TransferParams::default()
            };
            let t0 = Instant::now();
            let r = match transfer(&t.source, &t.target, &t.corr, &params, &|_| {}, &cancel) {
                Ok(r) => r,
                Err(e) => {
                    println!("| {} | {s:?} | error: {e} |", t.name);
                    continue;
                }
            };
            let secs = t0.elapsed().as_secs_f64();
            let de = t.truth.as_ref().map(|truth| {
                r.file_signal
                    .iter()
                    .zip(truth)
                    .map(|(&a, &b)| meshmatch::color::delta_e76(a, b) as f64)
                    .sum::<f64>()
                    / truth.len() as f64
            });
            println!(
                "| {} | {} | {:.2} | {} | {} | {:.4} | {secs:.1} |",
                t.name,
                s.map_or("auto".to_string(), |x| format!("{x}")),
                r.structure,
                r.map_score.map_or("-".into(), |q| format!("{q:.3}")),
                de.map_or("-".into(), |d| format!("{d:.2}")),
                r.exact.as_ref().map_or(f64::NAN, |e| e.coherence),
            );
        }
    }
}
