//! The desktop app: source and target viewports with locked cameras, correspondence editing,
//! painting, progressive transfer preview from a worker thread, files, sessions, undo/redo.
//!
//! All state lives in [`state::AppState`] (testable without a window); [`MeshMatchApp`] draws it
//! with egui and forwards requests to the [`crate::jobs::worker::Worker`].

pub mod autosave;
pub mod brush;
pub mod engine;
pub mod feature_aligned;
pub mod files;
pub mod paint_bench;
pub mod quilt;
pub mod state;
pub mod system_tool;
pub mod systems;
pub mod tools;
pub mod unsaved;
pub mod view;
pub mod weather;

use std::path::PathBuf;
use std::time::Instant;

use eframe::egui::{self, Color32};

use crate::correspondence::Side;
use crate::error::{Error, Result};
use crate::jobs::worker::{Command, Engine, Worker};
pub use state::{AppParams, AppState, Brush, Request, Selection};
pub use view::{Tool, Views};

/// What `main` passes to the app.
#[derive(Clone, Debug, Default)]
pub struct Startup {
    /// Source mesh file; `None` (with no target) = the default demo scene.
    pub source: Option<PathBuf>,
    /// Target mesh file.
    pub target: Option<PathBuf>,
    /// Correspondences JSON to load with the meshes.
    pub correspondences: Option<PathBuf>,
}

/// Rolling UI frame-time statistics (milliseconds).
#[derive(Clone, Debug, Default)]
pub struct FrameStats {
    times: std::collections::VecDeque<f32>,
}

impl FrameStats {
    /// Record the CPU time of one frame.
    pub fn push(&mut self, ms: f32) {
        self.times.push_back(ms);
        if self.times.len() > 240 {
            self.times.pop_front();
        }
    }
    /// Number of frames recorded (at most 240).
    pub fn len(&self) -> usize {
        self.times.len()
    }
    /// No frame recorded yet.
    pub fn is_empty(&self) -> bool {
        self.times.is_empty()
    }
    /// Mean and maximum over the recent frames.
    pub fn summary(&self) -> (f32, f32) {
        let n = self.times.len().max(1) as f32;
        let mean = self.times.iter().sum::<f32>() / n;
        let max = self.times.iter().copied().fold(0.0, f32::max);
        (mean, max)
    }
}

/// The eframe application.
pub struct MeshMatchApp<E: Engine>
where
    E::Params: AppParams,
{
    /// Window-independent state.
    pub state: AppState<E::Params>,
    /// The viewports.
    pub views: Views,
    worker: Worker<E::Params>,
    show_help: bool,
    /// UI frame times (CPU time spent in `ui`).
    pub frame_stats: FrameStats,
    demo_scenes: Vec<SceneEntry>,
    frame_log_every: Option<std::time::Duration>,
    frame_log_each: bool,
    frame_log_at: Instant,
    last_frame_start: Option<Instant>,
    /// The running application (completion, update, detail), if any.
    pub tool: Option<tools::ToolJob>,
    /// The synthesis systems' tools ([`systems::registry`]): windows, settings, jobs.
    pub systems: Vec<Box<dyn systems::SystemTool<E::Params>>>,
    /// File dialogs (the system's, or the built-in browser where it cannot work).
    pub files: files::FileDialogs,
    /// The window was checked against the monitor's size.
    fitted_to_monitor: bool,
    /// What the transfer moves (colour or detail) and the detail strength.
    pub signal: tools::SignalSettings,
    repaint: Option<egui::Context>,
    /// The unsaved-work prompt, the autosave and the recovery offer.
    pub safety: unsaved::Safety,
}

/// Whether the views draw on a CPU rasteriser (set once the render state is known); read by the
/// worker's wake-up callbacks, which are made before the window exists.
static SOFTWARE_RENDERER: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

/// Longest a worker event waits for a repaint (bursts of events coalesce; while a job runs the
/// window also repaints every [`busy_repaint`]). Input still repaints at once. On a software
/// renderer, where every frame of the window costs the job CPU, streamed results show twice a
/// second instead of ten times.
fn wake_delay() -> std::time::Duration {
    let software = SOFTWARE_RENDERER.load(std::sync::atomic::Ordering::Relaxed);
    std::time::Duration::from_millis(if software { 500 } else { 100 })
}
/// Repaint period while a job runs and nothing else asks for a frame (streamed results show, the
/// busy indicator turns, the elapsed time counts): 20 frames a second on a GPU, 1 on a software
/// renderer, where each frame of the window costs the job about a tenth of a second of CPU (the
/// default transfer took 28 s in the app at 10 frames a second, 17 s at 4; 12 s in the CLI;
/// later 10.8 s at 4 frames a second plus results streamed at up to 10, against 7.5 s in the CLI).
fn busy_repaint(software_renderer: bool) -> std::time::Duration {
    std::time::Duration::from_millis(if software_renderer { 1000 } else { 50 })
}

/// A small rotating arc that says "working". Unlike `egui::Spinner`, which asks for a repaint
/// every frame, it asks for one after `period` (see [`busy_repaint`]), so a running job does not
/// keep the window (and a software renderer) drawing flat out.
fn busy_indicator(ui: &mut egui::Ui, period: std::time::Duration) {
    let size = ui.spacing().interact_size.y;
    let (rect, _) = ui.allocate_exact_size(egui::vec2(size, size), egui::Sense::hover());
    let t = ui.input(|i| i.time) as f32;
    let r = rect.height() * 0.35;
    let start = (t * 5.0) % std::f32::consts::TAU;
    let points: Vec<egui::Pos2> = (0..=16)
        .map(|k| {
            let a = start + k as f32 / 16.0 * std::f32::consts::PI * 1.5;
            rect.center() + r * egui::vec2(a.cos(), a.sin())
        })
        .collect();
    ui.painter().add(egui::Shape::line(
        points,
        egui::Stroke::new(2.0, ui.visuals().strong_text_color()),
    ));
    ui.ctx().request_repaint_after(period);
}

/// A Scene-menu entry: its name and the function that builds it.
pub type SceneEntry = (String, fn() -> Result<DemoScene>);

/// A demo scene: two meshes and their correspondences.
pub struct DemoScene {
    /// Exemplar mesh.
    pub source: crate::mesh::TriMesh,
    /// Mesh to texture.
    pub target: crate::mesh::TriMesh,
    /// Correspondences in file indices.
    pub correspondences: Vec<crate::correspondence::Correspondence>,
}

