//! Feature-aligned texturing in the app (Xu et al. 2009): Tools > "Feature-aligned texture...", a
//! [`SystemTool`] that finds the target's salient curves, orients a field along them and
//! synthesises an image's texture along that field.

use std::any::Any;
use std::path::PathBuf;
use std::sync::Arc;

use eframe::egui;

use super::state::{AppParams, AppState, CurveOverlay};
use super::system_tool::{FilePrompt, SystemTool, ToolAction, Wake};
use super::tools::{ToolJob, ToolOutcome, image_chooser, load_exemplar};
use crate::correspondence::Side;
use crate::error::{Error, Result};
use crate::geometry::vertex_normals;
use crate::geometry::{Curve, CurveKind, CurveParams, salient_curves};
use crate::mesh::TriMesh;
use crate::synthesis::feature_aligned::{self, Params};
use crate::work::CancelToken;

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
    /// The target's salient curves found with "Find curves", each kept or dropped by the user.
    pub found: Option<FoundCurves>,
    /// Draw the found curves over the target view.
    pub show_curves: bool,
    /// Why the last "Find curves" found nothing.
    pub find_error: Option<String>,
    /// Draw the oriented field of the kept curves over the target view (computed on its own
    /// thread, again after every keep or drop).
    pub show_field: bool,
    /// The field last computed, for the kept flags it was computed with.
    pub field: Option<FieldPreview>,
    /// The field being computed.
    field_job: Option<FieldJob>,
    /// Why the last field failed.
    pub field_error: Option<String>,
}

/// The oriented field of one choice of kept curves, as arrows for the overlay.
#[derive(Clone, Debug)]
pub struct FieldPreview {
    /// The kept flags it was computed for.
    pub kept: Vec<bool>,
    /// Arrows (start, end) along the field, about 40 across the target.
    pub arrows: Arc<Vec<[[f32; 3]; 2]>>,
}

/// A field being computed on its own thread.
#[derive(Clone, Debug)]
struct FieldJob {
    kept: Vec<bool>,
    rx: crossbeam_channel::Receiver<Result<FieldPreview>>,
    cancel: CancelToken,
}

/// Arrows along a unit tangent field for drawing: one at the first vertex met in each cell of a
/// grid `cells` across the bounding box's longest side, `0.7` cells long, centred on the vertex
/// and lifted off the surface by a hundredth of a cell along its normal.
pub fn field_arrows(mesh: &TriMesh, field: &[[f32; 3]], cells: usize) -> Vec<[[f32; 3]; 2]> {
    let Some((lo, hi)) = mesh.bounds() else {
        return Vec::new();
    };
    let (lo, hi) = (glam::Vec3::from(lo), glam::Vec3::from(hi));
    let cell = ((hi - lo).max_element() / cells.max(1) as f32).max(1e-12);
    let normals = vertex_normals(&mesh.positions, &mesh.faces);
    let mut seen = std::collections::HashSet::new();
    let mut out = Vec::new();
    for (i, (&p, &u)) in mesh.positions.iter().zip(field).enumerate() {
        let p = glam::Vec3::from(p);
        let key = ((p - lo) / cell).floor().as_ivec3();
        if !seen.insert(key) {
            continue;
        }
        let u = glam::Vec3::from(u);
        if u.length_squared() < 0.5 {
            continue;
        }
        let lift = glam::Vec3::from(normals[i]) * (0.01 * cell);
        let half = u * (0.35 * cell);
        out.push([(p + lift - half).to_array(), (p + lift + half).to_array()]);
    }
    out
}

/// Salient curves found on the target, with the user's choice of which to use.
#[derive(Clone, Debug)]
pub struct FoundCurves {
    /// The curves, longest first.
    pub curves: Vec<Curve>,
    /// Per curve, whether the synthesis uses it.
    pub kept: Vec<bool>,
    /// The target's vertex count when they were found (a different mesh makes them stale).
    pub vertices: usize,
    /// The curves' polylines as the overlay draws them.
    lines: Arc<Vec<(Vec<[f32; 3]>, bool)>>,
}

