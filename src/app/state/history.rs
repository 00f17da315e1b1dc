//! Paint layers, tool previews and the undo history.

use super::*;

#[derive(Clone)]
pub(super) struct Snapshot {
    pub(super) corr: Vec<Correspondence>,
    pub(super) pending_source: Option<u32>,
    pub(super) paint: [Option<Vec<[f32; 4]>>; 2],
    /// Texel layers' tiles (shared with the layer until a stroke touches them).
    pub(super) texels: [Option<paint_layer::TexelTiles>; 2],
    /// Mask layers: per vertex, and the texel one's tiles.
    pub(super) mask: [Option<Vec<[f32; 4]>>; 2],
    pub(super) mask_texels: [Option<paint_layer::TexelTiles>; 2],
    /// A whole mesh replaced by a tool (index in `meshes`, the slot before): undoing puts it back.
    pub(super) slot: Option<(usize, Box<MeshSlot>)>,
}

/// Put a texel layer back to kept tiles (or remove it).
fn restore_texels(
    layer: &mut Option<paint_layer::TexelLayer>,
    tiles: Option<paint_layer::TexelTiles>,
) {
    match (layer.as_mut(), tiles) {
        (Some(l), Some(t)) => {
            if !l.restore(&t) {
                *layer = Some(paint_layer::TexelLayer::from_tiles(&t));
            }
        }
        (None, Some(t)) => *layer = Some(paint_layer::TexelLayer::from_tiles(&t)),
        (Some(_), None) => *layer = None,
        (None, None) => {}
    }
}

/// Brush settings for painting vertex colours.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Brush {
    /// Radius as a fraction of the mesh's bounding radius.
    pub radius: f32,
    /// sRGB colour.
    pub color: [f32; 3],
    /// 1 = hard edge, 0 = fully soft falloff.
    pub hardness: f32,
    /// Remove paint instead of adding it.
    pub eraser: bool,
    /// Paint a ball in space around the picked point, through to surfaces the view does not
    /// see (for masks); otherwise a dab paints only what the view sees under the brush.
    pub through: bool,
    /// Attenuate a dab where the surface turns away from the view.
    pub normal_falloff: bool,
    /// Distance between the dabs of a stroke, as a fraction of the brush's screen radius.
    pub spacing: f32,
    /// Stroke smoothing: 0 follows the pointer, towards 1 the stroke lags behind it and its
    /// path smooths out.
    pub smoothing: f32,
    /// What a click or drag in the view does.
    pub mode: PaintMode,
    /// The layer strokes and fills go into.
    pub target: super::PaintTarget,
    /// A region fill takes the texels (or vertices) whose shown colour differs from the seed's
    /// by at most this in every channel (0..=1).
    pub fill_tolerance: f32,
}

/// What a click or drag in a view does with the Paint tool.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum PaintMode {
    /// Dabs along the drag.
    #[default]
    Brush,
    /// A click takes the colour under the pointer.
    Eyedropper,
    /// A click fills the region of similar colour under the pointer.
    Fill,
    /// A click fills the UV island (chart) under the pointer.
    IslandFill,
}

impl Default for Brush {
    fn default() -> Self {
        Brush {
            radius: 0.08,
            color: [0.9, 0.1, 0.1],
            hardness: 0.5,
            eraser: false,
            through: false,
            normal_falloff: true,
            spacing: 0.25,
            smoothing: 0.0,
            mode: PaintMode::Brush,
            target: super::PaintTarget::Paint,
            fill_tolerance: 0.1,
        }
    }
}

impl<P: AppParams> AppState<P> {
    // ----- correspondences -----

    pub(super) fn snapshot(&self) -> Snapshot {
        Snapshot {
            corr: self.corr.clone(),
            pending_source: self.pending_source,
            // a tool preview is never an undo state: record the paint underneath it
            paint: [0, 1].map(|i| match &self.preview_backup {
                Some((side, _, p)) if side_index(*side) == i => p.clone(),
                _ => self.meshes[i].as_ref().and_then(|s| s.paint.clone()),
            }),
            texels: [0, 1].map(|i| {
                self.meshes[i]
                    .as_ref()
                    .and_then(|s| s.texels.as_ref().map(|l| l.tiles()))
            }),
            mask: [0, 1].map(|i| self.meshes[i].as_ref().and_then(|s| s.mask.clone())),
            mask_texels: [0, 1].map(|i| {
                self.meshes[i]
                    .as_ref()
                    .and_then(|s| s.mask_texels.as_ref().map(|l| l.tiles()))
            }),
            slot: None,
        }
    }

