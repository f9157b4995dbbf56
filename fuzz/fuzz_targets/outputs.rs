//! The command line's one way out for files (`crates/timbre-cli/src/output.rs`) on
//! any arrangement of a directory: regular files, directories, named pipes, links
//! (to files, to links, dangling), hard links; any choice of inputs and outputs,
//! named directly or through `.`, `..` and links; outputs committed or dropped.
//! What must hold: no panic; a refusal leaves the directory exactly as it was;
//! an accepted output never replaced an input, a non-regular file or another
//! output, and once committed or dropped no temporary file is left.
#![no_main]

#[path = "../../crates/timbre-cli/src/output.rs"]
#[allow(dead_code)]
mod output;

use std::collections::BTreeMap;
use std::os::unix::fs::{FileTypeExt, MetadataExt};
use std::path::{Path, PathBuf};

use libfuzzer_sys::fuzz_target;

const ENTRIES: usize = 6;

/// What a directory entry is, and for a regular file its bytes and inode.
#[derive(Debug, PartialEq, Eq, Clone)]
enum Seen {
    File(Vec<u8>, u64),
    Dir,
    Fifo,
    Link(PathBuf),
}

fn survey(dir: &Path) -> BTreeMap<String, Seen> {
    let mut seen = BTreeMap::new();
    for entry in std::fs::read_dir(dir).unwrap() {
        let entry = entry.unwrap();
        let path = entry.path();
        let meta = std::fs::symlink_metadata(&path).unwrap();
        let kind = if meta.file_type().is_symlink() {
            Seen::Link(std::fs::read_link(&path).unwrap())
        } else if meta.is_dir() {
            Seen::Dir
        } else if meta.file_type().is_fifo() {
            Seen::Fifo
        } else {
            Seen::File(std::fs::read(&path).unwrap(), meta.ino())
        };
        seen.insert(entry.file_name().to_string_lossy().into_owned(), kind);
    }
    seen
}

fuzz_target!(|data: &[u8]| {
    if data.len() < ENTRIES + 2 {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let name = |k: u8| format!("n{}", k as usize % ENTRIES);
    // The entries, in two passes so that links may lead to what comes later.
    for (k, &b) in data[..ENTRIES].iter().enumerate() {
        let path = d.join(format!("n{k}"));
        match b % 6 {
            0 => {}
            1 | 2 => std::fs::write(&path, format!("input {k}")).unwrap(),
            3 => std::fs::create_dir(&path).unwrap(),
            4 => {
                let c = std::ffi::CString::new(path.to_str().unwrap()).unwrap();
                // SAFETY: a valid C string and a mode.
                unsafe { libc::mkfifo(c.as_ptr(), 0o600) };
            }
            _ => {}
        }
    }
    for (k, &b) in data[..ENTRIES].iter().enumerate() {
        let path = d.join(format!("n{k}"));
        if b % 6 == 5 {
            let to = name(b / 6);
            if b & 0x80 != 0 {
                let _ = std::fs::hard_link(d.join(&to), &path);
            } else {
                let _ = std::os::unix::fs::symlink(&to, &path);
            }
        }
    }
    let flags = data[ENTRIES];
    let commit = flags & 1 == 1;
    // The rest: pairs of (role, entry): even roles name an input, odd an output,
    // spelt plainly, through `.`, or through `..` of a directory.
    let spell = |b: u8| -> PathBuf {
        let entry = name(b);
        match (b >> 4) % 3 {
            0 => d.join(entry),
            1 => d.join(".").join(entry),
            _ => d.join("n0").join("..").join(entry),
        }
    };
    let mut reads = vec![];
    let mut outputs = vec![];
    for pair in data[ENTRIES + 1..].chunks_exact(2).take(8) {
        if pair[0] % 2 == 0 {
            reads.push(spell(pair[1]));
        } else {
            outputs.push(spell(pair[1]));
        }
    }
    let before = survey(d);
    let asked: Vec<&Path> = outputs.iter().map(PathBuf::as_path).collect();
    let prepared = match output::prepare_all(&asked, &reads) {
        Err(_) => {
            assert_eq!(survey(d), before, "a refusal changed the directory");
            return;
        }
        Ok(prepared) => prepared,
    };
    // What each input was (through links), to compare after; only regular files
    // are read (a run reads nothing else, and a pipe would block the reading).
    let inputs: Vec<(PathBuf, Option<Vec<u8>>)> = reads
        .iter()
        .map(|r| {
            let regular = std::fs::metadata(r).is_ok_and(|m| m.is_file());
            (r.clone(), regular.then(|| std::fs::read(r).ok()).flatten())
        })
        .collect();
    let mut committed = 0;
    for (k, mut out) in prepared.into_iter().enumerate() {
        std::io::Write::write_all(out.file(), format!("output {k}").as_bytes()).unwrap();
        if commit {
            // A commit may fail only if the target changed meanwhile, which it
            // did not.
            out.commit().unwrap();
            committed += 1;
        }
    }
    for (path, bytes) in inputs {
        if let Some(bytes) = bytes {
            assert_eq!(std::fs::read(&path).ok(), Some(bytes), "{path:?} was replaced");
        }
    }
    let after = survey(d);
    for (entry, was) in &before {
        let now = after.get(entry).unwrap_or_else(|| panic!("{entry} vanished"));
        match (was, now) {
            (Seen::File(..), Seen::File(..)) => {}
            (was, now) => assert_eq!(was, now, "{entry} is not a file and changed"),
        }
    }
    assert!(
        after.keys().all(|n| !n.ends_with(".partial")),
        "a temporary file was left: {after:?}"
    );
    assert!(after.len() <= before.len() + committed);
});
