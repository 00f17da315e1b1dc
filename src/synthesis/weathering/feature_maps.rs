//! The feature maps texture artists bake (ambient occlusion, curvature, cavity, thickness,
//! world-space normal, height), from the features of the geometry-correlated transfer, into
//! textures in a mesh's UVs (or a generated atlas), as the bakers of Substance Painter and
//! Blender make them.
//!
//! 1. Per vertex ([`vertex_maps`]): the Mertens features ([`super::features`]) with two
//!    curvature radii, the chosen one and the cavity radius, plus [`crate::geometry::thickness`];
//!    each map is brought to `[0, 1]` (see [`MAP_NAMES`] for what black and white mean).
//! 2. Per texel ([`bake_feature_maps`]): every texel a UV triangle covers takes the vertex
//!    values interpolated barycentrically at its centre (`geometry::bake_uv`, the conservative
//!    rasteriser every bake of the project uses; normals renormalised), then the charts are
//!    dilated by [`GUTTER_RINGS`] texels and the rest of the texels outside them filled by
//!    pull-push (`geometry::fill_gutters_dilated`), so mipmaps and bilinear filtering never meet
//!    a background colour at chart borders.
//! 3. Encoding ([`encode_map`]): 8- or 16-bit PNG, grey (one channel) or RGB (the normal),
//!    values stored linearly (these are data, not colours).

use glam::Vec3;

use super::{Params, Up};
use crate::error::{Error, Result};
use crate::geometry::{AtlasParams, BakedImage, OcclusionBvh, UvAtlas};
use crate::mesh::TriMesh;
use crate::work::CancelToken;

/// The maps, in the order `all` bakes them:
///
/// - `ao`: visible fraction of the outer hemisphere (white open, black fully occluded);
/// - `curvature`: solid-angle curvature at [`MapParams::radius`], signed: mid grey (0.5) flat,
///   lighter convex, darker concave;
/// - `cavity`: fine-scale concavity (solid-angle curvature at [`MapParams::cavity_radius`],
///   concave part only): white flat or convex, darker in creases and pits;
/// - `thickness`: mean inward ray distance ([`crate::geometry::thickness`]): black thin, white
///   thick;
/// - `normal`: world-space (object-space) unit normal as RGB = `0.5 + 0.5 n`;
/// - `height`: position along the up axis over the bounding box (black bottom, white top).
pub const MAP_NAMES: [&str; 6] = ["ao", "curvature", "cavity", "thickness", "normal", "height"];

/// Signed and one-sided maps are scaled so that this quantile of their magnitude over the
/// vertices reaches black (or white): the few sharpest spots saturate, the rest keep contrast.
pub const SCALE_QUANTILE: f32 = 0.99;

/// Rings of texels the charts are dilated by before pull-push fills the rest of the gutters
/// (Blender's default bake margin is 16 texels at 1024²; 8 keeps mip levels up to 3 clean).
pub const GUTTER_RINGS: usize = 8;

/// Parameters of the feature-map bake.
#[derive(Clone, Debug, PartialEq)]
pub struct MapParams {
    /// Side of the square textures in texels.
    pub texture_size: u32,
    /// Curvature radius as a fraction of the bounding-box diagonal (the `curvature` map).
    pub radius: f32,
    /// Radius of the `cavity` map's fine-scale curvature, fraction of the diagonal.
    pub cavity_radius: f32,
    /// Rays per vertex for occlusion and thickness.
    pub rays: usize,
    /// Random seed (ray directions).
    pub seed: u64,
    /// The object's up axis (the `height` map).
    pub up: Up,
    /// Lay out a new atlas even if the mesh has UVs.
    pub new_atlas: bool,
}

impl Default for MapParams {
    fn default() -> Self {
        MapParams {
            texture_size: 2048,
            radius: Params::default().curvature_radii[0],
            cavity_radius: 0.003,
            rays: Params::default().rays,
            seed: 0,
            up: Up::Y,
            new_atlas: false,
        }
    }
}

/// One map's values per vertex, in `[0, 1]`.
#[derive(Clone, Debug)]
pub struct VertexMap {
    /// Map name (one of [`MAP_NAMES`]).
    pub name: &'static str,
    /// 1 (grey) or 3 (RGB, the normal).
    pub channels: usize,
    /// `n × channels` values, vertex-major.
    pub values: Vec<f32>,
    /// How the raw feature was scaled to `[0, 1]`, in words.
    pub scale: String,
}

/// One baked map: its texture (gutters filled) and what it is.
#[derive(Clone, Debug)]
pub struct FeatureMap {
    /// Map name (one of [`MAP_NAMES`]).
    pub name: &'static str,
    /// 1 (grey) or 3 (RGB).
    pub channels: usize,
    /// The texture, values in `[0, 1]` (grey maps repeat the value in the three channels).
    pub image: BakedImage,
    /// How the raw feature was scaled to `[0, 1]`, in words.
    pub scale: String,
}

