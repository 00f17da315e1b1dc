//! The app's state, independent of any window: meshes, correspondences, undo history, paint
//! layers, parameters and job status. The UI calls these methods; tests call them directly.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant};

use crate::jobs::worker::{Side, Solved, WorkerEvent};
use crate::jobs::{Correspondence, CorrespondenceFile, Event, Progress};
use crate::{Error, Result, TriMesh};

/// Delay between the last edit and the restart of the transfer.
pub const DEBOUNCE: Duration = Duration::from_millis(150);
/// Most undo steps kept.
pub const UNDO_LIMIT: usize = 100;
/// Size (pixels per side) of the texture baked on export, as `transfer --texture-size` defaults.
pub const EXPORT_TEXTURE_SIZE: u32 = 1024;

/// Parameters the app can edit, save and send to the worker.
pub trait AppParams:
    Clone + Default + PartialEq + serde::Serialize + serde::de::DeserializeOwned + Send + 'static
{
    /// Draw the parameter editors (each with a tooltip); true when a value changed.
    fn ui(&mut self, ui: &mut eframe::egui::Ui) -> bool;
}

/// One loaded mesh and what is displayed for it.
#[derive(Clone)]
pub struct MeshSlot {
    /// The mesh as loaded (file vertex numbering).
    pub file: Arc<TriMesh>,
    /// Identity of this load (changes whenever the mesh is replaced).
    pub id: u64,
    /// The working-resolution mesh once the worker prepared it.
    pub working: Option<Arc<TriMesh>>,
    /// File vertex of each working vertex.
    pub working_to_file: Option<Arc<[u32]>>,
    /// A working vertex for each file vertex (the first one that maps to it), `u32::MAX` if none.
    pub file_to_working: Option<Vec<u32>>,
    /// Base colours of the displayed mesh (before paint).
    pub base_colors: Vec<[f32; 3]>,
    /// Vertex normals of the displayed mesh (for marker visibility).
    pub normals: Vec<[f32; 3]>,
    /// Paint layer on the displayed mesh: RGB + coverage per vertex.
    pub paint: Option<Vec<[f32; 4]>>,
    /// Geometry changed since the renderer last uploaded it.
    pub geometry_dirty: bool,
    /// Colours changed since the renderer last uploaded them.
    pub colors_dirty: bool,
    /// Name of the built-in scene this mesh came from (it has no file), if any.
    pub scene: Option<String>,
    /// Texture image applied with File > Open texture (or a dropped image), if any.
    pub texture_file: Option<PathBuf>,
    /// Paint restored from a session, kept with the positions it was painted on so that the
    /// working mesh, once prepared, gets it from the original rather than from the file mesh;
    /// with it, the layer applied at load (to tell whether strokes were made since).
    restored_paint: Option<(PaintSample, Vec<[f32; 4]>)>,
}

impl MeshSlot {
    fn new(mesh: Arc<TriMesh>, id: u64) -> Self {
        let base_colors = crate::render::display_colors(&mesh, None);
        let normals = crate::render::gpu::vertex_normals(&mesh.positions, &mesh.faces);
        MeshSlot {
            normals,
            file: mesh,
            id,
            working: None,
            working_to_file: None,
            file_to_working: None,
            base_colors,
            paint: None,
            geometry_dirty: true,
            colors_dirty: true,
            scene: None,
            texture_file: None,
            restored_paint: None,
        }
    }

    /// The mesh shown in the view: the working mesh when prepared, else the file mesh.
    pub fn displayed(&self) -> &TriMesh {
        self.working.as_deref().unwrap_or(&self.file)
    }

    /// File vertex of a displayed vertex.
    pub fn to_file(&self, v: u32) -> u32 {
        match &self.working_to_file {
            Some(map) => map.get(v as usize).copied().unwrap_or(v),
            None => v,
        }
    }

    /// Displayed vertex of a file vertex, if it is shown.
    pub fn to_displayed(&self, f: u32) -> Option<u32> {
        match &self.file_to_working {
            Some(map) => map.get(f as usize).copied().filter(|&w| w != u32::MAX),
            None => ((f as usize) < self.file.positions.len()).then_some(f),
        }
    }

    /// Position of a file vertex on the displayed mesh.
    pub fn file_vertex_position(&self, f: u32) -> Option<[f32; 3]> {
        let d = self.to_displayed(f)?;
        self.displayed().positions.get(d as usize).copied()
    }

    /// Colours to draw: base colours with the paint layer composited.
    pub fn display_colors(&self) -> Vec<[f32; 3]> {
        match &self.paint {
            None => self.base_colors.clone(),
            Some(p) => self
                .base_colors
                .iter()
                .zip(p)
                .map(|(b, p)| {
                    let a = p[3];
                    [0, 1, 2].map(|k| b[k] * (1.0 - a) + p[k] * a)
                })
                .collect(),
        }
    }
}

/// The selected marker: pair index, side and (for the target) which of its vertices.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Selection {
    /// Index into the correspondence list.
    pub pair: usize,
    /// Which view's marker.
    pub side: Side,
    /// Index into `target_vertices` (0 for the source marker).
    pub k: usize,
}

/// What the UI should ask the worker to do.
#[derive(Clone, Debug)]
pub enum Request<P> {
    /// Replace a mesh.
    SetMesh(Side, u64, Arc<TriMesh>),
    /// Start a transfer.
    Start(Vec<Correspondence>, P),
    /// Stop the running job.
    Cancel,
}

/// The state of the transfer job as the status bar shows it.
#[derive(Clone, Debug, Default)]
pub struct JobStatus {
    /// Job number currently expected (0 = none yet).
    pub job: u64,
    /// A job is running.
    pub running: bool,
    /// Latest progress.
    pub progress: Progress,
    /// Number of partial results received for the current job.
    pub partials: usize,
    /// Wall time of the last finished job.
    pub finished_secs: Option<f64>,
    /// Last outcome in words ("done", "cancelled", an error).
    pub outcome: String,
}

/// A paint layer with the vertex positions it was painted on.
#[derive(Clone, Debug)]
struct PaintSample {
    positions: Vec<[f32; 3]>,
    rgba: Vec<[f32; 4]>,
}

