//! Wavefront OBJ reader/writer (hand-written) with MTL `map_Kd` textures.

use super::{check_content, check_exportable, fan, finish, text_lines, warn, write_atomic_all};
use crate::error::{Error, Result};
use crate::mesh::TriMesh;
use crate::mesh::validate::{MAX_FACES, MAX_VERTICES};
use std::collections::{HashMap, HashSet};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Options for `save_obj`.
#[derive(Clone, Debug)]
pub struct ObjOptions {
    /// Write `vn` lines and `f v/t/n` references: the mesh's own normals, else smooth normals
    /// split at sharp edges by angle, one `vn` per distinct corner normal.
    pub normals: bool,
    /// Write `r g b` after `v x y z` when the mesh has vertex colours.
    pub vertex_colors: bool,
}

impl Default for ObjOptions {
    fn default() -> Self {
        ObjOptions {
            normals: true,
            vertex_colors: true,
        }
    }
}

const NONE: u32 = u32::MAX;

/// The largest forward (positive) reference seen for one kind of index, with its line.
#[derive(Default)]
struct MaxRef {
    index: u64,
    line: usize,
}

impl MaxRef {
    fn note(&mut self, index: u64, line: usize) {
        if index > self.index {
            self.index = index;
            self.line = line;
        }
    }
    fn check(&self, count: usize, what: &str, path: &Path) -> Result<()> {
        if self.index > count as u64 {
            return Err(Error::format(
                path,
                format!(
                    "line {}: {what} index {} out of range (the file has {count} {what} entries)",
                    self.line, self.index
                ),
            ));
        }
        Ok(())
    }
}

/// Resolve an OBJ index token (1-based, or negative = relative to the entries so far) to 0-based.
fn resolve(
    tok: &str,
    count: usize,
    line: usize,
    what: &str,
    max: &mut MaxRef,
    path: &Path,
) -> Result<u32> {
    let v: i64 = tok.parse().map_err(|_| {
        Error::format(
            path,
            format!("line {line}: bad {what} index '{}'", clip(tok)),
        )
    })?;
    if v > 0 {
        if v > u32::MAX as i64 {
            return Err(Error::format(
                path,
                format!("line {line}: {what} index {v} out of range"),
            ));
        }
        max.note(v as u64, line);
        Ok((v - 1) as u32)
    } else if v < 0 {
        let r = count as i64 + v;
        if r < 0 {
            return Err(Error::format(
                path,
                format!(
                    "line {line}: relative {what} index {v} out of range (only {count} so far)"
                ),
            ));
        }
        Ok(r as u32)
    } else {
        Err(Error::format(
            path,
            format!("line {line}: {what} index 0 (OBJ indices start at 1)"),
        ))
    }
}

/// A token shortened for messages.
fn clip(s: &str) -> String {
    s.chars().take(40).collect()
}

fn parse_f32(tok: Option<&str>, line: usize, what: &str, path: &Path) -> Result<f32> {
    parse_number(tok, line, what, path)
}

/// A coordinate at the file's precision (rounded to single precision by `finish`).
fn parse_f64(tok: Option<&str>, line: usize, what: &str, path: &Path) -> Result<f64> {
    parse_number(tok, line, what, path)
}

fn parse_number<T: std::str::FromStr>(
    tok: Option<&str>,
    line: usize,
    what: &str,
    path: &Path,
) -> Result<T> {
    let tok = tok.ok_or_else(|| Error::format(path, format!("line {line}: {what} is missing")))?;
    tok.parse::<T>().map_err(|_| {
        Error::format(
            path,
            format!("line {line}: {what} is not a number: '{}'", clip(tok)),
        )
    })
}

/// Parse OBJ bytes; `path` names the file in messages and locates MTL files and textures.
/// At most [`MAX_VERTICES`] vertices and [`MAX_FACES`] triangles.
///
/// The steps: [`read_line`] per line (vertices, texture coordinates, normals, faces through
/// [`read_face`], material libraries and names), [`check_references`] (forward references
/// within the file, degenerate faces), then [`assemble`] (colours, UVs, averaged normals,
/// texture).
pub fn load_obj_bytes(bytes: &[u8], path: &Path) -> Result<TriMesh> {
    load_obj_bytes_exact(bytes, path).map(|(m, _)| m)
}

