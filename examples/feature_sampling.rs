//! The Mertens features evaluated sparsely (`weathering::features`: curvature at radius `r` on a
//! grid of `r / 4`, occlusion on the finest grid, interpolated back) against every vertex
//! evaluated (`solid_angle_curvature` and `directional_occlusion` on all vertices), on the horse
//! refined to `N` points (default 100000; `N=500000 cargo run --release --example
//! feature_sampling`), with the same opening criterion per radius. `BRUTE=1` also checks the
//! tree against every triangle summed exactly at 1000 vertices. Prints the time of each and, per feature column, the correlation and the
//! mean absolute difference between the two; for occlusion, also the difference between two
//! full evaluations with different ray seeds (the noise floor the sparse one is judged against).
use meshmatch::geometry::{
    SolidAngleCurvature, directional_occlusion, refine_to_density, vertex_normals,
};
use meshmatch::synthesis::weathering::{Params, features_on_surface, opening_for_radius};
use meshmatch::work::{CancelToken, Stopwatch};

fn std(a: &[f32]) -> f64 {
    let n = a.len() as f64;
    let m = a.iter().map(|&x| x as f64).sum::<f64>() / n;
    (a.iter().map(|&x| (x as f64 - m).powi(2)).sum::<f64>() / n).sqrt()
}

fn corr(a: &[f32], b: &[f32]) -> (f64, f64) {
    let n = a.len() as f64;
    let (ma, mb) = (
        a.iter().map(|&x| x as f64).sum::<f64>() / n,
        b.iter().map(|&x| x as f64).sum::<f64>() / n,
    );
    let (mut sab, mut saa, mut sbb, mut mad) = (0.0, 0.0, 0.0, 0.0);
    for (&x, &y) in a.iter().zip(b) {
        let (dx, dy) = (x as f64 - ma, y as f64 - mb);
        sab += dx * dy;
        saa += dx * dx;
        sbb += dy * dy;
        mad += (x as f64 - y as f64).abs();
    }
    (sab / (saa * sbb).sqrt().max(1e-30), mad / n)
}

