//! Stanford PLY reader (ascii, binary little/big endian; faces and triangle strips) and binary
//! little-endian writer.

use super::{check_content, check_exportable, fan, finish, write_atomic_all};
use crate::error::{Error, Result};
use crate::mesh::TriMesh;
use std::path::Path;

/// Options for `save_ply`.
#[derive(Clone, Debug)]
pub struct PlyOptions {
    /// Write `nx ny nz`: the mesh's own normals, else area-weighted vertex normals.
    pub normals: bool,
    /// Write `red green blue` (uchar) when the mesh has vertex colours.
    pub vertex_colors: bool,
}

impl Default for PlyOptions {
    fn default() -> Self {
        PlyOptions {
            normals: true,
            vertex_colors: true,
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    fn parse(s: &str) -> Option<Scalar> {
        Some(match s {
            "char" | "int8" => Scalar::I8,
            "uchar" | "uint8" => Scalar::U8,
            "short" | "int16" => Scalar::I16,
            "ushort" | "uint16" => Scalar::U16,
            "int" | "int32" => Scalar::I32,
            "uint" | "uint32" => Scalar::U32,
            "float" | "float32" => Scalar::F32,
            "double" | "float64" => Scalar::F64,
            _ => return None,
        })
    }
    fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }
    /// Scale that maps this type's colour values to [0, 1].
    fn color_scale(self) -> f64 {
        match self {
            Scalar::F32 | Scalar::F64 => 1.0,
            Scalar::U16 | Scalar::I16 => 1.0 / 65535.0,
            _ => 1.0 / 255.0,
        }
    }
}

#[derive(Clone, Copy, Debug)]
enum Kind {
    Scalar(Scalar),
    List(Scalar, Scalar),
}

#[derive(Clone, Debug)]
struct Property {
    name: String,
    kind: Kind,
}

#[derive(Clone, Debug)]
struct Element {
    name: String,
    count: usize,
    props: Vec<Property>,
}

#[derive(Clone, Copy, PartialEq)]
enum Encoding {
    Ascii,
    Le,
    Be,
}

/// Reads scalars from the body of a PLY file.
struct Body<'a> {
    data: &'a [u8],
    pos: usize,
    enc: Encoding,
}

impl Body<'_> {
    fn remaining(&self) -> usize {
        self.data.len() - self.pos
    }

    /// Next ASCII token.
    fn token(&mut self) -> Option<&[u8]> {
        let d = self.data;
        while self.pos < d.len() && d[self.pos].is_ascii_whitespace() {
            self.pos += 1;
        }
        let start = self.pos;
        while self.pos < d.len() && !d[self.pos].is_ascii_whitespace() {
            self.pos += 1;
        }
        (self.pos > start).then(|| &d[start..self.pos])
    }

    /// Read one value of type `t` as f64 (exact for every PLY integer type); `None` at the end
    /// of the data; `Err(token)` for a non-numeric ASCII token.
    fn read(&mut self, t: Scalar) -> std::result::Result<Option<f64>, String> {
        if self.enc == Encoding::Ascii {
            let Some(tok) = self.token() else {
                return Ok(None);
            };
            let s = std::str::from_utf8(tok).map_err(|_| "<non-UTF-8>".to_string())?;
            return s
                .parse::<f64>()
                .map(Some)
                .map_err(|_| s.chars().take(40).collect());
        }
        let n = t.size();
        if self.remaining() < n {
            self.pos = self.data.len();
            return Ok(None);
        }
        let b = &self.data[self.pos..self.pos + n];
        self.pos += n;
        let mut a = [0u8; 8];
        a[..n].copy_from_slice(b);
        if self.enc == Encoding::Be {
            a[..n].reverse();
        }
        Ok(Some(match t {
            Scalar::I8 => a[0] as i8 as f64,
            Scalar::U8 => a[0] as f64,
            Scalar::I16 => i16::from_le_bytes([a[0], a[1]]) as f64,
            Scalar::U16 => u16::from_le_bytes([a[0], a[1]]) as f64,
            Scalar::I32 => i32::from_le_bytes([a[0], a[1], a[2], a[3]]) as f64,
            Scalar::U32 => u32::from_le_bytes([a[0], a[1], a[2], a[3]]) as f64,
            Scalar::F32 => f32::from_le_bytes([a[0], a[1], a[2], a[3]]) as f64,
            Scalar::F64 => f64::from_le_bytes(a),
        }))
    }

    /// Skip `n` values of type `t`.
    fn skip(&mut self, t: Scalar, n: usize) -> bool {
        if self.enc == Encoding::Ascii {
            (0..n).all(|_| self.token().is_some())
        } else {
            match n.checked_mul(t.size()) {
                Some(b) if b <= self.remaining() => {
                    self.pos += b;
                    true
                }
                _ => false,
            }
        }
    }
}

