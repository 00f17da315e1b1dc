//! Orbit camera framed on a mesh's bounding sphere, screen rays and triangle picking.
//!
//! A [`Camera`] is expressed relative to the bounds of the mesh it looks at (angles, a zoom factor
//! and a pan in units of the bounding radius), so one camera can drive two views of two different
//! meshes and move them identically relative to each mesh: that is how the app locks cameras.

use glam::{Mat4, Vec2, Vec3};

use crate::geometry::BARY_EPS;

/// Field of view of every view along its shorter side, in degrees.
pub const FOV_Y_DEG: f32 = 35.0;

/// Vertical field of view in radians for a viewport of `aspect` = width / height: [`FOV_Y_DEG`]
/// when the view is wide, widened when it is tall so that the horizontal field is [`FOV_Y_DEG`]
/// (the framed bounding sphere then fits across a narrow view as well as up a wide one).
pub fn fov_y(aspect: f32) -> f32 {
    let base = FOV_Y_DEG.to_radians();
    let aspect = aspect.max(1e-3);
    if aspect >= 1.0 {
        base
    } else {
        2.0 * ((base * 0.5).tan() / aspect).atan()
    }
}

/// An orbit camera relative to a mesh's bounding sphere.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Camera {
    /// Rotation about the vertical (+Y) axis in degrees; 0 looks at the mesh from +Z.
    pub azimuth_deg: f32,
    /// Angle above the horizontal plane in degrees (clamped to ±89).
    pub elevation_deg: f32,
    /// Distance multiplier: 1 frames the bounding sphere, smaller is closer.
    pub zoom: f32,
    /// Pan of the orbit centre in the view plane, in units of the bounding radius.
    pub pan: [f32; 2],
}

impl Default for Camera {
    fn default() -> Self {
        Camera {
            azimuth_deg: 30.0,
            elevation_deg: 15.0,
            zoom: 1.0,
            pan: [0.0, 0.0],
        }
    }
}

/// Centre and radius of a mesh's bounding sphere (from its axis-aligned bounds).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frame {
    /// Centre of the bounding box.
    pub center: Vec3,
    /// Half the bounding box diagonal (at least a tiny positive number).
    pub radius: f32,
}

impl Frame {
    /// The frame of a set of points; a unit frame at the origin when empty or non-finite.
    pub fn of_points(points: &[[f32; 3]]) -> Self {
        let mut lo = Vec3::splat(f32::INFINITY);
        let mut hi = Vec3::splat(f32::NEG_INFINITY);
        for p in points {
            let v = Vec3::from(*p);
            if v.is_finite() {
                lo = lo.min(v);
                hi = hi.max(v);
            }
        }
        if !lo.is_finite() || !hi.is_finite() {
            return Frame {
                center: Vec3::ZERO,
                radius: 1.0,
            };
        }
        Frame {
            center: (lo + hi) * 0.5,
            radius: ((hi - lo).length() * 0.5).max(1e-6),
        }
    }
}

impl Camera {
    /// Unit vector from the orbit centre towards the eye.
    pub fn direction(&self) -> Vec3 {
        let az = self.azimuth_deg.to_radians();
        let el = self.elevation_deg.clamp(-89.0, 89.0).to_radians();
        Vec3::new(el.cos() * az.sin(), el.sin(), el.cos() * az.cos())
    }

    /// Camera right and up vectors (world space).
    fn basis(&self) -> (Vec3, Vec3) {
        let dir = self.direction();
        let right = Vec3::Y.cross(dir).normalize_or(Vec3::X);
        let up = dir.cross(right).normalize_or(Vec3::Y);
        (right, up)
    }

    /// Eye position and orbit target for a mesh frame.
    pub fn eye_target(&self, frame: &Frame) -> (Vec3, Vec3) {
        let (right, up) = self.basis();
        let target = frame.center + (right * self.pan[0] + up * self.pan[1]) * frame.radius;
        let dist = frame.radius / (FOV_Y_DEG.to_radians() * 0.5).sin() * self.zoom.max(1e-3);
        (target + self.direction() * dist, target)
    }

    /// View and projection matrices (wgpu depth range [0, 1]) for a viewport aspect ratio.
    pub fn matrices(&self, frame: &Frame, aspect: f32) -> (Mat4, Mat4) {
        let (eye, target) = self.eye_target(frame);
        let (_, up) = self.basis();
        let view = Mat4::look_at_rh(eye, target, up);
        let dist = (eye - target).length();
        let near = (dist - frame.radius * 1.5).max(dist * 1e-3).max(1e-6);
        let far = dist + frame.radius * 1.5;
        let proj = Mat4::perspective_rh(fov_y(aspect), aspect.max(1e-3), near, far);
        (view, proj)
    }

    /// Combined view-projection matrix.
    pub fn view_proj(&self, frame: &Frame, aspect: f32) -> Mat4 {
        let (v, p) = self.matrices(frame, aspect);
        p * v
    }

