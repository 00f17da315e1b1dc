//! Mesh quilting in the app (Zhou et al. 2006): Tools > "Quilt geometric texture...", a
//! [`SystemTool`] that covers the target with the elements of a built-in or chosen swatch.

use std::any::Any;
use std::path::PathBuf;

use eframe::egui;

use super::state::{AppParams, AppState};
use super::system_tool::{FilePrompt, SystemTool, ToolAction, Wake};
use super::tools::{ToolJob, ToolOutcome};
use crate::correspondence::Side;
use crate::error::{Error, Result};
use crate::mesh::TriMesh;
use crate::synthesis::quilting::{self, Axis, Params, SwatchKind};

/// Where the swatch comes from.
#[derive(Clone, Debug, PartialEq)]
pub enum SwatchChoice {
    /// A built-in procedural swatch.
    Builtin(SwatchKind),
    /// A mesh file (elements over z = 0, z up); `None` until chosen.
    File(Option<PathBuf>),
}

/// The "Quilt geometric texture" window.
#[derive(Clone, Debug)]
pub struct QuiltDialog {
    /// Shown this frame.
    pub open: bool,
    /// The swatch.
    pub swatch: SwatchChoice,
    /// Swatch width as a fraction of the target's bounding-box diagonal.
    pub size: f32,
    /// Random seed.
    pub seed: u64,
    /// Merge threads that continue each other across patch seams.
    pub merge: bool,
    /// Move elements the cut drops into the gaps between patches.
    pub nudge: bool,
    pub fill: bool,
    /// Keep the clear part of a thread no whole copy fits.
    pub trim: bool,
    /// Give rings that end a chain at a seam their missing partners.
    pub relink: bool,
    /// Place patches on one global lattice.
    pub lattice: bool,
}

impl Default for QuiltDialog {
    fn default() -> Self {
        QuiltDialog {
            open: false,
            swatch: SwatchChoice::Builtin(SwatchKind::Chain),
            size: 0.1,
            seed: Params::default().seed,
            merge: Params::default().merge_elements,
            nudge: Params::default().nudge,
            fill: Params::default().fill,
            trim: Params::default().trim,
            relink: Params::default().relink,
            lattice: Params::default().lattice,
        }
    }
}

