//! Helpers shared by the subcommands: loading, output paths, progress bars, masks, solver flags.

use std::io::IsTerminal;
use std::path::Path;

use crate::error::{Error, Result};
use crate::mesh::{TriMesh, io};
use crate::work::Event;

/// Lines saying what a command wrote ("wrote out.glb"), held until its outputs are in place:
/// every output is written under a temporary name and renamed when the whole command succeeded
/// (`mesh::io::StagedWrites`), so a line printed earlier could name a file that a failure or an
/// interrupt then never delivers.
static ANNOUNCED: std::sync::Mutex<Vec<String>> = std::sync::Mutex::new(Vec::new());

/// Say `line` on stderr once the command's outputs are in place (at once outside a command,
/// where nothing is staged).
pub fn announce(line: String) {
    if io::staging() {
        ANNOUNCED
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .push(line);
    } else {
        eprintln!("{line}");
    }
}

/// [`announce`] "wrote `path`".
pub fn announce_written(path: &Path) {
    announce(format!("wrote {}", path.display()));
}

/// The lines held by [`announce`], taken: printed by the caller after a commit, dropped after a
/// failure.
pub(crate) fn take_announced() -> Vec<String> {
    std::mem::take(&mut *ANNOUNCED.lock().unwrap_or_else(|e| e.into_inner()))
}

/// Load a mesh the engine can work on: `check_usable` and [`check_geometry`]. Loader warnings
/// are printed only when every check passes, so a refused file is one line.
pub fn load_usable(path: &Path) -> Result<TriMesh> {
    load_usable_exact(path).map(|(m, _)| m)
}

/// [`load_usable`], with the file's coordinates at its own precision.
fn load_usable_exact(path: &Path) -> Result<(TriMesh, Vec<[f64; 3]>)> {
    let (m, mut warnings, exact) = io::load_with_warnings_exact(path)?;
    let (m, more) = make_usable(m, path)?;
    warnings.extend(more);
    io::print_warnings(&warnings);
    Ok((m, exact))
}

/// The working units of one command, so that the same inputs in millimetres, metres or inches
/// give the same result. The first mesh the command takes fixes the unit: its own bounding-box
/// diagonal, computed from the file's digits at the file's precision; every mesh is put in that
/// unit (each coordinate divided by it before the rounding to single precision), lengths
/// given on the command line are divided by it, and every mesh written is multiplied back (a
/// vertex where an input had one gets that input's own coordinates, so a transfer's output
/// keeps its target's positions bit for bit). The same shape scaled (the same digits) thus
/// reaches the systems as the same numbers, and every choice a system makes is the same. The
/// Python package takes its meshes through the same door ([`WorkingUnits::adopt`]), so its
/// results are the command line's.
#[derive(Debug, Default)]
pub struct WorkingUnits {
    unit: Option<f64>,
    /// The file coordinates of every taken vertex, by its working coordinates' bits.
    file_positions: std::collections::HashMap<[u32; 3], [f32; 3]>,
}

impl WorkingUnits {
    /// No mesh taken yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// The file length of one working unit (1 before any mesh is taken).
    pub fn unit(&self) -> f64 {
        self.unit.unwrap_or(1.0)
    }

    /// [`load_usable`] in these units (the first mesh fixes them).
    pub fn load(&mut self, path: &Path) -> Result<TriMesh> {
        let (m, exact) = load_usable_exact(path)?;
        Ok(self.adopt(m, Some(&exact)))
    }

    /// `mesh` (in file units, usable) in these units; `exact` are its coordinates at the file's
    /// precision where known (else its own). The first mesh fixes the unit.
    pub fn adopt(&mut self, mut mesh: TriMesh, exact: Option<&[[f64; 3]]>) -> TriMesh {
        let own: Vec<[f64; 3]>;
        let raw = match exact.filter(|e| e.len() == mesh.positions.len()) {
            Some(e) => e,
            None => {
                own = mesh.positions.iter().map(|p| p.map(f64::from)).collect();
                &own
            }
        };
        let unit = *self.unit.get_or_insert_with(|| {
            let d = diagonal(raw);
            if d.is_finite() && d > 0.0 { d } else { 1.0 }
        });
        // a coordinate beyond single precision in its own units stays infinite, so that
        // `make_usable` refused the mesh already
        let working: Vec<[f32; 3]> = raw
            .iter()
            .map(|p| {
                p.map(|x| {
                    let f = x as f32;
                    if f.is_finite() { (x / unit) as f32 } else { f }
                })
            })
            .collect();
        if self.unit() != 1.0 {
            for (w, f) in working.iter().zip(&mesh.positions) {
                self.file_positions.entry(w.map(f32::to_bits)).or_insert(*f);
            }
        }
        mesh.positions = working;
        mesh
    }