/// Parsed header.
struct Header {
    enc: Encoding,
    elements: Vec<Element>,
    texture_file: Option<String>,
    body_start: usize,
}

fn parse_header(bytes: &[u8], path: &Path) -> Result<Header> {
    let bad = |msg: String| Error::format(path, msg);
    let mut pos = 0usize;
    let mut enc = None;
    let mut elements: Vec<Element> = Vec::new();
    let mut texture_file = None;
    let mut line_no = 0usize;
    loop {
        let Some(nl) = bytes[pos..].iter().position(|&b| b == b'\n') else {
            return Err(bad("truncated header (no end_header line)".into()));
        };
        let raw = &bytes[pos..pos + nl];
        pos += nl + 1;
        line_no += 1;
        let line = String::from_utf8_lossy(raw);
        let line = line.trim_end_matches('\r');
        let mut toks = line.split_ascii_whitespace();
        let key = toks.next().unwrap_or("");
        if line_no == 1 {
            if key != "ply" {
                return Err(bad("not a PLY file (first line is not 'ply')".into()));
            }
            continue;
        }
        match key {
            "" => {}
            "format" => {
                enc = Some(match toks.next() {
                    Some("ascii") => Encoding::Ascii,
                    Some("binary_little_endian") => Encoding::Le,
                    Some("binary_big_endian") => Encoding::Be,
                    other => {
                        return Err(bad(format!(
                            "header line {line_no}: unknown format '{}'",
                            other.unwrap_or("")
                        )));
                    }
                })
            }
            "comment" => {
                let rest: Vec<&str> = toks.collect();
                if rest.len() >= 2 && rest[0].eq_ignore_ascii_case("texturefile") {
                    texture_file = Some(rest[1..].join(" "));
                }
            }
            "obj_info" => {}
            "element" => {
                let name = toks.next().unwrap_or("").to_string();
                let count = toks
                    .next()
                    .and_then(|c| c.parse::<usize>().ok())
                    .ok_or_else(|| bad(format!("header line {line_no}: bad element line")))?;
                elements.push(Element {
                    name,
                    count,
                    props: Vec::new(),
                });
            }
            "property" => {
                let el = elements.last_mut().ok_or_else(|| {
                    bad(format!(
                        "header line {line_no}: property before any element"
                    ))
                })?;
                let t = toks.next().unwrap_or("");
                let kind = if t == "list" {
                    let c = toks.next().and_then(Scalar::parse);
                    let i = toks.next().and_then(Scalar::parse);
                    match (c, i) {
                        (Some(c), Some(i)) if !matches!(c, Scalar::F32 | Scalar::F64) => {
                            Kind::List(c, i)
                        }
                        _ => {
                            return Err(bad(format!(
                                "header line {line_no}: bad list property types"
                            )));
                        }
                    }
                } else {
                    Kind::Scalar(Scalar::parse(t).ok_or_else(|| {
                        bad(format!(
                            "header line {line_no}: unknown property type '{}'",
                            t.chars().take(40).collect::<String>()
                        ))
                    })?)
                };
                let name = toks
                    .next()
                    .ok_or_else(|| bad(format!("header line {line_no}: property has no name")))?;
                el.props.push(Property {
                    name: name.to_string(),
                    kind,
                });
            }
            "end_header" => break,
            _ => {
                return Err(bad(format!(
                    "header line {line_no}: unknown keyword '{}'",
                    key.chars().take(40).collect::<String>()
                )));
            }
        }
    }
    let enc = enc.ok_or_else(|| bad("header has no format line".into()))?;
    Ok(Header {
        enc,
        elements,
        texture_file,
        body_start: pos,
    })
}

