//! The floating windows: help, the systems' tools and errors.

use eframe::egui::{self, Color32};

use super::{AppParams, MeshMatchApp, files, systems};
use crate::jobs::worker::Engine;

impl<E: Engine> MeshMatchApp<E>
where
    E::Params: AppParams,
{
    pub(super) fn help_window(&mut self, ctx: &egui::Context) {
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

    pub(super) fn system_windows(&mut self, ctx: &egui::Context) {
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

    pub(super) fn errors_window(&mut self, ctx: &egui::Context) {
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
}
