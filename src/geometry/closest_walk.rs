//! The closest point of a triangle mesh to a point, found by walking over the surface from a
//! face near the answer (the answer for a point nearby, as in an iterative fit where each point
//! moves a little per round), instead of descending a BVH from its root.
//!
//! From the start face, the closest point of the current face is found (Ericson's Voronoi-region
//! test). Where it lies inside the face, the walk stops: that is a local minimum of the distance
//! (over a valley another one, across it, can be nearer by a hair). Where it lies on an edge or
//! a vertex, the faces around that edge's (or vertex's) vertices are tried and the walk moves to
//! the nearest, while that is strictly nearer. The answer is a local minimum of the distance
//! over the surface: the global one for a point closer to the surface than the surface's reach
//! (its distance to the medial axis), which is what a tracked point near the surface is. A point
//! far off, or a start on the wrong sheet of a thin part, can stop at another local minimum;
//! [`super::TriangleBvh::closest_point`] is the search for those.

use glam::Vec3;

use super::closest_on_triangle;
use crate::mesh::Csr;

/// Steps a walk takes at most before it settles for the nearest face found so far.
const MAX_STEPS: usize = 64;

/// Closest point of the mesh (`positions`, `faces`, `faces_of` its vertex-to-face CSR) to `p`,
/// walked from face `start`: `(face, barycentric coordinates, distance)`; `None` for a start out
/// of range or a `p` that is not finite.
pub fn closest_point_walk(
    positions: &[[f32; 3]],
    faces: &[[u32; 3]],
    faces_of: &Csr,
    p: Vec3,
    start: u32,
) -> Option<(u32, [f32; 3], f32)> {
    if start as usize >= faces.len() || !p.is_finite() {
        return None;
    }
    let eval = |f: u32| {
        let [a, b, c] = faces[f as usize].map(|v| Vec3::from(positions[v as usize]));
        let l = closest_on_triangle(p, a, b, c);
        let q = a * l[0] + b * l[1] + c * l[2];
        (l, q.distance_squared(p))
    };
    let mut face = start;
    let (mut bary, mut d2) = eval(face);
    for _ in 0..MAX_STEPS {
        if bary.iter().all(|&b| b > 0.0) {
            break;
        }
        let mut next = (face, bary, d2);
        for (k, &v) in faces[face as usize].iter().enumerate() {
            if bary[k] <= 0.0 {
                continue;
            }
            for &g in faces_of.row(v as usize) {
                if g == face {
                    continue;
                }
                let (l, d) = eval(g);
                if d < next.2 {
                    next = (g, l, d);
                }
            }
        }
        if next.0 == face {
            break;
        }
        (face, bary, d2) = next;
    }
    Some((face, bary, d2.sqrt()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::TriangleBvh;
    use crate::mesh::vertex_faces;

    /// A bumpy grid: 60 x 60 vertices over the unit square, heights a few waves.
    fn bumpy() -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
        let (mut pos, faces) = crate::testdata::grid_cells(59, 59, 1.0 / 59.0);
        for p in &mut pos {
            p[2] = 0.05 * (7.0 * p[0]).sin() * (5.0 * p[1]).cos();
        }
        (pos, faces)
    }

    #[test]
    fn a_walk_from_a_nearby_face_finds_the_closest_point() {
        let (pos, faces) = bumpy();
        let faces_of = vertex_faces(pos.len(), &faces);
        let bvh = TriangleBvh::new(&pos, &faces);
        let mut worst = 0.0f32;
        let mut moved = 0;
        for i in 0..2000 {
            let t = i as f32 * 0.618_034;
            let p = Vec3::new(
                0.1 + 0.8 * t.fract(),
                0.1 + 0.8 * (t * 1.7).fract(),
                0.01 * (t * 3.1).sin(),
            );
            let (f, _, d) = bvh.closest_point(p.to_array()).unwrap();
            // start a few faces away, as a point tracked over rounds does
            let start = (f as usize + 2 * ((i % 3) + 1)).min(faces.len() - 1) as u32;
            let (g, _, e) = closest_point_walk(&pos, &faces, &faces_of, p, start).unwrap();
            worst = worst.max((e - d).abs());
            moved += (g != start) as usize;
        }
        // Over a valley a point has two local minima at nearly the same distance, one on each
        // side: the walk may settle on either, a distance within a thousandth of an edge.
        let edge = 1.0 / 59.0;
        assert!(worst < 1e-3 * edge, "walked distance off by {worst}");
        assert!(
            moved > 1000,
            "the walks mostly started on the answer: {moved}"
        );
    }

    #[test]
    fn a_bad_start_or_point_is_refused() {
        let (pos, faces) = bumpy();
        let faces_of = vertex_faces(pos.len(), &faces);
        let p = Vec3::splat(0.5);
        assert!(closest_point_walk(&pos, &faces, &faces_of, p, u32::MAX).is_none());
        assert!(closest_point_walk(&pos, &faces, &faces_of, Vec3::NAN, 0).is_none());
    }
}
