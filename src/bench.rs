//! `meshmatch bench`: stage timings of a MeshMatch transfer at several working resolutions, on
//! inputs built from the shared data (Spot textured as source, the horse as target).

use crate::error::Result;
use crate::mesh::TriMesh;
use crate::meshmatch::{self as mm, TransferParams};
use crate::work::{CancelToken, Event};
use std::time::Instant;

/// One row of the benchmark table.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct BenchRow {
    /// Working vertices of the target.
    pub vertices: usize,
    /// Working vertices of the source.
    pub source_vertices: usize,
    /// Hierarchy construction, source + target, seconds.
    pub hierarchy_s: f64,
    /// Shape features (HKS and frames), source + target, seconds.
    pub hks_s: f64,
    /// Geodesic fans: both preparations' fan tables and the source's fans, plus the solve's
    /// "fan updates" (target tables built there, the per-iteration pre-filter of the target's
    /// signal; the target's fans themselves are gathered inside the E-step), seconds.
    pub fans_s: f64,
    /// E-step (propagation + random search) per EM iteration at the finest level, seconds.
    pub estep_s_per_iter: f64,
    /// M-step (voting) per EM iteration at the finest level, seconds.
    pub mstep_s_per_iter: f64,
    /// After a correspondence edit (six pairs, on the prepared meshes): from the start of the new
    /// solve, affinities included, to its first partial result, seconds.
    pub first_preview_s: f64,
    /// From the start of the first solve (no correspondences) to its first partial result.
    pub first_solve_preview_s: f64,
    /// Load-free end to end: prepare both meshes and solve, seconds.
    pub end_to_end_s: f64,
    /// Peak resident set size of the process so far, MiB.
    pub peak_rss_mb: f64,
    /// Final mean patch distance over the exact nearest-neighbour distance, on a sample of
    /// finest-level target vertices searched exhaustively (all source vertices x 18 rotations).
    pub energy_ratio_vs_exact: Option<f64>,
    /// MeshMatch's whole solve time over the exhaustive search's time at the finest level.
    pub speed_ratio_vs_exact: Option<f64>,
    /// Every stage's time (source and target preparation, then the solve), seconds.
    #[serde(skip)]
    pub stages: Vec<(String, f64)>,
    /// EM iterations run per level, finest first (fewer than asked where a level converged).
    pub iterations: Vec<usize>,
}

/// Largest source working resolution of a row: beyond it only the target grows (Spot's texture
/// holds no more detail than a 256K-vertex sampling shows).
pub const MAX_SOURCE_VERTICES: usize = 256_000;

/// Finest-level target vertices searched exhaustively for the exact baseline.
pub const EXACT_SAMPLES: usize = 48;

/// Peak resident set size of this process in MiB (Linux `VmHWM`), 0 where unknown.
pub fn peak_rss_mb() -> f64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines().find(|l| l.starts_with("VmHWM:")).and_then(|l| {
                l.split_whitespace()
                    .nth(1)
                    .and_then(|k| k.parse::<f64>().ok())
            })
        })
        .map(|kb| kb / 1024.0)
        .unwrap_or(0.0)
}

/// Parse sizes such as `16k,64k,256k,1m` or `20000`.
pub fn parse_sizes(s: &str) -> Result<Vec<usize>> {
    s.split(',')
        .map(|t| {
            let t = t.trim().to_ascii_lowercase();
            let (num, mul) = if let Some(n) = t.strip_suffix('k') {
                (n, 1_000.0)
            } else if let Some(n) = t.strip_suffix('m') {
                (n, 1_000_000.0)
            } else {
                (t.as_str(), 1.0)
            };
            let max = crate::mesh::MAX_WORKING_VERTICES;
            num.parse::<f64>()
                .ok()
                .filter(|v| v.is_finite() && *v > 0.0)
                .map(|v| v * mul)
                .filter(|v| *v >= 1.0 && *v <= max as f64)
                .map(|v| v as usize)
                .ok_or_else(|| {
                    crate::error::Error::InvalidInput(format!(
                        "--sizes {s}: cannot use '{t}' (use e.g. 16k,64k; each from 1 to {max} vertices)"
                    ))
                })
        })
        .collect()
}

fn sum(timings: &[(String, f64)], pred: impl Fn(&str) -> bool) -> f64 {
    timings
        .iter()
        .filter(|(n, _)| pred(n))
        .map(|(_, s)| s)
        .sum()
}

/// Six correspondences for the edit measurement: on each mesh, the vertices at both ends of the
/// three bounding-box axes (file indices). What they mean does not matter for the timing.
fn extreme_pairs(source: &TriMesh, target: &TriMesh) -> Vec<crate::correspondence::Correspondence> {
    let ends = |m: &TriMesh| -> Vec<u32> {
        let mut out = Vec::with_capacity(6);
        for axis in 0..3 {
            for sign in [-1.0f32, 1.0] {
                let v = (0..m.positions.len())
                    .filter(|&i| m.positions[i][axis].is_finite())
                    .max_by(|&a, &b| {
                        (sign * m.positions[a][axis]).total_cmp(&(sign * m.positions[b][axis]))
                    })
                    .unwrap_or(0);
                out.push(m.file_index.get(v).copied().unwrap_or(v as u32));
            }
        }
        out
    };
    ends(source)
        .into_iter()
        .zip(ends(target))
        .map(|(s, t)| crate::correspondence::Correspondence {
            source_vertex: s,
            target_vertices: vec![t],
        })
        .collect()
}

/// Default parameters of a row at `n` working vertices: the source's (capped at
/// [`MAX_SOURCE_VERTICES`]) and the target's.
fn size_params(n: usize) -> (TransferParams, TransferParams) {
    let with = |vertices| TransferParams {
        vertices,
        ..TransferParams::default()
    };
    (with(n.min(MAX_SOURCE_VERTICES)), with(n))
}

