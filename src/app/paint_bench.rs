//! `meshmatch bench --system paint`: the UI-thread cost of painting. A stroke of dabs across a
//! UV sphere of `n` vertices seen whole in an 800x600 view, into a 2048² texel layer, the same
//! seen from close up (the brush's disc large on the screen), and into vertex paint on the same
//! mesh without its UVs, with the default brush.

use std::time::Instant;

use glam::{Vec2, Vec3};

use crate::bench::{SystemRow, peak_rss_mb};
use crate::correspondence::Side;
use crate::error::Result;
use crate::mesh::TriMesh;
use crate::render::{Camera, Frame};

use super::brush::BrushView;
use super::state::AppState;

/// Dabs per measured stroke.
const DABS: usize = 120;

/// A latitude-longitude sphere of about `n` vertices with UVs (a seam at longitude 0).
pub fn uv_sphere(n: usize) -> TriMesh {
    let rings = ((n as f32 / 2.0).sqrt().round() as u32).max(4);
    lat_long_sphere(rings, 2 * rings)
}

/// A unit latitude-longitude sphere of `rings` x `segs` quads with latitude-longitude UVs (a
/// seam at longitude 0).
pub fn lat_long_sphere(rings: u32, segs: u32) -> TriMesh {
    let mut m = TriMesh::default();
    let mut uv = Vec::new();
    for r in 0..=rings {
        let th = std::f32::consts::PI * r as f32 / rings as f32;
        for s in 0..=segs {
            let ph = std::f32::consts::TAU * s as f32 / segs as f32;
            m.positions
                .push([th.sin() * ph.cos(), th.cos(), -th.sin() * ph.sin()]);
            uv.push([s as f32 / segs as f32, 1.0 - r as f32 / rings as f32]);
        }
    }
    let row = segs + 1;
    let mut uvs = Vec::new();
    for r in 0..rings {
        for s in 0..segs {
            let a = r * row + s;
            let (b, c, d) = (a + 1, a + row, a + row + 1);
            for f in [[a, c, b], [b, c, d]] {
                m.faces.push(f);
                uvs.extend(f.map(|v| uv[v as usize]));
            }
        }
    }
    m.uvs = Some(uvs);
    m.file_index = (0..m.positions.len() as u32).collect();
    m.file_vertex_count = m.positions.len();
    m
}

/// Time a stroke of [`DABS`] dabs across `mesh`'s front: (first dab, median, 95th percentile),
/// seconds.
fn stroke_times(mesh: TriMesh, zoom: f32) -> (f64, f64, f64) {
    let mut st = AppState::<crate::meshmatch::TransferParams>::new();
    let frame = Frame::of_points(&mesh.positions);
    st.set_mesh(Side::Target, mesh, false);
    let camera = Camera {
        azimuth_deg: 0.0,
        elevation_deg: 0.0,
        zoom,
        pan: [0.0, 0.0],
    };
    let size = Vec2::new(800.0, 600.0);
    let mut times = Vec::with_capacity(DABS);
    for k in 0..DABS {
        let t = k as f32 / (DABS - 1) as f32;
        let a = (t - 0.5) * 1.4 * zoom;
        let p = Vec3::new(a.sin(), 0.3 * zoom * (3.0 * t).sin(), 0.0);
        let p = Vec3::new(p.x, p.y, (1.0 - p.x * p.x - p.y * p.y).max(0.0).sqrt());
        let Some(s) = camera.project(&frame, p, size) else {
            continue;
        };
        let view = BrushView::new(&camera, &frame, size, s, p);
        let clock = Instant::now();
        st.paint_dab(Side::Target, &view, k == 0);
        times.push(clock.elapsed().as_secs_f64());
    }
    let first = times.first().copied().unwrap_or(0.0);
    let mut rest = times[1.min(times.len())..].to_vec();
    rest.sort_by(f64::total_cmp);
    let at = |q: f64| {
        rest.get(((rest.len() as f64 - 1.0) * q).round() as usize)
            .copied()
            .unwrap_or(0.0)
    };
    (first, at(0.5), at(0.95))
}

