//! The menu bar and the keyboard shortcuts that mirror it.

use eframe::egui;

use super::{AppParams, MeshMatchApp, files, state, unsaved, weathering};
use crate::correspondence::Side;
use crate::error::Result;
use crate::jobs::worker::Engine;

impl<E: Engine> MeshMatchApp<E>
where
    E::Params: AppParams,
{
    pub(super) fn menu_bar(&mut self, ui: &mut egui::Ui) {
        egui::MenuBar::new().ui(ui, |ui| {
            ui.menu_button("File", |ui| self.file_menu(ui));
            ui.menu_button("Edit", |ui| self.edit_menu(ui));
            ui.menu_button("Tools", |ui| self.tools_menu(ui));
            ui.menu_button("Scene", |ui| self.scene_menu(ui));
            ui.menu_button("View", |ui| self.view_menu(ui));
            if ui
                .button("?")
                .on_hover_text("Mouse and keyboard help")
                .clicked()
            {
                self.show_help = !self.show_help;
            }
        });
    }

    /// The File menu: open, save and export, sessions, recent files.
    fn file_menu(&mut self, ui: &mut egui::Ui) {
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
            Some(
                "Format by extension, as `transfer --out` (a baked texture for .glb/.obj with UVs)",
            ),
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
                                guarded = Some(unsaved::Guarded::OpenMesh(Side::Source, p.clone()));
                                opened = true;
                            }
                            if ui.small_button("as target").clicked() {
                                guarded = Some(unsaved::Guarded::OpenMesh(Side::Target, p.clone()));
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
    }

    /// The Edit menu: undo, redo, delete.
    fn edit_menu(&mut self, ui: &mut egui::Ui) {
        if ui.button("Undo  (Ctrl+Z)").clicked() {
            self.state.undo();
        }
        if ui.button("Redo  (Ctrl+Shift+Z)").clicked() {
            self.state.redo();
        }
        if ui.button("Delete selected  (Del)").clicked() {
            self.state.delete_selected();
        }
    }

    /// The Tools menu: completion, update, detail transfer and every system's tool.
    fn tools_menu(&mut self, ui: &mut egui::Ui) {
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
    }

    /// The Scene menu: the demo scenes.
    fn scene_menu(&mut self, ui: &mut egui::Ui) {
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
    }

    /// The View menu: wireframe, locked cameras, features, framing, help.
    fn view_menu(&mut self, ui: &mut egui::Ui) {
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
            if let Some(d) = self.system_mut::<weathering::FeatureDialog>() {
                d.open = true;
            }
            ui.close();
        }
        if ui.button("Frame all  (F)").clicked() {
            self.views.frame_all();
        }
        ui.checkbox(&mut self.show_help, "Help  (H)");
    }

    pub(super) fn shortcuts(&mut self, ctx: &egui::Context) {
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
}
