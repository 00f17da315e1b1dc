//! End-to-end tests of the `meshmatch` command line: `info` on every shared mesh, bad inputs,
//! `convert`, `demo`, `synth`.

mod scratch;
use scratch::Scratch;

use meshmatch::testdata::data_path;
use std::path::{Path, PathBuf};
use std::process::Command;

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_meshmatch"))
}

fn tmpdir(name: &str) -> Scratch {
    Scratch::new(&format!("cli-{name}"))
}

fn info_json(path: &Path) -> serde_json::Value {
    let out = bin().arg("info").arg("--json").arg(path).output().unwrap();
    assert!(
        out.status.success(),
        "info failed on {}: {}",
        path.display(),
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8(out.stdout).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines.len(), 1, "one JSON line per file");
    serde_json::from_str(lines[0]).unwrap()
}

#[test]
fn info_reports_documented_counts_for_every_shared_mesh() {
    // (file, vertices, signal, triangles)
    let cases = [
        ("spot/spot.obj", 2930, "texture", 5856),
        ("cow/cow.ply", 2903, "none", 5804),
        ("robustness/cow_tristrips.ply", 2903, "none", 5804),
        ("horse/horse.ply", 48485, "none", 96966),
        ("igea/igea.ply", 134345, "none", 268686),
        ("nefertiti/nefertiti.obj", 49971, "none", 99938),
        ("cat/cat.obj", 7949, "none", 15894),
        ("human/human_man.obj", 6890, "none", 13776),
        ("human/human_woman.obj", 6890, "none", 13776),
        ("bunny/bunny.obj", 3301, "none", 6598),
        ("penguin/penguin.obj", 3362, "none", 6720),
    ];
    for (rel, nv, signal, nf) in cases {
        let v = info_json(&data_path(rel));
        assert_eq!(v["vertices"], nv, "{rel}");
        assert_eq!(v["signal"], signal, "{rel}");
        assert_eq!(v["faces"], nf, "{rel}");
        assert!(v["components"].as_u64().unwrap() >= 1, "{rel}");
        assert!(v["boundary_loops"].is_u64(), "{rel}");
        assert!(v["repairs"].is_object(), "{rel}");
        assert_eq!(v["path"], data_path(rel).display().to_string());
    }
    // Closed, single-piece meshes.
    for rel in ["spot/spot.obj", "cow/cow.ply", "bunny/bunny.obj"] {
        let v = info_json(&data_path(rel));
        assert_eq!(v["components"], 1, "{rel}");
        assert_eq!(v["boundary_loops"], 0, "{rel}");
    }
}

fn expect_clean_failure(args: &[&std::ffi::OsStr], mention: &str) {
    let out = bin().args(args).output().unwrap();
    assert_eq!(out.status.code(), Some(2), "exit code for {args:?}");
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(
        err.trim_end().lines().count(),
        1,
        "one-line message, got: {err}"
    );
    assert!(
        err.contains(mention),
        "message should name {mention}: {err}"
    );
    assert!(
        !err.contains("panicked") && !err.contains("internal error"),
        "no panic: {err}"
    );
}

