//! The two 3D viewports: GPU resources, camera input, picking, markers and the paint cursor.

use eframe::egui::{self, Color32, Pos2, Rect, Sense, Stroke, Vec2};
use eframe::egui_wgpu;
use eframe::wgpu;
use glam::Vec2 as GVec2;

use super::brush::BrushView;
use super::state::paint_fill::FillKind;
use super::state::paint_layer::{TILE, has_uvs};
use super::state::{AppParams, AppState, PaintMode, Selection, marker_color, side_index};
use crate::correspondence::Side;
use crate::geometry::TriangleBvh;
use crate::render::{
    Camera, DrawStyle, GpuMesh, MarkerInstance, MeshRenderer, PaintSlot, RenderTarget, fov_y, pick,
};

/// What a left-drag does in a viewport.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Tool {
    /// Clicks add/select correspondences; drags orbit (or move a grabbed marker).
    Correspond,
    /// Drags paint with the brush; Alt+drag orbits.
    Paint,
}

/// Per-view GPU resources.
#[derive(Default)]
struct ViewGpu {
    mesh: Option<GpuMesh>,
    target: Option<RenderTarget>,
    texture: Option<egui::TextureId>,
    /// Something changed since the last draw.
    dirty: bool,
    /// The marker spheres last uploaded with the mesh.
    markers: Vec<MarkerInstance>,
    /// Ray-query tree of the uploaded mesh (picking and marker occlusion).
    bvh: Option<TriangleBvh>,
}

/// A correspondence marker as one view sees it.
#[derive(Clone, Copy, Debug)]
struct MarkerView {
    sel: Selection,
    /// Screen position of the marked vertex.
    screen: Pos2,
    /// World position of the marked vertex.
    world: glam::Vec3,
    /// Not hidden behind the mesh.
    visible: bool,
}

/// How near (points) a click must land to an overlay polyline to keep or drop it.
pub const OVERLAY_PICK_RADIUS: f32 = 8.0;

/// The overlay projected into one view.
struct OverlayOnScreen {
    /// Per polyline, per point: screen position and whether it is in sight.
    lines: Vec<Vec<Option<(Pos2, bool)>>>,
    /// Per field arrow: its ends and whether its middle is in sight.
    arrows: Vec<(Pos2, Pos2, bool)>,
}

