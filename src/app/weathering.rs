//! Geometry-correlated transfer in the app (Mertens et al. 2006): Tools > "Weather target from
//! source..." and Tools > "Show geometric feature..." (ambient occlusion, curvature, height as
//! a grey paint layer), each a [`SystemTool`].

use std::any::Any;
use std::path::PathBuf;
use std::sync::{Arc, Mutex};

use eframe::egui;

use super::state::{AppParams, AppState};
use super::system_tool::{FilePrompt, SystemTool, ToolAction, Wake};
use super::tools::{ToolJob, ToolOutcome};
use crate::correspondence::Side;
use crate::error::{Error, Result};
use crate::synthesis::weathering::{self, CcaReport, Method, Params, Up, feature_maps};
use crate::work::Event;

/// Working vertices of an app run (responsive; the CLI's default is the paper's density).
pub const APP_VERTICES: usize = 32_000;

/// Settings of "Weather target from source".
#[derive(Clone, Debug)]
pub struct WeatherSettings {
    /// Vertical axis of both objects.
    pub up: Up,
    /// Synthesis method.
    pub method: Method,
    /// Working vertices per mesh.
    pub vertices: usize,
    /// Occlusion rays per vertex.
    pub rays: usize,
    /// Guidance clusters.
    pub clusters: usize,
    /// Random seed.
    pub seed: u64,
    /// Canonical components the guidance keeps (the rules found; all on: the paper).
    pub components: [bool; 3],
}

impl WeatherSettings {
    /// [`Params::components`] for these settings: `None` when every component is on.
    pub fn component_list(&self) -> Option<Vec<usize>> {
        if self.components.iter().all(|&c| c) {
            return None;
        }
        Some((0..3).filter(|&k| self.components[k]).collect())
    }
}

impl Default for WeatherSettings {
    fn default() -> Self {
        let p = Params::default();
        WeatherSettings {
            up: p.up,
            method: p.method,
            vertices: APP_VERTICES,
            rays: p.rays,
            clusters: p.clusters,
            seed: 0,
            components: [true; 3],
        }
    }
}

/// The "Weather target from source" window.
#[derive(Clone, Debug, Default)]
pub struct WeatherDialog {
    /// Shown this frame.
    pub open: bool,
    /// The next run's settings.
    pub settings: WeatherSettings,
    /// The last run's CCA: which features matter.
    pub report: Arc<Mutex<Option<CcaReport>>>,
}

fn up_ui(ui: &mut egui::Ui, up: &mut Up) {
    ui.horizontal(|ui| {
        ui.label("Up axis:")
            .on_hover_text("The objects' vertical axis, for the height feature");
        ui.selectable_value(up, Up::Y, "Y");
        ui.selectable_value(up, Up::Z, "Z");
    });
}