/// Run one size: prepare Spot (source) and the horse (target) at `n` working vertices, solve.
pub fn bench_size(source: &TriMesh, target: &TriMesh, n: usize) -> Result<BenchRow> {
    let (params_source, mut params) = size_params(n);
    params.exact_samples = EXACT_SAMPLES;
    let cancel = CancelToken::new();
    let t0 = Instant::now();
    let (ps, pt) = mm::prepare_pair(
        source,
        &params_source,
        target,
        &params,
        &crate::work::no_events,
        &cancel,
    )?;
    let solve_start = Instant::now();
    let first = std::sync::Mutex::new(None::<f64>);
    let sink = |e: Event| {
        if let Event::Partial { .. } = e {
            let mut f = first.lock().expect("not poisoned");
            if f.is_none() {
                *f = Some(solve_start.elapsed().as_secs_f64());
            }
        }
    };
    let r = mm::solve(&ps, &pt, &[], &params, &sink, &cancel)?;
    let end = t0.elapsed().as_secs_f64();
    // A correspondence edit: a new solve on the same prepared meshes with six pairs (affinities
    // recomputed), stopped at its first partial result.
    let corr = extreme_pairs(source, target);
    let edit_cancel = CancelToken::new();
    let edit_start = Instant::now();
    let edit_first = std::sync::Mutex::new(None::<f64>);
    let edit_sink = |e: Event| {
        if let Event::Partial { .. } = e {
            let mut f = edit_first.lock().expect("not poisoned");
            if f.is_none() {
                *f = Some(edit_start.elapsed().as_secs_f64());
            }
            edit_cancel.cancel();
        }
    };
    match mm::solve(&ps, &pt, &corr, &params, &edit_sink, &edit_cancel) {
        Ok(_) | Err(crate::error::Error::Cancelled) => {}
        Err(e) => return Err(e),
    }
    let edit_preview = edit_first.into_inner().expect("not poisoned");
    // E-steps the finest level ran (fewer than `iterations` where it converged)
    let iters = r.iterations.first().copied().unwrap_or(0).max(1) as f64;
    let prep = |p: &mm::PreparedMesh, name: &str| sum(p.timings(), |n| n == name);
    Ok(BenchRow {
        iterations: r.iterations.clone(),
        vertices: pt.working_mesh().num_vertices(),
        source_vertices: ps.working_mesh().num_vertices(),
        hierarchy_s: prep(&ps, "hierarchy") + prep(&pt, "hierarchy"),
        hks_s: prep(&ps, "features") + prep(&pt, "features"),
        fans_s: prep(&ps, "fans") + prep(&pt, "fans") + sum(&r.timings, |n| n == "fan updates"),
        estep_s_per_iter: sum(&r.timings, |n| n == "search finest") / iters,
        mstep_s_per_iter: sum(&r.timings, |n| n == "vote finest") / iters,
        first_preview_s: edit_preview.unwrap_or(f64::NAN),
        first_solve_preview_s: first
            .into_inner()
            .expect("not poisoned")
            .unwrap_or(f64::NAN),
        // the exact-search check is the bench's diagnostic, not part of the transfer
        end_to_end_s: end - r.exact.as_ref().map_or(0.0, |e| e.check_seconds),
        peak_rss_mb: peak_rss_mb(),
        energy_ratio_vs_exact: r
            .exact
            .as_ref()
            .map(|e| e.meshmatch_energy / e.exact_energy.max(1e-30)),
        speed_ratio_vs_exact: r
            .exact
            .as_ref()
            .map(|e| e.meshmatch_seconds / e.exact_seconds.max(1e-30)),
        stages: ps
            .timings()
            .iter()
            .map(|(n, t)| (format!("source {n}"), *t))
            .chain(
                pt.timings()
                    .iter()
                    .map(|(n, t)| (format!("target {n}"), *t)),
            )
            .chain(r.timings.iter().cloned())
            .chain(r.exact.as_ref().map(|e| {
                (
                    "exact check (not in end to end)".to_string(),
                    e.check_seconds,
                )
            }))
            .collect(),
    })
}

/// One cancel probe: when the cancel was requested and how long the job took to return.
#[derive(Clone, Debug, serde::Serialize)]
pub struct CancelProbe {
    /// Seconds after the job's start that the cancel was requested.
    pub at_s: f64,
    /// The stage the job was in (the last progress event's stage and level).
    pub stage: String,
    /// From the cancel request to the job's return, milliseconds (0 when it had finished).
    pub latency_ms: f64,
    /// The job had already finished when the cancel came (the probe measures nothing).
    pub finished: bool,
}

