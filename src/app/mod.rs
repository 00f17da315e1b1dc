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
pub mod quilting;
pub mod state;
pub mod system_tool;
pub mod systems;
pub mod tools;
pub mod unsaved;
pub mod view;
pub mod weathering;

mod menu;
mod scenes;
mod side_panel;
mod start;
mod status_bar;
mod windows;

pub use scenes::{DemoScene, SceneEntry};

use std::path::PathBuf;
use std::time::Instant;

use eframe::egui::{self};

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
