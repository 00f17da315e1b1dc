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

/// A vector of `len` copies of `value`, or a one-line error naming `what` and the size when the
/// memory cannot be had (`try_reserve`: an allocation failure is an error, not an abort).
pub fn try_filled<T: Clone>(len: usize, value: T, what: &str) -> Result<Vec<T>> {
    let mut v = Vec::new();
    v.try_reserve_exact(len).map_err(|_| {
        Error::InvalidInput(format!(
            "not enough memory for {what} ({:.0} MiB); use fewer working vertices",
            (len as f64) * std::mem::size_of::<T>() as f64 / (1u64 << 20) as f64
        ))
    })?;
    v.resize(len, value);
    Ok(v)
}

#[cfg(test)]
mod tests {
    #[test]
    fn an_impossible_allocation_is_an_error_not_an_abort() {
        let e = super::try_filled(usize::MAX / 8, 0.0f32, "the fans").unwrap_err();
        assert!(
            e.to_string().contains("not enough memory for the fans"),
            "{e}"
        );
        assert_eq!(super::try_filled(3, 1u8, "x").unwrap(), vec![1, 1, 1]);
    }
}