/// Cancel latency of a whole transfer (prepare both meshes, solve) at `n` working vertices, as
/// the app runs it: `probes` runs, each cancelled at an evenly spaced point of a run of
/// `end_to_end_s` seconds.
pub fn cancel_probes(
    source: &TriMesh,
    target: &TriMesh,
    n: usize,
    end_to_end_s: f64,
    probes: usize,
) -> Result<Vec<CancelProbe>> {
    let mut out = Vec::with_capacity(probes);
    for k in 0..probes {
        let at = end_to_end_s * (k as f64 + 0.5) / probes as f64;
        let cancel = CancelToken::new();
        let stage = std::sync::Arc::new(std::sync::Mutex::new(String::from("start")));
        let (tx, rx) = crossbeam_channel::bounded(1);
        let (s, t, c, st) = (
            source.clone(),
            target.clone(),
            cancel.clone(),
            stage.clone(),
        );
        let job = std::thread::spawn(move || {
            let (params_source, params) = size_params(n);
            let sink = |e: Event| {
                if let Event::Progress(p) = e {
                    let name = if p.stage == "solve" {
                        format!("solve level {}", p.level)
                    } else {
                        p.stage.to_string()
                    };
                    *st.lock().expect("not poisoned") = name;
                }
            };
            let r = (|| {
                let (ps, pt) = mm::prepare_pair(&s, &params_source, &t, &params, &sink, &c)?;
                mm::solve(&ps, &pt, &[], &params, &sink, &c).map(|_| ())
            })();
            let _ = tx.send(Instant::now());
            r
        });
        std::thread::sleep(std::time::Duration::from_secs_f64(at));
        let stage_then = stage.lock().expect("not poisoned").clone();
        let asked = Instant::now();
        cancel.cancel();
        let returned = rx
            .recv()
            .map_err(|_| crate::error::Error::InvalidInput("the probed job panicked".into()))?;
        match job.join() {
            Ok(Ok(())) | Ok(Err(crate::error::Error::Cancelled)) => {}
            Ok(Err(e)) => return Err(e),
            Err(_) => {
                return Err(crate::error::Error::InvalidInput(
                    "the probed job panicked".into(),
                ));
            }
        }
        out.push(CancelProbe {
            at_s: at,
            stage: stage_then,
            latency_ms: returned.saturating_duration_since(asked).as_secs_f64() * 1000.0,
            finished: returned <= asked,
        });
    }
    Ok(out)
}

/// Run the benchmark at every size, printing a table (or JSON lines) as rows complete.
/// With `probes > 0`, each size is followed by that many cancel probes ([`cancel_probes`]).
pub fn run(sizes: &[usize], json: bool, probes: usize) -> Result<()> {
    let mut source = crate::mesh::io::load(&crate::testdata::data_path("spot/spot.obj"))?;
    source.repair()?;
    let mut target = crate::mesh::io::load(&crate::testdata::data_path("horse/horse.ply"))?;
    target.repair()?;
    if !json {
        println!(
            "{:>9} {:>9} {:>8} {:>8} {:>8} {:>10} {:>10} {:>9} {:>9} {:>9} {:>8} {:>9}",
            "vertices",
            "source",
            "hier_s",
            "hks_s",
            "fans_s",
            "estep/it",
            "mstep/it",
            "preview",
            "total_s",
            "rss_MiB",
            "E/exact",
            "t/exact"
        );
    }
    for &n in sizes {
        let row = bench_size(&source, &target, n)?;
        if json {
            println!("{}", serde_json::to_string(&row).expect("serialisable"));
        } else {
            println!(
                "{:>9} {:>9} {:>8.3} {:>8.3} {:>8.3} {:>10.3} {:>10.3} {:>9.3} {:>9.2} {:>9.0} {:>8.3} {:>9.4}",
                row.vertices,
                row.source_vertices,
                row.hierarchy_s,
                row.hks_s,
                row.fans_s,
                row.estep_s_per_iter,
                row.mstep_s_per_iter,
                row.first_preview_s,
                row.end_to_end_s,
                row.peak_rss_mb,
                row.energy_ratio_vs_exact.unwrap_or(f64::NAN),
                row.speed_ratio_vs_exact.unwrap_or(f64::NAN)
            );
            let stages: Vec<String> = row
                .stages
                .iter()
                .map(|(n, t)| format!("{n} {t:.2}"))
                .collect();
            eprintln!("  stages (s): {}", stages.join(", "));
            let its: Vec<String> = row.iterations.iter().map(|i| i.to_string()).collect();
            eprintln!("  EM iterations per level, finest first: {}", its.join(" "));
        }
        if probes > 0 {
            let p = cancel_probes(&source, &target, n, row.end_to_end_s, probes)?;
            if json {
                println!(
                    "{}",
                    serde_json::json!({"vertices": row.vertices, "cancel_probes": p})
                );
            } else {
                let live: Vec<&CancelProbe> = p.iter().filter(|x| !x.finished).collect();
                let mut ms: Vec<f64> = live.iter().map(|x| x.latency_ms).collect();
                ms.sort_by(f64::total_cmp);
                match live
                    .iter()
                    .max_by(|a, b| a.latency_ms.total_cmp(&b.latency_ms))
                {
                    Some(worst) => println!(
                        "  cancel latency over {} probes: median {:.1} ms, max {:.1} ms (at {:.2} s, {})",
                        live.len(),
                        ms[ms.len() / 2],
                        worst.latency_ms,
                        worst.at_s,
                        worst.stage
                    ),
                    None => println!("  cancel latency: every probed job had finished"),
                }
            }
        }
    }
    Ok(())
}

/// One row of the systems' benchmark (`meshmatch bench --system weather|quilt`).
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct SystemRow {
    /// The system and its case.
    pub case: String,
    /// Working vertices (surface points) per mesh, or base vertices for quilting.
    pub vertices: usize,
    /// Stage times, seconds.
    pub stages: Vec<(String, f64)>,
    /// End to end, seconds.
    pub total_s: f64,
    /// Output faces (quilting) or 0.
    pub faces: usize,
    /// Peak resident set size of the process so far, MiB.
    pub peak_rss_mb: f64,
}

