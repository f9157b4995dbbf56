//! How library code reads files: only through a loader the host supplies, so an
//! embedding host decides what a script may open.

use std::io::{self, Read};
use std::path::{Path, PathBuf};

/// The most bytes a script may have read from one file (256 MiB): a 23-minute stereo
/// 48 kHz 32-bit sound. Checked before reading, so `(include "/dev/zero")` or a huge
/// file is an error, not a render that runs out of memory.
pub const MAX_FILE_BYTES: u64 = 256 << 20;

/// The bytes of the regular file `path`, if it has at most `limit` of them. A device,
/// a pipe or a directory is refused (it may never end), and so is a longer file,
/// before anything is read (and if it grows while being read).
pub fn read_bounded(path: &Path, limit: u64) -> io::Result<Vec<u8>> {
    let file = std::fs::File::open(path)?;
    let meta = file.metadata()?;
    if !meta.is_file() {
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            "not a regular file (a device, a pipe or a directory)",
        ));
    }
    let too_long = || {
        io::Error::new(
            io::ErrorKind::InvalidInput,
            format!(
                "more than {} MiB, the most a script may read from one file",
                limit >> 20
            ),
        )
    };
    if meta.len() > limit {
        return Err(too_long());
    }
    let mut bytes = Vec::with_capacity(meta.len() as usize);
    file.take(limit + 1).read_to_end(&mut bytes)?;
    if bytes.len() as u64 > limit {
        return Err(too_long());
    }
    Ok(bytes)
}

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
        let bytes = read_bounded(&resolved, MAX_FILE_BYTES)?;
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_file_is_read_only_within_its_limit() {
        let dir = std::env::temp_dir().join(format!("timbre-loader-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("ten.txt");
        std::fs::write(&path, b"0123456789").unwrap();
        assert_eq!(read_bounded(&path, 10).unwrap(), b"0123456789");
        let err = read_bounded(&path, 9).unwrap_err();
        assert!(
            err.to_string().contains("the most a script may read"),
            "{err}"
        );
        // A directory is not a file to read.
        let err = read_bounded(&dir, 100).unwrap_err();
        assert!(err.to_string().contains("not a regular file"), "{err}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
