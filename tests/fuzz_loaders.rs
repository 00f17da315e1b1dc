//! Property-based fuzzing of the mesh loaders: real files mutated (bit flips, byte inserts and
//! deletes, truncation, numbers in glTF JSON replaced), glTF structure edited (many nodes
//! instancing a mesh, many buffers on the BIN chunk, sparse accessors without buffer view, huge
//! counts, device and directory URIs, node cycles) and random ASCII PLY / OBJ text. Every
//! input must give `Ok` with a consistent mesh or `Err` with a one-line message naming the
//! file, never a panic. `PROPTEST_CASES=20000` runs a long campaign.

mod scratch;
use scratch::Scratch;

use meshmatch::TriMesh;
use meshmatch::mesh::io;
use meshmatch::testdata::data_path;
use proptest::prelude::*;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// Load `bytes` as `name` (its extension picks the loader) and check the outcome.
fn check(bytes: &[u8], name: &str) {
    // A directory that does not exist: relative textures/MTL/buffers resolve to nothing.
    let path = PathBuf::from("/nonexistent-meshmatch-fuzz").join(name);
    let r = std::panic::catch_unwind(|| io::load_bytes(bytes, &path));
    match r {
        Err(_) => panic!("loader panicked on {} bytes as {name}", bytes.len()),
        Ok(Ok(m)) => check_mesh(&m, name),
        Ok(Err(e)) => {
            let msg = e.to_string();
            assert!(msg.contains(name), "message does not name the file: {msg}");
            assert!(!msg.contains('\n'), "multi-line message: {msg}");
        }
    }
}

fn check_mesh(m: &TriMesh, name: &str) {
    let n = m.num_vertices();
    assert!(
        m.faces.iter().flatten().all(|&v| (v as usize) < n),
        "{name}: face index out of range"
    );
    if let Some(uv) = &m.uvs {
        assert_eq!(uv.len(), 3 * m.num_faces(), "{name}: uvs");
    }
    if let Some(c) = &m.colors {
        assert_eq!(c.len(), n, "{name}: colors");
    }
    if let Some(nr) = &m.normals {
        assert_eq!(nr.len(), n, "{name}: normals");
    }
    assert_eq!(m.file_index.len(), n);
    assert_eq!(m.file_vertex_count, n);
    // The rest of the pipeline must also cope without panicking.
    let _ = m.validate();
    let mut r = m.clone();
    let _ = r.repair();
}

/// Seed files: real meshes plus exports made by this crate (small texture to keep cases fast).
struct Seeds {
    cow_ply: Vec<u8>,
    strips_ply: Vec<u8>,
    ascii_ply: Vec<u8>,
    obj: Vec<u8>,
    glb: Vec<u8>,
    gltf: Vec<u8>,
}

