//! `meshmatch batch`: a job file of real jobs run as child processes, the summary, resume and
//! `--force`, `[[each]]` expansion, broken jobs reported one line each while the others run,
//! cancel, and the OpenJD template checked and run by the `openjd` CLI (when it is installed).

use meshmatch::testdata::data_path;
use std::path::Path;
use std::process::{Command, Output};

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_meshmatch"))
}

/// A temporary folder removed when the test ends, with the bunny copied in as `bunny.obj`.
fn workdir() -> tempfile::TempDir {
    let d = tempfile::Builder::new()
        .prefix("meshmatch-batch-")
        .tempdir()
        .unwrap();
    std::fs::copy(data_path("bunny/bunny.obj"), d.path().join("bunny.obj")).unwrap();
    d
}

fn batch(job_file: &Path, extra: &[&str]) -> Output {
    bin()
        .arg("batch")
        .arg(job_file)
        .args(extra)
        .output()
        .unwrap()
}

fn summary(dir: &Path, stem: &str) -> serde_json::Value {
    let p = dir.join(format!("{stem}-batch/batch-summary.json"));
    serde_json::from_str(&std::fs::read_to_string(&p).unwrap()).unwrap()
}

fn statuses(s: &serde_json::Value) -> Vec<String> {
    s["jobs"]
        .as_array()
        .unwrap()
        .iter()
        .map(|j| j["status"].as_str().unwrap().to_string())
        .collect()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Three real jobs (two conversions and a small transfer) and one that fails when it runs.
fn three_jobs_and_a_failure(dir: &Path) -> std::path::PathBuf {
    let spot = data_path("spot/spot.obj");
    let text = format!(
        r#"
[[job]]
name = "spot-ply"
args = ["convert", "{spot}", "out/spot.ply"]

[[job]]
name = "bunny-glb"
args = ["convert", "bunny.obj", "out/bunny.glb"]

[[job]]
name = "spot-to-bunny"
args = ["transfer", "--source", "{spot}", "--target", "bunny.obj", "--out", "out/bunny_spot.ply",
        "--vertices", "2000", "--iterations", "1"]

[[job]]
name = "wrong-extension"
args = ["convert", "bunny.obj", "out/bunny.txt"]
"#,
        spot = spot.display()
    );
    let path = dir.join("jobs.toml");
    std::fs::write(&path, text).unwrap();
    path
}

#[test]
fn batch_runs_records_resumes_and_forces() {
    let tmp = workdir();
    let dir = tmp.path();
    let jobs = three_jobs_and_a_failure(dir);

    let first = batch(&jobs, &["--jobs", "2"]);
    assert_eq!(first.status.code(), Some(1), "{}", stderr(&first));
    let s = summary(dir, "jobs");
    assert_eq!(statuses(&s), ["ok", "ok", "ok", "failed"], "{s:#}");
    assert_eq!(s["counts"]["ok"], 3);
    assert_eq!(s["counts"]["failed"], 1);
    for out in ["out/spot.ply", "out/bunny.glb", "out/bunny_spot.ply"] {
        assert!(dir.join(out).is_file(), "{out} missing");
    }
    assert!(!dir.join("out/bunny.txt").exists());
    let failed = &s["jobs"][3];
    let error = failed["error"].as_str().unwrap();
    assert!(error.contains("must end in"), "{error}");
    assert_eq!(failed["outputs"][0], "out/bunny.txt");
    assert_eq!(s["jobs"][2]["outputs"][0], "out/bunny_spot.ply");
    assert!(s["jobs"][2]["seconds"].as_f64().unwrap() > 0.0);
    // Every job's log beside the summary, and the table.
    let logs = dir.join("jobs-batch");
    // the transfer's log shows its progress as plain lines, its stage times and what it wrote
    let transfer_log = std::fs::read_to_string(logs.join("2-spot-to-bunny.log")).unwrap();
    assert!(transfer_log.contains("% solve"), "{transfer_log}");
    assert!(transfer_log.contains("wrote "), "{transfer_log}");
    let log = std::fs::read_to_string(logs.join("3-wrong-extension.log")).unwrap();
    assert!(log.contains("must end in"), "{log}");
    let table = std::fs::read_to_string(logs.join("batch-summary.txt")).unwrap();
    assert_eq!(table.lines().count(), 5, "{table}");
    assert!(table.lines().nth(4).unwrap().contains("failed"), "{table}");
    let err = stderr(&first);
    assert!(err.contains("job 3 (wrong-extension)"), "{err}");

    // A rerun skips the three finished jobs; the failed one runs (and fails) again.
    let again = batch(&jobs, &[]);
    assert_eq!(again.status.code(), Some(1), "{}", stderr(&again));
    let s = summary(dir, "jobs");
    assert_eq!(
        statuses(&s),
        ["skipped", "skipped", "skipped", "failed"],
        "{s:#}"
    );

    // A changed input reruns the jobs that read it, and only them.
    let mut bunny = std::fs::read_to_string(dir.join("bunny.obj")).unwrap();
    bunny.push_str("\n# edited\n");
    std::fs::write(dir.join("bunny.obj"), bunny).unwrap();
    let edited = batch(&jobs, &["--only", "0,1"]);
    assert_eq!(edited.status.code(), Some(0), "{}", stderr(&edited));
    let s = summary(dir, "jobs");
    assert_eq!(
        statuses(&s),
        ["skipped", "ok", "skipped", "failed"],
        "{s:#}"
    );

    // --force reruns everything.
    let forced = batch(&jobs, &["--force"]);
    assert_eq!(forced.status.code(), Some(1), "{}", stderr(&forced));
    let s = summary(dir, "jobs");
    assert_eq!(statuses(&s), ["ok", "ok", "ok", "failed"], "{s:#}");
}

#[test]
fn each_expands_one_job_per_matching_file() {
    let tmp = workdir();
    let dir = tmp.path();
    std::fs::create_dir_all(dir.join("meshes")).unwrap();
    for name in ["a.obj", "b.obj"] {
        std::fs::copy(dir.join("bunny.obj"), dir.join("meshes").join(name)).unwrap();
    }
    std::fs::write(dir.join("meshes/notes.txt"), "not a mesh").unwrap();
    // JSON this time, with the log folder given.
    let jobs = dir.join("lib.json");
    let text = r#"{"each": [{"glob": "meshes/*.obj", "name": "ply-{stem}",
        "args": ["convert", "{path}", "out/{stem}.ply"]}]}"#;
    std::fs::write(&jobs, text).unwrap();
    let logs = dir.join("logs");
    let o = batch(&jobs, &["--log-dir", logs.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(logs.join("batch-summary.json")).unwrap())
            .unwrap();
    let names: Vec<&str> = s["jobs"]
        .as_array()
        .unwrap()
        .iter()
        .map(|j| j["name"].as_str().unwrap())
        .collect();
    assert_eq!(names, ["ply-a", "ply-b"]);
    assert_eq!(s["jobs"][1]["args"][1], "meshes/b.obj");
    assert!(dir.join("out/a.ply").is_file() && dir.join("out/b.ply").is_file());
}