impl<P: AppParams> SystemTool<P> for QuiltDialog {
    fn label(&self) -> &'static str {
        "Quilt geometric texture..."
    }
    fn hover(&self) -> &'static str {
        "Mesh quilting (Zhou et al. 2006): cover the target with 3D elements from a swatch \
         (chain mail, weave, nuts, studs, scales), every element whole; the result replaces the \
         target (Ctrl+Z undoes) and exports with File > Export"
    }
    fn is_open(&self) -> bool {
        self.open
    }
    fn set_open(&mut self, open: bool) {
        self.open = open;
    }
    fn file_prompt(&self) -> FilePrompt {
        (
            "Choose a swatch mesh",
            "meshes",
            &["obj", "ply", "gltf", "glb"],
        )
    }
    fn set_file(&mut self, path: PathBuf) {
        self.swatch = SwatchChoice::File(Some(path));
    }
    fn ui(&mut self, ui: &mut egui::Ui, state: &AppState<P>, busy: bool) -> ToolAction {
        let mut action = ToolAction::None;
        ui.label("Swatch:");
        ui.horizontal_wrapped(|ui| {
            for k in SwatchKind::ALL {
                ui.selectable_value(&mut self.swatch, SwatchChoice::Builtin(k), k.as_str());
            }
            let is_file = matches!(self.swatch, SwatchChoice::File(_));
            if ui
                .selectable_label(is_file, "from file...")
                .on_hover_text("A mesh whose connected components lie over z = 0, z up")
                .clicked()
            {
                action = ToolAction::ChooseFile;
            }
        });
        if let SwatchChoice::File(Some(p)) = &self.swatch {
            ui.label(format!(
                "file: {}",
                p.file_name().unwrap_or_default().to_string_lossy()
            ));
        }
        ui.add(egui::Slider::new(&mut self.size, 0.02..=0.5).text("swatch width"))
            .on_hover_text(
                "The swatch's width as a fraction of the target's bounding-box diagonal",
            );
        ui.add(egui::DragValue::new(&mut self.seed).prefix("seed "));
        ui.checkbox(&mut self.merge, "merge threads across seams")
            .on_hover_text(
                "Threads (elongated elements) that continue each other across patch seams are \
                 deformed half-way and stitched into one instead of one copy being dropped; \
                 slower, compact elements are never merged",
            );
        ui.checkbox(&mut self.nudge, "fill gaps at seams")
            .on_hover_text(
                "A thread (elongated element) dropped where two patches meet is tried again \
                 moved by a quarter or half of its spacing, and kept whole where it clears every \
                 other element; compact elements are never moved",
            );
        ui.checkbox(&mut self.fill, "fill the gaps left between patches")
            .on_hover_text(
                "Once the surface is covered, every gap wider than the swatch's own largest \
                 gets the first copy of a swatch element, lined up with its neighbours or moved \
                 by up to half a spacing, that clears every other element",
            );
        ui.checkbox(&mut self.trim, "cut threads short where no whole one fits")
            .on_hover_text(
                "A thread (elongated element) dropped at a seam, torn off around a thin part \
                 or too long for a gap keeps its longest clear part, cut across and capped \
                 (at least a quarter of it); compact elements are never cut",
            );
        ui.checkbox(&mut self.relink, "relink chains broken at seams")
            .on_hover_text(
                "A ring with fewer links than in the swatch (a chain ending where two patches \
                 meet) gets its missing partner where that adds links, replacing at most one \
                 element",
            );
        ui.checkbox(&mut self.lattice, "one lattice over the surface")
            .on_hover_text(
                "Patches are laid on one global lattice (two stripe patterns along the \
                 orientation field and across it), so threads and crossings line up across \
                 seams; near the lattice's singularities patches are matched to their \
                 neighbours as in the paper. Off: every patch is matched",
            );
        let ready =
            state.slot(Side::Target).is_some() && !matches!(self.swatch, SwatchChoice::File(None));
        ui.horizontal(|ui| {
            if ui
                .add_enabled(ready && !busy, egui::Button::new("Run"))
                .on_hover_text("Runs on its own thread; the quilted mesh replaces the target")
                .clicked()
            {
                action = ToolAction::Run;
            }
            if ui.button("Close").clicked() {
                action = ToolAction::Close;
            }
        });
        if state.slot(Side::Target).is_none() {
            ui.label("open a target mesh first");
        }
        action
    }
    fn start(&mut self, state: &AppState<P>, wake: Wake) -> Result<ToolJob> {
        let Some(base) = state.slot(Side::Target).map(|s| s.displayed().clone()) else {
            return Err(Error::InvalidInput("open a target mesh first".into()));
        };
        let (lo, hi) = base
            .bounds()
            .ok_or_else(|| Error::InvalidMesh("the target is empty".into()))?;
        let diag = glam::Vec3::from(hi).distance(glam::Vec3::from(lo));
        let params = Params {
            swatch_size: Some(self.size * diag),
            seed: self.seed,
            merge_elements: self.merge,
            nudge: self.nudge,
            fill: self.fill,
            trim: self.trim,
            relink: self.relink,
            lattice: self.lattice,
            ..Params::default()
        };
        let choice = self.swatch.clone();
        let seed = self.seed;
        Ok(ToolJob::spawn("quilt", wake, move |sink, cancel| {
            let swatch = match &choice {
                SwatchChoice::Builtin(k) => quilting::swatch(*k, seed),
                SwatchChoice::File(Some(p)) => {
                    quilting::load_swatch(crate::mesh::io::load(p)?, Axis::Z)?
                }
                SwatchChoice::File(None) => {
                    return Err(Error::InvalidInput("choose a swatch file first".into()));
                }
            };
            let input = quilting::Input {
                base: &base,
                swatch: &swatch,
                field: None,
            };
            let out = quilting::run(&input, &params, sink, cancel)?;
            let mut positions = out.elements.positions.clone();
            let mut faces = out.elements.faces.clone();
            let o = positions.len() as u32;
            positions.extend_from_slice(&base.positions);
            faces.extend(base.faces.iter().map(|f| [f[0] + o, f[1] + o, f[2] + o]));
            let mesh = TriMesh::new(positions, faces);
            Ok(ToolOutcome::Mesh(
                Side::Target,
                mesh,
                format!(
                    "quilted {} elements over the target in {:.1} s{}: {}",
                    out.stats.elements,
                    out.stats.seconds,
                    if out.stats.merged > 0 {
                        format!(" ({} thread copies merged across seams)", out.stats.merged)
                    } else {
                        String::new()
                    },
                    out.stats.arrangement_summary()
                ),
            ))
        }))
    }
    fn as_any_mut(&mut self) -> &mut dyn Any {
        self
    }
}