impl<E: Engine> MeshMatchApp<E>
where
    E::Params: AppParams,
{
    /// Create the app with `engine` on a worker thread; `repaint` wakes the UI on worker events.
    pub fn new(engine: E, repaint: Option<egui::Context>) -> Self {
        let wake_ctx = repaint.clone();
        let worker = Worker::spawn(engine, move || {
            if let Some(ctx) = &repaint {
                // Coalesce bursts of events into at most one repaint per wake delay.
                ctx.request_repaint_after(wake_delay());
            }
        });
        MeshMatchApp {
            state: AppState::new(),
            views: Views::default(),
            worker,
            show_help: false,
            frame_stats: FrameStats::default(),
            demo_scenes: Vec::new(),
            // MESHMATCH_FRAME_LOG=1 prints UI frame-time statistics to stderr every 2 s.
            frame_log_every: std::env::var_os("MESHMATCH_FRAME_LOG")
                .map(|_| std::time::Duration::from_secs(2)),
            // MESHMATCH_FRAME_LOG=frames also prints every frame's time (for percentiles).
            frame_log_each: std::env::var_os("MESHMATCH_FRAME_LOG").is_some_and(|v| v == "frames"),
            frame_log_at: Instant::now(),
            last_frame_start: None,
            tool: None,
            systems: systems::registry(),
            files: files::FileDialogs::default(),
            fitted_to_monitor: false,
            signal: tools::SignalSettings::default(),
            repaint: wake_ctx,
            safety: unsaved::Safety::default(),
        }
    }

    /// Start an application on the current meshes (`which`: "complete-target",
    /// "complete-source", "detail"); errors become messages.
    pub fn start_tool(&mut self, which: &str) {
        if let Some(t) = &self.tool {
            self.state.report(format!(
                "{} is still running: wait for it or cancel it",
                t.name
            ));
            return;
        }
        let ctx = self.repaint.clone();
        let wake = move || {
            if let Some(c) = &ctx {
                c.request_repaint_after(wake_delay());
            }
        };
        let job = match which {
            "complete-target" | "complete-source" => {
                let side = if which == "complete-target" {
                    Side::Target
                } else {
                    Side::Source
                };
                match (
                    self.state.painted_mesh(side),
                    self.state.paint_coverage(side),
                ) {
                    (Some(m), Some(c)) => tools::completion_job(side, m, c, wake),
                    _ => Err(Error::InvalidInput(format!("no {side:?} mesh to complete"))),
                }
            }
            "suggest" => match (self.state.slot(Side::Source), self.state.slot(Side::Target)) {
                (Some(s), Some(t)) => Ok(tools::suggest_job(
                    (*s.file).clone(),
                    (*t.file).clone(),
                    self.state.corr.clone(),
                    tools::SUGGESTED_PAIRS,
                    wake,
                )),
                _ => Err(Error::InvalidInput(
                    "suggesting correspondences needs a source and a target mesh".into(),
                )),
            },
            "atlas-source" | "atlas-target" => {
                let side = if which == "atlas-target" {
                    Side::Target
                } else {
                    Side::Source
                };
                match self.state.slot(side) {
                    Some(s) => Ok(tools::atlas_job(
                        side,
                        s.id,
                        s.working.clone().unwrap_or_else(|| s.file.clone()),
                        state::paint_layer::TEXEL_LAYER_SIZE,
                        wake,
                    )),
                    None => Err(Error::InvalidInput(format!("no {side:?} mesh to lay out"))),
                }
            }
            "detail" => match (self.state.slot(Side::Source), self.state.slot(Side::Target)) {
                (Some(s), Some(t)) => Ok(tools::detail_job(
                    (*s.file).clone(),
                    (*t.file).clone(),
                    self.signal.strength,
                    wake,
                )),
                _ => Err(Error::InvalidInput(
                    "detail transfer needs a source (detailed) and a target mesh".into(),
                )),
            },
            _ => Err(Error::InvalidInput(format!("unknown tool {which}"))),
        };
        match job {
            Ok(j) => {
                self.state.message = format!("{} running...", j.name);
                self.tool = Some(j);
            }
            Err(e) => self.state.report(e),
        }
    }

    /// The system tool of type `T`, if this build has it.
    pub fn system<T: 'static>(&self) -> Option<&T> {
        self.systems.iter().find_map(|t| {
            let any: &dyn std::any::Any = t.as_ref();
            any.downcast_ref::<T>()
        })
    }

    /// The system tool of type `T`, mutable, if this build has it.
    pub fn system_mut<T: 'static>(&mut self) -> Option<&mut T> {
        self.systems
            .iter_mut()
            .find_map(|t| t.as_any_mut().downcast_mut::<T>())
    }

    /// Open the "Paint with exemplar" window, with `image` already chosen when given.
    pub fn open_exemplar_dialog(&mut self, image: Option<PathBuf>) {
        if let Some(d) = self.system_mut::<tools::ExemplarDialog>() {
            d.open = true;
            if image.is_some() {
                d.settings.image = image;
            }
        }
    }

    /// Paint with exemplar with `settings` (see [`Self::start_system`]).
    pub fn start_exemplar(&mut self, settings: &tools::ExemplarSettings) {
        let Some(i) = self
            .systems
            .iter_mut()
            .position(|t| t.as_any_mut().is::<tools::ExemplarDialog>())
        else {
            return;
        };
        if let Some(d) = self.systems[i]
            .as_any_mut()
            .downcast_mut::<tools::ExemplarDialog>()
        {
            d.settings = settings.clone();
        }
        self.start_system(i);
    }

    /// Start system tool `i` with its current settings on its own thread; partial results show
    /// in the view; errors are messages.
    pub fn start_system(&mut self, i: usize) {
        if let Some(t) = &self.tool {
            self.state.report(format!(
                "{} is still running: wait for it or cancel it",
                t.name
            ));
            return;
        }
        let ctx = self.repaint.clone();
        let wake: systems::Wake = Box::new(move || {
            if let Some(c) = &ctx {
                c.request_repaint_after(wake_delay());
            }
        });
        let Some(tool) = self.systems.get_mut(i) else {
            return;
        };
        match tool.start(&self.state, wake) {
            Ok(j) => {
                self.state.message = format!("{} running...", j.name);
                self.tool = Some(j);
            }
            Err(e) => self.state.report(e),
        }
    }

    /// Export the transfer result to `path` in the background (a texture bake, and an atlas for a
    /// target without UVs, take seconds): progress in the status bar, cancel, no frozen window.
    pub fn start_export(&mut self, path: &std::path::Path) {
        if let Some(t) = &self.tool {
            self.state.report(format!(
                "{} is still running: wait for it or cancel it",
                t.name
            ));
            return;
        }
        let task = match self.state.export_task(path) {
            Ok(t) => t,
            Err(e) => return self.state.report(e),
        };
        let ctx = self.repaint.clone();
        let j = tools::ToolJob::spawn(
            "export",
            move || {
                if let Some(c) = &ctx {
                    c.request_repaint_after(wake_delay());
                }
            },
            move |_sink, cancel| Ok(tools::ToolOutcome::Done(task(cancel)?)),
        );
        self.state.message = format!("exporting {}...", path.display());
        self.tool = Some(j);
    }

    /// Start the texture update: the source (textured, old geometry) onto `new` geometry.
    pub fn start_update(&mut self, new: crate::mesh::TriMesh) {
        if self.tool.is_some() {
            self.state
                .report("an application is still running: wait for it or cancel it");
            return;
        }
        let Some(old) = self.state.slot(Side::Source).map(|s| (*s.file).clone()) else {
            self.state
                .report("open the textured mesh (old geometry) as the source first");
            return;
        };
        let ctx = self.repaint.clone();
        let j = tools::update_job(old, new, move || {
            if let Some(c) = &ctx {
                c.request_repaint_after(wake_delay());
            }
        });
        self.state.message = format!("{} running...", j.name);
        self.tool = Some(j);
    }

    /// Apply a finished application's outcome (called every frame).
    pub fn poll_tool(&mut self) {
        let Some(t) = &self.tool else { return };
        if let Some(side) = t.preview
            && let Some(p) = t.take_partial()
        {
            self.state.show_tool_preview(side, &p);
        }
        let Some(r) = t.poll() else { return };
        let name = t.name;
        self.tool = None;
        self.state.end_tool_preview();
        match r {
            Ok(o) => {
                let replaces = matches!(o, tools::ToolOutcome::Mesh(..));
                self.state.apply_tool_outcome(o);
                if replaces {
                    self.views.frame_all();
                }
            }
            Err(Error::Cancelled) => self.state.message = format!("{name} cancelled"),
            Err(e) => self.state.report(format!("{name}: {e}")),
        }
    }

    /// Register demo scenes for the Scene menu.
    pub fn with_demo_scenes(mut self, scenes: Vec<SceneEntry>) -> Self {
        self.state.scenes = scenes.clone();
        self.demo_scenes = scenes;
        self
    }

    /// Load a demo scene by its index in the Scene menu.
    pub fn load_demo(&mut self, index: usize) -> Result<()> {
        let (name, _) = self
            .demo_scenes
            .get(index)
            .ok_or_else(|| Error::InvalidInput("no such demo scene".into()))?;
        let name = name.clone();
        self.state.load_scene_named(&name)?;
        self.views.frame_all();
        Ok(())
    }

    /// Show a scene (two meshes + correspondences) and start the transfer.
    pub fn load_scene(&mut self, scene: DemoScene) -> Result<()> {
        self.state.set_mesh(Side::Source, scene.source, false);
        self.state.set_mesh(Side::Target, scene.target, false);
        self.state.set_correspondences(scene.correspondences)?;
        self.views.frame_all();
        Ok(())
    }

    /// Apply startup options: open files, or the first demo scene. What opens is the saved
    /// state (no unsaved work yet).
    pub fn startup(&mut self, s: &Startup) {
        self.open_startup(s);
        self.state.mark_saved(None);
    }

    fn open_startup(&mut self, s: &Startup) {
        match (&s.source, &s.target) {
            (None, None) => {
                if !self.demo_scenes.is_empty()
                    && let Err(e) = self.load_demo(0)
                {
                    self.state.report(e);
                }
            }
            (src, tgt) => {
                for (side, p) in [(Side::Source, src), (Side::Target, tgt)] {
                    if let Some(p) = p
                        && let Err(e) = self.state.open_mesh(side, p)
                    {
                        self.state.report(e);
                    }
                }
                if let Some(c) = &s.correspondences {
                    let r = crate::correspondence::CorrespondenceFile::load(c)
                        .and_then(|f| self.state.set_correspondence_file(f, c));
                    if let Err(e) = r {
                        self.state.report(e);
                    }
                }
            }
        }
    }

    /// Forward the state's requests to the worker and apply the worker's events (never blocks).
    pub fn pump(&mut self, now: Instant) {
        self.state.tick(now);
        for req in self.state.take_requests() {
            match req {
                Request::SetMesh(side, id, mesh) => self.worker.send(match side {
                    Side::Source => Command::SetSource(id, mesh),
                    Side::Target => Command::SetTarget(id, mesh),
                }),
                Request::Start(corr, params) => {
                    let job = self.worker.start(corr, params);
                    self.state.job_started(job);
                }
                Request::Cancel => self.worker.cancel(),
            }
        }
        for ev in self.worker.poll() {
            self.state.apply_event(ev);
        }
    }

    /// Wait (up to `timeout`) for worker events and apply them; for tests and scripts.
    pub fn wait_events(&mut self, timeout: std::time::Duration) -> bool {
        match self.worker.recv_timeout(timeout) {
            Some(ev) => {
                self.state.apply_event(ev);
                for ev in self.worker.poll() {
                    self.state.apply_event(ev);
                }
                true
            }
            None => false,
        }
    }

    /// Carry out a file action with the chosen path; errors go to the message window.
    fn apply_file(&mut self, action: files::FileAction, p: PathBuf) {
        use files::FileAction as A;
        let result = match action {
            A::OpenMesh(side) => return self.guard(unsaved::Guarded::OpenMesh(side, p)),
            A::OpenTexture => self.state.open_texture(&p),
            A::OpenCorrespondences => crate::correspondence::CorrespondenceFile::load(&p)
                .and_then(|f| self.state.set_correspondence_file(f, &p)),
            A::SaveCorrespondences => self.state.correspondence_file().save(&p),
            A::ExportResult => {
                self.start_export(&p);
                Ok(())
            }
            A::ExportDense => self.state.export_dense_result(&p),
            A::ExportPainted(side) => match self.state.painted_export_mesh(side) {
                Some(m) => crate::mesh::io::save(&m, &p),
                None => Err(Error::InvalidInput("no mesh".into())),
            },
            A::OpenSession => return self.guard(unsaved::Guarded::OpenSession(p)),
            A::SaveSession => {
                let r = self.state.save_session_to(&p);
                self.session_saved(r.is_ok());
                r
            }
            A::SystemFile(i, _) => {
                if let Some(t) = self.systems.get_mut(i) {
                    t.set_file(p.clone());
                }
                Ok(())
            }
            A::SystemSave(i, _) => {
                if let Some(t) = self.systems.get_mut(i) {
                    t.set_save_file(p.clone());
                }
                self.start_system(i);
                return;
            }
            A::EditedGeometry => crate::mesh::io::load(&p).map(|m| self.start_update(m)),
        };
        match result {
            Ok(()) => {
                let verb = match action {
                    A::SaveCorrespondences | A::SaveSession => "saved",
                    A::ExportResult | A::ExportDense | A::ExportPainted(_) => "exported",
                    A::SystemFile(_, prompt) => prompt.1,
                    A::EditedGeometry => return,
                    _ => "opened",
                };
                self.state.message = format!("{verb} {}", p.display());
            }
            Err(e) => self.state.report(e),
        }
    }

    fn menu_bar(&mut self, ui: &mut egui::Ui) {
        egui::MenuBar::new().ui(ui, |ui| {
            ui.menu_button("File", |ui| {
                let mut result: Result<()> = Ok(());
                use files::FileAction as A;
                let mut ask = |ui: &mut egui::Ui, label: &str, action: A, hover: Option<&str>| {
                    let mut r = ui.button(label);
                    if let Some(h) = hover {
                        r = r.on_hover_text(h);
                    }
                    if r.clicked() {
                        self.files.request(action);
                        ui.close();
                    }
                };
                ask(ui, "Open source mesh...", A::OpenMesh(Side::Source), None);
                ask(ui, "Open target mesh...", A::OpenMesh(Side::Target), None);
                ask(ui, "Open source texture...", A::OpenTexture, None);
                ask(ui, "Open correspondences...", A::OpenCorrespondences, None);
                ask(ui, "Save correspondences...", A::SaveCorrespondences, None);
                ui.separator();
                ask(
                    ui,
                    "Export result...",
                    A::ExportResult,
                    Some("Format by extension, as `transfer --out` (a baked texture for .glb/.obj with UVs)"),
                );
                ask(
                    ui,
                    "Export dense result...",
                    A::ExportDense,
                    Some("The result on the working-resolution mesh (PLY vertex colours)"),
                );
                for side in [Side::Source, Side::Target] {
                    ask(
                        ui,
                        &format!("Export painted {side:?}..."),
                        A::ExportPainted(side),
                        None,
                    );
                }
                ui.separator();
                ask(ui, "Open session...", A::OpenSession, None);
                ask(
                    ui,
                    "Save session as...",
                    A::SaveSession,
                    Some("Meshes by file, computed meshes and paint in files beside the session"),
                );
                let mut guarded = None;
                if ui.button("Save session  (Ctrl+S)").clicked() {
                    self.save_or_ask(None);
                    ui.close();
                }
                if ui
                    .button("New session  (Ctrl+N)")
                    .on_hover_text("Empty views; asks to save unsaved work first")
                    .clicked()
                {
                    guarded = Some(unsaved::Guarded::New);
                    ui.close();
                }
                ui.separator();
                ui.menu_button("Recent", |ui| {
                    if self.state.recent.is_empty() {
                        ui.label("(none)");
                    }
                    let mut opened = false;
                    for r in self.state.recent.clone() {
                        let (name, p) = (r.path.display().to_string(), &r.path);
                        match r.kind {
                            state::RecentKind::Session => {
                                if ui.button(format!("Session {name}")).clicked() {
                                    guarded = Some(unsaved::Guarded::OpenSession(p.clone()));
                                    opened = true;
                                }
                            }
                            state::RecentKind::Texture => {
                                if ui.button(format!("Source texture {name}")).clicked() {
                                    result = self.state.open_texture(p);
                                }
                            }
                            state::RecentKind::Mesh => {
                                ui.horizontal(|ui| {
                                    ui.label(&name);
                                    if ui.small_button("as source").clicked() {
                                        guarded = Some(unsaved::Guarded::OpenMesh(
                                            Side::Source,
                                            p.clone(),
                                        ));
                                        opened = true;
                                    }
                                    if ui.small_button("as target").clicked() {
                                        guarded = Some(unsaved::Guarded::OpenMesh(
                                            Side::Target,
                                            p.clone(),
                                        ));
                                        opened = true;
                                    }
                                });
                            }
                        }
                    }
                    if opened {
                        self.views.frame_all();
                        ui.close();
                    }
                });
                if let Err(e) = result {
                    self.state.report(e);
                }
                if let Some(g) = guarded {
                    self.guard(g);
                }
            });
            ui.menu_button("Edit", |ui| {
                if ui.button("Undo  (Ctrl+Z)").clicked() {
                    self.state.undo();
                }
                if ui.button("Redo  (Ctrl+Shift+Z)").clicked() {
                    self.state.redo();
                }
                if ui.button("Delete selected  (Del)").clicked() {
                    self.state.delete_selected();
                }
            });
            ui.menu_button("Tools", |ui| {
                let busy = self.tool.is_some();
                if ui
                    .add_enabled(!busy, egui::Button::new("Complete target from its paint"))
                    .on_hover_text(
                        "Paint-by-example: the painted part of the target is the example, \
                         the rest is synthesised (MeshMatch §5.4)",
                    )
                    .clicked()
                {
                    self.start_tool("complete-target");
                    ui.close();
                }
                if ui
                    .add_enabled(!busy, egui::Button::new("Complete source from its paint"))
                    .clicked()
                {
                    self.start_tool("complete-source");
                    ui.close();
                }
                if ui
                    .add_enabled(
                        !busy,
                        egui::Button::new("Update texture for new geometry..."),
                    )
                    .on_hover_text(
                        "The source is the textured mesh before the edit; pick the edited \
                         geometry: unchanged parts keep their colours, the rest is synthesised",
                    )
                    .clicked()
                {
                    ui.close();
                    self.files.request(files::FileAction::EditedGeometry);
                }
                if ui
                    .add_enabled(!busy, egui::Button::new("Transfer detail source -> target"))
                    .on_hover_text(
                        "Move the source's fine geometric detail onto the target's surface \
                         (MeshMatch §5.3), with the strength set under Parameters > Signal: detail",
                    )
                    .clicked()
                {
                    self.start_tool("detail");
                    ui.close();
                }
                let mut open = None;
                for (i, t) in self.systems.iter().enumerate() {
                    if ui
                        .add_enabled(!busy, egui::Button::new(t.label()))
                        .on_hover_text(t.hover())
                        .clicked()
                    {
                        open = Some(i);
                        ui.close();
                    }
                }
                if let Some(i) = open {
                    self.systems[i].set_open(true);
                }
            });
            ui.menu_button("Scene", |ui| {
                let mut pick = None;
                for (i, (name, _)) in self.demo_scenes.iter().enumerate() {
                    if ui.button(name).clicked() {
                        pick = Some(i);
                    }
                }
                if self.demo_scenes.is_empty() {
                    ui.label("(no demo scenes)");
                }
                if let Some(i) = pick {
                    self.guard(unsaved::Guarded::Scene(i));
                }
            });
            ui.menu_button("View", |ui| {
                if ui
                    .checkbox(&mut self.views.wireframe, "Wireframe")
                    .changed()
                {
                    self.views.invalidate();
                }
                ui.checkbox(&mut self.views.lock_cameras, "Lock cameras");
                if ui
                    .button("Show geometric feature...")
                    .on_hover_text(
                        "Colour either view by ambient occlusion, curvature at a radius, height \
                         or the weathering guidance (the same window as under Tools)",
                    )
                    .clicked()
                {
                    if let Some(d) = self.system_mut::<weather::FeatureDialog>() {
                        d.open = true;
                    }
                    ui.close();
                }
                if ui.button("Frame all  (F)").clicked() {
                    self.views.frame_all();
                }
                ui.checkbox(&mut self.show_help, "Help  (H)");
            });
            if ui
                .button("?")
                .on_hover_text("Mouse and keyboard help")
                .clicked()
            {
                self.show_help = !self.show_help;
            }
        });
    }

    /// For a side whose displayed mesh has no UVs (it paints its vertices): a button that lays
    /// out a UV atlas on it, so that strokes paint a texel layer.
    fn atlas_buttons(&mut self, ui: &mut egui::Ui) {
        for side in [Side::Source, Side::Target] {
            let Some(slot) = self.state.slot(side) else {
                continue;
            };
            if state::paint_layer::has_uvs(slot.displayed()) {
                continue;
            }
            let free = self.tool.is_none();
            if ui
                .add_enabled(
                    free,
                    egui::Button::new(format!("UV atlas for the {side:?}")),
                )
                .on_hover_text(format!(
                    "The {side:?} mesh has no UVs, so strokes paint its vertices. Lay out a UV \
                     atlas on it (in the background) to paint a {0}x{0} texel layer instead; \
                     paint already on its vertices stays with the result",
                    state::paint_layer::TEXEL_LAYER_SIZE
                ))
                .clicked()
            {
                self.start_tool(match side {
                    Side::Source => "atlas-source",
                    Side::Target => "atlas-target",
                });
            }
        }
    }

    /// Visibility and opacity of the result, the paint and the mask, and the layer painted into.
    fn layers_panel(&mut self, ui: &mut egui::Ui) {
        use state::PaintTarget;
        ui.label(egui::RichText::new("Layers").strong());
        let mut layers = self.state.layers;
        let target = &mut self.state.brush.target;
        egui::Grid::new("paint layers").num_columns(3).show(ui, |ui| {
            let rows = [
                (
                    "Result",
                    &mut layers.result,
                    None,
                    "The mesh's texture or colours, a transfer's result, an application's outcome",
                ),
                (
                    "Paint",
                    &mut layers.paint,
                    Some(PaintTarget::Paint),
                    "The brush's paint (completion takes it as the example)",
                ),
                (
                    "Mask",
                    &mut layers.mask,
                    Some(PaintTarget::Mask),
                    "A mask: painting with exemplar acts where it is painted",
                ),
            ];
            ui.label(egui::RichText::new("shown").small().weak());
            ui.label(egui::RichText::new("opacity").small().weak());
            ui.label(egui::RichText::new("paint into").small().weak());
            ui.end_row();
            for (name, l, t, tip) in rows {
                ui.checkbox(&mut l.visible, name)
                    .on_hover_text(format!("{tip}. Shown and exported when ticked"));
                ui.add(egui::Slider::new(&mut l.opacity, 0.0..=1.0))
                    .on_hover_text("How strongly the views and the export show the layer");
                match t {
                    Some(t) => {
                        ui.radio_value(target, t, "")
                            .on_hover_text("Strokes and fills go into this layer");
                    }
                    None => {
                        ui.label("");
                    }
                }
                ui.end_row();
            }
        });
        if layers != self.state.layers {
            self.state.set_layers(layers);
            self.views.invalidate();
        }
    }

    fn side_panel(&mut self, ui: &mut egui::Ui) {
        egui::ScrollArea::vertical().show(ui, |ui| {
            ui.heading("Tool");
            ui.horizontal(|ui| {
                ui.selectable_value(&mut self.views.tool, Tool::Correspond, "Correspondences")
                    .on_hover_text("Click source then target to add a pair");
                ui.selectable_value(&mut self.views.tool, Tool::Paint, "Paint")
                    .on_hover_text(
                        "Click or drag to paint what the view sees (at the texture's \
                         resolution on a mesh with UVs, else on its vertices); Alt+drag orbits",
                    );
            });
            if self.views.tool == Tool::Paint {
                let b = &mut self.state.brush;
                ui.horizontal(|ui| {
                    use state::PaintMode;
                    ui.selectable_value(&mut b.mode, PaintMode::Brush, "Brush")
                        .on_hover_text("Click or drag to paint");
                    ui.selectable_value(&mut b.mode, PaintMode::Eyedropper, "Eyedropper")
                        .on_hover_text(
                            "Click to take the colour under the pointer (also Ctrl+click)",
                        );
                    ui.selectable_value(&mut b.mode, PaintMode::Fill, "Fill").on_hover_text(
                        "Click to fill the connected region of similar colour under the pointer \
                         (across UV seams); one undo step",
                    );
                    ui.selectable_value(&mut b.mode, PaintMode::IslandFill, "Island")
                        .on_hover_text(
                            "Click to fill the whole UV island (chart) under the pointer; \
                             without UVs, the connected part of the mesh. One undo step",
                        );
                });
                if b.mode == state::PaintMode::Fill {
                    ui.add(egui::Slider::new(&mut b.fill_tolerance, 0.0..=1.0).text("tolerance"))
                        .on_hover_text(
                            "A fill spreads while the shown colour differs from the clicked one by \
                             at most this in every channel",
                        );
                }
                ui.add(egui::Slider::new(&mut b.radius, 0.005..=0.5).text("radius"))
                    .on_hover_text("Brush radius as a fraction of the mesh size");
                ui.add(egui::Slider::new(&mut b.hardness, 0.0..=1.0).text("hardness"))
                    .on_hover_text("1 = hard edge, 0 = soft falloff");
                ui.horizontal(|ui| {
                    ui.color_edit_button_rgb(&mut b.color);
                    ui.checkbox(&mut b.eraser, "eraser");
                });
                ui.horizontal(|ui| {
                    ui.checkbox(&mut b.through, "paint through").on_hover_text(
                        "Paint a ball around the point under the pointer, surfaces hidden from \
                         the view included (for masks). Off: only what the view sees under the \
                         brush.",
                    );
                    ui.add_enabled(
                        !b.through,
                        egui::Checkbox::new(&mut b.normal_falloff, "normal falloff"),
                    )
                    .on_hover_text("Fade the dab where the surface turns away from the view");
                });
                ui.add(egui::Slider::new(&mut b.spacing, 0.05..=2.0).text("spacing"))
                    .on_hover_text("Distance between a stroke's dabs, in brush radii");
                ui.add(egui::Slider::new(&mut b.smoothing, 0.0..=0.95).text("smoothing"))
                    .on_hover_text(
                        "Stroke smoothing: the stroke lags behind the pointer and \
                                    its path smooths out",
                    );
                if !self.state.color_history.is_empty() {
                    ui.horizontal_wrapped(|ui| {
                        for c in self.state.color_history.clone() {
                            let [r, g, bl] = c.map(|x| (x * 255.0).round() as u8);
                            let swatch = egui::Button::new("")
                                .fill(Color32::from_rgb(r, g, bl))
                                .min_size(egui::vec2(18.0, 18.0));
                            if ui
                                .add(swatch)
                                .on_hover_text("A colour painted with: click to paint with it")
                                .clicked()
                            {
                                self.state.brush.color = c;
                                self.state.brush.eraser = false;
                            }
                        }
                    });
                }
                ui.label(
                    egui::RichText::new(
                        "Ctrl+click picks a colour, Shift+click draws a straight line",
                    )
                    .small()
                    .weak(),
                );
                self.layers_panel(ui);
                self.atlas_buttons(ui);
            }
            ui.separator();
            ui.horizontal(|ui| {
                ui.heading("Correspondences");
                let ready = self.tool.is_none()
                    && self.state.slot(Side::Source).is_some()
                    && self.state.slot(Side::Target).is_some();
                if ui
                    .add_enabled(ready, egui::Button::new("Suggest"))
                    .on_hover_text(format!(
                        "Add {} well-spread pairs from the global shape map (functional maps, \
                         the current pairs as landmarks); move or delete any. One undo step.",
                        tools::SUGGESTED_PAIRS
                    ))
                    .clicked()
                {
                    self.start_tool("suggest");
                }
            });
            if let Some(v) = self.state.pending_source {
                ui.colored_label(Color32::YELLOW, format!("source {v} waiting for a target"));
            }
            let mut delete = None;
            let mut select = None;
            egui::Grid::new("pairs").striped(true).show(ui, |ui| {
                for (i, c) in self.state.corr.iter().enumerate() {
                    let [r, g, b] = state::marker_color(i);
                    let sel = self.state.selected.is_some_and(|s| s.pair == i);
                    let label = egui::RichText::new(format!("{:>2}", i + 1))
                        .color(Color32::from_rgb(r, g, b))
                        .strong();
                    if ui.selectable_label(sel, label).clicked() {
                        select = Some(i);
                    }
                    let targets: Vec<String> =
                        c.target_vertices.iter().map(|t| t.to_string()).collect();
                    ui.label(format!("{} -> {}", c.source_vertex, targets.join(", ")));
                    if ui
                        .small_button("x")
                        .on_hover_text("Delete this pair")
                        .clicked()
                    {
                        delete = Some(i);
                    }
                    ui.end_row();
                }
            });
            if let Some(i) = select {
                self.state.select(Some(Selection {
                    pair: i,
                    side: Side::Source,
                    k: 0,
                }));
            }
            if let Some(i) = delete {
                self.state.delete_pair(i);
            }
            ui.separator();
            ui.heading("Parameters");
            self.signal.ui(ui);
            let mut p = self.state.params.clone();
            if p.ui(ui) {
                self.state.set_params(p, Instant::now());
            }
            ui.separator();
            ui.horizontal(|ui| {
                if self.signal.signal == tools::Signal::Detail {
                    if ui
                        .add_enabled(self.tool.is_none(), egui::Button::new("Transfer detail"))
                        .on_hover_text(
                            "Displace the target by the source's detail at the chosen strength \
                             (replaces the target)",
                        )
                        .clicked()
                    {
                        self.start_tool("detail");
                    }
                } else if ui.button("Restart transfer").clicked() {
                    self.state.schedule_restart(Instant::now());
                }
                if ui
                    .add_enabled(self.state.job.running, egui::Button::new("Cancel"))
                    .clicked()
                {
                    self.state.cancel_job();
                }
            });
        });
    }

    fn status_bar(&mut self, ui: &mut egui::Ui) {
        ui.horizontal(|ui| {
            let j = &self.state.job;
            let p = &j.progress;
            if j.running {
                busy_indicator(ui, busy_repaint(self.views.software_renderer));
                let mut text = p.stage.to_string();
                if p.levels > 0 {
                    text += &format!(
                        "  level {} of {} (0 = finest)  iteration {}",
                        p.level, p.levels, p.iteration
                    );
                }
                if p.energy > 0.0 {
                    text += &format!("  energy {:.4}", p.energy);
                }
                text += &format!("  {:.1} s", p.elapsed);
                ui.label(text);
                ui.add(egui::ProgressBar::new(p.fraction).desired_width(120.0));
            } else if !j.outcome.is_empty() {
                ui.label(format!("transfer {}", j.outcome));
            } else if self.state.restart_pending() {
                ui.label("transfer starting...");
            }
            if let Some(t) = &self.tool {
                ui.separator();
                busy_indicator(ui, busy_repaint(self.views.software_renderer));
                let f = t.fraction.lock().map(|f| *f).unwrap_or(0.0);
                ui.label(format!(
                    "{} {:.1} s",
                    t.name,
                    t.started.elapsed().as_secs_f32()
                ));
                ui.add(egui::ProgressBar::new(f).desired_width(100.0));
                if ui.small_button("Cancel").clicked() {
                    t.cancel.cancel();
                }
            }
            ui.separator();
            ui.label(&self.state.message);
            ui.with_layout(egui::Layout::right_to_left(egui::Align::Center), |ui| {
                let (mean, max) = self.frame_stats.summary();
                ui.label(format!("UI {mean:.1} ms (max {max:.1})"));
            });
        });
    }

    fn help_window(&mut self, ctx: &egui::Context) {
        let mut open = self.show_help;
        egui::Window::new("Help")
            .open(&mut open)
            .collapsible(false)
            .show(ctx, |ui| {
                ui.label(
                    "Mouse (either view)\n\
                     - Orbit: left-drag, or Alt + left-drag\n\
                     - Pan: middle-drag, or Shift + left-drag\n\
                     - Zoom: mouse wheel\n\
                     - Cameras are locked by default (View > Lock cameras): both views move \
                       together relative to each mesh's bounds.\n\n\
                     Correspondences\n\
                     - Click a source point, then a target point: adds a numbered pair.\n\
                     - Shift-click on the target: adds another target point to the selected pair.\n\
                     - Click a marker to select it; drag it to move it; Delete removes it.\n\n\
                     Painting (Tool: Paint)\n\
                     - Click or left-drag paints what the view sees, Alt + left-drag orbits.\n\
                     - Shift + click: a straight line from the last dab; Ctrl + click: pick \
                     the colour under the pointer.\n\n\
                     Keys\n\
                     - F frame all - H help - Ctrl+Z undo - Ctrl+Shift+Z redo - Delete remove\n\
                     - Drop a file on a view: a mesh opens there, an image becomes its \
                       texture, a JSON opens as a session (or correspondences).",
                );
            });
        self.show_help = open;
    }

    fn system_windows(&mut self, ctx: &egui::Context) {
        let busy = self.tool.is_some();
        for i in 0..self.systems.len() {
            if !self.systems[i].is_open() {
                continue;
            }
            let mut open = true;
            let mut action = systems::ToolAction::None;
            let (tool, state) = (&mut self.systems[i], &self.state);
            egui::Window::new(tool.label().trim_end_matches("..."))
                .open(&mut open)
                .collapsible(false)
                .resizable(false)
                .show(ctx, |ui| action = tool.ui(ui, state, busy));
            if action == systems::ToolAction::ChooseFile {
                let prompt = self.systems[i].file_prompt();
                self.files.request(files::FileAction::SystemFile(i, prompt));
                action = systems::ToolAction::None;
            }
            if action == systems::ToolAction::ChooseSaveFile {
                let prompt = self.systems[i].save_prompt();
                self.files.request(files::FileAction::SystemSave(i, prompt));
                action = systems::ToolAction::None;
            }
            self.systems[i].set_open(open && action == systems::ToolAction::None);
            if action == systems::ToolAction::Run {
                self.start_system(i);
            }
        }
    }

    fn errors_window(&mut self, ctx: &egui::Context) {
        if self.state.errors.is_empty() {
            return;
        }
        let mut dismiss = false;
        egui::Window::new("Error")
            .collapsible(false)
            .show(ctx, |ui| {
                for e in &self.state.errors {
                    ui.colored_label(Color32::from_rgb(255, 120, 120), e);
                }
                if ui.button("Dismiss").clicked() {
                    dismiss = true;
                }
            });
        if dismiss {
            self.state.errors.clear();
        }
    }

    fn shortcuts(&mut self, ctx: &egui::Context) {
        let typing = ctx.egui_wants_keyboard_input();
        if typing {
            return;
        }
        let (save, new) = ctx.input(|i| {
            let cmd = i.modifiers.command && !i.modifiers.shift;
            (
                cmd && i.key_pressed(egui::Key::S),
                cmd && i.key_pressed(egui::Key::N),
            )
        });
        if save {
            self.save_or_ask(None);
        }
        if new {
            self.guard(unsaved::Guarded::New);
        }
        let (undo, redo, del, frame, help) = ctx.input(|i| {
            let cmd = i.modifiers.command;
            (
                cmd && !i.modifiers.shift && i.key_pressed(egui::Key::Z),
                cmd && (i.modifiers.shift && i.key_pressed(egui::Key::Z)
                    || i.key_pressed(egui::Key::Y)),
                i.key_pressed(egui::Key::Delete) || i.key_pressed(egui::Key::Backspace),
                i.key_pressed(egui::Key::F),
                i.key_pressed(egui::Key::H),
            )
        });
        if undo {
            self.state.undo();
        }
        if redo {
            self.state.redo();
        }
        if del {
            self.state.delete_selected();
        }
        if frame {
            self.views.frame_all();
        }
        if help {
            self.show_help = !self.show_help;
        }
    }

    /// Draw one frame of the whole UI into `ui`.
    pub fn frame_ui(&mut self, ui: &mut egui::Ui, rs: Option<&eframe::egui_wgpu::RenderState>) {
        let clock = Instant::now();
        let ctx = ui.ctx().clone();
        self.pump(Instant::now());
        self.poll_tool();
        self.shortcuts(&ctx);
        egui::Panel::top("menu").show(ui, |ui| self.menu_bar(ui));
        egui::Panel::bottom("status").show(ui, |ui| self.status_bar(ui));
        egui::Panel::right("side")
            .default_size(300.0)
            .show(ui, |ui| self.side_panel(ui));
        self.state.overlay = self
            .systems
            .iter()
            .filter(|t| t.is_open())
            .find_map(|t| t.overlay());
        let dropped = egui::CentralPanel::no_frame()
            .show(ui, |ui| self.views.show(ui, rs, &mut self.state))
            .inner;
        if let Some(line) = self.state.overlay_clicked.take()
            && let Some(t) = self
                .systems
                .iter_mut()
                .find(|t| t.is_open() && t.overlay().is_some())
        {
            t.overlay_clicked(line);
        }
        if let Some((side, path)) = dropped {
            self.guard(unsaved::Guarded::Dropped(side, path));
        }
        self.help_window(&ctx);
        self.system_windows(&ctx);
        self.files.show(&ctx);
        if let Some((action, path)) = self.files.take() {
            self.apply_file(action, path);
        }
        self.safety_after_files();
        self.errors_window(&ctx);
        self.safety_frame(&ctx);
        // Edits made this frame: send them now rather than next frame.
        self.pump(Instant::now());
        if self.state.restart_pending() {
            ctx.request_repaint_after(state::DEBOUNCE / 3);
        }
        SOFTWARE_RENDERER.store(
            self.views.software_renderer,
            std::sync::atomic::Ordering::Relaxed,
        );
        if self.state.job.running || self.tool.is_some() {
            ctx.request_repaint_after(busy_repaint(self.views.software_renderer));
        }
        let frame_ms = clock.elapsed().as_secs_f32() * 1000.0;
        self.frame_stats.push(frame_ms);
        if self.frame_log_each {
            // The interval since the previous frame's start includes egui's tessellation,
            // the window's paint and present, and any idle wait for the next repaint.
            let interval = self
                .last_frame_start
                .map_or(0.0, |t| clock.duration_since(t).as_secs_f32() * 1000.0);
            eprintln!(
                "frame-ms {frame_ms:.3} interval-ms {interval:.3} paint-ms {:.3} upload-ms {:.3} dabs {} running {} partials {} outcome {}",
                self.views.paint_ms.get(),
                self.views.upload_ms.get(),
                self.views.dabs.get(),
                self.state.job.running as u8,
                self.state.job.partials,
                self.state.job.outcome
            );
        }
        self.last_frame_start = Some(clock);
        self.views.paint_ms.set(0.0);
        self.views.upload_ms.set(0.0);
        self.views.dabs.set(0);
        if let Some(every) = self.frame_log_every
            && self.frame_log_at.elapsed() >= every
        {
            let (mean, max) = self.frame_stats.summary();
            eprintln!(
                "frame-stats: mean {mean:.2} ms max {max:.2} ms over {} frames; running {} stage {} partials {} view draw ms {:?}",
                self.frame_stats.len(),
                self.state.job.running,
                self.state.job.progress.stage,
                self.state.job.partials,
                self.views.last_draw_ms
            );
            self.frame_log_at = Instant::now();
        }
    }
}

