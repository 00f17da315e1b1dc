//! Map accuracy on SMPL man -> woman for a few functional-map settings:
//! `cargo run --release --no-default-features --example fmap_params`.
use meshmatch::geometry::{FmapParams, shape_map};
use meshmatch::testdata::data_path;
use meshmatch::work::CancelToken;
use std::time::Instant;

fn main() {
    let load = |n: &str| meshmatch::mesh::io::load(&data_path(n)).unwrap();
    let (man, woman) = (load("human/human_man.obj"), load("human/human_woman.obj"));
    let lm: Vec<(u32, u32)> = [411u32, 2445, 5906, 3354, 6755, 3215]
        .iter()
        .map(|&v| (v, v))
        .collect();
    let tol = 0.1 * man.area().sqrt() as f32;
    let variants: Vec<(&str, FmapParams)> = vec![
        ("default", FmapParams::default()),
        (
            "HKS 16",
            FmapParams {
                hks: 16,
                ..FmapParams::default()
            },
        ),
        (
            "step 5",
            FmapParams {
                k_step: 5,
                ..FmapParams::default()
            },
        ),
        (
            "no orientation",
            FmapParams {
                orientation: 0.0,
                ..FmapParams::default()
            },
        ),
        (
            "k_desc 100",
            FmapParams {
                k_descriptors: 100,
                ..FmapParams::default()
            },
        ),
        (
            "k_final 150",
            FmapParams {
                k_final: 150,
                ..FmapParams::default()
            },
        ),
    ];
    // The first two (without and with HKS) also without landmarks, where only the descriptors
    // and the orientation term decide; then other HKS counts.
    let runs = variants
        .iter()
        .map(|(n, p)| (n.to_string(), p.clone(), true))
        .chain(
            variants
                .iter()
                .take(2)
                .map(|(n, p)| (format!("{n}, no landmarks"), p.clone(), false)),
        )
        .chain([4usize, 8, 32].into_iter().map(|h| {
            let p = FmapParams {
                hks: h,
                ..FmapParams::default()
            };
            (format!("hks {h}, no landmarks"), p, false)
        }));
    for (name, p, with_landmarks) in runs {
        let t = Instant::now();
        let m = shape_map(
            (&man.positions, &man.faces),
            (&woman.positions, &woman.faces),
            if with_landmarks { &lm } else { &[] },
            &p,
            &CancelToken::new(),
        )
        .unwrap();
        let (mut sum, mut good) = (0.0f64, 0usize);
        for (t, &s) in m.target_to_source.iter().enumerate() {
            let a = man.positions[s as usize];
            let b = man.positions[t];
            let e = (0..3).map(|i| (a[i] - b[i]).powi(2)).sum::<f32>().sqrt();
            sum += e as f64;
            if e <= tol {
                good += 1;
            }
        }
        let n = m.target_to_source.len();
        println!(
            "{name}: mean err {:.4}, within {:.1}%, score {:.3}, {:.1}s",
            sum / n as f64,
            100.0 * good as f64 / n as f64,
            m.quality.score(),
            t.elapsed().as_secs_f64()
        );
    }
}
