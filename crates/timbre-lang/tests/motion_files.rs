//! The `motion` form and the nodes of motion on bad input: each problem a diagnostic
//! with its code, pointing at the form, with a help line; every file the import
//! touches (the glTF file and its buffers) read through the sandboxed loader.

use std::path::Path;

use timbre_ir::{Diagnostics, SourceFile};
use timbre_lang::{compile, CompileOptions, Compiled, FsLoader, Loader, Registry, SandboxLoader};

fn shot() -> Vec<u8> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/car-pass.glb");
    std::fs::read(path).unwrap()
}

fn compile_in(dir: &Path, loader: &dyn Loader, text: &str) -> Result<Compiled, Diagnostics> {
    let registry = Registry::new();
    let options = CompileOptions::new(&registry, loader);
    let source = SourceFile::new(dir.join("scene.tt").display().to_string(), text);
    compile(source, Some(dir), &options)
}

/// The one error of `text` (with the shot as `shot.glb` beside it): its code, message,
/// underlined text and help.
fn error(text: &str, files: &[(&str, &[u8])]) -> (String, String, String, String) {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("shot.glb"), shot()).unwrap();
    for (name, bytes) in files {
        std::fs::write(dir.path().join(name), bytes).unwrap();
    }
    let sandbox = SandboxLoader::new([dir.path()]).unwrap();
    let Err(Diagnostics(diags)) = compile_in(dir.path(), &sandbox, text) else {
        panic!("{text} compiled");
    };
    let diag = &diags[0];
    let span = diag.labels.first().map(|l| l.0).unwrap_or_default();
    (
        diag.code.to_string(),
        diag.message.clone(),
        text[span.start..span.end].to_owned(),
        diag.help.clone().unwrap_or_default(),
    )
}

const SCENE: &str =
    "(scene :duration 1)\n(motion shot \"shot.glb\")\n(listener :object \"Camera\")\n";

#[test]
fn a_node_the_file_does_not_have_gets_the_closest_name() {
    let text = format!("{SCENE}(define-sound s () (speed \"Bal\"))\n(instance a (s))");
    let (code, message, underlined, help) = error(&text, &[]);
    assert_eq!(code, "timbre::unknown-node");
    assert_eq!(message, "no node is named \"Bal\"");
    assert_eq!(underlined, "\"Bal\"");
    assert_eq!(help, "did you mean \"Ball\"?");
}

#[test]
fn a_node_before_any_motion_file_asks_for_one() {
    let text = "(scene :duration 1)\n(define-sound s () (speed \"Ball\"))\n(instance a (s))";
    let (code, message, underlined, help) = error(text, &[]);
    assert_eq!(code, "timbre::unknown-node");
    assert_eq!(message, "no motion file to find node `Ball` in");
    assert_eq!(underlined, "\"Ball\"");
    assert!(help.contains("(motion shot \"car-pass.glb\")"), "{help}");
}

#[test]
fn an_object_without_a_mesh_is_no_obstacle() {
    let text = format!("{SCENE}(box cam :object \"Camera\")\n(define-sound s () (sine (* t 440)))\n(instance a (s) :at (0 0 0))");
    let (code, message, underlined, help) = error(&text, &[]);
    assert_eq!(code, "timbre::no-mesh");
    assert_eq!(message, "node \"Camera\" has no mesh to be an obstacle");
    assert_eq!(underlined, "\"Camera\"");
    assert!(help.contains("(box :size"), "{help}");
}

#[test]
fn object_and_position_together_are_refused() {
    let text = format!("{SCENE}(source car :object \"Car\" :position (0 0 0))");
    let (code, _, underlined, help) = error(&text, &[]);
    assert_eq!(code, "timbre::conflicting-options");
    assert_eq!(underlined, "\"Car\"");
    assert_eq!(help, "keep one of :object and :position");
}

