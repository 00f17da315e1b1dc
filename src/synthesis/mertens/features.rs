//! The per-vertex geometric features of Mertens et al. 2006 §3.1 (12 numbers with 4 radii):
//! normalised height (1), unit normal (3), solid-angle curvature at each radius (4),
//! directional occlusion on SH bands 0 and 1 (4).

use glam::Vec3;

use super::{Params, Up};
use crate::error::{Error, Result};
use crate::geometry::{
    OcclusionBvh, directional_occlusion_with, solid_angle_curvature_cancellable,
};
use crate::work::{CancelToken, Stopwatch};

/// Features of every vertex of one mesh.
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct FeatureSet {
    /// Feature names, one per column: `height`, `normal-x|y|z`, `curvature-<i>`, `ao`,
    /// `occlusion-x|y|z`.
    pub names: Vec<String>,
    /// Columns per vertex.
    pub dim: usize,
    /// Values, `n × dim`, vertex-major.
    pub values: Vec<f32>,
    /// Curvature radii in mesh units (the `curvature-<i>` columns).
    pub radii: Vec<f32>,
    /// Seconds spent on: normals+height, curvature, occlusion.
    pub seconds: [f64; 3],
    /// The faces were wound inwards ([`wound_inwards`]) and were flipped for the features.
    pub flipped: bool,
}

impl FeatureSet {
    /// Number of vertices.
    pub fn len(&self) -> usize {
        self.values.len() / self.dim.max(1)
    }
    /// True when there are no vertices.
    pub fn is_empty(&self) -> bool {
        self.values.is_empty()
    }
    /// The features of vertex `v`.
    pub fn row(&self, v: usize) -> &[f32] {
        &self.values[v * self.dim..(v + 1) * self.dim]
    }
    /// Column index of feature `name` (see [`feature_field`] for the accepted spellings).
    pub fn column(&self, name: &str) -> Option<usize> {
        let canon = canonical_name(name);
        self.names.iter().position(|n| *n == canon)
    }
}

/// Names of the features for `radii` curvature radii, in column order.
pub fn feature_names(radii: usize) -> Vec<String> {
    let mut v = vec!["height".to_string()];
    v.extend(["normal-x", "normal-y", "normal-z"].map(String::from));
    v.extend((0..radii).map(|i| format!("curvature-{i}")));
    v.extend(["ao", "occlusion-x", "occlusion-y", "occlusion-z"].map(String::from));
    v
}

/// Refuse an unknown feature name before any feature is computed (`radii` curvature radii).
pub fn check_feature_name(name: &str, radii: usize) -> Result<()> {
    let names = feature_names(radii);
    if names.contains(&canonical_name(name)) {
        return Ok(());
    }
    Err(Error::InvalidInput(format!(
        "unknown feature '{name}' (expected one of: {}; curvature:<i> works too)",
        names.join(", ")
    )))
}

fn canonical_name(name: &str) -> String {
    let n = name
        .trim()
        .to_ascii_lowercase()
        .replace(['_', ':', ' '], "-");
    match n.as_str() {
        "occlusion" | "ambient-occlusion" => "ao".into(),
        "curvature" => "curvature-0".into(),
        "normal" => "normal-y".into(),
        _ => n,
    }
}

/// One feature as a scalar field (one value per vertex), for display. `name` is a column name
/// (`height`, `normal-y`, `curvature-2`, `ao`, `occlusion-y`, …); `curvature:2`, `curvature_2`
/// and `occlusion` (= `ao`) are accepted too. Unknown names are a one-line `InvalidInput`
/// listing the valid ones.
pub fn feature_field(fs: &FeatureSet, name: &str) -> Result<Vec<f32>> {
    let c = fs.column(name).ok_or_else(|| {
        Error::InvalidInput(format!(
            "unknown feature '{name}' (expected one of: {})",
            fs.names.join(", ")
        ))
    })?;
    Ok(fs.values.iter().skip(c).step_by(fs.dim).copied().collect())
}