    /// [`load_signal_source`] in these units.
    pub fn load_signal_source(&mut self, path: &Path, texture: Option<&Path>) -> Result<TriMesh> {
        let source = self.load(path)?;
        with_signal(source, path, texture)
    }

    /// A length given in file units (a command-line option), in working units.
    pub fn length(&self, x: f32) -> f32 {
        (x as f64 / self.unit()) as f32
    }

    /// A length in working units, in file units (for messages).
    pub fn file_length(&self, x: f32) -> f32 {
        (x as f64 * self.unit()) as f32
    }

    /// A point in working units, in file units.
    pub fn file_point(&self, p: [f32; 3]) -> [f32; 3] {
        p.map(|x| self.file_length(x))
    }

    /// A point in working units, in file units: an input vertex's own coordinates where it is
    /// one.
    pub fn file_position(&self, p: [f32; 3]) -> [f32; 3] {
        match self.file_positions.get(&p.map(f32::to_bits)) {
            Some(f) => *f,
            None => self.file_point(p),
        }
    }

    /// `mesh` (in working units) back in file units.
    pub fn to_file<'a>(&self, mesh: &'a TriMesh) -> std::borrow::Cow<'a, TriMesh> {
        if self.unit() == 1.0 {
            return std::borrow::Cow::Borrowed(mesh);
        }
        let mut m = mesh.clone();
        for p in &mut m.positions {
            *p = self.file_position(*p);
        }
        std::borrow::Cow::Owned(m)
    }

    /// Save `mesh` (in working units) to `path` in file units.
    pub fn save(&self, mesh: &TriMesh, path: &Path) -> Result<()> {
        io::save(&self.to_file(mesh), path)
    }
}

