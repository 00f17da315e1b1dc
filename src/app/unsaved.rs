//! Nothing lost: the Save / Don't save / Cancel prompt before closing the window or replacing
//! the session with unsaved work, the periodic autosave and the recovery prompt at start.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use eframe::egui;

use crate::correspondence::Side;

use super::autosave::{self, Autosave, Recovery};
use super::files::FileAction;
use super::{AppParams, Engine, MeshMatchApp};

/// An action that would drop unsaved work: asked about first when the work is unsaved.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Guarded {
    /// Close the window.
    Close,
    /// File > New session.
    New,
    /// A built-in scene (index in the Scene menu).
    Scene(usize),
    /// Open a session file.
    OpenSession(PathBuf),
    /// Open a mesh into one side (it drops the correspondences, that side's paint and the undo
    /// history; the other side stays).
    OpenMesh(Side, PathBuf),
    /// A file dropped on a view (opened by its kind).
    Dropped(Side, PathBuf),
}

impl Guarded {
    /// Whether the action keeps the session (a texture or correspondence file dropped on a
    /// view is an undoable edit, not a replacement).
    fn keeps_work(&self) -> bool {
        match self {
            Guarded::Dropped(_, p) => {
                let ext = p
                    .extension()
                    .map(|e| e.to_string_lossy().to_ascii_lowercase())
                    .unwrap_or_default();
                match ext.as_str() {
                    "png" | "jpg" | "jpeg" => true,
                    // a session replaces everything; a correspondence file is one undo step
                    "json" => !is_session_file(p),
                    _ => false,
                }
            }
            _ => false,
        }
    }

    /// The question the prompt asks.
    fn question(&self) -> String {
        let name = |p: &Path| {
            p.file_name()
                .map_or_else(|| p.display().to_string(), |n| n.to_string_lossy().into())
        };
        match self {
            Guarded::Close => "Save your work before closing?".into(),
            Guarded::New => "Save your work before starting a new session?".into(),
            Guarded::Scene(_) => "Save your work before opening the scene?".into(),
            Guarded::OpenSession(p) | Guarded::Dropped(_, p) => {
                format!("Save your work before opening {}?", name(p))
            }
            Guarded::OpenMesh(side, p) => format!(
                "Save your work before opening {} as the {}? (Its pairs and undo history go.)",
                name(p),
                if *side == Side::Source {
                    "source"
                } else {
                    "target"
                }
            ),
        }
    }
}

fn is_json(p: &Path) -> bool {
    p.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("json"))
}

/// Whether a JSON file is a session (it has parameters) rather than a correspondence file.
fn is_session_file(p: &Path) -> bool {
    crate::mesh::io::read_text_file(p, "the session file")
        .ok()
        .and_then(|t| serde_json::from_str::<serde_json::Value>(&t).ok())
        .is_some_and(|v| v.get("params").is_some())
}

/// The prompt's and the autosave's state in the app.
#[derive(Debug, Default)]
pub struct Safety {
    /// This app's autosave (none when the data folder cannot be used).
    pub autosave: Option<Autosave>,
    /// Autosaves of apps that were killed, offered one at a time.
    pub recoveries: Vec<Recovery>,
    /// The action waiting for the Save / Don't save / Cancel answer.
    pub confirm: Option<Guarded>,
    /// The action to carry out once the Save dialog has saved the session.
    after_save: Option<Guarded>,
    /// The window may close (the user answered the prompt, or nothing was unsaved).
    close_allowed: bool,
    /// The window should be asked to close at the next frame.
    close_now: bool,
}

