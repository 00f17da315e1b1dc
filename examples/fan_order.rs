//! Does vertex order matter to the fan sampling table? The horse refined to `N` working
//! vertices (default 256K), its fan table built in the refined order and in a Morton (Z-curve)
//! order of the same vertices: seconds for each. `cargo run --release --example fan_order`.
//! (Measured: 5.8 s against 3.1 s at 256K. Working meshes are not reordered yet: with a Morton
//! ordered source, completion by example lost its quality (mean patch distance 1.2 against
//! 0.07). The hierarchy's edge collapse breaks ties by vertex index, and in that order it left
//! 4 vertices of the painted region without faces at level 1 (5 components against 1): the
//! collapse must not strand vertices before meshes can be reordered. Rejecting collapses that
//! strand a vertex or pinch the boundary was tried: the completion test's colour distance fell
//! from 61 to 36 (12 in the refinement's order), so another order dependence remains.)
use meshmatch::features::{FanSampler, tangent_frames};
use meshmatch::hierarchy::Level;
use std::time::Instant;

fn morton(p: [f32; 3], lo: [f32; 3], scale: f32) -> u64 {
    let spread = |x: u32| {
        let mut v = x as u64 & 0x1f_ffff;
        v = (v | v << 32) & 0x1f00000000ffff;
        v = (v | v << 16) & 0x1f0000ff0000ff;
        v = (v | v << 8) & 0x100f00f00f00f00f;
        v = (v | v << 4) & 0x10c30c30c30c30c3;
        (v | v << 2) & 0x1249249249249249
    };
    let q = |k: usize| (((p[k] - lo[k]) * scale).clamp(0.0, 2_097_151.0)) as u32;
    spread(q(0)) | spread(q(1)) << 1 | spread(q(2)) << 2
}

fn main() {
    let n: usize = std::env::var("N")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(256_000);
    let mut m = meshmatch::mesh::io::load(&meshmatch::testdata::data_path("horse/horse.ply"))
        .expect("horse");
    m.repair().expect("repair");
    let r = meshmatch::geometry::refine_to_density(&m, n);
    let (p, f) = (r.mesh.positions, r.mesh.faces);
    let time = |p: Vec<[f32; 3]>, f: Vec<[u32; 3]>, name: &str| {
        let lev = Level::new(p, f);
        let frames = tangent_frames(&lev.normals);
        let mut best = f64::INFINITY;
        for _ in 0..3 {
            let t = Instant::now();
            let s = FanSampler::new(&lev, &frames, 2.5 * lev.mean_edge);
            best = best.min(t.elapsed().as_secs_f64());
            std::hint::black_box(&s);
        }
        println!(
            "{name}: {} vertices, fan table {best:.3} s (best of 3)",
            lev.len()
        );
    };
    time(p.clone(), f.clone(), "refined order");
    let (mut lo, mut hi) = ([f32::MAX; 3], [f32::MIN; 3]);
    for q in &p {
        for k in 0..3 {
            lo[k] = lo[k].min(q[k]);
            hi[k] = hi[k].max(q[k]);
        }
    }
    let ext = (0..3)
        .map(|k| hi[k] - lo[k])
        .fold(0.0f32, f32::max)
        .max(1e-30);
    let mut order: Vec<u32> = (0..p.len() as u32).collect();
    order.sort_by_key(|&i| morton(p[i as usize], lo, 2_097_151.0 / ext));
    let mut inv = vec![0u32; p.len()];
    for (new, &old) in order.iter().enumerate() {
        inv[old as usize] = new as u32;
    }
    let pm: Vec<[f32; 3]> = order.iter().map(|&i| p[i as usize]).collect();
    let mut fm: Vec<[u32; 3]> = f.iter().map(|t| t.map(|v| inv[v as usize])).collect();
    fm.sort_by_key(|t| *t.iter().min().unwrap_or(&0));
    time(pm, fm, "Morton order");
}