impl<P: AppParams> SystemTool<P> for WeatherDialog {
    fn label(&self) -> &'static str {
        "Weather target from source..."
    }
    fn hover(&self) -> &'static str {
        "Geometry-correlated transfer (Mertens et al. 2006): learn how the source's colour follows \
         its geometry (crevices, exposed tops, edges) and apply it to the target by its geometry; \
         no correspondences needed"
    }
    fn is_open(&self) -> bool {
        self.open
    }
    fn set_open(&mut self, open: bool) {
        self.open = open;
    }
    fn file_prompt(&self) -> FilePrompt {
        ("", "", &[])
    }
    fn set_file(&mut self, _path: PathBuf) {}
    fn ui(&mut self, ui: &mut egui::Ui, state: &AppState<P>, busy: bool) -> ToolAction {
        let s = &mut self.settings;
        let mut action = ToolAction::None;
        ui.label("Source: the textured model (its colours are the example)");
        ui.label("Target: the shape to weather");
        up_ui(ui, &mut s.up);
        ui.horizontal(|ui| {
            ui.label("Method:");
            ui.selectable_value(&mut s.method, Method::Parametric, "parametric")
                .on_hover_text("Per-cluster histogram matching of colour and its detail bands");
            ui.selectable_value(&mut s.method, Method::NonParametric, "non-parametric")
                .on_hover_text(
                    "Copies source colours chosen by guidance, neighbourhood and coherence: \
                     keeps the grain and small structures",
                );
        });
        ui.add(egui::Slider::new(&mut s.vertices, 4_000..=200_000).text("working vertices"))
            .on_hover_text("Both meshes are refined to about this many vertices");
        ui.add(egui::Slider::new(&mut s.rays, 16..=256).text("occlusion rays"));
        ui.add(egui::Slider::new(&mut s.clusters, 2..=100).text("clusters"))
            .on_hover_text("Segments of the guidance field (the paper's only parameter)");
        ui.add(egui::DragValue::new(&mut s.seed).prefix("seed "));
        if let Some(r) = self.report.lock().ok().and_then(|r| r.clone()) {
            ui.separator();
            ui.label("Rules found (canonical components of the last run):")
                .on_hover_text(
                    "Each component is one way the source's colour follows its geometry; its \
                     correlation says how strongly, its features what it follows. Switch one \
                     off and Run again to drop the rule it carries.",
                );
            for k in 0..r.correlations.len().min(3) {
                let top = r
                    .top_features(k, 3)
                    .iter()
                    .map(|(n, w)| format!("{n} {w:+.2}"))
                    .collect::<Vec<_>>()
                    .join(", ");
                ui.checkbox(
                    &mut s.components[k],
                    format!(
                        "component {k}: correlation {:.2}, weighs {top}",
                        r.correlations[k]
                    ),
                );
            }
            if !r.mean_weights.is_empty() {
                let mut w: Vec<(&String, f32)> = r
                    .feature_names
                    .iter()
                    .zip(r.mean_weights.iter().copied())
                    .collect();
                w.sort_by(|a, b| b.1.total_cmp(&a.1));
                let top = w
                    .iter()
                    .take(4)
                    .map(|(n, x)| format!("{n} {x:.2}"))
                    .collect::<Vec<_>>()
                    .join(", ");
                ui.label(format!("The regressed colour follows: {top}"))
                    .on_hover_text(
                        "The features the regression on geometry compares, weighed by how far \
                         the colour follows them (1 = the most; half of every weight is the same \
                         for all, so none is below 0.5)",
                    );
            }
            egui::CollapsingHeader::new("All CCA weights")
                .id_salt("weather_cca_weights")
                .show(ui, |ui| {
                    ui.monospace(r.to_text());
                });
        }
        let some_on = s.components.iter().any(|&c| c);
        let ready =
            state.slot(Side::Source).is_some() && state.slot(Side::Target).is_some() && some_on;
        ui.horizontal(|ui| {
            if ui
                .add_enabled(ready && !busy, egui::Button::new("Run"))
                .on_hover_text("Runs on its own thread; one undo step")
                .clicked()
            {
                action = ToolAction::Run;
            }
            if ui.button("Close").clicked() {
                action = ToolAction::Close;
            }
        });
        if !some_on {
            ui.label("switch at least one component on");
        } else if !ready {
            ui.label("open a textured source and a target first");
        }
        action
    }
    fn start(&mut self, state: &AppState<P>, wake: Wake) -> Result<ToolJob> {
        let (Some(source), Some(target)) = (
            state.painted_mesh(Side::Source),
            state.painted_mesh(Side::Target),
        ) else {
            return Err(Error::InvalidInput(
                "open a textured source and a target first".into(),
            ));
        };
        let s = &self.settings;
        let params = Params {
            working_vertices: s.vertices,
            up: s.up,
            method: s.method,
            rays: s.rays,
            clusters: s.clusters,
            seed: s.seed,
            components: s.component_list(),
            ..Params::default()
        };
        let n = target.num_vertices();
        let report = self.report.clone();
        let mut job = ToolJob::spawn("weather", wake, move |sink, cancel| {
            let input = weathering::Input {
                source: &source,
                target: &target,
                source_mask: None,
            };
            let out = weathering::run(&input, &params, sink, cancel)?;
            let top = top_features(&out.report);
            if let Ok(mut r) = report.lock() {
                *r = Some(out.report.clone());
            }
            Ok(ToolOutcome::Colors(
                Side::Target,
                out.colors[..n].to_vec(),
                format!(
                    "target weathered from the source; features that matter most: {top} (Ctrl+Z undoes)"
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

/// The three features with the largest weight in the first canonical direction kept.
fn top_features(r: &CcaReport) -> String {
    let k = r.enabled.iter().position(|&e| e).unwrap_or(0);
    r.top_features(k, 3)
        .iter()
        .map(|(n, x)| format!("{n} {:.2}", x.abs()))
        .collect::<Vec<_>>()
        .join(", ")
}

/// The "Show geometric feature" window: one feature of one side as a grey paint layer.
#[derive(Clone, Debug)]
pub struct FeatureDialog {
    /// Shown this frame.
    pub open: bool,
    /// Which mesh.
    pub side: Side,
    /// Feature name (`ao`, `height`, `curvature-0` .. `curvature-3`, `normal-y`, ...).
    pub feature: String,
    /// Vertical axis.
    pub up: Up,
    /// Occlusion rays per vertex.
    pub rays: usize,
    /// Side of the baked maps ("Save maps...").
    pub texture_size: u32,
    /// Bits per channel of the saved maps (8 or 16).
    pub bits: u8,
    /// Where the next job writes every map (`<stem>_<map>.png`); `None`: the next job shows the
    /// feature.
    pub save_to: Option<PathBuf>,
}

impl Default for FeatureDialog {
    fn default() -> Self {
        FeatureDialog {
            open: false,
            side: Side::Target,
            feature: "ao".into(),
            up: Up::Y,
            rays: Params::default().rays,
            texture_size: 2048,
            bits: 8,
            save_to: None,
        }
    }
}

/// Bake every feature map of `mesh` (its UVs, or a generated atlas) and write them beside
/// `path` as `<stem>_<map>.png`: the "Save maps..." job.
pub fn save_maps_job(
    mesh: crate::mesh::TriMesh,
    params: feature_maps::MapParams,
    bits: u8,
    path: PathBuf,
    wake: Wake,
) -> ToolJob {
    ToolJob::spawn("feature maps", wake, move |sink, cancel| {
        let progress = |f: f32| {
            sink(Event::Progress(crate::work::Progress {
                stage: "feature maps",
                fraction: f,
                ..Default::default()
            }))
        };
        let maps = feature_maps::bake_feature_maps(
            &mesh,
            &feature_maps::MAP_NAMES,
            &params,
            &progress,
            cancel,
        )?;
        let written = feature_maps::save_map_pngs(&maps, &path, bits)?;
        let atlas = if maps.atlas.is_some() {
            " (through a generated atlas: the mesh has no UVs)"
        } else {
            ""
        };
        Ok(ToolOutcome::Done(format!(
            "wrote {} maps{atlas}: {}",
            written.len(),
            written
                .iter()
                .filter_map(|p| p.file_name().map(|n| n.to_string_lossy().into_owned()))
                .collect::<Vec<_>>()
                .join(", ")
        )))
    })
}

/// The features offered, with what they show.
const FEATURES: &[(&str, &str)] = &[
    ("ao", "ambient occlusion: dark in crevices"),
    ("height", "normalised height along the up axis"),
    (
        "curvature-0",
        "curvature, smallest radius (1% of the diagonal)",
    ),
    ("curvature-1", "curvature, 3% of the diagonal"),
    ("curvature-2", "curvature, 10% of the diagonal"),
    (
        "curvature-3",
        "curvature, largest radius (30% of the diagonal)",
    ),
    ("occlusion-y", "directional occlusion towards +Y"),
    ("normal-y", "normal's up component"),
];

impl<P: AppParams> SystemTool<P> for FeatureDialog {
    fn label(&self) -> &'static str {
        "Show geometric feature..."
    }
    fn hover(&self) -> &'static str {
        "Ambient occlusion, curvature at four scales or height as a grey paint layer: the \
         features the geometry-correlated transfer learns from"
    }
    fn is_open(&self) -> bool {
        self.open
    }
    fn set_open(&mut self, open: bool) {
        self.open = open;
    }
    fn file_prompt(&self) -> FilePrompt {
        ("", "", &[])
    }
    fn set_file(&mut self, _path: PathBuf) {}
    fn ui(&mut self, ui: &mut egui::Ui, state: &AppState<P>, busy: bool) -> ToolAction {
        let mut action = ToolAction::None;
        ui.horizontal(|ui| {
            ui.label("Mesh:");
            ui.selectable_value(&mut self.side, Side::Source, "source");
            ui.selectable_value(&mut self.side, Side::Target, "target");
        });
        for (name, what) in FEATURES {
            ui.radio_value(&mut self.feature, name.to_string(), *name)
                .on_hover_text(*what);
        }
        up_ui(ui, &mut self.up);
        ui.add(egui::Slider::new(&mut self.rays, 16..=256).text("occlusion rays"));
        let ready = state.slot(self.side).is_some();
        ui.horizontal(|ui| {
            if ui
                .add_enabled(ready && !busy, egui::Button::new("Show"))
                .on_hover_text("Computes it on its own thread; one undo step")
                .clicked()
            {
                action = ToolAction::Run;
            }
            if ui.button("Close").clicked() {
                action = ToolAction::Close;
            }
        });
        ui.separator();
        ui.label(
            "Bake every map (ao, curvature, cavity, thickness, normal, height) into textures:",
        );
        ui.horizontal(|ui| {
            egui::ComboBox::from_id_salt("feature_map_size")
                .selected_text(format!("{} px", self.texture_size))
                .show_ui(ui, |ui| {
                    for s in [512u32, 1024, 2048, 4096] {
                        ui.selectable_value(&mut self.texture_size, s, format!("{s} px"));
                    }
                });
            ui.selectable_value(&mut self.bits, 8, "8-bit");
            ui.selectable_value(&mut self.bits, 16, "16-bit");
        });
        if ui
            .add_enabled(ready && !busy, egui::Button::new("Save maps..."))
            .on_hover_text(
                "One PNG per map beside the file you name (<name>_ao.png, ...), in the mesh's \
                 UVs or a generated atlas, gutters filled; runs on its own thread",
            )
            .clicked()
        {
            action = ToolAction::ChooseSaveFile;
        }
        action
    }
    fn save_prompt(&self) -> FilePrompt {
        ("Save feature maps", "PNG image", &["png"])
    }
    fn set_save_file(&mut self, path: PathBuf) {
        self.save_to = Some(path);
    }
    fn start(&mut self, state: &AppState<P>, wake: Wake) -> Result<ToolJob> {
        let side = self.side;
        let Some(mut mesh) = state.painted_mesh(side) else {
            return Err(Error::InvalidInput(format!("open a {side:?} mesh first")));
        };
        if let Some(path) = self.save_to.take() {
            // through the mesh's own UVs, as displayed
            mesh.uvs = state.slot(side).and_then(|s| s.displayed().uvs.clone());
            mesh.colors = None;
            let params = feature_maps::MapParams {
                texture_size: self.texture_size,
                rays: self.rays,
                up: self.up,
                ..Default::default()
            };
            return Ok(save_maps_job(mesh, params, self.bits, path, wake));
        }
        let params = Params {
            up: self.up,
            rays: self.rays,
            ..Params::default()
        };
        let feature = self.feature.clone();
        Ok(ToolJob::spawn("feature", wake, move |_sink, cancel| {
            let fs = weathering::features(&mesh.positions, &mesh.faces, &params, cancel)?;
            let f = weathering::feature_field(&fs, &feature)?;
            let (lo, hi) = f
                .iter()
                .fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), &x| {
                    (a.min(x), b.max(x))
                });
            let (lo, hi) = if feature == "ao" || feature == "height" {
                (0.0, 1.0)
            } else {
                (lo, hi)
            };
            let span = (hi - lo).max(1e-12);
            let grey = f
                .iter()
                .map(|&x| {
                    let g = ((x - lo) / span).clamp(0.0, 1.0);
                    [g, g, g]
                })
                .collect();
            Ok(ToolOutcome::Colors(
                side,
                grey,
                format!(
                    "{side:?}: {feature} as grey, {lo:.3} (black) .. {hi:.3} (white); Ctrl+Z undoes"
                ),
            ))
        }))
    }
    fn as_any_mut(&mut self) -> &mut dyn Any {
        self
    }
}