/// [`load_obj_bytes`], with the file's coordinates in double precision too.
pub(super) fn load_obj_bytes_exact(bytes: &[u8], path: &Path) -> Result<(TriMesh, Vec<[f64; 3]>)> {
    check_content(bytes, super::MeshFormat::Obj, path)?;
    let mut data = ObjData::default();
    // Lines end in \n, \r\n or a lone \r (files from classic Mac OS tools).
    for (li, raw) in text_lines(bytes).enumerate() {
        read_line(&mut data, raw, li + 1, path)?;
    }
    check_references(&data, path)?;
    let raw = std::mem::take(&mut data.pos);
    let mesh = assemble(data, raw.len(), path);
    finish(mesh, raw, path)
}

/// What the lines of an OBJ file have given so far.
#[derive(Default)]
struct ObjData {
    /// Positions at the file's precision.
    pos: Vec<[f64; 3]>,
    cols: Vec<[f32; 3]>,
    tex: Vec<[f32; 2]>,
    nrm: Vec<[f32; 3]>,
    faces: Vec<[u32; 3]>,
    /// Per triangle corner, its texture coordinate (or `NONE`).
    corner_vt: Vec<u32>,
    /// Per triangle corner, its normal (or `NONE`).
    corner_vn: Vec<u32>,
    max_v: MaxRef,
    max_vt: MaxRef,
    max_vn: MaxRef,
    mtllibs: Vec<String>,
    /// Materials used by faces, in order of first use (the set makes the check O(1)).
    used_materials: Vec<String>,
    used_set: HashSet<String>,
    current_mtl: Option<String>,
    /// Faces of fewer than three corners, skipped.
    short_faces: usize,
    /// The corners `[v, vt, vn]` of the face being read.
    poly: Vec<[u32; 3]>,
}

/// One line of the file (comments stripped): a `v`, `vt`, `vn`, `f`, `mtllib` or `usemtl`
/// statement; other statements are not part of a triangle mesh.
fn read_line(d: &mut ObjData, raw: &[u8], line_no: usize, path: &Path) -> Result<()> {
    let text = String::from_utf8_lossy(raw);
    let text = text.split('#').next().unwrap_or("");
    let mut toks = text.split_ascii_whitespace();
    let Some(key) = toks.next() else {
        return Ok(());
    };
    match key {
        "v" => {
            let x = parse_f64(toks.next(), line_no, "x coordinate", path)?;
            let y = parse_f64(toks.next(), line_no, "y coordinate", path)?;
            let z = parse_f64(toks.next(), line_no, "z coordinate", path)?;
            let rest: Vec<&str> = toks.collect();
            // v x y z [w] or v x y z r g b [a]
            if rest.len() >= 3 {
                let mut c = [0.0f32; 3];
                for k in 0..3 {
                    c[k] = parse_f32(Some(rest[k]), line_no, "vertex colour", path)?;
                }
                if d.cols.len() == d.pos.len() {
                    d.cols.push(c);
                }
            } else if let Some(w) = rest.first() {
                parse_f32(Some(w), line_no, "w coordinate", path)?;
            }
            d.pos.push([x, y, z]);
            if d.pos.len() > MAX_VERTICES {
                return Err(Error::format(
                    path,
                    format!("line {line_no}: more than {MAX_VERTICES} vertices (the budget)"),
                ));
            }
        }
        "vt" => {
            let u = parse_f32(toks.next(), line_no, "u coordinate", path)?;
            let v = match toks.next() {
                Some(t) => parse_f32(Some(t), line_no, "v coordinate", path)?,
                None => 0.0,
            };
            d.tex.push([u, v]);
        }
        "vn" => {
            let x = parse_f32(toks.next(), line_no, "normal x", path)?;
            let y = parse_f32(toks.next(), line_no, "normal y", path)?;
            let z = parse_f32(toks.next(), line_no, "normal z", path)?;
            d.nrm.push([x, y, z]);
        }
        "f" | "fo" => read_face(d, toks, line_no, path)?,
        "mtllib" => {
            let rest = text.trim_start()[6..].trim();
            if !rest.is_empty() {
                d.mtllibs.push(rest.to_string());
            }
        }
        "usemtl" => {
            let rest = text.trim_start()[6..].trim();
            d.current_mtl = (!rest.is_empty()).then(|| rest.to_string());
        }
        _ => {} // o, g, s, l, p, curves: not part of a triangle mesh
    }
    Ok(())
}