/// Geometry-correlated transfer, Spot (textured) -> the horse, both at `n` surface points:
/// features, CCA, matching and synthesis by `method`.
pub fn weather_row(n: usize, method: crate::synthesis::mertens::Method) -> Result<SystemRow> {
    use crate::synthesis::mertens;
    let mut source = crate::mesh::io::load(&crate::testdata::data_path("spot/spot.obj"))?;
    source.repair()?;
    let mut target = crate::mesh::io::load(&crate::testdata::data_path("horse/horse.ply"))?;
    target.repair()?;
    let params = mertens::Params {
        working_vertices: n,
        method,
        ..mertens::Params::default()
    };
    let t = Instant::now();
    let input = mertens::Input {
        source: &source,
        target: &target,
        source_mask: None,
    };
    let out = mertens::run(&input, &params, &|_| {}, &CancelToken::new())?;
    Ok(SystemRow {
        case: format!("weather spot -> horse, {method:?}").to_lowercase(),
        vertices: out.target.mesh.num_vertices(),
        stages: out
            .timings
            .iter()
            .map(|(k, s)| (k.to_string(), *s))
            .collect(),
        total_s: t.elapsed().as_secs_f64(),
        faces: 0,
        peak_rss_mb: peak_rss_mb(),
    })
}

/// Multi-rule weathering recipes (`synthesis::mertens::recipes`) transferred cow -> cat and
/// igea -> bunny at `n` points with the default parameters: per recipe, the correlation of L*,
/// a*, b* with the recipe applied to the target, the Lab W1 distance and the grain kept, and the
/// k-nearest-neighbour floor beside (`meshmatch bench --system weather-recipes`).
pub fn weather_recipe_rows(n: usize, json: bool) -> Result<()> {
    use crate::synthesis::mertens::{self, recipes};
    let cancel = CancelToken::new();
    for (s, t) in [
        ("cow/cow.ply", "cat/cat.obj"),
        ("igea/igea.ply", "bunny/bunny.obj"),
    ] {
        let load = |p: &str| -> Result<crate::mesh::TriMesh> {
            let mut m = crate::mesh::io::load(&crate::testdata::data_path(p))?;
            m.repair()?;
            Ok(m)
        };
        let pair = recipes::prepare(&load(s)?, &load(t)?, n, mertens::Up::Y, &cancel)?;
        for r in recipes::recipes() {
            let e = recipes::evaluate(&pair, &r, &mertens::Params::default(), &cancel)?;
            if json {
                println!(
                    "{}",
                    serde_json::json!({"pair": format!("{s} -> {t}"), "recipe": r.name,
                        "points": n, "method": e.method, "knn": e.knn, "seconds": e.seconds})
                );
            } else {
                let f = |x: &recipes::Scores| {
                    format!(
                        "L {:.2} a {:.2} b {:.2} W1 {:.2} grain {:.2}",
                        x.corr[0], x.corr[1], x.corr[2], x.w1, x.grain
                    )
                };
                println!(
                    "weather {s} -> {t} {:<8} {n} pts: {} | kNN floor {} | {:.1} s",
                    r.name,
                    f(&e.method),
                    f(&e.knn),
                    e.seconds
                );
            }
        }
    }
    Ok(())
}

/// Mesh quilting of the chain-mail swatch over a plane (`planar`) or the bunny, with the swatch
/// `1 / swatches` of the base's bounding-box diagonal wide.
pub fn quilt_row(planar: bool, swatches: f32) -> Result<SystemRow> {
    quilt_row_of(
        crate::synthesis::quilting::SwatchKind::Chain,
        planar,
        swatches,
        false,
    )
}

/// Mesh quilting of `kind` over a plane or the bunny, threads merged across seams or not.
pub fn quilt_row_of(
    kind: crate::synthesis::quilting::SwatchKind,
    planar: bool,
    swatches: f32,
    merge: bool,
) -> Result<SystemRow> {
    use crate::synthesis::quilting;
    let base = if planar {
        quilting::plane(1.0, 1.0, 64, 64)
    } else {
        let mut b = crate::mesh::io::load(&crate::testdata::data_path("bunny/bunny.obj"))?;
        b.repair()?;
        b
    };
    let (lo, hi) = base
        .bounds()
        .ok_or_else(|| crate::error::Error::InvalidMesh("empty base".into()))?;
    let diag = glam::Vec3::from(hi).distance(glam::Vec3::from(lo));
    let swatch = quilting::swatch(kind, 1);
    let params = quilting::Params {
        swatch_size: Some(diag / swatches),
        merge_elements: merge,
        ..quilting::Params::default()
    };
    let t = Instant::now();
    let input = quilting::Input {
        base: &base,
        swatch: &swatch,
        field: None,
    };
    let out = quilting::run(&input, &params, &|_| {}, &CancelToken::new())?;
    Ok(SystemRow {
        case: format!(
            "quilt {} on {} (swatch = diagonal / {swatches}){}",
            kind.as_str(),
            if planar { "a plane" } else { "the bunny" },
            if merge { ", threads merged" } else { "" }
        ),
        vertices: base.num_vertices(),
        stages: vec![("quilt".into(), out.stats.seconds)],
        total_s: t.elapsed().as_secs_f64(),
        faces: out.elements.num_faces(),
        peak_rss_mb: peak_rss_mb(),
    })
}

/// Mesh quilting of a finite swatch (`quilting::finite_patch`, loaded as a swatch file would
/// be) over the bunny or the horse, the swatch a tenth of the diagonal wide.
pub fn quilt_finite_row(
    kind: crate::synthesis::quilting::PatchKind,
    horse: bool,
) -> Result<SystemRow> {
    use crate::synthesis::quilting;
    let name = if horse {
        "horse/horse.ply"
    } else {
        "bunny/bunny.obj"
    };
    let mut base = crate::mesh::io::load(&crate::testdata::data_path(name))?;
    base.repair()?;
    let (lo, hi) = base
        .bounds()
        .ok_or_else(|| crate::error::Error::InvalidMesh("empty base".into()))?;
    let diag = glam::Vec3::from(hi).distance(glam::Vec3::from(lo));
    let swatch = quilting::load_swatch(quilting::finite_patch(kind, 1), quilting::Axis::Z)?;
    let params = quilting::Params {
        swatch_size: Some(diag / 10.0),
        ..quilting::Params::default()
    };
    let t = Instant::now();
    let input = quilting::Input {
        base: &base,
        swatch: &swatch,
        field: None,
    };
    let out = quilting::run(&input, &params, &|_| {}, &CancelToken::new())?;
    Ok(SystemRow {
        case: format!(
            "quilt finite {} on the {} (swatch = diagonal / 10; {})",
            kind.as_str(),
            if horse { "horse" } else { "bunny" },
            out.stats.arrangement_summary()
        ),
        vertices: base.num_vertices(),
        stages: vec![("quilt".into(), out.stats.seconds)],
        total_s: t.elapsed().as_secs_f64(),
        faces: out.elements.num_faces(),
        peak_rss_mb: peak_rss_mb(),
    })
}