/// For each point of `to`, the index of the nearest point of `from` (identity when both lists
/// are the same points); empty when `from` is empty.
pub fn nearest_map(from: &[[f32; 3]], to: &[[f32; 3]]) -> Vec<u32> {
    if from.is_empty() {
        return Vec::new();
    }
    if from == to {
        return (0..to.len() as u32).collect();
    }
    let grid = PointGrid::new(from);
    to.iter().map(|&p| grid.nearest(from, p)).collect()
}

/// Carry a per-vertex paint layer painted on `from` onto the vertices `to` (nearest vertex).
pub fn remap_paint(from: &[[f32; 3]], paint: &[[f32; 4]], to: &[[f32; 3]]) -> Vec<[f32; 4]> {
    if paint.len() != from.len() {
        return vec![[0.0; 4]; to.len()];
    }
    let map = nearest_map(from, to);
    if map.is_empty() {
        return vec![[0.0; 4]; to.len()];
    }
    map.iter().map(|&i| paint[i as usize]).collect()
}

/// A uniform grid over points for nearest-point queries (about two points per cell).
struct PointGrid {
    min: glam::Vec3,
    cell: f32,
    dims: [i32; 3],
    start: Vec<u32>,
    items: Vec<u32>,
}

impl PointGrid {
    fn new(points: &[[f32; 3]]) -> Self {
        let mut min = glam::Vec3::splat(f32::INFINITY);
        let mut max = glam::Vec3::splat(f32::NEG_INFINITY);
        for p in points {
            let v = glam::Vec3::from(*p);
            min = min.min(v);
            max = max.max(v);
        }
        let ext = (max - min).max(glam::Vec3::splat(1e-6));
        let cells = (points.len() as f32 / 2.0).max(1.0);
        let cell = ((ext.x * ext.y * ext.z) / cells)
            .cbrt()
            .max(ext.max_element() / 256.0);
        let dims = [0, 1, 2].map(|k| ((ext[k] / cell).floor() as i32 + 1).clamp(1, 1024));
        let n = (dims[0] * dims[1] * dims[2]) as usize;
        let mut grid = PointGrid {
            min,
            cell,
            dims,
            start: vec![0; n + 1],
            items: vec![0; points.len()],
        };
        let ids: Vec<usize> = points.iter().map(|p| grid.index(grid.coord(*p))).collect();
        for &c in &ids {
            grid.start[c + 1] += 1;
        }
        for c in 0..n {
            grid.start[c + 1] += grid.start[c];
        }
        let mut fill = grid.start.clone();
        for (i, &c) in ids.iter().enumerate() {
            grid.items[fill[c] as usize] = i as u32;
            fill[c] += 1;
        }
        grid
    }

    fn coord(&self, p: [f32; 3]) -> [i32; 3] {
        [0, 1, 2]
            .map(|k| (((p[k] - self.min[k]) / self.cell).floor() as i32).clamp(0, self.dims[k] - 1))
    }

    fn index(&self, c: [i32; 3]) -> usize {
        ((c[2] * self.dims[1] + c[1]) * self.dims[0] + c[0]) as usize
    }

    /// Index of the point nearest to `p` (rings of cells until no nearer one can exist).
    fn nearest(&self, points: &[[f32; 3]], p: [f32; 3]) -> u32 {
        let q = glam::Vec3::from(p);
        let c = self.coord(p);
        let mut best = (f32::INFINITY, 0u32);
        let max_r = self.dims.into_iter().max().unwrap_or(1);
        for r in 0..=max_r {
            for z in (c[2] - r).max(0)..=(c[2] + r).min(self.dims[2] - 1) {
                for y in (c[1] - r).max(0)..=(c[1] + r).min(self.dims[1] - 1) {
                    for x in (c[0] - r).max(0)..=(c[0] + r).min(self.dims[0] - 1) {
                        let ring = (x - c[0]).abs().max((y - c[1]).abs()).max((z - c[2]).abs());
                        if ring != r {
                            continue;
                        }
                        let cell = self.index([x, y, z]);
                        for &i in
                            &self.items[self.start[cell] as usize..self.start[cell + 1] as usize]
                        {
                            let d = q.distance_squared(glam::Vec3::from(points[i as usize]));
                            if d < best.0 || (d == best.0 && i < best.1) {
                                best = (d, i);
                            }
                        }
                    }
                }
            }
            // Points in ring r + 1 are at least r cells away from `p`.
            let reach = r as f32 * self.cell;
            if best.0.is_finite() && best.0 <= reach * reach {
                break;
            }
        }
        best.1
    }
}

#[derive(Clone)]
struct Snapshot {
    corr: Vec<Correspondence>,
    pending_source: Option<u32>,
    paint: [Option<Vec<[f32; 4]>>; 2],
}

/// Brush settings for painting vertex colours.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Brush {
    /// Radius as a fraction of the mesh's bounding radius.
    pub radius: f32,
    /// sRGB colour.
    pub color: [f32; 3],
    /// 1 = hard edge, 0 = fully soft falloff.
    pub hardness: f32,
    /// Remove paint instead of adding it.
    pub eraser: bool,
}

impl Default for Brush {
    fn default() -> Self {
        Brush {
            radius: 0.08,
            color: [0.9, 0.1, 0.1],
            hardness: 0.5,
            eraser: false,
        }
    }
}

/// The session file: meshes, correspondences (file indices), parameters and paint sidecars.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct Session<P> {
    /// Source mesh path.
    pub source: Option<PathBuf>,
    /// Target mesh path.
    pub target: Option<PathBuf>,
    /// Correspondences in file vertex indices.
    pub correspondences: CorrespondenceFile,
    /// Transfer parameters.
    pub params: P,
    /// Painted source colours (PLY sidecar, relative to the session file), if any.
    pub source_paint: Option<PathBuf>,
    /// Painted target colours (PLY sidecar, relative to the session file), if any.
    pub target_paint: Option<PathBuf>,
    /// Paint coverage per sidecar vertex (0-255) of the source; absent = fully painted.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub source_paint_coverage: Option<Vec<u8>>,
    /// Paint coverage per sidecar vertex (0-255) of the target; absent = fully painted.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub target_paint_coverage: Option<Vec<u8>>,
    /// Built-in scene the source mesh comes from when it has no file (e.g. "Zebra -> giraffe").
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub source_scene: Option<String>,
    /// Built-in scene the target mesh comes from when it has no file.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub target_scene: Option<String>,
    /// Texture image opened for the source (File > Open texture), if any.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub source_texture: Option<PathBuf>,
}