    /// Record the current state for undo (call before an edit).
    pub fn push_undo(&mut self) {
        // every recorded step is a change worth saving
        self.mark_changed();
        self.undo.push(self.snapshot());
        if self.undo.len() > UNDO_LIMIT {
            self.undo.remove(0);
        }
        self.redo.clear();
    }

    pub(super) fn restore(&mut self, s: Snapshot) {
        if let Some((i, mut slot)) = s.slot {
            slot.geometry_dirty = true;
            slot.colors_dirty = true;
            let side = if i == 0 { Side::Source } else { Side::Target };
            self.requests
                .push(Request::SetMesh(side, slot.id, slot.file.clone()));
            self.meshes[i] = Some(*slot);
            // The restored mesh is the answer: no transfer overwrites it.
            self.restart_at = None;
        }
        let corr_changed = s.corr != self.corr;
        self.corr = s.corr;
        self.pending_source = s.pending_source;
        for (i, p) in s.paint.into_iter().enumerate() {
            if let Some(slot) = self.meshes[i].as_mut()
                && slot.paint != p
                // Never apply a layer painted on another version of the mesh.
                && p.as_ref().is_none_or(|l| l.len() == slot.displayed().num_vertices())
            {
                slot.paint = p;
                slot.colors_dirty = true;
            }
        }
        for (i, m) in s.mask.into_iter().enumerate() {
            if let Some(slot) = self.meshes[i].as_mut()
                && slot.mask != m
                && m.as_ref()
                    .is_none_or(|l| l.len() == slot.displayed().num_vertices())
            {
                slot.mask = m;
                slot.colors_dirty = true;
            }
        }
        for (i, (t, m)) in s.texels.into_iter().zip(s.mask_texels).enumerate() {
            if let Some(slot) = self.meshes[i].as_mut() {
                restore_texels(&mut slot.texels, t);
                restore_texels(&mut slot.mask_texels, m);
            }
        }
        if let Some(sel) = self.selected
            && !self.marker_exists(sel)
        {
            self.selected = None;
        }
        if corr_changed {
            self.schedule_restart_now();
        }
    }

    /// Undo the last edit (correspondence or paint stroke); false if there is none.
    pub fn undo(&mut self) -> bool {
        let Some(s) = self.undo.pop() else {
            self.message = "nothing to undo".into();
            return false;
        };
        let mut cur = self.snapshot();
        if let Some((i, _)) = &s.slot {
            cur.slot = self.meshes[*i].clone().map(|m| (*i, Box::new(m)));
        }
        self.redo.push(cur);
        self.restore(s);
        self.mark_changed();
        self.message = format!(
            "undone ({} more undo, {} redo)",
            self.undo.len(),
            self.redo.len()
        );
        true
    }

    /// Redo the last undone edit; false if there is none.
    pub fn redo(&mut self) -> bool {
        let Some(s) = self.redo.pop() else {
            self.message = "nothing to redo".into();
            return false;
        };
        let mut cur = self.snapshot();
        if let Some((i, _)) = &s.slot {
            cur.slot = self.meshes[*i].clone().map(|m| (*i, Box::new(m)));
        }
        self.undo.push(cur);
        self.restore(s);
        self.mark_changed();
        self.message = format!(
            "redone ({} undo, {} more redo)",
            self.undo.len(),
            self.redo.len()
        );
        true
    }

    /// Number of undo and redo steps available.
    pub fn history_len(&self) -> (usize, usize) {
        (self.undo.len(), self.redo.len())
    }

    // ----- painting -----

    /// Paint (or erase) a ball of the brush radius around a point of one side's displayed mesh
    /// (paint through: every surface inside it, seen or not). `record` pushes an undo step
    /// (true at the start of a stroke). Returns the painted vertex (or texel) count.
    pub fn paint_at(&mut self, side: Side, center: [f32; 3], record: bool) -> usize {
        self.paint_dab_at(side, paint_layer::DabAt::Ball(center), record)
    }

    /// Paint coverage per displayed vertex of one side (0 where unpainted).
    pub fn paint_coverage(&self, side: Side) -> Option<Vec<f32>> {
        let slot = self.slot(side)?;
        let n = slot.displayed().num_vertices();
        Some(match slot.paint_per_vertex() {
            Some(p) => p.iter().map(|x| x[3]).collect(),
            None => vec![0.0; n],
        })
    }

