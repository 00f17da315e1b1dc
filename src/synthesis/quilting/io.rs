//! Writers for quilted geometry: OBJ with one object `element_N` per element (and optionally the
//! base as object `base`), so importers such as Blender's make each a separate object; binary PLY
//! with a per-vertex `int element` property. Both carry smooth normals.

use std::fmt::Write as _;
use std::path::Path;

use super::QuiltOutput;
use crate::error::{Error, Result};
use crate::mesh::TriMesh;
use crate::mesh::io::{export_corner_normals, export_vertex_normals, write_atomic};

/// Write `out` as OBJ: every vertex first (the elements', then the base's, in order), then one
/// object `o element_N` per output element with its faces, and with `base` the object `o base`.
/// Faces refer to `vn` normals: smooth, split at sharp edges by angle.
pub fn save_quilt_obj(out: &QuiltOutput, base: Option<&TriMesh>, path: &Path) -> Result<()> {
    let m = &out.elements;
    if out.element_id.len() != m.num_vertices() {
        return Err(Error::InvalidInput(
            "quilt output has an element id count different from its vertex count".into(),
        ));
    }
    let extra = base.map_or(0, |b| b.num_vertices() + b.num_faces());
    let mut s = String::with_capacity(60 * (m.num_vertices() + m.num_faces() + extra));
    s.push_str("# written by meshmatch (mesh quilting)\n");
    let _ = writeln!(
        s,
        "# {} elements, {} vertices, {} faces",
        out.num_elements(),
        m.num_vertices(),
        m.num_faces()
    );
    for p in m
        .positions
        .iter()
        .chain(base.iter().flat_map(|b| &b.positions))
    {
        let _ = writeln!(s, "v {} {} {}", p[0], p[1], p[2]);
    }
    // Normals: one `vn` per distinct corner normal of the elements, then of the base.
    let mut ids: std::collections::HashMap<[u32; 3], u32> = std::collections::HashMap::new();
    let mut vn = |s: &mut String, n: [f32; 3]| -> u32 {
        let next = ids.len() as u32 + 1;
        *ids.entry(n.map(f32::to_bits)).or_insert_with(|| {
            let _ = writeln!(s, "vn {} {} {}", n[0], n[1], n[2]);
            next
        })
    };
    let elem_n: Vec<u32> = export_corner_normals(m)
        .into_iter()
        .map(|n| vn(&mut s, n))
        .collect();
    let base_n: Vec<u32> = base.map_or_else(Vec::new, |b| {
        export_corner_normals(b)
            .into_iter()
            .map(|n| vn(&mut s, n))
            .collect()
    });
    let face = |s: &mut String, f: [u32; 3], off: u32, n: &[u32]| {
        let [a, b, c] = f.map(|v| v + off + 1);
        let _ = writeln!(s, "f {a}//{} {b}//{} {c}//{}", n[0], n[1], n[2]);
    };
    // Faces bucketed by element (each element's faces in file order).
    let mut by_element: Vec<Vec<usize>> = vec![Vec::new(); out.num_elements()];
    for (fi, f) in m.faces.iter().enumerate() {
        let e = out.element_id[f[0] as usize] as usize;
        if e >= by_element.len() {
            by_element.resize(e + 1, Vec::new());
        }
        by_element[e].push(fi);
    }
    for (e, faces) in by_element.iter().enumerate() {
        if faces.is_empty() {
            continue;
        }
        let _ = writeln!(s, "o element_{e}");
        for &fi in faces {
            face(&mut s, m.faces[fi], 0, &elem_n[3 * fi..3 * fi + 3]);
        }
    }
    if let Some(b) = base {
        let off = m.num_vertices() as u32;
        s.push_str("o base\n");
        for (fi, &f) in b.faces.iter().enumerate() {
            face(&mut s, f, off, &base_n[3 * fi..3 * fi + 3]);
        }
    }
    write_atomic(path, s.as_bytes())
}

/// Write `out` as binary little-endian PLY with vertex properties `x y z`, `nx ny nz` (float,
/// area-weighted vertex normals) and `element` (int), and faces as `vertex_indices` lists.
pub fn save_quilt_ply(out: &QuiltOutput, path: &Path) -> Result<()> {
    let m = &out.elements;
    if out.element_id.len() != m.num_vertices() {
        return Err(Error::InvalidInput(
            "quilt output has an element id count different from its vertex count".into(),
        ));
    }
    let header = format!(
        "ply\nformat binary_little_endian 1.0\ncomment written by meshmatch (mesh quilting)\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\nproperty float nx\nproperty float ny\nproperty float nz\nproperty int element\nelement face {}\nproperty list uchar int vertex_indices\nend_header\n",
        m.num_vertices(),
        m.num_faces()
    );
    let mut b = Vec::with_capacity(header.len() + 28 * m.num_vertices() + 13 * m.num_faces());
    b.extend_from_slice(header.as_bytes());
    let normals = export_vertex_normals(m);
    for ((p, n), &e) in m.positions.iter().zip(&normals).zip(&out.element_id) {
        for x in p.iter().chain(n) {
            b.extend_from_slice(&x.to_le_bytes());
        }
        b.extend_from_slice(&(e as i32).to_le_bytes());
    }
    for f in &m.faces {
        b.push(3);
        for &v in f {
            b.extend_from_slice(&(v as i32).to_le_bytes());
        }
    }
    write_atomic(path, &b)
}