/// The bounding-box diagonal of the points of `raw` finite in single precision, in double
/// precision (0 for none).
fn diagonal(raw: &[[f64; 3]]) -> f64 {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for p in raw
        .iter()
        .filter(|p| p.iter().all(|&x| (x as f32).is_finite()))
    {
        for k in 0..3 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    if lo[0] > hi[0] {
        return 0.0;
    }
    (0..3).map(|k| (hi[k] - lo[k]).powi(2)).sum::<f64>().sqrt()
}

/// A mesh made ready for the engine the way [`load_usable`] makes a file's (`check_usable`,
/// [`check_geometry`], duplicate faces dropped, the valence checked), `name` naming it in the
/// messages; returns the warnings for the caller to show. Meshes made in memory (the Python
/// package) go through it too, so they are refused in the same words.
pub fn make_usable(mut m: TriMesh, name: &Path) -> Result<(TriMesh, Vec<String>)> {
    let mut warnings = Vec::new();
    m.check_usable()?;
    check_geometry(&m, name)?;
    let dups = drop_duplicate_faces(&mut m);
    if dups > 0 {
        warnings.push(format!(
            "{}: {dups} duplicate faces (same three vertices as an earlier face) ignored",
            name.display()
        ));
    }
    check_valence(&m, name)?;
    Ok((m, warnings))
}

/// Most triangles one vertex may be a corner of (a fan-triangulated polygon of a million corners
/// would make the hierarchy's edge collapses quadratic).
pub const MAX_VALENCE: usize = 10_000;

/// Remove faces with the same vertex set as an earlier face (their per-corner UVs too); the
/// vertices and their order are kept. Returns how many were removed.
fn drop_duplicate_faces(m: &mut TriMesh) -> usize {
    let mut seen = std::collections::HashSet::with_capacity(m.faces.len());
    let keep: Vec<bool> = m
        .faces
        .iter()
        .map(|f| {
            let mut k = *f;
            k.sort_unstable();
            seen.insert(k)
        })
        .collect();
    let removed = keep.iter().filter(|&&k| !k).count();
    if removed == 0 {
        return 0;
    }
    if let Some(uvs) = m.uvs.as_mut().filter(|u| u.len() == 3 * keep.len()) {
        let mut i = 0;
        uvs.retain(|_| {
            let k = keep[i / 3];
            i += 1;
            k
        });
    }
    let mut i = 0;
    m.faces.retain(|_| {
        let k = keep[i];
        i += 1;
        k
    });
    removed
}

/// Refuse a vertex that is a corner of more than [`MAX_VALENCE`] triangles.
fn check_valence(m: &TriMesh, path: &Path) -> Result<()> {
    let mut count = vec![0u32; m.positions.len()];
    for f in &m.faces {
        for &v in f {
            if let Some(c) = count.get_mut(v as usize) {
                *c = c.saturating_add(1);
            }
        }
    }
    if let Some((v, &c)) = count
        .iter()
        .enumerate()
        .find(|&(_, &c)| c as usize > MAX_VALENCE)
    {
        let file_v = m.file_index.get(v).copied().unwrap_or(v as u32);
        return Err(Error::InvalidMesh(format!(
            "{}: vertex {file_v} is a corner of {c} triangles (at most {MAX_VALENCE}); a polygon \
             with that many corners must be triangulated or remeshed first",
            path.display()
        )));
    }
    Ok(())
}

/// Smallest and largest bounding-box diagonal accepted by the engine's commands.
pub const MIN_EXTENT: f64 = 1e-12;
/// See [`MIN_EXTENT`].
pub const MAX_EXTENT: f64 = 1e12;

/// Refuse geometry the engine cannot work on, with a message naming the file: a vertex with a
/// NaN or infinite coordinate (a text value beyond ±3.4e38 reads as infinite), no face of
/// positive area (every vertex at one point, or on one line), or a size outside
/// [`MIN_EXTENT`]..[`MAX_EXTENT`]. Every command that synthesises refuses the same way.
pub fn check_geometry(m: &TriMesh, path: &Path) -> Result<()> {
    let name = path.display();
    if let Some((i, p)) = m
        .positions
        .iter()
        .enumerate()
        .find(|(_, p)| !p.iter().all(|x| x.is_finite()))
    {
        let file_i = m.file_index.get(i).copied().unwrap_or(i as u32);
        return Err(Error::InvalidMesh(format!(
            "{name}: vertex {file_i} has a coordinate that is not a finite number ({} {} {}); \
             fix or remove it (values beyond ±3.4e38 read as infinite)",
            p[0], p[1], p[2]
        )));
    }
    let (mut lo, mut hi) = ([f64::MAX; 3], [f64::MIN; 3]);
    for p in &m.positions {
        for k in 0..3 {
            lo[k] = lo[k].min(p[k] as f64);
            hi[k] = hi[k].max(p[k] as f64);
        }
    }
    let has_area = m.faces.iter().any(|f| {
        if f[0] == f[1] || f[1] == f[2] || f[0] == f[2] {
            return false;
        }
        let [a, b, c] = f.map(|i| {
            let p = m.positions[i as usize];
            [p[0] as f64, p[1] as f64, p[2] as f64]
        });
        let (u, v) = (
            [b[0] - a[0], b[1] - a[1], b[2] - a[2]],
            [c[0] - a[0], c[1] - a[1], c[2] - a[2]],
        );
        let n = [
            u[1] * v[2] - u[2] * v[1],
            u[2] * v[0] - u[0] * v[2],
            u[0] * v[1] - u[1] * v[0],
        ];
        n[0] * n[0] + n[1] * n[1] + n[2] * n[2] > 0.0
    });
    if !has_area {
        return Err(Error::InvalidMesh(format!(
            "{name}: {} degenerate (zero area or repeated vertices)",
            crate::mesh::all_faces(m.faces.len())
        )));
    }
    let diag = (0..3).map(|k| (hi[k] - lo[k]).powi(2)).sum::<f64>().sqrt();
    if !(MIN_EXTENT..=MAX_EXTENT).contains(&diag) {
        return Err(Error::InvalidMesh(format!(
            "{name}: the mesh spans {diag:.3e} units, outside the supported {MIN_EXTENT:e} to \
             {MAX_EXTENT:e}; rescale it"
        )));
    }
    Ok(())
}

/// What an output path must be.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OutKind {
    /// A mesh: .ply, .glb, .gltf or .obj.
    Mesh,
    /// A PNG image.
    #[cfg_attr(not(feature = "gui"), allow(dead_code))]
    Png,
    /// Any file name (CSV, text).
    File,
}

/// The given input paths (optional ones left out), for [`check_outputs`].
pub fn input_paths<'a>(paths: &[Option<&'a std::path::PathBuf>]) -> Vec<&'a Path> {
    paths.iter().flatten().map(|p| p.as_path()).collect()
}

