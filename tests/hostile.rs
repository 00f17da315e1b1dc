//! Hostile inputs to every subcommand (issue 20): each row of the campaign as a small, fast
//! regression test on tiny generated files, plus a property-style sweep of the numeric flags.
//! Every case must end in exit 0 or 2 with a one-line error, within a time bound, and must not
//! damage a file.

mod scratch;
use scratch::Scratch;

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

fn tmpdir(name: &str) -> Scratch {
    Scratch::new(&format!("hostile-{name}"))
}

/// Exit code and stderr of `meshmatch args`, killed (and the test failed) after `limit`.
fn run_in(dir: &Path, args: &[&str], limit: Duration) -> (i32, String) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_meshmatch"))
        .args(args)
        .current_dir(dir)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut err = child.stderr.take().unwrap();
    let reader = std::thread::spawn(move || {
        let mut s = String::new();
        let _ = std::io::Read::read_to_string(&mut err, &mut s);
        s
    });
    let t = Instant::now();
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        if t.elapsed() > limit {
            let _ = child.kill();
            let _ = child.wait();
            panic!("meshmatch {args:?} ran past {limit:?}");
        }
        std::thread::sleep(Duration::from_millis(10));
    };
    let stderr = reader.join().unwrap();
    // A signal (abort) has no code: report it as -1.
    (status.code().unwrap_or(-1), stderr)
}

/// Numeric values every sweep sends through each flag.
const HOSTILE_VALUES: [&str; 9] = [
    "0",
    "-1",
    "NaN",
    "inf",
    "-inf",
    "1e39",
    "1e-30",
    "1000000000000",
    "18446744073709551615",
];

/// `meshmatch <args>` (split on spaces by the shell) in `dir` under an address-space limit of
/// `limit_kb` KB (`ulimit -v`).
fn run_under_memory_limit(dir: &Path, limit_kb: u32, args: &str) -> std::process::Output {
    Command::new("sh")
        .arg("-c")
        .arg(format!(
            "ulimit -v {limit_kb} && exec '{}' {args}",
            env!("CARGO_BIN_EXE_meshmatch")
        ))
        .current_dir(dir)
        .output()
        .unwrap()
}

/// A `size²` two-colour-ramp exemplar, `ex.png` in `dir`.
fn exemplar_png(dir: &Path, size: u32) {
    let mut img = image::RgbImage::new(size, size);
    for (x, y, p) in img.enumerate_pixels_mut() {
        *p = image::Rgb([(x * 255 / size) as u8, (y * 255 / size) as u8, 90]);
    }
    img.save(dir.join("ex.png")).unwrap();
}

fn run(dir: &Path, args: &[&str]) -> (i32, String) {
    run_in(dir, args, Duration::from_secs(20))
}

/// The command is refused with exit 2 and one line on stderr that mentions `mention`.
fn refused(dir: &Path, args: &[&str], mention: &str) {
    let (code, err) = run(dir, args);
    assert_eq!(code, 2, "exit code of {args:?}: {err}");
    assert_eq!(
        err.trim_end().lines().count(),
        1,
        "{args:?}: one line, got {err}"
    );
    assert!(
        err.contains(mention),
        "{args:?}: should mention '{mention}': {err}"
    );
    assert!(
        !err.contains("internal error") && !err.contains("panicked"),
        "{args:?}: {err}"
    );
}

/// A coloured grid of `n` x `n` vertices as ASCII PLY, positions through `pos`.
fn grid_ply(path: &Path, n: usize, colors: bool, pos: impl Fn(usize, usize) -> String) {
    let mut s = format!(
        "ply\nformat ascii 1.0\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\n",
        n * n
    );
    if colors {
        s.push_str("property uchar red\nproperty uchar green\nproperty uchar blue\n");
    }
    s.push_str(&format!(
        "element face {}\nproperty list uchar int vertex_indices\nend_header\n",
        2 * (n - 1) * (n - 1)
    ));
    for j in 0..n {
        for i in 0..n {
            s.push_str(&pos(i, j));
            if colors {
                let k = j * n + i;
                s.push_str(&format!(
                    " {} {} {}",
                    k * 37 % 256,
                    k * 91 % 256,
                    k * 13 % 256
                ));
            }
            s.push('\n');
        }
    }
    for j in 0..n - 1 {
        for i in 0..n - 1 {
            let a = j * n + i;
            s.push_str(&format!(
                "3 {} {} {}\n3 {} {} {}\n",
                a,
                a + 1,
                a + n + 1,
                a,
                a + n + 1,
                a + n
            ));
        }
    }
    std::fs::write(path, s).unwrap();
}

fn plain(i: usize, j: usize) -> String {
    format!(
        "{} {} {}",
        i as f32 / 9.0,
        j as f32 / 9.0,
        0.1 * ((i * j) % 3) as f32
    )
}

/// `src.ply` (coloured), `tgt.ply` and a few hostile variants in a fresh folder.
fn scene(name: &str) -> Scratch {
    let d = tmpdir(name);
    grid_ply(&d.join("src.ply"), 10, true, plain);
    grid_ply(&d.join("tgt.ply"), 10, false, plain);
    for (file, bad) in [
        ("nan.ply", "nan 0 0"),
        ("inf.ply", "inf 0 0"),
        ("big.ply", "1e39 0 0"),
    ] {
        grid_ply(&d.join(file), 10, true, |i, j| {
            if (i, j) == (4, 4) {
                bad.to_string()
            } else {
                plain(i, j)
            }
        });
    }
    grid_ply(&d.join("point.ply"), 10, false, |_, _| "0.5 0.5 0.5".into());
    grid_ply(&d.join("allnan.ply"), 10, false, |_, _| {
        "nan nan nan".into()
    });
    for (file, s) in [("micro.ply", 1e-6f64), ("tiny.ply", 1e-30)] {
        grid_ply(&d.join(file), 10, false, |i, j| {
            format!("{:e} {:e} 0", i as f64 * s, j as f64 * s)
        });
    }
    d
}

