//! Statistics shared by the synthesis systems, as free functions on flat row-major arrays:
//!
//! - [`cca`] / [`Cca`]: canonical correlation analysis (whitening + SVD, ridge-regularised)
//! - [`pdf_transfer`]: Pitié et al. 2005 n-D PDF transfer by random rotations
//! - [`kmeans`] / [`KMeans`]: k-means++ seeding and Lloyd iterations
//! - [`histogram`]: quantile functions, Heeger-Bergen histogram matching, KS distance, the
//!   Wasserstein-1 distance ([`wasserstein1`])
//! - [`KdTree`]: exact k-nearest neighbours in a few dimensions
//! - [`beats`]: a candidate must win by a margin, so that near ties keep one order (ties)
//! - [`pearson`]: Pearson's correlation coefficient (correlation)

pub mod cca;
pub mod correlation;
pub mod histogram;
pub mod kdtree;
pub mod kmeans;
pub mod pdf_transfer;
pub mod ties;

pub use cca::{Cca, cca};
pub use correlation::pearson;
pub use histogram::{
    blend_quantiles, ks_distance, match_histogram, match_to_quantiles, quantile_function,
    quantile_sorted, wasserstein1,
};
pub use kdtree::KdTree;
pub use kmeans::{KMeans, kmeans};
pub use pdf_transfer::{PdfTransferParams, pdf_transfer, random_rotation};
pub use ties::beats;