/// Where a path leads, for comparing outputs with inputs and with each other whatever the
/// spelling (`out/o.ply`, `./out//o.ply`, `out/../out/o.ply`) or the links on the way: the path
/// resolved one component at a time as the system will once its folders exist (symbolic links
/// followed, dangling ones included; `..` after a folder that does not exist yet undoes it),
/// plus the device and inode of the file when it exists (a hard link is the same file under
/// another name).
#[derive(Debug)]
struct Location {
    path: std::path::PathBuf,
    inode: Option<(u64, u64)>,
}

impl Location {
    fn same(&self, other: &Location) -> bool {
        self.path == other.path || (self.inode.is_some() && self.inode == other.inode)
    }
}

/// Whether paths `a` and `b` lead to the same file, whatever their spelling or the links on the
/// way ([`Location`]); false when either cannot be resolved.
pub fn same_location(a: &Path, b: &Path) -> bool {
    match (locate("", a), locate("", b)) {
        (Ok(a), Ok(b)) => a.same(&b),
        _ => false,
    }
}

/// The [`Location`] of `p`; an error naming `flag` when a folder on its way is a file
/// ("--out a/b.ply: a is a file, not a folder").
fn locate(flag: &str, p: &Path) -> Result<Location> {
    use std::collections::VecDeque;
    use std::os::unix::fs::MetadataExt as _;
    use std::path::{Component, PathBuf};
    let inode = std::fs::metadata(p).ok().map(|m| (m.dev(), m.ino()));
    let start = if p.is_absolute() {
        PathBuf::from("/")
    } else {
        std::env::current_dir().map_err(|e| Error::io(Path::new("."), e))?
    };
    // (component, the user's spelling of the path up to it; None inside a link's target)
    let mut queue: VecDeque<(PathBuf, Option<PathBuf>)> = VecDeque::new();
    let mut shown = PathBuf::new();
    for c in p.components() {
        shown.push(c);
        queue.push_back((PathBuf::from(c.as_os_str()), Some(shown.clone())));
    }
    let mut path = start;
    let mut links = 0;
    while let Some((c, spelt)) = queue.pop_front() {
        match c.components().next() {
            Some(Component::RootDir) => path = PathBuf::from("/"),
            Some(Component::ParentDir) => {
                path.pop();
            }
            Some(Component::Normal(n)) => {
                let next = path.join(n);
                match std::fs::symlink_metadata(&next) {
                    Ok(m) if m.file_type().is_symlink() && links < 40 => {
                        links += 1;
                        let target = std::fs::read_link(&next).map_err(|e| Error::io(&next, e))?;
                        // The link's own spelling names where its target ends.
                        let mut last = spelt;
                        for t in target.components().rev() {
                            queue.push_front((PathBuf::from(t.as_os_str()), last.take()));
                        }
                        continue;
                    }
                    Ok(m) if !m.is_dir() && !queue.is_empty() => {
                        let name = spelt.unwrap_or_else(|| next.clone());
                        return Err(Error::InvalidInput(format!(
                            "{flag} {}: {} is a file, not a folder",
                            p.display(),
                            name.display()
                        )));
                    }
                    _ => path = next,
                }
            }
            _ => {}
        }
    }
    Ok(Location { path, inode })
}

/// The files an output writes beside itself when its mesh has a texture: an OBJ's material
/// file and texture (`<stem>.mtl`, `<stem>_texture.png`), a PLY's texture; no other output may
/// take their names.
fn sidecars(p: &Path) -> Vec<(&'static str, std::path::PathBuf)> {
    let ext = p
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase());
    let Some(stem) = p.file_stem().map(|s| s.to_string_lossy().into_owned()) else {
        return Vec::new();
    };
    let texture = ("texture", p.with_file_name(format!("{stem}_texture.png")));
    match ext.as_deref() {
        Some("obj") => vec![
            ("material file", p.with_file_name(format!("{stem}.mtl"))),
            texture,
        ],
        Some("ply") => vec![texture],
        _ => Vec::new(),
    }
}

