//! The one trait every synthesis system implements to live in the app (see `systems.rs` for
//! the registry): a Tools menu entry, a settings window and a job.

use std::any::Any;
use std::path::PathBuf;

use eframe::egui;

use super::state::{AppParams, AppState};
use super::tools::ToolJob;
use crate::error::Result;

/// What the user asked of a system's window this frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ToolAction {
    /// Nothing.
    None,
    /// Run with the current settings (the window closes).
    Run,
    /// Close the window.
    Close,
    /// Ask for the system's input file (the app's file dialog; see [`SystemTool::file_prompt`]).
    ChooseFile,
    /// Ask where to write the system's output (a save dialog; see [`SystemTool::save_prompt`]),
    /// then start the job, which writes it.
    ChooseSaveFile,
}

/// The file a system asks for: dialog title, filter name, extensions.
pub type FilePrompt = (&'static str, &'static str, &'static [&'static str]);

/// A wake-up call for the UI thread (a repaint), given to running jobs.
pub type Wake = Box<dyn Fn() + Send + Sync>;

/// One synthesis system in the app: a Tools menu entry, a settings window and a job.
pub trait SystemTool<P: AppParams>: Any {
    /// The Tools menu entry and window title.
    fn label(&self) -> &'static str;
    /// The menu entry's tooltip.
    fn hover(&self) -> &'static str;
    /// Whether its window is shown.
    fn is_open(&self) -> bool;
    /// Show or hide its window.
    fn set_open(&mut self, open: bool);
    /// The file [`ToolAction::ChooseFile`] asks for.
    fn file_prompt(&self) -> FilePrompt;
    /// The chosen file arrived.
    fn set_file(&mut self, path: PathBuf);
    /// The file [`ToolAction::ChooseSaveFile`] asks for (a save dialog).
    fn save_prompt(&self) -> FilePrompt {
        ("", "", &[])
    }
    /// The file to write was chosen; the job starts next.
    fn set_save_file(&mut self, _path: PathBuf) {}
    /// Draw the settings; `busy`: another tool is running.
    fn ui(&mut self, ui: &mut egui::Ui, state: &AppState<P>, busy: bool) -> ToolAction;
    /// Start the job on its own thread with the current settings.
    fn start(&mut self, state: &AppState<P>, wake: Wake) -> Result<ToolJob>;
    /// Polylines to draw over a view while the window is open.
    fn overlay(&self) -> Option<std::sync::Arc<super::state::CurveOverlay>> {
        None
    }
    /// The user clicked polyline `line` of [`SystemTool::overlay`] in its view.
    fn overlay_clicked(&mut self, _line: usize) {}
    /// For callers that know the concrete tool (tests, scripts).
    fn as_any_mut(&mut self) -> &mut dyn Any;
}
