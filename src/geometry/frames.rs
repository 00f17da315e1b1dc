//! Per-vertex tangent frames and the discrete Levi-Civita transport between them.

use glam::Vec3;

/// An orthonormal tangent basis `[t1, t2]` per unit normal `n`, with `t1 × t2 = n`, by the
/// branchless construction of Duff et al. 2017 ("Building an orthonormal basis, revisited"):
/// `s = sign(n_z)`, `a = -1/(s + n_z)`, `b = n_x n_y a`, `t1 = (1 + s n_x² a, s b, -s n_x)`,
/// `t2 = (b, s + n_y² a, -n_y)`. Arbitrary but deterministic; zero normals are treated as +z.
pub fn tangent_frames(normals: &[[f32; 3]]) -> Vec<[[f32; 3]; 2]> {
    normals
        .iter()
        .map(|n| {
            let v = Vec3::from(*n);
            let v = if v.length_squared() > 0.0 && v.is_finite() {
                v.normalize()
            } else {
                Vec3::Z
            };
            let s = 1.0f32.copysign(v.z);
            let a = -1.0 / (s + v.z);
            let b = v.x * v.y * a;
            let t1 = Vec3::new(1.0 + s * v.x * v.x * a, s * b, -s * v.x);
            let t2 = Vec3::new(b, s + v.y * v.y * a, -v.y);
            [t1.to_array(), t2.to_array()]
        })
        .collect()
}

/// Rotate `v` by the minimal rotation taking unit `from` onto unit `to` (Rodrigues, with
/// `c = from × to`: `R v = (from·to) v + c × v + c (c·v) / (1 + from·to)`). For opposite normals
/// the rotation by π about `fallback_axis` (a unit vector orthogonal to `from`) is used.
fn rotate_onto(from: Vec3, to: Vec3, v: Vec3, fallback_axis: Vec3) -> Vec3 {
    let cos = from.dot(to);
    if 1.0 + cos < 1e-6 {
        // half turn about fallback_axis
        return 2.0 * fallback_axis.dot(v) * fallback_axis - v;
    }
    let c = from.cross(to);
    cos * v + c.cross(v) + c * (c.dot(v) / (1.0 + cos))
}

/// The discrete Levi-Civita transport angle `ρ_ab` across edge (a, b): b's frame is carried to
/// a's tangent plane by the minimal rotation taking `n_b` onto `n_a`, and `ρ_ab` is the angle
/// of b's carried first axis measured in a's frame, `atan2(R t1_b · t2_a, R t1_b · t1_a)`.
///
/// Convention: a tangent vector at b with angle `φ` in b's frame (`cos φ t1_b + sin φ t2_b`)
/// arrives at a with angle `φ + ρ_ab` in a's frame; `ρ_ba = -ρ_ab`. Frames are
/// `[t1, t2]` with `t1 × t2 = n` (as from [`tangent_frames`]); normals must be unit length.
pub fn parallel_transport_angle(
    normal_a: [f32; 3],
    frame_a: [[f32; 3]; 2],
    normal_b: [f32; 3],
    frame_b: [[f32; 3]; 2],
) -> f32 {
    let (na, nb) = (Vec3::from(normal_a), Vec3::from(normal_b));
    let tb = Vec3::from(frame_b[0]);
    let t = rotate_onto(nb, na, tb, Vec3::from(frame_b[1]));
    t.dot(Vec3::from(frame_a[1]))
        .atan2(t.dot(Vec3::from(frame_a[0])))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_are_orthonormal_and_transport_is_antisymmetric() {
        let normals = [
            [0.0, 0.0, 1.0],
            [0.0, 0.0, -1.0],
            [0.6, 0.0, 0.8],
            [0.0, 1.0, 0.0],
            [-0.48, 0.6, -0.64],
        ];
        let fr = tangent_frames(&normals);
        for (n, f) in normals.iter().zip(&fr) {
            let (n, a, b) = (Vec3::from(*n), Vec3::from(f[0]), Vec3::from(f[1]));
            assert!((a.length() - 1.0).abs() < 1e-6 && (b.length() - 1.0).abs() < 1e-6);
            assert!(a.dot(b).abs() < 1e-6 && a.dot(n).abs() < 1e-6);
            assert!((a.cross(b) - n).length() < 1e-5);
        }
        for i in 0..normals.len() {
            for j in 0..normals.len() {
                if Vec3::from(normals[i]).dot(Vec3::from(normals[j])) < -0.5 {
                    continue;
                }
                let ab = parallel_transport_angle(normals[i], fr[i], normals[j], fr[j]);
                let ba = parallel_transport_angle(normals[j], fr[j], normals[i], fr[i]);
                let d = (ab + ba).rem_euclid(std::f32::consts::TAU);
                assert!(
                    !(1e-4..=std::f32::consts::TAU - 1e-4).contains(&d),
                    "{i} {j} {ab} {ba}"
                );
            }
        }
        // same normal, b's first axis at +30 degrees in a's frame
        let n = [0.0, 0.0, 1.0];
        let fa = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        let (c, s) = (30f32.to_radians().cos(), 30f32.to_radians().sin());
        let fb = [[c, s, 0.0], [-s, c, 0.0]];
        let r = parallel_transport_angle(n, fa, n, fb);
        assert!((r - 30f32.to_radians()).abs() < 1e-5, "{r}");
    }
}
