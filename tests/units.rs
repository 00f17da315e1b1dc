//! Units: the same inputs in other units give the same output, up to the scale. Each case runs
//! the command line, as a user does, on a shared mesh written in those units and compares the
//! output with the unscaled run's: colours per vertex (sRGB, of 255) must be identical, positions
//! divided by the scale the same (of the bounding-box diagonal; exactly in powers of two).
//!
//! The scaled files are written as a person converting units would write them: every
//! coordinate multiplied in double precision and written with all its digits (OBJ). Each
//! command reads its meshes in a working unit, the first mesh's own diagonal, at the file's
//! precision (`cli::common::WorkingUnits`), so millimetres, metres and kilometres reach the
//! systems as the same numbers.

mod scratch;
use scratch::Scratch;

use meshmatch::mesh::TriMesh;
use meshmatch::mesh::io::{load, save};
use meshmatch::testdata::data_path;
use std::path::{Path, PathBuf};
use std::process::Command;

/// Powers of two (exact in floating point) and the metric ones.
const SCALES: [f64; 4] = [1024.0, 1.0 / 1024.0, 1e-3, 1e3];

fn exact(s: f64) -> bool {
    s.log2().fract() == 0.0
}

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_meshmatch"))
}

/// `rel` from the shared data, scaled by `s`, written as OBJ into `dir` with every coordinate
/// multiplied in double precision and written in full (the unscaled copy too, so that every run
/// reads the same format).
fn scaled(dir: &Path, rel: &str, s: f64) -> PathBuf {
    let m = load(&data_path(rel)).unwrap();
    let name = Path::new(rel).file_stem().unwrap().to_string_lossy();
    let path = dir.join(format!("{name}_x{s}.obj"));
    // the mesh with its UVs and texture as the project writes it, then its `v` lines (written
    // in vertex order) replaced by the scaled coordinates
    save(&m, &path).unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    let mut v = 0;
    let lines: Vec<String> = text
        .lines()
        .map(|l| {
            if !l.starts_with("v ") {
                return l.to_string();
            }
            let p = m.positions[v];
            v += 1;
            let rest: Vec<&str> = l.split_ascii_whitespace().skip(4).collect();
            let mut out = format!(
                "v {} {} {}",
                p[0] as f64 * s,
                p[1] as f64 * s,
                p[2] as f64 * s
            );
            for r in rest {
                out.push(' ');
                out.push_str(r);
            }
            out
        })
        .collect();
    assert_eq!(v, m.positions.len());
    std::fs::write(&path, lines.join("\n") + "\n").unwrap();
    path
}

/// Run `meshmatch args` and load its output `out`.
fn run<S: AsRef<std::ffi::OsStr>>(args: &[S], out: &Path) -> TriMesh {
    let o = bin().args(args).output().unwrap();
    assert!(
        o.status.success(),
        "meshmatch {:?} failed: {}",
        args.iter().map(|a| a.as_ref()).collect::<Vec<_>>(),
        String::from_utf8_lossy(&o.stderr)
    );
    load(out).unwrap()
}

/// (mean colour difference of 255, share of vertices off by more than 2 of 255 in a channel)
fn colour_difference(a: &TriMesh, b: &TriMesh) -> (f64, f64) {
    let (ca, cb) = (a.vertex_signal().unwrap(), b.vertex_signal().unwrap());
    assert_eq!(ca.len(), cb.len());
    let mut sum = 0.0;
    let mut off = 0usize;
    for (x, y) in ca.iter().zip(&cb) {
        let d: Vec<f64> = (0..3)
            .map(|c| 255.0 * (x[c] as f64 - y[c] as f64).abs())
            .collect();
        sum += d.iter().sum::<f64>() / 3.0;
        off += usize::from(d.iter().any(|&v| v > 2.0));
    }
    (sum / ca.len() as f64, off as f64 / ca.len() as f64)
}

