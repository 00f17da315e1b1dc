//! Per-vertex features for MeshMatch (Chen et al. 2012, §3.2 and §4.1): shape features (Heat
//! Kernel Signature + normal·up, geodesic affinities to correspondences) and geodesic fans of a
//! pre-filtered signal (Zelinka & Garland 2004), plus local tangent frames and the frame-to-frame
//! rotation used to carry patch orientations across edges and levels.

mod affine_fit;
mod fan_table;
mod frames;
mod geodesics;
mod hks;

pub use affine_fit::min_norm_affine;
pub use fan_table::*;
pub use frames::*;
pub use geodesics::edge_geodesics;
pub use hks::*;

/// Number of fan radii (MeshMatch: R = 3).
pub const FAN_RADII: usize = 3;
/// Number of fan angles (MeshMatch: A = 18, 20 degrees apart).
pub const FAN_ANGLES: usize = 18;
/// Degrees per fan angle step.
pub const ANGLE_STEP_DEG: f32 = 360.0 / FAN_ANGLES as f32;
/// Number of HKS time scales.
pub const HKS_TIMES: usize = 8;
/// Laplacian eigenpairs the automatic HKS sums over.
pub const HKS_EIGENPAIRS: usize = 120;
/// Automatic shape feature size: 8 HKS scales + normal·up.
pub const SHAPE_DIM: usize = HKS_TIMES + 1;