/// Check every output before any work: the extension its kind needs, not a directory, its
/// folder not a file, and distinct from every input and from each other (and from the files an
/// OBJ output writes beside itself) by where it leads, not how it is spelt (`outputs` are
/// `(flag, path, kind)`); then create their folders. A command that passes this writes nothing
/// until its work has succeeded.
pub fn check_outputs(inputs: &[&Path], outputs: &[(&str, &Path, OutKind)]) -> Result<()> {
    let mut ins = Vec::with_capacity(inputs.len());
    for p in inputs {
        // An input's folder being a file fails when it is read, with the reader's message.
        if let Ok(l) = locate("", p) {
            ins.push(l);
        }
    }
    // (what claims it, its location): each output and the files it writes beside itself.
    let mut seen: Vec<(String, Location)> = Vec::new();
    for &(flag, p, kind) in outputs {
        let ext = p
            .extension()
            .and_then(|e| e.to_str())
            .map(|e| e.to_ascii_lowercase());
        let want = match kind {
            OutKind::Mesh if !matches!(ext.as_deref(), Some("ply" | "glb" | "gltf" | "obj")) => {
                Some(".ply, .glb, .gltf or .obj")
            }
            OutKind::Png if ext.as_deref() != Some("png") => Some(".png"),
            _ => None,
        };
        if p.is_dir() || p.as_os_str().to_string_lossy().ends_with('/') {
            return Err(Error::InvalidInput(format!(
                "{flag} {}: is a directory; give a file name",
                p.display()
            )));
        }
        if let Ok(meta) = std::fs::metadata(p)
            && !meta.is_file()
        {
            return Err(Error::InvalidInput(format!(
                "{flag} {}: is not a regular file",
                p.display()
            )));
        }
        if let Some(want) = want {
            return Err(Error::InvalidInput(format!(
                "{flag} {}: must end in {want}",
                p.display()
            )));
        }
        let here = locate(flag, p)?;
        if ins.iter().any(|i| i.same(&here)) {
            return Err(Error::InvalidInput(format!(
                "{flag} {}: is also an input of this command; write elsewhere",
                p.display()
            )));
        }
        if let Some((other, _)) = seen.iter().find(|(_, q)| q.same(&here)) {
            return Err(Error::InvalidInput(format!(
                "{flag} {}: the same file as {other}; give each output its own path",
                p.display()
            )));
        }
        let mut mine = Vec::new();
        for (what, side) in sidecars(p) {
            let l = locate(flag, &side)?;
            if let Some((other, _)) = seen.iter().find(|(_, q)| q.same(&l)) {
                return Err(Error::InvalidInput(format!(
                    "{flag} {}: its {what} {} is the same file as {other}; give each output its \
                     own name",
                    p.display(),
                    side.display()
                )));
            }
            mine.push((format!("the {what} of {flag} {}", p.display()), l));
        }
        seen.push((format!("{flag} {}", p.display()), here));
        seen.extend(mine);
    }
    for &(flag, p, _) in outputs {
        if let Some(dir) = p.parent().filter(|d| !d.as_os_str().is_empty()) {
            io::create_folders(dir).map_err(|e| {
                Error::InvalidInput(format!(
                    "{flag} {}: cannot create its folder ({e})",
                    p.display()
                ))
            })?;
        }
    }
    Ok(())
}

/// The parser of a whole-number flag: a number from `lo` to `hi`. Anything else, a negative
/// number or a fraction included, is refused in one line naming the flag and its range
/// ("--rays -1: use 1 to 4096 rays per vertex"), before any work; a negative number reaches it
/// (rather than clap's "unexpected argument") where the flag has `allow_negative_numbers`.
#[derive(Clone, Copy, Debug)]
pub struct Whole<T> {
    lo: T,
    hi: Option<T>,
    unit: &'static str,
}

/// A [`Whole`] from `lo` to `hi`.
pub const fn whole<T>(lo: T, hi: T) -> Whole<T> {
    Whole {
        lo,
        hi: Some(hi),
        unit: "",
    }
}

/// A [`Whole`] of at least `lo`, as large as the type holds.
pub const fn at_least<T>(lo: T) -> Whole<T> {
    Whole {
        lo,
        hi: None,
        unit: "",
    }
}

impl<T> Whole<T> {
    /// What the number counts, for the message ("rays per vertex").
    pub const fn unit(mut self, unit: &'static str) -> Self {
        self.unit = unit;
        self
    }

    /// Refuse `value` for `flag` outside the range, in the words the parser uses (for values
    /// that come from elsewhere than the command line: the Python package's keyword arguments).
    pub fn check(&self, flag: &str, value: T) -> Result<()>
    where
        T: PartialOrd + std::fmt::Display,
    {
        if value >= self.lo && self.hi.as_ref().is_none_or(|hi| value <= *hi) {
            Ok(())
        } else {
            Err(Error::InvalidInput(self.message(flag, &value.to_string())))
        }
    }

