//! Sessions, the Recent list and exports.

use std::path::{Path, PathBuf};

use super::*;

/// The session file: meshes, correspondences (file indices), parameters and paint sidecars.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct Session<P> {
    /// Source mesh path.
    pub source: Option<PathBuf>,
    /// Target mesh path.
    pub target: Option<PathBuf>,
    /// Correspondences in file vertex indices.
    pub correspondences: CorrespondenceFile,
    /// Transfer parameters.
    pub params: P,
    /// Painted source colours (PLY sidecar, relative to the session file), if any.
    pub source_paint: Option<PathBuf>,
    /// Painted target colours (PLY sidecar, relative to the session file), if any.
    pub target_paint: Option<PathBuf>,
    /// Paint coverage per sidecar vertex (0-255) of the source; absent = fully painted.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub source_paint_coverage: Option<Vec<u8>>,
    /// Paint coverage per sidecar vertex (0-255) of the target; absent = fully painted.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub target_paint_coverage: Option<Vec<u8>>,
    /// Built-in scene the source mesh comes from when it has no file (e.g. "Zebra -> giraffe").
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub source_scene: Option<String>,
    /// Built-in scene the target mesh comes from when it has no file.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub target_scene: Option<String>,
    /// Texture image opened for the source (File > Open texture), if any.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub source_texture: Option<PathBuf>,
    /// The source's texel paint layer (RGBA PNG sidecar, relative to the session file), if any.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub source_paint_texels: Option<PathBuf>,
    /// The target's texel paint layer (RGBA PNG sidecar), if any.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub target_paint_texels: Option<PathBuf>,
    /// The source's texel mask layer (RGBA PNG sidecar), if any.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub source_mask_texels: Option<PathBuf>,
    /// The target's texel mask layer (RGBA PNG sidecar), if any.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub target_mask_texels: Option<PathBuf>,
}

/// What a recently opened file was opened as.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum RecentKind {
    /// A mesh (offered as source or target).
    Mesh,
    /// A texture image for the source.
    Texture,
    /// A session JSON.
    Session,
}

/// One entry of the Recent menu.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct RecentFile {
    /// The file.
    pub path: PathBuf,
    /// What it was opened as.
    pub kind: RecentKind,
}

/// Where the Recent list is kept between runs: `$XDG_CONFIG_HOME/meshmatch/recent.json`
/// (or `~/.config/...`; `%APPDATA%\meshmatch\recent.json` on Windows).
pub fn default_recent_store() -> Option<PathBuf> {
    let base = std::env::var_os("XDG_CONFIG_HOME")
        .filter(|v| !v.is_empty())
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("APPDATA").map(PathBuf::from))
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".config")))?;
    Some(base.join("meshmatch").join("recent.json"))
}

impl<P: AppParams> AppState<P> {
    /// Read the Recent list from `store` (missing or unreadable: empty) and keep it saved there.
    pub fn load_recent(&mut self, store: PathBuf) {
        self.recent = crate::mesh::io::read_input_file(&store, 1 << 20, "the Recent list")
            .ok()
            .and_then(|b| serde_json::from_slice::<Vec<RecentFile>>(&b).ok())
            .unwrap_or_default();
        self.recent.truncate(10);
        self.recent_store = Some(store);
    }

    pub(super) fn push_recent(&mut self, path: &Path, kind: RecentKind) {
        let path = abs(path);
        self.recent.retain(|r| r.path != path);
        self.recent.insert(0, RecentFile { path, kind });
        self.recent.truncate(10);
        if let Some(store) = &self.recent_store {
            let r = store
                .parent()
                .map_or(Ok(()), std::fs::create_dir_all)
                .map_err(|e| Error::io(store, e))
                .and_then(|_| {
                    let text = serde_json::to_vec_pretty(&self.recent).unwrap_or_default();
                    crate::mesh::io::write_atomic(store, &text)
                });
            if let Err(e) = r {
                self.message = format!("recent files not saved: {e}");
            }
        }
    }

    // ----- export and sessions -----

    /// The target slot and the finished transfer, or the error an export reports.
    pub(super) fn target_and_result(&self) -> Result<(&MeshSlot, &Solved)> {
        let slot = self
            .slot(Side::Target)
            .ok_or_else(|| Error::InvalidInput("no target mesh".into()))?;
        let res = self
            .result
            .as_ref()
            .ok_or_else(|| Error::InvalidInput("no finished transfer to export yet".into()))?;
        Ok((slot, res))
    }

