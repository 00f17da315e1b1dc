//! Painting: dabs from a view (projection with a depth test) or in a ball (paint through), into
//! a texel layer at the texture's resolution on a mesh with UVs, else into per-vertex paint.
//!
//! A texel layer is RGBA8 (sRGB colour, coverage) in tiles of [`TILE`]² texels shared by
//! reference: the undo history keeps the tile list of each step, and a stroke copies a tile the
//! first time it touches one, so an undo step costs the tiles a stroke touched, not the layer.
//! Within a stroke each texel keeps the strongest dab weight it received (a stroke mask), laid
//! over the layer as it was when the stroke began: overlapping dabs do not build up, and the
//! stroke's edge is the brush's.

use std::sync::Arc;

use glam::{Vec2, Vec3};

use super::layers::{Layers, PaintTarget};
use super::*;
use crate::app::brush::{BrushView, Dab, ball_vertex_weights, falloff};

/// Side of a tile of a texel layer, in texels.
pub const TILE: usize = 64;
/// Side of a texel layer on a mesh with UVs but no texture.
pub const TEXEL_LAYER_SIZE: u32 = 2048;
/// Largest texel layer side (a larger texture is painted at this size).
pub const MAX_TEXEL_LAYER_SIZE: u32 = 8192;

/// One tile: RGBA8 texels, row-major.
pub type Tile = [[u8; 4]; TILE * TILE];

/// The tiles of a texel layer as an undo step keeps them.
#[derive(Clone)]
pub struct TexelTiles {
    width: u32,
    height: u32,
    tiles: Vec<Arc<Tile>>,
}

/// A stroke in progress: the layer before it, the strongest weight per texel so far and the
/// texels it touched.
struct Stroke {
    base: Vec<Arc<Tile>>,
    mask: Vec<u8>,
    touched: Vec<u32>,
    color: [u8; 3],
    eraser: bool,
}

/// Paint at a texture's resolution: RGBA8 texels in shared tiles (see the module doc).
pub struct TexelLayer {
    /// Width in texels.
    pub width: u32,
    /// Height in texels.
    pub height: u32,
    tiles_x: usize,
    tiles: Vec<Arc<Tile>>,
    /// Tiles changed since the views last uploaded them.
    dirty: Vec<u32>,
    dirty_flag: Vec<bool>,
    stroke: Option<Box<Stroke>>,
}

impl Clone for TexelLayer {
    /// The texels (a stroke in progress is not carried).
    fn clone(&self) -> Self {
        TexelLayer {
            width: self.width,
            height: self.height,
            tiles_x: self.tiles_x,
            tiles: self.tiles.clone(),
            dirty: self.dirty.clone(),
            dirty_flag: self.dirty_flag.clone(),
            stroke: None,
        }
    }
}

/// Composite `w` of `color` over the straight-alpha texel `dst`, in 8 bits.
#[inline]
fn over(dst: [u8; 4], color: [u8; 3], w: f32) -> [u8; 4] {
    let a0 = dst[3] as f32 / 255.0;
    let a = a0 + w * (1.0 - a0);
    if a <= 0.0 {
        return [color[0], color[1], color[2], 0];
    }
    let mut out = [0u8; 4];
    for k in 0..3 {
        let c = (dst[k] as f32 * a0 * (1.0 - w) + color[k] as f32 * w) / a;
        out[k] = c.round().clamp(0.0, 255.0) as u8;
    }
    out[3] = (a * 255.0).round() as u8;
    out
}

impl TexelLayer {
    /// An empty (transparent) layer.
    pub fn new(width: u32, height: u32) -> Self {
        let width = width.clamp(1, MAX_TEXEL_LAYER_SIZE);
        let height = height.clamp(1, MAX_TEXEL_LAYER_SIZE);
        let tiles_x = (width as usize).div_ceil(TILE);
        let n = tiles_x * (height as usize).div_ceil(TILE);
        let empty = Arc::new([[0u8; 4]; TILE * TILE]);
        TexelLayer {
            width,
            height,
            tiles_x,
            tiles: vec![empty; n],
            dirty: (0..n as u32).collect(),
            dirty_flag: vec![true; n],
            stroke: None,
        }
    }

    /// A layer from an RGBA image (colour sRGB, alpha coverage).
    pub fn from_image(img: &image::RgbaImage) -> Self {
        let mut l = TexelLayer::new(img.width(), img.height());
        for (x, y, p) in img.enumerate_pixels() {
            if p.0[3] > 0 {
                l.set(x, y, p.0);
            }
        }
        l
    }

    /// The layer as an RGBA image.
    pub fn to_image(&self) -> image::RgbaImage {
        image::RgbaImage::from_fn(self.width, self.height, |x, y| image::Rgba(self.get(x, y)))
    }

    /// Number of tiles.
    pub fn tile_count(&self) -> usize {
        self.tiles.len()
    }

    #[inline]
    fn locate(&self, x: u32, y: u32) -> (usize, usize) {
        let (x, y) = (x as usize, y as usize);
        (
            (y / TILE) * self.tiles_x + x / TILE,
            (y % TILE) * TILE + x % TILE,
        )
    }