/// Time a stroke of [`DABS`] dabs across the middle of `mesh` as the app's default view shows
/// it in an 800x600 viewport, the points picked under a horizontal line through the centre:
/// (first dab, median, 95th percentile) seconds and the median number of texels per dab.
fn picked_stroke_times(mesh: TriMesh) -> (f64, f64, f64, usize) {
    let mut st = AppState::<crate::meshmatch::TransferParams>::new();
    let frame = Frame::of_points(&mesh.positions);
    let camera = Camera::default();
    let size = Vec2::new(800.0, 600.0);
    let points: Vec<(Vec2, Vec3)> = (0..DABS)
        .filter_map(|k| {
            let s = Vec2::new(250.0 + 300.0 * k as f32 / (DABS - 1) as f32, 300.0);
            let (o, d) = camera.ray(&frame, s, size);
            let hit = crate::render::pick(&mesh.positions, &mesh.faces, o, d)?;
            Some((s, hit.point))
        })
        .collect();
    st.set_mesh(Side::Target, mesh, false);
    let mut times = Vec::with_capacity(points.len());
    let mut texels = Vec::with_capacity(points.len());
    for (k, &(s, p)) in points.iter().enumerate() {
        let view = BrushView::new(&camera, &frame, size, s, p);
        let clock = Instant::now();
        texels.push(st.paint_dab(Side::Target, &view, k == 0));
        times.push(clock.elapsed().as_secs_f64());
    }
    let first = times.first().copied().unwrap_or(0.0);
    let mut rest = times[1.min(times.len())..].to_vec();
    rest.sort_by(f64::total_cmp);
    texels.sort_unstable();
    let at = |q: f64| {
        rest.get(((rest.len() as f64 - 1.0) * q).round() as usize)
            .copied()
            .unwrap_or(0.0)
    };
    let tex = texels.get(texels.len() / 2).copied().unwrap_or(0);
    (first, at(0.5), at(0.95), tex)
}

/// The rows: texel layer at 2048² and vertex paint, both on a sphere of about `n` vertices.
pub fn paint_rows(n: usize) -> Result<Vec<SystemRow>> {
    let mesh = uv_sphere(n);
    let vertices = mesh.positions.len();
    let mut bare = mesh.clone();
    bare.uvs = None;
    let mut rows = Vec::new();
    for (case, m, zoom) in [
        ("paint dab, texel layer 2048^2", mesh.clone(), 1.0),
        (
            "paint dab, texel layer 2048^2, close-up (zoom 0.3)",
            mesh,
            0.3,
        ),
        ("paint dab, vertex paint", bare, 1.0),
    ] {
        let (first, median, p95) = stroke_times(m, zoom);
        rows.push(SystemRow {
            case: case.into(),
            vertices,
            stages: vec![
                ("first dab".into(), first),
                ("dab median".into(), median),
                ("dab p95".into(), p95),
            ],
            total_s: median,
            faces: 0,
            peak_rss_mb: peak_rss_mb(),
        });
    }
    Ok(rows)
}

/// The demo giraffe (the default scene's target) with a generated UV atlas for a 2048² texel
/// layer, a stroke across its middle as the app's default view shows it: the row reports the
/// median number of texels a dab paints in the case name.
pub fn giraffe_row() -> Result<SystemRow> {
    let mut mesh = crate::demo::giraffe();
    let params = crate::geometry::AtlasParams {
        texture_size: super::state::paint_layer::TEXEL_LAYER_SIZE,
        ..Default::default()
    };
    let a = crate::geometry::uv_atlas(
        &mesh.positions,
        &mesh.faces,
        &params,
        &|_| {},
        &crate::work::CancelToken::new(),
    )?;
    mesh.uvs = Some(a.uvs);
    mesh.texture = None;
    mesh.colors = None;
    let vertices = mesh.positions.len();
    let (first, median, p95, texels) = picked_stroke_times(mesh);
    Ok(SystemRow {
        case: format!(
            "paint dab, texel layer 2048^2, giraffe with a generated atlas ({texels} texels a dab)"
        ),
        vertices,
        stages: vec![
            ("first dab".into(), first),
            ("dab median".into(), median),
            ("dab p95".into(), p95),
        ],
        total_s: median,
        faces: 0,
        peak_rss_mb: peak_rss_mb(),
    })
}
