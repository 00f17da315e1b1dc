//! meshmatch: example-based texturing of 3D meshes.
//!
//! The engine (everything but `app` and `render`) runs headless and deterministic under a seed;
//! the desktop app and the CLI are thin clients of the same library calls.
//! See `docs/ARCHITECTURE.md` for the module map.

pub mod applications;
pub mod bench;
pub mod cli;
pub mod color;
pub mod correspondence;
pub mod demo;
pub mod error;
pub mod features;
pub mod geometry;
pub mod ground_truth;
pub mod hierarchy;
pub mod jobs;
pub mod mesh;
pub mod meshmatch;
pub mod stats;
pub mod synthesis;
pub mod testdata;
pub mod work;

#[cfg(feature = "gui")]
pub mod app;
#[cfg(feature = "gui")]
pub mod render;

pub use error::{Error, Result};
pub use mesh::TriMesh;