/// Refuse a header declaring more vertices than [`MAX_VERTICES`] or more faces or strips than
/// [`MAX_FACES`], whatever the file size (a sparse file can declare 300M vertices cheaply).
fn check_budget(h: &Header, path: &Path) -> Result<()> {
    use crate::mesh::validate::{MAX_FACES, MAX_VERTICES};
    for el in &h.elements {
        let limit = match el.name.as_str() {
            "vertex" => MAX_VERTICES,
            "face" | "tristrips" => MAX_FACES,
            _ => continue,
        };
        if el.count > limit {
            return Err(Error::format(
                path,
                format!(
                    "element '{}' declares {} items, more than the budget of {limit}",
                    el.name, el.count
                ),
            ));
        }
    }
    Ok(())
}

/// The budget error of a PLY header found in `head` (the file's first bytes), if its header
/// declares too much; `None` when the header is within budget or not complete in `head`. Lets
/// `load` refuse a huge file before reading it.
pub(super) fn header_budget_error(head: &[u8], path: &Path) -> Option<Error> {
    let h = parse_header(head, path).ok()?;
    check_budget(&h, path).err()
}

/// Reject element counts the file cannot possibly hold (before anything is allocated).
fn check_counts(h: &Header, body_len: usize, path: &Path) -> Result<()> {
    let mut need: usize = 0;
    for el in &h.elements {
        let per_item: usize = if h.enc == Encoding::Ascii {
            // every value is at least one character and a separator
            el.props.len()
        } else {
            el.props
                .iter()
                .map(|p| match p.kind {
                    Kind::Scalar(s) => s.size(),
                    Kind::List(c, _) => c.size(),
                })
                .sum()
        };
        need = need.saturating_add(el.count.saturating_mul(per_item));
        if need > body_len.saturating_add(1) || (el.props.is_empty() && el.count > body_len) {
            return Err(Error::format(
                path,
                format!(
                    "element '{}' declares {} items but the file is only {body_len} bytes after the header (truncated or corrupt)",
                    el.name.chars().take(40).collect::<String>(),
                    el.count
                ),
            ));
        }
    }
    Ok(())
}

#[derive(Clone, Copy, PartialEq)]
enum Role {
    Skip,
    Pos(usize),
    Normal(usize),
    Color(usize),
    Uv(usize),
    Indices,
    TexCoord,
}

fn vertex_role(name: &str) -> Role {
    match name {
        "x" => Role::Pos(0),
        "y" => Role::Pos(1),
        "z" => Role::Pos(2),
        "nx" => Role::Normal(0),
        "ny" => Role::Normal(1),
        "nz" => Role::Normal(2),
        "red" | "diffuse_red" | "r" => Role::Color(0),
        "green" | "diffuse_green" | "g" => Role::Color(1),
        "blue" | "diffuse_blue" | "b" => Role::Color(2),
        "s" | "u" | "texture_u" | "texture_s" => Role::Uv(0),
        "t" | "v" | "texture_v" | "texture_t" => Role::Uv(1),
        _ => Role::Skip,
    }
}

/// Parse PLY bytes; `path` names the file in messages and locates `comment TextureFile` images.
///
/// The steps: the header and its budget, then per element [`plan_element`] (each property's
/// role), [`reserve_vertices`], and per item [`read_item`] (its values from the body) and
/// [`store_item`] (a vertex, a face fanned into triangles or a triangle strip); then
/// [`check_faces`] and [`assemble`] (the mesh with its normals, colours, UVs and texture).
pub fn load_ply_bytes(bytes: &[u8], path: &Path) -> Result<TriMesh> {
    load_ply_bytes_exact(bytes, path).map(|(m, _)| m)
}

