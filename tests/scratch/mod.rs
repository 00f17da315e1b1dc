//! Scratch folders for tests: each is a fresh folder in the temporary directory that deletes
//! itself, with everything in it, when dropped (also when its test fails), so a test run leaves
//! nothing behind. It reads as a `Path` (`dir.join("a.ply")`, `&dir` where a `&Path` is asked).

#![allow(dead_code)]

use std::path::{Path, PathBuf};

/// A self-deleting scratch folder.
pub struct Scratch(tempfile::TempDir);

impl Scratch {
    /// A fresh folder named after `name` (a unique suffix keeps parallel tests apart).
    pub fn new(name: &str) -> Scratch {
        Scratch(
            tempfile::Builder::new()
                .prefix(&format!("meshmatch-{name}-"))
                .tempdir()
                .expect("a scratch folder in the temporary directory"),
        )
    }

    /// The folder's path.
    pub fn path(&self) -> &Path {
        self.0.path()
    }

    /// The folder's path (as `PathBuf::as_path` reads).
    pub fn as_path(&self) -> &Path {
        self.0.path()
    }

    /// The folder's path, owned.
    pub fn to_path_buf(&self) -> PathBuf {
        self.0.path().to_path_buf()
    }
}

impl std::ops::Deref for Scratch {
    type Target = Path;
    fn deref(&self) -> &Path {
        self.0.path()
    }
}

impl AsRef<Path> for Scratch {
    fn as_ref(&self) -> &Path {
        self.0.path()
    }
}

impl AsRef<std::ffi::OsStr> for Scratch {
    fn as_ref(&self) -> &std::ffi::OsStr {
        self.0.path().as_os_str()
    }
}
