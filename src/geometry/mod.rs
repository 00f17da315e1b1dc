//! Shared geometric primitives: welding, normals, cotan Laplacian and mass matrices, Laplacian
//! eigenpairs and the heat kernel signature, heat-method geodesics, tangent frames, a triangle
//! BVH, working-resolution refinement and Taubin smoothing.

mod basic;
mod bvh;
mod eigen;
mod frames;
mod heat;
mod laplacian;
mod refine;

pub use basic::{face_areas, face_normals, mean_edge_length, taubin_smooth, vertex_normals, weld};
pub use bvh::TriangleBvh;
pub use eigen::{hks, hks_times, laplacian_eigen};
pub use frames::{parallel_transport_angle, tangent_frames};
pub use heat::HeatGeodesics;
pub use laplacian::{cotan_laplacian, mass_matrix_barycentric, mass_matrix_voronoi};
pub use refine::{Refined, nearest_original, refine_to_density};
