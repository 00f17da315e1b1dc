//! glTF 2.0 / GLB reader (document model from the `gltf` crate, buffers and accessors read here
//! with bounds checks) and a hand-written GLB / glTF writer.

use super::{base64, check_content, check_exportable, finish, warn, write_atomic};
use crate::error::{Error, Result};
use crate::mesh::Texture;
use crate::mesh::TriMesh;
use crate::mesh::validate::{MAX_FACES, MAX_VERTICES};
use gltf::accessor::{DataType, Dimensions};
use gltf::mesh::{Mode, Semantic};
use std::borrow::Cow;
use std::collections::HashMap;
use std::path::Path;
use std::sync::Arc;

/// The file's buffers: the GLB BIN chunk is borrowed (shared by every buffer that uses it),
/// external and data-URI buffers are owned.
type Buffers<'a> = [Cow<'a, [u8]>];

/// Options for `save_glb` / `save_gltf`.
#[derive(Clone, Debug)]
pub struct GlbOptions {
    /// Write COLOR_0 (linear float RGB) when the mesh has vertex colours.
    pub vertex_colors: bool,
    /// Write TEXCOORD_0 and a material with an embedded PNG `baseColorTexture` when the mesh has
    /// UVs (and a texture).
    pub texture: bool,
}

impl Default for GlbOptions {
    fn default() -> Self {
        GlbOptions {
            vertex_colors: true,
            texture: true,
        }
    }
}

/// Required extensions the loader can ignore safely (they only change shading).
const SUPPORTED_REQUIRED: &[&str] = &[
    "KHR_materials_unlit",
    "KHR_materials_pbrSpecularGlossiness",
    "KHR_texture_transform",
];

/// The one-line reason a file that requires extension `ext` is refused.
fn unsupported_extension(ext: &str) -> String {
    let (what, fix) = match ext {
        "KHR_draco_mesh_compression" => ("Draco-compressed geometry", "without compression"),
        "EXT_meshopt_compression" | "KHR_meshopt_compression" => {
            ("meshoptimizer-compressed buffers", "without compression")
        }
        "KHR_mesh_quantization" => ("quantized vertex attributes", "without quantization"),
        "KHR_texture_basisu" => (
            "KTX2 / Basis Universal textures",
            "with PNG or JPEG textures",
        ),
        "EXT_texture_webp" => ("WebP textures", "with PNG or JPEG textures"),
        "EXT_texture_avif" => ("AVIF textures", "with PNG or JPEG textures"),
        _ => ("a required glTF extension", "without it"),
    };
    format!(
        "uses {} ({what}), which meshmatch cannot read; re-export {fix}",
        clip(ext)
    )
}

/// Most nested nodes followed (guards against cyclic or absurdly deep node graphs).
const MAX_NODE_DEPTH: usize = 64;

/// Validate every index of the document (so the `gltf` wrappers cannot panic) while tolerating
/// a missing POSITION `min`/`max`, which the loader does not need.
fn validate(root: &gltf::json::Root, path: &Path) -> Result<()> {
    use gltf::json::validation::Validate;
    // gltf-json 1.4's POSITION min/max check indexes `accessors` unchecked: check it first.
    for (mi, m) in root.meshes.iter().enumerate() {
        for p in &m.primitives {
            if p.attributes
                .values()
                .any(|a| a.value() >= root.accessors.len())
            {
                return Err(Error::format(
                    path,
                    format!("invalid glTF: mesh {mi} refers to a missing accessor"),
                ));
            }
        }
    }
    let mut errors = Vec::new();
    root.validate(root, gltf::json::Path::new, &mut |p, e| {
        let p = p();
        let s = p.as_str();
        if !(s.contains("POSITION") && (s.ends_with(".min") || s.ends_with(".max"))) {
            errors.push(format!("{s}: {e}"));
        }
    });
    match errors.first() {
        None => Ok(()),
        Some(e) => Err(Error::format(path, format!("invalid glTF: {}", clip(e)))),
    }
}

/// Decode a `%XX`-escaped relative URI.
fn percent_decode(s: &str) -> String {
    let b = s.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        if b[i] == b'%'
            && i + 2 < b.len()
            && b[i + 1].is_ascii_hexdigit()
            && b[i + 2].is_ascii_hexdigit()
        {
            let hex = |c: u8| (c as char).to_digit(16).unwrap_or(0) as u8;
            out.push(hex(b[i + 1]) * 16 + hex(b[i + 2]));
            i += 3;
        } else {
            out.push(b[i]);
            i += 1;
        }
    }
    String::from_utf8_lossy(&out).into_owned()
}

/// Bytes of a URI: a base64 data URI, or a file relative to the glTF file's directory (absolute
/// paths and `..` are accepted, as for OBJ/MTL and PLY textures) that must be a regular file of
/// at most `limit` bytes (`what` names it in messages).
fn read_uri(uri: &str, path: &Path, limit: u64, what: &str) -> Result<Vec<u8>> {
    if let Some(rest) = uri.strip_prefix("data:") {
        let (meta, data) = rest
            .split_once(',')
            .ok_or_else(|| Error::format(path, "malformed data URI"))?;
        if !meta.ends_with(";base64") {
            return Err(Error::format(path, "data URI is not base64"));
        }
        return base64::decode(data).ok_or_else(|| Error::format(path, "bad base64 in data URI"));
    }
    if uri.contains("://") {
        return Err(Error::format(
            path,
            format!("external URI '{}' is not supported", clip(uri)),
        ));
    }
    let name = percent_decode(uri);
    let file = path.parent().unwrap_or(Path::new(".")).join(&name);
    super::read_regular_file(&file, limit, what).map_err(|e| {
        Error::format(
            path,
            format!("cannot read buffer/image '{}': {e}", clip(&name)),
        )
    })
}

