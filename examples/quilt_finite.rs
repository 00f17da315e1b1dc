//! Finite swatches as an artist models them (`quilting::finite_patch`: interlinked tilted rings,
//! a finite weave, a pebble cluster) quilted over the bunny, the horse and a saddle with the
//! swatch a tenth of the base's diagonal wide (`FRAC`). Per run: how the tile was found, element
//! density over the swatch's (all, convex, saddle regions), the share of the swatch's links
//! reproduced, element pairs whose surfaces cross, coverage and run time.
//! `cargo run --release --example quilt_finite` (`KIND=rings-patch|weave-patch|pebbles`,
//! `BASE=bunny|horse|saddle|cylinder` (a limb of radius 1 and length 12, only when named), `DETECT=0` for the box tiling without detection, `LATTICE=0` for the
//! paper's matching on every patch, `FILL=0` without the gap filling, `TRIM=0` with whole threads only, `RELINK=0` without relinking broken chains, `SEED=n` the run's seed, `OUT=dir` to write each quilt as OBJ, with `CROP=x,y,z` also the elements and base faces within
//! 1.2 swatch widths of that point, for close-up renders, and with `CENTRES=1` each element's
//! vertex centroid and share of its swatch element, for density maps).
use glam::Vec3;
use meshmatch::synthesis::quilting::{self, Input, Params, PatchKind, finite_patch, load_swatch};
use meshmatch::work::{CancelToken, no_events};

