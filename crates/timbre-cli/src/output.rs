//! The one way out for every file timbre writes: sounds, pictures, graphs, MIDI
//! files, note listings, formatted scripts, evolved scenes, REPL saves.
//!
//! An output is *prepared* before any work is done: the name is checked (a device,
//! a pipe, a socket or a directory is never replaced, nor any file the run reads or
//! another output of the same run, links and hard links included), and a temporary
//! file is created beside the target under an unpredictable name with `O_EXCL`, so
//! that nothing planted in the directory (a link at the name a render would use) can
//! receive the bytes. The temporary file takes the replaced file's mode and owner
//! (or the output is refused), and is renamed over the target only when complete
//! ([`Output::commit`]); dropped uncommitted (an error, an interruption) it is
//! removed and the target is left as it was.

use std::fs::File;
use std::io::Write;
use std::path::{Path, PathBuf};

/// An output being written: its temporary file, renamed over the target by
/// [`Output::commit`], removed if dropped before.
pub struct Output {
    /// The name as given (for messages).
    requested: PathBuf,
    /// The file replaced: the name given, or where a symbolic link there leads (the
    /// link is kept and leads to the new file).
    target: PathBuf,
    temp: tempfile::NamedTempFile,
}

impl std::fmt::Debug for Output {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Output")
            .field("requested", &self.requested)
            .field("target", &self.target)
            .finish()
    }
}

impl Output {
    /// The temporary file, to write the output into.
    pub fn file(&mut self) -> &mut File {
        self.temp.as_file_mut()
    }

    /// The name the output was asked for.
    pub fn path(&self) -> &Path {
        &self.requested
    }

    /// Moves the finished file over the target. The target is checked once more:
    /// if something other than a regular file appeared there meanwhile, it is left
    /// alone and the output is removed.
    pub fn commit(mut self) -> Result<(), String> {
        let requested = self.requested.clone();
        let cannot =
            |e: &dyn std::fmt::Display| format!("cannot write `{}`: {e}", requested.display());
        self.temp.as_file_mut().flush().map_err(|e| cannot(&e))?;
        if let Ok(meta) = std::fs::symlink_metadata(&self.target) {
            if !meta.is_file() {
                return Err(cannot(&format!(
                    "{} appeared there while it was written; it was left alone",
                    kind_of(&meta)
                )));
            }
        }
        self.temp
            .persist(&self.target)
            .map(drop)
            .map_err(|e| cannot(&e.error))
    }
}

/// Prepares one output (see the module's documentation); `reads` are the files the
/// run reads or has read.
pub fn prepare(requested: &Path, reads: &[PathBuf]) -> Result<Output, String> {
    Ok(prepare_all(&[requested], reads)?
        .pop()
        .expect("one output asked for"))
}

/// Prepares every output of a run at once, before any of them is written: each is
/// checked against the files the run reads and against the others.
pub fn prepare_all(requested: &[&Path], reads: &[PathBuf]) -> Result<Vec<Output>, String> {
    let read: Vec<FileKey> = reads.iter().filter_map(|p| FileKey::of(p)).collect();
    let mut outputs: Vec<(FileKey, Output)> = Vec::with_capacity(requested.len());
    for &path in requested {
        let cannot = |reason: String| format!("cannot write `{}`: {reason}", path.display());
        let (target, existing) = resolve(path).map_err(cannot)?;
        let key = FileKey::of(&target).ok_or_else(|| {
            cannot("its directory does not exist; create it first or choose another name".into())
        })?;
        if read.iter().any(|r| r.same(&key)) {
            return Err(cannot(
                "the run reads that file, and the output would replace it; choose another name"
                    .into(),
            ));
        }
        if let Some((_, other)) = outputs.iter().find(|(k, _)| k.same(&key)) {
            return Err(cannot(format!(
                "it is the same file as the output `{}`; give each output its own name",
                other.requested.display()
            )));
        }
        let temp = create_temp(&target, existing.as_ref(), TEMP_NAME_RANDOM).map_err(cannot)?;
        outputs.push((
            key,
            Output {
                requested: path.to_path_buf(),
                target,
                temp,
            },
        ));
    }
    Ok(outputs.into_iter().map(|(_, output)| output).collect())
}