    /// The texel at `(x, y)` (row 0 at the top).
    #[inline]
    pub fn get(&self, x: u32, y: u32) -> [u8; 4] {
        let (t, i) = self.locate(x, y);
        self.tiles[t][i]
    }

    fn mark(&mut self, t: usize) {
        if !self.dirty_flag[t] {
            self.dirty_flag[t] = true;
            self.dirty.push(t as u32);
        }
    }

    /// Set one texel.
    pub fn set(&mut self, x: u32, y: u32, v: [u8; 4]) {
        let (t, i) = self.locate(x, y);
        Arc::make_mut(&mut self.tiles[t])[i] = v;
        self.mark(t);
    }

    /// Whether any texel has paint.
    pub fn is_empty(&self) -> bool {
        self.tiles.iter().all(|t| t.iter().all(|p| p[3] == 0))
    }

    /// The tiles as they are now (shared, for the undo history).
    pub fn tiles(&self) -> TexelTiles {
        TexelTiles {
            width: self.width,
            height: self.height,
            tiles: self.tiles.clone(),
        }
    }

    /// Put back tiles kept by [`Self::tiles`]; false (and nothing changes) if they belong to a
    /// layer of another size.
    pub fn restore(&mut self, t: &TexelTiles) -> bool {
        if t.width != self.width || t.height != self.height || t.tiles.len() != self.tiles.len() {
            return false;
        }
        for i in 0..self.tiles.len() {
            if !Arc::ptr_eq(&self.tiles[i], &t.tiles[i]) {
                self.tiles[i] = t.tiles[i].clone();
                self.mark(i);
            }
        }
        self.stroke = None;
        true
    }

    /// A layer from kept tiles.
    pub fn from_tiles(t: &TexelTiles) -> Self {
        let mut l = TexelLayer::new(t.width, t.height);
        l.tiles = t.tiles.clone();
        l
    }

    /// Tiles changed since the last call (the views upload them).
    pub fn take_dirty(&mut self) -> Vec<u32> {
        for &t in &self.dirty {
            self.dirty_flag[t as usize] = false;
        }
        std::mem::take(&mut self.dirty)
    }

    /// Mark every tile changed (a new upload of the whole layer).
    pub fn mark_all_dirty(&mut self) {
        for t in 0..self.tiles.len() {
            self.mark(t);
        }
    }

    /// A tile's rectangle in the layer (x, y, width, height) and its texels (rows of [`TILE`]).
    pub fn tile_data(&self, t: u32) -> ([u32; 4], &[u8]) {
        let t = t as usize;
        let x = ((t % self.tiles_x) * TILE) as u32;
        let y = ((t / self.tiles_x) * TILE) as u32;
        let w = (self.width - x).min(TILE as u32);
        let h = (self.height - y).min(TILE as u32);
        (
            [x, y, w, h],
            bytemuck::cast_slice::<[u8; 4], u8>(&self.tiles[t][..]),
        )
    }

    /// Start a stroke of `color` (sRGB), or of the eraser.
    pub fn begin_stroke(&mut self, color: [f32; 3], eraser: bool) {
        let n = (self.width * self.height) as usize;
        let (mut mask, mut touched) = match self.stroke.take() {
            Some(s) => (s.mask, s.touched),
            None => (Vec::new(), Vec::new()),
        };
        if mask.len() != n {
            mask = vec![0; n];
            touched.clear();
        }
        for &t in &touched {
            mask[t as usize] = 0;
        }
        touched.clear();
        self.stroke = Some(Box::new(Stroke {
            base: self.tiles.clone(),
            mask,
            touched,
            color: color.map(|c| (c.clamp(0.0, 1.0) * 255.0).round() as u8),
            eraser,
        }));
    }

    /// Whether a stroke is in progress.
    pub fn in_stroke(&self) -> bool {
        self.stroke.is_some()
    }

    /// Whether texel `(x, y)` has the full weight of the current stroke already.
    #[inline]
    pub fn saturated(&self, x: u32, y: u32) -> bool {
        self.stroke
            .as_ref()
            .is_some_and(|s| s.mask[(y * self.width + x) as usize] == 255)
    }

    /// Give texel `(x, y)` at least `weight` of the current stroke; true when it changed.
    pub fn stamp(&mut self, x: u32, y: u32, weight: f32) -> bool {
        let Some(s) = self.stroke.as_mut() else {
            return false;
        };
        let i = (y * self.width + x) as usize;
        let m = (weight.clamp(0.0, 1.0) * 255.0).round() as u8;
        if m <= s.mask[i] {
            return false;
        }
        if s.mask[i] == 0 {
            s.touched.push(i as u32);
        }
        s.mask[i] = m;
        let (t, k) = (
            (y as usize / TILE) * self.tiles_x + x as usize / TILE,
            (y as usize % TILE) * TILE + x as usize % TILE,
        );
        let base = s.base[t][k];
        let w = m as f32 / 255.0;
        let v = if s.eraser {
            let a = (base[3] as f32 * (1.0 - w)).round() as u8;
            [base[0], base[1], base[2], a]
        } else {
            over(base, s.color, w)
        };
        Arc::make_mut(&mut self.tiles[t])[k] = v;
        self.mark(t);
        true
    }