    /// The refusal of `value` for `flag`.
    fn message(&self, flag: &str, value: &str) -> String
    where
        T: std::fmt::Display,
    {
        let unit = if self.unit.is_empty() {
            String::new()
        } else {
            format!(" {}", self.unit)
        };
        match &self.hi {
            Some(hi) => format!("{flag} {value}: use {} to {hi}{unit}", self.lo),
            None => format!("{flag} {value}: use {} or more{unit}", self.lo),
        }
    }
}

impl<T> clap::builder::TypedValueParser for Whole<T>
where
    T: std::str::FromStr + PartialOrd + std::fmt::Display + Clone + Send + Sync + 'static,
{
    type Value = T;

    fn parse_ref(
        &self,
        _cmd: &clap::Command,
        arg: Option<&clap::Arg>,
        value: &std::ffi::OsStr,
    ) -> std::result::Result<T, clap::Error> {
        let text = value.to_string_lossy();
        match text.trim().parse::<T>() {
            Ok(v) if v >= self.lo && self.hi.as_ref().is_none_or(|hi| v <= *hi) => Ok(v),
            _ => {
                let flag = arg
                    .and_then(|a| a.get_long())
                    .map(|l| format!("--{l}"))
                    .unwrap_or_else(|| "value".into());
                Err(clap::Error::raw(
                    clap::error::ErrorKind::ValueValidation,
                    format!("{}\n", self.message(&flag, &text)),
                ))
            }
        }
    }
}

/// `--vertices` of the MeshMatch commands (`transfer`, `complete`, `update`, `detail`): from the
/// hierarchy's coarsest level (below it `detail` would collapse its meshes) to the working
/// budget that `TransferParams::validate` checks.
pub const VERTICES: Whole<usize> = whole(
    crate::mesh::MIN_WORKING_VERTICES,
    crate::mesh::MAX_WORKING_VERTICES,
)
.unit("working vertices");
/// `--levels` of the MeshMatch commands.
pub const LEVELS: Whole<usize> = whole(1, crate::meshmatch::MAX_LEVELS).unit("levels");
/// `--iterations` of the MeshMatch commands.
pub const ITERATIONS: Whole<usize> =
    whole(0, crate::meshmatch::MAX_ITERATIONS).unit("iterations per level");
/// Every `--seed`.
pub const SEED: Whole<u64> = whole(0, u64::MAX);
/// Every `--texture-size`: from the smallest side a generated atlas fits in (a target without
/// UVs gets one; refused up front rather than after the solve).
pub const TEXTURE_SIZE: Whole<u32> =
    whole(crate::geometry::MIN_ATLAS_SIZE, MAX_TEXTURE_SIZE).unit("pixels per side");
/// Every `--rays`.
pub const RAYS: Whole<usize> = whole(1, MAX_RAYS).unit("rays per vertex");

/// Most occlusion rays per vertex accepted by `--rays`.
pub const MAX_RAYS: usize = 4096;

/// Refuse `--rays` outside 1..=[`MAX_RAYS`].
pub fn check_rays(rays: usize) -> Result<()> {
    if !(1..=MAX_RAYS).contains(&rays) {
        return Err(Error::InvalidInput(format!(
            "--rays {rays}: use 1 to {MAX_RAYS} rays per vertex"
        )));
    }
    Ok(())
}

/// Largest baked texture side accepted by `--texture-size`.
pub const MAX_TEXTURE_SIZE: u32 = 8192;

/// Texels per side of a baked result texture when neither `--texture-size` nor the target's own
/// texture says.
pub const DEFAULT_TEXTURE_SIZE: u32 = 2048;

/// The side of a baked result texture: `--texture-size` when given, else the side of `mesh`'s own
/// texture, else [`DEFAULT_TEXTURE_SIZE`].
pub fn texture_side(asked: Option<u32>, mesh: &crate::mesh::TriMesh) -> u32 {
    asked.unwrap_or_else(|| {
        mesh.texture
            .as_ref()
            .map(|t| {
                t.image
                    .width()
                    .max(t.image.height())
                    .clamp(1, MAX_TEXTURE_SIZE)
            })
            .unwrap_or(DEFAULT_TEXTURE_SIZE)
    })
}