#[test]
fn bad_inputs_give_one_line_errors_and_exit_code_2() {
    let d = tmpdir("bad");
    let empty = d.join("empty.obj");
    std::fs::write(&empty, b"").unwrap();
    let png_as_obj = d.join("image.obj");
    std::fs::copy(data_path("spot/spot_texture.png"), &png_as_obj).unwrap();
    let bad_index = d.join("bad_index.obj");
    std::fs::write(&bad_index, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 7\n").unwrap();
    let nan = d.join("nan.obj");
    std::fs::write(&nan, "v nan nan nan\nv inf 0 0\nv 0 nan 0\nf 1 2 3\n").unwrap();
    let horse = std::fs::read(data_path("horse/horse.ply")).unwrap();
    let trunc = d.join("truncated.ply");
    std::fs::write(&trunc, &horse[..horse.len() / 2]).unwrap();
    let missing = d.join("does_not_exist.ply");
    for p in [&empty, &png_as_obj, &bad_index, &nan, &trunc, &missing] {
        let name = p.file_name().unwrap().to_string_lossy().into_owned();
        expect_clean_failure(&["info".as_ref(), p.as_os_str()], &name);
        expect_clean_failure(
            &[
                "convert".as_ref(),
                p.as_os_str(),
                d.join("out.ply").as_os_str(),
            ],
            &name,
        );
    }
    // an option out of its documented range, or a swatch name that is none of them, is named
    // with what it may be
    let bunny = data_path("bunny/bunny.obj");
    let image = data_path("textures/1.jpg");
    expect_clean_failure(
        &[
            "synth".as_ref(),
            "--exemplar".as_ref(),
            image.as_os_str(),
            "--target".as_ref(),
            bunny.as_os_str(),
            "--out".as_ref(),
            d.join("s.ply").as_os_str(),
            "--levels".as_ref(),
            "9".as_ref(),
        ],
        "--levels 9: use 1 to 8",
    );
    expect_clean_failure(
        &[
            "swatch".as_ref(),
            "--kind".as_ref(),
            "foo".as_ref(),
            "--out".as_ref(),
            d.join("sw.obj").as_os_str(),
        ],
        "rings-patch, weave-patch, pebbles",
    );
    // A bad file among good ones: the good one still prints, exit code 2.
    let out = bin()
        .args(["info", "--json"])
        .arg(data_path("cow/cow.ply"))
        .arg(&empty)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert_eq!(String::from_utf8_lossy(&out.stdout).lines().count(), 1);
}

#[test]
fn convert_keeps_counts_across_formats() {
    let d = tmpdir("convert");
    for ext in ["ply", "obj", "glb"] {
        let out = d.join(format!("spot.{ext}"));
        let st = bin()
            .arg("convert")
            .arg(data_path("spot/spot.obj"))
            .arg(&out)
            .status()
            .unwrap();
        assert!(st.success());
        let v = info_json(&out);
        assert_eq!(v["faces"], 5856, "{ext}");
        assert_eq!(v["signal"], "texture", "{ext}");
        if ext != "glb" {
            assert_eq!(v["vertices"], 2930, "{ext}");
        } else {
            // GLB splits UV seams; the file's first 2930 vertices are Spot's, seam copies follow.
            assert!(v["vertices"].as_u64().unwrap() >= 2930);
        }
    }
}

/// A small exemplar for `synth`: a shared texture shrunk to 48 x 48, written as PNG; returns its
/// path and its colour palette.
fn small_exemplar(d: &Path, name: &str) -> (PathBuf, std::collections::HashSet<[u8; 3]>) {
    let img = image::open(data_path(&format!("textures/{name}")))
        .unwrap()
        .to_rgb8();
    let img = image::imageops::resize(&img, 48, 48, image::imageops::FilterType::Triangle);
    let path = d.join("exemplar.png");
    img.save(&path).unwrap();
    (path, img.pixels().map(|p| p.0).collect())
}

#[test]
fn synth_on_bunny_with_fast_search_uses_the_exemplars_palette() {
    let d = tmpdir("synth");
    let (ex, palette) = small_exemplar(&d, "bricks.png");
    let out_path = d.join("bunny_bricks.ply");
    let out = bin()
        .args(["synth", "--search", "fast", "--seed", "1", "--exemplar"])
        .arg(&ex)
        .arg("--target")
        .arg(data_path("bunny/bunny.obj"))
        .arg("--out")
        .arg(&out_path)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "synth failed: {err}");
    assert!(err.contains("fast search"), "{err}");
    let m = meshmatch::mesh::io::load(&out_path).unwrap();
    // The uniform-density mesh: the bunny refined, every vertex coloured from the exemplar.
    assert!(m.num_vertices() > 3301, "{} vertices", m.num_vertices());
    let cols = m.colors.as_ref().expect("vertex colours");
    let to_u8 = |c: &[f32; 3]| c.map(|x| (x * 255.0).round() as u8);
    let hits = cols.iter().filter(|c| palette.contains(&to_u8(c))).count();
    assert!(
        hits * 100 >= cols.len() * 99,
        "{hits} of {} vertices carry an exemplar colour",
        cols.len()
    );
    // and its colour distribution: the exemplar's, not a few of its colours
    let exc: Vec<[f32; 3]> = palette_colors(&ex);
    let hx = meshmatch::synthesis::exemplar::color_histogram(&exc, 8);
    let ho = meshmatch::synthesis::exemplar::color_histogram(cols, 8);
    let l1 = meshmatch::synthesis::exemplar::histogram_l1(&hx, &ho);
    assert!(l1 < 0.5, "colour histogram L1 {l1}");
    std::fs::remove_dir_all(&d).ok();
}

