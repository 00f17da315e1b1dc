//! `meshmatch bench`: stage timings of a MeshMatch transfer at several working resolutions, on
//! inputs built from the shared data (Spot textured as source, the horse as target), and the
//! rows of each synthesis system (`--system`), one file per system.

mod exemplar;
mod feature_aligned;
mod map;
mod quilting;
mod texture;
mod transfer;
mod weathering;

use exemplar::every_shared_pair;
pub use exemplar::{synth_character_rows, synth_row, synth_texture_row};
pub use feature_aligned::features_row;
pub use map::{map_row, structure_row};
pub use quilting::{quilt_finite_row, quilt_row, quilt_row_of};
pub use texture::texture_rows;
pub use transfer::{
    BenchRow, CancelProbe, EXACT_SAMPLES, MAX_SOURCE_VERTICES, bench_size, cancel_probes, run,
};
pub use weathering::{feature_map_rows, weather_recipe_rows, weather_row};

use crate::error::Result;

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

/// `meshmatch bench --system weather|features|quilt|map|synth|synth-texture|synth-character`: the rows of a
/// synthesis system.
pub fn run_system(system: &str, sizes: &[usize], json: bool) -> Result<()> {
    let rows: Vec<SystemRow> = match system {
        "synth" => {
            every_shared_pair(synth_row, "on", json);
            Vec::new()
        }
        "feature-maps" => {
            let mut rows = Vec::new();
            for &n in sizes {
                rows.extend(feature_map_rows(n.clamp(16, 8192) as u32)?);
            }
            rows
        }
        "synth-character" => {
            exemplar::synth_character_rows(json)?;
            Vec::new()
        }
        "synth-texture" => {
            every_shared_pair(synth_texture_row, "into", json);
            Vec::new()
        }
        "weather" => {
            use crate::synthesis::weathering::Method;
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
            quilt_finite_row(crate::synthesis::quilting::PatchKind::Weave, true)?,
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
                "--system {system}: use meshmatch, weather, weather-recipes, features, quilt, map, texture, synth, \
                 synth-texture, synth-character \
                 or feature-maps"
            )));
        }
    };
    print_rows(rows, json);
    Ok(())
}

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
            let stages = if stages.is_empty() {
                String::new()
            } else {
                format!(" ({})", stages.join(", "))
            };
            println!(
                "{}: {} vertices, {:.2} s end to end{}{}, peak RSS {:.0} MiB",
                r.case,
                r.vertices,
                r.total_s,
                stages,
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