/// Largest distance between `a`'s positions and `b`'s divided by `s`, of `a`'s bounding-box
/// diagonal.
fn position_difference(a: &TriMesh, b: &TriMesh, s: f64) -> f64 {
    assert_eq!(a.positions.len(), b.positions.len());
    let (lo, hi) = a.bounds().unwrap();
    let diag = (0..3)
        .map(|k| (hi[k] as f64 - lo[k] as f64).powi(2))
        .sum::<f64>()
        .sqrt();
    a.positions
        .iter()
        .zip(&b.positions)
        .map(|(p, q)| {
            (0..3)
                .map(|k| (p[k] as f64 - q[k] as f64 / s).powi(2))
                .sum::<f64>()
                .sqrt()
        })
        .fold(0.0, f64::max)
        / diag
}

/// Colours of a system's output in each unit against the unscaled run's: identical; positions
/// scaled (exactly in powers of two).
fn colours_follow_the_units(
    name: &str,
    inputs: &[&str],
    args: impl Fn(&[PathBuf], &Path) -> Vec<std::ffi::OsString>,
) {
    let dir = Scratch::new(&format!("units-{name}"));
    let one: Vec<PathBuf> = inputs.iter().map(|r| scaled(&dir, r, 1.0)).collect();
    let out1 = dir.join("out_1.ply");
    let base = run(&args(&one, &out1), &out1);
    for s in SCALES {
        let ins: Vec<PathBuf> = inputs.iter().map(|r| scaled(&dir, r, s)).collect();
        let out = dir.join(format!("out_{s}.ply"));
        let got = run(&args(&ins, &out), &out);
        let (m, off) = colour_difference(&base, &got);
        assert!(
            base.vertex_signal() == got.vertex_signal(),
            "{name} x{s}: mean colour difference {m:.3} of 255, {off:.4} of the vertices off by \
             more than 2 of 255"
        );
        let d = position_difference(&base, &got, s);
        if exact(s) {
            assert_eq!(d, 0.0, "{name} x{s}: positions");
        }
        assert!(
            d < 1e-6,
            "{name} x{s}: positions differ by {d:.2e} of the diagonal"
        );
    }
}

fn os(v: &[&dyn AsRef<std::ffi::OsStr>]) -> Vec<std::ffi::OsString> {
    v.iter().map(|a| a.as_ref().to_os_string()).collect()
}

#[test]
fn completion_is_the_same_in_any_units() {
    // a mask file of the vertices to synthesise: every third vertex's neighbourhood would be
    // trivial; a contiguous third of the file's vertices (Spot's vertex order is spatially
    // coherent) is a real hole
    let dir = Scratch::new("units-complete-mask");
    let mask = dir.join("mask.txt");
    let n = load(&data_path("spot/spot.obj")).unwrap().positions.len();
    std::fs::write(
        &mask,
        (0..n / 3).map(|v| format!("{v}\n")).collect::<String>(),
    )
    .unwrap();
    colours_follow_the_units("complete", &["spot/spot.obj"], |i, o| {
        os(&[
            &"complete",
            &"--mesh",
            &i[0],
            &"--mask",
            &mask,
            &"--vertices",
            &"4000",
            &"--out",
            &o,
        ])
    });
}

#[test]
fn texture_update_is_the_same_in_any_units() {
    // the new mesh: Spot, with its head moved
    let dir = Scratch::new("units-update-new");
    let mut new = load(&data_path("spot/spot.obj")).unwrap();
    let (lo, hi) = new.bounds().unwrap();
    for p in &mut new.positions {
        let t = ((p[2] - lo[2]) / (hi[2] - lo[2])).clamp(0.0, 1.0);
        p[1] += 0.08 * (hi[1] - lo[1]) * t * t;
    }
    let new_path = dir.join("spot_edited.obj");
    save(&new, &new_path).unwrap();
    let rel_new = new_path.to_string_lossy().to_string();
    colours_follow_the_units("update", &["spot/spot.obj", &rel_new], |i, o| {
        os(&[
            &"update",
            &"--old",
            &i[0],
            &"--new",
            &i[1],
            &"--vertices",
            &"4000",
            &"--out",
            &o,
        ])
    });
}

