//! The per-vertex geometric features of Mertens et al. 2006 §3.1 (12 numbers with 4 radii):
//! normalised height (1), unit normal (3), solid-angle curvature at each radius (4),
//! directional occlusion on SH bands 0 and 1 (4).

use glam::Vec3;

use super::{Params, Up};

/// Grid spacing of the samples at which curvature at radius `r` is evaluated, over `r`; see
/// [`features`].
pub const CELL_PER_RADIUS: f32 = 0.25;
/// Grid spacing of the finest samples (occlusion and the smallest radius), over the smallest
/// radius. Measured on the horse at 500K points (`examples/feature_sampling.rs`): against every
/// vertex evaluated, 1/3 gives correlations 0.991 (smallest radius) and 0.975 (occlusion, where
/// two full evaluations with different rays agree to 0.964) in 3.6 s, 1/4 gives 0.994 and 0.974
/// in 5.3 s.
pub const LEVEL0_CELL_PER_RADIUS: f32 = 1.0 / 3.0;
use crate::error::{Error, Result};
use crate::geometry::{
    OcclusionBvh, SOLID_ANGLE_BETA, SolidAngleCurvature, directional_occlusion_with,
    sparse_samples_if_worth_it,
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
    /// Vertices at which occlusion and the smallest radius were evaluated (level 0 of the
    /// sampling; every vertex on a coarse mesh).
    pub evaluated: usize,
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
/// `params.curvature_radii × bbox diagonal`, occlusion casts `params.rays` rays per evaluated
/// vertex.
///
/// Height and normals are exact per vertex. Occlusion and the smallest radius are evaluated at a
/// grid subsample of spacing `r_min × LEVEL0_CELL_PER_RADIUS` (level 0), curvature at a larger
/// radius `r` at a grid subsample of level 0 of spacing `r × CELL_PER_RADIUS`, and everything is
/// interpolated back to every vertex (`geometry::sparse_evaluation`; the role of the paper's
/// Gaussian pyramid: each feature computed at the resolution its scale needs). On a mesh too
/// coarse for a subsample to pay (more than half its vertices sampled) every vertex is
/// evaluated. The tree's opening criterion grows with the radius (`SOLID_ANGLE_BETA ×
/// sqrt(r / r_min)`, at most 8), where fewer samples make the accuracy affordable.
///
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
    features_on_surface(positions, faces, None, params, cancel)
}

/// The solid-angle tree's opening criterion for radius `r` when the smallest radius is `r_min`:
/// `SOLID_ANGLE_BETA × sqrt(r / r_min)`, at most 8 (see [`features`]).
pub fn opening_for_radius(r: f32, r_min: f32) -> f32 {
    (SOLID_ANGLE_BETA * (r / r_min).sqrt()).clamp(SOLID_ANGLE_BETA, 8.0)
}

/// A triangulated surface: positions and faces.
pub type Surface<'a> = (&'a [[f32; 3]], &'a [[u32; 3]]);

/// [`features`] of a mesh whose vertices lie on another triangulation of the same surface,
/// `surface = (positions, faces)` (the input a working mesh was refined from): the occlusion
/// rays are cast against the surface's triangles, far fewer than the working mesh's, with the
/// same results. `None` uses the mesh itself.
///
/// The features are computed on the mesh scaled by the power of two nearest its size (exact in
/// floating point), so the same mesh in any units gets the same values (radii in its units).
pub fn features_on_surface(
    positions: &[[f32; 3]],
    faces: &[[u32; 3]],
    surface: Option<Surface<'_>>,
    params: &Params,
    cancel: &CancelToken,
) -> Result<FeatureSet> {
    let e = crate::geometry::unit_exponent(positions);
    if e == 0 {
        return features_unit(positions, faces, surface, params, cancel);
    }
    let scale = |ps: &[[f32; 3]]| crate::geometry::scaled_by_power_of_two(ps, -e);
    let unit = scale(positions);
    let unit_surface = surface.map(|(p, f)| (scale(p), f));
    let mut fs = features_unit(
        &unit,
        faces,
        unit_surface.as_ref().map(|(p, f)| (p.as_slice(), *f)),
        params,
        cancel,
    )?;
    let up = 2f32.powi(e);
    fs.radii.iter_mut().for_each(|r| *r *= up);
    Ok(fs)
}

