//! Greedy steps of the curve-guided field at several working sizes:
//! `cargo run --release --example field_steps`. For the shared horse and a 100K-vertex cube,
//! prints the time per greedy step (mean, max), the whole field's time, and how much of the
//! curves' length ends up oriented as the full-resolution greedy orients it.
use meshmatch::geometry::{
    Curve, CurveParams, FieldCurve, FieldParams, oriented_curve_field, salient_curves,
};
use meshmatch::synthesis::feature_aligned;
use meshmatch::work::CancelToken;
use std::time::Instant;

fn main() {
    let mut horse =
        meshmatch::mesh::io::load(&meshmatch::testdata::data_path("horse/horse.ply")).unwrap();
    horse.repair().unwrap();
    let sizes: Vec<usize> = std::env::args()
        .nth(1)
        .map(|s| s.split(',').map(|x| x.parse().unwrap()).collect())
        .unwrap_or(vec![24_000, 12_000, 8_000, 4_000]);
    for (name, mesh) in [
        ("horse", horse),
        ("cube", meshmatch::demo::crease_cube(129)),
    ] {
        let curves = salient_curves(&mesh.positions, &mesh.faces, &CurveParams::default()).unwrap();
        let fc: Vec<FieldCurve> = curves.iter().map(FieldCurve::from).collect();
        let t = Instant::now();
        let full = oriented_curve_field(
            &mesh.positions,
            &mesh.faces,
            &fc,
            &FieldParams::default(),
            &CancelToken::new(),
        )
        .unwrap();
        let report = |label: String,
                      f: &meshmatch::geometry::CurveField,
                      secs: f64,
                      greedy: usize| {
            let total: f32 = curves.iter().map(Curve::length).sum();
            let same: f32 = curves
                .iter()
                .enumerate()
                .filter(|(i, _)| f.forward[*i] == full.forward[*i])
                .map(|(_, c)| c.length())
                .sum();
            let steps = &f.step_secs[..greedy.min(f.step_secs.len())];
            let mean = steps.iter().sum::<f64>() / steps.len().max(1) as f64;
            let rough = meshmatch::geometry::field_roughness(&mesh.faces, &f.field);
            let max = steps.iter().cloned().fold(0.0, f64::max);
            println!(
                "{name} {} v, {} curves, {label}: {secs:.2} s, {} greedy steps, mean {:.0} ms, max {:.0} ms, same orientation {:.1}%, roughness {rough:.5}",
                mesh.num_vertices(),
                curves.len(),
                steps.len(),
                mean * 1e3,
                max * 1e3,
                100.0 * same / total
            );
        };
        report(
            "full".into(),
            &full,
            t.elapsed().as_secs_f64(),
            full.step_secs.len(),
        );
        for &s in &sizes {
            if s >= mesh.num_vertices() {
                continue;
            }
            let params = feature_aligned::Params {
                coarse_greedy_above: Some(s),
                greedy_vertices: s,
                ..Default::default()
            };
            let t = Instant::now();
            let (_, f, _) = feature_aligned::curves_and_field(
                &mesh,
                Some(&curves),
                &params,
                &CancelToken::new(),
            )
            .unwrap();
            let n = f.step_secs.len();
            report(
                format!("greedy at <= {s}"),
                &f,
                t.elapsed().as_secs_f64(),
                n,
            );
        }
    }
}
