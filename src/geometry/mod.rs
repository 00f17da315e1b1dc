//! Shared geometric primitives, one implementation each, as free functions on flat arrays:
//!
//! - [`weld`], [`face_normals`], [`vertex_normals`], [`face_areas`], [`mean_edge_length`]
//! - [`cotan_laplacian`] (PSD stiffness `L = -cotmatrix`), [`mass_matrix_voronoi`],
//!   [`mass_matrix_barycentric`]
//! - [`laplacian_eigen`] (smallest eigenpairs of `L φ = λ M φ`, flat column-major vectors),
//!   [`hks`] (flat vertex-major `n × times`), [`hks_times`]
//! - [`laplacian_deform`] (uniform Laplacian coordinates + soft position constraints, Zhou et
//!   al. 2006 eq. (4)-(5))
//! - [`HeatGeodesics`] (heat-method distances, factorised once, many source sets)
//! - [`tangent_frames`] / [`Frames`] by a [`FrameRule`], [`transport_angle`]
//! - [`smooth_direction_field`] (Knöppel et al. 2013: the smooth tangent field nearest a guide)
//! - [`TriangleBvh`] (closest point, ray hit)
//! - [`refine_to_density`] / [`Refined`], [`nearest_original`]
//! - [`morton_order`] (a cache-friendly visiting order along the Z-order curve)
//! - [`value_noise`] (hashed-lattice value noise with a [`Fade`])
//! - [`taubin_smooth`]
//! - [`shape_map`] / [`functional_map`] (functional maps + ZoomOut: a global intrinsic map)
//! - [`solid_angle_curvature`] (Connolly / Mertens multi-scale curvature, Barnes-Hut tree)
//! - [`principal_curvatures`] (tensor averaging), [`salient_curves`] (crest lines after
//!   Yoshizawa et al. 2005, creases by dihedral angle; Xu et al. 2009 §4.1 grouping)
//! - [`oriented_curve_field`] (Xu et al. 2009 greedy curve orientation + harmonic diffusion)
//! - [`distance_to_polylines`] (surface distance to salient curves: Euclidean near, edge paths far)
//! - [`directional_occlusion`] (ray-cast visibility on SH bands 0 and 1), [`thickness`] (mean
//!   inward ray distance)
//! - [`sparse_samples`] (a grid subsample of the vertices and the interpolation back: expensive
//!   smooth fields evaluated at their own scale)
//! - [`offset_surface`], [`shell_point`] / [`shell_point_ruled`], [`shell_stretch`], [`minimize_shell_stretch`]
//!   (tetrahedral shell maps, Zhou et al. 2006 eq. (8)-(9): offset, map, L2 stretch, its
//!   minimisation)
//! - [`exp_map`] / [`ExpMap`] (discrete exponential map of a geodesic disc)
//! - [`stripe_pattern`] / [`StripePattern`] (Knöppel et al. 2015: a phase per vertex advancing
//!   at a given frequency along a direction field; two of them make a global lattice)
//! - [`uv_atlas`] (charts, LSCM + ARAP, packing: UVs for a mesh without them)
//! - [`bake_uv`] / [`fill_gutters`] (conservative UV rasterisation, pull-push gutters),
//!   [`bake_closest`] (another surface's colours by closest point),
//!   [`mip_chain`], [`sample_bilinear`]

mod basic;
mod bvh;
mod closest_walk;
mod crest_lines;
mod curvature;
mod curve_distance;
mod curve_guided_field;
mod direction_fields;
mod distance_transform;
mod eigen;
mod expmap;
mod frames;
mod functional_map;
mod heat;
mod laplacian;
mod laplacian_editing;
mod morton_order;
mod noise;
mod occlusion;
mod refine;
mod shell_map;
mod solid_angle_curvature;
mod sparse_evaluation;
mod stripe_patterns;
mod thickness;
mod uv_atlas;
mod uv_bake;

pub use basic::{
    face_areas, face_normals, mean_edge_length, scaled_by_power_of_two, taubin_smooth,
    unit_exponent, vertex_normals, weld,
};
/// The renderer's picking shares the closest-point query's barycentric tolerance.
#[cfg(feature = "gui")]
pub(crate) use bvh::BARY_EPS;
pub use bvh::TriangleBvh;
pub(crate) use bvh::closest_on_triangle;
pub use closest_walk::closest_point_walk;
pub use crest_lines::{Curve, CurveKind, CurveParams, salient_curves};
pub use curvature::{PrincipalCurvatures, principal_curvatures};
pub use curve_distance::{Polyline, distance_to_polylines};
pub use curve_guided_field::{
    CurveField, FieldCurve, FieldParams, HarmonicFieldSolver, curve_field_completing_orientations,
    curve_tangents, field_roughness, oriented_curve_field, score_terms,
};
pub use direction_fields::smooth_direction_field;
pub use distance_transform::distance_transform;
pub use eigen::{hks, hks_times, laplacian_eigen};
pub use expmap::{DiscSeed, ExpMap, exp_map, tangent_direction};
pub use frames::{FrameRule, Frames, frame_of, tangent_frames, transport_angle};
pub(crate) use functional_map::cholesky_solve;
pub use functional_map::{FmapParams, MapQuality, ShapeMap, Spectrum, functional_map, shape_map};
pub use heat::HeatGeodesics;
pub use laplacian::{cotan_laplacian, mass_matrix_barycentric, mass_matrix_voronoi};
pub use laplacian_editing::laplacian_deform;
pub use morton_order::{inverse_order, morton_order};
pub use noise::{Fade, value_noise};
pub use occlusion::{OcclusionBvh, directional_occlusion, directional_occlusion_with};
pub(crate) use refine::IntMap;
pub use refine::{Refined, nearest_original, refine_to_density, refine_to_edge_length};
pub use shell_map::{
    ShellStretch, StretchReport, minimize_shell_stretch, offset_surface, shell_point,
    shell_point_ruled, shell_stretch,
};
pub use solid_angle_curvature::{
    BETA as SOLID_ANGLE_BETA, SolidAngleCurvature, SolidAngleTree, solid_angle_curvature,
    solid_angle_curvature_cancellable,
};
pub use sparse_evaluation::{SparseSamples, sparse_samples, sparse_samples_if_worth_it};
pub use stripe_patterns::{StripePattern, stripe_pattern};
pub use thickness::thickness;
pub use uv_atlas::{AtlasParams, MIN_ATLAS_SIZE, UvAtlas, min_atlas_size, uv_atlas};
pub use uv_bake::{
    BAKE_BYTES_PER_TEXEL, BakedImage, bake_closest, bake_onto, bake_uv, check_bake_memory,
    fill_gutters, fill_gutters_dilated, mip_chain, sample_bilinear, uv_texels,
};
