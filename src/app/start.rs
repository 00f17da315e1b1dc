//! Starting the tools' jobs on the worker, and polling them.

use std::path::PathBuf;

use super::{AppParams, MeshMatchApp, state, systems, tools, wake_delay};
use crate::correspondence::Side;
use crate::error::Error;
use crate::jobs::worker::Engine;

impl<E: Engine> MeshMatchApp<E>
where
    E::Params: AppParams,
{
    /// Start an application on the current meshes (`which`: "complete-target",
    /// "complete-source", "detail"); errors become messages.
    pub fn start_tool(&mut self, which: &str) {
        if let Some(t) = &self.tool {
            self.state.report(format!(
                "{} is still running: wait for it or cancel it",
                t.name
            ));
            return;
        }
        let ctx = self.repaint.clone();
        let wake = move || {
            if let Some(c) = &ctx {
                c.request_repaint_after(wake_delay());
            }
        };
        let job = match which {
            "complete-target" | "complete-source" => {
                let side = if which == "complete-target" {
                    Side::Target
                } else {
                    Side::Source
                };
                match (
                    self.state.painted_mesh(side),
                    self.state.paint_coverage(side),
                ) {
                    (Some(m), Some(c)) => tools::completion_job(side, m, c, wake),
                    _ => Err(Error::InvalidInput(format!("no {side:?} mesh to complete"))),
                }
            }
            "suggest" => match (self.state.slot(Side::Source), self.state.slot(Side::Target)) {
                (Some(s), Some(t)) => Ok(tools::suggest_job(
                    (*s.file).clone(),
                    (*t.file).clone(),
                    self.state.corr.clone(),
                    tools::SUGGESTED_PAIRS,
                    wake,
                )),
                _ => Err(Error::InvalidInput(
                    "suggesting correspondences needs a source and a target mesh".into(),
                )),
            },
            "atlas-source" | "atlas-target" => {
                let side = if which == "atlas-target" {
                    Side::Target
                } else {
                    Side::Source
                };
                match self.state.slot(side) {
                    Some(s) => Ok(tools::atlas_job(
                        side,
                        s.id,
                        s.working.clone().unwrap_or_else(|| s.file.clone()),
                        state::paint_layer::TEXEL_LAYER_SIZE,
                        wake,
                    )),
                    None => Err(Error::InvalidInput(format!("no {side:?} mesh to lay out"))),
                }
            }
            "detail" => match (self.state.slot(Side::Source), self.state.slot(Side::Target)) {
                (Some(s), Some(t)) => Ok(tools::detail_job(
                    (*s.file).clone(),
                    (*t.file).clone(),
                    self.signal.strength,
                    wake,
                )),
                _ => Err(Error::InvalidInput(
                    "detail transfer needs a source (detailed) and a target mesh".into(),
                )),
            },
            _ => Err(Error::InvalidInput(format!("unknown tool {which}"))),
        };
        match job {
            Ok(j) => {
                self.state.message = format!("{} running...", j.name);
                self.tool = Some(j);
            }
            Err(e) => self.state.report(e),
        }
    }

    /// The system tool of type `T`, if this build has it.
    pub fn system<T: 'static>(&self) -> Option<&T> {
        self.systems.iter().find_map(|t| {
            let any: &dyn std::any::Any = t.as_ref();
            any.downcast_ref::<T>()
        })
    }

    /// The system tool of type `T`, mutable, if this build has it.
    pub fn system_mut<T: 'static>(&mut self) -> Option<&mut T> {
        self.systems
            .iter_mut()
            .find_map(|t| t.as_any_mut().downcast_mut::<T>())
    }

    /// Open the "Paint with exemplar" window, with `image` already chosen when given.
    pub fn open_exemplar_dialog(&mut self, image: Option<PathBuf>) {
        if let Some(d) = self.system_mut::<tools::ExemplarDialog>() {
            d.open = true;
            if image.is_some() {
                d.settings.image = image;
            }
        }
    }

    /// Paint with exemplar with `settings` (see [`Self::start_system`]).
    pub fn start_exemplar(&mut self, settings: &tools::ExemplarSettings) {
        let Some(i) = self
            .systems
            .iter_mut()
            .position(|t| t.as_any_mut().is::<tools::ExemplarDialog>())
        else {
            return;
        };
        if let Some(d) = self.systems[i]
            .as_any_mut()
            .downcast_mut::<tools::ExemplarDialog>()
        {
            d.settings = settings.clone();
        }
        self.start_system(i);
    }

    /// Start system tool `i` with its current settings on its own thread; partial results show
    /// in the view; errors are messages.
    pub fn start_system(&mut self, i: usize) {
        if let Some(t) = &self.tool {
            self.state.report(format!(
                "{} is still running: wait for it or cancel it",
                t.name
            ));
            return;
        }
        let ctx = self.repaint.clone();
        let wake: systems::Wake = Box::new(move || {
            if let Some(c) = &ctx {
                c.request_repaint_after(wake_delay());
            }
        });
        let Some(tool) = self.systems.get_mut(i) else {
            return;
        };
        match tool.start(&self.state, wake) {
            Ok(j) => {
                self.state.message = format!("{} running...", j.name);
                self.tool = Some(j);
            }
            Err(e) => self.state.report(e),
        }
    }

    /// Export the transfer result to `path` in the background (a texture bake, and an atlas for a
    /// target without UVs, take seconds): progress in the status bar, cancel, no frozen window.
    pub fn start_export(&mut self, path: &std::path::Path) {
        if let Some(t) = &self.tool {
            self.state.report(format!(
                "{} is still running: wait for it or cancel it",
                t.name
            ));
            return;
        }
        let task = match self.state.export_task(path) {
            Ok(t) => t,
            Err(e) => return self.state.report(e),
        };
        let ctx = self.repaint.clone();
        let j = tools::ToolJob::spawn(
            "export",
            move || {
                if let Some(c) = &ctx {
                    c.request_repaint_after(wake_delay());
                }
            },
            move |_sink, cancel| Ok(tools::ToolOutcome::Done(task(cancel)?)),
        );
        self.state.message = format!("exporting {}...", path.display());
        self.tool = Some(j);
    }

    /// Start the texture update: the source (textured, old geometry) onto `new` geometry.
    pub fn start_update(&mut self, new: crate::mesh::TriMesh) {
        if self.tool.is_some() {
            self.state
                .report("an application is still running: wait for it or cancel it");
            return;
        }
        let Some(old) = self.state.slot(Side::Source).map(|s| (*s.file).clone()) else {
            self.state
                .report("open the textured mesh (old geometry) as the source first");
            return;
        };
        let ctx = self.repaint.clone();
        let j = tools::update_job(old, new, move || {
            if let Some(c) = &ctx {
                c.request_repaint_after(wake_delay());
            }
        });
        self.state.message = format!("{} running...", j.name);
        self.tool = Some(j);
    }

    /// Apply a finished application's outcome (called every frame).
    pub fn poll_tool(&mut self) {
        let Some(t) = &self.tool else { return };
        if let Some(side) = t.preview
            && let Some(p) = t.take_partial()
        {
            self.state.show_tool_preview(side, &p);
        }
        let Some(r) = t.poll() else { return };
        let name = t.name;
        self.tool = None;
        self.state.end_tool_preview();
        match r {
            Ok(o) => {
                let replaces = matches!(o, tools::ToolOutcome::Mesh(..));
                self.state.apply_tool_outcome(o);
                if replaces {
                    self.views.frame_all();
                }
            }
            Err(Error::Cancelled) => self.state.message = format!("{name} cancelled"),
            Err(e) => self.state.report(format!("{name}: {e}")),
        }
    }
}
