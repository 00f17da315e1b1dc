//! Loader/exporter tests on the shared real meshes: documented counts, the tristrip cow, round
//! trips through PLY/OBJ/GLB/glTF, Spot's texture signal, and bad inputs.

mod scratch;
use scratch::Scratch;

use meshmatch::TriMesh;
use meshmatch::color::srgb_to_lab;
use meshmatch::mesh::io::{self, GlbOptions};
use meshmatch::testdata::data_path;
use std::collections::HashMap;
use std::path::Path;

/// A fresh scratch directory for one test.
fn scratch(name: &str) -> Scratch {
    Scratch::new(&format!("io-{name}"))
}

fn load(rel: &str) -> TriMesh {
    let p = data_path(rel);
    io::load(&p).unwrap_or_else(|e| panic!("{rel}: {e}"))
}

#[test]
fn every_shared_mesh_loads_with_documented_counts() {
    let cases = [
        ("spot/spot.obj", 2930),
        ("cow/cow.ply", 2903),
        ("horse/horse.ply", 48485),
        ("igea/igea.ply", 134345),
        ("nefertiti/nefertiti.obj", 49971),
        ("cat/cat.obj", 7949),
        ("human/human_man.obj", 6890),
        ("human/human_woman.obj", 6890),
        ("bunny/bunny.obj", 3301),
        ("penguin/penguin.obj", 3362),
        ("robustness/cow_tristrips.ply", 2903),
    ];
    for (rel, nv) in cases {
        let t = std::time::Instant::now();
        let m = load(rel);
        let load_ms = t.elapsed().as_secs_f64() * 1e3;
        let r = m.validate();
        println!(
            "{rel}: {} vertices, {} faces, {} boundary loops, {} components, loaded in {load_ms:.1} ms",
            m.num_vertices(),
            m.num_faces(),
            r.boundary_loops,
            r.components,
        );
        assert_eq!(m.num_vertices(), nv, "{rel}");
        assert_eq!(m.file_vertex_count, nv, "{rel}");
        assert_eq!(m.file_index.len(), nv);
        assert!(
            m.file_index
                .iter()
                .enumerate()
                .all(|(i, &f)| f as usize == i)
        );
        assert_eq!(m.path.as_deref(), Some(data_path(rel).as_path()));
        m.check_usable().unwrap();
        // Euler: a closed surface of genus g has F = 2V - 4 + 4g; with boundaries, F is a bit
        // less. Every shared mesh is within 5% of 2V.
        let ratio = m.num_faces() as f64 / nv as f64;
        assert!((1.9..=2.05).contains(&ratio), "{rel}: F/V = {ratio}");
        assert_eq!(r.non_finite_vertices, 0, "{rel}");
    }
    // Attributes the files carry.
    let spot = load("spot/spot.obj");
    assert!(spot.texture.is_some() && spot.uvs.is_some());
    let uvs = spot.uvs.as_ref().unwrap();
    let distinct: std::collections::HashSet<[u32; 2]> =
        uvs.iter().map(|u| u.map(f32::to_bits)).collect();
    assert_eq!(
        distinct.len(),
        3225,
        "Spot's documented texture coordinate count"
    );
    let tex = spot.texture.as_ref().unwrap();
    assert_eq!((tex.image.width(), tex.image.height()), (1024, 1024));
    let horse = load("horse/horse.ply");
    assert!(horse.normals.is_some());
    let bunny = load("bunny/bunny.obj");
    assert!(bunny.normals.is_some(), "bunny.obj has vn per corner");
}

/// Triangles as cyclic-order-normalised triples (rotated so the smallest index is first).
fn oriented(f: [u32; 3]) -> [u32; 3] {
    let k = (0..3).min_by_key(|&k| f[k]).unwrap();
    [f[k], f[(k + 1) % 3], f[(k + 2) % 3]]
}

#[test]
fn tristrip_cow_equals_face_cow() {
    let cow = load("cow/cow.ply");
    let strips = load("robustness/cow_tristrips.ply");
    assert_eq!(cow.num_vertices(), strips.num_vertices());
    for (a, b) in cow.positions.iter().zip(&strips.positions) {
        for k in 0..3 {
            // cow.ply stores doubles, the strip file floats: equal after rounding to f32.
            assert_eq!(a[k], b[k]);
        }
    }
    let sorted = |m: &TriMesh| {
        let mut v: Vec<[u32; 3]> = m
            .faces
            .iter()
            .map(|f| {
                let mut s = *f;
                s.sort_unstable();
                s
            })
            .collect();
        v.sort_unstable();
        v
    };
    assert_eq!(strips.num_faces(), cow.num_faces());
    assert_eq!(sorted(&cow), sorted(&strips), "same set of triangles");
    let orient: HashMap<[u32; 3], [u32; 3]> = cow
        .faces
        .iter()
        .map(|f| {
            let mut s = *f;
            s.sort_unstable();
            (s, oriented(*f))
        })
        .collect();
    let mut same = 0;
    for f in &strips.faces {
        let mut s = *f;
        s.sort_unstable();
        if orient[&s] == oriented(*f) {
            same += 1;
        }
    }
    println!(
        "orientation agrees on {same} of {} triangles",
        strips.num_faces()
    );
    assert_eq!(
        same,
        strips.num_faces(),
        "every strip triangle keeps cow.ply's winding"
    );
}

