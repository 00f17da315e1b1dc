//! Correspondence editing: clicks, selection, moves, deletion.

use super::*;

/// The selected marker: pair index, side and (for the target) which of its vertices.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Selection {
    /// Index into the correspondence list.
    pub pair: usize,
    /// Which view's marker.
    pub side: Side,
    /// Index into `target_vertices` (0 for the source marker).
    pub k: usize,
}

impl<P: AppParams> AppState<P> {
    pub(super) fn marker_exists(&self, s: Selection) -> bool {
        self.corr.get(s.pair).is_some_and(|c| match s.side {
            Side::Source => s.k == 0,
            Side::Target => s.k < c.target_vertices.len(),
        })
    }

    /// Handle a click on a displayed vertex of one view: source click starts a pair, target click
    /// completes it; with `add` (Shift) a target click adds another target vertex to the selected
    /// pair (one-to-many).
    pub fn click_vertex(&mut self, side: Side, displayed_vertex: u32, add: bool) {
        let Some(slot) = self.slot(side) else { return };
        let f = slot.to_file(displayed_vertex);
        match side {
            Side::Source => {
                self.push_undo();
                self.pending_source = Some(f);
                self.selected = None;
                self.message = format!("source vertex {f}: now click the target");
            }
            Side::Target => {
                if let Some(s) = self.pending_source {
                    self.push_undo();
                    self.corr.push(Correspondence {
                        source_vertex: s,
                        target_vertices: vec![f],
                    });
                    self.pending_source = None;
                    self.selected = Some(Selection {
                        pair: self.corr.len() - 1,
                        side: Side::Target,
                        k: 0,
                    });
                    self.message = format!("pair {} added", self.corr.len());
                    self.schedule_restart_now();
                } else if add && let Some(sel) = self.selected {
                    if self.corr[sel.pair].target_vertices.contains(&f) {
                        return;
                    }
                    self.push_undo();
                    self.corr[sel.pair].target_vertices.push(f);
                    self.selected = Some(Selection {
                        pair: sel.pair,
                        side: Side::Target,
                        k: self.corr[sel.pair].target_vertices.len() - 1,
                    });
                    self.message = format!("target point added to pair {}", sel.pair + 1);
                    self.schedule_restart_now();
                } else {
                    self.message = "click a source point first (Shift-click adds targets to the selected pair)".into();
                }
            }
        }
    }

    /// Select a marker.
    pub fn select(&mut self, sel: Option<Selection>) {
        self.selected = sel.filter(|s| self.marker_exists(*s));
    }

    /// Delete the selected marker: a source marker removes its pair; a target marker removes that
    /// target vertex (and the pair when it was the last). Returns true if something was removed.
    pub fn delete_selected(&mut self) -> bool {
        let Some(sel) = self.selected else {
            if self.pending_source.is_some() {
                self.push_undo();
                self.pending_source = None;
                return true;
            }
            return false;
        };
        if !self.marker_exists(sel) {
            return false;
        }
        self.push_undo();
        let c = &mut self.corr[sel.pair];
        if sel.side == Side::Source || c.target_vertices.len() <= 1 {
            self.corr.remove(sel.pair);
        } else {
            c.target_vertices.remove(sel.k);
        }
        self.selected = None;
        self.schedule_restart_now();
        true
    }

    /// Delete a whole pair by index.
    pub fn delete_pair(&mut self, pair: usize) {
        if pair < self.corr.len() {
            self.push_undo();
            self.corr.remove(pair);
            self.selected = None;
            self.schedule_restart_now();
        }
    }

    /// Move a marker to another displayed vertex. `record` pushes an undo step (true at the start
    /// of a drag, false while it continues).
    pub fn move_marker(&mut self, sel: Selection, displayed_vertex: u32, record: bool) {
        if !self.marker_exists(sel) {
            return;
        }
        let Some(slot) = self.slot(sel.side) else {
            return;
        };
        let f = slot.to_file(displayed_vertex);
        let cur = match sel.side {
            Side::Source => self.corr[sel.pair].source_vertex,
            Side::Target => self.corr[sel.pair].target_vertices[sel.k],
        };
        if cur == f {
            return;
        }
        if record {
            self.push_undo();
        }
        match sel.side {
            Side::Source => self.corr[sel.pair].source_vertex = f,
            Side::Target => self.corr[sel.pair].target_vertices[sel.k] = f,
        }
        // a drag's later moves record no undo step but move the marker
        self.mark_changed();
        self.schedule_restart_now();
    }

    /// The correspondences as a file, with the positions of their vertices on the loaded meshes
    /// (none when a mesh is missing).
    pub fn correspondence_file(&self) -> CorrespondenceFile {
        match (self.slot(Side::Source), self.slot(Side::Target)) {
            (Some(s), Some(t)) => {
                CorrespondenceFile::with_positions(self.corr.clone(), &s.file, &t.file)
            }
            _ => CorrespondenceFile {
                correspondences: self.corr.clone(),
                positions: Vec::new(),
            },
        }
    }

    /// Replace all correspondences by those of a file read from `path`, each first checked
    /// against the loaded meshes by its stored positions ([`CorrespondenceFile::resolve`]): pairs
    /// that point at other vertices than where they were written move to the nearest vertex of
    /// their stored position, and a note says how many.
    pub fn set_correspondence_file(
        &mut self,
        mut file: CorrespondenceFile,
        path: &std::path::Path,
    ) -> Result<()> {
        let source = self.slot(Side::Source).map(|s| s.file.clone());
        let target = self.slot(Side::Target).map(|s| s.file.clone());
        let note = file.resolve(source.as_deref(), target.as_deref(), path);
        self.set_correspondences(file.correspondences)?;
        if let Some(note) = note {
            self.report(format!("warning: {note}"));
        }
        Ok(())
    }

    /// Replace all correspondences (e.g. from a file), as one undoable edit.
    pub fn set_correspondences(&mut self, corr: Vec<Correspondence>) -> Result<()> {
        for (side, verts) in [
            (
                Side::Source,
                corr.iter().map(|c| c.source_vertex).collect::<Vec<_>>(),
            ),
            (
                Side::Target,
                corr.iter()
                    .flat_map(|c| c.target_vertices.iter().copied())
                    .collect(),
            ),
        ] {
            if let Some(slot) = self.slot(side) {
                let n = slot.file.positions.len() as u32;
                if let Some(bad) = verts.iter().find(|&&v| v >= n) {
                    return Err(Error::InvalidInput(format!(
                        "correspondence vertex {bad} out of range for the {side:?} mesh ({n} vertices)"
                    )));
                }
            }
        }
        self.push_undo();
        self.corr = corr;
        self.selected = None;
        self.pending_source = None;
        self.schedule_restart_now();
        Ok(())
    }
}
