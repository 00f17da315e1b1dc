//! `meshmatch batch JOBS.toml`: many subcommands from a job file, N at a time, each a child
//! process of this binary run in the job file's folder, with per-job logs, a summary, resume and
//! cancel; or, with `--emit-openjd DIR`, the same jobs as an OpenJD job template for a farm.
//! The format and the rules are in docs/batch.md.

mod jobfile;
mod openjd;
mod resume;
mod run;
mod summary;
mod validate;

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use crate::error::{Error, Result};
use summary::Status;

/// Arguments of `meshmatch batch`.
#[derive(clap::Args, Debug)]
pub struct BatchArgs {
    /// The job file: `[[job]]` tables (`name`, `args`) and `[[each]]` tables (`glob`, `args`,
    /// `name`) in TOML, or the same in JSON (by the extension .json). Relative paths in it are
    /// relative to its folder, where every job runs.
    pub job_file: PathBuf,
    /// Jobs run at a time (default: the number of cores divided by --threads-per-job; 1 without
    /// it, since a job uses every core).
    #[arg(long, allow_negative_numbers = true, value_parser = PARALLEL)]
    pub jobs: Option<usize>,
    /// Threads each job may use (its RAYON_NUM_THREADS); default every core.
    #[arg(long, allow_negative_numbers = true, value_parser = THREADS)]
    pub threads_per_job: Option<usize>,
    /// Where the logs and the summary go (default: `<job file stem>-batch/` beside the job file).
    #[arg(long)]
    pub log_dir: Option<PathBuf>,
    /// Rerun jobs that are up to date.
    #[arg(long)]
    pub force: bool,
    /// Run only the jobs of these indices (comma-separated or repeated), as a farm task does.
    #[arg(long, value_delimiter = ',', allow_negative_numbers = true, value_parser = JOB_INDEX)]
    pub only: Vec<usize>,
    /// Write an OpenJD job template (template.json) and its parameter values (params.json) into
    /// this folder instead of running: one task per job.
    #[arg(long)]
    pub emit_openjd: Option<PathBuf>,
}

/// Largest `--jobs` and `--threads-per-job`.
const MAX_PARALLEL: usize = 1024;
/// `--jobs`.
const PARALLEL: super::common::Whole<usize> =
    super::common::whole(1, MAX_PARALLEL).unit("jobs at a time");
/// `--threads-per-job`.
const THREADS: super::common::Whole<usize> =
    super::common::whole(1, MAX_PARALLEL).unit("threads per job");
/// `--only`.
const JOB_INDEX: super::common::Whole<usize> =
    super::common::at_least(0).unit("(a job's index from 0)");

impl BatchArgs {
    /// Run the subcommand; returns the exit code: 0 when every job succeeded or was up to date,
    /// 1 when any failed, 130 when cancelled.
    pub fn run(&self) -> Result<i32> {
        self.check_counts()?;
        let job_file =
            std::path::absolute(&self.job_file).map_err(|e| Error::io(&self.job_file, e))?;
        if !job_file.is_file() {
            return Err(Error::InvalidInput(format!(
                "{}: no such job file",
                self.job_file.display()
            )));
        }
        let dir = job_file.parent().map(Path::to_path_buf).unwrap_or_default();
        let mut jobs = jobfile::load(&job_file, &dir)?;
        validate::validate(&mut jobs, &dir, &job_file);
        let log_dir = match &self.log_dir {
            Some(d) => std::path::absolute(d).map_err(|e| Error::io(d, e))?,
            None => dir.join(format!("{}-batch", stem(&job_file))),
        };
        let exe = std::env::current_exe().map_err(|e| Error::io("meshmatch", e))?;
        if let Some(out) = &self.emit_openjd {
            return emit(out, &job_file, &exe, &log_dir, &jobs);
        }
        let selected = self.selected(&jobs)?;
        std::fs::create_dir_all(&log_dir).map_err(|e| Error::io(&log_dir, e))?;
        let opts = run::Options {
            jobs: self.parallel(),
            threads_per_job: self.threads_per_job,
            force: self.force,
            exe,
            dir,
            log_dir,
        };
        let cancel = cancel_flag();
        let outcomes = run::run(&jobs, &selected, &opts, &cancel);
        let all = summary::write_summary(&opts.log_dir, &job_file, &jobs, outcomes)?;
        Ok(finish(&all, &selected, &opts.log_dir))
    }