fn seeds() -> &'static Seeds {
    static S: OnceLock<Seeds> = OnceLock::new();
    S.get_or_init(|| {
        let read = |rel: &str| std::fs::read(data_path(rel)).unwrap();
        let dir = Scratch::new("fuzz");
        // A small textured, coloured mesh with UV seams: a cube-ish fan cut from the cow.
        let mut m = io::load(&data_path("cow/cow.ply")).unwrap();
        m.faces.truncate(300);
        let pos = m.positions.clone();
        m.uvs = Some(
            m.faces
                .iter()
                .enumerate()
                .flat_map(|(f, face)| {
                    let p = &pos;
                    face.map(|v| [p[v as usize][0] + (f % 3) as f32, p[v as usize][1]])
                })
                .collect(),
        );
        m.colors = Some(pos.iter().map(|p| [p[0].fract().abs(), 0.5, 0.25]).collect());
        m.texture = Some(std::sync::Arc::new(meshmatch::mesh::Texture {
            image: image::RgbImage::from_fn(8, 8, |x, y| image::Rgb([x as u8 * 30, y as u8 * 30, 7])),
            path: None,
        }));
        let glb = dir.join("small.glb");
        io::save(&m, &glb).unwrap();
        let gltf = dir.join("small.gltf");
        io::save(&m, &gltf).unwrap();
        let obj = dir.join("small.obj");
        m.texture = None;
        io::save(&m, &obj).unwrap();
        let spot_head: Vec<u8> = {
            // first part of Spot (mtllib, v, vt, f lines) keeps cases fast
            let s = read("spot/spot.obj");
            let text = String::from_utf8(s).unwrap();
            text.lines()
                .filter(|l| !l.starts_with("f ") || l.len() % 7 == 0)
                .take(4000)
                .collect::<Vec<_>>()
                .join("\n")
                .into_bytes()
        };
        let mut obj_bytes = std::fs::read(&obj).unwrap();
        obj_bytes.extend(b"\n");
        let cut = spot_head[..20000].iter().rposition(|&b| b == b'\n').unwrap();
        obj_bytes.extend(&spot_head[..cut]);
        let ascii_ply = b"ply\nformat ascii 1.0\ncomment TextureFile t.png\nelement vertex 5\nproperty float x\nproperty float y\nproperty float z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\nproperty float s\nproperty float t\nelement face 3\nproperty list uchar int vertex_indices\nproperty list uchar float texcoord\nelement tristrips 1\nproperty list int int vertex_indices\nend_header\n0 0 0 1 2 3 0 0\n1 0 0 4 5 6 1 0\n1 1 0 7 8 9 1 1\n0 1 0 1 1 1 0 1\n2 2 2 0 0 0 .5 .5\n3 0 1 2 6 0 0 1 0 1 1\n4 0 1 2 3 0\n3 2 3 4 6 1 1 0 1 .5 .5\n7 0 1 2 -1 2 3 4\n".to_vec();
        let s = Seeds {
            cow_ply: read("cow/cow.ply"),
            strips_ply: read("robustness/cow_tristrips.ply"),
            ascii_ply,
            obj: obj_bytes,
            glb: std::fs::read(&glb).unwrap(),
            gltf: self_contained(&gltf),
        };
        let _ = std::fs::remove_dir_all(&dir);
        s
    })
}

/// One byte-level mutation; positions are fractions of the length so they fit any file.
#[derive(Clone, Debug)]
enum Mutation {
    Flip(f64, u8),
    Set(f64, u8),
    Insert(f64, Vec<u8>),
    Delete(f64, usize),
    Truncate(f64),
    /// Mutate inside the first 600 bytes (headers) where most of the structure lives.
    HeaderSet(usize, u8),
}

fn mutation() -> impl Strategy<Value = Mutation> {
    let interesting = prop_oneof![
        any::<u8>(),
        Just(b'0'),
        Just(b'9'),
        Just(b'-'),
        Just(b' '),
        Just(b'\n'),
        Just(0xFF),
        Just(0),
    ];
    prop_oneof![
        (0.0..1.0f64, 0..8u8).prop_map(|(p, b)| Mutation::Flip(p, b)),
        (0.0..1.0f64, interesting.clone()).prop_map(|(p, b)| Mutation::Set(p, b)),
        (0.0..1.0f64, proptest::collection::vec(any::<u8>(), 1..8))
            .prop_map(|(p, v)| Mutation::Insert(p, v)),
        (0.0..1.0f64, 1..64usize).prop_map(|(p, n)| Mutation::Delete(p, n)),
        (0.0..1.0f64).prop_map(Mutation::Truncate),
        (0..600usize, interesting).prop_map(|(p, b)| Mutation::HeaderSet(p, b)),
    ]
}

