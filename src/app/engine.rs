//! The MeshMatch engine behind the app's worker, and the parameter editors.

use std::sync::Arc;

use eframe::egui;

use super::DemoScene;
use super::state::AppParams;
use crate::correspondence::Correspondence;
use crate::error::Result;
use crate::jobs::worker::{Engine, Solved};
use crate::mesh::TriMesh;
use crate::meshmatch::{self, PreparedMesh, TransferParams};
use crate::work::{CancelToken, Event};

/// [`crate::meshmatch`] as a worker engine: `prepare` once per mesh and preparation parameters,
/// `solve` per correspondence edit.
#[derive(Clone, Copy, Debug, Default)]
pub struct MeshMatchEngine;

impl Engine for MeshMatchEngine {
    type Params = TransferParams;
    type Prepared = PreparedMesh;

    fn prepare_key(&self, p: &TransferParams) -> String {
        // Everything `prepare` reads: working density, hierarchy depth and fan radius. (It
        // reads `structure` too, only to skip the global map's spectrum when the map is off;
        // a solve with the map on computes a missing spectrum itself.)
        format!("{}|{:?}|{}", p.vertices, p.levels, p.fan_radius)
    }

    fn prepare(
        &self,
        mesh: &TriMesh,
        params: &TransferParams,
        sink: &dyn Fn(Event),
        cancel: &CancelToken,
    ) -> Result<PreparedMesh> {
        meshmatch::prepare(mesh, params, sink, cancel)
    }

    fn prepare_pair(
        &self,
        source: &TriMesh,
        target: &TriMesh,
        params: &TransferParams,
        sink: &dyn Fn(Event),
        cancel: &CancelToken,
    ) -> Result<(PreparedMesh, PreparedMesh)> {
        meshmatch::prepare_pair(source, params, target, params, sink, cancel)
    }

    fn working(&self, p: &PreparedMesh) -> (Arc<TriMesh>, Arc<[u32]>, Arc<[u32]>) {
        (
            Arc::new(p.working_mesh().clone()),
            p.working_to_file().into(),
            p.file_to_working().into(),
        )
    }

    fn solve(
        &self,
        source: &PreparedMesh,
        target: &PreparedMesh,
        corr: &[Correspondence],
        params: &TransferParams,
        sink: &dyn Fn(Event),
        cancel: &CancelToken,
    ) -> Result<Solved> {
        let r = meshmatch::solve(source, target, corr, params, sink, cancel)?;
        // The source at full resolution through the solution: the view shows each working
        // vertex's colour read there, and export bakes every texel from it.
        let full = meshmatch::Resampler::new(source, target, &r.nnf, cancel)?.map(Arc::new);
        let working_signal = match &full {
            Some(f) => f.vertex_signal(),
            None => r.working_signal,
        };
        Ok(Solved {
            working_signal,
            file_signal: r.file_signal,
            layout: Some(meshmatch::BakeLayout::of(target)),
            full,
            texture: None,
        })
    }
}

