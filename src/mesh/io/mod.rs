//! Mesh and image input/output: OBJ (+MTL), PLY, glTF/GLB; atomic writes.
//!
//! Loaders never weld or reorder vertices: vertex `i` of a loaded mesh is the file's vertex `i`
//! (for glTF: POSITION entries, primitives concatenated in file order). Polygons are triangulated
//! as fans; texture coordinates are stored per corner (`uvs[3 * f + k]`, V up). Loaders check
//! every count against the file size before allocating and return `Error::Format` naming the
//! file and the problem; they never panic on bad input. They do not call `repair`.

mod base64;
mod glb;
mod obj;
mod ply;

use crate::error::{Error, Result};
use crate::mesh::Texture;
use crate::mesh::TriMesh;
use std::path::{Path, PathBuf};
use std::sync::Arc;

pub use glb::{GlbOptions, load_gltf_bytes, save_glb, save_gltf};
pub use obj::{ObjOptions, load_obj_bytes, save_obj};
pub use ply::{PlyOptions, load_ply_bytes, save_ply};

/// Write `bytes` to `path` atomically: a temporary file beside it, flushed to disk (`sync_all`),
/// then a rename. On any failure the temporary file is removed and `path` is left untouched.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    write_atomic_all(&[(path, bytes)])
}

/// Write several files as one, as a mesh and the files beside it (an OBJ's material file and
/// texture): each to a temporary name beside it, then all renamed, the first first (inside a
/// [`StagedWrites`] group, at its commit). If any of them cannot be written none replaces
/// anything and no temporary is left, so a failed export leaves no sidecar behind.
pub fn write_atomic_all(files: &[(&Path, &[u8])]) -> Result<()> {
    if let Some((path, _)) = files.iter().find(|(p, _)| is_protected(p)) {
        return Err(Error::InvalidInput(format!(
            "{}: is a file this command read; not overwritten",
            path.display()
        )));
    }
    let mut temps: Vec<(PathBuf, PathBuf)> = Vec::with_capacity(files.len());
    for &(path, bytes) in files {
        match write_temporary(path, bytes) {
            Ok(tmp) => temps.push((tmp, path.to_path_buf())),
            Err(e) => {
                for (t, _) in &temps {
                    let _ = std::fs::remove_file(t);
                }
                written(&temps.into_iter().map(|t| t.0).collect::<Vec<_>>());
                return Err(e);
            }
        }
    }
    let names: Vec<PathBuf> = temps.iter().map(|t| t.0.clone()).collect();
    // Inside a group of staged writes the renames wait for the group's commit.
    if let Ok(mut g) = STAGED.lock()
        && let Some(list) = g.as_mut()
    {
        for (tmp, path) in temps {
            list.retain(|(_, p)| *p != path);
            list.push((tmp, path));
        }
        drop(g);
        written(&names);
        return Ok(());
    }
    let renamed = rename_all(temps);
    written(&names);
    renamed
}

/// Write `bytes` to a temporary file beside `path`, flushed to disk; returns its name.
fn write_temporary(path: &Path, bytes: &[u8]) -> Result<PathBuf> {
    use std::io::Write as _;
    let dir = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "out".into());
    let tmp = dir.join(format!(".{name}.tmp{}", std::process::id()));
    // known from before its first byte until the caller has staged or renamed it, so that an
    // interrupted command removes it too
    WRITING
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .push(tmp.clone());
    let done = std::fs::File::create(&tmp).and_then(|mut file| {
        file.write_all(bytes)?;
        file.sync_all()
    });
    if let Err(e) = done {
        let _ = std::fs::remove_file(&tmp);
        written(std::slice::from_ref(&tmp));
        return Err(Error::io(path, e));
    }
    Ok(tmp)
}

/// `temps` are no longer being written: staged, renamed or removed.
fn written(temps: &[PathBuf]) {
    WRITING
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .retain(|t| !temps.contains(t));
}

/// Temporary files being written right now ([`write_temporary`]).
static WRITING: std::sync::Mutex<Vec<PathBuf>> = std::sync::Mutex::new(Vec::new());