/// [`load_ply_bytes`], with the file's coordinates at its precision too (double for ASCII and
/// double properties).
pub(super) fn load_ply_bytes_exact(bytes: &[u8], path: &Path) -> Result<(TriMesh, Vec<[f64; 3]>)> {
    check_content(bytes, super::MeshFormat::Ply, path)?;
    let h = parse_header(bytes, path)?;
    check_budget(&h, path)?;
    let body_len = bytes.len() - h.body_start;
    check_counts(&h, body_len, path)?;
    let mut body = Body {
        data: bytes,
        pos: h.body_start,
        enc: h.enc,
    };
    let mut data = PlyData::default();
    let mut item = Item::default();
    for el in &h.elements {
        let elname: String = el.name.chars().take(40).collect();
        let at = ItemPlace {
            path,
            element: &elname,
            count: el.count,
        };
        let plan = plan_element(el, data.have_vertices, path)?;
        if plan.is_vertex {
            data.have_vertices = true;
            reserve_vertices(&mut data, &plan, el.count, path)?;
        }
        if el.props.is_empty() {
            continue;
        }
        for i in 0..el.count {
            read_item(&mut body, el, &plan.roles, &at, i, &mut item)?;
            store_item(&mut data, &plan, &item, &at, i)?;
        }
    }
    check_faces(&data, path)?;
    let raw = std::mem::take(&mut data.positions);
    let mesh = assemble(data, raw.len(), h.texture_file.as_deref(), path);
    finish(mesh, raw, path)
}

/// What the elements have given so far.
#[derive(Default)]
struct PlyData {
    /// Positions at the file's precision.
    positions: Vec<[f64; 3]>,
    normals: Vec<[f32; 3]>,
    colors: Vec<[f32; 3]>,
    /// Per-vertex UVs.
    vuv: Vec<[f32; 2]>,
    faces: Vec<[u32; 3]>,
    /// Per-corner UVs (from face `texcoord` lists, zero where a face has none).
    cuv: Vec<[f32; 2]>,
    /// Whether any face had a `texcoord` list.
    has_cuv: bool,
    /// Whether the first vertex element has been read.
    have_vertices: bool,
    /// Faces of fewer than three vertices, skipped.
    short_faces: usize,
}

/// The values of one item of an element.
#[derive(Default)]
struct Item {
    p: [f64; 3],
    nrm: [f32; 3],
    col: [f32; 3],
    uv: [f32; 2],
    /// Vertex indices (faces and strips).
    list: Vec<f64>,
    /// Face texture coordinates.
    tc: Vec<f64>,
}

/// An element's name (at most 40 characters), its count and the file, for messages.
struct ItemPlace<'a> {
    path: &'a Path,
    element: &'a str,
    count: usize,
}

impl ItemPlace<'_> {
    /// The body ended inside item `i`.
    fn truncated(&self, i: usize) -> Error {
        Error::format(
            self.path,
            format!(
                "truncated data in element '{}' (item {i} of {})",
                self.element, self.count
            ),
        )
    }

    /// Token `tok` of item `i` is not a number.
    fn not_number(&self, i: usize, tok: String) -> Error {
        Error::format(
            self.path,
            format!(
                "element '{}' item {i}: '{tok}' is not a number",
                self.element
            ),
        )
    }
}

/// How one element is read: each property's role and which vertex attributes it carries.
struct ElementPlan {
    roles: Vec<Role>,
    /// The first element named `vertex`.
    is_vertex: bool,
    is_face: bool,
    is_strip: bool,
    want_n: bool,
    want_c: bool,
    want_uv: bool,
}

/// The roles of an element's properties; a vertex element without `x`, `y` or `z` is an error.
fn plan_element(el: &Element, have_vertices: bool, path: &Path) -> Result<ElementPlan> {
    let is_vertex = el.name == "vertex" && !have_vertices;
    let is_face = el.name == "face";
    let is_strip = el.name == "tristrips";
    let roles: Vec<Role> = el
        .props
        .iter()
        .map(|p| match (&p.kind, is_vertex, is_face || is_strip) {
            (Kind::Scalar(_), true, _) => vertex_role(&p.name),
            (Kind::List(..), false, true)
                if p.name == "vertex_indices" || p.name == "vertex_index" =>
            {
                Role::Indices
            }
            (Kind::List(..), false, true) if is_face && p.name == "texcoord" => Role::TexCoord,
            _ => Role::Skip,
        })
        .collect();
    let has = |f: &dyn Fn(Role) -> bool| roles.iter().any(|&r| f(r));
    if is_vertex {
        for k in 0..3 {
            if !has(&|r| r == Role::Pos(k)) {
                return Err(Error::format(
                    path,
                    format!("vertex element has no '{}' property", ["x", "y", "z"][k]),
                ));
            }
        }
    }
    let want_n = is_vertex && (0..3).all(|k| has(&|r| r == Role::Normal(k)));
    let want_c = is_vertex && (0..3).all(|k| has(&|r| r == Role::Color(k)));
    let want_uv = is_vertex && (0..2).all(|k| has(&|r| r == Role::Uv(k)));
    Ok(ElementPlan {
        roles,
        is_vertex,
        is_face,
        is_strip,
        want_n,
        want_c,
        want_uv,
    })
}