/// [`prepare_all`] of the outputs a run may or may not ask for, each given back in
/// its place (`None` where none was asked for).
pub fn prepare_asked<const N: usize>(
    asked: [Option<&Path>; N],
    reads: &[PathBuf],
) -> Result<[Option<Output>; N], String> {
    let paths: Vec<&Path> = asked.iter().flatten().copied().collect();
    let mut prepared = prepare_all(&paths, reads)?.into_iter();
    Ok(asked.map(|path| path.and_then(|_| prepared.next())))
}

/// Replaces the file at `path` (or creates it) with `bytes`, through [`prepare`].
pub fn replace_file(path: &Path, bytes: &[u8], reads: &[PathBuf]) -> Result<(), String> {
    let mut output = prepare(path, reads)?;
    output
        .file()
        .write_all(bytes)
        .map_err(|e| format!("cannot write `{}`: {e}", path.display()))?;
    output.commit()
}

/// Checks that standard output can take a stream (`-o -` with standard output
/// closed would otherwise write nowhere and succeed). Rust's runtime puts
/// `/dev/null`, opened for reading and writing, on a standard descriptor that was
/// closed when the process started; a shell's `> /dev/null` opens it write-only, so
/// that one is still allowed.
pub fn check_stdout() -> Result<(), String> {
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        // SAFETY: F_GETFL only reads descriptor 1's status flags.
        let flags = unsafe { libc::fcntl(1, libc::F_GETFL) };
        let null = std::fs::metadata("/dev/null").map(|m| m.rdev()).ok();
        let is_null = || {
            // SAFETY: a zeroed stat for fstat to fill.
            let mut stat: libc::stat = unsafe { std::mem::zeroed() };
            // SAFETY: a valid descriptor number and a pointer to a stat.
            (unsafe { libc::fstat(1, &mut stat) } == 0)
                && stat.st_mode & libc::S_IFMT == libc::S_IFCHR
                && Some(stat.st_rdev) == null
        };
        let reopened = flags != -1 && flags & libc::O_ACCMODE == libc::O_RDWR && is_null();
        if flags == -1 || reopened {
            return Err(
                "standard output is closed: nothing written there would arrive; \
                        give a file name with -o"
                    .into(),
            );
        }
    }
    Ok(())
}

/// Writes larger than the process's file size limit fail with an error (EFBIG) that
/// names the file, instead of killing the process (SIGXFSZ) with its temporary file
/// left behind.
pub fn ignore_file_size_signal() {
    #[cfg(unix)]
    // SAFETY: setting a signal's disposition to "ignore" runs no code of ours.
    unsafe {
        libc::signal(libc::SIGXFSZ, libc::SIG_IGN);
    }
}

/// Random characters in a temporary file's name (62 choices each).
const TEMP_NAME_RANDOM: usize = 12;

/// Bytes of the target's name kept in the temporary file's name (a name has at most
/// 255 bytes, and the temporary one adds about 25).
const TEMP_NAME_KEPT: usize = 200;

/// The file an output named `path` replaces, and its metadata if it exists. A
/// symbolic link is followed (and kept); anything but a regular file is refused.
fn resolve(path: &Path) -> Result<(PathBuf, Option<std::fs::Metadata>), String> {
    if path.as_os_str().is_empty() || path.file_name().is_none() {
        return Err("it names a directory, not a file; choose a file name".into());
    }
    let meta = match std::fs::symlink_metadata(path) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            return Ok((path.to_path_buf(), None))
        }
        Err(e) => return Err(e.to_string()),
        Ok(meta) => meta,
    };
    let target = if meta.file_type().is_symlink() {
        std::fs::canonicalize(path).map_err(|_| {
            "it is a symbolic link that leads nowhere; remove it or choose another name".to_string()
        })?
    } else {
        path.to_path_buf()
    };
    let meta = std::fs::metadata(&target).map_err(|e| e.to_string())?;
    if !meta.is_file() {
        return Err(format!(
            "it is {}, not a regular file, and the output would replace it; choose a file name",
            kind_of(&meta)
        ));
    }
    Ok((target, Some(meta)))
}

