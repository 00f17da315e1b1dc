//! Per-vertex tangent frames and the discrete Levi-Civita transport between them.
//!
//! Two rules pick a vertex's first axis, as a named choice ([`FrameRule`]): the surface tools
//! (direction fields) use Duff et al.'s branchless basis, MeshMatch's fans and patch orientations
//! (§3.1, §4.1) the global axis least aligned with the normal. Neither is the other turned by a
//! fixed rule (at `n = +x` Duff's first axis is `-z`, the axis rule's is `+y`; at `n = +z` both are
//! `+x`), so each is kept, with the transport arithmetic it has always been used with.

use glam::Vec3;

/// How a vertex's tangent frame is chosen from its normal.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FrameRule {
    /// The branchless construction of Duff et al. 2017 ("Building an orthonormal basis,
    /// revisited") on the normalised normal (zero or non-finite normals count as +z):
    /// `s = sign(n_z)`, `a = -1/(s + n_z)`, `b = n_x n_y a`, `t1 = (1 + s n_x² a, s b, -s n_x)`,
    /// `t2 = (b, s + n_y² a, -n_y)`. Transport: the minimal rotation between the normals in
    /// Rodrigues' form `R v = (from·to) v + c × v + c (c·v) / (1 + from·to)`, `c = from × to`, and
    /// for opposite normals the half turn about the first frame's second axis. Used by the
    /// surface tools (direction fields).
    Duff,
    /// The global axis least aligned with the (unit) normal (x if `|n_x| < 0.6`, else y if
    /// `|n_y| < 0.6`, else z), projected into the tangent plane; `t2 = n × t1`. An arbitrary but
    /// smooth choice, as in MeshMatch §3.1. Transport: rotation about the unit axis
    /// `from × to / |from × to|` by the angle between the normals, and none where the normals
    /// are parallel or opposite (`|from × to| ≤ 1e-6`). Used by the fans and patch orientations.
    AxisProjection,
}

/// A tangent frame per vertex: `t1`, `t2` orthonormal and orthogonal to the vertex normal, with
/// `t1 × t2 = n`.
#[derive(Clone, Debug, Default)]
pub struct Frames {
    /// First tangent (the polar reference direction, angle 0).
    pub t1: Vec<[f32; 3]>,
    /// Second tangent, `n × t1` (angle 90 degrees).
    pub t2: Vec<[f32; 3]>,
}

impl Frames {
    /// Number of frames.
    pub fn len(&self) -> usize {
        self.t1.len()
    }

    /// True when there are no frames.
    pub fn is_empty(&self) -> bool {
        self.t1.is_empty()
    }

    /// Frame `i` as `(t1, t2)`.
    #[inline]
    pub fn get(&self, i: usize) -> (Vec3, Vec3) {
        (Vec3::from(self.t1[i]), Vec3::from(self.t2[i]))
    }

    /// Coordinates `(d·t1, d·t2)` of vector `d` in frame `i`.
    #[inline]
    pub fn coords(&self, i: usize, d: Vec3) -> (f32, f32) {
        (d.dot(Vec3::from(self.t1[i])), d.dot(Vec3::from(self.t2[i])))
    }

    /// Polar angle of vector `d` in frame `i`: `atan2(d·t2, d·t1)`.
    #[inline]
    pub fn angle(&self, i: usize, d: Vec3) -> f32 {
        let (x, y) = self.coords(i, d);
        y.atan2(x)
    }
}

/// The tangent frame `(t1, t2)` of one normal by `rule` (see [`FrameRule`]).
#[inline]
pub fn frame_of(n: Vec3, rule: FrameRule) -> (Vec3, Vec3) {
    match rule {
        FrameRule::Duff => {
            let v = if n.length_squared() > 0.0 && n.is_finite() {
                n.normalize()
            } else {
                Vec3::Z
            };
            let s = 1.0f32.copysign(v.z);
            let a = -1.0 / (s + v.z);
            let b = v.x * v.y * a;
            let t1 = Vec3::new(1.0 + s * v.x * v.x * a, s * b, -s * v.x);
            let t2 = Vec3::new(b, s + v.y * v.y * a, -v.y);
            (t1, t2)
        }
        FrameRule::AxisProjection => {
            let a = if n.x.abs() < 0.6 {
                Vec3::X
            } else if n.y.abs() < 0.6 {
                Vec3::Y
            } else {
                Vec3::Z
            };
            let t1 = (a - n * n.dot(a)).normalize_or(Vec3::X);
            let t2 = n.cross(t1);
            (t1, t2)
        }
    }
}

/// Tangent frames of per-vertex normals by `rule` (see [`frame_of`]).
pub fn tangent_frames(normals: &[[f32; 3]], rule: FrameRule) -> Frames {
    let (t1, t2) = normals
        .iter()
        .map(|n| {
            let (a, b) = frame_of(Vec3::from(*n), rule);
            (a.to_array(), b.to_array())
        })
        .unzip();
    Frames { t1, t2 }
}

