//! Tidy checks on the node catalogue: every entry has its place everywhere a node
//! needs one. (The random-tree generator's coverage is checked in timbre-gen's `tests/generate.rs`,
//! the engines' agreement on each entry's example in timbre-jit's differential
//! tests, and each entry's conformance case in the top-level `tests/`.)

use std::collections::BTreeSet;
use std::path::Path;

use timbre_lang::catalogue::{self, Kind, NODES};
use timbre_lang::{compile_str, CompileOptions, NoFiles, Registry};
use timbre_syntax::{Expr, ExprKind};

/// Entries without an example, and why.
const NO_EXAMPLE: &[(&str, &str)] = &[("sample", "it needs a sound file")];

fn nodes_md() -> String {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../lang-spec/nodes.md");
    std::fs::read_to_string(path).expect("lang-spec/nodes.md")
}

/// The text of the section under the heading `title` (up to the next heading of
/// the same or a higher level), if there is one.
fn section<'a>(doc: &'a str, title: &str) -> Option<&'a str> {
    let mut lines = doc.lines().enumerate();
    let (start, level) = lines.find_map(|(i, line)| {
        let hashes = line.chars().take_while(|c| *c == '#').count();
        (hashes >= 2 && line[hashes..].trim() == title).then_some((i, hashes))
    })?;
    let all: Vec<&str> = doc.lines().collect();
    let end = all[start + 1..]
        .iter()
        .position(|line| {
            let hashes = line.chars().take_while(|c| *c == '#').count();
            hashes >= 2 && hashes <= level
        })
        .map_or(all.len(), |p| start + 1 + p);
    let first = doc.lines().take(start).map(|l| l.len() + 1).sum::<usize>();
    let len = all[start..end].iter().map(|l| l.len() + 1).sum::<usize>();
    Some(&doc[first..(first + len).min(doc.len())])
}

/// Every name called in an expression.
fn calls(expr: &Expr, into: &mut BTreeSet<String>) {
    if let ExprKind::List(items) = &expr.kind {
        if let Some(head) = items.first().and_then(Expr::as_symbol) {
            into.insert(head.to_owned());
        }
        for item in items {
            calls(item, into);
        }
    }
}

#[test]
fn names_are_unique_and_not_forms() {
    let mut seen = BTreeSet::new();
    for node in NODES {
        assert!(seen.insert(node.name), "`{}` is listed twice", node.name);
        assert!(!catalogue::FORMS.contains(&node.name), "{}", node.name);
    }
}

#[test]
fn every_node_is_defined_in_its_nodes_md_section() {
    let doc = nodes_md();
    for node in NODES {
        let text = section(&doc, node.section).unwrap_or_else(|| {
            panic!(
                "`{}`: lang-spec/nodes.md has no heading `{}`",
                node.name, node.section
            )
        });
        assert!(
            text.contains(&format!("`{}`", node.name)),
            "`{}` is not described in the section `{}` of lang-spec/nodes.md",
            node.name,
            node.section
        );
    }
}

#[test]
fn every_node_has_an_example_that_calls_it() {
    let registry = Registry::new();
    let options = CompileOptions::new(&registry, &NoFiles);
    for node in NODES {
        if node.example.is_empty() {
            assert!(
                NO_EXAMPLE.iter().any(|(n, _)| *n == node.name),
                "`{}` has no example (and no named exemption)",
                node.name
            );
            continue;
        }
        let parse = timbre_syntax::parse(node.example);
        let mut called = BTreeSet::new();
        for expr in &parse.exprs {
            calls(expr, &mut called);
        }
        assert!(
            called.contains(node.name),
            "the example of `{}` does not call it: {}",
            node.name,
            node.example
        );
        let program = compile_str(node.example, &options)
            .unwrap_or_else(|e| panic!("the example of `{}`: {e:?}", node.name));
        let root = program.root.expect("a sound");
        assert_eq!(program.graph.width(root), 1, "{}", node.example);
        // A stateful node's example keeps the node (it cannot fold away).
        if node.kind == Kind::Stateful {
            assert!(
                program.graph.nodes().any(|(_, n)| n.op.kind() == node.name
                    || (node.name == "phasor" && n.op.kind() == "phasor")),
                "the example of `{}` has no `{}` node",
                node.name,
                node.name
            );
        }
    }
}

#[test]
fn every_nodes_md_index_entry_is_a_node() {
    // The index table lists nodes by name; each must be in the catalogue (or be a
    // leaf: `t`, `pi`, numbers).
    let doc = nodes_md();
    let index = section(&doc, "Index").expect("an index");
    let names: BTreeSet<&str> = catalogue::names().collect();
    for line in index.lines().filter(|l| l.starts_with("| [")) {
        for name in line.split('`').skip(1).step_by(2) {
            if ["t", "pi", "CustomNode", "Registry::register"].contains(&name) {
                continue;
            }
            assert!(names.contains(name), "index names `{name}`, not a node");
        }
    }
    for name in &names {
        assert!(
            index.contains(&format!("`{name}`")),
            "`{name}` is missing from the index of lang-spec/nodes.md"
        );
    }
}

/// Every `"timbre::…"` code literal in the workspace's sources.
fn diagnostic_codes(dir: &Path, into: &mut BTreeSet<String>) {
    for entry in std::fs::read_dir(dir).unwrap().flatten() {
        let path = entry.path();
        if path.is_dir() {
            diagnostic_codes(&path, into);
        } else if path.extension().is_some_and(|e| e == "rs") {
            let text = std::fs::read_to_string(&path).unwrap();
            for piece in text.split("\"timbre::").skip(1) {
                let code: String = piece
                    .chars()
                    .take_while(|c| c.is_ascii_lowercase() || *c == '-' || *c == ':')
                    .collect();
                if piece[code.len()..].starts_with('"') {
                    into.insert(format!("timbre::{code}"));
                }
            }
        }
    }
}

#[test]
fn every_diagnostic_code_is_in_grammar_md() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let grammar = std::fs::read_to_string(root.join("lang-spec/grammar.md")).unwrap();
    let mut codes = BTreeSet::new();
    for krate in std::fs::read_dir(root.join("crates")).unwrap().flatten() {
        let src = krate.path().join("src");
        if src.is_dir() {
            diagnostic_codes(&src, &mut codes);
        }
    }
    assert!(codes.len() > 50, "found only {codes:?}");
    let missing: Vec<&String> = codes
        .iter()
        .filter(|c| !grammar.contains(&format!("`{c}`")))
        .collect();
    assert!(
        missing.is_empty(),
        "not in lang-spec/grammar.md: {missing:?}"
    );
}