fn palette_colors(path: &Path) -> Vec<[f32; 3]> {
    let img = image::open(path).unwrap().to_rgb8();
    meshmatch::synthesis::exemplar::image_colors(&img)
}

#[test]
fn synth_with_a_missing_image_fails_cleanly_and_defaults_match_the_library() {
    let d = tmpdir("synth_bad");
    let missing = d.join("no_such_exemplar.png");
    expect_clean_failure(
        &[
            "synth".as_ref(),
            "--exemplar".as_ref(),
            missing.as_os_str(),
            "--target".as_ref(),
            data_path("bunny/bunny.obj").as_os_str(),
            "--out".as_ref(),
            d.join("out.ply").as_os_str(),
        ],
        "no_such_exemplar.png",
    );
    assert!(!d.join("out.ply").exists());
    // The command's documented defaults are the library's.
    let help = bin().args(["synth", "--help"]).output().unwrap();
    let help = String::from_utf8_lossy(&help.stdout);
    let p = meshmatch::synthesis::SynthParams::default();
    for want in [
        format!("[default: {}]", p.orientation.as_str()),
        format!("[default: {}]", p.search.as_str()),
        format!("[default: {}]", p.levels),
    ] {
        assert!(help.contains(&want), "synth --help lacks {want}: {help}");
    }
    std::fs::remove_dir_all(&d).ok();
}

/// Run the binary through bash: `prelude` (limits, traps) first, then `meshmatch ARGS`.
fn via_bash(prelude: &str, args: &[&std::ffi::OsStr]) -> std::process::Output {
    Command::new("bash")
        .arg("-c")
        .arg(format!("{prelude}; exec \"$0\" \"$@\""))
        .arg(env!("CARGO_BIN_EXE_meshmatch"))
        .args(args)
        .output()
        .unwrap()
}

/// A GLB container around a JSON document and a BIN chunk.
fn glb(doc: &serde_json::Value, bin: &[u8]) -> Vec<u8> {
    let mut js = serde_json::to_vec(doc).unwrap();
    while !js.len().is_multiple_of(4) {
        js.push(b' ');
    }
    let mut out = Vec::new();
    out.extend(b"glTF");
    out.extend(2u32.to_le_bytes());
    out.extend(((12 + 8 + js.len() + 8 + bin.len()) as u32).to_le_bytes());
    out.extend((js.len() as u32).to_le_bytes());
    out.extend(b"JSON");
    out.extend(&js);
    out.extend((bin.len() as u32).to_le_bytes());
    out.extend(b"BIN\0");
    out.extend(bin);
    out
}

