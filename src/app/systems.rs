//! The synthesis systems as app tools. Each is one [`SystemTool`] in [`registry`]: the Tools
//! menu lists them, their windows are drawn, their file requests answered and their jobs run
//! through this one trait, so a new system is one entry here (and its dialog, next to it).

use std::any::Any;
use std::path::PathBuf;

use eframe::egui;

use super::state::{AppParams, AppState};
use super::tools::{ExemplarAction, ExemplarDialog, ToolJob, exemplar_job};
use crate::error::{Error, Result};

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

/// The systems of this build, in Tools menu order.
pub fn registry<P: AppParams>() -> Vec<Box<dyn SystemTool<P>>> {
    vec![
        Box::new(ExemplarDialog::default()),
        Box::new(super::weather::WeatherDialog::default()),
        Box::new(super::weather::FeatureDialog::default()),
        Box::new(super::quilt::QuiltDialog::default()),
        Box::new(super::feature_aligned::FeatureAlignedDialog::default()),
    ]
}

/// Wei & Levoy 2001: "Paint with exemplar".
impl<P: AppParams> SystemTool<P> for ExemplarDialog {
    fn label(&self) -> &'static str {
        "Paint with exemplar..."
    }
    fn hover(&self) -> &'static str {
        "Synthesize an image's texture over the whole mesh or its painted region (Wei & Levoy \
         2001); the view updates after every pass"
    }
    fn is_open(&self) -> bool {
        self.open
    }
    fn set_open(&mut self, open: bool) {
        self.open = open;
    }
    fn file_prompt(&self) -> FilePrompt {
        (
            "Choose an exemplar image",
            "images",
            &["png", "jpg", "jpeg"],
        )
    }
    fn set_file(&mut self, path: PathBuf) {
        self.settings.image = Some(path);
    }
    fn ui(&mut self, ui: &mut egui::Ui, state: &AppState<P>, busy: bool) -> ToolAction {
        match ExemplarDialog::ui(self, ui, state, busy) {
            ExemplarAction::None => ToolAction::None,
            ExemplarAction::Run => ToolAction::Run,
            ExemplarAction::Close => ToolAction::Close,
            ExemplarAction::ChooseImage => ToolAction::ChooseFile,
        }
    }
    fn start(&mut self, state: &AppState<P>, wake: Wake) -> Result<ToolJob> {
        let side = self.settings.side;
        let (Some(mut mesh), Some(coverage)) =
            (state.painted_mesh(side), state.paint_coverage(side))
        else {
            return Err(Error::InvalidInput(format!(
                "open a {side:?} mesh to paint first"
            )));
        };
        if self.settings.region == super::tools::Region::Texture {
            // into its texture: the mesh as displayed, with its own UVs
            if let Some(slot) = state.slot(side) {
                mesh.uvs = slot.displayed().uvs.clone();
            }
        }
        exemplar_job(&self.settings, mesh, &coverage, wake)
    }
    fn as_any_mut(&mut self) -> &mut dyn Any {
        self
    }
}