fn main() {
    let frac: f32 = std::env::var("FRAC")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(0.1);
    let out_dir = std::env::var("OUT").ok();
    println!(
        "| swatch | base | tiled by | elements | density (convex / saddle) | links reproduced | crossing pairs | coverage | time |"
    );
    println!("| --- | --- | --- | ---: | --- | --- | ---: | ---: | ---: |");
    for kind in PatchKind::ALL {
        if std::env::var("KIND").is_ok_and(|k| k != kind.as_str()) {
            continue;
        }
        let sw = load_swatch(finite_patch(kind, 1), quilting::Axis::Z).expect("swatch");
        // the cylinder (a limb as thin as a patch is wide) only when asked for
        let cylinder = std::env::var("BASE").is_ok_and(|b| b == "cylinder");
        let bases: &[&str] = if cylinder {
            &["cylinder"]
        } else {
            &["bunny", "horse", "saddle"]
        };
        for &name in bases {
            if std::env::var("BASE").is_ok_and(|b| b != name) {
                continue;
            }
            let base = match name {
                "bunny" => meshmatch::testdata::data_path("bunny/bunny.obj"),
                "horse" => meshmatch::testdata::data_path("horse/horse.ply"),
                _ => Default::default(),
            };
            let base = if name == "saddle" {
                quilting::saddle(0.5, 64)
            } else if name == "cylinder" {
                {
                    let (p, f) = meshmatch::testdata::cylinder(1.0, 12.0, 64, 200);
                    meshmatch::TriMesh::new(p, f)
                }
            } else {
                let mut b = meshmatch::mesh::io::load(&base).expect("base");
                b.repair().expect("repair");
                b
            };
            let (lo, hi) = base.bounds().expect("bounds");
            let diag = Vec3::from(hi).distance(Vec3::from(lo));
            let params = Params {
                swatch_size: Some(frac * diag),
                detect_period: !std::env::var("DETECT").is_ok_and(|v| v == "0"),
                lattice: !std::env::var("LATTICE").is_ok_and(|v| v == "0"),
                fill: !std::env::var("FILL").is_ok_and(|v| v == "0"),
                trim: !std::env::var("TRIM").is_ok_and(|v| v == "0"),
                relink: !std::env::var("RELINK").is_ok_and(|v| v == "0"),
                seed: std::env::var("SEED")
                    .ok()
                    .and_then(|s| s.parse().ok())
                    .unwrap_or(1),
                ..Params::default()
            };
            let input = Input {
                base: &base,
                swatch: &sw,
                field: None,
            };
            let out = quilting::run(&input, &params, &no_events, &CancelToken::new()).expect("run");
            let crossing = quilting::crossing_pairs(&out).len();
            let s = &out.stats;
            let opt = |x: Option<f32>| x.map_or("-".to_string(), |v| format!("{v:.2}"));
            println!(
                "| {} | {} | {} ({}) | {} | {:.2} ({} / {}) | {} ({:.2} per element; swatch {:.2} on its lattice, {:.2} as modelled) | {} | {:.3} | {:.1} s |",
                kind.as_str(),
                name,
                s.periodicity,
                s.tile_elements,
                s.elements,
                s.density_ratio,
                opt(s.density_ratio_convex),
                opt(s.density_ratio_saddle),
                s.link_share
                    .map_or("-".to_string(), |x| format!("{:.0}%", 100.0 * x)),
                s.links_per_element,
                s.swatch_links_per_element,
                s.modelled_links_per_element,
                crossing,
                s.coverage,
                s.seconds
            );
            if std::env::var("STATS").is_ok_and(|v| v == "1") {
                println!("{s:?}");
            }
            if let Some(dir) = &out_dir {
                let path = std::path::Path::new(dir).join(format!("{}_{name}.obj", kind.as_str()));
                quilting::save_quilt_obj(&out, Some(&base), &path).expect("write");
                if std::env::var("CENTRES").is_ok_and(|v| v == "1") {
                    // each element's vertex centroid and share, for density maps
                    let mut sum = vec![(Vec3::ZERO, 0usize); out.num_elements()];
                    for (v, &e) in out.element_id.iter().enumerate() {
                        sum[e as usize].0 += Vec3::from(out.elements.positions[v]);
                        sum[e as usize].1 += 1;
                    }
                    let text: String = sum
                        .iter()
                        .zip(&out.element_share)
                        .map(|((c, n), w)| {
                            let c = *c / (*n).max(1) as f32;
                            format!("{} {} {} {w}\n", c.x, c.y, c.z)
                        })
                        .collect();
                    // each element's links (by the linking number of centre curves)
                    let curves: Vec<Option<Vec<Vec3>>> = (0..out.num_elements())
                        .map(|e| {
                            let vs: Vec<usize> = (0..out.element_id.len())
                                .filter(|&v| out.element_id[v] as usize == e)
                                .collect();
                            let (v0, v1) = (vs[0], vs[vs.len() - 1] + 1);
                            let ps = &out.elements.positions[v0..v1];
                            let fs: Vec<[u32; 3]> = out
                                .elements
                                .faces
                                .iter()
                                .filter(|f| (v0..v1).contains(&(f[0] as usize)))
                                .map(|f| f.map(|v| v - v0 as u32))
                                .collect();
                            quilting::links::centre_curve(ps, &fs)
                        })
                        .collect();
                    let mut degree = vec![0u32; out.num_elements()];
                    for (a, b) in quilting::links::linked_pairs(&curves) {
                        degree[a as usize] += 1;
                        degree[b as usize] += 1;
                    }
                    let text: String = text
                        .lines()
                        .zip(&degree)
                        .map(|(l, d)| format!("{l} {d}\n"))
                        .collect();
                    let path = std::path::Path::new(dir)
                        .join(format!("{}_{name}_centres.txt", kind.as_str()));
                    std::fs::write(path, text).expect("write");
                }
                if let Ok(c) = std::env::var("CROP") {
                    let c: Vec<f32> = c.split(',').filter_map(|x| x.parse().ok()).collect();
                    let c = Vec3::new(c[0], c[1], c[2]);
                    let r = 1.2 * frac * diag;
                    let near = |p: &[f32; 3]| Vec3::from(*p).distance(c) <= r;
                    let mut positions = Vec::new();
                    let mut faces = Vec::new();
                    let m = &out.elements;
                    let mut keep = vec![true; out.num_elements()];
                    for (v, p) in m.positions.iter().enumerate() {
                        if !near(p) {
                            keep[out.element_id[v] as usize] = false;
                        }
                    }
                    let mut map = vec![u32::MAX; m.num_vertices()];
                    for (v, p) in m.positions.iter().enumerate() {
                        if keep[out.element_id[v] as usize] {
                            map[v] = positions.len() as u32;
                            positions.push(*p);
                        }
                    }
                    for f in &m.faces {
                        if map[f[0] as usize] != u32::MAX {
                            faces.push(f.map(|v| map[v as usize]));
                        }
                    }
                    let o = positions.len() as u32;
                    positions.extend_from_slice(&base.positions);
                    faces.extend(
                        base.faces
                            .iter()
                            .filter(|f| f.iter().all(|&v| near(&base.positions[v as usize])))
                            .map(|f| f.map(|v| v + o)),
                    );
                    let mut crop = meshmatch::TriMesh::new(positions, faces);
                    let _ = crop.repair();
                    let path = std::path::Path::new(dir)
                        .join(format!("{}_{name}_close.obj", kind.as_str()));
                    meshmatch::mesh::io::save(&crop, &path).expect("write");
                }
            }
        }
    }
}
