//! `meshmatch bench`: stage timings at several working resolutions.

use crate::error::Result;

/// Most `--cancel-probes`.
const MAX_CANCEL_PROBES: usize = 1000;

/// Arguments of `meshmatch bench`.
#[derive(clap::Args, Debug)]
pub struct BenchArgs {
    /// Working resolutions, e.g. `16k,64k,256k,1m` (each at most 4m).
    #[arg(long, default_value = "16k,64k", allow_negative_numbers = true)]
    pub sizes: String,
    /// One JSON object per line per size.
    #[arg(long)]
    pub json: bool,
    /// After each size, cancel that many whole transfers at evenly spaced moments and
    /// report how long each took to stop (at most 1000).
    #[arg(long, default_value_t = 0, allow_negative_numbers = true,
          value_parser = super::common::whole(0, MAX_CANCEL_PROBES))]
    pub cancel_probes: usize,
    /// Which system: meshmatch (the transfer's table), weather (geometry-correlated transfer,
    /// Spot -> horse at each size), weather-recipes (multi-rule recipes cow -> cat and
    /// igea -> bunny at each size, scored against the recipe on the target, kNN floor beside),
    /// features (feature-aligned texturing of a cube of each size,
    /// curves, field, synthesis and optimisation at that many vertices), quilt (chain mail on a plane and on the bunny), map (the
    /// global shape map man -> woman at each size, and a transfer with structure 0 and auto),
    /// texture (full-resolution delivery of a ground-truth task solved at the first size, at
    /// 1024, 2048 and 4096 texels per side, with its scores), paint (the UI thread's time per
    /// dab of a stroke on a UV sphere of each size, into a 2048² texel layer and into vertex
    /// paint, and on the demo giraffe with a generated atlas) or
    /// synth (`synth` with its defaults, every shared texture on every shared mesh, on the
    /// surface), synth-texture (the same into each mesh's texture space with Wei-Levoy) or
    /// synth-character (patch pasting, Wei-Levoy and triplanar projection in the same layout,
    /// measured against the image: contrast, Lab W1, patch and reverse distance; pairs by file
    /// name in MESHMATCH_PAIRS, e.g. `bunny.obj:2.jpg,penguin.obj:3.jpg`) or feature-maps
    /// (every baked feature map of Spot and the bunny, at each --sizes value as the texture
    /// side, e.g. `--sizes 1024,2048`).
    #[arg(long, default_value = "meshmatch")]
    pub system: String,
    /// Worker threads, one run of the whole table per count, e.g. `1,2` for the parallel
    /// scaling of every stage (default: every core).
    #[arg(long, allow_negative_numbers = true)]
    pub threads: Option<String>,
}

impl BenchArgs {
    /// Run the subcommand; returns the exit code.
    pub fn run(&self) -> Result<i32> {
        let Some(list) = &self.threads else {
            return self.run_once();
        };
        let mut counts = Vec::new();
        for t in list.split(',') {
            match t.trim().parse::<usize>() {
                Ok(n) if (1..=256).contains(&n) => counts.push(n),
                _ => {
                    return Err(crate::error::Error::InvalidInput(format!(
                        "--threads {list}: use thread counts from 1 to 256, e.g. 1,2"
                    )));
                }
            }
        }
        // Every worker thread takes memory of its own besides the work's: refuse up front what
        // cannot fit, as the working sizes are (an allocation failing on the 200th thread
        // aborts the process).
        let sizes = crate::bench::parse_sizes(&self.sizes)?;
        let work = if self.system == "meshmatch" {
            let largest = sizes.iter().copied().max().unwrap_or(0) as u64;
            largest.saturating_mul(crate::meshmatch::WORKING_VERTEX_BYTES)
        } else {
            0
        };
        for &n in &counts {
            crate::work::check_memory(
                (n as u64)
                    .saturating_mul(crate::work::per_thread_bytes())
                    .saturating_add(work),
                &format!("--threads {n} (each worker thread with its own buffers)"),
                "use fewer --threads",
            )?;
        }
        for n in counts {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(n)
                .build()
                .map_err(|e| crate::error::Error::InvalidInput(format!("--threads {n}: {e}")))?;
            println!("threads: {n}");
            pool.install(|| self.run_once())?;
        }
        Ok(0)
    }

    fn run_once(&self) -> Result<i32> {
        if self.cancel_probes > MAX_CANCEL_PROBES {
            return Err(crate::error::Error::InvalidInput(format!(
                "--cancel-probes {}: use 0 to {MAX_CANCEL_PROBES}",
                self.cancel_probes
            )));
        }
        #[cfg(feature = "gui")]
        if self.system == "paint" {
            let sizes = crate::bench::parse_sizes(&self.sizes)?;
            for n in sizes {
                crate::bench::print_rows(crate::app::paint_bench::paint_rows(n)?, self.json);
            }
            crate::bench::print_rows(vec![crate::app::paint_bench::giraffe_row()?], self.json);
            return Ok(0);
        }
        if self.system != "meshmatch" {
            crate::bench::run_system(
                &self.system,
                &crate::bench::parse_sizes(&self.sizes)?,
                self.json,
            )?;
            return Ok(0);
        }
        crate::bench::run(
            &crate::bench::parse_sizes(&self.sizes)?,
            self.json,
            self.cancel_probes,
        )?;
        Ok(0)
    }
}