/// Rename each (temporary, destination) in order; on a failure remove the temporaries not yet
/// moved and report it.
fn rename_all(list: Vec<(PathBuf, PathBuf)>) -> Result<()> {
    let mut it = list.into_iter();
    while let Some((tmp, path)) = it.next() {
        if let Err(e) = std::fs::rename(&tmp, &path) {
            let _ = std::fs::remove_file(&tmp);
            for (t, _) in it {
                let _ = std::fs::remove_file(&t);
            }
            return Err(Error::io(&path, e));
        }
    }
    Ok(())
}

/// Files written under their temporary names while a [`StagedWrites`] group is open:
/// (temporary, final path).
static STAGED: std::sync::Mutex<Option<Vec<(PathBuf, PathBuf)>>> = std::sync::Mutex::new(None);

/// All or nothing for the outputs of one command: while the group is open, [`write_atomic`]
/// (every writer of meshes, textures, sidecars, CSVs and images) leaves each file under its
/// temporary name beside its destination; [`StagedWrites::commit`] renames them all at the end,
/// and dropping the group without a commit (an error, a panic) removes them, so no existing file
/// is replaced unless the whole command succeeded.
#[must_use = "commit the group, or drop it to discard its files"]
pub struct StagedWrites(());

impl StagedWrites {
    /// Open the group (the CLI does, around every subcommand).
    pub fn begin() -> StagedWrites {
        if let Ok(mut g) = STAGED.lock() {
            *g = Some(Vec::new());
        }
        StagedWrites(())
    }

    /// Move every staged file to its destination. A rename failing (which needs a destination
    /// that changed kind meanwhile) removes the files not yet moved and reports it.
    pub fn commit(self) -> Result<()> {
        COMMITTING.store(true, std::sync::atomic::Ordering::SeqCst);
        let list = STAGED
            .lock()
            .ok()
            .and_then(|mut g| g.take())
            .unwrap_or_default();
        MADE_FOLDERS
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .clear();
        rename_all(list)
    }
}

impl Drop for StagedWrites {
    fn drop(&mut self) {
        discard_staged();
    }
}

/// Folders made for outputs while a [`StagedWrites`] group is open, outermost first: a
/// command that fails or is interrupted removes them again (those left empty), so it leaves
/// the file system as it found it.
static MADE_FOLDERS: std::sync::Mutex<Vec<PathBuf>> = std::sync::Mutex::new(Vec::new());

/// `create_dir_all`, remembering the folders it made while a group is open.
pub fn create_folders(dir: &Path) -> std::io::Result<()> {
    let missing: Vec<PathBuf> = dir
        .ancestors()
        .take_while(|a| !a.as_os_str().is_empty() && std::fs::symlink_metadata(a).is_err())
        .map(Path::to_path_buf)
        .collect();
    let made = std::fs::create_dir_all(dir);
    if staging() {
        MADE_FOLDERS
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .extend(missing.into_iter().rev().filter(|d| d.is_dir()));
    }
    made
}

/// Set once a group's commit has begun: from then on its outputs are being delivered whole,
/// and an interrupt lets the command finish rather than leave some of them renamed and the
/// others not ([`committing`]).
static COMMITTING: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

/// True once the command's outputs are being put in place (a signal handler then lets the
/// command end as it would have).
pub fn committing() -> bool {
    COMMITTING.load(std::sync::atomic::Ordering::SeqCst)
}

/// True while a [`StagedWrites`] group is open (outputs wait for its commit).
pub fn staging() -> bool {
    STAGED.lock().map(|g| g.is_some()).unwrap_or(false)
}

/// Remove the files staged so far under their temporary names (a group dropped without a
/// commit, or a command interrupted by a signal, which runs no destructors).
pub fn discard_staged() {
    let list = STAGED.lock().unwrap_or_else(|e| e.into_inner()).take();
    for (tmp, _) in list.unwrap_or_default() {
        let _ = std::fs::remove_file(&tmp);
    }
    for tmp in WRITING.lock().unwrap_or_else(|e| e.into_inner()).drain(..) {
        let _ = std::fs::remove_file(&tmp);
    }
    // deepest first; a folder something else has meanwhile put a file in stays
    for dir in MADE_FOLDERS
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .drain(..)
        .rev()
    {
        let _ = std::fs::remove_dir(&dir);
    }
}