fn apply(bytes: &[u8], muts: &[Mutation]) -> Vec<u8> {
    let mut b = bytes.to_vec();
    for m in muts {
        let at = |f: f64, len: usize| ((f * len as f64) as usize).min(len.saturating_sub(1));
        if b.is_empty() {
            break;
        }
        match m {
            Mutation::Flip(p, bit) => {
                let i = at(*p, b.len());
                b[i] ^= 1 << bit;
            }
            Mutation::Set(p, v) => {
                let i = at(*p, b.len());
                b[i] = *v;
            }
            Mutation::Insert(p, v) => {
                let i = at(*p, b.len());
                b.splice(i..i, v.iter().copied());
            }
            Mutation::Delete(p, n) => {
                let i = at(*p, b.len());
                let e = (i + n).min(b.len());
                b.drain(i..e);
            }
            Mutation::Truncate(p) => {
                let i = at(*p, b.len());
                b.truncate(i);
            }
            Mutation::HeaderSet(i, v) => {
                if *i < b.len() {
                    b[*i] = *v;
                }
            }
        }
    }
    b
}

/// Replace some numbers in a GLB's JSON chunk and rebuild a container with consistent lengths,
/// so the corruption reaches accessor/buffer-view validation instead of the container check.
fn mutate_glb_json(glb: &[u8], picks: &[(f64, u64)]) -> Vec<u8> {
    let json_len = u32::from_le_bytes(glb[12..16].try_into().unwrap()) as usize;
    let json = &glb[20..20 + json_len];
    let bin = &glb[20 + json_len..];
    let text = String::from_utf8_lossy(json).into_owned();
    let mut spans = Vec::new();
    let tb = text.as_bytes();
    let mut i = 0;
    while i < tb.len() {
        if tb[i].is_ascii_digit() {
            let s = i;
            while i < tb.len() && tb[i].is_ascii_digit() {
                i += 1;
            }
            spans.push((s, i));
        } else {
            i += 1;
        }
    }
    let mut chosen: Vec<(usize, usize, u64)> = picks
        .iter()
        .map(|&(f, v)| {
            let k = ((f * spans.len() as f64) as usize).min(spans.len() - 1);
            (spans[k].0, spans[k].1, v)
        })
        .collect();
    chosen.sort_by_key(|c| std::cmp::Reverse(c.0));
    chosen.dedup_by_key(|c| c.0);
    let mut t = text;
    for (s, e, v) in chosen {
        t.replace_range(s..e, &v.to_string());
    }
    glb_bytes(t.into_bytes(), bin)
}

/// A structural change to a glTF document (the kind of input byte mutations rarely reach).
#[derive(Clone, Debug)]
enum GltfEdit {
    /// Add `n` nodes instancing mesh 0 to scene 0.
    Nodes(usize),
    /// Add `n` buffers without uri (all on the GLB BIN chunk).
    BinBuffers(usize),
    /// Make accessor `a` (fraction of the list) sparse with no bufferView and `count` elements.
    Sparse(f64, u64),
    /// Set accessor `a`'s count.
    Count(f64, u64),
    /// Add a buffer whose uri is one of a few hostile paths.
    UriBuffer(usize),
    /// Set the first primitive's mode.
    Mode(u64),
    /// Make node `a` a child of node `b` (fractions), possibly a cycle.
    Child(f64, f64),
}

fn gltf_edit() -> impl Strategy<Value = GltfEdit> {
    let count = prop_oneof![
        Just(0u64),
        Just(3),
        1..1000u64,
        Just(20_000),
        Just(20_000_001),
        Just(u32::MAX as u64),
        Just(u64::MAX),
    ];
    prop_oneof![
        (1..200usize).prop_map(GltfEdit::Nodes),
        (1..3000usize).prop_map(GltfEdit::BinBuffers),
        (0.0..1.0f64, count.clone()).prop_map(|(a, c)| GltfEdit::Sparse(a, c)),
        (0.0..1.0f64, count).prop_map(|(a, c)| GltfEdit::Count(a, c)),
        (0..6usize).prop_map(GltfEdit::UriBuffer),
        (0..9u64).prop_map(GltfEdit::Mode),
        (0.0..1.0f64, 0.0..1.0f64).prop_map(|(a, b)| GltfEdit::Child(a, b)),
    ]
}

