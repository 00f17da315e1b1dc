//! The MeshMatch transfer's benchmark (`meshmatch bench`): stage timings at several working
//! resolutions, Spot (textured) as source and the horse as target, and cancel probes.

use super::peak_rss_mb;
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