/// The SMPL man (coloured by height bands) and the woman refined to `n` vertices and moved, with
/// six landmarks (head top, hands, feet, a toe) on the same SMPL vertices.
fn bodies(n: usize) -> Result<(TriMesh, TriMesh, Vec<crate::correspondence::Correspondence>)> {
    let load = |p: &str| crate::mesh::io::load(&crate::testdata::data_path(p));
    let mut man = load("human/human_man.obj")?;
    man.colors = Some(
        man.positions
            .iter()
            .map(|p| {
                let band = ((p[1] * 12.0).floor() as i32).rem_euclid(2) as f32;
                [0.15 + 0.7 * band, if p[0] > 0.0 { 0.85 } else { 0.15 }, 0.5]
            })
            .collect(),
    );
    let woman = load("human/human_woman.obj")?;
    let r = crate::geometry::refine_to_density(&woman, n);
    let (s, c) = (0.6f32.sin(), 0.6f32.cos());
    let moved = TriMesh::new(
        r.mesh
            .positions
            .iter()
            .map(|p| [c * p[0] + s * p[2] + 0.3, p[1] - 0.2, -s * p[0] + c * p[2]])
            .collect(),
        r.mesh.faces.clone(),
    );
    let corr = [411u32, 2445, 5906, 3354, 6755, 3215]
        .iter()
        .map(|&v| crate::correspondence::Correspondence {
            source_vertex: v,
            target_vertices: vec![v],
        })
        .collect();
    Ok((man, moved, corr))
}

/// The global shape map (`meshmatch map`) from the SMPL man onto the woman refined to `n`
/// vertices and moved, six landmarks.
pub fn map_row(n: usize) -> Result<SystemRow> {
    let (man, woman, corr) = bodies(n)?;
    let t = Instant::now();
    let m = crate::meshmatch::map_meshes(&man, &woman, &corr, &CancelToken::new())?;
    Ok(SystemRow {
        case: format!(
            "map man -> woman (k = {}, computed on {} x {} vertices, isometry score {:.2})",
            m.k, m.map_vertices.0, m.map_vertices.1, m.score
        ),
        vertices: woman.num_vertices(),
        stages: m.timings.clone(),
        total_s: t.elapsed().as_secs_f64(),
        faces: 0,
        peak_rss_mb: peak_rss_mb(),
    })
}

/// A whole transfer man -> woman (as [`map_row`]) at `n` working vertices with the given
/// structure (`None` = auto), to compare its cost with and without the map.
pub fn structure_row(n: usize, structure: Option<f32>) -> Result<SystemRow> {
    let (man, woman, corr) = bodies(n)?;
    let params = crate::meshmatch::TransferParams {
        vertices: n,
        structure,
        ..Default::default()
    };
    let t = Instant::now();
    let r = crate::meshmatch::transfer(&man, &woman, &corr, &params, &|_| {}, &CancelToken::new())?;
    Ok(SystemRow {
        case: format!(
            "transfer man -> woman, structure {} (used {:.2})",
            structure.map_or("auto".to_string(), |x| format!("{x}")),
            r.structure
        ),
        vertices: n,
        stages: r
            .timings
            .iter()
            .filter(|(k, _)| k == "global map" || k.ends_with("prepare") || k == "affinities")
            .cloned()
            .collect(),
        total_s: t.elapsed().as_secs_f64(),
        faces: 0,
        peak_rss_mb: peak_rss_mb(),
    })
}

/// Feature-aligned texturing (Xu et al. 2009) of a subdivided cube of about `n` vertices with
/// [`crate::demo::line_exemplar`]: salient curves, oriented field, field-driven synthesis of about `n`
/// vertices and the texture optimisation with the feature-to-feature constraint.
pub fn features_row(n: usize) -> Result<SystemRow> {
    use crate::synthesis::feature_aligned;
    let k = ((n as f64 / 6.0).sqrt().round() as usize).max(2);
    let target = crate::demo::crease_cube(k);
    let exemplar = crate::demo::line_exemplar();
    // about 4.5 area / h^2 synthesized vertices: h for n of them on the cube's area 6
    let h = (4.5 * 6.0 / n as f64).sqrt() as f32;
    let params = feature_aligned::Params {
        align_features: true,
        synth: crate::synthesis::wei_levoy::SynthParams {
            scale: Some(h * exemplar.width() as f32),
            max_vertices: (n * 2).max(200_000),
            ..Default::default()
        },
        ..Default::default()
    };
    let t = Instant::now();
    let input = feature_aligned::Input {
        target: &target,
        exemplar: &exemplar,
        curves: None,
        alpha: None,
        feature_mask: None,
    };
    let out = feature_aligned::run(&input, &params, &|_| {}, &CancelToken::new())?;
    Ok(SystemRow {
        case: format!(
            "features: cube of {} vertices, {} curves, a line exemplar aligned",
            target.num_vertices(),
            out.curves.len()
        ),
        vertices: out.synth.mesh.num_vertices(),
        stages: vec![
            ("curves".into(), out.timings.curves),
            ("field".into(), out.timings.field),
            (
                "greedy step (mean)".into(),
                out.field.step_secs.iter().sum::<f64>() / out.field.step_secs.len().max(1) as f64,
            ),
            (
                "greedy step (max)".into(),
                out.field.step_secs.iter().cloned().fold(0.0, f64::max),
            ),
            ("synthesis".into(), out.timings.synthesis),
            ("optimisation".into(), out.timings.optimization),
        ],
        total_s: t.elapsed().as_secs_f64(),
        faces: 0,
        peak_rss_mb: peak_rss_mb(),
    })
}