/// What a recently opened file was opened as.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum RecentKind {
    /// A mesh (offered as source or target).
    Mesh,
    /// A texture image for the source.
    Texture,
    /// A session JSON.
    Session,
}

/// One entry of the Recent menu.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct RecentFile {
    /// The file.
    pub path: PathBuf,
    /// What it was opened as.
    pub kind: RecentKind,
}

/// Where the Recent list is kept between runs: `$XDG_CONFIG_HOME/meshmatch/recent.json`
/// (or `~/.config/...`; `%APPDATA%\meshmatch\recent.json` on Windows).
pub fn default_recent_store() -> Option<PathBuf> {
    let base = std::env::var_os("XDG_CONFIG_HOME")
        .filter(|v| !v.is_empty())
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("APPDATA").map(PathBuf::from))
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".config")))?;
    Some(base.join("meshmatch").join("recent.json"))
}

/// The paint layer under a tool preview: side, mesh id and the paint itself.
type PreviewBackup = (Side, u64, Option<Vec<[f32; 4]>>);

/// Everything the app knows, without any window.
pub struct AppState<P: AppParams> {
    /// Source and target meshes (index 0 = source, 1 = target).
    pub meshes: [Option<MeshSlot>; 2],
    /// Correspondences in file vertex indices.
    pub corr: Vec<Correspondence>,
    /// A source vertex clicked but not yet paired (file index).
    pub pending_source: Option<u32>,
    /// Selected marker.
    pub selected: Option<Selection>,
    /// Transfer parameters.
    pub params: P,
    /// Job status.
    pub job: JobStatus,
    /// The latest result (per target file vertex), for export.
    pub result: Option<Arc<Solved>>,
    /// Messages to show the user (dismissable).
    pub errors: Vec<String>,
    /// One-line status message.
    pub message: String,
    /// Brush settings.
    pub brush: Brush,
    /// Recently opened files, newest first.
    pub recent: Vec<RecentFile>,
    /// File the Recent list is saved to after every change (`None`: not persisted).
    pub recent_store: Option<PathBuf>,
    /// Built-in scenes by name, so sessions saved from them can be reopened.
    pub scenes: Vec<super::SceneEntry>,
    undo: Vec<Snapshot>,
    redo: Vec<Snapshot>,
    /// Paint layer kept aside while a tool previews partial results: side, mesh id, paint.
    preview_backup: Option<PreviewBackup>,
    restart_at: Option<Instant>,
    requests: Vec<Request<P>>,
    next_id: u64,
}

/// Index of a side in `meshes`.
pub fn side_index(side: Side) -> usize {
    match side {
        Side::Source => 0,
        Side::Target => 1,
    }
}

impl<P: AppParams> Default for AppState<P> {
    fn default() -> Self {
        Self::new()
    }
}

impl<P: AppParams> AppState<P> {
    /// Empty state with default parameters.
    pub fn new() -> Self {
        AppState {
            meshes: [None, None],
            corr: Vec::new(),
            pending_source: None,
            selected: None,
            params: P::default(),
            job: JobStatus::default(),
            result: None,
            errors: Vec::new(),
            message: String::new(),
            brush: Brush::default(),
            recent: Vec::new(),
            recent_store: None,
            scenes: Vec::new(),
            undo: Vec::new(),
            redo: Vec::new(),
            preview_backup: None,
            restart_at: None,
            requests: Vec::new(),
            next_id: 1,
        }
    }

    /// The slot of one side.
    pub fn slot(&self, side: Side) -> Option<&MeshSlot> {
        self.meshes[side_index(side)].as_ref()
    }

    fn slot_mut(&mut self, side: Side) -> Option<&mut MeshSlot> {
        self.meshes[side_index(side)].as_mut()
    }

    /// Report an error to the user (shown in a dismissable window).
    pub fn report(&mut self, e: impl std::fmt::Display) {
        self.errors.push(e.to_string());
    }

    /// Replace one mesh; correspondences are kept only if both meshes stay (`keep_corr`).
    pub fn set_mesh(&mut self, side: Side, mesh: TriMesh, keep_corr: bool) {
        let id = self.next_id;
        self.next_id += 1;
        let mesh = Arc::new(mesh);
        self.meshes[side_index(side)] = Some(MeshSlot::new(mesh.clone(), id));
        if !keep_corr {
            self.corr.clear();
            self.pending_source = None;
            self.selected = None;
            self.undo.clear();
            self.redo.clear();
        }
        if side == Side::Target {
            self.result = None;
        }
        self.requests.push(Request::SetMesh(side, id, mesh));
        self.schedule_restart_now();
    }

    /// Load a mesh file into one side; errors become messages.
    pub fn open_mesh(&mut self, side: Side, path: &Path) -> Result<()> {
        let mesh = crate::mesh::io::load(path)?;
        mesh_usable(&mesh)?;
        self.set_mesh(side, mesh, false);
        self.push_recent(path, RecentKind::Mesh);
        Ok(())
    }

    /// Apply a texture image to the source mesh (it must have UVs).
    pub fn open_texture(&mut self, path: &Path) -> Result<()> {
        self.open_texture_for(Side::Source, path)
    }

    /// Apply a texture image to one side's mesh (it must have UVs); correspondences are kept.
    pub fn open_texture_for(&mut self, side: Side, path: &Path) -> Result<()> {
        let slot = self.slot(side).ok_or_else(|| {
            Error::InvalidInput(format!("open a {side:?} mesh before its texture"))
        })?;
        let scene = slot.scene.clone();
        let mesh = with_texture(&slot.file, path)?;
        self.set_mesh(side, mesh, true);
        if let Some(slot) = self.slot_mut(side) {
            slot.scene = scene;
            slot.texture_file = Some(path.to_path_buf());
        }
        self.push_recent(path, RecentKind::Texture);
        Ok(())
    }