/// Reserve room for `count` vertices and their attributes; an allocation failure is an error,
/// not an abort (the count is within budget, but the process may have less memory than the
/// budget needs).
fn reserve_vertices(
    data: &mut PlyData,
    plan: &ElementPlan,
    count: usize,
    path: &Path,
) -> Result<()> {
    let no_memory = |_| Error::format(path, format!("not enough memory for {count} vertices"));
    data.positions.try_reserve(count).map_err(no_memory)?;
    if plan.want_n {
        data.normals.try_reserve(count).map_err(no_memory)?;
    }
    if plan.want_c {
        data.colors.try_reserve(count).map_err(no_memory)?;
    }
    if plan.want_uv {
        data.vuv.try_reserve(count).map_err(no_memory)?;
    }
    Ok(())
}

/// Read item `i` of element `el` from the body into `item`, skipping the properties it does not
/// use.
fn read_item(
    body: &mut Body,
    el: &Element,
    roles: &[Role],
    at: &ItemPlace,
    i: usize,
    item: &mut Item,
) -> Result<()> {
    item.p = [0.0f64; 3];
    item.nrm = [0.0f32; 3];
    item.col = [0.0f32; 3];
    item.uv = [0.0f32; 2];
    item.list.clear();
    item.tc.clear();
    for (prop, &role) in el.props.iter().zip(roles) {
        match prop.kind {
            Kind::Scalar(t) => {
                if role == Role::Skip && body.enc != Encoding::Ascii {
                    if !body.skip(t, 1) {
                        return Err(at.truncated(i));
                    }
                    continue;
                }
                let v = body
                    .read(t)
                    .map_err(|tok| at.not_number(i, tok))?
                    .ok_or_else(|| at.truncated(i))?;
                match role {
                    Role::Pos(k) => item.p[k] = v,
                    Role::Normal(k) => item.nrm[k] = v as f32,
                    Role::Color(k) => item.col[k] = (v * t.color_scale()) as f32,
                    Role::Uv(k) => item.uv[k] = v as f32,
                    _ => {}
                }
            }
            Kind::List(ct, it) => {
                let c = body
                    .read(ct)
                    .map_err(|tok| at.not_number(i, tok))?
                    .ok_or_else(|| at.truncated(i))?;
                if !(c >= 0.0 && c.fract() == 0.0) {
                    return Err(Error::format(
                        at.path,
                        format!("element '{}' item {i}: bad list length {c}", at.element),
                    ));
                }
                let c = c as usize;
                let room = if body.enc == Encoding::Ascii {
                    body.remaining() / 2 + 1
                } else {
                    body.remaining() / it.size()
                };
                if c > room {
                    return Err(at.truncated(i));
                }
                let dest = match role {
                    Role::Indices => &mut item.list,
                    Role::TexCoord => &mut item.tc,
                    _ => {
                        if !body.skip(it, c) {
                            return Err(at.truncated(i));
                        }
                        continue;
                    }
                };
                for _ in 0..c {
                    let v = body
                        .read(it)
                        .map_err(|tok| at.not_number(i, tok))?
                        .ok_or_else(|| at.truncated(i))?;
                    dest.push(v);
                }
            }
        }
    }
    Ok(())
}