fn clip(s: &str) -> String {
    s.chars().take(60).collect()
}

/// Typed read of a whole accessor as `count * multiplicity` f64 values (exact for u32),
/// normalized integers mapped to [0,1] / [-1,1] when `normalized` is set; sparse substitution
/// applied. Every byte range is checked against its view and buffer.
fn read_accessor(acc: &gltf::Accessor, buffers: &Buffers, path: &Path) -> Result<Vec<f64>> {
    let dims = acc.dimensions();
    if matches!(dims, Dimensions::Mat2 | Dimensions::Mat3 | Dimensions::Mat4) {
        return Err(Error::format(
            path,
            format!(
                "accessor {}: matrix accessors are not vertex data",
                acc.index()
            ),
        ));
    }
    let m = dims.multiplicity();
    let dt = acc.data_type();
    let csize = dt.size();
    let count = acc.count();
    let bad = |msg: String| Error::format(path, format!("accessor {}: {msg}", acc.index()));
    let normalized = acc.normalized();
    let read_comp = |b: &[u8], dt: DataType| -> f64 {
        let v = match dt {
            DataType::I8 => b[0] as i8 as f64,
            DataType::U8 => b[0] as f64,
            DataType::I16 => i16::from_le_bytes([b[0], b[1]]) as f64,
            DataType::U16 => u16::from_le_bytes([b[0], b[1]]) as f64,
            DataType::U32 => u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
            DataType::F32 => f32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
        };
        if !normalized {
            return v;
        }
        match dt {
            DataType::I8 => (v / 127.0).max(-1.0),
            DataType::U8 => v / 255.0,
            DataType::I16 => (v / 32767.0).max(-1.0),
            DataType::U16 => v / 65535.0,
            DataType::U32 => v / u32::MAX as f64,
            DataType::F32 => v,
        }
    };
    // Slice of a buffer view, checked.
    let view_bytes = |view: &gltf::buffer::View| -> Result<&[u8]> {
        let buf = buffers
            .get(view.buffer().index())
            .ok_or_else(|| bad("missing buffer".into()))?;
        let end = view
            .offset()
            .checked_add(view.length())
            .filter(|&e| e <= buf.len())
            .ok_or_else(|| {
                bad(format!(
                    "buffer view {} runs past the end of its buffer ({} bytes)",
                    view.index(),
                    buf.len()
                ))
            })?;
        Ok(&buf[view.offset()..end])
    };
    let elem = m * csize;
    let mut out: Vec<f64>;
    if let Some(view) = acc.view() {
        let bytes = view_bytes(&view)?;
        let stride = view.stride().unwrap_or(elem);
        if stride < elem {
            return Err(bad(format!(
                "byte stride {stride} smaller than element size {elem}"
            )));
        }
        if count > 0 {
            let need = stride
                .checked_mul(count - 1)
                .and_then(|x| x.checked_add(elem))
                .and_then(|x| x.checked_add(acc.offset()));
            if need.is_none_or(|n| n > bytes.len()) {
                return Err(bad(format!(
                    "{count} elements do not fit in buffer view {} ({} bytes)",
                    view.index(),
                    bytes.len()
                )));
            }
        }
        out = Vec::new();
        out.try_reserve_exact(count * m)
            .map_err(|_| bad(format!("not enough memory for {count} elements")))?;
        for i in 0..count {
            let base = acc.offset() + i * stride;
            for c in 0..m {
                let o = base + c * csize;
                out.push(read_comp(&bytes[o..o + csize], dt));
            }
        }
    } else {
        if acc.sparse().is_none() {
            return Err(bad("no buffer view".into()));
        }
        if count > MAX_VERTICES {
            return Err(bad(format!(
                "sparse accessor of {count} elements exceeds the budget of {MAX_VERTICES}"
            )));
        }
        out = vec![0.0; count * m];
    }
    if let Some(sp) = acc.sparse() {
        let n = sp.count();
        let iv = sp.indices();
        let ibytes = view_bytes(&iv.view())?;
        let isize = match iv.index_type() {
            gltf::accessor::sparse::IndexType::U8 => 1,
            gltf::accessor::sparse::IndexType::U16 => 2,
            gltf::accessor::sparse::IndexType::U32 => 4,
        };
        let vv = sp.values();
        let vbytes = view_bytes(&vv.view())?;
        let ifits = n
            .checked_mul(isize)
            .and_then(|x| x.checked_add(iv.offset()))
            .is_some_and(|e| e <= ibytes.len());
        let vfits = n
            .checked_mul(elem)
            .and_then(|x| x.checked_add(vv.offset()))
            .is_some_and(|e| e <= vbytes.len());
        if !ifits || !vfits {
            return Err(bad("sparse data runs past its buffer view".into()));
        }
        for s in 0..n {
            let io = iv.offset() + s * isize;
            let b = &ibytes[io..io + isize];
            let target = match isize {
                1 => b[0] as usize,
                2 => u16::from_le_bytes([b[0], b[1]]) as usize,
                _ => u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as usize,
            };
            if target >= count {
                return Err(bad(format!("sparse index {target} out of range")));
            }
            for c in 0..m {
                let o = vv.offset() + s * elem + c * csize;
                out[target * m + c] = read_comp(&vbytes[o..o + csize], dt);
            }
        }
    }
    Ok(out)
}

