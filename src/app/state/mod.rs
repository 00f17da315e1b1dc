//! The app's state, independent of any window: meshes, correspondences, undo history, paint
//! layers, parameters and job status. The UI calls these methods; tests call them directly.
//!
//! By seam: `slot.rs` (loaded meshes), `correspondences.rs` (editing pairs), `history.rs` (paint
//! layers and undo), `session.rs` (sessions, Recent, exports), `changes.rs` (unsaved work); the
//! job and meshes here.

mod changes;
mod correspondences;
mod history;
pub mod layers;
pub mod paint_fill;
pub mod paint_layer;
mod session;
mod slot;

pub use correspondences::Selection;
use history::Snapshot;
pub use history::{Brush, PaintMode};
pub use layers::{LayerShow, Layers, PaintTarget};
pub use session::{RecentFile, RecentKind, Session, default_recent_store};
pub use slot::{MeshSlot, nearest_map, remap_paint};

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant};

use crate::correspondence::Side;
use crate::correspondence::{Correspondence, CorrespondenceFile};
use crate::error::{Error, Result};
use crate::jobs::worker::{Solved, WorkerEvent};
use crate::mesh::TriMesh;
use crate::work::{Event, Progress};

/// Delay between the last edit and the restart of the transfer.
pub const DEBOUNCE: Duration = Duration::from_millis(150);
/// Most undo steps kept.
pub const UNDO_LIMIT: usize = 100;
/// Size (pixels per side) of the texture baked on export, as `transfer --texture-size` defaults.
pub const EXPORT_TEXTURE_SIZE: u32 = 2048;

