//! Criterion benchmarks of MeshMatch's stages on the shared data (Spot textured as source, the
//! horse as target): hierarchy, HKS shape features, fan sampling tables, the whole preparation
//! of each mesh, and a solve (coarse-to-fine EM) on prepared meshes. `meshmatch bench` reports the
//! same stages per working resolution with the exact-search baseline; these are the
//! statistically repeated micro-measurements (`cargo bench --bench stages`).

use criterion::{Criterion, criterion_group, criterion_main};
use meshmatch::features::{FanSampler, shape_features, tangent_frames};
use meshmatch::hierarchy::{Hierarchy, HierarchyOptions};
use meshmatch::meshmatch::{TransferParams, prepare, solve};
use meshmatch::work::{CancelToken, no_events};
use meshmatch::{TriMesh, mesh::io, testdata::data_path};
use std::hint::black_box;

/// Working vertices of both meshes in these benchmarks.
const N: usize = 16_000;

fn load(rel: &str) -> TriMesh {
    let mut m = io::load(&data_path(rel)).expect("the shared data is beside the repository");
    m.repair().expect("repairable");
    m
}

fn stages(c: &mut Criterion) {
    let spot = load("spot/spot.obj");
    let horse = load("horse/horse.ply");
    let params = TransferParams {
        vertices: N,
        ..TransferParams::default()
    };
    let cancel = CancelToken::new();
    let ps = prepare(&spot, &params, &no_events, &cancel).expect("prepare spot");
    let pt = prepare(&horse, &params, &no_events, &cancel).expect("prepare horse");
    let w = pt.working_mesh();
    let mut g = c.benchmark_group("stages");
    g.sample_size(10);
    g.bench_function("hierarchy (horse, 48K)", |b| {
        b.iter(|| {
            Hierarchy::build(
                black_box(&w.positions),
                &w.faces,
                HierarchyOptions::default(),
            )
            .expect("hierarchy")
        })
    });
    let h = pt.hierarchy();
    g.bench_function("shape features (horse)", |b| {
        b.iter(|| shape_features(black_box(h), 2_000).expect("features"))
    });
    let l0 = &h.levels[0];
    let frames = tangent_frames(&l0.normals);
    g.bench_function("fan table (horse, finest level)", |b| {
        b.iter(|| FanSampler::new(black_box(l0), &frames, params.fan_radius * l0.mean_edge))
    });
    let sampler = FanSampler::new(l0, &frames, params.fan_radius * l0.mean_edge);
    let signal: Vec<f32> = (0..l0.len() * 3).map(|i| (i % 7) as f32 / 7.0).collect();
    g.bench_function("fans from table (horse, RGB)", |b| {
        b.iter(|| sampler.fans(black_box(l0), &signal, 3))
    });
    g.bench_function("prepare spot (16K)", |b| {
        b.iter(|| prepare(black_box(&spot), &params, &no_events, &cancel).expect("prepare"))
    });
    g.bench_function("solve spot -> horse", |b| {
        b.iter(|| solve(black_box(&ps), &pt, &[], &params, &no_events, &cancel).expect("solve"))
    });
    g.finish();
}

criterion_group!(benches, stages);
criterion_main!(benches);