    /// Open a file by its kind: an image becomes `side`'s texture, a JSON a session (or a
    /// correspondence file when it has no parameters), anything else a mesh on `side`.
    pub fn open_any(&mut self, side: Side, path: &Path) -> Result<()> {
        let ext = path
            .extension()
            .map(|e| e.to_string_lossy().to_ascii_lowercase())
            .unwrap_or_default();
        match ext.as_str() {
            "png" | "jpg" | "jpeg" => self.open_texture_for(side, path),
            "json" => {
                let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
                let v: serde_json::Value = serde_json::from_str(&text)
                    .map_err(|e| Error::format(path, format!("invalid JSON: {e}")))?;
                if v.get("params").is_some() {
                    self.open_session(path)
                } else {
                    let f = crate::jobs::CorrespondenceFile::load(path)?;
                    self.set_correspondences(f.correspondences)
                }
            }
            _ => self.open_mesh(side, path),
        }
    }

    /// Read the Recent list from `store` (missing or unreadable: empty) and keep it saved there.
    pub fn load_recent(&mut self, store: PathBuf) {
        self.recent = std::fs::read(&store)
            .ok()
            .and_then(|b| serde_json::from_slice::<Vec<RecentFile>>(&b).ok())
            .unwrap_or_default();
        self.recent.truncate(10);
        self.recent_store = Some(store);
    }

    fn push_recent(&mut self, path: &Path, kind: RecentKind) {
        let path = abs(path);
        self.recent.retain(|r| r.path != path);
        self.recent.insert(0, RecentFile { path, kind });
        self.recent.truncate(10);
        if let Some(store) = &self.recent_store {
            let r = store
                .parent()
                .map_or(Ok(()), std::fs::create_dir_all)
                .map_err(|e| Error::io(store, e))
                .and_then(|_| {
                    let text = serde_json::to_vec_pretty(&self.recent).unwrap_or_default();
                    crate::mesh::io::write_atomic(store, &text)
                });
            if let Err(e) = r {
                self.message = format!("recent files not saved: {e}");
            }
        }
    }

    /// Build a built-in scene by name.
    fn build_scene(&self, name: &str) -> Result<super::DemoScene> {
        let (_, f) = self
            .scenes
            .iter()
            .find(|(n, _)| n == name)
            .ok_or_else(|| Error::InvalidInput(format!("no built-in scene named {name:?}")))?;
        f()
    }

    /// Show a built-in scene (both meshes and its correspondences) and start the transfer.
    pub fn load_scene_named(&mut self, name: &str) -> Result<()> {
        let scene = self.build_scene(name)?;
        self.set_mesh(Side::Source, scene.source, false);
        self.set_mesh(Side::Target, scene.target, false);
        for side in [Side::Source, Side::Target] {
            if let Some(slot) = self.slot_mut(side) {
                slot.scene = Some(name.to_string());
            }
        }
        self.set_correspondences(scene.correspondences)
    }

    /// Take the requests for the worker accumulated since the last call.
    pub fn take_requests(&mut self) -> Vec<Request<P>> {
        std::mem::take(&mut self.requests)
    }

    /// Restart the transfer after the debounce delay (called after every edit).
    pub fn schedule_restart(&mut self, now: Instant) {
        self.restart_at = Some(now + DEBOUNCE);
    }

    fn schedule_restart_now(&mut self) {
        self.schedule_restart(Instant::now());
    }

    /// Is a restart waiting for its debounce delay?
    pub fn restart_pending(&self) -> bool {
        self.restart_at.is_some()
    }

    /// Advance time: once the debounce delay passed, queue a transfer start. Returns true when a
    /// start was queued.
    pub fn tick(&mut self, now: Instant) -> bool {
        match self.restart_at {
            Some(t) if now >= t => {
                self.restart_at = None;
                if self.meshes.iter().all(Option::is_some) {
                    self.requests
                        .push(Request::Start(self.corr.clone(), self.params.clone()));
                    true
                } else {
                    false
                }
            }
            _ => false,
        }
    }

    /// The worker accepted a start as job `job`.
    pub fn job_started(&mut self, job: u64) {
        self.job.job = job;
        self.job.running = true;
        self.job.partials = 0;
        self.job.outcome = "running".into();
        self.job.progress = Progress::default();
    }

    /// Ask the running job to stop.
    pub fn cancel_job(&mut self) {
        self.restart_at = None;
        self.requests.push(Request::Cancel);
    }

    /// Set parameters; a change restarts the transfer.
    pub fn set_params(&mut self, params: P, now: Instant) {
        if params != self.params {
            self.params = params;
            self.schedule_restart(now);
        }
    }

