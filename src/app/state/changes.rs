//! Unsaved work: every edit worth keeping (a paint stroke, a correspondence, a tool's result, a
//! parameter, a mesh opened or replaced, an undo or redo) counts as a change; saving or opening a
//! session marks the count as saved. The close prompt and the autosave read it.

use std::path::{Path, PathBuf};

use super::*;

impl<P: AppParams> AppState<P> {
    /// Count one change to the session (called by every edit; see the module's list).
    pub fn mark_changed(&mut self) {
        self.edits += 1;
    }

    /// Changes made since the state was created: a number that grows with every edit (the
    /// autosave compares it with the one it last wrote).
    pub fn edits(&self) -> u64 {
        self.edits
    }

    /// Is there work that no saved session holds?
    pub fn is_dirty(&self) -> bool {
        self.saved_edits != Some(self.edits)
    }

    /// Everything up to now is saved (in `path`, when given: the file a plain Save writes next).
    pub fn mark_saved(&mut self, path: Option<&Path>) {
        self.saved_edits = Some(self.edits);
        if let Some(p) = path {
            self.session_path = Some(abs(p));
        }
    }

    /// The work is in no file the user chose (recovered from an autosave): dirty until saved.
    pub fn mark_unsaved(&mut self) {
        self.saved_edits = None;
        self.session_path = None;
    }

    /// The session file the work was last saved to or opened from, if any.
    pub fn session_path(&self) -> Option<&PathBuf> {
        self.session_path.as_ref()
    }

    /// Save the session to `path` and mark the work saved there.
    pub fn save_session_to(&mut self, path: &Path) -> Result<()> {
        self.save_session(path)?;
        self.mark_saved(Some(path));
        Ok(())
    }

    /// Start an empty session: no meshes, no correspondences, default parameters, no history.
    pub fn new_session(&mut self) {
        self.cancel_job();
        self.meshes = [None, None];
        self.corr.clear();
        self.pending_source = None;
        self.selected = None;
        self.params = P::default();
        self.result = None;
        self.undo.clear();
        self.redo.clear();
        self.preview_backup = None;
        self.restart_at = None;
        self.overlay = None;
        self.session_path = None;
        self.mark_changed();
        self.mark_saved(None);
        self.message = "new session".into();
    }

    /// What unsaved work there is, in words (for the close prompt): pairs, paint, computed
    /// meshes.
    pub fn work_summary(&self) -> Vec<String> {
        let mut out = Vec::new();
        if !self.corr.is_empty() {
            out.push(format!("{} correspondence pairs", self.corr.len()));
        }
        for (i, name) in ["source", "target"].into_iter().enumerate() {
            let Some(slot) = &self.meshes[i] else {
                continue;
            };
            let vertex = |l: &Option<Vec<[f32; 4]>>| {
                l.as_ref().is_some_and(|p| p.iter().any(|c| c[3] > 0.0))
            };
            let texel = |l: &Option<super::paint_layer::TexelLayer>| {
                l.as_ref().is_some_and(|l| !l.is_empty())
            };
            if vertex(&slot.paint)
                || vertex(&slot.mask)
                || texel(&slot.texels)
                || texel(&slot.mask_texels)
            {
                out.push(format!("paint on the {name}"));
            }
            if slot.file.path.is_none() && slot.scene.is_none() {
                out.push(format!("a computed {name} mesh"));
            }
        }
        out
    }
}
