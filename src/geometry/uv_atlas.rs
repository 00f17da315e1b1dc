//! A UV atlas for a mesh without texture coordinates: charts by normal-cone region growing,
//! flattened by LSCM with ARAP refinement and packed by shape into one square page (the
//! `uvunwrap` crate; see the README's "UV atlas" section for why it over `xatlas` bindings).
//!
//! The result is per-corner UVs in the project's convention (V up, `uvs[3 * f + k]` is corner `k`
//! of face `f`) inside `[0, 1]²` of a `texture_size²` image, with at least `padding` empty texels
//! around every chart. Charts never overlap, so a signal baked through them ([`super::bake_uv`])
//! is one-to-one.

use crate::error::{Error, Result};
use crate::work::CancelToken;

/// The smallest texture side an atlas can be laid out for with `padding` texels around each
/// chart.
pub const fn min_atlas_size(padding: u32) -> u32 {
    let need = 4 * padding + 4;
    if need > 16 { need } else { 16 }
}

/// The smallest texture side an atlas with the default padding can be laid out for: the least
/// `--texture-size` every command takes, so a target without UVs is refused before the work.
pub const MIN_ATLAS_SIZE: u32 = min_atlas_size(AtlasParams::DEFAULT_PADDING);

/// Parameters of [`uv_atlas`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AtlasParams {
    /// Side of the square texture the atlas is laid out for, in texels.
    pub texture_size: u32,
    /// Empty texels around every chart (charts are at least twice this apart).
    pub padding: u32,
    /// Largest angle between a face normal and its chart's mean normal, degrees (0..90).
    pub max_chart_angle: f32,
    /// Largest ratio of a triangle's UV-area share to its surface-area share before a chart is
    /// split (>= 1).
    pub max_area_distortion: f32,
    /// Charts stop growing at the surface area of this many average faces (0: no limit).
    /// Flattening a chart costs more than linearly in its size, so a dense scan laid out in a
    /// few huge charts spends minutes there: Igea (269K faces) took 117 s in 87 charts and takes
    /// 14 s in 340 with 4096, covering 52% of the texture instead of 60% (`cargo run --release
    /// --example atlas_chart_size`). Meshes with no more faces than this are not affected.
    pub max_chart_faces: usize,
}

impl AtlasParams {
    /// Empty texels around every chart unless a caller says otherwise.
    pub const DEFAULT_PADDING: u32 = 4;
}

impl Default for AtlasParams {
    fn default() -> Self {
        AtlasParams {
            texture_size: 2048,
            padding: Self::DEFAULT_PADDING,
            max_chart_angle: 70.0,
            max_area_distortion: 4.0,
            max_chart_faces: 4096,
        }
    }
}

/// A generated atlas.
#[derive(Clone, Debug)]
pub struct UvAtlas {
    /// Per-corner UVs (V up) in `[0, 1]²` of the square texture.
    pub uvs: Vec<[f32; 2]>,
    /// Number of charts.
    pub charts: usize,
    /// Fraction of the texture covered by charts.
    pub utilization: f32,
    /// Texels per world unit along the surface.
    pub texels_per_unit: f32,
}

