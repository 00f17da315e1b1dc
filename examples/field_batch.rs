//! The curve-guided field's greedy orientation, one curve per step (the paper) against batches:
//! `cargo run --release --no-default-features --example field_batch`. Prints each run's time,
//! steps and how many curves end up oriented as the one-per-step run orients them (up to one
//! global flip) and the field's roughness, on the demo giraffe and Spot.
use meshmatch::geometry::{
    CurveParams, FieldCurve, FieldParams, oriented_curve_field, salient_curves,
};
use meshmatch::work::CancelToken;
use std::time::Instant;

fn main() {
    let spot =
        meshmatch::mesh::io::load(&meshmatch::testdata::data_path("spot/spot.obj")).expect("spot");
    for (name, mesh) in [("giraffe", meshmatch::demo::giraffe()), ("spot", spot)] {
        let curves =
            salient_curves(&mesh.positions, &mesh.faces, &CurveParams::default()).expect("curves");
        let fc: Vec<FieldCurve> = curves.iter().map(FieldCurve::from).collect();
        let mut reference: Option<Vec<bool>> = None;
        for batch in [0.0, 0.125, 0.25] {
            let t = Instant::now();
            let f = oriented_curve_field(
                &mesh.positions,
                &mesh.faces,
                &fc,
                &FieldParams {
                    batch,
                    ..FieldParams::default()
                },
                &CancelToken::new(),
            )
            .expect("field");
            let secs = t.elapsed().as_secs_f64();
            // Roughness of the unit field: mean |f_a - f_b|² over the edges (lower is smoother,
            // a consistent orientation).
            let (mut e, mut m) = (0.0f64, 0usize);
            for tri in &mesh.faces {
                for k in 0..3 {
                    let (a, b) = (tri[k] as usize, tri[(k + 1) % 3] as usize);
                    e += (0..3)
                        .map(|d| ((f.field[a][d] - f.field[b][d]) as f64).powi(2))
                        .sum::<f64>();
                    m += 1;
                }
            }
            let agree = reference.as_ref().map(|r| {
                let same = r.iter().zip(&f.forward).filter(|(a, b)| a == b).count();
                same.max(r.len() - same)
            });
            println!(
                "{name}: {} vertices, {} curves, batch {batch}: {secs:.2} s, {} steps, agree {:?}, \
                 roughness {:.5}",
                mesh.num_vertices(),
                fc.len(),
                f.step_secs.len(),
                agree,
                e / m.max(1) as f64
            );
            if reference.is_none() {
                reference = Some(f.forward.clone());
            }
        }
    }
}