/// `synth` with its defaults (vertex budget, auto orientation, alpha) of one shared texture on
/// one shared mesh: what a user gets from `meshmatch synth --exemplar T --target M --out o.ply`.
pub fn synth_row(mesh: &std::path::Path, texture: &std::path::Path) -> Result<SystemRow> {
    use crate::synthesis::wei_levoy::{self, DEFAULT_VERTEX_BUDGET, SynthParams};
    let t = Instant::now();
    let mut target = crate::mesh::io::load(mesh)?;
    target.repair()?;
    let (tex, alpha) = crate::mesh::io::load_texture_with_alpha(texture)?;
    let params = SynthParams::default();
    let min = (4u32 << (params.levels.clamp(1, 8) - 1)).max(8);
    let (ex, _) =
        wei_levoy::fit_exemplar_to_budget(tex.image, &target, None, DEFAULT_VERTEX_BUDGET, min);
    let alpha = alpha.map(|a| wei_levoy::resize_alpha(a, ex.width(), ex.height()));
    let input = wei_levoy::Input {
        exemplar: &ex,
        target: &target,
        mask: None,
        alpha: alpha.as_ref(),
    };
    let r = wei_levoy::run(&input, &params, &|_| {}, &CancelToken::new())?;
    let name = |p: &std::path::Path| {
        p.file_name()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default()
    };
    Ok(SystemRow {
        case: format!(
            "synth {} on {} ({}x{} px, {})",
            name(texture),
            name(mesh),
            ex.width(),
            ex.height(),
            r.orientation_used.as_str()
        ),
        vertices: r.mesh.num_vertices(),
        stages: vec![
            ("prepare".into(), r.timings.prepare),
            ("orientation".into(), r.timings.orientation),
            ("neighbourhoods".into(), r.timings.neighbourhoods),
            ("search".into(), r.timings.search),
        ],
        total_s: t.elapsed().as_secs_f64(),
        faces: 0,
        peak_rss_mb: peak_rss_mb(),
    })
}

/// `synth` into a texture with its defaults (texel budget, auto orientation, alpha, a
/// 2048² texture): what a user gets from `meshmatch synth --exemplar T --target M --out o.glb`.
pub fn synth_texture_row(mesh: &std::path::Path, texture: &std::path::Path) -> Result<SystemRow> {
    use crate::synthesis::wei_levoy::{TextureInput, TextureParams, synthesize_texture};
    let t = Instant::now();
    let mut target = crate::mesh::io::load(mesh)?;
    target.repair()?;
    let (tex, alpha) = crate::mesh::io::load_texture_with_alpha(texture)?;
    let input = TextureInput {
        exemplar: &tex.image,
        alpha: alpha.as_ref(),
        target: &target,
        field: None,
    };
    let r = synthesize_texture(
        &input,
        &TextureParams::default(),
        &|_| {},
        &CancelToken::new(),
    )?;
    let name = |p: &std::path::Path| {
        p.file_name()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default()
    };
    Ok(SystemRow {
        case: format!(
            "synth {} into {}'s texture ({}, {}² working, exemplar {} px wide, {})",
            name(texture),
            name(mesh),
            if r.atlas.is_some() {
                "atlas"
            } else {
                "own UVs"
            },
            r.working_size,
            r.working_exemplar_width,
            r.orientation_used.as_str()
        ),
        vertices: r.level_texels.first().copied().unwrap_or(0),
        stages: vec![
            ("prepare".into(), r.timings.prepare),
            ("orientation".into(), r.timings.orientation),
            ("neighbourhoods".into(), r.timings.neighbourhoods),
            ("search".into(), r.timings.search),
            ("magnify".into(), r.timings.magnify),
        ],
        total_s: t.elapsed().as_secs_f64(),
        faces: 0,
        peak_rss_mb: peak_rss_mb(),
    })
}

/// The shared meshes (one level of folders under the data directory, robustness cases left out)
/// and textures (`textures/`), sorted.
fn shared_meshes_and_textures() -> (Vec<std::path::PathBuf>, Vec<std::path::PathBuf>) {
    let dir = crate::testdata::data_dir();
    let ext = |p: &std::path::Path| {
        p.extension()
            .and_then(|e| e.to_str())
            .map(|e| e.to_ascii_lowercase())
            .unwrap_or_default()
    };
    let mut meshes = Vec::new();
    let mut textures = Vec::new();
    for entry in std::fs::read_dir(&dir).into_iter().flatten().flatten() {
        let sub = entry.path();
        let robustness = sub.file_name().is_some_and(|n| n == "robustness");
        for f in std::fs::read_dir(&sub).into_iter().flatten().flatten() {
            let p = f.path();
            match ext(&p).as_str() {
                "obj" | "ply" | "glb" | "gltf" if !robustness => meshes.push(p),
                "png" | "jpg" | "jpeg" if sub.file_name().is_some_and(|n| n == "textures") => {
                    textures.push(p)
                }
                _ => {}
            }
        }
    }
    meshes.sort();
    textures.sort();
    (meshes, textures)
}