    /// Bilinear sample at UV `(u, v)` (V up; outside `[0, 1]` the layer repeats, its edges
    /// clamp): straight sRGB colour and coverage, the colours weighted by coverage (unpainted
    /// texels do not darken the edge of a stroke).
    pub fn sample(&self, uv: [f32; 2]) -> [f32; 4] {
        let (w, h) = (self.width as f32, self.height as f32);
        let wrap = |t: f32| {
            if (0.0..=1.0).contains(&t) {
                t
            } else {
                t.rem_euclid(1.0)
            }
        };
        let x = wrap(uv[0]) * w - 0.5;
        let y = (1.0 - wrap(uv[1])) * h - 0.5;
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let mut acc = [0.0f32; 4];
        for (dx, dy, wt) in [
            (0, 0, (1.0 - fx) * (1.0 - fy)),
            (1, 0, fx * (1.0 - fy)),
            (0, 1, (1.0 - fx) * fy),
            (1, 1, fx * fy),
        ] {
            let xi = (x0 as i64 + dx).clamp(0, self.width as i64 - 1) as u32;
            let yi = (y0 as i64 + dy).clamp(0, self.height as i64 - 1) as u32;
            let p = self.get(xi, yi);
            let a = p[3] as f32 / 255.0 * wt;
            for k in 0..3 {
                acc[k] += p[k] as f32 / 255.0 * a;
            }
            acc[3] += a;
        }
        let a = acc[3];
        if a > 0.0 {
            for c in acc.iter_mut().take(3) {
                *c /= a;
            }
        }
        acc
    }

    /// The paint per vertex of `mesh` (whose UVs it was painted through): the mean of the
    /// samples at the vertex's corners.
    pub fn per_vertex(&self, mesh: &TriMesh) -> Option<Vec<[f32; 4]>> {
        let uvs = mesh
            .uvs
            .as_ref()
            .filter(|u| u.len() == 3 * mesh.faces.len())?;
        let n = mesh.positions.len();
        let mut sum = vec![[0.0f32; 5]; n];
        for (f, face) in mesh.faces.iter().enumerate() {
            for (k, &v) in face.iter().enumerate() {
                let Some(s) = sum.get_mut(v as usize) else {
                    continue;
                };
                let p = self.sample(uvs[3 * f + k]);
                for c in 0..3 {
                    s[c] += p[c] * p[3];
                }
                s[3] += p[3];
                s[4] += 1.0;
            }
        }
        Some(
            sum.into_iter()
                .map(|s| {
                    if s[4] == 0.0 || s[3] <= 0.0 {
                        return [0.0; 4];
                    }
                    [s[0] / s[3], s[1] / s[3], s[2] / s[3], s[3] / s[4]]
                })
                .collect(),
        )
    }
}

/// Write a texel layer as an RGBA PNG (atomically: a reader sees the old file or the new one).
pub fn save_texel_layer(layer: &TexelLayer, path: &std::path::Path) -> Result<()> {
    let mut bytes = Vec::new();
    layer
        .to_image()
        .write_to(
            &mut std::io::Cursor::new(&mut bytes),
            image::ImageFormat::Png,
        )
        .map_err(|e| Error::format(path, format!("PNG encoding failed: {e}")))?;
    crate::mesh::io::write_atomic(path, &bytes)
}

/// Read a texel layer written by [`save_texel_layer`].
pub fn load_texel_layer(path: &std::path::Path) -> Result<TexelLayer> {
    let meta = std::fs::metadata(path).map_err(|e| Error::io(path, e))?;
    if !meta.is_file() {
        return Err(Error::format(path, "the paint layer is not a regular file"));
    }
    let img = image::ImageReader::open(path)
        .map_err(|e| Error::io(path, e))?
        .with_guessed_format()
        .map_err(|e| Error::io(path, e))?
        .decode()
        .map_err(|e| Error::format(path, format!("cannot decode the paint layer: {e}")))?;
    let (w, h) = (img.width(), img.height());
    if w > MAX_TEXEL_LAYER_SIZE || h > MAX_TEXEL_LAYER_SIZE {
        return Err(Error::format(
            path,
            format!("a paint layer of {w}x{h} texels is larger than {MAX_TEXEL_LAYER_SIZE}²"),
        ));
    }
    Ok(TexelLayer::from_image(&img.to_rgba8()))
}

/// An empty texel layer for `mesh`: its texture's size, else [`TEXEL_LAYER_SIZE`]².
pub fn new_layer_for(mesh: &TriMesh) -> TexelLayer {
    let (w, h) = mesh
        .texture
        .as_ref()
        .map(|t| t.image.dimensions())
        .unwrap_or((TEXEL_LAYER_SIZE, TEXEL_LAYER_SIZE));
    TexelLayer::new(w, h)
}

/// Whether `mesh` has per-corner UVs a texel layer can be painted through.
pub fn has_uvs(mesh: &TriMesh) -> bool {
    mesh.uvs
        .as_ref()
        .is_some_and(|u| u.len() == 3 * mesh.faces.len() && !mesh.faces.is_empty())
}

