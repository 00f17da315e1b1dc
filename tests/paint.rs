//! Painting as a texture painter expects: a dab paints only what the view sees (a thin slab's
//! far side and the giraffe's far side of the neck stay clean, "paint through" reaches them);
//! on a mesh with UVs the paint lives in a texel layer at the texture's resolution (a stroke
//! across a UV seam paints both charts without a gap or a bleed into the gutter, its edge is the
//! brush's, undo restores the layer exactly, a GLB export carries it at full resolution, and
//! completion reads it as it reads vertex paint). A region fill stays inside its region (it stops
//! at a strong colour edge, crosses UV seams, never reaches the gutter), an island fill paints
//! exactly its chart's texels, undo of a fill restores the layer exactly; hidden layers stay out
//! of the composite and the export, opacity 0.5 blends half, and sessions keep the mask.

#![cfg(feature = "gui")]

mod scratch;

use eframe::egui;
use glam::{Vec2, Vec3};
use meshmatch::TriMesh;
use meshmatch::app::AppParams;
use meshmatch::app::brush::BrushView;
use meshmatch::app::state::AppState;
use meshmatch::correspondence::Side;
use meshmatch::render::{Camera, Frame};

#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
struct NoParams;

impl AppParams for NoParams {
    fn ui(&mut self, _: &mut egui::Ui) -> bool {
        false
    }
}

/// A view of 800x600 points looking along `-dir` at the mesh, the pointer over `p`.
fn view_of(mesh: &TriMesh, dir: Vec3, p: Vec3) -> BrushView {
    let d = dir.normalize();
    let camera = Camera {
        azimuth_deg: d.x.atan2(d.z).to_degrees(),
        elevation_deg: d.y.clamp(-1.0, 1.0).asin().to_degrees(),
        zoom: 1.0,
        pan: [0.0, 0.0],
    };
    let frame = Frame::of_points(&mesh.positions);
    let size = Vec2::new(800.0, 600.0);
    let s = camera
        .project(&frame, p, size)
        .expect("in front of the eye");
    BrushView::new(&camera, &frame, size, s, p)
}

/// An `n`x`n` grid over `[0, 1]²` at height `z`, facing +Z (or -Z when `flip`).
fn grid(n: u32, z: f32, flip: bool, m: &mut TriMesh) {
    let base = m.positions.len() as u32;
    for y in 0..=n {
        for x in 0..=n {
            m.positions
                .push([x as f32 / n as f32, y as f32 / n as f32, z]);
        }
    }
    for y in 0..n {
        for x in 0..n {
            let a = base + y * (n + 1) + x;
            let (b, c, d) = (a + 1, a + n + 1, a + n + 2);
            if flip {
                m.faces.push([a, c, b]);
                m.faces.push([b, c, d]);
            } else {
                m.faces.push([a, b, c]);
                m.faces.push([b, d, c]);
            }
        }
    }
}

/// A closed thin slab: a 1x1 square, `t` thick, both large sides finely gridded.
fn slab(t: f32) -> TriMesh {
    let mut m = TriMesh::default();
    grid(40, t * 0.5, false, &mut m);
    grid(40, -t * 0.5, true, &mut m);
    // Close the rim (the four thin sides).
    let n = 41u32;
    let back = n * n;
    let rim: Vec<u32> = (0..40)
        .chain((0..40).map(|y| 40 + y * n))
        .chain((0..40).map(|x| 40 * n + 40 - x))
        .chain((0..40).map(|y| (40 - y) * n))
        .collect();
    for k in 0..rim.len() {
        let (a, b) = (rim[k], rim[(k + 1) % rim.len()]);
        m.faces.push([a, back + a, b]);
        m.faces.push([b, back + a, back + b]);
    }
    m.file_index = (0..m.positions.len() as u32).collect();
    m.file_vertex_count = m.positions.len();
    m
}

fn state_with(side: Side, mesh: TriMesh) -> AppState<NoParams> {
    let mut s = AppState::<NoParams>::new();
    s.set_mesh(side, mesh, false);
    s
}

#[test]
fn a_dab_from_the_view_leaves_the_far_side_of_a_thin_slab_unpainted() {
    let t = 0.02;
    let mesh = slab(t);
    let mut st = state_with(Side::Source, mesh.clone());
    st.brush.radius = 0.1;
    st.brush.hardness = 0.8;
    let centre = Vec3::new(0.5, 0.5, t * 0.5);
    let view = view_of(&mesh, Vec3::Z, centre);
    let n = st.paint_dab(Side::Source, &view, true);
    assert!(n > 0);
    let cov = st.paint_coverage(Side::Source).unwrap();
    let front: Vec<usize> = (0..mesh.positions.len())
        .filter(|&v| mesh.positions[v][2] > 0.0)
        .collect();
    let painted_front = front.iter().filter(|&&v| cov[v] > 0.5).count();
    assert!(
        painted_front >= 10,
        "{painted_front} front vertices painted"
    );
    for (v, p) in mesh.positions.iter().enumerate() {
        if p[2] < 0.0 {
            assert_eq!(cov[v], 0.0, "far-side vertex {v} at {p:?} painted");
        }
    }
    // Paint through (a ball thicker than the slab) reaches the far side.
    st.brush.through = true;
    st.paint_dab(Side::Source, &view, true);
    let cov = st.paint_coverage(Side::Source).unwrap();
    let far = (0..mesh.positions.len())
        .filter(|&v| mesh.positions[v][2] < 0.0 && cov[v] > 0.5)
        .count();
    assert!(far >= 10, "paint through reached {far} far-side vertices");
}