/// Decode the image of a texture (buffer view or URI); errors describe what failed. Reads the
/// JSON directly: `gltf::Image::source` unwraps a missing `mimeType` / `uri`.
fn read_image(
    img: &gltf::image::Image,
    doc: &gltf::Document,
    buffers: &Buffers,
    path: &Path,
) -> Result<Texture> {
    let json = doc
        .as_json()
        .images
        .get(img.index())
        .ok_or_else(|| Error::format(path, "image index out of range"))?;
    let bytes: Vec<u8> = if let Some(vi) = &json.buffer_view {
        let view = doc
            .views()
            .nth(vi.value())
            .ok_or_else(|| Error::format(path, "image buffer view out of range"))?;
        let buf = buffers
            .get(view.buffer().index())
            .ok_or_else(|| Error::format(path, "image buffer missing"))?;
        let end = view
            .offset()
            .checked_add(view.length())
            .filter(|&e| e <= buf.len())
            .ok_or_else(|| Error::format(path, "image buffer view out of range"))?;
        buf[view.offset()..end].to_vec()
    } else if let Some(uri) = &json.uri {
        read_uri(uri, path, super::MAX_FILE_BYTES, "the image")?
    } else {
        return Err(Error::format(path, "image has neither bufferView nor uri"));
    };
    super::decode_texture(&bytes, path)
}

/// Accumulated output of all primitives.
#[derive(Default)]
struct Acc {
    positions: Vec<[f32; 3]>,
    normals: Vec<[f32; 3]>,
    has_normals: Vec<bool>,
    colors: Vec<[f32; 3]>,
    any_colors: bool,
    faces: Vec<[u32; 3]>,
    uvs: Vec<[f32; 2]>,
    any_uvs: bool,
    texture: Option<Arc<Texture>>,
    texture_source: Option<usize>,
    texture_failed: bool,
}

/// Parse glTF JSON or GLB bytes; `path` names the file in messages and is the base for external
/// buffers and images. Every primitive of every node of the default scene (else of all root
/// nodes) is read with its world transform; points and lines are skipped, strips and fans
/// converted to triangles.
pub fn load_gltf_bytes(bytes: &[u8], path: &Path) -> Result<TriMesh> {
    load_gltf_bytes_exact(bytes, path).map(|(m, _)| m)
}

