//! `timbre graph` names what a reader of a scene looks for: keyframe nodes by their
//! variable, instances with their class.

mod common;

use common::run_in;

#[test]
fn keyframes_show_their_variable_and_instances_their_class() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("scene.tt"),
        "(define-sound hit (amp f) (* amp (sine (* t f)) (damp (* t 5))))\n\
         (keyframes force :interp linear (0 0.2) (1 0.9))\n\
         (keyframes path (0 (0 1 0)) (1 (2 1 0)))\n\
         (instance first (hit :amp force :f 440) :start 0)\n\
         (instance second (hit :amp 0.5 :f (index path 0)) :start 0.5)\n",
    )
    .unwrap();
    let run = run_in(Some(dir.path()), ["graph", "scene.tt", "-o", "-"]);
    run.assert_success();
    let dot = &run.stdout;
    let keyframe_lines: Vec<&str> = dot.lines().filter(|l| l.contains("keyframe")).collect();
    assert!(
        keyframe_lines
            .iter()
            .any(|l| l.contains("label=\"force\\nkeyframe\\n2 keys, linear\"")),
        "{dot}"
    );
    assert!(
        keyframe_lines
            .iter()
            .any(|l| l.contains("path.x\\nkeyframe")),
        "{dot}"
    );
    assert!(dot.contains("instance first: hit\\n0 s"), "{dot}");
    assert!(dot.contains("instance second: hit\\n0.5 s"), "{dot}");
}