/// Files read so far, when [`protect_inputs`] was called (the CLI does; the app does not, so it
/// can save over a file it opened): canonical paths, and device and inode numbers (a hard link
/// is the same file under another name).
static PROTECTED: std::sync::Mutex<Option<Vec<ReadFile>>> = std::sync::Mutex::new(None);

/// A file read since [`protect_inputs`]: its canonical path, and its device and inode numbers.
type ReadFile = (PathBuf, Option<(u64, u64)>);

/// From now on, remember every file the loaders read (meshes, MTL files, textures, buffers,
/// correspondences, masks) and never write over one: [`write_atomic`] refuses it and a texture
/// written beside a mesh takes another name. For one-shot processes such as the CLI.
pub fn protect_inputs() {
    let mut g = PROTECTED.lock().unwrap_or_else(|e| e.into_inner());
    g.get_or_insert_with(Vec::new);
}

/// Device and inode numbers of an existing file.
fn inode(path: &Path) -> Option<(u64, u64)> {
    use std::os::unix::fs::MetadataExt as _;
    std::fs::metadata(path).ok().map(|m| (m.dev(), m.ino()))
}

fn note_input(path: &Path) {
    let mut g = PROTECTED.lock().unwrap_or_else(|e| e.into_inner());
    if let Some(list) = g.as_mut()
        && let Ok(c) = std::fs::canonicalize(path)
        && !list.iter().any(|(p, _)| *p == c)
    {
        list.push((c, inode(path)));
    }
}

/// True when `path` is a file read since [`protect_inputs`] (under any name).
pub fn is_protected(path: &Path) -> bool {
    let g = PROTECTED.lock().unwrap_or_else(|e| e.into_inner());
    match g.as_ref() {
        Some(list) if !list.is_empty() => {
            let id = inode(path);
            std::fs::canonicalize(path).is_ok_and(|c| {
                list.iter()
                    .any(|(p, i)| *p == c || (id.is_some() && *i == id))
            })
        }
        _ => false,
    }
}

/// Largest file a loader reads beside a mesh (an external glTF buffer or image, an MTL file, a
/// texture), and largest total of the external glTF buffers of one file: 2 GiB.
pub const MAX_FILE_BYTES: u64 = 2 << 30;

/// Largest mesh file read: 4 GiB (a text OBJ within the vertex budget can pass 2 GiB).
pub const MAX_MESH_FILE_BYTES: u64 = 4 << 30;

/// Read a file the loaders refer to (`what` names it in messages: "mesh", "texture", ...):
/// it must be a regular file (not a directory, device or pipe such as `/dev/zero` or
/// `/dev/stdin`) of at most `limit` bytes.
fn read_regular_file(file: &Path, limit: u64, what: &str) -> std::io::Result<Vec<u8>> {
    use std::io::{Error as IoError, ErrorKind, Read as _};
    let meta = std::fs::metadata(file)?;
    if !meta.is_file() {
        let kind = if meta.is_dir() {
            "a directory"
        } else {
            "not a regular file"
        };
        return Err(IoError::new(
            ErrorKind::InvalidInput,
            format!("{what} is {kind}"),
        ));
    }
    if meta.len() > limit {
        return Err(IoError::new(
            ErrorKind::InvalidInput,
            format!(
                "{what} has {} bytes, more than the limit of {limit}",
                meta.len()
            ),
        ));
    }
    let f = std::fs::File::open(file)?;
    note_input(file);
    let mut out = Vec::new();
    out.try_reserve_exact(meta.len() as usize).map_err(|_| {
        IoError::new(
            ErrorKind::OutOfMemory,
            format!("not enough memory to read {what} ({} bytes)", meta.len()),
        )
    })?;
    // The size may change while reading: never take more than the limit.
    f.take(limit + 1).read_to_end(&mut out)?;
    if out.len() as u64 > limit {
        return Err(IoError::new(
            ErrorKind::InvalidInput,
            format!("{what} grew past the limit of {limit} bytes while being read"),
        ));
    }
    Ok(out)
}

/// Largest auxiliary text file read (a correspondences JSON, a vertex mask, a session): 256 MiB.
pub const MAX_TEXT_FILE_BYTES: u64 = 256 << 20;

