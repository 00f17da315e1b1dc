//! The procedural demo scene: determinism, watertight manifold meshes, zebra stripes, the
//! giraffe's neck, cerberus' three heads, landmarks and default correspondences.

use glam::Vec3;
use meshmatch::TriMesh;
use meshmatch::demo::{self, Landmark, sdf::signed_volume};
use std::sync::OnceLock;

fn scene() -> &'static demo::DemoScene {
    static S: OnceLock<demo::DemoScene> = OnceLock::new();
    S.get_or_init(|| {
        let t = std::time::Instant::now();
        let s = demo::scene();
        println!("demo::scene() took {:.3} s", t.elapsed().as_secs_f64());
        s
    })
}

fn assert_clean(name: &str, m: &TriMesh) {
    let r = m.validate();
    println!("{name}: {r:?}");
    assert_eq!(r.components, 1, "{name}: components");
    assert_eq!(r.boundary_loops, 0, "{name}: boundary loops");
    assert_eq!(r.non_manifold_edges, 0, "{name}: non-manifold edges");
    assert_eq!(r.non_manifold_vertices, 0, "{name}: non-manifold vertices");
    assert_eq!(r.degenerate_faces, 0, "{name}: degenerate faces");
    assert_eq!(r.duplicate_faces, 0, "{name}: duplicate faces");
    assert_eq!(r.isolated_vertices, 0, "{name}: isolated vertices");
    assert_eq!(r.non_finite_vertices, 0, "{name}: non-finite vertices");
    // Closed surface: Euler characteristic of a sphere-like genus-0 surface is 2.
    let edges = 3 * r.faces / 2;
    let chi = r.vertices as i64 - edges as i64 + r.faces as i64;
    assert_eq!(
        chi, 2,
        "{name}: Euler characteristic {chi} (expected genus 0)"
    );
    // Consistent orientation: every directed edge is used by exactly one face.
    let mut directed: Vec<(u32, u32)> = m
        .faces
        .iter()
        .flat_map(|f| [(f[0], f[1]), (f[1], f[2]), (f[2], f[0])])
        .collect();
    directed.sort_unstable();
    let clashes = directed.windows(2).filter(|w| w[0] == w[1]).count();
    assert_eq!(
        clashes, 0,
        "{name}: {clashes} inconsistently oriented edges"
    );
    let vol = signed_volume(m);
    assert!(
        vol > 0.0,
        "{name}: signed volume {vol} (faces must face outward)"
    );
    if let Some(n) = &m.normals {
        assert_eq!(n.len(), m.num_vertices());
        // No folded triangles: each face's geometric normal agrees with its vertex normals.
        let folded = m
            .faces
            .iter()
            .filter(|f| {
                let [a, b, c] = f.map(|v| Vec3::from(m.positions[v as usize]));
                let face_n = (b - a).cross(c - a);
                let vn: Vec3 = f.iter().map(|&v| Vec3::from(n[v as usize])).sum();
                let bad = face_n.dot(vn) <= 0.0;
                if bad && std::env::var("DEMO_DEBUG").is_ok() {
                    println!("{name}: folded face at {:?}", (a + b + c) / 3.0);
                }
                bad
            })
            .count();
        println!("{name}: {folded} folded faces");
        assert_eq!(folded, 0, "{name}: folded faces");
    }
}

#[test]
fn meshes_are_closed_oriented_manifolds() {
    let s = scene();
    for (name, m) in [
        ("zebra", &s.zebra),
        ("giraffe", &s.giraffe),
        ("cerberus", &s.cerberus),
        ("vase", &s.vase),
    ] {
        assert_clean(name, m);
    }
}

#[test]
fn scene_is_deterministic() {
    let a = scene();
    let b = demo::scene();
    for (x, y) in [
        (&a.zebra, &b.zebra),
        (&a.giraffe, &b.giraffe),
        (&a.cerberus, &b.cerberus),
        (&a.vase, &b.vase),
    ] {
        assert_eq!(x.positions, y.positions);
        assert_eq!(x.faces, y.faces);
        assert_eq!(x.colors, y.colors);
    }
    assert_eq!(a.vase_painted, b.vase_painted);
}

