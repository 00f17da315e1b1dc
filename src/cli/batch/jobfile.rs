//! The job file: `[[job]]` and `[[each]]` tables in TOML, or the same structure in JSON, read
//! into a list of [`Job`]s. A broken entry becomes a job that carries its error, so the others
//! are never lost; only a file that cannot be read or parsed at all is refused.

use std::path::{Path, PathBuf};

use serde_json::{Map, Value};

use crate::error::{Error, Result};

/// One job of a batch, as expanded from the job file.
#[derive(Clone, Debug)]
pub struct Job {
    /// Its number in the expanded list (the `[[job]]` tables in order, then each `[[each]]`
    /// table's matches in order), the OpenJD task parameter.
    pub index: usize,
    /// Its `name`, or `job-<index>`; for `[[each]]`, its `name` template or the file's stem.
    pub name: String,
    /// The arguments of one `meshmatch` subcommand, as on the command line.
    pub args: Vec<String>,
    /// Why it cannot run, found before any job starts (then it is reported as failed).
    pub error: Option<String>,
    /// Existing files named by its arguments (outputs excluded), relative to the job folder.
    pub inputs: Vec<PathBuf>,
    /// The values of its output arguments (`--out`, `--out-dense`, `--nnf-out`, `convert`'s
    /// output), relative to the job folder.
    pub outputs: Vec<PathBuf>,
}

impl Job {
    fn new(name: String, args: Vec<String>, error: Option<String>) -> Job {
        Job {
            index: 0,
            name,
            args,
            error,
            inputs: Vec::new(),
            outputs: Vec::new(),
        }
    }

    /// How messages name the job: `job 3 (spot-to-bunny)`.
    pub fn label(&self) -> String {
        format!("job {} ({})", self.index, self.name)
    }
}

/// Read the job file (TOML, or JSON by the extension `.json`) and expand it; relative globs are
/// matched in `dir`, the job file's folder.
pub fn load(path: &Path, dir: &Path) -> Result<Vec<Job>> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    let is_json = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("json"));
    let doc: Value = if is_json {
        serde_json::from_str(&text).map_err(|e| Error::format(path, e.to_string()))?
    } else {
        let table: toml::Table =
            toml::from_str(&text).map_err(|e| Error::format(path, one_line(&e.to_string())))?;
        serde_json::to_value(table).map_err(|e| Error::format(path, e.to_string()))?
    };
    let Value::Object(top) = doc else {
        return Err(Error::format(
            path,
            "expected a table of `job` and `each` lists",
        ));
    };
    if let Some(k) = top.keys().find(|k| *k != "job" && *k != "each") {
        return Err(Error::format(
            path,
            format!("unknown key `{k}` (a job file has `job` and `each` lists)"),
        ));
    }
    let mut jobs = Vec::new();
    for (i, entry) in list(&top, "job", path)?.iter().enumerate() {
        jobs.push(plain_job(i, entry));
    }
    for (i, entry) in list(&top, "each", path)?.iter().enumerate() {
        jobs.extend(each_jobs(i, entry, dir));
    }
    for (i, job) in jobs.iter_mut().enumerate() {
        job.index = i;
        if job.name.is_empty() {
            job.name = format!("job-{i}");
        }
    }
    Ok(jobs)
}

/// A TOML parser's message on one line (it draws the offending line under its first line).
fn one_line(text: &str) -> String {
    let lines: Vec<&str> = text
        .lines()
        .map(str::trim)
        .filter(|l| !l.is_empty() && !l.starts_with('|') && !l.starts_with('^'))
        .collect();
    lines.join(" ")
}

/// The array under `key` (absent = empty).
fn list<'a>(top: &'a Map<String, Value>, key: &str, path: &Path) -> Result<&'a [Value]> {
    match top.get(key) {
        None => Ok(&[]),
        Some(Value::Array(a)) => Ok(a),
        Some(_) => Err(Error::format(
            path,
            format!("`{key}` must be a list of tables ([[{key}]] in TOML)"),
        )),
    }
}

/// The string fields of an entry, checked: only `allowed` keys, `args` a list of strings.
struct Entry {
    name: Option<String>,
    glob: Option<String>,
    args: Vec<String>,
}