impl AppParams for TransferParams {
    fn ui(&mut self, ui: &mut egui::Ui) -> bool {
        let mut changed = false;
        egui::Grid::new("params").num_columns(2).show(ui, |ui| {
            ui.label("Working vertices");
            changed |= ui
                .add(
                    egui::DragValue::new(&mut self.vertices)
                        .range(500..=400_000)
                        .speed(500.0),
                )
                .on_hover_text(
                    "Meshes with fewer vertices are refined up to this count before matching \
                     (paper: 64K). Changing it re-prepares both meshes.",
                )
                .changed();
            ui.end_row();
            ui.label("Levels");
            let mut auto = self.levels.is_none();
            ui.horizontal(|ui| {
                if ui
                    .checkbox(&mut auto, "auto")
                    .on_hover_text("Hierarchy levels down to about 128 vertices")
                    .changed()
                {
                    self.levels = if auto { None } else { Some(6) };
                    changed = true;
                }
                if let Some(l) = self.levels.as_mut() {
                    changed |= ui
                        .add(egui::DragValue::new(l).range(1..=16))
                        .on_hover_text("Number of coarse-to-fine hierarchy levels")
                        .changed();
                }
            });
            ui.end_row();
            ui.label("Iterations");
            changed |= ui
                .add(egui::DragValue::new(&mut self.iterations).range(1..=50))
                .on_hover_text("EM iterations per level at most (paper: 5)")
                .changed();
            ui.end_row();
            ui.label("Tolerance");
            changed |= ui
                .add(
                    egui::DragValue::new(&mut self.tolerance)
                        .range(0.0..=0.2)
                        .speed(0.001)
                        .max_decimals(3),
                )
                .on_hover_text(
                    "A level stops iterating once an iteration improves its energy by less than \
                     this fraction (0 = always run every iteration)",
                )
                .changed();
            ui.end_row();
            ui.label("Shape weight");
            changed |= ui
                .add(egui::Slider::new(&mut self.shape_weight, 0.0..=10.0).logarithmic(true))
                .on_hover_text(
                    "Weight of the shape features relative to the colour fans \
                     (1 = equal after normalisation; higher follows geometry more)",
                )
                .changed();
            ui.end_row();
            ui.label("Structure");
            let mut auto = self.structure.is_none();
            ui.horizontal(|ui| {
                if ui
                    .checkbox(&mut auto, "auto")
                    .on_hover_text(
                        "Let the global shape map's isometry score choose: 1 between \
                         near-isometric shapes (two bodies, an edited scan), 0 between \
                         different ones",
                    )
                    .changed()
                {
                    self.structure = if auto { None } else { Some(0.5) };
                    changed = true;
                }
                if let Some(x) = self.structure.as_mut() {
                    changed |= ui
                        .add(egui::Slider::new(x, 0.0..=1.0))
                        .on_hover_text(
                            "How closely to keep the source's layout through a global shape \
                             map: 0 = pure patch synthesis (restyle a different shape), \
                             1 = follow the map at every level (similar shapes)",
                        )
                        .changed();
                }
            });
            ui.end_row();
            ui.label("Fan radius");
            changed |= ui
                .add(egui::Slider::new(&mut self.fan_radius, 0.5..=8.0))
                .on_hover_text("Colour fan radius in mean edge lengths of each level")
                .changed();
            ui.end_row();
            ui.label("Seed");
            changed |= ui
                .add(egui::DragValue::new(&mut self.seed))
                .on_hover_text("Random seed; results are deterministic for a given seed")
                .changed();
            ui.end_row();
            ui.label("Sharpen");
            changed |= ui
                .checkbox(&mut self.sharpen, "")
                .on_hover_text(
                    "Final nearest-neighbour copy at the finest level instead of the \
                     filtered vote (crisper edges)",
                )
                .changed();
            ui.end_row();
        });
        changed
    }
}

fn zebra_cached() -> &'static TriMesh {
    static ZEBRA: std::sync::OnceLock<TriMesh> = std::sync::OnceLock::new();
    ZEBRA.get_or_init(crate::demo::zebra)
}

fn animal_scene(
    target: TriMesh,
    target_marks: Vec<(crate::demo::Landmark, [f32; 3])>,
) -> DemoScene {
    let source = zebra_cached().clone();
    let corr = crate::demo::default_correspondences(
        &source,
        &crate::demo::landmarks_zebra(),
        &target,
        &target_marks,
    );
    DemoScene {
        source,
        target,
        correspondences: corr.correspondences,
    }
}

/// Demo scene: procedural zebra -> giraffe with landmark correspondences.
pub fn zebra_to_giraffe() -> Result<DemoScene> {
    Ok(animal_scene(
        crate::demo::giraffe(),
        crate::demo::landmarks_giraffe(),
    ))
}

/// Demo scene: zebra -> three-headed cerberus (one-to-many head correspondences).
pub fn zebra_to_cerberus() -> Result<DemoScene> {
    Ok(animal_scene(
        crate::demo::cerberus(),
        crate::demo::landmarks_cerberus(),
    ))
}

/// Demo scene: the partly painted vase as exemplar for its own unpainted copy (completion).
pub fn vase() -> Result<DemoScene> {
    let (source, painted) = crate::demo::vase_with_mask();
    let mut target = source.clone();
    target.colors = None;
    target.texture = None;
    // Anchor the copy to itself at its extreme points (same vertex numbering on both sides).
    let mut anchors: Vec<u32> = Vec::new();
    for axis in 0..3 {
        for sign in [1.0f32, -1.0] {
            if let Some((i, _)) = source
                .positions
                .iter()
                .enumerate()
                .filter(|(i, _)| painted.get(*i).copied().unwrap_or(true))
                .max_by(|a, b| (sign * a.1[axis]).total_cmp(&(sign * b.1[axis])))
                && !anchors.contains(&(i as u32))
            {
                anchors.push(i as u32);
            }
        }
    }
    Ok(DemoScene {
        source,
        target,
        correspondences: anchors
            .into_iter()
            .map(|v| Correspondence {
                source_vertex: v,
                target_vertices: vec![v],
            })
            .collect(),
    })
}

/// The Scene menu: name and builder of each demo scene (the first is the startup scene).
pub fn demo_scenes() -> Vec<super::SceneEntry> {
    vec![
        (
            "Zebra -> giraffe".into(),
            zebra_to_giraffe as fn() -> Result<DemoScene>,
        ),
        ("Zebra -> cerberus".into(), zebra_to_cerberus),
        ("Vase (completion)".into(), vase),
    ]
}
