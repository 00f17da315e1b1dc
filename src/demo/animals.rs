//! The three procedural animals: signed-distance bodies, zebra stripes, landmarks.
//!
//! Conventions for every animal: Y is up, the animal stands on `y = 0` and faces +X, so its
//! left side is -Z and its right side is +Z (forward × up = right). Lengths are in scene units
//! (the zebra is about 1.7 units from tail to muzzle).

use super::Landmark;
use super::sdf::{capsule, ellipsoid, noise3, project, rot_x_to, round_cone, smax, smin, sphere};
use glam::{Quat, Vec3};
use std::sync::LazyLock;

/// A leg as a chain of round cones through `(joint, radius)` pairs, blended at the joints, with
/// a flat-soled hoof/paw cut at `y = 0`.
fn leg(p: Vec3, joints: &[(Vec3, f32)], k: f32) -> f32 {
    let mut d = f32::INFINITY;
    for w in joints.windows(2) {
        let s = round_cone(p, w[0].0, w[1].0, w[0].1, w[1].1);
        d = if d.is_finite() { smin(d, s, k) } else { s };
    }
    // Flat sole on the ground plane.
    smax(d, -p.y, 0.012)
}

/// Blend `part` into `d` with radius `k`, unless the lower bound `lb` of the part's distance
/// shows it cannot change `d` (`smin(d, x, k) = d` whenever `x >= d + k`), so far parts cost
/// nothing and the result is unchanged.
#[inline]
fn blend_lazy(d: f32, k: f32, lb: f32, part: impl FnOnce() -> f32) -> f32 {
    if lb >= d + k { d } else { smin(d, part(), k) }
}

/// A leg chain with precomputed bounds: an enclosing capsule and one sphere per segment.
pub(crate) struct Chain {
    joints: Vec<(Vec3, f32)>,
    spheres: Vec<(Vec3, f32)>,
    a: Vec3,
    b: Vec3,
    r: f32,
}

impl Chain {
    fn new(joints: &[(Vec3, f32)]) -> Chain {
        let spheres: Vec<(Vec3, f32)> = joints
            .windows(2)
            .map(|w| {
                (
                    (w[0].0 + w[1].0) * 0.5,
                    (w[1].0 - w[0].0).length() * 0.5 + w[0].1.max(w[1].1),
                )
            })
            .collect();
        let (a, b) = (joints[0].0, joints[joints.len() - 1].0);
        let r = joints
            .iter()
            .map(|&(j, r)| capsule(j, a, b, 0.0) + r)
            .fold(0.0f32, f32::max);
        Chain {
            joints: joints.to_vec(),
            spheres,
            a,
            b,
            r,
        }
    }
    /// The leg's distance.
    fn dist(&self, p: Vec3) -> f32 {
        leg(p, &self.joints, 0.03)
    }
    /// `smin(d, dist, k)`, skipping the leg when its bounds show it cannot change `d`.
    fn blend_into(&self, d: f32, k: f32, p: Vec3) -> f32 {
        if capsule(p, self.a, self.b, self.r) >= d + k {
            return d;
        }
        let lb = self
            .spheres
            .iter()
            .map(|&(c, r)| (p - c).length() - r)
            .fold(f32::INFINITY, f32::min);
        blend_lazy(d, k, lb, || self.dist(p))
    }
}

/// Smooth-min of a slice of distances with blend radius `k`.
fn smin_all(ds: &[f32], k: f32) -> f32 {
    ds.iter()
        .copied()
        .reduce(|a, b| smin(a, b, k))
        .unwrap_or(f32::INFINITY)
}

// ---------------------------------------------------------------------------------------------
// Zebra
// ---------------------------------------------------------------------------------------------