/// Parameters the app can edit, save and send to the worker.
pub trait AppParams:
    Clone + Default + PartialEq + serde::Serialize + serde::de::DeserializeOwned + Send + 'static
{
    /// Draw the parameter editors (each with a tooltip); true when a value changed.
    fn ui(&mut self, ui: &mut eframe::egui::Ui) -> bool;
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
    /// Visibility and opacity of the result, the paint and the mask (views and export).
    pub layers: Layers,
    /// Colours strokes were painted with, newest first.
    pub color_history: Vec<[f32; 3]>,
    /// Recently opened files, newest first.
    pub recent: Vec<RecentFile>,
    /// File the Recent list is saved to after every change (`None`: not persisted).
    pub recent_store: Option<PathBuf>,
    /// Built-in scenes by name, so sessions saved from them can be reopened.
    pub scenes: Vec<super::SceneEntry>,
    /// Polylines an open tool draws over a view (the feature-aligned tool's salient curves).
    pub overlay: Option<std::sync::Arc<CurveOverlay>>,
    /// An overlay polyline the user clicked in its view this frame (the open tool keeps or
    /// drops it).
    pub overlay_clicked: Option<usize>,
    undo: Vec<Snapshot>,
    redo: Vec<Snapshot>,
    /// Paint layer kept aside while a tool previews partial results: side, mesh id, paint.
    preview_backup: Option<PreviewBackup>,
    restart_at: Option<Instant>,
    requests: Vec<Request<P>>,
    next_id: u64,
    /// Changes counted so far ([`AppState::mark_changed`]).
    edits: u64,
    /// `edits` when the work was last saved (`None`: never, as after a recovery).
    saved_edits: Option<u64>,
    /// The session file last saved or opened.
    session_path: Option<PathBuf>,
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
            layers: Layers::default(),
            color_history: Vec::new(),
            recent: Vec::new(),
            recent_store: None,
            scenes: Vec::new(),
            overlay: None,
            overlay_clicked: None,
            undo: Vec::new(),
            redo: Vec::new(),
            preview_backup: None,
            restart_at: None,
            requests: Vec::new(),
            next_id: 1,
            edits: 0,
            saved_edits: Some(0),
            session_path: None,
        }
    }

    /// The slot of one side.
    pub fn slot(&self, side: Side) -> Option<&MeshSlot> {
        self.meshes[side_index(side)].as_ref()
    }

    pub(super) fn slot_mut(&mut self, side: Side) -> Option<&mut MeshSlot> {
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
        self.mark_changed();
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
                    let f = crate::correspondence::CorrespondenceFile::load(path)?;
                    self.set_correspondence_file(f, path)
                }
            }
            _ => self.open_mesh(side, path),
        }
    }

    /// Build a built-in scene by name.
    pub(super) fn build_scene(&self, name: &str) -> Result<super::DemoScene> {
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
        self.set_correspondences(scene.correspondences)?;
        // A built-in scene as it comes is no unsaved work.
        self.session_path = None;
        self.mark_saved(None);
        Ok(())
    }

    /// Take the requests for the worker accumulated since the last call.
    pub fn take_requests(&mut self) -> Vec<Request<P>> {
        std::mem::take(&mut self.requests)
    }

    /// Restart the transfer after the debounce delay (called after every edit).
    pub fn schedule_restart(&mut self, now: Instant) {
        self.restart_at = Some(now + DEBOUNCE);
    }

    pub(super) fn schedule_restart_now(&mut self) {
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
            self.mark_changed();
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
                    .any(|s| s.paint[i].is_some() || s.mask[i].is_some());
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
                slot.own_signal = side == Side::Source;
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
                let map = if slot.paint.is_some() || slot.mask.is_some() || history_paint {
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
                let mut mask = slot.mask.take();
                carry(&mut mask);
                slot.mask = mask.filter(|l| l.len() == working.positions.len());
                slot.normals =
                    crate::render::gpu::vertex_normals(&working.positions, &working.faces);
                slot.working = Some(working);
                slot.working_to_file = Some(working_to_file);
                slot.file_to_working = Some(f2w);
                slot.geometry_dirty = true;
                slot.colors_dirty = true;
                for snap in self.undo.iter_mut().chain(self.redo.iter_mut()) {
                    carry(&mut snap.paint[i]);
                    carry(&mut snap.mask[i]);
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
                self.show_result_texture(&result);
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

    /// Show a finished result at its texture's resolution: the target's working mesh takes the
    /// result's UVs and texture and is drawn through it, per pixel (until the next partial
    /// result, which is shown in vertex colours again).
    fn show_result_texture(&mut self, result: &Solved) {
        let Some((uvs, texture)) = &result.texture else {
            return;
        };
        if let Some(slot) = self.slot_mut(Side::Target)
            && let Some(working) = slot.working.as_ref()
            && uvs.len() == 3 * working.faces.len()
        {
            let mut shown = (**working).clone();
            shown.uvs = Some(uvs.to_vec());
            shown.texture = Some(texture.clone());
            slot.working = Some(Arc::new(shown));
            slot.own_signal = true;
            slot.geometry_dirty = true;
        }
    }

    pub(super) fn set_target_colors(&mut self, signal: &[[f32; 3]]) {
        if let Some(slot) = self.slot_mut(Side::Target)
            && signal.len() == slot.displayed().positions.len()
        {
            slot.base_colors = signal.to_vec();
            slot.own_signal = false;
            slot.colors_dirty = true;
        }
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

/// Polylines drawn over one view, in the mesh's coordinates: kept ones bright, dropped ones faint.
#[derive(Clone, Debug, Default)]
pub struct CurveOverlay {
    /// The view they belong to.
    pub side: Option<Side>,
    /// The polylines and whether each closes on itself (shared with the tool that found them).
    pub lines: std::sync::Arc<Vec<(Vec<[f32; 3]>, bool)>>,
    /// Per polyline, whether it is kept.
    pub kept: Vec<bool>,
    /// Short arrows along a tangent field (start, end), in the mesh's coordinates.
    pub arrows: std::sync::Arc<Vec<[[f32; 3]; 2]>>,
}