/// Visit the texels of `width`×`height` that faces of `mesh` cover through its UVs: every texel
/// whose centre lies in a face's UV triangle or within one texel of it (so that filtering at a
/// chart's border reads painted texels), with the face and the barycentric coordinates of the
/// nearest point of the face. `keep` culls faces and parts of faces by their world corners;
/// faces larger than 32² texels are split in four until they are not (or `keep` drops them).
pub fn for_texels(
    mesh: &TriMesh,
    width: u32,
    height: u32,
    faces: impl Iterator<Item = usize>,
    keep: &dyn Fn([Vec3; 3]) -> bool,
    visit: &mut dyn FnMut(u32, u32, usize, [f32; 3]),
) {
    let Some(uvs) = mesh
        .uvs
        .as_ref()
        .filter(|u| u.len() == 3 * mesh.faces.len())
    else {
        return;
    };
    let (w, h) = (width as f32, height as f32);
    let eye = [Vec3::X, Vec3::Y, Vec3::Z];
    let mut stack: Vec<([Vec3; 3], u32)> = Vec::new();
    for f in faces {
        let corners = mesh.faces[f].map(|v| Vec3::from(mesh.positions[v as usize]));
        let tex = [0, 1, 2].map(|k| {
            let t = uvs[3 * f + k];
            Vec2::new(t[0] * w, (1.0 - t[1]) * h)
        });
        if !tex.iter().all(|t| t.is_finite()) {
            continue;
        }
        stack.clear();
        stack.push((eye, 0));
        while let Some((bary, depth)) = stack.pop() {
            let world = bary.map(|b| corners[0] * b.x + corners[1] * b.y + corners[2] * b.z);
            if !keep(world) {
                continue;
            }
            let t = bary.map(|b| tex[0] * b.x + tex[1] * b.y + tex[2] * b.z);
            let lo = t[0].min(t[1]).min(t[2]);
            let hi = t[0].max(t[1]).max(t[2]);
            let ext = hi - lo;
            if ext.x * ext.y > 1024.0 && depth < 10 {
                let m = [
                    (bary[0] + bary[1]) * 0.5,
                    (bary[1] + bary[2]) * 0.5,
                    (bary[2] + bary[0]) * 0.5,
                ];
                stack.push(([bary[0], m[0], m[2]], depth + 1));
                stack.push(([m[0], bary[1], m[1]], depth + 1));
                stack.push(([m[2], m[1], bary[2]], depth + 1));
                stack.push(([m[0], m[1], m[2]], depth + 1));
                continue;
            }
            raster_uv(t, width, height, &mut |x, y, l| {
                let b = bary[0] * l[0] + bary[1] * l[1] + bary[2] * l[2];
                visit(x, y, f, b.to_array());
            });
        }
    }
}

/// Texels of a `width`×`height` image within one texel of the triangle `t` (texel units, row 0
/// at the top), with the barycentric coordinates of the nearest point of the triangle.
fn raster_uv(t: [Vec2; 3], width: u32, height: u32, visit: &mut dyn FnMut(u32, u32, [f32; 3])) {
    let area = (t[1] - t[0]).perp_dot(t[2] - t[0]);
    if area.abs() < 1e-12 {
        return;
    }
    let inv = 1.0 / area;
    // Distance (texels) per unit of each barycentric coordinate: twice the area over the
    // opposite edge's length.
    let edge = [t[2] - t[1], t[0] - t[2], t[1] - t[0]];
    let scale = edge.map(|e| area.abs() / e.length().max(1e-12));
    let lo = t[0].min(t[1]).min(t[2]) - Vec2::ONE;
    let hi = t[0].max(t[1]).max(t[2]) + Vec2::ONE;
    let x0 = (lo.x - 0.5).ceil().max(0.0) as i64;
    let y0 = (lo.y - 0.5).ceil().max(0.0) as i64;
    let x1 = ((hi.x - 0.5).floor() as i64).min(width as i64 - 1);
    let y1 = ((hi.y - 0.5).floor() as i64).min(height as i64 - 1);
    for y in y0..=y1 {
        for x in x0..=x1 {
            let p = Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
            let l1 = (p - t[0]).perp_dot(t[2] - t[0]) * inv;
            let l2 = (t[1] - t[0]).perp_dot(p - t[0]) * inv;
            let l = [1.0 - l1 - l2, l1, l2];
            if (0..3).any(|k| l[k] * scale[k] < -1.0) {
                continue;
            }
            let mut c = l.map(|v| v.max(0.0));
            let s = c[0] + c[1] + c[2];
            if s <= 0.0 {
                continue;
            }
            c = c.map(|v| v / s);
            visit(x as u32, y as u32, c);
        }
    }
}

// ----- layers on a slot (see `super::layers`) -----

impl MeshSlot {
    /// The vertex colours a view draws. Without UVs, every layer is composited here (the
    /// vertex paint is the paint layer). With UVs, the result alone (its colours with the
    /// vertex layer over them, applications' outcomes land there); the view composites the
    /// result's weight and the texel layers per pixel.
    pub fn shown_colors(&self, layers: &Layers) -> Vec<[f32; 3]> {
        if has_uvs(self.displayed()) {
            return self.display_colors();
        }
        let [wr, wp, wm] = layers.weights();
        let none = [0.0f32; 4];
        (0..self.base_colors.len())
            .map(|v| {
                let c = super::layers::result_shown(self.base_colors[v], wr);
                let p = self.paint.as_ref().and_then(|p| p.get(v)).unwrap_or(&none);
                let m = self.mask.as_ref().and_then(|m| m.get(v)).unwrap_or(&none);
                super::layers::over(super::layers::over(c, *p, wp), *m, wm)
            })
            .collect()
    }