#[test]
fn a_dab_on_the_giraffes_neck_leaves_the_far_side_clean() {
    let giraffe = meshmatch::demo::giraffe();
    let neck = meshmatch::demo::landmarks_giraffe()
        .into_iter()
        .find(|(l, _)| *l == meshmatch::demo::Landmark::Neck)
        .expect("a neck landmark")
        .1;
    let v = meshmatch::demo::nearest_vertex(&giraffe, neck).unwrap() as usize;
    let mut st = state_with(Side::Target, giraffe.clone());
    // The normals the app paints with.
    let normals = st.slot(Side::Target).unwrap().normals.clone();
    let p = Vec3::from(giraffe.positions[v]);
    let view = view_of(&giraffe, Vec3::from(normals[v]), p);
    // The default brush.
    let n = st.paint_dab(Side::Target, &view, true);
    assert!(n > 20, "{n} vertices painted");
    let cov = st.paint_coverage(Side::Target).unwrap();
    let facing_away =
        |v: usize| Vec3::from(normals[v]).dot(view.eye - Vec3::from(giraffe.positions[v])) < 0.0;
    for (v, &c) in cov.iter().enumerate() {
        if facing_away(v) {
            assert_eq!(c, 0.0, "vertex {v} facing away from the view is painted");
        }
    }
    // A ball (paint through) as wide as the neck goes round it.
    st.brush.through = true;
    st.brush.radius = 0.2;
    st.paint_dab(Side::Target, &view, true);
    let cov = st.paint_coverage(Side::Target).unwrap();
    let behind = (0..giraffe.positions.len())
        .filter(|&v| facing_away(v) && cov[v] > 0.5)
        .count();
    assert!(
        behind > 20,
        "paint through reached {behind} vertices facing away"
    );
}

/// A 1x1 plane (z = 0, facing +Z, `n`x`n` grid) whose left half (x < 0.5) is laid out at
/// u in [0.05, 0.45] and right half at u in [0.55, 0.95] (a seam down the middle), v = 0.05 +
/// 0.9 y.
fn seamed_plane(n: u32) -> TriMesh {
    let mut m = TriMesh::default();
    grid(n, 0.0, false, &mut m);
    let uv = |p: [f32; 3], right: bool| -> [f32; 2] {
        let u = if right {
            0.55 + 0.8 * (p[0] - 0.5)
        } else {
            0.05 + 0.8 * p[0]
        };
        [u, 0.05 + 0.9 * p[1]]
    };
    let uvs = m
        .faces
        .iter()
        .flat_map(|f| {
            let right = f.iter().map(|&v| m.positions[v as usize][0]).sum::<f32>() / 3.0 > 0.5;
            f.map(|v| uv(m.positions[v as usize], right))
        })
        .collect();
    m.uvs = Some(uvs);
    m.file_index = (0..m.positions.len() as u32).collect();
    m.file_vertex_count = m.positions.len();
    m
}

/// A stroke of dabs from `a` to `b` (world, on the plane) seen from +Z.
fn stroke(st: &mut AppState<NoParams>, mesh: &TriMesh, a: Vec3, b: Vec3, dabs: usize) {
    for k in 0..=dabs {
        let p = a.lerp(b, k as f32 / dabs as f32);
        let view = view_of(mesh, Vec3::Z, p);
        st.paint_dab(Side::Target, &view, k == 0);
    }
}