/// `v` carried by the minimal rotation taking unit normal `from` onto unit normal `to`, in the
/// arithmetic of `rule` (see [`FrameRule`]); `fallback_axis` (a unit vector orthogonal to
/// `from`) is the half-turn axis for opposite normals under [`FrameRule::Duff`].
#[inline]
fn rotate_onto(rule: FrameRule, from: Vec3, to: Vec3, v: Vec3, fallback_axis: Vec3) -> Vec3 {
    match rule {
        FrameRule::Duff => {
            let cos = from.dot(to);
            if 1.0 + cos < 1e-6 {
                // half turn about fallback_axis
                return 2.0 * fallback_axis.dot(v) * fallback_axis - v;
            }
            let c = from.cross(to);
            cos * v + c.cross(v) + c * (c.dot(v) / (1.0 + cos))
        }
        FrameRule::AxisProjection => {
            let axis = from.cross(to);
            let s = axis.length();
            let c = from.dot(to);
            if s > 1e-6 {
                let k = axis / s;
                v * c + k.cross(v) * s + k * k.dot(v) * (1.0 - c)
            } else {
                v
            }
        }
    }
}

/// The discrete Levi-Civita transport angle from frame `from` (normal `n_from`, frame
/// `(t1, t2)`) to frame `to`: `from`'s first axis is carried to `to`'s tangent plane by the
/// minimal rotation taking `n_from` onto `n_to` (in `rule`'s arithmetic, [`FrameRule`]), and
/// the result is its polar angle in `to`'s frame.
///
/// Convention: a tangent vector with polar angle `φ` in `from`'s frame arrives with angle
/// `φ + result` in `to`'s frame; swapping the two negates it. Normals must be unit length.
#[inline]
pub fn transport_angle(
    rule: FrameRule,
    n_from: Vec3,
    from: (Vec3, Vec3),
    n_to: Vec3,
    to: (Vec3, Vec3),
) -> f32 {
    let t = rotate_onto(rule, n_from, n_to, from.0, from.1);
    t.dot(to.1).atan2(t.dot(to.0))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn angle(rule: FrameRule, n: &[[f32; 3]], f: &Frames, a: usize, b: usize) -> f32 {
        let (na, nb) = (Vec3::from(n[a]), Vec3::from(n[b]));
        transport_angle(rule, na, f.get(a), nb, f.get(b))
    }

    #[test]
    fn frames_are_orthonormal_and_transport_is_antisymmetric() {
        let normals = [
            [0.0, 0.0, 1.0],
            [0.0, 0.0, -1.0],
            [0.6, 0.0, 0.8],
            [0.0, 1.0, 0.0],
            [-0.48, 0.6, -0.64],
        ];
        for rule in [FrameRule::Duff, FrameRule::AxisProjection] {
            let fr = tangent_frames(&normals, rule);
            for (i, n) in normals.iter().enumerate() {
                let (n, (a, b)) = (Vec3::from(*n), fr.get(i));
                assert!((a.length() - 1.0).abs() < 1e-6 && (b.length() - 1.0).abs() < 1e-6);
                assert!(a.dot(b).abs() < 1e-6 && a.dot(n).abs() < 1e-6);
                assert!((a.cross(b) - n).length() < 1e-5);
            }
            for i in 0..normals.len() {
                for j in 0..normals.len() {
                    if Vec3::from(normals[i]).dot(Vec3::from(normals[j])) < -0.5 {
                        continue;
                    }
                    let ab = angle(rule, &normals, &fr, i, j);
                    let ba = angle(rule, &normals, &fr, j, i);
                    let d = (ab + ba).rem_euclid(std::f32::consts::TAU);
                    assert!(
                        !(1e-4..=std::f32::consts::TAU - 1e-4).contains(&d),
                        "{rule:?} {i} {j} {ab} {ba}"
                    );
                }
            }
        }
    }

    #[test]
    fn transport_between_frames_of_one_normal_is_their_angle() {
        let n = Vec3::Z;
        let th = 30f32.to_radians();
        for rule in [FrameRule::Duff, FrameRule::AxisProjection] {
            let (t1, t2) = frame_of(n, rule);
            // same normal, `to`'s first axis at +30 degrees in `from`'s frame
            let t1y = t1 * th.cos() + t2 * th.sin();
            let to = (t1y, n.cross(t1y));
            let a = transport_angle(rule, n, (t1, t2), n, to);
            assert!((a + th).abs() < 1e-5, "{rule:?} {a}");
            let b = transport_angle(rule, n, to, n, (t1, t2));
            assert!((b - th).abs() < 1e-5, "{rule:?} {b}");
        }
    }

    #[test]
    fn the_rules_differ_by_no_fixed_rotation() {
        let (d, p) = (FrameRule::Duff, FrameRule::AxisProjection);
        assert_eq!(frame_of(Vec3::Z, d).0, frame_of(Vec3::Z, p).0);
        assert_eq!(frame_of(Vec3::X, d).0, Vec3::NEG_Z);
        assert_eq!(frame_of(Vec3::X, p).0, Vec3::Y);
    }
}