#[test]
fn a_quantity_needs_a_track() {
    let text = format!("{SCENE}(define-sound s () (speed 3))\n(instance a (s))");
    let (code, message, underlined, _) = error(&text, &[]);
    assert_eq!(code, "timbre::not-a-track");
    assert_eq!(message, "expected a track, found a number");
    assert_eq!(underlined, "3");
    let text = format!("{SCENE}(define-sound s () (distance \"Car\"))\n(instance a (s))");
    let (code, message, _, help) = error(&text, &[]);
    assert_eq!(code, "timbre::arity");
    assert_eq!(message, "`distance` takes 2 tracks, found 1 argument");
    assert_eq!(
        help,
        "write (distance \"Car\" \"Camera\"), and :time T to read it at scene time T"
    );
}

#[test]
fn a_file_that_is_not_gltf_or_is_cut_short_is_an_error_at_the_form() {
    let text = "(scene :duration 1)\n(motion shot \"bad.glb\")";
    let (code, _, underlined, help) = error(text, &[("bad.glb", b"(scene)")]);
    assert_eq!(code, "timbre::gltf-parse");
    assert_eq!(underlined, "\"bad.glb\"");
    assert!(!help.is_empty());
    let cut = shot()[..4000].to_vec();
    let (code, _, underlined, _) = error(text, &[("bad.glb", &cut)]);
    assert!(code.starts_with("timbre::gltf-"), "{code}");
    assert_eq!(underlined, "\"bad.glb\"");
}

const GLTF: &str = r#"{"asset": {"version": "2.0"},
  "buffers": [{"uri": "BIN", "byteLength": 12}],
  "bufferViews": [{"buffer": 0, "byteLength": 12}],
  "accessors": [{"bufferView": 0, "componentType": 5126, "count": 1, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 1]}],
  "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
  "nodes": [{"name": "A", "mesh": 0}], "scenes": [{"nodes": [0]}]}"#;

#[test]
fn a_missing_buffer_is_named() {
    let text = "(scene :duration 1)\n(motion shot \"shot.gltf\")";
    let gltf = GLTF.replace("BIN", "shot.bin");
    let (code, message, underlined, _) = error(text, &[("shot.gltf", gltf.as_bytes())]);
    assert_eq!(code, "timbre::gltf-buffer");
    assert!(message.contains("shot.bin"), "{message}");
    assert_eq!(underlined, "\"shot.gltf\"");
    // With the buffer beside it, the file reads.
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("shot.gltf"), gltf).unwrap();
    std::fs::write(dir.path().join("shot.bin"), [0u8; 12]).unwrap();
    let text = "(scene :duration 1)\n(motion shot \"shot.gltf\")\n(define-sound s () (combine (position \"A\")))\n(instance a (s))";
    compile_in(dir.path(), &FsLoader, text).unwrap_or_else(|e| panic!("{e:?}"));
}

#[test]
fn a_buffer_outside_the_sandbox_is_refused() {
    let outer = tempfile::tempdir().unwrap();
    let inner = outer.path().join("shots");
    std::fs::create_dir(&inner).unwrap();
    std::fs::write(outer.path().join("secret.bin"), [0u8; 12]).unwrap();
    std::fs::write(
        inner.join("shot.gltf"),
        GLTF.replace("BIN", "../secret.bin"),
    )
    .unwrap();
    let sandbox = SandboxLoader::new([&inner]).unwrap();
    let text = "(scene :duration 1)\n(motion shot \"shot.gltf\")";
    let Err(Diagnostics(diags)) = compile_in(&inner, &sandbox, text) else {
        panic!("read a buffer outside the sandbox");
    };
    assert_eq!(diags[0].code, "timbre::gltf-buffer");
    assert!(diags[0].message.contains("outside"), "{}", diags[0].message);
    // The file system loader reads it.
    compile_in(&inner, &FsLoader, text).unwrap_or_else(|e| panic!("{e:?}"));
}