#[test]
fn a_stroke_across_a_uv_seam_paints_both_charts_at_texel_resolution() {
    let mesh = seamed_plane(8);
    let mut st = state_with(Side::Target, mesh.clone());
    st.brush.radius = 0.05;
    st.brush.hardness = 0.999;
    st.brush.color = [0.0, 0.2, 1.0];
    stroke(
        &mut st,
        &mesh,
        Vec3::new(0.25, 0.5, 0.0),
        Vec3::new(0.75, 0.5, 0.0),
        50,
    );
    let slot = st.slot(Side::Target).unwrap();
    assert!(
        slot.paint.is_none(),
        "a mesh with UVs takes no vertex paint"
    );
    let layer = slot.texels.as_ref().expect("a texel layer");
    assert_eq!((layer.width, layer.height), (2048, 2048));
    // Along the stroke's line on the surface, both sides of the seam: painted everywhere.
    for k in 0..=400 {
        let x = 0.3 + 0.4 * k as f32 / 400.0;
        let right = x > 0.5;
        let u = if right {
            0.55 + 0.8 * (x - 0.5)
        } else {
            0.05 + 0.8 * x
        };
        let s = layer.sample([u, 0.05 + 0.9 * 0.5]);
        assert!(s[3] > 0.97, "gap at x = {x}: coverage {}", s[3]);
        assert!((s[2] - 1.0).abs() < 0.01 && s[0] < 0.01, "{s:?} at x = {x}");
    }
    // The gutter between the charts (u in (0.45, 0.55), beyond a texel and a half of either
    // chart) stays empty.
    let (lo, hi) = ((0.45 * 2048.0 + 1.5) as u32, (0.55 * 2048.0 - 1.5) as u32);
    for y in 0..2048 {
        for x in lo..=hi {
            assert_eq!(
                layer.get(x, y)[3],
                0,
                "paint in the gutter at texel {x},{y}"
            );
        }
    }
    // The stroke's edge is the brush's: across it (along y at x = 0.3), coverage goes from
    // full to none within two texels, not over a triangle (256 texels here).
    let column = ((0.05 + 0.8 * 0.3) * 2048.0) as u32;
    let alpha: Vec<u8> = (0..2048).map(|y| layer.get(column, y)[3]).collect();
    let full = alpha.iter().filter(|&&a| a == 255).count();
    let partial = alpha.iter().filter(|&&a| a > 0 && a < 255).count();
    assert!(full > 50, "{full} full texels across the stroke");
    assert!(
        partial <= 4,
        "{partial} partial texels across the stroke's two edges"
    );
}

#[test]
fn undo_of_a_texel_stroke_restores_the_layer_exactly_and_redo_puts_it_back() {
    let mesh = seamed_plane(8);
    let mut st = state_with(Side::Target, mesh.clone());
    st.brush.radius = 0.08;
    st.brush.hardness = 0.3;
    st.brush.color = [1.0, 0.5, 0.0];
    stroke(
        &mut st,
        &mesh,
        Vec3::new(0.2, 0.3, 0.0),
        Vec3::new(0.6, 0.4, 0.0),
        20,
    );
    let first = st
        .slot(Side::Target)
        .unwrap()
        .texels
        .as_ref()
        .unwrap()
        .to_image();
    st.brush.color = [0.1, 0.9, 0.2];
    stroke(
        &mut st,
        &mesh,
        Vec3::new(0.3, 0.2, 0.0),
        Vec3::new(0.4, 0.8, 0.0),
        20,
    );
    let second = st
        .slot(Side::Target)
        .unwrap()
        .texels
        .as_ref()
        .unwrap()
        .to_image();
    assert_ne!(first, second);
    assert!(st.undo());
    let layer = st.slot(Side::Target).unwrap().texels.as_ref().unwrap();
    assert!(layer.to_image() == first, "undo did not restore the layer");
    assert!(st.redo());
    let layer = st.slot(Side::Target).unwrap().texels.as_ref().unwrap();
    assert!(
        layer.to_image() == second,
        "redo did not restore the stroke"
    );
    assert!(st.undo());
    assert!(st.undo());
    assert!(
        st.slot(Side::Target).unwrap().texels.is_none(),
        "undoing the first stroke removes the layer"
    );
}

#[test]
fn a_glb_export_carries_the_texel_layer_at_full_resolution() {
    let dir = scratch::Scratch::new("paint_glb");
    let mesh = seamed_plane(8);
    let mut st = state_with(Side::Target, mesh.clone());
    st.brush.radius = 0.04;
    st.brush.hardness = 0.999;
    st.brush.color = [1.0, 0.0, 1.0];
    let centre = Vec3::new(0.3, 0.6, 0.0);
    st.paint_dab(Side::Target, &view_of(&mesh, Vec3::Z, centre), true);
    let out = dir.join("painted.glb");
    let m = st.painted_export_mesh(Side::Target).unwrap();
    meshmatch::mesh::io::save(&m, &out).unwrap();
    let back = meshmatch::mesh::io::load(&out).unwrap();
    let tex = back.texture.as_ref().expect("a texture in the GLB");
    assert_eq!(tex.image.dimensions(), (2048, 2048));
    let layer = st.slot(Side::Target).unwrap().texels.as_ref().unwrap();
    // Every texel of the layer, painted or not, is in the file (PNG: lossless).
    let base = meshmatch::render::gpu::DEFAULT_VERTEX_COLOR.map(|c| (c * 255.0).round() as u8);
    let mut painted = 0;
    for y in 0..2048 {
        for x in 0..2048 {
            let p = layer.get(x, y);
            if p[3] == 255 {
                painted += 1;
                assert_eq!(tex.image.get_pixel(x, y).0, [p[0], p[1], p[2]]);
            }
        }
    }
    assert!(painted > 1000, "{painted} painted texels");
    // An unpainted texel inside a chart keeps the base colour.
    let (x, y) = ((0.9 * 2048.0) as u32, (0.5 * 2048.0) as u32);
    assert_eq!(layer.get(x, y)[3], 0);
    assert_eq!(tex.image.get_pixel(x, y).0, base);
}

