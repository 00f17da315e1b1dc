//! The batch as an Open Job Description job template (specification `jobtemplate-2023-09`): one
//! step whose tasks are the jobs, an INT task parameter `Job` (the job's index) selecting each,
//! every task running `meshmatch batch JOBFILE --only <Job> --log-dir LOGDIR`. The job file, the
//! meshmatch executable and the log folder are job parameters of type PATH, so a farm's path
//! mapping rewrites them for each worker.

use std::path::Path;

use serde_json::json;

use super::jobfile::Job;
use super::summary::write_now;
use crate::error::{Error, Result};

/// File names written into the `--emit-openjd` folder.
pub const TEMPLATE: &str = "template.json";
pub const PARAMS: &str = "params.json";

/// Write `template.json` and `params.json` (the job parameter values, for
/// `openjd run template.json -p file://params.json`) into `out` for the jobs without an error.
/// Paths must be absolute. Returns how many tasks the step has.
pub fn emit(
    out: &Path,
    job_file: &Path,
    exe: &Path,
    log_dir: &Path,
    jobs: &[Job],
) -> Result<usize> {
    let indices: Vec<usize> = jobs
        .iter()
        .filter(|j| j.error.is_none())
        .map(|j| j.index)
        .collect();
    if indices.is_empty() {
        return Err(Error::InvalidInput(format!(
            "{}: no job can run, so there is no task to write",
            job_file.display()
        )));
    }
    let stem = job_file
        .file_stem()
        .map_or_else(|| "jobs".into(), |s| s.to_string_lossy().into_owned());
    let template = template(&stem, &range(&indices));
    let params = json!({
        "JobFile": job_file.display().to_string(),
        "Meshmatch": exe.display().to_string(),
        "LogDir": log_dir.display().to_string(),
    });
    for name in [TEMPLATE, PARAMS] {
        if crate::cli::common::same_location(&out.join(name), job_file) {
            return Err(Error::InvalidInput(format!(
                "--emit-openjd {}: its {name} would be written over the job file {}; emit \
                 into another folder",
                out.display(),
                job_file.display()
            )));
        }
    }
    std::fs::create_dir_all(out).map_err(|e| Error::io(out, e))?;
    for (name, v) in [(TEMPLATE, template), (PARAMS, params)] {
        let text = serde_json::to_string_pretty(&v).unwrap_or_default() + "\n";
        write_now(&out.join(name), text.as_bytes())?;
    }
    Ok(indices.len())
}

/// The job template.
fn template(stem: &str, range: &str) -> serde_json::Value {
    // A job name is at most 128 characters.
    let name: String = format!("meshmatch batch {stem}")
        .chars()
        .take(128)
        .collect();
    json!({
        "specificationVersion": "jobtemplate-2023-09",
        "name": name,
        "description": "meshmatch batch: one task per job of the job file, run by `meshmatch batch JOBFILE --only INDEX` in the job file's folder.",
        "parameterDefinitions": [
            {
                "name": "JobFile",
                "type": "PATH",
                "objectType": "FILE",
                "description": "The batch job file (TOML or JSON); its jobs run in its folder."
            },
            {
                "name": "Meshmatch",
                "type": "PATH",
                "objectType": "FILE",
                "description": "The meshmatch executable on the worker."
            },
            {
                "name": "LogDir",
                "type": "PATH",
                "objectType": "DIRECTORY",
                "description": "Where each job's log, its record and the batch summary go."
            }
        ],
        "steps": [{
            "name": "Jobs",
            "parameterSpace": {
                "taskParameterDefinitions": [
                    {"name": "Job", "type": "INT", "range": range}
                ]
            },
            "script": {
                "actions": {
                    "onRun": {
                        "command": "{{Param.Meshmatch}}",
                        "args": [
                            "batch", "{{Param.JobFile}}",
                            "--only", "{{Task.Param.Job}}",
                            "--log-dir", "{{Param.LogDir}}"
                        ]
                    }
                }
            }
        }]
    })
}

/// An OpenJD range expression of sorted indices: `0-3,5,7-9`.
fn range(indices: &[usize]) -> String {
    let mut parts = Vec::new();
    let mut k = 0;
    while k < indices.len() {
        let first = indices[k];
        let mut last = first;
        while k + 1 < indices.len() && indices[k + 1] == last + 1 {
            k += 1;
            last = indices[k];
        }
        parts.push(if first == last {
            first.to_string()
        } else {
            format!("{first}-{last}")
        });
        k += 1;
    }
    parts.join(",")
}

#[cfg(test)]
mod tests {
    #[test]
    fn range_expressions() {
        assert_eq!(super::range(&[0]), "0");
        assert_eq!(super::range(&[0, 1, 2, 3, 5, 7, 8, 9]), "0-3,5,7-9");
    }
}