    /// Write the transfer result on the target file mesh as `transfer --out` does (format by
    /// extension; `.glb`/`.obj` get a texture baked into the target's UV layout, or into an
    /// atlas generated for a target without UVs).
    pub fn export_result(&self, path: &Path) -> Result<()> {
        self.export_task(path)?(&crate::work::CancelToken::new()).map(|_| ())
    }

    /// [`Self::export_result`] as a task to run off the window's thread (generating an atlas
    /// takes seconds on a large target): what it needs is captured by reference count; it returns
    /// the status line to show.
    pub fn export_task(
        &self,
        path: &Path,
    ) -> Result<impl FnOnce(&crate::work::CancelToken) -> Result<String> + Send + 'static> {
        let (slot, res) = self.target_and_result()?;
        if res.file_signal.len() != slot.file.positions.len() {
            return Err(Error::InvalidInput(
                "result does not match the target mesh".into(),
            ));
        }
        let file = slot.file.clone();
        let res = self.result.clone().expect("checked above");
        let path = path.to_path_buf();
        Ok(move |cancel: &crate::work::CancelToken| {
            let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("");
            let (m, note) = match &res.layout {
                Some(layout) => {
                    let d = crate::meshmatch::deliver(
                        &file,
                        layout,
                        &res.working_signal,
                        &res.file_signal,
                        ext,
                        EXPORT_TEXTURE_SIZE,
                        res.full.as_deref(),
                        cancel,
                    )?;
                    let note = d.atlas_line(EXPORT_TEXTURE_SIZE);
                    (d.mesh, note)
                }
                None => {
                    let mut m = (*file).clone();
                    m.colors = Some(res.file_signal.clone());
                    m.texture = None;
                    (m, None)
                }
            };
            crate::mesh::io::save(&m, &path)?;
            Ok(match note {
                Some(n) => format!("exported {} ({n})", path.display()),
                None => format!("exported {}", path.display()),
            })
        })
    }

    /// Write the transfer result on the dense working mesh (as `transfer --out-dense` does).
    pub fn export_dense_result(&self, path: &Path) -> Result<()> {
        let (slot, res) = self.target_and_result()?;
        let working = slot
            .working
            .as_ref()
            .filter(|w| w.positions.len() == res.working_signal.len())
            .ok_or_else(|| {
                Error::InvalidInput("result does not match the target's working mesh".into())
            })?;
        crate::mesh::io::save(
            &crate::meshmatch::deliver_dense(working, &res.working_signal),
            path,
        )
    }

    /// Save the session as JSON at `path`. Meshes are named by file, or by built-in scene when
    /// they have none; a computed mesh (a tool's result, in no file) goes to a sidecar beside it
    /// (PLY, or GLB when it has UVs); each paint layer goes to a PLY sidecar beside it (the displayed mesh with the paint's
    /// colours) with its coverage in the JSON. The JSON is written last, so it never names a
    /// sidecar that is not complete.
    pub fn save_session(&self, path: &Path) -> Result<()> {
        let mut names: [(Option<PathBuf>, Option<String>); 2] = [(None, None), (None, None)];
        for (side, suffix) in [(Side::Source, "source_mesh"), (Side::Target, "target_mesh")] {
            if let Some(slot) = self.slot(side) {
                let file = slot.file.path.as_ref().map(|p| abs(p));
                let mut name = (file, slot.scene.clone());
                if name.0.is_none() && name.1.is_none() {
                    // PLY keeps the vertices as they are (pairs and paint name them); GLB keeps
                    // a mesh's UVs and texture
                    let textured = slot.file.uvs.is_some() || slot.file.texture.is_some();
                    let ext = if textured { "glb" } else { "ply" };
                    let p = path.with_extension(format!("{suffix}.{ext}"));
                    crate::mesh::io::save(&slot.file, &p)?;
                    name.0 = Some(p.file_name().map_or_else(|| p.clone(), PathBuf::from));
                }
                names[side_index(side)] = name;
            }
        }
        let mut paint: [(Option<PathBuf>, Option<Vec<u8>>); 2] = [(None, None), (None, None)];
        for (side, suffix) in [
            (Side::Source, "source_paint"),
            (Side::Target, "target_paint"),
        ] {
            let Some(slot) = self.slot(side) else {
                continue;
            };
            let Some(layer) = &slot.paint else { continue };
            let p = path.with_extension(format!("{suffix}.ply"));
            let mut m = slot.displayed().clone();
            m.colors = Some(layer.iter().map(|c| [c[0], c[1], c[2]]).collect());
            m.texture = None;
            m.uvs = None;
            m.normals = None;
            crate::mesh::io::save(&m, &p)?;
            let coverage = layer
                .iter()
                .map(|c| (c[3].clamp(0.0, 1.0) * 255.0).round() as u8)
                .collect();
            // Named relative to the session file, so the pair can move together.
            let name = p.file_name().map_or_else(|| p.clone(), PathBuf::from);
            paint[side_index(side)] = (Some(name), Some(coverage));
        }
        let mut texels: [Option<PathBuf>; 4] = [None, None, None, None];
        for (k, side, suffix) in [
            (0, Side::Source, "source_paint_texels"),
            (1, Side::Target, "target_paint_texels"),
            (2, Side::Source, "source_mask_texels"),
            (3, Side::Target, "target_mask_texels"),
        ] {
            let Some(slot) = self.slot(side) else {
                continue;
            };
            let layer = if k < 2 {
                slot.texels.as_ref()
            } else {
                slot.mask_texels.as_ref()
            };
            let Some(layer) = layer.filter(|l| !l.is_empty()) else {
                continue;
            };
            let p = path.with_extension(format!("{suffix}.png"));
            paint_layer::save_texel_layer(layer, &p)?;
            texels[k] = Some(p.file_name().map_or_else(|| p.clone(), PathBuf::from));
        }
        let [
            source_paint_texels,
            target_paint_texels,
            source_mask_texels,
            target_mask_texels,
        ] = texels;
        let [(src_paint, src_cov), (tgt_paint, tgt_cov)] = paint;
        let [(source, source_scene), (target, target_scene)] = names;
        let session = Session {
            source,
            target,
            correspondences: self.correspondence_file(),
            params: self.params.clone(),
            source_paint: src_paint,
            target_paint: tgt_paint,
            source_paint_coverage: src_cov,
            target_paint_coverage: tgt_cov,
            source_scene,
            target_scene,
            source_texture: self
                .slot(Side::Source)
                .and_then(|s| s.texture_file.as_ref().map(|p| abs(p))),
            source_paint_texels,
            target_paint_texels,
            source_mask_texels,
            target_mask_texels,
        };
        let text = serde_json::to_string_pretty(&session)
            .map_err(|e| Error::InvalidInput(format!("cannot serialise session: {e}")))?;
        crate::mesh::io::write_atomic(path, text.as_bytes())
    }

    /// Open a session JSON: both meshes (files or built-in scenes), the source texture,
    /// correspondences, parameters and paint. Nothing changes when any part fails to load.
    /// The session is the saved state of the work, and goes on the Recent list.
    pub fn open_session(&mut self, path: &Path) -> Result<()> {
        self.load_session(path)?;
        self.mark_saved(Some(path));
        self.push_recent(path, RecentKind::Session);
        Ok(())
    }

    /// [`Self::open_session`] without marking the work saved or touching the Recent list (an
    /// autosave's recovery).
    pub fn load_session(&mut self, path: &Path) -> Result<()> {
        // the loaders' rule: a regular file of bounded size (no directory, device or pipe)
        let text = crate::mesh::io::read_text_file(path, "the session file")?;
        let mut s: Session<P> = serde_json::from_str(&text)
            .map_err(|e| Error::format(path, format!("invalid session JSON: {e}")))?;
        // Relative paths in the session are relative to the session file.
        let dir = path.parent().unwrap_or(Path::new("."));
        let resolve = |p: &PathBuf| dir.join(p);
        let mut built: Vec<(String, crate::app::DemoScene)> = Vec::new();
        // A side the session names no mesh for stays empty (a session saved with one mesh).
        let mut meshes: [Option<(Side, TriMesh, Option<String>)>; 2] = [None, None];
        for (side, file, scene) in [
            (Side::Source, &s.source, &s.source_scene),
            (Side::Target, &s.target, &s.target_scene),
        ] {
            let mesh = match (file, scene) {
                (Some(f), _) => crate::mesh::io::load(&resolve(f))?,
                (None, Some(name)) => {
                    if !built.iter().any(|(n, _)| n == name) {
                        let sc = self.build_scene(name)?;
                        built.push((name.clone(), sc));
                    }
                    let sc = &built
                        .iter()
                        .find(|(n, _)| n == name)
                        .expect("built above")
                        .1;
                    match side {
                        Side::Source => sc.source.clone(),
                        Side::Target => sc.target.clone(),
                    }
                }
                (None, None) => continue,
            };
            mesh_usable(&mesh)?;
            meshes[side_index(side)] = Some((
                side,
                mesh,
                if file.is_none() { scene.clone() } else { None },
            ));
        }
        let texture = s.source_texture.as_ref().map(resolve);
        if let (Some(t), Some(m)) = (&texture, meshes[0].as_mut()) {
            m.1 = with_texture(&m.1, t)?;
        }
        let mut samples = [None, None];
        for (i, (sidecar, coverage)) in [
            (&s.source_paint, &s.source_paint_coverage),
            (&s.target_paint, &s.target_paint_coverage),
        ]
        .into_iter()
        .enumerate()
        {
            let Some(sidecar) = sidecar else { continue };
            let m = crate::mesh::io::load(&resolve(sidecar))?;
            let colors = m.colors.clone().ok_or_else(|| {
                Error::format(resolve(sidecar), "paint sidecar has no vertex colours")
            })?;
            if coverage.as_ref().is_some_and(|c| c.len() != colors.len()) {
                return Err(Error::format(
                    path,
                    "paint coverage does not match its sidecar's vertex count",
                ));
            }
            let rgba = colors
                .iter()
                .enumerate()
                .map(|(v, c)| {
                    let a = coverage.as_ref().map_or(1.0, |cov| cov[v] as f32 / 255.0);
                    [c[0], c[1], c[2], a]
                })
                .collect();
            samples[i] = Some(slot::PaintSample {
                positions: m.positions,
                rgba,
            });
        }
        let mut texel_layers = [None, None, None, None];
        for (i, sidecar) in [
            &s.source_paint_texels,
            &s.target_paint_texels,
            &s.source_mask_texels,
            &s.target_mask_texels,
        ]
        .into_iter()
        .enumerate()
        {
            if let Some(sidecar) = sidecar {
                texel_layers[i] = Some(paint_layer::load_texel_layer(&resolve(sidecar))?);
            }
        }
        // Pairs whose meshes were renumbered since the session was saved (re-exported by another
        // tool) move to the nearest vertex of their stored position.
        let mesh_of = |i: usize| meshes[i].as_ref().map(|m| &m.1);
        let note = s.correspondences.resolve(mesh_of(0), mesh_of(1), path);
        let counts = [0, 1].map(|i| mesh_of(i).map_or(0, |m| m.positions.len()));
        for c in &s.correspondences.correspondences {
            let bad_t = c.target_vertices.iter().any(|&t| t as usize >= counts[1]);
            if c.source_vertex as usize >= counts[0] || bad_t {
                return Err(Error::format(
                    path,
                    "a correspondence is out of range for the session's meshes",
                ));
            }
        }
        // Everything loaded: replace the state.
        for (i, m) in meshes.into_iter().enumerate() {
            let Some((side, mesh, scene)) = m else {
                self.meshes[i] = None;
                continue;
            };
            self.set_mesh(side, mesh, false);
            if let Some(slot) = self.slot_mut(side) {
                slot.scene = scene;
                if side == Side::Source {
                    slot.texture_file = texture.clone();
                }
            }
        }
        for (i, sample) in samples.into_iter().enumerate() {
            if let (Some(sample), Some(slot)) = (sample, self.meshes[i].as_mut()) {
                let applied =
                    remap_paint(&sample.positions, &sample.rgba, &slot.displayed().positions);
                slot.paint = Some(applied.clone());
                slot.restored_paint = Some((sample, applied));
                slot.colors_dirty = true;
            }
        }
        for (i, layer) in texel_layers.into_iter().enumerate() {
            if let (Some(layer), Some(slot)) = (layer, self.meshes[i % 2].as_mut()) {
                if i < 2 {
                    slot.texels = Some(layer);
                } else {
                    slot.mask_texels = Some(layer);
                }
            }
        }
        self.params = s.params;
        self.set_correspondences(s.correspondences.correspondences)?;
        if let Some(note) = note {
            self.report(format!("warning: {note}"));
        }
        self.undo.clear();
        self.redo.clear();
        Ok(())
    }

    /// Meshes read from files under `dir` count as computed again (no file): the next save
    /// writes them beside itself. For meshes recovered from an autosave that is then removed.
    pub fn forget_files_under(&mut self, dir: &Path) {
        let dir = abs(dir);
        for slot in self.meshes.iter_mut().flatten() {
            if slot
                .file
                .path
                .as_ref()
                .is_some_and(|p| abs(p).starts_with(&dir))
            {
                Arc::make_mut(&mut slot.file).path = None;
            }
            if slot
                .texture_file
                .as_ref()
                .is_some_and(|p| abs(p).starts_with(&dir))
            {
                slot.texture_file = None;
            }
        }
    }
}