/// Compare a reloaded mesh with the original. `split` allows GLB seam copies (vertices >= N
/// that duplicate a vertex's position).
fn assert_round_trip(orig: &TriMesh, back: &TriMesh, what: &str, split: bool) {
    let n = orig.num_vertices();
    if split {
        assert!(back.num_vertices() >= n, "{what}");
    } else {
        assert_eq!(back.num_vertices(), n, "{what}");
    }
    assert_eq!(
        &back.positions[..n],
        &orig.positions[..],
        "{what}: positions"
    );
    assert_eq!(back.num_faces(), orig.num_faces(), "{what}");
    let mut copies = 0;
    for (fo, fb) in orig.faces.iter().zip(&back.faces) {
        for k in 0..3 {
            if fo[k] != fb[k] {
                assert!(split && fb[k] as usize >= n, "{what}: face index changed");
                assert_eq!(
                    back.positions[fb[k] as usize], orig.positions[fo[k] as usize],
                    "{what}: seam copy"
                );
                copies += 1;
            }
        }
    }
    if split {
        println!(
            "{what}: {} seam vertices added, {copies} corners use them",
            back.num_vertices() - n
        );
    }
    match (&orig.uvs, &back.uvs) {
        (None, None) => {}
        (Some(a), Some(b)) => {
            assert_eq!(a.len(), b.len());
            let worst = a
                .iter()
                .zip(b)
                .map(|(x, y)| (x[0] - y[0]).abs().max((x[1] - y[1]).abs()))
                .fold(0.0f32, f32::max);
            assert!(worst <= 1e-6, "{what}: uv error {worst}");
        }
        (a, b) => panic!("{what}: uvs {} -> {}", a.is_some(), b.is_some()),
    }
    match (&orig.colors, &back.colors) {
        (None, None) => {}
        (Some(a), Some(b)) => {
            let worst = a
                .iter()
                .zip(b)
                .flat_map(|(x, y)| (0..3).map(move |k| (x[k] - y[k]).abs()))
                .fold(0.0f32, f32::max);
            assert!(worst <= 1.0 / 255.0, "{what}: colour error {worst}");
            if split {
                // seam copies carry their source vertex's colour
                for (j, fb) in back.faces.iter().flatten().enumerate() {
                    let o = orig.faces[j / 3][j % 3] as usize;
                    let d = (0..3).map(|k| (b[*fb as usize][k] - a[o][k]).abs());
                    assert!(d.fold(0.0f32, f32::max) <= 1.0 / 255.0);
                }
            }
        }
        (a, b) => panic!("{what}: colors {} -> {}", a.is_some(), b.is_some()),
    }
    match (&orig.normals, &back.normals) {
        // Every writer adds smooth normals to a mesh without them (tests/files.rs).
        (None, Some(_)) => {}
        (Some(a), Some(b)) => {
            let worst = a
                .iter()
                .zip(b)
                .map(|(x, y)| {
                    let x = glam::Vec3::from(*x).normalize_or_zero();
                    let y = glam::Vec3::from(*y).normalize_or_zero();
                    (x - y).abs().max_element()
                })
                .fold(0.0f32, f32::max);
            assert!(worst <= 1e-5, "{what}: normal error {worst}");
        }
        (a, b) => panic!("{what}: normals {} -> {}", a.is_some(), b.is_some()),
    }
    match (&orig.texture, &back.texture) {
        (None, None) => {}
        (Some(a), Some(b)) => assert!(a.image == b.image, "{what}: texture pixels"),
        (a, b) => panic!("{what}: texture {} -> {}", a.is_some(), b.is_some()),
    }
}