/// An `f` statement: its corners `v[/vt[/vn]]` resolved, the polygon fanned into triangles
/// (a face of fewer than three corners is counted and skipped), its material noted as used.
fn read_face(
    d: &mut ObjData,
    toks: std::str::SplitAsciiWhitespace,
    line_no: usize,
    path: &Path,
) -> Result<()> {
    d.poly.clear();
    for tok in toks {
        let mut parts = tok.split('/');
        let v = parts.next().unwrap_or("");
        let vi = resolve(v, d.pos.len(), line_no, "vertex", &mut d.max_v, path)?;
        let vt = match parts.next() {
            Some(t) if !t.is_empty() => resolve(
                t,
                d.tex.len(),
                line_no,
                "texture coordinate",
                &mut d.max_vt,
                path,
            )?,
            _ => NONE,
        };
        let vn = match parts.next() {
            Some(t) if !t.is_empty() => {
                resolve(t, d.nrm.len(), line_no, "normal", &mut d.max_vn, path)?
            }
            _ => NONE,
        };
        if parts.next().is_some() {
            return Err(Error::format(
                path,
                format!("line {line_no}: bad face corner '{}'", clip(tok)),
            ));
        }
        d.poly.push([vi, vt, vn]);
    }
    if d.poly.len() < 3 {
        d.short_faces += 1;
        return Ok(());
    }
    if let Some(m) = &d.current_mtl
        && d.used_materials.last() != Some(m)
        && d.used_set.insert(m.clone())
    {
        d.used_materials.push(m.clone());
    }
    if d.faces.len() + d.poly.len() > MAX_FACES + 2 {
        return Err(Error::format(
            path,
            format!("line {line_no}: more than {MAX_FACES} triangles (the budget)"),
        ));
    }
    let (poly, faces) = (&d.poly, &mut d.faces);
    let (corner_vt, corner_vn) = (&mut d.corner_vt, &mut d.corner_vn);
    fan(poly.len(), |a, b, c| {
        faces.push([poly[a][0], poly[b][0], poly[c][0]]);
        for k in [a, b, c] {
            corner_vt.push(poly[k][1]);
            corner_vn.push(poly[k][2]);
        }
    });
    Ok(())
}

/// Every forward reference within the file's entries, and some faces unless all were
/// degenerate (a warning counts the skipped ones).
fn check_references(d: &ObjData, path: &Path) -> Result<()> {
    d.max_v.check(d.pos.len(), "vertex", path)?;
    d.max_vt.check(d.tex.len(), "texture coordinate", path)?;
    d.max_vn.check(d.nrm.len(), "normal", path)?;
    let short_faces = d.short_faces;
    if short_faces > 0 && d.faces.is_empty() {
        return Err(Error::format(
            path,
            format!(
                "{} degenerate (fewer than 3 vertices)",
                crate::mesh::all_faces(short_faces)
            ),
        ));
    }
    if short_faces > 0 {
        warn(format!(
            "{}: skipped {short_faces} faces with fewer than 3 vertices",
            path.display()
        ));
    }
    Ok(())
}

/// The mesh: vertex colours where every vertex has one (0..255 scaled to 0..1), per-corner UVs,
/// per-vertex normals averaged from the corners', and the texture of the materials used; `n`
/// vertices, whose positions [`finish`] sets.
fn assemble(d: ObjData, n: usize, path: &Path) -> TriMesh {
    let ObjData {
        mut cols,
        tex,
        nrm,
        faces,
        corner_vt,
        corner_vn,
        mtllibs,
        used_materials,
        ..
    } = d;
    let mut mesh = TriMesh {
        faces,
        ..Default::default()
    };
    if cols.len() == n && n > 0 {
        // Some writers use 0..255 colours; scale those to 0..1.
        let max = cols
            .iter()
            .flatten()
            .fold(0.0f32, |m, &c| if c.is_finite() { m.max(c) } else { m });
        if max > 1.0 {
            cols.iter_mut().flatten().for_each(|c| *c /= 255.0);
        }
        mesh.colors = Some(cols);
    }
    if corner_vt.iter().any(|&t| t != NONE) {
        mesh.uvs = Some(
            corner_vt
                .iter()
                .map(|&t| if t == NONE { [0.0; 2] } else { tex[t as usize] })
                .collect(),
        );
    }
    if !corner_vn.is_empty() && corner_vn.iter().all(|&t| t != NONE) {
        mesh.normals = average_corner_normals(&mesh.faces, n, &corner_vn, &nrm);
    }
    if !used_materials.is_empty() || !mtllibs.is_empty() {
        mesh.texture = find_texture(&mtllibs, &used_materials, path);
    }
    mesh
}