/// A UV sphere (latitude-longitude UVs, a seam at longitude 0).
fn uv_sphere(rings: u32, segs: u32) -> TriMesh {
    meshmatch::app::paint_bench::lat_long_sphere(rings, segs)
}

#[test]
fn completion_reads_a_texel_layer_as_it_reads_vertex_paint() {
    let mesh = uv_sphere(24, 48);
    let mut st = state_with(Side::Target, mesh.clone());
    st.brush.radius = 0.25;
    st.brush.hardness = 0.9;
    st.brush.color = [0.1, 0.7, 0.2];
    st.brush.through = true;
    // Paint the upper cap from above (through: a ball), one stroke.
    let mut first = true;
    for p in &mesh.positions {
        if p[1] > 0.4 {
            st.paint_at(Side::Target, *p, first);
            first = false;
        }
    }
    let slot = st.slot(Side::Target).unwrap();
    assert!(slot.texels.is_some() && slot.paint.is_none());
    let cov = st.paint_coverage(Side::Target).unwrap();
    for (v, p) in mesh.positions.iter().enumerate() {
        if p[1] > 0.45 {
            assert!(cov[v] > 0.5, "vertex {v} at {p:?}: coverage {}", cov[v]);
        }
        if p[1] < 0.0 {
            assert_eq!(cov[v], 0.0);
        }
    }
    let painted = st.painted_mesh(Side::Target).unwrap();
    let cols = painted.colors.as_ref().unwrap();
    for (v, c) in cols.iter().enumerate() {
        if cov[v] > 0.99 {
            assert!((c[1] - 0.7).abs() < 0.02, "{c:?}");
        }
    }
    let job = meshmatch::app::tools::completion_job(Side::Target, painted, cov, || {}).unwrap();
    let outcome = job.wait().unwrap();
    st.apply_tool_outcome(outcome);
    // The rest of the sphere is completed from the painted green.
    let out = st.slot(Side::Target).unwrap().painted_colors();
    for (v, p) in mesh.positions.iter().enumerate() {
        if p[1] < -0.2 {
            let c = out[v];
            assert!(
                (c[0] - 0.1).abs() < 0.1 && (c[1] - 0.7).abs() < 0.1 && (c[2] - 0.2).abs() < 0.1,
                "vertex {v} at {p:?} completed as {c:?}"
            );
        }
    }
}

#[test]
fn a_face_in_front_hides_the_one_behind_in_the_dab_depth_buffer() {
    use meshmatch::app::brush::Dab;
    let view = BrushView::new(
        &Camera {
            azimuth_deg: 0.0,
            elevation_deg: 0.0,
            zoom: 1.0,
            pan: [0.0, 0.0],
        },
        &Frame {
            center: Vec3::ZERO,
            radius: 1.0,
        },
        Vec2::new(200.0, 200.0),
        Vec2::new(100.0, 100.0),
        Vec3::new(0.0, 0.0, 0.1),
    );
    // Two parallel squares facing +Z (the camera), 0.2 apart.
    let mut pos = Vec::new();
    for z in [0.1f32, -0.1] {
        for (x, y) in [(-0.5, -0.5), (0.5, -0.5), (0.5, 0.5), (-0.5, 0.5)] {
            pos.push([x, y, z]);
        }
    }
    let faces = vec![[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7]];
    let dab = Dab::new(view, 20.0, 0.5, true, &pos, &faces, 1.0);
    let n = Vec3::Z;
    assert!(dab.weight(Vec3::new(0.01, 0.0, 0.1), n) > 0.9);
    assert_eq!(dab.weight(Vec3::new(0.01, 0.0, -0.1), n), 0.0);
    // Outside the disc.
    assert_eq!(dab.weight(Vec3::new(0.45, 0.0, 0.1), n), 0.0);
}