/// Apply structural edits to a GLB's JSON and rebuild the container around the same BIN chunk.
fn edit_glb(glb: &[u8], edits: &[GltfEdit]) -> Vec<u8> {
    use serde_json::{Value, json};
    let json_len = u32::from_le_bytes(glb[12..16].try_into().unwrap()) as usize;
    let mut doc: Value = serde_json::from_slice(&glb[20..20 + json_len]).unwrap();
    let bin = &glb[20 + json_len..];
    let bin_len = u32::from_le_bytes(bin[0..4].try_into().unwrap());
    let pick = |f: f64, n: usize| ((f * n as f64) as usize).min(n.saturating_sub(1));
    for e in edits {
        match e {
            GltfEdit::Nodes(n) => {
                for _ in 0..*n {
                    let nodes = doc["nodes"].as_array_mut().unwrap();
                    nodes.push(json!({"mesh": 0}));
                    let k = nodes.len() - 1;
                    doc["scenes"][0]["nodes"]
                        .as_array_mut()
                        .unwrap()
                        .push(json!(k));
                }
            }
            GltfEdit::BinBuffers(n) => {
                let b = doc["buffers"].as_array_mut().unwrap();
                b.extend((0..*n).map(|_| json!({"byteLength": bin_len})));
                let last = b.len() - 1;
                if let Some(v) = doc["bufferViews"].as_array_mut().unwrap().last_mut() {
                    v["buffer"] = json!(last);
                }
            }
            GltfEdit::Sparse(a, count) => {
                let accs = doc["accessors"].as_array_mut().unwrap();
                let k = pick(*a, accs.len());
                let acc = &mut accs[k];
                acc.as_object_mut().unwrap().remove("bufferView");
                acc["count"] = json!(count);
                acc["sparse"] = json!({"count": 1,
                    "indices": {"bufferView": 0, "componentType": 5125},
                    "values": {"bufferView": 0}});
            }
            GltfEdit::Count(a, count) => {
                let accs = doc["accessors"].as_array_mut().unwrap();
                let k = pick(*a, accs.len());
                accs[k]["count"] = json!(count);
            }
            GltfEdit::UriBuffer(u) => {
                let uri = ["/dev/zero", "/dev/null", ".", "..", "missing.bin", "data:,"][*u];
                doc["buffers"]
                    .as_array_mut()
                    .unwrap()
                    .push(json!({"byteLength": 4, "uri": uri}));
            }
            GltfEdit::Mode(m) => {
                doc["meshes"][0]["primitives"][0]["mode"] = json!(m);
            }
            GltfEdit::Child(a, b) => {
                let n = doc["nodes"].as_array().unwrap().len();
                let (a, b) = (pick(*a, n), pick(*b, n));
                let node = &mut doc["nodes"][b];
                if node.get("children").is_none() {
                    node["children"] = json!([]);
                }
                node["children"].as_array_mut().unwrap().push(json!(a));
            }
        }
    }
    glb_bytes(serde_json::to_vec(&doc).unwrap(), bin)
}

