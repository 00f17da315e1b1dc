//! Does the visiting order matter to the fan sampling table and the fans? The horse refined to
//! `N` working vertices (default 256K), its fan table built and one 3-channel fan gather run
//! visiting the vertices in the refinement's order (the identity) and in the Morton order that
//! `FanSampler::new` uses (its walks on a copy of the level renumbered in that order), both on
//! the mesh as refined; then the same mesh renumbered in Morton order and visited in vertex
//! order on the level itself, as MeshMatch's working meshes are (`meshmatch::prepare` renumbers
//! them; `FanSampler::in_vertex_order`). Best of three each.
//! `cargo run --release --example fan_order` (`N=1000000` for a film-resolution mesh).
//!
//! Renumbering the working meshes was once tried and dropped: with a Morton ordered example,
//! completion by example lost its quality. The cause was a bug in `mesh::connected_components`
//! (a face's stale root could be relinked, splitting a component, and the HKS eigen-solve then
//! saw spurious components), not the order; it is fixed, and the hierarchy breaks its ties by
//! the refinement's numbering (`Hierarchy::build_keyed`), so renumbering leaves it unchanged.
use meshmatch::features::{FanSampler, tangent_frames};
use meshmatch::hierarchy::Level;
use meshmatch::work::CancelToken;
use std::time::Instant;

fn best_of_3(mut f: impl FnMut()) -> f64 {
    let mut best = f64::INFINITY;
    for _ in 0..3 {
        let t = Instant::now();
        f();
        best = best.min(t.elapsed().as_secs_f64());
    }
    best
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
    let cancel = CancelToken::new();
    let run = |lev: &Level, order: Vec<u32>, name: &str| {
        let frames = tangent_frames(&lev.normals);
        let radius = 2.5 * lev.mean_edge;
        let mut s = FanSampler::default();
        let table = best_of_3(|| {
            s = FanSampler::with_order(lev, &frames, radius, &order, &cancel)
                .expect("a permutation");
        });
        let signal: Vec<f32> = lev.positions.iter().flatten().copied().collect();
        let mut out = Vec::new();
        let gather = best_of_3(|| s.fans_into(lev, &signal, 3, &mut out));
        println!(
            "{name}: {} vertices, fan table {table:.3} s, 3-channel fans {gather:.3} s (best of 3)",
            lev.len()
        );
    };
    let lev = Level::new(p.clone(), f.clone());
    let identity: Vec<u32> = (0..p.len() as u32).collect();
    run(&lev, identity, "refined order, visited in order");
    run(
        &lev,
        meshmatch::geometry::morton_order(&lev.positions),
        "refined order, visited in Morton order (the default)",
    );
    drop(lev);
    let order = meshmatch::geometry::morton_order(&p);
    let inv = meshmatch::geometry::inverse_order(&order);
    let pm: Vec<[f32; 3]> = order.iter().map(|&i| p[i as usize]).collect();
    let mut fm: Vec<[u32; 3]> = f.iter().map(|t| t.map(|v| inv[v as usize])).collect();
    fm.sort_by_key(|t| *t.iter().min().unwrap_or(&0));
    let lev = Level::new(pm, fm);
    let identity: Vec<u32> = (0..lev.len() as u32).collect();
    run(
        &lev,
        identity,
        "renumbered in Morton order, visited in order",
    );
}