fn main() {
    let n: usize = std::env::var("N")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(100_000);
    let name = std::env::var("MESH").unwrap_or_else(|_| "horse/horse.ply".into());
    let mut mesh = meshmatch::mesh::io::load(&meshmatch::testdata::data_path(&name)).expect("mesh");
    mesh.repair().expect("repair");
    let r = refine_to_density(&mesh, n);
    let (p, f) = (&r.mesh.positions, &r.mesh.faces);
    let params = Params::default();
    let sw = Stopwatch::start();
    let fs = features_on_surface(
        p,
        f,
        Some((&mesh.positions, &mesh.faces)),
        &params,
        &CancelToken::new(),
    )
    .expect("features");
    let sparse_s = sw.secs();
    println!(
        "{name} at {} points: sparse features {sparse_s:.2} s (curvature {:.2}, occlusion {:.2})",
        p.len(),
        fs.seconds[1],
        fs.seconds[2]
    );
    let radii = fs.radii.clone();
    // the same orientation as the features use
    let flipped: Vec<[u32; 3]> = f.iter().map(|t| [t[0], t[2], t[1]]).collect();
    let f = if fs.flipped { &flipped } else { f };
    let sw = Stopwatch::start();
    // the same opening criterion per radius as the features use, so that only the sampling
    // differs
    let r_min = radii.iter().copied().fold(f32::INFINITY, f32::min);
    let sac = SolidAngleCurvature::new(p, f);
    let all: Vec<u32> = (0..p.len() as u32).collect();
    let cols: Vec<Vec<f32>> = radii
        .iter()
        .map(|&r| {
            let beta = opening_for_radius(r, r_min);
            sac.at(&all, &[r], beta, &CancelToken::new())
                .expect("curvature")
        })
        .collect();
    let curv: Vec<f32> = (0..p.len())
        .flat_map(|v| cols.iter().map(move |c| c[v]))
        .collect();
    let curv_s = sw.secs();
    let normals = vertex_normals(p, f);
    let sw = Stopwatch::start();
    let occ = directional_occlusion(p, f, &normals, params.rays, params.seed);
    let occ_s = sw.secs();
    let occ2 = directional_occlusion(p, f, &normals, params.rays, params.seed + 1);
    println!("every vertex: curvature {curv_s:.2} s, occlusion {occ_s:.2} s");
    let nr = radii.len();
    let col = |name: &str| {
        let c = fs.column(name).expect("column");
        fs.values
            .iter()
            .skip(c)
            .step_by(fs.dim)
            .copied()
            .collect::<Vec<f32>>()
    };
    if std::env::var("BRUTE").is_ok() {
        let tree = meshmatch::geometry::SolidAngleTree::new(p, f);
        let mut stack = Vec::new();
        for (j, &r) in radii.iter().enumerate() {
            let (mut a, mut b, mut sp, mut fu) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
            let spc = col(&format!("curvature-{j}"));
            for v in (0..p.len()).step_by(p.len() / 1000) {
                a.push(brute_omega(p[v], r, p, f));
                b.push(tree.solid_angle_in_ball(p[v], r, 2.5, &mut stack));
                sp.push(spc[v] * std::f32::consts::TAU);
                fu.push(curv[v * nr + j] * std::f32::consts::TAU);
            }
            let (c, d) = corr(&a, &b);
            let (c2, d2) = corr(&a, &sp);
            let (c3, d3) = corr(&a, &fu);
            println!(
                "   sparse against brute force: {c2:.4} {:.5}; full (with cone) {c3:.4} {:.5}",
                d2 / std::f64::consts::TAU,
                d3 / std::f64::consts::TAU
            );
            println!(
                "radius {j}: tree against brute force over 1000 vertices: correlation {c:.4}, mean abs diff of omega/2pi {:.5}, std {:.4}",
                d / std::f64::consts::TAU,
                std(&a) / std::f64::consts::TAU
            );
        }
    }
    println!("| feature | correlation sparse/full | mean abs diff | full/full (other seed) |");
    for (j, r) in radii.iter().enumerate() {
        let full: Vec<f32> = curv.iter().skip(j).step_by(nr).copied().collect();
        let sp = col(&format!("curvature-{j}"));
        let (c, d) = corr(&sp, &full);
        println!(
            "| curvature-{j} (r {r:.4}, std full {:.4} sparse {:.4}) | {c:.4} | {d:.5} | - |",
            std(&full),
            std(&sp)
        );
    }
    for (k, name) in ["ao", "occlusion-x", "occlusion-y", "occlusion-z"]
        .iter()
        .enumerate()
    {
        let full: Vec<f32> = occ.iter().map(|o| o[k]).collect();
        let other: Vec<f32> = occ2.iter().map(|o| o[k]).collect();
        let (c, d) = corr(&col(name), &full);
        let (c2, d2) = corr(&other, &full);
        println!("| {name} | {c:.4} | {d:.5} | {c2:.4} / {d2:.5} |");
    }
}

/// Brute-force `Ω` of the surface inside `B(p, r)` (every triangle, clipped by area fraction).
pub fn brute_omega(p: [f32; 3], r: f32, pos: &[[f32; 3]], faces: &[[u32; 3]]) -> f32 {
    use glam::Vec3;
    let p = Vec3::from(p);
    let mut om = 0.0f64;
    for t in faces {
        let q = t.map(|v| Vec3::from(pos[v as usize]) - p);
        let s = q.map(|x| x.length() - r);
        let neg = s.iter().filter(|&&x| x < 0.0).count();
        let f = match neg {
            0 => 0.0,
            3 => 1.0,
            _ => {
                let lone_neg = neg == 1;
                let i = (0..3).find(|&i| (s[i] < 0.0) == lone_neg).unwrap_or(0);
                let (a, b, c) = (s[i], s[(i + 1) % 3], s[(i + 2) % 3]);
                let f = (a * a / ((a - b) * (a - c))).clamp(0.0, 1.0);
                if lone_neg { f } else { 1.0 - f }
            }
        };
        if f > 0.0 {
            let (a, b, c) = (q[0], q[1], q[2]);
            let (la, lb, lc) = (a.length(), b.length(), c.length());
            let num = a.dot(b.cross(c));
            let den = la * lb * lc + a.dot(b) * lc + a.dot(c) * lb + b.dot(c) * la;
            if num != 0.0 || den != 0.0 {
                om += (f * 2.0 * num.atan2(den)) as f64;
            }
        }
    }
    om as f32
}
