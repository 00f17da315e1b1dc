//! Shared geometric primitives: welding, normals, cotan Laplacian and mass matrices, Laplacian
//! eigenpairs and the heat kernel signature, heat-method geodesics, tangent frames, a triangle
//! BVH, working-resolution refinement and Taubin smoothing.

mod basic;
mod eigen;
mod laplacian;

pub use basic::{face_areas, face_normals, mean_edge_length, taubin_smooth, vertex_normals, weld};
pub use eigen::{hks, hks_times, laplacian_eigen};
pub use laplacian::{cotan_laplacian, mass_matrix_barycentric, mass_matrix_voronoi};