#[test]
fn animals_stand_on_the_ground_and_have_sensible_size() {
    let s = scene();
    println!(
        "vertices: zebra {}, giraffe {}, cerberus {}, vase {}",
        s.zebra.num_vertices(),
        s.giraffe.num_vertices(),
        s.cerberus.num_vertices(),
        s.vase.num_vertices()
    );
    let n = s.zebra.num_vertices();
    assert!((20_000..=60_000).contains(&n), "zebra has {n} vertices");
    for (name, m) in [
        ("zebra", &s.zebra),
        ("giraffe", &s.giraffe),
        ("cerberus", &s.cerberus),
    ] {
        let (lo, hi) = m.bounds().unwrap();
        println!("{name}: bounds {lo:?} .. {hi:?}");
        assert!(
            lo[1].abs() < 0.005,
            "{name}: lowest point {} not on y=0",
            lo[1]
        );
        let len = hi[0] - lo[0];
        assert!((1.2..2.2).contains(&len), "{name}: length {len}");
        // Longer along X (facing +X) than wide along Z.
        assert!(hi[2] - lo[2] < 0.7 * len, "{name}: too wide");
    }
    assert!(s.giraffe.colors.is_none());
    assert!(s.cerberus.colors.is_none());
    assert!(s.zebra.colors.as_ref().is_some_and(|c| c.len() == n));
}

fn luminance(c: [f32; 3]) -> f32 {
    0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]
}

fn mark(marks: &[(Landmark, [f32; 3])], l: Landmark) -> Vec3 {
    Vec3::from(marks.iter().find(|m| m.0 == l).unwrap().1)
}

/// Stripe edges per unit area within `radius` of `centre`: mesh edges whose ends fall on
/// opposite sides of mid-grey, divided by the area of the faces in the ball.
fn transitions_per_area(m: &TriMesh, centre: Vec3, radius: f32) -> f32 {
    let cols = m.colors.as_ref().unwrap();
    let dark: Vec<bool> = cols.iter().map(|&c| luminance(c) < 0.45).collect();
    let inside = |v: u32| (Vec3::from(m.positions[v as usize]) - centre).length() < radius;
    let (mut cuts, mut area) = (0usize, 0.0f32);
    for f in &m.faces {
        if !f.iter().all(|&v| inside(v)) {
            continue;
        }
        let [a, b, c] = f.map(|v| Vec3::from(m.positions[v as usize]));
        area += 0.5 * (b - a).cross(c - a).length();
        for k in 0..3 {
            // Each interior edge is seen twice; count it from its lower-index side only.
            let (u, v) = (f[k], f[(k + 1) % 3]);
            if u < v && dark[u as usize] != dark[v as usize] {
                cuts += 1;
            }
        }
    }
    assert!(area > 0.01, "region around {centre} is too small: {area}");
    cuts as f32 / area
}

#[test]
fn zebra_stripes_look_like_a_zebra() {
    let s = scene();
    let cols = s.zebra.colors.as_ref().unwrap();
    let black = cols.iter().filter(|&&c| luminance(c) < 0.45).count() as f32 / cols.len() as f32;
    let grey = cols
        .iter()
        .filter(|&&c| (0.25..0.65).contains(&luminance(c)))
        .count() as f32
        / cols.len() as f32;
    println!("zebra black fraction {black:.3}, in-between (antialiased) {grey:.3}");
    assert!((0.30..=0.60).contains(&black), "black fraction {black}");
    // Crisp: only a thin antialiasing band is neither black nor white.
    assert!(grey < 0.15, "too much grey: {grey}");
    // Dark brown-black and slightly warm off-white, not pure.
    let darkest = cols
        .iter()
        .copied()
        .min_by(|a, b| luminance(*a).total_cmp(&luminance(*b)))
        .unwrap();
    let lightest = cols
        .iter()
        .copied()
        .max_by(|a, b| luminance(*a).total_cmp(&luminance(*b)))
        .unwrap();
    assert!(
        darkest[0] > 0.02 && darkest[0] >= darkest[2],
        "black {darkest:?}"
    );
    assert!(
        lightest[0] < 0.99 && lightest[0] >= lightest[2],
        "white {lightest:?}"
    );

    let marks = demo::landmarks_zebra();
    let neck = transitions_per_area(&s.zebra, mark(&marks, Landmark::Neck), 0.12);
    let rump = transitions_per_area(&s.zebra, mark(&marks, Landmark::Rump), 0.15);
    let fl = mark(&marks, Landmark::FrontLeftFoot);
    let leg = transitions_per_area(&s.zebra, fl + Vec3::new(0.0, 0.25, 0.0), 0.12);
    println!("stripe edges per unit area: neck {neck:.0}, legs {leg:.0}, hindquarters {rump:.0}");
    assert!(
        neck > 1.4 * rump,
        "neck stripes ({neck}) not denser than hindquarters ({rump})"
    );
    assert!(
        leg > 1.4 * rump,
        "leg stripes ({leg}) not denser than hindquarters ({rump})"
    );
}