impl FoundCurves {
    fn new(mut curves: Vec<Curve>, vertices: usize) -> FoundCurves {
        curves.sort_by(|a, b| b.length().total_cmp(&a.length()));
        let kept = vec![true; curves.len()];
        let lines = Arc::new(
            curves
                .iter()
                .map(|c| (c.points.clone(), c.closed))
                .collect(),
        );
        FoundCurves {
            curves,
            kept,
            vertices,
            lines,
        }
    }

    /// The kept curves.
    pub fn kept_curves(&self) -> Vec<Curve> {
        self.curves
            .iter()
            .zip(&self.kept)
            .filter(|(_, k)| **k)
            .map(|(c, _)| c.clone())
            .collect()
    }
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
            found: None,
            show_curves: true,
            find_error: None,
            show_field: false,
            field: None,
            field_job: None,
            field_error: None,
        }
    }
}

impl FeatureAlignedDialog {
    /// Find the target's salient curves (on the UI thread: a fraction of a second at 100K
    /// vertices), all kept.
    pub fn find_curves<P: AppParams>(&mut self, state: &AppState<P>) {
        self.find_error = None;
        let Some(mesh) = state.painted_mesh(Side::Target) else {
            self.find_error = Some("open a target mesh first".into());
            return;
        };
        match salient_curves(&mesh.positions, &mesh.faces, &CurveParams::default()) {
            Ok(c) if c.is_empty() => {
                self.found = None;
                self.find_error = Some("no salient curve on the target".into());
            }
            Ok(c) => {
                self.found = Some(FoundCurves::new(c, mesh.num_vertices()));
                self.show_curves = true;
            }
            Err(e) => {
                self.found = None;
                self.find_error = Some(e.to_string());
            }
        }
    }
}

impl FeatureAlignedDialog {
    /// Collect a finished field, and start one when the kept curves changed since the last.
    fn update_field<P: AppParams>(&mut self, ctx: &egui::Context, state: &AppState<P>) {
        if let Some(j) = &self.field_job
            && let Ok(res) = j.rx.try_recv()
        {
            match res {
                Ok(f) => {
                    self.field = Some(f);
                    self.field_error = None;
                }
                Err(e) => {
                    self.field = None;
                    self.field_error = Some(e.to_string());
                }
            }
            self.field_job = None;
        }
        let Some(found) = self.found.as_ref().filter(|_| self.show_field) else {
            if let Some(j) = self.field_job.take() {
                j.cancel.cancel();
            }
            return;
        };
        let current = self.field.as_ref().is_some_and(|f| f.kept == found.kept);
        let running = self
            .field_job
            .as_ref()
            .is_some_and(|j| j.kept == found.kept);
        if current || running {
            return;
        }
        if let Some(j) = self.field_job.take() {
            j.cancel.cancel();
        }
        let kept = found.kept_curves();
        if kept.is_empty() {
            self.field = None;
            self.field_error = Some("every curve is dropped: no field".into());
            return;
        }
        let Some(mesh) = state.painted_mesh(Side::Target) else {
            return;
        };
        let (tx, rx) = crossbeam_channel::bounded(1);
        let cancel = CancelToken::new();
        let job = FieldJob {
            kept: found.kept.clone(),
            rx,
            cancel: cancel.clone(),
        };
        let flags = found.kept.clone();
        let ctx = ctx.clone();
        std::thread::spawn(move || {
            // the window gets the CPU first
            crate::work::lower_thread_priority();
            let res =
                feature_aligned::curves_and_field(&mesh, Some(&kept), &Params::default(), &cancel)
                    .map(|(_, field, _)| FieldPreview {
                        kept: flags,
                        arrows: Arc::new(field_arrows(&mesh, &field.field, 40)),
                    });
            if !cancel.is_cancelled() {
                let _ = tx.send(res);
                ctx.request_repaint();
            }
        });
        self.field_job = Some(job);
        self.field_error = None;
    }

