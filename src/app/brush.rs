//! Projection painting: what one dab of the brush reaches from the current view.
//!
//! A dab is a disc on the screen around the pointer. It reaches the surface points (vertices, or
//! texels through the mesh's UVs) that project into the disc and that the view sees: each is
//! tested against a depth buffer of the disc's square, rasterised on the CPU from the faces that
//! project there (the nearest surface's 1/w plane per pixel, so a point is compared with the
//! surface in front of it at its own sub-pixel position). Falloff is in screen space, optionally
//! attenuated by the angle between the surface and the line of sight. "Paint through" instead
//! paints a ball in space around the picked point, every surface inside it, seen or not.

use glam::{Mat4, Vec2, Vec3, Vec4, Vec4Swizzles};

use crate::render::{Camera, Frame, fov_y};

/// How a view sees a dab: its projection, the viewport and the pointer.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BrushView {
    /// World to clip space.
    pub view_proj: Mat4,
    /// Camera position.
    pub eye: Vec3,
    /// Viewport size in points.
    pub size: Vec2,
    /// Pointer position in the viewport (points, origin top-left).
    pub pointer: Vec2,
    /// Points per world unit at view depth 1 (vertically).
    pub focal: f32,
    /// The surface point under the pointer.
    pub hit: Vec3,
}

impl BrushView {
    /// The view of `camera` framing `frame` in a viewport of `size` points, with the pointer at
    /// `pointer` over the surface point `hit`.
    pub fn new(camera: &Camera, frame: &Frame, size: Vec2, pointer: Vec2, hit: Vec3) -> Self {
        let aspect = size.x / size.y.max(1.0);
        let (eye, _) = camera.eye_target(frame);
        BrushView {
            view_proj: camera.view_proj(frame, aspect),
            eye,
            size,
            pointer,
            focal: 0.5 * size.y / (fov_y(aspect) * 0.5).tan(),
            hit,
        }
    }

    /// Viewport position (points) and 1/w (w: view depth) of a world point; `None` in front of
    /// the near plane (where the views clip the mesh away) or behind the eye.
    #[inline]
    pub fn project(&self, p: Vec3) -> Option<(Vec2, f32)> {
        self.project_clip(self.view_proj * p.extend(1.0))
    }

    /// [`Self::project`] of a point given in clip space (clip coordinates are linear in the
    /// barycentric coordinates of a triangle's corners, so a face's texels interpolate them).
    #[inline]
    pub fn project_clip(&self, c: Vec4) -> Option<(Vec2, f32)> {
        if c.w <= 1e-9 || c.z < 0.0 {
            return None;
        }
        let inv = 1.0 / c.w;
        let ndc = c.xy() * inv;
        Some((
            Vec2::new(
                (ndc.x + 1.0) * 0.5 * self.size.x,
                (1.0 - ndc.y) * 0.5 * self.size.y,
            ),
            inv,
        ))
    }

    /// Screen radius (points) of a world radius `r` around the picked point.
    pub fn screen_radius(&self, r: f32) -> f32 {
        let w = self.project(self.hit).map_or(1.0, |(_, q)| 1.0 / q);
        r * self.focal / w.max(1e-9)
    }
}

/// Brush falloff at `d` (distance over radius, 0 at the centre): full strength inside the
/// hardness, a smoothstep down to 0 at the rim.
#[inline]
pub fn falloff(d: f32, hardness: f32) -> f32 {
    if d >= 1.0 {
        return 0.0;
    }
    let h = hardness.clamp(0.0, 0.999);
    let t = ((d - h) / (1.0 - h)).clamp(0.0, 1.0);
    1.0 - t * t * (3.0 - 2.0 * t)
}

/// Attenuation by the angle between the surface normal `n` and the line of sight `v` (both
/// unit): full strength up to 80 degrees from facing the eye (Blender's default normal falloff
/// angle), fading to 0 at grazing, 0 facing away.
#[inline]
pub fn facing(n: Vec3, v: Vec3) -> f32 {
    let c = (n.dot(v) / 0.17).clamp(0.0, 1.0);
    c * c * (3.0 - 2.0 * c)
}