const Z_NECK_A: Vec3 = Vec3::new(0.40, 1.02, 0.0);
const Z_NECK_B: Vec3 = Vec3::new(0.70, 1.40, 0.0);
const Z_HEAD_A: Vec3 = Vec3::new(0.76, 1.42, 0.0);
const Z_HEAD_B: Vec3 = Vec3::new(1.03, 1.16, 0.0);
const Z_MUZZLE: Vec3 = Vec3::new(1.04, 1.14, 0.0);
const Z_TAIL_A: Vec3 = Vec3::new(-0.50, 1.08, 0.0);
const Z_TAIL_B: Vec3 = Vec3::new(-0.62, 0.64, 0.0);
const Z_TUFT: Vec3 = Vec3::new(-0.635, 0.56, 0.0);

/// Zebra leg joints for side `s` (-1 left, +1 right); front legs then hind legs.
fn zebra_leg_joints(front: bool, s: f32) -> [(Vec3, f32); 6] {
    let z = 0.11 * s;
    if front {
        [
            (Vec3::new(0.34, 0.96, z * 0.8), 0.11),
            (Vec3::new(0.34, 0.66, z), 0.072),
            (Vec3::new(0.36, 0.40, z), 0.045),
            (Vec3::new(0.37, 0.12, z), 0.034),
            (Vec3::new(0.38, 0.06, z), 0.038),
            (Vec3::new(0.39, 0.02, z), 0.046),
        ]
    } else {
        [
            (Vec3::new(-0.36, 0.98, z * 0.7), 0.15),
            (Vec3::new(-0.27, 0.62, z), 0.09),
            (Vec3::new(-0.42, 0.40, z), 0.045),
            (Vec3::new(-0.40, 0.12, z), 0.034),
            (Vec3::new(-0.39, 0.06, z), 0.038),
            (Vec3::new(-0.385, 0.02, z), 0.046),
        ]
    }
}

fn z_torso(p: Vec3) -> f32 {
    smin_all(
        &[
            ellipsoid(
                p,
                Vec3::new(0.0, 0.93, 0.0),
                Vec3::new(0.50, 0.24, 0.20),
                Quat::IDENTITY,
            ),
            ellipsoid(
                p,
                Vec3::new(0.30, 0.92, 0.0),
                Vec3::new(0.24, 0.25, 0.19),
                Quat::IDENTITY,
            ),
            ellipsoid(
                p,
                Vec3::new(-0.32, 0.97, 0.0),
                Vec3::new(0.25, 0.25, 0.20),
                Quat::IDENTITY,
            ),
            ellipsoid(
                p,
                Vec3::new(0.0, 0.87, 0.0),
                Vec3::new(0.34, 0.22, 0.21),
                Quat::IDENTITY,
            ),
        ],
        0.10,
    )
}

const Z_MANE_A: Vec3 = Vec3::new(0.43, 1.20, 0.0);
const Z_MANE_B: Vec3 = Vec3::new(0.72, 1.52, 0.0);
static Z_MANE_ROT: LazyLock<Quat> = LazyLock::new(|| rot_x_to(Z_MANE_B - Z_MANE_A));
static Z_TUFT_ROT: LazyLock<Quat> = LazyLock::new(|| rot_x_to(Z_TAIL_B - Z_TAIL_A));

fn z_neck(p: Vec3) -> f32 {
    smin(
        round_cone(p, Z_NECK_A, Z_NECK_B, 0.15, 0.085),
        ellipsoid(
            p,
            (Z_MANE_A + Z_MANE_B) * 0.5,
            Vec3::new(0.22, 0.05, 0.022),
            *Z_MANE_ROT,
        ),
        0.05,
    )
}

fn z_neck_lb(p: Vec3) -> f32 {
    capsule(p, Z_NECK_A, Z_NECK_B, 0.15).min(capsule(p, Z_MANE_A, Z_MANE_B, 0.06))
}

fn z_head(p: Vec3) -> f32 {
    let mut head = smin_all(
        &[
            round_cone(p, Z_HEAD_A, Z_HEAD_B, 0.088, 0.06),
            ellipsoid(
                p,
                Vec3::new(0.79, 1.35, 0.0),
                Vec3::new(0.10, 0.09, 0.075),
                Quat::IDENTITY,
            ),
            sphere(p, Z_MUZZLE, 0.068),
        ],
        0.06,
    );
    for s in [-1.0, 1.0] {
        let ear = round_cone(
            p,
            Vec3::new(0.745, 1.50, 0.045 * s),
            Vec3::new(0.70, 1.65, 0.095 * s),
            0.034,
            0.014,
        );
        head = smin(head, ear, 0.025);
    }
    head
}