#[test]
fn a_session_keeps_the_texel_layer_in_a_png_beside_it() {
    let dir = scratch::Scratch::new("paint_session");
    let plane = dir.join("plane.glb");
    meshmatch::mesh::io::save(&seamed_plane(8), &plane).unwrap();
    let mut st = AppState::<NoParams>::new();
    st.open_mesh(Side::Source, &plane).unwrap();
    st.open_mesh(Side::Target, &plane).unwrap();
    let mesh = st.slot(Side::Target).unwrap().displayed().clone();
    st.brush.color = [0.9, 0.8, 0.1];
    stroke(
        &mut st,
        &mesh,
        Vec3::new(0.2, 0.2, 0.0),
        Vec3::new(0.8, 0.7, 0.0),
        30,
    );
    let painted = st
        .slot(Side::Target)
        .unwrap()
        .texels
        .as_ref()
        .unwrap()
        .to_image();
    // A mask stroke too, into the mask layer.
    st.brush.target = meshmatch::app::state::PaintTarget::Mask;
    st.brush.color = [0.1, 0.2, 0.9];
    stroke(
        &mut st,
        &mesh,
        Vec3::new(0.2, 0.8, 0.0),
        Vec3::new(0.8, 0.3, 0.0),
        30,
    );
    let mask = st
        .slot(Side::Target)
        .unwrap()
        .mask_texels
        .as_ref()
        .unwrap()
        .to_image();
    let session = dir.join("s.json");
    st.save_session(&session).unwrap();
    assert!(dir.join("s.target_paint_texels.png").exists());
    assert!(dir.join("s.target_mask_texels.png").exists());
    let mut back = AppState::<NoParams>::new();
    back.open_session(&session).unwrap();
    let slot = back.slot(Side::Target).unwrap();
    let layer = slot.texels.as_ref().unwrap();
    assert!(layer.to_image() == painted, "the reopened layer differs");
    assert!(
        slot.mask_texels.as_ref().unwrap().to_image() == mask,
        "the reopened mask differs"
    );
    assert!(back.slot(Side::Source).unwrap().texels.is_none());
    assert!(back.slot(Side::Source).unwrap().mask_texels.is_none());
}

/// The face of a z = 0 plane that contains `p` (in x, y).
fn face_under(mesh: &TriMesh, p: Vec3) -> usize {
    (0..mesh.faces.len())
        .find(|&f| {
            let [a, b, c] = mesh.faces[f].map(|v| Vec2::from_slice(&mesh.positions[v as usize]));
            let q = p.truncate();
            let s = |u: Vec2, v: Vec2| (v - u).perp_dot(q - u);
            let (d0, d1, d2) = (s(a, b), s(b, c), s(c, a));
            (d0 >= 0.0 && d1 >= 0.0 && d2 >= 0.0) || (d0 <= 0.0 && d1 <= 0.0 && d2 <= 0.0)
        })
        .expect("a face under the point")
}

#[test]
fn the_eyedropper_returns_the_colour_under_the_cursor_and_strokes_fill_the_history() {
    let mesh = seamed_plane(8);
    let mut st = state_with(Side::Target, mesh.clone());
    st.brush.radius = 0.05;
    st.brush.hardness = 0.999;
    let painted = [0.2, 0.6, 0.9];
    st.brush.color = painted;
    let centre = Vec3::new(0.3, 0.6, 0.0);
    st.paint_dab(Side::Target, &view_of(&mesh, Vec3::Z, centre), true);
    st.brush.color = [1.0, 0.0, 0.0];
    st.paint_dab(
        Side::Target,
        &view_of(&mesh, Vec3::Z, Vec3::new(0.7, 0.2, 0.0)),
        true,
    );
    assert_eq!(st.color_history, vec![[1.0, 0.0, 0.0], painted]);
    st.brush.color = [0.0; 3];
    assert!(st.pick_color(Side::Target, face_under(&mesh, centre), centre.to_array()));
    let c = st.brush.color;
    for k in 0..3 {
        assert!(
            (c[k] - painted[k]).abs() < 0.01,
            "picked {c:?}, painted {painted:?}"
        );
    }
    // Off the paint: the mesh's own colour.
    let off = Vec3::new(0.9, 0.9, 0.0);
    let c = st
        .color_at(Side::Target, face_under(&mesh, off), off.to_array())
        .unwrap();
    let grey = meshmatch::render::gpu::DEFAULT_VERTEX_COLOR;
    for k in 0..3 {
        assert!((c[k] - grey[k]).abs() < 0.01, "{c:?}");
    }
}

/// The seamed plane with a dark band painted across the left chart's texels at v in
/// [0.45, 0.55] (a strong colour edge for a fill to stop at).
fn plane_with_band() -> (TriMesh, AppState<NoParams>) {
    let mesh = seamed_plane(8);
    let mut st = state_with(Side::Target, mesh.clone());
    st.brush.radius = 0.05;
    st.brush.hardness = 0.999;
    st.brush.color = [0.05, 0.05, 0.05];
    stroke(
        &mut st,
        &mesh,
        Vec3::new(0.0, 0.5, 0.0),
        Vec3::new(1.0, 0.5, 0.0),
        80,
    );
    (mesh, st)
}