/// Read an input file that is not a mesh (correspondences, masks, sessions) by the loaders' rule:
/// a regular file (no directory, device or pipe such as `/dev/zero`) of at most `limit` bytes;
/// `what` names it in the message ("the correspondences file", ...).
pub fn read_input_file(path: &Path, limit: u64, what: &str) -> Result<Vec<u8>> {
    read_regular_file(path, limit, what).map_err(|e| Error::io(path, e))
}

/// [`read_input_file`] with [`MAX_TEXT_FILE_BYTES`], as UTF-8 text.
pub fn read_text_file(path: &Path, what: &str) -> Result<String> {
    let bytes = read_input_file(path, MAX_TEXT_FILE_BYTES, what)?;
    String::from_utf8(bytes).map_err(|_| Error::format(path, format!("{what} is not UTF-8 text")))
}

thread_local! {
    /// Warnings of the load in progress on this thread (see `warn`).
    static WARNINGS: std::cell::RefCell<Vec<String>> = const { std::cell::RefCell::new(Vec::new()) };
}

/// Note a warning of the load in progress; it is printed on stderr only if the load succeeds,
/// so a failed load prints exactly one line (its error).
fn warn(msg: String) {
    WARNINGS.with(|w| w.borrow_mut().push(msg));
}

/// Run a loader and return its result with the warnings it noted.
fn collect_warnings<T>(load: impl FnOnce() -> Result<T>) -> (Result<T>, Vec<String>) {
    let outer = WARNINGS.with(|w| std::mem::take(&mut *w.borrow_mut()));
    let res = load();
    let mine = WARNINGS.with(|w| std::mem::replace(&mut *w.borrow_mut(), outer));
    (res, mine)
}

/// Print warnings on stderr, one `warning: ...` line each.
pub fn print_warnings(warnings: &[String]) {
    use std::io::Write as _;
    let mut err = std::io::stderr().lock();
    for w in warnings {
        let _ = writeln!(err, "warning: {w}");
    }
}

/// Lines of a text file ending in `\n`, `\r\n` or a lone `\r` (classic Mac OS), without their
/// terminators; line `i` of the iterator is line `i + 1` of the file.
fn text_lines(bytes: &[u8]) -> impl Iterator<Item = &[u8]> {
    let mut rest = Some(bytes);
    std::iter::from_fn(move || {
        let r = rest?;
        match r.iter().position(|&b| b == b'\n' || b == b'\r') {
            Some(i) => {
                let skip = if r[i] == b'\r' && r.get(i + 1) == Some(&b'\n') {
                    2
                } else {
                    1
                };
                rest = Some(&r[i + skip..]);
                Some(&r[..i])
            }
            None => {
                rest = None;
                Some(r)
            }
        }
    })
}

/// The mesh formats this module reads and writes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MeshFormat {
    /// Wavefront OBJ (+ MTL + texture image).
    Obj,
    /// Stanford PLY (ascii or binary).
    Ply,
    /// glTF 2.0 JSON with external or data-URI buffers.
    Gltf,
    /// Binary glTF 2.0.
    Glb,
}

impl MeshFormat {
    /// The format named by a path's extension (case-insensitive), if any.
    pub fn from_path(path: &Path) -> Option<Self> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        match ext.as_str() {
            "obj" => Some(MeshFormat::Obj),
            "ply" => Some(MeshFormat::Ply),
            "gltf" => Some(MeshFormat::Gltf),
            "glb" => Some(MeshFormat::Glb),
            _ => None,
        }
    }

    fn name(self) -> &'static str {
        match self {
            MeshFormat::Obj => "an OBJ file",
            MeshFormat::Ply => "a PLY file",
            MeshFormat::Gltf => "a glTF file",
            MeshFormat::Glb => "a GLB file",
        }
    }
}