/// [`load_gltf_bytes`], with the coordinates in double precision too (glTF stores single
/// precision, so a scaled copy's coordinates were rounded in its own units).
pub(super) fn load_gltf_bytes_exact(bytes: &[u8], path: &Path) -> Result<(TriMesh, Vec<[f64; 3]>)> {
    check_content(bytes, super::MeshFormat::Glb, path)?;
    let gltf = gltf::Gltf::from_slice_without_validation(bytes)
        .map_err(|e| Error::format(path, format!("invalid glTF: {e}")))?;
    // Before validation: a compressed file's accessors have no data of their own, and "missing
    // data" would hide the reason.
    if let Some(ext) = gltf
        .document
        .as_json()
        .extensions_required
        .iter()
        .find(|e| !SUPPORTED_REQUIRED.contains(&e.as_str()))
    {
        return Err(Error::format(path, unsupported_extension(ext)));
    }
    validate(gltf.document.as_json(), path)?;
    let doc = &gltf.document;
    let roots: Vec<gltf::Node> = match doc.default_scene().or_else(|| {
        (doc.scenes().len() == 1)
            .then(|| doc.scenes().next())
            .flatten()
    }) {
        Some(scene) => scene.nodes().collect(),
        None => {
            let mut is_child = vec![false; doc.nodes().len()];
            for n in doc.nodes() {
                for c in n.children() {
                    is_child[c.index()] = true;
                }
            }
            doc.nodes().filter(|n| !is_child[n.index()]).collect()
        }
    };
    // Every (mesh, world transform) to read, in file order.
    let mut instances: Vec<(gltf::Mesh, glam::Mat4)> = Vec::new();
    if roots.is_empty() && doc.nodes().len() == 0 {
        // No scene graph at all: take the meshes as they are.
        for mesh in doc.meshes() {
            instances.push((mesh, glam::Mat4::IDENTITY));
        }
    }
    let mut visited = vec![false; doc.nodes().len()];
    let mut stack: Vec<(gltf::Node, glam::Mat4, usize)> = roots
        .into_iter()
        .rev()
        .map(|n| (n, glam::Mat4::IDENTITY, 0))
        .collect();
    while let Some((node, parent, depth)) = stack.pop() {
        if depth > MAX_NODE_DEPTH || std::mem::replace(&mut visited[node.index()], true) {
            return Err(Error::format(
                path,
                "node hierarchy is not a tree (a node has several parents, a cycle, or is too deep)",
            ));
        }
        let world = parent * glam::Mat4::from_cols_array_2d(&node.transform().matrix());
        if let Some(mesh) = node.mesh() {
            instances.push((mesh, world));
        }
        let children: Vec<gltf::Node> = node.children().collect();
        for c in children.into_iter().rev() {
            stack.push((c, world, depth + 1));
        }
    }
    // The vertex budget on the total over all instances, from the accessors' declared counts,
    // before any buffer is read or any vertex allocated.
    let mut total = 0usize;
    for (mesh, _) in &instances {
        for prim in mesh.primitives() {
            if matches!(
                prim.mode(),
                Mode::Points | Mode::Lines | Mode::LineLoop | Mode::LineStrip
            ) {
                continue;
            }
            if let Some(a) = prim.get(&Semantic::Positions) {
                total = total.saturating_add(a.count());
            }
        }
    }
    if total > MAX_VERTICES {
        return Err(over_budget(path, total));
    }
    let mut buffers: Vec<Cow<[u8]>> = Vec::new();
    // External buffer files of one glTF may add up to at most MAX_FILE_BYTES.
    let mut external_left = super::MAX_FILE_BYTES;
    for b in doc.buffers() {
        let data: Cow<[u8]> = match b.source() {
            gltf::buffer::Source::Bin => Cow::Borrowed(gltf.blob.as_deref().ok_or_else(|| {
                Error::format(
                    path,
                    format!("buffer {} refers to a missing BIN chunk", b.index()),
                )
            })?),
            gltf::buffer::Source::Uri(uri) => {
                let data = read_uri(uri, path, external_left, "the buffer")?;
                if !uri.starts_with("data:") {
                    external_left -= data.len() as u64;
                }
                Cow::Owned(data)
            }
        };
        if data.len() < b.length() {
            return Err(Error::format(
                path,
                format!(
                    "buffer {} has {} bytes but the file declares {}",
                    b.index(),
                    data.len(),
                    b.length()
                ),
            ));
        }
        buffers.push(data);
    }
    let mut acc = Acc::default();
    let mut cache: Vec<Option<Arc<Vec<Option<Prim>>>>> = vec![None; doc.meshes().len()];
    // (node, world matrix) roots.
    for (mesh, world) in &instances {
        read_mesh(mesh, *world, &buffers, path, &mut acc, doc, &mut cache)?;
    }
    let n = acc.positions.len();
    let raw: Vec<[f64; 3]> = acc.positions.iter().map(|p| p.map(f64::from)).collect();
    let mut mesh = TriMesh {
        faces: acc.faces,
        ..Default::default()
    };
    if n > 0 && acc.has_normals.iter().all(|&h| h) {
        mesh.normals = Some(acc.normals);
    }
    if acc.any_colors {
        mesh.colors = Some(acc.colors);
    }
    if acc.any_uvs {
        mesh.uvs = Some(acc.uvs);
    }
    mesh.texture = acc.texture;
    finish(mesh, raw, path)
}

/// One primitive's data as read from its accessors, before any node transform: read once per
/// mesh and reused by every node that instances the mesh.
struct Prim {
    positions: Vec<[f32; 3]>,
    normals: Option<Vec<[f32; 3]>>,
    /// sRGB colours.
    colors: Option<Vec<[f32; 3]>>,
    /// Per-vertex UVs, V up.
    uvs: Option<Vec<[f32; 2]>>,
    /// Triangles (indices into this primitive's vertices), orientation as in the file.
    tris: Vec<[u32; 3]>,
    /// Image of the material's base colour texture.
    image: Option<usize>,
}

/// Error for a vertex total over the budget, before anything of that size is allocated.
fn over_budget(path: &Path, total: usize) -> Error {
    Error::format(
        path,
        format!(
            "{total} vertices (primitives times the nodes that instance them) exceed the budget of {MAX_VERTICES}"
        ),
    )
}

