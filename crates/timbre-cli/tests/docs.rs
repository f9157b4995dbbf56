//! Every `lisp` code block of the user guide (`docs/*.md`) is a whole file that
//! `timbre check` accepts, so the guide cannot drift from the language.

mod common;

use std::path::Path;

/// The `lisp` blocks of a Markdown text, with the line each starts on.
fn lisp_blocks(text: &str) -> Vec<(usize, String)> {
    let mut blocks = vec![];
    let mut current: Option<(usize, String)> = None;
    for (i, line) in text.lines().enumerate() {
        match (&mut current, line.trim_end()) {
            (None, "```lisp") => current = Some((i + 2, String::new())),
            (Some(_), "```") => blocks.extend(current.take()),
            (Some((_, block)), line) => {
                block.push_str(line);
                block.push('\n');
            }
            (None, _) => {}
        }
    }
    blocks
}

#[test]
fn every_lisp_block_in_the_guide_checks() {
    let docs = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../docs");
    let dir = tempfile::tempdir().unwrap();
    // A block may read the example shot by its bare name, as the guide tells users
    // to run it beside the file.
    let examples = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples");
    std::fs::copy(
        examples.join("car-pass.glb"),
        dir.path().join("car-pass.glb"),
    )
    .unwrap();
    // …and the contact shots as the examples do, from `shots/` beside it.
    std::fs::create_dir(dir.path().join("shots")).unwrap();
    for name in ["cube-drop", "stairs", "dominoes", "can"] {
        let file = format!("{name}.glb");
        std::fs::copy(
            examples.join("shots").join(&file),
            dir.path().join("shots").join(&file),
        )
        .unwrap();
    }
    // …and the scene the Blender extension writes for the cube drop, which reads its
    // motion as `soundtrack.glb`: the cube-drop shot has the same nodes (Cube, Floor,
    // Camera).
    std::fs::copy(
        examples.join("shots").join("cube-drop.glb"),
        dir.path().join("soundtrack.glb"),
    )
    .unwrap();
    let mut checked = 0;
    let mut failures = vec![];
    for entry in std::fs::read_dir(&docs).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_none_or(|e| e != "md") {
            continue;
        }
        let text = std::fs::read_to_string(&path).unwrap();
        for (line, block) in lisp_blocks(&text) {
            let file = dir.path().join("block.tt");
            std::fs::write(&file, &block).unwrap();
            let out = common::command().arg("check").arg(&file).output().unwrap();
            checked += 1;
            if !out.status.success() {
                failures.push(format!(
                    "{}:{line}:\n{}",
                    path.display(),
                    String::from_utf8_lossy(&out.stderr)
                ));
            }
        }
    }
    assert!(
        checked >= 5,
        "only {checked} blocks found under {}",
        docs.display()
    );
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn blocks_are_found_with_their_lines() {
    let text =
        "intro\n```lisp\n(sine t)\n```\n```console\n$ x\n```\n```lisp\n(white)\n(pink)\n```\n";
    assert_eq!(
        lisp_blocks(text),
        vec![
            (3, "(sine t)\n".to_owned()),
            (9, "(white)\n(pink)\n".to_owned())
        ]
    );
}
