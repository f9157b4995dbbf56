//! How library code reads files: only through a loader the host supplies, so an
//! embedding host decides what a script may open.

use std::io;
use std::path::{Path, PathBuf};

pub trait Loader {
    /// Reads `path` as written in the script, relative to `base` (the directory of
    /// the file that names it, if it came from a file). Returns the resolved name
    /// (for messages and for resolving further relative paths) and the bytes.
    fn load(&self, path: &str, base: Option<&Path>) -> io::Result<(PathBuf, Vec<u8>)>;
}

/// Reads from the file system, resolving relative paths against the naming file.
#[derive(Clone, Copy, Debug, Default)]
pub struct FsLoader;

impl Loader for FsLoader {
    fn load(&self, path: &str, base: Option<&Path>) -> io::Result<(PathBuf, Vec<u8>)> {
        let path = Path::new(path);
        let resolved = match base {
            Some(dir) if path.is_relative() => dir.join(path),
            _ => path.to_path_buf(),
        };
        let bytes = std::fs::read(&resolved)?;
        // One name per file, so that `lib/../lib/a.tt` and `lib/a.tt` are one include.
        let resolved = std::fs::canonicalize(&resolved).unwrap_or(resolved);
        Ok((resolved, bytes))
    }
}

/// Refuses every file: for hosts that allow scripts no file access.
#[derive(Clone, Copy, Debug, Default)]
pub struct NoFiles;

impl Loader for NoFiles {
    fn load(&self, path: &str, _base: Option<&Path>) -> io::Result<(PathBuf, Vec<u8>)> {
        Err(io::Error::new(
            io::ErrorKind::PermissionDenied,
            format!("this host allows no file access (asked for `{path}`)"),
        ))
    }
}
