//! `meshmatch bench`: stage timings at several working resolutions.

use crate::error::Result;

/// Arguments of `meshmatch bench`.
#[derive(clap::Args, Debug)]
pub struct BenchArgs {
    /// Working resolutions, e.g. `16k,64k,256k,1m` (each at most 4m).
    #[arg(long, default_value = "16k,64k")]
    pub sizes: String,
    /// One JSON object per line per size.
    #[arg(long)]
    pub json: bool,
    /// After each size, cancel that many whole transfers at evenly spaced moments and
    /// report how long each took to stop (at most 1000).
    #[arg(long, default_value_t = 0)]
    pub cancel_probes: usize,
    /// Which system: meshmatch (the transfer's table), weather (geometry-correlated transfer,
    /// Spot -> horse at each size), quilt (chain mail on a plane and on the bunny), map (the
    /// global shape map man -> woman at each size, and a transfer with structure 0 and auto) or
    /// synth (`synth` with its defaults, every shared texture on every shared mesh).
    #[arg(long, default_value = "meshmatch")]
    pub system: String,
}

impl BenchArgs {
    /// Run the subcommand; returns the exit code.
    pub fn run(&self) -> Result<i32> {
        if self.cancel_probes > 1000 {
            return Err(crate::error::Error::InvalidInput(format!(
                "--cancel-probes {}: use 0 to 1000",
                self.cancel_probes
            )));
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