impl<E: Engine> MeshMatchApp<E>
where
    E::Params: AppParams,
{
    /// Autosave into `<root>/autosave/` every `period` while there are unsaved changes, and
    /// offer the autosaves of killed apps found there for recovery.
    pub fn with_autosave(mut self, root: &Path, period: Duration) -> Self {
        self.safety.recoveries = autosave::orphans(root);
        match Autosave::start(root, period) {
            Ok(a) => self.safety.autosave = Some(a),
            Err(e) => self.state.message = format!("no autosave: {e}"),
        }
        self
    }

    /// Whether the window may close now (nothing unsaved, or the user answered the prompt).
    pub fn close_allowed(&self) -> bool {
        self.safety.close_allowed
    }

    /// Whether `action` would drop unsaved work: anything unsaved for a replacement of the
    /// whole session; for a mesh opened into one side (the other stays), only the pairs, that
    /// side's paint or a computed mesh there.
    fn drops_work(&self, action: &Guarded) -> bool {
        if !self.state.is_dirty() || action.keeps_work() {
            return false;
        }
        let side = match action {
            Guarded::OpenMesh(side, _) => *side,
            Guarded::Dropped(side, p) if !is_json(p) => *side,
            _ => return true,
        };
        let slot = self.state.slot(side);
        !self.state.corr.is_empty()
            || slot.is_some_and(|s| {
                s.paint
                    .as_ref()
                    .is_some_and(|p| p.iter().any(|c| c[3] > 0.0))
                    || (s.file.path.is_none() && s.scene.is_none())
            })
    }

    /// Carry out `action`, after asking to save when there is unsaved work it would drop.
    pub fn guard(&mut self, action: Guarded) {
        if self.drops_work(&action) {
            self.safety.confirm = Some(action);
        } else {
            self.perform(action);
        }
    }

    fn perform(&mut self, action: Guarded) {
        let r = match action {
            Guarded::Close => {
                self.safety.close_allowed = true;
                self.safety.close_now = true;
                Ok(())
            }
            Guarded::New => {
                self.state.new_session();
                Ok(())
            }
            Guarded::Scene(i) => self.load_demo(i),
            Guarded::OpenSession(p) => self.state.open_session(&p).map(|()| self.open_message(&p)),
            Guarded::OpenMesh(side, p) => self
                .state
                .open_mesh(side, &p)
                .map(|()| self.open_message(&p)),
            Guarded::Dropped(side, p) => self
                .state
                .open_any(side, &p)
                .map(|()| self.open_message(&p)),
        };
        self.views.frame_all();
        if let Err(e) = r {
            self.state.report(e);
        }
    }

    /// Open a file from a dialog, Recent or a drop, through [`Self::guard`]; the status line
    /// says what was opened.
    fn open_message(&mut self, p: &Path) {
        self.state.message = format!("opened {}", p.display());
    }

    /// File > Save session: to the session's file when it has one, else ask where. `then` runs
    /// once the work is saved.
    pub fn save_or_ask(&mut self, then: Option<Guarded>) {
        match self.state.session_path().cloned() {
            Some(p) => match self.state.save_session_to(&p) {
                Ok(()) => {
                    self.state.message = format!("saved {}", p.display());
                    if let Some(a) = then {
                        self.perform(a);
                    }
                }
                Err(e) => self.state.report(e),
            },
            None => {
                self.safety.after_save = then;
                self.files.request(FileAction::SaveSession);
            }
        }
    }

    /// The Save dialog saved the session (or failed): carry out what was waiting for it.
    pub(super) fn session_saved(&mut self, ok: bool) {
        let then = self.safety.after_save.take();
        if ok && let Some(a) = then {
            self.perform(a);
        }
    }

    /// Once per frame: the window's close request, the prompts, the autosave.
    pub(super) fn safety_frame(&mut self, ctx: &egui::Context) {
        if ctx.input(|i| i.viewport().close_requested()) && !self.safety.close_allowed {
            if self.state.is_dirty() {
                ctx.send_viewport_cmd(egui::ViewportCommand::CancelClose);
                self.safety.confirm = Some(Guarded::Close);
            } else {
                self.safety.close_allowed = true;
            }
        }
        if std::mem::take(&mut self.safety.close_now) {
            ctx.send_viewport_cmd(egui::ViewportCommand::Close);
        }
        self.recovery_prompt(ctx);
        self.save_prompt(ctx);
        let now = Instant::now();
        if let Some(a) = self.safety.autosave.as_mut() {
            a.tick(&self.state, now);
            if let Some(e) = a.error.take() {
                self.state.message = e;
            }
            if let Some(d) = a.due_in(&self.state, now) {
                ctx.request_repaint_after(d.max(Duration::from_millis(20)));
            }
        }
    }

    /// A Save dialog that closed without saving drops what waited for it.
    pub(super) fn safety_after_files(&mut self) {
        if self.safety.after_save.is_some() && !self.files.browsing() {
            self.safety.after_save = None;
        }
    }

    fn save_prompt(&mut self, ctx: &egui::Context) {
        let Some(action) = self.safety.confirm.clone() else {
            return;
        };
        let mut answer = None;
        let summary = self.state.work_summary();
        let modal = egui::Modal::new(egui::Id::unique("unsaved-work")).show(ctx, |ui| {
            ui.set_max_width(420.0);
            ui.heading("Unsaved work");
            ui.label(action.question());
            if !summary.is_empty() {
                ui.label(format!("Not saved yet: {}.", summary.join(", ")));
            }
            ui.add_space(8.0);
            ui.horizontal(|ui| {
                if ui
                    .button("Save")
                    .on_hover_text("Save the session (Enter), then go on")
                    .clicked()
                {
                    answer = Some(0);
                }
                if ui.button("Don't save").clicked() {
                    answer = Some(1);
                }
                if ui.button("Cancel").clicked() {
                    answer = Some(2);
                }
            });
        });
        // Enter saves (the default answer), Escape or a click outside cancels
        if answer.is_none() && ctx.input(|i| i.key_pressed(egui::Key::Enter)) {
            answer = Some(0);
        }
        if modal.should_close() && answer.is_none() {
            answer = Some(2);
        }
        let Some(a) = answer else { return };
        self.safety.confirm = None;
        match a {
            0 => self.save_or_ask(Some(action)),
            1 => self.perform(action),
            _ => {}
        }
    }

    fn recovery_prompt(&mut self, ctx: &egui::Context) {
        if self.safety.confirm.is_some() {
            return;
        }
        let Some(r) = self.safety.recoveries.first() else {
            return;
        };
        let what = describe(&r.session);
        let age = r.age();
        let mut answer = None;
        egui::Modal::new(egui::Id::unique("recover-work")).show(ctx, |ui| {
            ui.set_max_width(440.0);
            ui.heading("Recover unsaved work?");
            ui.label(format!(
                "MeshMatch did not close normally. Its last autosave ({age}) holds:"
            ));
            for line in &what {
                ui.label(format!("  - {line}"));
            }
            ui.add_space(8.0);
            ui.horizontal(|ui| {
                if ui
                    .button("Recover")
                    .on_hover_text("Open the autosaved session, unsaved until you save it (Enter)")
                    .clicked()
                {
                    answer = Some(true);
                }
                if ui
                    .button("Discard")
                    .on_hover_text("Delete the autosave")
                    .clicked()
                {
                    answer = Some(false);
                }
            });
        });
        // Enter recovers: the answer that deletes nothing
        if answer.is_none() && ctx.input(|i| i.key_pressed(egui::Key::Enter)) {
            answer = Some(true);
        }
        match answer {
            Some(true) => self.recover_first(),
            Some(false) => {
                let r = self.safety.recoveries.remove(0);
                r.discard();
            }
            None => {}
        }
    }

    /// Restore the first offered autosave: the session comes back as unsaved work, is autosaved
    /// again at once under this app, and the dead app's folder goes.
    pub fn recover_first(&mut self) {
        if self.safety.recoveries.is_empty() {
            return;
        }
        let r = self.safety.recoveries.remove(0);
        match r.restore(&mut self.state) {
            Ok(()) => {
                self.views.frame_all();
                let kept = match self.safety.autosave.as_mut() {
                    Some(a) => a.write(&self.state).map(|_| ()),
                    None => Ok(()),
                };
                match kept {
                    Ok(()) => {
                        self.state.message =
                            "recovered the autosaved session (not saved yet)".into();
                        r.discard();
                    }
                    Err(e) => self.state.report(format!(
                        "recovered, but the autosave could not be rewritten ({e}); the old one \
                         stays in {}",
                        r.dir.display()
                    )),
                }
            }
            Err(e) => {
                self.state.report(format!(
                    "the autosave could not be recovered: {e} (it stays in {})",
                    r.dir.display()
                ));
            }
        }
    }

    /// A clean exit: the autosave folder goes (called when the window closes).
    pub fn finish_autosave(&mut self) {
        if let Some(a) = self.safety.autosave.take() {
            a.finish();
        }
    }
}

/// What an autosaved session holds, in lines for the recovery prompt.
fn describe(session: &Path) -> Vec<String> {
    let Some(v) = crate::mesh::io::read_text_file(session, "the autosave")
        .ok()
        .and_then(|t| serde_json::from_str::<serde_json::Value>(&t).ok())
    else {
        return vec!["(unreadable)".into()];
    };
    let mut out = Vec::new();
    for side in ["source", "target"] {
        let name = v[side]
            .as_str()
            .map(|p| {
                let p = Path::new(p);
                if p.is_relative() {
                    "a computed mesh".to_string()
                } else {
                    p.file_name()
                        .map_or(p.display().to_string(), |n| n.to_string_lossy().into())
                }
            })
            .or_else(|| {
                v[format!("{side}_scene")]
                    .as_str()
                    .map(|s| format!("scene {s}"))
            });
        if let Some(n) = name {
            let paint = if v[format!("{side}_paint")].is_string() {
                ", painted"
            } else {
                ""
            };
            out.push(format!("{side}: {n}{paint}"));
        }
    }
    let pairs = v["correspondences"]["correspondences"]
        .as_array()
        .map_or(0, Vec::len);
    out.push(format!("{pairs} correspondence pairs"));
    out
}