    /// Orbit by a screen-space drag of `delta` pixels.
    pub fn orbit(&mut self, delta: Vec2) {
        self.azimuth_deg = (self.azimuth_deg - delta.x * 0.4).rem_euclid(360.0);
        self.elevation_deg = (self.elevation_deg + delta.y * 0.4).clamp(-89.0, 89.0);
    }

    /// Pan by a screen-space drag of `delta` pixels in a view of `size` pixels.
    pub fn pan_by(&mut self, delta: Vec2, size: Vec2) {
        let dist = self.zoom / (FOV_Y_DEG.to_radians() * 0.5).sin();
        let fov = fov_y(size.x / size.y.max(1.0));
        let world_per_px = 2.0 * dist * (fov * 0.5).tan() / size.y.max(1.0);
        self.pan[0] -= delta.x * world_per_px;
        self.pan[1] += delta.y * world_per_px;
    }

    /// Zoom by a mouse-wheel amount (positive = closer).
    pub fn zoom_by(&mut self, scroll: f32) {
        self.zoom = (self.zoom * (-scroll * 0.002).exp()).clamp(0.02, 20.0);
    }

    /// Frame the whole mesh again, keeping the viewing angles.
    pub fn frame_all(&mut self) {
        self.zoom = 1.0;
        self.pan = [0.0, 0.0];
    }

    /// The world-space ray through pixel `px` of a `size` viewport (origin top-left).
    pub fn ray(&self, frame: &Frame, px: Vec2, size: Vec2) -> (Vec3, Vec3) {
        let inv = self.view_proj(frame, size.x / size.y.max(1.0)).inverse();
        let ndc = Vec2::new(px.x / size.x * 2.0 - 1.0, 1.0 - px.y / size.y * 2.0);
        let a = inv.project_point3(ndc.extend(0.0));
        let b = inv.project_point3(ndc.extend(1.0));
        (a, (b - a).normalize_or(Vec3::NEG_Z))
    }

    /// Project a world point to pixel coordinates of a `size` viewport; `None` behind the eye.
    pub fn project(&self, frame: &Frame, p: Vec3, size: Vec2) -> Option<Vec2> {
        let clip = self.view_proj(frame, size.x / size.y.max(1.0)) * p.extend(1.0);
        if clip.w <= 1e-9 {
            return None;
        }
        let ndc = clip.truncate() / clip.w;
        Some(Vec2::new(
            (ndc.x + 1.0) * 0.5 * size.x,
            (1.0 - ndc.y) * 0.5 * size.y,
        ))
    }
}

/// A ray hit on a triangle mesh.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// The triangle hit.
    pub face: usize,
    /// Ray parameter of the hit.
    pub t: f32,
    /// World position of the hit.
    pub point: Vec3,
    /// The corner of the triangle nearest to the hit point (a vertex index).
    pub nearest_vertex: u32,
}

