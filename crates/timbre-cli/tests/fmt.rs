//! `timbre fmt`: prints, checks and rewrites files in the canonical layout, keeping
//! their comments, and leaves a file with syntax errors as it was.

mod common;

use common::{run, run_in};

const MESSY: &str = concat!(
    "; A bee, written in a hurry.\n",
    "(define-sound bee (f)   ; its pitch\n",
    "        (* 0.5\n",
    "   (sine (* t f))))\n",
    "\n",
    "\n",
    "; Two of them.\n",
    "(instance a (bee 220) :start 0 :stop 1)   (instance b (bee 330)\n",
    " :start 0.5 :stop 1.5)\n",
);

const TIDY: &str = concat!(
    "; A bee, written in a hurry.\n",
    "(define-sound bee (f) ; its pitch\n",
    "  (* 0.5 (sine (* t f))))\n",
    "\n",
    "; Two of them.\n",
    "(instance a (bee 220) :start 0 :stop 1)\n",
    "(instance b (bee 330) :start 0.5 :stop 1.5)\n",
);

#[test]
fn fmt_prints_checks_and_rewrites_keeping_comments() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bees.tt");
    std::fs::write(&path, MESSY).unwrap();

    let printed = run_in(Some(dir.path()), ["fmt", "bees.tt"]);
    printed.assert_success();
    assert_eq!(printed.stdout, TIDY);
    assert_eq!(
        std::fs::read_to_string(&path).unwrap(),
        MESSY,
        "printing rewrote"
    );

    run_in(Some(dir.path()), ["fmt", "--check", "bees.tt"])
        .assert_code(1)
        .assert_stderr_has("not in the canonical layout");

    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o640)).unwrap();
    }
    run_in(Some(dir.path()), ["fmt", "--write", "bees.tt"]).assert_success();
    assert_eq!(std::fs::read_to_string(&path).unwrap(), TIDY);
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        let mode = std::fs::metadata(&path).unwrap().permissions().mode();
        assert_eq!(mode & 0o777, 0o640, "permissions kept");
    }
    run_in(Some(dir.path()), ["fmt", "--check", "bees.tt"]).assert_success();
    let entries: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
    assert_eq!(entries.len(), 1, "no temporary file left behind");
}

#[test]
fn a_file_with_syntax_errors_is_left_as_it_was() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("broken.tt");
    let broken = "(define-sound bee (f)\n  (* 0.5 (sine (* t f)))\n";
    std::fs::write(&path, broken).unwrap();
    run_in(Some(dir.path()), ["fmt", "--write", "broken.tt"])
        .assert_code(1)
        .assert_stderr_has("unclosed")
        .assert_stderr_has("left as it is");
    assert_eq!(std::fs::read_to_string(&path).unwrap(), broken);
}

/// `timbre check --lowered` writes a file that renders the very samples the
/// original does: the bell (an included library, 60 random modes), the siren, and
/// the wind, whose noises keep their seeds without the scene's `:seed 1`.
#[test]
fn a_lowered_file_renders_the_same_samples() {
    let dir = tempfile::tempdir().unwrap();
    let settings = ["--duration", "0.5", "--sample-rate", "16000"];
    for name in ["bell", "siren", "wind"] {
        let lowered = run([
            "check",
            "--lowered",
            common::example(name).to_str().unwrap(),
        ]);
        lowered.assert_success();
        assert!(!lowered.stdout.contains("(scene"), "{}", lowered.stdout);
        let path = dir.path().join(format!("{name}-lowered.tt"));
        std::fs::write(&path, &lowered.stdout).unwrap();

        let original = common::render_wav(
            [common::example(name).to_str().unwrap()]
                .into_iter()
                .chain(settings),
        );
        let again = common::render_wav([path.to_str().unwrap()].into_iter().chain(settings));
        assert_eq!(original.samples.len(), 8000, "{name}");
        assert!(
            original.samples.iter().any(|x| *x != 0.0),
            "{name} is silent"
        );
        assert_eq!(again.samples, original.samples, "{name}: another sound");
    }
}

#[test]
fn a_scene_prints_each_instance_as_its_timer_lets_it_out() {
    let lowered = run([
        "check",
        "--lowered",
        "--expr",
        "(define-sound hum (f) (sine (* t f))) (instance a (hum 220) :stop 1)",
    ]);
    lowered.assert_success();
    assert_eq!(
        lowered.stdout,
        "; instance a (hum), from 0 s\n(sine (* t 220))\n"
    );
}

/// Every bundled example is in the layout `timbre fmt` gives, so a newcomer's
/// `timbre fmt --check examples/*.tt` passes.
#[test]
fn the_bundled_examples_are_in_the_canonical_layout() {
    let root = common::workspace_root();
    let mut files: Vec<String> = std::fs::read_dir(root.join("examples"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "tt"))
        .map(|p| p.display().to_string())
        .collect();
    files.sort();
    assert!(files.len() >= 10, "examples found: {files:?}");
    let mut args = vec!["fmt".to_owned(), "--check".to_owned()];
    args.extend(files);
    run_in(Some(&root), args).assert_success();
}
