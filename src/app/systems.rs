//! The synthesis systems as app tools. Each is one [`SystemTool`] (in `system_tool.rs`) in
//! [`registry`]: the Tools menu lists them, their windows are drawn, their file requests
//! answered and their jobs run through this one trait, so a new system is one entry here (and
//! its dialog, next to it).

use std::any::Any;
use std::path::PathBuf;

use eframe::egui;

use super::state::{AppParams, AppState};
pub use super::system_tool::{FilePrompt, SystemTool, ToolAction, Wake};
use super::tools::{ExemplarAction, ExemplarDialog, ToolJob, exemplar_job};
use crate::error::{Error, Result};

/// The systems of this build, in Tools menu order.
pub fn registry<P: AppParams>() -> Vec<Box<dyn SystemTool<P>>> {
    vec![
        Box::new(ExemplarDialog::default()),
        Box::new(super::weathering::WeatherDialog::default()),
        Box::new(super::weathering::FeatureDialog::default()),
        Box::new(super::quilting::QuiltDialog::default()),
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
            (state.painted_mesh(side), state.region_coverage(side))
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