fn entry(v: &Value, allowed: &[&str]) -> std::result::Result<Entry, String> {
    let Value::Object(m) = v else {
        return Err("not a table".into());
    };
    if let Some(k) = m.keys().find(|k| !allowed.contains(&k.as_str())) {
        return Err(format!("unknown key `{k}` (use {})", allowed.join(", ")));
    }
    let string = |key: &str| match m.get(key) {
        None => Ok(None),
        Some(Value::String(s)) => Ok(Some(s.clone())),
        Some(_) => Err(format!("`{key}` must be a string")),
    };
    let args = match m.get("args") {
        Some(Value::Array(a)) => a
            .iter()
            .map(|x| x.as_str().map(str::to_string))
            .collect::<Option<Vec<_>>>()
            .ok_or_else(|| "`args` must be a list of strings".to_string())?,
        Some(_) => return Err("`args` must be a list of strings".into()),
        None => return Err("no `args` (the subcommand and its arguments)".into()),
    };
    Ok(Entry {
        name: string("name")?,
        glob: string("glob")?,
        args,
    })
}

/// A `[[job]]` table.
fn plain_job(i: usize, v: &Value) -> Job {
    let given_name = v.get("name").and_then(Value::as_str).map(str::to_string);
    match entry(v, &["name", "args"]) {
        Ok(e) => Job::new(e.name.unwrap_or_default(), e.args, None),
        Err(msg) => Job::new(
            given_name.unwrap_or_default(),
            Vec::new(),
            Some(format!("[[job]] table {}: {msg}", i + 1)),
        ),
    }
}

/// An `[[each]]` table: one job per file matching its glob, or one failed job saying why none.
fn each_jobs(i: usize, v: &Value, dir: &Path) -> Vec<Job> {
    let fallback = v
        .get("name")
        .and_then(Value::as_str)
        .map_or_else(|| format!("each-{}", i + 1), str::to_string);
    let failed = |msg: String| vec![Job::new(fallback.clone(), Vec::new(), Some(msg))];
    let e = match entry(v, &["name", "glob", "args"]) {
        Ok(e) => e,
        Err(msg) => return failed(format!("[[each]] table {}: {msg}", i + 1)),
    };
    let Some(pattern) = e.glob else {
        return failed(format!("[[each]] table {}: no `glob`", i + 1));
    };
    let files = match matches(&pattern, dir) {
        Ok(f) if f.is_empty() => {
            return failed(format!(
                "[[each]] table {}: glob \"{pattern}\" matches no file",
                i + 1
            ));
        }
        Ok(f) => f,
        Err(msg) => {
            return failed(format!(
                "[[each]] table {}: glob \"{pattern}\": {msg}",
                i + 1
            ));
        }
    };
    let template = e.name.unwrap_or_else(|| "{stem}".into());
    files
        .iter()
        .map(|f| {
            let args = e.args.iter().map(|a| substitute(a, f)).collect();
            Job::new(substitute(&template, f), args, None)
        })
        .collect()
}

/// The files (not folders) matching `pattern`, relative to `dir` when the pattern is, sorted.
fn matches(pattern: &str, dir: &Path) -> std::result::Result<Vec<PathBuf>, String> {
    glob::Pattern::new(pattern).map_err(|e| e.to_string())?;
    let relative = Path::new(pattern).is_relative();
    let full = if relative {
        let base = glob::Pattern::escape(&dir.to_string_lossy());
        format!("{base}/{pattern}")
    } else {
        pattern.to_string()
    };
    let mut files = Vec::new();
    for entry in glob::glob(&full).map_err(|e| e.to_string())? {
        let p = entry.map_err(|e| e.to_string())?;
        if !p.is_file() {
            continue;
        }
        let p = if relative {
            p.strip_prefix(dir).map(Path::to_path_buf).unwrap_or(p)
        } else {
            p
        };
        files.push(p);
    }
    files.sort();
    Ok(files)
}

/// `{path}`, `{name}` (file name) and `{stem}` (file name without extension) of `file` in `s`.
fn substitute(s: &str, file: &Path) -> String {
    let text = |o: Option<&std::ffi::OsStr>| o.map(|x| x.to_string_lossy().into_owned());
    s.replace("{path}", &file.to_string_lossy())
        .replace("{name}", &text(file.file_name()).unwrap_or_default())
        .replace("{stem}", &text(file.file_stem()).unwrap_or_default())
}