#[test]
fn a_region_fill_stays_inside_its_region_and_stops_at_a_strong_colour_edge() {
    use meshmatch::app::state::paint_fill::FillKind;
    let (mesh, mut st) = plane_with_band();
    let before = st
        .slot(Side::Target)
        .unwrap()
        .texels
        .as_ref()
        .unwrap()
        .to_image();
    st.brush.color = [0.0, 0.8, 0.2];
    st.brush.fill_tolerance = 0.1;
    // Click the lower left quarter (grey, below the band).
    let p = Vec3::new(0.2, 0.2, 0.0);
    let n = st.fill_at(
        Side::Target,
        face_under(&mesh, p),
        p.to_array(),
        FillKind::Region,
    );
    assert!(n > 10_000, "{n} texels filled");
    let layer = st.slot(Side::Target).unwrap().texels.as_ref().unwrap();
    let green = |uv: [f32; 2]| {
        let s = layer.sample(uv);
        s[3] > 0.99 && s[1] > 0.75 && s[0] < 0.05
    };
    // Below the band, both charts (the fill crosses the UV seam through the seam's links):
    for (x, y) in [
        (0.1, 0.1),
        (0.45, 0.3),
        (0.55, 0.3),
        (0.9, 0.1),
        (0.3, 0.38),
    ] {
        let u = if x > 0.5 {
            0.55 + 0.8 * (x - 0.5)
        } else {
            0.05 + 0.8 * x
        };
        assert!(green([u, 0.05 + 0.9 * y]), "not filled at ({x}, {y})");
    }
    // Above the band (y > 0.55 on the plane) nothing changes, nor does any texel the band
    // painted fully; the gutter stays empty.
    let (w, h) = (layer.width, layer.height);
    let above = ((1.0 - (0.05 + 0.9 * 0.55)) * h as f32) as u32;
    let mut band = 0;
    for y in 0..h {
        for x in 0..w {
            let b = before.get_pixel(x, y).0;
            if y < above || b[3] == 255 {
                band += usize::from(b[3] == 255);
                assert_eq!(layer.get(x, y), b, "changed at {x},{y}");
            }
        }
    }
    assert!(band > 50_000, "{band} texels in the band");
    let (lo, hi) = ((0.45 * 2048.0 + 1.5) as u32, (0.55 * 2048.0 - 1.5) as u32);
    for y in 0..h {
        for x in lo..=hi {
            assert_eq!(layer.get(x, y)[3], 0, "paint in the gutter at {x},{y}");
        }
    }
    // The dark band is not green anywhere.
    for k in 0..=100 {
        let x = 0.02 + 0.96 * k as f32 / 100.0;
        let u = if x > 0.5 {
            0.55 + 0.8 * (x - 0.5)
        } else {
            0.05 + 0.8 * x
        };
        let s = layer.sample([u, 0.05 + 0.9 * 0.5]);
        assert!(s[1] < 0.1, "the fill crossed the band at x = {x}: {s:?}");
    }
}

#[test]
fn an_island_fill_paints_exactly_its_charts_texels_and_undo_restores_the_layer() {
    use meshmatch::app::state::paint_fill::{FillKind, uv_charts};
    use meshmatch::app::state::paint_layer::for_texels;
    let (mesh, mut st) = plane_with_band();
    let before = st
        .slot(Side::Target)
        .unwrap()
        .texels
        .as_ref()
        .unwrap()
        .to_image();
    let charts = uv_charts(&mesh);
    let mut ids: Vec<u32> = charts.clone();
    ids.sort_unstable();
    ids.dedup();
    assert_eq!(ids.len(), 2, "the seamed plane has two charts");
    st.brush.color = [1.0, 0.9, 0.0];
    let p = Vec3::new(0.8, 0.7, 0.0);
    let f = face_under(&mesh, p);
    let n = st.fill_at(Side::Target, f, p.to_array(), FillKind::Island);
    let mut expected = vec![false; 2048 * 2048];
    for_texels(
        &mesh,
        2048,
        2048,
        (0..mesh.faces.len()).filter(|&g| charts[g] == charts[f]),
        &|_| true,
        &mut |x, y, _, _| expected[(y * 2048 + x) as usize] = true,
    );
    let layer = st.slot(Side::Target).unwrap().texels.as_ref().unwrap();
    let mut filled = 0;
    for y in 0..2048 {
        for x in 0..2048 {
            let inside = expected[(y * 2048 + x) as usize];
            let p = layer.get(x, y);
            if inside {
                assert_eq!(p, [255, 230, 0, 255], "chart texel {x},{y} not filled");
                filled += 1;
            } else {
                assert_eq!(
                    p,
                    before.get_pixel(x, y).0,
                    "texel {x},{y} off the chart changed"
                );
            }
        }
    }
    assert!(filled > 100_000 && n > 0, "{filled} texels in the chart");
    // One undo step restores the layer exactly.
    assert!(st.undo());
    let layer = st.slot(Side::Target).unwrap().texels.as_ref().unwrap();
    assert!(layer.to_image() == before, "undo did not restore the layer");
}

