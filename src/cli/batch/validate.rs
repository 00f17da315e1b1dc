//! Every job checked before any runs, by the CLI's own clap parser: its subcommand and arguments,
//! and the files it reads. The same pass finds its inputs and outputs for the resume rule.

use std::any::TypeId;
use std::ffi::OsString;
use std::path::{Path, PathBuf};

use clap::parser::ValueSource;
use clap::{CommandFactory, FromArgMatches};

use super::jobfile::Job;
use crate::cli::Cli;

/// True for the arguments whose values a job writes: `--out`, `--out-*`, `--*-out`, and
/// `convert`'s positional `output`.
pub fn is_output(id: &str) -> bool {
    id == "out" || id == "output" || id.starts_with("out_") || id.ends_with("_out")
}

/// Check every job still without an error, and fill in its inputs and outputs; a job that
/// fails gets its one-line error. `dir` is the job folder (relative paths are read there); no
/// job may write over `job_file` itself.
pub fn validate(jobs: &mut [Job], dir: &Path, job_file: &Path) {
    let cli = Cli::command();
    for job in jobs.iter_mut().filter(|j| j.error.is_none()) {
        if let Err(msg) = check(job, &cli, dir) {
            job.error = Some(msg);
        } else if let Some(o) = job
            .outputs
            .iter()
            .find(|o| crate::cli::common::same_location(&dir.join(o), job_file))
        {
            job.error = Some(format!(
                "{} is the job file itself: a job may not write over it",
                o.display()
            ));
        }
    }
}

fn check(job: &mut Job, cli: &clap::Command, dir: &Path) -> Result<(), String> {
    match job.args.first().map(String::as_str) {
        None => return Err("`args` is empty: name a subcommand first".into()),
        Some("batch") => return Err("a job cannot run `batch` itself".into()),
        Some(a) if a.starts_with('-') => {
            return Err(format!("`args` must start with a subcommand, not \"{a}\""));
        }
        _ => {}
    }
    let argv =
        std::iter::once(OsString::from("meshmatch")).chain(job.args.iter().map(|a| a.into()));
    let matches = cli.clone().try_get_matches_from(argv).map_err(|e| {
        use clap::error::ErrorKind;
        match e.kind() {
            ErrorKind::DisplayHelp | ErrorKind::DisplayVersion => {
                "asks for help or the version instead of doing work".to_string()
            }
            _ => crate::cli::clap_error_line(&e),
        }
    })?;
    Cli::from_arg_matches(&matches).map_err(|e| crate::cli::clap_error_line(&e))?;
    let Some((name, sub)) = matches.subcommand() else {
        return Err("no subcommand".into());
    };
    let Some(cmd) = cli.find_subcommand(name) else {
        return Err(format!("unknown subcommand `{name}`"));
    };
    for arg in cmd.get_arguments() {
        let id = arg.get_id().as_str();
        if sub.value_source(id) != Some(ValueSource::CommandLine) {
            continue;
        }
        let Ok(Some(values)) = sub.try_get_raw(id) else {
            continue;
        };
        let is_path = arg.get_value_parser().type_id() == TypeId::of::<PathBuf>();
        let flag = arg
            .get_long()
            .map_or_else(|| id.to_string(), |l| format!("--{l}"));
        for v in values {
            let p = PathBuf::from(v);
            if is_output(id) {
                job.outputs.push(p);
            } else if dir.join(&p).is_file() {
                job.inputs.push(p);
            } else if is_path {
                return Err(format!("{flag} {}: no such file", p.display()));
            }
        }
    }
    Ok(())
}