/// OBJ normals are per corner: per vertex the average of its unit corner normals, if every
/// vertex has one.
fn average_corner_normals(
    faces: &[[u32; 3]],
    n: usize,
    corner_vn: &[u32],
    nrm: &[[f32; 3]],
) -> Option<Vec<[f32; 3]>> {
    let mut acc = vec![[0.0f32; 3]; n];
    let mut seen = vec![false; n];
    for (c, &t) in corner_vn.iter().enumerate() {
        let v = faces[c / 3][c % 3] as usize;
        let nv = glam::Vec3::from(nrm[t as usize]).normalize_or_zero();
        acc[v] = (glam::Vec3::from(acc[v]) + nv).into();
        seen[v] = true;
    }
    seen.iter().all(|&s| s).then(|| {
        acc.into_iter()
            .map(|a| glam::Vec3::from(a).normalize_or_zero().into())
            .collect()
    })
}

/// Resolve a file name written in an MTL/OBJ file relative to `dir`, trying the whole string,
/// then with backslashes as separators, then its trailing tokens (after `map_Kd` options).
fn resolve_file(dir: &Path, name: &str) -> Option<PathBuf> {
    let try_one = |n: &str| {
        let p = dir.join(n);
        p.is_file().then_some(p)
    };
    if let Some(p) = try_one(name).or_else(|| try_one(&name.replace('\\', "/"))) {
        return Some(p);
    }
    let toks: Vec<&str> = name.split_ascii_whitespace().collect();
    (0..toks.len())
        .rev()
        .find_map(|i| try_one(&toks[i..].join(" ")))
}

/// The texture of the first used material (in face order) whose MTL entry has `map_Kd`.
fn find_texture(
    mtllibs: &[String],
    used: &[String],
    path: &Path,
) -> Option<std::sync::Arc<crate::mesh::Texture>> {
    let dir = path.parent().unwrap_or(Path::new("."));
    // material name -> (map_Kd value, MTL directory); textured material names in file order.
    let mut maps: HashMap<String, (String, PathBuf)> = HashMap::new();
    let mut file_order: Vec<String> = Vec::new();
    for lib in mtllibs {
        let candidates: Vec<String> = if resolve_file(dir, lib).is_some() {
            vec![lib.clone()]
        } else {
            lib.split_ascii_whitespace().map(str::to_string).collect()
        };
        for name in candidates {
            let Some(mtl_path) = resolve_file(dir, &name) else {
                warn(format!(
                    "{}: material library '{}' not found; continuing without it",
                    path.display(),
                    clip(&name)
                ));
                continue;
            };
            let text = match super::read_regular_file(
                &mtl_path,
                super::MAX_FILE_BYTES,
                "the material library",
            ) {
                Ok(t) => t,
                Err(e) => {
                    warn(format!("{}: cannot read ({e})", mtl_path.display()));
                    continue;
                }
            };
            let text = String::from_utf8_lossy(&text);
            let mtl_dir = mtl_path.parent().unwrap_or(Path::new(".")).to_path_buf();
            let mut cur: Option<String> = None;
            for line in text_lines(text.as_bytes()) {
                let line = String::from_utf8_lossy(line);
                let t = line.trim();
                let (key, rest) = t.split_once(char::is_whitespace).unwrap_or((t, ""));
                match key {
                    "newmtl" => cur = Some(rest.trim().to_string()),
                    "map_Kd" | "map_kd" => {
                        if let Some(m) = &cur
                            && !maps.contains_key(m)
                        {
                            maps.insert(m.clone(), (rest.trim().to_string(), mtl_dir.clone()));
                            file_order.push(m.clone());
                        }
                    }
                    _ => {}
                }
            }
        }
    }
    // Materials in face order; with no usemtl at all, the first textured material of the MTL
    // files (in file order) applies, so the choice never depends on hash order.
    let order: Vec<&String> = if used.is_empty() {
        file_order.iter().collect()
    } else {
        used.iter().collect()
    };
    let textured: Vec<&(String, PathBuf)> = order.iter().filter_map(|m| maps.get(*m)).collect();
    let (name, mtl_dir) = textured.first()?;
    if textured.iter().any(|t| t.0 != *name) {
        warn(format!(
            "{}: several textured materials; only '{}' is used",
            path.display(),
            clip(name)
        ));
    }
    match resolve_file(mtl_dir, name) {
        Some(p) => super::load_texture_or_warn(&p, path),
        None => {
            warn(format!(
                "{}: texture '{}' not found; continuing without texture",
                path.display(),
                clip(name)
            ));
            None
        }
    }
}