fn z_head_lb(p: Vec3) -> f32 {
    capsule(p, Vec3::new(0.78, 1.38, 0.0), Z_MUZZLE, 0.11).min(capsule(
        p,
        Vec3::new(0.745, 1.50, 0.0),
        Vec3::new(0.70, 1.65, 0.0),
        0.14,
    ))
}

fn z_tail(p: Vec3) -> f32 {
    smin(
        capsule(p, Z_TAIL_A, Z_TAIL_B, 0.022),
        ellipsoid(p, Z_TUFT, Vec3::new(0.09, 0.035, 0.035), *Z_TUFT_ROT),
        0.03,
    )
}

const LEGS: [(bool, f32); 4] = [(true, -1.0), (true, 1.0), (false, -1.0), (false, 1.0)];
static Z_LEGS: LazyLock<[Chain; 4]> =
    LazyLock::new(|| LEGS.map(|(f, s)| Chain::new(&zebra_leg_joints(f, s))));
static G_LEGS: LazyLock<[Chain; 4]> =
    LazyLock::new(|| LEGS.map(|(f, s)| Chain::new(&giraffe_leg_joints(f, s))));
static C_LEGS: LazyLock<[Chain; 4]> =
    LazyLock::new(|| LEGS.map(|(f, s)| Chain::new(&cerberus_leg_joints(f, s))));

/// Zebra region distances: torso, neck, head, legs (FL, FR, BL, BR), tail.
pub(crate) fn zebra_parts(p: Vec3) -> [f32; 8] {
    let l: [f32; 4] = std::array::from_fn(|i| Z_LEGS[i].dist(p));
    [
        z_torso(p),
        z_neck(p),
        z_head(p),
        l[0],
        l[1],
        l[2],
        l[3],
        z_tail(p),
    ]
}

/// The zebra's signed distance: torso, then neck, head, legs and tail smoothly blended in
/// (parts that cannot affect the value are skipped by bounds).
pub(crate) fn zebra_sdf(p: Vec3) -> f32 {
    let mut d = z_torso(p);
    d = blend_lazy(d, 0.10, z_neck_lb(p), || z_neck(p));
    d = blend_lazy(d, 0.06, z_head_lb(p), || z_head(p));
    for l in Z_LEGS.iter() {
        d = l.blend_into(d, 0.07, p);
    }
    blend_lazy(d, 0.04, capsule(p, Z_TAIL_A, Z_TUFT, 0.1), || z_tail(p))
}

/// Bounding box of the zebra.
pub(crate) fn zebra_bounds() -> (Vec3, Vec3) {
    (Vec3::new(-0.72, -0.01, -0.26), Vec3::new(1.14, 1.70, 0.26))
}

/// Signed distance to the nearest stripe edge for a stripe phase `phi` with local period
/// `lambda` (positive on black): a triangle wave scaled to scene units, `duty` = black share.
#[inline]
fn stripe(phi: f32, lambda: f32, duty: f32) -> f32 {
    let f = phi - phi.floor();
    lambda * (duty * 0.5 - (f - 0.5).abs())
}