const FAST: &[&str] = &["--vertices", "300", "--iterations", "1", "--levels", "2"];

fn with<'a>(base: &[&'a str], extra: &[&'a str]) -> Vec<&'a str> {
    base.iter().chain(extra).copied().collect()
}

#[test]
fn huge_and_invalid_parameters_are_refused_before_work() {
    let d = scene("params");
    let t = [
        "transfer", "--source", "src.ply", "--target", "tgt.ply", "--out", "o.ply",
    ];
    let c = [
        "complete", "--mesh", "src.ply", "--mask", "mask.txt", "--out", "o.ply",
    ];
    let u = [
        "update", "--old", "src.ply", "--new", "tgt.ply", "--out", "o.ply",
    ];
    let de = [
        "detail", "--source", "src.ply", "--target", "tgt.ply", "--out", "o.ply",
    ];
    std::fs::write(d.join("mask.txt"), "1\n2\n").unwrap();
    for base in [&t[..], &c[..], &u[..], &de[..]] {
        refused(&d, &with(base, &["--vertices", "1000000000000"]), "4000000");
        refused(
            &d,
            &with(base, &["--vertices", "18446744073709551615"]),
            "4000000",
        );
        refused(&d, &with(base, &["--iterations", "1000000000"]), "1000");
        refused(&d, &with(base, &["--tolerance", "NaN"]), "--tolerance");
        refused(&d, &with(base, &["--tolerance=-0.1"]), "--tolerance");
        refused(&d, &with(base, &["--tolerance", "1"]), "--tolerance");
        refused(&d, &with(base, &["--levels", "0"]), "--levels");
        refused(
            &d,
            &with(base, &["--shape-weight", "NaN"]),
            "--shape-weight",
        );
        refused(&d, &with(base, &["--shape-weight=-1"]), "--shape-weight");
        refused(
            &d,
            &with(base, &["--shape-weight", "inf"]),
            "--shape-weight",
        );
    }
    refused(
        &d,
        &with(&t, &["--fine-shape-scale", "NaN"]),
        "--fine-shape-scale",
    );
    for bad in ["2", "-0.5", "NaN", "inf", "structure"] {
        refused(&d, &with(&t, &["--structure", bad]), "--structure");
    }
    for size in ["0", "65536", "100000"] {
        let args = with(&t[..5], &["--out", "o.glb", "--texture-size", size]);
        refused(&d, &args, "8192");
    }
    refused(&d, &["bench", "--sizes", "1000000000000"], "--sizes");
    refused(&d, &["bench", "--sizes", "0"], "--sizes");
    refused(
        &d,
        &[
            "features",
            "src.ply",
            "--out",
            "f.ply",
            "--rays",
            "1000000000",
        ],
        "--rays",
    );
    assert!(!d.join("o.ply").exists() && !d.join("o.glb").exists());
}

#[test]
fn degenerate_new_meshes_in_update_are_refused_or_run_bounded() {
    let d = scene("update");
    for (new, mention) in [
        ("point.ply", "zero area"),
        ("allnan.ply", "finite"),
        ("tiny.ply", "rescale"),
    ] {
        let args = with(
            &["update", "--old", "src.ply", "--new", new, "--out", "o.ply"],
            FAST,
        );
        refused(&d, &args, mention);
    }
    // A mesh scaled by 1e-6 is valid: the example's density is clamped, the run is short.
    let args = with(
        &[
            "update",
            "--old",
            "src.ply",
            "--new",
            "micro.ply",
            "--out",
            "o.ply",
        ],
        FAST,
    );
    let (code, err) = run(&d, &args);
    assert_eq!(code, 0, "{err}");
}

#[test]
fn non_finite_vertices_are_refused_by_every_command() {
    let d = scene("nonfinite");
    std::fs::write(d.join("mask.txt"), "1\n").unwrap();
    for bad in ["nan.ply", "inf.ply", "big.ply"] {
        let cases: [Vec<&str>; 4] = [
            vec![
                "transfer", "--source", "src.ply", "--target", bad, "--out", "o.ply",
            ],
            vec![
                "complete", "--mesh", bad, "--mask", "mask.txt", "--out", "o.ply",
            ],
            vec!["update", "--old", bad, "--new", "tgt.ply", "--out", "o.ply"],
            vec![
                "detail", "--source", "src.ply", "--target", bad, "--out", "o.ply",
            ],
        ];
        for args in cases {
            refused(&d, &with(&args, FAST), "not a finite number");
        }
    }
}

#[test]
fn sparse_ply_declaring_300m_vertices_is_refused_before_reading() {
    let d = tmpdir("sparse");
    let p = d.join("huge.ply");
    let mut f = std::fs::File::create(&p).unwrap();
    std::io::Write::write_all(
        &mut f,
        b"ply\nformat binary_little_endian 1.0\nelement vertex 300000000\nproperty float x\nproperty float y\nproperty float z\nelement face 0\nproperty list uchar int vertex_indices\nend_header\n",
    )
    .unwrap();
    f.set_len(3_600_000_200).unwrap(); // sparse: no disk used
    drop(f);
    let t = Instant::now();
    refused(&d, &["info", "huge.ply"], "budget");
    refused(&d, &["convert", "huge.ply", "out.obj"], "budget");
    assert!(t.elapsed() < Duration::from_secs(5), "{:?}", t.elapsed());
    std::fs::remove_file(&p).unwrap();
}

#[test]
fn correspondences_files_are_capped() {
    let d = scene("corr");
    let t = [
        "transfer", "--source", "src.ply", "--target", "tgt.ply", "--out", "o.ply",
    ];
    #[cfg(unix)]
    refused(
        &d,
        &with(&t, &["--correspondences", "/dev/zero"]),
        "not a regular file",
    );
    refused(&d, &with(&t, &["--correspondences", "."]), "directory");
    let pairs = |n: usize, targets: usize| {
        let v: Vec<String> = (0..n)
            .map(|i| {
                let ts: Vec<String> = (0..targets).map(|k| ((i + k) % 100).to_string()).collect();
                format!(
                    "{{\"source_vertex\": {}, \"target_vertices\": [{}]}}",
                    i % 100,
                    ts.join(",")
                )
            })
            .collect();
        format!("{{\"correspondences\": [{}]}}", v.join(","))
    };
    std::fs::write(d.join("many.json"), pairs(10_000, 40)).unwrap();
    std::fs::write(d.join("pairs.json"), pairs(300, 1)).unwrap();
    std::fs::write(d.join("targets.json"), pairs(100, 20)).unwrap();
    refused(
        &d,
        &with(&t, &["--correspondences", "many.json"]),
        "at most 256",
    );
    refused(
        &d,
        &with(&t, &["--correspondences", "pairs.json"]),
        "at most 256",
    );
    refused(
        &d,
        &with(&t, &["--correspondences", "targets.json"]),
        "at most 1024",
    );
    refused(
        &d,
        &[
            "complete",
            "--mesh",
            "src.ply",
            "--mask",
            "/dev/zero",
            "--out",
            "o.ply",
        ],
        "not a regular file",
    );
}

#[test]
fn huge_polygons_and_duplicate_faces_do_not_run_away() {
    let d = scene("polygons");
    // One face of 20,000 corners: its fan makes vertex 1 a corner of 19,998 triangles.
    let n = 20_000;
    let mut s = String::new();
    for i in 0..n {
        let a = std::f32::consts::TAU * i as f32 / n as f32;
        s.push_str(&format!("v {} {} 0\n", a.cos(), a.sin()));
    }
    s.push('f');
    for i in 1..=n {
        s.push_str(&format!(" {i}"));
    }
    s.push('\n');
    std::fs::write(d.join("poly.obj"), s).unwrap();
    let t = ["transfer", "--source", "src.ply", "--out", "o.ply"];
    refused(
        &d,
        &with(&with(&t, &["--target", "poly.obj"]), FAST),
        "triangulated",
    );
    // A PLY of 20,000 faces of 255 corners each (5.1M corners) over rings of a cylinder:
    // refused or run within the bound, never a runaway.
    let (rings, per) = (200usize, 255usize);
    let mut s = format!(
        "ply\nformat ascii 1.0\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\nelement face 20000\nproperty list uchar int vertex_indices\nend_header\n",
        rings * per
    );
    for r in 0..rings {
        for i in 0..per {
            let a = std::f32::consts::TAU * i as f32 / per as f32;
            s.push_str(&format!("{} {} {}\n", a.cos(), a.sin(), r as f32 * 0.01));
        }
    }
    for f in 0..20_000usize {
        let (r, k) = (f % rings, f / rings);
        s.push_str("255");
        for i in 0..per {
            s.push_str(&format!(" {}", r * per + (i + k) % per));
        }
        s.push('\n');
    }
    std::fs::write(d.join("gons.ply"), s).unwrap();
    let t0 = Instant::now();
    let (code, err) = run(&d, &with(&with(&t, &["--target", "gons.ply"]), FAST));
    assert!(code == 0 || code == 2, "exit {code}: {err}");
    assert!(
        !err.contains("panicked") && !err.contains("internal error"),
        "{err}"
    );
    if code == 2 {
        // warnings about the file may come first; the error itself is one line
        let errors = err.lines().filter(|l| !l.starts_with("warning")).count();
        assert_eq!(errors, 1, "{err}");
    }
    eprintln!(
        "20,000 255-gons: exit {code} in {:.1} s: {}",
        t0.elapsed().as_secs_f64(),
        err.lines().last().unwrap_or("")
    );
    // 200,000 copies of two faces: dropped with a warning, the transfer is quick.
    let mut s = String::from("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0.5\n");
    s.push_str(&"f 1 2 3\nf 2 4 3\n".repeat(100_000));
    std::fs::write(d.join("dups.obj"), s).unwrap();
    let (code, err) = run(&d, &with(&with(&t, &["--target", "dups.obj"]), FAST));
    assert_eq!(code, 0, "{err}");
    assert!(err.contains("duplicate faces"), "{err}");
}

#[test]
fn outputs_are_checked_before_any_work_and_inputs_never_overwritten() {
    let d = scene("outputs");
    std::fs::write(d.join("keep.ply"), b"old").unwrap();
    std::fs::create_dir_all(d.join("folder")).unwrap();
    let t = ["transfer", "--source", "src.ply", "--target", "tgt.ply"];
    for flag in ["--nnf-out", "--out-dense"] {
        let args = with(&with(&t, &["--out", "keep.ply", flag, "folder"]), FAST);
        refused(&d, &args, "directory");
        assert_eq!(std::fs::read(d.join("keep.ply")).unwrap(), b"old");
    }
    refused(
        &d,
        &with(&with(&t, &["--out", "x.ply", "--nnf-out", "x.ply"]), FAST),
        "same file",
    );
    refused(&d, &with(&with(&t, &["--out", "./tgt.ply"]), FAST), "input");
    refused(
        &d,
        &with(&with(&t, &["--out", "x.txt"]), FAST),
        ".ply, .glb, .gltf or .obj",
    );
    refused(&d, &["convert", "src.ply", "src.ply"], "input");
    let src = std::fs::read(d.join("src.ply")).unwrap();
    let tgt = std::fs::read(d.join("tgt.ply")).unwrap();
    assert_eq!(std::fs::read(d.join("src.ply")).unwrap(), src);
    assert_eq!(std::fs::read(d.join("tgt.ply")).unwrap(), tgt);
}

#[test]
fn convert_beside_its_source_keeps_the_source_texture() {
    let d = tmpdir("sidecar");
    let img = image::RgbImage::from_fn(4, 4, |x, y| image::Rgb([x as u8 * 60, y as u8 * 60, 7]));
    img.save(d.join("m_texture.png")).unwrap();
    std::fs::write(d.join("m.mtl"), "newmtl a\nmap_Kd m_texture.png\n").unwrap();
    std::fs::write(
        d.join("m.obj"),
        "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nusemtl a\nf 1/1 2/2 3/3\n",
    )
    .unwrap();
    let before = std::fs::read(d.join("m_texture.png")).unwrap();
    let (code, err) = run(&d, &["convert", "m.obj", "m.ply"]);
    assert_eq!(code, 0, "{err}");
    assert_eq!(std::fs::read(d.join("m_texture.png")).unwrap(), before);
    assert!(d.join("m_ply_texture.png").exists());
    let ply = std::fs::read(d.join("m.ply")).unwrap();
    assert!(String::from_utf8_lossy(&ply).contains("TextureFile m_ply_texture.png"));
}

#[cfg(feature = "gui")]
#[test]
fn render_needs_a_png_output_and_finite_angles() {
    let d = scene("render");
    refused(&d, &["render", "src.ply", "--out", "tgt.ply"], ".png");
    refused(
        &d,
        &["render", "src.ply", "--out", "r.png", "--azimuth", "NaN"],
        "--azimuth",
    );
}

/// Property-style sweep: every numeric flag of `transfer` over a fixed list of hostile values
/// (zero, negatives, NaN, infinities, huge, tiny) ends in exit 0 or 2, a refusal is one line,
/// and nothing aborts, panics or runs past its bound.
#[test]
fn numeric_flags_accept_or_refuse_cleanly() {
    let d = scene("sweep");
    let values = HOSTILE_VALUES;
    let flags = [
        "--vertices",
        "--levels",
        "--iterations",
        "--seed",
        "--shape-weight",
        "--fine-shape-scale",
        "--texture-size",
        "--structure",
    ];
    for flag in flags {
        for v in values {
            let mut args = vec![
                "transfer", "--source", "src.ply", "--target", "tgt.ply", "--out", "o.ply",
            ];
            // The base settings keep an accepted run short; the flag under test replaces its own.
            for pair in FAST.chunks(2) {
                if pair[0] != flag {
                    args.extend_from_slice(pair);
                }
            }
            let kv = format!("{flag}={v}");
            args.push(&kv);
            let (code, err) = run_in(&d, &args, Duration::from_secs(15));
            assert!(code == 0 || code == 2, "{kv}: exit {code}: {err}");
            assert!(
                !err.contains("internal error") && !err.contains("panicked"),
                "{kv}: {err}"
            );
            if code == 2 {
                assert_eq!(err.trim_end().lines().count(), 1, "{kv}: {err}");
            }
        }
    }
}

/// The library's front doors refuse what the CLI refuses: bad parameters and a NaN vertex are
/// errors, not panics.
#[test]
fn library_front_doors_refuse_hostile_parameters_and_vertices() {
    use meshmatch::TriMesh;
    use meshmatch::meshmatch::{TransferParams, prepare};
    use meshmatch::work::CancelToken;
    let grid = |bad: bool| {
        let n = 6;
        let mut pos = Vec::new();
        for j in 0..n {
            for i in 0..n {
                pos.push([i as f32, j as f32, 0.0]);
            }
        }
        if bad {
            pos[7] = [f32::NAN, 0.0, 0.0];
        }
        let mut faces = Vec::new();
        for j in 0..n - 1 {
            for i in 0..n - 1 {
                let a = (j * n + i) as u32;
                let n = n as u32;
                faces.push([a, a + 1, a + n + 1]);
                faces.push([a, a + n + 1, a + n]);
            }
        }
        TriMesh::new(pos, faces)
    };
    let cancel = CancelToken::new();
    let ok = TransferParams {
        vertices: 200,
        ..TransferParams::default()
    };
    assert!(prepare(&grid(true), &ok, &|_| {}, &cancel).is_err());
    for p in [
        TransferParams {
            vertices: usize::MAX,
            ..ok.clone()
        },
        TransferParams {
            iterations: 1_000_000_000,
            ..ok.clone()
        },
        TransferParams {
            shape_weight: f32::NAN,
            ..ok.clone()
        },
        TransferParams {
            levels: Some(0),
            ..ok.clone()
        },
    ] {
        assert!(p.validate().is_err(), "{p:?}");
        assert!(prepare(&grid(false), &p, &|_| {}, &cancel).is_err());
    }
    assert!(prepare(&grid(false), &ok, &|_| {}, &cancel).is_ok());
}

#[test]
fn app_sessions_and_recent_lists_follow_the_regular_file_rule() {
    use meshmatch::app::AppState;
    use meshmatch::meshmatch::TransferParams;
    let d = tmpdir("session");
    let mut state: AppState<TransferParams> = AppState::new();
    let t0 = Instant::now();
    // a device that never ends and a directory: refused at once, nothing read
    for bad in [Path::new("/dev/zero"), d.as_path()] {
        let e = state.open_session(bad).expect_err("refused").to_string();
        assert!(
            e.contains("not a regular file") || e.contains("is a directory"),
            "{e}"
        );
    }
    assert!(t0.elapsed() < Duration::from_secs(5));
    // a Recent list that is a device is ignored, not read
    state.load_recent(PathBuf::from("/dev/zero"));
    assert!(state.recent.is_empty());
    assert!(state.meshes.iter().all(|m| m.is_none()));
}

#[test]
fn work_beyond_the_memory_limit_is_refused_before_work_by_every_system() {
    // Under an address-space limit the largest working sizes cannot fit: a one-line error
    // naming the memory, at once, not an abort halfway through.
    let d = scene("memory");
    exemplar_png(&d, 32);
    // (address-space limit in KB, command): the quilt's face cap keeps it under 2 GB.
    let cases: &[(u32, &str)] = &[
        (
            2_000_000,
            "transfer --source src.ply --target tgt.ply --out o.ply --vertices 4000000",
        ),
        (
            2_000_000,
            "weather --source src.ply --target tgt.ply --out o.ply --vertices 4000000",
        ),
        (
            2_000_000,
            "synth --target tgt.ply --exemplar ex.png --out o.ply --vertex-budget 2000000 \
             --exemplar-width 32 --scale 0.04",
        ),
        (
            2_000_000,
            "bake --from src.ply --to tgt.ply --out o.glb --texture-size 8192",
        ),
        (
            2_000_000,
            "transfer --source src.ply --target tgt.ply --out o.glb --texture-size 8192",
        ),
        (
            400_000,
            "quilt --swatch chain --base tgt.ply --out o.ply --swatch-size 0.07",
        ),
    ];
    for &(limit, args) in cases {
        let t0 = Instant::now();
        let out = run_under_memory_limit(&d, limit, args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args}: {err}");
        let last = err.trim_end().lines().last().unwrap_or("");
        assert!(last.contains("MiB of memory"), "{args}: {err}");
        assert!(
            err.lines()
                .all(|l| !l.contains("panicked") && !l.contains("allocation")),
            "{args}: {err}"
        );
        assert!(t0.elapsed() < Duration::from_secs(10), "{args}");
        assert!(
            !d.join("o.ply").exists() && !d.join("o.glb").exists(),
            "{args}"
        );
    }
}

/// Every other command's numeric flags with hostile values: exit 0 or a one-line error (2), never
/// a panic, an abort or a run past the bound.
#[test]
fn numeric_flags_of_every_system_accept_or_refuse_cleanly() {
    let d = scene("sweep_systems");
    exemplar_png(&d, 24);
    let values = HOSTILE_VALUES;
    let cases: &[(&[&str], &[&str])] = &[
        (
            &[
                "weather",
                "--source",
                "src.ply",
                "--target",
                "tgt.ply",
                "--out",
                "o.ply",
                "--vertices",
                "300",
                "--rays",
                "8",
                "--clusters",
                "4",
            ],
            &[
                "--vertices",
                "--rays",
                "--clusters",
                "--seed",
                "--texture-size",
            ],
        ),
        (
            &[
                "synth",
                "--target",
                "tgt.ply",
                "--exemplar",
                "ex.png",
                "--out",
                "o.glb",
                "--texel-budget",
                "2000",
                "--levels",
                "2",
                "--texture-size",
                "64",
            ],
            &[
                "--scale",
                "--texel-budget",
                "--levels",
                "--seed",
                "--texture-size",
            ],
        ),
        (
            &[
                "synth",
                "--target",
                "tgt.ply",
                "--exemplar",
                "ex.png",
                "--out",
                "o.ply",
                "--vertex-budget",
                "2000",
                "--levels",
                "2",
            ],
            &[
                "--scale",
                "--exemplar-width",
                "--vertex-budget",
                "--levels",
                "--seed",
                "--texture-size",
            ],
        ),
        (
            &[
                "quilt", "--swatch", "studs", "--base", "tgt.ply", "--out", "o.ply",
            ],
            &["--swatch-size", "--thickness", "--seed"],
        ),
        (
            &[
                "bake",
                "--from",
                "src.ply",
                "--to",
                "tgt.ply",
                "--out",
                "o.glb",
                "--texture-size",
                "64",
            ],
            &["--texture-size"],
        ),
        (
            &["curves", "tgt.ply", "--out", "c.obj"],
            &["--threshold", "--min-length", "--crease-angle"],
        ),
        (
            &["features", "tgt.ply", "--out", "f.ply", "--rays", "8"],
            &["--rays", "--seed"],
        ),
        (
            &[
                "detail",
                "--source",
                "src.ply",
                "--target",
                "tgt.ply",
                "--out",
                "o.ply",
                "--vertices",
                "300",
                "--iterations",
                "1",
                "--levels",
                "2",
            ],
            &["--strength"],
        ),
    ];
    let mut failures = Vec::new();
    for (base, flags) in cases {
        for flag in *flags {
            for v in values {
                // The base settings keep an accepted run short; the flag under test replaces its own.
                let mut args: Vec<&str> = Vec::new();
                let mut i = 0;
                while i < base.len() {
                    if base[i] == *flag {
                        i += 2;
                        continue;
                    }
                    args.push(base[i]);
                    i += 1;
                }
                let kv = format!("{flag}={v}");
                args.push(&kv);
                let (code, err) = run_in(&d, &args, Duration::from_secs(30));
                let clean = (code == 0 || code == 2)
                    && !err.contains("internal error")
                    && !err.contains("panicked")
                    && (code == 0 || err.trim_end().lines().count() == 1);
                if !clean {
                    failures.push(format!("{} {kv}: exit {code}: {err}", base[0]));
                }
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn a_ply_within_budget_but_beyond_the_memory_limit_is_an_error_not_an_abort() {
    // 19M vertices is within the loaders' 20M budget; under a 400 MB address-space limit their
    // arrays cannot be had: a one-line error, not "memory allocation failed" and an abort.
    let d = tmpdir("ply_memory");
    let header = "ply\nformat binary_little_endian 1.0\nelement vertex 19000000\n\
                  property float x\nproperty float y\nproperty float z\n\
                  property uchar red\nproperty uchar green\nproperty uchar blue\n\
                  element face 0\nproperty list uchar int vertex_indices\nend_header\n";
    let f = std::fs::File::create(d.join("big.ply")).unwrap();
    std::io::Write::write_all(&mut &f, header.as_bytes()).unwrap();
    f.set_len(300_000_000).unwrap(); // sparse: zeros on disk cost nothing
    let out = run_under_memory_limit(&d, 400_000, "info big.ply");
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert_eq!(err.trim_end().lines().count(), 1, "{err}");
    assert!(err.contains("not enough memory"), "{err}");
    let _ = std::fs::remove_file(d.join("big.ply"));
}

#[test]
fn hostile_exemplar_images_are_refused_in_one_line() {
    let d = scene("exemplars");
    std::fs::write(d.join("empty.png"), b"").unwrap();
    std::fs::write(d.join("text.png"), b"hello").unwrap();
    image::RgbImage::new(1, 1).save(d.join("one.png")).unwrap();
    image::RgbaImage::new(64, 64)
        .save(d.join("clear.png"))
        .unwrap(); // alpha 0 everywhere
    for (file, mention) in [
        ("empty.png", "cannot decode"),
        ("text.png", "cannot decode"),
        ("one.png", "too small"),
        ("clear.png", "transparent everywhere"),
        ("missing.png", "missing.png"),
    ] {
        refused(
            &d,
            &[
                "synth",
                "--target",
                "tgt.ply",
                "--exemplar",
                file,
                "--out",
                "o.ply",
            ],
            mention,
        );
    }
}

#[test]
fn word_flags_are_checked_before_work() {
    let d = scene("words");
    refused(
        &d,
        &[
            "features",
            "tgt.ply",
            "--out",
            "f.ply",
            "--feature",
            "bogus",
        ],
        "unknown feature",
    );
    refused(
        &d,
        &[
            "features",
            "tgt.ply",
            "--out",
            "f.ply",
            "--feature",
            "curvature:9",
        ],
        "unknown feature",
    );
    // The up axis is checked for the built-in swatches too, where it is not used.
    refused(
        &d,
        &[
            "quilt",
            "--swatch",
            "chain",
            "--base",
            "tgt.ply",
            "--out",
            "q.ply",
            "--swatch-up",
            "w",
        ],
        "--swatch-up",
    );
    assert!(!d.join("f.ply").exists() && !d.join("q.ply").exists());
}

#[test]
fn texture_optimisation_flags_are_checked_in_one_line() {
    let d = scene("optimise");
    exemplar_png(&d, 32);
    grid_ply(&d.join("flat.ply"), 10, false, |i, j| {
        format!("{} {} 0", i as f32 / 9.0, j as f32 / 9.0)
    });
    meshmatch::mesh::io::save(&meshmatch::demo::crest_block(6), &d.join("block.obj")).unwrap();
    meshmatch::demo::line_exemplar()
        .save(d.join("line.png"))
        .unwrap();
    image::RgbImage::from_pixel(32, 32, image::Rgb([128, 128, 128]))
        .save(d.join("plain.png"))
        .unwrap();
    let synth = |extra: &[&'static str], target: &'static str, ex: &'static str| {
        let mut a = vec![
            "synth",
            "--target",
            target,
            "--exemplar",
            ex,
            "--out",
            "o.ply",
        ];
        a.extend_from_slice(extra);
        a
    };
    for (extra, mention) in [
        (&["--method", "bogus"][..], "--method"),
        (
            &["--align-features", "--orientation", "random"][..],
            "--orientation features",
        ),
        (&["--feature-mask", "plain.png"][..], "--align-features"),
        (&["--method", "optimize", "--displace"][..], "--displace"),
    ] {
        refused(&d, &synth(extra, "block.obj", "line.png"), mention);
    }
    // an exemplar without any line, a target without any curve
    refused(
        &d,
        &synth(&["--align-features"], "block.obj", "plain.png"),
        "no line feature",
    );
    refused(
        &d,
        &synth(&["--align-features"], "flat.ply", "line.png"),
        "no salient curve",
    );
    assert!(!d.join("o.ply").exists());
}

/// Two outputs, or an output and an input, are compared by where they lead, not how they are
/// spelt: another spelling of the same folder (`..`, `.`, doubled slashes, a folder that does
/// not exist yet), a symbolic link on the way or a hard link is refused before any work, in one
/// line naming both options, and nothing is written or changed. So is an OBJ output's material
/// file taken by another output, and an output inside a file.
#[test]
fn outputs_are_compared_by_where_they_lead_whatever_the_spelling() {
    let d = scene("spelling");
    exemplar_png(&d, 16);
    std::fs::create_dir_all(d.join("kept")).unwrap();
    std::fs::write(d.join("kept/o.ply"), b"old").unwrap();
    std::os::unix::fs::symlink("fresh", d.join("link")).unwrap();
    std::fs::hard_link(d.join("tgt.ply"), d.join("hard.ply")).unwrap();
    std::fs::write(d.join("afile"), b"a file").unwrap();
    let transfer = ["transfer", "--source", "src.ply", "--target", "tgt.ply"];
    let synth = ["synth", "--exemplar", "ex.png", "--target", "tgt.ply"];
    let weather = ["weather", "--source", "src.ply", "--target", "tgt.ply"];
    for cmd in [&transfer[..], &synth[..], &weather[..]] {
        for (out, dense) in [
            ("fresh/o.ply", "fresh/../fresh/o.ply"),
            ("./fresh//o.ply", "fresh/o.ply"),
            ("fresh/o.ply", "link/o.ply"),
            ("kept/sub/../o.ply", "kept/o.ply"),
            ("kept/o.ply", "link/../kept/./o.ply"),
        ] {
            let args = with(cmd, &["--out", out, "--out-dense", dense]);
            let (code, err) = run(&d, &args);
            assert_eq!(code, 2, "{args:?}: {err}");
            assert_eq!(err.trim_end().lines().count(), 1, "{args:?}: {err}");
            assert!(
                err.contains(&format!("--out-dense {dense}"))
                    && err.contains(&format!("--out {out}")),
                "{args:?}: should name both options: {err}"
            );
            assert!(!d.join("fresh").exists(), "{args:?}: wrote before refusing");
            assert!(!d.join("kept/sub").exists(), "{args:?}: made a folder");
            assert_eq!(std::fs::read(d.join("kept/o.ply")).unwrap(), b"old");
        }
    }
    refused(
        &d,
        &with(
            &transfer,
            &["--out", "o.ply", "--nnf-out", "fresh/../tgt.ply"],
        ),
        "input",
    );
    refused(&d, &with(&transfer, &["--out", "hard.ply"]), "input");
    refused(
        &d,
        &with(&transfer, &["--out", "o.obj", "--nnf-out", "o.mtl"]),
        "--out o.obj",
    );
    refused(
        &d,
        &with(&transfer, &["--out", "o.OBJ", "--out-dense", "o.obj"]),
        "o.mtl",
    );
    for out in ["afile/o.ply", "afile/deeper/o.ply"] {
        refused(
            &d,
            &with(&transfer, &["--out", out]),
            &format!("--out {out}: afile is a file, not a folder"),
        );
    }
    refused(
        &d,
        &["demo", "--out", "afile/demo"],
        "afile is a file, not a folder",
    );
    assert_eq!(std::fs::read(d.join("afile")).unwrap(), b"a file");
    assert_eq!(
        std::fs::read(d.join("hard.ply")).unwrap(),
        std::fs::read(d.join("tgt.ply")).unwrap()
    );
}

/// Every numeric flag of every subcommand, found in clap's definition of the command line (so a
/// new flag is covered without being listed), given `-1` as its own word: the refusal must come
/// from the flag's range check and name the flag (never clap's "unexpected argument '-1'"), in
/// one line, before any file is read (the inputs here do not exist). Flags for which a negative
/// number is a valid value get as far as the missing input instead.
#[test]
fn minus_one_reaches_the_range_check_of_every_numeric_flag() {
    use clap::CommandFactory;
    use std::any::TypeId;
    let d = tmpdir("minus_one");
    // The required arguments of each subcommand (inputs that do not exist, fresh outputs).
    let bases: &[(&str, &[&str])] = &[
        ("info", &["in.ply"]),
        ("convert", &["in.ply", "o.ply"]),
        (
            "bake",
            &["--from", "in.ply", "--to", "in2.ply", "--out", "o.glb"],
        ),
        ("demo", &["--out", "demo"]),
        (
            "transfer",
            &[
                "--source", "in.ply", "--target", "in2.ply", "--out", "o.ply",
            ],
        ),
        (
            "map",
            &[
                "--source", "in.ply", "--target", "in2.ply", "--out", "o.csv",
            ],
        ),
        (
            "synth",
            &[
                "--exemplar",
                "in.png",
                "--target",
                "in.ply",
                "--out",
                "o.ply",
            ],
        ),
        ("complete", &["--mesh", "in.ply", "--out", "o.ply"]),
        (
            "update",
            &["--old", "in.ply", "--new", "in2.ply", "--out", "o.ply"],
        ),
        (
            "detail",
            &[
                "--source", "in.ply", "--target", "in2.ply", "--out", "o.ply",
            ],
        ),
        (
            "weather",
            &[
                "--source", "in.ply", "--target", "in2.ply", "--out", "o.ply",
            ],
        ),
        ("features", &["in.ply", "--out", "o.ply"]),
        (
            "quilt",
            &["--swatch", "studs", "--base", "in.ply", "--out", "o.ply"],
        ),
        ("swatch", &["--kind", "studs", "--out", "o.ply"]),
        ("curves", &["in.ply", "--out", "o.obj"]),
        ("bench", &["--sizes", "1"]),
        ("render", &["in.ply", "--out", "o.png"]),
        ("batch", &["jobs.toml"]),
    ];
    // Flags whose value is a number or a list of numbers though clap reads them as text or
    // through a parser of their own.
    let textual = ["structure", "sizes", "threads", "size"];
    // Flags for which -1 is a valid value.
    let negative_ok = ["strength", "azimuth", "elevation"];
    let numeric = [
        TypeId::of::<u8>(),
        TypeId::of::<u16>(),
        TypeId::of::<u32>(),
        TypeId::of::<u64>(),
        TypeId::of::<usize>(),
        TypeId::of::<i32>(),
        TypeId::of::<i64>(),
        TypeId::of::<f32>(),
        TypeId::of::<f64>(),
    ];
    let cli = meshmatch::cli::Cli::command();
    let mut failures = Vec::new();
    let mut checked = 0;
    for sub in cli.get_subcommands() {
        let name = sub.get_name();
        for arg in sub.get_arguments() {
            let Some(long) = arg.get_long() else { continue };
            let ty = arg.get_value_parser().type_id();
            if !numeric.iter().any(|t| ty == *t) && !textual.contains(&long) {
                continue;
            }
            let Some((_, base)) = bases.iter().find(|(n, _)| *n == name) else {
                failures.push(format!("{name}: no base arguments listed in this test"));
                continue;
            };
            // A flag of the base (bench --sizes) is replaced by the one under test.
            let flag = format!("--{long}");
            let mut args: Vec<&str> = vec![name];
            let mut i = 0;
            while i < base.len() {
                if base[i] == flag {
                    i += 2;
                    continue;
                }
                args.push(base[i]);
                i += 1;
            }
            args.extend([flag.as_str(), "-1"]);
            let (code, err) = run(&d, &args);
            checked += 1;
            let line = err.trim_end();
            let ok = if negative_ok.contains(&long) {
                code == 2 && line.contains("in.ply") && !line.contains("unexpected")
            } else {
                code == 2
                    && line.lines().count() == 1
                    && line.contains(&format!("{flag} -1"))
                    && !line.contains("unexpected")
            };
            if !ok {
                failures.push(format!("{}: exit {code}: {line}", args.join(" ")));
            }
        }
    }
    assert!(checked >= 21, "only {checked} numeric flags found");
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// `detail --vertices` has the lower bound of every MeshMatch command (the hierarchy's coarsest
/// level): 0 or 1 working vertices would collapse the target. The refusal names the option and
/// its range, before any work; the library's front door refuses it too.
#[test]
fn working_vertices_below_the_coarsest_level_are_refused_by_every_meshmatch_command() {
    let d = scene("min_vertices");
    let min = meshmatch::mesh::MIN_WORKING_VERTICES;
    let max = meshmatch::mesh::MAX_WORKING_VERTICES;
    let cmds: [&[&str]; 4] = [
        &[
            "detail", "--source", "src.ply", "--target", "tgt.ply", "--out", "o.ply",
        ],
        &[
            "transfer", "--source", "src.ply", "--target", "tgt.ply", "--out", "o.ply",
        ],
        &["complete", "--mesh", "src.ply", "--out", "o.ply"],
        &[
            "update", "--old", "src.ply", "--new", "tgt.ply", "--out", "o.ply",
        ],
    ];
    for cmd in cmds {
        for v in ["0", "1", "127"] {
            refused(
                &d,
                &with(cmd, &["--vertices", v]),
                &format!("--vertices {v}: use {min} to {max}"),
            );
        }
        assert!(!d.join("o.ply").exists());
    }
    let m = {
        let (p, f) = meshmatch::testdata::grid(12);
        meshmatch::TriMesh::new(p, f)
    };
    let p = meshmatch::meshmatch::TransferParams {
        vertices: 1,
        ..Default::default()
    };
    let e = meshmatch::applications::transfer_detail(
        &m,
        &m,
        1.0,
        &p,
        &|_| {},
        &meshmatch::work::CancelToken::new(),
    )
    .expect_err("refused")
    .to_string();
    assert!(e.contains("--vertices 1"), "{e}");
}

/// `bench --threads` beyond what memory allows is refused up front in one line, like a working
/// size beyond it, instead of aborting when the 200th worker thread's buffers cannot be had.
#[test]
fn thread_counts_beyond_the_memory_limit_are_refused_before_work() {
    let d = tmpdir("bench_threads");
    let t0 = Instant::now();
    let out = run_under_memory_limit(&d, 4_000_000, "bench --sizes 1k --threads 1,256");
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert_eq!(err.trim_end().lines().count(), 1, "{err}");
    assert!(
        err.contains("--threads 256") && err.contains("MiB of memory"),
        "{err}"
    );
    // refused before the first count's run: nothing on stdout
    assert!(
        out.stdout.is_empty(),
        "{}",
        String::from_utf8_lossy(&out.stdout)
    );
    assert!(t0.elapsed() < Duration::from_secs(10));
}