/// The result of [`bake_feature_maps`].
#[derive(Clone, Debug)]
pub struct FeatureMaps {
    /// The maps, in the order asked.
    pub maps: Vec<FeatureMap>,
    /// Per-corner UVs the maps were baked through (the mesh's own or the generated atlas).
    pub uvs: Vec<[f32; 2]>,
    /// The atlas generated, when the mesh had no UVs (or a new one was asked for).
    pub atlas: Option<UvAtlas>,
    /// The per-vertex values that were interpolated.
    pub vertex: Vec<VertexMap>,
}

/// The map names `spec` asks for: `all`, one name, or a comma-separated list. Unknown names are a
/// one-line `InvalidInput` listing the valid ones.
pub fn parse_map_names(spec: &str) -> Result<Vec<&'static str>> {
    let spec = spec.trim().to_ascii_lowercase();
    if spec == "all" {
        return Ok(MAP_NAMES.to_vec());
    }
    let mut out = Vec::new();
    for part in spec.split(',') {
        let part = part.trim();
        let canon = match part {
            "occlusion" | "ambient-occlusion" => "ao",
            "normals" => "normal",
            p => p,
        };
        match MAP_NAMES.iter().find(|&&n| n == canon) {
            Some(n) if !out.contains(n) => out.push(*n),
            Some(_) => {}
            None => {
                return Err(Error::InvalidInput(format!(
                    "unknown map '{part}' (expected all or one of: {})",
                    MAP_NAMES.join(", ")
                )));
            }
        }
    }
    Ok(out)
}

/// Refuse map parameters out of range before any work.
pub fn check_map_params(p: &MapParams) -> Result<()> {
    for (flag, r) in [("--radius", p.radius), ("--cavity-radius", p.cavity_radius)] {
        if !(r > 0.0 && r <= 1.0) {
            return Err(Error::InvalidInput(format!(
                "{flag} {r}: use a fraction of the bounding-box diagonal in (0, 1]"
            )));
        }
    }
    if !(1..=4096).contains(&p.rays) {
        return Err(Error::InvalidInput(format!(
            "--rays {}: use 1 to 4096 rays per vertex",
            p.rays
        )));
    }
    Ok(())
}

/// The `quantile` of `|x|` over the finite values of `xs`, at least `1e-9`.
fn magnitude_quantile(xs: impl Iterator<Item = f32>, quantile: f32) -> f32 {
    let mut v: Vec<f32> = xs.filter(|x| x.is_finite()).map(f32::abs).collect();
    if v.is_empty() {
        return 1e-9;
    }
    let k = ((v.len() - 1) as f32 * quantile).round() as usize;
    let (_, q, _) = v.select_nth_unstable_by(k, f32::total_cmp);
    q.max(1e-9)
}