/// Lay `faces` of `positions` out in a UV atlas for a `params.texture_size²` texture.
/// `progress` receives a fraction in [0, 1]; `cancel` stops the work promptly.
pub fn uv_atlas(
    positions: &[[f32; 3]],
    faces: &[[u32; 3]],
    params: &AtlasParams,
    progress: &(dyn Fn(f32) + Sync),
    cancel: &CancelToken,
) -> Result<UvAtlas> {
    let size = params.texture_size;
    if size < min_atlas_size(params.padding) {
        return Err(Error::InvalidInput(format!(
            "texture size {size} is too small for an atlas with {} texels of padding",
            params.padding
        )));
    }
    if faces.is_empty() {
        return Err(Error::InvalidMesh("no faces to lay out in an atlas".into()));
    }
    if faces
        .iter()
        .flatten()
        .any(|&v| v as usize >= positions.len())
    {
        return Err(Error::InvalidMesh(
            "a face has an out-of-range vertex index".into(),
        ));
    }
    let indices: Vec<u32> = faces.iter().flatten().copied().collect();
    // Faces with a non-finite corner get no chart (the crate refuses such positions): give those
    // corners a finite stand-in and ignore the faces.
    let finite = |p: &[f32; 3]| p.iter().all(|c| c.is_finite());
    let any_bad = positions.iter().any(|p| !finite(p));
    let clean: Vec<[f32; 3]>;
    let ignored: Vec<bool>;
    let input = if any_bad {
        clean = positions
            .iter()
            .map(|p| if finite(p) { *p } else { [0.0; 3] })
            .collect();
        ignored = faces
            .iter()
            .map(|f| f.iter().any(|&v| !finite(&positions[v as usize])))
            .collect();
        let mut m = uvunwrap::MeshInput::new(&clean, &indices);
        m.ignored_faces = Some(&ignored);
        m
    } else {
        uvunwrap::MeshInput::new(positions, &indices)
    };
    // 0 (no limit) at or below the cap, and for a degenerate or non-finite total area
    let max_chart_area = if params.max_chart_faces > 0 && faces.len() > params.max_chart_faces {
        let area: f64 = super::face_areas(positions, faces)
            .iter()
            .filter(|a| a.is_finite())
            .sum();
        let a = (area * params.max_chart_faces as f64 / faces.len() as f64) as f32;
        if a.is_finite() && a > 0.0 { a } else { 0.0 }
    } else {
        0.0
    };
    let options = uvunwrap::Options {
        max_chart_angle: params.max_chart_angle,
        max_area_distortion: params.max_area_distortion,
        max_chart_area,
        density: uvunwrap::Density::Auto { page_size: size },
        padding: params.padding,
        ..Default::default()
    };
    let stage_base = |s: uvunwrap::Stage| match s {
        uvunwrap::Stage::Segmenting => (0.0, 0.1),
        uvunwrap::Stage::Parameterizing => (0.1, 0.6),
        uvunwrap::Stage::Packing => (0.7, 0.28),
        _ => (0.98, 0.02),
    };
    let atlas = uvunwrap::generate_with_progress(&[input], &options, |p| {
        let (base, span) = stage_base(p.stage);
        let frac = match p.total {
            Some(t) if t > 0 => p.done as f32 / t as f32,
            // Packing has no known total: approach the end of its span.
            _ => 1.0 - 1.0 / (1.0 + p.done as f32 / 64.0),
        };
        progress(base + span * frac.clamp(0.0, 1.0));
        !cancel.is_cancelled()
    })
    .map_err(|e| match e {
        uvunwrap::Error::Cancelled => Error::Cancelled,
        e => Error::InvalidMesh(format!("UV atlas generation failed: {e}")),
    })?;
    let out = atlas
        .meshes
        .first()
        .ok_or_else(|| Error::InvalidMesh("UV atlas generation gave no mesh".into()))?;
    if out.indices.len() != indices.len() {
        return Err(Error::InvalidMesh(
            "UV atlas generation changed the triangle count".into(),
        ));
    }
    // Pages (normally one) side by side in a square grid of the texture; each page keeps its
    // aspect (a cropped page is shorter than wide).
    let pages = atlas.page_count.max(1) as usize;
    let grid = (pages as f64).sqrt().ceil() as usize;
    let (pw, ph) = (atlas.width.max(1) as f32, atlas.height.max(1) as f32);
    let cell = 1.0 / grid as f32;
    let sx = cell * pw / size as f32;
    let sy = cell * ph / size as f32;
    let uvs: Vec<[f32; 2]> = out
        .indices
        .iter()
        .map(|&i| {
            let v = &out.vertices[i as usize];
            let page = v.page.unwrap_or(0) as usize;
            let (gx, gy) = ((page % grid) as f32, (page / grid) as f32);
            // The crate lays charts out with V growing down the image; taken as the project's V
            // (up), the layout is mirrored top to bottom as a whole and every chart keeps its
            // orientation (counter-clockwise, not mirrored, as seen in the image).
            let u = gx * cell + v.uv[0] * sx;
            let vv = gy * cell + v.uv[1] * sy;
            [u.clamp(0.0, 1.0), vv.clamp(0.0, 1.0)]
        })
        .collect();
    // One page texel is `cell` texture texels along each axis.
    let covered = atlas.utilization * pw * ph * pages as f32 * cell * cell;
    Ok(UvAtlas {
        uvs,
        charts: atlas.chart_count as usize,
        utilization: covered / (size as f32 * size as f32),
        texels_per_unit: atlas.texels_per_unit * cell,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cube() -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
        let p = (0..8)
            .map(|i| [(i & 1) as f32, ((i >> 1) & 1) as f32, ((i >> 2) & 1) as f32])
            .collect();
        let f = vec![
            [0, 2, 1],
            [1, 2, 3],
            [4, 5, 6],
            [5, 7, 6],
            [0, 1, 4],
            [1, 5, 4],
            [2, 6, 3],
            [3, 6, 7],
            [0, 4, 2],
            [2, 4, 6],
            [1, 3, 5],
            [3, 7, 5],
        ];
        (p, f)
    }

    #[test]
    fn cube_atlas_is_inside_the_square_and_keeps_area_ratios() {
        let (p, f) = cube();
        let a = uv_atlas(
            &p,
            &f,
            &AtlasParams {
                texture_size: 256,
                ..Default::default()
            },
            &|_| {},
            &CancelToken::new(),
        )
        .unwrap();
        assert_eq!(a.uvs.len(), 36);
        assert!(a.charts >= 1 && a.charts <= 12, "{} charts", a.charts);
        assert!(
            a.uvs
                .iter()
                .all(|u| (0.0..=1.0).contains(&u[0]) && (0.0..=1.0).contains(&u[1]))
        );
        // Every face of the cube has the same area: the UV areas agree within the distortion
        // bound, and none is degenerate.
        let areas: Vec<f32> = (0..12)
            .map(|t| {
                let [a, b, c] = [a.uvs[3 * t], a.uvs[3 * t + 1], a.uvs[3 * t + 2]];
                0.5 * ((b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1]))
            })
            .collect();
        let max = areas.iter().map(|a| a.abs()).fold(0.0f32, f32::max);
        let min = areas.iter().map(|a| a.abs()).fold(f32::INFINITY, f32::min);
        assert!(min > 0.0 && max / min < 1.5, "UV areas {areas:?}");
        // Orientation: counter-clockwise in V-up UVs, as the faces are outward.
        assert!(areas.iter().all(|&a| a > 0.0), "{areas:?}");
    }

    #[test]
    fn the_chart_size_cap_splits_large_charts() {
        let (p, f) = crate::testdata::uv_sphere(48, 96); // 9,024 faces
        let atlas = |cap: usize, p: &[[f32; 3]], f: &[[u32; 3]]| {
            uv_atlas(
                p,
                f,
                &AtlasParams {
                    texture_size: 1024,
                    max_chart_faces: cap,
                    ..Default::default()
                },
                &|_| {},
                &CancelToken::new(),
            )
            .unwrap()
        };
        let free = atlas(0, &p, &f);
        let capped = atlas(512, &p, &f);
        // every chart holds at most the area of 512 average faces: at least 9024 / 512 charts
        assert!(
            capped.charts >= f.len() / 512 && capped.charts > free.charts,
            "{} charts capped, {} free",
            capped.charts,
            free.charts
        );
        assert!(capped.utilization > 0.3, "{}", capped.utilization);
        // an out-of-range index is an error, not a panic
        let mut bad = f.clone();
        bad[7][1] = p.len() as u32;
        assert!(matches!(
            uv_atlas(
                &p,
                &bad,
                &AtlasParams::default(),
                &|_| {},
                &CancelToken::new()
            ),
            Err(Error::InvalidMesh(_))
        ));
    }

    #[test]
    fn cancel_stops_the_atlas() {
        let (p, f) = cube();
        let c = CancelToken::new();
        c.cancel();
        let r = uv_atlas(&p, &f, &AtlasParams::default(), &|_| {}, &c);
        assert!(matches!(r, Err(Error::Cancelled)), "{r:?}");
    }

    #[test]
    fn bad_positions_and_sizes_are_refused_or_skipped() {
        let (mut p, f) = cube();
        p[7] = [f32::NAN, 0.0, 0.0];
        let a = uv_atlas(
            &p,
            &f,
            &AtlasParams::default(),
            &|_| {},
            &CancelToken::new(),
        )
        .unwrap();
        assert_eq!(a.uvs.len(), 36);
        let small = AtlasParams {
            texture_size: 8,
            ..Default::default()
        };
        assert!(uv_atlas(&p, &f, &small, &|_| {}, &CancelToken::new()).is_err());
    }
}