/// The nearest surface's 1/w over a square of the viewport, sampled at the centres of cells
/// of at least a point (at most [`DEPTH_CELLS`] across): per cell the plane (value at the
/// centre and its screen gradient) of the nearest face there.
pub struct ScreenDepth {
    origin: Vec2,
    cell: f32,
    w: i32,
    h: i32,
    /// Per cell: 1/w at its centre (0 = no surface), d/dx, d/dy (per point).
    planes: Vec<[f32; 3]>,
    /// Per cell: the nearest face (`u32::MAX` = none).
    faces: Vec<u32>,
}

/// Most depth cells across a dab's square: a larger disc is sampled more coarsely (the planes
/// keep the depth exact within a cell; only occluders' edges are found to a cell).
pub const DEPTH_CELLS: f32 = 160.0;

/// Vertices of a mesh projected into a view: viewport position and 1/w (`q <= 0`: behind).
pub struct Projected {
    /// Viewport positions.
    pub screen: Vec<Vec2>,
    /// 1/w per vertex (0 behind the eye).
    pub q: Vec<f32>,
}

impl Projected {
    /// Project every position.
    pub fn new(view: &BrushView, positions: &[[f32; 3]]) -> Self {
        let mut screen = Vec::with_capacity(positions.len());
        let mut q = Vec::with_capacity(positions.len());
        for p in positions {
            match view.project(Vec3::from(*p)) {
                Some((s, iw)) => {
                    screen.push(s);
                    q.push(iw);
                }
                None => {
                    screen.push(Vec2::splat(f32::NAN));
                    q.push(0.0);
                }
            }
        }
        Projected { screen, q }
    }

    /// Whether face `f`'s screen bounds overlap the box `[lo, hi]` (faces behind the eye never).
    #[inline]
    pub fn face_overlaps(&self, f: [u32; 3], lo: Vec2, hi: Vec2) -> bool {
        let [a, b, c] = f.map(|v| v as usize);
        if self.q[a] <= 0.0 || self.q[b] <= 0.0 || self.q[c] <= 0.0 {
            return false;
        }
        let (sa, sb, sc) = (self.screen[a], self.screen[b], self.screen[c]);
        let flo = sa.min(sb).min(sc);
        let fhi = sa.max(sb).max(sc);
        flo.x <= hi.x && flo.y <= hi.y && fhi.x >= lo.x && fhi.y >= lo.y
    }
}

impl ScreenDepth {
    /// Rasterise the faces of `faces` that overlap the square `[lo, hi]` of the viewport;
    /// with them, the indices of those faces.
    pub fn new(proj: &Projected, faces: &[[u32; 3]], lo: Vec2, hi: Vec2) -> (Self, Vec<u32>) {
        let ext = (hi - lo).max(Vec2::ONE);
        let cell = (ext.max_element() / DEPTH_CELLS).max(1.0);
        let w = (ext.x / cell).ceil().max(1.0) as i32;
        let h = (ext.y / cell).ceil().max(1.0) as i32;
        let mut d = ScreenDepth {
            origin: lo,
            cell,
            w,
            h,
            planes: vec![[0.0; 3]; (w * h) as usize],
            faces: vec![u32::MAX; (w * h) as usize],
        };
        let mut hit = Vec::new();
        for (k, f) in faces.iter().enumerate() {
            if proj.face_overlaps(*f, lo, hi) {
                let [a, b, c] = f.map(|v| v as usize);
                d.raster(
                    [proj.screen[a], proj.screen[b], proj.screen[c]],
                    [proj.q[a], proj.q[b], proj.q[c]],
                    k as u32,
                );
                hit.push(k as u32);
            }
        }
        (d, hit)
    }

    /// Centre of cell `(x, y)`.
    #[inline]
    fn centre(&self, x: i32, y: i32) -> Vec2 {
        self.origin + Vec2::new(x as f32 + 0.5, y as f32 + 0.5) * self.cell
    }

    /// The face seen at viewport position `s`, if any.
    pub fn face_at(&self, s: Vec2) -> Option<u32> {
        let c = (s - self.origin) / self.cell;
        let (x, y) = (c.x.floor() as i32, c.y.floor() as i32);
        if x < 0 || y < 0 || x >= self.w || y >= self.h {
            return None;
        }
        Some(self.faces[(y * self.w + x) as usize]).filter(|&f| f != u32::MAX)
    }

