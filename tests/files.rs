//! Files other tools read as they were meant: smooth normals on every mesh output, `.gltf` with
//! its buffer and texture beside it, correspondences that survive renumbered vertices, required
//! glTF extensions refused by name, quilted OBJs as separate objects (tests/quilting.rs).

use meshmatch::TriMesh;
use meshmatch::correspondence::{Correspondence, CorrespondenceFile, Side};
use meshmatch::mesh::io;
use meshmatch::testdata::data_path;
mod scratch;
use scratch::Scratch;

/// A self-deleting scratch folder for one test.
fn scratch(name: &str) -> Scratch {
    Scratch::new(&format!("files-{name}"))
}

/// The unit cube, corner 0 at the origin: 8 vertices, 12 outward triangles, no normals.
fn cube() -> TriMesh {
    let (p, f) = meshmatch::testdata::cuboid(1.0, 1.0, 1.0);
    TriMesh::new(p, f)
}

/// A UV sphere of radius 1 about the origin, without normals.
fn sphere(rings: usize, segs: usize) -> TriMesh {
    let (p, f) = meshmatch::testdata::uv_sphere(rings, segs);
    TriMesh::new(p, f)
}

fn unit(n: [f32; 3]) -> bool {
    ((n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt() - 1.0).abs() < 1e-4
}

#[test]
fn every_mesh_output_carries_smooth_normals_split_at_sharp_edges() {
    let dir = scratch("normals");
    for ext in ["ply", "obj", "glb", "gltf"] {
        // The sphere: smooth, one normal per vertex, pointing outward.
        let s = sphere(12, 24);
        let p = dir.join(format!("sphere.{ext}"));
        io::save(&s, &p).unwrap();
        let back = io::load(&p).unwrap();
        let n = back
            .normals
            .as_ref()
            .unwrap_or_else(|| panic!("{ext}: no normals"));
        assert_eq!(
            back.num_vertices(),
            s.num_vertices(),
            "{ext}: a smooth mesh is not split"
        );
        for (i, (q, v)) in back.positions.iter().zip(n).enumerate() {
            assert!(unit(*v), "{ext}: normal {i} not unit: {v:?}");
            let d = q[0] * v[0] + q[1] * v[1] + q[2] * v[2];
            assert!(d > 0.9, "{ext}: normal {i} points inward ({d})");
        }
        // The cube: every normal unit and axis-aligned; corner 0 has 3 distinct ones in GLB and
        // glTF (vertex copies) and in OBJ (`vn` per corner).
        let c = cube();
        let p = dir.join(format!("cube.{ext}"));
        io::save(&c, &p).unwrap();
        let back = io::load(&p).unwrap();
        let n = back
            .normals
            .as_ref()
            .unwrap_or_else(|| panic!("{ext}: no normals"));
        assert!(n.iter().all(|v| unit(*v)), "{ext}: {n:?}");
        assert_eq!(
            &back.positions[..8],
            &c.positions[..],
            "{ext}: file order kept"
        );
        match ext {
            "glb" | "gltf" => {
                assert_eq!(back.num_vertices(), 24, "{ext}: 3 copies per corner");
                let mut at_origin: Vec<[f32; 3]> = back
                    .positions
                    .iter()
                    .zip(n)
                    .filter(|(q, _)| **q == [0.0; 3])
                    .map(|(_, v)| *v)
                    .collect();
                at_origin.sort_by(|a, b| a.partial_cmp(b).unwrap());
                at_origin.dedup();
                assert_eq!(at_origin.len(), 3, "{ext}: {at_origin:?}");
                for v in &at_origin {
                    assert!(v.iter().filter(|x| x.abs() > 0.999).count() == 1, "{v:?}");
                }
            }
            "obj" => {
                let text = std::fs::read_to_string(&p).unwrap();
                let vn: Vec<&str> = text.lines().filter(|l| l.starts_with("vn ")).collect();
                assert_eq!(vn.len(), 6, "one vn per face direction");
                let mut used: Vec<&str> = text
                    .lines()
                    .filter(|l| l.starts_with("f "))
                    .flat_map(|l| l.split_whitespace().skip(1))
                    .filter_map(|c| c.strip_prefix("1//"))
                    .collect();
                used.sort();
                used.dedup();
                assert_eq!(used.len(), 3, "corner 1 refers to 3 normals: {used:?}");
            }
            _ => {
                // PLY: one (area-weighted) normal per vertex, the cube's diagonal at corner 0.
                let v = n[0];
                assert!(v.iter().all(|x| *x < -0.5), "{v:?}");
            }
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_mesh_with_its_own_normals_keeps_them() {
    let dir = scratch("own_normals");
    let mut c = cube();
    c.normals = Some(vec![[0.0, 1.0, 0.0]; 8]);
    for ext in ["ply", "obj", "glb", "gltf"] {
        let p = dir.join(format!("cube.{ext}"));
        io::save(&c, &p).unwrap();
        let back = io::load(&p).unwrap();
        assert_eq!(back.num_vertices(), 8, "{ext}");
        assert!(
            back.normals.unwrap().iter().all(|n| *n == [0.0, 1.0, 0.0]),
            "{ext}"
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn gltf_is_written_with_its_buffer_and_texture_beside_it() {
    let dir = scratch("gltf");
    let mut spot = io::load(&data_path("spot/spot.obj")).unwrap();
    spot.colors = spot.vertex_signal();
    let glb = dir.join("spot.glb");
    let gltf = dir.join("spot.gltf");
    io::save(&spot, &glb).unwrap();
    io::save(&spot, &gltf).unwrap();
    assert!(dir.join("spot.bin").is_file());
    assert!(dir.join("spot_texture.png").is_file());
    let json: serde_json::Value = serde_json::from_slice(&std::fs::read(&gltf).unwrap()).unwrap();
    assert_eq!(json["buffers"][0]["uri"], "spot.bin");
    assert_eq!(json["images"][0]["uri"], "spot_texture.png");
    // The gltf crate's own importer validates the document and reads the files beside it.
    let (doc, buffers, images) = gltf::import(&gltf).unwrap();
    assert_eq!(buffers.len(), 1);
    assert_eq!(images.len(), 1);
    let prim = doc.meshes().next().unwrap().primitives().next().unwrap();
    assert!(prim.get(&gltf::Semantic::Normals).is_some());
    gltf::import(&glb).unwrap();
    // The project's loader: the same mesh from both.
    let a = io::load(&glb).unwrap();
    let b = io::load(&gltf).unwrap();
    assert_eq!(a.positions, b.positions);
    assert_eq!(a.faces, b.faces);
    assert_eq!(a.uvs, b.uvs);
    assert_eq!(a.normals, b.normals);
    assert_eq!(a.colors, b.colors);
    assert!(a.texture.as_ref().unwrap().image == b.texture.as_ref().unwrap().image);
    assert_eq!(a.num_vertices(), spot.num_vertices().max(a.num_vertices()));

    // (A failed command inside a group of staged writes leaving none of the three files is
    // checked in tests/staged_writes.rs: the group is process-wide, so it cannot open here
    // beside tests writing files in parallel.)
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn the_cli_writes_gltf_where_it_writes_glb() {
    let dir = scratch("cli_gltf");
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_meshmatch"))
        .args(["swatch", "--kind", "studs", "--out"])
        .arg(dir.join("studs.gltf"))
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let m = io::load(&dir.join("studs.gltf")).unwrap();
    assert!(m.num_faces() > 0 && m.normals.is_some());
    assert!(dir.join("studs.bin").is_file());
    let _ = std::fs::remove_dir_all(&dir);
}

/// A one-triangle glTF whose accessors hold no data, requiring `ext`.
fn requiring(ext: &str) -> serde_json::Value {
    serde_json::json!({
        "asset": {"version": "2.0"},
        "extensionsUsed": [ext],
        "extensionsRequired": [ext],
        "meshes": [{"primitives": [{
            "attributes": {"POSITION": 0},
            "indices": 1,
            "extensions": {ext: {"bufferView": 0, "attributes": {"POSITION": 0}}}
        }]}],
        "accessors": [
            {"componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]},
            {"componentType": 5123, "count": 3, "type": "SCALAR"}
        ],
        "buffers": [{"byteLength": 4, "uri": "data:application/octet-stream;base64,AAAAAA=="}],
        "bufferViews": [{"buffer": 0, "byteLength": 4}],
        "nodes": [{"mesh": 0}],
        "scenes": [{"nodes": [0]}],
        "scene": 0
    })
}

#[test]
fn required_extensions_that_cannot_be_read_are_refused_by_name() {
    let dir = scratch("extensions");
    let cases = [
        (
            "KHR_draco_mesh_compression",
            "uses KHR_draco_mesh_compression (Draco-compressed geometry), which meshmatch cannot \
             read; re-export without compression",
        ),
        (
            "EXT_meshopt_compression",
            "uses EXT_meshopt_compression (meshoptimizer-compressed buffers), which meshmatch \
             cannot read; re-export without compression",
        ),
        (
            "KHR_mesh_quantization",
            "uses KHR_mesh_quantization (quantized vertex attributes), which meshmatch cannot \
             read; re-export without quantization",
        ),
        (
            "VENDOR_unknown",
            "uses VENDOR_unknown (a required glTF extension), which meshmatch cannot read; \
             re-export without it",
        ),
    ];
    for (ext, want) in cases {
        let doc = requiring(ext);
        let p = dir.join("x.gltf");
        std::fs::write(&p, serde_json::to_vec(&doc).unwrap()).unwrap();
        let e = io::load(&p).unwrap_err().to_string();
        assert_eq!(e, format!("{}: {want}", p.display()));
        // As a GLB, through the CLI: one line, exit code 2.
        let g = dir.join("x.glb");
        let mut js = serde_json::to_vec(&doc).unwrap();
        while !js.len().is_multiple_of(4) {
            js.push(b' ');
        }
        let mut b = b"glTF".to_vec();
        b.extend(2u32.to_le_bytes());
        b.extend(((12 + 8 + js.len()) as u32).to_le_bytes());
        b.extend((js.len() as u32).to_le_bytes());
        b.extend(b"JSON");
        b.extend(&js);
        std::fs::write(&g, &b).unwrap();
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_meshmatch"))
            .arg("info")
            .arg(&g)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{err}");
        assert_eq!(err.lines().count(), 1, "{err}");
        assert!(err.contains(want), "{err}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

fn pairs() -> Vec<Correspondence> {
    (0..12)
        .map(|i| Correspondence {
            source_vertex: 10 * i,
            target_vertices: vec![10 * i + 3],
        })
        .collect()
}

#[test]
fn correspondence_files_without_positions_still_load() {
    let dir = scratch("corr_old");
    let p = dir.join("old.json");
    std::fs::write(
        &p,
        r#"{"correspondences": [
            {"source_vertex": 12, "target_vertices": [40]},
            {"source_vertex": 97, "target_vertices": [31, 50, 87]}
        ]}"#,
    )
    .unwrap();
    let mut f = CorrespondenceFile::load(&p).unwrap();
    assert!(f.positions.is_empty());
    assert_eq!(f.correspondences[1].target_vertices, vec![31, 50, 87]);
    // Without stored positions nothing moves, whatever the meshes.
    let s = sphere(12, 24);
    assert_eq!(f.resolve(Some(&s), Some(&s), &p), None);
    assert_eq!(f.correspondences[0].source_vertex, 12);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn correspondences_follow_their_stored_positions_onto_renumbered_meshes() {
    let dir = scratch("corr_moved");
    let source = sphere(12, 24);
    let target = sphere(14, 20);
    let file = CorrespondenceFile::with_positions(pairs(), &source, &target);
    let p = dir.join("pairs.json");
    file.save(&p).unwrap();
    let text = std::fs::read_to_string(&p).unwrap();
    assert!(text.contains("source_position") && text.contains("target_positions"));
    let back = CorrespondenceFile::load(&p).unwrap();
    assert_eq!(back, file);
    // Unchanged meshes: nothing moves, no warning.
    let mut same = back.clone();
    assert_eq!(same.resolve(Some(&source), Some(&target), &p), None);
    assert_eq!(same.correspondences, pairs());

    // The target re-exported with 3 vertices inserted at the front: every index is off by 3.
    let mut renumbered = target.clone();
    let extra = [[5.0, 5.0, 5.0], [6.0, 5.0, 5.0], [5.0, 6.0, 5.0]];
    renumbered.positions.splice(0..0, extra);
    for f in &mut renumbered.faces {
        *f = f.map(|v| v + 3);
    }
    renumbered.faces.push([0, 1, 2]);
    renumbered.file_index = (0..renumbered.positions.len() as u32).collect();
    renumbered.file_vertex_count = renumbered.positions.len();
    let mut moved = back.clone();
    let warning = moved.resolve(Some(&source), Some(&renumbered), &p);
    assert_eq!(
        warning.as_deref(),
        Some(
            format!(
                "{}: 12 of 12 correspondences moved to the nearest vertex of their stored position",
                p.display()
            )
            .as_str()
        )
    );
    for (a, b) in moved.correspondences.iter().zip(pairs()) {
        assert_eq!(a.source_vertex, b.source_vertex);
        assert_eq!(a.target_vertices, vec![b.target_vertices[0] + 3]);
    }
    // Some pairs only: an index out of range and one moved far are re-projected, the rest kept.
    let mut some = back.clone();
    let mut cut = source.clone();
    cut.positions.swap(0, 10);
    for f in &mut cut.faces {
        *f = f.map(|v| match v {
            0 => 10,
            10 => 0,
            v => v,
        });
    }
    let w = some.resolve(Some(&cut), None, &p).unwrap();
    assert!(
        w.ends_with("2 of 12 correspondences moved to the nearest vertex of their stored position"),
        "{w}"
    );
    assert_eq!(some.correspondences[0].source_vertex, 10);
    assert_eq!(some.correspondences[1].source_vertex, 0);
    assert_eq!(some.correspondences[2].source_vertex, 20);
    // Resolving one side leaves the other alone.
    let mut t_only = back.clone();
    let moved_t = t_only.resolve_side(Side::Target, &renumbered);
    assert!(moved_t.iter().all(|&m| m));
    assert_eq!(t_only.correspondences[5].source_vertex, 50);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn the_cli_warns_once_when_correspondences_move() {
    let dir = scratch("corr_cli");
    let mesh = sphere(12, 24);
    let file = CorrespondenceFile::with_positions(pairs(), &mesh, &mesh);
    let corr = dir.join("pairs.json");
    file.save(&corr).unwrap();
    let mut renumbered = mesh.clone();
    renumbered
        .positions
        .splice(0..0, [[5.0, 5.0, 5.0], [6.0, 5.0, 5.0], [5.0, 6.0, 5.0]]);
    for f in &mut renumbered.faces {
        *f = f.map(|v| v + 3);
    }
    renumbered.faces.push([0, 1, 2]);
    let m = dir.join("m.ply");
    io::save(&renumbered, &m).unwrap();
    let src = dir.join("s.ply");
    io::save(&mesh, &src).unwrap();
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_meshmatch"))
        .arg("map")
        .arg("--source")
        .arg(&src)
        .arg("--target")
        .arg(&m)
        .arg("--correspondences")
        .arg(&corr)
        .arg("--out")
        .arg(dir.join("map.csv"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    let lines: Vec<&str> = err
        .lines()
        .filter(|l| l.contains("correspondences moved"))
        .collect();
    assert_eq!(lines.len(), 1, "{err}");
    assert!(
        lines[0].contains("12 of 12 correspondences moved to the nearest vertex"),
        "{err}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}