    /// Apply an event from the worker.
    pub fn apply_event(&mut self, ev: WorkerEvent) {
        match ev {
            WorkerEvent::Prepared {
                side,
                mesh_id,
                working,
                working_to_file,
                file_to_working,
            } => {
                let i = side_index(side);
                let history_paint = self
                    .undo
                    .iter()
                    .chain(self.redo.iter())
                    .any(|s| s.paint[i].is_some());
                let Some(slot) = self.slot_mut(side) else {
                    return;
                };
                if slot.id != mesh_id {
                    return;
                }
                let nw = working.positions.len() as u32;
                let f2w: Vec<u32> = if file_to_working.len() == slot.file.positions.len() {
                    file_to_working
                        .iter()
                        .map(|&w| if w < nw { w } else { u32::MAX })
                        .collect()
                } else {
                    let mut f2w = vec![u32::MAX; slot.file.positions.len()];
                    for (w, &f) in working_to_file.iter().enumerate() {
                        if let Some(e) = f2w.get_mut(f as usize)
                            && *e == u32::MAX
                        {
                            *e = w as u32;
                        }
                    }
                    f2w
                };
                slot.base_colors = match side {
                    Side::Source => crate::render::display_colors(&working, None),
                    Side::Target => {
                        vec![crate::render::gpu::DEFAULT_VERTEX_COLOR; working.positions.len()]
                    }
                };
                // Paint lives on the displayed mesh: carry it (and the undo history's layers of
                // this side) onto the working mesh by nearest vertex.
                let old_positions = slot.displayed().positions.clone();
                let restored = slot.restored_paint.take();
                let map = if slot.paint.is_some() || history_paint {
                    nearest_map(&old_positions, &working.positions)
                } else {
                    Vec::new()
                };
                // Layers of another length belong to an older mesh: left for `restore` to skip.
                let carry = |layer: &mut Option<Vec<[f32; 4]>>| {
                    if let Some(l) = layer.as_mut()
                        && l.len() == old_positions.len()
                        && !map.is_empty()
                    {
                        *l = map.iter().map(|&i| l[i as usize]).collect();
                    }
                };
                slot.paint = match restored {
                    // Untouched since the session was opened: take it from the saved positions.
                    Some((sample, applied)) if slot.paint.as_ref() == Some(&applied) => Some(
                        remap_paint(&sample.positions, &sample.rgba, &working.positions),
                    ),
                    _ => {
                        let mut p = slot.paint.take();
                        carry(&mut p);
                        p.filter(|l| l.len() == working.positions.len())
                    }
                };
                slot.normals =
                    crate::render::gpu::vertex_normals(&working.positions, &working.faces);
                slot.working = Some(working);
                slot.working_to_file = Some(working_to_file);
                slot.file_to_working = Some(f2w);
                slot.geometry_dirty = true;
                slot.colors_dirty = true;
                for snap in self.undo.iter_mut().chain(self.redo.iter_mut()) {
                    carry(&mut snap.paint[i]);
                }
            }
            WorkerEvent::Job { job, event } => {
                if job != self.job.job {
                    return;
                }
                match event {
                    Event::Progress(p) => self.job.progress = p,
                    Event::Partial { progress, signal } => {
                        self.job.progress = progress;
                        self.job.partials += 1;
                        self.set_target_colors(&signal);
                    }
                    Event::StageTime(..) => {}
                }
            }
            WorkerEvent::Done {
                job,
                result,
                elapsed,
            } => {
                if job != self.job.job {
                    return;
                }
                self.job.running = false;
                self.job.finished_secs = Some(elapsed);
                self.job.outcome = format!("done in {elapsed:.2} s");
                self.set_target_colors(&result.working_signal);
                self.result = Some(result);
            }
            WorkerEvent::Cancelled { job } => {
                if job == self.job.job {
                    self.job.running = false;
                    self.job.outcome = "cancelled".into();
                }
            }
            WorkerEvent::Failed { job, message } => {
                if job == self.job.job {
                    self.job.running = false;
                    self.job.outcome = format!("failed: {message}");
                    self.report(format!("Transfer failed: {message}"));
                }
            }
        }
    }

    fn set_target_colors(&mut self, signal: &[[f32; 3]]) {
        if let Some(slot) = self.slot_mut(Side::Target)
            && signal.len() == slot.displayed().positions.len()
        {
            slot.base_colors = signal.to_vec();
            slot.colors_dirty = true;
        }
    }

    // ----- correspondences -----

    fn snapshot(&self) -> Snapshot {
        Snapshot {
            corr: self.corr.clone(),
            pending_source: self.pending_source,
            // a tool preview is never an undo state: record the paint underneath it
            paint: [0, 1].map(|i| match &self.preview_backup {
                Some((side, _, p)) if side_index(*side) == i => p.clone(),
                _ => self.meshes[i].as_ref().and_then(|s| s.paint.clone()),
            }),
        }
    }

    /// Record the current state for undo (call before an edit).
    pub fn push_undo(&mut self) {
        self.undo.push(self.snapshot());
        if self.undo.len() > UNDO_LIMIT {
            self.undo.remove(0);
        }
        self.redo.clear();
    }

    fn restore(&mut self, s: Snapshot) {
        let corr_changed = s.corr != self.corr;
        self.corr = s.corr;
        self.pending_source = s.pending_source;
        for (i, p) in s.paint.into_iter().enumerate() {
            if let Some(slot) = self.meshes[i].as_mut()
                && slot.paint != p
                // Never apply a layer painted on another version of the mesh.
                && p.as_ref().is_none_or(|l| l.len() == slot.displayed().num_vertices())
            {
                slot.paint = p;
                slot.colors_dirty = true;
            }
        }
        if let Some(sel) = self.selected
            && !self.marker_exists(sel)
        {
            self.selected = None;
        }
        if corr_changed {
            self.schedule_restart_now();
        }
    }

    /// Undo the last edit (correspondence or paint stroke); false if there is none.
    pub fn undo(&mut self) -> bool {
        let Some(s) = self.undo.pop() else {
            self.message = "nothing to undo".into();
            return false;
        };
        let cur = self.snapshot();
        self.redo.push(cur);
        self.restore(s);
        self.message = format!(
            "undone ({} more undo, {} redo)",
            self.undo.len(),
            self.redo.len()
        );
        true
    }

    /// Redo the last undone edit; false if there is none.
    pub fn redo(&mut self) -> bool {
        let Some(s) = self.redo.pop() else {
            self.message = "nothing to redo".into();
            return false;
        };
        let cur = self.snapshot();
        self.undo.push(cur);
        self.restore(s);
        self.message = format!(
            "redone ({} undo, {} more redo)",
            self.undo.len(),
            self.redo.len()
        );
        true
    }

    /// Number of undo and redo steps available.
    pub fn history_len(&self) -> (usize, usize) {
        (self.undo.len(), self.redo.len())
    }

    fn marker_exists(&self, s: Selection) -> bool {
        self.corr.get(s.pair).is_some_and(|c| match s.side {
            Side::Source => s.k == 0,
            Side::Target => s.k < c.target_vertices.len(),
        })
    }

    /// Handle a click on a displayed vertex of one view: source click starts a pair, target click
    /// completes it; with `add` (Shift) a target click adds another target vertex to the selected
    /// pair (one-to-many).
    pub fn click_vertex(&mut self, side: Side, displayed_vertex: u32, add: bool) {
        let Some(slot) = self.slot(side) else { return };
        let f = slot.to_file(displayed_vertex);
        match side {
            Side::Source => {
                self.push_undo();
                self.pending_source = Some(f);
                self.selected = None;
                self.message = format!("source vertex {f}: now click the target");
            }
            Side::Target => {
                if let Some(s) = self.pending_source {
                    self.push_undo();
                    self.corr.push(Correspondence {
                        source_vertex: s,
                        target_vertices: vec![f],
                    });
                    self.pending_source = None;
                    self.selected = Some(Selection {
                        pair: self.corr.len() - 1,
                        side: Side::Target,
                        k: 0,
                    });
                    self.message = format!("pair {} added", self.corr.len());
                    self.schedule_restart_now();
                } else if add && let Some(sel) = self.selected {
                    if self.corr[sel.pair].target_vertices.contains(&f) {
                        return;
                    }
                    self.push_undo();
                    self.corr[sel.pair].target_vertices.push(f);
                    self.selected = Some(Selection {
                        pair: sel.pair,
                        side: Side::Target,
                        k: self.corr[sel.pair].target_vertices.len() - 1,
                    });
                    self.message = format!("target point added to pair {}", sel.pair + 1);
                    self.schedule_restart_now();
                } else {
                    self.message = "click a source point first (Shift-click adds targets to the selected pair)".into();
                }
            }
        }
    }