/// `mesh` with a full-resolution result as `--out` wants it (`update`, `complete`): by extension,
/// a texture of `size` texels baked from `full` into its UVs or a generated atlas (`.glb`,
/// `.gltf`, `.obj`), or `colors` on its file vertices (`.ply`, or no full-resolution result).
pub fn with_result(
    mesh: &crate::mesh::TriMesh,
    colors: Vec<[f32; 3]>,
    full: Option<&(
        std::sync::Arc<crate::meshmatch::Resampler>,
        std::sync::Arc<crate::meshmatch::BakeLayout>,
    )>,
    out: &Path,
    size: u32,
) -> Result<crate::mesh::TriMesh> {
    let ext = out.extension().and_then(|e| e.to_str()).unwrap_or("");
    match full {
        Some((full, layout)) if !ext.eq_ignore_ascii_case("ply") => {
            let d = crate::meshmatch::deliver(
                mesh,
                layout,
                &[],
                &colors,
                ext,
                size,
                Some(full),
                &crate::work::CancelToken::new(),
            )?;
            if let Some(line) = d.atlas_line(size) {
                eprintln!("{line}");
            }
            eprintln!(
                "baked a {size}x{size} texture read from the example at full resolution ({:.0}% \
                 of the surface read exactly where it is unchanged)",
                100.0 * full.coincident_share()
            );
            Ok(d.mesh)
        }
        _ => {
            let mut m = mesh.clone();
            m.colors = Some(colors);
            m.texture = None;
            Ok(m)
        }
    }
}

/// Refuse a `--texture-size` outside [`TEXTURE_SIZE`]'s range, or too large for memory.
pub fn check_texture_size(size: u32) -> Result<()> {
    TEXTURE_SIZE.check("--texture-size", size)?;
    crate::geometry::check_bake_memory(size)
}

/// A progress bar and the event sink that drives it (stage times printed above the bar).
pub fn progress_bar() -> indicatif::ProgressBar {
    let bar = indicatif::ProgressBar::new(1000);
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "{spinner} [{elapsed_precise}] {bar:30} {percent:>3}% {msg}",
        )
        .expect("valid template"),
    );
    bar
}

pub fn bar_sink(bar: &indicatif::ProgressBar, e: Event) {
    match e {
        Event::Progress(p) | Event::Partial { progress: p, .. } => {
            let position = (p.fraction.clamp(0.0, 1.0) * 1000.0) as u64;
            bar.set_position(position);
            if p.iteration > 0 {
                bar.set_message(format!(
                    "{} level {}/{} iteration {} energy {:.4}",
                    p.stage, p.level, p.levels, p.iteration, p.energy
                ));
            } else {
                bar.set_message(p.stage.to_string());
            }
            if progress_lines() {
                log_progress(bar, position, p.stage);
            }
        }
        Event::StageTime(name, s) => {
            let line = format!("  {name:<12} {s:8.3} s");
            if progress_lines() {
                eprintln!("{line}");
            } else {
                bar.println(line);
            }
        }
    }
}

/// The environment variable that asks for [`log_progress`]'s lines (`lines`); `batch` sets it
/// for its jobs, so their logs show them.
pub const PROGRESS_ENV: &str = "MESHMATCH_PROGRESS";

/// Whether progress goes to stderr as plain lines: asked for by [`PROGRESS_ENV`] and stderr
/// not a terminal (where the bar is drawn instead). Otherwise a command run with stderr
/// captured says nothing before its summary, and a refusal stays one line.
fn progress_lines() -> bool {
    static ON: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *ON.get_or_init(|| {
        std::env::var_os(PROGRESS_ENV).is_some_and(|v| v == "lines")
            && !std::io::stderr().is_terminal()
    })
}

/// Where the progress is not drawn (a batch job's log, a render farm), a plain line each time
/// a command enters a stage or passes a tenth of its work, so that a log shows a long run
/// moving: `[00:01:23]  40% synthesis`.
fn log_progress(bar: &indicatif::ProgressBar, position: u64, stage: &str) {
    static LAST: std::sync::Mutex<Option<(u64, String)>> = std::sync::Mutex::new(None);
    let mut last = LAST.lock().unwrap_or_else(|e| e.into_inner());
    let tenth = position / 100;
    let news = last
        .as_ref()
        .is_none_or(|(t, st)| *t != tenth || st != stage);
    if news {
        let secs = bar.elapsed().as_secs();
        eprintln!(
            "[{:02}:{:02}:{:02}] {:>3}% {stage}",
            secs / 3600,
            secs / 60 % 60,
            secs % 60,
            position / 10
        );
        *last = Some((tenth, stage.to_string()));
    }
}