    fn raster(&mut self, s: [Vec2; 3], q: [f32; 3], face: u32) {
        let area = (s[1] - s[0]).perp_dot(s[2] - s[0]);
        if area.abs() < 1e-12 {
            return;
        }
        let inv = 1.0 / area;
        // The 1/w plane: q(p) = q0 + gx (x - x0) + gy (y - y0).
        let (e1, e2) = (s[1] - s[0], s[2] - s[0]);
        let (dq1, dq2) = (q[1] - q[0], q[2] - q[0]);
        let gx = (dq1 * e2.y - dq2 * e1.y) * inv;
        let gy = (dq2 * e1.x - dq1 * e2.x) * inv;
        let lo = (s[0].min(s[1]).min(s[2]) - self.origin) / self.cell;
        let hi = (s[0].max(s[1]).max(s[2]) - self.origin) / self.cell;
        let ix0 = ((lo.x - 0.5).ceil() as i32).max(0);
        let iy0 = ((lo.y - 0.5).ceil() as i32).max(0);
        let ix1 = ((hi.x - 0.5).floor() as i32).min(self.w - 1);
        let iy1 = ((hi.y - 0.5).floor() as i32).min(self.h - 1);
        for y in iy0..=iy1 {
            for x in ix0..=ix1 {
                let p = self.centre(x, y);
                let b1 = (p - s[0]).perp_dot(e2) * inv;
                let b2 = e1.perp_dot(p - s[0]) * inv;
                let b0 = 1.0 - b1 - b2;
                if b0 < 0.0 || b1 < 0.0 || b2 < 0.0 {
                    continue;
                }
                let qp = q[0] + gx * (p.x - s[0].x) + gy * (p.y - s[0].y);
                let i = (y * self.w + x) as usize;
                // Larger 1/w is nearer.
                if qp > self.planes[i][0] {
                    self.planes[i] = [qp, gx, gy];
                    self.faces[i] = face;
                }
            }
        }
    }

    /// Whether a surface point at viewport position `s` and view depth `w` is seen: the
    /// surface of the cell under `s`, its plane carried to `s`, is not in front of it by more
    /// than `eps` (world units) plus half a cell of that surface's depth slope (a surface seen
    /// edge-on changes depth fast across a cell). Occluders' edges are found to half a cell.
    pub fn visible(&self, s: Vec2, w: f32, eps: f32) -> bool {
        let c = (s - self.origin) / self.cell;
        let (x, y) = (c.x.floor() as i32, c.y.floor() as i32);
        if x < 0 || y < 0 || x >= self.w || y >= self.h {
            return true;
        }
        let [q, gx, gy] = self.planes[(y * self.w + x) as usize];
        if q <= 0.0 {
            return true;
        }
        let o = s - self.centre(x, y);
        let mut qs = q + gx * o.x + gy * o.y;
        if qs <= 0.0 {
            qs = q;
        }
        // |grad w| = |grad q| / q^2, per point.
        let slope = 0.5 * self.cell * (gx * gx + gy * gy).sqrt() / (qs * qs);
        w <= 1.0 / qs + eps + slope
    }
}

/// One dab from a view: where it is on the screen and the depth buffer under it.
pub struct Dab {
    /// The view.
    pub view: BrushView,
    /// Brush radius in points.
    pub radius_px: f32,
    /// Hardness (see [`falloff`]).
    pub hardness: f32,
    /// Attenuate by the angle to the surface normal.
    pub normal_falloff: bool,
    /// Depth tolerance in world units.
    pub eps: f32,
    /// The mesh's vertices projected.
    pub projected: Projected,
    /// Depth of the disc's square.
    pub depth: ScreenDepth,
    /// The faces whose screen bounds overlap the disc's square.
    pub faces: Vec<u32>,
    /// 1 when the surface under the pointer faces the eye (its outside is seen), -1 when its
    /// inside is (an open sheet seen from behind): the side the normal falloff treats as front.
    pub side: f32,
}

