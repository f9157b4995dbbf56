//! Data-driven snapshots: every `data/ok/*.tim` must parse without errors and every
//! `data/err/*.tim` with at least one; the rendered parse of each is compared with
//! the `.txt` file beside it (refresh with `UPDATE_EXPECT=1 cargo test`).

mod common;

use std::path::Path;

use expect_test::expect_file;

fn check_dir(dir: &str, expect_errors: bool) {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data")
        .join(dir);
    let mut inputs: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|entry| entry.unwrap().path())
        .filter(|path| path.extension().is_some_and(|ext| ext == "tim"))
        .collect();
    inputs.sort();
    assert!(!inputs.is_empty(), "no inputs in {}", dir.display());
    for input in inputs {
        let source = std::fs::read_to_string(&input).unwrap();
        let parse = timbre_syntax::parse(&source);
        assert_eq!(
            !parse.errors.is_empty(),
            expect_errors,
            "{}: {:?}",
            input.display(),
            parse.errors
        );
        expect_file![input.with_extension("txt")].assert_eq(&common::render_parse(&parse));
    }
}

#[test]
fn ok_inputs() {
    check_dir("ok", false);
}

#[test]
fn err_inputs() {
    check_dir("err", true);
}