    /// The vertex and texel layers the brush paints into for `target`.
    pub fn target_layers(
        &mut self,
        target: PaintTarget,
    ) -> (&mut Option<Vec<[f32; 4]>>, &mut Option<TexelLayer>) {
        match target {
            PaintTarget::Paint => (&mut self.paint, &mut self.texels),
            PaintTarget::Mask => (&mut self.mask, &mut self.mask_texels),
        }
    }

    /// Mask coverage per displayed vertex (the texel mask sampled at the vertices over the
    /// vertex mask); `None` when the slot has no mask paint.
    pub fn mask_per_vertex(&self) -> Option<Vec<[f32; 4]>> {
        let texel = self
            .mask_texels
            .as_ref()
            .and_then(|l| l.per_vertex(self.displayed()));
        stack_per_vertex(self.mask.as_ref(), texel)
    }
}

impl<P: AppParams> AppState<P> {
    /// The region exemplar painting acts on, per displayed vertex of one side: the mask's
    /// coverage when the mask has paint, else the paint's (0 where unpainted).
    pub fn region_coverage(&self, side: Side) -> Option<Vec<f32>> {
        let slot = self.slot(side)?;
        match slot.mask_per_vertex() {
            Some(m) if m.iter().any(|c| c[3] > 0.0) => Some(m.iter().map(|c| c[3]).collect()),
            _ => self.paint_coverage(side),
        }
    }
}

/// A vertex layer with a texel layer sampled at the vertices over it (straight colour and
/// coverage per vertex); `None` when there is neither.
pub fn stack_per_vertex(
    vertex: Option<&Vec<[f32; 4]>>,
    texel: Option<Vec<[f32; 4]>>,
) -> Option<Vec<[f32; 4]>> {
    match (vertex, texel) {
        (None, None) => None,
        (Some(p), None) => Some(p.clone()),
        (None, Some(t)) => Some(t),
        (Some(p), Some(t)) => Some(
            p.iter()
                .zip(&t)
                .map(|(v, t)| {
                    let a = t[3] + v[3] * (1.0 - t[3]);
                    if a <= 0.0 {
                        return [0.0; 4];
                    }
                    let c = [0, 1, 2].map(|k| (t[k] * t[3] + v[k] * v[3] * (1.0 - t[3])) / a);
                    [c[0], c[1], c[2], a]
                })
                .collect(),
        ),
    }
}

/// Where a dab is: seen from a view, or a ball in space (paint through).
#[derive(Clone, Copy, Debug)]
pub enum DabAt {
    /// Projected from a view, with a depth test.
    View(BrushView),
    /// A ball of the brush radius around a point.
    Ball([f32; 3]),
}

impl MeshSlot {
    /// The paint per displayed vertex: the vertex layer with the texel layer sampled at the
    /// vertices over it (what the applications read at their working resolution).
    pub fn paint_per_vertex(&self) -> Option<Vec<[f32; 4]>> {
        let texel = self
            .texels
            .as_ref()
            .and_then(|l| l.per_vertex(self.displayed()));
        stack_per_vertex(self.paint.as_ref(), texel)
    }

    /// Colours with all paint composited per vertex (the texel layer sampled at the vertices).
    pub fn painted_colors(&self) -> Vec<[f32; 3]> {
        match self.paint_per_vertex() {
            None => self.base_colors.clone(),
            Some(p) => self
                .base_colors
                .iter()
                .zip(&p)
                .map(|(b, p)| [0, 1, 2].map(|k| b[k] * (1.0 - p[3]) + p[k] * p[3]))
                .collect(),
        }
    }

    /// The displayed mesh with its texture at the texel layers' resolution, the layers shown
    /// as `layers` says (see [`super::layers`]): the result (the mesh's own texture, else its
    /// colours with the vertex layer baked through the UVs) over the hidden-result grey, the
    /// paint over it, the mask over that; for export. `None` without a texel layer or UVs.
    pub fn painted_texture_mesh(&self, layers: &Layers) -> Option<TriMesh> {
        let size = self.texels.as_ref().or(self.mask_texels.as_ref())?;
        let m = self.displayed();
        if !has_uvs(m) {
            return None;
        }
        let (w, h) = (size.width, size.height);
        let mut img = image::RgbImage::new(w, h);
        match (&m.texture, self.shows_texture()) {
            (Some(t), true) => {
                img = if t.image.dimensions() == (w, h) {
                    t.image.clone()
                } else {
                    image::imageops::resize(&t.image, w, h, image::imageops::FilterType::Triangle)
                };
            }
            _ => {
                let cols = self.display_colors();
                for_texels(m, w, h, 0..m.faces.len(), &|_| true, &mut |x, y, f, b| {
                    let face = m.faces[f];
                    let c = [0, 1, 2].map(|k| {
                        (0..3)
                            .map(|j| b[j] * cols[face[j] as usize][k])
                            .sum::<f32>()
                    });
                    img.put_pixel(x, y, image::Rgb(c.map(|v| (v * 255.0).round() as u8)));
                });
            }
        }
        let [wr, wp, wm] = layers.weights();
        let stack: Vec<(&TexelLayer, f32)> = [(&self.texels, wp), (&self.mask_texels, wm)]
            .into_iter()
            .filter_map(|(l, wt)| {
                l.as_ref()
                    .filter(|l| wt > 0.0 && (l.width, l.height) == (w, h))
                    .map(|l| (l, wt))
            })
            .collect();
        for (x, y, px) in img.enumerate_pixels_mut() {
            let mut c = px.0.map(|v| v as f32 / 255.0);
            if wr < 1.0 {
                c = super::layers::result_shown(c, wr);
            }
            for (l, wt) in &stack {
                let p = l.get(x, y);
                if p[3] > 0 {
                    let p = [0, 1, 2, 3].map(|k| p[k] as f32 / 255.0);
                    c = super::layers::over(c, p, *wt);
                }
            }
            px.0 = c.map(|v| (v * 255.0).round().clamp(0.0, 255.0) as u8);
        }
        let mut out = m.clone();
        out.colors = None;
        out.texture = Some(Arc::new(crate::mesh::Texture {
            image: img,
            path: None,
        }));
        Some(out)
    }
}

