//! The command-line interface: `meshmatch [COMMAND]`. No command opens the app.
//!
//! One file per subcommand, each with an `Args` struct (clap) and `run(&self) -> Result<i32>`.
//! A new subcommand is its file plus one line in the `commands!` list below.

pub mod bake;
mod batch;
mod bench;
pub mod common;
pub mod complete;
mod convert;
mod demo;
pub mod detail;
pub mod exemplar;
pub mod feature_aligned;
pub mod features;
mod info;
mod map;
pub mod quilting;
#[cfg(feature = "gui")]
mod render;
pub mod transfer;
pub mod update;
pub mod weathering;

use std::io::Write;

use clap::{Parser, Subcommand};

use crate::error::Result;

pub use common::{SolveArgs, read_mask};
pub use info::info_json;
#[cfg(feature = "gui")]
pub use render::MarkerSide;

/// Example-based texturing of 3D meshes.
#[derive(Parser, Debug)]
#[command(name = "meshmatch", version, about, long_about = None)]
pub struct Cli {
    /// What to do; without a command the desktop app opens on the demo scene.
    #[command(subcommand)]
    pub command: Option<Command>,
}

/// Declares the subcommands: the `Command` enum (variant doc = the command's help) and its
/// dispatch to each `Args::run`.
macro_rules! commands {
    ($( $(#[$meta:meta])* $name:ident($args:ty), )*) => {
        /// The subcommands.
        #[derive(Subcommand, Debug)]
        pub enum Command {
            $( $(#[$meta])* $name($args), )*
        }

        impl Command {
            /// Run the subcommand; returns the exit code.
            #[allow(unused_doc_comments)]
            pub fn run(&self) -> Result<i32> {
                match self {
                    $( $(#[$meta])* Command::$name(a) => a.run(), )*
                }
            }
        }
    };
}

commands! {
    /// Print counts, bounds, components, boundary loops, signal kind and repairs of mesh files.
    Info(info::InfoArgs),
    /// Convert a mesh between formats (by extension), keeping vertex order, UVs, colours, texture.
    Convert(convert::ConvertArgs),
    /// Bake a coloured mesh (a dense synth, quilt or transfer result) into a texture on another
    /// mesh of the same shape, through its UVs or a generated UV atlas.
    Bake(bake::BakeArgs),
    /// Write the procedural demo scene (zebra, giraffe, cerberus, vase) as GLB files.
    Demo(demo::DemoArgs),
    /// Transfer a texture from a source mesh to a target mesh (MeshMatch).
    Transfer(transfer::TransferArgs),
    /// The global intrinsic shape map between two meshes (functional maps + ZoomOut) as a CSV of
    /// target vertex -> source vertex; the correspondences are landmarks.
    Map(map::MapArgs),
    /// Synthesize a texture over a mesh from a 2D exemplar image (Wei and Levoy 2001).
    Synth(exemplar::SynthArgs),
    /// Complete a partly painted mesh by example: the painted (or unmasked) vertices are the
    /// example, the rest is synthesised; painted vertices keep their colours exactly.
    Complete(complete::CompleteArgs),
    /// Update the texture after a geometry edit: copy colours where the new surface coincides with
    /// the old one, synthesise only the changed region.
    Update(update::UpdateArgs),
    /// Transfer geometric detail (displacement along the normal) from a detailed mesh to a smooth one.
    Detail(detail::DetailArgs),
    /// Geometry-correlated transfer (Mertens et al. 2006): weathering, dirt, moss learned from a
    /// textured model and applied to any shape by its geometry, without correspondences.
    Weather(weathering::WeatherArgs),
    /// Bake one geometric feature as vertex colours: ambient occlusion, curvature, height...
    Features(features::FeaturesArgs),
    /// Mesh quilting (Zhou et al. 2006): cover a surface with 3D elements from a swatch (chain
    /// mail, weaves, nuts, studs, scales), every element whole.
    Quilt(quilting::QuiltArgs),
    /// Write a built-in procedural swatch for `quilt`.
    Swatch(quilting::SwatchArgs),
    /// Salient curves (crest lines and sharp creases) of a mesh as OBJ polylines (Xu et al. 2009).
    Curves(feature_aligned::CurvesArgs),
    /// Time the transfer's stages at several working resolutions (Spot -> horse from the shared data).
    Bench(bench::BenchArgs),
    /// Run many subcommands from a job file (TOML or JSON), N at a time, each as a child process,
    /// with logs, a summary and resume; or write it as an OpenJD job template for a render farm.
    Batch(batch::BatchArgs),
    /// Render a mesh to a PNG offscreen (headlight Lambert shading, vertex colours or texture).
    #[cfg(feature = "gui")]
    Render(render::RenderArgs),
}

/// Run the CLI; returns the process exit code.
pub fn main() -> i32 {
    std::panic::set_hook(Box::new(|info| {
        let msg = info
            .payload()
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| info.payload().downcast_ref::<String>().cloned())
            .unwrap_or_else(|| "unknown".into());
        if is_broken_pipe(&msg) {
            // stdout was closed by the reader (`| head`): not an error, nothing to say.
            return;
        }
        let at = info
            .location()
            .map(|l| format!(" at {}:{}", l.file(), l.line()))
            .unwrap_or_default();
        // Never panic inside the hook (eprintln! would, if stderr is gone too).
        let _ = writeln!(
            std::io::stderr().lock(),
            "meshmatch: internal error: {msg}{at}"
        );
    }));
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => {
            use clap::error::{ContextKind, ContextValue, ErrorKind};
            if matches!(
                e.kind(),
                ErrorKind::DisplayHelp
                    | ErrorKind::DisplayVersion
                    | ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand
            ) {
                let _ = e.print();
                return e.exit_code();
            }
            // A value refused by a flag's own parser reads like every other range check:
            // "--structure 2: use auto or ...".
            if e.kind() == ErrorKind::ValueValidation
                && let (Some(ContextValue::String(arg)), Some(ContextValue::String(value))) = (
                    e.get(ContextKind::InvalidArg),
                    e.get(ContextKind::InvalidValue),
                )
                && let Some(why) = std::error::Error::source(&e)
            {
                let flag = arg.split_whitespace().next().unwrap_or(arg);
                let _ = writeln!(std::io::stderr().lock(), "meshmatch: {flag} {value}: {why}");
                return 2;
            }
            // "-inf" and "-nan" are not numbers to clap's negative-number test, so they arrive
            // as an unknown option; say which option they were given to.
            // (clap names the first letter, "-i", as a short option)
            let args: Vec<String> = std::env::args_os()
                .map(|a| a.to_string_lossy().into_owned())
                .collect();
            if e.kind() == ErrorKind::UnknownArgument
                && let Some(ContextValue::String(bad)) = e.get(ContextKind::InvalidArg)
                && let Some(at) = args
                    .iter()
                    .position(|a| is_signed_non_finite(a) && a.starts_with(bad.as_str()))
            {
                let arg = &args[at];
                let flag = at
                    .checked_sub(1)
                    .map(|i| args[i].as_str())
                    .filter(|f| f.starts_with("--"));
                let line = match flag {
                    Some(flag) => format!("{flag} {arg}: not a finite number"),
                    None => format!("{arg}: not a finite number"),
                };
                let _ = writeln!(std::io::stderr().lock(), "meshmatch: {line} (see --help)");
                return 2;
            }
            let first = clap_error_line(&e);
            let _ = writeln!(std::io::stderr().lock(), "meshmatch: {first} (see --help)");
            return 2;
        }
    };
    let res = std::panic::catch_unwind(|| match &cli.command {
        None => open_app(),
        Some(c) => {
            // A command never writes over a file it read (an output's texture beside an input),
            // and its outputs replace existing files only once the whole command succeeded.
            crate::mesh::io::protect_inputs();
            let staged = crate::mesh::io::StagedWrites::begin();
            // interrupted (Ctrl-C, a scheduler's SIGTERM), a command leaves none of its files
            // behind; `batch` cancels its jobs with its own handler
            if !matches!(c, Command::Batch(_)) {
                let _ = ctrlc::set_handler(|| {
                    // the outputs are complete and being renamed: the command ends as it would
                    // have, with every file delivered
                    if crate::mesh::io::committing() {
                        return;
                    }
                    crate::mesh::io::discard_staged();
                    std::process::exit(130);
                });
            }
            let code = c.run();
            let said = common::take_announced();
            let code = code?;
            staged.commit()?;
            let mut err = std::io::stderr().lock();
            for line in said {
                let _ = writeln!(err, "{line}");
            }
            Ok(code)
        }
    });
    match res {
        Ok(Ok(code)) => code,
        Ok(Err(e)) => {
            let _ = writeln!(std::io::stderr().lock(), "meshmatch: {e}");
            2
        }
        Err(payload) => {
            let msg = payload
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| payload.downcast_ref::<String>().cloned())
                .unwrap_or_default();
            if is_broken_pipe(&msg) { 0 } else { 2 }
        }
    }
}

/// "-inf", "-infinity" and "-nan" in any case: a value that parses as a float but that clap,
/// which takes a word starting with '-' for an option unless it is a finite number, never
/// hands to the option's parser.
fn is_signed_non_finite(arg: &str) -> bool {
    arg.strip_prefix('-')
        .map(|r| ["inf", "infinity", "nan"].contains(&r.to_ascii_lowercase().as_str()))
        .unwrap_or(false)
}

/// A bad argument as one line, like every other refusal (clap's own text adds a usage hint on
/// further lines), without clap's "error: " prefix.
pub(crate) fn clap_error_line(e: &clap::Error) -> String {
    let text = e.to_string();
    let first: Vec<&str> = text
        .lines()
        .map(str::trim)
        .skip_while(|l| l.is_empty())
        .take_while(|l| !l.is_empty() && !l.starts_with("Usage:"))
        .collect();
    first.join(" ").trim_start_matches("error: ").to_string()
}

/// True for the panic of `print!`/`println!` when stdout is a closed pipe: the reader (e.g.
/// `head`) has all it wants, so the program stops quietly with status 0, as Unix tools do.
fn is_broken_pipe(panic_msg: &str) -> bool {
    panic_msg.starts_with("failed printing to stdout") && panic_msg.contains("Broken pipe")
}

#[cfg(feature = "gui")]
fn open_app() -> Result<i32> {
    crate::app::run(crate::app::Startup::default())?;
    Ok(0)
}

#[cfg(not(feature = "gui"))]
fn open_app() -> Result<i32> {
    eprintln!(
        "meshmatch was built without the `gui` feature; run `meshmatch --help` for the commands"
    );
    Ok(2)
}