/// What a byte buffer looks like, judged from its first bytes (magic numbers, NUL bytes).
fn sniff(bytes: &[u8]) -> Option<&'static str> {
    const MAGICS: &[(&[u8], &str)] = &[
        (b"\x89PNG", "a PNG image"),
        (b"\xFF\xD8\xFF", "a JPEG image"),
        (b"GIF8", "a GIF image"),
        (b"%PDF", "a PDF document"),
        (b"PK\x03\x04", "a ZIP archive"),
        (b"\x1F\x8B", "gzip-compressed data"),
        (b"\x7FELF", "an executable"),
        (b"RIFF", "a RIFF (WebP/WAV/AVI) file"),
        (b"II*\0", "a TIFF image"),
        (b"MM\0*", "a TIFF image"),
        (b"BM", "a BMP image"),
        (b"glTF", "a binary glTF (GLB) file"),
        (b"ply", "a PLY file"),
        (b"solid ", "an STL file"),
    ];
    for (magic, what) in MAGICS {
        if bytes.starts_with(magic) {
            // "BM" and "solid " are plausible text starts; only trust them for binary-looking data.
            if (*what == "a BMP image" || *what == "an STL file") && !looks_binary(bytes) {
                continue;
            }
            return Some(what);
        }
    }
    let head = &bytes[..bytes.len().min(4096)];
    let first = head.iter().find(|b| !b.is_ascii_whitespace());
    if first == Some(&b'{') {
        return Some("a JSON (glTF) file");
    }
    if looks_binary(bytes) {
        return Some("binary data");
    }
    None
}

/// True when the first 4 KiB hold a NUL byte or many control characters.
fn looks_binary(bytes: &[u8]) -> bool {
    let head = &bytes[..bytes.len().min(4096)];
    let ctrl = head
        .iter()
        .filter(|&&b| b < 0x20 && !matches!(b, b'\n' | b'\r' | b'\t' | 0x0C))
        .count();
    head.contains(&0) || ctrl * 20 > head.len().max(1)
}

/// Refuse content that is clearly not `fmt` (e.g. a PNG renamed to .obj) with a one-line error.
fn check_content(bytes: &[u8], fmt: MeshFormat, path: &Path) -> Result<()> {
    if bytes.is_empty() {
        return Err(Error::format(path, "empty file"));
    }
    let kind = sniff(bytes);
    let ok = match fmt {
        MeshFormat::Obj => kind.is_none(),
        MeshFormat::Ply => bytes.starts_with(b"ply"),
        MeshFormat::Gltf | MeshFormat::Glb => matches!(
            kind,
            Some("a binary glTF (GLB) file") | Some("a JSON (glTF) file")
        ),
    };
    if ok {
        return Ok(());
    }
    let looks = kind.unwrap_or("text of another kind");
    Err(Error::format(
        path,
        format!("not {} (looks like {looks})", fmt.name()),
    ))
}

/// Load a mesh by file extension (.obj, .ply, .gltf, .glb, case-insensitive), checking that the
/// content matches the extension. Sets `path`, the identity `file_index` and `file_vertex_count`.
/// The file must be a regular file of at most `MAX_FILE_BYTES`. Warnings (a missing texture,
/// skipped faces) are printed on stderr only when the load succeeds.
pub fn load(path: &Path) -> Result<TriMesh> {
    let (mesh, warnings) = load_with_warnings(path)?;
    print_warnings(&warnings);
    Ok(mesh)
}

/// Like `load`, but returns the warnings instead of printing them, so a caller that may still
/// fail (e.g. on `check_usable`) can print exactly one error line.
pub fn load_with_warnings(path: &Path) -> Result<(TriMesh, Vec<String>)> {
    load_with_warnings_exact(path).map(|(m, w, _)| (m, w))
}

/// Like [`load_with_warnings`], with every vertex's coordinates as the file gives them too, at
/// its precision (double for OBJ, ASCII and double PLY; glTF stores single): what a command's
/// working units are computed from (`cli::common::WorkingUnits`).
pub fn load_with_warnings_exact(path: &Path) -> Result<(TriMesh, Vec<String>, Vec<[f64; 3]>)> {
    let fmt = MeshFormat::from_path(path)
        .ok_or_else(|| Error::UnsupportedFormat { path: path.into() })?;
    if fmt == MeshFormat::Ply
        && let Some(e) = ply_header_budget(path)
    {
        return Err(e);
    }
    let bytes =
        read_regular_file(path, MAX_MESH_FILE_BYTES, "the file").map_err(|e| Error::io(path, e))?;
    let (res, warnings) = load_format_bytes(&bytes, fmt, path);
    res.map(|(m, exact)| (m, warnings, exact))
}