    /// Take a finished application's outcome: new colours become the side's paint layer (one
    /// undo step), a new mesh replaces the side without starting a transfer on it.
    pub fn apply_tool_outcome(&mut self, outcome: crate::app::tools::ToolOutcome) {
        use crate::app::tools::ToolOutcome;
        match outcome {
            ToolOutcome::Done(message) => self.message = message,
            ToolOutcome::Uvs(side, id, uvs, message) => {
                let Some(slot) = self.meshes[side_index(side)].as_mut() else {
                    return;
                };
                let m = slot.displayed();
                if slot.id != id || uvs.len() != 3 * m.faces.len() {
                    self.report("the mesh changed while its atlas was laid out; lay it out again");
                    return;
                }
                let mut shown = m.clone();
                shown.uvs = Some(uvs);
                let shown = Arc::new(shown);
                match slot.working {
                    Some(_) => slot.working = Some(shown),
                    None => slot.file = shown,
                }
                slot.geometry_dirty = true;
                slot.colors_dirty = true;
                self.mark_changed();
                self.message = message;
            }
            ToolOutcome::Colors(side, colors, message) => {
                self.end_tool_preview();
                let Some(n) = self.slot(side).map(|s| s.displayed().num_vertices()) else {
                    return;
                };
                if colors.len() != n {
                    self.report("the completed mesh no longer matches the view (it was re-prepared); run it again");
                    return;
                }
                self.push_undo();
                if let Some(slot) = self.meshes[side_index(side)].as_mut() {
                    slot.paint = Some(colors.iter().map(|c| [c[0], c[1], c[2], 1.0]).collect());
                    slot.colors_dirty = true;
                }
                self.message = message;
            }
            ToolOutcome::Mesh(side, mesh, message) => {
                // One undo step puts the replaced mesh back (set_mesh starts a new history, so
                // the step is recorded after it, with the state from before).
                let i = side_index(side);
                let mut before = self.snapshot();
                before.slot = self.meshes[i].clone().map(|m| (i, Box::new(m)));
                // Computed: whatever file it started from no longer holds it (a session saves
                // it beside itself).
                let mut mesh = mesh;
                mesh.path = None;
                self.set_mesh(side, mesh, false);
                if before.slot.is_some() {
                    self.undo.push(before);
                }
                // The result is the answer: do not overwrite it with a transfer.
                self.restart_at = None;
                self.message = message;
            }
            ToolOutcome::Correspondences(pairs, message) => {
                let (ns, nt) = (
                    self.slot(Side::Source)
                        .map(|s| s.file.file_vertex_count.max(s.file.num_vertices())),
                    self.slot(Side::Target)
                        .map(|s| s.file.file_vertex_count.max(s.file.num_vertices())),
                );
                let (Some(ns), Some(nt)) = (ns, nt) else {
                    return;
                };
                let fits = pairs.iter().all(|c| {
                    (c.source_vertex as usize) < ns
                        && c.target_vertices.iter().all(|&t| (t as usize) < nt)
                });
                if !fits {
                    self.report("the meshes changed while the pairs were suggested; suggest again");
                    return;
                }
                if pairs.is_empty() {
                    self.message = message;
                    return;
                }
                self.push_undo();
                self.corr.extend(pairs);
                self.selected = None;
                self.message = message;
                self.schedule_restart_now();
            }
        }
    }

    /// Show a running tool's partial result on one side: `colors` (at least one per displayed
    /// vertex; the first ones are used) replace the displayed colours until the tool ends. The
    /// paint layer underneath is kept aside and comes back with [`AppState::end_tool_preview`];
    /// previews are not undo steps. False when the side is gone or has fewer colours than vertices.
    pub fn show_tool_preview(&mut self, side: Side, colors: &[[f32; 3]]) -> bool {
        let Some(slot) = self.meshes[side_index(side)].as_mut() else {
            return false;
        };
        let n = slot.displayed().num_vertices();
        if colors.len() < n {
            return false;
        }
        if self.preview_backup.is_none() {
            self.preview_backup = Some((side, slot.id, slot.paint.clone()));
        }
        slot.paint = Some(
            colors[..n]
                .iter()
                .map(|c| [c[0], c[1], c[2], 1.0])
                .collect(),
        );
        slot.colors_dirty = true;
        true
    }

    /// Take a tool preview down: the side's paint layer returns to what it was before.
    pub fn end_tool_preview(&mut self) {
        let Some((side, id, paint)) = self.preview_backup.take() else {
            return;
        };
        if let Some(slot) = self.meshes[side_index(side)].as_mut()
            && slot.id == id
        {
            let n = slot.displayed().num_vertices();
            // a re-prepared mesh (other vertices) dropped its paint: keep it dropped
            slot.paint = paint.filter(|p| p.len() == n);
            slot.colors_dirty = true;
        }
    }

    /// The displayed mesh of one side with its displayed colours (paint included), for export.
    pub fn painted_mesh(&self, side: Side) -> Option<TriMesh> {
        let slot = self.slot(side)?;
        let mut m = slot.displayed().clone();
        m.colors = Some(slot.painted_colors());
        m.texture = None;
        m.uvs = None;
        Some(m)
    }
}
