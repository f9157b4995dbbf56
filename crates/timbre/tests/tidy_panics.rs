//! Every call that can panic left in the library crates' code (not their tests) is
//! listed in `panics.txt` with the reason it cannot fire: a script, a file or an API
//! argument gets an error, never a panic, so a new one must be argued for or turned
//! into an error. Sites are matched by file and the text of their line, not by line
//! number, so edits elsewhere do not break the list.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// The library crates: what a host links, and what reads scripts and files.
const CRATES: [&str; 11] = [
    "timbre",
    "timbre-diag",
    "timbre-ir",
    "timbre-lang",
    "timbre-gen",
    "timbre-jit",
    "timbre-scene",
    "timbre-motion",
    "timbre-modal",
    "timbre-syntax",
    "timbre-evolve",
];

/// What can panic: the calls and macros a reviewer looks for.
const PANICKING: [&str; 9] = [
    ".unwrap()",
    ".expect(",
    "assert!(",
    "assert_eq!(",
    "assert_ne!(",
    "unreachable!(",
    "panic!(",
    "todo!(",
    "unimplemented!(",
];

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn rust_files(dir: &Path, into: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for path in entries.flatten().map(|e| e.path()) {
        if path.is_dir() {
            rust_files(&path, into);
        } else if path.extension().is_some_and(|e| e == "rs") {
            into.push(path);
        }
    }
}

/// Whether `code` calls one of [`PANICKING`] (a macro not preceded by a letter or
/// `_`, so `debug_assert!` is not `assert!`).
fn panics(code: &str) -> bool {
    PANICKING.iter().any(|needle| {
        code.match_indices(needle).any(|(at, _)| {
            needle.starts_with('.')
                || !code[..at]
                    .chars()
                    .next_back()
                    .is_some_and(|c| c.is_alphanumeric() || c == '_')
        })
    })
}

/// The code of a line without a trailing `//` comment (unless the line has a
/// string, where `//` may be part of it).
fn code_of(line: &str) -> &str {
    match (line.find("//"), line.contains('"')) {
        (Some(at), false) => &line[..at],
        _ => line,
    }
}

/// The trimmed lines of `text` that can panic, outside comments (doc examples
/// included) and items under `#[cfg(test)]`.
fn sites(text: &str) -> Vec<String> {
    let mut found = vec![];
    let mut lines = text.lines();
    while let Some(line) = lines.next() {
        let trimmed = line.trim();
        if trimmed.starts_with("#[cfg(test)]") {
            // Skip the item: up to its `;`, or its braces' balance.
            let mut depth = 0i64;
            let mut opened = false;
            for line in lines.by_ref() {
                let code = code_of(line);
                depth += code.matches('{').count() as i64 - code.matches('}').count() as i64;
                opened |= code.contains('{');
                if (opened && depth <= 0) || (!opened && code.trim_end().ends_with(';')) {
                    break;
                }
            }
            continue;
        }
        if trimmed.starts_with("//") {
            continue;
        }
        if panics(code_of(trimmed)) {
            found.push(trimmed.to_owned());
        }
    }
    found
}

#[test]
fn every_panic_left_in_the_libraries_is_listed_with_the_reason_it_cannot_fire() {
    let root = root();
    // (file, line text) → how many times it appears in the code.
    let mut in_code: BTreeMap<(String, String), usize> = BTreeMap::new();
    for krate in CRATES {
        let mut files = vec![];
        rust_files(&root.join("crates").join(krate).join("src"), &mut files);
        for file in files {
            let text = std::fs::read_to_string(&file).unwrap();
            let name = file
                .strip_prefix(&root)
                .unwrap()
                .to_string_lossy()
                .replace('\\', "/");
            for site in sites(&text) {
                *in_code.entry((name.clone(), site)).or_default() += 1;
            }
        }
    }
    assert!(
        in_code
            .keys()
            .any(|(f, _)| f.starts_with("crates/timbre-ir/")),
        "found no sites at all: is the scan looking in the right place? {}",
        root.display()
    );
    let list_path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/panics.txt");
    let list = std::fs::read_to_string(&list_path).unwrap();
    let mut listed: BTreeMap<(String, String), usize> = BTreeMap::new();
    let mut malformed = vec![];
    for line in list
        .lines()
        .filter(|l| !l.trim().is_empty() && !l.starts_with('#'))
    {
        let parsed = line.split_once(": ").and_then(|(file, rest)| {
            let (site, reason) = rest.split_once(" — ")?;
            (!reason.trim().is_empty()).then(|| (file.to_owned(), site.trim().to_owned()))
        });
        match parsed {
            Some(key) => *listed.entry(key).or_default() += 1,
            None => malformed.push(line),
        }
    }
    assert!(
        malformed.is_empty(),
        "lines of {} are `path: the line's code — the reason it cannot fire`: {malformed:#?}",
        list_path.display()
    );
    let mut problems = vec![];
    for ((file, site), &n) in &in_code {
        let have = listed
            .get(&(file.clone(), site.clone()))
            .copied()
            .unwrap_or(0);
        for _ in have..n {
            problems.push(format!(
                "not listed: return an error instead, or add the line\n{file}: {site} — WHY IT CANNOT FIRE"
            ));
        }
    }
    for ((file, site), &n) in &listed {
        let have = in_code
            .get(&(file.clone(), site.clone()))
            .copied()
            .unwrap_or(0);
        for _ in have..n {
            problems.push(format!(
                "listed, but no such line in the code (remove it from the list):\n{file}: {site}"
            ));
        }
    }
    assert!(
        problems.is_empty(),
        "{} in {}:\n\n{}",
        problems.len(),
        list_path.display(),
        problems.join("\n\n")
    );
}

#[test]
fn the_scan_finds_what_panics_and_skips_tests_comments_and_doc_examples() {
    let text = r#"
/// ```
/// x.unwrap();
/// ```
fn f() {
    let a = b.unwrap(); // why
    debug_assert!(a > 0);
    // c.expect("no");
    assert_eq!(a, 1);
    let d = e.unwrap_or(0);
}

#[cfg(test)]
mod tests {
    fn g() {
        h.unwrap();
    }
}

fn after() {
    unreachable!("x")
}
"#;
    assert_eq!(
        sites(text),
        [
            "let a = b.unwrap(); // why",
            "assert_eq!(a, 1);",
            "unreachable!(\"x\")"
        ]
    );
}
