//! Salient curves on boxes with constant-radius rounded edges (meshed from a signed distance,
//! an irregular triangulation): `cargo run --release --example rounded_edges`. Prints, per fillet
//! radius, how many of the 12 edges a curve follows (within two mean edge lengths of the fillet's
//! middle line over 80% of its length) and how many curves lie off every edge.
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
        if std::env::var("RELAX").is_ok() {
            meshmatch::demo::sdf::relax(&mut mesh, &f, 5, 1e-4);
        }
        let h = mean_edge_length(&mesh.positions, &mesh.faces);
        let t = std::time::Instant::now();
        let curves = salient_curves(
            &mesh.positions,
            &mesh.faces,
            &CurveParams {
                smooth: std::env::var("SMOOTH")
                    .map(|s| s.parse().unwrap())
                    .unwrap_or(1),
                ..CurveParams::default()
            },
        )
        .unwrap();
        let secs = t.elapsed().as_secs_f64();
        // the 12 edges' middle lines: on the fillet, at 45 degrees
        let c = 0.5 - r + r * std::f32::consts::FRAC_1_SQRT_2;
        let _ = c;
        let mut edges = Vec::new();
        for axis in 0..3 {
            for (sa, sb) in [(1.0f32, 1.0f32), (1.0, -1.0), (-1.0, 1.0), (-1.0, -1.0)] {
                let pts: Vec<Vec3> = (0..=40)
                    .map(|i| {
                        let t = -0.4 * (0.5 - r) * 2.0 + 0.8 * (0.5 - r) * 2.0 * i as f32 / 40.0;
                        let mut p = [0.0f32; 3];
                        p[axis] = t * 0.5;
                        p[(axis + 1) % 3] = sa * c;
                        p[(axis + 2) % 3] = sb * c;
                        Vec3::from(p)
                    })
                    .collect();
                edges.push(pts);
            }
        }
        let near = |p: Vec3| {
            curves
                .iter()
                .flat_map(|c| c.points.iter())
                .any(|q| Vec3::from(*q).distance(p) < 2.0 * h)
        };
        let found = edges
            .iter()
            .filter(|e| e.iter().filter(|p| near(**p)).count() as f32 >= 0.8 * e.len() as f32)
            .count();
        let stray = curves
            .iter()
            .filter(|c| {
                !c.points.iter().any(|q| {
                    edges
                        .iter()
                        .flatten()
                        .any(|p| p.distance(Vec3::from(*q)) < 2.0 * h)
                })
            })
            .count();
        let cc = c;
        let (mut on_len, mut off) = (0.0f32, 0usize);
        {
            for c in &curves {
                // distance to the nearest edge's middle line (infinite), median over the curve
                let mut ds: Vec<f32> = c
                    .points
                    .iter()
                    .map(|q| {
                        let q = Vec3::from(*q).abs();
                        (0..3)
                            .map(|a| {
                                let (u, v) = (q[(a + 1) % 3], q[(a + 2) % 3]);
                                ((u - cc).powi(2) + (v - cc).powi(2)).sqrt()
                            })
                            .fold(f32::INFINITY, f32::min)
                    })
                    .collect();
                ds.sort_by(f32::total_cmp);
                let md = ds[ds.len() / 2];
                if md < 2.0 * h {
                    on_len += c.length();
                } else {
                    off += 1;
                }
                if std::env::var("VERBOSE").is_err() {
                    continue;
                }
                println!(
                    "  {:?} {} points, length {:.3}, strength {:.1}, median distance to the middle line {:.1} h",
                    c.kind,
                    c.points.len(),
                    c.length(),
                    c.strength,
                    md / h
                );
            }
        }
        println!(
            "fillet radius {r} ({:.1} edge lengths): {} vertices, {} curves in {secs:.2} s; on the middle lines (median distance < 2 h): {:.0}% of the 12 edges' straight length; {off} curves off them (old measure: {found} of 12 edges, {stray} stray)",
            r / h,
            mesh.num_vertices(),
            curves.len(),
            100.0 * on_len / (12.0 * 2.0 * (0.5 - r))
        );
    }
}
