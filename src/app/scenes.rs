//! Demo scenes and what the app opens at start.

use super::{AppParams, MeshMatchApp, Startup};
use crate::correspondence::Side;
use crate::error::{Error, Result};
use crate::jobs::worker::Engine;

/// A Scene-menu entry: its name and the function that builds it.
pub type SceneEntry = (String, fn() -> Result<DemoScene>);

/// A demo scene: two meshes and their correspondences.
pub struct DemoScene {
    /// Exemplar mesh.
    pub source: crate::mesh::TriMesh,
    /// Mesh to texture.
    pub target: crate::mesh::TriMesh,
    /// Correspondences in file indices.
    pub correspondences: Vec<crate::correspondence::Correspondence>,
}

impl<E: Engine> MeshMatchApp<E>
where
    E::Params: AppParams,
{
    /// Register demo scenes for the Scene menu.
    pub fn with_demo_scenes(mut self, scenes: Vec<SceneEntry>) -> Self {
        self.state.scenes = scenes.clone();
        self.demo_scenes = scenes;
        self
    }

    /// Load a demo scene by its index in the Scene menu.
    pub fn load_demo(&mut self, index: usize) -> Result<()> {
        let (name, _) = self
            .demo_scenes
            .get(index)
            .ok_or_else(|| Error::InvalidInput("no such demo scene".into()))?;
        let name = name.clone();
        self.state.load_scene_named(&name)?;
        self.views.frame_all();
        Ok(())
    }

    /// Show a scene (two meshes + correspondences) and start the transfer.
    pub fn load_scene(&mut self, scene: DemoScene) -> Result<()> {
        self.state.set_mesh(Side::Source, scene.source, false);
        self.state.set_mesh(Side::Target, scene.target, false);
        self.state.set_correspondences(scene.correspondences)?;
        self.views.frame_all();
        Ok(())
    }

    /// Apply startup options: open files, or the first demo scene. What opens is the saved
    /// state (no unsaved work yet).
    pub fn startup(&mut self, s: &Startup) {
        self.open_startup(s);
        self.state.mark_saved(None);
    }

    pub(super) fn open_startup(&mut self, s: &Startup) {
        match (&s.source, &s.target) {
            (None, None) => {
                if !self.demo_scenes.is_empty()
                    && let Err(e) = self.load_demo(0)
                {
                    self.state.report(e);
                }
            }
            (src, tgt) => {
                for (side, p) in [(Side::Source, src), (Side::Target, tgt)] {
                    if let Some(p) = p
                        && let Err(e) = self.state.open_mesh(side, p)
                    {
                        self.state.report(e);
                    }
                }
                if let Some(c) = &s.correspondences {
                    let r = crate::correspondence::CorrespondenceFile::load(c)
                        .and_then(|f| self.state.set_correspondence_file(f, c));
                    if let Err(e) = r {
                        self.state.report(e);
                    }
                }
            }
        }
    }
}
