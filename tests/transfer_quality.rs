//! Transfers between different shapes keep the source's look: the target's area-weighted colour
//! distribution is close to the source's, and no colour appears that the source does not have.
//! Spot -> cow and Spot -> horse (real data), the demo zebra -> giraffe and zebra -> cerberus (with
//! the default correspondences; the cerberus's three heads share one-to-many pairs).

use meshmatch::color::{delta_e76, srgb_to_lab};
use meshmatch::correspondence::Correspondence;
use meshmatch::geometry::mass_matrix_barycentric;
use meshmatch::meshmatch::{PreparedMesh, TransferParams, TransferResult, prepare, solve};
use meshmatch::work::{CancelToken, no_events};
use meshmatch::{TriMesh, demo, mesh::io, testdata::data_path};

/// Area-weighted Lab histogram (8 x 8 x 8 bins over L [0,100], a and b [-64,64]), normalised.
fn lab_histogram(mesh: &TriMesh, colors: &[[f32; 3]]) -> Vec<f64> {
    let area = mass_matrix_barycentric(&mesh.positions, &mesh.faces);
    let mut h = vec![0.0; 512];
    for (c, a) in colors.iter().zip(&area) {
        let l = srgb_to_lab(*c);
        let bin = |x: f32, lo: f32, hi: f32| {
            (((x - lo) / (hi - lo) * 8.0).floor() as i32).clamp(0, 7) as usize
        };
        h[bin(l[0], 0.0, 100.0) * 64 + bin(l[1], -64.0, 64.0) * 8 + bin(l[2], -64.0, 64.0)] += a;
    }
    let s: f64 = h.iter().sum();
    h.iter().map(|x| x / s).collect()
}

fn l1(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y).abs()).sum()
}

/// Fraction of target colours farther than `tol` (CIE76) from every source colour.
fn novel_fraction(source: &[[f32; 3]], target: &[[f32; 3]], tol: f32) -> f64 {
    // Quantise the source palette to keep the search small.
    let mut palette: Vec<[f32; 3]> = source
        .iter()
        .map(|c| c.map(|x| (x * 64.0).round() / 64.0))
        .collect();
    palette.sort_by(|a, b| a.partial_cmp(b).unwrap());
    palette.dedup();
    let novel = target
        .iter()
        .filter(|c| palette.iter().all(|p| delta_e76(**c, *p) > tol))
        .count();
    novel as f64 / target.len() as f64
}

fn check(
    name: &str,
    source: &TriMesh,
    target: &TriMesh,
    corr: &[Correspondence],
) -> (PreparedMesh, PreparedMesh, TransferResult) {
    let params = TransferParams {
        vertices: 12_000,
        iterations: 3,
        ..TransferParams::default()
    };
    let cancel = CancelToken::new();
    let ps = prepare(source, &params, &no_events, &cancel).unwrap();
    let pt = prepare(target, &params, &no_events, &cancel).unwrap();
    let r = solve(&ps, &pt, corr, &params, &no_events, &cancel).unwrap();
    let src_colors = ps.signal().expect("source signal");
    let hs = lab_histogram(ps.working_mesh(), src_colors);
    let ht = lab_histogram(pt.working_mesh(), &r.working_signal);
    // Baseline: the source's mean colour everywhere.
    let mean = {
        let mut m = [0.0f32; 3];
        for c in src_colors {
            for k in 0..3 {
                m[k] += c[k] / src_colors.len() as f32;
            }
        }
        m
    };
    let hm = lab_histogram(pt.working_mesh(), &vec![mean; r.working_signal.len()]);
    let (d, d_mean) = (l1(&hs, &ht), l1(&hs, &hm));
    let novel = novel_fraction(src_colors, &r.working_signal, 6.0);
    eprintln!(
        "{name}: histogram L1 {d:.3} (mean-colour fill {d_mean:.3}), novel colours {:.2}%",
        100.0 * novel
    );
    assert!(
        d < 0.6 && d < 0.4 * d_mean,
        "{name}: colour distribution differs from the source's"
    );
    assert!(
        novel < 0.01,
        "{name}: {:.2}% of target vertices have colours the source lacks",
        100.0 * novel
    );
    (ps, pt, r)
}

#[test]
fn spot_onto_cow_keeps_spots_palette_and_proportions() {
    let spot = io::load(&data_path("spot/spot.obj")).unwrap();
    let cow = io::load(&data_path("cow/cow.ply")).unwrap();
    check("spot -> cow", &spot, &cow, &[]);
}

#[test]
fn spot_onto_horse_keeps_spots_palette_and_proportions() {
    let spot = io::load(&data_path("spot/spot.obj")).unwrap();
    let horse = io::load(&data_path("horse/horse.ply")).unwrap();
    check("spot -> horse", &spot, &horse, &[]);
}

#[test]
fn zebra_onto_giraffe_keeps_the_stripes_palette_and_proportions() {
    let (zebra, giraffe) = (demo::zebra(), demo::giraffe());
    let corr = demo::default_correspondences(
        &zebra,
        &demo::landmarks_zebra(),
        &giraffe,
        &demo::landmarks_giraffe(),
    );
    check("zebra -> giraffe", &zebra, &giraffe, &corr.correspondences);
}

#[test]
fn zebra_onto_cerberus_keeps_the_stripes_palette_and_proportions() {
    let (zebra, cerberus) = (demo::zebra(), demo::cerberus());
    let corr = demo::default_correspondences(
        &zebra,
        &demo::landmarks_zebra(),
        &cerberus,
        &demo::landmarks_cerberus(),
    );
    assert!(
        corr.correspondences
            .iter()
            .any(|c| c.target_vertices.len() == 3),
        "the cerberus pairs include one-to-many entries"
    );
    check(
        "zebra -> cerberus",
        &zebra,
        &cerberus,
        &corr.correspondences,
    );
}