/// The temporary file for `target`: in its directory (so the rename is atomic),
/// hidden, named `.NAME.RANDOM.partial`, created with `O_EXCL` (so it is never a
/// file or link already there), with the mode and owner of `existing`.
fn create_temp(
    target: &Path,
    existing: Option<&std::fs::Metadata>,
    random: usize,
) -> Result<tempfile::NamedTempFile, String> {
    let dir = match target.parent() {
        Some(dir) if !dir.as_os_str().is_empty() => dir,
        _ => Path::new("."),
    };
    let name = target
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let mut cut = name.len().min(TEMP_NAME_KEPT);
    while !name.is_char_boundary(cut) {
        cut -= 1;
    }
    let prefix = format!(".{}.", &name[..cut]);
    let mut builder = tempfile::Builder::new();
    builder
        .prefix(&prefix)
        .suffix(".partial")
        .rand_bytes(random);
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        // A new file gets the usual mode less the umask, as `File::create` gives.
        builder.permissions(std::fs::Permissions::from_mode(0o666));
    }
    let temp = builder
        .tempfile_in(dir)
        .map_err(|e| format!("cannot create a file in `{}`: {e}", dir.display()))?;
    if let Some(old) = existing {
        keep_mode_and_owner(temp.as_file(), old)?;
    }
    Ok(temp)
}

/// Gives `file` the mode and owner of `old`, or says why it cannot.
#[cfg(unix)]
fn keep_mode_and_owner(file: &File, old: &std::fs::Metadata) -> Result<(), String> {
    use std::os::unix::fs::MetadataExt;
    file.set_permissions(old.permissions())
        .map_err(|e| format!("cannot give the new file the old one's mode: {e}"))?;
    let new = file.metadata().map_err(|e| e.to_string())?;
    if (new.uid(), new.gid()) != (old.uid(), old.gid()) {
        std::os::unix::fs::fchown(file, Some(old.uid()), Some(old.gid())).map_err(|e| {
            format!(
                "it belongs to user {} and group {}, and the new file cannot ({e}); \
                 refusing to replace it with a file of another owner",
                old.uid(),
                old.gid()
            )
        })?;
        // Changing the owner may clear the set-user and set-group bits.
        file.set_permissions(old.permissions())
            .map_err(|e| format!("cannot give the new file the old one's mode: {e}"))?;
    }
    Ok(())
}

#[cfg(not(unix))]
fn keep_mode_and_owner(file: &File, old: &std::fs::Metadata) -> Result<(), String> {
    file.set_permissions(old.permissions())
        .map_err(|e| format!("cannot give the new file the old one's mode: {e}"))
}

/// What a file that is not a regular file is, for messages.
fn kind_of(meta: &std::fs::Metadata) -> &'static str {
    if meta.is_dir() {
        return "a directory";
    }
    if meta.file_type().is_symlink() {
        return "a symbolic link";
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        let kind = meta.file_type();
        if kind.is_fifo() {
            return "a named pipe";
        } else if kind.is_socket() {
            return "a socket";
        } else if kind.is_char_device() || kind.is_block_device() {
            return "a device";
        }
    }
    "a special file"
}

/// Which file a path is: its device and inode if it exists (so hard links and
/// links are one file), and its canonical name (its directory's canonical path
/// and its own name, for a file not yet there).
struct FileKey {
    inode: Option<(u64, u64)>,
    name: PathBuf,
}