/// Read the first 64 KiB of a regular PLY file and return the budget error of its header, if
/// any, so that a file declaring 300M vertices is refused before gigabytes are read.
fn ply_header_budget(path: &Path) -> Option<Error> {
    use std::io::Read as _;
    if !std::fs::metadata(path).ok()?.is_file() {
        return None;
    }
    let mut head = Vec::with_capacity(64 << 10);
    std::fs::File::open(path)
        .ok()?
        .take(64 << 10)
        .read_to_end(&mut head)
        .ok()?;
    ply::header_budget_error(&head, path)
}

/// Load a mesh from bytes, choosing the format by `path`'s extension; `path` names the file in
/// messages and is the base for relative references (MTL files, textures, glTF buffers).
/// Warnings are printed on stderr only when the load succeeds.
pub fn load_bytes(bytes: &[u8], path: &Path) -> Result<TriMesh> {
    let fmt = MeshFormat::from_path(path)
        .ok_or_else(|| Error::UnsupportedFormat { path: path.into() })?;
    let (res, warnings) = load_format_bytes(bytes, fmt, path);
    let (mesh, _) = res?;
    print_warnings(&warnings);
    Ok(mesh)
}

/// The mesh in `bytes` and its exact coordinates, with the warnings its loader noted.
type Loaded = (Result<(TriMesh, Vec<[f64; 3]>)>, Vec<String>);

fn load_format_bytes(bytes: &[u8], fmt: MeshFormat, path: &Path) -> Loaded {
    // A UTF-8 byte order mark (some Windows tools write one) is not part of the content.
    let bytes = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes);
    collect_warnings(|| match fmt {
        MeshFormat::Obj => obj::load_obj_bytes_exact(bytes, path),
        MeshFormat::Ply => ply::load_ply_bytes_exact(bytes, path),
        MeshFormat::Gltf | MeshFormat::Glb => glb::load_gltf_bytes_exact(bytes, path),
    })
}

/// Set the positions of a freshly parsed mesh from the file's coordinates `exact` (rounded to
/// single precision), fill its bookkeeping fields and check the per-corner UV length. Returns
/// the mesh and `exact`.
fn finish(
    mut mesh: TriMesh,
    exact: Vec<[f64; 3]>,
    path: &Path,
) -> Result<(TriMesh, Vec<[f64; 3]>)> {
    mesh.positions = exact.iter().map(|p| p.map(|x| x as f32)).collect();
    let n = mesh.positions.len();
    if n > u32::MAX as usize {
        return Err(Error::format(path, "more than 2^32 vertices"));
    }
    if let Some(f) = mesh.faces.iter().flatten().find(|&&v| v as usize >= n) {
        // Parsers check indices; this is a last line of defence against a parser bug.
        return Err(Error::format(
            path,
            format!("face references vertex {f} but the file has {n} vertices"),
        ));
    }
    if let Some(uv) = &mesh.uvs
        && uv.len() != 3 * mesh.faces.len()
    {
        return Err(Error::format(path, "texture coordinate count mismatch"));
    }
    for (what, len) in [
        ("normal", mesh.normals.as_ref().map(Vec::len)),
        ("colour", mesh.colors.as_ref().map(Vec::len)),
    ] {
        if let Some(l) = len
            && l != n
        {
            return Err(Error::format(path, format!("{what} count mismatch")));
        }
    }
    // A colour that is not a number (NaN or infinite, from a broken exporter) would reach every
    // system's statistics (a weathering's PCA, a transfer's patch distances) and fail far from
    // here; it is read as black, and said once with the file's name.
    if let Some(colors) = mesh.colors.as_mut() {
        let mut bad = 0usize;
        let mut first = None;
        for (i, c) in colors.iter_mut().enumerate() {
            if !c.iter().all(|x| x.is_finite()) {
                first.get_or_insert(i);
                bad += 1;
                *c = [0.0; 3];
            }
        }
        if let Some(first) = first {
            warn(format!(
                "{}: {bad} vertex colours are not numbers (the first at vertex {first}); read as \
                 black",
                path.display()
            ));
        }
    }
    mesh.file_index = (0..n as u32).collect();
    mesh.file_vertex_count = n;
    mesh.path = Some(path.to_path_buf());
    Ok((mesh, exact))
}