    /// Select a marker.
    pub fn select(&mut self, sel: Option<Selection>) {
        self.selected = sel.filter(|s| self.marker_exists(*s));
    }

    /// Delete the selected marker: a source marker removes its pair; a target marker removes that
    /// target vertex (and the pair when it was the last). Returns true if something was removed.
    pub fn delete_selected(&mut self) -> bool {
        let Some(sel) = self.selected else {
            if self.pending_source.is_some() {
                self.push_undo();
                self.pending_source = None;
                return true;
            }
            return false;
        };
        if !self.marker_exists(sel) {
            return false;
        }
        self.push_undo();
        let c = &mut self.corr[sel.pair];
        if sel.side == Side::Source || c.target_vertices.len() <= 1 {
            self.corr.remove(sel.pair);
        } else {
            c.target_vertices.remove(sel.k);
        }
        self.selected = None;
        self.schedule_restart_now();
        true
    }

    /// Delete a whole pair by index.
    pub fn delete_pair(&mut self, pair: usize) {
        if pair < self.corr.len() {
            self.push_undo();
            self.corr.remove(pair);
            self.selected = None;
            self.schedule_restart_now();
        }
    }

    /// Move a marker to another displayed vertex. `record` pushes an undo step (true at the start
    /// of a drag, false while it continues).
    pub fn move_marker(&mut self, sel: Selection, displayed_vertex: u32, record: bool) {
        if !self.marker_exists(sel) {
            return;
        }
        let Some(slot) = self.slot(sel.side) else {
            return;
        };
        let f = slot.to_file(displayed_vertex);
        let cur = match sel.side {
            Side::Source => self.corr[sel.pair].source_vertex,
            Side::Target => self.corr[sel.pair].target_vertices[sel.k],
        };
        if cur == f {
            return;
        }
        if record {
            self.push_undo();
        }
        match sel.side {
            Side::Source => self.corr[sel.pair].source_vertex = f,
            Side::Target => self.corr[sel.pair].target_vertices[sel.k] = f,
        }
        self.schedule_restart_now();
    }

    /// Replace all correspondences (e.g. from a file), as one undoable edit.
    pub fn set_correspondences(&mut self, corr: Vec<Correspondence>) -> Result<()> {
        for (side, verts) in [
            (
                Side::Source,
                corr.iter().map(|c| c.source_vertex).collect::<Vec<_>>(),
            ),
            (
                Side::Target,
                corr.iter()
                    .flat_map(|c| c.target_vertices.iter().copied())
                    .collect(),
            ),
        ] {
            if let Some(slot) = self.slot(side) {
                let n = slot.file.positions.len() as u32;
                if let Some(bad) = verts.iter().find(|&&v| v >= n) {
                    return Err(Error::InvalidInput(format!(
                        "correspondence vertex {bad} out of range for the {side:?} mesh ({n} vertices)"
                    )));
                }
            }
        }
        self.push_undo();
        self.corr = corr;
        self.selected = None;
        self.pending_source = None;
        self.schedule_restart_now();
        Ok(())
    }

    // ----- painting -----

    /// Paint (or erase) around a point on one side's displayed mesh with the current brush.
    /// `record` pushes an undo step (true at the start of a stroke). Returns painted vertex count.
    pub fn paint_at(&mut self, side: Side, center: [f32; 3], record: bool) -> usize {
        let brush = self.brush;
        if record && self.slot(side).is_some() {
            self.push_undo();
        }
        let Some(slot) = self.slot_mut(side) else {
            return 0;
        };
        let mesh = slot.displayed();
        let frame = crate::render::Frame::of_points(&mesh.positions);
        let r = (brush.radius * frame.radius).max(1e-9);
        let c = glam::Vec3::from(center);
        let n = mesh.positions.len();
        let positions = mesh.positions.clone();
        let paint = slot.paint.get_or_insert_with(|| vec![[0.0; 4]; n]);
        let mut count = 0;
        for (p, dst) in positions.iter().zip(paint.iter_mut()) {
            let d = glam::Vec3::from(*p).distance(c) / r;
            if d >= 1.0 {
                continue;
            }
            // Hardness h: full strength inside radius h, smooth falloff to 0 at the rim.
            let h = brush.hardness.clamp(0.0, 0.999);
            let t = ((d - h) / (1.0 - h)).clamp(0.0, 1.0);
            let w = 1.0 - t * t * (3.0 - 2.0 * t);
            if brush.eraser {
                dst[3] *= 1.0 - w;
            } else {
                let a = dst[3] + w * (1.0 - dst[3]);
                for k in 0..3 {
                    dst[k] = if a > 0.0 {
                        (dst[k] * dst[3] * (1.0 - w) + brush.color[k] * w) / a
                    } else {
                        brush.color[k]
                    };
                }
                dst[3] = a;
            }
            count += 1;
        }
        slot.colors_dirty = true;
        count
    }

    /// Paint coverage per displayed vertex of one side (0 where unpainted).
    pub fn paint_coverage(&self, side: Side) -> Option<Vec<f32>> {
        let slot = self.slot(side)?;
        let n = slot.displayed().num_vertices();
        Some(match &slot.paint {
            Some(p) => p.iter().map(|x| x[3]).collect(),
            None => vec![0.0; n],
        })
    }