    fn check_counts(&self) -> Result<()> {
        for (flag, v) in [
            ("--jobs", self.jobs),
            ("--threads-per-job", self.threads_per_job),
        ] {
            if let Some(n) = v.filter(|n| !(1..=MAX_PARALLEL).contains(n)) {
                return Err(Error::InvalidInput(format!(
                    "{flag} {n}: use 1 to {MAX_PARALLEL}"
                )));
            }
        }
        Ok(())
    }

    /// Jobs at a time: `--jobs`, else cores / `--threads-per-job`, else 1.
    fn parallel(&self) -> usize {
        if let Some(n) = self.jobs {
            return n;
        }
        let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
        self.threads_per_job.map_or(1, |t| (cores / t).max(1))
    }

    /// The indices to run: `--only`'s (each must exist), else all.
    fn selected(&self, jobs: &[jobfile::Job]) -> Result<Vec<usize>> {
        if self.only.is_empty() {
            return Ok((0..jobs.len()).collect());
        }
        if let Some(&i) = self.only.iter().find(|&&i| i >= jobs.len()) {
            return Err(Error::InvalidInput(format!(
                "--only {i}: the job file has {} jobs (0 to {})",
                jobs.len(),
                jobs.len().saturating_sub(1)
            )));
        }
        let mut s = self.only.clone();
        s.sort_unstable();
        s.dedup();
        Ok(s)
    }
}

fn stem(path: &Path) -> String {
    path.file_stem()
        .map_or_else(|| "jobs".into(), |s| s.to_string_lossy().into_owned())
}

/// A flag set by Ctrl-C (SIGINT, SIGTERM): no job starts after it, running ones are killed.
fn cancel_flag() -> Arc<AtomicBool> {
    let flag = Arc::new(AtomicBool::new(false));
    let f = flag.clone();
    if let Err(e) = ctrlc::set_handler(move || f.store(true, Ordering::SeqCst)) {
        eprintln!("meshmatch: warning: Ctrl-C will not cancel the batch cleanly ({e})");
    }
    flag
}

/// `--emit-openjd`: the template for the jobs that can run; the others are reported.
fn emit(
    out: &Path,
    job_file: &Path,
    exe: &Path,
    log_dir: &Path,
    jobs: &[jobfile::Job],
) -> Result<i32> {
    let out = std::path::absolute(out).map_err(|e| Error::io(out, e))?;
    let bad: Vec<_> = jobs.iter().filter(|j| j.error.is_some()).collect();
    for j in &bad {
        eprintln!(
            "failed    {}: {}",
            j.label(),
            j.error.as_deref().unwrap_or("")
        );
    }
    let n = openjd::emit(&out, job_file, exe, log_dir, jobs)?;
    eprintln!(
        "wrote {} and {} ({n} tasks); check with: openjd check {}",
        out.join(openjd::TEMPLATE).display(),
        out.join(openjd::PARAMS).display(),
        out.join(openjd::TEMPLATE).display()
    );
    Ok(if bad.is_empty() { 0 } else { 1 })
}

/// Print the counts of the whole batch; the exit code of this run.
fn finish(all: &[summary::Outcome], selected: &[usize], log_dir: &Path) -> i32 {
    let count = |s: Status| all.iter().filter(|o| o.status == s).count();
    eprintln!(
        "batch: {} ok, {} skipped, {} failed, {} cancelled, {} not run; summary in {}",
        count(Status::Ok),
        count(Status::Skipped),
        count(Status::Failed),
        count(Status::Cancelled),
        count(Status::NotRun),
        log_dir.join("batch-summary.txt").display()
    );
    let mine = |s: Status| {
        selected
            .iter()
            .any(|&i| all.get(i).is_some_and(|o| o.status == s))
    };
    if mine(Status::Cancelled) {
        130
    } else if mine(Status::Failed) {
        1
    } else {
        0
    }
}