/// Add item `i` to the mesh data: a vertex with its attributes, a face fanned into triangles
/// (with its texture coordinates), or a triangle strip.
fn store_item(
    data: &mut PlyData,
    plan: &ElementPlan,
    item: &Item,
    at: &ItemPlace,
    i: usize,
) -> Result<()> {
    if plan.is_vertex {
        data.positions.push(item.p);
        if plan.want_n {
            data.normals.push(item.nrm);
        }
        if plan.want_c {
            data.colors.push(item.col);
        }
        if plan.want_uv {
            data.vuv.push(item.uv);
        }
    } else if plan.is_face {
        let (list, tc) = (&item.list, &item.tc);
        if list.len() < 3 {
            data.short_faces += 1;
            return Ok(());
        }
        let idx = to_indices(list, at.path, at.element, i)?;
        let with_tc = tc.len() == 2 * idx.len();
        data.has_cuv |= with_tc;
        let (faces, cuv) = (&mut data.faces, &mut data.cuv);
        fan(idx.len(), |a, b, c| {
            faces.push([idx[a], idx[b], idx[c]]);
            for k in [a, b, c] {
                cuv.push(if with_tc {
                    [tc[2 * k] as f32, tc[2 * k + 1] as f32]
                } else {
                    [0.0; 2]
                });
            }
        });
    } else if plan.is_strip {
        strips_to_faces(
            &item.list,
            &mut data.faces,
            &mut data.cuv,
            at.path,
            at.element,
            i,
        )?;
    }
    Ok(())
}

/// A vertex element, some faces unless all were degenerate (a warning counts the skipped ones),
/// and every face index within the vertices.
fn check_faces(data: &PlyData, path: &Path) -> Result<()> {
    if !data.have_vertices {
        return Err(Error::format(path, "no vertex element"));
    }
    let short_faces = data.short_faces;
    if short_faces > 0 && data.faces.is_empty() {
        return Err(Error::format(
            path,
            format!(
                "{} degenerate (fewer than 3 vertices)",
                crate::mesh::all_faces(short_faces)
            ),
        ));
    }
    if short_faces > 0 {
        super::warn(format!(
            "{}: skipped {short_faces} faces with fewer than 3 vertices",
            path.display()
        ));
    }
    let n = data.positions.len();
    if let Some(bad) = data.faces.iter().flatten().find(|&&v| v as usize >= n) {
        return Err(Error::format(
            path,
            format!("a face references vertex {bad} but the file has {n} vertices"),
        ));
    }
    Ok(())
}

/// The mesh: normals and colours where every vertex has one, per-corner UVs from the faces'
/// texture coordinates or else the vertices', and the `comment TextureFile` image beside `path`.
fn assemble(data: PlyData, n: usize, texture_file: Option<&str>, path: &Path) -> TriMesh {
    let mut mesh = TriMesh {
        faces: data.faces,
        ..Default::default()
    };
    let (normals, colors, vuv) = (data.normals, data.colors, data.vuv);
    mesh.normals = (normals.len() == n && n > 0).then_some(normals);
    mesh.colors = (colors.len() == n && n > 0).then_some(colors);
    if data.has_cuv {
        mesh.uvs = Some(data.cuv);
    } else if vuv.len() == n && n > 0 {
        mesh.uvs = Some(
            mesh.faces
                .iter()
                .flat_map(|f| f.map(|v| vuv[v as usize]))
                .collect(),
        );
    }
    if let Some(name) = texture_file {
        let dir = path.parent().unwrap_or(Path::new("."));
        mesh.texture = super::load_texture_or_warn(&dir.join(name), path);
    }
    mesh
}

/// Convert a list of numbers to vertex indices (non-negative integers below 2^32).
fn to_indices(list: &[f64], path: &Path, el: &str, i: usize) -> Result<Vec<u32>> {
    list.iter()
        .map(|&v| {
            if v >= 0.0 && v < u32::MAX as f64 && v.fract() == 0.0 {
                Ok(v as u32)
            } else {
                Err(Error::format(
                    path,
                    format!("element '{el}' item {i}: bad vertex index {v}"),
                ))
            }
        })
        .collect()
}

