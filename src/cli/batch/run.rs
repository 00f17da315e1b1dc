//! Running the jobs: each a child process of this same binary, in the job folder, N at a time,
//! its stdout and stderr in its log. A job that fails (or crashes) is recorded and the batch goes
//! on; a cancel stops starting jobs and kills the running ones.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use super::jobfile::Job;
use super::resume;
use super::summary::{self, Outcome, Status};
use crate::error::{Error, Result};

/// How to run a batch.
pub struct Options {
    /// Jobs at a time.
    pub jobs: usize,
    /// `RAYON_NUM_THREADS` of every job (none: a job uses every core).
    pub threads_per_job: Option<usize>,
    /// Rerun jobs that are up to date.
    pub force: bool,
    /// The meshmatch executable.
    pub exe: PathBuf,
    /// The job folder: every job's working directory.
    pub dir: PathBuf,
    pub log_dir: PathBuf,
}

/// A job running as a child process.
struct Running {
    index: usize,
    child: Child,
    start: Instant,
    log: String,
    key: Option<String>,
}

/// Run the jobs numbered `selected`; returns the outcome of each job of `jobs` (by index; `None`
/// for those not selected). Every outcome is recorded in the log folder as soon as it is known.
pub fn run(
    jobs: &[Job],
    selected: &[usize],
    opts: &Options,
    cancel: &AtomicBool,
) -> Vec<Option<Outcome>> {
    let binary = resume::binary_id(&opts.exe);
    let bar = super::super::common::progress_bar();
    bar.set_length(selected.len() as u64);
    bar.set_style(
        indicatif::ProgressStyle::with_template("[{elapsed_precise}] {bar:30} {pos}/{len} {msg}")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    let mut outcomes: Vec<Option<Outcome>> = vec![None; jobs.len()];
    let mut queue: std::collections::VecDeque<usize> = selected.iter().copied().collect();
    let mut running: Vec<Running> = Vec::new();
    let mut finish = |o: Outcome, bar: &indicatif::ProgressBar| {
        report(bar, &jobs[o.index], &o);
        if let Err(e) = summary::write_record(&opts.log_dir, &jobs[o.index], &o) {
            say(bar, &format!("meshmatch: {e}"));
        }
        bar.inc(1);
        let i = o.index;
        outcomes[i] = Some(o);
    };
    loop {
        if cancel.load(Ordering::SeqCst) {
            for r in running.drain(..) {
                finish(stop(r, jobs, opts), &bar);
            }
            for i in queue.drain(..) {
                let msg = Some("cancelled before it started".to_string());
                finish(Outcome::of(&jobs[i], Status::Cancelled, msg), &bar);
            }
            break;
        }
        while running.len() < opts.jobs.max(1)
            && let Some(i) = queue.pop_front()
        {
            match start(&jobs[i], &binary, opts) {
                Started::Done(o) => finish(o, &bar),
                Started::Running(r) => running.push(r),
            }
        }
        if running.is_empty() && queue.is_empty() {
            break;
        }
        let mut k = 0;
        while k < running.len() {
            match running[k].child.try_wait() {
                Ok(None) => k += 1,
                // A job that ends after a Ctrl-C (which reaches it too) was cancelled.
                _ if cancel.load(Ordering::SeqCst) => {
                    let r = running.swap_remove(k);
                    finish(stop(r, jobs, opts), &bar);
                }
                done => {
                    let r = running.swap_remove(k);
                    finish(ended(r, done.ok().flatten(), jobs, opts), &bar);
                }
            }
        }
        let names: Vec<&str> = running
            .iter()
            .map(|r| jobs[r.index].name.as_str())
            .collect();
        bar.set_message(names.join(", "));
        std::thread::sleep(Duration::from_millis(50));
    }
    bar.finish_and_clear();
    outcomes
}

enum Started {
    Done(Outcome),
    Running(Running),
}

/// Start `job`, or decide it without running: refused up front, or up to date.
fn start(job: &Job, binary: &str, opts: &Options) -> Started {
    if let Some(e) = &job.error {
        return Started::Done(Outcome::of(job, Status::Failed, Some(e.clone())));
    }
    let key = resume::job_key(job, binary, &opts.dir);
    let last = summary::read_record(&opts.log_dir, job);
    if !opts.force
        && key.is_some()
        && resume::outputs_exist(job, &opts.dir)
        && let Some(last) =
            last.filter(|l| matches!(l.status, Status::Ok | Status::Skipped) && l.key == key)
    {
        let mut o = Outcome::of(job, Status::Skipped, None);
        o.key = key;
        o.log = last.log;
        return Started::Done(o);
    }
    let start = Instant::now();
    match spawn(job, opts) {
        Ok((child, log)) => Started::Running(Running {
            index: job.index,
            child,
            start,
            log,
            key,
        }),
        Err(e) => Started::Done(Outcome::of(job, Status::Failed, Some(e.to_string()))),
    }
}

/// The child process of `job`, its stdout and stderr into its log; returns it and the log's
/// file name.
fn spawn(job: &Job, opts: &Options) -> Result<(Child, String)> {
    let log = format!("{}.log", summary::stem(job));
    let path = opts.log_dir.join(&log);
    let out = std::fs::File::create(&path).map_err(|e| Error::io(&path, e))?;
    let err = out.try_clone().map_err(|e| Error::io(&path, e))?;
    let mut cmd = Command::new(&opts.exe);
    cmd.args(&job.args)
        .current_dir(&opts.dir)
        .stdin(Stdio::null())
        .stdout(out)
        .stderr(err)
        // the log shows the job's progress as plain lines
        .env(super::super::common::PROGRESS_ENV, "lines");
    if let Some(t) = opts.threads_per_job {
        cmd.env("RAYON_NUM_THREADS", t.to_string());
    }
    let child = cmd.spawn().map_err(|e| Error::io(&opts.exe, e))?;
    Ok((child, log))
}

/// The outcome of a job whose process ended with `status` (`None`: it could not be waited for).
fn ended(
    r: Running,
    status: Option<std::process::ExitStatus>,
    jobs: &[Job],
    opts: &Options,
) -> Outcome {
    let job = &jobs[r.index];
    let ok = status.is_some_and(|s| s.success());
    let error = (!ok).then(|| error_line(&opts.log_dir.join(&r.log), status));
    let mut o = Outcome::of(job, if ok { Status::Ok } else { Status::Failed }, error);
    o.seconds = r.start.elapsed().as_secs_f64();
    o.log = Some(r.log);
    o.key = if ok { r.key } else { None };
    if !ok {
        remove_temporaries(job, r.child.id(), &opts.dir);
    }
    o
}

/// Kill a running job (cancel).
fn stop(mut r: Running, jobs: &[Job], opts: &Options) -> Outcome {
    let _ = r.child.kill();
    let _ = r.child.wait();
    let job = &jobs[r.index];
    remove_temporaries(job, r.child.id(), &opts.dir);
    let mut o = Outcome::of(
        job,
        Status::Cancelled,
        Some("cancelled while running".into()),
    );
    o.seconds = r.start.elapsed().as_secs_f64();
    o.log = Some(r.log);
    o
}

/// The temporary files a killed job may leave beside its outputs (`.<name>.tmp<pid>`: a
/// subcommand writes every output under such a name and renames it only once it succeeded, so
/// a killed job never leaves a half-written output, only these).
fn remove_temporaries(job: &Job, pid: u32, dir: &Path) {
    let suffix = format!(".tmp{pid}");
    let mut folders: Vec<PathBuf> = job
        .outputs
        .iter()
        .filter_map(|o| dir.join(o).parent().map(Path::to_path_buf))
        .collect();
    folders.dedup();
    for folder in folders {
        let Ok(entries) = std::fs::read_dir(&folder) else {
            continue;
        };
        for e in entries.flatten() {
            let name = e.file_name().to_string_lossy().into_owned();
            if name.starts_with('.') && name.ends_with(&suffix) {
                let _ = std::fs::remove_file(e.path());
            }
        }
    }
}

/// The line that says why a job failed: its last `meshmatch: ...` line (without that prefix),
/// else its last line, else how the process ended.
fn error_line(log: &Path, status: Option<std::process::ExitStatus>) -> String {
    let text = std::fs::read(log)
        .map(|b| String::from_utf8_lossy(&b).into_owned())
        .unwrap_or_default();
    let lines: Vec<&str> = text
        .lines()
        .map(str::trim)
        .filter(|l| !l.is_empty())
        .collect();
    let line = lines
        .iter()
        .rev()
        .find(|l| l.starts_with("meshmatch:"))
        .or(lines.last());
    let how = match status {
        Some(s) => match s.code() {
            Some(c) => format!("exit status {c}"),
            None => format!("killed ({s})"),
        },
        None => "lost track of the process".to_string(),
    };
    match line {
        Some(l) => format!(
            "{} ({how})",
            l.trim_start_matches("meshmatch:").trim_start()
        ),
        None => how,
    }
}

/// Print a line above the progress bar (or plainly when the bar is hidden: not a terminal).
pub fn say(bar: &indicatif::ProgressBar, line: &str) {
    if bar.is_hidden() {
        eprintln!("{line}");
    } else {
        bar.println(line);
    }
}

/// The status line of a finished job.
fn report(bar: &indicatif::ProgressBar, job: &Job, o: &Outcome) {
    let line = match o.status {
        Status::Ok => format!("ok        {:7.2} s  {}", o.seconds, job.label()),
        Status::Skipped => format!("skipped             {}: up to date", job.label()),
        _ => format!(
            "{:<9} {:7.2} s  {}: {}",
            o.status.as_str(),
            o.seconds,
            job.label(),
            o.error.as_deref().unwrap_or("")
        ),
    };
    say(bar, &line);
}