/// Read a mask file: vertex indices (file numbering), one per line; `#` comments and blank lines
/// are ignored. Returns per-vertex flags of length `n`.
pub fn read_mask(path: &Path, n: usize) -> Result<Vec<bool>> {
    let text = io::read_text_file(path, "the mask file")?;
    let mut mask = vec![false; n];
    for (i, line) in text.lines().enumerate() {
        let t = line.split('#').next().unwrap_or("").trim();
        if t.is_empty() {
            continue;
        }
        let v: usize = t.parse().map_err(|_| {
            Error::format(path, format!("line {}: '{t}' is not a vertex index", i + 1))
        })?;
        if v >= n {
            return Err(Error::format(
                path,
                format!("line {}: vertex {v} out of range (the mesh has {n})", i + 1),
            ));
        }
        mask[v] = true;
    }
    Ok(mask)
}

/// Parse "R,G,B" (0-255) into an sRGB colour in [0, 1].
pub fn parse_rgb(s: &str) -> Result<[f32; 3]> {
    let v: Vec<&str> = s.split(',').map(str::trim).collect();
    let bad = || Error::InvalidInput(format!("--clay {s}: expected R,G,B with values 0-255"));
    if v.len() != 3 {
        return Err(bad());
    }
    let mut c = [0.0f32; 3];
    for (k, x) in v.iter().enumerate() {
        c[k] = x.parse::<u8>().map_err(|_| bad())? as f32 / 255.0;
    }
    Ok(c)
}

/// Solver settings shared by `complete`, `update` and `detail`.
#[derive(clap::Args, Debug)]
pub struct SolveArgs {
    /// Working resolution (vertices; coarser meshes are refined to it), 128 to 4,000,000.
    #[arg(long, default_value_t = 64_000, allow_negative_numbers = true,
          value_parser = VERTICES)]
    pub vertices: usize,
    /// Number of hierarchy levels, 1 to 16 (default: down to about 128 vertices).
    #[arg(long, allow_negative_numbers = true, value_parser = LEVELS)]
    pub levels: Option<usize>,
    /// EM iterations per level at most, 0 to 1000.
    #[arg(long, default_value_t = 5, allow_negative_numbers = true, value_parser = ITERATIONS)]
    pub iterations: usize,
    /// A level stops iterating once an iteration lowers its energy by less than this fraction
    /// (0 = always run every iteration).
    #[arg(long, default_value_t = crate::meshmatch::DEFAULT_TOLERANCE, allow_negative_numbers = true)]
    pub tolerance: f32,
    /// Random seed (runs with the same seed are identical).
    #[arg(long, default_value_t = 0, allow_negative_numbers = true, value_parser = SEED)]
    pub seed: u64,
    /// Weight of shape features against colour (1 = equal); finite, 0 or more.
    #[arg(long, allow_hyphen_values = true)]
    pub shape_weight: Option<f32>,
    /// Keep the filtered vote at the finest level instead of the nearest-neighbour copy.
    #[arg(long)]
    pub no_sharpen: bool,
}

impl SolveArgs {
    /// The transfer parameters, with `shape_weight` defaulting to `default_shape_weight`.
    /// Checked by `TransferParams::validate`, so a bad value is refused before any file is read.
    pub fn params(&self, default_shape_weight: f32) -> Result<crate::meshmatch::TransferParams> {
        let p = crate::meshmatch::TransferParams {
            vertices: self.vertices,
            levels: self.levels,
            iterations: self.iterations,
            tolerance: self.tolerance,
            seed: self.seed,
            shape_weight: self.shape_weight.unwrap_or(default_shape_weight),
            sharpen: !self.no_sharpen,
            ..Default::default()
        };
        p.validate()?;
        Ok(p)
    }
}

/// Load a source that must carry a signal: its own texture or vertex colours, or `texture`
/// (which needs UVs) in their place.
pub fn load_signal_source(path: &Path, texture: Option<&Path>) -> Result<TriMesh> {
    with_signal(load_usable(path)?, path, texture)
}

/// `source` (loaded from `path`) checked to carry a signal, with `texture` in place of its own.
fn with_signal(mut source: TriMesh, path: &Path, texture: Option<&Path>) -> Result<TriMesh> {
    if let Some(tex) = texture {
        if source.uvs.is_none() {
            return Err(Error::InvalidInput(format!(
                "{}: --source-texture needs a source with UVs",
                path.display()
            )));
        }
        source.texture = Some(std::sync::Arc::new(io::load_texture(tex)?));
        source.colors = None;
    }
    if source.vertex_signal().is_none() {
        return Err(Error::InvalidInput(format!(
            "{}: the source carries no texture or vertex colours to transfer (use --source-texture)",
            path.display()
        )));
    }
    Ok(source)
}