/// The maps `names` of every vertex of `mesh`, in `[0, 1]` (see [`MAP_NAMES`]).
pub fn vertex_maps(
    mesh: &TriMesh,
    names: &[&'static str],
    p: &MapParams,
    cancel: &CancelToken,
) -> Result<Vec<VertexMap>> {
    check_map_params(p)?;
    let params = Params {
        up: p.up,
        rays: p.rays,
        seed: p.seed,
        curvature_radii: vec![p.radius, p.cavity_radius],
        ..Params::default()
    };
    let fs = super::features(&mesh.positions, &mesh.faces, &params, cancel)?;
    let n = fs.len();
    let col = |name: &str| super::feature_field(&fs, name);
    let mut out = Vec::with_capacity(names.len());
    for &name in names {
        cancel.check()?;
        let map = match name {
            "ao" => VertexMap {
                name,
                channels: 1,
                values: col("ao")?,
                scale: "visible fraction of the hemisphere".into(),
            },
            "height" => VertexMap {
                name,
                channels: 1,
                values: col("height")?,
                scale: format!("{:?} over the bounding box", p.up).to_lowercase(),
            },
            "normal" => {
                let mut values = Vec::with_capacity(3 * n);
                for v in 0..n {
                    let r = fs.row(v);
                    values.extend([r[1], r[2], r[3]].map(|x| 0.5 + 0.5 * x));
                }
                VertexMap {
                    name,
                    channels: 3,
                    values,
                    scale: "0.5 + 0.5 n".into(),
                }
            }
            "curvature" => {
                let k = col("curvature-0")?;
                let s = magnitude_quantile(k.iter().copied(), SCALE_QUANTILE);
                VertexMap {
                    name,
                    channels: 1,
                    values: k
                        .iter()
                        .map(|x| (0.5 + 0.5 * x / s).clamp(0.0, 1.0))
                        .collect(),
                    scale: format!(
                        "0.5 + 0.5 k / {s:.4} (k: solid-angle curvature at radius {:.4})",
                        fs.radii[0]
                    ),
                }
            }
            "cavity" => {
                let k = col("curvature-1")?;
                let s = magnitude_quantile(k.iter().copied().filter(|&x| x < 0.0), SCALE_QUANTILE);
                VertexMap {
                    name,
                    channels: 1,
                    values: k
                        .iter()
                        .map(|&x| 1.0 - (x.min(0.0).abs() / s).clamp(0.0, 1.0))
                        .collect(),
                    scale: format!(
                        "1 - max(0, -k) / {s:.4} (k: solid-angle curvature at radius {:.4})",
                        fs.radii[1]
                    ),
                }
            }
            "thickness" => {
                // the features' orientation (a mesh wound inwards is flipped there)
                let normals: Vec<[f32; 3]> = (0..n)
                    .map(|v| {
                        let r = fs.row(v);
                        [r[1], r[2], r[3]]
                    })
                    .collect();
                let bvh = OcclusionBvh::new(&mesh.positions, &mesh.faces);
                let t = crate::geometry::thickness(
                    &bvh,
                    &mesh.positions,
                    &normals,
                    p.rays,
                    p.seed,
                    cancel,
                )?;
                let s = magnitude_quantile(t.iter().copied(), SCALE_QUANTILE);
                VertexMap {
                    name,
                    channels: 1,
                    // no inward hit (an open mesh's rim): as thick as the thickest
                    values: t
                        .iter()
                        .map(|&x| if x.is_finite() { (x / s).min(1.0) } else { 1.0 })
                        .collect(),
                    // in the mesh's own size, so that the words do not depend on its units
                    scale: format!(
                        "mean inward distance / {:.4} of the bounding-box diagonal",
                        s / diagonal(mesh)
                    ),
                }
            }
            other => {
                return Err(Error::InvalidInput(format!(
                    "unknown map '{other}' (expected one of: {})",
                    MAP_NAMES.join(", ")
                )));
            }
        };
        out.push(map);
    }
    Ok(out)
}

/// Bake the maps `names` of `mesh` into `p.texture_size²` textures through its UVs (a generated
/// atlas when it has none, or with `p.new_atlas`), gutters filled by pull-push. `progress`
/// receives a fraction in [0, 1] after each stage (atlas, features, each map), on the calling
/// thread.
pub fn bake_feature_maps(
    mesh: &TriMesh,
    names: &[&'static str],
    p: &MapParams,
    progress: &dyn Fn(f32),
    cancel: &CancelToken,
) -> Result<FeatureMaps> {
    check_map_params(p)?;
    crate::geometry::check_bake_memory(p.texture_size)?;
    if names.is_empty() {
        return Err(Error::InvalidInput("no map to bake".into()));
    }
    if mesh.faces.is_empty() {
        return Err(Error::InvalidMesh("no faces to bake".into()));
    }
    let mut atlas = None;
    let uvs = match (&mesh.uvs, p.new_atlas) {
        (Some(uv), false) if uv.len() >= 3 * mesh.faces.len() => uv.clone(),
        _ => {
            let ap = AtlasParams {
                texture_size: p.texture_size,
                ..Default::default()
            };
            let a = crate::geometry::uv_atlas(&mesh.positions, &mesh.faces, &ap, &|_| {}, cancel)?;
            let uvs = a.uvs.clone();
            atlas = Some(a);
            uvs
        }
    };
    progress(0.3);
    let vertex = vertex_maps(mesh, names, p, cancel)?;
    progress(0.8);
    let size = p.texture_size as usize;
    let faces = &mesh.faces;
    let mut maps = Vec::with_capacity(vertex.len());
    for (i, vm) in vertex.iter().enumerate() {
        progress(0.8 + 0.2 * i as f32 / vertex.len() as f32);
        cancel.check()?;
        let c = vm.channels;
        let vals = &vm.values;
        let mut image = crate::geometry::bake_uv(&uvs, faces.len(), size, size, |f, b| {
            let face = faces[f];
            let mut out = [0.0f32; 3];
            for k in 0..3 {
                let v = face[k] as usize;
                for (ch, o) in out.iter_mut().enumerate() {
                    *o += b[k] * vals[v * c + ch.min(c - 1)];
                }
            }
            if c == 3 {
                // a unit normal again, as bakers store it
                let n = (Vec3::from(out) * 2.0 - Vec3::ONE).normalize_or_zero();
                out = (n * 0.5 + Vec3::splat(0.5)).to_array();
            }
            out
        });
        crate::geometry::fill_gutters_dilated(&mut image, GUTTER_RINGS);
        maps.push(FeatureMap {
            name: vm.name,
            channels: c,
            image,
            scale: vm.scale.clone(),
        });
    }
    progress(1.0);
    Ok(FeatureMaps {
        maps,
        uvs,
        atlas,
        vertex,
    })
}

/// A baked map as an image of `bits` (8 or 16) per channel: grey for one-channel maps, RGB for
/// the normal; values quantised linearly (`round(v × (2^bits - 1))`).
pub fn encode_map(map: &FeatureMap, bits: u8) -> Result<image::DynamicImage> {
    let (w, h) = (map.image.width as u32, map.image.height as u32);
    let px = &map.image.pixels;
    let q8 = |x: f32| (x.clamp(0.0, 1.0) * 255.0).round() as u8;
    let q16 = |x: f32| (x.clamp(0.0, 1.0) * 65535.0).round() as u16;
    let img = match (bits, map.channels) {
        (8, 1) => image::DynamicImage::ImageLuma8(
            image::GrayImage::from_raw(w, h, px.iter().map(|p| q8(p[0])).collect()).expect("size"),
        ),
        (8, _) => image::DynamicImage::ImageRgb8(
            image::RgbImage::from_raw(w, h, px.iter().flat_map(|p| p.map(q8)).collect())
                .expect("size"),
        ),
        (16, 1) => image::DynamicImage::ImageLuma16(
            image::ImageBuffer::from_raw(w, h, px.iter().map(|p| q16(p[0])).collect())
                .expect("size"),
        ),
        (16, _) => image::DynamicImage::ImageRgb16(
            image::ImageBuffer::from_raw(w, h, px.iter().flat_map(|p| p.map(q16)).collect())
                .expect("size"),
        ),
        _ => {
            return Err(Error::InvalidInput(format!("--bits {bits}: use 8 or 16")));
        }
    };
    Ok(img)
}

/// The PNG bytes of [`encode_map`].
pub fn map_png(map: &FeatureMap, bits: u8) -> Result<Vec<u8>> {
    let img = encode_map(map, bits)?;
    let mut out = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut out), image::ImageFormat::Png)
        .map_err(|e| Error::InvalidInput(format!("cannot encode PNG: {e}")))?;
    Ok(out)
}