/// Height normalised to [0, 1] along `up` by the mesh's own bounding box.
pub fn normalised_height(positions: &[[f32; 3]], up: Up) -> Vec<f32> {
    let k = up.axis();
    let (lo, hi) = positions
        .iter()
        .map(|p| p[k])
        .filter(|x| x.is_finite())
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), x| {
            (a.min(x), b.max(x))
        });
    let span = hi - lo;
    positions
        .iter()
        .map(|p| if span > 0.0 { (p[k] - lo) / span } else { 0.5 })
        .collect()
}

/// Is the mesh wound inwards? Only a closed mesh (no boundary edge) can tell: its signed volume
/// is negative. Open meshes (terrains, scans) are trusted as wound (a ray or volume vote is
/// unreliable there: under a terrain everything is open).
pub fn wound_inwards(positions: &[[f32; 3]], faces: &[[u32; 3]]) -> bool {
    let n = positions.len();
    if faces.iter().any(|f| f.iter().any(|&v| v as usize >= n)) {
        return false;
    }
    if !crate::mesh::boundary_loops(faces).is_empty() {
        return false;
    }
    let volume: f64 = faces
        .iter()
        .map(|f| {
            let [a, b, c] = f.map(|v| Vec3::from(positions[v as usize]).as_dvec3());
            a.dot(b.cross(c))
        })
        .sum();
    volume < 0.0
}

/// The features of Mertens et al. §3.1 for every vertex (see [`FeatureSet`]): curvature radii are
/// `params.curvature_radii × bbox diagonal`, occlusion uses `params.rays` rays per vertex.
/// Normals are area-weighted vertex normals; the up axis only affects `height` (normals and
/// occlusion stay in object space, so a gravity direction can matter). A mesh wound inwards
/// ([`wound_inwards`]) is evaluated with its faces flipped, so that source and target agree on
/// what "outside" means (`FeatureSet::flipped` tells).
pub fn features(
    positions: &[[f32; 3]],
    faces: &[[u32; 3]],
    params: &Params,
    cancel: &CancelToken,
) -> Result<FeatureSet> {
    let n = positions.len();
    if n == 0 || faces.is_empty() {
        return Err(Error::InvalidInput("mesh has no faces".into()));
    }
    let sw = Stopwatch::start();
    let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
    for p in positions {
        lo = lo.min(Vec3::from(*p));
        hi = hi.max(Vec3::from(*p));
    }
    let diag = (hi - lo).length();
    if !(diag > 0.0 && diag.is_finite()) {
        return Err(Error::InvalidInput(
            "mesh has zero or non-finite extent".into(),
        ));
    }
    // Consistent orientation: every feature assumes outward normals; a closed mesh wound
    // inwards is flipped.
    let flipped = wound_inwards(positions, faces);
    let flipped_faces: Vec<[u32; 3]>;
    let faces: &[[u32; 3]] = if flipped {
        flipped_faces = faces.iter().map(|f| [f[0], f[2], f[1]]).collect();
        &flipped_faces
    } else {
        faces
    };
    let normals = crate::geometry::vertex_normals(positions, faces);
    let height = normalised_height(positions, params.up);
    let t0 = sw.secs();
    cancel.check()?;
    let radii: Vec<f32> = params.curvature_radii.iter().map(|r| r * diag).collect();
    let sw = Stopwatch::start();
    let curv = solid_angle_curvature_cancellable(positions, faces, &radii, cancel)?;
    let t1 = sw.secs();
    let sw = Stopwatch::start();
    let bvh = OcclusionBvh::new(positions, faces);
    let occ =
        directional_occlusion_with(&bvh, positions, &normals, params.rays, params.seed, cancel)?;
    let t2 = sw.secs();
    let nr = radii.len();
    let dim = 8 + nr;
    let mut values = Vec::with_capacity(n * dim);
    for v in 0..n {
        values.push(height[v]);
        values.extend_from_slice(&normals[v]);
        values.extend_from_slice(&curv[v * nr..(v + 1) * nr]);
        values.extend_from_slice(&occ[v]);
    }
    Ok(FeatureSet {
        names: feature_names(nr),
        dim,
        values,
        radii,
        seconds: [t0, t1, t2],
        flipped,
    })
}
