//! The curve-guided field's greedy orientation, one curve per step (the paper) against batches:
//! `cargo run --release --no-default-features --example field_batch`. Prints each run's time,
//! steps and how many curves end up oriented as the one-per-step run orients them (up to one
//! global flip) and the field's roughness, on the demo giraffe and Spot.
use meshmatch::geometry::{
    CurveParams, FieldCurve, FieldParams, field_roughness, oriented_curve_field, salient_curves,
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
            // Roughness of the unit field (lower is smoother, a consistent orientation).
            let rough = field_roughness(&mesh.faces, &f.field);
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
                rough
            );
            if reference.is_none() {
                reference = Some(f.forward.clone());
            }
        }
    }
}
