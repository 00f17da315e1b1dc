//! Writers for quilted geometry: OBJ with one `g element_N` group per element (and optionally
//! the base as group `base`), binary PLY with a per-vertex `int element` property.

use std::fmt::Write as _;
use std::path::Path;

use super::QuiltOutput;
use crate::error::{Error, Result};
use crate::mesh::TriMesh;
use crate::mesh::io::write_atomic;

/// Write `out` as OBJ: vertices, then one group `element_N` per element with its faces; with
/// `base`, its vertices follow and its faces form the group `base`.
pub fn save_quilt_obj(out: &QuiltOutput, base: Option<&TriMesh>, path: &Path) -> Result<()> {
    let m = &out.elements;
    let extra = base.map_or(0, |b| b.num_vertices() + b.num_faces());
    let mut s = String::with_capacity(40 * (m.num_vertices() + m.num_faces() + extra));
    s.push_str("# written by meshmatch (mesh quilting)\n");
    let _ = writeln!(
        s,
        "# {} elements, {} vertices, {} faces",
        out.num_elements(),
        m.num_vertices(),
        m.num_faces()
    );
    for p in &m.positions {
        let _ = writeln!(s, "v {} {} {}", p[0], p[1], p[2]);
    }
    let mut current = u32::MAX;
    for f in &m.faces {
        let e = out.element_id[f[0] as usize];
        if e != current {
            current = e;
            let _ = writeln!(s, "g element_{e}");
        }
        let _ = writeln!(s, "f {} {} {}", f[0] + 1, f[1] + 1, f[2] + 1);
    }
    if let Some(b) = base {
        let off = m.num_vertices() as u32;
        for p in &b.positions {
            let _ = writeln!(s, "v {} {} {}", p[0], p[1], p[2]);
        }
        s.push_str("g base\n");
        for f in &b.faces {
            let _ = writeln!(
                s,
                "f {} {} {}",
                f[0] + off + 1,
                f[1] + off + 1,
                f[2] + off + 1
            );
        }
    }
    write_atomic(path, s.as_bytes())
}

/// Write `out` as binary little-endian PLY with vertex properties `x y z` (float) and
/// `element` (int), and faces as `vertex_indices` lists.
pub fn save_quilt_ply(out: &QuiltOutput, path: &Path) -> Result<()> {
    let m = &out.elements;
    if out.element_id.len() != m.num_vertices() {
        return Err(Error::InvalidInput(
            "quilt output has an element id count different from its vertex count".into(),
        ));
    }
    let header = format!(
        "ply\nformat binary_little_endian 1.0\ncomment written by meshmatch (mesh quilting)\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\nproperty int element\nelement face {}\nproperty list uchar int vertex_indices\nend_header\n",
        m.num_vertices(),
        m.num_faces()
    );
    let mut b = Vec::with_capacity(header.len() + 16 * m.num_vertices() + 13 * m.num_faces());
    b.extend_from_slice(header.as_bytes());
    for (p, &e) in m.positions.iter().zip(&out.element_id) {
        for x in p {
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