fn round_trip_all(orig: &TriMesh, label: &str) {
    let dir = scratch(label);
    for ext in ["ply", "obj", "glb", "gltf"] {
        let p = dir.join(format!("{label}.{ext}"));
        io::save(orig, &p).unwrap_or_else(|e| panic!("{label}.{ext}: {e}"));
        let back = io::load(&p).unwrap_or_else(|e| panic!("{label}.{ext}: {e}"));
        assert_round_trip(
            orig,
            &back,
            &format!("{label}.{ext}"),
            matches!(ext, "glb" | "gltf"),
        );
        // The exported file round-trips again to the same bytes-equivalent mesh.
        if ext != "glb" && ext != "gltf" {
            let p2 = dir.join(format!("{label}_2.{ext}"));
            io::save(&back, &p2).unwrap();
            assert_round_trip(
                &back,
                &io::load(&p2).unwrap(),
                &format!("{label}.{ext} x2"),
                false,
            );
        }
    }
    // No temporary files are left behind by the atomic writes.
    for e in std::fs::read_dir(&dir).unwrap() {
        let name = e.unwrap().file_name().to_string_lossy().into_owned();
        assert!(!name.contains(".tmp"), "leftover {name}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn round_trip_textured_spot() {
    let spot = load("spot/spot.obj");
    round_trip_all(&spot, "spot_textured");
}

#[test]
fn round_trip_vertex_coloured_spot() {
    let mut spot = load("spot/spot.obj");
    spot.colors = spot.vertex_signal();
    spot.uvs = None;
    spot.texture = None;
    round_trip_all(&spot, "spot_coloured");
    // Colours and texture together: the GLB texture-only option drops COLOR_0.
    let mut both = load("spot/spot.obj");
    both.colors = both.vertex_signal();
    round_trip_all(&both, "spot_both");
    let dir = scratch("glb_opts");
    let p = dir.join("tex_only.glb");
    io::save_glb(
        &both,
        &p,
        &GlbOptions {
            vertex_colors: false,
            texture: true,
        },
    )
    .unwrap();
    let back = io::load(&p).unwrap();
    assert!(back.colors.is_none() && back.texture.is_some() && back.uvs.is_some());
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn round_trip_normals_horse() {
    let horse = load("horse/horse.ply");
    round_trip_all(&horse, "horse");
}

#[test]
fn spot_signal_has_black_patches_and_pink_nose() {
    let spot = load("spot/spot.obj");
    let sig = spot.vertex_signal().expect("spot has a texture signal");
    let lab: Vec<[f32; 3]> = sig.iter().map(|&c| srgb_to_lab(c)).collect();
    let n = lab.len() as f32;
    // The texture's patches are dark grey #404040 (L* = 27.1) and the eyes black; a vertex on a
    // patch reads L* < 35 after bilinear filtering and corner averaging.
    let patch = meshmatch::color::srgb_to_lab([64.0 / 255.0; 3])[0];
    assert!((patch - 27.1).abs() < 0.2);
    let tex = spot.texture.as_ref().unwrap();
    let px = |x: u32, y: u32| tex.image.get_pixel(x, y).0;
    assert_eq!(px(220, 250), [64, 64, 64], "a patch pixel in the texture");
    for t in [25.0, 30.0, 35.0] {
        let f = lab.iter().filter(|l| l[0] < t).count() as f32 / n;
        println!("fraction with L* < {t}: {:.1}%", 100.0 * f);
    }
    let black = lab.iter().filter(|l| l[0] < 35.0).count() as f32 / n;
    let pink = lab.iter().filter(|l| l[1] > 15.0 && l[0] > 50.0).count();
    let mean_l = lab.iter().map(|l| l[0]).sum::<f32>() / n;
    let sd_l = (lab.iter().map(|l| (l[0] - mean_l).powi(2)).sum::<f32>() / n).sqrt();
    println!(
        "spot signal: {:.1}% near-black, {pink} pink vertices, L* mean {mean_l:.1} sd {sd_l:.1}",
        100.0 * black
    );
    assert!(black > 0.05, "black patches: {black}");
    assert!(pink >= 10, "pink nose: {pink}");
    assert!(sd_l > 15.0, "not one flat colour: sd {sd_l}");
}

/// The error message names the file and contains `needle`.
fn expect_err(path: &Path, needle: &str) -> String {
    let r = std::panic::catch_unwind(|| io::load(path));
    let msg = match r {
        Ok(Err(e)) => e.to_string(),
        Ok(Ok(m)) => panic!(
            "{}: loaded ({} vertices) but should fail",
            path.display(),
            m.num_vertices()
        ),
        Err(_) => panic!("{}: loader panicked", path.display()),
    };
    println!("{msg}");
    let name = path.file_name().unwrap().to_string_lossy();
    assert!(
        msg.contains(&*name),
        "message does not name the file: {msg}"
    );
    assert!(msg.contains(needle), "expected '{needle}' in: {msg}");
    assert!(!msg.contains('\n'), "one line: {msg}");
    msg
}

#[test]
fn bad_inputs_give_clear_errors() {
    let dir = scratch("bad");
    for ext in ["obj", "ply", "glb", "gltf"] {
        let p = dir.join(format!("empty.{ext}"));
        std::fs::write(&p, b"").unwrap();
        expect_err(&p, "empty file");
    }
    // Truncated binary PLY.
    let horse = std::fs::read(data_path("horse/horse.ply")).unwrap();
    let p = dir.join("horse_half.ply");
    std::fs::write(&p, &horse[..horse.len() / 2]).unwrap();
    expect_err(&p, "truncated");
    // Absurd count in a tiny file: refused before allocating.
    let p = dir.join("huge.ply");
    std::fs::write(
        &p,
        "ply\nformat binary_little_endian 1.0\nelement vertex 999999999999\nproperty float x\nproperty float y\nproperty float z\nend_header\n\0\0\0\0",
    )
    .unwrap();
    expect_err(&p, "999999999999");
    // OBJ out-of-range and zero indices name the line.
    let p = dir.join("range.obj");
    std::fs::write(&p, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 4\n").unwrap();
    expect_err(&p, "line 5");
    let p = dir.join("zero.obj");
    std::fs::write(&p, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n").unwrap();
    expect_err(&p, "line 4");
    let p = dir.join("word.obj");
    std::fs::write(&p, "v 0 0 0\nv 1 zero 0\n").unwrap();
    expect_err(&p, "line 2");
    // A PNG renamed to .obj.
    let p = dir.join("picture.obj");
    std::fs::copy(data_path("spot/spot_texture.png"), &p).unwrap();
    expect_err(&p, "not an OBJ file (looks like a PNG image)");
    let p = dir.join("picture.ply");
    std::fs::copy(data_path("textures/1.jpg"), &p).unwrap();
    expect_err(&p, "not a PLY file (looks like a JPEG image)");
    // Unknown extension.
    let p = dir.join("mesh.stl");
    std::fs::write(&p, b"solid x").unwrap();
    expect_err(&p, "unsupported format");
    // All coordinates NaN/inf: loads, but is refused by check_usable and repair.
    let p = dir.join("nan.obj");
    std::fs::write(&p, "v nan 0 0\nv inf 1 0\nv 0 -inf 1\nf 1 2 3\n").unwrap();
    let mut m = io::load(&p).unwrap();
    assert_eq!(m.validate().non_finite_vertices, 3);
    let e = m.check_usable().unwrap_err().to_string();
    assert!(e.contains("nan.obj") && e.contains("finite"), "{e}");
    assert!(m.repair().is_err());
    // Broken GLB buffers, made from a valid export.
    let spot = load("spot/spot.obj");
    let good = dir.join("spot.glb");
    io::save(&spot, &good).unwrap();
    let bytes = std::fs::read(&good).unwrap();
    io::load(&good).unwrap();
    let json_len = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    let bin_at = 20 + json_len;
    // (a) the BIN chunk length field shrunk (chunk shorter than the declared buffer)
    let mut b = bytes.clone();
    let bin_len = u32::from_le_bytes(b[bin_at..bin_at + 4].try_into().unwrap());
    b[bin_at..bin_at + 4].copy_from_slice(&(bin_len / 2).to_le_bytes());
    let p = dir.join("short_chunk.glb");
    std::fs::write(&p, &b).unwrap();
    expect_err(&p, "");
    // (b) file truncated in the middle of the BIN chunk
    let p = dir.join("truncated.glb");
    std::fs::write(&p, &bytes[..bin_at + 1000]).unwrap();
    expect_err(&p, "");
    // (c) consistent container, but the buffer declared larger than the chunk
    let text = String::from_utf8(bytes[20..20 + json_len].to_vec()).unwrap();
    let grown = text.replace(
        &format!("\"byteLength\":{bin_len}}}"),
        &format!("\"byteLength\":{}}}", bin_len * 2),
    );
    assert_ne!(grown, text);
    let mut grown = grown.into_bytes();
    while !grown.len().is_multiple_of(4) {
        grown.push(b' ');
    }
    let mut b = Vec::new();
    b.extend(b"glTF");
    b.extend(2u32.to_le_bytes());
    b.extend(((bytes.len() - json_len + grown.len()) as u32).to_le_bytes());
    b.extend((grown.len() as u32).to_le_bytes());
    b.extend(b"JSON");
    b.extend(&grown);
    b.extend(&bytes[bin_at..]);
    let p = dir.join("long_buffer.glb");
    std::fs::write(&p, &b).unwrap();
    expect_err(&p, "buffer 0 has");
    // (d) glTF JSON with a bad buffer URI
    let p = dir.join("bad_uri.gltf");
    std::fs::write(
        &p,
        text.replace(
            &format!("\"byteLength\":{bin_len}}}"),
            &format!("\"byteLength\":{bin_len},\"uri\":\"missing%20file.bin\"}}"),
        ),
    )
    .unwrap();
    expect_err(&p, "missing file.bin");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn obj_features_polygons_negative_indices_colours_groups() {
    let dir = scratch("objfeat");
    let p = dir.join("quad.obj");
    std::fs::write(
        &p,
        "# two objects\no a\nv 0 0 0 1 0 0\nv 1 0 0 0 1 0\nv 1 1 0 0 0 1\nv 0 1 0 1 1 1\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvn 0 0 1\nf 1/1/1 2/2/1 3/3/1 4/4/1\ng b\nv 2 0 0 0.5 0.5 0.5\nf -4/-3 -1/-2 -3/-1\nf 2//1 5//1 3//1\n",
    )
    .unwrap();
    let m = io::load(&p).unwrap();
    assert_eq!(m.num_vertices(), 5);
    assert_eq!(m.faces, vec![[0, 1, 2], [0, 2, 3], [1, 4, 2], [1, 4, 2]]);
    let uv = m.uvs.as_ref().unwrap();
    assert_eq!(
        &uv[..6],
        &[
            [0.0, 0.0],
            [1.0, 0.0],
            [1.0, 1.0],
            [0.0, 0.0],
            [1.0, 1.0],
            [0.0, 1.0]
        ]
    );
    assert_eq!(&uv[6..9], &[[1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]);
    assert_eq!(&uv[9..], &[[0.0, 0.0]; 3], "corners without vt get (0, 0)");
    assert_eq!(m.colors.as_ref().unwrap()[4], [0.5, 0.5, 0.5]);
    assert!(
        m.normals.is_none(),
        "vertex 4 has no vn, so no per-vertex normals"
    );
    // Missing MTL/texture: a warning, the mesh still loads.
    let p = dir.join("nomtl.obj");
    std::fs::write(
        &p,
        "mtllib gone.mtl\nusemtl x\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 2/1 3/1\n",
    )
    .unwrap();
    let m = io::load(&p).unwrap();
    assert!(m.texture.is_none() && m.uvs.is_some());
    let p = dir.join("notex.obj");
    std::fs::write(
        dir.join("notex.mtl"),
        "newmtl x\nmap_Kd -s 1 1 1 absent.png\n",
    )
    .unwrap();
    std::fs::write(
        &p,
        "mtllib notex.mtl\nusemtl x\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
    )
    .unwrap();
    assert!(io::load(&p).unwrap().texture.is_none());
    // map_Kd with options, upper-case extension.
    std::fs::copy(data_path("textures/4.png"), dir.join("t.png")).unwrap();
    std::fs::write(dir.join("opt.mtl"), "newmtl x\nmap_Kd -s 1 1 1 t.png\n").unwrap();
    let p = dir.join("OPT.OBJ");
    std::fs::write(
        &p,
        "mtllib opt.mtl\nusemtl x\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
    )
    .unwrap();
    assert!(io::load(&p).unwrap().texture.is_some());
    // A UTF-8 byte order mark does not hide the first line.
    let p = dir.join("bom.obj");
    std::fs::write(&p, "\u{feff}v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
    assert_eq!(io::load(&p).unwrap().num_vertices(), 3);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn ply_ascii_big_endian_lists_strips_and_unknown_elements() {
    let dir = scratch("plyfeat");
    let ascii = "ply\nformat ascii 1.0\ncomment hi\nobj_info x\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\nproperty list uchar int junk\nproperty float s\nproperty float t\nelement edge 1\nproperty int vertex1\nproperty int vertex2\nelement face 1\nproperty list uchar uint vertex_index\nproperty list uchar float texcoord\nend_header\n0 0 0 255 0 0 2 7 8 0 0\n1 0 0 0 255 0 0 1 0\n1 1 0 0 0 255 1 5 1 1\n0 1 0 255 255 255 0 0 1\n0 1\n4 0 1 2 3 8 0 0 1 0 1 1 0 1\n";
    let p = dir.join("a.ply");
    std::fs::write(&p, ascii).unwrap();
    let m = io::load(&p).unwrap();
    assert_eq!(m.faces, vec![[0, 1, 2], [0, 2, 3]]);
    assert_eq!(m.colors.as_ref().unwrap()[1], [0.0, 1.0, 0.0]);
    assert_eq!(
        m.uvs.as_ref().unwrap()[5],
        [0.0, 1.0],
        "per-face texcoord wins"
    );
    // Big-endian binary with double coordinates, ushort list counts, short indices and a strip.
    let mut b = b"ply\r\nformat binary_big_endian 1.0\r\nelement vertex 4\r\nproperty double x\r\nproperty double y\r\nproperty double z\r\nelement tristrips 1\r\nproperty list ushort short vertex_indices\r\nend_header\r\n".to_vec();
    for v in [
        [0.0f64, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [1.0, 1.0, 0.0],
    ] {
        for c in v {
            b.extend(c.to_be_bytes());
        }
    }
    let strip: [i16; 7] = [0, 1, 2, 3, -1, 3, 3];
    b.extend((strip.len() as u16).to_be_bytes());
    for s in strip {
        b.extend(s.to_be_bytes());
    }
    let p = dir.join("be.ply");
    std::fs::write(&p, &b).unwrap();
    let m = io::load(&p).unwrap();
    assert_eq!(
        m.faces,
        vec![[0, 1, 2], [2, 1, 3]],
        "odd strip triangles flip winding"
    );
    assert_eq!(m.positions[3], [1.0, 1.0, 0.0]);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn gltf_node_transforms_strips_and_colours() {
    use serde_json::json;
    // One triangle strip quad, placed twice: node 0 translated, node 1 (child) mirrored in x.
    let mut bin = Vec::new();
    for p in [
        [0.0f32, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [1.0, 1.0, 0.0],
    ] {
        for c in p {
            bin.extend(c.to_le_bytes());
        }
    }
    for c in [
        [255u8, 0, 0, 255],
        [0, 255, 0, 255],
        [0, 0, 255, 255],
        [188, 188, 188, 255],
    ] {
        bin.extend(c);
    }
    for i in [0u16, 1, 2, 3] {
        bin.extend(i.to_le_bytes());
    }
    let doc = json!({
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [
            {"mesh": 0, "translation": [10.0, 0.0, 0.0], "children": [1]},
            {"mesh": 0, "scale": [-1.0, 1.0, 1.0]}
        ],
        "meshes": [{"primitives": [
            {"attributes": {"POSITION": 0, "COLOR_0": 1}, "indices": 2, "mode": 5, "material": 0},
            {"attributes": {"POSITION": 0}, "mode": 0}
        ]}],
        // An image with no mimeType whose bytes are not an image: a warning, no texture.
        "materials": [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}],
        "textures": [{"source": 0}],
        "images": [{"bufferView": 2}],
        "buffers": [{"byteLength": bin.len(), "uri": format!("data:application/octet-stream;base64,{}", b64(&bin))}],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": 48},
            {"buffer": 0, "byteOffset": 48, "byteLength": 16},
            {"buffer": 0, "byteOffset": 64, "byteLength": 8}
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [0,0,0], "max": [1,1,0]},
            {"bufferView": 1, "componentType": 5121, "normalized": true, "count": 4, "type": "VEC4"},
            {"bufferView": 2, "componentType": 5123, "count": 4, "type": "SCALAR"}
        ]
    });
    let dir = scratch("gltffeat");
    let p = dir.join("t.gltf");
    std::fs::write(&p, serde_json::to_vec(&doc).unwrap()).unwrap();
    let m = io::load(&p).unwrap();
    assert_eq!(
        m.num_vertices(),
        8,
        "points primitive skipped, two instances"
    );
    assert_eq!(m.positions[1], [11.0, 0.0, 0.0]);
    assert_eq!(
        m.positions[5],
        [9.0, 0.0, 0.0],
        "child inherits the parent transform"
    );
    assert_eq!(m.faces[..2], [[0, 1, 2], [2, 1, 3]]);
    // The mirrored instance flips winding back so its faces stay counter-clockwise.
    assert_eq!(m.faces[2..], [[4, 6, 5], [6, 7, 5]]);
    assert!(m.texture.is_none());
    let c = m.colors.as_ref().unwrap();
    assert!((c[0][0] - 1.0).abs() < 1e-6 && c[0][1] == 0.0 && c[0][2] == 0.0);
    // 188/255 linear is about 0.737 -> sRGB about 0.874
    assert!((c[3][0] - meshmatch::color::linear_to_srgb(188.0 / 255.0)).abs() < 1e-6);
    let _ = std::fs::remove_dir_all(&dir);
}

fn b64(data: &[u8]) -> String {
    const A: &[u8] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut s = String::new();
    for ch in data.chunks(3) {
        let v = (ch[0] as u32) << 16
            | (*ch.get(1).unwrap_or(&0) as u32) << 8
            | *ch.get(2).unwrap_or(&0) as u32;
        for i in 0..4 {
            if i <= ch.len() {
                s.push(A[(v >> (18 - 6 * i) & 63) as usize] as char);
            } else {
                s.push('=');
            }
        }
    }
    s
}

#[test]
fn per_vertex_uvs_go_to_ply_vertex_properties_and_jpeg_textures_load() {
    let mut cow = load("cow/cow.ply");
    let uvs: Vec<[f32; 2]> = cow
        .faces
        .iter()
        .flat_map(|f| {
            f.map(|v| {
                let p = cow.positions[v as usize];
                [p[0] * 0.1 + 0.5, p[1] * 0.1 + 0.5]
            })
        })
        .collect();
    cow.uvs = Some(uvs);
    let tex = io::load_texture(&data_path("textures/1.jpg")).unwrap();
    assert!(tex.image.width() > 0 && tex.path.is_some());
    cow.texture = Some(std::sync::Arc::new(tex));
    let dir = scratch("pvuv");
    let p = dir.join("cow_uv.ply");
    io::save(&cow, &p).unwrap();
    let bytes = std::fs::read(&p).unwrap();
    let header = String::from_utf8_lossy(&bytes[..400]);
    assert!(
        header.contains("property float s\nproperty float t\n"),
        "{header}"
    );
    assert!(!header.contains("texcoord"));
    assert!(header.contains("comment TextureFile cow_uv_texture.png"));
    assert!(dir.join("cow_uv_texture.png").is_file());
    let _ = std::fs::remove_dir_all(&dir);
    round_trip_all(&cow, "cow_uv");
    // OBJ colours written as 0..255 integers are scaled to 0..1.
    let dir = scratch("obj255");
    let p = dir.join("c.obj");
    std::fs::write(
        &p,
        "v 0 0 0 255 0 0\nv 1 0 0 0 128 0\nv 0 1 0 0 0 51\nf 1 2 3\n",
    )
    .unwrap();
    let m = io::load(&p).unwrap();
    assert_eq!(m.colors.unwrap()[2], [0.0, 0.0, 0.2]);
    let _ = std::fs::remove_dir_all(&dir);
}

/// A GLB container around a JSON document and a BIN chunk.
fn glb(doc: &serde_json::Value, bin: &[u8]) -> Vec<u8> {
    let mut js = serde_json::to_vec(doc).unwrap();
    while !js.len().is_multiple_of(4) {
        js.push(b' ');
    }
    let mut bin = bin.to_vec();
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
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
    out.extend(&bin);
    out
}

#[test]
fn sparse_positions_instanced_by_many_nodes_are_refused_by_the_vertex_budget() {
    use serde_json::json;
    // A 1M-vertex sparse POSITION accessor with no bufferView (all zeros but one), instanced by
    // 100 nodes: 100M vertices from a file of a few KB. Refused before any vertex is allocated.
    let mut bin = Vec::new();
    bin.extend(0u32.to_le_bytes());
    for c in [1.0f32, 2.0, 3.0] {
        bin.extend(c.to_le_bytes());
    }
    let doc = |count: usize, nodes: usize| {
        json!({
            "asset": {"version": "2.0"},
            "scene": 0,
            "scenes": [{"nodes": (0..nodes).collect::<Vec<_>>()}],
            "nodes": (0..nodes).map(|_| json!({"mesh": 0})).collect::<Vec<_>>(),
            "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
            "buffers": [{"byteLength": 16}],
            "bufferViews": [
                {"buffer": 0, "byteOffset": 0, "byteLength": 4},
                {"buffer": 0, "byteOffset": 4, "byteLength": 12}
            ],
            "accessors": [{
                "componentType": 5126, "count": count, "type": "VEC3",
                "sparse": {"count": 1,
                    "indices": {"bufferView": 0, "componentType": 5125},
                    "values": {"bufferView": 1}}
            }]
        })
    };
    let dir = scratch("sparsebomb");
    let p = dir.join("bomb.glb");
    std::fs::write(&p, glb(&doc(1_000_000, 100), &bin)).unwrap();
    // Refused from the declared counts (the message names the instanced total), before anything
    // is allocated.
    let msg = expect_err(&p, "exceed the budget of 20000000");
    assert!(msg.contains("100000000 vertices"), "{msg}");
    // The same accessor used by 3 nodes is fine: read once, instanced three times.
    let p = dir.join("three.glb");
    std::fs::write(&p, glb(&doc(6, 3), &bin)).unwrap();
    let m = io::load(&p).unwrap();
    assert_eq!(m.num_vertices(), 18);
    assert_eq!(m.positions[0], [1.0, 2.0, 3.0]);
    assert_eq!(m.positions[12], [1.0, 2.0, 3.0]);
    assert_eq!(m.num_faces(), 6);
    // A bufferView-backed accessor (within the budget) whose count does not fit its view.
    let mut d = doc(6, 1);
    d["accessors"][0] =
        json!({"bufferView": 1, "componentType": 5126, "count": 1_000_000, "type": "VEC3"});
    let p = dir.join("count.glb");
    std::fs::write(&p, glb(&d, &bin)).unwrap();
    expect_err(&p, "do not fit in buffer view 1");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn external_references_must_be_regular_files() {
    use serde_json::json;
    let dir = scratch("devices");
    // glTF buffers that are devices or a directory: refused, one line.
    for (name, uri) in [
        ("zero.gltf", "/dev/zero"),
        ("null.gltf", "/dev/null"),
        ("dir.gltf", "."),
    ] {
        let p = dir.join(name);
        let doc = json!({"asset": {"version": "2.0"}, "buffers": [{"byteLength": 4, "uri": uri}]});
        std::fs::write(&p, serde_json::to_vec(&doc).unwrap()).unwrap();
        let msg = expect_err(&p, "cannot read buffer/image");
        assert!(
            msg.contains("not a regular file") || msg.contains("a directory"),
            "{msg}"
        );
    }
    // A PLY whose TextureFile is a device: loads, without texture (a warning, not a hang).
    let p = dir.join("zerotex.ply");
    std::fs::write(
        &p,
        "ply\nformat ascii 1.0\ncomment TextureFile /dev/zero\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nproperty float s\nproperty float t\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0 0 0\n1 0 0 1 0\n0 1 0 0 1\n3 0 1 2\n",
    )
    .unwrap();
    let (m, warnings) = io::load_with_warnings(&p).unwrap();
    assert!(m.texture.is_none());
    assert_eq!(warnings.len(), 1, "{warnings:?}");
    assert!(warnings[0].contains("not a regular file"), "{warnings:?}");
    // The mesh file itself: a link to a device, a directory.
    let link = dir.join("zero.obj");
    std::os::unix::fs::symlink("/dev/zero", &link).unwrap();
    expect_err(&link, "not a regular file");
    let sub = dir.join("sub.ply");
    std::fs::create_dir_all(&sub).unwrap();
    expect_err(&sub, "is a directory");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn obj_with_200k_materials_loads() {
    let mut s = String::from("v 0 0 0\nv 1 0 0\nv 0 1 0\n");
    for i in 0..200_000 {
        s.push_str(&format!("usemtl m{i}\nf 1 2 3\n"));
    }
    let dir = scratch("mats");
    let p = dir.join("mats.obj");
    std::fs::write(&p, s).unwrap();
    // (Quadratic in the material count, this took over a minute; a set keeps it linear.)
    let m = io::load(&p).unwrap();
    assert_eq!(m.num_faces(), 200_000);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn obj_without_usemtl_takes_the_first_textured_material_of_the_mtl() {
    let dir = scratch("nousemtl");
    image::RgbImage::new(2, 2).save(dir.join("a.png")).unwrap();
    image::RgbImage::new(3, 3).save(dir.join("b.png")).unwrap();
    std::fs::write(
        dir.join("two.mtl"),
        "newmtl ma\nmap_Kd a.png\nnewmtl mb\nmap_Kd b.png\nnewmtl mc\nmap_Kd b.png\nnewmtl md\nmap_Kd b.png\n",
    )
    .unwrap();
    let p = dir.join("two.obj");
    std::fs::write(
        &p,
        "mtllib two.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nf 1/1 2/2 3/3\n",
    )
    .unwrap();
    // Hash order differs between maps in one process: 20 loads would disagree if it decided.
    for _ in 0..20 {
        let (m, warnings) = io::load_with_warnings(&p).unwrap();
        assert_eq!(
            m.texture.as_ref().unwrap().image.width(),
            2,
            "ma (a.png) is first"
        );
        assert!(
            warnings.iter().all(|w| w.contains("'a.png' is used")),
            "{warnings:?}"
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn obj_and_mtl_with_classic_mac_line_endings_load() {
    let dir = scratch("cr");
    image::RgbImage::new(2, 2).save(dir.join("t.png")).unwrap();
    std::fs::write(dir.join("m.mtl"), "newmtl m\rmap_Kd t.png\r").unwrap();
    let p = dir.join("cr.obj");
    std::fs::write(
        &p,
        "mtllib m.mtl\rv 0 0 0\rv 1 0 0\rv 0 1 0\rv 1 1 0\rvt 0 0\rusemtl m\rf 1/1 2/1 3/1\r\nf 2/1 4/1 3/1\r",
    )
    .unwrap();
    let m = io::load(&p).unwrap();
    assert_eq!(m.num_vertices(), 4);
    assert_eq!(m.faces, vec![[0, 1, 2], [1, 3, 2]]);
    assert!(m.texture.is_some());
    // Line numbers in errors count CR, LF and CRLF lines alike.
    let p = dir.join("crbad.obj");
    std::fs::write(&p, "v 0 0 0\rv 1 0 0\r\nv 0 1 0\nf 1 2 9\r").unwrap();
    expect_err(&p, "line 4");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn glb_bin_chunk_is_shared_by_its_buffers() {
    use serde_json::json;
    let dir = scratch("glbshare");
    // 3000 buffers on one 4 MB BIN chunk: borrowed, not copied 3000 times (12 GB).
    let mut bin = vec![0u8; 4 << 20];
    for (i, c) in [0.0f32, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0]
        .iter()
        .enumerate()
    {
        bin[4 * i..4 * i + 4].copy_from_slice(&c.to_le_bytes());
    }
    let doc = json!({
        "asset": {"version": "2.0"},
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
        "buffers": (0..3000).map(|_| json!({"byteLength": 4 << 20})).collect::<Vec<_>>(),
        "bufferViews": [{"buffer": 2999, "byteOffset": 0, "byteLength": 36}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3"}]
    });
    let p = dir.join("shared.glb");
    std::fs::write(&p, glb(&doc, &bin)).unwrap();
    // 3000 copies of the 4 MiB chunk would be 12 GiB; shared, it loads at once.
    let m = io::load(&p).unwrap();
    assert_eq!(m.num_faces(), 1);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn repair_reports_counts_and_keeps_the_map_to_file_indices() {
    let dir = scratch("repair");
    let p = dir.join("repair.obj");
    // Vertex 1 is unused; face 2 duplicates face 1 (other winding); face 4 is degenerate.
    std::fs::write(
        &p,
        "v 9 9 9\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 2 3 4\nf 3 2 4\nf 3 5 4\nf 2 2 3\n",
    )
    .unwrap();
    let mut m = io::load(&p).unwrap();
    let before = m.validate();
    assert_eq!(
        (
            before.degenerate_faces,
            before.duplicate_faces,
            before.isolated_vertices
        ),
        (1, 1, 1)
    );
    let rep = m.repair().unwrap();
    assert_eq!(rep.degenerate_faces_removed, 1);
    assert_eq!(rep.duplicate_faces_removed, 1);
    assert_eq!(rep.unreferenced_vertices_removed, 1);
    assert_eq!(rep.non_finite_faces_removed, 0);
    assert_eq!(m.file_index, vec![1, 2, 3, 4]);
    assert_eq!(m.file_vertex_count, 5);
    assert_eq!(m.faces, vec![[0, 1, 2], [1, 3, 2]]);
    assert_eq!(m.positions[0], [0.0, 0.0, 0.0]);
    let _ = std::fs::remove_dir_all(&dir);
}

/// A failed export leaves nothing behind: an OBJ's material file and texture (and a PLY's
/// texture) are written with the mesh as one, under temporary names renamed together, so when
/// the mesh itself cannot be written (here its name is taken by a folder) neither sidecar nor
/// temporary remains, and an existing sidecar is not replaced.
#[test]
fn a_failed_export_leaves_no_sidecar_behind() {
    let d = scratch("failed_export");
    let mut m = TriMesh::new(
        vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
        vec![[0, 1, 2]],
    );
    m.uvs = Some(vec![[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]);
    m.texture = Some(std::sync::Arc::new(meshmatch::mesh::Texture {
        image: image::RgbImage::from_pixel(4, 4, image::Rgb([200, 10, 10])),
        path: None,
    }));
    let listing = || {
        let mut v: Vec<String> = std::fs::read_dir(&d)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    };
    for name in ["o.obj", "p.ply"] {
        std::fs::create_dir_all(d.join(name)).unwrap();
    }
    std::fs::write(d.join("o_texture.png"), b"old").unwrap();
    assert!(io::save(&m, &d.join("o.obj")).is_err());
    assert!(io::save(&m, &d.join("p.ply")).is_err());
    assert_eq!(listing(), ["o.obj", "o_texture.png", "p.ply"]);
    assert_eq!(std::fs::read(d.join("o_texture.png")).unwrap(), b"old");
    // and a successful one writes all three
    io::save(&m, &d.join("ok.obj")).unwrap();
    assert_eq!(
        listing(),
        [
            "o.obj",
            "o_texture.png",
            "ok.mtl",
            "ok.obj",
            "ok_texture.png",
            "p.ply"
        ]
    );
}

#[test]
fn colours_that_are_not_numbers_load_as_black_with_the_files_name() {
    // A broken exporter's NaN or infinite colours would reach a weathering's PCA or a transfer's
    // patch distances and fail there, far from the file: they load as black, said once.
    let dir = scratch("nan-colours");
    let p = dir.join("nan.ply");
    std::fs::write(
        &p,
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nproperty float red\nproperty float green\nproperty float blue\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0 0.5 0.5 0.5\n1 0 0 nan 0.2 0.3\n0 1 0 inf 1 1\n3 0 1 2\n",
    )
    .unwrap();
    let (m, warnings) = io::load_with_warnings(&p).unwrap();
    let colors = m.colors.as_ref().expect("the file's colours are kept");
    assert!(colors.iter().flatten().all(|c| c.is_finite()));
    assert_eq!(colors[1], [0.0; 3]);
    assert_eq!(colors[2], [0.0; 3]);
    assert!((colors[0][0] - 0.5).abs() < 1e-6, "{colors:?}");
    assert_eq!(warnings.len(), 1, "{warnings:?}");
    assert!(
        warnings[0].contains("nan.ply") && warnings[0].contains("2 vertex colours"),
        "{warnings:?}"
    );
}