impl<P: AppParams> AppState<P> {
    /// The displayed mesh of one side with its paint, for "Export painted mesh": with a texel
    /// layer, its UVs and a texture at the layer's resolution; otherwise vertex colours. Either
    /// way it carries what the view shows: the visible layers at their opacities.
    pub fn painted_export_mesh(&self, side: Side) -> Option<TriMesh> {
        self.slot(side)
            .and_then(|s| s.painted_texture_mesh(&self.layers))
            .or_else(|| {
                let mut m = self.painted_mesh(side)?;
                m.colors = self.slot(side).map(|s| s.shown_colors(&self.layers));
                Some(m)
            })
    }

    /// The colour the view shows at `point` of face `face` of one side's displayed mesh
    /// (sRGB, unshaded): its texture or colours with the paint over them. The eyedropper.
    pub fn color_at(&self, side: Side, face: usize, point: [f32; 3]) -> Option<[f32; 3]> {
        let slot = self.slot(side)?;
        let m = slot.displayed();
        let f = *m.faces.get(face)?;
        let corners = f.map(|v| m.positions.get(v as usize).copied());
        let [Some(a), Some(b), Some(c)] = corners else {
            return None;
        };
        let bary = barycentric(Vec3::from(point), [a, b, c].map(Vec3::from));
        let uv = m.uvs.as_ref().filter(|_| has_uvs(m)).map(|u| {
            (0..3).fold([0.0f32; 2], |acc, k| {
                let t = u[3 * face + k];
                [acc[0] + bary[k] * t[0], acc[1] + bary[k] * t[1]]
            })
        });
        let [wr, wp, wm] = self.layers.weights();
        let textured = uv.is_some();
        let cols = if textured {
            slot.display_colors()
        } else {
            slot.shown_colors(&self.layers)
        };
        let mut col = match (&m.texture, uv, slot.shows_texture()) {
            (Some(t), Some(uv), true) => crate::mesh::sample_texture(t, uv),
            _ => [0, 1, 2].map(|k| {
                (0..3)
                    .map(|j| bary[j] * cols.get(f[j] as usize).map_or(0.0, |c| c[k]))
                    .sum::<f32>()
            }),
        };
        if let Some(uv) = uv {
            col = super::layers::result_shown(col, wr);
            for (l, wt) in [(slot.texels.as_ref(), wp), (slot.mask_texels.as_ref(), wm)] {
                if let Some(l) = l {
                    col = super::layers::over(col, l.sample(uv), wt);
                }
            }
        }
        Some(col.map(|x| x.clamp(0.0, 1.0)))
    }

    /// Take the colour at a surface point as the brush colour (see [`Self::color_at`]).
    pub fn pick_color(&mut self, side: Side, face: usize, point: [f32; 3]) -> bool {
        match self.color_at(side, face, point) {
            Some(c) => {
                self.brush.color = c;
                self.brush.eraser = false;
                self.message = format!(
                    "picked colour #{:02x}{:02x}{:02x}",
                    (c[0] * 255.0).round() as u8,
                    (c[1] * 255.0).round() as u8,
                    (c[2] * 255.0).round() as u8
                );
                true
            }
            None => false,
        }
    }

    /// Paint one dab from a view with the current brush: only what the view sees, or, with
    /// [`Brush::through`], a ball around the picked point. `record` starts a stroke (one undo
    /// step). Returns the number of vertices or texels painted.
    pub fn paint_dab(&mut self, side: Side, view: &BrushView, record: bool) -> usize {
        if self.brush.through {
            self.paint_dab_at(side, DabAt::Ball(view.hit.to_array()), record)
        } else {
            self.paint_dab_at(side, DabAt::View(*view), record)
        }
    }