    /// Take a finished application's outcome: new colours become the side's paint layer (one
    /// undo step), a new mesh replaces the side without starting a transfer on it.
    pub fn apply_tool_outcome(&mut self, outcome: super::tools::ToolOutcome) {
        use super::tools::ToolOutcome;
        match outcome {
            ToolOutcome::Colors(side, colors, message) => {
                self.end_tool_preview();
                let Some(n) = self.slot(side).map(|s| s.displayed().num_vertices()) else {
                    return;
                };
                if colors.len() != n {
                    self.report("the completed mesh no longer matches the view (it was re-prepared); run it again");
                    return;
                }
                self.push_undo();
                if let Some(slot) = self.meshes[side_index(side)].as_mut() {
                    slot.paint = Some(colors.iter().map(|c| [c[0], c[1], c[2], 1.0]).collect());
                    slot.colors_dirty = true;
                }
                self.message = message;
            }
            ToolOutcome::Mesh(side, mesh, message) => {
                self.set_mesh(side, mesh, false);
                // The result is the answer: do not overwrite it with a transfer.
                self.restart_at = None;
                self.message = message;
            }
        }
    }

    /// Show a running tool's partial result on one side: `colors` (at least one per displayed
    /// vertex; the first ones are used) replace the displayed colours until the tool ends. The
    /// paint layer underneath is kept aside and comes back with [`AppState::end_tool_preview`];
    /// previews are not undo steps. False when the side is gone or has fewer colours than vertices.
    pub fn show_tool_preview(&mut self, side: Side, colors: &[[f32; 3]]) -> bool {
        let Some(slot) = self.meshes[side_index(side)].as_mut() else {
            return false;
        };
        let n = slot.displayed().num_vertices();
        if colors.len() < n {
            return false;
        }
        if self.preview_backup.is_none() {
            self.preview_backup = Some((side, slot.id, slot.paint.clone()));
        }
        slot.paint = Some(
            colors[..n]
                .iter()
                .map(|c| [c[0], c[1], c[2], 1.0])
                .collect(),
        );
        slot.colors_dirty = true;
        true
    }

    /// Take a tool preview down: the side's paint layer returns to what it was before.
    pub fn end_tool_preview(&mut self) {
        let Some((side, id, paint)) = self.preview_backup.take() else {
            return;
        };
        if let Some(slot) = self.meshes[side_index(side)].as_mut()
            && slot.id == id
        {
            let n = slot.displayed().num_vertices();
            // a re-prepared mesh (other vertices) dropped its paint: keep it dropped
            slot.paint = paint.filter(|p| p.len() == n);
            slot.colors_dirty = true;
        }
    }

    /// The displayed mesh of one side with its displayed colours (paint included), for export.
    pub fn painted_mesh(&self, side: Side) -> Option<TriMesh> {
        let slot = self.slot(side)?;
        let mut m = slot.displayed().clone();
        m.colors = Some(slot.display_colors());
        m.texture = None;
        m.uvs = None;
        Some(m)
    }

    // ----- export and sessions -----

    /// The target slot and the finished transfer, or the error an export reports.
    fn target_and_result(&self) -> Result<(&MeshSlot, &Solved)> {
        let slot = self
            .slot(Side::Target)
            .ok_or_else(|| Error::InvalidInput("no target mesh".into()))?;
        let res = self
            .result
            .as_ref()
            .ok_or_else(|| Error::InvalidInput("no finished transfer to export yet".into()))?;
        Ok((slot, res))
    }

    /// Write the transfer result on the target file mesh as `transfer --out` does (format by
    /// extension; `.glb`/`.obj` of a target with UVs get a texture baked into its UV layout).
    pub fn export_result(&self, path: &Path) -> Result<()> {
        let (slot, res) = self.target_and_result()?;
        if res.file_signal.len() != slot.file.positions.len() {
            return Err(Error::InvalidInput(
                "result does not match the target mesh".into(),
            ));
        }
        let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("");
        let m = match &res.layout {
            Some(layout) => crate::meshmatch::deliver(
                &slot.file,
                layout,
                &res.working_signal,
                &res.file_signal,
                ext,
                EXPORT_TEXTURE_SIZE,
            ),
            None => {
                let mut m = (*slot.file).clone();
                m.colors = Some(res.file_signal.clone());
                m.texture = None;
                m
            }
        };
        crate::mesh::io::save(&m, path)
    }

    /// Write the transfer result on the dense working mesh (as `transfer --out-dense` does).
    pub fn export_dense_result(&self, path: &Path) -> Result<()> {
        let (slot, res) = self.target_and_result()?;
        let working = slot
            .working
            .as_ref()
            .filter(|w| w.positions.len() == res.working_signal.len())
            .ok_or_else(|| {
                Error::InvalidInput("result does not match the target's working mesh".into())
            })?;
        crate::mesh::io::save(
            &crate::meshmatch::deliver_dense(working, &res.working_signal),
            path,
        )
    }

    /// Save the session as JSON at `path`. Meshes are named by file, or by built-in scene when
    /// they have none; each paint layer goes to a PLY sidecar beside it (the displayed mesh with
    /// the paint's colours) with its coverage in the JSON.
    pub fn save_session(&self, path: &Path) -> Result<()> {
        let mut names: [(Option<PathBuf>, Option<String>); 2] = [(None, None), (None, None)];
        for side in [Side::Source, Side::Target] {
            if let Some(slot) = self.slot(side) {
                let file = slot.file.path.as_ref().map(|p| abs(p));
                let name = (file, slot.scene.clone());
                if name.0.is_none() && name.1.is_none() {
                    return Err(Error::InvalidInput(format!(
                        "the {side:?} mesh has no file (it was computed): export it and open \
                         the file before saving the session"
                    )));
                }
                names[side_index(side)] = name;
            }
        }
        let mut paint: [(Option<PathBuf>, Option<Vec<u8>>); 2] = [(None, None), (None, None)];
        for (side, suffix) in [
            (Side::Source, "source_paint"),
            (Side::Target, "target_paint"),
        ] {
            let Some(slot) = self.slot(side) else {
                continue;
            };
            let Some(layer) = &slot.paint else { continue };
            let p = path.with_extension(format!("{suffix}.ply"));
            let mut m = slot.displayed().clone();
            m.colors = Some(layer.iter().map(|c| [c[0], c[1], c[2]]).collect());
            m.texture = None;
            m.uvs = None;
            m.normals = None;
            crate::mesh::io::save(&m, &p)?;
            let coverage = layer
                .iter()
                .map(|c| (c[3].clamp(0.0, 1.0) * 255.0).round() as u8)
                .collect();
            // Named relative to the session file, so the pair can move together.
            let name = p.file_name().map_or_else(|| p.clone(), PathBuf::from);
            paint[side_index(side)] = (Some(name), Some(coverage));
        }
        let [(src_paint, src_cov), (tgt_paint, tgt_cov)] = paint;
        let [(source, source_scene), (target, target_scene)] = names;
        let session = Session {
            source,
            target,
            correspondences: CorrespondenceFile {
                correspondences: self.corr.clone(),
            },
            params: self.params.clone(),
            source_paint: src_paint,
            target_paint: tgt_paint,
            source_paint_coverage: src_cov,
            target_paint_coverage: tgt_cov,
            source_scene,
            target_scene,
            source_texture: self
                .slot(Side::Source)
                .and_then(|s| s.texture_file.as_ref().map(|p| abs(p))),
        };
        let text = serde_json::to_string_pretty(&session)
            .map_err(|e| Error::InvalidInput(format!("cannot serialise session: {e}")))?;
        crate::mesh::io::write_atomic(path, text.as_bytes())
    }