#[test]
fn fills_without_uvs_act_on_vertices_and_undo_in_one_step() {
    use meshmatch::app::state::paint_fill::FillKind;
    // Two separate sheets side by side: an island fill takes one, a region fill stops at paint.
    let mut mesh = TriMesh::default();
    grid(40, 0.0, false, &mut mesh);
    let base = mesh.positions.len() as u32;
    grid(40, 0.0, false, &mut mesh);
    for p in &mut mesh.positions[base as usize..] {
        p[0] += 2.0;
    }
    mesh.file_index = (0..mesh.positions.len() as u32).collect();
    mesh.file_vertex_count = mesh.positions.len();
    let mut st = state_with(Side::Target, mesh.clone());
    st.brush.color = [0.0, 0.0, 1.0];
    let top = |x: f32, y: f32| Vec3::new(x, y, 0.0);
    let face_at = |p: Vec3| {
        (0..mesh.faces.len())
            .find(|&f| {
                let c = mesh.faces[f].map(|v| Vec3::from(mesh.positions[v as usize]));
                c.iter().all(|q| (q.z - p.z).abs() < 1e-6) && {
                    let lo = c[0].min(c[1]).min(c[2]);
                    let hi = c[0].max(c[1]).max(c[2]);
                    p.x >= lo.x && p.x <= hi.x && p.y >= lo.y && p.y <= hi.y
                }
            })
            .unwrap()
    };
    let p = top(0.5, 0.5);
    let n = st.fill_at(Side::Target, face_at(p), p.to_array(), FillKind::Island);
    assert_eq!(
        n, base as usize,
        "the island fill takes the first slab's vertices"
    );
    let paint = st.slot(Side::Target).unwrap().paint.clone().unwrap();
    assert!(
        paint[..base as usize]
            .iter()
            .all(|c| *c == [0.0, 0.0, 1.0, 1.0])
    );
    assert!(paint[base as usize..].iter().all(|c| c[3] == 0.0));
    assert!(st.undo());
    assert!(st.slot(Side::Target).unwrap().paint.is_none());
    // A painted line across the first slab's top splits it for a region fill.
    st.brush.color = [0.0, 0.0, 0.0];
    st.brush.radius = 0.03;
    st.brush.hardness = 0.999;
    for k in 0..=60 {
        let q = top(k as f32 / 60.0, 0.5);
        st.paint_dab(Side::Target, &view_of(&mesh, Vec3::Z, q), k == 0);
    }
    st.brush.color = [1.0, 1.0, 0.0];
    let p = top(0.5, 0.2);
    st.fill_at(Side::Target, face_at(p), p.to_array(), FillKind::Region);
    let slot = st.slot(Side::Target).unwrap();
    let paint = slot.paint.as_ref().unwrap();
    for (v, q) in mesh.positions.iter().enumerate().take(base as usize) {
        let yellow = paint[v] == [1.0, 1.0, 0.0, 1.0];
        if q[1] < 0.4 {
            assert!(yellow, "vertex {v} at {q:?} below the line not filled");
        }
        if q[1] > 0.6 {
            assert!(!yellow, "vertex {v} at {q:?} beyond the line filled");
        }
    }
}