/// Closest ray/triangle intersection (Möller–Trumbore 1997, "Fast, minimum storage ray-triangle
/// intersection": solve `o + t d = (1-u-v) a + u b + v c` by Cramer's rule), both faces counted.
pub fn pick(positions: &[[f32; 3]], faces: &[[u32; 3]], origin: Vec3, dir: Vec3) -> Option<Hit> {
    use rayon::prelude::*;
    let best = faces
        .par_iter()
        .enumerate()
        .filter_map(|(fi, f)| {
            let get = |i: u32| positions.get(i as usize).map(|p| Vec3::from(*p));
            let (a, b, c) = (get(f[0])?, get(f[1])?, get(f[2])?);
            let e1 = b - a;
            let e2 = c - a;
            let p = dir.cross(e2);
            let det = e1.dot(p);
            if det.abs() < 1e-12 {
                return None;
            }
            let inv = 1.0 / det;
            let s = origin - a;
            let u = s.dot(p) * inv;
            if !(-BARY_EPS..=1.0 + BARY_EPS).contains(&u) {
                return None;
            }
            let q = s.cross(e1);
            let v = dir.dot(q) * inv;
            if v < -BARY_EPS || u + v > 1.0 + BARY_EPS {
                return None;
            }
            let t = e2.dot(q) * inv;
            (t > 0.0).then_some((fi, t))
        })
        .min_by(|a, b| a.1.total_cmp(&b.1))?;
    let (face, t) = best;
    let point = origin + dir * t;
    let f = faces[face];
    let nearest_vertex = *f
        .iter()
        .min_by(|&&i, &&j| {
            let di = Vec3::from(positions[i as usize]).distance_squared(point);
            let dj = Vec3::from(positions[j as usize]).distance_squared(point);
            di.total_cmp(&dj)
        })
        .expect("three corners");
    Some(Hit {
        face,
        t,
        point,
        nearest_vertex,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn centre_pixel_ray_hits_the_facing_triangle() {
        let positions = vec![[-1.0, -1.0, 0.0], [1.0, -1.0, 0.0], [0.0, 1.0, 0.0]];
        let faces = vec![[0, 1, 2]];
        let frame = Frame::of_points(&positions);
        let cam = Camera {
            azimuth_deg: 0.0,
            elevation_deg: 0.0,
            ..Camera::default()
        };
        let size = Vec2::new(200.0, 100.0);
        let (o, d) = cam.ray(&frame, size * 0.5, size);
        let hit = pick(&positions, &faces, o, d).expect("hit");
        assert_eq!(hit.face, 0);
        assert!(hit.point.z.abs() < 1e-4);
        // A pixel in the corner misses.
        let (o, d) = cam.ray(&frame, Vec2::new(1.0, 1.0), size);
        assert!(pick(&positions, &faces, o, d).is_none());
        // Projection and ray agree: projecting the top vertex lands above the centre.
        let top = cam.project(&frame, Vec3::new(0.0, 1.0, 0.0), size).unwrap();
        assert!(top.y < 50.0 && (top.x - 100.0).abs() < 1e-2);
        let (o, d) = cam.ray(&frame, top + Vec2::new(0.0, 3.0), size);
        assert_eq!(pick(&positions, &faces, o, d).unwrap().nearest_vertex, 2);
    }

    #[test]
    fn picking_exactly_at_a_projected_vertex_hits_that_vertex_on_the_near_side() {
        // A UV sphere; every vertex facing the camera, clicked exactly where it projects.
        let (rings, segs) = (16u32, 24u32);
        let mut positions = Vec::new();
        for r in 0..=rings {
            let th = std::f32::consts::PI * r as f32 / rings as f32;
            for k in 0..segs {
                let ph = std::f32::consts::TAU * k as f32 / segs as f32;
                positions.push([th.sin() * ph.cos(), th.cos(), th.sin() * ph.sin()]);
            }
        }
        let id = |r: u32, k: u32| r * segs + k % segs;
        let mut faces = Vec::new();
        for r in 0..rings {
            for k in 0..segs {
                faces.push([id(r, k), id(r + 1, k), id(r + 1, k + 1)]);
                faces.push([id(r, k), id(r + 1, k + 1), id(r, k + 1)]);
            }
        }
        let frame = Frame::of_points(&positions);
        let cam = Camera::default();
        let (eye, _) = cam.eye_target(&frame);
        let bvh = crate::geometry::TriangleBvh::new(&positions, &faces);
        let size = Vec2::new(450.0, 650.0);
        let mut checked = 0;
        for (v, p) in positions.iter().enumerate().skip(segs as usize) {
            let p = Vec3::from(*p);
            if r_is_pole(v, segs, rings) || p.dot(eye - p) < 0.3 * (eye - p).length() {
                continue;
            }
            let s = cam.project(&frame, p, size).unwrap();
            let (o, d) = cam.ray(&frame, s, size);
            let hit = pick(&positions, &faces, o, d).expect("a ray through a vertex hits");
            assert!(hit.point.distance(p) < 1e-3, "vertex {v}: hit {hit:?}");
            assert_eq!(hit.nearest_vertex as usize, v);
            let (_, _, t) = bvh.ray_hit(o.to_array(), d.to_array()).expect("bvh hit");
            assert!((o + d * t).distance(p) < 1e-3, "vertex {v}: bvh t {t}");
            checked += 1;
        }
        assert!(checked > 50, "{checked} vertices checked");
    }

    /// The duplicated pole rows of the test sphere (many coincident vertices).
    fn r_is_pole(v: usize, segs: u32, rings: u32) -> bool {
        let r = v as u32 / segs;
        r == 0 || r == rings
    }

    #[test]
    fn the_framed_bounding_sphere_fits_across_a_tall_view_too() {
        // A long thin mesh along x, seen from +Z in a view twice as tall as wide.
        let positions = vec![[-1.0, -0.1, 0.0], [1.0, -0.1, 0.0], [0.0, 0.1, 0.0]];
        let frame = Frame::of_points(&positions);
        let cam = Camera {
            azimuth_deg: 0.0,
            elevation_deg: 0.0,
            ..Camera::default()
        };
        for size in [Vec2::new(300.0, 600.0), Vec2::new(600.0, 300.0)] {
            for p in &positions {
                let s = cam.project(&frame, Vec3::from(*p), size).unwrap();
                assert!(
                    s.x > 0.0 && s.x < size.x && s.y > 0.0 && s.y < size.y,
                    "{p:?} at {s:?} in {size:?}"
                );
            }
            // Rays and projection agree in both shapes.
            let (o, d) = cam.ray(&frame, size * 0.5 + Vec2::new(10.0, 0.0), size);
            let back = cam.project(&frame, o + d * 3.0, size).unwrap();
            assert!((back - (size * 0.5 + Vec2::new(10.0, 0.0))).length() < 0.05);
        }
    }
}