impl<E: Engine> eframe::App for MeshMatchApp<E>
where
    E::Params: AppParams,
{
    fn ui(&mut self, ui: &mut egui::Ui, frame: &mut eframe::Frame) {
        let rs = frame.wgpu_render_state().cloned();
        self.fit_to_monitor(ui.ctx());
        self.frame_ui(ui, rs.as_ref());
    }

    fn on_exit(&mut self) {
        // a clean exit: nothing to recover at the next start
        self.finish_autosave();
    }
}

impl<E: Engine> MeshMatchApp<E>
where
    E::Params: AppParams,
{
    /// Once the monitor's size is known: shrink a window that does not fit on it (the default
    /// 1400x820 on a 1280x1024 Xvfb screen would hide the side panel's right edge).
    fn fit_to_monitor(&mut self, ctx: &egui::Context) {
        if self.fitted_to_monitor {
            return;
        }
        let (monitor, inner) = ctx.input(|i| (i.viewport().monitor_size, i.viewport().inner_rect));
        let (Some(m), Some(r)) = (monitor, inner) else {
            return;
        };
        self.fitted_to_monitor = true;
        // Room for a title bar and a panel or task bar.
        let want = egui::vec2(r.width().min(m.x - 16.0), r.height().min(m.y - 64.0))
            .max(egui::vec2(640.0, 400.0));
        if want.x < r.width() || want.y < r.height() {
            ctx.send_viewport_cmd(egui::ViewportCommand::InnerSize(want));
            ctx.send_viewport_cmd(egui::ViewportCommand::OuterPosition(egui::pos2(0.0, 0.0)));
        }
    }
}