/// Distance from `p` to the segment `a b` (screen points).
fn point_segment_distance(p: Pos2, a: Pos2, b: Pos2) -> f32 {
    let ab = b - a;
    let l2 = ab.length_sq();
    let t = if l2 > 0.0 {
        ((p - a).dot(ab) / l2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (a + ab * t).distance(p)
}

/// The viewports' state: cameras, GPU resources and interaction.
pub struct Views {
    renderer: Option<MeshRenderer>,
    gpu: [ViewGpu; 2],
    /// Camera of each view (relative to each mesh's bounds).
    pub cameras: [Camera; 2],
    /// Move both views together.
    pub lock_cameras: bool,
    /// Draw triangle edges.
    pub wireframe: bool,
    /// Current tool.
    pub tool: Tool,
    dragging_marker: Option<Selection>,
    painting: bool,
    /// Where the last dab of a stroke was (view and screen position): a stroke's next dabs
    /// are spaced from it, Shift+click draws a straight line from it.
    last_dab: Option<(Side, Pos2)>,
    /// The smoothed pointer of the stroke in progress.
    smoothed: Pos2,
    /// Milliseconds spent painting dabs in the current frame (the frame log prints it).
    pub paint_ms: std::cell::Cell<f32>,
    /// Of `paint_ms`, the milliseconds spent uploading texel tiles this frame.
    pub upload_ms: std::cell::Cell<f32>,
    /// Dabs painted in the current frame (the frame log prints it).
    pub dabs: std::cell::Cell<u32>,
    /// Milliseconds spent encoding+submitting the last redraw of each view.
    pub last_draw_ms: [f32; 2],
    /// Screen rectangles of the two views in the last frame (points).
    pub rects: [Rect; 2],
    /// The view the pointer was last over (where a drop with no pointer position goes).
    pub last_hovered: Option<Side>,
    /// The views are drawn by a software rasteriser (lavapipe): frames are expensive.
    pub software_renderer: bool,
}

impl Default for Views {
    fn default() -> Self {
        Views {
            renderer: None,
            gpu: Default::default(),
            cameras: [Camera::default(); 2],
            lock_cameras: true,
            wireframe: false,
            tool: Tool::Correspond,
            dragging_marker: None,
            painting: false,
            last_dab: None,
            smoothed: Pos2::ZERO,
            paint_ms: std::cell::Cell::new(0.0),
            upload_ms: std::cell::Cell::new(0.0),
            dabs: std::cell::Cell::new(0),
            last_draw_ms: [0.0; 2],
            rects: [Rect::NOTHING; 2],
            last_hovered: None,
            software_renderer: false,
        }
    }
}

/// Marker sphere radius on screen, in points.
const MARKER_RADIUS: f32 = 9.0;

impl Views {
    /// Mark both views for redraw.
    pub fn invalidate(&mut self) {
        for g in &mut self.gpu {
            g.dirty = true;
        }
    }

    /// Reset both cameras to frame their meshes.
    pub fn frame_all(&mut self) {
        for c in &mut self.cameras {
            c.frame_all();
        }
        self.invalidate();
    }

    fn camera_changed(&mut self, from: usize) {
        if self.lock_cameras {
            self.cameras[1 - from] = self.cameras[from];
        }
        self.invalidate();
    }

    /// Upload changed meshes/colours (colour changes write only the colour buffer).
    fn sync_gpu<P: AppParams>(&mut self, rs: &egui_wgpu::RenderState, state: &mut AppState<P>) {
        if self.renderer.is_none() {
            // 4x MSAA on a GPU; a software rasteriser (lavapipe) draws single-sampled, which is
            // several times cheaper and keeps orbiting smooth while a job fills the cores.
            self.software_renderer = rs.adapter.get_info().device_type == wgpu::DeviceType::Cpu;
            let samples = if self.software_renderer { 1 } else { 4 };
            self.renderer = Some(MeshRenderer::new(&rs.device, Some(&rs.adapter), samples));
        }
        let renderer = self.renderer.as_ref().expect("created above");
        for i in 0..2 {
            let g = &mut self.gpu[i];
            match state.meshes[i].as_mut() {
                None => {
                    if g.mesh.take().is_some() {
                        g.dirty = true;
                    }
                    g.bvh = None;
                    g.markers.clear();
                }
                Some(slot) => {
                    if slot.geometry_dirty || g.mesh.is_none() {
                        let cols = slot.shown_colors(&state.layers);
                        let m = slot.displayed();
                        g.mesh = Some(GpuMesh::new(
                            &rs.device,
                            &rs.queue,
                            renderer,
                            m,
                            &cols,
                            slot.shows_texture(),
                        ));
                        g.bvh = Some(TriangleBvh::new(&m.positions, &m.faces));
                        g.markers.clear();
                        slot.geometry_dirty = false;
                        slot.colors_dirty = false;
                        g.dirty = true;
                    } else if slot.colors_dirty {
                        let textured = slot.shows_texture();
                        if let Some(m) = g.mesh.as_mut() {
                            m.update_colors(&rs.queue, &slot.shown_colors(&state.layers), textured);
                        }
                        slot.colors_dirty = false;
                        g.dirty = true;
                    }
                    // The texel layers (paint, mask), tile by tile as strokes change them.
                    let uvs = has_uvs(slot.displayed());
                    let weights = if uvs {
                        state.layers.weights()
                    } else {
                        [1.0; 3]
                    };
                    if let Some(m) = g.mesh.as_mut()
                        && m.set_layers(weights)
                    {
                        g.dirty = true;
                    }
                    for (which, layer) in [
                        (PaintSlot::Paint, slot.texels.as_mut()),
                        (PaintSlot::Mask, slot.mask_texels.as_mut()),
                    ] {
                        match (layer, g.mesh.as_mut()) {
                            (Some(layer), Some(m)) if uvs => {
                                let clock = std::time::Instant::now();
                                if m.set_paint_layer(
                                    &rs.device,
                                    renderer,
                                    which,
                                    layer.width,
                                    layer.height,
                                ) {
                                    layer.mark_all_dirty();
                                }
                                let tiles = layer.take_dirty();
                                for &t in &tiles {
                                    let (rect, bytes) = layer.tile_data(t);
                                    m.write_paint(&rs.queue, which, rect, bytes, (4 * TILE) as u32);
                                }
                                if !tiles.is_empty() {
                                    g.dirty = true;
                                }
                                let ms = clock.elapsed().as_secs_f32() * 1000.0;
                                self.paint_ms.set(self.paint_ms.get() + ms);
                                self.upload_ms.set(self.upload_ms.get() + ms);
                            }
                            (_, Some(m)) if m.paint_layer_size(which).is_some() => {
                                m.clear_paint_layer(&rs.device, renderer, which);
                                g.dirty = true;
                            }
                            _ => {}
                        }
                    }
                }
            }
        }
    }

    /// Draw one view into its texture if needed; returns the egui texture to show.
    fn draw_view(
        &mut self,
        rs: &egui_wgpu::RenderState,
        i: usize,
        size_px: [u32; 2],
    ) -> Option<egui::TextureId> {
        let renderer = self.renderer.as_ref()?;
        let g = &mut self.gpu[i];
        let resized = g
            .target
            .as_ref()
            .is_none_or(|t| t.width != size_px[0] || t.height != size_px[1]);
        if resized {
            let t = RenderTarget::new(&rs.device, renderer, size_px[0], size_px[1]);
            let mut egui_r = rs.renderer.write();
            match g.texture {
                Some(id) => egui_r.update_egui_texture_from_wgpu_texture(
                    &rs.device,
                    &t.view,
                    wgpu::FilterMode::Linear,
                    id,
                ),
                None => {
                    g.texture = Some(egui_r.register_native_texture(
                        &rs.device,
                        &t.view,
                        wgpu::FilterMode::Linear,
                    ))
                }
            }
            g.target = Some(t);
            g.dirty = true;
        }
        if g.dirty {
            let clock = std::time::Instant::now();
            let style = DrawStyle {
                wireframe: self.wireframe,
                ..DrawStyle::default()
            };
            let mut enc = rs.device.create_command_encoder(&Default::default());
            renderer.draw(
                &rs.queue,
                &mut enc,
                g.target.as_ref().expect("created above"),
                g.mesh.as_ref(),
                &self.cameras[i],
                &style,
            );
            rs.queue.submit([enc.finish()]);
            g.dirty = false;
            self.last_draw_ms[i] = clock.elapsed().as_secs_f32() * 1000.0;
        }
        g.texture
    }

    /// Show both viewports side by side in `ui`.
    pub fn show<P: AppParams>(
        &mut self,
        ui: &mut egui::Ui,
        rs: Option<&egui_wgpu::RenderState>,
        state: &mut AppState<P>,
    ) -> Option<(Side, std::path::PathBuf)> {
        if let Some(rs) = rs {
            self.sync_gpu(rs, state);
        }
        let full = ui.available_rect_before_wrap();
        let half = (full.width() - 4.0) * 0.5;
        let rects = [
            Rect::from_min_size(full.min, Vec2::new(half, full.height())),
            Rect::from_min_size(
                Pos2::new(full.min.x + half + 4.0, full.min.y),
                Vec2::new(half, full.height()),
            ),
        ];
        self.rects = rects;
        let mut dropped = None;
        for (i, rect) in rects.into_iter().enumerate() {
            let side = if i == 0 { Side::Source } else { Side::Target };
            let resp = ui.interact(
                rect,
                ui.scope_id().with(("view", i)),
                Sense::click_and_drag(),
            );
            let ppp = ui.ctx().pixels_per_point();
            let size_px = [
                (rect.width() * ppp).round().max(1.0) as u32,
                (rect.height() * ppp).round().max(1.0) as u32,
            ];
            if let Some(rs) = rs {
                self.sync_markers(rs, state, side, rect);
            }
            let tex = rs.and_then(|rs| self.draw_view(rs, i, size_px));
            let painter = ui.painter_at(rect);
            match tex {
                Some(id) => {
                    painter.image(
                        id,
                        rect,
                        Rect::from_min_max(Pos2::ZERO, Pos2::new(1.0, 1.0)),
                        Color32::WHITE,
                    );
                }
                None => {
                    painter.rect_filled(rect, 0.0, Color32::from_gray(40));
                }
            }
            let title = match (side, state.slot(side)) {
                (Side::Source, Some(s)) => format!("Source: {}", mesh_name(s, side)),
                (Side::Target, Some(s)) => format!("Target: {}", mesh_name(s, side)),
                (_, None) => format!("{side:?}: drop a mesh file here or use File > Open"),
            };
            painter.text(
                rect.min + Vec2::new(8.0, 6.0),
                egui::Align2::LEFT_TOP,
                title,
                egui::FontId::proportional(14.0),
                Color32::from_gray(230),
            );
            self.handle_input(ui, &resp, rect, side, state);
            self.draw_overlay(&painter, rect, side, state);
            self.draw_marker_labels(&painter, rect, side, state, tex.is_some());
            if self.tool == Tool::Paint
                && let Some(p) = resp.hover_pos()
            {
                self.draw_brush_cursor(&painter, rect, p, side, state);
            }
            if let Some(pos) = ui.ctx().input(|inp| inp.pointer.hover_pos())
                && rect.contains(pos)
            {
                self.last_hovered = Some(side);
            }
        }
        // Drag-and-drop of files: onto the view under the pointer; when the pointer position is
        // unknown (some platforms report none during a drop), the view last hovered, else the
        // target.
        let files = ui.ctx().input(|inp| inp.raw.dropped_files.clone());
        if let Some(path) = files.into_iter().next().map(|f| f.path().to_path_buf()) {
            let side = ui
                .ctx()
                .input(|inp| inp.pointer.hover_pos())
                .and_then(|pos| {
                    let i = rects.iter().position(|r| r.contains(pos))?;
                    Some(if i == 0 { Side::Source } else { Side::Target })
                })
                .or(self.last_hovered)
                .unwrap_or(Side::Target);
            dropped = Some((side, path));
        }
        ui.allocate_rect(full, Sense::hover());
        dropped
    }

    fn frame_of(
        &self,
        state: &AppState<impl AppParams>,
        side: Side,
    ) -> Option<crate::render::Frame> {
        self.gpu[side_index(side)]
            .mesh
            .as_ref()
            .map(|m| m.frame)
            .or_else(|| {
                state
                    .slot(side)
                    .map(|s| crate::render::Frame::of_points(&s.displayed().positions))
            })
    }

    /// Pick the displayed mesh of `side` under screen position `pos`.
    pub fn pick_at(
        &self,
        state: &AppState<impl AppParams>,
        side: Side,
        rect: Rect,
        pos: Pos2,
    ) -> Option<crate::render::Hit> {
        let slot = state.slot(side)?;
        let frame = self.frame_of(state, side)?;
        let local = GVec2::new(pos.x - rect.min.x, pos.y - rect.min.y);
        let size = GVec2::new(rect.width(), rect.height());
        let (o, d) = self.cameras[side_index(side)].ray(&frame, local, size);
        let m = slot.displayed();
        match &self.gpu[side_index(side)].bvh {
            // The tree of the uploaded mesh: microseconds, and no rayon on the UI thread.
            Some(bvh) => {
                let (face, bary, t) = bvh.ray_hit(o.to_array(), d.to_array())?;
                let f = m.faces[face as usize];
                let k = (0..3).max_by(|&a, &b| bary[a].total_cmp(&bary[b]))?;
                Some(crate::render::Hit {
                    face: face as usize,
                    t,
                    point: o + d * t,
                    nearest_vertex: f[k],
                })
            }
            None => pick(&m.positions, &m.faces, o, d),
        }
    }

    /// Screen position of a file vertex's marker.
    pub fn marker_pos(
        &self,
        state: &AppState<impl AppParams>,
        side: Side,
        rect: Rect,
        file_vertex: u32,
    ) -> Option<Pos2> {
        self.marker_view(state, side, rect, file_vertex)
            .map(|(p, _, _)| p)
    }

    /// Screen and world position of a file vertex's marker, and whether it is in view: not
    /// hidden by the mesh (a ray query on the uploaded mesh), or, before the mesh is on the GPU,
    /// on a surface facing the camera.
    fn marker_view(
        &self,
        state: &AppState<impl AppParams>,
        side: Side,
        rect: Rect,
        file_vertex: u32,
    ) -> Option<(Pos2, glam::Vec3, bool)> {
        let slot = state.slot(side)?;
        let p = glam::Vec3::from(slot.file_vertex_position(file_vertex)?);
        let frame = self.frame_of(state, side)?;
        let size = GVec2::new(rect.width(), rect.height());
        let cam = &self.cameras[side_index(side)];
        let s = cam.project(&frame, p, size)?;
        let (eye, _) = cam.eye_target(&frame);
        let visible = match &self.gpu[side_index(side)].bvh {
            Some(bvh) => {
                let d = p - eye;
                // The marked vertex lies on the surface: only hits clearly in front of it hide it.
                let slack =
                    (self.marker_world_radius(side, &frame, rect, p) / d.length()).clamp(1e-4, 0.5);
                bvh.ray_hit(eye.to_array(), d.to_array())
                    .is_none_or(|(_, _, t)| t >= 1.0 - slack)
            }
            None => slot
                .to_displayed(file_vertex)
                .and_then(|d| slot.normals.get(d as usize))
                .is_none_or(|n| glam::Vec3::from(*n).dot(eye - p) >= 0.0),
        };
        Some((Pos2::new(rect.min.x + s.x, rect.min.y + s.y), p, visible))
    }

    /// World radius that makes a marker at `p` [`MARKER_RADIUS`] points wide on screen.
    fn marker_world_radius(
        &self,
        side: Side,
        frame: &crate::render::Frame,
        rect: Rect,
        p: glam::Vec3,
    ) -> f32 {
        let (eye, target) = self.cameras[side_index(side)].eye_target(frame);
        let forward = (target - eye).normalize_or(glam::Vec3::NEG_Z);
        let depth = (p - eye).dot(forward).max(1e-6);
        let world_per_point =
            2.0 * depth * (fov_y(rect.aspect_ratio()) * 0.5).tan() / rect.height().max(1.0);
        MARKER_RADIUS * world_per_point
    }

    /// All markers of a side as this view sees them.
    fn markers(&self, state: &AppState<impl AppParams>, side: Side, rect: Rect) -> Vec<MarkerView> {
        let mut out = Vec::new();
        for (pair, c) in state.corr.iter().enumerate() {
            for (k, &v) in c.vertices(side).iter().enumerate() {
                if let Some((screen, world, visible)) = self.marker_view(state, side, rect, v) {
                    out.push(MarkerView {
                        sel: Selection { pair, side, k },
                        screen,
                        world,
                        visible,
                    });
                }
            }
        }
        out
    }

    fn marker_under(
        &self,
        state: &AppState<impl AppParams>,
        side: Side,
        rect: Rect,
        pos: Pos2,
    ) -> Option<Selection> {
        self.markers(state, side, rect)
            .into_iter()
            .filter(|m| m.screen.distance(pos) <= MARKER_RADIUS + 2.0)
            .min_by(|a, b| {
                // Prefer markers in view, then the nearest.
                (!a.visible, a.screen.distance(pos))
                    .partial_cmp(&(!b.visible, b.screen.distance(pos)))
                    .unwrap_or(std::cmp::Ordering::Equal)
            })
            .map(|m| m.sel)
    }

    /// Upload the marker spheres of `side` when they changed (which marks the view for redraw).
    fn sync_markers<P: AppParams>(
        &mut self,
        rs: &egui_wgpu::RenderState,
        state: &AppState<P>,
        side: Side,
        rect: Rect,
    ) {
        let i = side_index(side);
        let Some(mesh) = self.gpu[i].mesh.as_ref() else {
            return;
        };
        let frame = mesh.frame;
        let selected_pair = state.selected.map(|s| s.pair);
        let mut instances: Vec<MarkerInstance> = self
            .markers(state, side, rect)
            .into_iter()
            .map(|m| MarkerInstance {
                center: m.world.to_array(),
                radius: self.marker_world_radius(side, &frame, rect, m.world),
                color: marker_color(m.sel.pair).map(|x| x as f32 / 255.0),
                rim: if selected_pair == Some(m.sel.pair) {
                    1.0
                } else {
                    0.0
                },
            })
            .collect();
        if side == Side::Source
            && let Some(v) = state.pending_source
            && let Some((_, world, _)) = self.marker_view(state, side, rect, v)
        {
            instances.push(MarkerInstance {
                center: world.to_array(),
                radius: self.marker_world_radius(side, &frame, rect, world),
                color: marker_color(state.corr.len()).map(|x| x as f32 / 255.0),
                rim: 2.0,
            });
        }
        let g = &mut self.gpu[i];
        if g.markers != instances {
            if let Some(mesh) = g.mesh.as_mut() {
                mesh.set_markers(&rs.device, &rs.queue, &instances);
            }
            g.markers = instances;
            g.dirty = true;
        }
    }

    fn handle_input<P: AppParams>(
        &mut self,
        ui: &egui::Ui,
        resp: &egui::Response,
        rect: Rect,
        side: Side,
        state: &mut AppState<P>,
    ) {
        let i = side_index(side);
        let (mods, primary, middle) = ui.input(|inp| {
            (
                inp.modifiers,
                inp.pointer.button_down(egui::PointerButton::Primary),
                inp.pointer.button_down(egui::PointerButton::Middle),
            )
        });
        // Zoom with the wheel.
        if resp.hovered() {
            let scroll = ui.input(|inp| inp.smooth_scroll_delta.y);
            if scroll != 0.0 {
                self.cameras[i].zoom_by(scroll);
                self.camera_changed(i);
            }
        }
        // Start of a drag: grab a marker, start a paint stroke, or nothing (camera).
        if resp.drag_started_by(egui::PointerButton::Primary)
            && let Some(pos) = resp.interact_pointer_pos()
        {
            if self.tool == Tool::Paint
                && state.brush.mode == PaintMode::Brush
                && !mods.alt
                && !mods.shift
                && !mods.command
            {
                if self.dab(state, side, rect, pos, true) {
                    self.painting = true;
                    self.last_dab = Some((side, pos));
                    self.smoothed = pos;
                }
            } else if !mods.alt
                && !mods.shift
                && let Some(sel) = self.marker_under(
                    state,
                    side,
                    rect,
                    ui.input(|i| i.pointer.press_origin()).unwrap_or(pos),
                )
            {
                state.select(Some(sel));
                self.dragging_marker = Some(sel);
                state.push_undo();
            }
        }
        if resp.dragged() {
            let delta = resp.drag_delta();
            let pos = resp.interact_pointer_pos();
            if let (Some(sel), Some(pos)) = (self.dragging_marker, pos) {
                if let Some(hit) = self.pick_at(state, side, rect, pos) {
                    state.move_marker(sel, hit.nearest_vertex, false);
                }
            } else if self.painting {
                if let Some(pos) = pos {
                    // Smoothing: the stroke follows the pointer part of the way each frame.
                    let k = 1.0 - state.brush.smoothing.clamp(0.0, 0.95);
                    self.smoothed += (pos - self.smoothed) * k;
                    let to = self.smoothed;
                    if let Some((s, from)) = self.last_dab
                        && s == side
                        && let Some(last) = self.dab_line(state, side, rect, from, to, false, false)
                    {
                        self.last_dab = Some((side, last));
                    }
                }
            } else if middle || (primary && mods.shift) {
                self.cameras[i].pan_by(
                    GVec2::new(delta.x, delta.y),
                    GVec2::new(rect.width(), rect.height()),
                );
                self.camera_changed(i);
            } else if primary {
                self.cameras[i].orbit(GVec2::new(delta.x, delta.y));
                self.camera_changed(i);
            }
        }
        if resp.drag_stopped() {
            self.dragging_marker = None;
            self.painting = false;
        }
        // Click on an overlay polyline: the open tool keeps or drops it (before any other click).
        let on_overlay = resp.clicked()
            && !mods.alt
            && !mods.shift
            && resp.interact_pointer_pos().is_some_and(|pos| {
                self.overlay_line_at(rect, side, state, pos)
                    .map(|k| state.overlay_clicked = Some(k))
                    .is_some()
            });
        // Click in Paint mode: one dab (its own undo step); Shift+click a straight line from the
        // last dab; Ctrl+click takes the colour under the pointer (eyedropper).
        if resp.clicked()
            && !on_overlay
            && self.tool == Tool::Paint
            && !mods.alt
            && let Some(pos) = resp.interact_pointer_pos()
        {
            let fill = match state.brush.mode {
                PaintMode::Fill => Some(FillKind::Region),
                PaintMode::IslandFill => Some(FillKind::Island),
                _ => None,
            };
            if mods.command || state.brush.mode == PaintMode::Eyedropper {
                if let Some(hit) = self.pick_at(state, side, rect, pos) {
                    state.pick_color(side, hit.face, hit.point.to_array());
                }
            } else if let Some(kind) = fill {
                let clock = std::time::Instant::now();
                if let Some(hit) = self.pick_at(state, side, rect, pos) {
                    state.fill_at(side, hit.face, hit.point.to_array(), kind);
                }
                self.paint_ms
                    .set(self.paint_ms.get() + clock.elapsed().as_secs_f32() * 1000.0);
            } else if mods.shift {
                if let Some((s, from)) = self.last_dab
                    && s == side
                    && let Some(last) = self.dab_line(state, side, rect, from, pos, true, true)
                {
                    self.last_dab = Some((side, last));
                }
            } else if self.dab(state, side, rect, pos, true) {
                self.last_dab = Some((side, pos));
            }
        }
        // Click: select a marker, or pick a vertex.
        if resp.clicked()
            && !on_overlay
            && self.tool == Tool::Correspond
            && let Some(pos) = resp.interact_pointer_pos()
        {
            if !mods.shift
                && let Some(sel) = self.marker_under(state, side, rect, pos)
            {
                state.select(Some(sel));
            } else if let Some(hit) = self.pick_at(state, side, rect, pos) {
                state.click_vertex(side, hit.nearest_vertex, mods.shift);
            }
        }
    }

    /// The open tool's overlay as this view shows it: per polyline, per point, the screen
    /// position and whether the point is in sight (not hidden by the mesh); per field arrow, its
    /// two ends and whether its middle is in sight. `None` when the overlay is for the other view.
    fn overlay_on_screen<P: AppParams>(
        &self,
        rect: Rect,
        side: Side,
        state: &AppState<P>,
    ) -> Option<OverlayOnScreen> {
        let o = state.overlay.as_ref()?;
        if o.side != Some(side) {
            return None;
        }
        let frame = self.frame_of(state, side)?;
        let size = GVec2::new(rect.width(), rect.height());
        let cam = &self.cameras[side_index(side)];
        let (eye, _) = cam.eye_target(&frame);
        let bvh = self.gpu[side_index(side)].bvh.as_ref();
        let seen = |p: glam::Vec3| {
            bvh.is_none_or(|b| {
                let d = p - eye;
                b.ray_hit(eye.to_array(), d.to_array())
                    .is_none_or(|(_, _, t)| t >= 0.995)
            })
        };
        let to_screen = |p: glam::Vec3| {
            cam.project(&frame, p, size)
                .map(|s| Pos2::new(rect.min.x + s.x, rect.min.y + s.y))
        };
        let lines = o
            .lines
            .iter()
            .map(|(points, _)| {
                points
                    .iter()
                    .map(|&p| {
                        let p = glam::Vec3::from(p);
                        to_screen(p).map(|s| (s, seen(p)))
                    })
                    .collect()
            })
            .collect();
        let arrows = o
            .arrows
            .iter()
            .filter_map(|[a, b]| {
                let (a, b) = (glam::Vec3::from(*a), glam::Vec3::from(*b));
                Some((to_screen(a)?, to_screen(b)?, seen((a + b) * 0.5)))
            })
            .collect();
        Some(OverlayOnScreen { lines, arrows })
    }

    /// Screen position of a point of `side`'s mesh space, and whether the mesh hides it.
    pub fn project_point(
        &self,
        state: &AppState<impl AppParams>,
        side: Side,
        p: [f32; 3],
    ) -> Option<(Pos2, bool)> {
        let rect = self.rects[side_index(side)];
        let frame = self.frame_of(state, side)?;
        let cam = &self.cameras[side_index(side)];
        let p = glam::Vec3::from(p);
        let s = cam.project(&frame, p, GVec2::new(rect.width(), rect.height()))?;
        let (eye, _) = cam.eye_target(&frame);
        let hidden = self.gpu[side_index(side)].bvh.as_ref().is_some_and(|b| {
            b.ray_hit(eye.to_array(), (p - eye).to_array())
                .is_some_and(|(_, _, t)| t < 0.995)
        });
        Some((Pos2::new(rect.min.x + s.x, rect.min.y + s.y), hidden))
    }

    /// The overlay polyline under a click at `pos`: the nearest segment in sight within
    /// [`OVERLAY_PICK_RADIUS`] points.
    fn overlay_line_at<P: AppParams>(
        &self,
        rect: Rect,
        side: Side,
        state: &AppState<P>,
        pos: Pos2,
    ) -> Option<usize> {
        let o = state.overlay.as_ref()?;
        let screen = self.overlay_on_screen(rect, side, state)?;
        let mut best: Option<(f32, usize)> = None;
        for (k, (pts, (_, closed))) in screen.lines.iter().zip(o.lines.iter()).enumerate() {
            let n = pts.len();
            let segs = if *closed { n } else { n.saturating_sub(1) };
            if n == 1
                && let Some((a, true)) = pts[0]
            {
                let d = a.distance(pos);
                if d <= OVERLAY_PICK_RADIUS && best.is_none_or(|(bd, _)| d < bd) {
                    best = Some((d, k));
                }
            }
            for i in 0..segs {
                let (Some((a, va)), Some((b, vb))) = (pts[i], pts[(i + 1) % n]) else {
                    continue;
                };
                if !(va || vb) {
                    continue;
                }
                let d = point_segment_distance(pos, a, b);
                if d <= OVERLAY_PICK_RADIUS && best.is_none_or(|(bd, _)| d < bd) {
                    best = Some((d, k));
                }
            }
        }
        best.map(|(_, k)| k)
    }

    /// The open tool's overlay over this view: kept polylines orange, dropped ones grey, both
    /// faint where the mesh hides them; field arrows cyan where in sight.
    fn draw_overlay<P: AppParams>(
        &self,
        painter: &egui::Painter,
        rect: Rect,
        side: Side,
        state: &AppState<P>,
    ) {
        let (Some(o), Some(screen)) = (
            state.overlay.as_ref(),
            self.overlay_on_screen(rect, side, state),
        ) else {
            return;
        };
        for (a, b, seen) in &screen.arrows {
            if !seen {
                continue;
            }
            let colour = Color32::from_rgb(60, 210, 235);
            painter.line_segment([*a, *b], Stroke::new(1.5, colour));
            // a head at the arrow's end: the field's direction, not only its line
            let d = *b - *a;
            let len = d.length();
            if len > 4.0 {
                let u = d / len;
                let side_v = egui::vec2(-u.y, u.x);
                let h = (0.35 * len).min(5.0);
                let back = *b - u * h;
                painter.line_segment([*b, back + side_v * h * 0.5], Stroke::new(1.5, colour));
                painter.line_segment([*b, back - side_v * h * 0.5], Stroke::new(1.5, colour));
            }
        }
        for (k, (pts, (_, closed))) in screen.lines.iter().zip(o.lines.iter()).enumerate() {
            let kept = o.kept.get(k).copied().unwrap_or(true);
            let n = pts.len();
            let segs = if *closed { n } else { n.saturating_sub(1) };
            for i in 0..segs {
                let (Some((a, va)), Some((b, vb))) = (pts[i], pts[(i + 1) % n]) else {
                    continue;
                };
                let visible = va || vb;
                let colour = match (kept, visible) {
                    (true, true) => Color32::from_rgb(255, 150, 30),
                    (true, false) => Color32::from_rgba_unmultiplied(255, 150, 30, 60),
                    (false, true) => Color32::from_gray(150),
                    (false, false) => Color32::from_rgba_unmultiplied(150, 150, 150, 40),
                };
                let width = if kept && visible { 2.5 } else { 1.5 };
                painter.line_segment([a, b], Stroke::new(width, colour));
            }
        }
    }

    /// Numbers on the marker spheres (faded on hidden ones). Without a GPU view the markers
    /// themselves are drawn here as flat discs.
    fn draw_marker_labels<P: AppParams>(
        &self,
        painter: &egui::Painter,
        rect: Rect,
        side: Side,
        state: &AppState<P>,
        spheres_drawn: bool,
    ) {
        let mut markers = self.markers(state, side, rect);
        // Hidden markers first, the ones in view on top.
        markers.sort_by_key(|m| m.visible);
        for m in markers {
            let alpha = if m.visible { 255 } else { 110 };
            if !spheres_drawn {
                let [r, g, b] = marker_color(m.sel.pair);
                let selected = state.selected.is_some_and(|s| s.pair == m.sel.pair);
                painter.circle(
                    m.screen,
                    MARKER_RADIUS,
                    Color32::from_rgba_unmultiplied(r, g, b, alpha),
                    Stroke::new(
                        if selected { 3.0 } else { 1.5 },
                        if selected {
                            Color32::WHITE
                        } else {
                            Color32::from_black_alpha(alpha)
                        },
                    ),
                );
            }
            painter.text(
                m.screen,
                egui::Align2::CENTER_CENTER,
                format!("{}", m.sel.pair + 1),
                egui::FontId::proportional(11.0),
                Color32::from_black_alpha(alpha),
            );
        }
        if side == Side::Source
            && let Some(v) = state.pending_source
            && let Some(p) = self.marker_pos(state, side, rect, v)
        {
            if !spheres_drawn {
                let [r, g, b] = marker_color(state.corr.len());
                painter.circle(
                    p,
                    MARKER_RADIUS,
                    Color32::from_rgb(r, g, b),
                    Stroke::new(2.0, Color32::YELLOW),
                );
            }
            painter.text(
                p,
                egui::Align2::CENTER_CENTER,
                "?",
                egui::FontId::proportional(11.0),
                Color32::BLACK,
            );
        }
    }

    /// How the view of `side` sees a dab at `pos`; `None` when the pointer is off the mesh.
    pub fn brush_view(
        &self,
        state: &AppState<impl AppParams>,
        side: Side,
        rect: Rect,
        pos: Pos2,
    ) -> Option<BrushView> {
        let hit = self.pick_at(state, side, rect, pos)?;
        let frame = self.frame_of(state, side)?;
        Some(BrushView::new(
            &self.cameras[side_index(side)],
            &frame,
            GVec2::new(rect.width(), rect.height()),
            GVec2::new(pos.x - rect.min.x, pos.y - rect.min.y),
            hit.point,
        ))
    }

    /// Paint one dab at `pos` (`record`: the start of a stroke); false when the pointer is off
    /// the mesh.
    fn dab<P: AppParams>(
        &self,
        state: &mut AppState<P>,
        side: Side,
        rect: Rect,
        pos: Pos2,
        record: bool,
    ) -> bool {
        let clock = std::time::Instant::now();
        let Some(view) = self.brush_view(state, side, rect, pos) else {
            return false;
        };
        state.paint_dab(side, &view, record);
        self.dabs.set(self.dabs.get() + 1);
        self.paint_ms
            .set(self.paint_ms.get() + clock.elapsed().as_secs_f32() * 1000.0);
        true
    }

    /// Dabs from `from` (already painted) towards `to`, [`super::Brush::spacing`] apart on the
    /// screen; with `to_end` the last one lands on `to`, else dabs stop short of it where the
    /// spacing says. `record` makes the first dab start a stroke. Returns the last dab's
    /// position, if any.
    #[allow(clippy::too_many_arguments)]
    fn dab_line<P: AppParams>(
        &self,
        state: &mut AppState<P>,
        side: Side,
        rect: Rect,
        from: Pos2,
        to: Pos2,
        record: bool,
        to_end: bool,
    ) -> Option<Pos2> {
        let frame = self.frame_of(state, side)?;
        let view = self
            .brush_view(state, side, rect, to)
            .or_else(|| self.brush_view(state, side, rect, from))?;
        let r = view.screen_radius((state.brush.radius * frame.radius).max(1e-9));
        let step = (state.brush.spacing.clamp(0.05, 4.0) * r).max(1.0);
        let d = from.distance(to);
        let n = if to_end {
            (d / step).ceil()
        } else {
            (d / step).floor()
        }
        .min(512.0) as usize;
        if n == 0 {
            return None;
        }
        let dir = (to - from) / d.max(1e-6);
        let gap = if to_end { d / n as f32 } else { step };
        let mut last = None;
        for k in 1..=n {
            let p = from + dir * gap * k as f32;
            self.dab(state, side, rect, p, record && last.is_none());
            last = Some(p);
        }
        last
    }

    /// Screen outline of the brush under `pos`: the disc a dab covers; painting through, the
    /// world-space circle of the brush radius in the tangent plane at the picked point, projected
    /// at 32 points. `None` when the pointer is off the mesh.
    pub fn brush_outline(
        &self,
        state: &AppState<impl AppParams>,
        side: Side,
        rect: Rect,
        pos: Pos2,
    ) -> Option<Vec<Pos2>> {
        let hit = self.pick_at(state, side, rect, pos)?;
        let frame = self.frame_of(state, side)?;
        if !state.brush.through {
            // A dab from the view: a disc on the screen.
            let view = self.brush_view(state, side, rect, pos)?;
            let r = view.screen_radius((state.brush.radius * frame.radius).max(1e-9));
            return Some(
                (0..48)
                    .map(|k| {
                        let t = k as f32 * std::f32::consts::TAU / 48.0;
                        pos + Vec2::new(t.cos(), t.sin()) * r
                    })
                    .collect(),
            );
        }
        let m = state.slot(side)?.displayed();
        let [a, b, c] = m.faces[hit.face].map(|v| glam::Vec3::from(m.positions[v as usize]));
        let n = (b - a).cross(c - a).try_normalize()?;
        let (u, w) = n.any_orthonormal_pair();
        // The same radius `paint_at` paints with.
        let r = (state.brush.radius * frame.radius).max(1e-9);
        let size = GVec2::new(rect.width(), rect.height());
        let cam = &self.cameras[side_index(side)];
        (0..32)
            .map(|k| {
                let t = k as f32 * std::f32::consts::TAU / 32.0;
                let p = hit.point + r * (t.cos() * u + t.sin() * w);
                let s = cam.project(&frame, p, size)?;
                Some(Pos2::new(rect.min.x + s.x, rect.min.y + s.y))
            })
            .collect()
    }

    fn draw_brush_cursor<P: AppParams>(
        &self,
        painter: &egui::Painter,
        rect: Rect,
        pos: Pos2,
        side: Side,
        state: &AppState<P>,
    ) {
        let Some(outline) = self.brush_outline(state, side, rect, pos) else {
            return;
        };
        let c = state.brush.color.map(|x| (x * 255.0) as u8);
        let color = if state.brush.eraser {
            Color32::WHITE
        } else {
            Color32::from_rgb(c[0], c[1], c[2])
        };
        painter.add(egui::Shape::closed_line(outline, Stroke::new(1.5, color)));
    }
}

/// A view's title: the file name, or for a built-in scene's mesh its part of the scene's name
/// ("zebra" of "Zebra -> giraffe"); then the vertex count, and the working mesh's once prepared.
fn mesh_name(slot: &super::state::MeshSlot, side: Side) -> String {
    let m = &slot.file;
    let name = match (&m.path, &slot.scene) {
        (Some(p), _) => p
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_else(|| p.display().to_string()),
        (None, Some(scene)) => {
            let part = match (scene.split_once("->"), side) {
                (Some((a, _)), Side::Source) => a,
                (Some((_, b)), Side::Target) => b,
                (None, _) => scene.as_str(),
            };
            format!("{} (built-in)", part.trim().to_lowercase())
        }
        (None, None) => "unsaved mesh".into(),
    };
    match &slot.working {
        Some(w) => format!(
            "{name} ({} vertices, working {})",
            m.positions.len(),
            w.positions.len()
        ),
        None => format!("{name} ({} vertices)", m.positions.len()),
    }
}
