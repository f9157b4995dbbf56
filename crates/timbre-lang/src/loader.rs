//! How library code reads files: only through a loader the host supplies, so an
//! embedding host decides what a script may open.

use std::io::{self, Read};
use std::path::{Path, PathBuf};

pub use timbre_ir::limits::MAX_FILE_BYTES;

/// The bytes of the regular file `path`, if it has at most `limit` of them. A device,
/// a pipe or a directory is refused (it may never end), and so is a longer file,
/// before anything is read (and if it grows while being read).
pub fn read_bounded(path: &Path, limit: u64) -> io::Result<Vec<u8>> {
    read_open_bounded(open_regular(path)?, limit)
}

/// Opens `path` for reading if it is a regular file. The opening itself cannot block
/// (`O_NONBLOCK`: opening a named pipe with no writer would wait for one forever),
/// and anything but a regular file is refused before a byte is read.
pub fn open_regular(path: &Path) -> io::Result<std::fs::File> {
    let mut options = std::fs::OpenOptions::new();
    options.read(true);
    #[cfg(unix)]
    std::os::unix::fs::OpenOptionsExt::custom_flags(&mut options, libc::O_NONBLOCK);
    let file = options.open(path)?;
    regular(file)
}

/// `file` if it is a regular file, else the error that says what it is not. On a
/// regular file `O_NONBLOCK` changes nothing, so it is left set.
fn regular(file: std::fs::File) -> io::Result<std::fs::File> {
    if !file.metadata()?.is_file() {
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            "not a regular file (a device, a pipe, a socket or a directory)",
        ));
    }
    Ok(file)
}

/// [`read_bounded`] of a file already open (and checked to be regular).
fn read_open_bounded(file: std::fs::File, limit: u64) -> io::Result<Vec<u8>> {
    let meta = file.metadata()?;
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

/// Reads only inside directories the host allows, capability-style: each directory is
/// opened once, and every file is opened through it (`cap-std`), so a path that
/// leaves it by `..`, an absolute path elsewhere, and a symbolic link that leads
/// outside are all refused by the opening itself, not by comparing strings (which a
/// link defeats). A link is followed only if it is relative and stays inside.
/// Relative paths resolve against the naming file, as with [`FsLoader`]; a path
/// named by no file resolves against the first directory.
#[derive(Debug)]
pub struct SandboxLoader {
    roots: Vec<(PathBuf, cap_std::fs::Dir)>,
}

impl SandboxLoader {
    /// A loader confined to `dirs` (each must exist).
    pub fn new<P: AsRef<Path>>(dirs: impl IntoIterator<Item = P>) -> io::Result<Self> {
        let roots = dirs
            .into_iter()
            .map(|dir| {
                let path = std::fs::canonicalize(dir.as_ref())?;
                let opened =
                    cap_std::fs::Dir::open_ambient_dir(&path, cap_std::ambient_authority())?;
                Ok((path, opened))
            })
            .collect::<io::Result<Vec<_>>>()?;
        Ok(SandboxLoader { roots })
    }
}

/// `path` with `.` and `..` taken out lexically (after an opening that has checked
/// they stay inside).
fn normalised(path: &Path) -> PathBuf {
    let mut out = PathBuf::new();
    for part in path.components() {
        match part {
            std::path::Component::CurDir => {}
            std::path::Component::ParentDir => {
                out.pop();
            }
            other => out.push(other),
        }
    }
    out
}

impl Loader for SandboxLoader {
    fn load(&self, path: &str, base: Option<&Path>) -> io::Result<(PathBuf, Vec<u8>)> {
        let requested = Path::new(path);
        let outside = || {
            io::Error::new(
                io::ErrorKind::PermissionDenied,
                format!("`{path}` is outside the directories this host allows"),
            )
        };
        let full = match base {
            Some(dir) if requested.is_relative() => dir.join(requested),
            _ => requested.to_path_buf(),
        };
        for (root, dir) in &self.roots {
            let relative = if full.is_absolute() {
                match full.strip_prefix(root) {
                    Ok(relative) => relative.to_path_buf(),
                    Err(_) => continue,
                }
            } else {
                full.clone()
            };
            let mut options = cap_std::fs::OpenOptions::new();
            options.read(true);
            #[cfg(unix)]
            cap_std::fs::OpenOptionsExt::custom_flags(&mut options, libc::O_NONBLOCK);
            let file = dir
                .open_with(&relative, &options)
                .map_err(|e| match e.kind() {
                    io::ErrorKind::NotFound => e,
                    _ => outside(),
                })?;
            let bytes = read_open_bounded(regular(file.into_std())?, MAX_FILE_BYTES)?;
            return Ok((root.join(normalised(&relative)), bytes));
        }
        Err(outside())
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

    /// A named pipe with no writer would block an ordinary open forever: it is
    /// refused at once, through either loader.
    #[cfg(unix)]
    #[test]
    fn a_named_pipe_is_refused_without_blocking() {
        let dir = std::env::temp_dir().join(format!("timbre-fifo-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let fifo = dir.join("pipe.tt");
        let name = std::ffi::CString::new(fifo.to_str().unwrap()).unwrap();
        // SAFETY: a valid C string and a mode.
        assert_eq!(unsafe { libc::mkfifo(name.as_ptr(), 0o600) }, 0);
        let started = std::time::Instant::now();
        let err = read_bounded(&fifo, 100).unwrap_err();
        assert!(err.to_string().contains("not a regular file"), "{err}");
        let err = FsLoader.load("pipe.tt", Some(&dir)).unwrap_err();
        assert!(err.to_string().contains("not a regular file"), "{err}");
        let sandbox = SandboxLoader::new([&dir]).unwrap();
        let err = sandbox.load("pipe.tt", Some(&dir)).unwrap_err();
        assert!(err.to_string().contains("not a regular file"), "{err}");
        assert!(started.elapsed() < std::time::Duration::from_secs(5));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