    /// Whether a field is being computed.
    pub fn field_running(&self) -> bool {
        self.field_job.is_some()
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
        // Curves found on another target are stale.
        let target_vertices = state
            .slot(Side::Target)
            .map(|s| s.displayed().num_vertices());
        if self
            .found
            .as_ref()
            .is_some_and(|f| Some(f.vertices) != target_vertices)
        {
            self.found = None;
        }
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
        ui.separator();
        ui.horizontal(|ui| {
            if ui
                .add_enabled(
                    state.slot(Side::Target).is_some(),
                    egui::Button::new("Find curves"),
                )
                .on_hover_text(
                    "Find the target's crests, creases and rims now, to see them and choose which \
                     ones the texture follows (without this, Run finds and uses them all)",
                )
                .clicked()
            {
                self.find_curves(state);
            }
            if self.found.is_some() {
                ui.checkbox(&mut self.show_curves, "Show on the target");
                ui.checkbox(&mut self.show_field, "Show the field")
                    .on_hover_text(
                        "Arrows along the field the texture will follow, oriented by the kept \
                         curves (recomputed after every keep or drop)",
                    );
            }
        });
        self.update_field(ui.ctx(), state);
        if self.show_field && self.found.is_some() {
            if self.field_job.is_some() {
                ui.horizontal(|ui| {
                    ui.spinner();
                    ui.label("orienting the curves and diffusing the field...");
                });
            } else if let Some(e) = &self.field_error {
                ui.colored_label(egui::Color32::from_rgb(230, 120, 90), e);
            }
        }
        if let Some(e) = &self.find_error {
            ui.colored_label(egui::Color32::from_rgb(230, 120, 90), e);
        }
        if let Some(f) = &mut self.found {
            let kept = f.kept.iter().filter(|k| **k).count();
            ui.label(format!(
                "{} salient curves, {kept} kept (orange; dropped ones grey). Click a curve in \
                 the view, or tick it here, to keep or drop it",
                f.curves.len()
            ));
            egui::ScrollArea::vertical()
                .max_height(140.0)
                .show(ui, |ui| {
                    for (i, c) in f.curves.iter().enumerate() {
                        let kind = match c.kind {
                            CurveKind::Ridge => "ridge",
                            CurveKind::Ravine => "ravine",
                            CurveKind::Crease => "crease",
                        };
                        let text = format!(
                            "{:>2}. {kind}{}, length {:.3}",
                            i + 1,
                            if c.closed { " (closed)" } else { "" },
                            c.length()
                        );
                        ui.checkbox(&mut f.kept[i], text);
                    }
                });
        }
        ui.separator();
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
    fn overlay(&self) -> Option<Arc<CurveOverlay>> {
        let f = self.found.as_ref()?;
        if !self.show_curves && !self.show_field {
            return None;
        }
        let arrows = match &self.field {
            Some(p) if self.show_field => p.arrows.clone(),
            _ => Arc::new(Vec::new()),
        };
        let (lines, kept) = if self.show_curves {
            (f.lines.clone(), f.kept.clone())
        } else {
            (Arc::new(Vec::new()), Vec::new())
        };
        Some(Arc::new(CurveOverlay {
            side: Some(Side::Target),
            lines,
            kept,
            arrows,
        }))
    }
    fn overlay_clicked(&mut self, line: usize) {
        if let Some(k) = self.found.as_mut().and_then(|f| f.kept.get_mut(line)) {
            *k = !*k;
        }
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
        // The user's choice of curves, when they were found on this target.
        let chosen: Option<Vec<Curve>> = match &self.found {
            Some(f) if f.vertices == n => {
                let kept = f.kept_curves();
                if kept.is_empty() {
                    return Err(Error::InvalidInput(
                        "every curve is dropped: keep at least one, or find the curves again"
                            .into(),
                    ));
                }
                Some(kept)
            }
            _ => None,
        };
        let mut job = ToolJob::spawn("feature-aligned texture", wake, move |sink, cancel| {
            let (img, alpha) = load_exemplar(&path, pixels)?;
            let input = feature_aligned::Input {
                target: &mesh,
                exemplar: &img,
                curves: chosen.as_deref(),
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