/// `row` for every shared mesh with every shared texture, printed as each finishes (a failed
/// pair prints its error, `synth TEXTURE <joiner> MESH: ...`).
fn every_shared_pair(
    row: fn(&std::path::Path, &std::path::Path) -> Result<SystemRow>,
    joiner: &str,
    json: bool,
) {
    let (meshes, textures) = shared_meshes_and_textures();
    for m in &meshes {
        for t in &textures {
            match row(m, t) {
                Ok(r) => print_rows(vec![r], json),
                Err(e) => println!("synth {} {joiner} {}: {e}", t.display(), m.display()),
            }
        }
    }
}

/// `meshmatch bench --system weather|features|quilt|map|synth|synth-texture`: the rows of a
/// synthesis system.
pub fn run_system(system: &str, sizes: &[usize], json: bool) -> Result<()> {
    let rows: Vec<SystemRow> = match system {
        "synth" => {
            every_shared_pair(synth_row, "on", json);
            Vec::new()
        }
        "synth-character" => {
            synth_character_rows(json)?;
            Vec::new()
        }
        "synth-texture" => {
            every_shared_pair(synth_texture_row, "into", json);
            Vec::new()
        }
        "weather" => {
            use crate::synthesis::mertens::Method;
            let mut rows = Vec::new();
            for &n in sizes {
                for m in [Method::Parametric, Method::NonParametric] {
                    rows.push(weather_row(n, m)?);
                }
            }
            rows
        }
        "weather-recipes" => {
            for &n in sizes {
                weather_recipe_rows(n, json)?;
            }
            Vec::new()
        }
        "features" => sizes
            .iter()
            .map(|&n| features_row(n))
            .collect::<Result<_>>()?,
        "quilt" => vec![
            quilt_row(true, 8.0)?,
            quilt_row(false, 10.0)?,
            quilt_row(false, 18.0)?,
            quilt_row_of(
                crate::synthesis::quilting::SwatchKind::Weave,
                false,
                10.0,
                false,
            )?,
            quilt_row_of(
                crate::synthesis::quilting::SwatchKind::Weave,
                false,
                10.0,
                true,
            )?,
            quilt_finite_row(crate::synthesis::quilting::PatchKind::Rings, false)?,
            quilt_finite_row(crate::synthesis::quilting::PatchKind::Rings, true)?,
            quilt_finite_row(crate::synthesis::quilting::PatchKind::Weave, false)?,
            quilt_finite_row(crate::synthesis::quilting::PatchKind::Pebbles, false)?,
        ],
        "texture" => texture_rows(sizes.first().copied().unwrap_or(64_000))?,
        "map" => {
            let mut rows = Vec::new();
            for &n in sizes {
                rows.push(map_row(n)?);
                rows.push(structure_row(n, Some(0.0))?);
                rows.push(structure_row(n, None)?);
            }
            rows
        }
        _ => {
            return Err(crate::error::Error::InvalidInput(format!(
                "--system {system}: use meshmatch, weather, weather-recipes, features, quilt, map, texture, synth \
                 or synth-texture"
            )));
        }
    };
    print_rows(rows, json);
    Ok(())
}

/// Full-resolution delivery (`meshmatch bench --system texture`): a ground-truth task (Spot with
/// a detailed brick texture, re-tessellated, bent and moved, a UV atlas on the target) solved
/// once at `n` working vertices, then its texture delivered at 1024^2, 2048^2 and 4096^2: the
/// resampler (patch maps, the coincident check, corner images) and the bake timed apart, the
/// working-vertex bake beside them, each row with its scores against the truth.
pub fn texture_rows(n: usize) -> Result<Vec<SystemRow>> {
    use crate::ground_truth::{Deformation, TexelTask, TextureKind, detailed_texture, score};
    use crate::meshmatch::{BakeLayout, Resampler, prepare_pair, solve};
    let mut source = crate::mesh::io::load(&crate::testdata::data_path("spot/spot.obj"))?;
    source.texture = Some(std::sync::Arc::new(crate::mesh::Texture {
        image: detailed_texture(TextureKind::Bricks, 2048),
        path: None,
    }));
    let task = TexelTask::new(source, 12_000, Deformation::BentAndMoved, 4096, 7)?;
    let params = TransferParams {
        vertices: n,
        ..TransferParams::default()
    };
    let cancel = CancelToken::new();
    let (ps, pt) = prepare_pair(
        &task.source,
        &params,
        &task.target,
        &params,
        &|_| {},
        &cancel,
    )?;
    let r = solve(&ps, &pt, &task.correspondences, &params, &|_| {}, &cancel)?;
    let layout = BakeLayout::of(&pt);
    let mut rows = Vec::new();
    for size in [1024u32, 2048, 4096] {
        let (truth, covered) = task.truth(size);
        let t = Instant::now();
        let full = Resampler::new(&ps, &pt, &r.nnf, &cancel)?.ok_or_else(|| {
            crate::error::Error::InvalidInput("the source cannot be resampled".into())
        })?;
        let t_resampler = t.elapsed().as_secs_f64();
        let t = Instant::now();
        let image = layout.bake_resampled(&task.target, &full, size);
        let t_bake = t.elapsed().as_secs_f64();
        let s_full = score(&image, &truth, &covered);
        let t = Instant::now();
        let image = layout.bake(&task.target, &r.working_signal, size);
        let t_working = t.elapsed().as_secs_f64();
        let s_working = score(&image, &truth, &covered);
        rows.push(SystemRow {
            case: format!(
                "texture {size}^2, bricks on Spot bent: full resolution dE {:.2} SSIM {:.3} \
                 sharpness {:.2}, working vertices dE {:.2} SSIM {:.3} sharpness {:.2}",
                s_full.delta_e,
                s_full.ssim,
                s_full.sharpness,
                s_working.delta_e,
                s_working.ssim,
                s_working.sharpness
            ),
            vertices: pt.working_mesh().num_vertices(),
            stages: full
                .timings()
                .iter()
                .map(|(k, s)| (k.to_string(), *s))
                .chain([
                    ("resampler".into(), t_resampler),
                    ("bake".into(), t_bake),
                    ("working-vertex bake".into(), t_working),
                ])
                .collect(),
            total_s: t_resampler + t_bake,
            faces: 0,
            peak_rss_mb: peak_rss_mb(),
        });
    }
    Ok(rows)
}