/// Write an OBJ (+ `<stem>.mtl` + `<stem>_texture.png` when the mesh has a texture) keeping the
/// vertex order; texture coordinates and normals (see [`ObjOptions::normals`]) are deduplicated
/// per distinct corner value.
pub fn save_obj(mesh: &TriMesh, path: &Path, opts: &ObjOptions) -> Result<()> {
    check_exportable(mesh, path)?;
    let mut s = String::with_capacity(64 * (mesh.num_vertices() + mesh.num_faces()));
    s.push_str("# written by meshmatch\n");
    // The OBJ, its material file and its texture are written as one (no sidecar is left
    // behind by a failed export).
    let texture = super::texture_beside(mesh, path)?;
    let mut sidecars: Vec<(std::path::PathBuf, Vec<u8>)> = Vec::new();
    if let Some((tex_name, tex_path, png)) = texture {
        let stem = path
            .file_stem()
            .map(|x| x.to_string_lossy().into_owned())
            .unwrap_or_else(|| "mesh".into());
        let mtl_name = format!("{stem}.mtl");
        let mtl = format!(
            "# written by meshmatch\nnewmtl material0\nKa 0 0 0\nKd 1 1 1\nKs 0 0 0\nillum 1\nmap_Kd {tex_name}\n"
        );
        sidecars.push((path.with_file_name(&mtl_name), mtl.into_bytes()));
        sidecars.push((tex_path, png));
        let _ = writeln!(s, "mtllib {mtl_name}\nusemtl material0");
    }
    let colors = mesh.colors.as_ref().filter(|_| opts.vertex_colors);
    for (i, p) in mesh.positions.iter().enumerate() {
        let _ = write!(s, "v {} {} {}", p[0], p[1], p[2]);
        if let Some(c) = colors {
            let c = c[i];
            let _ = write!(s, " {} {} {}", c[0], c[1], c[2]);
        }
        s.push('\n');
    }
    let mut corner_t: Vec<u32> = Vec::new();
    if let Some(uvs) = &mesh.uvs {
        let mut ids: HashMap<[u32; 2], u32> = HashMap::new();
        corner_t.reserve(uvs.len());
        for uv in uvs {
            let key = uv.map(f32::to_bits);
            let next = ids.len() as u32;
            let id = *ids.entry(key).or_insert_with(|| {
                let _ = writeln!(s, "vt {} {}", uv[0], uv[1]);
                next
            });
            corner_t.push(id + 1);
        }
    }
    let mut corner_n: Vec<u32> = Vec::new();
    if opts.normals {
        let cn = super::export_corner_normals(mesh);
        let mut ids: HashMap<[u32; 3], u32> = HashMap::new();
        corner_n.reserve(cn.len());
        for n in &cn {
            let key = n.map(f32::to_bits);
            let next = ids.len() as u32;
            let id = *ids.entry(key).or_insert_with(|| {
                let _ = writeln!(s, "vn {} {} {}", n[0], n[1], n[2]);
                next
            });
            corner_n.push(id + 1);
        }
    }
    for (f, face) in mesh.faces.iter().enumerate() {
        s.push('f');
        for (k, &fv) in face.iter().enumerate() {
            let v = fv + 1;
            let c = 3 * f + k;
            match (corner_t.is_empty(), corner_n.is_empty()) {
                (true, true) => write!(s, " {v}"),
                (false, true) => write!(s, " {v}/{}", corner_t[c]),
                (true, false) => write!(s, " {v}//{}", corner_n[c]),
                (false, false) => write!(s, " {v}/{}/{}", corner_t[c], corner_n[c]),
            }
            .ok();
        }
        s.push('\n');
    }
    let mut files: Vec<(&Path, &[u8])> = vec![(path, s.as_bytes())];
    files.extend(sidecars.iter().map(|(p, b)| (p.as_path(), b.as_slice())));
    write_atomic_all(&files)
}