/// Read every primitive of `mesh` (None for points, lines and primitives without POSITION).
/// `base` vertices are already loaded: the budget is checked on the running total before each
/// POSITION accessor is read.
fn read_prims(
    mesh: &gltf::Mesh,
    buffers: &Buffers,
    path: &Path,
    mut base: usize,
) -> Result<Vec<Option<Prim>>> {
    let mut out = Vec::new();
    for prim in mesh.primitives() {
        let mode = prim.mode();
        if matches!(
            mode,
            Mode::Points | Mode::Lines | Mode::LineLoop | Mode::LineStrip
        ) {
            out.push(None);
            continue;
        }
        let Some(pacc) = prim.get(&Semantic::Positions) else {
            warn(format!(
                "{}: mesh {} has a primitive without POSITION; skipped",
                path.display(),
                mesh.index()
            ));
            out.push(None);
            continue;
        };
        if pacc.dimensions() != Dimensions::Vec3 {
            return Err(Error::format(path, "POSITION is not VEC3"));
        }
        let nv = pacc.count();
        let total = base.saturating_add(nv);
        if total > MAX_VERTICES {
            return Err(over_budget(path, total));
        }
        base = total;
        let f3 = |c: &[f64]| [c[0] as f32, c[1] as f32, c[2] as f32];
        let positions: Vec<[f32; 3]> = read_accessor(&pacc, buffers, path)?
            .chunks_exact(3)
            .map(f3)
            .collect();
        let normals = match prim.get(&Semantic::Normals) {
            Some(a) if a.dimensions() == Dimensions::Vec3 && a.count() == nv => Some(
                read_accessor(&a, buffers, path)?
                    .chunks_exact(3)
                    .map(f3)
                    .collect(),
            ),
            _ => None,
        };
        let colors = match prim.get(&Semantic::Colors(0)) {
            Some(a)
                if matches!(a.dimensions(), Dimensions::Vec3 | Dimensions::Vec4)
                    && a.count() == nv =>
            {
                let m = a.dimensions().multiplicity();
                Some(
                    read_accessor(&a, buffers, path)?
                        .chunks_exact(m)
                        .map(|c| [c[0], c[1], c[2]].map(|x| crate::color::linear_to_srgb(x as f32)))
                        .collect(),
                )
            }
            _ => None,
        };
        let uvs = match prim.get(&Semantic::TexCoords(0)) {
            Some(a) if a.dimensions() == Dimensions::Vec2 && a.count() == nv => Some(
                read_accessor(&a, buffers, path)?
                    .chunks_exact(2)
                    .map(|c| [c[0] as f32, 1.0 - c[1] as f32])
                    .collect(),
            ),
            _ => None,
        };
        // Corner list (indices into this primitive's vertices).
        let idx: Vec<u32> = match prim.indices() {
            Some(ia) => {
                if ia.dimensions() != Dimensions::Scalar {
                    return Err(Error::format(path, "indices accessor is not SCALAR"));
                }
                read_accessor(&ia, buffers, path)?
                    .into_iter()
                    .map(|x| x as u32)
                    .collect()
            }
            None => (0..nv as u32).collect(),
        };
        if let Some(&bad) = idx.iter().find(|&&i| i as usize >= nv) {
            return Err(Error::format(
                path,
                format!(
                    "mesh {}: index {bad} out of range ({nv} vertices in the primitive)",
                    mesh.index()
                ),
            ));
        }
        let mut tris: Vec<[u32; 3]> = Vec::new();
        match mode {
            Mode::Triangles => {
                tris.extend(idx.chunks_exact(3).map(|c| [c[0], c[1], c[2]]));
            }
            Mode::TriangleStrip => {
                for i in 0..idx.len().saturating_sub(2) {
                    let t = if i % 2 == 0 {
                        [idx[i], idx[i + 1], idx[i + 2]]
                    } else {
                        [idx[i + 1], idx[i], idx[i + 2]]
                    };
                    if t[0] != t[1] && t[1] != t[2] && t[0] != t[2] {
                        tris.push(t);
                    }
                }
            }
            Mode::TriangleFan => {
                for i in 1..idx.len().saturating_sub(1) {
                    let t = [idx[0], idx[i], idx[i + 1]];
                    if t[0] != t[1] && t[1] != t[2] && t[0] != t[2] {
                        tris.push(t);
                    }
                }
            }
            _ => {}
        }
        let image = prim
            .material()
            .pbr_metallic_roughness()
            .base_color_texture()
            .map(|info| info.texture().source().index());
        out.push(Some(Prim {
            positions,
            normals,
            colors,
            uvs,
            tris,
            image,
        }));
    }
    Ok(out)
}

/// Append the primitives of `mesh`, transformed by `world`, to `acc`. The accessors of a mesh are
/// read once (`cache`, by mesh index); the vertex and triangle budgets are checked on the running
/// totals before anything is appended.
fn read_mesh(
    mesh: &gltf::Mesh,
    world: glam::Mat4,
    buffers: &Buffers,
    path: &Path,
    acc: &mut Acc,
    doc: &gltf::Document,
    cache: &mut [Option<Arc<Vec<Option<Prim>>>>],
) -> Result<()> {
    let prims = match &cache[mesh.index()] {
        Some(p) => p.clone(),
        None => {
            let p = Arc::new(read_prims(mesh, buffers, path, acc.positions.len())?);
            cache[mesh.index()] = Some(p.clone());
            p
        }
    };
    let normal_m = glam::Mat3::from_mat4(world).inverse().transpose();
    let flip = glam::Mat3::from_mat4(world).determinant() < 0.0;
    for prim in prims.iter().flatten() {
        let nv = prim.positions.len();
        let base = acc.positions.len();
        let total = base.saturating_add(nv);
        if total > MAX_VERTICES {
            return Err(over_budget(path, total));
        }
        let faces = acc.faces.len().saturating_add(prim.tris.len());
        if faces > MAX_FACES {
            return Err(Error::format(
                path,
                format!(
                    "{faces} triangles (primitives times the nodes that instance them) exceed the budget of {MAX_FACES}"
                ),
            ));
        }
        acc.positions.extend(
            prim.positions
                .iter()
                .map(|&p| world.transform_point3(glam::Vec3::from(p)).to_array()),
        );
        match &prim.normals {
            Some(n) => {
                acc.normals.extend(n.iter().map(|&v| {
                    (normal_m * glam::Vec3::from(v))
                        .normalize_or_zero()
                        .to_array()
                }));
                acc.has_normals.push(true);
            }
            None => {
                acc.normals.extend(std::iter::repeat_n([0.0; 3], nv));
                acc.has_normals.push(false);
            }
        }
        match &prim.colors {
            Some(c) => {
                if !acc.any_colors {
                    acc.colors = vec![[1.0; 3]; base];
                    acc.any_colors = true;
                }
                acc.colors.extend_from_slice(c);
            }
            None => {
                if acc.any_colors {
                    acc.colors.extend(std::iter::repeat_n([1.0; 3], nv));
                }
            }
        }
        if prim.uvs.is_some() && !acc.any_uvs {
            acc.uvs = vec![[0.0; 2]; 3 * acc.faces.len()];
            acc.any_uvs = true;
        }
        for t in &prim.tris {
            let mut t = *t;
            if flip {
                t.swap(1, 2);
            }
            if acc.any_uvs {
                for &v in t.iter() {
                    acc.uvs.push(match &prim.uvs {
                        Some(u) => u[v as usize],
                        None => [0.0; 2],
                    });
                }
            }
            acc.faces.push(t.map(|v| v + base as u32));
        }
        // Base colour texture of the material (the first one found is used).
        if let Some(src) = prim.image {
            match acc.texture_source {
                None if !acc.texture_failed => {
                    let img = doc
                        .images()
                        .nth(src)
                        .ok_or_else(|| Error::format(path, "image index out of range"))?;
                    match read_image(&img, doc, buffers, path) {
                        Ok(t) => {
                            acc.texture = Some(Arc::new(t));
                            acc.texture_source = Some(src);
                        }
                        Err(e) => {
                            acc.texture_failed = true;
                            warn(format!(
                                "texture not loaded ({e}); continuing without texture"
                            ));
                        }
                    }
                }
                Some(i) if i != src => {
                    warn(format!(
                        "{}: several base colour textures; only image {i} is used",
                        path.display()
                    ));
                }
                _ => {}
            }
        }
    }
    Ok(())
}