/// Print system rows, as JSON lines or one sentence each.
pub fn print_rows(rows: Vec<SystemRow>, json: bool) {
    for r in rows {
        if json {
            println!("{}", serde_json::to_string(&r).expect("serialisable"));
        } else {
            let stages: Vec<String> = r
                .stages
                .iter()
                .map(|(k, s)| format!("{k} {s:.2} s"))
                .collect();
            println!(
                "{}: {} vertices, {:.2} s end to end ({}){}, peak RSS {:.0} MiB",
                r.case,
                r.vertices,
                r.total_s,
                stages.join(", "),
                if r.faces > 0 {
                    format!(", {} output faces", r.faces)
                } else {
                    String::new()
                },
                r.peak_rss_mb
            );
        }
    }
}

/// `meshmatch bench --system synth-character`: for each shared mesh and image (or the pairs in
/// `MESHMATCH_PAIRS`, `mesh.obj:image.png,...` by file name), what `synth` gives with its
/// defaults for a textured output (patch pasting), with `--method neighbourhood` (Wei-Levoy in
/// texture space), and triplanar projection at the same scale, all in the same layout, measured
/// texel by texel ([`crate::synthesis::wei_levoy::character`]); `MESHMATCH_METHODS` picks
/// among `patches,neighbourhood,triplanar`.
pub fn synth_character_rows(json: bool) -> Result<()> {
    use crate::synthesis::wei_levoy::character::{Exemplar, measure, triplanar_texture};
    use crate::synthesis::wei_levoy::patch_pasting::{PatchParams, paste_patches};
    use crate::synthesis::wei_levoy::{TextureInput, TextureParams, synthesize_texture};
    let (meshes, textures) = shared_meshes_and_textures();
    let wanted: Option<Vec<(String, String)>> = std::env::var("MESHMATCH_PAIRS").ok().map(|v| {
        v.split(',')
            .filter_map(|p| p.split_once(':'))
            .map(|(m, t)| (m.to_string(), t.to_string()))
            .collect()
    });
    let name = |p: &std::path::Path| {
        p.file_name()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default()
    };
    if !json {
        println!(
            "| mesh x image | method | contrast | Lab W1 | patch distance | reverse distance | seconds |"
        );
        println!("| --- | --- | ---: | ---: | ---: | ---: | ---: |");
    }
    for m in &meshes {
        for t in &textures {
            if let Some(w) = &wanted
                && !w.iter().any(|(wm, wt)| *wm == name(m) && *wt == name(t))
            {
                continue;
            }
            let mut target = crate::mesh::io::load(m)?;
            target.repair()?;
            let (tex, alpha) = crate::mesh::io::load_texture_with_alpha(t)?;
            let (lo, hi) = target.bounds().unwrap_or(([0.0; 3], [0.0; 3]));
            let scale = glam::Vec3::from(hi).distance(glam::Vec3::from(lo)) / 4.0;
            let ex = Exemplar {
                image: &tex.image,
                alpha: alpha.as_ref(),
                scale,
            };
            let methods = std::env::var("MESHMATCH_METHODS")
                .unwrap_or_else(|_| "patches,neighbourhood,triplanar".into());
            let input = TextureInput {
                exemplar: &tex.image,
                alpha: alpha.as_ref(),
                target: &target,
                field: None,
            };
            let params = TextureParams::default();
            let cancel = CancelToken::new();
            // patch pasting lays the texture out (the target's UVs or an atlas); the others
            // go into the same layout
            let t0 = Instant::now();
            let patches =
                paste_patches(&input, &params, &PatchParams::default(), &|_| {}, &cancel)?;
            let secs = t0.elapsed().as_secs_f64();
            let laid = &patches.mesh;
            let texture = |m: &TriMesh| m.texture.as_ref().map(|x| x.image.clone());
            for method in methods.split(',') {
                let (tx, secs) = match method {
                    "patches" => (texture(laid), secs),
                    "neighbourhood" => {
                        let mut m = target.clone();
                        m.uvs.clone_from(&laid.uvs);
                        let t0 = Instant::now();
                        let r = synthesize_texture(
                            &TextureInput {
                                target: &m,
                                ..input
                            },
                            &params,
                            &|_| {},
                            &cancel,
                        )?;
                        (texture(&r.mesh), t0.elapsed().as_secs_f64())
                    }
                    "triplanar" => (
                        triplanar_texture(laid, &ex, params.texture_size as usize),
                        0.0,
                    ),
                    _ => continue,
                };
                if let Some(tx) = tx
                    && let Some(c) = measure(laid, &tx, &ex, 1)
                {
                    print_character(json, &name(m), &name(t), method, &c, secs);
                }
            }
        }
    }
    Ok(())
}

fn print_character(
    json: bool,
    mesh: &str,
    image: &str,
    method: &str,
    c: &crate::synthesis::wei_levoy::character::Character,
    secs: f64,
) {
    if json {
        println!(
            "{}",
            serde_json::json!({"mesh": mesh, "image": image, "method": method, "character": c, "seconds": secs})
        );
    } else {
        println!(
            "| {mesh} x {image} | {method} | {:.2} | {:.1} | {:.1} | {:.1} | {:.1} |",
            c.contrast, c.lab_w1, c.patch_distance, c.reverse_distance, secs
        );
    }
}