/// Where map `name` goes when `out` is asked for: `out` itself when it is the only map, else
/// `<stem>_<name>.<ext>` beside it.
pub fn map_path(out: &std::path::Path, name: &str, only: bool) -> std::path::PathBuf {
    if only {
        return out.to_path_buf();
    }
    let stem = out
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "maps".into());
    let ext = out
        .extension()
        .map(|e| format!(".{}", e.to_string_lossy()))
        .unwrap_or_default();
    out.with_file_name(format!("{stem}_{name}{ext}"))
}

/// Write `maps` as PNGs of `bits` per channel to `out` (one map) or `<stem>_<name>.png` beside it
/// (several), all or none (`io::write_atomic_all`). Returns the paths written.
pub fn save_map_pngs(
    maps: &FeatureMaps,
    out: &std::path::Path,
    bits: u8,
) -> Result<Vec<std::path::PathBuf>> {
    let only = maps.maps.len() == 1;
    let mut files = Vec::with_capacity(maps.maps.len());
    for m in &maps.maps {
        files.push((map_path(out, m.name, only), map_png(m, bits)?));
    }
    let refs: Vec<(&std::path::Path, &[u8])> = files
        .iter()
        .map(|(p, b)| (p.as_path(), b.as_slice()))
        .collect();
    crate::mesh::io::write_atomic_all(&refs)?;
    Ok(files.into_iter().map(|(p, _)| p).collect())
}

/// `mesh` with the map as its 8-bit texture (through the UVs the maps were baked in), for a
/// textured .glb, .gltf or .obj; vertex colours dropped.
pub fn textured_with(mesh: &TriMesh, maps: &FeatureMaps, map: &FeatureMap) -> TriMesh {
    let mut out = mesh.clone();
    out.uvs = Some(maps.uvs.clone());
    out.colors = None;
    out.texture = Some(std::sync::Arc::new(crate::mesh::Texture {
        image: map.image.to_rgb8(),
        path: None,
    }));
    out
}

/// The bounding-box diagonal of `mesh` (1 for a mesh without extent).
fn diagonal(mesh: &TriMesh) -> f32 {
    let d = mesh
        .bounds()
        .map(|(lo, hi)| glam::Vec3::from(hi).distance(glam::Vec3::from(lo)))
        .unwrap_or(0.0);
    if d > 0.0 && d.is_finite() { d } else { 1.0 }
}