/// Quintic-free smoothstep.
#[inline]
fn smoothstep(e0: f32, e1: f32, x: f32) -> f32 {
    let t = ((x - e0) / (e1 - e0)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// Zebra stripe signed distance at `p` (positive = black), from region-wise stripe phases
/// blended with softmax weights of the same region distances that build the body.
pub(crate) fn zebra_stripe(p: Vec3) -> f32 {
    let parts = zebra_parts(p);
    let sigma = 0.025;
    let warp = Vec3::new(noise3(p * 3.0, 1), noise3(p * 3.0, 2), noise3(p * 3.0, 3)) * 0.035
        + Vec3::new(noise3(p * 9.0, 4), noise3(p * 9.0, 5), noise3(p * 9.0, 6)) * 0.008;
    let q = p + warp;

    // Torso: near-vertical bands whose period widens from the shoulder (0.10) to the flank
    // (0.16); phase = integral of dx / lambda(x) with lambda linear in x.
    let xw = q.x + 0.22 * (q.y - 0.93);
    let (a, b) = (0.1415f32, -0.0923f32);
    let lam_t = (a + b * xw).max(0.05);
    let vert = stripe(lam_t.ln() / b, lam_t, 0.5);
    // Haunch: stripes fanning out from a centre below the flank (rays of constant angle), so
    // they run vertically where they meet the torso bands, sweep back over the rump and turn
    // horizontal on the back of the thigh; their spacing r * dtheta widens away from the centre.
    let c = Vec3::new(0.0, 0.45, 0.0);
    let (dx, dy) = (q.x - c.x, q.y - c.y);
    let r = (dx * dx + dy * dy).sqrt().max(1e-3);
    let dtheta = 0.30;
    let arcs = stripe(dy.atan2(dx) / dtheta + 0.25, r * dtheta, 0.5);
    let hw = smoothstep(-0.05, -0.28, q.x);
    let mut torso = vert + (arcs - vert) * hw;
    // White belly midline, black dorsal line.
    torso -= smoothstep(0.78, 0.69, p.y) * smoothstep(0.16, 0.05, p.z.abs()) * 0.2;
    torso += smoothstep(0.03, 0.012, p.z.abs()) * smoothstep(1.08, 1.15, p.y) * 0.2;

    // Neck: rings around the neck axis, period 0.07, carried up into the mane.
    let nu = (Z_NECK_B - Z_NECK_A).normalize();
    let neck = stripe((q - Z_NECK_A).dot(nu) / 0.07 + 0.15, 0.07, 0.5);

    // Head: thin rings along the head axis (period 0.046), black muzzle, black ear tips.
    let hu = (Z_HEAD_B - Z_HEAD_A).normalize();
    let mut head = stripe((q - Z_HEAD_A).dot(hu) / 0.046, 0.046, 0.45);
    let muzzle = smoothstep(
        0.085,
        0.06,
        (p - (Z_MUZZLE + Vec3::new(0.035, -0.015, 0.0))).length(),
    );
    head += muzzle * 0.3;
    head += smoothstep(1.60, 1.63, p.y) * 0.2;

    // Legs: horizontal rings, period 0.05 low down widening to 0.075 at the top; black hooves.
    let lam_l = 0.05 + 0.025 * smoothstep(0.3, 0.8, p.y);
    let mut leg = stripe(q.y / lam_l, lam_l, 0.5);
    leg += smoothstep(0.075, 0.06, p.y) * 0.3;

    // Tail: rings (period 0.045), black tuft.
    let mut tail = stripe(q.y / 0.045, 0.045, 0.5);
    tail += smoothstep(0.66, 0.62, p.y) * 0.3;

    let region = [torso, neck, head, leg, leg, leg, leg, tail];
    // Region weights: the body-part distances, with the leg pattern kept off the torso and the
    // neck pattern off the chest so the patterns meet along short seams instead of mixing.
    let leg_pen = 0.3 * smoothstep(0.62, 0.80, p.y);
    let neck_pen = 0.3 * smoothstep(1.02, 0.88, p.y);
    let pen = [0.0, neck_pen, 0.0, leg_pen, leg_pen, leg_pen, leg_pen, 0.0];
    let dmin = parts
        .iter()
        .zip(pen)
        .map(|(d, e)| d + e)
        .fold(f32::INFINITY, f32::min);
    let (mut num, mut den) = (0.0f32, 0.0f32);
    for ((d, s), e) in parts.iter().zip(region).zip(pen) {
        let w = (-(d + e - dmin) / sigma).exp();
        num += w * s;
        den += w;
    }
    num / den
}

/// Zebra sRGB colour for a stripe signed distance, antialiased over `aa` scene units.
pub(crate) fn zebra_color(d: f32, aa: f32) -> [f32; 3] {
    const WHITE: [f32; 3] = [0.93, 0.91, 0.86];
    const BLACK: [f32; 3] = [0.10, 0.075, 0.06];
    let t = smoothstep(-0.5 * aa, 0.5 * aa, d);
    std::array::from_fn(|k| WHITE[k] + (BLACK[k] - WHITE[k]) * t)
}

/// Zebra landmarks: seed points near each feature projected onto the surface.
pub(crate) fn zebra_landmarks() -> Vec<(Landmark, [f32; 3])> {
    let seeds = [
        (Landmark::Nose, Vec3::new(1.14, 1.12, 0.0)),
        (Landmark::HeadTop, Vec3::new(0.74, 1.60, 0.0)),
        (Landmark::Neck, Vec3::new(0.56, 1.22, -0.35)),
        (Landmark::Back, Vec3::new(0.0, 1.40, 0.0)),
        (Landmark::Rump, Vec3::new(-0.36, 0.95, -0.45)),
        (Landmark::Belly, Vec3::new(0.0, 0.55, 0.0)),
        (Landmark::Chest, Vec3::new(0.70, 0.92, 0.0)),
        (Landmark::Tail, Vec3::new(-0.64, 0.40, 0.0)),
        (Landmark::FrontLeftFoot, Vec3::new(0.39, 0.0, -0.11)),
        (Landmark::FrontRightFoot, Vec3::new(0.39, 0.0, 0.11)),
        (Landmark::BackLeftFoot, Vec3::new(-0.385, 0.0, -0.11)),
        (Landmark::BackRightFoot, Vec3::new(-0.385, 0.0, 0.11)),
    ];
    seeds
        .iter()
        .map(|&(l, s)| (l, project(&zebra_sdf, s, 1e-3).to_array()))
        .collect()
}

// ---------------------------------------------------------------------------------------------
// Giraffe
// ---------------------------------------------------------------------------------------------

fn giraffe_leg_joints(front: bool, s: f32) -> [(Vec3, f32); 6] {
    let z = 0.10 * s;
    if front {
        [
            (Vec3::new(0.30, 1.32, z * 0.8), 0.10),
            (Vec3::new(0.30, 1.04, z), 0.068),
            (Vec3::new(0.31, 0.56, z), 0.040),
            (Vec3::new(0.32, 0.12, z), 0.030),
            (Vec3::new(0.33, 0.06, z), 0.034),
            (Vec3::new(0.34, 0.02, z), 0.042),
        ]
    } else {
        [
            (Vec3::new(-0.30, 1.26, z * 0.7), 0.14),
            (Vec3::new(-0.21, 1.00, z * 0.9), 0.085),
            (Vec3::new(-0.35, 0.60, z), 0.040),
            (Vec3::new(-0.33, 0.12, z), 0.030),
            (Vec3::new(-0.325, 0.06, z), 0.034),
            (Vec3::new(-0.32, 0.02, z), 0.042),
        ]
    }
}

const G_NECK_A: Vec3 = Vec3::new(0.30, 1.40, 0.0);
const G_NECK_B: Vec3 = Vec3::new(0.80, 2.36, 0.0);

static G_TILT: LazyLock<Quat> = LazyLock::new(|| Quat::from_rotation_z(0.18));
const G_TAIL_A: Vec3 = Vec3::new(-0.42, 1.30, 0.0);
const G_TAIL_B: Vec3 = Vec3::new(-0.50, 0.78, 0.0);
const G_TUFT: Vec3 = Vec3::new(-0.51, 0.70, 0.0);
static G_TUFT_ROT: LazyLock<Quat> = LazyLock::new(|| rot_x_to(G_TAIL_B - G_TAIL_A));
const G_HEAD_A: Vec3 = Vec3::new(0.80, 2.42, 0.0);
const G_HEAD_B: Vec3 = Vec3::new(1.04, 2.30, 0.0);

fn g_head(p: Vec3) -> f32 {
    let mut head = smin_all(
        &[
            round_cone(p, G_HEAD_A, G_HEAD_B, 0.075, 0.045),
            ellipsoid(
                p,
                Vec3::new(0.82, 2.38, 0.0),
                Vec3::new(0.08, 0.065, 0.06),
                Quat::IDENTITY,
            ),
            sphere(p, G_HEAD_B + Vec3::new(0.0, -0.005, 0.0), 0.05),
        ],
        0.05,
    );
    for s in [-1.0, 1.0] {
        let oss = smin(
            round_cone(
                p,
                Vec3::new(0.77, 2.46, 0.035 * s),
                Vec3::new(0.75, 2.58, 0.045 * s),
                0.022,
                0.018,
            ),
            sphere(p, Vec3::new(0.75, 2.59, 0.045 * s), 0.027),
            0.015,
        );
        let ear = round_cone(
            p,
            Vec3::new(0.76, 2.44, 0.05 * s),
            Vec3::new(0.72, 2.48, 0.15 * s),
            0.026,
            0.012,
        );
        head = smin(head, smin(oss, ear, 0.01), 0.02);
    }
    head
}

/// The giraffe's signed distance.
pub(crate) fn giraffe_sdf(p: Vec3) -> f32 {
    let tilt = *G_TILT;
    let mut d = smin_all(
        &[
            ellipsoid(
                p,
                Vec3::new(0.0, 1.30, 0.0),
                Vec3::new(0.46, 0.22, 0.18),
                tilt,
            ),
            ellipsoid(
                p,
                Vec3::new(0.26, 1.38, 0.0),
                Vec3::new(0.23, 0.24, 0.17),
                tilt,
            ),
            ellipsoid(
                p,
                Vec3::new(-0.28, 1.22, 0.0),
                Vec3::new(0.20, 0.19, 0.16),
                tilt,
            ),
        ],
        0.10,
    );
    let mane_a = Vec3::new(0.30, 1.62, 0.0);
    let mane_b = Vec3::new(0.72, 2.40, 0.0);
    d = blend_lazy(d, 0.12, capsule(p, G_NECK_A, G_NECK_B, 0.16), || {
        smin(
            round_cone(p, G_NECK_A, G_NECK_B, 0.15, 0.062),
            capsule(p, mane_a, mane_b, 0.018),
            0.06,
        )
    });
    d = blend_lazy(
        d,
        0.06,
        capsule(p, Vec3::new(0.76, 2.48, 0.0), G_HEAD_B, 0.2),
        || g_head(p),
    );
    for l in G_LEGS.iter() {
        d = l.blend_into(d, 0.07, p);
    }
    blend_lazy(d, 0.04, capsule(p, G_TAIL_A, G_TUFT, 0.1), || {
        smin(
            capsule(p, G_TAIL_A, G_TAIL_B, 0.018),
            ellipsoid(p, G_TUFT, Vec3::new(0.09, 0.032, 0.032), *G_TUFT_ROT),
            0.03,
        )
    })
}

/// Bounding box of the giraffe.
pub(crate) fn giraffe_bounds() -> (Vec3, Vec3) {
    (Vec3::new(-0.62, -0.01, -0.24), Vec3::new(1.12, 2.66, 0.24))
}

/// Giraffe landmarks (same conventions as the zebra's).
pub(crate) fn giraffe_landmarks() -> Vec<(Landmark, [f32; 3])> {
    let seeds = [
        (Landmark::Nose, Vec3::new(1.14, 2.28, 0.0)),
        (Landmark::HeadTop, Vec3::new(0.78, 2.60, 0.0)),
        (Landmark::Neck, Vec3::new(0.55, 1.88, -0.30)),
        (Landmark::Back, Vec3::new(0.0, 1.80, 0.0)),
        (Landmark::Rump, Vec3::new(-0.30, 1.20, -0.40)),
        (Landmark::Belly, Vec3::new(0.0, 0.85, 0.0)),
        (Landmark::Chest, Vec3::new(0.70, 1.30, 0.0)),
        (Landmark::Tail, Vec3::new(-0.52, 0.50, 0.0)),
        (Landmark::FrontLeftFoot, Vec3::new(0.34, 0.0, -0.10)),
        (Landmark::FrontRightFoot, Vec3::new(0.34, 0.0, 0.10)),
        (Landmark::BackLeftFoot, Vec3::new(-0.32, 0.0, -0.10)),
        (Landmark::BackRightFoot, Vec3::new(-0.32, 0.0, 0.10)),
    ];
    seeds
        .iter()
        .map(|&(l, s)| (l, project(&giraffe_sdf, s, 1e-3).to_array()))
        .collect()
}

// ---------------------------------------------------------------------------------------------
// Cerberus
// ---------------------------------------------------------------------------------------------

fn cerberus_leg_joints(front: bool, s: f32) -> [(Vec3, f32); 5] {
    let z = 0.10 * s;
    if front {
        [
            (Vec3::new(0.28, 0.64, z * 0.8), 0.085),
            (Vec3::new(0.25, 0.40, z), 0.058),
            (Vec3::new(0.28, 0.12, z), 0.036),
            (Vec3::new(0.30, 0.05, z), 0.042),
            (Vec3::new(0.33, 0.035, z), 0.040),
        ]
    } else {
        [
            (Vec3::new(-0.30, 0.66, z * 0.7), 0.11),
            (Vec3::new(-0.20, 0.42, z), 0.065),
            (Vec3::new(-0.34, 0.20, z), 0.036),
            (Vec3::new(-0.31, 0.05, z), 0.040),
            (Vec3::new(-0.28, 0.035, z), 0.040),
        ]
    }
}

/// Neck base, head centre and facing direction of cerberus head `i` (0 left, 1 centre, 2 right).
fn cerberus_head(i: usize) -> (Vec3, Vec3, Vec3) {
    let s = i as f32 - 1.0;
    let base = Vec3::new(0.30, 0.74, 0.07 * s);
    let head = Vec3::new(0.52 - 0.06 * s.abs(), 1.06 - 0.05 * s.abs(), 0.26 * s);
    let dir = Vec3::new(1.0, -0.15, 0.45 * s).normalize();
    (base, head, dir)
}

static DOG_HEADS: LazyLock<[(Vec3, Vec3, Vec3, Quat); 3]> = LazyLock::new(|| {
    std::array::from_fn(|i| {
        let (base, c, dir) = cerberus_head(i);
        (base, c, dir, rot_x_to(dir))
    })
});
static C_TILT: LazyLock<Quat> = LazyLock::new(|| Quat::from_rotation_z(0.05));

/// One dog head at `c` facing `dir` (`rot` takes +X to `dir`): skull, muzzle, nose, pointed ears.
fn dog_head(p: Vec3, c: Vec3, dir: Vec3, rot: Quat) -> f32 {
    let side = dir.cross(Vec3::Y).normalize();
    let mut d = smin_all(
        &[
            ellipsoid(p, c, Vec3::new(0.10, 0.085, 0.08), rot),
            round_cone(
                p,
                c + dir * 0.05 - Vec3::Y * 0.01,
                c + dir * 0.19 - Vec3::Y * 0.035,
                0.058,
                0.038,
            ),
            sphere(p, c + dir * 0.20 - Vec3::Y * 0.03, 0.032),
        ],
        0.05,
    );
    for s in [-1.0, 1.0] {
        let ear = round_cone(
            p,
            c + Vec3::Y * 0.05 + side * (0.045 * s) - dir * 0.02,
            c + Vec3::Y * 0.17 + side * (0.07 * s) - dir * 0.05,
            0.034,
            0.015,
        );
        d = smin(d, ear, 0.02);
    }
    d
}

/// The cerberus signed distance: one dog body with three necks and heads.
pub(crate) fn cerberus_sdf(p: Vec3) -> f32 {
    let mut d = smin_all(
        &[
            ellipsoid(
                p,
                Vec3::new(0.0, 0.63, 0.0),
                Vec3::new(0.40, 0.16, 0.15),
                *C_TILT,
            ),
            ellipsoid(
                p,
                Vec3::new(0.24, 0.66, 0.0),
                Vec3::new(0.21, 0.21, 0.19),
                Quat::IDENTITY,
            ),
            ellipsoid(
                p,
                Vec3::new(-0.28, 0.63, 0.0),
                Vec3::new(0.18, 0.16, 0.15),
                Quat::IDENTITY,
            ),
        ],
        0.09,
    );
    let heads = &*DOG_HEADS;
    let necks_lb = heads
        .iter()
        .map(|h| capsule(p, h.0, h.1, 0.11))
        .fold(f32::INFINITY, f32::min);
    d = blend_lazy(d, 0.10, necks_lb, || {
        let n: [f32; 3] = std::array::from_fn(|i| {
            let (base, c, dir, _) = heads[i];
            round_cone(p, base, c - dir * 0.03, 0.10, 0.065)
        });
        smin(smin(n[0], n[1], 0.04), n[2], 0.04)
    });
    let heads_lb = heads
        .iter()
        .map(|h| sphere(p, h.1 + h.2 * 0.06 + Vec3::Y * 0.04, 0.23))
        .fold(f32::INFINITY, f32::min);
    d = blend_lazy(d, 0.05, heads_lb, || {
        heads
            .iter()
            .map(|&(_, c, dir, rot)| dog_head(p, c, dir, rot))
            .fold(f32::INFINITY, f32::min)
    });
    for l in C_LEGS.iter() {
        d = l.blend_into(d, 0.06, p);
    }
    let t0 = Vec3::new(-0.38, 0.70, 0.0);
    let t1 = Vec3::new(-0.52, 0.82, 0.0);
    let t2 = Vec3::new(-0.60, 0.98, 0.0);
    let t3 = Vec3::new(-0.58, 1.08, 0.0);
    blend_lazy(d, 0.04, capsule(p, t0, t2, 0.16), || {
        smin(
            smin(
                round_cone(p, t0, t1, 0.036, 0.03),
                round_cone(p, t1, t2, 0.03, 0.024),
                0.02,
            ),
            round_cone(p, t2, t3, 0.024, 0.017),
            0.02,
        )
    })
}

/// Bounding box of cerberus.
pub(crate) fn cerberus_bounds() -> (Vec3, Vec3) {
    (Vec3::new(-0.72, -0.01, -0.52), Vec3::new(0.82, 1.30, 0.52))
}

/// Cerberus landmarks: three `Nose`, three `HeadTop` and three `Neck` entries, one per head
/// (left, centre, right), and the body landmarks once.
pub(crate) fn cerberus_landmarks() -> Vec<(Landmark, [f32; 3])> {
    let mut seeds = Vec::new();
    for i in 0..3 {
        let (base, c, dir) = cerberus_head(i);
        seeds.push((Landmark::Nose, c + dir * 0.30 - Vec3::Y * 0.03));
        seeds.push((Landmark::HeadTop, c + Vec3::Y * 0.15 + dir * 0.01));
        let mid = (base + c) * 0.5;
        let out = if i == 1 {
            Vec3::new(0.0, 0.0, -1.0)
        } else {
            Vec3::new(0.0, 0.0, i as f32 - 1.0)
        };
        seeds.push((Landmark::Neck, mid + out * 0.25));
    }
    seeds.extend([
        (Landmark::Back, Vec3::new(0.0, 1.0, 0.0)),
        (Landmark::Rump, Vec3::new(-0.30, 0.62, -0.40)),
        (Landmark::Belly, Vec3::new(0.0, 0.30, 0.0)),
        (Landmark::Chest, Vec3::new(0.60, 0.60, 0.0)),
        (Landmark::Tail, Vec3::new(-0.56, 1.20, 0.0)),
        (Landmark::FrontLeftFoot, Vec3::new(0.32, 0.0, -0.10)),
        (Landmark::FrontRightFoot, Vec3::new(0.32, 0.0, 0.10)),
        (Landmark::BackLeftFoot, Vec3::new(-0.29, 0.0, -0.10)),
        (Landmark::BackRightFoot, Vec3::new(-0.29, 0.0, 0.10)),
    ]);
    seeds
        .iter()
        .map(|&(l, s)| (l, project(&cerberus_sdf, s, 1e-3).to_array()))
        .collect()
}
