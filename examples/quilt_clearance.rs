//! Do quilted elements keep clear of each other? Every built-in swatch over a plane, the bunny
//! and the horse with the swatch `FRAC` (default 0.1) of the base's diagonal wide: elements, the
//! smallest distance between vertices of different elements against the clearance the quilting
//! enforces (`tau`, half the swatch's own, scaled), the pairs of elements closer than `tau / 2`,
//! and the pairs whose surfaces cross (an edge of one piercing a triangle of the other, by ray
//! casting along every edge); and the face density against the swatch's (output faces per base
//! area over swatch faces per scaled swatch area). `cargo run --release --example
//! quilt_clearance` (`BASE=plane` for one base, `THICK` the shell thickness in swatch widths,
//! `MERGE=1` to merge threads across seams, `LATTICE=0` for the paper's matching on every patch, `DIST` the largest flattening distortion, `STATS=1`
//! to print each run's counters). Also the shell's L2 stretch before and after
//! its minimisation (`SWEEPS`, default the quilting's), and element size uniformity: each
//! element's surface area over its swatch element's (scaled), mean and coefficient of
//! variation.
use std::collections::HashMap;

use glam::Vec3;
use meshmatch::synthesis::quilting::{self, Input, Params, SwatchKind, swatch};
use meshmatch::work::{CancelToken, no_events};