/// Random ASCII PLY: header from a vocabulary of elements/properties/types, body of numbers
/// and junk tokens.
fn ascii_ply() -> impl Strategy<Value = String> {
    let ty = prop_oneof![
        Just("char"),
        Just("uchar"),
        Just("short"),
        Just("ushort"),
        Just("int"),
        Just("uint"),
        Just("float"),
        Just("double"),
        Just("int8"),
        Just("uint32"),
        Just("float64"),
        Just("bogus")
    ];
    let pname = prop_oneof![
        Just("x"),
        Just("y"),
        Just("z"),
        Just("nx"),
        Just("red"),
        Just("green"),
        Just("blue"),
        Just("s"),
        Just("t"),
        Just("u"),
        Just("vertex_indices"),
        Just("vertex_index"),
        Just("texcoord"),
        Just("other"),
    ];
    let prop = (any::<bool>(), ty.clone(), ty, pname).prop_map(|(list, t1, t2, n)| {
        if list {
            format!("property list {t1} {t2} {n}")
        } else {
            format!("property {t1} {n}")
        }
    });
    let ename = prop_oneof![
        Just("vertex"),
        Just("face"),
        Just("tristrips"),
        Just("edge"),
        Just("material")
    ];
    let count = prop_oneof![0..6u64, Just(u32::MAX as u64), Just(999_999_999_999u64)];
    let element = (ename, count, proptest::collection::vec(prop, 0..6)).prop_map(|(e, c, ps)| {
        let mut s = format!("element {e} {c}\n");
        for p in ps {
            s.push_str(&p);
            s.push('\n');
        }
        s
    });
    let token = prop_oneof![
        (0..10i32).prop_map(|v| v.to_string()),
        (-3..3i32).prop_map(|v| v.to_string()),
        any::<f32>().prop_map(|v| v.to_string()),
        Just("nan".to_string()),
        Just("inf".to_string()),
        Just("1e300".to_string()),
        Just("4294967295".to_string()),
        Just("abc".to_string()),
        Just("\n".to_string()),
    ];
    (
        proptest::collection::vec(element, 0..5),
        proptest::collection::vec(token, 0..80),
        any::<bool>(),
    )
        .prop_map(|(els, toks, fmt)| {
            let mut s = String::from("ply\n");
            s.push_str(if fmt {
                "format ascii 1.0\n"
            } else {
                "format binary_little_endian 1.0\n"
            });
            for e in els {
                s.push_str(&e);
            }
            s.push_str("end_header\n");
            s.push_str(&toks.join(" "));
            s
        })
}

/// Random OBJ text from a vocabulary of statements with valid and invalid arguments.
fn obj_text() -> impl Strategy<Value = String> {
    let num = prop_oneof![
        (-5.0..5.0f32).prop_map(|v| v.to_string()),
        Just("nan".to_string()),
        Just("-inf".to_string()),
        Just("1e40".to_string()),
        Just("x".to_string()),
    ];
    let idx = prop_oneof![
        (1..8i64).prop_map(|v| v.to_string()),
        (-8..0i64).prop_map(|v| v.to_string()),
        Just("0".to_string()),
        Just("99999999999".to_string()),
        Just("".to_string()),
        Just("q".to_string()),
    ];
    let corner = (idx.clone(), idx.clone(), idx, 0..5u8).prop_map(|(a, b, c, form)| match form {
        0 => a,
        1 => format!("{a}/{b}"),
        2 => format!("{a}//{c}"),
        3 => format!("{a}/{b}/{c}"),
        _ => format!("{a}/{b}/{c}/{a}"),
    });
    let line = prop_oneof![
        4 => proptest::collection::vec(num.clone(), 0..8).prop_map(|v| format!("v {}", v.join(" "))),
        2 => proptest::collection::vec(num.clone(), 0..3).prop_map(|v| format!("vt {}", v.join(" "))),
        1 => proptest::collection::vec(num, 0..4).prop_map(|v| format!("vn {}", v.join(" "))),
        4 => proptest::collection::vec(corner, 0..6).prop_map(|v| format!("f {}", v.join(" "))),
        1 => Just("mtllib nothing.mtl".to_string()),
        1 => Just("usemtl m".to_string()),
        1 => Just("g group".to_string()),
        1 => Just("# comment".to_string()),
        1 => Just("l 1 2".to_string()),
    ];
    proptest::collection::vec(line, 0..40).prop_map(|l| l.join("\n"))
}