/// Run the app with a given engine (blocks until the window closes).
pub fn run_with<E: Engine>(engine: E, startup: Startup, demo_scenes: Vec<SceneEntry>) -> Result<()>
where
    E::Params: AppParams,
{
    // Background work (the worker's and the tools' parallel loops) runs on rayon's global pool at
    // a lower priority than the window, which uses no rayon itself: the UI and the software
    // renderer stay smooth while a transfer fills every core, at no cost when the UI is idle.
    // (Already built, e.g. by an embedding program: keep that pool.)
    let _ = rayon::ThreadPoolBuilder::new()
        .start_handler(|_| crate::work::lower_thread_priority())
        .build_global();
    let options = eframe::NativeOptions {
        viewport: egui::ViewportBuilder::default()
            .with_inner_size([1400.0, 820.0])
            .with_title("MeshMatch")
            .with_drag_and_drop(true),
        renderer: eframe::Renderer::Wgpu,
        ..Default::default()
    };
    eframe::run_native(
        "MeshMatch",
        options,
        Box::new(move |cc| {
            let mut app =
                MeshMatchApp::new(engine, Some(cc.egui_ctx.clone())).with_demo_scenes(demo_scenes);
            if let Some(store) = state::default_recent_store() {
                app.state.load_recent(store);
            }
            app.startup(&startup);
            if let Some(root) = autosave::data_dir() {
                app = app.with_autosave(&root, autosave::period_from_env());
            }
            Ok(Box::new(app))
        }),
    )
    .map_err(|e| Error::InvalidInput(format!("cannot open the window: {e}")))
}

/// Run the desktop app (blocks until the window closes). With no paths in `startup` it opens the
/// demo scene (procedural zebra -> giraffe) with the transfer already running.
pub fn run(startup: Startup) -> Result<()> {
    run_with(engine::MeshMatchEngine, startup, engine::demo_scenes())
}