fn assert_marks_on_mesh(name: &str, m: &TriMesh, marks: &[(Landmark, [f32; 3])]) {
    for &(l, p) in marks {
        let v = demo::nearest_vertex(m, p).unwrap();
        let d = (Vec3::from(m.positions[v as usize]) - Vec3::from(p)).length();
        assert!(d < 0.02, "{name}: {l:?} at {p:?} is {d} from the mesh");
    }
}

#[test]
fn landmarks_lie_on_their_meshes_and_make_sense() {
    let s = scene();
    let z = demo::landmarks_zebra();
    let g = demo::landmarks_giraffe();
    let c = demo::landmarks_cerberus();
    assert_marks_on_mesh("zebra", &s.zebra, &z);
    assert_marks_on_mesh("giraffe", &s.giraffe, &g);
    assert_marks_on_mesh("cerberus", &s.cerberus, &c);
    for (name, marks) in [("zebra", &z), ("giraffe", &g), ("cerberus", &c)] {
        let nose = mark(marks, Landmark::Nose);
        let tail = mark(marks, Landmark::Tail);
        assert!(
            nose.x > tail.x + 1.0,
            "{name}: nose must be at +X, far from the tail"
        );
        assert!(mark(marks, Landmark::Back).y > mark(marks, Landmark::Belly).y + 0.2);
        for f in [
            Landmark::FrontLeftFoot,
            Landmark::FrontRightFoot,
            Landmark::BackLeftFoot,
            Landmark::BackRightFoot,
        ] {
            assert!(mark(marks, f).y < 0.02, "{name}: {f:?} not on the ground");
        }
        // Left is -Z.
        assert!(mark(marks, Landmark::FrontLeftFoot).z < mark(marks, Landmark::FrontRightFoot).z);
    }
    // The giraffe's head is far above its back.
    let (head, back) = (mark(&g, Landmark::HeadTop), mark(&g, Landmark::Back));
    println!("giraffe head top {:.2}, back {:.2}", head.y, back.y);
    assert!(head.y > 1.6 * back.y);
    let zr = mark(&z, Landmark::HeadTop).y / mark(&z, Landmark::Back).y;
    assert!(zr < 1.4, "zebra head/back ratio {zr}");
    // Cerberus: three heads, pairwise far apart.
    let noses: Vec<Vec3> = c
        .iter()
        .filter(|m| m.0 == Landmark::Nose)
        .map(|m| Vec3::from(m.1))
        .collect();
    let tops: Vec<Vec3> = c
        .iter()
        .filter(|m| m.0 == Landmark::HeadTop)
        .map(|m| Vec3::from(m.1))
        .collect();
    assert_eq!(noses.len(), 3);
    assert_eq!(tops.len(), 3);
    for i in 0..3 {
        for j in i + 1..3 {
            assert!(
                (noses[i] - noses[j]).length() > 0.25,
                "noses {i} {j} too close"
            );
            assert!(
                (tops[i] - tops[j]).length() > 0.25,
                "head tops {i} {j} too close"
            );
        }
    }
}

