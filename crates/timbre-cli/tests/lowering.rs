//! Data-driven snapshots of lowering: every `lowering/NAME.tt` is read as
//! `timbre check --ir NAME.tt` reads it, and the graph of its sounds
//! (`timbre_ir::dump`) must equal `lowering/NAME.ir` beside it. Refresh the snapshots
//! with `UPDATE_EXPECT=1 cargo test --release -p timbre-cli --test lowering`, then
//! read the diff. Files the inputs read (a library, tables, a sound, frames) are in
//! `lowering/data/`. Every form of `timbre_lang::catalogue::FORMS` has an input named
//! after it, so a new form cannot go without a snapshot.

mod common;

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

use expect_test::expect_file;

fn lowering_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/lowering")
}

/// The `.tt` inputs of the folder, sorted.
fn inputs() -> Vec<PathBuf> {
    let mut inputs: Vec<PathBuf> = std::fs::read_dir(lowering_dir())
        .unwrap()
        .map(|entry| entry.unwrap().path())
        .filter(|path| path.extension().is_some_and(|ext| ext == "tt"))
        .collect();
    inputs.sort();
    assert!(
        !inputs.is_empty(),
        "no inputs in {}",
        lowering_dir().display()
    );
    inputs
}

/// What `timbre check --ir PATH` prints, made by the functions the command calls:
/// the file read through an engine with the command's rate, limits and file access,
/// then the graph reachable from its sounds.
fn ir_dump(path: &Path) -> String {
    let text = std::fs::read_to_string(path).unwrap();
    let engine = timbre::Engine::new(48_000.0)
        .with_file_access()
        .with_limits(timbre::Limits::default());
    let source = timbre::SourceFile::new(path.display().to_string(), text);
    let file = engine
        .read_scene_source(source, path.parent())
        .unwrap_or_else(|e| panic!("{}: {e:?}", path.display()));
    let program = file.program();
    let roots: Vec<_> = program.sound_roots().collect();
    timbre_ir::dump(&program.graph, &roots)
}

#[test]
fn every_input_lowers_to_its_snapshot() {
    for input in inputs() {
        let dump = ir_dump(&input);
        assert!(!dump.is_empty(), "{}: no sound to dump", input.display());
        expect_file![input.with_extension("ir")].assert_eq(&dump);
    }
}

#[test]
fn the_command_prints_the_same_dumps() {
    for input in inputs() {
        let run = common::run(["check".as_ref(), "--ir".as_ref(), input.as_os_str()]);
        run.assert_success();
        assert_eq!(run.stdout, ir_dump(&input), "{}", input.display());
    }
}

#[test]
fn every_form_has_an_input_and_every_input_a_snapshot() {
    let dir = lowering_dir();
    let stems = |ext: &str| -> BTreeSet<String> {
        common::dir_entries(&dir)
            .into_iter()
            .filter_map(|name| name.strip_suffix(ext).map(str::to_owned))
            .collect()
    };
    let inputs = stems(".tt");
    let missing: Vec<&str> = timbre_lang::catalogue::FORMS
        .iter()
        .copied()
        .filter(|form| !inputs.contains(*form))
        .collect();
    assert!(
        missing.is_empty(),
        "forms without a `tests/lowering/FORM.tt`: {missing:?}"
    );
    assert_eq!(
        inputs,
        stems(".ir"),
        "each input has one snapshot, each snapshot one input"
    );
}