/// Everything needed to write one glTF primitive: split vertices, attributes, embedded PNG.
struct GlbData {
    json: serde_json::Value,
    bin: Vec<u8>,
}

/// Append `data` to `bin` at a 4-byte aligned offset, returning (offset, length).
fn push_aligned(bin: &mut Vec<u8>, data: &[u8]) -> (usize, usize) {
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let off = bin.len();
    bin.extend_from_slice(data);
    (off, data.len())
}

fn f32_bytes(v: impl Iterator<Item = f32>) -> Vec<u8> {
    v.flat_map(f32::to_le_bytes).collect()
}

/// Build the glTF JSON and binary buffer for `mesh`. Vertices whose corners carry different UVs
/// or normals (smooth normals split at sharp edges, when the mesh has none of its own) are split:
/// output vertices 0..N are the mesh's vertices in order, the copies follow.
///
/// The steps: [`split_vertices`], [`write_attributes`] (positions, normals, colours, UVs and
/// indices into the buffer), [`write_material`] (the material and its image) and [`root_json`].
fn build(
    mesh: &TriMesh,
    opts: &GlbOptions,
    path: &Path,
    image_uri: Option<&str>,
) -> Result<GlbData> {
    let uvs = mesh.uvs.as_ref().filter(|_| opts.texture);
    let corner_n = super::export_corner_normals(mesh);
    let split = split_vertices(mesh, uvs.map(|u| u.as_slice()), &corner_n);
    let mut w = BinWriter::default();
    let colors = mesh.colors.as_ref().filter(|_| opts.vertex_colors);
    let (attributes, indices) = write_attributes(&mut w, mesh, colors, uvs.is_some(), &split);
    let (material, images) = write_material(&mut w, mesh, uvs.is_some(), image_uri, path)?;
    while !w.bin.len().is_multiple_of(4) {
        w.bin.push(0);
    }
    let root = root_json(&w, attributes, indices, material, images);
    Ok(GlbData {
        json: root,
        bin: w.bin,
    })
}

/// The output vertices: per output vertex its source vertex, UV and normal, and the faces on
/// them.
struct SplitVertices {
    src: Vec<u32>,
    faces: Vec<[u32; 3]>,
    uv: Vec<[f32; 2]>,
    normals: Vec<[f32; 3]>,
}

/// Each vertex takes its first corner's UV and normal; a corner that differs gets a copy of the
/// vertex (one per distinct UV and normal), numbered after the mesh's vertices.
fn split_vertices(
    mesh: &TriMesh,
    uvs: Option<&[[f32; 2]]>,
    corner_n: &[[f32; 3]],
) -> SplitVertices {
    let n = mesh.num_vertices();
    // source vertex of every output vertex, output UV and normal, and output faces.
    let mut src: Vec<u32> = (0..n as u32).collect();
    let mut out_faces = mesh.faces.clone();
    let mut out_uv: Vec<[f32; 2]> = vec![[0.0; 2]; if uvs.is_some() { n } else { 0 }];
    let mut out_n: Vec<[f32; 3]> = match &mesh.normals {
        Some(nr) => nr.clone(),
        None => vec![[0.0, 0.0, 1.0]; n],
    };
    let mut assigned = vec![false; n];
    let mut copies: HashMap<(u32, [u32; 2], [u32; 3]), u32> = HashMap::new();
    for (f, face) in mesh.faces.iter().enumerate() {
        for k in 0..3 {
            let v = face[k] as usize;
            let uv = uvs.map_or([0.0; 2], |u| u[3 * f + k]);
            let nrm = corner_n[3 * f + k];
            if !assigned[v] {
                assigned[v] = true;
                if uvs.is_some() {
                    out_uv[v] = uv;
                }
                out_n[v] = nrm;
            } else if (uvs.is_some() && out_uv[v].map(f32::to_bits) != uv.map(f32::to_bits))
                || out_n[v].map(f32::to_bits) != nrm.map(f32::to_bits)
            {
                let key = (v as u32, uv.map(f32::to_bits), nrm.map(f32::to_bits));
                let id = *copies.entry(key).or_insert_with(|| {
                    src.push(v as u32);
                    if uvs.is_some() {
                        out_uv.push(uv);
                    }
                    out_n.push(nrm);
                    (src.len() - 1) as u32
                });
                out_faces[f][k] = id;
            }
        }
    }
    SplitVertices {
        src,
        faces: out_faces,
        uv: out_uv,
        normals: out_n,
    }
}