/// [`features_on_surface`] on a mesh of about unit size.
fn features_unit(
    positions: &[[f32; 3]],
    faces: &[[u32; 3]],
    surface: Option<Surface<'_>>,
    params: &Params,
    cancel: &CancelToken,
) -> Result<FeatureSet> {
    let n = positions.len();
    if n == 0 || faces.is_empty() {
        return Err(Error::InvalidInput("mesh has no faces".into()));
    }
    let clock = Stopwatch::start();
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
    // inwards is flipped (and its surface with it).
    let flipped = wound_inwards(positions, faces);
    let flip = |f: &[[u32; 3]]| -> Vec<[u32; 3]> { f.iter().map(|t| [t[0], t[2], t[1]]).collect() };
    let flipped_faces: Vec<[u32; 3]>;
    let faces: &[[u32; 3]] = if flipped {
        flipped_faces = flip(faces);
        &flipped_faces
    } else {
        faces
    };
    let flipped_surface: Vec<[u32; 3]>;
    let (surf_pos, surf_faces): (&[[f32; 3]], &[[u32; 3]]) = match surface {
        Some((p, f)) if flipped => {
            flipped_surface = flip(f);
            (p, &flipped_surface)
        }
        Some((p, f)) => (p, f),
        None => (positions, faces),
    };
    let normals = crate::geometry::vertex_normals(positions, faces);
    let height = normalised_height(positions, params.up);
    let t0 = clock.secs();
    cancel.check()?;
    let radii: Vec<f32> = params.curvature_radii.iter().map(|r| r * diag).collect();
    let nr = radii.len();
    // the smallest radius (1% of the diagonal sets the finest grid when there are none)
    let r_min = match radii.iter().copied().reduce(f32::min) {
        Some(r) => r,
        None => 0.01 * diag,
    };
    // A pyramid of grid subsamples (`geometry::sparse_evaluation`): level 0 is a grid of
    // spacing r_min × LEVEL0_CELL_PER_RADIUS over the vertices, where occlusion and the smallest
    // radius are evaluated; curvature at a larger radius r on a grid of spacing
    // r × CELL_PER_RADIUS over level 0, interpolated back onto level 0; then one pass carries
    // everything from level 0 to every vertex. A level 0 holding more than half the vertices
    // is not worth it: every vertex is evaluated then.
    let clock = Stopwatch::start();
    let s0 = sparse_samples_if_worth_it(positions, &normals, r_min * LEVEL0_CELL_PER_RADIUS);
    let (p0, n0): (Vec<[f32; 3]>, Vec<[f32; 3]>) = s0
        .vertices
        .iter()
        .map(|&v| (positions[v as usize], normals[v as usize]))
        .unzip();
    let m = s0.len();
    // level-0 values: curvature columns, then the 4 occlusion columns
    let dim0 = nr + 4;
    let mut level0 = vec![0.0f32; m * dim0];
    let sac = SolidAngleCurvature::new(positions, faces);
    for (j, &r) in radii.iter().enumerate() {
        cancel.check()?;
        // the tree's error grows with the radius (`SOLID_ANGLE_BETA`), and larger radii have
        // quadratically fewer samples: a stricter opening criterion there
        let beta = opening_for_radius(r, r_min);
        let sj = sparse_samples_if_worth_it(&p0, &n0, r * CELL_PER_RADIUS);
        let at: Vec<u32> = sj
            .vertices
            .iter()
            .map(|&i| s0.vertices[i as usize])
            .collect();
        let col = sj.interpolate(&p0, &n0, &sac.at(&at, &[r], beta, cancel)?, 1);
        for (i, x) in col.into_iter().enumerate() {
            level0[i * dim0 + j] = x;
        }
    }
    drop(sac);
    let t1 = clock.secs();
    let clock = Stopwatch::start();
    let bvh = OcclusionBvh::new(surf_pos, surf_faces);
    let occ0 = directional_occlusion_with(&bvh, &p0, &n0, params.rays, params.seed, cancel)?;
    drop(bvh);
    for (i, o) in occ0.iter().enumerate() {
        level0[i * dim0 + nr..(i + 1) * dim0].copy_from_slice(o);
    }
    let all = s0.interpolate(positions, &normals, &level0, dim0);
    let t2 = clock.secs();
    let dim = 8 + nr;
    let mut values = Vec::with_capacity(n * dim);
    for v in 0..n {
        values.push(height[v]);
        values.extend_from_slice(&normals[v]);
        values.extend_from_slice(&all[v * dim0..(v + 1) * dim0]);
    }
    Ok(FeatureSet {
        names: feature_names(nr),
        dim,
        values,
        radii,
        seconds: [t0, t1, t2],
        flipped,
        evaluated: m,
    })
}
