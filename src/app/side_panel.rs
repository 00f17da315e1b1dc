//! The side panel: tools, brushes, layers, correspondences and the transfer's settings.

use eframe::egui::{self, Color32};
use std::time::Instant;

use super::{AppParams, MeshMatchApp, Selection, Tool, state, tools};
use crate::correspondence::Side;
use crate::jobs::worker::Engine;

impl<E: Engine> MeshMatchApp<E>
where
    E::Params: AppParams,
{
    pub(super) fn side_panel(&mut self, ui: &mut egui::Ui) {
        egui::ScrollArea::vertical().show(ui, |ui| {
            ui.heading("Tool");
            ui.horizontal(|ui| {
                ui.selectable_value(&mut self.views.tool, Tool::Correspond, "Correspondences")
                    .on_hover_text("Click source then target to add a pair");
                ui.selectable_value(&mut self.views.tool, Tool::Paint, "Paint")
                    .on_hover_text(
                        "Click or drag to paint what the view sees (at the texture's \
                         resolution on a mesh with UVs, else on its vertices); Alt+drag orbits",
                    );
            });
            if self.views.tool == Tool::Paint {
                self.brush_panel(ui);
            }
            ui.separator();
            self.correspondences_panel(ui);
            ui.separator();
            ui.heading("Parameters");
            self.signal.ui(ui);
            let mut p = self.state.params.clone();
            if p.ui(ui) {
                self.state.set_params(p, Instant::now());
            }
            ui.separator();
            ui.horizontal(|ui| {
                if self.signal.signal == tools::Signal::Detail {
                    if ui
                        .add_enabled(self.tool.is_none(), egui::Button::new("Transfer detail"))
                        .on_hover_text(
                            "Displace the target by the source's detail at the chosen strength \
                             (replaces the target)",
                        )
                        .clicked()
                    {
                        self.start_tool("detail");
                    }
                } else if ui.button("Restart transfer").clicked() {
                    self.state.schedule_restart(Instant::now());
                }
                if ui
                    .add_enabled(self.state.job.running, egui::Button::new("Cancel"))
                    .clicked()
                {
                    self.state.cancel_job();
                }
            });
        });
    }

    /// The brush: mode, size, hardness, colour, stroke settings, recent colours, then the
    /// layers and the UV atlas buttons.
    fn brush_panel(&mut self, ui: &mut egui::Ui) {
        let b = &mut self.state.brush;
        ui.horizontal(|ui| {
            use state::PaintMode;
            ui.selectable_value(&mut b.mode, PaintMode::Brush, "Brush")
                .on_hover_text("Click or drag to paint");
            ui.selectable_value(&mut b.mode, PaintMode::Eyedropper, "Eyedropper")
                .on_hover_text("Click to take the colour under the pointer (also Ctrl+click)");
            ui.selectable_value(&mut b.mode, PaintMode::Fill, "Fill")
                .on_hover_text(
                    "Click to fill the connected region of similar colour under the pointer \
                 (across UV seams); one undo step",
                );
            ui.selectable_value(&mut b.mode, PaintMode::IslandFill, "Island")
                .on_hover_text(
                    "Click to fill the whole UV island (chart) under the pointer; \
                     without UVs, the connected part of the mesh. One undo step",
                );
        });
        if b.mode == state::PaintMode::Fill {
            ui.add(egui::Slider::new(&mut b.fill_tolerance, 0.0..=1.0).text("tolerance"))
                .on_hover_text(
                    "A fill spreads while the shown colour differs from the clicked one by \
                     at most this in every channel",
                );
        }
        ui.add(egui::Slider::new(&mut b.radius, 0.005..=0.5).text("radius"))
            .on_hover_text("Brush radius as a fraction of the mesh size");
        ui.add(egui::Slider::new(&mut b.hardness, 0.0..=1.0).text("hardness"))
            .on_hover_text("1 = hard edge, 0 = soft falloff");
        ui.horizontal(|ui| {
            ui.color_edit_button_rgb(&mut b.color);
            ui.checkbox(&mut b.eraser, "eraser");
        });
        ui.horizontal(|ui| {
            ui.checkbox(&mut b.through, "paint through").on_hover_text(
                "Paint a ball around the point under the pointer, surfaces hidden from \
                 the view included (for masks). Off: only what the view sees under the \
                 brush.",
            );
            ui.add_enabled(
                !b.through,
                egui::Checkbox::new(&mut b.normal_falloff, "normal falloff"),
            )
            .on_hover_text("Fade the dab where the surface turns away from the view");
        });
        ui.add(egui::Slider::new(&mut b.spacing, 0.05..=2.0).text("spacing"))
            .on_hover_text("Distance between a stroke's dabs, in brush radii");
        ui.add(egui::Slider::new(&mut b.smoothing, 0.0..=0.95).text("smoothing"))
            .on_hover_text(
                "Stroke smoothing: the stroke lags behind the pointer and \
                            its path smooths out",
            );
        if !self.state.color_history.is_empty() {
            ui.horizontal_wrapped(|ui| {
                for c in self.state.color_history.clone() {
                    let [r, g, bl] = c.map(|x| (x * 255.0).round() as u8);
                    let swatch = egui::Button::new("")
                        .fill(Color32::from_rgb(r, g, bl))
                        .min_size(egui::vec2(18.0, 18.0));
                    if ui
                        .add(swatch)
                        .on_hover_text("A colour painted with: click to paint with it")
                        .clicked()
                    {
                        self.state.brush.color = c;
                        self.state.brush.eraser = false;
                    }
                }
            });
        }
        ui.label(
            egui::RichText::new("Ctrl+click picks a colour, Shift+click draws a straight line")
                .small()
                .weak(),
        );
        self.layers_panel(ui);
        self.atlas_buttons(ui);
    }

    /// The correspondences: Suggest, the pending source, the pairs (select, delete).
    fn correspondences_panel(&mut self, ui: &mut egui::Ui) {
        ui.horizontal(|ui| {
            ui.heading("Correspondences");
            let ready = self.tool.is_none()
                && self.state.slot(Side::Source).is_some()
                && self.state.slot(Side::Target).is_some();
            if ui
                .add_enabled(ready, egui::Button::new("Suggest"))
                .on_hover_text(format!(
                    "Add {} well-spread pairs from the global shape map (functional maps, \
                 the current pairs as landmarks); move or delete any. One undo step.",
                    tools::SUGGESTED_PAIRS
                ))
                .clicked()
            {
                self.start_tool("suggest");
            }
        });
        if let Some(v) = self.state.pending_source {
            ui.colored_label(Color32::YELLOW, format!("source {v} waiting for a target"));
        }
        let mut delete = None;
        let mut select = None;
        egui::Grid::new("pairs").striped(true).show(ui, |ui| {
            for (i, c) in self.state.corr.iter().enumerate() {
                let [r, g, b] = state::marker_color(i);
                let sel = self.state.selected.is_some_and(|s| s.pair == i);
                let label = egui::RichText::new(format!("{:>2}", i + 1))
                    .color(Color32::from_rgb(r, g, b))
                    .strong();
                if ui.selectable_label(sel, label).clicked() {
                    select = Some(i);
                }
                let targets: Vec<String> =
                    c.target_vertices.iter().map(|t| t.to_string()).collect();
                ui.label(format!("{} -> {}", c.source_vertex, targets.join(", ")));
                if ui
                    .small_button("x")
                    .on_hover_text("Delete this pair")
                    .clicked()
                {
                    delete = Some(i);
                }
                ui.end_row();
            }
        });
        if let Some(i) = select {
            self.state.select(Some(Selection {
                pair: i,
                side: Side::Source,
                k: 0,
            }));
        }
        if let Some(i) = delete {
            self.state.delete_pair(i);
        }
    }

    /// Visibility and opacity of the result, the paint and the mask, and the layer painted into.
    pub(super) fn layers_panel(&mut self, ui: &mut egui::Ui) {
        use state::PaintTarget;
        ui.label(egui::RichText::new("Layers").strong());
        let mut layers = self.state.layers;
        let target = &mut self.state.brush.target;
        egui::Grid::new("paint layers").num_columns(3).show(ui, |ui| {
            let rows = [
                (
                    "Result",
                    &mut layers.result,
                    None,
                    "The mesh's texture or colours, a transfer's result, an application's outcome",
                ),
                (
                    "Paint",
                    &mut layers.paint,
                    Some(PaintTarget::Paint),
                    "The brush's paint (completion takes it as the example)",
                ),
                (
                    "Mask",
                    &mut layers.mask,
                    Some(PaintTarget::Mask),
                    "A mask: painting with exemplar acts where it is painted",
                ),
            ];
            ui.label(egui::RichText::new("shown").small().weak());
            ui.label(egui::RichText::new("opacity").small().weak());
            ui.label(egui::RichText::new("paint into").small().weak());
            ui.end_row();
            for (name, l, t, tip) in rows {
                ui.checkbox(&mut l.visible, name)
                    .on_hover_text(format!("{tip}. Shown and exported when ticked"));
                ui.add(egui::Slider::new(&mut l.opacity, 0.0..=1.0))
                    .on_hover_text("How strongly the views and the export show the layer");
                match t {
                    Some(t) => {
                        ui.radio_value(target, t, "")
                            .on_hover_text("Strokes and fills go into this layer");
                    }
                    None => {
                        ui.label("");
                    }
                }
                ui.end_row();
            }
        });
        if layers != self.state.layers {
            self.state.set_layers(layers);
            self.views.invalidate();
        }
    }

    /// For a side whose displayed mesh has no UVs (it paints its vertices): a button that lays
    /// out a UV atlas on it, so that strokes paint a texel layer.
    pub(super) fn atlas_buttons(&mut self, ui: &mut egui::Ui) {
        for side in [Side::Source, Side::Target] {
            let Some(slot) = self.state.slot(side) else {
                continue;
            };
            if state::paint_layer::has_uvs(slot.displayed()) {
                continue;
            }
            let free = self.tool.is_none();
            if ui
                .add_enabled(
                    free,
                    egui::Button::new(format!("UV atlas for the {side:?}")),
                )
                .on_hover_text(format!(
                    "The {side:?} mesh has no UVs, so strokes paint its vertices. Lay out a UV \
                     atlas on it (in the background) to paint a {0}x{0} texel layer instead; \
                     paint already on its vertices stays with the result",
                    state::paint_layer::TEXEL_LAYER_SIZE
                ))
                .clicked()
            {
                self.start_tool(match side {
                    Side::Source => "atlas-source",
                    Side::Target => "atlas-target",
                });
            }
        }
    }
}