fn main() {
    let frac: f32 = std::env::var("FRAC")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(0.1);
    let only = std::env::var("BASE").ok();
    // shell thickness in units of the swatch width (default: the swatch's own height)
    let thick: Option<f32> = std::env::var("THICK").ok().and_then(|s| s.parse().ok());
    let sweeps: Option<usize> = std::env::var("SWEEPS").ok().and_then(|s| s.parse().ok());
    for name in ["plane", "bunny/bunny.obj", "horse/horse.ply"] {
        if only.as_deref().is_some_and(|o| o != name) {
            continue;
        }
        let base = if name == "plane" {
            quilting::plane(1.0, 1.0, 64, 64)
        } else {
            let mut b =
                meshmatch::mesh::io::load(&meshmatch::testdata::data_path(name)).expect("base");
            b.repair().expect("repair");
            b
        };
        let (lo, hi) = base.bounds().expect("bounds");
        let diag = Vec3::from(hi).distance(Vec3::from(lo));
        for kind in SwatchKind::ALL {
            if std::env::var("KIND").is_ok_and(|k| k != kind.as_str()) {
                continue;
            }
            let sw = swatch(kind, 1);
            let params = Params {
                swatch_size: Some(frac * diag),
                thickness: thick.map(|t| t * frac * diag),
                shell_sweeps: sweeps.unwrap_or(Params::default().shell_sweeps),
                max_distortion: std::env::var("DIST")
                    .ok()
                    .and_then(|v| v.parse().ok())
                    .unwrap_or(Params::default().max_distortion),
                merge_elements: std::env::var("MERGE").is_ok_and(|v| v == "1"),
                nudge: !std::env::var("NUDGE").is_ok_and(|v| v == "0"),
                lattice: !std::env::var("LATTICE").is_ok_and(|v| v == "0"),
                patch_radius: std::env::var("PR")
                    .ok()
                    .and_then(|v| v.parse().ok())
                    .unwrap_or(Params::default().patch_radius),
                ..Params::default()
            };
            let out = quilting::run(
                &Input {
                    base: &base,
                    swatch: &sw,
                    field: None,
                },
                &params,
                &no_events,
                &CancelToken::new(),
            )
            .expect("quilt");
            if let Ok(dir) = std::env::var("OUT") {
                let file = format!(
                    "{dir}/{}_{}.obj",
                    name.split('/').next().unwrap_or(name),
                    kind.as_str()
                );
                quilting::save_quilt_obj(&out, Some(&base), std::path::Path::new(&file))
                    .expect("save");
            }
            if std::env::var("STATS").is_ok() {
                println!("{:?}", out.stats);
            }
            let l = out.stats.swatch_size;
            let tau = 0.5 * sw.clearance() * l / sw.extent[0];
            // vertex grid of cell tau
            let mut grid: HashMap<[i32; 3], Vec<u32>> = HashMap::new();
            let key = |p: Vec3| {
                let q = (p / tau).floor();
                [q.x as i32, q.y as i32, q.z as i32]
            };
            let pos = &out.elements.positions;
            for (i, p) in pos.iter().enumerate() {
                grid.entry(key(Vec3::from(*p))).or_default().push(i as u32);
            }
            let mut dmin = f32::INFINITY;
            let mut close: std::collections::HashSet<(u32, u32)> = Default::default();
            for (i, p) in pos.iter().enumerate() {
                let p = Vec3::from(*p);
                let k = key(p);
                for dz in -1..=1 {
                    for dy in -1..=1 {
                        for dx in -1..=1 {
                            let Some(l) = grid.get(&[k[0] + dx, k[1] + dy, k[2] + dz]) else {
                                continue;
                            };
                            for &j in l {
                                let (a, b) = (out.element_id[i], out.element_id[j as usize]);
                                if a == b {
                                    continue;
                                }
                                let d = p.distance(Vec3::from(pos[j as usize]));
                                dmin = dmin.min(d);
                                if d < 0.5 * tau {
                                    close.insert((a.min(b), a.max(b)));
                                }
                            }
                        }
                    }
                }
            }
            let pierce = quilting::crossing_pairs(&out);
            // face density against the swatch's: output faces per base area over swatch faces
            // per (scaled) swatch area
            let base_area: f64 = meshmatch::geometry::face_areas(&base.positions, &base.faces)
                .iter()
                .sum();
            let s = l / sw.extent[0];
            let swatch_density =
                sw.mesh.num_faces() as f64 / (sw.extent[0] * sw.extent[1] * s * s) as f64;
            let density = out.elements.num_faces() as f64 / base_area / swatch_density;
            // element area over its swatch element's, scaled
            let area = |pos: &[[f32; 3]], faces: &[[u32; 3]]| -> f64 {
                meshmatch::geometry::face_areas(pos, faces).iter().sum()
            };
            // per element: its vertex and face ranges (contiguous in the output); merged
            // elements (several swatch copies joined) have no single swatch element to compare
            // with and are left out of the size statistics
            let ne = out.num_elements();
            let mut vr = vec![(usize::MAX, 0usize); ne];
            for (v, &e) in out.element_id.iter().enumerate() {
                let r = &mut vr[e as usize];
                r.0 = r.0.min(v);
                r.1 = r.1.max(v + 1);
            }
            let mut fr = vec![(usize::MAX, 0usize); ne];
            for (k, f) in out.elements.faces.iter().enumerate() {
                let r = &mut fr[out.element_id[f[0] as usize] as usize];
                r.0 = r.0.min(k);
                r.1 = r.1.max(k + 1);
            }
            let mut ratios = Vec::new();
            for (e, &src) in out.element_source.iter().enumerate() {
                if out.element_pieces[e] != 1 {
                    continue;
                }
                let (v0, v1) = vr[e];
                let faces: Vec<[u32; 3]> = out.elements.faces[fr[e].0..fr[e].1]
                    .iter()
                    .map(|f| f.map(|v| v - v0 as u32))
                    .collect();
                let a_out = area(&out.elements.positions[v0..v1], &faces);
                let a_in = area(
                    sw.element_positions(src as usize),
                    &sw.element_faces(src as usize),
                ) * (s * s) as f64;
                if a_in > 0.0 {
                    ratios.push(a_out / a_in);
                }
            }
            let m = ratios.iter().sum::<f64>() / ratios.len().max(1) as f64;
            let cv = (ratios.iter().map(|r| (r - m) * (r - m)).sum::<f64>()
                / ratios.len().max(1) as f64)
                .sqrt()
                / m;
            println!(
                "{name} {kind:?}: {} elements ({} merged), face density {:.2} of the swatch's, element area {m:.3} of the swatch's (CV {cv:.3}), shell L2 {:.4} -> {:.4}, min vertex distance {:.3} tau, {} element pairs closer than tau/2, {} pairs interpenetrating, {:.2} s",
                out.num_elements(),
                out.element_pieces.iter().filter(|&&k| k > 1).count(),
                density,
                out.stats.shell_stretch_before,
                out.stats.shell_stretch,
                dmin / tau,
                close.len(),
                pierce.len(),
                out.stats.seconds
            );
        }
    }
}