/// Load an image file (PNG or JPEG) as an sRGB RGB8 texture.
pub fn load_texture(path: &Path) -> Result<Texture> {
    let bytes =
        read_regular_file(path, MAX_FILE_BYTES, "the texture").map_err(|e| Error::io(path, e))?;
    let mut tex = decode_texture(&bytes, path)?;
    tex.path = Some(path.to_path_buf());
    Ok(tex)
}

/// Load an image file (PNG or JPEG) as an sRGB RGB8 texture and, when it has transparent pixels
/// (alpha below one half), its alpha channel.
pub fn load_texture_with_alpha(path: &Path) -> Result<(Texture, Option<image::GrayImage>)> {
    let bytes =
        read_regular_file(path, MAX_FILE_BYTES, "the image").map_err(|e| Error::io(path, e))?;
    let img = decode_image(&bytes, path)?;
    let alpha = img.color().has_alpha().then(|| {
        let rgba = img.to_rgba8();
        image::GrayImage::from_fn(rgba.width(), rgba.height(), |x, y| {
            image::Luma([rgba.get_pixel(x, y).0[3]])
        })
    });
    let alpha = alpha.filter(|a| a.pixels().any(|p| p.0[0] < 128));
    Ok((
        Texture {
            image: img.to_rgb8(),
            path: Some(path.to_path_buf()),
        },
        alpha,
    ))
}

fn decode_image(bytes: &[u8], path: &Path) -> Result<image::DynamicImage> {
    image::ImageReader::new(std::io::Cursor::new(bytes))
        .with_guessed_format()
        .map_err(|e| Error::io(path, e))?
        .decode()
        .map_err(|e| Error::format(path, format!("cannot decode image: {e}")))
}

/// Decode PNG/JPEG bytes into an RGB8 texture; `path` names the image in messages.
fn decode_texture(bytes: &[u8], path: &Path) -> Result<Texture> {
    Ok(Texture {
        image: decode_image(bytes, path)?.to_rgb8(),
        path: None,
    })
}

/// Load a texture referenced by a mesh file; failures become a warning (see `warn`) and `None`.
fn load_texture_or_warn(tex_path: &Path, mesh_path: &Path) -> Option<Arc<Texture>> {
    match load_texture(tex_path) {
        Ok(t) => Some(Arc::new(t)),
        Err(e) => {
            warn(format!(
                "{}: texture not loaded ({e}); continuing without texture",
                mesh_path.display()
            ));
            None
        }
    }
}

/// Encode a texture as PNG bytes.
fn encode_png(tex: &Texture, path: &Path) -> Result<Vec<u8>> {
    let mut out = Vec::new();
    tex.image
        .write_to(&mut std::io::Cursor::new(&mut out), image::ImageFormat::Png)
        .map_err(|e| Error::format(path, format!("cannot encode PNG: {e}")))?;
    Ok(out)
}

/// The name of a file written beside an exported mesh, `<stem><suffix>` (`_texture.png`,
/// `.bin`), never that of a file this command read (`convert spot.obj spot.ply` beside the
/// source's `spot_texture.png`): then `<stem>_<ext><suffix>`, numbered if need be.
fn name_beside(path: &Path, suffix: &str) -> (String, PathBuf) {
    let stem = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "mesh".into());
    let mut name = format!("{stem}{suffix}");
    let mut side = path.with_file_name(&name);
    let mut k = 1;
    while is_protected(&side) {
        let ext = path
            .extension()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default();
        let (base, dot) = suffix.rsplit_once('.').unwrap_or((suffix, ""));
        name = if k == 1 {
            format!("{stem}_{ext}{suffix}")
        } else {
            format!("{stem}_{ext}{base}_{k}.{dot}")
        };
        side = path.with_file_name(&name);
        k += 1;
    }
    (name, side)
}

/// The texture of `mesh` to write beside `path`, if it has one (see [`name_beside`]): its file
/// name, path and PNG bytes (written by the caller with the mesh, through
/// [`write_atomic_all`]).
fn texture_beside(mesh: &TriMesh, path: &Path) -> Result<Option<(String, PathBuf, Vec<u8>)>> {
    let Some(tex) = &mesh.texture else {
        return Ok(None);
    };
    let (name, tex_path) = name_beside(path, "_texture.png");
    let png = encode_png(tex, &tex_path)?;
    Ok(Some((name, tex_path, png)))
}

