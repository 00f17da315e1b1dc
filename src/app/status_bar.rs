//! The status bar: what runs, how far it is, how long it took.

use eframe::egui;

use super::{AppParams, MeshMatchApp, busy_repaint};
use crate::jobs::worker::Engine;

/// A small rotating arc that says "working". Unlike `egui::Spinner`, which asks for a repaint
/// every frame, it asks for one after `period` (see [`busy_repaint`]), so a running job does not
/// keep the window (and a software renderer) drawing flat out.
fn busy_indicator(ui: &mut egui::Ui, period: std::time::Duration) {
    let size = ui.spacing().interact_size.y;
    let (rect, _) = ui.allocate_exact_size(egui::vec2(size, size), egui::Sense::hover());
    let t = ui.input(|i| i.time) as f32;
    let r = rect.height() * 0.35;
    let start = (t * 5.0) % std::f32::consts::TAU;
    let points: Vec<egui::Pos2> = (0..=16)
        .map(|k| {
            let a = start + k as f32 / 16.0 * std::f32::consts::PI * 1.5;
            rect.center() + r * egui::vec2(a.cos(), a.sin())
        })
        .collect();
    ui.painter().add(egui::Shape::line(
        points,
        egui::Stroke::new(2.0, ui.visuals().strong_text_color()),
    ));
    ui.ctx().request_repaint_after(period);
}

impl<E: Engine> MeshMatchApp<E>
where
    E::Params: AppParams,
{
    pub(super) fn status_bar(&mut self, ui: &mut egui::Ui) {
        ui.horizontal(|ui| {
            let j = &self.state.job;
            let p = &j.progress;
            if j.running {
                busy_indicator(ui, busy_repaint(self.views.software_renderer));
                let mut text = p.stage.to_string();
                if p.levels > 0 {
                    text += &format!(
                        "  level {} of {} (0 = finest)  iteration {}",
                        p.level, p.levels, p.iteration
                    );
                }
                if p.energy > 0.0 {
                    text += &format!("  energy {:.4}", p.energy);
                }
                text += &format!("  {:.1} s", p.elapsed);
                ui.label(text);
                ui.add(egui::ProgressBar::new(p.fraction).desired_width(120.0));
            } else if !j.outcome.is_empty() {
                ui.label(format!("transfer {}", j.outcome));
            } else if self.state.restart_pending() {
                ui.label("transfer starting...");
            }
            if let Some(t) = &self.tool {
                ui.separator();
                busy_indicator(ui, busy_repaint(self.views.software_renderer));
                let f = t.fraction.lock().map(|f| *f).unwrap_or(0.0);
                ui.label(format!(
                    "{} {:.1} s",
                    t.name,
                    t.started.elapsed().as_secs_f32()
                ));
                ui.add(egui::ProgressBar::new(f).desired_width(100.0));
                if ui.small_button("Cancel").clicked() {
                    t.cancel.cancel();
                }
            }
            ui.separator();
            ui.label(&self.state.message);
            ui.with_layout(egui::Layout::right_to_left(egui::Align::Center), |ui| {
                let (mean, max) = self.frame_stats.summary();
                ui.label(format!("UI {mean:.1} ms (max {max:.1})"));
            });
        });
    }
}