proptest! {
    #[test]
    fn mutated_binary_ply(muts in proptest::collection::vec(mutation(), 1..6), strips in any::<bool>()) {
        let s = seeds();
        let seed = if strips { &s.strips_ply } else { &s.cow_ply };
        check(&apply(seed, &muts), "mutated.ply");
    }

    #[test]
    fn mutated_ascii_ply(muts in proptest::collection::vec(mutation(), 1..6)) {
        check(&apply(&seeds().ascii_ply, &muts), "mutated_ascii.ply");
    }

    #[test]
    fn mutated_obj(muts in proptest::collection::vec(mutation(), 1..6)) {
        check(&apply(&seeds().obj, &muts), "mutated.obj");
    }

    #[test]
    fn mutated_glb(muts in proptest::collection::vec(mutation(), 1..6), gltf in any::<bool>()) {
        let s = seeds();
        if gltf {
            check(&apply(&s.gltf, &muts), "mutated.gltf");
        } else {
            check(&apply(&s.glb, &muts), "mutated.glb");
        }
    }

    #[test]
    fn glb_json_numbers_replaced(
        picks in proptest::collection::vec(
            (0.0..1.0f64, prop_oneof![0..16u64, 0..100_000u64, Just(u32::MAX as u64), Just(u64::MAX)]),
            1..4,
        )
    ) {
        check(&mutate_glb_json(&seeds().glb, &picks), "numbers.glb");
    }

    #[test]
    fn glb_structure_edited(edits in proptest::collection::vec(gltf_edit(), 1..5)) {
        check(&edit_glb(&seeds().glb, &edits), "edited.glb");
    }

    #[test]
    fn random_ascii_ply(text in ascii_ply()) {
        check(text.as_bytes(), "random.ply");
    }

    #[test]
    fn random_obj(text in obj_text()) {
        check(text.as_bytes(), "random.obj");
    }
}

#[test]
fn seeds_load_unmutated() {
    let s = seeds();
    for (b, n) in [
        (&s.cow_ply, "a.ply"),
        (&s.strips_ply, "b.ply"),
        (&s.ascii_ply, "c.ply"),
        (&s.obj, "d.obj"),
        (&s.glb, "e.glb"),
        (&s.gltf, "f.gltf"),
    ] {
        let m = io::load_bytes(b, Path::new(n)).unwrap_or_else(|e| panic!("{n}: {e}"));
        assert!(m.num_faces() > 0, "{n}");
        check_mesh(&m, n);
    }
}

/// A written `.gltf` with its buffer and image files inlined as base64 data URIs, so its bytes
/// load on their own (the fuzz cases parse bytes, with no files beside them).
fn self_contained(path: &Path) -> Vec<u8> {
    let mut js: serde_json::Value = serde_json::from_slice(&std::fs::read(path).unwrap()).unwrap();
    let dir = path.parent().unwrap();
    for (key, mime) in [
        ("buffers", "application/octet-stream"),
        ("images", "image/png"),
    ] {
        if let Some(list) = js.get_mut(key).and_then(|v| v.as_array_mut()) {
            for item in list {
                if let Some(uri) = item.get("uri").and_then(|u| u.as_str()) {
                    let bytes = std::fs::read(dir.join(uri)).unwrap();
                    item["uri"] = format!("data:{mime};base64,{}", base64(&bytes)).into();
                }
            }
        }
    }
    serde_json::to_vec(&js).unwrap()
}

/// Standard base64 with padding.
fn base64(bytes: &[u8]) -> String {
    const T: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for c in bytes.chunks(3) {
        let n = (c[0] as u32) << 16
            | (*c.get(1).unwrap_or(&0) as u32) << 8
            | *c.get(2).unwrap_or(&0) as u32;
        for k in 0..4 {
            if k <= c.len() {
                out.push(T[(n >> (18 - 6 * k) & 63) as usize] as char);
            } else {
                out.push('=');
            }
        }
    }
    out
}

/// A GLB container: the header and the JSON chunk (space-padded to 4 bytes), then `bin` as it
/// is (already chunked, or whatever the mutation made of it).
fn glb_bytes(mut js: Vec<u8>, bin: &[u8]) -> Vec<u8> {
    while !js.len().is_multiple_of(4) {
        js.push(b' ');
    }
    let mut out = Vec::new();
    out.extend(b"glTF");
    out.extend(2u32.to_le_bytes());
    out.extend(((12 + 8 + js.len() + bin.len()) as u32).to_le_bytes());
    out.extend((js.len() as u32).to_le_bytes());
    out.extend(b"JSON");
    out.extend(&js);
    out.extend(bin);
    out
}