#[test]
fn broken_jobs_get_one_line_each_and_the_others_run() {
    let tmp = workdir();
    let dir = tmp.path();
    let jobs = dir.join("broken.toml");
    let text = r#"
[[job]]
name = "good"
args = ["convert", "bunny.obj", "out/good.ply"]

[[job]]
name = "unknown-command"
args = ["frobnicate", "bunny.obj"]

[[job]]
name = "missing-input"
args = ["convert", "missing.obj", "out/x.ply"]

[[job]]
args = "convert bunny.obj out/y.ply"

[[job]]
name = "recursive"
args = ["batch", "broken.toml"]

[[each]]
name = "bad-glob"
glob = "meshes/[*.obj"
args = ["convert", "{path}", "out/{stem}.ply"]

[[each]]
glob = "nothing/*.obj"
args = ["convert", "{path}", "out/{stem}.ply"]
"#;
    std::fs::write(&jobs, text).unwrap();
    let o = batch(&jobs, &[]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(dir.join("out/good.ply").is_file());
    let s = summary(dir, "broken");
    assert_eq!(
        statuses(&s),
        [
            "ok", "failed", "failed", "failed", "failed", "failed", "failed"
        ],
        "{s:#}"
    );
    let errors: Vec<&str> = s["jobs"]
        .as_array()
        .unwrap()
        .iter()
        .map(|j| j["error"].as_str().unwrap_or(""))
        .collect();
    for (k, want) in [
        (1, "frobnicate"),
        (2, "missing.obj: no such file"),
        (3, "`args` must be a list of strings"),
        (4, "cannot run `batch`"),
        (5, "glob \"meshes/[*.obj\""),
        (6, "matches no file"),
    ] {
        assert!(errors[k].contains(want), "job {k}: {}", errors[k]);
        assert!(!errors[k].contains('\n'), "job {k}: {}", errors[k]);
    }
    // One line on stderr per broken job, naming it.
    let err = stderr(&o);
    for label in [
        "job 1 (unknown-command)",
        "job 2 (missing-input)",
        "job 3 (job-3)",
        "job 4 (recursive)",
        "job 5 (bad-glob)",
        "job 6 (each-2)",
    ] {
        assert_eq!(
            err.lines().filter(|l| l.contains(label)).count(),
            1,
            "{label}: {err}"
        );
    }

    // A file that does not parse at all is one line and no run.
    let bad = dir.join("bad.toml");
    std::fs::write(&bad, "[[job]]\nargs = [\"info\", \n").unwrap();
    let o = batch(&bad, &[]);
    assert_eq!(o.status.code(), Some(2));
    let err = stderr(&o);
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(err.contains("bad.toml"), "{err}");
}

#[cfg(target_os = "linux")]
#[test]
fn ctrl_c_kills_running_jobs_and_leaves_no_partial_output() {
    let tmp = workdir();
    let dir = tmp.path();
    let jobs = dir.join("long.toml");
    let spot = data_path("spot/spot.obj");
    let text = format!(
        r#"
[[job]]
name = "long"
args = ["transfer", "--source", "{spot}", "--target", "bunny.obj", "--out", "out/long.ply",
        "--vertices", "400000"]

[[job]]
name = "next"
args = ["convert", "bunny.obj", "out/next.ply"]
"#,
        spot = spot.display()
    );
    std::fs::write(&jobs, text).unwrap();
    let child = bin()
        .arg("batch")
        .arg(&jobs)
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    std::thread::sleep(std::time::Duration::from_millis(1500));
    // SAFETY: kill(2) on the child's pid, which has not been waited for yet.
    unsafe { libc::kill(child.id() as i32, libc::SIGINT) };
    let start = std::time::Instant::now();
    let o = child.wait_with_output().unwrap();
    assert!(start.elapsed().as_secs_f64() < 5.0, "cancel took too long");
    assert_eq!(o.status.code(), Some(130), "{}", stderr(&o));
    let s = summary(dir, "long");
    assert_eq!(statuses(&s), ["cancelled", "cancelled"], "{s:#}");
    let left: Vec<_> = std::fs::read_dir(dir.join("out"))
        .map(|d| d.flatten().map(|e| e.file_name()).collect())
        .unwrap_or_default();
    assert!(left.is_empty(), "left behind: {left:?}");
}

fn openjd() -> Option<std::path::PathBuf> {
    let path = std::env::var_os("PATH")?;
    std::env::split_paths(&path)
        .map(|d| d.join("openjd"))
        .find(|p| p.is_file())
}

#[test]
fn openjd_template_passes_check_and_runs_a_task() {
    let Some(openjd) = openjd() else {
        println!("skipped: no `openjd` executable on PATH (pip install openjd-cli)");
        return;
    };
    let tmp = workdir();
    let dir = tmp.path();
    let jobs = dir.join("farm.toml");
    let text = r#"
[[job]]
name = "first"
args = ["convert", "bunny.obj", "out/first.ply"]

[[job]]
name = "second"
args = ["convert", "bunny.obj", "out/second.glb"]
"#;
    std::fs::write(&jobs, text).unwrap();
    let ojd = dir.join("openjd");
    let o = batch(&jobs, &["--emit-openjd", ojd.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let template = ojd.join("template.json");
    let t: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&template).unwrap()).unwrap();
    assert_eq!(t["specificationVersion"], "jobtemplate-2023-09");
    assert_eq!(
        t["steps"][0]["parameterSpace"]["taskParameterDefinitions"][0]["range"],
        "0-1"
    );

    let check = Command::new(&openjd)
        .arg("check")
        .arg(&template)
        .output()
        .unwrap();
    assert!(check.status.success(), "openjd check: {}", stderr(&check));
    let params = format!("file://{}", ojd.join("params.json").display());
    let run = Command::new(&openjd)
        .arg("run")
        .arg(&template)
        .args([
            "--job-param",
            &params,
            "--step",
            "Jobs",
            "--task-param",
            "Job=1",
        ])
        .output()
        .unwrap();
    assert!(
        run.status.success(),
        "openjd run: {}{}",
        String::from_utf8_lossy(&run.stdout),
        stderr(&run)
    );
    assert!(dir.join("out/second.glb").is_file());
    assert!(!dir.join("out/first.ply").exists());
    let s = summary(dir, "farm");
    assert_eq!(statuses(&s), ["not_run", "ok"], "{s:#}");
}

#[test]
fn nothing_writes_over_the_job_file_itself() {
    let d = workdir();
    // a job whose output is its own job file (a map's CSV may have any extension)
    let own = d.path().join("self.toml");
    let text = r#"
[[job]]
name = "over-itself"
args = ["map", "--source", "bunny.obj", "--target", "bunny.obj", "--out", "self.toml"]

[[job]]
name = "fine"
args = ["convert", "bunny.obj", "out/bunny.ply"]
"#;
    std::fs::write(&own, text).unwrap();
    let o = batch(&own, &[]);
    assert!(!o.status.success(), "{}", stderr(&o));
    assert_eq!(std::fs::read_to_string(&own).unwrap(), text);
    let s = summary(d.path(), "self");
    assert_eq!(statuses(&s), ["failed", "ok"]);
    let err = s["jobs"][0]["error"].as_str().unwrap();
    assert!(err.contains("job file itself"), "{err}");

    // an OpenJD template emitted next to a job file named like one of its files
    let params = d.path().join("params.json");
    let json = r#"{"job": [{"name": "c", "args": ["convert", "bunny.obj", "out/b.ply"]}]}"#;
    std::fs::write(&params, json).unwrap();
    let o = batch(&params, &["--emit-openjd", d.path().to_str().unwrap()]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("over the job file"), "{}", stderr(&o));
    assert_eq!(std::fs::read_to_string(&params).unwrap(), json);
    assert!(!d.path().join("template.json").exists());
}