#[test]
fn hidden_layers_stay_out_of_the_export_and_half_opacity_blends_half() {
    use meshmatch::app::state::PaintTarget;
    let mut mesh = seamed_plane(8);
    let base = [0.2f32, 0.4, 0.6];
    mesh.colors = Some(vec![base; mesh.positions.len()]);
    let mut st = state_with(Side::Target, mesh.clone());
    st.brush.radius = 0.05;
    st.brush.hardness = 0.999;
    // Paint red at one spot, a blue mask over the same spot.
    let p = Vec3::new(0.3, 0.6, 0.0);
    st.brush.color = [1.0, 0.0, 0.0];
    st.paint_dab(Side::Target, &view_of(&mesh, Vec3::Z, p), true);
    st.brush.target = PaintTarget::Mask;
    st.brush.color = [0.0, 0.0, 1.0];
    st.paint_dab(Side::Target, &view_of(&mesh, Vec3::Z, p), true);
    let (x, y) = (
        ((0.05 + 0.8 * 0.3) * 2048.0) as u32,
        ((1.0 - (0.05 + 0.9 * 0.6)) * 2048.0) as u32,
    );
    {
        let slot = st.slot(Side::Target).unwrap();
        assert_eq!(slot.texels.as_ref().unwrap().get(x, y), [255, 0, 0, 255]);
        assert_eq!(
            slot.mask_texels.as_ref().unwrap().get(x, y),
            [0, 0, 255, 255]
        );
    }
    let texel = |st: &AppState<NoParams>| -> [i32; 3] {
        let m = st.painted_export_mesh(Side::Target).unwrap();
        m.texture
            .as_ref()
            .unwrap()
            .image
            .get_pixel(x, y)
            .0
            .map(|v| v as i32)
    };
    let near = |a: [i32; 3], b: [f32; 3]| {
        (0..3).all(|k| (a[k] - (b[k] * 255.0).round() as i32).abs() <= 1)
    };
    // Everything shown: the mask on top.
    assert!(near(texel(&st), [0.0, 0.0, 1.0]), "{:?}", texel(&st));
    // Mask hidden: the paint.
    st.layers.mask.visible = false;
    assert!(near(texel(&st), [1.0, 0.0, 0.0]), "{:?}", texel(&st));
    // Paint hidden too: the result underneath, exactly as if never painted.
    st.layers.paint.visible = false;
    assert!(near(texel(&st), base), "{:?}", texel(&st));
    // Paint at half opacity: half the result, half the paint.
    st.layers.paint.visible = true;
    st.layers.paint.opacity = 0.5;
    let half = [0.5 * base[0] + 0.5, 0.5 * base[1], 0.5 * base[2]];
    assert!(near(texel(&st), half), "{:?} vs {half:?}", texel(&st));
    // The eyedropper sees what the view shows.
    let c = st
        .color_at(Side::Target, face_under(&mesh, p), p.to_array())
        .unwrap();
    for k in 0..3 {
        assert!((c[k] - half[k]).abs() < 0.01, "{c:?} vs {half:?}");
    }
    // The result hidden: grey under the half paint.
    st.layers.result.visible = false;
    let g = meshmatch::render::gpu::DEFAULT_VERTEX_COLOR;
    let grey_half = [0.5 * g[0] + 0.5, 0.5 * g[1], 0.5 * g[2]];
    assert!(
        near(texel(&st), grey_half),
        "{:?} vs {grey_half:?}",
        texel(&st)
    );
    // The mask stroke is its own undo step: undoing it leaves the paint.
    assert!(st.undo());
    let slot = st.slot(Side::Target).unwrap();
    assert!(slot.mask_texels.is_none());
    assert_eq!(slot.texels.as_ref().unwrap().get(x, y), [255, 0, 0, 255]);
}

#[test]
fn vertex_layers_composite_by_visibility_and_opacity() {
    use meshmatch::app::state::PaintTarget;
    let mut mesh = slab(0.05);
    let base = [0.2f32, 0.4, 0.6];
    mesh.colors = Some(vec![base; mesh.positions.len()]);
    let mut st = state_with(Side::Target, mesh.clone());
    st.brush.hardness = 0.999;
    let p = Vec3::new(0.5, 0.5, 0.025);
    st.brush.color = [1.0, 1.0, 1.0];
    st.paint_dab(Side::Target, &view_of(&mesh, Vec3::Z, p), true);
    st.brush.target = PaintTarget::Mask;
    st.brush.color = [0.0, 0.0, 0.0];
    st.paint_dab(
        Side::Target,
        &view_of(&mesh, Vec3::Z, Vec3::new(0.1, 0.1, 0.025)),
        true,
    );
    let slot = st.slot(Side::Target).unwrap();
    let paint = slot.paint.as_ref().unwrap();
    let mask = slot.mask.as_ref().unwrap();
    let v = (0..paint.len())
        .find(|&v| paint[v][3] == 1.0 && mask[v][3] == 0.0)
        .unwrap();
    let m = (0..mask.len())
        .find(|&v| mask[v][3] == 1.0 && paint[v][3] == 0.0)
        .unwrap();
    let shown = |st: &AppState<NoParams>| st.slot(Side::Target).unwrap().shown_colors(&st.layers);
    assert_eq!(shown(&st)[v], [1.0; 3]);
    assert_eq!(shown(&st)[m], [0.0; 3]);
    st.layers.paint.opacity = 0.5;
    st.layers.mask.visible = false;
    let c = shown(&st);
    for k in 0..3 {
        assert!((c[v][k] - (0.5 * base[k] + 0.5)).abs() < 1e-5, "{:?}", c[v]);
        assert!((c[m][k] - base[k]).abs() < 1e-5, "{:?}", c[m]);
    }
    // Layers change what is shown, not what the applications read.
    assert_eq!(st.paint_coverage(Side::Target).unwrap()[v], 1.0);
    // The export carries the same colours.
    let e = st.painted_export_mesh(Side::Target).unwrap();
    assert_eq!(e.colors.as_ref().unwrap()[v], c[v]);
    // Exemplar painting's region is the mask once it has paint.
    let region = st.region_coverage(Side::Target).unwrap();
    assert_eq!(region[m], 1.0);
    assert_eq!(region[v], 0.0);
}