    /// Paint one dab (see [`DabAt`]); into the side's texel layer when its displayed mesh has
    /// UVs, else into its vertex paint.
    pub fn paint_dab_at(&mut self, side: Side, at: DabAt, record: bool) -> usize {
        let brush = self.brush;
        if record && self.slot(side).is_some() {
            self.push_undo();
            if !brush.eraser {
                remember_color(&mut self.color_history, brush.color);
            }
        }
        let Some(slot) = self.slot_mut(side) else {
            return 0;
        };
        let mesh: Arc<TriMesh> = slot.working.clone().unwrap_or_else(|| slot.file.clone());
        let frame = crate::render::Frame::of_points(&mesh.positions);
        let r_world = (brush.radius * frame.radius).max(1e-9);
        let normals = std::mem::take(&mut slot.normals);
        let count = if has_uvs(&mesh) {
            let layer = slot
                .target_layers(brush.target)
                .1
                .get_or_insert_with(|| new_layer_for(&mesh));
            if record || !layer.in_stroke() {
                layer.begin_stroke(brush.color, brush.eraser);
            }
            texel_dab(layer, &mesh, &normals, at, &brush, r_world, frame.radius)
        } else {
            let weights = match at {
                DabAt::Ball(c) => {
                    ball_vertex_weights(&mesh.positions, Vec3::from(c), r_world, brush.hardness)
                }
                DabAt::View(view) => {
                    let dab = Dab::new(
                        view,
                        view.screen_radius(r_world),
                        brush.hardness,
                        brush.normal_falloff,
                        &mesh.positions,
                        &mesh.faces,
                        frame.radius,
                    );
                    dab.vertex_weights(&mesh.positions, &normals)
                }
            };
            let n = mesh.positions.len();
            let paint = slot
                .target_layers(brush.target)
                .0
                .get_or_insert_with(|| vec![[0.0; 4]; n]);
            for &(v, w) in &weights {
                let dst = &mut paint[v as usize];
                if brush.eraser {
                    dst[3] *= 1.0 - w;
                } else {
                    let a = dst[3] + w * (1.0 - dst[3]);
                    for k in 0..3 {
                        dst[k] = if a > 0.0 {
                            (dst[k] * dst[3] * (1.0 - w) + brush.color[k] * w) / a
                        } else {
                            brush.color[k]
                        };
                    }
                    dst[3] = a;
                }
            }
            slot.colors_dirty = true;
            weights.len()
        };
        slot.normals = normals;
        if count > 0 {
            // a stroke's later dabs record no undo step but change the paint
            self.mark_changed();
        }
        count
    }
}

/// Barycentric coordinates of `p` (projected onto the triangle's plane) in the triangle `t`.
pub(super) fn barycentric(p: Vec3, t: [Vec3; 3]) -> [f32; 3] {
    let (e1, e2, d) = (t[1] - t[0], t[2] - t[0], p - t[0]);
    let (d11, d12, d22) = (e1.dot(e1), e1.dot(e2), e2.dot(e2));
    let (d1, d2) = (d.dot(e1), d.dot(e2));
    let den = d11 * d22 - d12 * d12;
    if den.abs() < 1e-20 {
        return [1.0, 0.0, 0.0];
    }
    let v = (d22 * d1 - d12 * d2) / den;
    let w = (d11 * d2 - d12 * d1) / den;
    [1.0 - v - w, v, w]
}

/// Most colours kept in the colour history.
pub const COLOR_HISTORY: usize = 10;

/// Put `c` first in the colour history (once).
pub(super) fn remember_color(history: &mut Vec<[f32; 3]>, c: [f32; 3]) {
    history.retain(|h| h != &c);
    history.insert(0, c);
    history.truncate(COLOR_HISTORY);
}

/// Threads that compute a dab's texels for the UI thread: a pool of their own at the window's
/// priority, so that a transfer filling rayon's global pool (at a lower priority) does not
/// delay a dab.
fn paint_pool() -> Option<&'static rayon::ThreadPool> {
    static POOL: std::sync::OnceLock<Option<rayon::ThreadPool>> = std::sync::OnceLock::new();
    POOL.get_or_init(|| {
        let n = std::thread::available_parallelism().map_or(1, |n| n.get());
        rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .thread_name(|i| format!("meshmatch-paint-{i}"))
            .build()
            .ok()
    })
    .as_ref()
}

/// Faces per parallel task of a dab.
const DAB_FACE_CHUNK: usize = 16;

/// A face's corners as a dab reads them at every texel: positions, vertex normals (zero where
/// missing) and, seen from a view, clip coordinates.
#[derive(Clone, Copy, Default)]
struct FaceCorners {
    p: [Vec3; 3],
    n: [Vec3; 3],
    clip: [glam::Vec4; 3],
}

impl FaceCorners {
    fn new(mesh: &TriMesh, normals: &[[f32; 3]], view_proj: Option<glam::Mat4>, f: usize) -> Self {
        let face = mesh.faces[f];
        let p = face.map(|v| Vec3::from(mesh.positions[v as usize]));
        let n = face.map(|v| {
            normals
                .get(v as usize)
                .map_or(Vec3::ZERO, |n| Vec3::from(*n))
        });
        let clip = match view_proj {
            Some(m) => p.map(|q| m * q.extend(1.0)),
            None => [glam::Vec4::ZERO; 3],
        };
        FaceCorners { p, n, clip }
    }

    #[inline]
    fn point(&self, b: [f32; 3]) -> Vec3 {
        self.p[0] * b[0] + self.p[1] * b[1] + self.p[2] * b[2]
    }