#[test]
fn exemplar_synthesis_is_the_same_in_any_units() {
    let exemplar = data_path("textures/1.jpg");
    colours_follow_the_units("synth", &["bunny/bunny.obj"], |i, o| {
        os(&[
            &"synth",
            &"--exemplar",
            &exemplar,
            &"--target",
            &i[0],
            &"--vertex-budget",
            &"30000",
            &"--out",
            &o,
        ])
    });
}

#[test]
fn features_are_the_same_in_any_units() {
    for feature in ["ao", "curvature", "height"] {
        colours_follow_the_units(
            &format!("features-{feature}"),
            &["bunny/bunny.obj"],
            |i, o| {
                os(&[
                    &"features",
                    &i[0],
                    &"--feature",
                    &feature,
                    &"--rays",
                    &"16",
                    &"--out",
                    &o,
                ])
            },
        );
    }
}

/// Transfer (at its default 64K working vertices) and weathering: their searches read shape
/// descriptors (a curvature is a second difference of the coordinates), so the last bit of a
/// coordinate would change their choices.
#[test]
fn transfer_and_weathering_follow_the_units() {
    colours_follow_the_units("transfer", &["spot/spot.obj", "bunny/bunny.obj"], |i, o| {
        os(&[
            &"transfer",
            &"--source",
            &i[0],
            &"--target",
            &i[1],
            &"--out",
            &o,
        ])
    });
    colours_follow_the_units("weather", &["spot/spot.obj", "bunny/bunny.obj"], |i, o| {
        os(&[
            &"weather",
            &"--source",
            &i[0],
            &"--target",
            &i[1],
            &"--vertices",
            &"5000",
            &"--rays",
            &"16",
            &"--out",
            &o,
        ])
    });
}

#[test]
fn detail_and_quilting_scale_their_geometry_with_the_units() {
    let dir = Scratch::new("units-geometry");
    // quilting: the same elements, in the base's units
    let quilt = |s: f64| {
        let base = scaled(&dir, "bunny/bunny.obj", s);
        let out = dir.join(format!("quilt_{s}.ply"));
        run(
            &os(&[
                &"quilt",
                &"--base",
                &base,
                &"--swatch",
                &"chain",
                &"--out",
                &out,
            ]),
            &out,
        )
    };
    let q1 = quilt(1.0);
    for s in SCALES {
        let q = quilt(s);
        assert_eq!(q.faces.len(), q1.faces.len(), "quilt x{s}");
        let d = position_difference(&q1, &q, s);
        if exact(s) {
            assert_eq!(d, 0.0, "quilt x{s}");
        }
        assert!(
            d < 1e-6,
            "quilt x{s}: positions differ by {d:.2e} of the diagonal"
        );
    }
    // detail: the displaced target, scaled back, where the unscaled run puts it
    let detail = |s: f64| {
        let src = scaled(&dir, "cow/cow.ply", s);
        let tgt = scaled(&dir, "bunny/bunny.obj", s);
        let out = dir.join(format!("detail_{s}.ply"));
        run(
            &os(&[
                &"detail",
                &"--source",
                &src,
                &"--target",
                &tgt,
                &"--vertices",
                &"4000",
                &"--out",
                &out,
            ]),
            &out,
        )
    };
    let d1 = detail(1.0);
    for s in SCALES {
        let d = position_difference(&d1, &detail(s), s);
        if exact(s) {
            assert_eq!(d, 0.0, "detail x{s}");
        }
        assert!(
            d < 1e-6,
            "detail x{s}: positions differ by {d:.2e} of the diagonal"
        );
    }
}