/// The binary buffer with its buffer views and accessors, as they are added.
#[derive(Default)]
struct BinWriter {
    bin: Vec<u8>,
    views: Vec<serde_json::Value>,
    accessors: Vec<serde_json::Value>,
}

impl BinWriter {
    /// Append `data` as a buffer view (with `target`, if any) read by accessor `acc`; returns
    /// the accessor's index.
    fn add(&mut self, data: Vec<u8>, target: Option<u32>, acc: serde_json::Value) -> usize {
        use serde_json::json;
        let (off, len) = push_aligned(&mut self.bin, &data);
        let mut view = json!({"buffer": 0, "byteOffset": off, "byteLength": len});
        if let Some(t) = target {
            view["target"] = json!(t);
        }
        self.views.push(view);
        let mut acc = acc;
        acc["bufferView"] = json!(self.views.len() - 1);
        self.accessors.push(acc);
        self.accessors.len() - 1
    }
}

/// Per-axis bounds of the finite coordinates (zero where there are none).
fn position_bounds(pos: &[[f32; 3]]) -> ([f32; 3], [f32; 3]) {
    let mut lo = [f32::INFINITY; 3];
    let mut hi = [f32::NEG_INFINITY; 3];
    for p in pos {
        for k in 0..3 {
            if p[k].is_finite() {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
    }
    if lo[0] > hi[0] {
        lo = [0.0; 3];
        hi = [0.0; 3];
    }
    (lo, hi)
}

/// The vertex attributes (POSITION with its bounds, NORMAL, COLOR_0 in linear light where
/// `colors`, TEXCOORD_0 with V down where `with_uv`) and the indices: the attributes' accessor
/// map and the indices' accessor.
fn write_attributes(
    w: &mut BinWriter,
    mesh: &TriMesh,
    colors: Option<&Vec<[f32; 3]>>,
    with_uv: bool,
    split: &SplitVertices,
) -> (serde_json::Map<String, serde_json::Value>, usize) {
    use serde_json::json;
    let src = &split.src;
    let m = src.len();
    let mut attributes = serde_json::Map::new();
    let pos: Vec<[f32; 3]> = src.iter().map(|&s| mesh.positions[s as usize]).collect();
    let (lo, hi) = position_bounds(&pos);
    let a = w.add(
        f32_bytes(pos.iter().flatten().copied()),
        Some(34962),
        json!({"componentType": 5126, "count": m, "type": "VEC3", "min": lo, "max": hi}),
    );
    attributes.insert("POSITION".into(), json!(a));
    let a = w.add(
        f32_bytes(split.normals.iter().flatten().copied()),
        Some(34962),
        json!({"componentType": 5126, "count": m, "type": "VEC3"}),
    );
    attributes.insert("NORMAL".into(), json!(a));
    if let Some(c) = colors {
        let a = w.add(
            f32_bytes(src.iter().flat_map(|&s| {
                c[s as usize].map(|x| crate::color::srgb_to_linear(x.clamp(0.0, 1.0)))
            })),
            Some(34962),
            json!({"componentType": 5126, "count": m, "type": "VEC3"}),
        );
        attributes.insert("COLOR_0".into(), json!(a));
    }
    if with_uv {
        let a = w.add(
            f32_bytes(split.uv.iter().flat_map(|uv| [uv[0], 1.0 - uv[1]])),
            Some(34962),
            json!({"componentType": 5126, "count": m, "type": "VEC2"}),
        );
        attributes.insert("TEXCOORD_0".into(), json!(a));
    }
    let ia = w.add(
        split
            .faces
            .iter()
            .flatten()
            .flat_map(|v| v.to_le_bytes())
            .collect(),
        Some(34963),
        json!({"componentType": 5125, "count": 3 * split.faces.len(), "type": "SCALAR"}),
    );
    (attributes, ia)
}

/// The material, and where the mesh has a texture and UVs its image: referred to by
/// `image_uri`, or else a PNG embedded in the buffer.
fn write_material(
    w: &mut BinWriter,
    mesh: &TriMesh,
    with_uv: bool,
    image_uri: Option<&str>,
    path: &Path,
) -> Result<(serde_json::Value, Vec<serde_json::Value>)> {
    use serde_json::json;
    let mut material = json!({
        "name": "material0",
        "pbrMetallicRoughness": {"baseColorFactor": [1.0, 1.0, 1.0, 1.0], "metallicFactor": 0.0, "roughnessFactor": 1.0},
        "doubleSided": false
    });
    let mut images = Vec::new();
    if let (Some(tex), true) = (&mesh.texture, with_uv) {
        if let Some(uri) = image_uri {
            images.push(json!({"uri": uri, "mimeType": "image/png"}));
        } else {
            let png = super::encode_png(tex, path)?;
            let (off, len) = push_aligned(&mut w.bin, &png);
            w.views
                .push(json!({"buffer": 0, "byteOffset": off, "byteLength": len}));
            images.push(json!({"bufferView": w.views.len() - 1, "mimeType": "image/png"}));
        }
        material["pbrMetallicRoughness"]["baseColorTexture"] = json!({"index": 0});
    }
    Ok((material, images))
}

/// The glTF document: one scene, node, mesh and primitive, with the sampler and texture where
/// there is an image.
fn root_json(
    w: &BinWriter,
    attributes: serde_json::Map<String, serde_json::Value>,
    ia: usize,
    material: serde_json::Value,
    images: Vec<serde_json::Value>,
) -> serde_json::Value {
    use serde_json::json;
    let mut root = json!({
        "asset": {"version": "2.0", "generator": "meshmatch"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": attributes, "indices": ia, "material": 0, "mode": 4}]}],
        "materials": [material],
        "buffers": [{"byteLength": w.bin.len()}],
        "bufferViews": w.views,
        "accessors": w.accessors,
    });
    if !images.is_empty() {
        root["images"] = json!(images);
        root["samplers"] =
            json!([{"magFilter": 9729, "minFilter": 9987, "wrapS": 10497, "wrapT": 10497}]);
        root["textures"] = json!([{"sampler": 0, "source": 0}]);
    }
    root
}

/// Write a binary glTF (GLB): POSITION, NORMAL (the mesh's own, else smooth normals split at sharp
/// edges by angle), COLOR_0 (linear), TEXCOORD_0 (V down) and an embedded PNG `baseColorTexture`,
/// as enabled by `opts` and present on the mesh. Output vertices 0..N are the mesh's vertices in
/// order; vertices with several corner UVs or normals get copies after them.
pub fn save_glb(mesh: &TriMesh, path: &Path, opts: &GlbOptions) -> Result<()> {
    check_exportable(mesh, path)?;
    let d = build(mesh, opts, path, None)?;
    let mut js = serde_json::to_vec(&d.json).map_err(|e| Error::format(path, e.to_string()))?;
    while !js.len().is_multiple_of(4) {
        js.push(b' ');
    }
    let total = 12 + 8 + js.len() + 8 + d.bin.len();
    if total > u32::MAX as usize {
        return Err(Error::InvalidInput(format!(
            "{}: mesh too large for GLB (over 4 GiB)",
            path.display()
        )));
    }
    let mut out = Vec::with_capacity(total);
    out.extend(b"glTF");
    out.extend(2u32.to_le_bytes());
    out.extend((total as u32).to_le_bytes());
    out.extend((js.len() as u32).to_le_bytes());
    out.extend(b"JSON");
    out.extend(&js);
    out.extend((d.bin.len() as u32).to_le_bytes());
    out.extend(b"BIN\0");
    out.extend(&d.bin);
    write_atomic(path, &out)
}

/// Write a glTF JSON file with its buffer as `<stem>.bin` and its texture (when written) as
/// `<stem>_texture.png` beside it, referred to by relative URIs; the same content and vertex order
/// as `save_glb`. The three files are written together ([`super::write_atomic_all`]), so a failed
/// write leaves none of them.
pub fn save_gltf(mesh: &TriMesh, path: &Path, opts: &GlbOptions) -> Result<()> {
    check_exportable(mesh, path)?;
    let textured = opts.texture && mesh.uvs.is_some();
    let image = if textured {
        super::texture_beside(mesh, path)?
    } else {
        None
    };
    let image_uri = image.as_ref().map(|(name, _, _)| uri_escape(name));
    let mut d = build(mesh, opts, path, image_uri.as_deref())?;
    let (bin_name, bin_path) = super::name_beside(path, ".bin");
    d.json["buffers"][0]["uri"] = serde_json::json!(uri_escape(&bin_name));
    let js = serde_json::to_vec_pretty(&d.json).map_err(|e| Error::format(path, e.to_string()))?;
    let mut files: Vec<(&Path, &[u8])> = vec![(bin_path.as_path(), &d.bin)];
    if let Some((_, tex_path, png)) = &image {
        files.push((tex_path.as_path(), png));
    }
    files.push((path, &js));
    super::write_atomic_all(&files)
}

/// A file name as a relative URI: every byte outside the unreserved set (and `/`) `%XX`-escaped.
fn uri_escape(name: &str) -> String {
    let mut out = String::with_capacity(name.len());
    for b in name.bytes() {
        if b.is_ascii_alphanumeric() || matches!(b, b'-' | b'_' | b'.' | b'~') {
            out.push(b as char);
        } else {
            out.push_str(&format!("%{b:02X}"));
        }
    }
    out
}
