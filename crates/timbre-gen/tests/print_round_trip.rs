//! The printer on every example, every conformance file and random trees: printing
//! and formatting are idempotent, keep the meaning (the same expressions parse back),
//! and formatting keeps every comment.

use std::path::{Path, PathBuf};

use rand::SeedableRng;
use timbre_gen::generate::{random_tree, GenConfig};
use timbre_syntax::{format_source, parse, print};
use timbre_testkit::tt_files;

/// The expressions of a text, as their values print (spans and spelling aside).
fn meaning(text: &str) -> Vec<String> {
    let parsed = parse(text);
    assert!(parsed.errors.is_empty(), "{:?}\n{text}", parsed.errors);
    parsed.exprs.iter().map(|e| e.to_string()).collect()
}

/// The comments of a text, in order (none of the files has a `;` in a string).
fn comments(text: &str) -> Vec<&str> {
    text.lines()
        .filter_map(|line| line.find(';').map(|at| line[at..].trim_end()))
        .collect()
}

fn check(name: &str, text: &str) {
    let printed = print(&parse(text).exprs);
    assert_eq!(
        print(&parse(&printed).exprs),
        printed,
        "{name}: print is not stable"
    );
    assert_eq!(
        meaning(&printed),
        meaning(text),
        "{name}: print changed the meaning"
    );

    let formatted = format_source(text).unwrap();
    assert_eq!(
        format_source(&formatted).unwrap(),
        formatted,
        "{name}: format is not idempotent"
    );
    assert_eq!(
        meaning(&formatted),
        meaning(text),
        "{name}: format changed the meaning"
    );
    assert_eq!(
        comments(&formatted),
        comments(text),
        "{name}: comments moved or lost"
    );
    for line in formatted.lines() {
        assert_eq!(line, line.trim_end(), "{name}: blanks at the end of a line");
    }
}

#[test]
fn every_example_and_conformance_file_round_trips() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let files: Vec<PathBuf> = ["examples", "tests/conformance"]
        .iter()
        .flat_map(|dir| tt_files(&root.join(dir)))
        .collect();
    let mut checked = 0;
    for path in files {
        let text = std::fs::read_to_string(&path).unwrap();
        // Conformance cases of syntax errors are not formatted (tested elsewhere).
        if parse(&text).errors.is_empty() {
            check(&path.display().to_string(), &text);
            checked += 1;
        }
    }
    assert!(checked > 60, "only {checked} files parse");
}

#[test]
fn a_thousand_random_trees_round_trip() {
    let config = GenConfig {
        max_nodes: 60,
        ..GenConfig::default()
    };
    for seed in 0..1000u64 {
        let tree = random_tree(&mut rand::rngs::StdRng::seed_from_u64(seed), &config);
        check(&format!("tree {seed}"), &tree);
    }
}
