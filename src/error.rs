//! The library's error type: every failure a user can cause is a variant with a clear message.

use std::path::PathBuf;

/// Errors from loading, validating, processing and exporting meshes.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying I/O error.
        source: std::io::Error,
    },
    /// A file was read but its contents are not a valid mesh/image of the expected format.
    #[error("{path}: {msg}")]
    Format {
        /// The file.
        path: PathBuf,
        /// What is wrong, in one line.
        msg: String,
    },
    /// The file extension names no format this tool reads or writes.
    #[error("{path}: unsupported format (expected .obj, .ply, .gltf or .glb)")]
    UnsupportedFormat {
        /// The file.
        path: PathBuf,
    },
    /// A mesh that loaded but cannot be used (no faces, no finite coordinates, too large).
    #[error("{0}")]
    InvalidMesh(String),
    /// A request the library cannot honour (bad parameter, bad correspondence index).
    #[error("{0}")]
    InvalidInput(String),
    /// A long job was cancelled by the user.
    #[error("cancelled")]
    Cancelled,
}

/// Result alias used throughout the crate.
pub type Result<T> = std::result::Result<T, Error>;

impl Error {
    /// A format error for `path` with message `msg`.
    pub fn format(path: impl Into<PathBuf>, msg: impl Into<String>) -> Self {
        Error::Format {
            path: path.into(),
            msg: msg.into(),
        }
    }
    /// An I/O error for `path`.
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Io {
            path: path.into(),
            source,
        }
    }
}
