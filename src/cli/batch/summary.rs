//! What a batch leaves in its log folder: per job `<index>-<name>.log` (its stdout and stderr)
//! and `<index>-<name>.json` (its outcome and resume key), and over all jobs
//! `batch-summary.json` and the table `batch-summary.txt`, rebuilt from the per-job records after
//! every run (so tasks of one batch run apart, `--only`, still add up to one summary).

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use super::jobfile::Job;
use crate::error::{Error, Result};

/// How a job ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Status {
    /// Ran and exited with status 0.
    Ok,
    /// Up to date: outputs present, same key as its last successful run.
    Skipped,
    /// Refused before running, or exited non-zero, or could not start.
    Failed,
    /// Stopped (or never started) because the batch was cancelled.
    Cancelled,
    /// Not part of this run (`--only`) and no record of an earlier one.
    NotRun,
}

impl Status {
    pub fn as_str(self) -> &'static str {
        match self {
            Status::Ok => "ok",
            Status::Skipped => "skipped",
            Status::Failed => "failed",
            Status::Cancelled => "cancelled",
            Status::NotRun => "not run",
        }
    }
}

/// The record of one job's last run.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Outcome {
    pub index: usize,
    pub name: String,
    pub args: Vec<String>,
    pub status: Status,
    /// Wall-clock seconds of the run (0 when skipped or not started).
    pub seconds: f64,
    pub outputs: Vec<String>,
    /// One line: why it failed.
    pub error: Option<String>,
    /// Its log file, relative to the log folder.
    pub log: Option<String>,
    /// The resume key of its last successful run.
    pub key: Option<String>,
}

impl Outcome {
    /// An outcome of `job` without a run.
    pub fn of(job: &Job, status: Status, error: Option<String>) -> Outcome {
        Outcome {
            index: job.index,
            name: job.name.clone(),
            args: job.args.clone(),
            status,
            seconds: 0.0,
            outputs: job
                .outputs
                .iter()
                .map(|o| o.to_string_lossy().into_owned())
                .collect(),
            error,
            log: None,
            key: None,
        }
    }
}

/// The file name of a job's files without extension: `<index>-<name>`, the name reduced to
/// letters, digits, `.`, `_` and `-`.
pub fn stem(job: &Job) -> String {
    let name: String = job
        .name
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || matches!(c, '.' | '_' | '-') {
                c
            } else {
                '_'
            }
        })
        .take(80)
        .collect();
    format!("{}-{name}", job.index)
}

fn record_path(log_dir: &Path, job: &Job) -> PathBuf {
    log_dir.join(format!("{}.json", stem(job)))
}

/// The record of `job`'s last run, if any.
pub fn read_record(log_dir: &Path, job: &Job) -> Option<Outcome> {
    let text = std::fs::read_to_string(record_path(log_dir, job)).ok()?;
    serde_json::from_str(&text).ok()
}

/// Keep `outcome` as `job`'s record.
pub fn write_record(log_dir: &Path, job: &Job, outcome: &Outcome) -> Result<()> {
    let text = serde_json::to_string_pretty(outcome).unwrap_or_default();
    write_now(&record_path(log_dir, job), text.as_bytes())
}

/// Write a file at once through a temporary name and a rename (the batch's own files are not
/// part of the staged writes that a subcommand's outputs wait in until it succeeds: each record
/// must be on disk as soon as its job ends, for resume after an interrupted batch).
pub fn write_now(path: &Path, bytes: &[u8]) -> Result<()> {
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned());
    let tmp = path.with_file_name(format!(
        ".{}.tmp{}",
        name.unwrap_or_default(),
        std::process::id()
    ));
    std::fs::write(&tmp, bytes).map_err(|e| Error::io(path, e))?;
    std::fs::rename(&tmp, path).map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        Error::io(path, e)
    })
}

/// Write `batch-summary.json` and `batch-summary.txt`: `outcomes` for the jobs of this run,
/// each other job's record (or "not run"). Returns the outcomes of every job.
pub fn write_summary(
    log_dir: &Path,
    job_file: &Path,
    jobs: &[Job],
    mut outcomes: Vec<Option<Outcome>>,
) -> Result<Vec<Outcome>> {
    let all: Vec<Outcome> = jobs
        .iter()
        .map(|j| {
            outcomes
                .get_mut(j.index)
                .and_then(Option::take)
                .or_else(|| read_record(log_dir, j))
                .unwrap_or_else(|| Outcome::of(j, Status::NotRun, j.error.clone()))
        })
        .collect();
    let count = |s: Status| all.iter().filter(|o| o.status == s).count();
    let json = serde_json::json!({
        "job_file": job_file.display().to_string(),
        "meshmatch": env!("CARGO_PKG_VERSION"),
        "counts": {
            "ok": count(Status::Ok),
            "skipped": count(Status::Skipped),
            "failed": count(Status::Failed),
            "cancelled": count(Status::Cancelled),
            "not_run": count(Status::NotRun),
        },
        "jobs": all,
    });
    let text = serde_json::to_string_pretty(&json).unwrap_or_default();
    write_now(&log_dir.join("batch-summary.json"), text.as_bytes())?;
    write_now(&log_dir.join("batch-summary.txt"), table(&all).as_bytes())?;
    Ok(all)
}

/// Widest the summary table's name column grows.
const NAME_COLUMN: usize = 60;

/// The summary as a text table: index, name, status, seconds, outputs, error.
pub fn table(all: &[Outcome]) -> String {
    // the name column fits the longest name up to NAME_COLUMN characters; a longer name runs
    // past it (a width past 65535 is not even formattable)
    let w = all
        .iter()
        .map(|o| o.name.chars().count())
        .max()
        .unwrap_or(4)
        .clamp(4, NAME_COLUMN);
    let mut s = format!(
        "{:>5}  {:<w$}  {:<9}  {:>8}  {:<30}  error\n",
        "index", "name", "status", "seconds", "outputs"
    );
    for o in all {
        let outputs = if o.outputs.is_empty() {
            "-".to_string()
        } else {
            o.outputs.join(", ")
        };
        s += &format!(
            "{:>5}  {:<w$}  {:<9}  {:>8.2}  {:<30}  {}\n",
            o.index,
            o.name,
            o.status.as_str(),
            o.seconds,
            outputs,
            o.error.as_deref().unwrap_or("")
        );
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_name_of_any_length_fits_the_table() {
        let outcome = |name: String| Outcome {
            index: 0,
            name,
            args: Vec::new(),
            status: Status::Ok,
            seconds: 1.0,
            outputs: Vec::new(),
            error: None,
            log: None,
            key: None,
        };
        let long = "a".repeat(70_000);
        let t = table(&[outcome(long.clone()), outcome("short".into())]);
        assert!(t.contains(&long));
        // short names still line up in a column of at most NAME_COLUMN characters
        let row = t.lines().find(|l| l.contains("short")).unwrap();
        assert!(
            row.len() < 5 + 2 + NAME_COLUMN + 2 + 9 + 2 + 8 + 2 + 30 + 4,
            "{row}"
        );
    }
}
