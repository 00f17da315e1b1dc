//! Salient curves on boxes with constant-radius rounded edges (CAD fillets), meshed from a
//! signed distance and relaxed on the surface: `cargo run --release --example rounded_edges`
//! (`RAW=1`: the marching-tetrahedra mesh unrelaxed, `VERBOSE=1`: every curve). Prints, per
//! fillet radius, the curves' length lying on the fillets' middle lines (median distance under
//! two mean edge lengths) as a share of the 12 edges' straight length, and the curves off them.
use glam::Vec3;
use meshmatch::geometry::{CurveParams, mean_edge_length, salient_curves};

fn main() {
    for r in [0.02f32, 0.05, 0.1, 0.2] {
        let half = Vec3::splat(0.5);
        let f = move |p: Vec3| {
            let q = p.abs() - (half - Vec3::splat(r));
            q.max(Vec3::ZERO).length() + q.max_element().min(0.0) - r
        };
        let mut mesh =
            meshmatch::demo::sdf::mesh_sdf(&f, Vec3::splat(-0.6), Vec3::splat(0.6), 0.015);
        if std::env::var("RAW").is_err() {
            meshmatch::demo::sdf::relax(&mut mesh, &f, 5, 1e-4);
        }
        let h = mean_edge_length(&mesh.positions, &mesh.faces);
        let t = std::time::Instant::now();
        let curves = salient_curves(&mesh.positions, &mesh.faces, &CurveParams::default()).unwrap();
        let secs = t.elapsed().as_secs_f64();
        // the middle lines of the fillets lie at 45 degrees on them
        let c = 0.5 - r + r * std::f32::consts::FRAC_1_SQRT_2;
        let (mut on_len, mut off) = (0.0f32, 0usize);
        for cv in &curves {
            // distance to the nearest edge's middle line (infinite), median over the curve
            let mut ds: Vec<f32> = cv
                .points
                .iter()
                .map(|q| {
                    let q = Vec3::from(*q).abs();
                    (0..3)
                        .map(|a| {
                            let (u, v) = (q[(a + 1) % 3], q[(a + 2) % 3]);
                            ((u - c).powi(2) + (v - c).powi(2)).sqrt()
                        })
                        .fold(f32::INFINITY, f32::min)
                })
                .collect();
            ds.sort_by(f32::total_cmp);
            let md = ds[ds.len() / 2];
            if md < 2.0 * h {
                on_len += cv.length();
            } else {
                off += 1;
            }
            if std::env::var("VERBOSE").is_ok() {
                println!(
                    "  {:?} {} points, length {:.3}, strength {:.1}, median distance to the middle line {:.1} h",
                    cv.kind,
                    cv.points.len(),
                    cv.length(),
                    cv.strength,
                    md / h
                );
            }
        }
        println!(
            "fillet radius {r} ({:.1} edge lengths): {} vertices, {} curves in {secs:.2} s; on the middle lines: {:.0}% of the 12 edges' straight length; {off} curves off them",
            r / h,
            mesh.num_vertices(),
            curves.len(),
            100.0 * on_len / (12.0 * 2.0 * (0.5 - r))
        );
    }
}