impl Dab {
    /// Prepare a dab of `radius_px` points on `positions`/`faces` seen by `view`; `scale` is
    /// the mesh's bounding radius (the depth tolerance is a small fraction of it).
    pub fn new(
        view: BrushView,
        radius_px: f32,
        hardness: f32,
        normal_falloff: bool,
        positions: &[[f32; 3]],
        faces: &[[u32; 3]],
        scale: f32,
    ) -> Self {
        let projected = Projected::new(&view, positions);
        let r = radius_px.max(0.5) + 1.0;
        let (lo, hi) = (view.pointer - Vec2::splat(r), view.pointer + Vec2::splat(r));
        let (depth, overlapping) = ScreenDepth::new(&projected, faces, lo, hi);
        let side = depth
            .face_at(view.pointer)
            .and_then(|f| {
                let [a, b, c] = faces[f as usize].map(|v| Vec3::from(positions[v as usize]));
                let n = (b - a).cross(c - a);
                let d = n.dot(view.eye - a);
                (d != 0.0).then_some(d.signum())
            })
            .unwrap_or(1.0);
        Dab {
            view,
            radius_px: radius_px.max(0.5),
            hardness,
            normal_falloff,
            eps: 2e-3 * scale,
            projected,
            depth,
            faces: overlapping,
            side,
        }
    }

    /// The square of the viewport the disc covers.
    pub fn bounds(&self) -> (Vec2, Vec2) {
        let r = Vec2::splat(self.radius_px);
        (self.view.pointer - r, self.view.pointer + r)
    }

    /// Weight of a surface point `p` with normal `n` (unit or zero) seen at viewport position
    /// `s` and 1/w `q`: 0 outside the disc or hidden.
    #[inline]
    pub fn weight_projected(&self, p: Vec3, n: Vec3, s: Vec2, q: f32) -> f32 {
        if q <= 0.0 {
            return 0.0;
        }
        let d = s.distance(self.view.pointer) / self.radius_px;
        let mut w = falloff(d, self.hardness);
        if w <= 0.0 || !self.depth.visible(s, 1.0 / q, self.eps) {
            return 0.0;
        }
        if self.normal_falloff && n != Vec3::ZERO {
            w *= facing(n * self.side, (self.view.eye - p).normalize_or_zero());
        }
        w
    }

    /// Whether a face with corners `t` can take paint from this dab: always, unless the normal
    /// falloff is on and the face turns its back on the eye (relative to [`Self::side`]).
    #[inline]
    pub fn face_can_take(&self, t: [Vec3; 3]) -> bool {
        !self.normal_falloff
            || (t[1] - t[0]).cross(t[2] - t[0]).dot(self.view.eye - t[0]) * self.side > 0.0
    }

    /// Whether viewport position `s` lies in the disc.
    #[inline]
    pub fn in_disc(&self, s: Vec2) -> bool {
        s.distance_squared(self.view.pointer) < self.radius_px * self.radius_px
    }

    /// Weight of a surface point `p` with normal `n`.
    #[inline]
    pub fn weight(&self, p: Vec3, n: Vec3) -> f32 {
        match self.view.project(p) {
            Some((s, q)) => self.weight_projected(p, n, s, q),
            None => 0.0,
        }
    }

    /// Weights of the vertices the dab reaches (`normals` per vertex).
    pub fn vertex_weights(&self, positions: &[[f32; 3]], normals: &[[f32; 3]]) -> Vec<(u32, f32)> {
        let r2 = self.radius_px * self.radius_px;
        let mut out = Vec::new();
        for (v, p) in positions.iter().enumerate() {
            let s = self.projected.screen[v];
            let q = self.projected.q[v];
            if q <= 0.0 || s.distance_squared(self.view.pointer) >= r2 {
                continue;
            }
            let n = normals.get(v).map_or(Vec3::ZERO, |n| Vec3::from(*n));
            let w = self.weight_projected(Vec3::from(*p), n, s, q);
            if w > 0.0 {
                out.push((v as u32, w));
            }
        }
        out
    }
}

/// Weights of the vertices inside a ball of radius `r` around `center` (paint through).
pub fn ball_vertex_weights(
    positions: &[[f32; 3]],
    center: Vec3,
    r: f32,
    hardness: f32,
) -> Vec<(u32, f32)> {
    let r = r.max(1e-9);
    positions
        .iter()
        .enumerate()
        .filter_map(|(v, p)| {
            let w = falloff(Vec3::from(*p).distance(center) / r, hardness);
            (w > 0.0).then_some((v as u32, w))
        })
        .collect()
}