    #[inline]
    fn normal(&self, b: [f32; 3]) -> Vec3 {
        (self.n[0] * b[0] + self.n[1] * b[1] + self.n[2] * b[2]).normalize_or_zero()
    }

    #[inline]
    fn clip(&self, b: [f32; 3]) -> glam::Vec4 {
        self.clip[0] * b[0] + self.clip[1] * b[1] + self.clip[2] * b[2]
    }
}

/// Stamp the weights `weight` gives the texels of `faces` (culled by `keep`, see
/// [`for_texels`]) into the stroke: the weights of texels the stroke has not yet given their
/// full weight are computed in parallel over chunks of faces (each face's corners read once,
/// see [`FaceCorners`]), then stamped in order. Returns the number of texels that changed.
#[allow(clippy::too_many_arguments)]
fn stamp_faces(
    layer: &mut TexelLayer,
    mesh: &TriMesh,
    normals: &[[f32; 3]],
    view_proj: Option<glam::Mat4>,
    faces: &[usize],
    keep: &(dyn Fn([Vec3; 3]) -> bool + Sync),
    weight: &(dyn Fn(&FaceCorners, [f32; 3]) -> f32 + Sync),
) -> usize {
    use rayon::prelude::*;
    let (w, h) = (layer.width, layer.height);
    let l: &TexelLayer = layer;
    let chunk = |faces: &[usize]| {
        let mut out: Vec<(u32, f32)> = Vec::new();
        let mut at = usize::MAX;
        let mut corners = FaceCorners::default();
        for_texels(
            mesh,
            w,
            h,
            faces.iter().copied(),
            keep,
            &mut |x, y, f, b| {
                // Full already this stroke: nothing more to add.
                if l.saturated(x, y) {
                    return;
                }
                if f != at {
                    corners = FaceCorners::new(mesh, normals, view_proj, f);
                    at = f;
                }
                let wt = weight(&corners, b);
                if wt > 0.0 {
                    out.push((y * w + x, wt));
                }
            },
        );
        out
    };
    let found: Vec<Vec<(u32, f32)>> = match paint_pool() {
        Some(pool) => pool.install(|| faces.par_chunks(DAB_FACE_CHUNK).map(chunk).collect()),
        None => vec![chunk(faces)],
    };
    let mut count = 0;
    for (t, wt) in found.into_iter().flatten() {
        if layer.stamp(t % w, t / w, wt) {
            count += 1;
        }
    }
    count
}

/// One dab into a texel layer: the texels of the faces the dab can reach, weighted.
fn texel_dab(
    layer: &mut TexelLayer,
    mesh: &TriMesh,
    normals: &[[f32; 3]],
    at: DabAt,
    brush: &Brush,
    r_world: f32,
    scale: f32,
) -> usize {
    match at {
        DabAt::Ball(c) => {
            let c = Vec3::from(c);
            let keep = |p: [Vec3; 3]| {
                let lo = p[0].min(p[1]).min(p[2]);
                let hi = p[0].max(p[1]).max(p[2]);
                c.clamp(lo, hi).distance_squared(c) <= r_world * r_world
            };
            let faces: Vec<usize> = (0..mesh.faces.len())
                .filter(|&f| keep(mesh.faces[f].map(|v| Vec3::from(mesh.positions[v as usize]))))
                .collect();
            let weight = |fc: &FaceCorners, b: [f32; 3]| {
                falloff(fc.point(b).distance(c) / r_world, brush.hardness)
            };
            stamp_faces(layer, mesh, normals, None, &faces, &keep, &weight)
        }
        DabAt::View(view) => {
            let dab = Dab::new(
                view,
                view.screen_radius(r_world),
                brush.hardness,
                brush.normal_falloff,
                &mesh.positions,
                &mesh.faces,
                scale,
            );
            let (lo, hi) = dab.bounds();
            let corners = |f: usize| mesh.faces[f].map(|v| Vec3::from(mesh.positions[v as usize]));
            let faces: Vec<usize> = dab
                .faces
                .iter()
                .map(|&f| f as usize)
                .filter(|&f| {
                    dab.projected.face_overlaps(mesh.faces[f], lo, hi)
                        && dab.face_can_take(corners(f))
                })
                .collect();
            let keep = |p: [Vec3; 3]| {
                let mut slo = Vec2::splat(f32::INFINITY);
                let mut shi = Vec2::splat(f32::NEG_INFINITY);
                for q in p {
                    match view.project(q) {
                        Some((s, _)) => {
                            slo = slo.min(s);
                            shi = shi.max(s);
                        }
                        None => return false,
                    }
                }
                slo.x <= hi.x && slo.y <= hi.y && shi.x >= lo.x && shi.y >= lo.y
            };
            let weight = |fc: &FaceCorners, b: [f32; 3]| {
                let Some((s, q)) = view.project_clip(fc.clip(b)) else {
                    return 0.0;
                };
                if !dab.in_disc(s) {
                    return 0.0;
                }
                let n = if brush.normal_falloff {
                    fc.normal(b)
                } else {
                    Vec3::ZERO
                };
                dab.weight_projected(fc.point(b), n, s, q)
            };
            stamp_faces(
                layer,
                mesh,
                normals,
                Some(view.view_proj),
                &faces,
                &keep,
                &weight,
            )
        }
    }
}