    /// Open a session JSON: both meshes (files or built-in scenes), the source texture,
    /// correspondences, parameters and paint. Nothing changes when any part fails to load.
    pub fn open_session(&mut self, path: &Path) -> Result<()> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        let s: Session<P> = serde_json::from_str(&text)
            .map_err(|e| Error::format(path, format!("invalid session JSON: {e}")))?;
        // Relative paths in the session are relative to the session file.
        let dir = path.parent().unwrap_or(Path::new("."));
        let resolve = |p: &PathBuf| dir.join(p);
        let mut built: Vec<(String, super::DemoScene)> = Vec::new();
        let mut meshes = Vec::new();
        for (side, file, scene) in [
            (Side::Source, &s.source, &s.source_scene),
            (Side::Target, &s.target, &s.target_scene),
        ] {
            let mesh = match (file, scene) {
                (Some(f), _) => crate::mesh::io::load(&resolve(f))?,
                (None, Some(name)) => {
                    if !built.iter().any(|(n, _)| n == name) {
                        let sc = self.build_scene(name)?;
                        built.push((name.clone(), sc));
                    }
                    let sc = &built
                        .iter()
                        .find(|(n, _)| n == name)
                        .expect("built above")
                        .1;
                    match side {
                        Side::Source => sc.source.clone(),
                        Side::Target => sc.target.clone(),
                    }
                }
                (None, None) => {
                    return Err(Error::format(
                        path,
                        format!("session names no {side:?} mesh (neither a file nor a scene)"),
                    ));
                }
            };
            mesh_usable(&mesh)?;
            meshes.push((
                side,
                mesh,
                if file.is_none() { scene.clone() } else { None },
            ));
        }
        let texture = s.source_texture.as_ref().map(resolve);
        if let Some(t) = &texture {
            meshes[0].1 = with_texture(&meshes[0].1, t)?;
        }
        let mut samples = [None, None];
        for (i, (sidecar, coverage)) in [
            (&s.source_paint, &s.source_paint_coverage),
            (&s.target_paint, &s.target_paint_coverage),
        ]
        .into_iter()
        .enumerate()
        {
            let Some(sidecar) = sidecar else { continue };
            let m = crate::mesh::io::load(&resolve(sidecar))?;
            let colors = m.colors.clone().ok_or_else(|| {
                Error::format(resolve(sidecar), "paint sidecar has no vertex colours")
            })?;
            if coverage.as_ref().is_some_and(|c| c.len() != colors.len()) {
                return Err(Error::format(
                    path,
                    "paint coverage does not match its sidecar's vertex count",
                ));
            }
            let rgba = colors
                .iter()
                .enumerate()
                .map(|(v, c)| {
                    let a = coverage.as_ref().map_or(1.0, |cov| cov[v] as f32 / 255.0);
                    [c[0], c[1], c[2], a]
                })
                .collect();
            samples[i] = Some(PaintSample {
                positions: m.positions,
                rgba,
            });
        }
        let counts = [meshes[0].1.positions.len(), meshes[1].1.positions.len()];
        for c in &s.correspondences.correspondences {
            let bad_t = c.target_vertices.iter().any(|&t| t as usize >= counts[1]);
            if c.source_vertex as usize >= counts[0] || bad_t {
                return Err(Error::format(
                    path,
                    "a correspondence is out of range for the session's meshes",
                ));
            }
        }
        // Everything loaded: replace the state.
        for (side, mesh, scene) in meshes {
            self.set_mesh(side, mesh, false);
            if let Some(slot) = self.slot_mut(side) {
                slot.scene = scene;
                if side == Side::Source {
                    slot.texture_file = texture.clone();
                }
            }
        }
        for (i, sample) in samples.into_iter().enumerate() {
            if let (Some(sample), Some(slot)) = (sample, self.meshes[i].as_mut()) {
                let applied =
                    remap_paint(&sample.positions, &sample.rgba, &slot.displayed().positions);
                slot.paint = Some(applied.clone());
                slot.restored_paint = Some((sample, applied));
                slot.colors_dirty = true;
            }
        }
        self.params = s.params;
        self.set_correspondences(s.correspondences.correspondences)?;
        self.undo.clear();
        self.push_recent(path, RecentKind::Session);
        Ok(())
    }
}

/// `p` as an absolute path (unchanged if that fails).
fn abs(p: &Path) -> PathBuf {
    std::path::absolute(p).unwrap_or_else(|_| p.to_path_buf())
}

/// `mesh` with a texture image from `path` (it must have UVs); its vertex colours are dropped.
fn with_texture(mesh: &TriMesh, path: &Path) -> Result<TriMesh> {
    if mesh.uvs.is_none() {
        return Err(Error::InvalidInput(
            "the mesh has no UV coordinates to map a texture".into(),
        ));
    }
    let tex = crate::mesh::io::load_texture(path)?;
    let mut mesh = mesh.clone();
    mesh.texture = Some(Arc::new(tex));
    mesh.colors = None;
    Ok(mesh)
}

/// Reject meshes that cannot be displayed or transferred.
pub fn mesh_usable(mesh: &TriMesh) -> Result<()> {
    if mesh.positions.is_empty() || mesh.faces.is_empty() {
        return Err(Error::InvalidMesh("the mesh has no faces".into()));
    }
    Ok(())
}

pub use crate::render::marker_color;
