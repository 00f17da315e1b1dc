//! Feature-aligned texturing in the app (Xu et al. 2009): Tools > "Feature-aligned texture...", a
//! [`SystemTool`] that finds the target's salient curves, orients a field along them and
//! synthesises an image's texture along that field.

use std::any::Any;
use std::path::PathBuf;

use eframe::egui;

use super::state::{AppParams, AppState};
use super::systems::{FilePrompt, SystemTool, ToolAction, Wake};
use super::tools::{ToolJob, ToolOutcome, image_chooser, load_exemplar};
use crate::correspondence::Side;
use crate::error::{Error, Result};
use crate::synthesis::feature_aligned::{self, Params};

/// The "Feature-aligned texture" window.
#[derive(Clone, Debug)]
pub struct FeatureAlignedDialog {
    /// Shown this frame.
    pub open: bool,
    /// The exemplar image (its x axis follows the curves); `None` until chosen.
    pub image: Option<PathBuf>,
    /// Exemplar width on the surface as a fraction of the target's bounding-box diagonal.
    pub scale: f32,
    /// The exemplar is resized to this width in pixels (never enlarged).
    pub pixels: u32,
    /// Random seed.
    pub seed: u64,
    /// Follow the neighbourhood synthesis with the texture optimisation (whole patches).
    pub optimize: bool,
    /// Put the image's principal line exactly on the curves (implies the optimisation).
    pub align_features: bool,
}

impl Default for FeatureAlignedDialog {
    fn default() -> Self {
        FeatureAlignedDialog {
            open: false,
            image: None,
            scale: 0.2,
            pixels: 64,
            seed: 0,
            optimize: false,
            align_features: true,
        }
    }
}

impl<P: AppParams> SystemTool<P> for FeatureAlignedDialog {
    fn label(&self) -> &'static str {
        "Feature-aligned texture..."
    }
    fn hover(&self) -> &'static str {
        "Feature-aligned texturing (Xu et al. 2009): the target's crests, creases and rims orient \
         the texture, which then flows along them; the image's horizontal lines follow the curves"
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
        self.image = Some(path);
    }
    fn ui(&mut self, ui: &mut egui::Ui, state: &AppState<P>, busy: bool) -> ToolAction {
        let mut action = ToolAction::None;
        if image_chooser(
            ui,
            self.image.as_deref(),
            "Lines along the image's x axis will run along the curves",
        ) {
            action = ToolAction::ChooseFile;
        }
        ui.add(egui::Slider::new(&mut self.scale, 0.02..=1.0).text("scale"))
            .on_hover_text("The image's width on the surface, as a fraction of the diagonal");
        ui.add(egui::Slider::new(&mut self.pixels, 16..=256).text("exemplar pixels"))
            .on_hover_text("The image is shrunk to this width first: it sets the vertex count");
        ui.checkbox(
            &mut self.align_features,
            "Put the image's line on the curves",
        )
        .on_hover_text(
            "The image's strongest thin horizontal stroke (a groove, a seam) is laid exactly \
                 on every crest, crease and rim (texture optimisation with the feature-to-feature \
                 constraint); an image whose strokes are vertical is turned",
        );
        ui.add_enabled(
            !self.align_features,
            egui::Checkbox::new(
                &mut self.optimize,
                "Optimise whole patches (keeps structure, slower)",
            ),
        )
        .on_hover_text("Texture optimisation after the synthesis, without the line constraint");
        ui.add(egui::DragValue::new(&mut self.seed).prefix("seed "));
        let ready = self.image.is_some() && state.slot(Side::Target).is_some();
        ui.horizontal(|ui| {
            if ui
                .add_enabled(ready && !busy, egui::Button::new("Run"))
                .on_hover_text("Runs on its own thread; the view updates after every pass")
                .clicked()
            {
                action = ToolAction::Run;
            }
            if ui.button("Close").clicked() {
                action = ToolAction::Close;
            }
        });
        action
    }
    fn start(&mut self, state: &AppState<P>, wake: Wake) -> Result<ToolJob> {
        let path = self.image.clone().ok_or_else(|| {
            Error::InvalidInput("choose an exemplar image first (PNG or JPEG)".into())
        })?;
        let Some(mesh) = state.painted_mesh(Side::Target) else {
            return Err(Error::InvalidInput("open a target mesh first".into()));
        };
        let (lo, hi) = mesh
            .bounds()
            .ok_or_else(|| Error::InvalidMesh("the target is empty".into()))?;
        let diag = glam::Vec3::from(hi).distance(glam::Vec3::from(lo));
        let mut params = Params::default();
        params.synth.scale = Some(self.scale * diag);
        params.synth.seed = self.seed;
        params.align_features = self.align_features;
        params.optimization.seed = self.seed;
        if self.align_features || self.optimize {
            params.method = crate::synthesis::texture_optimization::Method::Optimize;
        }
        let pixels = self.pixels;
        let n = mesh.num_vertices();
        let mut job = ToolJob::spawn("feature-aligned texture", wake, move |sink, cancel| {
            let (img, alpha) = load_exemplar(&path, pixels)?;
            let input = feature_aligned::Input {
                target: &mesh,
                exemplar: &img,
                curves: None,
                alpha: alpha.as_ref(),
                feature_mask: None,
            };
            let out = feature_aligned::run(&input, &params, sink, cancel)?;
            let colors = out
                .synth
                .mesh
                .colors
                .as_ref()
                .map(|c| c[..n].to_vec())
                .ok_or_else(|| Error::InvalidInput("synthesis gave no colours".into()))?;
            Ok(ToolOutcome::Colors(
                Side::Target,
                colors,
                format!(
                    "target textured along {} salient curves ({} vertices synthesized; Ctrl+Z undoes)",
                    out.curves.len(),
                    out.synth.mesh.num_vertices()
                ),
            ))
        });
        job.preview = Some(Side::Target);
        Ok(job)
    }
    fn as_any_mut(&mut self) -> &mut dyn Any {
        self
    }
}