/// Save a mesh by file extension (.ply binary, .obj + .mtl + .png, .glb, .gltf) with default
/// options; the exported file keeps the mesh's vertex order.
pub fn save(mesh: &TriMesh, path: &Path) -> Result<()> {
    match MeshFormat::from_path(path) {
        Some(MeshFormat::Ply) => save_ply(mesh, path, &PlyOptions::default()),
        Some(MeshFormat::Obj) => save_obj(mesh, path, &ObjOptions::default()),
        Some(MeshFormat::Glb) => save_glb(mesh, path, &GlbOptions::default()),
        Some(MeshFormat::Gltf) => save_gltf(mesh, path, &GlbOptions::default()),
        None => Err(Error::UnsupportedFormat { path: path.into() }),
    }
}

/// Check a mesh is consistent enough to export (indices in range, attribute lengths).
fn check_exportable(mesh: &TriMesh, path: &Path) -> Result<()> {
    let n = mesh.num_vertices();
    let bad = |msg: &str| Err(Error::InvalidInput(format!("{}: {msg}", path.display())));
    if mesh.faces.iter().flatten().any(|&v| v as usize >= n) {
        return bad("face index out of range");
    }
    if mesh
        .uvs
        .as_ref()
        .is_some_and(|u| u.len() != 3 * mesh.faces.len())
    {
        return bad("uvs must have 3 entries per face");
    }
    if mesh.normals.as_ref().is_some_and(|v| v.len() != n) {
        return bad("normals must have one entry per vertex");
    }
    if mesh.colors.as_ref().is_some_and(|v| v.len() != n) {
        return bad("colors must have one entry per vertex");
    }
    Ok(())
}

/// The normal of every corner an export writes (`3 * f + k`): the mesh's own per-vertex normals
/// when it has them, else smooth normals split at sharp edges by angle
/// ([`crate::mesh::corner_normals`], as the app draws), so no exported mesh shades flat.
pub fn export_corner_normals(mesh: &TriMesh) -> Vec<[f32; 3]> {
    match &mesh.normals {
        Some(nr) => mesh
            .faces
            .iter()
            .flat_map(|f| f.map(|v| nr[v as usize]))
            .collect(),
        None => {
            crate::mesh::corner_normals(&mesh.positions, &mesh.faces, crate::mesh::SHARP_ANGLE_DEG)
        }
    }
}

/// The normal of every vertex an export writes where a format has one normal per vertex (PLY):
/// the mesh's own, else area-weighted vertex normals.
pub fn export_vertex_normals(mesh: &TriMesh) -> Vec<[f32; 3]> {
    match &mesh.normals {
        Some(nr) => nr.clone(),
        None => crate::mesh::vertex_normals(&mesh.positions, &mesh.faces),
    }
}

/// Per-vertex UVs when every corner of each vertex carries the same UV (exact bit equality);
/// vertices used by no face get (0, 0).
fn per_vertex_uvs(mesh: &TriMesh) -> Option<Vec<[f32; 2]>> {
    let uvs = mesh.uvs.as_ref()?;
    let mut out: Vec<Option<[f32; 2]>> = vec![None; mesh.num_vertices()];
    for (f, face) in mesh.faces.iter().enumerate() {
        for k in 0..3 {
            let uv = uvs[3 * f + k];
            let slot = &mut out[face[k] as usize];
            match slot {
                None => *slot = Some(uv),
                Some(prev) => {
                    if prev.map(f32::to_bits) != uv.map(f32::to_bits) {
                        return None;
                    }
                }
            }
        }
    }
    Some(out.into_iter().map(|u| u.unwrap_or([0.0; 2])).collect())
}

/// Triangulate a polygon as a fan around its first corner, appending `(a, b, c)` corner triples.
fn fan(n: usize, mut emit: impl FnMut(usize, usize, usize)) {
    for i in 1..n.saturating_sub(1) {
        emit(0, i, i + 1);
    }
}