impl FileKey {
    fn of(path: &Path) -> Option<FileKey> {
        let name = match std::fs::canonicalize(path) {
            Ok(name) => name,
            Err(_) => {
                let dir = match path.parent() {
                    Some(dir) if !dir.as_os_str().is_empty() => dir,
                    _ => Path::new("."),
                };
                std::fs::canonicalize(dir).ok()?.join(path.file_name()?)
            }
        };
        Some(FileKey {
            inode: inode(path),
            name,
        })
    }

    fn same(&self, other: &FileKey) -> bool {
        self.name == other.name || (self.inode.is_some() && self.inode == other.inode)
    }
}

#[cfg(unix)]
fn inode(path: &Path) -> Option<(u64, u64)> {
    use std::os::unix::fs::MetadataExt;
    std::fs::metadata(path).ok().map(|m| (m.dev(), m.ino()))
}

#[cfg(not(unix))]
fn inode(_: &Path) -> Option<(u64, u64)> {
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_link_planted_at_the_temporary_name_is_not_followed() {
        let dir = tempfile::tempdir().unwrap();
        let victim = dir.path().join("victim");
        std::fs::write(&victim, "precious").unwrap();
        let target = dir.path().join("out.wav");
        // With no random characters the name is predictable: `.out.wav..partial`.
        let planted = dir.path().join(".out.wav..partial");
        std::os::unix::fs::symlink(&victim, &planted).unwrap();
        let err = create_temp(&target, None, 0).unwrap_err();
        assert!(err.contains("exists"), "{err}");
        assert_eq!(std::fs::read_to_string(&victim).unwrap(), "precious");
    }

    #[test]
    fn a_file_read_or_written_twice_is_refused_links_included() {
        let dir = tempfile::tempdir().unwrap();
        let script = dir.path().join("s.tt");
        std::fs::write(&script, "(sine (* t 440))").unwrap();
        let link = dir.path().join("link.tt");
        std::os::unix::fs::symlink(&script, &link).unwrap();
        let hard = dir.path().join("hard.tt");
        std::fs::hard_link(&script, &hard).unwrap();
        let reads = [script.clone()];
        for path in [&script, &link, &hard] {
            let err = prepare(path, &reads).unwrap_err();
            assert!(err.contains("the run reads that file"), "{err}");
        }
        let a = dir.path().join("a.png");
        let err = prepare_all(&[&a, &dir.path().join(".").join("a.png")], &[]).unwrap_err();
        assert!(err.contains("the same file as the output"), "{err}");
        assert_eq!(
            std::fs::read_to_string(&script).unwrap(),
            "(sine (* t 440))"
        );
        // Nothing is left behind by the refusals.
        let left: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
        assert_eq!(left.len(), 3);
    }

    #[test]
    fn devices_pipes_and_directories_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        for (path, kind) in [
            (PathBuf::from("/dev/null"), "a device"),
            (dir.path().to_path_buf(), "a directory"),
        ] {
            let err = prepare(&path, &[]).unwrap_err();
            assert!(err.contains(kind), "{err}");
        }
        let dangling = dir.path().join("dangling");
        std::os::unix::fs::symlink(dir.path().join("nowhere"), &dangling).unwrap();
        assert!(prepare(&dangling, &[])
            .unwrap_err()
            .contains("leads nowhere"));
        let missing = dir.path().join("no-such-dir").join("x.wav");
        assert!(prepare(&missing, &[])
            .unwrap_err()
            .contains("directory does not exist"));
    }

    #[test]
    fn committed_replaces_dropped_leaves_the_target_whole() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("t.txt");
        std::fs::write(&target, "old").unwrap();
        std::fs::set_permissions(&target, std::fs::Permissions::from_mode(0o640)).unwrap();
        let mut output = prepare(&target, &[]).unwrap();
        output.file().write_all(b"new").unwrap();
        drop(output);
        assert_eq!(std::fs::read_to_string(&target).unwrap(), "old");
        replace_file(&target, b"new", &[]).unwrap();
        assert_eq!(std::fs::read_to_string(&target).unwrap(), "new");
        let mode = std::fs::metadata(&target).unwrap().permissions().mode();
        assert_eq!(mode & 0o777, 0o640);
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }
}