#[test]
fn crafted_gltf_and_device_references_fail_cleanly_within_3_gb() {
    use serde_json::json;
    let d = tmpdir("bombs");
    let limit = "ulimit -v 3000000";
    let mut bin = Vec::new();
    bin.extend(0u32.to_le_bytes());
    for c in [0.0f32, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0] {
        bin.extend(c.to_le_bytes());
    }
    // 20M-vertex sparse POSITION accessor without bufferView, instanced by 100 nodes (2 KB).
    let bomb = json!({
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": (0..100).collect::<Vec<_>>()}],
        "nodes": (0..100).map(|_| json!({"mesh": 0})).collect::<Vec<_>>(),
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
        "buffers": [{"byteLength": 40}],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": 4},
            {"buffer": 0, "byteOffset": 4, "byteLength": 12}
        ],
        "accessors": [{
            "componentType": 5126, "count": 20_000_000, "type": "VEC3",
            "sparse": {"count": 1,
                "indices": {"bufferView": 0, "componentType": 5125},
                "values": {"bufferView": 1}}
        }]
    });
    let p = d.join("sparse_bomb.glb");
    std::fs::write(&p, glb(&bomb, &bin)).unwrap();
    let out = via_bash(limit, &["info".as_ref(), p.as_os_str()]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert_eq!(err.trim_end().lines().count(), 1, "{err}");
    assert!(
        err.contains("sparse_bomb.glb") && err.contains("budget"),
        "{err}"
    );
    // 3000 buffers sharing one 4 MB BIN chunk: loads within the limit.
    let mut big = vec![0u8; 4 << 20];
    big[..40].copy_from_slice(&bin);
    let shared = json!({
        "asset": {"version": "2.0"},
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
        "buffers": (0..3000).map(|_| json!({"byteLength": 4 << 20})).collect::<Vec<_>>(),
        "bufferViews": [{"buffer": 1234, "byteOffset": 4, "byteLength": 36}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3"}]
    });
    let p = d.join("bufclone.glb");
    std::fs::write(&p, glb(&shared, &big)).unwrap();
    let out = via_bash(limit, &["info".as_ref(), "--json".as_ref(), p.as_os_str()]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["faces"], 1);
    // Buffers and textures that are devices, not files.
    let p = d.join("devzero.gltf");
    std::fs::write(
        &p,
        r#"{"asset": {"version": "2.0"}, "buffers": [{"byteLength": 4, "uri": "/dev/zero"}]}"#,
    )
    .unwrap();
    let out = via_bash(limit, &["info".as_ref(), p.as_os_str()]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert_eq!(err.trim_end().lines().count(), 1, "{err}");
    assert!(
        err.contains("devzero.gltf") && err.contains("not a regular file"),
        "{err}"
    );
    let p = d.join("devzero.ply");
    std::fs::write(
        &p,
        "ply\nformat ascii 1.0\ncomment TextureFile /dev/zero\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n",
    )
    .unwrap();
    let out = via_bash(limit, &["info".as_ref(), "--json".as_ref(), p.as_os_str()]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(
        err.starts_with("warning:") && err.contains("not a regular file"),
        "{err}"
    );
}

#[test]
fn a_refused_file_prints_one_line_without_its_warnings() {
    let d = tmpdir("twoline");
    // A short face (a warning) and an out-of-range index (the error).
    let ply = d.join("twoline.ply");
    std::fs::write(
        &ply,
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 2\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n2 0 1\n3 0 1 5\n",
    )
    .unwrap();
    // Only a short face: loads with a warning, then has no faces.
    let obj = d.join("twoline.obj");
    std::fs::write(&obj, "v 0 0 0\nv 1 0 0\nf 1 2\n").unwrap();
    // A missing material library (a warning) and no faces.
    let obj2 = d.join("twoline2.obj");
    std::fs::write(&obj2, "mtllib missing.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\n").unwrap();
    for p in [&ply, &obj, &obj2] {
        let name = p.file_name().unwrap().to_string_lossy().into_owned();
        expect_clean_failure(&["info".as_ref(), p.as_os_str()], &name);
        expect_clean_failure(
            &[
                "convert".as_ref(),
                p.as_os_str(),
                d.join("out.ply").as_os_str(),
            ],
            &name,
        );
    }
    // When the file is accepted the warning is printed.
    let ok = d.join("ok.obj");
    std::fs::write(&ok, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2\nf 1 2 3\n").unwrap();
    let out = bin().arg("info").arg(&ok).output().unwrap();
    assert!(out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("warning:") && err.contains("skipped 1 faces"),
        "{err}"
    );
}

#[test]
fn info_stops_quietly_when_stdout_is_closed() {
    let d = tmpdir("pipe");
    let cow = data_path("cow/cow.ply");
    let files: Vec<&std::ffi::OsStr> = std::iter::repeat_n(cow.as_os_str(), 200).collect();
    for (redirect, label) in [
        ("2>\"$ERRFILE\"", "stderr apart"),
        ("2>&1", "stderr on the pipe"),
    ] {
        let errfile = d.join("err.txt");
        let out = Command::new("bash")
            .arg("-c")
            .arg(format!(
                "\"$0\" info --json \"$@\" {redirect} | head -1 >/dev/null; echo \"${{PIPESTATUS[0]}}\""
            ))
            .arg(env!("CARGO_BIN_EXE_meshmatch"))
            .args(&files)
            .env("ERRFILE", &errfile)
            .output()
            .unwrap();
        let status = String::from_utf8_lossy(&out.stdout);
        assert_eq!(status.trim(), "0", "{label}: exit status");
        if redirect.contains("ERRFILE") {
            let err = std::fs::read_to_string(&errfile).unwrap();
            assert!(err.is_empty(), "{label}: nothing on stderr, got: {err}");
        }
    }
}

#[test]
fn convert_removes_its_temporary_file_when_the_write_fails() {
    let d = tmpdir("fsize");
    let out_dir = d.join("out");
    let _ = std::fs::remove_dir_all(&out_dir);
    std::fs::create_dir_all(&out_dir).unwrap();
    let target = out_dir.join("cow.ply");
    // Files larger than 8 KB cannot be written (EFBIG); the cow's PLY is about 120 KB.
    let out = via_bash(
        "ulimit -f 8; trap '' XFSZ",
        &[
            "convert".as_ref(),
            data_path("cow/cow.ply").as_os_str(),
            target.as_os_str(),
        ],
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert_eq!(err.trim_end().lines().count(), 1, "{err}");
    assert!(err.contains("cow.ply"), "{err}");
    let left: Vec<_> = std::fs::read_dir(&out_dir)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert!(left.is_empty(), "nothing left behind: {left:?}");
}

#[test]
fn convert_keeps_the_file_vertex_order_and_faces_of_a_mesh_needing_repair() {
    let d = tmpdir("norepair");
    let src = d.join("repair.obj");
    // An unused first vertex, a duplicate face and a degenerate face.
    std::fs::write(
        &src,
        "v 9 9 9\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 2 3 4\nf 2 3 4\nf 3 5 4\nf 2 2 3\n",
    )
    .unwrap();
    let orig = meshmatch::mesh::io::load(&src).unwrap();
    for ext in ["ply", "obj", "glb"] {
        let out = d.join(format!("r.{ext}"));
        let st = bin().arg("convert").arg(&src).arg(&out).status().unwrap();
        assert!(st.success(), "{ext}");
        let back = meshmatch::mesh::io::load(&out).unwrap();
        assert_eq!(
            back.positions, orig.positions,
            "{ext}: same vertices, same order"
        );
        assert_eq!(back.faces, orig.faces, "{ext}: same faces");
        let v = info_json(&out);
        assert_eq!(v["vertices"], 5, "{ext}");
        assert_eq!(v["repairs"]["unreferenced_vertices_removed"], 1, "{ext}");
        assert_eq!(v["repairs"]["duplicate_faces_removed"], 1, "{ext}");
        assert_eq!(v["repairs"]["degenerate_faces_removed"], 1, "{ext}");
    }
}

#[test]
fn an_interrupted_command_leaves_no_temporary_file() {
    // Ctrl-C while the output is being written (under its temporary name, renamed when the
    // command succeeds): the command stops with 130 and takes its temporary file with it
    let d = tmpdir("interrupt");
    let tet = d.join("tet.obj");
    std::fs::write(
        &tet,
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 2 3 4\nf 3 1 4\n",
    )
    .unwrap();
    let mut child = bin()
        .args(["features", "--rays", "1", "--texture-size", "8192"])
        .args(["--feature", "normal", "--out"])
        .arg(d.join("p.png"))
        .arg(&tet)
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let temporary = || {
        std::fs::read_dir(&*d)
            .unwrap()
            .flatten()
            .any(|e| e.file_name().to_string_lossy().contains(".tmp"))
    };
    let start = std::time::Instant::now();
    while !temporary() && start.elapsed().as_secs() < 120 {
        if child.try_wait().unwrap().is_some() {
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    if child.try_wait().unwrap().is_some() {
        // finished before its file could be caught: nothing to interrupt
        return;
    }
    Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    let status = child.wait().unwrap();
    if status.code() == Some(0) {
        return; // the rename won the race
    }
    assert_eq!(status.code(), Some(130));
    assert!(!temporary(), "a temporary file is left behind");
    assert!(!d.join("p.png").exists());
}

#[test]
fn a_failed_command_leaves_no_folder_it_made_and_says_it_wrote_nothing() {
    // The output's folders are made before the work (so that a path under a file is refused
    // up front); a command that then fails takes the folders it made with it, and only a
    // command that delivered its files says "wrote".
    let d = tmpdir("failed-folders");
    let flat = d.join("flat.obj");
    std::fs::write(&flat, "v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n").unwrap();
    let out = d.join("new").join("deeper").join("o.ply");
    let o = bin()
        .args(["features", "--feature", "curvature", "--out"])
        .arg(&out)
        .arg(&flat)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(!err.contains("wrote"), "{err}");
    assert!(
        !d.join("new").exists(),
        "the folders made for the output are left: {err}"
    );

    // the same command on a real mesh makes them, delivers and says so last
    let tet = d.join("tet.obj");
    std::fs::write(
        &tet,
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 2 3 4\nf 3 1 4\n",
    )
    .unwrap();
    let o = bin()
        .args(["features", "--feature", "curvature", "--out"])
        .arg(&out)
        .arg(&tet)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(out.exists());
    assert!(
        err.trim_end()
            .lines()
            .last()
            .unwrap_or("")
            .starts_with("wrote"),
        "{err}"
    );
}

#[test]
fn a_value_that_is_not_a_finite_number_names_its_option() {
    for v in ["-inf", "-NaN", "-infinity"] {
        let o = bin()
            .args([
                "transfer", "--source", "s.obj", "--target", "t.obj", "--out", "o.ply",
            ])
            .args(["--tolerance", v])
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{err}");
        assert!(
            err.contains(&format!("--tolerance {v}: not a finite number")),
            "{v}: {err}"
        );
    }
}

/// Run where stderr is a log (a batch job sets MESHMATCH_PROGRESS=lines for its jobs), a long
/// command shows that it moves: a plain line per stage and per tenth of the work,
/// `[hh:mm:ss]  40% stage`, the stage times, and "wrote" last. Without it a captured stderr
/// holds the summary alone, so a refusal stays one line.
#[test]
fn a_log_shows_the_progress_as_plain_lines() {
    let d = tmpdir("log");
    let out = d.join("t.ply");
    let transfer = |progress: Option<&str>| {
        let mut c = bin();
        c.args(["transfer", "--vertices", "2000", "--source"])
            .arg(data_path("spot/spot.obj"))
            .arg("--target")
            .arg(data_path("bunny/bunny.obj"))
            .arg("--out")
            .arg(&out)
            .env_remove("MESHMATCH_PROGRESS");
        if let Some(v) = progress {
            c.env("MESHMATCH_PROGRESS", v);
        }
        c.output().unwrap()
    };
    let quiet = transfer(None);
    let err = String::from_utf8_lossy(&quiet.stderr);
    assert!(quiet.status.success(), "{err}");
    assert!(!err.contains("% solve"), "{err}");
    let o = transfer(Some("lines"));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    let progress: Vec<(u32, &str)> = err
        .lines()
        .filter_map(|l| {
            let rest = l.strip_prefix('[')?;
            let (clock, rest) = rest.split_once("] ")?;
            let ok = clock.len() == 8 && clock.split(':').all(|f| f.parse::<u32>().is_ok());
            let (pct, stage) = rest.trim_start().split_once("% ")?;
            ok.then_some((pct.parse().ok()?, stage))
        })
        .collect();
    let solve: Vec<u32> = progress
        .iter()
        .filter(|(_, st)| *st == "solve")
        .map(|p| p.0)
        .collect();
    assert!(solve.len() >= 3, "the solve's tenths: {err}");
    assert!(solve.windows(2).all(|w| w[0] < w[1]), "{err}");
    assert!(progress.iter().any(|(_, st)| *st == "refine"), "{err}");
    assert!(
        err.lines().any(|l| l.trim_start().starts_with("level 0")),
        "stage times: {err}"
    );
    assert!(
        err.lines().last().is_some_and(|l| l.starts_with("wrote ")),
        "{err}"
    );
}