#[test]
fn default_correspondences_map_landmarks() {
    let s = scene();
    let z = demo::landmarks_zebra();
    let g = demo::landmarks_giraffe();
    let c = demo::landmarks_cerberus();
    let zg = demo::default_correspondences(&s.zebra, &z, &s.giraffe, &g);
    assert_eq!(zg.correspondences.len(), z.len());
    for (corr, (_, p)) in zg.correspondences.iter().zip(&z) {
        assert_eq!(corr.target_vertices.len(), 1);
        let q = Vec3::from(s.zebra.positions[corr.source_vertex as usize]);
        assert!((q - Vec3::from(*p)).length() < 0.02);
    }
    let zc = demo::default_correspondences(&s.zebra, &z, &s.cerberus, &c);
    let nose_v = demo::nearest_vertex(&s.zebra, mark(&z, Landmark::Nose).to_array()).unwrap();
    let nose = zc
        .correspondences
        .iter()
        .find(|k| k.source_vertex == nose_v)
        .expect("nose correspondence");
    assert_eq!(
        nose.target_vertices.len(),
        3,
        "one-to-many to the three heads"
    );
    let heads: Vec<Vec3> = nose
        .target_vertices
        .iter()
        .map(|&v| Vec3::from(s.cerberus.positions[v as usize]))
        .collect();
    assert!((heads[0] - heads[2]).length() > 0.25);
    // Every index is valid and the JSON round-trips.
    for k in &zc.correspondences {
        assert!((k.source_vertex as usize) < s.zebra.num_vertices());
        assert!(
            k.target_vertices
                .iter()
                .all(|&v| (v as usize) < s.cerberus.num_vertices())
        );
    }
    let json = serde_json::to_string(&zc).unwrap();
    let back: meshmatch::correspondence::CorrespondenceFile = serde_json::from_str(&json).unwrap();
    assert_eq!(back, zc);
}

#[test]
fn vase_is_painted_on_its_upper_part_only() {
    let s = scene();
    let (m, painted) = (&s.vase, &s.vase_painted);
    assert_eq!(painted.len(), m.num_vertices());
    let (lo, hi) = m.bounds().unwrap();
    let frac = painted.iter().filter(|&&p| p).count() as f32 / painted.len() as f32;
    println!(
        "vase: {} vertices, painted fraction {frac:.3}",
        m.num_vertices()
    );
    assert!((0.2..0.6).contains(&frac), "painted fraction {frac}");
    let cols = m.colors.as_ref().unwrap();
    let clay = cols[0];
    let h = hi[1] - lo[1];
    for (i, (&p, &c)) in m.positions.iter().zip(cols).enumerate() {
        let rel = (p[1] - lo[1]) / h;
        if painted[i] {
            assert!(rel > 0.55, "painted vertex at relative height {rel}");
        } else {
            assert_eq!(c, clay, "unpainted vertex {i} is not clay");
        }
    }
    // The painted zone carries a pattern: several distinct colours.
    let mut distinct: Vec<[u8; 3]> = cols
        .iter()
        .zip(painted)
        .filter(|(_, p)| **p)
        .map(|(c, _)| c.map(|x| (x * 4.0).round() as u8))
        .collect();
    distinct.sort();
    distinct.dedup();
    assert!(
        distinct.len() >= 3,
        "painted zone has {} colours",
        distinct.len()
    );
    // A vase, not a cylinder: it has a foot and a lip wider than its neck.
    let radius_at = |y: f32| {
        m.positions
            .iter()
            .filter(|p| (p[1] - y).abs() < 0.01)
            .map(|p| (p[0] * p[0] + p[2] * p[2]).sqrt())
            .fold(0.0f32, f32::max)
    };
    let (belly, neck, lip) = (
        radius_at(0.36 * h),
        radius_at(0.78 * h),
        radius_at(0.99 * h),
    );
    assert!(
        belly > 1.8 * neck && lip > neck * 1.2,
        "belly {belly} neck {neck} lip {lip}"
    );
}