/// Triangles of a strip list with negative entries as restarts: even triangles (a, b, c), odd
/// ones (b, a, c) so every triangle keeps the strip's orientation; triangles with a repeated
/// vertex (strip stitching) are skipped.
fn strips_to_faces(
    list: &[f64],
    faces: &mut Vec<[u32; 3]>,
    cuv: &mut Vec<[f32; 2]>,
    path: &Path,
    el: &str,
    item: usize,
) -> Result<()> {
    let mut run: Vec<u32> = Vec::new();
    let mut flush = |run: &mut Vec<u32>| {
        for j in 0..run.len().saturating_sub(2) {
            let (a, b, c) = if j % 2 == 0 {
                (run[j], run[j + 1], run[j + 2])
            } else {
                (run[j + 1], run[j], run[j + 2])
            };
            if a != b && b != c && a != c {
                faces.push([a, b, c]);
                cuv.extend([[0.0; 2]; 3]);
            }
        }
        run.clear();
    };
    for &v in list {
        if v < 0.0 {
            flush(&mut run);
        } else if v < u32::MAX as f64 && v.fract() == 0.0 {
            run.push(v as u32);
        } else {
            return Err(Error::format(
                path,
                format!("element '{el}' item {item}: bad vertex index {v}"),
            ));
        }
    }
    flush(&mut run);
    Ok(())
}

/// Write a binary little-endian PLY: float x y z, float nx ny nz (the mesh's own normals, else
/// area-weighted vertex normals; unless `opts.normals` is off), uchar red green blue,
/// per-vertex float `s t` when every vertex has one UV (else a per-face `texcoord` list), faces
/// as `list uchar int vertex_indices`; with a texture, `comment TextureFile <stem>_texture.png`
/// and the PNG beside the file.
pub fn save_ply(mesh: &TriMesh, path: &Path, opts: &PlyOptions) -> Result<()> {
    check_exportable(mesh, path)?;
    let normals = opts.normals.then(|| super::export_vertex_normals(mesh));
    let normals = normals.as_ref();
    let colors = mesh.colors.as_ref().filter(|_| opts.vertex_colors);
    let vuv = super::per_vertex_uvs(mesh);
    let face_uv = if vuv.is_none() {
        mesh.uvs.as_ref()
    } else {
        None
    };
    // The PLY and its texture are written as one (no texture is left behind by a failed export).
    let texture = super::texture_beside(mesh, path)?;
    let tex_name = texture.as_ref().map(|(name, _, _)| name.clone());
    let mut h =
        String::from("ply\nformat binary_little_endian 1.0\ncomment written by meshmatch\n");
    if let Some(t) = &tex_name {
        h.push_str(&format!("comment TextureFile {t}\n"));
    }
    h.push_str(&format!(
        "element vertex {}\nproperty float x\nproperty float y\nproperty float z\n",
        mesh.num_vertices()
    ));
    if normals.is_some() {
        h.push_str("property float nx\nproperty float ny\nproperty float nz\n");
    }
    if colors.is_some() {
        h.push_str("property uchar red\nproperty uchar green\nproperty uchar blue\n");
    }
    if vuv.is_some() {
        h.push_str("property float s\nproperty float t\n");
    }
    h.push_str(&format!(
        "element face {}\nproperty list uchar int vertex_indices\n",
        mesh.num_faces()
    ));
    if face_uv.is_some() {
        h.push_str("property list uchar float texcoord\n");
    }
    h.push_str("end_header\n");
    let mut out = h.into_bytes();
    out.reserve(mesh.num_vertices() * 32 + mesh.num_faces() * 40);
    for i in 0..mesh.num_vertices() {
        for c in mesh.positions[i] {
            out.extend(c.to_le_bytes());
        }
        if let Some(n) = normals {
            for c in n[i] {
                out.extend(c.to_le_bytes());
            }
        }
        if let Some(c) = colors {
            out.extend(crate::color::to_u8(c[i]));
        }
        if let Some(uv) = &vuv {
            for c in uv[i] {
                out.extend(c.to_le_bytes());
            }
        }
    }
    for (f, face) in mesh.faces.iter().enumerate() {
        out.push(3);
        for v in face {
            out.extend((*v as i32).to_le_bytes());
        }
        if let Some(uv) = face_uv {
            out.push(6);
            for k in 0..3 {
                for c in uv[3 * f + k] {
                    out.extend(c.to_le_bytes());
                }
            }
        }
    }
    match &texture {
        Some((_, tex_path, png)) => write_atomic_all(&[(path, &out), (tex_path, png)]),
        None => write_atomic_all(&[(path, &out)]),
    }
}
